"""Nonlinear solvers: ``Matrices(M, C, K).solver(dt, elements=[...], ...)``.

The solver of a model with localized nonlinear elements does, once, what every call of
`nonlinear_mck_response` did before its time loop: it checks the options and the elements,
builds the element laws' residual and the C loop (`_response._c_runner`, compiled once and
cached) and the linear step of the scheme (`dtdyn.nonlinear._linear_step.linear_step`: the
modal decomposition, the polynomial weights, or the scheme's one-step model) with the C
loop's matrices. ``run(force, ...)`` then checks its own inputs (force, initial conditions,
ground record), sets the initial state and runs the loop; `nonlinear_mck_response` is one
solver and one run (bitwise the same results).

The linear step's input matrix holds the loaded DOFs' columns (U = [I[:, force_dofs], -L^T]),
so a step is built per distinct ``force_dofs`` of the runs: at construction for every DOF,
then at the first run with other ``force_dofs`` (kept in the solver for the next runs).

dtdyn.linear does not import this room (the layers); `register` puts the solver in
`dtdyn.linear._solver.NONLINEAR` when this module is imported, which `import dtdyn` does.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from dtdyn._engine import ground as support
from dtdyn._engine import linalg
from dtdyn._engine import validate
from dtdyn._engine.errors import DtdynKernelError
from dtdyn._engine.public import public
from dtdyn._engine.result import Response
from dtdyn._engine.stepping import check_quantities
from dtdyn.generated import c_api
from dtdyn.linear._solver import NONLINEAR
from dtdyn.nonlinear import _response as core
from dtdyn.nonlinear._elements import check_elements, element_matrix
from dtdyn.nonlinear._linear_step import EXPLICIT, THETA_LIMIT, linear_step


#: ``force_dofs`` of a solver that builds no step before its first run (nonlinear_mck_response:
#: the run's loaded DOFs are known only once its force and ground record are checked)
LAZY = object()


@dataclass(frozen=True)
class _Plan:
    """What the runs with one set of loaded DOFs share: the linear step (its output rows
    selected), the C loop with its matrices and their addresses (``mats``, the
    forces-before-t_0 slot None), or None on the casadi backend (or without a compiler)."""

    step: object
    runner: tuple | None
    dims: tuple
    mats: tuple | None
    t_build: float
    t_compile: float


class MatricesNonlinearSolver:
    """`Matrices` with localized nonlinear elements, prepared for one sample step; `run` runs
    one load case.

    Made by ``Matrices(M, C, K).solver(dt, elements=[...], ...)``. ``nonlinear_mck_response(M,
    C, K, force, dt, elements=..., **kw)`` (without ``accuracy``, ``estimate=True``) is this
    solver and one ``run``, bitwise.

    Thread safety: `run` may be called from several threads at once on one solver with the
    C backend: a run reads the solver's step and C loop and allocates its own state, work
    arrays and outputs, and the C loop releases the GIL. The casadi backend's runs (CasADi
    functions share their work memory) and the first run with new ``force_dofs`` (which
    builds its step) take a lock: they run one at a time.

    Parameters
    ----------
    model : Matrices
        The linear part M q'' + C q' + K q (made dense).
    dt : float
        Sample step, s, > 0.
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen`.
    scheme : str, optional
        As `nonlinear_mck_response` (default "modal_ramp"); not "auto".
    substeps : int
        Steps per sample.
    outputs : sequence of int, optional
        Stored DOFs (all by default).
    quantities : subset of ("x", "v", "a", "g", "z")
        What is stored.
    modes : sequence of int, optional
        Modal schemes only: the modes kept.
    backend : {"c", "casadi"}
        The implementation.
    tol : float
        Newton's tolerance.
    max_iter : int
        Newton iterations per step.
    solver : {"newton", "fast_newton"}
        CasADi rootfinder plugin (backend "casadi").
    compiled : bool
        Backend "casadi": compile the record function.
    estimate : bool, optional
        False skips the embedded estimate of modal_quintic and modal_explicit; True (a second
        run at other sub-steps) is `nonlinear_mck_response`'s only.
    force_dofs : sequence of int, optional
        The loaded DOFs whose linear step is built here (every DOF by default); a run with
        other ``force_dofs`` builds its own at its first use, kept for the next runs.
    **scheme_params
        The scheme's parameters.

    Attributes
    ----------
    model : Matrices
        The model.
    dt : float
        The sample step, s.
    elements : tuple
        The checked elements.
    scheme : str
        The method.
    params : dict
        The scheme's parameters as given.
    substeps : int
        Steps per sample.
    outputs : ndarray of int
        The stored DOFs.
    quantities : tuple of str
        The stored quantities.
    backend : str
        The backend asked for (``info["backend"]`` of a result says which one ran).
    setup_time : float
        Seconds the construction took.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.eye(2), 0.1 * np.eye(2), np.array([[2e3, -1e3], [-1e3, 1e3]])
    >>> solver = dd.Matrices(M, C, K).solver(1e-3, elements=[dd.Cubic(0, k3=1e6)],
    ...                                      scheme="modal_parabolic")
    >>> peaks = [np.abs(solver.run(np.full(2001, f), force_dofs=[1]).x).max() for f in (1, 2)]
    >>> bool(peaks[1] < 2 * peaks[0])   # the cubic spring stiffens
    True
    """

    def __init__(self, model, dt, *, elements, scheme=None, substeps=1, outputs=None,
                 quantities=("x", "v", "a"), modes=None, backend="c", tol=1e-12, max_iter=30,
                 solver="newton", compiled=False, estimate=None, force_dofs=None,
                 **scheme_params):
        t0 = time.perf_counter()
        for name in ("accuracy", "max_substeps"):
            if name in scheme_params:
                raise ValueError(
                    f"{name}={scheme_params[name]!r}: an accuracy target picks the method and "
                    "the sub-steps per record, so it is an option of nonlinear_mck_response, "
                    "not of a solver (give scheme and substeps)")
        if estimate is not None and not isinstance(estimate, (bool, np.bool_)):
            raise ValueError(f"estimate must be True or False, got {estimate!r} (a relative "
                             "error target is accuracy=...)")
        if estimate:
            raise ValueError("estimate=True runs the record a second time at other sub-steps: "
                             "it is an option of nonlinear_mck_response, not of a solver "
                             "(estimate=False or None)")
        if scheme is None:
            scheme = "modal_ramp"
        if scheme == "auto":
            raise ValueError("scheme 'auto' picks the method for an accuracy target: it is an "
                             "option of nonlinear_mck_response (with accuracy=...), not of a "
                             "solver")
        self.model = model
        # the dense matrices, as nonlinear_mck_response checks them (a Matrices is checked)
        M, C, K = ((model.M, model.C, model.K) if not model.sparse else
                   linalg.mck(model.M, model.C, model.K))
        self._mck = M, C, K
        n = M.shape[0]
        self.dt = validate.positive_scalar("dt", dt)
        self.outputs = validate.dof_indices("outputs", outputs, n)
        self.quantities = check_quantities(quantities, core.QUANTITIES)
        elements = check_elements(elements)
        if not elements:
            raise ValueError("elements is empty: use mck_response or modal_filter_response for a "
                             "linear model")
        self.elements = elements
        self.substeps = validate.step_count("substeps", substeps)
        self._max_iter = validate.step_count("max_iter", max_iter)
        self._tol = validate.positive_scalar("tol", tol)
        if backend not in ("c", "casadi"):
            raise ValueError(f"backend must be 'c' or 'casadi', got {backend!r}")
        if solver not in ("newton", "fast_newton"):
            raise ValueError(f"solver must be 'newton' or 'fast_newton', got {solver!r}")
        if compiled and solver != "fast_newton":
            raise ValueError("compiled=True needs solver='fast_newton': CasADi cannot generate C "
                             "for its 'newton' rootfinder")
        self.backend, self._solver, self._compiled = backend, solver, compiled
        self.scheme, self.params, self._modes = scheme, dict(scheme_params), modes
        self._estimate = estimate is not False
        self._L = element_matrix(elements, n)
        self._sz = sz = core._sizes(elements)
        self._h = self.dt / self.substeps
        if "z" in self.quantities and not sz.nz:
            raise ValueError("quantities asks for 'z', but no element has internal states "
                             "(BoucWen has z)")
        self._nzo = sz.nz if "z" in self.quantities else 0
        # only the quantities asked are computed and stored: rows of x, v, a per output DOF,
        # then the element forces g (Dog = I), then the internal states z (copied by the loop)
        self._asked = [q for q in ("x", "v", "a") if q in self.quantities]
        self._rows = np.concatenate([np.arange(self.outputs.size)
                                     + self.outputs.size * "xva".index(q)
                                     for q in self._asked] + [np.zeros(0, dtype=int)])
        zeros = np.zeros(n)
        self._rest = core._forces_at_rest(elements, sz, self._L @ zeros, self._L @ zeros)
        self._plans: dict = {}
        self._lock = threading.Lock()
        # the step of the runs' force_dofs (every DOF unless told): checks scheme and modes
        if force_dofs is not LAZY:
            self._plan(validate.dof_indices("force_dofs", force_dofs, n))
        self.setup_time = time.perf_counter() - t0

    def __repr__(self) -> str:
        params = "".join(f", {k}={v!r}" for k, v in self.params.items())
        return (f"<{type(self).__name__} of {self.model!r}: dt={self.dt!r}, "
                f"{len(self.elements)} elements, scheme={self.scheme!r}{params}, "
                f"substeps={self.substeps}, backend={self.backend!r}>")

    def _plan(self, force_dofs) -> _Plan:
        """The `_Plan` of ``force_dofs`` (built at its first use, under the lock)."""
        key = force_dofs.tobytes()
        plan = self._plans.get(key)
        if plan is None:
            with self._lock:
                plan = self._plans.get(key)
                if plan is None:
                    plan = self._plans[key] = self._build(force_dofs)
        return plan

    def _build(self, force_dofs) -> _Plan:
        M, C, K = self._mck
        sz, method = self._sz, self.scheme
        step = linear_step(method, M, C, K, self._h, force_dofs, self._L, self.outputs,
                           self._modes, sz.need_v, estimate=self._estimate, **self.params)
        rows = self._rows
        Co, Dof, Dog = step.Co[rows], step.Dof[rows], step.Dog[rows]
        if "g" in self.quantities:
            Co = np.vstack([Co, np.zeros((sz.ne, Co.shape[1]))])
            Dof = np.vstack([Dof, np.zeros((sz.ne, Dof.shape[1]))])
            Dog = np.vstack([Dog, np.eye(sz.ne)])
        step = replace(step, Co=Co, Dof=Dof, Dog=Dog)
        dims = (step.A.shape[0], force_dofs.size, sz.ne, sz.nw, sz.nz, step.Co.shape[0])
        if step.modal is not None:
            dims += (step.modal["nm"], step.modal["nh"], step.modal["stencil"].size)
        runner, mats, t_build, t_compile = None, None, 0.0, 0.0
        if self.backend == "c":
            reuse = core.LU_REUSE_MIN is not None and sz.nw + sz.nz >= core.LU_REUSE_MIN
            runner, t_build, t_compile = core._c_runner(self.elements, dims, method in EXPLICIT,
                                                        reuse)
            mats = None if runner is None else core._c_addresses(core._c_mats(step))
        return _Plan(step, runner, dims, mats, t_build, t_compile)

    @public
    def run(self, force, *, force_dofs=None, x0=None, v0=None, ground_acceleration=None,
            ground_velocity=None, ground_displacement=None, influence=None) -> Response:
        """Run one load case: the time history of the model and its elements under ``force``.

        Parameters
        ----------
        force : array_like, shape (n_steps + 1, len(force_dofs))
            Force samples at t_k = k dt, linear between samples (a 1-D array is one column);
            may be None with a ground record.
        force_dofs : sequence of int, optional
            0-based loaded DOFs (all DOFs when None).
        x0, v0 : (N,) array_like, optional
            Displacement and velocity at t_0 (rest when None); the elements start from the
            deformations they give, their internal states from 0.
        ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
            Support acceleration at the force's times: the DOFs are then relative to the
            support, loaded by f - M r a_g, and the result adds ``a_abs``.
        ground_velocity, ground_displacement : array_like, optional
            Instead of ``ground_acceleration`` (one ground record at most), as in
            `nonlinear_mck_response`.
        influence : (N,) or (N, n_dir) array_like, optional
            r, each DOF's motion per unit support motion (default: ones).

        Returns
        -------
        Response
            As `nonlinear_mck_response`: ``x``, ``v``, ``a`` (``g``, ``z``) of the outputs;
            ``info`` with the scheme, the times of this run and the Newton statistics.

        Raises
        ------
        NewtonError
            A step did not converge.
        DtdynStepStabilityError
            A modal step beyond its stability limit for the elements' tangent stiffness.

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> p = dd.problem("P4", n_samples=1001)
        >>> solver = dd.Matrices(p["M"], p["C"], p["K"]).solver(p["dt"], elements=p["elements"])
        >>> solver.run(p["force"], force_dofs=p["force_dofs"]).x.shape
        (1001, 4)
        """
        t0 = time.perf_counter()
        M, C, K = self._mck
        n, dt, sz, S, method = M.shape[0], self.dt, self._sz, self.substeps, self.scheme
        outputs, quantities, elements = self.outputs, self.quantities, self.elements
        fs = 1.0 / dt
        force, force_dofs, ground = support.prepare(M, force, force_dofs, n, ground_acceleration,
                                                    influence, dt=dt,
                                                    ground_velocity=ground_velocity,
                                                    ground_displacement=ground_displacement)
        force_dofs = validate.dof_indices("force_dofs", force_dofs, n)
        f = validate.force_record(force, force_dofs.size)
        at_rest = x0 is None and v0 is None
        q0, qd0 = validate.initial_conditions(x0, v0, n)
        validate.output_size("nonlinear_mck_response", f.shape[0],
                             len(quantities) * max(outputs.size, len(elements)))
        plan = self._plan(force_dofs)
        step, L = plan.step, self._L
        y0, yd0 = L @ q0, L @ qd0
        g0, rate0 = self._rest if at_rest else core._forces_at_rest(elements, sz, y0, yd0)
        # the loop solves every sample's step, t_0's too, with the trapezoidal z_k = z_{k-1} +
        # h/2 (z'_k + z'_{k-1}): "previous" values z = 0, z' = -z'_0 make z_0 = 0 its solution
        # (the states start from 0, whatever y'_0 is)
        rate0 = -rate0
        x = np.ascontiguousarray(step.X0f @ f[0] + step.X0g @ g0 + step.X0x @ q0
                                 + step.X0v @ qd0)
        # the force polynomials' past: g_0 at rest, else the motion's continuation
        # (`startup`); the history rows end the state, g_{-1} first
        n_hist = step.modal["nh"] // sz.ne if step.modal else 0
        nst = step.modal["stencil"].size if step.modal else 0
        past = np.tile(g0, (max(n_hist, nst - 1), 1))
        if len(past) and (q0.any() or qd0.any()):
            from dtdyn.nonlinear._startup import forces_before_start
            smooth = forces_before_start(M, C, K, L, elements, force_dofs, f, dt, q0, qd0,
                                         self._h, len(past))
            if smooth is not None:
                past = smooth
                x[x.size - n_hist * sz.ne:] = past[:n_hist].ravel()
        u = np.concatenate([y0] + ([yd0] if sz.need_v else []) + [np.zeros(sz.nz)])
        t1 = time.perf_counter()

        used, embedded, t_around = self.backend, None, 0.0
        t_build, t_compile = plan.t_build, plan.t_compile
        if used == "c" and plan.runner is None:
            used = "casadi"
        nzo, tol, max_iter = self._nzo, self._tol, self._max_iter
        if used == "c":
            t2 = time.perf_counter()
            rc, out, stats, fail, t_run = core._run_c(
                plan.runner, step, sz, f, S, tol, max_iter, x, u, g0.copy(), rate0.copy(),
                THETA_LIMIT.get(method, np.inf), nzo, past, plan.mats)
            t_around = time.perf_counter() - t2 - t_run  # the Python around the loop: setup
            dims = plan.dims
            if rc == 2:
                raise RuntimeError(f"dtdyn_nl_run was compiled for other sizes than {dims}")
            if rc == c_api.ERR_WORK:
                raise DtdynKernelError("dtdyn_nl_run", rc, f"dims {dims}")
            if rc == 3:
                core._stability_error(method, fail, S, fs, stats[3])
            if rc:
                core._newton_error(fail, S, fs, stats[3], max_iter,
                                   method in EXPLICIT and not sz.nz)
            iters = {"max": int(stats[0]), "mean": stats[1] / ((f.shape[0] - 1) * S + 1),
                     "factorizations": int(stats[-1])}
            worst, theta = float(stats[2]), float(stats[4])
            if step.modal is not None and step.modal["stencil"].size:
                embedded = stats[5:-1]
        else:
            xa = np.concatenate([x, u, g0, rate0, [0.0, 0.0]])
            with self._lock:  # CasADi functions share their work memory
                out, worst, theta, t_build, t_compile, t_run = core._run_casadi(
                    elements, step, sz, f, S, self._solver, tol, max_iter, self._compiled, xa,
                    method, fs, nzo)
            iters = None
        asked, no = self._asked, outputs.size
        store = {q: out[:, asked.index(q) * no:(asked.index(q) + 1) * no] if q in asked else None
                 for q in ("x", "v", "a")}
        n_motion = len(asked) * no
        store["g"] = out[:, n_motion:n_motion + sz.ne] if "g" in quantities else None
        store["z"] = out[:, step.Co.shape[0]:] if nzo else None
        estimate_info = {}
        if embedded is not None:  # largest |error| per output row, relative per quantity
            est = 0.0
            for i, q in enumerate(asked):
                scale = np.abs(store[q]).max()
                e = embedded[i * no:(i + 1) * no].max()
                est = max(est, float(e / scale) if scale > 0 else (0.0 if e == 0 else np.inf))
            estimate_info = {"error_estimate": est, "error_estimate_kind": "embedded"}
        params = self.params
        return support.finish(Response(dt * np.arange(f.shape[0]), outputs, **store,
                              info={"scheme": method, "substeps": S, "backend": used, "dt": dt,
                                    "n_steps": f.shape[0] - 1,
                                    "elements": [el.describe() for el in elements],
                                    "setup_time": t1 - t0 + t_around, "construct_time": t_build,
                                    "compile_time": t_compile, "run_time": t_run,
                                    "newton_iterations": iters, "max_residual": worst,
                                    "max_theta": theta, **estimate_info,
                                    **({"params": dict(params)} if params else {})}), ground)


def _linear_only(options: dict, defaults: dict, why: str) -> None:
    """Refuse the linear solvers' own options given other values than their defaults."""
    for name, default in defaults.items():
        value = options.pop(name, default)
        if value != default:
            raise ValueError(f"{name}={value!r} is an option of the linear solvers: {why} "
                             f"(remove {name})")


def matrices_solver(model, dt, **options) -> MatricesNonlinearSolver:
    """``Matrices.solver(dt, elements=..., ...)``: the `MatricesNonlinearSolver`."""
    _linear_only(options, {"form": "acceleration", "unstable": "raise"},
                 "a solver with elements steps its scheme's linear step with the element forces "
                 "as inputs and raises DtdynStepStabilityError at a step beyond its limit")
    return MatricesNonlinearSolver(model, dt, **options)


#: the options of a run, which a solver does not take
RUN_OPTIONS = ("force", "force_dofs", "x0", "v0", "ground_acceleration", "ground_velocity",
               "ground_displacement", "influence")


def chain_solver(chain, dt, **options):
    """``Chain.solver(dt, elements=..., ...)``: the prepared
    `dtdyn.nonlinear._chain.ChainNonlinearSolver`, each run bitwise
    `nonlinear_chain_response`."""
    from dtdyn.nonlinear._chain import ChainNonlinearSolver
    _linear_only(options, {"sweep": "stable", "workers": None, "unstable": "raise"},
                 "nonlinear_chain_response steps the plain DT-TMM of its own")
    _no_run_options(options)
    return ChainNonlinearSolver(chain, dt, **options)


def _no_run_options(options: dict) -> None:
    """Refuse a run's options (`RUN_OPTIONS`) given to a solver."""
    for name in RUN_OPTIONS:
        if name in options:
            raise ValueError(f"{name} is an option of run(...), not of the solver")


def station_solver(model, dt, **options):
    """``Beam.solver`` / ``Shaft.solver`` with elements: the prepared
    `dtdyn.nonlinear._stations.BeamNonlinearSolver` / ``ShaftNonlinearSolver``, each run
    bitwise `nonlinear_beam_response` / `nonlinear_shaft_response`."""
    from dtdyn.nonlinear import _stations
    _linear_only(options, {"unstable": "raise"}, "the nonlinear runs check their own steps")
    _no_run_options(options)
    if not check_elements(options.get("elements", ())):
        raise ValueError(f"elements is empty: use {type(model).__name__}.solver without "
                         "elements for a linear model")
    make = (_stations.BeamNonlinearSolver if type(model).__name__ == "Beam" else
            _stations.ShaftNonlinearSolver)
    return make(model, dt, **options)


def register() -> None:
    """Put this room's solvers in `dtdyn.linear._solver.NONLINEAR` (by model class name)."""
    NONLINEAR.update(Matrices=matrices_solver, Chain=chain_solver, Beam=station_solver,
                     Shaft=station_solver)


register()
