"""The nonlinear modal methods are data of the one scheme table (generated/scheme_table.py
METHODS and AUTO, from dtdyn.derive.nonlinear), beside the time integrators (TABLE), and the
runtime reads them from there."""
from dtdyn._engine.schemes import NAMES
from dtdyn.generated import nl_modal
from dtdyn.generated.scheme_table import AUTO, METHODS, TABLE
from dtdyn.nonlinear import _accuracy as accuracy, _linear_step as linear_step


def test_methods_sit_beside_the_time_integrators():
    assert set(METHODS).isdisjoint(TABLE)
    assert NAMES == tuple(TABLE)                       # the time integrators only
    assert AUTO["singular_mass"] in TABLE
    assert {AUTO[k] for k in ("first", "next", "then")} <= set(METHODS)
    assert (accuracy.AUTO, accuracy.AUTO_NEXT, accuracy.AUTO_THEN, accuracy.AUTO_SINGULAR_M) == (
        AUTO["first"], AUTO["next"], AUTO["then"], AUTO["singular_mass"])


def test_runtime_reads_the_table():
    assert linear_step.MODAL == tuple(METHODS)
    assert set(linear_step.POLYNOMIAL) == set(nl_modal.POLYNOMIALS)   # those with tables
    assert linear_step.EXPLICIT == ("modal_explicit",)
    for name, row in METHODS.items():
        assert row["order"] == row["degree"] + 1, name
        assert accuracy.scheme_order(name, {}) == row["order"]
        assert linear_step.THETA_LIMIT[name] == row["theta_limit"]


def test_theta_limits():
    """The ramp invariant treats the element force like linear-acceleration Newmark (beta =
    1/6), stable up to Omega_t = h sqrt(k_t / m) = sqrt 12: theta = B0 k_t = Omega_t^2 / 6 = 2
    (a hand formula). The polynomial methods' limits are those of their tables."""
    omega_t_squared = 12.0  # linear acceleration's limit Omega_t^2 (Newmark, beta = 1/6)
    assert METHODS["modal_ramp"]["theta_limit"] == omega_t_squared / 6
    assert METHODS["modal_quintic"]["theta_limit"] == nl_modal.QUINTIC_THETA_LIMIT
    assert METHODS["modal_explicit"]["theta_limit"] == nl_modal.EXPLICIT_THETA_LIMIT
    assert METHODS["modal_parabolic"]["theta_limit"] == 0.01   # held, not derived
