"""Beam mode shapes and frequency responses over the node blocks (issue #14, item 4).

Truths: scipy.linalg.eigh and a dense solve on beam_matrices, and the closed-form receptance of
a uniform cantilever written here.
Shapes: inverse iteration with the sweep, finished by one pivoted banded step (backward stable:
LU with partial pivoting of a band matrix with l = 3 sub-diagonals has growth at most
2^(2l) = 64, and each row sums 2l + 1 = 7 terms, so its residual is at most about
64 * 7 eps ||K|| ||phi||, asserted as 500 eps; measured <= 0.3 eps). Each shape is then held to
the rigorous a posteriori bound of both computations: with rho = phi^T K phi (phi^T M phi = 1)
and r = K phi - rho M phi, the M-angle to the true eigenvector is at most
theta = ||r||_{M^-1} / gap (Davis-Kahan), so ||phi_sweep - phi_eigh||_M <= theta_sweep +
theta_eigh; eigh's own error is of order eps lambda_max / gap, 1e-7 .. 1e-9 for the lowest
shapes of a 200-element beam (lambda_max / lambda_1 ~ 1e10 to 1e11).
Responses: the pivoted banded LU and LAPACK's dense LU both solve Z(omega) u = f backward
stably, each to a relative error of about eps cond(Z) with a small constant (the growth of
partial pivoting, modest in practice); two of them differ by at most their sum, held to
4 eps cond(Z) |u|_max. cond ~ 1e6 .. 1e9 for these 40-element beams, so 1e-10 relative is out of
reach at low frequency. Undamped beams are checked between their resonances too, where the
unpivoted sweep loses accuracy (element growth) and the pivoted solve does not.
"""
import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd

E, I, RHO_A, LENGTH = 2.1e11, 8.0e-6, 20.0, 3.0


def _eta(K, M, phi):
    """||r||_{M^-1}, rho and ||r||_2 of an M-normalized phi, r = K phi - rho M phi."""
    rho = phi @ K @ phi
    r = K @ phi - rho * (M @ phi)
    return float(np.sqrt(r @ np.linalg.solve(M, r))), rho, float(np.linalg.norm(r))


@pytest.mark.parametrize("left, right", [("clamped", "free"), ("pinned", "pinned")])
def test_modes_equal_eigh_within_the_a_posteriori_bound(left, right):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=200, left=left, right=right)
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    m = dd.beam_modes(beam, count=8)
    lam_all, V = sla.eigh(K, M)
    assert m.dof_names == beam.dof_names
    norm_K = np.linalg.norm(K, 2)
    theta = np.empty(8)  # the bound on each shape's M-angle to the true eigenvector
    for r in range(8):
        phi, v = m.shapes[:, r], V[:, r] * np.sign(V[:, r] @ M @ m.shapes[:, r])
        (eta_s, rho_s, res), (eta_e, rho_e, _) = _eta(K, M, phi), _eta(K, M, v)
        assert res <= 500 * np.finfo(float).eps * norm_K * np.linalg.norm(phi), r
        others = np.delete(lam_all, r)
        gap = min(np.abs(others - rho_s).min(), np.abs(others - rho_e).min())
        theta[r] = eta_s / gap
        d = phi - v
        assert np.sqrt(d @ M @ d) <= (eta_s + eta_e) / gap, r
    # two shapes at M-angles theta_r, theta_s to orthogonal eigenvectors: |phi_r^T M phi_s| <=
    # sin theta_r + sin theta_s; the diagonal is 1 to rounding (n eps)
    G = m.shapes.T @ M @ m.shapes
    bound = theta[:, None] + theta[None, :]
    np.fill_diagonal(bound, M.shape[0] * np.finfo(float).eps)
    assert np.all(np.abs(G - np.eye(8)) <= bound)
    np.testing.assert_array_equal(m.omega, dd.beam_frequencies(beam, count=8))


@pytest.mark.parametrize("left, right", [("clamped", "free"), ("pinned", "pinned"),
                                         ("sliding", "pinned")])
def test_undamped_response_between_resonances_equals_direct_solve(left, right):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=40, left=left, right=right)
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    wn = dd.beam_frequencies(beam, count=10)
    w = np.r_[0.0, 0.5 * (wn[:-1] + wn[1:]), wn[:5] * (1 + 1e-6)]
    n = beam.n_dof
    for f, o in ((n - 1, 0), ("w20", "w20"), ("psi30", "w10")):
        H = dd.beam_frequency_response(beam, w, f, o)
        fi = beam.dof(f) if isinstance(f, str) else f
        oi = beam.dof(o) if isinstance(o, str) else o
        for x, h in zip(w, H):
            Z = K - x * x * M
            col = np.linalg.solve(Z, np.eye(n)[fi])
            tol = 4 * np.finfo(float).eps * np.linalg.cond(Z) * np.abs(col).max()
            assert abs(h - col[oi]) <= tol, (x, abs(h - col[oi]) / np.abs(col).max())


@pytest.mark.parametrize("left, right", [("clamped", "free"), ("pinned", (1e6, 1e4)),
                                         ("sliding", "pinned")])
def test_frequency_response_equals_direct_solve(left, right):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=40, left=left, right=right,
                   rayleigh=(0.5, 1e-5), point_masses=[dd.PointMass(12, 4.0, 0.3)],
                   supports=[dd.Support(20, k_w=3e5, c_w=40.0, c_psi=2.0)])
    M, C, K = (A.toarray() for A in dd.beam_matrices(beam))
    w = np.array([0.0, 5.0, 80.0, 700.0, 4e3])
    n = beam.n_dof
    for f, o in (("w20", "w20"), ("psi30", "w10"), (n - 1, 0)):
        H = dd.beam_frequency_response(beam, w, f, o)
        fi = beam.dof(f) if isinstance(f, str) else f
        oi = beam.dof(o) if isinstance(o, str) else o
        for x, h in zip(w, H):
            Z = K + 1j * x * C - x * x * M
            col = np.linalg.solve(Z, np.eye(n)[fi])
            tol = 4 * np.finfo(float).eps * np.linalg.cond(Z) * np.abs(col).max()
            assert abs(h - col[oi]) <= tol, (x, abs(h - col[oi]) / np.abs(col).max())
    # several loaded DOFs and outputs at once: (omega, outputs, force_dofs), the columns of
    # the dense inverse
    fs, os = ["w20", "psi30", n - 1], [0, "w10", "w20"]
    H = dd.beam_frequency_response(beam, w, force_dofs=fs, outputs=os)
    assert H.shape == (w.size, 3, 3)
    fi = [beam.dof(f) if isinstance(f, str) else f for f in fs]
    oi = [beam.dof(o) if isinstance(o, str) else o for o in os]
    for x, h in zip(w, H):
        Z = K + 1j * x * C - x * x * M
        ref = np.linalg.inv(Z)[np.ix_(oi, fi)]
        tol = 4 * np.finfo(float).eps * np.linalg.cond(Z) * np.abs(ref).max()
        assert np.abs(h - ref).max() <= tol


def test_exact_field_matrix_gives_the_cantilever_tip_receptance():
    """w(x) = A (cosh bx - cos bx) + B (sinh bx - sin bx) holds w(0) = w'(0) = 0; M(L) = 0 and
    V(L) = F give A, B, and the tip receptance
    w(L) / F = (sin bL cosh bL - cos bL sinh bL) / (EI b^3 (1 + cos bL cosh bL)),
    b^4 = rho_A omega^2 / EI (static limit L^3 / (3 EI)). Five exact elements reproduce it, to
    rounding, where 5 Hermite elements are off by their discretization error."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=5)
    w = np.array([1.0, 30.0, 150.0, 900.0, 2500.0, 6000.0])
    H = dd.beam_frequency_response(beam, w, "w5", "w5", exact=True)
    EI = E * I
    bL = (RHO_A * w**2 / EI) ** 0.25 * LENGTH
    b = bL / LENGTH
    ref = (np.sin(bL) * np.cosh(bL) - np.cos(bL) * np.sinh(bL)) / (
        EI * b**3 * (1 + np.cos(bL) * np.cosh(bL)))
    assert np.abs(H.real / ref - 1).max() <= 1e-10
    assert np.abs(H.imag).max() == 0.0
    fe = dd.beam_frequency_response(beam, w, "w5", "w5")
    assert np.abs(fe.real / ref - 1).max() > 1e-4  # the Hermite model's own error


def test_bad_inputs_are_named():
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=4, rayleigh=(0.1, 0.0))
    with pytest.raises(ValueError, match=r"rayleigh = \(0.1, 0.0\) with exact=True"):
        dd.beam_frequency_response(beam, [1.0], "w4", "w4", exact=True)
    with pytest.raises(ValueError, match=r"omega = \[nan\]"):
        dd.beam_frequency_response(beam, [np.nan], "w4", "w4")
    with pytest.raises(ValueError, match=r"force_dofs: no DOF named 'w0'"):
        dd.beam_frequency_response(beam, [1.0], "w0", "w4")
    with pytest.raises(ValueError, match=r"count must be an integer >= 1, got 0"):
        dd.beam_modes(beam, count=0)
