r"""Natural frequencies of long chains by the Wittrick-Williams count, O(N) per evaluation.

For a chain (station n joins mass n to mass n - 1, station 0 to the ground) the number of
natural frequencies with :math:`\omega^2 < \lambda` equals the number of negative pivots of
:math:`K - \lambda M` (Sylvester's law of inertia; Wittrick & Williams, *Q. J. Mech. Appl.
Math.* 24, 1971, with no interior element DOFs). The pivots are the dynamic stiffnesses of the
chain condensed from the ground up, the frequency-domain Riccati recursion of the stable sweep:
mass i sees through station i the stiffness

.. math::

    s_0 = k_0 - \lambda m_0, \qquad
    s_i = \frac{k_i\, s_{i-1}}{k_i + s_{i-1}} - \lambda m_i, \qquad d_i = s_i + k_{i+1}
    \ (k_N = 0),

(station i in series with what is below it, less the inertia of mass i). This equals the
textbook pivot :math:`d_i = k_i + k_{i+1} - \lambda m_i - k_i^2 / d_{i-1}`, but adds positive
terms where that one cancels, so the lowest frequencies of a long chain keep a few ulps of
relative accuracy (the textbook count, like LAPACK's dstebz, is accurate only to a few ulps of
the largest eigenvalue: 1e-8 relative on the lowest of a 100,000-mass chain).

Each root :math:`\lambda_j` is the smallest :math:`\lambda` with count > j: bisection on the
count, from :math:`[0, \lambda_{\max}]` (Gershgorin: :math:`\max_i (a_i + k_i + k_{i+1})/m_i`),
all wanted roots at once, until the bracket is two adjacent floating-point numbers. No root is
missed or found twice (the count decides) and nothing overflows (a tiny pivot is replaced by
-pivmin). The counts run in the generated C kernel (generated/sturm.c), with a NumPy
fallback.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources

import numpy as np

from dtdyn._engine import cbuild, validate

__all__ = ["chain_frequencies", "chain_poles", "sturm_counts"]


def _coefficients(mass, stiffness):
    m = validate.vector("mass", mass, positive=True)
    k = validate.vector("stiffness", stiffness, positive=True, length=m.size)
    pivmin = np.finfo(float).tiny * max(1.0, float(k.max()) ** 2)
    return m, k, pivmin


@lru_cache(maxsize=None)
def _c_counts():
    source = resources.files("dtdyn.generated").joinpath("sturm.c").read_text()
    lib = cbuild.load_library(source, "sturm")
    return None if lib is None else cbuild.bind(lib, "dtdyn_sturm_counts")


def _counts(m, k, pivmin, lam, backend="c"):
    """Eigenvalues below each lam: negative pivots d_i = s_i + k_{i+1} (module docstring)."""
    lam = np.ascontiguousarray(lam, dtype=float)
    fn = _c_counts() if backend == "c" else None
    if fn is not None:
        out = np.empty(lam.size, dtype=np.int64)
        fn(m.size, k.ctypes.data, m.ctypes.data, pivmin, lam.size, lam.ctypes.data,
           out.ctypes.data)
        return out
    s = k[0] - lam * m[0]
    c = np.zeros(lam.size, dtype=np.int64)
    for i in range(1, m.size + 1):
        kn = k[i] if i < m.size else 0.0
        d = s + kn
        d = np.where(np.abs(d) < pivmin, -pivmin, d)
        c += d < 0
        if i < m.size:
            s = kn * s / d - lam * m[i]
    return c


def sturm_counts(mass, stiffness, omega, backend="c") -> np.ndarray:
    """The number of natural frequencies of the chain below each ``omega`` (rad/s)."""
    m, k, pivmin = _coefficients(mass, stiffness)
    w = validate.vector("omega", np.atleast_1d(omega), nonnegative=True)
    return _counts(m, k, pivmin, w**2, backend)


def chain_frequencies(mass, stiffness, count=None, below=None, backend="c") -> np.ndarray:
    """Natural frequencies omega_n (rad/s, ascending) of a chain fixed to the ground at station
    0, by bisection on the Wittrick-Williams count (module docstring).

    Parameters
    ----------
    mass, stiffness : (N,) array_like
        m_n > 0 and k_n > 0 of station n (station n joins mass n to mass n - 1).
    count : int, optional
        The lowest ``count`` frequencies.
    below : float, optional
        Every frequency below this (rad/s). With neither, all N.
    backend : {"c", "numpy"}
        The count's loop (C falls back to NumPy, with one warning, without a compiler).

    Returns
    -------
    ndarray
        omega_n, rad/s, ascending.

    Examples
    --------
    >>> import dtdyn as dd
    >>> w = dd.chain_frequencies([10, 9, 8, 7, 6, 6, 5.5, 5, 4.5, 4, 3.5, 4, 2.5, 2, 2],
    ...                          [55000, 50000, 45000, 40000, 40000, 35000, 30000, 25000, 20000,
    ...                           15000, 10000, 9000, 8000, 7000, 6000])       # P3
    >>> round(float(w[0]), 2), round(float(w[-1]), 1)
    (9.49, 148.2)
    """
    if backend not in ("c", "numpy"):
        raise ValueError(f"backend must be 'c' or 'numpy', got {backend!r}")
    m, k, pivmin = _coefficients(mass, stiffness)
    n = m.size
    if count is not None and below is not None:
        raise ValueError("give count or below, not both")
    # Gershgorin: every row of M^-1 K sums to at most 2 (k_i + k_{i+1}) / m_i in magnitude
    lam_max = float(np.max(2.0 * (k + np.r_[k[1:], 0.0]) / m)) * (1 + 1e-12)
    if below is not None:
        below = validate.positive_scalar("below", below)
        count = int(_counts(m, k, pivmin, [below**2], backend)[0])
    elif count is None:
        count = n
    else:
        count = validate.step_count("count", count)
        if count > n:
            raise ValueError(f"count = {count} exceeds the {n} masses of the chain")
    if count == 0:
        return np.zeros(0)
    j = np.arange(count)
    lo, hi = np.zeros(count), np.full(count, lam_max)
    if below is not None:
        hi[:] = below**2
    while True:
        mid = 0.5 * (lo + hi)
        open_ = (mid > lo) & (mid < hi)  # brackets not yet two adjacent floats
        if not open_.any():
            break
        c = _counts(m, k, pivmin, mid[open_], backend)
        idx = np.flatnonzero(open_)
        above = c > j[idx]
        hi[idx[above]] = mid[open_][above]
        lo[idx[~above]] = mid[open_][~above]
    return np.sqrt(hi)


def chain_poles(mass, stiffness, damping, count=None, *, tol=1e-13, max_iter=100) -> np.ndarray:
    r"""Complex poles s_r (Im s_r > 0, ascending |s|) of a damped chain, by Newton's method on
    det D(s) (D = K + s C + s^2 M) through the same recursion in the Laplace domain: with
    :math:`\kappa_i = k_i + s c_i`,

    .. math::

        s_0 = \kappa_0 + s^2 m_0, \qquad
        s_i = \frac{\kappa_i s_{i-1}}{\kappa_i + s_{i-1}} + s^2 m_i, \qquad
        d_i = s_i + \kappa_{i+1}\ (\kappa_N = 0),

    the pivots of D(s), so :math:`\frac{d}{ds} \log \det D = \sum_i d_i' / d_i` in O(N)
    (the derivatives run along the recursion). All wanted poles are iterated together, each
    deflated by the others and by the conjugates (Aberth-Ehrlich: det D is a polynomial whose
    roots are the s_r and their conjugates), from the undamped poles j omega_r
    (`chain_frequencies`). For underdamped chains; a pole that does not converge or leaves the
    upper half-plane raises ValueError (use `modal_model` then).

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        m > 0, k > 0, c >= 0 of each station.
    count : int, optional
        The lowest ``count`` poles (all N by default).
    tol, max_iter : float, int
        The iteration stops when every step is below tol |s|.

    Returns
    -------
    (count,) complex ndarray

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> s = dd.chain_poles([1.0], [4.0], [0.4])           # m s^2 + c s + k = 0
    >>> np.round(s, 6)
    array([-0.2+1.989975j])
    """
    m, k, _ = _coefficients(mass, stiffness)
    c = validate.vector("damping", damping, nonnegative=True, length=m.size)
    s = 1j * chain_frequencies(m, k, count=count)
    for _ in range(max_iter):
        near = s[:, None] - s[None, :]
        np.fill_diagonal(near, np.inf)
        deflate = (1.0 / near).sum(axis=1) + (1.0 / (s[:, None] - s.conj()[None, :])).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = _log_det_derivative(m, k, c, s)
            # a pivot exactly 0: s is a pole to the last bit (no step)
            step = np.where(np.isfinite(ratio), 1.0 / (ratio - deflate), 0.0)
        s = s - step
        if np.all(np.abs(step) <= tol * np.abs(s)):
            break
    else:
        raise ValueError(f"the pole iteration did not converge in {max_iter} steps (largest "
                         f"relative step {np.max(np.abs(step) / np.abs(s)):.2g}): the chain may be "
                         "heavily damped; use modal_model")
    if np.any(s.imag <= 0):
        raise ValueError("a pole left the upper half-plane (an overdamped mode): use modal_model")
    return s[np.argsort(np.abs(s))]


def _log_det_derivative(m, k, c, s):
    """d/ds log det D(s) = sum_i d_i'(s) / d_i(s) over the pivots of D, for every s at once."""
    s2, ds2 = s * s, 2.0 * s
    p, dp = k[0] + s * c[0] + s2 * m[0], c[0] + ds2 * m[0]
    total = 0.0
    for i in range(1, m.size):
        kap = k[i] + s * c[i]
        d, dd = p + kap, dp + c[i]  # pivot of mass i - 1: s_{i-1} + kappa_i
        total = total + dd / d
        p, dp = kap * p / d + s2 * m[i], (c[i] * p * p + kap * kap * dp) / (d * d) + ds2 * m[i]
    return total + dp / p
