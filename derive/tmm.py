"""Transfer matrix method in the Laplace domain.

State vector z = [x, f, 1]^T: displacement, internal force, 1 (augmented column). A chain
(station n: spring k_n parallel to damper c_n from node n-1 to mass m_n, force F_n on mass n)

    ground |--[k1,c1]--(m1)--[k2,c2]--(m2)-- ... --[kN,cN]--(mN)  free
                        F1                F2                 FN

has the system matrix U = prod_{n=N..1} P_n M_n S_n (last element leftmost). With x_0 = 0 at the
base and f = 0 beyond the free end, f_base = -U23/U22, and the free-vibration poles are the roots
of U22(s) = 0.
"""
from __future__ import annotations

import sympy as sp

s = sp.Symbol("s")
x, f = sp.symbols("x f")


def spring_damper(k, c):
    """Field matrix of a spring k parallel to a damper c: x_R = x_L + f/(k + c s)."""
    return sp.Matrix([[1, 1 / (k + c * s), 0], [0, 1, 0], [0, 0, 1]])


def mass(m):
    """Point matrix of a mass: f_R = f_L + m s^2 x."""
    return sp.Matrix([[1, 0, 0], [m * s**2, 1, 0], [0, 0, 1]])


def ground_spring_damper(kg, cg):
    """Point matrix of a spring kg and a damper cg from the mass to the ground:
    f_R = f_L + (kg + cg s) x."""
    return sp.Matrix([[1, 0, 0], [kg + cg * s, 1, 0], [0, 0, 1]])


def force(F):
    """Point matrix of an external force on the station: f_R = f_L - F."""
    return sp.Matrix([[1, 0, 0], [0, 1, -F], [0, 0, 1]])


def station(m, k, c, F=0, kg=0, cg=0):
    """Station n: spring-damper, then mass with its ground spring-damper, then force."""
    return force(F) * ground_spring_damper(kg, cg) * mass(m) * spring_damper(k, c)


def chain_symbols(n):
    """m1..mN, k1..kN, c1..cN, F1..FN."""
    return tuple(sp.symbols(f"{p}1:{n + 1}") for p in ("m", "k", "c", "F"))


def system_matrix(ms, ks, cs, Fs):
    """U = P_N M_N S_N ... P_1 M_1 S_1 and the partial products U_n = P_n..S_1 (n = 1..N)."""
    U = sp.eye(3)
    partial = []
    for m, k, c, F in zip(ms, ks, cs, Fs):
        U = station(m, k, c, F) * U
        partial.append(U)
    return U, partial


def chain_response(ms, ks, cs, Fs):
    """Displacements x_1..x_N in the Laplace domain from the boundary conditions.

    x_0 = 0 and f_{N+1} = 0 give f_base = -U23/U22; x_n is row 1 of U_n [0, f_base, 1]^T.
    """
    U, partial = system_matrix(ms, ks, cs, Fs)
    f_base = -U[1, 2] / U[1, 1]
    z0 = sp.Matrix([0, f_base, 1])
    return [sp.together(sp.simplify((Un * z0)[0])) for Un in partial]


def transfer_function(n, output, load):
    """x_output / F_load (1-based indices) of a symbolic n-mass chain, as one rational function."""
    ms, ks, cs, Fs = chain_symbols(n)
    Fs_on = [Fs[i] if i == load - 1 else 0 for i in range(n)]
    xs = chain_response(ms, ks, cs, Fs_on)
    return sp.factor(sp.cancel(xs[output - 1] / Fs[load - 1]))


def characteristic_polynomial(n):
    """U22(s) of the unloaded chain times prod (k_n + c_n s): a polynomial whose roots are the
    poles."""
    ms, ks, cs, _ = chain_symbols(n)
    U, _ = system_matrix(ms, ks, cs, [0] * n)
    scale = sp.Mul(*[k + c * s for k, c in zip(ks, cs)])
    return sp.expand(sp.cancel(U[1, 1] * scale))
