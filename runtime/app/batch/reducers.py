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
========== ==================================================================================

A user reducer is any callable ``f(response, scene)`` returning a dict: name -> a value
(a number or an array; its dimensions are named ``<name>_0``, ``<name>_1``, ...) or a tuple
``(dims, values)``. It runs on the workers (it is pickled with cloudpickle, so a lambda or a
local function works). Its shapes must be the same for every case.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

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


@dataclass(frozen=True)
class Spectrum:
    """The ``srs`` reducer with its periods and damping: ``psa`` (period, output), the
    pseudo-acceleration spectrum (`dtdyn.response_spectrum`) of each output's absolute
    acceleration.

    Attributes
    ----------
    periods : tuple of float
        Natural periods, s (default 40 log-spaced from 0.05 to 4 s).
    damping : float
        Damping ratio (default 0.05).

    Examples
    --------
    >>> from dtdyn.app.batch import Spectrum
    >>> Spectrum(periods=(0.1, 1.0)).damping
    0.05
    """

    periods: tuple = field(default_factory=lambda: tuple(np.geomspace(0.05, 4.0, 40)))
    damping: float = 0.05
    name = "srs"

    def coords(self) -> dict:
        return {"period": np.asarray(self.periods, dtype=float)}

    def __call__(self, response, scene) -> dict:
        from dtdyn.modal.spectrum import response_spectrum

        acc = response.a_abs if response.a_abs is not None else response.a
        if acc is None:
            raise ValueError("reduce 'srs' needs the accelerations: add \"a\" to "
                             "output.quantities")
        acc = np.asarray(acc)
        psa = np.column_stack([response_spectrum(acc[:, j], scene.dt, self.periods,
                                                 damping=self.damping).psa[0]
                               for j in range(acc.shape[1])])
        return {"psa": (("period", "output"), psa)}


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
