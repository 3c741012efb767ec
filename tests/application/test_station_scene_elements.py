"""[[element]] tables in scenes of kind "shaft" and "beam": the run is nonlinear_shaft_response /
nonlinear_beam_response on the scene's model (the same numbers as the direct call, bitwise) and
equals nonlinear_mck_response on Scene.matrices() (the same scheme and substeps) to rounding;
modal methods, which need matrices, are refused with the field named."""
import numpy as np
import pytest

import dtdyn as dd

SHAFT = {
    "title": "geared line with a cubic bearing",
    "model": {"kind": "shaft", "inertia": [1.0, 0.3, 0.9], "stiffness": [1e4, 1.2e4, 9e3],
              "damping": [0.5, 0.8, 0.3]},
    "branch": [{"name": "out", "at": 1, "ratio": 2.0, "inertia": [0.5, 0.4],
                "stiffness": [6e3, 5e3], "damping": [0.2, 0.2]}],
    "load": [{"dof": "main.2", "kind": "sine", "amplitude": 50.0, "frequency": 8.0}],
    "element": [{"kind": "cubic", "i": "out.1", "k3": 4e6},
                {"kind": "cubic", "i": "main.0", "j": "main.2", "k3": 1e6}],
    "scheme": {"name": "hht", "alpha": -0.1},
    "nonlinear": {"substeps": 2},
    "time": {"dt": 2e-3, "duration": 0.5},
    "output": {"quantities": ["x", "v"]},
}
BEAM = {
    "title": "cantilever with a tip gap",
    "model": {"kind": "beam", "E": 2.1e11, "I": 8.0e-6, "rho_A": 20.0, "length": 3.0,
              "elements": 30, "left": "clamped", "right": "free", "rayleigh": [0.5, 1e-5]},
    "load": [{"dof": "w30", "kind": "step", "amplitude": 2e3}],
    "element": [{"kind": "gap", "i": "w30", "gap": 1e-3, "stiffness": 1e7, "smoothing": 1e-5}],
    "scheme": {"name": "newmark"},
    "time": {"dt": 1e-4, "duration": 0.05},
    "output": {"outputs": ["w30", "psi15"], "quantities": ["x"]},
}


def _check(spec, direct):
    scene = dd.scene_from_dict(spec)
    response, report = dd.run_scene(scene)
    assert report["backend"] == "c" and report["substeps"] == spec.get("nonlinear", {}).get(
        "substeps", 1)
    kw = dict(elements=scene.elements, force_dofs=scene.loaded, scheme=scene.scheme,
              outputs=scene.outputs, quantities=scene.quantities, **scene.nonlinear,
              **scene.scheme_params)
    same = direct(scene.model, scene.force, scene.dt, **kw)
    M, C, K = (A.toarray() for A in scene.matrices())
    ref = dd.nonlinear_mck_response(M, C, K, scene.force, scene.dt, **kw)
    for q in scene.quantities:
        a = getattr(response, q)
        np.testing.assert_array_equal(a, getattr(same, q))
        # the two runs solve the same steps (module docstring of dtdyn.nonlinear._stations:
        # equal to nonlinear_mck_response to rounding; 1e-9 as the linear station tests)
        assert np.abs(a - getattr(ref, q)).max() <= 1e-9 * np.abs(getattr(ref, q)).max(), q
    return response


def test_shaft_scene_with_elements():
    r = _check(SHAFT, dd.nonlinear_shaft_response)
    assert np.abs(r.x).max() > 0


def test_beam_scene_with_a_tip_gap():
    r = _check(BEAM, dd.nonlinear_beam_response)
    assert np.abs(r.x[:, 0]).max() > 1e-3  # the tip closes the gap


@pytest.mark.parametrize("spec", [SHAFT, BEAM])
def test_modal_methods_are_refused(spec):
    bad = dict(spec, scheme={"name": "modal_parabolic"})
    bad.pop("nonlinear", None)
    with pytest.raises(ValueError, match="scheme.name = 'modal_parabolic': the modal methods"):
        dd.scene_from_dict(bad)


@pytest.mark.parametrize("spec", [SHAFT, BEAM])
def test_accuracy_targets_are_refused(spec):
    """An accuracy target runs on matrices and chains (nonlinear_mck_response); the station sweep
    runs at a fixed nonlinear.substeps: the field is named."""
    bad = dict(spec, nonlinear={"accuracy": 1e-6})
    with pytest.raises(ValueError, match=r"nonlinear.accuracy = 1e-06: a (shaft|beam) with "
                                         r"\[\[element\]\] runs the DT-TMM sweep at a fixed"):
        dd.scene_from_dict(bad)
