"""One scheme table (generated from derive/integrators.py) decides for the runtime, the scenes,
the command and the docs: they accept and refuse the same parameter values."""
import re
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated.scheme_table import TABLE

# the user guide's scheme table (it was the README's before the README shrank)
README = Path(__file__).resolve().parents[2] / "docs" / "guide" / "chains.md"


def _scene(scheme: dict) -> dict:
    return {"model": {"mass": [1.0, 1.0], "stiffness": [100.0, 100.0], "damping": [0.1, 0.1]},
            "load": [{"dof": 1, "kind": "step"}], "scheme": scheme,
            "time": {"dt": 0.01, "duration": 0.1}}


@pytest.mark.parametrize("name, key, value, ok", [
    ("newmark", "gamma", 0.3, False), ("newmark", "gamma", 0.6, True),
    ("newmark", "beta", -0.1, False), ("wilson", "theta", 0.9, False),
    ("wilson", "theta", 1.5, True), ("hht", "alpha", 0.1, False), ("hht", "alpha", -0.2, True),
    ("generalized_alpha", "rho_inf", 1.2, False), ("generalized_alpha", "rho_inf", 0.5, True),
])
def test_scene_and_runtime_give_the_same_verdict(name, key, value, ok):
    force = np.ones(11)
    calls = (lambda: dd.chain_response([1.0, 1.0], [100.0, 100.0], [0.1, 0.1], force, 0.01,
                                       force_dofs=[1], scheme=name, **{key: value}),
             lambda: dd.scene_from_dict(_scene({"name": name, key: value})))
    for call in calls:
        if ok:
            call()
        else:
            with pytest.raises(ValueError, match=f"{key} = {value!r} is outside"):
                call()


def test_guide_scheme_table_lists_the_table():
    rows = re.findall(r"^\| `([a-z_0-9]+)`.*$", README.read_text(), flags=re.M)
    named = set()
    for line in re.findall(r"^\| `[a-z_0-9].*$", README.read_text(), flags=re.M):
        named |= set(re.findall(r"`([a-z_0-9]+)`", line.split("|")[1]))
    assert set(TABLE) <= named, set(TABLE) - named
    for name, row in TABLE.items():
        for param in row["params"]:
            line = next(l for l in README.read_text().splitlines()
                        if l.startswith("| `") and f"`{name}`" in l.split("|")[1])
            assert f"`{param}`" in line, (name, param)
    assert rows


def test_multistep_start_up_comes_from_the_table():
    for name, row in TABLE.items():
        assert (row["startup_scheme"] is None) == (row["startup_steps"] == 0), name
        assert row["startup_scheme"] in (None, *TABLE)
