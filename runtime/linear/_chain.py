"""Chains of masses, springs and dampers: assembly and the DT-TMM time history.

::

    ground |--[k1,c1]--(m1)--[k2,c2]--(m2)-- ... --[kN,cN]--(mN)  free
                        F1  |             F2  |              FN
                        [kg1,cg1]         [kg2,cg2]          (optional, to the ground)

Station n (1-based in the papers, 0-based here): a spring k_n parallel to a damper c_n from node
n-1 to mass m_n; node 0 is ground. Each mass may also have a spring kg_n and a damper cg_n to
the ground (``ground_stiffness``, ``ground_damping``): mass-proportional and Rayleigh damping,
elastic supports. docs/dttmm.md has the station matrices and the sweep.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import kernels
from dtdyn._engine import threads as cpu
from dtdyn._engine import validate
from dtdyn._engine.result import Response
from dtdyn._engine.errors import DtdynAccuracyWarning
from dtdyn._engine.public import public, warn
from dtdyn.linear._solver import Model, Solver, nonlinear_solver, schemes_of_run
from dtdyn.linear._stability import chain_highest_frequency

#: the plain sweep warns above this estimated relative error
PLAIN_SWEEP_TOLERANCE = 1e-6
#: chain_response's default workers: the C stable sweep runs on two threads from this many
#: masses on (benchmarks/chain_speed.py measures both)
SPLIT_MASSES = 5_000


def sweep_threads(workers, n_masses: int) -> int:
    """Threads of the C stable sweep for ``workers`` (see `chain_response`): 1 or 2."""
    if workers is None:
        return 2 if n_masses >= SPLIT_MASSES and cpu.available() >= 2 else 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1 (threads of the "
                         "stable sweep)")
    return 2 if workers >= 2 and n_masses >= 2 else 1


class Chain(Model):
    """A chain of masses, springs and dampers: the model of `chain_response`.

    ::

        ground |--[k0,c0]--(m0)--[k1,c1]--(m1)-- ... --(mN-1)  free
                            [kg0,cg0] to the ground (optional)

    Station n joins mass n to mass n - 1 (station 0 to the ground) by a spring k_n parallel to
    a damper c_n; each mass may also have a spring kg_n and a damper cg_n to the ground.
    Checked once when made; ``solver(dt, ...)`` prepares it for many load cases (`Solver`).
    It unpacks as ``m, k, c, kg, cg = chain``.

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        m_n > 0, k_n >= 0, c_n >= 0 (N s/m) of station n (0-based); every station connected
        (k_n + c_n > 0).
    ground_stiffness, ground_damping : (N,) array_like, optional
        kg_n >= 0, cg_n >= 0: a spring and a damper from mass n to the ground (zeros).

    Attributes
    ----------
    mass, stiffness, damping, ground_stiffness, ground_damping : (N,) ndarray
        The checked values (read-only copies); also ``m``, ``k``, ``c``, ``kg``, ``cg``.
    n_dof : int
        N, the number of masses.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> chain = dd.Chain([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], ground_stiffness=[5.0, 0.0])
    >>> solver = chain.solver(0.02, scheme="hht", alpha=-0.1)
    >>> [solver.run(np.full(501, f), force_dofs=[1]).x.shape for f in (1.0, 2.0)]
    [(501, 2), (501, 2)]
    """

    _fields = ("m", "k", "c", "kg", "cg")

    def __init__(self, mass, stiffness, damping, *, ground_stiffness=None, ground_damping=None):
        m = validate.vector("mass", mass, positive=True)
        k = validate.vector("stiffness", stiffness, nonnegative=True, length=m.size)
        c = validate.vector("damping", damping, nonnegative=True, length=m.size)
        kg, cg = (np.zeros(m.size) if v is None else
                  validate.vector(name, v, nonnegative=True, length=m.size)
                  for name, v in (("ground_stiffness", ground_stiffness),
                                  ("ground_damping", ground_damping)))
        loose = np.flatnonzero((k == 0.0) & (c == 0.0))
        if loose.size:
            raise ValueError(f"station {int(loose[0])} has stiffness = damping = 0: the chain "
                             "is disconnected there")
        arrays = []
        for arr in (m, k, c, kg, cg):
            arr = np.array(arr, dtype=float)     # a copy: the model does not change under it
            arr.flags.writeable = False
            arrays.append(arr)
        self._arrays = tuple(arrays)

    m = mass = property(lambda self: self._arrays[0], doc="m_n, kg")
    k = stiffness = property(lambda self: self._arrays[1], doc="k_n, N/m")
    c = damping = property(lambda self: self._arrays[2], doc="c_n, N s/m")
    kg = ground_stiffness = property(lambda self: self._arrays[3], doc="kg_n, N/m")
    cg = ground_damping = property(lambda self: self._arrays[4], doc="cg_n, N s/m")

    def __iter__(self):
        return iter(self._arrays)

    def __getitem__(self, i):
        return self._arrays[i]

    def __len__(self) -> int:
        return 5

    @property
    def n_dof(self) -> int:
        return self._arrays[0].size

    def __repr__(self) -> str:
        grounded = " with ground elements" if self.kg.any() or self.cg.any() else ""
        return f"Chain({self.n_dof} masses{grounded})"

    def matrices(self, sparse: bool | None = None):
        """(M, C, K) of the chain, as `chain_matrices`."""
        return chain_matrices(self.m, self.k, self.c, sparse, ground_stiffness=self.kg,
                              ground_damping=self.cg)

    @public
    def solver(self, dt, *, scheme="newmark", form=None, sweep="stable", backend="c",
               outputs=None, quantities=("x", "v", "a"), unstable="raise", workers=None,
               elements=None, substeps=None, tol=None,
               max_iter=None, **scheme_params) -> ChainSolver:
        """Prepare the chain for many load cases at the sample step ``dt``.

        Checks the options and the stability limit (the chain's highest mode) and loads the
        C kernels of the scheme (and of its start-up scheme), once. Each ``run`` of the
        returned solver is one load case, the results of `chain_response` bitwise.

        Parameters
        ----------
        dt : float
            Sample step, s, > 0.
        scheme : str
            Any scheme of `chain_response`; its parameters as keywords.
        form : {"displacement", "acceleration"} or None
            As `chain_response`.
        sweep : {"stable", "plain"}
            As `chain_response` (the plain sweep warns with its error estimate per run).
        backend : {"c", "numpy"}
            As `chain_response`.
        outputs : sequence of int, optional
            Masses whose response is stored (all by default).
        quantities : subset of ("x", "v", "a")
            What is stored; the others are None in the results.
        unstable : {"raise", "warn"}
            As `chain_response`: refused here, or warned about.
        workers : int, optional
            Threads of the C stable sweep of each run, as `chain_response`.
        elements : sequence of elements, optional
            Localized nonlinear elements (`Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen`):
            the solver of `nonlinear_chain_response` instead: the checks, the linear step, the
            elements' unit responses and the compiled loop prepared once, each ``run`` equal
            to the function bitwise.
        substeps, tol, max_iter : optional
            With ``elements`` only: as `nonlinear_chain_response` (its defaults when None).
        **scheme_params
            The scheme's parameters.

        Returns
        -------
        Solver
            ``run(force, force_dofs=..., x0=..., v0=..., ground_acceleration=...)`` per load
            case; safe to call from several threads at once.

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> solver = dd.Chain([2.0, 3.0], [20.0, 15.0], [5.0, 6.0]).solver(0.02, outputs=[1])
        >>> r = solver.run(np.ones(501), force_dofs=[1], x0=[0.01, 0.0])
        >>> bool((r.x == dd.chain_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], np.ones(501),
        ...                                0.02, force_dofs=[1], x0=[0.01, 0.0],
        ...                                outputs=[1]).x).all())
        True
        """
        nonlinear = dict(substeps=substeps, tol=tol, max_iter=max_iter)
        if elements is not None:  # dtdyn.nonlinear's solver, by the registry (the layers)
            return nonlinear_solver(self, dt, elements, scheme=scheme, form=form,
                                    backend=backend, outputs=outputs, quantities=quantities,
                                    unstable=unstable, sweep=sweep, workers=workers, **nonlinear,
                                    **scheme_params)
        nonlinear_solver(self, dt, None, **nonlinear)  # none of them without elements
        return ChainSolver(self, dt, scheme, form, sweep, backend, outputs, quantities,
                           unstable, workers, scheme_params)


def chain_parameters(mass, stiffness, damping, ground_stiffness=None,
                     ground_damping=None) -> Chain:
    """The checked `Chain`: m > 0, k, c, kg, cg >= 0 (kg, cg zeros when None), same length,
    each station connected (k_n + c_n > 0)."""
    return Chain(mass, stiffness, damping, ground_stiffness=ground_stiffness,
                 ground_damping=ground_damping)


def rayleigh_chain_damping(mass, stiffness, rayleigh, ground_stiffness=None):
    r"""The chain form of Rayleigh damping :math:`C = \alpha M + \beta K`.

    Each station's damper is beta k_n and each mass's damper to the ground
    alpha m_n + beta kg_n, so that `chain_matrices` assembles exactly alpha M + beta K
    (the spring of station n is between two masses, m_n alone touches the ground).

    Parameters
    ----------
    mass, stiffness : (N,) array_like
        The chain (as `chain_response`).
    rayleigh : (alpha, beta)
        The mass- and stiffness-proportional coefficients, 1/s and s, >= 0. Modal damping
        ratios follow :math:`\zeta_r = \alpha / (2 \omega_r) + \beta \omega_r / 2`.
    ground_stiffness : (N,) array_like, optional
        Springs from the masses to the ground (part of K).

    Returns
    -------
    damping, ground_damping : (N,) ndarray
        For ``damping`` and ``ground_damping`` of the chain functions.

    Examples
    --------
    >>> import dtdyn as dd
    >>> c, cg = dd.rayleigh_chain_damping([2.0, 3.0], [20.0, 15.0], (0.5, 0.01))
    >>> c.tolist(), cg.tolist()
    ([0.2, 0.15], [1.0, 1.5])
    """
    m, k, _, kg, _ = chain_parameters(mass, stiffness, np.zeros(np.size(mass)), ground_stiffness)
    coef = validate.vector("rayleigh", rayleigh, nonnegative=True, length=2)
    alpha, beta = (float(v) for v in coef)
    return beta * k, alpha * m + beta * kg


def chain_matrices(mass, stiffness, damping, sparse: bool | None = None, *,
                   ground_stiffness=None, ground_damping=None):
    """Assembled (M, C, K) of a chain; scipy.sparse CSR when ``sparse`` (default: N > 200).

    K[n, n] += k_n + kg_n and, for n > 0, K[n-1, n-1] += k_n, K[n-1, n] = K[n, n-1] = -k_n;
    C alike with c_n and cg_n.

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        m_n > 0, k_n >= 0, c_n >= 0 of station n (0-based); station n joins mass n to mass n - 1
        (to the ground for n = 0).
    sparse : bool, optional
        scipy.sparse CSR matrices when True, dense arrays when False (default: N > 200).
    ground_stiffness, ground_damping : (N,) array_like, optional
        kg_n >= 0, cg_n >= 0: a spring and a damper from mass n to the ground (zeros).

    Returns
    -------
    M, C, K : (N, N) ndarray or scipy.sparse.csr_matrix

    Examples
    --------
    >>> import dtdyn as dd
    >>> M, C, K = dd.chain_matrices([2.0, 3.0], [20.0, 15.0], [5.0, 6.0])
    >>> K
    array([[ 35., -15.],
           [-15.,  15.]])
    """
    m, k, c, kg, cg = chain_parameters(mass, stiffness, damping, ground_stiffness,
                                       ground_damping)
    sparse = m.size > 200 if sparse is None else sparse

    def band(e, ground):
        diag = e + ground
        diag[:-1] += e[1:]
        return sps.diags([diag, -e[1:], -e[1:]], [0, 1, -1], format="csr")

    if not sparse:  # before anything is assembled: three dense n x n matrices
        validate.memory(f"chain_matrices(sparse=False): {m.size:,} masses as three dense "
                        f"{m.size:,} x {m.size:,} matrices", 3 * 8 * m.size * m.size,
                        "use sparse=True (scipy.sparse CSR, for mck_response and mck_modes) "
                        "or chain_response, which never forms the matrices")
    M, C, K = sps.diags(m, format="csr"), band(c, cg), band(k, kg)
    return (M, C, K) if sparse else (M.toarray(), C.toarray(), K.toarray())


def chain_response(mass, stiffness, damping, force, dt, *, ground_stiffness=None,
                   ground_damping=None, force_dofs=None, scheme="newmark", form=None,
                   sweep="stable", backend="c", outputs=None,
                   quantities=("x", "v", "a"), x0=None, v0=None, unstable="raise",
                   progress=False, ground_acceleration=None, ground_velocity=None,
                   ground_displacement=None, influence=None, workers=None,
                   **scheme_params) -> Response:
    """Time history of a chain by the discrete-time transfer matrix method (DT-TMM).

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        m_n > 0, k_n >= 0, c_n >= 0 of station n (0-based).
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Samples at t_k = k dt, k = 0 .. n_steps, for the masses in ``force_dofs``; linear in
        between where the scheme samples between steps (HHT, generalized-alpha, Wilson). A 1-D
        array is one column.
    dt : float
        Time step, > 0.
    ground_stiffness, ground_damping : (N,) array_like, optional
        kg_n >= 0, cg_n >= 0: a spring and a damper from mass n to the ground (zeros); e.g.
        mass-proportional or Rayleigh damping (`rayleigh_chain_damping`). Under support motion
        they move with the support like station 0.
    force_dofs : sequence of int, optional
        0-based masses the force columns act on (all masses when None).
    scheme : str
        "newmark" (beta, gamma), "average_acceleration", "linear_acceleration", "fox_goodwin",
        "newmark_1_8", "central_difference", "fox_euler", "wilson" (theta), "houbolt", "park",
        "hht" (alpha), "generalized_alpha" (rho_inf); parameters as keywords.
    form : {"displacement", "acceleration"} or None
        Primary unknown of the step transfer matrices (None: "displacement", or
        "acceleration" for an explicit scheme, which has only that form and needs c_n > 0 on
        every station there).
    sweep : {"stable", "plain"}
        "stable": the Riccati sweep, O(N) and accurate on any chain. "plain": the source's product
        of transfer matrices, kept for study; it loses accuracy like (m A / k)^N and warns
        (DtdynAccuracyWarning) with its error estimate when that exceeds 1e-6. The estimate
        (``info["error_estimate"]``, relative error of the displacements, max over time and
        masses) carries each step's rounding error on through the scheme, as derived in
        dtdyn.derive.dttmm; it is inf when the response may be all rounding error.
    backend : {"c", "numpy"}
        The generated C kernel (compiled on first use) or the generated NumPy sweep.
    outputs : sequence of int, optional
        Masses whose response is stored (all by default).
    quantities : subset of ("x", "v", "a")
        What is stored; the others are None in the result.
    x0, v0 : (N,) array_like, optional
        Initial displacement and velocity (rest when None); the initial acceleration is the
        consistent one, a_0 = M^-1 (f_0 - C v0 - K x0).
    unstable : {"raise", "warn"}
        A conditionally stable scheme whose limit the chain's highest mode exceeds at this dt:
        DtdynUnstableError before the run, or a DtdynStabilityWarning and the run (for study).
        Any run stops with FloatingPointError at its first non-finite step.
    progress : bool
        Show a progress bar (tqdm) on long runs.
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
        r, each DOF's motion per unit support motion (default: ones; a chain on a moving base).
    workers : int, optional
        Threads of the C stable sweep: 2 splits the chain at 60 % of its masses and runs
        the two parts side by side, handing two numbers over per step (a long chain is bound by
        memory traffic, which two cores share; larger values use 2). Default: 2 from
        `SPLIT_MASSES` masses on, when this process may use two CPUs (its affinity, capped by
        the environment variable DTDYN_THREADS), else 1.
        ``info["workers"]`` says how many ran.
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    Response
        ``t`` and ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.chain_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], np.ones(501), 0.02,
    ...                       force_dofs=[1], scheme="hht", alpha=-0.1)
    >>> r.x.shape
    (501, 2)

    Notes
    -----
    Each step: the scheme makes a_e = A x_e + B, v_e = D x_e + E at every mass; the Riccati
    relation f_n = S_n u_{n-1} + R_n is carried from the free end to the base, then the
    displacements forward (dtdyn.derive.dttmm). Only the loaded force columns are read and only
    the requested outputs stored: memory is O(N + n_steps * (len(force_dofs) + len(outputs))).

    References
    ----------
    Rui, Wang, Rong, He & Lu (2008), Discrete time transfer matrix method for multibody system
    dynamics. Horner & Pilkey (1978), The Riccati transfer matrix method.
    """
    chain = Chain(mass, stiffness, damping, ground_stiffness=ground_stiffness,
                  ground_damping=ground_damping)
    solver = chain.solver(dt, scheme=scheme, form=form, sweep=sweep, backend=backend,
                          outputs=outputs, quantities=quantities, unstable=unstable,
                          workers=workers, **scheme_params)
    return solver.run(force, force_dofs=force_dofs, x0=x0, v0=v0, progress=progress,
                      ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
                      ground_displacement=ground_displacement, influence=influence)


class ChainSolver(Solver):
    """The `Solver` of `Chain`: the scheme checked against the chain (an explicit scheme needs
    a damper on every station in the acceleration form), the kernels loaded, the matrices of
    the initial acceleration assembled once; each run sweeps the chain (DT-TMM)."""

    def __init__(self, chain, dt, scheme, form, sweep, backend, outputs, quantities, unstable,
                 workers, scheme_params):
        m, k, c, kg, cg = chain
        if sweep not in kernels.SWEEP_CODE:
            raise ValueError(f"sweep must be 'stable' or 'plain', got {sweep!r}")
        super().__init__(chain, dt, scheme, form, backend, outputs, quantities, unstable,
                         lambda limit: chain_highest_frequency(m, k, limit, kg), scheme_params)
        info = self._info
        kappa = np.min([np.abs(k * K0["p"] + c * K0["r"]) for K0 in
                        (s.coefficients(self.form, self.dt) for s in schemes_of_run(info))], axis=0)
        if np.any(kappa == 0.0):  # (a ground damper does not help: the station's row divides)
            n = int(np.flatnonzero(kappa == 0.0)[0])
            raise ValueError(f"damping[{n}] = 0 with the explicit scheme {info.name!r}: the "
                             "acceleration-form spring row divides by k Dx + c Dv = 0; give "
                             "every station a damper or use an implicit scheme")
        self.sweep = sweep
        # a composite scheme calls the kernel once per sub-step: one thread (no hand-over)
        self.threads = (sweep_threads(workers, m.size)
                        if sweep == "stable" and backend == "c" and not info.stages else 1)
        self._ground_mass = sps.diags(m)
        _, self._C, self._K = chain.matrices(sparse=True)
        if backend == "c":  # compile or load the kernels now, not in the first run
            for sch in schemes_of_run(info):
                kernels.c_chain_function(sch)
        self._used = ("c" if backend == "c" and kernels.c_chain_function(schemes_of_run(info)[-1])
                      else "numpy")

    def _initial_acceleration(self, case):
        f0 = case.f0
        if case.x0.any() or case.v0.any():  # a_0 = M^-1 (f_0 - C v_0 - K x_0)
            f0 = f0 - self._C @ case.v0 - self._K @ case.x0
        return f0 / self.model.m

    def _stepper(self, loaded):
        tracker = kernels.PlainSweepError(self.model.n_dof) if self.sweep == "plain" else None
        model, backend, form, sweep, dt = self.model, self.backend, self.form, self.sweep, self.dt
        outputs, threads = self.outputs, self.threads

        def make_advance(sch, coeffs):
            return kernels.chain_advance(backend, sch, coeffs, form, sweep, model, dt, loaded,
                                         outputs, tracker, threads)
        return make_advance

    def _annotate(self, res):
        used = self._used
        res.info.update(method="DT-TMM", sweep=self.sweep, backend=used,
                        workers=self.threads if used == "c" else 1)
        if self.sweep == "plain" and res.info["error_estimate"] > PLAIN_SWEEP_TOLERANCE:
            warn(f"plain DT-TMM sweep on {self.model.n_dof} masses: estimated relative error "
                 f"{res.info['error_estimate']:.1e} (cancellation in the transfer-matrix "
                 "product); use sweep='stable'", DtdynAccuracyWarning)
