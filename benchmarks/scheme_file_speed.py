"""A scheme from a scheme file runs at the speed of the same scheme built in, same run.

The file (Bossak-alpha written as relations, the example of docs/guide/scheme_files.md) and the
built-in `bossak` derive to the same coefficients and are compiled from the same templates; this
script checks that nothing on the file's path (its module imported from the cache, its C kernel
compiled there) costs time per step. Each case alternates the two within every repeat and keeps
the loop's own time (``info["run_time"]``): median [min, max] of the repeats after a warm-up,
BLAS pinned to one thread, and the ratio file / built-in of the medians.

Cases: a chain of 10,000 masses, 2,000 steps (displacement and acceleration forms, C sweep);
the same chain as sparse M, C, K through mck_response (C loop, sparse LU); a shaft of 10,000
disks (C tree loop).

Then the composite scheme `bathe` (two sub-steps a step, each a kernel call from Python) against
`average_acceleration` at half its step (two kernel steps a step, in one call), on the chain and
on a small chain of 10 masses, where the calls' overhead shows.

Usage: python benchmarks/scheme_file_speed.py [--quick]
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import dtdyn as dd
from dtdyn.app import SPREAD, interleaved, pin_blas

#: the loop's own time of a run (its info), not the call's
RUN_TIME = lambda r: r.info["run_time"]  # noqa: E731

FILE = '''
name = "file_bossak"
relations = [
  "x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",
  "v1 = v0 + dt*((1 - gamma)*a0 + gamma*a1)",
  "xe = x1", "ve = v1",
  "ae = (1 - alpha_m)*a1 + alpha_m*a0",
]
[parameters.alpha_m]
default = -0.1
range = [-0.5, 0.0]
[substitutions]
beta = "(1 - alpha_m)**2/4"
gamma = "1/2 - alpha_m"
'''


def main(quick: bool = False) -> None:
    n, steps, repeats = (2000, 500, 3) if quick else (10_000, 2000, 9)
    folder = Path(tempfile.mkdtemp())
    (folder / "file_bossak.toml").write_text(FILE)
    scheme = dd.load_scheme(folder / "file_bossak.toml")
    rng = np.random.default_rng(0)
    m, k, c = rng.uniform(1, 2, n), rng.uniform(1e5, 2e5, n), rng.uniform(0.1, 1.0, n)
    f = rng.standard_normal(steps + 1)
    dt, out = 1e-3, [n - 1]
    M, C, K = dd.chain_matrices(m, k, c, sparse=True)
    shaft = dd.Shaft(m, k, c, left="clamped")
    cases = {
        "chain, displacement form": lambda s: dd.chain_response(
            m, k, c, f, dt, force_dofs=[n - 1], outputs=out, scheme=s),
        "chain, acceleration form": lambda s: dd.chain_response(
            m, k, c, f, dt, force_dofs=[n - 1], outputs=out, scheme=s, form="acceleration"),
        "mck_response (sparse)": lambda s: dd.mck_response(
            M, C, K, f, dt, force_dofs=[n - 1], outputs=out, scheme=s),
        "shaft (tree loop)": lambda s: dd.shaft_response(
            shaft, f, dt, force_dofs=[shaft.dof_names[-1]], outputs=[shaft.dof_names[-1]],
            scheme=s),
    }
    print(f"{n:,} DOFs, {steps:,} steps; loop time per step, {SPREAD}, {repeats} repeats")
    print(f"{'case':28s} {'file scheme':>24s} {'built-in bossak':>24s} {'ratio':>7s}")
    with pin_blas(1):
        for name, run in cases.items():
            a, b = run(scheme), run("bossak")
            assert np.array_equal(a.x, b.x), name       # same derivation, same bits
            t = interleaved({"file": lambda run=run: run(scheme),
                             "built-in": lambda run=run: run("bossak")}, repeats, key=RUN_TIME)
            tf, tb = t["file"], t["built-in"]
            per = 1.0 / steps
            print(f"{name:28s} {tf.scaled(per).format('us'):>24s} "
                  f"{tb.scaled(per).format('us'):>24s} {tf / tb:7.3f}")

    bathe = dd.load_scheme("bathe")
    small = rng.uniform(1, 2, 10), rng.uniform(1e5, 2e5, 10), rng.uniform(0.1, 1.0, 10)
    f2 = np.repeat(f, 2)[: 2 * steps + 1]
    print("\nbathe (2 sub-steps per step) against average_acceleration at dt/2; per step of dt")
    print(f"{'case':28s} {'bathe':>24s} {'avg. acc., 2 steps':>24s} {'ratio':>7s}")
    with pin_blas(1):
        for name, (mm, kk, cc) in (("chain, 10,000 masses" if not quick else "chain", (m, k, c)),
                                   ("chain, 10 masses", small)):
            last = [mm.size - 1]

            def run_b(mm=mm, kk=kk, cc=cc, last=last):
                return dd.chain_response(mm, kk, cc, f, dt, force_dofs=last, outputs=last,
                                         scheme=bathe)

            def run_a(mm=mm, kk=kk, cc=cc, last=last):
                return dd.chain_response(mm, kk, cc, f2, dt / 2, force_dofs=last, outputs=last,
                                         scheme="average_acceleration")
            t = interleaved({"bathe": run_b, "avg": run_a}, repeats, key=RUN_TIME)
            tf, tb = t["bathe"], t["avg"]
            per = 1.0 / steps
            print(f"{name:28s} {tf.scaled(per).format('us'):>24s} "
                  f"{tb.scaled(per).format('us'):>24s} {tf / tb:7.3f}")


if __name__ == "__main__":
    main("--quick" in sys.argv)
