"""Modal digital filters: derivation, sections, and responses against independent truths."""
import mpmath
import numpy as np
import pytest
import scipy.signal as sig
import sympy as sp

from dtdyn import problem
from dtdyn.derive import modal_filters as D
from dtdyn.generated import modal_filters as G
from dtdyn.linear._chain import chain_matrices
from dtdyn.linear._discretize import first_order_form
from dtdyn.linear._exact import exact_response
from dtdyn.modal._model import from_poles_residues, modal_model
from dtdyn.modal._filters import (_c_modes, modal_filter_response, modal_states, run_bank,
                                 run_modes, sections, to_sos)

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
        np.testing.assert_allclose([b0[0], b1[0], b2[0]], B, rtol=1e-9,
                                   atol=1e-15 * np.abs(B).max())
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
    model = modal_model(M, C, K, force_dofs=[n - 1], outputs=[0])
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


@pytest.mark.parametrize("method", ["modes", "sections"])
@pytest.mark.parametrize("quantity, key", [("displacement", "x"), ("velocity", "v"),
                                           ("acceleration", "a")])
@pytest.mark.parametrize("name", ["P2", "P3"])
def test_ramp_invariant_equals_exact(name, quantity, key, method):
    """All modes, all outputs: the ramp invariant is exact for a piecewise-linear force."""
    prob = {"P2": P2, "P3": P3}[name]
    M, C, K = _system(prob)
    n = M.shape[0]
    fs, N = (50.0, 2000) if name == "P2" else (1000.0, 2000)
    f = _ramp_force(N, fs)[:, None]
    r = modal_filter_response(M, C, K, f, 1 / fs, force_dofs=[n - 1], outputs=list(range(n)),
                              quantities=(key,), algorithm=method)
    assert r.info["filters"] == method
    ex = exact_response(M, C, K, f, 1 / fs, force_dofs=[n - 1])
    got, ref = getattr(r, key), getattr(ex, key)
    assert np.max(np.abs(got - ref)) / np.max(np.abs(ref)) < 1e-10


def _non_proportional():
    """5 DOFs, one discrete damper between DOFs 1 and 3 and one to ground: complex modes."""
    M, _, K = chain_matrices(np.ones(5), np.full(5, 1e3), np.zeros(5), sparse=False)
    C = np.zeros((5, 5))
    C[np.ix_([1, 3], [1, 3])] = 4.0 * np.array([[1, -1], [-1, 1]])
    C[0, 0] += 0.5
    return M, C, K


@pytest.mark.parametrize("method", ["modes", "sections"])
@pytest.mark.parametrize("inputs", [[4], [1, 4]])
def test_non_proportional_damping(inputs, method):
    """Complex modes, one or two inputs (two: the residues are factored by their SVD), still
    exact."""
    M, C, K = _non_proportional()
    fs, N = 200.0, 3000
    rng = np.random.default_rng(2)
    f = rng.standard_normal((N, len(inputs)))
    f[0] = 0.0
    r = modal_filter_response(M, C, K, f, 1 / fs, force_dofs=inputs, outputs=[0, 2, 4],
                              algorithm=method, quantities=("x",))
    ex = exact_response(M, C, K, f, 1 / fs, force_dofs=inputs, outputs=[0, 2, 4])
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
        ex = exact_response(M, C, K, force(tf)[:, None], 1 / (16 * fs), force_dofs=[1], outputs=[0])
        truth = ex.x[::16, 0]
        truth_half = ex.x[8::16, 0]
        for inv in ("ramp", "step", "impulse"):
            r = modal_filter_response(M, C, K, force(t)[:, None], 1 / fs, force_dofs=[1],
                                      outputs=[0], invariant=inv, quantities=("x",))
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
    model = modal_model(M, C, K, force_dofs=[1], outputs=[0, 1])
    fs = 100.0
    f = _ramp_force(5000, fs, seed=4)[:, None]
    sos, in_col, out_col, direct = sections(model, fs)
    y_c = run_bank(sos, in_col, out_col, direct, f, 2, backend="c")
    y_np = run_bank(sos, in_col, out_col, direct, f, 2, backend="numpy")
    np.testing.assert_allclose(y_c, y_np, rtol=0, atol=1e-12 * np.abs(y_np).max())
    rows = to_sos(model, 1 / fs, output=1, input=0)
    y_sp = sum(sig.sosfilt(row[None, :], f[:, 0]) for row in rows)
    np.testing.assert_allclose(y_c[:, 1], y_sp, rtol=0, atol=1e-12 * np.abs(y_sp).max())


# --- the per-mode form ------------------------------------------------------------------------
def test_increment_form_equals_complex_recursion():
    """The real increments of the derivation reproduce (1 + d) eta + g0 x_a + g1 x_b."""
    inc = D.increment_form()
    syms = (D.e_re, D.e_im, D.d_re, D.d_im, D.g0r, D.g0i, D.g1r, D.g1i, D.xa, D.xb)
    f_re, f_im = (sp.lambdify(syms, inc[k]) for k in ("e_re", "e_im"))
    rng = np.random.default_rng(3)
    for _ in range(20):
        er, ei, dr, di, g0r, g0i, g1r, g1i, xa, xb = rng.standard_normal(10)
        want = (1 + complex(dr, di)) * complex(er, ei) + complex(g0r, g0i) * xa + \
            complex(g1r, g1i) * xb
        args = (er, ei, dr, di, g0r, g0i, g1r, g1i, xa, xb)
        got = complex(er + f_re(*args), ei + f_im(*args))
        assert abs(got - want) <= 1e-14 * (1 + abs(want))


def test_increment_is_accurate_for_small_pole_angles():
    """d = e^{sT} - 1 to full relative precision where 1 + d would lose it (mpmath oracle)."""
    poles = np.array([-1e-3 + 0.5j, -2.0 + 30.0j, -7.0])
    model = from_poles_residues(poles, np.array([1.0 + 1j, 2j, 3.0]))
    mpmath.mp.dps = 40
    for fs in (1e3, 1e6):
        st = modal_states(model, fs)
        for s, d in zip(st.poles, st.increment):
            ref = complex(mpmath.expm1(mpmath.mpc(s.real, s.imag) / fs))
            assert abs(d - ref) <= 4e-16 * abs(ref)


def _overdamped():
    """Two real poles beside two lightly damped pairs (as in test_hard_cases)."""
    return chain_matrices([1.0, 1.0, 0.5], [1e4, 1e4, 1e2], [0.5, 0.5, 400.0], sparse=False)


@pytest.mark.parametrize("invariant", ["ramp", "step", "impulse"])
@pytest.mark.parametrize("quantity", ["displacement", "acceleration"])
@pytest.mark.parametrize("case", ["P2", "P3 undamped", "P3 damped", "non-proportional, 2 inputs",
                                  "overdamped"])
def test_modes_equal_sections(case, quantity, invariant):
    """The per-mode form (C and lfilter) equals the section bank to round-off, 2,000 samples:
    measured <= 3e-13 except P3 (~2e-12: the bank's rounded a1 = -2 cos(omega T) moves mode 1,
    omega T = 9.5e-3, by ~ eps / (omega T)^2 relative, see test_long_undamped_record_...). The
    cases' 2, 15, 4 and 5 states run the C kernel's chunks of 4, 16, 4 and 8 states."""
    if case == "P2":
        (M, C, K), inputs, outputs, fs = _system(P2), [1], [0, 1], 50.0
    elif case.startswith("P3"):
        M, C, K = _system(P3)
        C = 1e-3 * K if case == "P3 damped" else C
        inputs, outputs, fs = [14], list(range(15)), 1000.0
    elif case == "overdamped":
        (M, C, K), inputs, outputs, fs = _overdamped(), [2], [0, 1, 2], 500.0
    else:
        (M, C, K), inputs, outputs, fs = _non_proportional(), [1, 4], [0, 2, 4], 200.0
    model = modal_model(M, C, K, inputs, outputs)
    f = np.random.default_rng(7).standard_normal((2000, len(inputs)))
    bank = run_bank(*sections(model, fs, invariant, quantity), f, len(outputs))
    st = modal_states(model, fs, invariant, quantity)
    assert st.n_states == model.n_modes  # rank-one residues: one state per mode
    chunk = {"P2": 4, "overdamped": 4, "non-proportional, 2 inputs": 8}.get(case, 16)
    assert _c_modes() is None or _c_modes()[1](st.n_states) == chunk
    scale = np.abs(bank).max()
    for backend in ("c", "numpy"):
        np.testing.assert_allclose(run_modes(st, f, backend), bank, rtol=0, atol=5e-12 * scale)


def test_real_mode_shapes_use_real_weights():
    """Undamped or proportionally damped: the weights are real (the C kernel then forms the
    outputs from the real parts only); complex modes keep complex weights."""
    for C_of in (lambda K: 0 * K, lambda K: 1e-3 * K):
        M, _, K = _system(P3)
        st = modal_states(modal_model(M, C_of(K), K, [14], list(range(15))), 1000.0)
        assert not np.any(st.weights.imag)
    M, C, K = _non_proportional()
    st = modal_states(modal_model(M, C, K, [4], [0, 2, 4]), 200.0)
    assert np.any(st.weights.imag)


def test_modes_of_general_residues():
    """Residues of rank two (e.g. identified from measurements) and a zero residue: one state
    per rank-one factor; the per-mode form still equals the bank."""
    rng = np.random.default_rng(11)
    poles = np.array([-0.5 + 20j, -1.0 + 45j, -3.0 + 80j, -60.0])
    R = rng.standard_normal((4, 3, 2)) + 1j * rng.standard_normal((4, 3, 2))
    R[1] = 0.0
    R[3] = R[3].real
    model = from_poles_residues(poles, R, force_dofs=[0, 1], outputs=[0, 1, 2])
    fs = 400.0
    st = modal_states(model, fs)
    assert st.n_states == 6  # two factors per rank-two residue, none for the zero one
    for r in range(4):
        j = st.mode == r
        np.testing.assert_allclose(np.einsum("jo,ji->oi", st.weights[j], st.inputs[j]),
                                   (2.0 if model.oscillatory[r] else 1.0) * model.residues[r],
                                   atol=1e-14 * np.abs(R).max())
    f = rng.standard_normal((1500, 2))
    bank = run_bank(*sections(model, fs), f, 3)
    for backend in ("c", "numpy"):
        np.testing.assert_allclose(run_modes(st, f, backend), bank, rtol=0,
                                   atol=1e-12 * np.abs(bank).max())


def test_long_undamped_record_does_not_drift():
    """P3 undamped, 1,000,000 samples (500 s, 4,700 periods of mode 1) after a unit triangle
    pulse (f_1 = 1): the free vibration y(nT) = sum_r 2 Re(R_r e^{s_r nT} (1 - e^{-s_r T})^2 /
    (s_r^2 T)), n >= 2, evaluated in 40-digit arithmetic from the model's poles and residues
    (the ramp invariant is exact for this force), is reproduced to 1e-11 (measured 7e-13). The
    lfilter fallback, whose pole is e^{sT} itself, reaches 2e-11 (bound 1e-10), and the section
    bank 6e-9: its a1 = -2 cos(omega T) carries a frequency error ~ eps / (omega T)^2."""
    M, C, K = _system(P3)
    fs, N = 2000.0, 1_000_000
    f = np.zeros((N, 1))
    f[1, 0] = 1.0
    r = modal_filter_response(M, C, K, f, 1 / fs, force_dofs=[14], outputs=[0, 14],
                              algorithm="modes", quantities=("x",))
    model = modal_model(M, C, K, [14], [0, 14])
    mpmath.mp.dps = 40
    T = mpmath.mpf(1) / 2000
    idx = np.unique(np.r_[np.linspace(2, N - 1, 40).astype(int), N - 5:N])
    ref = np.zeros((idx.size, 2))
    for s, R in zip(model.poles, model.residues[:, :, 0]):
        sm = mpmath.mpc(s.real, s.imag)
        F = (1 - mpmath.exp(-sm * T)) ** 2 / (sm * sm * T)
        for k, n in enumerate(idx):
            w = mpmath.exp(sm * n * T) * F
            ref[k] += [2 * float((mpmath.mpc(Ro.real, Ro.imag) * w).real) for Ro in R]
    err = np.max(np.abs(r.x[idx] - ref)) / np.max(np.abs(ref))
    assert err < (1e-11 if r.info["backend"] == "c" else 1e-10), err


def test_auto_algorithm_and_bad_algorithm():
    """algorithm="auto" picks the per-mode form for P3 with all outputs; unknown methods are
    refused."""
    M, C, K = _system(P3)
    f = _ramp_force(500, 1000.0)[:, None]
    r = modal_filter_response(M, C, K, f, 0.001, force_dofs=[14], outputs=list(range(15)),
                              quantities=("x",))
    assert r.info["filters"] == "modes" and r.info["states"] == 15
    with pytest.raises(ValueError, match="algorithm must be one of"):
        modal_filter_response(M, C, K, f, 0.001, force_dofs=[14], outputs=[14],
                              algorithm="fast", quantities=("x",))


def test_mode_selection_keeps_only_those_sections():
    M, C, K = _system(P3)
    C = 1e-3 * K
    r_all = modal_filter_response(M, C, K, _ramp_force(100, 1000.0)[:, None], 0.001,
                                  force_dofs=[14], outputs=[14], quantities=("x",))
    r_two = modal_filter_response(M, C, K, _ramp_force(100, 1000.0)[:, None], 0.001,
                                  force_dofs=[14], outputs=[14], modes=[0, 1], algorithm="modes",
                                  quantities=("x",))
    assert r_all.info["sections"] == 15 and r_two.info["sections"] == 2
    assert r_two.info["modes"] == 2 and r_two.info["states"] == 2


@pytest.mark.parametrize("kw, words", [
    (dict(dt=0.0), ["dt"]), (dict(dt=-1.0), ["dt"]),
    (dict(force=np.array([[0.0], [np.nan], [1.0]])), ["force[1, 0]", "nan"]),
    (dict(invariant="cubic"), ["invariant", "'cubic'"]),
    (dict(quantities=("jerk",)), ["quantities", "'jerk'"]),
    (dict(algorithm="fast"), ["algorithm", "'fast'"]),
    (dict(force=np.ones((5, 2))), ["force", "(5, 2)"]),
])
def test_bad_input(kw, words):
    M, C, K = _system(P2)
    args = dict(force=np.ones((5, 1)), dt=0.01, M=M, C=C, K=K, force_dofs=[1], outputs=[0],
                quantities=("x",))
    args.update(kw)
    with pytest.raises(ValueError) as exc:
        modal_filter_response(**args)
    for w in words:
        assert w in str(exc.value)


@pytest.mark.parametrize("method", ["modes", "sections"])
@pytest.mark.parametrize("quantity, key", [("displacement", "x"), ("velocity", "v"),
                                           ("acceleration", "a")])
def test_ramp_starts_at_rest_under_a_nonzero_first_sample(method, quantity, key):
    """P3 under a unit step plus a slow sine (f_0 = 1): at rest at t_0, like exact_response
    (without the correction the filters would start from a ramp at t_{-1}: 5e-3 here)."""
    P = problem("P3")
    dt, n = 1e-3, 800
    f = (1.0 + np.sin(0.01 * np.arange(n + 1)))[:, None]
    ex = exact_response(P["M"], P["C"], P["K"], f, dt, force_dofs=[14], outputs=[14, 3])
    r = modal_filter_response(P["M"], P["C"], P["K"], f, dt, force_dofs=[14], outputs=[14, 3],
                              algorithm=method, quantities=(key,))
    want = getattr(ex, key)
    assert np.abs(getattr(r, key) - want).max() <= 1e-10 * np.abs(want).max()


def test_initial_conditions_add_the_free_response():
    """x0, v0: the free response (residue sum, exact) plus the forced one equals exact_response
    with the same initial state: 1e-12 of the peak on P3 with light stiffness damping."""
    import dtdyn as dd

    p = dd.problem("P3")
    M, K = p["M"], p["K"]
    C = 1e-3 * K
    x0, v0 = np.linspace(0.0, 1e-3, 15), np.linspace(1e-2, 0.0, 15)
    f = np.sin(np.arange(2001) * 1e-3 * 30.0)
    a = dd.modal_filter_response(M, C, K, f, 1e-3, force_dofs=[14], x0=x0, v0=v0)
    b = dd.exact_response(M, C, K, f, 1e-3, force_dofs=[14], x0=x0, v0=v0)
    for q in "xva":
        ref = getattr(b, q)
        assert np.abs(getattr(a, q) - ref).max() <= 1e-12 * np.abs(ref).max(), q
    np.testing.assert_allclose(a.x[0], x0, atol=1e-15)
