"""PSD tables: log-log segments, dB/octave slopes and the exact rms, against quadrature and
pyyeti's `psd.area` / `psd.interp` (independent implementations of the same convention)."""
import numpy as np
import pytest
import scipy.integrate as si

from dtdyn.random_vibration import psd_table

SPEC = [(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)]


def test_rms_equals_quadrature_and_pyyeti():
    t = psd_table(SPEC)
    f = [p[0] for p in SPEC]
    ms = sum(si.quad(t, a, b, epsabs=0, epsrel=1e-13)[0] for a, b in zip(f[:-1], f[1:]))
    assert t.mean_square == pytest.approx(ms, rel=1e-12)   # quad, epsrel 1e-13
    pyyeti_psd = pytest.importorskip("pyyeti.psd")
    area = pyyeti_psd.area(np.array(SPEC, dtype=float))[0]
    assert t.grms == pytest.approx(np.sqrt(area), rel=1e-13)
    assert t.grms == t.rms


def test_flat_segment_and_minus_one_slope_by_hand():
    t = psd_table([(10, 2.0), (110, 2.0)])
    assert t.mean_square == pytest.approx(200.0, rel=1e-15)
    t = psd_table([(100, 1.0), (400, 0.25)])                # G ~ 1/f: G1 f1 ln(f2/f1)
    assert t.mean_square == pytest.approx(100.0 * np.log(4.0), rel=1e-14)


def test_log_log_interpolation_and_zero_outside():
    t = psd_table(SPEC)
    fm = np.sqrt(20 * 80)                                   # geometric mean: sqrt(G1 G2)
    assert t(fm) == pytest.approx(np.sqrt(0.01 * 0.04), rel=1e-14)
    assert t(np.array([10.0, 2000.1])).tolist() == [0.0, 0.0]
    assert t(20.0) == pytest.approx(0.01, rel=1e-15) and t(2000.0) == pytest.approx(0.007)
    pyyeti_psd = pytest.importorskip("pyyeti.psd")
    f = np.geomspace(20, 2000, 101)
    ref = pyyeti_psd.interp(np.array(SPEC, dtype=float), f, linear=False).ravel()
    np.testing.assert_allclose(t(f), ref, rtol=1e-12)


def test_slopes_in_db_per_octave():
    t = psd_table(SPEC)
    # doubling the PSD per octave is 10 log10(2) = 3.0103 dB/octave
    np.testing.assert_allclose(t.slopes, [10 * np.log10(2), 0.0, 10 * np.log10(0.175) /
                                          np.log2(2000 / 350)], rtol=1e-14)
    s = psd_table([(20, "+3 dB/oct"), (80, 0.04), (350, 0.04), (2000, "-3 dB/octave")])
    assert s.values[0] == pytest.approx(0.04 * 0.25 ** (3 / (10 * np.log10(2))), rel=1e-14)
    assert s.values[-1] == pytest.approx(0.04 * (2000 / 350) ** (-3 / (10 * np.log10(2))))
    np.testing.assert_allclose(s.slopes, [3.0, 0.0, -3.0], rtol=1e-13)


@pytest.mark.parametrize("rows, match", [
    ([(20, 0.01)], "at least two"),
    ([(80, 0.01), (20, 0.02)], "increasing"),
    ([(20, 0.01), (80, -0.04)], r"breakpoints\[1\] value = -0.04"),
    ([(20, 0.01), (80, "3 db per oct")], "neither a number nor a slope"),
    ([(20, "+3 dB/oct"), (80, "-3 dB/oct")], "both slopes"),
    ([(20, 0.01), ("x", 0.02)], r"breakpoints\[1\] frequency"),
])
def test_bad_tables_name_the_entry(rows, match):
    with pytest.raises(ValueError, match=match):
        psd_table(rows)
