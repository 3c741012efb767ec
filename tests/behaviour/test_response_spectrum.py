"""Earthquake response spectra against an independent SDOF solution: exact_response (matrix
exponential) of each oscillator under the record linearly upsampled 50 times, with a zero tail
for the free vibration, its peaks picked at the samples. Such sampled peaks are low by at most
1 - cos(pi f / fs_up) ~ (pi f / fs_up)^2 / 2 = 2e-5 at 10 Hz: the tolerance. Ours are exact
between samples, so never below the reference."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app import main

DT, N, UP = 0.01, 2001, 50


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(5)
    ag = np.convolve(rng.standard_normal(N), np.ones(5) / 5, mode="same") * np.hanning(N) * 2.0
    ag[0] = ag[-1] = 0.0   # from rest, back to rest (the spectrum's record starts at 0)
    return ag


def _reference(ag, T, zeta):
    t_up = np.arange((N - 1) * UP + 1) * DT / UP
    a = np.r_[np.interp(t_up, np.arange(N) * DT, ag), np.zeros(int(3 * T * UP / DT))]
    w = 2 * np.pi / T
    r = dd.exact_response([[1.0]], [[2 * zeta * w]], [[w * w]], None, DT / UP,
                          ground_acceleration=a)
    return np.abs(r.x).max(), np.abs(r.a_abs).max()


def test_equals_the_upsampled_exact_sdof(record):
    T = np.array([0.1, 0.3, 1.0, 3.0])
    s = dd.response_spectrum(record, DT, T, damping_ratio=[0.0, 0.05])
    for i, zeta in enumerate(s.damping_ratio):
        for j, Tj in enumerate(T):
            sd, sa = _reference(record, Tj, zeta)
            assert sd * (1 - 1e-12) <= s.sd[i, j] <= sd * (1 + 2e-5)
            assert sa * (1 - 1e-12) <= s.sa[i, j] <= sa * (1 + 2e-5)
    w = 2 * np.pi / T
    np.testing.assert_allclose(s.psv, w * s.sd, rtol=1e-15)
    np.testing.assert_allclose(s.psa, w**2 * s.sd, rtol=1e-15)
    np.testing.assert_allclose(s.sa[0], s.psa[0], rtol=1e-9)   # undamped: SA = PSA


def test_command_writes_the_csv(record, tmp_path, capsys):
    np.savetxt(tmp_path / "rec.csv", record / 9.80665)
    out = tmp_path / "spec.csv"
    assert main(["spectrum", str(tmp_path / "rec.csv"), "--dt", "0.01", "--units", "g",
                 "--periods", "0.1", "3.0", "4", "--damping-ratio", "0.05",
                 "--out", str(out)]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    s = dd.response_spectrum(record, DT, np.geomspace(0.1, 3.0, 4), damping_ratio=0.05)
    np.testing.assert_allclose(table[:, 2], s.sd[0], rtol=1e-12)
    np.testing.assert_allclose(table[:, 5], s.sa[0], rtol=1e-12)
    assert main(["spectrum", str(tmp_path / "rec.csv"), "--dt", "0.01", "--periods", "1", "0.5",
                 "3"]) == 2
    assert "--periods" in capsys.readouterr().err


@pytest.mark.parametrize("kw, match", [
    ({"periods": [0.0, 1.0]}, r"periods\[0\] = 0.0"),
    ({"damping_ratio": -0.1}, r"damping_ratio\[0\] = -0.1"),
    ({"damping_ratio": 1.0}, r"damping_ratio\[0\] = 1.0: must be < 1"),
    ({"dt": 0.0}, "dt"),
])
def test_bad_input(record, kw, match):
    args = dict(dt=DT, periods=[1.0])
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        dd.response_spectrum(record, **args)


# --- the default periods and their bias bound (from tests/application/test_warnings.py) -------
def _ordinary_record(n=2001, dt=0.01, seed=0) -> np.ndarray:
    """A 100 Hz earthquake-like record (m/s^2): white noise through a Kanai-Tajimi filter
    (2.5 Hz, 0.6) under a trapezoidal envelope, as examples/batch/make_records.py (the same as
    tests/application/test_warnings.py)."""
    import scipy.signal

    t = np.arange(n) * dt
    wg, zg = 2 * np.pi * 2.5, 0.6
    _, ag, _ = scipy.signal.lsim(([2 * zg * wg, wg**2], [1.0, 2 * zg * wg, wg**2]),
                                 np.random.default_rng(seed).standard_normal(n), t)
    ag *= np.minimum(t / 2.0, 1.0) * np.where(t > 8.0, np.exp(-0.5 * (t - 8.0)), 1.0)
    return 3.0 * ag / np.abs(ag).max()


def test_default_periods_bias_bound_and_accuracy():
    """The default periods start at 10 samples per period, where the linear-interpolation
    bias bound 1 - sinc^2(dt/T) is 3.2 % (< 5 %, the warning level, reached at 8.03 dt). And
    the bound is what a record shows: SA of an ordinary 100 Hz record against SA of its
    band-limited (FFT) interpolation, 16 times finer, differs by less than the bound at
    10 dt, and by more than 5 % at 4 dt (where the old default periods went below)."""
    import warnings

    from scipy.signal import resample

    from dtdyn.modal._spectrum import WARN_SAMPLES_PER_PERIOD, default_periods

    dt = 0.01
    T = default_periods(dt)
    assert T[0] == pytest.approx(10 * dt) and T.size == 60
    assert 1 - np.sinc(dt / T[0]) ** 2 == pytest.approx(0.0325, abs=5e-4)
    assert 1 - np.sinc(1 / WARN_SAMPLES_PER_PERIOD) ** 2 == pytest.approx(0.05, rel=1e-9)
    assert default_periods(0.001)[0] == pytest.approx(0.02)       # 1 kHz: from 0.02 s
    with pytest.raises(ValueError, match="dt = 1 s"):
        default_periods(1.0)
    ag = np.r_[_ordinary_record(seed=1), np.zeros(200)]
    periods = np.array([4 * dt, 10 * dt])
    linear = dd.response_spectrum(ag, dt, periods[1:])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dd.SRSSamplingWarning)
        linear4 = dd.response_spectrum(ag, dt, periods[:1])
        band = dd.response_spectrum(resample(ag, 16 * ag.size), dt / 16, periods)
    err10 = abs(linear.sa[0, 0] / band.sa[0, 1] - 1)
    err4 = abs(linear4.sa[0, 0] / band.sa[0, 0] - 1)
    assert err10 < 1 - np.sinc(0.1) ** 2, err10
    assert err4 > 0.05, err4
