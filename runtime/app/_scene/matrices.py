"""Scene models with general matrices (``kind = "matrices"``): inline arrays, an .npz file or
Matrix Market files, DOF names, Rayleigh or modal damping."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import scipy.sparse as sps

from dtdyn.app._loads import finite_number
from dtdyn.app._scene.schema import (_MATRIX_DAMPING_KEYS, _MATRIX_MODEL_KEYS, _MATRIX_NAMES,
                                    _MTX_SUFFIXES, _number_list, _table)

def _inline_matrix(name: str, value) -> np.ndarray:
    """A matrix written in the scene as an array of rows (each an array of numbers)."""
    if not isinstance(value, list) or not value:
        raise ValueError(f"{name} = {value!r}: must be a non-empty array of rows (nested arrays of "
                         "numbers) or a Matrix Market file path")
    n_cols = None
    for i, row in enumerate(value):
        if not isinstance(row, list):
            raise ValueError(f"{name}[{i}] = {row!r}: every row must be an array of numbers")
        if n_cols is None:
            n_cols = len(row)
        elif len(row) != n_cols:
            raise ValueError(f"{name}[{i}] has {len(row)} entries, row 0 has {n_cols}: "
                             "all rows must have the same length")
        for j, v in enumerate(row):
            finite_number(f"{name}[{i}][{j}]", v)
    return np.array(value, dtype=float)


def _resolve_file(name: str, raw, base_dir: Path, suffixes: tuple[str, ...]) -> Path:
    if not isinstance(raw, str) or not raw.strip():
        raise ValueError(f"{name} = {raw!r}: must be a non-empty file path")
    path = Path(base_dir) / raw
    if not path.name.lower().endswith(suffixes):
        raise ValueError(f"{name} = {raw!r}: unsupported file type, allowed: "
                         f"{', '.join(map(repr, suffixes))}")
    if not path.is_file():
        raise ValueError(f"{name} = {raw!r}: no such file {str(path)!r}")
    return path


def _mtx_matrix(name: str, raw: str, base_dir: Path):
    """A matrix from a Matrix Market file: CSR when the file is in coordinate format."""
    import scipy.io

    path = _resolve_file(name, raw, base_dir, _MTX_SUFFIXES)
    try:
        A = scipy.io.mmread(path)
    except Exception as exc:  # noqa: BLE001 - any parse failure becomes a field-naming error
        raise ValueError(f"{name} = {raw!r}: cannot read {str(path)!r} as Matrix Market: "
                         f"{exc}") from None
    if sps.issparse(A):
        if np.iscomplexobj(A.data):
            raise ValueError(f"{name} = {raw!r}: complex entries, the matrix must be real")
        return sps.csr_matrix(A, dtype=float)
    if np.iscomplexobj(A):
        raise ValueError(f"{name} = {raw!r}: complex entries, the matrix must be real")
    return np.asarray(A, dtype=float)


def _npz_matrices(raw, base_dir: Path) -> dict:
    path = _resolve_file("model.file", raw, base_dir, (".npz",))
    try:
        with np.load(path, allow_pickle=False) as z:
            names = list(z.files)
            extra = [k for k in names if k not in _MATRIX_NAMES]
            if extra:
                raise ValueError(f"model.file = {raw!r}: unexpected array(s) {', '.join(extra)}; "
                                 "allowed: M, K, C (sparse matrices: use Matrix Market files)")
            for key in ("M", "K"):
                if key not in names:
                    raise ValueError(f"model.file = {raw!r}: has no array {key!r} "
                                     f"(found: {', '.join(names) or 'none'})")
            out = {}
            for key in names:
                arr = z[key]
                if not (np.issubdtype(arr.dtype, np.floating)
                        or np.issubdtype(arr.dtype, np.integer)):
                    raise ValueError(f"model.file = {raw!r}: array {key} has dtype {arr.dtype}, "
                                     "must be real numbers")
                out[key] = np.array(arr, dtype=float)
            return out
    except ValueError as exc:
        if str(exc).startswith("model.file"):
            raise
        raise ValueError(f"model.file = {raw!r}: cannot read {str(path)!r}: {exc}") from None
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"model.file = {raw!r}: cannot read {str(path)!r}: {exc}") from None


def _check_matrix(label: str, A, n: int | None = None):
    """Square (n x n when given), non-empty and finite; ``label`` names the field in errors."""
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise ValueError(f"{label} has shape {A.shape}: must be a non-empty square matrix")
    if n is not None and A.shape != (n, n):
        raise ValueError(f"{label} has shape {A.shape}, expected {(n, n)} to match model.M")
    if sps.issparse(A):
        coo = A.tocoo()
        bad = ~np.isfinite(coo.data)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            i, j, v = int(coo.row[k]), int(coo.col[k]), float(coo.data[k])
            raise ValueError(f"{label}[{i}, {j}] = {v!r}: every entry must be finite")
    else:
        bad = ~np.isfinite(A)
        if bad.any():
            i, j = (int(x) for x in np.argwhere(bad)[0])
            raise ValueError(f"{label}[{i}, {j}] = {float(A[i, j])!r}: every entry must be finite")
    return A


def _read_matrices(model: dict, base_dir: Path) -> dict:
    """M, K and C (None when absent) as given: dense ndarrays and/or sparse CSR."""
    labels = {}
    if "file" in model:
        both = [k for k in _MATRIX_NAMES if k in model]
        if both:
            raise ValueError(f"model.file = {model['file']!r} and model.{both[0]} are both given: "
                             "take the matrices from one place")
        mats = _npz_matrices(model["file"], base_dir)
        for key in mats:
            labels[key] = f"model.file = {model['file']!r}: array {key}"
    else:
        mats = {}
        for key in _MATRIX_NAMES:
            if key not in model:
                if key != "C":
                    raise ValueError(f"model.{key} is required for model.kind = 'matrices' "
                                     "(or give model.file, an .npz with arrays M, K, C)")
                continue
            value = model[key]
            if isinstance(value, str):
                mats[key] = _mtx_matrix(f"model.{key}", value, base_dir)
                labels[key] = f"model.{key} = {value!r}: matrix"
            else:
                mats[key] = _inline_matrix(f"model.{key}", value)
                labels[key] = f"model.{key}"
    _check_matrix(labels["M"], mats["M"])
    n = mats["M"].shape[0]
    for key in ("K", "C"):
        if key in mats:
            _check_matrix(labels[key], mats[key], n)
    mats.setdefault("C", None)
    return mats


def _symmetric(A: np.ndarray) -> bool:
    scale = float(np.max(np.abs(A))) if A.size else 0.0
    return float(np.max(np.abs(A - A.T))) <= 1e-10 * max(scale, 1e-300)


def _modal_damping(zeta: np.ndarray, M: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``M Phi diag(2 zeta_r omega_r) Phi^T M`` with ``Phi^T M Phi = I`` (scipy.linalg.eigh)."""
    import scipy.linalg

    where = "model.damping.modal"
    if not _symmetric(M):
        raise ValueError(f"{where} needs a symmetric positive definite model.M; M is not symmetric")
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise ValueError(f"{where} needs a symmetric positive definite model.M; M is not positive "
                         "definite") from None
    if not _symmetric(K):
        raise ValueError(f"{where} needs a symmetric model.K; K is not symmetric")
    try:
        lam, phi = scipy.linalg.eigh(K, M)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ValueError(f"{where}: the eigenproblem K phi = omega^2 M phi failed: {exc}") from None
    tol = 1e-9 * max(float(np.max(np.abs(lam))), 1e-300)
    if lam.min() < -tol:
        raise ValueError(f"{where} needs a positive semidefinite model.K; K has the eigenvalue "
                         f"omega^2 = {lam.min():.6g} < 0")
    omega = np.sqrt(np.clip(lam, 0.0, None))
    if zeta.size == 1:
        zeta = np.full(omega.size, float(zeta[0]))
    MPhi = M @ phi
    return (MPhi * (2.0 * zeta * omega)) @ MPhi.T


def _parse_damping_options(tbl, n: int) -> tuple[str | None, np.ndarray | None]:
    _table("model.damping", tbl, _MATRIX_DAMPING_KEYS)
    if "rayleigh" in tbl and "modal" in tbl:
        raise ValueError(f"model.damping.rayleigh = {tbl['rayleigh']!r} and model.damping.modal = "
                         f"{tbl['modal']!r} are both given: choose one")
    if "rayleigh" in tbl:
        coef = _number_list("model.damping.rayleigh", tbl["rayleigh"], nonnegative=True)
        if coef.size != 2:
            raise ValueError(f"model.damping.rayleigh = {tbl['rayleigh']!r}: must be [alpha, beta] "
                             "(C += alpha M + beta K)")
        return "rayleigh", coef
    if "modal" in tbl:
        zeta = _number_list("model.damping.modal", tbl["modal"], nonnegative=True)
        if zeta.size not in (1, n):
            raise ValueError(f"model.damping.modal = {tbl['modal']!r}: has {zeta.size} ratios, "
                             f"give one (all modes) or {n} (one per mode, ascending frequency)")
        return "modal", zeta
    return None, None


def _parse_dof_names(value, n: int) -> tuple[str, ...]:
    if value is None:
        return tuple(str(i) for i in range(n))
    if not isinstance(value, list):
        raise ValueError(f"model.dofs = {value!r}: must be an array of {n} DOF names (strings)")
    for i, v in enumerate(value):
        if not isinstance(v, str) or not v.strip():
            raise ValueError(f"model.dofs[{i}] = {v!r}: every DOF name must be a non-empty string")
    if len(value) != n:
        raise ValueError(f"model.dofs has {len(value)} names, expected {n} (one per row of "
                         "model.M)")
    seen = set()
    for i, v in enumerate(value):
        if v in seen:
            raise ValueError(f"model.dofs[{i}] = {v!r}: repeats a DOF name")
        seen.add(v)
    return tuple(value)


def _parse_matrix_model(model: dict, base_dir: Path):
    """(M, C, K, dof_names) of a ``kind = "matrices"`` model, damping options added to C."""
    _table("model", model, _MATRIX_MODEL_KEYS)
    mats = _read_matrices(model, base_dir)
    M, K, C = mats["M"], mats["K"], mats["C"]
    n = M.shape[0]
    names = _parse_dof_names(model.get("dofs"), n)
    sparse = model.get("sparse")
    if sparse is not None and not isinstance(sparse, bool):
        raise ValueError(f"model.sparse = {sparse!r}: must be true or false")
    if sparse is None:  # as read; a mix of dense and sparse becomes sparse
        sparse = any(sps.issparse(A) for A in (M, K, C) if A is not None)
    if C is None:
        C = sps.csr_matrix((n, n)) if sparse else np.zeros((n, n))
    if sparse:
        M, C, K = (sps.csr_matrix(A, dtype=float) for A in (M, C, K))
    else:
        M, C, K = (A.toarray() if sps.issparse(A) else np.asarray(A, dtype=float)
                   for A in (M, C, K))
    damping = model.get("damping", {})
    option, values = _parse_damping_options(damping, n)
    if option == "rayleigh":
        C = C + values[0] * M + values[1] * K
    elif option == "modal":
        dense = (A.toarray() if sps.issparse(A) else A for A in (M, K))
        extra = _modal_damping(values, *dense)
        C = C + (sps.csr_matrix(extra) if sparse else extra)
    if sparse:
        C = sps.csr_matrix(C)
    return M, C, K, names
