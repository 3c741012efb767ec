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
========== ==================================================================================

A user reducer is any callable ``f(response, scene)`` returning a dict: name -> a value
(a number or an array; its dimensions are named ``<name>_0``, ``<name>_1``, ...) or a tuple
``(dims, values)``. It runs on the workers (it is pickled with cloudpickle, so a lambda or a
local function works). Its shapes must be the same for every case.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dtdyn._engine.public import public, warn

__all__ = ["REDUCERS", "Spectrum", "reducers_from", "MOTION"]

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
        (`dtdyn.modal.spectrum.default_periods`), dt of the batch's first case: the periods
        its records resolve (10 samples per period at least). A case whose record is coarser
        than those periods allow warns (`SRSSamplingWarning`, counted in the batch's summary).
    damping_ratio : float
        Damping ratio (default 0.05; ``damping`` before this release: deprecated).

    Examples
    --------
    >>> from dtdyn.app.batch import Spectrum
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
        from dtdyn.modal.spectrum import default_periods
        periods = default_periods(dt, count=40, shortest=0.05, longest=4.0)
        return replace(self, periods=tuple(float(T) for T in periods))

    def coords(self) -> dict:
        if self.periods is None:
            return {}        # known once a case gives dt (the batch resolves it first)
        return {"period": np.asarray(self.periods, dtype=float)}

    def __call__(self, response, scene) -> dict:
        from dtdyn.modal.spectrum import response_spectrum

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


def resolve(reducers, dt) -> list:
    """The reducers with a default-period `Spectrum` resolved for records of step ``dt``."""
    return [r.resolved(dt) if isinstance(r, Spectrum) else r for r in reducers]


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
            elif item in REDUCERS:
                out.append(REDUCERS[item])
            else:
                raise ValueError(f"reduce = {item!r}: unknown reducer, allowed: "
                                 f"{', '.join(map(repr, [*REDUCERS, 'srs']))} or a callable")
        elif isinstance(item, Spectrum) or item in REDUCERS.values():
            out.append(item)
        elif callable(item):
            out.append(_User(item))
        else:
            raise ValueError(f"reduce entry {item!r}: must be a reducer name, a Spectrum or a "
                             "callable f(response, scene) -> dict")
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

    if isinstance(r, Spectrum):
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
