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
