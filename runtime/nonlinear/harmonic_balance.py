"""Periodic steady state of M q'' + C q' + K q + L^T g(L q, L q') = f(t) by harmonic balance.

The motion and the force are truncated Fourier series of the forcing's angular frequency omega,

    q(t) = Re sum_{k=0}^{H} Q_k e^{i k omega t},     f(t) = Re sum_k F_k e^{i k omega t},

and each harmonic of the linear part is solved through its receptance
H(w) = (K - w^2 M + i w C)^-1, so that only the elements' deformations y = L q are unknown
(the condensation):

    R_k = Y_k - L H(k omega) P F_k + L H(k omega) L^T G_k(Y, omega) = 0,    k = 0 .. H,

with P placing the loaded DOFs and G_k the harmonics of the element forces g(y(t), y'(t)).
G_k comes from alternating frequency-time evaluation (AFT): y and y' sampled at N points of a
period by an inverse FFT, the element laws evaluated there, G_k by the FFT. The Jacobian
dG/dY = E_f diag(dg/dy) E_i + omega E_f diag(dg/dy') E_i D uses the laws' exact derivatives
(CasADi), E_i and E_f the sampling and projection matrices of the real Fourier basis, D the
derivative in that basis. The outputs follow as X_k = H_o(k omega) (P F_k - L^T G_k).

The curve (Y, omega) is continued by pseudo-arclength (predictor along the tangent, Newton
corrector orthogonal to it, in variables scaled by the largest |Y| so far and the frequency
span; step grown or cut by the corrector's iteration count and the tangent's turn), so it goes
through folds; a fold is a sign change of the tangent's frequency component, refined by a
root search on that component along the arc.

Stability: Hill's method on the full model. A perturbation e^{lambda t} p(t), p periodic,
gives the quadratic eigenproblem

    [lambda^2 M_h + lambda (2 M_h N + C_h + G_v) + (M_h N^2 + C_h N + K_h + G_y + G_v N)] p = 0

in the Fourier coefficients of p (N = omega D, M_h = I (x) M, ..., G_y, G_v the elements'
linearization dg/dy, dg/dy' in the harmonic basis). Of its 2 n (2 H + 1) eigenvalues the 2 n
with the smallest |Im lambda| approximate the Floquet exponents (the others are copies shifted
by i k omega); the orbit is stable when all have Re lambda < 0 (Floquet multipliers
e^{lambda T} inside the unit circle). References: Krack & Gross, "Harmonic Balance for
Nonlinear Vibration Problems", Springer 2019 (ch. 2-5); Cameron & Griffin, J. Appl. Mech. 56
(1989) 149 (AFT); Lazarus & Thomas, C. R. Mecanique 338 (2010) 510 (Hill's method).
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn._engine import linalg, validate
from dtdyn._engine.errors import NewtonError
from dtdyn._engine.extras import require
from dtdyn._engine.public import public
from dtdyn.nonlinear.elements import casadi_ops, check_elements, element_matrix

__all__ = ["harmonic_balance", "HarmonicBalanceResult"]

#: the modal receptance is used up to this many DOFs (dense eigenproblem of size 2n, once);
#: beyond, and for sparse M, K, a sparse LU of K - w^2 M + i w C per harmonic and evaluation
MODAL_MAX_DOFS = 2000


# ----------------------------------------------------------------------------------------------
# receptances of the linear part, restricted to the rows L, outputs and columns L^T, P


class _ModalReceptance:
    """H(w) = sum_r psi_r x_r / (i w - s_r) over all 2n poles (exact, not truncated)."""

    name = "modal"

    def __init__(self, M, C, K, rows, cols):
        from dtdyn.modal.model import modal_factors
        s, psi, x = modal_factors(M, C, K)
        self.s, self.A, self.B = s, rows @ psi, x @ cols

    def __call__(self, w):
        d = 1.0 / (1j * w[:, None] - self.s[None, :])
        H = np.einsum("rp,mp,pc->mrc", self.A, d, self.B)
        dH = np.einsum("rp,mp,pc->mrc", self.A, -1j * d * d, self.B)
        return H, dH


class _DirectReceptance:
    """H(w) by solves with D(w) = K - w^2 M + i w C (a sparse LU when M, K are sparse);
    dH/dw = -H D'(w) H from the transposed solve (the rows) and the plain one (the columns)."""

    name = "direct"

    def __init__(self, M, C, K, rows, cols):
        self.M, self.C, self.K, self.rows, self.cols = M, C, K, rows, cols
        self.sparse = sps.issparse(M)

    def __call__(self, w):
        r, c = self.rows.shape[0], self.cols.shape[1]
        H = np.empty((w.size, r, c), complex)
        dH = np.empty_like(H)
        for m, wk in enumerate(w):
            D = self.K - wk * wk * self.M + 1j * wk * self.C
            dD = -2.0 * wk * self.M + 1j * self.C
            if self.sparse:
                lu = spla.splu(sps.csc_matrix(D))
                Z = lu.solve(np.asarray(self.cols, complex))
                W = lu.solve(np.asarray(self.rows.T, complex), trans="T")
            else:
                Z = np.linalg.solve(D, self.cols)
                W = np.linalg.solve(D.T, self.rows.T)
            H[m] = self.rows @ Z
            dH[m] = -(W.T @ (dD @ Z))
        return H, dH


# ----------------------------------------------------------------------------------------------
# the real Fourier basis: y(theta) = Y_0 + sum_k Re Y_k cos k theta - Im Y_k sin k theta


def _basis(H: int, N: int):
    """E_i (N x 2H+1): samples of the basis; E_f: the projection (E_f E_i = I); D: d/dtheta."""
    theta = 2.0 * np.pi * np.arange(N) / N
    Ei = np.empty((N, 2 * H + 1))
    Ei[:, 0] = 1.0
    D = np.zeros((2 * H + 1, 2 * H + 1))
    for k in range(1, H + 1):
        Ei[:, 2 * k - 1] = np.cos(k * theta)
        Ei[:, 2 * k] = -np.sin(k * theta)
        D[2 * k - 1, 2 * k] = -k          # (a + i b) i k = -k b + i k a
        D[2 * k, 2 * k - 1] = k
    Ef = Ei.T * (2.0 / N)
    Ef[0] = 1.0 / N
    return Ei, Ef, D


def _complex(U):
    """(2H+1, m) real layout -> (H+1, m) complex harmonics."""
    Y = np.empty((U.shape[0] // 2 + 1, U.shape[1]), complex)
    Y[0] = U[0]
    Y[1:] = U[1::2] + 1j * U[2::2]
    return Y


def _real(Y):
    U = np.empty((2 * Y.shape[0] - 1, Y.shape[1]))
    U[0] = Y[0].real
    U[1::2] = Y[1:].real
    U[2::2] = Y[1:].imag
    return U


def _samples(Y, N):
    """Time samples over one period (N x m) of Re sum_k Y_k e^{i k theta} (inverse FFT)."""
    spec = np.zeros((N // 2 + 1, Y.shape[1]), complex)
    spec[0] = N * Y[0].real
    spec[1:Y.shape[0]] = 0.5 * N * Y[1:]
    return np.fft.irfft(spec, n=N, axis=0)


def _block_real(A):
    """The real (2H+1)r x (2H+1)c matrix of y_k = A_k x_k per harmonic (A: (H+1, r, c))."""
    nh, r, c = A.shape
    out = np.zeros(((2 * nh - 1), r, (2 * nh - 1), c))
    out[0, :, 0, :] = A[0].real
    for k in range(1, nh):
        a, b = 2 * k - 1, 2 * k
        out[a, :, a, :], out[a, :, b, :] = A[k].real, -A[k].imag
        out[b, :, a, :], out[b, :, b, :] = A[k].imag, A[k].real
    return out.reshape((2 * nh - 1) * r, (2 * nh - 1) * c)


# ----------------------------------------------------------------------------------------------
# the elements' laws with their derivatives (CasADi)


def _law_function(elements, N):
    """f(y, v) -> (g, dg/dy, dg/dv), each (ne, N), mapped over the N samples of a period."""
    ca = require("casadi", "nonlinear", "harmonic_balance")
    ops = casadi_ops()
    ne = len(elements)
    y, v = ca.SX.sym("y", ne), ca.SX.sym("v", ne)
    g = [el.force(y[e], v[e], [], ops) for e, el in enumerate(elements)]
    g = [ca.SX(ge) if not isinstance(ge, ca.SX) else ge for ge in g]
    gy = [ca.gradient(g[e], y[e]) for e in range(ne)]
    gv = [ca.gradient(g[e], v[e]) for e in range(ne)]
    fn = ca.Function("laws", [y, v], [ca.vertcat(*g), ca.vertcat(*gy), ca.vertcat(*gv)])
    mapped = fn.map(N)

    def evaluate(ys, vs):
        out = mapped(ys, vs)
        return tuple(np.array(o, dtype=float).reshape(ne, N) for o in out)
    return evaluate


# ----------------------------------------------------------------------------------------------
# the condensed residual R(U, omega) and its Jacobian


class _System:
    def __init__(self, receptance, laws, ne, no, F, H, N):
        self.rec, self.laws, self.ne, self.no, self.F, self.H, self.N = (receptance, laws, ne,
                                                                         no, F, H, N)
        self.Ei, self.Ef, self.D = _basis(H, N)
        self.k = np.arange(H + 1, dtype=float)
        self.evaluations = 0

    def receptance(self, omega):
        Hm, dHm = self.rec(self.k * omega)
        return Hm, dHm * self.k[:, None, None]     # d/d omega of H(k omega)

    def forces(self, U, omega):
        """(G complex (H+1, ne), g, dg/dy, dg/dv samples (ne, N), y' samples (N, ne))."""
        Y = _complex(U)
        y = _samples(Y, self.N)
        yd = _samples(1j * self.k[:, None] * Y, self.N) * omega
        g, gy, gv = self.laws(y.T, yd.T)
        self.evaluations += 1
        spec = np.fft.rfft(g, axis=1).T * (2.0 / self.N)
        spec[0] *= 0.5
        return spec[:self.H + 1], g, gy, gv

    def residual(self, U, omega, jacobian=True):
        ne, H = self.ne, self.H
        Hm, dHm = self.receptance(omega)
        G, g, gy, gv = self.forces(U, omega)
        Hyy, Hyf = Hm[:, :ne, :ne], Hm[:, :ne, ne:]
        R = _complex(U) - np.einsum("kec,kc->ke", Hyf, self.F) \
            + np.einsum("kef,kf->ke", Hyy, G)
        R = _real(R).ravel()
        if not jacobian:
            return R, None, None
        Jel = (np.einsum("jn,en,nk->ejk", self.Ef, gy, self.Ei)
               + omega * np.einsum("jn,en,nk->ejk", self.Ef, gv, self.Ei @ self.D))
        nU = (2 * H + 1) * ne
        Jg = np.zeros((2 * H + 1, ne, 2 * H + 1, ne))
        idx = np.arange(ne)
        Jg[:, idx, :, idx] = Jel
        JU = np.eye(nU) + _block_real(Hyy) @ Jg.reshape(nU, nU)
        dG = _complex(self.Ef @ (gv.T * (self.Ei @ self.D @ U)))
        dR = (-np.einsum("kec,kc->ke", dHm[:, :ne, ne:], self.F)
              + np.einsum("kef,kf->ke", dHm[:, :ne, :ne], G)
              + np.einsum("kef,kf->ke", Hyy, dG))
        return R, JU, _real(dR).ravel()

    def outputs(self, U, omega):
        """The outputs' complex harmonics (H+1, no)."""
        ne = self.ne
        Hm, _ = self.receptance(omega)
        G = self.forces(U, omega)[0]
        return (np.einsum("koc,kc->ko", Hm[:, ne:, ne:], self.F)
                - np.einsum("kof,kf->ko", Hm[:, ne:, :ne], G))

    def linearization(self, U, omega):
        """The elements' dg/dy and dg/dy' in the harmonic basis: (ne, 2H+1, 2H+1) each."""
        _, _, gy, gv = self.forces(U, omega)
        return (np.einsum("jn,en,nk->ejk", self.Ef, gy, self.Ei),
                np.einsum("jn,en,nk->ejk", self.Ef, gv, self.Ei))


# ----------------------------------------------------------------------------------------------
# Hill's method


def _hill(M, C, K, L, Jy, Jv, omega, D):
    """The 2n Floquet exponents (those with the smallest |Im|) of the orbit (module docstring)."""
    n, nH = M.shape[0], D.shape[0]
    I_H = np.eye(nH)
    Nab = omega * D
    Gy = sum(np.kron(Jy[e], np.outer(L[e], L[e])) for e in range(L.shape[0]))
    Gv = sum(np.kron(Jv[e], np.outer(L[e], L[e])) for e in range(L.shape[0]))
    A2 = np.kron(I_H, M)
    A1 = 2.0 * np.kron(Nab, M) + np.kron(I_H, C) + Gv
    A0 = (np.kron(Nab @ Nab, M) + np.kron(Nab, C) + np.kron(I_H, K) + Gy
          + Gv @ np.kron(Nab, np.eye(n)))
    m = n * nH
    Z, I_m = np.zeros((m, m)), np.eye(m)
    lam = sla.eigvals(np.block([[Z, I_m], [-A0, -A1]]), np.block([[I_m, Z], [Z, A2]]))
    lam = lam[np.isfinite(lam)]
    keep = lam.size // nH
    return lam[np.argsort(np.abs(lam.imag), kind="stable")[:keep]]


# ----------------------------------------------------------------------------------------------
# the result


@dataclass(frozen=True)
class HarmonicBalanceResult:
    """A periodic steady-state frequency response curve (one entry per point along the arc).

    Attributes
    ----------
    frequency_hz, omega : (points,) ndarray
        Forcing frequency of each point, Hz and rad/s (not monotonic through folds).
    harmonics : (points, outputs, H + 1) complex ndarray
        X_k of each output: x(t) = Re sum_k X_k e^{i k omega t}.
    x_max : (points, outputs) ndarray
        max |x(t)| over a period.
    rms : (points, outputs) ndarray
        The root mean square of x(t) over a period.
    stable : (points,) bool ndarray or None
        Hill's method (None when ``stability=False``).
    floquet_exponents : (points, 2n) complex ndarray or None
        The Floquet exponents from Hill's method, 1/s (multipliers exp(lambda T)).
    folds : (folds,) int ndarray
        Index of the point next to each fold (sign change of d omega / ds).
    fold_frequency_hz : (folds,) ndarray
        The folds' frequencies, refined along the arc.
    outputs : (outputs,) int ndarray
    element_harmonics : (points, elements, H + 1) complex ndarray
        Y_k of each element's deformation.
    info : dict
        newton_iterations, steps, rejected_steps, law_evaluations, run_time, receptance,
        n_time, harmonics, stop.
    """

    frequency_hz: np.ndarray
    omega: np.ndarray
    harmonics: np.ndarray
    x_max: np.ndarray
    rms: np.ndarray
    stable: np.ndarray | None
    floquet_exponents: np.ndarray | None
    folds: np.ndarray
    fold_frequency_hz: np.ndarray
    outputs: np.ndarray
    element_harmonics: np.ndarray
    info: dict = field(default_factory=dict)

    def plot(self, output: int = 0, ax=None):
        """x_max of ``outputs[output]`` against frequency, unstable points dashed."""
        plt = require("matplotlib.pyplot", "plot", "HarmonicBalanceResult.plot")
        if ax is None:
            ax = plt.figure().add_subplot()
        f, x = self.frequency_hz, self.x_max[:, output]
        st = np.ones(f.size, bool) if self.stable is None else self.stable
        for i in range(f.size - 1):
            ax.plot(f[i:i + 2], x[i:i + 2], "C0-" if st[i] and st[i + 1] else "C3--", lw=1.2)
        ax.set_xlabel("frequency, Hz")
        ax.set_ylabel(f"max |x| of DOF {int(self.outputs[output])}")
        return ax


def _peak(Y, n_eval=4096):
    """max |x(t)| of each column of harmonics Y (H+1, m): samples + parabolic refinement."""
    x = _samples(Y, n_eval)
    a = np.abs(x)
    i = np.argmax(a, axis=0)
    cols = np.arange(a.shape[1])
    y0, y1, y2 = a[(i - 1) % n_eval, cols], a[i, cols], a[(i + 1) % n_eval, cols]
    den = y0 - 2 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(den < 0, 0.5 * (y0 - y2) / den, 0.0)
    return y1 - 0.25 * (y0 - y2) * p


# ----------------------------------------------------------------------------------------------
# input checks


def _force_harmonics(force, nf, H):
    arr = np.asarray(force)
    if not np.issubdtype(arr.dtype, np.number) or arr.dtype == bool:
        raise ValueError(f"force must be numbers (amplitudes per loaded DOF), got {force!r}")
    arr = arr.astype(complex)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim == 1:
        if arr.size != nf:
            raise ValueError(f"force has {arr.size} amplitude(s), expected one per force_dofs "
                             f"entry ({nf})")
        F = np.zeros((H + 1, nf), complex)
        F[1] = arr
    elif arr.ndim == 2:
        if arr.shape[0] != nf or arr.shape[1] > H + 1:
            raise ValueError(f"force has shape {arr.shape}, expected (len(force_dofs), m) = "
                             f"({nf}, m) with m <= harmonics + 1 = {H + 1} (columns: "
                             "harmonics 0, 1, ...)")
        F = np.zeros((H + 1, nf), complex)
        F[:arr.shape[1]] = arr.T
        if np.any(F[0].imag != 0):
            raise ValueError("force[:, 0] is the static part (harmonic 0) and must be real, got "
                             f"{arr[:, 0]!r}")
    else:
        raise ValueError(f"force must be 1-D (one amplitude per loaded DOF) or 2-D (loaded DOF "
                         f"x harmonic), got shape {arr.shape}")
    if not np.all(np.isfinite(F)):
        raise ValueError(f"force has a non-finite amplitude: {force!r}")
    if not np.any(F):
        raise ValueError("force is zero everywhere: a forced response needs a non-zero force "
                         "(the unforced backbone is not implemented)")
    return F


def _frequency_range(frequencies):
    try:
        f = np.asarray(frequencies, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"frequencies must be (start, end) in Hz, got {frequencies!r}") from None
    if f.shape != (2,) or not np.all(np.isfinite(f)) or np.any(f <= 0) or f[0] == f[1]:
        raise ValueError(f"frequencies must be (start, end) in Hz, two different finite "
                         f"numbers > 0, got {frequencies!r}")
    return float(f[0]), float(f[1])


def _positive_int(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


# ----------------------------------------------------------------------------------------------
# continuation


class _Continuation:
    def __init__(self, system, tol, max_iter, w_span):
        self.s, self.tol, self.max_iter, self.sw = system, tol, max_iter, w_span
        self.su = 0.0
        self.newton = 0

    def scaled_jac(self, JU, Jw):
        return np.column_stack([JU, Jw * self.sw / self.su])

    def solve_fixed(self, U, omega):
        """Newton at fixed omega; U (2H+1, ne)."""
        shape = U.shape
        u = U.ravel().copy()
        for it in range(1, self.max_iter + 1):
            R, JU, _ = self.s.residual(u.reshape(shape), omega)
            du = _solve(JU, R)
            u -= du
            self.newton += 1
            if not np.all(np.isfinite(u)):
                break
            if np.abs(du).max() <= self.tol * max(np.abs(u).max(), self.su, 1e-300):
                return u.reshape(shape), it
        raise NewtonError(f"harmonic_balance: Newton did not converge at {omega / 2 / np.pi:.6g}"
                          f" Hz in {self.max_iter} iterations (residual "
                          f"{np.abs(R).max():.3g} m)")

    def tangent(self, U, omega, previous):
        R, JU, Jw = self.s.residual(U, omega)
        J = self.scaled_jac(JU, Jw)
        t = _solve(np.vstack([J, previous]), np.concatenate([np.zeros(J.shape[0]), [1.0]]))
        t /= np.linalg.norm(t)
        return t if t @ previous > 0 else -t

    def correct(self, x_pred, t, x0, ds):
        """Pseudo-arclength Newton: R(x) = 0, t . (x - x0) = ds; None when it fails."""
        x = x_pred.copy()
        shape = (2 * self.s.H + 1, self.s.ne)
        for it in range(1, self.max_iter + 1):
            U, omega = x[:-1].reshape(shape) * self.su, x[-1] * self.sw
            R, JU, Jw = self.s.residual(U, omega)
            A = np.vstack([self.scaled_jac(JU, Jw), t])
            b = np.concatenate([R / self.su, [t @ (x - x0) - ds]])
            try:
                dx = _solve(A, b)
            except np.linalg.LinAlgError:
                return None, it
            x = x - dx
            self.newton += 1
            if not np.all(np.isfinite(x)):
                return None, it
            if np.abs(dx).max() <= self.tol * max(np.abs(x[:-1]).max(), 1.0):
                return x, it
        return None, self.max_iter


def _solve(A, b):
    with warnings.catch_warnings():
        warnings.simplefilter("error", sla.LinAlgWarning)
        try:
            return sla.solve(A, b)
        except sla.LinAlgWarning:
            return np.linalg.lstsq(A, b, rcond=None)[0]


@public
def harmonic_balance(M, C, K, *, elements, force_dofs, force, frequencies, harmonics=7,  # noqa: C901
                     outputs=None, n_time=None, receptance="auto", stability=True, step=0.02,
                     max_step=0.1, min_step=1e-7, max_angle=0.35, max_points=5000, tol=1e-10,
                     max_iter=20) -> HarmonicBalanceResult:
    """Periodic steady-state frequency response of M q'' + C q' + K q + L^T g = f(t) by
    harmonic balance with pseudo-arclength continuation (through folds) and Hill's stability.

    Parameters
    ----------
    M, C, K : (n, n) array_like or scipy.sparse matrix
        The linear part (K - w^2 M + i w C nonsingular at every harmonic k omega: no rigid-body
        mode, and damping where k omega meets a natural frequency).
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap` (its kink is sampled, not resolved), `Law` (in x and v);
        `BoucWen` (internal state) is not supported.
    force_dofs : sequence of int
        0-based loaded DOFs.
    force : array_like
        Shape (len(force_dofs),): amplitudes F of f(t) = Re(F e^{i omega t}) (a real F is
        F cos omega t). Shape (len(force_dofs), m), m <= harmonics + 1: column k is F_k of
        f(t) = Re sum_k F_k e^{i k omega t} (column 0 the static force, real).
    frequencies : (start, end)
        The forcing frequency range, Hz; the curve is continued from start to end (end < start
        sweeps down).
    harmonics : int
        H, the highest harmonic kept (0 .. H, the static part included).
    outputs : sequence of int, optional
        DOFs whose harmonics are returned (all by default).
    n_time : int, optional
        Samples per period of the AFT (default: the power of 2 >= 8 (H + 1); at least 2 H + 2).
        A polynomial law of degree p is alias-free from (p + 1) H + 1 samples.
    receptance : {"auto", "modal", "direct"}
        "modal": the exact modal sum over all 2n poles (one eigenproblem, then O(n) per
        harmonic); "direct": an LU of K - w^2 M + i w C per harmonic and evaluation (sparse
        matrices stay sparse). "auto": modal for dense models up to 2000 DOFs, else direct.
    stability : bool
        Hill's method at every point (dense, of size 2 n (2 H + 1)).
    step, max_step, min_step : float
        Initial, largest and smallest arclength step in the scaled variables (frequency per
        the range's span, deformations per their largest amplitude so far).
    max_angle : float
        A step whose tangent turns by more than this (rad) is retried at half the length.
    max_points : int
        The most points along the curve.
    tol : float
        Newton stops when its step is below ``tol`` times the largest scaled unknown.
    max_iter : int
        Newton iterations per corrector.

    Returns
    -------
    HarmonicBalanceResult

    Raises
    ------
    NewtonError
        No solution at the start frequency, or the step fell below ``min_step``.

    Notes
    -----
    The equations, AFT, the condensation, the continuation and Hill's method are in the module
    docstring and docs/guide/harmonic_balance.md. Krack & Gross, "Harmonic Balance for
    Nonlinear Vibration Problems", Springer 2019.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.harmonic_balance(np.eye(1), [[0.05]], np.eye(1), elements=[dd.Cubic(0, k3=0.1)],
    ...                         force_dofs=[0], force=[0.05], frequencies=(0.1, 0.3),
    ...                         harmonics=3)
    >>> bool(r.stable.all()), r.folds.size
    (True, 0)
    """
    t_start = time.perf_counter()
    sparse = sps.issparse(M) or sps.issparse(K)
    M, C, K = linalg.mck(M, C, K, keep_sparse=sparse)
    n = M.shape[0]
    elements = check_elements(elements)
    if not elements:
        raise ValueError("elements is empty: harmonic_balance needs at least one element (a "
                         "Cubic(i, k3=0) gives the linear response)")
    for e, el in enumerate(elements):
        if el.n_internal:
            raise ValueError(f"elements[{e}] ({el.describe()}) has internal states (hysteresis):"
                             " harmonic_balance does not support it yet")
    H = _positive_int("harmonics", harmonics, 1)
    N = 2 ** math.ceil(math.log2(8 * (H + 1))) if n_time is None else \
        _positive_int("n_time", n_time, 2 * H + 2)
    force_dofs = validate.dof_indices("force_dofs", force_dofs, n, default_all=False)
    outputs = validate.dof_indices("outputs", outputs, n)
    F = _force_harmonics(force, force_dofs.size, H)
    f0, f1 = _frequency_range(frequencies)
    if receptance not in ("auto", "modal", "direct"):
        raise ValueError(f"receptance must be 'auto', 'modal' or 'direct', got {receptance!r}")
    validate.flag("stability", stability)
    step = validate.positive_scalar("step", step)
    max_step = validate.positive_scalar("max_step", max_step)
    min_step = validate.positive_scalar("min_step", min_step)
    max_angle = validate.positive_scalar("max_angle", max_angle)
    tol = validate.positive_scalar("tol", tol)
    max_iter = _positive_int("max_iter", max_iter, 1)
    max_points = _positive_int("max_points", max_points, 2)
    if min_step > step or step > max_step:
        raise ValueError(f"need min_step <= step <= max_step, got {min_step!r}, {step!r}, "
                         f"{max_step!r}")

    L = element_matrix(elements, n)
    ne, no = len(elements), outputs.size
    P = np.zeros((n, force_dofs.size))
    P[force_dofs, np.arange(force_dofs.size)] = 1.0
    Po = np.zeros((no, n))
    Po[np.arange(no), outputs] = 1.0
    rows, cols = np.vstack([L, Po]), np.hstack([L.T, P])
    if receptance == "auto":
        receptance = "direct" if (sparse or n > MODAL_MAX_DOFS) else "modal"
    if receptance == "modal":
        if sparse:
            validate.dense_conversion("M", M, copies=3)
            M, C, K = M.toarray(), C.toarray(), K.toarray()
        rec = _ModalReceptance(M, C, K, rows, cols)
    else:
        if sparse:
            M, C, K = sps.csc_matrix(M), sps.csc_matrix(C), sps.csc_matrix(K)
        rec = _DirectReceptance(M, C, K, rows, cols)
    system = _System(rec, _law_function(elements, N), ne, no, F, H, N)

    w0, w1 = 2 * np.pi * f0, 2 * np.pi * f1
    direction = 1.0 if w1 > w0 else -1.0
    cont = _Continuation(system, tol, max_iter, abs(w1 - w0))

    # the first point: Newton at the start frequency from the linear response
    Hm, _ = system.receptance(w0)
    U = _real(np.einsum("kec,kc->ke", Hm[:, :ne, ne:], F))
    cont.su = max(np.abs(U).max(), 1e-300)
    U, _ = cont.solve_fixed(U, w0)
    cont.su = max(np.abs(U).max(), 1e-300)
    nx = U.size + 1
    e_w = np.zeros(nx)
    e_w[-1] = direction
    t = cont.tangent(U, w0, e_w)

    points = [(U, w0)]
    tw = [t[-1]]
    arcs = []               # (U_i, omega_i, t_i, ds, su) of each accepted step, for the folds
    ds, steps, rejected, stop = step, 0, 0, "end of the range"
    while True:
        if len(points) >= max_points:
            stop = "max_points"
            warnings.warn(f"harmonic_balance stopped after max_points = {max_points} points at "
                          f"{points[-1][1] / 2 / np.pi:.6g} Hz", RuntimeWarning, stacklevel=2)
            break
        U, w = points[-1]
        x0 = np.concatenate([U.ravel() / cont.su, [w / cont.sw]])
        x, its = cont.correct(x0 + ds * t, t, x0, ds)
        t_new = None
        if x is not None:
            U_new, w_new = x[:-1].reshape(U.shape) * cont.su, x[-1] * cont.sw
            su_old = cont.su
            cont.su = max(cont.su, np.abs(U_new).max())
            t_prev = np.concatenate([t[:-1] * su_old / cont.su, t[-1:]])
            t_new = cont.tangent(U_new, w_new, t_prev / np.linalg.norm(t_prev))
            cos = float(np.clip(t_new @ t_prev / np.linalg.norm(t_prev), -1, 1))
            if math.acos(cos) > max_angle:
                cont.su = su_old
                t_new = None
        if t_new is None:
            rejected += 1
            ds *= 0.5
            if ds < min_step:
                raise NewtonError(f"harmonic_balance: the arclength step fell below min_step = "
                                  f"{min_step:g} at {w / 2 / np.pi:.6g} Hz (a bifurcation, a "
                                  "kink of a law, or a resonance of the linear part without "
                                  "damping?)")
            continue
        steps += 1
        arcs.append((U, w, t, ds, su_old))
        if (w_new - w1) * direction > 0:        # past the end: the last point at the end
            frac = (w1 - w) / (w_new - w)
            U_end, _ = cont.solve_fixed(U + frac * (U_new - U), w1)
            points.append((U_end, w1))
            tw.append(cont.tangent(U_end, w1, t_new)[-1])
            break
        points.append((U_new, w_new))
        tw.append(t_new[-1])
        t = t_new
        if (w_new - w0) * direction < 0:
            stop = "left the range below the start frequency"
            break
        ds = min(max_step, ds * (1.5 if its <= 3 else (1.0 if its <= 6 else 0.6)))

    # folds: sign changes of d omega / ds, refined by a root search along the arc
    folds, fold_w = [], []
    tw = np.asarray(tw)
    for i in range(len(tw) - 1):
        if np.sign(tw[i]) != np.sign(tw[i + 1]) and i < len(arcs):
            folds.append(i if abs(tw[i]) < abs(tw[i + 1]) else i + 1)
            fold_w.append(_refine_fold(cont, *arcs[i], tw[i], tw[i + 1]))

    Us = np.array([p[0] for p in points])
    omega = np.array([p[1] for p in points])
    X = np.array([system.outputs(U, w) for U, w in points])          # (points, H+1, no)
    Yel = np.array([_complex(U) for U in Us])                        # (points, H+1, ne)
    x_max = np.array([_peak(Xp) for Xp in X])
    rms = np.sqrt(np.abs(X[:, 0].real) ** 2 + 0.5 * np.sum(np.abs(X[:, 1:]) ** 2, axis=1))
    stable = lam = None
    if stability:
        Md, Cd, Kd = ((A.toarray() if sps.issparse(A) else A) for A in (M, C, K))
        _, _, D = _basis(H, N)
        lam = []
        for U, w in points:
            Jy, Jv = system.linearization(U, w)
            lam.append(_hill(Md, Cd, Kd, L, Jy, Jv, w, D))
        width = max(v.size for v in lam)
        lam = np.array([np.pad(v, (0, width - v.size), constant_values=np.nan) for v in lam])
        stable = np.nanmax(lam.real, axis=1) < 1e-9 * omega
    info = dict(newton_iterations=cont.newton, steps=steps, rejected_steps=rejected,
                law_evaluations=system.evaluations, run_time=time.perf_counter() - t_start,
                receptance=rec.name, n_time=N, harmonics=H, stop=stop)
    return HarmonicBalanceResult(
        frequency_hz=omega / (2 * np.pi), omega=omega, harmonics=np.transpose(X, (0, 2, 1)),
        x_max=x_max, rms=rms, stable=stable, floquet_exponents=lam,
        folds=np.array(folds, dtype=np.int64), fold_frequency_hz=np.array(fold_w) / (2 * np.pi),
        outputs=outputs, element_harmonics=np.transpose(Yel, (0, 2, 1)), info=info)


def _refine_fold(cont, U, w, t, ds, su, tw0, tw1):
    """omega at d omega / ds = 0 between a point and the next: the root of the tangent's
    frequency component along the step (secant/bisection on the arclength, brentq)."""
    from scipy.optimize import brentq
    su_now = cont.su
    cont.su = su
    x0 = np.concatenate([U.ravel() / su, [w / cont.sw]])
    found = {}

    def tw_at(s):
        x, _ = cont.correct(x0 + s * t, t, x0, s)
        if x is None:
            raise NewtonError("fold refinement failed")
        Ux, wx = x[:-1].reshape(U.shape) * su, x[-1] * cont.sw
        found[s] = wx
        return cont.tangent(Ux, wx, t)[-1]
    try:
        s = brentq(tw_at, 0.0, ds, xtol=1e-12 * ds, rtol=1e-14)
        tw_at(s)
        return found[s]
    except (NewtonError, ValueError):
        return w
    finally:
        cont.su = su_now
