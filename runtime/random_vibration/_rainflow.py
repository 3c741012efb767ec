"""Rainflow cycle counting (ASTM E1049-85, section 5.4.4) and its histograms.

`rainflow_cycles` finds the reversals of a load record and counts them with the three-point
stack; the loop is hand-written C (dtdyn/_engine/csrc/rainflow.h, compiled on first use), with a
NumPy and Python implementation of the same steps when no C compiler is there (one
`DtdynFallbackWarning` per process). The cycles are those of the `rainflow` package's
``extract_cycles`` (range, mean, count 0.5 or 1.0, start and end index), in the same order, on
every record of three samples or more; a record of two samples is one half cycle here (ASTM: the
first and last samples are reversals), where that package finds none.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import NamedTuple

import numpy as np

from dtdyn._engine import cbuild
from dtdyn._engine.public import public
from dtdyn._engine.validate import real_array

__all__ = ["CycleHistogram", "Cycles", "rainflow_cycles", "turning_points"]

_BACKENDS = ("c", "numpy")


class CycleHistogram(NamedTuple):
    """Cycle counts binned by range (and by mean for a range-mean matrix).

    Attributes
    ----------
    counts : ndarray
        Cycles in each bin (half cycles count 0.5): shape ``(n_range,)`` or
        ``(n_range, n_mean)``.
    range_edges : (n_range + 1,) ndarray
        Bin edges of the ranges (the signal's unit); bins are ``[e_i, e_i+1)``, the last one
        closed.
    mean_edges : (n_mean + 1,) ndarray or None
        Bin edges of the means; None for a range histogram.

    Examples
    --------
    >>> import dtdyn as dd
    >>> h = dd.rainflow_cycles([0.0, 2.0, -1.0, 3.0, 0.0]).histogram(range_bins=[0, 2, 4, 6])
    >>> h.counts.tolist(), h.range_edges.tolist()
    ([0.0, 1.5, 0.5], [0.0, 2.0, 4.0, 6.0])
    """

    counts: np.ndarray
    range_edges: np.ndarray
    mean_edges: np.ndarray | None


@dataclass(frozen=True)
class Cycles:
    """The rainflow cycles of a record, one entry per cycle in the order they are counted.

    Attributes
    ----------
    ranges : (n_cycles,) ndarray
        Ranges ``|x[end] - x[start]|`` (the signal's unit); the amplitude is half of it.
    means : (n_cycles,) ndarray
        Means ``(x[start] + x[end]) / 2``.
    counts : (n_cycles,) ndarray
        1.0 for a full cycle, 0.5 for a half cycle.
    start, end : (n_cycles,) ndarray of int
        Sample indices of the cycle's two reversals, the older first.
    residue : ndarray of int
        Sample indices of the reversals left on the stack at the end (the residue); each pair of
        neighbours is one of the last half cycles.
    info : dict
        ``backend`` (``"c"`` or ``"numpy"``), ``n_samples``, ``n_turning_points``.

    Examples
    --------
    >>> import dtdyn as dd
    >>> c = dd.rainflow_cycles([-2, 1, -3, 5, -1, 3, -4, 4, -2])   # ASTM E1049 fig. 6
    >>> c.ranges.tolist(), c.counts.tolist()
    ([3.0, 4.0, 4.0, 8.0, 9.0, 8.0, 6.0], [0.5, 0.5, 1.0, 0.5, 0.5, 0.5, 0.5])
    """

    ranges: np.ndarray
    means: np.ndarray
    counts: np.ndarray
    start: np.ndarray
    end: np.ndarray
    residue: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def amplitudes(self) -> np.ndarray:
        """Half the ranges."""
        return 0.5 * self.ranges

    def histogram(self, range_bins=10) -> CycleHistogram:
        """Cycle counts binned by range.

        Parameters
        ----------
        range_bins : int or sequence of float
            The number of equal bins from 0 to the largest range, or the bin edges (increasing;
            every cycle must fall inside them).

        Returns
        -------
        CycleHistogram
            ``counts`` of shape ``(n_range,)``, ``range_edges``, ``mean_edges`` None.
        """
        edges = _edges("range_bins", range_bins, self.ranges, 0.0)
        counts, _ = np.histogram(self.ranges, bins=edges, weights=self.counts)
        return CycleHistogram(counts, edges, None)

    def matrix(self, range_bins=10, mean_bins=10) -> CycleHistogram:
        """Cycle counts binned by range and mean (the rainflow matrix).

        Parameters
        ----------
        range_bins : int or sequence of float
            The number of equal bins from 0 to the largest range, or the bin edges.
        mean_bins : int or sequence of float
            The number of equal bins from the lowest to the highest mean, or the bin edges.

        Returns
        -------
        CycleHistogram
            ``counts`` of shape ``(n_range, n_mean)`` (row: range bin, column: mean bin),
            ``range_edges``, ``mean_edges``.
        """
        r_edges = _edges("range_bins", range_bins, self.ranges, 0.0)
        m_edges = _edges("mean_bins", mean_bins, self.means, None)
        counts, _, _ = np.histogram2d(self.ranges, self.means, bins=(r_edges, m_edges),
                                      weights=self.counts)
        return CycleHistogram(counts, r_edges, m_edges)

    def damage(self, sn_curve, *, mean_correction=None, ultimate_strength=None) -> float:
        """Palmgren-Miner damage of these cycles: `dtdyn.miner_damage` of their ranges, counts
        and means (the parameters are that function's)."""
        from dtdyn.random_vibration._fatigue import miner_damage

        return miner_damage(self.ranges, self.counts, sn_curve, means=self.means,
                            mean_correction=mean_correction,
                            ultimate_strength=ultimate_strength)


def _edges(name, bins, values, low):
    """Bin edges from a count (equal bins over [low or min(values), max(values)]) or checked
    edges that hold every value."""
    if np.ndim(bins) == 0:
        if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
            raise ValueError(f"{name} must be a number of bins >= 1 or a sequence of bin "
                             f"edges; got {name}={bins!r}")
        lo = low if low is not None else (float(values.min()) if values.size else 0.0)
        hi = float(values.max()) if values.size else lo
        if hi <= lo:
            hi = lo + 1.0  # all values equal (or none): one unit wide bins
        return np.linspace(lo, hi, int(bins) + 1)
    edges = real_array(name, bins, "a sequence of bin edges")
    if edges.ndim != 1 or edges.size < 2 or not np.all(np.isfinite(edges)) \
            or np.any(np.diff(edges) <= 0):
        raise ValueError(f"{name} must be at least two finite, increasing bin edges; "
                         f"got {name}={bins!r}")
    outside = (values < edges[0]) | (values > edges[-1])
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(f"{name} = [{edges[0]:g} .. {edges[-1]:g}] leaves out "
                         f"{int(outside.sum())} cycle(s), e.g. cycle {i} at {values[i]:g}: "
                         f"widen the edges so that no cycle (and no damage) is dropped")
    return edges


@cache
def _c_kernels():
    source = resources.files("dtdyn.generated").joinpath("rainflow.c").read_text()
    lib = cbuild.load_library(source, "rainflow")
    if lib is None:
        return None
    return cbuild.bind(lib, "dtdyn_turning_points"), cbuild.bind(lib, "dtdyn_rainflow")


def _signal(signal) -> np.ndarray:
    x = real_array("signal", signal, "a load record (a 1-D array of samples)")
    if x.ndim != 1:
        raise ValueError(f"signal must be a 1-D record of samples; got shape {x.shape}")
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"signal[{i}] = {float(x[i])!r} is not finite ({int(bad.sum())} "
                         "non-finite sample(s)): rainflow counting needs finite samples; remove "
                         "or interpolate them first")
    return np.ascontiguousarray(x)


def _backend(backend):
    if backend not in _BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(map(repr, _BACKENDS))}; "
                         f"got backend={backend!r}")
    return _c_kernels() if backend == "c" else None


def _turning_points_numpy(x: np.ndarray) -> np.ndarray:
    """The reversals of rainflow.h's dtdyn_turning_points, vectorized: each run of equal samples
    stands at its last sample; an interior run is a reversal where the slope changes sign; the
    run holding sample 0 is sample 0, and the last sample is a reversal."""
    n = x.size
    if n <= 1:
        return np.arange(n, dtype=np.int64)
    ends = np.flatnonzero(np.r_[x[1:] != x[:-1], True])  # last sample of each run
    down = np.diff(x[ends]) < 0                           # slope leaving each run but the last
    turn = np.flatnonzero(down[1:] != down[:-1]) + 1      # interior runs where the sign flips
    return np.concatenate(([0], ends[turn], [n - 1])).astype(np.int64)


def _stack_count_numpy(x: np.ndarray, tp: np.ndarray):
    """The three-point stack count of rainflow.h's dtdyn_rainflow, as a Python loop."""
    vals = x[tp].tolist()
    idx = tp.tolist()
    sv, si = [], []  # the stack: values and sample indices
    lo = 0
    start, end, count = [], [], []
    for v, i in zip(vals, idx):
        sv.append(v)
        si.append(i)
        while len(sv) - lo >= 3:
            x1, x2, x3 = sv[-3], sv[-2], sv[-1]
            if abs(x3 - x2) < abs(x2 - x1):
                break
            if len(sv) - lo == 3:
                start.append(si[lo])
                end.append(si[lo + 1])
                count.append(0.5)
                lo += 1
            else:
                start.append(si[-3])
                end.append(si[-2])
                count.append(1.0)
                sv[-3:] = [x3]
                si[-3:] = [si[-1]]
    res = si[lo:]
    start += res[:-1]
    end += res[1:]
    count += [0.5] * max(len(res) - 1, 0)
    return (np.array(start, dtype=np.int64), np.array(end, dtype=np.int64),
            np.array(count, dtype=float), np.array(res, dtype=np.int64))


@public
def turning_points(signal, *, backend="c") -> np.ndarray:
    """The reversals (peaks and valleys) of a load record, as sample indices.

    Parameters
    ----------
    signal : array_like, shape (n,)
        The load record (finite samples).
    backend : {"c", "numpy"}
        The compiled loop (default; NumPy when no C compiler is there) or NumPy.

    Returns
    -------
    (n_tp,) ndarray of int
        Indices of the reversals, increasing: the first and the last sample, and every
        interior sample where the slope changes sign; a plateau (equal samples) counts once,
        at its last sample (ASTM E1049-85 section 5.4.4, as the `rainflow` package reads it).

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.turning_points([0.0, 1.0, 1.0, 2.0, 0.0, 0.5, 0.5, -1.0]).tolist()
    [0, 3, 4, 6, 7]
    """
    x = _signal(signal)
    fns = _backend(backend)
    if fns is None:
        return _turning_points_numpy(x)
    tp = np.empty(x.size, dtype=np.int64)
    m = fns[0](x.size, x.ctypes.data, tp.ctypes.data)
    return tp[:m].copy()


@public
def rainflow_cycles(signal, *, backend="c") -> Cycles:
    """Rainflow cycles of a load record (ASTM E1049-85 (2011), section 5.4.4).

    Parameters
    ----------
    signal : array_like, shape (n,)
        The load record: stress, strain or force samples (finite; NaN or inf is a ValueError
        naming the first such sample).
    backend : {"c", "numpy"}
        The compiled loop (default; the NumPy implementation, with one `DtdynFallbackWarning`,
        when no C compiler is there) or NumPy and Python.

    Returns
    -------
    Cycles
        ``ranges``, ``means``, ``counts`` (1.0 or 0.5), ``start`` and ``end`` indices of each
        cycle in the order counted, and the ``residue``.

    Notes
    -----
    First the reversals are found (`turning_points`). Then they are pushed one by one on a
    stack; with the three newest points forming the ranges Y (older) and X (newer):

    - X < Y: read the next reversal;
    - X >= Y and Y holds the oldest point on the stack: Y is a half cycle, its oldest point is
      dropped;
    - X >= Y otherwise: Y is a full cycle, its two points are dropped.

    At the end each range between neighbours left on the stack (the residue) is a half cycle.
    Both steps are O(n). The range of a cycle is ``|x[end] - x[start]|``, its mean
    ``(x[start] + x[end]) / 2``.

    These are the cycles of the `rainflow` package's ``extract_cycles`` (same values, same
    order) for every record of three samples or more. Two samples are one half cycle here (the
    first and last samples are reversals); that package returns none for them.

    References
    ----------
    ASTM E1049-85 (reapproved 2011), Standard Practices for Cycle Counting in Fatigue Analysis,
    section 5.4.4 (rainflow counting) and X1.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> c = dd.rainflow_cycles(np.sin(np.linspace(0, 20 * np.pi, 2001)))
    >>> float(c.counts.sum()), float(c.ranges.max().round(6))
    (10.5, 2.0)
    """
    x = _signal(signal)
    fns = _backend(backend)
    if fns is None:
        tp = _turning_points_numpy(x)
        start, end, count, residue = _stack_count_numpy(x, tp)
        used = "numpy"
    else:
        tp = np.empty(x.size, dtype=np.int64)
        n_tp = fns[0](x.size, x.ctypes.data, tp.ctypes.data)
        cap = max(n_tp, 1)
        start = np.empty(cap, dtype=np.int64)
        end = np.empty(cap, dtype=np.int64)
        count = np.empty(cap, dtype=float)
        n_res = np.zeros(1, dtype=np.int64)
        n_c = fns[1](n_tp, x.ctypes.data, tp.ctypes.data, start.ctypes.data, end.ctypes.data,
                     count.ctypes.data, n_res.ctypes.data)
        start, end, count = start[:n_c], end[:n_c], count[:n_c]
        residue = tp[:int(n_res[0])].copy()
        used = "c"
    xs, xe = x[start], x[end]
    return Cycles(ranges=np.abs(xs - xe), means=0.5 * (xs + xe), counts=count, start=start,
                  end=end, residue=residue,
                  info={"backend": used, "n_samples": int(x.size),
                        "n_turning_points": int(tp.size if fns is None else n_tp)})
