"""The per-step nonlinear problem of each discretization.

With localized forces L^T g(y, y', z), y = L q, every linear step of dtdyn takes the element
forces as inputs next to f. In the shifted form (the state x_k known before step k is solved)

    w_k = Cw x_k + Dwf f_k + Dwg g_k,   x_{k+1} = A x_k + Bf f_k + Bg g_k,

so each step is the small system  w_k - Dwg g(w_k, z_k) = Q_k,  Q_k = Cw x_k + Dwf f_k, in the
element deformations only: the source's x_nl(n) + B0 g(x_nl(n)) = Q(n) with B0 = -Dwg. This
module derives B0 for the two families from their definitions:

- modal ramp filters: from eta_n = e^{sT} eta_{n-1} + c0 p_{n-1} + c1 p_n (the ramp invariant of
  dtdyn.derive.modal_filters, unit residue) with p_n = psi^T (f_n - L^T g_n) and y = L phi eta
  + conj: B0 = sum_r 2 Re(c1(s_r) (L phi_r)(L psi_r)^T);
- one-step schemes on M, C, K (acceleration form of dtdyn.derive.kernels): from
  (M + r C + p K) a_{n+1} = w0 (f_n - L^T g_n) + w1 (f_{n+1} - L^T g_{n+1}) - (history) and
  x_{n+1} = p a_{n+1} + (history): B0 = p w1 L (M + r C + p K)^-1 L^T. HHT and
  generalized-alpha thus average the element forces like the external ones.

Internal states (elements with memory) follow the trapezoidal rule
z_k = z_{k-1} + h/2 (z'(w_k, z_k) + z'(w_{k-1}, z_{k-1})), solved together with w_k.
"""
from __future__ import annotations

from functools import lru_cache

import sympy as sp

from . import kernels, modal_filters

# scalar stand-ins: one mode or one DOF, one element
eta_prev, p_prev, f_n, g_n = sp.symbols(r"\eta_{n-1} p_{n-1} f_n g_n")
phi_L, psi_f, psi_L = sp.symbols("phi_L psi_f psi_L")  # L phi, psi at f's DOF, L psi
s, T = modal_filters.s, modal_filters.T


@lru_cache(maxsize=None)
def modal_step() -> dict:
    """One complex modal term: y_n = (L phi) eta_n with the ramp-invariant recursion.

    Returns B0 (the coefficient of g_n moved to the left) and Q (what remains), in s, T.
    """
    inv = modal_filters.derive_invariant("ramp")
    c0, c1 = (sp.simplify(c.subs(modal_filters.R, 1)) for c in (inv.c0, inv.c1))
    p_n = psi_f * f_n - psi_L * g_n
    eta_n = sp.exp(s * T) * eta_prev + c0 * p_prev + c1 * p_n
    y_n = sp.expand(phi_L * eta_n)
    B0 = -sp.diff(y_n, g_n)
    Q = sp.simplify(y_n + B0 * g_n)
    assert sp.diff(Q, g_n) == 0
    return {"c0": c0, "c1": c1, "B0": sp.factor(B0), "Q": Q}


@lru_cache(maxsize=None)
def scheme_coefficient(name: str) -> sp.Expr:
    """p w1 of a one-step scheme: B0 = p w1 L (M + r C + p K)^-1 L^T."""
    spec = kernels.scheme_spec(name)
    rows = dict(kernels.constant_table(spec, "acceleration"))
    return sp.simplify(rows["p"] * rows["w1"])


def scheme_effective(name: str) -> tuple[sp.Expr, sp.Expr]:
    """(r, p) of K_eff = M + r C + p K."""
    spec = kernels.scheme_spec(name)
    rows = dict(kernels.constant_table(spec, "acceleration"))
    return sp.simplify(rows["r"]), sp.simplify(rows["p"])


# --- parabolic treatment of the element forces (method "modal_parabolic") ----------------------
#
# Between t_k and t_{k+1} the ramp invariant takes g linear. The parabola through g_{k-1}, g_k,
# g_{k+1} adds  (g_{k+1} - 2 g_k + g_{k-1}) u (u - T) / (2 T^2),  u = t - t_k, whose response is
# N2 (g_{k+1} - 2 g_k + g_{k-1}) with N2 = integral_0^T e^{s(T-u)} u (u - T) / (2 T^2) du:
# third order in T instead of second, same per-step problem.

zz = modal_filters.z
uu = modal_filters.u


@lru_cache(maxsize=None)
def parabola_coefficient() -> dict:
    """N2(s, T) in closed form, as T * (2 phi3(z) - phi2(z)) / 2 with z = sT, and its series."""
    closed = sp.simplify(sp.integrate(sp.exp(s * (T - uu)) * uu * (uu - T) / (2 * T**2),
                                      (uu, 0, T), conds="none"))
    phi2 = modal_filters.phi2(zz)
    phi3 = (sp.exp(zz) - 1 - zz - zz**2 / 2) / zz**3
    phi_form = T * (2 * phi3 - phi2) / 2
    assert sp.simplify(closed - phi_form.subs(zz, s * T)) == 0
    kernel = (2 * phi3 - phi2) / 2
    ser = sp.series(kernel, zz, 0, 18).removeO()
    series = [sp.Rational(ser.coeff(zz, k)) for k in range(18)]
    return {"closed": closed, "kernel": kernel, "series": series}
