"""The restricted force-law parser (runtime/expressions.py).

Evaluation is checked against values computed by hand (math module, written out term by term),
both with NumPy and through a casadi.Function; to_sympy against a hand-written SymPy expression;
and every refusal names the field and happens at parse time.
"""
import math
import os
import pickle
import re
import subprocess
import sys
import warnings

import casadi
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

from dtdyn.nonlinear._elements import NUMPY_OPS, Law, casadi_ops
from dtdyn.nonlinear._expressions import MAX_LENGTH, ParsedExpression, parse_expression

FIELD = "elements[2].expression"

# (text, constants, hand formula in plain math, hand formula in SymPy)
X, V, K, C = sp.symbols("x v k c")
CASES = [
    ("k*x**3 + c*v", {"k": 2.0, "c": 0.5},
     lambda x, v, k, c: k * x * x * x + c * v, K * X**3 + C * V),
    ("-x/2 + 2e7*v**2 - +3", {},
     lambda x, v: -0.5 * x + 20000000.0 * v * v - 3.0, -X / 2 + 20000000 * V**2 - 3),
    ("sqrt(abs(x))*sign(x) + exp(-v) - log(1 + x**2)", {},
     lambda x, v: math.copysign(math.sqrt(abs(x)), x) + math.exp(-v) - math.log(1 + x * x),
     sp.sqrt(sp.Abs(X)) * sp.sign(X) + sp.exp(-V) - sp.log(1 + X**2)),
    ("sin(x)*cos(v) + tan(x) - tanh(v) + sinh(x)/cosh(v) + atan(x*v)/pi", {},
     lambda x, v: (math.sin(x) * math.cos(v) + math.tan(x) - math.tanh(v)
                   + math.sinh(x) / math.cosh(v) + math.atan(x * v) / math.pi),
     (sp.sin(X) * sp.cos(V) + sp.tan(X) - sp.tanh(V) + sp.sinh(X) / sp.cosh(V)
      + sp.atan(X * V) / sp.pi)),
    ("k*max(x - c, 0) + k*min(x + c, 0)", {"k": 1e3, "c": 0.05},
     lambda x, v, k, c: k * (x - c if x > c else 0.0) + k * (x + c if x < -c else 0.0),
     K * sp.Max(X - C, 0) + K * sp.Min(X + C, 0)),
    ("2**-x**2", {}, lambda x, v: 2.0 ** (-(x * x)), 2 ** (-X**2)),  # ** binds right
]
POINTS = [(0.3, -1.2), (-0.7, 0.4), (0.02, 2.5), (1.1, -0.03)]


@pytest.mark.parametrize("text, consts, hand, _", CASES)
def test_numpy_scalars_match_hand_values(text, consts, hand, _):
    expr = parse_expression(text, constants=tuple(consts), name=FIELD)
    for x, v in POINTS:
        got = expr.evaluate(NUMPY_OPS, x=x, v=v, **consts)
        assert_allclose(got, hand(x, v, **consts), rtol=1e-14, atol=1e-300)


@pytest.mark.parametrize("text, consts, hand, _", CASES)
def test_numpy_arrays_match_hand_values(text, consts, hand, _):
    expr = parse_expression(text, constants=tuple(consts))
    x = np.array([p[0] for p in POINTS])
    v = np.array([p[1] for p in POINTS])
    got = expr.evaluate(NUMPY_OPS, x=x, v=v, **consts)
    assert_allclose(got, [hand(a, b, **consts) for a, b in POINTS], rtol=1e-14)


@pytest.mark.parametrize("text, consts, hand, _", CASES)
def test_casadi_function_matches_hand_values(text, consts, hand, _):
    expr = parse_expression(text, constants=tuple(consts))
    xs, vs = casadi.SX.sym("x"), casadi.SX.sym("v")
    g = expr.evaluate(casadi_ops(), x=xs, v=vs, **consts)
    assert isinstance(g, casadi.SX)
    f = casadi.Function("g", [xs, vs], [g])
    for x, v in POINTS:
        assert_allclose(float(f(x, v)), hand(x, v, **consts), rtol=1e-14)


@pytest.mark.parametrize("text, consts, _, hand", CASES)
def test_to_sympy_equals_hand_expression(text, consts, _, hand):
    got = parse_expression(text, constants=tuple(consts)).to_sympy()
    assert sp.simplify(got - hand) == 0


def test_to_sympy_keeps_integer_powers_and_takes_symbols():
    got = parse_expression("x**3").to_sympy()
    assert got.is_Pow and got.exp == 3 and got.exp.is_Integer
    y = sp.Symbol("y", real=True)
    assert parse_expression("x**3 + v").to_sympy({"x": y}) == y**3 + V


def test_names_are_the_declared_names_used():
    expr = parse_expression("k*x**3 + pi*sin(x)", constants=("k", "c"))
    assert expr.names == frozenset({"k", "x"})
    assert isinstance(expr, ParsedExpression) and expr.text == "k*x**3 + pi*sin(x)"


def test_numpy_semantics_for_python_floats():
    # literals and Python floats are computed as numpy.float64: inf/nan, not exceptions/complex
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert parse_expression("1/x").evaluate(NUMPY_OPS, x=0.0) == np.inf
        assert np.isnan(parse_expression("x**0.5").evaluate(NUMPY_OPS, x=-1.0))
    # a constant power too large for a float is refused at parse time (issue 12: it used to
    # evaluate to inf here, to an exact 10-billion-digit integer in SymPy)
    with pytest.raises(ValueError, match="constant exponent"):
        parse_expression("10**10**10")


@pytest.mark.parametrize("values, words", [
    (dict(x=1.0), ["missing", "k"]),
    (dict(x=1.0, k=2.0, y=3.0), ["unexpected", "y"]),
    (dict(x=1.0, k=2.0, pi=3.0), ["unexpected", "pi"]),
])
def test_evaluate_refuses_missing_and_extra_values(values, words):
    expr = parse_expression("k*x", constants=("k",), name=FIELD)
    with pytest.raises(ValueError) as err:
        expr.evaluate(NUMPY_OPS, **values)
    assert FIELD in str(err.value) and all(w in str(err.value) for w in words)


def test_declared_unused_values_are_accepted():
    # v is declared (default variables) but unused: giving it is fine, leaving it out too
    expr = parse_expression("2*x")
    assert expr.evaluate(NUMPY_OPS, x=1.5, v=9.0) == 3.0
    assert expr.evaluate(NUMPY_OPS, x=1.5) == 3.0


def test_pickle_round_trip():
    expr = parse_expression("k*x**3 + c*v", constants=("k", "c"), name=FIELD)
    back = pickle.loads(pickle.dumps(expr))
    assert back == expr and back.name == FIELD
    assert back.evaluate(NUMPY_OPS, x=0.1, v=2.0, k=2.0, c=0.5) == \
        expr.evaluate(NUMPY_OPS, x=0.1, v=2.0, k=2.0, c=0.5)


# (text, a piece the message must show)
REFUSED = [
    ('__import__("os")', "call to '__import__' is not allowed"),
    ("().__class__", "attribute access"),
    ("x.real", "attribute access"),
    ("open('f')", "call to 'open'"),
    ("lambda: 1", "lambda"),
    ("[x for x in y]", "comprehension"),
    ("x if v else 1", "conditional"),
    ("x < 1", "comparison"),
    ('"s"', "string"),
    ("sin(x, v)", "sin takes 1 argument, got 2"),
    ("max(x)", "max takes 2 arguments, got 1"),
    ("sin(x=1)", "keyword argument 'x='"),
    ("sin(*x)", "'*' unpacking"),
    ("x + y", "unknown name 'y'"),
    ("sin + 1", "'sin' is a function"),
    ("x % 2", "'%'"),
    ("x // 2", "'//'"),
    ("not x", "'not'"),
    ("x and v", "'and'/'or'"),
    ("(x := 1)", "':='"),
    ('f"{x}"', "f-string"),
    ("x[0]", "indexing"),
    ("1j", "complex"),
    ("True", "True/False"),
    ("1e999", "not finite"),
    ("x; v", "not a valid expression"),
    ("x = 1", "not a valid expression"),
    ("-" * 300 + "x", "nesting deeper"),
    ('__import__("os").system("echo hi")', "only the listed functions may be called"),
    ("", "is empty"),
    ("   ", "is empty"),
    ("x" + "+x" * (MAX_LENGTH // 2), f"the limit is {MAX_LENGTH}"),
    (3.0, "must be a string"),
    (None, "must be a string"),
]


@pytest.mark.parametrize("text, piece", REFUSED, ids=[repr(t)[:30] for t, _ in REFUSED])
def test_refused_with_the_field_named(text, piece):
    with pytest.raises(ValueError) as err:
        parse_expression(text, name=FIELD)
    msg = str(err.value)
    assert msg.startswith(FIELD) and piece in msg, msg


def test_length_limit_is_exact():
    ok = "x" + " " * (MAX_LENGTH - 1)
    assert parse_expression(ok).names == {"x"}
    with pytest.raises(ValueError, match="1001 characters"):
        parse_expression(ok + " ", name=FIELD)


def test_message_shows_the_offending_piece():
    with pytest.raises(ValueError, match=r"attribute access is not allowed \(at 'v\.real'\)"):
        parse_expression("x + v.real", name=FIELD)


@pytest.mark.parametrize("variables, constants, words", [
    (("x", "v"), ("x",), "declared twice"),
    (("x", "v"), ("pi",), "reserved"),
    (("x", "v"), ("sin",), "reserved"),
    (("x", "v"), ("a b",), "not a valid name"),
    (("x", "lambda"), (), "not a valid name"),
    (("x", 3), (), "not a valid name"),
])
def test_declared_names_are_checked(variables, constants, words):
    with pytest.raises(ValueError, match=words):
        parse_expression("x", variables=variables, constants=constants, name=FIELD)


def test_law_refuses_malicious_expression_at_construction():
    with pytest.raises(ValueError, match="Law.expression"):
        Law(0, expression='__import__("os").system("echo hi")')
    with pytest.raises(ValueError, match="Law.expression.*unknown name 'y'"):
        Law(0, 1, expression="k*y", k=1.0)


def test_law_constant_may_not_shadow_a_variable():
    with pytest.raises(ValueError, match="declared twice"):
        Law(0, expression="x", x=1.0)


def test_law_force_and_uses_velocity():
    law = Law(0, 1, expression="k*x**3 + c*v", k=2.0, c=0.5)
    assert_allclose(law.force(0.1, 2.0, [], NUMPY_OPS), 2 * 0.001 + 1.0, rtol=1e-15)
    assert law.uses_velocity is True
    assert Law(0, expression="k*x", k=1.0).uses_velocity is False
    assert sp.simplify(law.to_sympy() - (K * X**3 + C * V)) == 0


def test_imports_without_sympy():
    code = ("import sys; sys.modules['sympy'] = None; sys.modules['jinja2'] = None\n"
            "from dtdyn.nonlinear._expressions import parse_expression\n"
            "from dtdyn.nonlinear._elements import NUMPY_OPS\n"
            "print(parse_expression('k*x', constants=('k',)).evaluate(NUMPY_OPS, x=2.0, k=3.0))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ), timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert float(proc.stdout) == 6.0


@pytest.mark.parametrize("text, words", [
    ("9**9**9*x", "constant exponent 3.8742e+08 is larger than 64"),
    ("x**65", "constant exponent 65"),
    ("1e308*10*x", "not a finite float"),
    ("(1/0.0)*x", "not a finite float"),
    ("\uff58**3", "U+FF58"),                       # a fullwidth x, which Python reads as x
])
def test_constants_and_names_are_bounded(text, words):
    """Constant parts are folded in floats with limits (no exact 9**387420489, which used to
    hang to_sympy and overflow at run time); only plain ASCII is read."""
    with pytest.raises(ValueError, match=re.escape(words)):
        parse_expression(text)


def test_constant_names_are_ascii():
    with pytest.raises(ValueError, match="ASCII letters"):
        parse_expression("k*x", constants=("k\uff4b",))
    assert parse_expression("x**64 + 2.0**10*x").names == frozenset({"x"})
