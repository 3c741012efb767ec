"""Checked matrices and factorizations shared by the M, C, K entry points."""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from dtdyn._engine import validate


def square_matrix(name: str, value, n: int | None = None, keep_sparse: bool = False):
    """A finite, non-empty, square float64 matrix (``n`` x ``n`` to match M when given).

    scipy.sparse input stays sparse (CSR) when ``keep_sparse``, else it is densified.
    """
    if sps.issparse(value) and np.iscomplexobj(value.data):
        raise ValueError(f"{name} is a complex sparse matrix (dtype {value.dtype}): dtdyn takes "
                         f"real values; pass {name}.real explicitly if the imaginary part is to "
                         "be dropped")
    if sps.issparse(value) and keep_sparse:
        arr = sps.csr_matrix(value, dtype=float)
        data = arr.data
    else:
        if sps.issparse(value):
            validate.dense_conversion(name, value)
            value = value.toarray()
        validate.matrix_rows(name, value)
        if np.iscomplexobj(value) or isinstance(value, (str, bytes)):
            validate.real_array(name, value, "a real numeric matrix")
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):  # OverflowError: int beyond float
            raise ValueError(f"{name} must be a real numeric matrix, got "
                             f"{type(value).__name__}") from None
        data = arr
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {arr.shape}")
    if n is not None and arr.shape != (n, n):
        raise ValueError(f"{name} has shape {arr.shape}, expected {(n, n)} to match M")
    bad = ~np.isfinite(data)
    if bad.any():
        if sps.issparse(arr):
            raise ValueError(f"{name} has a non-finite entry")
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"{name}[{i}, {j}] = {float(arr[i, j])!r}: every entry must be finite")
    return arr


def mck(M, C, K, keep_sparse: bool = False, physical: bool = True):
    """Checked (M, C, K) of one size; ``physical``: M is a mass matrix (`check_mass`). A sparse
    M that is to be made dense is first checked to fit three times (M, C and K) in memory
    (`validate.dense_conversion`)."""
    if sps.issparse(M) and not keep_sparse:
        validate.dense_conversion("M", M, copies=3)
    M = square_matrix("M", M, keep_sparse=keep_sparse)
    if physical:
        check_mass(M)
    n = M.shape[0]
    return M, square_matrix("C", C, n, keep_sparse), square_matrix("K", K, n, keep_sparse)


#: relative tolerance of the mass checks: |M - M^T| <= SYM_TOL max|M|, and the eigenvalues of M
#: >= -SYM_TOL max|M| (round-off of an assembled matrix, far below any physical mass)
SYM_TOL = 1e-10


def check_mass(M) -> None:
    """M of a structure: symmetric and positive semi-definite (zero rows allowed: massless DOFs),
    to SYM_TOL relative to its largest entry. A negative diagonal entry is named by its DOF;
    dense M is tested by a Cholesky factorization of M + SYM_TOL max|M| I, sparse M by its
    diagonal only. C and K are not restricted: gyroscopic and circulatory terms are
    non-symmetric and negative stiffness is physical (the stability checks see its growth)."""
    diag = M.diagonal()
    bad = np.flatnonzero(diag < 0.0)
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"M[{i}, {i}] = {float(diag[i])!r}: negative mass at DOF {i} (M must be "
                         "symmetric positive semi-definite)")
    scale = abs(M).max()
    if scale == 0.0:
        return
    asym = abs(M - M.T).max()
    if asym > SYM_TOL * scale:
        raise ValueError(f"M is not symmetric: max |M - M^T| = {asym:.3g} > {SYM_TOL:g} max |M| "
                         f"= {SYM_TOL * scale:.3g}")
    if sps.issparse(M) or np.count_nonzero(M - np.diag(diag)) == 0:
        return
    try:
        np.linalg.cholesky(M + SYM_TOL * scale * np.eye(M.shape[0]))
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(0.5 * (M + M.T))[0])
        raise ValueError(f"M is not positive semi-definite: its smallest eigenvalue is "
                         f"{low:.6g} (a mass matrix has none below 0)") from None


def solver(A, what: str, why: str = ""):
    """``solve(B) = A^-1 B`` by sparse or dense LU, factorized once; ValueError naming ``what``
    when A is singular or numerically singular (condition number * n * eps >= 1)."""
    if sps.issparse(A):
        return sparse_lu(A, what, why).solve
    lu_piv = dense_lu(A, what, why)
    return lambda B: sla.lu_solve(lu_piv, B, check_finite=False)


#: the column orderings `sparse_lu` tries when asked for the least fill: minimum degree on
#: A^T + A (structural models: symmetric patterns) and COLAMD (SuperLU's default)
FILL_ORDERINGS = ("MMD_AT_PLUS_A", "COLAMD")


def sparse_lu(A, what: str, why: str = "", orderings=("COLAMD",)):
    """SuperLU (scipy.sparse.linalg.splu) of a sparse A, Pr A Pc = L U: of the column orderings
    in ``orderings``, the one whose L and U have the fewest entries (a factorization per
    ordering: worth it when the factors are applied many times). ValueError naming ``what``
    when A is singular or a pivot is below eps of the largest (no digit of the solve left)."""
    tail = f": {why}" if why else ""
    A = sps.csc_matrix(A)
    best = None
    for spec in orderings:
        try:
            lu = spla.splu(A, permc_spec=spec)
        except RuntimeError as exc:
            raise ValueError(f"{what} is singular ({exc}){tail}") from None
        if best is None or lu.L.nnz + lu.U.nnz < best.L.nnz + best.U.nnz:
            best = lu
    pivots = np.abs(best.U.diagonal())
    if not np.isfinite(pivots).all() or pivots.min() <= np.finfo(float).eps * pivots.max():
        raise ValueError(f"{what} is singular or numerically singular (LU pivots from "
                         f"{pivots.min():.3g} to {pivots.max():.3g}){tail}")
    return best


def dense_lu(A, what: str, why: str = ""):
    """(LU, piv) of a dense A (scipy.linalg.lu_factor), with the singularity check of `solver`."""
    tail = f": {why}" if why else ""
    n = A.shape[0]
    cond = np.linalg.cond(A)
    if not np.isfinite(cond) or cond * n * np.finfo(float).eps >= 1.0:
        raise ValueError(f"{what} is singular or numerically singular (condition number "
                         f"{cond:.3g}){tail}")
    return sla.lu_factor(A, check_finite=False)


def node_blocks(A):
    """The 2 x 2 node blocks of a matrix with two DOFs per node, node by node: D[i] = A[node i,
    node i], E[i] = A[node i, node i + 1], F[i] = A[node i + 1, node i] (arrays (nodes, 2, 2),
    (nodes - 1, 2, 2) twice)."""
    A = sps.csr_matrix(A)
    nodes = A.shape[0] // 2
    i = 2 * np.arange(nodes)
    D, E, F = (np.empty((k, 2, 2)) for k in (nodes, nodes - 1, nodes - 1))
    for a in range(2):
        for b in range(2):
            D[:, a, b] = A[i + a, i + b].A1
            E[:, a, b] = A[i[:-1] + a, i[1:] + b].A1
            F[:, a, b] = A[i[1:] + a, i[:-1] + b].A1
    return D, E, F
