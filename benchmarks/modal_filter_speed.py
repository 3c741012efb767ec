"""Modal filter speed and long-record accuracy: dtdyn's two filter forms against scipy.signal.

Writes docs/modal_filter_speed.md. Run from the repository root:

    python benchmarks/modal_filter_speed.py

Problem: P3 (`dtdyn.problem("P3")`), the 15-DOF chain, as given: undamped (C = 0). The
modal model keeps its undamped poles (Re s = 0, allowed by dtdyn.modal._model); damping would
not change the work per sample. Force on DOF 14 (0-based), random piecewise-linear (standard
normal samples, first one 0), fs = 2000 Hz, ramp invariant, 1,000,000 samples.

The two forms of dtdyn.modal._filters (its module docstring):
- sections: one real second-order section per mode and output (15 for one output, 225 for all
  15), generated C kernel filter_bank.c;
- modes: one complex state per mode (15), updated in increment form, outputs formed from the
  states by one product with the mode shapes, generated C kernel modal_states.c.

(a) The filters alone, for the displacement of DOF 14 and of all 15 DOFs: run_bank (C) and
    run_modes (C); scipy.signal.sosfilt on the same sections (each row filtered separately and
    the outputs summed: the same work as the parallel bank) and, for one output and reference
    only, one sosfilt call over all 15 rows (a cascade: a different filter, same number of
    section updates); the NumPy fallbacks (scipy.signal.lfilter per section / per state, timed
    on 200,000 samples and extrapolated).
(b) The whole response, modal_filter_response (modal model + coefficients + filters) with
    method "modes", "sections" and "auto", against scipy.signal.lsim (first-order form from
    dtdyn.linear._discretize.first_order_form, linear interpolation, i.e. the same piecewise-
    linear force), whose Python loop is timed on 100,000 samples and extrapolated linearly (its
    cost per step is constant). The maximum relative difference is measured on the common
    first 100,000 samples.
(c) Accuracy over the whole record, DOF 14. Truth: the same modal model (its double-precision
    poles and residues taken as exact) filtered in 80-bit extended precision (numpy.longdouble,
    scipy.signal.lfilter) with e^{sT}, c0, c1 computed in 40-digit arithmetic (mpmath): the
    ramp invariant is exact for this force, so this isolates each filter's own round-off
    (its drift: ~1e-19 per step). exact_response (matrix exponential, the reference of the
    tests) is compared too: its difference from the truth also contains the eigensolver's error
    in the poles.
Times: median [min, max] of repeats after one warm-up call (which also compiles the C kernels),
BLAS pinned to one thread (dtdyn.app.pin_blas, threadpoolctl).
"""
from __future__ import annotations

import contextlib
import functools
import io
import os
import pathlib
import platform
import sys
import time

import mpmath
import numpy as np
import scipy
import scipy.signal as sig

from dtdyn.app import Timing, measure, pin_blas
from dtdyn.linear._chain import chain_matrices
from dtdyn.linear._discretize import first_order_form
from dtdyn.linear._exact import exact_response
from dtdyn.modal._model import modal_model
from dtdyn.modal._filters import (modal_filter_response, modal_states, run_bank, run_modes,
                                         sections)

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from problems import P3  # noqa: E402

N = 1_000_000
N_LSIM = 100_000
N_LF = 200_000
FS = 2000.0
LOADED = 14


def timed(fn, repeats):
    """(Timing: median and spread of ``repeats`` calls after a warm-up, last result)."""
    out, t = measure(fn, repeats)
    return t, out


def rel_diff(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def ms(t):
    return f"{t.format():>26s}" if isinstance(t, Timing) else f"{t * 1e3:9.1f} ms"


def extended_precision_truth(model, force):
    """y = sum_r 2 Re(eta_r), eta_r the ramp-invariant recursion of mode r in long double with
    e^{sT}, c0, c1 (residue included) evaluated by mpmath (40 digits) from the model's poles."""
    mpmath.mp.dps = 40
    T = mpmath.mpf(1) / int(FS)

    def ld(v):
        re, im = (np.longdouble(mpmath.nstr(part, 30)) for part in (v.real, v.imag))
        return re + 1j * im

    x = force.astype(np.clongdouble)
    y = np.zeros(force.size, np.longdouble)
    for s, R in zip(model.poles, model.residues[:, 0, 0]):
        sm, Rm = mpmath.mpc(s.real, s.imag), mpmath.mpc(R.real, R.imag)
        e = mpmath.exp(sm * T)
        c1 = Rm * (e - 1 - sm * T) / (sm * sm * T)  # weight of x_n (the ramp invariant's N0)
        c0 = Rm * (1 + (sm * T - 1) * e) / (sm * sm * T)  # weight of x_{n-1} (N1)
        b = np.array([ld(c1), ld(c0)], np.clongdouble)
        a = np.array([1, -ld(e)], np.clongdouble)
        y += 2 * sig.lfilter(b, a, x).real
    return y.astype(float)


def main():
    M, C, K = chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)
    n = M.shape[0]
    rng = np.random.default_rng(0)
    force = rng.standard_normal(N)
    force[0] = 0.0
    x = force[:, None]
    print(f"P3 undamped 15-DOF chain, force on DOF {LOADED}, fs = {FS:g} Hz, ramp invariant, "
          f"{N:,} samples; {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}")

    # (a) the filters alone
    print("\n(a) the filters alone")
    kernel = {}
    for outputs in ([LOADED], list(range(n))):
        n_out = len(outputs)
        model = modal_model(M, C, K, [LOADED], outputs)
        sos, in_col, out_col, direct = sections(model, FS, "ramp")
        st = modal_states(model, FS, "ramp")
        sos6 = np.column_stack([sos[:, :3], np.ones(len(sos)), sos[:, 3:]])
        rep = 3 if n_out == 1 else 2
        t_bank, y_bank = timed(functools.partial(run_bank, sos, in_col, out_col, direct, x,
                                                   n_out), rep)
        t_modes, y_modes = timed(functools.partial(run_modes, st, x), rep)

        def rowwise(n_out=n_out, sos6=sos6, out_col=out_col):
            y = np.zeros((N, n_out))
            for row, o in zip(sos6, out_col):
                y[:, o] += sig.sosfilt(row[None, :], force)
            return y

        t_rows, y_rows = timed(rowwise, 3)
        t_lf, _ = timed(functools.partial(run_bank, sos, in_col, out_col, direct, x[:N_LF],
                                            n_out, backend="numpy"), 3)
        t_lfm, _ = timed(functools.partial(run_modes, st, x[:N_LF], backend="numpy"), 3)
        scale = N / N_LF
        kernel[n_out] = (t_bank, t_modes, t_rows)
        label = "DOF 14" if n_out == 1 else "all 15 DOFs"
        print(f"   displacement of {label}: {len(sos)} sections, {st.n_states} modal states")
        print(f"      run_bank, sections (generated C)          {ms(t_bank)}  "
              f"({t_bank / N / len(sos) * 1e9:.2f} ns per sample and section)")
        print(f"      run_modes, per mode (generated C)         {ms(t_modes)}  "
              f"({t_modes / N * 1e9:.1f} ns per sample)")
        print(f"      sosfilt, each row separately, summed      {ms(t_rows)}  "
              f"({t_rows / N / len(sos) * 1e9:.2f} ns per sample and section)")
        if n_out == 1:
            t_casc, _ = timed(functools.partial(sig.sosfilt, sos6, force), 3)
            print(f"      sosfilt, one call, rows as a cascade      {ms(t_casc)}  "
                  "(reference only: a different filter)")
        print(f"      NumPy fallback, lfilter per section       {ms(t_lf.scaled(scale))}  "
              f"(extrapolated from {N_LF:,} samples)")
        print(f"      NumPy fallback, lfilter per modal state   {ms(t_lfm.scaled(scale))}  "
              f"(extrapolated from {N_LF:,} samples)")
        print(f"      speed-up over row-wise sosfilt: bank {t_rows / t_bank:.1f}x (target >= 1x), "
              f"per mode {t_rows / t_modes:.1f}x; per mode vs bank {t_bank / t_modes:.1f}x")
        print(f"      max relative difference: bank vs sosfilt {rel_diff(y_bank, y_rows):.1e}, "
              f"per mode vs bank {rel_diff(y_modes, y_bank):.1e} (whole record)")

    # (b) the whole response against lsim
    A, B = first_order_form(M, C, K)
    t = np.arange(N_LSIM) / FS
    print(f"\n(b) whole response, modal_filter_response on {N:,} samples vs scipy.signal.lsim "
          f"(timed on {N_LSIM:,} samples, extrapolated x{N // N_LSIM})")
    for outputs in ([LOADED], list(range(n))):
        n_out = len(outputs)
        Cm = np.zeros((n_out, 2 * n))
        Cm[np.arange(n_out), outputs] = 1.0
        system = (A, B[:, [LOADED]], Cm, np.zeros((n_out, 1)))
        t_ls, (_, y_ls, _) = timed(functools.partial(sig.lsim, system, force[:N_LSIM], t), 3)
        y_ls = np.reshape(y_ls, (N_LSIM, n_out))
        t_ls_full = t_ls.scaled(N / N_LSIM)
        label = "DOF 14" if n_out == 1 else "all 15 DOFs"
        print(f"   outputs {label}:")
        print(f"      scipy.signal.lsim              {ms(t_ls_full)}  (extrapolated; measured "
              f"{t_ls.format()} on {N_LSIM:,} samples)")
        for method in ("modes", "sections", "auto"):
            t_mf, r = timed(functools.partial(modal_filter_response, M, C, K, x, 1 / FS,
                                                force_dofs=[LOADED], outputs=outputs,
                                                algorithm=method, quantities=("x",)),
                              3 if n_out == 1 else 2)
            diff = rel_diff(r.x[:N_LSIM], y_ls)
            print(f"      method={method + ',':10s} {r.info['filters']:8s}  {ms(t_mf)}  "
                  f"(coefficients {r.info['setup_time'] * 1e3:.1f} ms, filters "
                  f"{r.info['run_time'] * 1e3:.1f} ms); {t_ls_full / t_mf:.1f}x faster than lsim; "
                  f"max relative difference {diff:.1e}")
        print("      (target: >= 20x faster than lsim)")

    # (c) accuracy over the whole record
    model = modal_model(M, C, K, [LOADED], [LOADED])
    t0 = time.perf_counter()
    truth = extended_precision_truth(model, force)
    t_truth = time.perf_counter() - t0
    t0 = time.perf_counter()
    ex = exact_response(M, C, K, x, 1 / FS, force_dofs=[LOADED], outputs=[LOADED]).x[:, 0]
    t_ex = time.perf_counter() - t0
    ys = {
        "modes (C, increment form)": modal_filter_response(M, C, K, x, 1 / FS, force_dofs=[LOADED],
                                                           outputs=[LOADED], algorithm="modes",
                                                           quantities=("x",)).x[:, 0],
        "modes (lfilter, pole e^sT)": modal_filter_response(M, C, K, x, 1 / FS, force_dofs=[LOADED],
                                                            outputs=[LOADED], algorithm="modes",
                                                            backend="numpy",
                                                            quantities=("x",)).x[:, 0],
        "sections (C)": modal_filter_response(M, C, K, x, 1 / FS, force_dofs=[LOADED],
                                              outputs=[LOADED], algorithm="sections",
                                              quantities=("x",)).x[:, 0],
        "exact_response": ex,
    }
    print(f"\n(c) accuracy, DOF 14, max |y - truth| over the first n samples / max |truth| "
          f"(truth: extended precision, {t_truth:.1f} s; exact_response took {t_ex:.1f} s)")
    marks = (1_000, 10_000, 100_000, 1_000_000)
    print("   " + " " * 28 + "".join(f"n = {m:>9,}  " for m in marks))
    ref = np.max(np.abs(truth))
    for name, y in ys.items():
        print(f"   {name:28s}" + "".join(f"{np.max(np.abs(y[:m] - truth[:m])) / ref:13.1e}  "
                                         for m in marks))
    print("   against exact_response instead of the truth:")
    for name in ("modes (C, increment form)", "sections (C)"):
        y = ys[name]
        print(f"   {name:28s}" + "".join(f"{np.max(np.abs(y[:m] - ex[:m])) / ref:13.1e}  "
                                         for m in marks))
    w1 = model.omega[0]
    eps = np.finfo(float).eps
    print(f"   mode 1: theta = |s_1| T = {w1 / FS:.2e}. A section stores a1 = -2 cos(theta), "
          f"whose rounding moves theta by ~ eps / theta = {eps / (w1 / FS):.1e} (a relative "
          "frequency "
          f"error ~ {eps / (w1 / FS) ** 2:.1e}, a phase error that grows with n); the per-mode "
          f"form stores d = e^(sT) - 1 to ~ eps |d| = {eps * w1 / FS:.1e}.")


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(pin.describe())
        main()
    print(buf.getvalue(), end="")
    doc = ROOT / "docs" / "modal_filter_speed.md"
    doc.write_text("# Modal filter speed and long-record accuracy\n\nOutput of "
                   "`python benchmarks/modal_filter_speed.py` (2-core shared machine; ratios "
                   "measured in one run). What is timed and the reference of (c): the script's "
                   "docstring.\n\n```\n" + buf.getvalue() + "```\n")
