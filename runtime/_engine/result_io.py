"""Saving and loading a `Response` with its metadata: .npz, .nc (netCDF via xarray) or .csv.

The file extension chooses the format; `check_result_path` refuses an unknown one (and a folder
that does not exist or cannot be written) before a run starts. Every write is atomic: a failed
write leaves no partial file and an existing file untouched.

- ``.npz``: the arrays ``t``, ``outputs``, ``x``/``v``/``a`` (those stored), ``dof_names``
  (when known), array-valued ``info`` entries as ``info.<key>``, and the JSON text of the
  scalar metadata as ``dtdyn_metadata``; read with ``allow_pickle=False``.
- ``.nc``: an xarray Dataset with dimensions ``time`` and ``dof`` (netCDF 3 through SciPy: no
  other library needed besides xarray), the metadata as the attribute ``dtdyn_metadata``.
- ``.csv``: one table, ``t`` then one column per stored quantity and DOF (``x[3]``), values
  written with 17 significant digits (they read back bitwise); the metadata as a first comment
  line ``# dtdyn_metadata: {...}``; array-valued ``info`` entries are not kept (one table).
"""
from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn._engine.extras import require

FORMATS = (".npz", ".nc", ".csv")
QUANTITIES = ("x", "v", "a", "a_abs", "x_abs")
#: per element (g) or internal state (z), not per DOF: their columns are numbered 0, 1, ...
ELEMENT_QUANTITIES = ("g", "z")
_META_KEY = "dtdyn_metadata"


def check_result_path(path) -> Path:
    """``path`` as a Path, after checking that a result can be written there: a known extension
    (.npz, .nc, .csv), an existing, writable folder, and not a folder itself."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{str(path)!r} is a folder, not a file name")
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"{str(path)!r}: unknown result format {path.suffix or '(none)'!r}; "
                         f"use one of {', '.join(FORMATS)}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"{str(path)!r}: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"{str(path)!r}: the folder {str(folder)!r} is not writable")
    return path


def _versions() -> dict:
    import scipy

    from dtdyn import __version__
    return {"dtdyn": __version__, "numpy": np.__version__, "scipy": scipy.__version__}


def _json_safe(value):
    """Plain JSON values for the metadata (numpy scalars and small arrays become numbers and
    lists; anything else its repr)."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


def _split_info(info: dict):
    """(scalar metadata, array entries): arrays with more than one element go to the file as
    arrays, not as JSON."""
    arrays = {k: v for k, v in info.items() if isinstance(v, np.ndarray) and v.size > 1}
    return {k: v for k, v in info.items() if k not in arrays}, arrays


def _metadata(response) -> str:
    info, _ = _split_info(response.info)
    meta = dict(response.meta)
    meta.setdefault("versions", _versions())
    return json.dumps({"info": _json_safe(info), "meta": _json_safe(meta)}, allow_nan=True)


def save_result(response, path) -> Path:
    """Write ``response`` to ``path``; the extension chooses the format (module docstring)."""
    path = check_result_path(path)
    writer = {".npz": _write_npz, ".nc": _write_nc, ".csv": _write_csv}[path.suffix.lower()]
    write_atomic(path, lambda fh: writer(response, fh))
    return path


def _stored(response):
    return [q for q in QUANTITIES if getattr(response, q) is not None]


def _stored_elements(response):
    return [q for q in ELEMENT_QUANTITIES if getattr(response, q, None) is not None]


def _write_npz(response, fh) -> None:
    arrays = {"t": np.asarray(response.t), "outputs": np.asarray(response.outputs),
              _META_KEY: np.array(_metadata(response))}
    for q in _stored(response) + _stored_elements(response):
        arrays[q] = np.asarray(getattr(response, q))
    if response.dof_names is not None:
        arrays["dof_names"] = np.array(response.dof_names, dtype=str)
    for key, value in _split_info(response.info)[1].items():
        arrays[f"info.{key}"] = value
    np.savez(fh, **arrays)


def to_xarray(response):
    """The response as an xarray Dataset (dims ``time``, ``dof``; metadata in ``attrs``)."""
    xr = require("xarray", "netcdf", "Response.to_xarray")
    coords = {"time": ("time", np.asarray(response.t)),
              "dof": ("dof", np.asarray(response.outputs, dtype=np.int32))}
    if response.dof_names is not None:
        coords["dof_name"] = ("dof", np.array(response.dof_names, dtype=str))
    data = {q: (("time", "dof"), np.asarray(getattr(response, q))) for q in _stored(response)}
    data.update({q: (("time", {"g": "element", "z": "state"}[q]), np.asarray(getattr(response, q)))
                 for q in _stored_elements(response)})
    for key, value in _split_info(response.info)[1].items():
        dims = tuple(f"info_{key}_{i}" for i in range(value.ndim))
        if value.ndim >= 1 and value.shape[0] == len(response.t):
            dims = ("time",) + dims[1:]
        data[f"info.{key}"] = (dims, value)
    return xr.Dataset(data, coords=coords, attrs={_META_KEY: _metadata(response)})


def _write_nc(response, fh) -> None:
    fh.write(to_xarray(response).to_netcdf(engine="scipy"))


def _columns(response):
    names, columns = ["t"], [np.asarray(response.t)]
    for q in _stored(response):
        values = np.asarray(getattr(response, q))
        for j, dof in enumerate(np.asarray(response.outputs)):
            names.append(f"{q}[{int(dof)}]")
            columns.append(values[:, j])
    for q in _stored_elements(response):
        values = np.asarray(getattr(response, q))
        names += [f"{q}[{j}]" for j in range(values.shape[1])]
        columns += list(values.T)
    return names, np.column_stack(columns)


def _write_csv(response, fh) -> None:
    meta = json.loads(_metadata(response))
    if response.dof_names is not None:
        meta["dof_names"] = list(response.dof_names)
    names, table = _columns(response)
    text = io.StringIO()
    text.write(f"# {_META_KEY}: {json.dumps(meta)}\n")
    np.savetxt(text, table, fmt="%.17g", delimiter=",", header=",".join(names), comments="")
    fh.write(text.getvalue().encode())


def load_result(path):
    """Read a result written by `Response.save` (.npz, .nc or .csv) back into a `Response`.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd, tempfile, pathlib
    >>> r = dd.chain_response([1.0], [4.0], [0.1], np.ones(11), 0.1, quantities=("x",))
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "r.npz"
    >>> _ = r.save(path)
    >>> back = dd.load_result(path)
    >>> bool(np.array_equal(back.x, r.x)), back.v is None, back.info["scheme"]
    (True, True, 'newmark')

    Parameters
    ----------
    path : str or Path
        A file written by `Response.save`.

    Returns
    -------
    Response
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{str(path)!r}: unknown result format {suffix or '(none)'!r}; "
                         f"use one of {', '.join(FORMATS)}")
    if not path.is_file():
        raise FileNotFoundError(f"{str(path)!r}: no such result file")
    reader = {".npz": _read_npz, ".nc": _read_nc, ".csv": _read_csv}[suffix]
    try:
        return reader(path)
    except (KeyError, ValueError, OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{str(path)!r} is not a dtdyn result file ({suffix}): {exc}") from None


def _build(t, outputs, quantities: dict, metadata: str, dof_names=None, arrays=None):
    from dtdyn._engine.result import Response
    meta = json.loads(metadata)
    info = dict(meta["info"])
    info.update(arrays or {})
    return Response(np.asarray(t, dtype=float), np.asarray(outputs, dtype=np.int64),
                    **{q: quantities.get(q) for q in QUANTITIES + ELEMENT_QUANTITIES},
                    info=info, meta=meta["meta"],
                    dof_names=None if dof_names is None else tuple(str(n) for n in dof_names))


def _read_npz(path: Path):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k[5:]: z[k] for k in z.files if k.startswith("info.")}
        return _build(z["t"], z["outputs"],
                      {q: z[q] for q in QUANTITIES + ELEMENT_QUANTITIES if q in z.files},
                      str(z[_META_KEY]), z["dof_names"] if "dof_names" in z.files else None,
                      arrays)


def _read_nc(path: Path):
    xr = require("xarray", "netcdf", "load_result")
    with xr.open_dataset(path, engine="scipy") as ds:
        ds.load()
        arrays = {k[5:]: ds[k].values for k in ds.data_vars if k.startswith("info.")}
        names = ds["dof_name"].values if "dof_name" in ds.coords else None
        return _build(ds["time"].values, ds["dof"].values,
                      {q: ds[q].values for q in QUANTITIES + ELEMENT_QUANTITIES
                       if q in ds.data_vars},
                      ds.attrs[_META_KEY], names, arrays)


def _read_csv(path: Path):
    with open(path, encoding="utf-8") as fh:
        first = fh.readline()
        if not first.startswith(f"# {_META_KEY}: "):
            raise ValueError(f"the first line must be '# {_META_KEY}: ...'")
        header = fh.readline().strip().split(",")
        table = np.loadtxt(fh, delimiter=",", ndmin=2)
    meta = json.loads(first[len(f"# {_META_KEY}: "):])
    names = meta.pop("dof_names", None)
    if header[0] != "t" or table.shape[1] != len(header):
        raise ValueError("the table must start with a column t and match its header")
    outputs, quantities = [], {}
    for q in QUANTITIES:
        cols = [i for i, h in enumerate(header) if h.startswith(f"{q}[")]
        if cols:
            quantities[q] = np.ascontiguousarray(table[:, cols])
            dofs = [int(header[i][len(q) + 1:-1]) for i in cols]
            if outputs and dofs != outputs:
                raise ValueError(f"the {q} columns name other DOFs than the first quantity's")
            outputs = dofs
    for q in ELEMENT_QUANTITIES:
        cols = [i for i, h in enumerate(header) if h.startswith(f"{q}[")]
        if cols:
            quantities[q] = np.ascontiguousarray(table[:, cols])
    return _build(table[:, 0], outputs, quantities, json.dumps(meta), names)
