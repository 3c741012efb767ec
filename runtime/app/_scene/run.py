"""Running a scene: the stability check, the linear or nonlinear run, the exact-error check.

A linear scene runs on its model's solver (`dtdyn.linear._solver.Solver`: the checks, the
factorization and the kernel once); a `SolverCache` keeps the solvers, so that many scenes on
one model with the same settings (a batch's load cases on each worker) make it once.
"""
from __future__ import annotations

import collections
import dataclasses
import hashlib
import pickle
import threading
import time
import warnings

import numpy as np
import scipy.sparse as sps

from dtdyn._engine.public import warn
from dtdyn._engine.result import Response
from dtdyn.app._scene.schema import (EXACT_MAX_DOF, SCHEMES, UNSTABLE, Scene, _choice,
                                    model_module, model_options)

def natural_frequencies(scene: Scene) -> np.ndarray:
    """Undamped natural frequencies (rad/s) to check stability against: all of them up to
    EXACT_MAX_DOF DOFs, else the highest only (the one conditionally stable schemes lose first)."""
    import scipy.linalg as sla
    import scipy.sparse as sps

    if scene.kind == "matrices" or scene.model is not None:
        if scene.n_dof > EXACT_MAX_DOF:
            return np.array([])
        M, _, K = scene.matrices()
        M, K = (A.toarray() if sps.issparse(A) else np.asarray(A) for A in (M, K))
        try:
            lam = sla.eigh(K, M, eigvals_only=True)
        except (np.linalg.LinAlgError, ValueError):  # singular or indefinite M: skip the check
            return np.array([])
        return np.sqrt(np.clip(lam, 0.0, None))
    m, k = scene.mass, scene.stiffness
    s = 1.0 / np.sqrt(m)
    kk = k + np.append(k[1:], 0.0)
    if scene.ground_stiffness is not None:
        kk = kk + scene.ground_stiffness
    d, e = kk * s * s, -k[1:] * s[:-1] * s[1:]  # M^-1/2 K M^-1/2, tridiagonal
    n = m.size
    sel = {} if n <= EXACT_MAX_DOF else {"select": "i", "select_range": (n - 1, n - 1)}
    lam = sla.eigh_tridiagonal(d, e, eigvals_only=True, **sel)
    return np.sqrt(np.clip(lam, 0.0, None))


def check_stability(scene: Scene) -> bool:
    """Warn before a run whose dt makes the scheme unstable for a mode of the model.

    A nonlinear scene is checked for its linear part at the sub-step dt / substeps when its
    method is a scheme (the modal methods are exact for the linear part; nonlinear_mck_response
    checks the elements' tangent stiffness as it runs).
    """
    return _check_stability(scene, natural_frequencies)


def _check_stability(scene: Scene, frequencies) -> bool:
    """`check_stability` with the model's frequencies from ``frequencies(scene)``."""
    from dtdyn.linear._stability import warn_if_unstable

    scene.require_run("check_stability", load=False)
    dt = scene.dt
    if not scene.linear:
        if scene.scheme not in SCHEMES:
            return False
        dt = scene.dt / scene.nonlinear.get("substeps", 1)
    omegas = frequencies(scene)
    omegas = omegas[omegas > 0.0]
    if omegas.size == 0:
        return False
    return warn_if_unstable(scene.scheme, omegas, dt, **scene.scheme_params)


def scene_solver(scene: Scene):
    """The solver of a linear scene's model with the scene's dt, scheme, outputs and
    quantities (`dtdyn.linear._solver.Solver`), the one `mck_response`, `chain_response`,
    `shaft_response` or `beam_response` would make; None for a model kind without one."""
    common = dict(scheme=scene.scheme, backend=scene.backend, outputs=scene.outputs,
                  quantities=scene.quantities, unstable=scene.unstable, **scene.scheme_params)
    if scene.kind == "matrices":
        from dtdyn.linear._mck import Matrices

        return Matrices(scene.M, scene.C, scene.K).solver(scene.dt, **common)
    if scene.model is not None:  # a kind in MODEL_MODULES (a shaft, a beam)
        if not hasattr(scene.model, "solver"):
            return None
        return scene.model.solver(scene.dt, form=scene.form, **model_options(scene), **common)
    from dtdyn.linear._chain import Chain  # imported here: chain may compile kernels on first use

    chain = scene.chain
    model = Chain(chain["mass"], chain["stiffness"], chain["damping"],
                  ground_stiffness=chain["ground_stiffness"],
                  ground_damping=chain["ground_damping"])
    return model.solver(scene.dt, form=scene.form, sweep=scene.sweep, **common)


def model_digest(scene: Scene) -> str | None:
    """A hash of everything a scene's model (not its loads, scheme or outputs) gives its
    solver and natural frequencies: the chain's stations, the matrices (dense or sparse, their
    stored arrays) or a beam's or shaft's lumped data; None for a model kind it does not know
    (that model's solvers are then not cached)."""
    h = hashlib.blake2b(digest_size=20)

    def feed(x):
        if x is None:
            h.update(b"N")
        elif sps.issparse(x):
            h.update(f"S{x.format}".encode())
            x = x.tocsr()
            feed((x.shape, x.indptr, x.indices, x.data))
        elif isinstance(x, np.ndarray):
            if x.dtype == object:
                feed(tuple(x.ravel()))
                return
            a = np.ascontiguousarray(x)
            h.update(f"A{a.shape}{a.dtype.str}".encode())
            h.update(a.view(np.uint8).ravel())
        elif isinstance(x, (tuple, list)):
            h.update(f"T{len(x)}".encode())
            for y in x:
                feed(y)
        elif isinstance(x, dict):
            feed(sorted(x.items()))
        else:  # numbers (repr is exact), strings, frozen dataclasses (PointMass, ...)
            h.update(f"R{type(x).__name__}:{x!r}".encode())

    if scene.kind == "matrices":
        feed(("matrices", scene.M, scene.C, scene.K))
    elif scene.model is None:
        feed(("chain", scene.chain))
    elif scene.kind == "beam":
        b = scene.model
        feed(("beam", b.E, b.I, b.rho_A, b.length, b.elements, b.mass_matrix, b.rayleigh,
              b.point_masses, b.supports, b.ends, b.free))
    elif scene.kind == "shaft":
        feed(("shaft", tuple(scene.model.tree)))  # the lumped tree the runs sweep
    else:
        return None
    return h.hexdigest()


class SolverCache:
    """Solvers of scenes, kept for the scenes that come next on the same model.

    `run_scene` with ``solvers=`` a cache looks the scene's solver up by its model's content
    (`model_digest`) and its settings (dt, scheme and parameters, form, sweep, backend,
    outputs, quantities, unstable): found, it runs the load case on it; else it makes the
    solver and keeps it. The results are those of a fresh solver, bitwise (a solver's runs do
    not depend on the runs before). It also keeps each model's natural frequencies for the
    stability check. A batch's worker holds one (`run_batch`: one solver per model and
    settings per worker process). Scenes with ``[[element]]`` and no accuracy target get
    `nonlinear_solver`'s (keyed also by the elements and the [nonlinear] options); those with
    a target run as calls. Safe to use from several threads; the
    least recently used entries beyond ``size`` are dropped.

    A warning the solver gave when it was made (a dt past the stability limit with
    ``unstable = "warn"``) is given again for each scene that reuses it, as making it again
    would.

    Parameters
    ----------
    size : int
        Solvers kept (each holds its model's factors: a dense 2,000-DOF model about 100 MB).

    Attributes
    ----------
    built, reused : int
        Solvers made, and runs that found theirs (since the cache was made).

    Examples
    --------
    >>> import dtdyn as dd
    >>> from dtdyn.app._scene.run import SolverCache
    >>> cache, scene = SolverCache(), dd.load_scene()
    >>> runs = [dd.run_scene(scene, check=False, solvers=cache) for _ in range(3)]
    >>> cache.built, cache.reused
    (1, 2)
    """

    def __init__(self, size: int = 4):
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"size = {size!r}: must be an integer >= 1")
        self.size = size
        self.built = self.reused = 0
        self._solvers = collections.OrderedDict()
        self._omegas = collections.OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._solvers)

    def clear(self) -> None:
        """Drop every solver and frequency set (the counts stay)."""
        with self._lock:
            self._solvers.clear()
            self._omegas.clear()

    def _get(self, table, key):
        with self._lock:
            got = table.get(key)
            if got is not None:
                table.move_to_end(key)
            return got

    def _put(self, table, key, value):
        with self._lock:
            table[key] = value
            table.move_to_end(key)
            while len(table) > self.size:
                table.popitem(last=False)

    def solver(self, scene: Scene):
        """The scene's solver (`scene_solver`), reused or made and kept."""
        digest = model_digest(scene)
        if digest is None:
            return scene_solver(scene)
        key = (scene.kind, digest, repr(float(scene.dt)), scene.scheme,
               tuple(sorted((k, repr(v)) for k, v in scene.scheme_params.items())), scene.form,
               scene.sweep, scene.backend, np.asarray(scene.outputs).tobytes(),
               tuple(scene.quantities), scene.unstable, scene.refine)
        got = self._get(self._solvers, key)
        if got is not None:
            solver, again = got
            with self._lock:
                self.reused += 1
            for w in again:  # what making it gave (through `warn`: once per public call)
                warn(str(w.message), w.category)
            return solver
        again = ()
        if scene.unstable == "warn":  # keep its stability warning for the scenes that reuse it
            from dtdyn._engine.errors import DtdynStabilityWarning

            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                solver = scene_solver(scene)
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno,
                                       source=w.source)
            again = tuple(w for w in caught if issubclass(w.category, DtdynStabilityWarning))
        else:
            solver = scene_solver(scene)
        if solver is not None:
            with self._lock:
                self.built += 1
            self._put(self._solvers, key, (solver, again))
        return solver

    def nonlinear_solver(self, scene: Scene):
        """The solver of a scene with elements and no accuracy target (`Matrices.solver`,
        `Beam.solver` or `Shaft.solver` with ``elements``), reused or made and kept; None for
        the others (they run as a call)."""
        digest = model_digest(scene)
        if digest is None or scene.scheme == "auto" or \
                not set(scene.nonlinear) <= set(SOLVER_OPTIONS):
            return None
        key = ("nonlinear", scene.kind, digest, repr(float(scene.dt)), scene.scheme,
               tuple(sorted((k, repr(v)) for k, v in scene.scheme_params.items())),
               tuple(sorted((k, repr(v)) for k, v in scene.nonlinear.items())),
               hashlib.blake2b(pickle.dumps(scene.elements), digest_size=20).hexdigest(),
               np.asarray(scene.outputs).tobytes(), tuple(scene.quantities))
        got = self._get(self._solvers, key)
        if got is not None:
            with self._lock:
                self.reused += 1
            return got[0]
        if scene.model is not None:  # a beam or a shaft: its own solver
            model = scene.model
        else:
            from dtdyn.linear._mck import Matrices

            model = Matrices(*(m.toarray() if sps.issparse(m) else np.asarray(m)
                               for m in scene_matrices(scene)))
        solver = model.solver(scene.dt, elements=scene.elements, outputs=scene.outputs,
                              quantities=scene.quantities, scheme=scene.scheme,
                              **scene.nonlinear, **scene.scheme_params)
        with self._lock:
            self.built += 1
        self._put(self._solvers, key, (solver, ()))
        return solver

    def frequencies(self, scene: Scene) -> np.ndarray:
        """`natural_frequencies` of the scene's model, reused or computed and kept."""
        digest = model_digest(scene)
        if digest is None:
            return natural_frequencies(scene)
        key = (scene.kind, digest)
        got = self._get(self._omegas, key)
        if got is None:
            got = natural_frequencies(scene)
            self._put(self._omegas, key, got)
        return got


def scene_matrices(scene: Scene):
    """(M, C, K) of a scene: a chain's from ``chain_matrices`` (dense), else as held."""
    return scene.matrices(sparse=False)


def _support(scene: Scene) -> dict:
    """The [ground] and [initial] keywords of the entry points (those the scene has)."""
    kw = {}
    if scene.ground is not None:
        kw.update({f"ground_{scene.ground_quantity}": scene.ground, "influence": scene.influence})
    if scene.x0 is not None or scene.v0 is not None:
        kw.update(x0=scene.x0, v0=scene.v0)
    return kw


#: the [nonlinear] options a solver takes (an accuracy target picks sub-steps per record)
SOLVER_OPTIONS = ("substeps", "backend", "tol", "max_iter", "modes")


def _run_nonlinear(scene: Scene, solvers: SolverCache | None = None) -> tuple[Response, dict]:
    """``nonlinear_mck_response`` on the scene (through the cache's solver when ``solvers``
    holds or can make one: the same result, bitwise); errors get the scene file's name."""
    from dtdyn.nonlinear import _response as nonlinear

    start = time.perf_counter()
    try:
        solver = solvers.nonlinear_solver(scene) if solvers is not None else None
        if solver is not None:
            response = solver.run(scene.force, force_dofs=scene.loaded, **_support(scene))
        elif scene.model is not None:  # shaft, beam: the sweep with the condensed problem
            response = model_module(scene.kind).simulate_nonlinear(scene, _support(scene))
        else:
            M, C, K = (m.toarray() if sps.issparse(m) else np.asarray(m)
                       for m in scene_matrices(scene))
            response = nonlinear.nonlinear_mck_response(
                M, C, K, scene.force, scene.dt, force_dofs=scene.loaded, **_support(scene),
                elements=scene.elements,
                outputs=scene.outputs, quantities=scene.quantities, scheme=scene.scheme,
                **scene.nonlinear, **scene.scheme_params)
    except (nonlinear.NewtonError, nonlinear.DtdynStepStabilityError) as exc:
        has = ", ".join(f"nonlinear.{k} = {scene.nonlinear[k]:g}"
                        for k in ("accuracy", "max_substeps") if k in scene.nonlinear)
        has = has or f"nonlinear.substeps = {scene.nonlinear.get('substeps', 1)}"
        raise type(exc)(f"{scene.source}: {exc} (the scene has {has})") from None
    except ValueError as exc:
        if str(exc).startswith("modes"):  # the range of nonlinear.modes is known only here
            raise ValueError(f"{scene.source}: nonlinear.{exc}") from None
        raise
    wall = time.perf_counter() - start
    info = response.info
    report = {
        "title": scene.title, "scheme": info.get("scheme", scene.scheme),
        "scheme_params": dict(scene.scheme_params),
        "form": None, "sweep": None, "backend": info["backend"], "dt": scene.dt,
        "n_steps": scene.n_steps, "n_dof": scene.n_dof, "n_outputs": int(scene.outputs.size),
        "run_time_s": info["run_time"], "exact_time_s": None, "max_rel_error": None,
        "check": "skipped: a nonlinear scene has no exact solution (see reference_response)",
        "substeps": info["substeps"],
        "elements": list(info["elements"]), "setup_time_s": info["setup_time"],
        "construct_time_s": info.get("construct_time"), "compile_time_s": info.get("compile_time"),
        "total_time_s": wall, "newton_iterations": info["newton_iterations"],
        "max_residual": info["max_residual"], "max_theta": info.get("max_theta"),
        "accuracy": info.get("accuracy"), "accuracy_met": info.get("accuracy_met"),
        "error_estimate": info.get("error_estimate"),
    }
    return response, report


def run_scene(scene: Scene, progress: bool = False, check: bool = True,
              unstable: str | None = None,
              solvers: SolverCache | None = None) -> tuple[Response, dict]:
    """Simulate a scene with ``chain_response`` (chains), ``mck_response`` (general matrices) or
    ``nonlinear_mck_response`` (scenes with elements) and report run time and error.

    The error is measured against the matrix-exponential solution (``exact_response``) when the
    scene is linear and has at most ``EXACT_MAX_DOF`` DOFs (and, for matrices, a mass matrix
    that is nonsingular or singular only through massless DOFs with damping, the cases
    ``exact_response`` solves; the matrices are converted to dense for it)::

        max_rel_error = max_{i, j} |x[i, j] - x_exact[i, j]| / max_{i, j} |x_exact[i, j]|

    over all samples ``i`` and stored outputs ``j`` (``None`` when not computed).

    Returns
    -------
    response : Response
        Sampled at ``t_0 .. t_n`` for the DOFs ``scene.outputs``.
    report : dict
        ``title, scheme, scheme_params, form, sweep, backend, dt, n_steps, n_dof, n_outputs,
        run_time_s, exact_time_s, max_rel_error, check`` (``check``: "done", or why the
        exact comparison was skipped; ``check=False`` skips it). For matrices ``form`` is
        ``"acceleration"``, ``sweep`` None and ``backend`` the loop that ran (``"c"``, or
        ``"numpy"`` / ``"scipy.sparse"`` where no C compiler exists).
        A nonlinear scene (``form``, ``sweep``, ``max_rel_error`` None; ``backend`` the one used)
        adds ``substeps, elements`` (descriptions), ``setup_time_s,
        construct_time_s, compile_time_s`` (``run_time_s`` is the stepping loop alone,
        ``total_time_s`` the whole call), ``newton_iterations`` (``{"max", "mean"}`` per step,
        and the C loop's LU ``factorizations``; None for backend "casadi"), ``max_residual``
        and ``max_theta`` (``Response.info``), ``accuracy``, ``accuracy_met`` and
        ``error_estimate`` (None when not asked or not estimated); ``scheme`` is the method
        that ran (the one "auto" picked).

    Raises
    ------
    ValueError
        The scene has no ``[time]`` table or no load (``[[load]]`` or ``[ground]``): a scene
        holding only ``[model]`` is for `dtdyn modes`; the message names the table to add.
    DtdynUnstableError
        A linear scene whose dt is past its scheme's stability limit, unless ``unstable`` (or
        the scene's ``scheme.unstable``) is ``"warn"``.
    NewtonError, DtdynStepStabilityError
        A nonlinear scene's step failed (dtdyn.nonlinear._response); the message starts with the
        scene file and names the step, its time and the residual (or the tangent stiffness).

    Parameters
    ----------
    scene : Scene
    progress : bool
        A progress bar on long runs.
    check : bool
        Compare with `exact_response` (linear scenes up to ``EXACT_MAX_DOF`` DOFs).
    unstable : {"raise", "warn"} or None
        A linear scene's dt past the scheme's stability limit: raise DtdynUnstableError, or
        warn (DtdynStabilityWarning) and run it anyway, for study (the entry points'
        ``unstable=``). None: the scene's ``scheme.unstable`` (default "raise").
    solvers : SolverCache, optional
        Linear scenes: reuse the solver (and the natural frequencies of the stability check)
        kept there for the same model and settings, or make it and keep it; the results are
        the same, bitwise. None: a solver made for this run alone.

    Examples
    --------
    >>> import dtdyn as dd
    >>> response, report = dd.run_scene(dd.load_scene())
    >>> response.x.shape, report["check"], bool(report["max_rel_error"] < 1e-2)
    ((801, 15), 'done', True)
    """
    scene.require_run("run_scene")
    if unstable is not None and unstable != scene.unstable:
        if not scene.linear:
            raise ValueError(f"unstable = {unstable!r}: only for linear scenes; a scene with "
                             "[[element]] checks each step's stability as it runs")
        scene = dataclasses.replace(scene, unstable=_choice("unstable", unstable, UNSTABLE))
    if not scene.linear or scene.unstable == "raise":  # "warn": the solver warns, once
        cached = solvers is not None and scene.linear
        _check_stability(scene, solvers.frequencies if cached else natural_frequencies)
    if not scene.linear:
        return _run_nonlinear(scene, solvers)
    start = time.perf_counter()
    # the solver of mck_response, chain_response, shaft_response or beam_response: the same
    # results, bitwise
    solver = scene_solver(scene) if solvers is None else solvers.solver(scene)
    if solver is None:  # a model kind without a solver: its module's run
        response = model_module(scene.kind).simulate(scene, progress, _support(scene))
    else:
        response = solver.run(scene.force, force_dofs=scene.loaded, progress=progress,
                              **_support(scene))
    run_time = time.perf_counter() - start

    report = {
        "title": scene.title, "scheme": scene.scheme, "scheme_params": dict(scene.scheme_params),
        "form": scene.form if solver is None else solver.form, "sweep": scene.sweep,
        "backend": response.info.get("backend", scene.backend), "dt": scene.dt,
        "n_steps": scene.n_steps, "n_dof": scene.n_dof, "n_outputs": int(scene.outputs.size),
        "run_time_s": run_time, "exact_time_s": None, "max_rel_error": None, "check": None,
    }
    report["check"] = _exact_check(scene, response, report) if check else "not asked (--no-check)"
    return response, report


#: the exact check is skipped past this many multiply-adds of its state recursion
#: (n_steps (2 n_dof)^2: about half a minute)
EXACT_MAX_WORK = 1e11


def _exact_check(scene: Scene, response: Response, report: dict) -> str:
    """Compare the displacements with `exact_response`; fills ``report`` and returns "done" or
    why the check was skipped."""
    if response.x is None:
        return "skipped: the scene stores no displacement x"
    if scene.n_dof > EXACT_MAX_DOF:
        return (f"skipped: {scene.n_dof} DOFs > {EXACT_MAX_DOF} (the matrix exponential is "
                "dense, O(N^3))")
    from dtdyn.linear import _exact as exact

    work = scene.n_steps * (2 * scene.n_dof) ** 2
    if work > EXACT_MAX_WORK:
        return (f"skipped: the matrix exponential's recursion would take n_steps (2 n_dof)^2 = "
                f"{work:.3g} multiply-adds (more than {EXACT_MAX_WORK:.0e})")
    M, C, K = (m.toarray() if sps.issparse(m) else np.asarray(m) for m in scene_matrices(scene))
    start = time.perf_counter()
    try:
        ref = exact.exact_response(M, C, K, scene.force, scene.dt, force_dofs=scene.loaded,
                                   **_support(scene), outputs=scene.outputs, quantities=("x",))
    except exact.SingularMassError as exc:  # no exact solution to compare with
        return f"skipped: {exc}"
    except MemoryError as exc:  # its state record does not fit: refused before allocating
        return f"skipped: {exc}"
    report["exact_time_s"] = time.perf_counter() - start
    x, x_ref = np.asarray(response.x), np.asarray(ref.x)
    err = float(np.max(np.abs(x - x_ref)))
    scale = float(np.max(np.abs(x_ref)))
    report["max_rel_error"] = err / scale if scale > 0.0 else (0.0 if err == 0.0 else np.inf)
    return "done"
