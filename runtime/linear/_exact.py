"""Exact sampled response of a linear structure to a piecewise-linear (first-order-hold) force.

This is the reference solution for linear problems: it has no
discretisation error beyond round-off in the matrix exponential, for any ``dt``.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg
import scipy.sparse

from dtdyn._engine import ground as support
from dtdyn._engine import linalg
from dtdyn._engine import stepping, validate
from dtdyn.linear._discretize import first_order_form
from dtdyn._engine.result import Response
from dtdyn._engine.errors import SingularMassError

__all__ = ["SingularMassError", "exact_response", "foh_matrices"]

METHOD = "exact (matrix exponential, first-order hold)"


def foh_matrices(A: np.ndarray, B: np.ndarray, dt: float):
    """Exact first-order-hold discretisation of ``z' = A z + B u``.

    Returns ``(Phi, G0, G1)`` such that ``z_{n+1} = Phi z_n + G0 u_n + G1 u_{n+1}`` holds exactly
    when ``u`` is linear between the samples ``u_n`` and ``u_{n+1}``. See :func:`exact_response`
    for the formula.
    """
    ns, ni = B.shape
    F = np.zeros((ns + 2 * ni, ns + 2 * ni))
    F[:ns, :ns] = A * dt
    F[:ns, ns:ns + ni] = B * dt
    F[ns:ns + ni, ns + ni:] = np.eye(ni)
    E = scipy.linalg.expm(F)
    Phi = E[:ns, :ns]
    gam_a = E[:ns, ns:ns + ni]       # int_0^dt e^{A(dt-s)} ds B
    gam_b = E[:ns, ns + ni:]         # int_0^dt e^{A(dt-s)} (s/dt) ds B
    return Phi, gam_a - gam_b, gam_b


def _reduced_form(M, C, K, loaded):
    r"""``(A, B, Vz, Vf, m)``: ``z' = A z + B f``, ``q' = Vz z + Vf f``, ``m`` the DOFs whose
    velocity is a state (z = [q; q'_m]).

    Nonsingular M: z = [q; q'], the first-order form (`first_order_form`), Vz = [0 I], Vf = 0.
    Massless DOFs (zero rows and columns of M, index set z; the others m): their equations
    C_zz q_z' = f_z - C_zm q_m' - K_z q are first order, so z = [q; q_m'] and

        q_z' = C_zz^-1 (f_z - C_zm q_m' - K_z q),
        M_mm q_m'' = f_m - C_mm q_m' - C_mz q_z' - K_m q,

    which needs C_zz nonsingular (each massless DOF has damping that fixes its velocity).
    """
    N = M.shape[0]
    massless = np.flatnonzero(~M.any(axis=1))
    L = np.eye(N)[:, loaded]
    if massless.size == 0:
        A, B_all = first_order_form(M, C, K)
        Vz = np.hstack([np.zeros((N, N)), np.eye(N)])
        return A, B_all[:, loaded], Vz, np.zeros((N, len(loaded))), np.arange(N)
    z, m = massless, np.flatnonzero(M.any(axis=1))
    if M[:, z].any():
        raise ValueError(f"M has zero rows {z.tolist()} but not zero columns there: exact_response "
                         "handles massless DOFs (zero row and column) only")
    solve_m = (linalg.solver(M[np.ix_(m, m)], "M without its massless DOFs",
                             "exact_response needs it nonsingular") if m.size else None)
    solve_z = linalg.solver(C[np.ix_(z, z)], f"C at the massless DOFs {z.tolist()}",
                            "their velocity is fixed by C_zz q_z' = f_z - C_zm q_m' - K_z q")
    nm = m.size
    # q' = Vz [q; q_m'] + Vf f
    Vz = np.zeros((N, N + nm))
    Vf = np.zeros((N, len(loaded)))
    Vz[m, N + np.arange(nm)] = 1.0
    Vz[z, :N] = -solve_z(K[z])
    Vz[z, N:] = -solve_z(C[np.ix_(z, m)])
    Vf[z] = solve_z(L[z])
    # z' = [q'; q_m'']
    A = np.zeros((N + nm, N + nm))
    B = np.zeros((N + nm, len(loaded)))
    A[:N], B[:N] = Vz, Vf
    if solve_m is None:  # no mass at all: C q' + K q = f
        return A, B, Vz, Vf, m
    A[N:] = -solve_m(np.hstack([K[m], C[np.ix_(m, m)]]) + C[np.ix_(m, z)] @ Vz[z])
    B[N:] = solve_m(L[m] - C[np.ix_(m, z)] @ Vf[z])
    return A, B, Vz, Vf, m


def exact_response(M, C, K, force, dt, *, force_dofs=None, outputs=None,
                   quantities=("x", "v", "a"), x0=None, v0=None, ground_acceleration=None,
                   ground_velocity=None, ground_displacement=None,
                   influence=None) -> Response:
    r"""Exact response of ``M q'' + C q' + K q = L f(t)`` to a piecewise-linear force.

    The force is known at the samples :math:`t_n = n\,\Delta t` and is taken to be linear in
    between (first-order hold). For such an input the linear ODE has a closed-form solution,
    evaluated here with one matrix exponential, so the samples are exact up to round-off.

    Parameters
    ----------
    M, C, K : (N, N) array_like or scipy.sparse matrix
        Mass, damping and stiffness matrices (converted to dense; intended for small and
        medium N). ``M`` must be nonsingular, or singular only through massless DOFs (zero
        rows and columns) whose damping block ``C[z, z]`` is nonsingular: see Notes.
    force : (n_steps + 1, len(force_dofs)) array_like
        Force samples :math:`f_0 \dots f_n` at :math:`t_k = k\,\Delta t`; column ``j`` acts on
        DOF ``force_dofs[j]``. A 1-D array is one column.
    dt : float
        Sample interval, > 0.
    force_dofs : sequence of int, optional
        0-based DOFs the force columns act on (all DOFs when None). This defines the
        :math:`N \times n_{in}` selection matrix :math:`L`.
    outputs : sequence of int, optional
        0-based DOFs to store (all DOFs when None).
    quantities : subset of ("x", "v", "a")
        What is stored; the others are None in the result.
    x0, v0 : (N,) array_like, optional
        Initial displacement and velocity (zero when None).

    ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
        Support acceleration at the force's times, linear between samples: the DOFs are then
        relative to the support, loaded by f - M r a_g, and the result adds ``a_abs``
        (``force`` may be None).
    ground_velocity, ground_displacement : array_like, optional
        Instead of ``ground_acceleration`` (one ground record at most): the support velocity
        (m/s) or displacement (m), shaped like it, turned direction by direction into the
        acceleration record linear between samples whose motion passes through it
        (`ground_acceleration_from`); a displacement record also gives ``x_abs = x + r u_g``.
    influence : (N,) or (N, n_dir) array_like, optional
        r, each DOF's motion per unit support motion (default: ones).

    Returns
    -------
    Response
        ``t``, ``outputs`` and ``x``, ``v``, ``a`` of shape ``(n_steps + 1, len(outputs))``;
        ``info = {"method": ..., "run_time": seconds}``.

    Notes
    -----
    With :math:`z = [q;\ \dot q]` the system is :math:`\dot z = A z + B f` where

    .. math::

        A = \begin{bmatrix} 0 & I \\ -M^{-1}K & -M^{-1}C \end{bmatrix}, \qquad
        B = \begin{bmatrix} 0 \\ M^{-1}L \end{bmatrix}

    (:math:`M^{-1}` applied through an LU solve, never formed). On
    :math:`[t_n, t_{n+1}]`, with :math:`s = t - t_n`,
    :math:`f(t) = f_n + (f_{n+1} - f_n)\, s / \Delta t`, and

    .. math::

        z_{n+1} = \Phi z_n + \Gamma_a f_n + \Gamma_b (f_{n+1} - f_n)
                = \Phi z_n + (\Gamma_a - \Gamma_b) f_n + \Gamma_b f_{n+1},

    .. math::

        \Phi = e^{A\Delta t},\quad
        \Gamma_a = \int_0^{\Delta t} e^{A(\Delta t - s)}\,ds\; B,\quad
        \Gamma_b = \int_0^{\Delta t} e^{A(\Delta t - s)}\,\frac{s}{\Delta t}\,ds\; B .

    All three come from one exponential of an augmented block matrix (Van Loan 1978;
    Franklin, Powell & Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
    first-order-hold equivalent):

    .. math::

        \exp\begin{bmatrix} A\Delta t & B\Delta t & 0 \\ 0 & 0 & I \\ 0 & 0 & 0 \end{bmatrix}
        = \begin{bmatrix} \Phi & \Gamma_a & \Gamma_b \\ 0 & I & I \\ 0 & 0 & I \end{bmatrix},

    which follows by integrating :math:`[z; w_1; w_2]' = F [z; w_1; w_2]` over unit scaled
    time :math:`\tau = s/\Delta t` from :math:`[0; a; b]`: :math:`w_1 = a + \tau b`, so
    :math:`z(1) = \int_0^{\Delta t} e^{A(\Delta t-s)} B (a + b\, s/\Delta t)\, ds`.
    The weight of :math:`f_n` is :math:`\Gamma_0 = \Gamma_a - \Gamma_b`, that of
    :math:`f_{n+1}` is :math:`\Gamma_1 = \Gamma_b`.

    Accelerations come from the equation of motion at each sample,
    :math:`\ddot q_n = M^{-1}(L f_n - C \dot q_n - K q_n)`.

    Massless DOFs (set :math:`z`, the others :math:`m`): their rows
    :math:`C_{zz}\dot q_z = L_z f - C_{zm}\dot q_m - K_z q` are first order, so the state is
    :math:`[q;\ \dot q_m]` and the same exponential applies to that ODE. Their velocity follows
    from these rows at each sample; their acceleration uses the slope of the force segment
    ending at :math:`t_n` (it jumps where the force has a kink). A given ``v0`` must satisfy
    these rows at :math:`t_0`.

    References
    ----------
    C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE Trans.
    Automatic Control 23(3), 395-404, 1978.
    G. F. Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*,
    3rd ed., Addison-Wesley, 1998.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.exact_response([[2.0]], [[3.0]], [[12.0]], np.ones(501), 0.02)   # P1
    >>> round(float(r.x[-1, 0]), 3)    # at t = 10 s close to the static deflection 1/12
    0.083
    """
    start = time.perf_counter()
    M, C, K = linalg.mck(M, C, K)
    N = M.shape[0]
    force, force_dofs, ground = support.prepare(M, force, force_dofs, N, ground_acceleration,
                                                influence, dt=dt,
                                                ground_velocity=ground_velocity,
                                                ground_displacement=ground_displacement)
    f, dt, loaded = validate.time_history(force, dt, force_dofs, N)
    n_steps = f.shape[0] - 1
    outputs = validate.dof_indices("outputs", outputs, N)
    quantities = stepping.check_quantities(quantities)
    q0, qd0 = validate.initial_conditions(x0, v0, N)
    # the state record and the inputs' share (n_steps x at most 2N each), then the outputs
    validate.output_size("exact_response", n_steps + 1, 4 * N + outputs.size * len(quantities))

    try:
        A, B, Vz, Vf, m = _reduced_form(M, C, K, loaded)
    except ValueError as exc:  # every refusal of _reduced_form is about M or C_zz
        raise SingularMassError(str(exc)) from None
    ns = A.shape[0]
    Phi, G0, G1 = foh_matrices(A, B, dt)

    # Input contribution of every step at once, then the state recursion.
    g = f[:-1] @ G0.T + f[1:] @ G1.T            # (n_steps, ns)
    Z = np.empty((n_steps + 1, ns))
    Z[0, :N] = q0
    Z[0, N:] = qd0[m]
    if m.size < N:  # massless DOFs: their initial velocity follows from their equilibrium
        v_start = Vz @ Z[0] + Vf @ f[0]
        size = np.abs(Vz) @ np.abs(Z[0]) + np.abs(Vf) @ np.abs(f[0]) + np.abs(qd0)  # terms
        off = np.abs(qd0 - v_start) > 1e-10 * size
        if v0 is not None and off.any():
            i = int(np.argmax(off))
            raise ValueError(f"v0[{i}] = {qd0[i]:g} is not consistent with the equilibrium of the "
                             f"massless DOFs (it must be {v_start[i]:g})")
    PhiT = np.ascontiguousarray(Phi.T)
    z = Z[0]
    with np.errstate(over="ignore", invalid="ignore"):  # a growing response is named below
        for n in range(n_steps):
            z = z @ PhiT + g[n]
            Z[n + 1] = z

        # q' = Vz z + Vf f and q'' = Vz (A z + B f) + Vf f', for the stored DOFs only; f' is
        # the slope of the force segment ending at t_n (the first segment at t_0).
        Vz_o, Vf_o = Vz[outputs], Vf[outputs]
        vel = Z @ Vz_o.T + f @ Vf_o.T if "v" in quantities else None
        acc = None
        if "a" in quantities:
            slope = np.diff(f, axis=0, prepend=2 * f[:1] - f[1:2]) / dt
            acc = Z @ (Vz_o @ A).T + f @ (Vz_o @ B).T + slope @ Vf_o.T
    disp = np.ascontiguousarray(Z[:, outputs]) if "x" in quantities else None

    validate.finite_response("exact_response", dt, Z, vel, acc)
    t = dt * np.arange(n_steps + 1)
    return support.finish(Response(t=t, outputs=outputs, x=disp, v=vel, a=acc,
                    info={"method": METHOD, "dt": dt, "n_steps": n_steps,
                          "run_time": time.perf_counter() - start}), ground)
