"""Synthesized records: Gaussian records with a given PSD or cross-spectral matrix (Welch
estimates against their chi-square intervals, the variance against the table's integral and
its statistical error, coherence and phase of correlated pairs, no wrap-around correlation),
and shocks matched to a shock response spectrum (checked on a finer grid with exact peaks,
the velocity and displacement against numerical integration of the record)."""
import numpy as np
import pytest
from scipy import integrate, signal, stats

import dtdyn as dd
from dtdyn.random_vibration import psd_table
from dtdyn.random_vibration._synthesis import random_time_history, shock_time_history

TABLE = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
DT = 1e-4


def _inside(f, edges, width):
    """Frequencies more than ``width`` Hz from every band edge (the Hann window's leakage
    biases the estimate next to a jump of the target)."""
    return np.all(np.abs(f[:, None] - np.asarray(edges)[None, :]) > width, axis=1)


def test_welch_psd_within_its_chi_square_interval():
    # Welch with non-overlapping Hann segments: each bin of a Gaussian record's estimate is
    # target * chi2(2K) / (2K), K segments; a 99 % interval leaves out 1 % of the bins
    nperseg, outside, total = 2048, 0, 0
    for seed in range(3):
        x = random_time_history(TABLE, DT, 2**20, seed=seed)
        f, P = signal.welch(x, fs=1 / DT, window="hann", nperseg=nperseg, noverlap=0)
        K = x.size // nperseg
        lo, hi = stats.chi2.ppf([0.005, 0.995], 2 * K) / (2 * K)
        keep = _inside(f, [20.0, 2000.0], 4 * f[1]) & (f > 20) & (f < 2000)
        ratio = P[keep] / TABLE(f[keep])
        outside += int(np.count_nonzero((ratio < lo) | (ratio > hi)))
        total += ratio.size
    # expected 1 % (11.5 of 1,150 bins); the count's spread is Poisson-like, inflated by the
    # correlation of neighbouring Hann bins: 2 .. 25 is beyond 3 standard deviations
    assert 2 <= outside <= 25, (outside, total)


def test_variance_is_the_tables_mean_square_within_its_statistical_error():
    n = 2**20
    x = random_time_history(TABLE, DT, n, seed=11)
    # Var of the sample variance of a Gaussian record of length T: (1/T) int G(f)^2 df
    f = np.geomspace(20, 2000, 200_001)
    std = np.sqrt(np.trapezoid(TABLE(f) ** 2, f) / (n * DT))
    assert abs(np.mean(x**2) - TABLE.grms**2) < 4 * std
    assert abs(x.mean()) < 4 * np.sqrt(TABLE(20.0) / (n * DT)) + 1e-3 * TABLE.grms


def test_correlated_pair_cross_spectrum_coherence_and_phase():
    gamma2, tau = 0.6, 3e-4                   # coherence and the delay of input 1

    def cross(f):
        G1, G2 = TABLE(f), 2.0 * TABLE(f)
        S = np.zeros((f.size, 2, 2), dtype=complex)
        S[:, 0, 0], S[:, 1, 1] = G1, G2
        S[:, 0, 1] = np.sqrt(gamma2 * G1 * G2) * np.exp(2j * np.pi * f * tau)   # E[X0 X1^*]
        S[:, 1, 0] = np.conj(S[:, 0, 1])
        return S

    x = random_time_history(cross, DT, 2**20, seed=3)
    assert x.shape == (2**20, 2)
    nperseg = 2048
    K = x.shape[0] // nperseg
    f, P01 = signal.csd(x[:, 1], x[:, 0], fs=1 / DT, nperseg=nperseg, noverlap=0)  # E[X1^* X0]
    _, coh = signal.coherence(x[:, 0], x[:, 1], fs=1 / DT, nperseg=nperseg, noverlap=0)
    keep = _inside(f, [20.0, 2000.0], 4 * f[1]) & (f > 20) & (f < 2000)
    # coherence estimate: mean over the bins against gamma^2 (its std per bin is about
    # sqrt(2) gamma^2 (1 - gamma^2) / sqrt(K); its bias (1 - gamma^2)^2 / K)
    per_bin = np.sqrt(2) * gamma2 * (1 - gamma2) / np.sqrt(K)
    assert abs(coh[keep].mean() - gamma2) < 5 * per_bin / np.sqrt(keep.sum()) + 2 / K
    # phase: std sqrt((1 - gamma^2) / (2 K gamma^2)) per bin
    phase = np.angle(P01[keep] * np.exp(-2j * np.pi * f[keep] * tau))
    assert np.abs(phase).max() < 5 * np.sqrt((1 - gamma2) / (2 * K * gamma2))
    ratio = np.abs(P01[keep]) / np.abs(cross(f[keep])[:, 0, 1])
    assert abs(ratio.mean() - 1) < 0.02
    assert abs(np.var(x[:, 1]) / (2 * TABLE.grms**2) - 1) < 0.02


def test_fully_coherent_inputs_are_identical():
    # S = G [[1, 1], [1, 1]] is semidefinite (no Cholesky factor): the eigen factor gives it
    x = random_time_history(lambda f: TABLE(f)[:, None, None] * np.ones((1, 2, 2)), DT, 4096,
                            seed=0)
    np.testing.assert_allclose(x[:, 0], x[:, 1], rtol=0, atol=1e-12 * np.abs(x).max())


def test_seeded_and_reproducible():
    a = random_time_history(TABLE, DT, 5000, seed=7)
    np.testing.assert_array_equal(a, random_time_history(TABLE, DT, 5000, seed=7))
    np.testing.assert_array_equal(a, random_time_history(TABLE, DT, 5000,
                                                         seed=np.random.default_rng(7)))
    assert not np.allclose(a, random_time_history(TABLE, DT, 5000, seed=8))


def test_no_wrap_around_correlation_between_the_records_ends():
    # a narrow band (correlation at one step ~0.8): an FFT synthesis of the record's own
    # length would correlate the last sample with the first as neighbours; here their
    # correlation is the target's at n - 1 steps, ~0 (400 records: std 0.05)
    band = psd_table([(80, 1.0), (120, 1.0)])
    dt, n, runs = 1e-3, 1000, 400
    rng = np.random.default_rng(2)
    X = np.array([random_time_history(band, dt, n, seed=rng) for _ in range(runs)])
    f = np.linspace(80, 120, 100_001)
    rho1 = np.trapezoid(band(f) * np.cos(2 * np.pi * f * dt), f) / band.mean_square
    corr = lambda a, b: np.mean(a * b) / np.sqrt(np.mean(a * a) * np.mean(b * b))  # noqa: E731
    assert abs(corr(X[:, 0], X[:, 1]) - rho1) < 0.2
    assert abs(corr(X[:, 0], X[:, -1])) < 0.2
    # one long record: no repetition at any lag beyond the correlation time; Bartlett's
    # standard deviation of the sample autocorrelation sum_i x_i x_i+k / sum x^2 is
    # sqrt((n - k) sum_m rho_m^2) / n, sum_m rho_m^2 = int G^2 df / (2 dt m0^2)
    x = random_time_history(band, dt, 2**15, seed=4)
    r = signal.correlate(x, x, mode="full", method="fft")[x.size - 1:] / np.sum(x * x)
    lags = np.arange(x.size)
    sum_rho2 = np.trapezoid(band(f) ** 2, f) / (2 * dt * band.mean_square**2)
    late = (lags > 500) & (lags < x.size // 2)
    z = r[late] / (np.sqrt((x.size - lags[late]) * sum_rho2) / x.size)
    assert np.abs(z).max() < 6          # ~16,000 lags, correlated over ~25: about 4.5 expected


def test_errors_name_the_field():
    with pytest.raises(ValueError, match="Nyquist.*dt <= 0.00025"):
        random_time_history(TABLE, 1e-3, 100, seed=0)
    with pytest.raises(ValueError, match="freqs_hz is required"):
        random_time_history(np.ones(5), 1e-3, 100)
    with pytest.raises(ValueError, match="n_samples = 1"):
        random_time_history(TABLE, DT, 1)
    with pytest.raises(ValueError, match="not positive semidefinite"):
        random_time_history(np.array([[[1, 2], [2, 1]]] * 3), 1e-3, 100,
                            freqs_hz=[10, 20, 30])


def test_sampled_psd_white_band_variance():
    x = random_time_history(0.5, 1e-3, 2**18, freqs_hz=[100.0, 300.0], seed=1)
    std = np.sqrt(0.25 * 200 / (2**18 * 1e-3))
    assert abs(np.mean(x**2) - 100.0) < 4 * std


# ---------------------------------------------------------------------------------------------
# shocks


def _srs_target(f):
    """+6 dB/octave 50..100 Hz, +12 dB/octave 100..800 Hz, flat to 5 kHz (log-log)."""
    fk, vk = np.array([50.0, 100.0, 800.0, 5000.0]), np.array([10.0, 20.0, 1280.0, 1280.0])
    return np.exp(np.interp(np.log(f), np.log(fk), np.log(vk)))


def test_shock_matches_the_target_srs_within_1_5_db_everywhere():
    f = np.geomspace(50.0, 5000.0, 81)                    # 1/12 octave
    dt = 1 / (10 * 5000.0)
    s = shock_time_history(_srs_target(f), f, dt, seed=3)   # seeds 0..3 all converge; 3 in 11 steps
    assert s.info["converged"] and np.abs(s.error_db).max() < 1.5
    # every frequency: a grid 16 times finer, exact peaks (no sampling error)
    fine = np.geomspace(50.0, 5000.0, 16 * 80 + 1)
    srs = dd.shock_response_spectrum(s.a, dt, fine, 0.05, exact_peaks=True).maximax
    assert np.abs(20 * np.log10(srs / _srs_target(fine))).max() < 1.5
    # velocity and displacement: the closed forms against the wavelets (the record's
    # definition, sampled 10 times finer) integrated by the trapezoid rule, whose relative
    # error (omega h)^2 / 12 is 3e-4 on the 5 kHz wavelet alone, far less on the total
    w = s.wavelets
    t = np.arange(10 * (s.t.size - 1) + 1) * (dt / 10)
    a = sum(A * np.sin(2 * np.pi * fm * (t - t0) / N) * np.sin(2 * np.pi * fm * (t - t0))
            * ((t >= t0) & (t <= t0 + N / (2 * fm)))
            for fm, N, t0, A in zip(w["freqs_hz"], w["half_sines"], w["delay"], w["amplitude"]))
    np.testing.assert_allclose(a[::10], s.a, rtol=0, atol=1e-12 * np.abs(s.a).max())
    v = integrate.cumulative_trapezoid(a, t, initial=0.0)
    x = integrate.cumulative_trapezoid(v, t, initial=0.0)
    assert np.abs(v[::10] - s.v).max() < 3e-4 * np.abs(s.v).max()
    assert np.abs(x[::10] - s.x).max() < 3e-4 * np.abs(s.x).max()
    assert s.v[-1] == 0.0 and s.x[-1] == 0.0       # every wavelet ends inside the record
    assert abs(v[-1]) < 3e-4 * np.abs(v).max() and abs(x[-1]) < 3e-4 * np.abs(x).max()


def test_shock_seeded_and_errors():
    f = np.geomspace(100.0, 1000.0, 41)
    target = 10.0 * (f / 100.0)
    a = shock_time_history(target, f, 5e-5, seed=3, trials=1, max_iter=5)
    b = shock_time_history(target, f, 5e-5, seed=3, trials=1, max_iter=5)
    np.testing.assert_array_equal(a.a, b.a)
    with pytest.raises(ValueError, match="dt = 0.001.*10 samples per cycle"):
        shock_time_history(target, f, 1e-3)
    with pytest.raises(ValueError, match="srs has shape"):
        shock_time_history(target[:-1], f, 5e-5)
    with pytest.raises(ValueError, match="half_sines"):
        shock_time_history(target, f, 5e-5, half_sines=(1, 5))
