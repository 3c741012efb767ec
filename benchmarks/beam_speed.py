"""Beams: the DT-TMM block kernel against the assembled-matrix loops, and the accuracy of the
Wittrick-Williams frequencies.

1. Cantilever (E = 2.1e11, I = 8e-6, rho_A = 20, L = 3): the lowest five frequencies against
   (beta L)^2 sqrt(EI / (rho_A L^4)) (beta L to 15 digits) for 100, 200, 400 elements.
2. A step-loaded cantilever (tip displacement stored, average acceleration, displacement form
   for the DT-TMM, 400 steps of 1e-4 s) for 1,000 .. 10,000 elements, same run:
   `beam_response` (the block-tridiagonal C kernel, generated/block_chain.c) against
   `mck_response` on the same sparse matrices from `beam_matrices`, its NumPy/scipy.sparse loop
   (Newmark with scipy's sparse LU) and its C loop (SuperLU's factors). Per step: the time loop
   (`info["run_time"]`, factorization included) over the steps; construction (assembly, checks,
   a_0: the rest of the call) apart, in ms; the ratios of the whole calls. The fitted slope of
   log(time per step) over log(N) for each method; "diff": the largest difference of the tip
   displacement from the scipy.sparse run, relative to its largest value.

Times: median [min, max] of 3 runs after a warm-up, BLAS pinned to one thread
(dtdyn.app.pin_blas, threadpoolctl).
Usage: python benchmarks/beam_speed.py
"""
from __future__ import annotations

import functools

import numpy as np

import dtdyn as dd
from dtdyn.app import Timing, measure, pin_blas

E, I, RHO_A = 2.1e11, 8e-6, 20.0  # noqa: E741
BETA_L = np.array([1.87510406871196, 4.69409113297418, 7.85475743823761, 10.9955407348755,
                   14.1371683910465])
SIZES = (1000, 2000, 5000, 10000)
STEPS, DT = 400, 1e-4


def best(fn, repeats=3):
    """(total, run_time, result): the Timings (median, spread) of the whole call and of its
    time loop (``info["run_time"]``) over ``repeats`` calls after a warm-up, the last result."""
    loops = []

    def call():
        out = fn()
        loops.append(out.info.get("run_time"))
        return out
    out, total = measure(call, repeats)
    run = Timing([w if t is None else t for t, w in zip(loops[1:], total.times)])
    return total, run, out


def main():
    print("1) cantilever, lowest five frequencies: relative error against the closed form")
    for n in (100, 200, 400):
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=3.0, elements=n)
        w, t = measure(functools.partial(dd.beam_frequencies, beam, count=5), 3)
        ref = BETA_L**2 * np.sqrt(E * I / (RHO_A * 3.0**4))
        print(f"   {n:4d} elements: max {np.abs(w / ref - 1).max():.1e}  ({t.format('s')})")
    print(f"\n2) step load at the tip, average acceleration, {STEPS} steps: time loop per step "
          "(us), construction (ms)")
    print("   elements   DT-TMM (C)        mck scipy.sparse    mck C (SuperLU)    "
          "scipy/DT-TMM  C/DT-TMM   diff")
    per_step = {k: [] for k in ("dttmm", "scipy", "superlu")}
    for n in SIZES:
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=0.03 * n, elements=n)
        tip = beam.dof(f"w{n}")
        F = np.ones(STEPS + 1)
        M, C, K = dd.beam_matrices(beam)
        kw = dict(force_dofs=[tip], outputs=[tip], quantities=("x",),
                  scheme="average_acceleration")
        runs = {"dttmm": best(functools.partial(dd.beam_response, beam, F, DT, **kw)),
                "scipy": best(functools.partial(dd.mck_response, M, C, K, F, DT,
                                                backend="numpy", **kw)),
                "superlu": best(functools.partial(dd.mck_response, M, C, K, F, DT, **kw))}
        assert runs["dttmm"][2].info["backend"] == "c", "the C kernel did not run"
        cells = []
        for key, (total, run, _) in runs.items():
            per_step[key].append(run / STEPS * 1e6)
            cells.append(f"{run.scaled(1 / STEPS).format('us'):>22s} "
                         f"({(total - run) * 1e3:5.1f} ms)")
        ref = runs["scipy"][2].x
        diff = np.abs(runs["dttmm"][2].x - ref).max() / np.abs(ref).max()
        totals = {k: v[0] for k, v in runs.items()}
        ratios = [totals[k] / totals["dttmm"] for k in ("scipy", "superlu")]
        print(f"   {n:8d}   {cells[0]}   {cells[1]}    {cells[2]}   {ratios[0]:9.1f}x  "
              f"{ratios[1]:7.1f}x   {diff:.1e}")
    print("   per node and step: " + ", ".join(
        f"{n}: {t / (n + 1) * 1e3:.1f} ns" for n, t in zip(SIZES, per_step["dttmm"])) + " (DT-TMM)")
    slopes = {k: np.polyfit(np.log(SIZES), np.log(v), 1)[0] for k, v in per_step.items()}
    print(f"   fitted slope of log(time per step) over log(N): DT-TMM {slopes['dttmm']:.2f}, "
          f"scipy.sparse {slopes['scipy']:.2f}, SuperLU {slopes['superlu']:.2f} (1 = linear)")


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        main()
