"""Speed of the torsional DT-TMM (tree sweep), with ratios measured in the same run.

1. A 10,000-disk shaft (clamped, J = 1, k_t = 1e4, c_t = 1) and a 10,000-station tree (a main
   line with a geared branch at its middle), 2,000 steps of average acceleration at dt = 1e-4,
   torque step at the far disk: `shaft_response` (generated C tree loop) against `mck_response`
   on the assembled sparse model (`shaft_matrices`), the default C loop (SuperLU factors applied
   in C) and backend="numpy" (scipy.sparse Newmark). Same run, same scheme; the agreement is
   printed.
2. Cost per step of the tree loop for N = 1e3 .. 1e5 stations; the fitted slope of log(time)
   over log(N) is 1 for O(N) per step.

Times: median [min, max] of repeats after one warm-up run, BLAS pinned to one thread
(dtdyn.app.pin_blas, threadpoolctl).
Usage: python benchmarks/shaft_speed.py
"""
from __future__ import annotations

import functools

import numpy as np

import dtdyn as dd
from dtdyn.app import measure, pin_blas


def timed(fn, repeats=3):
    """(Timing: median and spread of ``repeats`` calls after a warm-up, last result)."""
    out, t = measure(fn, repeats)
    return t, out


def line(n):
    return dd.Shaft(np.ones(n), np.full(n, 1e4), np.ones(n))


def tree(n):
    h = n // 2
    br = dd.Branch(h // 2, np.ones(n - h), np.full(n - h, 1e4), np.ones(n - h), ratio=2.0,
                   name="b")
    return dd.Shaft(np.ones(h), np.full(h, 1e4), np.ones(h), branches=[br])


def compare(name, shaft, n_steps=2000, dt=1e-4):
    n = len(shaft.dof_names)
    M, C, K = dd.shaft_matrices(shaft)
    f = np.ones(n_steps + 1)
    kw = dict(force_dofs=[n - 1], outputs=[0, n - 1], scheme="average_acceleration")
    t_tmm, r = timed(lambda: dd.shaft_response(shaft, f, dt, **kw))
    t_c, rc = timed(lambda: dd.mck_response(M, C, K, f, dt, **kw))
    t_np, rn = timed(lambda: dd.mck_response(M, C, K, f, dt, backend="numpy", **kw), 3)
    diff = max(np.abs(r.x - ref.x).max() / np.abs(ref.x).max() for ref in (rc, rn))
    print(f"{name}: {n} stations, {n_steps} steps of dt = {dt:g}")
    print(f"  DT-TMM tree sweep (C)              {t_tmm.format():>26s}")
    print(f"  mck_response sparse, C loop        {t_c.format():>26s}   ratio {t_c / t_tmm:6.1f}x")
    print(f"  mck_response sparse, numpy backend {t_np.format():>26s}   ratio {t_np / t_tmm:6.1f}x"
          "   (scipy.sparse Newmark; target >= 10x)")
    print(f"  largest relative difference in x: {diff:.1e}")


def scaling(n_steps=500):
    sizes = [1_000, 3_000, 10_000, 30_000, 100_000]
    per = []
    for n in sizes:
        s = tree(n)
        t, _ = timed(functools.partial(dd.shaft_response, s, np.ones(n_steps + 1), 1e-4,
                                         force_dofs=[n - 1], outputs=[0]))
        per.append(t.scaled(1 / n_steps))
        print(f"  N = {n:7d}: {per[-1].format('us'):>24s} per step, "
              f"{per[-1] / n * 1e9:6.2f} ns per station-step")
    slope = np.polyfit(np.log(sizes), np.log(per), 1)[0]
    print(f"  fitted slope of log(time per step) over log(N): {slope:.2f}")


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        compare("10,000-disk shaft", line(10_000))
        compare("10,000-station tree (a geared branch)", tree(10_000))
        print("tree loop, cost per step:")
        scaling()
