"""Scenes with kind = "beam": the issue's [model] table, the run against mck_response on
Scene.matrices() (same scheme), `dtdyn modes --json` against the closed-form cantilever
frequencies, errors that name the field."""
import json
import subprocess
import sys

import numpy as np
import pytest

import dtdyn as dd

MODEL = {"kind": "beam", "E": 2.1e11, "I": 8.0e-6, "rho_A": 20.0, "length": 3.0,
         "elements": 200, "left": "clamped", "right": "free"}
SCENE = {
    "title": "cantilever",
    "model": MODEL | {"rayleigh": [0.5, 1e-6],
                      "point_masses": [{"node": 100, "mass": 5.0, "inertia": 0.01}],
                      "supports": [{"node": 150, "k_w": 1e5, "c_w": 20.0}]},
    "load": [{"dof": "w200", "kind": "step", "amplitude": 100.0}],
    "scheme": {"name": "newmark", "form": "acceleration"},
    "time": {"dt": 1e-4, "duration": 0.1},
    "output": {"outputs": ["w200", "psi100"], "quantities": ["x", "v"]},
}


def test_beam_scene_runs_like_the_assembled_model():
    scene = dd.scene_from_dict(SCENE)
    assert scene.kind == "beam" and scene.n_dof == 400 and scene.dof_names[:2] == ("w1", "psi1")
    M, C, K = scene.matrices()
    assert M.shape == (400, 400)
    response, report = dd.run_scene(scene)
    ref = dd.mck_response(M, C, K, scene.force, scene.dt, force_dofs=scene.loaded,
                          outputs=scene.outputs, quantities=("x", "v"))
    # both solve the same steps; each solve rounds at eps cond(A), cond(A) ~ 1 + Omega_max^2 / 4
    # (Omega_max = omega_max dt ~ 1e3), summed over the steps at worst (tests/test_beam.py);
    # the assembled solvers differ among themselves (dense, SuperLU, NumPy) by 1.4e-9 .. 2e-9
    omega_max = dd.beam_frequencies(scene.model)[-1]
    bound = scene.n_steps * np.finfo(float).eps * (1 + (omega_max * scene.dt) ** 2 / 4)
    for q in "xv":
        assert np.abs(getattr(response, q) - getattr(ref, q)).max() \
            <= bound * np.abs(getattr(ref, q)).max()


def test_modes_json_gives_the_cantilever_frequencies(tmp_path):
    path = tmp_path / "beam.toml"
    path.write_text("\n".join(["[model]"] + [f"{k} = {json.dumps(v)}" for k, v in MODEL.items()]
                              + ['[[load]]', 'dof = "w200"', 'kind = "step"', "[scheme]",
                                 'name = "newmark"', "[time]", "dt = 1e-4", "duration = 0.01"]))
    out = subprocess.run([sys.executable, "-m", "dtdyn", "modes", str(path), "--count",
                          "5", "--json"], capture_output=True, text=True, check=True)
    omega = np.array(json.loads(out.stdout)["omega_rad_s"])
    beta_l = np.array([1.875104, 4.694091, 7.854757, 10.995541, 14.137168])
    np.testing.assert_allclose(omega, beta_l**2 * np.sqrt(2.1e11 * 8e-6 / (20.0 * 3.0**4)),
                               rtol=1e-6)


@pytest.mark.parametrize("change, match", [
    ({"E": -1.0}, r"model\.E\[0\] = -1\.0"),
    ({"elements": 2.5}, r"elements = 2\.5"),
    ({"left": "glued"}, r"left = 'glued'"),
    ({"supports": [{"node": 3, "k": 1.0}]}, r"model\.supports\[0\]\.k: unknown key"),
    ({"nodes": 3}, r"model\.nodes: unknown key"),
])
def test_bad_beam_scene_names_the_field(change, match):
    with pytest.raises(ValueError, match=match):
        dd.scene_from_dict(SCENE | {"model": MODEL | change})


def test_missing_beam_key_is_named():
    model = dict(MODEL)
    del model["rho_A"]
    with pytest.raises(ValueError, match=r"model\.rho_A is required"):
        dd.scene_from_dict(SCENE | {"model": model})


def test_beam_scene_with_support_motion():
    """[ground] on a beam: the run equals beam_response with the same record (default
    influence: the rigid translation) and stores a_abs."""
    t = np.arange(1001) * 1e-4
    scene = dd.scene_from_dict(SCENE | {
        "ground": {"kind": "sine", "amplitude": 2.0, "frequency": 30.0, "units": "g"}})
    response, _ = dd.run_scene(scene)
    ag = 2.0 * 9.80665 * np.sin(2 * np.pi * 30.0 * t)
    same = dd.beam_response(scene.model, scene.force, scene.dt, force_dofs=scene.loaded,
                            ground_acceleration=ag, outputs=scene.outputs, form="acceleration",
                            quantities=("x", "v"))
    np.testing.assert_allclose(response.x, same.x, rtol=0, atol=1e-12 * np.abs(same.x).max())


def test_refine_key_reaches_the_beam_runs():
    """scheme.refine (linear) and nonlinear.refine (with [[element]]) are the runs' ``refine``:
    the scene equals beam_response / nonlinear_beam_response called with it, and a run's
    info says how many corrections a step took; other kinds and bad values are refused."""
    base = {k: v for k, v in SCENE.items() if k != "output"} | {"time": {"dt": 1e-4,
                                                                         "duration": 0.01}}
    for refine in (True, False):
        scene = dd.scene_from_dict(base | {"scheme": {"name": "newmark", "refine": refine}})
        r, _ = dd.run_scene(scene)
        ref = dd.beam_response(scene.model, scene.force, scene.dt, force_dofs=scene.loaded,
                               refine=refine)
        np.testing.assert_array_equal(r.x, ref.x)
        assert (r.info["refinements"] > 0) == refine
    nl = base | {"element": [{"kind": "cubic", "i": "w200", "k3": 1e9}],
                 "nonlinear": {"substeps": 1, "refine": True}, "scheme": {"name": "newmark"}}
    scene = dd.scene_from_dict(nl)
    r, _ = dd.run_scene(scene)
    ref = dd.nonlinear_beam_response(scene.model, scene.force, scene.dt,
                                     force_dofs=scene.loaded, elements=scene.elements,
                                     substeps=1, refine=True)
    np.testing.assert_array_equal(r.x, ref.x)
    with pytest.raises(ValueError, match=r"scheme\.refine = 'yes': must be \"auto\", true or "):
        dd.scene_from_dict(base | {"scheme": {"refine": "yes"}})
    with pytest.raises(ValueError, match=r"scheme\.refine = True: a scene with \[\[element\]\] "
                                         r"sets nonlinear\.refine"):
        dd.scene_from_dict(nl | {"scheme": {"name": "newmark", "refine": True}})
    chain = {"model": {"mass": [1.0], "stiffness": [4.0]}, "scheme": {"refine": False}}
    with pytest.raises(ValueError, match=r"scheme\.refine = False: only for beams"):
        dd.scene_from_dict(chain)
