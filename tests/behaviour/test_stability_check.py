"""The stability check before a run (dtdyn.linear._stability): an unconditionally stable scheme
warns at no step (the published limits themselves: tests/symbolic/test_stability.py)."""
import warnings

import dtdyn as dd
from dtdyn.linear._stability import warn_if_unstable


def test_an_unconditionally_stable_scheme_warns_at_no_step():
    """(Moved from tests/symbolic/test_stability.py, test_scene_warns_before_an_unstable_run.)"""
    with warnings.catch_warnings():
        warnings.simplefilter("error", dd.DtdynStabilityWarning)
        assert not warn_if_unstable("average_acceleration", [1e6], 1.0)
