"""Nonlinear normal modes: the backbone of M q'' + K q + L^T g(L q, L q') = 0 by harmonic balance.

The periodic motion of the unforced system (the damping C dropped) is continued in amplitude
from a linear mode. The motion is a truncated Fourier series of its own angular frequency omega,
q(t) = a Re sum_{k=0}^{H} Phi_k e^{i k omega t}, with a the amplitude of the first harmonic of
a reference DOF r. In the real basis (1, cos k theta, -sin k theta) with derivative D, the
unknowns are the normalized shape Phi, omega and xi of the extended periodic motion concept
(Krack 2015), a mass-proportional term -xi M q' that makes the conservative problem well posed:

    R(Phi, omega, xi; a) = omega^2 M Phi D^2 - xi omega M Phi D + K Phi
                           + L^T G(a Phi, omega) / a = 0,
    Re Phi_1[r] = 1,    Im Phi_1[r] = 0    (amplitude and phase normalization),

G the harmonics of the element forces by alternating frequency-time evaluation (AFT) with the
laws' exact derivatives (CasADi), as in `harmonic_balance`. For conservative elements xi is 0
at the solution (multiply by the velocity and average over a period: the energy balance leaves
xi omega^2 <q' M q'> = 0); for dissipative ones -xi M q' replaces the energy they take and
D = xi / (2 omega) is the equivalent modal damping ratio (Krack 2015). The solutions form a
curve in (Phi, omega, xi, log a), followed by pseudo-arclength continuation from the linear mode
(Phi = the mode shape with Phi_1[r] = 1, omega = its natural frequency, xi = 0) at the first
amplitude. The energy of a point is T + V at t = 0 (displacements extremal there at the
reference DOF): 1/2 q'^T M q' + 1/2 q^T K q + sum_e int_0^{y_e} g_e(s, 0) ds.

References: Krack, "Nonlinear modal analysis of nonconservative systems: extension of the
periodic motion concept", Computers & Structures 154 (2015) 59; Krack & Gross, "Harmonic
Balance for Nonlinear Vibration Problems", Springer 2019 (ch. 4); Kerschen, Peeters, Golinval &
Vakakis, "Nonlinear normal modes, Part I", Mech. Syst. Signal Process. 23 (2009) 170.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps

from dtdyn._engine import linalg, validate
from dtdyn._engine.errors import NewtonError
from dtdyn._engine.extras import require
from dtdyn._engine.public import public
from dtdyn.nonlinear._elements import check_elements, element_matrix
from dtdyn.nonlinear._harmonic_balance import (_basis, _complex, _law_function, _model, _peak,
                                               _positive_int, _projected, _range, _solve)

__all__ = ["backbone", "BackboneResult"]

#: the backbone is solved on the full model, densely: refused beyond this many unknowns
#: n (2 H + 1)
BACKBONE_MAX_SIZE = 4000

#: composite Gauss-Legendre rule for the elements' potential energy int_0^y g(s, 0) ds:
#: panels x nodes (exact for polynomial laws up to degree 7; a gap's kink costs O(1/panels^2))
_PANELS, _NODES = 128, 4


@dataclass(frozen=True)
class BackboneResult:
    """A backbone (nonlinear normal mode): one entry per point along the continuation.

    Attributes
    ----------
    frequency_hz, omega : (points,) ndarray
        The frequency of the periodic motion, Hz and rad/s.
    harmonics : (points, outputs, H + 1) complex ndarray
        X_k of each output: x(t) = Re sum_k X_k e^{i k omega t}; the phase is fixed by
        Im X_1 = 0 at the reference DOF.
    x_max : (points, outputs) ndarray
        max |x(t)| over a period.
    rms : (points, outputs) ndarray
        The root mean square of x(t) over a period.
    amplitude : (points,) ndarray
        a, the amplitude |X_1| of the first harmonic at the reference DOF (the continued
        parameter).
    energy : (points,) ndarray
        The mechanical energy T + V of the motion (at t = 0).
    damping_ratio : (points,) ndarray
        xi / (2 omega): zero (to the solver's tolerance) for conservative elements; for
        velocity-dependent laws the equivalent modal damping ratio of the extended periodic
        motion concept.
    outputs : (outputs,) int ndarray
    reference : int
        The reference DOF of the amplitude and the phase.
    mode : int
        The linear mode the backbone starts from (0-based, by increasing frequency).
    linear_frequency_hz : float
        That mode's natural frequency (of M and K).
    info : dict
        newton_iterations, steps, rejected_steps, law_evaluations, run_time, harmonics,
        n_time, stop.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> bb = dd.backbone(np.eye(1), K=np.eye(1), elements=[dd.Cubic(0, k3=0.5)],
    ...                  amplitudes=(0.01, 1.0), harmonics=5)
    >>> bool(bb.frequency_hz[-1] > bb.frequency_hz[0] > 1 / (2 * np.pi))
    True
    """

    frequency_hz: np.ndarray
    omega: np.ndarray
    harmonics: np.ndarray
    x_max: np.ndarray
    rms: np.ndarray
    amplitude: np.ndarray
    energy: np.ndarray
    damping_ratio: np.ndarray
    outputs: np.ndarray
    reference: int
    mode: int
    linear_frequency_hz: float
    info: dict = field(default_factory=dict)

    def plot(self, output: int = 0, ax=None, quantity: str = "x_max", **style):
        """The backbone against frequency, dotted black by default.

        Parameters
        ----------
        output : int
            Index into ``outputs`` (with ``quantity="x_max"``).
        ax : matplotlib Axes, optional
            Draw into these axes (e.g. a forced curve's ``plot()``); a new figure otherwise.
        quantity : {"x_max", "energy"}
            max |x| of the output, or the energy (the frequency-energy plot, energy on a log
            scale).
        **style
            Passed to ``ax.plot`` (default ``color="k", ls=":", label="backbone"``).

        Returns
        -------
        matplotlib Axes
        """
        plt = require("matplotlib.pyplot", "plot", "BackboneResult.plot")
        if quantity not in ("x_max", "energy"):
            raise ValueError(f"quantity must be 'x_max' or 'energy', got {quantity!r}")
        if ax is None:
            ax = plt.figure().add_subplot()
        style = {"color": "k", "ls": ":", "lw": 1.2, "label": "backbone", **style}
        if quantity == "energy":
            ax.semilogy(self.frequency_hz, self.energy, **style)
            ax.set_ylabel("energy")
        else:
            ax.plot(self.frequency_hz, self.x_max[:, output], **style)
            if not ax.get_ylabel():
                ax.set_ylabel(f"max |x| of DOF {int(self.outputs[output])}")
        ax.set_xlabel("frequency, Hz")
        return ax


class _Backbone:
    """R(z; p) of the module docstring: z = (Phi (2H+1) n, omega / w0, xi / w0), p = log a."""

    def __init__(self, M, K, L, laws, H, N, ref, w0):
        self.M, self.K, self.L, self.laws, self.H, self.N, self.ref, self.w0 = (
            M, K, L, laws, H, N, ref, w0)
        self.n, self.ne, self.nh = M.shape[0], L.shape[0], 2 * H + 1
        self.Ei, self.Ef, self.D = _basis(H, N)
        self.D2 = self.D @ self.D
        self.row_scale = 1.0 / max(np.abs(K).max(), w0 * w0 * np.abs(M).max())
        self.evaluations = 0

    def unpack(self, z):
        n, nh = self.n, self.nh
        return z[:nh * n].reshape(nh, n), z[nh * n] * self.w0, z[nh * n + 1] * self.w0

    def forces(self, Phi, omega, a):
        """The element samples: g, dg/dy, dg/dv (ne, N) at q = a Phi."""
        Yel = Phi @ self.L.T
        y = a * (self.Ei @ Yel)
        v = a * omega * (self.Ei @ self.D @ Yel)
        self.evaluations += 1
        return self.laws(y.T, v.T)

    def residual(self, z, p, jacobian=True):
        """(R, dR/dz, dR/dp) (Jacobians None without ``jacobian``)."""
        M, K, L, D, n, nh = self.M, self.K, self.L, self.D, self.n, self.nh
        Phi, omega, xi = self.unpack(z)
        a = math.exp(p)
        g, gy, gv = self.forces(Phi, omega, a)
        G = self.Ef @ g.T                                       # (nh, ne), of a Phi
        R = (omega ** 2 * (self.D2 @ Phi) @ M - xi * omega * (D @ Phi) @ M + Phi @ K
             + (G / a) @ L) * self.row_scale
        Rc = np.array([Phi[1, self.ref] - 1.0, Phi[2, self.ref]])
        R = np.concatenate([R.ravel(), Rc])
        if not jacobian:
            return R, None, None
        Jel = _projected(self.Ef, gy, self.Ei) + omega * _projected(self.Ef, gv, self.Ei @ D)
        m = nh * n
        J = np.zeros((m + 2, m + 2))
        J[:m, :m] = (np.kron(omega ** 2 * self.D2, M.T) - xi * omega * np.kron(D, M.T)
                     + np.kron(np.eye(nh), K.T)
                     + sum(np.kron(Jel[e], np.outer(L[e], L[e])) for e in range(self.ne)))
        Yel = Phi @ L.T
        dGw = self.Ef @ (gv.T * (self.Ei @ D @ Yel))           # d(G/a)/d omega
        J[:m, m] = (2 * omega * (self.D2 @ Phi) @ M - xi * (D @ Phi) @ M + dGw @ L).ravel() \
            * self.w0
        J[:m, m + 1] = (-omega * (D @ Phi) @ M).ravel() * self.w0
        J[:m, :m + 2] *= self.row_scale
        J[m, self.ref + n] = 1.0
        J[m + 1, self.ref + 2 * n] = 1.0
        JPhi = np.einsum("ejk,ke->je", Jel, Yel)                  # Jg Phi, element basis
        dp = np.concatenate([((JPhi - G / a) @ L).ravel() * self.row_scale, [0.0, 0.0]])
        return R, J, dp

    def energy(self, z, p, quad):
        """T + V at t = 0 of the point z at a = exp(p)."""
        Phi, omega, _ = self.unpack(z)
        a = math.exp(p)
        q = a * (self.Ei[0] @ Phi)
        v = a * omega * (self.Ei[0] @ self.D @ Phi)
        y = self.L @ q
        nodes, weights = quad
        s = np.outer(y, nodes)                                   # (ne, Q)
        g = self.laws_static(s)
        return 0.5 * v @ self.M @ v + 0.5 * q @ self.K @ q + float(np.sum(g @ weights * y))



def _quadrature():
    """Nodes in (0, 1) and weights (sum 1) of the composite Gauss-Legendre rule."""
    x, w = np.polynomial.legendre.leggauss(_NODES)
    h = 1.0 / _PANELS
    nodes = (np.arange(_PANELS)[:, None] * h + 0.5 * h * (x + 1.0)).ravel()
    return nodes, np.tile(0.5 * h * w, _PANELS)


def _linear_mode(M, K, mode):
    """(omega_r, phi_r) of the undamped mode ``mode`` (0-based by frequency)."""
    lam, vec = sla.eig(K, M)
    ok = np.isfinite(lam)
    lam, vec = lam[ok].real, vec[:, ok].real
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    if lam.size == 0 or lam[0] <= 1e-12 * max(abs(lam).max(), 1e-300):
        raise ValueError("K has a zero or negative eigenvalue (a rigid-body mode or an unstable "
                         "linear part): the backbone needs K - (k omega)^2 M nonsingular at "
                         "k = 0, i.e. K positive definite")
    if isinstance(mode, bool) or not isinstance(mode, (int, np.integer)) or \
            not 0 <= mode < lam.size:
        raise ValueError(f"mode must be an integer 0 .. {lam.size - 1} (the linear modes by "
                         f"increasing frequency), got {mode!r}")
    return math.sqrt(lam[mode]), vec[:, mode]


class _Continuation:
    """Pseudo-arclength continuation of R(z; p) = 0 in x = (z, p / ps)."""

    def __init__(self, bb, tol, max_iter, ps):
        self.bb, self.tol, self.max_iter, self.ps = bb, tol, max_iter, ps
        self.newton = 0

    def solve_fixed(self, z, p):
        z = z.copy()
        for _ in range(self.max_iter):
            R, J, _ = self.bb.residual(z, p)
            dz = _solve(J, R)
            z -= dz
            self.newton += 1
            if not np.all(np.isfinite(z)):
                break
            if np.abs(dz).max() <= self.tol * max(np.abs(z).max(), 1.0):
                return z
        raise NewtonError(f"backbone: Newton did not converge at the amplitude {math.exp(p):.6g}"
                          f" of the reference DOF in {self.max_iter} iterations (start lower, "
                          "or a resonance of a higher harmonic with another mode?)")

    def tangent(self, z, p, previous):
        _, J, dp = self.bb.residual(z, p)
        A = np.vstack([np.column_stack([J, dp * self.ps]), previous])
        t = _solve(A, np.concatenate([np.zeros(J.shape[0]), [1.0]]))
        t /= np.linalg.norm(t)
        return t if t @ previous > 0 else -t

    def correct(self, x_pred, t, x0, ds):
        x = x_pred.copy()
        for it in range(1, self.max_iter + 1):
            R, J, dp = self.bb.residual(x[:-1], x[-1] * self.ps)
            A = np.vstack([np.column_stack([J, dp * self.ps]), t])
            try:
                dx = _solve(A, np.concatenate([R, [t @ (x - x0) - ds]]))
            except np.linalg.LinAlgError:
                return None, it
            x = x - dx
            self.newton += 1
            if not np.all(np.isfinite(x)):
                return None, it
            if np.abs(dx).max() <= self.tol * max(np.abs(x).max(), 1.0):
                return x, it
        return None, self.max_iter


def _continue(cont, z, p0, p_end, measure, m_end, step, max_step, min_step, max_angle,
              max_points):
    """Points (z, p) from (z, p0) until measure(z, p) (increasing along the start of the curve)
    passes m_end; the last point is put on m_end by a secant search in p."""
    ps = cont.ps
    x = np.concatenate([z, [p0 / ps]])
    e = np.zeros(x.size)
    e[-1] = 1.0
    t = cont.tangent(z, p0, e)
    points, values = [(z, p0)], [measure(z, p0)]
    ds, steps, rejected, stop = step, 0, 0, "end of the range"
    while True:
        if len(points) >= max_points:
            stop = "max_points"
            warnings.warn(f"backbone stopped after max_points = {max_points} points at the "
                          f"amplitude {math.exp(points[-1][1]):.6g}", RuntimeWarning,
                          stacklevel=3)
            break
        x_new, its = cont.correct(x + ds * t, t, x, ds)
        t_new = None
        if x_new is not None:
            t_new = cont.tangent(x_new[:-1], x_new[-1] * ps, t)
            if math.acos(float(np.clip(t_new @ t, -1.0, 1.0))) > max_angle:
                t_new = None
        if t_new is None:
            rejected += 1
            ds *= 0.5
            if ds < min_step:
                raise NewtonError(f"backbone: the arclength step fell below min_step = "
                                  f"{min_step:g} at the amplitude {math.exp(x[-1] * ps):.6g} "
                                  f"({points[-1][0][-2] * cont.bb.w0 / (2 * np.pi):.6g} Hz; an "
                                  "internal resonance or a bifurcation of the mode?)")
            continue
        steps += 1
        z_new, p_new = x_new[:-1], x_new[-1] * ps
        m_new = measure(z_new, p_new)
        if m_new >= m_end:
            points.append(_secant(cont, points[-1], values[-1], (z_new, p_new), m_new, measure,
                                  m_end))
            values.append(m_end)
            break
        points.append((z_new, p_new))
        values.append(m_new)
        if p_new < p0:
            stop = "amplitude fell below its start"
            break
        x, t = x_new, t_new
        ds = min(max_step, ds * (1.5 if its <= 3 else (1.0 if its <= 6 else 0.6)))
    return points, steps, rejected, stop


def _secant(cont, A, mA, B, mB, measure, m_end):
    """The point between A = (z, p) and B where measure = m_end (Newton at fixed p, the
    secant/regula falsi in p)."""
    (zA, pA), (zB, pB) = A, B
    for _ in range(40):
        f = (m_end - mA) / (mB - mA)
        p = pA + f * (pB - pA)
        z = cont.solve_fixed(zA + f * (zB - zA), p)
        m = measure(z, p)
        if abs(m - m_end) <= 1e-13 * abs(m_end):
            break
        if m < m_end:
            zA, pA, mA = z, p, m
        else:
            zB, pB, mB = z, p, m
    return z, p


def _inputs(M, C, K, elements, harmonics, n_time, outputs, amplitudes, energies, step,
            max_step, min_step, max_angle, max_points, tol, max_iter):
    """The checked inputs of `backbone`."""
    if K is not None and C is None:          # C is not used: only its place in the signature
        C = np.zeros(np.shape(K))
    try:
        M, _, K, names, _, _ = _model(M, C, K)
    except ValueError as error:
        if K is None and "required" in str(error):
            raise ValueError("K is required with matrices M (C may be left out: the backbone "
                             "drops it), or give a Chain, Beam, Shaft or Matrices as the first "
                             "argument") from None
        raise
    for name, A in (("M", M), ("K", K)):
        if sps.issparse(A):
            validate.dense_conversion(name, A, "backbone", copies=3)
    M, K = (A.toarray() if sps.issparse(A) else A for A in (M, K))
    M, _, K = linalg.mck(M, np.zeros(np.shape(M)), K)
    n = M.shape[0]
    elements = check_elements(elements)
    if not elements:
        raise ValueError("elements is empty: a backbone needs at least one nonlinear element")
    for e, el in enumerate(elements):
        if el.n_internal:
            raise ValueError(f"elements[{e}] ({el.describe()}) has internal states (hysteresis):"
                             " backbone does not support it")
    H = _positive_int("harmonics", harmonics, 1)
    N = 2 ** math.ceil(math.log2(8 * (H + 1))) if n_time is None else \
        _positive_int("n_time", n_time, 2 * H + 2)
    if n * (2 * H + 1) > BACKBONE_MAX_SIZE:
        raise ValueError(f"backbone solves the full model densely: n (2 H + 1) = "
                         f"{n * (2 * H + 1)} unknowns here, at most {BACKBONE_MAX_SIZE}; use "
                         "fewer harmonics or a smaller (reduced) model")
    outputs = validate.dof_indices("outputs", outputs, n, names=names)
    if (amplitudes is None) == (energies is None):
        raise ValueError("give one of amplitudes=(start, end) and energies=(start, end)")
    use_energy = energies is not None
    lo, hi = _range("energies" if use_energy else "amplitudes",
                    energies if use_energy else amplitudes)
    if hi < lo:
        raise ValueError(f"{'energies' if use_energy else 'amplitudes'} must increase "
                         f"(start < end), got {(lo, hi)!r}")
    opts = dict(step=validate.positive_scalar("step", step),
                max_step=validate.positive_scalar("max_step", max_step),
                min_step=validate.positive_scalar("min_step", min_step),
                max_angle=validate.positive_scalar("max_angle", max_angle),
                max_points=_positive_int("max_points", max_points, 2))
    if not opts["min_step"] <= opts["step"] <= opts["max_step"]:
        raise ValueError(f"need min_step <= step <= max_step, got {min_step!r}, {step!r}, "
                         f"{max_step!r}")
    tol = validate.positive_scalar("tol", tol)
    max_iter = _positive_int("max_iter", max_iter, 1)

    return M, K, names, elements, H, N, outputs, use_energy, (lo, hi), opts, tol, max_iter


@public
def backbone(M, C=None, K=None, *, elements, mode=0, amplitudes=None, energies=None,
             harmonics=7, outputs=None, reference=None, n_time=None, step=0.05, max_step=0.2,
             min_step=1e-7, max_angle=0.35, max_points=2000, tol=1e-10,
             max_iter=20) -> BackboneResult:
    """Backbone (nonlinear normal mode) of M q'' + K q + L^T g(L q, L q') = 0 by harmonic balance:
    the periodic free motion continued in amplitude (or energy) from a linear mode.

    Parameters
    ----------
    M, C, K : (n, n) array_like, or a model
        The linear part; C is ignored (the backbone is the motion without damping and load).
        Or a `Chain`, `Beam`, `Shaft` or `Matrices` as ``M`` alone. K must be positive definite
        (no rigid-body mode).
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap`, `Law` (in x and v), as in `harmonic_balance`; a
        velocity-dependent law gives the damped nonlinear mode of the extended periodic motion
        concept (``damping_ratio``).
    mode : int
        The linear mode (0-based, by increasing natural frequency of K and M) the backbone
        starts from.
    amplitudes : (start, end), optional
        The range of a, the first harmonic's amplitude at the ``reference`` DOF.
    energies : (start, end), optional
        The range of the mechanical energy instead (give one of ``amplitudes`` and
        ``energies``); the curve is continued in amplitude until the energy passes the end.
    harmonics : int
        H, the highest harmonic kept (0 .. H).
    outputs : sequence of int or DOF names, optional
        DOFs whose harmonics are returned (all by default).
    reference : int or DOF name, optional
        The DOF of the amplitude and the phase (default: the largest entry of the mode shape
        weighted by sqrt(M_ii)).
    n_time : int, optional
        Samples per period of the AFT (default: the power of 2 >= 8 (H + 1)).
    step, max_step, min_step : float
        Initial, largest and smallest arclength step (the scaled variables: the shape
        normalized to 1 at the reference DOF, omega and xi per the linear frequency, log a per
        the range's span).
    max_angle : float
        A step whose tangent turns by more than this (rad) is retried at half the length.
    max_points : int
        The most points along the backbone.
    tol : float
        Newton stops when its step is below ``tol`` times the largest scaled unknown.
    max_iter : int
        Newton iterations per corrector.

    Returns
    -------
    BackboneResult

    Raises
    ------
    NewtonError
        No solution at the start (lower ``amplitudes[0]``), or the step fell below
        ``min_step`` (an internal resonance: a harmonic k omega meeting another mode).

    Notes
    -----
    Unknowns Phi (the harmonics of q / a), omega and xi; equations
    omega^2 M Phi D^2 - xi omega M Phi D + K Phi + L^T G(a Phi) / a = 0, Re Phi_1[r] = 1,
    Im Phi_1[r] = 0 (module docstring and docs/guide/harmonic_balance.md). The full model is
    solved densely: n (2 H + 1) must be at most 4000. Krack, Computers & Structures 154 (2015)
    59; Krack & Gross, "Harmonic Balance for Nonlinear Vibration Problems", Springer 2019.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> bb = dd.backbone(np.eye(1), K=np.eye(1), elements=[dd.Cubic(0, k3=0.5)],
    ...                  amplitudes=(0.01, 2.0), harmonics=7)
    >>> round(float(bb.x_max[-1, 0]), 4), round(float(bb.omega[-1]), 4)   # x'' + x + 0.5 x^3 = 0
    (2.0545, 1.5944)
    """
    t_start = time.perf_counter()
    M, K, names, elements, H, N, outputs, use_energy, (lo, hi), opts, tol, max_iter = _inputs(
        M, C, K, elements, harmonics, n_time, outputs, amplitudes, energies, step, max_step,
        min_step, max_angle, max_points, tol, max_iter)
    n = M.shape[0]
    w0, phi = _linear_mode(M, K, mode)
    if reference is None:
        ref = int(np.argmax(np.abs(phi) * np.sqrt(np.maximum(np.diag(M), 0.0))))
    else:
        ref = int(validate.dof_indices("reference", [reference], n, names=names)[0])
        if abs(phi[ref]) <= 1e-8 * np.abs(phi).max():
            raise ValueError(f"reference = {reference!r}: the linear mode {mode} does not move "
                             "that DOF (a node); choose another")
    L = element_matrix(elements, n)
    bb = _Backbone(M, K, L, _law_function(elements, N), H, N, ref, w0)
    quad = _quadrature()
    laws_q = _law_function(elements, quad[0].size)
    bb.laws_static = lambda s: laws_q(s, np.zeros_like(s))[0]

    nh = 2 * H + 1
    z = np.zeros(nh * n + 2)
    Phi0 = np.zeros((nh, n))
    Phi0[1] = phi / phi[ref]
    z[:nh * n], z[nh * n] = Phi0.ravel(), 1.0
    m_phi = Phi0[1] @ M @ Phi0[1]
    if use_energy:                     # the linear estimate E = 1/2 w0^2 a^2 phi^T M phi
        p0 = 0.5 * math.log(2.0 * lo / (w0 * w0 * m_phi))
        ps = max(0.5 * math.log(hi / lo), 1e-3)
    else:
        p0 = math.log(lo)
        ps = max(math.log(hi / lo), 1e-3)
    cont = _Continuation(bb, tol, max_iter, ps)
    z = cont.solve_fixed(z, p0)
    if use_energy:                     # E ~ a^2: Newton in log a on log E
        def measure(z, p):
            return bb.energy(z, p, quad)
        for _ in range(50):
            E = measure(z, p0)
            if abs(E - lo) <= 1e-13 * lo:
                break
            p0 += 0.5 * math.log(lo / E)
            z = cont.solve_fixed(z, p0)
        m_end = hi
    else:
        def measure(z, p):
            return p
        m_end = math.log(hi)
    points, steps, rejected, stop = _continue(cont, z, p0, m_end, measure, m_end, **opts)

    Z = np.array([q[0] for q in points])
    a = np.exp(np.array([q[1] for q in points]))
    omega = Z[:, nh * n] * w0
    xi = Z[:, nh * n + 1] * w0
    X = np.array([_complex(q[0][:nh * n].reshape(nh, n)[:, outputs]) for q in points])
    X *= a[:, None, None]
    x_max = np.array([_peak(Xp) for Xp in X])
    rms = np.sqrt(np.abs(X[:, 0].real) ** 2 + 0.5 * np.sum(np.abs(X[:, 1:]) ** 2, axis=1))
    energy = np.array([bb.energy(zp, pp, quad) for zp, pp in points])
    info = dict(newton_iterations=cont.newton, steps=steps, rejected_steps=rejected,
                law_evaluations=bb.evaluations, run_time=time.perf_counter() - t_start,
                harmonics=H, n_time=N, stop=stop)
    return BackboneResult(
        frequency_hz=omega / (2 * np.pi), omega=omega, harmonics=np.transpose(X, (0, 2, 1)),
        x_max=x_max, rms=rms, amplitude=a, energy=energy, damping_ratio=xi / (2 * omega),
        outputs=outputs, reference=ref, mode=int(mode), linear_frequency_hz=w0 / (2 * np.pi),
        info=info)
