"""Frequency-domain errors of the modal digital filters (dtdyn.modal._filter_errors).

The invariants' discrete frequency responses are checked against the Poisson alias sums of the
module docstring; the truncated sums come with a rigorous bound on the omitted aliases
(`alias_sum` docstring), so the tolerances are that bound plus a round-off allowance of 1e-8
relative (the observed round-off of both sides is <= ~2e-11 on these problems: the sections of
a chain's cross receptance cancel at high frequency).
"""
import numpy as np
import pytest

from dtdyn.modal import _filter_errors as fe
from dtdyn.linear._chain import chain_matrices
from dtdyn.modal._model import modal_model
from dtdyn.modal._filters import run_bank, sections

from problems import P2, P3

ROUND_OFF = 1e-8  # relative allowance for round-off (see module docstring)


def _p2_model(outputs=(0, 1)):
    M, C, K = chain_matrices(P2["mass"], P2["stiffness"], P2["damping"], sparse=False)
    return modal_model(M, C, K, force_dofs=[1], outputs=list(outputs))


def _one_dof(k=12.0):
    return modal_model([[2.0]], [[3.0]], [[k]], force_dofs=[0], outputs=[0])  # P1 (k = 12)


MODELS = {"P2": _p2_model, "1-DOF": _one_dof}


def _grid(fs, n=41):
    return np.linspace(0.0, 0.5, n) * fs


# --- the bank's frequency response is what run_bank does ------------------------------------
@pytest.mark.parametrize("invariant", fe.INVARIANTS)
def test_discrete_response_is_the_bank_transfer_function(invariant):
    """FFT of run_bank's impulse response (P2 is heavily damped: it decays to ~1e-35 within
    the record) against the evaluated sections at the FFT bins."""
    model, fs, n = _p2_model(), 20.0, 4096
    sos, in_col, out_col, direct = sections(model, fs, invariant)
    x = np.zeros((n, 1))
    x[0, 0] = 1.0
    y = run_bank(sos, in_col, out_col, direct, x, 2)
    bins = np.arange(0, n // 2 + 1, 64)
    ref = np.fft.rfft(y, axis=0)[bins]
    H = fe.discrete_frequency_response(model, 1 / fs, bins * fs / n, invariant)[:, :, 0]
    np.testing.assert_allclose(H, ref, rtol=1e-12, atol=1e-13 * np.abs(ref).max())


# --- ramp invariant: the sinc^2-weighted alias sum ---------------------------------------------
@pytest.mark.parametrize("fs", [50.0, 5.0])
@pytest.mark.parametrize("name", ["P2", "1-DOF"])
def test_ramp_invariant_is_sinc2_weighted_alias_sum(name, fs):
    model = MODELS[name]()
    f = _grid(fs)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "ramp")
    a = fe.alias_sum(model, 1 / fs, f, "ramp", n_alias=2000)
    scale = np.abs(Hd)
    # the bound on the omitted aliases (m = 3 moments, O(n_alias^-5)) is negligible
    assert np.all(a.tail_bound <= 1e-12 * scale)
    assert np.all(np.abs(a.value - Hd) <= a.tail_bound + ROUND_OFF * scale)
    # the plain truncation |k| <= 2000: its error is at most |closed-form tail| + bound, which
    # is itself below 1e-11 relative here (tail ~ mu_1 sin^2(pi x)/(pi^2 omega_s^2 3 n_alias^3))
    assert np.all(np.abs(a.tail) <= 1e-11 * scale)
    assert np.all(np.abs(a.truncated - Hd) <= np.abs(a.tail) + a.tail_bound + ROUND_OFF * scale)
    # and the aliases matter: the k = 0 term alone misses by far more than the tolerance
    k0 = fe.continuous_frequency_response(model, f) * fe.ramp_bias(f, 1 / fs)[:, None, None]
    assert np.max(np.abs(k0 - Hd) / scale) > 1e3 * ROUND_OFF


def test_ramp_plain_truncation_converges():
    """Without the closed-form tail (n_moments = 0) the plain truncation |k| <= 20000 still meets
    1e-8; its rigorous bound (no credit for the cancellation inside a conjugate pair) is looser."""
    model, fs = _p2_model(), 5.0
    f = _grid(fs, 21)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "ramp")
    a = fe.alias_sum(model, 1 / fs, f, "ramp", n_alias=20000, n_moments=0)
    assert np.all(a.tail_bound <= 1e-7 * np.abs(Hd))
    assert np.all(np.abs(a.value - Hd) <= a.tail_bound + ROUND_OFF * np.abs(Hd))
    assert np.max(np.abs(a.value - Hd) / np.abs(Hd)) < 1e-8


@pytest.mark.parametrize("quantity", ["velocity", "acceleration"])
def test_ramp_alias_sum_with_direct_term(quantity):
    """Velocity and acceleration add a direct term, which passes unchanged (sum sinc^2 = 1)."""
    model, fs = _p2_model(), 5.0
    f = _grid(fs)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "ramp", quantity)
    a = fe.alias_sum(model, 1 / fs, f, "ramp", quantity, n_alias=2000)
    scale = np.abs(Hd[1:])  # f = 0: velocity and acceleration are 0 there
    assert np.all(np.abs(a.value - Hd)[1:] <= a.tail_bound[1:] + ROUND_OFF * scale)


def test_ramp_low_frequency_is_continuous_times_sinc2():
    """For f <= 0.05 fs the k != 0 terms are bounded a priori by
    2 sin^2(pi x)/pi^2 sum_terms |c| sum_{k>=1} 1/((k - x)^2 ((k - x) omega_s - |p|)),
    and that bound is small: H_ramp ~ H(j omega) sinc^2(f/fs), a zero-phase bias."""
    for model, fs in ((_p2_model(), 50.0), (_one_dof(), 50.0), (_p2_model(), 5.0)):
        x = np.linspace(0.001, 0.05, 25)
        f = x * fs
        Hd = fe.discrete_frequency_response(model, 1 / fs, f, "ramp")
        approx = fe.continuous_frequency_response(model, f) * fe.ramp_bias(f, 1 / fs)[:, None, None]
        poles, coeffs, _ = fe._pole_terms(model, "displacement")
        ws = 2 * np.pi * fs
        k = np.arange(1, 200001)[None, :]
        u = k - x[:, None]
        per_pole = [np.sum(1 / (u**2 * (u * ws - abs(p))), axis=1) + 1 / (ws * 2e5**2)
                    for p in poles]  # + the integral bound of k > 200000
        bound = (2 * np.sin(np.pi * x)[:, None, None] ** 2 / np.pi**2
                 * np.einsum("rf,roi->foi", np.array(per_pole), np.abs(coeffs)))
        assert np.all(np.abs(Hd - approx) <= bound * (1 + 1e-9) + 1e-14 * np.abs(Hd))
        assert np.max(bound / np.abs(approx)) < 2e-2


def test_ramp_bias():
    fs = 100.0
    b = fe.ramp_bias([0.0, 25.0, 50.0, 100.0, 1.0], 1 / fs)
    np.testing.assert_allclose(b[:3], [1.0, (np.sin(np.pi / 4) / (np.pi / 4)) ** 2, 4 / np.pi**2],
                               rtol=1e-15)
    assert abs(b[3]) < 1e-30  # zero at fs
    z = np.pi * 0.01  # sinc^2 = 1 - z^2/3 + 2 z^4/45 - z^6/315 + ...
    assert abs(b[4] - (1 - z**2 / 3 + 2 * z**4 / 45 - z**6 / 315)) < 1e-15


# --- step invariant: half-sample lag --------------------------------------------------------
@pytest.mark.parametrize("name", ["P2", "1-DOF"])
def test_step_invariant_alias_sum(name):
    model, fs = MODELS[name](), 5.0
    f = _grid(fs)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "step")
    a = fe.alias_sum(model, 1 / fs, f, "step", n_alias=2000)
    assert np.all(a.tail_bound <= 1e-10 * np.abs(Hd))
    assert np.all(np.abs(a.value - Hd) <= a.tail_bound + ROUND_OFF * np.abs(Hd))


@pytest.mark.parametrize("fs", [50.0, 20.0])
@pytest.mark.parametrize("name", ["P2", "1-DOF"])
def test_step_invariant_phase_is_half_sample_lag(name, fs):
    """arg(H_step / H) = -pi f/fs + delta with |delta| <= arcsin(eps),
    eps = sum_{k != 0} |H(j(omega + k omega_s))| |sinc(x + k)| / |H(j omega) sinc(x)|
    (the aliases relative to the k = 0 term H(j omega) e^{-j pi x} sinc(x)); eps is computed
    with |k| <= 2000 and the rigorous tail bound sum |c| 2|sin(pi x)|/(pi U (omega_s - |p|/U))."""
    model = MODELS[name]()
    x = np.linspace(0.002, 0.05, 25)
    f = x * fs
    H = fe.continuous_frequency_response(model, f)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "step")
    ws, N = 2 * np.pi * fs, 2000
    k = np.concatenate([np.arange(-N, 0), np.arange(1, N + 1)])
    aliases = np.zeros(H.shape)
    for kk in k:
        aliases += (np.abs(fe.continuous_frequency_response(model, f + kk * fs))
                    * np.abs(np.sin(np.pi * x) / (np.pi * (x + kk)))[:, None, None])
    poles, coeffs, _ = fe._pole_terms(model, "displacement")
    U = N - x
    tail = sum(np.abs(c)[None] * (2 * np.abs(np.sin(np.pi * x)) / (np.pi * U * (ws - abs(p) / U))
                                  )[:, None, None] for p, c in zip(poles, coeffs))
    eps = (aliases + tail) / (np.abs(H) * np.sinc(x)[:, None, None])
    assert np.all(eps < 0.05 * np.pi * x[:, None, None])  # the lag is resolved by the bound
    delta = np.angle(Hd / H) + np.pi * x[:, None, None]
    assert np.all(np.abs(delta) <= np.arcsin(eps) + 1e-12)


# --- impulse invariant: aliasing --------------------------------------------------------------
@pytest.mark.parametrize("quantity", ["displacement", "velocity"])
def test_impulse_invariant_alias_sum(quantity):
    """Plain alias sum plus (T/2) h(0+); h(0+) = M^-1 != 0 for velocity tests that term."""
    model, fs = _p2_model(), 5.0
    f = _grid(fs)
    Hd = fe.discrete_frequency_response(model, 1 / fs, f, "impulse", quantity)
    a = fe.alias_sum(model, 1 / fs, f, "impulse", quantity, n_alias=2000)
    scale = np.abs(Hd)
    assert np.all(a.tail_bound <= 1e-10 * scale)
    assert np.all(np.abs(a.value - Hd) <= a.tail_bound + ROUND_OFF * scale)
    # its plain truncation converges only like 1/n_alias (H ~ 1/s^2 without a damping kernel)
    assert np.max(np.abs(a.truncated - Hd) / scale) > 1e-6


def test_impulse_error_grows_toward_nyquist_and_is_system_dependent():
    fs = 20.0
    x = np.array([0.01, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5])
    f = x * fs
    err, ramp_dev = {}, {}
    systems = {"P2": _p2_model(outputs=[1]), "1-DOF": _one_dof(),
               "stiff 1-DOF": _one_dof(k=1200.0)}
    for name, model in systems.items():
        H = fe.continuous_frequency_response(model, f)[:, 0, 0]
        Hi = fe.discrete_frequency_response(model, 1 / fs, f, "impulse")[:, 0, 0]
        Hr = fe.discrete_frequency_response(model, 1 / fs, f, "ramp")[:, 0, 0]
        err[name] = np.abs(Hi - H) / np.abs(H)
        ramp_dev[name] = np.abs(Hr / (H * fe.ramp_bias(f, 1 / fs)) - 1)
    for name in ("P2", "1-DOF"):  # resonances well below fs/2: the error rises monotonically
        assert np.all(np.diff(err[name]) > 0), err[name]
        assert err[name][-1] > 1.0 and err[name][-1] > 100 * err[name][0]
    # stiff 1-DOF (resonance 3.9 Hz, 0.2 fs): large already at low f, still largest at fs/2
    assert err["stiff 1-DOF"][0] > 0.05 and err["stiff 1-DOF"][-1] == err["stiff 1-DOF"].max()
    # system dependent: at f = 0.01 fs the three differ by orders of magnitude ...
    low = sorted(e[0] for e in err.values())
    assert low[-1] > 100 * low[0]
    # ... while, for each of them, the ramp invariant's deviation from its known, system
    # independent bias is >= 1000x smaller there (it is O((f/fs)^2) times the aliases)
    for name in systems:
        assert ramp_dev[name][0] < 1e-3 * err[name][0]


# --- truncation --------------------------------------------------------------------------------
def _p3():
    return chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)


def test_truncation_error_p3_five_of_fifteen_modes():
    M, C, K = _p3()
    f = np.linspace(0.0, 30.0, 3001)  # the 15 undamped resonances lie in 1.5..23.6 Hz
    r = fe.truncation_error(M, C, K, [14], [0, 14], [0, 1, 2, 3, 4], f)
    assert r.n_modes == 15 and r.kept == (0, 1, 2, 3, 4)
    assert np.isfinite(r.max_relative) and r.max_relative > 0
    assert r.peak_relative > 0 and r.static_relative > 0
    # static residual against K^-1 (an independent truth) minus the kept modes' sum at 0
    full0 = np.linalg.inv(K)[np.ix_([0, 14], [14])]
    kept0 = modal_model(M, C, K, [14], [0, 14], modes=range(5)).frequency_response([0.0])[0].real
    np.testing.assert_allclose(r.static_residual, full0 - kept0, rtol=1e-9,
                               atol=1e-12 * np.abs(full0).max())
    assert r.static_residual.shape == (2, 1) and np.all(np.abs(r.static_residual) > 0)
    d = r.as_dict()
    assert d["max_relative"] == r.max_relative and len(d["static_residual"]) == 2


def test_truncation_error_zero_with_all_modes():
    M, C, K = _p3()
    f = np.linspace(0.0, 30.0, 301)
    for q in ("displacement", "acceleration"):
        r = fe.truncation_error(M, C, K, [14], [0, 14], range(15), f, quantity=q)
        assert r.max_relative == 0 and r.peak_relative == 0 and r.static_relative == 0
        assert np.all(r.static_residual == 0)


def test_truncation_error_decreases_with_more_modes():
    M, C, K = _p3()
    C = 1e-3 * K  # light damping: finite peaks
    f = np.linspace(0.0, 5.0, 501)  # band of the first two modes
    errs = [fe.truncation_error(M, C, K, [14], [14], range(n), f).peak_relative
            for n in (3, 6, 10, 14)]
    assert all(b < a for a, b in zip(errs, errs[1:])), errs


# --- input checking ----------------------------------------------------------------------------
def test_bad_input():
    model = _p2_model()
    with pytest.raises(ValueError, match="invariant"):
        fe.discrete_frequency_response(model, 0.1, [1.0], "cubic")
    with pytest.raises(ValueError, match="quantity"):
        fe.continuous_frequency_response(model, [1.0], "jerk")
    with pytest.raises(ValueError, match="dt"):
        fe.ramp_bias([1.0], 0.0)
    with pytest.raises(ValueError, match="freqs_hz"):
        fe.discrete_frequency_response(model, 0.1, [np.nan], "ramp")
    with pytest.raises(ValueError, match="n_moments"):
        fe.alias_sum(model, 0.1, [1.0], "impulse", n_moments=0)
    with pytest.raises(ValueError, match="n_alias"):
        fe.alias_sum(_one_dof(k=1e8), 1, [0.1], "ramp", n_alias=2)
