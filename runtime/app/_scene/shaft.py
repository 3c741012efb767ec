"""Scenes with ``kind = "shaft"``: a torsional shaft with disks, gears and branches.

::

    [model]
    kind = "shaft"
    inertia = [1.0, 0.3, 0.9]             # disks J, kg m^2
    stiffness = [1e4, 1.2e4, 9e3]         # the shaft before each disk (stiffness[0]: from the
    damping = [0.5, 0.8, 0.3]             #   wall, left = "clamped"); a number or a continuous
    left = "clamped"                      #   shaft {length, G, Jp, rho, elements, damping}
    right = "free"                        # free | clamped | elastic (right_stiffness, ...);
                                          #   clamped: right_stiffness may be a continuous shaft
    ground_stiffness = [0.0, 0.0, 2e3]    # optional, also ground_damping, name ("main")

    [[branch]]                            # any number, in order; "on" names the parent line
    name = "out"
    on = "main"                           # default "main"
    at = 1                                # 0-based disk of that line
    ratio = 2.0                           # a gear mesh (omit for a direct connection)
    inertia = [0.5, 0.4]
    stiffness = [6e3, 5e3]

DOF names (loads' ``dof``, ``[output] outputs``): "<line>.<i>" (`dtdyn.Shaft`). The scene runs
`shaft_response` (scheme, form, backend from [scheme]); ``Scene.matrices()`` gives the assembled
sparse M, C, K and ``Scene.dof_names`` their DOFs; `dtdyn modes` counts the frequencies by
Wittrick-Williams (exact for continuous shafts).
"""
from __future__ import annotations

import numpy as np

#: [ground] is supported: the supports turn together (default influence: the rigid rotation)
GROUND = True
MODEL_KEYS = ("kind", "inertia", "stiffness", "damping", "left", "right", "right_stiffness",
              "right_damping", "ground_stiffness", "ground_damping", "name")
BRANCH_KEYS = ("name", "on", "at", "ratio", "inertia", "stiffness", "damping", "right",
               "right_stiffness", "right_damping", "ground_stiffness", "ground_damping")
SEGMENT_KEYS = ("length", "G", "Jp", "rho", "elements", "damping")


def _keys(where: str, table, allowed) -> dict:
    if not isinstance(table, dict):
        raise ValueError(f"{where} = {table!r}: must be a table")
    for key in table:
        if key not in allowed:
            raise ValueError(f"{where}.{key}: unknown key, allowed: {', '.join(allowed)}")
    return table


def _segment(where: str, v):
    """A stiffness: a number as given, or a table {length, G, Jp, rho, elements, damping}: a
    `ContinuousShaft`."""
    from dtdyn.linear._shaft import ContinuousShaft

    if not isinstance(v, dict):
        return v
    _keys(where, v, SEGMENT_KEYS)
    for key in ("length", "G", "Jp", "rho"):
        if key not in v:
            raise ValueError(f"{where}.{key} is required (a continuous shaft)")
    try:
        return ContinuousShaft(**v)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _stiffness(where: str, values):
    if not isinstance(values, list):
        raise ValueError(f"{where} = {values!r}: must be a list (one shaft before each disk)")
    return [_segment(f"{where}[{i}]", v) for i, v in enumerate(values)]


def _line_kwargs(where: str, table: dict) -> dict:
    kw = {}
    for key in ("inertia", "stiffness"):
        if key not in table:
            raise ValueError(f"{where}.{key} is required")
    kw["inertia"] = table["inertia"]
    kw["stiffness"] = _stiffness(f"{where}.stiffness", table["stiffness"])
    for key in ("damping", "ground_stiffness", "ground_damping", "right", "right_damping"):
        if key in table:
            kw[key] = table[key]
    if "right_stiffness" in table:  # a number, or a continuous shaft to a clamped right end
        kw["right_stiffness"] = _segment(f"{where}.right_stiffness", table["right_stiffness"])
    return kw


def parse_model(model: dict, branches, base_dir=None):
    """The `dtdyn.Shaft` of a ``[model]`` table (kind = "shaft") and its ``[[branch]]`` tables;
    errors name the field (``model.stiffness[2]``, ``branch[1].ratio``) and the value."""
    from dtdyn.linear._shaft import Branch, Shaft

    _keys("model", model, MODEL_KEYS)
    main = model.get("name", "main")
    branches = [] if branches is None else branches
    if not isinstance(branches, list):
        raise ValueError(f"branch = {branches!r}: must be an array of tables [[branch]]")
    specs = {}  # name -> (parent line, kwargs, index)
    order = []
    for j, tbl in enumerate(branches):
        where = f"branch[{j}]"
        _keys(where, tbl, BRANCH_KEYS)
        name = tbl.get("name", f"branch{j + 1}")
        on = tbl.get("on", main)
        if name in specs or name == main:
            raise ValueError(f"{where}.name = {name!r}: names must be unique")
        if on != main and on not in specs:
            raise ValueError(f"{where}.on = {on!r}: must name the main line ({main!r}) or a "
                             "branch defined above it")
        if "at" not in tbl:
            raise ValueError(f"{where}.at is required (the 0-based disk of {on!r})")
        specs[name] = (on, tbl, where)
        order.append(name)

    def build(name):
        on, tbl, where = specs[name]
        children = [build(c) for c in order if specs[c][0] == name]
        try:
            return Branch(tbl["at"], **_line_kwargs(where, tbl), ratio=tbl.get("ratio"),
                          branches=children, name=name)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None

    try:
        top = [build(c) for c in order if specs[c][0] == main]
        kw = _line_kwargs("model", model)
        return Shaft(**kw, left=model.get("left", "clamped"), branches=top, name=main)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(("branch", "model")) else f"model: {msg}") from None


def matrices(shaft, sparse=None):
    """(M, C, K): sparse CSR, or dense arrays when ``sparse`` is False."""
    from dtdyn.app._scene.schema import model_matrices
    from dtdyn.linear._shaft import shaft_matrices

    return model_matrices(shaft_matrices, shaft, sparse)


def simulate(scene, progress=False, support=None):
    """`shaft_response` on the scene."""
    from dtdyn.app._scene.schema import model_simulate
    from dtdyn.linear._shaft import shaft_response

    return model_simulate(shaft_response, scene, progress, support)


def simulate_nonlinear(scene, support=None):
    """`nonlinear_shaft_response` on a scene with [[element]] tables."""
    from dtdyn.app._scene.schema import model_simulate_nonlinear
    from dtdyn.nonlinear._stations import nonlinear_shaft_response

    return model_simulate_nonlinear(nonlinear_shaft_response, scene, support)


def frequencies(shaft, count=None) -> np.ndarray:
    """The lowest ``count`` (all when None, 20 with continuous shafts) natural frequencies by
    the Wittrick-Williams count."""
    from dtdyn.linear._shaft import shaft_frequencies

    if count is None and shaft.has_continuous:
        count = 20
    return shaft_frequencies(shaft, count=count)
