"""Discrete-time transfer matrix method: step transfer matrices and the two sweeps.

At each step an integrator makes every mass's displacement, velocity and
acceleration at the equilibrium point affine in one primary unknown u (u = xe - x_n, the
increment, in displacement form; u = ae in acceleration form):

    x = p u + q,   v = r u + s,   a = alpha u + b

with p, r, alpha the same at every mass (integrator and dt only) and q, s, b from each mass's
history. Acceleration form: p = Dx, q = Ex, r = Dv, s = Ev, alpha = 1, b = 0.
Displacement form, in increments: u = xe - x_n, so p = 1, q = x_n, r = D, s = D x_n + E,
alpha = A, b = A x_n + B. It is the source's displacement form (ae = A xe + B, ve = D xe + E,
the same station matrices up to their load column) with the unknown shifted by x_n. Written
in xe itself, B holds A x_n, a term of size |x| / dt^2 that cancels against the rest of B: its
rounding, eps |x| / dt^2, acts as a force and costs eps / (omega dt)^2 of relative accuracy (up
to 5.7e-10 on P3 for dt down to 1e-5, benchmarks/dttmm_vs_mck.py at commit 99ff3e0). In u the
terms are of size |v| / dt, and the cost is eps / (omega dt).
For the multistep schemes, b and s keep the lags of x in combinations whose coefficients sum
to zero; dtdyn.derive.kernels writes those in increments (x_n - x_{n-1}, ...).

State z = [u, f, 1]^T. Substituting into the element laws gives, for station n (spring-damper
from node n-1, mass m_n with a spring k_g and a damper c_g to the ground, force F_n):

    spring-damper: f = k (x_n - x_{n-1}) + c (v_n - v_{n-1})
                   => u_n = u_{n-1} + (f - Delta_n) / kappa,   kappa = k p + c r,
                      Delta_n = k (q_n - q_{n-1}) + c (s_n - s_{n-1})
    mass:          f_R = f_L + m a_n + k_g x_n + c_g v_n = f_L + mu u_n + beta_n,
                      mu = m alpha + k_g p + c_g r,   beta_n = m b_n + k_g q_n + c_g s_n
    force:         f_R = f_L - F_n

mu, like kappa, is the same at every step (once per run); beta_n, like Delta_n, is computed from
the history each step. With k_g = c_g = 0 (the plain chain) mu = m alpha and beta_n = m b_n.

Ground: u_0 = q_0 = s_0 = 0.

Plain sweep (the source's): z_n = T_n z_{n-1} from z_0 = [0, f_1, 1] with the unknown base force
f_1 fixed by f_{N+1} = 0. Its entries grow like (m alpha / kappa)^N, so the far-end displacement is
a difference of huge numbers (measured in tests/test_dttmm.py).

Stable sweep (Riccati transfer matrix, Horner & Pilkey 1978; He, Wang & Rui 2007): carry
f_n = S_n u_{n-1} + R_n from the free end (S_{N+1} = R_{N+1} = 0) back to the base, then
u_n = T11 u_{n-1} + T12 f_n + T13 forward. Given the station matrix T and the relation on its
right, f_R = S_R u_R + R_R, the relation on its left is

    S_L = (S_R T11 - T21) / (T22 - S_R T12),   R_L = (S_R T13 + R_R - T23) / (T22 - S_R T12).

S depends on the integrator, dt and the chain only, so it is computed once; each step only
carries R back and u forward: an O(N) elimination whose factors are bounded (S_n <= 0). The
forward step is u_n = [kappa u_{n-1} + R_R + F - beta - Delta] / (kappa + mu - S_R): its
divisor is at least mu >= m alpha, so it keeps the accuracy of the mass equation at any dt.

Error estimate of the plain sweep. Let P_u,n be the u-entry of T_n ... T_1 [0, 1, 0]^T (the
response of the step's equations to a unit base force) and P_f,N the f-entry of the whole
product, both computed once per run. The plain sweep's solve is f_1 = -Q_f / P_f,N (Q: the
product applied to [0, 0, 1]); a rounding error delta_j of f_1 changes u by delta_j P_u, so at
step j

    u_plain = u*(H_j) + delta_j P_u,        delta_j = -eps_P f_1,j + r_j,

u*(H) being the exact solution of the step's system for the history H it was given. Measured
on eleven scheme / form / chain cases (uniform chains of 3 and 4 masses, the stiff chain of
tests/test_hard_cases.py): the error vector is parallel to P_u (average acceleration on the
stiff chain: to 1e-6 after the first steps); the mean of delta_j / (eps f_1,j) is -eps_P / eps
within 0.03, eps_P being the relative rounding error of the computed P_f,N (one number per run,
here -2.1 eps .. 2.1 eps), except for Wilson's displacement form on the stiff chain (-0.78
against -2.1); the rest, r_j, is uncorrelated from step to step (lag-1 correlation at most 0.05
in six cases), standard deviation 0.4 .. 1.3 eps |f_1,j|.
That is the one-step error. It enters the history, x += x1_u e, v += v1_u e, a += a1_u e
(displacement form: e, D e, A e), and every later step carries it on: the step is linear and
time-invariant in H, H_{n+1} = Phi H_n + (force terms), so the error after step n is

    E_n = sum_{j <= n} delta_j Phi^(n-j) U P_u,        U = [x1_u, v1_u, a1_u, 0 ...]^T.

Phi^k U P_u grows: a displacement error e comes with a velocity error D e = gamma e / (beta dt),
which the slow modes integrate to ~ e D / omega (176x after 500 steps on the stiff chain of
tests/test_hard_cases.py). The estimate evaluates the sum as it goes, for the two parts apart:
two error histories, E_s (systematic part) and E_r (random part), rows as H and zero at t_0, are
advanced each step by the exact step with zero force (the Riccati recurrences with F = 0:
Sweeps.error_step) plus their one-step errors,

    u_s = u*(E_s; F = 0) - eps_P f_1,j P_u,
    u_r = u*(E_r; F = 0) + RANDOM_SPREAD s_j eps f_1,j P_u,     E_. <- update(E_., u_.),

s_j = +-1 a pseudo-random sign of the step index (splitmix64): one sample of the random walk, of
the size of the real one (a sum of uncorrelated errors is not bounded by a multiple of a single
step's error, and the same sign at every step would over-estimate it by ~sqrt(steps)).
RANDOM_SPREAD = 1.5 covers the measured spread 0.4 .. 1.3. eps_P comes from the product computed
once more in double-double arithmetic. With e_n = max_i |E_s,x,n,i| + max_i |E_r,x,n,i| and
e = max_n e_n, x_max = max_n max_i |x_n,i|, the relative error estimate (the measure of the
tests' rel_error) is

    e / (x_max - e)    (infinite when e >= x_max: the computed x may be all rounding error),

since max |x_true| >= x_max - e. Measured against the stable sweep, every scheme and both forms,
500 steps of a step force on uniform chains of 3, 4, 5 masses (k = 1e4, dt 1e-4 .. 3e-3) and on
the stiff chain (dt 1e-3 .. 1e-2), errors 1e-12 .. 1e-2 (290 runs): estimate / error 0.80 .. 9.7,
median 1.3; 3,000 to 20,000 steps, step and random forces (80 runs): 0.81 .. 2.2. The same sign
at every step (delta_j = eps f_1,j) gave 0.47 .. 81. Cost: two zero-force Riccati steps per step,
O(N), run inside the sweep's own station loops.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from . import integrators as I

k, c, m = sp.symbols("k c m", positive=True)
kg, cg = sp.symbols("k_g c_g", nonnegative=True)  # spring and damper from the mass to the ground
p, r = sp.symbols("p r")
alpha = sp.Symbol("alpha_u")  # the alpha of the module docstring (HHT owns the name alpha)
q_n, q_p, s_n, s_p, b_n, F_n = sp.symbols("q_n q_p s_n s_p b_n F_n")
kappa, Delta = sp.symbols("kappa Delta")
mu, beta = sp.symbols("mu beta_n")  # the grounded mass's u coefficient and history term
S_R, R_R, S_L, R_L = sp.symbols("S_R R_R S_L R_L")
u_p, f_n = sp.symbols("u_p f_n")


def spring_damper_step():
    """Field matrix of the spring-damper in u: u_n = u_{n-1} + (f - Delta)/kappa."""
    return sp.Matrix([[1, 1 / kappa, -Delta / kappa], [0, 1, 0], [0, 0, 1]])


def mass_step():
    """Point matrix of the mass and its ground spring-damper: f_R = f_L + mu u + beta."""
    return sp.Matrix([[1, 0, 0], [mu, 1, beta], [0, 0, 1]])


def force_step():
    """Point matrix of the external force: f_R = f_L - F."""
    return sp.Matrix([[1, 0, 0], [0, 1, -F_n], [0, 0, 1]])


def station_step():
    """T_n = force * mass * spring-damper, mapping [u_{n-1}, f_n, 1] to [u_n, f_{n+1}, 1]."""
    return force_step() * mass_step() * spring_damper_step()


#: kappa and Delta in the station's own symbols.
KAPPA = k * p + c * r
DELTA = k * (q_n - q_p) + c * (s_n - s_p)
#: mu and beta in the station's own symbols: m a + k_g x + c_g v = mu u + beta.
MU = m * alpha + kg * p + cg * r
BETA = m * b_n + kg * q_n + cg * s_n


@dataclass(frozen=True)
class Sweeps:
    """Scalar recurrences of both sweeps, in the symbols of this module.

    Stable (Riccati), per station n from N down to 1 (time-invariant part computed once):
        S_L = S_expr(S_R);  den = T22 - S_R T12;  R_L = g R_R + h
    then forward, n = 1..N:  u_n = a_fwd u_{n-1} + b_fwd   with b_fwd in R_R (= R_L of n + 1).
    The kernels evaluate them as (identities checked in derive_sweeps; a_fwd = g)
        R_L = g R_R + h,  h = ((mu - S_R) Delta + kappa (F - beta)) / den,  g = kappa / den,
        u_n = g u_{n-1} + (R_R + ((F - beta) - Delta)) / den
    with mu - S_R (= hD den) and 1 / den per station once per run: per station and step,
    F - beta, Delta and kappa are formed once, every division is a product with 1 / den, and
    the back pass, which also scales R_R + ((F - beta) - Delta) by 1 / den, reads no g row
    (the sweep at N = 1e5 is bound by memory traffic). h is not Delta + g ((F - beta) - Delta),
    equal but cancelling where g is close to 1 (stiff stations, large dt).
    Plain: z_n = T z_{n-1}: u_n = T11 u + T12 f + T13, f_{n+1} = T21 u + T22 f + T23; its error
    estimate runs the stable recurrences with F = 0 (error_step) on the error history.
    """

    T: sp.Matrix
    S_expr: sp.Expr
    g: sp.Expr
    h: sp.Expr
    a_fwd: sp.Expr
    b_fwd: sp.Expr
    den: sp.Expr  # time-invariant divisor of h and b_fwd: kernels store it per station (a
    # division, not a product with 1/den, whose rounding bias accumulates in the displacement form)
    h_num: sp.Expr  # h = h_num / den
    b_num: sp.Expr  # b_fwd = b_num / den
    hD: sp.Expr  # h = hD Delta + g (F - beta)
    # the step that carries the plain sweep's error (F = 0), linear in Delta, beta and R_R with
    # per-station coefficients computed once: R_L = g R_R + hD Delta + hb beta,
    # u_n = a_fwd u_{n-1} + fR R_R + fD Delta + fb beta
    error_step: dict


def derive_sweeps() -> Sweeps:
    T = station_step()
    den = T[1, 1] - S_R * T[0, 1]
    S_expr = sp.simplify((S_R * T[0, 0] - T[1, 0]) / den)
    R_expr = (S_R * T[0, 2] + R_R - T[1, 2]) / den
    g = sp.simplify(sp.diff(R_expr, R_R))
    h = sp.simplify(R_expr - g * R_R)
    # forward: f_n = S_L u_{n-1} + R_L, u_n = T11 u_{n-1} + T12 f_n + T13. Written with R_L and
    # S_L eliminated in favour of R_R, S_R, so that nothing is divided by kappa: kappa -> 0 as
    # dt -> 0 in the acceleration form, and (R_L - Delta)/kappa would cancel catastrophically.
    u_next = T[0, 0] * u_p + T[0, 1] * ((S_expr * u_p) + g * R_R + h) + T[0, 2]
    a_fwd = sp.factor(sp.cancel(sp.diff(u_next, u_p)))
    b_fwd = sp.factor(sp.cancel(u_next - a_fwd * u_p))
    den_s = sp.denom(sp.together(h))
    if sp.expand(den_s).coeff(S_R) > 0:  # written as kappa + mu - S_R, positive (S_R <= 0)
        den_s = sp.expand(-den_s)
    h_num, b_num = (sp.simplify(sp.together(e) * den_s) for e in (h, b_fwd))
    assert sp.simplify(h_num / den_s - h) == 0 and sp.simplify(b_num / den_s - b_fwd) == 0
    h0, b0 = (e.subs(F_n, 0) / den_s for e in (h_num, b_num))
    error_step = {"hD": sp.diff(h0, Delta), "hb": sp.diff(h0, beta),
                  "fR": sp.diff(b0, R_R), "fD": sp.diff(b0, Delta), "fb": sp.diff(b0, beta)}
    error_step = {n: sp.factor(sp.cancel(e)) for n, e in error_step.items()}
    es = error_step
    assert sp.simplify(h0 - es["hD"] * Delta - es["hb"] * beta) == 0
    assert sp.simplify(b0 - es["fR"] * R_R - es["fD"] * Delta - es["fb"] * beta) == 0
    hD = es["hD"]  # the error step's coefficient of Delta is the stable step's (F enters apart)
    assert sp.simplify(a_fwd - g) == 0
    assert sp.simplify(h - (hD * Delta + g * (F_n - beta))) == 0
    assert sp.simplify(den_s - (kappa + mu - S_R)) == 0 and sp.simplify(g * den_s - kappa) == 0
    assert sp.simplify(h * den_s - ((mu - S_R) * Delta + kappa * (F_n - beta))) == 0
    assert sp.simplify(b_fwd - (R_R + (F_n - beta) - Delta) / den_s) == 0
    return Sweeps(T, S_expr, g, h, a_fwd, b_fwd, den_s, h_num, b_num, hD, error_step)


#: weight of the random part of the plain sweep's rounding error (module docstring)
RANDOM_SPREAD = 1.5

FORMS = ("displacement", "acceleration")


def form_maps(form: str, der) -> dict:
    """p, r, alpha (constants) and q, s, b (history) of a form, from a derived integrator."""
    if form == "displacement":  # in increments, u = xe - x_n (module docstring)
        return {"p": sp.Integer(1), "r": der.D, "alpha_u": der.A,
                "q": I.x0, "s": sp.expand(der.D * I.x0 + der.E),
                "b": sp.expand(der.A * I.x0 + der.B)}
    if form == "acceleration":
        return {"p": der.Dx, "r": der.Dv, "alpha_u": sp.Integer(1),
                "q": der.Ex, "s": der.Ev, "b": sp.Integer(0)}
    raise ValueError(f"form must be one of {FORMS}, got {form!r}")
