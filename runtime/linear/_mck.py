"""The same integrators on assembled M, C, K (dense or scipy.sparse), factorizing once.

Acceleration form of every scheme (it exists for explicit ones too): with
x_e = Dx a_e + Ex, v_e = Dv a_e + Ev from the generated coefficients,

    (M + Dv C + Dx K) a_e = w0 F_n + w1 F_{n+1} - C Ev - K Ex,

then x, v, a at t_{n+1} from the scheme's update. This is the reference the DT-TMM sweeps must
equal, and the general-matrix path. `make_advance` also steps the displacement form
(u = x_e - x_n; beam_response), and factors a 2 x 2 node-block matrix by the matrix Riccati
sweep (`block_factors`).
"""
from __future__ import annotations

import ctypes
from functools import cache
from importlib import resources

import numpy as np
import scipy.sparse as sps

from dtdyn.generated import c_api
from dtdyn.generated.dttmm_sweep import combine, error_history_maps, shift_history

from dtdyn._engine import cbuild
from dtdyn._engine import linalg
from dtdyn._engine.kernels import DtdynKernelError
from dtdyn._engine.public import public
from dtdyn._engine.result import Response
from dtdyn.linear._solver import (Model, Solver, check_backend, nonlinear_solver,
                                  schemes_of_run, scheme_key)
from dtdyn.linear._stability import highest_frequency


def _initial_acceleration(M, f0):
    """a_0 from M a_0 = f_0 (f_0: the force minus C v_0 + K x_0 at t_0). A singular M (massless
    DOFs) is allowed when f_0 is consistent with it: then a_0 is the minimum-norm solution (its
    massless components are not physical; each step enforces their equilibrium)."""
    return mass_solver(M)(f0)


def mass_solver(M):
    """``solve(f0) = a_0`` of `_initial_acceleration`, M factorized once (a solver reuses it for
    every load case; reading the factors only, it may be called from several threads)."""
    try:
        return linalg.solver(M, "M")
    except ValueError:
        pass
    dense = M.toarray() if sps.issparse(M) else M

    def least_squares(f0):
        a0, *_ = np.linalg.lstsq(dense, f0, rcond=None)
        resid = dense @ a0 - f0
        if np.linalg.norm(resid) > 1e-12 * max(np.linalg.norm(f0), np.finfo(float).tiny):
            i = int(np.argmax(np.abs(resid)))
            raise ValueError(f"M is singular and the force at t_0 loads its null space (DOF {i}): "
                             "the initial state is not in equilibrium there") from None
        return a0
    return least_squares


@cache
def _c_loop():
    """The library of generated/mck_loop.c, or None without a compiler (one warning)."""
    source = resources.files("dtdyn.generated").joinpath("mck_loop.c").read_text()
    lib = cbuild.load_library(source, "mck_loop")
    if lib is not None:
        cbuild.bind(lib, "dtdyn_mck_loop")
    return lib


#: the effective matrix of each form, as errors name it
EFFECTIVE = {"acceleration": "the effective matrix M + Dv C + Dx K",
             "displacement": "the effective matrix A M + D C + K"}


def _c_operands(A, C, K, M=None, blocks=None, what=EFFECTIVE["acceleration"]):
    """(solver, idx, val, arrays, work): the solver code and the pointer arrays idx and val of
    dtdyn_mck_loop (mck_loop.c) for the effective matrix A and C, K (and M when the form needs
    M b), dense (row-major, A by its LU and pivots), sparse (CSR, A by its SuperLU factors of the
    least-fill ordering) or, with ``blocks`` = (P^-1, G, F) from `block_factors`, the 2 x 2
    node-block sweep; the arrays they point to (the caller keeps them alive); the multiply-adds
    of one step."""
    i64 = lambda a: np.ascontiguousarray(a, dtype=np.int64)  # noqa: E731
    f64 = lambda a: np.ascontiguousarray(a, dtype=float)  # noqa: E731
    if sps.issparse(A):
        mats = [sps.csr_matrix(B) for B in (K, C) + ((M,) if M is not None else ())]
        idx = [i64(a) for B in mats for a in (B.indptr, B.indices)] + [None] * (6 - 2 * len(mats))
        val = [f64(B.data) for B in mats] + [None] * (3 - len(mats))
        work = sum(B.nnz for B in mats) + 4 * A.shape[0]
        if blocks is not None:
            solver = 2
            idx += [None] * 6
            val += [f64(b) for b in blocks]
        else:
            solver = 1
            lu = linalg.sparse_lu(A, what, orderings=linalg.FILL_ORDERINGS)
            Lf, Uf = sps.tril(lu.L, -1, format="csr"), sps.triu(lu.U, 1, format="csr")
            idx += [i64(a) for B in (Lf, Uf) for a in (B.indptr, B.indices)]
            idx += [i64(lu.perm_r), i64(lu.perm_c)]
            val += [f64(B.data) for B in (Lf, Uf)] + [f64(1.0 / lu.U.diagonal())]
            work += Lf.nnz + Uf.nnz
    else:
        solver = 0
        LU, piv = linalg.dense_lu(A, what)
        idx = [None] * 10 + [i64(piv), None]
        val = [f64(K), f64(C), None if M is None else f64(M), f64(LU), None, None]
        work = 3 * A.shape[0] ** 2
    keep = [a for a in idx + val if a is not None]

    def pointers(arrays):
        return (ctypes.c_void_p * len(arrays))(*[None if a is None else a.ctypes.data
                                                 for a in arrays])
    return solver, pointers(idx), pointers(val), keep, work


def block_factors(A, what="the effective matrix") -> tuple:
    """(P^-1, G, F) of a matrix block tridiagonal in 2 x 2 node blocks (mck_loop.c block_solve):
    condensed from the last node, P_i = D_i - G_i F_i, G_i = E_i P_{i+1}^-1; a singular P_i is
    a ValueError naming the node."""
    D, E, F = linalg.node_blocks(A)
    nodes = D.shape[0]
    Pinv, G = np.empty((nodes, 2, 2)), np.empty((nodes - 1, 2, 2))
    P = D[-1]
    for k in range(nodes - 1, -1, -1):
        if k < nodes - 1:
            G[k] = E[k] @ Pinv[k + 1]
            P = D[k] - G[k] @ F[k]
        det = P[0, 0] * P[1, 1] - P[0, 1] * P[1, 0]
        if not np.isfinite(det) or abs(det) <= 1e-14 * max(np.abs(P).max() ** 2, 1e-300):
            raise ValueError(f"{what} is singular at node {k} (condensed pivot determinant "
                             f"{det:.3e})")
        Pinv[k] = np.array([[P[1, 1], -P[0, 1]], [-P[1, 0], P[0, 0]]]) / det
    return Pinv.ravel(), G.ravel(), F.ravel()


def make_advance(form, sch, K_, M, C, K, loaded, outputs, loop, blocks=None):
    """The ``advance(force_rows, H, xo, vo, ao)`` of stepping.integrate for assembled M, C, K in
    either form: u = (alpha M + r C + p K)^-1 (F - K q - C s - M b) each step (module
    docstring), in the C loop ``loop`` (mck_loop.c) or NumPy. ``blocks``: factor the effective
    matrix by `block_factors` (2 x 2 node blocks, the beam's matrix Riccati sweep) instead of
    LU. The same as ``step_operator(...)(loaded)``."""
    return step_operator(form, sch, K_, M, C, K, outputs, loop, blocks)(loaded)


def step_operator(form, sch, K_, M, C, K, outputs, loop, blocks=None, correct=None):
    """The factorized step of `make_advance` without its load: ``bind(loaded)`` gives the
    ``advance`` of the force columns on DOFs ``loaded``. The effective matrix is factorized
    here, once; each ``bind`` allocates its own scratch, so advances bound from one operator
    may run at the same time in several threads (the factors are only read). ``correct``
    (NumPy only): ``u = correct(u, H, Fe, solve)`` after each step's solve (a beam's
    refinement, `dtdyn.linear._beam.refined_step_operator`)."""
    A = K_["alpha_u"] * M + K_["r"] * C + K_["p"] * K
    with_m = form != "acceleration"  # the acceleration form has b = 0
    what = EFFECTIVE[form]
    if blocks:
        blocks = block_factors(A, what)
    if loop is not None:
        return _c_operator(loop, sch, K_, A, C, K, M if with_m else None, blocks, outputs,
                           what)
    solve = (linalg.sparse_lu(A, what, orderings=linalg.FILL_ORDERINGS).solve
             if sps.issparse(A) else linalg.solver(A, what))
    names = sch.history
    n = M.shape[0]

    def bind(loaded):
        def advance(frc, H, xo, vo, ao):
            Fe = np.zeros(n)
            for step in range(frc.shape[0] - 1):
                Fe[loaded] = K_["w0"] * frc[step] + K_["w1"] * frc[step + 1]
                rhs = Fe - K @ combine(K_, "q", H, names) - C @ combine(K_, "s", H, names)
                if with_m:
                    rhs -= M @ combine(K_, "b", H, names)
                u = solve(rhs)
                if correct is not None:
                    u = correct(u, H, Fe, solve)
                new = {q: combine(K_, q + "1", H, names, K_.get(q + "1_u", 0.0) * u)
                       for q in "xva"}
                shift_history(H, names, new)
                for arr, q in ((xo, "x"), (vo, "v"), (ao, "a")):
                    if arr is not None:
                        arr[step + 1] = new[q][outputs]
            return 0.0
        return advance
    return bind


def _c_operator(lib, sch, K_, A, C, K, M, blocks, outputs, what):
    """`step_operator` of the C loop: the operands once, ``bind(loaded)`` per load case."""
    names = list(sch.history)
    solver, idx, val, keep, step_work = _c_operands(A, C, K, M, blocks, what)
    # the step as matrices on the history rows (the generated maps of the plain sweep's error
    # history: the same step); rows q, s, b, then x1, v1, a1
    L_qsb, L_upd, c_u, shifts, rows = error_history_maps(K_, names)
    L = np.ascontiguousarray(np.vstack([L_qsb, L_upd]), dtype=float)
    c_u = np.ascontiguousarray(c_u.ravel())
    shift = np.array(shifts, dtype=np.int64).reshape(-1, 2)
    rows = np.arange(len(names), dtype=np.int64)[rows]
    out_idx = np.ascontiguousarray(outputs, dtype=np.int64)
    n = A.shape[0]
    run = lib.dtdyn_mck_loop

    def bind(loaded):
        loaded = np.ascontiguousarray(loaded, dtype=np.int64)
        work = np.empty(c_api.MCK_ROWS * n)  # scratch of this advance alone

        def advance(frc, H, xo, vo, ao):
            frc = np.ascontiguousarray(frc, dtype=float)
            Hc = np.ascontiguousarray(H)
            ptr = [0 if a is None else a.ctypes.data for a in (xo, vo, ao)]
            args = (solver, n, len(names), frc.shape[0] - 1, loaded.size, loaded.ctypes.data,
                    frc.ctypes.data, ctypes.addressof(idx), ctypes.addressof(val),
                    L.ctypes.data, c_u.ctypes.data, K_["w0"], K_["w1"], shift.shape[0],
                    shift.ctypes.data, rows.ctypes.data, Hc.ctypes.data, out_idx.size,
                    out_idx.ctypes.data, *ptr, work.ctypes.data, work.size)
            rc = cbuild.interruptible(lib, lambda: run(*args),
                                      work=(frc.shape[0] - 1) * step_work)
            if rc == c_api.ERR_WORK:
                raise DtdynKernelError("dtdyn_mck_loop", rc, f"n = {n}, n_work = {work.size}")
            if rc != 0:
                raise RuntimeError(f"dtdyn_mck_loop returned {rc} (stopped by its stop flag)")
            if Hc is not H:
                H[...] = Hc
            return 0.0
        advance.arrays = keep  # what idx and val point to lives as long as advance
        return advance
    bind.arrays = keep
    return bind


def mck_response(M, C, K, force, dt, *, force_dofs=None, scheme="newmark", outputs=None,
                 quantities=("x", "v", "a"), x0=None, v0=None, unstable="raise",
                 progress=False, ground_acceleration=None, ground_velocity=None,
                 ground_displacement=None, influence=None, backend="c",
                 **scheme_params) -> Response:
    """Time history of M q'' + C q' + K q = L f(t) by one of the generated integrators.

    Parameters
    ----------
    M, C, K : (N, N) array_like or scipy.sparse matrix
        Mass, damping, stiffness (sparse stays sparse: one sparse LU of the effective matrix).
        M may be singular (massless DOFs) where M + Dv C + Dx K is invertible and the initial
        state is consistent with it.
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Samples at t_k = k dt, k = 0 .. n_steps (a 1-D array is one column).
    dt : float
        Time step, > 0.
    force_dofs : sequence of int, optional
        0-based DOFs the force columns act on (all DOFs when None).
    scheme : str
        Any scheme of `chain_response`; parameters as keywords.
    outputs : sequence of int, optional
        DOFs whose response is stored (all by default).
    quantities : subset of ("x", "v", "a")
        What is stored; the others are None in the result.
    x0, v0 : (N,) array_like, optional
        Initial displacement and velocity (rest when None); a_0 = M^-1 (f_0 - C v0 - K x0).
    unstable : {"raise", "warn"}
        As `chain_response`: a conditionally stable scheme beyond its limit for the highest mode
        (when that can be computed: M nonsingular) is refused before the run, or warned about.
    progress : bool
        Show a progress bar on long runs.
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
    backend : {"c", "numpy"}
        The generated C loop (the effective matrix factorized once: dense LU, or for sparse
        matrices SuperLU's sparse LU of the least-fill ordering, applied by sparse substitution
        with sparse products for the load; the whole block of steps in one call; NumPy with one
        warning where no compiler exists) or the NumPy loop (scipy.sparse for sparse matrices).
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    Response
        ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.diag([2.0, 1.0]), np.zeros((2, 2)), np.array([[30.0, -10], [-10, 10]])
    >>> r = dd.mck_response(M, C, K, np.ones(101), 0.01, force_dofs=[1], scheme="wilson")
    >>> r.x.shape
    (101, 2)
    """
    solver = Matrices(M, C, K).solver(dt, scheme=scheme, backend=backend, outputs=outputs,
                                      quantities=quantities, unstable=unstable, **scheme_params)
    return solver.run(force, force_dofs=force_dofs, x0=x0, v0=v0, progress=progress,
                      ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
                      ground_displacement=ground_displacement, influence=influence)


class Matrices(Model):
    """A model given by its assembled matrices: M q'' + C q' + K q = L f(t).

    The model of `mck_response`, checked once; ``solver(dt, ...)`` prepares it for many load
    cases (`Solver`).

    Parameters
    ----------
    M, C, K : (N, N) array_like or scipy.sparse matrix
        Mass, damping, stiffness. M symmetric positive semi-definite (massless DOFs allowed
        where the effective matrix is invertible); C and K any real matrices (gyroscopic,
        circulatory terms, negative stiffness). Sparse input stays sparse (CSR), dense input is
        copied.

    Attributes
    ----------
    M, C, K : (N, N) ndarray or scipy.sparse.csr_matrix
        The checked matrices.
    n_dof : int
        N.
    sparse : bool
        Whether the matrices are scipy.sparse.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.Matrices(np.diag([2.0, 1.0]), np.zeros((2, 2)), [[30.0, -10], [-10, 10]])
    >>> solver = model.solver(0.01, scheme="wilson", outputs=[1])
    >>> r1, r2 = (solver.run(np.full(101, f), force_dofs=[1]) for f in (1.0, 2.0))
    >>> r1.x.shape, bool(np.allclose(r2.x, 2 * r1.x))
    ((101, 1), True)
    """

    def __init__(self, M, C, K):
        self.M, self.C, self.K = linalg.mck(M, C, K, keep_sparse=True)

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]

    @property
    def sparse(self) -> bool:
        return sps.issparse(self.M)

    def __repr__(self) -> str:
        return f"Matrices({self.n_dof} DOFs, {'sparse' if self.sparse else 'dense'})"

    @public
    def solver(self, dt, *, scheme=None, form="acceleration", backend="c", outputs=None,
               quantities=("x", "v", "a"), unstable="raise", elements=None, substeps=None,
               modes=None, tol=None, max_iter=None, solver=None, compiled=None, estimate=None,
               accuracy=None, **scheme_params) -> MatricesSolver:
        """Prepare the model for many load cases at the sample step ``dt``.

        Checks the options and the stability limit, factorizes the effective matrix of each
        scheme the run steps with (the start-up scheme of a multistep scheme too) and M (for
        the consistent initial acceleration), and loads the C loop, once. Each ``run`` of the
        returned solver is then one load case, the results of `mck_response` bitwise.

        With ``elements`` (localized nonlinear elements) the solver is that of
        `nonlinear_mck_response` (`dtdyn.nonlinear._solver.MatricesNonlinearSolver`): it
        checks the options and the elements, builds the scheme's linear step (the modal
        decomposition, the force polynomials' weights) and compiles the element laws into the
        C loop once; its ``run`` equals `nonlinear_mck_response` bitwise.

        Parameters
        ----------
        dt : float
            Sample step, s, > 0.
        scheme : str, optional
            Any scheme of `chain_response` (default "newmark"); its parameters (``beta``,
            ``gamma``, ``theta``, ``alpha``, ``rho_inf``) as keywords. With ``elements``: a
            scheme of `nonlinear_mck_response` (default "modal_ramp").
        form : {"acceleration", "displacement"}
            The step's unknown: the acceleration a_e, (M + Dv C + Dx K) a_e = F - C Ev - K Ex
            (`mck_response`'s), or the displacement increment u = x_e - x_n (implicit schemes
            only); both solve the scheme's equations, to rounding.
        backend : {"c", "numpy"}
            As `mck_response` (with ``elements``: "c" or "casadi").
        outputs : sequence of int, optional
            DOFs whose response is stored (all by default).
        quantities : subset of ("x", "v", "a")
            What is stored; the others are None in the results (with ``elements`` also "g",
            "z").
        unstable : {"raise", "warn"}
            A conditionally stable scheme beyond its limit for the highest mode: refused here
            (DtdynUnstableError), or warned about (linear solvers only).
        elements : sequence of elements, optional
            `Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen`: a nonlinear solver (above).
        substeps, modes, tol, max_iter, solver, compiled : optional
            With ``elements`` only: as `nonlinear_mck_response` (its defaults when None).
        estimate : bool, optional
            With ``elements`` only: False skips the embedded estimate of modal_quintic and
            modal_explicit (True, a second run at other sub-steps, is the function's only).
        accuracy : float, optional
            Refused: an accuracy target picks the method and the sub-steps per record, so it
            is an option of `nonlinear_mck_response`, not of a solver.
        **scheme_params
            The scheme's parameters.

        Returns
        -------
        Solver
            ``run(force, force_dofs=..., x0=..., v0=..., ground_acceleration=...)`` per load
            case; safe to call from several threads at once (with ``elements``: a
            `MatricesNonlinearSolver`, its C backend's runs too).

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> M, C, K = dd.chain_matrices([2.0, 3.0], [20.0, 15.0], [5.0, 6.0])
        >>> solver = dd.Matrices(M, C, K).solver(0.02, scheme="hht", alpha=-0.1)
        >>> r = solver.run(np.ones(501), force_dofs=[1])
        >>> bool((r.x == dd.mck_response(M, C, K, np.ones(501), 0.02, force_dofs=[1],
        ...                              scheme="hht", alpha=-0.1).x).all())
        True
        """
        nonlinear = dict(substeps=substeps, modes=modes, tol=tol, max_iter=max_iter,
                         solver=solver, compiled=compiled, estimate=estimate, accuracy=accuracy)
        if elements is not None:  # dtdyn.nonlinear's solver, by the registry (the layers)
            return nonlinear_solver(self, dt, elements, form=form, unstable=unstable,
                                    scheme=scheme, backend=backend, outputs=outputs,
                                    quantities=quantities, **nonlinear, **scheme_params)
        nonlinear_solver(self, dt, None, **nonlinear)  # none of them without elements
        return MatricesSolver(self, dt, "newmark" if scheme is None else scheme, form, backend,
                              outputs, quantities, unstable, scheme_params)


class MatricesSolver(Solver):
    """The `Solver` of `Matrices`: the effective matrix of each scheme factorized once (dense
    LU, SuperLU of the least-fill ordering, or the C loop's operands), M factorized once."""

    def __init__(self, model, dt, scheme, form, backend, outputs, quantities, unstable,
                 scheme_params):
        M, K = model.M, model.K
        loop = _c_loop() if check_backend(backend) == "c" else None
        super().__init__(model, dt, scheme, form, backend, outputs, quantities, unstable,
                         lambda limit: highest_frequency(M, K, limit), scheme_params)
        self._loop = loop
        self._ground_mass = M
        form = self.form
        self._steps = {scheme_key(s): step_operator(form, s, s.coefficients(form, self.dt), M,
                                                    model.C, K, self.outputs, loop)
                       for s in schemes_of_run(self._info)}
        self._mass_solve = mass_solver(M)

    def _initial_acceleration(self, case):
        f0 = case.f0
        if case.x0.any() or case.v0.any():  # (from rest: C 0 and K 0 are +0.0, f0 - 0 is f0)
            f0 = f0 - self.model.C @ case.v0 - self.model.K @ case.x0
        return self._mass_solve(f0)

    def _stepper(self, loaded):
        steps = self._steps
        return lambda sch, coeffs: steps[scheme_key(sch)](loaded)

    def _annotate(self, res):
        sparse = self.model.sparse
        res.info.update(method="assembled matrices", sparse=sparse,
                        backend="c" if self._loop is not None else
                        ("scipy.sparse" if sparse else "numpy"))
