r"""Mode shapes and frequency responses of beams over the 2 x 2 node blocks.

Both solve :math:`Z(s) u = f` with :math:`Z(s) = K + s C + s^2 M` block tridiagonal in 2 x 2
node blocks :math:`D_i` (node i with itself) and :math:`E_i` (node i with node i + 1). The
block Riccati sweep of `beam_response`, in the frequency domain, runs from the free (right) end

.. math::

    P_N = D_N, \quad P_i = D_i - E_i P_{i+1}^{-1} E_i^T, \qquad
    y_N = f_N, \quad y_i = f_i - E_i P_{i+1}^{-1} y_{i+1},

then :math:`u_0 = P_0^{-1} y_0`, :math:`u_{i+1} = P_{i+1}^{-1} (y_{i+1} - E_i^T u_i)`: O(N) per
value of s. A held DOF has the identity's row and column. :math:`P_i` is the dynamic stiffness
of nodes i .. N condensed onto node i, the matrix form of the Riccati relation f = S u + R.
The sweep eliminates without pivoting: at an s inside the spectrum of an undamped beam it can
meet a small pivot (element growth; about 20 eps cond(Z) on a 40-element pinned-pinned beam
next to its resonances, `python benchmarks/vector_state_figures.py`). So the receptance and the
last step of each shape use LAPACK's banded LU with partial pivoting on the same blocks
(`scipy.linalg.solve_banded`: backward stable, also O(N)).

Mode shapes: inverse iteration with the sweep at each Wittrick-Williams root
(`dtdyn.linear._sweep_modes`), then one more step by the pivoted banded LU, which leaves the
residual ||K phi - rho M phi|| at rounding level (`python benchmarks/vector_state_figures.py`
prints the residuals of both).

With ``exact=True`` every element enters by its exact dynamic stiffness (from the field matrix
exp(A L) of dtdyn.derive.beam, `generated/beam.md`) instead of :math:`K_e - \omega^2 M_e`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from dtdyn._engine import linalg, validate
from dtdyn._engine.frf import receptance_matrix
from dtdyn._engine.twofold import split, two_prod, two_sum
from dtdyn._engine.public import public
from dtdyn.generated import beam as derived
from dtdyn.linear import _sweep_modes as sweep_modes
from dtdyn.linear._beam import Beam, beam_frequencies, beam_matrices, rigid_translation
from dtdyn.modal._modes import Modes

__all__ = ["beam_modes", "beam_frequency_response"]


def _check_beam(beam):
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")


def _held(beam: Beam) -> np.ndarray:
    held = np.ones(2 * (beam.elements + 1), dtype=bool)
    held[beam.free] = False
    return held.reshape(-1, 2)


def _inverse(P, detmin):
    """Batched 2 x 2 inverses by the adjugate; a determinant below detmin set to detmin."""
    det = P[..., 0, 0] * P[..., 1, 1] - P[..., 0, 1] * P[..., 1, 0]
    det = np.where(np.abs(det) < detmin, detmin, det)
    adj = np.stack([np.stack([P[..., 1, 1], -P[..., 0, 1]], -1),
                    np.stack([-P[..., 1, 0], P[..., 0, 0]], -1)], -2)
    return adj / det[..., None, None]


def _masked(D, E, held, f):
    """The blocks and loads with each held DOF's row and column replaced by the identity's."""
    keep = ~held
    D = D * keep[None, :, :, None] * keep[None, :, None, :]
    D = D + np.eye(2)[None, None] * held[None, :, :, None] * np.eye(2)[None, None]
    E = E * keep[None, :-1, :, None] * keep[None, 1:, None, :]
    return D, E, f * keep[None]


def banded_solve(D, E, held, f):
    """u of the same block tridiagonal systems as `block_sweep`, by LAPACK's banded LU with
    partial pivoting (backward stable; O(N) per system), one system per leading index; a
    singular system (a resonance of an undamped model, to the bit) gives NaN."""
    D, E, f = _masked(D, E, held, f)
    k, nodes = D.shape[0], D.shape[1]
    ab = np.zeros((k, 7, 2 * nodes), dtype=np.result_type(D, E, f))
    i = np.arange(nodes)
    for a in range(2):
        for b in range(2):  # ab[3 + r - c, c] = A[r, c], r = 2 i + a (node i, DOF a)
            ab[:, 3 + a - b, 2 * i + b] = D[:, :, a, b]
            ab[:, 1 + a - b, 2 * i[:-1] + 2 + b] = E[:, :, a, b]
            ab[:, 5 + b - a, 2 * i[:-1] + a] = E[:, :, a, b]
    u = np.full((k, 2 * nodes), np.nan, dtype=ab.dtype)
    for j in range(k):
        try:
            u[j] = sla.solve_banded((3, 3), ab[j], f[j].reshape(-1), check_finite=False)
        except np.linalg.LinAlgError:
            pass
    return u.reshape(k, nodes, 2) * ~held[None]


def block_sweep(D, E, held, f, detmin=0.0):
    """u of the block tridiagonal system (module docstring), batched over the leading axis:
    D (k, nodes, 2, 2), E (k, nodes - 1, 2, 2), f (k, nodes, 2); held (nodes, 2)."""
    keep = ~held
    D, E, f = _masked(D, E, held, f)
    nodes = D.shape[1]
    Pinv = np.empty_like(D)
    y = np.empty_like(f)
    Pinv[:, -1] = _inverse(D[:, -1], detmin)
    y[:, -1] = f[:, -1]
    for i in range(nodes - 2, -1, -1):
        G = E[:, i] @ Pinv[:, i + 1]
        Pinv[:, i] = _inverse(D[:, i] - G @ np.swapaxes(E[:, i], -1, -2), detmin)
        y[:, i] = f[:, i] - (G @ y[:, i + 1, :, None])[..., 0]
    u = np.empty_like(f)
    u[:, 0] = (Pinv[:, 0] @ y[:, 0, :, None])[..., 0]
    for i in range(nodes - 1):
        rhs = y[:, i + 1] - (np.swapaxes(E[:, i], -1, -2) @ u[:, i, :, None])[..., 0]
        u[:, i + 1] = (Pinv[:, i + 1] @ rhs[..., None])[..., 0]
    return u * keep[None]


def beam_modes(beam: Beam, count=None, below=None) -> Modes:
    """Natural frequencies and mass-normalized mode shapes of a `Beam` (the model of
    `beam_matrices`), from the block Riccati sweep.

    The frequencies are `beam_frequencies` (the Wittrick-Williams count). Each shape is two
    steps of inverse iteration with the sweep's O(N) solve of (K - omega_r^2 M) u = M u_k at the
    root itself (close or repeated roots together, by Rayleigh-Ritz on their subspace:
    `dtdyn.linear._sweep_modes`) and, for an isolated root, a third by the pivoted banded LU
    (module docstring); scaled to phi^T M phi = 1 with its largest entry positive.

    Parameters
    ----------
    beam : Beam
    count : int, optional
        The lowest ``count`` modes (default: all ``beam.n_dof``).
    below : float, optional
        Every mode below this frequency (rad/s).

    Returns
    -------
    Modes
        ``omega`` (rad/s), ``shapes`` (n_dof, m) over ``dof_names`` ([w_i, psi_i] node by node,
        as `beam_matrices`), the influence r = `rigid_translation` (1 on every w, 0 on every
        psi), participation factors phi^T M r and effective masses.

    Examples
    --------
    >>> import dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=50)
    >>> m = dd.beam_modes(beam, count=3)
    >>> m.shapes.shape, m.dof_names[-2:]
    ((100, 3), ('w50', 'psi50'))
    """
    _check_beam(beam)
    w = beam_frequencies(beam, count=count, below=below)
    M, _, K = beam_matrices(beam)
    Mg, _, Kg = beam.global_matrices()
    DK, EK, _ = linalg.node_blocks(Kg)
    DM, EM, _ = linalg.node_blocks(Mg)
    held = _held(beam)
    detmin = (np.finfo(float).eps * float(np.abs(DK).max())) ** 2
    nodes, free = beam.elements + 1, beam.free

    def solve(lam, F):
        L = lam[:, None, None, None]
        full = np.zeros((lam.size, 2 * nodes))
        full[:, free] = F.T
        u = block_sweep(DK[None] - L * DM[None], EK[None] - L * EM[None], held,
                        full.reshape(lam.size, nodes, 2), detmin)
        return u.reshape(lam.size, -1)[:, free].T

    lam = w**2
    phi = (sweep_modes.inverse_iteration(lam, solve, lambda X: M @ X, lambda X: K @ X,
                                         beam.n_dof) if lam.size else np.zeros((beam.n_dof, 0)))
    phi = _pivoted_step(phi, lam, K, M)
    r = rigid_translation(beam)[:, 0]
    Mr = M @ r
    gamma = phi.T @ Mr
    return Modes(omega=w, shapes=phi, influence=r, participation=gamma,
                 effective_mass=gamma**2, total_mass=float(r @ Mr), dof_names=beam.dof_names)


def _band(A, width: int) -> np.ndarray:
    """LAPACK band storage of a sparse matrix with ``width`` sub- and super-diagonals:
    ab[width + i - j, j] = A[i, j] (scipy's dia data holds A[j - offset, j] at column j)."""
    D = A.todia()
    ab = np.zeros((2 * width + 1, A.shape[0]))
    for off, row in zip(D.offsets, D.data):
        ab[width - off] += row
    return ab


def _pivoted_step(phi, lam, K, M):
    """One step of inverse iteration per shape by the banded LU with partial pivoting (module
    docstring), on isolated roots (a cluster's Rayleigh-Ritz basis is kept); M-normalized,
    largest entry positive. A shift that is an eigenvalue to the bit (an exactly singular
    factor) keeps the sweep's shape."""
    if phi.shape[1] == 0:
        return phi
    width = max(abs(int(o)) for o in (K.todia().offsets.tolist() + M.todia().offsets.tolist()))
    bK, bM = _band(K, width), _band(M, width)
    out = phi.copy()
    for group in sweep_modes.clusters(lam):
        if group.size > 1:
            continue
        r = group[0]
        try:
            x = sla.solve_banded((width, width), bK - lam[r] * bM, M @ phi[:, r])
        except np.linalg.LinAlgError:
            continue
        x = x / np.sqrt(x @ (M @ x))
        out[:, r] = x * np.sign(x[np.argmax(np.abs(x))])
    return out


#: modes refined together (the products over the band run on (chunk, n) arrays)
_CHUNK = 16
#: residual-correction steps after the two steps of inverse iteration
_CORRECTIONS = 3
#: the least half-width (relative) of the interval in which the count must confirm a root
_CONFIRM = 1e-7


def _exact_band_product(diags, x):
    """K x as an unevaluated sum hi + lo, for K by its diagonals ``diags`` ((offset, K[i, i +
    offset] for every i, its two halves)), x (k, n): every product exact (Dekker's two-product)
    and the sums compensated (Knuth's two-sum), so hi + lo is K x to about eps^2 |K| |x|."""
    n = x.shape[-1]
    xh, xl = split(x)
    s, err = np.zeros_like(x), np.zeros_like(x)
    for d, a, ah, al in diags:
        rows, cols = (slice(0, n - d), slice(d, n)) if d >= 0 else (slice(-d, n),
                                                                     slice(0, n + d))
        b = x[:, cols]
        p, pe = two_prod(a, b, (ah, al), (xh[:, cols], xl[:, cols]))
        s[:, rows], te = two_sum(s[:, rows], p)
        err[:, rows] += te + pe
    return s, err


def _pencil_bands(beam: Beam):
    """K and M of `beam_matrices` scaled by powers of 2 (kscale, mscale: no rounding), their
    half-bandwidth, the diagonals of K split for `_exact_band_product`, and M's diagonals."""
    M, _, K = beam_matrices(beam)
    width = max(abs(int(o)) for o in (K.todia().offsets.tolist() + M.todia().offsets.tolist()))
    kscale = 2.0 ** np.round(np.log2(abs(K).max()))
    mscale = 2.0 ** np.round(np.log2(abs(M).max()))
    offsets = range(-width, width + 1)
    kd = [(d, K.diagonal(d) / kscale) for d in offsets]
    md = [(d, M.diagonal(d) / mscale) for d in offsets]
    return width, [(d, a, *split(a)) for d, a in kd], md, kscale / mscale


def refined_roots(beam: Beam, lam: np.ndarray, index: np.ndarray, blocks) -> np.ndarray:
    r"""Each root lam_j of the count (rad^2/s^2, > 0; ``index``: j, 0-based) to a few ulps of
    the eigenvalue of the (K, M) of `beam_matrices`: inverse iteration and residual correction
    with the banded LU of K - lam_j M (O(N) per root), the residual in twice the working
    precision; the result kept where the count confirms it as root j (`beam_frequencies`)."""
    from dtdyn.linear import _beam as count

    if lam.size == 0:
        return lam
    width, kd, md, unit = _pencil_bands(beam)
    n = beam.n_dof
    start = np.random.default_rng(0).uniform(0.5, 1.5, n)  # the same for every root
    sigma = lam / unit
    rho = np.empty_like(sigma)
    for c0 in range(0, sigma.size, _CHUNK):
        rho[c0:c0 + _CHUNK] = _refine_chunk(sigma[c0:c0 + _CHUNK], width, kd, md, start)
    rho = rho * unit
    # the count confirms rho as root j: one root in rho (1 -+ delta), delta beyond the
    # distance to the count's value and beyond the count's rounding (or a quarter of the gap
    # to the next root found, if less: a root the count cannot resolve keeps its value)
    gap = np.full(lam.size + 1, np.inf)
    gap[1:-1] = np.diff(lam)
    floor = np.minimum(_CONFIRM, 0.25 * np.minimum(gap[:-1], gap[1:]) / lam)
    delta = np.maximum(4.0 * np.abs(rho - lam) / lam, floor)
    ok = np.isfinite(rho) & (rho > 0.0)
    points = np.concatenate([rho * (1.0 - delta), rho * (1.0 + delta)])
    points = np.where(np.isfinite(points), points, 0.0)
    c = count._inertia(blocks, points.astype(count._WIDE) * count._WIDE(blocks[-1]))[0]
    ok &= (c[:lam.size] == index) & (c[lam.size:] == index + 1)
    return np.where(ok, rho, lam)


def _band_product(diags, x):
    """K x in working precision, K by its diagonals ((offset, K[i, i + offset] for every i))."""
    n = x.shape[-1]
    y = np.zeros_like(x)
    for d, a in diags:
        if d >= 0:
            y[:, :n - d] += a * x[:, d:]
        else:
            y[:, -d:] += a * x[:, :n + d]
    return y


def _refine_chunk(sigma, width, kd, md, start):
    """`refined_roots` for the shifts sigma (scaled units): two steps of inverse iteration from
    ``start``, then `_CORRECTIONS` steps x <- x - (z - alpha y), A z = r = (K - rho M) x (r in
    twice the working precision), A y = M x, alpha making the step M-orthogonal to x, rho the
    Rayleigh quotient; A = K - sigma M factored once (LAPACK dgbtrf, partial pivoting)."""
    k, n = sigma.size, start.size

    def band(shift):  # LAPACK's storage of K - shift M: ab[2 w + i - j, j] = A[i, j]
        ab = np.zeros((3 * width + 1, n))
        for (d, a, _, _), (_, m) in zip(kd, md):
            ab[2 * width - d, slice(d, n) if d >= 0 else slice(0, n + d)] = a - shift * m
        return ab

    factors = []
    for i in range(k):
        lu, piv, info = lapack.dgbtrf(band(sigma[i]), width, width)
        if info > 0:  # sigma an eigenvalue to the last bits: shifted by 2^-40 relative
            lu, piv, info = lapack.dgbtrf(band(sigma[i] * (1.0 + 2.0 ** -40)), width, width)
        factors.append((lu, piv) if info == 0 else None)

    def solve(rhs):  # rhs (k, n) or (k, n, 2)
        out = np.full_like(rhs, np.nan)
        for i, f in enumerate(factors):
            if f is not None:
                out[i] = lapack.dgbtrs(f[0], width, width, rhs[i], f[1])[0]
        return out

    def unit(x):
        return x / np.max(np.abs(x), axis=-1, keepdims=True)

    with np.errstate(all="ignore"):
        x = unit(solve(np.broadcast_to(_band_product(md, start[None]), (k, n)).copy()))
        x = unit(solve(_band_product(md, x)))
        for _ in range(_CORRECTIONS + 1):
            kh, kl = _exact_band_product(kd, x)
            Mx = _band_product(md, x)
            rho = np.sum(x * (kh + kl), axis=-1) / np.sum(x * Mx, axis=-1)
            if _ == _CORRECTIONS:
                return rho
            r = (kh - rho[:, None] * Mx) + kl
            zy = solve(np.stack([r, Mx], axis=-1))
            z, y = zy[..., 0], zy[..., 1]
            alpha = np.sum(Mx * z, axis=-1) / np.sum(Mx * y, axis=-1)
            x = unit(x - (z - alpha[:, None] * y))


def _dof(name, value, beam):
    names = beam.dof_names
    if isinstance(value, bool) or not isinstance(value, (str, int, np.integer)):
        raise ValueError(f"{name} = {value!r}: must be one DOF, an index or a name")
    if isinstance(value, str):
        if value not in names:
            raise ValueError(f"{name}: no DOF named {value!r} (held, or outside the beam; the "
                             f"DOFs are {names[0]} .. {names[-1]})")
        return names.index(value)
    if not 0 <= value < len(names):
        raise ValueError(f"{name} = {value!r}: outside 0..{len(names) - 1}")
    return int(value)


def _exact_blocks(beam: Beam, w: np.ndarray):
    """D, E (len(w), nodes, 2, 2) of the exact elements plus the nodal terms, at s = i w."""
    if beam.rayleigh is not None:
        raise ValueError(f"rayleigh = {beam.rayleigh!r} with exact=True: the exact field matrix "
                         "here is the undamped one; use exact=False (Hermite elements) or "
                         "dampers at nodes (Support c_w, c_psi)")
    h = beam.length / beam.elements
    Z = np.array([derived.element_dynamic_stiffness(beam.E * beam.I, beam.rho_A, h, x)
                  for x in w])
    nodes = beam.elements + 1
    D = np.zeros((w.size, nodes, 2, 2), dtype=complex)
    D[:, :-1] += Z[:, None, :2, :2]
    D[:, 1:] += Z[:, None, 2:, 2:]
    E = np.broadcast_to(Z[:, None, :2, 2:], (w.size, nodes - 1, 2, 2)).astype(complex)
    diag = beam.nodal_diagonals()
    s = 1j * w[:, None]
    nodal = (diag["k"][None] + s * diag["c"][None] + s * s * diag["m"][None]).reshape(
        w.size, nodes, 2)
    D[..., 0, 0] += nodal[..., 0]
    D[..., 1, 1] += nodal[..., 1]
    return D, E


@public(renamed={"force_dof": "force_dofs", "output": "outputs"})
def beam_frequency_response(beam: Beam, omega, force_dofs, outputs, *,
                            exact=False) -> np.ndarray:
    """Receptances u_o / f_i (m/N, rad/N, m/(N m) or rad/(N m)) at s = i omega for a unit
    force (on a w) or moment (on a psi) at each of ``force_dofs``, by the pivoted banded LU of
    the node blocks (module docstring), O(N) per frequency and loaded DOF.

    Parameters
    ----------
    beam : Beam
    omega : array_like
        Circular frequencies, rad/s, finite and >= 0.
    force_dofs, outputs : int or str, or a sequence of them
        The loaded DOFs and the DOFs whose motion is returned: indices into
        ``beam.dof_names`` or names ("w200", "psi3").
    exact : bool
        False: the Hermite elements, (K + i omega C - omega^2 M)^-1 of `beam_matrices`, with
        the beam's Rayleigh damping and dampers. True: every element by its exact
        Euler-Bernoulli dynamic stiffness (from exp(A L)), the point masses, supports and their
        dampers at the nodes; the elements undamped (a Rayleigh beam is refused).
        (`shaft_frequency_response` has ``exact=True`` by default: there it selects the
        continuous shafts' exact field matrices, and a lumped shaft is the same either way.)

    Returns
    -------
    complex ndarray
        Shape (len(omega), len(outputs), len(force_dofs)), or (len(omega),) when both are
        single DOFs. NaN where Z(omega) is singular to the bit (a resonance of an undamped
        beam).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=10)
    >>> H = dd.beam_frequency_response(beam, [0.0], "w10", "w10")
    >>> round(float(H.real[0] * 3 * 2.1e11 * 8e-6 / 3.0**3), 12)     # static: L^3 / (3 EI)
    1.0
    """
    _check_beam(beam)
    w = validate.frequencies("omega", omega)
    validate.flag("exact", exact)
    columns = {}

    def pair(i, o):
        if i not in columns:
            columns[i] = _all_receptances(beam, w, i, exact)
        return columns[i][:, beam.free[o]]

    return receptance_matrix(pair, force_dofs, outputs, lambda name, v: _dof(name, v, beam))


def _all_receptances(beam, w, i_f, exact) -> np.ndarray:
    """Every free DOF's receptance to a unit load on DOF ``i_f``: (len(w), 2 (elements + 1))."""
    nodes = beam.elements + 1
    if exact:
        D, E = _exact_blocks(beam, w)
    else:
        Mg, Cg, Kg = beam.global_matrices()
        (DK, EK, _), (DC, EC, _), (DM, EM, _) = (linalg.node_blocks(A) for A in (Kg, Cg, Mg))
        s = 1j * w[:, None, None, None]
        D, E = DK + s * DC + s * s * DM, EK + s * EC + s * s * EM
    f = np.zeros((w.size, 2 * nodes), dtype=complex)
    f[:, beam.free[i_f]] = 1.0
    u = banded_solve(D, E, _held(beam), f.reshape(w.size, nodes, 2))
    return u.reshape(w.size, -1)
