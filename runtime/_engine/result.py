"""The result object every simulation entry point returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Response:
    """Sampled response at ``t[0] .. t[n_steps]``.

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

    def column(self, dof: int) -> int:
        """Column of ``x``, ``v``, ``a`` that holds 0-based DOF ``dof``."""
        hits = np.flatnonzero(self.outputs == dof)
        if hits.size == 0:
            raise KeyError(f"DOF {dof} is not among the stored outputs {self.outputs.tolist()}")
        return int(hits[0])

    def save(self, path):
        """Write the response and its metadata to ``path``: ``.npz``, ``.nc`` (netCDF, needs
        xarray) or ``.csv``, chosen by the extension (an unknown one is a ValueError before
        anything is written); atomic. `dtdyn.load_result` reads it back. Returns the path."""
        from dtdyn._engine.result_io import save_result
        return save_result(self, path)

    def to_xarray(self):
        """The response as an xarray Dataset (dims ``time``, ``dof``; metadata in ``attrs``)."""
        from dtdyn._engine.result_io import to_xarray
        return to_xarray(self)
