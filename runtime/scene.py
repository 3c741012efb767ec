"""Scenes: a chain model, its loads, a scheme and a time grid, read from a TOML file.

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

Every error is a ``ValueError`` that names the file and the field, e.g.
``p3.toml: model.mass[3] = -1.0: every entry must be finite and > 0``.
"""
from __future__ import annotations

import importlib.resources
import os
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import validate
from .loads import finite_number, sample_load
from .result import Response

__all__ = ["Scene", "load_scene", "scene_from_dict", "run_scene", "save_results", "plot_response",
           "SCHEMES", "FORMS", "SWEEPS", "BACKENDS", "QUANTITIES", "EXACT_MAX_DOF"]

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
_MODEL_KEYS = ("mass", "stiffness", "damping")
_TIME_KEYS = ("dt", "duration")
_OUTPUT_KEYS = ("dofs", "quantities")
_SCHEME_COMMON = ("name", "form", "sweep", "backend")

DEFAULT_SCENE = "scenes/p3.toml"


@dataclass
class Scene:
    """A validated scene: everything ``simulate_chain`` needs, plus what to store.

    ``force`` has shape ``(n_steps + 1, len(loaded))``: column ``j`` is the sum of the loads on
    the 0-based DOF ``loaded[j]`` sampled at ``t_0 .. t_n``.
    """

    title: str
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    loads: list[dict]
    loaded: np.ndarray
    force: np.ndarray
    scheme: str
    scheme_params: dict
    form: str
    sweep: str
    backend: str
    dt: float
    n_steps: int
    outputs: np.ndarray
    quantities: tuple[str, ...] = ("x",)
    source: str = "<scene>"
    base_dir: Path = field(default_factory=Path.cwd)

    @property
    def n_dof(self) -> int:
        return int(self.mass.size)

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


def _parse_scheme(tbl) -> tuple[str, dict, str, str, str]:
    if not isinstance(tbl, dict):
        raise ValueError(f"scheme = {tbl!r}: must be a table [scheme]")
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
    form = _choice("scheme.form", tbl.get("form", "displacement"), FORMS)
    sweep = _choice("scheme.sweep", tbl.get("sweep", "stable"), SWEEPS)
    backend = _choice("scheme.backend", tbl.get("backend", "c"), BACKENDS)
    return name, params, form, sweep, backend


def _parse_output(tbl, n_dof: int) -> tuple[np.ndarray, tuple[str, ...]]:
    _table("output", tbl, _OUTPUT_KEYS)
    dofs = tbl.get("dofs")
    if dofs is not None and (not isinstance(dofs, list)
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


def _parse_loads(loads, n_dof: int, t: np.ndarray, base_dir: Path):
    if not isinstance(loads, list) or not loads or not all(isinstance(x, dict) for x in loads):
        raise ValueError(f"load = {loads!r}: must be one or more [[load]] tables")
    columns: dict[int, np.ndarray] = {}
    for i, spec in enumerate(loads):
        name = f"load[{i}]"
        dof = _required(name, spec, "dof")
        if isinstance(dof, bool) or not isinstance(dof, int) or not 0 <= dof < n_dof:
            raise ValueError(f"{name}.dof = {dof!r}: must be an integer mass index in 0..{n_dof - 1}")
        samples = sample_load(spec, t, base_dir, name=name, extra_keys=("dof",))
        columns[dof] = columns[dof] + samples if dof in columns else samples
    loaded = np.array(sorted(columns), dtype=np.int64)
    force = np.column_stack([columns[d] for d in loaded])
    return [dict(x) for x in loads], loaded, validate.force_samples(force, t.size - 1, loaded)


# ----------------------------------------------------------------------------------------------
# public API

def scene_from_dict(data: dict, base_dir: Path | str = ".", source: str = "<scene>") -> Scene:
    """Validate a parsed scene (the dict ``tomllib`` returns) and build a :class:`Scene`.

    ``base_dir`` is where ``file`` loads are looked for. Errors are ``ValueError`` naming the field
    (without the file name; :func:`load_scene` adds it).
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
    mass, stiffness, damping = _parse_model(data["model"])
    dt, n_steps = _parse_time(data["time"])
    scheme, params, form, sweep, backend = _parse_scheme(data["scheme"])
    outputs, quantities = _parse_output(data.get("output", {}), mass.size)
    t = np.arange(n_steps + 1) * dt
    loads, loaded, force = _parse_loads(data["load"], mass.size, t, base_dir)
    return Scene(title=title, mass=mass, stiffness=stiffness, damping=damping, loads=loads,
                 loaded=loaded, force=force, scheme=scheme, scheme_params=params, form=form,
                 sweep=sweep, backend=backend, dt=dt, n_steps=n_steps, outputs=outputs,
                 quantities=quantities, source=source, base_dir=base_dir)


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


def run_scene(scene: Scene, progress: bool = False) -> tuple[Response, dict]:
    """Simulate a scene with ``simulate_chain`` and report run time and error.

    The error is measured against the matrix-exponential solution (``exact_response``) when the
    scene is linear and has at most ``EXACT_MAX_DOF`` DOFs::

        max_rel_error = max_{i, j} |x[i, j] - x_exact[i, j]| / max_{i, j} |x_exact[i, j]|

    over all samples ``i`` and stored outputs ``j`` (``None`` when not computed).

    Returns
    -------
    response : Response
        Sampled at ``t_0 .. t_n`` for the DOFs ``scene.outputs``.
    report : dict
        ``title, scheme, scheme_params, form, sweep, backend, dt, n_steps, n_dof, n_outputs,
        run_time_s, exact_time_s, max_rel_error``.
    """
    from . import chain  # imported here: chain may compile kernels on first use

    start = time.perf_counter()
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
        import scipy.sparse

        from . import exact

        M, C, K = (m.toarray() if scipy.sparse.issparse(m) else np.asarray(m)
                   for m in chain.chain_matrices(scene.mass, scene.stiffness, scene.damping))
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

    Written atomically: to a temporary file in the same folder, then renamed over ``path``, so a
    failed write leaves no partial file (and an existing ``path`` untouched).
    """
    path = Path(path)
    arrays = {"t": np.asarray(response.t), "outputs": np.asarray(response.outputs)}
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
        ax.plot(response.t, x[:, j], lw=1.0, label=f"DOF {int(dof)} (mass {int(dof) + 1})")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("x [m]")
    ax.set_title(f"{scene.title}\n{scene.scheme}, dt = {scene.dt:g} s", fontsize=10)
    ax.grid(True, alpha=0.3)
    if x.shape[1] <= 20:
        ax.legend(fontsize=7, ncols=1 + x.shape[1] // 8, loc="best")
    _atomic_write(path, lambda f: fig.savefig(f, format=fmt, dpi=120))
