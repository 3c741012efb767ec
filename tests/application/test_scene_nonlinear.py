"""Scenes with nonlinear elements: [[element]] and [nonlinear] tables, field-naming errors, the
run through nonlinear_mck_response, `dtdyn simulate` statistics and loud step failures."""
from __future__ import annotations

import importlib.resources
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from dtdyn.app import _problems as problems
from dtdyn import DtdynStepStabilityError, NewtonError
from dtdyn.linear import chain_matrices
from dtdyn.app._cli import main
from dtdyn.nonlinear import Cubic, Gap, Law, nonlinear_mck_response, reference_response
from dtdyn.app._scene import load_scene, run_scene

P4_FILE = Path(str(importlib.resources.files("dtdyn.app").joinpath("scenes/p4.toml")))

# P4 (reference problem, runtime/problems.py) as a matrices model, 2000 samples at 1 kHz
P4_MODEL = """
[model]
kind = "matrices"
M = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
K = [[2e4, -1e4, 0.0, 0.0], [-1e4, 2e4, -1e4, 0.0], [0.0, -1e4, 2e4, -1e4], [0.0, 0.0, -1e4, 1e4]]
dofs = ["m0", "m1", "m2", "m3"]
[model.damping]
rayleigh = [1.0, 2e-4]
"""
P4_ELEMENTS = """
[[element]]
kind = "cubic"
i = 0
k3 = 2e7
[[element]]
kind = "cubic"
i = "m1"
j = 2
k3 = 2e7
"""
NOISE = """
[[load]]
dof = 3
kind = "white_noise"
std = 100.0
seed = 0
"""
NONLINEAR = """
[scheme]
name = "modal_ramp"
[nonlinear]
substeps = 3
"""
TIME = """
[time]
dt = 1e-3
duration = 1.999
"""
OUTPUT = """
[output]
outputs = ["m1", 3]
quantities = ["x", "a"]
"""


def write_scene(tmp_path: Path, *, model=P4_MODEL, elements=P4_ELEMENTS, loads=NOISE,
                nonlinear=NONLINEAR, time=TIME, extra=OUTPUT, name="scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(f'title = "nonlinear test"\n{model}\n{elements}\n{loads}\n'
                                    f'{nonlinear}\n{time}\n{extra}'))
    return path


def law_scene(tmp_path, *, expression, constants, scheme, nonlinear="", dt=1e-2, duration=3.0,
              name="law.toml"):
    """The P4 linear part with one Law element to ground at DOF 3 (and no cubic springs)."""
    consts = "".join(f"{k} = {v!r}\n" for k, v in constants.items())
    element = (f'[[element]]\nkind = "law"\ni = 3\nexpression = {expression!r}\n'
               f"[element.constants]\n{consts}")
    return write_scene(tmp_path, elements=element, nonlinear=scheme + nonlinear,
                       time=f"[time]\ndt = {dt!r}\nduration = {duration!r}\n", extra="",
                       name=name)


# ---------------------------------------------------------------------------------------------
# the packaged P4 scene is reference problem P4

def test_packaged_p4_scene_is_reference_problem_p4():
    sc = load_scene(P4_FILE)
    p = problems.p4()  # 100,000 samples of white noise, seed 0
    assert not sc.linear and sc.kind == "matrices"
    assert sc.scheme == "modal_ramp" and sc.nonlinear == {"substeps": 3} and sc.backend == "c"
    assert sc.dt == 1e-3 and sc.force.shape == (100_000, 1)
    assert_array_equal(sc.loaded, p["force_dofs"])
    assert_array_equal(sc.force, p["force"])
    for ours, theirs in ((sc.M, p["M"]), (sc.C, p["C"]), (sc.K, p["K"])):
        assert_allclose(ours, theirs, rtol=1e-15, atol=0.0)
    assert sc.elements == tuple(p["elements"])


# ---------------------------------------------------------------------------------------------
# the run: exactly nonlinear_mck_response, storing what the scene asks for

def test_p4_scene_equals_direct_nonlinear_response(tmp_path):
    sc = load_scene(write_scene(tmp_path))
    assert sc.n_steps == 1999 and sc.force.shape == (2000, 1)
    response, report = run_scene(sc)
    p = problems.p4(2000)
    direct = nonlinear_mck_response(p["M"], p["C"], p["K"], p["force"], p["dt"],
                                force_dofs=p["force_dofs"], elements=p["elements"], outputs=[1, 3],
                                scheme="modal_ramp", substeps=3)
    assert_array_equal(response.outputs, [1, 3])
    assert_array_equal(response.x, direct.x)
    assert_array_equal(response.a, direct.a)
    assert response.v is None  # the scene asks for x and a only
    assert_allclose(response.t, sc.t, rtol=1e-12)
    assert report["scheme"] == "modal_ramp" and report["substeps"] == 3
    assert report["max_rel_error"] is None and report["n_dof"] == 4 and report["n_outputs"] == 2
    assert report["elements"] == ["Cubic (DOF 0 - ground)", "Cubic (DOF 1 - DOF 2)"]
    assert report["total_time_s"] >= report["run_time_s"] > 0.0  # the loop is part of the call
    assert report["newton_iterations"]["max"] >= 1 and report["max_residual"] < 1e-10


def test_p4_scene_against_solve_ivp(tmp_path):
    """Behaviour against the independent truth: solve_ivp (DOP853, rtol 1e-12), 0.5 s of P4."""
    sc = load_scene(write_scene(tmp_path, time="[time]\ndt = 1e-3\nduration = 0.499\n",
                                extra=""))
    response, _ = run_scene(sc)
    p = problems.p4(500)
    ref = reference_response(p["M"], p["C"], p["K"], p["force"], p["dt"],
                             force_dofs=p["force_dofs"], elements=p["elements"], cache=False)
    err = np.max(np.abs(response.x - ref.x)) / np.max(np.abs(ref.x))
    assert err < 1e-4  # 1.5e-5: second order in h = 1/3 ms


def test_chain_model_with_elements_uses_chain_matrices(tmp_path):
    chain = ("[model]\nmass = [1.0, 2.0, 1.5]\nstiffness = [1e4, 2e4, 1e4]\n"
             "damping = [2.0, 1.0, 1.0]\n")
    elements = '[[element]]\nkind = "cubic"\ni = 2\nj = 0\nk3 = 1e7\n'
    scheme = '[scheme]\nname = "newmark"\nbeta = 0.3\ngamma = 0.6\n'
    path = write_scene(tmp_path, model=chain, elements=elements, loads=NOISE.replace("3", "2"),
                       nonlinear=scheme, extra="")
    sc = load_scene(path)
    assert sc.kind == "chain" and sc.scheme == "newmark"
    assert sc.scheme_params == {"beta": 0.3, "gamma": 0.6}
    response, report = run_scene(sc)
    M, C, K = chain_matrices(sc.mass, sc.stiffness, sc.damping, sparse=False)
    direct = nonlinear_mck_response(M, C, K, sc.force, 0.001, force_dofs=[2],
                                elements=[Cubic(2, 0, k3=1e7)], scheme="newmark", beta=0.3,
                                gamma=0.6)
    assert_array_equal(response.x, direct.x)
    assert report["scheme_params"] == {"beta": 0.3, "gamma": 0.6}


def test_modes_are_passed_and_checked(tmp_path):
    nl = NONLINEAR + "modes = [0, 1]\n"
    response, _ = run_scene(load_scene(write_scene(tmp_path, nonlinear=nl)))
    p = problems.p4(2000)
    direct = nonlinear_mck_response(p["M"], p["C"], p["K"], p["force"], p["dt"],
                                force_dofs=p["force_dofs"], elements=p["elements"], outputs=[1, 3],
                                substeps=3, modes=[0, 1])
    assert_array_equal(response.x, direct.x)
    path = write_scene(tmp_path, nonlinear=NONLINEAR + "modes = [0, 7]\n", name="m.toml")
    with pytest.raises(ValueError, match=r"m\.toml: nonlinear\.modes = \[0, 7\]"):
        run_scene(load_scene(path))


# ---------------------------------------------------------------------------------------------
# field-naming errors

def _element(kind_fields: str, i=3) -> str:
    return P4_ELEMENTS + f"[[element]]\ni = {i}\n{kind_fields}\n"


BAD = {
    "unknown kind": (dict(elements=_element('kind = "quartic"')),
                     r"element\[2\]\.kind = 'quartic': unknown value, allowed: 'cubic'"),
    "missing kind": (dict(elements=_element("k3 = 1.0")), r"element\[2\]\.kind is required"),
    "missing k3": (dict(elements=_element('kind = "cubic"')),
                   r"element\[2\]\.k3 is required for kind 'cubic'"),
    "k3 not a number": (dict(elements=_element('kind = "cubic"\nk3 = "big"')),
                        r"element\[2\]\.k3 = 'big': must be a number"),
    "dof out of range": (dict(elements=_element('kind = "cubic"\nk3 = 1.0', i=4)),
                         r"element\[2\]\.i = 4: must be a DOF index in 0\.\.3"),
    "unknown dof name": (dict(elements=_element('kind = "cubic"\nk3 = 1.0\nj = "roof"')),
                         r"element\[2\]\.j = 'roof': unknown DOF name"),
    "same dof": (dict(elements=_element('kind = "cubic"\nk3 = 1.0\nj = "m3"')),
                 r"element\[2\]\.j = 'm3': the same DOF as element\[2\]\.i = 3"),
    "unknown element key": (dict(elements=_element('kind = "cubic"\nk3 = 1.0\nk5 = 2.0')),
                            r"element\[2\]\.k5 = 2\.0: unknown key for kind 'cubic', allowed: "
                            r"kind, i, j, k3"),
    "gap stiffness": (dict(elements=_element('kind = "gap"\ngap = 1e-3\nstiffness = -1.0')),
                      r"element\[2\]\.stiffness = -1\.0: must be > 0"),
    "gap side": (dict(elements=_element('kind = "gap"\ngap = 1e-3\nstiffness = 1.0\n'
                                        'side = "up"')), r"element\[2\]\.side = 'up'"),
    "empty coeffs": (dict(elements=_element('kind = "polynomial"\ncoeffs = []')),
                     r"element\[2\]\.coeffs = \[\]: must be a non-empty array"),
    "bouc-wen n": (dict(elements=_element('kind = "bouc_wen"\nstiffness = 1.0\nbeta = 0.5\n'
                                          'gamma = 0.5\nn = 0.5')),
                   r"element\[2\]\.n = 0\.5: must be >= 1"),
    "bouc-wen beta + gamma": (dict(elements=_element('kind = "bouc_wen"\nstiffness = 1.0\n'
                                                     'beta = -1.0\ngamma = 0.5')),
                              r"element\[2\] \(kind 'bouc_wen'\): .*beta \+ gamma must be > 0"),
    "law undeclared name": (dict(elements=_element('kind = "law"\nexpression = "k*x"')),
                            r"element\[2\]\.expression = 'k\*x': unknown name 'k'"),
    "law constant not a number": (
        dict(elements=_element('kind = "law"\nexpression = "k*x"\n[element.constants]\n'
                               'k = "a"')), r"element\[2\]\.constants\.k = 'a': must be a number"),
    "law reserved constant": (
        dict(elements=_element('kind = "law"\nexpression = "j*x"\n[element.constants]\n'
                               'j = 1.0')), r"element\[2\]\.constants\.j = 1\.0: .*reserved"),
    "element not an array of tables": (dict(elements='[element]\nkind = "cubic"\ni = 0\n'
                                                     'k3 = 1.0\n'),
                                       r"element = .*: must be zero or more \[\[element\]\]"),
    "unknown scheme": (dict(nonlinear='[scheme]\nname = "rk4"\n'),
                       r"scheme\.name = 'rk4': a scene with \[\[element\]\] takes one of "
                       r"'modal_ramp'"),
    "multistep scheme": (dict(nonlinear='[scheme]\nname = "park"\n'),
                         r"scheme\.name = 'park': .*multistep schemes cannot"),
    "old nonlinear.method key": (dict(nonlinear='[nonlinear]\nmethod = "modal_ramp"\n'),
                                 r"nonlinear\.method = 'modal_ramp': unknown key"),
    "substeps": (dict(nonlinear='[nonlinear]\nsubsteps = 0\n'),
                 r"nonlinear\.substeps = 0: must be an integer >= 1"),
    "max_iter": (dict(nonlinear='[nonlinear]\nmax_iter = 2.5\n'), r"nonlinear\.max_iter = 2\.5"),
    "tol": (dict(nonlinear='[nonlinear]\ntol = -1e-9\n'), r"nonlinear\.tol = -1e-09: must be > 0"),
    "backend": (dict(nonlinear='[nonlinear]\nbackend = "numpy"\n'),
                r"nonlinear\.backend = 'numpy': unknown value, allowed: 'c', 'casadi'"),
    "unknown nonlinear key": (dict(nonlinear='[nonlinear]\nsolver = "newton"\n'),
                              r"nonlinear\.solver = 'newton': unknown key, allowed: substeps"),
    "modes for a scheme": (dict(nonlinear='[scheme]\nname = "newmark"\n[nonlinear]\nmodes = [0]\n'),
                           r"nonlinear\.modes = \[0\]: selects modal filters"),
    "modes repeat": (dict(nonlinear='[nonlinear]\nmodes = [1, 1]\n'),
                     r"nonlinear\.modes = \[1, 1\]: repeats a mode"),
    "modal scheme with parameters": (dict(nonlinear='[scheme]\nname = "modal_ramp"\nbeta = 0.3\n'),
                                     r"scheme\.beta = 0\.3: unknown key"),
    "chain-only scheme key": (dict(nonlinear='[scheme]\nname = "newmark"\nsweep = "plain"\n'),
                              r"scheme\.sweep = 'plain': only for linear chains"),
    "nonlinear without elements": (dict(elements="", nonlinear='[scheme]\nname = "newmark"\n'
                                        '[nonlinear]\nsubsteps = 3\n'),
                                   r"the \[nonlinear\] options need at least one \[\[element\]\]"),
    "accuracy zero": (dict(nonlinear='[nonlinear]\naccuracy = 0.0\n'),
                      r"nonlinear\.accuracy = 0\.0: must be > 0 \(a relative error"),
    "accuracy text": (dict(nonlinear='[nonlinear]\naccuracy = "1e-6"\n'),
                      r"nonlinear\.accuracy = '1e-6': must be a (finite )?number"),
    "max_substeps without accuracy": (dict(nonlinear='[nonlinear]\nmax_substeps = 8\n'),
                                      r"nonlinear\.max_substeps = 8: caps the sub-steps an "
                                      r"accuracy target may take; give nonlinear\.accuracy"),
    "max_substeps zero": (dict(nonlinear='[nonlinear]\naccuracy = 1e-6\nmax_substeps = 0\n'),
                          r"nonlinear\.max_substeps = 0: must be an integer >= 1"),
    "auto without accuracy": (dict(nonlinear='[scheme]\nname = "auto"\n'),
                              r"scheme\.name = 'auto': picks the method for an accuracy "
                              r"target; give nonlinear\.accuracy too"),
    "sparse model": (dict(model=P4_MODEL.replace('kind = "matrices"',
                                                 'kind = "matrices"\nsparse = true')),
                     r"model\.sparse = True: a scene with \[\[element\]\] runs on dense"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_malformed_nonlinear_scene_names_the_field(tmp_path, case):
    kwargs, pattern = BAD[case]
    path = write_scene(tmp_path, name="p4.toml", **kwargs)
    with pytest.raises(ValueError, match=pattern) as info:
        load_scene(path)
    assert str(info.value).startswith(f"{path}: ")


def test_linear_scene_without_a_scheme_takes_the_default(tmp_path):
    """No [[element]] and no [scheme]: mck_response's default scheme, newmark (beta = 1/4,
    gamma = 1/2), as the API runs it."""
    path = write_scene(tmp_path, elements="", nonlinear="")
    sc = load_scene(path)
    assert sc.linear and (sc.scheme, sc.scheme_params, sc.unstable) == ("newmark", {}, "raise")


def test_nonlinear_scene_refuses_scheme_unstable(tmp_path):
    path = write_scene(tmp_path, nonlinear='[scheme]\nname = "newmark"\nunstable = "warn"\n')
    with pytest.raises(ValueError, match=r"scheme\.unstable = 'warn': only for linear scenes"):
        load_scene(path)


# ---------------------------------------------------------------------------------------------
# Law elements: parsed, never evaluated as Python

def test_law_element_in_a_scene(tmp_path):
    path = law_scene(tmp_path, expression="k3*x**3 + c*v", constants={"k3": 2e7, "c": 5.0},
                     scheme="", nonlinear="[nonlinear]\nsubsteps = 2\n", dt=1e-3,
                     duration=0.499)
    sc = load_scene(path)
    assert sc.elements == (Law(3, expression="k3*x**3 + c*v", k3=2e7, c=5.0),)
    response, _ = run_scene(sc)
    p = problems.p4(500)
    ref = reference_response(p["M"], p["C"], p["K"], p["force"], p["dt"], force_dofs=[3],
                             elements=sc.elements, cache=False)
    assert np.max(np.abs(response.x - ref.x)) < 1e-3 * np.max(np.abs(ref.x))  # 1.3e-4


def test_malicious_law_is_refused_at_load(tmp_path, capfd):
    path = law_scene(tmp_path, expression='__import__("os").system("echo hi")', constants={},
                     scheme="", name="p4.toml")
    with pytest.raises(ValueError, match=r"p4\.toml: element\[0\]\.expression = "
                                         r"'__import__\(\"os\"\)\.system\(\"echo hi\"\)': "):
        load_scene(path)
    out = tmp_path / "r.npz"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    captured = capfd.readouterr()
    assert "element[0].expression" in captured.err and "hi" not in captured.out
    assert not out.exists()


# ---------------------------------------------------------------------------------------------
# `dtdyn simulate`: statistics, stored quantities, loud failures that write nothing

def test_cli_prints_nonlinear_statistics(tmp_path, capsys):
    out = tmp_path / "r.npz"
    assert main(["simulate", str(write_scene(tmp_path)), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 nonlinear element(s), scheme modal_ramp (3 substep(s) per sample, backend c)" in text
    assert "element[1]: Cubic (DOF 1 - DOF 2)" in text
    assert "construct time:" in text and "compile or cache load:" in text
    assert "run time:" in text and "us per step of h = dt / 3" in text
    assert "Newton iterations per step: max " in text and ", mean " in text
    assert "max residual: " in text and "error against the exact" not in text
    data = np.load(out)
    assert sorted(data.files) == ["a", "dof_names", "dtdyn_metadata", "outputs", "t", "x"]
    assert data["x"].shape == (2000, 2) and list(data["dof_names"]) == ["m1", "m3"]


def test_accuracy_scene_equals_the_direct_call(tmp_path, capsys):
    """[nonlinear] accuracy without a [scheme]: nonlinear_mck_response(accuracy=...) with the method
    it picks ("auto": modal_explicit on P4), bit for bit; the report and `dtdyn simulate` give
    the method that ran, the estimate and whether the target was met."""
    path = write_scene(tmp_path, nonlinear="[nonlinear]\naccuracy = 1e-6\n")
    sc = load_scene(path)
    assert sc.scheme == "auto" and sc.nonlinear == {"accuracy": 1e-6}
    response, report = run_scene(sc)
    p = problems.p4(2000)
    direct = nonlinear_mck_response(p["M"], p["C"], p["K"], p["force"], p["dt"],
                                force_dofs=p["force_dofs"], elements=p["elements"], outputs=[1, 3],
                                quantities=("x", "a"), accuracy=1e-6)
    assert_array_equal(response.x, direct.x)
    assert_array_equal(response.a, direct.a)
    assert report["scheme"] == direct.info["scheme"] == "modal_explicit"
    assert report["accuracy"] == 1e-6 and report["accuracy_met"]
    assert report["error_estimate"] == direct.info["error_estimate"] <= 1e-6
    assert main(["simulate", str(path)]) == 0
    text = capsys.readouterr().out
    assert "scheme auto (accuracy 1e-06, backend c)" in text
    assert "all the runs the target took" in text
    assert (f"error estimate: {report['error_estimate']:.3g} (relative; ran modal_explicit, "
            f"{report['substeps']} substep(s) per sample; accuracy 1e-06 met)") in text
    out = tmp_path / "r.npz"
    assert main(["simulate", str(path), "--out", str(out)]) == 0
    from dtdyn import load_result
    run = load_result(out).meta["run"]
    assert run["scheme"] == "modal_explicit" and run["accuracy_met"] and run["accuracy"] == 1e-6


def test_accuracy_scene_not_met_says_so(tmp_path, capsys):
    """A target beyond max_substeps: the run warns, `dtdyn simulate` prints "NOT met" with the
    estimate reached, and the results are still written (exit code 0: the response is the best
    one reached, and says what it is)."""
    path = write_scene(tmp_path, nonlinear='[scheme]\nname = "newmark"\n[nonlinear]\n'
                                           'accuracy = 1e-9\nmax_substeps = 2\n')
    assert main(["simulate", str(path)]) == 0
    out = capsys.readouterr()
    assert "dtdyn simulate: warning: DtdynAccuracyWarning: accuracy=1e-09 not reached" in out.err
    text = out.out
    assert "ran newmark, 2 substep(s) per sample; accuracy 1e-09 NOT met)" in text


GAP_HARD = '[[element]]\nkind = "gap"\ni = 3\ngap = 1e-4\nstiffness = 1e8\nsmoothing = 0.0\n'
TANH = dict(expression="F0*tanh(x/x0)", constants={"F0": 100.0, "x0": 1e-5})


def test_newton_failure_names_the_step_and_more_substeps_cure_it(tmp_path, capsys):
    """A stiff saturating law at dt = 10 ms: Newton cycles between the branches of tanh."""
    scheme = '[scheme]\nname = "average_acceleration"\n'
    path = law_scene(tmp_path, scheme=scheme, name="stiff.toml", **TANH)
    with pytest.raises(NewtonError, match=r"stiff\.toml: Newton did not converge at step 1 "
                                          r"\(sample 1, t = 0\.01 s\).*nonlinear\.substeps = 1"):
        run_scene(load_scene(path))
    out, plot = tmp_path / "r.npz", tmp_path / "r.png"
    assert main(["simulate", str(path), "--out", str(out), "--plot", str(plot)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("dtdyn simulate: run failed: ")
    assert "Newton did not converge at step 1" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stiff.toml"]  # nothing written

    cured = law_scene(tmp_path, scheme=scheme, nonlinear="[nonlinear]\nsubsteps = 16\n",
                      name="cured.toml", **TANH)
    response, report = run_scene(load_scene(cured))
    assert np.isfinite(response.x).all() and report["substeps"] == 16
    assert report["max_residual"] < 1e-9


def test_stiff_gap_beyond_the_stability_limit_names_the_step(tmp_path, capsys):
    """A Gap of huge stiffness at dt = 10 ms: Newton converges (the residual is piecewise
    linear and monotone), but the modal ramp filter's element step is unstable; the message
    names the step and the substeps that cure it."""
    time = "[time]\ndt = 1e-2\nduration = 2.0\n"
    path = write_scene(tmp_path, elements=GAP_HARD, nonlinear="", time=time, extra="",
                       name="gap.toml")
    with pytest.raises(DtdynStepStabilityError,
                       match=r"gap\.toml: scheme 'modal_ramp' is unstable at step 1 \(sample 1, "
                             r"t = 0\.01 s\).*use substeps >= 29"):
        run_scene(load_scene(path))
    out = tmp_path / "r.npz"
    assert main(["simulate", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unstable at step 1" in err and not out.exists()

    cured = write_scene(tmp_path, elements=GAP_HARD, nonlinear="[nonlinear]\nsubsteps = 32\n",
                        time=time, extra="", name="gap32.toml")
    response, report = run_scene(load_scene(cured))
    assert np.isfinite(response.x).all() and report["max_theta"] <= 2.0
    # the contact is reached: DOF 3 goes beyond the gap
    assert np.max(np.abs(response.x[:, 3])) > 1e-4
    # and the same element with an implicit scheme needs no substeps
    implicit = write_scene(tmp_path, elements=GAP_HARD,
                           nonlinear='[scheme]\nname = "average_acceleration"\n', time=time,
                           extra="", name="gap_aa.toml")
    response, _ = run_scene(load_scene(implicit))
    assert np.isfinite(response.x).all()


def test_gap_element_direct_equivalence(tmp_path):
    """Every Gap field reaches the element: the scene's element equals the one built in Python."""
    gap = ('[[element]]\nkind = "gap"\ni = 2\nj = "m3"\ngap = 1e-3\nstiffness = 1e6\n'
           'smoothing = 1e-5\nside = "positive"\n')
    sc = load_scene(write_scene(tmp_path, elements=gap))
    assert sc.elements == (Gap(2, 3, gap=1e-3, stiffness=1e6, smoothing=1e-5, side="positive"),)


def test_nonlinear_scene_with_an_initial_state(tmp_path):
    """[initial] in a scene with [[element]]: the run equals nonlinear_mck_response with x0, v0."""
    import dtdyn as dd

    path = tmp_path / "duffing.toml"
    path.write_text('[model]\nmass = [1.0]\nstiffness = [1e4]\ndamping = [2.0]\n'
                    '[[load]]\ndof = 0\nkind = "step"\namplitude = 0.0\n'
                    '[[element]]\nkind = "cubic"\ni = 0\nk3 = 1e9\n'
                    '[initial]\nx0 = [0.01]\nv0 = [-0.5]\n'
                    '[time]\ndt = 1e-3\nduration = 0.5\n')
    scene = dd.load_scene(path)
    response, _ = dd.run_scene(scene)
    same = dd.nonlinear_mck_response([[1.0]], [[2.0]], [[1e4]], np.zeros(501), 1e-3,
                                 elements=[dd.Cubic(0, k3=1e9)], x0=[0.01], v0=[-0.5],
                                 quantities=("x",))
    np.testing.assert_array_equal(response.x, same.x)
    assert response.x[0, 0] == pytest.approx(0.01, rel=1e-12)   # the modal state, projected


def test_nonlinear_scene_stores_element_forces_and_states(tmp_path):
    import dtdyn as dd

    path = tmp_path / "bw.toml"
    path.write_text('[model]\nmass = [1.0]\nstiffness = [1e4]\ndamping = [2.0]\n'
                    '[[load]]\ndof = 0\nkind = "sine"\namplitude = 30.0\nfrequency = 2.0\n'
                    '[[element]]\nkind = "bouc_wen"\ni = 0\nstiffness = 2e3\nbeta = 300.0\n'
                    'gamma = 300.0\n[time]\ndt = 1e-3\nduration = 1.0\n'
                    '[output]\nquantities = ["x", "g", "z"]\n')
    response, _ = dd.run_scene(dd.load_scene(path))
    assert response.g.shape == (1001, 1) and response.z.shape == (1001, 1)
    out = tmp_path / "r.npz"
    response.save(out)
    np.testing.assert_array_equal(dd.load_result(out).z, response.z)
    linear = path.read_text().split("[[element]]")[0] + '[scheme]\nname = "newmark"\n' \
        '[time]\ndt = 1e-3\nduration = 1.0\n[output]\nquantities = ["x", "g"]\n'
    path.write_text(linear)
    with pytest.raises(ValueError, match="output.quantities"):
        dd.load_scene(path)
