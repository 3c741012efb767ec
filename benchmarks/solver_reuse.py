"""Many load cases on one model: one solver's runs against as many mck_response (beam_response,
shaft_response) calls, same run.

A batch of load cases on one model (a load-case table, a Monte Carlo of forces) repeats, in
each `mck_response` call, everything that does not depend on the load: the checks of M, C, K,
the stability check, the sparse LU of the effective matrix and of M, the C loop's operands.
``dd.Matrices(M, C, K).solver(dt)`` does that once; each ``solver.run(force)`` then checks its
own inputs, allocates its outputs and runs the loop.

The model: a chain of 2,000 masses (random masses 1..2 kg, springs 1e5..2e5 N/m, dampers
0.1..1 N s/m) assembled sparse (``chain_matrices(..., sparse=True)``); 1,000 load cases of 100
steps (dt = 1e-3 s, average acceleration), a random force on the last mass. Three ways, timed
in turn within each repeat (same run, same machine state):

- ``solver.run``: one solver, one run per case;
- ``mck_response``: one call per case (the results are bitwise those of the runs);
- the loop: the C loop of each case alone (`dtdyn.linear._mck.step_operator`, the object the
  solver keeps), called on preallocated history and output arrays: the floor of a case.

Each is run twice: storing x, v, a of 3 DOFs, and of every DOF (4.8 MB per case, which each run
allocates and reads once for its finite-value check); each case's result is dropped before the
next. Then the same three ways on a beam (``dd.Beam``, 1,000 Hermite elements, 2,000 DOFs: the
matrix Riccati sweep of block_chain.c) and a shaft (``dd.Shaft``, a line of 2,000 disks: the
tree sweep), ``beam_response`` / ``shaft_response`` against their models' ``solver(dt).run``,
average acceleration, 100 steps of dt = 1e-4 s, a random force at the free end, x, v, a of 3
DOFs stored; "the loop" is the solver's own advance of each case, made once and called on
preallocated arrays. Times: per case, the median [min, max] of the repeats after a warm-up,
BLAS pinned to one thread (dtdyn.app._timing).

Usage: python benchmarks/solver_reuse.py [--quick] [--cases N]
(--quick: 100 cases, 2 repeats, docs untouched; --cases: N cases of each model, default 1000;
without --quick the output is written to docs/solver_reuse.md)
"""
from __future__ import annotations

import sys

import numpy as np

import dtdyn as dd
from dtdyn._engine.stepping import history_from_states
from dtdyn.app import SPREAD, interleaved, pin_blas
from dtdyn.linear._solver import scheme_key

N_DOF, N_STEPS, DT = 2000, 100, 1e-3


def loop_only(solver, forces, loaded):
    """The C loop of every case alone: the solver's factorized step, bound to ``loaded``,
    called on preallocated arrays (the history reset to the first case's initial state)."""
    info = solver._info
    advance = solver._steps[scheme_key(info)](loaded)
    out = solver.outputs
    f0 = np.zeros(N_DOF)
    f0[loaded] = forces[0][0]
    state = (np.zeros(N_DOF), np.zeros(N_DOF), solver._mass_solve(f0))
    H0 = history_from_states(info.history, [state])
    H = H0.copy()
    xo, vo, ao = (np.empty((N_STEPS + 1, out.size)) for _ in range(3))
    columns = [np.ascontiguousarray(f[:, None]) for f in forces]

    def run():
        for f in columns:
            H[...] = H0
            advance(f, H, xo, vo, ao)
        return xo, vo, ao
    return run


def case(n_cases, repeats, outputs, label):
    rng = np.random.default_rng(0)
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, N_DOF), rng.uniform(1e5, 2e5, N_DOF),
                                rng.uniform(0.1, 1, N_DOF), sparse=True)
    forces = rng.standard_normal((n_cases, N_STEPS + 1))
    load = [N_DOF - 1]
    setup = interleaved({"solver": lambda: dd.Matrices(M, C, K).solver(DT, outputs=outputs)},
                        repeats)["solver"]
    solver = dd.Matrices(M, C, K).solver(DT, outputs=outputs)
    # the three ways give the same numbers (the loop: its first case)
    ref = dd.mck_response(M, C, K, forces[0], DT, force_dofs=load, outputs=outputs)
    assert all(np.array_equal(getattr(solver.run(forces[0], force_dofs=load), q),
                              getattr(ref, q)) for q in "xva")
    loop = loop_only(solver, forces[:1], np.array(load))
    assert np.array_equal(loop()[0][1:], ref.x[1:])  # (row 0 is the initial state)
    def runs():  # each result dropped before the next case (not 1,000 results kept)
        for f in forces:
            solver.run(f, force_dofs=load)

    def calls():
        for f in forces:
            dd.mck_response(M, C, K, f, DT, force_dofs=load, outputs=outputs)

    t = interleaved({"solver.run": runs, "mck_response": calls,
                     "loop": loop_only(solver, forces, np.array(load))}, repeats)
    per = {name: tm.scaled(1.0 / n_cases) for name, tm in t.items()}
    show(f"{label}: {n_cases:,} cases of {N_STEPS} steps, {N_DOF:,}-DOF sparse chain",
         "mck_response", per, setup)
    return per


def show(title, call, per, setup):
    """Print one model's table: the solver's runs, the function's calls, the loop."""
    print(f"{title}; per case, ms, " + SPREAD)
    print(f"   {'solver.run':<14s} {per['solver.run'].format('ms'):>24s}   "
          f"{per['solver.run'] / per['loop']:5.3f} x the loop")
    print(f"   {call:<14s} {per[call].format('ms'):>24s}   "
          f"{per[call] / per['loop']:5.3f} x the loop, "
          f"{per[call] / per['solver.run']:4.2f} x solver.run")
    print(f"   {'the loop':<14s} {per['loop'].format('ms'):>24s}")
    share = 1.0 - per["loop"] / per[call]
    print(f"   setup in a {call} call: {(per[call] - per['loop']) * 1e3:.3f} ms "
          f"({share:.0%}); making the solver once: {setup.format('ms')}\n")


def model_loop(solver, forces, load):
    """The loop of every case alone for any model's solver: its advance for the first
    case's loaded DOFs, made once (the scheme's factors, the kernel's operands, its scratch),
    called on preallocated arrays with the history reset to the first case's initial state."""
    info = solver._info
    case = solver._load_case(forces[0], load, None, None, None, None, None, None)
    H0 = history_from_states(info.history, [solver._initial_state(case)])
    H = H0.copy()
    advance = solver._stepper(case.loaded)(info, info.coefficients(solver.form, solver.dt))
    xo, vo, ao = (np.empty((N_STEPS + 1, solver._stored.size)) for _ in range(3))
    columns = [np.ascontiguousarray(f[:, None]) for f in forces]

    def run():
        for f in columns:
            H[...] = H0
            advance(f, H, xo, vo, ao)
        return xo, vo, ao
    return run


def beam_and_shaft(n_cases, repeats):
    """The three ways on a 2,000-DOF beam and a 2,000-DOF shaft (module docstring)."""
    rng = np.random.default_rng(1)
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=1000,
                   rayleigh=(0.5, 1e-5))
    shaft = dd.Shaft(rng.uniform(0.01, 0.02, N_DOF), rng.uniform(1e5, 2e5, N_DOF),
                     rng.uniform(0.1, 1, N_DOF))
    beam_case = (beam, dd.beam_response, ["w1000"], ["w500", "w1000", "psi1000"],
                 "2,000-DOF beam (1,000 elements)")
    shaft_case = (shaft, dd.shaft_response, [N_DOF - 1], [0, N_DOF // 2, N_DOF - 1],
                  "2,000-DOF shaft (a line of disks)")
    return {name: model_case(name, *spec, rng.standard_normal((n_cases, N_STEPS + 1)), repeats)
            for name, spec in (("beam", beam_case), ("shaft", shaft_case))}


def model_case(name, model, response, load, outputs, what, forces, repeats):
    """solver.run, ``<name>_response`` and the loop on one model, timed in turn."""
    setup = interleaved({"solver": lambda: model.solver(1e-4, outputs=outputs)},
                        repeats)["solver"]
    solver = model.solver(1e-4, outputs=outputs)
    ref = response(model, forces[0], 1e-4, force_dofs=load, outputs=outputs)
    assert all(np.array_equal(getattr(solver.run(forces[0], force_dofs=load), q),
                              getattr(ref, q)) for q in "xva")
    assert np.array_equal(model_loop(solver, forces[:1], load)()[0][1:], ref.x[1:])
    call = f"{name}_response"

    def runs():
        for f in forces:
            solver.run(f, force_dofs=load)

    def calls():
        for f in forces:
            response(model, f, 1e-4, force_dofs=load, outputs=outputs)

    t = interleaved({"solver.run": runs, call: calls,
                     "loop": model_loop(solver, forces, load)}, repeats)
    per = {k: tm.scaled(1.0 / len(forces)) for k, tm in t.items()}
    show(f"x, v, a of 3 DOFs: {len(forces):,} cases of {N_STEPS} steps, {what}", call, per,
         setup)
    return per


def main(quick=False, n_cases=None):
    n, repeats = (100, 2) if quick else (1000, 3)
    n_cases = n if n_cases is None else n_cases
    few = case(n_cases, repeats, [0, N_DOF // 2, N_DOF - 1], "x, v, a of 3 DOFs")
    every = case(n_cases, repeats, None, f"x, v, a of every DOF ({N_DOF:,})")
    return few, every, beam_and_shaft(n_cases, repeats)


if __name__ == "__main__":
    import contextlib
    import io
    import pathlib

    quick = "--quick" in sys.argv
    n_cases = int(sys.argv[sys.argv.index("--cases") + 1]) if "--cases" in sys.argv else None
    command = " ".join(["python benchmarks/solver_reuse.py", *sys.argv[1:]])
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        few, every, models = main(quick=quick, n_cases=n_cases)
    print(buf.getvalue(), end="")
    if not quick:
        doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "solver_reuse.md"
        # benchmarks/nonlinear_solver_reuse.py's section, which ends the page, is kept
        from nonlinear_solver_reuse import SECTION
        old = doc.read_text() if doc.exists() else ""
        kept = "\n" + SECTION + old.split("\n" + SECTION, 1)[1] if SECTION in old else ""
        doc.write_text(kept.join([
            "# Many load cases on one model\n\n"
            "`dd.Matrices(M, C, K).solver(dt, ...)` checks the model and the options, checks the "
            "stability limit, factorizes the effective matrix and M and loads the C loop once; "
            "each `solver.run(force, ...)` then runs one load case and costs the loop plus the "
            "checks of its own inputs and its outputs. `mck_response` is one solver and one "
            "run, so a batch of calls pays the setup every time. The results are bitwise the "
            "same ([the guide](guide/solvers.md); tests/behaviour/test_solver.py). "
            "`dd.Beam(...).solver(dt, ...)` and `dd.Shaft(...).solver(dt, ...)` do the same for "
            "`beam_response` and `shaft_response` (tests/behaviour/test_solver_beam_shaft.py), "
            "and `run_batch` runs each worker's load cases on one solver per model and "
            "settings (tests/application/test_batch_solver_reuse.py).\n\n"
            f"Output of `{command}` (2-core shared machine; the three "
            "ways timed in turn within each repeat; \"the loop\" is the C loop of each case "
            "called on preallocated arrays, the floor of a case):\n\n```\n"
            + buf.getvalue() + "```\n\n"
            f"Through one solver a case costs {few['solver.run'] / few['loop']:.2f} x the "
            f"loop's own time with 3 outputs (the goal: at most 1.1 x) and "
            f"{every['solver.run'] / every['loop']:.2f} x with every DOF stored, where the "
            "run allocates 4.8 MB of outputs and reads them once to refuse a non-finite "
            "result. A `mck_response` call "
            f"costs {few['mck_response'] / few['solver.run']:.2f} x a run with 3 outputs, "
            "a `beam_response` call "
            f"{models['beam']['beam_response'] / models['beam']['solver.run']:.2f} x a beam "
            "solver's run and a `shaft_response` call "
            f"{models['shaft']['shaft_response'] / models['shaft']['solver.run']:.2f} x a "
            "shaft solver's run.\n", ""]))
