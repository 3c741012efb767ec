"""Scene files: the schema. A scene is a model (a chain or general M, C, K matrices), its loads,
a scheme and a time grid, read from a TOML file.

Layout of a scene file (``load_scene(None)`` reads the embedded default ``scenes/p3.toml``,
reference problem P3)::

    title = "..."                       # optional, default: the file name
    [model]                             # chain: ground -k1,c1- m1 -k2,c2- m2 ... mN (free)
    mass = [...]                        # kg, every entry > 0
    stiffness = [...]                   # N/m, every entry > 0, same length
    damping = [...]                     # N s/m, >= 0, optional (zeros)
    ground_stiffness = [...]            # optional: N/m, >= 0, a spring from each mass to the
    ground_damping = [...]              #   ground; N s/m, >= 0, a damper (zeros)
    rayleigh = [0.5, 1e-3]              # optional: C += alpha M + beta K in chain form (station
                                        #   dampers += beta k, ground dampers += alpha m +
                                        #   beta kg; alpha, beta >= 0)
    [[load]]                            # one or more to run; loads on the same dof add up
    dof = 14                            # 0-based mass index
    kind = "step"                       # and that kind's fields, see dtdyn.app._loads
    amplitude = 1.0
    [ground]                            # optional support motion (then [[load]] is optional):
    kind = "file"                       #   a ground record, any load kind, sampled at the
    path = "record.csv"                 #   scene's times; the DOFs are then relative to the
    scale = 1.0                         #   support and a_abs = a + r a_g is stored with a
    quantity = "acceleration"           #   or "velocity", "displacement" (then also
                                        #   x_abs = x + r u_g is stored with x): turned into the
                                        #   acceleration by ground_acceleration_from
    units = "g"                         #   acceleration: "g" (x 9.80665) or "m/s^2" (default);
                                        #   velocity "m/s", displacement "m" (the only ones)
    influence = [1.0, 1.0]              #   matrices scenes: r, one entry per DOF (default ones)
    dt = 0.005                          #   a file at its own step: interpolated linearly onto
                                        #   the scene's times; after the record's end an
                                        #   acceleration is 0, a velocity or displacement holds
                                        #   its last sample
    [initial]                           # optional: the state at t_0 (without [[load]] and
    x0 = [0.0, 0.01]                    #   [ground]: free vibration from it); displacement
    v0 = [0.0, 0.0]                     #   and velocity of every DOF (default zeros)
    [scheme]                            # optional: default newmark, beta = 0.25, gamma = 0.5
    name = "newmark"                    # plus that scheme's parameters: beta = 0.25, gamma = 0.5
    form = "displacement"               # optional (default: displacement; acceleration for an
                                        #   explicit scheme, its only form)
    sweep = "stable"                    # optional
    backend = "c"                       # optional
    unstable = "raise"                  # optional: "warn" runs a dt past the scheme's stability
                                        #   limit with a warning (for study; --unstable warn)
    refine = "auto"                     # optional, beams only: beam_response's refine
    [time]                              # required to run (not by `dtdyn modes`)
    dt = 1e-3                           # s
    duration = 0.8                      # s, an integer multiple of dt: n_steps = duration / dt
    [output]                            # optional
    outputs = [0, 14]                   # optional, default all
    quantities = ["x", "v", "a"]        # optional, default ["x"]; with [[element]] also "g"
                                        #   (element forces) and "z" (internal states)

Only ``[model]`` is required: a scene holding just a model is valid for ``dtdyn modes`` and
whatever does not integrate. ``[time]`` and a load (``[[load]]`` or ``[ground]``) are required
by the commands that integrate (``dtdyn simulate``, ``dtdyn batch``, `run_scene`); their
error names the command and the table to add.

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

A torsional shaft with disks, gears and branches (``kind = "shaft"``, with ``[[branch]]``
tables) and a beam in planar bending (``kind = "beam"``) have their own ``[model]`` keys:
dtdyn.app._scene.shaft and dtdyn.app._scene.beam describe them; loads and outputs name their DOFs
("main.3", "w200").

Paths are relative to the scene file. ``load.dof`` and ``output.outputs`` entries of such a scene
are 0-based indices or names from ``model.dofs``. It runs with ``mck_response`` (any scheme,
acceleration form, dense or sparse); ``scheme.form``, ``scheme.sweep`` and ``scheme.backend``
belong to chains and are rejected.

Nonlinear elements (dtdyn.nonlinear._elements) join the model, chain or matrices; any
``[[element]]`` table makes the scene nonlinear (``scenes/p4.toml``, reference problem P4)::

    [[element]]                         # zero or more, in the order given
    kind = "cubic"                      # cubic | polynomial | gap | law | bouc_wen
    i = 0                               # DOF: 0-based index (or a model.dofs name for matrices)
    j = 1                               # optional, default: ground; y = q_i - q_j (y = q_i)
    k3 = 2e7                            # and that kind's fields (below)
    [scheme]                            # optional, default "modal_ramp" ("auto" with accuracy)
    name = "modal_parabolic"            # "modal_ramp", "modal_parabolic", "modal_quintic",
                                        #   "modal_explicit" or a one-step scheme name (not
                                        #   houbolt, park) with its parameters; "auto" with
                                        #   accuracy
    [nonlinear]                         # optional
    substeps = 1                        # optional: steps per sample, h = dt / substeps (with
                                        #   accuracy: the first run's)
    accuracy = 1e-6                     # optional: a relative error target instead (the method
                                        #   and sub-steps chosen: nonlinear_mck_response's accuracy)
    max_substeps = 1024                 # optional, with accuracy: the most sub-steps tried
                                        #   (default: 10^8 DOF-steps over the record, >= 256)
    backend = "c"                       # optional: "c" or "casadi"
    tol = 1e-12                         # optional: relative Newton tolerance
    max_iter = 30                       # optional: Newton iterations per step
    modes = [0, 1]                      # optional, modal methods only: the modes kept (0-based,
                                        #   sorted by |pole|), default all
    refine = "auto"                     # optional, beams only: each step's solve corrected
                                        #   by its residual ("auto": from 2,000 elements; true,
                                        #   false); a linear beam scene: scheme.refine

Element kinds and fields (required unless a default is given; the defaults are those of the
element classes)::

    cubic       k3 (N/m^3)                          g = k3 y^3
    polynomial  coeffs = [c0, c1, ...]              g = sum_p c_p y^p
    gap         gap (m, >= 0), stiffness (N/m, > 0), smoothing (m, >= 0) [0.0],
                side ("both", "positive", "negative") ["both"]
    law         expression = "k*x**3 + c*v"         g(x, v): x = y, v = y'; arithmetic and the
                [element.constants]                 functions of dtdyn.nonlinear._expressions
                k = 2e7                             (parsed, never evaluated as Python);
                c = 0.5                             constants: a table of numbers [none]
    bouc_wen    stiffness (> 0), beta, gamma, alpha (>= 0) [0.1], A [1.0], n (>= 1) [1.0]

The scheme of a nonlinear scene is ``scheme.name`` (default ``"modal_ramp"``): a modal method
(no parameters) or a one-step scheme with its parameters (``beta = 0.3``, ...); ``scheme.form``,
``.sweep`` and ``.backend`` are refused (``nonlinear.backend`` chooses the backend).
``[nonlinear]`` without any ``[[element]]`` is an error. A nonlinear scene runs
``nonlinear_mck_response`` on dense M, C, K (a chain's from ``chain_matrices``;
``model.sparse = true`` is refused) with the loads sampled every ``dt`` and the stored outputs
and quantities the scene asks for; it is not compared with the exact solution.

The periodic steady state of a scene with ``[[element]]`` tables (``dtdyn steady``,
`run_steady`; ``scenes/duffing_steady.toml``) is set by a ``[harmonic]`` table whose keys are the
keywords of `harmonic_balance` (dtdyn.app._scene.steady describes them all)::

    [harmonic]
    freqs_hz = [0.05, 0.4]              # (start, end), Hz
    harmonics = 7                       # optional (default 7)
    force_dofs = [0]                    # loaded DOFs (indices or model.dofs names)
    force = [0.1]                       # one per force_dofs entry: a number or [re, im]
    # force_harmonics = [[0.0, 0.1, [0.0, 0.02]]]   # or a row of harmonics 0, 1, ... per DOF
    # ground_acceleration = 0.05        # or support motion (a number or [re, im]), influence
    stability = true                    # optional; step, max_step, min_step, max_angle,
                                        #   max_points, tol, max_iter, n_time, receptance too
    # frequency_hz = 0.25, amplitudes = [0.05, 15.0]: the load's amplitude swept at one
    #   frequency (harmonic_balance_amplitude) instead of freqs_hz

``[output] outputs`` chooses the stored DOFs. ``[time]``, ``[scheme]``, ``[nonlinear]``,
``[[load]]``, ``[ground]`` and ``[initial]`` belong to the time histories: a scene may hold both
kinds of table; ``dtdyn simulate`` then ignores ``[harmonic]`` and ``dtdyn steady`` ignores
those. A beam or shaft scene with ``[[element]]`` and ``[harmonic]`` but neither ``[time]`` nor
``[scheme]`` needs no time-history scheme.

Every error is a ``ValueError`` that names the file and the field, e.g.
``p3.toml: model.mass[3] = -1.0: every entry must be finite and > 0`` or
``p4.toml: element[1].expression = '__import__("os")': ...``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import validate
from dtdyn._engine.schemes import check_parameter
from dtdyn.generated.scheme_table import TABLE
from dtdyn.app._loads import finite_number

#: scheme name -> {parameter: (lower bound, upper bound)} (inclusive; None: unbounded), from the
#: generated scheme table (the same ranges the runtime checks)
SCHEMES: dict[str, dict[str, tuple[float | None, float | None]]] = {
    name: {p: spec["range"] for p, spec in row["params"].items()} for name, row in TABLE.items()}
FORMS = ("displacement", "acceleration")
SWEEPS = ("stable", "plain")
BACKENDS = ("c", "numpy")
QUANTITIES = ("x", "v", "a")
#: run_scene compares with the matrix-exponential solution up to this many DOFs
EXACT_MAX_DOF = 2000

_TOP_KEYS = ("title", "model", "load", "ground", "initial", "element", "nonlinear", "harmonic",
             "scheme", "time", "output", "branch")
#: the units each [ground] quantity may be given in, the default first
GROUND_UNITS = {"acceleration": ("m/s^2", "g"), "velocity": ("m/s",), "displacement": ("m",)}
#: standard gravity, m/s^2 (a [ground] record in units of g)
STANDARD_GRAVITY = 9.80665
#: model kinds: a chain (mass, stiffness, damping vectors) or general M, C, K matrices
MODEL_KINDS = ("chain", "matrices", "shaft", "beam")
#: kinds whose [model] table a module parses and runs: parse_model(model, branches, base_dir)
#: -> model object with ``dof_names``; matrices(model, sparse); simulate(scene, progress,
#: support); frequencies(model, count)
MODEL_MODULES = {"shaft": "dtdyn.app._scene.shaft", "beam": "dtdyn.app._scene.beam"}


_MODEL_KEYS = ("kind", "mass", "stiffness", "damping", "ground_stiffness", "ground_damping",
               "rayleigh")
_MATRIX_MODEL_KEYS = ("kind", "M", "K", "C", "file", "dofs", "sparse", "damping")
_MATRIX_DAMPING_KEYS = ("rayleigh", "modal")
_MATRIX_NAMES = ("M", "K", "C")
_MTX_SUFFIXES = (".mtx", ".mtx.gz", ".mtx.bz2")
_TIME_KEYS = ("dt", "duration")
_OUTPUT_KEYS = ("outputs", "quantities")
_SCHEME_COMMON = ("name", "form", "sweep", "backend", "unstable", "refine")
#: the scheme of a linear scene without ``scheme.name``: the entry points' own default
#: (``chain_response``, ``mck_response``, ``shaft_response``, ``beam_response``: ``"newmark"``
#: with beta = 1/4, gamma = 1/2, the average acceleration method)
DEFAULT_SCHEME = "newmark"
#: ``scheme.unstable`` (and ``--unstable``): what a linear run does when its dt is past the
#: scheme's stability limit, the entry points' ``unstable=`` keyword (default "raise")
UNSTABLE = ("raise", "warn")


def model_module(kind: str):
    """The module of a kind in MODEL_MODULES."""
    import importlib
    return importlib.import_module(MODEL_MODULES[kind])


def model_matrices(assemble, model, sparse=None):
    """(M, C, K) = assemble(model) of a kind in MODEL_MODULES: sparse CSR, or dense arrays when
    ``sparse`` is False."""
    M, C, K = assemble(model)
    return (M.toarray(), C.toarray(), K.toarray()) if sparse is False else (M, C, K)


def model_simulate(simulate, scene, progress=False, support=None):
    """simulate(model, force, dt, ...) of a kind in MODEL_MODULES with the scene's load,
    scheme (and its ``unstable``), outputs and support motion."""
    return simulate(scene.model, scene.force, scene.dt, force_dofs=scene.loaded,
                    scheme=scene.scheme, form=scene.form, backend=scene.backend,
                    outputs=scene.outputs, quantities=scene.quantities, progress=progress,
                    unstable=scene.unstable, **(support or {}), **model_options(scene),
                    **scene.scheme_params)


def model_simulate_nonlinear(simulate, scene, support=None):
    """simulate(model, force, dt, elements=..., ...) of a kind in MODEL_MODULES (its
    nonlinear_<kind>_response) with the scene's elements, load, scheme, [nonlinear] options,
    outputs and support motion."""
    return simulate(scene.model, scene.force, scene.dt, elements=scene.elements,
                    force_dofs=scene.loaded, scheme=scene.scheme, outputs=scene.outputs,
                    quantities=scene.quantities, **(support or {}), **scene.nonlinear,
                    **model_options(scene), **scene.scheme_params)


def model_options(scene) -> dict:
    """The model's own keywords of a scene's runs: a beam's ``refine``."""
    return {"refine": scene.refine} if scene.kind == "beam" else {}


#: element kind -> (class in dtdyn.nonlinear._elements, required fields, optional fields); the
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
_NONLINEAR_KEYS = ("substeps", "backend", "tol", "max_iter", "modes", "accuracy", "max_substeps",
                   "refine")
NONLINEAR_BACKENDS = ("c", "casadi")
_DEFAULT_NONLINEAR_METHOD = "modal_ramp"

DEFAULT_SCENE = "scenes/p3.toml"


@dataclass
class Scene:
    """A validated scene: what ``chain_response`` or ``mck_response`` needs, plus what to store.

    ``force`` has shape ``(n_steps + 1, len(loaded))``: column ``j`` is the sum of the loads on
    the 0-based DOF ``loaded[j]`` sampled at ``t_0 .. t_n``.

    Only ``[model]`` is required: that is all `dtdyn modes` and the other commands that do not
    integrate read. A run needs ``[time]`` (``dt``, ``n_steps``, ``force`` and ``ground`` are
    None without it) and a load (``[[load]]`` or ``[ground]``; an ``[initial]`` state alone is
    a free vibration, a zero ``force`` on DOF 0); `require_run` checks both and names the table
    to add. ``form`` None is the scheme's own (displacement; acceleration for an explicit
    scheme). Without ``[scheme]`` (or ``scheme.name``) a linear scene runs the
    entry points' default scheme, `DEFAULT_SCHEME` (``"newmark"``, beta = 1/4, gamma = 1/2).

    ``kind`` is ``"chain"`` (``mass``, ``stiffness``, ``damping`` set; ``M``, ``C``, ``K`` None)
    or ``"matrices"`` (``M``, ``C``, ``K`` set, all dense ndarrays or all scipy.sparse CSR, damping
    options already added to ``C``; ``mass``, ``stiffness``, ``damping`` None; ``dof_names`` one
    name per DOF; ``form = "acceleration"``, ``sweep = None``, ``backend = "c"``: the C loop of
    ``mck_response``, dense or sparse).

    A nonlinear scene has ``elements`` (dtdyn.nonlinear._elements objects, DOFs checked),
    ``scheme`` the method (``"modal_ramp"``, ``"modal_parabolic"`` or a one-step scheme),
    ``scheme_params`` that scheme's parameters, ``nonlinear`` the ``[nonlinear]`` options the
    file gives (``substeps``, ``tol``, ``max_iter``, ``modes``, ``backend``; the others take
    ``nonlinear_mck_response``'s defaults), ``backend`` ``"c"`` or ``"casadi"``, ``form`` and
    ``sweep`` None; matrices are dense.

    Attributes
    ----------
    title, source : str
        The scene's title and file.
    base_dir : Path
        The folder that relative file paths of the scene are read from (the scene file's).
    kind : {"chain", "matrices", "shaft", "beam"}
    model : object or None
        The model object of the kinds that build one (a `Shaft`, a `Beam`).
    dof_names : tuple of str or None
        One name per DOF where the model names them.
    mass, stiffness, damping : ndarray or None
        A chain's stations.
    ground_stiffness, ground_damping : ndarray or None
        A chain's springs and dampers from the masses to the ground (None: none; a
        ``model.rayleigh`` is already in them and in ``damping``).
    M, C, K : ndarray, scipy.sparse matrix or None
        A matrices model (damping options already in C).
    loads, loaded, force : list of dict, ndarray, ndarray
        The load tables, the loaded DOFs (``force_dofs`` of the runs) and the summed samples.
    scheme, scheme_params, form, sweep, backend : str, dict, str, str, str
    unstable : {"raise", "warn"}
        ``scheme.unstable``: the ``unstable=`` keyword of the linear entry points (a dt past
        the scheme's stability limit raises DtdynUnstableError, or warns and runs).
    dt, n_steps : float, int or None
        The ``[time]`` table (None without it).
    outputs, quantities : ndarray, tuple of str
    elements, nonlinear : tuple, dict
        Nonlinear elements and the ``[nonlinear]`` options.
    ground, ground_quantity, influence : ndarray or None, str, ndarray or None
        The ``[ground]`` record at the scene's times in SI units, what it samples
        ("acceleration", "velocity", "displacement"), and r (None: ones).
    x0, v0 : ndarray or None
        The ``[initial]`` displacement and velocity of every DOF (None: rest).
    harmonic : dict or None
        The ``[harmonic]`` table as the keywords of `harmonic_balance` (with ``frequency_hz``
        and ``amplitudes``: of `harmonic_balance_amplitude`), checked; None without one.
    refine : {"auto", True, False}
        A beam's ``refine`` (``scheme.refine``, or ``nonlinear.refine`` with [[element]]);
        "auto" for every other kind.

    Examples
    --------
    >>> import dtdyn as dd
    >>> scene = dd.load_scene()            # the embedded P3 scene
    >>> scene.n_dof, scene.scheme, scene.n_steps
    (15, 'average_acceleration', 800)
    """

    title: str
    mass: np.ndarray | None
    stiffness: np.ndarray | None
    damping: np.ndarray | None
    loads: list[dict]
    loaded: np.ndarray
    force: np.ndarray | None
    scheme: str
    scheme_params: dict
    form: str | None
    sweep: str | None
    backend: str
    dt: float | None
    n_steps: int | None
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
    ground: np.ndarray | None = None
    ground_quantity: str = "acceleration"
    influence: np.ndarray | None = None
    x0: np.ndarray | None = None
    v0: np.ndarray | None = None
    unstable: str = "raise"
    ground_stiffness: np.ndarray | None = None
    ground_damping: np.ndarray | None = None
    model: object | None = None  # the model object of a kind in MODEL_MODULES (e.g. a Shaft)
    harmonic: dict | None = None  # the [harmonic] table: harmonic_balance's keywords
    refine: str | bool = "auto"  # a beam's refine (scheme.refine, nonlinear.refine)

    @property
    def chain(self) -> dict:
        """A chain's data as the keywords of the chain functions (mass, stiffness, damping,
        ground_stiffness, ground_damping)."""
        return {"mass": self.mass, "stiffness": self.stiffness, "damping": self.damping,
                "ground_stiffness": self.ground_stiffness, "ground_damping": self.ground_damping}

    @property
    def n_dof(self) -> int:
        if self.model is not None:
            return len(self.dof_names)
        if self.kind == "matrices":
            return int(self.M.shape[0])
        return int(self.mass.size)

    def matrices(self, sparse: bool | None = None):
        """(M, C, K) of the model: a chain's assembled matrices (``chain_matrices``: sparse
        beyond 200 masses unless ``sparse`` says), or the matrices scene's own."""
        if self.kind == "matrices":
            return self.M, self.C, self.K
        if self.model is not None:  # a kind in MODEL_MODULES: sparse unless sparse=False
            return model_module(self.kind).matrices(self.model, sparse)
        from dtdyn.linear._chain import chain_matrices
        return chain_matrices(**self.chain, sparse=sparse)

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
    def duration(self) -> float | None:
        """``n_steps * dt`` in s (None without a ``[time]`` table)."""
        return None if self.dt is None else self.n_steps * self.dt

    @property
    def t(self) -> np.ndarray:
        """Sample times ``t_i = i dt``, ``i = 0 .. n_steps``."""
        self.require_run("Scene.t", load=False)
        return np.arange(self.n_steps + 1) * self.dt

    def require_run(self, command: str = "run_scene", load: bool = True) -> None:
        """Check that the scene can be integrated: it has a ``[time]`` table and (with
        ``load``) a load, ``[[load]]`` or ``[ground]``.

        A scene holding only ``[model]`` is valid for what does not integrate (`dtdyn modes`,
        ``Scene.matrices``); the commands and functions that integrate call this first.

        Parameters
        ----------
        command : str
            What asks, for the message (``"dtdyn simulate"``, ``"run_scene"``).
        load : bool
            Require a load as well as the time grid.

        Raises
        ------
        ValueError
            ``"<file>: <command> needs a [time] table with dt and duration ..."`` or ``"...
            needs a load ..."``, naming the table to add.

        Examples
        --------
        >>> import dtdyn as dd
        >>> s = dd.scene_from_dict({"model": {"mass": [1.0], "stiffness": [4.0]}})
        >>> s.require_run("dtdyn simulate")
        Traceback (most recent call last):
        ...
        ValueError: <scene>: dtdyn simulate needs a [time] table with dt and duration ...
        """
        if self.dt is None:
            raise ValueError(f"{self.source}: {command} needs a [time] table with dt and "
                             "duration (e.g. [time] dt = 0.01, duration = 1.0); the scene has "
                             "none")
        if load and self.force is None and self.ground is None:
            raise ValueError(f"{self.source}: {command} needs a load: one or more [[load]] "
                             "tables (dof, kind and that kind's fields) or a [ground] record; "
                             "the scene has neither (or an [initial] x0 / v0 not all zero: "
                             "free vibration)")

    @property
    def linear(self) -> bool:
        """True when the scene has no nonlinear elements."""
        return not self.elements



# ----------------------------------------------------------------------------------------------
# validation helpers shared by the parsers

def _table(name: str, value, allowed: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{name} = {value!r}: must be a table [{name}]")
    for key in value:
        if key not in allowed:
            raise ValueError(f"{name}.{key} = {value[key]!r}: unknown key, allowed: "
                             f"{', '.join(allowed)}")
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
        raise ValueError(f"{name} = {value!r}: unknown value, allowed: "
                         f"{', '.join(map(repr, allowed))}")
    return value


def _parse_model(model) -> dict:
    """A chain [model] as the keywords of the chain functions (`Scene.chain`)."""
    _table("model", model, _MODEL_KEYS)
    mass = _number_list("model.mass", _required("model", model, "mass"), positive=True)
    n = mass.size
    stiffness = _number_list("model.stiffness", _required("model", model, "stiffness"),
                             positive=True, length=n)
    damping, kg, cg = (
        _number_list(f"model.{key}", model[key], nonnegative=True, length=n) if key in model
        else (np.zeros(n) if key == "damping" else None)
        for key in ("damping", "ground_stiffness", "ground_damping"))
    if "rayleigh" in model:
        from dtdyn.linear._chain import rayleigh_chain_damping

        coef = _number_list("model.rayleigh", model["rayleigh"], nonnegative=True)
        if coef.size != 2:
            raise ValueError(f"model.rayleigh = {model['rayleigh']!r}: must be [alpha, beta] "
                             "(C += alpha M + beta K)")
        c_r, cg_r = rayleigh_chain_damping(mass, stiffness, coef, ground_stiffness=kg)
        damping = damping + c_r
        cg = cg_r if cg is None else cg + cg_r
    return {"mass": mass, "stiffness": stiffness, "damping": damping,
            "ground_stiffness": kg, "ground_damping": cg}


def _model_kind(model) -> str:
    if not isinstance(model, dict):
        raise ValueError(f"model = {model!r}: must be a table [model]")
    return _choice("model.kind", model.get("kind", "chain"), MODEL_KINDS)



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


def _scheme_name_params(tbl: dict, default: str | None = None, base_dir=None) -> tuple:
    """``scheme.name`` (``default`` when the table has none), or the scheme a scheme file
    ``scheme.file`` defines (a path relative to ``base_dir``; `dtdyn.load_scheme`), and its
    parameters, each checked against its bounds."""
    if "file" in tbl:
        if "name" in tbl:
            raise ValueError(f"scheme.name = {tbl['name']!r} and scheme.file = {tbl['file']!r}: "
                             "give one of them")
        if not isinstance(tbl["file"], str):
            raise ValueError(f"scheme.file = {tbl['file']!r}: must be the path of a scheme file")
        from dtdyn._engine.scheme_files import load_scheme
        path = Path(base_dir or ".") / tbl["file"]
        name = load_scheme(path)
        bounds = name.params
        _table("scheme", tbl, _SCHEME_COMMON + ("file",) + tuple(bounds))
    else:
        name = tbl.get("name", default)
        if name is None:
            raise ValueError(f"scheme.name is required, allowed: {', '.join(SCHEMES)}")
        _choice("scheme.name", name, tuple(SCHEMES))
        bounds = SCHEMES[name]
        _table("scheme", tbl, _SCHEME_COMMON + tuple(bounds))
    params = {key: check_parameter(name, key, finite_number(f"scheme.{key}", tbl[key]),
                                   f"scheme.{key}") for key in bounds if key in tbl}
    return name, params
