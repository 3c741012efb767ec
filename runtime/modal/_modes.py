r"""Natural modes of M q'' + C q' + K q = f: frequencies, mass-normalized shapes, participation
factors and effective modal masses; damping ratios and complex modes when C is given.

Undamped modes solve :math:`K \phi_r = \omega_r^2 M \phi_r` with :math:`\Phi^T M \Phi = I`
(scipy.linalg.eigh; for sparse models the lowest ``count`` by shift-invert Lanczos about 0,
scipy.sparse.linalg.eigsh with sigma = 0). For an influence vector r (the DOFs' motion under a
unit rigid support motion, ones by default; Chopra, *Dynamics of Structures*, sec. 13.1):

.. math::

    \Gamma_r = \phi_r^T M r \quad (\phi_r^T M \phi_r = 1), \qquad
    m_{\mathrm{eff},r} = \Gamma_r^2, \qquad \sum_r m_{\mathrm{eff},r} = r^T M r,

the last over all modes (the total mass for r = ones on a model with one translation per DOF).
With C, the damped modes are the eigenpairs of the first-order pencil
:math:`(\begin{smallmatrix} 0 & I \\ -K & -C \end{smallmatrix}) z = s (\begin{smallmatrix}
I & 0 \\ 0 & M \end{smallmatrix}) z` with :math:`\mathrm{Im}\,s > 0` (underdamped), sorted by
|s|: :math:`\omega_{n,r} = |s_r|`, :math:`\zeta_r = -\mathrm{Re}\,s_r / |s_r|`, and the
complex shape is the displacement part of z, scaled to a largest entry of 1. For
classical (e.g. Rayleigh) damping these are the undamped shapes and
:math:`\zeta_r = c_r / (2 \omega_r)`, :math:`c_r = \phi_r^T C \phi_r`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn._engine import linalg, validate

__all__ = ["Modes", "mck_modes"]


@dataclass(frozen=True)
class Modes:
    """The result of `mck_modes`, `beam_modes` and `shaft_modes`; mode r is column r, sorted
    by frequency.

    Attributes
    ----------
    omega : (m,) ndarray
        Natural frequencies, rad/s (``frequency_hz`` and ``period`` derive from it).
    shapes : (n, m) ndarray
        Mass-normalized shapes, each with its largest-magnitude entry positive.
    influence : (n,) ndarray
        The influence vector r.
    participation, effective_mass : (m,) ndarray
        Gamma_r = phi_r^T M r and m_eff,r = Gamma_r^2.
    total_mass : float
        r^T M r: the effective masses of all modes sum to it.
    damping_ratio, omega_d : (m,) ndarray or None
        With C: zeta_r = -Re s_r / |s_r| and the damped natural frequency
        omega_d,r = Im s_r = omega_n,r sqrt(1 - zeta_r^2), rad/s.
    poles : (m,) complex ndarray or None
        With C: s_r, Im s_r > 0.
    complex_shapes : (n, m) complex ndarray or None
        With C: the displacement part of the damped eigenvectors, largest entry 1.
    dof_names : tuple of str or None
        The rows' DOF names, for models that name them (`shaft_modes`, `beam_modes`).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = dd.chain_matrices([1.0, 1.0], [2.0, 1.0], [0.1, 0.1])
    >>> m = dd.mck_modes(M, C, K)
    >>> m.shapes.shape, bool(np.all(m.damping_ratio > 0))
    ((2, 2), True)
    """

    omega: np.ndarray
    shapes: np.ndarray
    influence: np.ndarray
    participation: np.ndarray
    effective_mass: np.ndarray
    total_mass: float
    damping_ratio: np.ndarray | None = None
    omega_d: np.ndarray | None = None
    poles: np.ndarray | None = None
    complex_shapes: np.ndarray | None = None
    dof_names: tuple | None = None

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2.0 * np.pi)

    @property
    def damped_omega(self) -> np.ndarray | None:
        """Deprecated: |s_r| (the natural frequency of the damped mode, not Im s_r); use
        `omega_d` (= Im s_r) or ``abs(poles)``."""
        from dtdyn._engine.public import warn
        warn("Modes.damped_omega (|s|) is deprecated: use Modes.omega_d (the damped frequency "
             "Im s) or abs(Modes.poles)", DeprecationWarning)
        return None if self.poles is None else np.abs(self.poles)

    @property
    def period(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return 2.0 * np.pi / self.omega

    @property
    def effective_mass_ratio(self) -> np.ndarray:
        """m_eff,r / (r^T M r): the share of the total mass each mode carries."""
        return self.effective_mass / self.total_mass

    def to_dict(self) -> dict:
        """Plain lists (JSON): frequencies, shapes by mode, participation, effective masses and,
        with damping, ratios and poles (as [re, im])."""
        out = {"omega_rad_s": self.omega.tolist(), "frequency_hz": self.frequency_hz.tolist(),
               "shapes": self.shapes.T.tolist(), "influence": self.influence.tolist(),
               "participation": self.participation.tolist(),
               "effective_mass": self.effective_mass.tolist(), "total_mass": self.total_mass}
        if self.damping_ratio is not None:
            out["damping_ratio"] = self.damping_ratio.tolist()
            out["omega_d_rad_s"] = self.omega_d.tolist()
            out["poles"] = [[p.real, p.imag] for p in self.poles]
        if self.dof_names is not None:
            out["dof_names"] = list(self.dof_names)
        return out


def mck_modes(M, C, K, *, count=None, influence=None) -> Modes:
    """Natural frequencies, mass-normalized shapes, participation factors and effective masses
    (module docstring), with damping ratios and complex modes when ``C`` is given.

    Parameters
    ----------
    M : (n, n) array_like or scipy.sparse matrix
        Mass matrix (symmetric positive definite).
    C : (n, n) array_like or None
        Damping, or None for the undamped modes only. Given, it adds ``damping_ratio``,
        ``omega_d``, ``poles`` and ``complex_shapes`` (dense; the first-order eigenproblem of
        size 2n).
    K : (n, n) array_like or scipy.sparse matrix
        Stiffness matrix (symmetric).
    count : int, optional
        The lowest ``count`` modes (all by default). Sparse M and K: shift-invert about 0 (count
        is then required and < n).
    influence : (n,) array_like, optional
        The influence vector r (default: ones, every DOF moves with the support).

    Returns
    -------
    Modes

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = dd.chain_matrices([1.0, 1.0], [2.0, 1.0], [0.0, 0.0])
    >>> m = dd.mck_modes(M, None, K)
    >>> np.round(m.omega ** 2, 6)          # K phi = omega^2 M phi: 2 -+ sqrt(2)
    array([0.585786, 3.414214])
    >>> round(float(m.effective_mass.sum()), 12)   # = the total mass, 2 kg
    2.0
    """
    sparse = sps.issparse(M) or sps.issparse(K)
    # M in C's place (checked as M first): an error in K names K, not C
    M, _, K = linalg.mck(M, M, K, keep_sparse=sparse)
    n = M.shape[0]
    _check_symmetric("K", K)
    if count is not None:
        count = validate.step_count("count", count)
        if count > n:
            raise ValueError(f"count = {count} exceeds the {n} DOFs of the model")
    r = np.ones(n) if influence is None else validate.vector("influence", influence, length=n)
    lam, phi = _undamped(M, K, count, sparse)
    if lam.min() < -1e-9 * max(abs(lam).max(), 1e-300):
        raise ValueError(f"K is not positive semi-definite: omega^2 = {lam.min():.6g} < 0 (a "
                         "mode that grows; modes needs a stable structure)")
    omega = np.sqrt(np.clip(lam, 0.0, None))
    big = np.argmax(np.abs(phi), axis=0)
    phi = phi * np.sign(phi[big, np.arange(phi.shape[1])])
    Mr = M @ r
    gamma = phi.T @ Mr
    extra = {}
    if C is not None:
        if sparse:
            raise ValueError("C with sparse M and K: the damped modes need dense matrices "
                             "(pass M.toarray(), ...) or leave C out")
        extra = _damped(M, linalg.square_matrix("C", C, n), K, omega.size)
    return Modes(omega=omega, shapes=phi, influence=r, participation=gamma,
                 effective_mass=gamma**2, total_mass=float(r @ Mr), **extra)


def _check_symmetric(name, A) -> None:
    asym = abs(A - A.T).max()
    scale = abs(A).max()
    if asym > linalg.SYM_TOL * scale:
        raise ValueError(f"{name} is not symmetric (max |{name} - {name}^T| = {asym:.3g}): the "
                         "undamped modes need symmetric M and K; use modal_model for general "
                         "matrices")


def _undamped(M, K, count, sparse):
    """(omega^2, Phi) sorted ascending, Phi^T M Phi = I."""
    n = M.shape[0]
    if sparse:
        if count is None or count >= n:
            raise ValueError(f"sparse M and K: give count < {n} (the lowest modes by "
                             "shift-invert), or pass dense matrices for all modes")
        try:
            lam, phi = spla.eigsh(sps.csc_matrix(K), k=count, M=sps.csc_matrix(M), sigma=0.0,
                                  which="LM")
        except (RuntimeError, spla.ArpackError) as exc:
            raise ValueError(f"the sparse eigenproblem failed ({exc}); a singular K needs a "
                             "rigid-body-free model for shift-invert about 0") from None
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        # eigsh's vectors are M-orthonormal to its tolerance: normalize exactly
        phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))
        return lam, phi
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise ValueError("M is not positive definite (a DOF without mass?): the modes need "
                         "every DOF to carry mass; condense the massless DOFs first") from None
    sel = {} if count is None else {"subset_by_index": [0, count - 1]}
    return sla.eigh(K, M, **sel)


def _damped(M, C, K, m):
    """Damping ratios, Im s and complex shapes of the m lowest underdamped modes."""
    n = M.shape[0]
    # scaled variables z = [q; q' / w0], the equations divided by mu: the blocks of A and B are
    # of order 1, which keeps the eigenvalues' relative error near eps (1e-8 unscaled on a
    # building with M ~ 1e5 and K ~ 1e8)
    mu = float(np.abs(np.diag(M)).max())
    w0 = float(np.sqrt(np.abs(np.diag(K)).max() / mu)) or 1.0
    Z0, eye = np.zeros((n, n)), np.eye(n)
    A = np.block([[Z0, w0 * eye], [-K / mu, -(w0 / mu) * C]])
    B = np.block([[eye, Z0], [Z0, (w0 / mu) * M]])
    s, Z = sla.eig(A, B)
    keep = np.flatnonzero(np.isfinite(s) & (s.imag > 0))
    keep = keep[np.argsort(np.abs(s[keep]))][:m]
    if keep.size < m:
        raise ValueError(f"C: only {keep.size} of the {m} modes are underdamped (oscillatory): "
                         "complex modes need Im s > 0; the others are overdamped")
    s = s[keep]
    psi = Z[:n, keep]
    psi = psi / psi[np.argmax(np.abs(psi), axis=0), np.arange(keep.size)]
    return {"damping_ratio": -s.real / np.abs(s), "omega_d": s.imag, "poles": s,
            "complex_shapes": psi}
