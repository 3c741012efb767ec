"""Stability from each scheme's definition against the published values (reference.md sec. 4)."""
import math

import numpy as np
import pytest

from dtdyn import (DtdynStabilityWarning, DtdynUnstableError, chain_response, critical_omega_dt,
                   run_scene, scene_from_dict, stability)
import sympy as sp

from dtdyn.app import main

BIG = np.geomspace(1e-2, 1e6, 300)


def test_average_acceleration_has_unit_spectral_radius():
    st = stability("average_acceleration", BIG)
    np.testing.assert_allclose(st.spectral_radius, 1.0, atol=1e-12)
    np.testing.assert_allclose(st.algorithmic_damping[:100], 0.0, atol=1e-12)


@pytest.mark.parametrize("scheme, crit", [
    ("central_difference", 2.0), ("fox_goodwin", math.sqrt(6.0)), ("newmark_1_8", math.sqrt(8.0)),
    ("linear_acceleration", math.sqrt(12.0)),
])
def test_critical_omega(scheme, crit):
    """gamma = 1/2: stable for Omega < 1/sqrt(gamma/2 - beta)."""
    assert critical_omega_dt(scheme) == pytest.approx(crit, rel=1e-9)


def test_wilson_unconditional_from_1_366():
    theta_c = (1 + math.sqrt(3)) / 2
    assert critical_omega_dt("wilson", theta=theta_c + 1e-6, upper=1e6) == math.inf
    assert critical_omega_dt("wilson", theta=1.4, upper=1e6) == math.inf
    assert critical_omega_dt("wilson", theta=1.3, upper=1e6) < 10.0


@pytest.mark.parametrize("scheme", ["houbolt", "park"])
def test_multistep_annihilate_high_frequencies(scheme):
    rho = stability(scheme, [1e2, 1e4, 1e6]).spectral_radius
    assert rho[2] < rho[1] < rho[0] and rho[2] < 0.01
    assert critical_omega_dt(scheme, upper=1e6) == math.inf


@pytest.mark.parametrize("rho_inf", [0.0, 0.3, 0.8, 1.0])
def test_generalized_alpha_tends_to_rho_inf(rho_inf):
    # the limit is approached slowly (a defective eigenvalue at infinity): 2e-5 off at 1e7
    rho = stability("generalized_alpha", [1e7], rho_inf=rho_inf).spectral_radius[0]
    assert rho == pytest.approx(rho_inf, abs=1e-4)
    assert np.all(stability("generalized_alpha", BIG, rho_inf=rho_inf).spectral_radius <= 1 + 1e-12)


@pytest.mark.parametrize("alpha", [-1 / 3, -0.1, 0.0])
def test_hht_spectral_radius_at_infinity(alpha):
    """Hilber, Hughes & Taylor (1977): rho_inf = (1 + alpha) / (1 - alpha)."""
    rho = stability("hht", [1e7], alpha=alpha).spectral_radius[0]
    assert rho == pytest.approx((1 + alpha) / (1 - alpha), abs=1e-4)


def test_fox_euler_as_published():
    """Newmark (1/2, 1): unconditionally stable, first-order damping xi_bar ~ Omega/2 ... the
    leading term of the algorithmic damping of Newmark is (gamma - 1/2) Omega / 2."""
    st = stability("fox_euler", [1e-3, 1e-2])
    np.testing.assert_allclose(st.algorithmic_damping, 0.25 * st.omega_dt, rtol=1e-2)
    assert critical_omega_dt("fox_euler", upper=1e6) == math.inf


@pytest.mark.slow
def test_period_elongation_series_of_average_acceleration():
    from dtdyn.derive.stability import Omega, period_elongation_series

    series, _ = period_elongation_series("average_acceleration")
    assert sp.simplify(series - Omega**2 / 12) == 0
    st = stability("average_acceleration", [1e-2, 3e-2])
    np.testing.assert_allclose(st.period_elongation, st.omega_dt**2 / 12, rtol=1e-3)


def test_damped_exact_limit():
    """For small Omega every scheme's damping approaches the physical one (xi_bar -> zeta
    is measured on top of it: algorithmic damping of the principal pair minus zeta -> 0)."""
    for s in ("average_acceleration", "hht", "generalized_alpha", "wilson"):
        st = stability(s, [1e-3], damping_ratio=0.05)
        assert abs(st.algorithmic_damping[0] - 0.05 / math.sqrt(1 - 0.05**2)) < 1e-3


def test_scene_warns_before_an_unstable_run():
    scene = scene_from_dict({
        "model": {"mass": [1.0, 1.0], "stiffness": [1e4, 1e4], "damping": [1.0, 1.0]},
        "load": [{"dof": 1, "kind": "step"}],
        "scheme": {"name": "central_difference", "form": "acceleration"},
        "time": {"dt": 0.05, "duration": 0.5},
    })
    with pytest.warns(DtdynStabilityWarning, match=r"mode 2 .*Omega = omega dt = 8"):
        with pytest.raises(DtdynUnstableError, match=r"Omega = omega dt = 8.09 > 2"):
            run_scene(scene)  # refused before it runs: it would blow up (static answer 2e-4)
    with pytest.warns(DtdynStabilityWarning, match="unstable at dt = 0.05"):
        response = chain_response([1.0, 1.0], [1e4, 1e4], [1.0, 1.0], np.ones(11), 0.05,
                                  force_dofs=[1], scheme="central_difference",
                                  form="acceleration", unstable="warn")  # for study, on request
    assert np.abs(response.x).max() > 1e-2
    # an unconditionally stable scheme warns at no dt: tests/behaviour/test_stability_check.py


def test_cli_table_and_plot(tmp_path, capsys):
    out = tmp_path / "stab.png"
    assert main(["stability", "central_difference", "hht", "--plot", str(out)]) == 0
    text = capsys.readouterr().out
    assert "central_difference" in text and "2.0000" in text and out.stat().st_size > 10_000
