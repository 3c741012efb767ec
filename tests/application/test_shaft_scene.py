"""Scenes with kind = "shaft": parsing, the run against mck_response on Scene.matrices(), the
modes command, errors that name the field."""
import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd

SCENE = {
    "title": "one gear driving two branches",
    "model": {"kind": "shaft", "inertia": [1.0, 0.3, 0.9], "stiffness": [1e4, 1.2e4, 9e3],
              "damping": [0.5, 0.8, 0.3], "left": "clamped"},
    "branch": [
        {"name": "a", "at": 1, "ratio": 2.0, "inertia": [0.5, 0.4], "stiffness": [6e3, 5e3],
         "damping": [0.2, 0.2]},
        {"name": "b", "at": 1, "ratio": -3.5, "inertia": [0.6, 0.45],
         "stiffness": [4e3, {"length": 1.0, "G": 8e10, "Jp": 1e-7, "rho": 7800.0,
                             "elements": 8}],
         "right": "clamped", "right_stiffness": 2e3},
        {"name": "c", "on": "a", "at": 1, "inertia": [0.2], "stiffness": [3e3]},
    ],
    "load": [{"dof": "main.0", "kind": "step", "amplitude": 10.0}],
    "scheme": {"name": "hht", "alpha": -0.1, "form": "acceleration"},
    "time": {"dt": 1e-3, "duration": 0.4},
    "output": {"outputs": ["main.0", "a.1", "b.1", "c.0"]},
}


TOML = """title = "one gear driving two branches"
[model]
kind = "shaft"
inertia = [1.0, 0.3, 0.9]
stiffness = [1e4, 1.2e4, 9e3]
damping = [0.5, 0.8, 0.3]
left = "clamped"

[[branch]]
name = "a"
at = 1
ratio = 2.0
inertia = [0.5, 0.4]
stiffness = [6e3, 5e3]
damping = [0.2, 0.2]

[[branch]]
name = "b"
at = 1
ratio = -3.5
inertia = [0.6, 0.45]
stiffness = [4e3, {length = 1.0, G = 8e10, Jp = 1e-7, rho = 7800.0, elements = 8}]
right = "clamped"
right_stiffness = 2e3

[[branch]]
name = "c"
on = "a"
at = 1
inertia = [0.2]
stiffness = [3e3]

[[load]]
dof = "main.0"
kind = "step"
amplitude = 10.0

[scheme]
name = "hht"
alpha = -0.1
form = "acceleration"

[time]
dt = 1e-3
duration = 0.4
"""


def test_scene_runs_and_equals_simulate_mck():
    sc = dd.scene_from_dict(SCENE)
    M, C, K = sc.matrices()
    assert M.shape == (15, 15) and sc.dof_names[:3] == ("main.0", "main.1", "main.2")
    assert sc.dof_names[5] == "c.0" and sc.dof_names[-2:] == ("b.1.e7", "b.1")  # depth first
    r, report = dd.run_scene(sc)
    ref = dd.mck_response(M, C, K, sc.force, sc.dt, force_dofs=sc.loaded, scheme="hht",
                          alpha=-0.1, outputs=sc.outputs)
    assert np.abs(r.x - ref.x).max() <= 1e-9 * np.abs(ref.x).max()
    assert report["backend"] == "c" and report["check"] == "done"


def test_modes_json_is_the_wittrick_williams_count(tmp_path):
    path = tmp_path / "gear.toml"
    path.write_text(TOML)
    out = subprocess.run([sys.executable, "-m", "dtdyn", "modes", str(path), "--count",
                          "5", "--json"], capture_output=True, text=True, check=True).stdout
    data = json.loads(out)
    sc = dd.load_scene(path)
    exact = dd.shaft_frequencies(sc.model, count=5)
    np.testing.assert_array_equal(data["omega_rad_s"], exact)
    M, _, K = sc.matrices(sparse=False)
    lumped = np.sqrt(sla.eigh(K, M, eigvals_only=True)[:5])
    assert np.abs(np.array(data["omega_rad_s"]) / lumped - 1).max() < 1e-2  # 8 segments vs exact


@pytest.mark.parametrize("change, match", [
    (lambda s: s["branch"][2].update(on="zz"), r"branch\[2\].on = 'zz'"),
    (lambda s: s["branch"][0].update(ratio=0.0), r"branch\[0\].*ratio = 0.0"),
    (lambda s: s["model"].update(left="pinned"), r"left = 'pinned'"),
    (lambda s: s["model"].update(stiffness=[1e4, -1.0, 9e3]), r"stiffness\[1\] = -1.0"),
    (lambda s: s["branch"][1]["stiffness"][1].update(rho=-2.0),
     r"branch\[1\].stiffness\[1\]: ContinuousShaft rho = -2.0"),
    (lambda s: s["branch"][0].update(at=9), r"at = 9"),
    (lambda s: s["model"].update(color="red"), r"model.color: unknown key"),
])
def test_errors_name_field_and_value(change, match):
    import copy
    s = copy.deepcopy(SCENE)
    change(s)
    with pytest.raises(ValueError, match=match):
        dd.scene_from_dict(s)


def test_continuous_shaft_to_a_clamped_right_end():
    """right_stiffness as a continuous-shaft table (right = "clamped"): the scene's model is the
    Shaft built directly, frequencies and run bitwise; a missing field is named."""
    seg = {"length": 1.0, "G": 8e10, "Jp": 1e-7, "rho": 7800.0, "elements": 8}
    spec = {"model": {"kind": "shaft", "inertia": [1.0, 0.5], "stiffness": [1e4, 2e4],
                      "damping": [0.1, 0.1], "right": "clamped", "right_stiffness": seg},
            "load": [{"dof": "main.1", "kind": "step", "amplitude": 1.0}],
            "scheme": {"name": "newmark"}, "time": {"dt": 1e-3, "duration": 0.05}}
    scene = dd.scene_from_dict(spec)
    direct = dd.Shaft([1.0, 0.5], [1e4, 2e4], [0.1, 0.1], right="clamped",
                      right_stiffness=dd.ContinuousShaft(**seg))
    assert scene.dof_names == direct.dof_names and scene.dof_names[2] == "main.right.e1"
    np.testing.assert_array_equal(dd.shaft_frequencies(scene.model, count=5),
                                  dd.shaft_frequencies(direct, count=5))
    response, _ = dd.run_scene(scene)
    ref = dd.shaft_response(direct, scene.force, scene.dt, force_dofs=scene.loaded,
                            outputs=scene.outputs)
    np.testing.assert_array_equal(response.x, ref.x)
    spec["model"]["right_stiffness"] = {"length": 1.0}
    with pytest.raises(ValueError, match=r"model.right_stiffness.G is required"):
        dd.scene_from_dict(spec)
