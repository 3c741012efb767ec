"""Many nonlinear elements on a DT-TMM chain: the chain loop's Newton with its LU factors kept
(newton_kept in newton.h, modified Newton) against a new LU at every Newton iteration (plain
Newton, newton_solve), same run.

A 100-mass chain (unit masses, springs 1e4 N/m, dampers 2 N s/m), white noise of 30 N on the last
mass, 10,000 steps of 1 ms, Newmark average acceleration, tol = 1e-12, and on its first stations
either cubic springs (k3 = 1e10 N/m^3, 1 unknown each: y) or Bouc-Wen elements (k = 5e3 N/m,
alpha = 0.1, beta = gamma = 50; 3 unknowns each: y, y', z). Both runs use the same generated loop
(nl_chain.c) with dims' Newton code DTDYN_NEWTON_PLAIN or DTDYN_NEWTON_KEPT_LU (chosen by
dtdyn.nonlinear._chain.LU_KEPT_MIN); time: the C loop's own (info["run_time"]), median
[min, max] of 7 each, interleaved, BLAS pinned to one thread; the ratio of the medians and
that of the minima (the least disturbed runs on a shared machine). The last column is the largest
difference of the two responses over their peak: both accept each step within the same
tolerance.

    python benchmarks/newton_kept_lu.py [n_steps]   (the default 10,000 writes
                                                     docs/newton_kept_lu.md)
"""
import contextlib
import io
import pathlib
import sys

import numpy as np

import dtdyn as dd
from dtdyn.app import interleaved, pin_blas
from dtdyn.nonlinear import _chain as chain

ABOUT = """\
The loops of `nonlinear_chain_response`, `nonlinear_beam_response` and `nonlinear_shaft_response`
(nl_chain.h, nl_stations.h) keep the LU factors of the Newton Jacobian from iteration to
iteration and from step to step from `LU_KEPT_MIN` unknowns u = [w; z] on
(`dtdyn.nonlinear._chain`): modified Newton (newton_kept in newton.h, as the modal loop's
newton_fixed), the factors formed anew where an iteration does not contract by 0.25 and at every
iteration from the fifth, every step accepted by the rule of [Newton acceptance](newton.md).
Below, every iteration factors the Jacobian at its iterate (newton_solve, the Python loop's
steps).

It pays where the Jacobian moves little along the record: Bouc-Wen elements need one
factorization for the whole record. It does not pay for hardening springs, whose Jacobian
follows the state: the kept factors converge linearly and take about twice the iterations, which
costs about what the factorizations saved. The difference of the two responses is the kept
factors' error, proportional to tol
(`tests/generated_code/test_kept_lu.py`)."""

CASES = ([("cubic", ne) for ne in (6, 12, 20, 30, 50, 80)]
         + [("Bouc-Wen", ne) for ne in (4, 6, 8, 12, 16)])


def elements(kind, ne):
    if kind == "cubic":
        return [dd.Cubic(i, i - 1 if i else None, k3=1e10) for i in range(ne)]
    return [dd.BoucWen(i, i - 1 if i else None, stiffness=5e3, alpha=0.1, beta=50.0, gamma=50.0)
            for i in range(ne)]


def main(n_steps=10_000):
    N = 100
    m, k, c = np.ones(N), np.full(N, 1e4), np.full(N, 2.0)
    f = 30.0 * np.random.default_rng(0).standard_normal(n_steps + 1)
    default = chain.LU_KEPT_MIN
    print(f"{n_steps} steps, Newmark average acceleration, {N} masses; LU kept from {default} "
          "unknowns on by default\n")
    print("| elements | unknowns | plain Newton [ms], median [min, max] | kept LU [ms] | "
          "speed-up (medians) | speed-up (minima) | iterations per step (plain, kept) | "
          "LU factorizations (kept) | difference |")
    print("|---|---|---|---|---|---|---|---|---|")
    try:
        for kind, ne in CASES:
            els = elements(kind, ne)
            runs = {}

            def run(reuse, els=els, runs=runs):
                chain.LU_KEPT_MIN = reuse
                r = chain.nonlinear_chain_response(m, k, c, f, 1e-3, force_dofs=[N - 1],
                                                   elements=els, quantities=("x",))
                runs[reuse] = r
                return r
            t = interleaved({None: lambda: run(None), 1: lambda: run(1)}, 7,
                            key=lambda r: r.info["run_time"])
            it = [runs[key].info["newton_iterations"] for key in (None, 1)]
            diff = np.abs(runs[1].x - runs[None].x).max() / np.abs(runs[None].x).max()
            nu = ne * (1 if kind == "cubic" else 3)
            print(f"| {ne} {kind} | {nu} | {t[None].format('ms', 3).removesuffix(' ms')} | "
                  f"{t[1].format('ms', 3).removesuffix(' ms')} | {t[None] / t[1]:.2f} | "
                  f"{t[None].min / t[1].min:.2f} | "
                  f"{it[0]['mean']:.2f}, {it[1]['mean']:.2f} | {it[1]['factorizations']} | "
                  f"{diff:.1e} |")
    finally:
        chain.LU_KEPT_MIN = default


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 10_000)
    print(buf.getvalue(), end="")
    if len(sys.argv) == 1:
        doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "newton_kept_lu.md"
        doc.write_text("# Many nonlinear elements on a chain: the Newton LU kept\n\n" + ABOUT
                       + "\n\nOutput of `python benchmarks/newton_kept_lu.py` (2-core shared "
                       "machine; ratios are measured in one run):\n\n" + buf.getvalue())
