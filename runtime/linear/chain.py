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

from typing import NamedTuple

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import ground as support
from dtdyn._engine import kernels
from dtdyn._engine import stepping
from dtdyn._engine import threads as cpu
from dtdyn._engine import validate
from dtdyn._engine.result import Response
from dtdyn._engine.schemes import get_scheme
from dtdyn._engine.errors import DtdynAccuracyWarning
from dtdyn._engine.public import warn
from dtdyn.linear.stability import chain_highest_frequency, check_dt

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


class Chain(NamedTuple):
    """A checked chain: masses m, station springs k and dampers c (station n joins mass n to
    mass n - 1, station 0 to the ground), each mass's spring kg and damper cg to the ground."""

    m: np.ndarray
    k: np.ndarray
    c: np.ndarray
    kg: np.ndarray
    cg: np.ndarray


def chain_parameters(mass, stiffness, damping, ground_stiffness=None,
                     ground_damping=None) -> Chain:
    """The checked `Chain`: m > 0, k, c, kg, cg >= 0 (kg, cg zeros when None), same length,
    each station connected (k_n + c_n > 0)."""
    m = validate.vector("mass", mass, positive=True)
    k = validate.vector("stiffness", stiffness, nonnegative=True, length=m.size)
    c = validate.vector("damping", damping, nonnegative=True, length=m.size)
    kg, cg = (np.zeros(m.size) if v is None else
              validate.vector(name, v, nonnegative=True, length=m.size)
              for name, v in (("ground_stiffness", ground_stiffness),
                              ("ground_damping", ground_damping)))
    loose = np.flatnonzero((k == 0.0) & (c == 0.0))
    if loose.size:
        raise ValueError(f"station {int(loose[0])} has stiffness = damping = 0: the chain is "
                         "disconnected there")
    return Chain(m, k, c, kg, cg)


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
    ground_stiffness, ground_damping : (N,) array_like, optional
        kg_n >= 0, cg_n >= 0: a spring and a damper from mass n to the ground (zeros).
    sparse : bool, optional
        scipy.sparse CSR matrices when True, dense arrays when False (default: N > 200).

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

    M, C, K = sps.diags(m, format="csr"), band(c, cg), band(k, kg)
    return (M, C, K) if sparse else (M.toarray(), C.toarray(), K.toarray())


def chain_response(mass, stiffness, damping, force, dt, *, ground_stiffness=None,
                   ground_damping=None, force_dofs=None, scheme="newmark", form="displacement", sweep="stable", backend="c", outputs=None,
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
    form : {"displacement", "acceleration"}
        Primary unknown of the step transfer matrices. Explicit schemes have only the
        acceleration form, and need c_n > 0 on every station there.
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
    chain = chain_parameters(mass, stiffness, damping, ground_stiffness, ground_damping)
    m, k, c, kg, cg = chain
    force, force_dofs, ground = support.prepare(sps.diags(m), force, force_dofs, m.size,
                                                ground_acceleration, influence, dt=dt,
                                                ground_velocity=ground_velocity,
                                                ground_displacement=ground_displacement)
    force, dt, loaded = validate.time_history(force, dt, force_dofs, m.size)
    x0, v0 = validate.initial_conditions(x0, v0, m.size)
    outputs = validate.dof_indices("outputs", outputs, m.size)
    quantities = stepping.check_quantities(quantities)
    if sweep not in kernels.SWEEP_CODE:
        raise ValueError(f"sweep must be 'stable' or 'plain', got {sweep!r}")
    if backend not in ("c", "numpy"):
        raise ValueError(f"backend must be 'c' or 'numpy', got {backend!r}")
    info = get_scheme(scheme, **scheme_params)
    check_dt(info, dt, lambda limit: chain_highest_frequency(m, k, limit, kg), unstable)
    K0 = info.coefficients(form, dt)
    kappa = k * K0["p"] + c * K0["r"]
    if np.any(kappa == 0.0):  # (a ground damper does not help: the station's row divides)
        n = int(np.flatnonzero(kappa == 0.0)[0])
        raise ValueError(f"damping[{n}] = 0 with the explicit scheme {info.name!r}: the acceleration-"
                         "form spring row divides by k Dx + c Dv = 0; give every station a damper "
                         "or use an implicit scheme")

    tracker = kernels.PlainSweepError(m.size) if sweep == "plain" else None
    threads = sweep_threads(workers, m.size) if sweep == "stable" and backend == "c" else 1

    def make_advance(sch, coeffs):
        return kernels.chain_advance(backend, sch, coeffs, form, sweep, chain, dt, loaded,
                                     outputs, tracker, threads)

    f0 = np.zeros(m.size)
    f0[loaded] = force[0]
    if x0.any() or v0.any():  # a_0 = M^-1 (f_0 - C v_0 - K x_0), consistent with the start
        _, C, K = chain_matrices(m, k, c, sparse=True, ground_stiffness=kg, ground_damping=cg)
        f0 = f0 - C @ v0 - K @ x0
    a0 = f0 / m
    res = stepping.integrate(info, form, dt, force, (x0, v0, a0), make_advance, outputs,
                             quantities, progress)
    used = "c" if backend == "c" and kernels.c_chain_function(info.name) else "numpy"
    res.info.update(method="DT-TMM", sweep=sweep, backend=used,
                    workers=threads if used == "c" else 1)
    if sweep == "plain" and res.info["error_estimate"] > PLAIN_SWEEP_TOLERANCE:
        warn(f"plain DT-TMM sweep on {m.size} masses: estimated relative error "
             f"{res.info['error_estimate']:.1e} (cancellation in the transfer-matrix "
             "product); use sweep='stable'", DtdynAccuracyWarning)
    return support.finish(res, ground)
