r"""An accuracy target for `nonlinear_mck_response`: the sub-steps chosen from an error estimate.

A scheme of order p run with S sub-steps (h = dt / S) has, once h is small enough for the leading
term to dominate, the error

    e_S(t) = x_S(t) - x(t) ~ c(t) h^p.

Two runs at S_c and S_f = r S_c (r = 2 here) differ by d = x_f - x_c ~ c(t) h_f^p (1 - r^p), so

    |e_f| ~ |d| / (r^p - 1),     |e_c| ~ |d| r^p / (r^p - 1)                      (Richardson)

and the combination x_R = x_f + d / (r^p - 1) cancels the leading term. Its own error is of
order q >= p + 1 (p + 2 for the schemes whose expansion holds only even powers: the ramp
invariant and the average-acceleration Newmark measure 4 on P4), estimated the same way from two
extrapolations R_k, R_{k-1}:

    |x_R,k - x| ~ |R_k - R_{k-1}| / (2^q - 1),

q_obs = log2(|R_{k-1} - R_{k-2}| / |R_k - R_{k-1}|) from four levels S_0 .. 8 S_0, and used only
when q >= p + 0.5: an extrapolation whose gain the runs do not show is never returned (a
kink, as a gap's contact, gives runs that look second order between two levels while their
extrapolation is worse than the finest run). q is the integer p + 2 .. 2 p when q_obs at this
level and at the one before (five levels) are both within P_SLACK of it (the even-power schemes
show 4; modal_parabolic on a Duffing oscillator 5.97 and 5.91: its h^4 and h^5 terms are
small), else min(p + 1, q_obs): a single observation above p + 1 is not trusted (Bouc-Wen's
kinks give 3.96, 2.0, 3.5, 1.4 at successive levels). With q capped at p + 1 the estimate is
high by up to (2^(p+2) - 1) / (2^(p+1) - 1) = 2.1 for the even-power schemes.

Norm: for each stored quantity (x, v, a, g, z) the largest |difference| over time and columns,
relative to the largest |value| of that quantity; the estimate is the largest over the
quantities (the measure of `dtdyn bench` and the tests: max over time and outputs relative to
max |x|).

The order p: modal_ramp 2, modal_parabolic 3, ... (``order`` in generated/scheme_table.py METHODS),
a one-step scheme its ``order`` in the scheme table (Newmark with gamma != 1/2: 1). The runs
themselves check it: from three levels the observed order p_obs = log2(|d_{k-1}| / |d_k|); the
estimate uses min(p, p_obs) (never an order the runs do not show), and the extrapolation is used
only when |p_obs - p| <= P_SLACK = 0.25 (the leading term dominates). Non-smooth elements (a gap's
contact, Bouc-Wen's sign(y')) break the expansion, and the estimate is then only as good as p_obs
says.

scheme="auto" (`nonlinear_mck_response` without a scheme, with a target): modal_explicit, then
modal_quintic, whose runs carry an embedded estimate (`reach_embedded`), and when a run's
estimate is not confirmed by the next one or a run fails, the Richardson sequence of modal_ramp
(`AUTO_THEN`): seventh or sixth order where the element forces are smooth, the second-order ramp
invariant where they are not. On a long record the embedded estimates are checked on its first
samples (`probe_window`), and the record then runs once, its estimate trusted: an accuracy
target at the price of one run with the estimate.
"""
from __future__ import annotations

import math
import time
from functools import partial

import numpy as np

from dtdyn._engine.errors import DtdynAccuracyWarning, DtdynStepStabilityError, NewtonError
from dtdyn._engine.public import warn
from dtdyn.generated.scheme_table import AUTO as _AUTO
from dtdyn.generated.scheme_table import METHODS, TABLE

#: the stored quantities the estimate measures, and the ones an extrapolation combines
MEASURED = ("x", "v", "a", "g", "z")

#: the extrapolation is used only when the observed order is within P_SLACK of the scheme's
P_SLACK = 0.25
COMBINED = MEASURED + ("a_abs", "x_abs")


def check_accuracy(accuracy):
    """accuracy as a float: a real number, finite and > 0, or ValueError naming it."""
    if isinstance(accuracy, (bool, np.bool_)) or not isinstance(
            accuracy, (int, float, np.integer, np.floating)):
        raise ValueError(f"accuracy must be a number (a relative error such as 1e-6), got "
                         f"{accuracy!r}")
    value = float(accuracy)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"accuracy must be finite and > 0, got {accuracy!r}")
    return value


def scheme_order(method, params) -> int:
    """The order p in h of ``method`` with these parameters (a modal method its order in METHODS:
    modal_ramp 2, modal_parabolic 3, modal_quintic 6, modal_explicit 7; a one-step scheme its
    order in TABLE, a scheme file's the derived one; Newmark with gamma != 1/2 is first
    order)."""
    if method in METHODS:
        return int(METHODS[method]["order"])
    if hasattr(method, "table"):   # a scheme file's scheme: the order its derivation found
        return int(method.table["order"])
    if method not in TABLE:
        raise ValueError(f"scheme {method!r} has no known order; accuracy and estimate "
                         f"need a method of {', '.join(METHODS)} or a scheme of "
                         f"{', '.join(TABLE)}")
    if method == "newmark" and float(params.get("gamma", 0.5)) != 0.5:
        return 1
    return int(TABLE[method]["order"])


def _order(coarse, fine) -> float:
    """log2(coarse / fine): the observed order of two successive differences (inf when the finer
    one is 0, -inf when the coarser one is)."""
    if fine <= 0:
        return np.inf
    return math.log2(coarse / fine) if coarse > 0 else -np.inf


def extrapolation_order(p, q_obs, q_before=None) -> float:
    """The order q the extrapolation's estimate assumes (module docstring): the integer
    p + 2 .. 2 p when the observed q_obs and the level before's q_before are both within P_SLACK
    of it (an expansion whose next terms vanish: even powers only, or a parabola whose h^4 and
    h^5 terms are small; one observation is not enough: Bouc-Wen's kinks showed 3.96 once),
    else min(p + 1, q_obs)."""
    q_int = round(q_obs) if math.isfinite(q_obs) else 0
    if (p + 2 <= q_int <= 2 * p and q_before is not None
            and max(abs(q_obs - q_int), abs(q_before - q_int)) <= P_SLACK):
        return float(q_int)
    return min(p + 1, q_obs)


def difference(a, b) -> float:
    """max over the stored quantities of max|a_q - b_q| / max|a_q| (0 for none stored); inf
    when a quantity's difference is not finite (a NaN or inf in either run never counts as
    agreement: Python's max(worst, nan) would return worst)."""
    worst = 0.0
    for q in MEASURED:
        x, y = getattr(a, q, None), getattr(b, q, None)
        if x is None or y is None:
            continue
        scale = np.abs(x).max()
        d = np.abs(x - y).max()
        term = float(d / scale) if scale > 0 else (0.0 if d == 0 else np.inf)
        if not math.isfinite(term):
            return np.inf
        worst = max(worst, term)
    return worst


def _extrapolate(fine, coarse, factor):
    """fine + factor (fine - coarse), quantity by quantity (a new Response; built by `reach`
    only when its difference to the previous level's is measured)."""
    from copy import copy
    out = copy(fine)
    out.info = dict(fine.info)
    for q in COMBINED:
        x, y = getattr(fine, q, None), getattr(coarse, q, None)
        if x is not None and y is not None:
            setattr(out, q, x + factor * (x - y))
    return out


def _timing(runs):
    keys = ("setup_time", "construct_time", "compile_time", "run_time")
    return {k: float(sum(r.info.get(k, 0.0) for r in runs)) for k in keys}


def estimate_only(run, substeps, method, params):
    """The run at ``substeps`` with the estimate of its own error from a companion run (S / 2
    when S is even: the cheaper one; 2 S otherwise). When the S / 2 companion fails
    (NewtonError, a modal step beyond its stability limit) the 2 S one is used; when the
    companion fails at every count tried, the last failure's type is raised (chained) naming
    the companion sub-steps."""
    p = scheme_order(method, params)
    S = substeps
    mine = run(S)
    tried = [S // 2, 2 * S] if S % 2 == 0 else [2 * S]
    for i, S_other in enumerate(tried):
        try:
            other = run(S_other)
            break
        except (NewtonError, DtdynStepStabilityError) as exc:
            if i == len(tried) - 1:
                raise type(exc)(
                    f"estimate: the run at {S} sub-steps succeeded but its companion run failed "
                    f"at {' and '.join(map(str, tried))} sub-steps ({type(exc).__name__}: {exc})"
                ) from exc
    t0 = time.perf_counter()
    if S_other < S:
        est = difference(mine, other) / (2**p - 1)       # mine is the fine run
    else:
        est = difference(mine, other) * 2**p / (2**p - 1)  # mine is the coarse run
    mine.info.update(_timing([mine, other]))
    mine.info.update(error_estimate=est, error_order=p, extrapolated=False,
                     estimate_time=time.perf_counter() - t0,
                     estimate_substeps=[S, other.info["substeps"]])
    return mine


def reach(run, accuracy, substeps, max_substeps, method, params, observed=False):
    """Run S_0 = ``substeps``, 2 S_0, 4 S_0, ... until an estimate <= ``accuracy``.

    After each run k >= 1: the estimate of the finest run, |d_k| / (2^p_e - 1), p_e = p (k = 1)
    or min(p, p_obs) (k >= 2); from k >= 3, when |p_obs - p| <= P_SLACK at the last two levels
    and q_obs >= p + 0.5, also that of the extrapolation R_k (module docstring). The first
    estimate <= accuracy returns its solution (R_k when both qualify: the smaller error); with
    ``observed`` only from k >= 2, where the order the runs show bounds the estimate (the
    polynomial methods' sequence after their embedded estimate was refused: their nominal
    order, 6 or 7, is far from what a kink or a start at the stability limit shows, and a
    two-run estimate would assume it). A run that fails (NewtonError, a modal step
    beyond its stability limit) restarts the sequence at twice its sub-steps. Beyond
    ``max_substeps``: a DtdynAccuracyWarning naming the target, the estimate reached and the
    sub-steps, and the best solution with its estimate (inf when no run had a neighbour to be
    estimated from, or its differences were not finite). When every run failed, the last
    failure's own type (chained) naming the target and the sub-steps tried.
    """
    p = scheme_order(method, params)
    # extrap: per level k >= 1 of the current sequence, [fine, coarse, R or None]: R_k is built
    # (once) only when a difference R_k - R_{k-1} is measured
    runs, diffs, levels, extrap, dR, all_runs = [], [], [], [], [], []

    def extrapolation(i):
        e = extrap[i]
        if e[2] is None:
            e[2] = _extrapolate(e[0], e[1], 1.0 / (2**p - 1))
        return e[2]
    spent = [0.0]  # the estimates' own work (differences, extrapolations), s
    log = []
    S = substeps
    best = None
    failure, last_ok = None, None  # the last failure; the last run that succeeded
    tried = []
    while S <= max_substeps:
        tried.append(S)
        try:
            r = run(S)
            last_ok = S
        except (NewtonError, DtdynStepStabilityError) as exc:
            failure = exc
            log.append((S, None, f"{type(exc).__name__}: restarted at {2 * S} sub-steps"))
            runs, diffs, levels, extrap, dR = [], [], [], [], []
            S *= 2
            continue
        all_runs.append(r)
        runs.append(r)
        levels.append(S)
        k = len(runs) - 1
        t_est = time.perf_counter()
        if k >= 1:
            diffs.append(difference(r, runs[-2]))
            p_eff, p_obs = p, None
            if k >= 2:
                p_obs = _order(diffs[-2], diffs[-1])
                p_eff = min(p, p_obs)
            plain = diffs[-1] / (2**p_eff - 1) if p_eff > 0 else np.inf
            cands = [(plain, r, False)]
            extrap.append([r, runs[-2], None])
            if p_obs is not None and abs(p_obs - p) <= P_SLACK and len(extrap) >= 2:
                R = extrapolation(-1)
                dR.append(difference(R, extrapolation(-2)))
                if len(dR) >= 2:  # four levels: the extrapolation's own observed order
                    q_obs = [_order(dR[i - 1], dR[i]) for i in range(max(1, len(dR) - 2),
                                                                      len(dR))]
                    q = extrapolation_order(p, q_obs[-1], q_obs[0] if len(q_obs) > 1 else None)
                    if q >= p + 0.5:  # the extrapolation gains over the finest run
                        cands.append((dR[-1] / (2**q - 1), R, True))
            else:
                dR.clear()
            log.append((S, min(c[0] for c in cands), None))
            est, sol, is_R = min(cands, key=lambda c: c[0])
            if (k >= 2 or not observed) and (best is None or est < best[0]):
                best = (est, sol, is_R, S, p_obs, list(levels))
            spent[0] += time.perf_counter() - t_est
            if est <= accuracy and (k >= 2 or not observed):
                return _finish(best, accuracy, True, all_runs, p, log, spent[0], method)
        else:
            log.append((S, None, None))
        S *= 2
    if not all_runs:  # every run failed: the last failure's own type
        raise type(failure)(
            f"accuracy={accuracy:g}: no run succeeded at {', '.join(map(str, tried))} sub-steps "
            f"(max_substeps={max_substeps}); the last: {type(failure).__name__}: {failure}"
        ) from failure
    if best is None:
        # runs succeeded but none had a successful neighbour to be estimated from: the last
        # of them, with an infinite estimate, and the warning below
        best = (np.inf, all_runs[-1], False, last_ok, None, [last_ok])
    warn(
        f"accuracy={accuracy:g} not reached: the error estimate is {best[0]:.3g} at "
        f"{best[3]} sub-steps (max_substeps={max_substeps}, scheme {method!r}, order {p}); "
        f"raise max_substeps or use a higher-order scheme", DtdynAccuracyWarning)
    return _finish(best, accuracy, False, all_runs, p, log, spent[0], method)


def _log(log, method):
    """accuracy_log entries of (sub-steps, estimate, note) tuples, with the method that ran."""
    return [{"substeps": s, "estimate": e, "note": n, "scheme": method} for s, e, n in log]


def _finish(best, accuracy, met, all_runs, p, log, estimate_time, method):
    est, sol, is_R, S, p_obs, used = best
    sol.info.update(_timing(all_runs))
    sol.info.update(substeps=S, error_estimate=float(est), accuracy=accuracy, accuracy_met=met,
                    extrapolated=is_R, error_order=p, observed_order=p_obs,
                    estimate_substeps=used, estimate_time=estimate_time,
                    accuracy_log=_log(log, method))
    return sol


#: scheme="auto" (generated/scheme_table.py AUTO, from dtdyn.derive.nonlinear.AUTO): the modal
#: methods whose runs estimate themselves, the explicit seventh-order one (no Newton solve, the
#: cheapest step) and then the implicit sixth-order one (stable for ten times the elements'
#: stiffness), then (an estimate not confirmed, or a run that fails) the ramp invariant's
#: Richardson sequence, robust on kinks and hysteresis; a one-step scheme when the mass matrix
#: is singular (no modal model)
AUTO, AUTO_NEXT = _AUTO["first"], _AUTO["next"]
AUTO_THEN, AUTO_SINGULAR_M = _AUTO["then"], _AUTO["singular_mass"]


#: the window that checks the embedded estimate before one run of the record is trusted: the
#: record's first PROBE_SAMPLES samples, on records of at least PROBE_RECORDS times as many
#: (shorter records: two runs of the record, the second confirming the first)
PROBE_SAMPLES, PROBE_RECORDS = 2000, 8
#: the window's estimate must meet the target with this margin before the record runs at its
#: sub-steps: the record holds more than its start (P4, 100,000 samples: the record's estimate
#: 11x the first 2,000 samples'); a record whose estimate misses the target runs again
PROBE_MARGIN = 10.0


def probe_window(n_samples):
    """The samples of the window that checks the embedded estimate (`reach_embedded`), or None
    when the record is too short for one (fewer than PROBE_RECORDS windows)."""
    return PROBE_SAMPLES if n_samples >= PROBE_RECORDS * PROBE_SAMPLES else None


#: `_probe`'s answer for a window without response
QUIET = -1


def _confirms(r, prev, spent):
    """(confirmed, difference): the difference of two runs (~ the coarser one's error) within a
    factor 3 of the coarser run's estimate; its time added to spent[0]."""
    t0 = time.perf_counter()
    d, est = difference(r, prev), prev.info["error_estimate"]
    spent[0] += time.perf_counter() - t0
    return est / 3 <= d <= 3 * est, d


def _unconfirmed(where, d, prev):
    """The log's note of a window run whose difference d does not confirm prev's estimate."""
    return (f"{where}: difference {d:.3g} to {prev.info['substeps']} sub-steps does not "
            f"confirm its estimate {prev.info['error_estimate']:.3g}")


def _probe(run_w, samples, accuracy, substeps, max_substeps, p, log, runs, spent):
    """The window's sub-steps: runs of the first ``samples`` samples from ``substeps``, the next
    S from the order p (S (estimate / goal)^(1/p) up, goal = accuracy / PROBE_MARGIN, the
    margin its safety;
    max(S + 1, S 2^(2/p)) when the estimate meets the goal: a run whose error is at most a
    quarter of it), until a run's estimate meets the goal and some run's estimate has been
    confirmed by the next one (`_confirms`): the coarsest such S (the estimator then follows
    the runs on this problem). A run after one whose estimate meets the goal only confirms it,
    and runs without its own estimate (``run_w(S, estimate=False)``). None when a window run
    fails, has no embedded estimate or does not confirm the one before (the window is the
    record's start: a run that fails there fails on the record too); QUIET when a window run's
    estimate is 0 (no response in the window: the record's runs confirm each other as without
    a window). Appends to ``log`` and ``runs``, the differences' time to spent[0]."""
    goal = accuracy / PROBE_MARGIN
    S, prev, confirmed = substeps, None, False
    where = f"window of {samples} samples"
    while S <= max_substeps:
        # a run after one whose estimate meets the goal only confirms it: its own estimate is
        # not formed (the window returns the coarser S either way, or None)
        confirming = prev is not None and prev.info["error_estimate"] <= goal
        try:
            r = run_w(S, estimate=False) if confirming else run_w(S)
        except (NewtonError, DtdynStepStabilityError) as exc:
            log.append((S, None, f"{where}: {type(exc).__name__}"))
            return None
        if confirming:
            runs.append(r)
            ok, d = _confirms(r, prev, spent)
            if not ok:
                log.append((S, None, _unconfirmed(where, d, prev)))
                return None
            log.append((S, None, f"{where}, confirms {prev.info['substeps']} (its own estimate "
                        "not formed)"))
            return prev.info["substeps"]
        if r.info.get("error_estimate_kind") != "embedded":
            log.append((S, None, f"{where}: no embedded estimate"))
            return None
        runs.append(r)
        est = r.info["error_estimate"]
        if not est > 0.0:      # no response in the window: nothing there checks the estimator
            log.append((S, est, f"{where}: estimate {est:.3g}, no window (the record confirms)"))
            return QUIET
        note = where
        if prev is not None:
            ok, d = _confirms(r, prev, spent)
            if not ok:
                log.append((S, est, _unconfirmed(where, d, prev)))
                return None
            confirmed = True
            note += f", confirms {prev.info['substeps']}"
        log.append((S, est, note))
        if confirmed and est <= goal:
            return S
        if est <= goal:
            grow = 2.0 ** (2.0 / p)
        else:
            grow = (est / goal) ** (1.0 / p) if math.isfinite(est) else 2.0
        prev, S = r, max(S + 1, math.ceil(S * grow))
    return None


def reach_embedded(run, accuracy, substeps, max_substeps, method, params, then=None,
                   after=None, probe=None):
    """``accuracy`` for a method whose every run reports an embedded estimate (modal_quintic and
    modal_explicit on the C backend).

    With ``probe`` = (run_w(S, method), samples), a run of the record's first ``samples``
    samples (`probe_window`: long records), the window checks the estimator first (`_probe`:
    runs from ``substeps`` until an estimate meets the target with the margin PROBE_MARGIN
    and a run has confirmed the estimate of the one before), and the record then runs once at
    that S: its estimate at or below the target is trusted and returned, one run of the record.
    A window that fails or does not confirm hands over as an unconfirmed record would (below);
    a record whose estimate misses the target goes on as follows, from that run.

    Without a window (short records): run S; when its estimate exceeds the target the next S
    follows from the order p, S (estimate / accuracy)^(1/p) * 1.2 rounded up (at least 2 S
    when the estimate already meets it: the confirmation). A run's estimate is trusted only
    when the next run confirms it: the difference of the two runs (~ the coarser one's error)
    within a factor 3 of the coarser run's estimate. Unconfirmed (a kink, a hysteresis, a run
    far from the asymptotic range: the force polynomial's error is then not its next term),
    the Richardson sequence `reach` takes over from ``substeps`` (trusted from three levels
    when it is this method's: ``observed``). A run that fails (NewtonError, a modal step
    beyond its stability limit) hands over to `reach` too, as does a run without an embedded
    estimate. ``then``: (run, method, params) of that Richardson sequence when it is not this
    method's (scheme "auto": `AUTO_THEN`); ``after``: (run, method) of another method with an
    embedded estimate tried the same way before it (scheme "auto": `AUTO_NEXT` after
    `AUTO`). The result's info["scheme"] names the method that ran; info["estimate_window"]
    the window's samples and sub-steps when one decided."""
    p = scheme_order(method, params)
    S, runs, log, prev, prev_S = substeps, [], [], None, None
    successor = after[1] if after is not None else "the Richardson sequence"
    spent = [0.0]  # the estimates' own work (differences of the runs), s
    trusted = None  # the window's levels when a single run of the record may be trusted
    if probe is not None:
        window = []
        S_w = _probe(partial(probe[0], method=method), probe[1], accuracy, substeps,
                     max_substeps, p, log, window, spent)
        runs += window
        if S_w is None:
            S = max_substeps + 1  # straight to the successor
        elif S_w == QUIET:
            pass                  # no window: the record's runs, from substeps
        else:
            S, trusted = S_w, [r.info["substeps"] for r in window]
    while S <= max_substeps:
        try:
            r = run(S)
        except (NewtonError, DtdynStepStabilityError) as exc:
            log.append((S, None, f"{type(exc).__name__}: {successor} takes over"))
            break
        if r.info.get("error_estimate_kind") != "embedded":
            log.append((S, None, f"no embedded estimate: {successor} takes over"))
            break
        runs.append(r)
        est = r.info["error_estimate"]
        if prev is not None:
            confirmed, d = _confirms(r, prev, spent)
            est_prev = prev.info["error_estimate"]
            log.append((S, est, None if confirmed else f"difference {d:.3g} to {prev_S} "
                        f"sub-steps does not confirm its estimate {est_prev:.3g}"))
            if not confirmed:
                break
            if est <= accuracy:
                return _finish((est, r, False, S, None, [prev_S, S]), accuracy, True, runs, p,
                               log, spent[0], method)
        elif trusted is not None:
            log.append((S, est, f"the window's runs at {', '.join(map(str, trusted))} "
                        "sub-steps confirmed the estimator"))
            if est <= accuracy:
                out = _finish((est, r, False, S, None, [S]), accuracy, True, runs, p, log,
                              spent[0], method)
                out.info["estimate_window"] = {"samples": probe[1], "substeps": trusted}
                return out
        else:
            log.append((S, est, None))
        grow = (est / accuracy) ** (1.0 / p) * 1.2 if math.isfinite(est) else 2.0
        prev, prev_S = r, S
        S = max(2 * S if est <= accuracy else S + 1, math.ceil(S * grow))
    if after is not None:
        out = reach_embedded(after[0], accuracy, substeps, max_substeps, after[1], {}, then,
                             probe=probe)
    else:
        run_r, method_r, params_r = then or (run, method, params)
        out = reach(run_r, accuracy, substeps, max_substeps, method_r, params_r,
                    observed=then is None)
    out.info["accuracy_log"] = _log(log, method) + out.info["accuracy_log"]
    out.info.update(_timing(runs + [out]))
    out.info["estimate_time"] = out.info.get("estimate_time", 0.0) + spent[0]
    return out
