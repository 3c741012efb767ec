"""Discrete-time state-space models of M q'' + C q' + K q = f, and a fast time loop for them.

- `newmark_ss`: SHARPy's model, built from the M-multiplied blocks
  derived in dtdyn.derive.state_space, so M is never inverted; with massless DOFs (singular M)
  it returns the same recursion with the state [q; q'; q''].
- `discrete_state_space`: the same kind of model for any scheme of the integrator library, from
  its generated coefficients; state = the scheme's history (x, v, a and lags), output
  [q; q'] or [q; q'; q''].
- `state_space_response`: the response of such a model to a force record, from rest (or given
  x0, v0) at t_0, run as x_{n+1} = A x_n + B f_n, y_n = C x_n + D f_n in a generated C loop.

Every model here removes the direct dependence on f_{n+1} as SHARPy does: with
z_{n+1} = Phi z_n + Gamma0 f_n + Gamma1 f_{n+1}, the state x_n = z_n - Gamma1 f_n gives
A = Phi, B = Gamma0 + Phi Gamma1, and the outputs y_n = S z_n = S x_n + S Gamma1 f_n. Each is a
`DiscreteModel`, which knows that shift: a zero state is not rest when f_0 != 0.
"""
from __future__ import annotations

import time
from functools import cache
from importlib import resources

import numpy as np
import scipy.linalg as sla

from dtdyn.generated import newmark_ss as _blocks

from dtdyn._engine import cbuild
from dtdyn._engine import linalg
from dtdyn._engine import ground as support
from dtdyn._engine import validate
from dtdyn._engine.errors import DtdynStabilityWarning, DtdynUnstableError
from dtdyn._engine.public import warn
from dtdyn._engine.result import Response
from dtdyn._engine.schemes import get_scheme
from dtdyn._engine.stepping import check_quantities
from dtdyn.linear._discrete_model import DiscreteModel, shifted


def newmark_ss(M, C, K, dt, num_damp=1e-4, M_is_SPD=False) -> DiscreteModel:
    """SHARPy's Newmark discrete-time state space, iterable as ``(Ass, Bss, Css, Dss)``.

    gamma = 1/2 + num_damp, beta = (1 + num_damp)^2 / 4. With y = [q; q'] and the derived
    M-multiplied blocks ``E1 y_{n+1} = E0 y_n + G0 f_n + G1 f_{n+1}``,

        Ass = E1^-1 E0,  Dss = E1^-1 G1,  Bss = E1^-1 (G0 + E0 Dss),  Css = I,

    equal to SHARPy's Ass1^-1 Ass0 etc. without forming M^-1.
    ``M_is_SPD`` is kept for SHARPy's signature; when True, M is checked to be symmetric positive
    definite (Cholesky) and a ValueError names it otherwise.

    Singular M (massless DOFs): det E1 = det M det(M + gamma dt C + beta dt^2 K), so no model
    with state [q; q'] and Css = I exists (SHARPy's formula fails there too: it needs M^-1). The
    Newmark recursion itself is well defined wherever M + gamma dt C + beta dt^2 K is invertible,
    so newmark_ss then returns that recursion with the same input f_n and output [q_n; q'_n],
    realized with the state [q; q'; q''] of `discrete_state_space` (3n states, Css selects q and
    q'). It agrees with `mck_response` and converges to `exact_response` at second order for
    num_damp = 0, first order otherwise (gamma > 1/2; tests/test_state_space.py).

    Output y_n = Css x_n + Dss f_n = [q_n; q'_n]; input f on every DOF; state
    x_n = [q_n; q'_n] - Dss f_n, so the state at rest under f_0 is -Dss f_0
    (`DiscreteModel.initial_state`; `state_space_response` starts there).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> Ass, Bss, Css, Dss = dd.newmark_ss(np.eye(2), np.zeros((2, 2)), 4 * np.eye(2), 0.1)
    >>> Ass.shape, Dss.shape
    ((4, 4), (4, 2))

    Parameters
    ----------
    M, C, K : (n, n) array_like
        Mass, damping, stiffness.
    dt : float
        Sample step, s.
    num_damp : float
        SHARPy's numerical damping alpha >= 0: gamma = 1/2 + alpha, beta = (1 + alpha)^2 / 4.
    M_is_SPD : bool
        SHARPy's flag; when True, M is checked to be symmetric positive definite.

    Returns
    -------
    DiscreteModel
        Iterable as ``(Ass, Bss, Css, Dss)``.
    """
    M, C, K = linalg.mck(M, C, K)
    dt = validate.positive_scalar("dt", dt)
    try:
        num_damp = float(num_damp)
    except (TypeError, ValueError):
        raise ValueError(f"num_damp must be a number, got {num_damp!r}") from None
    if not (np.isfinite(num_damp) and num_damp >= 0.0):
        raise ValueError(f"num_damp must be finite and >= 0, got {num_damp!r}")
    if M_is_SPD:
        if not np.allclose(M, M.T, rtol=1e-12, atol=0.0):
            raise ValueError("M_is_SPD=True but M is not symmetric")
        try:
            sla.cholesky(M)
        except sla.LinAlgError:
            raise ValueError("M_is_SPD=True but M is not positive definite") from None
    n = M.shape[0]
    beta, gamma = _blocks.sharpy_params(num_damp)
    if np.linalg.matrix_rank(M) < n:
        return discrete_state_space(M, C, K, dt, scheme="newmark", beta=beta, gamma=gamma)
    E1, E0, G0, G1 = (np.block(b) for b in _blocks.blocks(M, C, K, np.eye(n), np.zeros((n, n)),
                                                           dt, beta, gamma))
    solve = linalg.solver(E1, "the Newmark matrix [[M + beta dt^2 K, beta dt^2 C], "
                              "[gamma dt K, M + gamma dt C]]", "no discrete model at this dt")
    Ass = solve(E0)
    Dss = solve(G1)
    Bss = solve(G0 + E0 @ Dss)

    def initial(q0, v0, f0):
        return np.concatenate((q0, v0)) - Dss @ f0

    return DiscreteModel(Ass, Bss, np.eye(2 * n), Dss, dt, state="[q; q'] - Dss f_n",
                         quantities=("x", "v"), n_dof=n,
                         source=f"newmark_ss(num_damp={num_damp!r})", _physical_state=initial,
                         mass=M)


def discrete_state_space(M, C, K, dt, scheme="newmark", acceleration=False,
                         **scheme_params) -> DiscreteModel:
    """State-space model of one step of any scheme of the integrator library.

    State: the scheme's history per DOF (x, v, a and, for multistep schemes, the lags), shifted
    by the f_{n+1} feedthrough; input f on every DOF; output [q; q'] (and q'' when
    ``acceleration``). Each step solves, as `mck_response` does (acceleration form),

        (M + Dv C + Dx K) a_e = w0 f_n + w1 f_{n+1} - K Ex(h_n) - C Ev(h_n),
        h_{n+1} = c_u a_e + L h_n,

    with the generated coefficients; no inverse of M is formed. For Houbolt and Park this is the
    main recursion: the start-up steps of `mck_response` are not part of the LTI model (their
    lags start equal to the initial state).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.discrete_state_space(np.eye(1), np.zeros((1, 1)), np.eye(1), 0.1,
    ...                                 scheme="hht", alpha=-0.1, acceleration=True)
    >>> model.quantities
    ('x', 'v', 'a')

    Parameters
    ----------
    M, C, K : (n, n) array_like
        Mass, damping, stiffness.
    dt : float
        Sample step, s.
    scheme : str
        Any scheme of the scheme table (`dtdyn show --help` lists them); parameters as keywords.
    acceleration : bool
        Output [q; q'; q''] instead of [q; q'].
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    DiscreteModel
    """
    from dtdyn.linear._mck import _initial_acceleration
    M, C, K = linalg.mck(M, C, K)
    n = M.shape[0]
    info = get_scheme(scheme, **scheme_params)
    names = info.history

    def physical(q0, v0, f0):
        state = {"x": q0, "v": v0, "a": _initial_acceleration(M, f0 - C @ v0 - K @ q0)}
        return np.concatenate([state[h[0]] for h in names])

    params = "".join(f", {k}={v!r}" for k, v in info.params.items())
    return shifted(*scheme_blocks(M, C, K, dt, scheme, acceleration, **scheme_params), dt,
                   state=f"history [{', '.join(names)}] per DOF - Gamma1 f_n",
                   quantities=("x", "v", "a") if acceleration else ("x", "v"), n_dof=n,
                   source=f"discrete_state_space(scheme={info.name!r}{params})",
                   physical=physical, mass=M)


def scheme_blocks(M, C, K, dt, scheme="newmark", acceleration=False, **scheme_params):
    """(Phi, Gamma0, Gamma1, S) of z_{n+1} = Phi z_n + Gamma0 f_n + Gamma1 f_{n+1}, y_n = S z_n
    (module docstring): `discrete_state_space` before the feedthrough shift."""
    M, C, K = linalg.mck(M, C, K)
    dt = validate.positive_scalar("dt", dt)
    info = get_scheme(scheme, **scheme_params)
    coef = info.coefficients("acceleration", dt)
    names = info.history
    n, nh = M.shape[0], len(names)
    eye = np.eye(n)
    solve = linalg.solver(M + coef["r"] * C + coef["p"] * K, "the effective matrix M + Dv C + Dx K",
                          "no discrete model at this dt")

    def row(prefix):
        return np.hstack([coef.get(f"{prefix}_{h}", 0.0) * eye for h in names])

    KE = K @ row("q") + C @ row("s")  # K Ex + C Ev as a map of h
    U_h = np.zeros((nh * n, nh * n))
    U_u = np.zeros((nh * n, n))
    for i, h in enumerate(names):
        block = slice(i * n, (i + 1) * n)
        lag = 0 if h[1:] == "0" else int(h[2:])
        if lag == 0:  # x0, v0, a0 <- x1, v1, a1
            U_h[block] = row(h[0] + "1")
            U_u[block] = coef.get(f"{h[0]}1_u", 0.0) * eye
        else:  # xm1 <- x0, xm2 <- xm1, ...
            prev = names.index(h[0] + ("0" if lag == 1 else f"m{lag - 1}"))
            U_h[block, prev * n:(prev + 1) * n] = eye
    Keff_inv_KE = solve(KE)
    Keff_inv = solve(eye)
    Phi = U_h - U_u @ Keff_inv_KE
    G0 = coef["w0"] * (U_u @ Keff_inv)
    G1 = coef["w1"] * (U_u @ Keff_inv)
    outputs = ["x0", "v0"] + (["a0"] if acceleration else [])
    S = np.zeros((len(outputs) * n, nh * n))
    for k, h in enumerate(outputs):
        i = names.index(h)
        S[k * n:(k + 1) * n, i * n:(i + 1) * n] = eye
    return Phi, G0, G1, S


#: steps per block of `state_space_response`
SS_BLOCK = 4096


@cache
def _c_loop():
    source = resources.files("dtdyn.generated").joinpath("ss_response.c").read_text()
    lib = cbuild.load_library(source, "ss_response")
    if lib is None:
        return None
    return cbuild.bind(lib, "dtdyn_ss_states")


def state_space_response(model: DiscreteModel, force, *, force_dofs=None, outputs=None,
                         quantities=None, x0=None, v0=None, unstable="raise",
                         backend="c", ground_acceleration=None, ground_velocity=None,
                         ground_displacement=None, influence=None) -> Response:
    """Response of a discrete model (`newmark_ss`, `discrete_state_space`, `discretize`) to a
    force record, starting from rest at t_0 (or from ``x0``, ``v0``) whatever the model's state
    convention.

    Parameters
    ----------
    model : DiscreteModel
        The model; its ``dt`` is the sample step of ``force``.
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Samples at t_k = k dt (a 1-D array is one column).
    force_dofs : sequence of int, optional
        0-based DOFs the force columns act on (all DOFs when None).
    outputs : sequence of int, optional
        DOFs whose response is stored (all by default).
    quantities : subset of ("x", "v", "a"), optional
        What is stored (default: every quantity the model outputs); "a" needs a model with
        accelerations among its outputs.
    x0, v0 : (N,) array_like, optional
        Initial displacement and velocity (rest when None), mapped to the model's state by
        `DiscreteModel.initial_state` (the state of these models is shifted by the feedthrough
        of f_0, so a zero state is not rest under a nonzero first force sample).
    unstable : {"raise", "warn"}
        When the spectral radius of A exceeds 1 (the recursion grows): DtdynUnstableError
        before the run, or a DtdynStabilityWarning and the run.
    backend : {"c", "numpy"}
        The generated C recursion or a NumPy loop.
    ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
        Support acceleration at the force's times: the DOFs are then relative to the support,
        loaded by f - M r a_g with the model's ``mass`` (models built from M, C, K carry it),
        and the result adds ``a_abs`` (``force`` may be None).
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
        ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)).

    Notes
    -----
    The record runs in blocks of `SS_BLOCK` steps: per block the input and output maps are
    matrix-matrix products and only the recursion x_{n+1} = A x_n + w_n is sequential, in a
    generated C kernel (a NumPy loop when no compiler exists). Memory: the outputs asked for,
    plus one block of states and inputs. For raw matrices use `DiscreteModel.simulate`.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.diag([2.0, 1.0]), np.zeros((2, 2)), np.array([[30.0, -10], [-10, 10]])
    >>> r = dd.state_space_response(dd.discretize(M, C, K, 0.01, hold="foh"), np.ones(201),
    ...                             force_dofs=[1], quantities=("x",))
    >>> r.v is None
    True
    """
    if not isinstance(model, DiscreteModel):
        raise TypeError("model must be a DiscreteModel (from newmark_ss, discrete_state_space or "
                        f"discretize), got {type(model).__name__}; for raw (A, B, C, D) matrices "
                        "use DiscreteModel(A, B, C, D, dt).simulate(force)")
    if not model.quantities:
        raise ValueError("this model's outputs have no stated meaning: use model.simulate(force)")
    n = model.n_dof
    quantity = support.given(ground_acceleration, ground_velocity, ground_displacement)
    if quantity is not None and model.mass is None:
        raise ValueError(f"{support.RECORDS[quantity]} needs the structure's mass matrix: "
                         "build the model with newmark_ss, discrete_state_space or discretize "
                         "(they keep M)")
    force, force_dofs, ground = support.prepare(model.mass, force, force_dofs, n,
                                                ground_acceleration, influence, dt=model.dt,
                                                ground_velocity=ground_velocity,
                                                ground_displacement=ground_displacement)
    f, dt, dofs = validate.time_history(force, model.dt, force_dofs, n, min_samples=1)
    outputs = validate.dof_indices("outputs", outputs, n)
    quantities = check_quantities(model.quantities if quantities is None else quantities)
    missing = [q for q in quantities if q not in model.quantities]
    if missing:
        raise ValueError(f"quantities = {quantities}: this model outputs {model.quantities} only "
                         "(discrete_state_space(..., acceleration=True) adds 'a')")
    _check_radius(model, unstable)
    f0 = np.zeros(n)
    f0[dofs] = f[0]
    state0 = model.initial_state(x0, v0, f0)
    rows = np.concatenate([model.quantities.index(q) * n + outputs for q in quantities])
    every = rows.size == model.C.shape[0] and np.array_equal(rows, np.arange(rows.size))
    all_in = dofs.size == n and np.array_equal(dofs, np.arange(n))
    C = model.C if every else model.C[rows]  # no copies when everything is asked for
    D = model.D if every else model.D[rows]
    start = time.perf_counter()
    y = run_recursion(model.A, model.B if all_in else model.B[:, dofs], C,
                      D if all_in else D[:, dofs], f, state0, backend)
    run_time = time.perf_counter() - start
    k = outputs.size
    store = {q: np.ascontiguousarray(y[:, i * k:(i + 1) * k]) for i, q in enumerate(quantities)}
    response = Response(dt * np.arange(f.shape[0]), outputs, store.get("x"), store.get("v"),
                        store.get("a"), info={"method": model.source, "dt": dt,
                                              "n_steps": f.shape[0] - 1, "run_time": run_time,
                                              "backend": "c" if backend == "c" and _c_loop()
                                              else "numpy"})
    return support.finish(response, ground)


def _check_radius(model: DiscreteModel, unstable: str) -> None:
    """DtdynUnstableError (or a warning) when max |eig A| > 1 + 1e-6. The margin is the
    eigensolver's error on the unit circle: the lossless models (average acceleration) have
    |eig| = 1 exactly, computed to ~eps, but ~sqrt(eps) = 1.5e-8 for a defective pair (massless
    DOFs); a real growth below 1e-6 per step is not refused."""
    if unstable not in ("raise", "warn"):
        raise ValueError(f"unstable must be 'raise' or 'warn', got {unstable!r}")
    rho = float(np.max(np.abs(np.linalg.eigvals(model.A)))) if model.A.size else 0.0
    if rho > 1.0 + 1e-6:
        msg = (f"the discrete model ({model.source or 'user matrices'}, dt = {model.dt:g} s) is "
               f"unstable: the spectral radius of A is {rho:.10g} > 1, so its response grows "
               "without bound (unstable='warn' runs it anyway)")
        if unstable == "raise":
            raise DtdynUnstableError(msg)
        warn(msg, DtdynStabilityWarning)


def run_recursion(Ad, Bd, Cd, Dd, force, state0=None, backend="c") -> np.ndarray:
    """y_n of x_{n+1} = Ad x_n + Bd f_n, y_n = Cd x_n + Dd f_n for n = 0 .. len(force) - 1,
    from the state ``state0`` (zero when None): shape (len(force), rows of Cd)."""
    A = np.asarray(Ad, dtype=float)
    B, Cm, D = (np.atleast_2d(np.asarray(X, dtype=float)) for X in (Bd, Cd, Dd))
    ns = A.shape[0]
    if A.ndim != 2 or A.shape != (ns, ns):
        raise ValueError(f"Ad must be square, got shape {A.shape}")
    f = np.asarray(force, dtype=float)
    if f.ndim == 1:
        f = f[:, None]
    ni, no = B.shape[1], Cm.shape[0]
    for name, X, shape in (("Ad", A, (ns, ns)), ("Bd", B, (ns, ni)), ("Cd", Cm, (no, ns)),
                           ("Dd", D, (no, ni)), ("force", f, (f.shape[0], ni))):
        if X.shape != shape:
            raise ValueError(f"{name} has shape {X.shape}, expected {shape}")
        if not np.all(np.isfinite(X)):
            raise ValueError(f"{name} has a non-finite entry")
    x = np.zeros(ns) if state0 is None else validate.vector("state0", state0, length=ns)
    n_steps = f.shape[0]
    fn = _c_loop() if backend == "c" else None
    At = np.ascontiguousarray(A.T)
    identity = Cm.shape == (ns, ns) and np.array_equal(Cm, np.eye(ns))
    validate.output_size("state_space_response", n_steps, no)
    y = np.empty((n_steps, no))
    X = np.empty((min(n_steps, SS_BLOCK) + 1, ns))  # row 0: the state entering the block
    X[0] = x
    for start in range(0, n_steps, SS_BLOCK):
        fb = f[start:start + SS_BLOCK]
        nb = fb.shape[0]
        w = np.ascontiguousarray(fb @ B.T)
        if fn is None:
            for k in range(nb):
                X[k + 1] = A @ X[k] + w[k]
        else:
            fn(ns, nb, At.ctypes.data, w.ctypes.data, X.ctypes.data)
        yb = y[start:start + nb]
        if identity:
            yb[:] = X[:nb]
        else:
            np.matmul(X[:nb], Cm.T, out=yb)
        if D.any():
            yb += fb @ D.T
        X[0] = X[nb]
    return y
