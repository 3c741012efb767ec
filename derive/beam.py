"""Euler-Bernoulli beams in planar bending: element matrices and the exact field matrix.

Each node carries w (transverse displacement) and psi = dw/dx (rotation); the internal forces
are the bending moment M = EI w'' and the shear V = dM/dx = EI w'''.

Finite element (Hermite cubic, element of length L between nodes a and b, DOFs
[w_a, psi_a, w_b, psi_b]): with the shape functions N(xi), xi = x / L,

    N = [1 - 3 xi^2 + 2 xi^3,  L (xi - 2 xi^2 + xi^3),  3 xi^2 - 2 xi^3,  L (xi^3 - xi^2)],

    K_e = EI int_0^L N''^T N'' dx,       M_e = rho_A int_0^L N^T N dx   (consistent),

and the lumped mass by HRZ diagonal scaling (Hinton, Rock & Zienkiewicz 1976): the diagonal of
M_e scaled so that the translational entries sum to the element's mass rho_A L.

Laplace domain (the transfer matrix method): z = [w, psi, M, V] obeys z' = A z,

    A = [[0, 1, 0, 0], [0, 0, 1/EI, 0], [0, 0, 0, 1], [-rho_A s^2, 0, 0, 0]],

and since A^4 = b^4 I with b^4 = -rho_A s^2 / EI (b real for s = j omega), the field matrix is
exp(A L) = c0 I + c1 A + c2 A^2 + c3 A^3 with the Krylov functions

    c0 = (cosh bL + cos bL)/2,   c1 = (sinh bL + sin bL)/(2 b),
    c2 = (cosh bL - cos bL)/(2 b^2),   c3 = (sinh bL - sin bL)/(2 b^3),

checked here symbolically (d/dL of the sum equals A times it, and it is I at L = 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

x, L = sp.symbols("x L", positive=True)
EI, rho_A = sp.symbols("EI rho_A", positive=True)
b = sp.Symbol("b", positive=True)  # the wavenumber, b^4 = rho_A omega^2 / EI
s = sp.Symbol("s")


def shape_functions() -> sp.Matrix:
    """Hermite cubics N (1 x 4) on [0, L]: N_i has value/slope 1 at its own DOF, 0 at the rest."""
    xi = x / L
    N = sp.Matrix([[1 - 3 * xi**2 + 2 * xi**3, L * (xi - 2 * xi**2 + xi**3),
                    3 * xi**2 - 2 * xi**3, L * (xi**3 - xi**2)]])
    # the interpolation conditions, derived rather than assumed
    dN = N.diff(x)
    at = [N.subs(x, 0), dN.subs(x, 0), N.subs(x, L), dN.subs(x, L)]
    assert sp.Matrix([row for row in at]).applyfunc(sp.simplify) == sp.eye(4)
    return N


def stiffness_matrix() -> sp.Matrix:
    """K_e = EI int N''^T N'' dx (4 x 4)."""
    B = shape_functions().diff(x, 2)
    return (EI * (B.T * B)).applyfunc(lambda e: sp.factor(sp.integrate(e, (x, 0, L))))


def consistent_mass_matrix() -> sp.Matrix:
    """M_e = rho_A int N^T N dx (4 x 4)."""
    N = shape_functions()
    return (rho_A * (N.T * N)).applyfunc(lambda e: sp.factor(sp.integrate(e, (x, 0, L))))


def lumped_mass_matrix() -> sp.Matrix:
    """HRZ lumping: diag(M_e) scaled so that the w entries add up to rho_A L."""
    Mc = consistent_mass_matrix()
    d = [Mc[i, i] for i in range(4)]
    scale = rho_A * L / (d[0] + d[2])
    return sp.diag(*[sp.factor(scale * e) for e in d])


def field_generator() -> sp.Matrix:
    """A of z' = A z, z = [w, psi, M, V], in the Laplace variable s."""
    return sp.Matrix([[0, 1, 0, 0], [0, 0, 1 / EI, 0], [0, 0, 0, 1],
                      [-rho_A * s**2, 0, 0, 0]])


def field_matrix() -> sp.Matrix:
    """exp(A L) in the wavenumber b (s = j omega, b^4 = rho_A omega^2 / EI), checked."""
    A = field_generator().subs(s**2, -b**4 * EI / rho_A)
    assert (A**4 - b**4 * sp.eye(4)).applyfunc(sp.simplify) == sp.zeros(4)
    c0 = (sp.cosh(b * L) + sp.cos(b * L)) / 2
    c1 = (sp.sinh(b * L) + sp.sin(b * L)) / (2 * b)
    c2 = (sp.cosh(b * L) - sp.cos(b * L)) / (2 * b**2)
    c3 = (sp.sinh(b * L) - sp.sin(b * L)) / (2 * b**3)
    T = (c0 * sp.eye(4) + c1 * A + c2 * A**2 + c3 * A**3).applyfunc(sp.expand)
    assert (T.diff(L) - A * T).applyfunc(sp.simplify) == sp.zeros(4)
    assert T.subs(L, 0).applyfunc(sp.simplify) == sp.eye(4)
    return T


@dataclass(frozen=True)
class BeamSpec:
    """The derived beam matrices (symbols EI, rho_A, L; the field matrix also in b)."""

    K: sp.Matrix
    M: sp.Matrix
    M_lumped: sp.Matrix
    T: sp.Matrix


def derive_beam() -> BeamSpec:
    return BeamSpec(stiffness_matrix(), consistent_mass_matrix(), lumped_mass_matrix(),
                    field_matrix())


z = sp.Symbol("z", positive=True)  # b L
F = sp.symbols("f0:4")


def krylov_functions() -> tuple:
    """f_k(z), z = b L, with c_k = L^k f_k (module docstring): closed forms and their series to
    z^16 (used for z < 1, where the closed forms cancel; the first term left out is below
    1e-18 there, and at z = 1 the closed forms lose at most a few ulps)."""
    closed = ((sp.cosh(z) + sp.cos(z)) / 2, (sp.sinh(z) + sp.sin(z)) / (2 * z),
              (sp.cosh(z) - sp.cos(z)) / (2 * z**2), (sp.sinh(z) - sp.sin(z)) / (2 * z**3))
    series = tuple(sp.series(f, z, 0, 20).removeO() for f in closed)
    return closed, series


def field_matrix_scaled() -> sp.Matrix:
    """exp(A L) written in f_k(b L): f0 I + L f1 A + L^2 f2 A^2 + L^3 f3 A^3 (checked equal to
    `field_matrix`)."""
    A = field_generator().subs(s**2, -b**4 * EI / rho_A)
    T = sum((L**k * F[k] * A**k for k in range(4)), sp.zeros(4))
    closed, _ = krylov_functions()
    full = T.subs({F[k]: closed[k].subs(z, b * L) for k in range(4)})
    assert (full - field_matrix()).applyfunc(sp.simplify) == sp.zeros(4)
    return T.applyfunc(sp.expand)


def dynamic_stiffness_matrix() -> sp.Matrix:
    """The exact element's dynamic stiffness Z (4 x 4) at s = j omega, in f_k(b L):
    [F_a, Q_a, F_b, Q_b] = Z [w_a, psi_a, w_b, psi_b], the forces and moments the nodes apply
    to the element. A point force F makes the shear jump by F and a point moment Q the bending
    moment by -Q (from the variation of the energy), so with z_b = T z_a (`field_matrix_scaled`):
    F_a = V_a, Q_a = -M_a, F_b = -V_b, Q_b = M_b. Solving the first two rows of z_b = T z_a for
    [M_a, V_a] gives Z. Checked: Z at b = 0 is K_e (`stiffness_matrix`: the Hermite cubics are the
    exact static shapes) and dZ/d(omega^2) at 0 is -M_e (the consistent mass: the static shapes
    weight the inertia), and Z is symmetric."""
    T = field_matrix_scaled()
    wa, pa, wb, pb, Ma, Va = sp.symbols("w_a psi_a w_b psi_b M_a V_a")
    za = sp.Matrix([wa, pa, Ma, Va])
    zb = T * za
    sol = sp.solve([zb[0] - wb, zb[1] - pb], [Ma, Va], dict=True)[0]
    Mb, Vb = (sp.together(zb[i].subs(sol)) for i in (2, 3))
    loads = [sol[Va], -sol[Ma], -Vb, Mb]
    q = [wa, pa, wb, pb]
    Z = sp.Matrix(4, 4, lambda i, j: sp.factor(sp.expand(sp.together(loads[i]).diff(q[j]))))
    # the checks: static limit, consistent mass, symmetry
    lam_ = sp.Symbol("lam")  # omega^2 = b^4 EI / rho_A
    zz = b * L
    series = {F[0]: 1 + zz**4 / 24, F[1]: 1 + zz**4 / 120, F[2]: sp.Rational(1, 2) + zz**4 / 720,
              F[3]: sp.Rational(1, 6) + zz**4 / 5040}
    Zt = Z.subs(series).subs(b, (lam_ * rho_A / EI) ** sp.Rational(1, 4))
    assert (Zt.subs(lam_, 0) - stiffness_matrix()).applyfunc(sp.simplify) == sp.zeros(4)
    assert (Zt.diff(lam_).subs(lam_, 0) + consistent_mass_matrix()).applyfunc(sp.simplify) \
        == sp.zeros(4)
    # written from node a's rows by symmetry (Z = Z^T) and by the element's mirror symmetry
    # (x -> L - x flips w' : Z[b, b] = R Z[a, a] R, R = diag(1, -1)); both hold only through the
    # identities between the Krylov functions, so they are checked numerically, at 40 digits
    Zs = sp.Matrix(4, 4, lambda i, j: Z[min(i, j), max(i, j)] if min(i, j) < 2 else 0)
    Zs[2, 2], Zs[3, 3] = Z[0, 0], Z[1, 1]
    Zs[2, 3] = Zs[3, 2] = -Z[0, 1]
    closed, _ = krylov_functions()
    for bv, Lv, EIv in ((sp.Rational(7, 10), sp.Rational(13, 10), 2),
                        (sp.Rational(29, 10), sp.Rational(4, 5), sp.Rational(1, 2)),
                        (11, sp.Rational(11, 10), 3)):
        at = {F[k]: closed[k].subs(z, bv * Lv) for k in range(4)}
        num, sym = ((A.subs(at).subs({b: bv, L: Lv, EI: EIv})).evalf(40) for A in (Z, Zs))
        assert max(abs(num[i, j] - sym[i, j]) for i in range(4) for j in range(4)) \
            <= sp.Float(10, 40) ** -30 * max(abs(e) for e in num)
    return Zs
