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

Models: a Chain, Beam, Shaft or Matrices in place of M, C, K brings its (sparse) matrices, DOF
names and rigid motion; a sparse symmetric banded model's receptance is LAPACK's banded LU
(O(n) per harmonic; Z = D^-1 [L^T, B], and D symmetric gives dH/dw = -Z_L^T D' Z), or, with
Rayleigh damping and 50 DOFs or more, the reduced one (dtdyn.nonlinear._receptance: the modes
below a cut-off and a residual series, O(1) per harmonic). Support
motion adds the load -M r a_g (relative coordinates); `harmonic_balance_amplitude` continues in
the load factor s at a fixed omega instead (R_k = Y_k - s L H P F_k + L H L^T G_k).

Stability: Hill's method on the full model. A perturbation e^{lambda t} p(t), p periodic,
gives the quadratic eigenproblem

    [lambda^2 M_h + lambda (2 M_h N + C_h + G_v) + (M_h N^2 + C_h N + K_h + G_y + G_v N)] p = 0

in the Fourier coefficients of p (N = omega D, M_h = I (x) M, ..., G_y, G_v the elements'
linearization dg/dy, dg/dy' in the harmonic basis). Its 2 n (2 H + 1) eigenvalues are the
Floquet exponents and their copies shifted by i k omega (with p e^{-i k omega t}); of each the
copy whose eigenvector is centred on harmonic 0 (the centre of mass sum_k k |p_k|^2 /
sum_k |p_k|^2 over k = -H .. H within 1/2 of 0; among more such, the smallest |Im lambda|) is
kept, 2 n in all; the orbit is stable when all
have Re lambda < 0 (Floquet multipliers e^{lambda T} inside the unit circle). An exponent
crossing Re lambda = 0 between two points is located along the arc (Brent's method on its real
part) and named by its Im lambda there, modulo omega: 0 a fold (from the tangent) or a branch
point, omega / 2 a period doubling, else a Neimark-Sacker bifurcation. References: Krack &
Gross, "Harmonic Balance for Nonlinear Vibration Problems", Springer 2019 (ch. 2-5); Cameron &
Griffin, J. Appl. Mech. 56 (1989) 149 (AFT); Lazarus & Thomas, C. R. Mecanique 338 (2010) 510
(Hill's method); Peletan, Baguet, Torkhani & Jacquet-Richardet, Nonlinear Dyn. 72 (2013) 671,
and Guillot, Lazarus, Thomas, Vergez & Cochelin, J. Comput. Phys. 416 (2020) 109477 (the
selection by the eigenvectors). On a large model (``stability="reduced"``, or "auto" above
2 n (2 H + 1) = 6000) the same eigenproblem is solved for a reduced model: the modes below
2 (H + 1) omega_top and the elements' attachment modes P K^{-1} L^T with two mass corrections,
M, C, K projected (`dtdyn.nonlinear._hill_reduced`).
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
from dtdyn.nonlinear._elements import casadi_ops, check_elements, element_matrix

__all__ = ["harmonic_balance", "harmonic_balance_amplitude", "HarmonicBalanceResult"]

#: the modal receptance is used up to this many DOFs (dense eigenproblem of size 2n, once);
#: beyond, and for sparse M, K, a banded LU (symmetric banded models) or a sparse LU of
#: K - w^2 M + i w C per harmonic and evaluation
MODAL_MAX_DOFS = 2000


# ----------------------------------------------------------------------------------------------
# receptances of the linear part, restricted to the rows L, outputs and the columns L^T, B
# (B: the loads' patterns, P for the loaded DOFs, -M r for support motion). Each returns
# H (len(w), ne + no, ne + nb) and dH/dw (len(w), ne, ne + nb): the element rows only


class _ModalReceptance:
    """H(w) = sum_r psi_r x_r / (i w - s_r) over all 2n poles (exact, not truncated)."""

    name = "modal"

    def __init__(self, M, C, K, L, outputs, B):
        from dtdyn.modal._model import modal_factors
        s, psi, x = modal_factors(M, C, K)
        self.ne = L.shape[0]
        self.s, self.A, self.B = s, np.vstack([L @ psi, psi[outputs]]), x @ np.hstack([L.T, B])

    def __call__(self, w):
        d = 1.0 / (1j * w[:, None] - self.s[None, :])
        H = np.einsum("rp,mp,pc->mrc", self.A, d, self.B)
        dH = np.einsum("rp,mp,pc->mrc", self.A[:self.ne], -1j * d * d, self.B)
        return H, dH


class _DirectReceptance:
    """H(w) by solves with D(w) = K - w^2 M + i w C (a sparse LU when M, K are sparse);
    dH/dw = -H D'(w) H from the transposed solve (the element rows) and the plain one."""

    name = "direct"

    def __init__(self, M, C, K, L, outputs, B):
        self.M, self.C, self.K, self.L, self.outputs = M, C, K, L, outputs
        self.cols = np.hstack([L.T, B])
        self.sparse = sps.issparse(M)

    def __call__(self, w):
        ne = self.L.shape[0]
        r, c = ne + self.outputs.size, self.cols.shape[1]
        H = np.empty((w.size, r, c), complex)
        dH = np.empty((w.size, ne, c), complex)
        for m, wk in enumerate(w):
            D = self.K - wk * wk * self.M + 1j * wk * self.C
            dD = -2.0 * wk * self.M + 1j * self.C
            if self.sparse:
                lu = spla.splu(sps.csc_matrix(D))
                Z = lu.solve(np.asarray(self.cols, complex))
                W = lu.solve(np.asarray(self.L.T, complex), trans="T")
            else:
                Z = np.linalg.solve(D, self.cols)
                W = np.linalg.solve(D.T, self.L.T)
            H[m, :ne] = self.L @ Z
            H[m, ne:] = Z[self.outputs]
            dH[m] = -(W.T @ (dD @ Z))
        return H, dH


def _bandwidth(*mats) -> int:
    """The largest |i - j| of a stored entry of the sparse matrices."""
    return max((int(np.abs(A.row - A.col).max()) if A.nnz else 0)
               for A in (sps.coo_matrix(B) for B in mats))


def _symmetric(A, tol=1e-13) -> bool:
    diff = abs(A - A.T)
    return diff.nnz == 0 or diff.max() <= tol * max(abs(A).max(), 1e-300)


class _BandedReceptance:
    """H(w) of a banded symmetric model (a chain: tridiagonal; a beam: 2 x 2 node blocks,
    bandwidth 3; a shaft without branches) by LAPACK's banded LU with partial pivoting,
    O(n) per frequency, the method of `beam_frequency_response`. Z = D(w)^-1 [L^T, B] gives
    the element and output rows, and, D being symmetric, dH/dw = -Z_L^T D'(w) Z.

    With ``refine`` (receptance="banded" chosen, and the reference of "reduced"), each solve is
    refined (as `dtdyn.nonlinear._receptance.refined_solve`): corrections by the same LU with
    the residual [L^T, B] - D Z summed in twice the working precision (K Z and C Z exactly, M Z
    in working precision: its terms do not cancel), until a correction no longer halves. A
    beam of N elements loses about eps N^3.5 in the LU (docs/beam_conditioning.md);
    ``last_correction`` is the largest relative size of the last corrections of a call (near
    eps when the refinement converged). ``parts`` (alpha, beta, E) from
    `dtdyn.nonlinear._receptance.rayleigh_parts`: C Z is alpha M Z + beta K Z + E Z, K Z
    exactly (C's entries summed in double precision lose alpha M against beta K at large N)."""

    name = "banded"

    def __init__(self, M, C, K, L, outputs, B, width, refine=False, parts=None):
        self.refine, self.parts = refine, parts
        self.width, self.L, self.outputs = width, L, outputs
        cols = np.hstack([L.T, B])
        # a column repeated (a force where an element acts) is solved once
        unique, self.which = np.unique(cols, axis=1, return_inverse=True)
        self.which = self.which.ravel()
        self.cols = np.ascontiguousarray(unique, dtype=complex)
        self.ncols = cols.shape[1]
        self.M, self.C, self.K = sps.csr_matrix(M), sps.csr_matrix(C), sps.csr_matrix(K)
        self.bands = [self._band(A) for A in (M, C, K)]
        from dtdyn.nonlinear._receptance import band_diagonals
        self.kc = band_diagonals([K, C] if parts is None else [K], width)
        self.last_correction = 0.0

    def _band(self, A):
        """LAPACK's band storage ab[w + i - j, j] = A[i, j]."""
        A = sps.coo_matrix(A)
        ab = np.zeros((2 * self.width + 1, A.shape[0]))
        np.add.at(ab, (self.width + A.row - A.col, A.col), A.data)
        return ab

    def __call__(self, w):
        ne = self.L.shape[0]
        r = ne + self.outputs.size
        H = np.empty((w.size, r, self.ncols), complex)
        dH = np.empty((w.size, ne, self.ncols), complex)
        self.last_correction = 0.0
        for m, wk in enumerate(w):
            Zu, CZ = self._solve(wk)
            dDZ = (-2.0 * wk * (self.M @ Zu) + 1j * CZ)[:, self.which]
            Z = Zu[:, self.which]
            H[m, :ne] = self.L @ Z
            H[m, ne:] = Z[self.outputs]
            dH[m] = -np.einsum("ne,nc->ec", Z[:, :ne], dDZ)   # not BLAS: 1 x n @ n x c
        return H, dH

    def _solve(self, wk):
        """Z = D(wk)^-1 cols, refined, and C Z (both (n, columns), complex)."""
        from scipy.linalg import lapack

        from dtdyn.nonlinear._receptance import (REFINE_STEPS, REFINE_TOL, damping_product,
                                                 exact_product)
        bM, bC, bK = self.bands
        w = self.width
        ab = np.zeros((3 * w + 1, bK.shape[1]), complex)
        ab[w:] = bK - wk * wk * bM + 1j * wk * bC
        lu, piv, info = lapack.zgbtrf(ab, w, w)
        if info > 0:
            raise np.linalg.LinAlgError(f"D(w) singular at w = {wk:g} rad/s")
        B, c, w2 = self.cols, self.cols.shape[1], wk * wk
        Z = lapack.zgbtrs(lu, w, w, B, piv)[0]
        if not self.refine:
            return Z, self.C @ Z
        last = np.inf
        for _ in range(REFINE_STEPS):
            X = np.hstack([Z.real, Z.imag])
            mx = self.M @ X
            if self.parts is None:
                (kh, ch), (kl, cl) = exact_product(self.kc, X)      # K X and C X exactly
            else:         # K X exactly, C X = alpha M X + beta K X + E X from it
                (kh,), (kl,) = exact_product(self.kc, X)
                alpha, beta, E = self.parts
                ch, cl = beta * kh + alpha * mx, beta * kl
                if E is not None:
                    ch = ch + E @ X
            CZ = (ch[:, :c] + cl[:, :c]) + 1j * (ch[:, c:] + cl[:, c:])
            re = ((B.real - kh[:, :c] + w2 * mx[:, :c] + wk * ch[:, c:]) - kl[:, :c]
                  + wk * cl[:, c:])
            im = ((B.imag - kh[:, c:] + w2 * mx[:, c:] - wk * ch[:, :c]) - kl[:, c:]
                  - wk * cl[:, :c])
            dZ = lapack.zgbtrs(lu, w, w, re + 1j * im, piv)[0]
            size = float(np.abs(dZ).max()) / max(float(np.abs(Z).max()), 1e-300)
            if size > last:          # diverging: the LU too inaccurate at this w to correct
                break
            Z, CZ = Z + dZ, CZ + (self.C @ dZ if self.parts is None else
                                  damping_product(self.parts, self.M, self.K, dZ))
            stalled, last = size > 0.5 * last, size
            if stalled or size <= REFINE_TOL:
                break
        self.last_correction = max(self.last_correction, last if np.isfinite(last) else 0.0)
        return Z, CZ


#: the banded receptance is used for sparse symmetric models up to this bandwidth
BANDED_MAX_WIDTH = 16
#: "auto" tries the reduced receptance on sparse symmetric banded models with Rayleigh damping
#: from this many DOFs (below, its setup costs more than the banded LU's points save)
REDUCED_AUTO_MIN_DOFS = 50


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


def _projected(Ef, g, Ei):
    """E_f diag(g_e) E_i for each element e (g: (ne, N)) -> (ne, 2H+1, 2H+1), as BLAS
    products (numpy's einsum of the three factors does not use BLAS)."""
    return (Ef[None, :, :] * g[:, None, :]) @ Ei


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
    """R(U, p) = 0 with p the continuation parameter: the angular frequency omega
    (``omega=None``), or at a fixed ``omega`` the load factor a (the loads a F_k)."""

    def __init__(self, receptance, laws, ne, no, F, H, N, omega=None):
        self.rec, self.laws, self.ne, self.no, self.F, self.H, self.N = (receptance, laws, ne,
                                                                         no, F, H, N)
        self.fixed_omega = omega
        self.Ei, self.Ef, self.D = _basis(H, N)
        self.k = np.arange(H + 1, dtype=float)
        self.evaluations = 0
        self.receptance_evaluations = 0
        self._cache = {}
        self._static = None

    def split(self, p):
        """(omega, load factor) at the parameter p."""
        return (p, 1.0) if self.fixed_omega is None else (self.fixed_omega, p)

    def receptance(self, omega):
        """H(k omega), k = 0 .. H (element and output rows), and d/d omega of it (element
        rows); the last few kept (a point's tangent and outputs reuse its last evaluation)."""
        key = float(omega)
        if key not in self._cache:
            if len(self._cache) >= 4:
                self._cache.pop(next(iter(self._cache)))
            if self._static is None:             # harmonic 0: H(0), once
                self._static = self.rec(np.zeros(1))
            Hm, dHm = self.rec(self.k[1:] * omega)
            Hm = np.concatenate([self._static[0], Hm])
            dHm = np.concatenate([np.zeros_like(self._static[1]), dHm * self.k[1:, None, None]])
            self.receptance_evaluations += 1
            self._cache[key] = (Hm, dHm)
        return self._cache[key]

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

    def residual(self, U, p, jacobian=True):
        ne, H = self.ne, self.H
        omega, a = self.split(p)
        Hm, dHm = self.receptance(omega)
        G, g, gy, gv = self.forces(U, omega)
        Hyy, Hyf = Hm[:, :ne, :ne], Hm[:, :ne, ne:]
        load = np.einsum("kec,kc->ke", Hyf, self.F)
        R = _real(_complex(U) - a * load + np.einsum("kef,kf->ke", Hyy, G)).ravel()
        if not jacobian:
            return R, None, None
        Jel = _projected(self.Ef, gy, self.Ei) + omega * _projected(self.Ef, gv,
                                                                     self.Ei @ self.D)
        nU = (2 * H + 1) * ne
        Jg = np.zeros((2 * H + 1, ne, 2 * H + 1, ne))
        idx = np.arange(ne)
        Jg[:, idx, :, idx] = Jel
        JU = np.eye(nU) + _block_real(Hyy) @ Jg.reshape(nU, nU)
        if self.fixed_omega is not None:
            return R, JU, _real(-load).ravel()
        dG = _complex(self.Ef @ (gv.T * (self.Ei @ self.D @ U)))
        dR = (-np.einsum("kec,kc->ke", dHm[:, :, ne:], self.F)
              + np.einsum("kef,kf->ke", dHm[:, :, :ne], G)
              + np.einsum("kef,kf->ke", Hyy, dG))
        return R, JU, _real(dR).ravel()

    def outputs(self, U, p):
        """The outputs' complex harmonics (H+1, no)."""
        ne = self.ne
        omega, a = self.split(p)
        Hm, _ = self.receptance(omega)
        G = self.forces(U, omega)[0]
        return (a * np.einsum("koc,kc->ko", Hm[:, ne:, ne:], self.F)
                - np.einsum("kof,kf->ko", Hm[:, ne:, :ne], G))

    def linearization(self, U, omega):
        """The elements' dg/dy and dg/dy' in the harmonic basis: (ne, 2H+1, 2H+1) each."""
        _, _, gy, gv = self.forces(U, omega)
        return _projected(self.Ef, gy, self.Ei), _projected(self.Ef, gv, self.Ei)


# ----------------------------------------------------------------------------------------------
# Hill's method


def _hill(M, C, K, L, Jy, Jv, omega, D):
    """The 2n Floquet exponents of the orbit (module docstring): of the 2 n (2 H + 1)
    eigenvalues, the 2n whose eigenvectors are centred on harmonic 0 (|centre| <= 1/2, then
    the smallest |Im|)."""
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
    if np.array_equal(M, np.eye(n)):       # A2 = I (a reduced model): a standard eigenproblem
        lam, vec = np.linalg.eig(np.block([[Z, I_m], [-A0, -A1]]))
    else:
        lam, vec = sla.eig(np.block([[Z, I_m], [-A0, -A1]]), np.block([[I_m, Z], [Z, A2]]))
    ok = np.isfinite(lam)
    lam, vec = lam[ok], vec[:m, ok]
    keep = lam.size // nH
    centre = np.abs(_centre(vec, n, nH))
    # the central copies (|centre| <= 1/2: one per exponent when the truncation resolves
    # them) by |Im|, then the others by |centre|; the |Im| among the central ones settles
    # the cases where several are central: an odd law's orbit decouples the even and the odd
    # harmonics, and with few harmonics each block has its own (poorer or better) copies
    order = np.lexsort((np.abs(lam.imag), np.where(centre <= 0.5 + 1e-9, 0.0, centre)))
    # one copy per exponent: a candidate congruent modulo i omega to one kept already is
    # another copy of it (at Im = +-omega / 2, a real negative multiplier, both copies are
    # centred at +-1/2 and tie on |Im|), and the next candidate takes its place
    kept = []
    for i in order:
        d = lam[i] - lam[kept]
        k = np.round(d.imag / omega)
        if np.any((k != 0) & (np.abs(d - 1j * k * omega) <= 1e-6 * max(omega, abs(lam[i])))):
            continue
        kept.append(i)
        if len(kept) == keep:
            break
    return lam[np.array(kept, dtype=int)]


def _centre(vec, n, nH):
    """The centre of mass sum_k k |p_k|^2 / sum_k |p_k|^2 (k = -H .. H) of each eigenvector
    p(t) = sum_k p_k e^{i k omega t} (the columns of ``vec``, real-basis layout). A copy of an
    exponent shifted by i j omega has p e^{-i j omega t}, its centre moved by -j: the copy
    centred nearest 0 is kept (Peletan et al. 2013; Guillot et al. 2020), where the |Im|
    criterion alone can pick two copies of one exponent whose Im is near omega / 2."""
    P = vec.reshape(nH, n, -1)
    w0 = np.sum(np.abs(P[0]) ** 2, axis=0)
    a, b = P[1::2], P[2::2]
    wp = np.sum(np.abs(a + 1j * b) ** 2, axis=1) / 4      # e^{+i k theta}: (a + i b) / 2
    wm = np.sum(np.abs(a - 1j * b) ** 2, axis=1) / 4      # e^{-i k theta}: (a - i b) / 2
    k = np.arange(1, (nH - 1) // 2 + 1)[:, None]
    return np.sum(k * (wp - wm), axis=0) / (w0 + np.sum(wp + wm, axis=0))


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
    amplitude : (points,) ndarray
        The load factor of each point (ones for a frequency sweep; the continued parameter of
        `harmonic_balance_amplitude`).
    fold_amplitude : (folds,) ndarray
        The load factor at each fold (ones for a frequency sweep).
    a_abs_harmonics : (points, outputs, H + 1) complex ndarray or None
        Under ``ground_acceleration``: the harmonics of the outputs' absolute acceleration
        -(k omega)^2 X_k + r A_k.
    a_abs_max : (points, outputs) ndarray or None
        max |absolute acceleration| over a period.
    harmonic_convergence : (points,) ndarray
        At the points re-solved with 2 H harmonics (``convergence_points``): the largest
        change of x_max over the outputs, relative to the largest x_max there,
        max_o |x_max(2H) - x_max(H)| / max_o x_max(2H); NaN at the other points (and where
        the 2 H solve failed, counted in info["harmonic_convergence_failures"]).
    bifurcation_kind : (bifurcations,) str ndarray
        "fold" (from the tangent, as ``folds``), "neimark_sacker" (a complex pair of Floquet
        exponents crossing the imaginary axis: multipliers leaving or entering the unit circle
        off the real axis), "period_doubling" (a multiplier through -1) or "branch_point" (a
        real multiplier through +1 where the curve has no fold); sorted by index. The last
        three need ``stability=True``.
    bifurcation_index : (bifurcations,) int ndarray
        The point next to each bifurcation.
    bifurcation_frequency_hz, bifurcation_amplitude : (bifurcations,) ndarray
        The frequency and the load factor at each (the crossing refined along the arc).
    info : dict
        newton_iterations, steps, rejected_steps, law_evaluations, receptance_evaluations,
        run_time, receptance, n_time, harmonics, stop; harmonic_error (the largest, over the
        points, of the last two kept harmonics' largest |X_k| relative to the largest x_max:
        an estimate of the truncation error; NaN with harmonics < 3, where the last two kept
        would include the fundamental) and harmonic_error_points (per point);
        harmonic_convergence (the largest of ``harmonic_convergence``, NaN when no point was
        checked) and harmonic_convergence_failures.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.harmonic_balance(np.eye(1), [[0.05]], np.eye(1), elements=[dd.Cubic(0, k3=0.1)],
    ...                         force_dofs=[0], force=[0.05], freqs_hz=(0.1, 0.3),
    ...                         harmonics=3, outputs=[0])
    >>> r.harmonics.shape[1:], r.x_max.shape[1], r.omega.size == r.frequency_hz.size
    ((1, 4), 1, True)
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
    amplitude: np.ndarray | None = None
    fold_amplitude: np.ndarray | None = None
    a_abs_harmonics: np.ndarray | None = None
    a_abs_max: np.ndarray | None = None
    harmonic_convergence: np.ndarray | None = None
    bifurcation_kind: np.ndarray | None = None
    bifurcation_index: np.ndarray | None = None
    bifurcation_frequency_hz: np.ndarray | None = None
    bifurcation_amplitude: np.ndarray | None = None

    def save(self, path):
        """Write the curve to ``path``: ``.npz``, or ``.csv`` (one row per point) with its
        metadata in ``<name>.csv.json``, by the extension; every field, complex arrays as real
        and imaginary parts (`dtdyn._engine.curve_io`); atomic. `dtdyn.load_result` reads it
        back.

        Parameters
        ----------
        path : str or Path
            A ``.npz`` or ``.csv`` file name in an existing folder.

        Returns
        -------
        Path
            ``path``.
        """
        from dtdyn._engine.curve_io import save_curve
        return save_curve(self, path)

    def plot(self, output: int = 0, ax=None, backbone=None):
        """x_max of ``outputs[output]`` against frequency, unstable points dashed.

        Parameters
        ----------
        output : int
            Index into ``outputs``.
        ax : matplotlib Axes, optional
            Draw into these axes; a new figure otherwise.
        backbone : BackboneResult, optional
            A backbone (`backbone`) drawn over the curve (dotted), for the same DOF; it must
            be among the backbone's outputs.

        Returns
        -------
        matplotlib Axes
        """
        plt = require("matplotlib.pyplot", "plot", "HarmonicBalanceResult.plot")
        if ax is None:
            ax = plt.figure().add_subplot()
        f, x = self.frequency_hz, self.x_max[:, output]
        st = np.ones(f.size, bool) if self.stable is None else self.stable
        for i in range(f.size - 1):
            ax.plot(f[i:i + 2], x[i:i + 2], "C0-" if st[i] and st[i + 1] else "C3--", lw=1.2)
        ax.set_xlabel("frequency, Hz")
        ax.set_ylabel(f"max |x| of DOF {int(self.outputs[output])}")
        if backbone is not None:
            dof = int(self.outputs[output])
            where = np.flatnonzero(np.asarray(backbone.outputs) == dof)
            if where.size == 0:
                raise ValueError(f"backbone: DOF {dof} (outputs[{output}]) is not among the "
                                 f"backbone's outputs {list(map(int, backbone.outputs))}")
            backbone.plot(output=int(where[0]), ax=ax)
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


def _force_harmonics(force, nf, H, name="force", per="per force_dofs entry"):
    """The (H+1, nf) complex harmonics of ``force`` (``name`` in the messages)."""
    arr = np.asarray(force)
    if not np.issubdtype(arr.dtype, np.number) or arr.dtype == bool:
        raise ValueError(f"{name} must be numbers (amplitudes {per}), got {force!r}")
    arr = arr.astype(complex)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim == 1:
        if arr.size != nf:
            raise ValueError(f"{name} has {arr.size} amplitude(s), expected one {per} ({nf})")
        F = np.zeros((H + 1, nf), complex)
        F[1] = arr
    elif arr.ndim == 2:
        if arr.shape[0] != nf or arr.shape[1] > H + 1:
            raise ValueError(f"{name} has shape {arr.shape}, expected ({nf}, m): one row {per}, "
                             f"m <= harmonics + 1 = {H + 1} columns (harmonics 0, 1, ...)")
        F = np.zeros((H + 1, nf), complex)
        F[:arr.shape[1]] = arr.T
        if np.any(F[0].imag != 0):
            raise ValueError(f"{name}[:, 0] is the static part (harmonic 0) and must be real, "
                             f"got {arr[:, 0]!r}")
    else:
        raise ValueError(f"{name} must be 1-D (one amplitude {per}) or 2-D (a row {per}, a "
                         f"column per harmonic), got shape {arr.shape}")
    if not np.all(np.isfinite(F)):
        raise ValueError(f"{name} has a non-finite amplitude: {force!r}")
    if not np.any(F):
        raise ValueError(f"{name} is zero everywhere: a forced response needs a non-zero load "
                         "(the unforced motion: `backbone`)")
    return F


def _directions(ground_acceleration) -> int:
    """The number of ground directions of ``ground_acceleration`` (its rows)."""
    shape = np.shape(ground_acceleration)
    return 1 if len(shape) == 0 else shape[0]


def _loads(M, n, names, rigid, force_dofs, force, ground_acceleration, influence, H):
    """(B (n, nf) the loads' patterns on the DOFs, F (H+1, nf) their harmonics, r_g the
    influence (n, d) or None, A_g (H+1, d) the ground acceleration's harmonics or None)."""
    B, F, r, Ag = [], [], None, None
    if force is not None:
        force_dofs = validate.dof_indices("force_dofs", force_dofs, n, default_all=False,
                                          names=names)
        P = np.zeros((n, force_dofs.size))
        P[force_dofs, np.arange(force_dofs.size)] = 1.0
        B.append(P)
        F.append(_force_harmonics(force, force_dofs.size, H))
    elif force_dofs is not None:
        raise ValueError(f"force_dofs = {force_dofs!r} is given without force")
    if ground_acceleration is not None:
        d = _directions(ground_acceleration)
        Ag = _force_harmonics(ground_acceleration, d, H, "ground_acceleration",
                              "per ground direction")
        if influence is None:
            r = rigid(d)
        else:
            r = validate.real_array("influence", influence)
            r = r[:, None] if r.ndim == 1 else r
            if r.shape != (n, d) or not np.isfinite(r).all():
                raise ValueError(f"influence has shape {np.shape(influence)}, expected ({n},) or "
                                 f"({n}, {d}) finite values: one column per ground direction")
        B.append(-np.asarray(M @ r))
        F.append(Ag)
    elif influence is not None:
        raise ValueError("influence is given without ground_acceleration")
    if not B:
        raise ValueError("no load: give force (with force_dofs) or ground_acceleration")
    return np.hstack(B), np.hstack(F), r, Ag


def _model(M, C, K):
    """(M, C, K, dof names or None, rigid(d) the default influence, is a model object)."""
    from dtdyn.linear._beam import Beam, beam_matrices, rigid_translation
    from dtdyn.linear._chain import Chain
    from dtdyn.linear._mck import Matrices
    from dtdyn.linear._shaft import Shaft, rigid_rotation, shaft_matrices
    if isinstance(M, (Chain, Beam, Shaft, Matrices)):
        if C is not None or K is not None:
            raise ValueError(f"C and K must be left out when the first argument is a model "
                             f"({type(M).__name__}): it holds them")
        model = M
        if isinstance(model, Chain):
            M, C, K = model.matrices(sparse=True)
            return M, C, K, None, None, True
        if isinstance(model, Beam):
            M, C, K = beam_matrices(model)
            return M, C, K, model.dof_names, lambda d: rigid_translation(model, d), True
        if isinstance(model, Shaft):
            M, C, K = shaft_matrices(model)
            r = rigid_rotation(model)
            return (M, C, K, model.dof_names, lambda d: np.repeat(r[:, None], d, axis=1),
                    True)
        return model.M, model.C, model.K, None, None, True
    if C is None or K is None:
        raise ValueError("C and K are required with matrices M (or give a Chain, Beam, Shaft or "
                         "Matrices as the first argument)")
    return M, C, K, None, None, False


def _range(name, values, unit=""):
    """(start, end) of a continuation range: two different finite numbers > 0."""
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (start, end){unit}, got {values!r}") from None
    if v.shape != (2,) or not np.all(np.isfinite(v)) or np.any(v <= 0) or v[0] == v[1]:
        raise ValueError(f"{name} must be (start, end){unit}, two different finite numbers "
                         f"> 0, got {values!r}")
    return float(v[0]), float(v[1])


def _frequency_range(freqs_hz):
    return _range("freqs_hz", freqs_hz, " in Hz")


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
        raise NewtonError(f"harmonic_balance: Newton did not converge at {_where(self.s, omega)}"
                          f" in {self.max_iter} iterations (residual {np.abs(R).max():.3g})")

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


#: Hill's method is refused beyond this size 2 n (2 H + 1) of its dense eigenproblem
HILL_MAX_SIZE = 6000


def _stability_choice(stability, n, H):
    """None (no stability), "full" or "reduced" Hill's method from the ``stability`` option."""
    if stability is False:
        return None
    size = 2 * n * (2 * H + 1)
    if stability is True or stability == "full":
        if size > HILL_MAX_SIZE:
            raise ValueError(f"stability={stability!r}: Hill's method on the full model is a "
                             f"dense eigenproblem of size 2 n (2 H + 1) = {size} here (at most "
                             f"{HILL_MAX_SIZE}); pass stability='reduced' (or 'auto') for Hill's "
                             "method on a reduced model, or stability=False")
        return "full"
    if stability == "reduced":
        return "reduced"
    if stability == "auto":
        return "full" if size <= HILL_MAX_SIZE else "reduced"
    raise ValueError(f"stability must be True, False, 'auto', 'full' or 'reduced', got "
                     f"{stability!r}")


def _hill_model(choice, M, C, K, L, H, w_top, model=None):
    """The matrices (M, C, K, L) Hill's method runs on (dense), or None without stability, and
    a dict describing them; "reduced": `reduced_hill_model` for the frequencies up to
    (H + 1) ``w_top``."""
    if choice is None:
        return None
    if choice == "full":
        Md, Cd, Kd = ((A.toarray() if sps.issparse(A) else np.asarray(A, dtype=float))
                      for A in (M, C, K))
        return (Md, Cd, Kd, L), dict(method="full", size=M.shape[0])
    from dtdyn.nonlinear._hill_reduced import reduced_hill_model
    width = None
    if sps.issparse(M) or sps.issparse(K):
        if not all(_symmetric(sps.csr_matrix(A)) for A in (M, K)):
            raise ValueError("stability='reduced' needs symmetric M and K (the modes of K, M)")
        width = _bandwidth(M, C, K)
        width = width if width <= BANDED_MAX_WIDTH and _symmetric(sps.csr_matrix(C)) else None
    elif not (np.allclose(M, M.T, rtol=1e-13, atol=0) and np.allclose(K, K.T, rtol=1e-13,
                                                                       atol=0)):
        raise ValueError("stability='reduced' needs symmetric M and K (the modes of K, M)")
    from dtdyn.nonlinear._receptance import rayleigh_parts
    parts = rayleigh_parts(model, M, C, K) if sps.issparse(M) else None
    Mr, Cr, Kr, Lr, info = reduced_hill_model(M, C, K, L, (H + 1) * w_top, width=width,
                                              parts=parts)
    info.update(method="reduced")
    return (Mr, Cr, Kr, Lr), info

_COMMON_PARAMETERS = """harmonics : int
        H, the highest harmonic kept (0 .. H, the static part included).
    outputs : sequence of int or DOF names, optional
        DOFs whose harmonics are returned (all by default; give a few on a large model: the
        result holds (points, outputs, H + 1) complex numbers).
    n_time : int, optional
        Samples per period of the AFT (default: the power of 2 >= 8 (H + 1); at least 2 H + 2).
        A polynomial law of degree p is alias-free from (p + 1) H + 1 samples.
    receptance : {"auto", "modal", "direct", "banded", "reduced"}
        "modal": the exact modal sum over all 2n poles (one eigenproblem, then O(n) per
        harmonic); "direct": an LU of K - w^2 M + i w C per harmonic and evaluation (sparse
        matrices stay sparse); "banded": LAPACK's banded LU of a sparse symmetric banded model
        (chains, beams, shafts without branches), O(n) per harmonic, each solve refined with
        residuals in twice the working precision (a beam's assembled K loses ~eps N^3.5 in the
        LU alone: 7.8e-3 at 10,000 elements); "reduced" (sparse symmetric models with Rayleigh
        or no damping): the modes below a cut-off above the highest harmonic plus the higher
        modes' residual as a short series, built once, so that a point costs the same whatever
        n; it is checked at setup against "banded" at the highest harmonic frequency (1e-8
        relative) and falls back to "banded", with a warning, when the check fails
        (info["receptance"] and info["receptance_check"] say which ran and why). A `Beam` with
        ``rayleigh`` keeps alpha M and beta K apart in both (the modes' damping
        alpha + beta omega_r^2: its assembled C loses alpha M to rounding at large N, 40 % of
        the first mode's damping at 10,000 elements). "auto": modal for dense models up to
        2000 DOFs; for sparse symmetric ones of bandwidth <= 16 (a `Chain`, `Beam`, `Shaft`)
        "reduced" when they have Rayleigh or no damping and at least 50 DOFs, with LAPACK's
        banded LU without the refinement where its check fails (no warning), and that banded
        LU otherwise; else direct. The unrefined banded LU loses about eps N^3.5 on a beam of
        N elements (1.9e-6 of a static deflection at 1,000 elements, 7.8e-3 at 10,000; on a
        chain about eps N^2), more near a resonance: choose "banded" for the refined solves.
    stability : {"auto", "full", "reduced"} or bool
        Hill's method at every point, for the labels ``stable``, ``floquet_exponents`` and the
        bifurcations. "full" (or True): on the full model, a dense eigenproblem of size
        2 n (2 H + 1), refused above 6000. "reduced": on a reduced model of the modes below
        2 (H + 1) times the highest forcing frequency and the elements' attachment modes with
        two mass corrections (M, C, K projected, the elements' Jacobians of the point), of a
        size that does not grow with n (symmetric M, K; at most 150 reduced DOFs, else refused);
        its exponents equal the full Hill's to ~1e-8 relative in the tests. "auto": "full" up
        to 6000, "reduced" above. False: none (``stable`` and ``floquet_exponents`` None).
        info["stability"] says which ran, the reduced model's size and the time it took.
    step, max_step, min_step : float
        Initial, largest and smallest arclength step in the scaled variables (the parameter
        per its range's span, deformations per their largest amplitude so far).
    max_angle : float
        A step whose tangent turns by more than this (rad) is retried at half the length.
    max_points : int
        The most points along the curve.
    tol : float
        Newton stops when its step is below ``tol`` times the largest scaled unknown.
    max_iter : int
        Newton iterations per corrector.
    convergence_points : int or "all"
        The points re-solved with 2 H harmonics (and 2 ``n_time`` samples) at the same
        frequency and load, from the H solution, for ``harmonic_convergence``: this many
        spread evenly along the curve (its ends included) and the point of the largest
        amplitude; "all" every point; 0 none."""


def _receptance(receptance, M, C, K, L, outputs, B, w_max=None, model=None):
    """The receptance object of the choice ``receptance`` (and M, C, K as it holds them);
    ``w_max``: the highest angular frequency it will be asked for, if known (rad/s; "reduced"
    is then set up once); ``model``: the model object M, C, K come from, if any (a Beam's
    Rayleigh coefficients keep alpha M and beta K apart in "reduced" and "banded")."""
    from dtdyn.nonlinear._receptance import rayleigh_parts
    sparse = sps.issparse(M) or sps.issparse(K)
    n = M.shape[0]
    width = None
    if receptance in ("auto", "banded", "reduced"):
        width = (_bandwidth(M, C, K) if sparse and all(_symmetric(A) for A in (M, C, K))
                 else None)
        if receptance in ("banded", "reduced") and width is None:
            raise ValueError(f"receptance={receptance!r} needs sparse symmetric M, C, K (a Chain, "
                             "Beam or Shaft, or scipy.sparse matrices)")
    if receptance in ("auto", "reduced") and width is not None:
        from dtdyn.nonlinear._receptance import ReducedReceptance, rayleigh_coefficients
        auto = receptance == "auto"
        if not auto or (n >= REDUCED_AUTO_MIN_DOFS and width <= BANDED_MAX_WIDTH):
            parts = rayleigh_parts(model, M, C, K)
            damping = rayleigh_coefficients(M, C, K) if parts is None else parts[:2]
            if damping is None and not auto:
                raise ValueError("receptance='reduced' needs Rayleigh damping C = alpha M + "
                                 "beta K (or none): the modes must diagonalize C")
            if damping is not None:
                exact = _BandedReceptance(M, C, K, L, outputs, B, width, refine=True,
                                          parts=parts)
                backup = (_BandedReceptance(M, C, K, L, outputs, B, width) if auto else
                          None)
                return ReducedReceptance(exact, M, C, K, L, outputs, B, damping, w_max=w_max,
                                         strict=not auto, parts=parts,
                                         backup=backup), (M, C, K)
    chosen = receptance
    if receptance == "auto":
        receptance = ("banded" if width is not None and width <= BANDED_MAX_WIDTH else
                      "direct" if (sparse or n > MODAL_MAX_DOFS) else "modal")
    if receptance == "modal":
        if sparse:
            validate.dense_conversion("M", M, copies=3)
            M, C, K = M.toarray(), C.toarray(), K.toarray()
        return _ModalReceptance(M, C, K, L, outputs, B), (M, C, K)
    if receptance == "banded":  # chosen: refined; by "auto": LAPACK's solve as it is
        refine = chosen == "banded"
        return _BandedReceptance(M, C, K, L, outputs, B, width, refine=refine,
                                 parts=rayleigh_parts(model, M, C, K) if refine else None), \
            (M, C, K)
    if sparse:
        M, C, K = sps.csc_matrix(M), sps.csc_matrix(C), sps.csc_matrix(K)
    return _DirectReceptance(M, C, K, L, outputs, B), (M, C, K)


def _prepare(M, C, K, elements, force_dofs, force, ground_acceleration, influence, harmonics,
             outputs, n_time, receptance, stability, step, max_step, min_step, max_angle, tol,
             max_iter, max_points, convergence_points, omega=None, w_top=None):
    """The checked inputs: (system, continuation options, model data for the result);
    ``w_top``: the highest fundamental angular frequency of the run (rad/s), if known."""
    source = M
    M, C, K, names, rigid, is_model = _model(M, C, K)
    sparse = sps.issparse(M) or sps.issparse(K)
    M, C, K = linalg.mck(M, C, K, keep_sparse=sparse)
    n = M.shape[0]
    if rigid is None:
        def rigid(d):
            if d != 1:
                raise ValueError(f"ground_acceleration has {d} directions: give the influence "
                                 f"matrix ({n}, {d})")
            return np.ones((n, 1))
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
    outputs = validate.dof_indices("outputs", outputs, n, names=names)
    B, F, r_g, A_g = _loads(M, n, names, rigid, force_dofs, force, ground_acceleration,
                            influence, H)
    if receptance not in ("auto", "modal", "direct", "banded", "reduced"):
        raise ValueError(f"receptance must be 'auto', 'modal', 'direct', 'banded' or 'reduced', "
                         f"got {receptance!r}")
    stability = _stability_choice(stability, n, H)
    opts = dict(step=validate.positive_scalar("step", step),
                max_step=validate.positive_scalar("max_step", max_step),
                min_step=validate.positive_scalar("min_step", min_step),
                max_angle=validate.positive_scalar("max_angle", max_angle),
                max_points=_positive_int("max_points", max_points, 2))
    tol = validate.positive_scalar("tol", tol)
    max_iter = _positive_int("max_iter", max_iter, 1)
    if not opts["min_step"] <= opts["step"] <= opts["max_step"]:
        raise ValueError(f"need min_step <= step <= max_step, got {min_step!r}, {step!r}, "
                         f"{max_step!r}")

    if not (convergence_points == "all" or (isinstance(convergence_points, (int, np.integer))
                                            and not isinstance(convergence_points, bool)
                                            and convergence_points >= 0)):
        raise ValueError(f"convergence_points must be an integer >= 0 or 'all', got "
                         f"{convergence_points!r}")

    L = element_matrix(elements, n)
    # the highest harmonic frequency of the curve, H w_top (the H -> 2 H check asks for more:
    # a reduced receptance is rebuilt for it then)
    w_max = None if w_top is None else w_top * H
    rec, (M, C, K) = _receptance(receptance, M, C, K, L, outputs, B, w_max=w_max,
                                 model=source if is_model else None)
    system = _System(rec, _law_function(elements, N), len(elements), outputs.size, F, H, N,
                     omega)
    model = dict(M=M, C=C, K=K, L=L, outputs=outputs, r_g=r_g, A_g=A_g, stability=stability,
                 is_model=is_model, elements=elements, convergence_points=convergence_points)
    model["hill"] = _hill_model(stability, M, C, K, L, H, w_top,
                                model=source if is_model else None)
    return system, tol, max_iter, opts, model


def _arc(system, cont, U, p0, p1, step, max_step, min_step, max_angle, max_points):
    """Pseudo-arclength continuation of R(U, p) = 0 from (U, p0) until p passes p1:
    (points [(U, p)], the tangents' parameter components, the accepted steps, counts, stop)."""
    direction = 1.0 if p1 > p0 else -1.0
    nx = U.size + 1
    e_w = np.zeros(nx)
    e_w[-1] = direction
    t = cont.tangent(U, p0, e_w)

    points = [(U, p0, system.outputs(U, p0))]
    tw = [t[-1]]
    arcs = []               # (U_i, p_i, t_i, ds, su) of each accepted step, for the folds
    ds, steps, rejected, stop = step, 0, 0, "end of the range"
    while True:
        if len(points) >= max_points:
            stop = "max_points"
            warnings.warn(f"harmonic_balance stopped after max_points = {max_points} points at "
                          f"{_where(system, points[-1][1])}", RuntimeWarning, stacklevel=3)
            break
        U, w, _ = points[-1]
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
                                  f"{min_step:g} at {_where(system, w)} (a bifurcation, a "
                                  "kink of a law, or a resonance of the linear part without "
                                  "damping?)")
            continue
        steps += 1
        arcs.append((U, w, t, ds, su_old))
        if (w_new - p1) * direction > 0:        # past the end: the last point at the end
            frac = (p1 - w) / (w_new - w)
            U_end, _ = cont.solve_fixed(U + frac * (U_new - U), p1)
            tw.append(cont.tangent(U_end, p1, t_new)[-1])
            points.append((U_end, p1, system.outputs(U_end, p1)))
            break
        points.append((U_new, w_new, system.outputs(U_new, w_new)))
        tw.append(t_new[-1])
        t = t_new
        if (w_new - p0) * direction < 0:
            stop = "left the range below its start"
            break
        ds = min(max_step, ds * (1.5 if its <= 3 else (1.0 if its <= 6 else 0.6)))
    return points, np.asarray(tw), arcs, steps, rejected, stop


def _where(system, p) -> str:
    return (f"{p / 2 / np.pi:.6g} Hz" if system.fixed_omega is None else
            f"load factor {p:.6g} (at {system.fixed_omega / 2 / np.pi:.6g} Hz)")


def _curve(system, cont, U, p0, p1, opts, model, t_start) -> HarmonicBalanceResult:
    """Continue from the solution U at p0 to p1 and assemble the result."""
    points, tw, arcs, steps, rejected, stop = _arc(system, cont, U, p0, p1, **opts)

    # folds: sign changes of d p / ds, refined by a root search along the arc
    folds, fold_p, fold_steps = [], [], set()
    for i in range(len(tw) - 1):
        if np.sign(tw[i]) != np.sign(tw[i + 1]) and i < len(arcs):
            folds.append(i if abs(tw[i]) < abs(tw[i + 1]) else i + 1)
            fold_steps.add(i)
            fold_p.append(_refine_fold(cont, *arcs[i], tw[i], tw[i + 1]))
    fold_p = np.array(fold_p, dtype=float)

    H = system.H
    p = np.array([q[1] for q in points])
    omega, amplitude = (p, np.ones(p.size)) if system.fixed_omega is None else \
        (np.full(p.size, system.fixed_omega), p)
    X = np.array([q[2] for q in points])                             # (points, H+1, no)
    Yel = np.array([_complex(q[0]) for q in points])                 # (points, H+1, ne)
    x_max = np.array([_peak(Xp) for Xp in X])
    rms = np.sqrt(np.abs(X[:, 0].real) ** 2 + 0.5 * np.sum(np.abs(X[:, 1:]) ** 2, axis=1))
    # the truncation estimate: the last two kept harmonics (never the fundamental) against the
    # amplitude; none with a single harmonic above the fundamental or fewer (NaN)
    if H >= 3:
        last = np.abs(X[:, H - 1:]).max(axis=1).max(axis=1)
        harmonic_error = last / np.maximum(x_max.max(axis=1), 1e-300)
    else:
        harmonic_error = np.full(len(points), np.nan)
    a_abs = a_abs_max = None
    if model["A_g"] is not None:
        k = np.arange(H + 1)
        a_abs = (-(np.multiply.outer(omega, k) ** 2)[:, :, None] * X
                 + amplitude[:, None, None] * np.einsum("kd,od->ko", model["A_g"],
                                                        model["r_g"][model["outputs"]])[None])
        a_abs_max = np.array([_peak(A) for A in a_abs])
        a_abs = np.transpose(a_abs, (0, 2, 1))
    stable = lam = None
    hill_info = None
    if model["hill"] is not None:
        t_hill = time.perf_counter()
        (Md, Cd, Kd, Lh), hill_info = model["hill"]
        _, _, D = _basis(H, system.N)
        lam = []
        for (U, _, _), w in zip(points, omega):
            Jy, Jv = system.linearization(U, w)
            lam.append(_hill(Md, Cd, Kd, Lh, Jy, Jv, w, D))
        width = max(v.size for v in lam)
        lam = np.array([np.pad(v, (0, width - v.size), constant_values=np.nan) for v in lam])
        stable = np.nanmax(lam.real, axis=1) < 1e-9 * omega

        def hill_at(U, w):
            return _hill(Md, Cd, Kd, Lh, *system.linearization(U, w), w, D)
        crossings = _crossings(lam, omega, p, fold_steps, cont, arcs, system, hill_at)
        hill_info = dict(hill_info, time=time.perf_counter() - t_hill)
    else:
        crossings = []
    kinds = ["fold"] * len(folds) + [c[0] for c in crossings]
    b_index = np.array(list(folds) + [c[1] for c in crossings], dtype=np.int64)
    b_p = np.concatenate([fold_p, [c[2] for c in crossings]])
    order = np.argsort(b_index, kind="stable")
    b_kind = np.array(kinds, dtype="U16")[order] if kinds else np.array([], dtype="U16")
    b_index, b_p = b_index[order], b_p[order]
    # the receptance the curve ran with (the H -> 2H check may rebuild or replace it)
    receptance, check = system.rec.name, dict(getattr(system.rec, "check", None) or {}) or None
    convergence = _harmonic_convergence(system, cont, points, x_max, model)
    info = dict(newton_iterations=cont.newton, steps=steps, rejected_steps=rejected,
                law_evaluations=system.evaluations,
                receptance_evaluations=system.receptance_evaluations,
                run_time=time.perf_counter() - t_start, receptance=receptance,
                receptance_check=check, stability=hill_info,
                n_time=system.N, harmonics=H, stop=stop,
                harmonic_error=float(harmonic_error.max()),
                harmonic_error_points=harmonic_error,
                harmonic_convergence=(float(np.nanmax(convergence))
                                      if np.isfinite(convergence).any() else np.nan),
                harmonic_convergence_failures=int(np.count_nonzero(
                    np.isinf(convergence))))
    convergence[np.isinf(convergence)] = np.nan
    if system.fixed_omega is None:
        fold_w, fold_a = fold_p, np.ones(fold_p.size)
    else:
        fold_w, fold_a = np.full(fold_p.size, system.fixed_omega), fold_p
    return HarmonicBalanceResult(
        frequency_hz=omega / (2 * np.pi), omega=omega, harmonics=np.transpose(X, (0, 2, 1)),
        x_max=x_max, rms=rms, stable=stable, floquet_exponents=lam,
        folds=np.array(folds, dtype=np.int64), fold_frequency_hz=fold_w / (2 * np.pi),
        outputs=model["outputs"], element_harmonics=np.transpose(Yel, (0, 2, 1)), info=info,
        amplitude=amplitude, fold_amplitude=fold_a, a_abs_harmonics=a_abs, a_abs_max=a_abs_max,
        harmonic_convergence=convergence, bifurcation_kind=b_kind, bifurcation_index=b_index,
        bifurcation_frequency_hz=(b_p / (2 * np.pi) if system.fixed_omega is None else
                                  np.full(b_p.size, system.fixed_omega / (2 * np.pi))),
        bifurcation_amplitude=(np.ones(b_p.size) if system.fixed_omega is None else b_p))


@public(renamed={"frequencies": "freqs_hz"})
def harmonic_balance(M, C=None, K=None, *, elements, freqs_hz, force_dofs=None, force=None,
                     ground_acceleration=None, influence=None, harmonics=7, outputs=None,
                     n_time=None, receptance="auto", stability="auto", step=0.02, max_step=0.1,
                     min_step=1e-7, max_angle=0.35, max_points=5000, tol=1e-10,
                     max_iter=20, convergence_points=10) -> HarmonicBalanceResult:
    """Periodic steady-state frequency response of M q'' + C q' + K q + L^T g = f(t) by
    harmonic balance with pseudo-arclength continuation (through folds) and Hill's stability.

    Parameters
    ----------
    M, C, K : (n, n) array_like or scipy.sparse matrix, or a model
        The linear part (K - w^2 M + i w C nonsingular at every harmonic k omega: no rigid-body
        mode, and damping where k omega meets a natural frequency). Or a `Chain`, `Beam`,
        `Shaft` or `Matrices` as ``M`` alone (C and K left out): its matrices, its DOF names in
        ``force_dofs`` and ``outputs``, its rigid motion as the default ``influence``.
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap` (its kink is sampled, not resolved), `Law` (in x and v);
        `BoucWen` (internal state) is not supported. i, j index the model's DOFs.
    freqs_hz : (start, end)
        The forcing frequency range, Hz; the curve is continued from start to end (end < start
        sweeps down).
    force_dofs : sequence of int or DOF names
        0-based loaded DOFs (with ``force``).
    force : array_like, optional
        Shape (len(force_dofs),): amplitudes F of f(t) = Re(F e^{i omega t}) (a real F is
        F cos omega t). Shape (len(force_dofs), m), m <= harmonics + 1: column k is F_k of
        f(t) = Re sum_k F_k e^{i k omega t} (column 0 the static force, real).
    ground_acceleration : array_like, optional
        Support motion: amplitudes A of the ground acceleration a_g(t) = Re(A e^{i omega t}),
        m/s^2 (rad/s^2 on a shaft), one per ground direction (a scalar: one direction), or
        (directions, m) harmonics as ``force``. The DOFs, the outputs and the elements' y are
        then relative to the support (the load is -M r a_g).
    influence : (n,) or (n, directions) array_like, optional
        r, each DOF's motion per unit ground motion (ones; a beam's rigid translation, a
        shaft's rigid rotation).
    {common}

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
    ...                         force_dofs=[0], force=[0.05], freqs_hz=(0.1, 0.3),
    ...                         harmonics=3)
    >>> bool(r.stable.all()), r.folds.size
    (True, 0)
    """
    t_start = time.perf_counter()
    f0, f1 = _frequency_range(freqs_hz)
    system, tol, max_iter, opts, model = _prepare(
        M, C, K, elements, force_dofs, force, ground_acceleration, influence, harmonics,
        outputs, n_time, receptance, stability, step, max_step, min_step, max_angle, tol,
        max_iter, max_points, convergence_points, w_top=2 * np.pi * max(f0, f1))
    w0, w1 = 2 * np.pi * f0, 2 * np.pi * f1
    cont = _Continuation(system, tol, max_iter, abs(w1 - w0))
    U = _first_point(system, cont, w0)
    cont.su = max(np.abs(U).max(), 1e-300)
    return _curve(system, cont, U, w0, w1, opts, model, t_start)


def _first_point(system, cont, w0):
    """The curve's first point: Newton at w0 from the linear response. Where that fails (a load
    far beyond the linear range), the load is brought in by steps, s F for s = 1/8, 1/4, ..
    1 (a step that fails is halved, down to 1/1024), each Newton from the last solution."""
    ne, F = system.ne, system.F
    Hm, _ = system.receptance(w0)
    linear = _real(np.einsum("kec,kc->ke", Hm[:, :ne, ne:], F))
    cont.su = max(np.abs(linear).max(), 1e-300)
    try:
        return cont.solve_fixed(linear, w0)[0]
    except NewtonError as exc:
        failure = exc
    done, U, ds = 0.0, 0.0 * linear, 0.125
    try:
        while done < 1.0:
            s = min(1.0, done + ds)
            system.F = s * F
            cont.su = max(s * np.abs(linear).max(), np.abs(U).max(), 1e-300)
            try:
                U = cont.solve_fixed(U if done > 0 else s * linear, w0)[0]
            except NewtonError:
                ds /= 2
                if ds < 1.0 / 1024:
                    raise failure from None
                continue
            done, ds = s, 2 * ds
    finally:
        system.F = F
    return U


@public
def harmonic_balance_amplitude(M, C=None, K=None, *, elements, frequency_hz, amplitudes,
                               force_dofs=None, force=None, ground_acceleration=None,
                               influence=None, harmonics=7, outputs=None, n_time=None,
                               receptance="auto", stability="auto", step=0.02, max_step=0.1,
                               min_step=1e-7, max_angle=0.35, max_points=5000, tol=1e-10,
                               max_iter=20, convergence_points=10) -> HarmonicBalanceResult:
    """Periodic steady state at a fixed forcing frequency, continued in the load's amplitude:
    the load a f(t) for a from ``amplitudes[0]`` to ``amplitudes[1]`` (through folds).

    Parameters
    ----------
    M, C, K : (n, n) array_like or scipy.sparse matrix, or a model
        As `harmonic_balance`.
    elements : sequence of elements
        As `harmonic_balance`.
    frequency_hz : float
        The forcing frequency, Hz, > 0.
    amplitudes : (start, end)
        The range of the load factor a that multiplies ``force`` and ``ground_acceleration``
        (start >= 0; end < start decreases it).
    force_dofs, force, ground_acceleration, influence
        The load at a = 1, as `harmonic_balance`.
    {common}

    Returns
    -------
    HarmonicBalanceResult
        One point per load factor: ``amplitude`` holds a, ``frequency_hz`` is constant, and
        ``folds`` / ``fold_amplitude`` are the turning points in a.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.harmonic_balance_amplitude(np.eye(1), [[0.05]], np.eye(1),
    ...                                   elements=[dd.Cubic(0, k3=0.1)], force_dofs=[0],
    ...                                   force=[1.0], frequency_hz=0.2, amplitudes=(0.01, 0.1),
    ...                                   harmonics=3)
    >>> float(r.amplitude[0]), float(r.amplitude[-1])
    (0.01, 0.1)
    """
    t_start = time.perf_counter()
    f = validate.positive_scalar("frequency_hz", frequency_hz)
    a0, a1 = _amplitude_range(amplitudes)
    w = 2 * np.pi * f
    system, tol, max_iter, opts, model = _prepare(
        M, C, K, elements, force_dofs, force, ground_acceleration, influence, harmonics,
        outputs, n_time, receptance, stability, step, max_step, min_step, max_angle, tol,
        max_iter, max_points, convergence_points, omega=w, w_top=w)
    cont = _Continuation(system, tol, max_iter, abs(a1 - a0))
    ne = system.ne
    Hm, _ = system.receptance(w)
    lin = _real(np.einsum("kec,kc->ke", Hm[:, :ne, ne:], system.F))
    cont.su = max(np.abs(lin).max() * max(abs(a0), abs(a1)), 1e-300)
    U, _ = cont.solve_fixed(a0 * lin, a0)
    cont.su = max(np.abs(U).max(), cont.su)
    return _curve(system, cont, U, a0, a1, opts, model, t_start)


for _f in (harmonic_balance, harmonic_balance_amplitude):
    _f.__doc__ = _f.__wrapped__.__doc__ = _f.__doc__.replace("{common}", _COMMON_PARAMETERS)


def _amplitude_range(amplitudes):
    try:
        a = np.asarray(amplitudes, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"amplitudes must be (start, end), got {amplitudes!r}") from None
    if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(a < 0) or a[0] == a[1]:
        raise ValueError(f"amplitudes must be (start, end): two different finite load factors "
                         f">= 0, got {amplitudes!r}")
    return float(a[0]), float(a[1])


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


# ----------------------------------------------------------------------------------------------
# bifurcations from the Floquet exponents

#: an exponent whose Im / omega is within this of 0 (mod 1) is real (a multiplier near +1
#: when it crosses), within this of 1/2 a period-doubling one (a multiplier near -1)
REAL_TOL = 1e-3


def _kind(lam, omega):
    """0 real, 1 complex (Neimark-Sacker when it crosses), 2 period doubling, per exponent."""
    f = np.abs(lam.imag / omega) % 1.0
    f = np.minimum(f, 1.0 - f)
    return np.where(f < REAL_TOL, 0, np.where(f > 0.5 - REAL_TOL, 2, 1))


def _match(a, b, omega):
    """b reordered (and shifted by multiples of i omega) to follow a, by the assignment of
    least total distance modulo i omega."""
    from scipy.optimize import linear_sum_assignment
    d = a[:, None] - b[None, :]
    shift = np.round(d.imag / omega)
    r, c = linear_sum_assignment(np.abs(d - 1j * omega * shift))
    out = np.empty_like(a)
    out[r] = b[c] + 1j * omega * shift[r, c]
    return out


def _crossings(lam, omega, params, fold_steps, cont, arcs, system, hill_at):
    """(kind, index, parameter) of each exponent crossing the imaginary axis between two
    points: "neimark_sacker" for a complex pair (Im neither 0 nor omega / 2 mod omega),
    "period_doubling" at omega / 2, "branch_point" for a real exponent where the tangent has
    no fold (a fold's real exponent is the fold itself, recorded from the tangent: a real
    crossing, or one whose kind changes over the step, within a step of a fold is skipped)."""
    out = []
    for i in range(len(lam) - 1):
        a, b = lam[i], lam[i + 1]
        a, b = a[np.isfinite(a)], b[np.isfinite(b)]
        if a.size != b.size or a.size == 0:
            continue
        b = _match(a, b, omega[i])
        ua, ub = a.real > 1e-9 * omega[i], b.real > 1e-9 * omega[i + 1]
        ka, kb = _kind(a, omega[i]), _kind(b, omega[i + 1])
        for j in np.flatnonzero(ua != ub):
            if ka[j] == kb[j] == 1 and a[j].imag < 0:
                continue                           # the conjugate of a pair counted once
            p, frac, root = _refine_crossing(cont, arcs[i] if i < len(arcs) else None, system,
                                             hill_at, a[j], b[j], omega[i], params[i:i + 2])
            if root is not None:         # the kind of the exponent where Re = 0, at the
                w_root = p if system.fixed_omega is None else system.fixed_omega  # root's omega
                kind = int(_kind(np.array([root]), w_root)[0])
            else:                        # a kind that changes over the step: the unstable side
                kind = int(ka[j] if ka[j] == kb[j] else (kb[j] if ub[j] else ka[j]))
            # next to a fold, real crossings (and undetermined ones) are the fold itself
            if fold_steps & {i - 1, i, i + 1} and (kind == 0 or (root is None
                                                                 and ka[j] != kb[j])):
                continue
            name = ("branch_point", "neimark_sacker", "period_doubling")[kind]
            out.append((name, i if frac < 0.5 else i + 1, p))
    return out


def _refine_crossing(cont, arc, system, hill_at, la, lb, omega, pab):
    """(the parameter where Re lambda = 0 between two points, the fraction of the step, the
    exponent there or None): Brent's method along the step (a corrector and Hill's method per
    evaluation) on the real part of the exponent nearest the linear interpolation of la and
    lb. The exponent is returned when its |Re| at the root is below 1e-8 omega (not a jump
    between exponents); when the search fails, the linear interpolation of the points'
    parameters ``pab`` in Re lambda and None."""
    from scipy.optimize import brentq
    frac = float(la.real / (la.real - lb.real))
    linear = (pab[0] + frac * (pab[1] - pab[0]), frac, None)
    if arc is None:
        return linear
    U, p, t, ds, su = arc
    su_now = cont.su
    cont.su = su
    x0 = np.concatenate([U.ravel() / su, [p / cont.sw]])
    found = {}

    def re_at(s):
        x, _ = cont.correct(x0 + s * t, t, x0, s)
        if x is None:
            raise NewtonError("crossing refinement failed")
        Ux, px = x[:-1].reshape(U.shape) * su, x[-1] * cont.sw
        lam = hill_at(Ux, px if system.fixed_omega is None else system.fixed_omega)
        d = lam - (la + (s / ds) * (lb - la))
        d = d - 1j * omega * np.round(d.imag / omega)
        found[s] = (px, lam[np.argmin(np.abs(d))])
        return found[s][1].real
    try:
        s = brentq(lambda s: la.real if s == 0.0 else re_at(s), 0.0, ds, xtol=1e-10 * ds,
                   rtol=1e-14)
        if s not in found:
            re_at(s)
        px, root = found[s]
        return px, s / ds, (root if abs(root.real) <= 1e-8 * omega else None)
    except (NewtonError, ValueError):
        return linear
    finally:
        cont.su = su_now


# ----------------------------------------------------------------------------------------------
# convergence in the number of harmonics


def _check_indices(n_points, spec, x_max):
    """The points re-solved with 2 H harmonics: ``spec`` of them spread evenly along the curve
    (first and last included) and the one of the largest amplitude; all with "all"."""
    if spec == "all":
        return np.arange(n_points)
    if spec == 0:
        return np.array([], dtype=int)
    idx = np.round(np.linspace(0, n_points - 1, min(spec, n_points))).astype(int)
    return np.unique(np.append(idx, int(np.argmax(x_max.max(axis=1)))))


def _harmonic_convergence(system, cont, points, x_max, model):
    """max over the outputs of |x_max(2H) - x_max(H)| / max x_max(2H) at the checked points
    (NaN elsewhere; inf where Newton failed with 2 H harmonics)."""
    out = np.full(len(points), np.nan)
    idx = _check_indices(len(points), model["convergence_points"], x_max)
    if idx.size == 0:
        return out
    H2 = 2 * system.H
    F2 = np.zeros((H2 + 1, system.F.shape[1]), complex)
    F2[:system.H + 1] = system.F
    sys2 = _System(system.rec, _law_function(model["elements"], 2 * system.N), system.ne,
                   system.no, F2, H2, 2 * system.N, system.fixed_omega)
    sys2._static = system._static
    cont2 = _Continuation(sys2, cont.tol, cont.max_iter, cont.sw)
    for i in idx:
        U, p, _ = points[i]
        U2 = np.zeros((2 * H2 + 1, system.ne))
        U2[:U.shape[0]] = U
        cont2.su = max(np.abs(U).max(), 1e-300)
        try:
            U2, _ = cont2.solve_fixed(U2, p)
        except NewtonError:
            out[i] = np.inf
            continue
        x2 = _peak(sys2.outputs(U2, p))
        out[i] = np.abs(x2 - x_max[i]).max() / max(x2.max(), 1e-300)
    return out
