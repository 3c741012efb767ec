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
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from dtdyn._engine import validate
from dtdyn._engine.errors import SRSSamplingWarning
from dtdyn.modal.srs import shock_response_spectrum

__all__ = ["ResponseSpectrum", "response_spectrum"]


@dataclass(frozen=True)
class ResponseSpectrum:
    """Response spectra, one row per damping ratio and one column per period.

    Attributes
    ----------
    periods : (n_T,) ndarray
        Natural periods, s.
    damping : (n_z,) ndarray
        Damping ratios.
    sd, psv, psa, sa : (n_z, n_T) ndarray
        Relative displacement, pseudo-velocity, pseudo-acceleration and absolute acceleration
        (the record's acceleration unit: m/s^2 gives m, m/s and m/s^2).
    info : dict
        Timings and the sampling of the record.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> ag = np.sin(np.linspace(0, 20, 2001)) * np.hanning(2001)
    >>> s = dd.response_spectrum(ag, 0.01, [0.5, 1.0, 2.0], damping=[0.02, 0.05])
    >>> s.sd.shape, bool(np.allclose(s.psa, (2 * np.pi / s.periods) ** 2 * s.sd))
    ((2, 3), True)
    """

    periods: np.ndarray
    damping: np.ndarray
    sd: np.ndarray
    psv: np.ndarray
    psa: np.ndarray
    sa: np.ndarray
    info: dict = field(default_factory=dict)


def response_spectrum(ground_acceleration, dt, periods, damping=0.05, *,
                      backend="c") -> ResponseSpectrum:
    """Relative displacement, pseudo-velocity, pseudo-acceleration and absolute acceleration
    spectra of a ground acceleration record (module docstring).

    Parameters
    ----------
    ground_acceleration : (n,) array_like
        Samples at t_k = k dt, linear between them (from rest: the first sample should be ~0).
    dt : float
        Sample step, s.
    periods : array_like
        Natural periods, s, > 0.
    damping : float or sequence of float
        Damping ratios, 0 <= zeta < 1.
    backend : {"c", "scipy"}
        The filters' implementation (as `shock_response_spectrum`).

    Returns
    -------
    ResponseSpectrum

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> ag = np.r_[0.0, np.ones(99), 0.0]             # a 1 s pulse of 1 m/s^2
    >>> s = dd.response_spectrum(ag, 0.01, [0.5, 2.0])
    >>> s.sd.shape                                     # (damping ratios, periods)
    (1, 2)
    """
    a = validate.vector("ground_acceleration", ground_acceleration)
    T = validate.vector("periods", np.atleast_1d(np.asarray(periods, dtype=float)),
                        positive=True)
    zetas = validate.vector("damping", np.atleast_1d(np.asarray(damping, dtype=float)),
                            nonnegative=True)
    freqs = 1.0 / T
    omega = 2.0 * np.pi * freqs
    sd, sa, run = [], [], 0.0
    for i, zeta in enumerate(zetas):
        kw = dict(damping=float(zeta), window="total", exact_peaks=True, backend=backend)
        z = shock_response_spectrum(a, dt, freqs, response="relative_displacement", **kw)
        with warnings.catch_warnings():  # the sampling warning, if any, was given once above
            warnings.simplefilter("ignore", SRSSamplingWarning)
            acc = shock_response_spectrum(a, dt, freqs, response="absolute_acceleration", **kw)
        sd.append(z.maximax)
        sa.append(acc.maximax)
        run += sum(r.info["setup_time"] + r.info["run_time"] for r in (z, acc))
    sd, sa = np.array(sd), np.array(sa)
    return ResponseSpectrum(periods=T, damping=zetas, sd=sd, psv=omega * sd, psa=omega**2 * sd,
                            sa=sa, info={"dt": float(dt), "n_samples": int(a.size),
                                         "run_time": run})
