"""Saving and loading result curves: a dataclass result whose arrays run along the points of a
curve (`HarmonicBalanceResult`), as ``.npz`` or as a ``.csv`` table with a JSON sidecar.

Every field of the dataclass is saved by what it holds, so that fields added later are saved
and read back too:

- an array: real, integer, boolean and text arrays as they are; a complex array as two real
  arrays, its real and imaginary parts (``harmonics.re``, ``harmonics.im``);
- None: listed in the metadata, read back as None;
- ``info`` (a dict): its array entries of more than one element as arrays (``info.<key>``,
  complex ones as their two parts), the rest as JSON;
- any other field (numbers, strings, lists and dicts of them): JSON (a tuple reads back as a
  list, an array inside a list or dict as a list).

``.npz``: one array per array (or part), and the JSON metadata as ``dtdyn_metadata`` (read with
``allow_pickle=False``). ``.csv``: one row per point of the curve, one column per entry of each
numeric array whose first dimension is the number of points (the length of the first field):
``frequency_hz [Hz]``, ``omega [rad/s]``, ``stable``, ``x_max[0]`` (output 0),
``harmonics[0][1] re`` and ``harmonics[0][1] im`` (output 0, harmonic 1), ..., written with 17
significant digits (they read back bitwise). The other fields and the metadata go to the JSON
sidecar ``<name>.csv.json`` with the column layout and the table's SHA-256; both files are
renamed into place only once both are complete, the table last.

Which class a file holds is written in it by name and looked up among dtdyn's public names
(`dtdyn._engine.result_io.curve_type`; this module does not import the library).
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic, write_atomic_files
from dtdyn._engine.result_io import (_META_KEY, check_table, _json_safe, _split_info, _versions,
                                     check_result_path, sidecar_path)

#: the ``format`` entry of the metadata (.npz) and of a table's sidecar (.csv)
FORMAT = "dtdyn curve"
CSV_FORMAT = "dtdyn curve table"
FORMAT_VERSION = 1
FORMATS = (".npz", ".csv")
#: units of the fields that have one whatever the model: in the table's column names
UNITS = {"frequency_hz": "Hz", "omega": "rad/s", "fold_frequency_hz": "Hz"}


def check_curve_path(path) -> Path:
    """``path`` as a Path, after the checks of `check_result_path` and that its extension is
    one a curve is saved as (.npz, .csv)."""
    path = check_result_path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"{str(path)!r}: a frequency response curve is saved as .npz or .csv, "
                         f"not {path.suffix!r} (netCDF is for time histories)")
    return path


def _plain(where: str, value):
    """A JSON value for a field that is not an array (ValueError for what JSON cannot hold)."""
    if isinstance(value, dict):
        return {str(k): _plain(f"{where}[{k!r}]", v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(f"{where}[{i}]", v) for i, v in enumerate(value)]
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        return value.tolist()
    if isinstance(value, (np.bool_, np.integer, np.floating)):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"{where} holds a {type(value).__name__}: it cannot be saved (arrays, "
                     "numbers, strings, and lists and dicts of them can)")


def _fields(result):
    """(arrays {name: ndarray}, None fields [name], plain fields {name: JSON}, info dict)."""
    if not dataclasses.is_dataclass(result) or isinstance(result, type):
        raise TypeError(f"a curve result is a dataclass instance, got {type(result).__name__}")
    cls = type(result).__name__
    arrays, none, plain, info = {}, [], {}, {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if f.name == "info":
            info = dict(value or {})
        elif value is None:
            none.append(f.name)
        elif isinstance(value, np.ndarray):
            if value.dtype.kind not in "biufcU":
                raise ValueError(f"{cls}.{f.name} is an array of {value.dtype}: it cannot be "
                                 "saved (numbers, booleans and text can)")
            arrays[f.name] = value
        else:
            plain[f.name] = _plain(f"{cls}.{f.name}", value)
    return arrays, none, plain, info


def _n_points(result, arrays) -> int:
    first = dataclasses.fields(result)[0].name
    if first not in arrays or arrays[first].ndim < 1:
        raise ValueError(f"{type(result).__name__}.{first} must be an array: its length is the "
                         "number of points of the curve")
    return int(arrays[first].shape[0])


def _metadata(result, arrays, none, plain, info) -> dict:
    """The JSON metadata both formats hold."""
    scalars, info_arrays = _split_info(info)
    complex_ = sorted([k for k, v in arrays.items() if v.dtype.kind == "c"]
                      + [f"info.{k}" for k, v in info_arrays.items() if v.dtype.kind == "c"])
    return {"format": FORMAT, "version": FORMAT_VERSION, "type": type(result).__name__,
            "arrays": {k: v.dtype.str for k, v in arrays.items()}, "none": none,
            "fields": plain, "info": _json_safe(scalars),
            "info_arrays": {k: v.dtype.str for k, v in info_arrays.items()},
            "complex": complex_, "versions": _versions()}


def _put(out: dict, name: str, value: np.ndarray) -> None:
    if value.dtype.kind == "c":
        out[f"{name}.re"], out[f"{name}.im"] = value.real.copy(), value.imag.copy()
    else:
        out[name] = value


def save_curve(result, path) -> Path:
    """Write a curve result to ``path`` (.npz or .csv with its sidecar; module docstring);
    atomic. `dtdyn.load_result` reads it back."""
    path = check_curve_path(path)
    arrays, none, plain, info = _fields(result)
    n = _n_points(result, arrays)
    meta = _metadata(result, arrays, none, plain, info)
    info_arrays = _split_info(info)[1]
    if path.suffix.lower() == ".npz":
        out = {_META_KEY: np.array(json.dumps(meta, allow_nan=True))}
        for name, value in arrays.items():
            _put(out, name, value)
        for name, value in info_arrays.items():
            _put(out, f"info.{name}", value)
        write_atomic(path, lambda fh: np.savez(fh, **out))
        return path
    table, sidecar = _csv_files(path, n, arrays, info_arrays, meta)
    write_atomic_files([(sidecar_path(path), lambda fh: fh.write(sidecar)),
                        (path, lambda fh: fh.write(table))])
    return path


def _column_names(name: str, value: np.ndarray) -> list[str]:
    unit = f" [{UNITS[name]}]" if name in UNITS else ""
    parts = [" re", " im"] if value.dtype.kind == "c" else [""]
    return [name + "".join(f"[{i}]" for i in idx) + part + unit
            for idx in np.ndindex(value.shape[1:]) for part in parts]


def _block(value: np.ndarray) -> np.ndarray:
    """The (points, columns) block of a per-point array (complex: re, im of each entry)."""
    flat = value.reshape(value.shape[0], -1)
    if value.dtype.kind == "c":
        return np.stack([flat.real, flat.imag], axis=2).reshape(value.shape[0], -1)
    return flat.astype(float)


def _encode(value: np.ndarray) -> dict:
    """An array in the sidecar: dtype, shape, values (complex: re and im)."""
    out = {"dtype": value.dtype.str, "shape": list(value.shape)}
    if value.dtype.kind == "c":
        out.update(re=value.real.ravel().tolist(), im=value.imag.ravel().tolist())
    else:
        out["values"] = value.ravel().tolist()
    return out


def _decode(spec: dict) -> np.ndarray:
    dtype = np.dtype(spec["dtype"])
    if dtype.kind == "c":
        value = np.array(spec["re"], dtype=float) + 1j * np.array(spec["im"], dtype=float)
    else:
        value = np.array(spec["values"], dtype=float if dtype.kind == "f" else None)
    if value.size == 0 and dtype.kind == "U":
        value = value.astype(str)
    return value.astype(dtype).reshape(spec["shape"])


def _csv_files(path: Path, n: int, arrays: dict, info_arrays: dict, meta: dict):
    """(table bytes, sidecar bytes)."""
    names, blocks, layout, rest = [], [], [], {}
    for name, value in arrays.items():
        if value.ndim >= 1 and value.shape[0] == n and value.dtype.kind != "U":
            cols = _column_names(name, value)
            names += cols
            blocks.append(_block(value))
            layout.append({"name": name, "dtype": value.dtype.str,
                           "shape": list(value.shape[1:]), "columns": len(cols)})
        else:
            rest[name] = _encode(value)
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerow(names)
    np.savetxt(text, np.hstack(blocks), fmt="%.17g", delimiter=",")
    data = text.getvalue().encode("utf-8")
    sidecar = {**meta, "format": CSV_FORMAT, "table": path.name,
               "table_sha256": hashlib.sha256(data).hexdigest(), "n_points": n,
               "columns": names, "layout": layout, "other_arrays": rest,
               "info_arrays": {k: _encode(v) for k, v in info_arrays.items()}}
    return data, (json.dumps(sidecar, indent=1, allow_nan=True) + "\n").encode("utf-8")


# ----------------------------------------------------------------------------------------------
# reading


def is_curve(path: Path) -> bool:
    """True when ``path`` (.npz, or .csv with its sidecar) holds a curve (quietly False for
    anything it cannot read: the reader of time histories then says what is wrong)."""
    try:
        suffix = path.suffix.lower()
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                if _META_KEY not in z.files:
                    return False
                return json.loads(str(z[_META_KEY])).get("format") == FORMAT
        if suffix == ".csv":
            side = sidecar_path(path)
            return side.is_file() and json.loads(side.read_text("utf-8")).get(
                "format") == CSV_FORMAT
    except Exception:  # noqa: BLE001 - not a curve; the other reader reports the problem
        return False
    return False


def _check_meta(meta, name: str) -> None:
    if meta.get("version", 0) > FORMAT_VERSION:
        raise ValueError(f"{name} has curve format version {meta['version']}; this dtdyn reads "
                         f"up to {FORMAT_VERSION}: update dtdyn")


def _build(cls, meta: dict, arrays: dict, info_arrays: dict):
    """The ``cls`` instance of the fields read back."""
    known = {f.name for f in dataclasses.fields(cls)}
    kwargs = {**arrays, **{k: None for k in meta["none"]}, **meta["fields"]}
    unknown = sorted(set(kwargs) - known)
    if unknown:
        raise ValueError(f"the file holds fields {unknown} that {cls.__name__} does not have "
                         "(saved by another dtdyn version?)")
    if "info" in known:
        kwargs["info"] = {**meta["info"], **info_arrays}
    return cls(**kwargs)


def _part(get, name: str, dtype: str) -> np.ndarray:
    if np.dtype(dtype).kind == "c":
        return (get(f"{name}.re") + 1j * get(f"{name}.im")).astype(dtype)
    return get(name)


def read_npz(path: Path, lookup):
    """The curve in an .npz; ``lookup(type name)`` gives its class."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z[_META_KEY]))
        _check_meta(meta, repr(path.name))

        def get(key):
            return z[key]
        arrays = {k: _part(get, k, dt) for k, dt in meta["arrays"].items()}
        info_arrays = {k: _part(get, f"info.{k}", dt) for k, dt in meta["info_arrays"].items()}
    return _build(lookup(meta["type"]), meta, arrays, info_arrays)


def read_csv(path: Path, lookup):
    """The curve in a .csv and its sidecar; ``lookup(type name)`` gives its class."""
    sidecar = sidecar_path(path)
    meta = json.loads(sidecar.read_text(encoding="utf-8"))
    _check_meta(meta, repr(sidecar.name))
    data = path.read_bytes()
    text = io.StringIO(data.decode("utf-8"))
    header = next(csv.reader([text.readline()]), [])
    if header != meta["columns"]:
        raise ValueError(f"its header {header[:4]}... differs from the columns in "
                         f"{sidecar.name!r} {meta['columns'][:4]}...")
    table = np.loadtxt(text, delimiter=",", ndmin=2)
    n = meta["n_points"]
    check_table(table, n, header, data, meta, sidecar, path)
    arrays, start = {}, 0
    for entry in meta["layout"]:
        block = table[:, start:start + entry["columns"]]
        start += entry["columns"]
        dtype = np.dtype(entry["dtype"])
        if dtype.kind == "c":
            block = block[:, 0::2] + 1j * block[:, 1::2]
        arrays[entry["name"]] = np.ascontiguousarray(
            block.reshape([n] + entry["shape"]).astype(dtype))
    arrays.update({k: _decode(v) for k, v in meta["other_arrays"].items()})
    info_arrays = {k: _decode(v) for k, v in meta["info_arrays"].items()}
    return _build(lookup(meta["type"]), meta, arrays, info_arrays)
