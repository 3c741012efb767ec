"""Discrete state space: SHARPy's newmark_ss, any scheme, massless DOFs, the C time loop."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.signal as sig

from dtdyn.linear._discretize import first_order_form
from dtdyn.linear._exact import exact_response
from dtdyn.linear._mck import mck_response
from dtdyn.linear._discrete_model import DiscreteModel
from dtdyn.linear._state_space import discrete_state_space, newmark_ss, state_space_response


def random_system(n, rng):
    """Random SPD M, K and PSD C."""
    def spd(scale):
        X = rng.standard_normal((n, n))
        return scale * (X @ X.T / n + np.eye(n))
    return spd(1.0), 0.05 * spd(1.0), spd(100.0)


def sharpy_newmark_ss(M, C, K, dt, num_damp):
    """Oracle: reference.md section 5 typed as SHARPy writes it (with M^-1)."""
    n = M.shape[0]
    gamma, beta = 0.5 + num_damp, 0.25 * (1 + num_damp) ** 2
    Minv = np.linalg.inv(M)
    I = np.eye(n)
    Ass1 = np.block([[I + beta * dt**2 * Minv @ K, beta * dt**2 * Minv @ C],
                     [gamma * dt * Minv @ K, I + gamma * dt * Minv @ C]])
    Ass0 = np.block([[I - (0.5 - beta) * dt**2 * Minv @ K,
                      dt * I - (0.5 - beta) * dt**2 * Minv @ C],
                     [-(1 - gamma) * dt * Minv @ K, I - (1 - gamma) * dt * Minv @ C]])
    Bss0 = np.vstack([(0.5 - beta) * dt**2 * Minv, (1 - gamma) * dt * Minv])
    Bss1 = np.vstack([beta * dt**2 * Minv, gamma * dt * Minv])
    inv1 = np.linalg.inv(Ass1)
    return inv1 @ Ass0, inv1 @ (Bss0 + Ass0 @ inv1 @ Bss1), np.eye(2 * n), inv1 @ Bss1


def rel(a, b):
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


@pytest.mark.parametrize("n", [1, 2, 7, 50, 200])
@pytest.mark.parametrize("num_damp", [0.0, 1e-4, 0.1])
@pytest.mark.parametrize("spd", [False, True])
def test_newmark_ss_equals_sharpy(n, num_damp, spd):
    rng = np.random.default_rng(n)
    M, C, K = random_system(n, rng)
    dt = 0.01
    ours = newmark_ss(M, C, K, dt, num_damp=num_damp, M_is_SPD=spd)
    ref = sharpy_newmark_ss(M, C, K, dt, num_damp)
    for a, b in zip(ours, ref):
        # both are O(cond(E1) eps) away from exact; cond(E1) ~ 1e2 .. 1e3 here
        assert rel(a, b) < 1e-12


def transfer(A, B, C, D, z):
    return C @ np.linalg.solve(z * np.eye(A.shape[0]) - A, B) + D


def test_newmark_ss_without_damping_is_tustin():
    """Average acceleration (num_damp = 0) is the bilinear transform of the first-order form."""
    rng = np.random.default_rng(3)
    M, C, K = random_system(5, rng)
    dt = 0.02
    A, B = first_order_form(M, C, K)
    Ab, Bb, Cb, Db, _ = sig.cont2discrete((A, B, np.eye(10), np.zeros((10, 5))), dt,
                                          method="bilinear")
    ours = newmark_ss(M, C, K, dt, num_damp=0.0)
    for w in (0.1, 1.0, 7.0, 60.0):
        z = np.exp(1j * w * dt)
        assert rel(transfer(*ours, z), transfer(Ab, Bb, Cb, Db, z)) < 1e-12


@pytest.mark.parametrize("scheme, params", [("newmark", {}), ("average_acceleration", {}),
                                            ("fox_goodwin", {}), ("wilson", {}),
                                            ("hht", {"alpha": -0.2}),
                                            ("generalized_alpha", {"rho_inf": 0.5})])
def test_discrete_state_space_equals_simulate_mck(scheme, params):
    rng = np.random.default_rng(11)
    M, C, K = random_system(4, rng)
    dt, n_steps = 0.01, 400
    F = rng.standard_normal((n_steps + 1, 4))
    ref = mck_response(M, C, K, F, dt, scheme=scheme, **params)
    model = discrete_state_space(M, C, K, dt, scheme=scheme, acceleration=True, **params)
    A, B, Cm, D = model
    assert A.shape[0] == 12  # history (x0, v0, a0), all of it output: S = I, D = Gamma1
    h0 = np.zeros(12)
    h0[8:12] = np.linalg.solve(M, F[0])  # a_0
    x0 = h0 - D @ F[0]  # the state is shifted by -Gamma1 f_0 (by hand, as the oracle)
    y = model.simulate(F, state0=x0)
    np.testing.assert_allclose(y[:, :4], ref.x, rtol=0, atol=1e-12 * np.abs(ref.x).max())
    np.testing.assert_allclose(y[:, 4:8], ref.v, rtol=0, atol=1e-12 * np.abs(ref.v).max())
    np.testing.assert_allclose(y[:, 8:], ref.a, rtol=0, atol=1e-11 * np.abs(ref.a).max())
    np.testing.assert_array_equal(model.initial_state(f0=F[0]), x0)
    r = state_space_response(model, F)  # the same start, from the model's own convention
    for q in "xva":
        np.testing.assert_array_equal(getattr(r, q), y[:, "xva".index(q) * 4:][:, :4])


def _massless_system():
    """3 DOFs, DOF 1 massless with a damper to ground (its velocity is then defined)."""
    M = np.diag([1.0, 0.0, 2.0])
    K = np.array([[300.0, -100.0, 0.0], [-100.0, 250.0, -150.0], [0.0, -150.0, 150.0]])
    C = 0.002 * K + np.diag([0.0, 5.0, 0.0])
    return M, C, K


def _massless_truth(M, C, K, F, dt, n_steps):
    """Independent truth: eliminate v_1 = (f_1 - C_1m v_m - K_1 q) / C_11 and integrate the
    remaining linear ODE in [q_0, q_1, q_2, v_0, v_2] exactly (matrix exponential, force
    linear between samples)."""
    m, z = [0, 2], [1]
    Czz = C[np.ix_(z, z)]
    # v_z = Czz^-1 (f_z - C_zm v_m - K_z q)
    Vq = -np.linalg.solve(Czz, K[z])            # d v_z / d q
    Vv = -np.linalg.solve(Czz, C[np.ix_(z, m)])  # d v_z / d v_m
    Vf = np.linalg.solve(Czz, np.eye(3)[z])      # d v_z / d f
    # q' : q_m' = v_m, q_z' = v_z
    n = 5
    A = np.zeros((n, n))
    Bf = np.zeros((n, 3))
    A[np.ix_(m, [3, 4])] = np.eye(2)
    A[np.ix_(z, range(3))] = Vq
    A[np.ix_(z, [3, 4])] = Vv
    Bf[z] = Vf
    # M_mm v_m' = f_m - C_mm v_m - C_mz v_z - K_m q
    Mmm_inv = np.linalg.inv(M[np.ix_(m, m)])
    Cmm, Cmz = C[np.ix_(m, m)], C[np.ix_(m, z)]
    A[3:, :3] = -Mmm_inv @ (K[m] + Cmz @ Vq)
    A[3:, 3:] = -Mmm_inv @ (Cmm + Cmz @ Vv)
    Bf[3:] = Mmm_inv @ (np.eye(3)[m] - Cmz @ Vf)
    E = sla.expm(np.block([[A * dt, Bf * dt, np.zeros((n, 3))],
                           [np.zeros((3, n + 3)), np.eye(3)],
                           [np.zeros((3, n + 6))]]))
    Phi, Ga, Gb = E[:n, :n], E[:n, n:n + 3], E[:n, n + 3:]
    s = np.zeros(n)
    out = [s[:3].copy()]
    for k in range(n_steps):
        s = Phi @ s + (Ga - Gb) @ F[k] + Gb @ F[k + 1]
        out.append(s[:3].copy())
    return np.array(out)


def _massless_force(t):
    return np.stack([np.sin(3 * t) * t, 0 * t, 0.5 * (1 - np.cos(5 * t))], 1)


def test_exact_response_with_a_massless_dof():
    """exact_response eliminates the massless DOF as the oracle does; its velocity and
    acceleration satisfy the equations of motion at the samples."""
    M, C, K = _massless_system()
    dt, n = 0.01, 200
    t = np.arange(n + 1) * dt
    F = _massless_force(t)
    r = exact_response(M, C, K, F, dt)
    truth = _massless_truth(M, C, K, F, dt, n)
    np.testing.assert_allclose(r.x, truth, rtol=0, atol=1e-12 * np.abs(truth).max())
    resid = r.a @ M.T + r.v @ C.T + r.x @ K.T - F
    assert np.abs(resid).max() < 1e-10 * np.abs(F).max()
    # q1'' from the force's slope: the central difference of q1' agrees to O(dt^2)
    a1 = np.gradient(r.v[:, 1], dt)
    assert np.abs(a1[2:-2] - r.a[2:-2, 1]).max() < 1e-3 * np.abs(r.a[:, 1]).max()
    with pytest.raises(ValueError, match=r"C at the massless DOFs \[1\]"):
        exact_response(M, np.zeros((3, 3)), K, F, dt)
    with pytest.raises(ValueError, match=r"v0\[1\]"):
        exact_response(M, C, K, F, dt, v0=[0.0, 1.0, 0.0])
    # a consistent v0, computed in floating point: accepted
    vm = np.array([0.3, -0.2])
    v1 = -(C[1, [0, 2]] @ vm) / C[1, 1]
    r0 = exact_response(M, C, K, F, dt, v0=[vm[0], v1, vm[1]])
    assert r0.v[0] == pytest.approx([vm[0], v1, vm[1]], rel=1e-12)


def test_massless_dof():
    """SHARPy's formula needs M^-1; newmark_ss realizes the same recursion with the state
    [q; q'; q''], equals mck_response and converges at second order to exact_response."""
    M, C, K = _massless_system()
    T = 2.0
    with pytest.raises(np.linalg.LinAlgError):
        sharpy_newmark_ss(M, C, K, 0.01, 0.0)
    for num_damp, order in ((0.0, 2.0), (0.1, 1.0)):
        errs = []
        dts = [0.02, 0.01, 0.005]
        for dt in dts:
            n = int(round(T / dt))
            F = _massless_force(np.arange(n + 1) * dt)
            gamma, beta = 0.5 + num_damp, 0.25 * (1 + num_damp) ** 2
            ref = mck_response(M, C, K, F, dt, scheme="newmark", beta=beta, gamma=gamma)
            model = newmark_ss(M, C, K, dt, num_damp=num_damp)
            A, B, Cm, D = model
            assert A.shape == (9, 9) and Cm.shape == (6, 9)
            r = state_space_response(model, F)
            np.testing.assert_allclose(r.x, ref.x, rtol=0, atol=1e-12 * np.abs(ref.x).max())
            np.testing.assert_allclose(r.v, ref.v, rtol=0, atol=1e-12 * np.abs(ref.v).max())
            truth = exact_response(M, C, K, F, dt).x
            errs.append(np.abs(ref.x - truth).max() / np.abs(truth).max())
        slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
        # gamma = 1/2 + num_damp: second order without numerical damping, first order with it
        assert abs(slope - order) < 0.25, (num_damp, errs, slope)


def _dlsim_case(seed, ns, ni, no, n_steps, radius):
    """A random stable model (spectral radius ``radius``), input, x0 and dlsim's response."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((ns, ns))
    A *= radius / np.max(np.abs(np.linalg.eigvals(A)))
    B, Cm, D = (rng.standard_normal(s) for s in ((ns, ni), (no, ns), (no, ni)))
    u = rng.standard_normal((n_steps, ni))
    x0 = rng.standard_normal(ns)
    _, y_ref, _ = sig.dlsim((A, B, Cm, D, 1.0), u, x0=x0)
    return (A, B, Cm, D, u), x0, y_ref


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_state_space_response_across_blocks(monkeypatch, backend):
    """The record runs in blocks of SS_BLOCK steps; the state carried from block to block gives
    the same response as one block (here SS_BLOCK = 7 against 40 steps: 5 full blocks and 5)."""
    import dtdyn.linear._state_space as ss
    model, x0, y_ref = _dlsim_case(8, 6, 2, 3, 40, 0.9)
    monkeypatch.setattr(ss, "SS_BLOCK", 7)
    y = ss.run_recursion(*model, state0=x0, backend=backend)
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-12 * np.abs(y_ref).max())


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_state_space_response_equals_dlsim(backend):
    (A, B, Cm, D, u), x0, y_ref = _dlsim_case(5, 12, 3, 4, 500, 0.95)
    y = DiscreteModel(A, B, Cm, D, 1.0).simulate(u, state0=x0, backend=backend)
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-12 * np.abs(y_ref).max())


def test_bad_input():
    M, C, K = random_system(3, np.random.default_rng(0))
    with pytest.raises(ValueError, match="dt"):
        newmark_ss(M, C, K, 0.0)
    with pytest.raises(ValueError, match=r"K has shape \(2, 2\)"):
        newmark_ss(M, C, np.eye(2), 0.01)
    with pytest.raises(ValueError, match="square"):
        discrete_state_space(np.ones((2, 3)), C, K, 0.01)
    with pytest.raises(ValueError, match=r"C\[0, 1\] = nan"):
        C2 = C.copy()
        C2[0, 1] = np.nan
        discrete_state_space(M, C2, K, 0.01)
    with pytest.raises(ValueError, match="effective matrix"):
        discrete_state_space(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), 0.01)
    with pytest.raises(ValueError, match="num_damp"):
        newmark_ss(M, C, K, 0.01, num_damp=-1.0)
    with pytest.raises(ValueError, match=r"M\[0, 0\] = -.*negative mass at DOF 0"):
        newmark_ss(-M, C, K, 0.01, M_is_SPD=True)
    with pytest.raises(ValueError, match="not positive definite"):  # semi-definite: massless DOF
        newmark_ss(np.diag([1.0, 0.0, 1.0]), C, K, 0.01, M_is_SPD=True)
    with pytest.raises(ValueError, match="B has 3 rows"):
        DiscreteModel(np.eye(2), np.ones((3, 1)), np.eye(2), np.zeros((2, 1)), 0.1)
    raw = DiscreteModel(np.eye(2), np.ones((2, 1)), np.eye(2), np.zeros((2, 1)), 0.1)
    with pytest.raises(ValueError, match="force has a non-finite"):
        raw.simulate(np.full((5, 1), np.nan))
    with pytest.raises(TypeError, match="DiscreteModel"):
        state_space_response(tuple(raw), np.ones((5, 1)))
    with pytest.raises(ValueError, match="no stated meaning"):
        state_space_response(raw, np.ones((5, 1)))
    with pytest.raises(ValueError, match="force"):
        state_space_response(newmark_ss(M, C, K, 0.01), np.ones((5, 2)))
    with pytest.raises(ValueError, match="outputs"):
        state_space_response(newmark_ss(M, C, K, 0.01), np.ones((5, 3)), quantities=("a",))


@pytest.mark.parametrize("build", [
    lambda M, C, K, dt: newmark_ss(M, C, K, dt, num_damp=0.0),
    lambda M, C, K, dt: discrete_state_space(M, C, K, dt, scheme="newmark"),
    lambda M, C, K, dt: discrete_state_space(M, C, K, dt, scheme="generalized_alpha",
                                             rho_inf=0.7, acceleration=True),
], ids=["newmark_ss", "discrete_state_space", "generalized_alpha"])
def test_response_starts_at_rest_under_a_step(build):
    """The models' states are shifted by the f_0 feedthrough, so a zero state is not rest under a
    step: state_space_response starts at rest anyway and equals mck_response (same scheme) to
    1e-12 with no initial-state argument; the raw zero-state recursion does not."""
    M, C, K = np.diag([2.0, 1.0]), np.array([[0.3, -0.1], [-0.1, 0.1]]), \
        np.array([[30.0, -10.0], [-10.0, 10.0]])
    dt, n = 0.01, 400
    model = build(M, C, K, dt)
    scheme = "generalized_alpha" if "rho_inf=0.7" in model.source else "newmark"
    params = {"rho_inf": 0.7} if scheme == "generalized_alpha" else {}
    ref = mck_response(M, C, K, np.ones(n + 1), dt, force_dofs=[1], scheme=scheme, **params)
    r = state_space_response(model, np.ones(n + 1), force_dofs=[1])
    for q in model.quantities:
        err = np.abs(getattr(r, q) - getattr(ref, q)).max()
        assert err <= 1e-12 * np.abs(getattr(ref, q)).max()
    u = np.zeros((n + 1, 2))
    u[:, 1] = 1.0
    zero_state = model.simulate(u)[:, :2]
    assert np.abs(zero_state - ref.x).max() > 1e-3 * np.abs(ref.x).max()


def test_response_from_initial_conditions():
    """x0, v0 map to each model's state: the FOH discretization then equals exact_response (the
    matrix exponential) from the same initial state to round-off, Newmark equals mck_response."""
    M, C, K = np.diag([2.0, 1.0]), np.array([[0.3, -0.1], [-0.1, 0.1]]), \
        np.array([[30.0, -10.0], [-10.0, 10.0]])
    dt, n = 0.01, 300
    f = np.sin(np.arange(n + 1) * dt * 3.0)
    x0, v0 = np.array([0.1, -0.2]), np.array([0.0, 0.5])
    from dtdyn.linear._discretize import discretize
    ex = exact_response(M, C, K, f, dt, force_dofs=[1], x0=x0, v0=v0)
    for hold in ("foh", "tustin", "zoh"):
        r = state_space_response(discretize(M, C, K, dt, hold=hold), f, force_dofs=[1], x0=x0,
                                 v0=v0)
        np.testing.assert_allclose(r.x[0], x0, rtol=0, atol=1e-14)
        np.testing.assert_allclose(r.v[0], v0, rtol=0, atol=1e-14)
        if hold == "foh":
            assert np.abs(r.x - ex.x).max() <= 1e-12 * np.abs(ex.x).max()
    mk = mck_response(M, C, K, f, dt, force_dofs=[1], x0=x0, v0=v0, scheme="newmark")
    r = state_space_response(newmark_ss(M, C, K, dt, num_damp=0.0), f, force_dofs=[1], x0=x0,
                             v0=v0)
    assert np.abs(r.x - mk.x).max() <= 1e-12 * np.abs(mk.x).max()
