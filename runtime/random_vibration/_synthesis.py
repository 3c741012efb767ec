r"""Time histories synthesized from a specification: a stationary Gaussian record with a given
PSD (or cross-spectral matrix), and a shock whose shock response spectrum matches a target.

Random records: one FFT of twice the record's length
---------------------------------------------------
A record of ``n_samples`` samples at step dt is the first ``n_samples`` samples of

.. math::

    x_n = \operatorname{Re} \sum_{j=1}^{N/2-1} L_j \xi_j \sqrt{\Delta f}\,
          e^{2\pi i j n / N}, \qquad \Delta f = \frac{1}{N\,dt},\quad N \ge 2\,n_{samples},

with :math:`\xi_j` independent standard complex normal vectors (real and imaginary parts
N(0, 1)) and :math:`L_j L_j^H = S(f_j)`, the one-sided cross-spectral matrix at
:math:`f_j = j \Delta f` (a square root for one input; for several, the eigen factor
:math:`V \Lambda^{1/2}`, which also takes semidefinite matrices, coherence 1). Every sample is a
sum of independent Gaussians, so the record is exactly Gaussian, and its covariance is, exactly,

.. math::

    E[x_n x_{n+k}^H] = \Delta f \sum_j \operatorname{Re}\left(S(f_j) e^{-2\pi i f_j k\,dt}
    \right) = \sum_{m=-\infty}^{\infty} R\big((k + m N)\,dt\big)

by Poisson's summation formula, where :math:`R(\tau)` is the covariance of the continuous
process with PSD S (band-limited below the Nyquist frequency 1/(2 dt)). The term m = 0 is the
target; the others are the wrap-around of the FFT's period N dt. Because N >= 2 n_samples, every
lag |k| < n_samples inside the record has |k + mN| >= n_samples for m != 0: the record's
covariance is the target's up to the target's own correlation beyond the record's length. So
the record does not repeat, its start and end are no more correlated than the target's
process at that distance, and no window changes its PSD (an overlap-add of windowed segments
would smear the PSD by the window's spectrum and make the variance vary along the record). The
zero and Nyquist frequencies are left out (a zero-mean record). The PSD must be zero above the
Nyquist frequency: a table or sampled PSD reaching beyond it is an error.

Shocks: wavelets matched to a shock response spectrum
-----------------------------------------------------
The shock is a sum of wavelets (Smallwood; Irvine's wavelet synthesis)

.. math::

    a_m(t) = A_m \sin\!\left(\frac{2\pi f_m \tau}{N_m}\right) \sin(2\pi f_m \tau),
    \qquad \tau = t - t_m \in [0, N_m / (2 f_m)],

one per frequency of the target, N_m odd >= 3 half-sines of the envelope's carrier, t_m a
delay. Its velocity and displacement are, in closed form (c, d = 2 pi f_m (1 -+ 1/N_m)),

.. math::

    v_m = \frac{A_m}{2}\left(\frac{\sin c\tau}{c} - \frac{\sin d\tau}{d}\right), \qquad
    x_m = \frac{A_m}{2}\left(\frac{1 - \cos c\tau}{c^2} - \frac{1 - \cos d\tau}{d^2}\right),

and c T_m = (N_m - 1) pi, d T_m = (N_m + 1) pi are even multiples of pi for odd N_m: each
wavelet ends at zero velocity and zero displacement. The amplitudes are corrected,
:math:`A_m \leftarrow A_m (\text{target}/\text{SRS})^{1/2}`, the ratio taken as the geometric
mean over the frequencies of a grid four times finer than the target's that lie nearest f_m,
the SRS computed by `shock_response_spectrum` of the sampled record (linear between samples);
the square root damps the correction, which neighbouring wavelets share. The N_m and t_m of each
trial are drawn from the seeded generator; the best trial (smallest largest error in dB on the
fine grid) is kept.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft

from dtdyn._engine import validate
from dtdyn._engine.public import public
from dtdyn.random_vibration._psd import PsdTable
from dtdyn.random_vibration._response import _Spectrum

__all__ = ["random_time_history", "shock_time_history", "ShockTimeHistory"]

#: frequencies per block when the spectrum is evaluated and factored
BLOCK = 65536
#: the fine grid of the shock synthesis: points per interval of the target's frequencies
FINE = 4


def _count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} = {value!r}: must be an integer >= 1")
    return int(value)


def _samples(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2:
        raise ValueError(f"{name} = {value!r}: must be an integer >= 2")
    return int(value)


def _band_limits(psd, freqs_hz, nyquist: float):
    """(f_lo, f_hi) where the PSD may be non-zero; an error if it reaches above Nyquist."""
    tables = [psd] if isinstance(psd, PsdTable) else (
        list(psd) if isinstance(psd, (list, tuple)) and psd
        and all(isinstance(p, PsdTable) for p in psd) else [])
    if freqs_hz is not None:
        lo, hi, what = float(freqs_hz[0]), float(freqs_hz[-1]), "freqs_hz[-1]"
    elif tables:
        lo = min(float(t.freqs_hz[0]) for t in tables)
        hi = max(float(t.freqs_hz[-1]) for t in tables)
        what = "the PSD table's last breakpoint"
    else:
        return 0.0, nyquist
    if hi > nyquist * (1.0 + 1e-12):
        raise ValueError(f"psd: {what} is {hi:g} Hz, above the Nyquist frequency "
                         f"1/(2 dt) = {nyquist:g} Hz: take dt <= {0.5 / hi:.6g} s")
    return lo, hi


@public
def random_time_history(psd, dt, n_samples, *, freqs_hz=None, seed=None) -> np.ndarray:
    """A stationary Gaussian record with a given one-sided PSD or cross-spectral matrix,
    seeded, of any length without periodic repetition (module docstring: one FFT of at least
    twice the record's length, whose wrap-around falls beyond the record).

    Parameters
    ----------
    psd : PsdTable, sequence of PsdTable, callable, float or array_like
        The one-sided PSD, (unit)^2/Hz, as `random_response` takes it: a table (`psd_table`),
        one table per input (independent inputs), a callable of the frequency in Hz (returning
        shape ``(n,)``, ``(n, n_in)`` or ``(n, n_in, n_in)``), or samples at ``freqs_hz``:
        a number (white over ``freqs_hz[0] .. freqs_hz[-1]``), ``(n_freq,)``,
        ``(n_freq, n_in)`` or the complex Hermitian cross-spectral matrix
        ``(n_freq, n_in, n_in)`` with S_ij = E[X_i X_j^*] (correlated inputs; checked positive
        semidefinite). Between samples: log-log auto-spectra, linear coherency; zero outside
        ``freqs_hz`` (and outside a table's breakpoints).
    dt : float
        Sample step, s; the PSD must be zero above the Nyquist frequency 1 / (2 dt).
    n_samples : int
        Samples of the record, at t_k = k dt, k = 0 .. n_samples - 1.
    freqs_hz : array_like, optional
        The frequencies (Hz, increasing) of sampled ``psd``, or the band of a callable;
        required for a number or samples.
    seed : int, numpy.random.Generator or None
        As `numpy.random.default_rng` takes it; the same seed gives the same record.

    Returns
    -------
    ndarray
        Shape ``(n_samples,)`` for one input, ``(n_samples, n_in)`` for several.

    Notes
    -----
    The covariance of the record equals the target's, sum_m R((k + m N) dt) with N >= 2
    n_samples (Poisson summation; module docstring), so its variance is the PSD's integral
    (a table's ``grms**2``) up to the frequency step 1 / (N dt), and the Welch PSD of the record
    scatters about the target as chi-square with 2 x (segments) degrees of freedom. Memory: about
    48 N bytes per input (the spectrum, the transform and its output), checked before it starts.

    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration import psd_table
    >>> from dtdyn.random_vibration._synthesis import random_time_history
    >>> table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
    >>> x = random_time_history(table, 1e-4, 200_000, seed=1)
    >>> x.shape, bool(abs(x.std() / table.grms - 1) < 0.02)
    ((200000,), True)
    """
    dt = validate.positive_scalar("dt", dt)
    n = _samples("n_samples", n_samples)
    nyquist = 0.5 / dt
    f_user = None
    if freqs_hz is not None:
        f_user = validate.real_array("freqs_hz", freqs_hz, "an array of frequencies (Hz)")
        if (f_user.ndim != 1 or f_user.size < 2 or not np.all(np.isfinite(f_user))
                or np.any(f_user < 0) or np.any(np.diff(f_user) <= 0)):
            raise ValueError(f"freqs_hz = {freqs_hz!r}: must be a 1-D array of at least two "
                             "finite, increasing frequencies >= 0 (Hz)")
    elif not callable(psd) and not (isinstance(psd, (list, tuple)) and psd
                                    and all(callable(p) for p in psd)):
        raise ValueError("freqs_hz is required with a PSD given as a number or as samples: "
                         "the frequencies (Hz) of the samples")
    lo, hi = _band_limits(psd, f_user, nyquist)
    n_fft = scipy.fft.next_fast_len(2 * n, real=True)
    df = 1.0 / (n_fft * dt)
    probe = f_user if f_user is not None else np.array([min(1.0, nyquist)])
    spectrum = _Spectrum("psd", psd, probe)
    rng = np.random.default_rng(seed)
    n_in = spectrum.n_in
    j_lo = max(1, int(np.ceil(lo / df)))
    j_hi = min(n_fft // 2 - 1, int(np.floor(hi / df)))
    # the spectrum (N/2 complex), the transform's output (N real) and its working copy, per
    # input: about 6 n_fft bytes x 8 (n_fft >= 2 n_samples)
    validate.memory(f"random_time_history of {n:,} samples x {n_in} inputs", 48 * n_fft * n_in,
                    "synthesize shorter records (several seeds) and join their statistics")
    Z = np.zeros((n_fft // 2 + 1, n_in), dtype=complex)
    for start in range(j_lo, j_hi + 1, BLOCK):
        j = np.arange(start, min(start + BLOCK, j_hi + 1))
        S = spectrum(j * df)
        xi = rng.standard_normal((j.size, n_in, 2)) @ np.array([1.0, 1j])
        if n_in == 1:
            Z[j, 0] = np.sqrt(np.maximum(S[:, 0, 0].real, 0.0)) * xi[:, 0]
        else:
            lam, V = np.linalg.eigh(S)
            Z[j] = np.einsum("fij,fj,fj->fi", V, np.sqrt(np.maximum(lam, 0.0)), xi)
    # irfft: x_n = (1/N) (Z_0 + 2 sum_j Re(Z_j e^{2 pi i j n / N}) + ...), so Z_j N sqrt(df) / 2
    Z *= 0.5 * n_fft * np.sqrt(df)
    x = scipy.fft.irfft(Z, n=n_fft, axis=0)[:n]
    return x[:, 0].copy() if n_in == 1 else x


# ---------------------------------------------------------------------------------------------
# shocks


@dataclass
class ShockTimeHistory:
    """A synthesized shock and how well its shock response spectrum meets the target
    (`shock_time_history`).

    Attributes
    ----------
    t : (n,) ndarray
        Times t_k = k dt, s.
    a, v, x : (n,) ndarray
        Acceleration (the record; unit of the target), and the exact velocity and displacement
        of the sum of wavelets at the samples (unit * s, unit * s^2); each ends at 0.
    freqs_hz : (n_f,) ndarray
        The target's frequencies, Hz (one wavelet each).
    target, srs : (n_f,) ndarray
        The target and the maximax SRS of ``a`` (`shock_response_spectrum`).
    error_db : (n_f,) ndarray
        20 log10(srs / target).
    wavelets : dict
        ``freqs_hz``, ``half_sines`` (N_m), ``delay`` (t_m, s), ``amplitude`` (A_m).
    info : dict
        ``max_error_db`` on the target's frequencies, ``max_error_db_fine`` on the grid
        ``FINE`` times finer the amplitudes were corrected on, ``iterations``, ``trials``,
        ``damping_ratio``, ``converged``.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> f = np.geomspace(100.0, 2000.0, 27)
    >>> s = dd.shock_time_history(np.full(27, 50.0), f, 2e-5, seed=3)
    >>> s.a.shape == s.t.shape, bool(np.abs(s.error_db).max() < 1.5)
    (True, True)
    """

    t: np.ndarray
    a: np.ndarray
    v: np.ndarray
    x: np.ndarray
    freqs_hz: np.ndarray
    target: np.ndarray
    srs: np.ndarray
    error_db: np.ndarray
    wavelets: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"ShockTimeHistory({self.t.size} samples, {self.freqs_hz.size} wavelets, "
                f"max error {self.info.get('max_error_db', np.nan):.2f} dB)")


def _wavelet_sum(t, f, half_sines, delay, amplitude, derivative: int = 0) -> np.ndarray:
    """The sum of wavelets (derivative 0), its velocity (-1) or displacement (-2), exact."""
    out = np.zeros_like(t)
    for fm, nm, tm, am in zip(f, half_sines, delay, amplitude):
        end = nm / (2.0 * fm)
        i0 = int(np.searchsorted(t, tm, side="left"))
        i1 = int(np.searchsorted(t, tm + end, side="right"))
        tau = t[i0:i1] - tm
        c, d = 2.0 * np.pi * fm * (1.0 - 1.0 / nm), 2.0 * np.pi * fm * (1.0 + 1.0 / nm)
        if derivative == 0:
            out[i0:i1] += am * np.sin(np.pi * 2.0 * fm * tau / nm) * np.sin(2.0 * np.pi * fm * tau)
        elif derivative == -1:
            out[i0:i1] += 0.5 * am * (np.sin(c * tau) / c - np.sin(d * tau) / d)
        else:
            out[i0:i1] += 0.5 * am * ((1.0 - np.cos(c * tau)) / c**2
                                      - (1.0 - np.cos(d * tau)) / d**2)
    return out


@public
def shock_time_history(srs, freqs_hz, dt, *, damping_ratio=0.05, duration=None,
                       half_sines=(21, 61), seed=None, tolerance_db=1.0, max_iter=100,
                       trials=8) -> ShockTimeHistory:
    """A shock (acceleration) whose maximax shock response spectrum matches ``srs``: a sum of
    wavelets, one per frequency, each ending at zero velocity and displacement, amplitudes
    corrected iteratively (module docstring).

    Parameters
    ----------
    srs : array_like
        The target maximax absolute-acceleration SRS at ``freqs_hz`` (any unit, > 0), e.g. a
        specification's breakpoints interpolated on log-log axes.
    freqs_hz : array_like
        Increasing frequencies, Hz, > 0; one wavelet each (1/12 octave apart or closer is
        advisable: the SRS between them is checked on a grid four times finer).
    dt : float
        Sample step, s; at least 10 samples per cycle of the highest frequency
        (dt <= 1 / (10 freqs_hz[-1])) so that the SRS's sampling bounds stay small.
    damping_ratio : float
        The SRS's damping ratio (0.05: Q = 10).
    duration : float, optional
        Length of the record, s; default 20 cycles of the lowest frequency. Each wavelet lies
        inside it.
    half_sines : (int, int)
        The range the wavelets' N_m (odd) are drawn from; fewer where a wavelet would not
        fit in ``duration``. More half-sines make each wavelet narrower in frequency.
    seed : int, numpy.random.Generator or None
        Draws each trial's N_m and delays.
    tolerance_db : float
        Stop when the SRS is within +-``tolerance_db`` of the target on the fine grid.
    max_iter : int
        Amplitude corrections per trial.
    trials : int
        Random draws of N_m and delays tried, at most; the best is returned.

    Returns
    -------
    ShockTimeHistory
        ``t``, ``a``, ``v``, ``x``, the target, the achieved ``srs`` and ``error_db``, the
        wavelets, ``info["max_error_db"]`` and ``info["converged"]``.

    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration._synthesis import shock_time_history
    >>> f = np.geomspace(100.0, 2000.0, 53)                     # 1/12 octave
    >>> target = np.minimum(f / 100.0, 5.0) ** 2 * 10.0         # +12 dB/octave, then flat
    >>> s = shock_time_history(target, f, 2e-5, seed=1)
    >>> bool(s.info["max_error_db"] < 1.5), bool(abs(s.v[-1]) < 1e-9 * abs(s.v).max())
    (True, True)
    """
    from dtdyn.modal._srs import shock_response_spectrum

    f = validate.real_array("freqs_hz", freqs_hz, "an array of frequencies (Hz)")
    if (f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f)) or np.any(f <= 0)
            or np.any(np.diff(f) <= 0)):
        raise ValueError(f"freqs_hz = {freqs_hz!r}: must be a 1-D array of at least two "
                         "finite, increasing frequencies > 0 (Hz)")
    target = validate.real_array("srs", srs, "an array of SRS values")
    if target.shape != f.shape or not np.all(np.isfinite(target)) or np.any(target <= 0):
        raise ValueError(f"srs has shape {np.shape(srs)}, expected {f.shape} finite values "
                         "> 0: one per frequency of freqs_hz")
    dt = validate.positive_scalar("dt", dt)
    if dt > 1.0 / (10.0 * f[-1]) * (1.0 + 1e-12):
        raise ValueError(f"dt = {dt!r}: fewer than 10 samples per cycle of freqs_hz[-1] = "
                         f"{f[-1]:g} Hz; take dt <= {1.0 / (10.0 * f[-1]):.6g} s")
    zeta = validate.positive_scalar("damping_ratio", damping_ratio)
    if zeta >= 1.0:
        raise ValueError(f"damping_ratio = {damping_ratio!r}: must be in (0, 1)")
    duration = 20.0 / f[0] if duration is None else validate.positive_scalar("duration",
                                                                             duration)
    if duration < 1.5 / f[0]:
        raise ValueError(f"duration = {duration!r}: shorter than the shortest wavelet of "
                         f"freqs_hz[0] = {f[0]:g} Hz (3 half-sines, {1.5 / f[0]:.4g} s)")
    try:
        n_lo, n_hi = (int(v) for v in half_sines)
    except (TypeError, ValueError):
        raise ValueError(f"half_sines = {half_sines!r}: give two integers (low, high)") from None
    if not 3 <= n_lo <= n_hi:
        raise ValueError(f"half_sines = {half_sines!r}: need 3 <= low <= high")
    tolerance_db = validate.positive_scalar("tolerance_db", tolerance_db)
    max_iter, trials = _count("max_iter", max_iter), _count("trials", trials)
    rng = np.random.default_rng(seed)

    t = np.arange(int(np.floor(duration / dt + 1e-9)) + 1) * dt
    log_f = np.log(f)
    fine = np.exp(np.interp(np.linspace(0.0, f.size - 1.0, FINE * (f.size - 1) + 1),
                            np.arange(f.size), log_f))
    fine_target = np.exp(np.interp(np.log(fine), log_f, np.log(target)))
    owner = np.abs(np.log(fine)[:, None] - log_f[None, :]).argmin(axis=1)   # nearest wavelet
    count = np.bincount(owner, minlength=f.size)

    def spectrum(a, freqs):
        return shock_response_spectrum(a, dt, freqs, zeta).maximax

    best = None
    iterations = 0
    for _ in range(int(trials)):
        longest = np.maximum(np.floor((2.0 * f * t[-1] - 1.0) / 2.0) * 2.0 + 1.0, 3.0)
        n_m = 2 * rng.integers(n_lo // 2, n_hi // 2 + 1, f.size) + 1
        n_m = np.minimum(np.maximum(n_m, 3), longest).astype(int)
        length = n_m / (2.0 * f)
        delay = rng.uniform(0.0, 1.0, f.size) * np.maximum(t[-1] - length, 0.0)
        amplitude = target / 10.0 * rng.choice([-1.0, 1.0], f.size)
        for _ in range(int(max_iter)):
            iterations += 1
            a = _wavelet_sum(t, f, n_m, delay, amplitude)
            ratio = fine_target / spectrum(a, fine)
            worst = float(np.abs(20.0 * np.log10(ratio)).max())
            if best is None or worst < best[0]:
                best = (worst, n_m.copy(), delay.copy(), amplitude.copy())
            if worst <= tolerance_db:
                break
            amplitude = amplitude * np.exp(0.5 * np.bincount(owner, np.log(ratio),
                                                             minlength=f.size) / count)
        if best[0] <= tolerance_db:
            break

    worst, n_m, delay, amplitude = best
    a = _wavelet_sum(t, f, n_m, delay, amplitude)
    achieved = spectrum(a, f)
    error = 20.0 * np.log10(achieved / target)
    return ShockTimeHistory(
        t=t, a=a, v=_wavelet_sum(t, f, n_m, delay, amplitude, -1),
        x=_wavelet_sum(t, f, n_m, delay, amplitude, -2), freqs_hz=f, target=target,
        srs=achieved, error_db=error,
        wavelets={"freqs_hz": f, "half_sines": n_m, "delay": delay, "amplitude": amplitude},
        info={"max_error_db": float(np.abs(error).max()), "max_error_db_fine": worst,
              "iterations": iterations, "trials": int(trials), "damping_ratio": zeta,
              "converged": bool(worst <= tolerance_db)})
