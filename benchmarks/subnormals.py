"""Cost of responses that decay to zero: subnormal numbers in the C loops, measured in one run.

A response that dies out (a shock pulse followed by quiet; a wave entering a chain at rest,
whose far masses move by 1e-200, then 1e-310, then 0) passes through the subnormal range
(|x| < 2.2e-308), where an arithmetic operation can cost about a hundred cycles, and a lightly
damped recursion can stay there for the rest of the record. The C kernels run with subnormals
flushed to zero (the results change only near 2.2e-308), so such a record costs what a record
that never decays costs. Each case is timed against the same case with no value ever near
underflow (a noise floor of 1e-12 added to the record, or a random initial state of 1e-3): a
ratio near 1 means the decay costs nothing extra. Run on the code before the flush (commit
aae8357), the four ratios were 6.69, 10.45, 1.42 and 2.00 on this 2-core machine.

Times: median [min, max] of repeats after one warm-up run, BLAS pinned to one thread
(dtdyn.app.pin_blas, threadpoolctl); ratios of the medians.
Usage: python benchmarks/subnormals.py [--quick]
"""
from __future__ import annotations

import functools
import sys
import warnings

import numpy as np

import dtdyn as dd
from dtdyn.app import measure, pin_blas


def timed(fn, repeats):
    """Timing (median, spread) of ``repeats`` calls after a warm-up (and compilation)."""
    return measure(fn, repeats)[1]


def row(name, t_decay, t_floor, unit, count):
    print(f"   {name:<38s} {t_decay.format('ms'):>22s}  {t_floor.format('ms'):>22s}  "
          f"{t_decay / t_floor:5.2f}   ({t_decay / count * 1e9:.2f} ns per {unit})")


def main(quick=False):
    repeats = 3 if quick else 5
    rng = np.random.default_rng(0)
    print("case                                   decaying to 0, median     never near underflow"
          "    ratio")
    print("                                           [min, max]")

    # 1) shock response spectrum: a 5 ms half-sine, then quiet, 20 s at 10 kHz, 60 oscillators
    fs, n = 10_000.0, 100_000 if quick else 200_000
    pulse = np.zeros(n)
    pulse[:50] = np.sin(np.pi * np.arange(50) / 50)
    floor = pulse + 1e-12 * rng.standard_normal(n)
    freqs = np.geomspace(10.0, 2000.0, 60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dd.SRSSamplingWarning)
        for zeta in (0.05, 0.3):
            t = [timed(functools.partial(dd.shock_response_spectrum, a, 1 / fs, freqs,
                                           damping_ratio=zeta, workers=1), repeats)
                 for a in (pulse, floor)]
            row(f"SRS, half-sine then quiet, zeta {zeta}", *t, "sample-oscillator",
                n * freqs.size)

    # 2) DT-TMM chain from rest, loaded at its tip: the wave reaches about 10 masses in 0.1 s
    N, steps = 1000, 1000
    m, k, c = np.ones(N), np.full(N, 1e4), np.ones(N)
    F = np.ones((steps + 1, 1))
    x0 = 1e-3 * rng.standard_normal(N)
    t = [timed(lambda x0=x0: dd.chain_response(m, k, c, F, 1e-4, force_dofs=[N - 1],
                                                 outputs=[N - 1], quantities=("x",), x0=x0),
                 repeats) for x0 in (None, x0)]
    row(f"DT-TMM chain, {N} masses, from rest", *t, "mass-step", N * steps)

    # 3) modal filters (P4's linear model): an impulse, then quiet
    p4 = dd.problem("P4", n_samples=n)
    M, C, K = (p4[key] for key in ("M", "C", "K"))
    imp = np.zeros((n, 1))
    imp[0, 0] = 100.0
    imp_floor = imp + 1e-12 * rng.standard_normal(imp.shape)
    t = [timed(lambda f=f: dd.modal_filter_response(M, C, K, f, p4["dt"], force_dofs=[3],
                                                      quantities=("x",)), repeats)
         for f in (imp, imp_floor)]
    row("modal filters, P4L, impulse then quiet", *t, "sample", n)


if __name__ == "__main__":
    import contextlib
    import io
    import pathlib

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        main(quick="--quick" in sys.argv)
    print(buf.getvalue(), end="")
    if "--quick" not in sys.argv:
        doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "subnormals.md"
        doc.write_text(
            "# Responses that decay to zero\n\n"
            "A response that dies out passes through the subnormal numbers (|x| < 2.2e-308) on its "
            "way to zero, where each operation can cost about a hundred cycles, and a lightly "
            "damped "
            "recursion can stay there for the rest of the record. dtdyn's C kernels set the "
            "processor to flush subnormal results and operands to zero while they run (x86: "
            "MXCSR's FTZ and DAZ bits; AArch64: FPCR's FZ bit) and restore the caller's mode on "
            "return, so a decaying record costs what a record that never decays costs. The results "
            "change only near the underflow threshold: where gradual underflow would take a "
            "decaying recursion through the subnormals to 0, the flushed one can settle into a "
            "limit cycle just above 2.2e-308 (below 1e-300 for the filters of "
            "tests/behaviour/test_subnormals.py, which checks them against scipy.signal.lfilter). "
            "The NumPy and SciPy paths do not flush.\n\n"
            "Output of `python benchmarks/subnormals.py` (2-core shared machine; each "
            "ratio is measured in one run, against the same case kept away from underflow by a "
            "noise floor of 1e-12 or a random initial state):\n\n```\n" + buf.getvalue() + "```\n"
            "\nThe same script on the code before the flush (commit aae8357), same machine and "
            "session: ratios 6.69, 10.45, 1.42 and 2.00.\n")
