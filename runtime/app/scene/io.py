"""Saving and plotting a scene's response."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn._engine.result import Response
from dtdyn.app.scene.schema import Scene

def save_results(path: str | os.PathLike, response: Response, scene: Scene) -> None:
    """Write ``t``, ``outputs`` and the scene's requested quantities to an ``.npz`` file.

    A scene with general matrices also stores ``dof_names``: the names of ``outputs``.

    Written atomically: to a temporary file in the same folder, then renamed over ``path``, so a
    failed write leaves no partial file (and an existing ``path`` untouched).
    """
    path = Path(path)
    arrays = {"t": np.asarray(response.t), "outputs": np.asarray(response.outputs)}
    if scene.kind == "matrices":
        arrays["dof_names"] = np.array([scene.dof_label(d) for d in arrays["outputs"]], dtype=str)
    for q in scene.quantities:
        value = getattr(response, q)
        if value is None:
            raise ValueError(f"output.quantities asks for {q!r}, but the response did not store it")
        arrays[q] = np.asarray(value)
    write_atomic(path, lambda f: np.savez(f, **arrays))


def plot_response(path: str | os.PathLike, response: Response, scene: Scene) -> None:
    """Plot displacement against time, one labelled line per output DOF; saved atomically.

    Uses the Agg canvas directly (no pyplot, no global backend switch). The file format follows
    the suffix of ``path`` (``.png`` when there is none).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    if response.x is None:
        raise ValueError("the response has no displacement x to plot")
    fig = Figure(figsize=(8.0, 4.5), layout="constrained")
    canvas = FigureCanvasAgg(fig)
    fmt = path.suffix[1:].lower() or "png"
    if fmt not in canvas.get_supported_filetypes():
        raise ValueError(f"cannot plot to {str(path)!r}: unsupported format {fmt!r}, allowed: "
                         f"{', '.join(sorted(canvas.get_supported_filetypes()))}")
    ax = fig.add_subplot()
    x = np.asarray(response.x)
    if x.shape[1] > 10:  # more lines than the default colour cycle: colour by position instead
        from matplotlib import colormaps
        ax.set_prop_cycle(color=colormaps["viridis"](np.linspace(0.0, 0.95, x.shape[1])))
    for j, dof in enumerate(np.asarray(response.outputs)):
        if scene.kind == "matrices":
            name = scene.dof_label(dof)
            label = f"DOF {int(dof)}" if name == str(int(dof)) else f"{name} (DOF {int(dof)})"
        else:
            label = f"DOF {int(dof)} (mass {int(dof) + 1})"
        ax.plot(response.t, x[:, j], lw=1.0, label=label)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("x [m]")
    ax.set_title(f"{scene.title}\n{scene.scheme}, dt = {scene.dt:g} s", fontsize=10)
    ax.grid(True, alpha=0.3)
    if x.shape[1] <= 20:
        ax.legend(fontsize=7, ncols=1 + x.shape[1] // 8, loc="best")
    write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=120))
