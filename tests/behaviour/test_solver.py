"""Models that solve many times: ``Matrices(M, C, K).solver(dt, ...).run(force, ...)`` and
``Chain(...).solver(dt, ...).run(...)`` against the functions `mck_response` and
`chain_response`, which are one solver and one run: equal bitwise (same factorization, same
loop, same order of operations), however many load cases a solver has run before and from
however many threads at once."""
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import scipy.sparse as sps

import dtdyn as dd

N = 12
RNG = np.random.default_rng(7)
MASS, STIFF, DAMP = RNG.uniform(1, 2, N), RNG.uniform(1e3, 2e3, N), RNG.uniform(0.1, 1, N)
KG, CG = RNG.uniform(0, 50, N), RNG.uniform(0, 0.2, N)
FIELDS = ("x", "v", "a", "a_abs", "x_abs")


def cases(n_cases=3, n_steps=400):
    """Load cases: forces on two DOFs, initial states, ground records of each kind."""
    rng = np.random.default_rng(11)
    t = np.arange(n_steps + 1) * 1e-3
    out = []
    for i in range(n_cases):
        force = rng.standard_normal((n_steps + 1, 2))
        x0, v0 = rng.uniform(-1e-3, 1e-3, N), rng.uniform(-1e-2, 1e-2, N)
        ground = [dict(ground_acceleration=np.sin((5 + i) * t)),
                  dict(ground_velocity=0.01 * np.sin((7 + i) * t)),
                  dict(ground_displacement=1e-3 * (1 - np.cos((3 + i) * t)),
                       influence=np.linspace(0, 1, N))][i % 3]
        out.append(dict(force=force, force_dofs=[2, 9], x0=x0, v0=v0, **ground))
    out.append(dict(force=rng.standard_normal(n_steps + 1), force_dofs=[N - 1]))  # at rest
    return out


def assert_same(a, b, what):
    for q in FIELDS:
        A, B = getattr(a, q), getattr(b, q)
        assert (A is None) == (B is None), (what, q)
        if A is not None:
            assert A.tobytes() == B.tobytes(), (what, q, np.abs(A - B).max())  # bitwise
    info = {k: v for k, v in a.info.items() if k != "run_time"}
    assert info == {k: v for k, v in b.info.items() if k != "run_time"}, what


MCK_SCHEMES = [("newmark", {}), ("hht", {"alpha": -0.1}), ("wilson", {"theta": 1.42}),
               ("houbolt", {}), ("generalized_alpha", {"rho_inf": 0.6}),
               ("central_difference", {})]


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("scheme, params", MCK_SCHEMES)
def test_matrices_solver_equals_mck_response_bitwise(scheme, params, sparse, backend):
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP, sparse=sparse, ground_stiffness=KG,
                                ground_damping=CG)
    opts = dict(scheme=scheme, backend=backend, outputs=[0, 5, N - 1], **params)
    solver = dd.Matrices(M, C, K).solver(1e-3, **opts)
    for case in cases():                           # one solver, every load case in turn
        force = case.pop("force")
        assert_same(solver.run(force, **case), dd.mck_response(M, C, K, force, 1e-3, **opts,
                                                               **case), (scheme, case.keys()))


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("form, sweep", [("displacement", "stable"), ("acceleration", "stable"),
                                         ("displacement", "plain")])
@pytest.mark.parametrize("scheme, params", MCK_SCHEMES[:5])
def test_chain_solver_equals_chain_response_bitwise(scheme, params, form, sweep, backend):
    model = dict(ground_stiffness=KG, ground_damping=CG)
    opts = dict(scheme=scheme, form=form, sweep=sweep, backend=backend, outputs=[1, N - 1],
                **params)
    solver = dd.Chain(MASS, STIFF, DAMP, **model).solver(1e-3, **opts)
    for case in cases():
        force = case.pop("force")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", dd.DtdynAccuracyWarning)
            ref = dd.chain_response(MASS, STIFF, DAMP, force, 1e-3, **model, **opts, **case)
            assert_same(solver.run(force, **case), ref, (scheme, form, sweep))


def test_explicit_chain_in_the_acceleration_form():
    opts = dict(scheme="central_difference", form="acceleration", outputs=[0])
    solver = dd.Chain(MASS, STIFF, DAMP).solver(1e-4, **opts)
    for case in cases():
        force = case.pop("force")
        assert_same(solver.run(force, **case),
                    dd.chain_response(MASS, STIFF, DAMP, force, 1e-4, **opts, **case), "cd")


@pytest.mark.parametrize("make", ["matrices", "chain"])
def test_runs_on_several_threads_equal_the_runs_in_turn(make):
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP, sparse=True)
    model = dd.Matrices(M, C, K) if make == "matrices" else dd.Chain(MASS, STIFF, DAMP)
    solver = model.solver(1e-3, scheme="hht", alpha=-0.05)
    loads = cases(8, 3000)

    def run(case):
        case = dict(case)
        return solver.run(case.pop("force"), **case)

    in_turn = [run(c) for c in loads]
    with ThreadPoolExecutor(4) as pool:
        at_once = list(pool.map(run, loads))
    for a, b in zip(in_turn, at_once):
        assert_same(a, b, "threads")


def test_displacement_form_of_matrices_equals_the_acceleration_form_to_rounding():
    """Both forms solve the same scheme equations: they differ by the rounding of the solves,
    eps times the effective matrix's condition number (~1e4 here) over the steps."""
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP, sparse=False)
    model = dd.Matrices(M, C, K)
    case = cases()[0]
    force = case.pop("force")
    a = model.solver(1e-3, scheme="hht", alpha=-0.1).run(force, **case)
    d = model.solver(1e-3, scheme="hht", alpha=-0.1, form="displacement").run(force, **case)
    assert d.info["form"] == "displacement"
    for q in "xva":
        ref = getattr(a, q)
        assert np.abs(getattr(d, q) - ref).max() <= 1e-9 * np.abs(ref).max(), q
    with pytest.raises(ValueError, match="explicit .* no displacement form"):
        model.solver(1e-4, scheme="central_difference", form="displacement")


def test_solver_equals_the_exact_response_to_the_schemes_error():
    """Against the matrix exponential (force linear between samples): average acceleration's
    phase error, (omega dt)^2 / 12 per radian, is below 1e-5 of the peak at omega dt < 0.01."""
    M, C, K = dd.chain_matrices([2.0, 3.0], [20.0, 15.0], [5.0, 6.0])
    dt = 1e-3
    force = np.sin(np.arange(5001) * dt * 3.0)
    r = dd.Matrices(M, C, K).solver(dt, scheme="average_acceleration").run(force,
                                                                          force_dofs=[1])
    ref = dd.exact_response(M, C, K, force, dt, force_dofs=[1])
    assert np.abs(r.x - ref.x).max() <= 1e-5 * np.abs(ref.x).max()


def test_the_solver_checks_once_and_names_what_is_wrong():
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP)
    model = dd.Matrices(M, C, K)
    with pytest.raises(dd.DtdynUnstableError, match="central_difference.* unstable at dt"):
        model.solver(0.5, scheme="central_difference")    # before any force is given
    with pytest.raises(ValueError, match="backend must be 'c' or 'numpy', got 'fortran'"):
        model.solver(1e-3, backend="fortran")
    with pytest.raises(ValueError, match=r"outputs = \[12\] has an index outside 0..11"):
        model.solver(1e-3, outputs=[12])
    with pytest.raises(TypeError, match="'outptus'; did you mean 'outputs'"):
        model.solver(1e-3, outptus=[0])
    with pytest.raises(TypeError, match=r"scheme 'newmark' takes parameters \(beta, gamma\)"):
        model.solver(1e-3, alpha=-0.1)
    solver = model.solver(1e-3)
    with pytest.raises(TypeError, match="'forc_dofs'; did you mean 'force_dofs'"):
        solver.run(np.ones(11), forc_dofs=[0])
    with pytest.raises(ValueError, match="force has shape"):
        solver.run(np.ones((11, 3)), force_dofs=[0, 1])
    with pytest.raises(ValueError, match="x0 has length 3, expected 12"):
        solver.run(np.ones(11), force_dofs=[0], x0=np.zeros(3))
    with pytest.raises(ValueError, match="sweep must be 'stable' or 'plain'"):
        dd.Chain(MASS, STIFF, DAMP).solver(1e-3, sweep="fast")
    with pytest.raises(ValueError, match=r"damping\[3\] = 0 with the explicit scheme"):
        dd.Chain(MASS, STIFF, np.where(np.arange(N) == 3, 0.0, DAMP)).solver(
            1e-4, scheme="central_difference", form="acceleration")
    with pytest.raises(ValueError, match="station 0 has stiffness = damping = 0"):
        dd.Chain([1.0], [0.0], [0.0])


def test_a_chain_is_checked_and_kept():
    mass = MASS.copy()
    chain = dd.Chain(mass, STIFF, DAMP, ground_damping=CG)
    mass[0] = 100.0                                        # the model keeps its own copy
    assert chain.mass[0] == MASS[0] and chain.n_dof == N
    with pytest.raises(ValueError, match="read-only"):
        chain.mass[0] = 1.0
    m, k, c, kg, cg = chain
    assert np.array_equal(c, DAMP) and not kg.any() and np.array_equal(cg, CG)
    M, C, K = chain.matrices(sparse=True)
    assert sps.issparse(K)
    ref = dd.chain_matrices(MASS, STIFF, DAMP, sparse=False, ground_damping=CG)
    for a, b in zip((M, C, K), ref):
        assert np.array_equal(a.toarray(), b)
