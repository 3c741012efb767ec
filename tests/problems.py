"""Reference problems of shared/reference.md section 7 (shared by the tests)."""
import numpy as np

P1 = dict(mass=[2.0], stiffness=[12.0], damping=[3.0], dt=0.02, T=10.0, loaded=[0])
P2 = dict(mass=[2.0, 3.0], stiffness=[20.0, 15.0], damping=[5.0, 6.0], dt=0.02, T=10.0, loaded=[1])
P3 = dict(mass=[10, 9, 8, 7, 6, 6, 5.5, 5, 4.5, 4, 3.5, 4, 2.5, 2, 2],
          stiffness=[55000, 50000, 45000, 40000, 40000, 35000, 30000, 25000, 20000, 15000, 10000,
                     9000, 8000, 7000, 6000],
          damping=[0.0] * 15, dt=None, T=0.8, loaded=[14])
PROBLEMS = {"P1": P1, "P2": P2, "P3": P3}


def uniform_chain(n, m=1.0, k=1e4, c=1.0):
    return dict(mass=np.full(n, m), stiffness=np.full(n, k), damping=np.full(n, c), loaded=[n - 1])


def rel_error(x, ref):
    """max over time and outputs of |x - ref|, relative to max |ref|."""
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


def p4(n_samples=100_000):
    """P4 (reference.md section 7): the nonlinear 4-DOF chain, the shape of the source's example.

    ::

        ground --[k, k3]--(m0)--[k]--(m1)--[k, k3]--(m2)--[k]--(m3) <- f(t)

    Four unit masses, every linear spring k = 1e4 N/m, C = 1.0 M + 2e-4 K (Rayleigh; modal
    damping 1.5 % to 2.1 % over the linear modes at 5.5, 15.9, 24.4 and 29.9 Hz), cubic springs
    k3 = 2e7 N/m^3 from DOF 0 to ground and between DOFs 1 and 2 (0-based; the source counts
    from 1), white noise of 100 N standard deviation on DOF 3 sampled at fs = 1000 Hz
    (numpy default_rng(0)).

    The cubic forces matter: they are tens of percent of the linear ones in RMS and comparable
    at the peaks. Measured with dtdyn.nonlinear.reference over all 100,000 samples
    (y = relative displacement of the spring):

        spring             max|k3 y^3| / max|k y|    rms(k3 y^3) / rms(k y)    max |y|
        DOF 0 - ground     342 N / 258 N = 1.33       0.39                      0.026 m
        DOF 1 - DOF 2      176 N / 206 N = 0.85       0.24                      0.021 m

    (first 5000 samples: peak ratios 0.72 and 0.51; tests/test_nl_reference.py checks them.)
    """
    from dtdyn.app.problems import p4 as runtime_p4
    return runtime_p4(n_samples)
