"""Batch cases: scenes, a base scene with a table of variations, per-case seeds.

A case is a scene's TOML tables (the dict ``tomllib`` returns) with *overrides* by dotted key::

    model.stiffness[2] = 3.0e8      # entry 2 of the array model.stiffness
    load[0].seed = 17               # the seed of the first [[load]] table
    ground.path = "gm_017.csv"      # the [ground] record file
    ground.scale = 0.5
    element[1].k3 = 4e7

Each key is a table or array name followed by ``.name`` or ``[index]`` parts (0-based indices
of arrays, which must exist; a missing last key, or a missing table on the way, is added, and
the scene parser then accepts or refuses it by name). The case is then validated by the same
`scene_from_dict` as any scene file, on the worker that runs it, so a bad value fails that
case with the parser's message (``case 3: model.stiffness[2] = -1.0: every entry must be finite
and > 0``) while the batch goes on.

Files the scenes name (``[[load]] path``, ``[ground] path``, ``[model] file``, matrix files)
are read here, on the machine that starts the batch, and sent to the workers as bytes: the base
scenes' files once for the whole batch, a file named by an override with its case. The workers
need no shared file system to read them.

Per-case seeds: with a root seed, case ``i`` draws its random loads (``kind = "white_noise"``,
``"psd"`` or ``"shock"`` in ``[[load]]`` or ``[ground]``, in that order) from
``numpy.random.SeedSequence(root).spawn(n)[i]``: its first ``k`` 63-bit states seed those
``k`` loads (a seed the case's own overrides set is kept). The seeds depend only on the root
and the case's index, never on how the cases are split over tasks or workers.
"""
from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["CaseSpec", "Shared", "build_cases", "parse_key", "apply_overrides", "read_table",
           "case_seeds", "case_hashes", "FILE_KEYS"]

_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)")
_INDEX = re.compile(r"\[(\d+)\]")
#: keys whose string value names a file, relative to the scene's folder
FILE_KEYS = ("path", "file", "M", "K", "C")


def parse_key(key: str) -> list:
    """``"load[0].seed"`` -> ``["load", 0, "seed"]``; a ValueError names a malformed key."""
    if not isinstance(key, str) or not key:
        raise ValueError(f"vary key {key!r}: must be a dotted name such as 'load[0].seed'")
    parts: list = []
    for piece in key.split("."):
        match = _PART.fullmatch(piece)
        if match is None:
            raise ValueError(f"vary key {key!r}: {piece!r} is not a name with optional [index] "
                             "parts (e.g. 'model.stiffness[2]', 'load[0].seed', 'ground.path')")
        parts.append(match.group(1))
        parts += [int(i) for i in _INDEX.findall(match.group(2))]
    return parts


def apply_overrides(data: dict, overrides: dict) -> dict:
    """A copy of the scene tables ``data`` with ``overrides`` (dotted key -> value) set.

    Only the containers on each key's path are copied (``data`` is never changed, large inline
    matrices are shared). Raises ValueError naming the key when it does not fit the tables
    (an index past the end of an array, a name inside a value that is not a table).
    """
    out = dict(data)
    copied = {id(out)}
    for key, value in overrides.items():
        parts = parse_key(key)
        node = out
        for depth, part in enumerate(parts[:-1]):
            where = _where(parts[:depth + 1])
            child = _child(node, part, key, where, create=True)
            if isinstance(child, dict):
                if id(child) not in copied:
                    child = dict(child)
            elif isinstance(child, list):
                if id(child) not in copied:
                    child = list(child)
            else:
                raise ValueError(f"vary key {key!r}: {where} = {child!r} is a value, not a table "
                                 "or an array")
            copied.add(id(child))
            node[part] = child
            node = child
        _child(node, parts[-1], key, _where(parts), create=True)
        node[parts[-1]] = value
    return out


def _where(parts) -> str:
    text = ""
    for p in parts:
        text += f"[{p}]" if isinstance(p, int) else (f".{p}" if text else p)
    return text


def _child(node, part, key, where, create):
    if isinstance(part, int):
        if not isinstance(node, list):
            raise ValueError(f"vary key {key!r}: {where} indexes something that is not an array")
        if part >= len(node):
            raise ValueError(f"vary key {key!r}: {where} is past the end (the scene's array has "
                             f"{len(node)} entries)")
        return node[part]
    if not isinstance(node, dict):
        raise ValueError(f"vary key {key!r}: {where} names a key inside an array; give an index")
    if part not in node and create:
        return {}
    return node.get(part)


def _plain(value, where: str):
    """A table cell as a TOML value: numpy scalars become Python numbers; text stays text."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v, where) for v in value]
    raise ValueError(f"{where} = {value!r}: a variation must be a number, a string, a boolean "
                     "or a list of them")


def _absent(value) -> bool:
    """A missing cell of a DataFrame or a dict of columns: None, NaN, pandas.NA or NaT."""
    if value is None or type(value).__name__ in ("NAType", "NaTType"):
        return True
    return isinstance(value, (float, np.floating)) and bool(np.isnan(value))


def _cell(text: str):
    """A CSV cell: an integer, else a float, else true/false, else the text itself."""
    text = text.strip()
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text


def read_table(vary) -> list[dict]:  # noqa: C901 - one branch per accepted table form
    """The rows of a table of variations as dicts (dotted key -> value), one per case.

    ``vary`` is a CSV file (first row: the dotted keys; an empty cell leaves that key as the
    scene has it), a list of dicts, a dict of equal-length columns, or a pandas DataFrame.
    """
    if isinstance(vary, (str, os.PathLike)):
        path = Path(vary)
        if not path.is_file():
            raise ValueError(f"vary = {str(path)!r}: no such file")
        try:
            with open(path, newline="", encoding="utf-8") as fh:
                # comment lines read as empty ones, so reader.line_num stays the file's line
                reader = csv.reader("\n" if row.lstrip().startswith("#") else row
                                    for row in fh)
                rows = [(reader.line_num, r) for r in reader if any(c.strip() for c in r)]
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise ValueError(f"vary = {str(path)!r}: cannot read the table: {exc}") from None
        if not rows:
            raise ValueError(f"vary = {str(path)!r}: the table is empty (the first row names "
                             "the keys, one row per case follows)")
        header = [h.strip() for h in rows[0][1]]
        for h in header:
            parse_key(h)
        if len(set(header)) != len(header):
            raise ValueError(f"vary = {str(path)!r}: a key repeats in the header {header}")
        text = [parse_key(h)[-1] in FILE_KEYS for h in header]  # file names stay text
        table = []
        for line, row in rows[1:]:
            if len(row) != len(header):
                raise ValueError(f"vary = {str(path)!r}: line {line} has {len(row)} cells, the "
                                 f"header {len(header)}")
            table.append({k: (c.strip() if t else _cell(c))
                          for k, c, t in zip(header, row, text) if c.strip() != ""})
        return table
    columns = False
    if hasattr(vary, "to_dict") and hasattr(vary, "columns"):  # a pandas DataFrame
        vary, columns = vary.to_dict("records"), True
    if isinstance(vary, dict):
        lengths = {k: len(v) for k, v in vary.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"vary: the columns have different lengths {lengths}")
        n = next(iter(lengths.values()), 0)
        vary, columns = [{k: vary[k][i] for k in vary} for i in range(n)], True
    if columns:  # a table's NaN / None cell keeps the scene's value, as an empty CSV cell
        vary = [{k: v for k, v in row.items() if not _absent(v)} for row in vary]
    if not isinstance(vary, (list, tuple)) or not all(isinstance(r, dict) for r in vary):
        raise ValueError(f"vary = {type(vary).__name__}: must be a CSV file, a list of dicts, a "
                         "dict of columns or a pandas DataFrame")
    table = []
    for i, row in enumerate(vary):
        for k in row:
            parse_key(k)
        table.append({k: _plain(v, f"vary row {i}, {k}") for k, v in row.items()})
    return table


@dataclass
class Shared:
    """What every worker needs once: the base scenes (TOML tables or Scene objects), their
    sources and the bytes of the files they name (relative name -> bytes)."""

    bases: list            # dict (TOML tables, file names rewritten) or Scene
    sources: list[str]
    files: dict[str, bytes] = field(default_factory=dict)
    token: str = ""


@dataclass
class CaseSpec:
    """One case: which base scene, its overrides (seeds included), its first random load's seed
    (-1: none) and the bytes of files its overrides name."""

    index: int
    scene: int
    overrides: dict
    seed: int = -1
    files: dict[str, bytes] = field(default_factory=dict)


def _file_name(data: bytes, name: str) -> str:
    """Where a shipped file lives inside the worker's folder: by its content, so equal files
    are written once and different ones never collide."""
    return f"files/{hashlib.sha256(data).hexdigest()[:20]}/{Path(name).name}"


def _read_file(value: str, base_dir: Path, where: str) -> tuple[str, bytes]:
    path = Path(value) if Path(value).is_absolute() else base_dir / value
    if not path.is_file():
        raise ValueError(f"{where} = {value!r}: no such file in {str(path.parent)!r}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{where} = {value!r}: cannot read {str(path)!r}: {exc}") from None
    return _file_name(data, path.name), data


def _ship_files(node, base_dir: Path, files: dict, where: str = ""):
    """A copy of the scene tables whose file names point into the shipped folder; their bytes
    are added to ``files``."""
    if isinstance(node, dict):
        out = {}
        for key, value in node.items():
            here = f"{where}.{key}" if where else key
            if key in FILE_KEYS and isinstance(value, str):
                name, data = _read_file(value, base_dir, here)
                files[name] = data
                out[key] = name
            else:
                out[key] = _ship_files(value, base_dir, files, here)
        return out
    if isinstance(node, list):
        return [_ship_files(v, base_dir, files, f"{where}[{i}]") for i, v in enumerate(node)]
    return node


def _load_base(item, k: int):
    """(tables or Scene, source, base folder) of one given scene."""
    from dtdyn.app._scene.schema import Scene

    if isinstance(item, Scene):
        return item, item.source, None
    if isinstance(item, dict):
        return item, f"<scene {k}>", Path.cwd()
    if isinstance(item, (str, os.PathLike)):
        from dtdyn.app._scene.parse import parse_toml, read_scene_text

        path = Path(item)
        return parse_toml(read_scene_text(path), str(path)), str(path), path.parent
    raise ValueError(f"cases[{k}] = {item!r}: a case is a scene file path, a scene's tables "
                     "(dict) or a Scene")


#: the load kinds drawn from a seed (each batch case gets its own)
RANDOM_KINDS = ("white_noise", "psd", "shock")


def _noise_slots(data: dict) -> list[str]:
    """The seed keys of the random loads of scene tables, in order: [[load]] then [ground]."""
    slots = []
    loads = data.get("load")
    if isinstance(loads, list):
        slots += [f"load[{i}].seed" for i, spec in enumerate(loads)
                  if isinstance(spec, dict) and spec.get("kind") in RANDOM_KINDS]
    ground = data.get("ground")
    if isinstance(ground, dict) and ground.get("kind") in RANDOM_KINDS:
        slots.append("ground.seed")
    return slots


def case_seeds(root: int, n_cases: int, counts: list[int]) -> list[list[int]]:
    """Per-case seeds from one root: case ``i`` gets the first ``counts[i]`` 63-bit states of
    ``SeedSequence(root).spawn(n_cases)[i]``."""
    children = np.random.SeedSequence(root).spawn(n_cases)
    return [[int(s >> np.uint64(1)) for s in child.generate_state(max(c, 1), np.uint64)[:c]]
            for child, c in zip(children, counts)]


def build_cases(cases, vary=None,  # noqa: C901 - checks each input by name
                seed=None) -> tuple[Shared, list[CaseSpec], list[dict]]:
    """(shared, case specs, the parameters of each case) from ``run_batch``'s ``cases``, ``vary``
    and ``seed``: every given scene with every row of ``vary`` (scene-major), or each scene once.
    """
    from dtdyn.app._scene.schema import Scene

    if isinstance(cases, (str, os.PathLike, dict, Scene)):
        cases = [cases]
    cases = list(cases)
    if not cases:
        raise ValueError("cases is empty: give one or more scenes")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
                             or seed < 0):
        raise ValueError(f"seed = {seed!r}: the root seed must be an integer >= 0")
    rows = read_table(vary) if vary is not None else [{}]
    if vary is not None and not rows:
        raise ValueError("vary has no rows: one row per case")
    files: dict[str, bytes] = {}
    bases, sources, folders = [], [], []
    for k, item in enumerate(cases):
        data, source, folder = _load_base(item, k)
        if isinstance(data, Scene):
            if vary is not None or seed is not None:
                raise ValueError(f"cases[{k}] is a Scene object: vary and seed change a scene's "
                                 "tables; give its file path or its tables (dict) instead")
        else:
            try:
                data = _ship_files(data, folder, files)
            except ValueError as exc:
                raise ValueError(f"{source}: {exc}") from None
        bases.append(data)
        sources.append(source)
        folders.append(folder)
    specs, params = [], []
    for k, data in enumerate(bases):
        for row in rows:
            index = len(specs)
            case_files = {}
            overrides = dict(row)
            for key, value in row.items():
                if parse_key(key)[-1] in FILE_KEYS and isinstance(value, str):
                    name, data_ = _read_file(value, folders[k], f"case {index}: {key}")
                    case_files[name] = data_
                    overrides[key] = name
            if not isinstance(data, Scene):
                try:
                    apply_overrides(data, overrides)  # the keys fit the tables
                except ValueError as exc:
                    raise ValueError(f"case {index} ({sources[k]}): {exc}") from None
            specs.append(CaseSpec(index=index, scene=k, overrides=overrides, files=case_files))
            params.append(dict(row))
    if seed is not None:
        slots = [_noise_slots(apply_overrides(bases[s.scene], s.overrides)) for s in specs]
        seeds = case_seeds(int(seed), len(specs), [len(x) for x in slots])
        for spec, keys, values, p in zip(specs, slots, seeds, params):
            for key, value in zip(keys, values):
                if key not in spec.overrides:
                    spec.overrides[key] = value
                    p[key] = value
    for spec in specs:
        if not isinstance(bases[spec.scene], Scene):
            keys = _noise_slots(apply_overrides(bases[spec.scene], spec.overrides))
            if keys:
                first = apply_overrides(bases[spec.scene], spec.overrides)
                spec.seed = _get(first, keys[0])
    return (Shared(bases=bases, sources=sources, files=files, token=uuid.uuid4().hex), specs,
            params)


def _get(data: dict, key: str):
    node = data
    for part in parse_key(key):
        node = node[part]
    value = node
    if isinstance(value, bool) or not isinstance(value, int):
        return -1
    return int(value) if 0 <= value < 2**63 else -1


def case_hashes(shared: Shared, specs: list[CaseSpec], extra) -> list[str]:
    """Each case's content hash (SHA-256, 32 hex digits): its scene's tables after its
    overrides (the files they name by their content hashes, its seeds among the overrides) or
    a Scene object's pickle, its first seed, and ``extra`` (JSON-able: the reducers and
    ``check``)."""
    import pickle

    tail = json.dumps(extra, sort_keys=True, default=repr)
    scene_bytes: dict[int, bytes] = {}
    out = []
    for spec in specs:
        base = shared.bases[spec.scene]
        if isinstance(base, dict):
            data = json.dumps(apply_overrides(base, spec.overrides), sort_keys=True,
                              default=repr).encode()
        else:
            if spec.scene not in scene_bytes:
                try:
                    scene_bytes[spec.scene] = pickle.dumps(base, protocol=5)
                except Exception:  # noqa: BLE001 - an unpicklable part: its repr
                    scene_bytes[spec.scene] = repr(base).encode()
            data = scene_bytes[spec.scene]
        h = hashlib.sha256(data)
        h.update(f"|seed={spec.seed}|files={sorted(spec.files)}|".encode())
        h.update(tail.encode())
        out.append(h.hexdigest()[:32])
    return out
