"""What runs on a Dask worker: the shared files materialized once, the C warm-up, the cases of
one task, their reductions and the write of the task's block of the Zarr store.

Nothing here holds a ctypes object across tasks or ships one: every worker process compiles
(or loads from its on-disk cache) the kernels it needs on its first case, through
`dtdyn._engine.cbuild`, and keeps them in its own memory.
"""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dtdyn._engine.errors import (DtdynFallbackWarning, DtdynStepStabilityError,
                                  DtdynUnstableError, NewtonError, SingularMassError)
from dtdyn.app.batch.cases import CaseSpec, Shared, apply_overrides

__all__ = ["CBackendError", "RUN_ERRORS", "META", "NameClash", "probe", "run_chunk",
           "run_case", "cleanup"]

#: the errors expected to fail one case (NewtonError, ...); any other Exception of a case (a
#: library bug's TypeError, a user reducer's KeyError) fails it too, with its type and
#: message: only CBackendError (and KeyboardInterrupt) stop the batch
RUN_ERRORS = (NewtonError, DtdynStepStabilityError, DtdynUnstableError, SingularMassError,
              FloatingPointError, ValueError, MemoryError)
#: the per-case metadata variables and the coordinates of a batch: no reducer may make them
META = ("index", "status", "message", "backend", "worker", "run_time", "max_rel_error",
        "max_residual", "error_estimate", "seed", "params", "case", "time", "output",
        "output_name", "period")

_FOLDERS: dict[str, Path] = {}


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
    """Remove this worker's folder of the batch ``token`` (run on every worker at the end)."""
    got = _FOLDERS.pop(token, None)
    if got is not None:
        shutil.rmtree(got, ignore_errors=True)


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
    from dtdyn.app.scene.parse import scene_from_dict

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


def _run_case(shared, spec, reducers, check, layout, coords, strict, caught):
    from dtdyn.app.batch.reducers import reducer_name
    from dtdyn.app.scene.run import run_scene

    start = time.perf_counter()
    meta = {"index": spec.index, "status": "failed", "message": "", "backend": "",
            "run_time": np.nan, "max_rel_error": np.nan, "max_residual": np.nan,
            "error_estimate": np.nan, "seed": spec.seed, "worker": _address()}
    where = folder(shared)
    try:
        scene = scene_of(shared, spec, where)
        if _wants_c(scene):
            _require_compiler()
        response, report = run_scene(scene, check=check)
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


def probe(shared: Shared, specs: list[CaseSpec], reducers, check: bool) -> dict:
    """The warm-up of one worker: the C compiler required, then the given cases in order until
    one succeeds (its kernels compiled or loaded into this process). Returns the batch layout
    (its variables' dims and shapes, the coordinates), the case's run time, and the messages
    of the cases that failed before it."""
    failed = []
    for spec in specs:
        meta, arrays = run_case(shared, spec, reducers, check, coords=True, strict=True)
        if arrays is None:
            failed.append(f"case {spec.index}: {meta['message']}")
            continue
        coords = meta["coords"]
        return {"vars": {k: (tuple(d), tuple(np.shape(v))) for k, (d, v) in arrays.items()},
                "coords": coords, "dt": meta["dt"], "case": spec.index,
                "run_time": meta["run_time"], "failed": failed, "worker": _address()}
    return {"vars": None, "failed": failed, "worker": _address()}


def run_chunk(shared: Shared, specs: list[CaseSpec], reducers, check: bool, layout: dict,
              store: str | None, start: int):
    """Run the cases ``specs`` (indices ``start ..``) and write their block of every variable to
    the Zarr store (or return the blocks when ``store`` is None). Returns (metadata per case,
    blocks or None)."""
    metas, blocks = [], {name: np.full((len(specs), *shape), np.nan)
                         for name, (dims, shape) in layout["vars"].items()}
    for row, spec in enumerate(specs):
        meta, arrays = run_case(shared, spec, reducers, check, layout)
        metas.append(meta)
        if arrays is not None:
            for name, (dims, values) in arrays.items():
                blocks[name][row] = values
    if store is None:
        return metas, blocks
    from dtdyn.app.batch.store import write_block
    write_block(store, start, blocks)
    return metas, None
