"""Response PSDs and their integrals against independent truths: the closed forms of a
white-noise SDOF, H S H^H by hand, scipy.integrate.quad on the receptances, pyyeti's
`ode.solvepsd`, and the same model through its M, C, K."""
import numpy as np
import pytest
import scipy.integrate as si

import dtdyn as dd
from dtdyn.random_vibration import (beam_random_response, chain_random_response, psd_table,
                                    random_response, shaft_random_response)

FN, ZETA, W = 100.0, 0.05, 2.0                    # Hz, -, (m/s^2)^2/Hz
WN = 2 * np.pi * FN
#: 50 user frequencies, 0 .. 1e9 Hz: about 5 per decade, ~0.2 points per half-power band
COARSE = np.r_[0.0, np.geomspace(1.0, 1e9, 49)]


def sdof():
    return [[1.0]], [[2 * ZETA * WN]], [[WN**2]]


def test_white_noise_sdof_absolute_acceleration_closed_form():
    """int_0^inf |T|^2 W df = pi f_n W (1 + 4 zeta^2) / (4 zeta) (Miles' equation without its
    approximation). The band ends at 1e9 Hz: the tail beyond, ~ (2 zeta f_n)^2 W / 1e9, is
    6e-11 of the total, so 1e-9 checks the quadrature and not the truncation."""
    r = random_response(*sdof(), None, COARSE, ground_acceleration_psd=W)
    exact = np.pi * FN * W * (1 + 4 * ZETA**2) / (4 * ZETA)
    assert r.m0["a_abs"][0] == pytest.approx(exact, rel=1e-9)
    assert r.rms["a_abs"][0] == pytest.approx(np.sqrt(exact), rel=1e-9)
    assert r.info["rms_error_estimate"] < 1e-8
    # the user's grid alone (trapezoid) misses the peak: the refinement is what gives 1e-9
    trap = np.trapezoid(r.a_abs_psd[:, 0, 0].real, COARSE)
    assert abs(trap / exact - 1) > 0.1


def test_white_noise_sdof_relative_displacement_and_force():
    """x^2 = W / (8 zeta omega_n^3) for a base acceleration PSD W (and for a force PSD W on a
    unit mass); the tail beyond 1e9 Hz ~ f^-4 is nil, so the error estimate must cover the
    whole difference."""
    exact = W / (8 * ZETA * WN**3)
    for r in (random_response(*sdof(), None, COARSE, ground_acceleration_psd=W),
              random_response(*sdof(), W, COARSE)):
        err = abs(r.m0["x"][0] / exact - 1)
        assert err < 1e-10
        assert err <= max(2 * r.info["rms_error_estimate"], 1e-13)
        # velocity: W / (8 zeta omega_n) over 0 .. inf, less the tail beyond F = 1e9 Hz,
        # W / (4 pi^2 F) (|H_v|^2 -> 1 / omega^2; 6e-9 of the total)
        tail = W / (4 * np.pi**2 * COARSE[-1])
        assert r.m0["v"][0] == pytest.approx(W / (8 * ZETA * WN) - tail, rel=1e-10)
        # narrow band: zero crossings at about f_n, irregularity near 1
        assert r.zero_crossing_rate["x"][0] == pytest.approx(FN, rel=0.01)


def two_dof():
    """Two masses, non-proportional damping, modes 3.7 Hz and 9.4 Hz."""
    M = np.diag([2.0, 1.0])
    K = np.array([[3000.0, -1000.0], [-1000.0, 1000.0]])
    C = np.array([[1.2, -0.2], [-0.2, 0.9]])
    return M, C, K


def correlated(f):
    """A frequency-dependent cross-spectral matrix of two inputs, coherence 0.8."""
    f = np.atleast_1d(f)
    g1 = 4.0 / (1 + (f / 20.0) ** 2)
    g2 = np.full(f.shape, 1.5)
    c = 0.8 * np.sqrt(g1 * g2) * np.exp(-1j * 2 * np.pi * f * 0.01)
    return np.stack([np.stack([g1, c], -1), np.stack([np.conj(c), g2], -1)], -2)


def by_hand(M, C, K, f, S, quantity_power=0):
    w = 2 * np.pi * f
    H = np.linalg.inv(K - w**2 * M + 1j * w * C)
    Y = H @ S @ H.conj().T
    return Y * w ** (2 * quantity_power)


def test_output_cross_spectra_equal_h_s_hH_by_hand():
    M = np.diag([1.0, 2.0, 1.5])
    K = np.array([[3e4, -1e4, 0], [-1e4, 2.5e4, -1.5e4], [0, -1.5e4, 1.5e4]])
    C = 1e-3 * K + np.diag([0.5, 0.0, 0.2])
    f = np.linspace(0.5, 60.0, 50)
    S = correlated(f)
    r = random_response(M, C, K, S, f, force_dofs=[2, 0], outputs=[0, 1, 2])
    for k, fk in enumerate(f):
        Sk = np.zeros((3, 3), complex)
        Sk[np.ix_([2, 0], [2, 0])] = S[k]
        ref = by_hand(M, C, K, fk, Sk)
        for q, p in (("x", 0), ("v", 1), ("a", 2)):
            got = getattr(r, f"{q}_psd")[k]
            np.testing.assert_allclose(got, ref * (2 * np.pi * fk) ** (2 * p), rtol=1e-12,
                                       atol=1e-12 * np.abs(ref).max() * (2 * np.pi * fk) ** (2 * p))


def test_two_dof_moments_against_quad():
    """Every moment against scipy.integrate.quad on H S H^H by hand, panel by panel around the
    modes (epsrel 1e-12); the input is the callable cross-spectral matrix itself."""
    M, C, K = two_dof()
    f = np.linspace(0.0, 40.0, 9)
    r = random_response(M, C, K, correlated, f, force_dofs=[0, 1], outputs=[0, 1])
    fn = np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real) / (2 * np.pi)
    cuts = np.unique(np.r_[0.0, np.sort(fn), 40.0])
    for q, p in (("x", 0), ("a", 2)):
        for o in range(2):
            for k in (0, 1, 2, 4):
                def g(x, p=p, o=o, k=k):
                    return by_hand(M, C, K, x, correlated(x)[0], p)[o, o].real * x**k
                ref = sum(si.quad(g, a, b, epsabs=0, epsrel=1e-12, limit=200)[0]
                          for a, b in zip(cuts[:-1], cuts[1:]))
                got = getattr(r, f"m{k}")[q][o]
                assert got == pytest.approx(ref, rel=1e-9), (q, o, k)
    assert r.info["moment_error_estimate"] < 1e-8


def test_two_dof_against_pyyeti_solvepsd():
    """pyyeti's frequency-domain solution with uncorrelated force PSDs gives the same output
    PSDs at the user's frequencies; its rms (integrated on the user's grid) is off on a coarse
    grid, ours equals quad."""
    ode = pytest.importorskip("pyyeti.ode")
    M, C, K = two_dof()
    f = np.linspace(0.5, 30.0, 40)
    forcepsd = np.vstack([np.full(f.size, 3.0), np.full(f.size, 1.0)])
    fs = ode.FreqDirect(M, C, K)
    rms_y, psd_y = ode.solvepsd(fs, forcepsd, np.eye(2), f, [[None, None, np.eye(2), None]])
    r = random_response(M, C, K, forcepsd.T, f, force_dofs=[0, 1], outputs=[0, 1],
                        quantities=("x",))
    np.testing.assert_allclose(np.einsum("kii->ik", r.x_psd).real, psd_y[0], rtol=1e-10)

    def g(x, o):
        return sum(w * abs(np.linalg.inv(K - (2 * np.pi * x)**2 * M + 2j * np.pi * x * C)[o, i])
                   ** 2 for i, w in enumerate((3.0, 1.0)))
    ref = [np.sqrt(si.quad(g, 0.5, 30.0, args=(o,), points=[3.0, 9.0], epsabs=0,
                           epsrel=1e-12, limit=200)[0]) for o in range(2)]
    np.testing.assert_allclose(r.rms["x"], ref, rtol=1e-9)
    assert np.abs(rms_y[0] / ref - 1).max() > 1e-3     # the coarse grid's trapezoid


def test_chain_equals_matrices():
    m, k, c = [1.0, 2.0, 1.5, 0.8], [1e4, 2e4, 1.5e4, 8e3], [2.0, 3.0, 1.0, 0.5]
    kg, cg = [0.0, 500.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]
    M, C, K = dd.chain_matrices(m, k, c, sparse=False, ground_stiffness=kg, ground_damping=cg)
    f = np.linspace(1.0, 80.0, 30)
    S = correlated(f)
    kw = dict(force_dofs=[3, 1], outputs=[0, 3])
    a = chain_random_response(m, k, c, S, f, ground_stiffness=kg, ground_damping=cg, **kw)
    b = random_response(M, C, K, S, f, **kw)
    table = psd_table([(1.0, 0.5), (10.0, 2.0), (80.0, 2.0)])
    ga = chain_random_response(m, k, c, None, f, ground_stiffness=kg, ground_damping=cg,
                               ground_acceleration_psd=table)
    gb = random_response(M, C, K, None, f, ground_acceleration_psd=table)
    for x, y in ((a, b), (ga, gb)):
        for q in x.quantities:
            got, ref = getattr(x, f"{q}_psd"), getattr(y, f"{q}_psd")
            np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
            np.testing.assert_allclose(x.rms[q], y.rms[q], rtol=1e-10)
            np.testing.assert_allclose(x.m4[q], y.m4[q], rtol=1e-10)
    assert "a_abs" in ga.quantities


def test_sparse_matrices_equal_dense():
    """A sparse model finds its modes (which place the quadrature's panels) by shift-invert
    below the band instead of a dense eigensolve: the same PSDs to the quadrature's rounding
    (the panels move with ARPACK's last digits); a free chain's rigid mode included."""
    n = 80
    rng = np.random.default_rng(1)
    m, k, c = rng.uniform(0.5, 2, n), rng.uniform(1e7, 3e7, n), rng.uniform(0.5, 3, n)
    f = np.linspace(1.0, 20.0, 40)
    table = psd_table([(1.0, 0.5), (10.0, 2.0), (20.0, 2.0)])
    free = np.r_[0.0, k[1:]]                     # no spring to the ground: a rigid mode
    for springs, kw in ((free, dict(force_dofs=[n - 1])),
                        (k, dict(ground_acceleration_psd=table))):
        dense = dd.chain_matrices(m, springs, c, sparse=False)
        sparse = dd.chain_matrices(m, springs, c, sparse=True)
        psd = table if "force_dofs" in kw else None
        a = random_response(*dense, psd, f, outputs=[0, n - 1], **kw)
        b = random_response(*sparse, psd, f, outputs=[0, n - 1], **kw)
        for q in a.quantities:
            np.testing.assert_allclose(b.rms[q], a.rms[q], rtol=1e-8)


def test_beam_and_shaft_equal_their_matrices():
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=12, rayleigh=(2.0, 1e-5),
                   point_masses=[dd.PointMass(12, 5.0)])
    f = np.linspace(1.0, 300.0, 20)
    M, C, K = (A.toarray() for A in dd.beam_matrices(beam))
    tip, mid = beam.dof("w12"), beam.dof("w6")
    a = beam_random_response(beam, 1.0, f, force_dofs=["w12"], outputs=["w12", "w6"])
    b = random_response(M, C, K, 1.0, f, force_dofs=[tip], outputs=[tip, mid])
    g = beam_random_response(beam, None, f, ground_acceleration_psd=0.1, outputs=["w12"])
    # the rigid translation by hand: w 1, psi 0
    r = np.array([name.startswith("w") for name in beam.dof_names], dtype=float)
    h = random_response(M, C, K, None, f, ground_acceleration_psd=0.1, outputs=[tip],
                        influence=r)
    shaft = dd.Shaft([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3], [0.5, 0.8, 0.3],
                     branches=[dd.Branch(1, [0.5, 0.4], [6e3, 5e3], [0.2, 0.2], ratio=2.0)])
    Ms, Cs, Ks = (A.toarray() for A in dd.shaft_matrices(shaft))
    fs = np.linspace(0.0, 80.0, 20)
    s = shaft_random_response(shaft, None, fs, ground_acceleration_psd=1.0)
    t = random_response(Ms, Cs, Ks, None, fs, ground_acceleration_psd=1.0,
                        # the rigid rotation by hand: 1 on the main line, -1/2 past the gear
                        influence=[1.0, 1.0, 1.0, -0.5, -0.5])
    for x, y in ((a, b), (g, h), (s, t)):
        for q in x.quantities:
            ref = getattr(y, f"{q}_psd")
            np.testing.assert_allclose(getattr(x, f"{q}_psd"), ref, rtol=1e-8,
                                       atol=1e-10 * np.abs(ref).max())
            np.testing.assert_allclose(x.rms[q], y.rms[q], rtol=1e-8)


def test_cross_spectral_input_with_zero_coherence_equals_diagonal_input():
    M, C, K = two_dof()
    f = np.linspace(0.5, 30.0, 25)
    d = np.column_stack([np.full(f.size, 3.0), 1.0 + f / 30])
    full = np.zeros((f.size, 2, 2), complex)
    full[:, 0, 0], full[:, 1, 1] = d[:, 0], d[:, 1]
    a = random_response(M, C, K, d, f)
    b = random_response(M, C, K, full, f)
    for q in a.quantities:
        np.testing.assert_allclose(getattr(a, f"{q}_psd"), getattr(b, f"{q}_psd"), rtol=1e-14)
        np.testing.assert_allclose(a.m2[q], b.m2[q], rtol=1e-14)


def test_sampled_table_equals_the_table():
    """Samples at the breakpoints, log-log between them, are the table itself."""
    M, C, K = two_dof()
    table = psd_table([(1.0, 0.5), (4.0, 2.0), (10.0, 2.0), (30.0, 0.3)])
    f = table.freqs_hz
    a = random_response(M, C, K, table, f, force_dofs=[1])
    b = random_response(M, C, K, table(f), f, force_dofs=[1])
    for q in a.quantities:
        np.testing.assert_allclose(a.m0[q], b.m0[q], rtol=1e-11)


@pytest.mark.parametrize("change, match", [
    (lambda S: S.__setitem__((3, 0, 1), 0.5), r"psd\[3, 0, 1\] at .* Hz = .* is Hermitian"),
    (lambda S: S.__setitem__((2, 0, 0), -1.0), r"psd\[2, 0, 0\] .* must be real and >= 0"),
    (lambda S: (S.__setitem__((4, 0, 1), 5.0), S.__setitem__((4, 1, 0), 5.0)),
     r"psd\[4\] at .* Hz is not positive semidefinite"),
    (lambda S: S.__setitem__((1, 1, 1), np.nan), r"psd\[1, 1, 1\] .* is not finite"),
])
def test_bad_cross_spectra_are_named(change, match):
    M, C, K = two_dof()
    f = np.linspace(1.0, 20.0, 8)
    S = np.zeros((f.size, 2, 2), complex)
    S[:, 0, 0], S[:, 1, 1] = 1.0, 2.0
    change(S)
    with pytest.raises(ValueError, match=match):
        random_response(M, C, K, S, f)


def test_bad_inputs_are_named():
    M, C, K = two_dof()
    f = np.linspace(1.0, 20.0, 8)
    with pytest.raises(ValueError, match=r"psd has 1 input\(s\) and force_dofs names 2"):
        random_response(M, C, K, 1.0, f)
    with pytest.raises(ValueError, match=r"psd has shape \(3,\), expected \(8,\)"):
        random_response(M, C, K, [1.0, 2.0, 3.0], f, force_dofs=[0])
    with pytest.raises(ValueError, match="both given"):
        random_response(M, C, K, 1.0, f, ground_acceleration_psd=1.0)
    with pytest.raises(ValueError, match="C is None"):
        random_response(M, None, K, 1.0, f, force_dofs=[0])
    with pytest.raises(ValueError, match="freqs_hz"):
        random_response(M, C, K, 1.0, f[::-1], force_dofs=[0])
    with pytest.raises(ValueError, match="influence has shape"):
        random_response(M, C, K, None, f, ground_acceleration_psd=1.0, influence=[1.0])
    with pytest.raises(ValueError, match="undamped"):
        random_response(M, 0 * C, K, 1.0, f, force_dofs=[0])
    with pytest.raises(TypeError, match="did you mean 'outputs'"):
        random_response(M, C, K, 1.0, f, force_dofs=[0], outptus=[0])
