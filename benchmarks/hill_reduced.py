"""Hill's method on a reduced model (``stability="reduced"``) against Hill's method on the full
model, and its cost on beams of 1,000 and 10,000 elements.

A. Two Duffing oscillators (m = 1, k3 = 1) coupled by a spring 0.05, each grounded through a
   chain of 8 masses 0.01 (springs 9), Rayleigh damping 0.008 M + 0.002 K, forced 0.02 on the
   first, 0.16 .. 0.21 Hz, H = 5: 18 DOFs, folds and Neimark-Sacker points. The whole curve
   with ``stability=True`` (the dense Hill of size 2 n (2 H + 1) = 396) and with
   ``stability="reduced"``: the labels at every point, the largest |difference| of the largest
   real part of the exponents (over omega), the largest distance from each of the reduced
   model's 4 exponents of largest real part to the full model's nearest one (modulo i omega,
   over omega), the bifurcations of both.
B. The cantilever of benchmarks/harmonic_balance_beam.py (cubic spring at the tip, gap at
   mid-span, 5 .. 150 Hz) with 20 elements, H = 3: the same comparison, whole curve.
C. The same cantilever with 300 and 1,000 elements, H = 10 (the dense Hill would have size
   25,200 and 84,000): the reduced curve's exponents against the full model's Hill
   eigenproblem solved near each of them (sparse, shift-invert about the reduced exponent,
   ARPACK; the exponents of modes 1 and 2, Im > 0), at every 5th point (300) or 20th (1,000):
   their largest relative difference, and the labels from the full model's exponents
   found there.
D. Cost: the curve of the 1,000- and 10,000-element cantilevers (H = 10, receptance="reduced",
   the first Newton tol of harmonic_balance_beam.py's list that gets through with
   stability=False, then the same with stability="reduced"): points, run time, time per point, the
   stability's share, the labels and bifurcations.

BLAS pinned to one thread. Usage: python benchmarks/hill_reduced.py [--quick] (--quick skips
part B and the 1,000-element part of C).
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

import dtdyn as dd
from dtdyn.app import pin_blas

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from harmonic_balance_beam import curve, problem  # noqa: E402

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "tests"
                       / "behaviour"))
from test_hill_reduced import FC, coupled_chain  # noqa: E402   (the test's model)

def run(*args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return dd.harmonic_balance(*args, **kw)


def compare(full, red):
    """(labels equal, points, |d max Re| / omega, critical exponents' distance / omega)."""
    ma = np.nanmax(full.floquet_exponents.real, axis=1)
    mc = np.nanmax(red.floquet_exponents.real, axis=1)
    crit = 0.0
    for la, lc, w in zip(full.floquet_exponents, red.floquet_exponents, full.omega):
        lc = lc[np.isfinite(lc)]
        for x in lc[np.argsort(-lc.real)[:4]]:
            d = la - x
            d = d - 1j * w * np.round(d.imag / w)
            crit = max(crit, float(np.abs(d).min() / w))
    return (bool(np.array_equal(full.stable, red.stable)), full.stable.size,
            float(np.max(np.abs(ma - mc) / full.omega)), crit)


def bifurcations(r):
    return ", ".join(f"{k} {f:.9f}" for k, f in zip(r.bifurcation_kind,
                                                    r.bifurcation_frequency_hz))


def report_pair(name, full, red):
    same, pts, dmax, crit = compare(full, red)
    print(f"{name}: {pts} points, labels equal at every point: {same} "
          f"({int(np.count_nonzero(~red.stable))} unstable)")
    print(f"  largest |max Re full - max Re reduced| / omega: {dmax:.1e}; critical exponents "
          f"(4 of largest Re) to the full's nearest, / omega: {crit:.1e}")
    print(f"  reduced model: {red.info['stability']['modes']} modes + "
          f"{red.info['stability']['attachment']} attachment vectors = "
          f"{red.info['stability']['size']} DOFs (full: {full.info['stability']['size']})")
    print(f"  stability time: full {full.info['stability']['time']:.2f} s, reduced "
          f"{red.info['stability']['time']:.2f} s")
    print(f"  full   : {bifurcations(full)}")
    print(f"  reduced: {bifurcations(red)}")
    if full.bifurcation_kind.size == red.bifurcation_kind.size > 0:
        d = np.abs(full.bifurcation_frequency_hz - red.bifurcation_frequency_hz).max()
        print(f"  bifurcation frequencies: largest difference {d:.1e} Hz")


def part_a():
    M, C, K = coupled_chain(8)
    kw = dict(elements=[dd.Cubic(0, k3=1.0), dd.Cubic(1, k3=1.0)], force_dofs=[0], force=[FC],
              freqs_hz=(0.16, 0.21), harmonics=5, max_step=0.05, convergence_points=0)
    full = run(M, C, K, stability=True, **kw)
    red = run(M, C, K, stability="reduced", **kw)
    report_pair("A. coupled Duffings grounded through chains, n = 18, H = 5", full, red)


def part_b():
    b, args = problem(20)
    args.update(harmonics=3, freqs_hz=(5.0, 150.0), convergence_points=0, tol=1e-9,
                max_step=0.1)
    args.pop("stability")
    full = run(b, stability=True, **args)
    red = run(b, stability="reduced", **args)
    report_pair("B. cantilever, 20 elements (n = 40), H = 3", full, red)


def full_hill_near(M, C, K, L, Jy, Jv, omega, H, sigma, k=3):
    """The eigenvalues of the full model's Hill problem nearest sigma: shift-invert of its
    companion form with a sparse LU of Q(sigma) = sigma^2 A2 + sigma A1 + A0 (DOF-major)."""
    from dtdyn.nonlinear._harmonic_balance import _basis
    _, _, D = _basis(H, 8 * (H + 1))
    nH = 2 * H + 1
    N = omega * sps.csr_matrix(D)
    I_H, I_n = sps.identity(nH, format="csr"), sps.identity(M.shape[0], format="csr")
    Gy = sum(sps.kron(sps.csr_matrix(np.outer(L[e], L[e])), Jy[e]) for e in range(L.shape[0]))
    Gv = sum(sps.kron(sps.csr_matrix(np.outer(L[e], L[e])), Jv[e]) for e in range(L.shape[0]))
    A2 = sps.kron(M, I_H).tocsc()
    A1 = (2.0 * sps.kron(M, N) + sps.kron(C, I_H) + Gv).tocsc()
    A0 = (sps.kron(M, N @ N) + sps.kron(C, N) + sps.kron(K, I_H) + Gy
          + Gv @ sps.kron(I_n, N)).tocsc()
    lu = spla.splu((sigma * sigma * A2 + sigma * A1 + A0).astype(complex).tocsc())
    m = A2.shape[0]
    B1 = (A1 + sigma * A2).astype(complex)

    def op(z):
        u, v = z[:m], z[m:]
        x = -lu.solve(A2 @ v + B1 @ u)
        return np.concatenate([x, u + sigma * x])
    Op = spla.LinearOperator((2 * m, 2 * m), matvec=op, dtype=complex)
    mu = spla.eigs(Op, k=k, which="LM", return_eigenvectors=False, tol=1e-13)
    return sigma + 1.0 / mu


def part_c(n, every):
    from dtdyn.nonlinear import _harmonic_balance as hb
    b, args = problem(n)
    args.update(harmonics=10, freqs_hz=(5.0, 150.0), convergence_points=0, tol=1e-9,
                receptance="reduced", stability="reduced")
    red = run(b, **args)
    H = 10
    system, *_, model = hb._prepare(
        b, None, None, args["elements"], args["force_dofs"], args["force"], None, None, H,
        args["outputs"], None, "reduced", False, 0.02, 0.1, 1e-7, 0.35, 1e-9, 20, 5000, 0,
        w_top=2 * np.pi * 150.0)
    M, C, K = (sps.csr_matrix(model[x]) for x in "MCK")
    L = model["L"]
    from dtdyn.nonlinear._hill_reduced import reduced_hill_model
    _, _, D = hb._basis(H, system.N)
    big = reduced_hill_model(M, C, K, L, (H + 1) * 2 * np.pi * 150.0, width=3, cutoff=4.0,
                             terms=3)
    worst, labels, checked, conv = 0.0, 0, 0, 0.0
    t0 = time.perf_counter()
    for i in range(0, red.omega.size, every):
        w = red.omega[i]
        lam = red.floquet_exponents[i]
        lam = lam[np.isfinite(lam)]
        crit = lam[(lam.imag > 0)]
        crit = crit[np.argsort(-crit.real)[:2]]          # modes 1 and 2
        U = hb._real(red.element_harmonics[i].T)
        Jy, Jv = system.linearization(U, w)
        lb = hb._hill(*big[:4], Jy, Jv, w, D)
        for x in crit:
            conv = max(conv, float(np.abs(lb - x).min() / abs(x)))
        full = []
        for x in crit:
            near = full_hill_near(M, C, K, L, Jy, Jv, w, H, x)
            y = near[np.argmin(np.abs(near - x))]
            full.append(y)
            worst = max(worst, float(abs(y - x) / abs(y)))
        labels += (max(f.real for f in full) < 1e-9 * w) == red.stable[i]
        checked += 1
    print(f"C. cantilever, {n} elements (n = {M.shape[0]}), H = 10: {red.omega.size} points, "
          f"{checked} checked; reduced model {red.info['stability']['size']} DOFs "
          f"({red.info['stability']['modes']} modes)")
    print(f"  modes 1 and 2's exponents against a larger reduced model (modes below 4 (H + 1) "
          f"omega_top, 3 mass corrections: {big[4]['size']} DOFs): largest relative "
          f"difference {conv:.1e}")
    print(f"  modes 1 and 2's exponents, reduced against the full Hill (shift-invert): largest "
          f"relative difference {worst:.1e}; labels equal at {labels} of {checked}; "
          f"{int(np.count_nonzero(~red.stable))} unstable points; bifurcations: "
          f"{bifurcations(red) or 'none'} ({time.perf_counter() - t0:.0f} s)")


def part_d(n):
    off, tol, _ = curve(n, "reduced", stability=False)      # the first tol that gets through
    on, tol_on, _ = curve(n, "reduced", stability="reduced")
    s = on.info["stability"]
    print(f"D. cantilever, {n} elements: stability=False {off.omega.size} points in "
          f"{off.info['run_time']:.2f} s ({1e3 * off.info['run_time'] / off.omega.size:.1f} ms "
          f"per point); stability='reduced' {on.omega.size} points in {on.info['run_time']:.2f} s "
          f"({1e3 * on.info['run_time'] / on.omega.size:.1f} ms per point, Hill "
          f"{1e3 * s['time'] / on.omega.size:.1f} ms per point, reduced model {s['size']} DOFs: "
          f"{s['modes']} modes below {s['cutoff_hz']:.0f} Hz + {s['attachment']} attachment "
          f"vectors); {int(np.count_nonzero(on.stable))} stable, "
          f"{int(np.count_nonzero(~on.stable))} unstable; bifurcations: "
          f"{bifurcations(on) or 'none'} (Newton tol {tol:g}, {tol_on:g})")
    return on.info["run_time"] / on.omega.size, s["time"] / on.omega.size


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--parts", default="ABCD")
    a = parser.parse_args()
    with pin_blas(1):
        parts(a)


def parts(a):
    if "A" in a.parts:
        part_a()
    if "B" in a.parts and not a.quick:
        part_b()
    if "C" in a.parts:
        part_c(300, 5)
        if not a.quick:
            part_c(1000, 20)
    if "D" in a.parts:
        per = [part_d(n) for n in (1000, 10000)]
        print(f"D. per point, N = 10,000 / N = 1,000: the curve {per[1][0] / per[0][0]:.2f}, "
              f"Hill's method {per[1][1] / per[0][1]:.2f}")


if __name__ == "__main__":
    main()
