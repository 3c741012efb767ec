"""beam_frequencies against extended-precision eigenvalues of the same matrices (issue 29).

The reference: for each mode, two steps of inverse iteration in mpmath (34 digits) on the
banded K - sigma M of `beam_matrices`, from LAPACK's eigenpair, then the Rayleigh quotient
(each step multiplies the error by |lambda - sigma| / gap ~ 1e-8, so the reference is good
to far below the float64 errors compared). LAPACK (scipy eigh on the dense matrices) is the
yardstick: its error is about eps lambda_max absolute, the count's a few ulps relative.
"""
import time

import mpmath
import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.linear import _beam

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0


def _band_solve(A, rhs, p):
    """A x = rhs, A a dict-of-rows band (half-width p), by LU with partial pivoting."""
    n = len(rhs)
    A = [dict(row) for row in A]
    b = list(rhs)
    for k in range(n):
        last = min(n, k + p + 1)
        piv = max(range(k, last), key=lambda r: abs(A[r].get(k, 0)))
        A[k], A[piv] = A[piv], A[k]
        b[k], b[piv] = b[piv], b[k]
        for r in range(k + 1, last):
            f = A[r].get(k, 0) / A[k][k]
            if f:
                for c, v in A[k].items():
                    if c > k:
                        A[r][c] = A[r].get(c, 0) - f * v
                b[r] -= f * b[k]
    x = [mpmath.mpf(0)] * n
    for k in range(n - 1, -1, -1):
        x[k] = (b[k] - mpmath.fsum(v * x[c] for c, v in A[k].items() if c > k)) / A[k][k]
    return x


def extended_eigenvalues(K, M, modes, dps=34):
    """lambda_j of (K, M) (dense float arrays, banded) to about dps digits, for j in modes."""
    n = K.shape[0]
    rows, cols = np.nonzero(K)
    p = int(np.max(np.abs(rows - cols)))
    lam0, V = sla.eigh(K, M)
    out = []
    with mpmath.workdps(dps):
        band = lambda A: [{j: mpmath.mpf(float(A[i, j])) for j in range(max(0, i - p),  # noqa: E731
                                                                         min(n, i + p + 1))
                           if A[i, j] != 0.0} for i in range(n)]
        Kb, Mb = band(K), band(M)
        mv = lambda A, x: [mpmath.fsum(v * x[j] for j, v in row.items()) for row in A]  # noqa: E731
        for j in modes:
            sigma = mpmath.mpf(float(lam0[j]))
            A = [{c: Kb[i].get(c, 0) - sigma * Mb[i].get(c, 0) for c in set(Kb[i]) | set(Mb[i])}
                 for i in range(n)]
            x = [mpmath.mpf(float(v)) for v in V[:, j]]
            for _ in range(2):
                x = _band_solve(A, mv(Mb, x), p)
                s = max(abs(v) for v in x)
                x = [v / s for v in x]
            out.append(float(mpmath.fsum(a * b for a, b in zip(x, mv(Kb, x)))
                             / mpmath.fsum(a * b for a, b in zip(x, mv(Mb, x)))))
    return np.array(out), lam0


@pytest.mark.parametrize("ends", [("pinned", "pinned"), ("free", "free"), ("clamped", "free")])
def test_count_as_accurate_as_lapack(ends):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=64, left=ends[0], right=ends[1])
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    rigid = 2 if ends == ("free", "free") else 0
    modes = [rigid + j for j in (0, 1, 2, 3, 5, 9, 30, 100)]
    ref, lam0 = extended_eigenvalues(K, M, modes)
    w = dd.beam_frequencies(beam)
    ours = np.abs(w[modes] ** 2 - ref) / ref
    lapack = np.abs(lam0[modes] - ref) / ref
    # within 10x of LAPACK's worst error over these modes (mode by mode the count can be up
    # to ~50x off a mode where LAPACK happens to be exact to 4e-13; measured, not asserted)
    assert ours.max() <= 10 * lapack.max()
    assert ours.max() < 1e-10
    # the lowest modes: far better than LAPACK (its error is eps lambda_max absolute)
    assert ours[0] < 1e-3 * lapack[0]


def test_never_below_the_continuum():
    """Consistent mass: the FE frequencies are upper bounds of the continuum's; the issue's
    128-element pinned-pinned beam had mode 3 1.9e-7 below it."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=128, left="pinned", right="pinned")
    w = dd.beam_frequencies(beam, count=12)
    exact = (np.arange(1, 13) * np.pi) ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))
    assert np.all(w >= exact), (w / exact - 1)


def test_rigid_modes_exact_zeros_and_fast():
    free = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=200, left="free", right="free")
    cant = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=200, left="clamped", right="free")
    t0 = time.perf_counter()
    w_free = dd.beam_frequencies(free, count=20)
    t1 = time.perf_counter()
    dd.beam_frequencies(cant, count=20)
    t2 = time.perf_counter()
    assert w_free[0] == 0.0 and w_free[1] == 0.0 and w_free[2] > 0.0
    assert t1 - t0 < 2.0 * (t2 - t1) + 0.05
    pinned_free = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=20, left="pinned",
                          right="free")
    w = dd.beam_frequencies(pinned_free, count=3)
    assert w[0] == 0.0 and w[1] > 0.0
    assert _beam.rigid_body_modes(pinned_free) == 1


def test_roots_do_not_depend_on_count_and_few_counts(monkeypatch):
    """Every root's path depends on the beam and its index alone (the same bits for count,
    below and all); regula falsi inside each isolating bracket needs far fewer counts than
    bisecting to adjacent floats (93 for this beam)."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=200, left="clamped", right="free")
    inertia = _beam._inertia
    calls = []

    def counted(*args, **kwargs):
        calls.append(args[1].size)
        return inertia(*args, **kwargs)

    monkeypatch.setattr(_beam, "_inertia", counted)
    w5 = dd.beam_frequencies(beam, count=5)
    assert len(calls) <= 30, len(calls)
    monkeypatch.setattr(_beam, "_inertia", inertia)
    w = dd.beam_frequencies(beam, count=40)
    assert np.array_equal(w[:5], w5)
    assert np.array_equal(dd.beam_frequencies(beam, below=float(w[12]) * (1 + 1e-9)), w[:13])
    # the count agrees with LAPACK between the roots
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    lam = sla.eigh(K, M, eigvals_only=True)
    between = np.sqrt(lam[:39] * lam[1:40])
    assert np.array_equal(_beam.wittrick_williams_counts(beam, between),
                          np.arange(1, 40))


def test_guarded_pass_gives_the_same_counts():
    """The guarded pass (taken when a pivot cancels exactly) counts as the plain one."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=30, left="pinned", right="free",
                   supports=[dd.Support(node=12, k_w=1e6)])
    mod = _beam
    blocks = mod._count_blocks(beam)
    lam = np.geomspace(1.0, 1e14, 200).astype(mod._WIDE) * mod._WIDE(blocks[-1])
    plain, logdet = mod._inertia(blocks, lam, det=True)
    guarded, logdet_g = mod._inertia(blocks, lam, det=True, guard=True)
    assert np.array_equal(plain, guarded)
    assert np.allclose(logdet, logdet_g, rtol=0, atol=1e-9)


def test_shaft_count_with_a_stiff_spring():
    """shaft_frequencies' pivot recursion in the series form (S_L = -k s / (k + s) for a
    lumped spring): a shaft with springs six decades stiffer in its second half keeps a few
    ulps on the low modes, where -k + k^2 / D left eps k absolute (1.8e-7 relative on mode
    1 at 400 disks) and LAPACK is further off still."""
    rng = np.random.default_rng(1)
    n = 100
    k = np.where(np.arange(n) < n // 2, 1e6, 1e12)
    shaft = dd.Shaft(rng.uniform(0.5, 2.0, n), list(k), [0.0] * n, left="clamped")
    M, _, K = (A.toarray() for A in dd.shaft_matrices(shaft))
    modes = [0, 1, 2, 5, 20, 60]
    ref, lam0 = extended_eigenvalues(K, M, modes)
    w = dd.shaft_frequencies(shaft, count=61)
    ours = np.abs(w[modes] ** 2 - ref) / ref
    lapack = np.abs(lam0[modes] - ref) / ref
    assert ours.max() < 1e-14, ours        # a few ulps: the chain's count on the same shaft
    assert ours[0] < 1e-3 * lapack[0], (ours, lapack)
