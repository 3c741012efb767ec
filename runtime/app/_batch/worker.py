"""What runs on a Dask worker: the shared files materialized once, the C warm-up, the cases of
one task, their reductions and the write of the task's block of the Zarr store.

Nothing here holds a ctypes object across tasks or ships one: every worker process compiles
(or loads from its on-disk cache) the kernels it needs on its first case, through
`dtdyn._engine.cbuild`, and keeps them in its own memory. Likewise the solvers: the
scenes are shipped, and each worker process keeps the solver of each model and settings it
has run (`SOLVERS`, a `dtdyn.app._scene.run.SolverCache`), so that the load cases of a batch on
one model validate, factorize and load their kernel once per worker.
"""
from __future__ import annotations

import atexit
import json
import os
import shutil
import tempfile
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from dtdyn._engine.errors import (DtdynFallbackWarning, DtdynStepStabilityError,
                                  DtdynUnstableError, NewtonError, SingularMassError)
from dtdyn.app._batch.cases import CaseSpec, Shared, apply_overrides

__all__ = ["CBackendError", "RUN_ERRORS", "META", "NameClash", "probe", "run_chunk",
           "run_case", "cleanup", "solvers", "SOLVER_CACHE_SIZE"]

#: the errors expected to fail one case (NewtonError, ...); any other Exception of a case (a
#: library bug's TypeError, a user reducer's KeyError) fails it too, with its type and
#: message: only CBackendError (and KeyboardInterrupt) stop the batch
RUN_ERRORS = (NewtonError, DtdynStepStabilityError, DtdynUnstableError, SingularMassError,
              FloatingPointError, ValueError, MemoryError)
#: the per-case metadata variables and the coordinates of a batch: no reducer may make them
META = ("index", "status", "message", "backend", "worker", "run_time", "max_rel_error",
        "max_residual", "error_estimate", "seed", "params", "case", "time", "output",
        "output_name", "period", "freq_hz", "case_record", "case_hash")

_FOLDERS: dict[str, Path] = {}
#: the solvers a worker process keeps (models x settings; each holds its model's
#: factors, a dense 2,000-DOF model about 100 MB)
SOLVER_CACHE_SIZE = 4
_SOLVERS = None
_SOLVERS_LOCK = threading.Lock()


def solvers():
    """This worker process's `SolverCache` (made at its first linear case)."""
    global _SOLVERS
    with _SOLVERS_LOCK:
        if _SOLVERS is None:
            from dtdyn.app._scene.run import SolverCache

            _SOLVERS = SolverCache(SOLVER_CACHE_SIZE)
        return _SOLVERS


class CBackendError(RuntimeError):
    """A worker cannot run the C backend a case asks for (no compiler, a failed build, or
    ``DTDYN_NO_C``): a batch stops instead of falling back to NumPy or CasADi silently."""


class NameClash(ValueError):
    """Two reducers make the same variable, or a reducer makes a metadata or coordinate name:
    raised by the warm-up (`probe`), so the batch stops before it runs."""


def _address() -> str:
    try:
        from distributed import get_worker
        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def _write_file(path: Path, data: bytes) -> None:
    if path.is_file() and path.stat().st_size == len(data):
        return  # named by its content hash: already there
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
    os.replace(tmp, path)


def folder(shared: Shared) -> Path:
    """This worker's folder holding the batch's shipped files (written once per batch and
    process, removed at exit)."""
    got = _FOLDERS.get(shared.token)
    if got is None:
        got = Path(tempfile.mkdtemp(prefix=f"dtdyn-batch-{shared.token[:8]}-"))
        atexit.register(shutil.rmtree, got, True)
        for name, data in shared.files.items():
            _write_file(got / name, data)
        _FOLDERS[shared.token] = got
    return got


def cleanup(token: str) -> None:
    """Remove this worker's folder of the batch ``token`` and drop its solvers (run on every
    worker at the end)."""
    got = _FOLDERS.pop(token, None)
    if got is not None:
        shutil.rmtree(got, ignore_errors=True)
    if _SOLVERS is not None:
        _SOLVERS.clear()


def _require_compiler() -> None:
    from dtdyn._engine import cbuild

    if not cbuild.c_available():
        why = ("DTDYN_NO_C is set" if cbuild._disabled()
               else "no C compiler found (cc, gcc, clang or $CC)")
        raise CBackendError(f"worker {_address()}: the C backend is unavailable: {why}. A batch "
                            "does not fall back to NumPy silently: install a C compiler on every "
                            "worker (or unset DTDYN_NO_C), or give the scene backend = \"numpy\"")


def _wants_c(scene) -> bool:
    return scene.backend == "c" or (scene.kind == "matrices" and scene.linear)


def scene_of(shared: Shared, spec: CaseSpec, where: Path):
    """The case's Scene: its base tables with its overrides, validated by scene_from_dict."""
    from dtdyn.app._scene.parse import scene_from_dict

    base = shared.bases[spec.scene]
    if not isinstance(base, dict):
        return base  # a Scene object, run as given
    for name, data in spec.files.items():
        _write_file(where / name, data)
    data = apply_overrides(base, spec.overrides)
    source = shared.sources[spec.scene]
    try:
        return scene_from_dict(data, where, source)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def _coords(response, scene) -> dict:
    """The coordinates a case's response gives the batch: time, output (and output_name)."""
    coords = {"time": np.asarray(response.t), "output": np.asarray(response.outputs)}
    names = response.dof_names
    if names is None and scene.kind == "matrices" and scene.dof_names is not None:
        names = tuple(scene.dof_label(d) for d in response.outputs)
    if names is not None and list(names) != [str(int(d)) for d in response.outputs]:
        coords["output_name"] = np.array(names, dtype=str)
    return coords


def _fail(meta: dict, exc: BaseException, start: float, prefix: str = ""):
    meta["message"] = prefix + f"{type(exc).__name__}: {exc}"
    meta["run_time"] = time.perf_counter() - start
    return meta, None


def _nonfinite(name: str, dims, values) -> str | None:
    """The message of a non-finite stored value (the first one), or None."""
    values = np.asarray(values)
    if values.dtype.kind not in "fc":
        return None
    bad = ~np.isfinite(values)
    if not bad.any():
        return None
    where = np.argwhere(bad)[0] if values.ndim else ()
    parts = [("sample" if d == "time" else str(d)) + f" {int(i)}" for d, i in zip(dims, where)]
    return f"non-finite values in {name}" + (" at " + ", ".join(parts) if parts else "")


def _reported(caught) -> list:
    """The distinct warnings of a case, [(category, message)] in order: those a batch reports
    (not the C fallback, which stops it, nor DeprecationWarning)."""
    return list(dict.fromkeys((w.category, str(w.message)) for w in caught
                              if not issubclass(w.category, (DtdynFallbackWarning,
                                                             DeprecationWarning))))


def run_case(shared: Shared, spec: CaseSpec, reducers, check: bool, layout=None,
             coords: bool = False, strict: bool = False):
    """(metadata, {name: (dims, values)} or None) of one case. Any Exception of the case (a
    RUN_ERRORS error, a library bug, a failing reducer, a non-finite result) fails the case
    (status "failed", ``"<type>: <message>"``); a missing C backend raises CBackendError, and
    with ``strict`` (the warm-up) a reducer's name clash raises NameClash. The warnings of the
    run and of the reducers are caught (not printed by the worker): the metadata's
    ``warnings`` lists them, [(category, message)], once each, and a done case's message
    holds them (``"warning: ..."``)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        meta, arrays = _run_case(shared, spec, reducers, check, layout, coords, strict, caught)
    meta["warnings"] = _reported(caught)
    if meta["status"] == "done":
        meta["message"] = "; ".join(f"warning: {m}" for _, m in meta["warnings"])
    return meta, arrays


def _run_case(shared, spec, reducers, check, layout, coords, strict, caught):  # noqa: C901 - each stage fails the case with its own message
    from dtdyn.app._batch.reducers import reducer_name
    from dtdyn.app._scene.run import run_scene

    start = time.perf_counter()
    meta = {"index": spec.index, "status": "failed", "message": "", "backend": "",
            "run_time": np.nan, "max_rel_error": np.nan, "max_residual": np.nan,
            "error_estimate": np.nan, "seed": spec.seed, "worker": _address()}
    where = folder(shared)
    try:
        scene = scene_of(shared, spec, where)
        if _wants_c(scene):
            _require_compiler()
        response, report = run_scene(scene, check=check, solvers=solvers())
    except CBackendError:
        raise
    except Exception as exc:  # RUN_ERRORS and anything else: this case fails
        return _fail(meta, exc, start)
    used = str(response.info.get("backend", scene.backend))
    if _wants_c(scene) and used != "c":
        why = "; ".join(str(w.message) for w in caught if issubclass(w.category,
                                                                     DtdynFallbackWarning))
        raise CBackendError(f"worker {_address()}: case {spec.index} asked for the C backend and "
                            f"ran on {used!r}" + (f" ({why})" if why else "") + ". A batch does "
                            "not fall back silently: install a C compiler on every worker, or "
                            "give the scene backend = \"numpy\"")
    meta["backend"] = used
    try:
        for key in ("max_rel_error", "max_residual"):
            if report.get(key) is not None:
                meta[key] = float(report[key])
        if response.info.get("error_estimate") is not None:
            meta["error_estimate"] = float(response.info["error_estimate"])
    except Exception as exc:
        return _fail(meta, exc, start)
    arrays, made_by, failing = {}, {}, None
    try:
        for r in reducers:
            failing = reducer_name(r)
            got = r(response, scene)
            if not isinstance(got, dict):
                raise TypeError(f"returned {type(got).__name__}, not a dict of name -> values")
            for name in got:
                if name in META:
                    raise NameClash(f"reduce {failing!r}: the variable {name!r} has the name of "
                                    "a batch's metadata or coordinate; rename it")
                if name in made_by:
                    raise NameClash(f"reduce {failing!r}: the variable {name!r} is already made "
                                    f"by the reducer {made_by[name]!r}; rename it or drop one")
                made_by[name] = failing
            arrays.update(got)
        failing = None
        for name, (dims, values) in arrays.items():
            bad = _nonfinite(name, dims, values)
            if bad is not None:
                raise FloatingPointError(bad)
        if layout is not None:
            _check_layout(arrays, response, layout)
    except NameClash as exc:
        if strict:
            raise
        return _fail(meta, exc, start)
    except CBackendError:
        raise
    except Exception as exc:  # a reducer (possibly the user's), a non-finite value or a
        return _fail(meta, exc, start, f"reduce {failing!r}: " if failing else "")  # layout
    meta["status"] = "done"
    meta["run_time"] = time.perf_counter() - start
    if coords:
        meta["coords"] = _coords(response, scene)
        meta["dt"] = float(scene.dt)
    return meta, arrays


def _check_layout(arrays: dict, response, layout: dict) -> None:
    want, coords = layout["vars"], layout["coords"]
    if set(arrays) != set(want):
        raise ValueError(f"the case gives the variables {sorted(arrays)}, the batch "
                           f"{sorted(want)} (from its first case): every case of a batch stores "
                           "the same quantities")
    outputs = np.asarray(response.outputs)
    if not np.array_equal(outputs, coords["output"]):
        raise ValueError(f"the case stores the outputs {outputs.tolist()}, the batch "
                           f"{np.asarray(coords['output']).tolist()}: every case of a batch "
                           "stores the same DOFs")
    uses_time = any("time" in tuple(dims) for dims, _ in want.values())
    t = np.asarray(response.t)
    if uses_time and (t.shape != np.shape(coords["time"]) or
                      not np.array_equal(t, coords["time"])):
        first = np.asarray(coords["time"])
        raise ValueError(f"the case's time axis ({t.size} samples, dt = "
                         f"{_step(t)} s) differs from the batch's ({first.size} samples, dt = "
                         f"{_step(first)} s, from its first case): every case of a batch that "
                         "stores time histories has the same time axis (same time.dt and "
                         "time.duration)")
    for name, (dims, values) in arrays.items():
        wdims, wshape = want[name]
        if tuple(dims) != tuple(wdims) or tuple(np.shape(values)) != tuple(wshape):
            raise ValueError(f"{name} has dims {tuple(dims)} and shape {np.shape(values)}, "
                               f"the batch {tuple(wdims)} and {tuple(wshape)} (from its first "
                               "case): every case of a batch has the same samples and outputs")


def _step(t) -> str:
    return f"{float(t[1] - t[0]):g}" if len(t) > 1 else "?"


def probe(shared: Shared, specs: list[CaseSpec], reducers, check: bool,
          case_timeout: float | None = None) -> dict:
    """The warm-up of one worker: the C compiler required, then the given cases in order until
    one succeeds (its kernels compiled or loaded into this process). Returns the batch layout
    (its variables' dims and shapes, the coordinates), the case's run time, the messages
    of the cases that failed before it, and ``stuck`` (a case passed ``case_timeout``: its
    thread still runs, the caller restarts this worker)."""
    failed, stuck = [], False
    for spec in specs:
        meta, arrays, late = _timed(shared, spec, reducers, check, None, case_timeout,
                                    coords=True, strict=True)
        stuck = stuck or late
        if arrays is None:
            failed.append(f"case {spec.index}: {meta['message']}")
            continue
        coords = meta["coords"]
        return {"vars": {k: (tuple(d), tuple(np.shape(v))) for k, (d, v) in arrays.items()},
                "coords": coords, "dt": meta["dt"], "case": spec.index,
                "run_time": meta["run_time"], "failed": failed, "worker": _address(),
                "stuck": stuck}
    return {"vars": None, "failed": failed, "worker": _address(), "stuck": stuck}


def _timed(shared, spec, reducers, check, layout, case_timeout, **kw):
    """run_case in a thread of its own, waited for at most ``case_timeout`` s: (meta, arrays,
    stuck). A case past its time is failed (``TimeoutError: case exceeded 60 s``) and left
    running in its thread (stuck = True: the caller has its worker restarted)."""
    if case_timeout is None:
        return (*run_case(shared, spec, reducers, check, layout, **kw), False)
    box, done = {}, threading.Event()

    def target():
        try:
            box["got"] = run_case(shared, spec, reducers, check, layout, **kw)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the task's thread
            box["exc"] = exc
        finally:
            done.set()

    start = time.perf_counter()
    threading.Thread(target=target, name=f"dtdyn-case-{spec.index}", daemon=True).start()
    if not done.wait(case_timeout):
        meta = {"index": spec.index, "status": "failed", "backend": "",
                "run_time": time.perf_counter() - start, "max_rel_error": np.nan,
                "max_residual": np.nan, "error_estimate": np.nan, "seed": spec.seed,
                "worker": _address(), "warnings": [],
                "message": f"TimeoutError: case exceeded {case_timeout:g} s"}
        return meta, None, True
    if "exc" in box:
        raise box["exc"]
    return (*box["got"], False)


def run_chunk(shared: Shared, specs: list[CaseSpec], reducers, check: bool, layout: dict,
              store: str | None, case_timeout: float | None = None) -> dict:
    """Run the cases ``specs`` and write each to the Zarr store ``store`` as it finishes (its
    rows, its record, its status last), or keep their rows for the caller when ``store`` is
    None. Cases the store already shows done or failed (an earlier attempt of this task,
    before its worker died) are not run again. A case past ``case_timeout`` s is failed and
    the task ends there: the cases after it are returned in ``rest`` (to run again on a fresh
    worker process, the stuck case's thread dies with this one).

    Returns
    -------
    dict
        ``metas`` (the metadata of each case run or found finished, in order), ``rows``
        ({index: {name: values}} of the done cases, without a store), ``rest`` (indices not
        run), ``stuck`` (a case timed out: restart this worker), ``found`` (cases found
        finished in the store) and ``worker`` (this worker's address).
    """
    from dtdyn.app._batch.store import STATUS_PENDING, AsyncWriter, Writer

    out = {"metas": [], "rows": {} if store is None else None, "rest": [], "stuck": False,
           "found": 0, "worker": _address()}
    writer = None
    if store is not None:
        base = Writer(store, list(layout["vars"]))
        state = base.status([s.index for s in specs])
        todo = []
        for spec in specs:
            status, record = state[spec.index]
            if status != STATUS_PENDING:
                out["metas"].append({**json.loads(record), "index": spec.index,
                                     "status": status, "found": True})
                out["found"] += 1
            else:
                todo.append(spec)
        specs = todo
        writer = AsyncWriter(base)
    try:
        for pos, spec in enumerate(specs):
            meta, arrays, stuck = _timed(shared, spec, reducers, check, layout, case_timeout)
            out["metas"].append(meta)
            rows = None if arrays is None else {name: values
                                                for name, (dims, values) in arrays.items()}
            if writer is not None:
                writer.put(spec.index, rows, _record(meta))
            elif rows is not None:
                out["rows"][spec.index] = rows
            if stuck:
                out["stuck"] = True
                out["rest"] = [s.index for s in specs[pos + 1:]]
                break
    finally:
        if writer is not None:
            writer.close()
    return out


#: the fields of a case's metadata kept in the store's case_record
RECORD = ("status", "message", "backend", "worker", "run_time", "max_rel_error",
          "max_residual", "error_estimate", "warnings")


def _record(meta: dict) -> dict:
    return {k: meta.get(k, [] if k == "warnings" else "") for k in RECORD}
