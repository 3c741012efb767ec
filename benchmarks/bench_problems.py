"""The benchmark problems of `dtdyn bench`: what runs on each reference problem (the methods and
their settings, the references, the tables of schemes and targets), timed and reported by
`dtdyn.app._bench` (its timing, ranking and report writer).

P3 (`bench_p3`): every scheme of the scheme table at its defaults on the 15-DOF chain, with the
state-space models, the modal filters and scipy's lsim and solve_ivp as peers, against the
matrix exponential (exact for P3's piecewise-linear force); fixed-step methods sweep dt,
adaptive solvers sweep rtol.

P4 (`bench_p4`): the nonlinear 4-DOF chain, every nonlinear method over sub-steps against the
solve_ivp DOP853 rtol 1e-12 reference restarted at every sample (cached on disk); solve_ivp
peers run on a window of the record and are extrapolated (marked). Every run's time is also
reported over that of the linear modal filter response of P4L (P4 without its cubic springs,
same record, same run): the price of the nonlinearity; and nonlinear_mck_response's accuracy
targets (``accuracy=1e-3, 1e-6``), timed over all the runs each needs, and for scheme "auto"
against the best plain configuration reaching the same target (in the report's description).

`dtdyn bench` loads this file from the source checkout it runs in
(`dtdyn.app._bench.bench_problems`; outside a checkout it says so), e.g.
``dtdyn bench P3 --quick --out bench``.
"""
from __future__ import annotations

import functools
import statistics
import time

import numpy as np

from dtdyn.app import _problems as problems
from dtdyn.app._bench import _blas_pinned, _errors, _recorder, _timed
from dtdyn.app import Timing
from dtdyn.generated.scheme_table import TABLE


# --- P3: linear chain ---------------------------------------------------------------------------

#: every scheme of the table at its defaults, but plain newmark (= average_acceleration at its
#: defaults) and central_difference (explicit: no displacement form for P3's undamped chain)
P3_SCHEMES = [(name, {}) for name in TABLE if name not in ("newmark", "central_difference")]


@_blas_pinned
def bench_p3(quick=False, log=print):
    from scipy import signal
    from scipy.integrate import solve_ivp

    from dtdyn.linear._chain import chain_response
    from dtdyn.linear._discretize import discretize, first_order_form
    from dtdyn.linear._exact import exact_response
    from dtdyn.modal._filters import modal_filter_response
    from dtdyn.linear._state_space import discrete_state_space, state_space_response
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
        # the estimate's outputs: half the modal columns where they read one row of each
        # pair and no element force (modal_explicit with x outputs: nl_loop.h estimate_basis)
        per_sample += 2 * no * (nm // 2 if method == "modal_explicit" else nm + ne)
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


def _accuracy_against_plain(runs, method="auto accuracy"):
    """For each accuracy target run by ``method`` (its setting ``accuracy=...``): its time
    against the best plain configuration reaching the same target (the fastest run without a
    target, of any family, whose max error meets it), as sentences."""
    lines = []
    for r in runs:
        if r.method != method:
            continue
        target = float(r.setting.split("=")[1])
        plain = [p for p in runs if "accuracy" not in p.method and p.max_error <= target]
        if not plain:
            continue
        best = min(plain, key=lambda p: p.run_time)
        paired = ("" if r.linear_time is None or best.linear_time is None else
                  f" ({r.price(None) / best.price(None):.2f})")
        lines.append(f"accuracy={target:g}: {r.run_time * 1e3:.3g} ms (max error "
                     f"{r.max_error:.1e}) against {best.method} {best.setting} "
                     f"{best.run_time * 1e3:.3g} ms (max error {best.max_error:.1e}): "
                     f"{r.run_time / best.run_time:.2f}x{paired}")
    return lines


@_blas_pinned
def bench_p4(quick=False, log=print):
    from scipy.integrate import solve_ivp

    from dtdyn.linear._exact import exact_response
    from dtdyn.modal._filters import modal_filter_response
    from dtdyn.nonlinear._reference import check_reference, reference_response
    from dtdyn.nonlinear._response import nonlinear_mck_response
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
            window = i.get("estimate_window")
            how = (f"one run of the record, the estimator confirmed on its first "
                   f"{window['samples']} samples at {', '.join(map(str, window['substeps']))}"
                   if window else
                   f"{'extrapolated from ' if i['extrapolated'] else 'runs '}"
                   f"{', '.join(map(str, i['estimate_substeps']))}")
            note = (f"{i['scheme']}: estimate {i['error_estimate']:.2e} (x, all 4 DOFs), "
                    f"{i['substeps']} sub-steps ({how})")
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
    against_plain = _accuracy_against_plain(runs)
    for line in against_plain:
        log("  " + line)
    meta = {"problem": "P4", "description": f"nonlinear 4-DOF chain, {n} samples at 1 kHz; error "
            "of x at DOF 3 against solve_ivp DOP853 rtol 1e-12 restarted at every sample "
            f"(reference {'from the disk cache' if ref_r.info.get('cached') else f'{t_ref:.0f} s'}"
            f"; DOP853 vs Radau on 300 samples: {radau:.1e})"
            + (f"; the peak of the flop rates: {peak:.1f} GFLOP/s, one core's multiply-adds on "
               "4-lane vectors (generated/fma_peak.c), measured in the same run" if peak else "")
            + ("; accuracy= against the best plain configuration reaching the same target "
               "(the fastest run without a target whose max error meets it; times in the same "
               "run, their ratio and in parentheses the ratio of their times over the linear "
               "runs paired with each): " + "; ".join(against_plain) if against_plain else ""),
            "targets": [1e-3, 1e-6], "peak_gflops": peak,
            "linear_time": t_lin, "linear_build": lin_build, "linear_error": e_lin,
            "linear_min": min(lin_times), "linear_max": max(lin_times),
            "linear": "modal filter response (ramp invariant, C) of P4L, P4 without its cubic "
                      f"springs, on the same record ({len(lin_times)} runs: 5 before, one before "
                      "each timed run of dtdyn's nonlinear C loops, 5 after),"}
    return runs, meta


#: the problems `dtdyn bench` runs, by name
BENCHES = {"P3": bench_p3, "P4": bench_p4}
