"""TOML -> `Scene`: `load_scene` and `scene_from_dict`."""
from __future__ import annotations

import importlib.resources
import os
import tomllib
from pathlib import Path

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import validate
from dtdyn.app._loads import _read_file, finite_number, sample_load
from dtdyn.app._scene.schema import (BACKENDS, DEFAULT_SCENE, DEFAULT_SCHEME, FORMS, GROUND_UNITS,
                                    QUANTITIES, STANDARD_GRAVITY, SWEEPS, UNSTABLE, Scene,
                                    _OUTPUT_KEYS, _TIME_KEYS,
                                    _TOP_KEYS, _choice, _dof_index, _model_kind, _number_list,
                                    _parse_model, _required, _scheme_name_params, _table)
from dtdyn.app._scene.matrices import _parse_matrix_model
from dtdyn.app._scene.schema import MODEL_MODULES, model_module
from dtdyn.app._scene.elements import _parse_elements, _parse_nonlinear

#: the largest scene file read (bytes): TOML is parsed at about 6 MB/s into Python objects
MAX_SCENE_BYTES = 64 * 2**20


def _parse_time(tbl) -> tuple[float, int]:
    _table("time", tbl, _TIME_KEYS)
    dt = validate.positive_scalar("time.dt", finite_number("time.dt", _required("time", tbl, "dt")))
    duration = validate.positive_scalar(
        "time.duration", finite_number("time.duration", _required("time", tbl, "duration")))
    ratio = duration / dt
    n_steps = int(round(ratio))
    if abs(ratio - n_steps) > 1e-9 * max(ratio, 1.0):
        raise ValueError(f"time.duration = {tbl['duration']!r}: not an integer multiple of "
                         f"time.dt = {tbl['dt']!r} (duration/dt = {ratio!r})")
    return dt, validate.step_count("time.duration / time.dt", n_steps)


def _parse_scheme(tbl, kind: str = "chain", base_dir=None) -> tuple:
    """(name, params, form, sweep, backend, unstable) of a linear scene's [scheme] table; every
    key is optional (``tbl`` None: no table), the defaults those of the entry points."""
    if tbl is None:
        tbl = {}
    if not isinstance(tbl, dict):
        raise ValueError(f"scheme = {tbl!r}: must be a table [scheme]")
    if kind == "matrices":
        for key in ("form", "sweep", "backend"):
            if key in tbl:
                raise ValueError(f"scheme.{key} = {tbl[key]!r}: only for chain models; a model "
                                 "with kind = 'matrices' runs mck_response (acceleration form, "
                                 "dense or sparse as the matrices are): remove the key")
    name, params = _scheme_name_params(tbl, DEFAULT_SCHEME, base_dir)
    unstable = _choice("scheme.unstable", tbl.get("unstable", "raise"), UNSTABLE)
    if kind == "matrices":
        return name, params, "acceleration", None, "", unstable  # backend: from the matrices
    form = _choice("scheme.form", tbl["form"], FORMS) if "form" in tbl else None  # the scheme's
    sweep = _choice("scheme.sweep", tbl.get("sweep", "stable"), SWEEPS)
    backend = _choice("scheme.backend", tbl.get("backend", "c"), BACKENDS)
    return name, params, form, sweep, backend, unstable



def _parse_output(tbl, n_dof: int, names: tuple[str, ...] | None = None, nonlinear: bool = False
                  ) -> tuple[np.ndarray, tuple[str, ...]]:
    # nonlinear scenes may also store the element forces g and the internal states z
    allowed = QUANTITIES + (("g", "z") if nonlinear else ())
    _table("output", tbl, _OUTPUT_KEYS)
    dofs = tbl.get("outputs")
    if names is not None and dofs is not None:  # indices or DOF names
        if not isinstance(dofs, list) or not dofs:
            raise ValueError(f"output.outputs = {dofs!r}: must be a non-empty array of DOF indices "
                             "or names")
        given = dofs
        dofs = [_dof_index(f"output.outputs[{i}]", d, n_dof, names) for i, d in enumerate(given)]
        for i, d in enumerate(dofs):
            if d in dofs[:i]:
                raise ValueError(f"output.outputs = {given!r}: entry {i} ({given[i]!r}) repeats "
                                 f"DOF {d} ({names[d]!r})")
    elif dofs is not None and (not isinstance(dofs, list)
                               or any(isinstance(d, bool) or not isinstance(d, int) for d in dofs)):
        raise ValueError(f"output.outputs = {dofs!r}: must be an array of integer DOF indices")
    outputs = validate.dof_indices("output.outputs", dofs, n_dof)
    quantities = tbl.get("quantities", ["x"])
    if not isinstance(quantities, list) or not quantities:
        raise ValueError(f"output.quantities = {quantities!r}: must be a non-empty array, "
                         f"allowed entries: {', '.join(map(repr, allowed))}")
    for i, q in enumerate(quantities):
        _choice(f"output.quantities[{i}]", q, allowed)
    if len(set(quantities)) != len(quantities):
        raise ValueError(f"output.quantities = {quantities!r}: repeats an entry")
    return outputs, tuple(quantities)


def _parse_loads(loads, n_dof: int, t: np.ndarray, base_dir: Path,
                 names: tuple[str, ...] | None = None):
    if not isinstance(loads, list) or not loads or not all(isinstance(x, dict) for x in loads):
        raise ValueError(f"load = {loads!r}: must be one or more [[load]] tables")
    columns: dict[int, np.ndarray] = {}
    for i, spec in enumerate(loads):
        name = f"load[{i}]"
        dof = _dof_index(f"{name}.dof", _required(name, spec, "dof"), n_dof, names)
        samples = sample_load(spec, t, base_dir, name=name, extra_keys=("dof",))
        columns[dof] = columns[dof] + samples if dof in columns else samples
    loaded = np.array(sorted(columns), dtype=np.int64)
    force = np.column_stack([columns[d] for d in loaded])
    return [dict(x) for x in loads], loaded, validate.force_samples(force, t.size - 1, loaded)


def _load_dofs(loads, n_dof: int, names: tuple[str, ...] | None = None):
    """(load tables, loaded DOFs) of [[load]] tables in a scene without [time]: the DOFs are
    checked, the samples wait for a time grid (a run asks for [time] first)."""
    if not isinstance(loads, list) or not loads or not all(isinstance(x, dict) for x in loads):
        raise ValueError(f"load = {loads!r}: must be one or more [[load]] tables")
    dofs = {_dof_index(f"load[{i}].dof", _required(f"load[{i}]", spec, "dof"), n_dof, names)
            for i, spec in enumerate(loads)}
    return [dict(x) for x in loads], np.array(sorted(dofs), dtype=np.int64)


def _parse_refine(data: dict, kind: str, nonlinear: bool):
    """A beam's ``refine`` ("auto", true or false): ``scheme.refine`` in a linear scene,
    ``nonlinear.refine`` in one with [[element]]; refused elsewhere, naming the table."""
    table, other = ("nonlinear", "scheme") if nonlinear else ("scheme", "nonlinear")
    tbl = data.get(other)
    if isinstance(tbl, dict) and "refine" in tbl:
        raise ValueError(f"{other}.refine = {tbl['refine']!r}: "
                         + ("a scene with [[element]] sets nonlinear.refine" if nonlinear else
                            "a linear scene sets scheme.refine"))
    tbl = data.get(table)
    if not isinstance(tbl, dict) or "refine" not in tbl:
        return "auto"
    value = tbl["refine"]
    if kind != "beam":
        raise ValueError(f"{table}.refine = {value!r}: only for beams (model.kind = 'beam'), "
                         f"not {kind!r}: remove the key")
    if not (isinstance(value, bool) or value == "auto"):
        raise ValueError(f"{table}.refine = {value!r}: must be \"auto\", true or false")
    return value


def _parse_initial(tbl, n_dof: int):
    """(x0, v0) of the [initial] table, each of length n_dof or None."""
    if not isinstance(tbl, dict):
        raise ValueError(f"initial = {tbl!r}: must be an [initial] table")
    out = []
    for key in tbl:
        if key not in ("x0", "v0"):
            raise ValueError(f"initial.{key}: unknown key, allowed: x0, v0")
    for key in ("x0", "v0"):
        if key not in tbl:
            out.append(None)
            continue
        values = _number_list(f"initial.{key}", tbl[key])
        if values.size != n_dof:
            raise ValueError(f"initial.{key} has {values.size} entries, expected one per DOF "
                             f"({n_dof})")
        out.append(values)
    return tuple(out)


def _parse_ground(tbl, n_dof: int, t: np.ndarray, base_dir: Path, kind: str):
    """(samples, quantity, influence or None) of the [ground] table: the record at the scene's
    times in SI units (m/s^2, m/s or m by ``quantity``: "acceleration", "velocity",
    "displacement")."""
    if not isinstance(tbl, dict):
        raise ValueError(f"ground = {tbl!r}: must be a [ground] table")
    spec = dict(tbl)
    quantity = spec.pop("quantity", "acceleration")
    _choice("ground.quantity", quantity, tuple(GROUND_UNITS))
    scale = finite_number("ground.scale", spec.pop("scale", 1.0))
    units = spec.pop("units", GROUND_UNITS[quantity][0])
    if units not in GROUND_UNITS[quantity]:
        raise ValueError(f"ground.units = {units!r}: a {quantity} record is in "
                         f"{' or '.join(repr(u) for u in GROUND_UNITS[quantity])}"
                         + (" (\"g\" is for an acceleration record)" if units == "g" else ""))
    influence = spec.pop("influence", None)
    if influence is not None:
        if kind not in ("matrices", "beam"):
            raise ValueError(f"ground.influence: a {kind} moves with its base as a whole; the "
                             "key is for matrices and beam scenes")
        influence = np.asarray(_number_list("ground.influence", influence), dtype=float)
        if influence.size != n_dof:
            raise ValueError(f"ground.influence has {influence.size} entries, expected one per "
                             f"DOF ({n_dof})")
    if "dt" in spec:  # a record at its own step: linear between its samples, then held or 0
        record_dt = validate.positive_scalar("ground.dt", spec.pop("dt"))
        if spec.get("kind") != "file":
            raise ValueError(f"ground.dt = {record_dt!r}: only a kind = \"file\" record has its "
                             "own sample step")
        _table("ground", spec, ("kind", "path", "column"))
        record = _read_file("ground", spec, None, base_dir)
        after = 0.0 if quantity == "acceleration" else record[-1]   # the ground stays put
        samples = np.interp(t, record_dt * np.arange(record.size), record, right=after)
    else:
        samples = sample_load(spec, t, base_dir, name="ground")
    return samples * scale * (STANDARD_GRAVITY if units == "g" else 1.0), quantity, influence


def stored_columns(n_dof: int, n_loaded: int, ground: bool, n_outputs: int,
                   n_quantities: int) -> int:
    """Values per time sample a scene's run stores, for its up-front size check: the time,
    one force column per loaded DOF (with a [ground] record: its column, and the effective
    load -M r a_g on every DOF, the most it can reach), and each output's quantities.

    Examples
    --------
    >>> stored_columns(2000, 1, False, 1, 1)   # a 2,000-mass chain, one load, one output
    3
    >>> stored_columns(2000, 1, True, 1, 1)    # with support motion: every DOF is loaded
    2003
    """
    force = n_dof + 1 if ground else n_loaded
    return 1 + force + n_outputs * n_quantities


def _check_run_size(data, source: str, n_dof: int, names, n_steps: int, n_stored: int) -> None:
    """The up-front size check of a scene's run (`stored_columns`), before any load is
    sampled."""
    n_loaded = _load_dofs(data["load"], n_dof, names)[1].size if "load" in data else 0
    validate.output_size(f"{source}: time.duration / time.dt = {n_steps} steps", n_steps + 1,
                         stored_columns(n_dof, n_loaded, "ground" in data, n_stored, 1))


def read_scene_text(path: Path) -> str:
    """The text of a scene file, at most `MAX_SCENE_BYTES` (checked before it is read);
    ValueError naming the file otherwise."""
    source = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise ValueError(f"{source}: the scene file is {size:,} bytes; the limit is "
                             f"{MAX_SCENE_BYTES:,} (64 MiB): give large matrices as files "
                             "(model.file = \"model.npz\" or .mtx paths) and long records as "
                             "kind = \"file\" loads")
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{source}: cannot read the scene file: {exc}") from None


def parse_toml(text: str, source: str) -> dict:
    """``tomllib.loads(text)``; invalid TOML, or arrays and inline tables nested deeper than
    the reader's recursion allows (about 300 levels; a scene needs 2), is a ValueError naming
    ``source``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: invalid TOML: {exc}") from None
    except RecursionError:  # tomllib recurses once per level
        raise ValueError(f"{source}: invalid scene: arrays or inline tables nested too deep "
                         "for the TOML reader (a scene needs at most a matrix's 2 levels)"
                         ) from None


# ----------------------------------------------------------------------------------------------
# public API

def scene_from_dict(data: dict, base_dir: Path | str = ".",  # noqa: C901 (a check a table)
                    source: str = "<scene>") -> Scene:
    """Validate a parsed scene (the dict ``tomllib`` returns) and build a :class:`Scene`.

    Only ``[model]`` is required (enough for `dtdyn modes`); a run also needs ``[time]`` and a
    load (`Scene.require_run`). ``base_dir`` is where ``file`` loads and matrix files
    (``model.file``, ``.mtx`` paths) are looked for. Errors are ``ValueError`` naming the field
    (without the file name; :func:`load_scene` adds it).

    Parameters
    ----------
    data : dict
        The scene's tables (the layout of `dtdyn.app._scene.schema`).
    base_dir : str or Path
        Folder for relative file names.
    source : str
        Name used in error messages.

    Returns
    -------
    Scene

    Examples
    --------
    >>> import dtdyn as dd
    >>> s = dd.scene_from_dict({"model": {"mass": [1.0], "stiffness": [4.0]},
    ...                         "load": [{"dof": 0, "kind": "step"}],
    ...                         "scheme": {"name": "newmark"},
    ...                         "time": {"dt": 0.1, "duration": 1.0}})
    >>> s.n_steps, s.quantities
    (10, ('x',))
    >>> m = dd.scene_from_dict({"model": {"mass": [1.0], "stiffness": [4.0]}})  # for modes
    >>> m.dt is None, m.scheme
    (True, 'newmark')
    """
    if not isinstance(data, dict):
        raise ValueError(f"a scene must be a table, got {type(data).__name__}")
    for key in data:
        if key not in _TOP_KEYS:
            raise ValueError(f"{key}: unknown top-level key or table, allowed: "
                             f"{', '.join(_TOP_KEYS)}")
    nonlinear = bool(data.get("element"))
    # [model] alone is a valid scene (dtdyn modes); a run also needs [time] and a load, which
    # Scene.require_run checks where a run starts, naming the command
    if "model" not in data:
        raise ValueError("model is required: add a [model] table")
    if "nonlinear" in data and not nonlinear:
        raise ValueError(f"nonlinear = {data['nonlinear']!r}: the [nonlinear] options need at "
                         "least one [[element]] table")
    title = data.get("title", Path(source).stem)
    if not isinstance(title, str):
        raise ValueError(f"title = {title!r}: must be a string")

    base_dir = Path(base_dir)
    kind = _model_kind(data["model"])
    M = C = K = names = model = None
    chain = dict.fromkeys(("mass", "stiffness", "damping", "ground_stiffness", "ground_damping"))
    if kind == "matrices":
        if nonlinear and data["model"].get("sparse") is True:
            raise ValueError("model.sparse = True: a scene with [[element]] runs on dense "
                             "matrices; remove the key")
        M, C, K, names = _parse_matrix_model(data["model"], base_dir)
        n_dof = M.shape[0]
        if nonlinear:
            M, C, K = (A.toarray() if sps.issparse(A) else A for A in (M, C, K))
    elif kind in MODEL_MODULES:
        module = model_module(kind)
        if ((nonlinear and not hasattr(module, "simulate_nonlinear"))
                or ("ground" in data and not getattr(module, "GROUND", False))):
            what = "[[element]]" if nonlinear else "[ground]"
            raise ValueError(f"model.kind = {kind!r}: {what} is not supported for this kind yet; "
                             "remove it")
        model = model_module(kind).parse_model(data["model"], data.get("branch"), base_dir)
        names = tuple(model.dof_names)
        n_dof = len(names)
    else:
        chain = _parse_model(data["model"])
        n_dof = chain["mass"].size
    if "branch" in data and kind not in MODEL_MODULES:
        raise ValueError(f"branch: [[branch]] tables are for model.kind = 'shaft', not {kind!r}")
    dt, n_steps = _parse_time(data["time"]) if "time" in data else (None, None)
    elements, options, unstable = (), {}, "raise"
    if nonlinear:
        elements = _parse_elements(data["element"], n_dof, names)
        scheme, params, options, backend = _parse_nonlinear(data.get("nonlinear", {}),
                                                            data.get("scheme"))
        form = sweep = None
        from dtdyn.nonlinear._linear_step import MODAL

        if kind in MODEL_MODULES and "accuracy" in options:
            raise ValueError(f"nonlinear.accuracy = {options['accuracy']!r}: a {kind} with "
                             "[[element]] runs the DT-TMM sweep at a fixed nonlinear.substeps "
                             "(accuracy targets run on matrices and chains)")
        steady_only = "harmonic" in data and "time" not in data and "scheme" not in data
        if kind in MODEL_MODULES and scheme in MODAL and not steady_only:
            raise ValueError(f"scheme.name = {scheme!r}: the modal methods run on matrices; a "
                             f"{kind} with [[element]] runs the DT-TMM sweep with a one-step "
                             "scheme (newmark, hht, generalized_alpha, ...)")
    else:
        if "element" in data:  # an empty array: still a linear scene
            _parse_elements(data["element"], n_dof, names)
        scheme, params, form, sweep, backend, unstable = _parse_scheme(data.get("scheme"), kind,
                                                                       base_dir)
        if kind in MODEL_MODULES and sweep != "stable":
            raise ValueError(f"scheme.sweep = {sweep!r}: a {kind} runs the stable sweep only")
        if kind == "matrices":
            backend = "c"  # mck_response's C loop, dense or sparse (NumPy without a compiler)
    outputs, quantities = _parse_output(data.get("output", {}), n_dof, names, nonlinear)
    loads, loaded, force = [], np.zeros(0, dtype=np.int64), None
    ground, ground_quantity, influence = None, "acceleration", None
    if dt is not None:  # the loads are sampled at the scene's times
        _check_run_size(data, source, n_dof, names, n_steps, outputs.size * len(quantities))
        t = np.arange(n_steps + 1) * dt
        if "load" in data:
            loads, loaded, force = _parse_loads(data["load"], n_dof, t, base_dir, names)
        if "ground" in data:
            ground, ground_quantity, influence = _parse_ground(data["ground"], n_dof, t,
                                                               base_dir, kind)
    elif "load" in data:  # no times to sample them at: their DOFs are checked, no run asked
        loads, loaded = _load_dofs(data["load"], n_dof, names)
    x0 = v0 = None
    if "initial" in data:
        x0, v0 = _parse_initial(data["initial"], n_dof)
    refine = _parse_refine(data, kind, nonlinear)
    if (dt is not None and force is None and ground is None
            and any(a is not None and np.any(a) for a in (x0, v0))):
        # free vibration from the initial state: no load, the runs get a zero record on DOF 0
        loaded, force = np.zeros(1, dtype=np.int64), np.zeros((n_steps + 1, 1))
    harmonic = None
    if "harmonic" in data:  # the steady state's table (dtdyn steady)
        from dtdyn.app._scene.steady import parse_harmonic

        harmonic = parse_harmonic(data["harmonic"], n_dof, names, kind, elements)
    return Scene(title=title, **chain, loads=loads,
                 loaded=loaded, force=force, scheme=scheme, scheme_params=params, form=form,
                 sweep=sweep, backend=backend, dt=dt, n_steps=n_steps, outputs=outputs,
                 quantities=quantities, source=source, base_dir=base_dir, kind=kind, M=M, C=C, K=K,
                 dof_names=names, elements=elements, nonlinear=options, ground=ground,
                 ground_quantity=ground_quantity, influence=influence, x0=x0, v0=v0, model=model,
                 unstable=unstable, harmonic=harmonic, refine=refine)


def load_scene(path: str | os.PathLike | None = None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : path or None
        A TOML scene file; ``None`` reads the embedded default ``scenes/p3.toml`` (reference
        problem P3: 15-DOF undamped chain, unit step on mass 15, T = 0.8 s, dt = 1e-3, average
        acceleration, all masses stored).

    Returns
    -------
    Scene

    Raises
    ------
    ValueError
        ``"<file>: <field> = <value>: <what is wrong>"``: unreadable file, TOML syntax, unknown
        table or key, invalid value.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.load_scene().title[:2]
    'P3'
    >>> dd.load_scene().n_dof
    15
    """
    if path is None:
        resource = importlib.resources.files("dtdyn.app").joinpath(DEFAULT_SCENE)
        source = f"dtdyn.app/{DEFAULT_SCENE}"
        text = resource.read_text(encoding="utf-8")
        base_dir = Path(str(resource)).parent if isinstance(resource, Path) else Path.cwd()
    else:
        file = Path(path)
        source = str(file)
        text = read_scene_text(file)
        base_dir = file.parent
    data = parse_toml(text, source)
    try:
        return scene_from_dict(data, base_dir, source)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None
