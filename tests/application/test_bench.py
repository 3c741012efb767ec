"""`dtdyn bench`: the P3 work-precision report (quick sweep) is complete and consistent."""
import json

import numpy as np
import pytest

from dtdyn.app import bench


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
    from dtdyn.app.problems import p4, p4l
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
