"""Saving and plotting a scene's response."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn._engine.extras import require
from dtdyn._engine.result import Response
from dtdyn.app._scene.schema import QUANTITIES, Scene

def save_results(path: str | os.PathLike, response: Response, scene: Scene) -> Path:
    """Write the response with the scene's summary as metadata: ``.npz``, ``.nc`` or ``.csv``
    by the extension (`Response.save`; atomic, so a failed write leaves no partial file and an
    existing ``path`` untouched). DOF names of a matrices scene are stored with the outputs."""
    for q in scene.quantities:
        if getattr(response, q) is None:
            raise ValueError(f"output.quantities asks for {q!r}, but the response did not store it")
    names = response.dof_names
    if scene.kind == "matrices" and names is None:
        names = tuple(scene.dof_label(d) for d in response.outputs)
    stored = dataclasses.replace(  # only what the scene asks for
        response, **{q: None for q in QUANTITIES if q not in scene.quantities},
        meta={"scene": scene_summary(scene), **run_summary(response), **response.meta},
        dof_names=names)
    return stored.save(path)


def run_summary(response: Response) -> dict:
    """What the run chose, where the scene left it open (nonlinear.accuracy: the method "auto"
    picked, its sub-steps, the estimate reached), as {"run": {...}}; {} for a plain run."""
    info = response.info
    if info.get("accuracy") is None:
        return {}
    return {"run": {"scheme": info["scheme"], "substeps": int(info["substeps"]),
                    "error_estimate": float(info["error_estimate"]),
                    "accuracy": float(info["accuracy"]),
                    "accuracy_met": bool(info["accuracy_met"])}}


def scene_summary(scene: Scene) -> dict:
    """The scene in a few JSON-safe fields: what a saved result says about its origin."""
    return {"title": scene.title, "source": scene.source, "kind": scene.kind,
            "n_dof": scene.n_dof, "scheme": getattr(scene.scheme, "name", scene.scheme),
            **({"scheme_file": scene.scheme.path, "scheme_sha256": scene.scheme.sha256}
               if hasattr(scene.scheme, "sha256") else {}),
            "params": dict(scene.scheme_params),
            "dt": scene.dt, "n_steps": scene.n_steps, "force_dofs": scene.loaded.tolist(),
            "loads": scene.loads, "elements": [el.describe() for el in scene.elements],
            "quantities": list(scene.quantities),
            **({} if scene.ground is None else
               {"ground_quantity": scene.ground_quantity,
                f"ground_peak_{_GROUND_UNIT[scene.ground_quantity]}":
                    float(np.abs(scene.ground).max())})}


#: the SI unit of each [ground] quantity, as a metadata key suffix
_GROUND_UNIT = {"acceleration": "m_s2", "velocity": "m_s", "displacement": "m"}


def plot_checked_path(path) -> tuple[Path, str]:
    """(path, format) after checking the folder exists and matplotlib can write the format."""
    require("matplotlib", "plot", "plot_response")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    allowed = FigureCanvasAgg(Figure()).get_supported_filetypes()
    if fmt not in allowed:
        raise ValueError(f"cannot plot to {str(path)!r}: unsupported format {fmt!r}, allowed: "
                         f"{', '.join(sorted(allowed))}")
    if path.is_dir() or not (path.parent if str(path.parent) else Path(".")).is_dir():
        raise ValueError(f"cannot plot to {str(path)!r}: not a file in an existing folder")
    return path, fmt


def plot_response(path: str | os.PathLike, response: Response, scene: Scene) -> None:
    """Plot every stored quantity the scene asks for (x, v, a; a nonlinear scene's element
    forces g and internal states z) against time with `Response.plot`, one panel each
    (a shaft's in rad, rad/s, rad/s^2; a beam's w and psi outputs in separate panels), saved
    atomically.

    Up to 8 DOFs (``result_plot.MAX_LINES``): one line per DOF, labelled by the scene's DOF
    name or its 0-based index. More: a heat map (time x DOF) with a colour bar, so that a long
    chain stays readable. Uses the Agg canvas directly (no pyplot, no global backend switch);
    the format follows the suffix of ``path`` (``.png`` when none).
    """
    path, fmt = plot_checked_path(path)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    stored = [q for q in QUANTITIES + ("g", "z")  # g, z: a nonlinear scene's, when asked
              if q in scene.quantities and getattr(response, q, None) is not None]
    if not stored:
        raise ValueError("the response stores none of the scene's quantities: nothing to plot")
    if response.dof_names is None and scene.dof_names is not None:
        response = dataclasses.replace(
            response, dof_names=tuple(scene.dof_label(d) for d in response.outputs))
    fig = Figure(layout="constrained")
    FigureCanvasAgg(fig)
    response.plot(stored, fig=fig)
    n_panels = sum(1 for ax in fig.axes if ax.get_label() != "<colorbar>")
    fig.set_size_inches(8.0, 2.2 + 2.3 * n_panels)
    fig.suptitle(f"{scene.title}: {scene.scheme}, dt = {scene.dt:g} s", fontsize=10)
    write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=120))
