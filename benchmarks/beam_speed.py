"""Beams: the DT-TMM matrix Riccati sweep against the assembled-matrix loops, and the accuracy
of the Wittrick-Williams frequencies.

1. Cantilever (E = 2.1e11, I = 8e-6, rho_A = 20, L = 3): the lowest five frequencies against
   (beta L)^2 sqrt(EI / (rho_A L^4)) (beta L to 15 digits) for 100, 200, 400 elements.
2. Time per step of a step-loaded cantilever (tip displacement stored, average acceleration,
   displacement form) for 1,000 .. 10,000 elements: `simulate_beam` (C loop, Riccati sweep)
   against `simulate_mck` on the same sparse matrices, NumPy/scipy.sparse loop and C loop
   (SuperLU), same run; the fitted slope of log(time) over log(N).

Times: minimum of 3 runs after a warm-up. Usage: python benchmarks/beam_speed.py
"""
from __future__ import annotations

import time

import numpy as np

import dtdyn as dd

E, I, RHO_A = 2.1e11, 8e-6, 20.0
BETA_L = np.array([1.87510406871196, 4.69409113297418, 7.85475743823761, 10.9955407348755,
                   14.1371683910465])


def best(fn, repeats=3):
    out = fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main():
    print("1) cantilever, lowest five frequencies: relative error against the closed form")
    for n in (100, 200, 400):
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=3.0, elements=n)
        t, w = best(lambda: dd.beam_frequencies(beam, count=5), 1)
        ref = BETA_L**2 * np.sqrt(E * I / (RHO_A * 3.0**4))
        print(f"   {n:4d} elements: max {np.abs(w / ref - 1).max():.1e}  ({t:.2f} s)")
    print("\n2) time per step, step load at the tip, average acceleration (us per step)")
    print("   elements   sweep (C)   mck NumPy   mck C (SuperLU)   NumPy/sweep   C/sweep   diff")
    sizes, sweep_t = [1000, 3000, 10000], []
    for n in sizes:
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=0.03 * n, elements=n)
        tip = beam.dof(f"w{n}")
        steps, dt = 400, 1e-4
        F = np.ones(steps + 1)
        M, C, K = dd.beam_matrices(beam)
        kw = dict(force_dofs=[tip], outputs=[tip], quantities=("x",), scheme="average_acceleration")
        t1, r1 = best(lambda: dd.simulate_beam(beam, F, dt, **kw))
        t2, r2 = best(lambda: dd.simulate_mck(M, C, K, F, dt, backend="numpy", **kw))
        t3, r3 = best(lambda: dd.simulate_mck(M, C, K, F, dt, **kw))
        diff = np.abs(r1.x - r2.x).max() / np.abs(r2.x).max()
        us = [t / steps * 1e6 for t in (t1, t2, t3)]
        sweep_t.append(us[0])
        print(f"   {n:8d}   {us[0]:9.1f}   {us[1]:9.1f}   {us[2]:15.1f}   {us[1] / us[0]:11.1f}x"
              f"   {us[2] / us[0]:6.1f}x   {diff:.1e}")
    slope = np.polyfit(np.log(sizes), np.log(sweep_t), 1)[0]
    print(f"   fitted slope of log(time per step) over log(N), sweep: {slope:.2f} (1 = linear)")


if __name__ == "__main__":
    main()
