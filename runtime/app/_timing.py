"""Timing for the benchmarks and `dtdyn bench`: BLAS pinned, repeats after a warm-up, the spread.

Every time the benchmarks print is measured the same way:

- `pin_blas` limits the BLAS libraries loaded in the process (OpenBLAS, MKL, BLIS, through
  threadpoolctl) to a stated number of threads, one by default, for the measured calls: a
  BLAS call of a small matrix on several threads of a shared machine can take 50 times its
  one-thread time or not, so that the ranking of two methods would depend on the moment;
- `measure` calls a function once (the warm-up: compilation, caches) and then ``repeats``
  times, and keeps every repeat's time;
- `Timing` gives the median of the repeats and their spread (min-max and the quartiles), and
  says whether two timings' ranges overlap (then their order is within the run-to-run noise).

threadpoolctl is imported when `pin_blas` is entered, not with this module.
"""
from __future__ import annotations

import contextlib
import statistics
import time
from dataclasses import dataclass, field

__all__ = ["BlasPin", "Timing", "interleaved", "measure", "pin_blas"]


class Timing(float):
    """The times of the repeats of one measured call, in seconds; as a number, their median.

    A float (the median), so that a script's arithmetic on a time (per step, ratios) goes on
    unchanged, with the spread of the repeats kept beside it (`min`, `max`, `quartiles`,
    `format`).

    Parameters
    ----------
    times : sequence of float
        Each timed repeat (after the warm-up), s; at least one.
    first : float, optional
        The warm-up call's time, s (None: no warm-up was timed).

    Examples
    --------
    >>> t = Timing((1.0e-3, 1.2e-3, 1.1e-3), first=5e-3)
    >>> t.median, t.min, t.max, t * 1e3
    (0.0011, 0.001, 0.0012, 1.1)
    >>> t.format()
    '1.1 ms [1, 1.2]'
    >>> t.overlaps(Timing((1.15e-3,)))
    True
    """

    __slots__ = ("times", "first")

    def __new__(cls, times, first=None):
        times = tuple(float(t) for t in times)
        if len(times) == 0:
            raise ValueError("Timing needs at least one time; got times=()")
        self = super().__new__(cls, statistics.median(times))
        self.times = times
        self.first = None if first is None else float(first)
        return self

    def __repr__(self):
        return f"Timing({self.times!r}, first={self.first!r})"

    def __reduce__(self):
        return Timing, (self.times, self.first)

    @property
    def median(self) -> float:
        """Median of the repeats, s."""
        return float(self)

    @property
    def min(self) -> float:
        """Fastest repeat, s."""
        return min(self.times)

    @property
    def max(self) -> float:
        """Slowest repeat, s."""
        return max(self.times)

    @property
    def quartiles(self) -> tuple[float, float]:
        """(q1, q3): the 25 % and 75 % quantiles of the repeats (linear interpolation between
        the sorted repeats), s; both the single time when there is one repeat."""
        if len(self.times) == 1:
            return self.times[0], self.times[0]
        q1, _, q3 = statistics.quantiles(self.times, n=4, method="inclusive")
        return q1, q3

    @property
    def repeats(self) -> int:
        """Number of timed repeats."""
        return len(self.times)

    @property
    def build(self) -> float:
        """Construction and compile time: the warm-up call minus the median, s (0 when the
        warm-up was not timed or was faster)."""
        return 0.0 if self.first is None else max(self.first - self.median, 0.0)

    def scaled(self, factor: float) -> Timing:
        """The same timing with every time multiplied by ``factor`` (per step, per sample, an
        extrapolation from a window to the whole record)."""
        return Timing(tuple(t * factor for t in self.times),
                      None if self.first is None else self.first * factor)

    def overlaps(self, other: Timing) -> bool:
        """Whether the ranges [min, max] of the two timings' repeats intersect: then their
        order is not established by these repeats."""
        return self.min <= other.max and other.min <= self.max

    def format(self, unit: str = "ms", digits: int = 3) -> str:
        """``median [min, max]`` in ``unit`` (s, ms, us, ns), ``digits`` significant digits;
        one repeat: the time and ``(1 run)``."""
        scale = {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}
        if unit not in scale:
            raise ValueError(f"unit must be one of {', '.join(scale)}; got unit={unit!r}")
        k = scale[unit]
        if len(self.times) == 1:
            return f"{self.times[0] * k:.{digits}g} {unit} (1 run)"
        return (f"{self.median * k:.{digits}g} {unit} "
                f"[{self.min * k:.{digits}g}, {self.max * k:.{digits}g}]")

    def __str__(self):
        return self.format()

    def as_dict(self) -> dict:
        """JSON-ready: median, min, max, q1, q3, repeats and every repeat's time, s."""
        q1, q3 = self.quartiles
        return {"median": self.median, "min": self.min, "max": self.max, "q1": q1, "q3": q3,
                "repeats": self.repeats, "times": list(self.times)}


#: how `Timing.format` writes a spread, for the headers and notes of reports
SPREAD = "median of the repeats [min, max]"


def measure(fn, repeats: int = 5, *, warmup: bool = True, key=None, before=None,
            min_time: float = 0.0, max_repeats: int | None = None):
    """Call ``fn`` once (the warm-up, not in the median), then at least ``repeats`` times, timed.

    Parameters
    ----------
    fn : callable
        Called with no arguments.
    repeats : int
        Timed calls after the warm-up, >= 1.
    warmup : bool
        False: no warm-up call (``fn`` is called ``repeats`` times).
    key : callable, optional
        ``key(result)``: the time a call reports itself (e.g. its C loop's, ``info["run_time"]``),
        kept instead of the wall time of the call.
    before : callable, optional
        Run before each timed call, not timed (e.g. a baseline run to alternate with).
    min_time : float
        Keep repeating until the timed calls add up to ``min_time`` seconds (fast calls get
        more repeats, so that their spread samples the machine's noise), up to
        ``max_repeats`` calls.
    max_repeats : int, optional
        Upper bound of the timed calls when ``min_time`` asks for more (default
        ``max(repeats, 100)``).

    Returns
    -------
    result
        The last call's result.
    Timing
        The repeats' times (``key`` of each result if given, else wall time by
        ``time.perf_counter``); ``first`` is the warm-up's wall time.

    Examples
    --------
    >>> out, t = measure(lambda: sum(range(1000)), repeats=3)
    >>> out, t.repeats, t.min <= t.median <= t.max
    (499500, 3, True)
    """
    if int(repeats) < 1:
        raise ValueError(f"repeats must be >= 1; got repeats={repeats!r}")
    cap = max(int(repeats), 100 if max_repeats is None else int(max_repeats))
    first = None
    if warmup:
        t0 = time.perf_counter()
        out = fn()
        first = time.perf_counter() - t0
    times, spent = [], 0.0
    while len(times) < int(repeats) or (spent < min_time and len(times) < cap):
        if before is not None:
            before()
        t0 = time.perf_counter()
        out = fn()
        wall = time.perf_counter() - t0
        spent += wall
        times.append(wall if key is None else key(out))
    return out, Timing(tuple(times), first)


def interleaved(fns: dict, repeats: int, *, key=None) -> dict:
    """`Timing` of each of ``fns`` (name -> callable), called in turn within each of ``repeats``
    rounds after one warm-up round: a drift of the machine's speed reaches every function
    alike. ``key(result)``: the time a call reports itself (as in `measure`), else wall time.

    Examples
    --------
    >>> t = interleaved({"a": lambda: sum(range(100)), "b": lambda: sum(range(10))}, 3)
    >>> sorted(t), t["a"].repeats
    (['a', 'b'], 3)
    """
    first, times = {}, {name: [] for name in fns}
    for r in range(repeats + 1):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            out = fn()
            wall = time.perf_counter() - t0
            if r:
                times[name].append(wall if key is None else key(out))
            else:
                first[name] = wall
    return {name: Timing(times[name], first[name]) for name in fns}


@dataclass
class BlasPin:
    """What `pin_blas` did: the thread limit and each BLAS library found, with the number of
    threads it had before.

    Attributes
    ----------
    threads : int
        The limit set for every BLAS library of the process.
    libraries : list of dict
        threadpoolctl's description of each (``internal_api``, ``version``,
        ``threading_layer``, ``num_threads`` before the limit).
    """

    threads: int
    libraries: list = field(default_factory=list)

    def describe(self) -> str:
        """One sentence for a report, e.g. "BLAS pinned to 1 thread for the timed calls
        (threadpoolctl threadpool_limits(limits=1, user_api='blas'); openblas 0.3.30 pthreads,
        2 threads before)"."""
        libs = "; ".join(" ".join(str(lib[k]) for k in ("internal_api", "version",
                                                        "threading_layer") if lib.get(k))
                         + f", {lib.get('num_threads')} threads before"
                         for lib in self._distinct())
        call = f"threadpoolctl threadpool_limits(limits={self.threads}, user_api='blas')"
        return (f"BLAS pinned to {self.threads} thread{'s' if self.threads != 1 else ''} "
                f"for the timed calls ({call}; " + (libs or "no BLAS library loaded") + ")")

    def _distinct(self):
        seen, out = set(), []
        for lib in self.libraries:
            k = (lib.get("internal_api"), lib.get("version"), lib.get("threading_layer"),
                 lib.get("num_threads"))
            if k not in seen:
                seen.add(k)
                out.append(lib)
        return sorted(out, key=lambda lib: tuple(str(lib.get(k)) for k in
                                                 ("internal_api", "version")))

    def as_dict(self) -> dict:
        """JSON-ready: ``threads``, ``libraries`` and ``text`` (`describe`)."""
        keys = ("internal_api", "version", "threading_layer", "num_threads", "filepath")
        return {"threads": self.threads,
                "libraries": [{k: lib.get(k) for k in keys} for lib in self.libraries],
                "text": self.describe()}


@contextlib.contextmanager
def pin_blas(threads: int = 1):
    """Limit every BLAS library loaded in this process to ``threads`` threads in the block.

    threadpoolctl's ``threadpool_limits(limits=threads, user_api="blas")``; the previous limits
    are restored on exit. NumPy and SciPy are imported first, so that their BLAS is found.

    Parameters
    ----------
    threads : int
        Threads per BLAS library, >= 1.

    Yields
    ------
    BlasPin
        The limit and the libraries found (their thread counts before it).

    Examples
    --------
    >>> import numpy as np
    >>> with pin_blas(1) as pin:
    ...     _ = np.ones((50, 50)) @ np.ones((50, 50))
    >>> pin.threads
    1
    """
    if isinstance(threads, bool) or int(threads) != threads or threads < 1:
        raise ValueError(f"threads must be an integer >= 1; got threads={threads!r}")
    try:
        from threadpoolctl import threadpool_info, threadpool_limits
    except ImportError as exc:  # a dependency of dtdyn: an incomplete environment
        raise ModuleNotFoundError("timing with BLAS pinned needs threadpoolctl: "
                                  "pip install 'threadpoolctl>=3'") from exc
    import numpy  # noqa: F401  (load the BLAS libraries before looking them up)
    import scipy.linalg  # noqa: F401
    libraries = [lib for lib in threadpool_info() if lib.get("user_api") == "blas"]
    with threadpool_limits(limits=int(threads), user_api="blas"):
        yield BlasPin(int(threads), libraries)
