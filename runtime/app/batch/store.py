"""The Zarr store of a batch: its layout, the workers' block writes, the metadata, the rename.

Layout (Zarr format 2, consolidated metadata; ``xarray.open_zarr`` reads it)::

    case                      0 .. n_cases - 1
    time, output              the samples and the stored DOFs (output_name: matrices scenes'
                              DOF names); period: the srs reducer's periods
    x, v, a, a_abs, x_abs     (case, time, output)   time histories (reduce=None or "history")
    peak_x, rms_x, ...        (case, output)          reductions (dtdyn.app.batch.reducers)
    psa                       (case, period, output)
    status                    (case,)  "done" or "failed"
    message                   (case,)  the failure's message, or the warnings of a done case
    backend, worker           (case,)  what ran the case and where
    run_time                  (case,)  s, on the worker: parse, run and reduce
    max_rel_error             (case,)  linear cases: against exact_response (NaN: not checked)
    max_residual              (case,)  nonlinear cases: the largest final Newton residual
    error_estimate            (case,)  the run's error estimate (info["error_estimate"]; NaN: none)
    seed                      (case,)  the seed of the case's first random load (-1: none)
    params                    (case,)  the case's overrides as JSON
    <dotted key>              (case,)  each varied key as a coordinate (e.g. "ground.scale")
    attrs["dtdyn_batch"]      JSON: the summary (cases done and failed, wall time, cases per
                              second), the scenes, the reducers, the root seed, the versions

A failed case's values are NaN. Every variable is chunked along ``case`` by the batch's task
size, so each task writes whole chunks and no two workers write the same chunk. The store is
written under a temporary name next to ``out`` (``.<name>.<random>.partial``) and renamed to
``out`` when the batch has finished; a batch that stops on an error removes it.
"""
from __future__ import annotations

import json
import os
import shutil
import uuid
from pathlib import Path

import numpy as np

__all__ = ["check_out", "temporary_path", "create", "write_block", "finish", "discard"]

ZARR_FORMAT = 2


def check_out(out, overwrite: bool) -> Path:
    """``out`` as a Path after checking it can be written: a ``.zarr`` name in an existing,
    writable folder; an existing store only with ``overwrite``."""
    path = Path(out)
    if path.suffix.lower() != ".zarr":
        raise ValueError(f"out = {str(path)!r}: a batch writes a Zarr store; give a name ending "
                         "in .zarr")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"out = {str(path)!r}: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"out = {str(path)!r}: the folder {str(folder)!r} is not writable")
    if path.exists() and not overwrite:
        raise ValueError(f"out = {str(path)!r} exists; remove it or pass overwrite=True "
                         "(CLI: --overwrite)")
    if path.exists() and not path.is_dir():
        raise ValueError(f"out = {str(path)!r} exists and is not a Zarr store (a folder)")
    return path


def temporary_path(out: Path) -> Path:
    return out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.partial")


def create(path: Path, layout: dict, n_cases: int, chunk: int, case_coords: dict) -> None:
    """Write the store's metadata and coordinates; the data chunks are left to the workers
    (unwritten chunks read as NaN)."""
    import dask.array as da
    import xarray as xr

    coords = {"case": ("case", np.arange(n_cases))}
    for name, values in layout["coords"].items():
        dim = "output" if name == "output_name" else name
        coords[name] = (dim, np.asarray(values))
    coords.update({k: ("case", v) for k, v in case_coords.items()})
    data = {name: (("case", *dims), da.full((n_cases, *shape), np.nan, dtype=float,
                                            chunks=(chunk, *shape)))
            for name, (dims, shape) in layout["vars"].items()}
    ds = xr.Dataset(data, coords=coords)
    ds.to_zarr(path, mode="w-", compute=False, zarr_format=ZARR_FORMAT, consolidated=True)


def write_block(path, start: int, blocks: dict) -> None:
    """Write rows ``start ..`` of every variable (a worker's task: whole chunks)."""
    import zarr

    group = zarr.open_group(str(path), mode="r+", zarr_format=ZARR_FORMAT)
    for name, block in blocks.items():
        group[name][start:start + block.shape[0]] = block


def finish(path: Path, out: Path, meta_vars: dict, attrs: dict) -> None:
    """Add the per-case metadata and the attributes, consolidate, and rename to ``out``
    (replacing an existing store only after the new one is complete)."""
    import xarray as xr
    import zarr

    ds = xr.Dataset({k: ("case", v) for k, v in meta_vars.items()})
    ds.to_zarr(path, mode="a", zarr_format=ZARR_FORMAT, consolidated=False)
    group = zarr.open_group(str(path), mode="r+", zarr_format=ZARR_FORMAT)
    group.attrs["dtdyn_batch"] = json.dumps(attrs, allow_nan=True)
    zarr.consolidate_metadata(str(path), zarr_format=ZARR_FORMAT)
    if out.exists():
        old = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.old")
        os.replace(out, old)
        try:
            os.replace(path, out)
        except OSError:  # put the old store back: never leave the user without one
            os.replace(old, out)
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(path, out)


def discard(path: Path | None) -> None:
    if path is not None:
        shutil.rmtree(path, ignore_errors=True)
