"""The result object every simulation entry point returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: the kinds of DOF a `Response` knows: a translation (m) or a rotation (rad)
TRANSLATION, ROTATION = "translation", "rotation"
#: SI unit of each stored quantity by the kind of its DOF (g: element force or moment, z: the
#: internal state, Bouc-Wen's hysteretic displacement or rotation)
UNITS = {
    TRANSLATION: {"x": "m", "x_abs": "m", "v": "m/s", "a": "m/s^2", "a_abs": "m/s^2",
                  "g": "N", "z": "m"},
    ROTATION: {"x": "rad", "x_abs": "rad", "v": "rad/s", "a": "rad/s^2", "a_abs": "rad/s^2",
               "g": "N m", "z": "rad"},
}
#: per stored DOF (columns named by DOF), then per element (g) and per internal state (z)
DOF_QUANTITIES = ("x", "v", "a", "a_abs", "x_abs")
ELEMENT_QUANTITIES = ("g", "z")


@dataclass
class Response:
    """Sampled response at the times ``t[0]`` to ``t[n_steps]``.

    Attributes
    ----------
    t : (n_steps + 1,) ndarray
        Sample times t_k = k dt, s.
    outputs : (n_out,) int ndarray
        The stored DOFs (0-based); column ``j`` of ``x``, ``v``, ``a`` belongs to ``outputs[j]``.
    x, v, a : (n_steps + 1, n_out) ndarray or None
        Displacement, velocity, acceleration; None for a quantity the run was not asked to store.
    info : dict
        What was run: scheme and parameters, dt, backend, timings in seconds, error estimates.
    meta : dict
        What the run was about: a model or scene summary, units, anything the caller adds; saved
        with the result together with the versions of dtdyn, NumPy and SciPy.
    dof_names : tuple of str, optional
        Names of the stored DOFs (a scene's ``model.dofs``).
    a_abs : (n_steps + 1, n_out) ndarray or None
        Absolute acceleration a + r a_g of a run under support motion (a ground record;
        x, v, a are then relative to the support), when ``a`` is stored; None otherwise.
    x_abs : (n_steps + 1, n_out) ndarray or None
        Absolute displacement x + r u_g of a run under a ground displacement record
        (``ground_displacement``; u_g its own samples), when ``x`` is stored; None otherwise.
    g, z : (n_steps + 1, n_elements) and (n_steps + 1, n_states) ndarray or None
        Nonlinear runs asked for them: the element forces and the internal states.
    dof_kinds : tuple of str, optional
        ``"translation"`` or ``"rotation"`` for each stored DOF, which sets its units (m, m/s,
        m/s^2 or rad, rad/s, rad/s^2); None: every DOF a translation. `shaft_response` (all
        rotations) and `beam_response` (``psi`` DOFs rotations) fill it.
    element_kinds, state_kinds : tuple of str, optional
        The same for each column of ``g`` (a force, N, or a moment, N m) and of ``z`` (m or
        rad): the kind of the element's DOF i; None: translations.

    Files, tables and plots name a column by quantity, DOF and unit, ``x top [m]``,
    ``v main.1 [rad/s]``, ``a 4 [m/s^2]`` (the DOF's name where known, else its 0-based index),
    ``g 0 [N]`` (element 0); the time column is ``t [s]``.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.chain_response([1.0, 1.0], [4.0, 4.0], [0.1, 0.1], np.ones(11), 0.1,
    ...                       force_dofs=[1], outputs=[1], quantities=("x", "a"))
    >>> r.x.shape, r.v is None, r.column(1)
    ((11, 1), True, 0)
    """

    t: np.ndarray
    outputs: np.ndarray
    x: np.ndarray | None = None
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    info: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    dof_names: tuple | None = None
    a_abs: np.ndarray | None = None
    g: np.ndarray | None = None
    z: np.ndarray | None = None
    x_abs: np.ndarray | None = None
    dof_kinds: tuple | None = None
    element_kinds: tuple | None = None
    state_kinds: tuple | None = None

    def column(self, dof: int) -> int:
        """Column of ``x``, ``v``, ``a`` that holds 0-based DOF ``dof``."""
        hits = np.flatnonzero(self.outputs == dof)
        if hits.size == 0:
            raise KeyError(f"DOF {dof} is not among the stored outputs {self.outputs.tolist()}")
        return int(hits[0])

    def dof_label(self, j: int) -> str:
        """Name of the DOF in column ``j``: its entry in ``dof_names``, else its 0-based index."""
        if self.dof_names is not None:
            return str(self.dof_names[j])
        return str(int(np.asarray(self.outputs)[j]))

    def units(self, quantity: str) -> tuple:
        """The unit of every column of ``quantity``, from the kinds of its DOFs (`UNITS`).

        Parameters
        ----------
        quantity : {"x", "v", "a", "a_abs", "x_abs", "g", "z"}

        Returns
        -------
        tuple of str
            One unit per column: m, m/s, m/s^2, N (translations) or rad, rad/s, rad/s^2, N m
            (rotations); ``()`` for an element quantity that was not stored.

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> s = dd.Shaft([1.0, 2.0], [1e4, 2e4], [1.0, 1.0])
        >>> dd.shaft_response(s, np.ones(11), 1e-3, force_dofs=[1]).units("v")
        ('rad/s', 'rad/s')
        """
        if quantity in DOF_QUANTITIES:
            kinds, n, field_name = self.dof_kinds, np.asarray(self.outputs).size, "dof_kinds"
        elif quantity in ELEMENT_QUANTITIES:
            values = getattr(self, quantity)
            n = 0 if values is None else np.asarray(values).shape[1]
            field_name = {"g": "element_kinds", "z": "state_kinds"}[quantity]
            kinds = getattr(self, field_name)
        else:
            raise ValueError(f"quantity = {quantity!r}: not a Response quantity; use one of "
                             f"{', '.join(DOF_QUANTITIES + ELEMENT_QUANTITIES)}")
        if kinds is None:
            return (UNITS[TRANSLATION][quantity],) * n
        if len(kinds) != n:
            raise ValueError(f"{field_name} has {len(kinds)} entries for {n} columns of "
                             f"{quantity}")
        bad = [k for k in kinds if k not in UNITS]
        if bad:
            raise ValueError(f"{field_name} holds {bad[0]!r}; each entry must be one of "
                             f"{', '.join(map(repr, UNITS))}")
        return tuple(UNITS[k][quantity] for k in kinds)

    def save(self, path):
        """Write the response and its metadata to ``path``: ``.npz``, ``.nc`` (netCDF, needs
        xarray) or ``.csv``, chosen by the extension (an unknown one is a ValueError before
        anything is written); atomic. `dtdyn.load_result` reads it back.

        A ``.csv`` is one plain table that pandas and spreadsheets read with their defaults:
        one header row, the time ``t [s]`` first, then a column per stored quantity and DOF
        named by quantity, DOF and unit (``x top [m]``, ``v 3 [m/s]``); the metadata (run
        info, the model's summary, DOF names and kinds, versions) goes to the JSON sidecar
        ``<path>.json`` (``x.csv`` -> ``x.csv.json``), written together with the table.

        Parameters
        ----------
        path : str or Path
            The file; its extension chooses the format.

        Returns
        -------
        Path
            ``path``.

        Examples
        --------
        >>> import numpy as np, dtdyn as dd, tempfile, pathlib
        >>> r = dd.chain_response([1.0], [4.0], [0.1], np.ones(11), 0.1, quantities=("x",))
        >>> path = r.save(pathlib.Path(tempfile.mkdtemp()) / "r.csv")
        >>> path.read_text().splitlines()[0], path.with_name("r.csv.json").is_file()
        ('t [s],x 0 [m]', True)
        """
        from dtdyn._engine.result_io import save_result
        return save_result(self, path)

    def to_xarray(self):
        """The response as an xarray Dataset (dims ``time``, ``dof``; metadata in ``attrs``)."""
        from dtdyn._engine.result_io import to_xarray
        return to_xarray(self)

    def to_dataframe(self):
        """The response as a pandas DataFrame with the columns of `save` to CSV: ``t [s]``,
        then one per stored quantity and DOF (``x top [m]``); needs pandas (``dtdyn[pandas]``).

        Returns
        -------
        pandas.DataFrame
            The same table as ``pandas.read_csv`` of ``r.save("r.csv")`` (a RangeIndex; use
            ``.set_index("t [s]")`` for a time index).

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> r = dd.chain_response([1.0, 1.0], [4.0, 4.0], [0.1, 0.1], np.ones(11), 0.1,
        ...                       force_dofs=[1], quantities=("x", "a"))
        >>> list(r.to_dataframe().columns)
        ['t [s]', 'x 0 [m]', 'x 1 [m]', 'a 0 [m/s^2]', 'a 1 [m/s^2]']
        """
        from dtdyn._engine.result_io import to_dataframe
        return to_dataframe(self)

    def plot(self, quantities=None, outputs=None, *, fig=None, ax=None):
        """Plot the stored quantities against time: one subplot per quantity (and per unit,
        where a beam's outputs mix w and psi), a line per output with the DOF's name (or ``DOF
        <0-based index>``) in the legend, the unit on the y axis, ``t [s]`` on the x axis. More
        than 8 outputs are drawn as a heat map (time x DOF). Needs matplotlib (``dtdyn[plot]``).

        Parameters
        ----------
        quantities : sequence of str, optional
            Which of the stored "x", "v", "a", "a_abs", "x_abs", "g", "z" to draw (default:
            every stored one).
        outputs : sequence of int or str, optional
            The DOFs to draw, by 0-based index or name (default: every stored DOF).
        fig : matplotlib.figure.Figure, optional
            Draw into this figure (its subplots are added); default a new pyplot figure.
        ax : matplotlib Axes or sequence of Axes, optional
            Draw into these axes instead, one per subplot.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> from matplotlib.figure import Figure
        >>> s = dd.Shaft([1.0, 2.0], [1e4, 2e4], [1.0, 1.0])
        >>> r = dd.shaft_response(s, np.ones(101), 1e-3, force_dofs=[1], quantities=("x", "v"))
        >>> fig = r.plot(fig=Figure())
        >>> [a.get_ylabel() for a in fig.axes]
        ['x [rad]', 'v [rad/s]']
        """
        from dtdyn._engine.result_plot import plot
        return plot(self, quantities, outputs, fig=fig, ax=ax)
