r"""Mode shapes by inverse iteration on an O(N) sweep, at the roots of a Wittrick-Williams count.

Given the eigenvalues :math:`\lambda_r = \omega_r^2` of :math:`K \phi = \lambda M \phi` (from
the count, to the last bits) and a solver of :math:`(K - \sigma M) x = f` that costs O(N)
(the tree's or the beam's Riccati sweep), each shape is the limit of

.. math::

    x_{k+1} = (K - \lambda_r M)^{-1} M x_k,

which multiplies the component of every other mode s by
:math:`(\lambda_r - \tilde\lambda_r) / (\lambda_s - \tilde\lambda_r)`, :math:`\tilde\lambda_r`
the computed root: with the root correct to a few ulps one step leaves the other modes at
rounding level, and a second step removes what a poor start vector left (Wilkinson,
*The Algebraic Eigenvalue Problem*, ch. 9; Peters & Wilkinson 1971). A pivot that vanishes (the
shift is an eigenvalue to the bit) is replaced by eps times the largest stiffness, which only
scales the result. Roots closer than ``CLOSE`` relative to each other form a cluster: its
vectors are iterated together and replaced by the Rayleigh-Ritz vectors of the subspace they
span (the small pencil :math:`(X^T K X, X^T M X)`), which separates close roots and gives an
M-orthonormal basis of a repeated root's eigenspace. Every shape is scaled to
:math:`\phi^T M \phi = 1` with its largest-magnitude entry positive, as `dtdyn.modes`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

#: roots closer than this (relative) are iterated together as a cluster
CLOSE = 1e-6
#: inverse iteration steps (isolated roots; clusters take one more)
STEPS = 2


def clusters(lam: np.ndarray, close: float = CLOSE) -> list:
    """Index groups of the ascending ``lam`` whose neighbours are within ``close`` relative."""
    groups, start = [], 0
    for j in range(1, lam.size + 1):
        if j == lam.size or lam[j] - lam[j - 1] > close * max(abs(lam[j]), abs(lam[j - 1])):
            groups.append(np.arange(start, j))
            start = j
    return groups


def inverse_iteration(lam, solve, mass, stiffness, n: int, seed: int = 14) -> np.ndarray:
    """(n, len(lam)) mass-normalized shapes (module docstring).

    ``solve(sigma, F)``: X with (K - sigma_j M) X[:, j] = F[:, j] for every column j (sigma an
    array of shifts); ``mass(X)``, ``stiffness(X)``: M X and K X.
    """
    lam = np.asarray(lam, dtype=float)
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, lam.size))
    groups = clusters(lam)
    steps = STEPS + (1 if any(g.size > 1 for g in groups) else 0)
    for _ in range(steps):
        X = solve(lam, mass(X))
        X = X / np.abs(X).max(axis=0)
        for g in groups:
            if g.size > 1:
                X[:, g] = _ritz(X[:, g], mass, stiffness)
    for g in groups:
        if g.size > 1:
            X[:, g] = _ritz(X[:, g], mass, stiffness)
    X = X / np.sqrt(np.einsum("ij,ij->j", X, mass(X)))
    big = np.argmax(np.abs(X), axis=0)
    return X * np.sign(X[big, np.arange(X.shape[1])])


def _ritz(X, mass, stiffness):
    """The Rayleigh-Ritz vectors of span(X), M-orthonormal, ascending."""
    Mx, Kx = X.T @ mass(X), X.T @ stiffness(X)
    Mx, Kx = 0.5 * (Mx + Mx.T), 0.5 * (Kx + Kx.T)
    _, V = sla.eigh(Kx, Mx)
    return X @ V
