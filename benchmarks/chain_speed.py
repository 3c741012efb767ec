"""Speed of the DT-TMM chain kernels, with ratios measured in the same run.

1. C DT-TMM (stable sweep) against `mck_response` on the sparse assembled matrices, same scheme:
   its NumPy loop (scipy.sparse products, a SuperLU factorization) and its C loop (SuperLU's
   factors applied in C); uniform chain of 1,000 masses (m = 1, k = 1e4, c = 1), 10,000 steps of
   dt = 1e-4.
2. Cost per step of the C kernel for N = 1e2 .. 1e5 masses, on one thread and with the default
   `workers` (two threads, the chain split in two parts, from `SPLIT_MASSES` masses on): the
   fitted slope of log(time) over log(N) should be 1 (O(N) per step).
3. C against NumPy backends, and C on two threads against one: largest relative difference
   (should be <= 1e-12, or the scheme's own rounding sensitivity where that is larger: NumPy
   against `mck_response` on the assembled matrices; both backends form the same terms in the
   same order, the C recurrences take four masses a round).
4. Memory traffic of one thread at N = 1e5, where the 10 rows the sweep touches each step
   (8 MB) no longer fit in a core's L2 (2 MiB here): the doubles the stable sweep moves per
   mass-step, the rate that makes, and the rate of a peer that only streams (NumPy's x += y
   over a working set of the same size), measured in the same run; the peer's rate bounds the
   time per mass-step of one thread from below.

Times: median [min, max] of repeats after one warm-up run (compilation excluded and reported
apart), BLAS pinned to one thread (dtdyn.app.pin_blas, threadpoolctl).
Usage: python benchmarks/chain_speed.py [--quick]
"""
from __future__ import annotations

import functools
import sys
import time

import numpy as np

from dtdyn._engine import cbuild
from dtdyn._engine import kernels
from dtdyn import DtdynUnstableError
from dtdyn.linear._chain import SPLIT_MASSES, chain_matrices, chain_response
from dtdyn.linear._mck import mck_response
from dtdyn.app import measure, pin_blas


def timed(fn, repeats):
    """(Timing: median and spread of ``repeats`` calls after a warm-up, last result)."""
    out, t = measure(fn, repeats)
    return t, out


def chain(n):
    return np.ones(n), np.full(n, 1e4), np.ones(n)


def main(quick=False):
    t0 = time.perf_counter()
    kernels.c_chain_function("newmark")
    print(f"compile or cache load of chain_newmark.c: {time.perf_counter() - t0:.3f} s "
          f"(C available: {cbuild.c_available()})\n")

    n, steps, dt = 1000, 2000 if quick else 10_000, 1e-4
    m, k, c = chain(n)
    F = np.ones((steps + 1, 1))
    out = [0, n // 2, n - 1]
    M, C, K = chain_matrices(m, k, c, sparse=True)
    t_c, rc = timed(lambda: chain_response(m, k, c, F, dt, force_dofs=[n - 1], outputs=out,
                                             backend="c", quantities=("x",)), 5)
    t_mck, rm = timed(lambda: mck_response(M, C, K, F, dt, force_dofs=[n - 1], outputs=out,
                                             quantities=("x",), backend="numpy"),
                        1 if quick else 3)
    t_mc, _ = timed(lambda: mck_response(M, C, K, F, dt, force_dofs=[n - 1], outputs=out,
                                           quantities=("x",)), 1 if quick else 3)
    diff = np.max(np.abs(rc.x - rm.x)) / np.max(np.abs(rm.x))
    print(f"1) {n} masses x {steps} steps, Newmark average acceleration")
    print(f"   C DT-TMM                        {t_c.format():>26s}  "
          f"({t_c / steps * 1e6:.2f} us/step)")
    print(f"   mck_response sparse, NumPy loop {t_mck.format():>26s}  "
          f"({t_mck / steps * 1e6:.2f} us/step)")
    print(f"   mck_response sparse, C loop     {t_mc.format():>26s}  "
          f"({t_mc / steps * 1e6:.2f} us/step)")
    print(f"   speed-up {t_mck / t_c:.1f}x against the scipy.sparse loop (target >= 5x), "
          f"{t_mc / t_c:.1f}x against the C loop (SuperLU); max relative difference {diff:.1e}\n")

    print("2) C kernel cost per step against N (1,000 steps, outputs: last mass), on one thread\n"
          f"   and with the default workers (two threads from SPLIT_MASSES = {SPLIT_MASSES} "
          "masses on)")
    Ns = [100, 1000, 10_000, 30_000, 100_000]
    per, one = [], []
    for N in Ns:
        m, k, c = chain(N)
        s = 1000
        F = np.ones((s + 1, 1))
        times = []
        for workers in (1, None):
            t, r = timed(functools.partial(chain_response, m, k, c, F, dt, force_dofs=[N - 1],
                                             outputs=[N - 1], quantities=("x",),
                                             workers=workers), 3)
            times.append(t.scaled(1 / s))
        one.append(times[0])
        per.append(times[1])
        print(f"   N = {N:>7d}: one thread {times[0].scaled(1 / N).format('ns')}, default "
              f"({r.info['workers']} thread{'s' if r.info['workers'] > 1 else ''}) "
              f"{times[1].scaled(1 / N).format('ns')} per mass-step "
              f"({times[1] * 1e6:.2f} us/step)")
    slope = np.polyfit(np.log(Ns), np.log(per), 1)[0]
    print(f"   fitted slope of log(time/step) over log(N), default: {slope:.3f} (1 = linear)")
    worst = max(t / N for t, N in zip(per, Ns) if N >= 10_000) * 1e9
    worst1 = max(t / N for t, N in zip(one, Ns) if N >= 10_000) * 1e9
    print(f"   N = 1e4 .. 1e5: at most {worst:.2f} ns per mass-step with the default workers "
          f"(target <= 3); one thread: at most {worst1:.2f}\n")

    print("3) C against NumPy (1,000 masses, 1,000 steps of 1e-4, random force on 3 masses)")
    m, k, c = chain(1000)
    F = np.random.default_rng(0).standard_normal((1001, 3))
    M, C, K = chain_matrices(m, k, c, sparse=True)
    worst = {"displacement": (0.0, "", 0.0), "acceleration": (0.0, "", 0.0)}
    split = (0.0, "", "")
    from dtdyn.generated import SCHEMES
    for scheme in SCHEMES:
        forms = ("acceleration",) if scheme == "central_difference" else tuple(worst)
        ref = None
        for form in forms:
            kw = dict(force_dofs=[10, 500, 999], scheme=scheme, form=form, quantities=("x",))
            a = chain_response(m, k, c, F, 1e-4, backend="c", **kw)
            b = chain_response(m, k, c, F, 1e-4, backend="numpy", **kw)
            d = np.max(np.abs(a.x - b.x)) / np.max(np.abs(b.x))
            # two threads against one, on a stiff chain (k = 1e8, dt = 1e-3: every g near 1, so
            # the lower part's correction reaches far from the cut; unconditionally stable
            # schemes only)
            try:
                x1, x2 = (chain_response(m, 1e4 * k, c, F, 1e-3, workers=w, **kw).x
                          for w in (1, 2))
            except DtdynUnstableError:
                continue
            split = max(split, (np.max(np.abs(x2 - x1)) / np.max(np.abs(x1)), scheme, form))
            if d > worst[form][0]:
                if ref is None:
                    ref = mck_response(M, C, K, F, 1e-4, force_dofs=[10, 500, 999],
                                       scheme=scheme, quantities=("x",))
                e = np.max(np.abs(b.x - ref.x)) / np.max(np.abs(ref.x))
                worst[form] = (d, scheme, e)
    for form, (d, scheme, e) in worst.items():
        print(f"   {form} form, largest relative difference: {d:.1e} ({scheme}; NumPy against "
              f"mck_response, same scheme: {e:.1e}) (target <= max(1e-12, that))")
    print("   C on two threads against one (k = 1e8, dt = 1e-3, the unconditionally stable "
          "schemes): "
          f"largest relative difference "
          f"{split[0]:.1e} ({split[1]}, {split[2]} form; the split reorders two sums)")
    print("   (both evaluate the same generated expressions in the same order; the C kernel's\n"
          "    recurrences take four masses a round, so the backends agree to rounding, as "
          "closely\n"
          "    as the scheme's rounding lets two solvers of it agree: mck_response's sparse LU)\n")
    memory_traffic(Ns[-1], one[-1])


#: doubles the stable sweep moves per mass-step (displacement form, no ground elements, a few
#: loaded masses), each row once: the back pass reads x, v, a, m, k, c, mu - S_R and 1 / den and
#: writes b (a write that misses the cache reads the line first); the forward pass reads b and
#: g and reads and writes x, v and a
SWEEP_TRAFFIC = {"back pass": 8 + 2, "forward pass": 2 + 6}


def memory_traffic(N, t_step, rows=10):
    """Section 4: the sweep's bytes per second at N masses against NumPy's x += y (reads x
    and y, writes x: 3 doubles per element, no write miss) over rows * N doubles."""
    doubles = sum(SWEEP_TRAFFIC.values())
    x = np.ones(rows * N // 2)
    y = np.ones_like(x)
    t_peer, _ = timed(lambda: np.add(x, y, out=x), 50)
    peer = 3 * 8 * x.size / t_peer
    rate = doubles * 8 * N / t_step
    print(f"4) memory traffic of one thread at N = {N} (the {rows} rows the sweep touches each "
          f"step: {rows * N * 8 / 1e6:.1f} MB)")
    print(f"   stable sweep: {doubles} doubles per mass-step ("
          + ", ".join(f"{k} {v}" for k, v in SWEEP_TRAFFIC.items())
          + f"): {rate / 1e9:.1f} GB/s at {t_step / N * 1e9:.2f} ns per mass-step")
    print(f"   peer, NumPy x += y over {2 * x.size * 8 / 1e6:.1f} MB: {peer / 1e9:.1f} GB/s "
          f"(one pass {t_peer.format('ms')}); the "
          f"sweep streams at {rate / peer:.0%} of it")
    print(f"   at the peer's rate, {doubles} doubles take at least "
          f"{doubles * 8 / peer * 1e9:.2f} ns per mass-step")


if __name__ == "__main__":
    import contextlib
    import io
    import pathlib

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats\n")
        main(quick="--quick" in sys.argv)
    print(buf.getvalue(), end="")
    if "--quick" not in sys.argv:
        doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "chain_speed.md"
        doc.write_text("# DT-TMM chain speed\n\nOutput of `python benchmarks/chain_speed.py` "
                       "(2-core shared machine; ratios are measured in one run):\n\n```\n"
                       + buf.getvalue() + "```\n")
