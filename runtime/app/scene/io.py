"""Saving and plotting a scene's response."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn._engine.extras import require
from dtdyn._engine.result import Response
from dtdyn.app.scene.schema import QUANTITIES, Scene

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
            "n_dof": scene.n_dof, "scheme": scene.scheme, "params": dict(scene.scheme_params),
            "dt": scene.dt, "n_steps": scene.n_steps, "force_dofs": scene.loaded.tolist(),
            "loads": scene.loads, "elements": [el.describe() for el in scene.elements],
            "quantities": list(scene.quantities),
            **({} if scene.ground is None else
               {"ground_quantity": scene.ground_quantity,
                f"ground_peak_{_GROUND_UNIT[scene.ground_quantity]}":
                    float(np.abs(scene.ground).max())})}


#: the SI unit of each [ground] quantity, as a metadata key suffix
_GROUND_UNIT = {"acceleration": "m_s2", "velocity": "m_s", "displacement": "m"}


#: more stored DOFs than this are drawn as a heat map (time x DOF) instead of one line each
MAX_LINES = 8
_UNITS = {"x": ("displacement", "m"), "v": ("velocity", "m/s"), "a": ("acceleration", "m/s^2")}


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
    """Plot every stored quantity (x, v, a) against time, one panel each, saved atomically.

    Up to `MAX_LINES` DOFs: one labelled line per DOF. More: a heat map (time x DOF) with a
    colour bar, so that a long chain stays readable. Uses the Agg canvas directly (no pyplot,
    no global backend switch); the format follows the suffix of ``path`` (``.png`` when none).
    """
    path, fmt = plot_checked_path(path)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    stored = [q for q in QUANTITIES if q in scene.quantities and getattr(response, q) is not None]
    if not stored:
        raise ValueError("the response stores none of the scene's quantities: nothing to plot")
    outputs = np.asarray(response.outputs)
    fig = Figure(figsize=(8.0, 2.2 + 2.3 * len(stored)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(stored), 1, sharex=True, squeeze=False)[:, 0]
    for ax, q in zip(axes, stored):
        values = np.asarray(getattr(response, q))
        name, unit = _UNITS[q]
        if outputs.size > MAX_LINES:
            order = np.argsort(outputs)
            image = ax.pcolormesh(response.t, np.arange(outputs.size), values[:, order].T,
                                  shading="nearest", cmap="RdBu_r",
                                  vmin=-np.abs(values).max(), vmax=np.abs(values).max())
            fig.colorbar(image, ax=ax, label=f"{q} [{unit}]")
            ticks = np.unique(np.linspace(0, outputs.size - 1, min(outputs.size, 8)).astype(int))
            ax.set_yticks(ticks, [scene.dof_label(outputs[order][k]) for k in ticks])
            ax.set_ylabel("DOF")
        else:
            for j, dof in enumerate(outputs):
                ax.plot(response.t, values[:, j], lw=1.0, label=_label(scene, dof))
            ax.set_ylabel(f"{q} [{unit}]")
            ax.grid(True, alpha=0.3)
        ax.set_title(name, fontsize=9, loc="left")
    if outputs.size <= MAX_LINES:
        axes[0].legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(f"{scene.title}: {scene.scheme}, dt = {scene.dt:g} s", fontsize=10)
    write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=120))


def _label(scene: Scene, dof) -> str:
    if scene.kind == "matrices":
        name = scene.dof_label(dof)
        return f"DOF {int(dof)}" if name == str(int(dof)) else f"{name} (DOF {int(dof)})"
    return f"DOF {int(dof)} (mass {int(dof) + 1})"
