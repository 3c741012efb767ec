"""`modes` against independent truths: scipy.linalg.eigh (frequencies, shapes up to sign), the
hand formulas of a 2-DOF chain, the sum of the effective masses, Rayleigh damping ratios
zeta_r = alpha / (2 omega_r) + beta omega_r / 2, and the eigenvalues of the first-order form."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sps

import dtdyn as dd


@pytest.fixture(scope="module")
def building():
    """A 5-storey shear building: floor masses 2e5 kg, storey stiffness 3e8 N/m (top 2e8)."""
    return dd.chain_matrices([2e5] * 5, [3e8] * 4 + [2e8], [0.0] * 5, sparse=False)


def test_equals_eigh_and_masses_sum_to_the_total(p3):
    m = dd.mck_modes(p3["M"], None, p3["K"])
    lam, phi = sla.eigh(p3["K"], p3["M"])
    np.testing.assert_allclose(m.omega, np.sqrt(lam), rtol=1e-12)
    dots = np.abs(np.einsum("ij,ij->j", m.shapes, p3["M"] @ phi))   # |phi_ours . M phi| = 1
    np.testing.assert_allclose(dots, 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.shapes.T @ p3["M"] @ m.shapes, np.eye(15), atol=1e-12)
    total = p3["mass"].sum()
    assert m.total_mass == pytest.approx(total, rel=1e-14)
    assert m.effective_mass.sum() == pytest.approx(total, rel=1e-12)
    assert m.omega[0] == pytest.approx(9.49, abs=0.01) and m.omega[-1] == pytest.approx(148.2,
                                                                                      abs=0.1)


def test_two_dof_by_hand():
    """m = 1, k1 = 2, k2 = 1: omega^2 = 2 -+ sqrt 2, phi ~ [1, 1 + sqrt 2] and [1, 1 - sqrt 2];
    Gamma_r = phi_r^T M 1 with phi_r^T M phi_r = 1."""
    M, _, K = dd.chain_matrices([1.0, 1.0], [2.0, 1.0], [0.0, 0.0], sparse=False)
    m = dd.mck_modes(M, None, K)
    s2 = np.sqrt(2.0)
    np.testing.assert_allclose(m.omega**2, [2 - s2, 2 + s2], rtol=1e-14)
    for r, v in enumerate(([1.0, 1 + s2], [1.0, 1 - s2])):
        v = np.array(v) / np.linalg.norm(v)
        v *= np.sign(v[np.argmax(np.abs(v))])
        np.testing.assert_allclose(m.shapes[:, r], v, atol=1e-14)
        assert m.participation[r] == pytest.approx(v.sum(), rel=1e-13)
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(2 - s2) / (2 * np.pi), rel=1e-14)


def test_influence_count_and_sparse_shift_invert(building):
    M, _, K = building
    full = dd.mck_modes(M, None, K)
    low = dd.mck_modes(M, None, K, count=2)
    np.testing.assert_allclose(low.omega, full.omega[:2], rtol=1e-13)
    sp = dd.mck_modes(sps.csr_matrix(M), None, sps.csr_matrix(K), count=2)
    np.testing.assert_allclose(sp.omega, full.omega[:2], rtol=1e-10)
    np.testing.assert_allclose(sp.shapes, full.shapes[:, :2], atol=1e-8)
    # a roof-only influence (r = e_4): the effective masses sum to m_4
    r = np.eye(5)[4]
    top = dd.mck_modes(M, None, K, influence=r)
    assert top.effective_mass.sum() == pytest.approx(2e5, rel=1e-12)
    # the first mode of a regular shear building carries most of the mass
    assert 0.75 < full.effective_mass_ratio[0] < 0.95


def test_rayleigh_damping_ratios_and_complex_modes(building):
    M, _, K = building
    alpha, beta = 0.5, 2e-3
    C = alpha * M + beta * K
    m = dd.mck_modes(M, C, K)
    np.testing.assert_allclose(m.damping_ratio, alpha / (2 * m.omega) + beta * m.omega / 2,
                               rtol=1e-12)
    np.testing.assert_allclose(np.abs(m.poles), m.omega, rtol=1e-12)   # |s| = omega_n
    # the damped frequency Im s = omega_n sqrt(1 - zeta^2) (hand formula, classical damping)
    np.testing.assert_allclose(m.omega_d, m.omega * np.sqrt(1 - m.damping_ratio**2), rtol=1e-12)
    assert m.to_dict()["omega_d_rad_s"] == m.omega_d.tolist()
    with pytest.warns(DeprecationWarning, match="omega_d"):
        np.testing.assert_allclose(m.damped_omega, m.omega, rtol=1e-12)   # the old |s|
    # classical damping: the complex shapes are the real ones (scaled to a largest entry 1)
    real = m.shapes / m.shapes[np.argmax(np.abs(m.shapes), axis=0), np.arange(5)]
    np.testing.assert_allclose(m.complex_shapes, real, atol=1e-12)
    # non-proportional damping (a damper at the first storey only): poles = the eigenvalues
    # of A of the first-order form
    Cn = np.zeros((5, 5))
    Cn[0, 0] = 4e6
    mn = dd.mck_modes(M, Cn, K)
    A, _ = dd.first_order_form(M, Cn, K)
    ev = np.linalg.eigvals(A)
    ev = np.sort_complex(ev[ev.imag > 0])
    np.testing.assert_allclose(np.sort_complex(mn.poles), ev, rtol=1e-10)
    assert np.abs(mn.complex_shapes.imag).max() > 1e-3   # genuinely complex


@pytest.mark.parametrize("call, match", [
    (lambda M, K: dd.mck_modes(M, None, K, count=9), "count = 9 exceeds"),
    (lambda M, K: dd.mck_modes(M, None, K, count=0), "count must be an integer"),
    (lambda M, K: dd.mck_modes(M, None, K + np.triu(K, 1)), "K is not symmetric"),
    (lambda M, K: dd.mck_modes(M, None, -K), "K is not positive semi-definite"),
    (lambda M, K: dd.mck_modes(np.diag([1.0, 0.0, 1.0, 1.0, 1.0]), None, K),
     "M is not positive definite"),
    (lambda M, K: dd.mck_modes(M, None, K, influence=[1.0, 2.0]), "influence has length 2"),
    (lambda M, K: dd.mck_modes(sps.csr_matrix(M), None, sps.csr_matrix(K)), "give count < 5"),
    (lambda M, K: dd.mck_modes(M, 1e9 * np.eye(5), K), "underdamped"),
])
def test_bad_input(building, call, match):
    M, _, K = building
    with pytest.raises(ValueError, match=match):
        call(M, K)
