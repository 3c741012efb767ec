"""A user's time integrator from a scheme file (TOML): parsed, checked, derived like the built-ins.

A scheme file states a scheme's defining relations as text; nothing in it is executed. Each
relation ``"lhs = rhs"`` is split at its one ``=`` and each side is parsed by the restricted
expression parser of the force laws (`dtdyn.nonlinear._expressions`: Python's ``ast`` tree checked
against an allow-list of numbers, names, + - * / **, and a few functions), then built in SymPy.
The result is an `integrators.Scheme`, the same value the built-ins are, and it goes through the
same derivation (`integrators.derive_scheme`), kernel specs and templates.

Symbols a relation may use: ``x0 v0 a0`` (t_n), ``x1 v1 a1`` (t_n+1), ``xe ve ae`` (the
equilibrium point, where M ae + C ve + K xe = Fe = w0 F_n + w1 F_n+1), ``dt``, the lags
``xm1 xm2 vm1 vm2 am1`` (t_n-1, t_n-2; a scheme that uses them is multistep and starts with
average-acceleration steps), the scheme's parameters and the names of its substitutions.

A composite scheme gives ``[[stage]]`` tables instead of ``relations``: each sub-step's
relations and force weights, run in turn within one step (``dt`` is the whole step in every
stage). A later stage's ``x0 v0 a0`` are the state the stage before left, its lags ``xm1 vm1
am1`` the state before that (the kernels shift the history after every sub-step).

Checks at load (each a ValueError of one line naming the relation or the field):

- unknown keys, names, symbols, or expressions outside the allow-list;
- a relation that is not linear in the new state (x1, v1, a1, xe, ve, ae);
- relations that leave part of the new state undetermined (named), or contradict each other
  (the relation whose removal restores consistency is named);
- parameter names that are not plain identifiers or collide with the kernels' own names (the
  names reach C and Python source: they are checked against every identifier of the templates
  and the hand-written C, and against C and Python keywords).
"""
from __future__ import annotations

import hashlib
import keyword
import re
import tomllib
from pathlib import Path

import sympy as sp

from dtdyn.nonlinear._expressions import parse_expression

from . import integrators as I

#: the most relations, parameters and substitutions a file may give
MAX_ITEMS = 32

STATE = {"x0": I.x0, "v0": I.v0, "a0": I.a0, "x1": I.x1, "v1": I.v1, "a1": I.a1,
         "xe": I.xe, "ve": I.ve, "ae": I.ae, "dt": I.dt,
         "xm1": I.xm1, "xm2": I.xm2, "vm1": I.vm1, "vm2": I.vm2, "am1": I.am1}
#: the unknowns of a step: the new state and the equilibrium point
NEW = (I.x1, I.v1, I.a1, I.xe, I.ve, I.ae)
LAGS = (I.xm1, I.xm2, I.vm1, I.vm2, I.am1)
KEYS = ("name", "title", "reference", "notes", "order", "relations", "force_weights",
        "parameters", "substitutions", "stage")
NAME = re.compile(r"^[a-z][a-z0-9_]{0,39}$")
#: the names the generator gives the per-run constants of a step (dtdyn.derive.kernels
#: constant_table: w0, p, r, alpha_u, q_x0, x1_u, ...; cse temporaries k0, t1, ...)
GENERATED = re.compile(r"[a-z]\d+|p|r|alpha_u|(q|s|b|x1|v1|a1)_\w+")

C_KEYWORDS = frozenset("""auto break case char const continue default do double else enum extern
float for goto if inline int long register restrict return short signed sizeof static struct
switch typedef union unsigned void volatile while _Bool _Complex""".split())


def reserved_names() -> frozenset:
    """Every identifier of the C the kernels are built from (templates and hand-written
    headers, comments left out), the scheme symbols, and Python's keywords and builtins: a
    parameter may take none of them, nor a name of the form the generator gives its own
    constants (`GENERATED`)."""
    from . import emit

    words = set()
    for folder in (emit.TEMPLATES / "c", emit.CSOURCES):
        for path in sorted(folder.iterdir()):
            code = re.sub(r"/\*.*?\*/|//[^\n]*|\{#.*?#\}", " ", path.read_text(), flags=re.S)
            words |= set(re.findall(r"[A-Za-z_]\w*", code))
    import builtins
    words |= set(dir(builtins)) | set(keyword.kwlist) | C_KEYWORDS | set(STATE)
    words |= {"np", "math", "form", "pi", "Omega", "zeta", "one", "A"}
    return frozenset(words)


def digest(text: str) -> str:
    """The content hash a scheme file is cached under."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def parse(path: str | Path) -> I.Scheme:
    """The `integrators.Scheme` a scheme file defines (checked; nothing derived yet)."""
    from dtdyn._engine.scheme_files import read_scheme_text

    return parse_text(read_scheme_text(path), str(path))


def parse_text(text: str, source: str = "<scheme>") -> I.Scheme:  # noqa: C901 (one check a key)
    """`parse` of a scheme file's text; ``source`` names it in messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: invalid TOML: {exc}") from None
    except RecursionError:
        raise ValueError(f"{source}: arrays or tables nested too deep") from None
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise ValueError(f"{source}: unknown key {unknown[0]!r}; allowed: {', '.join(KEYS)}")
    if "name" not in data:
        raise ValueError(f"{source}: name is required")
    name = data["name"]
    if not isinstance(name, str) or not NAME.match(name):
        raise ValueError(f"{source}: name = {name!r} must be lower-case letters, digits and _, "
                         "starting with a letter, at most 40 characters")
    if name in I.SCHEMES:
        raise ValueError(f"{source}: name = {name!r} is a built-in scheme; choose another name")
    text_fields = {k: data.get(k, "") for k in ("title", "reference", "notes")}
    for k, v in text_fields.items():
        if not isinstance(v, str) or len(v) > 500:
            raise ValueError(f"{source}: {k} must be a string of at most 500 characters")
    reserved = reserved_names()

    # parameters: [parameters.NAME] default = ..., range = [lo, hi]
    params_tbl = data.get("parameters", {})
    if not isinstance(params_tbl, dict) or len(params_tbl) > MAX_ITEMS:
        raise ValueError(f"{source}: parameters must be a table of at most {MAX_ITEMS} tables")
    params, defaults, ranges = [], {}, {}
    for p, spec in params_tbl.items():
        where = f"{source}: parameters.{p}"
        _identifier(where, p, reserved)
        if not isinstance(spec, dict) or set(spec) - {"default", "range"} or "default" not in spec:
            raise ValueError(f"{where} must be a table with default = <number> and optionally "
                             "range = [lo, hi]")
        default = _number(f"{where}.default", spec["default"])
        lo = hi = None                     # no range: any real value
        if "range" in spec:
            rng = spec["range"]
            if not isinstance(rng, list) or len(rng) != 2:
                raise ValueError(f"{where}.range = {rng!r} must be [lo, hi]")
            lo, hi = (_number(f"{where}.range", v) for v in rng)
            if not lo <= default <= hi:
                raise ValueError(f"{where}.default = {default!r} is outside range [{lo}, {hi}]")
        params.append(p)
        defaults[p] = default
        ranges[p] = (lo, hi)
    psyms = {p: sp.Symbol(p, real=True) for p in params}

    # substitutions: name = "expression in dt, the parameters and earlier substitutions"
    subs_tbl = data.get("substitutions", {})
    if not isinstance(subs_tbl, dict) or len(subs_tbl) > MAX_ITEMS:
        raise ValueError(f"{source}: substitutions must be a table of at most {MAX_ITEMS} "
                         "entries")
    subs, known = {}, dict(psyms)
    for key, expr_text in subs_tbl.items():
        where = f"{source}: substitutions.{key}"
        _identifier(where, key, set(STATE) | set(psyms) | set(keyword.kwlist), False)
        expr = _expression(where, expr_text, {**known, "dt": I.dt})
        sym = sp.Symbol(key, real=True)
        subs[sym] = expr
        known[key] = sym
    # substitutions may use earlier ones: resolve to the parameters alone
    resolved = {}
    for sym, expr in subs.items():
        resolved[sym] = sp.sympify(expr).subs(resolved)

    order = data.get("order", None)
    if order is not None and (not isinstance(order, int) or isinstance(order, bool)
                              or not 1 <= order <= 8):
        raise ValueError(f"{source}: order = {order!r} must be an integer from 1 to 8")

    if "stage" in data:   # a composite scheme: one table of relations per sub-step
        if "relations" in data or "force_weights" in data:
            raise ValueError(f"{source}: give relations and force_weights in each [[stage]], "
                             "not at the top level, in a composite scheme")
        tables = data["stage"]
        if not isinstance(tables, list) or not 2 <= len(tables) <= 4:
            raise ValueError(f"{source}: stage must be 2 to 4 tables [[stage]]")
        stages = []
        for k, tbl in enumerate(tables):
            where = f"{source}: stage[{k}]"
            if not isinstance(tbl, dict) or set(tbl) - {"relations", "force_weights"} \
                    or "relations" not in tbl:
                raise ValueError(f"{where} must be a table with relations = [...] and "
                                 "optionally force_weights = [w0, w1]")
            stages.append(_relations(where, tbl, known, resolved))
    else:
        if "relations" not in data:
            raise ValueError(f"{source}: relations is required (or [[stage]] tables)")
        stages = [_relations(source, data, known, resolved)]
    used = set().union(*(u for _, _, u in stages))
    unused = [p for p in params if psyms[p] not in used]
    if unused:
        raise ValueError(f"{source}: parameters.{unused[0]} is declared but no relation, "
                         "force weight or substitution uses it")
    lags = tuple(s for s in LAGS if s in used or (s == I.xm1 and I.xm2 in used)
                 or (s == I.vm1 and I.vm2 in used))
    for k, (_, _, part_used) in enumerate(stages if len(stages) > 1 else ()):
        deep = sorted(str(lag) for lag in set(LAGS) & part_used if int(str(lag)[2:]) > k)
        if deep:   # stage k's lag j is the state j sub-steps back: within the step for j <= k
            raise ValueError(f"{source}: stage[{k}] uses {', '.join(deep)}; in a composite "
                             f"scheme stage[{k}]'s lags reach back {k} sub-step(s), to the "
                             "start of the step (xm1 vm1 am1 the state before the stage)")
    common = dict(params=tuple(params), defaults=defaults, substitutions=resolved, lags=lags,
                  reference=text_fields["reference"], notes=text_fields["notes"], ranges=ranges)
    if len(stages) == 1:
        rel, w, _ = stages[0]
        return I.Scheme(name, text_fields["title"] or name, rel, w,
                        startup_steps=I.MULTISTEP_STARTUP if lags else 0, order=order or 0,
                        **common)
    parts = tuple(I.Scheme(f"{name}_s{k + 1}", f"{name}, stage {k + 1}", rel, w, **common)
                  for k, (rel, w, _) in enumerate(stages))
    return I.Scheme(name, text_fields["title"] or name, (), (0, 1), stages=parts,
                    order=order or 0, **common)


def _relations(source: str, tbl: dict, known: dict, resolved: dict) -> tuple:
    """(relations, force weights, symbols used) of one table: the file's, or a [[stage]]'s."""
    rel_list = tbl["relations"]
    if not isinstance(rel_list, list) or not rel_list or len(rel_list) > MAX_ITEMS:
        raise ValueError(f"{source}: relations must be a list of 1 to {MAX_ITEMS} strings "
                         "'lhs = rhs'")
    symbols = {**STATE, **known}
    relations = []
    for i, rel in enumerate(rel_list):
        where = f"{source}: relations[{i}]"
        if not isinstance(rel, str) or rel.count("=") != 1:
            raise ValueError(f"{where} = {rel!r} must be one equation 'lhs = rhs' (one '=')")
        lhs, rhs = rel.split("=")
        eq = sp.Eq(_expression(where, lhs, symbols), _expression(where, rhs, symbols))
        if eq in (sp.true, sp.false):
            raise ValueError(f"{where} = {rel!r} holds {'always' if eq else 'never'}: it is "
                             "not a relation")
        relations.append((where, rel, eq))
    weights = tbl.get("force_weights", ["0", "1"])
    if not isinstance(weights, list) or len(weights) != 2:
        raise ValueError(f"{source}: force_weights = {weights!r} must be two expressions "
                         "[w0, w1]: Fe = w0 F_n + w1 F_n+1")
    w = tuple(_expression(f"{source}: force_weights[{i}]", str(t) if isinstance(t, (int, float))
                          else t, known) for i, t in enumerate(weights))
    eqs = tuple(eq.subs(resolved) for _, _, eq in relations)
    _check_determined(source, relations, eqs)
    used = set().union(*(eq.free_symbols for eq in eqs)) | set().union(
        *(sp.sympify(x).subs(resolved).free_symbols for x in w))
    if I.vm2 in used and I.vm1 not in used or I.xm2 in used and I.xm1 not in used:
        raise ValueError(f"{source}: a relation uses xm2 or vm2 without xm1 or vm1")
    return tuple(eq for _, _, eq in relations), w, used


def _identifier(where: str, name: str, reserved, reaches_code: bool = True) -> None:
    if not (isinstance(name, str) and re.fullmatch(r"[a-z][a-z0-9_]{0,31}", name)):
        raise ValueError(f"{where}: the name {name!r} must be lower-case letters, digits and _, "
                         "starting with a letter, at most 32 characters")
    if name in reserved or reaches_code and GENERATED.fullmatch(name):
        raise ValueError(f"{where}: the name {name!r} is reserved (a symbol of the relations or a "
                         "name of the generated kernels); choose another name")


def _number(where: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
            or abs(value) == float("inf"):
        raise ValueError(f"{where} = {value!r} must be a finite number")
    return float(value)


def _expression(where: str, text, symbols: dict):
    names = tuple(symbols)
    parsed = parse_expression(text, variables=(), constants=names, name=where)
    expr = parsed.to_sympy(symbols)
    if _degree(expr) > MAX_DEGREE:   # expanding it would take forever (((a + b)**64)**8)
        raise ValueError(f"{where} = {text!r}: a power of degree above {MAX_DEGREE}; a scheme's "
                         "relations are polynomials of low degree")
    return expr


#: the highest polynomial degree an expression may reach when expanded
MAX_DEGREE = 64


def _degree(e) -> float:
    """An upper bound of the degree of ``e`` expanded as a polynomial (cheap: no expansion)."""
    if e.is_Number or not e.free_symbols:
        return 0
    if e.is_Symbol:
        return 1
    if e.is_Add:
        return max(_degree(a) for a in e.args)
    if e.is_Mul:
        return sum(_degree(a) for a in e.args)
    if e.is_Pow:
        base, exp = e.args
        return _degree(base) * (abs(int(exp)) if exp.is_Integer else 1) + _degree(exp)
    return max(_degree(a) for a in e.args)


def _check_determined(source: str, relations, eqs) -> None:
    """The relations determine the new state from the history and the equilibrium point's
    acceleration ae (the unknown the equilibrium equation fixes): linear in the new state,
    independent and consistent. ValueError naming the relation or the unknown otherwise."""
    unknowns = [s for s in NEW if s != I.ae]
    rows = []
    for (where, text, _), eq in zip(relations, eqs):
        expr = sp.expand(eq.lhs - eq.rhs)
        for s in NEW:
            if sp.diff(expr, s).free_symbols & set(NEW):
                raise ValueError(f"{where} = {text!r} is not linear in the new state "
                                 "(x1, v1, a1, xe, ve, ae)")
        rows.append([sp.diff(expr, s) for s in unknowns])
    Mx = sp.Matrix(rows)
    rank = Mx.rank(simplify=True)
    if rank < len(unknowns):
        free = [str(s) for s in _undetermined(Mx, unknowns)]
        raise ValueError(f"{source}: the relations do not determine "
                         f"{', '.join(free)} (given ae, the equilibrium point's acceleration): "
                         f"{len(relations)} relations of rank {rank}, {len(unknowns)} needed")
    if len(eqs) > len(unknowns):   # one too many: name the one the others contradict or repeat
        for i in reversed(range(len(eqs))):
            rest = [e for j, e in enumerate(eqs) if j != i]
            if Mx.extract([j for j in range(len(eqs)) if j != i],
                          list(range(len(unknowns)))).rank(simplify=True) < len(unknowns):
                continue                  # the others alone do not determine the step
            sol = sp.solve(rest, unknowns, dict=True)
            where, text, _ = relations[i]
            if sol and sp.simplify((eqs[i].lhs - eqs[i].rhs).subs(sol[0])) != 0:
                raise ValueError(f"{where} = {text!r} contradicts the other relations")
            raise ValueError(f"{where} = {text!r} is redundant: the other relations determine "
                             "the step")


def _undetermined(Mx: sp.Matrix, unknowns) -> list:
    """The unknowns a null vector of ``Mx`` moves (those the relations leave free)."""
    free = []
    for vec in Mx.nullspace(simplify=True):
        free += [u for u, c in zip(unknowns, vec) if sp.simplify(c) != 0 and u not in free]
    return free


# --- derivation and checks -------------------------------------------------------------------

#: test problems for the order of accuracy: (Omega_0, zeta, z_0) with z_0 a root of
#: z^2 + 2 zeta Omega_0 z + Omega_0^2 = 0 (x = exp(z t / dt) solves the equation exactly):
#: undamped, and over-damped so that velocity-proportional errors show
ORDER_PROBES = ((sp.Integer(2), sp.Integer(0), 2 * sp.I),
                (sp.Integer(2), sp.Rational(5, 4), sp.Integer(-1)))


def order_of_accuracy(scheme: I.Scheme, params: dict | None = None, highest: int = 6) -> int:
    """The order p of the local truncation error, from the characteristic polynomial
    P(lambda) = det(lambda I - A(Omega, zeta)) of the amplification matrix: with the exact
    solution's growth lambda = exp(z), z = s dt, P(e^z) = O(dt^(p + 2)) (the truncation error
    of the equivalent multistep form, divided by dt^2 like x''; Hilber & Hughes 1978). Taylor
    series in a scale eps of Omega and z at the ``params`` (default: the scheme's defaults)."""
    from . import stability

    values = {sp.Symbol(p, real=True): sp.nsimplify(v)
              for p, v in {**scheme.defaults, **(params or {})}.items()}
    A = stability.amplification_matrix(scheme).subs(values)
    eps = sp.Symbol("eps", positive=True)
    n = A.shape[0]
    lowest = highest + 2
    for Om0, zeta0, z0 in ORDER_PROBES:
        Ae = A.subs({stability.Omega: eps * Om0, stability.zeta: zeta0})
        lam = sp.exp(eps * z0)
        M = (lam * sp.eye(n) - Ae).applyfunc(
            lambda e: sp.series(e, eps, 0, highest + 3).removeO())  # noqa: B023 (used at once)
        P = sp.expand(M.det(method="berkowitz"))
        P = sp.series(P, eps, 0, highest + 3).removeO()
        powers = [k for k in range(highest + 3) if sp.simplify(P.coeff(eps, k)) != 0]
        lowest = min(lowest, powers[0] if powers else highest + 2)
    return lowest - 2


def build(text: str, source: str) -> tuple[I.Scheme, dict[str, str]]:
    """Parse, check and derive a scheme file: the `Scheme` and {file name: text} of what the
    runtime loads (scheme_<name>.py, stability_<name>.py, chain_<name>.c, shaft_<name>.c,
    scheme_<name>.md, table.json)."""
    import json

    from . import emit, kernels

    scheme = parse_text(text, source)
    src = f"scheme file {scheme.name!r} (sha256 {digest(text)[:16]})"
    try:
        specs = [kernels.scheme_spec(part) for part in scheme.stages or (scheme,)]
    except ValueError as exc:  # not affine in the primary unknown, ...
        raise ValueError(f"{source}: the relations do not give a step of the form the kernels "
                         f"take: {exc}") from None
    files = emit.render_scheme(scheme, src)
    order = order_of_accuracy(scheme)
    if scheme.order and scheme.order != order:
        raise ValueError(f"{source}: order = {scheme.order} is claimed, but the local truncation "
                         f"error's series gives order {order} at the default parameters")
    row = I.table_row(scheme)
    row.update(order=order, name=scheme.name, history=list(specs[0].history), sha256=digest(text),
               claimed_order=scheme.order or None)
    files["table.json"] = json.dumps(row, indent=1) + "\n"
    return scheme, files
