"""Chains with springs and dampers to the ground at any mass, and Rayleigh damping in chain form.

The DT-TMM station matrix of a grounded mass (f_R = f_L + m a + kg x + cg v, derive/dttmm.py)
against the assembled-matrix solution of the same scheme, which solves the same tridiagonal
system each step: equal to rounding, 1e-10 relative as for plain chains (tests/test_dttmm.py).
The Laplace-domain TMM against a direct solve of (K + j w C - w^2 M) x = F, and the chain form
of Rayleigh damping against alpha M + beta K and the modal damping ratios it implies.
"""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated.scheme_table import TABLE  # the built-in schemes, in order

from problems import P3, rel_error

TOL = 1e-10
IMPLICIT = [s for s in TABLE if s != "central_difference"]


def _grounded(n=8, seed=3):
    """A random chain with springs to the ground at some masses and dampers at others."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(1.0, 3.0, n)
    k = rng.uniform(5e3, 2e4, n)
    c = rng.uniform(0.0, 2.0, n)
    kg = np.where(rng.random(n) < 0.5, rng.uniform(1e3, 5e4, n), 0.0)
    cg = np.where(rng.random(n) < 0.5, rng.uniform(0.5, 20.0, n), 0.0)
    return m, k, c, kg, cg


def _reference(m, k, c, kg, cg, F, dt, scheme, **kw):
    M, C, K = dd.chain_matrices(m, k, c, ground_stiffness=kg, ground_damping=cg, sparse=False)
    return dd.mck_response(M, C, K, F, dt, force_dofs=[m.size - 1], scheme=scheme, **kw)


def test_chain_matrices_add_the_ground_elements_on_the_diagonal():
    m, k, c, kg, cg = _grounded()
    M0, C0, K0 = dd.chain_matrices(m, k, c, sparse=False)
    M, C, K = dd.chain_matrices(m, k, c, ground_stiffness=kg, ground_damping=cg)
    np.testing.assert_array_equal(M, M0)
    # the same sums in another order: equal to an ulp of the diagonal
    np.testing.assert_allclose(K, K0 + np.diag(kg), rtol=0, atol=4e-16 * np.abs(K).max())
    np.testing.assert_allclose(C, C0 + np.diag(cg), rtol=0, atol=4e-16 * np.abs(C).max())
    Ms, Cs, Ks = dd.chain_matrices(m, k, c, sparse=True, ground_stiffness=kg, ground_damping=cg)
    np.testing.assert_array_equal(Ks.toarray(), K)
    np.testing.assert_array_equal(Cs.toarray(), C)


@pytest.mark.parametrize("scheme", IMPLICIT)
@pytest.mark.parametrize("dt", [1e-2, 1e-4])
def test_grounded_chain_equals_assembled(scheme, dt):
    m, k, c, kg, cg = _grounded()
    n_steps = 1500
    F = np.sin(np.arange(n_steps + 1) * dt * 40.0)[:, None]
    ref = _reference(m, k, c, kg, cg, F, dt, scheme)
    for form in ("displacement", "acceleration"):
        for backend in ("c", "numpy"):
            r = dd.chain_response(m, k, c, F, dt, ground_stiffness=kg, ground_damping=cg,
                                  force_dofs=[m.size - 1], scheme=scheme, form=form,
                                  backend=backend)
            for q in "xva":
                err = rel_error(getattr(r, q), getattr(ref, q))
                assert err < TOL, (scheme, form, backend, q, err)


def test_central_difference_with_ground_dampers():
    m, k, c, kg, cg = _grounded()
    c = c + 0.5  # the explicit scheme's acceleration form needs a damper on every station
    F = np.ones((2001, 1))
    ref = _reference(m, k, c, kg, cg, F, 1e-4, "central_difference")
    for backend in ("c", "numpy"):
        r = dd.chain_response(m, k, c, F, 1e-4, ground_stiffness=kg, ground_damping=cg,
                              force_dofs=[m.size - 1], scheme="central_difference",
                              form="acceleration", backend=backend)
        assert rel_error(r.x, ref.x) < TOL


def test_plain_sweep_and_initial_conditions_with_ground_elements():
    """A start from x0, v0 (consistent a_0 with the ground spring and damper forces); the plain
    sweep loses accuracy like (m A / k)^N (here ~800 per mass) and its error estimate, which
    carries the ground terms through the error history, tracks that loss within the factor
    the plain-chain tests allow (tests/test_dttmm.py: 0.1 .. 10)."""
    m, k, c, kg, cg = _grounded(n=3, seed=5)
    kg[0] = 2e4  # a ground spring on the first mass too
    F = np.zeros((801, 1))
    x0, v0 = np.array([1e-3, -2e-3, 3e-3]), np.array([0.1, 0.0, -0.2])
    ref = _reference(m, k, c, kg, cg, F, 1e-3, "newmark", x0=x0, v0=v0)
    for sweep in ("stable", "plain"):
        for backend in ("c", "numpy"):
            r = dd.chain_response(m, k, c, F, 1e-3, ground_stiffness=kg, ground_damping=cg,
                                  force_dofs=[2], sweep=sweep, backend=backend, x0=x0, v0=v0)
            if sweep == "stable":
                for q in "xva":
                    assert rel_error(getattr(r, q), getattr(ref, q)) < TOL, (backend, q)
            else:
                err = rel_error(r.x, ref.x)
                assert 0.1 < r.info["error_estimate"] / err < 10, (backend, err)


def test_ground_spring_shifts_the_frequency_of_one_mass():
    """A single mass on two parallel springs: omega = sqrt((k + kg) / m), undamped; the DT-TMM
    with average acceleration keeps the period to its known elongation (Omega^2 / 12)."""
    m, k, kg, dt = 2.0, 800.0, 1200.0, 1e-3
    omega = np.sqrt((k + kg) / m)
    n = 2000
    r = dd.chain_response([m], [k], [0.0], np.zeros(n + 1), dt, ground_stiffness=[kg],
                          x0=[0.01], scheme="average_acceleration")
    t = dt * np.arange(n + 1)
    # the exact discrete solution of the trapezoidal rule: cos of the stretched frequency
    omega_d = 2.0 / dt * np.arctan(omega * dt / 2.0)
    np.testing.assert_allclose(r.x[:, 0], 0.01 * np.cos(omega_d * t), atol=1e-12)


def test_rayleigh_chain_damping_assembles_alpha_m_plus_beta_k():
    m, k, _, kg, _ = _grounded()
    alpha, beta = 0.7, 2e-3
    c, cg = dd.rayleigh_chain_damping(m, k, (alpha, beta), ground_stiffness=kg)
    M, C, K = dd.chain_matrices(m, k, c, ground_stiffness=kg, ground_damping=cg, sparse=False)
    np.testing.assert_allclose(C, alpha * M + beta * K, rtol=0, atol=1e-15 * np.abs(K).max())
    modes = dd.mck_modes(M, C, K)
    w = modes.omega
    np.testing.assert_allclose(modes.damping_ratio, alpha / (2 * w) + beta * w / 2, rtol=1e-10)


def test_rayleigh_p3_time_history_equals_assembled():
    """P3 with 2 % Rayleigh damping at its first and last modes, run as a chain."""
    w = dd.chain_frequencies(P3["mass"], P3["stiffness"])
    w1, w2 = w[0], w[-1]
    beta = 2 * 0.02 / (w1 + w2)
    alpha = beta * w1 * w2
    c, cg = dd.rayleigh_chain_damping(P3["mass"], P3["stiffness"], (alpha, beta))
    F = np.ones((801, 1))
    r = dd.chain_response(P3["mass"], P3["stiffness"], c, F, 1e-3, ground_damping=cg,
                          force_dofs=[14])
    M, C, K = dd.chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)
    ref = dd.mck_response(M, alpha * M + beta * K, K, F, 1e-3, force_dofs=[14])
    assert rel_error(r.x, ref.x) < TOL


def test_frequency_response_with_ground_elements_equals_direct_solve():
    m, k, c, kg, cg = _grounded()
    M, C, K = dd.chain_matrices(m, k, c, ground_stiffness=kg, ground_damping=cg, sparse=False)
    omega = np.linspace(1.0, 200.0, 37)
    H = dd.chain_frequency_response(m, k, c, omega, force_dofs=5, outputs=2,
                                    ground_stiffness=kg, ground_damping=cg)
    for w, h in zip(omega, H):
        x = np.linalg.solve(K + 1j * w * C - w * w * M, np.eye(m.size)[5])
        assert abs(h - x[2]) <= 1e-11 * abs(x).max()


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_nonlinear_chain_with_ground_elements_equals_mck_path(backend):
    m, k, c, kg, cg = _grounded(n=6)
    f = np.random.default_rng(1).normal(0.0, 50.0, (1001, 1))
    els = [dd.Cubic(0, k3=2e7), dd.Cubic(2, 3, k3=2e7)]
    M, C, K = dd.chain_matrices(m, k, c, ground_stiffness=kg, ground_damping=cg, sparse=False)
    a = dd.nonlinear_chain_response(m, k, c, f, 1e-3, ground_stiffness=kg, ground_damping=cg,
                                    force_dofs=[5], elements=els, backend=backend, substeps=2)
    b = dd.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[5], elements=els,
                              scheme="newmark", substeps=2)
    for q in "xva":
        assert rel_error(getattr(a, q), getattr(b, q)) < 1e-12


@pytest.mark.parametrize("field, kw, match", [
    ("ground_stiffness", dict(ground_stiffness=[1.0, -2.0]), r"ground_stiffness\[1\] = -2"),
    ("ground_damping", dict(ground_damping=[np.nan, 0.0]), r"ground_damping\[0\] = nan"),
    ("ground_stiffness", dict(ground_stiffness=[1.0]), "ground_stiffness"),
])
def test_bad_ground_elements_are_named(field, kw, match):
    with pytest.raises(ValueError, match=match):
        dd.chain_response([1.0, 1.0], [1e3, 1e3], [0.0, 0.0], np.ones(11), 1e-3, **kw)
    with pytest.raises(ValueError, match=match):
        dd.chain_matrices([1.0, 1.0], [1e3, 1e3], [0.0, 0.0], **kw)


def test_bad_rayleigh_coefficients_are_named():
    with pytest.raises(ValueError, match="rayleigh"):
        dd.rayleigh_chain_damping([1.0], [1e3], (-0.1, 0.0))
    with pytest.raises(ValueError, match="rayleigh"):
        dd.rayleigh_chain_damping([1.0], [1e3], (0.1,))
