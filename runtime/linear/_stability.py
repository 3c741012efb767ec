"""Stability and accuracy of every scheme on x'' + 2 zeta omega x' + omega^2 x = 0.

Evaluates the amplification matrices derived from each scheme's own relations
(dtdyn.generated.stability): spectral radius rho = max |eig A(Omega, zeta)|, and from the
principal eigenvalue pair lambda = exp(Omega_bar (-xi_bar +- i)) the period elongation
Omega / Omega_bar - 1 and the algorithmic damping xi_bar (Hilber & Hughes 1978). The principal
pair is the eigenvalue with Im > 0 closest to the exact exp((-zeta + i sqrt(1 - zeta^2)) Omega).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dtdyn._engine.schemes import get_scheme
from dtdyn._engine.errors import DtdynStabilityWarning, DtdynUnstableError
from dtdyn._engine.public import public, warn
from dtdyn._engine import validate


@dataclass
class Stability:
    """The stability quantities of one scheme over ``omega_dt`` (from `stability`).

    Attributes
    ----------
    scheme : str
    params : dict
        The scheme's parameters.
    omega_dt : ndarray
        Omega = omega dt.
    damping_ratio : float
        Physical damping ratio zeta.
    spectral_radius, period_elongation, algorithmic_damping : ndarray
        rho = max |eig A|, T_num / T - 1, and the numerical damping ratio, per Omega.

    Examples
    --------
    >>> import dtdyn as dd
    >>> s = dd.stability("hht", [1.0], alpha=-0.1)
    >>> bool(s.spectral_radius[0] < 1.0), s.scheme
    (True, 'hht')
    """

    scheme: str
    params: dict
    omega_dt: np.ndarray
    damping_ratio: float
    spectral_radius: np.ndarray
    period_elongation: np.ndarray  # NaN where the principal pair is real (no oscillation)
    algorithmic_damping: np.ndarray

    @property
    def zeta(self) -> float:
        """Deprecated name of `damping_ratio`."""
        warn("Stability.zeta is now Stability.damping_ratio", DeprecationWarning)
        return self.damping_ratio


@public(renamed={"zeta": "damping_ratio"})
def stability(scheme, omega_dt, damping_ratio=0.0, **scheme_params) -> Stability:
    """Spectral radius, period elongation and algorithmic damping over ``omega_dt``.

    Each step of the scheme applied to x'' + 2 zeta omega x' + omega^2 x = 0 is
    y_{n+1} = A(Omega, zeta) y_n with Omega = omega dt (the amplification matrix the derivation
    gives); rho = max |eig A|. From the principal eigenvalue pair lambda = e^{(-xi + i) w dt}:
    period elongation T_num / T - 1 = Omega / (w dt) - 1 and algorithmic damping xi.

    Parameters
    ----------
    scheme : str
        A scheme of the scheme table; its parameters as keywords.
    omega_dt : array_like
        Omega = omega dt values.
    damping_ratio : float
        Physical damping ratio zeta, in [0, 1).
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    Stability

    Examples
    --------
    >>> import dtdyn as dd
    >>> s = dd.stability("average_acceleration", [0.1, 10.0])
    >>> [round(float(r), 12) for r in s.spectral_radius]
    [1.0, 1.0]
    """
    info = get_scheme(scheme, **scheme_params)
    W = validate.vector("omega_dt", np.atleast_1d(omega_dt), positive=True)
    zeta = _damping_ratio(damping_ratio)
    rho, elong, xi_bar = info.spectral(W, zeta)
    return Stability(info.name, dict(info.params), W, zeta, rho, elong, xi_bar)


@public(renamed={"zeta": "damping_ratio"})
def critical_omega_dt(scheme, damping_ratio=0.0, upper=1e4, **scheme_params) -> float:
    """The largest Omega below which rho <= 1 (inf when stable up to ``upper``).

    Parameters
    ----------
    scheme : str
        A scheme of the scheme table; its parameters as keywords.
    damping_ratio : float
        Physical damping ratio zeta, in [0, 1).
    upper : float
        Largest Omega searched.
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    float

    Examples
    --------
    >>> import dtdyn as dd
    >>> round(float(dd.critical_omega_dt("central_difference")), 6), dd.critical_omega_dt("hht")
    (2.0, inf)
    """
    zeta = _damping_ratio(damping_ratio)
    return get_scheme(scheme, **scheme_params).critical_omega_dt(zeta, upper)


def _damping_ratio(value) -> float:
    zeta = float(value)
    if not 0.0 <= zeta < 1.0:
        raise ValueError(f"damping_ratio must be in [0, 1), got {value!r}")
    return zeta


def warn_if_unstable(scheme, omegas, dt, zeta=0.0, **scheme_params) -> bool:
    """Warn (DtdynStabilityWarning) naming the worst unstable mode (1-based, ascending frequency)
    and its Omega = omega dt; returns whether any mode is unstable."""
    omegas = np.sort(np.asarray(omegas, dtype=float))
    st = stability(scheme, omegas * dt, zeta, **scheme_params)
    bad = np.flatnonzero(st.spectral_radius > 1.0 + 1e-10)
    if bad.size:
        i = int(bad[np.argmax(st.spectral_radius[bad])])  # the worst mode
        warn(f"scheme {st.scheme!r} is unstable at dt = {dt:g} s: mode {i + 1} "
             f"(omega = {omegas[i]:.6g} rad/s) has Omega = omega dt = {omegas[i] * dt:.4g}, "
             f"spectral radius {st.spectral_radius[i]:.6g} > 1 ({bad.size} unstable "
             "mode(s))", DtdynStabilityWarning)
        return True
    return False


@lru_cache(maxsize=128)
def _critical(scheme, params: tuple) -> float:
    return critical_omega_dt(scheme, **dict(params))


def check_dt(info, dt: float, omega_max, unstable: str = "raise") -> None:
    """Refuse (DtdynUnstableError) or, with ``unstable="warn"``, warn about a run whose
    Omega = omega_max dt exceeds the scheme's critical Omega (undamped; derived spectral radius).

    ``info`` is the resolved scheme (`dtdyn._engine.schemes.get_scheme`); ``omega_max`` the
    model's highest natural frequency in rad/s, None when it is unknown, or a callable
    ``omega_max(limit)`` (called only for conditionally stable schemes) that may return any
    upper bound of it that is <= ``limit`` (the check then passes) instead of the exact value.
    """
    if unstable not in ("raise", "warn"):
        raise ValueError(f"unstable must be 'raise' or 'warn', got {unstable!r}")
    crit = _critical(info.ref, tuple(sorted(info.params.items())))
    if not np.isfinite(crit):
        return
    omega = omega_max(crit / dt) if callable(omega_max) else omega_max
    if omega is None or not omega * dt > crit:
        return
    msg = (f"scheme {info.name!r} is unstable at dt = {dt:g} s: the highest mode "
           f"(omega = {omega:.6g} rad/s) has Omega = omega dt = {omega * dt:.4g} > {crit:.4g}, "
           f"its stability limit; use dt < {crit / omega:.4g} s or an unconditionally stable "
           "scheme")
    if unstable == "raise":
        raise DtdynUnstableError(msg + " (unstable='warn' runs it anyway, for study; in a scene: "
                                 "[scheme] unstable = \"warn\"; on the command line: "
                                 "--unstable warn)")
    warn(msg + " (run anyway: unstable='warn')", DtdynStabilityWarning)


def highest_frequency(M, K, limit=None):
    """The largest undamped natural frequency (rad/s) of M q'' + K q = 0, or None when M is
    singular or the eigenproblem cannot be solved (dense: LAPACK; sparse: ARPACK). A dense K
    that is not symmetric (circulatory terms) gives sqrt of the largest |eigenvalue| of the
    general pencil (K, M) (eigh would read one triangle only). ``limit`` is accepted for
    `check_dt` (no cheaper bound is used for general matrices)."""
    import scipy.linalg as sla
    import scipy.sparse as sps
    import scipy.sparse.linalg as spla

    try:
        if sps.issparse(M) or sps.issparse(K):
            lam = spla.eigsh(sps.csc_matrix(K), k=1, M=sps.csc_matrix(M), which="LA",
                             return_eigenvectors=False)[0]
        elif np.abs(K - K.T).max() > 1e-10 * np.abs(K).max():
            lam = float(np.abs(sla.eigvals(K, M)).max())
        else:
            n = np.shape(M)[0]
            lam = sla.eigh(K, M, eigvals_only=True, subset_by_index=[n - 1, n - 1])[0]
    except (np.linalg.LinAlgError, ValueError, RuntimeError, spla.ArpackError):
        return None
    return float(np.sqrt(max(lam, 0.0)))


def chain_highest_frequency(mass, stiffness, limit=None, ground_stiffness=None) -> float:
    """The largest undamped natural frequency (rad/s) of a chain: the top eigenvalue of the
    tridiagonal M^-1/2 K M^-1/2, O(N) (K with the springs to the ground, when given). With
    ``limit``, the Gershgorin bound max_i (d_i + |e_i-1| + |e_i|) is returned instead when its
    square root is <= ``limit`` (a well-resolved run then costs a few vector operations, not an
    eigenvalue)."""
    import scipy.linalg as sla

    m, k = np.asarray(mass, float), np.asarray(stiffness, float)
    kg = 0.0 if ground_stiffness is None else np.asarray(ground_stiffness, float)
    s = 1.0 / np.sqrt(m)
    d, e = (k + np.append(k[1:], 0.0) + kg) * s * s, -k[1:] * s[:-1] * s[1:]
    if limit is not None:
        off = np.abs(e)
        bound = float(np.sqrt(np.max(d + np.append(off, 0.0) + np.append(0.0, off))))
        if bound <= limit:
            return bound
    lam = sla.eigh_tridiagonal(d, e, eigvals_only=True, select="i",
                               select_range=(m.size - 1, m.size - 1))[0]
    return float(np.sqrt(max(lam, 0.0)))
