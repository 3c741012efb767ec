"""`DiscreteModel`: a discrete-time state-space model that carries its convention.

x_{n+1} = A x_n + B f_n,  y_n = C x_n + D f_n,  sampled every dt.

A raw (A, B, C, D) tuple cannot say what its state means. Every model dtdyn builds
(`newmark_ss`, `discrete_state_space`, `discretize`) removes the direct dependence on f_{n+1}
as SHARPy and scipy's first-order hold do, so its state is shifted by the input:
x_n = z_n - Gamma_1 f_n, with z_n the physical state. A zero state is then *not* rest when
f_0 != 0. The model knows its shift, so `initial_state` builds the state of a structure at rest
(or at given x0, v0) at t_0 under f_0, and `state_space_response` starts there by default.

The model is iterable as ``(A, B, C, D)`` for scipy and python-control:
``Ass, Bss, Css, Dss = newmark_ss(...)``, ``scipy.signal.dlsim((*model, model.dt), u)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING
from collections.abc import Callable

import numpy as np
import scipy.sparse

if TYPE_CHECKING:  # scipy.signal costs ~0.3 s to import: loaded by to_dlti only
    import scipy.signal

from dtdyn._engine import validate

__all__ = ["DiscreteModel"]


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """Discrete-time state-space model ``x_{n+1} = A x_n + B f_n, y_n = C x_n + D f_n``.

    Parameters
    ----------
    A, B, C, D : ndarray
        The matrices (iterating over the model yields them in this order).
    dt : float
        Sample step in seconds.
    state : str
        What the state x_n means (e.g. ``"[q; q'] - Dss f_n"``).
    quantities : tuple of str
        The output blocks, each ``n_dof`` rows: ``("x", "v")`` for y = [q; q'],
        ``("x", "v", "a")`` with q''. Empty for a model of unknown meaning.
    n_dof : int
        DOFs of the structure; the input f has one column per DOF.
    source : str
        Which function built the model and with which parameters.
    mass : ndarray, optional
        M of the structure when the model was built from M, C, K (support motion loads the
        model with -M r a_g).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.eye(2), 0.1 * np.eye(2), np.array([[2.0, -1.0], [-1.0, 1.0]])
    >>> model = dd.newmark_ss(M, C, K, 0.01, num_damp=0.0)
    >>> A, B, Cm, D = model                       # SHARPy's Ass, Bss, Css, Dss
    >>> r = dd.state_space_response(model, np.ones(101), force_dofs=[1])   # starts at rest
    >>> r.x.shape
    (101, 2)
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    state: str = "unspecified"
    quantities: tuple = ()
    n_dof: int = 0
    source: str = ""
    _physical_state: Callable | None = field(default=None, repr=False)
    mass: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self):
        A = _matrix("A", self.A)
        if A.shape[0] != A.shape[1]:
            raise ValueError(f"A must be square, got shape {A.shape}")
        B, C, D = (_matrix(name, value) for name, value in (("B", self.B), ("C", self.C),
                                                             ("D", self.D)))
        ns = A.shape[0]
        if B.shape[0] != ns:
            raise ValueError(f"B has {B.shape[0]} rows, expected {ns} to match A")
        if C.shape[1] != ns:
            raise ValueError(f"C has {C.shape[1]} columns, expected {ns} to match A")
        if D.shape != (C.shape[0], B.shape[1]):
            raise ValueError(f"D has shape {D.shape}, expected {(C.shape[0], B.shape[1])} "
                             "(rows of C, columns of B)")
        for name, value in (("A", A), ("B", B), ("C", C), ("D", D),
                            ("dt", validate.positive_scalar("dt", self.dt))):
            object.__setattr__(self, name, value)

    def __iter__(self):
        return iter((self.A, self.B, self.C, self.D))

    def __len__(self):
        return 4

    def __getitem__(self, i):
        return (self.A, self.B, self.C, self.D)[i]

    def __repr__(self):
        return (f"DiscreteModel({self.A.shape[0]} states, {self.B.shape[1]} inputs, "
                f"{self.C.shape[0]} outputs, dt={self.dt!r}, state={self.state!r}, "
                f"outputs={self.quantities!r}, from {self.source or 'user matrices'})")

    def initial_state(self, x0=None, v0=None, f0=None) -> np.ndarray:
        """The state x_0 of the structure with displacement ``x0``, velocity ``v0`` (rest when
        None) under the force ``f0`` at t_0 (every DOF; zero when None).

        For a model of unknown meaning (``quantities == ()``) only the zero state is defined.
        """
        if self._physical_state is None:
            if x0 is not None or v0 is not None:
                raise ValueError("this model's state has no stated meaning: x0, v0 cannot be "
                                 "mapped to it (build it with newmark_ss, discrete_state_space "
                                 "or discretize)")
            return np.zeros(self.A.shape[0])
        n = self.n_dof
        q0, qd0 = validate.initial_conditions(x0, v0, n)
        f = np.zeros(n) if f0 is None else validate.vector("f0", f0, length=n)
        return self._physical_state(q0, qd0, f)

    def simulate(self, force, state0=None, backend: str = "c", unstable: str = "raise"
                 ) -> np.ndarray:
        """The raw recursion: outputs y_n, shape (n_samples, rows of C), for inputs ``force``
        (n_samples, columns of B), from ``state0`` (zero when None). A model whose spectral
        radius exceeds 1 raises DtdynUnstableError (``unstable="warn"``: a warning, and it
        runs)."""
        from dtdyn.linear._state_space import _check_radius, run_recursion
        _check_radius(self, unstable)
        return run_recursion(self.A, self.B, self.C, self.D, force, state0, backend)

    def to_dlti(self) -> scipy.signal.dlti:
        """The model as a :class:`scipy.signal.dlti` with sample time ``dt``."""
        import scipy.signal  # deferred: `import dtdyn` does not load scipy.signal
        return scipy.signal.dlti(self.A, self.B, self.C, self.D, dt=self.dt)

    def to_control(self):
        """The model as a python-control ``StateSpace`` with sample time ``dt``."""
        from dtdyn._engine.extras import require
        control = require("control", None, "DiscreteModel.to_control")
        return control.StateSpace(self.A, self.B, self.C, self.D, self.dt)


def _matrix(name, value) -> np.ndarray:
    if scipy.sparse.issparse(value):
        value = value.toarray()
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real numeric matrix, "
                         f"got {type(value).__name__}") from None
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has a non-finite entry")
    return arr


def shifted(Phi, G0, G1, S, dt, *, state, quantities, n_dof, source, physical=None,
            mass=None):
    """The model of z_{n+1} = Phi z_n + G0 f_n + G1 f_{n+1}, y_n = S z_n with the state
    x_n = z_n - G1 f_n: A = Phi, B = G0 + Phi G1, C = S, D = S G1. ``physical(q0, v0, f0)``
    gives z_0; the model's initial state is z_0 - G1 f_0."""
    G1 = np.asarray(G1)

    def initial(q0, v0, f0):
        return physical(q0, v0, f0) - G1 @ f0

    return DiscreteModel(Phi, G0 + Phi @ G1, S, S @ G1, dt, state=state, quantities=quantities,
                         n_dof=n_dof, source=source,
                         _physical_state=None if physical is None else initial, mass=mass)
