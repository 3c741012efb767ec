"""The result object every simulation entry point returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Response:
    """Sampled response at ``t[0] .. t[n_steps]``.

    ``x``, ``v``, ``a`` have shape ``(n_steps + 1, len(outputs))``; column ``j`` belongs to the
    0-based DOF ``outputs[j]``. A quantity the run was not asked to store is ``None``.
    ``info`` holds what was run (scheme, parameters, backend, timings in seconds).
    """

    t: np.ndarray
    outputs: np.ndarray
    x: np.ndarray | None = None
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def column(self, dof: int) -> int:
        """Column of ``x``, ``v``, ``a`` that holds 0-based DOF ``dof``."""
        hits = np.flatnonzero(self.outputs == dof)
        if hits.size == 0:
            raise KeyError(f"DOF {dof} is not among the stored outputs {self.outputs.tolist()}")
        return int(hits[0])
