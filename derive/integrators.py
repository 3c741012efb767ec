"""Integrators as data: each scheme is its defining relations and parameters.

A scheme relates the new state (x1, v1, a1 at t_{n+1}) to the history (x0, v0, a0 at t_n and, for
multistep schemes, xm1, xm2, vm1, vm2 at t_{n-1}, t_{n-2}) and names the *equilibrium point*
quantities (xe, ve, ae) at which M ae + C ve + K xe = Fe is enforced, with
Fe = w0 F_n + w1 F_{n+1}. For Newmark xe = x1; for HHT/generalized-alpha they are weighted
averages; for Wilson theta they live at t + theta dt.

`derive_scheme` solves the relations (one linear solve in SymPy) for everything in terms of one
primary unknown, and returns

    displacement form:  ae = A xe + B,  ve = D xe + E          (A, D constants; B, E history)
    acceleration form:  xe = Dx ae + Ex, ve = Dv ae + Ev        (the source writes D, E, A, B)
    update:             x1, v1, a1 affine in the primary unknown and the history.

Sources: (Newmark 1959; Wilson, Farhoomand & Bathe 1973; Houbolt 1950;
Park 1975; Hilber, Hughes & Taylor 1977; Chung & Hulbert 1993).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import sympy as sp

dt = sp.Symbol("dt", positive=True)
x1, v1, a1 = sp.symbols("x1 v1 a1")
x0, v0, a0 = sp.symbols("x0 v0 a0")
xm1, xm2, vm1, vm2, am1 = sp.symbols("xm1 xm2 vm1 vm2 am1")
xe, ve, ae = sp.symbols("xe ve ae")
F0, F1 = sp.symbols("F0 F1")
beta, gamma, theta, alpha, rho_inf = sp.symbols("beta gamma theta alpha rho_inf", real=True)
alpha_m, alpha_f = sp.symbols("alpha_m alpha_f", real=True)

HALF = sp.Rational(1, 2)

#: Newmark kinematics with the equilibrium point of the alpha methods (alpha_m = alpha_f = 0:
#: Newmark).
NEWMARK_ALPHA = (
    sp.Eq(x1, x0 + dt * v0 + dt**2 * ((HALF - beta) * a0 + beta * a1)),
    sp.Eq(v1, v0 + dt * ((1 - gamma) * a0 + gamma * a1)),
    sp.Eq(xe, (1 - alpha_f) * x1 + alpha_f * x0),
    sp.Eq(ve, (1 - alpha_f) * v1 + alpha_f * v0),
    sp.Eq(ae, (1 - alpha_m) * a1 + alpha_m * a0),
)
NEWMARK_ALPHA_FORCE = (alpha_f, 1 - alpha_f)  # (w0, w1)

#: Wilson theta: linear acceleration over [t, t + theta dt], equilibrium at t + theta dt, then
#: interpolated back to t + dt (the real method, not the source's stretched time axis).
WILSON = (
    sp.Eq(xe, x0 + theta * dt * v0 + (theta * dt) ** 2 / 6 * (ae + 2 * a0)),
    sp.Eq(ve, v0 + theta * dt / 2 * (a0 + ae)),
    sp.Eq(a1, a0 + (ae - a0) / theta),
    sp.Eq(v1, v0 + dt / 2 * (a0 + a1)),
    sp.Eq(x1, x0 + dt * v0 + dt**2 / 6 * (a1 + 2 * a0)),
)

#: Houbolt: third-order backward differences (the source's printed B has a sign
#: misprint on x_{n-2}, its code is right, and so is this).
HOUBOLT = (
    sp.Eq(v1, (11 * x1 - 18 * x0 + 9 * xm1 - 2 * xm2) / (6 * dt)),
    sp.Eq(a1, (2 * x1 - 5 * x0 + 4 * xm1 - xm2) / dt**2),
    sp.Eq(xe, x1), sp.Eq(ve, v1), sp.Eq(ae, a1),
)

#: Park stiffly stable: the same three-step formula for velocity and acceleration.
PARK = (
    sp.Eq(v1, (10 * x1 - 15 * x0 + 6 * xm1 - xm2) / (6 * dt)),
    sp.Eq(a1, (10 * v1 - 15 * v0 + 6 * vm1 - vm2) / (6 * dt)),
    sp.Eq(xe, x1), sp.Eq(ve, v1), sp.Eq(ae, a1),
)

#: Start-up of the multistep schemes: this many steps of average-acceleration Newmark (second
#: order, like Houbolt and Park, so the global order is kept), which fill x_{n-1}, x_{n-2}, ...
MULTISTEP_STARTUP = 2


#: Admissible parameter values (closed intervals; None: unbounded), the same for every scheme that
#: takes the parameter. The runtime, the scene schema and the docs read them from the generated
#: scheme table.
PARAMETER_RANGES = {
    "beta": (0.0, None),           # beta = 0 is explicit (central difference, acceleration form)
    "gamma": (0.5, None),          # gamma < 1/2 adds negative algorithmic damping
    "theta": (1.0, None),          # unconditionally stable only from (1 + sqrt 3)/2 = 1.366
    "alpha": (-1.0 / 3.0, 0.0),    # HHT
    "rho_inf": (0.0, 1.0),         # generalized-alpha: spectral radius at infinite frequency
    "alpha_m": (-0.5, 0.0),        # Bossak: rho_inf = (1 + alpha_m) / (1 - alpha_m), 1/3..1
}

#: the scheme that starts the multistep schemes (fills their lags), second order like them
STARTUP_SCHEME = "average_acceleration"


@dataclass(frozen=True)
class Scheme:
    """A time integrator: defining relations plus parameters.

    ``params`` are what a user types (e.g. ``beta``, ``gamma``); ``substitutions`` express the
    relations' symbols in those parameters (HHT: alpha_f = -alpha, ...); ``fixed`` gives presets.
    ``lags`` are the extra history arrays the scheme needs beyond (x0, v0, a0). ``ranges``
    gives a parameter's admissible closed interval where it differs from `PARAMETER_RANGES`
    (a scheme file declares its own). Schemes hash by content (derivations are cached on them).
    """

    name: str
    title: str
    relations: tuple
    force_weights: tuple
    params: tuple = ()
    defaults: dict = field(default_factory=dict)
    substitutions: dict = field(default_factory=dict)
    lags: tuple = ()
    startup_steps: int = 0
    order: int = 2
    reference: str = ""
    notes: str = ""
    ranges: dict = field(default_factory=dict)
    #: a composite scheme's sub-steps, each a scheme run in turn within one step of dt (their
    #: ``dt`` is the whole step; a later stage's lags xm1, vm1 are the earlier stage's start)
    stages: tuple = ()

    def __hash__(self):
        return hash((self.name, self.relations, self.force_weights, self.params,
                     tuple(self.substitutions.items()), self.lags, self.stages))

    def parameter_range(self, p: str) -> tuple:
        """The closed interval (lo, hi) of parameter ``p`` (None: unbounded)."""
        return self.ranges.get(p) or PARAMETER_RANGES[p]

    @property
    def history(self) -> tuple:
        """Names of the per-DOF history arrays, in kernel order."""
        return ("x0", "v0", "a0") + tuple(str(s) for s in self.lags)


def _newmark_preset(name, title, b, g, order, reference, notes=""):
    return Scheme(name, title, NEWMARK_ALPHA, NEWMARK_ALPHA_FORCE,
                  substitutions={beta: b, gamma: g, alpha_m: 0, alpha_f: 0},
                  order=order, reference=reference, notes=notes)


NEWMARK_REF = "Newmark (1959), J. Eng. Mech. Div. ASCE 85(3)"

SCHEMES: dict[str, Scheme] = {s.name: s for s in (
    Scheme("newmark", "Newmark beta-gamma", NEWMARK_ALPHA, NEWMARK_ALPHA_FORCE,
           params=("beta", "gamma"), defaults={"beta": 0.25, "gamma": 0.5},
           substitutions={alpha_m: 0, alpha_f: 0}, order=2, reference=NEWMARK_REF,
           notes="Second order when gamma = 1/2, first order otherwise."),
    _newmark_preset("average_acceleration", "Newmark average acceleration (trapezoidal)",
                    sp.Rational(1, 4), HALF, 2, NEWMARK_REF, "Unconditionally stable, no damping."),
    _newmark_preset("linear_acceleration", "Newmark linear acceleration", sp.Rational(1, 6), HALF,
                    2, NEWMARK_REF, "Stable for omega dt < 3.464."),
    _newmark_preset("fox_goodwin", "Fox-Goodwin (Newmark beta = 1/12)", sp.Rational(1, 12), HALF,
                    2, NEWMARK_REF, "Stable for omega dt < 2.449."),
    _newmark_preset("newmark_1_8", "Newmark beta = 1/8 (the source's favourite)", sp.Rational(1, 8),
                    HALF, 2, NEWMARK_REF, "Stable for omega dt < 2.828."),
    _newmark_preset("central_difference", "Central difference (Newmark beta = 0, explicit)", 0,
                    HALF, 2, NEWMARK_REF,
                    "Explicit: acceleration form only; stable for omega dt < 2."),
    _newmark_preset("fox_euler", "Fox-Euler (Newmark beta = 1/2, gamma = 1)", HALF, 1, 1,
                    "Fox & Euler as defined in the DT-TMM source",
                    "First order, dissipative."),
    Scheme("wilson", "Wilson theta", WILSON, (1 - theta, theta), params=("theta",),
           defaults={"theta": 1.4}, order=2,
           reference="Wilson, Farhoomand & Bathe (1973), Earthq. Eng. Struct. Dyn. 1",
           notes="Unconditionally stable for theta >= (1 + sqrt 3)/2 = 1.366."),
    Scheme("houbolt", "Houbolt", HOUBOLT, (0, 1), lags=(xm1, xm2),
           startup_steps=MULTISTEP_STARTUP, order=2,
           reference="Houbolt (1950), J. Aeronaut. Sci. 17",
           notes="Multistep; starts with 2 steps of average acceleration."),
    Scheme("park", "Park stiffly stable", PARK, (0, 1), lags=(xm1, xm2, vm1, vm2),
           startup_steps=MULTISTEP_STARTUP, order=2,
           reference="Park (1975), J. Appl. Mech. 42",
           notes="Multistep; starts with 2 steps of average acceleration."),
    Scheme("hht", "HHT-alpha", NEWMARK_ALPHA, NEWMARK_ALPHA_FORCE, params=("alpha",),
           defaults={"alpha": -0.05},
           substitutions={alpha_m: 0, alpha_f: -alpha, gamma: (1 - 2 * alpha) / 2,
                          beta: (1 - alpha) ** 2 / 4},
           order=2, reference="Hilber, Hughes & Taylor (1977), Earthq. Eng. Struct. Dyn. 5",
           notes="alpha in [-1/3, 0]; alpha = 0 is average acceleration."),
    Scheme("generalized_alpha", "Generalized-alpha", NEWMARK_ALPHA, NEWMARK_ALPHA_FORCE,
           params=("rho_inf",), defaults={"rho_inf": 0.8},
           substitutions={alpha_m: (2 * rho_inf - 1) / (rho_inf + 1),
                          alpha_f: rho_inf / (rho_inf + 1),
                          gamma: HALF - (2 * rho_inf - 1) / (rho_inf + 1) + rho_inf / (rho_inf + 1),
                          beta: (1 - (2 * rho_inf - 1) / (rho_inf + 1)
                                 + rho_inf / (rho_inf + 1)) ** 2 / 4},
           order=2, reference="Chung & Hulbert (1993), J. Appl. Mech. 60",
           notes="rho_inf in [0, 1]: spectral radius at infinite frequency."),
    Scheme("bossak", "Wood-Bossak-Zienkiewicz alpha", NEWMARK_ALPHA, NEWMARK_ALPHA_FORCE,
           params=("alpha_m",), defaults={"alpha_m": -0.1},
           substitutions={alpha_f: 0, gamma: HALF - alpha_m, beta: (1 - alpha_m) ** 2 / 4},
           order=2, reference="Wood, Bossak & Zienkiewicz (1980), Int. J. Numer. Meth. Eng. 15",
           notes="alpha_m in [-1/2, 0]: rho_inf = (1 + alpha_m) / (1 - alpha_m)."),
)}


def resolve(scheme) -> Scheme:
    """A built-in scheme by name, or a `Scheme` value (a scheme file's) as it is."""
    if isinstance(scheme, Scheme):
        return scheme
    try:
        return SCHEMES[scheme]
    except KeyError:
        raise ValueError(f"unknown scheme {scheme!r}; available: {', '.join(SCHEMES)}") from None


@dataclass(frozen=True)
class Derived:
    """What `derive_scheme` returns; every entry is a SymPy expression."""

    scheme: Scheme
    A: sp.Expr  # d ae / d xe
    B: sp.Expr  # ae - A xe (history)
    D: sp.Expr  # d ve / d xe
    E: sp.Expr  # ve - D xe (history)
    Dx: sp.Expr  # d xe / d ae (acceleration form)
    Ex: sp.Expr
    Dv: sp.Expr  # d ve / d ae
    Ev: sp.Expr
    update_x: dict  # {"x1": expr, "v1": ..., "a1": ...} in xe and history
    update_a: dict  # the same in ae and history
    w0: sp.Expr
    w1: sp.Expr
    explicit: bool  # True when ae does not depend on xe (no displacement form)


def _solve(relations, primary):
    unknowns = [s for s in (x1, v1, a1, xe, ve, ae) if s != primary]
    sol = sp.solve(list(relations), unknowns, dict=True)
    if len(sol) != 1:
        raise ValueError(f"relations do not determine {unknowns} from {primary}")
    return {k: sp.simplify(v) for k, v in sol[0].items()}


def _affine(expr, var):
    """Split expr = coeff * var + rest, checking it is affine in var."""
    expr = sp.expand(expr)
    coeff = sp.simplify(expr.coeff(var, 1))
    rest = sp.simplify(expr - coeff * var)
    if rest.has(var) or coeff.has(var):
        raise ValueError(f"{expr} is not affine in {var}")
    return coeff, sp.factor_terms(rest)


def derive_scheme(scheme: str | Scheme) -> Derived:
    """Derive the displacement-form and acceleration-form coefficients of a scheme (a built-in
    name or a `Scheme` value)."""
    return _derive(resolve(scheme))


@cache
def _derive(s: Scheme) -> Derived:
    rel = tuple(r.subs(s.substitutions) for r in s.relations)
    w0, w1 = (sp.sympify(w).subs(s.substitutions) for w in s.force_weights)
    sol_a = _solve(rel, ae)  # everything in terms of ae: always exists (explicit schemes too)
    Dx, Ex = _affine(sol_a[xe], ae)
    Dv, Ev = _affine(sol_a[ve], ae)
    explicit = sp.simplify(Dx) == 0
    if explicit:
        A = B = D = E = sp.nan
        update_x = {}
    else:
        sol_x = _solve(rel, xe)
        A, B = _affine(sol_x[ae], xe)
        D, E = _affine(sol_x[ve], xe)
        update_x = {k: sp.simplify(sol_x[sym]) for k, sym in (("x1", x1), ("v1", v1), ("a1", a1))}
    update_a = {k: sp.simplify(sol_a[sym]) for k, sym in (("x1", x1), ("v1", v1), ("a1", a1))}
    return Derived(s, sp.simplify(A), B, sp.simplify(D), E, sp.simplify(Dx), Ex, sp.simplify(Dv),
                   Ev, update_x, update_a, sp.simplify(w0), sp.simplify(w1), bool(explicit))


def param_symbols(scheme: Scheme) -> tuple:
    """The SymPy symbols of the user parameters, in order (real, as in the relations)."""
    return tuple(sp.Symbol(p, real=True) for p in scheme.params)


def scheme_table() -> dict:
    """Every scheme as plain data (no SymPy): title, parameters with default and range, the
    preset values of the Newmark family, start-up, explicitness, order, reference, notes."""
    return {name: table_row(s) for name, s in SCHEMES.items()}


def table_row(s: Scheme) -> dict:
    """One scheme's row of `scheme_table`."""
    presets = {str(k): float(v) for k, v in s.substitutions.items()
               if str(k) in ("beta", "gamma") and sp.sympify(v).is_number}
    return {
        "title": s.title,
        "params": {p: {"default": float(s.defaults[p]), "range": s.parameter_range(p)}
                   for p in s.params},
        "presets": presets,
        "startup_steps": s.startup_steps,
        "startup_scheme": STARTUP_SCHEME if s.startup_steps else None,
        "explicit": any(derive_scheme(part).explicit for part in s.stages or (s,)),
        "stages": [part.name for part in s.stages],
        "order": s.order,
        "reference": s.reference,
        "notes": s.notes,
    }
