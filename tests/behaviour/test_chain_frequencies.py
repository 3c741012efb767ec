"""chain_frequencies (Wittrick-Williams count + bisection) against independent truths: the
closed form of a uniform fixed-free chain, scipy.linalg.eigh_tridiagonal on the symmetrized
pencil M^-1/2 K M^-1/2, and the count itself at every root."""
import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.linear._frequencies import sturm_counts


def _uniform_exact(N, m, k, count):
    """omega_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2N + 1))), j = 1 .. count (fixed-free)."""
    j = np.arange(1, count + 1)
    return 2.0 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * N + 1)))


def _tridiagonal(m, k):
    a = k + np.r_[k[1:], 0.0]
    return a / m, -k[1:] / np.sqrt(m[1:] * m[:-1])


@pytest.mark.parametrize("N", [1, 15, 2000, 100_000])
def test_uniform_chain_to_a_few_ulps(N):
    """Relative error of the lowest 10 against the closed form: <= 1e-12 even at N = 1e5, where
    omega_1 / omega_max = 1.6e-5 (the series form of the recursion keeps small roots exact)."""
    count = min(N, 10)
    w = dd.chain_frequencies(np.full(N, 2.0), np.full(N, 1e4), count=count)
    exact = _uniform_exact(N, 2.0, 1e4, count)
    assert np.abs(w / exact - 1).max() <= 1e-12


@pytest.mark.slow
def test_random_100k_chain_lowest_ten():
    """The issue's case: 100,000 random masses and springs, the lowest 10. eigh_tridiagonal
    (LAPACK's bisection, accurate to a few ulps of the largest eigenvalue) agrees to 1e-12 of
    omega_max^2; a relative check of ours is the uniform chain above."""
    rng = np.random.default_rng(1)
    m, k = rng.uniform(0.5, 2.0, 100_000), rng.uniform(5e3, 2e4, 100_000)
    w = dd.chain_frequencies(m, k, count=10)
    lam = sla.eigh_tridiagonal(*_tridiagonal(m, k), eigvals_only=True, select="i",
                               select_range=(0, 9))
    lam_max = np.max(2 * (k + np.r_[k[1:], 0.0]) / m)
    assert np.abs(w**2 - lam).max() <= 1e-12 * lam_max
    assert (sturm_counts(m, k, w * (1 - 1e-12)) == np.arange(10)).all()


def test_all_frequencies_of_a_2000_mass_chain_and_the_count_at_every_root():
    rng = np.random.default_rng(7)
    m, k = rng.uniform(0.5, 2.0, 2000), rng.uniform(5e3, 2e4, 2000)
    w = dd.chain_frequencies(m, k)
    lam = sla.eigh_tridiagonal(*_tridiagonal(m, k), eigvals_only=True)
    assert w.size == 2000 and np.all(np.diff(w) > 0)
    lam_max = np.max(2 * (k + np.r_[k[1:], 0.0]) / m)
    assert np.abs(w**2 - lam).max() <= 1e-12 * lam_max
    assert (sturm_counts(m, k, w * (1 - 1e-12)) == np.arange(2000)).all()
    assert (sturm_counts(m, k, w * (1 + 1e-12)) == np.arange(1, 2001)).all()


EPS = np.finfo(float).eps


@pytest.mark.parametrize("seed", range(12))
def test_polished_roots_equal_bisection_to_adjacent_floats(seed):
    """Laguerre's polish against bisection on the count alone to adjacent floats (polish=False,
    the computed count's own transition): both sit on the rounding floor of the recursion, a
    few ulps for these lengths (1.5 ulps the worst over 40 such chains), so 4 ulps. Mild and
    wild (1e-4..1e4 masses and springs) random chains, 1 to 400 masses."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    if seed % 2:
        m, k = rng.uniform(0.5, 2.0, n), rng.uniform(5e3, 2e4, n)
    else:
        m, k = 10 ** rng.uniform(-4, 4, n), 10 ** rng.uniform(-4, 4, n)
    w = dd.chain_frequencies(m, k)
    assert np.abs(w / dd.chain_frequencies(m, k, polish=False) - 1).max() <= 4 * EPS
    assert w.size == n and np.all(np.diff(w) > 0)


def test_polished_roots_against_the_count_at_every_root_of_2000_masses():
    """Two ulps below each polished root the count is j, two ulps above it is j + 1: no root
    missed or doubled, each within two ulps of the count's transition. The same roots, to the
    bit, whether asked for by count, below or all, in C or NumPy, and in any units (powers of
    two scale the frequencies exactly)."""
    rng = np.random.default_rng(7)
    m, k = rng.uniform(0.5, 2.0, 2000), rng.uniform(5e3, 2e4, 2000)
    w = dd.chain_frequencies(m, k)
    assert (sturm_counts(m, k, w * (1 - 2 * EPS)) == np.arange(2000)).all()
    assert (sturm_counts(m, k, w * (1 + 2 * EPS)) == np.arange(1, 2001)).all()
    np.testing.assert_array_equal(dd.chain_frequencies(m, k, count=25), w[:25])
    np.testing.assert_array_equal(dd.chain_frequencies(m, k, below=(w[39] + w[40]) / 2), w[:40])
    np.testing.assert_array_equal(dd.chain_frequencies(m[:60], k[:60], backend="numpy"),
                                  dd.chain_frequencies(m[:60], k[:60]))
    np.testing.assert_array_equal(dd.chain_frequencies(m * 2.0**400, k * 2.0**-300, count=30),
                                  w[:30] * 2.0**-350)


def test_below_numpy_backend_and_p3(p3):
    w = dd.chain_frequencies(p3["mass"], p3["stiffness"])
    M, _, K = dd.chain_matrices(p3["mass"], p3["stiffness"], p3["damping"], sparse=False)
    np.testing.assert_allclose(w, np.sqrt(sla.eigh(K, M, eigvals_only=True)), rtol=1e-12)
    np.testing.assert_allclose(dd.chain_frequencies(p3["mass"], p3["stiffness"], below=50.0),
                               w[w < 50.0], rtol=0)
    np.testing.assert_array_equal(dd.chain_frequencies(p3["mass"], p3["stiffness"],
                                                       backend="numpy"), w)
    assert dd.chain_frequencies(p3["mass"], p3["stiffness"], below=1.0).size == 0


@pytest.mark.parametrize("kw, match", [
    ({"count": 0}, "count must be an integer"),
    ({"count": 16}, "count = 16 exceeds"),
    ({"count": 2, "below": 3.0}, "not both"),
    ({"below": -1.0}, "below must be finite and > 0"),
    ({"backend": "fortran"}, "backend"),
])
def test_bad_input(p3, kw, match):
    with pytest.raises(ValueError, match=match):
        dd.chain_frequencies(p3["mass"], p3["stiffness"], **kw)
    with pytest.raises(ValueError, match=r"stiffness\[1\] = 0.0"):
        dd.chain_frequencies([1.0, 1.0], [1.0, 0.0])


def _first_order_poles(m, k, c):
    M, C, K = dd.chain_matrices(m, k, c, sparse=False)
    A, _ = dd.first_order_form(M, C, K)
    ev = np.linalg.eigvals(A)
    ev = ev[ev.imag > 0]
    return ev[np.argsort(np.abs(ev))]


@pytest.mark.parametrize("damping", ["stiffness", "uniform", "half"])
def test_damped_poles_equal_the_first_order_eigenvalues(p3, damping):
    """Proportional, uniform and non-proportional (dampers on the upper half only) damping on
    P3: the poles equal the eigenvalues of the first-order form to 1e-12."""
    c = {"stiffness": 1e-3 * p3["stiffness"], "uniform": np.full(15, 5.0),
         "half": np.r_[np.zeros(7), np.full(8, 40.0)]}[damping]
    s = dd.chain_poles(p3["mass"], p3["stiffness"], c)
    np.testing.assert_allclose(s, _first_order_poles(p3["mass"], p3["stiffness"], c), rtol=1e-12)


def test_damped_poles_of_a_long_chain_and_errors():
    """The lowest 20 of a 1,000-mass chain with random dampers: equal to numpy's eigenvalues of
    the 2,000-state first-order form within their own error, eps |A| / |s_1| ~ 1e-10."""
    rng = np.random.default_rng(2)
    m, k, c = rng.uniform(0.5, 2, 1000), rng.uniform(5e3, 2e4, 1000), rng.uniform(0, 1, 1000)
    s = dd.chain_poles(m, k, c, count=20)
    np.testing.assert_allclose(s, _first_order_poles(m, k, c)[:20], rtol=1e-9)
    with pytest.raises(ValueError, match="upper half-plane|did not converge"):
        dd.chain_poles([1.0, 1.0], [1.0, 1.0], [50.0, 50.0])       # overdamped


def _grounded(m, k, c, kg, cg):
    """M, C, K of the chain with springs kg and dampers cg from each mass to the ground,
    assembled here entry by entry (K[n, n] += kg_n, C[n, n] += cg_n)."""
    def tri(v, g):
        A = np.diag(v + np.r_[v[1:], 0.0] + g)
        A -= np.diag(v[1:], 1) + np.diag(v[1:], -1)
        return A
    return np.diag(m), tri(c, cg), tri(k, kg)


def _grounded_chain(seed, n=40):
    """Random masses, springs, dampers and ground elements; seed 2 also cuts stations 0 and
    n // 2 (k = 0: mass 0 and the upper half held by their ground springs only)."""
    rng = np.random.default_rng(seed)
    m, k, c = rng.uniform(0.5, 2.0, n), rng.uniform(5e3, 2e4, n), rng.uniform(0.0, 2.0, n)
    kg, cg = rng.uniform(1.0, 3e3, n), rng.uniform(0.0, 1.0, n)
    if seed == 2:
        k[[0, n // 2]] = 0.0
    return m, k, c, kg, cg


@pytest.mark.parametrize("seed", range(3))
def test_ground_springs_equal_eigh_of_the_assembled_matrices(seed):
    """K + diag(kg), M: scipy's eigh to 1e-12 (lambda_max / lambda_1 < 100 here, so eigh's own
    error is ~1e-14 relative; 8e-15 measured); the count between its roots."""
    m, k, c, kg, cg = _grounded_chain(seed)
    M, _, K = _grounded(m, k, c, kg, cg)
    lam = sla.eigh(K, M, eigvals_only=True)
    w = dd.chain_frequencies(m, k, ground_stiffness=kg)
    np.testing.assert_allclose(w, np.sqrt(lam), rtol=1e-12)
    np.testing.assert_array_equal(dd.chain_frequencies(m, k, ground_stiffness=kg,
                                                       backend="numpy"), w)
    np.testing.assert_allclose(dd.chain_frequencies(m, k, ground_stiffness=kg, polish=False),
                               w, rtol=4 * EPS)
    mids = np.sqrt(np.r_[0.5 * lam[0], 0.5 * (lam[1:] + lam[:-1]), 2 * lam[-1]])
    np.testing.assert_array_equal(sturm_counts(m, k, mids, ground_stiffness=kg),
                                  np.arange(41))
    if seed != 2:  # kg = 0 is the chain without ground springs, to the bit
        np.testing.assert_array_equal(dd.chain_frequencies(m, k, ground_stiffness=0 * kg),
                                      dd.chain_frequencies(m, k))


def test_a_chain_in_parts_held_by_ground_springs():
    """k_0 = 0 and an interior k_i = 0: the chain splits into parts that only ground springs
    hold; each eigenvalue of two equal parts is double, and both copies are found."""
    m = np.array([1.0, 2.0, 1.5, 1.0, 2.0, 1.5])
    k = np.array([0.0, 3e3, 2e3, 0.0, 3e3, 2e3])
    kg = np.array([5e2, 0.0, 0.0, 5e2, 0.0, 0.0])
    M, _, K = _grounded(m, k, np.zeros(6), kg, np.zeros(6))
    lam = sla.eigh(K, M, eigvals_only=True)
    w = dd.chain_frequencies(m, k, ground_stiffness=kg)
    np.testing.assert_allclose(w, np.sqrt(lam), rtol=1e-12)
    np.testing.assert_array_equal(dd.chain_frequencies(m, k, ground_stiffness=kg,
                                                       backend="numpy"), w)
    m2, k2 = m[:3], np.array([0.0, 3e3, 2e3])       # one part alone: each root twice above
    w2 = dd.chain_frequencies(m2, k2, ground_stiffness=kg[:3])
    assert np.sum(np.abs(w[:, None] / w2[None, :] - 1) <= 1e-14) == 6
    with pytest.raises(ValueError, match="coincide"):  # Aberth cannot start on a double root
        dd.chain_poles(m, k, np.full(6, 0.1), ground_stiffness=kg)


@pytest.mark.parametrize("seed", range(3))
def test_ground_dampers_poles_equal_the_first_order_eigenvalues(seed):
    """C + diag(cg), K + diag(kg) (seed 2 in parts): numpy's eigenvalues of the first-order
    form to 1e-12, as for P3 above."""
    m, k, c, kg, cg = _grounded_chain(seed, n=15)
    M, C, K = _grounded(m, k, c, kg, cg)
    A, _ = dd.first_order_form(M, C, K)
    ev = np.linalg.eigvals(A)
    ev = ev[ev.imag > 0]
    s = dd.chain_poles(m, k, c, ground_stiffness=kg, ground_damping=cg)
    np.testing.assert_allclose(s, ev[np.argsort(np.abs(ev))], rtol=1e-12)


@pytest.mark.parametrize("kw, match", [
    ({"ground_stiffness": [1.0, -1.0, 0.0]}, r"ground_stiffness\[1\] = -1.0"),
    ({"ground_stiffness": [1.0, np.nan, 0.0]}, r"ground_stiffness\[1\] = nan"),
    ({"ground_stiffness": [1.0, 1.0]}, "ground_stiffness has length 2, expected 3"),
    ({"ground_damping": [0.0, 0.0, -2.0]}, r"ground_damping\[2\] = -2.0"),
    ({"ground_damping": [0.0, np.inf, 0.0]}, r"ground_damping\[1\] = inf"),
])
def test_bad_ground_elements(kw, match):
    with pytest.raises(ValueError, match=match):
        dd.chain_poles([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.1, 0.1, 0.1], **kw)


def test_a_part_without_ground_is_refused():
    with pytest.raises(ValueError, match=r"stiffness\[2\] = 0.0 leaves masses 2..3 with no "
                                         "spring to the ground"):
        dd.chain_frequencies([1.0] * 5, [1.0, 1.0, 0.0, 1.0, 0.0],
                             ground_stiffness=[0.0, 0.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"stiffness\[0\] = 0.0 leaves masses 0..1"):
        sturm_counts([1.0, 1.0], [0.0, 1.0], [1.0], ground_stiffness=[0.0, 0.0])
    with pytest.raises(ValueError, match=r"stiffness\[0\] = 0.0: every entry must be finite "
                                         "and > 0"):
        dd.chain_frequencies([1.0, 1.0], [0.0, 1.0])    # without ground springs: k > 0


def test_below_beyond_the_floats_gives_every_frequency():
    """below^2 overflows a float (found by the fuzzer): every frequency is below it."""
    m, k = [1.0, 2.0], [100.0, 50.0]
    np.testing.assert_array_equal(dd.chain_frequencies(m, k, below=1.34e154),
                                  dd.chain_frequencies(m, k))
