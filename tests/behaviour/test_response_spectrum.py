"""Earthquake response spectra against an independent SDOF solution: exact_response (matrix
exponential) of each oscillator under the record linearly upsampled 50 times, with a zero tail
for the free vibration, its peaks picked at the samples. Such sampled peaks are low by at most
1 - cos(pi f / fs_up) ~ (pi f / fs_up)^2 / 2 = 2e-5 at 10 Hz: the tolerance. Ours are exact
between samples, so never below the reference."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app._cli import main

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
