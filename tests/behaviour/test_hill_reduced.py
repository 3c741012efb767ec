"""Hill's method on a reduced model (``stability="reduced"``) against Hill's method on the full
model: labels, critical Floquet exponents, folds and Neimark-Sacker points.

Tolerances: the reduced model holds the modes below w_m = 2 (H + 1) omega_top and the
attachment modes with two mass corrections, so its condensed receptance misses about
(w / w_m)^12 of the residual flexibility at a frequency w (module docstring of
dtdyn.nonlinear._hill_reduced); the critical exponents' eigenvectors live in the harmonics near
omega, where w / w_m <= 1 / (2 (H + 1)) and that is below 1e-12. The dense full Hill's own
rounding (QZ on a companion matrix whose entries span K / M) is ~1e-10 relative, so the
exponents are compared to 1e-8 omega, the bifurcations' frequencies to 1e-6 Hz (Brent's method
on the arc, tolerance 1e-10 of a step).
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.nonlinear import _harmonic_balance as hb
from dtdyn.nonlinear._hill_reduced import reduced_hill_model

KC, FC = 0.05, 0.02


def coupled_chain(s=6, ms=0.01):
    """Two unit Duffing masses coupled by KC, each grounded through s masses ms in series
    (springs s + 1: total static stiffness 1), C = 0.008 M + 0.002 K: modes near 0.17 Hz and
    the chains' modes from ~5 Hz, folds and Neimark-Sacker points between 0.16 and 0.21 Hz."""
    n = 2 + 2 * s
    K, M = np.zeros((n, n)), np.zeros((n, n))

    def spring(i, j, k):
        K[i, i] += k
        if j is not None:
            K[j, j] += k
            K[i, j] -= k
            K[j, i] -= k
    M[0, 0] = M[1, 1] = 1.0
    spring(0, 1, KC)
    for a, first in ((0, 2), (1, 2 + s)):
        chain = [a] + list(range(first, first + s))
        for p, q in zip(chain[:-1], chain[1:]):
            spring(p, q, float(s + 1))
        spring(chain[-1], None, float(s + 1))
        for q in chain[1:]:
            M[q, q] = ms
    return M, 0.008 * M + 0.002 * K, K


def _hill_eigenvalues(M, C, K, L, Jy, Jv, omega, D):
    """All 2 n (2 H + 1) eigenvalues of Hill's quadratic eigenproblem (the equations of
    docs/guide/harmonic_balance.md, assembled here as an oracle)."""
    import scipy.linalg as sla
    n, nH = M.shape[0], D.shape[0]
    N = omega * D
    Gy = sum(np.kron(Jy[e], np.outer(L[e], L[e])) for e in range(L.shape[0]))
    Gv = sum(np.kron(Jv[e], np.outer(L[e], L[e])) for e in range(L.shape[0]))
    A2 = np.kron(np.eye(nH), M)
    A1 = 2 * np.kron(N, M) + np.kron(np.eye(nH), C) + Gv
    A0 = (np.kron(N @ N, M) + np.kron(N, C) + np.kron(np.eye(nH), K) + Gy
          + Gv @ np.kron(N, np.eye(n)))
    m = n * nH
    Z, I_m = np.zeros((m, m)), np.eye(m)
    lam = sla.eigvals(np.block([[Z, I_m], [-A0, -A1]]), np.block([[I_m, Z], [Z, A2]]))
    return lam[np.isfinite(lam)]


def _curve(stability, **kw):
    M, C, K = coupled_chain()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return dd.harmonic_balance(M, C, K, elements=[dd.Cubic(0, k3=1.0), dd.Cubic(1, k3=1.0)],
                                   force_dofs=[0], force=[FC], freqs_hz=(0.16, 0.21),
                                   harmonics=3, max_step=0.05, convergence_points=0,
                                   stability=stability, **kw)


def test_reduced_hill_equals_the_full_one_on_a_chain_with_folds_and_neimark_sacker():
    full, red = _curve(True), _curve("reduced")
    assert full.info["stability"]["method"] == "full"
    info = red.info["stability"]
    assert info["method"] == "reduced" and info["size"] < full.info["stability"]["size"]
    assert np.array_equal(full.omega, red.omega)
    assert np.array_equal(full.stable, red.stable)
    assert (~red.stable).sum() > 10
    w = full.omega
    assert np.max(np.abs(np.nanmax(full.floquet_exponents.real, axis=1)
                         - np.nanmax(red.floquet_exponents.real, axis=1)) / w) < 1e-8
    # the critical exponents (those within 0.02 omega of the stability boundary: the two low
    # modes' pairs; the chains' modes have Re < -0.4 omega) are eigenvalues of the full
    # model's Hill problem (all its 2 n (2 H + 1), the copies included: with H = 3 the two
    # selections may keep different copies of an exponent, which differ by the truncation)
    M, C, K = coupled_chain()
    elements = [dd.Cubic(0, k3=1.0), dd.Cubic(1, k3=1.0)]
    system, *_, model = hb._prepare(M, C, K, elements, [0], [FC], None, None, 3, None, None,
                                    "auto", False, 0.02, 0.1, 1e-7, 0.35, 1e-9, 20, 5000, 0,
                                    w_top=2 * np.pi * 0.21)
    _, _, D = hb._basis(3, system.N)
    near = set(np.clip(np.concatenate([red.bifurcation_index + d for d in (-1, 0, 1)]), 0,
                       w.size - 1))
    for i in sorted(near | set(range(0, w.size, 10))):
        Jy, Jv = system.linearization(hb._real(red.element_harmonics[i].T), w[i])
        every = _hill_eigenvalues(M, C, K, model["L"], Jy, Jv, w[i], D)
        lr = red.floquet_exponents[i]
        crit = lr[np.isfinite(lr) & (lr.real > -0.02 * w[i])]
        assert crit.size >= 2
        for x in crit:
            assert np.abs(every - x).min() < 1e-8 * w[i], (w[i], x)
    kinds = list(red.bifurcation_kind)
    assert kinds.count("neimark_sacker") >= 4 and kinds.count("fold") >= 4
    assert list(full.bifurcation_kind) == kinds
    assert np.array_equal(full.bifurcation_index, red.bifurcation_index)
    assert np.allclose(red.bifurcation_frequency_hz, full.bifurcation_frequency_hz, rtol=0,
                       atol=1e-6)


def test_reduced_model_of_a_beam_gives_the_full_exponents():
    """A 12-element cantilever with a cubic spring at the tip and a gap at mid-span (the
    model of benchmarks/harmonic_balance_beam.py), H = 3: at 5 points of its curve through the
    first two modes, the reduced model's exponents of modes 1 and 2 equal the dense full
    Hill's to 1e-8 relative, and the largest real parts agree."""
    E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
    w1, w2 = 1.8751040687119611 ** 2, 4.6940911329741746 ** 2
    w1, w2 = (b * np.sqrt(E * I / (RHO_A * L ** 4)) for b in (w1, w2))
    beta = 0.1 / (w1 + w2)
    n = 12
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n,
                   rayleigh=(beta * w1 * w2, beta))
    tip, mid = beam.dof(f"w{n}"), beam.dof(f"w{n // 2}")
    elements = [dd.Cubic(tip, k3=7.5e8), dd.Gap(mid, gap=1e-3, stiffness=1e5)]
    H = 3
    r = dd.harmonic_balance(beam, elements=elements, force_dofs=[tip], force=[100.0],
                            outputs=[tip], freqs_hz=(5.0, 150.0), harmonics=H,
                            stability=False, max_step=0.1, convergence_points=0, tol=1e-9)
    system, *_, model = hb._prepare(beam, None, None, elements, [tip], [100.0], None, None, H,
                                    [tip], None, "auto", False, 0.02, 0.1, 1e-7, 0.35, 1e-9,
                                    20, 5000, 0, w_top=2 * np.pi * 150.0)
    M, C, K = (model[x].toarray() for x in "MCK")
    Mr, Cr, Kr, Lr, info = reduced_hill_model(model["M"], model["C"], model["K"], model["L"],
                                              (H + 1) * 2 * np.pi * 150.0, width=3)
    assert info["size"] < M.shape[0] // 2
    _, _, D = hb._basis(H, system.N)
    for i in np.linspace(0, r.omega.size - 1, 5).astype(int):
        w = r.omega[i]
        Jy, Jv = system.linearization(hb._real(r.element_harmonics[i].T), w)
        lf = hb._hill(M, C, K, model["L"], Jy, Jv, w, D)
        lr = hb._hill(Mr, Cr, Kr, Lr, Jy, Jv, w, D)
        assert abs(lf.real.max() - lr.real.max()) < 1e-8 * abs(lf.real.max())
        crit = lr[lr.imag > 0]
        for x in crit[np.argsort(-crit.real)[:2]]:
            d = lf - x
            d = d - 1j * w * np.round(d.imag / w)
            assert np.abs(d).min() < 1e-8 * abs(x), (w, x)


def test_auto_chooses_full_below_the_limit_and_reduced_above():
    M, C, K = coupled_chain()
    kw = dict(elements=[dd.Cubic(0, k3=1.0), dd.Cubic(1, k3=1.0)], force_dofs=[0], force=[FC],
              freqs_hz=(0.16, 0.161), harmonics=3, max_points=3, convergence_points=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        small = dd.harmonic_balance(M, C, K, **kw)
        assert small.info["stability"]["method"] == "full"
        off = dd.harmonic_balance(M, C, K, stability=False, **kw)
        assert off.stable is None and off.info["stability"] is None
        # 2 n (2 H + 1) = 5,600 <= 6,000 (full) and 8,800 (reduced) for n = 400 DOFs
        assert hb._stability_choice("auto", 400, 3) == "full"
        assert hb._stability_choice("auto", 400, 5) == "reduced"
        n = 400
        beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=n // 2,
                       rayleigh=(1.0, 1e-5))
        tip = beam.dof(f"w{n // 2}")
        big = dd.harmonic_balance(beam, elements=[dd.Cubic(tip, k3=7.5e8)], force_dofs=[tip],
                                  force=[100.0], outputs=[tip], freqs_hz=(5.0, 5.5),
                                  harmonics=5, max_points=3, convergence_points=0)
    assert big.info["stability"]["method"] == "reduced" and big.stable.size == 3


@pytest.mark.parametrize("value, match", [("yes", "stability must be"), (1, "stability must be")])
def test_bad_stability_is_named(value, match):
    M, C, K = coupled_chain(2)
    with pytest.raises(ValueError, match=match):
        dd.harmonic_balance(M, C, K, elements=[dd.Cubic(0, k3=1.0)], force_dofs=[0],
                            force=[FC], freqs_hz=(0.16, 0.17), stability=value)


def test_full_hill_above_the_limit_and_reduced_with_too_many_modes_are_refused():
    n = 400
    chain = dd.Chain(np.ones(n), np.full(n, 100.0), np.ones(n))
    kw = dict(elements=[dd.Cubic(n - 1, k3=1.0)], force_dofs=[n - 1], force=[1.0],
              freqs_hz=(0.1, 0.2))
    with pytest.raises(ValueError, match="stability='reduced'"):
        dd.harmonic_balance(chain, stability=True, **kw)
    with pytest.raises(ValueError, match="stability=False"):
        dd.harmonic_balance(chain, stability="reduced", **kw)
