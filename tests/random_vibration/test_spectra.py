"""VRS, FDS and ERS against closed forms (white noise), FatigueDS and pyyeti on the same inputs,
Davenport's formula against the mean of its Gumbel distribution, and the spectra of long
synthesized records within their statistical error; the FDS-equivalent PSD recomputed."""
import contextlib
import io
from math import gamma

import numpy as np
import pytest
from scipy import integrate

from dtdyn.random_vibration import psd_table
from dtdyn.random_vibration._rainflow import rainflow_cycles
from dtdyn.random_vibration._spectra import (EULER_GAMMA, extreme_response_spectrum,
                                            fatigue_damage_spectrum, fds_equivalent_psd,
                                            sdof_moments, vibration_response_spectrum)
from dtdyn.random_vibration._synthesis import random_time_history

TABLE = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])   # g^2/Hz
WIDE = np.r_[0.0, np.geomspace(1e-3, 1e9, 40)]     # a band wide enough for white-noise forms


def staircase(freq, psd):
    """FatigueDS's reading of a sampled PSD: constant on [f_j - df/2, f_j + df/2] (the ends
    clipped to the first and last sample), as a callable whose breakpoints are its steps."""
    df = freq[1] - freq[0]
    edges = np.r_[freq[0], freq[:-1] + df / 2, freq[-1]]

    def g(f):
        f = np.asarray(f, float)
        i = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, psd.size - 1)
        return np.where((f >= edges[0]) & (f <= edges[-1]), psd[i], 0.0)
    g.freqs_hz = edges
    return g


# ---------------------------------------------------------------------------------------------
# closed forms


@pytest.mark.parametrize("zeta", [0.01, 0.05, 0.2])
def test_white_noise_closed_forms(zeta):
    """m0 of a white base acceleration W: absolute acceleration pi f_n W (1 + 4 zeta^2) /
    (4 zeta), relative displacement W / (8 zeta omega^3), pseudo-acceleration omega^4 times it;
    the zero up-crossing rate of z is f_n exactly. The band's end at 1e9 Hz leaves out
    (2 zeta f_n)^2 W / 1e9 of the first, below 1e-6 relative."""
    f_n = np.array([5.0, 100.0, 3000.0])
    w = 2 * np.pi * f_n
    vrs = vibration_response_spectrum(1.0, f_n, zeta, psd_freqs_hz=WIDE)
    np.testing.assert_allclose(vrs.values**2, np.pi * f_n * (1 + 4 * zeta**2) / (4 * zeta),
                               rtol=1e-6)
    z = vibration_response_spectrum(1.0, f_n, zeta, response="relative_displacement",
                                    psd_freqs_hz=WIDE)
    np.testing.assert_allclose(z.values**2, 1 / (8 * zeta * w**3), rtol=1e-6)
    np.testing.assert_allclose(z.zero_crossing_rate, f_n, rtol=1e-6)
    pa = vibration_response_spectrum(1.0, f_n, zeta, response="pseudo_acceleration",
                                     psd_freqs_hz=WIDE)
    np.testing.assert_allclose(pa.values, w**2 * z.values, rtol=1e-12)
    assert vrs.info["rms_error_estimate"] < 1e-8


def test_coarse_grid_does_not_miss_the_resonance():
    """A 5-sample PSD (log-log between samples) against the same table: the same VRS, since
    the quadrature never uses the samples' grid, and the trapezoid on a 40-point grid of the
    oscillator's response PSD is far off."""
    f_s = TABLE.freqs_hz
    a = vibration_response_spectrum(TABLE, [123.4], 0.02)
    b = vibration_response_spectrum(TABLE.values, [123.4], 0.02, psd_freqs_hz=f_s)
    np.testing.assert_allclose(a.values, b.values, rtol=1e-9)
    f = np.geomspace(20, 2000, 40)
    p, zeta = f / 123.4, 0.02
    h2 = (1 + (2 * zeta * p) ** 2) / ((1 - p**2) ** 2 + (2 * zeta * p) ** 2)
    assert abs(np.sqrt(integrate.trapezoid(h2 * TABLE(f), f)) / a.values[0] - 1) > 0.05


def test_fds_narrow_band_formula():
    """The narrow-band FDS from the moments: nu0 T K^b / C (sqrt(2 m0))^b Gamma(1 + b/2)."""
    f_n, b, C, K, T = np.array([60.0, 600.0]), 5.0, 1e9, 3.0, 1800.0
    fds = fatigue_damage_spectrum(TABLE, f_n, 0.04, slope=b, coefficient=C, stress_factor=K,
                                  duration=T)
    m = sdof_moments(TABLE, f_n, 0.04, response="relative_displacement")
    nu0 = np.sqrt(m["m2"] / m["m0"])
    np.testing.assert_allclose(fds.values, nu0 * T * K**b / C * np.sqrt(2 * m["m0"]) ** b
                               * gamma(1 + b / 2), rtol=1e-12)


def test_davenport_is_the_mean_of_the_gumbel_distribution():
    """Up-crossings of a as Poisson events: P(max < a) = exp(-N e^(-a^2/2)) (sigma = 1).
    Its mean, integrated numerically, approaches u + gamma / u, u = sqrt(2 ln N), with an
    error falling like u^-3 (the next term of the expansion); its mode is u - ... -> u."""
    errors = []
    for N in (1e3, 1e5, 1e8):
        mean = integrate.quad(lambda a, N=N: 1 - np.exp(-N * np.exp(-a * a / 2)), 0, 50,
                              points=[np.sqrt(2 * np.log(N))], limit=200)[0]
        u = np.sqrt(2 * np.log(N))
        errors.append((mean - (u + EULER_GAMMA / u)) * u**3)
    assert max(abs(e) for e in errors) < 2.5          # |error| < 2.5 / u^3: 1e3 -> 0.7 %
    table = psd_table([(10, 1.0), (1000, 1.0)])
    ers = extreme_response_spectrum(table, [100.0], 0.05, duration=1000.0)
    mp = extreme_response_spectrum(table, [100.0], 0.05, duration=1000.0, peak="most_probable")
    u = np.sqrt(2 * np.log(ers.zero_crossing_rate[0] * 1000.0))
    np.testing.assert_allclose(ers.values / ers.rms, u + EULER_GAMMA / u, rtol=1e-14)
    np.testing.assert_allclose(mp.values / mp.rms, u, rtol=1e-14)


# ---------------------------------------------------------------------------------------------
# FatigueDS and pyyeti on the same inputs


def fatigueds(f_n, psd, freq, T, b, C, p):
    from FatigueDS import Spectrum
    s = Spectrum(freq_data=f_n.copy(), Q=10)
    s.set_random_load((psd, freq), T=T)
    s.get_ers()
    s.get_fds(k=b, C=C, p=p)
    return s


def test_fds_and_ers_equal_fatigueds_on_its_staircase():
    """FatigueDS integrates a sampled PSD as a staircase (constant over each sample's df) in
    closed form (Lalanne's I0, I2): given that staircase, the narrow-band FDS and the most
    probable ERS of the pseudo-acceleration are the same to 1e-10 (our quadrature: 1e-8 on
    the moments, typically far better)."""
    pytest.importorskip("FatigueDS")
    freq = np.arange(10.0, 1000.5, 1.0)
    psd = np.interp(freq, [10, 100, 500, 1000], [0.01, 0.05, 0.05, 0.005])
    f_n, T = np.arange(20.0, 900.0, 20.0), 3600.0
    s = fatigueds(f_n, psd, freq, T, 6.0, 1e20, 2.0)
    g = staircase(freq, psd)
    ers = extreme_response_spectrum(g, f_n, 0.05, duration=T, peak="most_probable")
    fds = fatigue_damage_spectrum(g, f_n, 0.05, slope=6.0, coefficient=1e20, stress_factor=2.0,
                                  duration=T)
    np.testing.assert_allclose(ers.values, s.ers, rtol=1e-10)
    np.testing.assert_allclose(fds.values, s.fds, rtol=1e-10)


def test_fatigueds_on_a_table_differs_by_its_staircase():
    """Given a log-log table sampled every df, FatigueDS's staircase (each sample held over the
    df around it: a midpoint rule on the table) differs from the table by O(df^2) in the
    moments: the FDS difference falls as df^2 (the cause, measured: halving df divides it by
    4), while ours is the table's own."""
    pytest.importorskip("FatigueDS")
    f_n, T = np.geomspace(30, 1500, 12), 3600.0
    ours = fatigue_damage_spectrum(TABLE, f_n, 0.05, slope=6.0, duration=T).values
    diffs = []
    for df in (2.0, 1.0, 0.5):
        freq = np.arange(20.0, 2000.0 + df / 2, df)
        diffs.append(np.abs(fatigueds(f_n, TABLE(freq), freq, T, 6.0, 1.0, 1.0).fds / ours
                            - 1).max())
    assert diffs[0] > 1e-6
    assert 3.2 < diffs[0] / diffs[1] < 4.8 and 3.2 < diffs[1] / diffs[2] < 4.8, diffs


def test_vrs_against_pyyeti_vrs_converges_with_its_grid():
    """pyyeti.srs.vrs sums the response PSD on its frequency grid (log-log interpolation of
    the table): its difference from ours falls as the grid is refined."""
    srs = pytest.importorskip("pyyeti.srs")
    f_n = np.array([50.0, 200.0, 1000.0])
    ours = vibration_response_spectrum(TABLE, f_n, 0.05).values
    spec = (TABLE.freqs_hz, TABLE.values)
    diffs = [np.abs(srs.vrs(spec, np.arange(20.0, 2000.0 + df / 2, df), 10.0, False, Fn=f_n)
                    / ours - 1).max() for df in (1.0, 0.1, 0.01)]
    assert diffs[2] < 1e-4 and diffs[0] > diffs[1] > diffs[2], diffs


@pytest.fixture(scope="module")
def record():
    dt = 1e-4
    return random_time_history(TABLE, dt, 2**17, seed=3), dt


def test_record_fds_equals_pyyeti_damage_indicators_up_to_its_bins(record):
    """pyyeti.fdepsd counts the same SDOF responses by rainflow, then puts each amplitude in
    one of `nbins` bins at its lower edge: its damage indicator sum(count amp^b) is below the
    rainflow sum by nearly b / nbins (the cause, measured: 10x the bins, 1/10 the
    difference)."""
    fdepsd = pytest.importorskip("pyyeti.fdepsd")
    x, dt = record
    f_n = np.array([60.0, 250.0])
    for resp, ours_r in (("absacce", "absolute_acceleration"), ("pvelo", "pseudo_velocity")):
        ours = fatigue_damage_spectrum(None, f_n, 0.05, slope=4.0, ground_acceleration=x,
                                       dt=dt, response=ours_r).values
        d = [fdepsd.fdepsd(x, 1 / dt, f_n, 10.0, resp=resp, detrend=False, winends=None,
                           hpfilter=None, nbins=nb, rolloff=None, parallel="no"
                           ).di_sig["b=4"].values / ours - 1 for nb in (300, 3000)]
        assert np.all(d[0] < 0) and np.all((-d[0] > 0.005) & (-d[0] < 4 / 300)), d
        np.testing.assert_allclose(d[0] / d[1], 10.0, rtol=0.05)
        # extrapolated to infinitely many bins, the difference is below the next term of the
        # binning error, O(b^2 / nbins^2) at 300 bins
        assert np.abs(d[1] - (d[0] - d[1]) / 9).max() < 4.0**2 / 300**2


def test_record_fds_against_fatigueds_convolution():
    """FatigueDS's time-domain FDS convolves the record with the sampled impulse response
    (a quadrature of Duhamel's integral, error O(dt^2)); ours filters the record exactly
    (linear between samples). Same rainflow and Miner sum: the difference is the quadrature's
    (the cause, measured: records of the same PSD at dt / 2, a quarter of the difference)."""
    pytest.importorskip("FatigueDS")
    from FatigueDS import Spectrum
    f_n, b = np.array([50.0, 200.0]), 4.0
    diffs = []
    for dt in (1e-4, 5e-5):
        x = random_time_history(TABLE, dt, int(round(13.1072 / dt)), seed=3)
        ours = fatigue_damage_spectrum(None, f_n, 0.05, slope=b, ground_acceleration=x, dt=dt)
        s = Spectrum(freq_data=f_n.copy(), Q=10)
        with contextlib.redirect_stderr(io.StringIO()), \
                contextlib.redirect_stdout(io.StringIO()):
            s.set_random_load((x, dt))
            s.get_fds(k=b, C=1.0, p=1.0)
        diffs.append(s.fds / ours.values - 1)
    assert np.all(np.abs(diffs[0]) < 0.01), diffs
    np.testing.assert_allclose(diffs[0] / diffs[1], 4.0, rtol=0.2)


# ---------------------------------------------------------------------------------------------
# against long synthesized records


def segment_error(values):
    """Mean and standard error of the mean over the first axis (records or segments)."""
    values = np.asarray(values)
    return values.mean(axis=0), values.std(axis=0, ddof=1) / np.sqrt(values.shape[0])


def test_spectra_of_a_long_record_agree_with_the_psd(record):
    """VRS, FDS (narrow band and Dirlik) and the up-crossing rate from the PSD against those
    of a 13 s synthesized record. Statistical error: the spread of the 8 segments' values
    (standard error of their mean), 4 of them allowed, plus each method's known bias: the
    narrow-band FDS of a Q = 10 oscillator's response overstates rainflow damage by a few %.
    The interpolation between samples (1 - sinc^2(f_n dt) < 0.2 %) is well inside."""
    x, dt = record
    f_n = np.array([60.0, 150.0, 300.0])
    T = (x.size - 1) * dt
    vrs = vibration_response_spectrum(TABLE, f_n, 0.05)
    rec = vibration_response_spectrum(None, f_n, 0.05, ground_acceleration=x, dt=dt)
    segments = np.array_split(x, 8)
    seg = np.array([vibration_response_spectrum(None, f_n, 0.05, ground_acceleration=s,
                                                dt=dt).values ** 2 for s in segments])
    _, se = segment_error(seg)
    assert np.all(np.abs(rec.values**2 - vrs.values**2) < 4 * se), (rec.values, vrs.values)
    np.testing.assert_allclose(rec.zero_crossing_rate, vrs.zero_crossing_rate, rtol=0.03)
    for method, bias in (("narrow_band", 0.08), ("dirlik", 0.03)):
        psd_fds = fatigue_damage_spectrum(TABLE, f_n, 0.05, slope=4.0, duration=T,
                                          method=method).values
        rec_fds = fatigue_damage_spectrum(None, f_n, 0.05, slope=4.0, ground_acceleration=x,
                                          dt=dt).values
        d = np.array([fatigue_damage_spectrum(None, f_n, 0.05, slope=4.0, ground_acceleration=s,
                                              dt=dt, duration=T).values for s in segments])
        _, se = segment_error(d)
        assert np.all(np.abs(psd_fds - rec_fds) < 4 * se + bias * rec_fds), (method, psd_fds,
                                                                            rec_fds, se)


def test_ers_is_the_mean_of_the_records_maxima():
    """The largest pseudo-acceleration of 12 independent 4 s records against Davenport's
    expected largest maximum: within 4 standard errors of the maxima's mean, plus Davenport's
    asymptotic error (< 2.5 / u^3, test above)."""
    dt, n = 1e-4, 40_000
    f_n = np.array([100.0, 250.0])
    T = (n - 1) * dt
    ers = extreme_response_spectrum(TABLE, f_n, 0.05, duration=T)
    maxima = np.array([extreme_response_spectrum(
        None, f_n, 0.05, ground_acceleration=random_time_history(TABLE, dt, n, seed=s),
        dt=dt).values for s in range(12)])
    mean, se = segment_error(maxima)
    u = np.sqrt(2 * np.log(ers.zero_crossing_rate * T))
    assert np.all(np.abs(mean - ers.values) < 4 * se + 2.5 / u**3 * ers.rms), (mean, ers.values)


def test_record_fds_is_the_rainflow_sum(record):
    """A record's FDS at one f_n is the Miner sum of the rainflow cycles of K y, y the
    oscillator's response (`sdof_response`), scaled to ``duration``."""
    import dtdyn as dd
    x, dt = record
    _, y = dd.sdof_response(x, dt, [80.0], 0.05, response="relative_displacement")
    cycles = rainflow_cycles(2.0 * y[:, 0])
    expected = np.sum(cycles.counts * (cycles.ranges / 2) ** 5.0) / 1e3
    got = fatigue_damage_spectrum(None, [80.0], 0.05, slope=5.0, coefficient=1e3,
                                  stress_factor=2.0, ground_acceleration=x, dt=dt,
                                  duration=2 * (x.size - 1) * dt)
    np.testing.assert_allclose(got.values, 2 * expected, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# the FDS-equivalent PSD


def test_equivalent_psd_gives_back_the_fds_and_the_table():
    """The table's FDS on natural frequencies that include its breakpoints and span its band:
    the equivalent PSD over the same duration is the table itself (a table log-log between the
    f_n is one), and over a tenth of the duration 10^(2/b) times it; its FDS recomputed is the
    target within the tolerance."""
    f_n = np.unique(np.r_[np.geomspace(20, 2000, 30), TABLE.freqs_hz])
    b, T = 8.0, 3600.0
    fds = fatigue_damage_spectrum(TABLE, f_n, 0.05, slope=b, duration=T)
    same = fds_equivalent_psd(fds, T, tolerance=1e-6)
    np.testing.assert_allclose(same.values, TABLE(f_n), rtol=1e-5)
    short = fds_equivalent_psd(fds, T / 10, tolerance=1e-6)
    np.testing.assert_allclose(short.values, 10 ** (2 / b) * TABLE(f_n), rtol=1e-5)
    again = fatigue_damage_spectrum(short, f_n, 0.05, slope=b, duration=T / 10)
    np.testing.assert_allclose(again.values, fds.values, rtol=1e-6)


def test_equivalent_psd_of_a_record_fds():
    """From a record's (rainflow) FDS: the narrow-band PSD whose FDS over the record's length
    matches it within the tolerance, and close to the PSD the record was drawn from: a mean
    square seen through a band B = 2 zeta f_n over T seconds scatters by about 1 / sqrt(B T)
    (Bendat & Piersol), 4 of those allowed."""
    dt = 1e-4
    x = random_time_history(TABLE, dt, 2**17, seed=5)
    f_n = np.geomspace(40, 400, 8)
    fds = fatigue_damage_spectrum(None, f_n, 0.05, slope=4.0, ground_acceleration=x, dt=dt)
    T = fds.info["duration"]
    G = fds_equivalent_psd(fds, T, tolerance=1e-5)
    again = fatigue_damage_spectrum(G, f_n, 0.05, slope=4.0, duration=T)
    np.testing.assert_allclose(again.values, fds.values, rtol=1e-5)
    scatter = 1 / np.sqrt(2 * 0.05 * f_n * T)
    inner = slice(1, -1)          # at the ends the table has one side: G makes up for it
    assert np.all(np.abs(G.values[inner] / TABLE(f_n[inner]) - 1) < 4 * scatter[inner]), (
        G.values, TABLE(f_n))


# ---------------------------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize("kwargs, match", [
    (dict(damping_ratio=0.0), "damping_ratio"),
    (dict(damping_ratio=1.5), "damping_ratio"),
    (dict(response="absolute"), "response"),
    (dict(freqs_hz=[100.0, 50.0]), "increase"),
    (dict(freqs_hz=[-1.0]), "freqs_hz"),
    (dict(ground_acceleration=np.zeros(10), dt=1e-3), "both given"),
])
def test_bad_input_names_the_field(kwargs, match):
    args = dict(ground_acceleration_psd=TABLE, freqs_hz=[50.0, 100.0])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        vibration_response_spectrum(**args)


def test_bad_input_of_the_fds_and_ers():
    with pytest.raises(ValueError, match="duration is needed"):
        fatigue_damage_spectrum(TABLE, [50.0], slope=4.0)
    with pytest.raises(ValueError, match="psd_freqs_hz is needed"):
        fatigue_damage_spectrum(1.0, [50.0], slope=4.0, duration=1.0)
    with pytest.raises(ValueError, match="slope"):
        fatigue_damage_spectrum(TABLE, [50.0], slope=-4.0, duration=1.0)
    with pytest.raises(ValueError, match="without dt"):
        extreme_response_spectrum(None, [50.0], ground_acceleration=np.zeros(10))
    with pytest.raises(ValueError, match="nu0 T > 1"):
        extreme_response_spectrum(TABLE, [50.0], duration=1e-3)
    with pytest.raises(ValueError, match="peak"):
        extreme_response_spectrum(TABLE, [50.0], duration=1.0, peak="mean")
    vrs = vibration_response_spectrum(TABLE, [50.0, 100.0])
    with pytest.raises(ValueError, match="fatigue damage spectrum"):
        fds_equivalent_psd(vrs, 10.0)
