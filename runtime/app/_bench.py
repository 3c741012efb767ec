"""Work-precision reports (`dtdyn bench`): every applicable method on a reference problem, error
against a tight reference and run time, as a Markdown table, JSON and a log-log plot.

The problems themselves (what runs, against which reference, the tables of schemes and targets)
live with the other benchmarks, in benchmarks/bench_problems.py of the source checkout
(`bench_problems` loads it); this module times, ranks and reports them.

Error: the displacement of the problem's output DOF (P3: mass 15; P4: DOF 3), max over time of
|x - x_ref| relative to max |x_ref|, and the RMS over time of the difference on the same scale.
Time: median of repeats after a warm-up, with their spread [min, max]; BLAS pinned to one
thread (threadpoolctl, `dtdyn.app._timing`) for the whole bench, so that a small matrix's BLAS
call does not take 0.6 ms or 35 ms by the moment; construction and compile (the first call
minus the median) reported apart. `rank_changes` compares the rankings of two or three such
reports.
"""
from __future__ import annotations

import functools
import importlib.util
import itertools
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from dtdyn._engine.atomic import write_atomic
from dtdyn.app._timing import SPREAD, Timing, measure, pin_blas


@dataclass
class Run:
    method: str
    family: str
    setting: str
    max_error: float
    rms_error: float
    run_time: float
    build_time: float
    note: str = ""
    #: the linear baseline's median timed in alternation with this run's repeats (P4)
    linear_time: float | None = None
    #: the spread of the repeats whose median is run_time: fastest and slowest, and their count
    run_time_min: float | None = None
    run_time_max: float | None = None
    repeats: int = 1

    def price(self, t_lin):
        """run time / linear baseline: the paired one where measured, else ``t_lin``."""
        return self.run_time / (self.linear_time or t_lin)

    def spread(self, scale=1e3):
        """``median [min, max]`` of the run time, times ``scale`` (ms by default)."""
        lo, hi = self.run_time_min, self.run_time_max
        if lo is None or self.repeats <= 1:
            return f"{self.run_time * scale:.3g} (1 run)"
        return f"{self.run_time * scale:.3g} [{lo * scale:.3g}, {hi * scale:.3g}]"


def _errors(x, ref):
    d = np.asarray(x) - np.asarray(ref)
    scale = np.abs(ref).max()
    return float(np.abs(d).max() / scale), float(np.sqrt(np.mean(d**2)) / scale)


#: fast calls are repeated until their timed calls add up to this many seconds (at most
#: MAX_REPEATS calls), so that their spread samples the machine's noise
MIN_TIME, MAX_REPEATS = 0.02, 25


def _timed(fn, repeats, key=None, before=None):
    """(result, run time, build time) by `dtdyn.app.measure`: the first call, then
    ``repeats`` timed calls, more for fast calls (MIN_TIME, MAX_REPEATS); the run time is a
    `Timing` (its median and spread). ``repeats`` = 0: the first call's time alone, no build
    time. ``key(result)``: the run time a call reports itself (e.g. its C loop's, from
    ``info``), kept instead of the wall time; the build time is still the first call's wall
    time minus the median wall time. ``before()``: run before each timed call, untimed (P4:
    one linear run, so that the ratio of the two medians sees the same stretch of a shared
    machine)."""
    own = []

    def call():
        out = fn()
        if key is not None:
            own.append(key(out))
        return out
    if repeats == 0:  # a single (cold) run: no build time to separate
        out, wall = measure(call, 1, warmup=False)
        return out, (wall if key is None else Timing(tuple(own))), 0.0
    out, wall = measure(call, repeats, before=before,
                        min_time=0.0 if before is not None else MIN_TIME,
                        max_repeats=MAX_REPEATS)
    return out, (wall if key is None else Timing(tuple(own[1:]))), wall.build


def _recorder(runs, log):
    """add(method, family, setting, x, x_ref, run time, build time, note[, linear time]):
    append and log a Run."""
    def add(method, family, setting, x, ref, t_run, t_build, note="", t_lin=None):
        e_max, e_rms = _errors(x, ref)
        t = t_run if isinstance(t_run, Timing) else Timing((t_run,))
        runs.append(Run(method, family, setting, e_max, e_rms, t.median, t_build, note, t_lin,
                        t.min, t.max, t.repeats))
        log(f"  {method:32s} {setting:>12s}  max {e_max:9.2e}  rms {e_rms:9.2e}  "
            f"{runs[-1].spread():>24s} ms  {note}")
    return add


def _blas_pinned(bench):
    """Run ``bench`` with BLAS pinned (`dtdyn.app.pin_blas`, one thread by default);
    the pin and the libraries it found go to the meta data (``meta["blas"]``)."""
    @functools.wraps(bench)
    def pinned(quick=False, log=print, blas_threads=1):
        with pin_blas(blas_threads) as pin:
            runs, meta = bench(quick=quick, log=log)
        meta["blas"] = pin.as_dict()
        return runs, meta
    return pinned


# --- the problems: benchmarks/bench_problems.py of the source checkout ----------------------------

#: the names `bench_problems` defines that this module hands on (``bench.bench_p3`` and so on)
PROBLEM_NAMES = ("BENCHES", "bench_p3", "bench_p4", "P3_SCHEMES", "P4_METHODS", "P4_ACCURACY",
                 "_modal_flops", "_fma_peak_kernel", "_fma_peak", "_steady_allocator")
_PROBLEMS = "dtdyn_bench_problems"  # its name in sys.modules


def bench_problems():
    """The module benchmarks/bench_problems.py (the problems `dtdyn bench` runs and their
    tables), loaded once from the dtdyn source checkout that holds this package (an editable
    install) or the working directory; ValueError outside a checkout."""
    if _PROBLEMS in sys.modules:
        return sys.modules[_PROBLEMS]
    from dtdyn.app._cli import _checkout
    for start in (Path(__file__).resolve().parent, Path.cwd()):
        checkout = _checkout(start)
        path = checkout / "benchmarks" / "bench_problems.py" if checkout else None
        if path is not None and path.is_file():
            break
    else:
        raise ValueError("`dtdyn bench` runs the benchmark problems of a dtdyn source checkout "
                         "(benchmarks/bench_problems.py): run it from inside one, or install "
                         "dtdyn from a checkout with `pip install -e .`")
    spec = importlib.util.spec_from_file_location(_PROBLEMS, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[_PROBLEMS] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[_PROBLEMS]
        raise
    return module


def __getattr__(name):
    """``bench.bench_p3``, ``bench.BENCHES``, ...: the names of `bench_problems`."""
    if name in PROBLEM_NAMES:
        return getattr(bench_problems(), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# --- report -------------------------------------------------------------------------------------

def ranking(runs, target):
    """The fastest run of each method with max error <= target, fastest first."""
    best = {}
    for r in runs:
        if r.max_error <= target and (r.method not in best
                                      or r.run_time < best[r.method].run_time):
            best[r.method] = r
    return sorted(best.values(), key=lambda r: r.run_time)


def _blas_text(meta):
    """The BLAS pin of a report's meta data, as a sentence (without its full stop)."""
    blas = meta.get("blas")
    return blas["text"] if blas else "BLAS threads not pinned"


def _linear_spread(meta):
    """P4's linear baseline time, median [min, max] in ms."""
    t, lo, hi = (meta.get(k) for k in ("linear_time", "linear_min", "linear_max"))
    if lo is None:
        return f"{t * 1e3:.3g} ms"
    return f"{t * 1e3:.3g} ms [{lo * 1e3:.3g}, {hi * 1e3:.3g}]"


def write_report(runs, meta, out_dir, command):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    name = meta["problem"]
    lines = [f"# Work-precision: {name}", "", f"Output of `{command}`. {meta['description']}.",
             f"Times: {SPREAD} after a warm-up: at least 3 repeats, calls faster than "
             f"{MIN_TIME * 1e3:g} ms in all repeated until they add up to it (at most "
             f"{MAX_REPEATS}) (P4's dtdyn runs: the time each reports for its C loops, 5 "
             "repeats; freed memory kept by the allocator, so that no run pays for faulting in "
             "fresh pages; P4's solve_ivp: one run on a window); build = construction and "
             "compile (first call minus the median). Two runs whose [min, max] ranges overlap "
             "are not ordered by this report: their ranks can swap from one report to the "
             "next.", "", _blas_text(meta) + ".", ""]
    t_lin = meta.get("linear_time")
    if t_lin:
        lines += [f"Linear baseline, the price of the nonlinearity: the {meta['linear']} runs in "
                  f"{_linear_spread(meta)} (max error {meta['linear_error']:.1e} against the "
                  "matrix exponential; the median of its runs); the column `time / linear` is "
                  "each run's time over the linear runs timed in alternation with its own "
                  "(median of 5 each) where there are such, else over that median: measured in "
                  "the same run.", ""]

    def ratio(r):  # the extra column, when there is a linear baseline
        return f" {r.price(t_lin):.3g} |" if t_lin else ""
    head, rule = (" time / linear |", "---|") if t_lin else ("", "")
    for target in meta["targets"]:
        ranked = ranking(runs, target)
        lines += [f"## Ranking at max error <= {target:g}", "",
                  "| rank | method | setting | max error | run time [ms], median [min, max] | "
                  "time / fastest |" + head, "|---|---|---|---|---|---|" + rule]
        for k, r in enumerate(ranked, 1):
            lines.append(f"| {k} | {r.method} | {r.setting} | {r.max_error:.2e} | "
                         f"{r.spread()} | {r.run_time / ranked[0].run_time:.3g} |"
                         + ratio(r))
        lines.append("")
    lines += ["## All runs", "", "| method | family | setting | max error | RMS error | run time "
              "[ms], median [min, max] |" + head + " build [ms] | repeats | note |",
              "|---|---|---|---|---|---|" + rule + "---|---|---|"]
    for r in runs:
        lines.append(f"| {r.method} | {r.family} | {r.setting} | {r.max_error:.2e} | "
                     f"{r.rms_error:.2e} | {r.spread()} |" + ratio(r)
                     + f" {r.build_time * 1e3:.3g} | {r.repeats} | {r.note} |")
    lines += ["", f"![error against run time](bench_{name}.png)", ""]
    md = out_dir / f"bench_{name}.md"
    write_atomic(md, lambda fh: fh.write("\n".join(lines).encode()))
    data = {"meta": meta, "command": command, "runs": [asdict(r) for r in runs]}
    write_atomic(out_dir / f"bench_{name}.json",
                 lambda fh: fh.write(json.dumps(data, indent=1).encode()))
    _plot(runs, meta, out_dir / f"bench_{name}.png")
    return md


def _plot(runs, meta, path):
    """Error against run time, one line per method: a marker shape per family (DT-TMM, state
    space, modal filters, nonlinear, peer) and a colour per method within it."""
    from dtdyn._engine.extras import require
    require("matplotlib", "plot", "dtdyn bench")
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.5, 5.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    families = list(dict.fromkeys(r.family for r in runs))
    markers = "osD^v<>ph*X"
    colors = colormaps["tab10"].colors
    for f, family in enumerate(families):
        methods = list(dict.fromkeys(r.method for r in runs if r.family == family))
        for k, m in enumerate(methods):
            pts = sorted((r.run_time, max(r.max_error, 1e-17)) for r in runs if r.method == m)
            ax.loglog([p[0] * 1e3 for p in pts], [p[1] for p in pts],
                      marker=markers[f % len(markers)], ls=("-", "--", ":")[k // 10 % 3],
                      ms=4.5, lw=1, label=m, color=colors[k % len(colors)])
    for target in meta["targets"]:
        ax.axhline(target, color="gray", lw=0.7, ls="--")
    ax.set_xlabel("run time [ms]")
    ax.set_ylabel("max relative error over time")
    ax.set_title(f"{meta['problem']}: error against run time (marker: family)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6.5, ncol=2, loc="best")
    fig.savefig(path, dpi=110)


def run(names, out_dir, quick=False, command="dtdyn bench", blas_threads=1):
    """Run the benches ``names`` (P3, P4) with BLAS pinned to ``blas_threads`` threads, write
    each report (Markdown, JSON, plot) to ``out_dir`` and print a summary; the report paths."""
    written = []
    benches = bench_problems().BENCHES
    for name in names:
        if name not in benches:
            raise ValueError(f"unknown problem {name!r}; available: {', '.join(benches)}")
        print(f"{name}:")
        t0 = time.perf_counter()
        runs, meta = benches[name](quick=quick, blas_threads=blas_threads)
        meta["wall_time"] = time.perf_counter() - t0
        md = write_report(runs, meta, out_dir, command)
        print(f"{name}: {len(runs)} runs in {meta['wall_time']:.0f} s; report {md}")
        print(f"  {_blas_text(meta)}; times: {SPREAD}")
        t_lin = meta.get("linear_time")
        if t_lin:
            print(f"  linear baseline ({name}L modal filters): {_linear_spread(meta)}")
        for target in meta["targets"]:
            top = ranking(runs, target)[:3]
            print(f"  fastest at max error <= {target:g}: " + "; ".join(
                f"{r.method} ({r.setting}) {r.max_error:.1e} in {r.spread()} ms"
                + (f" ({r.price(t_lin):.2g}x linear)" if t_lin else "")
                for r in top))
        written.append(md)
    return written


# --- the ranking from one report to the next ----------------------------------------------------

@dataclass(frozen=True)
class RankChange:
    """Two methods ranked in opposite orders by two reports although each of the two
    separates their run times (their [min, max] ranges are disjoint in both).

    ``first``, ``second``: the indices of the two reports (in the order given to
    `rank_changes`); ``faster_first``: the method faster in report ``first`` (by the median),
    ``faster_second`` the other one, faster in report ``second``; ``spreads``: each method's
    (min, median, max) run time in each report, s."""
    target: float
    first: int
    second: int
    faster_first: str
    faster_second: str
    spreads: dict

    def __str__(self):
        a, b = self.faster_first, self.faster_second

        def ms(method, i):
            lo, med, hi = self.spreads[method][i]
            return f"{med * 1e3:.3g} [{lo * 1e3:.3g}, {hi * 1e3:.3g}] ms"
        return (f"max error <= {self.target:g}: report {self.first}: {a} {ms(a, 0)} before "
                f"{b} {ms(b, 0)}; report {self.second}: {b} {ms(b, 1)} before {a} {ms(a, 1)}")


def _load(result):
    """A bench result as (runs, meta): from (runs, meta), a report's JSON data or its path."""
    if isinstance(result, (str, Path)):
        result = json.loads(Path(result).read_text())
    if isinstance(result, dict):
        fields = Run.__dataclass_fields__
        return ([Run(**{k: v for k, v in r.items() if k in fields}) for r in result["runs"]],
                result["meta"])
    runs, meta = result
    return list(runs), meta


def rank_changes(*results, targets=None):
    """Rank changes between two or three bench reports that their spreads do not explain.

    For each accuracy target, each report ranks the methods that reach it by their fastest
    run's median time (`ranking`). Two methods whose run times' ranges [min, max] over the
    repeats overlap in a report are not ordered by it: their ranks may swap from that report
    to another within the noise. A pair of methods ranked in opposite orders by two of the
    reports is reported when the ranges are disjoint in both: each report orders the two
    beyond its repeats' spread, and they disagree (a run-to-run change the repeats of one run
    do not show, such as a BLAS call of a small matrix taking 0.6 ms in one report and 35 ms
    in every repeat of the next). Methods missing from one of the two rankings are not
    compared.

    Parameters
    ----------
    *results : (runs, meta), dict or path
        Two or three reports of the same problem: what `bench_p3` / `bench_p4` return, the
        JSON data `write_report` writes (``bench_P3.json``) or its path.
    targets : sequence of float, optional
        The accuracy targets to compare at (default: the first report's ``meta["targets"]``).

    Returns
    -------
    list of RankChange
        Empty when every rank change is among methods whose spreads overlap.

    Examples
    --------
    >>> def report(a, b):  # methods a and b, run times (min, median, max) in ms
    ...     runs = [Run(m, "f", "s", 1e-4, 1e-5, t[1] / 1e3, 0.0, run_time_min=t[0] / 1e3,
    ...                 run_time_max=t[2] / 1e3, repeats=3) for m, t in (("a", a), ("b", b))]
    ...     return runs, {"problem": "X", "targets": [1e-3]}
    >>> rank_changes(report((1, 1.1, 1.2), (3, 3, 3.1)), report((2, 3, 4), (1.5, 2, 2.5)))
    []
    >>> for change in rank_changes(report((1, 1.1, 1.2), (3, 3, 3.1)),
    ...                            report((30, 32, 35), (1.5, 2, 2.5))):
    ...     print(change)  # doctest: +NORMALIZE_WHITESPACE
    max error <= 0.001: report 0: a 1.1 [1, 1.2] ms before b 3 [3, 3.1] ms;
    report 1: b 2 [1.5, 2.5] ms before a 32 [30, 35] ms
    """
    loaded = [_load(r) for r in results]
    if not 2 <= len(loaded) <= 3:
        raise ValueError(f"rank_changes compares 2 or 3 bench results; got {len(loaded)}")
    problems_ = {meta.get("problem") for _, meta in loaded}
    if len(problems_) > 1:
        raise ValueError(f"rank_changes compares reports of one problem; got problems "
                         f"{sorted(map(str, problems_))}")
    if targets is None:
        targets = loaded[0][1]["targets"]
    changes = []
    for target in targets:
        ranked = [{r.method: (k, r) for k, r in enumerate(ranking(runs, target))}
                  for runs, _ in loaded]
        for i, j in itertools.combinations(range(len(loaded)), 2):
            common = [m for m in ranked[i] if m in ranked[j]]
            for a, b in itertools.combinations(common, 2):
                (ka, ra), (kb, rb) = ranked[i][a], ranked[i][b]
                (la, sa), (lb, sb) = ranked[j][a], ranked[j][b]
                if (ka < kb) == (la < lb):
                    continue  # same order
                if _overlap(ra, rb) or _overlap(sa, sb):
                    continue  # one of the reports does not order them: within its spread
                fast, slow = (a, b) if ka < kb else (b, a)
                spreads = {m: tuple((_range(x)[0], x.run_time, _range(x)[1])
                                    for x in (ranked[i][m][1], ranked[j][m][1]))
                           for m in (fast, slow)}
                changes.append(RankChange(target, i, j, fast, slow, spreads))
    return changes


def _range(r):
    """(min, max) of a run's repeats (a run without them: its time, twice)."""
    return (r.run_time if r.run_time_min is None else r.run_time_min,
            r.run_time if r.run_time_max is None else r.run_time_max)


def _overlap(r, s):
    """Whether the [min, max] run time ranges of two runs intersect."""
    (lo_r, hi_r), (lo_s, hi_s) = _range(r), _range(s)
    return lo_r <= hi_s and lo_s <= hi_r
