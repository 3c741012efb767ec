r"""Natural frequencies of long chains by the Wittrick-Williams count, O(N) per evaluation.

For a chain (station n joins mass n to mass n - 1, station 0 to the ground) the number of
natural frequencies with :math:`\omega^2 < \lambda` equals the number of negative pivots of
:math:`K - \lambda M` (Sylvester's law of inertia; Wittrick & Williams, *Q. J. Mech. Appl.
Math.* 24, 1971, with no interior element DOFs). The pivots are the dynamic stiffnesses of the
chain condensed from the ground up, the frequency-domain Riccati recursion of the stable sweep:
mass i sees through station i the stiffness

.. math::

    s_0 = k_0 + k_{g,0} - \lambda m_0, \qquad
    s_i = \frac{k_i\, s_{i-1}}{k_i + s_{i-1}} + k_{g,i} - \lambda m_i, \qquad
    d_i = s_i + k_{i+1} \ (k_N = 0),

(station i in series with what is below it, plus the spring :math:`k_{g,i} \ge 0` from mass i
to the ground, less the inertia of mass i). A station with :math:`k_i = 0` (allowed with
ground springs, if every part of the chain keeps one) gives :math:`s_i = k_{g,i} - \lambda
m_i`: the chain splits there, :math:`d_{i-1} = s_{i-1}` is the last pivot of the part below,
and the count of the whole is the sum of the parts' counts. This equals the
textbook pivot :math:`d_i = k_i + k_{i+1} - \lambda m_i - k_i^2 / d_{i-1}`, but adds positive
terms where that one cancels, so the lowest frequencies of a long chain keep a few ulps of
relative accuracy (the textbook count, like LAPACK's dstebz, is accurate only to a few ulps of
the largest eigenvalue: 1e-8 relative on the lowest of a 100,000-mass chain).

Each root :math:`\lambda_j` is isolated by bisection on the count, all wanted roots at once,
until its bracket :math:`(l_j, h_j]` holds it alone (count :math:`j` at :math:`l_j`,
:math:`j + 1` at :math:`h_j`). The brackets start from :math:`[\lambda_{\rm low}/2,
\lambda_{\max}]`: Gershgorin above (:math:`\max_i (2 (k_i + k_{i+1}) + k_{g,i})/m_i` for
:math:`M^{-1} K`), and below :math:`\lambda_1 \ge 1/\operatorname{tr}(K^{-1} M) =
1 / \sum_i m_i \sum_{n \le i} 1/k_n = \lambda_{\rm low}` (the flexibility of the fixed-free
chain; ground springs only stiffen it; 0 for a chain in parts), halving at the geometric mean
while :math:`h > 4 l` (the lowest roots of a long chain lie many decades below
:math:`\lambda_{\max}`) and at the arithmetic mean after. Brackets that coincide share their
evaluation.

Each isolated root is then polished by Laguerre's iteration on :math:`p(\lambda) = \det(K -
\lambda M) = \prod_i d_i`, a polynomial of degree N whose roots are all real. Its logarithmic
derivatives follow the recursion in O(N): with :math:`g_i = k_i / d_{i-1}`,

.. math::

    s_0' = -m_0, \quad s_i' = g_i^2 s_{i-1}' - m_i, \qquad
    s_0'' = 0, \quad s_i'' = g_i^2 \Big(s_{i-1}'' - \frac{2 s_{i-1}'^2}{d_{i-1}}\Big),

    G = \frac{p'}{p} = \sum_i \frac{d_i'}{d_i} = \sum_r \frac{1}{\lambda - \lambda_r}, \qquad
    H = -G' = \sum_i \Big(\frac{d_i'^2}{d_i^2} - \frac{d_i''}{d_i}\Big)
      = \sum_r \frac{1}{(\lambda - \lambda_r)^2}

(:math:`d_i' = s_i'`, :math:`d_i'' = s_i''`). The Laguerre step

.. math::

    \lambda \leftarrow \lambda - \frac{N}{G \pm \sqrt{(N - 1)(N H - G^2)}}

with + when the count at :math:`\lambda` is :math:`j + 1` (the root is the nearest one below)
and - when it is :math:`j` (the nearest above) moves monotonically towards that root without
passing it, since all the roots are real, and converges cubically: about five evaluations per
root where Newton's step :math:`1/G`, pulled by the hundreds of roots on one side, crawls (Li
& Zeng, *SIAM J. Sci. Comput.* 15, 1994, for the tridiagonal eigenproblem). Every
evaluation also gives the count, which shrinks the bracket; a step that leaves the bracket (or
a non-finite G, H: a vanished pivot) is replaced by bisection, and the iteration stops when the
step is below an ulp or stops shrinking (the rounding floor of the recursion), after which the
result is kept inside its bracket. So no root is missed or found twice (the count decides the
brackets; a multiple root, of a chain in equal parts, never isolates and is bisected to
adjacent floats, once per multiplicity), the roots agree with bisection to adjacent
floating-point numbers (``polish=False``) to within the rounding floor of the recursion (a few
ulps for hundreds of masses, ~1e-13 relative at 100,000), and nothing overflows (a pivot
smaller than pivmin is replaced by -pivmin; k and m are scaled by powers of two to order one,
exactly). Every root starts from the same bracket, so its bits depend on the chain and its
index alone, not on ``count`` or ``below``. The
evaluations run in the generated C kernel (generated/sturm.c, four trial values interleaved per
pass over the chain), with a NumPy fallback.
"""
from __future__ import annotations

from functools import cache
from importlib import resources

import numpy as np

from dtdyn._engine import cbuild, validate

__all__ = ["chain_frequencies", "chain_poles", "sturm_counts"]


def _coefficients(mass, stiffness, ground_stiffness=None):
    """m > 0; k >= 0 and kg >= 0 (zeros without ground springs) such that every part of the
    chain is held to the ground, K + diag(kg) positive definite; pivmin (module docstring)."""
    m = validate.vector("mass", mass, positive=True)
    if ground_stiffness is None:
        k = validate.vector("stiffness", stiffness, positive=True, length=m.size)
        kg = np.zeros(m.size)
    else:
        k = validate.vector("stiffness", stiffness, nonnegative=True, length=m.size)
        kg = validate.vector("ground_stiffness", ground_stiffness, nonnegative=True,
                             length=m.size)
        # a station k_i = 0 starts a part of the chain that only its ground springs hold
        starts = np.flatnonzero(k == 0.0)
        if starts.size:
            held = np.add.reduceat((kg > 0).astype(np.int64), starts) > 0
            if not held.all():
                i = int(starts[np.flatnonzero(~held)[0]])
                ends = np.r_[starts[1:], m.size]
                last = int(ends[np.flatnonzero(~held)[0]]) - 1
                raise ValueError(
                    f"stiffness[{i}] = 0.0 leaves masses {i}..{last} with no spring to the "
                    f"ground (ground_stiffness is 0 there): K is singular")
    pivmin = np.finfo(float).tiny * max(1.0, float(k.max()) ** 2)
    return m, k, kg, pivmin


@cache
def _c_kernels():
    source = resources.files("dtdyn.generated").joinpath("sturm.c").read_text()
    lib = cbuild.load_library(source, "sturm")
    if lib is None:
        return None
    return cbuild.bind(lib, "dtdyn_sturm_counts"), cbuild.bind(lib, "dtdyn_sturm_laguerre")


def _counts(m, k, kg, pivmin, lam, backend="c"):
    """Eigenvalues below each lam: negative pivots d_i = s_i + k_{i+1} (module docstring)."""
    lam = np.ascontiguousarray(lam, dtype=float)
    fns = _c_kernels() if backend == "c" else None
    if fns is not None:
        out = np.empty(lam.size, dtype=np.int64)
        fns[0](m.size, k.ctypes.data, kg.ctypes.data, m.ctypes.data, pivmin, lam.size,
               lam.ctypes.data, out.ctypes.data)
        return out
    s = k[0] + kg[0] - lam * m[0]
    c = np.zeros(lam.size, dtype=np.int64)
    for i in range(1, m.size + 1):
        kn = k[i] if i < m.size else 0.0
        d = s + kn
        d = np.where(np.abs(d) < pivmin, -pivmin, d)
        c += d < 0
        if i < m.size:
            s = kn * s / d + kg[i] - lam * m[i]
    return c


def _laguerre_terms(m, k, kg, pivmin, lam, backend="c"):
    """The count and G = p'/p, H = -G' of p = det(K - lam M) at each lam (module docstring);
    G = NaN where a pivot before the last vanished, G = inf and H = 0 where the last did. The
    same operations in the same order as the C kernel, so both give the same bits."""
    lam = np.ascontiguousarray(lam, dtype=float)
    fns = _c_kernels() if backend == "c" else None
    if fns is not None:
        c, G, H = np.empty(lam.size, dtype=np.int64), np.empty(lam.size), np.empty(lam.size)
        fns[1](m.size, k.ctypes.data, kg.ctypes.data, m.ctypes.data, pivmin, lam.size,
               lam.ctypes.data, c.ctypes.data, G.ctypes.data, H.ctypes.data)
        return c, G, H
    n = m.size
    s, s1, s2 = k[0] + kg[0] - lam * m[0], np.full(lam.size, -m[0]), np.zeros(lam.size)
    g1, h1 = np.zeros(lam.size), np.zeros(lam.size)
    c, hit = np.zeros(lam.size, dtype=np.int64), np.zeros(lam.size, dtype=bool)
    with np.errstate(all="ignore"):  # after a vanished pivot the derivatives are discarded
        for i in range(1, n):
            kn, mn = k[i], m[i]
            d = s + kn
            tiny = np.abs(d) < pivmin
            d = np.where(tiny, -pivmin, d)
            hit |= tiny
            c += d < 0
            rd = 1.0 / d
            u, v, g = s1 * rd, s2 * rd, kn * rd
            g1 = g1 + u
            h1 = h1 + (u * u - v)
            s = kn * s / d + kg[i] - lam * mn
            s2 = g * g * (s2 - 2.0 * s1 * u)
            s1 = g * (kn * u) - mn
        tiny = np.abs(s) < pivmin
        d = np.where(tiny, -pivmin, s)
        c += d < 0
        u, v = s1 / d, s2 / d
        G = np.where(hit, np.nan, np.where(tiny, np.inf, g1 + u))
        H = np.where(hit | ~tiny, h1 + (u * u - v), 0.0)
    return c, G, H


def _bounds(m, k, kg):
    """[lambda_low / 2, lambda_max] holds every eigenvalue (module docstring)."""
    lam_max = float(np.max((2.0 * (k + np.r_[k[1:], 0.0]) + kg) / m)) * (1 + 1e-12)
    if np.any(k == 0.0):  # a chain in parts: no flexibility bound, bisection from 0
        return 0.0, lam_max
    trace = float(np.dot(m, np.cumsum(1.0 / k)))  # tr(K^-1 M) of the fixed-free chain
    lam_low = 0.5 / trace if np.isfinite(trace) and trace > 0 else 0.0
    return lam_low, lam_max


def _isolate(m, k, kg, pivmin, lo, hi, clo, chi, backend, alone=True):
    """Bisect (in place) each bracket (lo_j, hi_j] until it holds root j alone (count j at lo_j,
    j + 1 at hi_j; with ``alone`` False, on) or is two adjacent floats (returned: ``stuck``)."""
    j = np.arange(lo.size)
    while True:
        geometric = (lo > 0) & (hi > 4.0 * lo)
        mid = np.where(geometric, np.sqrt(lo) * np.sqrt(hi), 0.5 * lo + 0.5 * hi)
        splittable = (mid > lo) & (mid < hi)
        idx = np.flatnonzero(~((clo == j) & (chi == j + 1) & alone) & splittable)
        if idx.size == 0:
            return ~splittable
        points, where = np.unique(mid[idx], return_inverse=True)  # coinciding brackets
        c = _counts(m, k, kg, pivmin, points, backend)[where]
        above = c > j[idx]
        hi[idx[above]], chi[idx[above]] = mid[idx[above]], c[above]
        lo[idx[~above]], clo[idx[~above]] = mid[idx[~above]], c[~above]


#: Laguerre steps per root before it finishes by bisection alone (it takes about five)
_MAX_LAGUERRE = 60


def _polish(m, k, kg, pivmin, lo, hi, backend):
    """Laguerre's iteration on det(K - lambda M) for root j inside its isolating bracket
    (lo_j, hi_j], safeguarded by bisection (module docstring)."""
    n, eps = m.size, np.finfo(float).eps
    j = np.arange(lo.size)
    x = 0.5 * lo + 0.5 * hi
    out = hi.copy()
    done = ~((x > lo) & (x < hi))
    prev = np.full(lo.size, np.inf)  # the last accepted |step|
    steps = np.zeros(lo.size, dtype=np.int64)
    while not done.all():
        idx = np.flatnonzero(~done)
        xi = x[idx]
        c, G, H = _laguerre_terms(m, k, kg, pivmin, xi, backend)
        steps[idx] += 1
        right = c > j[idx]  # root j is below xi: step down
        hi[idx[right]], lo[idx[~right]] = xi[right], xi[~right]
        with np.errstate(all="ignore"):
            g, h = G * xi, H * xi * xi  # dimensionless
            root = np.sqrt((n - 1) * np.maximum(n * h - g * g, 0.0))
            a = np.where(G == np.inf, 0.0, xi * n / np.where(right, g + root, g - root))
        xn = xi - a
        # a non-finite G or H (an overflow, a vanished interior pivot) gives no step
        terms = (np.isfinite(G) & np.isfinite(H)) | ((G == np.inf) & (H == 0))
        valid = terms & np.isfinite(a) & np.where(right, a >= 0, a <= 0)
        inside = valid & (xn > lo[idx]) & (xn < hi[idx])
        kept = np.clip(xn, lo[idx], hi[idx])
        size = np.abs(a)
        # converged: a step below two ulps, a step that lands on the bracket's end, or steps
        # that stop shrinking once small (the rounding floor of the recursion)
        conv = valid & ((size <= 2 * eps * xi) | (~inside & (np.abs(kept - xn) <= 2 * eps * xi)))
        conv |= (prev[idx] <= 1e-8 * xi) & ~(inside & (size < 0.5 * prev[idx]))
        out[idx[conv]] = np.where(valid, kept, xi)[conv]
        prev[idx] = np.where(inside, size, np.inf)
        mid = 0.5 * lo[idx] + 0.5 * hi[idx]
        stuck = ~((mid > lo[idx]) & (mid < hi[idx])) & ~conv  # adjacent floats: bisection's end
        out[idx[stuck]] = hi[idx[stuck]]
        done[idx[conv | stuck]] = True
        x[idx] = np.where(inside & (steps[idx] < _MAX_LAGUERRE), xn, mid)
    return out


def sturm_counts(mass, stiffness, omega, backend="c", *, ground_stiffness=None) -> np.ndarray:
    """The number of natural frequencies of the chain (springs ``ground_stiffness`` from each
    mass to the ground, if given) below each ``omega`` (rad/s)."""
    m, k, kg, pivmin = _coefficients(mass, stiffness, ground_stiffness)
    w = validate.vector("omega", np.atleast_1d(omega), nonnegative=True)
    return _counts(m, k, kg, pivmin, w**2, backend)


def chain_frequencies(mass, stiffness, count=None, below=None, backend="c", *,
                      polish=True, ground_stiffness=None) -> np.ndarray:
    """Natural frequencies omega_n (rad/s, ascending) of a chain fixed to the ground at station
    0: each isolated by bisection on the Wittrick-Williams count, then polished by Laguerre's
    iteration on det(K - omega^2 M) (module docstring).

    Parameters
    ----------
    mass, stiffness : (N,) array_like
        m_n > 0 and k_n > 0 of station n (station n joins mass n to mass n - 1).
    count : int, optional
        The lowest ``count`` frequencies.
    below : float, optional
        Every frequency below this (rad/s). With neither, all N.
    backend : {"c", "numpy"}
        The recursion's loop (C falls back to NumPy, with one warning, without a compiler).
    polish : bool
        False: bisection on the count alone, to adjacent floating-point numbers (about 85
        counts per root instead of about seven evaluations; the same roots to a few ulps).
    ground_stiffness : (N,) array_like, optional
        kg_n >= 0, a spring from mass n to the ground (K[n, n] += kg_n). With it a station may
        have k_n = 0 (the chain in parts), as long as every part is held to the ground.

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
    m, k, kg, _ = _coefficients(mass, stiffness, ground_stiffness)
    # scaled by powers of two to max k = max m ~ 1 (exact: the same counts, to the bit), so
    # lambda ~ k/m and the derivatives stay within range whatever the units
    ek, em = int(np.frexp(max(k.max(), kg.max()))[1]), int(np.frexp(m.max())[1])
    k, kg, m = np.ldexp(k, -ek), np.ldexp(kg, -ek), np.ldexp(m, -em)
    pivmin = np.finfo(float).tiny * max(1.0, float(k.max()) ** 2)
    n = m.size
    if count is not None and below is not None:
        raise ValueError("give count or below, not both")
    if below is not None:
        below = validate.positive_scalar("below", below)
        with np.errstate(over="ignore"):     # below^2 beyond the floats: every frequency
            lam = np.ldexp(np.float64(below) ** 2, em - ek)
        count = m.size if not np.isfinite(lam) else int(
            _counts(m, k, kg, pivmin, [lam], backend)[0])
    elif count is None:
        count = n
    else:
        count = validate.step_count("count", count)
        if count > n:
            raise ValueError(f"count = {count} exceeds the {n} masses of the chain")
    if count == 0:
        return np.zeros(0)
    # every root from the same bracket, whatever count or below: root j's path (and so its
    # bits) depends on the chain and j alone
    lam_low, lam_max = _bounds(m, k, kg)
    lo, hi = np.full(count, lam_low), np.full(count, lam_max)
    clo, chi = np.zeros(count, dtype=np.int64), np.full(count, n, dtype=np.int64)
    stuck = _isolate(m, k, kg, pivmin, lo, hi, clo, chi, backend, alone=polish)
    if polish:
        lam = _polish(m, k, kg, pivmin, lo, hi, backend)
        lam[stuck] = hi[stuck]
    else:
        lam = hi
    return np.sqrt(np.ldexp(lam, ek - em))


def chain_poles(mass, stiffness, damping, count=None, *, tol=1e-13, max_iter=100,
                ground_stiffness=None, ground_damping=None) -> np.ndarray:
    r"""Complex poles s_r (Im s_r > 0, ascending |s|) of a damped chain, by Newton's method on
    det D(s) (D = K + s C + s^2 M) through the same recursion in the Laplace domain: with
    :math:`\kappa_i = k_i + s c_i` and :math:`\gamma_i = k_{g,i} + s c_{g,i}` (the spring and
    damper from mass i to the ground),

    .. math::

        s_0 = \kappa_0 + \gamma_0 + s^2 m_0, \qquad
        s_i = \frac{\kappa_i s_{i-1}}{\kappa_i + s_{i-1}} + \gamma_i + s^2 m_i, \qquad
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
    ground_stiffness, ground_damping : (N,) array_like, optional
        kg_n >= 0 and cg_n >= 0 from mass n to the ground (K[n, n] += kg_n, C[n, n] += cg_n);
        with ground springs a station may have k_n = 0 (`chain_frequencies`).

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
    m, k, kg, _ = _coefficients(mass, stiffness, ground_stiffness)
    c = validate.vector("damping", damping, nonnegative=True, length=m.size)
    cg = (np.zeros(m.size) if ground_damping is None else
          validate.vector("ground_damping", ground_damping, nonnegative=True, length=m.size))
    s = 1j * chain_frequencies(m, k, count=count, ground_stiffness=kg)
    if s.size > 1 and np.any(np.diff(s.imag) <= 1e-12 * s.imag[1:]):
        r = int(np.flatnonzero(np.diff(s.imag) <= 1e-12 * s.imag[1:])[0])
        raise ValueError(f"the undamped frequencies {r} and {r + 1} coincide "
                         f"({s.imag[r]!r} rad/s: a chain in equal parts), where the pole "
                         "iteration cannot start; use modal_model")
    for _ in range(max_iter):
        near = s[:, None] - s[None, :]
        np.fill_diagonal(near, np.inf)
        deflate = (1.0 / near).sum(axis=1) + (1.0 / (s[:, None] - s.conj()[None, :])).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = _log_det_derivative(m, k, c, kg, cg, s)
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


def _log_det_derivative(m, k, c, kg, cg, s):
    """d/ds log det D(s) = sum_i d_i'(s) / d_i(s) over the pivots of D, for every s at once."""
    s2, ds2 = s * s, 2.0 * s
    p, dp = k[0] + s * c[0] + (kg[0] + s * cg[0]) + s2 * m[0], c[0] + cg[0] + ds2 * m[0]
    total = 0.0
    for i in range(1, m.size):
        kap = k[i] + s * c[i]
        d, dd = p + kap, dp + c[i]  # pivot of mass i - 1: s_{i-1} + kappa_i
        total = total + dd / d
        p, dp = (kap * p / d + (kg[i] + s * cg[i]) + s2 * m[i],
                 (c[i] * p * p + kap * kap * dp) / (d * d) + cg[i] + ds2 * m[i])
    return total + dp / p
