"""A restricted parser for user force laws such as ``"k*x**3 + c*v"``.

Force laws arrive as text, from a scene's TOML file or from
``Law(i, j, expression="k*x**3 + c*v", k=..., c=...)``. That text is never handed to `eval`,
`exec`, `compile` or `sympy.sympify`: each of those runs arbitrary Python
(``__import__("os").system(...)``, ``().__class__.__mro__...``), and sympify itself calls eval.
Instead the text is parsed with ``ast.parse(text, mode="eval")`` (which builds a tree and runs
nothing), every node of the tree is checked against the whitelist below, and the checked tree is
walked to evaluate (NumPy or CasADi) or to build SymPy. Anything outside the whitelist is refused
with a ValueError at parse time, before anything runs.

Grammar accepted (Python's own precedence and associativity; ``**`` binds right)::

    expr     := expr ("+" | "-" | "*" | "/" | "**") expr
              | ("+" | "-") expr
              | "(" expr ")"
              | number                          int or float literal: 3, 0.5, 2e7
              | name                            a declared variable or constant, or pi
              | function "(" expr ")"
              | ("min" | "max") "(" expr "," expr ")"

Functions (`FUNCTIONS`), each with the attribute of the math namespace ``ops`` it calls
(`dtdyn.nonlinear._elements.NUMPY_OPS` or `~dtdyn.nonlinear._elements.casadi_ops`) and its SymPy
counterpart::

    sqrt exp log sin cos tan sinh cosh tanh      ops.<same name>     sympy.<same name>
    atan                                         ops.arctan          sympy.atan
    abs                                          ops.fabs            sympy.Abs
    sign                                         ops.sign            sympy.sign
    min(a, b), max(a, b)                         ops.fmin, ops.fmax  sympy.Min, sympy.Max

Refused: attributes (``x.real``), indexing, calls of anything else or with keywords or ``*args``,
lambda, comprehensions, comparisons, ``and``/``or``/``not``, ``a if c else b``, ``:=``,
strings and f-strings, True/False/None, complex literals, ``%``, ``//``, ``@``, bit operators,
undeclared names, empty text, text longer than `MAX_LENGTH` characters, nesting deeper than
`MAX_DEPTH` levels and more than `MAX_CONSTANTS` declared names. Parsing and checking take
time linear in the text and the number of names. Every message names the field (the ``name``
argument, e.g. ``"elements[2].expression"``) and shows the offending piece.

Example
-------
>>> from dtdyn.nonlinear._elements import NUMPY_OPS
>>> law = parse_expression("k*x**3 + c*v", constants=("k", "c"), name="Law.expression")
>>> sorted(law.names)
['c', 'k', 'v', 'x']
>>> float(law.evaluate(NUMPY_OPS, x=0.1, v=2.0, k=2.0, c=0.5))
1.002
"""
from __future__ import annotations

import ast
import keyword
import math
import operator
from dataclasses import dataclass, field

import numpy as np

from dtdyn._engine.extras import require

#: the longest text accepted (characters)
MAX_LENGTH = 1000
#: the deepest nesting of operations accepted (keeps every tree walk far from Python's
#: recursion limit; a sum of n terms nests n deep)
MAX_DEPTH = 200
#: the most named constants (and variables) an expression may declare: a text of at most
#: MAX_LENGTH characters cannot use more than MAX_LENGTH // 2 names
MAX_CONSTANTS = MAX_LENGTH // 2
#: the largest |exponent| a constant power may have (x**400 overflows for |x| > 6: no force law
#: needs more; 9**9**9 would otherwise be an exact integer of 370 million digits)
MAX_EXPONENT = 64

#: function name -> (number of arguments, attribute of ``ops``, SymPy name)
FUNCTIONS = {
    "sqrt": (1, "sqrt", "sqrt"),
    "exp": (1, "exp", "exp"),
    "log": (1, "log", "log"),
    "sin": (1, "sin", "sin"),
    "cos": (1, "cos", "cos"),
    "tan": (1, "tan", "tan"),
    "sinh": (1, "sinh", "sinh"),
    "cosh": (1, "cosh", "cosh"),
    "tanh": (1, "tanh", "tanh"),
    "atan": (1, "arctan", "atan"),
    "abs": (1, "fabs", "Abs"),
    "sign": (1, "sign", "sign"),
    "min": (2, "fmin", "Min"),
    "max": (2, "fmax", "Max"),
}
#: names that are always allowed (and so cannot be declared as variables or constants)
BUILTIN_NAMES = ("pi",)

_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNARYOPS = (ast.UAdd, ast.USub)
# how refused operators and nodes are named in messages
_OP_TEXT = {ast.Mod: "'%'", ast.FloorDiv: "'//'", ast.MatMult: "'@'", ast.LShift: "'<<'",
            ast.RShift: "'>>'", ast.BitOr: "'|'", ast.BitXor: "'^'", ast.BitAnd: "'&'",
            ast.Not: "'not'", ast.Invert: "'~'"}
_NODE_TEXT = {
    ast.Attribute: "attribute access", ast.Subscript: "indexing", ast.Lambda: "lambda",
    ast.ListComp: "a comprehension", ast.SetComp: "a comprehension",
    ast.DictComp: "a comprehension", ast.GeneratorExp: "a generator expression",
    ast.Compare: "a comparison", ast.BoolOp: "'and'/'or'",
    ast.IfExp: "a conditional expression (a if c else b)", ast.NamedExpr: "':=' assignment",
    ast.JoinedStr: "an f-string", ast.FormattedValue: "an f-string",
    ast.List: "a list", ast.Tuple: "a tuple", ast.Set: "a set", ast.Dict: "a dict",
    ast.Starred: "'*' unpacking", ast.Await: "'await'", ast.Yield: "'yield'",
    ast.YieldFrom: "'yield from'", ast.Slice: "a slice",
}


def _short(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


@dataclass(frozen=True, eq=False)
class _Parser:
    """Checks one tree against the whitelist; refusals name the field and the piece."""

    text: str
    name: str
    variables: tuple
    constants: tuple

    def refuse(self, problem: str, node=None):
        piece = ast.get_source_segment(self.text, node) if node is not None else None
        where = f" (at {_short(piece)!r})" if piece and piece.strip() != self.text else ""
        raise ValueError(f"{self.name} = {_short(self.text)!r}: {problem}{where}")

    def allowed_names(self) -> str:
        return ", ".join(self.variables + self.constants + BUILTIN_NAMES)

    def check(self, node, depth: int = 0) -> set:  # noqa: C901 (one branch per node type)
        """The declared names used under ``node``; ValueError for anything not whitelisted."""
        if depth > MAX_DEPTH:
            self.refuse(f"nesting deeper than {MAX_DEPTH} levels is not allowed")
        d = depth + 1
        if isinstance(node, ast.Expression):
            return self.check(node.body, d)
        if isinstance(node, ast.BinOp):
            if type(node.op) not in _BINOPS:
                self.refuse(f"operator {_OP_TEXT.get(type(node.op), type(node.op).__name__)} is "
                            "not allowed; allowed operators: + - * / **", node)
            used = self.check(node.left, d) | self.check(node.right, d)
            self.check_constants(node)
            return used
        if isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARYOPS:
                self.refuse(f"operator {_OP_TEXT.get(type(node.op), type(node.op).__name__)} is "
                            "not allowed; allowed operators: + - * / **", node)
            return self.check(node.operand, d)
        if isinstance(node, ast.Constant):
            value = node.value
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                kind = {str: "a string", bytes: "a bytes string", bool: "True/False",
                        complex: "a complex number"}.get(type(value), repr(value))
                self.refuse(f"{kind} is not allowed; only int and float numbers are", node)
            try:
                ok = math.isfinite(float(value))
            except OverflowError:
                ok = False
            if not ok:
                self.refuse(f"the number {_short(repr(value), 30)} is not finite as a float",
                            node)
            return set()
        if isinstance(node, ast.Name):
            if node.id in self.variables or node.id in self.constants:
                return {node.id}
            if node.id in BUILTIN_NAMES:
                return set()
            if node.id in FUNCTIONS:
                self.refuse(f"'{node.id}' is a function and must be called, as in "
                            f"{node.id}(x)", node)
            self.refuse(f"unknown name {node.id!r}; allowed names: {self.allowed_names()}", node)
        if isinstance(node, ast.Call):
            return self.check_call(node, d)
        text = _NODE_TEXT.get(type(node), f"'{type(node).__name__}'")
        self.refuse(f"{text} is not allowed", node)

    def check_constants(self, node: ast.BinOp) -> None:
        """Fold constant operands in floats: a constant exponent beyond MAX_EXPONENT, or a
        constant part that is not a finite float, is refused (no exact huge integers, ever)."""
        if isinstance(node.op, ast.Pow):
            exponent = _constant(node.right)
            if exponent is not None and abs(exponent) > MAX_EXPONENT:
                self.refuse(f"the constant exponent {exponent:g} is larger than {MAX_EXPONENT} "
                            "in magnitude", node)
        value = _constant(node)
        if value is not None and not math.isfinite(value):
            self.refuse("this constant part is not a finite float", node)

    def check_call(self, node: ast.Call, depth: int) -> set:
        listed = ", ".join(FUNCTIONS)
        if not isinstance(node.func, ast.Name):
            self.refuse("only the listed functions may be called, by name as in sin(x); "
                        f"allowed functions: {listed}", node)
        fn = node.func.id
        if fn not in FUNCTIONS:
            self.refuse(f"call to {fn!r} is not allowed; allowed functions: {listed}", node)
        for kw in node.keywords:
            what = "'**' unpacking" if kw.arg is None else f"keyword argument '{kw.arg}='"
            self.refuse(f"{what} in a call to {fn!r} is not allowed; pass arguments by "
                        "position", node)
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                self.refuse(f"'*' unpacking in a call to {fn!r} is not allowed", node)
        n = FUNCTIONS[fn][0]
        if len(node.args) != n:
            self.refuse(f"{fn} takes {n} argument{'s' if n > 1 else ''}, got "
                        f"{len(node.args)}", node)
        used = set()
        for arg in node.args:
            used |= self.check(arg, depth)
        return used


def _constant(node):
    """The float value of a constant subtree (numbers, + - * / ** of them, -x), inf when it
    overflows, None when it holds a name or a call."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        try:
            return float(node.value)
        except OverflowError:
            return math.inf
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARYOPS:
        value = _constant(node.operand)
        return None if value is None else (-value if isinstance(node.op, ast.USub) else value)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        a, b = _constant(node.left), _constant(node.right)
        if a is None or b is None:
            return None
        if isinstance(node.op, ast.Pow) and abs(b) > MAX_EXPONENT:
            return math.inf
        try:
            return float(_BINOPS[type(node.op)](a, b))
        except (OverflowError, ZeroDivisionError, ValueError):
            return math.inf
    return None


def check_count(field_name: str, n: int, kind: str = "constants") -> None:
    """ValueError when more than `MAX_CONSTANTS` names are declared (checked before any of them
    is looked at: an expression of at most `MAX_LENGTH` characters cannot use more)."""
    if n > MAX_CONSTANTS:
        raise ValueError(f"{field_name}: {n:,} {kind} declared; the limit is {MAX_CONSTANTS} "
                         f"(an expression of at most {MAX_LENGTH} characters cannot use more)")


def _names(kind: str, names, field_name: str) -> tuple:
    if isinstance(names, str):
        names = (names,)
    if hasattr(names, "__len__"):
        check_count(field_name, len(names), kind)
    try:
        names = tuple(names)
    except TypeError:
        raise ValueError(f"{field_name}: {kind} must be a list of names, got {names!r}") from None
    check_count(field_name, len(names), kind)
    for n in names:
        if not isinstance(n, str) or not n.isascii() or not n.isidentifier() \
                or keyword.iskeyword(n):
            raise ValueError(f"{field_name}: {kind[:-1]} name {n!r} is not a valid name "
                             "(ASCII letters, digits and _, not starting with a digit)")
        if n in FUNCTIONS or n in BUILTIN_NAMES:
            raise ValueError(f"{field_name}: {kind[:-1]} name {n!r} is reserved (a function "
                             "or pi); choose another name")
    return names


# -- the checked tree, compiled once into nested closures f(values, ops) (no eval) ----------

def _compile(node, number):
    """Closure tree for a checked node; ``number`` turns a literal into the leaf's value."""
    if isinstance(node, ast.Expression):
        return _compile(node.body, number)
    if isinstance(node, ast.BinOp):
        op, a, b = _BINOPS[type(node.op)], _compile(node.left, number), _compile(node.right,
                                                                                 number)
        return lambda vals, ops: op(a(vals, ops), b(vals, ops))
    if isinstance(node, ast.UnaryOp):
        a = _compile(node.operand, number)
        if isinstance(node.op, ast.UAdd):
            return a
        return lambda vals, ops: -a(vals, ops)
    if isinstance(node, ast.Constant):
        c = number(node.value)
        return lambda vals, ops: c
    if isinstance(node, ast.Name):
        if node.id == "pi":
            c = number(math.pi)
            return lambda vals, ops: c
        key = node.id
        return lambda vals, ops: vals[key]
    if isinstance(node, ast.Call):
        attr = FUNCTIONS[node.func.id][1]
        args = [_compile(a, number) for a in node.args]
        if len(args) == 1:
            (a,) = args
            return lambda vals, ops: getattr(ops, attr)(a(vals, ops))
        a, b = args
        return lambda vals, ops: getattr(ops, attr)(a(vals, ops), b(vals, ops))
    raise AssertionError(f"unchecked node {type(node).__name__}")  # _Parser.check refuses these


def _to_sympy(node, sym, sp):
    if isinstance(node, ast.Expression):
        return _to_sympy(node.body, sym, sp)
    if isinstance(node, ast.BinOp):
        a, b = _to_sympy(node.left, sym, sp), _to_sympy(node.right, sym, sp)
        return _BINOPS[type(node.op)](a, b)
    if isinstance(node, ast.UnaryOp):
        a = _to_sympy(node.operand, sym, sp)
        return a if isinstance(node.op, ast.UAdd) else -a
    if isinstance(node, ast.Constant):
        return sp.Integer(node.value) if isinstance(node.value, int) else sp.Float(node.value)
    if isinstance(node, ast.Name):
        return sp.pi if node.id == "pi" else sym[node.id]
    if isinstance(node, ast.Call):
        return getattr(sp, FUNCTIONS[node.func.id][2])(*(_to_sympy(a, sym, sp)
                                                         for a in node.args))
    raise AssertionError(f"unchecked node {type(node).__name__}")


@dataclass(frozen=True)
class ParsedExpression:
    """A checked force-law expression; build it with `parse_expression`.

    Attributes
    ----------
    text : str
        The text as given.
    names : frozenset of str
        The declared variables and constants the expression actually uses (not pi).
    variables, constants : tuple of str
        The names declared when parsing.
    name : str
        The field the text came from, used in error messages.
    """

    text: str
    names: frozenset
    variables: tuple
    constants: tuple
    name: str = field(default="expression", compare=False)
    _tree: ast.Expression = field(default=None, repr=False, compare=False)
    _numpy: object = field(default=None, repr=False, compare=False)
    _generic: object = field(default=None, repr=False, compare=False)
    _declared: frozenset = field(default=frozenset(), repr=False, compare=False)

    def __reduce__(self):
        # closures do not pickle: rebuild (and re-check) from the text
        return (parse_expression, (self.text, self.variables, self.constants, self.name))

    def evaluate(self, ops, **values):
        """The expression's value, computed by walking the checked tree with ``ops``.

        Parameters
        ----------
        ops : namespace
            The math functions: `dtdyn.nonlinear._elements.NUMPY_OPS` (floats and arrays; Python
            int/float values and the literals are computed as numpy.float64, so ``1/x`` at 0 is
            inf and ``x**0.5`` at x < 0 is nan, with NumPy's warnings) or
            ``casadi_ops()`` (CasADi SX/MX symbols or numbers).
        **values
            One value per name used (`names`); declared names that are not used may be given
            too. A missing or undeclared name is a ValueError.
        """
        keys = values.keys()
        if not (self.names <= keys and keys <= self._declared):
            missing = sorted(self.names - keys)
            extra = sorted(keys - self._declared)
            parts = []
            if missing:
                parts.append(f"missing value{'s' if len(missing) > 1 else ''} for "
                             f"{', '.join(missing)}")
            if extra:
                parts.append(f"unexpected value{'s' if len(extra) > 1 else ''} for "
                             f"{', '.join(extra)} (declared names: "
                             f"{', '.join(self.variables + self.constants)})")
            raise ValueError(f"{self.name} = {_short(self.text)!r}: {'; '.join(parts)}")
        if getattr(ops, "name", None) == "numpy":
            for k, v in values.items():
                if type(v) is float or type(v) is int:
                    values[k] = np.float64(v)
            return self._numpy(values, ops)
        return self._generic(values, ops)

    def to_sympy(self, symbols=None):
        """The expression in SymPy: each name a ``sympy.Symbol`` (or ``symbols[name]``).

        int literals become sympy.Integer (``x**3`` stays a power with an integer exponent),
        float literals sympy.Float, pi sympy.pi, abs/min/max Abs/Min/Max.
        """
        sp = require("sympy", "derive", "to_sympy")  # runtime/ imports without SymPy
        sym = {n: sp.Symbol(n) for n in self.variables + self.constants}
        sym.update(symbols or {})
        return _to_sympy(self._tree, sym, sp)


def parse_expression(text, variables=("x", "v"), constants=(), name="expression"):
    """Parse and check a force-law expression, running nothing.

    Parameters
    ----------
    text : str
        The expression, e.g. ``"k*x**3 + c*v"`` (grammar in the module docstring).
    variables : sequence of str
        The variables, by default the relative displacement x and velocity v.
    constants : sequence of str
        The named constants (their values are passed to `ParsedExpression.evaluate`).
    name : str
        The field the text came from, for messages: ``"Law.expression"``,
        ``"elements[2].expression"``.

    Returns
    -------
    ParsedExpression

    Raises
    ------
    ValueError
        Naming the field and the offending piece, for text that is not a string, is empty or
        longer than `MAX_LENGTH`, is not a Python expression, or uses anything outside the
        whitelist.
    """
    name = str(name)
    variables = _names("variables", variables, name)
    constants = _names("constants", constants, name)
    declared = variables + constants
    seen, twice = set(), set()  # linear in the number of names
    for n in declared:
        (twice if n in seen else seen).add(n)
    both = sorted(twice)
    if both:
        raise ValueError(f"{name}: {', '.join(both)} declared twice (variables {variables}, "
                         f"constants {constants})")
    if not isinstance(text, str):
        raise ValueError(f"{name} must be a string (an expression such as 'k*x**3 + c*v'), "
                         f"got {type(text).__name__} {_short(repr(text))}")
    if not text.strip():
        raise ValueError(f"{name} is empty; give an expression such as 'k*x**3 + c*v'")
    if len(text) > MAX_LENGTH:
        raise ValueError(f"{name} is {len(text)} characters long; the limit is {MAX_LENGTH}")
    if not text.isascii():  # Python would read fullwidth letters (NFKC) as the ASCII ones
        bad = next(ch for ch in text if not ch.isascii())
        raise ValueError(f"{name} = {_short(text)!r}: the character {bad!r} (U+{ord(bad):04X}) "
                         "is not allowed; write the expression in plain ASCII")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        col = f" (column {exc.offset})" if exc.offset else ""
        raise ValueError(f"{name} = {_short(text)!r} is not a valid expression: "
                         f"{exc.msg}{col}") from None
    except (ValueError, MemoryError, RecursionError) as exc:  # null bytes, absurd nesting
        raise ValueError(f"{name} = {_short(text)!r} is not a valid expression: "
                         f"{exc}") from None
    parser = _Parser(text.strip(), name, variables, constants)
    used = parser.check(tree)
    return ParsedExpression(text=text, names=frozenset(used), variables=variables,
                            constants=constants, name=name, _tree=tree,
                            _numpy=_compile(tree, lambda c: np.float64(c)),
                            _generic=_compile(tree, float),
                            _declared=frozenset(variables + constants))
