"""Rainflow counting speed: dtdyn.rainflow_cycles (C loop) against the `rainflow` package's
extract_cycles, measured in one run on the same record.

A Gaussian record of 10,000,000 samples (seeded; about 6.7 million reversals). Timed:
- ours, C loop (turning points, stack count, ranges and means): warm-up (compile or load), then
  3 repeats, median [min, max];
- ours, NumPy fallback (vectorized turning points, Python stack loop): once on the first
  1,000,000 samples, scaled to the record (it is O(n));
- rainflow.extract_cycles (pure Python), list of every cycle: once on the whole record.
The cycles are checked to be identical (range, mean, count, start, end) before the times are
printed. Usage: python benchmarks/rainflow_speed.py [n_samples]
"""
from __future__ import annotations

import os
import platform
import sys

import numpy as np
import rainflow

from dtdyn.app import measure, pin_blas
from dtdyn.random_vibration._rainflow import rainflow_cycles


def main(n=10_000_000):
    x = np.random.default_rng(0).standard_normal(n)
    print(f"rainflow counting of {n:,} Gaussian samples; {os.cpu_count()} CPUs, "
          f"{platform.processor() or platform.machine()}; numpy {np.__version__}, "
          f"rainflow {rainflow.__version__}")
    ours, t_c = measure(lambda: rainflow_cycles(x), repeats=3)
    assert ours.info["backend"] == "c", ours.info
    m = min(n, 1_000_000)
    _, t_np = measure(lambda: rainflow_cycles(x[:m], backend="numpy"), repeats=1, warmup=False)
    t_np = t_np.scaled(n / m)
    ref, t_rf = measure(lambda: list(rainflow.extract_cycles(x)), repeats=1, warmup=False)
    same = len(ref) == ours.ranges.size and all(
        np.array_equal(np.array([r[j] for r in ref]), a)
        for j, a in enumerate((ours.ranges, ours.means, ours.counts, ours.start, ours.end)))
    assert same, "cycles differ from rainflow.extract_cycles"
    print(f"{ours.ranges.size:,} cycles ({ours.info['n_turning_points']:,} reversals), "
          f"identical to rainflow.extract_cycles")
    rows = [("dtdyn rainflow_cycles, C", t_c),
            (f"dtdyn rainflow_cycles, NumPy fallback (scaled from {m:,})", t_np),
            ("rainflow.extract_cycles 3.2 (pure Python)", t_rf)]
    print(f"   {'':52s} {'time [s], median [min, max]':>28s} {'ns/sample':>10s} "
          f"{'vs C':>8s}")
    for name, t in rows:
        print(f"   {name:52s} {t.format('s').replace(' s', '', 1):>28s} {t / n * 1e9:10.1f} "
              f"{t / t_c:7.1f}x")
    print(f"speed-up of the C count over rainflow.extract_cycles: {t_rf / t_c:.0f}x "
          f"(same run, same record)")


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(pin.describe())
        main(int(float(sys.argv[1])) if len(sys.argv) > 1 else 10_000_000)
