"""Harmonic balance (dd.harmonic_balance) against independent truths.

Truths: the linear frequency response (a direct solve of K - w^2 M + i w C); the first-harmonic
Duffing relation [(k - m w^2) a + 3/4 k3 a^3]^2 + (c w a)^2 = F^2 (exact for a one-harmonic
balance: cos^3 = 3/4 cos + 1/4 cos 3, and 16 samples alias nothing into harmonic 1); periodic
orbits found by shooting (solve_ivp DOP853 at rtol 1e-12, Newton on the period map) with their
Floquet multipliers from the variational equations (the monodromy matrix); long runs of
nonlinear_mck_response started near the harmonic-balance orbit.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

import dtdyn as dd
from dtdyn import nonlinear_mck_response
from dtdyn.nonlinear._elements import BoucWen, Cubic, Law, element_matrix
from dtdyn.nonlinear._harmonic_balance import harmonic_balance, harmonic_balance_amplitude

# the Duffing oscillator of issue 31: m = 1, c = 0.02, k = 1, k3 = 0.5
C_D, K3, F_D = 0.02, 0.5, 0.1
RANGE = (0.05, 0.4)


def _duffing(harmonics, **kw):
    return harmonic_balance(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                            force_dofs=[0], force=[F_D], freqs_hz=RANGE,
                            harmonics=harmonics, **kw)


@pytest.fixture(scope="module")
def duffing7():
    return _duffing(7)


def _series(X, omega, t):
    """x(t) = Re sum_k X_k e^{i k omega t} for harmonics X (..., H + 1)."""
    k = np.arange(X.shape[-1])
    return np.real(np.exp(1j * omega * np.multiply.outer(t, k)) @ X.T)


def _shoot(M, C, K, cubic, F, f_dof, w, z0):
    """Periodic orbit by shooting: (initial state, the orbit's dense output, Floquet
    multipliers). ``cubic``: (i, j or None, k3) cubic springs."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)

    def forces(x):
        f, Kt = np.zeros(n), np.zeros((n, n))
        for i, j, k3 in cubic:
            lv = np.zeros(n)
            lv[i] = 1.0
            if j is not None:
                lv[j] = -1.0
            y = lv @ x
            f += lv * k3 * y**3
            Kt += np.outer(lv, lv) * 3 * k3 * y * y
        return f, Kt

    def rhs(t, z):
        x, v = z[:n], z[n:2 * n]
        fe, Kt = forces(x)
        p = np.zeros(n)
        p[f_dof] = F * np.cos(w * t)
        a = Minv @ (p - C @ v - K @ x - fe)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ (K + Kt), -Minv @ C]])
        Phi = z[2 * n:].reshape(2 * n, 2 * n)
        return np.concatenate([v, a, (A @ Phi).ravel()])

    T = 2 * np.pi / w
    I2 = np.eye(2 * n).ravel()

    def run(z, dense=False):
        return solve_ivp(rhs, (0, T), np.concatenate([z, I2]), method="DOP853", rtol=1e-12,
                         atol=1e-14, dense_output=dense)

    z = np.asarray(z0, dtype=float)
    for _ in range(20):            # Newton on the period map, its Jacobian the monodromy
        s = run(z, dense=True)
        Phi = s.y[2 * n:, -1].reshape(2 * n, 2 * n)
        dz = np.linalg.solve(Phi - np.eye(2 * n), s.y[:2 * n, -1] - z)
        z = z - dz
        if np.abs(dz).max() <= 1e-13 * np.abs(z).max():
            break
    s = run(z, dense=True)
    return z, s.sol, np.linalg.eigvals(s.y[2 * n:, -1].reshape(2 * n, 2 * n))


# ----------------------------------------------------------------------------------------------
# (a) linear elements: the linear frequency response


@pytest.mark.parametrize("receptance", ["modal", "direct"])
@pytest.mark.parametrize("element", [Cubic(1, 2, k3=0.0),
                                     Law(0, expression="k*x + c*v", k=40.0, c=0.5)])
def test_linear_elements_equal_the_linear_frequency_response(element, receptance):
    rng = np.random.default_rng(3)
    n = 4
    A = rng.standard_normal((n, n))
    M = np.eye(n) + 0.1 * A @ A.T
    K = np.diag([200.0, 300.0, 250.0, 150.0]) - 40.0 * (np.eye(n, k=1) + np.eye(n, k=-1))
    C = 0.002 * K + 0.1 * M
    F = np.array([1.0, 0.3 - 0.2j])
    r = harmonic_balance(M, C, K, elements=[element], force_dofs=[3, 1], force=F,
                         freqs_hz=(0.5, 4.0), harmonics=3, receptance=receptance)
    Kl, Cl = K.copy(), C.copy()
    if isinstance(element, Law):
        Kl[0, 0] += 40.0
        Cl[0, 0] += 0.5
    P = np.zeros((n, 2))
    P[[3, 1], [0, 1]] = 1.0
    for i, w in enumerate(r.omega):
        x1 = np.linalg.solve(Kl - w * w * M + 1j * w * Cl, P @ F)
        err = np.abs(r.harmonics[i, :, 1] - x1).max() / np.abs(x1).max()
        assert err < 1e-10, (i, w, err)
        assert np.abs(r.harmonics[i, :, [0, 2, 3]]).max() < 1e-10 * np.abs(x1).max()
        assert np.allclose(r.x_max[i], np.abs(x1), rtol=1e-10, atol=0)
    assert r.frequency_hz[0] == 0.5 and r.frequency_hz[-1] == 4.0
    assert np.all(np.diff(r.frequency_hz) > 0) and r.folds.size == 0 and r.stable.all()


# ----------------------------------------------------------------------------------------------
# (b) Duffing


def test_one_harmonic_duffing_satisfies_the_hand_relation_and_its_folds():
    r = _duffing(1)
    a, w = np.abs(r.harmonics[:, 0, 1]), r.omega
    res = ((1 - w**2) * a + 0.75 * K3 * a**3) ** 2 + (C_D * w * a) ** 2 - F_D**2
    assert np.abs(res).max() < 1e-9 * F_D**2
    assert r.folds.size == 2

    # hand folds: the local extrema of the upper root u+(a) = w^2 of the relation
    def u_plus(a):
        p = 1 + 0.75 * K3 * a * a
        b = 2 * p - C_D**2
        return 0.5 * (b + np.sqrt(b * b - 4 * (p * p - F_D**2 / (a * a))))
    a = np.linspace(0.05, 4.0, 200001)
    with np.errstate(invalid="ignore"):
        u = u_plus(a)
    d = np.diff(u)
    ext = np.flatnonzero(np.isfinite(d[1:]) & np.isfinite(d[:-1]) & (d[1:] * d[:-1] < 0)) + 1
    assert ext.size == 2          # the jump-up fold (local min of w), then the jump-down (max)
    hand = []
    for j, sign in zip(ext, (1, -1)):
        m = minimize_scalar(lambda x, sign=sign: sign * u_plus(x), bounds=(a[j - 1], a[j + 1]),
                            method="bounded", options=dict(xatol=1e-13))
        hand.append(np.sqrt(sign * m.fun) / (2 * np.pi))
    assert np.allclose(np.sort(r.fold_frequency_hz), np.sort(hand), rtol=1e-8, atol=0)


def test_duffing_equals_shooting_and_floquet(duffing7):
    """7 harmonics against shooting to 1e-6 of the amplitude, on every branch; Hill's exponents
    against the monodromy matrix's multipliers."""
    r = duffing7
    M, C, K = np.eye(1), np.array([[C_D]]), np.eye(1)
    picks = list(range(3, r.omega.size, max(1, r.omega.size // 12))) + list(r.folds + 1)
    for i in picks:
        w, X = r.omega[i], r.harmonics[i, 0]
        k = np.arange(X.size)
        z0 = [np.sum(X).real, np.sum(1j * k * w * X).real]
        z, sol, mu = _shoot(M, C, K, [(0, None, K3)], F_D, 0, w, z0)
        t = np.linspace(0, 2 * np.pi / w, 257)
        err = np.abs(sol(t)[0] - _series(X, w, t)).max() / r.x_max[i, 0]
        assert err < 1e-6, (r.frequency_hz[i], err)
        hill = np.sort(np.abs(np.exp(r.floquet_exponents[i] * 2 * np.pi / w)))
        assert np.allclose(hill, np.sort(np.abs(mu)), rtol=1e-6), (hill, mu)
        assert r.stable[i] == (np.abs(mu).max() < 1), (r.frequency_hz[i], mu)


def test_duffing_folds_bracket_the_unstable_branch(duffing7):
    r = duffing7
    assert r.folds.size == 2
    up, down = r.folds
    assert r.frequency_hz[up] > r.frequency_hz[down]     # jump-down fold at the higher frequency
    assert r.stable[:up - 1].all() and r.stable[down + 2:].all()
    assert not r.stable[up + 1:down].any()
    middle = r.x_max[up + 1:down, 0]
    assert middle.size > 3 and np.all(np.diff(middle) < 0)
    # converged in the harmonics: 7 and 11 give the same folds (the curve itself is checked
    # against shooting next to each fold in test_duffing_equals_shooting_and_floquet)
    eleven = _duffing(11)
    assert np.allclose(r.fold_frequency_hz, eleven.fold_frequency_hz, rtol=1e-7)


def test_duffing_against_long_time_integration(duffing7):
    """Started 1 % off the harmonic-balance orbit, nonlinear_mck_response settles on it at the
    stable points (upper and lower branch at 0.2 Hz, one beyond the folds) and leaves it on the
    unstable middle branch (for the upper or the lower branch, 13 % and 85 % away there).
    dt = T/400: modal_parabolic's error (w dt)^3 ~ 4e-6 and the force's linear interpolation
    (w dt)^2 / 12 ~ 2e-5 stay below 1e-3; 250 periods shrink the start's 1 % by the Floquet
    multiplier (<= 0.97 per period) to < 1e-5."""
    r = duffing7
    f = r.frequency_hz
    up, down = r.folds
    branch = [(0, up), (up, down), (down, f.size)]
    cases = [lo + int(np.argmin(np.abs(f[lo:hi] - 0.2))) for lo, hi in branch]
    cases.append(int(np.argmin(np.abs(f - 0.35))))
    for i in cases:
        w, X = r.omega[i], r.harmonics[i, 0]
        T = 2 * np.pi / w
        dt, periods = T / 400, 250
        t = np.arange(400 * periods + 1) * dt
        k = np.arange(X.size)
        x0 = 1.01 * np.sum(X).real
        v0 = np.sum(1j * k * w * X).real
        out = nonlinear_mck_response(np.eye(1), [[C_D]], np.eye(1), F_D * np.cos(w * t)[:, None],
                                     dt, force_dofs=[0], elements=[Cubic(0, k3=K3)],
                                     scheme="modal_parabolic", x0=[x0], v0=[v0],
                                     quantities=("x",))
        amp = np.abs(out.x[-401:, 0]).max()
        rel = abs(amp - r.x_max[i, 0]) / r.x_max[i, 0]
        if r.stable[i]:
            assert rel < 1e-3, (f[i], amp, r.x_max[i, 0])
        else:
            assert rel > 0.05, (f[i], amp, r.x_max[i, 0])


# ----------------------------------------------------------------------------------------------
# (c) two DOFs, a cubic spring between them


def test_two_dofs_cubic_between_dofs_against_shooting():
    M = np.diag([1.0, 0.5])
    K = np.array([[2.0, -1.0], [-1.0, 1.0]])
    C = 0.02 * M + 0.01 * K
    cubic = [(0, 1, 2.0)]
    r = harmonic_balance(M, C, K, elements=[Cubic(0, 1, k3=2.0), Cubic(1, k3=0.5)],
                         force_dofs=[0], force=[0.15], freqs_hz=(0.05, 0.35), harmonics=15)
    cubic.append((1, None, 0.5))
    direct = harmonic_balance(M, C, K, elements=[Cubic(0, 1, k3=2.0), Cubic(1, k3=0.5)],
                              force_dofs=[0], force=[0.15], freqs_hz=(0.05, 0.35),
                              harmonics=15, receptance="direct")
    n = min(r.omega.size, direct.omega.size)
    assert r.omega.size == direct.omega.size
    assert np.allclose(direct.harmonics[:n], r.harmonics[:n], rtol=0,
                       atol=1e-9 * np.abs(r.harmonics).max())
    assert r.folds.size >= 2
    picks = sorted(set(range(2, r.omega.size, max(1, r.omega.size // 5))) | set(r.folds + 1))
    for i in picks:
        w, X = r.omega[i], r.harmonics[i]
        k = np.arange(X.shape[1])
        z0 = np.concatenate([X.sum(axis=1).real, (X * 1j * k * w).sum(axis=1).real])
        z, sol, mu = _shoot(M, C, K, cubic, 0.15, 0, w, z0)
        t = np.linspace(0, 2 * np.pi / w, 257)
        err = np.abs(sol(t)[:2].T - _series(X, w, t)).max() / r.x_max[i].max()
        # the truncation error is of the size of the first harmonics left out, estimated by
        # the last two kept (odd harmonics only here: the laws are odd): 6e-6 at most here
        trunc = np.abs(X[:, -2:]).max() / r.x_max[i].max()
        assert err < 1e-7 + trunc, (r.frequency_hz[i], err, trunc)
        assert r.stable[i] == (np.abs(mu).max() < 1), (r.frequency_hz[i], mu)


def test_sweep_down_gives_the_same_curve_backwards():
    up = _duffing(1)
    down = harmonic_balance(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                            force_dofs=[0], force=[F_D], freqs_hz=RANGE[::-1], harmonics=1)
    assert down.frequency_hz[0] == RANGE[1] and down.frequency_hz[-1] == RANGE[0]
    assert down.folds.size == 2 and down.omega.size > 10
    assert np.allclose(np.sort(down.fold_frequency_hz), np.sort(up.fold_frequency_hz),
                       rtol=1e-9)
    a, w = np.abs(down.harmonics[:, 0, 1]), down.omega       # every point on the hand relation
    res = ((1 - w**2) * a + 0.75 * K3 * a**3) ** 2 + (C_D * w * a) ** 2 - F_D**2
    assert np.abs(res).max() < 1e-9 * F_D**2
    assert not down.stable[down.folds[0] + 1:down.folds[1]].any()


# ----------------------------------------------------------------------------------------------
# (d) bad inputs


def _call(**kw):
    args = dict(elements=[Cubic(0, k3=1.0)], force_dofs=[0], force=[1.0],
                freqs_hz=(0.1, 0.2))
    args.update(kw)
    return harmonic_balance(np.eye(1), [[0.1]], np.eye(1), **args)


@pytest.mark.parametrize("kw, match", [
    (dict(freqs_hz=(0.1,)), "freqs_hz"),
    (dict(freqs_hz=(0.1, 0.1)), "freqs_hz"),
    (dict(freqs_hz=(-1.0, 0.2)), "freqs_hz"),
    (dict(harmonics=0), "harmonics"),
    (dict(harmonics=2.5), "harmonics"),
    (dict(n_time=4, harmonics=3), "n_time"),
    (dict(force=[1.0, 2.0]), "force"),
    (dict(force=[0.0]), "force"),
    (dict(force=np.ones((1, 9)), harmonics=3), "force"),
    (dict(force=[[1j, 1.0]]), "force"),
    (dict(force=["a"]), "force"),
    (dict(force_dofs=[3]), "force_dofs"),
    (dict(outputs=[1]), "outputs"),
    (dict(elements=[]), "elements"),
    (dict(elements=[BoucWen(0, stiffness=1.0, beta=1.0, gamma=1.0)]), "internal states"),
    (dict(elements=[Cubic(2, k3=1.0)]), "elements"),
    (dict(receptance="fast"), "receptance"),
    (dict(stability="yes"), "stability"),
    (dict(step=-1.0), "step"),
    (dict(tol=0.0), "tol"),
])
def test_bad_inputs_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


def test_misspelled_keyword_is_named():
    with pytest.raises(TypeError, match="harmonics"):
        _call(harmonic=3)


def test_undamped_resonance_of_the_linear_part_is_a_newton_error():
    with pytest.raises((dd.NewtonError, ValueError)):
        harmonic_balance(np.eye(1), [[0.0]], np.eye(1), elements=[Cubic(0, k3=0.0)],
                         force_dofs=[0], force=[1.0], freqs_hz=(0.1, 0.3))


# ----------------------------------------------------------------------------------------------
# (e) models: chains, beams and shafts given as objects (the banded receptance)


def _chain8():
    n = 8
    return dd.Chain(np.full(n, 1.0), np.full(n, 400.0), np.full(n, 0.8),
                    ground_stiffness=np.full(n, 5.0))


def _beam():
    return dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=12, rayleigh=(2.0, 1e-5))


def _shaft():
    return dd.Shaft([1.0, 2.0, 1.5, 0.5], [1e4, 2e4, 2e4, 1e4], [1.0, 2.0, 2.0, 1.0])


@pytest.mark.parametrize("make, matrices", [
    (_chain8, lambda m: m.matrices(sparse=True)),
    (_beam, dd.beam_matrices),
    (_shaft, dd.shaft_matrices)])
def test_banded_receptance_equals_the_models_frequency_response(make, matrices):
    """The banded LU's receptances and their frequency derivative against the model's own
    frequency response (the chain's transfer matrices, the beam's node-block LU, the shaft's
    tree sweep) and a dense solve of dH/dw = -H (i C - 2 w M) H (a derivative of the inverse;
    a finite difference drowns in the stiff beam's rounding)."""
    from dtdyn.nonlinear._harmonic_balance import _bandwidth, _BandedReceptance
    model = make()
    M, C, K = matrices(model)
    n = M.shape[0]
    dofs = [n - 1, n // 2]
    L = element_matrix([Cubic(dofs[0], dofs[1], k3=1.0)], n)
    B = np.zeros((n, 1))
    B[dofs[0]] = 1.0
    rec = _BandedReceptance(M, C, K, L, np.array(dofs), B, _bandwidth(M, C, K))
    if isinstance(model, dd.Chain):
        w = np.array([3.0, 17.0, 40.0])
        Hf = dd.chain_frequency_response(model.m, model.k, model.c, w, dofs, dofs,
                                         ground_stiffness=model.kg)
    elif isinstance(model, dd.Beam):
        w = np.array([30.0, 170.0, 900.0])
        Hf = dd.beam_frequency_response(model, w, dofs, dofs)
    else:
        w = np.array([20.0, 110.0, 230.0])
        Hf = dd.shaft_frequency_response(model, w, dofs, dofs, exact=False)
    H, dH = rec(w)
    # rows: the element (dofs[0] - dofs[1]), then the outputs; columns: L^T, then the force
    expect_out = Hf[:, :, 0]                        # outputs per unit force at dofs[0]
    assert np.allclose(H[:, 1:, 1], expect_out, rtol=1e-10, atol=0)
    expect_el = Hf[:, 0, 0] - Hf[:, 1, 0]
    assert np.allclose(H[:, 0, 1], expect_el, rtol=1e-10, atol=0)
    Md, Cd, Kd = (A.toarray() for A in (M, C, K))
    cols = np.hstack([L.T, B])
    fd = np.array([-L @ np.linalg.solve(Kd - x * x * Md + 1j * x * Cd, 1j * Cd - 2 * x * Md)
                   @ np.linalg.solve(Kd - x * x * Md + 1j * x * Cd, cols) for x in w])
    assert np.allclose(dH, fd, rtol=1e-8, atol=1e-9 * np.abs(dH).max())


def test_chain_model_equals_its_matrices():
    """dd.Chain through the banded receptance against its dense matrices through the modal
    one (two independent receptances): harmonics, stability and folds."""
    chain = _chain8()
    kw = dict(elements=[Cubic(7, k3=300.0)], force_dofs=[7], force=[0.4],
              freqs_hz=(0.3, 1.2), harmonics=3, outputs=[0, 7])
    a = harmonic_balance(chain, **kw)
    M, C, K = (A.toarray() for A in chain.matrices(sparse=True))
    b = harmonic_balance(M, C, K, **kw)
    assert a.info["receptance"] == "banded" and b.info["receptance"] == "modal"
    assert a.omega.size == b.omega.size and a.folds.size == b.folds.size >= 2
    scale = np.abs(b.harmonics).max()
    assert np.abs(a.harmonics - b.harmonics).max() < 1e-9 * scale
    assert np.abs(a.omega - b.omega).max() < 1e-9 * b.omega.max()
    assert np.array_equal(a.stable, b.stable) and not a.stable.all()
    assert np.allclose(a.fold_frequency_hz, b.fold_frequency_hz, rtol=1e-9)


@pytest.mark.parametrize("make, matrices, dof, force, k3, band", [
    (_beam, dd.beam_matrices, "w12", 5.0, 2e11, (12.0, 30.0)),        # first mode 18.0 Hz
    (_shaft, dd.shaft_matrices, "main.3", 1.0, 2e6, (3.0, 9.0))])     # first mode 5.9 Hz
def test_beam_and_shaft_models_equal_their_matrices(make, matrices, dof, force, k3, band):
    """Through the model (banded LU, DOF names) and through its dense matrices (modal): the
    same curve, with its two folds, to 1e-9."""
    model = make()
    i = model.dof(dof)
    M, C, K = (A.toarray() for A in matrices(model))
    kw = dict(elements=[Cubic(i, k3=k3)], force=[force], freqs_hz=band, harmonics=3,
              stability=False)
    a = harmonic_balance(model, force_dofs=[dof], outputs=[dof], **kw)
    b = harmonic_balance(M, C, K, force_dofs=[i], outputs=[i], **kw)
    assert a.info["receptance"] == "banded" and b.info["receptance"] == "modal"
    assert a.omega.size == b.omega.size and a.folds.size == b.folds.size == 2
    assert np.abs(a.harmonics - b.harmonics).max() < 1e-9 * np.abs(b.harmonics).max()
    assert np.abs(a.omega - b.omega).max() < 1e-9 * b.omega.max()


def test_model_with_C_or_K_is_refused():
    with pytest.raises(ValueError, match="C and K"):
        harmonic_balance(_chain8(), np.eye(8), None, elements=[Cubic(7, k3=1.0)],
                         force_dofs=[7], force=[1.0], freqs_hz=(0.1, 0.2))
    with pytest.raises(ValueError, match="C and K are required"):
        harmonic_balance(np.eye(1), elements=[Cubic(0, k3=1.0)], force_dofs=[0], force=[1.0],
                         freqs_hz=(0.1, 0.2))


# ----------------------------------------------------------------------------------------------
# (f) base excitation


def test_base_excitation_linear_equals_the_transmissibility():
    """Zero nonlinearity: the relative motion X = -m A / (k - m w^2 + i c w) and the absolute
    acceleration's transmissibility |a_abs| / |A| = sqrt((k^2 + (c w)^2) / ((k - m w^2)^2 +
    (c w)^2)) (Chopra, sec. 3.6), at every point."""
    m, c, k, A = 2.0, 0.3, 50.0, 0.7
    r = harmonic_balance([[m]], [[c]], [[k]], elements=[Cubic(0, k3=0.0)],
                         ground_acceleration=A, freqs_hz=(0.2, 2.0), harmonics=3)
    w = r.omega
    X = -m * A / (k - m * w**2 + 1j * c * w)
    assert np.allclose(r.harmonics[:, 0, 1], X, rtol=1e-10, atol=0)
    T = np.sqrt((k**2 + (c * w) ** 2) / ((k - m * w**2) ** 2 + (c * w) ** 2))
    assert np.allclose(r.a_abs_max[:, 0] / A, T, rtol=1e-10, atol=0)
    assert np.allclose(np.abs(r.a_abs_harmonics[:, 0, 1]) / A, T, rtol=1e-10, atol=0)
    assert r.stable.all() and r.folds.size == 0


def test_base_excitation_chain_model_default_influence():
    """A chain's default influence is ones: the same curve as the explicit influence and as
    the equivalent force -M r a_g."""
    chain = _chain8()
    kw = dict(elements=[Cubic(7, 6, k3=300.0)], freqs_hz=(0.3, 1.2), harmonics=3,
              outputs=[0, 7], stability=False)
    a = harmonic_balance(chain, ground_acceleration=[0.5], **kw)
    M = chain.matrices(sparse=True)[0].toarray()
    b = harmonic_balance(chain, ground_acceleration=[0.5], influence=np.ones(8), **kw)
    c = harmonic_balance(chain, force_dofs=list(range(8)), force=-0.5 * M @ np.ones(8), **kw)
    assert np.abs(a.harmonics - b.harmonics).max() == 0
    assert np.abs(a.harmonics - c.harmonics).max() < 1e-12 * np.abs(c.harmonics).max()
    assert c.a_abs_harmonics is None and a.a_abs_harmonics.shape == a.harmonics.shape


def test_base_excitation_cubic_against_long_time_integration():
    """m = 2, c = 0.04, k = 2, k3 = 1, ground acceleration 0.05 cos(w t): at stable points
    (both branches at 0.2 Hz, and 0.35 Hz beyond the folds) nonlinear_mck_response under the
    same ground record, started 1 % off the orbit, settles on it: relative displacement and
    absolute acceleration within 1e-3 (the error budget of
    test_duffing_against_long_time_integration)."""
    M, C, K = np.array([[2.0]]), np.array([[0.04]]), np.array([[2.0]])
    r = harmonic_balance(M, C, K, elements=[Cubic(0, k3=1.0)], ground_acceleration=0.05,
                         freqs_hz=(0.05, 0.4), harmonics=7)
    assert r.folds.size == 2
    f = r.frequency_hz
    up, down = r.folds
    cases = [int(np.argmin(np.abs(f[:up] - 0.2))), down + int(np.argmin(np.abs(f[down:] - 0.2))),
             int(np.argmin(np.abs(f - 0.35)))]
    for i in cases:
        assert r.stable[i]
        w, X = r.omega[i], r.harmonics[i, 0]
        T = 2 * np.pi / w
        dt, periods = T / 400, 250
        t = np.arange(400 * periods + 1) * dt
        k = np.arange(X.size)
        x0 = 1.01 * np.sum(X).real
        v0 = np.sum(1j * k * w * X).real
        out = nonlinear_mck_response(M, C, K, None, dt, elements=[Cubic(0, k3=1.0)],
                                     ground_acceleration=0.05 * np.cos(w * t),
                                     scheme="modal_parabolic", x0=[x0], v0=[v0])
        amp = np.abs(out.x[-401:, 0]).max()
        assert abs(amp - r.x_max[i, 0]) < 1e-3 * r.x_max[i, 0], (f[i], amp, r.x_max[i, 0])
        acc = np.abs(out.a_abs[-401:, 0]).max()
        assert abs(acc - r.a_abs_max[i, 0]) < 1e-3 * r.a_abs_max[i, 0], (f[i], acc)


# ----------------------------------------------------------------------------------------------
# (g) continuation in the load's amplitude at a fixed frequency


def test_amplitude_continuation_linear_is_proportional():
    rng = np.random.default_rng(5)
    n = 3
    A = rng.standard_normal((n, n))
    M = np.eye(n) + 0.1 * A @ A.T
    K = np.diag([200.0, 300.0, 250.0]) - 40.0 * (np.eye(n, k=1) + np.eye(n, k=-1))
    C = 0.002 * K + 0.1 * M
    F = np.array([1.0, 0.3 - 0.2j])
    r = harmonic_balance_amplitude(M, C, K, elements=[Cubic(0, 2, k3=0.0)], force_dofs=[2, 0],
                                   force=F, frequency_hz=2.2, amplitudes=(0.0, 3.0),
                                   harmonics=3)
    w = 2 * np.pi * 2.2
    P = np.zeros((n, 2))
    P[[2, 0], [0, 1]] = 1.0
    x1 = np.linalg.solve(K - w * w * M + 1j * w * C, P @ F)
    assert r.amplitude[0] == 0.0 and r.amplitude[-1] == 3.0 and np.all(np.diff(r.amplitude) > 0)
    assert np.allclose(r.harmonics[:, :, 1], np.outer(r.amplitude, x1), rtol=0,
                       atol=1e-12 * 3.0 * np.abs(x1).max())
    assert np.all(r.frequency_hz == 2.2) and r.folds.size == 0 and r.stable.all()


def test_amplitude_continuation_duffing_hand_relation_and_folds():
    """One harmonic at 0.25 Hz (above the linear resonance): every point satisfies
    [(k - m w^2) a + 3/4 k3 a^3]^2 + (c w a)^2 = (s F)^2 (s the load factor), and the two
    folds in s are the local extrema of s(a) from that relation."""
    f = 0.25
    w = 2 * np.pi * f
    r = harmonic_balance_amplitude(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                                   force_dofs=[0], force=[F_D], frequency_hz=f,
                                   amplitudes=(0.05, 15.0), harmonics=1)
    a, s = np.abs(r.harmonics[:, 0, 1]), r.amplitude
    res = ((1 - w**2) * a + 0.75 * K3 * a**3) ** 2 + (C_D * w * a) ** 2 - (s * F_D) ** 2
    assert np.abs(res / (s * F_D) ** 2).max() < 1e-9
    assert r.folds.size == 2 and np.all(r.frequency_hz == f)

    def load(x):
        return np.sqrt(((1 - w**2) * x + 0.75 * K3 * x**3) ** 2 + (C_D * w * x) ** 2) / F_D
    x = np.linspace(1e-3, a.max(), 100001)
    d = np.diff(load(x))
    ext = np.flatnonzero(d[1:] * d[:-1] < 0) + 1
    assert ext.size == 2                         # a local max of s(a), then a local min
    hand = [sign * minimize_scalar(lambda y, sign=sign: sign * load(y),
                                   bounds=(x[j - 1], x[j + 1]), method="bounded",
                                   options=dict(xatol=1e-13)).fun
            for j, sign in zip(ext, (-1, 1))]
    assert np.allclose(np.sort(r.fold_amplitude), np.sort(hand), rtol=1e-8, atol=0)
    assert not r.stable[r.folds[0] + 1:r.folds[1]].any()


# ----------------------------------------------------------------------------------------------
# (h) convergence in the number of harmonics


def test_harmonic_error_bounds_the_change_from_H_to_2H():
    """info["harmonic_error"] (the last two kept harmonics against x_max) bounds the change of
    the orbit from H to 2 H harmonics at the same point (the end of an amplitude continuation
    on the lower Duffing branch, 0.2 Hz, load factor 1) and falls as H grows."""
    def end(H):
        r = harmonic_balance_amplitude(np.eye(1), [[C_D]], np.eye(1),
                                       elements=[Cubic(0, k3=K3)], force_dofs=[0], force=[F_D],
                                       frequency_hz=0.2, amplitudes=(2.0, 1.0), harmonics=H,
                                       stability=False)
        return r, r.harmonics[-1, 0]
    t = np.linspace(0, 2 * np.pi / (2 * np.pi * 0.2), 513)
    w = 2 * np.pi * 0.2
    errors = []
    for H in (3, 5, 7):
        r, X = end(H)
        _, X2 = end(2 * H)
        change = np.abs(_series(X, w, t) - _series(X2, w, t)).max() / r.x_max[-1, 0]
        est = r.info["harmonic_error_points"][-1]
        assert change < est, (H, change, est)
        errors.append(est)
        assert r.info["harmonic_error"] == r.info["harmonic_error_points"].max()
    assert errors[0] > errors[1] > errors[2]


@pytest.mark.parametrize("kw, match", [
    (dict(force=None, force_dofs=None), "no load"),
    (dict(force=None), "force_dofs"),
    (dict(influence=[1.0]), "influence"),
    (dict(ground_acceleration=[1.0, 2.0]), "influence"),
    (dict(ground_acceleration=[1.0], influence=[[1.0, 1.0]]), "influence"),
    (dict(ground_acceleration=[0.0], force=None, force_dofs=None), "ground_acceleration"),
    (dict(receptance="banded"), "banded"),
])
def test_bad_load_inputs_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


@pytest.mark.parametrize("kw, match", [
    (dict(amplitudes=(1.0,)), "amplitudes"),
    (dict(amplitudes=(-1.0, 1.0)), "amplitudes"),
    (dict(amplitudes=(1.0, 1.0)), "amplitudes"),
    (dict(frequency_hz=0.0), "frequency_hz"),
])
def test_bad_amplitude_inputs_name_the_field(kw, match):
    args = dict(elements=[Cubic(0, k3=1.0)], force_dofs=[0], force=[1.0], frequency_hz=0.2,
                amplitudes=(0.1, 1.0))
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        harmonic_balance_amplitude(np.eye(1), [[0.1]], np.eye(1), **args)


def test_hill_on_a_large_model_is_refused_with_advice():
    n = 400
    chain = dd.Chain(np.ones(n), np.full(n, 100.0), np.ones(n))
    with pytest.raises(ValueError, match="stability=False"):
        harmonic_balance(chain, elements=[Cubic(n - 1, k3=1.0)], force_dofs=[n - 1],
                         force=[1.0], freqs_hz=(0.1, 0.2))


def test_matrices_model_and_the_sparse_fallbacks():
    """dd.Matrices gives the curve of its matrices; sparse matrices go banded when symmetric,
    to the sparse LU when not (a gyroscopic C): each equal to the dense modal curve."""
    import scipy.sparse as sps
    M, C, K = (A.toarray() for A in _chain8().matrices(sparse=True))
    G = np.zeros((8, 8))
    G[2, 5], G[5, 2] = 0.3, -0.3                  # skew: a gyroscopic coupling
    kw = dict(elements=[Cubic(7, k3=300.0)], force_dofs=[7], force=[0.4],
              freqs_hz=(0.3, 1.2), harmonics=3, outputs=[7], stability=False)
    ref = harmonic_balance(M, C, K, **kw)
    for model, C2, kind in ((dd.Matrices(M, C, K), None, "modal"),
                            (sps.csr_matrix(M), sps.csr_matrix(C), "banded")):
        r = (harmonic_balance(model, **kw) if C2 is None else
             harmonic_balance(model, C2, sps.csr_matrix(K), **kw))
        assert r.info["receptance"] == kind
        assert np.abs(r.harmonics - ref.harmonics).max() < 1e-9 * np.abs(ref.harmonics).max()
    gyro = harmonic_balance(M, C + G, K, **kw)
    sparse = harmonic_balance(sps.csr_matrix(M), sps.csr_matrix(C + G), sps.csr_matrix(K), **kw)
    assert sparse.info["receptance"] == "direct" and gyro.info["receptance"] == "modal"
    assert np.abs(sparse.harmonics - gyro.harmonics).max() < 1e-9 * np.abs(gyro.harmonics).max()


def test_the_issue_keyword_frequencies_still_works():
    """Issue 31 names the range `frequencies`; the vocabulary's name is `freqs_hz`."""
    with pytest.warns(DeprecationWarning, match="'frequencies' is now 'freqs_hz'"):
        r = harmonic_balance(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                             force_dofs=[0], force=[F_D], frequencies=RANGE, harmonics=1)
    assert np.array_equal(r.frequency_hz, _duffing(1).frequency_hz)


# ----------------------------------------------------------------------------------------------
# (i) the change from H to 2 H harmonics; bifurcations


def test_harmonic_convergence_equals_the_error_against_shooting():
    """With H = 3 the orbit's amplitude is off by up to 1e-3; harmonic_convergence
    (|x_max(2H) - x_max(H)| / x_max(2H)) equals the error against the shooting orbit's max |x|
    up to the 2 H solution's own error, geometrically smaller (3 % of it at the largest
    amplitude, less elsewhere): within 10 % at every checked point (the ends, the largest
    amplitude and points spread along the curve, on every branch)."""
    r = _duffing(3, convergence_points=8)
    checked = np.flatnonzero(np.isfinite(r.harmonic_convergence))
    assert 8 <= checked.size <= 9 and checked[0] == 0 and checked[-1] == r.omega.size - 1
    assert int(np.argmax(r.x_max[:, 0])) in checked
    assert r.info["harmonic_convergence"] == np.nanmax(r.harmonic_convergence)
    assert r.info["harmonic_convergence_failures"] == 0
    for i in checked:
        w, X = r.omega[i], r.harmonics[i, 0]
        k = np.arange(X.size)
        z0 = [np.sum(X).real, np.sum(1j * k * w * X).real]
        _, sol, _ = _shoot(np.eye(1), np.array([[C_D]]), np.eye(1), [(0, None, K3)], F_D, 0, w,
                           z0)
        t = np.linspace(0, 2 * np.pi / w, 4097)
        j = int(np.argmax(np.abs(sol(t)[0])))
        peak = -minimize_scalar(lambda s, sol=sol: -abs(sol(s)[0]),
                                bounds=(t[max(j - 1, 0)], t[j + 1]),
                                method="bounded", options=dict(xatol=1e-12)).fun
        true = abs(peak - r.x_max[i, 0]) / peak
        assert abs(r.harmonic_convergence[i] - true) <= 0.1 * true + 1e-9, \
            (r.frequency_hz[i], r.harmonic_convergence[i], true)
    none = _duffing(3, convergence_points=0)
    assert np.isnan(none.harmonic_convergence).all() and np.isnan(none.info[
        "harmonic_convergence"])
    every = harmonic_balance_amplitude(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                                       force_dofs=[0], force=[F_D], frequency_hz=0.2,
                                       amplitudes=(0.5, 1.0), harmonics=3, stability=False,
                                       convergence_points="all")
    assert np.isfinite(every.harmonic_convergence).all()


def test_duffing_bifurcations_are_its_two_folds(duffing7):
    r = duffing7
    assert list(r.bifurcation_kind) == ["fold", "fold"]
    assert np.array_equal(r.bifurcation_index, r.folds)
    assert np.array_equal(r.bifurcation_frequency_hz, r.fold_frequency_hz)


# two identical Duffing oscillators coupled by a weak spring, forced on the first: 1:1 internal
# resonance, localized branches, and Neimark-Sacker bifurcations (Krein collisions of the
# multipliers, which leave the unit circle as complex pairs)
KC, CC, FC = 0.05, 0.01, 0.02


def _coupled(**kw):
    M = np.eye(2)
    K = np.array([[1 + KC, -KC], [-KC, 1 + KC]])
    C = CC * np.eye(2)
    r = harmonic_balance(M, C, K, elements=[Cubic(0, k3=1.0), Cubic(1, k3=1.0)],
                         force_dofs=[0], force=[FC], freqs_hz=(0.16, 0.21), harmonics=9,
                         max_step=0.05, **kw)
    return r, (M, C, K)


def test_neimark_sacker_points_against_shooting():
    """Every Neimark-Sacker point found by harmonic balance is bracketed by shooting orbits
    (at the points on both sides) whose monodromy matrices have all multipliers inside the unit
    circle on the stable side and a complex pair outside on the other; Hill's multipliers equal
    the monodromy's there (1e-6); the first one's frequency equals the shooting's (the root of
    max |mu| - 1 along the branch, Brent's method) to 1e-9. (Two of the five share their step
    with a fold, the stability flags then agree on both sides; they are left out.)"""
    from scipy.optimize import brentq
    r, (M, C, K) = _coupled()
    cubic = [(0, None, 1.0), (1, None, 1.0)]
    kinds = list(r.bifurcation_kind)
    assert kinds.count("neimark_sacker") >= 4 and kinds.count("fold") == r.folds.size
    assert not {"period_doubling", "branch_point"} & set(kinds)

    def state(i, frac=0.0):
        X, w = r.harmonics[i], r.omega[i]
        X = X + frac * (r.harmonics[i + 1] - X)
        w = w + frac * (r.omega[i + 1] - w)
        k = np.arange(X.shape[1])
        return np.concatenate([X.sum(axis=1).real, (X * 1j * k * w).sum(axis=1).real])

    ns = [(i, f) for kind, i, f in zip(r.bifurcation_kind, r.bifurcation_index,
                                       r.bifurcation_frequency_hz) if kind == "neimark_sacker"]
    checked = 0
    for n, (i, f) in enumerate(ns):
        steps = [j for j in (i - 1, i) if r.stable[j] != r.stable[j + 1]]
        if len(steps) != 1:
            continue               # a fold in the same step (checked by the folds' tests)
        lo = steps[0]
        mus = []
        for j in (lo, lo + 1):
            _, _, mu = _shoot(M, C, K, cubic, FC, 0, r.omega[j], state(j))
            hill = np.sort(np.abs(np.exp(r.floquet_exponents[j] * 2 * np.pi / r.omega[j])))
            assert np.allclose(hill, np.sort(np.abs(mu)), rtol=1e-6), (j, hill, mu)
            assert r.stable[j] == (np.abs(mu).max() < 1)
            mus.append(mu)
        out = mus[1] if r.stable[lo] else mus[0]
        assert np.all(np.abs(mus[0 if r.stable[lo] else 1]) < 1)
        big = out[np.abs(out) > 1]
        assert big.size == 2 and np.all(np.abs(big.imag) > 1e-2 * np.abs(big)), out
        checked += 1
        if n == 0:
            def excess(ff, lo=lo):
                frac = (ff - r.frequency_hz[lo]) / (r.frequency_hz[lo + 1] - r.frequency_hz[lo])
                _, _, mu = _shoot(M, C, K, cubic, FC, 0, 2 * np.pi * ff, state(lo, frac))
                return np.abs(mu).max() - 1
            f_shoot = brentq(excess, r.frequency_hz[lo], r.frequency_hz[lo + 1], xtol=1e-13)
            assert abs(f / f_shoot - 1) < 1e-9, (f, f_shoot)
    assert checked >= 3


def test_period_doubling_of_a_quadratic_oscillator_against_the_monodromy():
    """x'' + 0.02 x' + x + x^2 = 0.3 cos(w t): between 0.30 and 0.33 Hz one Floquet multiplier
    is real and below -1 (a period-doubled branch). Hill's exponents there sit at Im = +-w/2,
    whose two copies tie; each kept exponent must be a different multiplier. Truth: the
    multipliers of the monodromy matrix of the variational equation along the harmonic-balance
    orbit (solve_ivp, rtol 1e-11); both bifurcations are period doublings."""
    c = 0.02
    r = harmonic_balance(np.eye(1), [[c]], np.eye(1),
                         elements=[dd.Polynomial(0, coeffs=(0.0, 0.0, 1.0))], force_dofs=[0],
                         force=[0.3], freqs_hz=(0.25, 0.40), harmonics=6, convergence_points=0)
    for j in range(r.frequency_hz.size):
        X, w = r.harmonics[j][0], r.omega[j]
        k = np.arange(X.size)

        def rhs(t, s, X=X, w=w, k=k):
            x = np.real(np.sum(X * np.exp(1j * k * w * t)))
            return (np.array([[0.0, 1.0], [-(1.0 + 2.0 * x), -c]]) @ s.reshape(2, 2)).ravel()
        sol = solve_ivp(rhs, (0.0, 2 * np.pi / w), np.eye(2).ravel(), rtol=1e-11, atol=1e-12)
        mu = np.sort(np.abs(np.linalg.eigvals(sol.y[:, -1].reshape(2, 2))))
        hill = np.sort(np.abs(np.exp(r.floquet_exponents[j] * 2 * np.pi / w)))
        np.testing.assert_allclose(hill, mu, rtol=1e-4, err_msg=f"point {j}")
        assert r.stable[j] == (mu.max() < 1.0), j
    assert list(r.bifurcation_kind) == ["period_doubling", "period_doubling"]
    lo, hi = r.bifurcation_frequency_hz
    assert 0.29 < lo < 0.305 and 0.32 < hi < 0.34


def test_first_point_beyond_the_linear_range_brings_the_load_in_by_steps():
    """F = 1 at 0.08 Hz: Newton from the linear response does not converge there (residual
    0.09 after 20 iterations); the load brought in by steps gives the point the curve swept
    down from 0.15 Hz ends on."""
    kw = dict(elements=[Cubic(0, k3=K3)], force_dofs=[0], force=[1.0], harmonics=7)
    start = harmonic_balance(np.eye(1), [[C_D]], np.eye(1), freqs_hz=(0.08, 0.0808), **kw)
    swept = harmonic_balance(np.eye(1), [[C_D]], np.eye(1), freqs_hz=(0.15, 0.08), **kw)
    assert start.frequency_hz[0] == swept.frequency_hz[-1] == 0.08
    np.testing.assert_allclose(start.harmonics[0], swept.harmonics[-1], rtol=0,
                               atol=1e-9 * np.abs(swept.harmonics[-1]).max())
