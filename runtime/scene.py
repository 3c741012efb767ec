"""Scenes: a model (a chain or general M, C, K matrices), its loads, a scheme and a time grid,
read from a TOML file.

Layout of a scene file (``load_scene(None)`` reads the embedded default ``scenes/p3.toml``,
reference problem P3)::

    title = "..."                       # optional, default: the file name
    [model]                             # chain: ground -k1,c1- m1 -k2,c2- m2 ... mN (free)
    mass = [...]                        # kg, every entry > 0
    stiffness = [...]                   # N/m, every entry > 0, same length
    damping = [...]                     # N s/m, >= 0, optional (zeros)
    [[load]]                            # one or more; loads on the same dof add up
    dof = 14                            # 0-based mass index
    kind = "step"                       # and that kind's fields, see dtdyn.runtime.loads
    amplitude = 1.0
    [scheme]
    name = "newmark"                    # plus that scheme's parameters: beta = 0.25, gamma = 0.5
    form = "displacement"               # optional
    sweep = "stable"                    # optional
    backend = "c"                       # optional
    [time]
    dt = 1e-3                           # s
    duration = 0.8                      # s, an integer multiple of dt: n_steps = duration / dt
    [output]                            # optional
    dofs = [0, 14]                      # optional, default all
    quantities = ["x", "v", "a"]        # optional, default ["x"]

A model with general matrices (``kind = "matrices"``) replaces the chain keys of ``[model]``::

    [model]
    kind = "matrices"                   # default "chain" (the layout above)
    M = [[2.0, 0.0], [0.0, 1.0]]        # inline nested arrays (rows), or a Matrix Market path
    K = [[30.0, -10.0], [-10.0, 10.0]]  #   such as "k.mtx" (scipy.io.mmread; read as sparse)
    C = [[0.0, 0.0], [0.0, 0.0]]        # optional (zeros)
    # file = "model.npz"                # instead of M, K, C: an .npz with arrays M, K and
                                        #   optionally C (numpy.savez)
    dofs = ["floor", "roof"]            # optional DOF names (default "0", "1", ...)
    sparse = true                       # optional: true -> scipy.sparse CSR, false -> dense;
                                        #   omitted: as read (sparse if any matrix is sparse)
    [model.damping]                     # optional, added to C; at most one of:
    rayleigh = [0.5, 1e-3]              # C += alpha M + beta K  (alpha, beta >= 0)
    # modal = [0.02]                    # modal damping ratios zeta_r (one for all modes, or one
                                        #   per mode, ascending frequency):
                                        #   C += M Phi diag(2 zeta_r omega_r) Phi^T M, Phi the
                                        #   M-normalised eigenvectors of (K, M) (dense; needs M
                                        #   symmetric positive definite and K symmetric)

Paths are relative to the scene file. ``load.dof`` and ``output.dofs`` entries of such a scene
are 0-based indices or names from ``model.dofs``. It runs with ``simulate_mck`` (any scheme,
acceleration form, dense or sparse); ``scheme.form``, ``scheme.sweep`` and ``scheme.backend``
belong to chains and are rejected.

Every error is a ``ValueError`` that names the file and the field, e.g.
``p3.toml: model.mass[3] = -1.0: every entry must be finite and > 0``.
"""
from __future__ import annotations

import importlib.resources
import os
import tempfile
import time
import tomllib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sps

from . import validate
from .loads import finite_number, sample_load
from .result import Response

__all__ = ["Scene", "load_scene", "scene_from_dict", "run_scene", "save_results", "plot_response",
           "SCHEMES", "FORMS", "SWEEPS", "BACKENDS", "QUANTITIES", "EXACT_MAX_DOF", "MODEL_KINDS"]

#: scheme name -> {parameter: (lower bound, upper bound)} (inclusive; None: unbounded)
SCHEMES: dict[str, dict[str, tuple[float | None, float | None]]] = {
    "fox_euler": {},
    "newmark": {"beta": (0.0, None), "gamma": (0.0, None)},
    "average_acceleration": {},
    "linear_acceleration": {},
    "fox_goodwin": {},
    "newmark_1_8": {},
    "central_difference": {},
    "wilson": {"theta": (1.0, None)},
    "houbolt": {},
    "park": {},
    "hht": {"alpha": (-1.0 / 3.0, 0.0)},
    "generalized_alpha": {"rho_inf": (0.0, 1.0)},
}
FORMS = ("displacement", "acceleration")
SWEEPS = ("stable", "plain")
BACKENDS = ("c", "numpy")
QUANTITIES = ("x", "v", "a")
#: run_scene compares with the matrix-exponential solution up to this many DOFs
EXACT_MAX_DOF = 2000

_TOP_KEYS = ("title", "model", "load", "scheme", "time", "output")
#: model kinds: a chain (mass, stiffness, damping vectors) or general M, C, K matrices
MODEL_KINDS = ("chain", "matrices")
_MODEL_KEYS = ("kind", "mass", "stiffness", "damping")
_MATRIX_MODEL_KEYS = ("kind", "M", "K", "C", "file", "dofs", "sparse", "damping")
_MATRIX_DAMPING_KEYS = ("rayleigh", "modal")
_MATRIX_NAMES = ("M", "K", "C")
_MTX_SUFFIXES = (".mtx", ".mtx.gz", ".mtx.bz2")
_TIME_KEYS = ("dt", "duration")
_OUTPUT_KEYS = ("dofs", "quantities")
_SCHEME_COMMON = ("name", "form", "sweep", "backend")

DEFAULT_SCENE = "scenes/p3.toml"


@dataclass
class Scene:
    """A validated scene: what ``simulate_chain`` or ``simulate_mck`` needs, plus what to store.

    ``force`` has shape ``(n_steps + 1, len(loaded))``: column ``j`` is the sum of the loads on
    the 0-based DOF ``loaded[j]`` sampled at ``t_0 .. t_n``.

    ``kind`` is ``"chain"`` (``mass``, ``stiffness``, ``damping`` set; ``M``, ``C``, ``K`` None)
    or ``"matrices"`` (``M``, ``C``, ``K`` set, all dense ndarrays or all scipy.sparse CSR, damping
    options already added to ``C``; ``mass``, ``stiffness``, ``damping`` None; ``dof_names`` one
    name per DOF; ``form = "acceleration"``, ``sweep = None``, ``backend`` ``"numpy"`` or
    ``"scipy.sparse"``).
    """

    title: str
    mass: np.ndarray | None
    stiffness: np.ndarray | None
    damping: np.ndarray | None
    loads: list[dict]
    loaded: np.ndarray
    force: np.ndarray
    scheme: str
    scheme_params: dict
    form: str
    sweep: str | None
    backend: str
    dt: float
    n_steps: int
    outputs: np.ndarray
    quantities: tuple[str, ...] = ("x",)
    source: str = "<scene>"
    base_dir: Path = field(default_factory=Path.cwd)
    kind: str = "chain"
    M: np.ndarray | sps.csr_matrix | None = None
    C: np.ndarray | sps.csr_matrix | None = None
    K: np.ndarray | sps.csr_matrix | None = None
    dof_names: tuple[str, ...] | None = None

    @property
    def n_dof(self) -> int:
        if self.kind == "matrices":
            return int(self.M.shape[0])
        return int(self.mass.size)

    @property
    def sparse(self) -> bool:
        """True for a matrices scene held as scipy.sparse matrices."""
        return self.kind == "matrices" and sps.issparse(self.M)

    def dof_label(self, dof: int) -> str:
        """Name of a 0-based DOF for labels: its ``model.dofs`` name, else its index."""
        if self.dof_names is not None:
            return self.dof_names[int(dof)]
        return str(int(dof))

    @property
    def duration(self) -> float:
        return self.n_steps * self.dt

    @property
    def t(self) -> np.ndarray:
        """Sample times ``t_i = i dt``, ``i = 0 .. n_steps``."""
        return np.arange(self.n_steps + 1) * self.dt

    @property
    def linear(self) -> bool:
        """Scenes hold linear chains only (no nonlinear elements in the file format yet)."""
        return True


# ----------------------------------------------------------------------------------------------
# validation helpers

def _table(name: str, value, allowed: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{name} = {value!r}: must be a table [{name}]")
    for key in value:
        if key not in allowed:
            raise ValueError(f"{name}.{key} = {value[key]!r}: unknown key, allowed: {', '.join(allowed)}")
    return value


def _required(name: str, table: dict, key: str):
    if key not in table:
        raise ValueError(f"{name}.{key} is required")
    return table[key]


def _number_list(name: str, value, **checks) -> np.ndarray:
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{name} = {value!r}: must be an array of numbers")
    for i, v in enumerate(value):
        finite_number(f"{name}[{i}]", v)
        # checked here as well as in validate.vector so the message shows the TOML value
        if (checks.get("positive") and v <= 0) or (checks.get("nonnegative") and v < 0):
            need = "> 0" if checks.get("positive") else ">= 0"
            raise ValueError(f"{name}[{i}] = {v!r}: every entry must be finite and {need}")
    return validate.vector(name, value, **checks)


def _choice(name: str, value, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} = {value!r}: unknown value, allowed: {', '.join(map(repr, allowed))}")
    return value


def _parse_model(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _table("model", model, _MODEL_KEYS)
    mass = _number_list("model.mass", _required("model", model, "mass"), positive=True)
    n = mass.size
    stiffness = _number_list("model.stiffness", _required("model", model, "stiffness"),
                             positive=True, length=n)
    if "damping" in model:
        damping = _number_list("model.damping", model["damping"], nonnegative=True, length=n)
    else:
        damping = np.zeros(n)
    return mass, stiffness, damping


def _model_kind(model) -> str:
    if not isinstance(model, dict):
        raise ValueError(f"model = {model!r}: must be a table [model]")
    return _choice("model.kind", model.get("kind", "chain"), MODEL_KINDS)


# --- general matrices -------------------------------------------------------------------------

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
                if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
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
            raise ValueError(f"model.damping.modal = {tbl['modal']!r}: has {zeta.size} ratios, give "
                             f"one (all modes) or {n} (one per mode, ascending frequency)")
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
        raise ValueError(f"model.dofs has {len(value)} names, expected {n} (one per row of model.M)")
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


def _dof_index(name: str, value, n_dof: int, names: tuple[str, ...] | None) -> int:
    """A 0-based DOF from an integer index or (with ``names``) a DOF name."""
    if names is not None and isinstance(value, str):
        if value in names:
            return names.index(value)
        shown = ", ".join(map(repr, names[:12])) + (", ..." if len(names) > 12 else "")
        raise ValueError(f"{name} = {value!r}: unknown DOF name, model.dofs has {shown}")
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n_dof:
        if names is None:
            raise ValueError(f"{name} = {value!r}: must be an integer mass index in 0..{n_dof - 1}")
        raise ValueError(f"{name} = {value!r}: must be a DOF index in 0..{n_dof - 1} or a DOF "
                         "name from model.dofs")
    return value


def _parse_time(tbl) -> tuple[float, int]:
    _table("time", tbl, _TIME_KEYS)
    dt = validate.positive_scalar("time.dt", finite_number("time.dt", _required("time", tbl, "dt")))
    duration = validate.positive_scalar(
        "time.duration", finite_number("time.duration", _required("time", tbl, "duration")))
    ratio = duration / dt
    n_steps = int(round(ratio))
    if abs(ratio - n_steps) > 1e-9 * max(ratio, 1.0):
        raise ValueError(f"time.duration = {tbl['duration']!r}: not an integer multiple of "
                         f"time.dt = {tbl['dt']!r} (duration/dt = {ratio!r})")
    return dt, validate.step_count("time.duration / time.dt", n_steps)


def _parse_scheme(tbl, kind: str = "chain") -> tuple[str, dict, str, str | None, str]:
    if not isinstance(tbl, dict):
        raise ValueError(f"scheme = {tbl!r}: must be a table [scheme]")
    if kind == "matrices":
        for key in ("form", "sweep", "backend"):
            if key in tbl:
                raise ValueError(f"scheme.{key} = {tbl[key]!r}: only for chain models; a model "
                                 "with kind = 'matrices' runs simulate_mck (acceleration form, "
                                 "dense or sparse as the matrices are): remove the key")
    name = tbl.get("name")
    if name is None:
        raise ValueError(f"scheme.name is required, allowed: {', '.join(SCHEMES)}")
    _choice("scheme.name", name, tuple(SCHEMES))
    bounds = SCHEMES[name]
    _table("scheme", tbl, _SCHEME_COMMON + tuple(bounds))
    params = {}
    for key, (lo, hi) in bounds.items():
        if key not in tbl:
            continue
        v = finite_number(f"scheme.{key}", tbl[key])
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            rng = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
            raise ValueError(f"scheme.{key} = {tbl[key]!r}: must lie in {rng} for scheme {name!r}")
        params[key] = v
    if kind == "matrices":
        return name, params, "acceleration", None, ""  # backend: set from the matrices
    form = _choice("scheme.form", tbl.get("form", "displacement"), FORMS)
    sweep = _choice("scheme.sweep", tbl.get("sweep", "stable"), SWEEPS)
    backend = _choice("scheme.backend", tbl.get("backend", "c"), BACKENDS)
    return name, params, form, sweep, backend


def _parse_output(tbl, n_dof: int, names: tuple[str, ...] | None = None
                  ) -> tuple[np.ndarray, tuple[str, ...]]:
    _table("output", tbl, _OUTPUT_KEYS)
    dofs = tbl.get("dofs")
    if names is not None and dofs is not None:  # indices or DOF names
        if not isinstance(dofs, list) or not dofs:
            raise ValueError(f"output.dofs = {dofs!r}: must be a non-empty array of DOF indices "
                             "or names")
        given = dofs
        dofs = [_dof_index(f"output.dofs[{i}]", d, n_dof, names) for i, d in enumerate(given)]
        for i, d in enumerate(dofs):
            if d in dofs[:i]:
                raise ValueError(f"output.dofs = {given!r}: entry {i} ({given[i]!r}) repeats "
                                 f"DOF {d} ({names[d]!r})")
    elif dofs is not None and (not isinstance(dofs, list)
                               or any(isinstance(d, bool) or not isinstance(d, int) for d in dofs)):
        raise ValueError(f"output.dofs = {dofs!r}: must be an array of integer DOF indices")
    outputs = validate.dof_indices("output.dofs", dofs, n_dof)
    quantities = tbl.get("quantities", ["x"])
    if not isinstance(quantities, list) or not quantities:
        raise ValueError(f"output.quantities = {quantities!r}: must be a non-empty array, "
                         f"allowed entries: {', '.join(map(repr, QUANTITIES))}")
    for i, q in enumerate(quantities):
        _choice(f"output.quantities[{i}]", q, QUANTITIES)
    if len(set(quantities)) != len(quantities):
        raise ValueError(f"output.quantities = {quantities!r}: repeats an entry")
    return outputs, tuple(quantities)


def _parse_loads(loads, n_dof: int, t: np.ndarray, base_dir: Path,
                 names: tuple[str, ...] | None = None):
    if not isinstance(loads, list) or not loads or not all(isinstance(x, dict) for x in loads):
        raise ValueError(f"load = {loads!r}: must be one or more [[load]] tables")
    columns: dict[int, np.ndarray] = {}
    for i, spec in enumerate(loads):
        name = f"load[{i}]"
        dof = _dof_index(f"{name}.dof", _required(name, spec, "dof"), n_dof, names)
        samples = sample_load(spec, t, base_dir, name=name, extra_keys=("dof",))
        columns[dof] = columns[dof] + samples if dof in columns else samples
    loaded = np.array(sorted(columns), dtype=np.int64)
    force = np.column_stack([columns[d] for d in loaded])
    return [dict(x) for x in loads], loaded, validate.force_samples(force, t.size - 1, loaded)


# ----------------------------------------------------------------------------------------------
# public API

def scene_from_dict(data: dict, base_dir: Path | str = ".", source: str = "<scene>") -> Scene:
    """Validate a parsed scene (the dict ``tomllib`` returns) and build a :class:`Scene`.

    ``base_dir`` is where ``file`` loads and matrix files (``model.file``, ``.mtx`` paths) are
    looked for. Errors are ``ValueError`` naming the field (without the file name;
    :func:`load_scene` adds it).
    """
    if not isinstance(data, dict):
        raise ValueError(f"a scene must be a table, got {type(data).__name__}")
    for key in data:
        if key not in _TOP_KEYS:
            raise ValueError(f"{key}: unknown top-level key or table, allowed: {', '.join(_TOP_KEYS)}")
    for key in ("model", "load", "scheme", "time"):
        if key not in data:
            hint = "[[load]]" if key == "load" else f"[{key}]"
            raise ValueError(f"{key} is required: add a {hint} table")
    title = data.get("title", Path(source).stem)
    if not isinstance(title, str):
        raise ValueError(f"title = {title!r}: must be a string")

    base_dir = Path(base_dir)
    kind = _model_kind(data["model"])
    M = C = K = names = None
    mass = stiffness = damping = None
    if kind == "matrices":
        M, C, K, names = _parse_matrix_model(data["model"], base_dir)
        n_dof = M.shape[0]
    else:
        mass, stiffness, damping = _parse_model(data["model"])
        n_dof = mass.size
    dt, n_steps = _parse_time(data["time"])
    scheme, params, form, sweep, backend = _parse_scheme(data["scheme"], kind)
    if kind == "matrices":
        backend = "scipy.sparse" if sps.issparse(M) else "numpy"
    outputs, quantities = _parse_output(data.get("output", {}), n_dof, names)
    t = np.arange(n_steps + 1) * dt
    loads, loaded, force = _parse_loads(data["load"], n_dof, t, base_dir, names)
    return Scene(title=title, mass=mass, stiffness=stiffness, damping=damping, loads=loads,
                 loaded=loaded, force=force, scheme=scheme, scheme_params=params, form=form,
                 sweep=sweep, backend=backend, dt=dt, n_steps=n_steps, outputs=outputs,
                 quantities=quantities, source=source, base_dir=base_dir, kind=kind, M=M, C=C, K=K,
                 dof_names=names)


def load_scene(path: str | os.PathLike | None = None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : path or None
        A TOML scene file; ``None`` reads the embedded default ``scenes/p3.toml`` (reference
        problem P3: 15-DOF undamped chain, unit step on mass 15, T = 0.8 s, dt = 1e-3, average
        acceleration, all masses stored).

    Returns
    -------
    Scene

    Raises
    ------
    ValueError
        ``"<file>: <field> = <value>: <what is wrong>"``: unreadable file, TOML syntax, unknown
        table or key, invalid value.

    Example
    -------
    >>> load_scene().n_dof
    15
    """
    if path is None:
        resource = importlib.resources.files("dtdyn.runtime").joinpath(DEFAULT_SCENE)
        source = f"dtdyn.runtime/{DEFAULT_SCENE}"
        text = resource.read_text(encoding="utf-8")
        base_dir = Path(str(resource)).parent if isinstance(resource, Path) else Path.cwd()
    else:
        file = Path(path)
        source = str(file)
        try:
            text = file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ValueError(f"{source}: cannot read the scene file: {exc}") from None
        base_dir = file.parent
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: invalid TOML: {exc}") from None
    try:
        return scene_from_dict(data, base_dir, source)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def natural_frequencies(scene: Scene) -> np.ndarray:
    """Undamped natural frequencies (rad/s) to check stability against: all of them up to
    EXACT_MAX_DOF DOFs, else the highest only (the one conditionally stable schemes lose first)."""
    import scipy.linalg as sla
    import scipy.sparse as sps

    if scene.kind == "matrices":
        if scene.n_dof > EXACT_MAX_DOF:
            return np.array([])
        M, K = (A.toarray() if sps.issparse(A) else np.asarray(A) for A in (scene.M, scene.K))
        try:
            lam = sla.eigh(K, M, eigvals_only=True)
        except (np.linalg.LinAlgError, ValueError):  # singular or indefinite M: skip the check
            return np.array([])
        return np.sqrt(np.clip(lam, 0.0, None))
    m, k = scene.mass, scene.stiffness
    s = 1.0 / np.sqrt(m)
    kk = k + np.append(k[1:], 0.0)
    d, e = kk * s * s, -k[1:] * s[:-1] * s[1:]  # M^-1/2 K M^-1/2, tridiagonal
    n = m.size
    sel = {} if n <= EXACT_MAX_DOF else {"select": "i", "select_range": (n - 1, n - 1)}
    lam = sla.eigh_tridiagonal(d, e, eigvals_only=True, **sel)
    return np.sqrt(np.clip(lam, 0.0, None))


def check_stability(scene: Scene) -> bool:
    """Warn before a run whose dt makes the scheme unstable for a mode of the model."""
    from .stability import warn_if_unstable

    omegas = natural_frequencies(scene)
    omegas = omegas[omegas > 0.0]
    if omegas.size == 0:
        return False
    return warn_if_unstable(scene.scheme, omegas, scene.dt, **scene.scheme_params)


def run_scene(scene: Scene, progress: bool = False) -> tuple[Response, dict]:
    """Simulate a scene with ``simulate_chain`` (chains) or ``simulate_mck`` (general matrices)
    and report run time and error.

    The error is measured against the matrix-exponential solution (``exact_response``) when the
    scene is linear and has at most ``EXACT_MAX_DOF`` DOFs (and, for matrices, a mass matrix
    that is not numerically singular; the matrices are converted to dense for it)::

        max_rel_error = max_{i, j} |x[i, j] - x_exact[i, j]| / max_{i, j} |x_exact[i, j]|

    over all samples ``i`` and stored outputs ``j`` (``None`` when not computed).

    Returns
    -------
    response : Response
        Sampled at ``t_0 .. t_n`` for the DOFs ``scene.outputs``.
    report : dict
        ``title, scheme, scheme_params, form, sweep, backend, dt, n_steps, n_dof, n_outputs,
        run_time_s, exact_time_s, max_rel_error``. For matrices ``form`` is ``"acceleration"``,
        ``sweep`` None and ``backend`` ``"numpy"`` (dense) or ``"scipy.sparse"``.
    """
    check_stability(scene)
    start = time.perf_counter()
    if scene.kind == "matrices":
        from . import mck

        response = mck.simulate_mck(
            scene.M, scene.C, scene.K, scene.force, scene.dt, scene.n_steps, loaded=scene.loaded,
            scheme=scene.scheme, outputs=scene.outputs, quantities=scene.quantities,
            progress=progress, **scene.scheme_params)
        response.info.setdefault("backend", scene.backend)
    else:
        from . import chain  # imported here: chain may compile kernels on first use

        response = chain.simulate_chain(
            scene.mass, scene.stiffness, scene.damping, scene.force, scene.dt, scene.n_steps,
            loaded=scene.loaded, scheme=scene.scheme, form=scene.form, sweep=scene.sweep,
            backend=scene.backend, outputs=scene.outputs, quantities=scene.quantities,
            progress=progress, **scene.scheme_params)
    run_time = time.perf_counter() - start

    report = {
        "title": scene.title, "scheme": scene.scheme, "scheme_params": dict(scene.scheme_params),
        "form": scene.form, "sweep": scene.sweep, "backend": scene.backend, "dt": scene.dt,
        "n_steps": scene.n_steps, "n_dof": scene.n_dof, "n_outputs": int(scene.outputs.size),
        "run_time_s": run_time, "exact_time_s": None, "max_rel_error": None,
    }
    if scene.linear and scene.n_dof <= EXACT_MAX_DOF and response.x is not None:
        from . import exact

        if scene.kind == "matrices":
            matrices = (scene.M, scene.C, scene.K)
        else:
            matrices = chain.chain_matrices(scene.mass, scene.stiffness, scene.damping)
        M, C, K = (m.toarray() if sps.issparse(m) else np.asarray(m) for m in matrices)
        if not _nonsingular(M):  # the exact solution needs M^-1 (exact._factor_mass's test)
            return response, report
        start = time.perf_counter()
        ref = exact.exact_response(M, C, K, scene.force, scene.dt, scene.n_steps,
                                   loaded=scene.loaded, outputs=scene.outputs)
        report["exact_time_s"] = time.perf_counter() - start
        x, x_ref = np.asarray(response.x), np.asarray(ref.x)
        if x.shape != x_ref.shape:
            raise ValueError(f"response.x has shape {x.shape}, the exact solution {x_ref.shape}")
        err = float(np.max(np.abs(x - x_ref)))
        scale = float(np.max(np.abs(x_ref)))
        report["max_rel_error"] = err / scale if scale > 0.0 else (0.0 if err == 0.0 else np.inf)
    return response, report


def _nonsingular(M: np.ndarray) -> bool:
    cond = np.linalg.cond(M)
    return bool(np.isfinite(cond) and cond * M.shape[0] * np.finfo(float).eps < 1.0)


def _atomic_write(path: Path, write) -> None:
    """Call ``write(binary_file)`` on a temporary file next to ``path``, then rename it into place.

    On any failure the temporary file is removed and ``path`` is left as it was.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def save_results(path: str | os.PathLike, response: Response, scene: Scene) -> None:
    """Write ``t``, ``outputs`` and the scene's requested quantities to an ``.npz`` file.

    A scene with general matrices also stores ``dof_names``: the names of ``outputs``.

    Written atomically: to a temporary file in the same folder, then renamed over ``path``, so a
    failed write leaves no partial file (and an existing ``path`` untouched).
    """
    path = Path(path)
    arrays = {"t": np.asarray(response.t), "outputs": np.asarray(response.outputs)}
    if scene.kind == "matrices":
        arrays["dof_names"] = np.array([scene.dof_label(d) for d in arrays["outputs"]], dtype=str)
    for q in scene.quantities:
        value = getattr(response, q)
        if value is None:
            raise ValueError(f"output.quantities asks for {q!r}, but the response did not store it")
        arrays[q] = np.asarray(value)
    _atomic_write(path, lambda f: np.savez(f, **arrays))


def plot_response(path: str | os.PathLike, response: Response, scene: Scene) -> None:
    """Plot displacement against time, one labelled line per output DOF; saved atomically.

    Uses the Agg canvas directly (no pyplot, no global backend switch). The file format follows
    the suffix of ``path`` (``.png`` when there is none).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    if response.x is None:
        raise ValueError("the response has no displacement x to plot")
    fig = Figure(figsize=(8.0, 4.5), layout="constrained")
    canvas = FigureCanvasAgg(fig)
    fmt = path.suffix[1:].lower() or "png"
    if fmt not in canvas.get_supported_filetypes():
        raise ValueError(f"cannot plot to {str(path)!r}: unsupported format {fmt!r}, allowed: "
                         f"{', '.join(sorted(canvas.get_supported_filetypes()))}")
    ax = fig.add_subplot()
    x = np.asarray(response.x)
    if x.shape[1] > 10:  # more lines than the default colour cycle: colour by position instead
        from matplotlib import colormaps
        ax.set_prop_cycle(color=colormaps["viridis"](np.linspace(0.0, 0.95, x.shape[1])))
    for j, dof in enumerate(np.asarray(response.outputs)):
        if scene.kind == "matrices":
            name = scene.dof_label(dof)
            label = f"DOF {int(dof)}" if name == str(int(dof)) else f"{name} (DOF {int(dof)})"
        else:
            label = f"DOF {int(dof)} (mass {int(dof) + 1})"
        ax.plot(response.t, x[:, j], lw=1.0, label=label)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("x [m]")
    ax.set_title(f"{scene.title}\n{scene.scheme}, dt = {scene.dt:g} s", fontsize=10)
    ax.grid(True, alpha=0.3)
    if x.shape[1] <= 20:
        ax.legend(fontsize=7, ncols=1 + x.shape[1] // 8, loc="best")
    _atomic_write(path, lambda f: fig.savefig(f, format=fmt, dpi=120))
