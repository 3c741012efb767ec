"""Derived equations as a paper prints them: factored, collected on the history, named.

`readable(scheme)` takes a built-in scheme's name, a `Scheme` or its `Derived` value and returns
a `Readable`: the defining relations and substitutions, the force weights, the coefficients of
both forms (A, B, D, E; Dx, Ex, Dv, Ev), the updates of x1, v1, a1 and the DT-TMM station matrix
of each form, every right-hand side arranged for reading and printed three ways (`text`,
`latex`, `markdown`). The arrangement only regroups: each shown expression is the derived one
(the tests check simplify(shown - derived) == 0), and each station matrix equals the one
`dtdyn.derive.dttmm` builds once its "where" list is substituted back.

Arrangement of one right-hand side:

- no history symbol (A, D, Dx, Dv, w0, w1): ``sp.factor``, each factor written with a positive
  leading term, ``4 / (dt^2 (1 - alpha)^2 (1 + alpha))``;
- affine in the history (B, E, Ex, Ev, the updates): the shorter of one factored coefficient per
  history symbol, ``-x0 / (beta dt^2) - v0 / (beta dt) - (1 - 2 beta) a0 / (2 beta)``, and one
  numerator over the common denominator;
- station matrices: in the station's named quantities (kappa, mu, beta_n, Delta, q_n, s_n, b_n
  of dtdyn.derive.dttmm), themselves in the named coefficients A, D, ... ("where" list);
- a group with a line still wider than `WIDTH` names its common subexpressions with
  ``sympy.cse`` (c1, c2, ... in the "where" list), and a line still too wide is broken between
  terms.
"""
from __future__ import annotations

import textwrap
from dataclasses import dataclass
from types import SimpleNamespace

import sympy as sp

from . import dttmm, integrators as I

#: the widest printed line (text form)
WIDTH = 100

# -- symbols: how they print and where they go in a product or a sum -------------------------

_MODEL = (dttmm.m, dttmm.k, dttmm.c, dttmm.kg, dttmm.cg)
_HISTORY = (I.x0, I.v0, I.a0, I.xm1, I.xm2, I.vm1, I.vm2)
_NEW = (I.x1, I.v1, I.a1, I.xe, I.ve, I.ae, I.F0, I.F1)
_STATION = (dttmm.beta, dttmm.F_n, dttmm.mu, dttmm.Delta, dttmm.kappa, dttmm.q_n, dttmm.q_p,
            dttmm.s_n, dttmm.s_p, dttmm.b_n)
#: the symbols an expression is collected on, in the order their terms are written
LINEAR = _MODEL + _HISTORY + _NEW + _STATION
_RANK = {s: i for i, s in enumerate(LINEAR)}

#: the named coefficients, as symbols (what the station matrices are written in)
COEFFICIENTS = ("A", "B", "D", "E", "Dx", "Ex", "Dv", "Ev")
_COEF_SYMBOLS = {n: sp.Symbol(n) for n in COEFFICIENTS}

_TEXT_NAMES = {dttmm.q_p: "q_{n-1}", dttmm.s_p: "s_{n-1}"}
_LATEX_NAMES = {
    I.dt: r"\Delta t", I.xe: "x_e", I.ve: "v_e", I.ae: "a_e",
    I.xm1: "x_{m1}", I.xm2: "x_{m2}", I.vm1: "v_{m1}", I.vm2: "v_{m2}",
    I.F0: "F_n", I.F1: "F_{n+1}", dttmm.kg: "k_g", dttmm.cg: "c_g",
    dttmm.q_n: "q_n", dttmm.s_n: "s_n", dttmm.b_n: "b_n", dttmm.F_n: "F_n",
    dttmm.q_p: "q_{n-1}", dttmm.s_p: "s_{n-1}", dttmm.beta: r"\beta_n", dttmm.Delta: r"\Delta_n",
    **{s: f"{n[0]}_{n[1]}" for n, s in _COEF_SYMBOLS.items() if len(n) == 2},
}


def _category(sym) -> int:
    """Place of a symbol in a product: model, named quantities, parameters, dt, state."""
    if sym in _MODEL:
        return 0
    if sym in _RANK:
        return 5
    if sym == I.dt:
        return 3
    if sym in _COEF_SYMBOLS.values() or str(sym)[:1] == "c" and str(sym)[1:].isdigit():
        return 1
    return 2


# -- the printer -------------------------------------------------------------------------------

def _flat_factors(expr) -> list:
    """The factors of a (possibly unevaluated, nested) product."""
    if isinstance(expr, sp.Mul):
        return [f for a in expr.args for f in _flat_factors(a)]
    if isinstance(expr, sp.Pow) and isinstance(expr.base, sp.Mul) and expr.exp.is_Integer:
        return [sp.Pow(f, expr.exp) for f in _flat_factors(expr.base)]
    return [expr]


def _flat_terms(expr) -> list:
    if isinstance(expr, sp.Add):
        return [t for a in expr.args for t in _flat_terms(a)]
    return [expr]


def _degree(term) -> int:
    try:
        return sp.Poly(term, *sorted(term.free_symbols, key=str)).total_degree()
    except (sp.PolynomialError, sp.GeneratorsNeeded):
        return 0


def _term_key(term):
    """Numbers first, then the terms with a collected symbol in its order (x0 before v0 ...),
    then the rest by degree: 1 + 2 alpha - alpha^2, D x0 + E."""
    linear = [_RANK[s] for s in term.free_symbols if s in _RANK]
    return (0 if term.is_number else 1 if linear else 2, min(linear) if linear else -1,
            _degree(term), sp.default_sort_key(term))


def _ordered_terms(expr) -> list:
    return sorted(_flat_terms(expr), key=_term_key)


def _linear(expr) -> bool:
    return any(s in _RANK for s in sp.sympify(expr).free_symbols)


def _leading_positive(terms: list) -> list:
    """The terms of a parenthesized sum reordered to lead with a positive one: a polynomial in
    the parameters from its highest degree (2 rho_inf - 1, not -1 + 2 rho_inf), a sum with
    collected symbols from its last positive term, the newest quantity (11 x1 - 18 x0 + ...)."""
    if not terms or not _negative(terms[0]) or all(_negative(t) for t in terms):
        return terms
    if not any(_linear(t) for t in terms):
        return terms[::-1] if not _negative(terms[-1]) else terms
    first = max(i for i, t in enumerate(terms) if not _negative(t))  # x1, xe, ae: the newest
    return [terms[first]] + terms[:first] + terms[first + 1:]


def _flip(base):
    """-base, term by term (keeps a collected term's coefficient factored)."""
    return sp.Add(*[sp.Mul(-1, t) for t in _flat_terms(base)], evaluate=False)


def _flips(base) -> bool:
    """Whether a sum in a product is written with the sign outside: a polynomial in the
    parameters whose lowest-degree term is negative ((alpha - 1)^2 -> (1 - alpha)^2), a sum with
    collected symbols whose terms are mostly negative, unless a new quantity (x1, xe, ...) comes
    with a plus sign: -(5 x0 - 4 xm1 + xm2), but 11 x1 - 18 x0 + 9 xm1 - 2 xm2."""
    terms = _ordered_terms(base)
    if any(_linear(t) for t in terms):
        negative = [_negative(t) for t in terms]
        if any(not n and t.has(*_NEW) for t, n in zip(terms, negative)):
            return False
        return 2 * sum(negative) > len(terms)
    return _negative(terms[0])


def _negative(term) -> bool:
    """Whether a term prints with a leading minus sign."""
    return TEXT(term).startswith("-")


class _Printer:
    """One printer for the text and the LaTeX form (``latex``), the same arrangement."""

    def __init__(self, latex: bool):
        self.latex = latex

    def paren(self, s: str) -> str:
        return rf"\left({s}\right)" if self.latex else f"({s})"

    def symbol(self, sym) -> str:
        if self.latex:
            return _LATEX_NAMES.get(sym) or sp.latex(sym)
        return _TEXT_NAMES.get(sym, str(sym))

    def number(self, num) -> str:
        if num.is_Rational and num.q != 1:
            p, q = abs(num.p), num.q
            body = rf"\frac{{{p}}}{{{q}}}" if self.latex else f"{p}/{q}"
            return ("-" if num < 0 else "") + body
        return sp.latex(num) if self.latex else sp.sstr(num)

    def atom(self, expr) -> str:
        """An operand of a product or a power: parenthesized unless a symbol or a number."""
        s = self.add(expr, inner=True) if isinstance(expr, sp.Add) else self(expr)
        if isinstance(expr, sp.Symbol) or (expr.is_Integer and expr >= 0) or \
                isinstance(expr, sp.Function):
            return s
        return self.paren(s)

    def power(self, base, exp) -> str:
        if exp == 1:
            return self.atom(base)
        if exp == sp.Rational(1, 2):
            return rf"\sqrt{{{self(base)}}}" if self.latex else f"sqrt({self(base)})"
        e = self(exp) if exp.is_Integer and exp > 0 else self.paren(self(exp))
        return f"{self.atom(base)}^{{{e}}}" if self.latex else f"{self.atom(base)}^{e}"

    def add(self, expr, inner: bool = False) -> str:
        out = ""
        terms = _ordered_terms(expr)
        for i, t in enumerate(_leading_positive(terms) if inner else terms):
            s = self(t)
            if i == 0:
                out = s
            elif s.startswith("-"):
                out += " - " + s[1:]
            else:
                out += " + " + s
        return out

    def mul(self, expr) -> str:
        factors = _flat_factors(expr)
        coeff = sp.Mul(*[f for f in factors if f.is_number and not isinstance(f, sp.Pow)])
        negative = bool(coeff.is_negative)
        coeff = abs(coeff)
        linear = any(sym in _RANK for sym in expr.free_symbols)
        num, den, odd = [], [], []
        for f in factors:
            if f.is_number and not isinstance(f, sp.Pow):
                continue
            base, exp = f.as_base_exp()
            # each sum in the product leads with a positive term, the sign outside:
            # (alpha - 1)^2 -> (1 - alpha)^2, -2 (2 alpha - 1) -> 2 (1 - 2 alpha)
            if isinstance(base, sp.Add) and exp.is_Integer and _flips(base):
                base = _flip(base)
                negative ^= bool(exp % 2)
                if exp % 2:
                    odd.append(base)
            (den if exp.is_number and exp.is_negative else num).append(
                [base, -exp if exp.is_number and exp.is_negative else exp])
        if negative and odd and not linear:  # but a parameter's value is not -(1 - 2 rho_inf)
            for item in num + den:
                if item[0] is odd[0]:
                    item[0], negative = _flip(item[0]), False
                    break
        key = lambda be: (4 if not isinstance(be[0], sp.Symbol) else _category(be[0]),  # noqa
                          _RANK.get(be[0], 0), sp.default_sort_key(be[0]))
        p, q = (coeff.p, coeff.q) if coeff.is_Rational else (coeff, 1)
        top = [self.number(sp.sympify(p))] if p != 1 or not num else []
        num, den = sorted(num, key=key), sorted(den, key=key)
        top += [self.power(b, e) for b, e in num]
        bottom = [str(q)] if q != 1 else []
        bottom += [self.power(b, e) for b, e in den]
        sign = "-" if negative else ""
        if not bottom:
            return sign + " ".join(top)
        if self.latex:  # a lone sum over or under the bar needs no parentheses
            def part(items, parts):
                lone = len(parts) == 1 and len(items) == 1 and items[0][1] == 1 and \
                    isinstance(items[0][0], sp.Add)
                return self.add(items[0][0], inner=True) if lone else " ".join(parts)
            return sign + rf"\frac{{{part(num if p == 1 else [], top)}}}" \
                rf"{{{part(den if q == 1 else [], bottom)}}}"
        below = " ".join(bottom)
        return sign + " ".join(top) + " / " + (self.paren(below) if len(bottom) > 1 else below)

    def __call__(self, expr) -> str:
        expr = sp.sympify(expr)
        if isinstance(expr, sp.Symbol):
            return self.symbol(expr)
        if expr.is_number and not isinstance(expr, (sp.Pow, sp.Mul, sp.Add)):
            return self.number(expr)
        if isinstance(expr, sp.Add):
            return self.add(expr)
        if isinstance(expr, (sp.Mul, sp.Pow)):
            if isinstance(expr, sp.Pow) and not (expr.exp.is_number and expr.exp.is_negative):
                return self.power(expr.base, expr.exp)
            return self.mul(expr)
        if isinstance(expr, sp.Equality):
            return f"{self(expr.lhs)} = {self(expr.rhs)}"
        return sp.latex(expr) if self.latex else sp.sstr(expr)

    def terms(self, expr) -> list[str]:
        """The top-level terms of a sum, each with its sign ("+ ..." / "- ..."), for wrapping."""
        if not isinstance(expr, sp.Add):
            return [self(expr)]
        out = []
        for i, t in enumerate(_ordered_terms(expr)):
            s = self(t)
            out.append(s if i == 0 else ("- " + s[1:] if s.startswith("-") else "+ " + s))
        return out


TEXT, LATEX = _Printer(latex=False), _Printer(latex=True)


# -- arranging one expression ------------------------------------------------------------------

def _factored(expr):
    """sp.factor of a rational function of dt and the parameters (the expression if it is not)."""
    expr = sp.sympify(expr)
    try:
        return sp.factor(sp.cancel(expr))
    except sp.PolynomialError:
        return expr


def arrange(expr, linear=LINEAR):
    """The expression regrouped for reading (equal to ``expr``): factored, or collected on the
    symbols of ``linear`` it is affine in, with factored coefficients (module docstring)."""
    expr = sp.sympify(expr)
    present = [s for s in linear if expr.has(s)]
    if not present:
        return _factored(expr)
    expanded = sp.expand(expr)
    coeffs = {s: sp.cancel(expanded.coeff(s, 1)) for s in present}
    rest = sp.cancel(expanded - sum(c * s for s, c in coeffs.items()))
    if any(c.has(*present) for c in coeffs.values()) or rest.has(*present):
        return _factored(expr)  # not affine in them (a relation, a product of two): as it is
    per_term = sp.Add(*[sp.Mul(_factored(c), s, evaluate=False) for s, c in coeffs.items()
                        if c != 0], *([_factored(rest)] if rest != 0 else []), evaluate=False)
    together = sp.cancel(sp.together(expr))
    num, den = sp.fraction(together)
    if den == 1:
        return per_term
    ncoef = {s: sp.expand(num).coeff(s, 1) for s in present}
    nrest = sp.expand(sp.expand(num) - sum(c * s for s, c in ncoef.items()))
    terms = [sp.Mul(_factored(c), s, evaluate=False) for s, c in ncoef.items() if c != 0]
    terms += [_factored(nrest)] if nrest != 0 else []
    sign = 1
    if all(_negative(t) for t in terms):  # -(4 x0 + ...) / ...
        sign = -1
        terms = [sp.Mul(_factored(sp.cancel(-c)), s, evaluate=False)
                 for s, c in ncoef.items() if c != 0]
        terms += [_factored(-nrest)] if nrest != 0 else []
    common = sp.Mul(sign, sp.Add(*terms, evaluate=False), sp.Pow(_factored(den), -1),
                    evaluate=False)
    # one fraction when it is shorter and fits a line; a sum of terms otherwise (it can wrap)
    short = len(TEXT(common)) < min(len(TEXT(per_term)), WIDTH - 20)
    return common if short else per_term


# -- lines, sections and the whole derivation --------------------------------------------------

@dataclass(frozen=True)
class Line:
    """One displayed equation ``name = value``: ``value`` is the arranged SymPy expression."""

    name: str
    value: object
    latex_name: str = ""

    @property
    def text_rhs(self) -> str:
        return TEXT(self.value)

    @property
    def latex_rhs(self) -> str:
        return LATEX(self.value)

    def latex(self) -> str:
        return f"{self.latex_name or self.name} = {self.latex_rhs}"


@dataclass(frozen=True)
class Section:
    """A titled group of lines; ``matrix`` (rows of arranged entries) for a station matrix;
    ``where`` the named quantities its lines use."""

    title: str
    lines: tuple = ()
    where: tuple = ()
    matrix: tuple = ()
    note: str = ""
    given: tuple = ()  # lines shown in an earlier section (substituted, not printed again)

    def substituted(self):
        """The lines' values (or the matrix) with the where list substituted back."""
        values = sp.Matrix(self.matrix) if self.matrix else sp.Matrix([ln.value for ln in
                                                                       self.lines])
        subs = {_WHERE_SYMBOLS.get(w.name, sp.Symbol(w.name)): w.value
                for w in self.where + self.given}
        for _ in range(len(subs) + 1):  # each name may use the names after or before it
            if not values.free_symbols & set(subs):
                break
            values = values.subs(subs)
        return values if self.matrix else list(values)


_WHERE_SYMBOLS = {"kappa": dttmm.kappa, "mu": dttmm.mu, "beta_n": dttmm.beta,
                  "Delta": dttmm.Delta, "q_n": dttmm.q_n, "s_n": dttmm.s_n, "b_n": dttmm.b_n,
                  **_COEF_SYMBOLS}
_LATEX_LHS = {"kappa": r"\kappa", "mu": r"\mu", "beta_n": r"\beta_n", "Delta": r"\Delta_n",
              "q_n": "q_n", "s_n": "s_n", "b_n": "b_n", "Dx": "D_x", "Ex": "E_x", "Dv": "D_v",
              "Ev": "E_v", "w0": "w_0", "w1": "w_1", "x1": "x_1", "v1": "v_1", "a1": "a_1"}


def _line(name, value, linear=LINEAR, as_is=False) -> Line:
    """A line ``name = value``, value arranged (``as_is``: as written, a definition)."""
    latex_name = _LATEX_LHS.get(name) or (LATEX(name) if isinstance(name, sp.Basic) else name)
    text_name = TEXT(name) if isinstance(name, sp.Basic) else name
    return Line(text_name, sp.sympify(value) if as_is else arrange(value, linear), latex_name)


@dataclass(frozen=True)
class Readable:
    """A scheme's derivation arranged for reading; `text`, `latex` and `markdown` print it."""

    name: str
    title: str
    reference: str
    notes: str
    explicit: bool
    relations: tuple  # Line per defining relation, as the scheme writes it
    substitutions: tuple  # Line per substitution (symbol = its value in the parameters)
    sections: tuple  # Section: force weights, coefficients, updates, station matrices

    def text(self, width: int = WIDTH) -> str:
        return _text(self, width)

    def latex(self) -> str:
        return _latex(self)

    def markdown(self, level: int = 2) -> str:
        return _markdown(self, level)

    def latex_block(self) -> str:
        """One ``align*`` block, groups titled by \\text rows (a notebook's _repr_latex_)."""
        rows = [r"&\text{Defining relations}"]
        rows += [f"{ln.latex_name} &= {ln.latex_rhs}" for ln in self.relations + self.substitutions]
        for sec in self.sections:
            title = sec.title.replace("_", r"\_").replace("{", r"\{").replace("}", r"\}")
            rows.append(rf"&\text{{{title}}}")
            if sec.matrix:
                rows.append("&" + _latex_matrix(sec.matrix))
            rows += [f"{ln.latex_name} &= {ln.latex_rhs}" for ln in sec.lines + sec.where]
        return "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}"


def _station_sections(der) -> list[Section]:
    """The DT-TMM station matrix of each form, in the named quantities of dtdyn.derive.dttmm."""
    named = SimpleNamespace(**_COEF_SYMBOLS)
    values = {n: getattr(der, n) for n in COEFFICIENTS}
    trivial = {_COEF_SYMBOLS[n]: v for n, v in values.items() if v in (0, 1)}
    T = dttmm.station_step()
    out = []
    for form in dttmm.FORMS:
        if form == "displacement" and der.explicit:
            continue
        maps = dttmm.form_maps(form, named)
        maps = {n: sp.sympify(v).xreplace(trivial) for n, v in maps.items()}
        sub = {dttmm.p: maps["p"], dttmm.r: maps["r"], dttmm.alpha: maps["alpha_u"]}
        where = [_line(n, v, as_is=True) for n, v in (
            ("kappa", dttmm.KAPPA.xreplace(sub)), ("mu", dttmm.MU.xreplace(sub)),
            ("beta_n", dttmm.BETA), ("Delta", dttmm.DELTA),
            ("q_n", maps["q"]), ("s_n", maps["s"]), ("b_n", maps["b"]))]
        used = set().union(*(sp.sympify(w.value).free_symbols for w in where))
        given = [_line(n, values[n]) for n in COEFFICIENTS if _COEF_SYMBOLS[n] in used]
        unknown = "u = xe - x0, the increment" if form == "displacement" else "u = ae"
        out.append(Section(
            f"DT-TMM station matrix, {form} form ({unknown})",
            matrix=tuple(tuple(T.row(i)) for i in range(T.rows)),
            where=tuple(where), given=tuple(given),
            note="[u_{n-1}, f_n, 1] -> [u_n, f_{n+1}, 1] at mass n; k_g, c_g: its spring and "
                 "damper to the ground"))
    return out


def station_matrix(der, form: str) -> sp.Matrix:
    """The station matrix of a form with every quantity substituted (what `dtdyn show` printed
    before: the reference the arranged form is checked against)."""
    maps = dttmm.form_maps(form, der)
    subs = {dttmm.p: maps["p"], dttmm.r: maps["r"], dttmm.alpha: maps["alpha_u"],
            dttmm.b_n: maps["b"]}
    T = dttmm.station_step().subs({dttmm.mu: dttmm.MU, dttmm.beta: dttmm.BETA}).subs(subs)
    return T.subs({dttmm.kappa: dttmm.KAPPA.subs(subs),
                   dttmm.Delta: dttmm.DELTA}).subs({dttmm.q_n: maps["q"], dttmm.s_n: maps["s"]})


def _cse_group(section: Section, width: int) -> Section:
    """Name the common subexpressions of a section whose text is wider than ``width``."""
    pad = max((len(ln.name) for ln in section.lines), default=0)
    if all(len(part) <= width for ln in section.lines
           for part in _wrapped(f"  {ln.name.ljust(pad)} = ", ln.value, width)):
        return section
    temps, reduced = sp.cse([sp.sympify(ln.value) for ln in section.lines],
                            symbols=sp.numbered_symbols("t"), order="canonical")
    keep = {}  # the subexpressions worth a name: not a power of one symbol, not tiny
    for t, e in temps:
        e = e.xreplace(keep)
        if sp.count_ops(e) >= 3 and not (e.is_Pow and e.base.is_Symbol):
            keep[t] = sp.Symbol(f"c{len([v for v in keep.values() if v.is_Symbol]) + 1}")
            keep[keep[t]] = e
        else:
            keep[t] = e
    names = {t: v for t, v in keep.items() if isinstance(t, sp.Symbol) and t.name[0] == "t"}
    where = tuple(_line(str(names[t]), keep[names[t]]) for t, _ in temps
                  if names[t].is_Symbol and names[t] in keep)
    lines = tuple(Line(ln.name, arrange(r.xreplace(names)), ln.latex_name)
                  for ln, r in zip(section.lines, reduced))
    return Section(section.title, lines, section.where + where, section.matrix, section.note)


def readable(scheme, width: int = WIDTH) -> Readable:
    """The derivation of ``scheme`` (a built-in name, a `Scheme` or a `Derived`) for reading."""
    der = scheme if isinstance(scheme, I.Derived) else I.derive_scheme(scheme)
    s = der.scheme
    relations = tuple(_line(r.lhs, r.rhs, as_is=True) for r in s.relations)
    substitutions = tuple(_line(k, v, ()) for k, v in s.substitutions.items())
    sections = [Section("Equilibrium: M ae + C ve + K xe = w0 F_n + w1 F_{n+1}",
                        (_line("w0", der.w0), _line("w1", der.w1)))]
    if not der.explicit:
        sections.append(Section("Displacement form: ae = A xe + B, ve = D xe + E",
                                tuple(_line(n, getattr(der, n)) for n in "ABDE")))
    sections.append(Section("Acceleration form: xe = Dx ae + Ex, ve = Dv ae + Ev",
                            tuple(_line(n, getattr(der, n)) for n in ("Dx", "Ex", "Dv", "Ev"))))
    if der.update_x:
        sections.append(Section("Update from xe (displacement form)",
                                tuple(_line(k, v) for k, v in der.update_x.items())))
    sections.append(Section("Update from ae (acceleration form)",
                            tuple(_line(k, v) for k, v in der.update_a.items())))
    sections = [_cse_group(sec, width) for sec in sections] + _station_sections(der)
    if der.explicit:
        sections.insert(1, Section("Explicit: ae does not depend on xe, so there is no "
                                   "displacement form"))
    return Readable(s.name, s.title, s.reference, s.notes, der.explicit, relations,
                    substitutions, tuple(sections))


# -- renderings --------------------------------------------------------------------------------

def _wrapped(prefix: str, value, width: int) -> list[str]:
    """``prefix + value`` broken between the terms of a sum so that no line exceeds width."""
    one = prefix + TEXT(value)
    if len(one) <= width:
        return [one]
    lines, current = [], prefix
    for term in TEXT.terms(value):
        piece = term if current == prefix else " " + term
        if len(current) + len(piece) > width and current != prefix:
            lines.append(current)
            current, piece = " " * len(prefix) + term, ""
        current += piece
    return lines + [current]


def _aligned(lines, indent: str, width: int) -> list[str]:
    if not lines:
        return []
    w = max(len(ln.name) for ln in lines)
    out = []
    for ln in lines:
        out += _wrapped(f"{indent}{ln.name.ljust(w)} = ", ln.value, width)
    return out


def _matrix_rows(matrix, indent: str) -> list[str]:
    cells = [[TEXT(e) for e in row] for row in matrix]
    widths = [max(len(row[j]) for row in cells) for j in range(len(cells[0]))]
    return [indent + ("T = [ " if i == 0 else "    [ ")
            + "   ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip().ljust(
                sum(widths) + 3 * (len(widths) - 1)) + " ]"
            for i, row in enumerate(cells)]


def _text(r: Readable, width: int) -> str:
    out = [f"{r.title} ({r.name})"]
    out += [x for x in (r.reference, r.notes) if x]
    out += ["", "Defining relations"]
    for ln in r.relations:
        out += _wrapped(f"  {ln.name} = ", ln.value, width)
    if r.substitutions:
        out.append("  with")
        out += _aligned(r.substitutions, "    ", width)
    for sec in r.sections:
        out += ["", sec.title]
        if sec.note:
            out += textwrap.wrap(sec.note, width, initial_indent="  ", subsequent_indent="  ")
        if sec.matrix:
            out += _matrix_rows(sec.matrix, "  ")
        out += _aligned(sec.lines, "  ", width)
        if sec.where:
            out.append("  where" + _given(sec))
            out += _aligned(sec.where, "    ", width)
    return "\n".join(out) + "\n"


def _given(sec: Section) -> str:
    names = ", ".join(ln.name for ln in sec.given)
    return f" ({names} as above)" if names else ""


def _latex_matrix(matrix) -> str:
    rows = r" \\ ".join(" & ".join(LATEX(e) for e in row) for row in matrix)
    return rf"T = \begin{{bmatrix}} {rows} \end{{bmatrix}}"


def _latex(r: Readable) -> str:
    """A LaTeX fragment: one align* block per group (amsmath)."""
    def block(lines):
        return "\\begin{align*}\n" + " \\\\\n".join(
            f"{ln.latex_name} &= {ln.latex_rhs}" for ln in lines) + "\n\\end{align*}"

    out = [f"% {r.title} ({r.name}); {r.reference}", "% Defining relations",
           block(r.relations)]
    if r.substitutions:
        out += ["% with", block(r.substitutions)]
    for sec in r.sections:
        out.append(f"% {sec.title}")
        if sec.matrix:
            out.append("\\begin{equation*}\n" + _latex_matrix(sec.matrix) + "\n\\end{equation*}")
        if sec.lines:
            out.append(block(sec.lines))
        if sec.where:
            out += ["% where" + _given(sec), block(sec.where)]
    return "\n".join(out) + "\n"



def _md_math(text: str) -> str:
    """A section title with its formulas in $...$: split at ': ' and ', '."""
    if ": " not in text or "=" not in text:
        return text
    head, tail = text.split(": ", 1)
    parts = [p.strip() for p in tail.split(", ")]
    return head + ": " + ", ".join(f"${_md_symbols(p)}$" for p in parts)


def _md_symbols(s: str) -> str:
    for a, b in (("xe", "x_e"), ("ve", "v_e"), ("ae", "a_e"), ("Dx", "D_x"), ("Ex", "E_x"),
                 ("Dv", "D_v"), ("Ev", "E_v"), ("w0", "w_0"), ("w1", "w_1")):
        s = s.replace(a, b)
    return s


def _markdown(r: Readable, level: int = 2) -> str:
    """Markdown with $...$ math: headings of ``level``, one table per group."""
    h = "#" * level

    def table(lines):
        return ["| symbol | derived |", "|---|---|"] + [f"| ${ln.latex_name}$ | ${ln.latex_rhs}$ |"
                                         for ln in lines]

    out = [f"{h} Defining relations", ""]
    out += [f"$${ln.latex()}$$" for ln in r.relations]
    if r.substitutions:
        out += ["", "with " + ", ".join(f"${ln.latex()}$" for ln in r.substitutions) + "."]
    for sec in r.sections:
        title = _md_math(sec.title)
        out += ["", f"{h} {title}" if sec.matrix else f"{title}.", ""]
        if sec.matrix:
            out += [r"$[u_{n-1}, f_n, 1]^T \to [u_n, f_{n+1}, 1]^T$ at mass $n$; $k_g$, $c_g$: its "
                    "spring and damper to the ground:", "",
                    f"$${_latex_matrix(sec.matrix)}$$", ""]
        if sec.lines:
            out += table(sec.lines)
        if sec.where:
            given = ", ".join(f"${ln.latex_name}$" for ln in sec.given)
            where = "where" + (f" ({given} as above)" if given else "")
            out += (["", where, ""] if sec.lines else [where, ""]) + table(sec.where)
    return "\n".join(out).replace("\n\n\n", "\n\n").strip() + "\n"
