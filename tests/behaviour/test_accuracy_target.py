"""The accuracy target of nonlinear_mck_response (`accuracy=`) against independent
truths: the solve_ivp reference (DOP853, rtol 1e-12, restarted at every sample) for P4, Bouc-Wen
and the gap, solve_ivp directly for the Duffing oscillator released from x0, v0.

Error measure, the same as the estimate's: for each stored quantity the largest |x - x_ref|
over time and columns relative to the largest |x_ref|, the largest over the quantities.
The claims: the returned solution is within ``accuracy`` of the truth, and its estimate within a
factor 3 of its true error, where the scheme's order holds (smooth elements); where it does not
(the gap's kink, Bouc-Wen's |z| and sign(y')), each test says what is measured instead.
"""
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from dtdyn import DtdynAccuracyWarning, DtdynStepStabilityError, NewtonError
from dtdyn.nonlinear import _accuracy as acc
from dtdyn.nonlinear._elements import BoucWen, Cubic, Gap
from dtdyn.nonlinear._reference import reference_response
from dtdyn.nonlinear._response import nonlinear_mck_response
from problems import p4

#: P4 shortened to 20,000 samples (20 s at 1 kHz) to keep the CasADi backend's runs short
N_P4 = 20_000


def error(r, ref, quantities="xva"):
    return max(np.abs(getattr(r, q) - getattr(ref, q)).max() / np.abs(getattr(ref, q)).max()
               for q in quantities if getattr(r, q) is not None)


def check(r, ref, accuracy, quantities="xva"):
    """Within the target, and the estimate within a factor 3 of the true error."""
    e, est = error(r, ref, quantities), r.info["error_estimate"]
    assert r.info["accuracy_met"] and est <= accuracy
    assert e <= accuracy, (e, r.info)
    assert e / 3 <= est <= 3 * e, (est, e, r.info["substeps"], r.info["extrapolated"])
    return e, est


@pytest.fixture(scope="module")
def P4():
    P = p4(N_P4)
    P["args"] = (P["M"], P["C"], P["K"], P["force"], P["dt"])
    P["kw"] = dict(force_dofs=P["force_dofs"], elements=P["elements"])
    P["ref"] = reference_response(*P["args"], **P["kw"], cache=False)
    return P


# --- P4 -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("scheme, order", [("modal_ramp", 2), ("modal_parabolic", 3),
                                           ("newmark", 2)])
def test_p4_observed_order_is_the_one_the_estimate_assumes(P4, scheme, order):
    """The Richardson estimate |x_2S - x_S| / (2^p - 1) needs the order p the scheme states:
    measured on P4 against the reference at 2, 4, 8 sub-steps (log2 of successive error ratios:
    2.00, 3.00, 1.97-1.99 measured)."""
    errs = [error(nonlinear_mck_response(*P4["args"], **P4["kw"], scheme=scheme, substeps=S,
                                     quantities=("x",)), P4["ref"], "x") for S in (2, 4, 8)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - order) <= 0.1), orders


@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_p4_accuracy_1e6(P4, backend):
    """modal_parabolic: runs at 1, 2, 4, 8 sub-steps; the extrapolation of the 4 and 8 runs is
    returned (observed orders 3.0 of the runs, 4 of the extrapolations): 1.1e-8 true, 1.1e-8
    estimated, on both backends."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="modal_parabolic", accuracy=1e-6,
                           backend=backend)
    check(r, P4["ref"], 1e-6)
    assert r.info["backend"] == backend
    assert abs(r.info["observed_order"] - 3) <= 0.25


@pytest.mark.parametrize("scheme", ["modal_ramp", "newmark"])
def test_p4_accuracy_1e6_second_order_schemes(P4, scheme):
    """Second-order schemes, both symmetric (even powers only): their extrapolations show order
    4 = p + 2; the estimate takes it only when two successive levels show it (newmark: 1.00x
    measured), else q = p + 1 = 3, high by up to (2^4 - 1) / (2^3 - 1) = 2.14 (modal_ramp:
    2.14x measured): inside the factor 3, on the safe side."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme=scheme, accuracy=1e-6)
    e, est = check(r, P4["ref"], 1e-6)
    assert r.info["extrapolated"] and 0.9 <= est / e <= 2.2


def test_p4_accuracy_1e3_is_the_plain_run_at_two_substeps(P4):
    """1e-3: the 2-sub-step run with the estimate from the 1-sub-step run (7.4e-5 estimated,
    7.6e-5 true): the very run substeps=2 gives, bit for bit (tol keeps its meaning)."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="modal_parabolic", accuracy=1e-3)
    check(r, P4["ref"], 1e-3)
    assert r.info["substeps"] == 2 and not r.info["extrapolated"]
    plain = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="modal_parabolic", substeps=2)
    for q in "xva":
        np.testing.assert_array_equal(getattr(r, q), getattr(plain, q))
    assert r.info["estimate_substeps"] == [1, 2]


@pytest.mark.parametrize("substeps", [1, 4])
def test_error_estimate_without_a_target(P4, substeps):
    """estimate=True: the run asked for, with its error estimated from 2 S (S odd: the
    coarse run, |d| 2^p / (2^p - 1)) or S / 2 (S even: the fine run, |d| / (2^p - 1))."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="modal_parabolic", substeps=substeps,
                           estimate=True)
    assert r.info["substeps"] == substeps
    e, est = error(r, P4["ref"]), r.info["error_estimate"]
    assert e / 3 <= est <= 3 * e, (e, est)


# --- Duffing, released from x0, v0 --------------------------------------------------------------

@pytest.fixture(scope="module")
def duffing():
    from scipy.integrate import solve_ivp

    m, c, k, k3, a0, b0 = 1.0, 2.0, 1e4, 1e9, 1e-2, -0.5
    t = np.arange(501) * 1e-3
    sol = solve_ivp(lambda _, y: [y[1], -(c * y[1] + k * y[0] + k3 * y[0] ** 3) / m],
                    (0.0, t[-1]), [a0, b0], method="DOP853", rtol=1e-12, atol=1e-15, t_eval=t)

    class Ref:
        x, v, a = sol.y[0][:, None], sol.y[1][:, None], None

    def run(**kw):
        return nonlinear_mck_response([[m]], [[c]], [[k]], np.zeros(501), 1e-3,
                                  elements=[Cubic(0, k3=k3)], x0=[a0], v0=[b0],
                                  quantities=("x", "v"), **kw)
    return run, Ref


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize("scheme", ["modal_ramp", "newmark"])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_duffing(duffing, scheme, backend, accuracy):
    """k3 x0^2 = 10 k: strongly nonlinear; 8 to 32 sub-steps, extrapolated (estimate high by
    2.1, as on P4)."""
    run, ref = duffing
    check(run(scheme=scheme, backend=backend, accuracy=accuracy), ref, accuracy, "xv")


def test_duffing_modal_parabolic_1e6(duffing):
    """modal_parabolic released from x0 != 0, its force parabola's g_{-1} from the motion's
    continuation (dtdyn.nonlinear._startup): third order from the start (3.00 observed between 4
    and 64 sub-steps); its extrapolation shows order ~6 at two successive levels (5.97, 5.91),
    which the estimate then takes: 1e-6 at 32 sub-steps, extrapolated, 9.8e-8 true, estimate
    2.1x."""
    run, ref = duffing
    r = run(scheme="modal_parabolic", accuracy=1e-6)
    check(r, ref, 1e-6, "xv")
    assert r.info["extrapolated"]


@pytest.mark.xfail(strict=True, reason="one observation of the extrapolation's order (5.97 at 16 "
                   "sub-steps) is not trusted (Bouc-Wen's kinks showed 3.96 once), so q = p + 1 "
                   "= 4: the estimate is 3.2x above the true 3.1e-6 (the safe side)")
def test_duffing_modal_parabolic_1e3(duffing):
    run, ref = duffing
    check(run(scheme="modal_parabolic", accuracy=1e-3), ref, 1e-3, "xv")


def test_duffing_modal_parabolic_1e3_is_met(duffing):
    """What the xfail above leaves: 1e-3 is met (3.1e-6), the estimate high, never low."""
    run, ref = duffing
    r = run(scheme="modal_parabolic", accuracy=1e-3)
    e = error(r, ref, "xv")
    assert r.info["accuracy_met"] and e <= r.info["error_estimate"] <= 4 * e <= 4e-3


def test_duffing_past_forces_restore_the_order(duffing):
    """A constant g_{-1} = g_0 leaves the parabola an O(h) error at the first step and the
    observed order falls towards 2; with the motion's continuation it is 3 at every level
    (against the solve_ivp reference)."""
    run, ref = duffing
    errs = [error(run(scheme="modal_parabolic", substeps=S), ref, "xv") for S in (8, 16, 32, 64)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 3) <= 0.05), orders


# --- impact: a gap --------------------------------------------------------------------------

def _gap(smoothing, stiffness=1e6, gap=0.05, c=10.0):
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[c]])
    fs, n = 100.0, 200
    f = (1e3 * np.sin(2 * np.pi * 5 * np.arange(n) / fs))[:, None]
    els = [Gap(0, gap=gap, stiffness=stiffness, smoothing=smoothing)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, cache=False)

    def run(**kw):
        return nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, **kw)
    return run, ref


@pytest.mark.parametrize("scheme", ["newmark", "modal_ramp"])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_impact_with_a_kink(scheme, accuracy):
    """Contact at 100 times the linear stiffness, no smoothing: g has a kink at the contact, so
    the second order breaks down (observed 0.8 to 2.5 between 8 and 256 sub-steps against the
    reference). The extrapolation is refused (its observed order is not above p + 0.5 or the
    runs' order is not within 0.25 of p) and the plain estimate with the observed order
    min(p, p_obs) is returned: within the target and within 3x (ratios 1.06 to 1.9 measured),
    at 256 to 1024 (1e-3) and 8192 to 32768 (1e-6) sub-steps."""
    run, ref = _gap(0.0)
    for quantities in (("x",), ("x", "v", "a")):
        r = run(scheme=scheme, accuracy=accuracy, max_substeps=2**15, quantities=quantities)
        check(r, ref, accuracy, quantities)
        assert not r.info["extrapolated"]


def test_impact_smoothed():
    """The same gap with a smooth contact (smoothing 1e-3): second order again (1.96-2.00
    observed), the extrapolation is used (of the 512 and 1024 sub-step runs: x, v and a to
    1e-6 need more than 256 sub-steps)."""
    run, ref = _gap(1e-3)
    r = run(scheme="newmark", accuracy=1e-6, max_substeps=4096)
    check(r, ref, 1e-6)
    assert r.info["extrapolated"]


def test_impact_beyond_reach_warns():
    """The stiff gap of test_nonlinear.py (1e12 N/m, 1 % damping): 1 and 2 sub-steps fail
    (NewtonError) and restart the sequence at 4; no sub-step count up to 256 converges (observed
    orders at or below 0: the errors against the reference stay O(1)), and the warning says so
    instead of returning a result that claims the target."""
    run, ref = _gap(1e-4, stiffness=1e12, gap=1e-2, c=2.0)
    with pytest.warns(DtdynAccuracyWarning,
                      match=r"accuracy=0.001 not reached: the error estimate is .* at \d+ "
                            r"sub-steps \(max_substeps=256"):
        r = run(scheme="newmark", accuracy=1e-3, max_substeps=256, quantities=("x",))
    assert not r.info["accuracy_met"] and r.info["error_estimate"] > 1e-3
    assert error(r, ref, "x") > 1e-3                     # the warning is right
    notes = [e["note"] for e in r.info["accuracy_log"] if e["note"]]
    assert notes[0].startswith("NewtonError: restarted at 2 sub-steps")


# --- Bouc-Wen -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def bouc_wen():
    M, K, C = np.array([[1.0]]), np.array([[100.0]]), np.array([[0.5]])
    fs, n = 200.0, 1000
    f = (50.0 * np.sin(2 * np.pi * np.arange(n) / fs))[:, None]
    els = [BoucWen(0, stiffness=1e4, alpha=0.1, beta=50.0, gamma=50.0)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, cache=False)

    def run(**kw):
        return nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, **kw)
    return run, ref


@pytest.mark.parametrize("scheme", ["modal_ramp", "newmark"])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_bouc_wen(bouc_wen, scheme, accuracy):
    """Bouc-Wen (n = 1: |z| and sign(y') in z'): the runs show order 2.0, the extrapolations less
    than the smooth 4: at 1e-6 (128 sub-steps) the estimate is 2.0x below the true 4.2e-7,
    at 1e-3 (16 sub-steps) 2.4-2.5x above it; within the target and the factor 3."""
    run, ref = bouc_wen
    check(run(scheme=scheme, accuracy=accuracy), ref, accuracy)


def test_bouc_wen_modal_parabolic_runs_at_second_order(bouc_wen):
    """modal_parabolic on Bouc-Wen is second order, not third (observed 2.02-2.05): the estimate
    uses the observed order (ratio 0.93 measured at 1e-3, 32 sub-steps) and the extrapolation is
    refused; 1e-6 would need about 500 sub-steps, so a cap of 64 warns with what it reached."""
    run, ref = bouc_wen
    r = run(scheme="modal_parabolic", accuracy=1e-3)
    check(r, ref, 1e-3)
    assert not r.info["extrapolated"] and abs(r.info["observed_order"] - 2) <= 0.25
    with pytest.warns(DtdynAccuracyWarning, match=r"accuracy=1e-06 not reached.*at 64 sub-steps"):
        r = run(scheme="modal_parabolic", accuracy=1e-6, max_substeps=64)
    assert not r.info["accuracy_met"] and r.info["substeps"] == 64


# --- bad input ----------------------------------------------------------------------------------

@pytest.mark.parametrize("bad", [0, 0.0, -1e-6, np.nan, np.inf, "1e-6", True, [1e-6]])
def test_bad_accuracy_is_named(P4, bad):
    named = r"^accuracy must be (a number \(a relative error such as 1e-6\)|finite and > 0), got "
    with pytest.raises(ValueError, match=named):
        nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=bad)


def test_bad_max_substeps_and_unknown_order(P4):
    with pytest.raises(ValueError, match="max_substeps"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=1e-6, max_substeps=0)
    with pytest.raises(ValueError, match=r"substeps \(8\) must be <= max_substeps \(4\)"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=1e-6, substeps=8, max_substeps=4)
    with pytest.raises(ValueError, match="scheme 'nonsense' has no known order"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=1e-6, scheme="nonsense")


def test_cap_warns_with_target_estimate_and_substeps(P4):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DtdynAccuracyWarning,
                           match=r"accuracy=1e-12 not reached: the error estimate is "
                                 r"[0-9.e-]+ at 4 sub-steps \(max_substeps=4"):
            nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=1e-12, max_substeps=4)


def test_estimate_keyword_is_a_bool_and_the_old_name_is_named(P4):
    with pytest.raises(ValueError, match=r"estimate must be True or False, got 1e-06"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], estimate=1e-6)
    with pytest.raises(TypeError, match="'error_estimate'; did you mean 'estimate'"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], error_estimate=True)


def test_accuracy_with_estimate_true_is_the_accuracy_run(P4):
    """accuracy always reports the estimate: estimate=True beside it changes nothing."""
    kw = dict(P4["kw"], scheme="modal_parabolic", accuracy=1e-3)
    a = nonlinear_mck_response(*P4["args"], **kw)
    b = nonlinear_mck_response(*P4["args"], **kw, estimate=True)
    for q in "xva":
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q))
    assert a.info["error_estimate"] == b.info["error_estimate"]


# --- non-finite runs, failing companions ------------------------------------------------------

def _fake(S, nan=False):
    """A stand-in Response: x = sin(t) + h^2 cos(3t) + h^3 sin(2t) (second order, its
    extrapolation third), NaN at one sample if asked."""
    t = np.linspace(0.0, 1.0, 101)[:, None]
    x = np.sin(t) + (1.0 / S) ** 2 * np.cos(3 * t) + (1.0 / S) ** 3 * np.sin(2 * t)
    if nan:
        x[50, 0] = np.nan
    return SimpleNamespace(x=x, v=None, a=None, g=None, z=None, a_abs=None, x_abs=None,
                           info={"substeps": S})


def test_a_nan_is_never_agreement():
    """max(worst, nan) is worst in Python: a NaN in either run must give inf, not 0."""
    a, b = _fake(4), _fake(4, nan=True)
    assert acc.difference(a, a) == 0.0
    assert acc.difference(a, b) == np.inf and acc.difference(b, a) == np.inf
    both = _fake(4, nan=True)
    assert acc.difference(both, both) == np.inf        # NaN == NaN is no agreement either
    a.v, b.v = a.x.copy(), a.x.copy()                    # a later quantity cannot hide it
    assert acc.difference(a, b) == np.inf


def test_a_nan_run_is_never_reported_as_met():
    """The 2-sub-step run has a NaN: its estimate is inf and the sequence goes on; when every
    run has one, the cap warning fires with an infinite estimate."""
    r = acc.reach(lambda S: _fake(S, nan=S == 2), 1e-3, 1, 256, "newmark", {})
    log = {e["substeps"]: e["estimate"] for e in r.info["accuracy_log"]}
    assert log[2] == np.inf and r.info["accuracy_met"] and r.info["substeps"] > 2
    assert np.isfinite(r.x).all()
    with pytest.warns(DtdynAccuracyWarning, match=r"the error estimate is inf at"):
        r = acc.reach(lambda S: _fake(S, nan=True), 1e-3, 1, 8, "newmark", {})
    assert not r.info["accuracy_met"] and r.info["error_estimate"] == np.inf
    r = acc.estimate_only(lambda S: _fake(S, nan=S == 2), 4, "newmark", {})
    assert r.info["error_estimate"] == np.inf


def _stiff_gap(stiffness):
    """A gap 2000 times the linear stiffness at 1 kHz: modal_ramp at 1 sub-step is beyond its
    stability limit for 2e7 N/m (2 passes), at 1 and 2 for 1e8 (4 passes)."""
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    f = (1e3 * np.sin(2 * np.pi * 5 * np.arange(1000) / 1000.0))[:, None]
    els = [Gap(0, gap=1e-2, stiffness=stiffness)]

    def run(**kw):
        return nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[0], elements=els,
                                  scheme="modal_ramp", quantities=("x",), **kw)
    return run


def test_estimate_falls_back_to_2s_when_the_half_run_is_unstable():
    """substeps=2 runs; its S / 2 = 1 companion is beyond the stability limit, so the estimate
    comes from 4 (the coarse-run formula), and the result is the 2-sub-step run bit for bit."""
    run = _stiff_gap(2e7)
    with pytest.raises(DtdynStepStabilityError):
        run(substeps=1)
    r = run(substeps=2, estimate=True)
    plain, fine = run(substeps=2), run(substeps=4)
    np.testing.assert_array_equal(r.x, plain.x)
    assert r.info["substeps"] == 2 and r.info["estimate_substeps"] == [2, 4]
    d = np.abs(plain.x - fine.x).max() / np.abs(plain.x).max()
    assert r.info["error_estimate"] == d * 4 / 3


def test_estimate_names_the_companions_when_both_fail():
    def run(S):
        if S != 4:
            raise NewtonError(f"step 7 did not converge at {S} sub-steps")
        return _fake(S)
    with pytest.raises(NewtonError, match=r"run at 4 sub-steps succeeded but its companion run "
                                          r"failed at 2 and 8 sub-steps") as err:
        acc.estimate_only(run, 4, "newmark", {})
    assert isinstance(err.value.__cause__, NewtonError)
    with pytest.raises(NewtonError, match=r"companion run failed at 6 sub-steps"):
        acc.estimate_only(lambda S: _fake(S) if S == 3 else run(S), 3, "newmark", {})


def test_every_run_unstable_raises_the_stability_error():
    """1 and 2 sub-steps are both beyond the limit with max_substeps=2: the stability error
    itself (chained), naming the target and the sub-steps tried, not a NewtonError."""
    run = _stiff_gap(1e8)
    with pytest.raises(DtdynStepStabilityError,
                       match=r"accuracy=0.001: no run succeeded at 1, 2 sub-steps "
                             r"\(max_substeps=2\)") as err:
        run(accuracy=1e-3, max_substeps=2)
    assert isinstance(err.value.__cause__, DtdynStepStabilityError)
    assert not isinstance(err.value, NewtonError)


def test_lazy_extrapolation_builds_only_what_is_compared(monkeypatch):
    """The extrapolation is built only for the levels whose difference is measured: none while
    the observed order is off, and each level at most once."""
    built = []
    real = acc._extrapolate

    def counting(fine, coarse, factor):
        built.append(fine.info["substeps"])
        return real(fine, coarse, factor)
    monkeypatch.setattr(acc, "_extrapolate", counting)
    with pytest.warns(DtdynAccuracyWarning):
        r = acc.reach(lambda S: _fake(S), 1e-12, 1, 64, "newmark", {})
    assert sorted(built) == [4, 8, 16, 32, 64] and r.info["extrapolated"]
    built.clear()

    def first_order(S):                      # observed order 1, p = 2: never extrapolated
        out = _fake(S)
        out.x = out.x + (1.0 / S) * np.cos(5 * out.x)
        return out
    with pytest.warns(DtdynAccuracyWarning):
        acc.reach(first_order, 1e-12, 1, 16, "newmark", {})
    assert built == []


# --- modal_quintic: the embedded estimate ------------------------------------------------------

@pytest.mark.parametrize("scheme", ["modal_quintic", "modal_explicit"])
@pytest.mark.parametrize("substeps", [1, 2])
def test_p4_polynomial_embedded_estimate_within_3x(P4, scheme, substeps):
    """Every C run of modal_quintic and modal_explicit estimates its own error (the next term of
    the force polynomial carried by the dynamics linearized with the elements' tangent
    stiffness): within 3x of the true error on P4 (quintic 0.98x and 0.97x measured at 1 and 2
    sub-steps, 0.6-0.7x when the local errors were carried by the linear modes alone; explicit
    1.02x and 1.01x, true errors 4.8e-5 and 3.8e-7)."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme=scheme, substeps=substeps)
    e, est = error(r, P4["ref"]), r.info["error_estimate"]
    assert r.info["error_estimate_kind"] == "embedded"
    assert e / 3 <= est <= 3 * e, (e, est)


@pytest.mark.parametrize("scheme, substeps", [("modal_quintic", {1e-3: 1, 1e-6: 2}),
                                              ("modal_explicit", {1e-3: 1, 1e-6: 2})])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_p4_polynomial_accuracy(P4, accuracy, scheme, substeps):
    """accuracy= with modal_quintic or modal_explicit on a record of 20,000 samples: the first
    2,000 run at 1 and 2 sub-steps, the second run confirms the first's estimate (their
    difference within 3x of it), and the record then runs once, at the sub-steps whose window
    estimate is 10x below the target, its own estimate trusted: quintic at 1 (1e-3, 4.7e-6
    true) and 2 (1e-6, 7.6e-8 true), explicit at 1 (4.8e-5) and 2 (3.8e-7); estimates 0.97x to
    1.02x the true error."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme=scheme, accuracy=accuracy)
    check(r, P4["ref"], accuracy)
    S = substeps[accuracy]
    assert r.info["substeps"] == S and r.info["estimate_substeps"] == [S]
    assert r.info["estimate_window"] == {"samples": 2000, "substeps": [1, 2]}
    assert [e["substeps"] for e in r.info["accuracy_log"]] == [1, 2, S]


def test_p4_record_beyond_the_window_runs_again(P4, monkeypatch):
    """Without the margin, the window's estimate at 1 sub-step (1.1e-5) meets 2e-5 but the
    record's (4.9e-5) does not: the record runs again at 2 sub-steps, which confirms the first
    run's estimate, and is returned (two runs of the record, as without a window)."""
    monkeypatch.setattr(acc, "PROBE_MARGIN", 1.0)
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="modal_explicit", accuracy=2e-5)
    check(r, P4["ref"], 2e-5)
    assert r.info["substeps"] == 2 and r.info["estimate_substeps"] == [1, 2]
    assert "estimate_window" not in r.info
    assert [e["substeps"] for e in r.info["accuracy_log"]] == [1, 2, 1, 2]


@pytest.mark.parametrize("scheme", ["modal_quintic", "modal_explicit"])
def test_p4_polynomial_accuracy_on_casadi(scheme):
    """The casadi backend has no embedded estimate: the polynomial methods' own Richardson
    sequence, trusted only from three levels (their nominal orders 6 and 7 are not assumed from
    two runs). P4 over 2,000 samples at 1e-6: 4 sub-steps (runs 1, 2, 4), 2.9e-10 and 6.8e-10
    true, estimates 1.03x and 1.04x."""
    P = p4(2000)
    args, kw = (P["M"], P["C"], P["K"], P["force"], P["dt"]), dict(
        force_dofs=P["force_dofs"], elements=P["elements"])
    ref = reference_response(*args, **kw, cache=False)
    r = nonlinear_mck_response(*args, **kw, scheme=scheme, accuracy=1e-6, backend="casadi")
    check(r, ref, 1e-6)
    assert r.info["backend"] == "casadi" and r.info["estimate_substeps"][:3] == [1, 2, 4]


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_duffing_quintic(duffing, accuracy):
    """Released from x0, v0 (k3 x0^2 = 10 k): the 1-sub-step run is far outside the asymptotic
    range (error 0.21, embedded estimate 76), so the difference to the next run does not
    confirm its estimate and the Richardson sequence takes over: 1e-3 at 4 sub-steps (6.0e-6
    true, estimate 1.8x), 1e-6 at 8 (5.6e-8, 1.7x)."""
    run, ref = duffing
    check(run(scheme="modal_quintic", accuracy=accuracy), ref, accuracy, "xv")


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_duffing_explicit(duffing, accuracy):
    """modal_explicit released from x0, v0: the 1-sub-step run is beyond its stability limit
    (theta 0.35 > 0.264), so its own Richardson sequence runs, trusted only from three levels
    (the order they show): 1e-3 at 8 sub-steps (3.0e-6 true, estimate 1.26x), 1e-6 at 16
    (2.3e-8, 1.26x)."""
    run, ref = duffing
    check(run(scheme="modal_explicit", accuracy=accuracy), ref, accuracy, "xv")


@pytest.mark.parametrize("scheme", ["modal_quintic", "modal_explicit"])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_bouc_wen_polynomial(bouc_wen, accuracy, scheme):
    """Bouc-Wen's kinks (sign(y'), |z|) and its trapezoidal z: the embedded estimate is not
    confirmed, the Richardson sequence reaches the target (32 and 1024 sub-steps, estimate
    0.94x and 0.98x the true error measured, with either method; modal_explicit solves only
    z there, w = Q)."""
    run, ref = bouc_wen
    r = run(scheme=scheme, accuracy=accuracy, max_substeps=4096)
    check(r, ref, accuracy)


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_impact_smoothed_quintic(accuracy):
    """The smoothed contact: the embedded estimate is refused for lack of confirmation (runs
    below 16 sub-steps exceed the stability limit), the Richardson sequence reaches both
    targets (estimate 1.6x and 1.4x the true error measured)."""
    run, ref = _gap(1e-3)
    check(run(scheme="modal_quintic", accuracy=accuracy, max_substeps=4096), ref, accuracy)


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_impact_smoothed_explicit(accuracy):
    """The smoothed contact with modal_explicit: every run below 32 sub-steps exceeds its
    stability limit (theta 106 at 1 sub-step, 0.33 at 16), so its own Richardson sequence runs
    from 32, trusted only from three levels. 1e-6: 256 sub-steps, 9.7e-8 true, estimate 0.87x.
    1e-3: 128 sub-steps, 9.5e-6 true, estimate 5.6x on the safe side (the runs' observed order
    between 32, 64 and 128 is below the smooth 7); with two levels the estimate had assumed
    order 7 and returned 64 sub-steps at 1.05e-3, 0.17x."""
    run, ref = _gap(1e-3)
    r = run(scheme="modal_explicit", accuracy=accuracy, max_substeps=4096)
    if accuracy < 1e-4:
        check(r, ref, accuracy)
        return
    e, est = error(r, ref), r.info["error_estimate"]
    assert r.info["accuracy_met"] and e <= est <= min(accuracy, 6 * e), (e, est)


# --- scheme "auto": the method picked for the target ---------------------------------------------

@pytest.mark.parametrize("accuracy, substeps", [(1e-3, 1), (1e-6, 2)])
def test_auto_p4(P4, accuracy, substeps):
    """Without a scheme, accuracy= picks modal_explicit: on the record's first 2,000 samples
    the 2-sub-step run confirms the 1-sub-step run's estimate (1.1e-5), the record runs once at
    the sub-steps that window puts 10x below the target, and its own embedded estimate, at or
    below the target, is returned: 1 sub-step for 1e-3 (4.8e-5 true), 2 for 1e-6 (3.8e-7
    true), estimates 1.02x and 1.01x."""
    r = nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=accuracy)
    e, est = check(r, P4["ref"], accuracy)
    assert r.info["scheme"] == "modal_explicit" and r.info["substeps"] == substeps
    assert r.info["estimate_substeps"] == [substeps]
    assert 0.8 <= est / e <= 1.2


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_auto_duffing(duffing, accuracy):
    """modal_explicit's 1-sub-step run is beyond its stability limit, modal_quintic's estimate
    at 1 sub-step (249) is not confirmed (the difference to the next run is 0.21):
    modal_ramp's Richardson sequence takes over. Measured, both extrapolated: 8
    sub-steps, 1.4e-5 true, estimate 2.11x (1e-3: the extrapolation's order seen at one level
    only, so q = p + 1); 16, 8.9e-7, 1.00x (1e-6)."""
    run, ref = duffing
    r = run(accuracy=accuracy)
    e, est = check(r, ref, accuracy, "xv")
    assert r.info["scheme"] == "modal_ramp" and 0.8 <= est / e <= 2.2
    schemes = [entry["scheme"] for entry in r.info["accuracy_log"]]
    assert schemes[0] == "modal_explicit" and schemes[-1] == "modal_ramp"
    assert "modal_quintic" in schemes


@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_auto_bouc_wen(bouc_wen, accuracy):
    """Bouc-Wen's kinks: modal_ramp after the unconfirmed quintic estimate. Measured: 16
    sub-steps, 7.3e-5 true, 2.50x (1e-3); 128, 4.1e-7, 0.49x (1e-6), both extrapolated."""
    run, ref = bouc_wen
    r = run(accuracy=accuracy, max_substeps=4096)
    e, est = check(r, ref, accuracy)
    assert r.info["scheme"] == "modal_ramp" and 0.4 <= est / e <= 2.6


def test_window_that_fails_hands_over(monkeypatch):
    """A window of the smoothed gap's first 25 samples (shrunk from 2,000 so that the
    200-sample record has one): modal_explicit's and modal_quintic's window runs at 1 sub-step
    are beyond their stability limits, so each hands over at once (the window is the record's
    start: the record's run would fail there too) and modal_ramp's Richardson sequence returns
    what it returns without a window: 512 sub-steps, 2.1e-7 true, estimate 1.01x."""
    monkeypatch.setattr(acc, "PROBE_SAMPLES", 25)
    run, ref = _gap(1e-3)
    r = run(accuracy=1e-6)
    check(r, ref, 1e-6)
    assert r.info["scheme"] == "modal_ramp" and r.info["substeps"] == 512
    log = [(e["scheme"], e["note"]) for e in r.info["accuracy_log"]]
    assert log[:2] == [("modal_explicit", "window of 25 samples: DtdynStepStabilityError"),
                       ("modal_quintic", "window of 25 samples: DtdynStepStabilityError")]


@pytest.mark.parametrize("accuracy, substeps, high", [(1e-3, 3, 10.0), (1e-6, 7, 3.0)])
def test_window_at_a_strongly_nonlinear_start(duffing, monkeypatch, accuracy, substeps, high):
    """What one trusted run gives where the window is not the record: the Duffing oscillator
    released from x0, v0 with a window of its first 50 samples (shrunk from 2,000 so that the
    501-sample record has one). modal_explicit's window run is beyond its stability limit;
    modal_quintic's window runs at 1, 2, 3 (1e-3) and 1, 6, 7 sub-steps (1e-6) confirm its
    estimates, and the record runs once. Its estimate is high: 8.8x the true 4.0e-5 at 3
    sub-steps for 1e-3 (the record's decay takes it away from the window's regime, as the
    two-run confirmation of a record without a window would have shown: its 1-sub-step
    estimate, 249, is not confirmed), 2.4x the true 1.2e-7 at 7 sub-steps for 1e-6. On the
    safe side: the target is met, the estimate above the true error."""
    monkeypatch.setattr(acc, "PROBE_SAMPLES", 50)
    run, ref = duffing
    r = run(accuracy=accuracy)
    e, est = error(r, ref, "xv"), r.info["error_estimate"]
    assert r.info["scheme"] == "modal_quintic" and r.info["substeps"] == substeps
    assert r.info["estimate_window"]["samples"] == 50
    assert r.info["accuracy_met"] and e <= est <= accuracy and est <= high * e, (e, est)


def test_no_window_for_kinks(bouc_wen, monkeypatch):
    """Bouc-Wen's sign(y') and |z|: a kink that a window of the record's start may not reach
    would leave the record's estimate unchecked, so its runs never take a window (here one of
    100 samples would fit the 1,000-sample record) and each estimate is confirmed on the
    record."""
    monkeypatch.setattr(acc, "PROBE_SAMPLES", 100)
    run, ref = bouc_wen
    r = run(accuracy=1e-3, max_substeps=4096)
    check(r, ref, 1e-3)
    assert not any((e["note"] or "").startswith("window") for e in r.info["accuracy_log"])


@pytest.mark.parametrize("smoothing", [0.0, 1e-3])
@pytest.mark.parametrize("accuracy", [1e-3, 1e-6])
def test_auto_impact(smoothing, accuracy):
    """The gap, with a kink and smoothed: modal_ramp after the quintic runs beyond their
    stability limit or unconfirmed. Measured with the kink: 1024 sub-steps, 1.8e-4 true, 1.06x
    (1e-3); 32768, 1.3e-7, 1.91x (1e-6: within the default cap, 10^8 DOF-steps over the 199
    steps of the record); smoothed: 256, 3.3e-6, 2.21x; 512, 2.1e-7, 1.01x."""
    run, ref = _gap(smoothing)
    r = run(accuracy=accuracy)
    e, est = check(r, ref, accuracy)
    assert r.info["scheme"] == "modal_ramp" and 0.9 <= est / e <= 2.3


def test_auto_needs_a_target_and_takes_no_parameters(P4):
    with pytest.raises(ValueError, match=r"scheme 'auto' picks the method for an accuracy "
                                         r"target: it needs accuracy="):
        nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="auto")
    with pytest.raises(ValueError, match=r"takes no scheme parameters \(got beta\)"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], scheme="auto", accuracy=1e-3, beta=0.3)


def test_auto_with_a_singular_mass_matrix_runs_average_acceleration():
    """A massless DOF (no modal model): the average-acceleration Newmark's Richardson sequence
    meets the target against a truth of the same scheme, the extrapolation of its 256- and
    512-sub-step runs (their difference 2.2e-9 here, the extrapolation's error far below):
    6.1e-10 true at 8 sub-steps, extrapolated, estimate 6.3e-9 measured."""
    M, C, K = np.diag([1.0, 0.0]), np.diag([0.5, 2.0]), np.array([[2e3, -1e3], [-1e3, 1e3]])
    f = (10.0 * np.sin(2 * np.pi * 3 * np.arange(500) / 1000.0))[:, None]
    kw = dict(force_dofs=[0], elements=[Cubic(0, k3=1e7)])
    r = nonlinear_mck_response(M, C, K, f, 1e-3, **kw, accuracy=1e-6)
    assert r.info["scheme"] == "average_acceleration" and r.info["accuracy_met"]
    a, b = (nonlinear_mck_response(M, C, K, f, 1e-3, **kw, scheme="average_acceleration",
                               substeps=S).x for S in (256, 512))
    truth = b + (b - a) / 3
    assert np.abs(r.x - truth).max() / np.abs(truth).max() <= 1e-6


def test_quintic_estimate_false_skips_the_embedded_estimate(P4):
    """estimate=False: modal_quintic's loop without its estimate (the solution bit for bit the
    same: the estimate only reads it), no error_estimate in info; with accuracy it is refused."""
    kw = dict(P4["kw"], scheme="modal_quintic", substeps=1)
    a = nonlinear_mck_response(*P4["args"], **kw)
    b = nonlinear_mck_response(*P4["args"], **kw, estimate=False)
    for q in "xva":
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q))
    assert "error_estimate" in a.info and "error_estimate" not in b.info
    with pytest.raises(ValueError, match="estimate=False with accuracy: an accuracy target always "
                                         "estimates"):
        nonlinear_mck_response(*P4["args"], **P4["kw"], accuracy=1e-3, estimate=False)


def test_default_cap_is_a_step_budget(monkeypatch):
    """max_substeps=None: 256 per sample, or as many as keep DOFs x sub-steps x samples within
    STEP_BUDGET (10^8; here shrunk to 300 per step of the 199-step record of one DOF)."""
    from dtdyn.nonlinear import _response as R
    assert (R.MAX_SUBSTEPS, R.STEP_BUDGET) == (256, 10**8)
    monkeypatch.setattr(R, "STEP_BUDGET", 199 * 300)
    run, _ = _gap(0.0)
    with pytest.warns(DtdynAccuracyWarning, match=r"at 256 sub-steps \(max_substeps=300,"):
        run(scheme="newmark", accuracy=1e-14, substeps=128, quantities=("x",))
    monkeypatch.setattr(R, "STEP_BUDGET", 199 * 100)
    with pytest.warns(DtdynAccuracyWarning, match=r"\(max_substeps=256,"):
        run(scheme="newmark", accuracy=1e-14, substeps=128, quantities=("x",))


def test_a_window_without_response_checks_nothing():
    """A load that starts after the window (zero force over its 2,000 samples): the window's
    estimates are 0 and confirm nothing, so the record's own runs confirm each other (no
    estimate_window) and the target holds against a run at 128 sub-steps."""
    M = np.diag([1.0, 0.5])
    K = np.array([[300.0, -100.0], [-100.0, 100.0]])
    C = 0.01 * K + 0.05 * M
    dt, n = 1e-2, 20000
    t = dt * np.arange(n)
    f = (30.0 * np.sin(2.1 * t) * np.clip((t - 40.0) / 60.0, 0, 1))[:, None]
    kw = dict(elements=[Cubic(1, k3=3e4)], force_dofs=[0], outputs=[0, 1])
    ref = nonlinear_mck_response(M, C, K, f, dt, scheme="modal_explicit", substeps=128, **kw)
    r = nonlinear_mck_response(M, C, K, f, dt, scheme="modal_explicit", accuracy=1e-3, **kw)
    assert "estimate_window" not in r.info
    assert "no window" in (r.info["accuracy_log"][0]["note"] or "")
    assert np.abs(r.x - ref.x).max() / np.abs(ref.x).max() <= 1e-3
