"""Fatigue damage: S-N curves, Palmgren-Miner sums over counted cycles, spectral damage from a PSD.

Stresses in an S-N curve are amplitudes S (half the range) throughout. `miner_damage` sums
n_i / N(S_i) over cycles (e.g. `rainflow_cycles`), with an optional Goodman mean-stress
correction; `spectral_damage` gives the expected damage of a stationary Gaussian zero-mean
stress from its one-sided PSD by the narrow-band (Rayleigh), Wirsching-Light, Dirlik or
Tovo-Benasciutti formula.

Every spectral method here writes the damage as a sum of cycle rates times the expectation of
1 / N(S) over an amplitude density that is a mixture of Rayleigh and exponential densities; on a
piecewise power-law S-N curve each term is a difference of regularized incomplete gamma
functions, so two slopes and an endurance limit are integrated exactly (no quadrature).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from dtdyn._engine.public import public
from dtdyn._engine.validate import real_array

__all__ = ["SNCurve", "miner_damage", "spectral_damage", "spectral_damage_from_moments",
           "spectral_moments"]

METHODS = ("narrow_band", "wirsching_light", "dirlik", "tovo_benasciutti")


def _positive(name, value):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number; got {name}={value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number; got {name}={value!r}")
    return v


@public
@dataclass(frozen=True)
class SNCurve:
    """An S-N (Woehler) curve in stress amplitudes: cycles to failure N at amplitude S.

    Parameters
    ----------
    slope : float
        Basquin's exponent b (> 0) of N = C S^-b at amplitudes S >= ``knee`` (all S without a
        knee).
    coefficient : float
        Basquin's coefficient C (> 0), in (stress unit)^b.
    knee : float, optional
        Amplitude where the slope changes to ``slope_below_knee`` (two-slope curve, e.g.
        Eurocode 3's at 5e6 cycles). Below it N = C_2 S^-b_2 with C_2 = C knee^(b_2 - b), so
        that N is continuous at the knee.
    slope_below_knee : float, optional
        b_2 (> 0), required with ``knee``.
    endurance_limit : float
        Amplitudes below it do no damage (N infinite: the cut-off); default 0.

    Notes
    -----
    Basquin (1910): N = C S^-b. A curve given in ranges, N = C_r (2 S)^-b, is this one with
    C = C_r 2^-b (and every stress halved: knee, endurance limit).

    Examples
    --------
    >>> import dtdyn as dd
    >>> sn = dd.SNCurve(slope=3.0, coefficient=1e12, knee=50.0, slope_below_knee=5.0)
    >>> sn.cycles_to_failure([100.0, 50.0, 25.0]).tolist()
    [1000000.0, 8000000.0, 256000000.0]
    """

    slope: float
    coefficient: float
    knee: float | None = None
    slope_below_knee: float | None = None
    endurance_limit: float = 0.0

    def __post_init__(self):
        _positive("slope", self.slope)
        _positive("coefficient", self.coefficient)
        if (self.knee is None) != (self.slope_below_knee is None):
            raise ValueError("knee and slope_below_knee go together (a two-slope curve); got "
                             f"knee={self.knee!r}, slope_below_knee={self.slope_below_knee!r}")
        if self.knee is not None:
            _positive("knee", self.knee)
            _positive("slope_below_knee", self.slope_below_knee)
        el = float(self.endurance_limit)
        if not (np.isfinite(el) and el >= 0):
            raise ValueError("endurance_limit must be a finite amplitude >= 0; got "
                             f"endurance_limit={self.endurance_limit!r}")

    def pieces(self) -> list[tuple[float, float, float, float]]:
        """The curve as power laws N = c S^-k on amplitude intervals: ``(low, high, c, k)``
        from the endurance limit up (``high`` of the last is inf)."""
        b, C, el = float(self.slope), float(self.coefficient), float(self.endurance_limit)
        if self.knee is None:
            return [(el, np.inf, C, b)]
        knee, b2 = float(self.knee), float(self.slope_below_knee)
        C2 = C * knee ** (b2 - b)
        out = [(el, knee, C2, b2)] if el < knee else []
        return out + [(max(el, knee), np.inf, C, b)]

    def cycles_to_failure(self, amplitudes) -> np.ndarray:
        """N at each amplitude (inf below the endurance limit)."""
        s = np.abs(real_array("amplitudes", amplitudes))
        n = np.full(s.shape, np.inf)
        for lo, hi, c, k in self.pieces():
            m = (s >= lo) & (s < hi)
            with np.errstate(divide="ignore"):
                n[m] = c * s[m] ** -k
        return n


def _check_curve(sn_curve):
    if not isinstance(sn_curve, SNCurve):
        raise TypeError(f"sn_curve must be a dtdyn.SNCurve; got {type(sn_curve).__name__}")
    return sn_curve


def _goodman(amplitudes, means, ultimate_strength):
    su = _positive("ultimate_strength", ultimate_strength)
    bad = means >= su
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"a mean stress at or above ultimate_strength = {su:g} (means[{i}] = "
                         f"{means[i]:g}) has no Goodman equivalent amplitude: the part fails "
                         "statically")
    return amplitudes / (1.0 - means / su)


@public
def miner_damage(ranges, counts, sn_curve, *, means=None, mean_correction=None,
                 ultimate_strength=None) -> float:
    """Palmgren-Miner damage of counted cycles: D = sum_i n_i / N(S_i).

    Parameters
    ----------
    ranges : array_like
        Stress range of each cycle (or bin); the amplitude is S = range / 2.
    counts : array_like
        Cycles n_i of each range (0.5 for a half cycle), the same length.
    sn_curve : SNCurve
        N(S), S the amplitude.
    means : array_like, optional
        Mean stress of each cycle; needed by ``mean_correction``.
    mean_correction : {None, "goodman"}
        ``"goodman"``: each amplitude is replaced by the fully reversed amplitude of equal life,
        S_eq = S_a / (1 - S_m / S_u) (Goodman 1899), before N is read; compressive means
        (S_m < 0) lower it. A mean at or above S_u is a ValueError.
    ultimate_strength : float, optional
        S_u (> 0), required with ``mean_correction="goodman"``.

    Returns
    -------
    float
        The damage D (failure is expected at D = 1).

    Notes
    -----
    Palmgren (1924), Miner (1945): each cycle of amplitude S uses up 1 / N(S) of the life; the
    order of the cycles is ignored.

    Examples
    --------
    >>> import dtdyn as dd
    >>> sn = dd.SNCurve(slope=3.0, coefficient=1e12)
    >>> dd.miner_damage([200.0, 100.0], [10.0, 0.5], sn)  # 10/1e6 + 0.5/8e6
    1.00625e-05
    """
    sn = _check_curve(sn_curve)
    r = real_array("ranges", ranges).ravel()
    n = real_array("counts", counts).ravel()
    if r.shape != n.shape:
        raise ValueError(f"ranges and counts must have the same length; got {r.size} ranges "
                         f"and {n.size} counts")
    for name, v in (("ranges", r), ("counts", n)):
        bad = ~np.isfinite(v) | (v < 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name}[{i}] = {float(v[i])!r}: {name} must be finite and >= 0")
    s = 0.5 * r
    if mean_correction is not None:
        if mean_correction != "goodman":
            raise ValueError(f"mean_correction must be None or 'goodman'; got "
                             f"mean_correction={mean_correction!r}")
        if means is None or ultimate_strength is None:
            raise ValueError("mean_correction='goodman' needs means and ultimate_strength")
        m = real_array("means", means).ravel()
        if m.shape != r.shape or not np.all(np.isfinite(m)):
            raise ValueError(f"means must be {r.size} finite values, one per range")
        s = _goodman(s, m, ultimate_strength)
    elif ultimate_strength is not None:
        raise ValueError("ultimate_strength is used only with mean_correction='goodman'")
    return float(np.sum(n / sn.cycles_to_failure(s)))


@public
def spectral_moments(psd, freqs_hz) -> dict:
    """Spectral moments m_k = int_0^inf f^k G(f) df, k = 0, 1, 2, 4, of a one-sided PSD.

    Parameters
    ----------
    psd : array_like, shape (n,)
        One-sided PSD G(f) of the stress, (stress unit)^2 / Hz, >= 0.
    freqs_hz : array_like, shape (n,)
        Frequencies f, Hz, increasing, >= 0.

    Returns
    -------
    dict
        ``m0``, ``m1``, ``m2``, ``m4`` (the trapezoidal rule on the given grid, which must
        resolve every peak of G).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> f = np.linspace(0.0, 10.0, 1001)         # G = 1 on [0, 10] Hz: m_k = 10^(k+1)/(k+1)
    >>> {k: round(v, 2) for k, v in dd.spectral_moments(np.ones_like(f), f).items()}
    {'m0': 10.0, 'm1': 50.0, 'm2': 333.33, 'm4': 20000.03}
    """
    g = real_array("psd", psd)
    f = real_array("freqs_hz", freqs_hz)
    if g.ndim != 1 or f.ndim != 1:
        raise ValueError(f"psd and freqs_hz must be 1-D (one stress); got shapes {g.shape} and "
                         f"{f.shape}")
    if f.size < 2 or g.shape != f.shape:
        raise ValueError(f"psd and freqs_hz must be two arrays of the same length >= 2; got "
                         f"{g.size} and {f.size} values")
    if not np.all(np.isfinite(f)) or f[0] < 0 or np.any(np.diff(f) <= 0):
        raise ValueError("freqs_hz must be finite, >= 0 and increasing")
    bad = ~np.isfinite(g) | (g < 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"psd[{i}] = {float(g[i])!r}: a PSD is finite and >= 0")
    from scipy import integrate  # deferred: `import dtdyn` stays light

    return {f"m{k}": float(integrate.trapezoid(f**k * g, f)) for k in (0, 1, 2, 4)}


def _rayleigh_moment(k, sigma, lo, hi):
    """int_lo^hi s^k (s / sigma^2) exp(-s^2 / (2 sigma^2)) ds."""
    a = 1.0 + 0.5 * k
    xl, xh = lo * lo / (2 * sigma * sigma), hi * hi / (2 * sigma * sigma)
    return (np.sqrt(2.0) * sigma) ** k * special.gamma(a) * _gamma_part(a, xl, xh)


def _exponential_moment(k, q, lo, hi):
    """int_lo^hi s^k exp(-s / q) / q ds."""
    a = 1.0 + k
    return q**k * special.gamma(a) * _gamma_part(a, lo / q, hi / q)


def _gamma_part(a, xl, xh):
    """P(a, xh) - P(a, xl) (regularized lower incomplete gamma), from the side that keeps its
    relative accuracy."""
    if xh <= a:
        return special.gammainc(a, xh) - special.gammainc(a, xl)
    return special.gammaincc(a, xl) - (0.0 if np.isinf(xh) else special.gammaincc(a, xh))


def _components(method, m0, m1, m2, m4, slope):
    """The method's damage as [(rate 1/s, "rayleigh" or "exponential", scale)], with the
    Wirsching-Light factor (1 for the others)."""
    sigma = np.sqrt(m0)
    nu0, nu_p = np.sqrt(m2 / m0), np.sqrt(m4 / m2)  # mean up-crossings, peaks per second
    a1, a2 = m1 / np.sqrt(m0 * m2), m2 / np.sqrt(m0 * m4)
    if method == "narrow_band":
        return [(nu0, "rayleigh", sigma)], 1.0
    if method == "wirsching_light":
        eps = np.sqrt(max(1.0 - a2 * a2, 0.0))
        a, c = 0.926 - 0.033 * slope, 1.587 * slope - 2.323
        return [(nu0, "rayleigh", sigma)], a + (1.0 - a) * (1.0 - eps) ** c
    if method == "tovo_benasciutti":
        b = ((a1 - a2) * (1.112 * (1 + a1 * a2 - (a1 + a2)) * np.exp(2.11 * a2) + (a1 - a2))
             / (a2 - 1.0) ** 2)
        return [(b * nu0, "rayleigh", sigma), ((1.0 - b) * nu_p, "rayleigh", a2 * sigma)], 1.0
    # Dirlik (1985): the amplitude S = sqrt(m0) Z
    xm = m1 / m0 * np.sqrt(m2 / m4)
    d1 = 2.0 * (xm - a2 * a2) / (1.0 + a2 * a2)
    r = (a2 - xm - d1 * d1) / (1.0 - a2 - d1 + d1 * d1)
    d2 = (1.0 - a2 - d1 + d1 * d1) / (1.0 - r)
    d3 = 1.0 - d1 - d2
    q = 1.25 * (a2 - d3 - d2 * r) / d1
    return [(d1 * nu_p, "exponential", q * sigma), (d2 * nu_p, "rayleigh", abs(r) * sigma),
            (d3 * nu_p, "rayleigh", sigma)], 1.0


@public
def spectral_damage_from_moments(moments, sn_curve, duration, *, method="dirlik",
                                 mean_stress=0.0, ultimate_strength=None) -> float:
    """Expected fatigue damage of a stationary Gaussian stress from its spectral moments.

    Parameters
    ----------
    moments : dict
        ``m0``, ``m1``, ``m2``, ``m4`` of the one-sided stress PSD in Hz (`spectral_moments`,
        or a `random_response` result's moments of one output).
    sn_curve : SNCurve
        N(S), S the amplitude.
    duration : float
        Exposure time T, s.
    method : {"dirlik", "tovo_benasciutti", "wirsching_light", "narrow_band"}
        The amplitude distribution (see `spectral_damage`).
    mean_stress : float
        A constant mean stress on which the zero-mean process rides; with
        ``ultimate_strength`` every amplitude is scaled by 1 / (1 - mean_stress / S_u)
        (Goodman).
    ultimate_strength : float, optional
        S_u, for the Goodman correction of ``mean_stress``.

    Returns
    -------
    float
        The damage D over ``duration``.

    Examples
    --------
    >>> import dtdyn as dd          # narrow band: D = nu0 T (sqrt(2 m0))^b Gamma(1 + b/2) / C
    >>> sn = dd.SNCurve(slope=4.0, coefficient=1e12)
    >>> moments = {"m0": 1e2, "m1": 1e3, "m2": 1e4, "m4": 1.2e6}
    >>> round(dd.spectral_damage_from_moments(moments, sn, 3600.0, method="narrow_band"), 8)
    0.00288
    """
    sn = _check_curve(sn_curve)
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}; got "
                         f"method={method!r}")
    try:
        m0, m1, m2, m4 = (float(moments[k]) for k in ("m0", "m1", "m2", "m4"))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"moments must hold m0, m1, m2 and m4; got {moments!r}") from exc
    for name, v in (("m0", m0), ("m1", m1), ("m2", m2), ("m4", m4)):
        _positive(f"moments[{name!r}]", v)
    # a PSD's moments satisfy m1^2 <= m0 m2 and m2^2 <= m0 m4 (Cauchy-Schwarz): alpha1, alpha2
    # in (0, 1]; other sets are no spectrum's
    a1, a2 = m1 / np.sqrt(m0 * m2), m2 / np.sqrt(m0 * m4)
    if a1 > 1.0 + 1e-9 or a2 > 1.0 + 1e-9:
        raise ValueError(f"moments {moments!r} are no PSD's: alpha1 = m1/sqrt(m0 m2) = {a1:.6g}"
                         f" and alpha2 = m2/sqrt(m0 m4) = {a2:.6g} must be at most 1")
    if 1.0 - a2 < 1e-10 and method in ("dirlik", "tovo_benasciutti"):
        method = "narrow_band"     # both tend to it as alpha2 -> 1 (their formulas are 0/0 there)
    T = _positive("duration", duration)
    gain = 1.0
    if ultimate_strength is not None:
        gain = float(_goodman(np.array([1.0]), np.array([float(mean_stress)]),
                              ultimate_strength)[0])
    elif mean_stress != 0.0:
        raise ValueError("mean_stress needs ultimate_strength (the Goodman correction)")
    parts, factor = _components(method, m0, m1, m2, m4, float(sn.slope))
    total = 0.0
    for rate, kind, scale in parts:
        moment = _rayleigh_moment if kind == "rayleigh" else _exponential_moment
        scale = scale * gain
        if not (np.isfinite(rate) and np.isfinite(scale)) or rate < 0 or scale < 0:
            raise ValueError(f"method {method!r} gives no valid amplitude distribution for the "
                             f"moments {moments!r} (a term of rate {rate!r}, scale {scale!r})")
        for lo, hi, c, k in sn.pieces():
            if scale > 0:
                total += rate * moment(k, scale, lo, hi) / c
    return float(factor * T * total)


@public
def spectral_damage(psd, freqs_hz, sn_curve, duration, *, method="dirlik", mean_stress=0.0,
                    ultimate_strength=None) -> float:
    r"""Expected fatigue damage of a stationary Gaussian stress with a one-sided PSD.

    Parameters
    ----------
    psd : array_like, shape (n,)
        One-sided PSD G(f) of the stress, (stress unit)^2 / Hz.
    freqs_hz : array_like, shape (n,)
        Frequencies, Hz, increasing (the moments are integrated by the trapezoidal rule).
    sn_curve : SNCurve
        N(S), S the amplitude (one or two slopes, endurance limit).
    duration : float
        Exposure time T, s.
    method : {"dirlik", "tovo_benasciutti", "wirsching_light", "narrow_band"}
        The amplitude distribution of the rainflow cycles (Notes).
    mean_stress : float
        A constant mean stress, with ``ultimate_strength`` (Goodman), default 0.
    ultimate_strength : float, optional
        S_u for the Goodman correction of ``mean_stress``.

    Returns
    -------
    float
        The damage D = T sum_j nu_j E_j[1 / N(S)] over ``duration``.

    Notes
    -----
    With m_k = int f^k G df, sigma = sqrt(m0), the mean up-crossing rate nu_0 = sqrt(m2/m0), the
    peak rate nu_p = sqrt(m4/m2), alpha_1 = m1 / sqrt(m0 m2) and alpha_2 = m2 / sqrt(m0 m4)
    (= nu_0 / nu_p), for Basquin's N = C S^-b:

    - narrow band (Rayleigh amplitudes, one cycle per up-crossing; Miles 1954, Bendat 1964):
      D_NB = nu_0 T (sqrt(2) sigma)^b Gamma(1 + b/2) / C;
    - Wirsching & Light (1980): D = lambda D_NB, lambda = a + (1 - a)(1 - eps)^c with
      a = 0.926 - 0.033 b, c = 1.587 b - 2.323, eps = sqrt(1 - alpha_2^2);
    - Dirlik (1985): nu_p cycles per second whose amplitude S = sigma Z has the density
      p(Z) = D1/Q e^(-Z/Q) + D2 Z/R^2 e^(-Z^2/(2 R^2)) + D3 Z e^(-Z^2/2) with
      x_m = (m1/m0) sqrt(m2/m4), D1 = 2 (x_m - alpha_2^2) / (1 + alpha_2^2),
      R = (alpha_2 - x_m - D1^2) / (1 - alpha_2 - D1 + D1^2), D2 = (1 - alpha_2 - D1 + D1^2) /
      (1 - R), D3 = 1 - D1 - D2, Q = 1.25 (alpha_2 - D3 - D2 R) / D1; so that
      D = nu_p T sigma^b [D1 Q^b Gamma(1 + b) + sqrt(2)^b Gamma(1 + b/2) (D2 |R|^b + D3)] / C;
    - Tovo & Benasciutti (2005): D = beta D_NB + (1 - beta) alpha_2^(b - 1) D_NB (the second
      term: nu_p cycles of Rayleigh amplitudes of scale alpha_2 sigma), with
      beta = (alpha_1 - alpha_2) [1.112 (1 + alpha_1 alpha_2 - (alpha_1 + alpha_2))
      e^(2.11 alpha_2) + (alpha_1 - alpha_2)] / (alpha_2 - 1)^2.

    On a two-slope curve with an endurance limit each term is integrated piecewise in closed
    form (incomplete gamma functions); Wirsching-Light's lambda then uses the upper slope b.

    References
    ----------
    Dirlik, T. (1985), Application of computers in fatigue analysis, PhD thesis, University of
    Warwick. Wirsching, P. H. & Light, M. C. (1980), Fatigue under wide band random stresses,
    J. Struct. Div. ASCE 106(7), 1593-1607. Benasciutti, D. & Tovo, R. (2005), Spectral methods
    for lifetime prediction under wide-band stationary random processes, Int. J. Fatigue 27(8),
    867-877.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> f = np.linspace(0.0, 200.0, 2001)
    >>> G = np.where((f > 40) & (f < 60), 5.0, 0.0)               # MPa^2/Hz, 100 MPa^2
    >>> sn = dd.SNCurve(slope=4.0, coefficient=1e13)
    >>> d = dd.spectral_damage(G, f, sn, 3600.0, method="narrow_band")
    >>> print(f"{d:.4e}")
    1.4350e-03
    """
    return spectral_damage_from_moments(spectral_moments(psd, freqs_hz), sn_curve, duration,
                                        method=method, mean_stress=mean_stress,
                                        ultimate_strength=ultimate_strength)
