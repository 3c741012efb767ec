"""Shock response spectrum speed: dtdyn.modal._srs against pyyeti.srs.srs, measured in one run.

1,000,000 samples (10 s at 100 kHz: a train of half-sine and decaying-sine shocks in noise) at
200 log-spaced frequencies, 10 Hz .. 10 kHz (>= 10 points per cycle, so neither code upsamples),
5 % damping, absolute acceleration, total window (primary + residual), peaks at the samples.

Compared, each timed 3 times (median [min, max]; the C kernel compiled or loaded first), BLAS
pinned to one thread (dtdyn.app.pin_blas, threadpoolctl; the SRS threads are dtdyn's own):
- ours, 1 thread and the default (threads = CPU count for a run this size; the C kernel releases
  the GIL), and ours with exact peaks;
- pyyeti.srs.srs(rolloff="none", time="total") with parallel="no" and its default "auto" (if
  importable), which filter with scipy.signal.lfilter per frequency;
- a plain loop of scipy.signal.lfilter per frequency over the same ramp-invariant sections
  (generated coefficients), sampled peaks over the record plus one cycle of zeros of the lowest
  frequency (pyyeti's residual convention) - the like-for-like baseline when pyyeti is absent.
Writes docs/srs_speed.md. Usage: python benchmarks/srs_speed.py
"""
from __future__ import annotations

import contextlib
import io
import os
import pathlib
import platform
import warnings

import numpy as np
import scipy
import scipy.signal as sig

from dtdyn.app import measure, pin_blas
from dtdyn.generated import modal_filters as coef
from dtdyn.modal._srs import _poles_residues, shock_response_spectrum


def record(fs=100e3, n=1_000_000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    a = 0.5 * rng.standard_normal(n)
    for t0 in np.arange(0.2, 9.5, 0.5):  # one shock every 0.5 s
        tau = rng.uniform(0.5e-3, 5e-3)
        m = (t >= t0) & (t <= t0 + tau)
        a[m] += rng.uniform(20, 200) * np.sin(np.pi * (t[m] - t0) / tau)
        f0 = rng.uniform(200, 5000)
        m = (t >= t0 + tau) & (t <= t0 + tau + 0.05)
        a[m] += rng.uniform(5, 50) * np.exp(-(t[m] - t0 - tau) / 0.01) \
            * np.sin(2 * np.pi * f0 * (t[m] - t0 - tau))
    return a


def lfilter_loop(a, fs, freqs, zeta):
    s1, R = _poles_residues(freqs, zeta, "absolute_acceleration")
    b0, b1, b2, a1, a2 = coef.pair_sections("ramp", s1, R, 1.0 / fs)
    x = np.concatenate((a, np.zeros(int(np.ceil(fs / freqs.min())))))
    out = np.empty(freqs.size)
    for j in range(freqs.size):
        y = sig.lfilter([b0[j], b1[j], b2[j]], [1.0, a1[j], a2[j]], x)
        out[j] = max(y.max(), -y.min())
    return out


def timed(fn, repeats=3):
    """(Timing: median and spread of ``repeats`` calls, the last result)."""
    out, t = measure(fn, repeats, warmup=False)
    return t, out


def main():
    fs, zeta = 100e3, 0.05
    a = record(fs)
    freqs = np.geomspace(10.0, 10e3, 200)
    n = a.size
    print(f"SRS of {n:,} samples at fs = {fs:g} Hz, {freqs.size} frequencies "
          f"{freqs[0]:g} .. {freqs[-1]:g} Hz, damping {zeta}, absolute acceleration, total window")
    print(f"machine: {os.cpu_count()} CPUs, {platform.processor() or platform.machine()}; "
          f"numpy {np.__version__}, scipy {scipy.__version__}")
    shock_response_spectrum(a[:1000], 1 / fs, freqs[:2], zeta)  # compile / load the C kernel
    rows = []
    t1, r1 = timed(lambda: shock_response_spectrum(a, 1 / fs, freqs, zeta, workers=1))
    rows.append(("dtdyn srs, 1 thread", t1))
    t2, r2 = timed(lambda: shock_response_spectrum(a, 1 / fs, freqs, zeta))
    rows.append((f"dtdyn srs, {r2.info['workers']} threads (default)", t2))
    t3, r3 = timed(lambda: shock_response_spectrum(a, 1 / fs, freqs, zeta, exact_peaks=True))
    rows.append((f"dtdyn srs, exact peaks, {r3.info['workers']} threads", t3))
    t_lf, m_lf = timed(lambda: lfilter_loop(a, fs, freqs, zeta))
    rows.append(("scipy.signal.lfilter loop (same filter)", t_lf))
    try:
        from pyyeti import srs as pysrs
    except ImportError:
        pysrs = None
    if pysrs is not None:
        kw = dict(stype="absacce", peak="abs", rolloff="none", time="total")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t_py, m_py = timed(lambda: pysrs.srs(a, fs, freqs, 1 / (2 * zeta), parallel="no",
                                                 **kw))
            rows.append(("pyyeti.srs.srs, parallel='no'", t_py))
            t_pa, m_pa = timed(lambda: pysrs.srs(a, fs, freqs, 1 / (2 * zeta), **kw))
            rows.append(("pyyeti.srs.srs, parallel='auto' (default)", t_pa))
    print()
    print(f"   {'':46s} {'time [s], median [min, max]':>28s} {'ns/sample/freq':>15s} "
          f"{'vs dtdyn default':>17s}")
    for name, t in rows:
        print(f"   {name:46s} {t.format('s').removesuffix(' s'):>28s} "
              f"{t / (n * freqs.size) * 1e9:15.2f} {t / t2:16.2f}x")
    print()
    if pysrs is not None:
        print(f"speed-up of dtdyn (default) over pyyeti: {t_py / t2:.1f}x (pyyeti parallel='no'), "
              f"{t_pa / t2:.1f}x (pyyeti default); 1 thread against 1 process: {t_py / t1:.1f}x")
        print(f"max relative difference of maximax, dtdyn vs pyyeti: "
              f"{np.max(np.abs(r2.maximax - m_py) / r2.maximax):.1e} (sampled peaks, same filter; "
              "residual: dtdyn closed form, pyyeti samples)")
    else:
        print("pyyeti not importable: compared with the lfilter loop only")
    print(f"speed-up of dtdyn (default) over the lfilter loop: {t_lf / t2:.1f}x; max relative "
          f"difference {np.max(np.abs(r2.maximax - m_lf) / r2.maximax):.1e}")
    print(f"exact peaks change the spectrum by at most {np.max(r3.maximax / r2.maximax - 1):.1e} "
          f"(peak-picking bound at 10 kHz: {r2.info['peak_error_bound'][-1]:.1e})")


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(pin.describe())
        main()
    print(buf.getvalue(), end="")
    doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "srs_speed.md"
    doc.write_text("# Shock response spectrum speed\n\nOutput of `python benchmarks/srs_speed.py` "
                   "(2-core shared machine; every time the median [min, max] of 3 runs, ratios "
                   "of the medians measured in the same run):\n\n```\n" + buf.getvalue() + "```\n")
