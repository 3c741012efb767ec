"""Modal filter bank speed: the generated C bank against scipy.signal, measured in one run.

Writes docs/modal_filter_speed.md. Run from the repository root:

    python benchmarks/modal_filter_speed.py

Problem: P3 (shared/reference.md section 7), the 15-DOF chain, as given: undamped (C = 0). The
modal model keeps its undamped poles (Re s = 0, allowed by dtdyn.runtime.modal); damping would
not change the work per sample (one second-order section per mode and output/input pair).
Force on DOF 14 (0-based), random piecewise-linear (standard normal samples, first one 0),
fs = 2000 Hz, ramp invariant.

(a) The filter bank alone on 1,000,000 samples, displacement of DOF 14: dtdyn's run_bank (C)
    against scipy.signal.sosfilt on the same 15 sections, each row filtered separately and the
    outputs summed (the same work as the parallel bank), and, for reference only, one sosfilt
    call over all 15 rows (a cascade: a different filter, same number of section updates).
(b) The whole response: modal_filter_response (modal model + sections + C bank) on 1,000,000
    samples against scipy.signal.lsim (first-order form from
    dtdyn.runtime.discretize.first_order_form, linear interpolation, i.e. the same
    piecewise-linear force), whose Python loop is timed on 100,000 samples and extrapolated
    linearly to 1,000,000 (its cost per step is constant). Outputs: DOF 14 (15 sections) and
    all 15 DOFs (225 sections). The maximum relative difference is measured on the common
    first 100,000 samples; a diagnosis of the 15-output case, and the accuracy of both against
    exact_response over the first 1,000 / 10,000 / 100,000 samples.
Times: minimum of repeats after one warm-up call (which also compiles the C kernel).
"""
from __future__ import annotations

import contextlib
import io
import os
import pathlib
import platform
import sys
import time

import numpy as np
import scipy
import scipy.signal as sig

from dtdyn.runtime.chain import chain_matrices
from dtdyn.runtime.discretize import first_order_form
from dtdyn.runtime.exact import exact_response
from dtdyn.runtime.modal import modal_model
from dtdyn.runtime.modal_filters import modal_filter_response, run_bank, sections

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from problems import P3  # noqa: E402

N_BANK = 1_000_000
N_LSIM = 100_000
FS = 2000.0
LOADED = 14


def best_of(fn, repeats):
    out = fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def rel_diff(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def main():
    M, C, K = chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)
    n = M.shape[0]
    rng = np.random.default_rng(0)
    force = rng.standard_normal(N_BANK)
    force[0] = 0.0
    x = force[:, None]
    print(f"P3 undamped 15-DOF chain, force on DOF {LOADED}, fs = {FS:g} Hz, ramp invariant; "
          f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"NumPy {np.__version__}, SciPy {scipy.__version__}")

    # (a) the bank alone
    model = modal_model(M, C, K, [LOADED], [LOADED])
    sos, in_col, out_col, direct = sections(model, FS, "ramp")
    sos6 = np.column_stack([sos[:, :3], np.ones(len(sos)), sos[:, 3:]])
    t_bank, y_bank = best_of(lambda: run_bank(sos, in_col, out_col, direct, x, 1), 5)
    t_rows, y_rows = best_of(lambda: sum(sig.sosfilt(row[None, :], force) for row in sos6), 3)
    t_casc, _ = best_of(lambda: sig.sosfilt(sos6, force), 3)
    n_lf = 200_000
    t_lf, _ = best_of(lambda: run_bank(sos, in_col, out_col, direct, x[:n_lf], 1,
                                       backend="numpy"), 2)
    print(f"\n(a) filter bank, {len(sos)} sections (one per mode), {N_BANK:,} samples, "
          "displacement of DOF 14")
    print(f"   run_bank (generated C)                    {t_bank * 1e3:8.1f} ms  "
          f"({t_bank / N_BANK / len(sos) * 1e9:.2f} ns per sample and section)")
    print(f"   sosfilt, each row separately, summed      {t_rows * 1e3:8.1f} ms  "
          f"({t_rows / N_BANK / len(sos) * 1e9:.2f} ns per sample and section)")
    print(f"   sosfilt, one call, rows as a cascade      {t_casc * 1e3:8.1f} ms  "
          "(reference only: a different filter)")
    print(f"   run_bank NumPy fallback (lfilter per row) {t_lf / n_lf * N_BANK * 1e3:8.1f} ms  "
          f"(extrapolated from {n_lf:,} samples)")
    print(f"   bank / row-wise sosfilt speed-up {t_rows / t_bank:.2f}x (target >= 1x); vs the "
          f"cascade {t_casc / t_bank:.2f}x; max relative difference bank vs row-wise sosfilt "
          f"{rel_diff(y_bank[:, 0], y_rows):.1e}")

    # (b) whole response against lsim
    A, B = first_order_form(M, C, K)
    t = np.arange(N_LSIM) / FS
    print(f"\n(b) whole response, modal_filter_response on {N_BANK:,} samples vs scipy.signal.lsim "
          f"(timed on {N_LSIM:,} samples, extrapolated x{N_BANK // N_LSIM})")
    results = {}
    for outputs in ([LOADED], list(range(n))):
        Cm = np.zeros((len(outputs), 2 * n))
        Cm[np.arange(len(outputs)), outputs] = 1.0
        system = (A, B[:, [LOADED]], Cm, np.zeros((len(outputs), 1)))
        t_mf, r = best_of(lambda: modal_filter_response(x, FS, M, C, K, [LOADED], outputs),
                          3 if len(outputs) == 1 else 2)
        t_ls, (_, y_ls, _) = best_of(lambda: sig.lsim(system, force[:N_LSIM], t), 1)
        y_ls = np.reshape(y_ls, (N_LSIM, len(outputs)))
        results[len(outputs)] = (r, y_ls)
        t_ls_full = t_ls * N_BANK / N_LSIM
        diff = rel_diff(r.x[:N_LSIM], y_ls)
        label = "DOF 14" if len(outputs) == 1 else "all 15 DOFs"
        print(f"   outputs {label}: {r.info['sections']} sections")
        print(f"      modal_filter_response   {t_mf * 1e3:9.1f} ms  (sections "
              f"{r.info['setup_time'] * 1e3:.2f} ms, bank {r.info['run_time'] * 1e3:.1f} ms)")
        print(f"      scipy.signal.lsim       {t_ls_full * 1e3:9.1f} ms  (extrapolated; measured "
              f"{t_ls * 1e3:.1f} ms on {N_LSIM:,} samples)")
        print(f"      speed-up {t_ls_full / t_mf:.1f}x (target >= 20x); max relative difference "
              f"{diff:.1e} (first {N_LSIM:,} samples)")

    # diagnosis of the 15-output case: the bank's passes write y (n, n_out) with stride n_out;
    # the same sections run output by output into contiguous arrays
    model15 = modal_model(M, C, K, [LOADED], list(range(n)))
    sos15, in15, out15, direct15 = sections(model15, FS, "ramp")

    def per_output():
        y = np.empty((n, N_BANK))
        for o in range(n):
            keep = out15 == o
            y[o] = run_bank(sos15[keep], in15[keep], np.zeros(int(keep.sum()), np.int64),
                            direct15[[o]], x, 1)[:, 0]
        return y

    t_po, y_po = best_of(per_output, 2)
    same = rel_diff(y_po.T, results[n][0].x)
    print(f"   diagnosis, all 15 DOFs: the same 225 sections run output by output into contiguous "
          f"arrays take {t_po * 1e3:.1f} ms (max relative difference {same:.1e}); the gap to the "
          "bank time above is the cost of one pass per section over the whole (n, 15) output, "
          "written with stride 15")

    # accuracy against exact_response (matrix exponential, exact for the piecewise-linear force)
    ex = exact_response(M, C, K, x[:N_LSIM], 1 / FS, N_LSIM - 1, loaded=[LOADED],
                        outputs=[LOADED]).x[:, 0]
    r1, yl1 = results[1]
    print("\naccuracy, DOF 14, against exact_response (max relative error over the first n "
          "samples; P3 is undamped, so an error in a modal frequency grows linearly with n):")
    for m in (1_000, 10_000, 100_000):
        print(f"   n = {m:>7,}: modal filters {rel_diff(r1.x[:m, 0], ex[:m]):.1e}, lsim "
              f"{rel_diff(yl1[:m, 0], ex[:m]):.1e}")
    w1 = model.frequencies[0]
    print(f"   the section's pole angle theta = |s_1| T = {w1 / FS:.2e} for the lowest mode is "
          f"stored through a1 = -2 cos(theta); its rounding perturbs the modal frequency by "
          f"~ eps / theta^2 = {np.finfo(float).eps / (w1 / FS) ** 2:.1e} relative")


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main()
    print(buf.getvalue(), end="")
    doc = ROOT / "docs" / "modal_filter_speed.md"
    doc.write_text("# Modal filter bank speed\n\nOutput of "
                   "`python benchmarks/modal_filter_speed.py` (2-core shared machine; ratios "
                   "measured in one run). What is timed: the script's docstring.\n\n```\n"
                   + buf.getvalue() + "```\n")
