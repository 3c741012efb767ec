"""Models that solve many times: the solver layer under every linear time-history function.

A model (`Matrices`, `Chain`) is checked once when it is made. ``model.solver(dt, ...)``
resolves the scheme, checks its stability limit against the model's highest mode, factorizes
what the step needs and loads its compiled kernel: the cost of a run that does not depend on
the load. ``solver.run(force, ...)`` then runs one load case (force, initial conditions, support
motion) and may be called any number of times; `mck_response` and `chain_response` are one
``solver(...)`` and one ``run(...)``.

The preparation every run shares lives here, once: the output selection and the backend check
(`Solver.__init__`), the support motion, the force and the initial conditions (`load_case`),
the time loop (`dtdyn._engine.stepping.integrate`) and the absolute motion of the result.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


from dtdyn._engine import ground as support
from dtdyn._engine import stepping
from dtdyn._engine import validate
from dtdyn._engine.public import public
from dtdyn._engine.result import Response
from dtdyn._engine.schemes import SchemeInfo, get_scheme
from dtdyn.linear._stability import check_dt

#: the backends of the linear solvers
BACKENDS = ("c", "numpy")

#: the solvers of models with localized nonlinear elements, by model class name:
#: ``NONLINEAR["Matrices"](model, dt, elements=..., **options)``. dtdyn.nonlinear fills it when
#: it is imported (`dtdyn.nonlinear._solver.register`; ``import dtdyn`` imports it): the layers
#: keep dtdyn.linear from importing dtdyn.nonlinear
NONLINEAR: dict = {}


def nonlinear_solver(model, dt, elements, **options):
    """``model.solver(dt, elements=..., **options)``: the nonlinear solver `NONLINEAR` holds
    for the model's class (the options that are None take its defaults; the factory refuses
    the linear solvers' own options). Without elements: None, after refusing any option that
    is not None (the nonlinear options given to a linear solver)."""
    name = type(model).__name__
    if elements is None:  # a linear solver: no nonlinear option may be given
        given = [k for k, v in options.items() if v is not None]
        if given:
            raise ValueError(f"{given[0]}={options[given[0]]!r} is an option of the solvers with "
                             "elements (the nonlinear functions'); this solver has no elements")
        return None
    options = {k: v for k, v in options.items() if v is not None}
    make = NONLINEAR.get(name)
    if make is None:
        if not NONLINEAR:
            raise RuntimeError("elements= needs dtdyn.nonlinear, which registers the nonlinear "
                               "solvers when imported: import dtdyn (or dtdyn.nonlinear) first")
        raise TypeError(f"{name}.solver takes no elements (nonlinear solvers: "
                        f"{', '.join(sorted(NONLINEAR))})")
    return make(model, dt, elements=elements, **options)


def check_backend(backend) -> str:
    """``backend`` if it is one of `BACKENDS`, else a ValueError naming it."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be 'c' or 'numpy', got {backend!r}")
    return backend


class LoadCase(NamedTuple):
    """One run's checked inputs: the force on the DOFs ``loaded`` (with the support motion's
    effective load), the initial state, the force vector f_0 at t_0 and the ground record."""

    force: np.ndarray
    loaded: np.ndarray
    x0: np.ndarray
    v0: np.ndarray
    f0: np.ndarray
    ground: support.Ground | None


def load_case(M, n_dof: int, dt: float, force, force_dofs=None, x0=None, v0=None,
              ground_acceleration=None, ground_velocity=None, ground_displacement=None,
              influence=None, names=None, rigid=None) -> LoadCase:
    """The `LoadCase` of one run of a model with mass matrix ``M`` (for the support motion's
    load f - M r a_g): the ground record turned into a load, the force and ``force_dofs``
    checked, the initial conditions checked (rest when None), f_0 scattered to every DOF.
    A model whose DOFs have ``names`` (a beam, a shaft) takes them in ``force_dofs``, and
    ``rigid(n_dir)``, its rigid-body pattern, is the default influence of a ground record."""
    if names is None:
        force, force_dofs, ground = support.prepare(
            M, force, force_dofs, n_dof, ground_acceleration, influence, dt=dt,
            ground_velocity=ground_velocity, ground_displacement=ground_displacement)
    else:
        force, force_dofs, ground = support.prepare_model(
            M, force, force_dofs, names, rigid, dt=dt, ground_acceleration=ground_acceleration,
            ground_velocity=ground_velocity, ground_displacement=ground_displacement,
            influence=influence)
    force, dt, loaded = validate.time_history(force, dt, force_dofs, n_dof)
    x0, v0 = validate.initial_conditions(x0, v0, n_dof)
    f0 = np.zeros(n_dof)
    f0[loaded] = force[0]
    return LoadCase(force, loaded, x0, v0, f0, ground)


def schemes_of_run(scheme: SchemeInfo) -> list:
    """The schemes a run steps with: the start-up scheme of a multistep scheme (as
    `stepping.integrate` resolves it), then the scheme itself."""
    if scheme.stages:  # a composite scheme: its sub-steps (stepping.integrate)
        return list(scheme.stages)
    first = [scheme.startup()] if scheme.startup_steps else []
    return first + [scheme]


def scheme_key(scheme: SchemeInfo) -> tuple:
    return scheme.name, tuple(sorted(scheme.params.items()))


class Model:
    """The protocol of dtdyn's linear models: ``n_dof`` and ``solver(dt, ...)``, which returns
    a `Solver` of the model at the sample step ``dt``. `Matrices`, `Chain`, `Beam` and `Shaft`
    follow it (a model with ``dof_names`` takes them in ``outputs`` and ``force_dofs``)."""

    @property
    def n_dof(self) -> int:
        raise NotImplementedError

    def solver(self, dt, **options) -> Solver:
        raise NotImplementedError


class Solver:
    """A model prepared for one sample step and scheme; `run` runs one load case.

    Made by a model's ``solver`` method (`Matrices.solver`, `Chain.solver`, `Beam.solver`,
    `Shaft.solver`), which checks the options, the stability limit, factorizes and loads the
    compiled kernel once; each `run` then costs the time loop and the checks of its own
    inputs. ``mck_response(M, C, K, force, dt, **kw)`` is ``Matrices(M, C, K).solver(dt,
    ...).run(force, ...)``, bitwise (and so are `chain_response`, `beam_response` and
    `shaft_response` with their models).

    Thread safety: `run` may be called from several threads at once on one solver. A run reads
    the solver's factors and kernels and allocates its own history, outputs and scratch; the
    C loops release the GIL, so load cases on two threads run on two cores. A Ctrl-C in the
    main thread stops the C loops of every thread (each then raises).

    Parameters
    ----------
    model : Model
        The model; its ``n_dof`` sizes the checks (its ``dof_names``, where it has them, name
        the DOFs of ``outputs`` and of each run's ``force_dofs``).
    dt : float
        Sample step, s, > 0.
    scheme : str
        A scheme of the scheme table.
    form : {"acceleration", "displacement"} or None
        The step's unknown (None: "displacement", or "acceleration" for an explicit scheme).
    backend : {"c", "numpy"}
        The implementation.
    outputs : sequence of int or None
        Stored DOFs (None: all).
    quantities : subset of ("x", "v", "a")
        Stored quantities.
    unstable : {"raise", "warn"}
        A step beyond the scheme's stability limit is refused or warned about.
    omega_max : float, callable or None
        The model's highest natural frequency (rad/s), or ``omega_max(limit)`` giving it or a
        bound <= limit (`dtdyn.linear._stability.check_dt`).
    scheme_params : dict
        The scheme's parameters.

    Attributes
    ----------
    model : Model
        The model (`Matrices`, `Chain`, `Beam` or `Shaft`).
    dt : float
        The sample step, s.
    scheme : str
        The resolved scheme's name (``newmark`` with ``beta=0`` is ``central_difference``).
    params : dict
        The scheme's parameters, defaults filled in.
    form : str
        ``"acceleration"`` or ``"displacement"``: the primary unknown of the step.
    outputs : ndarray of int
        The stored DOFs.
    quantities : tuple of str
        The stored quantities, of ``("x", "v", "a")``.
    backend : str
        The backend asked for (``info["backend"]`` of a result says which one ran).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = dd.chain_matrices([2.0, 3.0], [20.0, 15.0], [5.0, 6.0])
    >>> solver = dd.Matrices(M, C, K).solver(0.02, scheme="hht", alpha=-0.1)
    >>> steps = [solver.run(np.full(101, f), force_dofs=[1]) for f in (1.0, 2.0)]
    >>> bool(np.allclose(steps[1].x, 2 * steps[0].x))
    True
    """

    def __init__(self, model: Model, dt, scheme, form, backend, outputs, quantities, unstable,
                 omega_max, scheme_params: dict):
        n = model.n_dof
        self.model = model
        self.backend = check_backend(backend)
        self.dt = validate.positive_scalar("dt", dt)
        self._names = getattr(model, "dof_names", None)
        self.outputs = validate.dof_indices("outputs", outputs, n, names=self._names)
        self.quantities = stepping.check_quantities(quantities)
        self._info = get_scheme(scheme, **scheme_params)
        if form is None:  # the displacement form; an explicit scheme has only the acceleration form
            form = "acceleration" if self._info.explicit else "displacement"
        if form not in ("acceleration", "displacement"):
            raise ValueError(f"form must be 'displacement' or 'acceleration', got {form!r}")
        self.form = form
        check_dt(self._info, self.dt, omega_max, unstable)
        self._ground_mass = None  # M of the support motion's load, set by the subclass
        self._rigid = None  # a named model's rigid-body pattern rigid(n_dir), set by the subclass
        self._stored = self.outputs  # the stepped state's rows stored (a beam's differ)

    @property
    def scheme(self) -> str:
        return self._info.name

    @property
    def params(self) -> dict:
        return dict(self._info.params)

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self._info.params.items())
        return (f"<{type(self).__name__} of {self.model!r}: dt={self.dt!r}, "
                f"scheme={self.scheme!r}{', ' if params else ''}{params}, "
                f"form={self.form!r}, backend={self.backend!r}>")

    @public
    def run(self, force, *, force_dofs=None, x0=None, v0=None, ground_acceleration=None,
            ground_velocity=None, ground_displacement=None, influence=None,
            progress=False) -> Response:
        """Run one load case: the time history of the model under ``force`` from (x0, v0).

        Parameters
        ----------
        force : array_like, shape (n_steps + 1, len(force_dofs))
            Samples at t_k = k dt, k = 0 .. n_steps (a 1-D array is one column); may be None
            with a ground record.
        force_dofs : sequence of int, optional
            0-based DOFs the force columns act on (all DOFs when None).
        x0, v0 : (N,) array_like, optional
            Initial displacement and velocity (rest when None); the initial acceleration is
            the consistent one, a_0 = M^-1 (f_0 - C v_0 - K x_0).
        ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
            Support acceleration at the force's times, linear between samples: the DOFs are
            then relative to the support, loaded by f - M r a_g, and the result adds
            ``a_abs``.
        ground_velocity, ground_displacement : array_like, optional
            Instead of ``ground_acceleration`` (one ground record at most): the support
            velocity (m/s) or displacement (m), turned into the acceleration record linear
            between samples whose motion passes through it (`ground_acceleration_from`); a
            displacement record also gives ``x_abs = x + r u_g``.
        influence : (N,) or (N, n_dir) array_like, optional
            r, each DOF's motion per unit support motion (default: ones).
        progress : bool
            Show a progress bar (tqdm) on long runs.

        Returns
        -------
        Response
            ``t`` and ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)) (None where not
            in ``quantities``).

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> solver = dd.Chain([2.0, 3.0], [20.0, 15.0], [5.0, 6.0]).solver(0.02)
        >>> solver.run(np.ones(501), force_dofs=[1]).x.shape
        (501, 2)
        """
        case = self._load_case(force, force_dofs, x0, v0, ground_acceleration, ground_velocity,
                               ground_displacement, influence)
        res = stepping.integrate(self._info, self.form, self.dt, case.force,
                                 self._initial_state(case), self._stepper(case.loaded),
                                 self._stored, self.quantities, progress)
        self._annotate(res)
        return support.finish(res, case.ground)

    def _load_case(self, force, force_dofs, x0, v0, *ground) -> LoadCase:
        """The checked `LoadCase` of one run (`load_case`; ``ground``: the acceleration,
        velocity and displacement records and the influence)."""
        return load_case(self._ground_mass, self.model.n_dof, self.dt, force, force_dofs, x0, v0,
                         *ground, names=self._names, rigid=self._rigid)

    def _initial_state(self, case: LoadCase) -> tuple:
        """(x_0, v_0, a_0) of the stepped state (a_0 the consistent one)."""
        return case.x0, case.v0, self._initial_acceleration(case)

    # what a model's solver supplies
    def _initial_acceleration(self, case: LoadCase) -> np.ndarray:
        raise NotImplementedError

    def _stepper(self, loaded) -> stepping.MakeAdvance:
        """The ``make_advance(scheme, coefficients)`` of one run, force on ``loaded``."""
        raise NotImplementedError

    def _annotate(self, res: Response) -> None:
        """Add the solver's own entries to ``res.info`` (and warn about the run)."""
