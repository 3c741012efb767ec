"""Harmonic balance on chains of 4 .. 100,000 masses with one nonlinear element: time per point
of the continued curve against the chain's length.

The chain is a rail on an elastic foundation: N masses of 1 kg, springs of 1e4 N/m and dashpots
of 10 N s/m between them, each mass on a spring of 100 N/m and a dashpot of 2 N s/m to the
ground (its stiffness matrix stays well conditioned as N grows: cond ~ 400), a cubic spring
k3 = 1e3 N/m^3 from the tip to the ground, a force 20 cos(omega t) N at the tip, swept from
0.5 to 3 Hz (across the band edge sqrt(100) rad/s = 1.6 Hz) with 5 harmonics, the tip as the
only output, no stability (Hill's method works on the full model). The model goes in as a
`dd.Chain`: the receptance is LAPACK's banded LU of the tridiagonal K - w^2 M + i w C, O(N) per
harmonic and frequency, and the nonlinear problem is the element's 11 real unknowns whatever N.

Printed per N: the points of the curve, the run time per point (one run, after a warm-up of
the compiled law; BLAS on one thread), the receptance evaluations per point (each: harmonics
1 .. 5, one banded solve each) and the time of one evaluation (median of 5), and the peak tip
amplitude (the same from N = 1,000 on: the waves die out along the chain before its far end).

Usage: python benchmarks/harmonic_balance_scaling.py   (about a minute)
"""
from __future__ import annotations

import time

import numpy as np

import dtdyn as dd
from dtdyn.app import pin_blas

SIZES = (4, 100, 1_000, 10_000, 100_000)
H = 5


def chain(n):
    return dd.Chain(np.full(n, 1.0), np.full(n, 1e4), np.full(n, 10.0),
                    ground_stiffness=np.full(n, 100.0), ground_damping=np.full(n, 2.0))


def run(n):
    model = chain(n)
    return dd.harmonic_balance(model, elements=[dd.Cubic(n - 1, k3=1e3)], force_dofs=[n - 1],
                               force=[20.0], freqs_hz=(0.5, 3.0), harmonics=H,
                               outputs=[n - 1], stability=False)


def receptance_time(n, repeats=5):
    """One evaluation of the receptance as a run makes it: harmonics 1 .. 5 of 1.5 Hz (harmonic 0
    is solved once per curve), the median of ``repeats``."""
    from dtdyn.nonlinear._harmonic_balance import _BandedReceptance
    from dtdyn.nonlinear._elements import element_matrix
    M, C, K = chain(n).matrices(sparse=True)
    L = element_matrix([dd.Cubic(n - 1, k3=1.0)], n)
    B = np.zeros((n, 1))
    B[n - 1] = 1.0
    rec = _BandedReceptance(M, C, K, L, np.array([n - 1]), B, 1)
    w = 2 * np.pi * 1.5 * np.arange(1, H + 1)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        rec(w)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    run(4)                                  # warm-up: CasADi's law function, imports
    print(f"{'N':>8} {'points':>7} {'folds':>6} {'ms/point':>9} {'rec/point':>10} "
          f"{'ms/rec':>8} {'peak tip [m]':>13}")
    for n in SIZES:
        r = run(n)
        pts = r.omega.size
        per = r.info["run_time"] / pts
        print(f"{n:>8} {pts:>7} {r.folds.size:>6} {1e3 * per:>9.2f} "
              f"{r.info['receptance_evaluations'] / pts:>10.2f} "
              f"{1e3 * receptance_time(n):>8.3f} {r.x_max.max():>13.6f}")


if __name__ == "__main__":
    with pin_blas():
        main()
