"""Beams and shafts that solve many times: ``Beam.solver(dt, ...).run(force, ...)`` and
``Shaft.solver(dt, ...).run(...)`` against `beam_response` and `shaft_response`, which are one
solver and one run: equal bitwise (same factorization, same kernel, same order of operations),
however many load cases a solver has run before and from however many threads at once. The
runs are also held against `mck_response` on the assembled matrices (an independent path: the
sparse LU of the effective matrix instead of the sweeps) to the rounding of the solves."""
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.linear import _beam, _shaft

FIELDS = ("x", "v", "a", "a_abs", "x_abs")
SCHEMES = [("newmark", {}), ("hht", {"alpha": -0.1}), ("wilson", {"theta": 1.42}),
           ("houbolt", {}), ("generalized_alpha", {"rho_inf": 0.6})]


def beam():
    return dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=12, right=(2e5, 0.0),
                   rayleigh=(0.5, 1e-5), point_masses=[dd.PointMass(6, mass=2.0, inertia=0.01)],
                   supports=[dd.Support(4, k_w=1e5, c_w=10.0)])


def shaft():
    seg = dd.ContinuousShaft(length=0.5, G=8e10, Jp=1e-7, rho=7800.0, elements=4, damping=0.5)
    out = dd.Branch(1, [0.5, 0.4], [6e3, 5e3], [1.0, 1.0], ratio=2.0, name="out")
    tail = dd.Branch(2, [0.2], [seg], [0.0], name="tail")
    return dd.Shaft([1.0, 0.3, 0.9, 0.5], [1e4, 1.2e4, 9e3, 8e3], [1.0, 2.0, 1.0, 1.0],
                    ground_damping=[0.1, 0.0, 0.0, 0.2], branches=[out, tail])


def cases(model, n_cases=3, n_steps=300, dt=1e-4):
    """Load cases on ``model``: forces on two DOFs (by name and by index), initial states,
    ground records of each kind (an influence of its own on the last), and a case from rest."""
    rng = np.random.default_rng(11)
    n = len(model.dof_names)
    t = np.arange(n_steps + 1) * dt
    loaded = [model.dof_names[n // 3], n - 1]
    out = []
    for i in range(n_cases):
        x0, v0 = rng.uniform(-1e-5, 1e-5, n), rng.uniform(-1e-3, 1e-3, n)
        ground = [dict(ground_acceleration=np.sin((500 + 30 * i) * t)),
                  dict(ground_velocity=0.01 * np.sin((700 + i) * t)),
                  dict(ground_displacement=1e-5 * (1 - np.cos((300 + i) * t)),
                       influence=np.linspace(0, 1, n))][i % 3]
        out.append(dict(force=rng.standard_normal((n_steps + 1, 2)), force_dofs=loaded, x0=x0,
                        v0=v0, **ground))
    out.append(dict(force=rng.standard_normal(n_steps + 1), force_dofs=[n - 2]))  # at rest
    return out


def assert_same(a, b, what):
    for q in FIELDS:
        A, B = getattr(a, q), getattr(b, q)
        assert (A is None) == (B is None), (what, q)
        if A is not None:
            assert A.tobytes() == B.tobytes(), (what, q, np.abs(A - B).max())  # bitwise
    assert np.array_equal(a.outputs, b.outputs) and a.dof_names == b.dof_names, what
    assert a.dof_kinds == b.dof_kinds, what
    info = {k: v for k, v in a.info.items() if k != "run_time"}
    assert info == {k: v for k, v in b.info.items() if k != "run_time"}, what


MODELS = {"beam": (beam, dd.beam_response), "shaft": (shaft, dd.shaft_response)}


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
@pytest.mark.parametrize("scheme, params", SCHEMES)
@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_solver_equals_the_response_function_bitwise(kind, scheme, params, form, backend):
    make, response = MODELS[kind]
    model = make()
    outputs = [model.dof_names[0], len(model.dof_names) - 1]
    opts = dict(scheme=scheme, form=form, backend=backend, outputs=outputs, **params)
    solver = model.solver(1e-4, **opts)
    assert solver.model is model and solver.scheme == scheme and solver.form == form
    for case in cases(model):                      # one solver, every load case in turn
        force = case.pop("force")
        assert_same(solver.run(force, **case), response(model, force, 1e-4, **opts, **case),
                    (kind, scheme, form, sorted(case)))


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_explicit_scheme_in_the_acceleration_form(kind):
    make, response = MODELS[kind]
    model = make()
    dt = 2e-7 if kind == "beam" else 1e-5
    opts = dict(scheme="central_difference", form="acceleration", quantities=("x", "a"))
    solver = model.solver(dt, **opts)
    for case in cases(model, n_steps=200, dt=dt):
        force = case.pop("force")
        assert_same(solver.run(force, **case), response(model, force, dt, **opts, **case), kind)
    with pytest.raises(ValueError, match="explicit .* no displacement form"):
        model.solver(dt, scheme="central_difference", form="displacement")  # before any run


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_solver_equals_mck_response_on_the_assembled_matrices(kind):
    """An independent path: the sparse LU of M + Dv C + Dx K on `beam_matrices` or
    `shaft_matrices`. Both solve the same scheme equations; they differ by the rounding of the
    solves, eps times the effective matrix's condition number (< 1e8 here) over 300 steps."""
    make, _ = MODELS[kind]
    model = make()
    M, C, K = (dd.beam_matrices if kind == "beam" else dd.shaft_matrices)(model)
    solver = model.solver(1e-4, scheme="hht", alpha=-0.1)
    for case in cases(model):
        force = case.pop("force")
        if "influence" not in case and any(k.startswith("ground") for k in case):
            case["influence"] = (_beam.rigid_translation(model)[:, 0] if kind == "beam"
                                 else _shaft.rigid_rotation(model))
        case["force_dofs"] = [model.dof(d) if isinstance(d, str) else d
                              for d in case["force_dofs"]]
        got = solver.run(force, **case)
        ref = dd.mck_response(M, C, K, force, 1e-4, scheme="hht", alpha=-0.1, **case)
        for q in ("x", "v", "a", "a_abs"):
            r = getattr(ref, q)
            if r is not None:
                assert np.abs(getattr(got, q) - r).max() <= 1e-6 * np.abs(r).max(), (kind, q)


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_runs_on_several_threads_equal_the_runs_in_turn(kind):
    make, _ = MODELS[kind]
    model = make()
    solver = model.solver(1e-4, scheme="houbolt", outputs=[0, 3, 7])
    loads = cases(model, 8, 2000)

    def run(case):
        case = dict(case)
        return solver.run(case.pop("force"), **case)

    in_turn = [run(c) for c in loads]
    with ThreadPoolExecutor(4) as pool:
        at_once = list(pool.map(run, loads))
    for a, b in zip(in_turn, at_once):
        assert_same(a, b, "threads")


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_the_solver_checks_once_and_names_what_is_wrong(kind):
    make, _ = MODELS[kind]
    model = make()
    with pytest.raises(dd.DtdynUnstableError, match="central_difference.* unstable at dt"):
        model.solver(0.5, scheme="central_difference", form="acceleration")
    with pytest.raises(ValueError, match="backend must be 'c' or 'numpy', got 'fortran'"):
        model.solver(1e-4, backend="fortran")
    with pytest.raises(ValueError, match="form must be 'displacement' or 'acceleration'"):
        model.solver(1e-4, form="velocity")
    with pytest.raises(ValueError, match="outputs: no DOF named 'nope'"):
        model.solver(1e-4, outputs=["nope"])
    with pytest.raises(TypeError, match="'outptus'; did you mean 'outputs'"):
        model.solver(1e-4, outptus=[0])
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
        model.solver(-1.0)
    solver = model.solver(1e-4, quantities=("x",))
    with pytest.raises(ValueError, match="force_dofs: no DOF named 'nope'"):
        solver.run(np.ones(5), force_dofs=["nope"])
    r = solver.run(np.ones(5), force_dofs=[0])
    assert r.v is None and r.x.shape == (5, len(model.dof_names))
    assert repr(solver).startswith(f"<{type(solver).__name__} of ")


def test_shaft_explicit_scheme_needs_a_damper_on_every_shaft():
    s = dd.Shaft([1.0, 2.0], [1e4, 2e4])
    with pytest.raises(ValueError, match="damping 0 with the explicit scheme"):
        s.solver(1e-4, scheme="central_difference", form="acceleration")


def test_a_warning_of_the_run_is_the_functions():
    """`unstable="warn"` warns once when the solver is made, as the function does."""
    model = shaft()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.solver(1e-2, scheme="central_difference", form="acceleration", unstable="warn")
    assert [w.category for w in caught] == [dd.DtdynStabilityWarning]
