"""Modal digital filters: derivation, sections, and responses against independent truths."""
import mpmath
import numpy as np
import pytest
import scipy.signal as sig
import sympy as sp

from dtdyn.derive import modal_filters as D
from dtdyn.generated import modal_filters as G
from dtdyn.runtime.chain import chain_matrices
from dtdyn.runtime.discretize import first_order_form
from dtdyn.runtime.exact import exact_response
from dtdyn.runtime.modal import modal_model
from dtdyn.runtime.modal_filters import modal_filter_response, run_bank, sections, to_sos

from problems import P2, P3


# --- tier 1: the derivation equals the published closed forms -----------------------------
def test_invariants_equal_reference_formulas():
    s, T, R = D.s, D.T, D.R
    step, imp, ramp = (D.derive_invariant(n) for n in ("step", "impulse", "ramp"))
    assert sp.simplify(step.c0 - R * (sp.exp(s * T) - 1) / s) == 0 and step.c1 == 0
    assert imp.c0 == 0 and sp.simplify(imp.c1 - T * R) == 0
    N0 = R * (sp.exp(s * T) - 1 - s * T) / (s**2 * T)  # weight of x_n in y_n (reference)
    N1 = R * (1 + (s * T - 1) * sp.exp(s * T)) / (s**2 * T)  # weight of x_{n-1}
    assert sp.simplify(ramp.c1 - N0) == 0 and sp.simplify(ramp.c0 - N1) == 0


def test_pair_sections_equal_matlab_lines():
    """B = 2 conv(real N, real D) + 2 conv(imag N, imag D), A = real(conv(D, conj D))."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        S = complex(-rng.uniform(0.01, 5), rng.uniform(1, 300))
        Rr = complex(*rng.standard_normal(2))
        T = rng.uniform(1e-4, 1e-2)
        N = Rr / S / S / T * np.array([-1 - S * T + np.exp(S * T), 1 + (S * T - 1) * np.exp(S * T)])
        Dd = np.array([1, -np.exp(S * T)])
        B = 2 * np.convolve(N.real, Dd.real) + 2 * np.convolve(N.imag, Dd.imag)
        A = np.real(np.convolve(Dd, np.conj(Dd)))
        b0, b1, b2, a1, a2 = G.pair_sections("ramp", np.array([S]), np.array([Rr]), T)
        np.testing.assert_allclose([b0[0], b1[0], b2[0]], B, rtol=1e-9, atol=1e-15 * np.abs(B).max())
        np.testing.assert_allclose([1, a1[0], a2[0]], A, rtol=1e-13)


def test_phi_functions_accurate_for_small_arguments():
    z = np.array([1e-8 + 1e-6j, 0.3 - 0.9j, 0.99j, 1.5 + 2j, -40 + 3j])
    p1, p2 = G.phi(z)
    mpmath.mp.dps = 40  # oracle in 40-digit arithmetic
    zm = [mpmath.mpc(v.real, v.imag) for v in z]
    ref1 = [complex(mpmath.expm1(v) / v) for v in zm]
    ref2 = [complex((mpmath.expm1(v) - v) / v**2) for v in zm]
    np.testing.assert_allclose(p1, ref1, rtol=1e-14)
    np.testing.assert_allclose(p2, ref2, rtol=1e-14)


# --- tier 2/3: the bank against scipy.signal.cont2discrete and exact_response ----------------
def _bank_tf(sos, direct_value, zs):
    out = np.full(zs.shape, direct_value, dtype=complex)
    for b0, b1, b2, a1, a2 in sos:
        w = 1 / zs
        out += (b0 + b1 * w + b2 * w * w) / (1 + a1 * w + a2 * w * w)
    return out


def _system(prob):
    return chain_matrices(prob["mass"], prob["stiffness"], prob["damping"], sparse=False)


@pytest.mark.parametrize("invariant, method", [("step", "zoh"), ("ramp", "foh"),
                                               ("impulse", "impulse")])
@pytest.mark.parametrize("name", ["P2", "P3", "single"])
def test_bank_equals_cont2discrete(invariant, method, name):
    if name == "single":
        M, C, K = np.array([[2.0]]), np.array([[3.0]]), np.array([[12.0]])  # P1
    else:
        M, C, K = _system({"P2": P2, "P3": P3}[name])
        if name == "P3":
            C = 1e-3 * K  # P3 is undamped; a light damping keeps the continuous TF finite
    n = M.shape[0]
    fs = 200.0 if name != "P3" else 2000.0
    model = modal_model(M, C, K, inputs=[n - 1], outputs=[0])
    sos, _, _, direct = sections(model, fs, invariant)
    A, B = first_order_form(M, C, K)
    Cm = np.zeros((1, 2 * n))
    Cm[0, 0] = 1.0
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((A, B[:, [n - 1]], Cm, np.zeros((1, 1))), 1 / fs,
                                          method=method)
    zs = np.exp(1j * 2 * np.pi * np.array([0.1, 1.0, 3.0, 10.0, 40.0]) / fs)
    ours = _bank_tf(sos, direct[0, 0], zs)
    ref = np.array([(Cd @ np.linalg.solve(z * np.eye(2 * n) - Ad, Bd) + Dd)[0, 0] for z in zs])
    np.testing.assert_allclose(ours, ref, rtol=1e-11, atol=1e-12 * np.abs(ref).max())


def _ramp_force(n, fs, seed=0):
    """A piecewise-linear force that starts at zero (the filters start at rest)."""
    rng = np.random.default_rng(seed)
    f = rng.standard_normal(n)
    f[0] = 0.0
    return f


@pytest.mark.parametrize("quantity, key", [("displacement", "x"), ("velocity", "v"),
                                           ("acceleration", "a")])
@pytest.mark.parametrize("name", ["P2", "P3"])
def test_ramp_invariant_equals_exact(name, quantity, key):
    prob = {"P2": P2, "P3": P3}[name]
    M, C, K = _system(prob)
    n = M.shape[0]
    fs, N = (50.0, 2000) if name == "P2" else (1000.0, 2000)
    f = _ramp_force(N, fs)[:, None]
    r = modal_filter_response(f, fs, M, C, K, inputs=[n - 1], outputs=list(range(n)),
                              quantity=quantity)
    ex = exact_response(M, C, K, f, 1 / fs, N - 1, loaded=[n - 1])
    got, ref = getattr(r, key), getattr(ex, key)
    assert np.max(np.abs(got - ref)) / np.max(np.abs(ref)) < 1e-10


def test_non_proportional_damping():
    """5 DOFs, one discrete damper between DOFs 1 and 3: complex modes, still exact."""
    M, _, K = chain_matrices(np.ones(5), np.full(5, 1e3), np.zeros(5), sparse=False)
    C = np.zeros((5, 5))
    C[np.ix_([1, 3], [1, 3])] = 4.0 * np.array([[1, -1], [-1, 1]])
    C[0, 0] += 0.5
    fs, N = 200.0, 3000
    f = _ramp_force(N, fs, seed=2)[:, None]
    r = modal_filter_response(f, fs, M, C, K, inputs=[4], outputs=[0, 2, 4])
    ex = exact_response(M, C, K, f, 1 / fs, N - 1, loaded=[4], outputs=[0, 2, 4])
    assert np.max(np.abs(r.x - ex.x)) / np.max(np.abs(ex.x)) < 1e-10


def test_step_and_impulse_errors_follow_theory():
    """For a smooth force: ramp error O(T^2); step O(T), being the response half a sample late
    (compared with the truth at t + T/2 it is O(T^2)). The impulse invariant is the rectangle
    rule T sum h(t_n - t_k) x_k; for displacement h(0) = sum 2 Re R_r = 0 and x_0 = 0 here, so
    it equals the trapezoid rule: O(T^2), its error being the aliasing of h."""
    M, C, K = _system(P2)
    errs = {"ramp": [], "step": [], "step shifted": [], "impulse": []}
    fss = [50.0, 100.0, 200.0, 400.0]
    for fs in fss:
        t = np.arange(int(8 * fs)) / fs
        force = lambda tt: np.sin(2.1 * tt) ** 3  # noqa: E731  smooth, zero at t = 0
        fine = int(8 * fs) * 16
        tf = np.arange(fine) / (16 * fs)
        ex = exact_response(M, C, K, force(tf)[:, None], 1 / (16 * fs), fine - 1, loaded=[1],
                            outputs=[0])
        truth = ex.x[::16, 0]
        truth_half = ex.x[8::16, 0]
        for inv in ("ramp", "step", "impulse"):
            r = modal_filter_response(force(t)[:, None], fs, M, C, K, [1], [0], invariant=inv)
            y = r.x[:, 0]
            if inv == "step":
                e = np.max(np.abs(y[1:] - truth_half[:len(y) - 1])) / np.max(np.abs(truth))
                errs["step shifted"].append(e)
            errs[inv].append(np.max(np.abs(y - truth)) / np.max(np.abs(truth)))
    slope = {k: -np.polyfit(np.log(fss), np.log(v), 1)[0] for k, v in errs.items()}
    assert abs(slope["ramp"] - 2) < 0.2 and abs(slope["step shifted"] - 2) < 0.2, slope
    assert abs(slope["step"] - 1) < 0.2 and abs(slope["impulse"] - 2) < 0.2, slope


def test_sos_export_and_backends_agree():
    M, C, K = _system(P2)
    model = modal_model(M, C, K, inputs=[1], outputs=[0, 1])
    fs = 100.0
    f = _ramp_force(5000, fs, seed=4)[:, None]
    sos, in_col, out_col, direct = sections(model, fs)
    y_c = run_bank(sos, in_col, out_col, direct, f, 2, backend="c")
    y_np = run_bank(sos, in_col, out_col, direct, f, 2, backend="numpy")
    np.testing.assert_allclose(y_c, y_np, rtol=0, atol=1e-12 * np.abs(y_np).max())
    rows = to_sos(model, fs, output=1, input=0)
    y_sp = sum(sig.sosfilt(row[None, :], f[:, 0]) for row in rows)
    np.testing.assert_allclose(y_c[:, 1], y_sp, rtol=0, atol=1e-12 * np.abs(y_sp).max())


def test_mode_selection_keeps_only_those_sections():
    M, C, K = _system(P3)
    C = 1e-3 * K
    r_all = modal_filter_response(_ramp_force(100, 1000.0)[:, None], 1000.0, M, C, K, [14], [14])
    r_two = modal_filter_response(_ramp_force(100, 1000.0)[:, None], 1000.0, M, C, K, [14], [14],
                                  modes=[0, 1])
    assert r_all.info["sections"] == 15 and r_two.info["sections"] == 2


@pytest.mark.parametrize("kw, words", [
    (dict(fs=0.0), ["fs"]), (dict(fs=-1.0), ["fs"]),
    (dict(force=np.array([[0.0], [np.nan], [1.0]])), ["force[1, 0]", "nan"]),
    (dict(invariant="cubic"), ["invariant", "'cubic'"]),
    (dict(quantity="jerk"), ["quantity", "'jerk'"]),
    (dict(force=np.ones((5, 2))), ["force", "(5, 2)"]),
])
def test_bad_input(kw, words):
    M, C, K = _system(P2)
    args = dict(force=np.ones((5, 1)), fs=100.0, M=M, C=C, K=K, inputs=[1], outputs=[0])
    args.update(kw)
    with pytest.raises(ValueError) as exc:
        modal_filter_response(**args)
    for w in words:
        assert w in str(exc.value)
