"""A model with nonlinear elements that solves many times:
``Matrices(M, C, K).solver(dt, elements=[...], ...).run(force, ...)`` against
`nonlinear_mck_response`, which is one such solver and one run: equal bitwise (same linear
step, same C loop or CasADi graph, same order of operations), however many load cases the
solver has run before, with which loaded DOFs, and from however many threads at once. The
function's own accuracy is tested against solve_ivp in test_nonlinear.py; one run here is
checked against that reference too (`reference_response`, DOP853 at rtol 1e-12)."""
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.nonlinear._reference import reference_response

N_SAMPLES = 600
P4 = dd.problem("P4", n_samples=N_SAMPLES)
M, C, K, DT, ELEMENTS = P4["M"], P4["C"], P4["K"], P4["dt"], P4["elements"]
RNG = np.random.default_rng(3)
FIELDS = ("x", "v", "a", "g", "z", "a_abs", "x_abs")


def assert_same(a, b, what):
    for q in FIELDS:
        A, B = getattr(a, q, None), getattr(b, q, None)
        assert (A is None) == (B is None), (what, q)
        if A is not None:
            assert A.tobytes() == B.tobytes(), (what, q, np.abs(A - B).max())  # bitwise
    times = ("setup_time", "construct_time", "compile_time", "run_time")
    assert ({k: v for k, v in a.info.items() if k not in times}
            == {k: v for k, v in b.info.items() if k not in times}), what


def load_cases():
    """A force on DOF 3 from rest, a force on two DOFs from (x0, v0), a ground record alone,
    a ground record with a force."""
    t = np.arange(N_SAMPLES) * DT
    return [dict(force=P4["force"], force_dofs=[3]),
            dict(force=50 * RNG.standard_normal((N_SAMPLES, 2)), force_dofs=[1, 3],
                 x0=RNG.uniform(-5e-3, 5e-3, 4), v0=RNG.uniform(-0.1, 0.1, 4)),
            dict(force=None, ground_acceleration=30 * np.sin(2 * np.pi * 12 * t)),
            dict(force=P4["force"][:, 0], force_dofs=[3],
                 ground_velocity=0.2 * np.sin(2 * np.pi * 7 * t), influence=[1, 1, 0.5, 0])]


OPTIONS = [dict(scheme="modal_ramp"),
           dict(scheme="modal_parabolic", substeps=2),
           dict(scheme="modal_quintic", outputs=[0, 3], quantities=("x", "a", "g")),
           dict(scheme="modal_quintic", estimate=False, modes=[0, 1, 2]),
           dict(scheme="modal_explicit", substeps=3),
           dict(scheme="newmark", substeps=2),
           dict(scheme="hht", alpha=-0.1, quantities=("v",)),
           dict(scheme="modal_ramp", backend="casadi"),
           dict(scheme="newmark", backend="casadi", substeps=2, solver="fast_newton")]


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: "-".join(map(str, o.values())))
def test_solver_runs_equal_nonlinear_mck_response_bitwise(options):
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, **options)
    for i, case in enumerate(load_cases()):
        case = dict(case)
        force = case.pop("force")
        ref = dd.nonlinear_mck_response(M, C, K, force, DT, elements=ELEMENTS, **options, **case)
        assert_same(solver.run(force, **case), ref, (options, i))


def test_many_runs_on_one_solver_equal_fresh_calls():
    """Runs in any order, loaded DOFs changing from run to run, give each the fresh call's
    result (nothing of one run leaks into the next: state, history, forces before t_0)."""
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, scheme="modal_quintic")
    cases = load_cases()
    refs = []
    for case in cases:
        case = dict(case)
        force = case.pop("force")
        refs.append(dd.nonlinear_mck_response(M, C, K, force, DT, elements=ELEMENTS,
                                              scheme="modal_quintic", **case))
    for i in [0, 1, 0, 2, 3, 1, 1, 0, 3, 2]:
        case = dict(cases[i])
        assert_same(solver.run(case.pop("force"), **case), refs[i], i)


def test_runs_from_threads_equal_sequential_runs():
    """One solver, eight load cases on four threads at once: each equals its sequential run."""
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, scheme="modal_parabolic",
                                         substeps=2)
    forces = [100 * RNG.standard_normal(4 * N_SAMPLES) for _ in range(8)]
    x0s = [RNG.uniform(-1e-3, 1e-3, 4) for _ in range(8)]
    with ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(lambda fx: solver.run(fx[0], force_dofs=[3], x0=fx[1]),
                                 zip(forces, x0s)))
    for f, x0, r in zip(forces, x0s, parallel):
        assert_same(r, solver.run(f, force_dofs=[3], x0=x0), "thread")


def test_solver_run_against_ode_reference():
    """An independent truth: DOP853 at rtol 1e-12 on the first 300 samples; modal_quintic with
    2 sub-steps is sixth order, its error on P4 ~1e-9 of the peak (test_nonlinear.py)."""
    n = 300
    ref = reference_response(M, C, K, P4["force"][:n], DT, force_dofs=[3], elements=ELEMENTS,
                             cache=False)
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, scheme="modal_quintic",
                                         substeps=2)
    r = solver.run(P4["force"][:n], force_dofs=[3])
    np.testing.assert_allclose(r.x, ref.x, rtol=0, atol=1e-7 * np.abs(ref.x).max())


def test_solver_attributes_and_rest_of_protocol():
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS[0], scheme="hht", alpha=-0.2,
                                         substeps=2, outputs=[3])
    assert (solver.dt, solver.scheme, solver.params, solver.substeps) == (DT, "hht",
                                                                          {"alpha": -0.2}, 2)
    assert solver.outputs.tolist() == [3] and solver.elements == (ELEMENTS[0],)
    assert "hht" in repr(solver) and solver.setup_time > 0
    r = solver.run(P4["force"], force_dofs=[3])
    assert r.x.shape == (N_SAMPLES, 1) and r.info["scheme"] == "hht"


@pytest.mark.parametrize("options, match", [
    (dict(accuracy=1e-6), "accuracy=1e-06: an accuracy target .* not of a solver"),
    (dict(estimate=True), "estimate=True .* not of a solver"),
    (dict(scheme="auto"), "scheme 'auto' .* not of a solver"),
    (dict(form="displacement"), "form='displacement' is an option of the linear solvers"),
    (dict(unstable="warn"), "unstable='warn' is an option of the linear solvers"),
    (dict(backend="numpy"), "backend must be 'c' or 'casadi', got 'numpy'"),
    (dict(substeps=0), "substeps"),
    (dict(scheme="modal_ramp", alpha=0.1), "takes no scheme parameters, got alpha"),
    (dict(quantities=("x", "z")), "no element has internal states"),
])
def test_bad_solver_options_are_named(options, match):
    with pytest.raises(ValueError, match=match):
        dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, **options)


def test_bad_elements_and_keywords_are_named():
    with pytest.raises(ValueError, match="elements is empty"):
        dd.Matrices(M, C, K).solver(DT, elements=[])
    with pytest.raises(ValueError, match=r"elements\[0\] .*outside the model's DOFs 0..3"):
        dd.Matrices(M, C, K).solver(DT, elements=[dd.Cubic(7, k3=1.0)])
    with pytest.raises(TypeError, match="'substep'; did you mean 'substeps'"):
        dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS, substep=2)
    # the nonlinear options without elements: the linear solver refuses them by name
    with pytest.raises(ValueError, match="substeps=2 is an option of the solvers with elements"):
        dd.Matrices(M, C, K).solver(DT, substeps=2)


def test_bad_run_inputs_are_named():
    solver = dd.Matrices(M, C, K).solver(DT, elements=ELEMENTS)
    with pytest.raises(ValueError, match="force"):
        solver.run(np.ones((N_SAMPLES, 2)), force_dofs=[3])  # two columns, one loaded DOF
    with pytest.raises(ValueError, match="force_dofs"):
        solver.run(np.ones(N_SAMPLES), force_dofs=[4])
    with pytest.raises(ValueError, match="x0"):
        solver.run(np.ones(N_SAMPLES), force_dofs=[3], x0=np.zeros(3))
    with pytest.raises(TypeError, match="'ground_acceleraton'"):
        solver.run(None, ground_acceleraton=np.ones(N_SAMPLES))
    # the solver still runs after refused inputs
    assert_same(solver.run(P4["force"], force_dofs=[3]),
                dd.nonlinear_mck_response(M, C, K, P4["force"], DT, elements=ELEMENTS,
                                          force_dofs=[3]), "after errors")


# --- chains, beams, shafts: prepared solvers, each run bitwise the model's function ------------
# Chain.solver, Beam.solver and Shaft.solver reach it through the registry with elements=...;
# here through the registry itself (dtdyn.linear._solver.nonlinear_solver)

def station_models():
    rng = np.random.default_rng(5)
    chain = dd.Chain(np.ones(6), np.full(6, 1e4), np.full(6, 0.5), ground_stiffness=np.ones(6))
    shaft = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=20)
    return [
        (chain, lambda f, **kw: dd.nonlinear_chain_response(
            chain.mass, chain.stiffness, chain.damping, f, 1e-3, ground_stiffness=np.ones(6),
            **kw), [dd.Cubic(2, 3, k3=1e8)], [5], 1e-3, 30 * rng.standard_normal(301)),
        (shaft, lambda f, **kw: dd.nonlinear_shaft_response(shaft, f, 1e-3, **kw),
         [dd.Cubic(shaft.dof("main.1"), k3=1e9)], ["main.2"], 1e-3, np.full(201, 50.0)),
        (beam, lambda f, **kw: dd.nonlinear_beam_response(beam, f, 1e-4, **kw),
         [dd.Gap(beam.dof("w20"), gap=1e-4, stiffness=1e7)], ["w20"], 1e-4, np.full(201, 100.0))]


@pytest.mark.parametrize("index", [0, 1, 2], ids=["chain", "shaft", "beam"])
def test_chain_beam_shaft_solvers_equal_their_functions_bitwise(index):
    from dtdyn.linear._solver import nonlinear_solver
    model, call, elements, load, dt, force = station_models()[index]
    solver = nonlinear_solver(model, dt, elements, scheme="hht", alpha=-0.05, substeps=2)
    for f in (force, 0.5 * force, force):
        ref = call(f, elements=elements, force_dofs=load, scheme="hht", alpha=-0.05, substeps=2)
        assert_same(solver.run(f, force_dofs=load), ref, type(model).__name__)
    with pytest.raises(ValueError, match="elements is empty"):
        nonlinear_solver(model, dt, [])
    with pytest.raises(ValueError, match="unstable='warn' is an option of the linear solvers"):
        nonlinear_solver(model, dt, elements, unstable="warn")
    with pytest.raises(ValueError, match="x0 is an option of run"):
        nonlinear_solver(model, dt, elements, x0=np.zeros(model.n_dof))


def test_chain_beam_and_shaft_solvers_with_elements_equal_their_functions():
    """Chain, Beam and Shaft take elements= in solver(): each run is the model's nonlinear
    function's result, bitwise; a linear solver refuses the nonlinear options."""
    chain = dd.Chain([2.0, 3.0, 1.0], [20.0, 15.0, 10.0], [0.5, 0.6, 0.2])
    f = np.ones((501, 1))
    els = [dd.Cubic(2, k3=50.0)]
    a = chain.solver(0.02, elements=els, substeps=2).run(f, force_dofs=[2])
    b = dd.nonlinear_chain_response(chain.mass, chain.stiffness, chain.damping, f, 0.02,
                                    force_dofs=[2], elements=els, substeps=2)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.g, b.g)
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=10)
    tip = beam.dof("w10")
    fb = 100.0 * np.ones((201, 1))
    els = [dd.Cubic(tip, k3=1e9)]
    a = beam.solver(1e-4, elements=els, tol=1e-10).run(fb, force_dofs=[tip])
    b = dd.nonlinear_beam_response(beam, fb, 1e-4, force_dofs=[tip], elements=els, tol=1e-10)
    assert np.array_equal(a.x, b.x)
    shaft = dd.Shaft([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3], [0.5, 0.8, 0.3])
    els = [dd.Cubic(2, k3=1e6)]
    a = shaft.solver(1e-3, elements=els, max_iter=20).run(10.0 * f, force_dofs=[2])
    b = dd.nonlinear_shaft_response(shaft, 10.0 * f, 1e-3, force_dofs=[2], elements=els,
                                    max_iter=20)
    assert np.array_equal(a.x, b.x)
    with pytest.raises(ValueError, match="substeps=2 is an option of the solvers with elements"):
        chain.solver(0.02, substeps=2)


# Beams and shafts: the solver prepares once what nonlinear_beam_response /
# nonlinear_shaft_response build before their loop (checks, the step's factors, the compiled
# loop; per force_dofs the elements' unit responses); each run is the function's result bitwise.
STATION_BEAM = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=12,
                       rayleigh=(0.0, 2e-6))
STATION_SHAFT = dd.Shaft([1.0, 2.0, 1.5, 1.0], [1e4, 2e4, 2e4, 1.5e4], [1.0, 1.0, 1.0, 1.0],
                         branches=[dd.Branch(2, [0.5, 0.8], [5e3, 6e3], [0.5, 0.5], ratio=2.0,
                                             name="out")])


def station_cases(kind):
    """(model, function, dt, elements, load cases): a force from rest, a ground record alone, two
    forces from (x0, v0), and a Bouc-Wen element's force and states stored."""
    rng = np.random.default_rng(11)
    if kind == "beam":
        model, dt, t = STATION_BEAM, 1e-4, np.arange(201) * 1e-4
        f = (200.0 * np.sin(2 * np.pi * 15 * t))[:, None]
        els = [dd.Gap(model.dof("w12"), gap=2e-4, stiffness=2e6),
               dd.Cubic(model.dof("w6"), k3=1e12)]
        loads, scale = ["w12", "w6"], (1e-5, 1e-3)
        hysteretic = dd.BoucWen(model.dof("w12"), stiffness=2e6, beta=5e3, gamma=5e3)
        call = dd.nonlinear_beam_response
    else:
        model, dt, t = STATION_SHAFT, 1e-3, np.arange(201) * 1e-3
        f = (300.0 * np.sin(40 * t))[:, None]
        els = [dd.Cubic(model.dof("main.1"), k3=1e9),
               dd.Cubic(model.dof("main.3"), model.dof("out.1"), k3=5e8)]
        loads, scale = ["main.3", "out.1"], (1e-3, 0.1)
        hysteretic = dd.BoucWen(model.dof("main.1"), stiffness=1e4, beta=50.0, gamma=50.0)
        call = dd.nonlinear_shaft_response
    n = model.n_dof
    cases = [dict(force=f, force_dofs=loads[:1]),
             dict(force=None, ground_acceleration=20 * np.sin(2 * np.pi * 12 * t)),
             dict(force=np.column_stack([f[:, 0], 0.3 * f[:, 0]]), force_dofs=loads,
                  x0=rng.uniform(-scale[0], scale[0], n), v0=rng.uniform(-scale[1], scale[1], n))]
    return model, call, dt, els, hysteretic, cases


@pytest.mark.parametrize("kind", ["beam", "shaft"])
@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("substeps", [1, 2])
def test_beam_and_shaft_solver_runs_equal_their_functions_bitwise(kind, backend, substeps):
    model, call, dt, els, hysteretic, cases = station_cases(kind)
    options = [dict(backend=backend, substeps=substeps),
               dict(backend=backend, substeps=substeps, scheme="hht", alpha=-0.1,
                    form="acceleration", outputs=[0, 3], quantities=("x", "a", "g"))]
    for opts in options:
        solver = model.solver(dt, elements=els, **opts)
        for i, case in enumerate(cases):
            case = dict(case)
            force = case.pop("force")
            ref = call(model, force, dt, elements=els, **opts, **case)
            assert_same(solver.run(force, **case), ref, (kind, opts, i))
    solver = model.solver(dt, elements=[hysteretic], quantities=("x", "g", "z"),
                          backend=backend, substeps=substeps)
    case = dict(cases[0])
    force = case.pop("force")
    ref = call(model, force, dt, elements=[hysteretic], quantities=("x", "g", "z"),
               backend=backend, substeps=substeps, **case)
    assert ref.z is not None and np.abs(ref.z).max() > 0
    assert_same(solver.run(force, **case), ref, (kind, "BoucWen"))


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_many_beam_and_shaft_runs_on_one_solver_equal_fresh_calls(kind):
    """Runs in any order, the loaded DOFs changing from run to run (one plan each, kept), from
    rest or not, give each the fresh call's result; runs from threads too (C loop)."""
    model, call, dt, els, _, cases = station_cases(kind)
    refs = []
    for case in cases:
        case = dict(case)
        force = case.pop("force")
        refs.append(call(model, force, dt, elements=els, scheme="generalized_alpha",
                         rho_inf=0.8, **case))
    solver = model.solver(dt, elements=els, scheme="generalized_alpha", rho_inf=0.8)
    order = [0, 2, 1, 0, 2, 2, 1, 0]
    for i in order:
        case = dict(cases[i])
        assert_same(solver.run(case.pop("force"), **case), refs[i], (kind, i))

    def run(i):
        case = dict(cases[i])
        return solver.run(case.pop("force"), **case)
    with ThreadPoolExecutor(4) as pool:
        for i, res in zip(order, pool.map(run, order)):
            assert_same(res, refs[i], (kind, "thread", i))
    from dtdyn.linear._solver import nonlinear_solver
    with pytest.raises(ValueError, match="influence is an option of run"):
        nonlinear_solver(model, dt, els, influence=np.ones(model.n_dof))
    with pytest.raises(ValueError, match="elements is empty"):
        model.solver(dt, elements=[])


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("substeps", [1, 2])
def test_chain_solver_runs_equal_nonlinear_chain_response_bitwise(backend, substeps):
    """The chain's solver prepares once (checks, the compiled loop; per force_dofs the elements'
    unit responses); runs in any order equal fresh calls of nonlinear_chain_response."""
    rng = np.random.default_rng(12)
    n = 20
    m, k, c = rng.uniform(1, 2, n), rng.uniform(1e4, 2e4, n), rng.uniform(0.1, 0.5, n)
    kg = np.zeros(n)
    kg[5] = 3e3
    chain = dd.Chain(m, k, c, ground_stiffness=kg)
    t = np.arange(201) * 1e-3
    f = (30 * np.sin(40 * t))[:, None]
    cases = [dict(force=f, force_dofs=[n - 1]),
             dict(force=None, ground_acceleration=5 * np.sin(30 * t)),
             dict(force=np.column_stack([f[:, 0], 0.5 * f[:, 0]]), force_dofs=[3, 10],
                  x0=rng.uniform(-1e-3, 1e-3, n), v0=rng.uniform(-0.1, 0.1, n))]
    for els, opts in (([dd.Cubic(0, k3=1e9), dd.Cubic(10, 11, k3=5e8)],
                       dict(scheme="hht", alpha=-0.1, form="acceleration", outputs=[0, 4],
                            quantities=("x", "a", "g"))),
                      ([dd.BoucWen(0, stiffness=1e4, beta=50.0, gamma=50.0)],
                       dict(quantities=("x", "g", "z")))):
        opts = dict(opts, backend=backend, substeps=substeps)
        refs = []
        for case in cases:
            case = dict(case)
            force = case.pop("force")
            refs.append(dd.nonlinear_chain_response(m, k, c, force, 1e-3, elements=els,
                                                    ground_stiffness=kg, **opts, **case))
        solver = chain.solver(1e-3, elements=els, **opts)
        for i in [0, 1, 2, 0, 2, 1]:
            case = dict(cases[i])
            assert_same(solver.run(case.pop("force"), **case), refs[i], (opts, i))
