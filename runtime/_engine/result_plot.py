"""`Response.plot`: the stored quantities against time, labelled by DOF name and unit.

One subplot per quantity and unit (a beam's w and psi outputs go to two subplots: metres and
radians share no axis), a line per output labelled by the DOF's name (or ``DOF <0-based
index>``),
the unit on the y axis, ``t [s]`` on the x axis; more than `MAX_LINES` outputs are drawn as a
heat map (time x DOF) with a colour bar. matplotlib is imported only here, on first use.
"""
from __future__ import annotations

import numpy as np

from dtdyn._engine.extras import require
from dtdyn._engine.result import DOF_QUANTITIES, ELEMENT_QUANTITIES, ROTATION, TRANSLATION

#: more lines than this in one subplot are drawn as a heat map (time x DOF)
MAX_LINES = 8
#: what each quantity is, by the kind of its DOFs (subplot titles)
TITLES = {
    TRANSLATION: {"x": "displacement", "v": "velocity", "a": "acceleration",
                  "a_abs": "absolute acceleration", "x_abs": "absolute displacement",
                  "g": "element force", "z": "internal state"},
    ROTATION: {"x": "rotation", "v": "angular velocity", "a": "angular acceleration",
               "a_abs": "absolute angular acceleration", "x_abs": "absolute rotation",
               "g": "element moment", "z": "internal state"},
}
_ORDER = DOF_QUANTITIES + ELEMENT_QUANTITIES


def _quantities(response, quantities) -> list[str]:
    stored = [q for q in _ORDER if getattr(response, q, None) is not None]
    if quantities is None:
        if not stored:
            raise ValueError("the response stores no quantity: nothing to plot")
        return stored
    if isinstance(quantities, str):
        quantities = [quantities]
    for q in quantities:
        if q not in _ORDER:
            raise ValueError(f"quantities holds {q!r}: not a Response quantity; use one of "
                             f"{', '.join(_ORDER)}")
        if q not in stored:
            raise ValueError(f"quantities holds {q!r}, which the response did not store "
                             f"(stored: {', '.join(stored) or 'none'})")
    return list(quantities)


def _columns(response, outputs) -> list[int]:
    """Columns of x, v, a to draw for ``outputs`` (DOF indices or names; None: all)."""
    n = np.asarray(response.outputs).size
    if outputs is None:
        return list(range(n))
    if isinstance(outputs, (str, int, np.integer)):
        outputs = [outputs]
    columns = []
    for d in outputs:
        if isinstance(d, str):
            names = response.dof_names or ()
            if d not in names:
                shown = ", ".join(map(str, names[:8])) + (" ..." if len(names) > 8 else "")
                raise ValueError(f"outputs holds {d!r}, which is not a stored DOF name "
                                 f"(stored: {shown or 'no names; use 0-based DOF indices'})")
            columns.append(list(names).index(d))
        else:
            try:
                columns.append(response.column(int(d)))
            except KeyError:
                raise ValueError(f"outputs holds DOF {d!r}, which is not among the stored "
                                 f"outputs {np.asarray(response.outputs).tolist()}") from None
    return columns


def panels(response, quantities=None, outputs=None) -> list[tuple]:
    """The subplots `plot` draws: (quantity, unit, kind, columns, labels) each."""
    result = []
    dof_columns = _columns(response, outputs)
    for q in _quantities(response, quantities):
        units = response.units(q)
        if q in DOF_QUANTITIES:  # legend: the DOF's name, else "DOF <0-based index>"
            cols = dof_columns
            labels = [response.dof_label(j) if response.dof_names is not None
                      else f"DOF {response.dof_label(j)}" for j in cols]
            kinds = response.dof_kinds
        else:
            cols = list(range(len(units)))
            labels = [f"{'element' if q == 'g' else 'state'} {j}" for j in cols]
            kinds = response.element_kinds if q == "g" else response.state_kinds
        for unit in dict.fromkeys(units[j] for j in cols):  # each unit once, in order
            picked = [k for k, j in enumerate(cols) if units[j] == unit]
            kind = TRANSLATION if kinds is None else kinds[cols[picked[0]]]
            result.append((q, unit, kind, [cols[k] for k in picked], [labels[k] for k in picked]))
    return result


def plot(response, quantities=None, outputs=None, *, fig=None, ax=None):
    """`Response.plot` (its docstring); returns the Figure."""
    require("matplotlib", "plot", "Response.plot")
    todo = panels(response, quantities, outputs)
    if ax is not None:
        axes = list(np.atleast_1d(np.asarray(ax, dtype=object)).ravel())
        if len(axes) != len(todo):
            raise ValueError(f"ax holds {len(axes)} axes for {len(todo)} subplots "
                             f"({', '.join(f'{q} [{u}]' for q, u, *_ in todo)})")
        fig = axes[0].figure
    else:
        if fig is None:
            import matplotlib.pyplot as plt
            fig = plt.figure(figsize=(8.0, 1.2 + 2.3 * len(todo)), layout="constrained")
        axes = list(fig.subplots(len(todo), 1, sharex=True, squeeze=False)[:, 0])
    t = np.asarray(response.t)
    for axis, (q, unit, kind, cols, labels) in zip(axes, todo):
        values = np.asarray(getattr(response, q))[:, cols]
        if len(cols) > MAX_LINES:
            limit = float(np.nanmax(np.abs(values))) if values.size else 1.0
            limit = limit if np.isfinite(limit) and limit > 0 else 1.0
            order = list(range(len(cols)))
            if q in DOF_QUANTITIES:  # rows by DOF index
                order = list(np.argsort(np.asarray(response.outputs)[cols], kind="stable"))
            image = axis.pcolormesh(t, np.arange(len(cols)), values[:, order].T,
                                    shading="nearest", cmap="RdBu_r", vmin=-limit, vmax=limit)
            fig.colorbar(image, ax=axis, label=f"{q} [{unit}]")
            ticks = np.unique(np.linspace(0, len(cols) - 1, min(len(cols), 8)).astype(int))
            axis.set_yticks(ticks, [response.dof_label(cols[order[k]]) if q in DOF_QUANTITIES
                                    else str(cols[order[k]]) for k in ticks])
            axis.set_ylabel("DOF" if q in DOF_QUANTITIES else
                            ("element" if q == "g" else "state"))
        else:
            for k, label in enumerate(labels):
                axis.plot(t, values[:, k], lw=1.0, label=label)
            axis.set_ylabel(f"{q} [{unit}]")
            axis.grid(True, alpha=0.3)
            axis.legend(fontsize=7, loc="best")
        axis.set_title(TITLES[kind][q], fontsize=9, loc="left")
    axes[-1].set_xlabel("t [s]")
    return fig
