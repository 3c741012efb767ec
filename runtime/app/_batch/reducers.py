"""Reductions of each case's response, computed on the workers: what a batch stores per case
instead of (or with) the time histories.

Every reducer maps ``(response, scene)`` to ``{name: (dims, values)}`` without the ``case``
dimension; the batch adds it. ``"output"`` is the dimension of the stored DOFs, ``"time"`` of
the samples.

========== ==================================================================================
name       variables
========== ==================================================================================
history    the time histories: ``x``, ``v``, ``a`` (those the scene stores), ``a_abs``,
           ``x_abs`` (under support motion), ``g``, ``z`` (nonlinear element forces and
           states); dims (time, output), (time, element), (time, state)
peak       ``peak_<q>`` = max over time of ``|q|`` for each stored motion quantity q; (output)
rms        ``rms_<q>`` = sqrt(mean over the samples of q^2); (output)
drift      ``peak_drift`` = max over time of ``|x_j - x_{j-1}|``: the stored outputs, in the
           scene's order, are the floors from the bottom up; the first floor's drift is its
           displacement relative to the support (x is relative under support motion); (output)
srs        ``psa`` = the pseudo-acceleration response spectrum (`dtdyn.response_spectrum`) of
           each output's absolute acceleration (``a_abs`` under support motion, else ``a``):
           floor spectra; (period, output). `Spectrum` chooses the periods and the damping
           ratio (default: 40 periods from max(0.05 s, 10 dt) to 4 s, 5 %)
welch      ``welch_<q>`` = the one-sided PSD of each stored motion quantity q by Welch's
           method (`Welch`: `scipy.signal.welch`, Hann segments of 1,024 samples, half
           overlapping), (freq_hz, output); ``welch_dof``, its equivalent degrees of freedom
damage     ``damage_<q>`` = the Palmgren-Miner damage of the rainflow cycles of q (`Damage`:
           an S-N curve is required, so the name alone is an error), (output)
========== ==================================================================================

`Rms`, `Welch` and `Damage` take ``start`` (s): the samples before it are left out, so that
the start-up from rest of a run under a stationary random load does not bias the statistics
of its stationary part. `dtdyn.app._batch.monte_carlo_summary` gives the across-case means and
their confidence intervals.

A user reducer is any callable ``f(response, scene)`` returning a dict: name -> a value
(a number or an array; its dimensions are named ``<name>_0``, ``<name>_1``, ...) or a tuple
``(dims, values)``. It runs on the workers (it is pickled with cloudpickle, so a lambda or a
local function works). Its shapes must be the same for every case.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dtdyn._engine.public import public, warn

__all__ = ["REDUCERS", "Spectrum", "Rms", "Welch", "Damage", "reducers_from", "MOTION"]

#: the stored motion quantities of a Response, per output DOF
MOTION = ("x", "v", "a", "a_abs", "x_abs")


def _motion(response) -> list[str]:
    return [q for q in MOTION if getattr(response, q, None) is not None]


def history(response, scene) -> dict:
    out = {q: (("time", "output"), np.asarray(getattr(response, q))) for q in _motion(response)}
    for q, dim in (("g", "element"), ("z", "state")):
        if getattr(response, q, None) is not None:
            out[q] = (("time", dim), np.asarray(getattr(response, q)))
    return out


def peak(response, scene) -> dict:
    return {f"peak_{q}": (("output",), np.abs(getattr(response, q)).max(axis=0))
            for q in _motion(response)}


def rms(response, scene) -> dict:
    return {f"rms_{q}": (("output",), np.sqrt(np.mean(np.square(getattr(response, q)), axis=0)))
            for q in _motion(response)}


def drift(response, scene) -> dict:
    if response.x is None:
        raise ValueError("reduce 'drift' needs the displacements: add \"x\" to "
                         "output.quantities")
    x = np.asarray(response.x)
    below = np.concatenate([np.zeros((x.shape[0], 1)), x[:, :-1]], axis=1)
    return {"peak_drift": (("output",), np.abs(x - below).max(axis=0))}


@public(renamed={"damping": "damping_ratio"})
@dataclass(frozen=True)
class Spectrum:
    """The ``srs`` reducer with its periods and damping ratio: ``psa`` (period, output), the
    pseudo-acceleration spectrum (`dtdyn.response_spectrum`) of each output's absolute
    acceleration.

    Attributes
    ----------
    periods : tuple of float, optional
        Natural periods, s. Default (None): 40 log-spaced from max(0.05 s, 10 dt) to 4 s
        (`dtdyn.modal._spectrum.default_periods`), dt of the batch's first case: the periods
        its records resolve (10 samples per period at least). A case whose record is coarser
        than those periods allow warns (`SRSSamplingWarning`, counted in the batch's summary).
    damping_ratio : float
        Damping ratio (default 0.05; ``damping`` before this release: deprecated).

    Examples
    --------
    >>> from dtdyn.app._batch import Spectrum
    >>> Spectrum(periods=(0.1, 1.0)).damping_ratio
    0.05
    >>> T = Spectrum().resolved(0.01).periods        # a 100 Hz record: 0.1 s to 4 s
    >>> len(T), round(T[0], 6), round(T[-1], 6)
    (40, 0.1, 4.0)
    """

    periods: tuple | None = None
    damping_ratio: float = 0.05
    name = "srs"

    @property
    def damping(self) -> float:
        """Deprecated: `damping_ratio`."""
        warn("Spectrum.damping is now Spectrum.damping_ratio; Spectrum.damping will be removed "
             "in the next release", DeprecationWarning)
        return self.damping_ratio

    def resolved(self, dt) -> Spectrum:
        """This spectrum with its periods set: the given ones, or the default for a record of
        step ``dt`` (s)."""
        if self.periods is not None:
            return self
        from dtdyn.modal._spectrum import default_periods
        periods = default_periods(dt, count=40, shortest=0.05, longest=4.0)
        return replace(self, periods=tuple(float(T) for T in periods))

    def coords(self) -> dict:
        if self.periods is None:
            return {}        # known once a case gives dt (the batch resolves it first)
        return {"period": np.asarray(self.periods, dtype=float)}

    def __call__(self, response, scene) -> dict:
        from dtdyn.modal._spectrum import response_spectrum

        acc = response.a_abs if response.a_abs is not None else response.a
        if acc is None:
            raise ValueError("reduce 'srs' needs the accelerations: add \"a\" to "
                             "output.quantities")
        acc = np.asarray(acc)
        periods = self.resolved(scene.dt).periods
        psa = np.column_stack([response_spectrum(acc[:, j], scene.dt, periods,
                                                 damping_ratio=self.damping_ratio).psa[0]
                               for j in range(acc.shape[1])])
        return {"psa": (("period", "output"), psa)}


def _start_index(start: float, scene, name: str, needed: int = 2) -> int:
    """The first sample at or after ``start`` s; at least ``needed`` samples must remain."""
    n = scene.n_steps + 1
    first = int(np.ceil(start / scene.dt - 1e-9))
    if n - first < needed:
        raise ValueError(f"reduce {name!r}: start = {start:g} s leaves {max(n - first, 0)} "
                         f"sample(s) of the {n} of the record (dt = {scene.dt:g} s); "
                         f"{name} needs at least {needed}")
    return first


def _start(name: str, start) -> float:
    if isinstance(start, bool) or not isinstance(start, (int, float, np.integer, np.floating)) \
            or not np.isfinite(start) or start < 0:
        raise ValueError(f"{name}.start = {start!r}: must be a time >= 0 (s)")
    return float(start)


@public
@dataclass(frozen=True)
class Rms:
    """The ``rms`` reducer from a start time on: ``rms_<q>`` (output), the root mean square
    over the samples at or after ``start`` of each stored motion quantity q.

    Attributes
    ----------
    start : float
        s (default 0: every sample, as the name ``"rms"``). Under a stationary random load a
        run from rest reaches its stationary state after a few times the slowest mode's decay
        time 1 / (zeta omega); the samples before ``start`` are left out.

    Examples
    --------
    >>> from dtdyn.app._batch import Rms
    >>> Rms(start=1.0)
    Rms(start=1.0)
    """

    start: float = 0.0
    name = "rms"

    def __post_init__(self):
        _start("Rms", self.start)

    def __call__(self, response, scene) -> dict:
        first = _start_index(self.start, scene, self.name, 1)
        return {f"rms_{q}": (("output",), np.sqrt(np.mean(np.square(
            np.asarray(getattr(response, q))[first:]), axis=0))) for q in _motion(response)}


def _overlap_correlation(window: np.ndarray, shift: int, segments: int) -> float:
    """sum_{j=1}^{K-1} (1 - j/K) rho(j), rho(j) = (sum_n w_n w_{n+jD})^2 / (sum_n w_n^2)^2:
    the correlation of the K half-overlapping periodograms of Welch's estimate."""
    norm = float(np.sum(window**2)) ** 2
    total = 0.0
    for j in range(1, segments):
        lag = j * shift
        if lag >= window.size:
            break
        total += (1.0 - j / segments) * float(np.dot(window[:-lag], window[lag:])) ** 2 / norm
    return total


@public
@dataclass(frozen=True)
class Welch:
    """The ``welch`` reducer: ``welch_<q>`` (freq_hz, output), the one-sided PSD of each stored
    motion quantity q by Welch's method (`scipy.signal.welch`: Hann segments of ``nperseg``
    samples overlapping by half, each segment's mean removed, density scaling, (unit)^2/Hz)
    over the samples at or after ``start``; and ``welch_dof`` (a number per case), the
    estimate's equivalent degrees of freedom nu.

    Attributes
    ----------
    nperseg : int
        Samples per segment (default 1024): the resolution is 1 / (nperseg dt) Hz.
    start : float
        s: the samples before it are left out (the start-up from rest).
    dt : float, optional
        The records' sample step, s: set by the batch from its first case (every case must
        have it); it fixes the frequencies ``freq_hz = k / (nperseg dt)``.

    Notes
    -----
    For a Gaussian record, each bin of Welch's estimate (away from 0 Hz and the Nyquist
    frequency) is G(f) chi^2_nu / nu with (Welch 1967, eq. 9; Percival & Walden, *Spectral
    Analysis for Physical Applications*, 1993, eq. 292b)

        nu = 2 K / (1 + 2 sum_{j=1}^{K-1} (1 - j/K) rho(j)),
        rho(j) = (sum_n w_n w_{n+jD})^2 / (sum_n w_n^2)^2,

    K segments of the window w shifted by D = nperseg / 2 samples (rho(1) = 1/36 for Hann),
    so that `monte_carlo_summary` gives the mean PSD over cases its chi-square interval with
    the cases' nu added (the cases are independent). The estimate is the PSD smoothed by the
    window's spectral kernel (about 1.5 bins wide): a resonance narrower than a few bins is
    flattened.

    Examples
    --------
    >>> from dtdyn.app._batch import Welch
    >>> w = Welch(nperseg=8).resolved(0.01)
    >>> w.coords()["freq_hz"].tolist()
    [0.0, 12.5, 25.0, 37.5, 50.0]
    """

    nperseg: int = 1024
    start: float = 0.0
    dt: float | None = None
    name = "welch"

    def __post_init__(self):
        if isinstance(self.nperseg, bool) or not isinstance(self.nperseg, (int, np.integer)) \
                or self.nperseg < 4:
            raise ValueError(f"Welch.nperseg = {self.nperseg!r}: must be an integer >= 4 "
                             "(samples per segment)")
        _start("Welch", self.start)
        if self.dt is not None and not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"Welch.dt = {self.dt!r}: must be a time step > 0 (s)")

    def resolved(self, dt) -> Welch:
        """This reducer with the records' step ``dt`` (s) set (kept if already set)."""
        return self if self.dt is not None else replace(self, dt=float(dt))

    def coords(self) -> dict:
        if self.dt is None:
            return {}        # known once a case gives dt (the batch resolves it first)
        return {"freq_hz": np.fft.rfftfreq(int(self.nperseg), self.dt)}

    def dof(self, n_samples: int) -> float:
        """The equivalent degrees of freedom nu of the estimate from ``n_samples`` samples."""
        from scipy.signal import get_window

        shift = int(self.nperseg) - int(self.nperseg) // 2
        segments = 1 + (n_samples - int(self.nperseg)) // shift
        window = get_window("hann", int(self.nperseg))
        return 2.0 * segments / (1.0 + 2.0 * _overlap_correlation(window, shift, segments))

    def __call__(self, response, scene) -> dict:
        from scipy.signal import welch

        dt = self.dt if self.dt is not None else float(scene.dt)
        if not np.isclose(scene.dt, dt, rtol=1e-12, atol=0.0):
            raise ValueError(f"reduce 'welch': the case's dt = {scene.dt:g} s differs from the "
                             f"batch's {dt:g} s (from its first case): the PSDs of a batch "
                             "share their frequencies")
        first = _start_index(self.start, scene, self.name, int(self.nperseg))
        out = {}
        for q in _motion(response):
            record = np.asarray(getattr(response, q))[first:]
            _, G = welch(record, fs=1.0 / dt, window="hann", nperseg=int(self.nperseg),
                         noverlap=int(self.nperseg) // 2, detrend="constant",
                         scaling="density", axis=0)
            out[f"welch_{q}"] = (("freq_hz", "output"), G)
        out["welch_dof"] = ((), np.asarray(self.dof(scene.n_steps + 1 - first)))
        return out


@public
@dataclass(frozen=True)
class Damage:
    """The ``damage`` reducer: ``damage_<q>`` (output), the Palmgren-Miner damage
    (`dtdyn.miner_damage`) of the rainflow cycles (`dtdyn.rainflow_cycles`, half cycles of
    the residue included) of ``scale * q`` at each output, over the samples at or after
    ``start``.

    Attributes
    ----------
    sn_curve : dtdyn.SNCurve
        The S-N curve, in the unit of ``scale * q`` (amplitudes).
    quantities : tuple of str
        The motion quantities whose damage is computed (default ``("x",)``); each must be
        stored by the scenes (``[output] quantities``).
    scale : float
        Stress per unit of the quantity (default 1: the S-N curve is in the quantity's unit).
    start : float
        s: the samples before it are left out (the start-up from rest).
    mean_correction : {None, "goodman"}
        As `dtdyn.miner_damage`, with ``ultimate_strength``.
    ultimate_strength : float, optional
        S_u, with ``mean_correction="goodman"``.

    Examples
    --------
    >>> import dtdyn as dd
    >>> from dtdyn.app._batch import Damage
    >>> Damage(dd.SNCurve(slope=5.0, coefficient=1e12), scale=2e8).quantities
    ('x',)
    """

    sn_curve: object = None
    quantities: tuple = ("x",)
    scale: float = 1.0
    start: float = 0.0
    mean_correction: str | None = None
    ultimate_strength: float | None = None
    name = "damage"

    def __post_init__(self):
        from dtdyn.random_vibration._fatigue import SNCurve

        if not isinstance(self.sn_curve, SNCurve):
            raise ValueError(f"Damage.sn_curve = {self.sn_curve!r}: give a dtdyn.SNCurve "
                             "(reduce 'damage' needs the S-N curve: "
                             "Damage(sn_curve=dd.SNCurve(slope, coefficient)))")
        quantities = (self.quantities,) if isinstance(self.quantities, str) else \
            tuple(self.quantities)
        if not quantities or any(q not in MOTION for q in quantities):
            raise ValueError(f"Damage.quantities = {self.quantities!r}: each must be one of "
                             f"{', '.join(map(repr, MOTION))}")
        object.__setattr__(self, "quantities", quantities)
        if isinstance(self.scale, bool) or not isinstance(
                self.scale, (int, float, np.integer, np.floating)) or \
                not np.isfinite(self.scale) or self.scale <= 0:
            raise ValueError(f"Damage.scale = {self.scale!r}: must be a finite number > 0 "
                             "(stress per unit of the quantity)")
        _start("Damage", self.start)
        if self.mean_correction not in (None, "goodman"):
            raise ValueError(f"Damage.mean_correction = {self.mean_correction!r}: must be None "
                             "or 'goodman'")

    def __call__(self, response, scene) -> dict:
        from dtdyn.random_vibration._rainflow import rainflow_cycles

        first = _start_index(self.start, scene, self.name, 2)
        out = {}
        for q in self.quantities:
            values = getattr(response, q, None)
            if values is None:
                raise ValueError(f"reduce 'damage' needs the quantity {q!r}: add it to "
                                 "output.quantities (or give Damage(quantities=...) one "
                                 "the scene stores)")
            record = self.scale * np.asarray(values)[first:]
            out[f"damage_{q}"] = (("output",), np.array([
                rainflow_cycles(record[:, j]).damage(
                    self.sn_curve, mean_correction=self.mean_correction,
                    ultimate_strength=self.ultimate_strength)
                for j in range(record.shape[1])]))
        return out


#: the reducers with parameters, by name: a name alone gives the defaults (Damage has none)
CONFIGURABLE = (Spectrum, Rms, Welch, Damage)


def resolve(reducers, dt) -> list:
    """The reducers with a default-period `Spectrum` and a `Welch` resolved for records of
    step ``dt``."""
    return [r.resolved(dt) if isinstance(r, (Spectrum, Welch)) else r for r in reducers]


#: the reducers by name
REDUCERS = {"history": history, "peak": peak, "rms": rms, "drift": drift}


class _User:
    """A user callable as a reducer: values without dims get ``<name>_<i>`` dims."""

    def __init__(self, fn):
        self.fn = fn
        self.name = getattr(fn, "__name__", "reducer")

    def __call__(self, response, scene) -> dict:
        got = self.fn(response, scene)
        if not isinstance(got, dict):
            raise ValueError(f"reducer {self.name!r} returned {type(got).__name__}, not a dict "
                             "name -> value or (dims, value)")
        out = {}
        for key, value in got.items():
            if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], (tuple, list)):
                dims, values = tuple(value[0]), np.asarray(value[1])
            else:
                values = np.asarray(value)
                dims = tuple(f"{key}_{i}" for i in range(values.ndim))
            if values.ndim != len(dims):
                raise ValueError(f"reducer {self.name!r}: {key!r} has {values.ndim} dimension(s) "
                                 f"but names {len(dims)}: {dims}")
            if "case" in dims:
                raise ValueError(f"reducer {self.name!r}: {key!r} may not use the dimension "
                                 "'case' (the batch adds it)")
            out[str(key)] = (dims, values)
        return out


def reducers_from(reduce) -> list:
    """The reducers of ``run_batch(reduce=...)``: None (the time histories), a comma-separated
    string of names, or a sequence of names, `Spectrum` objects and callables."""
    if reduce is None:
        return [history]
    if isinstance(reduce, str):
        reduce = [r.strip() for r in reduce.split(",") if r.strip()]
    elif callable(reduce):
        reduce = [reduce]
    out = []
    for item in reduce:
        if isinstance(item, str):
            if item == "srs":
                out.append(Spectrum())
            elif item == "welch":
                out.append(Welch())
            elif item == "damage":
                raise ValueError("reduce = 'damage': the damage needs an S-N curve; give "
                                 "dtdyn.app._batch.Damage(sn_curve=dtdyn.SNCurve(slope, "
                                 "coefficient)) in reduce")
            elif item in REDUCERS:
                out.append(REDUCERS[item])
            else:
                raise ValueError(f"reduce = {item!r}: unknown reducer, allowed: "
                                 f"{', '.join(map(repr, [*REDUCERS, 'srs', 'welch']))}, a "
                                 "Damage or a callable")
        elif isinstance(item, CONFIGURABLE) or item in REDUCERS.values():
            out.append(item)
        elif callable(item):
            out.append(_User(item))
        else:
            raise ValueError(f"reduce entry {item!r}: must be a reducer name, a Spectrum, Rms, "
                             "Welch or Damage, or a callable f(response, scene) -> dict")
    if not out:
        raise ValueError("reduce is empty: give None (time histories) or one or more reducers")
    return out


def reducer_coords(reducers) -> dict:
    """Extra coordinates the reducers define (the spectrum's periods)."""
    coords = {}
    for r in reducers:
        if hasattr(r, "coords"):
            coords.update(r.coords())
    return coords


def reducer_name(r) -> str:
    return getattr(r, "name", None) or getattr(r, "__name__", "reducer")


def reducer_fingerprint(r) -> str:
    """What a resumed batch compares of a reducer: its name, and its parameters (`Spectrum`)
    or the source of a callable (its code's bytes when the source is not available)."""
    import hashlib
    import inspect

    if isinstance(r, CONFIGURABLE):
        return repr(r)
    fn = r.fn if isinstance(r, _User) else r
    if fn in REDUCERS.values():
        return reducer_name(r)
    try:
        text = inspect.getsource(fn).encode()
    except (OSError, TypeError):
        code = getattr(fn, "__code__", None)
        text = code.co_code if code is not None else repr(type(fn)).encode()
    return f"{reducer_name(r)}:{hashlib.sha256(text).hexdigest()[:16]}"
