"""A Beam's Rayleigh damping kept apart in harmonic balance's receptances: the modes' damping
alpha + beta omega_r^2 exactly (its assembled C = alpha M + beta K, summed entry by entry in
double precision, loses alpha M at large N), C v = alpha M v + beta K v + E v in the refined
banded solves, and "auto" choosing the reduced receptance on such models."""
import warnings

import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.nonlinear._elements import element_matrix
from dtdyn.nonlinear._harmonic_balance import _bandwidth, _BandedReceptance
from dtdyn.nonlinear._receptance import (ReducedReceptance, exact_product,
                                         rayleigh_coefficients, rayleigh_parts)

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
W1, W2 = (b ** 2 * np.sqrt(E * I / (RHO_A * L ** 4)) for b in (1.8751040687119611,
                                                              4.6940911329741746))
BETA = 2 * 0.05 / (W1 + W2)                        # 5 % of critical in modes 1 and 2
ALPHA = BETA * W1 * W2


def _beam(n, **kw):
    return dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(ALPHA, BETA), **kw)


def _receptances(beam, w_max=2 * np.pi * 1500.0, dof=None):
    """(refined banded, reduced) receptances of the tip deflection under a tip force, built as
    harmonic_balance builds them for a Beam (alpha M and beta K apart), and the parts."""
    M, C, K = dd.beam_matrices(beam)
    tip = beam.dof(dof or f"w{beam.elements}")
    Lm = element_matrix([dd.Cubic(tip, k3=1.0)], M.shape[0])
    B = np.zeros((M.shape[0], 1))
    B[tip] = 1.0
    parts = rayleigh_parts(beam, M, C, K)
    exact = _BandedReceptance(M, C, K, Lm, np.array([tip]), B, _bandwidth(M, C, K),
                              refine=True, parts=parts)
    rec = ReducedReceptance(exact, M, C, K, Lm, np.array([tip]), B,
                            rayleigh_coefficients(M, C, K), w_max=w_max, parts=parts)
    return exact, rec, parts


def _continuous_tip(omega):
    """The tip receptance of the continuous clamped-free Rayleigh-damped beam (closed form:
    EI* = EI (1 + i omega beta), b^4 = rho_A (omega^2 - i omega alpha) / EI*, x = b L)."""
    ei = E * I * (1 + 1j * omega * BETA)
    b = (RHO_A * (omega ** 2 - 1j * omega * ALPHA) / ei) ** 0.25
    x = b * L
    return ((np.sin(x) * np.cosh(x) - np.cos(x) * np.sinh(x))
            / (ei * b ** 3 * (1 + np.cos(x) * np.cosh(x))))


def test_modal_damping_is_rayleighs_where_the_assembled_c_lost_alpha_m():
    # 2,000 elements: the assembled C's first mode is damped 1e-4 too little (measured in
    # the benchmark: 7e-6 at 1,000, 1e-4 at 2,000, 0.4 at 10,000 elements); the reduced
    # receptance's is alpha + beta w_1^2 to rounding, w_1 from beam_frequencies
    beam = _beam(2000)
    _, rec, parts = _receptances(beam)
    assert rec.name == "reduced" and rec.check["damping"] == "rayleigh"
    assert parts[2] is None
    w = dd.beam_frequencies(beam, count=3)
    assert np.abs(rec.modal_damping[:3] / (ALPHA + BETA * w ** 2) - 1).max() <= 1e-13
    phi = rec.modes[:, :1]
    hi, lo = exact_product(rec.cd, phi)
    assembled = float(phi[:, 0] @ (hi + lo)[:, 0]) / (ALPHA + BETA * w[0] ** 2) - 1
    assert abs(assembled) > 3e-5                  # what the receptance no longer uses


@pytest.mark.parametrize("n, tol", [(1000, 1e-8), (3000, 1e-8)])
def test_reduced_receptance_equals_the_continuous_beam(n, tol):
    # Hermite elements: the discretization error is below 1e-12 in this band from 300
    # elements; the rest is the rounding of the assembled K's lowest stiffness (its refined
    # k_1 moves by ~1e-10, erratically in N), times the peak's amplification 1 / (2 zeta):
    # measured at 18 Hz 2.5e-9 at 1,000, 4e-15 at 3,000 (1e-8 at 2,000, 2e-7 at 5,000)
    _, rec, _ = _receptances(_beam(n))
    w = 2 * np.pi * np.array([1e-3, 15.0, 18.0, 60.0, 110.0])
    H = rec(w)[0][:, 0, 0]
    assert np.abs(H / _continuous_tip(w) - 1).max() <= tol


def test_refined_banded_keeps_alpha_m_apart():
    # 1,000 elements: the refinement converges (its last correction near eps) and the solve is
    # that of alpha M + beta K, not of C's entries (with those: 6.8e-6 at 18 Hz)
    exact, _, _ = _receptances(_beam(1000))
    for f in (15.0, 18.0, 60.0, 110.0):
        w = 2 * np.pi * f
        H = exact(np.array([w]))[0][0, 0, 0]
        assert exact.last_correction <= 1e-12
        assert abs(H / _continuous_tip(w) - 1) <= 1e-8, f


def test_parts_with_point_masses_and_supports():
    """Beam's C = alpha M + beta K of the elements plus the supports' dampers: the parts
    E = C - alpha M - beta K reproduce C, and the kept modes' damping matrix equals
    phi^T C phi of the dense generalized eigenproblem."""
    beam = _beam(40, point_masses=[dd.PointMass(20, mass=3.0, inertia=0.01)],
                 supports=[dd.Support(30, k_w=2e5, c_w=50.0)], right=(1e6, 0.0))
    M, C, K = dd.beam_matrices(beam)
    parts = rayleigh_parts(beam, M, C, K)
    alpha, beta, Ex = parts
    assert (alpha, beta) == (ALPHA, BETA) and Ex is not None
    diff = C - (alpha * M + beta * K + Ex)
    assert abs(diff).max() <= 1e-13 * abs(C).max()
    assert rayleigh_coefficients(M, C, K) is None     # not alpha M + beta K of the whole model
    exact, rec, _ = _receptances(beam, w_max=2 * np.pi * 400.0)
    # the dense eigensolver's lowest eigenvalues carry about eps k_max / k_r (1e-9 here; the
    # reduced receptance's modes are refined), and its modes that error's square root
    k, phi = sla.eigh(K.toarray(), M.toarray())
    m = rec.k.size
    assert m >= 3 and np.allclose(rec.k, k[:m], rtol=1e-8)
    Cp = phi[:, :m].T @ C.toarray() @ phi[:, :m]
    assert np.allclose(rec.modal_damping, np.diag(Cp), rtol=1e-6)
    # the damper's share of the modes' damping, which the parts' E carries
    share = np.diag(phi[:, :m].T @ Ex.toarray() @ phi[:, :m]) / np.diag(Cp)
    assert np.abs(share).max() > 1e-2
    # the higher modes' residual keeps alpha, beta only: checked against the refined banded
    # receptance, which holds E, at the top of the band (passed or fell back, never silent)
    w = 2 * np.pi * np.array([5.0, 40.0, 150.0])
    H, Hx = rec(w)[0], exact(w)[0]
    if rec.name == "reduced":
        assert rec.check["error"] <= 1e-8
        assert np.abs(H - Hx).max() <= 1e-7 * np.abs(Hx).max()
    else:
        assert np.array_equal(H, Hx)


def _curve(beam, receptance, **kw):
    tip = beam.dof(f"w{beam.elements}")
    args = dict(elements=[dd.Cubic(tip, k3=7.5e8)], force_dofs=[tip], force=[100.0],
                freqs_hz=(10.0, 30.0), harmonics=5, outputs=[tip], stability=False,
                max_step=0.05, tol=1e-9, convergence_points=0)
    args.update(kw)
    return dd.harmonic_balance(beam, receptance=receptance, **args)


def test_auto_chooses_reduced_on_a_rayleigh_beam():
    beam = _beam(300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                     # no fall-back warning
        r = _curve(beam, "auto")
    assert r.info["receptance"] == "reduced"
    assert r.info["receptance_check"]["damping"] == "rayleigh"
    # the same points as the refined banded receptance (Newton at each frequency)
    for fk, xk in zip(r.frequency_hz[::15], r.x_max[::15, 0]):
        with pytest.warns(RuntimeWarning, match="stopped after max_points = 2"):
            rb = _curve(beam, "banded", freqs_hz=(fk, 30.0), max_points=2)
        # both solve the same model: the reduced one is checked to 1e-8, times the peak's
        # amplification (zeta = 5 %)
        assert abs(rb.x_max[0, 0] / xk - 1) <= 2e-7


def test_auto_stays_banded_below_its_size_and_without_rayleigh_damping():
    small = _beam(20)                                      # 40 DOFs
    assert _curve(small, "auto", max_step=0.2).info["receptance"] == "banded"
    # a damper at mid-span: the residual series (alpha, beta only) misses it by 3e-4 at the
    # top of the band, so "auto" falls back to the banded LU, silently (its Newton stops at
    # 1e-8 on 100 elements: the unrefined LU's rounding)
    damped = _beam(100, supports=[dd.Support(50, c_w=100.0)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = _curve(damped, "auto", max_step=0.2, tol=1e-8)
    assert r.info["receptance"] == "banded"
    assert "differs from the exact banded receptance" in r.info["receptance_check"]["reason"]
    chain = dd.Chain(np.ones(60), np.full(60, 1e4), np.arange(60) + 1.0)   # not Rayleigh
    r = dd.harmonic_balance(chain, elements=[dd.Cubic(59, k3=1e3)], force_dofs=[59],
                            force=[1.0], freqs_hz=(1.0, 1.5), harmonics=3, stability=False,
                            outputs=[59], convergence_points=0)
    assert r.info["receptance"] == "banded" and r.info["receptance_check"] is None


def test_auto_falls_back_to_the_plain_banded_lu_silently():
    # a long rail (C = 1.9 M + 1e-3 K: Rayleigh) whose band is dense in modes: the reduced
    # receptance gives up, "auto" runs LAPACK's banded LU as before, without a warning
    n = 3000
    chain = dd.Chain(np.ones(n), np.full(n, 1e4), np.full(n, 10.0),
                     ground_stiffness=np.full(n, 100.0), ground_damping=np.full(n, 2.0))
    kw = dict(elements=[dd.Cubic(n - 1, k3=1.0)], force_dofs=[n - 1], force=[1.0],
              freqs_hz=(2.0, 3.0), harmonics=3, stability=False, outputs=[n - 1],
              convergence_points=0, max_points=3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = dd.harmonic_balance(chain, receptance="auto", **kw)
    assert not [w for w in caught if "falls back" in str(w.message)]
    assert r.info["receptance"] == "banded"
    assert "modes below" in r.info["receptance_check"]["reason"]
