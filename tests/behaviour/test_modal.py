"""Modal models (poles and residues) for the modal digital filters: reference.md section 6."""
import dataclasses
import warnings

import numpy as np
import pytest
import scipy.linalg as sla

from dtdyn.linear._chain import DtdynAccuracyWarning, chain_matrices
from dtdyn.modal._model import ModalModel, from_poles_residues, modal_model

from problems import P3

POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}


def direct_frf(M, C, K, omega, inputs, outputs, quantity="displacement"):
    """(K - omega^2 M + j omega C)^-1 restricted to outputs x inputs, times (j omega)^p."""
    out = []
    for w in omega:
        H = np.linalg.solve(K - w**2 * M + 1j * w * C, np.eye(M.shape[0]))
        out.append(H[np.ix_(outputs, inputs)] * (1j * w) ** POWER[quantity])
    return np.array(out)


def max_rel(H, ref):
    """max over frequencies of ||H - ref||_F / ||ref||_F."""
    return max(np.linalg.norm(a - b) / np.linalg.norm(b) for a, b in zip(H, ref))


def proportional_3dof():
    M, _, K = chain_matrices([2.0, 3.0, 1.5], [1000.0, 800.0, 600.0], [0.0, 0.0, 0.0])
    return M, 0.5 * M + 1e-3 * K, K


def damper_5dof():
    """5-DOF chain with light proportional damping plus a discrete damper between DOFs 2 and 4
    (1-based; indices 1 and 3): non-proportional."""
    M, C, K = chain_matrices([1.0, 2.0, 1.5, 1.0, 0.8], [4000.0, 3000.0, 3500.0, 2000.0, 1500.0],
                             [0.4, 0.3, 0.3, 0.2, 0.2])
    cd = 25.0
    C[1, 1] += cd
    C[3, 3] += cd
    C[1, 3] -= cd
    C[3, 1] -= cd
    return M, C, K


def p3():
    return chain_matrices(P3["mass"], P3["stiffness"], P3["damping"])


def overdamped_2dof():
    return chain_matrices([1.0, 1.0], [100.0, 100.0], [500.0, 500.0])


SYSTEMS = {"proportional_3dof": proportional_3dof, "damper_5dof": damper_5dof, "p3": p3,
           "overdamped_2dof": overdamped_2dof}


def test_damper_system_is_non_proportional():
    M, C, K = damper_5dof()
    Minv = np.linalg.inv(M)
    assert np.linalg.norm(C @ Minv @ K - K @ Minv @ C) > 1e-3 * np.linalg.norm(K @ Minv @ C)


def frequency_grid(model, n=20):
    """n frequencies from low to above the last mode, away from the poles (undamped P3)."""
    f = model.omega
    pos = np.linspace(-0.7, f.size - 0.3, n)
    pos = np.floor(pos) + 0.25 + 0.5 * (pos - np.floor(pos))  # never within 1/4 gap of a mode
    omega = np.interp(pos, np.arange(-1, f.size + 1), np.concatenate([[0.0], f, [1.5 * f[-1]]]))
    top = f[-1]
    wd = model.poles.imag[model.oscillatory]
    assert wd.size == 0 or np.min(np.abs(omega[:, None] - wd[None, :])) > 1e-3 * top
    assert omega.size == n and np.all(np.diff(omega) > 0)
    return omega


@pytest.mark.parametrize("name", sorted(SYSTEMS))
@pytest.mark.parametrize("quantity", ["displacement", "velocity", "acceleration"])
def test_modal_frf_equals_direct_solve(name, quantity):
    M, C, K = SYSTEMS[name]()
    n = M.shape[0]
    model = modal_model(M, C, K, None, None)
    assert model.residues.shape == (model.n_modes, n, n)
    omega = frequency_grid(model)
    H = model.frequency_response(omega, quantity)
    assert H.shape == (20, n, n)
    assert max_rel(H, direct_frf(M, C, K, omega, range(n), range(n), quantity)) < 1e-10


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_frf_subset_of_dofs(name):
    M, C, K = SYSTEMS[name]()
    n = M.shape[0]
    inputs, outputs = [n - 1, 0], [0, n // 2]
    model = modal_model(M, C, K, inputs, outputs)
    assert model.force_dofs.tolist() == inputs and model.outputs.tolist() == outputs
    omega = frequency_grid(model)
    ref = direct_frf(M, C, K, omega, inputs, outputs)
    assert max_rel(model.frequency_response(omega), ref) < 1e-10


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_poles_equal_state_space_eigenvalues(name):
    M, C, K = SYSTEMS[name]()
    n = M.shape[0]
    model = modal_model(M, C, K, [0], [0])
    Minv = np.linalg.inv(M)
    eig = np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]]))
    ours = np.concatenate([model.poles, np.conj(model.poles[model.oscillatory])])
    assert ours.size == 2 * n
    scale = np.abs(eig).max()
    for lam in eig:  # a one-to-one match (the eigenvalues here are distinct)
        j = np.argmin(np.abs(ours - lam))
        assert abs(ours[j] - lam) < 1e-10 * scale
        ours = np.delete(ours, j)
    assert np.all(np.diff(model.omega) >= 0)
    np.testing.assert_allclose(model.omega, np.abs(model.poles))
    np.testing.assert_allclose(model.damping_ratio, -model.poles.real / np.abs(model.poles))
    assert np.array_equal(model.oscillatory, model.poles.imag > 0)


def test_p3_undamped_frequencies():
    M, C, K = p3()
    model = modal_model(M, C, K, [14], [14])
    ref = np.sqrt(sla.eigh(K, M, eigvals_only=True))
    assert model.n_modes == 15 and model.oscillatory.all()
    np.testing.assert_allclose(model.omega, ref, rtol=1e-10, atol=0)
    np.testing.assert_allclose(model.poles.imag, ref, rtol=1e-10, atol=0)
    assert np.abs(model.damping_ratio).max() < 1e-12
    assert model.omega[0] == pytest.approx(9.49, abs=0.01)
    assert model.omega[-1] == pytest.approx(148.2, abs=0.05)


def test_proportional_residues_are_classical():
    """Proportional damping: R_r = u_r u_r^T / (2 j omega_d), u_r mass-normalized."""
    M, C, K = proportional_3dof()
    lam, U = sla.eigh(K, M)
    w = np.sqrt(lam)
    zeta = 0.5 / (2 * w) + 1e-3 * w / 2
    wd = w * np.sqrt(1 - zeta**2)
    model = modal_model(M, C, K, None, None)
    np.testing.assert_allclose(model.poles, -zeta * w + 1j * wd, rtol=1e-12)
    np.testing.assert_allclose(model.damping_ratio, zeta, rtol=1e-10)
    for r in range(3):
        ref = np.outer(U[:, r], U[:, r]) / (2j * wd[r])
        assert np.linalg.norm(model.residues[r] - ref) < 1e-12 * np.linalg.norm(ref)


def test_one_dof_analytic():
    m, k, c = 2.0, 12.0, 3.0  # P1
    model = modal_model([[m]], [[c]], [[k]], [0], [0])
    wd = np.sqrt(k / m - (c / (2 * m)) ** 2)
    assert model.poles[0] == pytest.approx(-c / (2 * m) + 1j * wd, rel=1e-14)
    assert model.residues[0, 0, 0] == pytest.approx(1 / (2j * m * wd), rel=1e-13)


def test_overdamped_real_poles():
    M, C, K = overdamped_2dof()
    model = modal_model(M, C, K, [1], [0, 1])
    assert (~model.oscillatory).sum() >= 2
    real = ~model.oscillatory
    assert np.all(model.poles[real].imag == 0) and np.all(model.poles[real].real < 0)
    assert np.all(model.residues[real].imag == 0)
    np.testing.assert_allclose(model.damping_ratio[real], 1.0)
    # all four poles are real here: four modes
    assert model.n_modes == 4 and not model.oscillatory.any()
    # the FRF (real poles summed once, no conjugate) is checked in the parametrized tests


def test_repeated_eigenvalues():
    """Identical uncoupled oscillators: a double pole, not B-biorthogonal from LAPACK."""
    M, C, K = np.diag([1.0, 2.0, 1.0]), np.diag([0.1, 0.2, 0.1]), np.diag([4.0, 8.0, 4.0])
    model = modal_model(M, C, K, None, None)
    omega = np.linspace(0.3, 5.0, 20)
    assert max_rel(model.frequency_response(omega), direct_frf(M, C, K, omega, range(3),
                                                               range(3))) < 1e-12


def test_rigid_body_raises():
    m = np.array([1.0, 2.0, 1.5])
    k = np.array([0.0, 300.0, 200.0])
    # free-free, undamped: a double pole at s = 0 (chain_matrices refuses a station with
    # k = c = 0, so the ground damper is only there to assemble M and K; C = 0 is passed)
    M, _, K = chain_matrices(m, k, [1.0, 0, 0])
    with pytest.raises(ValueError, match=r"rigid-body mode\(s\).*not supported by the modal "
                                         r"filters: 2 pole\(s\) at s = 0"):
        modal_model(M, np.zeros((3, 3)), K, [0], [0])
    # damped to ground only: one pole at s = 0
    M, C, K = chain_matrices(m, k, [2.0, 0.5, 0.5])
    with pytest.raises(ValueError, match=r"rigid-body.*1 pole\(s\) at s = 0"):
        modal_model(M, C, K, [0], [0])


def test_critically_damped_is_refused_and_near_critical_warns():
    with pytest.raises(ValueError, match="defective"):
        modal_model([[1.0]], [[2.0]], [[1.0]], [0], [0])
    with pytest.warns(DtdynAccuracyWarning, match="nearly critically damped"):
        model = modal_model([[1.0]], [[2.0 + 1e-9]], [[1.0]], [0], [0])
    omega = np.linspace(0.1, 5, 20)
    assert max_rel(model.frequency_response(omega),
                   direct_frf(np.eye(1), np.eye(1) * (2 + 1e-9), np.eye(1), omega, [0], [0])) < 1e-6
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        modal_model([[1.0]], [[2.001]], [[1.0]], [0], [0])


def test_select_keeps_the_right_modes():
    M, C, K = damper_5dof()
    full = modal_model(M, C, K, [4], [0, 4])
    part = full.select([3, 0])
    np.testing.assert_array_equal(part.poles, full.poles[[0, 3]])
    np.testing.assert_array_equal(part.residues, full.residues[[0, 3]])
    np.testing.assert_array_equal(part.oscillatory, full.oscillatory[[0, 3]])
    assert part.force_dofs.tolist() == [4] and part.outputs.tolist() == [0, 4]
    rest = full.select([1, 2, 4])
    omega = np.linspace(1, 150, 20)
    np.testing.assert_allclose(part.frequency_response(omega) + rest.frequency_response(omega),
                               full.frequency_response(omega), rtol=1e-12, atol=0)
    via_arg = modal_model(M, C, K, [4], [0, 4], modes=[0, 3])
    np.testing.assert_allclose(via_arg.poles, part.poles, rtol=1e-14)
    np.testing.assert_allclose(via_arg.residues, part.residues, rtol=1e-12)
    for bad, msg in [([5], r"outside 0\.\.4"), ([1, 1], "repeats"), ([], "non-empty"),
                     ([0.5], "integer"), ([-1], "outside")]:
        with pytest.raises(ValueError, match=msg):
            full.select(bad)


def test_from_poles_residues_roundtrip():
    M, C, K = overdamped_2dof()
    C = C * 0.01  # mixed: oscillatory modes
    for M_, C_, K_ in [(M, C, K), damper_5dof(), overdamped_2dof()]:
        model = modal_model(M_, C_, K_, [0], [0, 1])
        again = from_poles_residues(model.poles, model.residues, model.force_dofs, model.outputs)
        np.testing.assert_array_equal(again.poles, model.poles)
        np.testing.assert_array_equal(again.residues, model.residues)
        np.testing.assert_array_equal(again.oscillatory, model.oscillatory)
        # given in any order: sorted by |s|
        perm = np.arange(model.n_modes)[::-1]
        again = from_poles_residues(model.poles[perm], model.residues[perm], [0], [0, 1])
        np.testing.assert_array_equal(again.poles, model.poles)
        omega = np.linspace(0.5, 200, 20)
        np.testing.assert_allclose(again.frequency_response(omega, "acceleration"),
                                   model.frequency_response(omega, "acceleration"), rtol=1e-13)


def test_from_poles_residues_siso_and_undamped():
    # one undamped mode (Re s = 0 allowed) and one real pole, 1-D residues
    model = from_poles_residues([-3.0, 10j], [0.5, -0.05j])
    assert model.oscillatory.tolist() == [False, True]  # sorted: |-3| < |10j|
    assert model.residues.shape == (2, 1, 1) and model.force_dofs.tolist() == [0]
    np.testing.assert_allclose(model.damping_ratio, [1.0, 0.0])
    s = 1j * np.array([1.0, 2.0])
    ref = 0.5 / (s + 3) + (-0.05j) / (s - 10j) + 0.05j / (s + 10j)
    np.testing.assert_allclose(model.frequency_response([1.0, 2.0])[:, 0, 0], ref, rtol=1e-14)
    # a single-DOF oscillator: x/F = 1/(m (s^2 + 2 zeta w s + w^2))
    w, zeta, m = 7.0, 0.02, 3.0
    p = -zeta * w + 1j * w * np.sqrt(1 - zeta**2)
    one = from_poles_residues([p], [1 / (2j * m * p.imag)], force_dofs=[3], outputs=[5])
    om = np.array([2.0, 7.0, 11.0])
    ref = 1 / (m * (-(om**2) + 2j * zeta * w * om + w**2))
    np.testing.assert_allclose(one.frequency_response(om)[:, 0, 0], ref, rtol=1e-13)
    assert one.force_dofs.tolist() == [3] and one.outputs.tolist() == [5]
    # real pole given a round-off imaginary residue part: dropped
    assert from_poles_residues([-2.0], [1.0 + 1e-17j]).residues[0, 0, 0].imag == 0


@pytest.mark.parametrize("poles, residues, kw, msg", [
    ([0.1 + 5j], [1j], {}, "unstable pole"),
    ([2.0], [1.0], {}, "unstable pole"),
    ([0.0], [1.0], {}, r"rigid-body.*s = 0"),
    ([-1 - 5j], [1j], {}, "Im s < 0"),
    ([np.nan], [1.0], {}, "not finite"),
    ([-1 + 5j], [np.inf], {}, "not finite"),
    ([-1 + 5j, -2 + 3j], [1j], {}, "residues has shape"),
    ([-1 + 5j], np.ones((1, 2, 1)), {}, "residues has shape"),
    ([-1 + 5j], np.ones((1, 1, 2)), {"force_dofs": [0, 1], "outputs": [2, 3]},
     "residues has shape"),
    ([-2.0], [1j], {}, "real pole needs a real residue"),
    ([], [], {}, "non-empty"),
    ([-1 + 5j], [1j], {"force_dofs": [0, 0]}, "repeats"),
    ([-1 + 5j], [1j], {"outputs": [-1]}, "outside"),
    ([-1 + 5j], [1j], {"force_dofs": [0.5]}, "integer"),
    ("abc", [1j], {}, "poles must be numeric"),
])
def test_from_poles_residues_errors(poles, residues, kw, msg):
    with pytest.raises(ValueError, match=msg):
        from_poles_residues(poles, residues, **kw)


def test_roundoff_positive_real_part_is_undamped():
    model = from_poles_residues([1e-15 + 10j], [0.1j])
    assert model.damping_ratio[0] == pytest.approx(0, abs=1e-15)


def test_modal_model_errors():
    M, C, K = proportional_3dof()
    with pytest.raises(ValueError, match="force_dofs"):
        modal_model(M, C, K, [3], [0])
    with pytest.raises(ValueError, match="outputs.*repeats"):
        modal_model(M, C, K, [0], [1, 1])
    with pytest.raises(ValueError, match="force_dofs"):
        modal_model(M, C, K, [0.5], [0])
    with pytest.raises(ValueError, match=r"^M is singular"):
        modal_model(np.diag([1.0, 0.0, 1.0]), C, K, [0], [0])
    with pytest.raises(ValueError, match=r"C has shape"):
        modal_model(M, C[:2, :2], K, [0], [0])
    with pytest.raises(ValueError, match=r"K\[0, 1\]"):
        K2 = K.copy()
        K2[0, 1] = np.nan
        modal_model(M, C, K2, [0], [0])
    with pytest.raises(ValueError, match="unstable pole"):
        modal_model(M, -C, K, [0], [0])
    with pytest.raises(ValueError, match="modes"):
        modal_model(M, C, K, [0], [0], modes=[3])


def test_frequency_response_errors_and_scalar():
    model = modal_model(*proportional_3dof(), [0], [2])
    with pytest.raises(ValueError, match="quantity"):
        model.frequency_response([1.0], "force")
    with pytest.raises(ValueError, match="omega"):
        model.frequency_response([1.0, np.nan])
    with pytest.raises(ValueError, match="omega"):
        model.frequency_response(np.ones((2, 2)))
    assert model.frequency_response(3.0).shape == (1, 1, 1)
    # omega = 0: the static flexibility K^-1
    M, C, K = proportional_3dof()
    assert model.frequency_response(0.0)[0, 0, 0] == pytest.approx(np.linalg.inv(K)[2, 0],
                                                                   rel=1e-12)


def test_model_is_immutable_and_validated():
    model = modal_model(*proportional_3dof(), [0], [2])
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.poles = model.poles
    with pytest.raises(ValueError, match="read-only"):
        model.residues[0, 0, 0] = 1.0
    with pytest.raises(ValueError, match="sorted"):
        ModalModel(model.poles[::-1], model.residues[::-1], model.oscillatory, [0], [2])
    with pytest.raises(ValueError, match="oscillatory"):
        ModalModel(model.poles, model.residues, ~model.oscillatory, [0], [2])
    with pytest.raises(ValueError, match="real residue"):
        ModalModel(np.array([-1.0 + 0j]), np.array([[[1j]]]), np.array([False]), [0], [0])
