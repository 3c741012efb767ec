r"""Discrete-time state-space equivalents of ``M q'' + C q' + K q = f(t)``.

:func:`first_order_form` builds the continuous first-order form :math:`\dot z = A z + B f`,
:math:`z = [q;\ \dot q]`; :func:`discretize` turns it into :math:`(A_d, B_d, C_d, D_d)` with
the same conventions as :func:`scipy.signal.cont2discrete` for the output :math:`y = z`
(zero-order hold, first-order hold, impulse invariance, Tustin), computed here directly from
matrix exponentials of augmented matrices and linear solves. :func:`to_dlti` and
:func:`to_control` wrap the result as a :class:`scipy.signal.dlti` or a python-control
``StateSpace``.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse

from dtdyn._engine import linalg
from dtdyn._engine import validate
from dtdyn.linear._discrete_model import DiscreteModel, shifted

__all__ = ["HOLDS", "first_order_form", "discretize"]

#: Accepted values of ``hold`` in :func:`discretize` ("bilinear" is an alias of "tustin").
HOLDS = ("zoh", "foh", "impulse", "tustin", "bilinear")


def first_order_form(M, C, K):
    r"""Continuous first-order form of ``M q'' + C q' + K q = f``.

    Parameters
    ----------
    M, C, K : (N, N) array_like or scipy.sparse matrix
        Mass, damping and stiffness matrices (densified). ``M`` must be invertible (it may be
        non-symmetric or indefinite: this is the algebra of any second-order system; the
        time-history entry points require a mass matrix, symmetric positive semi-definite);
        every entry must be finite.

    Returns
    -------
    A : (2N, 2N) ndarray
    B : (2N, N) ndarray
        With :math:`z = [q;\ \dot q]` and the force :math:`f` acting on every DOF,
        :math:`\dot z = A z + B f`, where

        .. math::

            A = \begin{bmatrix} 0 & I \\ -M^{-1}K & -M^{-1}C \end{bmatrix}, \qquad
            B = \begin{bmatrix} 0 \\ M^{-1} \end{bmatrix}.

        :math:`M^{-1}` is applied through a Cholesky factorisation when ``M`` is symmetric
        positive definite and an LU factorisation otherwise; it is never formed explicitly
        except as the solve :math:`M^{-1} I` that *is* the block of ``B``.

    Raises
    ------
    ValueError
        If a matrix is not square, not finite or not the size of ``M`` (the message names the
        argument), or if ``M`` is singular or numerically singular.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> A, B = dd.first_order_form(np.eye(1), 0.2 * np.eye(1), 4.0 * np.eye(1))
    >>> A
    array([[ 0. ,  1. ],
           [-4. , -0.2]])
    """
    M, C, K = linalg.mck(M, C, K, physical=False)  # any nonsingular M
    N = M.shape[0]
    solve = linalg.solver(M, "M", "a first-order form needs an invertible mass matrix")
    rhs = solve(np.hstack((K, C, np.eye(N))))      # [M^-1 K, M^-1 C, M^-1] in one solve
    A = np.zeros((2 * N, 2 * N))
    A[:N, N:] = np.eye(N)
    A[N:, :] = -rhs[:, :2 * N]
    B = np.zeros((2 * N, N))
    B[N:, :] = rhs[:, 2 * N:]
    return A, B


def _hold_name(hold) -> str:
    if not isinstance(hold, str) or hold.lower() not in HOLDS:
        raise ValueError("hold must be one of 'zoh', 'foh', 'impulse', 'tustin' "
                         f"(alias 'bilinear'), got {hold!r}")
    hold = hold.lower()
    return "tustin" if hold == "bilinear" else hold


def discretize(M, C, K, dt, hold="zoh") -> DiscreteModel:
    r"""Discrete-time state space of ``M q'' + C q' + K q = f`` sampled every ``dt``.

    The continuous system is :func:`first_order_form`, :math:`\dot z = A z + B f`,
    :math:`z = [q;\ \dot q]`, with output :math:`y = z` (continuous :math:`C_c = I`,
    :math:`D_c = 0`). The result is the discrete system

    .. math::

        x_{n+1} = A_d x_n + B_d f_n, \qquad y_n = C_d x_n + D_d f_n,

    matrix for matrix what ``scipy.signal.cont2discrete((A, B, I, 0), dt, method=hold)``
    returns, but computed here (the state :math:`x_n` equals :math:`z_n` only for
    ``"zoh"`` and ``"impulse"``; see below).

    Parameters
    ----------
    M, C, K : (N, N) array_like or scipy.sparse matrix
        Mass (invertible), damping and stiffness matrices.
    dt : float
        Sample interval, finite and > 0.
    hold : {"zoh", "foh", "impulse", "tustin"}, optional
        Discretisation rule (case-insensitive); ``"bilinear"`` is accepted as an alias of
        ``"tustin"``. Default ``"zoh"``.

    Returns
    -------
    DiscreteModel
        Iterable as ``(Ad, Bd, Cd, Dd)``: (2N, 2N), (2N, N), (2N, 2N), (2N, N); outputs
        [q; q']; it knows its state (below), so `state_space_response` starts at rest.

    Raises
    ------
    ValueError
        For a bad ``M``, ``C``, ``K`` (see :func:`first_order_form`), ``dt <= 0`` or not finite,
        or an unknown ``hold``; the message names the argument.

    Notes
    -----
    Write :math:`\Phi = e^{A\Delta t}`. All exponentials below are single ``expm`` calls on
    augmented block matrices (Van Loan 1978).

    **Zero-order hold** (``"zoh"``; :math:`f` constant on :math:`[t_n, t_{n+1})`; exact for
    such inputs; Franklin, Powell & Workman 1998):

    .. math::

        \exp\left(\Delta t \begin{bmatrix} A & B \\ 0 & 0 \end{bmatrix}\right)
        = \begin{bmatrix} \Phi & \Gamma \\ 0 & I \end{bmatrix}, \quad
        A_d = \Phi,\ B_d = \Gamma = \int_0^{\Delta t} e^{As}\,ds\,B,\ C_d = I,\ D_d = 0.

    **First-order hold** (``"foh"``; triangle hold, :math:`f` linear between samples; exact
    for such inputs; Franklin, Powell & Workman 1998, pp. 204-206, as cited by scipy):

    .. math::

        \exp\begin{bmatrix} A\Delta t & B\Delta t & 0 \\ 0 & 0 & I \\ 0 & 0 & 0 \end{bmatrix}
        = \begin{bmatrix} \Phi & \Gamma_1 & \Gamma_2 \\ 0 & I & I \\ 0 & 0 & I \end{bmatrix},

    with :math:`\Gamma_1 = \int_0^{\Delta t} e^{A(\Delta t-s)}ds\,B` and
    :math:`\Gamma_2 = \int_0^{\Delta t} e^{A(\Delta t-s)}\,\tfrac{s}{\Delta t}\,ds\,B`. The exact
    recursion :math:`z_{n+1} = \Phi z_n + (\Gamma_1 - \Gamma_2) f_n + \Gamma_2 f_{n+1}` depends
    on :math:`f_{n+1}`; scipy's convention removes it with the state
    :math:`x_n = z_n - \Gamma_2 f_n`, giving

    .. math::

        A_d = \Phi, \quad B_d = \Gamma_1 - \Gamma_2 + \Phi\Gamma_2, \quad
        C_d = I, \quad D_d = \Gamma_2 ,

    so :math:`y_n = x_n + \Gamma_2 f_n = z_n`; a simulation from :math:`z_0` starts at
    :math:`x_0 = z_0 - \Gamma_2 f_0` (the same device as the Newmark state space,
    :math:`x_n = y_n - A_{ss1}^{-1}B_{ss1} f_n`); `DiscreteModel.initial_state` does it.
    (:math:`\Gamma_1, \Gamma_2` are :math:`\Gamma_a, \Gamma_b` of
    :func:`dtdyn.linear._exact.foh_matrices`.)

    **Impulse invariance** (``"impulse"``; the discrete impulse response is :math:`\Delta t`
    times the sampled continuous impulse response :math:`C e^{At}B`, including the
    :math:`t = 0` sample; scipy's convention):

    .. math::

        A_d = \Phi, \quad B_d = \Phi B\,\Delta t, \quad C_d = I, \quad D_d = B\,\Delta t .

    **Tustin / bilinear** (``"tustin"``; :math:`s \leftarrow \tfrac{2}{\Delta t}\tfrac{z-1}{z+1}`,
    the generalised bilinear transform with :math:`\alpha = 1/2`; Zhang, Chen & Chen 2009;
    Franklin, Powell & Workman 1998). With :math:`E = I - \tfrac{\Delta t}{2} A`:

    .. math::

        A_d = E^{-1}\left(I + \tfrac{\Delta t}{2} A\right), \quad
        B_d = E^{-1} B\,\Delta t, \quad
        C_d = E^{-1}, \quad
        D_d = \tfrac12 B_d = \tfrac{\Delta t}{2} E^{-1} B

    (scipy's :math:`C_d = C E^{-1}`, :math:`D_d = D + \alpha C B_d` with :math:`C = I`,
    :math:`D = 0`), whose transfer function is
    :math:`H_c\!\left(\tfrac{2}{\Delta t}\tfrac{z-1}{z+1}\right)` exactly.

    References
    ----------
    G. F. Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
    Addison-Wesley, 1998 (zero-order-hold, Tustin and triangle-hold equivalents).
    C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE Trans.
    Automatic Control 23(3), 395-404, 1978.
    G. Zhang, X. Chen, T. Chen, "Digital redesign via the generalized bilinear transformation",
    Int. J. Control 82(4), 741-754, 2009.
    SciPy, ``scipy.signal.cont2discrete`` documentation and source (conventions for ``C_d``,
    ``D_d`` and the foh state).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.discretize(np.eye(1), np.zeros((1, 1)), np.eye(1), 0.1, hold="zoh")
    >>> Ad, Bd, Cd, Dd = model
    >>> Ad.shape, model.state
    ((2, 2), "[q; q']")
    """
    dt = validate.positive_scalar("dt", dt)
    hold = _hold_name(hold)
    A, B = first_order_form(M, C, K)
    ns, ni = B.shape
    eye = np.eye(ns)
    common = dict(quantities=("x", "v"), n_dof=ni, source=f"discretize(hold={hold!r})",
                  mass=linalg.square_matrix("M", M))

    def z0(q0, v0, f0):
        return np.concatenate((q0, v0))

    if hold == "zoh":
        F = np.zeros((ns + ni, ns + ni))
        F[:ns, :ns] = A
        F[:ns, ns:] = B
        E = scipy.linalg.expm(dt * F)
        return DiscreteModel(E[:ns, :ns], E[:ns, ns:], eye, np.zeros((ns, ni)), dt,
                             state="[q; q']", _physical_state=z0, **common)

    if hold == "foh":
        F = np.zeros((ns + 2 * ni, ns + 2 * ni))
        F[:ns, :ns] = A * dt
        F[:ns, ns:ns + ni] = B * dt
        F[ns:ns + ni, ns + ni:] = np.eye(ni)
        E = scipy.linalg.expm(F)
        Phi, gam1, gam2 = E[:ns, :ns], E[:ns, ns:ns + ni], E[:ns, ns + ni:]
        return shifted(Phi, gam1 - gam2, gam2.copy(), eye, dt, state="[q; q'] - Gamma2 f_n",
                       physical=z0, **common)

    if hold == "impulse":  # scipy's convention: the zero state is rest (y_0 = dt B f_0)
        Phi = scipy.linalg.expm(A * dt)
        return DiscreteModel(Phi, Phi @ B * dt, eye, B * dt, dt, state="impulse-invariant state",
                             _physical_state=z0, **common)

    # tustin: generalised bilinear transform with alpha = 1/2; state E z_n - dt/2 B f_n
    half = 0.5 * dt
    lu_piv = scipy.linalg.lu_factor(eye - half * A, check_finite=False)
    Ad = scipy.linalg.lu_solve(lu_piv, eye + half * A, check_finite=False)
    Bd = scipy.linalg.lu_solve(lu_piv, dt * B, check_finite=False)
    Cd = scipy.linalg.lu_solve(lu_piv, eye, trans=1, check_finite=False).T

    def tustin_state(q0, v0, f0):
        return (eye - half * A) @ z0(q0, v0, f0) - half * (B @ f0)

    return DiscreteModel(Ad, Bd, Cd, 0.5 * Bd, dt, state="(I - dt/2 A) [q; q'] - dt/2 B f_n",
                         _physical_state=tustin_state, **common)
