r"""Response PSDs of linear models under stationary random loads, and their integrals.

Input-output relation
---------------------
With :math:`H(f)` the receptance from the loads to the output DOFs at :math:`s = 2\pi i f`
(:math:`Z(s) = K + s C + s^2 M`, :math:`H = Z^{-1}` restricted to outputs and loads) and
:math:`S_f(f)` the one-sided cross-spectral matrix of the loads, the output cross-spectral
matrix is (Bendat & Piersol, *Random Data*, 4th ed., sec. 7.1; Newland, *An Introduction to
Random Vibrations*, ch. 7)

.. math::

    S_x = H S_f H^{H}, \qquad S_v = (2\pi f)^2 S_x, \qquad S_a = (2\pi f)^4 S_x .

Under support motion (DOFs relative to the support, :math:`u = x + r u_g`; `Ground` in
`dtdyn._engine.ground`) the load is :math:`-M r \ddot u_g`, so :math:`H_g = -H M r` and the
absolute acceleration is :math:`\ddot u = (-(2\pi f)^2 H_g + r)\ddot u_g`, with the ground
accelerations' cross-spectral matrix in place of :math:`S_f`.

Moments
-------
The spectral moments of each output's auto-spectrum :math:`G(f) = S_{oo}(f)` are
:math:`m_k = \int f^k G(f)\,df` (f in Hz, k = 0, 1, 2, 4) over ``freqs_hz[0] ..
freqs_hz[-1]``; :math:`m_0` is the mean square, :math:`\nu_0^+ = \sqrt{m_2/m_0}` the rate of
zero up-crossings and :math:`\nu_p = \sqrt{m_4/m_2}` of peaks (Rice), and
:math:`\gamma = m_2/\sqrt{m_0 m_4}` the irregularity factor (1 for a narrow band).

Quadrature
----------
The integrals do not use the user's grid: a lightly damped mode's peak is a few
:math:`\zeta f_n` wide. The band is cut into panels at every breakpoint of the input PSD and,
around every mode (:math:`f_n`, :math:`\zeta_n` of the model's undamped modes, the damping
ratio projected :math:`\phi^T C \phi / (2\omega_n)`), at :math:`f_n` and
:math:`f_n \pm \zeta_n f_n \cdot 2^j`, j = 0, 1, 2, ...: each panel is then at least as far from
the poles :math:`f_n (\pm\sqrt{1-\zeta^2} + i\zeta)` as it is wide, where Gauss-Legendre
quadrature converges geometrically. Each panel is integrated by the 8-point rule on each half;
the difference from the rule on the whole panel estimates the error, and panels are halved
until the sum of the estimates is below ``accuracy`` times each integral (each output, each
quantity, each moment). That sum is reported: ``info["rms_error_estimate"]`` is the largest
relative error estimate of an rms (half that of its mean square), ``info["moment_error_estimate"]``
the largest of any moment. The estimate bounds the error of the coarser rule, so the reported
integrals (the finer one) are usually much better than it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn._engine import linalg, validate
from dtdyn._engine.errors import DtdynAccuracyWarning
from dtdyn._engine.public import public, warn
from dtdyn.random_vibration._psd import PsdTable

__all__ = ["RandomResponse", "random_response", "chain_random_response",
           "beam_random_response", "shaft_random_response"]

#: Gauss-Legendre points per half panel
GAUSS_POINTS = 8
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(GAUSS_POINTS)
#: the moments m_k computed
MOMENTS = (0, 1, 2, 4)
#: relative tolerance of the Hermitian and positive-semidefinite checks of an input spectrum
PSD_TOL = 1e-10
#: most frequencies evaluated by the quadrature before it stops with a warning
MAX_NODES = 400_000
#: frequencies per block of a dense solve or a spectrum evaluation
BLOCK = 512


@dataclass
class RandomResponse:
    """Output spectra and their integrals (module docstring).

    Attributes
    ----------
    freqs_hz : (n_freq,) ndarray
        The user's frequencies, Hz.
    outputs : (n_out,) ndarray
        0-based output DOFs.
    dof_names : tuple of str or None
        Their names, where the model names its DOFs (beams, shafts).
    quantities : tuple of str
        The quantities computed: those asked for, and ``"a_abs"`` under support motion.
    x_psd, v_psd, a_psd : (n_freq, n_out, n_out) complex ndarray or None
        One-sided output cross-spectral matrices of displacement, velocity and acceleration
        (relative to the support under support motion), (unit)^2/Hz; None when not asked for.
    a_abs_psd : (n_freq, n_out, n_out) complex ndarray or None
        The absolute acceleration's, under support motion.
    rms, m0, m1, m2, m4 : dict
        By quantity (``"x"``, ``"v"``, ``"a"``, ``"a_abs"``): each output's rms and spectral
        moments m_k = int f^k G(f) df (f in Hz) over the band, (n_out,) arrays.
    info : dict
        ``rms_error_estimate``, ``moment_error_estimate`` (relative), ``n_integration_freqs``,
        ``modes_hz`` and ``damping_ratio`` (the modes the quadrature refined around),
        ``band_hz``, ``accuracy``.

    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration import random_response
    >>> r = random_response([[1.0]], [[0.4]], [[400.0]], 1.0, np.linspace(0.0, 50.0, 26))
    >>> r.x_psd.shape, sorted(r.rms), bool(r.irregularity_factor["x"][0] > 0.9)
    ((26, 1, 1), ['a', 'v', 'x'], True)
    """

    freqs_hz: np.ndarray
    outputs: np.ndarray
    dof_names: tuple | None
    quantities: tuple
    x_psd: np.ndarray | None = None
    v_psd: np.ndarray | None = None
    a_psd: np.ndarray | None = None
    a_abs_psd: np.ndarray | None = None
    rms: dict = field(default_factory=dict)
    m0: dict = field(default_factory=dict)
    m1: dict = field(default_factory=dict)
    m2: dict = field(default_factory=dict)
    m4: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    @property
    def zero_crossing_rate(self) -> dict:
        """Zero up-crossings per second, sqrt(m2 / m0), by quantity."""
        return {q: _ratio(self.m2[q], self.m0[q]) for q in self.m0}

    @property
    def peak_rate(self) -> dict:
        """Peaks (maxima) per second, sqrt(m4 / m2), by quantity."""
        return {q: _ratio(self.m4[q], self.m2[q]) for q in self.m0}

    @property
    def irregularity_factor(self) -> dict:
        """m2 / sqrt(m0 m4), by quantity: 1 for a narrow band, towards 0 for a broad one."""
        return {q: _ratio(self.m2[q] ** 2, self.m0[q] * self.m4[q]) for q in self.m0}

    def __repr__(self) -> str:
        shown = ", ".join(f"{q} rms {np.array2string(v, precision=4)}"
                          for q, v in self.rms.items())
        return (f"RandomResponse({self.freqs_hz.size} frequencies, {self.outputs.size} outputs; "
                f"{shown})")


def _ratio(a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(np.where(b > 0, a / np.where(b > 0, b, 1.0), np.nan))


# ---------------------------------------------------------------------------------------------
# the input spectrum


class _Spectrum:
    """A checked one-sided input cross-spectral matrix: ``self(f)`` is (len(f), n_in, n_in)
    complex; ``edges`` are its breakpoints (Hz)."""

    def __init__(self, name: str, psd, freqs_hz: np.ndarray):
        self.name = name
        self.samples = None
        self.tables = None
        self.function = None
        if isinstance(psd, PsdTable):
            psd = [psd]
        if isinstance(psd, (list, tuple)) and psd and all(callable(p) for p in psd):
            self.tables = list(psd)
            self.n_in = len(psd)
            self.edges = np.concatenate([np.asarray(getattr(p, "freqs_hz", []), dtype=float)
                                         for p in psd])
        elif callable(psd):
            self.function = psd
            probe = self._shape(np.asarray(psd(freqs_hz[:1])), 1)
            self.n_in = probe.shape[1]
            self.edges = np.asarray(getattr(psd, "freqs_hz", []), dtype=float)
        else:
            arr = np.asarray(psd)
            if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number)
                                           and not np.issubdtype(arr.dtype, np.bool_)):
                raise ValueError(f"{name} must be a PSD table (psd_table), a callable of "
                                 "the frequency in Hz, a number or an array of numbers, got "
                                 f"{type(psd).__name__}")
            if arr.ndim == 0:
                arr = np.full(freqs_hz.size, arr)
            if arr.shape[0] != freqs_hz.size or arr.ndim > 3:
                raise ValueError(f"{name} has shape {arr.shape}, expected ({freqs_hz.size},), "
                                 f"({freqs_hz.size}, n_in) or ({freqs_hz.size}, n_in, n_in): "
                                 "one row per frequency of freqs_hz")
            S = self._shape(arr, freqs_hz.size)
            self._check(S, freqs_hz, sampled=True)
            self.samples, self.n_in, self.edges = S, S.shape[1], freqs_hz
            d = np.real(np.einsum("kii->ki", S))
            root = np.sqrt(d)
            with np.errstate(divide="ignore", invalid="ignore"):
                G = S / (root[:, :, None] * root[:, None, :])
            self._coherency = np.where(np.isfinite(G), G, 0.0)
            self._diag = d
        self.edges = np.unique(self.edges[np.isfinite(self.edges)])

    def _shape(self, arr, n_freq: int) -> np.ndarray:
        if arr.ndim == 0:
            arr = np.full(n_freq, arr)
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim == 2:
            S = np.zeros(arr.shape + (arr.shape[1],), dtype=complex)
            i = np.arange(arr.shape[1])
            S[:, i, i] = arr
        elif arr.ndim == 3 and arr.shape[1] == arr.shape[2]:
            S = arr.astype(complex)
        else:
            raise ValueError(f"{self.name} has shape {arr.shape}, expected (n_freq,), "
                             "(n_freq, n_in) or (n_freq, n_in, n_in)")
        if S.shape[0] != n_freq:
            raise ValueError(f"{self.name} gave {S.shape[0]} rows for {n_freq} frequencies")
        return S

    def _check(self, S, f, sampled: bool) -> None:
        """Finite, Hermitian, real non-negative diagonal, positive semidefinite; each error
        names the entry."""
        def where(k, i=None, j=None):
            if sampled:
                entry = f"[{k}]" if i is None else f"[{k}, {i}, {j}]"
                return f"{self.name}{entry} at {f[k]:g} Hz"
            return f"{self.name}({f[k]:g} Hz)" + ("" if i is None else f"[{i}, {j}]")

        bad = np.argwhere(~np.isfinite(S))
        if bad.size:
            k, i, j = bad[0]
            raise ValueError(f"{where(k, i, j)} = {S[k, i, j]!r} is not finite")
        scale = np.abs(S).max(axis=(1, 2))
        tol = PSD_TOL * np.where(scale > 0, scale, 1.0)
        d = np.einsum("kii->ki", S)
        bad = np.argwhere((np.abs(d.imag) > tol[:, None]) | (d.real < -tol[:, None]))
        if bad.size:
            k, i = bad[0]
            raise ValueError(f"{where(k, i, i)} = {d[k, i]!r}: an auto-spectrum must be real "
                             "and >= 0")
        dev = np.abs(S - np.conj(np.swapaxes(S, 1, 2)))
        bad = np.argwhere(dev > tol[:, None, None])
        if bad.size:
            k, i, j = bad[0]
            raise ValueError(f"{where(k, i, j)} = {S[k, i, j]!r} but the conjugate of "
                             f"[{j}, {i}] is {np.conj(S[k, j, i])!r}: a cross-spectral matrix "
                             "is Hermitian")
        if S.shape[1] > 1:
            low = np.linalg.eigvalsh(S)[:, 0]
            bad = np.flatnonzero(low < -tol * S.shape[1])
            if bad.size:
                k = bad[0]
                raise ValueError(f"{where(k)} is not positive semidefinite (smallest "
                                 f"eigenvalue {low[k]:.3g}): a coherence above 1 between two "
                                 "inputs")

    def __call__(self, f: np.ndarray) -> np.ndarray:
        if self.tables is not None:
            S = np.zeros((f.size, self.n_in, self.n_in), dtype=complex)
            for i, table in enumerate(self.tables):
                S[:, i, i] = np.asarray(table(f), dtype=float).reshape(f.size)
            self._check(S, f, sampled=False)
            return S
        if self.function is not None:
            S = self._shape(np.asarray(self.function(f)), f.size)
            if S.shape[1] != self.n_in:
                raise ValueError(f"{self.name} gave {S.shape[1]} inputs at some frequencies and "
                                 f"{self.n_in} at others")
            self._check(S, f, sampled=False)
            return S
        return self._interpolate(f)

    def _interpolate(self, f: np.ndarray) -> np.ndarray:
        """Between the samples: each auto-spectrum a straight line on log-log axes (linear
        where a sample is 0), the coherency S_ij / sqrt(S_ii S_jj) linear in f; a mix of
        positive semidefinite coherency matrices with unit diagonal is one, so S stays one."""
        fs, d = self.edges, self._diag
        i = np.clip(np.searchsorted(fs, f, side="right") - 1, 0, fs.size - 2)
        f0, f1 = fs[i], fs[i + 1]
        t = ((f - f0) / (f1 - f0))[:, None]
        d0, d1 = d[i], d[i + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            n = np.log(d1 / d0) / np.log(f1 / f0)[:, None]
            loglog = d0 * (f / f0)[:, None] ** n
        positive = (d0 > 0) & (d1 > 0) & (f0 > 0)[:, None]
        diag = np.where(positive, loglog, d0 + t * (d1 - d0))
        G = self._coherency[i] + t[:, :, None] * (self._coherency[i + 1] - self._coherency[i])
        root = np.sqrt(np.maximum(diag, 0.0))
        return G * root[:, :, None] * root[:, None, :]


# ---------------------------------------------------------------------------------------------
# the models: receptances to the loads at the outputs, modes, and the mass for support motion


class _MCK:
    dof_names = None

    def __init__(self, M, C, K):
        if C is None:
            raise ValueError("C is None: an undamped model's response PSD has infinite peaks "
                             "and its mean square is infinite; give the damping matrix")
        self.M, self.C, self.K = linalg.mck(M, C, K, keep_sparse=True)
        self.n_dof = self.M.shape[0]

    def modes(self, below):
        if sps.issparse(self.M) and self.n_dof > 64:
            lam, phi = _sparse_modes_below(self.M, self.K, below)
        else:
            lam, phi = sla.eigh(*(A.toarray() if sps.issparse(A) else A
                                  for A in (self.K, self.M)))
        keep = (lam > 0) & (lam < below**2)
        return _projected(np.sqrt(lam[keep]), phi[:, keep], self.C)

    def mass(self):
        return self.M

    def rigid(self, n_dir):
        return np.ones((self.n_dof, n_dir))

    def receptance(self, w, load, outputs):
        """x at ``outputs`` per load column: (len(w), n_out, n_load); ``load`` is (n_dof,
        n_load)."""
        out = np.empty((w.size, outputs.size, load.shape[1]), dtype=complex)
        if sps.issparse(self.M):
            for k, wk in enumerate(w):
                Z = (self.K + 1j * wk * self.C - wk * wk * self.M).tocsc()
                out[k] = spla.splu(Z).solve(load.astype(complex))[outputs]
            return out
        for lo in range(0, w.size, BLOCK):
            s = 1j * w[lo:lo + BLOCK, None, None]
            Z = self.K[None] + s * self.C[None] + s * s * self.M[None]
            x = np.linalg.solve(Z, np.broadcast_to(load, (Z.shape[0],) + load.shape))
            out[lo:lo + BLOCK] = x[:, outputs]
        return out


def _sparse_modes_below(M, K, below, first=16):
    """The eigenpairs (k_r, phi_r) of K phi = k M phi up to beyond k = below^2 by shift-invert
    (ARPACK) about a small negative shift, so that rigid-body modes (k = 0) do not make K - sigma M
    singular; the count doubles until the largest found lies above below^2. The modes only place
    the quadrature's panels (their frequencies and damping), so ARPACK's tolerance suffices."""
    n = M.shape[0]
    M, K = sps.csc_matrix(M), sps.csc_matrix(K)
    scale = abs(K).max() / abs(M).max()
    sigma = -1e-8 * min(below * below, scale) if below > 0 else -1e-8 * scale
    count = min(first, n - 2)
    while True:
        lam, phi = spla.eigsh(K, k=count, M=M, sigma=sigma, which="LM")
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        if lam[-1] >= below * below or count == n - 2:
            return lam, phi
        count = min(2 * count, n - 2)


class _Chain:
    """A chain through the Laplace-domain transfer matrices of `chain_frequency_response`,
    with a load on every mass at once: O(N) per frequency for any load vector."""

    dof_names = None

    def __init__(self, mass, stiffness, damping, ground_stiffness, ground_damping):
        from dtdyn.linear._chain import Chain
        self.chain = Chain(mass, stiffness, damping, ground_stiffness=ground_stiffness,
                           ground_damping=ground_damping)
        self.n_dof = self.chain.n_dof

    def modes(self, below):
        c = self.chain
        m, k, kg = c.m, c.k, c.kg
        # M^-1/2 K M^-1/2, tridiagonal
        kd = k + np.r_[k[1:], 0.0] + kg
        diag = kd / m
        off = -k[1:] / np.sqrt(m[:-1] * m[1:])
        lam, y = sla.eigh_tridiagonal(diag, off, select="v", select_range=(0.0, below**2))
        keep = lam > 0
        phi = y[:, keep] / np.sqrt(m)[:, None]
        _, C, _ = c.matrices(sparse=True)
        return _projected(np.sqrt(lam[keep]), phi, C)

    def mass(self):
        return sps.diags(self.chain.m)

    def rigid(self, n_dir):
        return np.ones((self.n_dof, n_dir))

    def receptance(self, w, load, outputs):
        from dtdyn.linear._tmm import station
        chain, N = self.chain, self.n_dof
        n_load = load.shape[1]
        out = np.empty((w.size, outputs.size, n_load), dtype=complex)
        xa = np.empty(N, dtype=complex)
        xb = np.empty((N, n_load), dtype=complex)
        for k, wk in enumerate(w):
            s = 1j * wk
            a = np.array([0.0, 1.0, 0.0], dtype=complex)  # the base force's own solution
            b = np.zeros((3, n_load), dtype=complex)      # the loads', base force 0
            b[2] = 1.0
            for n in range(N):
                T = station(chain, n, s)
                a, b = T @ a, T @ b
                b[1] -= load[n]                 # elements.force(F): f -= F (state [x, f, 1])
                xa[n], xb[n] = a[0], b[0]
            f_base = -b[1] / a[1]               # free end: f_N = 0
            out[k] = (xb + xa[:, None] * f_base[None])[outputs]
        return out


class _Stations:
    """A beam or a shaft through its O(N) receptances; a load vector by reciprocity
    (H symmetric): H P at output o is the response of every DOF to a unit load at o, times P."""

    def __init__(self, model, kind):
        self.model, self.kind = model, kind
        if kind == "beam":
            from dtdyn.linear._beam import beam_matrices, rigid_translation
            from dtdyn.linear._beam_frequency import beam_frequency_response, beam_modes
            self._frf = lambda w, i, o: beam_frequency_response(model, w, i, o)
            self._modes = beam_modes
            self.matrices = beam_matrices(model)
            self._rigid = lambda n_dir: rigid_translation(model, n_dir)
        else:
            from dtdyn.linear._shaft import rigid_rotation, shaft_matrices
            from dtdyn.linear._shaft_frequency import shaft_frequency_response, shaft_modes
            self._frf = lambda w, i, o: shaft_frequency_response(model, w, i, o, exact=False)
            self._modes = shaft_modes
            self.matrices = shaft_matrices(model)
            self._rigid = lambda n_dir: np.repeat(rigid_rotation(model)[:, None], n_dir, 1)
        self.dof_names = tuple(model.dof_names)
        self.n_dof = len(self.dof_names)

    def modes(self, below):
        m = self._modes(self.model, below=below)
        keep = m.omega > 0
        return _projected(m.omega[keep], m.shapes[:, keep], self.matrices[1])

    def mass(self):
        return self.matrices[0]

    def rigid(self, n_dir):
        return self._rigid(n_dir)

    def receptance(self, w, load, outputs):
        columns = np.flatnonzero(np.any(load != 0, axis=1))
        unit = (np.count_nonzero(load, axis=0) == 1).all() and np.all(load[columns].sum(1) == 1)
        if unit and columns.size == load.shape[1]:
            order = np.argmax(load != 0, axis=0)   # one unit load per column: the DOFs
            return self._frf(w, [int(i) for i in order], [int(o) for o in outputs])
        H = self._frf(w, [int(o) for o in outputs], [int(j) for j in columns])  # (w, j, o)
        return np.einsum("wjo,jd->wod", H, load[columns])


def _projected(omega, phi, C):
    """(f_n in Hz, zeta_n) with zeta_n = phi^T C phi / (2 omega_n), phi mass-normalized."""
    Cphi = C @ phi
    zeta = np.einsum("ij,ij->j", phi, np.asarray(Cphi)) / (2.0 * omega)
    return omega / (2.0 * np.pi), zeta


# ---------------------------------------------------------------------------------------------
# the quadrature


def _edges(f_lo, f_hi, fn, zeta, extra) -> np.ndarray:
    """Panel edges: the band's ends, the input's breakpoints, and around each mode f_n and
    f_n +- zeta f_n 2^j (module docstring)."""
    pts = [np.array([f_lo, f_hi]), np.asarray(extra, dtype=float)]
    span = f_hi - f_lo
    for f, z in zip(fn, zeta):
        width = z * f
        steps = width * 2.0 ** np.arange(int(np.ceil(np.log2(max(span / width, 1.0)))) + 2)
        pts.append(np.concatenate([[f], f + steps, f - steps]))
    e = np.concatenate(pts)
    e = np.unique(e[(e >= f_lo) & (e <= f_hi)])
    keep = np.r_[True, np.diff(e) > 1e-12 * max(f_hi, 1e-300)]
    e = e[keep]
    e[-1] = f_hi
    return e


def _rule(a, b):
    """Gauss-Legendre nodes (n_panel * GAUSS_POINTS,) and weights of each panel [a, b]."""
    half = 0.5 * (b - a)[:, None]
    f = 0.5 * (a + b)[:, None] + half * _NODES[None]
    return f.reshape(-1), (half * _WEIGHTS[None])


def _integrate(evaluate, edges, accuracy):
    """Adaptive composite Gauss-Legendre over the panels: (integrals (n_comp,), relative error
    estimates (n_comp,), frequencies evaluated)."""
    a, b = edges[:-1], edges[1:]
    coarse = None
    done_value, done_error = 0.0, 0.0
    n_eval = 0

    def panels(lo, hi):
        f, w = _rule(lo, hi)
        g = evaluate(f).reshape(lo.size, GAUSS_POINTS, -1)
        return np.einsum("pn,pnc->pc", w, g)

    while True:
        if coarse is None:
            coarse = panels(a, b)
            n_eval += a.size * GAUSS_POINTS
        mid = 0.5 * (a + b)
        left, right = panels(a, mid), panels(mid, b)
        n_eval += 2 * a.size * GAUSS_POINTS
        fine = left + right
        error = np.abs(coarse - fine)
        total = done_value + fine.sum(0)
        scale = np.where(np.abs(total) > 0, np.abs(total), 1.0)
        rel = (done_error + error.sum(0)) / scale
        if rel.max() <= accuracy or n_eval > MAX_NODES:
            if rel.max() > accuracy:
                warn(f"random response: the quadrature stopped after {n_eval} frequencies "
                     f"with an estimated relative error {rel.max():.2g} above accuracy = "
                     f"{accuracy:g}", DtdynAccuracyWarning)
            return total, rel, n_eval
        score = (error / scale).max(1)
        split = score > 0.25 * accuracy / a.size
        done_value = done_value + fine[~split].sum(0)
        done_error = done_error + error[~split].sum(0)
        a, mid, b = a[split], mid[split], b[split]
        a, b = np.concatenate([a, mid]), np.concatenate([mid, b])
        coarse = np.concatenate([left[split], right[split]])


# ---------------------------------------------------------------------------------------------
# the entry points


def _options(freqs_hz, quantities, accuracy):
    """The checked (freqs_hz, quantities, accuracy)."""
    f_user = validate.real_array("freqs_hz", freqs_hz, "an array of frequencies (Hz)")
    if (f_user.ndim != 1 or f_user.size < 2 or not np.all(np.isfinite(f_user))
            or np.any(f_user < 0) or np.any(np.diff(f_user) <= 0)):
        raise ValueError(f"freqs_hz = {freqs_hz!r}: must be a 1-D array of at least two "
                         "finite, increasing frequencies >= 0 (Hz)")
    accuracy = validate.positive_scalar("accuracy", accuracy)
    if accuracy >= 1.0:
        raise ValueError(f"accuracy = {accuracy!r}: a relative error target, < 1")
    if isinstance(quantities, str):
        quantities = (quantities,)
    quantities = tuple(quantities)
    for q in quantities:
        if q not in ("x", "v", "a"):
            raise ValueError(f"quantities = {quantities!r}: each must be 'x', 'v' or 'a'")
    if not quantities or len(set(quantities)) != len(quantities):
        raise ValueError(f"quantities = {quantities!r}: give 'x', 'v' and/or 'a', each once")
    return f_user, quantities, accuracy


def _ground_load(model, spectrum, influence, outs):
    """(load -M r (n_dof, n_dir), r at the outputs) of support motion."""
    n_dir = spectrum.n_in
    if influence is None:
        if n_dir != 1 and model.dof_names is None:
            raise ValueError(f"ground_acceleration_psd has {n_dir} directions: give the "
                             f"influence matrix ({model.n_dof}, {n_dir})")
        r = model.rigid(n_dir)
    else:
        r = validate.real_array("influence", influence)
        r = r[:, None] if r.ndim == 1 else r
        if r.shape != (model.n_dof, n_dir) or not np.isfinite(r).all():
            raise ValueError(f"influence has shape {np.shape(influence)}, expected "
                             f"({model.n_dof},) or ({model.n_dof}, {n_dir}) finite values: "
                             "one column per direction of ground_acceleration_psd")
    return -np.asarray(model.mass() @ r), r[outs]


def _loading(model, psd, f_user, force_dofs, ground_acceleration_psd, influence, outs):
    """(spectrum, load (n_dof, n_in), r at the outputs or None)."""
    if ground_acceleration_psd is not None:
        if psd is not None:
            raise ValueError("psd and ground_acceleration_psd are both given: give one (their "
                             "cross-spectra are not known)")
        if force_dofs is not None:
            raise ValueError("force_dofs is given with ground_acceleration_psd: the support "
                             "motion loads every DOF through -M r (influence)")
        spectrum = _Spectrum("ground_acceleration_psd", ground_acceleration_psd, f_user)
        return (spectrum,) + _ground_load(model, spectrum, influence, outs)
    if influence is not None:
        raise ValueError("influence is given without ground_acceleration_psd")
    if psd is None:
        raise ValueError("psd is None: give the loads' PSD or ground_acceleration_psd")
    spectrum = _Spectrum("psd", psd, f_user)
    dofs = validate.dof_indices("force_dofs", force_dofs, model.n_dof, names=model.dof_names)
    if dofs.size != spectrum.n_in:
        raise ValueError(f"psd has {spectrum.n_in} input(s) and force_dofs names "
                         f"{dofs.size} DOF(s): one PSD column (or row and column of a "
                         "cross-spectral matrix) per loaded DOF")
    load = np.zeros((model.n_dof, dofs.size))
    load[dofs, np.arange(dofs.size)] = 1.0
    return spectrum, load, None


def _run(model, psd, freqs_hz, force_dofs, outputs, quantities, ground_acceleration_psd,
         influence, accuracy) -> RandomResponse:
    f_user, quantities, accuracy = _options(freqs_hz, quantities, accuracy)
    names = model.dof_names
    outs = validate.dof_indices("outputs", outputs, model.n_dof, names=names)
    spectrum, load, r_out = _loading(model, psd, f_user, force_dofs, ground_acceleration_psd,
                                     influence, outs)
    ground = r_out is not None
    kinds = list(quantities) + (["a_abs"] if ground and "a" in quantities else [])

    def transfers(f):
        """Each quantity's transfer from the inputs to the outputs: (len(f), n_out, n_in)."""
        w = 2.0 * np.pi * f
        H = model.receptance(w, load, outs)
        if not np.all(np.isfinite(H)):
            k = int(np.argwhere(~np.isfinite(H))[0, 0])
            raise ValueError(f"the receptance is not finite at {f[k]:g} Hz: an undamped "
                             "resonance (give damping) or a singular K at 0 Hz")
        s = (1j * w)[:, None, None]
        out = {"x": H, "v": s * H, "a": s * s * H}
        if "a_abs" in kinds:
            out["a_abs"] = s * s * H + r_out[None]
        return out

    def evaluate(f):
        """The integrands f^k G_q,oo(f): (len(f), n_comp)."""
        parts = []
        for lo in range(0, f.size, BLOCK):
            fb = f[lo:lo + BLOCK]
            S = spectrum(fb)
            T = transfers(fb)
            G = np.stack([np.einsum("foi,fij,foj->fo", T[q], S, T[q].conj()).real
                          for q in kinds], axis=1)                  # (f, q, o)
            powers = np.stack([fb**k for k in MOMENTS], axis=1)     # (f, k)
            parts.append((G[:, :, None, :] * powers[:, None, :, None]).reshape(fb.size, -1))
        return np.concatenate(parts)

    # the output cross-spectral matrices returned: (n_freq, n_out, n_out) complex per quantity
    validate.memory(f"the response spectra of {outs.size:,} outputs at {f_user.size:,} "
                    f"frequencies ({', '.join(kinds)})",
                    16 * f_user.size * outs.size**2 * len(kinds),
                    "ask for the outputs you need (outputs=[...]): each spectrum holds every "
                    "pair of outputs")
    band = (float(f_user[0]), float(f_user[-1]))
    fn, zeta = model.modes(2.0 * np.pi * 2.0 * max(band[1], 1e-300))
    inside = (fn > 0) & (zeta > 0)
    if np.any(zeta[fn <= band[1]] <= 1e-12):
        k = int(np.flatnonzero(zeta[fn <= band[1]] <= 1e-12)[0])
        raise ValueError(f"the mode at {fn[k]:g} Hz is undamped (damping ratio "
                         f"{zeta[k]:.2g}): its peak and the mean square are infinite")
    edges = _edges(*band, fn[inside], np.minimum(zeta[inside], 1.0), spectrum.edges)
    total, rel, n_eval = _integrate(evaluate, edges, accuracy)
    total = total.reshape(len(kinds), len(MOMENTS), outs.size)
    rel = rel.reshape(len(kinds), len(MOMENTS), outs.size)

    S = spectrum(f_user)
    T = transfers(f_user)
    spectra = {q: T[q] @ S @ np.conj(np.swapaxes(T[q], 1, 2)) for q in kinds}
    moments = {f"m{k}": {q: total[i, j] for i, q in enumerate(kinds)}
               for j, k in enumerate(MOMENTS)}
    result = RandomResponse(
        freqs_hz=f_user, outputs=outs,
        dof_names=None if names is None else tuple(names[i] for i in outs),
        quantities=tuple(kinds),
        x_psd=spectra.get("x"), v_psd=spectra.get("v"), a_psd=spectra.get("a"),
        a_abs_psd=spectra.get("a_abs"),
        rms={q: np.sqrt(np.maximum(moments["m0"][q], 0.0)) for q in kinds},
        **moments,
        info={"rms_error_estimate": float(0.5 * rel[:, 0].max()),
              "moment_error_estimate": float(rel.max()),
              "n_integration_freqs": int(n_eval), "accuracy": accuracy, "band_hz": band,
              "modes_hz": fn[inside], "damping_ratio": zeta[inside],
              "input": "ground_acceleration_psd" if ground else "psd"})
    return result


def _doc(model: str, example: str, keywords: str = "") -> str:
    """The docstring of an entry point: its model's lines, the shared ones (with ``keywords``,
    the model's own keyword parameters, after ``freqs_hz``: the signature's order), its
    example."""
    head, tail = _SHARED.split("    force_dofs : ", 1)
    return model + head + keywords + "    force_dofs : " + tail + example


_SHARED = """
    psd : PsdTable, sequence of PsdTable, callable, number, array_like or None
        One-sided PSD of the loads, (unit)^2/Hz: a `psd_table` (one loaded DOF), one table
        per loaded DOF (independent loads), a callable ``psd(f_hz)`` returning one of the
        shapes below, a number (white noise over the band), or samples at ``freqs_hz``
        (log-log between them): shape (n_freq,), (n_freq, n_in) (independent loads) or
        (n_freq, n_in, n_in), the complex Hermitian cross-spectral matrix (checked: Hermitian,
        real non-negative auto-spectra, positive semidefinite). None with
        ``ground_acceleration_psd``.
    freqs_hz : (n_freq,) array_like
        Frequencies, Hz, increasing, >= 0: where the output spectra are returned. The band
        ``freqs_hz[0] .. freqs_hz[-1]`` is the one integrated, on a finer grid of its own.
    force_dofs : sequence, optional
        The loaded DOFs, one per input (default: every DOF).
    outputs : sequence, optional
        The DOFs whose spectra are returned (default: every DOF).
    quantities : tuple of str
        Any of ``"x"``, ``"v"``, ``"a"``.
    ground_acceleration_psd : as ``psd``, optional
        Instead of ``psd``: the support's acceleration PSD, (m/s^2)^2/Hz, one input per ground
        direction. The DOFs are then relative to the support, and ``a_abs`` is added when
        ``"a"`` is asked for.
    influence : (n_dof,) or (n_dof, n_dir) array_like, optional
        r, each DOF's motion per unit support motion (default: the model's rigid motion).
    accuracy : float
        Relative error target of every mean square and spectral moment
        (`dtdyn.random_vibration._response`: the quadrature and its error estimate).

    Returns
    -------
    RandomResponse
        The output cross-spectral matrices at ``freqs_hz``, the rms and spectral moments of
        each output, ``info["rms_error_estimate"]``.

    Notes
    -----
    S_y = H S_f H^H at each frequency (H: the receptances from the loads to the outputs);
    m_k = int f^k S_oo(f) df by adaptive Gauss-Legendre panels placed around every mode's
    half-power band (`dtdyn.random_vibration._response`).
"""


@public
def random_response(M, C, K, psd, freqs_hz, *, force_dofs=None, outputs=None,
                    quantities=("x", "v", "a"), ground_acceleration_psd=None, influence=None,
                    accuracy=1e-8) -> RandomResponse:
    return _run(_MCK(M, C, K), psd, freqs_hz, force_dofs, outputs, quantities,
                ground_acceleration_psd, influence, accuracy)


random_response.__wrapped__.__doc__ = random_response.__doc__ = _doc("""Response PSDs, rms and
    spectral moments of M q'' + C q' + K q = f under stationary random loads or support motion.

    Parameters
    ----------
    M, C, K : (n, n) array_like or scipy.sparse matrix
        Mass, damping and stiffness (C is required: without damping the peaks are infinite).
""", """
    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration import random_response
    >>> k, zeta = (2 * np.pi * 100.0) ** 2, 0.05           # f_n = 100 Hz, 5 %
    >>> f = np.r_[0.0, np.geomspace(1.0, 1e9, 49)]          # a coarse grid, Hz
    >>> r = random_response([[1.0]], [[2 * zeta * np.sqrt(k)]], [[k]], None, f,
    ...                     ground_acceleration_psd=1.0)
    >>> miles = np.pi * 100.0 * (1 + 4 * zeta**2) / (4 * zeta)   # exact for white noise
    >>> print(f"{r.m0['a_abs'][0] / miles - 1:.0e}")
    -6e-11
""")


@public
def chain_random_response(mass, stiffness, damping, psd, freqs_hz, *, ground_stiffness=None,
                          ground_damping=None, force_dofs=None, outputs=None,
                          quantities=("x", "v", "a"), ground_acceleration_psd=None,
                          influence=None, accuracy=1e-8) -> RandomResponse:
    return _run(_Chain(mass, stiffness, damping, ground_stiffness, ground_damping), psd,
                freqs_hz, force_dofs, outputs, quantities, ground_acceleration_psd, influence,
                accuracy)


chain_random_response.__wrapped__.__doc__ = chain_random_response.__doc__ = _doc("""Response
    PSDs, rms and spectral moments of a chain (as `chain_response`) under random loads or
    support motion, by the chain's transfer matrices with every load at once: O(N) per
    frequency.

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        The chain (as `chain_response`; damping: dashpots, N s/m).
""", """
    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn.random_vibration import chain_random_response, psd_table
    >>> table = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
    >>> r = chain_random_response([2.0, 1.0], [4e5, 2e5], [40.0, 20.0], None,
    ...                           np.geomspace(20, 2000, 30), ground_acceleration_psd=table)
    >>> r.a_abs_psd.shape, bool(r.info["rms_error_estimate"] < 1e-8)
    ((30, 2, 2), True)
""", keywords="""    ground_stiffness, ground_damping : (N,) array_like, optional
        Springs and dampers from the masses to the ground.
""")


@public
def beam_random_response(beam, psd, freqs_hz, *, force_dofs=None, outputs=None,
                         quantities=("x", "v", "a"), ground_acceleration_psd=None,
                         influence=None, accuracy=1e-8) -> RandomResponse:
    from dtdyn.linear._beam import Beam
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")
    return _run(_Stations(beam, "beam"), psd, freqs_hz, force_dofs, outputs, quantities,
                ground_acceleration_psd, influence, accuracy)


beam_random_response.__wrapped__.__doc__ = beam_random_response.__doc__ = _doc("""Response
    PSDs, rms and spectral moments of a `Beam` (the model of `beam_matrices`) under random
    loads or support motion, by `beam_frequency_response` (O(N) per frequency and loaded DOF;
    support motion by reciprocity, O(N) per frequency and output).

    Parameters
    ----------
    beam : Beam
        With damping (``rayleigh``, or dampers at supports): the peaks are infinite without.
""", """
    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn import Beam
    >>> from dtdyn.random_vibration import beam_random_response
    >>> beam = Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=20,
    ...             rayleigh=(1.0, 1e-5))
    >>> r = beam_random_response(beam, 1.0, np.linspace(1.0, 500.0, 40), force_dofs=["w20"],
    ...                          outputs=["w20", "w10"], quantities=("x",))
    >>> r.x_psd.shape, r.dof_names
    ((40, 2, 2), ('w20', 'w10'))
""")


@public
def shaft_random_response(shaft, psd, freqs_hz, *, force_dofs=None, outputs=None,
                          quantities=("x", "v", "a"), ground_acceleration_psd=None,
                          influence=None, accuracy=1e-8) -> RandomResponse:
    from dtdyn.linear._shaft import Shaft
    if not isinstance(shaft, Shaft):
        raise ValueError(f"shaft must be a Shaft, got {type(shaft).__name__}")
    return _run(_Stations(shaft, "shaft"), psd, freqs_hz, force_dofs, outputs, quantities,
                ground_acceleration_psd, influence, accuracy)


shaft_random_response.__wrapped__.__doc__ = shaft_random_response.__doc__ = _doc("""Response
    PSDs (rotations, rad^2/Hz; torques' PSDs in (N m)^2/Hz) of a `Shaft`'s lumped model (that
    of `shaft_matrices`) under random torques or support rotation, by
    `shaft_frequency_response` with ``exact=False`` (O(N) per frequency and loaded DOF;
    support motion by reciprocity, O(N) per frequency and output).

    Parameters
    ----------
    shaft : Shaft
        With damping: the peaks are infinite without.
""", """
    Examples
    --------
    >>> import numpy as np
    >>> from dtdyn import Shaft
    >>> from dtdyn.random_vibration import shaft_random_response
    >>> shaft = Shaft([1.0, 0.5], [1e4, 5e3], [2.0, 1.0])
    >>> r = shaft_random_response(shaft, 1.0, np.linspace(0.0, 60.0, 25), force_dofs=[1])
    >>> r.rms["x"].shape
    (2,)
""")
