"""Frequency responses between several loaded DOFs and outputs, from a one-pair solver."""
from __future__ import annotations

import numpy as np


def _dofs(name, value, index) -> list:
    if isinstance(value, (str, int, np.integer)) or np.ndim(value) == 0:
        return [index(name, value)]
    values = [index(name, v) for v in value]
    if not values:
        raise ValueError(f"{name} is empty: give at least one DOF")
    return values


def receptance_matrix(pair, force_dofs, outputs, index) -> np.ndarray:
    """H[f, o, i] = pair(force_dofs[i], outputs[o])[f]: complex (n_omega, n_out, n_in), or the
    1-D (n_omega,) of ``pair`` itself when both ``force_dofs`` and ``outputs`` are single DOFs.
    ``index(name, dof)`` checks one DOF (an index or a name) and returns its index."""
    inputs = _dofs("force_dofs", force_dofs, index)
    outs = _dofs("outputs", outputs, index)
    H = np.stack([np.stack([pair(i, o) for i in inputs], axis=-1) for o in outs], axis=1)
    single = not (np.ndim(force_dofs) or np.ndim(outputs))
    return H[:, 0, 0] if single else H
