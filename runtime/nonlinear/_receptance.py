r"""A reduced receptance of a large sparse model: the modes below a cut-off plus the exact
residual of the modes above it, so that one evaluation costs the same for 1,000 DOFs as for
100,000.

With Rayleigh damping C = alpha M + beta K and mass-normalized modes (K phi_r = k_r M phi_r),

.. math::

    H(w) = (K - w^2 M + i w C)^{-1} = \sum_r \frac{\phi_r \phi_r^T}{a k_r - b},
    \qquad a = 1 + i w \beta, \quad b = w^2 - i w \alpha .

The m modes below the cut-off w_m are kept as they are; for the others |b / (a k_r)| < 1
whenever w < w_m, and the geometric series gives

.. math::

    \sum_{r > m} \frac{\phi_r \phi_r^T}{a k_r - b}
    = \sum_{j \ge 0} \frac{(b / s)^j}{a^{j + 1}} \, V_j, \qquad
    V_j = s^j (K^{-1} M)^j P K^{-1}, \quad P = I - \Phi \Phi^T M,

(s = w_m^2 a scale), V_0 the residual (static) flexibility, the higher V_j its mass
corrections. V_j is needed only at the rows (elements, outputs) and columns (elements, loads)
of the harmonic balance: one LU of K, then one solve and one projection per column and term,
once. The projection P is applied after every solve, which keeps the terms clean of the
low modes (a solve with K of a beam of many elements carries rounding errors along its lowest
modes, cond(K) ~ N^4: P removes them).

Each evaluation then costs O(m + J) per row and column, whatever the size of the model. The
modes come from ARPACK (shift-invert about 0 with the same LU), each then refined by residual
correction with a banded LU of K - k_r M (`refined_modes`), and every solve with K is refined
by residuals in twice the working precision (`refined_solve`): a Hermite beam of N elements
has cond(K) ~ N^4 and a double-precision LU loses about eps N^3.5 (ARPACK's lowest frequency
of a 10,000-element beam: 4e-3; refined: 1e-15 from `beam_frequencies`). The kept modes'
damping: a model that carries its Rayleigh coefficients (a `Beam` with ``rayleigh``;
`rayleigh_parts`) gives alpha + beta k_r exactly (plus its supports' dampers, phi^T E phi),
and every product with C is alpha M v + beta K v + E v: C = alpha M + beta K summed entry by
entry in double precision loses alpha M against beta K at large N (a 10,000-element beam: the
first mode's damping 40 % below alpha + beta k_1). Given matrices alone, the model is C as it
is: the kept modes' damping is C's own, phi^T C phi (C phi summed exactly), as an m x m matrix
where alpha + beta k_r does not reproduce it. The cut-off: the highest
frequency asked for, w_c (the highest harmonic of the band, with a margin), times 2.5 (the
series' ratio |b / (a s)| <= 0.16); the number of terms J grows until the reduced receptance
equals the exact banded one (`_BandedReceptance`) at w_c and at the first natural frequency
to ``rtol`` (the largest entry's difference over the largest entry), or the model is left to
the exact receptance. Both the numbers and the outcome are in ``check``. The check is made at
w_c only: near a resonance both receptances carry the rounding of the model's own matrices
(a Hermite beam of N elements: a relative error of about eps N^3.5 in its lowest stiffness,
amplified by 1 / (2 zeta) at the peak), which no choice of modes removes.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn._engine.twofold import split, two_prod, two_sum

#: the reduced receptance keeps at most this many modes (a model with more below its cut-off,
#: e.g. a long chain whose band is dense in modes, keeps the exact banded receptance)
REDUCED_MAX_MODES = 200
#: the highest term of the residual series
REDUCED_MAX_TERMS = 40
#: the modes kept: those below this multiple of the highest frequency asked for
REDUCED_CUTOFF = 2.5
#: without ``w_max``, the first setup covers this multiple of the first frequency asked for
REDUCED_FIRST = 4.0
#: the verified range: this multiple of the highest frequency asked for (so that a continuation
#: step a little past the end of the band needs no new setup)
REDUCED_MARGIN = 1.25


# ----------------------------------------------------------------------------------------------
# solves with a banded matrix refined by residuals in twice the working precision: a Hermite
# beam of N elements has cond(K) ~ N^4, and a double-precision LU of K loses about eps N^3.5
# relative (docs/beam_conditioning.md); b - K x summed exactly (Dekker's two-product, Knuth's
# two-sum) and corrected with the same LU recovers the digits while that loss is below 1

#: refinement steps at most (each stops early when its correction no longer halves)
REFINE_STEPS = 6
#: refinement stops at a correction below this (relative to the solution's largest entry)
REFINE_TOL = 1e-13


def band_diagonals(mats, width):
    """One sparse matrix or a list of them (half-bandwidth ``width``), row-aligned by diagonals
    for `exact_product`: a[m, j, i] = A_m[i, i + j - width] (0 outside), with its two halves."""
    single = not isinstance(mats, (list, tuple))
    mats = [mats] if single else list(mats)
    n = mats[0].shape[0]
    a = np.zeros((len(mats), 2 * width + 1, n))
    for m, A in enumerate(mats):
        A = sps.coo_matrix(A)
        np.add.at(a[m], (A.col - A.row + width, A.row), A.data)
    return (single, width, a[..., None], *(h[..., None] for h in split(a)))


def exact_product(bands, X):
    """A X as an unevaluated sum hi + lo (X real (n, k), A from `band_diagonals`; a list of
    matrices gives (matrices, n, k) arrays): every product exact (Dekker's two-product) and
    the sums compensated (Knuth's two-sum), so that hi + lo is A X to about eps^2 |A| |X|."""
    single, w, a, ah, al = bands
    n, k = X.shape
    Xh, Xl = split(X)
    s, err = np.zeros((a.shape[0], n, k)), np.zeros((a.shape[0], n, k))
    for j in range(2 * w + 1):
        d = j - w
        rows, cols = (slice(0, n - d), slice(d, n)) if d >= 0 else (slice(-d, n), slice(0, n + d))
        aj, ahj, alj = a[:, j, rows], ah[:, j, rows], al[:, j, rows]
        p, pe = two_prod(aj, X[cols], (ahj, alj), (Xh[cols], Xl[cols]))
        s[:, rows], te = two_sum(s[:, rows], p)
        err[:, rows] += te + pe
    return (s[0], err[0]) if single else (s, err)


def refined_solve(solve, diags, B, steps=REFINE_STEPS):
    """X with A X = B (real): ``solve`` an LU's solve, then corrections X += solve(B - A X)
    with the residual from `exact_product`, until a correction is below REFINE_TOL |X| or no
    longer halves (at most ``steps``)."""
    X = solve(B)
    last = np.inf
    for _ in range(steps):
        hi, lo = exact_product(diags, X)
        dX = solve((B - hi) - lo)
        size = float(np.abs(dX).max()) / max(float(np.abs(X).max()), 1e-300)
        if size > last:                   # diverging: the LU too inaccurate to correct with
            break
        X = X + dX
        if size <= REFINE_TOL or size > 0.5 * last:
            break
        last = size
    return X


def refined_modes(K, M, k, phi, width, steps=4):
    """The eigenpairs (k, phi) of K phi = k M phi (from ARPACK) refined one by one: residual
    correction with the banded LU of K - k_r M (LAPACK, partial pivoting) and the residual
    (K - rho M) x in twice the working precision, rho the Rayleigh quotient (x <- x - (z - a y),
    A z = r, A y = M x, a making the step M-orthogonal to x); then M-orthonormalized."""
    from scipy.linalg import lapack
    n = K.shape[0]
    diags = band_diagonals(K, width)
    M = sps.csr_matrix(M)
    bands = []
    for A in (K, M):
        A = sps.coo_matrix(A)
        ab = np.zeros((3 * width + 1, n))
        np.add.at(ab, (2 * width + A.row - A.col, A.col), A.data)
        bands.append(ab)
    rho = np.array(k, dtype=float)
    out = np.array(phi, dtype=float)
    for r in range(rho.size):
        lu, piv, info = lapack.dgbtrf(bands[0] - rho[r] * bands[1], width, width)
        if info != 0:                                       # k_r exact to the last bit
            continue
        x = out[:, r] / np.abs(out[:, r]).max()
        for step in range(steps + 1):
            hi, lo = exact_product(diags, x[:, None])
            Mx = M @ x
            rho[r] = float(x @ (hi[:, 0] + lo[:, 0])) / float(x @ Mx)
            if step == steps:
                break
            res = (hi[:, 0] - rho[r] * Mx) + lo[:, 0]
            z = lapack.dgbtrs(lu, width, width, np.column_stack([res, Mx]), piv)[0]
            a = float(Mx @ z[:, 0]) / float(Mx @ z[:, 1])
            x = x - (z[:, 0] - a * z[:, 1])
            x = x / np.abs(x).max()
        out[:, r] = x
    for r in range(rho.size):                                # M-orthonormal (Gram-Schmidt)
        x = out[:, r]
        if r:
            x = x - out[:, :r] @ (out[:, :r].T @ (M @ x))
        out[:, r] = x / np.sqrt(float(x @ (M @ x)))
    return rho, out


def rayleigh_parts(model, M, C, K, tol=1e-8):
    """(alpha, beta, E) with C = alpha M + beta K + E, for a model that carries its Rayleigh
    coefficients (a `Beam` with ``rayleigh``), else None. E (sparse, or None when zero): what
    Beam's C holds beside alpha M + beta K of the whole model, its supports' dampers less alpha
    times its point masses and beta times its support springs (Beam forms alpha M + beta K from
    the elements alone). M, C, K: the model's assembled matrices, in the order of its DOFs;
    C is checked against the parts (``tol`` relative, on two random vectors).

    A receptance built from the parts keeps alpha M and beta K apart: the modes' damping is
    alpha + beta k_r exactly, and C v = alpha M v + beta K v + E v, where C summed entry by
    entry in double precision loses alpha M against beta K at large N (a 10,000-element beam:
    the first mode's damping 40 % low)."""
    from dtdyn.linear._beam import Beam
    if not isinstance(model, Beam) or model.rayleigh is None:
        return None
    alpha, beta = model.rayleigh
    diag = model.nodal_diagonals()
    e = (diag["c"] - alpha * diag["m"] - beta * diag["k"])[model.free]
    E = sps.diags(e).tocsr() if np.any(e) else None
    rng = np.random.default_rng(1)
    for x in (rng.standard_normal(M.shape[0]) for _ in range(2)):
        terms = [C @ x, alpha * (M @ x), beta * (K @ x)] + ([E @ x] if E is not None else [])
        scale = sum(float(np.abs(t).max()) for t in terms)
        if np.abs(terms[0] - sum(terms[1:])).max() > tol * scale:
            return None
    return float(alpha), float(beta), E


def damping_product(parts, M, K, X):
    """C X = alpha M X + beta K X + E X in working precision (``parts`` from `rayleigh_parts`;
    M, K sparse)."""
    alpha, beta, E = parts
    out = alpha * (M @ X) + beta * (K @ X)
    return out if E is None else out + E @ X


def rayleigh_coefficients(M, C, K, tol=1e-8):
    """(alpha, beta) with C = alpha M + beta K to ``tol`` (relative, on two random vectors),
    or None. C = 0 gives (0, 0)."""
    rng = np.random.default_rng(0)
    n = M.shape[0]
    v, u = rng.standard_normal(n), rng.standard_normal(n)
    Cv = C @ v
    if not np.any(Cv) and not np.any(C @ u):
        return 0.0, 0.0
    A = np.column_stack([M @ v, K @ v])
    scale = np.maximum(np.abs(A).max(axis=0), 1e-300)       # the columns differ by ~ cond(K)
    (alpha, beta), *_ = np.linalg.lstsq(A / scale, Cv, rcond=None)
    alpha, beta = alpha / scale[0], beta / scale[1]
    for x in (v, u):
        terms = (C @ x, alpha * (M @ x), beta * (K @ x))
        scale = sum(np.abs(t).max() for t in terms)
        if np.abs(terms[0] - terms[1] - terms[2]).max() > tol * scale:
            return None
    return max(float(alpha), 0.0), max(float(beta), 0.0)


def modes_below(M, K, w) -> int:
    """The number of eigenvalues k_r < w^2 of K phi = k M phi (Sylvester's inertia: the negative
    pivots of a symmetric sparse LU of K - w^2 M with diagonal pivots), or -1 when the LU is not
    symmetric."""
    lu = spla.splu(sps.csc_matrix(K - (w * w) * M), permc_spec="MMD_AT_PLUS_A",
                   diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return -1
    return int(np.sum(lu.U.diagonal() < 0))


class ReducedReceptance:
    """H(w) = modes below a cut-off + the residual series (module docstring), built on the first
    call that needs a frequency above the verified range (``w_max`` up front when known), and
    checked at the highest frequency against ``exact`` (a `_BandedReceptance` of the same rows
    and columns). When the check fails, or the model has too many modes below the cut-off,
    every call goes to ``exact`` and ``name`` becomes "banded" (``check`` says why;
    ``strict``: with a warning).

    Calls return H (len(w), ne + no, ne + nb) and dH/dw (len(w), ne, ne + nb), as the other
    receptances of `harmonic_balance`.

    ``parts``: (alpha, beta, E) from `rayleigh_parts` when the model carries its Rayleigh
    coefficients: the kept modes' damping is then alpha + beta k_r (+ phi^T E phi) exactly,
    not C's assembled entries (``damping`` is then ignored). ``backup``: the receptance the
    calls go to after a failed check (default ``exact``; "auto" gives LAPACK's banded LU
    without refinement, its receptance before)."""

    def __init__(self, exact, M, C, K, L, outputs, B, damping, *, w_max=None, rtol=1e-8,
                 strict=False, parts=None, backup=None):
        self.exact, self.rtol, self.strict, self.parts = exact, rtol, strict, parts
        self.backup = exact if backup is None else backup
        if parts is not None:
            damping = parts[:2]
        self.M, self.C, self.K = sps.csc_matrix(M), sps.csr_matrix(C), sps.csc_matrix(K)
        self.alpha, self.beta = damping
        self.ne = L.shape[0]
        self.rows = sps.vstack([sps.csr_matrix(L),
                                sps.csr_matrix((np.ones(outputs.size),
                                                (np.arange(outputs.size), outputs)),
                                               shape=(outputs.size, M.shape[0]))]).tocsr()
        self.cols = np.hstack([np.asarray(L.T, dtype=float), np.asarray(B, dtype=float)])
        self.cover = 0.0
        self.fallback = False
        self.name = "reduced"
        self.check = dict(receptance="reduced", rtol=rtol, builds=0,
                          damping="rayleigh" if parts is not None else "C")
        #: the kept modes' damping (the diagonal of their modal damping matrix), 1/s
        self.modal_damping = np.zeros(0)
        self._lu = None
        self.Cm = None
        width = exact.width
        self.kd, self.cd = band_diagonals(self.K, width), band_diagonals(self.C, width)
        if w_max is not None and w_max > 0:
            self._build(REDUCED_MARGIN * w_max)

    # ------------------------------------------------------------------------------------------
    def __call__(self, w):
        w = np.asarray(w, dtype=float)
        top = float(np.abs(w).max()) if w.size else 0.0
        if self.fallback:
            return self.backup(w)
        if top == 0.0 and not self.cover:
            return self.exact(w)                  # the static harmonic before the first build
        if not self.fallback and top > self.cover:
            self._build(2.0 * top if self.cover else REDUCED_FIRST * top)
        if self.fallback:
            return self.backup(w)
        return self._evaluate(w)

    def _evaluate(self, w, terms=None):
        J = self.S.shape[0] if terms is None else terms
        a = 1.0 + 1j * w * self.beta
        b = w * w - 1j * w * self.alpha
        da, db = 1j * self.beta, 2.0 * w - 1j * self.alpha
        if self.Cm is None:        # modes: 1 / (a k - b)
            den = a[:, None] * self.k[None, :] - b[:, None]
            d = 1.0 / den
            dd = -(da * self.k[None, :] - db[:, None]) * d * d
            H = np.einsum("rp,mp,pc->mrc", self.A, d, self.Bm)
            dH = np.einsum("rp,mp,pc->mrc", self.A[:self.ne], dd, self.Bm)
        else:                      # (diag(k) - w^2 I + i w Phi^T C Phi)^-1 by its 2m poles
            d = 1.0 / (1j * w[:, None] - self.poles[None, :])
            H = np.einsum("rp,mp,pc->mrc", self.Ap, d, self.Xb)
            dH = np.einsum("rp,mp,pc->mrc", self.Ap[:self.ne], -1j * d * d, self.Xb)
        if J:
            q = b / self.s
            dq = db / self.s
            j = np.arange(J)
            qj = q[:, None] ** j[None, :]
            f = qj / a[:, None] ** (j[None, :] + 1)
            with np.errstate(divide="ignore", invalid="ignore"):
                qjm = np.where(j[None, :] > 0, q[:, None] ** np.maximum(j - 1, 0)[None, :], 0.0)
            df = (j[None, :] * qjm * dq[:, None] / a[:, None] ** (j[None, :] + 1)
                  - (j[None, :] + 1) * qj * da / a[:, None] ** (j[None, :] + 2))
            H = H + np.einsum("mj,jrc->mrc", f, self.S[:J])
            dH = dH + np.einsum("mj,jrc->mrc", df, self.S[:J, :self.ne])
        return H, dH

    # ------------------------------------------------------------------------------------------
    def _give_up(self, reason):
        if self.strict:
            warnings.warn(f"receptance='reduced' falls back to the exact banded receptance: "
                          f"{reason}", RuntimeWarning, stacklevel=4)
        self.fallback = True
        self.name = "banded"
        self.check.update(receptance="banded", reason=reason)

    def _modal_damping(self, k, phi):
        """(the kept modes' damping matrix phi^T C phi, None), or (None, why not)."""
        m = k.size
        if self.parts is not None:   # alpha + beta k_r exactly, and the supports' part
            E = self.parts[2]
            Cp = np.diag(self.alpha + self.beta * k)
            if E is not None:
                Cp = Cp + phi.T @ (E @ phi)
                Cp = 0.5 * (Cp + Cp.T)
        else:                        # phi^T C phi, C phi exactly
            hi, lo = exact_product(self.cd, phi)
            Cp = phi.T @ (hi + lo)
            Cp = 0.5 * (Cp + Cp.T)
        if m >= 2 and self.parts is None:
            # alpha, beta from the modes' damping: C's entries may have lost alpha M to
            # rounding (a long beam)
            c = np.diag(Cp)
            (alpha, beta), *_ = np.linalg.lstsq(np.column_stack([np.ones(m), k / k[-1]]),
                                               c, rcond=None)
            fit = np.abs(alpha + beta * k / k[-1] - c).max()
            off = np.abs(Cp - np.diag(c)).max()
            if max(fit, off) > 1e-6 * np.abs(c).max():
                return None, (f"the damping is not Rayleigh's (alpha M + beta K) in the "
                              f"modes: {max(fit, off) / np.abs(c).max():.1e}")
            self.alpha, self.beta = max(float(alpha), 0.0), max(float(beta) / k[-1], 0.0)
        return Cp, None

    def _build(self, w_c):
        """Modes below REDUCED_CUTOFF w_c, the residual terms until the check at w_c passes."""
        self.check["builds"] += 1
        w_m = REDUCED_CUTOFF * w_c
        m = modes_below(self.M, self.K, w_m)
        n = self.M.shape[0]
        if m < 0:
            return self._give_up("the symmetric LU of K - w^2 M pivoted off the diagonal (no "
                                 "mode count)")
        if m > REDUCED_MAX_MODES or m >= n - 2:
            return self._give_up(f"{m} modes below {w_m / 2 / np.pi:.4g} Hz (more than "
                                 f"{min(REDUCED_MAX_MODES, n - 3)})")
        if self._lu is None:
            try:
                self._lu = spla.splu(self.K)
            except RuntimeError as exc:              # "Factor is exactly singular"
                return self._give_up(f"the LU of K failed ({exc}): a rigid-body mode?")
        lu = self._lu
        width = self.exact.width

        def solve(V):            # K^-1 V refined (cond(K) ~ N^4 for a beam of N elements)
            return refined_solve(lu.solve, self.kd, V)

        if m:
            op = spla.LinearOperator(self.K.shape, matvec=lu.solve, dtype=float)
            try:
                # a fixed start vector: the same modes, and the same setup time, every run
                v0 = np.random.default_rng(0).standard_normal(n)
                k, phi = spla.eigsh(self.K, m, M=self.M, sigma=0.0, OPinv=op, v0=v0)
            except spla.ArpackError as exc:
                return self._give_up(f"ARPACK found no {m} modes: {exc}")
            k, phi = refined_modes(self.K, self.M, k, phi, width)
            Cp, reason = self._modal_damping(k, phi)
            if reason:
                return self._give_up(reason)
            # the kept modes with their own modal damping matrix where alpha + beta k_r misses
            # it: the supports' part E, or C as it is (C = alpha M + beta K summed in double
            # loses alpha M at large N: its lowest modes' damping is off, and C couples them)
            miss = np.abs(Cp - np.diag(self.alpha + self.beta * k)).max(axis=1)
            self.Cm = Cp if np.any(miss > 1e-3 * self.rtol * np.diag(Cp)) else None
            self.modal_damping = np.diag(Cp).copy()
        else:
            k, phi = np.zeros(0), np.zeros((n, 0))
            self.Cm = None
        self.k, self.A, self.Bm, self.modes = k, self.rows @ phi, phi.T @ self.cols, phi
        if self.Cm is not None:    # the kept modes' poles and residue factors (dense, 2m)
            from dtdyn.modal._model import modal_factors
            self.poles, psi, x = modal_factors(np.eye(m), self.Cm, np.diag(k))
            self.Ap, self.Xb = self.A @ psi, x @ self.Bm
        self.s = w_m * w_m
        MP = self.M @ phi

        def project(V):
            return V - phi @ (MP.T @ V)

        checks = np.array([w_c])
        Hx = self.exact(checks)[0][0]
        V = project(solve(self.cols))
        S = []
        err = np.inf
        for _ in range(REDUCED_MAX_TERMS):
            S.append(self.rows @ V)
            self.S = np.array(S)
            Hr = self._evaluate(checks)[0][0]
            err_new = float(np.abs(Hr - Hx).max() / np.abs(Hx).max())
            if err_new <= self.rtol or err_new > 0.5 * err:       # met, or no longer improving
                err = min(err, err_new)
                break
            err = err_new
            V = project(solve(self.M @ V)) * self.s
        self.check.update(modes=int(m), terms=len(S), cutoff_hz=w_m / 2 / np.pi,
                          verified_to_hz=w_c / 2 / np.pi, error=err)
        if err > self.rtol:
            return self._give_up(f"it differs from the exact banded receptance by {err:.2e} "
                                 f"(relative) at {w_c / 2 / np.pi:.4g} Hz, more than rtol = "
                                 f"{self.rtol:g}")
        self.cover = w_c
