"""chain_frequencies and chain_poles against LAPACK in the same run.

Lowest 10 natural frequencies of a 100,000-mass random chain (masses 0.5..2 kg, springs
5e3..2e4 N/m): `chain_frequencies` (roots isolated by the Wittrick-Williams count, polished by
Laguerre's iteration on det(K - lambda M), C) against
scipy.linalg.eigh_tridiagonal (LAPACK stebz bisection) on the symmetrized pencil; and the
relative error of each on a uniform chain of the same length, whose frequencies are known in
closed form. Then the lowest 20 damped poles of a 1,000-mass chain (`chain_poles`) against
numpy.linalg.eigvals of the 2,000-state first-order form. Times: median [min, max] of 3 runs
after a warm-up, BLAS pinned to one thread (dtdyn.app.pin_blas, threadpoolctl).

    python benchmarks/chain_frequencies.py
"""
import numpy as np
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.app import measure, pin_blas


def _tridiagonal(m, k):
    a = k + np.r_[k[1:], 0.0]
    return a / m, -k[1:] / np.sqrt(m[1:] * m[:-1])


def _timed(fn, repeats=3):
    """(result, Timing: median and spread of ``repeats`` calls after a warm-up)."""
    return measure(fn, repeats)


def main(n=100_000, count=10):
    rng = np.random.default_rng(1)
    m, k = rng.uniform(0.5, 2.0, n), rng.uniform(5e3, 2e4, n)
    dd.chain_frequencies(m[:10], k[:10])  # compile or load the kernel
    w, t_ours = _timed(lambda: dd.chain_frequencies(m, k, count=count))
    lam, t_lapack = _timed(lambda: sla.eigh_tridiagonal(*_tridiagonal(m, k), eigvals_only=True,
                                                        select="i",
                                                        select_range=(0, count - 1)))
    print(f"lowest {count} of a {n:,}-mass random chain: chain_frequencies "
          f"{t_ours.format('s')}, eigh_tridiagonal {t_lapack.format('s')} "
          f"(ratio of the medians {t_ours / t_lapack:.2f})")
    mu, ku = np.full(n, 2.0), np.full(n, 1e4)
    j = np.arange(1, count + 1)
    exact = 2 * np.sqrt(ku[0] / mu[0]) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    ours = dd.chain_frequencies(mu, ku, count=count)
    lapack = np.sqrt(sla.eigh_tridiagonal(*_tridiagonal(mu, ku), eigvals_only=True, select="i",
                                          select_range=(0, count - 1)))
    print(f"uniform chain, max relative error of the lowest {count}: chain_frequencies "
          f"{np.max(np.abs(ours / exact - 1)):.1e}, eigh_tridiagonal "
          f"{np.max(np.abs(lapack / exact - 1)):.1e}")
    m, k, c = rng.uniform(0.5, 2, 1000), rng.uniform(5e3, 2e4, 1000), rng.uniform(0, 1, 1000)
    s, t_poles = _timed(lambda: dd.chain_poles(m, k, c, count=20))
    M, C, K = dd.chain_matrices(m, k, c, sparse=False)
    A, _ = dd.first_order_form(M, C, K)
    ev, t_eig = _timed(lambda: np.linalg.eigvals(A))
    ev = ev[ev.imag > 0]
    ev = ev[np.argsort(np.abs(ev))][:20]
    print(f"lowest 20 damped poles of a 1,000-mass chain: chain_poles {t_poles.format('s')}, "
          f"eigvals of the first-order form {t_eig.format('s')}; they agree to "
          f"{np.max(np.abs(s / ev - 1)):.1e}")


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        main()
