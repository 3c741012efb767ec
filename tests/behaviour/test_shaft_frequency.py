"""Shaft mode shapes and frequency responses from the tree's sweep (issue #14, item 4).

Truths: scipy.linalg.eigh and a dense solve of (K + i w C - w^2 M) on the matrices assembled by
hand from each element's energy (test_shaft.hand_matrices), and closed forms of continuous
shafts written here. Tolerances: the shapes' rounding is of order eps lambda_max / gap
(Wilkinson) for the sweep and for eigh alike, below 1e-13 for these systems, so 1e-8 relative
leaves room and still catches a wrong shape; a direct solve and the sweep of the same linear
system agree to eps times the system's condition, below 1e-12 away from resonances, so 1e-10.
"""
import math

import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd
from test_shaft import SYSTEMS


def _same_up_to_sign(A, B):
    return np.minimum(np.abs(A - B).max(axis=0), np.abs(A + B).max(axis=0)) / np.abs(B).max(axis=0)


@pytest.mark.parametrize("name", SYSTEMS)
def test_modes_equal_eigh(name):
    s, (M, _, K), dofs = SYSTEMS[name]()
    lam, V = sla.eigh(K, M)
    m = dd.shaft_modes(s)
    assert m.dof_names == tuple(dofs)
    assert np.abs(m.omega**2 - lam).max() <= 1e-10 * lam.max()
    assert _same_up_to_sign(m.shapes, V).max() <= 1e-8
    assert np.abs(m.shapes.T @ M @ m.shapes - np.eye(len(dofs))).max() <= 1e-12
    assert np.abs(m.participation - m.shapes.T @ M @ m.influence).max() <= 1e-12
    few = dd.shaft_modes(s, count=2)
    np.testing.assert_array_equal(few.omega, m.omega[:2])
    assert _same_up_to_sign(few.shapes, m.shapes[:, :2]).max() <= 1e-12


def test_repeated_root_gives_an_orthonormal_eigenspace():
    """Three equal branches on one disk: the modes where they swing against each other (the
    disk at rest) are double roots. The returned pair must span eigh's eigenspace and be
    M-orthonormal."""
    br = [dd.Branch(1, [0.5, 0.4], [6e3, 5e3], name=n) for n in ("a", "b", "c")]
    s = dd.Shaft([1.0, 0.3], [1e4, 1.2e4], branches=br)
    M, _, K = (A.toarray() for A in dd.shaft_matrices(s))
    lam, V = sla.eigh(K, M)
    m = dd.shaft_modes(s)
    double = np.flatnonzero(np.diff(lam) <= 1e-9 * lam[1:])
    assert double.size >= 1
    assert np.abs(m.shapes.T @ M @ m.shapes - np.eye(lam.size)).max() <= 1e-12
    resid = K @ m.shapes - M @ m.shapes * m.omega**2
    assert np.abs(resid).max() <= 1e-10 * np.abs(K).max()
    for j in double:  # same subspace: equal M-projectors
        P1 = m.shapes[:, j:j + 2] @ m.shapes[:, j:j + 2].T @ M
        P2 = V[:, j:j + 2] @ V[:, j:j + 2].T @ M
        assert np.abs(P1 - P2).max() <= 1e-9


@pytest.mark.parametrize("name", SYSTEMS)
def test_frequency_response_equals_direct_solve(name):
    s, (M, C, K), dofs = SYSTEMS[name]()
    w = np.array([0.0, 1.0, 17.0, 90.0, 260.0, 1e3])
    n = len(dofs)
    for f, o in ((n - 1, 0), (1, n - 1), (0, 0)):
        H = dd.shaft_frequency_response(s, w, dofs[f], o)
        ref = np.array([np.linalg.solve(K + 1j * x * C - x * x * M, np.eye(n)[f])[o] for x in w])
        assert np.abs(H - ref).max() <= 1e-10 * np.abs(ref).max()
    # every pair at once: (omega, outputs, force_dofs), the columns of the dense inverse
    H = dd.shaft_frequency_response(s, w, force_dofs=[dofs[n - 1], 0], outputs=[0, n - 1, 1])
    ref = np.array([np.linalg.inv(K + 1j * x * C - x * x * M)[np.ix_([0, n - 1, 1], [n - 1, 0])]
                    for x in w])
    assert H.shape == (w.size, 3, 2)
    assert np.abs(H - ref).max() <= 1e-10 * np.abs(ref).max()


def test_damped_continuous_clamped_free_tip_receptance():
    """phi(x) = A sinh(gamma x / L) solves rho J_p s^2 phi = G (1 + tau s) J_p phi'' with phi(0)
    = 0, and the tip torque is T = G (1 + tau s) J_p phi'(L) = z (1 + tau s) gamma A cosh(gamma),
    z = G J_p / L, gamma = s L sqrt(rho / (G (1 + tau s))): phi(L) / T = tanh(gamma) / (z (1 +
    tau s) gamma)."""
    L, G, Jp, rho, c_t = 2.0, 8e10, 1e-6, 7800.0, 3.0
    seg = dd.ContinuousShaft(L, G, Jp, rho, damping=c_t)
    s_ = dd.Shaft([0.0], [seg])
    w = np.linspace(10.0, 2.2e4, 57)
    H = dd.shaft_frequency_response(s_, w, "main.0", "main.0")
    s, z, tau = 1j * w, G * Jp / L, c_t * L / (G * Jp)
    gam = s * L * np.sqrt(rho / (G * (1 + tau * s)))
    ref = np.tanh(gam) / (z * (1 + tau * s) * gam)
    assert np.abs(H / ref - 1).max() <= 1e-10


def _clamped_clamped(J_d, E=(40, 60)):
    G, Jp, rho = 8e10, 1e-6, 7800.0
    a = dd.ContinuousShaft(0.4, G, Jp, rho, elements=E[0])
    b = dd.ContinuousShaft(0.6, G, Jp, rho, elements=E[1])
    return dd.Shaft([J_d], [a], right="clamped", right_stiffness=b), (G, Jp, rho)


def test_continuous_clamped_right_end_frequencies_and_response():
    """A shaft clamped at both ends (two segments, 0.4 m and 0.6 m, meeting at disk J_d):
    J_d = 0 gives j pi c / L; the receptance at the disk is 1 / (a_1 + a_2 - omega^2 J_d), a_i
    = z_i beta_i cot(beta_i), beta_i = omega L_i / c (each segment held at its far end)."""
    s, (G, Jp, rho) = _clamped_clamped(0.0)
    c = math.sqrt(G / rho)
    w = dd.shaft_frequencies(s, count=6)
    assert np.abs(w / (np.arange(1, 7) * math.pi * c / 1.0) - 1).max() <= 1e-12
    s, _ = _clamped_clamped(0.03)
    om = np.array([50.0, 3e3, 9e3, 1.3e4])
    H = dd.shaft_frequency_response(s, om, "main.0", "main.0")
    a = sum(G * Jp / Li * (om * Li / c) / np.tan(om * Li / c) for Li in (0.4, 0.6))
    assert np.abs(H / (1 / (a - om**2 * 0.03)) - 1).max() <= 1e-10
    # lumped (exact=False): the model of shaft_matrices, the points inside both segments
    M, C, K = (A.toarray() for A in dd.shaft_matrices(s))
    i = s.dof("main.0")
    Hl = dd.shaft_frequency_response(s, om, i, i, exact=False)
    ref = np.array([np.linalg.solve(K - x * x * M, np.eye(K.shape[0])[i])[i] for x in om])
    assert np.abs(Hl - ref).max() <= 1e-10 * np.abs(ref).max()
    assert s.dof_names[-1] == "main.right.e59"


def test_continuous_clamped_right_end_modes_closed_form():
    """The lumped clamped-clamped shaft (J_d = 0, both segments cut into pieces of one length h)
    is a uniform fixed-fixed chain, k = G J_p / h, m = rho J_p h, whose modes are exactly the
    sampled sines: phi_j(x_i) = sqrt(2 / (rho J_p L)) sin(j pi x_i / L) (mass-normalized: the
    sum of sin^2 over the n - 1 points is n / 2) and omega_j = 2 sqrt(k / m) sin(j pi h / (2 L))."""
    E = (20, 30)
    s, (G, Jp, rho) = _clamped_clamped(0.0, E)
    m = dd.shaft_modes(s, count=4)
    h = 1.0 / sum(E)
    x = np.empty(len(s.dof_names))
    for k, nm in enumerate(s.dof_names):  # main.0.e<j>, main.0, main.right.e<j>
        parts = nm.split(".")
        x[k] = (0.4 if len(parts) == 2 else
                int(parts[2][1:]) * h + (0.4 if parts[1] == "right" else 0.0))
    j = np.arange(1, 5)
    ref = np.sqrt(2 / (rho * Jp * 1.0)) * np.sin(np.outer(x, j) * math.pi)
    assert _same_up_to_sign(m.shapes, ref).max() <= 1e-10
    w = 2 * np.sqrt(G * Jp / h / (rho * Jp * h)) * np.sin(j * math.pi * h / 2)
    assert np.abs(m.omega / w - 1).max() <= 1e-12


def test_bad_inputs_are_named():
    s, _ = _clamped_clamped(0.0)
    with pytest.raises(ValueError, match=r"omega = \[-1.0\]"):
        dd.shaft_frequency_response(s, [-1.0], 0, 0)
    with pytest.raises(ValueError, match=r"outputs: no DOF named 'main.9'"):
        dd.shaft_frequency_response(s, [1.0], "main.0", "main.9")
    with pytest.raises(ValueError, match=r"force_dofs = 'main.0.e3' .* inside a lumped"):
        dd.shaft_frequency_response(s, [1.0], "main.0.e3", "main.0")
    with pytest.raises(ValueError, match=r"right_damping = 1.0: a ContinuousShaft"):
        dd.Shaft([1.0], [1.0], right="clamped",
                 right_stiffness=dd.ContinuousShaft(1.0, 1.0, 1.0, 1.0), right_damping=1.0)
    with pytest.raises(ValueError, match=r"count = 0"):
        dd.shaft_modes(s, count=0)
