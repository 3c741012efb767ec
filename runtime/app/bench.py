"""Work-precision reports (`dtdyn bench`): every applicable method on a reference problem, error
against a tight reference and run time, as a Markdown table, JSON and a log-log plot.

Error: the displacement of the problem's output DOF (P3: mass 15; P4: DOF 3), max over time of
|x - x_ref| relative to max |x_ref|, and the RMS over time of the difference on the same scale.
Time: median of repeats after a warm-up, with their spread [min, max]; BLAS pinned to one
thread (threadpoolctl, `dtdyn.app.timing`) for the whole bench, so that a small matrix's BLAS
call does not take 0.6 ms or 35 ms by the moment; construction and compile (the first call
minus the median) reported apart. `rank_changes` compares the rankings of two or three such
reports. Fixed-step methods sweep dt (P3) or sub-steps (P4); adaptive solvers
sweep rtol. References: the matrix exponential (exact for P3's piecewise-linear force) and the
solve_ivp DOP853 rtol 1e-12 reference restarted at every sample (P4, cached on disk). solve_ivp
peers on P4 run on a window of the record and are extrapolated (marked). P4 also reports every
run's time over that of the linear modal filter response of P4L (P4 without its cubic springs,
same record, same run): the price of the nonlinearity; and nonlinear_mck_response's accuracy targets
(``accuracy=1e-3, 1e-6``), timed over all the runs each needs.
"""
from __future__ import annotations

import functools
import itertools
import json
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from dtdyn.app import problems
from dtdyn._engine.atomic import write_atomic
from dtdyn.app.timing import SPREAD, Timing, measure, pin_blas
from dtdyn.generated.scheme_table import TABLE


@dataclass
class Run:
    method: str
    family: str
    setting: str
    max_error: float
    rms_error: float
    run_time: float
    build_time: float
    note: str = ""
    #: the linear baseline's median timed in alternation with this run's repeats (P4)
    linear_time: float | None = None
    #: the spread of the repeats whose median is run_time: fastest and slowest, and their count
    run_time_min: float | None = None
    run_time_max: float | None = None
    repeats: int = 1

    def price(self, t_lin):
        """run time / linear baseline: the paired one where measured, else ``t_lin``."""
        return self.run_time / (self.linear_time or t_lin)

    def spread(self, scale=1e3):
        """``median [min, max]`` of the run time, times ``scale`` (ms by default)."""
        lo, hi = self.run_time_min, self.run_time_max
        if lo is None or self.repeats <= 1:
            return f"{self.run_time * scale:.3g} (1 run)"
        return f"{self.run_time * scale:.3g} [{lo * scale:.3g}, {hi * scale:.3g}]"


def _errors(x, ref):
    d = np.asarray(x) - np.asarray(ref)
    scale = np.abs(ref).max()
    return float(np.abs(d).max() / scale), float(np.sqrt(np.mean(d**2)) / scale)


#: fast calls are repeated until their timed calls add up to this many seconds (at most
#: MAX_REPEATS calls), so that their spread samples the machine's noise
MIN_TIME, MAX_REPEATS = 0.02, 25


def _timed(fn, repeats, key=None, before=None):
    """(result, run time, build time) by `dtdyn.app.timing.measure`: the first call, then
    ``repeats`` timed calls, more for fast calls (MIN_TIME, MAX_REPEATS); the run time is a
    `Timing` (its median and spread). ``repeats`` = 0: the first call's time alone, no build
    time. ``key(result)``: the run time a call reports itself (e.g. its C loop's, from
    ``info``), kept instead of the wall time; the build time is still the first call's wall
    time minus the median wall time. ``before()``: run before each timed call, untimed (P4:
    one linear run, so that the ratio of the two medians sees the same stretch of a shared
    machine)."""
    own = []

    def call():
        out = fn()
        if key is not None:
            own.append(key(out))
        return out
    if repeats == 0:  # a single (cold) run: no build time to separate
        out, wall = measure(call, 1, warmup=False)
        return out, (wall if key is None else Timing(tuple(own))), 0.0
    out, wall = measure(call, repeats, before=before,
                        min_time=0.0 if before is not None else MIN_TIME,
                        max_repeats=MAX_REPEATS)
    return out, (wall if key is None else Timing(tuple(own[1:]))), wall.build


def _recorder(runs, log):
    """add(method, family, setting, x, x_ref, run time, build time, note[, linear time]):
    append and log a Run."""
    def add(method, family, setting, x, ref, t_run, t_build, note="", t_lin=None):
        e_max, e_rms = _errors(x, ref)
        t = t_run if isinstance(t_run, Timing) else Timing((t_run,))
        runs.append(Run(method, family, setting, e_max, e_rms, t.median, t_build, note, t_lin,
                        t.min, t.max, t.repeats))
        log(f"  {method:32s} {setting:>12s}  max {e_max:9.2e}  rms {e_rms:9.2e}  "
            f"{runs[-1].spread():>24s} ms  {note}")
    return add


def _blas_pinned(bench):
    """Run ``bench`` with BLAS pinned (`dtdyn.app.timing.pin_blas`, one thread by default);
    the pin and the libraries it found go to the meta data (``meta["blas"]``)."""
    @functools.wraps(bench)
    def pinned(quick=False, log=print, blas_threads=1):
        with pin_blas(blas_threads) as pin:
            runs, meta = bench(quick=quick, log=log)
        meta["blas"] = pin.as_dict()
        return runs, meta
    return pinned


# --- P3: linear chain ---------------------------------------------------------------------------

#: every scheme of the table at its defaults, but plain newmark (= average_acceleration at its
#: defaults) and central_difference (explicit: no displacement form for P3's undamped chain)
P3_SCHEMES = [(name, {}) for name in TABLE if name not in ("newmark", "central_difference")]


@_blas_pinned
def bench_p3(quick=False, log=print):
    from scipy import signal
    from scipy.integrate import solve_ivp

    from dtdyn.linear.chain import chain_response
    from dtdyn.linear.discretize import discretize, first_order_form
    from dtdyn.linear.exact import exact_response
    from dtdyn.modal.filters import modal_filter_response
    from dtdyn.linear.state_space import discrete_state_space, state_space_response
    P = problems.p3()
    M, C, K, T, out = P["M"], P["C"], P["K"], P["T"], P["output"]
    dts = (2e-3, 1e-3, 5e-4) if quick else (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
    reps = 3
    runs = []
    add = _recorder(runs, log)

    for dt in dts:
        n = int(round(T / dt))
        f = np.ones((n + 1, 1))
        ref = exact_response(M, C, K, f, dt, force_dofs=[14], outputs=[out]).x[:, 0]
        setting = f"dt={dt:g}"
        for name, params in P3_SCHEMES:
            r, t_run, t_b = _timed(functools.partial(
                chain_response, P["mass"], P["stiffness"], P["damping"], f, dt, force_dofs=[14],
                scheme=name, outputs=[out], quantities=("x",), **params), reps)
            add(f"DT-TMM {name}", "DT-TMM (C)", setting, r.x[:, 0], ref, t_run, t_b)

        def ss(build, f=f):  # the model and its response, from rest at t_0 (state shifted)
            return state_space_response(build(), f, force_dofs=[14], outputs=[out],
                                        quantities=("x",))
        r, t_run, t_b = _timed(functools.partial(
            ss, functools.partial(discrete_state_space, M, C, K, dt)), reps)
        add("state space (Newmark)", "state space", setting, r.x[:, 0], ref, t_run, t_b)
        r, t_run, t_b = _timed(functools.partial(
            ss, functools.partial(discretize, M, C, K, dt, hold="foh")), reps)
        add("exact discretization (foh)", "state space", setting, r.x[:, 0], ref, t_run, t_b)
        for inv in ("ramp", "step", "impulse"):
            r, t_run, t_b = _timed(functools.partial(
                modal_filter_response, M, C, K, f, dt, force_dofs=[14], outputs=[out],
                invariant=inv, quantities=("x",)), reps)
            add(f"modal filters {inv}", "modal filters", setting, r.x[:, 0], ref, t_run, t_b)
        for keep in (5, 10):
            r, t_run, t_b = _timed(functools.partial(
                modal_filter_response, M, C, K, f, dt, force_dofs=[14], outputs=[out],
                modes=range(keep), invariant="ramp", quantities=("x",)), reps)
            add(f"modal filters ramp, {keep} modes", "modal filters", setting, r.x[:, 0], ref,
                t_run, t_b)
        A, B = first_order_form(M, C, K)[:2]
        sys = signal.StateSpace(A, B[:, [14]], np.eye(30)[[out]], np.zeros((1, 1)))
        tt = np.arange(n + 1) * dt
        (_, y, _), t_run, t_b = _timed(functools.partial(signal.lsim, sys, f[:, 0], tt), reps)
        add("scipy lsim", "peer", setting, y, ref, t_run, t_b)

    # adaptive peers on the dt = 1e-3 grid
    dt = 1e-3
    n = int(round(T / dt))
    tt = np.arange(n + 1) * dt
    ref = exact_response(M, C, K, np.ones((n + 1, 1)), dt, force_dofs=[14], outputs=[out]).x[:, 0]
    A, B = first_order_form(M, C, K)[:2]
    b = B[:, 14].copy()

    def rhs(_t, s):
        return A @ s + b

    for solver in ("RK45", "DOP853", "LSODA", "Radau"):
        for rtol in ((1e-4, 1e-7) if quick else (1e-3, 1e-5, 1e-7, 1e-9)):
            implicit = {"jac": lambda _t, _s: A} if solver in ("Radau", "LSODA") else {}
            sol, t_run, t_b = _timed(functools.partial(
                solve_ivp, rhs, (0, T), np.zeros(30), method=solver, t_eval=tt, rtol=rtol,
                atol=rtol * 1e-4, **implicit), reps)
            add(f"solve_ivp {solver}", "peer", f"rtol={rtol:g}", sol.y[out], ref, t_run, t_b)
    meta = {"problem": "P3", "description": "15-DOF chain (Kumar & Sankar 1986), undamped, unit "
            "step on mass 15, T = 0.8 s; error of x at mass 15 against the matrix exponential",
            "targets": [1e-3, 1e-6]}
    return runs, meta


# --- P4: nonlinear ------------------------------------------------------------------------------

P4_METHODS = [("modal_explicit", {}), ("modal_explicit", {"estimate": False}),
              ("modal_quintic", {}), ("modal_quintic", {"estimate": False}),
              ("modal_parabolic", {}), ("modal_ramp", {}), ("newmark", {}),
              ("hht", {"alpha": -0.05}), ("generalized_alpha", {"rho_inf": 0.8})]

#: accuracy targets run on P4 (nonlinear_mck_response's accuracy=: "auto" and modal_parabolic)
P4_ACCURACY = (1e-3, 1e-6)


def _modal_flops(method, r, S, ne, n_modes, no):
    """Floating-point operations per sample of the modal loop (nl_loop.c, modal_run; a
    multiply-add counted as 2): per sub-step eta = L + Bg g, Q = (Cw L + Dwf f) + (Cw Bg) g, the
    predictor, each Newton iteration (the two cubic laws' residual and Jacobian, ~24, and the
    2 x 2 solve, ~12, at mean iterations + 1 evaluations; modal_explicit: no predictor, one
    evaluation of the laws and their tangent, ~12, and the rows of its theta |(Cw Bg) dg/dy|,
    |Cw Bg| |g'| + 0 g, 2 ne^2 + ne),
    the next linear part
    [H Bf] [hist; f] + T eta (dia y + off y[partner]) and Cw of it; the polynomial methods'
    estimate, evaluated a block at a time after the Newton solves (the difference stencil, the gain
    K = dg/du J^-1 [I; 0] from the 2 x 2 inverse, (Cw T) e + (Cw Eg) dn + (Cw Bs) dg, K of it,
    T e + Eg dn + Bs dg); per sample the outputs (x of all DOFs, [Co Dof Dog]) and the
    estimate's (Co e + Dog dg)."""
    from dtdyn.generated.nl_modal import POLYNOMIALS
    nm, nf, nw = 2 * n_modes, 1, ne
    nodes, *_, stencil = POLYNOMIALS.get(method, ((), None, None, None, None, ()))
    nh = {"modal_ramp": 0, "modal_parabolic": 1}.get(method, sum(j < 0 for j in nodes)) * ne
    if method == "modal_explicit":
        step = 12 + 2 * ne**2 + ne
    else:
        step = nw + 2 * nw * ne + (r.info["newton_iterations"]["mean"] + 1) * 36
    sub = 2 * nm * ne + 2 * (nw * nf + nw * ne) + step + 2 * nm * (nh + nf) + 3 * nm + 2 * nw * nm
    per_sample = 2 * no * (nm + nf + ne)
    if "error_estimate" in r.info:  # the polynomial methods' embedded estimate
        sub += (2 * len(stencil) * ne + 8 + 2 * ne * nw * nw + 2 * nw * nm + 4 * nw * ne
                + 2 * ne * nw + 3 * nm + 4 * nm * ne)
        per_sample += 2 * no * (nm + ne)
    return S * sub + per_sample


def _fma_peak_kernel():
    """dtdyn_fma_peak(rounds) of generated/fma_peak.c (12 chains of 4-lane multiply-adds, 96
    flops a round; returns their sum), or None without a C compiler."""
    from importlib import resources

    from dtdyn._engine import cbuild
    lib = cbuild.load_library(resources.files("dtdyn.generated").joinpath("fma_peak.c")
                              .read_text(), "fma_peak")
    return None if lib is None else cbuild.bind(lib, "dtdyn_fma_peak")


def _fma_peak(rounds=2_000_000, repeats=5):
    """GFLOP/s of this core's multiply-add peak for the loops' 4-lane vectors
    (`_fma_peak_kernel`), the best of ``repeats``; None without a C compiler."""
    peak = _fma_peak_kernel()
    if peak is None:
        return None
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        peak(rounds)
        best = min(best, time.perf_counter() - t0)
    return 96 * rounds / best / 1e9


def _steady_allocator():
    """glibc: keep freed memory (no mmap of large arrays, no trimming), so that each run's
    output arrays reuse mapped pages instead of faulting fresh ones in: ~1 ms of P4's 100,000
    samples, landing on one run or another by the allocator's state. Elsewhere: nothing."""
    import ctypes
    import ctypes.util
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        libc.mallopt(-3, 1 << 25)  # M_MMAP_THRESHOLD, 32 MiB: glibc's largest on 64 bits
        libc.mallopt(-1, (1 << 31) - 1)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError, TypeError):
        pass


@_blas_pinned
def bench_p4(quick=False, log=print):
    from scipy.integrate import solve_ivp

    from dtdyn.linear.exact import exact_response
    from dtdyn.modal.filters import modal_filter_response
    from dtdyn.nonlinear.reference import check_reference, reference_response
    from dtdyn.nonlinear.response import nonlinear_mck_response
    n = 10_000 if quick else 100_000
    _steady_allocator()
    P = problems.p4(n)
    out = P["output"]
    args = (P["M"], P["C"], P["K"], P["force"], P["dt"])
    kw = dict(force_dofs=P["force_dofs"], elements=P["elements"])
    t0 = time.perf_counter()
    ref_r = reference_response(*args, **kw)
    t_ref = time.perf_counter() - t0
    ref = ref_r.x[:, out]
    radau = check_reference(*args, **kw, n_samples=300)
    runs = []
    add = _recorder(runs, log)

    def loop_time(r):  # the C loop's own time, as every nonlinear and linear run reports it
        return r.info["run_time"]

    # the linear baseline: the modal filter response of P4L (P4 without its cubic springs) on
    # the same record, timed like the nonlinear runs (the C loop's run time, median of 3), its
    # error against the matrix exponential of P4L
    L = problems.p4l(n)

    def linear():
        return modal_filter_response(L["M"], L["C"], L["K"], L["force"], L["dt"],
                                     force_dofs=L["force_dofs"], quantities=("x",))
    lin, _, lin_build = _timed(linear, 0)
    peak = _fma_peak()
    # measured before, between (one before each timed nonlinear run) and after the
    # nonlinear runs (the machine is shared: each run's ratio uses the linear runs alternating
    # with its own)
    lin_times = [loop_time(linear()) for _ in range(5)]

    def lin_time():  # one more linear run; the last 5 pair with a configuration's 5 runs
        lin_times.append(loop_time(linear()))
    exact = exact_response(L["M"], L["C"], L["K"], L["force"], L["dt"],
                           force_dofs=L["force_dofs"], quantities=("x",))
    e_lin = _errors(lin.x[:, out], exact.x[:, out])[0]

    for method, params in P4_METHODS:
        levels = {"modal_quintic": (1, 2) if params else (1, 2, 4),
                  "modal_explicit": (1, 2) if params else (1, 2, 4),
                  "modal_parabolic": (1, 2, 3, 4, 8, 12)}.get(method, (1, 2, 3, 4, 8))
        for S in levels:
            r, t_run, t_b = _timed(functools.partial(
                nonlinear_mck_response, *args, **kw, scheme=method, substeps=S,
                quantities=("x",), **params), 5, loop_time, lin_time)
            note = ""
            if method.startswith("modal_"):
                fl = _modal_flops(method, r, S, len(P["elements"]), 4, 4)
                rate = fl * (n - 1) / t_run / 1e9
                note = (f"{fl:.0f} flop/sample, {rate:.2f} GFLOP/s achieved"
                        + (f" ({rate / peak:.0%} of the peak)" if peak else ""))
            label = method + "".join(f" {k}={v}" for k, v in params.items() if k == "estimate")
            add(label, "nonlinear (C)", f"substeps={S}", r.x[:, out], ref, t_run, t_b, note,
                statistics.median(lin_times[-5:]))
    # accuracy targets: the time sums every run the target needs (their C loops) and the
    # estimates' own work (differences and extrapolations of the records)
    for scheme in ("auto", "modal_parabolic"):
        for target in P4_ACCURACY:
            r, t_run, t_b = _timed(functools.partial(
                nonlinear_mck_response, *args, **kw, scheme=scheme, accuracy=target,
                quantities=("x",)), 5,
                lambda r: r.info["run_time"] + r.info["estimate_time"], lin_time)
            i = r.info
            note = (f"{i['scheme']}: estimate {i['error_estimate']:.2e} (x, all 4 DOFs), "
                    f"{i['substeps']} sub-steps "
                    f"({'extrapolated from ' if i['extrapolated'] else 'runs '}"
                    f"{', '.join(map(str, i['estimate_substeps']))})")
            add(f"{scheme} accuracy", "nonlinear (C)", f"accuracy={target:g}", r.x[:, out],
                ref, t_run, t_b, note, statistics.median(lin_times[-5:]))
    lin_times += [loop_time(linear()) for _ in range(5)]
    t_lin = statistics.median(lin_times)
    log(f"  linear P4L modal filters (ramp)  max {e_lin:9.2e} (vs matrix exponential)  "
        f"{Timing(tuple(lin_times)).format()}  (median [min, max] of {len(lin_times)}: 5 before, "
        "one before each timed nonlinear run, 5 after)")
    for S in (4, 8):
        r, t_run, t_b = _timed(functools.partial(
            nonlinear_mck_response, *args, **kw, scheme="newmark", substeps=S, backend="casadi",
            solver="fast_newton", compiled=True, quantities=("x",)), 1)
        add("CasADi newmark (compiled)", "peer", f"substeps={S}", r.x[:, out], ref,
            r.info["run_time"], t_b, "fast_newton in mapaccum")

    # solve_ivp across the kinks (force interpolated), on a window, extrapolated
    M, C, K, fs = P["M"], P["C"], P["K"], 1.0 / P["dt"]
    Minv = np.linalg.inv(M)
    L = np.array([[1.0, 0, 0, 0], [0, 1.0, -1.0, 0]])
    k3 = P["k3"]

    def run_ivp(solver, rtol, n_win):
        f = P["force"][:n_win, 0]
        tt = np.arange(n_win) / fs

        def rhs(t, s):
            q, v = s[:4], s[4:]
            F = np.zeros(4)
            F[3] = np.interp(t, tt, f)
            return np.concatenate([v, Minv @ (F - C @ v - K @ q - L.T @ (k3 * (L @ q) ** 3))])
        sol = solve_ivp(rhs, (0, tt[-1]), np.zeros(8), method=solver, t_eval=tt, rtol=rtol,
                        atol=rtol * 1e-3)
        return sol.y[out]

    for solver, n_win in (("RK45", 1000), ("DOP853", 1000), ("LSODA", 1000), ("Radau", 200)):
        n_win = min(n_win, n)
        for rtol in ((1e-5, 1e-7) if quick else (1e-4, 1e-6, 1e-8)):
            y, t_run, _ = _timed(functools.partial(run_ivp, solver, rtol, n_win), 0)
            add(f"solve_ivp {solver}", "peer", f"rtol={rtol:g}", y, ref[:n_win],
                t_run.scaled(n / n_win), 0.0,
                f"window of {n_win} samples, time extrapolated x{n // n_win}")
    meta = {"problem": "P4", "description": f"nonlinear 4-DOF chain, {n} samples at 1 kHz; error "
            "of x at DOF 3 against solve_ivp DOP853 rtol 1e-12 restarted at every sample "
            f"(reference {'from the disk cache' if ref_r.info.get('cached') else f'{t_ref:.0f} s'}"
            f"; DOP853 vs Radau on 300 samples: {radau:.1e})"
            + (f"; the peak of the flop rates: {peak:.1f} GFLOP/s, one core's multiply-adds on "
               "4-lane vectors (generated/fma_peak.c), measured in the same run" if peak else ""),
            "targets": [1e-3, 1e-6], "peak_gflops": peak,
            "linear_time": t_lin, "linear_build": lin_build, "linear_error": e_lin,
            "linear_min": min(lin_times), "linear_max": max(lin_times),
            "linear": "modal filter response (ramp invariant, C) of P4L, P4 without its cubic "
                      f"springs, on the same record ({len(lin_times)} runs: 5 before, one before "
                      "each timed run of dtdyn's nonlinear C loops, 5 after),"}
    return runs, meta


# --- report -------------------------------------------------------------------------------------

BENCHES = {"P3": bench_p3, "P4": bench_p4}


def ranking(runs, target):
    """The fastest run of each method with max error <= target, fastest first."""
    best = {}
    for r in runs:
        if r.max_error <= target and (r.method not in best
                                      or r.run_time < best[r.method].run_time):
            best[r.method] = r
    return sorted(best.values(), key=lambda r: r.run_time)


def _blas_text(meta):
    """The BLAS pin of a report's meta data, as a sentence (without its full stop)."""
    blas = meta.get("blas")
    return blas["text"] if blas else "BLAS threads not pinned"


def _linear_spread(meta):
    """P4's linear baseline time, median [min, max] in ms."""
    t, lo, hi = (meta.get(k) for k in ("linear_time", "linear_min", "linear_max"))
    if lo is None:
        return f"{t * 1e3:.3g} ms"
    return f"{t * 1e3:.3g} ms [{lo * 1e3:.3g}, {hi * 1e3:.3g}]"


def write_report(runs, meta, out_dir, command):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    name = meta["problem"]
    lines = [f"# Work-precision: {name}", "", f"Output of `{command}`. {meta['description']}.",
             f"Times: {SPREAD} after a warm-up: at least 3 repeats, calls faster than "
             f"{MIN_TIME * 1e3:g} ms in all repeated until they add up to it (at most "
             f"{MAX_REPEATS}) (P4's dtdyn runs: the time each reports for its C loops, 5 "
             "repeats; freed memory kept by the allocator, so that no run pays for faulting in "
             "fresh pages; P4's solve_ivp: one run on a window); build = construction and "
             "compile (first call minus the median). Two runs whose [min, max] ranges overlap "
             "are not ordered by this report: their ranks can swap from one report to the "
             "next.", "", _blas_text(meta) + ".", ""]
    t_lin = meta.get("linear_time")
    if t_lin:
        lines += [f"Linear baseline, the price of the nonlinearity: the {meta['linear']} runs in "
                  f"{_linear_spread(meta)} (max error {meta['linear_error']:.1e} against the "
                  "matrix exponential; the median of its runs); the column `time / linear` is "
                  "each run's time over the linear runs timed in alternation with its own "
                  "(median of 5 each) where there are such, else over that median: measured in "
                  "the same run.", ""]

    def ratio(r):  # the extra column, when there is a linear baseline
        return f" {r.price(t_lin):.3g} |" if t_lin else ""
    head, rule = (" time / linear |", "---|") if t_lin else ("", "")
    for target in meta["targets"]:
        ranked = ranking(runs, target)
        lines += [f"## Ranking at max error <= {target:g}", "",
                  "| rank | method | setting | max error | run time [ms], median [min, max] | "
                  "time / fastest |" + head, "|---|---|---|---|---|---|" + rule]
        for k, r in enumerate(ranked, 1):
            lines.append(f"| {k} | {r.method} | {r.setting} | {r.max_error:.2e} | "
                         f"{r.spread()} | {r.run_time / ranked[0].run_time:.3g} |"
                         + ratio(r))
        lines.append("")
    lines += ["## All runs", "", "| method | family | setting | max error | RMS error | run time "
              "[ms], median [min, max] |" + head + " build [ms] | repeats | note |",
              "|---|---|---|---|---|---|" + rule + "---|---|---|"]
    for r in runs:
        lines.append(f"| {r.method} | {r.family} | {r.setting} | {r.max_error:.2e} | "
                     f"{r.rms_error:.2e} | {r.spread()} |" + ratio(r)
                     + f" {r.build_time * 1e3:.3g} | {r.repeats} | {r.note} |")
    lines += ["", f"![error against run time](bench_{name}.png)", ""]
    md = out_dir / f"bench_{name}.md"
    write_atomic(md, lambda fh: fh.write("\n".join(lines).encode()))
    data = {"meta": meta, "command": command, "runs": [asdict(r) for r in runs]}
    write_atomic(out_dir / f"bench_{name}.json",
                 lambda fh: fh.write(json.dumps(data, indent=1).encode()))
    _plot(runs, meta, out_dir / f"bench_{name}.png")
    return md


def _plot(runs, meta, path):
    """Error against run time, one line per method: a marker shape per family (DT-TMM, state
    space, modal filters, nonlinear, peer) and a colour per method within it."""
    from dtdyn._engine.extras import require
    require("matplotlib", "plot", "dtdyn bench")
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.5, 5.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    families = list(dict.fromkeys(r.family for r in runs))
    markers = "osD^v<>ph*X"
    colors = colormaps["tab10"].colors
    for f, family in enumerate(families):
        methods = list(dict.fromkeys(r.method for r in runs if r.family == family))
        for k, m in enumerate(methods):
            pts = sorted((r.run_time, max(r.max_error, 1e-17)) for r in runs if r.method == m)
            ax.loglog([p[0] * 1e3 for p in pts], [p[1] for p in pts],
                      marker=markers[f % len(markers)], ls=("-", "--", ":")[k // 10 % 3],
                      ms=4.5, lw=1, label=m, color=colors[k % len(colors)])
    for target in meta["targets"]:
        ax.axhline(target, color="gray", lw=0.7, ls="--")
    ax.set_xlabel("run time [ms]")
    ax.set_ylabel("max relative error over time")
    ax.set_title(f"{meta['problem']}: error against run time (marker: family)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6.5, ncol=2, loc="best")
    fig.savefig(path, dpi=110)


def run(names, out_dir, quick=False, command="dtdyn bench", blas_threads=1):
    """Run the benches ``names`` (P3, P4) with BLAS pinned to ``blas_threads`` threads, write
    each report (Markdown, JSON, plot) to ``out_dir`` and print a summary; the report paths."""
    written = []
    for name in names:
        if name not in BENCHES:
            raise ValueError(f"unknown problem {name!r}; available: {', '.join(BENCHES)}")
        print(f"{name}:")
        t0 = time.perf_counter()
        runs, meta = BENCHES[name](quick=quick, blas_threads=blas_threads)
        meta["wall_time"] = time.perf_counter() - t0
        md = write_report(runs, meta, out_dir, command)
        print(f"{name}: {len(runs)} runs in {meta['wall_time']:.0f} s; report {md}")
        print(f"  {_blas_text(meta)}; times: {SPREAD}")
        t_lin = meta.get("linear_time")
        if t_lin:
            print(f"  linear baseline ({name}L modal filters): {_linear_spread(meta)}")
        for target in meta["targets"]:
            top = ranking(runs, target)[:3]
            print(f"  fastest at max error <= {target:g}: " + "; ".join(
                f"{r.method} ({r.setting}) {r.max_error:.1e} in {r.spread()} ms"
                + (f" ({r.price(t_lin):.2g}x linear)" if t_lin else "")
                for r in top))
        written.append(md)
    return written


# --- the ranking from one report to the next ----------------------------------------------------

@dataclass(frozen=True)
class RankChange:
    """Two methods ranked in opposite orders by two reports although each of the two
    separates their run times (their [min, max] ranges are disjoint in both).

    ``first``, ``second``: the indices of the two reports (in the order given to
    `rank_changes`); ``faster_first``: the method faster in report ``first`` (by the median),
    ``faster_second`` the other one, faster in report ``second``; ``spreads``: each method's
    (min, median, max) run time in each report, s."""
    target: float
    first: int
    second: int
    faster_first: str
    faster_second: str
    spreads: dict

    def __str__(self):
        a, b = self.faster_first, self.faster_second

        def ms(method, i):
            lo, med, hi = self.spreads[method][i]
            return f"{med * 1e3:.3g} [{lo * 1e3:.3g}, {hi * 1e3:.3g}] ms"
        return (f"max error <= {self.target:g}: report {self.first}: {a} {ms(a, 0)} before "
                f"{b} {ms(b, 0)}; report {self.second}: {b} {ms(b, 1)} before {a} {ms(a, 1)}")


def _load(result):
    """A bench result as (runs, meta): from (runs, meta), a report's JSON data or its path."""
    if isinstance(result, (str, Path)):
        result = json.loads(Path(result).read_text())
    if isinstance(result, dict):
        fields = Run.__dataclass_fields__
        return ([Run(**{k: v for k, v in r.items() if k in fields}) for r in result["runs"]],
                result["meta"])
    runs, meta = result
    return list(runs), meta


def rank_changes(*results, targets=None):
    """Rank changes between two or three bench reports that their spreads do not explain.

    For each accuracy target, each report ranks the methods that reach it by their fastest
    run's median time (`ranking`). Two methods whose run times' ranges [min, max] over the
    repeats overlap in a report are not ordered by it: their ranks may swap from that report
    to another within the noise. A pair of methods ranked in opposite orders by two of the
    reports is reported when the ranges are disjoint in both: each report orders the two
    beyond its repeats' spread, and they disagree (a run-to-run change the repeats of one run
    do not show, such as a BLAS call of a small matrix taking 0.6 ms in one report and 35 ms
    in every repeat of the next). Methods missing from one of the two rankings are not
    compared.

    Parameters
    ----------
    *results : (runs, meta), dict or path
        Two or three reports of the same problem: what `bench_p3` / `bench_p4` return, the
        JSON data `write_report` writes (``bench_P3.json``) or its path.
    targets : sequence of float, optional
        The accuracy targets to compare at (default: the first report's ``meta["targets"]``).

    Returns
    -------
    list of RankChange
        Empty when every rank change is among methods whose spreads overlap.

    Examples
    --------
    >>> def report(a, b):  # methods a and b, run times (min, median, max) in ms
    ...     runs = [Run(m, "f", "s", 1e-4, 1e-5, t[1] / 1e3, 0.0, run_time_min=t[0] / 1e3,
    ...                 run_time_max=t[2] / 1e3, repeats=3) for m, t in (("a", a), ("b", b))]
    ...     return runs, {"problem": "X", "targets": [1e-3]}
    >>> rank_changes(report((1, 1.1, 1.2), (3, 3, 3.1)), report((2, 3, 4), (1.5, 2, 2.5)))
    []
    >>> for change in rank_changes(report((1, 1.1, 1.2), (3, 3, 3.1)),
    ...                            report((30, 32, 35), (1.5, 2, 2.5))):
    ...     print(change)  # doctest: +NORMALIZE_WHITESPACE
    max error <= 0.001: report 0: a 1.1 [1, 1.2] ms before b 3 [3, 3.1] ms;
    report 1: b 2 [1.5, 2.5] ms before a 32 [30, 35] ms
    """
    loaded = [_load(r) for r in results]
    if not 2 <= len(loaded) <= 3:
        raise ValueError(f"rank_changes compares 2 or 3 bench results; got {len(loaded)}")
    problems_ = {meta.get("problem") for _, meta in loaded}
    if len(problems_) > 1:
        raise ValueError(f"rank_changes compares reports of one problem; got problems "
                         f"{sorted(map(str, problems_))}")
    if targets is None:
        targets = loaded[0][1]["targets"]
    changes = []
    for target in targets:
        ranked = [{r.method: (k, r) for k, r in enumerate(ranking(runs, target))}
                  for runs, _ in loaded]
        for i, j in itertools.combinations(range(len(loaded)), 2):
            common = [m for m in ranked[i] if m in ranked[j]]
            for a, b in itertools.combinations(common, 2):
                (ka, ra), (kb, rb) = ranked[i][a], ranked[i][b]
                (la, sa), (lb, sb) = ranked[j][a], ranked[j][b]
                if (ka < kb) == (la < lb):
                    continue  # same order
                if _overlap(ra, rb) or _overlap(sa, sb):
                    continue  # one of the reports does not order them: within its spread
                fast, slow = (a, b) if ka < kb else (b, a)
                spreads = {m: tuple((_range(x)[0], x.run_time, _range(x)[1])
                                    for x in (ranked[i][m][1], ranked[j][m][1]))
                           for m in (fast, slow)}
                changes.append(RankChange(target, i, j, fast, slow, spreads))
    return changes


def _range(r):
    """(min, max) of a run's repeats (a run without them: its time, twice)."""
    return (r.run_time if r.run_time_min is None else r.run_time_min,
            r.run_time if r.run_time_max is None else r.run_time_max)


def _overlap(r, s):
    """Whether the [min, max] run time ranges of two runs intersect."""
    (lo_r, hi_r), (lo_s, hi_s) = _range(r), _range(s)
    return lo_r <= hi_s and lo_s <= hi_r
