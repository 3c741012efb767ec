"""The nonlinear room reads its modal methods from the one scheme table (generated/
scheme_table.py METHODS and AUTO, from dtdyn.derive.nonlinear): the linear step's registry and
scheme="auto"'s choices hold no list of their own (the table itself:
tests/generated_code/test_method_table.py)."""
from dtdyn.generated import nl_modal
from dtdyn.generated.scheme_table import AUTO, METHODS
from dtdyn.nonlinear import _accuracy as accuracy, _linear_step as linear_step


def test_auto_reads_the_table():
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
