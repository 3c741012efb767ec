"""Tests of dtdyn.linear._exact against independent truths (closed form, quadrature, DOP853)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm

from dtdyn.linear._exact import exact_response, foh_matrices
from dtdyn import Response


def chain(m, k, c):
    """Fixed-free chain: M diag, K and C tridiagonal."""
    m, k, c = (np.asarray(a, dtype=float) for a in (m, k, c))

    def tri(s):
        n = s.size
        T = np.zeros((n, n))
        for i in range(n):
            T[i, i] += s[i]
            if i + 1 < n:
                T[i, i] += s[i + 1]
                T[i, i + 1] = T[i + 1, i] = -s[i + 1]
        return T

    return np.diag(m), tri(c), tri(k)


M2, C2, K2 = chain([2.0, 3.0], [20.0, 15.0], [5.0, 6.0])


def test_chain_helper_matches_brief():
    np.testing.assert_array_equal(K2, [[35.0, -15.0], [-15.0, 15.0]])
    np.testing.assert_array_equal(C2, [[11.0, -6.0], [-6.0, 6.0]])


# ---------------------------------------------------------------- (1) 1-DOF step, closed form
def test_one_dof_unit_step_closed_form():
    m, k, c = 2.0, 12.0, 3.0
    dt, n = 0.02, 500                       # P1: T = 10 s
    r = exact_response([[m]], [[c]], [[k]], np.ones(n + 1), dt)
    assert isinstance(r, Response)
    assert r.x.shape == r.v.shape == r.a.shape == (n + 1, 1)
    assert r.info["method"] == "exact (matrix exponential, first-order hold)"

    w = np.sqrt(k / m)
    zeta = c / (2.0 * np.sqrt(k * m))
    assert zeta < 1.0
    wd = w * np.sqrt(1.0 - zeta**2)
    t = dt * np.arange(n + 1)
    np.testing.assert_allclose(r.t, t, rtol=0, atol=1e-15)
    e = np.exp(-zeta * w * t)
    x = (1.0 - e * (np.cos(wd * t) + zeta / np.sqrt(1.0 - zeta**2) * np.sin(wd * t))) / k
    v = e * np.sin(wd * t) * w**2 / (wd * k)
    a = (1.0 - c * v - k * x) / m
    np.testing.assert_allclose(r.x[:, 0], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.v[:, 0], v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.a[:, 0], a, rtol=0, atol=1e-12)
    assert r.x[0, 0] == 0.0 and r.v[0, 0] == 0.0
    assert r.a[0, 0] == pytest.approx(1.0 / m, abs=1e-15)


# ------------------------------------------- FOH input matrices against direct quadrature
def test_foh_matrices_against_quadrature():
    N = 2
    A = np.zeros((4, 4))
    A[:N, N:] = np.eye(N)
    A[N:, :N] = -np.linalg.solve(M2, K2)
    A[N:, N:] = -np.linalg.solve(M2, C2)
    B = np.zeros((4, 2))
    B[N:, :] = np.linalg.inv(M2)
    dt = 0.3
    Phi, G0, G1 = foh_matrices(A, B, dt)
    kern = lambda s: expm(A * (dt - s)) @ B                       # noqa: E731
    gam_a, _ = quad_vec(kern, 0.0, dt, epsabs=1e-14, epsrel=1e-13)
    gam_b, _ = quad_vec(lambda s: kern(s) * (s / dt), 0.0, dt, epsabs=1e-14, epsrel=1e-13)
    np.testing.assert_allclose(Phi, expm(A * dt), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(G0, gam_a - gam_b, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(G1, gam_b, rtol=1e-10, atol=1e-14)


# ------------------------------------------------------- (2) 2-DOF chain against DOP853
def ramp_then_sine(t):
    """Ramp to 1 over 1 s, then 1 + 0.5 sin(3 (t - 1)); kink at t = 1."""
    return np.where(t < 1.0, t, 1.0 + 0.5 * np.sin(3.0 * (t - 1.0)))


def dop853_reference(M, C, K, L, fs, dt, z0):
    """Integrate the interpolated-force ODE interval by interval (kinks at every sample)."""
    N = M.shape[0]
    Minv = np.linalg.inv(M)
    out = [np.array(z0, dtype=float)]
    z = out[0]
    for n in range(fs.shape[0] - 1):
        f0, f1 = fs[n], fs[n + 1]
        t0 = n * dt

        def rhs(t, y, f0=f0, f1=f1, t0=t0):
            u = f0 + (f1 - f0) * (t - t0) / dt
            q, qd = y[:N], y[N:]
            return np.concatenate([qd, Minv @ (L @ u - C @ qd - K @ q)])

        sol = solve_ivp(rhs, (t0, t0 + dt), z, method="DOP853", rtol=1e-12, atol=1e-14)
        assert sol.success
        z = sol.y[:, -1]
        out.append(z)
    return np.array(out)


@pytest.mark.parametrize("with_ic", [False, True])
def test_two_dof_chain_against_dop853(with_ic):
    dt, n = 0.05, 120                        # 6 s, force kink at t = 1 s is a sample
    t = dt * np.arange(n + 1)
    fs = ramp_then_sine(t)[:, None]
    L = np.array([[0.0], [1.0]])
    x0 = np.array([0.02, -0.01]) if with_ic else None
    v0 = np.array([-0.1, 0.3]) if with_ic else None
    r = exact_response(M2, C2, K2, fs, dt, force_dofs=[1], x0=x0, v0=v0)
    z0 = np.concatenate([np.zeros(2) if x0 is None else x0, np.zeros(2) if v0 is None else v0])
    Z = dop853_reference(M2, C2, K2, L, fs, dt, z0)
    xs, vs = Z[:, :2], Z[:, 2:]
    acc = np.linalg.solve(M2, (L @ fs.T - C2 @ vs.T - K2 @ xs.T)).T
    for got, ref in ((r.x, xs), (r.v, vs), (r.a, acc)):
        scale = np.abs(ref).max()
        assert np.abs(got - ref).max() <= 1e-9 * scale
    np.testing.assert_array_equal(r.outputs, [0, 1])


def test_outputs_subset_and_sparse_and_full_force():
    dt, n = 0.05, 40
    t = dt * np.arange(n + 1)
    full = np.column_stack([0.3 * np.cos(2 * t), ramp_then_sine(t)])
    ref = exact_response(M2, C2, K2, full, dt)           # loaded=None: all DOFs
    sp = exact_response(scipy.sparse.csr_matrix(M2), scipy.sparse.csr_matrix(C2),
                        scipy.sparse.csr_matrix(K2), full, dt, outputs=[1])
    assert sp.x.shape == (n + 1, 1)
    np.testing.assert_array_equal(sp.outputs, [1])
    assert sp.column(1) == 0
    np.testing.assert_allclose(sp.x[:, 0], ref.x[:, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(sp.v[:, 0], ref.v[:, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(sp.a[:, 0], ref.a[:, 1], rtol=0, atol=1e-14)
    # superposition: the sum of the single-DOF loadings equals the full loading
    r0 = exact_response(M2, C2, K2, full[:, 0], dt, force_dofs=[0])
    r1 = exact_response(M2, C2, K2, full[:, 1], dt, force_dofs=[1])
    np.testing.assert_allclose(r0.x + r1.x, ref.x, rtol=0, atol=1e-15)


def test_free_vibration_undamped_closed_form():
    m, k = 2.0, 12.0
    w = np.sqrt(k / m)
    dt, n = 0.1, 200
    r = exact_response([[m]], [[0.0]], [[k]], np.zeros(n + 1), dt, x0=[0.5], v0=[1.5])
    t = r.t
    np.testing.assert_allclose(r.x[:, 0], 0.5 * np.cos(w * t) + 1.5 / w * np.sin(w * t),
                               rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- (3) bad inputs
def _msg(excinfo):
    return str(excinfo.value)


@pytest.mark.parametrize("dt", [0.0, -0.1, np.nan, "x"])
def test_bad_dt(dt):
    with pytest.raises(ValueError, match="dt"):
        exact_response(M2, C2, K2, np.ones((11, 2)), dt)


@pytest.mark.parametrize("n_samples", [0, 1])
def test_too_few_samples(n_samples):
    with pytest.raises(ValueError, match="force has"):
        exact_response(M2, C2, K2, np.ones((n_samples, 2)), 0.1)


def test_nan_force():
    f = np.ones((11, 2))
    f[3, 1] = np.nan
    with pytest.raises(ValueError, match="force") as e:
        exact_response(M2, C2, K2, f, 0.1)
    assert "[3, 1]" in _msg(e)


def test_force_wrong_shape():
    with pytest.raises(ValueError, match="force"):
        exact_response(M2, C2, K2, np.ones((10, 3)), 0.1)


@pytest.mark.parametrize("Mbad", [np.array([[1.0, 2.0], [2.0, 4.0]]), np.diag([1.0, 1e-30])])
def test_singular_mass(Mbad):
    """Singular M that is not a set of massless DOFs (zero rows and columns) is refused."""
    with pytest.raises(ValueError, match="M is singular"):
        exact_response(Mbad, C2, K2, np.ones((11, 2)), 0.1)


def test_no_mass_at_all():
    """M = 0 leaves C q' + K q = f: one DOF under a step, q = f/k (1 - exp(-k t / c))."""
    c, k, dt, n = 2.0, 5.0, 0.01, 300
    r = exact_response([[0.0]], [[c]], [[k]], np.ones(n + 1), dt)
    t = r.t
    np.testing.assert_allclose(r.x[:, 0], (1 - np.exp(-k * t / c)) / k, rtol=0, atol=1e-14)
    np.testing.assert_allclose(r.v[:, 0], np.exp(-k * t / c) / c, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="C at the massless DOFs"):
        exact_response(np.zeros((2, 2)), np.zeros((2, 2)), K2, np.ones((11, 2)), 0.1)


def test_mismatched_K_shape():
    with pytest.raises(ValueError, match=r"^K has shape \(3, 3\)"):
        exact_response(M2, C2, np.eye(3), np.ones((11, 2)), 0.1)


def test_non_square_and_non_finite_matrices():
    with pytest.raises(ValueError, match="^C must be a non-empty square"):
        exact_response(M2, np.ones((2, 3)), K2, np.ones((11, 2)), 0.1)
    Kbad = K2.copy()
    Kbad[0, 1] = np.inf
    with pytest.raises(ValueError, match=r"^K\[0, 1\]"):
        exact_response(M2, C2, Kbad, np.ones((11, 2)), 0.1)
    with pytest.raises(ValueError, match="^M must be a non-empty square"):
        exact_response(np.ones(2), C2, K2, np.ones((11, 2)), 0.1)


def test_bad_indices_and_initial_conditions():
    f = np.ones((11, 1))
    with pytest.raises(ValueError, match="force_dofs"):
        exact_response(M2, C2, K2, f, 0.1, force_dofs=[2])
    with pytest.raises(ValueError, match="outputs"):
        exact_response(M2, C2, K2, np.ones((11, 2)), 0.1, outputs=[0, 0])
    with pytest.raises(ValueError, match="x0"):
        exact_response(M2, C2, K2, np.ones((11, 2)), 0.1, x0=[1.0])
    with pytest.raises(ValueError, match="v0"):
        exact_response(M2, C2, K2, np.ones((11, 2)), 0.1, v0=[1.0, np.nan])
