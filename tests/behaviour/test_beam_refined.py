"""The beam's time step refined (``refine=``): iterative refinement of every step's solve with
the residual taken element by element in double-double (block_chain.h; dtdyn.linear._beam
refined_step_operator for NumPy).

Oracles: the static deflection of a cantilever with a tip spring (Hermite elements are nodally
exact for a static load: k x + k3 x^3 = F, k = 3 EI / L^3), the element stiffness as
[I, -T]^T F^-1 [I, -T] (the form the residual uses), and the unrefined step where rounding
is small (bitwise below the "auto" threshold)."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated import beam as derived
from dtdyn.linear import _beam as beam_mod

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
W1 = 1.8751040687119611 ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))   # rad/s, the first mode


def ramp_and_hold(dt, ramp, end):
    t = np.arange(int(round(end / dt)) + 1) * dt
    return np.where(t < ramp, 0.5 * (1 - np.cos(np.pi * t / ramp)), 1.0)


def test_the_residuals_element_form_is_the_element_stiffness():
    h = 3e-4
    Ke = derived.element_stiffness(E * I, h)
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=h * 10, elements=10)
    hh, (f00, f01, f11), _ = beam_mod._element_terms(beam)
    F_inv = np.array([[f00, f01], [f01, f11]])
    B = np.hstack([np.eye(2), -np.array([[1.0, -hh], [0.0, 1.0]])])   # y = x_i - T x_{i+1}
    assert np.allclose(B.T @ F_inv @ B, Ke, rtol=1e-14, atol=1e-14 * np.abs(Ke).max())


def test_static_deflection_with_a_cubic_spring_at_2000_elements():
    """A tip force ramped in and held on a 2,000-element cantilever with a cubic spring at the
    tip; mode 1 critically damped (alpha M), so 0.25 s after the ramp its transient is
    (1 + w1 t) exp(-w1 t) ~ 2e-11 of the deflection. Refined, the end deflection equals the
    static root to 1e-9 (Newton's tol 1e-12; measured 1e-14 for the linear beam,
    docs/beam_conditioning.md); unrefined it misses that by the eps N^3.5 rounding
    (measured 3e-7 at 2,000 elements)."""
    n, force, k3, dt = 2000, 1000.0, 7.5e8, 2e-4
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(2 * W1, 0.0))
    tip = beam.dof(f"w{n}")
    k = 3 * E * I / L ** 3
    roots = np.roots([k3, 0.0, k, -force])
    x_static = float(roots[np.abs(roots.imag) < 1e-12].real.max())
    f = force * ramp_and_hold(dt, 0.05, 0.3)
    err = {}
    for refine in (True, False):
        r = dd.nonlinear_beam_response(beam, f, dt, force_dofs=[tip], outputs=[tip],
                                       elements=[dd.Cubic(tip, k3=k3)], quantities=("x",),
                                       scheme="average_acceleration", refine=refine)
        assert r.info["refinements"] == (beam_mod.REFINE_CORRECTIONS if refine else 0)
        err[refine] = abs(r.x[-1, 0] / x_static - 1)
    assert err[True] < 1e-9, err
    assert err[False] > 1e-8, err      # the test tells the two apart


def test_beta_only_damping_is_no_longer_garbage_at_10000_elements():
    """C = beta K alone at 10,000 elements: the unrefined step is unstable there (its rounding
    breaks the damping's null space: the run overflows or ends far off), the refined one gives
    the static tip deflection L^3 / (3 EI) to 1e-6 (measured 7e-10 over 0.6 s,
    docs/beam_conditioning.md; here after 0.3 s of hold the overdamped high modes, which
    creep at w1 / 2, leave up to exp(-17) ~ 4e-8 of their start)."""
    n, dt = 10_000, 2e-4
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(0.0, 2 / W1))
    tip = beam.dof(f"w{n}")
    f = ramp_and_hold(dt, 0.05, 0.35)
    solver = beam.solver(dt, scheme="average_acceleration", outputs=[tip], quantities=("x",))
    r = solver.run(f, force_dofs=[tip])
    assert r.info["refinements"] == beam_mod.REFINE_CORRECTIONS     # "auto" at 10,000
    assert abs(r.x[-1, 0] / (L ** 3 / (3 * E * I)) - 1) < 1e-6


def _features_beam(n, **kw):
    return dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, left="pinned",
                   right=(1e6, 1e4), rayleigh=(1.0, 2e-5),
                   point_masses=[dd.PointMass(n // 3, 2.0, 0.1)],
                   supports=[dd.Support(2 * n // 3, k_w=1e6, c_w=50.0, c_psi=1.0)], **kw)


@pytest.mark.parametrize("elements", [False, True])
def test_auto_is_bitwise_the_unrefined_step_below_the_threshold(elements):
    n = 200
    assert n < beam_mod.REFINE_MIN_ELEMENTS
    beam = _features_beam(n)
    tip, mid = beam.dof(f"w{n // 2}"), beam.dof(f"psi{n // 4}")
    f = np.sin(0.07 * np.arange(301))[:, None] * [100.0, 5.0]
    kw = dict(force_dofs=[tip, mid], scheme="hht")
    if elements:
        run = lambda refine: dd.nonlinear_beam_response(  # noqa: E731
            beam, f, 1e-4, elements=[dd.Cubic(tip, k3=1e12)], refine=refine, **kw)
    else:
        run = lambda refine: dd.beam_response(beam, f, 1e-4, refine=refine, **kw)  # noqa: E731
    auto, off, on = run("auto"), run(False), run(True)
    assert auto.info["refinements"] == 0 and on.info["refinements"] > 0
    for q in "xva":
        assert getattr(auto, q).tobytes() == getattr(off, q).tobytes()
    # the plain step's rounding, about eps N^3.5 of the low modes (measured: 0.12 of it at
    # N = 50 and 200), is what the refined one removes
    scale = np.abs(off.x).max(axis=0)
    assert np.all(np.abs(on.x - off.x).max(axis=0) <= np.finfo(float).eps * n ** 3.5 * scale)


@pytest.mark.parametrize("scheme, form", [("newmark", "displacement"),
                                          ("generalized_alpha", "acceleration"),
                                          ("houbolt", "displacement")])
@pytest.mark.parametrize("mass_matrix", ["consistent", "lumped"])
def test_c_and_numpy_agree_when_refined(scheme, form, mass_matrix):
    n = 300
    beam = _features_beam(n, mass_matrix=mass_matrix)
    dofs = [beam.dof(f"w{n // 2}"), beam.dof(f"psi{n}")]
    f = np.sin(0.05 * np.arange(201))[:, None] * [100.0, 5.0]
    r = {b: dd.beam_response(beam, f, 2e-5, force_dofs=dofs, scheme=scheme, form=form,
                             backend=b, refine=True) for b in ("c", "numpy")}
    for q in "xv":
        a, b = getattr(r["c"], q), getattr(r["numpy"], q)
        # the two sum the residual in another order: they agree to the state's rounding
        assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max(), q


def test_nonlinear_c_and_numpy_agree_when_refined():
    n = 300
    beam = _features_beam(n)
    tip = beam.dof(f"w{n // 2}")
    f = 200.0 * np.sin(0.05 * np.arange(201))
    r = {b: dd.nonlinear_beam_response(beam, f, 2e-5, force_dofs=[tip], backend=b,
                                       elements=[dd.Cubic(tip, k3=1e13)], refine=True)
         for b in ("c", "numpy")}
    assert np.abs(r["c"].x - r["numpy"].x).max() <= 1e-11 * np.abs(r["c"].x).max()


@pytest.mark.parametrize("bad", ["yes", 1, None])
def test_refine_refuses_other_values(bad):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=4)
    with pytest.raises(ValueError, match="refine"):
        beam.solver(1e-4, refine=bad)
