"""Shock response spectra by ramp-invariant modal filters (ISO 18431-4, Smallwood's algorithm).

(About 670 lines, a hundred of them this derivation: the windows, the exact peaks and the error
bounds share the one filter bank and its state, so they stay together.)

Model
-----
A base-excited single-DOF oscillator of natural frequency f (omega = 2 pi f) and damping ratio
zeta, relative displacement z = x - x_base:

    z'' + 2 zeta omega z' + omega^2 z = -a(t),

where a(t) is the base acceleration. The record a_0 .. a_{N-1} (a_n at t_n = n dt, fs = 1/dt) is
taken to be **linear between samples**, starting at rest at t_{-1} = -1/fs with a_{-1} = 0 (a
ramp up to a_0 over one sample) and ramping back to 0 over [t_{N-1}, t_N] (zero input
afterwards). For that piecewise-linear input the ramp-invariant filter is exact at the samples:
this is the shock response spectrum of the linearly interpolated record, computed without
discretisation error.

Responses (all strictly proper transfer functions of s, poles s1, conj(s1) with
s1 = -zeta omega + j omega sqrt(1 - zeta^2)); the residue R at s1 (by partial fractions of
H_z(s) = -1 / ((s - s1)(s - conj s1)), R_z = -1 / (s1 - conj s1) = j / (2 omega_d)):

    relative_displacement   z                                 R = R_z
    relative_velocity       z'                                R = s1 R_z
    absolute_acceleration   x'' = -(2 zeta omega z' + w^2 z)  R = -(2 zeta omega s1 + omega^2) R_z
    pseudo_velocity         omega z                           R = omega R_z
    pseudo_acceleration     omega^2 z                         R = omega^2 R_z

The real second-order section of each frequency comes from the *generated* coefficients
``dtdyn.generated.modal_filters.pair_sections("ramp", s1, R, T)``; the sections run over the
record in the generated C kernel ``run_bank`` of :mod:`dtdyn.modal._filters`. The section
output is y_n = 2 Re q_n where q' = s1 q + R a(t) (the complex modal coordinate), which is what
lets this module rebuild the continuous state between samples (below).

Windows
-------
``primary``: t_{-1} <= t <= t_{N-1} (during the record). ``residual``: t >= t_{N-1} (the ramp
back to zero over one sample, then free vibration for ever). ``total``: both. The residual's free
vibration y(tau) = A e^{-zeta omega tau} cos(omega_d tau - phi) from t_N on has its extremes in
closed form (first local maximum at omega_d tau = phi - asin(zeta) mod 2 pi, value
A sqrt(1 - zeta^2) e^{-zeta omega tau}; the minimum half a period later; or the start value): no
zero padding, no cap on its length, exact for every frequency in both peak modes. A and phi come
from the state at t_N, rebuilt from the outputs at t_N and t_N + T (see below; its rounding error
grows like eps / sin(omega_d T), 1e-12 relative at omega_d T = 1e-4). pyyeti's residual starts at
t_N (the first appended zero) and picks samples over one cycle of the lowest frequency: it is
lower than this one when the response already decays at t_{N-1}, and by the peak-picking error.

Peaks
-----
``exact_peaks=False`` takes the extremes of the primary window at the samples (after the optional
upsampling). For a response oscillating at f sampled at fs (undamped sinusoid, worst sampling
phase: the peak half a sample from the nearest sample) the sampled peak is low by up to

    e_peak = 1 - cos(pi f / fs)                 (ppc = fs / f points per cycle)

(5 ppc: 19.1 %; 10 ppc: 4.9 %; 20 ppc: 1.2 %). This is the bound for a response ringing at f (the
usual case near the spectrum's peak; light damping does not raise it); an extreme set by the
input itself (a fast input change, e.g. a record that stops abruptly) follows the input's time
scale instead. ``points_per_cycle`` upsamples the record by linear interpolation, which is exact
under the piecewise-linear model (the ramp invariant sees the same input), so only e_peak
shrinks. ``exact_peaks=True`` removes e_peak. Candidate intervals are those whose upper estimate
max(y_k, y_{k+1}) + max|second difference| / 4 (twice the chord bulge T^2 max|y''| / 8 of the
interval) reaches the sampled extreme, at most 128 per frequency and sign. On each, the state q at
the interval start is rebuilt from the two end samples (y_k = 2 Re q_k, y_{k+1} = 2 Re(p q_k +
c0 a_k + c1 a_{k+1}), p = e^{s1 T}: a 2 x 2 real system with determinant proportional to
sin(omega_d T)), the response inside is evaluated with the same ramp formulas at step tau
(q(tau) = e^{s1 tau} q_k + c0(tau) a_k + c1(tau) a(t_k + tau), generated
``forced_coefficients``) on a 16-point grid, then polished by Newton's method on
y'(tau) = 2 Re(s1 q + R a) = 0. The result is the true extreme of the response to the
piecewise-linear input (to rounding; tested against a dense DOP853 solution to 1e-8).

Because that state rebuild needs sin(omega_d T) away from 0, the record is linearly upsampled
(exactly, as above) to at least 3 points per cycle of the highest frequency whenever the state is
needed (``window`` other than "primary", or ``exact_peaks``).

A second, different error applies if the record samples a band-limited signal rather than a
piecewise-linear one: linear interpolation multiplies the input spectrum by
(sin(pi f/fs)/(pi f/fs))^2, so content at f is attenuated by up to

    e_bias = 1 - sinc^2(f / fs)                 (fs / 4: 18.9 %; fs / 10: 3.2 %)

which neither upsampling nor exact peaks reduce (pyyeti documents e_bias + e_peak as its bound).
:class:`SRSSamplingWarning` is issued when e_peak (if peaks are picked at samples) or e_bias at the
highest frequency exceeds 5 % (about fs / 9.9 and fs / 8.0): the 10 points per cycle that ISO
18431-4 and pyyeti recommend. The warning is for frequencies the caller chose; the default sets
stay below it: `dtdyn srs` takes fs / 1e4 .. fs / 10 (e_peak 4.9 %, e_bias 3.2 % at fs / 10;
on five synthetic 100 Hz earthquake records the sampled peaks were at most 2.2 % below the exact
ones over that range, 2.0 % at fs / 10), and `dtdyn.modal._spectrum.default_periods` starts at
10 samples per period.

References
----------
ISO 18431-4:2007, Mechanical vibration and shock - Signal processing - Part 4: Shock-response
spectrum analysis. D. O. Smallwood (1981), An improved recursive formula for calculating shock
response spectra, Shock and Vibration Bulletin 51. Ahlin, Magnevall & Josefsson (2006), modal
digital filters.
"""
from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dtdyn.generated import modal_filters as coef

from dtdyn._engine import threads as cpu
from dtdyn._engine import validate
from dtdyn._engine.atomic import write_atomic
from dtdyn._engine.extras import require
from dtdyn.modal._filters import _c_bank, run_bank
from dtdyn._engine.errors import SRSSamplingWarning
from dtdyn._engine.public import public, warn

__all__ = ["RESPONSES", "WINDOWS", "SRS", "SRSSamplingWarning", "shock_response_spectrum",
           "sdof_response", "load_record", "peak_error_bound", "bias_error_bound", "plot_srs",
           "save_srs_csv"]

RESPONSES = ("absolute_acceleration", "relative_displacement", "relative_velocity",
             "pseudo_velocity", "pseudo_acceleration")
WINDOWS = ("primary", "residual", "total")
#: warn when the stated peak-picking or bias error at the highest frequency exceeds this
WARN_ERROR = 0.05
#: the keywords renamed in this release (old -> new), accepted with a DeprecationWarning
RENAMED = {"accel": "ground_acceleration", "freqs": "freqs_hz", "damping": "damping_ratio"}
#: minimum points per cycle of the highest frequency when the state is rebuilt from samples
MIN_STATE_PPC = 3.0
#: grid points per interval for the exact-peak search (then Newton)
_GRID = 16
#: at most this many candidate intervals per frequency and extreme for the exact-peak search
_MAX_CANDIDATES = 128
#: rows x columns per chunk of the exact-peak candidate sweep (temporaries stay in cache)
_CHUNK_ELEMS = 1 << 16
_CHUNK_MIN_ROWS = 1024
#: bytes of filter output per run_bank call: frequencies are filtered in blocks of this size, so
#: the working memory stays bounded however many frequencies are asked for
_BLOCK_BYTES = 4 << 20


@dataclass
class SRS:
    """A shock response spectrum.

    ``positive`` is the largest value of the response (max y), ``negative`` the magnitude of the
    most negative one (-min y), ``maximax`` the larger of the two; one entry per natural
    frequency ``freqs_hz``. ``info`` records the parameters (``damping_ratio``, ...), the
    effective sampling rate, the per-frequency error bounds ``peak_error_bound`` (0 with exact
    peaks) and ``bias_bound``, and timings in seconds.

    Attributes
    ----------
    freqs_hz : (n_f,) ndarray
        Natural frequencies of the oscillators, Hz (``freqs`` before this release: a deprecated
        read-only alias).
    maximax, positive, negative : (n_f,) ndarray
    info : dict

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> srs = dd.shock_response_spectrum(np.sin(np.arange(100) / 5.0), 1e-3, [10.0, 20.0])
    >>> srs.maximax.shape
    (2,)
    """

    freqs_hz: np.ndarray
    maximax: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def freqs(self) -> np.ndarray:
        """Deprecated: `freqs_hz`."""
        warn("SRS.freqs is now SRS.freqs_hz; SRS.freqs will be removed in the next release",
             DeprecationWarning)
        return self.freqs_hz


@public(renamed={"freqs": "freqs_hz"})
def peak_error_bound(freqs_hz, fs):
    """Largest relative shortfall of a sinusoid's peak picked at the samples,
    e_peak = 1 - cos(pi f / fs) (f capped at fs / 2).

    Parameters
    ----------
    freqs_hz : array_like
        Frequencies f of the response, Hz.
    fs : float
        Sampling rate, Hz.

    Returns
    -------
    ndarray
        e_peak per frequency.

    Examples
    --------
    >>> from dtdyn.modal._srs import peak_error_bound
    >>> round(float(peak_error_bound(10.0, 100.0)), 4)      # 10 samples per cycle
    0.0489
    """
    return 1.0 - np.cos(np.pi * np.minimum(np.asarray(freqs_hz, dtype=float) / fs, 0.5))


@public(renamed={"freqs": "freqs_hz"})
def bias_error_bound(freqs_hz, fs):
    """Attenuation at f of a band-limited input by linear interpolation between its samples,
    e_bias = 1 - sinc^2(f / fs), sinc(x) = sin(pi x) / (pi x).

    Parameters
    ----------
    freqs_hz : array_like
        Frequencies f of the input's content, Hz.
    fs : float
        Sampling rate, Hz.

    Returns
    -------
    ndarray
        e_bias per frequency.

    Examples
    --------
    >>> from dtdyn.modal._srs import bias_error_bound
    >>> round(float(bias_error_bound(10.0, 100.0)), 4)      # 10 samples per cycle
    0.0325
    """
    return 1.0 - np.sinc(np.asarray(freqs_hz, dtype=float) / fs) ** 2


# --- inputs ---------------------------------------------------------------------------------
def _check_record(ground_acceleration) -> np.ndarray:
    a = validate.real_array("ground_acceleration", ground_acceleration, "a 1-D record")
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"ground_acceleration must be a non-empty 1-D record, got shape "
                         f"{a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"ground_acceleration[{i}] = {a[i]!r} is not finite (sample {i} of "
                         f"{a.size})")
    return a


def _check_common(ground_acceleration, dt, freqs_hz, damping_ratio, response, points_per_cycle):
    """Checked (record, fs = 1/dt, freqs_hz, zeta, points_per_cycle)."""
    a = _check_record(ground_acceleration)
    fs = 1.0 / validate.positive_scalar("dt", dt)
    f = validate.vector("freqs_hz", np.atleast_1d(validate.real_array("freqs_hz", freqs_hz)),
                        positive=True)
    try:
        zeta = float(damping_ratio)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"damping_ratio must be a number, got {damping_ratio!r}") from None
    if not (np.isfinite(zeta) and 0.0 <= zeta < 1.0):
        raise ValueError(f"damping_ratio must be a ratio with 0 <= damping_ratio < 1 "
                         f"(underdamped), got {damping_ratio!r}")
    if response not in RESPONSES:
        raise ValueError(f"response must be one of {RESPONSES}, got {response!r}")
    if points_per_cycle is not None:
        points_per_cycle = validate.positive_scalar("points_per_cycle", points_per_cycle)
    return a, fs, f, zeta, points_per_cycle


def _poles_residues(freqs, zeta, response):
    """Upper pole s1 and the residue R of the response's transfer function at s1."""
    w = 2.0 * np.pi * freqs
    wd = w * math.sqrt(1.0 - zeta * zeta)
    s1 = -zeta * w + 1j * wd
    Rz = 0.5j / wd  # -1 / (s1 - conj(s1))
    R = {"relative_displacement": Rz,
         "relative_velocity": s1 * Rz,
         "absolute_acceleration": -(2.0 * zeta * w * s1 + w * w) * Rz,
         "pseudo_velocity": w * Rz,
         "pseudo_acceleration": w * w * Rz}[response]
    return s1, R


def _upsample_factor(f_max, fs, ppc):
    if ppc is None:
        return 1
    ratio = ppc * f_max / fs
    if not ratio < 2.0**53:  # inf, or beyond any record that fits in memory
        raise ValueError(f"freqs_hz (or 1 / periods) up to {f_max:.6g} Hz at dt = "
                         f"{1.0 / fs:.6g} s: the record would be upsampled {ratio:.3g} times "
                         f"({ppc:g} points per cycle); ask for lower freqs_hz (longer periods) "
                         "or sample the record at a smaller dt")
    return max(1, math.ceil(ratio - 1e-9))


def _extended_input(a: np.ndarray, u: int) -> np.ndarray:
    """The input on the grid t_{-1} + j T/u, j = 0 .. u (N + 1) + 1.

    Index 0 is t_{-1} (rest, 0), u (n + 1) is t_n, J_end = u N is t_{N-1}, j_N = u (N + 1) is t_N
    (0 after the ramp down), j_N + 1 one more zero sample (for the free-vibration state).
    """
    padded = np.concatenate(([0.0], a, [0.0]))  # t_{-1} .. t_N
    if u == 1:
        body = padded
    else:
        frac = np.arange(u) / u
        body = np.empty(u * (padded.size - 1) + 1)
        body[:-1] = (padded[:-1, None] + np.diff(padded)[:, None] * frac[None, :]).ravel()
        body[-1] = padded[-1]
    return np.concatenate((body, [0.0]))


# --- the filters ----------------------------------------------------------------------------
def _blocks(n_freq, length):
    nb = int(max(1, min(n_freq, _BLOCK_BYTES // max(1, 8 * length))))
    return [slice(i, min(i + nb, n_freq)) for i in range(0, n_freq, nb)]


def _run(e_col, sos, backend):
    k = len(sos)
    return run_bank(sos, np.zeros(k, np.int64), np.arange(k, dtype=np.int64), np.zeros((k, 1)),
                    e_col, k, backend)


def _rebuild_state(yk, yk1, ek, ek1, p, c0, c1):
    """q_k with y_k = 2 Re q_k and y_{k+1} = 2 Re(p q_k + c0 e_k + c1 e_{k+1})."""
    a = 0.5 * yk
    g = (c0 * ek + c1 * ek1).real
    b = (p.real * a + g - 0.5 * yk1) / p.imag
    return a + 1j * b


def _interval_response(q, s1, R, ek, ek1, Te, tau):
    """y, y', y'' at step tau into an interval whose input runs linearly from ek to ek1."""
    c0, c1 = coef.forced_coefficients("ramp", s1, R, tau)
    slope = (ek1 - ek) / Te
    x = ek + slope * tau
    qt = np.exp(s1 * tau) * q + c0 * ek + c1 * x
    dq = s1 * qt + R * x
    return 2.0 * qt.real, 2.0 * dq.real, 2.0 * (s1 * dq + R * slope).real


def _free_extremes(yN, yN1, s1, zeta, Te):
    """Max and min of the free vibration from t_N given its samples at t_N and t_N + Te."""
    p = np.exp(s1 * Te)
    q = _rebuild_state(yN, yN1, 0.0, 0.0, p, 0.0, 0.0)
    A = 2.0 * np.abs(q)
    phi = -np.angle(q)  # y(tau) = A e^{sigma tau} cos(omega_d tau - phi)
    psi = math.asin(zeta)
    sigma, wd = s1.real, s1.imag
    c = math.sqrt(1.0 - zeta * zeta)
    t_max = np.mod(phi - psi, 2.0 * np.pi) / wd
    t_min = np.mod(phi - psi + np.pi, 2.0 * np.pi) / wd
    return (np.maximum(yN, A * c * np.exp(sigma * t_max)),
            np.minimum(yN, -A * c * np.exp(sigma * t_min)))


def _top_per_column(rows, cols, score):
    """Keep the _MAX_CANDIDATES highest ``score`` entries of each column."""
    if rows.size == 0:
        return rows, cols
    order = np.lexsort((-score, cols))
    rows, cols = rows[order], cols[order]
    keep = (np.arange(cols.size) - np.searchsorted(cols, cols)) < _MAX_CANDIDATES
    return rows[keep], cols[keep]


def _candidates(block, smax, smin):
    """Intervals (row i: samples i, i+1 of ``block``) that may exceed the sampled extremes.

    Upper estimate on interval i: max(y_i, y_{i+1}) + T^2/8 max|y''|, with y'' T^2 estimated by the
    larger second difference at the interval's two ends and doubled for safety, i.e.
    max(y_i, y_{i+1}) + max(|d2 y_i|, |d2 y_{i+1}|) / 4 (a sinusoid at omega: d2 = 4 sin^2(omega
    T/2) A, true bulge A (1 - cos(omega T/2)); an input kink changes y'' only, y stays C^1); the
    same for the minimum. Returns ((rows, cols) for the max, (rows, cols) for the min). Works in
    chunks of rows so that the temporaries stay in cache.
    """
    M, nb = block.shape
    if M < 3:
        rows, cols = np.nonzero(np.ones((M - 1, nb), dtype=bool))
        return (rows, cols), (rows, cols)
    step = max(_CHUNK_MIN_ROWS, _CHUNK_ELEMS // nb)
    found = {+1: ([], [], []), -1: ([], [], [])}
    for r0 in range(0, M - 1, step):
        r1 = min(r0 + step, M - 1)  # intervals r0 .. r1-1
        b0, b1 = max(r0 - 1, 0), min(r1 + 2, M)
        yc = block[b0:b1]
        d2 = np.abs(yc[2:] - 2.0 * yc[1:-1] + yc[:-2])  # centred on rows b0+1 .. b1-2
        if r0 == 0:
            d2 = np.concatenate((d2[:1], d2))
        if b1 == M:
            d2 = np.concatenate((d2, d2[-1:]))  # now rows r0 .. r1
        bulge = np.maximum(d2[:-1], d2[1:])
        bulge *= 0.25
        y0, y1 = block[r0:r1], block[r0 + 1:r1 + 1]
        for sign, edge, ref in ((+1, np.maximum, smax), (-1, np.minimum, smin)):
            est = edge(y0, y1)
            if sign > 0:
                est += bulge
                hit = est >= ref[None, :]
            else:
                est -= bulge
                hit = est <= ref[None, :]
            idx = np.flatnonzero(hit)
            rows, cols = np.divmod(idx, nb)
            found[sign][0].append(rows + r0)
            found[sign][1].append(cols)
            found[sign][2].append(sign * est[rows, cols])
    out = []
    for sign in (+1, -1):
        rows, cols, score = (np.concatenate(v) for v in found[sign])
        out.append(_top_per_column(rows, cols, score))
    return out[0], out[1]


def _refine(y, e, k, c, s1, R, Te, sign, sampled):
    """Exact extreme (sign +1: max, -1: min) of each column: the sampled one or the best over the
    candidate intervals k (between samples k and k + 1 of y) of columns c."""
    if k.size == 0:
        return sampled
    s, r = s1[c], R[c]
    ek, ek1 = e[k], e[k + 1]
    c0T, c1T = coef.forced_coefficients("ramp", s, r, Te)
    q = _rebuild_state(y[k, c], y[k + 1, c], ek, ek1, np.exp(s * Te), c0T, c1T)
    q = np.where(k == 0, 0.0, q)  # t_{-1}: at rest, exactly
    tau = np.linspace(0.0, Te, _GRID + 1)
    yg, _, _ = _interval_response(q[:, None], s[:, None], r[:, None], ek[:, None], ek1[:, None],
                                  Te, tau[None, :])
    i = np.argmax(sign * yg, axis=1)
    best = sign * yg[np.arange(i.size), i]
    t = tau[i]
    lo_t = tau[np.maximum(i - 1, 0)]
    hi_t = tau[np.minimum(i + 1, _GRID)]
    for _ in range(8):  # Newton on y'(tau) = 0, kept inside the bracketing grid cells
        _, d1, d2 = _interval_response(q, s, r, ek, ek1, Te, t)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.nan_to_num(np.where(sign * d2 < 0.0, -d1 / d2, 0.0))
        t_new = np.clip(t + step, lo_t, hi_t)
        done = np.all(np.abs(t_new - t) <= 1e-14 * Te)
        t = t_new
        if done:
            break
    yn, _, _ = _interval_response(q, s, r, ek, ek1, Te, t)
    best = np.maximum(best, sign * yn)
    out = sign * np.asarray(sampled, dtype=float).copy()
    np.maximum.at(out, c, best)
    return sign * out


def _exact_extremes(y, e, lo, hi, s1, R, Te, smax, smin):
    """True (max, min) over the intervals between samples lo .. hi of every column of y."""
    (kx, cx), (kn, cn) = _candidates(y[lo:hi + 1], smax, smin)
    return (_refine(y, e, kx + lo, cx, s1, R, Te, +1, smax),
            _refine(y, e, kn + lo, cn, s1, R, Te, -1, smin))


def _block_extremes(e, sos, s1, R, zeta, Te, J_end, j_N, window, exact, backend):
    """(max, min) over the asked window of each section's output, for one block of sections."""
    y = _run(e[:, None], sos, backend)
    n = y.shape[1]
    hi = np.full(n, -np.inf)
    lo = np.full(n, np.inf)
    if window in ("primary", "total"):
        pmax = y[:J_end + 1].max(axis=0)
        pmin = y[:J_end + 1].min(axis=0)
        if exact:
            pmax, pmin = _exact_extremes(y, e, 0, J_end, s1, R, Te, pmax, pmin)
        hi, lo = np.maximum(hi, pmax), np.minimum(lo, pmin)
    if window in ("residual", "total"):
        rmax = y[J_end:j_N + 1].max(axis=0)
        rmin = y[J_end:j_N + 1].min(axis=0)
        if exact:  # the ramp back to zero, [t_{N-1}, t_N]
            rmax, rmin = _exact_extremes(y, e, J_end, j_N, s1, R, Te, rmax, rmin)
        fmax, fmin = _free_extremes(y[j_N], y[j_N + 1], s1, zeta, Te)
        hi = np.maximum(hi, np.maximum(rmax, fmax))
        lo = np.minimum(lo, np.minimum(rmin, fmin))
    return hi, lo


def _workers(workers, n_tasks, work):
    if workers is None:
        workers = min(cpu.available(), 8) if work > 2e7 else 1
    return int(max(1, min(workers, n_tasks)))


# --- public API -----------------------------------------------------------------------------
@public(renamed=RENAMED)
def shock_response_spectrum(ground_acceleration, dt, freqs_hz, damping_ratio=0.05,
                            response="absolute_acceleration", window="total",
                            points_per_cycle=None, exact_peaks=False, *, backend="c",
                            workers=None) -> SRS:
    """Shock response spectrum of a base-acceleration record.

    Each oscillator (natural frequency f, omega = 2 pi f, damping ratio zeta) is
    z'' + 2 zeta omega z' + omega^2 z = -a(t), z relative to the base; the spectrum is the
    extreme of the chosen response over the chosen window (module notes).

    Parameters
    ----------
    ground_acceleration : array_like, shape (n,)
        Base acceleration samples a_n at t_n = n dt (any unit; the spectrum of
        absolute_acceleration and pseudo_acceleration is in the same unit). Linear between
        samples, from rest at t_{-1} (a_{-1} = 0) and back to 0 at t_N (see the module notes).
        (``accel`` before this release: deprecated.)
    dt : float
        Sample step, s (sampling rate fs = 1 / dt).
    freqs_hz : array_like
        Natural frequencies of the oscillators, Hz, > 0 (``freqs``: deprecated).
    damping_ratio : float
        Damping ratio zeta, 0 <= zeta < 1 (Q = 1 / (2 zeta); 0.05 is Q = 10)
        (``damping``: deprecated).
    response : str
        One of RESPONSES: "absolute_acceleration" (default), "relative_displacement",
        "relative_velocity", "pseudo_velocity" (omega z), "pseudo_acceleration" (omega^2 z).
    window : {"total", "primary", "residual"}
        During the record, after it (closed-form free vibration), or both.
    points_per_cycle : float, optional
        Upsample the record by linear interpolation (exact under the model) so that the highest
        frequency has at least this many samples per cycle: peak-picking error 1 - cos(pi/ppc).
    exact_peaks : bool
        Refine every extreme between samples (true extremes of the piecewise-linear-input
        response; no peak-picking error).
    backend : {"c", "scipy"}
        Filter implementation passed to run_bank.
    workers : int, optional
        Threads for long runs (the C kernel releases the GIL); default: the CPUs this process
        may use (capped by the environment variable DTDYN_THREADS; at most 8) when
        n_samples x n_freqs > 2e7, else 1.

    Returns
    -------
    SRS
        freqs_hz, maximax, positive (max y), negative (-min y), info.

    Raises
    ------
    ValueError
        Naming the argument: non-finite samples, dt <= 0, freqs_hz <= 0, damping_ratio outside
        [0, 1), unknown response or window, points_per_cycle <= 0.

    Warns
    -----
    SRSSamplingWarning
        When the peak-picking bound 1 - cos(pi f / fs_eff) (not with exact_peaks) or the
        band-limited bias bound 1 - sinc^2(f / fs) exceeds 5 % at the highest frequency
        (about fs / 10 and fs / 8).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> dt = 1e-4
    >>> t = np.arange(201) * dt
    >>> accel = np.where(t < 0.01, np.sin(np.pi * t / 0.01), 0.0)   # 10 ms half-sine, 1 g
    >>> srs = dd.shock_response_spectrum(accel, dt, [10.0, 100.0], exact_peaks=True)
    >>> bool(srs.maximax[1] > 1.5)           # near 1/T the response amplifies the pulse
    True
    """
    a, fs, f, zeta, ppc = _check_common(ground_acceleration, dt, freqs_hz, damping_ratio,
                                        response, points_per_cycle)
    if window not in WINDOWS:
        raise ValueError(f"window must be one of {WINDOWS}, got {window!r}")
    if not isinstance(exact_peaks, (bool, np.bool_)):
        raise ValueError(f"exact_peaks must be True or False, got {exact_peaks!r}")
    if backend not in ("c", "scipy"):
        raise ValueError(f"backend must be 'c' or 'scipy', got {backend!r}")
    result = _spectrum(a, fs, f, zeta, response, window, ppc, bool(exact_peaks), backend,
                       workers)
    _warn_sampling(f, fs, result.info["fs_effective"], result.info["peak_error_bound"],
                   result.info["bias_bound"], bool(exact_peaks))
    return result


def _spectrum(a, fs, f, zeta, response, window, ppc, exact_peaks, backend, workers) -> SRS:
    """The spectrum of checked inputs (shock_response_spectrum without its checks and warning)."""
    t0 = time.perf_counter()
    f_max = float(f.max())
    u = _upsample_factor(f_max, fs, ppc)
    if exact_peaks or window != "primary":
        u = max(u, _upsample_factor(f_max, fs, MIN_STATE_PPC))
    fs_e = u * fs
    Te = 1.0 / fs_e
    peak_err = np.zeros_like(f) if exact_peaks else peak_error_bound(f, fs_e)
    bias = bias_error_bound(f, fs)

    N = a.size
    # the record upsampled u times, and a block of filter outputs per worker
    cols = 1 + 2 * max(1, min(f.size, _BLOCK_BYTES // (8 * u * (N + 1))))
    validate.memory(f"shock_response_spectrum: the record ({N:,} samples at dt = {1.0 / fs:.6g} "
                    f"s) upsampled {u:,} times for freqs_hz (or 1 / periods) up to "
                    f"{f_max:.6g} Hz, {u * (N + 1):,} samples x {cols} values",
                    8 * u * (N + 1) * cols, "ask for lower freqs_hz (longer periods), fewer "
                    "points_per_cycle or a shorter record")
    e = _extended_input(a, u)
    J_end, j_N = u * N, u * (N + 1)
    s1, R = _poles_residues(f, zeta, response)
    sos = np.stack(coef.pair_sections("ramp", s1, R, Te), axis=-1)
    if backend == "c":
        _c_bank()  # compile or load once, before any threads
    blocks = _blocks(f.size, e.size)
    n_workers = _workers(workers, len(blocks), float(e.size) * f.size)

    def task(b):
        return _block_extremes(e, sos[b], s1[b], R[b], zeta, Te, J_end, j_N, window,
                               exact_peaks, backend)

    t1 = time.perf_counter()
    if n_workers > 1:
        with ThreadPoolExecutor(n_workers) as pool:
            parts = list(pool.map(task, blocks))
    else:
        parts = [task(b) for b in blocks]
    hi = np.concatenate([p[0] for p in parts])
    lo = np.concatenate([p[1] for p in parts])
    t2 = time.perf_counter()
    positive, negative = hi, -lo
    return SRS(f.copy(), np.maximum(positive, negative), positive, negative,
               info={"method": "ramp-invariant modal filters (ISO 18431-4 / Smallwood)",
                     "response": response, "damping_ratio": zeta, "window": window, "fs": fs,
                     "fs_effective": fs_e, "upsample": u, "exact_peaks": exact_peaks,
                     "n_samples": N, "peak_error_bound": peak_err, "bias_bound": bias,
                     "backend": "c" if backend == "c" and _c_bank() else "scipy.lfilter",
                     "workers": n_workers, "setup_time": t1 - t0, "run_time": t2 - t1})


def _warn_sampling(f, fs, fs_e, peak_err, bias, exact):
    i = int(np.argmax(f))
    if peak_err[i] <= WARN_ERROR and bias[i] <= WARN_ERROR:
        return
    n_bad = int(np.sum((peak_err > WARN_ERROR) | (bias > WARN_ERROR)))
    parts = [f"the record has {fs / f[i]:.3g} samples per cycle at {f[i]:g} Hz (fs = {fs:g} Hz; "
             f"{n_bad} of {f.size} frequencies exceed the 5 % error level of about 10 samples "
             "per cycle):"]
    if not exact and peak_err[i] > WARN_ERROR:
        at = "" if fs_e == fs else f", {fs_e / f[i]:.3g} after upsampling to {fs_e:g} Hz"
        parts.append(f"peaks picked at the samples can be low by up to 1 - cos(pi f/fs) = "
                     f"{100 * peak_err[i]:.3g} % at {f[i]:g} Hz (worst sampling phase of a "
                     f"sinusoidal response{at}; pass points_per_cycle or exact_peaks=True);")
    parts.append(f"if the record samples a band-limited signal, linear interpolation also "
                 f"attenuates its content at {f[i]:g} Hz by up to 1 - sinc^2(f/fs) = "
                 f"{100 * bias[i]:.3g} % (not reduced by upsampling or exact peaks)")
    warn(" ".join(parts), SRSSamplingWarning)


@public(renamed=RENAMED)
def sdof_response(ground_acceleration, dt, freqs_hz, damping_ratio=0.05,
                  response="absolute_acceleration", points_per_cycle=None, *, backend="c"):
    """Response histories at the (upsampled) samples t_0 .. t_{N-1}: ``(t, y)``, y (n_t, n_freqs).

    The same filters as :func:`shock_response_spectrum` (no extremes, no windows): for each
    natural frequency f, the response of z'' + 2 zeta omega z' + omega^2 z = -a(t)
    (omega = 2 pi f) chosen by ``response``.

    Parameters
    ----------
    ground_acceleration, dt, freqs_hz, damping_ratio, response, points_per_cycle
        As `shock_response_spectrum` (the old keywords ``accel``, ``freqs`` and ``damping``
        are deprecated).
    backend : {"c", "scipy"}
        Filter implementation passed to run_bank.

    Returns
    -------
    t : (n_t,) ndarray
    y : (n_t, len(freqs_hz)) ndarray

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> t, y = dd.sdof_response(np.ones(100), 1e-3, [5.0, 50.0])
    >>> y.shape
    (100, 2)
    """
    a, fs, f, zeta, ppc = _check_common(ground_acceleration, dt, freqs_hz, damping_ratio,
                                        response, points_per_cycle)
    u = _upsample_factor(float(f.max()), fs, ppc)
    validate.output_size(f"sdof_response (the record upsampled {u} times)", u * a.size,
                         1 + f.size)
    e = _extended_input(a, u)
    s1, R = _poles_residues(f, zeta, response)
    sos = np.stack(coef.pair_sections("ramp", s1, R, 1.0 / (u * fs)), axis=-1)
    y = np.empty((u * (a.size - 1) + 1, f.size))
    for b in _blocks(f.size, e.size):
        y[:, b] = _run(e[:, None], sos[b], backend)[u:u * a.size + 1]
    return np.arange(y.shape[0]) / (u * fs), y


# --- files ----------------------------------------------------------------------------------
def load_record(path, column: int | None = None) -> np.ndarray:
    """Samples from a .npy file (1-D, or 2-D: take ``column``, default the last) or a CSV/text
    file (one sample a row, or columns such as t, a: take ``column``; one header line is
    skipped). A ``column`` for a 1-D record is an error (there is nothing to choose).

    Parameters
    ----------
    path : str or Path
        .npy, .csv or text file.
    column : int, optional
        The column of a table.

    Returns
    -------
    (n,) ndarray

    Examples
    --------
    >>> import numpy as np, dtdyn as dd, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.npy"
    >>> np.save(path, np.array([[0.0, 1.0], [0.001, 2.0]]))   # columns t, a
    >>> dd.load_record(path)
    array([1., 2.])
    """
    p = Path(path)
    if p.suffix.lower() == ".npy":
        data = np.load(p, allow_pickle=False)
    else:
        try:
            data = np.loadtxt(p, delimiter=",", ndmin=2)
        except ValueError:
            data = np.loadtxt(p, delimiter=",", ndmin=2, skiprows=1)
        if data.ndim == 2 and data.shape[1] == 1:
            data = data[:, 0]
    data = np.asarray(data, dtype=float)
    if data.ndim == 2:
        col = -1 if column is None else column
        if not -data.shape[1] <= col < data.shape[1]:
            raise ValueError(f"column {col} is outside the {data.shape[1]} columns of {path}")
        data = data[:, col]
    elif column is not None:
        raise ValueError(f"column {column}: {path} holds a single column of samples")
    if data.ndim != 1:
        raise ValueError(f"{path}: expected a 1-D record or a table of columns, got shape "
                         f"{data.shape}")
    return data


# --- output ---------------------------------------------------------------------------------
def save_srs_csv(path, srs: SRS) -> None:
    """Columns freq_hz, maximax, positive, negative; written atomically."""
    path = Path(path)
    rows = np.column_stack([srs.freqs_hz, srs.maximax, srs.positive, srs.negative])
    head = "freq_hz,maximax,positive,negative"
    write_atomic(path, lambda fh: np.savetxt(fh, rows, delimiter=",", header=head, comments="",
                                              fmt="%.10g"))


def plot_srs(path, srs: SRS, title: str | None = None) -> None:
    """Maximax, positive and negative spectra on log-log axes (Agg canvas); saved atomically."""
    require("matplotlib", "plot", "plot_srs")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    fig = Figure(figsize=(7.0, 4.5), layout="constrained")
    canvas = FigureCanvasAgg(fig)
    fmt = path.suffix[1:].lower() or "png"
    if fmt not in canvas.get_supported_filetypes():
        raise ValueError(f"cannot plot to {str(path)!r}: unsupported format {fmt!r}, allowed: "
                         f"{', '.join(sorted(canvas.get_supported_filetypes()))}")
    ax = fig.add_subplot()
    for values, label, style in ((srs.maximax, "maximax", dict(lw=2.0, color="k")),
                                 (srs.positive, "positive", dict(lw=1.0, ls="--")),
                                 (srs.negative, "negative", dict(lw=1.0, ls=":"))):
        v = np.where(values > 0.0, values, np.nan)
        ax.loglog(srs.freqs_hz, v, label=label, **style)
    info = srs.info
    ax.set_xlabel("natural frequency [Hz]")
    ax.set_ylabel(info.get("response", "response").replace("_", " "))
    zeta = info.get("damping_ratio", float("nan"))
    ax.set_title(title or (f"SRS, damping ratio {zeta:g}, "
                           f"{info.get('window', '')} window"), fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    write_atomic(path, lambda fh: fig.savefig(fh, format=fmt, dpi=120))
