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

from dataclasses import dataclass
from functools import cache

import sympy as sp

from . import kernels, modal_filters

# scalar stand-ins: one mode or one DOF, one element
eta_prev, p_prev, f_n, g_n = sp.symbols(r"\eta_{n-1} p_{n-1} f_n g_n")
phi_L, psi_f, psi_L = sp.symbols("phi_L psi_f psi_L")  # L phi, psi at f's DOF, L psi
s, T = modal_filters.s, modal_filters.T


@cache
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


@cache
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


@cache
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


# --- polynomial treatment of the element forces of higher degree ("modal_quintic",
# "modal_explicit") ------------------------------------------------------------------------------
#
# Over the step [t_k, t_k + h] the element forces are the polynomial of degree m through m + 1
# samples g_{k+j}: implicit (modal_quintic), j = 1-m .. 1, g_{k+1} the step's own unknown as in the
# ramp and the parabola; explicit (modal_explicit), j = -m .. 0, the polynomial through known
# samples extrapolated over the step (the step's own forces follow from the step's response, one
# evaluation of the element laws, no Newton solve):
#
#     g(t_k + v h) = sum_j l_j(v) g_{k+j},   l_j the Lagrange basis on the nodes j, v = u/h.
#
# One modal term (unit residue) then receives W_j(s, h) g_{k+j} with
#
#     W_j = integral_0^h e^{s(h-u)} l_j(u/h) du = h sum_i c_ji i! phi_{i+1}(z),   z = s h,
#
# l_j(v) = sum_i c_ji v^i and phi_n(z) = (e^z - sum_{l<n} z^l / l!) / z^n = sum_k z^k / (k+n)!.
# Implicit m = 1 is the ramp invariant, m = 2 the parabola above. The error of degree m is led by
# the next Newton term (the node that the polynomial lacks: 1 - (m + 1) implicit, 1 explicit),
# nabla^{m+1} g_{k+1} prod_j (v - j) / (m+1)!: its response E(s, h) nabla^{m+1} g_{k+1} is the
# step's local error, carried along by the linear dynamics (the embedded estimate).

#: the degree of "modal_quintic": the implicit polynomial through six samples, order m + 1 = 6
QUINTIC_DEGREE = 5
#: the degree of "modal_explicit": the polynomial through g_{k-6} .. g_k, order m + 1 = 7 (its
#: stability limit mu = 0.228, `polynomial_stability`: explicit degrees 4 and 5 grow slowly from
#: small mu on, as the parabola does, and 7 halves the limit)
EXPLICIT_DEGREE = 6


@dataclass(frozen=True)
class ModalMethod:
    """A nonlinear modal method: the ramp-invariant modal filters (one complex first-order
    recursion per kept mode, exact for a force linear between samples) with the element forces
    g taken over each step as the polynomial of ``degree`` through their samples, g_{k+1-m} ..
    g_{k+1} (implicit: each step solves for its own forces) or g_{k-m} .. g_k (``explicit``:
    extrapolated, Dwg = 0, one evaluation of the element laws a step, no Newton solve).

    Its order in h is ``degree`` + 1. ``polynomial``: its weights W_j are generated tables
    (generated/nl_modal.py POLYNOMIALS) and its runs carry the embedded estimate (the next
    Newton term). ``theta_held``: the theta = |B0 dg/dy| its loops hold it to instead of the
    derived stability limit (`polynomial_stability`), for a method that grows from theta = 0 on.
    """

    name: str
    title: str
    degree: int
    explicit: bool = False
    polynomial: bool = False
    theta_held: float | None = None
    reference: str = ""
    notes: str = ""

    @property
    def order(self) -> int:
        """The order in h: the force polynomial's degree + 1 (the linear part is exact)."""
        return self.degree + 1


MODAL_REF = ("Ahlin, Magnevall & Josefsson (2006), Simulation of forced response in "
             "linear and nonlinear mechanical systems using digital filters, ISMA")

#: The nonlinear modal methods, the second family of `nonlinear_mck_response`'s schemes beside
#: the time integrators of `dtdyn.derive.integrators.SCHEMES` (which run there as their
#: effective nonlinear system). generated/scheme_table.py carries them as METHODS.
MODAL_METHODS: dict[str, ModalMethod] = {m.name: m for m in (
    ModalMethod("modal_ramp", "Modal filters, ramp invariant", 1, reference=MODAL_REF,
                notes="The element force treated as linear over the step, like the linear-"
                      "acceleration method: stable up to B0 k_t = 2 (Omega_t = sqrt 12)."),
    ModalMethod("modal_parabolic", "Modal filters, parabolic element forces", 2,
                theta_held=0.01, reference=MODAL_REF + "; the parabola: dtdyn's addition",
                notes="The parabola through g_{k-1}, g_k, g_{k+1}; grows like Adams-Moulton 3 on "
                      "the imaginary axis (rho - 1 ~ 1e-3 a step at theta = 0.03 without "
                      "damping), so it is held to theta <= 0.01."),
    ModalMethod("modal_quintic", "Modal filters, quintic element forces", QUINTIC_DEGREE,
                polynomial=True, reference=MODAL_REF + "; the polynomial: dtdyn's addition",
                notes="The polynomial through g_{k-4} .. g_{k+1}, with an embedded error "
                      "estimate; every root of the free mass stays in the unit disk up to the "
                      "derived theta limit (Omega_t = 1.61)."),
    ModalMethod("modal_explicit", "Modal filters, explicit element forces", EXPLICIT_DEGREE,
                explicit=True, polynomial=True,
                reference=MODAL_REF + "; the polynomial: dtdyn's addition",
                notes="The polynomial through g_{k-6} .. g_k extrapolated over the step: no "
                      "Newton solve; theta = |(Cw Bg) dg/dy|, the weight of g_k on the next "
                      "step's y (Omega_t = 0.48); the embedded estimate of modal_quintic."),
)}

#: the polynomial methods: degree and explicit
POLYNOMIAL_METHODS = {m.name: (m.degree, m.explicit) for m in MODAL_METHODS.values()
                      if m.polynomial}

#: scheme="auto" of `nonlinear_mck_response` with an accuracy target: the modal methods whose
#: runs estimate themselves, the explicit seventh-order one first (no Newton solve, the
#: cheapest step) and then the implicit sixth-order one (stable for ten times the elements'
#: stiffness); then, when an estimate is not confirmed or a run fails, the ramp invariant's
#: Richardson sequence (robust on kinks and hysteresis); a one-step time integrator when the
#: mass matrix is singular (no modal model); on a backend without embedded estimates, "then".
AUTO = {"first": "modal_explicit", "next": "modal_quintic", "then": "modal_ramp",
        "singular_mass": "average_acceleration"}
vv = sp.Symbol("v")  # u / h
mu = sp.Symbol("mu", positive=True)  # k_t h^2 / m: the element's stiffness seen by one step
lam_ = sp.Symbol("lambda")


def polynomial_nodes(degree: int, explicit: bool = False) -> list:
    """The nodes j of g_{k+j}, oldest first: 1-m .. 1 (implicit), -m .. 0 (explicit)."""
    return list(range(-degree, 1)) if explicit else list(range(1 - degree, 2))


def lagrange(nodes, j):
    """The Lagrange basis polynomial l_j(v) on ``nodes``."""
    return sp.prod([(vv - i) / sp.Integer(j - i) for i in nodes if i != j])


def phi_series(n: int, k: int) -> sp.Rational:
    """Coefficient of z^k in phi_n(z): 1 / (k + n)!."""
    return sp.Rational(1, sp.factorial(k + n))


def _kernel_coefficients(poly, n_terms: int) -> dict:
    """For p(v) = sum_i c_i v^i: h-free weight integral_0^1 e^{z(1-v)} p(v) dv as
    sum_i c_i i! phi_{i+1}(z): its phi coefficients and its Taylor series in z, and its s -> 0
    limits on a free unit mass, a = integral_0^1 (1 - v) p dv (displacement) and
    b = integral_0^1 p dv (velocity)."""
    c = sp.Poly(sp.expand(poly), vv).all_coeffs()[::-1]
    phis = [sp.Rational(ci) * sp.factorial(i) for i, ci in enumerate(c)]  # of phi_{i+1}
    series = [sum(p * phi_series(i + 1, k) for i, p in enumerate(phis)) for k in range(n_terms)]
    a = sp.integrate((1 - vv) * poly, (vv, 0, 1))
    b = sp.integrate(poly, (vv, 0, 1))
    return {"phi": phis, "series": series, "a": a, "b": b}


@cache
def polynomial_weights(degree: int, explicit: bool = False, n_terms: int = 40) -> dict:
    """The weights W_j / h (j over `polynomial_nodes`) and the estimate's E / h (module
    comment), each as phi coefficients and a Taylor series in z; the difference stencil of
    nabla^{degree+1}; the free-mass limits a_j, b_j; and the stability limit
    (`polynomial_stability`)."""
    nodes = polynomial_nodes(degree, explicit)
    weights = {j: _kernel_coefficients(lagrange(nodes, j), n_terms) for j in nodes}
    omega = sp.prod([vv - i for i in nodes]) / sp.factorial(degree + 1)
    estimate = _kernel_coefficients(omega, n_terms)
    # the polynomial reproduces every polynomial of its degree: sum_j l_j(v) j^q = v^q
    for q in range(degree + 1):
        assert sp.expand(sum(lagrange(nodes, j) * sp.Integer(j) ** q for j in nodes)
                         - vv**q) == 0
    # nabla^{m+1} g_{k+1} = sum_i stencil_i g_{k+1-i}
    stencil = [(-1) ** i * sp.binomial(degree + 1, i) for i in range(degree + 2)]
    return {"degree": degree, "explicit": explicit, "nodes": nodes, "weights": weights,
            "estimate": estimate, "stencil": stencil, **polynomial_stability(degree, explicit)}


def characteristic_polynomial(degree: int, explicit: bool = False) -> sp.Expr:
    """Of the free unit mass y'' = -k_t y stepped with the degree-m force polynomial, exact in
    the linear part (the limit s -> 0 of the modal step, where the element's stiffness matters
    most): with V = h y',

        y_{k+1} = y_k + V_k - mu sum_j a_j y_{k+j},   V_{k+1} = V_k - mu sum_j b_j y_{k+j},

    mu = k_t h^2; y_k = lambda^k gives (lambda - 1)^2 + mu ((lambda - 1) A + B) = 0, A and B the
    generating polynomials of a_j and b_j, times lambda^(-j_0), j_0 the oldest node."""
    nodes = polynomial_nodes(degree, explicit)
    lo = nodes[0]
    w = {j: (sp.integrate((1 - vv) * lagrange(nodes, j), (vv, 0, 1)),
             sp.integrate(lagrange(nodes, j), (vv, 0, 1))) for j in nodes}
    A = sum(w[j][0] * lam_ ** (j - lo) for j in nodes)
    B = sum(w[j][1] * lam_ ** (j - lo) for j in nodes)
    return sp.expand((lam_ - 1) ** 2 * lam_ ** (-lo) + mu * ((lam_ - 1) * A + B))


@cache
def polynomial_stability(degree: int, explicit: bool = False) -> dict:
    """The largest mu (and theta = a_n mu, a_n h^2 the weight of the newest sample in y: g_{k+1}
    implicit, whose theta is the |B0 dg/dy| the loops measure; g_k explicit, whose theta is
    |(Cw Bg) dg/dy|, its weight in the next step's y) up to which every root of the
    characteristic polynomial lies in the closed unit disk: the boundary locus
    mu(phi) = -(lambda - 1)^2 lambda^(-j_0) / ((lambda - 1) A + B) at lambda = e^{i phi}, its
    smallest real positive value; found as the smallest mu at which the spectral radius exceeds
    1 + 1e-9 (the round-off of the double root at mu = 0). The ramp (implicit m = 1) gives
    mu = 12, theta = 2; implicit degrees 4 and 5 keep every root inside up to mu = 1.40 and 2.59,
    explicit degree 6 up to 0.228; the parabola (m = 2) grows from the start, by ~ 0.02 mu^2
    per step, so its "limit" is where that reaches 1e-9 (its loops hold it to a chosen theta
    instead, `ModalMethod.theta_held`)."""
    import numpy as np
    from scipy.optimize import brentq

    poly = characteristic_polynomial(degree, explicit)
    nodes = polynomial_nodes(degree, explicit)
    a_new = sp.integrate((1 - vv) * lagrange(nodes, nodes[-1]), (vv, 0, 1))
    coeffs = [sp.Poly(poly, lam_).coeff_monomial(lam_**k) for k in range(sp.degree(poly, lam_),
                                                                          -1, -1)]
    fc = [sp.lambdify(mu, c, "numpy") for c in coeffs]

    def growth(m_val):  # spectral radius - 1
        return np.abs(np.roots([float(c(m_val)) for c in fc])).max() - 1.0
    tiny = 1e-9  # above round-off of the roots (a double root at mu = 0)
    grid = np.geomspace(1e-4, 1e3, 1401)
    bad = [m for m in grid if growth(m) > tiny]
    limit = 0.0
    if bad and bad[0] > grid[0]:
        k = int(np.searchsorted(grid, bad[0]))
        limit = float(brentq(lambda m: growth(m) - tiny, grid[k - 1], grid[k], xtol=1e-14))
    return {"a1": a_new, "mu_limit": limit, "theta_limit": float(a_new) * limit}


def polynomial_context() -> dict:
    """What generated/nl_modal.py and nonlinear.md carry of the polynomial methods
    (`polynomial_weights`), as text: one entry per method of POLYNOMIAL_METHODS."""
    def table(k):
        return {"phi": [repr(float(c)) for c in k["phi"]],
                "series": [repr(float(c)) for c in k["series"]], "a": sp.sstr(k["a"]),
                "b": sp.sstr(k["b"])}
    out = []
    for name, (degree, explicit) in POLYNOMIAL_METHODS.items():
        pw = polynomial_weights(degree, explicit)
        cp = characteristic_polynomial(degree, explicit)
        out.append({
            "method": name, "prefix": name.removeprefix("modal_").upper(), "degree": degree,
            "explicit": explicit, "nodes": pw["nodes"],
            "weights": [(j, table(pw["weights"][j])) for j in pw["nodes"]],
            "estimate": table(pw["estimate"]), "stencil": [int(c) for c in pw["stencil"]],
            "a1": sp.sstr(pw["a1"]), "mu_limit": repr(pw["mu_limit"]),
            "theta_limit": repr(pw["theta_limit"]), "charpoly": sp.sstr(cp),
            "latex": [(j, [sp.latex(c) for c in pw["weights"][j]["phi"]],
                       sp.latex(pw["weights"][j]["a"]), sp.latex(pw["weights"][j]["b"]))
                      for j in pw["nodes"]],
            "estimate_latex": [sp.latex(c) for c in pw["estimate"]["phi"]],
            "charpoly_latex": sp.latex(cp), "a1_latex": sp.latex(pw["a1"])})
    return {"polynomials": out}


def method_table() -> dict:
    """Every nonlinear modal method as plain data (no SymPy): title, degree of the force
    polynomial, order, explicit, polynomial (generated tables and an embedded estimate), the
    theta limit its loops hold it to (derived by `polynomial_stability` unless held lower),
    reference and notes; checks `AUTO` against the methods and the time integrators."""
    from .integrators import SCHEMES
    for key, name in AUTO.items():
        known = SCHEMES if key == "singular_mass" else MODAL_METHODS
        if name not in known:
            raise ValueError(f"nonlinear.AUTO[{key!r}] = {name!r} is not one of {list(known)}")
    out = {}
    for m in MODAL_METHODS.values():
        limit = m.theta_held
        if limit is None:
            limit = polynomial_stability(m.degree, m.explicit)["theta_limit"]
        out[m.name] = {"title": m.title, "degree": m.degree, "order": m.order,
                       "explicit": m.explicit, "polynomial": m.polynomial,
                       "theta_limit": float(limit), "reference": m.reference, "notes": m.notes}
    return out
