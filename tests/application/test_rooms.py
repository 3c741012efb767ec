"""Each subpackage's `__all__` names its public objects: those `dtdyn` exports too are the very
same objects (the keyword-checked functions), none of them a module, and importing the
subpackages alone loads none of the deferred modules (test_import_cost.py)."""
import importlib

import pytest

import dtdyn
from test_import_cost import _fresh

ROOMS = ["dtdyn.linear", "dtdyn.modal", "dtdyn.nonlinear", "dtdyn.random_vibration", "dtdyn.app",
         "dtdyn._engine"]


@pytest.mark.parametrize("room", ROOMS)
def test_all_names_are_the_public_objects(room):
    package = importlib.import_module(room)
    for name in package.__all__:
        obj = getattr(package, name)
        assert not isinstance(obj, type(dtdyn)), f"{room}.{name} is a module"
        if name in dtdyn.__all__:      # a room may offer more (random_vibration.PsdTable)
            assert obj is getattr(dtdyn, name), f"{room}.{name} is not dtdyn.{name}"
        assert name in dir(package)
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = package.not_a_name


def test_engine_offers_nothing_and_rooms_cover_the_library():
    assert dtdyn._engine.__all__ == []
    rooms = set().union(*(importlib.import_module(r).__all__ for r in ROOMS))
    assert {"chain_response", "Modes", "modal_model", "nonlinear_mck_response", "psd_table",
            "run_scene", "problem"} <= rooms


def test_importing_a_room_loads_none_of_the_deferred_modules():
    out = _fresh("import dtdyn.linear, dtdyn.modal, dtdyn.nonlinear\nimport json\n"
                 "print(json.dumps({'loaded': loaded()}))")
    assert out["loaded"] == []
