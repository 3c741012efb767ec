"""`run_batch`: many scenes and load cases on Dask distributed, on this machine or a cluster."""
from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import sys
import time

import numpy as np

from dtdyn._engine.extras import require
from dtdyn._engine.public import warn
from dtdyn.app._batch import store, worker
from dtdyn.app._batch.cases import build_cases, case_hashes
from dtdyn.app._batch.main_guard import check_main_guard
from dtdyn.app._batch.worker import CBackendError
from dtdyn.app._batch.reducers import (Spectrum, reducer_coords, reducer_fingerprint,
                                      reducer_name, reducers_from, resolve)

__all__ = ["run_batch", "auto_chunk", "local_cluster", "TASK_BYTES", "TASKS_PER_WORKER",
           "PROBE_CASES", "WORKER_ENVIRON", "CLUSTER_CONFIG"]

#: chunk="auto": about this many tasks per worker (load balance against per-task overhead) ...
TASKS_PER_WORKER = 4
#: ... and at most this many bytes of stored values per task (the memory a task holds)
TASK_BYTES = 64 * 2**20
#: the warm-up tries the first cases in order until one succeeds, at most this many
PROBE_CASES = 10
#: failed cases listed by the printed summary (all are in the result's status and message)
LISTED_FAILURES = 10
#: the environment of the worker processes of the LocalCluster that run_batch starts: glibc malloc
#: settings and the default threads of dtdyn's C loops.
#: Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536 (its config
#: distributed.nanny.pre-spawn-environ), and setting either threshold turns off glibc's dynamic
#: mmap threshold: every array above 128 KiB a case allocates (a 100,000-sample P4 case: the
#: load, the response, the reducers' temporaries) is then a fresh mmap, zeroed page by page
#: (about 6,200 page faults a case) and unmapped when freed: a P4 case took 64 ms on such a
#: worker against 52 ms in a plain process (a 64 KiB trim threshold alone, with a high mmap
#: threshold, is as slow: the freed heap top goes back at once). These values are glibc's own
#: dynamic ceilings on 64-bit Linux (mmap above 32 MiB, return the heap's free top above twice
#: that), fixed: a worker keeps at most 64 MiB of freed heap. Other C libraries ignore them.
#: DTDYN_THREADS = 1: each worker process runs one task on one core (the C loops that can split
#: their work, such as chain_response's stable sweep, then stay on one thread)
WORKER_ENVIRON = {"MALLOC_MMAP_THRESHOLD_": str(32 * 2**20),
                  "MALLOC_TRIM_THRESHOLD_": str(64 * 2**20), "DTDYN_THREADS": "1"}
#: the Dask config of that LocalCluster: WORKER_ENVIRON before the workers start, and the
#: worker's statistical profiler (it samples the task thread's stack every 10 ms, for the
#: dashboard) off
CLUSTER_CONFIG = {"distributed.worker.profile.enabled": False,
                  **{f"distributed.nanny.pre-spawn-environ.{k}": v
                     for k, v in WORKER_ENVIRON.items()}}


def auto_chunk(n_cases: int, n_workers: int, case_bytes: int) -> int:
    """Cases per task for ``chunk="auto"``: about `TASKS_PER_WORKER` tasks per worker, each
    holding at most `TASK_BYTES` of results (at least one case)."""
    by_count = math.ceil(n_cases / (TASKS_PER_WORKER * max(n_workers, 1)))
    by_memory = max(1, TASK_BYTES // max(case_bytes, 1))
    return max(1, min(by_count, by_memory, n_cases))


def local_cluster(workers: int | None = None):
    """The LocalCluster `run_batch` starts with ``client=None``: ``workers`` processes (default
    one per CPU), one thread each, with `CLUSTER_CONFIG` (glibc's malloc thresholds of
    `WORKER_ENVIRON`, the profiler off). The caller closes it."""
    import dask
    from distributed import LocalCluster

    # the nanny lets a variable already in os.environ win over its config (and copies its
    # config into os.environ, so an earlier cluster of this process leaves 65536 there): set
    # ours in os.environ while the workers start, then put back what was there
    saved = {k: os.environ.get(k) for k in WORKER_ENVIRON}
    try:
        os.environ.update(WORKER_ENVIRON)
        with dask.config.set(CLUSTER_CONFIG):
            return LocalCluster(n_workers=int(workers or os.cpu_count() or 1),
                                threads_per_worker=1, processes=True, dashboard_address=":0",
                                silence_logs=logging.ERROR)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _case_coords(params: list[dict]) -> dict:
    """Each varied key as a per-case coordinate: numbers (NaN where a case leaves it), integers
    (when every case sets one), or text ("" where a case leaves it)."""
    keys = list(dict.fromkeys(k for p in params for k in p))
    out = {}
    for key in keys:
        values = [p.get(key) for p in params]
        given = [v for v in values if v is not None]
        if all(isinstance(v, int) and not isinstance(v, bool) for v in given) and \
                len(given) == len(values) and all(-2**63 <= v < 2**63 for v in given):
            out[key] = np.array(values, dtype=np.int64)
        elif all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in given):
            out[key] = np.array([np.nan if v is None else float(v) for v in values])
        else:
            out[key] = np.array(["" if v is None else str(v) for v in values], dtype=str)
    return out


def _meta_vars(records: list[dict], names=None) -> dict:
    """The per-case metadata variables from the cases' records (``names``: those to make)."""
    def col(key, dtype):
        default = np.nan if dtype is float else ""
        return np.array([r.get(key, default) if r.get(key) is not None else default
                         for r in records], dtype=dtype)

    out = {"status": col("status", str), "message": col("message", str),
           "backend": col("backend", str), "worker": col("worker", str),
           "run_time": col("run_time", float), "max_rel_error": col("max_rel_error", float),
           "max_residual": col("max_residual", float),
           "error_estimate": col("error_estimate", float)}
    return out if names is None else {k: out[k] for k in names}


def _in_memory(layout, n, rows, meta_vars, case_coords, attrs):
    import xarray as xr

    coords = {"case": ("case", np.arange(n))}
    for name, values in layout["coords"].items():
        coords[name] = ("output" if name == "output_name" else name, np.asarray(values))
    coords.update({k: ("case", v) for k, v in case_coords.items()})
    data = {}
    for name, (dims, shape) in layout["vars"].items():
        values = np.full((n, *shape), np.nan)
        for index, got in rows.items():
            values[index] = got[name]
        data[name] = (("case", *dims), values)
    data.update({k: ("case", v) for k, v in meta_vars.items()})
    return xr.Dataset(data, coords=coords, attrs={"dtdyn_batch": json.dumps(attrs)})


def _task_failed(specs, exc: BaseException) -> list[dict]:
    """The metadata of the cases of a task that did not return, run alone (its worker died,
    ...)."""
    try:
        message = f"{type(exc).__name__}: {exc}"
    except Exception:  # noqa: BLE001 - an exception whose str() fails
        message = f"{type(exc).__name__}: {exc!r}"
    message += " (run alone, its task did not return: its worker died or lost the scenes)"
    return [{"index": s.index, "status": "failed", "message": message, "backend": "",
             "worker": "", "run_time": np.nan, "max_rel_error": np.nan, "max_residual": np.nan,
             "error_estimate": np.nan, "seed": s.seed, "warnings": []} for s in specs]


def _stop(client, futures, timeout: float = 60.0) -> None:
    """Stop a batch's tasks: cancel those not yet running, wait (at most ``timeout`` s) for
    those a worker is running (a running task cannot be stopped: it writes its cases to the
    store as they finish), then cancel them too."""
    from distributed import wait

    if not futures:
        return
    try:
        running = {k for keys in client.processing().values() for k in keys}
        busy = [f for f in futures if f.key in running and not f.done()]
        client.cancel([f for f in futures if f not in busy])
        if busy:
            wait(busy, timeout=timeout)
    except Exception:  # noqa: BLE001 - the client may be gone: stopping is best effort
        pass
    try:
        client.cancel(futures)
    except Exception:  # noqa: BLE001
        pass


def _category(c):
    """A warning category from its class or its name (a record read back from a store)."""
    if not isinstance(c, str):
        return c
    import builtins

    from dtdyn._engine import errors
    got = getattr(errors, c, None) or getattr(builtins, c, None)
    return got if isinstance(got, type) and issubclass(got, Warning) else UserWarning


def _warning_counts(records: list[dict]) -> list[tuple]:
    """[(category, message, number of cases)] of the cases' warnings, each distinct warning
    once, the most frequent first."""
    counts: dict = {}
    for m in records:
        for c, msg in m.get("warnings", ()):
            key = (c if isinstance(c, str) else c.__name__, msg)
            counts[key] = counts.get(key, 0) + 1
    return [(_category(c), msg, k) for (c, msg), k in sorted(counts.items(),
                                                             key=lambda kv: -kv[1])]


def _summary_lines(summary: dict, records: list[dict]) -> list[str]:
    lines = [f"{summary['cases']} cases: {summary['done']} done, {summary['failed']} failed; "
             f"wall time {summary['wall_time_s']:.2f} s, {summary['cases_per_s']:.1f} cases/s "
             f"on {summary['workers']} worker(s), {summary['tasks']} tasks of up to "
             f"{summary['chunk']} cases"]
    if summary.get("skipped"):
        lines.append(f"  resumed: {summary['skipped']} case(s) finished before, "
                     f"{summary['ran']} run now")
    if summary.get("lost_tasks"):
        lines.append(f"  {summary['lost_tasks']} task attempt(s) lost with their worker and run "
                     "again")
    if summary.get("timed_out"):
        lines.append(f"  {summary['timed_out']} case(s) failed past case_timeout = "
                     f"{summary['case_timeout_s']:g} s (their workers restarted)")
    for w in summary.get("warnings", ()):
        lines.append(f"  {w['category']} x{w['cases']}: {w['message']}")
    failed = [(i, m) for i, m in enumerate(records) if m.get("status") == "failed"]
    for i, m in failed[:LISTED_FAILURES]:
        lines.append(f"  case {i} failed: {m.get('message', '')}")
    if len(failed) > LISTED_FAILURES:
        lines.append(f"  ... and {len(failed) - LISTED_FAILURES} more (the result's status and "
                     "message variables list every case)")
    return lines


def _tasks(pending: list[int], chunk: int, size: int) -> list[list[int]]:
    """The pending cases in tasks of at most ``size`` cases (at least one chunk), whole
    chunks of ``chunk`` cases each: no two tasks write the same chunk of the store."""
    groups: dict[int, list[int]] = {}
    for i in pending:
        groups.setdefault(i // chunk, []).append(i)
    tasks, current = [], []
    for group in groups.values():
        if current and len(current) + len(group) > size:
            tasks.append(current)
            current = []
        current = current + group
    if current:
        tasks.append(current)
    return tasks


def _suspicious(keys, dask_scheduler=None) -> int:
    """On the scheduler: how many times a worker died while running one of ``keys``."""
    return sum(getattr(dask_scheduler.tasks.get(k), "suspicious", 0) for k in keys)


def _lost_attempts(client, futures, seen: int) -> int:
    """The task attempts of ``futures`` lost with their worker (the scheduler's count, which
    includes the attempts it ran again by itself; else the ``seen`` lost results)."""
    try:
        return max(seen, int(client.run_on_scheduler(_suspicious, [f.key for f in futures])))
    except Exception:  # noqa: BLE001 - a scheduler without dtdyn: what the client saw
        return seen


def _restart(client, address) -> None:
    """Restart the worker process ``address`` (a timed-out case's thread still runs there)."""
    try:
        client.restart_workers([address], timeout=120)
    except Exception:  # noqa: BLE001 - no nanny, or gone already: the thread runs on
        pass


def _resume_match(path, state, hashes, params, fingerprints, check, code) -> None:
    """Refuse (ResumeMismatchError) a store whose code version, reducers, check or cases
    differ from this batch's, saying what differs."""
    info = state["attrs"]["resume"]
    problems = []
    if info.get("code") != code:
        old = info.get("code") or {}
        problems.append(f"it was written by dtdyn {old.get('dtdyn')} with the generated kernels "
                        f"{old.get('generated')}, this is dtdyn {code['dtdyn']} with "
                        f"{code['generated']} (its finished cases may differ from what this "
                        "code computes)")
    if info.get("cases") != len(hashes):
        problems.append(f"it has {info.get('cases')} cases, this batch {len(hashes)}")
    if info.get("reducers") != fingerprints:
        problems.append(f"its reducers are {info.get('reducers')}, this batch's {fingerprints}")
    if info.get("check") != bool(check):
        problems.append(f"it was run with check={info.get('check')}, this batch with "
                        f"check={bool(check)}")
    if not problems:
        differ = [i for i, (a, b) in enumerate(zip(state["hashes"], hashes)) if a != b]
        if differ:
            shown = ", ".join(str(i) for i in differ[:10]) + (" ..." if len(differ) > 10 else "")
            first = differ[0]
            problems.append(f"{len(differ)} of its {len(hashes)} cases differ from this batch's "
                            f"(their scenes after the variations, files or seeds): cases "
                            f"{shown}; case {first} has params {state['params'][first]} in the "
                            f"store and {json.dumps(params[first])} here")
    if problems:
        raise store.ResumeMismatchError(
            f"out = {str(path)!r} cannot be resumed by this batch: " + "; ".join(problems) +
            ". Resume it with the cases and the code that wrote it, or pass overwrite=True "
            "(CLI: --overwrite) to run the batch again")


def _runnable(shared, specs, unstable) -> None:
    """Refuse, before a worker starts, a base scene that no case can run (no [time] table or
    no load, and no ``vary`` key that sets one); with ``unstable``, set each linear base
    scene's ``scheme.unstable``."""
    import dataclasses

    from dtdyn.app._scene.schema import UNSTABLE, Scene, _choice

    if unstable is not None:
        _choice("unstable", unstable, UNSTABLE)
    for k, base in enumerate(shared.bases):
        if isinstance(base, Scene):
            base.require_run("run_batch")
            if unstable is not None and base.linear:
                shared.bases[k] = dataclasses.replace(base, unstable=unstable)
            continue
        varied = {key.split(".")[0].split("[")[0] for spec in specs if spec.scene == k
                  for key in spec.overrides}
        has = set(base) | varied
        if "time" not in has:
            raise ValueError(f"{shared.sources[k]}: run_batch needs a [time] table with dt and "
                             "duration (e.g. [time] dt = 0.01, duration = 1.0); the scene has "
                             "none")
        if not has & {"load", "ground", "initial"}:
            raise ValueError(f"{shared.sources[k]}: run_batch needs a load: one or more "
                             "[[load]] tables (dof, kind and that kind's fields) or a [ground] "
                             "record; the scene has neither (or an [initial] state: free "
                             "vibration)")
        if unstable is not None and not base.get("element"):
            scheme = base.get("scheme", {})
            if isinstance(scheme, dict):  # else the parser names the bad value
                shared.bases[k] = {**base, "scheme": {**scheme, "unstable": unstable}}


# noqa below: the entry point validates each keyword by name, then runs the warm-up, the rounds
# of tasks and their retries, which share the progress bar, the counts and the store
def run_batch(cases, *, vary=None, seed=None, client=None, workers=None, reduce=None,  # noqa: C901
              out=None, chunk="auto", progress=True, check=True, overwrite=False,
              unstable=None, resume=False, rerun_failed=False, case_timeout=None):
    """Run many scenes and load cases on Dask distributed: this machine or a cluster.

    Each case is a scene, run by `run_scene` on a Dask worker exactly as it runs alone (the
    same results, bitwise, on the same backend and threads: the LocalCluster's workers keep
    a chain's stable sweep on one thread, DTDYN_THREADS = 1, where a plain process takes two
    from 5,000 masses on, which agree with one to rounding). Cases are grouped into tasks of
    ``chunk`` cases; the base scenes and the files they name are scattered to the workers once; each
    worker compiles or loads its C kernels once (a warm-up before the tasks) and a worker
    without a C compiler stops the batch with an error instead of falling back to NumPy. A case
    that fails (`NewtonError`, `DtdynUnstableError`, a ValueError of the scene parser, any other
    exception, a non-finite stored value, a case that kills its worker) is recorded with its
    message and the batch goes on. A task that does not return (its worker died) runs again,
    then its cases one at a time, each alone: only a case that fails alone is failed.

    With ``out``, each case is written to the store as it finishes (its rows, its record, its
    status last): a batch stopped at any moment (an error, Ctrl-C, a killed client, a lost
    scheduler, a power cut) leaves a store holding every finished case, and
    ``resume=True`` runs only the others; the final store equals an uninterrupted run's, bit
    for bit per case.

    Parameters
    ----------
    cases : path, dict, Scene or a sequence of them
        Scene files, scene tables (the dict of a parsed TOML file, relative files from the
        current folder) or `Scene` objects (run as given, without ``vary`` or ``seed``).
    vary : path, list of dict, dict of lists or pandas.DataFrame, optional
        A table of variations, one row per case, applied to every scene of ``cases``: columns
        are dotted keys of the scene's tables (``"model.stiffness[2]"``, ``"load[0].seed"``,
        ``"ground.path"``, ``"ground.scale"``, ``"element[1].k3"``); a CSV file has them in its
        first row (an empty cell keeps the scene's value). Each case is validated by
        `scene_from_dict` on its worker, with the same named errors as a scene file.
    seed : int, optional
        Root seed: case ``i``'s random loads (``white_noise`` in ``[[load]]`` and ``[ground]``)
        take seeds from ``numpy.random.SeedSequence(seed).spawn(n_cases)[i]`` (a seed the case
        sets in ``vary`` is kept), independent of the split over tasks and workers.
    client : distributed.Client, optional
        Where to run. None starts a LocalCluster on this machine (`local_cluster`: processes,
        one thread each, ``workers`` of them, default one per CPU; glibc's malloc thresholds
        of `WORKER_ENVIRON`, the profiler off) and closes it at the end; any Client, e.g.
        ``Client("tcp://scheduler:8786")``, runs the same code on a cluster (every worker needs
        dtdyn installed and, with ``out``, the store's folder shared).
    workers : int, optional
        Worker processes of the LocalCluster (only with ``client=None``).
    reduce : str, sequence or callable, optional
        What to keep per case: None, the time histories of the stored quantities (dims case,
        time, output); or reducers computed on the workers: ``"peak"``, ``"rms"``, ``"drift"``
        (peak inter-storey drift), ``"srs"`` (the pseudo-acceleration response spectrum of each
        output's absolute acceleration, by default at 40 periods from max(0.05 s, 10 dt) to
        4 s; `dtdyn.app._batch.Spectrum` sets the periods and the damping ratio),
        ``"history"``, or callables ``f(response, scene) -> {name: value or (dims, value)}``;
        a comma-separated string or a list.
    out : path, optional
        A Zarr store (``*.zarr``) written by the workers case by case as the cases finish, so
        memory stays bounded by a task and a stopped batch keeps its finished cases (created
        when the warm-up has given the layout; per case ``status`` "pending", "done" or
        "failed"). None: the results come back in memory.
    chunk : int or "auto"
        Cases per task; "auto" gives about 4 tasks per worker, each holding at most 64 MB of
        results.
    progress : bool
        A progress bar and a summary printed at the end. The workers' warnings are collected
        (not printed per case): the summary lists each distinct one once with the number of
        cases that gave it (``SRSSamplingWarning x130: ...``); with ``progress=False`` each is
        issued once as a Python warning at the caller's line (``"130 of 130 case(s): ..."``).
    check : bool
        Linear cases: compare with `exact_response` (the ``max_rel_error`` of each case).
    overwrite : bool
        Replace an existing ``out``: it is removed when the new store is created (after the
        warm-up; a batch refused before keeps it).
    unstable : {"raise", "warn"} or None
        Linear cases whose dt is past the scheme's stability limit: fail (DtdynUnstableError)
        or run anyway with a warning; sets ``scheme.unstable`` of every linear scene (a
        ``vary`` column ``scheme.unstable`` still wins). None: each scene's own.
    resume : bool
        Continue an existing ``out``: run only its cases not done (status "pending"); its
        cases must be this batch's (matched by each case's content hash: the scene after
        its variations, the files it names, its seeds, the reducers and ``check``) and it
        must have been written by this code (``dtdyn.__version__`` and the hash of the
        generated kernels' manifest), else `ResumeMismatchError` says what differs. Without
        a store at ``out``, the batch starts one.
    rerun_failed : bool
        With ``resume``: run the store's failed cases again too.
    case_timeout : float, optional
        Seconds: a case running longer is failed (``"TimeoutError: case exceeded 60 s"``),
        its worker process restarted (the stuck computation cannot be stopped otherwise) and
        the rest of its task runs again; None: no limit.

    Returns
    -------
    xarray.Dataset
        Dims ``case``, ``time`` / ``period``, ``output``: the kept variables, NaN for failed
        cases, and per case ``status`` ("done", "failed"), ``message``, ``backend``, ``worker``,
        ``run_time``, ``max_rel_error``, ``max_residual``, ``error_estimate`` (the run's
        ``info["error_estimate"]``, NaN: none), ``seed`` (of the first random load, -1: none),
        ``params`` (JSON) and each varied key as a coordinate; ``attrs["dtdyn_batch"]`` (JSON)
        holds the summary (its ``warnings``: category, message and number of cases of each
        distinct warning; a done case's ``message`` holds its own warnings; ``ran``: the
        cases this call ran, ``skipped``: those a resumed store had finished, ``lost_tasks``:
        task attempts lost with their worker and run again, ``timed_out``: cases failed by
        ``case_timeout``), ``case_hash`` per case. Opened lazily from ``out`` when given
        (with ``case_record``, the JSON of each finished case's metadata).

    Raises
    ------
    ValueError
        Bad cases, keys, missing files, reducers or ``out``, a scene without ``[time]`` or a
        load that no ``vary`` column sets (before anything runs), reducer
        variables whose names clash (the warm-up), or no case of the first ten succeeded (the
        warm-up: nothing to take the layout from).
    dtdyn.app._batch.ResumeMismatchError
        ``resume=True`` on a store of other cases, reducers or code (a ValueError).
    dtdyn.app._batch.CBackendError
        A worker cannot run the C backend the scenes ask for.

    Examples
    --------
    >>> import dtdyn as dd
    >>> ds = dd.run_batch(dd.load_scene(), workers=1, reduce="peak", progress=False)
    >>> ds.sizes["case"], ds["peak_x"].shape, str(ds["status"].values[0])
    (1, (1, 15), 'done')
    """
    for module in ("distributed", "xarray", "zarr"):
        require(module, "batch", "run_batch")
    from distributed import as_completed
    from tqdm.auto import tqdm

    reducers = reducers_from(reduce)
    if not (chunk == "auto" or (isinstance(chunk, (int, np.integer)) and not
                                isinstance(chunk, bool) and chunk >= 1)):
        raise ValueError(f"chunk = {chunk!r}: must be 'auto' or an integer >= 1 (cases per task)")
    if workers is not None:
        if client is not None:
            raise ValueError(f"workers = {workers!r}: only for client=None (a LocalCluster); a "
                             "given client has its own workers")
        if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
            raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    if case_timeout is not None and (isinstance(case_timeout, bool) or not isinstance(
            case_timeout, (int, float, np.integer, np.floating)) or not
            math.isfinite(case_timeout) or case_timeout <= 0):
        raise ValueError(f"case_timeout = {case_timeout!r}: must be a number of seconds > 0 "
                         "(or None: no limit)")
    if resume and out is None:
        raise ValueError("resume=True continues a store: give out= (the .zarr store to resume)")
    if resume and overwrite:
        raise ValueError("resume=True and overwrite=True: resume continues the store, "
                         "overwrite replaces it; give one")
    if rerun_failed and not resume:
        raise ValueError("rerun_failed=True reruns the failed cases of a resumed store: give "
                         "resume=True too")
    if client is None:
        check_main_guard()
    shared, specs, params = build_cases(cases, vary, seed)
    _runnable(shared, specs, unstable)
    n = len(specs)
    out_path = store.check_out(out, overwrite, resume) if out is not None else None
    fingerprints = [reducer_fingerprint(r) for r in reducers]
    hashes = case_hashes(shared, specs, {"reducers": fingerprints, "check": bool(check)})
    code = store.code_version()
    state = None
    if resume and out_path.exists():
        state = store.read_state(out_path, check_chunks=True)
        _resume_match(out_path, state, hashes, params, fingerprints, check, code)
        pending = [i for i, st in enumerate(state["status"])
                   if st == store.STATUS_PENDING or (rerun_failed and st == "failed")]
        periods = state["layout"]["coords"].get("period")
        if periods is not None:   # the store's periods, not those of this run's first case
            reducers = [dataclasses.replace(r, periods=tuple(float(T) for T in periods))
                        if isinstance(r, Spectrum) and r.periods is None else r
                        for r in reducers]
    else:
        pending = list(range(n))
    case_coords = _case_coords(params)
    base_attrs = {"summary": None, "scenes": shared.sources, "root_seed": seed,
                  "reducers": [reducer_name(r) for r in reducers], "check": check,
                  "versions": _versions(), "resume": {"code": code, "reducers": fingerprints,
                                                      "check": bool(check), "cases": n}}

    own = client is None
    cluster = shared_f = None
    futures = []
    counts = {"ran": 0, "found": 0, "lost_seen": 0, "lost": 0, "timed_out": 0}
    started = time.perf_counter()
    cluster_time = warm = 0.0
    addresses, tasks, size = [], [], 0
    metas: list[dict | None] = [None] * n
    rows: dict = {}
    try:
        if pending:
            if own:
                from distributed import Client

                cluster = local_cluster(workers)
                client = Client(cluster)
            cluster_time = time.perf_counter() - started
        start = time.perf_counter()
        if pending:
            if not client.scheduler_info()["workers"]:
                client.wait_for_workers(1, timeout=120)
            addresses = list(client.scheduler_info()["workers"])
            shared_f = client.scatter(shared, broadcast=True, hash=False)
            warm = time.perf_counter()
            probe_specs = [specs[i] for i in pending[:PROBE_CASES]]
            futures = [client.submit(worker.probe, shared_f, probe_specs, reducers, check,
                                     case_timeout, workers=[a], allow_other_workers=False,
                                     pure=False)
                       for a in addresses]
            probes, lost = [], []
            for fut in futures:
                try:
                    probes.append(fut.result())
                except (CBackendError, ValueError):
                    raise
                except Exception as exc:  # noqa: BLE001 - a worker died in its warm-up
                    lost.append(f"{type(exc).__name__}: {exc}")
            futures = []
            if not probes:
                raise RuntimeError("every worker's warm-up failed:\n  " + "\n  ".join(lost))
            for p in probes:
                if p.get("stuck"):
                    _restart(client, p["worker"])
            warm = time.perf_counter() - warm
            if state is not None:
                layout = state["layout"]
            else:
                layout = probes[0]
                if layout["vars"] is None:
                    raise ValueError(f"the first {min(n, PROBE_CASES)} case(s) all failed, so "
                                     "the batch has no layout to store:\n  " +
                                     "\n  ".join(layout["failed"]))
                reducers = resolve(reducers, layout["dt"])  # default periods: first case's dt
                layout["coords"].update(reducer_coords(reducers))
                for name in layout["vars"]:
                    if name in case_coords:
                        raise worker.NameClash(f"reduce: the variable {name!r} has the name of "
                                               "a varied key (a per-case coordinate); rename it")
            case_bytes = 8 * sum(int(np.prod(shape)) for _, shape in layout["vars"].values())
            size = (auto_chunk(len(pending), len(addresses), case_bytes) if chunk == "auto"
                    else int(chunk))
            if out_path is None:
                per_chunk = size
            elif state is not None:
                per_chunk = state["chunk"]
            else:
                per_chunk = store.store_chunk(size, case_bytes)
            size = max(per_chunk, size // per_chunk * per_chunk)
            if out_path is not None and state is None:
                store.create(out_path, layout, n, per_chunk, case_coords,
                             {"seed": np.array([s.seed for s in specs], dtype=np.int64),
                              "params": np.array([json.dumps(p) for p in params], dtype=object),
                              "case_hash": np.array(hashes, dtype=object)},
                             {**base_attrs, "resume": {**base_attrs["resume"],
                                                       "vars": list(layout["vars"])}})
            elif out_path is not None and rerun_failed:
                store.reset(out_path, [i for i in pending
                                       if state["status"][i] == "failed"])
            tasks = _tasks(pending, per_chunk, size)
        holder = {"shared": shared_f}

        def submit(idx):
            return client.submit(worker.run_chunk, holder["shared"], [specs[i] for i in idx],
                                 reducers, check, layout,
                                 None if out_path is None else str(out_path), case_timeout,
                                 pure=False)

        def record(got, ac):
            failed = 0
            for m in got["metas"]:
                metas[m["index"]] = m
                counts["found" if m.get("found") else "ran"] += 1
                failed += m["status"] != "done"
            if got["rows"] is not None:
                rows.update(got["rows"])
            bar.update(len(got["metas"]))
            bar.set_postfix(failed=sum(1 for m in metas if m and m["status"] != "done"))
            if got["stuck"]:
                counts["timed_out"] += 1
                _restart(client, got["worker"])
                if got["rest"]:
                    fut = submit(got["rest"])
                    futures.append(fut)
                    ac.add(fut)
                    return fut, got["rest"]
            return None

        def run_round(round_tasks):
            """Run tasks concurrently; record those that return; the others with their error."""
            nonlocal futures
            futures = [submit(t) for t in round_tasks]
            task_of = {fut.key: t for fut, t in zip(futures, round_tasks)}
            lost = []
            ac = as_completed(list(futures))
            for fut in ac:
                try:
                    extra = record(fut.result(), ac)
                except CBackendError:
                    raise
                except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                    lost.append((task_of[fut.key], exc))
                    continue
                if extra is not None:
                    task_of[extra[0].key] = extra[1]
            counts["lost_seen"] += len(lost)
            counts["lost"] += _lost_attempts(client, futures, len(lost))
            return sorted(lost, key=lambda t: t[0][0])

        def write_failed(got):
            if out_path is not None:
                store.Writer(out_path, list(layout["vars"])).write(
                    [(m["index"], None, worker._record(m)) for m in got])

        with tqdm(total=n, initial=n - len(pending), unit="case",
                  disable=not progress or not pending, file=sys.stderr, desc="batch") as bar:
            lost = run_round(tasks) if tasks else []
            # A task that did not return died with its worker, or lost the scattered scenes
            # when every worker holding them died: maybe beside the case that killed them.
            # Its tasks run again with the scenes scattered anew, concurrently when there are
            # several (a case the store shows finished is not run again); the cases of those
            # failing again, one at a time, each alone on the cluster: only a case that fails
            # alone is failed.
            if len(lost) > 1:
                holder["shared"] = client.scatter(shared, broadcast=True, hash=False)
                lost = run_round([t for t, _ in lost])
            fresh = False   # the scenes scattered since the last failure
            for idx, _ in lost:
                for i in idx:
                    if metas[i] is not None:
                        continue   # returned by a task of the case's timed-out task mate
                    if not fresh:
                        holder["shared"] = client.scatter(shared, broadcast=True, hash=False)
                    alone = run_round([[i]])
                    for _, exc in alone:   # it failed alone: it is failed
                        got = _task_failed(specs[i:i + 1], exc)
                        write_failed(got)
                        metas[i] = got[0]
                        counts["ran"] += 1
                        bar.update(1)
                    fresh = not alone
        wall = time.perf_counter() - start
        if out_path is not None:
            final = store.read_state(out_path)
            records = final["records"]
            for i, st in enumerate(final["status"]):
                records[i] = {**records[i], "status": st}
        else:
            records = [worker._record(m) for m in metas]
        statuses = [r.get("status") for r in records]
        done, failed = statuses.count("done"), statuses.count("failed")
        warned = _warning_counts(records)
        summary = {"cases": n, "done": done, "failed": failed,
                   "pending": n - done - failed, "ran": counts["ran"] + counts["found"],
                   "skipped": n - len(pending), "lost_tasks": counts["lost"],
                   "timed_out": counts["timed_out"], "case_timeout_s": case_timeout,
                   "wall_time_s": wall,
                   "cases_per_s": (counts["ran"] + counts["found"]) / wall if wall > 0
                   else float("inf"),
                   "cluster_start_s": cluster_time if own and pending else None,
                   "warm_up_s": warm, "workers": len(addresses), "tasks": len(tasks),
                   "chunk": size,
                   "warnings": [{"category": c.__name__, "message": msg, "cases": k}
                                for c, msg, k in warned]}
        if state is not None:
            base_attrs = {**state["attrs"], "versions": base_attrs["versions"]}
        else:
            base_attrs["resume"]["vars"] = list(layout["vars"])
        attrs = {**base_attrs, "summary": summary}
        if out_path is not None:
            store.finish(out_path, _meta_vars(records, store.FINAL_VARS), attrs)
        if progress:
            print("\n".join(_summary_lines(summary, records)))
        else:  # no summary printed: each distinct warning of the cases once, at the caller
            for category, msg, k in warned:
                warn(f"{k} of {n} case(s): {msg}", category)
        if out_path is None:
            meta_vars = _meta_vars(records)
            meta_vars.update({"seed": np.array([s.seed for s in specs], dtype=np.int64),
                              "params": np.array([json.dumps(p) for p in params], dtype=str),
                              "case_hash": np.array(hashes, dtype=str)})
            return _in_memory(layout, n, rows, meta_vars, case_coords, attrs)
    except BaseException:
        if client is not None:
            _stop(client, futures)
        raise
    finally:
        if client is not None and shared_f is not None:
            try:
                client.run(worker.cleanup, shared.token)
            except Exception:  # noqa: BLE001 - best effort: a worker may be gone
                pass
        if own and client is not None:
            client.close()
            cluster.close()
    import xarray as xr
    return xr.open_zarr(out_path, zarr_format=store.ZARR_FORMAT, consolidated=True)


def _versions() -> dict:
    import dask
    import distributed
    import scipy
    import xarray
    import zarr

    from dtdyn import __version__
    return {"dtdyn": __version__, "numpy": np.__version__, "scipy": scipy.__version__,
            "dask": dask.__version__, "distributed": distributed.__version__,
            "xarray": xarray.__version__, "zarr": zarr.__version__}
