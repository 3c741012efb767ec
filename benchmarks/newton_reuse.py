"""Many nonlinear elements: the C loop's kept LU factors (modified Newton) against a new LU at
every Newton iteration (plain Newton, the peer), same run.

A 24-DOF chain (unit masses, springs 1e4 N/m, dampers 2 N s/m), Bouc-Wen elements (k = 5e3 N/m,
alpha = 0.1, beta = gamma = 50) on the first 1 .. 12 stations (3 unknowns each: y, y', z), white
noise of 30 N on the top mass, 20,000 steps of 1 ms, Newmark average acceleration, tol = 1e-12.
Both runs use the same generated loop (nl_loop.c, newton_fixed), compiled with and without
NL_LU_REUSE; time: the C loop's own (info["run_time"]), median [min, max] of 5 each,
alternating, BLAS pinned to one thread (dtdyn.app.pin_blas). The
last column is the largest difference of the two responses over their peak: both accept each
step within the same tolerance, so they differ by what the hysteresis carries of it.

    python benchmarks/newton_reuse.py [n_steps]     (the default 20,000 writes docs/newton_reuse.md)
"""
import contextlib
import io
import pathlib
import sys

import numpy as np

import dtdyn as dd
from dtdyn.app import Timing, pin_blas
from dtdyn.nonlinear import _response as response


def main(n_steps=20_000):
    N = 24
    M, C, K = dd.chain_matrices(np.ones(N), np.full(N, 1e4), np.full(N, 2.0), sparse=False)
    f = 30.0 * np.random.default_rng(0).standard_normal(n_steps)
    default = response.LU_REUSE_MIN
    print(f"{n_steps} steps, Newmark average acceleration; LU kept from {default} unknowns on by "
          "default\n")
    print("| unknowns | plain Newton [ms], median [min, max] | kept LU [ms] | speed-up "
          "(medians) | iterations per step "
          "(plain, kept) | LU factorizations (kept) | difference |")
    print("|---|---|---|---|---|---|---|")
    try:
        for ne in (1, 2, 4, 6, 8, 12):
            els = [dd.BoucWen(i, i - 1 if i else None, stiffness=5e3, alpha=0.1, beta=50.0,
                              gamma=50.0) for i in range(ne)]
            times, runs = {None: [], 1: []}, {}
            for _ in range(5):
                for reuse in (None, 1):
                    response.LU_REUSE_MIN = reuse
                    r = dd.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[N - 1],
                                                  elements=els, scheme="newmark",
                                                  quantities=("x",))
                    times[reuse].append(r.info["run_time"])
                    runs[reuse] = r
            best = {k: Timing(v) for k, v in times.items()}
            it = [runs[k].info["newton_iterations"] for k in (None, 1)]
            diff = np.abs(runs[1].x - runs[None].x).max() / np.abs(runs[None].x).max()
            print(f"| {3 * ne} | {best[None].format('ms', 3).removesuffix(' ms')} | "
                  f"{best[1].format('ms', 3).removesuffix(' ms')} | "
                  f"{best[None] / best[1]:.2f} | {it[0]['mean']:.2f}, {it[1]['mean']:.2f} | "
                  f"{it[1]['factorizations']} | {diff:.1e} |")
    finally:
        response.LU_REUSE_MIN = default


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 20_000)
    print(buf.getvalue(), end="")
    if len(sys.argv) == 1:
        doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "newton_reuse.md"
        doc.write_text("# Many nonlinear elements: the Newton Jacobian's LU kept\n\nOutput of "
                       "`python benchmarks/newton_reuse.py` (2-core shared machine; ratios are "
                       "measured in one run):\n\n" + buf.getvalue())
