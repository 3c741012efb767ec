"""Steady-state scenes: the ``[harmonic]`` table, its run (`harmonic_balance` on the scene's
model and elements), saving and plotting the frequency response curve.

::

    [harmonic]
    freqs_hz = [0.05, 0.4]              # (start, end), Hz: the curve from start to end
    harmonics = 7                       # optional: H, harmonics 0 .. H (default 7)
    force_dofs = [0]                    # the loaded DOFs: indices or model DOF names
    force = [0.1]                       # one amplitude per force_dofs entry: a number (F cos
                                        #   omega t) or [re, im] (Re(F e^{i omega t}))
    # force_harmonics = [[0.0, 0.1, [0.0, 0.02]]]   # instead of force: a row per DOF, entry k
                                        #   harmonic k (a number or [re, im]; entry 0 real)
    # ground_acceleration = 0.05        # support motion, m/s^2 (rad/s^2 on a shaft): a number
                                        #   or [re, im]; or ground_acceleration_harmonics = [...]
    # influence = [1.0, 1.0]            # matrices and beam scenes: r, one entry per DOF
    stability = "auto"                  # optional: Hill's method at every point (true or
                                        # "full": the whole model; "reduced"; false: none)
    # step, max_step, min_step, max_angle, max_points, tol, max_iter, n_time, receptance,
    #   convergence_points: optional, harmonic_balance's keywords and defaults
    # frequency_hz = 0.25               # instead of freqs_hz: at one frequency, the load
    # amplitudes = [0.05, 15.0]         #   factor continued from start to end
                                        #   (harmonic_balance_amplitude)

The keys are the keywords of `harmonic_balance`. The model (any kind) and its ``[[element]]``
tables (at least one; no ``bouc_wen``) are the scene's, ``[output] outputs`` the stored DOFs.
``[time]``, ``[scheme]``, ``[nonlinear]``, ``[[load]]``, ``[ground]`` and ``[initial]`` belong
to the time histories: a scene may hold both, `dtdyn simulate` (`run_scene`) then runs the time
history and ignores ``[harmonic]``, `dtdyn steady` (`run_steady`) runs the steady state and
ignores those tables.
"""
from __future__ import annotations

import dataclasses
import inspect
import os
import time
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn.app._loads import finite_number
from dtdyn.app._scene.schema import Scene, _choice, _dof_index, _number_list, _table

HARMONIC_KEYS = ("freqs_hz", "frequency_hz", "amplitudes", "harmonics", "force_dofs", "force",
                 "force_harmonics", "ground_acceleration", "ground_acceleration_harmonics",
                 "influence", "stability", "step", "max_step", "min_step", "max_angle",
                 "max_points", "tol", "max_iter", "n_time", "receptance", "convergence_points")
RECEPTANCES = ("auto", "modal", "direct", "banded", "reduced")
#: the most outputs `plot_steady` draws, one panel each
MAX_PANELS = 8


def _defaults() -> dict:
    """harmonic_balance's keyword defaults (the scene's when a key is left out)."""
    from dtdyn.nonlinear._harmonic_balance import harmonic_balance

    return {name: p.default for name, p in inspect.signature(harmonic_balance).parameters.items()
            if p.default is not inspect.Parameter.empty}


def _integer(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{name} = {value!r}: must be an integer >= {minimum}")
    return value


def _positive(name: str, value) -> float:
    v = finite_number(name, value)
    if v <= 0:
        raise ValueError(f"{name} = {value!r}: must be > 0")
    return v


def _range(name: str, value, what: str, minimum_open: bool) -> tuple[float, float]:
    """(start, end): two different finite numbers, > 0 (``minimum_open``) or >= 0."""
    if not isinstance(value, list) or len(value) != 2:
        raise ValueError(f"{name} = {value!r}: must be [start, end] ({what})")
    a, b = (finite_number(f"{name}[{i}]", v) for i, v in enumerate(value))
    for i, v in enumerate((a, b)):
        if v < 0 or (minimum_open and v == 0):
            need = "> 0" if minimum_open else ">= 0"
            raise ValueError(f"{name}[{i}] = {value[i]!r}: must be {need}")
    if a == b:
        raise ValueError(f"{name} = {value!r}: start and end must differ")
    return a, b


def _amplitude(name: str, value) -> complex:
    """A number (real) or [re, im] (complex)."""
    if isinstance(value, list):
        if len(value) != 2:
            raise ValueError(f"{name} = {value!r}: a complex amplitude is [re, im], two numbers")
        return complex(finite_number(f"{name}[0]", value[0]),
                       finite_number(f"{name}[1]", value[1]))
    return complex(finite_number(name, value), 0.0)


def _harmonic_row(name: str, row, H: int) -> np.ndarray:
    """[F_0, F_1, ...] (each a number or [re, im]; F_0 real), at most H + 1 entries."""
    if not isinstance(row, list) or not row:
        raise ValueError(f"{name} = {row!r}: must be an array [harmonic 0, harmonic 1, ...] of "
                         "numbers or [re, im] pairs")
    if len(row) > H + 1:
        raise ValueError(f"{name} has {len(row)} entries: at most harmonic.harmonics + 1 = "
                         f"{H + 1} (harmonics 0 .. {H})")
    values = np.array([_amplitude(f"{name}[{k}]", v) for k, v in enumerate(row)])
    if values[0].imag != 0:
        raise ValueError(f"{name}[0] = {row[0]!r}: harmonic 0 (the static part) must be real")
    return values


def _loads(tbl: dict, H: int, n_dof: int, names, kind: str) -> dict:
    """force_dofs, force; ground_acceleration, influence: harmonic_balance's keywords."""
    for key in ("force", "ground_acceleration"):
        if key in tbl and f"{key}_harmonics" in tbl:
            raise ValueError(f"harmonic.{key} and harmonic.{key}_harmonics: give one of them "
                             "(the fundamental alone, or a row of harmonics 0, 1, ...)")
    kw = {**_force(tbl, H, n_dof, names), **_ground(tbl, H, n_dof, kind)}
    if not kw:
        raise ValueError("harmonic: no load: give force_dofs and force (or force_harmonics), or "
                         "ground_acceleration (or ground_acceleration_harmonics)")
    return kw


def _force(tbl: dict, H: int, n_dof: int, names) -> dict:
    """force_dofs and force (harmonic_balance's) of the table, or {} without a force."""
    kw = {}
    fkey = next((k for k in ("force", "force_harmonics") if k in tbl), None)
    if fkey is not None:
        if "force_dofs" not in tbl:
            raise ValueError(f"harmonic.force_dofs is required with harmonic.{fkey}: the "
                             "loaded DOFs, one per entry")
        given = tbl["force_dofs"]
        if not isinstance(given, list) or not given:
            raise ValueError(f"harmonic.force_dofs = {given!r}: must be a non-empty array of DOF "
                             "indices" + (" or names" if names is not None else ""))
        dofs = [_dof_index(f"harmonic.force_dofs[{i}]", d, n_dof, names)
                for i, d in enumerate(given)]
        for i, d in enumerate(dofs):
            if d in dofs[:i]:
                raise ValueError(f"harmonic.force_dofs = {given!r}: entry {i} ({given[i]!r}) "
                                 "repeats a DOF")
        values = tbl[fkey]
        if not isinstance(values, list) or len(values) != len(dofs):
            raise ValueError(f"harmonic.{fkey} = {values!r}: must be an array with one entry per "
                             f"harmonic.force_dofs entry ({len(dofs)})")
        if fkey == "force":
            F = np.array([_amplitude(f"harmonic.force[{i}]", v) for i, v in enumerate(values)])
        else:
            rows = [_harmonic_row(f"harmonic.force_harmonics[{i}]", v, H)
                    for i, v in enumerate(values)]
            F = np.zeros((len(rows), max(r.size for r in rows)), complex)
            for i, r in enumerate(rows):
                F[i, :r.size] = r
        if not np.any(F):
            raise ValueError(f"harmonic.{fkey} = {values!r}: the load is zero everywhere")
        kw["force_dofs"], kw["force"] = dofs, F
    elif "force_dofs" in tbl:
        raise ValueError(f"harmonic.force_dofs = {tbl['force_dofs']!r}: given without "
                         "harmonic.force (or harmonic.force_harmonics)")
    return kw


def _ground(tbl: dict, H: int, n_dof: int, kind: str) -> dict:
    """ground_acceleration and influence (harmonic_balance's) of the table, or {}."""
    kw = {}
    if "ground_acceleration" in tbl:
        A = np.array([_amplitude("harmonic.ground_acceleration", tbl["ground_acceleration"])])
        if not np.any(A):
            raise ValueError(f"harmonic.ground_acceleration = {tbl['ground_acceleration']!r}: "
                             "the load is zero")
        kw["ground_acceleration"] = A
    elif "ground_acceleration_harmonics" in tbl:
        row = _harmonic_row("harmonic.ground_acceleration_harmonics",
                            tbl["ground_acceleration_harmonics"], H)
        if not np.any(row):
            raise ValueError(f"harmonic.ground_acceleration_harmonics = "
                             f"{tbl['ground_acceleration_harmonics']!r}: the load is zero")
        kw["ground_acceleration"] = row[None, :]
    if "influence" in tbl:
        if "ground_acceleration" not in kw:
            raise ValueError("harmonic.influence is given without harmonic.ground_acceleration")
        if kind not in ("matrices", "beam"):
            raise ValueError(f"harmonic.influence: a {kind} moves with its base as a whole; the "
                             "key is for matrices and beam scenes")
        r = _number_list("harmonic.influence", tbl["influence"])
        if r.size != n_dof:
            raise ValueError(f"harmonic.influence has {r.size} entries, expected one per DOF "
                             f"({n_dof})")
        kw["influence"] = r
    return kw


def parse_harmonic(tbl, n_dof: int, names, kind: str, elements) -> dict:
    """The keywords of `harmonic_balance` (``amplitudes`` and ``frequency_hz``:
    `harmonic_balance_amplitude`) from a ``[harmonic]`` table, every field checked; errors
    name the field and its value (``harmonic.freqs_hz[1] = -1.0: must be > 0``)."""
    if not isinstance(tbl, dict):
        raise ValueError(f"harmonic = {tbl!r}: must be a table [harmonic]")
    _table("harmonic", tbl, HARMONIC_KEYS)
    if not elements:
        raise ValueError("harmonic: the steady state needs at least one [[element]] table (an "
                         "element with kind = \"cubic\" and k3 = 0.0 gives the linear response)")
    for k, el in enumerate(elements):
        if el.n_internal:
            raise ValueError(f"element[{k}] ({el.describe()}): [harmonic] does not support "
                             "elements with internal states (hysteresis) yet")
    defaults = _defaults()
    H = _integer("harmonic.harmonics", tbl.get("harmonics", defaults["harmonics"]), 1)
    kw = {"harmonics": H, **_sweep(tbl)}
    kw.update(_loads(tbl, H, n_dof, names, kind))
    kw.update(_options(tbl, H, defaults))
    return kw


def _sweep(tbl: dict) -> dict:
    """freqs_hz, or frequency_hz and amplitudes."""
    kw = {}
    if "freqs_hz" in tbl:
        for key in ("frequency_hz", "amplitudes"):
            if key in tbl:
                raise ValueError(f"harmonic.{key} = {tbl[key]!r} with harmonic.freqs_hz: give "
                                 "freqs_hz (a frequency sweep) or frequency_hz and amplitudes "
                                 "(the load's amplitude swept at one frequency)")
        kw["freqs_hz"] = _range("harmonic.freqs_hz", tbl["freqs_hz"], "Hz", True)
    elif "frequency_hz" in tbl or "amplitudes" in tbl:
        for key in ("frequency_hz", "amplitudes"):
            if key not in tbl:
                raise ValueError(f"harmonic.{key} is required: a sweep of the load's amplitude "
                                 "takes frequency_hz (Hz) and amplitudes = [start, end]")
        kw["frequency_hz"] = _positive("harmonic.frequency_hz", tbl["frequency_hz"])
        kw["amplitudes"] = _range("harmonic.amplitudes", tbl["amplitudes"],
                                  "load factors", False)
    else:
        raise ValueError("harmonic.freqs_hz is required: [start, end] in Hz (or frequency_hz and "
                         "amplitudes, a sweep of the load's amplitude at one frequency)")
    return kw


def _options(tbl: dict, H: int, defaults: dict) -> dict:
    """The continuation's and the solver's options the table gives."""
    kw = {}
    if "stability" in tbl:
        if not (isinstance(tbl["stability"], bool)
                or tbl["stability"] in ("auto", "full", "reduced")):
            raise ValueError(f"harmonic.stability = {tbl['stability']!r}: must be true, false, "
                             "'auto', 'full' or 'reduced'")
        kw["stability"] = tbl["stability"]
    for key in ("step", "max_step", "min_step", "max_angle", "tol"):
        if key in tbl:
            kw[key] = _positive(f"harmonic.{key}", tbl[key])
    step = {k: kw.get(k, defaults[k]) for k in ("min_step", "step", "max_step")}
    if not step["min_step"] <= step["step"] <= step["max_step"]:
        given = ", ".join(f"harmonic.{k} = {tbl[k]!r}" for k in step if k in tbl)
        raise ValueError(f"{given}: need min_step <= step <= max_step (defaults "
                         f"{defaults['min_step']:g}, {defaults['step']:g}, "
                         f"{defaults['max_step']:g})")
    for key, minimum in (("max_points", 2), ("max_iter", 1), ("n_time", 2 * H + 2)):
        if key in tbl:
            kw[key] = _integer(f"harmonic.{key}", tbl[key], minimum)
    if "receptance" in tbl:
        kw["receptance"] = _choice("harmonic.receptance", tbl["receptance"], RECEPTANCES)
    if "convergence_points" in tbl:     # the points re-solved with 2 H harmonics: n or "all"
        value = tbl["convergence_points"]
        kw["convergence_points"] = "all" if value == "all" else \
            _integer("harmonic.convergence_points", value, 0)
    return kw


# ----------------------------------------------------------------------------------------------
# the run


def _model_args(scene: Scene) -> tuple:
    """The model argument(s) of harmonic_balance: a Chain, the matrices, a Beam or a Shaft."""
    if scene.kind == "matrices":
        return scene.M, scene.C, scene.K
    if scene.model is not None:
        return (scene.model,)
    from dtdyn.linear._chain import Chain

    chain = scene.chain
    return (Chain(chain["mass"], chain["stiffness"], chain["damping"],
                  ground_stiffness=chain["ground_stiffness"],
                  ground_damping=chain["ground_damping"]),)


def require_harmonic(scene: Scene, command: str = "run_steady") -> None:
    """ValueError naming the table to add when the scene has no ``[harmonic]`` table."""
    if scene.harmonic is None:
        raise ValueError(f"{scene.source}: {command} needs a [harmonic] table (freqs_hz = "
                         "[start, end] in Hz, force_dofs and force, or ground_acceleration); "
                         "the scene has none")


def run_steady(scene: Scene, command: str = "run_steady"):
    """The periodic steady state of a scene with a ``[harmonic]`` table: `harmonic_balance`
    (or, with ``frequency_hz`` and ``amplitudes``, `harmonic_balance_amplitude`) on its model,
    its ``[[element]]`` tables and ``[output] outputs``.

    Parameters
    ----------
    scene : Scene
        A scene with a ``[harmonic]`` table (`dtdyn.app._scene.steady`).
    command : str
        What asks, for the messages.

    Returns
    -------
    result : HarmonicBalanceResult
    report : dict
        ``title, kind, n_dof, elements`` (descriptions), ``sweep`` ("frequency" or
        "amplitude"), ``harmonics, n_points, fold_frequency_hz, fold_amplitude``,
        ``stable_fraction`` (None without stability), ``run_time_s`` (the call's own),
        ``total_time_s``, ``receptance, stop, harmonic_error``.

    Raises
    ------
    ValueError
        No ``[harmonic]`` table, or a load or option harmonic_balance refuses (the message
        starts with the scene file).
    NewtonError
        No solution at the start, or the continuation's step fell below ``min_step``.
    """
    from dtdyn._engine.errors import NewtonError
    from dtdyn.nonlinear._harmonic_balance import harmonic_balance, harmonic_balance_amplitude

    require_harmonic(scene, command)
    kw = dict(scene.harmonic)
    sweep = "amplitude" if "amplitudes" in kw else "frequency"
    function = harmonic_balance_amplitude if sweep == "amplitude" else harmonic_balance
    start = time.perf_counter()
    try:
        result = function(*_model_args(scene), elements=list(scene.elements),
                          outputs=scene.outputs, **kw)
    except NewtonError as exc:
        raise NewtonError(f"{scene.source}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{scene.source}: [harmonic]: {exc}") from None
    info = result.info
    report = {
        "title": scene.title, "kind": scene.kind, "n_dof": scene.n_dof,
        "elements": [el.describe() for el in scene.elements], "sweep": sweep,
        "harmonics": kw["harmonics"], "n_points": int(result.frequency_hz.size),
        "fold_frequency_hz": np.asarray(result.fold_frequency_hz).tolist(),
        "fold_amplitude": (None if result.fold_amplitude is None
                           else np.asarray(result.fold_amplitude).tolist()),
        "stable_fraction": (None if result.stable is None
                            else float(np.mean(result.stable))),
        "run_time_s": info.get("run_time"), "total_time_s": time.perf_counter() - start,
        "receptance": info.get("receptance"), "stop": info.get("stop"),
        "harmonic_error": info.get("harmonic_error"),
    }
    return result, report


def _plain(value):
    """JSON values of the keywords (complex arrays: [re, im] pairs)."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "c":
            return np.stack([value.real, value.imag], axis=-1).tolist()
        return value.tolist()
    if isinstance(value, tuple):
        return list(value)
    return value


def steady_summary(scene: Scene) -> dict:
    """The scene in a few JSON-safe fields: what a saved curve says about its origin."""
    return {"title": scene.title, "source": scene.source, "kind": scene.kind,
            "n_dof": scene.n_dof, "elements": [el.describe() for el in scene.elements],
            "outputs": [scene.dof_label(d) for d in scene.outputs],
            "harmonic": {k: _plain(v) for k, v in (scene.harmonic or {}).items()}}


def save_steady(path: str | os.PathLike, result, scene: Scene) -> Path:
    """Write the curve with the scene's summary in ``info["scene"]``: ``.npz`` or ``.csv`` (and
    its ``.csv.json`` sidecar) by the extension (`HarmonicBalanceResult.save`; atomic)."""
    stored = dataclasses.replace(result, info={**result.info, "scene": steady_summary(scene)})
    return stored.save(path)


def plot_steady(path: str | os.PathLike, result, scene: Scene) -> None:
    """Draw max |x| of each output (up to `MAX_PANELS`, one panel each) against the forcing
    frequency (`HarmonicBalanceResult.plot`: unstable parts dashed), or against the load
    factor for a sweep of the amplitude; saved atomically, the format by the suffix."""
    from dtdyn.app._scene.io import plot_checked_path

    path, fmt = plot_checked_path(path)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = min(len(result.outputs), MAX_PANELS)
    fig = Figure(figsize=(7.0, 1.0 + 2.6 * n), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    amplitude = "amplitudes" in (scene.harmonic or {})
    for j, ax in enumerate(axes):
        if amplitude:
            a, x = result.amplitude, result.x_max[:, j]
            st = np.ones(a.size, bool) if result.stable is None else result.stable
            for i in range(a.size - 1):
                ax.plot(a[i:i + 2], x[i:i + 2], "C0-" if st[i] and st[i + 1] else "C3--",
                        lw=1.2)
            ax.set_xlabel("load factor")
        else:
            result.plot(output=j, ax=ax)
        ax.set_ylabel(f"max |x| of DOF {scene.dof_label(result.outputs[j])}")
        ax.grid(True, alpha=0.3)
    more = (f" (the first {n} of {len(result.outputs)} outputs)"
            if len(result.outputs) > n else "")
    where = f" at {scene.harmonic['frequency_hz']:g} Hz" if amplitude else ""
    fig.suptitle(f"{scene.title}: harmonic balance, H = {scene.harmonic['harmonics']}{where}; "
                 f"unstable dashed{more}", fontsize=10)
    write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=110))
