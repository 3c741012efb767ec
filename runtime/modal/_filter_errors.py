"""Frequency-domain errors of the modal digital filters.

The bank of `dtdyn.modal._filters` replaces the continuous receptance
H(s) = sum_r R_r/(s - s_r) + conj(R_r)/(s - conj(s_r)) (+ real poles) by a sum of digital
sections. This module evaluates what that replacement does to the frequency response, and what
dropping modes does. Notation: T = 1/fs, omega = 2 pi f, omega_s = 2 pi fs, x = f/fs,
sinc(u) = sin(pi u)/(pi u) (numpy.sinc), z = e^{j omega T}.

Where the errors come from
--------------------------
Each invariant rebuilds the continuous force from its samples x_n with a kernel, runs it through
the continuous system and samples the response at t_n = n T. By Poisson's summation formula the
discrete frequency response of the section of one modal term c/(s - p) is then an alias sum.
Write Hq(s) = sum_terms c/(s - p) + D for the continuous function the bank discretises, where
the terms are every pole with its residue for the asked quantity (both members of a conjugate
pair: s_r R_r^q and conj) and D the direct term of `modal_filters.sections` (0 for displacement).
For displacement and velocity Hq is the truncated modal sum `ModalModel.frequency_response`; for
acceleration it lacks the term j omega sum_r 2 Re R_r that the bank drops (zero for a complete
mode set of a mechanical system, part of the truncation error otherwise).

Ramp invariant (first-order hold: x linear between samples, the triangle kernel on [-T, T] whose
Fourier transform is T sinc^2(f/fs); the response g = h * triangle is continuous, so Poisson's
formula holds without a jump term):

    H_ramp(e^{j omega T}) = sum over all integers k of  Hq(j(omega + k omega_s)) sinc^2(x + k).

This is an identity, not an approximation: every filter output sample equals the exact
response to the piecewise-linear force. The pole terms converge absolutely (|term_k| ~ 1/k^3),
the direct term passes exactly (sum_k sinc^2(x + k) = 1), and since
sinc^2(x + k) = sin^2(pi x)/(pi (x + k))^2 the k != 0 terms are O(x^2 |Hq(j omega_s)|/k^2):
at low f/fs

    H_ramp(e^{j omega T}) ~ Hq(j omega) sinc^2(f/fs)          (`ramp_bias`),

a real, positive, system-independent factor (no phase error) that is 1 - (pi x)^2/3 + ... at low
frequency and 0 at f = fs (there the k = -1 alias takes over: the discrete response is
periodic in fs and equals Hq(0) at f = fs as at f = 0).

Step invariant (zero-order hold: x held over [t_n, t_{n+1}), the kernel 1 on [0, T], transform
T e^{-j pi x} sinc(x)):

    H_step(e^{j omega T}) = D + sum_k (pole part of Hq)(j(omega + k omega_s))
                                     * e^{-j pi (x + k)} sinc(x + k)

with e^{-j pi (x + k)} = (-1)^k e^{-j pi x}. The k = 0 term is Hq(j omega) sinc(x) e^{-j pi x}:
a half-sample delay (phase -pi f/fs relative to the continuous FRF) and a magnitude droop
sinc(x); the aliases add a phase error bounded by arcsin(|aliases| / |Hq(j omega) sinc(x)|).
(The bank passes D x_n directly; the held force's own alias sum would give the average
D (1 + z^-1)/2 at the jumps, so D is by convention outside the sum.)

Impulse invariant (T-scaled, y_n = e^{sT} y_{n-1} + T c x_n, i.e. T h(nT) with h(0) = h(0+)):

    H_impulse(e^{j omega T}) = D + (T/2) h(0+) + sum_k (pole part of Hq)(j(omega + k omega_s))

(symmetric partial sums; h(0+) = sum_terms c, 0 for displacement with every mode). No kernel
damps the aliases: the error depends on how large Hq is near omega_s - omega relative to Hq at
omega, i.e. on the system, and grows toward fs/2 where the first alias Hq(j(omega - omega_s)) is
as large as Hq(j omega) itself.

`alias_sum` evaluates these sums term by term for |k| <= n_alias, adds the closed-form
(Hurwitz zeta) tails of the first terms of the large-s expansion of each pole term, and returns
a rigorous bound on what remains, so that the tests can compare them with
`discrete_frequency_response`, which evaluates the bank's own sections.

Truncation
----------
`truncation_error` compares the modal sum of the selected modes with the full one (every mode),
band-wise and at omega = 0 (the static residual flexibility left out).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dtdyn._engine import validate
from dtdyn.modal._model import ModalModel, modal_model, quantity_name
from dtdyn.modal._filters import quantity_residues, sections

__all__ = ["INVARIANTS", "discrete_frequency_response", "continuous_frequency_response",
           "ramp_bias", "alias_sum", "AliasSum", "truncation_error", "TruncationError"]

INVARIANTS = ("step", "impulse", "ramp")


def _freqs(freqs_hz) -> np.ndarray:
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if f.ndim != 1 or f.size == 0:
        raise ValueError(f"freqs_hz must be a non-empty 1-D sequence, got shape {f.shape}")
    if not np.isfinite(f).all():
        raise ValueError(f"freqs_hz[{int(np.flatnonzero(~np.isfinite(f))[0])}] is not finite")
    return f


def _invariant(invariant: str) -> str:
    if invariant not in INVARIANTS:
        raise ValueError(f"invariant must be one of {INVARIANTS}, got {invariant!r}")
    return invariant


def _quantity(quantity: str) -> str:
    return quantity_name(quantity)


def discrete_frequency_response(model: ModalModel, dt: float, freqs_hz, invariant: str,
                                quantity: str = "x") -> np.ndarray:
    """The bank's frequency response H(e^{j 2 pi f / fs}), fs = 1/dt: complex (n_f, n_out, n_in).

    The sum over the sections of `modal_filters.sections(model, fs, invariant, quantity)` of
    (b0 + b1 w + b2 w^2)/(1 + a1 w + a2 w^2), w = e^{-j 2 pi f / fs}, plus the direct term: the
    transfer function that `run_bank` applies, periodic in f with period fs. At an undamped
    pole the result is (nearly) infinite. Conditioning: the denominator of a mode with
    |s_r| T << 1 is ~ (|s_r| T)^2 against coefficients of size 1, so round-off gives a relative
    error ~ 1e-16 / (|s_r| T)^2 near that mode, the same sensitivity the bank has to its
    rounded coefficients.

    Parameters
    ----------
    model : ModalModel
    dt : float
        Sample step, s.
    freqs_hz : array_like
        Frequencies, Hz.
    invariant : {"ramp", "step", "impulse"}
    quantity : {"x", "v", "a"}

    Returns
    -------
    (n_f, n_out, n_in) complex ndarray

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.modal_model(np.eye(1), 0.2 * np.eye(1), 4.0 * np.eye(1))
    >>> H = dd.discrete_frequency_response(model, 0.01, [0.0], "ramp")
    >>> round(float(H[0, 0, 0].real), 10)   # the static flexibility 1/k
    0.25
    """
    fs = 1.0 / validate.positive_scalar("dt", dt)
    f = _freqs(freqs_hz)
    sos, in_col, out_col, direct = sections(model, fs, _invariant(invariant), _quantity(quantity))
    n_out, n_in = model.outputs.size, model.force_dofs.size
    w = np.exp(-2j * np.pi * f / fs)[:, None]
    b0, b1, b2, a1, a2 = (sos[:, j][None, :] for j in range(5))
    with np.errstate(divide="ignore", invalid="ignore"):
        per_section = (b0 + w * (b1 + w * b2)) / (1.0 + w * (a1 + w * a2))  # (n_f, n_sec)
    scatter = np.zeros((len(sos), n_out * n_in))
    scatter[np.arange(len(sos)), out_col * n_in + in_col] = 1.0
    H = (per_section @ scatter).reshape(f.size, n_out, n_in)
    return H + direct[None, :, :]


def continuous_frequency_response(model: ModalModel, freqs_hz,
                                  quantity: str = "x") -> np.ndarray:
    """The continuous truncated modal sum at s = j 2 pi f: complex (n_f, n_out, n_in).

    `ModalModel.frequency_response(2 pi f, quantity)`; see the module docstring for how it
    differs from the bank's target for acceleration with a truncated mode set.

    Parameters
    ----------
    model : ModalModel
    freqs_hz : array_like
        Frequencies, Hz.
    quantity : {"x", "v", "a"}

    Returns
    -------
    (n_f, n_out, n_in) complex ndarray

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.modal_model(np.eye(1), 0.2 * np.eye(1), 4.0 * np.eye(1))
    >>> round(float(dd.continuous_frequency_response(model, [0.0])[0, 0, 0].real), 12)
    0.25
    """
    return model.frequency_response(2.0 * np.pi * _freqs(freqs_hz), _quantity(quantity))


def ramp_bias(freqs_hz, dt: float) -> np.ndarray:
    """(sin(pi f/fs)/(pi f/fs))^2 = numpy.sinc(f/fs)^2, fs = 1/dt: the ramp invariant's
    input-spectrum factor (real, zero phase, system independent, 1 at f = 0 and 0 at f = fs).

    Parameters
    ----------
    freqs_hz : array_like
        Frequencies, Hz.
    dt : float
        Sample step, s.

    Returns
    -------
    ndarray

    Examples
    --------
    >>> import dtdyn as dd
    >>> [round(float(b), 4) for b in dd.ramp_bias([0.0, 50.0, 100.0], 0.01)]
    [1.0, 0.4053, 0.0]
    """
    fs = 1.0 / validate.positive_scalar("dt", dt)
    return np.sinc(_freqs(freqs_hz) / fs) ** 2


def _pole_terms(model: ModalModel, quantity: str):
    """(poles, coefficients (n_terms, n_out, n_in), direct): Hq(s) = sum c/(s - p) + direct,
    both members of every conjugate pair listed."""
    Rq, direct = quantity_residues(model, quantity)
    osc = model.oscillatory
    poles = np.concatenate([model.poles, np.conj(model.poles[osc])])
    coeffs = np.concatenate([Rq, np.conj(Rq[osc])], axis=0)
    return poles, coeffs, direct


@dataclass(frozen=True, eq=False)
class AliasSum:
    """Result of `alias_sum`, arrays of shape (n_f, n_out, n_in).

    ``truncated``: the plain sum over |k| <= n_alias (plus the direct and, for the impulse
    invariant, the (T/2) h(0+) terms); ``tail``: the omitted |k| > n_alias part of the first
    ``n_moments`` terms of the large-s expansion, summed in closed form; ``value`` =
    truncated + tail; ``tail_bound``: a rigorous bound on |value - infinite sum| (the rest of
    the omitted terms; round-off not included). |truncated - infinite sum| <= |tail| +
    tail_bound.
    """

    value: np.ndarray
    truncated: np.ndarray
    tail: np.ndarray
    tail_bound: np.ndarray
    n_alias: int
    n_moments: int


#: (kappa(x), q): |kernel(x + k)| <= kappa / |x + k|^q for k != 0
def _kernel_decay(invariant, x):
    if invariant == "ramp":
        return np.sin(np.pi * x) ** 2 / np.pi**2, 2
    if invariant == "step":
        return np.abs(np.sin(np.pi * x)) / np.pi, 1
    return np.ones_like(x), 0


def _power_tail(invariant, n, x, K):
    """S_n(x) = sum over |k| > K of kernel(x + k) / (x + k)^n, n >= 1, in closed form
    (Hurwitz zeta, digamma; symmetric pairing of k and -k). The step kernel is not alternating:
    (-1)^k e^{-j pi x} sinc(x + k) = e^{-j pi x} sin(pi x) / (pi (x + k))."""
    from scipy.special import digamma, zeta

    def Z(m):  # sum_{|k|>K} 1/(x + k)^m, m >= 1 (symmetric for m = 1)
        if m == 1:
            return digamma(K + 1 - x) - digamma(K + 1 + x)
        return zeta(m, K + 1 + x) + (-1) ** m * zeta(m, K + 1 - x)

    if invariant == "ramp":
        return np.sin(np.pi * x) ** 2 / np.pi**2 * Z(n + 2)
    if invariant == "step":
        return np.exp(-1j * np.pi * x) * np.sin(np.pi * x) / np.pi * Z(n + 1)
    return Z(n)


def alias_sum(model: ModalModel, dt: float, freqs_hz, invariant: str,
              quantity: str = "x", n_alias: int = 2000, n_moments: int = 3,
              chunk: int = 4096) -> AliasSum:
    """The Poisson alias sum of the module docstring over all k, with a bound on its error.

    Parameters
    ----------
    model, dt, freqs_hz, invariant, quantity
        As `discrete_frequency_response`, which the infinite sum equals.
    n_alias : int
        Aliases summed term by term: k = -n_alias..n_alias (symmetric). Needs
        (n_alias - |f/fs|) fs > max |s_r| / (2 pi).
    n_moments : int
        Terms of the large-s expansion c/(s - p) = sum_{j < m} c p^j / s^{j+1}
        + c p^m / (s^m (s - p)) whose |k| > n_alias tails are added in closed form: the moments
        mu_j = sum over the pole terms of c p^j multiply sum_{|k|>n_alias} kernel(x + k) /
        (j omega_s (x + k))^{j+1}, a Hurwitz zeta sum (a digamma difference for the impulse
        invariant's j = 0, summed symmetrically). 0 gives the plain truncation (allowed for ramp
        and step; the impulse invariant's terms decay only like 1/k, so it needs >= 1).
    chunk : int
        Aliases evaluated at once (memory: n_f x chunk complex).

    Returns
    -------
    AliasSum
        ``tail_bound`` bounds the remainders c p^m / (s^m (s - p)) kernel over |k| > n_alias:
        with x = f/fs, U = n_alias - |x|, P = |p|, |s| = omega_s |x + k| >= omega_s U on the
        omitted aliases, |kernel| <= kappa / |x + k|^q (ramp: kappa = sin^2(pi x)/pi^2, q = 2;
        step: kappa = |sin(pi x)|/pi, q = 1; impulse: 1, 0), and each side's sum of the
        decreasing terms bounded by the integral from U,

            |omitted remainder| <= sum over pole terms of
                2 kappa |c| P^m / (omega_s^m (omega_s - P/U) (m + q) U^(m + q)),

        i.e. O(n_alias^-(m + q)). It takes no credit for the cancellations inside a conjugate
        pair, so it is pessimistic.
    """
    fs = 1.0 / validate.positive_scalar("dt", dt)
    f = _freqs(freqs_hz)
    invariant, quantity = _invariant(invariant), _quantity(quantity)
    n_alias, n_moments = int(n_alias), int(n_moments)
    if n_alias < 1:
        raise ValueError(f"n_alias must be >= 1, got {n_alias}")
    kappa, q = _kernel_decay(invariant, f / fs)
    if n_moments < 0 or n_moments + q < 1:
        raise ValueError(f"n_moments must be >= {max(0, 1 - q)} for the {invariant} invariant, "
                         f"got {n_moments}")
    poles, coeffs, direct = _pole_terms(model, quantity)
    ws = 2.0 * np.pi * fs
    x = f / fs
    U = n_alias - np.abs(x)
    P = np.abs(poles)
    if np.any(U <= 0) or np.any(U[:, None] * ws <= P[None, :]):
        raise ValueError(f"n_alias = {n_alias} is too small: the omitted aliases must lie beyond "
                         f"every pole (max |s_r| = {P.max():.4g} rad/s, omega_s = {ws:.4g} rad/s,"
                         f" max |f/fs| = {np.abs(x).max():.4g})")

    ks = np.arange(-n_alias, n_alias + 1)
    per_pole = np.zeros((f.size, poles.size), dtype=complex)
    for start in range(0, ks.size, chunk):
        k = ks[start:start + chunk][None, :]
        u = x[:, None] + k                                     # (n_f, nk)
        # sin(pi (x + k)) = (-1)^k sin(pi x) exactly: evaluating sin at large arguments would
        # lose ~ eps |x + k| to argument reduction
        with np.errstate(divide="ignore", invalid="ignore"):
            if invariant == "ramp":       # sinc^2(x + k)
                kern = np.where(u == 0, 1.0, (np.sin(np.pi * x)[:, None] / (np.pi * u)) ** 2)
            elif invariant == "step":     # e^{-j pi (x + k)} sinc(x + k)
                kern = np.where(u == 0, 1.0, (np.exp(-1j * np.pi * x) * np.sin(np.pi * x)
                                              / np.pi)[:, None] / u)
            else:
                kern = np.ones(u.shape)
        jw = 1j * ws * u
        for r, p in enumerate(poles):
            per_pole[:, r] += np.sum(kern / (jw - p), axis=1)
    truncated = np.einsum("fr,roi->foi", per_pole, coeffs) + direct[None, :, :]
    if invariant == "impulse":
        truncated = truncated + 0.5 / fs * np.sum(coeffs, axis=0)[None, :, :]   # (T/2) h(0+)

    tail = np.zeros_like(truncated)
    for j in range(n_moments):
        mu = np.einsum("r,roi->oi", poles**j, coeffs)
        S = _power_tail(invariant, j + 1, x, n_alias) / (1j * ws) ** (j + 1)
        tail += S[:, None, None] * mu[None, :, :]

    m = n_moments
    per = (2.0 * kappa[:, None] * P[None, :] ** m
           / (ws**m * (ws - P[None, :] / U[:, None]) * (m + q) * U[:, None] ** (m + q)))
    bound = np.einsum("fr,roi->foi", per, np.abs(coeffs))
    return AliasSum(truncated + tail, truncated, tail, bound, n_alias, n_moments)


@dataclass(frozen=True, eq=False)
class TruncationError:
    """Error of the modal sum of the kept modes against the full modal sum (every mode).

    Attributes
    ----------
    max_relative : float
        max over the band and the (output, input) pairs of |H_full - H_kept| / |H_full|
        (frequencies where H_full is not finite or zero, e.g. at an undamped pole, skipped).
    at_hz : float
        Frequency of that maximum.
    peak_relative : float
        max over the pairs of (max over the band |H_full - H_kept|) / (max over the band |H_full|).
    static_residual : float ndarray (n_out, n_in)
        Displacement H_full(0) - H_kept(0), the static flexibility of the dropped modes (real
        part; the imaginary part is round-off). The velocity and acceleration FRFs vanish at
        omega = 0, so this is reported for displacement whatever ``quantity``. H_full(0) = K^-1
        restricted to the outputs and inputs.
    static_relative : float
        max over the pairs of |static_residual| / |H_full(0)| (pairs with H_full(0) = 0 skipped).
    kept, n_modes : kept mode indices (sorted by frequency) and the total number of modes.
    skipped : int
        Number of (frequency, pair) points skipped in ``max_relative``.
    """

    max_relative: float
    at_hz: float
    peak_relative: float
    static_residual: np.ndarray
    static_relative: float
    kept: tuple
    n_modes: int
    quantity: str
    skipped: int = 0

    def as_dict(self) -> dict:
        return {"max_relative": self.max_relative, "at_hz": self.at_hz,
                "peak_relative": self.peak_relative,
                "static_residual": self.static_residual.tolist(),
                "static_relative": self.static_relative, "kept": list(self.kept),
                "n_modes": self.n_modes, "quantity": self.quantity, "skipped": self.skipped}


def truncation_error(M, C, K, force_dofs, outputs, modes, freqs_hz,
                     quantity: str = "x") -> TruncationError:
    """The FRF error of keeping only ``modes``: H_full - H_kept relative to H_full.

    Parameters
    ----------
    M, C, K : (n, n) array_like
        As `modal.modal_model`.
    force_dofs, outputs : sequence of int
        Force and response DOFs.
    modes : sequence of int
        Kept modes (indices into the modes sorted by |s_r|, as `ModalModel.select`).
    freqs_hz : array_like
        The band, Hz.
    quantity : {"displacement", "velocity", "acceleration"}
        FRF compared over the band (continuous modal sums, `continuous_frequency_response`).

    Returns
    -------
    TruncationError
        Exactly zero errors when ``modes`` holds every mode (both sums are then the same
        arithmetic).

    Examples
    --------
    >>> import dtdyn as dd
    >>> p = dd.problem("P3")
    >>> e = dd.truncation_error(p["M"], p["C"], p["K"], [14], [14], range(5), [1.0, 5.0])
    >>> bool(e.peak_relative < 0.1)
    True
    """
    quantity = _quantity(quantity)
    f = _freqs(freqs_hz)
    full = modal_model(M, C, K, force_dofs, outputs)
    kept = full.select(modes)
    kept_idx = tuple(int(i) for i in np.sort(np.asarray(modes).ravel()))
    H_full = continuous_frequency_response(full, f, quantity)
    dH = H_full - continuous_frequency_response(kept, f, quantity)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(dH) / np.abs(H_full)
    ok = np.isfinite(rel) & np.isfinite(np.abs(H_full)) & (np.abs(H_full) > 0)
    if ok.any():
        masked = np.where(ok, rel, -np.inf)
        flat = int(np.argmax(masked))
        max_rel, at = float(masked.ravel()[flat]), float(f[np.unravel_index(flat, rel.shape)[0]])
    else:
        max_rel, at = float("nan"), float("nan")
    finite = np.isfinite(np.abs(H_full)) & np.isfinite(np.abs(dH))
    num = np.where(finite, np.abs(dH), 0.0).max(axis=0)
    den = np.where(finite, np.abs(H_full), 0.0).max(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        peak = num / den
    peak_rel = float(np.nanmax(peak)) if np.isfinite(peak).any() else float("nan")

    H0_full = full.frequency_response([0.0])[0]
    residual = H0_full - kept.frequency_response([0.0])[0]
    nz = np.abs(H0_full) > 0
    static_rel = float(np.max(np.abs(residual[nz]) / np.abs(H0_full[nz]))) if nz.any() else 0.0
    # conjugate pairs make H(0) real: the imaginary part is round-off
    return TruncationError(max_rel, at, peak_rel, np.ascontiguousarray(residual.real), static_rel,
                           kept_idx, full.n_modes, quantity, int((~ok).sum()))
