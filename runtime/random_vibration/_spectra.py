r"""Spectra for test specification: the vibration response spectrum (VRS), the fatigue damage
spectrum (FDS) and the extreme response spectrum (ERS) of a base acceleration, from its PSD or
from a time record, and the PSD whose FDS over a test duration equals a given one.

The oscillators
---------------
Each spectrum is a function of the natural frequency f_n of a base-excited single-DOF
oscillator (omega_n = 2 pi f_n, damping ratio zeta, Q = 1 / (2 zeta)), with z the
displacement relative to the base and a(t) the base acceleration:

.. math::

    \ddot z + 2\zeta\omega_n \dot z + \omega_n^2 z = -a(t).

The response y is one of `dtdyn.modal._srs.RESPONSES`: ``"absolute_acceleration"``
(:math:`-(2\zeta\omega_n\dot z + \omega_n^2 z)`), ``"relative_displacement"`` (z),
``"relative_velocity"``, ``"pseudo_velocity"`` (:math:`\omega_n z`) or
``"pseudo_acceleration"`` (:math:`\omega_n^2 z`).

From a PSD
----------
With G(f) the one-sided PSD of a and H_y(f) the transfer from a to y, the spectral moments of
the response are :math:`m_k = \int f^k |H_y(f)|^2 G(f)\,df` (k = 0, 1, 2, 4; f in Hz) over the
PSD's band. They are integrated by `random_response` on the oscillator (M = 1,
C = 2 zeta omega_n, K = omega_n^2, under ``ground_acceleration_psd``): adaptive
Gauss-Legendre panels placed at the PSD's breakpoints and around the resonance's half-power
band, with an error estimate (`dtdyn.random_vibration._response`). Then

.. math::

    \mathrm{VRS}(f_n) = \sqrt{m_0}, \qquad
    \mathrm{ERS}(f_n) = \sqrt{m_0}\left(\sqrt{2\ln(\nu_0^+ T)}
        + \frac{\gamma}{\sqrt{2\ln(\nu_0^+ T)}}\right), \qquad \nu_0^+ = \sqrt{m_2/m_0},

the ERS being the expected largest maximum of y over the duration T of a stationary Gaussian
response whose up-crossings of high levels are Poisson events (Davenport 1964;
gamma = 0.5772..., Euler's constant); ``peak="most_probable"`` gives the mode of the same
distribution, :math:`\sqrt{m_0}\sqrt{2\ln(\nu_0^+ T)}` (Lalanne's ERS, that of FatigueDS). The FDS
is the expected Miner damage over T of the stress :math:`\sigma = K y` on Basquin's curve
:math:`N = C S^{-b}` (S the amplitude): with the narrow-band (Rayleigh) formula (Lalanne, vol. 4,
eq. 4.41; Miles 1954)

.. math::

    \mathrm{FDS}(f_n) = \nu_0^+ T \frac{K^b}{C} \left(\sqrt{2 m_0}\right)^b
        \Gamma\!\left(1 + \frac{b}{2}\right),

or any other method of `spectral_damage_from_moments` (Dirlik, Wirsching-Light,
Tovo-Benasciutti) from the same moments.

From a time record
------------------
The responses of the oscillators to the record (linear between samples) come from the exact
ramp-invariant modal filters of `sdof_response` and `shock_response_spectrum`. VRS: the rms of
each response; FDS: the rainflow cycles of K y (`rainflow_cycles`, ASTM E1049-85) summed by
Palmgren-Miner on N = C S^-b, scaled by ``duration`` / (record length) when a duration is
given; ERS: the largest value of y during the record (``shock_response_spectrum`` with
``window="primary"``, exact peaks between samples by default).

The FDS-equivalent PSD
----------------------
Every method's damage grows as sigma^b = (m_0)^(b/2), and m_0 is linear in G; so a PSD flat
at G_0 near f_n has FDS(f_n) = G_0^(b/2) FDS_1(f_n), FDS_1 that of the unit PSD. Inverting this
at every f_n gives the first estimate (for the narrow-band formula and relative displacement
it is Lalanne's :math:`G = \frac{32\pi^3 f_n^3}{Q}\frac{z_{rms}^2}{1}` with
:math:`z_{rms} = \frac{1}{\sqrt 2}(\mathrm{FDS}\,C/(K^b f_n T\,\Gamma(1+b/2)))^{1/b}`, up to the
band's ends); the PSD is then the table log-log between the f_n, and since its FDS at f_n also
sees the neighbouring values, it is corrected, :math:`G \leftarrow G\,(\mathrm{FDS}_{target}
/ \mathrm{FDS}(G))^{2/b}`, until the recomputed FDS is within ``tolerance`` of the target.

References
----------
C. Lalanne, *Mechanical Vibration and Shock Analysis*, 2nd ed., ISTE/Wiley 2009, vol. 3
(Random Vibration) ch. 6-8, vol. 4 (Fatigue Damage) ch. 4, vol. 5 (Specification
Development) ch. 2-4. A. G. Davenport (1964), Note on the distribution of the largest value of a
random function with application to gust loading, Proc. ICE 28(2), 187-196. S. O. Rice (1945),
Mathematical analysis of random noise, Bell System Tech. J. 24, 46-156.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dtdyn._engine import validate
from dtdyn._engine.public import public
from dtdyn.random_vibration._fatigue import METHODS, SNCurve, spectral_damage_from_moments
from dtdyn.random_vibration._psd import PsdTable
from dtdyn.random_vibration._response import random_response

__all__ = ["VibrationSpectrum", "vibration_response_spectrum", "fatigue_damage_spectrum",
           "extreme_response_spectrum", "fds_equivalent_psd", "sdof_moments"]

#: the responses of the oscillator (those of the SRS)
RESPONSES = ("absolute_acceleration", "relative_displacement", "relative_velocity",
             "pseudo_velocity", "pseudo_acceleration")
#: Euler's constant, Davenport's expected largest peak
EULER_GAMMA = 0.5772156649015329
PEAKS = ("expected", "most_probable")
#: bytes of response histories held at once by the record-based spectra
_BLOCK_BYTES = 32 << 20
#: past steps mixed by the Anderson acceleration of `fds_equivalent_psd`
ANDERSON_MEMORY = 5


@dataclass
class VibrationSpectrum:
    """A VRS, FDS or ERS over the oscillators' natural frequencies (module docstring).

    Attributes
    ----------
    kind : str
        ``"vrs"``, ``"fds"`` or ``"ers"``.
    freqs_hz : (n,) ndarray
        Natural frequencies f_n of the oscillators, Hz.
    values : (n,) ndarray
        The spectrum: the response's rms (VRS), the damage (FDS) or the largest response
        (ERS), per f_n.
    rms : (n,) ndarray
        The response's rms per f_n (from its PSD, or of the record's response).
    zero_crossing_rate : (n,) ndarray
        Zero up-crossings per second of the response, sqrt(m2 / m0) (from a PSD) or counted
        (from a record).
    damping_ratio : float
    response : str
        One of `RESPONSES`.
    info : dict
        ``source`` (``"psd"`` or ``"record"``), ``duration``, for an FDS ``slope``,
        ``coefficient``, ``stress_factor``, ``method``; from a PSD the moments ``m0``, ``m1``,
        ``m2``, ``m4`` (arrays) and ``rms_error_estimate``; ``band_hz``.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd          # Miles: sqrt(pi/2 f_n Q W) = 3.96 at 100 Hz
    >>> s = dd.vibration_response_spectrum(dd.psd_table([(20, 0.01), (2000, 0.01)]),
    ...                                    np.array([100.0, 200.0]), damping_ratio=0.05)
    >>> s.kind, s.values.round(3).tolist()
    ('vrs', [3.957, 5.615])
    """

    kind: str
    freqs_hz: np.ndarray
    values: np.ndarray
    rms: np.ndarray
    zero_crossing_rate: np.ndarray
    damping_ratio: float
    response: str
    info: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        k = int(np.argmax(self.values))
        return (f"VibrationSpectrum({self.kind}, {self.freqs_hz.size} natural frequencies "
                f"{self.freqs_hz[0]:g} .. {self.freqs_hz[-1]:g} Hz, damping ratio "
                f"{self.damping_ratio:g}, {self.response}; largest {self.values[k]:.4g} at "
                f"{self.freqs_hz[k]:.4g} Hz)")


# ---------------------------------------------------------------------------------------------
# checks


def _natural_freqs(freqs_hz) -> np.ndarray:
    f = validate.vector("freqs_hz", np.atleast_1d(validate.real_array("freqs_hz", freqs_hz)),
                        positive=True)
    if np.any(np.diff(f) <= 0):
        raise ValueError(f"freqs_hz = {freqs_hz!r}: natural frequencies must increase")
    return f


def _ratio(damping_ratio) -> float:
    try:
        zeta = float(damping_ratio)
    except (TypeError, ValueError):
        raise ValueError(f"damping_ratio must be a number, got {damping_ratio!r}") from None
    if not (np.isfinite(zeta) and 0.0 < zeta < 1.0):
        raise ValueError(f"damping_ratio = {damping_ratio!r}: must satisfy 0 < damping_ratio "
                         "< 1 (Q = 1 / (2 damping_ratio) > 0.5; an undamped oscillator's "
                         "response to a PSD is infinite)")
    return zeta


def _response(response) -> str:
    if response not in RESPONSES:
        raise ValueError(f"response = {response!r}: must be one of {', '.join(RESPONSES)}")
    return response


def _input(ground_acceleration_psd, psd_freqs_hz, ground_acceleration, dt):
    """'psd' or 'record', after checking that exactly one input is given."""
    if ground_acceleration is not None:
        if ground_acceleration_psd is not None:
            raise ValueError("ground_acceleration_psd and ground_acceleration are both given: "
                             "give the PSD or the time record")
        if dt is None:
            raise ValueError("ground_acceleration is given without dt (its sample step, s)")
        if psd_freqs_hz is not None:
            raise ValueError("psd_freqs_hz is given with a time record: it belongs to "
                             "ground_acceleration_psd")
        return "record"
    if ground_acceleration_psd is None:
        raise ValueError("give ground_acceleration_psd (a PSD) or ground_acceleration and dt "
                         "(a time record)")
    if dt is not None:
        raise ValueError("dt is given with ground_acceleration_psd: it belongs to a time "
                         "record (ground_acceleration)")
    return "psd"


def _band(psd, psd_freqs_hz) -> np.ndarray:
    """The frequencies handed to `random_response`: the band integrated, with every breakpoint
    of the PSD (a table's own, or the samples')."""
    if psd_freqs_hz is not None:
        f = validate.real_array("psd_freqs_hz", psd_freqs_hz, "an array of frequencies (Hz)")
        if (f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f)) or np.any(f < 0)
                or np.any(np.diff(f) <= 0)):
            raise ValueError(f"psd_freqs_hz = {psd_freqs_hz!r}: must be a 1-D array of at least "
                             "two finite, increasing frequencies >= 0 (Hz)")
        return f
    if isinstance(psd, PsdTable):
        return np.asarray(psd.freqs_hz, dtype=float)
    edges = getattr(psd, "freqs_hz", None)
    if callable(psd) and edges is not None and np.size(edges) >= 2:
        return np.asarray(edges, dtype=float)
    raise ValueError("psd_freqs_hz is needed: ground_acceleration_psd is not a PSD table (a "
                     "number, samples or a callable have no band of their own); give the "
                     "frequencies (Hz) of the samples, or the band of a number or callable")


# ---------------------------------------------------------------------------------------------
# from a PSD: the moments of each oscillator's response


@public
def sdof_moments(ground_acceleration_psd, freqs_hz, damping_ratio=0.05, *,
                 response="absolute_acceleration", psd_freqs_hz=None, accuracy=1e-8) -> dict:
    """Spectral moments of each base-excited oscillator's response to a base-acceleration PSD.

    Parameters
    ----------
    ground_acceleration_psd : PsdTable, callable, number or array_like
        One-sided PSD of the base acceleration, (unit)^2/Hz: a `psd_table`, a callable of
        the frequency in Hz (with ``psd_freqs_hz`` its band, or a ``freqs_hz`` attribute
        holding its breakpoints), a number (white over ``psd_freqs_hz``) or samples at
        ``psd_freqs_hz`` (log-log between them).
    freqs_hz : (n,) array_like
        Natural frequencies f_n of the oscillators, Hz, increasing.
    damping_ratio : float
        zeta, 0 < zeta < 1 (Q = 1 / (2 zeta)).
    response : str
        One of `RESPONSES` (module docstring).
    psd_freqs_hz : (m,) array_like, optional
        The PSD's frequencies (samples) or band (number, callable); a table carries its own.
    accuracy : float
        Relative error target of every moment (the quadrature of `random_response`).

    Returns
    -------
    dict
        ``m0``, ``m1``, ``m2``, ``m4``: (n,) arrays, m_k = int f^k |H_y|^2 G df (f in Hz), and
        ``rms_error_estimate``, the largest estimated relative error of an rms.

    Notes
    -----
    The oscillator is M = 1, C = 2 zeta omega_n, K = omega_n^2 under support motion, so that
    `random_response` gives the relative displacement ``x``, velocity ``v`` and the absolute
    acceleration ``a_abs``; the pseudo-velocity and pseudo-acceleration moments are omega_n^2
    and omega_n^4 times those of ``x``.

    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration._spectra import sdof_moments
    >>> m = sdof_moments(1.0, [100.0], 0.05, response="relative_displacement",
    ...                  psd_freqs_hz=[0.0, 1e6])       # white: m0 = W / (8 zeta omega_n^3)
    >>> print(f"{m['m0'][0] * 8 * 0.05 * (2 * np.pi * 100.0) ** 3:.6f}")
    1.000000
    """
    f_n = _natural_freqs(freqs_hz)
    zeta = _ratio(damping_ratio)
    response = _response(response)
    band = _band(ground_acceleration_psd, psd_freqs_hz)
    quantity = {"absolute_acceleration": "a_abs", "relative_velocity": "v"}.get(response, "x")
    out = {k: np.empty(f_n.size) for k in ("m0", "m1", "m2", "m4")}
    worst = 0.0
    for i, fn in enumerate(f_n):
        w = 2.0 * np.pi * fn
        r = random_response([[1.0]], [[2.0 * zeta * w]], [[w * w]], None, band,
                            ground_acceleration_psd=ground_acceleration_psd,
                            quantities=("x", "v", "a") if quantity == "a_abs" else (quantity,),
                            accuracy=accuracy)
        scale = {"pseudo_velocity": w * w, "pseudo_acceleration": w**4}.get(response, 1.0)
        for k in out:
            out[k][i] = scale * getattr(r, k)[quantity][0]
        worst = max(worst, r.info["rms_error_estimate"])
    out["rms_error_estimate"] = worst
    out["band_hz"] = (float(band[0]), float(band[-1]))
    return out


def _rate(m):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(np.where(m["m0"] > 0, m["m2"] / np.where(m["m0"] > 0, m["m0"], 1.0),
                                0.0))


def _psd_info(m, duration=None):
    info = {"source": "psd", "band_hz": m["band_hz"],
            "rms_error_estimate": m["rms_error_estimate"],
            **{k: m[k] for k in ("m0", "m1", "m2", "m4")}}
    if duration is not None:
        info["duration"] = duration
    return info


# ---------------------------------------------------------------------------------------------
# from a record: the oscillators' responses, a block of frequencies at a time


def _record_blocks(ground_acceleration, dt, f_n, zeta, response, points_per_cycle):
    """Yield (slice of f_n, response histories (n_t, block)) by `sdof_response`."""
    from dtdyn.modal._srs import sdof_response
    a = validate.real_array("ground_acceleration", ground_acceleration, "a 1-D record")
    per = max(1, int(_BLOCK_BYTES // (8 * max(a.size, 1) * max(1, _upsampling(
        f_n, dt, points_per_cycle)))))
    for lo in range(0, f_n.size, per):
        b = slice(lo, min(lo + per, f_n.size))
        _, y = sdof_response(a, dt, f_n[b], zeta, response=response,
                             points_per_cycle=points_per_cycle)
        yield b, y


def _upsampling(f_n, dt, ppc):
    if ppc is None:
        return 1
    return max(1, int(np.ceil(float(ppc) * float(f_n.max()) * float(dt) - 1e-9)))


def _record_length(ground_acceleration, dt) -> float:
    dt = validate.positive_scalar("dt", dt)
    n = np.size(ground_acceleration)
    if n < 2:
        raise ValueError(f"ground_acceleration has {n} sample(s): a record needs at least two")
    return (n - 1) * dt


def _record_stats(y, T):
    rms = np.sqrt(np.mean(y * y, axis=0))
    ups = np.count_nonzero((y[:-1] < 0.0) & (y[1:] >= 0.0), axis=0)
    return rms, ups / T


# ---------------------------------------------------------------------------------------------
# the spectra


_INPUT_DOC = """    ground_acceleration_psd : PsdTable, callable, number or array_like, optional
        One-sided PSD of the base acceleration, (unit)^2/Hz (as `sdof_moments`); or None with
        ``ground_acceleration``.
    freqs_hz : (n,) array_like
        Natural frequencies f_n of the oscillators, Hz, increasing.
    damping_ratio : float
        zeta, 0 < zeta < 1 (Q = 1 / (2 zeta); 0.05 is Q = 10).
"""
_RESPONSE_DOC = """    response : str
        One of `RESPONSES`: ``"absolute_acceleration"``, ``"relative_displacement"``,
        ``"relative_velocity"``, ``"pseudo_velocity"``, ``"pseudo_acceleration"``.
"""
_SOURCE_DOC = """    psd_freqs_hz : (m,) array_like, optional
        The PSD's frequencies (samples) or band (a number or callable); a table has its own.
    ground_acceleration : (n_samples,) array_like, optional
        Instead of a PSD: a base-acceleration record, samples at t_k = k dt, linear between
        them (as `shock_response_spectrum`).
    dt : float, optional
        The record's sample step, s.
"""
_ACCURACY_DOC = """    accuracy : float
        Relative error target of the moments (from a PSD).
"""


@public
def vibration_response_spectrum(ground_acceleration_psd, freqs_hz, damping_ratio=0.05, *,
                                response="absolute_acceleration", psd_freqs_hz=None,
                                ground_acceleration=None, dt=None, points_per_cycle=None,
                                accuracy=1e-8) -> VibrationSpectrum:
    return _vrs(ground_acceleration_psd, freqs_hz, damping_ratio, response, psd_freqs_hz,
                ground_acceleration, dt, points_per_cycle, accuracy)


def _vrs(psd, freqs_hz, damping_ratio, response, psd_freqs_hz, record, dt, ppc, accuracy):
    f_n, zeta, response = _natural_freqs(freqs_hz), _ratio(damping_ratio), _response(response)
    if _input(psd, psd_freqs_hz, record, dt) == "psd":
        m = sdof_moments(psd, f_n, zeta, response=response, psd_freqs_hz=psd_freqs_hz,
                         accuracy=accuracy)
        rms = np.sqrt(m["m0"])
        return VibrationSpectrum("vrs", f_n, rms, rms, _rate(m), zeta, response, _psd_info(m))
    T = _record_length(record, dt)
    rms, rate = np.empty(f_n.size), np.empty(f_n.size)
    for b, y in _record_blocks(record, dt, f_n, zeta, response, ppc):
        rms[b], rate[b] = _record_stats(y, T)
    return VibrationSpectrum("vrs", f_n, rms.copy(), rms, rate, zeta, response,
                             {"source": "record", "duration": T, "dt": float(dt)})


vibration_response_spectrum.__wrapped__.__doc__ = vibration_response_spectrum.__doc__ = (
    """Vibration response spectrum: the rms response of a base-excited oscillator at every
    natural frequency, from a base-acceleration PSD (exact integration) or a time record.

    Parameters
    ----------
""" + _INPUT_DOC + _RESPONSE_DOC + _SOURCE_DOC + """    points_per_cycle : float, optional
        From a record: upsample it linearly (exact under the linear-between-samples model) to
        at least this many samples per cycle of the highest f_n.
""" + _ACCURACY_DOC + """
    Returns
    -------
    VibrationSpectrum
        ``values`` = ``rms`` = sqrt(m0) per f_n (module docstring), ``zero_crossing_rate``.

    Notes
    -----
    VRS(f_n) = sqrt(int |H_y(f)|^2 G(f) df), integrated to ``accuracy`` by the quadrature of
    `random_response` (panels around the resonance: the peak is never missed). For white
    noise W and the absolute acceleration, VRS^2 = pi f_n W (1 + 4 zeta^2) / (4 zeta) (Miles'
    equation without its approximation).

    Examples
    --------
    >>> from dtdyn.random_vibration import psd_table
    >>> from dtdyn.random_vibration._spectra import vibration_response_spectrum
    >>> table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # g^2/Hz
    >>> vrs = vibration_response_spectrum(table, [50.0, 200.0, 1000.0], damping_ratio=0.05)
    >>> vrs.values.round(2).tolist()                              # grms
    [4.36, 11.18, 15.5]
    """)


@public
def extreme_response_spectrum(ground_acceleration_psd, freqs_hz, damping_ratio=0.05, *,
                              duration=None, response="pseudo_acceleration", peak="expected",
                              psd_freqs_hz=None, ground_acceleration=None, dt=None,
                              exact_peaks=True, accuracy=1e-8) -> VibrationSpectrum:
    f_n, zeta, response = _natural_freqs(freqs_hz), _ratio(damping_ratio), _response(response)
    if peak not in PEAKS:
        raise ValueError(f"peak = {peak!r}: must be one of {', '.join(PEAKS)}")
    if _input(ground_acceleration_psd, psd_freqs_hz, ground_acceleration, dt) == "psd":
        if duration is None:
            raise ValueError("duration is needed with ground_acceleration_psd: the exposure "
                             "time T, s, over which the largest peak is expected")
        T = validate.positive_scalar("duration", duration)
        m = sdof_moments(ground_acceleration_psd, f_n, zeta, response=response,
                         psd_freqs_hz=psd_freqs_hz, accuracy=accuracy)
        rms, nu0 = np.sqrt(m["m0"]), _rate(m)
        n = nu0 * T
        if np.any(n <= 1.0):
            i = int(np.flatnonzero(n <= 1.0)[0])
            raise ValueError(f"duration = {duration!r}: at f_n = {f_n[i]:g} Hz the response "
                             f"crosses zero {n[i]:.3g} times upwards in it; the largest-peak "
                             "formula needs nu0 T > 1 (a longer duration)")
        u = np.sqrt(2.0 * np.log(n))
        factor = u + EULER_GAMMA / u if peak == "expected" else u
        info = _psd_info(m, T)
        info["peak"], info["peak_factor"] = peak, factor
        return VibrationSpectrum("ers", f_n, rms * factor, rms, nu0, zeta, response, info)
    from dtdyn.modal._srs import shock_response_spectrum
    T = _record_length(ground_acceleration, dt)
    if duration is not None:
        raise ValueError("duration is given with a time record: the ERS of a record is its "
                         "largest response during the record itself")
    s = shock_response_spectrum(ground_acceleration, dt, f_n, zeta, response=response,
                                window="primary", exact_peaks=bool(exact_peaks))
    rms, rate = np.empty(f_n.size), np.empty(f_n.size)
    for b, y in _record_blocks(ground_acceleration, dt, f_n, zeta, response, None):
        rms[b], rate[b] = _record_stats(y, T)
    return VibrationSpectrum("ers", f_n, s.positive, rms, rate, zeta, response,
                             {"source": "record", "duration": T, "dt": float(dt),
                              "negative": s.negative, "exact_peaks": bool(exact_peaks)})


extreme_response_spectrum.__wrapped__.__doc__ = extreme_response_spectrum.__doc__ = (
    """Extreme response spectrum: the largest response of a base-excited oscillator at every
    natural frequency, expected over ``duration`` from a PSD (Rice, Davenport), or found in a
    time record.

    Parameters
    ----------
""" + _INPUT_DOC + """    duration : float
        From a PSD: the exposure time T, s.
    response : str
        One of `RESPONSES` (default ``"pseudo_acceleration"``, omega_n^2 z: Lalanne's ERS).
    peak : {"expected", "most_probable"}
        From a PSD: the expected largest maximum, sigma (u + gamma / u), u = sqrt(2 ln(nu0 T))
        (Davenport 1964), or the most probable one, sigma u (Lalanne; FatigueDS).
""" + _SOURCE_DOC + """    exact_peaks : bool
        From a record: refine each maximum between samples (`shock_response_spectrum`).
""" + _ACCURACY_DOC + """
    Returns
    -------
    VibrationSpectrum
        ``values``: the largest maximum of y per f_n (from a record: max y during it;
        ``info["negative"]`` holds -min y); ``rms``, ``zero_crossing_rate``.

    Notes
    -----
    For a stationary Gaussian response with nu0 = sqrt(m2 / m0) up-crossings of zero per
    second, up-crossings of a high level a are Poisson events at the rate
    nu0 exp(-a^2 / (2 m0)) (Rice 1945), so the largest maximum over T has the Gumbel-type
    distribution P(max < a) = exp(-nu0 T exp(-a^2 / (2 m0))), whose mean is, for large nu0 T,
    sqrt(m0) (u + gamma / u) with u = sqrt(2 ln(nu0 T)) and gamma = 0.5772 (Davenport) and whose
    mode is sqrt(m0) u. A record's maximum scatters about that mean (its standard deviation is
    about sqrt(m0) pi / (sqrt(6) u)).

    Examples
    --------
    >>> from dtdyn.random_vibration import psd_table
    >>> from dtdyn.random_vibration._spectra import extreme_response_spectrum
    >>> table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # g^2/Hz
    >>> ers = extreme_response_spectrum(table, [50.0, 200.0, 1000.0], duration=3600.0)
    >>> ers.values.round(1).tolist()                              # g
    [21.9, 59.0, 86.3]
    """)


@public
def fatigue_damage_spectrum(ground_acceleration_psd, freqs_hz, damping_ratio=0.05, *,
                            slope, coefficient=1.0, stress_factor=1.0, duration=None,
                            response="relative_displacement", method="narrow_band",
                            psd_freqs_hz=None, ground_acceleration=None, dt=None,
                            points_per_cycle=None, accuracy=1e-8) -> VibrationSpectrum:
    f_n, zeta, response = _natural_freqs(freqs_hz), _ratio(damping_ratio), _response(response)
    sn = SNCurve(slope=slope, coefficient=coefficient)
    K = validate.positive_scalar("stress_factor", stress_factor)
    b, C = float(sn.slope), float(sn.coefficient)
    if method not in METHODS:
        raise ValueError(f"method = {method!r}: must be one of {', '.join(METHODS)}")
    common = {"slope": b, "coefficient": C, "stress_factor": K}
    if _input(ground_acceleration_psd, psd_freqs_hz, ground_acceleration, dt) == "psd":
        if duration is None:
            raise ValueError("duration is needed with ground_acceleration_psd: the exposure "
                             "time T, s, over which the damage is summed")
        T = validate.positive_scalar("duration", duration)
        m = sdof_moments(ground_acceleration_psd, f_n, zeta, response=response,
                         psd_freqs_hz=psd_freqs_hz, accuracy=accuracy)
        damage = np.array([spectral_damage_from_moments(
            {k: K * K * m[k][i] for k in ("m0", "m1", "m2", "m4")}, sn, T, method=method)
            for i in range(f_n.size)])
        info = {**_psd_info(m, T), "method": method, **common}
        return VibrationSpectrum("fds", f_n, damage, np.sqrt(m["m0"]), _rate(m), zeta,
                                 response, info)
    from dtdyn.random_vibration._rainflow import rainflow_cycles
    T_record = _record_length(ground_acceleration, dt)
    T = T_record if duration is None else validate.positive_scalar("duration", duration)
    damage, rms, rate = np.empty(f_n.size), np.empty(f_n.size), np.empty(f_n.size)
    for blk, y in _record_blocks(ground_acceleration, dt, f_n, zeta, response,
                                 points_per_cycle):
        rms[blk], rate[blk] = _record_stats(y, T_record)
        for j, i in enumerate(range(blk.start, blk.stop)):
            damage[i] = rainflow_cycles(K * y[:, j]).damage(sn)
    damage *= T / T_record
    return VibrationSpectrum("fds", f_n, damage, rms, rate, zeta, response,
                             {"source": "record", "duration": T, "record_duration": T_record,
                              "dt": float(dt), "method": "rainflow", **common})


fatigue_damage_spectrum.__wrapped__.__doc__ = fatigue_damage_spectrum.__doc__ = (
    """Fatigue damage spectrum: the Miner damage of a base-excited oscillator at every natural
    frequency, its stress K y on Basquin's curve N = C S^-b, from a base-acceleration PSD
    (spectral moments) or a time record (rainflow).

    Parameters
    ----------
""" + _INPUT_DOC + """    slope : float
        Basquin's exponent b of N = C S^-b (S the stress amplitude).
    coefficient : float
        Basquin's C (default 1: the FDS is then in units of (K y)^b, as in Lalanne).
    stress_factor : float
        K, the stress per unit response, sigma = K y (default 1).
    duration : float
        The exposure time T, s: required from a PSD; from a record the damage is scaled by
        T / (record length) when given (default: the record's own length).
    response : str
        One of `RESPONSES` (default ``"relative_displacement"``: the stress of a
        one-mode structure follows its relative displacement, as in Lalanne's FDS).
    method : str
        From a PSD: ``"narrow_band"`` (default; Lalanne's FDS), ``"dirlik"``,
        ``"wirsching_light"`` or ``"tovo_benasciutti"`` (`spectral_damage_from_moments`).
""" + _SOURCE_DOC + """    points_per_cycle : float, optional
        From a record: upsample it (linearly, exact under the model) to at least this many
        samples per cycle of the highest f_n before counting (peaks between samples are
        otherwise missed: up to 1 - cos(pi f_n dt) of an amplitude).
""" + _ACCURACY_DOC + """
    Returns
    -------
    VibrationSpectrum
        ``values``: the damage per f_n; ``rms``, ``zero_crossing_rate`` of the response y.

    Notes
    -----
    Narrow band (Lalanne, vol. 4 eq. 4.41): FDS = nu0 T K^b / C (sqrt(2 m0))^b Gamma(1 + b/2)
    with m0, m2 the moments of y and nu0 = sqrt(m2 / m0). From a record: D = sum n_i K^b S_i^b
    / C over the rainflow cycles of y (S_i: half the range; n_i = 1 or 0.5).

    Examples
    --------
    >>> from dtdyn.random_vibration import psd_table
    >>> from dtdyn.random_vibration._spectra import fatigue_damage_spectrum
    >>> table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # g^2/Hz
    >>> fds = fatigue_damage_spectrum(table, [50.0, 200.0], slope=8.0, duration=3600.0,
    ...                               response="pseudo_acceleration")
    >>> [f"{d:.3e}" for d in fds.values]                     # (g)^8, C = K = 1
    ['9.009e+12', '6.454e+16']
    """)


# ---------------------------------------------------------------------------------------------
# the PSD equivalent to an FDS


@public
def fds_equivalent_psd(fds, duration, *, tolerance=1e-4, max_iterations=50,
                       accuracy=1e-8) -> PsdTable:
    """The PSD whose fatigue damage spectrum over ``duration`` equals ``fds`` (test tailoring):
    a table log-log between the natural frequencies.

    Parameters
    ----------
    fds : VibrationSpectrum
        A fatigue damage spectrum (`fatigue_damage_spectrum`, from a PSD or a record, or a sum
        of several for a mission); its ``freqs_hz``, damping ratio, response, S-N curve,
        stress factor and method (narrow band for a record's) are used again.
    duration : float
        The test duration T, s.
    tolerance : float
        Relative difference allowed between the recomputed FDS and ``fds`` at every f_n.
    max_iterations : int
        Corrections after the first estimate (0: the per-f_n inversion alone).
    accuracy : float
        Relative error target of the moments.

    Returns
    -------
    PsdTable
        (unit)^2/Hz at ``fds.freqs_hz``, log-log between them, zero outside.

    Notes
    -----
    Damage grows as m0^(b/2) and m0 is linear in G: a PSD flat at G near f_n has
    FDS(f_n) = G^(b/2) FDS_1(f_n), FDS_1 that of the unit PSD on the same band, which inverts
    to G(f_n) = (FDS(f_n) / FDS_1(f_n))^(2/b) (Lalanne, vol. 5 ch. 4, with the exact moments in
    place of Miles' approximation). The table's FDS at f_n also sees the neighbouring values;
    each correction G <- G (FDS_target / FDS(G))^(2/b) brings it back, until every f_n is within
    ``tolerance`` (a RuntimeError if ``max_iterations`` do not suffice); the iteration on
    ln G is accelerated by Anderson mixing of the last steps (Walker & Ni 2011).

    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration import psd_table
    >>> from dtdyn.random_vibration._spectra import fatigue_damage_spectrum, fds_equivalent_psd
    >>> flight = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
    >>> f_n = np.geomspace(20, 2000, 25)
    >>> fds = fatigue_damage_spectrum(flight, f_n, slope=8.0, duration=10 * 3600.0)
    >>> test = fds_equivalent_psd(fds, duration=3600.0)      # 10 hours in 1 hour
    >>> print(f"{test.grms / flight.grms:.3f}")               # about 10^(1/8)
    1.333
    """
    if not isinstance(fds, VibrationSpectrum) or fds.kind != "fds":
        raise ValueError(f"fds must be a fatigue damage spectrum (fatigue_damage_spectrum), "
                         f"got {type(fds).__name__}"
                         + (f" of kind {fds.kind!r}" if isinstance(fds, VibrationSpectrum)
                            else ""))
    T = validate.positive_scalar("duration", duration)
    tolerance = validate.positive_scalar("tolerance", tolerance)
    max_iterations = int(max_iterations)
    if max_iterations < 0:
        raise ValueError(f"max_iterations = {max_iterations!r}: must be >= 0")
    f, target = fds.freqs_hz, np.asarray(fds.values, dtype=float)
    if f.size < 2:
        raise ValueError("fds has a single natural frequency: a PSD table needs two or more")
    bad = ~np.isfinite(target) | (target <= 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"fds.values[{i}] = {target[i]!r} at {f[i]:g} Hz: an FDS to invert "
                         "must be finite and > 0 at every natural frequency")
    info = fds.info
    method = info.get("method", "narrow_band")
    method = "narrow_band" if method == "rainflow" else method
    b = float(info["slope"])
    kw = dict(slope=b, coefficient=info["coefficient"], stress_factor=info["stress_factor"],
              duration=T, response=fds.response, method=method, accuracy=accuracy)

    def damage(G):
        table = PsdTable(f, G)
        return fatigue_damage_spectrum(table, f, fds.damping_ratio, **kw).values

    # the fixed point of x <- x + (2/b) ln(FDS_target / FDS(e^x)), x = ln G, accelerated by
    # Anderson mixing over the last ANDERSON_MEMORY steps (the plain iteration contracts by
    # only ~0.85 per step at a breakpoint of the PSD)
    x = (2.0 / b) * np.log(target / damage(np.ones(f.size)))
    xs, rs = [], []
    for _ in range(max_iterations + 1):
        d = damage(np.exp(x))
        r = (2.0 / b) * np.log(target / d)
        if np.max(np.abs(d / target - 1.0)) <= tolerance or max_iterations == 0:
            return PsdTable(f, np.exp(x))
        xs, rs = (xs + [x])[-ANDERSON_MEMORY - 1:], (rs + [r])[-ANDERSON_MEMORY - 1:]
        if len(xs) > 1:
            dR = np.diff(np.array(rs), axis=0).T
            dX = np.diff(np.array(xs), axis=0).T
            gamma_, *_ = np.linalg.lstsq(dR, r, rcond=None)
            x = x + r - (dX + dR) @ gamma_
        else:
            x = x + r
    raise RuntimeError(f"fds_equivalent_psd: the recomputed FDS is still "
                       f"{np.max(np.abs(d / target - 1.0)):.2g} from the target after "
                       f"{max_iterations} corrections (tolerance {tolerance:g}); raise "
                       "max_iterations or tolerance, or give a smoother FDS")
