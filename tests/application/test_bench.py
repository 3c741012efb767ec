"""`dtdyn bench`: the P3 work-precision report (quick sweep) is complete and consistent."""
import json

import numpy as np
import pytest

from dtdyn.app import _bench as bench


@pytest.fixture(scope="module")
def p3_runs():
    return bench.bench_p3(quick=True, log=lambda *a: None)


def test_p3_covers_every_family(p3_runs):
    runs, meta = p3_runs
    families = {r.family for r in runs}
    assert families == {"DT-TMM (C)", "state space", "modal filters", "peer"}
    assert {"solve_ivp RK45", "solve_ivp DOP853", "solve_ivp LSODA", "solve_ivp Radau",
            "scipy lsim"} <= {r.method for r in runs}


def test_p3_errors_follow_theory(p3_runs):
    runs, _ = p3_runs
    by = {(r.method, r.setting): r.max_error for r in runs}
    # the FOH discretization is exact for P3's (constant) force: round-off only
    assert max(v for (m, _), v in by.items() if m == "exact discretization (foh)") < 1e-10
    # average acceleration is second order: halving dt divides the error by ~4
    e = [by[("DT-TMM average_acceleration", f"dt={dt:g}")] for dt in (2e-3, 1e-3, 5e-4)]
    assert all(3.5 < a / b < 4.5 for a, b in zip(e, e[1:])), e


def test_ranking_and_report(p3_runs, tmp_path):
    runs, meta = p3_runs
    ranked = bench.ranking(runs, 1e-3)
    assert all(r.max_error <= 1e-3 for r in ranked)
    assert [r.run_time for r in ranked] == sorted(r.run_time for r in ranked)
    assert len({r.method for r in ranked}) == len(ranked)
    md = bench.write_report(runs, meta, tmp_path, "dtdyn bench P3 --quick")
    data = json.loads((tmp_path / "bench_P3.json").read_text())
    assert len(data["runs"]) == len(runs) and (tmp_path / "bench_P3.png").stat().st_size > 0
    assert "Ranking at max error <= 0.001" in md.read_text()
    assert np.isfinite([r["max_error"] for r in data["runs"]]).all()


def test_linear_baseline_column(p3_runs, tmp_path):
    """With a linear baseline time in meta (P4: the modal filter response of P4L), the report
    adds `time / linear` = run time / baseline to the rankings and to every run; without one
    (P3) it has no such column."""
    runs, meta = p3_runs
    md = bench.write_report(runs, meta, tmp_path, "dtdyn bench P3 --quick").read_text()
    assert "time / linear" not in md
    base = runs[0].run_time / 2.0
    meta = {**meta, "linear_time": base, "linear_error": 1e-14, "linear": "a baseline"}
    md = bench.write_report(runs, meta, tmp_path, "dtdyn bench P3 --quick").read_text()
    assert "| time / linear |" in md and "runs in" in md
    row = next(line for line in md.splitlines()
               if line.startswith(f"| {runs[0].method} | {runs[0].family} | {runs[0].setting} |"))
    assert row.split("|")[7].strip() == "2"                   # run time / baseline
    width = None                                              # every table row is complete
    for line in md.splitlines():
        if line.startswith(("| rank", "| method")):
            width = line.count("|")
        elif line.startswith("|"):
            assert line.count("|") == width, line

def test_p4l_is_p4_without_its_springs():
    from dtdyn.app._problems import p4, p4l
    P, L = p4(500), p4l(500)
    assert L["elements"] == [] and len(P["elements"]) == 2
    for key in ("M", "C", "K", "force"):
        np.testing.assert_array_equal(P[key], L[key])


def test_fma_peak_kernel_does_the_work_it_counts():
    """generated/fma_peak.c, the peak the P4 report divides each loop's flop rate by: `rounds`
    rounds of 12 chains a <- a x + y on 4 lanes (96 flops a round). Its returned sum equals the
    same recurrence run in NumPy (one rounding per multiply-add there, two in NumPy: after 1000
    rounds of a contraction by ~1 - 1e-6 the two differ by a few ulps of the sum, 1e-12 held),
    so no chain was dropped or folded; the peak is a positive rate."""
    kernel = bench._fma_peak_kernel()
    if kernel is None:
        pytest.skip("no C compiler")
    rounds = 1000
    x = np.array([0.999999, 0.9999991, 0.9999992, 0.9999993])
    y = np.array([1e-6, 2e-6, 3e-6, 4e-6])
    a = np.arange(12)[:, None] + np.array([0.0, 0.25, 0.5, 0.75])
    for _ in range(rounds):
        a = a * x + y
    total = kernel(rounds)
    assert total == pytest.approx(a.sum(), rel=1e-12)
    assert 0 < bench._fma_peak(rounds=10_000, repeats=2) < np.inf


# --- timing: BLAS pinned, spreads, the ranking from one report to the next ----------------------

def _report(**times):
    """A one-target bench result; ``times``: method -> (min, median, max) run time in ms."""
    runs = [bench.Run(m, "f", "dt=1", 1e-4, 1e-5, t[1] / 1e3, 0.0, run_time_min=t[0] / 1e3,
                      run_time_max=t[2] / 1e3, repeats=5) for m, t in times.items()]
    return runs, {"problem": "P3", "targets": [1e-3]}


def test_rank_changes_only_beyond_both_spreads():
    """A swap is reported only when both reports separate the two methods' [min, max] ranges
    and order them oppositely: a swap within either report's spread is noise."""
    base = _report(a=(1.0, 1.1, 1.2), b=(2.0, 2.1, 2.2), c=(5.0, 5.5, 6.0))
    assert bench.rank_changes(base, base) == []
    # a and b swap, but b's range reaches a's in the second report: within its spread
    assert bench.rank_changes(base, _report(a=(1.5, 2.4, 3.0), b=(1.9, 2.0, 2.6),
                                            c=(5.0, 5.5, 6.0))) == []
    # a's BLAS call on every repeat of the second report: 30 ms, clearly after b and c
    slow = _report(a=(28.0, 30.0, 35.0), b=(2.0, 2.1, 2.2), c=(5.0, 5.5, 6.0))
    changes = bench.rank_changes(base, slow)
    assert {(c.faster_first, c.faster_second) for c in changes} == {("a", "b"), ("a", "c")}
    assert all((c.first, c.second, c.target) == (0, 1, 1e-3) for c in changes)
    np.testing.assert_allclose(changes[0].spreads["a"], [(1e-3, 1.1e-3, 1.2e-3),
                                                         (28e-3, 30e-3, 35e-3)])
    assert "report 1: b 2.1 [2, 2.2] ms before a 30 [28, 35] ms" in str(changes[0])
    # three reports: every pair compared; the report in the middle agrees with the first
    three = bench.rank_changes(base, base, slow)
    assert {(c.first, c.second) for c in three} == {(0, 2), (1, 2)}
    # a method missing from a ranking (not reaching the target) is not compared
    changes = bench.rank_changes(base, _report(b=(2.0, 2.1, 2.2), c=(1.0, 1.1, 1.2)))
    assert [(c.faster_first, c.faster_second) for c in changes] == [("b", "c")]
    assert bench.rank_changes(base, _report(c=(0.1, 0.1, 0.1), d=(0.2, 0.2, 0.2))) == []


def test_rank_changes_input_errors(tmp_path):
    with pytest.raises(ValueError, match="2 or 3 bench results; got 1"):
        bench.rank_changes(_report(a=(1, 1, 1)))
    other = ([], {"problem": "P4", "targets": [1e-3]})
    with pytest.raises(ValueError, match="one problem; got problems"):
        bench.rank_changes(_report(a=(1, 1, 1)), other)


def test_timing_spread():
    """measure: a warm-up, then the repeats (more for fast calls); Timing's median, range,
    quartiles and overlap against hand-computed values."""
    from dtdyn.app import Timing, measure
    calls = []
    out, t = measure(lambda: calls.append(1) or len(calls), repeats=3)
    assert out == 4 and len(calls) == 4 and t.repeats == 3 and t.first is not None
    _, t = measure(lambda: None, repeats=3, min_time=1.0, max_repeats=7)
    assert t.repeats == 7
    t = Timing((4.0, 1.0, 3.0, 2.0, 10.0), first=12.0)
    assert (t.median, t.min, t.max, t.quartiles, t.build) == (3.0, 1.0, 10.0, (2.0, 4.0), 9.0)
    assert t.format("s") == "3 s [1, 10]" and Timing((2e-3,)).format() == "2 ms (1 run)"
    assert t.overlaps(Timing((10.0, 11.0))) and not t.overlaps(Timing((10.5, 11.0)))
    assert t.scaled(0.5).times == (2.0, 0.5, 1.5, 1.0, 5.0)
    with pytest.raises(ValueError, match="repeats must be >= 1; got repeats=0"):
        measure(lambda: None, repeats=0)
    with pytest.raises(ValueError, match="unit must be one of s, ms, us, ns; got unit='h'"):
        t.format("h")


def test_pin_blas_limits_and_restores():
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from dtdyn.app import pin_blas
    before = [lib["num_threads"] for lib in threadpoolctl.threadpool_info()
              if lib["user_api"] == "blas"]
    with pin_blas(1) as pin:
        inside = [lib["num_threads"] for lib in threadpoolctl.threadpool_info()
                  if lib["user_api"] == "blas"]
    after = [lib["num_threads"] for lib in threadpoolctl.threadpool_info()
             if lib["user_api"] == "blas"]
    assert inside == [1] * len(before) and after == before
    assert pin.threads == 1 and "BLAS pinned to 1 thread" in pin.describe()
    assert "threadpool_limits(limits=1, user_api='blas')" in pin.describe()
    with pytest.raises(ValueError, match="threads must be an integer >= 1; got threads=0"):
        with pin_blas(0):
            pass


@pytest.mark.slow
def test_three_bench_runs_rank_only_within_spreads(tmp_path):
    """Three consecutive `dtdyn bench P3` runs (BLAS pinned to one thread): their rankings
    change only among methods whose run time ranges overlap; each report states the pin and
    shows every time's spread."""
    import subprocess
    import sys
    paths = []
    for k in range(3):
        out = tmp_path / f"run{k}"
        proc = subprocess.run([sys.executable, "-m", "dtdyn", "bench", "P3", "--out",
                               str(out)], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        assert "BLAS pinned to 1 thread" in proc.stdout
        paths.append(out / "bench_P3.json")
    changes = bench.rank_changes(*paths)
    assert changes == [], "\n".join(map(str, changes))
    data = json.loads(paths[0].read_text())
    assert data["meta"]["blas"]["threads"] == 1
    for r in data["runs"]:
        assert r["run_time_min"] <= r["run_time"] <= r["run_time_max"], r
        assert r["repeats"] >= 3, r
    md = (paths[0].parent / "bench_P3.md").read_text()
    assert "BLAS pinned to 1 thread for the timed calls" in md
    assert "| run time [ms], median [min, max] |" in md
    row = next(line for line in md.splitlines() if line.startswith("| 1 |"))
    assert row.split("|")[5].strip().count("[") == 1               # "median [min, max]"
