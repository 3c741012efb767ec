"""Running a scene: the stability check, the linear or nonlinear run, the exact-error check."""
from __future__ import annotations

import dataclasses
import time

import numpy as np
import scipy.sparse as sps

from dtdyn._engine.result import Response
from dtdyn.app.scene.schema import (EXACT_MAX_DOF, SCHEMES, UNSTABLE, Scene, _choice,
                                    model_module)

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
    from dtdyn.linear.stability import warn_if_unstable

    scene.require_run("check_stability", load=False)
    dt = scene.dt
    if not scene.linear:
        if scene.scheme not in SCHEMES:
            return False
        dt = scene.dt / scene.nonlinear.get("substeps", 1)
    omegas = natural_frequencies(scene)
    omegas = omegas[omegas > 0.0]
    if omegas.size == 0:
        return False
    return warn_if_unstable(scene.scheme, omegas, dt, **scene.scheme_params)


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


def _run_nonlinear(scene: Scene) -> tuple[Response, dict]:
    """``nonlinear_mck_response`` on the scene; errors get the scene file's name."""
    from dtdyn.nonlinear import response as nonlinear

    start = time.perf_counter()
    try:
        if scene.model is not None:  # shaft, beam: the sweep with the condensed element problem
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
              unstable: str | None = None) -> tuple[Response, dict]:
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
        A nonlinear scene's step failed (dtdyn.nonlinear.response); the message starts with the
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
    if not scene.linear or scene.unstable == "raise":
        check_stability(scene)  # "warn": the entry point warns, once
    if not scene.linear:
        return _run_nonlinear(scene)
    start = time.perf_counter()
    if scene.kind == "matrices":
        from dtdyn.linear import mck

        response = mck.mck_response(
            scene.M, scene.C, scene.K, scene.force, scene.dt, force_dofs=scene.loaded,
            **_support(scene), scheme=scene.scheme, outputs=scene.outputs,
            quantities=scene.quantities, backend=scene.backend, progress=progress,
            unstable=scene.unstable, **scene.scheme_params)
    elif scene.model is not None:  # a kind in MODEL_MODULES (a shaft, a beam)
        response = model_module(scene.kind).simulate(scene, progress, _support(scene))
    else:
        from dtdyn.linear import chain  # imported here: chain may compile kernels on first use

        response = chain.chain_response(
            **scene.chain, force=scene.force, dt=scene.dt, force_dofs=scene.loaded,
            **_support(scene), scheme=scene.scheme, form=scene.form, sweep=scene.sweep,
            backend=scene.backend, outputs=scene.outputs, quantities=scene.quantities,
            progress=progress, unstable=scene.unstable, **scene.scheme_params)
    run_time = time.perf_counter() - start

    report = {
        "title": scene.title, "scheme": scene.scheme, "scheme_params": dict(scene.scheme_params),
        "form": scene.form, "sweep": scene.sweep,
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
    from dtdyn.linear import exact

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
