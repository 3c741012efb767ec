"""Modal models (poles and residues) of M q'' + C q' + K q = f, for the modal digital filters.

Ahlin, Josefsson & Magnevall, modal digital filters. The displacement receptance from the
input DOFs to the output DOFs is the partial-fraction sum

    H(s) = sum over oscillatory modes r of  R_r/(s - s_r) + conj(R_r)/(s - conj(s_r))
         + sum over real (overdamped) poles p of  R_p/(s - p)

with s_r = sigma_r + j omega_r (omega_r > 0) and R_r of shape (n_outputs, n_inputs).

General (non-proportional) damping: the first-order form with z = [q; q'],

    B z' = A z + [0; f],   A = [[0, I], [-K, -C]],   B = [[I, 0], [0, M]],

so that (s B - A) Z(s) = [0; F(s)] and H(s) is the (q, f) block of (s B - A)^-1. With the right
eigenvectors Psi (A Psi = B Psi S) and the left ones Phi (Phi^H A = S Phi^H B) of the pencil,
Phi^H A Psi = G S with G = Phi^H B Psi, hence Phi^H (s B - A) Psi = G (s I - S) and

    (s B - A)^-1 = Psi (s I - S)^-1 G^-1 Phi^H,   R_r = psi_r[q_out] (G^-1 Phi^H)[r, n + in].

For distinct eigenvalues G is diagonal, G = diag(a_r), a_r = phi_r^H B psi_r, and this is the
familiar R_r = psi_r[q_out] conj(phi_r[n + in]) / a_r; solving with the whole G also covers
repeated (semisimple) eigenvalues, e.g. identical uncoupled oscillators, whose left and right
eigenvectors LAPACK does not make B-biorthogonal.

Numerics: the pencil is solved in scaled variables (time scaled by Omega = sqrt(|K|/|M|), the
velocity equation divided by |M|), which leaves the poles s = Omega s~ and residues unchanged in
exact arithmetic but makes the blocks of A and B of comparable size: on the 15-DOF P3 chain it
improves the undamped frequencies from ~5e-13 to ~1e-14 relative and the modal FRF from ~2e-10
to ~3e-12.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from dtdyn._engine import linalg
from dtdyn._engine import validate
from dtdyn._engine.errors import DtdynAccuracyWarning
from dtdyn._engine.public import warn

#: a pole with |s| below this times max |s| is a rigid-body (zero) pole
ZERO_POLE_TOLERANCE = 1e-8
#: real parts up to this times |s| (eigensolver round-off of an undamped mode) count as undamped
UNDAMPED_TOLERANCE = 1e-12
#: estimated relative error eps * kappa^2 (kappa: worst eigenvalue condition number) of the modal
#: sum above which modal_model warns, and above which it refuses (defective eigenvalue)
WARN_ERROR, REFUSE_ERROR = 1e-8, 1e-3

QUANTITY_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}
#: the vocabulary's quantity names ("x", "v", "a") and the long names used inside the modal code
QUANTITY_NAMES = {"x": "displacement", "v": "velocity", "a": "acceleration"}


def quantity_name(quantity) -> str:
    """"displacement", "velocity" or "acceleration" for ``quantity`` given as "x", "v", "a" (or
    already in long form); ValueError naming the value otherwise."""
    if isinstance(quantity, str):
        if quantity in QUANTITY_NAMES:
            return QUANTITY_NAMES[quantity]
        if quantity in QUANTITY_POWER:
            return quantity
    raise ValueError(f"quantity must be one of 'x', 'v', 'a' (displacement, velocity, "
                     f"acceleration), got {quantity!r}")


def _index_array(name: str, values, n: int | None, what: str) -> np.ndarray:
    """Unique non-negative integer indices (below ``n`` when given), as int64."""
    idx = np.atleast_1d(np.asarray(values))
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"{name} must be a non-empty sequence of integer {what} indices, "
                         f"got {values!r}")
    if idx.min() < 0 or (n is not None and idx.max() >= n):
        where = f"0..{n - 1}" if n is not None else ">= 0"
        raise ValueError(f"{name} = {idx.tolist()} has an index outside {where}")
    if np.unique(idx).size != idx.size:
        raise ValueError(f"{name} = {idx.tolist()} repeats an index")
    return idx.astype(np.int64)


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr)  # own copy
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class ModalModel:
    """Poles and residues of the displacement receptance x_out / F_in (module docstring).

    Attributes
    ----------
    poles : complex ndarray, shape (n_modes,)
        One pole per mode, sorted by |s| ascending: the pole with Im > 0 of an oscillatory mode
        (its conjugate is implied), the real value (imaginary part 0) of a real pole.
    residues : complex ndarray, shape (n_modes, n_outputs, n_inputs)
        R_r of each pole (real, i.e. imaginary part 0, for a real pole).
    oscillatory : bool ndarray, shape (n_modes,)
        True where the mode is a conjugate pair (Im s_r > 0).
    force_dofs, outputs : int64 ndarray
        0-based DOF indices of the force inputs and the displacement outputs.

    Construct with `modal_model` (from M, C, K) or `from_poles_residues` (experimental data);
    direct construction validates but does not sort. The arrays are read-only copies.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.modal_model(np.eye(1), 0.2 * np.eye(1), 4.0 * np.eye(1))
    >>> model.poles
    array([-0.1+1.99749844j])
    """

    poles: np.ndarray
    residues: np.ndarray
    oscillatory: np.ndarray
    force_dofs: np.ndarray
    outputs: np.ndarray

    def __post_init__(self):
        inputs = _index_array("force_dofs", self.force_dofs, None, "DOF")
        outputs = _index_array("outputs", self.outputs, None, "DOF")
        poles = np.asarray(self.poles)
        if poles.ndim != 1 or poles.size == 0 or not np.issubdtype(poles.dtype, np.number):
            raise ValueError("poles must be a non-empty 1-D numeric array, "
                             f"got shape {poles.shape}")
        poles = poles.astype(complex)
        n_modes = poles.size
        residues = np.asarray(self.residues)
        want = (n_modes, outputs.size, inputs.size)
        if not np.issubdtype(residues.dtype, np.number) or residues.shape != want:
            raise ValueError(f"residues has shape {residues.shape}, expected (n_modes, n_outputs, "
                             f"n_inputs) = {want}")
        residues = residues.astype(complex)
        osc = np.asarray(self.oscillatory)
        if osc.dtype != bool or osc.shape != (n_modes,):
            raise ValueError(f"oscillatory must be a boolean array of shape {(n_modes,)}, got "
                             f"{osc.dtype} {osc.shape}")
        _check_poles(poles)
        bad = np.flatnonzero(osc != (poles.imag > 0))
        if bad.size:
            r = int(bad[0])
            raise ValueError(f"oscillatory[{r}] = {bool(osc[r])} but poles[{r}] = {poles[r]!r}: a "
                             "mode is oscillatory exactly when its pole has Im > 0")
        if not np.isfinite(residues).all():
            r, o, i = np.argwhere(~np.isfinite(residues))[0]
            raise ValueError(f"residues[{r}, {o}, {i}] = {residues[r, o, i]!r} is not finite")
        real_bad = np.flatnonzero(~osc & np.any(residues.imag != 0, axis=(1, 2)))
        if real_bad.size:
            r = int(real_bad[0])
            raise ValueError(f"residues[{r}] has a non-zero imaginary part, but poles[{r}] = "
                             f"{poles[r].real!r} is real: a real pole needs a real residue")
        freq = np.abs(poles)
        if np.any(np.diff(freq) < 0):
            r = int(np.flatnonzero(np.diff(freq) < 0)[0])
            raise ValueError(f"poles must be sorted by |s| ascending: |poles[{r}]| = {freq[r]:.6g}"
                             f" > |poles[{r + 1}]| = {freq[r + 1]:.6g} (from_poles_residues sorts)")
        for name, value in (("poles", poles), ("residues", residues), ("oscillatory", osc),
                            ("force_dofs", inputs), ("outputs", outputs)):
            object.__setattr__(self, name, _frozen(value))

    @property
    def n_modes(self) -> int:
        return int(self.poles.size)

    @property
    def omega(self) -> np.ndarray:
        """Natural frequencies omega_n,r = |s_r| in rad/s (ascending)."""
        return np.abs(self.poles)

    @property
    def omega_d(self) -> np.ndarray:
        """Damped natural frequencies omega_d,r = Im s_r in rad/s (0 for a real pole)."""
        return self.poles.imag.copy()

    @property
    def damping_ratio(self) -> np.ndarray:
        """-Re s_r / |s_r| (1 for a real pole; ~0 or roughly -1e-16 for an undamped mode)."""
        return -self.poles.real / np.abs(self.poles)

    @property
    def frequencies(self) -> np.ndarray:
        """Deprecated name of `omega` (rad/s)."""
        warn("ModalModel.frequencies is now ModalModel.omega (rad/s)", DeprecationWarning)
        return self.omega

    @property
    def damping_ratios(self) -> np.ndarray:
        """Deprecated name of `damping_ratio`."""
        warn("ModalModel.damping_ratios is now ModalModel.damping_ratio", DeprecationWarning)
        return self.damping_ratio

    def select(self, modes) -> ModalModel:
        """The model with only ``modes`` (indices into the sorted modes, kept in sorted order)."""
        idx = np.sort(_index_array("modes", modes, self.n_modes, "mode"))
        return ModalModel(self.poles[idx], self.residues[idx], self.oscillatory[idx],
                          self.force_dofs, self.outputs)

    def frequency_response(self, omega, quantity: str = "x") -> np.ndarray:
        """The truncated modal sum at s = j omega: complex array (len(omega), n_out, n_in).

        ``quantity`` "velocity" multiplies the displacement receptance by s, "acceleration" by
        s^2. No residual terms for the modes left out. At an undamped pole the result is inf.
        """
        quantity = quantity_name(quantity)
        omega = validate.vector("omega", np.atleast_1d(np.asarray(omega, dtype=float)))
        s = 1j * omega[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            g = 1.0 / (s - self.poles[None, :])
            gc = np.where(self.oscillatory[None, :], 1.0 / (s - np.conj(self.poles)[None, :]), 0)
            H = (np.einsum("fr,roi->foi", g, self.residues)
                 + np.einsum("fr,roi->foi", gc, np.conj(self.residues)))
            return H * s[:, :, None] ** QUANTITY_POWER[quantity]


def _check_poles(poles: np.ndarray) -> None:
    """Finite, no pole at 0, none with Re s > 0 (beyond round-off), none with Im s < 0."""
    bad = np.flatnonzero(~np.isfinite(poles))
    if bad.size:
        raise ValueError(f"poles[{int(bad[0])}] = {poles[bad[0]]!r} is not finite")
    zero = np.flatnonzero(poles == 0)
    if zero.size:
        raise ValueError(f"poles[{int(zero[0])}] = 0: rigid-body mode(s) ({zero.size} pole(s) at "
                         "s = 0) are not supported by the modal filters")
    unstable = np.flatnonzero(poles.real > UNDAMPED_TOLERANCE * np.abs(poles))
    if unstable.size:
        r = int(unstable[0])
        raise ValueError(f"unstable pole poles[{r}] = {poles[r]!r}: Re s > 0 (undamped poles, "
                         "Re s = 0, are allowed)")
    neg = np.flatnonzero(poles.imag < 0)
    if neg.size:
        r = int(neg[0])
        raise ValueError(f"poles[{r}] = {poles[r]!r} has Im s < 0: give each oscillatory mode once,"
                         " by its pole with Im s > 0 (the conjugate pole and residue are implied)")


def from_poles_residues(poles, residues, force_dofs=(0,), outputs=(0,)) -> ModalModel:
    """A ModalModel from poles and residues (e.g. identified from measured FRFs).

    Parameters
    ----------
    poles : (n_modes,) complex array_like
        Per oscillatory mode its pole with Im s > 0; per real pole its real value. Re s <= 0
        (undamped modes, Re s = 0, are allowed); s = 0 and Re s > 0 are refused.
    residues : (n_modes, n_outputs, n_inputs) complex array_like
        Displacement-receptance residues (module docstring); shape (n_modes,) for one input
        and one output. A real pole's must be real (an imaginary part up to 1e-12 of its
        magnitude is dropped as round-off).
    force_dofs, outputs : sequence of int
        0-based DOF labels of the inputs (loaded DOFs) and outputs.

    Returns
    -------
    ModalModel
        The modes sorted by |s| ascending (stable).

    Examples
    --------
    >>> import dtdyn as dd
    >>> model = dd.from_poles_residues([-0.1 + 10j], [-0.05j])    # one measured mode
    >>> round(float(model.omega[0]), 4)
    10.0005
    """
    inputs = _index_array("force_dofs", force_dofs, None, "DOF")
    outputs = _index_array("outputs", outputs, None, "DOF")
    try:
        p = np.atleast_1d(np.asarray(poles, dtype=complex))
    except (TypeError, ValueError):
        raise ValueError(f"poles must be numeric, got {poles!r}") from None
    if p.ndim != 1 or p.size == 0:
        raise ValueError(f"poles must be a non-empty 1-D sequence, got shape {p.shape}")
    try:
        R = np.asarray(residues, dtype=complex)
    except (TypeError, ValueError):
        raise ValueError(f"residues must be numeric, got {type(residues).__name__}") from None
    if R.ndim == 1 and R.shape == (p.size,) and inputs.size == outputs.size == 1:
        R = R[:, None, None]
    want = (p.size, outputs.size, inputs.size)
    if R.shape != want:
        raise ValueError(f"residues has shape {R.shape}, expected (n_modes, n_outputs, n_inputs) "
                         f"= {want}" + (" or (n_modes,)" if want[1:] == (1, 1) else ""))
    _check_poles(p)
    if not np.isfinite(R).all():
        r, o, i = np.argwhere(~np.isfinite(R))[0]
        raise ValueError(f"residues[{r}, {o}, {i}] = {R[r, o, i]!r} is not finite")
    R = R.copy()
    for r in np.flatnonzero(p.imag == 0):
        size = np.abs(R[r]).max()
        if np.abs(R[r].imag).max() > 1e-12 * size:
            raise ValueError(f"residues[{r}] is complex but poles[{r}] = {p[r].real!r} is real: a "
                             "real pole needs a real residue")
        R[r] = R[r].real
    order = np.argsort(np.abs(p), kind="stable")
    return ModalModel(p[order], R[order], p[order].imag > 0, inputs, outputs)


def modal_model(M, C, K, force_dofs=None, outputs=None, modes=None) -> ModalModel:
    """Poles and displacement-receptance residues of M q'' + C q' + K q = f (general damping).

    Parameters
    ----------
    M, C, K : (n, n) array_like (scipy.sparse is densified)
        Mass (nonsingular), damping, stiffness; need not be symmetric or proportional.
    force_dofs, outputs : sequence of int or None
        0-based force and displacement DOFs (None: all DOFs).
    modes : sequence of int, optional
        Keep only these modes (indices into the modes sorted by |s_r|), as ModalModel.select.

    Returns
    -------
    ModalModel
        All 2n poles: a conjugate pair gives one oscillatory mode, each real pole (overdamped)
        one mode of its own.

    Raises
    ------
    ValueError
        M singular; a rigid-body mode (pole at s = 0, or K numerically singular); a defective
        eigenvalue (e.g. an exactly critically damped mode: a double pole the partial-fraction
        sum cannot represent); an unstable pole.

    Notes
    -----
    The generalized eigenproblem A z = s B z is solved by scipy.linalg.eig with left and right
    eigenvectors, in scaled variables; residues as in the module docstring. O((2n)^3).
    A conditioning estimate eps * kappa^2 (kappa = the largest eigenvalue condition number) of
    the modal sum's relative error gives a DtdynAccuracyWarning above 1e-8 (a nearly critically
    damped mode) and a ValueError above 1e-3.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.modal_model(np.eye(2), 0.01 * np.eye(2), np.array([[2.0, -1.0], [-1.0, 1.0]]),
    ...                        force_dofs=[1], outputs=[0, 1])
    >>> model.n_modes, np.round(model.omega, 4)
    (2, array([0.618, 1.618]))
    """
    M, C, K = linalg.mck(M, C, K)
    n = M.shape[0]
    inputs = validate.dof_indices("force_dofs", force_dofs, n)
    outputs = validate.dof_indices("outputs", outputs, n)
    s, Psi_q, X_f = modal_factors(M, C, K)
    R_all = np.einsum("or,ri->roi", Psi_q[outputs], X_f[:, inputs])

    keep, osc = _pair_poles(s)
    poles = s[keep].copy()
    R = R_all[keep]
    poles[~osc] = poles[~osc].real
    R[~osc] = R[~osc].real  # a real eigenpair of a real pencil has real vectors
    order = np.argsort(np.abs(poles), kind="stable")
    model = ModalModel(poles[order], R[order], osc[order], inputs, outputs)
    return model if modes is None else model.select(modes)


def modal_factors(M, C, K, initial: bool = False):
    """All 2n poles s_r and rank-one residue factors of M q'' + C q' + K q = f.

    Returns (s, Psi_q, X_f) with H(s) = sum_r Psi_q[:, r] X_f[r, :] / (s - s_r) over all 2n
    eigenvalues (conjugates included), i.e. R_r = outer(Psi_q[:, r], X_f[r, :]); the velocity
    part of the eigenvector is s_r Psi_q[:, r]. Same checks as `modal_model` (module docstring).
    ``initial``: also X_x, so that the modal coordinates of a state (q, q') are
    eta = X_x q + X_f M q' (the left eigenvectors applied to B z).
    """
    M, C, K = linalg.mck(M, C, K)
    n = M.shape[0]
    linalg.solver(M, "M", "the modal model needs a nonsingular mass matrix (no massless DOFs)")

    # scaled pencil: s = Omega s~, velocity w = q'/Omega, velocity equation divided by mu
    mu = np.linalg.norm(M, 1)
    k_norm = np.linalg.norm(K, 1)
    omega_s = np.sqrt(k_norm / mu) if k_norm > 0 else 1.0
    I, Z = np.eye(n), np.zeros((n, n))
    A = np.block([[Z, I], [-K / (omega_s**2 * mu), -C / (omega_s * mu)]])
    B = np.block([[I, Z], [Z, M / mu]])
    s_t, Phi, Psi = sla.eig(A, B, left=True, right=True)
    if not np.isfinite(s_t).all():
        raise ValueError("the eigenproblem has infinite or undefined eigenvalues: M, C, K give a "
                         "singular pencil")
    s = omega_s * s_t

    _check_rigid_body(s, K)

    G = Phi.conj().T @ B @ Psi
    try:
        X = np.linalg.solve(G, Phi.conj().T)  # rows: left eigenvectors with X B Psi = I
    except np.linalg.LinAlgError:
        raise ValueError("defective eigenvalue (e.g. an exactly critically damped mode): the "
                         "partial-fraction modal sum cannot represent a double pole") from None
    kappa = np.max(np.linalg.norm(X, axis=1) * np.linalg.norm(B @ Psi, axis=0))
    estimate = np.finfo(float).eps * kappa**2
    if not np.isfinite(estimate) or estimate > REFUSE_ERROR:
        raise ValueError(f"defective or nearly defective eigenvalue (eigenvalue condition number "
                         f"{kappa:.3g}, e.g. an exactly critically damped mode): the partial-"
                         "fraction modal sum cannot represent a double pole")
    if estimate > WARN_ERROR:
        warn(f"nearly defective eigenvalue (condition number {kappa:.3g}, e.g. a nearly "
             f"critically damped mode): modal sum relative error ~{estimate:.1e}",
             DtdynAccuracyWarning)
    # H(s) = (1/(Omega^2 mu)) sum psi~ x~ / (s~ - s~_r) = sum psi~ x~ / (Omega mu (s - s_r))
    if initial:  # eta = X B~ z~, z~ = [q; q' / Omega], B~ = diag(I, M / mu)
        return s, Psi[:n], X[:, n:] / (omega_s * mu), X[:, :n]
    return s, Psi[:n], X[:, n:] / (omega_s * mu)


def _check_rigid_body(s: np.ndarray, K: np.ndarray) -> None:
    """ValueError for poles at s = 0 (|s| < 1e-8 max |s|, or K numerically singular)."""
    n = K.shape[0]
    smax = np.abs(s).max()
    zero = np.abs(s) < ZERO_POLE_TOLERANCE * smax
    sv = np.linalg.svd(K, compute_uv=False)
    null = int(np.sum(sv <= n * np.finfo(float).eps * sv[0])) if sv[0] > 0 else n
    if not zero.any() and null == 0:
        return
    if not zero.any():
        # an undamped rigid-body mode is a double zero pole that round-off splits by ~sqrt(eps)
        zero = np.abs(s) < np.sqrt(n * np.finfo(float).eps) * 100 * smax
    raise ValueError(f"rigid-body mode(s) are not supported by the modal filters: {int(zero.sum())}"
                     f" pole(s) at s = 0 (|s| < {ZERO_POLE_TOLERANCE:g} max|s| = {smax:.4g} rad/s,"
                     f" or K singular: {null} null direction(s) of K); constrain the structure or "
                     "add a ground spring")


def _pair_poles(s: np.ndarray):
    """(indices to keep, oscillatory flags): the Im > 0 member of each conjugate pair, each real
    pole (LAPACK returns real eigenvalues of a real pencil with Im exactly 0)."""
    real = np.flatnonzero(s.imag == 0)
    pos = np.flatnonzero(s.imag > 0)
    neg = list(np.flatnonzero(s.imag < 0))
    if len(neg) != pos.size:
        raise ValueError(f"eigenvalues not in conjugate pairs: {pos.size} with Im > 0, {len(neg)} "
                         "with Im < 0")
    scale = np.abs(s).max()
    for r in pos:
        j = int(np.argmin(np.abs(s[neg] - np.conj(s[r]))))
        if abs(s[neg[j]] - np.conj(s[r])) > 1e-8 * scale:
            raise ValueError(f"pole {s[r]!r} has no conjugate partner among the eigenvalues")
        neg.pop(j)
    keep = np.concatenate([pos, real]).astype(np.int64)
    osc = np.concatenate([np.ones(pos.size, bool), np.zeros(real.size, bool)])
    return keep, osc
