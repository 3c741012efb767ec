"""Nonlinear solvers of a beam and a chain against their functions: 200 load cases of 200 steps
on a 200-element beam (and a 200-mass chain) with one cubic spring, `model.solver(dt,
elements=...).run` against `nonlinear_beam_response` (`nonlinear_chain_response`), interleaved
call by call, each pair checked equal. Sums of perf_counter times over the cases; the machine is
shared, so read the ratio, not the milliseconds.

Usage: python benchmarks/nonlinear_station_solver_reuse.py   (about 10 s)
"""
import time
import numpy as np
import dtdyn as dd

beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=200)
tip = beam.dof("w200")
els = [dd.Cubic(tip, k3=1e12)]
rng = np.random.default_rng(1)
cases = [(100.0 * rng.standard_normal((201, 1))) for _ in range(200)]
for backend in ("c", "numpy"):
    n_cases = len(cases) if backend == "c" else 20
    solver = beam.solver(1e-4, elements=els, outputs=[tip], backend=backend)
    solver.run(cases[0], force_dofs=[tip])  # warm-up: compile, plan of force_dofs
    dd.nonlinear_beam_response(beam, cases[0], 1e-4, elements=els, force_dofs=[tip],
                               outputs=[tip], backend=backend)
    t_fun = t_run = 0.0
    for f in cases[:n_cases]:
        a = time.perf_counter()
        r1 = dd.nonlinear_beam_response(beam, f, 1e-4, elements=els, force_dofs=[tip],
                                        outputs=[tip], backend=backend)
        b = time.perf_counter()
        r2 = solver.run(f, force_dofs=[tip])
        c = time.perf_counter()
        assert np.array_equal(r1.x, r2.x)
        t_fun += b - a
        t_run += c - b
    print(f"backend {backend}: {n_cases} cases x 200 steps, 200-element beam, 1 Cubic: "
          f"function {t_fun / n_cases * 1e3:.3f} ms/case, solver.run {t_run / n_cases * 1e3:.3f}"
          f" ms/case, ratio function/run = {t_fun / t_run:.2f}")

# the chain: 200 masses, one cubic spring, 200 cases x 200 steps
n = 200
chain = dd.Chain(np.ones(n), np.full(n, 1e4), np.full(n, 0.5))
cels = [dd.Cubic(0, k3=1e7)]
solver = chain.solver(1e-3, elements=cels, outputs=[n - 1])
kw = dict(elements=cels, force_dofs=[n - 1], outputs=[n - 1])
solver.run(cases[0], force_dofs=[n - 1])
dd.nonlinear_chain_response(chain.mass, chain.stiffness, chain.damping, cases[0], 1e-3, **kw)
t_fun = t_run = 0.0
for f in cases:
    a = time.perf_counter()
    r1 = dd.nonlinear_chain_response(chain.mass, chain.stiffness, chain.damping, f, 1e-3, **kw)
    b = time.perf_counter()
    r2 = solver.run(f, force_dofs=[n - 1])
    c = time.perf_counter()
    assert np.array_equal(r1.x, r2.x)
    t_fun += b - a
    t_run += c - b
print(f"chain c: 200 cases x 200 steps, 200 masses, 1 Cubic: function "
      f"{t_fun / 200 * 1e3:.3f} ms/case, solver.run {t_run / 200 * 1e3:.3f} ms/case, "
      f"ratio function/run = {t_fun / t_run:.2f}")
