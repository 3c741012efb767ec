"""Kernel specs: the derived relations reshaped into what the templates print.

Every map a kernel needs is linear in the history (x0, v0, a0, lags), with coefficients that
depend on dt and the scheme parameters only, so the emitted code computes those coefficients once
per run and each step is a few multiply-adds per mass:

    q, s, b   = L_qsb . h                       (per form, see dttmm.form_maps)
    x1, v1, a1 = c_u u + L_upd . h              (u the primary unknown of the form)

In the displacement form the lags of x enter through increments (dx0 = x0 - xm1, ...:
`in_increments`).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from . import dttmm, integrators as I


@dataclass(frozen=True)
class FormSpec:
    form: str
    constants: dict  # name -> expr in dt and params: p, r, alpha
    hist_terms: dict  # "q"/"s"/"b" -> {hist name: coeff expr}
    update: dict  # "x1"/"v1"/"a1" -> {"u" or hist name: coeff expr}


@dataclass(frozen=True)
class SchemeSpec:
    name: str
    scheme: I.Scheme
    derived: I.Derived
    params: tuple  # user parameter names
    history: tuple  # history names, kernel order
    w0: sp.Expr
    w1: sp.Expr
    forms: dict  # form -> FormSpec (explicit schemes: acceleration only)


def _linear(expr, variables, what):
    """Coefficients of an expression that must be linear (no constant) in ``variables``."""
    expr = sp.expand(expr)
    coeffs = {str(v): sp.simplify(expr.coeff(v, 1)) for v in variables}
    rest = sp.simplify(expr - sum(sp.Symbol(n) * cf for n, cf in coeffs.items()))
    if rest != 0:
        raise ValueError(f"{what} is not linear in {variables}: remainder {rest}")
    return {n: cf for n, cf in coeffs.items() if cf != 0}


U = sp.Symbol("u")


def increment_pair(name: str) -> tuple[str, str]:
    """The two history rows of an increment: dx0 = x0 - xm1, dxm1 = xm1 - xm2 (the same for v)."""
    base = name[1:]
    lag = 0 if base[1:] == "0" else int(base[2:])
    return base, f"{base[0]}m{lag + 1}"


def in_increments(terms: dict, history: tuple) -> dict:
    """Write the zero-sum combinations of a quantity's lags in increments.

    c0 x0 + c1 xm1 + c2 xm2 = c0 (x0 - xm1) + (c0 + c1) (xm1 - xm2) when c0 + c1 + c2 = 0: the
    key "dx0" stands for x0 - xm1, "dxm1" for xm1 - xm2 (`increment_pair`). The increments are
    differences of nearby numbers, so a coefficient of size 1/dt^2 multiplies |x_n - x_n-1|,
    not |x| (dtdyn.derive.dttmm, displacement form). Keys keep the history's order; a
    combination whose coefficients do not sum to zero is left as it is.
    """
    out = dict(terms)
    for qty in "xv":
        group = [h for h in history if h[0] == qty]  # x0, xm1, xm2, ... (lag order)
        coeffs = [terms.get(h, 0) for h in group]
        if sum(1 for cf in coeffs if cf != 0) < 2 or sp.simplify(sum(coeffs)) != 0:
            continue
        partial = 0
        for h, cf in zip(group[:-1], coeffs):
            partial = sp.simplify(partial + cf)
            out.pop(h, None)
            if partial != 0:
                out["d" + h] = partial
        out.pop(group[-1], None)
    order = [h for name in history for h in ("d" + name, name)] + ["u"]
    return {h: out[h] for h in order if h in out}


def scheme_spec(scheme: str | I.Scheme) -> SchemeSpec:
    """The kernel spec of a built-in scheme (by name) or of a `Scheme` value."""
    der = I.derive_scheme(scheme)
    scheme = der.scheme
    name = scheme.name
    hist = [sp.Symbol(h) for h in scheme.history]
    forms = {}
    for form in dttmm.FORMS:
        if form == "displacement" and der.explicit:
            continue
        maps = dttmm.form_maps(form, der)
        # the primary unknown is called u in the kernels, and its term comes last; in the
        # displacement form u = xe - x0 (dtdyn.derive.dttmm)
        if form == "displacement":
            upd, primary, shifted = der.update_x, I.xe, U + I.x0
            steps = lambda terms: in_increments(terms, scheme.history)  # noqa: E731
        else:
            upd, primary, shifted = der.update_a, I.ae, U
            steps = lambda terms: terms  # noqa: E731
        forms[form] = FormSpec(
            form,
            {n: sp.simplify(maps[n]) for n in ("p", "r", "alpha_u")},
            {n: steps(_linear(maps[n], hist, f"{name}.{form}.{n}")) for n in ("q", "s", "b")},
            {n: steps(_linear(upd[n].subs(primary, shifted), hist + [U], f"{name}.{form}.{n}"))
             for n in ("x1", "v1", "a1")},
        )
    return SchemeSpec(name, scheme, der, scheme.params, scheme.history, der.w0, der.w1, forms)


def constant_table(spec: SchemeSpec, form: str) -> list[tuple[str, sp.Expr]]:
    """All per-run constants of one form as (C/Python name, expression), deterministic order."""
    fs = spec.forms[form]
    rows = [("w0", spec.w0), ("w1", spec.w1)]
    rows += [(n, fs.constants[n]) for n in ("p", "r", "alpha_u")]
    for n in ("q", "s", "b"):
        rows += [(f"{n}_{h}", cf) for h, cf in fs.hist_terms[n].items()]
    for n in ("x1", "v1", "a1"):
        rows += [(f"{n}_{h}", cf) for h, cf in fs.update[n].items()]
    return rows
