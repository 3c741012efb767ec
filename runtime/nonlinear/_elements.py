"""Localized nonlinear elements: a force law between DOF i and DOF j (or ground).

The equations of motion with localized nonlinear forces are

    M q'' + C q' + K q + L^T g(y, y', z) = f,    y = L q,   z' = h(y', z)

where each element e contributes one row of L (+1 at DOF i, -1 at DOF j, nothing for ground), so
y_e = q_i - q_j is its relative displacement and y'_e its relative velocity; the element pushes
DOF i with -g_e and DOF j with +g_e (a restoring force for g_e of the sign of y_e). Elements with
memory carry internal states z integrated with the step (Bouc-Wen's hysteretic displacement).

Each law is written once against a small math namespace (`NUMPY_OPS` or `casadi_ops()`), so the
same definition builds the CasADi residual of the per-step solve and evaluates the solve_ivp
reference. (`casadi_ops()` builds the CasADi namespace on first use.)

    Cubic(i, j=None, k3=...)                    g = k3 y^3
    Polynomial(i, j=None, coeffs=[c0, c1, ...]) g = sum_p coeffs[p] y^p
    Gap(i, j=None, gap=..., stiffness=...)      g = k (max(y - gap, 0) - max(-y - gap, 0))
    Law(i, j=None, expression="...", **consts)  g = expression in x, v and the constants
    BoucWen(i, j=None, stiffness=..., ...)      g = alpha k y + (1 - alpha) k z,
                                                z' = A y' - beta |y'| |z|^(n-1) z - gamma y' |z|^n
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from dtdyn._engine.extras import require
from dtdyn._engine.public import suggest, unknown_keyword


class _Ops:
    """The functions a force law may use, bound to NumPy floats or CasADi symbols."""

    def __init__(self, name, mod, fabs, fmax, fmin, log1p):
        self.name = name
        for fn in ("sqrt", "exp", "log", "sin", "cos", "tan", "tanh", "sinh", "cosh", "arctan",
                   "sign"):
            setattr(self, fn, getattr(mod, "atan" if (fn == "arctan" and name == "casadi")
                                      else fn))
        self.fabs, self.fmax, self.fmin, self.log1p = fabs, fmax, fmin, log1p


NUMPY_OPS = _Ops("numpy", np, np.abs, np.maximum, np.minimum, np.log1p)


def casadi_ops():
    """The CasADi namespace (imported on first use)."""
    ca = require("casadi", "nonlinear", "the nonlinear elements' CasADi laws")
    return _Ops("casadi", ca, ca.fabs, ca.fmax, ca.fmin, lambda x: ca.log(1 + x))


def _dof(name: str, value, allow_none: bool = False):
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} must be a 0-based DOF index (integer >= 0), got {value!r}")
    return int(value)


def _number(name: str, value, *, positive=False, nonnegative=False) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float range
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (positive and v <= 0) or (nonnegative and v < 0):
        need = "> 0" if positive else (">= 0" if nonnegative else "finite")
        raise ValueError(f"{name} must be finite and {need}, got {value!r}")
    return v


@dataclass(frozen=True)
class Element:
    """Base: DOFs i (and j, or ground when None); subclasses define `force` (and `rate`)."""

    i: int
    j: int | None = None

    #: number of internal states z (elements with memory)
    n_internal = 0
    #: whether g depends on the relative velocity
    uses_velocity = False

    def __post_init__(self):
        kind = type(self).__name__
        object.__setattr__(self, "i", _dof(f"{kind}.i", self.i))
        object.__setattr__(self, "j", _dof(f"{kind}.j", self.j, allow_none=True))
        if self.j == self.i:
            raise ValueError(f"{kind}: i and j are both DOF {self.i}; an element joins two "
                             "different DOFs (or one DOF and ground, j=None)")

    def force(self, y, v, z, ops):
        """g(y, y', z): the element pushes DOF i with -g and DOF j with +g."""
        raise NotImplementedError

    def rate(self, y, v, z, ops):
        """z' for the internal states (empty for elements without memory)."""
        return []

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.n_internal)

    def describe(self) -> str:
        where = f"DOF {self.i}" + (" - ground" if self.j is None else f" - DOF {self.j}")
        return f"{type(self).__name__} ({where})"


@dataclass(frozen=True)
class Cubic(Element):
    """Cubic spring g = k3 y^3 (N/m^3).

    Attributes
    ----------
    i, j : int, int or None
        The element acts on y = q_i - q_j (j None: between DOF i and the ground).
    k3 : float
        Cubic stiffness, N/m^3.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.Cubic(0, 1, k3=2e7).describe()
    'Cubic (DOF 0 - DOF 1)'
    """

    k3: float = field(default=None, kw_only=True)

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "k3", _number("Cubic.k3", self.k3))

    def force(self, y, v, z, ops):
        return self.k3 * y * y * y


@dataclass(frozen=True)
class Polynomial(Element):
    """Polynomial spring g = sum_p coeffs[p] y^p (numpy.polynomial order: coeffs[0] constant).

    Attributes
    ----------
    i, j : int, int or None
        The element acts on y = q_i - q_j (j None: between DOF i and the ground).
    coeffs : tuple of float
        c_0, c_1, ... of g = sum_p c_p y^p.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.Polynomial(2, coeffs=(0.0, 1e3, 0.0, 5e6)).describe()
    'Polynomial (DOF 2 - ground)'
    """

    coeffs: tuple = field(default=None, kw_only=True)

    def __post_init__(self):
        super().__post_init__()
        if self.coeffs is None or np.ndim(self.coeffs) != 1 or len(self.coeffs) == 0:
            raise ValueError(f"Polynomial.coeffs must be a non-empty list of numbers, got "
                             f"{self.coeffs!r}")
        c = tuple(_number(f"Polynomial.coeffs[{p}]", c) for p, c in enumerate(self.coeffs))
        object.__setattr__(self, "coeffs", c)

    def force(self, y, v, z, ops):
        g = self.coeffs[-1]
        for c in reversed(self.coeffs[:-1]):  # Horner
            g = g * y + c
        return g


@dataclass(frozen=True)
class Gap(Element):
    """Clearance of +-gap then a linear contact spring of ``stiffness`` (both sides).

    g = k (r(y - gap) - r(-y - gap)) with r(u) = max(u, 0); ``side`` "positive" or "negative"
    keeps one contact only. ``smoothing`` = delta > 0 replaces r by the softplus
    delta log(1 + e^(u/delta)) (C-infinity; contact force k delta log 2 at first touch), which
    helps Newton at a large dt; 0 keeps the exact kink.

    Attributes
    ----------
    i, j : int, int or None
        The element acts on y = q_i - q_j (j None: between DOF i and the ground).
    gap : float
        Clearance, m (>= 0).
    stiffness : float
        Contact stiffness, N/m.
    smoothing : float
        Softplus width, m (0: exact kink).
    side : {"both", "positive", "negative"}

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.Gap(0, gap=1e-3, stiffness=1e6).describe()
    'Gap (DOF 0 - ground)'
    """

    gap: float = field(default=None, kw_only=True)
    stiffness: float = field(default=None, kw_only=True)
    smoothing: float = field(default=0.0, kw_only=True)
    side: str = field(default="both", kw_only=True)

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "gap", _number("Gap.gap", self.gap, nonnegative=True))
        object.__setattr__(self, "stiffness", _number("Gap.stiffness", self.stiffness,
                                                      positive=True))
        object.__setattr__(self, "smoothing", _number("Gap.smoothing", self.smoothing,
                                                      nonnegative=True))
        if self.side not in ("both", "positive", "negative"):
            raise ValueError(f"Gap.side must be 'both', 'positive' or 'negative', got "
                             f"{self.side!r}")

    def _ramp(self, u, ops):
        d = self.smoothing
        if d == 0.0:
            return ops.fmax(u, 0.0)
        return ops.fmax(u, 0.0) + d * ops.log1p(ops.exp(-ops.fabs(u) / d))

    def force(self, y, v, z, ops):
        g = 0.0
        if self.side in ("both", "positive"):
            g = g + self._ramp(y - self.gap, ops)
        if self.side in ("both", "negative"):
            g = g - self._ramp(-y - self.gap, ops)
        return self.stiffness * g


@dataclass(frozen=True)
class Law(Element):
    """A user force law g(x, v): an arithmetic expression in x, v and named constants.

    The text is parsed by `dtdyn.nonlinear._expressions` (arithmetic, x, v, the constants given
    and a fixed list of functions); anything else is refused here, before anything runs.

    Attributes
    ----------
    i, j : int, int or None
        The element acts on y = q_i - q_j (j None: between DOF i and the ground).
    expression : str
        g(x, v), x = y and v = y'.
    constants : dict
        Named numbers used in the expression.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.Law(0, expression="c*v*abs(v)", c=0.5).describe()
    'Law (DOF 0 - ground)'
    """

    expression: str = field(default=None, kw_only=True)
    constants: dict = field(default_factory=dict, kw_only=True)

    def __init__(self, i, j=None, *, expression=None, **constants):
        object.__setattr__(self, "i", i)
        object.__setattr__(self, "j", j)
        object.__setattr__(self, "expression", expression)
        object.__setattr__(self, "constants", dict(constants))
        self.__post_init__()

    def __post_init__(self):
        from dtdyn.nonlinear._expressions import check_count, parse_expression
        super().__post_init__()
        check_count("Law", len(self.constants))  # before any constant is looked at
        for k, c in self.constants.items():
            if isinstance(c, str) and suggest(str(k), ("expression",)):
                raise unknown_keyword("Law", str(k), ("i", "j", "expression"))
        consts = {str(k): _number(f"Law constant {k}", c) for k, c in self.constants.items()}
        object.__setattr__(self, "constants", consts)
        parsed = parse_expression(self.expression, variables=("x", "v"),
                                  constants=tuple(consts), name="Law.expression")
        unused = sorted(set(consts) - set(parsed.names))
        if unused:
            raise TypeError(f"Law got the constant {unused[0]!r}, which Law.expression = "
                            f"{self.expression!r} does not use (a misspelled name?)")
        object.__setattr__(self, "_parsed", parsed)

    @property
    def uses_velocity(self):
        return "v" in self._parsed.names

    def force(self, y, v, z, ops):
        return self._parsed.evaluate(ops, x=y, v=v, **self.constants)

    def to_sympy(self):
        """The law as a SymPy expression in x, v and the constants' symbols."""
        return self._parsed.to_sympy()

    def __hash__(self):
        return hash((type(self), self.i, self.j, self.expression,
                     tuple(sorted(self.constants.items()))))


@dataclass(frozen=True)
class BoucWen(Element):
    """Bouc-Wen hysteresis (Wen 1976): a spring with memory.

        g = alpha k y + (1 - alpha) k z,
        z' = A y' - beta |y'| |z|^(n-1) z - gamma y' |z|^n,   z(0) = 0.

    k: initial stiffness; alpha: post- to pre-yield stiffness ratio; A, beta, gamma, n: the
    loop's shape (with A = 1 the ultimate z is (A / (beta + gamma))^(1/n), the yield
    displacement). z is integrated with the step (trapezoidal rule, solved with y).

    Attributes
    ----------
    i, j : int, int or None
        The element acts on y = q_i - q_j (j None: between DOF i and the ground).
    stiffness, alpha, A, beta, gamma, n : float
        As in the equations above.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.BoucWen(0, stiffness=1e4, beta=50.0, gamma=50.0).describe()
    'BoucWen (DOF 0 - ground)'
    """

    stiffness: float = field(default=None, kw_only=True)
    alpha: float = field(default=0.1, kw_only=True)
    A: float = field(default=1.0, kw_only=True)
    beta: float = field(default=None, kw_only=True)
    gamma: float = field(default=None, kw_only=True)
    n: float = field(default=1.0, kw_only=True)

    n_internal = 1
    uses_velocity = True

    def __post_init__(self):
        super().__post_init__()
        for name, kw in (("stiffness", dict(positive=True)), ("alpha", dict(nonnegative=True)),
                         ("A", {}), ("beta", {}), ("gamma", {}), ("n", dict(positive=True))):
            object.__setattr__(self, name, _number(f"BoucWen.{name}", getattr(self, name), **kw))
        if self.n < 1.0:
            raise ValueError(f"BoucWen.n must be >= 1, got {self.n!r}")
        if self.beta + self.gamma <= 0:
            raise ValueError(f"BoucWen: beta + gamma must be > 0 for a bounded loop, got beta = "
                             f"{self.beta!r}, gamma = {self.gamma!r}")

    def force(self, y, v, z, ops):
        return self.alpha * self.stiffness * y + (1.0 - self.alpha) * self.stiffness * z[0]

    def rate(self, y, v, z, ops):
        zz = z[0]
        az = ops.fabs(zz)
        if self.n == 1.0:
            return [self.A * v - self.beta * ops.fabs(v) * zz - self.gamma * v * az]
        p = az ** (self.n - 1.0)
        return [self.A * v - self.beta * ops.fabs(v) * p * zz - self.gamma * v * p * az]


def element_matrix(elements, n_dof: int) -> np.ndarray:
    """L (n_elements x n_dof): y = L q, and L^T g the elements' forces on the DOFs."""
    L = np.zeros((len(elements), n_dof))
    for e, el in enumerate(elements):
        for name, d in (("i", el.i), ("j", el.j)):
            if d is not None and d >= n_dof:
                raise ValueError(f"elements[{e}] ({type(el).__name__}).{name} = {d} is outside "
                                 f"the model's DOFs 0..{n_dof - 1}")
        L[e, el.i] = 1.0
        if el.j is not None:
            L[e, el.j] = -1.0
    return L


def check_elements(elements) -> tuple:
    """A tuple of Element objects (a clear error for anything else)."""
    if isinstance(elements, Element):
        elements = [elements]
    try:
        elements = tuple(elements)
    except TypeError:
        raise ValueError(f"elements must be a list of dtdyn elements (Cubic, Polynomial, Gap, "
                         f"Law, BoucWen), got {elements!r}") from None
    for e, el in enumerate(elements):
        if not isinstance(el, Element):
            raise ValueError(f"elements[{e}] = {el!r} is not a dtdyn element (Cubic, Polynomial, "
                             "Gap, Law, BoucWen)")
    return elements
