"""Tight reference time histories for structures with localized nonlinear elements.

The problem:

    M q'' + C q' + K q + L^T g(y, y', z) = B f(t),    y = L q,    z' = h(y, y', z),

with q = q' = 0 and z = 0 at t = 0, the force known at the samples t_k = k / fs and linear in
between. It is integrated as the first-order system s = [q; q'; z] by SciPy's DOP853 (or Radau)
at rtol 1e-12, restarted at every sample; `check_reference` runs both and reports how far apart
they are, which is the accuracy a report can state for the reference.
"""
from __future__ import annotations

import hashlib
import time
import zipfile
from pathlib import Path

import numpy as np
import scipy
import scipy.linalg

from dtdyn._engine import linalg
from dtdyn._engine import validate
from dtdyn._engine.atomic import write_atomic
from dtdyn.nonlinear._elements import NUMPY_OPS, check_elements, element_matrix
from dtdyn._engine.result import Response

__all__ = ["reference_response", "check_reference", "reference_cache_dir"]

#: bump when the algorithm changes so stale cache files are not reused
VERSION = "nl_reference-1"
#: the ``ode_solver`` choices: names of scipy.integrate solver classes (scipy.integrate is
#: imported where a reference is integrated, so `import dtdyn` does not load it)
METHODS = ("DOP853", "Radau")


def reference_cache_dir() -> Path:
    """``<dtdyn cache>/reference/``, created: the folder of `dtdyn._engine.cbuild.cache_dir`
    (``$DTDYN_CACHE``, else ``$XDG_CACHE_HOME/dtdyn``, else ``~/.cache/dtdyn``)."""
    from dtdyn._engine.cbuild import cache_dir
    path = cache_dir() / "reference"
    path.mkdir(parents=True, exist_ok=True)
    return path


# ----------------------------------------------------------------------------------------------
# inputs

def _check_inputs(force, dt, M, C, K, force_dofs, elements, outputs, n_samples):
    fs = 1.0 / validate.positive_scalar("dt", dt)
    M, C, K = linalg.mck(M, C, K)
    N = M.shape[0]
    force_dofs = validate.dof_indices("force_dofs", force_dofs, N)
    outputs = validate.dof_indices("outputs", outputs, N)
    elements = check_elements(() if elements is None else elements)
    L = element_matrix(elements, N)
    f = np.asarray(force, dtype=float)
    if f.ndim == 1 and force_dofs.size == 1:
        f = f[:, None]
    if f.ndim != 2 or f.shape[1] != force_dofs.size or f.shape[0] < 1:
        raise ValueError(f"force has shape {f.shape}, expected (n_samples, len(force_dofs)) = "
                         f"(n_samples, {force_dofs.size}) with n_samples >= 1")
    if n_samples is not None:
        n_samples = validate.step_count("n_samples", n_samples)
        if n_samples > f.shape[0]:
            raise ValueError(f"n_samples = {n_samples} is more than the {f.shape[0]} force "
                             "samples given")
        f = f[:n_samples]
    bad = ~np.isfinite(f)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"force[{i}, {j}] = {f[i, j]!r} (sample {i}, force_dofs[{j}] = DOF "
                         f"{force_dofs[j]}) is not finite")
    solve_M = linalg.solver(M, "M", "the reference needs a nonsingular mass matrix")
    return np.ascontiguousarray(f), fs, M, C, K, force_dofs, elements, outputs, L, solve_M


def _default_scale(M, K, B, f, fs, n_internal):
    """Per-component scale of [q; q'; z] for the default atol = rtol * scale.

    x_ref = max_i |x_i| with (K + w_s^2 M) x = B f_peak (f_peak: the largest |f| of each force
    column), the static deflection under the peak force; w_s = 2 pi fs / 1000 regularises
    rigid-body modes (K singular) and barely changes it otherwise. v_ref = w_1 x_ref with w_1 the
    lowest natural frequency of (K + w_s^2 M, M): an underestimate of velocities, so the velocity
    tolerance errs on the tight side. Internal states (Bouc-Wen's z) are displacement-like and
    get x_ref.
    """
    N = M.shape[0]
    ws2 = (2.0 * np.pi * fs / 1000.0) ** 2
    Kr = K + ws2 * M
    Kr = 0.5 * (Kr + Kr.T)
    fpeak = B @ np.max(np.abs(f), axis=0)
    try:
        x = np.linalg.solve(Kr, fpeak)
        lam = scipy.linalg.eigh(Kr, 0.5 * (M + M.T), eigvals_only=True)
        w1 = float(np.sqrt(max(lam.min(), ws2)))
    except (np.linalg.LinAlgError, ValueError):  # indefinite or odd matrices: a plain estimate
        x = fpeak / (np.abs(np.diag(Kr)).max())
        w1 = float(np.sqrt(ws2))
    x_ref = float(np.max(np.abs(x)))
    if not np.isfinite(x_ref) or x_ref == 0.0:
        x_ref = 1.0  # no force at all: the solution is zero, any atol will do
    return np.concatenate([np.full(N, x_ref), np.full(N, w1 * x_ref), np.full(n_internal, x_ref)])


def _resolve_atol(atol, rtol, scale):
    if atol is None:
        return rtol * scale
    a = np.asarray(atol, dtype=float)
    if a.ndim == 0:
        a = np.full(scale.size, float(a))
    if a.shape != scale.shape or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"atol must be a positive number or {scale.size} positive numbers (one "
                         f"per state [q, q', z]), got {atol!r}")
    return a


# ----------------------------------------------------------------------------------------------
# the system

class _System:
    """s' = A s + c0 + c1 tau - G g(P s) (+ z' in the last rows), tau in [0, 1/fs] the time
    since the last sample; c0, c1 from the force samples at the ends of the interval."""

    def __init__(self, M, C, K, solve_M, B, L, elements):
        N, ne = M.shape[0], len(elements)
        nz = sum(el.n_internal for el in elements)
        ns = 2 * N + nz
        self.N, self.ne, self.nz, self.ns = N, ne, nz, ns
        self.elements = elements
        A = np.zeros((ns, ns))
        A[:N, N:2 * N] = np.eye(N)
        A[N:2 * N, :N] = -solve_M(K)
        A[N:2 * N, N:2 * N] = -solve_M(C)
        self.A = A
        self.MinvB = solve_M(B)                               # (N, n_force)
        G = np.zeros((ns, ne))
        if ne:
            G[N:2 * N] = solve_M(L.T)
        self.G = G
        P = np.zeros((2 * ne, ns))                            # [y; y'] = P s
        P[:ne, :N] = L
        P[ne:, N:2 * N] = L
        self.P = P
        offsets, off = [], 2 * N
        for el in elements:
            offsets.append((off, off + el.n_internal))
            off += el.n_internal
        self.offsets = offsets
        # one product for the linear part, the force and the elements' forces:
        # s' = W [s; 1; tau; g]  (then the z rows overwritten by the rates)
        W = np.zeros((ns, ns + 2 + ne))
        W[:, :ns] = A
        W[:, ns + 2:] = -G
        self.W = W
        self.u = np.zeros(ns + 2 + ne)
        self.u[ns] = 1.0
        self.n_rhs = 0

    def set_interval(self, f0, f1, fs):
        """Force f0 + (f1 - f0) fs tau on the interval."""
        N, ns = self.N, self.ns
        self.W[N:2 * N, ns] = self.MinvB @ f0
        self.W[N:2 * N, ns + 1] = self.MinvB @ ((f1 - f0) * fs)

    def rhs(self, tau, s):
        self.n_rhs += 1
        u = self.u  # scratch input; the output is a new array (SciPy keeps references to it)
        ns, ne = self.ns, self.ne
        u[:ns] = s
        u[ns + 1] = tau
        if not ne:
            return self.W @ u
        yv = (self.P @ s).tolist()
        rates = []
        for e, el in enumerate(self.elements):
            a, b = self.offsets[e]
            if a == b:
                u[ns + 2 + e] = el.force(yv[e], yv[ne + e], (), NUMPY_OPS)
            else:
                z = s[a:b].tolist()
                u[ns + 2 + e] = el.force(yv[e], yv[ne + e], z, NUMPY_OPS)
                rates.append((a, b, el.rate(yv[e], yv[ne + e], z, NUMPY_OPS)))
        out = self.W @ u
        for a, b, r in rates:
            out[a:b] = r
        return out

    def element_forces(self, S):
        """g at every stored state S (n, ns), vectorized over samples: (n, ne)."""
        n, ne = S.shape[0], self.ne
        g = np.zeros((n, ne))
        if ne:
            Y = S @ self.P.T
            for e, el in enumerate(self.elements):
                a, b = self.offsets[e]
                z = [S[:, c] for c in range(a, b)]
                g[:, e] = el.force(Y[:, e], Y[:, ne + e], z, NUMPY_OPS)
        return g


def _integrate(system, f, fs, method, rtol, atol):
    """States at every sample; the solver restarted at each sample, first step carried over."""
    import scipy.integrate  # deferred: ~0.2 s, needed only when a reference is integrated
    Solver = getattr(scipy.integrate, method)
    n, ns = f.shape[0], system.ns
    S = np.zeros((n, ns))
    s = np.zeros(ns)
    dt = 1.0 / fs
    first = None
    n_steps = 0
    for k in range(n - 1):
        system.set_interval(f[k], f[k + 1], fs)
        solver = Solver(system.rhs, 0.0, s, dt, rtol=rtol, atol=atol, first_step=first)
        before = solver.h_abs
        while solver.status == "running":
            before = solver.h_abs
            msg = solver.step()
            n_steps += 1
            if solver.status == "failed":
                raise RuntimeError(f"{method} failed between samples {k} and {k + 1} "
                                   f"(t = {k * dt:.6g} s): {msg}")
        s = solver.y
        S[k + 1] = s
        # the last step was usually cut short to land on the sample: carry the proposal
        # made before it, so the next interval does not start from a needlessly small step
        first = float(min(max(before, solver.h_abs), dt))
    return S, n_steps


# ----------------------------------------------------------------------------------------------
# cache

def _cache_key(arrays, fs, elements, method, rtol, atol) -> str:
    h = hashlib.sha256()
    for name, a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    h.update(repr((float(fs), [repr(el) for el in elements], method, float(rtol), VERSION,
                   scipy.__version__, np.__version__)).encode())
    h.update(np.ascontiguousarray(atol, dtype=float).tobytes())
    return h.hexdigest()


def _cache_load(path: Path, key: str, shape):
    """The stored states, or None when the file is missing, partial, corrupt or not ours."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            S = np.array(data["states"])
            n_steps = int(data["n_steps"])
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if S.shape != shape or not np.all(np.isfinite(S)):
        return None
    return S, n_steps


def _cache_store(path: Path, key: str, S, n_steps):
    """Write to a temporary file in the same folder, then os.replace: readers see either no
    file or a complete one, and racing writers each replace it with identical content."""
    write_atomic(path, lambda fh: np.savez(fh, key=np.array(key), states=S,
                                           n_steps=np.array(n_steps)))


# ----------------------------------------------------------------------------------------------
# entry points

def reference_response(M, C, K, force, dt, *, elements=(), force_dofs=None, outputs=None,
                       ode_solver="DOP853", rtol=1e-12, atol=None, cache=True, n_samples=None
                       ) -> Response:
    r"""Reference response of a structure with localized nonlinear elements.

    Solves, from rest (:math:`q = \dot q = 0`, :math:`z = 0`),

    .. math::

        M \ddot q + C \dot q + K q + L^T g(L q, L \dot q, z) = B f(t), \qquad
        \dot z = h(L q, L \dot q, z),

    where :math:`L` (`element_matrix`) gives each element's relative displacement
    :math:`y_e = q_i - q_j`, :math:`g_e` its force law and :math:`h` the internal-state rates
    (Bouc-Wen), and :math:`B` puts force column ``j`` on DOF ``force_dofs[j]``. The force is
    known at :math:`t_k = k\,\Delta t` and linear in between (the same first-order hold as
    `exact_response`, whose answer this equals when there are no elements).

    Parameters
    ----------
    M, C, K : (N, N) array_like
        Mass (nonsingular), damping and stiffness matrices of the linear part.
    force : (n_steps + 1, len(force_dofs)) array_like
        Force samples at :math:`t_0 \dots t_n`, finite; 1-D when one DOF is loaded.
    dt : float
        Sample step, s (> 0).
    elements : sequence of Element
        Nonlinear elements (`dtdyn.nonlinear._elements`); empty for a linear structure.
    force_dofs : sequence of int, optional
        0-based DOFs the force columns act on (all DOFs when None).
    outputs : sequence of int, optional
        DOFs whose x, v, a are returned (all by default).
    ode_solver : {"DOP853", "Radau"}
        SciPy solver class used on each interval.
    rtol : float
        Relative tolerance (default 1e-12).
    atol : float or (2 N + n_z,) array_like, optional
        Absolute tolerance per state [q, q', z]. Default ``rtol * scale`` with the scale of
        `_default_scale`: displacement x_ref = the largest static deflection under the peak
        force, velocity w_1 x_ref (w_1 the lowest natural frequency), internal states x_ref.
        Tying atol to the response's size keeps the error relative to max |x| near rtol
        without letting zero crossings (where a pure relative test has no floor) force tiny
        steps; an estimate within a factor of ten is enough, since atol only matters where
        the state is smaller than atol / rtol.
    cache : bool
        Reuse or store the states in ``<dtdyn cache>/reference/<sha256>.npz`` (see
        `reference_cache_dir`). The key covers M, C, K, the force, the force DOFs, fs, the
        elements' reprs, method, rtol, the resolved atol and a version string (plus SciPy's
        and NumPy's versions); ``outputs`` is not part of it (all DOFs are stored).
    n_samples : int, optional
        Use only the first ``n_samples`` force samples (all by default). A shorter run is
        always the start of the full one: the state at a later sample needs the whole
        history, so there is no window that starts elsewhere.

    Returns
    -------
    Response
        ``t = k / fs`` and ``x``, ``v``, ``a`` of shape (n_samples, len(outputs));
        ``info``: method, rtol, atol, n_solver_steps, n_rhs (0 when cached), run_time,
        cached, and ``internal`` (n_samples, n_z) holding z (Bouc-Wen states) at the samples.

    Notes
    -----
    The force has a kink at every sample (its derivative jumps), so the solution's third
    derivative jumps there too. An adaptive solver that steps across a kink sees a large
    local error, rejects and shrinks the step until the kink is resolved, and its high-order
    error estimate no longer describes the error; restarting at every sample makes each
    interval smooth, so DOP853's 8th order holds inside it and no step straddles a kink. The
    solver object is created per interval (public SciPy API, no solve_ivp overhead) with the
    last step size carried over as ``first_step``. Accelerations are
    :math:`\ddot q = M^{-1}(B f - C \dot q - K q - L^T g)` at the samples.

    Non-smooth laws (Gap without smoothing, Bouc-Wen's :math:`|\dot y|`) have kinks inside
    intervals too; the solver handles them by step rejection at some cost in time.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> r = dd.reference_response(np.eye(1), 0.1 * np.eye(1), np.eye(1), np.ones(51), 0.1,
    ...                           elements=[dd.Cubic(0, k3=0.5)], cache=False)
    >>> r.x.shape
    (51, 1)
    """
    start = time.perf_counter()
    method = ode_solver
    if method not in METHODS:
        raise ValueError(f"ode_solver must be one of {sorted(METHODS)}, got {method!r}")
    rtol = validate.positive_scalar("rtol", rtol)
    f, fs, M, C, K, force_dofs, elements, outputs, L, solve_M = _check_inputs(
        force, dt, M, C, K, force_dofs, elements, outputs, n_samples)
    N = M.shape[0]
    B = np.zeros((N, force_dofs.size))
    B[force_dofs, np.arange(force_dofs.size)] = 1.0
    system = _System(M, C, K, solve_M, B, L, elements)
    atol = _resolve_atol(atol, rtol, _default_scale(M, K, B, f, fs, system.nz))

    n = f.shape[0]
    S = None
    path = None
    cached = False
    n_steps = 0
    if cache:
        key = _cache_key([("M", M), ("C", C), ("K", K), ("force", f),
                          ("force_dofs", force_dofs)], fs, elements, method, rtol, atol)
        path = reference_cache_dir() / f"{key}.npz"
        hit = _cache_load(path, key, (n, system.ns))
        if hit is not None:
            S, n_steps = hit
            cached = True
    if S is None:
        S, n_steps = _integrate(system, f, fs, method, rtol, atol)
        if cache:
            _cache_store(path, key, S, n_steps)

    q, qd, z = S[:, :N], S[:, N:2 * N], S[:, 2 * N:]
    g = system.element_forces(S)
    acc = solve_M((f @ B.T - qd @ C.T - q @ K.T - g @ L).T).T
    return Response(
        t=np.arange(n) / fs,  # fs = 1 / dt
        outputs=outputs,
        x=np.ascontiguousarray(q[:, outputs]),
        v=np.ascontiguousarray(qd[:, outputs]),
        a=np.ascontiguousarray(acc[:, outputs]),
        info={"method": f"reference ({method}, restarted at every sample)", "solver": method,
              "rtol": rtol, "atol": atol, "n_solver_steps": n_steps,
              "n_rhs": 0 if cached else system.n_rhs, "cached": cached,
              "cache_file": None if path is None else str(path),
              "internal": np.ascontiguousarray(z),
              "run_time": time.perf_counter() - start},
    )


def check_reference(M, C, K, force, dt, *, elements=(), force_dofs=None, outputs=None,
                    n_samples=2000, rtol=1e-12, atol=None, cache=False) -> float:
    """Self-check of the reference: DOP853 against Radau on the first ``n_samples`` samples.

    Returns
    -------
    float
        max over outputs of ( max over time |x_DOP853 - x_Radau| / max over time |x_Radau| ),
        the number a report can quote as the reference's own accuracy. Outputs that stay at
        zero are skipped.

    Parameters
    ----------
    M, C, K, force, dt, elements, force_dofs, outputs
        As `reference_response`.
    n_samples : int
        The samples compared (the start of the record).
    rtol, atol, cache
        As `reference_response`.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> e = dd.check_reference(np.eye(1), 0.1 * np.eye(1), np.eye(1), np.ones(51), 0.1,
    ...                        elements=[dd.Cubic(0, k3=0.5)])
    >>> bool(e < 1e-9)
    True
    """
    n_total = np.shape(force)[0] if np.ndim(force) >= 1 else 0
    n_samples = min(validate.step_count("n_samples", n_samples), max(n_total, 1))
    args = (M, C, K, force, dt)
    kw = dict(elements=elements, force_dofs=force_dofs, outputs=outputs, rtol=rtol, atol=atol,
              cache=cache, n_samples=n_samples)
    a = reference_response(*args, ode_solver="DOP853", **kw).x
    b = reference_response(*args, ode_solver="Radau", **kw).x
    peak = np.max(np.abs(b), axis=0)
    live = peak > 0
    if not live.any():
        return float(np.max(np.abs(a - b)))
    return float(np.max(np.max(np.abs(a - b), axis=0)[live] / peak[live]))
