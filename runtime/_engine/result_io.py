"""Saving and loading a `Response` with its metadata: .npz, .nc (netCDF via xarray) or .csv.

The file extension chooses the format; `check_result_path` refuses an unknown one (and a folder
that does not exist or cannot be written) before a run starts. Every write is atomic: a failed
write leaves no partial file and an existing file untouched.

- ``.npz``: the arrays ``t``, ``outputs``, ``x``/``v``/``a`` (those stored), ``dof_names``
  (when known), array-valued ``info`` entries as ``info.<key>``, and the JSON text of the
  scalar metadata as ``dtdyn_metadata``; read with ``allow_pickle=False``.
- ``.nc``: an xarray Dataset with dimensions ``time`` and ``dof`` (netCDF 3 through SciPy: no
  other library needed besides xarray), the metadata as the attribute ``dtdyn_metadata``.
- ``.csv``: one plain table that pandas (``pandas.read_csv``) and spreadsheets read with their
  defaults: one header row, ``t [s]`` then one column per stored quantity and DOF named by
  quantity, DOF and unit (``x top [m]``, ``v main.1 [rad/s]``, ``a_abs 4 [m/s^2]``; the DOF's
  name where the model has one, else its 0-based index; ``g 0 [N]``, ``z 0 [m]`` per element
  and internal state), values written with 17 significant digits (they read back bitwise).
  The metadata goes to the JSON sidecar ``<name>.csv.json`` next to it: the run info (array
  entries too), the model summary and versions, the outputs, DOF names and kinds, the column
  layout and the table's SHA-256. Both files are renamed into place only once both are
  complete, the table last. `load_result` also reads the earlier single-file format (metadata
  as a first comment line ``# dtdyn_metadata: {...}``).
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import zipfile
import zlib
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic, write_atomic_files
from dtdyn._engine.extras import require
from dtdyn._engine.result import DOF_QUANTITIES as QUANTITIES
from dtdyn._engine.result import ELEMENT_QUANTITIES
from dtdyn._engine.version import VERSION

FORMATS = (".npz", ".nc", ".csv")
_META_KEY = "dtdyn_metadata"
#: the ``format`` entry of a CSV's JSON sidecar
CSV_FORMAT = "dtdyn result table"
CSV_FORMAT_VERSION = 1
#: the kinds fields a CSV sidecar (and .npz, .nc metadata) keeps
_KIND_FIELDS = ("dof_kinds", "element_kinds", "state_kinds")


def sidecar_path(path) -> Path:
    """The JSON metadata sidecar of a CSV result: ``x.csv`` -> ``x.csv.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")


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
    if path.suffix.lower() == ".csv" and sidecar_path(path).is_dir():
        raise ValueError(f"{str(path)!r}: its metadata sidecar {str(sidecar_path(path))!r} is "
                         "a folder")
    return path


def _versions() -> dict:
    import scipy

    return {"dtdyn": VERSION, "numpy": np.__version__, "scipy": scipy.__version__}


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


def _kinds(response) -> dict:
    """The DOF, element and state kinds the response has (only those set)."""
    return {k: list(getattr(response, k)) for k in _KIND_FIELDS
            if getattr(response, k, None) is not None}


def _metadata_dict(response) -> dict:
    info, _ = _split_info(response.info)
    meta = dict(response.meta)
    meta.setdefault("versions", _versions())
    return {"info": _json_safe(info), "meta": _json_safe(meta), **_kinds(response)}


def _metadata(response) -> str:
    return json.dumps(_metadata_dict(response), allow_nan=True)


def save_result(response, path) -> Path:
    """Write ``response`` to ``path``; the extension chooses the format (module docstring)."""
    path = check_result_path(path)
    if path.suffix.lower() == ".csv":
        table, sidecar = _csv_files(response, path)
        # the sidecar first, the table last: a reader that sees the new table sees its metadata
        write_atomic_files([(sidecar_path(path), lambda fh: fh.write(sidecar)),
                            (path, lambda fh: fh.write(table))])
        return path
    writer = {".npz": _write_npz, ".nc": _write_nc}[path.suffix.lower()]
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


TIME_COLUMN = "t [s]"


def column_names(response) -> list[str]:
    """The table's column names: ``t [s]``, then ``<quantity> <DOF> [<unit>]`` per stored
    quantity and DOF (the DOF's name, else its 0-based index; units by `Response.units`), then
    ``g <element> [<unit>]`` and ``z <state> [<unit>]``."""
    names = [TIME_COLUMN]
    for q in _stored(response):
        names += [f"{q} {response.dof_label(j)} [{unit}]"
                  for j, unit in enumerate(response.units(q))]
    for q in _stored_elements(response):
        names += [f"{q} {j} [{unit}]" for j, unit in enumerate(response.units(q))]
    return names


def _layout(response) -> list:
    """[[quantity, number of columns], ...] after ``t``, in the table's order."""
    return [[q, int(np.asarray(getattr(response, q)).shape[1])]
            for q in _stored(response) + _stored_elements(response)]


def _columns(response):
    """(column names, the table as one (n_samples, n_columns) array)."""
    n = np.asarray(response.t).size
    parts = [np.asarray(response.t, dtype=float).reshape(n, 1)]
    for q in _stored(response) + _stored_elements(response):
        values = np.asarray(getattr(response, q))
        if values.ndim != 2 or values.shape[0] != n:
            raise ValueError(f"{q} has shape {values.shape}; a table needs ({n}, columns) "
                             f"for the {n} samples of t")
        parts.append(values)
    return column_names(response), np.hstack(parts)


def _header_line(names) -> str:
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerow(names)  # quotes a name holding a comma
    return text.getvalue()


def _csv_files(response, path: Path) -> tuple[bytes, bytes]:
    """(table bytes, sidecar bytes) of ``response`` saved as ``path``."""
    names, table = _columns(response)
    text = io.StringIO()
    text.write(_header_line(names))
    np.savetxt(text, table, fmt="%.17g", delimiter=",")
    data = text.getvalue().encode("utf-8")
    _, arrays = _split_info(response.info)
    sidecar = {"format": CSV_FORMAT, "version": CSV_FORMAT_VERSION, "table": path.name,
               "table_sha256": hashlib.sha256(data).hexdigest(), "n_samples": int(table.shape[0]),
               "columns": names, "layout": _layout(response),
               "outputs": [int(d) for d in np.asarray(response.outputs)],
               "dof_names": None if response.dof_names is None else
               [str(n) for n in response.dof_names],
               **_metadata_dict(response),
               "info_arrays": {k: {"dtype": v.dtype.str, "shape": list(v.shape),
                                   "values": v.ravel().tolist()}
                               for k, v in arrays.items() if v.dtype.kind in "biuf"}}
    return data, (json.dumps(sidecar, indent=1, allow_nan=True) + "\n").encode("utf-8")


def to_dataframe(response):
    """`Response.to_dataframe`: the CSV table as a pandas DataFrame."""
    pd = require("pandas", "pandas", "Response.to_dataframe")
    names, table = _columns(response)
    return pd.DataFrame(table, columns=names)


def load_result(path):
    """Read a result written by `Response.save` (.npz, .nc or .csv) back into a `Response`, or
    by `HarmonicBalanceResult.save` (.npz or .csv; `dtdyn._engine.curve_io`) into a
    `HarmonicBalanceResult`.

    A ``.csv`` is read with its JSON sidecar ``<name>.csv.json`` (the metadata, DOF names and
    kinds, the column layout): a missing sidecar or a header that differs from it is a
    ValueError; a table whose bytes changed since it was saved (its SHA-256 differs) is read
    as it is now, with a warning. The single-file CSV of earlier releases (metadata as a first
    comment line) is read too.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd, tempfile, pathlib
    >>> r = dd.chain_response([1.0], [4.0], [0.1], np.ones(11), 0.1, quantities=("x",))
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "r.npz"
    >>> _ = r.save(path)
    >>> back = dd.load_result(path)
    >>> bool(np.array_equal(back.x, r.x)), back.v is None, back.info["scheme"]
    (True, True, 'newmark')
    >>> back = dd.load_result(r.save(path.with_suffix(".csv")))   # r.csv and r.csv.json
    >>> bool(np.array_equal(back.x, r.x)), back.info["scheme"]
    (True, 'newmark')
    >>> c = dd.harmonic_balance(np.eye(1), [[0.05]], np.eye(1), elements=[dd.Cubic(0, k3=0.1)],
    ...                         force_dofs=[0], force=[0.05], freqs_hz=(0.1, 0.3), harmonics=3)
    >>> back = dd.load_result(c.save(path.with_name("frc.csv")))   # frc.csv and frc.csv.json
    >>> type(back).__name__, bool(np.array_equal(back.harmonics, c.harmonics))
    ('HarmonicBalanceResult', True)

    Parameters
    ----------
    path : str or Path
        A file written by `Response.save` or `HarmonicBalanceResult.save` (for a ``.csv``,
        with its sidecar next to it).

    Returns
    -------
    Response or HarmonicBalanceResult
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{str(path)!r}: unknown result format {suffix or '(none)'!r}; "
                         f"use one of {', '.join(FORMATS)}")
    if not path.is_file():
        raise FileNotFoundError(f"{str(path)!r}: no such result file")
    reader = {".npz": _read_npz, ".nc": _read_nc, ".csv": _read_csv}[suffix]
    from dtdyn._engine import curve_io
    if suffix != ".nc" and curve_io.is_curve(path):   # a HarmonicBalanceResult's file
        read_curve = {".npz": curve_io.read_npz, ".csv": curve_io.read_csv}[suffix]

        def reader(path):
            return read_curve(path, curve_type)
    try:
        return reader(path)
    except (KeyError, ValueError, OSError, json.JSONDecodeError, zipfile.BadZipFile, EOFError,
            zlib.error) as exc:  # a truncated or empty .npz: BadZipFile, EOFError, zlib.error
        raise ValueError(f"{str(path)!r} is not a dtdyn result file ({suffix}; "
                         f"{path.stat().st_size:,} bytes): {type(exc).__name__}: "
                         f"{exc}") from None


#: the result classes a curve file (`dtdyn._engine.curve_io`) may name: public names of dtdyn
CURVE_TYPES = ("HarmonicBalanceResult",)


def curve_type(name: str):
    """The class of a saved curve by its public name, ``dtdyn.<name>``: looked up in the loaded
    package, not imported (the engine imports no layer above it; `load_result` is reached through
    ``dtdyn``, so the package is loaded by then)."""
    if name not in CURVE_TYPES:
        raise ValueError(f"the file holds a {name!r}; dtdyn reads curves of "
                         f"{', '.join(CURVE_TYPES)}")
    import sys
    return getattr(sys.modules["dtdyn"], name)


def check_table(table, rows: int, header, data: bytes, meta: dict, sidecar: Path, path: Path):
    """A CSV table's shape against its sidecar (ValueError), its bytes against the sidecar's
    SHA-256 (a warning: the values are read as they are now)."""
    if table.shape != (rows, len(header)):
        raise ValueError(f"the table is {table.shape[0]} x {table.shape[1]}; {sidecar.name!r} "
                         f"says {rows} x {len(header)}")
    if hashlib.sha256(data).hexdigest() != meta.get("table_sha256"):
        from dtdyn._engine.public import warn
        warn(f"{path.name} changed after it was saved (its SHA-256 differs from the one in "
             f"{sidecar.name}); its values are read as they are now", UserWarning)


def _build(t, outputs, quantities: dict, metadata, dof_names=None, arrays=None):
    from dtdyn._engine.result import Response
    meta = json.loads(metadata) if isinstance(metadata, str) else metadata
    info = dict(meta["info"])
    info.update(arrays or {})
    kinds = {k: tuple(str(v) for v in meta[k]) for k in _KIND_FIELDS if meta.get(k) is not None}
    return Response(np.asarray(t, dtype=float), np.asarray(outputs, dtype=np.int64),
                    **{q: quantities.get(q) for q in QUANTITIES + ELEMENT_QUANTITIES},
                    info=info, meta=meta["meta"],
                    dof_names=None if dof_names is None else tuple(str(n) for n in dof_names),
                    **kinds)


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
    sidecar = sidecar_path(path)
    data = path.read_bytes()
    if data.startswith(f"# {_META_KEY}: ".encode()):
        return _read_commented_csv(path)
    if not sidecar.is_file():
        raise ValueError(f"its metadata sidecar {sidecar.name!r} is missing (Response.save and "
                         "dtdyn simulate --out write it next to the table)")
    meta = json.loads(sidecar.read_text(encoding="utf-8"))
    if not isinstance(meta, dict) or meta.get("format") != CSV_FORMAT:
        raise ValueError(f"{sidecar.name!r} is not the sidecar of a dtdyn table (format "
                         f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    if meta.get("version", 0) > CSV_FORMAT_VERSION:
        raise ValueError(f"{sidecar.name!r} has format version {meta['version']}; this dtdyn "
                         f"reads up to {CSV_FORMAT_VERSION}: update dtdyn")
    text = io.StringIO(data.decode("utf-8"))
    header = next(csv.reader([text.readline()]), [])
    if header != meta["columns"]:
        raise ValueError(f"its header {header[:4]}... differs from the columns in "
                         f"{sidecar.name!r} {meta['columns'][:4]}...")
    table = np.loadtxt(text, delimiter=",", ndmin=2)
    check_table(table, meta["n_samples"], header, data, meta, sidecar, path)
    quantities, start = {}, 1
    for q, width in meta["layout"]:
        quantities[q] = np.ascontiguousarray(table[:, start:start + width])
        start += width
    arrays = {k: np.array(v["values"], dtype=np.dtype(v["dtype"])).reshape(v["shape"])
              for k, v in meta.get("info_arrays", {}).items()}
    return _build(table[:, 0], meta["outputs"], quantities, meta, meta.get("dof_names"), arrays)


def _read_commented_csv(path: Path):
    """The single-file CSV of earlier releases: ``# dtdyn_metadata: {...}``, then ``t,x[0],...``."""
    with open(path, encoding="utf-8") as fh:
        first = fh.readline()
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
