"""The Duffing oscillator of issue 31 by harmonic balance against periodic orbits by shooting.

x'' + 0.02 x' + x + 0.5 x^3 = F cos(omega t) (m = 1, c = 0.02, k = 1, ``Cubic(0, k3=0.5)``),
F = 0.1, 0.3 and 1, continued from 0.15 to 1.2 Hz: just below the linear natural frequency
(0.159 Hz) to above the jump-down fold at F = 1 (0.891 Hz), so the range holds the primary
resonance and both folds at every force. ``max_step=0.02`` puts about 280 points on each curve
(points within 1 % of each fold on both sides of it).

Shooting (the helpers of tests/behaviour/test_harmonic_balance_duffing.py): solve_ivp DOP853
at rtol 1e-12 (atol 1e-13) over one period with the variational equations, Newton on the
period map (its Jacobian the monodromy matrix Phi, the Floquet multipliers its eigenvalues),
started from the harmonic-balance orbit at the point's frequency.
The shooting orbit's Fourier coefficients X_k from 64 samples of its dense output
(x(t) = Re sum_k X_k e^{i k omega t}). At every point of the curve:

- kept: sum_{k <= H} |X_k(curve) - X_k(shooting)| / x_max, the error of the harmonics the
  curve holds (it bounds their part of max_t |x_curve(t) - x_shooting(t)|);
- whole: max_t |x_curve(t) - x_shooting(t)| / x_max over 513 instants of the period, the
  whole orbit's error;
- dropped: sum_{k > H} |X_k(shooting)| / x_max, the harmonics the curve cannot hold
  (whole <= kept + dropped);
- labels: the curve's stable flag against max |multiplier| < 1 of the monodromy matrix;
  Hill: the largest difference of the sorted |exp(lambda T)| of Hill's exponents from the
  sorted |multipliers|.

Points closer than 1e-4 (relative) to a fold frequency are reported apart: at a fixed frequency
next to a fold the amplitude moves as the square root of the distance, so the fold's own
(tiny) shift is magnified there and the label flips at the fold itself.

Folds by shooting: Newton on the augmented system (the period-map residual P(z0, omega) - z0
and det(Phi - I) = 0; unknowns z0 and omega; dP/domega from the parameter's variational
equation, the row of det(Phi - I) by forward differences), started from the curve's fold.

Part 2: the same for H = 9 and 11 (every second point). Part 3: below the range at F = 1 (a
curve of 25 harmonics swept down to 0.05 Hz, its orbits refined by shooting): the dropped part
of 7, 9, ... harmonics of the shooting orbit, and the fewest harmonics whose dropped part is
below 1e-6.

Usage: python benchmarks/duffing_shooting.py   (about 2 minutes)
"""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "behaviour"))
from test_harmonic_balance_duffing import (  # noqa: E402
    C, FORCES, K3, NEAR_FOLD, compare, curve, fold, fourier, periodic_orbit, start)

import dtdyn as dd  # noqa: E402


def check(r, F, i):
    """compare() with the label's agreement and the largest |multiplier|."""
    q = compare(r, F, i)
    q["mu_max"] = np.abs(q["mu"]).max()
    q["label"] = bool(r.stable[i]) == bool(q["mu_max"] < 1)
    return q


def part1():
    print("1) H = 7, every point of the curve (0.15 .. 1.2 Hz, max_step 0.02) against shooting")
    print("   kept / whole / dropped: max over the points farther than 1e-4 from a fold;")
    print("   'within 1 %': the same max over the points 1e-4 .. 1e-2 from a fold\n")
    print("| F | points | kept | kept within 1 % | whole | dropped (9th+) | 9th alone | labels "
          "| Hill - monodromy | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    near_rows, fold_rows = [], []
    for F in FORCES:
        t0 = time.perf_counter()
        r = curve(F, 7, convergence_points=0)
        rows = [check(r, F, i) for i in range(r.omega.size)]
        el = time.perf_counter() - t0
        near = np.array([q["near"] for q in rows])
        far = near >= NEAR_FOLD
        band = far & (near <= 1e-2)

        def top(key, mask, rows=rows):
            return max(q[key] for q, m in zip(rows, mask) if m)
        labels = sum(q["label"] for q, m in zip(rows, far) if m)
        print(f"| {F} | {r.omega.size} | {top('kept', far):.1e} | {top('kept', band):.1e} "
              f"({band.sum()} pts) | {top('whole', far):.1e} | {top('dropped', far):.1e} | "
              f"{top('x9', far):.1e} | {labels}/{far.sum()} | {top('hill', far):.1e} | {el:.1f} |")
        for q, fq in zip(rows, r.frequency_hz):
            if q["near"] < NEAR_FOLD:
                near_rows.append((F, fq, q))
        for j, ff in zip(r.folds, r.fold_frequency_hz):
            z, w = fold(F, start(r.harmonics[j, 0], r.omega[j]), 2 * np.pi * ff)
            fs = w / (2 * np.pi)
            fold_rows.append((F, ff, fs, ff / fs - 1))
    print("\n   points within 1e-4 of a fold (not in the table above):")
    for F, fq, q in near_rows:
        print(f"   F = {F}: {fq:.6f} Hz, {q['near']:.1e} from the fold: kept {q['kept']:.1e}, "
              f"whole {q['whole']:.1e}, max |mu| {q['mu_max']:.6f}, labels agree: {q['label']}")
    print("\n   folds: harmonic balance (fold_frequency_hz) against shooting (augmented Newton)")
    for F, ff, fs, rel in fold_rows:
        print(f"   F = {F}: {ff:.10f} Hz against {fs:.10f} Hz, relative {rel:+.1e}")


def part2():
    print("\n2) H = 9 and 11, every second point: max over the points farther than 1e-4 from "
          "a fold\n")
    print("| F | H | points checked | kept | whole | dropped | labels |")
    print("|---|---|---|---|---|---|---|")
    for H in (9, 11):
        for F in FORCES:
            r = curve(F, H, convergence_points=0)
            rows = [check(r, F, i) for i in range(0, r.omega.size, 2)]
            rows = [q for q in rows if q["near"] >= NEAR_FOLD]
            print(f"| {F} | {H} | {len(rows)} | {max(q['kept'] for q in rows):.1e} | "
                  f"{max(q['whole'] for q in rows):.1e} | "
                  f"{max(q['dropped'] for q in rows):.1e} | "
                  f"{sum(q['label'] for q in rows)}/{len(rows)} |")


def part3():
    print("\n3) Below the range, F = 1: the shooting orbit's harmonics beyond H (sum |X_k| / "
          "x_max, k > H)\n")
    r = dd.harmonic_balance(np.eye(1), [[C]], np.eye(1), elements=[dd.Cubic(0, k3=K3)],
                            force_dofs=[0], force=[1.0], freqs_hz=(0.15, 0.05), harmonics=25,
                            stability=False, convergence_points=0)
    f = r.frequency_hz
    picks = [int(np.argmin(np.abs(f - g))) for g in (0.14, 0.12, 0.10, 0.09, 0.08)]
    sup = np.flatnonzero((f > 0.06) & (f < 0.075))
    picks.append(int(sup[np.argmax(r.x_max[sup, 0])]))
    Hs = (7, 9, 11, 15, 19, 23)
    print("| Hz | x_max | " + " | ".join(f"H = {H}" for H in Hs) + " | fewest H for 1e-6 |")
    print("|---" * (len(Hs) + 3) + "|")
    for i in picks:
        _, sol, _ = periodic_orbit(1.0, r.omega[i], start(r.harmonics[i, 0], r.omega[i]))
        Xs = np.abs(fourier(sol, r.omega[i], n=256)) / r.x_max[i, 0]
        tails = np.cumsum(Xs[::-1])[::-1]          # tails[h] = sum_{k >= h}
        need = int(np.flatnonzero(tails[1:] < 1e-6)[0])
        print(f"| {f[i]:.4f} | {r.x_max[i, 0]:.3f} | "
              + " | ".join(f"{tails[H + 1]:.1e}" for H in Hs) + f" | {need} |")
    print(f"\n   (the superharmonic resonance 3 omega ~ the orbit's own frequency: folds of "
          f"the 25-harmonic curve at {', '.join(f'{x:.4f}' for x in r.fold_frequency_hz)} Hz)")


if __name__ == "__main__":
    t0 = time.perf_counter()
    part1()
    part2()
    part3()
    print(f"\n({time.perf_counter() - t0:.0f} s)")
