"""One naming pattern (docs/vocabulary.md), checked on every name in `dtdyn.__all__`, and every
public function's unknown keywords refused with the closest valid name."""
import dataclasses
import inspect
import warnings

import numpy as np
import pytest

import dtdyn as dd

PUBLIC = [n for n in dd.__all__ if n != "__version__"]
CALLABLES = [n for n in PUBLIC if callable(getattr(dd, n))
             and not (isinstance(getattr(dd, n), type)
                      and issubclass(getattr(dd, n), BaseException))]

#: damping = dashpot coefficients (N s/m, N m s/rad) of the models that have them; a damping
#: ratio is always `damping_ratio`
DASHPOTS = {"chain_response", "chain_random_response", "chain_matrices",
            "chain_frequency_response", "chain_poles",
            "nonlinear_chain_response", "Chain", "Shaft", "Branch", "ContinuousShaft", "Scene"}
#: one (input, output) pair by nature: a filter's second-order sections
SINGLE_PAIR = {"to_sos"}
#: keywords that are the user's own names: a Law's constants, a problem's options
FREE_KEYWORDS = {"Law", "problem"}
RENAMED = {"simulate_chain": "chain_response", "simulate_mck": "mck_response",
           "simulate_beam": "beam_response", "simulate_shaft": "shaft_response",
           "nonlinear_response": "nonlinear_mck_response",
           "frequency_response": "chain_frequency_response",
           "undamped_poles": "chain_frequencies", "modes": "mck_modes",
           "p1": "problem", "p2": "problem", "p3": "problem", "p4": "problem"}


def parameters(name):
    obj = getattr(dd, name)
    return inspect.signature(obj.__init__ if isinstance(obj, type) else obj).parameters


def test_time_histories_are_named_response():
    assert not [n for n in PUBLIC if n.startswith("simulate")]
    returning = [n for n in CALLABLES if not isinstance(getattr(dd, n), type)
                 and inspect.signature(getattr(dd, n)).return_annotation == "Response"]
    assert returning and all(n.endswith("_response") for n in returning), returning


def test_model_first_and_mck_order():
    for name in CALLABLES:
        names = list(parameters(name))
        if "M" in names and "K" in names:
            assert names.index("M") < names.index("K"), name
            if "C" in names:
                assert names.index("M") < names.index("C") < names.index("K"), name


def test_argument_names_follow_the_vocabulary():
    for name in CALLABLES:
        names = set(parameters(name))
        assert not names & {"accel", "freqs", "frequencies", "omega_hz", "zeta"}, name
        if name not in SINGLE_PAIR:
            assert not names & {"force_dof", "output", "input"}, name
        if "damping" in names:
            assert name in DASHPOTS, f"{name}: a damping ratio is damping_ratio"


def test_frequency_fields_carry_their_unit():
    for cls in (dd.Modes, dd.ModalModel, dd.SRS, dd.ResponseSpectrum):
        fields = [f.name for f in dataclasses.fields(cls)]
        fields += [n for n, v in vars(cls).items() if isinstance(v, property)
                   and not (v.__doc__ or "").startswith("Deprecated")]
        for f in fields:
            if "freq" in f:
                assert f.endswith("_hz"), f"{cls.__name__}.{f}"


@pytest.mark.parametrize("name", CALLABLES)
def test_unknown_keyword_is_a_type_error_with_the_closest_name(name):
    if name in FREE_KEYWORDS:
        pytest.skip("its keywords are the user's own names (checked by the function itself)")
    obj = getattr(dd, name)
    with pytest.raises(TypeError, match="unexpected keyword argument 'zz_not_a_keyword'"):
        obj(zz_not_a_keyword=1)
    if "outputs" in parameters(name):
        with pytest.raises(TypeError, match="'outptus'; did you mean 'outputs'"):
            obj(outptus=[0])


def test_misspelled_keyword_on_a_run():
    M, C, K = dd.chain_matrices([1.0, 1.0], [2.0, 1.0], [0.1, 0.1])
    with pytest.raises(TypeError, match="'outptus'; did you mean 'outputs'"):
        dd.mck_response(M, C, K, np.ones((11, 2)), 0.1, outptus=[0])
    with pytest.raises(TypeError, match="'bta'; did you mean 'beta'"):
        dd.mck_response(M, C, K, np.ones((11, 2)), 0.1, bta=0.3)
    with pytest.raises(TypeError, match=r"scheme 'newmark' takes parameters \(beta, gamma\)"):
        dd.mck_response(M, C, K, np.ones((11, 2)), 0.1, theta=1.4)
    with pytest.raises(TypeError, match="'n_sample'; did you mean 'n_samples'"):
        dd.problem("P4", n_sample=10)


@pytest.mark.parametrize("old, new", sorted(RENAMED.items()))
def test_old_names_warn_and_are_not_public(old, new):
    assert old not in dd.__all__ and new in dd.__all__
    with pytest.warns(DeprecationWarning, match=f"dtdyn.{old} is now dtdyn.{new}"):
        getattr(dd, old)
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        dd.no_such_name  # noqa: B018  (the attribute access is the test)


def test_old_names_give_the_new_results():
    p = dd.problem("P2")
    force = np.ones(51)
    new = dd.mck_response(p["M"], p["C"], p["K"], force, 0.02, force_dofs=[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        old = dd.simulate_mck(p["M"], p["C"], p["K"], force, 0.02, force_dofs=[1])
        np.testing.assert_array_equal(dd.p2()["K"], p["K"])
        assert dd.p4(10)["force"].shape == dd.problem("P4", n_samples=10)["force"].shape
        m_old = dd.modes(p["M"], p["K"], p["C"])
    np.testing.assert_array_equal(old.x, new.x)
    np.testing.assert_array_equal(m_old.poles, dd.mck_modes(p["M"], p["C"], p["K"]).poles)


def test_law_constants_checked_against_the_expression():
    with pytest.raises(TypeError, match="'expresion'; did you mean 'expression'"):
        dd.Law(0, expresion="k*x**3", k=1.0)
    with pytest.raises(TypeError, match="constant 'c', which Law.expression = 'k\\*x\\*\\*3' does "
                                        "not use"):
        dd.Law(0, expression="k*x**3", k=1.0, c=2.0)
