"""Shafts and beams with localized nonlinear elements at stations (issue 14 item 6):
nonlinear_shaft_response and nonlinear_beam_response against nonlinear_mck_response on the dense
assembled matrices (shaft_matrices / beam_matrices .toarray()), same scheme, same substeps.

Truth: nonlinear_mck_response solves the same condensed per-step problem with a dense
factorization of the assembled effective matrix instead of the O(N) sweep, so the two are equal
to rounding; held to 1e-9 relative (the issue's tolerance for the linear sweeps) on x, v, a and
the element forces g, except a beam's rotational accelerations (their bound in
test_beam_equals_assembled). Each case is first checked to be nonlinear: the elements change the
response by far more than the tolerance (against the linear shaft_response / beam_response).
"""
import os
import shutil

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.linear._shaft import rigid_rotation
from dtdyn.nonlinear import _response as NL
from dtdyn.nonlinear import _stations as stations

SCHEMES = [("newmark", {}), ("hht", {"alpha": -0.1}), ("generalized_alpha", {"rho_inf": 0.7})]


def _close(a, b, what, rtol=1e-9):
    err = np.abs(a - b).max() / np.abs(b).max()
    assert err <= rtol, f"{what}: relative difference {err:.3g} > {rtol:g}"


def _shaft():
    """A clamped 4-disk main line, a geared branch (ratio 2) at disk 2, a cubic bearing spring
    to ground on disk 1 and a cubic coupling between the main line's end and the branch's end."""
    shaft = dd.Shaft([1.0, 2.0, 1.5, 1.0], [1e4, 2e4, 2e4, 1.5e4], [1.0, 1.0, 1.0, 1.0],
                     branches=[dd.Branch(2, [0.5, 0.8], [5e3, 6e3], [0.5, 0.5], ratio=2.0,
                                         name="out")])
    elements = [dd.Cubic(shaft.dof("main.1"), k3=1e9),
                dd.Cubic(shaft.dof("main.3"), shaft.dof("out.1"), k3=5e8)]
    t = np.arange(801) * 1e-3
    f = np.column_stack([300.0 * np.sin(40 * t), 150.0 * np.cos(25 * t) * (t > 0.05)])
    return shaft, elements, f, ["main.3", "out.1"]


def _beam():
    """A 20-element cantilever (3 m, light stiffness-proportional damping: 1.1e-4 of critical in
    the first mode): a stiff contact (Gap) at the tip and a cubic spring to ground at
    mid-span; a force at the tip pushes it into the stop."""
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=20, rayleigh=(0.0, 2e-6))
    elements = [dd.Gap(beam.dof("w20"), gap=2e-4, stiffness=2e6),
                dd.Cubic(beam.dof("w10"), k3=1e12)]
    t = np.arange(601) * 1e-4
    f = (200.0 * np.sin(2 * np.pi * 15 * t))[:, None]
    return beam, elements, f, ["w20"]


@pytest.fixture(scope="module")
def shaft_case():
    return _shaft()


@pytest.fixture(scope="module")
def beam_case():
    return _beam()


def test_cases_are_nonlinear(shaft_case, beam_case):
    shaft, elements, f, dofs = shaft_case
    lin = dd.shaft_response(shaft, f, 1e-3, force_dofs=dofs)
    nl = dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=dofs, elements=elements)
    assert np.abs(nl.x - lin.x).max() > 0.05 * np.abs(lin.x).max()
    beam, elements, f, dofs = beam_case
    lin = dd.beam_response(beam, f, 1e-4, force_dofs=dofs)
    nl = dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, elements=elements,
                                    quantities=("x", "g"))
    assert np.abs(nl.x - lin.x).max() > 0.05 * np.abs(lin.x).max()
    assert (np.abs(nl.g[:, 0]) > 0).any() and (nl.g[:, 0] == 0).any()  # contact made and lost


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
@pytest.mark.parametrize("scheme, params", SCHEMES)
def test_shaft_equals_assembled(shaft_case, scheme, params, form, backend):
    shaft, elements, f, dofs = shaft_case
    M, C, K = (A.toarray() for A in dd.shaft_matrices(shaft))
    idx = [shaft.dof(d) for d in dofs]
    a = dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=dofs, elements=elements,
                                    scheme=scheme, form=form, substeps=2, backend=backend,
                                    quantities=("x", "v", "a", "g"), **params)
    b = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=idx, elements=elements,
                              scheme=scheme, substeps=2, quantities=("x", "v", "a", "g"),
                              **params)
    assert a.dof_names == shaft.dof_names
    for q in "xvag":
        _close(getattr(a, q), getattr(b, q), q)


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
@pytest.mark.parametrize("scheme, params", SCHEMES)
def test_beam_equals_assembled(beam_case, scheme, params, form, backend):
    beam, elements, f, dofs = beam_case
    M, C, K = (A.toarray() for A in dd.beam_matrices(beam))
    a = dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, elements=elements,
                                   scheme=scheme, form=form, substeps=2, backend=backend,
                                   quantities=("x", "v", "a", "g"), **params)
    b = NL.nonlinear_mck_response(M, C, K, f, 1e-4, force_dofs=[beam.dof(d) for d in dofs],
                              elements=elements, scheme=scheme, substeps=2,
                              quantities=("x", "v", "a", "g"), **params)
    assert a.dof_names == beam.dof_names
    for q in "xvg":
        _close(getattr(a, q), getattr(b, q), q)
    w = np.arange(0, beam.n_dof, 2)  # w20 ... : beam.dof_names alternate w, psi
    _close(a.a[:, w], b.a[:, w], "a (translations)")
    # the rotations' accelerations carry the rounding of the highest (rotation) modes: a is a
    # difference of displacements over beta h^2, cond(A) ~ 2e3 here, and the sweep and the
    # dense solve round differently. Bound: the linear sweep's own difference from the
    # assembled solve (beam_response against mck_response), same model, load, scheme and h
    # (measured: nonlinear 1.4e-9 .. 8e-9, linear 8e-9 .. 4.3e-8)
    idx = [beam.dof(d) for d in dofs]
    fine = np.interp(np.arange(2 * f.shape[0] - 1) * 5e-5, np.arange(f.shape[0]) * 1e-4, f[:, 0])
    la = dd.beam_response(beam, fine, 5e-5, force_dofs=idx, scheme=scheme, form=form,
                          backend=backend, **params).a
    lb = dd.mck_response(M, C, K, fine, 5e-5, force_dofs=idx, scheme=scheme, **params).a
    _close(a.a, b.a, "a", rtol=max(1e-9, np.abs(la - lb).max() / np.abs(lb).max()))


def test_initial_conditions_outputs_and_ground_motion(shaft_case, beam_case):
    """x0, v0 (a_0 consistent with the elements' forces at x0), outputs by name, and support
    motion (the shaft's default influence: the rigid rotation) against the same reference."""
    shaft, elements, f, dofs = shaft_case
    M, C, K = (A.toarray() for A in dd.shaft_matrices(shaft))
    n = M.shape[0]
    x0, v0 = np.linspace(0.01, 0.03, n), np.linspace(-1.0, 1.0, n)
    a = dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=dofs, elements=elements,
                                    x0=x0, v0=v0, outputs=["out.1", "main.1"])
    b = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[shaft.dof(d) for d in dofs],
                              elements=elements, scheme="newmark", x0=x0, v0=v0,
                              outputs=[shaft.dof("out.1"), shaft.dof("main.1")])
    assert a.dof_names == ("out.1", "main.1")
    for q in "xva":
        _close(getattr(a, q), getattr(b, q), q)
    ag = 50.0 * np.sin(30 * np.arange(801) * 1e-3)
    a = dd.nonlinear_shaft_response(shaft, None, 1e-3, elements=elements, ground_acceleration=ag)
    b = NL.nonlinear_mck_response(M, C, K, None, 1e-3, elements=elements, scheme="newmark",
                              ground_acceleration=ag, influence=rigid_rotation(shaft))
    for q in ("x", "v", "a", "a_abs"):
        _close(getattr(a, q), getattr(b, q), q)
    beam, elements, f, dofs = beam_case
    M, C, K = (A.toarray() for A in dd.beam_matrices(beam))
    v0 = np.zeros(beam.n_dof)
    v0[beam.dof("w20")] = 0.05
    a = dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, elements=elements, v0=v0,
                                   outputs=["w10", "psi20"])
    b = NL.nonlinear_mck_response(M, C, K, f, 1e-4, force_dofs=[beam.dof(d) for d in dofs],
                              elements=elements, scheme="newmark", v0=v0,
                              outputs=[beam.dof("w10"), beam.dof("psi20")])
    assert a.dof_names == ("w10", "psi20")
    for q in "xv":
        _close(getattr(a, q), getattr(b, q), q)
    _close(a.a[:, 0], b.a[:, 0], "a (w10)")


def test_bad_element_dofs_are_named(shaft_case, beam_case):
    shaft, _, f, dofs = shaft_case
    with pytest.raises(ValueError, match=r"elements\[1\] \(Cubic\)\.j = 6 is outside the "
                                         r"shaft's DOFs 0\.\.5"):
        dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=dofs,
                                    elements=[dd.Cubic(0, k3=1.0), dd.Cubic(1, 6, k3=1.0)])
    with pytest.raises(ValueError, match=r"'main\.9' is not a DOF of this shaft"):
        shaft.dof("main.9")
    beam, _, f, dofs = beam_case
    with pytest.raises(ValueError, match=r"elements\[0\] \(Gap\)\.i = 40 is outside the beam's "
                                         r"DOFs 0\.\.39 .*beam\.dof_names"):
        dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs,
                                   elements=[dd.Gap(40, gap=0.0, stiffness=1.0)])
    with pytest.raises(ValueError, match="elements is empty"):
        dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, elements=[])
    with pytest.raises(ValueError, match="multistep"):
        dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, scheme="houbolt",
                                   elements=[dd.Cubic(0, k3=1.0)])


# the C loop needs a C compiler (CC, else cc), as the kernels do
needs_c = pytest.mark.skipif(shutil.which(os.environ.get("CC", "cc")) is None,
                             reason="no C compiler on this machine")


def _python_loop(monkeypatch):
    """Run the next calls in Python around the same step kernels (no compiled whole loop)."""
    monkeypatch.setattr(stations, "_c_driver", lambda *a: None)


@needs_c
@pytest.mark.parametrize("model", ["shaft", "beam"])
def test_c_loop_equals_the_python_loop(shaft_case, beam_case, monkeypatch, model):
    """The whole loop in C (generated/nl_stations.c) computes what the Python loop around the
    same step kernel (beam_response's block chain, shaft_response's tree sweep) computes, in
    the same order: bit for bit, two substeps, every quantity stored. Truth for both:
    test_*_equals_assembled."""
    if model == "shaft":
        shaft, elements, f, dofs = shaft_case
        run = lambda: dd.nonlinear_shaft_response(  # noqa: E731
            shaft, f, 1e-3, force_dofs=dofs, elements=elements, substeps=2, scheme="hht",
            alpha=-0.1, quantities=("x", "v", "a", "g"))
    else:
        beam, elements, f, dofs = beam_case
        run = lambda: dd.nonlinear_beam_response(  # noqa: E731
            beam, f, 1e-4, force_dofs=dofs, elements=elements, substeps=2, form="acceleration",
            quantities=("x", "v", "a", "g"))
    c = run()
    _python_loop(monkeypatch)
    py = run()
    assert (c.info["loop"], py.info["loop"]) == ("c", "python")
    assert c.info["newton_iterations"]["max"] >= 1
    for q in "xvag":
        np.testing.assert_array_equal(getattr(c, q), getattr(py, q), err_msg=q)
    assert c.info["newton_iterations"] == py.info["newton_iterations"]
    assert c.info["max_residual"] == py.info["max_residual"]


@needs_c
def test_c_loop_with_internal_states(shaft_case, monkeypatch):
    """An element that needs y' and has an internal state (BoucWen) beside the cubics: 6
    unknowns, whose Newton step LAPACK (Python loop) and newton.h's LU (C loop) solve with
    their own rounding, so the loops agree to rounding (1e-12 of each quantity's peak;
    measured ~1e-15) rather than bit for bit."""
    shaft, elements, f, dofs = shaft_case
    els = [*elements, dd.BoucWen(shaft.dof("out.0"), stiffness=3e3, alpha=0.1, beta=50.0,
                                 gamma=50.0)]

    def run():
        return dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=dofs, elements=els,
                                           substeps=2, quantities=("x", "v", "a", "g", "z"))
    c = run()
    _python_loop(monkeypatch)
    py = run()
    assert (c.info["loop"], py.info["loop"]) == ("c", "python") and np.abs(c.z).max() > 0
    for q in "xvagz":
        _close(getattr(c, q), getattr(py, q), q, rtol=1e-12)


@needs_c
def test_c_loop_names_the_step_where_newton_fails(beam_case, monkeypatch):
    """No Newton iteration allowed (max_iter=0): the C loop's failure is the
    Python loop's NewtonError, naming the same step."""
    beam, elements, f, dofs = beam_case
    messages = []
    for python in (False, True):
        if python:
            _python_loop(monkeypatch)
        with pytest.raises(NL.NewtonError, match=r"at step \d+ \(sample \d+") as info:
            dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=dofs, elements=elements,
                                       max_iter=0)
        messages.append(str(info.value))
    assert messages[0] == messages[1]
