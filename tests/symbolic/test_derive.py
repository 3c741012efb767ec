"""Tier 1: the SymPy derivations (dtdyn.derive) against hand formulas typed here.

Every oracle below is written out by hand from shared/reference.md sections 2-4 (closed forms, or
the defining relations solved on paper); the derived expression must equal it identically,
``sp.simplify(derived - hand) == 0``. Published misprints are typed too and must *differ*.
"""
from __future__ import annotations

import random

import pytest
import sympy as sp

from dtdyn.derive import dttmm, tmm
from dtdyn.derive import integrators as I

# Symbols with the same names and assumptions as dtdyn.derive.integrators (SymPy symbols with equal
# name and assumptions are equal, so these are the module's symbols without importing them).
dt = sp.Symbol("dt", positive=True)
x0, v0, a0 = sp.symbols("x0 v0 a0")
xm1, xm2, vm1, vm2 = sp.symbols("xm1 xm2 vm1 vm2")
xe, ve, ae = sp.symbols("xe ve ae")
beta, gamma, theta, alpha, rho = sp.symbols("beta gamma theta alpha rho_inf", real=True)

R = sp.Rational


STATE = (x0, v0, a0, xm1, xm2, vm1, vm2, xe, ae)


def _zero(d) -> bool:
    """d == 0 identically: the expanded numerator of a rational function vanishes."""
    numerator, _ = sp.fraction(sp.together(d))
    return sp.expand(numerator) == 0 or sp.simplify(d) == 0


def same(a, b) -> bool:
    """True when a - b is identically zero.

    Rational functions: ``cancel`` decides. Expressions affine in the state symbols (all the
    integrator maps) are split into their coefficients first, which is much faster than
    cancelling the whole difference and proves the same thing.
    """
    d = sp.sympify(a) - sp.sympify(b)
    state = [v for v in STATE if d.has(v)]
    if state:
        parts = [sp.diff(d, v) for v in state] + [d.subs({v: 0 for v in state})]
        if not any(pt.has(v) for pt in parts for v in state):  # affine: compare coefficients
            return all(_zero(pt) for pt in parts)
    return _zero(d)


def test_symbols_are_the_modules():
    assert (dt, x0, v0, a0, xm1, xm2, vm1, vm2) == (I.dt, I.x0, I.v0, I.a0, I.xm1, I.xm2, I.vm1,
                                                     I.vm2)
    assert (xe, ve, ae, beta, gamma, theta, alpha, rho) == (I.xe, I.ve, I.ae, I.beta, I.gamma,
                                                            I.theta, I.alpha, I.rho_inf)


# ------------------------------------------------------------------ TMM, reference section 2
s = sp.Symbol("s")
m1, m2, k1, k2, c1, c2, F = sp.symbols("m1 m2 k1 k2 c1 c2 F")
P_HAND = (m1 * m2 * s**4 + (c2 * m1 + c2 * m2 + c1 * m2) * s**3
          + (k2 * m2 + k1 * m2 + k2 * m1 + c1 * c2) * s**2 + (k2 * c1 + k1 * c2) * s + k1 * k2)


def test_tmm_two_dof_x1_over_F():
    assert same(tmm.transfer_function(2, 1, 1), (m2 * s**2 + c2 * s + k2) / P_HAND)


def test_tmm_two_dof_x2_over_F_and_misprint():
    derived = tmm.transfer_function(2, 2, 1)
    assert same(derived, (c2 * s + k2) / P_HAND)
    misprint = F * (c2 * s + k2) / P_HAND  # the source's numerator carries a stray factor F
    assert not same(derived, misprint)
    assert F not in derived.free_symbols


def test_tmm_characteristic_polynomial():
    assert sp.expand(tmm.characteristic_polynomial(2) - P_HAND) == 0


def test_tmm_element_matrices():
    k, c, m = sp.symbols("k c m")
    assert tmm.spring_damper(k, c) == sp.Matrix([[1, 1 / (k + c * s), 0], [0, 1, 0], [0, 0, 1]])
    assert tmm.mass(m) == sp.Matrix([[1, 0, 0], [m * s**2, 1, 0], [0, 0, 1]])
    assert tmm.force(F) == sp.Matrix([[1, 0, 0], [0, 1, -F], [0, 0, 1]])


def test_tmm_one_dof_by_hand():
    """1 DOF: x/F = 1/(m s^2 + c s + k); the pole polynomial is m s^2 + c s + k."""
    assert same(tmm.transfer_function(1, 1, 1), 1 / (m1 * s**2 + c1 * s + k1))
    assert sp.expand(tmm.characteristic_polynomial(1) - (m1 * s**2 + c1 * s + k1)) == 0


# ------------------------------------------------------------------ Newmark family, section 4
def newmark_hand(b, g):
    """A, B, D, E of Newmark(beta, gamma), reference section 4."""
    A = 1 / (b * dt**2)
    B = -A * (x0 + dt * v0 + (R(1, 2) - b) * dt**2 * a0)
    D = g / (b * dt)
    E = v0 + dt * ((1 - g) * a0 + g * B)
    return A, B, D, E


def newmark_hand_acceleration(b, g):
    """Dx, Ex, Dv, Ev: xe = x1 = Dx a1 + Ex, ve = v1 = Dv a1 + Ev."""
    return (b * dt**2, x0 + dt * v0 + (R(1, 2) - b) * dt**2 * a0,
            g * dt, v0 + (1 - g) * dt * a0)


def check_abde(der, hand):
    for name, h in zip("ABDE", hand):
        assert same(getattr(der, name), h), (der.scheme.name, name, getattr(der, name), h)


def test_newmark_general():
    der = I.derive_scheme("newmark")
    assert not der.explicit
    check_abde(der, newmark_hand(beta, gamma))
    Dx, Ex, Dv, Ev = newmark_hand_acceleration(beta, gamma)
    assert same(der.Dx, Dx) and same(der.Ex, Ex) and same(der.Dv, Dv) and same(der.Ev, Ev)
    assert der.w0 == 0 and der.w1 == 1
    # update, displacement form: x1 = xe, a1 = A xe + B, v1 = D xe + E
    A, B, D, E = newmark_hand(beta, gamma)
    assert same(der.update_x["x1"], xe)
    assert same(der.update_x["a1"], A * xe + B)
    assert same(der.update_x["v1"], D * xe + E)
    # update, acceleration form
    assert same(der.update_a["a1"], ae)
    assert same(der.update_a["x1"], Dx * ae + Ex)
    assert same(der.update_a["v1"], Dv * ae + Ev)


PRESETS = {
    "average_acceleration": (R(1, 4), R(1, 2)),
    "linear_acceleration": (R(1, 6), R(1, 2)),
    "fox_goodwin": (R(1, 12), R(1, 2)),
    "newmark_1_8": (R(1, 8), R(1, 2)),
    "fox_euler": (R(1, 2), 1),
}


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_newmark_presets(name):
    b, g = PRESETS[name]
    der = I.derive_scheme(name)
    assert not der.explicit
    check_abde(der, newmark_hand(b, g))
    Dx, Ex, Dv, Ev = newmark_hand_acceleration(b, g)
    assert same(der.Dx, Dx) and same(der.Ex, Ex) and same(der.Dv, Dv) and same(der.Ev, Ev)
    assert der.w0 == 0 and der.w1 == 1


def test_average_acceleration_numbers():
    """The same, with the numbers worked out: A = 4/dt^2, D = 2/dt."""
    der = I.derive_scheme("average_acceleration")
    assert same(der.A, 4 / dt**2) and same(der.D, 2 / dt)
    assert same(der.B, -(4 * x0 / dt**2 + 4 * v0 / dt + a0))
    assert same(der.E, -(2 * x0 / dt + v0))


def test_fox_euler_defining_relations():
    """Fox-Euler as the source defines it: x1 = x0 + dt v0 + dt^2/2 a1, v1 = v0 + dt a1."""
    der = I.derive_scheme("fox_euler")
    a1 = der.A * xe + der.B
    assert same(xe, x0 + dt * v0 + dt**2 / 2 * a1)
    assert same(der.D * xe + der.E, v0 + dt * a1)


def test_central_difference_is_explicit():
    der = I.derive_scheme("central_difference")
    assert der.explicit is True
    assert der.Dx == 0
    assert same(der.Dv, dt / 2)
    assert same(der.Ex, x0 + dt * v0 + dt**2 / 2 * a0)
    assert same(der.Ev, v0 + dt / 2 * a0)
    assert der.update_x == {}
    assert same(der.update_a["v1"], v0 + dt / 2 * (a0 + ae))


# ------------------------------------------------------------------ Houbolt
HOUBOLT_B = -(5 * x0 - 4 * xm1 + xm2) / dt**2
HOUBOLT_E = -(18 * x0 - 9 * xm1 + 2 * xm2) / (6 * dt)


def test_houbolt():
    der = I.derive_scheme("houbolt")
    check_abde(der, (2 / dt**2, HOUBOLT_B, 11 / (6 * dt), HOUBOLT_E))
    assert der.w0 == 0 and der.w1 == 1
    assert same(der.update_x["x1"], xe)


def test_houbolt_misprint_differs():
    der = I.derive_scheme("houbolt")
    misprint = -(5 * x0 - 4 * xm1 - xm2) / dt**2
    assert not same(der.B, misprint)
    assert same(der.B - misprint, -2 * xm2 / dt**2)


def test_houbolt_acceleration_form():
    """x1 = (ae - B)/A; v1 from the backward difference with that x1."""
    der = I.derive_scheme("houbolt")
    x1 = (ae - HOUBOLT_B) * dt**2 / 2
    assert same(der.Dx * ae + der.Ex, x1)
    assert same(der.Dv * ae + der.Ev, (11 * x1 - 18 * x0 + 9 * xm1 - 2 * xm2) / (6 * dt))


# ------------------------------------------------------------------ Park
def test_park_A_D():
    der = I.derive_scheme("park")
    assert same(der.A, R(100, 36) / dt**2)
    assert same(der.D, R(10, 6) / dt)
    assert der.w0 == 0 and der.w1 == 1


def test_park_B_E_by_hand():
    """v1 = (10 x1 + Vh)/(6 dt), Vh = -15 x0 + 6 xm1 - xm2; a1 = (10 v1 + Ah)/(6 dt),
    Ah = -15 v0 + 6 vm1 - vm2  =>  a1 = 100 x1/(36 dt^2) + 10 Vh/(36 dt^2) + Ah/(6 dt)."""
    der = I.derive_scheme("park")
    Vh = -15 * x0 + 6 * xm1 - xm2
    Ah = -15 * v0 + 6 * vm1 - vm2
    assert same(der.E, Vh / (6 * dt))
    assert same(der.B, 10 * Vh / (36 * dt**2) + Ah / (6 * dt))
    # and the defining relations hold for the derived displacement form
    v1 = der.D * xe + der.E
    a1 = der.A * xe + der.B
    assert same(v1, (10 * xe - 15 * x0 + 6 * xm1 - xm2) / (6 * dt))
    assert same(a1, (10 * v1 - 15 * v0 + 6 * vm1 - vm2) / (6 * dt))


# ------------------------------------------------------------------ Wilson theta
def wilson_hand():
    td = theta * dt
    A = 6 / td**2
    B = -A * (x0 + td * v0 + td**2 / 3 * a0)
    D = 3 / td
    E = v0 + td / 2 * (a0 + B)
    return A, B, D, E


def test_wilson_equilibrium_point():
    der = I.derive_scheme("wilson")
    check_abde(der, wilson_hand())
    assert same(der.A, 6 / (theta * dt) ** 2)
    assert same(der.w0, 1 - theta) and same(der.w1, theta)


def test_wilson_update_interpolates_back():
    der = I.derive_scheme("wilson")
    A, B, _, _ = wilson_hand()
    ae_x = A * xe + B
    a1 = a0 + (ae_x - a0) / theta
    assert same(der.update_x["a1"], a1)
    assert same(der.update_x["v1"], v0 + dt / 2 * (a0 + a1))
    assert same(der.update_x["x1"], x0 + dt * v0 + dt**2 / 6 * (a1 + 2 * a0))
    # acceleration form: the same with ae the unknown
    a1a = a0 + (ae - a0) / theta
    assert same(der.update_a["a1"], a1a)
    assert same(der.update_a["x1"], x0 + dt * v0 + dt**2 / 6 * (a1a + 2 * a0))
    assert same(der.update_a["v1"], v0 + dt / 2 * (a0 + a1a))


def test_wilson_is_not_the_stretched_linear_acceleration_method():
    """The source stores the value at t + theta dt as x_{t+dt}: that is not what is derived."""
    der = I.derive_scheme("wilson")
    assert not same(der.update_x["x1"], xe)
    stretched = x0 + theta * dt * v0 + (theta * dt) ** 2 / 6 * (ae + 2 * a0)
    assert not same(der.update_a["x1"], stretched)
    assert not same(der.update_a["a1"], ae)
    # ... except at theta = 1, where both are linear acceleration
    assert same(der.update_a["x1"].subs(theta, 1), stretched.subs(theta, 1))


# ------------------------------------------------------------------ HHT-alpha
def alpha_hand(af, am, b, g):
    """A, B, D, E of the alpha family: Newmark kinematics, xe = (1-af) x1 + af x0 (same for v),
    ae = (1-am) a1 + am a0. With a1 = A_N x1 + B_N, v1 = D_N x1 + E_N (Newmark's) and
    x1 = (xe - af x0)/(1 - af)."""
    AN, BN, DN, EN = newmark_hand(b, g)
    x1 = (xe - af * x0) / (1 - af)
    ae_x = (1 - am) * (AN * x1 + BN) + am * a0
    ve_x = (1 - af) * (DN * x1 + EN) + af * v0
    A = sp.diff(ae_x, xe)
    D = sp.diff(ve_x, xe)
    return A, sp.expand(ae_x - A * xe), D, sp.expand(ve_x - D * xe)


def test_hht():
    der = I.derive_scheme("hht")
    assert same(der.w0, -alpha) and same(der.w1, 1 + alpha)
    b, g = (1 - alpha) ** 2 / 4, (1 - 2 * alpha) / 2
    hand = alpha_hand(-alpha, 0, b, g)
    check_abde(der, hand)
    # in closed form: A = 1/(beta dt^2 (1 + alpha)), D = gamma/(beta dt)
    assert same(der.A, 1 / (b * dt**2 * (1 + alpha)))
    assert same(der.D, g / (b * dt))
    assert same(der.update_x["x1"], (xe + alpha * x0) / (1 + alpha))
    assert same(der.update_a["a1"], ae)


def test_hht_alpha_zero_is_average_acceleration():
    der = I.derive_scheme("hht")
    avg = I.derive_scheme("average_acceleration")
    for name in "ABDE":
        assert same(getattr(der, name).subs(alpha, 0), getattr(avg, name)), name
    for name in ("Dx", "Ex", "Dv", "Ev"):
        assert same(getattr(der, name).subs(alpha, 0), getattr(avg, name)), name
    assert der.w0.subs(alpha, 0) == 0 and der.w1.subs(alpha, 0) == 1


# ------------------------------------------------------------------ generalized-alpha
def test_generalized_alpha():
    der = I.derive_scheme("generalized_alpha")
    am = (2 * rho - 1) / (rho + 1)
    af = rho / (rho + 1)
    g = R(1, 2) - am + af
    b = (1 - am + af) ** 2 / 4
    assert same(der.w1, 1 / (1 + rho))
    assert same(der.w0, rho / (1 + rho))
    check_abde(der, alpha_hand(af, am, b, g))
    assert same(der.A, (1 - am) / ((1 - af) * b * dt**2))
    assert same(der.D, g / (b * dt))


def test_generalized_alpha_rho_one_is_average_acceleration():
    der = I.derive_scheme("generalized_alpha")
    avg = I.derive_scheme("average_acceleration")
    A, D = der.A.subs(rho, 1), der.D.subs(rho, 1)
    assert same(A, avg.A) and same(D, avg.D)
    assert same(A, 4 / dt**2) and same(D, 2 / dt)
    assert same(der.w0.subs(rho, 1), R(1, 2)) and same(der.w1.subs(rho, 1), R(1, 2))
    # equilibrium point at the midpoint: xe = (x0 + x1)/2, ve = (v0 + v1)/2, ae = (a0 + a1)/2,
    # and x1, v1, a1 obey average-acceleration Newmark
    up = {k: v.subs(rho, 1) for k, v in der.update_x.items()}
    B, E = der.B.subs(rho, 1), der.E.subs(rho, 1)
    assert same((x0 + up["x1"]) / 2, xe)
    assert same((v0 + up["v1"]) / 2, D * xe + E)
    assert same((a0 + up["a1"]) / 2, A * xe + B)
    assert same(up["x1"], x0 + dt * v0 + dt**2 / 4 * (a0 + up["a1"]))
    assert same(up["v1"], v0 + dt / 2 * (a0 + up["a1"]))


# ------------------------------------------------------------------ every scheme: consistency
@pytest.mark.parametrize("name", [n for n in I.SCHEMES if n != "central_difference"])
def test_forms_are_inverse(name):
    """Acceleration form = displacement form solved for xe: Dx = 1/A, Ex = -B/A, Dv = D/A,
    Ev = E - D B/A (implicit schemes)."""
    der = I.derive_scheme(name)
    assert not der.explicit
    assert same(der.Dx, 1 / der.A)
    assert same(der.Ex, -der.B / der.A)
    assert same(der.Dv, der.D / der.A)
    assert same(der.Ev, der.E - der.D * der.B / der.A)


# ------------------------------------------------------------------ DT-TMM, reference section 3
k, c, m = dttmm.k, dttmm.c, dttmm.m
A_, B_n, D_, E_n, E_p, x_p, f_ = sp.symbols("A B_n D E_n E_p x_p f")


def displacement_station(kg=0, cg=0):
    """The station matrix with the displacement-form maps p = 1, q = 0, r = D, s = E, alpha = A
    (a plain chain unless the mass has a ground spring kg and damper cg)."""
    T = dttmm.station_step()
    return T.subs({dttmm.kappa: dttmm.KAPPA, dttmm.Delta: dttmm.DELTA, dttmm.mu: dttmm.MU,
                   dttmm.beta: dttmm.BETA}).subs({dttmm.kg: kg, dttmm.cg: cg}).subs(
        {dttmm.p: 1, dttmm.r: D_, dttmm.alpha: A_, dttmm.q_n: 0, dttmm.q_p: 0,
         dttmm.s_n: E_n, dttmm.s_p: E_p, dttmm.b_n: B_n})


def test_dttmm_spring_damper_row():
    T = displacement_station()
    z = sp.Matrix([x_p, f_, 1])
    x_n = (T * z)[0]
    # reference sec. 3 with D_{n-1} = D_n = D (same integrator at every mass)
    hand = ((k + c * D_) * x_p + f_ + c * (E_p - E_n)) / (k + c * D_)
    assert same(x_n, hand)
    # station 1: the ground has D_0 = E_0 = 0 and x_0 = 0
    x_1 = x_n.subs({x_p: 0, E_p: 0})
    D0 = 0
    hand1 = ((k + c * D0) * 0 + f_ + c * (0 - E_n)) / (k + c * D_)
    assert same(x_1, hand1)


def test_dttmm_mass_and_force_rows():
    T = displacement_station()
    z = sp.Matrix([x_p, f_, 1])
    out = T * z
    x_n = out[0]
    # mass row f_R = f_L + m (A x_n + B_n), then the force: f <- f - F_n
    assert same(out[1], f_ + m * (A_ * x_n + B_n) - dttmm.F_n)
    assert out[2] == 1
    assert dttmm.mass_step() == sp.Matrix([[1, 0, 0], [dttmm.mu, 1, dttmm.beta], [0, 0, 1]])
    plain = {dttmm.kg: 0, dttmm.cg: 0}
    assert same(dttmm.MU.subs(plain), m * dttmm.alpha)
    assert same(dttmm.BETA.subs(plain), m * dttmm.b_n)


def test_dttmm_mass_row_with_ground_spring_damper():
    """f_R = f_L + m a + kg x + cg v, with a = A x + B, v = D x + E (x the displacement)."""
    kg, cg = sp.symbols("kg_t cg_t", nonnegative=True)
    T = displacement_station(kg, cg)
    out = T * sp.Matrix([x_p, f_, 1])
    x_n = out[0]
    hand = f_ + m * (A_ * x_n + B_n) + kg * x_n + cg * (D_ * x_n + E_n) - dttmm.F_n
    assert same(out[1], hand)
    assert dttmm.force_step() == sp.Matrix([[1, 0, 0], [0, 1, -dttmm.F_n], [0, 0, 1]])


def test_dttmm_acceleration_form_divisor():
    """Acceleration form: the spring row divides by k Dx + c Dv, the mass row adds m a."""
    der = I.derive_scheme("newmark")
    maps = dttmm.form_maps("acceleration", der)
    kappa = dttmm.KAPPA.subs({dttmm.p: maps["p"], dttmm.r: maps["r"]})
    assert same(kappa, k * beta * dt**2 + c * gamma * dt)
    assert maps["alpha_u"] == 1 and maps["b"] == 0
    cd = I.derive_scheme("central_difference")
    maps = dttmm.form_maps("acceleration", cd)
    assert same(dttmm.KAPPA.subs({dttmm.p: maps["p"], dttmm.r: maps["r"]}), c * dt / 2)


def test_dttmm_riccati_relations_by_hand():
    """Eliminate f_L from f_R = S_R u_R + R_R and [u_R, f_R] = T [u_L, f_L]."""
    sw = dttmm.derive_sweeps()
    T = sw.T
    uL, fL = sp.symbols("uL fL")
    uR = T[0, 0] * uL + T[0, 1] * fL + T[0, 2]
    fR = T[1, 0] * uL + T[1, 1] * fL + T[1, 2]
    sol = sp.solve(sp.Eq(fR, dttmm.S_R * uR + dttmm.R_R), fL, dict=True)
    assert len(sol) == 1
    f_rel = sp.expand(sol[0][fL])
    S_hand = f_rel.coeff(uL)
    assert same(sw.S_expr, S_hand)
    R_hand = sp.simplify(f_rel - S_hand * uL)
    assert same(sw.g * dttmm.R_R + sw.h, R_hand)
    assert same(sw.g, sp.diff(R_hand, dttmm.R_R))
    # forward: u_n = T11 u + T12 (S_L u + R_L) + T13, with S_L, R_L the relation just derived
    # (the module may write the forward step in S_L, R_L or in S_R, R_R: compare in S_R, R_R)
    left = {dttmm.S_L: S_hand, dttmm.R_L: R_hand}
    fwd = T[0, 0] * dttmm.u_p + T[0, 1] * (dttmm.S_L * dttmm.u_p + dttmm.R_L) + T[0, 2]
    assert same((sw.a_fwd * dttmm.u_p + sw.b_fwd).subs(left), fwd.subs(left))
    # closed forms (the generated sweep's docstring)
    kap, am = dttmm.kappa, dttmm.mu
    assert same(sw.S_expr, kap * (dttmm.S_R - am) / (-dttmm.S_R + am + kap))
    assert same(sw.g, kap / (-dttmm.S_R + am + kap))
    assert same(sw.a_fwd.subs(left), kap / (-dttmm.S_R + am + kap))


def test_dttmm_riccati_bounded_symbolically():
    """S_R = -sigma <= 0, kappa > 0, mu = m alpha + kg p + cg r > 0  =>  S_L < 0, 0 < g < 1,
    0 < a_fwd < 1."""
    sw = dttmm.derive_sweeps()
    sigma = sp.Symbol("sigma", nonnegative=True)
    kap = sp.Symbol("kappa_pos", positive=True)
    mu = sp.Symbol("mu_pos", positive=True)
    sub = {dttmm.S_R: -sigma, dttmm.kappa: kap, dttmm.mu: mu}
    S_L = sp.factor(sw.S_expr.subs(sub))
    g = sp.factor(sw.g.subs(sub))
    assert S_L.is_negative is True
    assert g.is_positive is True
    assert sp.factor(1 - g).is_positive is True
    a_fwd = sp.factor(sw.a_fwd.subs(dttmm.S_L, S_L).subs(sub))
    assert a_fwd.is_positive is True
    assert sp.factor(1 - a_fwd).is_positive is True


@pytest.mark.parametrize("name", ["average_acceleration", "newmark_1_8", "wilson", "houbolt",
                                  "park", "hht", "generalized_alpha", "central_difference"])
def test_dttmm_riccati_bounded_at_random_points(name):
    """Carry S from the free end over random positive chains with the scheme's own p, r, alpha."""
    sw = dttmm.derive_sweeps()
    der = I.derive_scheme(name)
    rng = random.Random(sum(map(ord, name)))
    S_f = sp.lambdify((dttmm.S_R, dttmm.kappa, dttmm.mu), sw.S_expr)
    g_f = sp.lambdify((dttmm.S_R, dttmm.kappa, dttmm.mu), sw.g)
    defaults = {I.beta: 0.3, I.gamma: 0.6, I.theta: 1.4, I.alpha: -0.1, I.rho_inf: 0.7}
    for form in dttmm.FORMS:
        if form == "displacement" and der.explicit:
            continue
        maps = dttmm.form_maps(form, der)
        for _ in range(20):
            h = 10 ** rng.uniform(-5, -1)
            pv, rv, av = (float(maps[n].subs(defaults).subs(I.dt, h))
                          for n in ("p", "r", "alpha_u"))
            assert pv >= 0 and rv > 0 and av > 0
            S_R = 0.0
            for _n in range(30):
                mk = 10 ** rng.uniform(-2, 2)
                kk = 10 ** rng.uniform(0, 6)
                cc = 10 ** rng.uniform(-3, 2)
                kgr = rng.choice([0.0, 10 ** rng.uniform(0, 6)])  # a ground spring-damper
                cgr = rng.choice([0.0, 10 ** rng.uniform(-3, 2)])  # at some masses
                kap = kk * pv + cc * rv
                mu = mk * av + kgr * pv + cgr * rv
                g = g_f(S_R, kap, mu)
                S_R = S_f(S_R, kap, mu)
                assert S_R <= 0.0
                assert 0.0 <= g <= 1.0
