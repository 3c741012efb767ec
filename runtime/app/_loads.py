"""Load time histories for scenes: a ``[[load]]`` table of a scene file -> samples at times ``t``.

Kinds and their fields (defaults in brackets)::

    step         amplitude [1.0], t0 [0.0]        f(t) = amplitude          for t >= t0, else 0
    ramp         slope, t0 [0.0]                  f(t) = slope (t - t0)     for t >= t0, else 0
    sine         amplitude, frequency (Hz), phase (rad) [0.0]
                                                  f(t) = amplitude sin(2 pi frequency t + phase)
    white_noise  std, seed (int)                  f(t_i) = std * default_rng(seed).standard_normal
    file         path, column [0]                 one sample per time step from a .csv or .npy file
    psd          psd, seed (int)                  a stationary Gaussian record with the one-sided
                                                  PSD given as breakpoints [[Hz, value], ...]
                                                  (log-log between them, a value may be a slope
                                                  "+3 dB/oct"; dtdyn.random_vibration.psd_table),
                                                  by random_time_history(table, dt, len(t), seed)
    shock        srs, seed (int), damping_ratio [0.05], t0 [0.0]
                                                  a shock whose SRS matches the target given as
                                                  breakpoints [[Hz, value], ...] (log-log between
                                                  them, on a 1/12-octave grid) within 1.5 dB, by
                                                  shock_time_history, starting at t0

A ``file`` path is taken relative to the scene file's folder. The file must hold exactly
``len(t)`` samples (one per time step ``t_0 .. t_n``, at the scene's ``dt``); a CSV is read with
``numpy.loadtxt(delimiter=",")`` (``#`` starts a comment), a 2-D file picks ``column``.

Every error is a ``ValueError`` naming the field, e.g. ``load[0].frequency = -2.0: ...``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dtdyn._engine import validate

__all__ = ["LOAD_KINDS", "sample_load", "finite_number"]

#: kind -> (required fields, optional fields with their defaults)
LOAD_KINDS: dict[str, tuple[tuple[str, ...], dict]] = {
    "step": ((), {"amplitude": 1.0, "t0": 0.0}),
    "ramp": (("slope",), {"t0": 0.0}),
    "sine": (("amplitude", "frequency"), {"phase": 0.0}),
    "white_noise": (("std", "seed"), {}),
    "file": (("path",), {"column": 0}),
    "psd": (("psd", "seed"), {}),
    "shock": (("srs", "seed"), {"damping_ratio": 0.05, "t0": 0.0}),
}


def finite_number(name: str, value) -> float:
    """A finite real number from TOML (int or float; not bool, not a string)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {value!r}: must be a number")
    try:
        v = float(value)
    except OverflowError:  # a TOML integer beyond the float range
        raise ValueError(f"{name} = {value!r}: must be finite") from None
    if not np.isfinite(v):
        raise ValueError(f"{name} = {value!r}: must be finite")
    return v


def _integer(name: str, value, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} = {value!r}: must be an integer")
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} = {value!r}: must be >= {minimum}")
    return int(value)


def _time_step(t: np.ndarray) -> float | None:
    """The sample spacing of ``t`` (None for a single sample)."""
    if t.size < 2:
        return None
    return float(t[-1] - t[0]) / (t.size - 1)


def _read_file(name: str, spec: dict, n: int | None, base_dir: Path) -> np.ndarray:
    """The samples of a "file" load (n: the count it must have; None: any, at least 2)."""
    raw = spec["path"]
    if not isinstance(raw, str) or not raw.strip():
        raise ValueError(f"{name}.path = {raw!r}: must be a non-empty string")
    column = _integer(f"{name}.column", spec.get("column", 0), minimum=0)
    path = Path(base_dir) / raw
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".npy"):
        raise ValueError(f"{name}.path = {raw!r}: unsupported file type {path.suffix!r}, "
                         "allowed: '.csv', '.npy'")
    if not path.is_file():
        raise ValueError(f"{name}.path = {raw!r}: no such file {str(path)!r}")
    try:
        if suffix == ".csv":
            data = np.loadtxt(path, delimiter=",", dtype=float, ndmin=2)
        else:
            data = np.asarray(np.load(path, allow_pickle=False), dtype=float)
    except (ValueError, OSError) as exc:
        raise ValueError(f"{name}.path = {raw!r}: cannot read {str(path)!r}: {exc}") from None
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2:
        raise ValueError(f"{name}.path = {raw!r}: expected a 1-D or 2-D array, "
                         f"got shape {data.shape}")
    if column >= data.shape[1]:
        raise ValueError(f"{name}.column = {column}: the file {raw!r} has "
                         f"{data.shape[1]} column(s)")
    samples = data[:, column]
    if (n is not None and samples.size != n) or samples.size < 2:
        raise ValueError(f"{name}.path = {raw!r}: has {samples.size} samples, expected "
                         f"{n if n is not None else 'at least 2'} (one per time step t_0 .. t_n "
                         "at the scene's dt, or at the ground record's own dt)")
    bad = ~np.isfinite(samples)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}.path = {raw!r}: sample {i} (column {column}) is {samples[i]!r}, "
                         "not finite")
    return np.array(samples, dtype=float)


def sample_load(spec: dict, t: np.ndarray, base_dir: Path, *, name: str = "load",
                extra_keys: tuple[str, ...] = ()) -> np.ndarray:
    """Samples of one load at times ``t``.

    Parameters
    ----------
    spec : dict
        ``{"kind": ..., <that kind's fields>}`` as read from a ``[[load]]`` table.
    t : ndarray, shape (n,)
        Sample times (uniformly spaced for ``white_noise`` and ``file``: one value per sample).
    base_dir : Path
        Folder that a ``file`` load's relative ``path`` is resolved against.
    name : str
        Field path used in error messages, e.g. ``"load[2]"``.
    extra_keys : tuple of str
        Keys the caller handles itself (e.g. ``"dof"``); accepted and ignored here.

    Returns
    -------
    ndarray, shape (n,)
        Finite float samples.

    Raises
    ------
    ValueError
        Naming the field and the value: unknown kind or key, missing or invalid field, unreadable
        file or a file with the wrong number of samples.

    Example
    -------
    >>> sample_load({"kind": "ramp", "slope": 2.0}, np.array([0.0, 0.5, 1.0]), Path("."))
    array([0., 1., 2.])
    """
    if not isinstance(spec, dict):
        raise ValueError(f"{name} must be a table, got {spec!r}")
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"t must be 1-D, got shape {t.shape}")

    kind = spec.get("kind")
    if not isinstance(kind, str) or kind not in LOAD_KINDS:  # [] would be unhashable
        allowed = ", ".join(repr(k) for k in LOAD_KINDS)
        raise ValueError(f"{name}.kind = {kind!r}: unknown load kind, allowed: {allowed}")
    required, optional = LOAD_KINDS[kind]
    allowed_keys = ("kind", *extra_keys, *required, *optional)
    for key in spec:
        if key not in allowed_keys:
            raise ValueError(f"{name}.{key} = {spec[key]!r}: unknown key for kind {kind!r}, "
                             f"allowed: {', '.join(allowed_keys)}")
    for key in required:
        if key not in spec:
            raise ValueError(f"{name}.{key} is required for kind {kind!r}")

    def num(key: str) -> float:
        return finite_number(f"{name}.{key}", spec.get(key, optional.get(key)))

    dt = _time_step(t)
    # times equal to t0 up to rounding of t = i * dt count as "on or after t0"
    tol = 1e-9 * dt if dt else 0.0

    if kind == "step":
        amplitude, t0 = num("amplitude"), num("t0")
        return np.where(t >= t0 - tol, amplitude, 0.0)

    if kind == "ramp":
        slope, t0 = num("slope"), num("t0")
        return np.where(t >= t0 - tol, slope * (t - t0), 0.0)

    if kind == "sine":
        amplitude, phase = num("amplitude"), num("phase")
        frequency = validate.positive_scalar(f"{name}.frequency", num("frequency"))
        if dt and frequency > 0.5 / dt:
            raise ValueError(f"{name}.frequency = {spec['frequency']!r}: above the Nyquist "
                             f"frequency 0.5/dt = {0.5 / dt:g} Hz of the time grid")
        return amplitude * np.sin(2.0 * np.pi * frequency * t + phase)

    if kind == "white_noise":
        std = num("std")
        if std < 0.0:
            raise ValueError(f"{name}.std = {spec['std']!r}: must be >= 0")
        seed = _integer(f"{name}.seed", spec["seed"], minimum=0)
        return std * np.random.default_rng(seed).standard_normal(t.size)

    records = {"shock": lambda: _shock_record(name, spec, t, dt, num("damping_ratio"), num("t0")),
               "psd": lambda: _psd_record(name, spec, t, dt),
               "file": lambda: _read_file(name, spec, t.size, Path(base_dir))}
    return records[kind]()


def _shock_record(name: str, spec: dict, t: np.ndarray, dt: float | None, zeta: float,
                  t0: float) -> np.ndarray:
    """The samples of a "shock" load: `shock_time_history` of the target SRS (breakpoints,
    log-log on a 1/12-octave grid) at the step of t, from t0 on, zero before."""
    from dtdyn.random_vibration._psd import PsdTable
    from dtdyn.random_vibration._synthesis import shock_time_history

    seed = _integer(f"{name}.seed", spec["seed"], minimum=0)
    if dt is None:
        raise ValueError(f"{name}: a shock load needs at least two time steps")
    raw = spec["srs"]
    try:
        f, value = np.array(raw, dtype=float).T
        target = PsdTable(f, value)          # the same log-log interpolation as a PSD table
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}.srs = {raw!r}: give breakpoints [[Hz, value], ...], "
                         f"increasing frequencies, values > 0 ({exc})") from None
    if not 0.0 < zeta < 1.0:
        raise ValueError(f"{name}.damping_ratio = {zeta!r}: must be in (0, 1)")
    n = int(np.ceil(12 * np.log2(f[-1] / f[0]))) + 1
    grid = np.geomspace(f[0], f[-1], n)
    shock = shock_time_history(target(grid), grid, dt, damping_ratio=zeta, seed=seed)
    start = int(round(t0 / dt))
    if t0 < 0 or start + shock.a.size > t.size:
        raise ValueError(f"{name}: the shock lasts {shock.t[-1]:g} s from t0 = {t0:g} s, "
                         f"beyond the scene's {t[-1]:g} s: lengthen time.duration or move t0")
    out = np.zeros(t.size)
    out[start:start + shock.a.size] = shock.a
    return out


def _psd_record(name: str, spec: dict, t: np.ndarray, dt: float | None) -> np.ndarray:
    """The samples of a "psd" load: a Gaussian record with the table's PSD at the step of t."""
    from dtdyn.random_vibration import psd_table
    from dtdyn.random_vibration._synthesis import random_time_history

    seed = _integer(f"{name}.seed", spec["seed"], minimum=0)
    if dt is None:
        raise ValueError(f"{name}: a psd load needs at least two time steps")
    raw = spec["psd"]
    if isinstance(raw, (str, bytes, dict)) or not isinstance(raw, (list, tuple)):
        raise ValueError(f"{name}.psd = {raw!r}: give breakpoints [[Hz, PSD], ...]")
    try:
        table = psd_table(raw)
    except ValueError as exc:
        raise ValueError(f"{name}.psd = {raw!r}: {str(exc).removeprefix('psd_table: ')}") from None
    if table.freqs_hz[-1] > 0.5 / dt * (1.0 + 1e-12):
        raise ValueError(f"{name}.psd reaches {table.freqs_hz[-1]:g} Hz, above the Nyquist "
                         f"frequency 0.5/dt = {0.5 / dt:g} Hz of the time grid: take "
                         f"dt <= {0.5 / table.freqs_hz[-1]:.6g} s")
    return random_time_history(table, dt, t.size, seed=seed)
