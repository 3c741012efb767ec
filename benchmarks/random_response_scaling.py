"""Response PSDs of a beam at 2,000 frequencies: the time per frequency grows like the element
count (O(N)), and the receptances equal a sparse direct solve.

A clamped-free beam (E = 2.1e11, I = 8e-6, rho_A = 20, elements 0.3 m long: L = 0.3 N, a long
rail or pipeline; Rayleigh damping C = 1.0 M + 1e-5 K) of N = 1,250 .. 20,000 elements, a random
force at the tip with a PSD table
(20 .. 2,000 Hz), the outputs the tip and the middle: at 2,000 frequencies (1 .. 2,000 Hz) the
output cross-spectral matrix S = H S_f H^H, H by `beam_frequency_response` (the path
`beam_random_response` takes for the PSDs it returns: the block-tridiagonal LU of the node
blocks), in blocks of 50 frequencies.

Times: each block of 50 frequencies timed once after a warm-up block, BLAS pinned to one
thread (dtdyn.app.pin_blas); per frequency: the median over the 40 blocks [min, max].
The slope of log(time per frequency) against log(N) is fitted over the five sizes.

Accuracy: for N = 20,000, at five frequencies, H against the solution of
(K - omega^2 M + i omega C) u = e_tip on `beam_matrices` by a sparse LU with iterative
refinement, its residual summed in long double (the exact solution, rounded): the largest
difference relative to the largest receptance at that frequency; beside it, the same difference
of a plain scipy.sparse.linalg.spsolve (what a direct solve alone gets). (The element length is
kept at 0.3 m so that Z's condition number stays far below 1/eps: with 20,000 elements in a 3 m
beam a direct solve loses everything at 400 Hz.)

Usage: python benchmarks/random_response_scaling.py   (about a minute)
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

import dtdyn as dd
from dtdyn.app import Timing, pin_blas
from dtdyn.random_vibration import psd_table

SIZES = (1250, 2500, 5000, 10000, 20000)
FREQS_HZ = np.linspace(1.0, 2000.0, 2000)
BLOCK = 50
TABLE = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # N^2/Hz


def beam(n):
    return dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=0.3 * n, elements=n, left="clamped",
                   rayleigh=(1.0, 1e-5))


def response_psd(b, n, freqs_hz):
    """(S (n_freq, 2, 2), H (n_freq, 2, 1)) at the tip and the middle, force at the tip."""
    H = dd.beam_frequency_response(b, 2 * np.pi * freqs_hz, [f"w{n}"], [f"w{n}", f"w{n // 2}"])
    S = H @ (TABLE(freqs_hz)[:, None, None] * np.swapaxes(H.conj(), 1, 2))
    return S, H


def timed(n):
    """Timing per frequency over the blocks, and H at every frequency."""
    b = beam(n)
    t0 = time.perf_counter()
    response_psd(b, n, FREQS_HZ[:BLOCK])                      # warm-up
    first = time.perf_counter() - t0
    times, H = [], []
    for lo in range(0, FREQS_HZ.size, BLOCK):
        t0 = time.perf_counter()
        _, h = response_psd(b, n, FREQS_HZ[lo:lo + BLOCK])
        times.append((time.perf_counter() - t0) / BLOCK)
        H.append(h)
    return Timing(times, first / BLOCK), np.concatenate(H)


def refined_solve(Z, rhs, steps=4):
    """u with Z u = rhs by one sparse LU and ``steps`` rounds of iterative refinement whose
    residual rhs - Z u is summed in long double (each round gains about -log10(cond eps)
    digits; the result is the exact solution rounded, where cond(Z) eps << 1)."""
    lu = spla.splu(Z.tocsc())
    Zr = Z.tocsr()
    data = Zr.data.astype(np.clongdouble)
    rows = np.repeat(np.arange(Zr.shape[0]), np.diff(Zr.indptr))
    u = lu.solve(rhs).astype(np.clongdouble)
    for _ in range(steps):
        Zu = np.zeros(Zr.shape[0], dtype=np.clongdouble)
        np.add.at(Zu, rows, data * u[Zr.indices])
        r = rhs.astype(np.clongdouble) - Zu
        u = u + lu.solve(r.astype(complex)).astype(np.clongdouble)
    return u.astype(complex)


def direct(n, freqs_hz):
    """Receptances at the tip and the middle by a sparse direct solve refined to the exact
    solution (`refined_solve`), and the largest relative difference of a plain spsolve from
    it (the unrefined direct solve's own rounding error)."""
    M, C, K = (sps.csc_matrix(A) for A in dd.beam_matrices(beam(n)))
    b = beam(n)
    tip, mid = b.dof(f"w{n}"), b.dof(f"w{n // 2}")
    out, spread = [], []
    for f in freqs_hz:
        w = 2 * np.pi * f
        Z = (K - w * w * M + 1j * w * C).tocsc()
        rhs = np.zeros(M.shape[0], dtype=complex)
        rhs[tip] = 1.0
        u = refined_solve(Z, rhs)
        plain = spla.spsolve(Z, rhs)
        out.append([u[tip], u[mid]])
        spread.append(np.abs(plain - u).max() / np.abs(u).max())
    return np.array(out)[:, :, None], np.array(spread)


def main():
    print(f"beam response PSD (tip force, tip and middle outputs) at {FREQS_HZ.size} "
          "frequencies, time per frequency: median over 40 blocks of 50 [min, max]")
    print("   elements   per frequency            total (s)")
    per_freq = []
    with pin_blas(1):
        for n in SIZES:
            t, H = timed(n)
            per_freq.append(t.median)
            print(f"   {n:8,d}   {t.format('ms'):24s} {sum(t.times) * BLOCK:7.2f}")
            if n == SIZES[-1]:
                H_last = H
    slope = np.polyfit(np.log(SIZES), np.log(per_freq), 1)[0]
    print(f"   fitted slope of log(time per frequency) against log(elements): {slope:.2f}")
    pick = np.array([1, 400, 999, 1500, 1999])
    ref, spread = direct(SIZES[-1], FREQS_HZ[pick])
    err = (np.abs(H_last[pick] - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2)))
    print(f"   {SIZES[-1]:,d} elements against (K - w^2 M + i w C) u = e_tip solved with "
          "refinement:")
    for f, e, s in zip(FREQS_HZ[pick], err, spread):
        print(f"      {f:7.1f} Hz: max relative difference {e:.1e}   (a plain spsolve: "
              f"{s:.1e})")


if __name__ == "__main__":
    main()
