"""Amplification matrix of every scheme, from its own definition.

Apply a scheme to x'' + 2 zeta omega x' + omega^2 x = 0 in its acceleration form
(x_e = Dx a_e + Ex(h), v_e = Dv a_e + Ev(h), with Ex, Ev linear in the history h):

    a_e = -(2 zeta omega Ev + omega^2 Ex) / (1 + 2 zeta omega Dv + omega^2 Dx),
    h_{n+1} = c_u a_e + L h_n                       (x1, v1, a1 from the update; lags shift)

so h_{n+1} = A h_n. With the history scaled to y = (x, dt v, dt^2 a, ...) the entries depend on
Omega = omega dt and zeta only. Spectral radius rho = max |eig A|; the principal pair
lambda = exp(Omega_bar (-xi_bar +- i)) gives the period elongation Omega / Omega_bar - 1 and the
algorithmic damping xi_bar (Hilber & Hughes 1978).
"""
from __future__ import annotations

from functools import cache

import sympy as sp

from . import integrators as I, kernels

Omega, zeta = sp.symbols("Omega zeta", nonnegative=True)


def _scale(name):
    """Power of dt that makes a history quantity dimensionless like x: x 0, v 1, a 2."""
    return {"x": 0, "v": 1, "a": 2}[name[0]]


@cache
def amplification_matrix(name: str | I.Scheme) -> sp.Matrix:
    """A(Omega, zeta, params) acting on the scaled history (x, dt v, dt^2 a, lags) of a built-in
    scheme (by name) or a `Scheme` value."""
    scheme = I.resolve(name)
    if scheme.stages:  # a composite scheme: its sub-steps in turn, A = A_k ... A_2 A_1
        A = sp.eye(len(scheme.history))
        for part in scheme.stages:
            A = (amplification_matrix(part) * A).applyfunc(sp.cancel)
        return A
    spec = kernels.scheme_spec(name)
    fs = spec.forms["acceleration"]
    dt, omega = I.dt, sp.Symbol("omega", positive=True)
    hist = list(spec.history)
    h = {n: sp.Symbol(n) for n in hist}
    lin = lambda coeffs: sum(c * h[n] for n, c in coeffs.items() if n in h)  # noqa: E731
    Ex, Ev = lin(fs.hist_terms["q"]), lin(fs.hist_terms["s"])
    Dx, Dv = fs.constants["p"], fs.constants["r"]
    ae = -(2 * zeta * omega * Ev + omega**2 * Ex) / (1 + 2 * zeta * omega * Dv + omega**2 * Dx)
    new = {}
    for q in ("x1", "v1", "a1"):
        terms = fs.update[q]
        new[q[0] + "0"] = terms.get("u", 0) * ae + lin(terms)
    for n in hist:  # lags: xm1 <- x0, xm2 <- xm1, ...
        if n[1] == "m":
            lag = int(n[2:])
            new[n] = h[n[0] + ("0" if lag == 1 else f"m{lag - 1}")]
    # scaled variables y_n = dt^k h_n; A_ij = d y_i' / d y_j = dt^(k_i - k_j) d h_i' / d h_j
    rows = []
    for ni in hist:
        row = []
        for nj in hist:
            entry = sp.diff(new[ni], h[nj]) * dt ** (_scale(ni) - _scale(nj))
            row.append(sp.simplify(entry.subs(omega, Omega / dt)))
        rows.append(row)
    A = sp.Matrix(rows)
    assert not A.has(dt), f"{name}: amplification matrix still depends on dt"
    return A


def period_elongation_series(name: str, order: int = 4):
    """Leading terms in Omega of the period elongation of a scheme with a 2 x 2 principal block
    (undamped): from the eigenvalues' argument Omega_bar, Omega / Omega_bar - 1."""
    A = amplification_matrix(name).subs(zeta, 0)
    lam = sp.symbols("lam")
    # x and dt v rows/columns carry the principal pair; a is slaved for the Newmark family
    poly = sp.numer(sp.factor(sp.together(A.charpoly(lam).as_expr())))
    return sp.series(_principal_elongation(poly, lam), Omega, 0, order).removeO(), poly


def _principal_elongation(poly, lam):
    """Omega/Omega_bar - 1 from a characteristic polynomial lam^k (lam^2 - 2 A1 lam + A2)."""
    quad = [f for f in sp.factor_list(poly, lam)[1] if sp.degree(f[0], lam) == 2][0][0]
    quad = sp.Poly(quad, lam)
    c2, c1, c0 = quad.all_coeffs()
    A1, A2 = -c1 / (2 * c2), c0 / c2  # lam^2 - 2 A1 lam + A2
    omega_bar = sp.acos(A1 / sp.sqrt(A2))
    return Omega / omega_bar - 1
