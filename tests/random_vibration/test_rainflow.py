"""Rainflow counting against ASTM E1049-85's worked example and the `rainflow` package (cycle for
cycle), the C loop against its NumPy fallback, and the histograms."""
import os
import subprocess
import sys

import numpy as np
import pytest
import rainflow  # the reference (test extra)

from dtdyn.random_vibration._fatigue import SNCurve, miner_damage
from dtdyn.random_vibration._rainflow import rainflow_cycles, turning_points


def as_tuples(c):
    return list(zip(c.ranges.tolist(), c.means.tolist(), c.counts.tolist(), c.start.tolist(),
                    c.end.tolist()))


def record(seed):
    """A random record: Gaussian, rounded (plateaus and repeated values), an integer random walk
    (long plateaus, also at both ends), or a sum of sines; 3 .. 20,000 samples."""
    rng = np.random.default_rng(seed)
    n = int(rng.choice([3, 4, 5, 7, 10, 50, 1000, 20_000]))
    kind = seed % 4
    if kind == 0:
        return rng.standard_normal(n)
    if kind == 1:
        return np.round(2 * rng.standard_normal(n)) / 2
    if kind == 2:
        x = np.cumsum(rng.integers(-1, 2, n)).astype(float)
        return np.r_[x[0], x[0], x, x[-1]]
    t = np.arange(n)
    return np.sin(0.3 * t) + 0.5 * np.sin(0.07 * t + seed) + 0.1 * rng.standard_normal(n)


def test_astm_e1049_example():
    """ASTM E1049-85 X1 (fig. 6): ranges 3 (0.5), 4 (1.5), 6 (0.5), 8 (1.0), 9 (0.5)."""
    c = rainflow_cycles([-2, 1, -3, 5, -1, 3, -4, 4, -2])
    table = {}
    for r, n in zip(c.ranges, c.counts):
        table[float(r)] = table.get(float(r), 0.0) + n
    assert table == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    assert c.residue.tolist() == [3, 6, 7, 8]


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_equals_the_rainflow_package_on_100_records(backend):
    for seed in range(100):
        x = record(seed)
        ref = [tuple(map(float, r[:3])) + tuple(r[3:]) for r in rainflow.extract_cycles(x)]
        assert as_tuples(rainflow_cycles(x, backend=backend)) == ref, seed


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("x", [[], [1.0], [0.0, 1.0, 0.5], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0, 1.0],
                               [0.0, 1.0, 1.0, 1.0], [0.0, 0.0, 1.0, 0.0, 0.0]])
def test_short_and_flat_records_equal_the_package(x, backend):
    ref = [tuple(map(float, r[:3])) + tuple(r[3:]) for r in rainflow.extract_cycles(x)]
    assert as_tuples(rainflow_cycles(x, backend=backend)) == ref


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_two_samples_are_one_half_cycle(backend):
    """The one documented difference: ASTM takes the first and the last sample as reversals, so
    two samples are a half cycle; rainflow 3.2 finds no cycle in them."""
    assert list(rainflow.extract_cycles([0.0, 3.0])) == []
    c = rainflow_cycles([0.0, 3.0], backend=backend)
    assert as_tuples(c) == [(3.0, 1.5, 0.5, 0, 1)]
    assert c.residue.tolist() == [0, 1]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_non_finite_samples_are_named(bad, backend):
    x = np.arange(10.0)
    x[5] = bad
    with pytest.raises(ValueError, match=r"signal\[5\] = .* is not finite"):
        rainflow_cycles(x, backend=backend)
    with pytest.raises(ValueError, match=r"signal must be a 1-D record"):
        rainflow_cycles(np.ones((3, 3)))
    with pytest.raises(ValueError, match="backend must be one of"):
        rainflow_cycles(np.arange(3.0), backend="fortran")


def test_c_equals_numpy_fallback():
    rng = np.random.default_rng(7)
    x = np.round(rng.standard_normal(200_000), 2)  # many repeated values
    a, b = rainflow_cycles(x, backend="c"), rainflow_cycles(x, backend="numpy")
    assert a.info["backend"] == "c" and b.info["backend"] == "numpy"
    for f in ("ranges", "means", "counts", "start", "end", "residue"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    np.testing.assert_array_equal(turning_points(x), turning_points(x, backend="numpy"))


def test_reversals_of_tiny_differences_are_kept():
    """Slope signs, not their product (which underflows below 1e-154): a record scaled by
    1e-200 has the same cycles, scaled."""
    x = record(3)
    a, b = rainflow_cycles(x), rainflow_cycles(x * 1e-200)
    np.testing.assert_array_equal(a.start, b.start)
    np.testing.assert_array_equal(a.end, b.end)
    np.testing.assert_allclose(b.ranges, np.abs(x[a.end] * 1e-200 - x[a.start] * 1e-200))


def test_fallback_without_compiler_warns_once():
    code = ("import warnings, numpy as np\n"
            "from dtdyn.random_vibration._rainflow import rainflow_cycles\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    c = [rainflow_cycles(np.sin(np.arange(100.0))) for _ in range(2)]\n"
            "print(c[0].info['backend'], sum('C backend unavailable' in str(m.message) "
            "for m in w))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, DTDYN_NO_C="1"), timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["numpy", "1"]


def test_range_histogram_equals_the_package_binning():
    x = record(1000 * 4 + 0)  # Gaussian
    nbins = 12
    binsize = (x.max() - x.min()) / nbins
    # rainflow.count_cycles keys a cycle by its bin's right edge n * binsize, n = ceil(r / size)
    ref = dict(rainflow.count_cycles(x, binsize=binsize))
    h = rainflow_cycles(x).histogram(range_bins=np.arange(nbins + 1) * binsize)
    for n in range(1, nbins + 1):
        assert h.counts[n - 1] == pytest.approx(ref.get(n * binsize, 0.0), abs=1e-12), n


def test_matrix_sums_and_edges():
    c = rainflow_cycles(record(5))
    m = c.matrix(range_bins=8, mean_bins=5)
    assert m.counts.shape == (8, 5)
    assert m.counts.sum() == pytest.approx(c.counts.sum())
    assert m.range_edges[0] == 0.0 and m.range_edges[-1] == pytest.approx(c.ranges.max())
    np.testing.assert_allclose(m.counts.sum(axis=1), c.histogram(range_bins=8).counts)
    with pytest.raises(ValueError, match="range_bins = .* leaves out"):
        c.histogram(range_bins=[0.0, 0.5 * c.ranges.max()])
    with pytest.raises(ValueError, match="mean_bins must be"):
        c.matrix(mean_bins=0)


def test_cycles_damage_is_miner_of_the_cycles():
    c = rainflow_cycles(50.0 * record(9))
    sn = SNCurve(slope=5.0, coefficient=1e15)
    hand = float(np.sum(c.counts / (1e15 * (c.ranges / 2) ** -5.0)))
    assert c.damage(sn) == pytest.approx(hand, rel=1e-13)
    assert c.damage(sn) == miner_damage(c.ranges, c.counts, sn)
