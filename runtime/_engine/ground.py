r"""Support motion: a ground acceleration, velocity or displacement record as an effective load,
and the absolute motion of the result.

With the DOFs measured relative to the moving support, :math:`u = x + r\,u_g` (r: the
influence vector or matrix, one column per ground direction; ones when every DOF moves with the
ground), the equations become

.. math::

    M \ddot x + C \dot x + K x = f - M r\, \ddot u_g(t), \qquad
    \ddot u^{\mathrm{abs}} = \ddot x + r\, \ddot u_g

(C r = K r = 0 for a rigid support motion; Chopra, *Dynamics of Structures*, sec. 9.4). The
ground acceleration is sampled at the force's times and, like the force, linear between
samples, so every entry point keeps its own treatment of the load. A velocity or displacement
record is first turned, direction by direction, into the acceleration record linear between
samples whose motion passes through it (`ground_acceleration_from`). The run gives x, v, a
relative to the support, ``a_abs``, and for a displacement record also
:math:`u^{\mathrm{abs}} = x + r\, u_g` (``x_abs``, u_g the record's own samples).
"""
from __future__ import annotations

import numpy as np

from dtdyn._engine import validate

#: the keyword of each ground record, by the quantity it samples
RECORDS = {"acceleration": "ground_acceleration", "velocity": "ground_velocity",
           "displacement": "ground_displacement"}


class Ground:
    """The checked record a_g (n_samples, n_dir), influence r (n_dof, n_dir) and, for a
    displacement record, its samples u_g (n_samples, n_dir)."""

    def __init__(self, record, influence, n_dof: int, n_samples: int | None,
                 quantity: str = "acceleration", dt: float | None = None):
        name = RECORDS[quantity]
        a = validate.real_array(name, record, "a record of samples")
        if a.ndim == 1:
            a = a[:, None]
        least = 3 if quantity == "displacement" else 2
        if a.ndim != 2 or a.shape[0] < least or a.shape[1] < 1:
            raise ValueError(f"{name} has shape {np.shape(record)}, expected (n_samples,) or "
                             f"(n_samples, n_directions), n_samples >= {least}")
        if n_samples is not None and a.shape[0] != n_samples:
            raise ValueError(f"{name} has {a.shape[0]} samples and force {n_samples}: both are "
                             "sampled at t_k = k dt")
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            i, j = bad[0]
            raise ValueError(f"{name}[{i}, {j}] = {float(a[i, j])!r} is not finite")
        if influence is None:
            if a.shape[1] != 1:
                raise ValueError(f"{name} has {a.shape[1]} directions: give the influence "
                                 "matrix (n_dof, n_directions)")
            r = np.ones((n_dof, 1))
        else:
            r = validate.real_array("influence", influence)
            if r.ndim == 1:
                r = r[:, None]
            if r.shape != (n_dof, a.shape[1]) or not np.isfinite(r).all():
                raise ValueError(f"influence has shape {np.shape(influence)}, expected "
                                 f"({n_dof},) or ({n_dof}, {a.shape[1]}) finite values: one "
                                 f"column per direction of {name}")
        self.quantity, self.u = quantity, None
        if quantity != "acceleration":
            if quantity == "displacement":
                self.u = np.ascontiguousarray(a)
            a = np.column_stack([ground_acceleration_from(dt, **{quantity: col}) for col in a.T])
        self.a, self.r = np.ascontiguousarray(a), r

    def load(self, M, force, force_dofs):
        """(force', force_dofs'): f - M r a_g on the loaded DOFs and those M r reaches."""
        p = np.asarray(M @ self.r)  # (n_dof, n_dir)
        reached = np.flatnonzero(np.any(p != 0.0, axis=1))
        dofs = reached if force is None else np.union1d(force_dofs, reached)
        out = -(self.a @ p[dofs].T)
        if force is not None:
            out[:, np.searchsorted(dofs, force_dofs)] += force
        return np.ascontiguousarray(out), dofs.astype(np.int64)

    def absolute(self, a, outputs):
        """a + r a_g at the outputs (None when a is not stored)."""
        return None if a is None else a + self.a @ self.r[outputs].T

    def absolute_displacement(self, x, outputs):
        """x + r u_g at the outputs (None when x is not stored or the record is not a
        displacement)."""
        return None if x is None or self.u is None else x + self.u @ self.r[outputs].T

    def describe(self) -> dict:
        return {"directions": int(self.a.shape[1]), "quantity": self.quantity,
                "peak": float(np.abs(self.a).max())}


def given(ground_acceleration=None, ground_velocity=None, ground_displacement=None):
    """The quantity of the one ground record given ("acceleration", "velocity",
    "displacement"), or None; more than one is a ValueError naming them."""
    records = {"acceleration": ground_acceleration, "velocity": ground_velocity,
               "displacement": ground_displacement}
    named = [q for q, rec in records.items() if rec is not None]
    if len(named) > 1:
        both = "both" if len(named) == 2 else "all"
        raise ValueError(f"{' and '.join(RECORDS[q] for q in named)} are {both} given: give "
                         "one ground record (ground_acceleration, ground_velocity or "
                         "ground_displacement)")
    return named[0] if named else None


def prepare(M, force, force_dofs, n_dof, ground_acceleration, influence, *, dt=None,
            ground_velocity=None, ground_displacement=None):
    """The load every entry point runs: (force, force_dofs, ground or None).

    Without ground motion the inputs come back as they are (``force`` required); with it,
    ``force`` may be None (the support motion alone) and ``force_dofs`` is checked here. At
    most one of ``ground_acceleration``, ``ground_velocity``, ``ground_displacement`` is given;
    a velocity or displacement record is converted with the sample step ``dt``."""
    quantity = given(ground_acceleration, ground_velocity, ground_displacement)
    if quantity is None:
        if influence is not None:
            raise ValueError("influence is given without a ground record (ground_acceleration, "
                             "ground_velocity or ground_displacement)")
        if force is None:
            raise ValueError("force is None: give a force record or a ground record "
                             "(ground_acceleration, ground_velocity or ground_displacement)")
        return force, force_dofs, None
    record = {"acceleration": ground_acceleration, "velocity": ground_velocity,
              "displacement": ground_displacement}[quantity]
    n_samples = None
    if force is not None:
        force_dofs = validate.dof_indices("force_dofs", force_dofs, n_dof)
        force = validate.force_record(force, force_dofs.size)
        n_samples = force.shape[0]
    ground = Ground(record, influence, n_dof, n_samples, quantity, dt)
    force, dofs = ground.load(M, force, force_dofs)
    return force, dofs, ground


def prepare_model(M, force, force_dofs, names, rigid, *, dt, ground_acceleration=None,
                  ground_velocity=None, ground_displacement=None, influence=None):
    """`prepare` for a model whose DOFs have names (a beam, a shaft): ``force_dofs`` may name
    them, and without ``influence`` a ground record moves the DOFs by ``rigid(n_dir)``, the
    model's rigid-body pattern per ground direction."""
    n = len(names)
    if force_dofs is not None:
        force_dofs = validate.dof_indices("force_dofs", force_dofs, n, names=names)
    quantity = given(ground_acceleration, ground_velocity, ground_displacement)
    if influence is None and quantity is not None:
        record = {"acceleration": ground_acceleration, "velocity": ground_velocity,
                  "displacement": ground_displacement}[quantity]
        influence = rigid(1 if np.ndim(record) < 2 else np.shape(record)[1])
    return prepare(M, force, force_dofs, n, ground_acceleration, influence, dt=dt,
                   ground_velocity=ground_velocity, ground_displacement=ground_displacement)


def finish(response, ground):
    """The response with ``a_abs`` (and ``x_abs`` for a displacement record) and
    ``info["ground"]`` when the run had support motion."""
    if ground is not None:
        response.a_abs = ground.absolute(response.a, response.outputs)
        response.x_abs = ground.absolute_displacement(response.x, response.outputs)
        response.info["ground"] = ground.describe()
    return response


def ground_acceleration_from(dt, *, displacement=None, velocity=None):
    r"""The ground acceleration record, linear between samples (the library's assumption for
    every load), whose motion passes through a prescribed displacement or velocity record.

    - ``displacement`` u_k: a acceleration linear between samples is a displacement cubic
      between them, twice continuously differentiable: the cubic spline through u_k, here with
      zero slope at t_0 (the ground starts at rest) and zero curvature at the end. Its second
      derivative at the samples, from :math:`a_{k-1} + 4 a_k + a_{k+1} = 6 (u_{k+1} - 2 u_k +
      u_{k-1}) / dt^2`, is the record; integrated back it returns u_k at every sample.
    - ``velocity`` v_k: then :math:`(a_k + a_{k+1}) dt / 2 = v_{k+1} - v_k` fixes a up to a
      sample-to-sample alternation :math:`(-1)^k a_0`, chosen with the least energy
      (:math:`\min \sum a_k^2`); integrated back it returns v_k at every sample.

    Every time-history entry point calls it (direction by direction) when given
    ``ground_displacement`` or ``ground_velocity`` instead of ``ground_acceleration``; call it
    yourself to see or reuse the record (an OpenSees user may know the silent zero of
    -disp/-vel inputs: here the motion is the one asked for).

    Parameters
    ----------
    dt : float
        Sample step, s.
    displacement, velocity : (n,) array_like
        Exactly one of them, samples at t_k = k dt (m, m/s).

    Returns
    -------
    (n,) ndarray
        Acceleration samples, m/s^2 (for m and m/s).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> t = np.arange(201) * 0.01
    >>> a = dd.ground_acceleration_from(0.01, displacement=1 - np.cos(2 * np.pi * t))
    >>> round(float(a[100] / (2 * np.pi) ** 2), 3)         # ~ cos(2 pi t) at t = 1 s
    1.0
    """
    import scipy.interpolate

    dt = validate.positive_scalar("dt", dt)
    if (displacement is None) == (velocity is None):
        raise ValueError("give exactly one of displacement and velocity")
    if displacement is not None:
        u = validate.vector("displacement", displacement)
        if u.size < 3:
            raise ValueError(f"displacement has {u.size} samples; the spline needs at least 3")
        t = dt * np.arange(u.size)
        spline = scipy.interpolate.CubicSpline(t, u, bc_type=((1, 0.0), (2, 0.0)))
        return spline(t, 2)
    v = validate.vector("velocity", velocity)
    if v.size < 2:
        raise ValueError(f"velocity has {v.size} samples, expected at least 2")
    p = np.zeros(v.size)  # the particular solution with a_0 = 0
    rhs = 2.0 * np.diff(v) / dt
    for k in range(v.size - 1):
        p[k + 1] = rhs[k] - p[k]
    alt = (-1.0) ** np.arange(v.size)
    return p - alt * (alt @ p) / v.size
