"""The same integrators on assembled M, C, K (dense or scipy.sparse), factorizing once.

Acceleration form of every scheme (it exists for explicit ones too): with
x_e = Dx a_e + Ex, v_e = Dv a_e + Ev from the generated coefficients,

    (M + Dv C + Dx K) a_e = w0 F_n + w1 F_{n+1} - C Ev - K Ex,

then x, v, a at t_{n+1} from the scheme's update. This is the reference the DT-TMM sweeps must
equal, and the general-matrix path.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn.generated.dttmm_sweep import combine, shift_history

from . import stepping, validate
from .result import Response
from .schemes import get_scheme


def _matrix(name, A, n=None):
    if sps.issparse(A):
        A = sps.csr_matrix(A, dtype=float)
        data = A.data
    else:
        A = np.asarray(A, dtype=float)
        data = A
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {A.shape}")
    if n is not None and A.shape[0] != n:
        raise ValueError(f"{name} has shape {A.shape}, expected ({n}, {n}) to match M")
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{name} has a non-finite entry")
    return A


def _factor(A, name):
    """A solve function for A (sparse LU or dense LU), with a clear error when singular."""
    if sps.issparse(A):
        try:
            lu = spla.splu(sps.csc_matrix(A))
        except RuntimeError as exc:
            raise ValueError(f"{name} is singular: {exc}") from None
        return lu.solve
    lu, piv = sla.lu_factor(A, check_finite=False)
    d = np.abs(np.diag(lu))
    if d.min() <= np.finfo(float).eps * A.shape[0] * max(d.max(), 1e-300):
        raise ValueError(f"{name} is singular (smallest LU pivot {d.min():.3g})")
    return lambda b: sla.lu_solve((lu, piv), b, check_finite=False)


def simulate_mck(M, C, K, force, dt, n_steps, loaded=None, scheme="newmark", outputs=None,
                 quantities=("x", "v", "a"), progress=False, **scheme_params) -> Response:
    """Time history of M q'' + C q' + K q = L f(t) by one of the generated integrators.

    Same force convention and result as `simulate_chain`: ``force`` has shape
    (n_steps + 1, len(loaded)) with samples at t_0 .. t_n; zero initial state; M must be
    nonsingular (for the initial acceleration).
    """
    M = _matrix("M", M)
    n = M.shape[0]
    C, K = _matrix("C", C, n), _matrix("K", K, n)
    dt = validate.positive_scalar("dt", dt)
    n_steps = validate.step_count("n_steps", n_steps)
    loaded = validate.dof_indices("loaded", loaded, n)
    force = validate.force_samples(force, n_steps, loaded)
    outputs = validate.dof_indices("outputs", outputs, n)
    quantities = stepping.check_quantities(quantities)
    info = get_scheme(scheme, **scheme_params)
    f0 = np.zeros(n)
    f0[loaded] = force[0]
    a0 = _factor(M, "M")(f0)

    def make_advance(sch, K_):
        solve = _factor(M + K_["r"] * C + K_["p"] * K, "the effective matrix M + Dv C + Dx K")
        names = sch.history

        def advance(frc, H, xo, vo, ao):
            Fe = np.zeros(n)
            for step in range(frc.shape[0] - 1):
                Fe[loaded] = K_["w0"] * frc[step] + K_["w1"] * frc[step + 1]
                ae = solve(Fe - K @ combine(K_, "q", H, names) - C @ combine(K_, "s", H, names))
                new = {q: combine(K_, q + "1", H, names, K_.get(q + "1_u", 0.0) * ae)
                       for q in "xva"}
                shift_history(H, names, new)
                for arr, q in ((xo, "x"), (vo, "v"), (ao, "a")):
                    if arr is not None:
                        arr[step + 1] = new[q][outputs]
            return 0.0
        return advance

    res = stepping.integrate(info, "acceleration", dt, force, (np.zeros(n), np.zeros(n), a0),
                             make_advance, outputs, quantities, progress)
    res.info.update(method="assembled matrices", sparse=sps.issparse(M))
    return res
