"""The Zarr store of a batch: its layout, the per-case writes, the per-case status, resuming.

Layout (Zarr format 2, consolidated metadata; ``xarray.open_zarr`` reads it)::

    case                      0 .. n_cases - 1
    time, output              the samples and the stored DOFs (output_name: matrices scenes'
                              DOF names); period: the srs reducer's periods
    x, v, a, a_abs, x_abs     (case, time, output)   time histories (reduce=None or "history")
    peak_x, rms_x, ...        (case, output)          reductions (dtdyn.app._batch.reducers)
    psa                       (case, period, output)
    welch_x, ...              (case, freq_hz, output)  the welch reducer's PSDs (welch_dof: case)
    status                    (case,)  "pending", "done" or "failed"
    case_record               (case,)  JSON: the finished case's metadata and warnings
    case_hash                 (case,)  the case's content hash (scene after its variations,
                              files, seed, reducers, check): what a resumed batch matches
    seed                      (case,)  the seed of the case's first random load (-1: none)
    params                    (case,)  the case's overrides as JSON
    <dotted key>              (case,)  each varied key as a coordinate (e.g. "ground.scale")
    attrs["dtdyn_batch"]      JSON: the scenes, the reducers, the root seed, the versions, the
                              code version and reducers a resume checks ("resume"), and once
                              the batch has finished its summary
    written when the batch finishes (from case_record):
    message                   (case,)  the failure's message, or the warnings of a done case
    backend, worker           (case,)  what ran the case and where
    run_time                  (case,)  s, on the worker: parse, run and reduce
    max_rel_error             (case,)  linear cases: against exact_response (NaN: not checked)
    max_residual              (case,)  nonlinear cases: the largest final Newton residual
    error_estimate            (case,)  the run's error estimate (info["error_estimate"]; NaN: none)

The store is created (under a temporary name, renamed to ``out`` once its metadata is
complete) when the warm-up has given the layout; then every case is written as it finishes:
its rows of every variable (NaN for a failed case), its ``case_record``, and last its
``status``. Each write replaces a whole chunk file atomically (a new file renamed over the
old one), so a batch killed at any moment leaves chunks that are either before or after a
write, and a case whose status is not "done" or "failed" is "pending": run again on resume.
Every variable is chunked along ``case`` by `store_chunk` cases; a task owns whole chunks, so
no two tasks write the same chunk file.

The chunk writes are plain Zarr v2 (numcodecs' codecs named in each array's ``.zarray``):
zarr-python's own ``array[i] = row`` costs about 1 ms of CPU per array per case on this
machine, a direct chunk write a third of it, done in a thread beside the next case.
"""
from __future__ import annotations

import hashlib
import json
import os
import queue
import shutil
import threading
import uuid
from pathlib import Path

import numpy as np

__all__ = ["ResumeMismatchError", "check_out", "create", "Writer", "AsyncWriter", "read_state",
           "finish", "reset", "code_version", "store_chunk", "STORE_CHUNK_BYTES", "ZARR_FORMAT",
           "STATUS_PENDING"]

ZARR_FORMAT = 2
#: at most about this many bytes of a case's values per chunk along ``case``: each finished
#: case rewrites its chunk, so a chunk of c cases costs c / 2 case-sizes of writes per case
STORE_CHUNK_BYTES = 1 << 20
STATUS_PENDING = "pending"
#: the per-case variables a batch writes as it goes (besides the reducers' variables)
RUN_VARS = ("status", "case_record")
#: the per-case metadata variables written when the batch finishes, from case_record
FINAL_VARS = ("message", "backend", "worker", "run_time", "max_rel_error", "max_residual",
              "error_estimate")


class ResumeMismatchError(ValueError):
    """``run_batch(..., resume=True)`` on a store whose cases, reducers or code version are not
    this batch's (or that was not written by a resumable batch): the message says what
    differs."""


def check_out(out, overwrite: bool, resume: bool = False) -> Path:
    """``out`` as a Path after checking it can be written: a ``.zarr`` name in an existing,
    writable folder; an existing store only with ``overwrite`` or ``resume``."""
    path = Path(out)
    if path.suffix.lower() != ".zarr":
        raise ValueError(f"out = {str(path)!r}: a batch writes a Zarr store; give a name ending "
                         "in .zarr")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"out = {str(path)!r}: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"out = {str(path)!r}: the folder {str(folder)!r} is not writable")
    if path.exists() and not (overwrite or resume):
        raise ValueError(f"out = {str(path)!r} exists; remove it, pass resume=True to run its "
                         "cases not yet done or overwrite=True to replace it (CLI: --resume, "
                         "--overwrite)")
    if path.exists() and not path.is_dir():
        raise ValueError(f"out = {str(path)!r} exists and is not a Zarr store (a folder)")
    return path


def code_version() -> dict:
    """What a resumed batch must match: dtdyn's version and the hash of the generated
    kernels' manifest (generated/manifest.json)."""
    import dtdyn
    import dtdyn.generated

    manifest = Path(dtdyn.generated.__file__).with_name("manifest.json")
    try:
        digest = hashlib.sha256(manifest.read_bytes()).hexdigest()[:16]
    except OSError:
        digest = "none"
    return {"dtdyn": dtdyn.__version__, "generated": digest}


def store_chunk(task_size: int, case_bytes: int) -> int:
    """Cases per chunk along ``case``: at most the task size, at most about
    `STORE_CHUNK_BYTES` of values (at least one case)."""
    return max(1, min(int(task_size), STORE_CHUNK_BYTES // max(int(case_bytes), 1)))


def _replace(src: Path, dst: Path) -> None:
    """Put the folder ``src`` at ``dst``, replacing an existing ``dst`` only once ``src`` is in
    place (the old one is removed after)."""
    if dst.exists():
        old = dst.with_name(f".{dst.name}.{uuid.uuid4().hex[:8]}.old")
        os.replace(dst, old)
        try:
            os.replace(src, dst)
        except OSError:  # put the old store back: never leave the user without one
            os.replace(old, dst)
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(src, dst)


def create(out: Path, layout: dict, n_cases: int, chunk: int, case_coords: dict,
           fixed: dict, attrs: dict) -> None:
    """Write the store's metadata, coordinates and the per-case variables known before the
    run (``fixed``: seed, params, case_hash), every status "pending"; the data chunks are left
    to the cases (unwritten chunks read as NaN). Written under a temporary name and renamed
    to ``out`` (replacing an existing store) once complete."""
    import dask.array as da
    import xarray as xr
    import zarr

    coords = {"case": ("case", np.arange(n_cases))}
    for name, values in layout["coords"].items():
        dim = "output" if name == "output_name" else name
        coords[name] = (dim, np.asarray(values))
    coords.update({k: ("case", v) for k, v in case_coords.items()})
    data = {name: (("case", *dims), da.full((n_cases, *shape), np.nan, dtype=float,
                                            chunks=(chunk, *shape)))
            for name, (dims, shape) in layout["vars"].items()}
    per_case = {"status": np.array([STATUS_PENDING] * n_cases, dtype=object),
                "case_record": np.array(["{}"] * n_cases, dtype=object)}
    per_case.update({k: (np.asarray(v, dtype=object) if np.asarray(v).dtype.kind in "OUS"
                         else np.asarray(v)) for k, v in fixed.items()})
    data.update({k: ("case", v) for k, v in per_case.items()})
    encoding = {k: {"chunks": (chunk,)} for k in per_case}
    ds = xr.Dataset(data, coords=coords)
    tmp = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.partial")
    try:
        ds.to_zarr(tmp, mode="w-", compute=False, zarr_format=ZARR_FORMAT, consolidated=False,
                   encoding=encoding)
        group = zarr.open_group(str(tmp), mode="r+", zarr_format=ZARR_FORMAT)
        group.attrs["dtdyn_batch"] = json.dumps(attrs, allow_nan=True)
        zarr.consolidate_metadata(str(tmp), zarr_format=ZARR_FORMAT)
        _replace(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


class _Array:
    """One Zarr v2 array of the store, written a chunk at a time (numcodecs)."""

    def __init__(self, folder: Path):
        import numcodecs

        meta = json.loads((folder / ".zarray").read_text())
        if meta.get("order", "C") != "C" or meta.get("zarr_format") != 2:
            raise ValueError(f"{folder}: not a C-ordered Zarr v2 array")
        self.folder = folder
        self.chunks = tuple(meta["chunks"])
        self.shape = tuple(meta["shape"])
        self.dtype = np.dtype(meta["dtype"])
        self.sep = meta.get("dimension_separator") or "."
        self.filters = [numcodecs.get_codec(f) for f in (meta.get("filters") or [])]
        self.compressor = (numcodecs.get_codec(meta["compressor"]) if meta.get("compressor")
                           else None)
        self.fill = np.nan if self.dtype.kind == "f" else ""
        if any(c != s for c, s in zip(self.chunks[1:], self.shape[1:])):
            raise ValueError(f"{folder}: chunked along more than the case dimension")

    def _file(self, k: int) -> Path:
        return self.folder / self.sep.join([str(k)] + ["0"] * (len(self.shape) - 1))

    def read_chunk(self, k: int) -> np.ndarray:
        try:
            data = self._file(k).read_bytes()
        except FileNotFoundError:
            return np.full(self.chunks, self.fill, dtype=self.dtype)
        if self.compressor is not None:
            data = self.compressor.decode(data)
        for f in reversed(self.filters):
            data = f.decode(data)
        return np.frombuffer(data, dtype=self.dtype).reshape(self.chunks).copy() \
            if self.dtype.kind != "O" else np.asarray(data, dtype=object).reshape(self.chunks)

    def write_chunk(self, k: int, values: np.ndarray) -> None:
        data = np.ascontiguousarray(values, dtype=self.dtype)
        for f in self.filters:
            data = f.encode(data)
        if self.compressor is not None:
            data = self.compressor.encode(data)
        path = self._file(k)
        tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}")
        with open(tmp, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)   # a reader (or a kill) sees the old chunk or the new one

    def readable(self, k: int) -> bool:
        """Whether chunk ``k`` is absent or decodes (a power cut can leave a damaged one)."""
        try:
            self.read_chunk(k)
        except Exception:  # noqa: BLE001 - any decoding error
            return False
        return True

    def read(self, damaged: set | None = None) -> np.ndarray:
        """The whole array; with ``damaged``, a chunk that does not decode reads as its fill
        and its number is added to the set."""
        n = self.shape[0]
        c = self.chunks[0]
        parts = []
        for k in range(-(-n // c)):
            try:
                parts.append(self.read_chunk(k))
            except Exception:  # noqa: BLE001 - a damaged chunk
                if damaged is None:
                    raise
                damaged.add(k)
                parts.append(np.full(self.chunks, self.fill, dtype=self.dtype))
        return np.concatenate(parts)[:n] if parts else np.empty((0, *self.shape[1:]),
                                                                 dtype=self.dtype)


class Writer:
    """Writes finished cases into a store: their rows (NaN for a failed case), then their
    ``case_record``, then their ``status`` (each chunk file replaced atomically)."""

    def __init__(self, path, names):
        self.path = Path(path)
        self.arrays = {name: _Array(self.path / name) for name in (*names, *RUN_VARS)}
        self.names = tuple(names)

    def write(self, cases: list) -> None:
        """``cases``: [(index, {name: values} or None, record (dict))], records with their
        ``status``. All rows of every array first, then the records, then the statuses."""
        if not cases:
            return
        order = [*self.names, "case_record", "status"]
        for name in order:
            array = self.arrays[name]
            c = array.chunks[0]
            by_chunk: dict[int, list] = {}
            for index, rows, record in cases:
                by_chunk.setdefault(index // c, []).append((index, rows, record))
            for k, items in by_chunk.items():
                values = array.read_chunk(k)
                for index, rows, record in items:
                    if name == "status":
                        values[index - k * c] = record["status"]
                    elif name == "case_record":
                        values[index - k * c] = json.dumps(_plain(record), allow_nan=True)
                    elif rows is None or name not in rows:
                        values[index - k * c] = np.nan
                    else:
                        values[index - k * c] = rows[name]
                array.write_chunk(k, values)

    def status(self, indices) -> dict:
        """{index: (status, record)} of the given cases as the store has them now."""
        out = {}
        st, rec = self.arrays["status"], self.arrays["case_record"]
        c = st.chunks[0]
        chunks = {}
        for i in indices:
            k = i // c
            if k not in chunks:
                chunks[k] = (st.read_chunk(k), rec.read_chunk(k))
            s, r = chunks[k]
            out[i] = (str(s[i - k * c]), str(r[i - k * c]))
        return out


class AsyncWriter:
    """A `Writer` in a thread beside the cases: `put` queues a finished case, `close` waits
    until every queued case is written (and raises the writer's error, if any). Cases queued
    while a write runs are written together (one write per chunk)."""

    def __init__(self, writer: Writer):
        self.writer = writer
        self.queue: queue.Queue = queue.Queue()
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="dtdyn-batch-writer", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        stop = False
        while not stop:
            batch = [self.queue.get()]
            while True:
                try:
                    batch.append(self.queue.get_nowait())
                except queue.Empty:
                    break
            stop = any(item is None for item in batch)
            cases = [item for item in batch if item is not None]
            if self.error is None:
                try:
                    self.writer.write(cases)
                except BaseException as exc:  # noqa: BLE001 - raised by close()
                    self.error = exc

    def put(self, index: int, rows, record: dict) -> None:
        if self.error is not None:
            raise self.error
        self.queue.put((index, rows, record))

    def close(self) -> None:
        self.queue.put(None)
        self.thread.join()
        if self.error is not None:
            raise self.error


def _plain(record: dict) -> dict:
    """A case's metadata as JSON-able values (warning categories by name)."""
    out = {}
    for key, value in record.items():
        if key == "warnings":
            value = [[c if isinstance(c, str) else c.__name__, str(m)] for c, m in value]
        elif isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out


def read_state(path: Path, check_chunks: bool = False) -> dict:
    """What a resumed batch needs of an existing store: its attributes (``dtdyn_batch``),
    ``case_hash``, ``status`` and ``case_record`` (parsed) per case, the layout (variables'
    dims and shapes without ``case``, coordinates) and the chunk along ``case``. Raises
    ResumeMismatchError when ``path`` is not a batch store that can be resumed. With
    ``check_chunks``, every chunk of the data is decoded: the cases of a chunk that does not
    decode (a write the file system lost in a power cut) read as pending, the chunk removed."""
    import zarr

    try:
        group = zarr.open_group(str(path), mode="r", zarr_format=ZARR_FORMAT)
        attrs = json.loads(group.attrs["dtdyn_batch"])
    except Exception as exc:  # noqa: BLE001 - anything unreadable: not a batch store
        raise ResumeMismatchError(f"out = {str(path)!r} is not a batch store that can be "
                                  f"resumed ({type(exc).__name__}: {exc})") from None
    missing = [k for k in ("case_hash", *RUN_VARS) if k not in group]
    if "resume" not in attrs or missing:
        raise ResumeMismatchError(
            f"out = {str(path)!r} was written without what a resume needs (no "
            f"{', '.join(missing) or 'resume attributes'}: a dtdyn before resumable batches); "
            "pass overwrite=True to run the batch again")
    arrays = {k: _Array(path / k) for k in ("case_hash", *RUN_VARS)}
    damaged: set = set()
    status = [str(s) for s in arrays["status"].read(damaged if check_chunks else None)]
    records = []
    for r in arrays["case_record"].read(damaged if check_chunks else None):
        try:
            records.append(json.loads(str(r) or "{}"))
        except ValueError:
            records.append({})
    hashes = [str(h) for h in arrays["case_hash"].read()]
    params = ([str(p) for p in _Array(path / "params").read()] if "params" in group
              else [""] * len(status))
    skip = {"case", "status", "case_record", "case_hash", "seed", "params", *FINAL_VARS}
    layout_vars, coords = {}, {}
    for name, array in group.arrays():
        dims = tuple(array.attrs.get("_ARRAY_DIMENSIONS", ()))
        if name in skip or not dims:
            continue
        if dims[0] == "case":
            if name in attrs.get("resume", {}).get("vars", ()):
                layout_vars[name] = (dims[1:], tuple(array.shape[1:]))
        else:
            coords[name] = np.asarray(array[...])
    c = arrays["status"].chunks[0]
    if check_chunks:
        _repair(path, group, attrs, status, records, damaged, c)
    return {"attrs": attrs, "hashes": hashes, "status": status, "records": records,
            "params": params, "damaged": sorted(damaged),
            "layout": {"vars": {k: layout_vars[k] for k in attrs["resume"]["vars"]
                                if k in layout_vars},
                       "coords": coords},
            "chunk": arrays["status"].chunks[0], "n": len(status)}


def _repair(path: Path, group, attrs: dict, status: list, records: list, damaged: set,
            c: int) -> None:
    """Mark pending the cases of every chunk that does not decode (``damaged`` holds those of
    status and case_record already) and remove those chunks' files."""
    names = [name for name in attrs["resume"].get("vars", ()) if name in group]
    for name in names:
        data = _Array(path / name)
        damaged |= {k for k in range(-(-len(status) // c)) if not data.readable(k)}
    cases = []
    for k in sorted(damaged):
        for name in (*names, *RUN_VARS):
            _Array(path / name)._file(k).unlink(missing_ok=True)
        for i in range(k * c, min((k + 1) * c, len(status))):
            status[i], records[i] = STATUS_PENDING, {}
            cases.append(i)
    reset(path, cases)


def reset(path: Path, indices) -> None:
    """Mark the cases ``indices`` pending again (a resume that reruns failed cases)."""
    if not indices:
        return
    arr = _Array(Path(path) / "status")
    c = arr.chunks[0]
    by_chunk: dict[int, list] = {}
    for i in indices:
        by_chunk.setdefault(i // c, []).append(i)
    for k, items in by_chunk.items():
        values = arr.read_chunk(k)
        for i in items:
            values[i - k * c] = STATUS_PENDING
        arr.write_chunk(k, values)


def finish(path: Path, meta_vars: dict, attrs: dict) -> None:
    """Write the per-case metadata from the records and the attributes, and consolidate."""
    import xarray as xr
    import zarr

    group = zarr.open_group(str(path), mode="r+", zarr_format=ZARR_FORMAT)
    for name in meta_vars:
        if name in group:
            del group[name]
    chunk = group["status"].chunks[0]
    ds = xr.Dataset({k: ("case", v) for k, v in meta_vars.items()})
    ds.to_zarr(path, mode="a", zarr_format=ZARR_FORMAT, consolidated=False,
               encoding={k: {"chunks": (chunk,)} for k in meta_vars})
    group = zarr.open_group(str(path), mode="r+", zarr_format=ZARR_FORMAT)
    group.attrs["dtdyn_batch"] = json.dumps(attrs, allow_nan=True)
    zarr.consolidate_metadata(str(path), zarr_format=ZARR_FORMAT)
