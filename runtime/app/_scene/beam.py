"""Scenes with ``kind = "beam"``: a uniform Euler-Bernoulli beam in planar bending.

::

    [model]
    kind = "beam"
    E = 2.1e11                            # Pa
    I = 8.0e-6                            # m^4
    rho_A = 20.0                          # kg/m
    length = 3.0                          # m
    elements = 200
    left = "clamped"                      # clamped | pinned | sliding | free | [k_w, k_psi]
    right = "free"                        #   (an elastic end: springs to the ground)
    mass_matrix = "consistent"            # optional: or "lumped" (HRZ)
    rayleigh = [0.5, 1e-5]                # optional: C = alpha M + beta K
    point_masses = [{node = 100, mass = 5.0, inertia = 0.1}]       # optional
    supports = [{node = 50, k_w = 1e5, c_w = 20.0}]                # optional: k_psi, c_psi too

DOF names (loads' ``dof``, ``[output] outputs``): "w<node>", "psi<node>" (`dtdyn.Beam`); held
DOFs are not among them. The scene runs `beam_response` (scheme, form, backend and refine from
[scheme]; with [[element]] `nonlinear_beam_response`, refine from [nonlinear]);
``Scene.matrices()`` gives the assembled sparse M, C, K and ``Scene.dof_names`` their DOFs;
`dtdyn modes` counts the frequencies by Wittrick-Williams.
"""
from __future__ import annotations

import numpy as np

#: [ground] is supported: the supports move together (default influence: w 1, psi 0)
GROUND = True
MODEL_KEYS = ("kind", "E", "I", "rho_A", "length", "elements", "left", "right", "mass_matrix",
              "rayleigh", "point_masses", "supports")
TABLES = {"point_masses": ("PointMass", ("node", "mass", "inertia")),
          "supports": ("Support", ("node", "k_w", "k_psi", "c_w", "c_psi"))}


def _items(where: str, values, cls, allowed):
    if not isinstance(values, list):
        raise ValueError(f"{where} = {values!r}: must be an array of inline tables")
    out = []
    for i, tbl in enumerate(values):
        if not isinstance(tbl, dict):
            raise ValueError(f"{where}[{i}] = {tbl!r}: must be an inline table")
        for key in tbl:
            if key not in allowed:
                raise ValueError(f"{where}[{i}].{key}: unknown key, allowed: "
                                 f"{', '.join(allowed)}")
        if "node" not in tbl:
            raise ValueError(f"{where}[{i}].node is required")
        out.append(cls(**tbl))
    return out


def parse_model(model: dict, branches, base_dir=None):
    """The `dtdyn.Beam` of a ``[model]`` table (kind = "beam"); errors name the field and the
    value (``model.E[0] = -1.0``, ``model.supports[1].k_w``)."""
    import dtdyn.linear._beam as B

    if branches is not None:
        raise ValueError("branch: [[branch]] tables are for model.kind = 'shaft'")
    for key in model:
        if key not in MODEL_KEYS:
            raise ValueError(f"model.{key}: unknown key, allowed: {', '.join(MODEL_KEYS)}")
    for key in ("E", "I", "rho_A", "length", "elements"):
        if key not in model:
            raise ValueError(f"model.{key} is required (kind = 'beam')")
    kw = {k: model[k] for k in ("E", "I", "rho_A", "length", "elements", "left", "right",
                                "mass_matrix", "rayleigh") if k in model}
    for key, (cls, allowed) in TABLES.items():
        if key in model:
            kw[key] = _items(f"model.{key}", model[key], getattr(B, cls), allowed)
    try:
        return B.Beam(**kw)
    except (ValueError, TypeError) as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith("model") else f"model.{msg}") from None


def matrices(beam, sparse=None):
    """(M, C, K): sparse CSR, or dense arrays when ``sparse`` is False."""
    from dtdyn.app._scene.schema import model_matrices
    from dtdyn.linear._beam import beam_matrices

    return model_matrices(beam_matrices, beam, sparse)


def simulate(scene, progress=False, support=None):
    """`beam_response` on the scene, with its [ground] record when it has one."""
    from dtdyn.app._scene.schema import model_simulate
    from dtdyn.linear._beam import beam_response

    return model_simulate(beam_response, scene, progress, support)


def simulate_nonlinear(scene, support=None):
    """`nonlinear_beam_response` on a scene with [[element]] tables."""
    from dtdyn.app._scene.schema import model_simulate_nonlinear
    from dtdyn.nonlinear._stations import nonlinear_beam_response

    return model_simulate_nonlinear(nonlinear_beam_response, scene, support)


def frequencies(beam, count=None) -> np.ndarray:
    """The lowest ``count`` (all when None) natural frequencies by the Wittrick-Williams count."""
    from dtdyn.linear._beam import beam_frequencies

    return beam_frequencies(beam, count=count)
