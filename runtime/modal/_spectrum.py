r"""Earthquake response spectra of a ground acceleration record.

For each natural period T (omega = 2 pi / T) and damping ratio zeta, the oscillator
:math:`\ddot z + 2 \zeta \omega \dot z + \omega^2 z = -\ddot u_g(t)` (z relative to the ground)
gives (Chopra, *Dynamics of Structures*, sec. 6.6):

- SD  = max |z|                        relative displacement
- PSV = omega SD                       pseudo-velocity
- PSA = omega^2 SD                     pseudo-acceleration
- SA  = max |z'' + u_g''|              absolute acceleration (= PSA for zeta = 0)

The record is linear between samples; each oscillator runs the ramp-invariant digital filter
of `shock_response_spectrum` (exact at the samples for such a record) with its peaks found
exactly between samples (``exact_peaks``), over the record and the free vibration after it
(``window="total"``). So the spectra are those of the piecewise-linear record, to round-off.

Shortest periods
----------------
If the record samples a band-limited ground motion, the straight lines between samples
attenuate its content at f = 1 / T by up to e_bias = 1 - sinc^2(dt / T) (`dtdyn.modal._srs`):
3.2 % at 10 samples per period, 5 % at 8.03, 12.5 % at 5, 59 % at 2. An oscillator of period T
is excited mostly near f, so this is the spectrum's error there: on five synthetic 100 Hz
earthquake records (``examples/batch/make_records.py``) against the spectra of their band-limited
(FFT, 16 times) interpolation, SA and PSA differed by at most 2.0 % at T = 10 dt, 3.2 % at 8 dt,
8.1 % at 5 dt, 10 % at 4 dt. `default_periods` therefore starts at 10 samples per period
(`MIN_SAMPLES_PER_PERIOD`), and `response_spectrum` issues `SRSSamplingWarning` when a period it
is given has e_bias above 5 % (T < 8.03 dt).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dtdyn._engine import validate
from dtdyn._engine.errors import SRSSamplingWarning
from dtdyn._engine.public import public, warn
from dtdyn.modal._srs import WARN_ERROR, _spectrum, bias_error_bound

__all__ = ["ResponseSpectrum", "response_spectrum", "default_periods", "MIN_SAMPLES_PER_PERIOD"]

#: the default periods start at this many samples per period: e_bias = 1 - sinc^2(1/10) = 3.2 %
MIN_SAMPLES_PER_PERIOD = 10.0


def _samples_at_warn_level() -> float:
    """T / dt where 1 - sinc^2(dt / T) = WARN_ERROR (8.03 for 5 %), by bisection on dt / T."""
    lo, hi = 1e-6, 0.5           # e_bias rises monotonically with dt / T on (0, 1/2]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if bias_error_bound(mid, 1.0) < WARN_ERROR else (lo, mid)
    return 1.0 / lo


#: fewer samples per period than this: e_bias above WARN_ERROR (5 %), a SRSSamplingWarning
WARN_SAMPLES_PER_PERIOD = _samples_at_warn_level()


@public
def default_periods(dt, count=60, shortest=0.02, longest=5.0) -> np.ndarray:
    """The periods a response spectrum takes by default: ``count`` log-spaced from
    max(shortest, 10 dt) to ``longest``, seconds.

    A period T resolved by the record has at least `MIN_SAMPLES_PER_PERIOD` = 10 samples:
    the linear interpolation between samples then attenuates a band-limited record's content
    at 1 / T by at most e_bias = 1 - sinc^2(dt / T) = 3.2 % (module notes), below the 5 % of
    `SRSSamplingWarning`.

    Parameters
    ----------
    dt : float
        Sample step of the record, s.
    count : int
        Number of periods (>= 1).
    shortest, longest : float
        Period range asked for, s; the start is raised to 10 dt when the record is coarser.

    Returns
    -------
    (count,) ndarray
        Periods, s, ascending.

    Raises
    ------
    ValueError
        ``dt``, ``count``, ``shortest`` or ``longest`` not positive, or 10 dt > ``longest``
        (the record resolves none of the periods asked for).

    Examples
    --------
    >>> from dtdyn.modal._spectrum import default_periods
    >>> T = default_periods(0.01)            # a 100 Hz record: from 10 dt = 0.1 s to 5 s
    >>> T.size, float(T[0]), float(T[-1])
    (60, 0.1, 5.0)
    >>> float(default_periods(0.001)[0])     # 1 kHz: from 0.02 s
    0.02
    """
    dt = validate.positive_scalar("dt", dt)
    shortest = validate.positive_scalar("shortest", shortest)
    longest = validate.positive_scalar("longest", longest)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"count must be an integer >= 1, got {count!r}")
    start = max(shortest, MIN_SAMPLES_PER_PERIOD * dt)
    if start > longest:
        raise ValueError(f"dt = {dt:g} s: the record resolves periods from "
                         f"{MIN_SAMPLES_PER_PERIOD:g} dt = {start:g} s on, above longest = "
                         f"{longest:g} s; give the periods")
    return np.geomspace(start, longest, int(count))


def _warn_short_periods(T, dt) -> None:
    """SRSSamplingWarning when the shortest period has e_bias above WARN_ERROR."""
    bias = bias_error_bound(dt / T, 1.0)
    i = int(np.argmin(T))
    if bias[i] <= WARN_ERROR:
        return
    n_bad = int(np.sum(bias > WARN_ERROR))
    warn(f"the shortest period T = {T[i]:g} s spans {T[i] / dt:.3g} samples of dt = {dt:g} s "
         f"({n_bad} of {T.size} periods are below {WARN_SAMPLES_PER_PERIOD * dt:.4g} s = "
         f"{WARN_SAMPLES_PER_PERIOD:.3g} dt, the 5 % error level): if the record samples a "
         f"band-limited signal, linear interpolation between its samples attenuates its content "
         f"at 1/T = {1.0 / T[i]:g} Hz by up to 1 - sinc^2(dt/T) = {100 * bias[i]:.3g} %; the "
         f"default periods (periods=None) start at max(0.02 s, {MIN_SAMPLES_PER_PERIOD:g} dt) = "
         f"{max(0.02, MIN_SAMPLES_PER_PERIOD * dt):g} s", SRSSamplingWarning)


@dataclass(frozen=True)
class ResponseSpectrum:
    """Response spectra, one row per damping ratio and one column per period.

    Attributes
    ----------
    periods : (n_T,) ndarray
        Natural periods, s.
    damping_ratio : (n_z,) ndarray
        Damping ratios (``damping`` before this release: a deprecated read-only alias).
    sd, psv, psa, sa : (n_z, n_T) ndarray
        Relative displacement, pseudo-velocity, pseudo-acceleration and absolute acceleration
        (the record's acceleration unit: m/s^2 gives m, m/s and m/s^2).
    info : dict
        Timings and the sampling of the record.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> ag = np.sin(np.linspace(0, 20, 2001)) * np.hanning(2001)
    >>> s = dd.response_spectrum(ag, 0.01, [0.5, 1.0, 2.0], damping_ratio=[0.02, 0.05])
    >>> s.sd.shape, bool(np.allclose(s.psa, (2 * np.pi / s.periods) ** 2 * s.sd))
    ((2, 3), True)
    """

    periods: np.ndarray
    damping_ratio: np.ndarray
    sd: np.ndarray
    psv: np.ndarray
    psa: np.ndarray
    sa: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def damping(self) -> np.ndarray:
        """Deprecated: `damping_ratio`."""
        warn("ResponseSpectrum.damping is now ResponseSpectrum.damping_ratio; "
             "ResponseSpectrum.damping will be removed in the next release", DeprecationWarning)
        return self.damping_ratio


@public(renamed={"damping": "damping_ratio"})
def response_spectrum(ground_acceleration, dt, periods=None, damping_ratio=0.05, *,
                      backend="c") -> ResponseSpectrum:
    """Relative displacement, pseudo-velocity, pseudo-acceleration and absolute acceleration
    spectra of a ground acceleration record (module docstring).

    For each period T (omega = 2 pi / T) and damping ratio zeta, z'' + 2 zeta omega z' +
    omega^2 z = -a_g(t): SD = max |z|, PSV = omega SD, PSA = omega^2 SD, SA = max |z'' + a_g|.

    Parameters
    ----------
    ground_acceleration : (n,) array_like
        Samples at t_k = k dt, linear between them (from rest: the first sample should be ~0).
    dt : float
        Sample step, s.
    periods : array_like, optional
        Natural periods, s, > 0. Default: `default_periods` (dt): 60 log-spaced from
        max(0.02 s, 10 dt) to 5 s, the periods the record resolves to 3.2 % (module notes).
    damping_ratio : float or sequence of float
        Damping ratios, 0 <= zeta < 1 (``damping``: deprecated).
    backend : {"c", "scipy"}
        The filters' implementation (as `shock_response_spectrum`).

    Returns
    -------
    ResponseSpectrum

    Raises
    ------
    ValueError
        Naming the argument: a non-finite sample, dt <= 0, a period <= 0, a damping ratio
        outside [0, 1).

    Warns
    -----
    SRSSamplingWarning
        A period shorter than 8.03 dt: the record's linear interpolation may attenuate the
        content there by more than 5 % (module notes).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> ag = np.r_[0.0, np.ones(99), 0.0]             # a 1 s pulse of 1 m/s^2
    >>> s = dd.response_spectrum(ag, 0.01, [0.5, 2.0])
    >>> s.sd.shape                                     # (damping ratios, periods)
    (1, 2)
    >>> dd.response_spectrum(ag, 0.01).periods.size    # the default periods, 0.1 s to 5 s
    60
    """
    a = validate.vector("ground_acceleration", ground_acceleration)
    dt = validate.positive_scalar("dt", dt)
    if periods is None:
        T = default_periods(dt)
    else:
        T = validate.vector("periods", np.atleast_1d(validate.real_array("periods", periods)),
                            positive=True)
    zetas = validate.vector("damping_ratio",
                            np.atleast_1d(validate.real_array("damping_ratio", damping_ratio)),
                            nonnegative=True)
    bad = np.flatnonzero(zetas >= 1.0)
    if bad.size:
        raise ValueError(f"damping_ratio[{bad[0]}] = {float(zetas[bad[0]])!r}: must be < 1 "
                         "(underdamped)")
    if backend not in ("c", "scipy"):
        raise ValueError(f"backend must be 'c' or 'scipy', got {backend!r}")
    # the four spectra kept (damping ratios x periods each) and one damping ratio's two SRS
    # results (maximax, positive, negative per period) while they are computed
    validate.memory(f"response_spectrum: {zetas.size:,} damping ratios x {T.size:,} periods x "
                    "4 spectra (sd, psv, psa, sa)", 8 * (4 * zetas.size + 6) * T.size,
                    "ask for fewer periods or damping ratios")
    _warn_short_periods(T, dt)
    freqs = 1.0 / T
    omega = 2.0 * np.pi * freqs
    sd, sa, run = [], [], 0.0
    for zeta in zetas:
        z, acc = (_spectrum(a, 1.0 / dt, freqs, float(zeta), response, "total", None, True,
                            backend, None)
                  for response in ("relative_displacement", "absolute_acceleration"))
        sd.append(z.maximax)
        sa.append(acc.maximax)
        run += sum(r.info["setup_time"] + r.info["run_time"] for r in (z, acc))
    sd, sa = np.array(sd), np.array(sa)
    return ResponseSpectrum(periods=T, damping_ratio=zetas, sd=sd, psv=omega * sd,
                            psa=omega**2 * sd, sa=sa,
                            info={"dt": float(dt), "n_samples": int(a.size), "run_time": run})
