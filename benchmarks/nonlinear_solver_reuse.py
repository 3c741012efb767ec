"""Many load cases on one nonlinear model: one solver's runs against as many
nonlinear_mck_response calls, same run.

Each `nonlinear_mck_response` call checks the options and the elements, builds the scheme's
linear step (the modal decomposition and the force polynomials' weights of a modal method,
the scheme's one-step model of a one-step scheme), finds the compiled element laws and C loop
in its cache and copies the loop's matrices, before a time loop that on a small model takes
a few microseconds. ``dd.Matrices(M, C, K).solver(dt, elements=[...])`` does that once; each
``solver.run(force, ...)`` then checks its own inputs, sets the initial state and runs the loop.

The model: P4 (`dd.problem("P4")`: 4 unit masses, springs 1e4 N/m, Rayleigh damping, cubic
springs k3 = 2e7 N/m^3 from DOF 0 to ground and between DOFs 1 and 2), 1,000 load cases: white
noise of 100 N standard deviation on DOF 3 (numpy default_rng(0)), dt = 1 ms, x, v, a of every
DOF stored. Per scheme and record length, three ways timed in turn within each repeat
(dtdyn.app.interleaved, after a warm-up round; BLAS pinned to one thread):

- ``solver.run``: one solver, one run per case;
- ``nonlinear_mck_response``: one call per case (bitwise the same results, checked on the first
  case);
- the loop: the C loop's own time, as the solver's runs report it (``info["run_time"]``), summed
  over the cases: the floor of a case.

Each case's result is dropped before the next. Times: per case, the median [min, max] of the
repeats.

Usage: python benchmarks/nonlinear_solver_reuse.py [--quick] [--cases N]
(--quick: 100 cases, 1 repeat, docs untouched; --cases: N cases, default 1000; without
--quick the output is written to docs/solver_reuse.md, its section "Nonlinear elements")
"""
from __future__ import annotations

import sys

import dtdyn as dd
from dtdyn.app import SPREAD, Timing, interleaved, pin_blas

#: (scheme, its parameters, steps per case)
CONFIGS = [("modal_ramp", {}, 100), ("modal_ramp", {}, 1000), ("modal_quintic", {}, 1000),
           ("newmark", {}, 100)]

#: the heading of this benchmark's section in docs/solver_reuse.md
SECTION = "## Nonlinear elements: one solver, many load cases"


def config(scheme, params, n_steps, n_cases, repeats):
    p = dd.problem("P4", n_samples=n_cases * (n_steps + 1))
    M, C, K, dt, elements = p["M"], p["C"], p["K"], p["dt"], p["elements"]
    forces = p["force"][:, 0].reshape(n_cases, n_steps + 1)
    load = p["force_dofs"]
    options = dict(elements=elements, scheme=scheme, **params)
    setup = interleaved({"solver": lambda: dd.Matrices(M, C, K).solver(dt, **options)},
                        repeats)["solver"]
    solver = dd.Matrices(M, C, K).solver(dt, **options)
    ref = dd.nonlinear_mck_response(M, C, K, forces[0], dt, force_dofs=load, **options)
    run = solver.run(forces[0], force_dofs=load)
    assert all(getattr(run, q).tobytes() == getattr(ref, q).tobytes() for q in "xva")
    loops = []  # the C loops' own time of each round of runs

    def runs():  # each result dropped before the next case (not 1,000 results kept)
        total = 0.0
        for f in forces:
            total += solver.run(f, force_dofs=load).info["run_time"]
        loops.append(total)

    def calls():
        for f in forces:
            dd.nonlinear_mck_response(M, C, K, f, dt, force_dofs=load, **options)

    t = interleaved({"solver.run": runs, "nonlinear_mck_response": calls}, repeats)
    t["loop"] = Timing(tuple(loops[1:]), loops[0])  # the warm-up round's apart, as interleaved
    per = {name: tm.scaled(1.0 / n_cases) for name, tm in t.items()}
    show(f"{scheme}{''.join(f', {k}={v}' for k, v in params.items())}: {n_cases:,} cases of "
         f"{n_steps:,} steps", per, setup)
    return per


def show(title, per, setup):
    call = "nonlinear_mck_response"
    print(f"{title}; per case, ms, " + SPREAD)
    print(f"   {'solver.run':<23s} {per['solver.run'].format('ms'):>26s}   "
          f"{per['solver.run'] / per['loop']:6.1f} x the loop")
    print(f"   {call:<23s} {per[call].format('ms'):>26s}   "
          f"{per[call] / per['loop']:6.1f} x the loop, "
          f"{per[call] / per['solver.run']:5.1f} x solver.run")
    print(f"   {'the loop (C)':<23s} {per['loop'].format('ms'):>26s}")
    print(f"   making the solver once: {setup.format('ms')}\n")


def main(quick=False, n_cases=None):
    n, repeats = (100, 1) if quick else (1000, 2)
    n_cases = n if n_cases is None else n_cases
    return {(s, n_steps): config(s, params, n_steps, n_cases, repeats)
            for s, params, n_steps in CONFIGS}


def write_section(path, command, text, results):
    """Put this benchmark's section at the end of ``path`` (replacing an earlier one)."""
    doc = path.read_text() if path.exists() else ""
    doc = doc.split("\n" + SECTION)[0].rstrip("\n") + "\n\n"
    call = "nonlinear_mck_response"
    ratios = ", ".join(f"{s} with {n:,} steps {per[call] / per['solver.run']:.1f} x"
                       for (s, n), per in results.items())
    doc += (
        f"{SECTION}\n\n"
        "`dd.Matrices(M, C, K).solver(dt, elements=[...], scheme=..., substeps=...)` checks the "
        "options and the elements, builds the scheme's linear step (the modal decomposition, "
        "the force polynomials' weights, or the one-step model of a scheme of the library) and "
        "finds the compiled element laws and C loop once; each `run(force, ...)` equals "
        "`nonlinear_mck_response` bitwise (tests/behaviour/test_nonlinear_solver.py). On P4 "
        "(4 DOFs, two cubic springs) the loop itself takes microseconds, so a call is almost "
        "all setup.\n\n"
        f"Output of `{command}` (2-core shared machine; solver runs and calls timed in turn "
        "within each repeat; \"the loop\" is the C loop's own time that each run reports):\n\n"
        "```\n" + text + "```\n\n"
        f"A `nonlinear_mck_response` call costs, per case: {ratios} a solver's run.\n")
    path.write_text(doc)


if __name__ == "__main__":
    import contextlib
    import io
    import pathlib

    quick = "--quick" in sys.argv
    n_cases = int(sys.argv[sys.argv.index("--cases") + 1]) if "--cases" in sys.argv else None
    command = " ".join(["python benchmarks/nonlinear_solver_reuse.py", *sys.argv[1:]])
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        results = main(quick=quick, n_cases=n_cases)
    print(buf.getvalue(), end="")
    if not quick:
        write_section(pathlib.Path(__file__).resolve().parents[1] / "docs" / "solver_reuse.md",
                      command, buf.getvalue(), results)
