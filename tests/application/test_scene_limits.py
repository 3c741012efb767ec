"""A scene's limits, seen from inside the scene parser (dtdyn.app._scene.parse), from the fault
suite's third round (tests/behaviour/test_fault_suite_escapes.py): the memory estimate counts
what a run stores, and an oversized scene file is refused before it is read."""
from pathlib import Path

import pytest

import dtdyn as dd
from problems import chain_scene
from dtdyn.app._scene import parse
from dtdyn.app._scene.parse import stored_columns


def _write(tmp, name, text):
    path = Path(tmp) / name
    path.write_text(text)
    return path




def test_scene_estimate_counts_what_is_stored():
    """A chain scene stores the time, the loaded DOFs' force columns and the outputs' quantities,
    not a force column per DOF (a 2,000-mass, 400,000-step, one-output scene was refused with
    "needs 5.97 GiB"; it needs 3 values per sample, 9.6 MB)."""
    assert stored_columns(2000, 1, False, 1, 1) == 3
    assert stored_columns(2000, 2, False, 3, 2) == 1 + 2 + 6
    # support motion loads every DOF that M r reaches (at most all) plus the record itself
    assert stored_columns(2000, 0, True, 1, 1) == 1 + 2001 + 1
    assert 400_001 * stored_columns(2000, 1, False, 1, 1) * 8 < 10e6


def test_an_oversized_scene_file_is_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setattr(parse, "MAX_SCENE_BYTES", 100)
    path = _write(tmp_path, "big.toml", chain_scene(20, 10))
    with pytest.raises(ValueError, match=r"big\.toml: the scene file is [\d,]+ bytes; the limit "
                                         r"is 100"):
        dd.load_scene(path)
