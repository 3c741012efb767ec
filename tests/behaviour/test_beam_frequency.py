"""Beam mode shapes and frequency responses from the block Riccati sweep (issue #14, item 4).

Truths: scipy.linalg.eigh and a dense solve on beam_matrices, and the closed-form receptance of
a uniform cantilever written here. Shapes: any floating-point method that works on K (eigh
too) leaves an eigenvector error of order eps lambda_max / gap_r (Wilkinson's bound for a
backward error eps ||K||); for a 200-element beam lambda_max / lambda_1 ~ 1e10 to 1e11, so the
lowest shapes are good to 1e-7 .. 1e-9 only. Both eigh and the sweep carry it; the sweep's
elimination without pivoting passes near-singular pivots inside the spectrum (element growth),
measured at up to 34x the bound (pinned-pinned, mode 6: 4.7e-7; the others <= 10x): the test
allows 50x. Responses: the same linear system solved two ways agrees to eps cond(Z(omega))
relative to the solution (both backward stable); cond ~ 1e6 .. 1e9 for these 40-element beams,
so 1e-10 relative is out of reach at low frequency: each frequency is held to 4 eps cond.
"""
import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd

E, I, RHO_A, LENGTH = 2.1e11, 8.0e-6, 20.0, 3.0


def _up_to_sign(A, B):
    return np.minimum(np.abs(A - B).max(axis=0), np.abs(A + B).max(axis=0)) / np.abs(B).max(axis=0)


@pytest.mark.parametrize("left, right", [("clamped", "free"), ("pinned", "pinned")])
def test_modes_equal_eigh_within_the_rounding_bound(left, right):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=200, left=left, right=right)
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    m = dd.beam_modes(beam, count=8)
    lam, V = sla.eigh(K, M, subset_by_index=[0, 7])
    lam_max = sla.eigh(K, M, eigvals_only=True, subset_by_index=[K.shape[0] - 1] * 2)[0]
    edges = np.r_[0.0, lam, 2 * lam[-1]]
    gap = np.minimum(np.diff(edges)[:-1], np.diff(edges)[1:])
    bound = 50 * np.finfo(float).eps * lam_max / gap
    assert m.dof_names == beam.dof_names
    assert np.all(_up_to_sign(m.shapes, V) <= bound)
    assert np.abs(m.shapes.T @ M @ m.shapes - np.eye(8)).max() <= bound.max()
    np.testing.assert_array_equal(m.omega, dd.beam_frequencies(beam, count=8))


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
    with pytest.raises(ValueError, match=r"force_dof: no DOF named 'w0'"):
        dd.beam_frequency_response(beam, [1.0], "w0", "w4")
    with pytest.raises(ValueError, match=r"count must be an integer >= 1, got 0"):
        dd.beam_modes(beam, count=0)
