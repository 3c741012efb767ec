"""The nonlinear modal methods are data of the one scheme table (generated/scheme_table.py
METHODS and AUTO, from dtdyn.derive.nonlinear), beside the time integrators (TABLE), and the
engine's scheme registry reads the integrators from there (that the nonlinear room reads the
methods from there: tests/behaviour/test_nonlinear_method_table.py)."""
from dtdyn._engine.schemes import NAMES
from dtdyn.generated import nl_modal
from dtdyn.generated.scheme_table import AUTO, METHODS, TABLE


def test_methods_sit_beside_the_time_integrators():
    assert set(METHODS).isdisjoint(TABLE)
    assert NAMES == tuple(TABLE)                       # the time integrators only
    assert AUTO["singular_mass"] in TABLE
    assert {AUTO[k] for k in ("first", "next", "then")} <= set(METHODS)


def test_theta_limits():
    """The ramp invariant treats the element force like linear-acceleration Newmark (beta =
    1/6), stable up to Omega_t = h sqrt(k_t / m) = sqrt 12: theta = B0 k_t = Omega_t^2 / 6 = 2
    (a hand formula). The polynomial methods' limits are those of their tables."""
    omega_t_squared = 12.0  # linear acceleration's limit Omega_t^2 (Newmark, beta = 1/6)
    assert METHODS["modal_ramp"]["theta_limit"] == omega_t_squared / 6
    assert METHODS["modal_quintic"]["theta_limit"] == nl_modal.QUINTIC_THETA_LIMIT
    assert METHODS["modal_explicit"]["theta_limit"] == nl_modal.EXPLICIT_THETA_LIMIT
    assert METHODS["modal_parabolic"]["theta_limit"] == 0.01   # held, not derived
