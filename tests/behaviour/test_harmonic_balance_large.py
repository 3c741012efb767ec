"""The reduced receptance of harmonic balance (modes below a cut-off + the residual series,
dtdyn.nonlinear._receptance) against the exact banded one, and its fall-backs."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.nonlinear._elements import element_matrix
from dtdyn.nonlinear._harmonic_balance import _bandwidth, _BandedReceptance
from dtdyn.nonlinear._receptance import ReducedReceptance, rayleigh_coefficients

W1 = 1.8751040687 ** 2 * np.sqrt(2.1e11 * 8e-6 / (20.0 * 3.0 ** 4))     # cantilever, rad/s


def _beam(n, zeta=0.05, supports=()):
    w2 = W1 * (4.6940911330 / 1.8751040687) ** 2
    beta = 2 * zeta / (W1 + w2)
    return dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=n,
                   rayleigh=(beta * W1 * w2, beta), supports=supports)


def _pair(beam, w_max):
    n = beam.elements
    M, C, K = dd.beam_matrices(beam)
    els = [dd.Cubic(beam.dof(f"w{n}"), k3=1.0), dd.Gap(beam.dof(f"w{n // 2}"), gap=1e-3,
                                                       stiffness=1.0)]
    L = element_matrix(els, M.shape[0])
    out = np.array([beam.dof(f"w{n}"), beam.dof(f"psi{n // 3}")])
    B = np.zeros((M.shape[0], 1))
    B[beam.dof(f"w{n}")] = 1.0
    exact = _BandedReceptance(M, C, K, L, out, B, _bandwidth(M, C, K), refine=True)
    damping = rayleigh_coefficients(M, C, K)
    return exact, ReducedReceptance(exact, M, C, K, L, out, B, damping, w_max=w_max)


def test_reduced_equals_banded_at_the_highest_frequency():
    exact, rec = _pair(_beam(200), w_max=20 * 200.0 * 2 * np.pi)
    assert rec.name == "reduced" and rec.check["error"] <= 1e-8
    assert 0 < rec.check["modes"] <= 30
    w = np.array([rec.check["verified_to_hz"]]) * 2 * np.pi
    (H, dH), (Hx, dHx) = rec(w), exact(w)
    assert np.abs(H - Hx).max() <= 1e-8 * np.abs(Hx).max()
    # over the band, off the resonances: the rounding of the 200-element model's own matrices
    # (eps N^3.5 ~ 1e-8 of its lowest stiffness, times 1 / (2 zeta) at a peak) is the floor
    w = 2 * np.pi * np.array([0.0, 5.0, 60.0, 400.0, 1500.0, 4000.0])
    (H, dH), (Hx, dHx) = rec(w), exact(w)
    for m in range(w.size):
        assert np.abs(H[m] - Hx[m]).max() <= 1e-6 * np.abs(Hx[m]).max()
        assert np.abs(dH[m] - dHx[m]).max() <= 1e-5 * np.abs(dHx[m]).max()


def test_reduced_builds_lazily_and_extends():
    exact, rec = _pair(_beam(100), w_max=None)
    w = 2 * np.pi * np.arange(1, 6) * 30.0
    H, _ = rec(w)
    assert rec.check["builds"] == 1 and rec.name == "reduced"
    H2, _ = rec(w * 10)                                   # past the verified range: a new setup
    assert rec.check["builds"] == 2
    Hx, _ = exact(w * 10)
    assert np.abs(H2 - Hx).max() <= 1e-6 * np.abs(Hx).max()


def test_reduced_falls_back_without_rayleigh_damping_or_with_many_modes():
    beam = _beam(100, supports=[dd.Support(50, c_w=100.0)])
    M, C, K = dd.beam_matrices(beam)
    assert rayleigh_coefficients(M, C, K) is None
    # a long chain on a soft foundation: its band is dense in modes
    n = 3000
    chain = dd.Chain(np.ones(n), np.full(n, 1e4), np.full(n, 10.0),
                     ground_stiffness=np.full(n, 100.0), ground_damping=np.full(n, 2.0))
    M, C, K = chain.matrices(sparse=True)
    L = element_matrix([dd.Cubic(n - 1, k3=1.0)], n)
    B = np.zeros((n, 1))
    B[n - 1] = 1.0
    exact = _BandedReceptance(M, C, K, L, np.array([n - 1]), B, 1)
    rec = ReducedReceptance(exact, M, C, K, L, np.array([n - 1]), B,
                            rayleigh_coefficients(M, C, K) or (0.0, 0.0), w_max=2 * np.pi * 15)
    assert rec.name == "banded" and "modes below" in rec.check["reason"]
    w = np.array([10.0, 20.0])
    assert np.array_equal(rec(w)[0], exact(w)[0])


def test_harmonic_balance_reduced_equals_banded():
    beam = _beam(200)
    tip = beam.dof("w200")
    kw = dict(elements=[dd.Cubic(tip, k3=7.5e8)], force_dofs=[tip], force=[100.0],
              freqs_hz=(10.0, 30.0), harmonics=5, outputs=[tip], stability=False,
              max_step=0.05, tol=1e-7)
    rb = dd.harmonic_balance(beam, receptance="banded", **kw)
    rr = dd.harmonic_balance(beam, receptance="reduced", **kw)
    assert rr.info["receptance"] == "reduced"
    assert rr.folds.size == rb.folds.size == 0
    # the continuation's steps differ (its step control sees rounding): compare the reduced
    # curve at points of the banded one, each the first point (Newton at that frequency) of a
    # curve over the same top frequency (the reduced receptance is built for H x 30 Hz, as in rr)
    f = rb.frequency_hz[::20]
    for fk, xk in zip(f, rb.x_max[::20, 0]):
        with pytest.warns(RuntimeWarning, match="stopped after max_points = 2"):
            r1 = dd.harmonic_balance(beam, receptance="reduced",
                                     **{**kw, "freqs_hz": (fk, 30.0), "max_points": 2})
        assert r1.info["receptance"] == "reduced" and r1.frequency_hz[0] == fk
        # Newton stops at tol = 1e-7 (1e-10 does not converge on this model: its residual
        # carries the rounding of cond(K) ~ N^4), and the peak (18 Hz, zeta = 5 %) adds the
        # model's rounding times 1 / (2 zeta): 1e-5
        assert abs(r1.x_max[0, 0] / xk - 1) <= 1e-5


def test_reduced_needs_a_symmetric_sparse_model():
    with pytest.raises(ValueError, match="receptance='reduced' needs sparse symmetric"):
        dd.harmonic_balance(np.eye(2), np.eye(2) * 0.1, np.eye(2), elements=[dd.Cubic(0, k3=1.0)],
                            force_dofs=[0], force=[0.1], freqs_hz=(0.1, 0.2),
                            receptance="reduced")


def _static_tip(n):
    """(tip deflection under a unit tip force by a plain banded LU, by the refined banded
    receptance at w = 0, the closed form L^3 / (3 EI): Hermite elements are nodally exact)."""
    import scipy.linalg as sla
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=n)
    M, C, K = dd.beam_matrices(beam)
    tip = beam.dof(f"w{n}")
    L = element_matrix([dd.Cubic(tip, k3=1.0)], M.shape[0])
    B = np.zeros((M.shape[0], 1))
    B[tip] = 1.0
    rec = _BandedReceptance(M, C, K, L, np.array([tip]), B, _bandwidth(M, C, K), refine=True)
    plain = sla.solve_banded((3, 3), rec.bands[2], B[:, 0])[tip]
    return plain, rec(np.array([0.0]))[0][0, 0, 0].real, 3.0 ** 3 / (3 * 2.1e11 * 8e-6), rec


def test_refined_banded_receptance_recovers_the_static_deflection():
    # 3,000 elements: cond(K) ~ N^4, the plain LU loses about eps N^3.5 (measured 3.3e-4);
    # refined with residuals in twice the working precision: measured 0 (to the last bit)
    plain, refined, exact, rec = _static_tip(3000)
    assert abs(plain / exact - 1) > 1e-4                  # plain double fails visibly
    assert abs(refined / exact - 1) < 1e-8
    assert rec.last_correction < 1e-13                    # the refinement converged


def test_refined_banded_receptance_equals_the_continuous_beam():
    # the undamped cantilever's tip receptance (closed form; 60 Hz is between modes 1 and 2,
    # 3,000 elements leave a discretization error ~1e-15): plain LU 1.7e-3, refined 5e-15
    n, f = 3000, 60.0
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=n)
    M, C, K = dd.beam_matrices(beam)
    tip = beam.dof(f"w{n}")
    L = element_matrix([dd.Cubic(tip, k3=1.0)], M.shape[0])
    B = np.zeros((M.shape[0], 1))
    B[tip] = 1.0
    rec = _BandedReceptance(M, C, K, L, np.array([tip]), B, _bandwidth(M, C, K), refine=True)
    w = 2 * np.pi * f
    b = (20.0 * w * w / (2.1e11 * 8e-6)) ** 0.25
    x = b * 3.0
    exact = ((np.sin(x) * np.cosh(x) - np.cos(x) * np.sinh(x))
             / (2.1e11 * 8e-6 * b ** 3 * (1 + np.cos(x) * np.cosh(x))))
    H = rec(np.array([w]))[0][0, 0, 0]
    assert abs(H / exact - 1) < 1e-8


def test_reduced_passes_its_check_at_2000_elements():
    # ARPACK's f1 of a 2,000-element beam is off by 3e-5 (cond(K) ~ N^4); refined by
    # residual correction they equal beam_frequencies (Wittrick-Williams) to rounding, and the
    # reduced receptance equals the refined banded one over the band, the peak included
    beam = _beam(2000)
    exact, rec = _pair(beam, w_max=2 * np.pi * 10 * 30.0)
    assert rec.name == "reduced" and rec.check["error"] <= 1e-8
    m = rec.k.size
    w_ww = dd.beam_frequencies(beam, count=m)
    assert np.abs(np.sqrt(rec.k) / w_ww - 1).max() < 1e-12
    w = 2 * np.pi * np.array([1e-3, 15.0, 18.0, 60.0, 110.0, 300.0])
    (H, dH), (Hx, dHx) = rec(w), exact(w)
    for k in range(w.size):
        assert np.abs(H[k] - Hx[k]).max() <= 1e-8 * np.abs(Hx[k]).max()
        assert np.abs(dH[k] - dHx[k]).max() <= 1e-6 * np.abs(dHx[k]).max()


def test_harmonic_balance_reduced_at_2000_elements():
    beam = _beam(2000)
    tip = beam.dof("w2000")
    r = dd.harmonic_balance(beam, receptance="reduced", elements=[dd.Cubic(tip, k3=7.5e8)],
                            force_dofs=[tip], force=[100.0], freqs_hz=(10.0, 30.0), harmonics=5,
                            outputs=[tip], stability=False, max_step=0.05)
    assert r.info["receptance"] == "reduced"
    assert r.info["stop"] == "end of the range"
