"""Convergence order of every integrator (test tier 3 of shared/style.md).

Each scheme runs the DT-TMM chain solver (`chain_response`) over a dt sweep; the error against
`exact_response` is fitted as log(error) = p log(dt) + const and the slope p is compared with the
scheme's order (the generated module's ORDER: 1 for Fox-Euler, 2 for all others).

The truth: the schemes only see the force at the samples t_n (and, for HHT, generalized-alpha and
Wilson, its linear interpolation between two samples), so the problem they solve is the one with
the piecewise-linear interpolant of the force. `exact_response` is the exact solution of exactly
that problem (matrix exponential, first-order hold). Comparing with the continuous force instead
would add an O(dt^2) interpolation error that has nothing to do with the integrator.

Problems (shared/reference.md, section 7):
- P2, 2-DOF chain m = [2, 3], k = [20, 15], c = [5, 6], damped on every station (so central
  difference runs in acceleration form). Force F(t) = 1 - cos(2 t) on the last mass: smooth, and
  zero with zero slope at t = 0, so there is no start-up transient (a step force would also work
  here because the exact truth uses the same samples, but a smooth force keeps the test about the
  integrator, not about how a scheme starts on a discontinuous load).
  Natural frequencies 1.58 and 4.47 rad/s, longest period 4.0 s; T = 4 s.
  dt = T / 80 ... T / 1280 (omega_max dt = 0.22 ... 0.014: asymptotic range, and inside the
  central-difference limit omega dt < 2).
- P3, the undamped 15-DOF chain (Kumar & Sankar), unit step on mass 15, T = 0.8 s, for average
  acceleration; omega_max = 148.2 rad/s, so dt <= 2e-3 (omega_max dt <= 0.3) is asymptotic.

Error: max over time and over all outputs of |x - x_exact|, divided by max |x_exact|.

Tolerance on the slope: +-0.25. Measured slopes on P2 are within 0.02 of the order for every
scheme, form, backend and sweep (x: 0.990 for Fox-Euler, 2.000 +- 0.002 for the others; v: 0.981
for Fox-Euler, >= 1.991 for the others; pre-asymptotic curvature at the coarsest dt is the main
deviation); +-0.25 leaves room for that on other machines/BLAS while still failing
any scheme whose order drops by one (a wrong coefficient or a lagged force typically gives p ~ 1,
a constant bias gives p ~ 0). The fit uses 5 points, so one noisy point cannot move it by 0.25.
"""
from __future__ import annotations

import functools
import importlib

import numpy as np
import pytest

from dtdyn.generated import SCHEMES
from dtdyn.linear._chain import chain_matrices, chain_response
from dtdyn.linear._exact import exact_response
from dtdyn import problem

SLOPE_TOL = 0.25  # see the module docstring

# ---------------------------------------------------------------------------------------- P2
P2_MASS = [2.0, 3.0]
P2_STIFF = [20.0, 15.0]
P2_DAMP = [5.0, 6.0]
P2_T = 4.0
P2_OMEGA_F = 2.0  # forcing frequency of F(t) = 1 - cos(omega t), rad/s
P2_STEPS = (80, 160, 320, 640, 1280)
P2_LOADED = [1]  # last mass, 0-based

# ---------------------------------------------------------------------------------------- P3
P3_MASS, P3_STIFF = (problem("P3")[key] for key in ("mass", "stiffness"))
P3_T = 0.8
P3_DTS = (2e-3, 1e-3, 5e-4, 2.5e-4)


def scheme_module(name):
    return importlib.import_module(f"dtdyn.generated.scheme_{name}")


def p2_force(n_steps):
    dt = P2_T / n_steps
    t = dt * np.arange(n_steps + 1)
    return dt, (1.0 - np.cos(P2_OMEGA_F * t))[:, None]


@functools.cache
def p2_exact(n_steps):
    dt, force = p2_force(n_steps)
    M, C, K = chain_matrices(P2_MASS, P2_STIFF, P2_DAMP)
    return exact_response(M, C, K, force, dt, force_dofs=P2_LOADED)


def rel_error(approx, exact):
    """max_t max_outputs |approx - exact| / max |exact|."""
    return float(np.max(np.abs(approx - exact)) / np.max(np.abs(exact)))


def fitted_slope(dts, errors):
    dts, errors = np.asarray(dts), np.asarray(errors)
    assert np.all(np.isfinite(errors)) and np.all(errors > 0.0), errors
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


def p2_sweep(scheme, form, backend="c", sweep="stable", **params):
    """dts and the relative x, v errors of a scheme on P2 with the smooth force."""
    dts, ex, ev = [], [], []
    for n in P2_STEPS:
        dt, force = p2_force(n)
        res = chain_response(P2_MASS, P2_STIFF, P2_DAMP, force, dt, force_dofs=P2_LOADED,
                             scheme=scheme, form=form, sweep=sweep, backend=backend, **params)
        ref = p2_exact(n)
        assert res.x.shape == ref.x.shape == (n + 1, 2)
        dts.append(dt)
        ex.append(rel_error(res.x, ref.x))
        ev.append(rel_error(res.v, ref.v))
    return dts, ex, ev


def scheme_form_cases():
    cases = []
    for name in SCHEMES:
        for form in scheme_module(name).FORMS:
            cases.append(pytest.param(name, form, id=f"{name}-{form}"))
    return cases


def test_every_scheme_is_covered():
    # central difference is explicit: acceleration form only (reference.md sec. 3)
    assert scheme_module("central_difference").FORMS == ("acceleration",)
    assert len(scheme_form_cases()) == 2 * len(SCHEMES) - 1
    assert {scheme_module(s).ORDER for s in SCHEMES} == {1, 2}
    assert scheme_module("fox_euler").ORDER == 1


@pytest.mark.parametrize("backend, sweep", [("c", "stable"), ("numpy", "stable"), ("c", "plain")])
@pytest.mark.parametrize("scheme, form", scheme_form_cases())
def test_order_p2_smooth_force(scheme, form, backend, sweep):
    order = scheme_module(scheme).ORDER
    dts, ex, ev = p2_sweep(scheme, form, backend, sweep)
    px, pv = fitted_slope(dts, ex), fitted_slope(dts, ev)
    msg = (f"{scheme} ({form}, {backend}, {sweep}): slope x {px:.3f}, v {pv:.3f}, ORDER {order}; "
           f"x errors {np.array(ex)}")
    assert abs(px - order) <= SLOPE_TOL, msg
    assert abs(pv - order) <= SLOPE_TOL, msg
    # the errors also decrease at every halving and are far above round-off
    assert np.all(np.diff(ex) < 0.0), msg
    assert ex[-1] > 1e-12, msg
    # and they are small in absolute terms at the finest dt (omega_max dt = 0.014)
    assert ex[-1] < (1e-2 if order == 1 else 1e-4), msg


@pytest.mark.parametrize("scheme, params, order", [
    ("newmark", {"beta": 0.3, "gamma": 0.5}, 2),
    # gamma != 1/2 is first order (the derivation's notes say so; ORDER is per scheme = 2)
    ("newmark", {"beta": 0.3, "gamma": 0.6}, 1),
    ("newmark", {"beta": 0.0}, 2),  # resolves to central difference
    ("hht", {"alpha": -1.0 / 3.0}, 2),
    ("hht", {"alpha": 0.0}, 2),
    ("generalized_alpha", {"rho_inf": 0.0}, 2),
    ("generalized_alpha", {"rho_inf": 1.0}, 2),
    ("wilson", {"theta": 2.0}, 2),
], ids=lambda v: str(v).replace(" ", ""))
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
def test_order_p2_parameters(scheme, params, order, form):
    if params.get("beta") == 0.0 and form == "displacement":
        with pytest.raises(ValueError, match="explicit"):  # no displacement form exists
            p2_sweep(scheme, form, **params)
        return
    dts, ex, ev = p2_sweep(scheme, form, **params)
    px, pv = fitted_slope(dts, ex), fitted_slope(dts, ev)
    msg = f"{scheme} {params} ({form}): slope x {px:.3f}, v {pv:.3f}, expected {order}"
    assert abs(px - order) <= SLOPE_TOL, msg
    assert abs(pv - order) <= SLOPE_TOL, msg


def alpha_lag(scheme, params):
    """alpha_m - alpha_f of the Chung-Hulbert form (0 for schemes without alpha parameters).

    HHT: alpha_m = 0, alpha_f = -alpha. Generalized-alpha: alpha_m = (2 rho - 1)/(rho + 1),
    alpha_f = rho/(rho + 1) (reference.md sec. 4). Bossak: alpha_f = 0, alpha_m its parameter.
    """
    if scheme == "hht":
        return 0.0 - (-params.get("alpha", -0.05))
    if scheme == "generalized_alpha":
        rho = params.get("rho_inf", 0.8)
        return (2.0 * rho - 1.0) / (rho + 1.0) - rho / (rho + 1.0)
    if scheme == "bossak":  # alpha_f = 0
        return params.get("alpha_m", -0.1)
    return 0.0


@pytest.mark.parametrize("scheme", SCHEMES)
def test_acceleration_order_p2(scheme):
    """Accelerations converge at ORDER too, to q''(t_n + (alpha_m - alpha_f) dt) for the alpha
    methods: their a_n lags (or leads) the sampled acceleration by a fraction of a step, so
    against q''(t_n) they are only first order (Arnold & Bruls 2007, Multibody Syst. Dyn. 18;
    Erlicher, Bonaventura & Bursi 2002, Comput. Mech. 28). x and v are second order regardless.
    """
    module = scheme_module(scheme)
    form = "acceleration" if module.EXPLICIT else "displacement"
    lag = alpha_lag(scheme, {})
    dts, e_plain, e_shift = [], [], []
    for n in P2_STEPS:
        dt, force = p2_force(n)
        res = chain_response(P2_MASS, P2_STIFF, P2_DAMP, force, dt, force_dofs=P2_LOADED,
                             scheme=scheme, form=form, quantities=("a",))
        ref = p2_exact(n)
        jerk = np.gradient(ref.a, dt, axis=0)  # O(dt^2) accurate, multiplied by lag * dt below
        shifted = ref.a + lag * dt * jerk
        skip = 3  # np.gradient is one-sided at the ends; the first rows are the initial state
        dts.append(dt)
        e_plain.append(rel_error(res.a[skip:], ref.a[skip:]))
        e_shift.append(rel_error(res.a[skip:], shifted[skip:]))
    p_shift = fitted_slope(dts, e_shift)
    assert abs(p_shift - module.ORDER) <= SLOPE_TOL, (scheme, p_shift)
    if lag != 0.0:
        p_plain = fitted_slope(dts, e_plain)
        assert abs(p_plain - 1.0) <= SLOPE_TOL, (scheme, p_plain)


# ---------------------------------------------------------------------------------------- P3
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
def test_order_p3_average_acceleration(form):
    """P3 (undamped 15-DOF, unit step on mass 15) with average acceleration, dt = 2e-3 ... 2.5e-4.

    The step is the force the papers use; the truth uses the same (constant) samples, so it is
    exact for it. Measured local slopes 1.99, 2.00, 2.00 (at dt = 4e-3 the first one would be 1.94:
    omega_max dt = 0.6 is not yet asymptotic, which is why the sweep starts at 2e-3).
    """
    M, C, K = chain_matrices(P3_MASS, P3_STIFF, np.zeros(15))
    errors, last = [], []
    for dt in P3_DTS:
        n = int(round(P3_T / dt))
        force = np.ones((n + 1, 1))
        res = chain_response(P3_MASS, P3_STIFF, np.zeros(15), force, dt, force_dofs=[14],
                             scheme="average_acceleration", form=form, quantities=("x",))
        ref = exact_response(M, C, K, force, dt, force_dofs=[14])
        assert res.x.shape == ref.x.shape == (n + 1, 15)
        errors.append(rel_error(res.x, ref.x))
        last.append(rel_error(res.x[:, 14], ref.x[:, 14]))
    p, p_last = fitted_slope(P3_DTS, errors), fitted_slope(P3_DTS, last)
    assert abs(p - 2.0) <= SLOPE_TOL, (p, errors)
    assert abs(p_last - 2.0) <= SLOPE_TOL, (p_last, last)
    assert errors[-1] < 1e-4, errors


def test_p3_central_difference_acceleration_form_needs_damping():
    # P3 is undamped: the explicit scheme's acceleration-form spring row divides by c Dv = 0
    force = np.ones((11, 1))
    with pytest.raises(ValueError, match="damping"):
        chain_response(P3_MASS, P3_STIFF, np.zeros(15), force, 1e-3, force_dofs=[14],
                       scheme="central_difference", form="acceleration")
