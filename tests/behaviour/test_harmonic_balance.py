"""Harmonic balance (runtime/nonlinear/harmonic_balance.py) against independent truths.

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

from dtdyn import nonlinear_mck_response
from dtdyn._engine.errors import NewtonError
from dtdyn.nonlinear.elements import BoucWen, Cubic, Law
from dtdyn.nonlinear.harmonic_balance import harmonic_balance

# the Duffing oscillator of issue 31: m = 1, c = 0.02, k = 1, k3 = 0.5
C_D, K3, F_D = 0.02, 0.5, 0.1
RANGE = (0.05, 0.4)


def _duffing(harmonics, **kw):
    return harmonic_balance(np.eye(1), [[C_D]], np.eye(1), elements=[Cubic(0, k3=K3)],
                            force_dofs=[0], force=[F_D], frequencies=RANGE,
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
                         frequencies=(0.5, 4.0), harmonics=3, receptance=receptance)
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
                         force_dofs=[0], force=[0.15], frequencies=(0.05, 0.35), harmonics=15)
    cubic.append((1, None, 0.5))
    direct = harmonic_balance(M, C, K, elements=[Cubic(0, 1, k3=2.0), Cubic(1, k3=0.5)],
                              force_dofs=[0], force=[0.15], frequencies=(0.05, 0.35),
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
                            force_dofs=[0], force=[F_D], frequencies=RANGE[::-1], harmonics=1)
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
                frequencies=(0.1, 0.2))
    args.update(kw)
    return harmonic_balance(np.eye(1), [[0.1]], np.eye(1), **args)


@pytest.mark.parametrize("kw, match", [
    (dict(frequencies=(0.1,)), "frequencies"),
    (dict(frequencies=(0.1, 0.1)), "frequencies"),
    (dict(frequencies=(-1.0, 0.2)), "frequencies"),
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
    with pytest.raises((NewtonError, ValueError)):
        harmonic_balance(np.eye(1), [[0.0]], np.eye(1), elements=[Cubic(0, k3=0.0)],
                         force_dofs=[0], force=[1.0], frequencies=(0.1, 0.3))
