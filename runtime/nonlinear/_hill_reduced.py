r"""Hill's method on a reduced model: the stability of a harmonic-balance orbit of a large model
at a cost that does not grow with the model.

Hill's quadratic eigenproblem (`dtdyn.nonlinear._harmonic_balance`) has the size
2 n (2 H + 1) of the full model. Its Floquet exponents are those of the perturbation
q(t) = e^{lambda t} p(t), p periodic, of

.. math::

    M \ddot q + C \dot q + K q + L^T (G_y(t) L q + G_v(t) L \dot q) = 0,

with G_y, G_v the elements' dg/dy, dg/dy' along the orbit: a linear model with periodic
coefficients acting only at the elements' DOFs. It is projected on a basis T (q = T z) made of

* the modes below a cut-off w_m: K phi_r = k_r M phi_r, k_r < w_m^2 (M-orthonormal), and
* the elements' attachment modes with their mass corrections: R_0 = P K^{-1} L^T,
  R_j = P K^{-1} M R_{j-1} (j = 1 .. J), P = I - Phi Phi^T M the projection off the kept modes
  (the residual flexibility of the modes above w_m, the static correction of Craig-Bampton and
  Rubin, and its first J terms in (w / w_m)^2),

which gives M_r = T^T M T, C_r = T^T C T, K_r = T^T K T, L_r = L T (a model of m + ne (J + 1)
DOFs), diagonalized once so that M_r = I. Hill's method then runs on the reduced model with the
elements' Jacobians of the point, unchanged (they act on y = L q = L_r z).

The subspace holds the exact response of the modes below w_m and, through the Krylov terms
R_0 .. R_J, the response of the modes above it to forces at the elements up to
O((w / w_m)^{2 (J + 1)}); the Galerkin projection (left and right bases equal) of a symmetric
M, K doubles the order, so the condensed receptance L_r (K_r - w^2 M_r + i w C_r)^{-1} L_r^T
equals L (K - w^2 M + i w C)^{-1} L^T to about (w / w_m)^{4 (J + 1)} times the residual
flexibility's share (C = alpha M + beta K: the modes diagonalize it; otherwise C's coupling of
kept and neglected modes adds terms of the same order). Every frequency Hill's method asks of the
linear part, |Im lambda + k omega| <= (H + 1) omega_top, is below w_c = (H + 1) omega_top;
w_m = HILL_CUTOFF w_c with HILL_CUTOFF = 2 and J = HILL_TERMS = 2 puts the neglected part below
(1/2)^{12} = 2.4e-4 of the residual flexibility at the top harmonic and below 1e-12 at the
fundamental, where the critical exponents live (their eigenvectors are dominated by the
harmonics near omega). The exponents of the neglected modes themselves (the full model's 2 n
less the reduced model's 2 (m + ne (J + 1))) are those of modes above w_m, perturbed by the
elements only through the residual the basis holds: with Rayleigh damping their real parts are
near -(alpha + beta w_r^2) / 2, far from the stability boundary, and the reduced model's
residual modes stand in for them.

On a sparse symmetric banded model (a chain, beam, shaft) the modes come from ARPACK with a
sparse LU of K, refined (`refined_modes`), and every solve with K is refined with residuals in
twice the working precision (`refined_solve`), as the reduced receptance does: a Hermite beam
of N elements has cond(K) ~ N^4. K T and C T are summed exactly (`exact_product`), so K_r and
C_r keep their digits.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

__all__ = ["reduced_hill_model", "HILL_CUTOFF", "HILL_TERMS", "HILL_MAX_REDUCED"]

#: the kept modes: those below this multiple of w_c = (H + 1) omega_top
HILL_CUTOFF = 2.0
#: mass-correction terms R_1 .. R_J of the attachment modes
HILL_TERMS = 2
#: the reduced model's DOFs at most (its Hill eigenproblem is dense: 2 m (2 H + 1))
HILL_MAX_REDUCED = 150


def reduced_hill_model(M, C, K, L, w_c, *, width=None, cutoff=HILL_CUTOFF, terms=HILL_TERMS,
                       parts=None):
    """The reduced model (M_r = I, C_r, K_r, L_r) of Hill's method and a dict of what it holds.

    Parameters
    ----------
    M, C, K : (n, n) ndarray or scipy.sparse matrix
        The linear part (M, K symmetric, K nonsingular).
    L : (ne, n) ndarray
        The elements' deformation rows (y = L q).
    w_c : float
        The highest frequency Hill's method asks of the linear part, rad/s ((H + 1) omega_top).
    width : int or None
        Half-bandwidth of a sparse banded model (its solves are then refined), else None.
    cutoff : float
        Modes below ``cutoff * w_c`` are kept.
    terms : int
        The mass corrections R_1 .. R_J of the attachment modes.
    parts : (alpha, beta, E) or None
        A model's Rayleigh coefficients (`rayleigh_parts`): C_r = alpha M_r + beta K_r +
        T^T E T, not T^T C T (an assembled C loses alpha M against beta K at large n).

    Returns
    -------
    Mr, Cr, Kr, Lr : ndarray
        The reduced model (Mr the identity).
    info : dict
        ``modes`` (m), ``attachment`` (the attachment vectors kept), ``size`` (the reduced
        DOFs), ``cutoff_hz``.
    """
    ne = L.shape[0]
    w_m = cutoff * w_c
    sparse = sps.issparse(M) or sps.issparse(K)
    if sparse:
        M, C, K = sps.csc_matrix(M), sps.csr_matrix(C), sps.csc_matrix(K)
        k, phi, solve, prod = _sparse_modes(M, K, C, w_m, width)
    else:
        M, C, K = (np.asarray(A, dtype=float) for A in (M, C, K))
        k, phi, solve, prod = _dense_modes(M, K, C, w_m)
    m = k.size
    if m + ne * (terms + 1) > HILL_MAX_REDUCED:
        raise ValueError(f"stability='reduced': {m} modes below {w_m / 2 / np.pi:.4g} Hz, a "
                         f"reduced model of {m + ne * (terms + 1)} DOFs (at most "
                         f"{HILL_MAX_REDUCED}); pass stability=False for this model and band")
    MP = M @ phi

    def project(V):
        return V - phi @ (MP.T @ V)

    V = project(solve(np.asarray(L.T, dtype=float)))
    blocks = [V]
    for _ in range(terms):
        V = project(solve(M @ V))
        blocks.append(V)
    R = np.hstack(blocks)
    # the attachment block M-orthonormal (dropping directions its columns repeat)
    R = R / np.sqrt(np.einsum("ij,ij->j", R, M @ R))
    g, Z = np.linalg.eigh(R.T @ (M @ R))
    keep = g > 1e-12 * g.max()
    R = R @ (Z[:, keep] / np.sqrt(g[keep]))
    R = project(R)          # once more off the modes (rounding)
    T = np.hstack([phi, R])
    KT, CT = prod(T)
    Mr, Kr, Cr = T.T @ (M @ T), T.T @ KT, T.T @ CT
    Mr, Kr = 0.5 * (Mr + Mr.T), 0.5 * (Kr + Kr.T)
    if m:                        # the modes' block exactly: k_r (refined), M-orthonormal
        Kr[:m, :m] = np.diag(k)
        Mr[:m, :m] = np.eye(m)
        Kr[:m, m:], Kr[m:, :m] = 0.0, 0.0
        Mr[:m, m:], Mr[m:, :m] = 0.0, 0.0
    if parts is not None:
        alpha, beta, E = parts
        Cr = alpha * Mr + beta * Kr + (0.0 if E is None else T.T @ (E @ T))
    # the reduced model's own modes: Mr = I, Kr diagonal
    kr, Z = sla.eigh(Kr, Mr)
    Cr = Z.T @ Cr @ Z
    Lr = (np.asarray(L, dtype=float) @ T) @ Z
    info = dict(modes=int(m), attachment=int(R.shape[1]), size=int(T.shape[1]),
                cutoff_hz=w_m / 2 / np.pi, top_hz=float(np.sqrt(max(kr[-1], 0.0)) / 2 / np.pi))
    return np.eye(kr.size), Cr, np.diag(kr), Lr, info


def _sparse_modes(M, K, C, w_m, width):
    """Modes below w_m of a sparse model, a (refined) solve with K, and T -> (K T, C T)."""
    from dtdyn.nonlinear._receptance import (band_diagonals, exact_product, modes_below,
                                             refined_modes, refined_solve)
    lu = spla.splu(K)
    n = K.shape[0]
    if width is not None:
        kd, cd = band_diagonals(K, width), band_diagonals(C, width)

        def solve(V):
            return refined_solve(lu.solve, kd, V)

        def prod(T):
            (kh, kl), (ch, cl) = exact_product(kd, T), exact_product(cd, T)
            return kh + kl, ch + cl
    else:
        def solve(V):
            return lu.solve(V)

        def prod(T):
            return K @ T, C @ T
    m = modes_below(M, K, w_m)
    if m < 0:        # no inertia count: ARPACK's modes until one lies above w_m
        m = None
    if m is None or m > 0:
        op = spla.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
        want = min(m if m is not None else 20, n - 2)
        while True:
            k, phi = spla.eigsh(K, want, M=M, sigma=0.0, OPinv=op)
            if m is not None or k.max() >= w_m ** 2 or want >= min(HILL_MAX_REDUCED, n - 2):
                break
            want = min(2 * want, n - 2)
        order = np.argsort(k)
        k, phi = k[order], phi[:, order]
        sel = k < w_m ** 2
        k, phi = k[sel], phi[:, sel]
        if width is not None and k.size:
            k, phi = refined_modes(K, M, k, phi, width)
    else:
        k, phi = np.zeros(0), np.zeros((n, 0))
    return k, phi, solve, prod


def _dense_modes(M, K, C, w_m):
    """Modes below w_m of a dense model, a solve with K, and T -> (K T, C T)."""
    k, phi = sla.eigh(K, M, subset_by_value=(-np.inf, w_m ** 2))
    lu = sla.lu_factor(K)

    def solve(V):
        return sla.lu_solve(lu, V)

    def prod(T):
        return K @ T, C @ T
    return k, phi, solve, prod
