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
    kind = "step"                       # and that kind's fields, see dtdyn.app.loads
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
    outputs = [0, 14]                   # optional, default all
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

Paths are relative to the scene file. ``load.dof`` and ``output.outputs`` entries of such a scene
are 0-based indices or names from ``model.dofs``. It runs with ``simulate_mck`` (any scheme,
acceleration form, dense or sparse); ``scheme.form``, ``scheme.sweep`` and ``scheme.backend``
belong to chains and are rejected.

Nonlinear elements (dtdyn.nonlinear.elements) join the model, chain or matrices; any
``[[element]]`` table makes the scene nonlinear (``scenes/p4.toml``, reference problem P4)::

    [[element]]                         # zero or more, in the order given
    kind = "cubic"                      # cubic | polynomial | gap | law | bouc_wen
    i = 0                               # DOF: 0-based index (or a model.dofs name for matrices)
    j = 1                               # optional, default: ground; y = q_i - q_j (y = q_i)
    k3 = 2e7                            # and that kind's fields (below)
    [scheme]                            # optional, default "modal_ramp"
    name = "modal_parabolic"            # "modal_ramp", "modal_parabolic" or a one-step scheme
                                        #   name (not houbolt, park) with its parameters
    [nonlinear]                         # optional
    substeps = 1                        # optional: steps per sample, h = dt / substeps
    backend = "c"                       # optional: "c" or "casadi"
    tol = 1e-12                         # optional: relative Newton tolerance
    max_iter = 30                       # optional: Newton iterations per step
    modes = [0, 1]                      # optional, modal methods only: the modes kept (0-based,
                                        #   sorted by |pole|), default all

Element kinds and fields (required unless a default is given; the defaults are those of the
element classes)::

    cubic       k3 (N/m^3)                          g = k3 y^3
    polynomial  coeffs = [c0, c1, ...]              g = sum_p c_p y^p
    gap         gap (m, >= 0), stiffness (N/m, > 0), smoothing (m, >= 0) [0.0],
                side ("both", "positive", "negative") ["both"]
    law         expression = "k*x**3 + c*v"         g(x, v): x = y, v = y'; arithmetic and the
                [element.constants]                 functions of dtdyn.nonlinear.expressions (parsed,
                k = 2e7                             never evaluated as Python); constants: a table
                c = 0.5                             of numbers [none]
    bouc_wen    stiffness (> 0), beta, gamma, alpha (>= 0) [0.1], A [1.0], n (>= 1) [1.0]

The scheme of a nonlinear scene is ``scheme.name`` (default ``"modal_ramp"``): a modal method
(no parameters) or a one-step scheme with its parameters (``beta = 0.3``, ...); ``scheme.form``,
``.sweep`` and ``.backend`` are refused (``nonlinear.backend`` chooses the backend). ``[nonlinear]`` without any ``[[element]]`` is an
error. A nonlinear scene runs ``nonlinear_response`` on dense M, C, K (a chain's from
``chain_matrices``; ``model.sparse = true`` is refused) with the loads sampled every ``dt``
and the stored outputs and quantities the scene asks for; it is not compared
with the exact solution.

Every error is a ``ValueError`` that names the file and the field, e.g.
``p3.toml: model.mass[3] = -1.0: every entry must be finite and > 0`` or
``p4.toml: element[1].expression = '__import__("os")': ...``.
"""
from __future__ import annotations

import importlib.resources
import os
import time
import tomllib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import validate
from dtdyn._engine.atomic import write_atomic
from dtdyn.app.loads import finite_number, sample_load
from dtdyn._engine.result import Response

__all__ = ["Scene", "load_scene", "scene_from_dict", "run_scene", "save_results", "plot_response",
           "SCHEMES", "FORMS", "SWEEPS", "BACKENDS", "QUANTITIES", "EXACT_MAX_DOF", "MODEL_KINDS",
           "ELEMENT_KINDS", "NONLINEAR_BACKENDS"]

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

_TOP_KEYS = ("title", "model", "load", "element", "nonlinear", "scheme", "time", "output")
#: model kinds: a chain (mass, stiffness, damping vectors) or general M, C, K matrices
MODEL_KINDS = ("chain", "matrices")
_MODEL_KEYS = ("kind", "mass", "stiffness", "damping")
_MATRIX_MODEL_KEYS = ("kind", "M", "K", "C", "file", "dofs", "sparse", "damping")
_MATRIX_DAMPING_KEYS = ("rayleigh", "modal")
_MATRIX_NAMES = ("M", "K", "C")
_MTX_SUFFIXES = (".mtx", ".mtx.gz", ".mtx.bz2")
_TIME_KEYS = ("dt", "duration")
_OUTPUT_KEYS = ("outputs", "quantities")
_SCHEME_COMMON = ("name", "form", "sweep", "backend")

#: element kind -> (class in dtdyn.nonlinear.elements, required fields, optional fields); the
#: optional fields' defaults are the classes' own
ELEMENT_KINDS: dict[str, tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    "cubic": ("Cubic", ("k3",), ()),
    "polynomial": ("Polynomial", ("coeffs",), ()),
    "gap": ("Gap", ("gap", "stiffness"), ("smoothing", "side")),
    "law": ("Law", ("expression",), ("constants",)),
    "bouc_wen": ("BoucWen", ("stiffness", "beta", "gamma"), ("alpha", "A", "n")),
}
#: element field -> what it must be: "number", "numbers", ">= 0", "> 0", ">= 1", "text",
#: "table", or a tuple of allowed strings
_ELEMENT_FIELDS = {
    "k3": "number", "coeffs": "numbers", "gap": ">= 0", "stiffness": "> 0", "smoothing": ">= 0",
    "side": ("both", "positive", "negative"), "expression": "text", "constants": "table",
    "alpha": ">= 0", "A": "number", "beta": "number", "gamma": "number", "n": ">= 1",
}
#: Law's own argument names, which its constants cannot take
_LAW_RESERVED = ("i", "j", "expression")
_NONLINEAR_KEYS = ("substeps", "backend", "tol", "max_iter", "modes")
NONLINEAR_BACKENDS = ("c", "casadi")
_DEFAULT_NONLINEAR_METHOD = "modal_ramp"

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

    A nonlinear scene has ``elements`` (dtdyn.nonlinear.elements objects, DOFs checked),
    ``scheme`` the method (``"modal_ramp"``, ``"modal_parabolic"`` or a one-step scheme),
    ``scheme_params`` that scheme's parameters, ``nonlinear`` the ``[nonlinear]`` options the
    file gives (``substeps``, ``tol``, ``max_iter``, ``modes``, ``backend``; the others take
    ``nonlinear_response``'s defaults), ``backend`` ``"c"`` or ``"casadi"``, ``form`` and
    ``sweep`` None; matrices are dense.
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
    form: str | None
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
    elements: tuple = ()
    nonlinear: dict = field(default_factory=dict)

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
        """True when the scene has no nonlinear elements."""
        return not self.elements


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


def _scheme_name_params(tbl: dict) -> tuple[str, dict]:
    """``scheme.name`` and its parameters, each checked against its bounds in SCHEMES."""
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
    return name, params


def _parse_scheme(tbl, kind: str = "chain") -> tuple[str, dict, str, str | None, str]:
    if not isinstance(tbl, dict):
        raise ValueError(f"scheme = {tbl!r}: must be a table [scheme]")
    if kind == "matrices":
        for key in ("form", "sweep", "backend"):
            if key in tbl:
                raise ValueError(f"scheme.{key} = {tbl[key]!r}: only for chain models; a model "
                                 "with kind = 'matrices' runs simulate_mck (acceleration form, "
                                 "dense or sparse as the matrices are): remove the key")
    name, params = _scheme_name_params(tbl)
    if kind == "matrices":
        return name, params, "acceleration", None, ""  # backend: set from the matrices
    form = _choice("scheme.form", tbl.get("form", "displacement"), FORMS)
    sweep = _choice("scheme.sweep", tbl.get("sweep", "stable"), SWEEPS)
    backend = _choice("scheme.backend", tbl.get("backend", "c"), BACKENDS)
    return name, params, form, sweep, backend


# --- nonlinear elements and options -----------------------------------------------------------

def _element_field(name: str, value, what):
    """One element field checked as ``_ELEMENT_FIELDS`` says; ``name`` e.g. ``element[0].k3``."""
    if isinstance(what, tuple):
        return _choice(name, value, what)
    if what == "text":
        if not isinstance(value, str):
            raise ValueError(f"{name} = {value!r}: must be a string (an expression such as "
                             "'k*x**3 + c*v')")
        return value
    if what == "numbers":
        if not isinstance(value, list) or not value:
            raise ValueError(f"{name} = {value!r}: must be a non-empty array of numbers")
        return [finite_number(f"{name}[{p}]", c) for p, c in enumerate(value)]
    if what == "table":
        if not isinstance(value, dict):
            raise ValueError(f"{name} = {value!r}: must be a table of numbers")
        consts = {}
        for key, c in value.items():
            if key in _LAW_RESERVED:
                raise ValueError(f"{name}.{key} = {c!r}: the name {key!r} is reserved "
                                 f"({', '.join(_LAW_RESERVED)} are the element's own fields)")
            consts[key] = finite_number(f"{name}.{key}", c)
        return consts
    v = finite_number(name, value)
    bound = {"> 0": v > 0, ">= 0": v >= 0, ">= 1": v >= 1}.get(what, True)
    if not bound:
        raise ValueError(f"{name} = {value!r}: must be {what}")
    return v


def _parse_element(k: int, spec, n_dof: int, names: tuple[str, ...] | None):
    """The element of ``[[element]]`` number k (0-based), built from checked fields."""
    from dtdyn.nonlinear import elements as el_mod

    name = f"element[{k}]"
    if not isinstance(spec, dict):
        raise ValueError(f"{name} = {spec!r}: must be an [[element]] table")
    kind = spec.get("kind")
    if kind is None:
        raise ValueError(f"{name}.kind is required, allowed: {', '.join(map(repr, ELEMENT_KINDS))}")
    _choice(f"{name}.kind", kind, tuple(ELEMENT_KINDS))
    cls_name, required, optional = ELEMENT_KINDS[kind]
    allowed = ("kind", "i", "j", *required, *optional)
    for key in spec:
        if key not in allowed:
            raise ValueError(f"{name}.{key} = {spec[key]!r}: unknown key for kind {kind!r}, "
                             f"allowed: {', '.join(allowed)}")
    for key in ("i", *required):
        if key not in spec:
            raise ValueError(f"{name}.{key} is required for kind {kind!r}")
    i = _dof_index(f"{name}.i", spec["i"], n_dof, names)
    j = None
    if "j" in spec:
        j = _dof_index(f"{name}.j", spec["j"], n_dof, names)
        if j == i:
            raise ValueError(f"{name}.j = {spec['j']!r}: the same DOF as {name}.i = {spec['i']!r}; "
                             "an element joins two different DOFs (omit j for ground)")
    fields = {key: _element_field(f"{name}.{key}", spec[key], _ELEMENT_FIELDS[key])
              for key in (*required, *optional) if key in spec}
    if kind == "law":  # parsed here so that a refused expression names this field
        from dtdyn.nonlinear.expressions import parse_expression

        constants = fields.pop("constants", {})
        parse_expression(fields["expression"], variables=("x", "v"), constants=tuple(constants),
                         name=f"{name}.expression")
        fields.update(constants)
    try:
        return getattr(el_mod, cls_name)(i, j, **fields)
    except ValueError as exc:  # a rule across fields (e.g. Bouc-Wen's beta + gamma > 0)
        raise ValueError(f"{name} (kind {kind!r}): {exc}") from None


def _parse_elements(tables, n_dof: int, names: tuple[str, ...] | None) -> tuple:
    if not isinstance(tables, list) or not all(isinstance(x, dict) for x in tables):
        raise ValueError(f"element = {tables!r}: must be zero or more [[element]] tables")
    return tuple(_parse_element(k, spec, n_dof, names) for k, spec in enumerate(tables))


def _nonlinear_methods() -> tuple[str, ...]:
    from dtdyn.nonlinear.linear_step import MODAL, MULTISTEP

    return MODAL + tuple(s for s in SCHEMES if s not in MULTISTEP)


def _parse_nonlinear(tbl, scheme_tbl) -> tuple[str, dict, dict, str]:
    """(method, scheme parameters, options, backend) of a nonlinear scene (module docstring)."""
    from dtdyn.nonlinear.linear_step import MODAL

    _table("nonlinear", tbl, _NONLINEAR_KEYS)
    methods = _nonlinear_methods()
    method, params = _DEFAULT_NONLINEAR_METHOD, {}
    if scheme_tbl is not None:
        if not isinstance(scheme_tbl, dict):
            raise ValueError(f"scheme = {scheme_tbl!r}: must be a table [scheme]")
        for key in ("form", "sweep", "backend"):
            if key in scheme_tbl:
                raise ValueError(f"scheme.{key} = {scheme_tbl[key]!r}: only for linear chains; a "
                                 "scene with [[element]] runs nonlinear_response (set "
                                 "nonlinear.backend): remove the key")
        name = scheme_tbl.get("name")
        if name not in methods:
            raise ValueError(f"scheme.name = {name!r}: a scene with [[element]] takes one of "
                             f"{', '.join(map(repr, methods))} (multistep schemes cannot run "
                             "nonlinear elements)")
        if name in MODAL:
            _table("scheme", scheme_tbl, ("name",))
            method = name
        else:
            method, params = _scheme_name_params(scheme_tbl)
    options = {}
    for key in ("substeps", "max_iter"):
        if key in tbl:
            v = tbl[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"nonlinear.{key} = {v!r}: must be an integer >= 1")
            options[key] = v
    if "tol" in tbl:
        tol = finite_number("nonlinear.tol", tbl["tol"])
        if tol <= 0:
            raise ValueError(f"nonlinear.tol = {tbl['tol']!r}: must be > 0")
        options["tol"] = tol
    if "modes" in tbl:
        modes = tbl["modes"]
        if method not in MODAL:
            raise ValueError(f"nonlinear.modes = {modes!r}: selects modal filters; method "
                             f"{method!r} integrates all DOFs (remove modes)")
        if (not isinstance(modes, list) or not modes
                or any(isinstance(m, bool) or not isinstance(m, int) or m < 0 for m in modes)):
            raise ValueError(f"nonlinear.modes = {modes!r}: must be a non-empty array of 0-based "
                             "mode indices (integers >= 0)")
        if len(set(modes)) != len(modes):
            raise ValueError(f"nonlinear.modes = {modes!r}: repeats a mode")
        options["modes"] = list(modes)
    backend = _choice("nonlinear.backend", tbl.get("backend", "c"), NONLINEAR_BACKENDS)
    if "backend" in tbl:
        options["backend"] = backend
    return method, params, options, backend


def _parse_output(tbl, n_dof: int, names: tuple[str, ...] | None = None
                  ) -> tuple[np.ndarray, tuple[str, ...]]:
    _table("output", tbl, _OUTPUT_KEYS)
    dofs = tbl.get("outputs")
    if names is not None and dofs is not None:  # indices or DOF names
        if not isinstance(dofs, list) or not dofs:
            raise ValueError(f"output.outputs = {dofs!r}: must be a non-empty array of DOF indices "
                             "or names")
        given = dofs
        dofs = [_dof_index(f"output.outputs[{i}]", d, n_dof, names) for i, d in enumerate(given)]
        for i, d in enumerate(dofs):
            if d in dofs[:i]:
                raise ValueError(f"output.outputs = {given!r}: entry {i} ({given[i]!r}) repeats "
                                 f"DOF {d} ({names[d]!r})")
    elif dofs is not None and (not isinstance(dofs, list)
                               or any(isinstance(d, bool) or not isinstance(d, int) for d in dofs)):
        raise ValueError(f"output.outputs = {dofs!r}: must be an array of integer DOF indices")
    outputs = validate.dof_indices("output.outputs", dofs, n_dof)
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
    nonlinear = bool(data.get("element"))  # [scheme] is optional then
    for key in ("model", "load", "time") + (() if nonlinear else ("scheme",)):
        if key not in data:
            hint = "[[load]]" if key == "load" else f"[{key}]"
            raise ValueError(f"{key} is required: add a {hint} table")
    if "nonlinear" in data and not nonlinear:
        raise ValueError(f"nonlinear = {data['nonlinear']!r}: the [nonlinear] options need at "
                         "least one [[element]] table")
    title = data.get("title", Path(source).stem)
    if not isinstance(title, str):
        raise ValueError(f"title = {title!r}: must be a string")

    base_dir = Path(base_dir)
    kind = _model_kind(data["model"])
    M = C = K = names = None
    mass = stiffness = damping = None
    if kind == "matrices":
        if nonlinear and data["model"].get("sparse") is True:
            raise ValueError("model.sparse = True: a scene with [[element]] runs on dense "
                             "matrices; remove the key")
        M, C, K, names = _parse_matrix_model(data["model"], base_dir)
        n_dof = M.shape[0]
        if nonlinear:
            M, C, K = (A.toarray() if sps.issparse(A) else A for A in (M, C, K))
    else:
        mass, stiffness, damping = _parse_model(data["model"])
        n_dof = mass.size
    dt, n_steps = _parse_time(data["time"])
    elements, options = (), {}
    if nonlinear:
        elements = _parse_elements(data["element"], n_dof, names)
        scheme, params, options, backend = _parse_nonlinear(data.get("nonlinear", {}),
                                                            data.get("scheme"))
        form = sweep = None
    else:
        if "element" in data:  # an empty array: still a linear scene
            _parse_elements(data["element"], n_dof, names)
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
                 dof_names=names, elements=elements, nonlinear=options)


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
        resource = importlib.resources.files("dtdyn.app").joinpath(DEFAULT_SCENE)
        source = f"dtdyn.app/{DEFAULT_SCENE}"
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
    """Warn before a run whose dt makes the scheme unstable for a mode of the model.

    A nonlinear scene is checked for its linear part at the sub-step dt / substeps when its
    method is a scheme (the modal methods are exact for the linear part; nonlinear_response
    checks the elements' tangent stiffness as it runs).
    """
    from dtdyn.linear.stability import warn_if_unstable

    dt = scene.dt
    if not scene.linear:
        if scene.scheme not in SCHEMES:
            return False
        dt = scene.dt / scene.nonlinear.get("substeps", 1)
    omegas = natural_frequencies(scene)
    omegas = omegas[omegas > 0.0]
    if omegas.size == 0:
        return False
    return warn_if_unstable(scene.scheme, omegas, dt, **scene.scheme_params)


def scene_matrices(scene: Scene):
    """(M, C, K) of a scene: a chain's from ``chain_matrices`` (dense), else as held."""
    if scene.kind == "matrices":
        return scene.M, scene.C, scene.K
    from dtdyn.linear.chain import chain_matrices

    return chain_matrices(scene.mass, scene.stiffness, scene.damping, sparse=False)


def _run_nonlinear(scene: Scene) -> tuple[Response, dict]:
    """``nonlinear_response`` on the scene; errors get the scene file's name."""
    from dtdyn.nonlinear import response as nonlinear

    M, C, K = scene_matrices(scene)
    start = time.perf_counter()
    try:
        response = nonlinear.nonlinear_response(
            M, C, K, scene.force, scene.dt, force_dofs=scene.loaded, elements=scene.elements,
            outputs=scene.outputs, quantities=scene.quantities, scheme=scene.scheme,
            **scene.nonlinear, **scene.scheme_params)
    except (nonlinear.NewtonError, nonlinear.DtdynStepStabilityError) as exc:
        substeps = scene.nonlinear.get("substeps", 1)
        raise type(exc)(f"{scene.source}: {exc} (the scene has nonlinear.substeps = "
                        f"{substeps})") from None
    except ValueError as exc:
        if str(exc).startswith("modes"):  # the range of nonlinear.modes is known only here
            raise ValueError(f"{scene.source}: nonlinear.{exc}") from None
        raise
    wall = time.perf_counter() - start
    info = response.info
    report = {
        "title": scene.title, "scheme": scene.scheme, "scheme_params": dict(scene.scheme_params),
        "form": None, "sweep": None, "backend": info["backend"], "dt": scene.dt,
        "n_steps": scene.n_steps, "n_dof": scene.n_dof, "n_outputs": int(scene.outputs.size),
        "run_time_s": info["run_time"], "exact_time_s": None, "max_rel_error": None,
        "substeps": info["substeps"],
        "elements": list(info["elements"]), "setup_time_s": info["setup_time"],
        "construct_time_s": info["construct_time"], "compile_time_s": info["compile_time"],
        "total_time_s": wall, "newton_iterations": info["newton_iterations"],
        "max_residual": info["max_residual"], "max_theta": info["max_theta"],
    }
    return response, report


def run_scene(scene: Scene, progress: bool = False) -> tuple[Response, dict]:
    """Simulate a scene with ``simulate_chain`` (chains), ``simulate_mck`` (general matrices) or
    ``nonlinear_response`` (scenes with elements) and report run time and error.

    The error is measured against the matrix-exponential solution (``exact_response``) when the
    scene is linear and has at most ``EXACT_MAX_DOF`` DOFs (and, for matrices, a mass matrix
    that is nonsingular or singular only through massless DOFs with damping, the cases
    ``exact_response`` solves; the matrices are converted to dense for it)::

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
        A nonlinear scene (``form``, ``sweep``, ``max_rel_error`` None; ``backend`` the one used)
        adds ``substeps, elements`` (descriptions), ``setup_time_s,
        construct_time_s, compile_time_s`` (``run_time_s`` is the stepping loop alone,
        ``total_time_s`` the whole call), ``newton_iterations`` (``{"max", "mean"}`` per step;
        None for backend "casadi"), ``max_residual`` and ``max_theta`` (``Response.info``).

    Raises
    ------
    NewtonError, DtdynStepStabilityError
        A nonlinear scene's step failed (dtdyn.nonlinear.response); the message starts with the
        scene file and names the step, its time and the residual (or the tangent stiffness).
    """
    check_stability(scene)
    if not scene.linear:
        return _run_nonlinear(scene)
    start = time.perf_counter()
    if scene.kind == "matrices":
        from dtdyn.linear import mck

        response = mck.simulate_mck(
            scene.M, scene.C, scene.K, scene.force, scene.dt, force_dofs=scene.loaded,
            scheme=scene.scheme, outputs=scene.outputs, quantities=scene.quantities,
            progress=progress, **scene.scheme_params)
        response.info.setdefault("backend", scene.backend)
    else:
        from dtdyn.linear import chain  # imported here: chain may compile kernels on first use

        response = chain.simulate_chain(
            scene.mass, scene.stiffness, scene.damping, scene.force, scene.dt,
            force_dofs=scene.loaded, scheme=scene.scheme, form=scene.form, sweep=scene.sweep,
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
        from dtdyn.linear import exact

        if scene.kind == "matrices":
            matrices = (scene.M, scene.C, scene.K)
        else:
            matrices = chain.chain_matrices(scene.mass, scene.stiffness, scene.damping)
        M, C, K = (m.toarray() if sps.issparse(m) else np.asarray(m) for m in matrices)
        start = time.perf_counter()
        try:
            ref = exact.exact_response(M, C, K, scene.force, scene.dt, force_dofs=scene.loaded,
                                       outputs=scene.outputs, quantities=("x",))
        except exact.SingularMassError:  # no exact solution to compare with
            return response, report
        report["exact_time_s"] = time.perf_counter() - start
        x, x_ref = np.asarray(response.x), np.asarray(ref.x)
        if x.shape != x_ref.shape:
            raise ValueError(f"response.x has shape {x.shape}, the exact solution {x_ref.shape}")
        err = float(np.max(np.abs(x - x_ref)))
        scale = float(np.max(np.abs(x_ref)))
        report["max_rel_error"] = err / scale if scale > 0.0 else (0.0 if err == 0.0 else np.inf)
    return response, report


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
    write_atomic(path, lambda f: np.savez(f, **arrays))


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
    write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=120))
