"""Deterministic printing of SymPy expressions for the NumPy and C templates."""
from __future__ import annotations

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.pycode import PythonCodePrinter


def _small_power(printer, expr, mul):
    base, exp = expr.as_base_exp()
    if exp.is_Integer and 2 <= abs(exp) <= 4:
        b = printer.parenthesize(base, sp.printing.precedence.PRECEDENCE["Mul"] + 1)
        prod = mul.join([b] * int(abs(exp)))
        return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
    return None


class CPrinter(C99CodePrinter):
    """C99 with x**2 -> x*x and rationals as double literals."""

    def _print_Pow(self, expr):
        return _small_power(self, expr, "*") or super()._print_Pow(expr)

    def _print_Rational(self, expr):
        return f"({float(expr.p)!r}/{float(expr.q)!r})"


class NumPyPrinter(PythonCodePrinter):
    """Plain arithmetic that works on floats and ndarrays alike."""

    def _print_Pow(self, expr):
        return _small_power(self, expr, "*") or super()._print_Pow(expr)

    def _print_Rational(self, expr):
        return f"({float(expr.p)!r}/{float(expr.q)!r})"

    def _print_Integer(self, expr):
        return f"{float(expr)!r}"


class ArrayPrinter(NumPyPrinter):
    """`NumPyPrinter` whose functions are NumPy's (``np.sqrt``, ``np.minimum``, ...): for the
    generated code that evaluates on arrays (amplification matrices over Omega) or that a scheme
    file's expressions reach. The built-in schemes use none, so their code is the same."""

    _RENAMED = {"atan": "arctan", "asin": "arcsin", "acos": "arccos"}

    def _module_format(self, fqn, register=True):
        if fqn.startswith("math."):
            name = fqn[5:]
            return "np." + self._RENAMED.get(name, name)
        return super()._module_format(fqn, register)

    def _print_Min(self, expr):
        return self._nested("np.minimum", expr.args)

    def _print_Max(self, expr):
        return self._nested("np.maximum", expr.args)

    def _print_sign(self, expr):
        return f"np.sign({self._print(expr.args[0])})"

    def _nested(self, fn, args):
        out = self._print(args[0])
        for a in args[1:]:
            out = f"{fn}({out}, {self._print(a)})"
        return out


_C, _PY, _ARRAY = CPrinter(), NumPyPrinter(), ArrayPrinter()


def c(expr) -> str:
    return _C.doprint(sp.sympify(expr))


def py(expr) -> str:
    return _PY.doprint(sp.sympify(expr))


def py_array(expr) -> str:
    """`py` with NumPy's functions (`ArrayPrinter`)."""
    return _ARRAY.doprint(sp.sympify(expr))


def cse_assignments(rows, prefix="t"):
    """One joint cse() over named outputs: ([(tmp, expr)...], [(name, expr)...]), deterministic."""
    names = [n for n, _ in rows]
    exprs = [sp.sympify(e) for _, e in rows]
    symbols = sp.numbered_symbols(prefix)
    temps, reduced = sp.cse(exprs, symbols=symbols, order="canonical")
    return temps, list(zip(names, reduced))
