"""beam_frequencies mode by mode against LAPACK on the same matrices, with and without the x86
long double in the count (issue 29).

The reference is the 34-digit eigenvalue of the same (K, M) (`extended_eigenvalues` of
test_frequency_accuracy: mpmath inverse iteration). LAPACK (scipy eigh, dense) errs by about
eps lambda_max absolute; the refined roots by a few ulps relative, whatever the count's
arithmetic: the count only isolates each root and seeds the shift. Where LAPACK happens to be
exact (error 0), the yardstick is one ulp (eps).
"""
import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.linear import _beam as beam_module
from dtdyn.linear import _beam_frequency as beam_frequency
from test_frequency_accuracy import extended_eigenvalues

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0
EPS = np.finfo(float).eps
ENDS = [("pinned", "pinned"), ("free", "free"), ("clamped", "free")]


@pytest.fixture(params=["long double", "double"])
def precision(request, monkeypatch):
    """The count in the platform's long double (80-bit on x86), or forced to double as on
    platforms where long double is double (MSVC; the path every platform can take)."""
    if request.param == "double":
        monkeypatch.setattr(beam_module, "_WIDE", np.float64)
    return request.param


def _errors(beam, extra=()):
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    rigid = beam_module.rigid_body_modes(beam)
    modes = [rigid + j for j in (0, 1, 2, 3, 4, 5, 9, 30, 100) if rigid + j < beam.n_dof]
    modes += [beam.n_dof + j for j in extra]
    ref, lam0 = extended_eigenvalues(K, M, modes)
    w = dd.beam_frequencies(beam)
    return np.abs(w[modes] ** 2 - ref) / ref, np.abs(lam0[modes] - ref) / ref, (modes, ref)


@pytest.mark.parametrize("ends", ENDS)
def test_every_mode_within_10x_of_lapack(ends, precision):
    """Mode by mode (the issue's 64-element pinned-pinned mode 5: the count alone 2.2e-11,
    LAPACK 4.2e-13), including the highest modes, in both arithmetics."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=64, left=ends[0], right=ends[1])
    ours, lapack, _ = _errors(beam, extra=(-3, -2, -1))
    assert np.all(ours <= 10.0 * np.maximum(lapack, EPS)), (ours, lapack)
    # a few ulps: the Rayleigh quotient of a vector good to rounding, the residual in twice
    # the working precision
    assert ours.max() < 8 * EPS, ours


def test_fine_mesh_in_double_only():
    """256 elements with the count in double: its roots alone are up to ~2e-9 off (measured;
    the count's rounding without the 11 extra bits), the refined ones a few ulps, far better
    than LAPACK on the low modes (3.6e-7 on mode 1)."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=256, left="pinned",
                   right="pinned")
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(beam_module, "_WIDE", np.float64)
        ours, lapack, (modes, ref) = _errors(beam)
        mp.setattr(beam_frequency, "refined_roots", lambda beam, lam, index, blocks: lam)
        raw = np.abs(dd.beam_frequencies(beam)[modes] ** 2 - ref) / ref
    finally:
        mp.undo()
    assert np.all(ours <= 10.0 * np.maximum(lapack, EPS)), (ours, lapack)
    assert ours.max() < 8 * EPS, ours
    assert ours[0] < 1e-6 * lapack[0]
    assert raw.max() > 100 * ours.max()  # the refinement, not the count, gives the digits


def test_never_below_the_continuum_in_double(monkeypatch):
    monkeypatch.setattr(beam_module, "_WIDE", np.float64)
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=128, left="pinned", right="pinned")
    w = dd.beam_frequencies(beam, count=12)
    exact = (np.arange(1, 13) * np.pi) ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))
    assert np.all(w >= exact), w / exact - 1


def test_repeated_root_keeps_the_count(precision):
    """A free-free beam's two highest roots agree to an ulp (the two end rotations): the count
    cannot confirm either refined value as a single root, so both keep the count's, which
    agrees with LAPACK to a few ulps there; every other root is refined, and the same bits
    come whether asked by count or for all."""
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=64, left="free", right="free")
    M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
    lam = sla.eigh(K, M, eigvals_only=True)
    w = dd.beam_frequencies(beam)
    assert np.all(np.abs(w[-2:] ** 2 / lam[-2:] - 1) < 8 * EPS)
    assert np.array_equal(dd.beam_frequencies(beam, count=20), w[:20])


def test_supports_and_point_masses_in_double(monkeypatch):
    """Springs and a point mass (close pairs of roots at the top of the spectrum)."""
    monkeypatch.setattr(beam_module, "_WIDE", np.float64)
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=48, left="pinned", right="free",
                   supports=[dd.Support(node=16, k_w=1e7)],
                   point_masses=[dd.PointMass(node=24, mass=50.0, inertia=0.1)])
    ours, lapack, _ = _errors(beam, extra=(-4, -3, -2, -1))
    assert np.all(ours <= 10.0 * np.maximum(lapack, EPS)), (ours, lapack)


@pytest.mark.parametrize("call", ["mck_response", "mck_modes", "Matrices"])
def test_ragged_matrix_is_named(call):
    M = [[1.0], [1.0, 2.0]]
    K = np.eye(2)
    run = {"mck_response": lambda: dd.mck_response(M, np.zeros((2, 2)), K, np.zeros(5), 0.1,
                                                   force_dofs=[0]),
           "mck_modes": lambda: dd.mck_modes(M, None, K),
           "Matrices": lambda: dd.Matrices(M, None, K)}[call]
    with pytest.raises(ValueError, match=r"M must be a square matrix.*row 1 has 2 entries, "
                                         r"row 0 has 1 entry"):
        run()
    with pytest.raises(ValueError, match=r"K must be a square matrix.*row 1 has a number"):
        dd.mck_modes(np.eye(2), None, [[1.0, 0.0], 1.0])
