"""The time-loop driver shared by the DT-TMM chains and the assembled-matrix solver.

A *stepper* advances the per-DOF history H (rows named by the scheme's HISTORY: x0, v0, a0 and
lags such as xm1) over a block of steps and writes the requested outputs. This module runs the
start-up of multistep schemes (average-acceleration steps that fill the lags), chunks long runs
for the progress bar, and allocates only the outputs asked for.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from dtdyn._engine import validate
from dtdyn._engine.result import Response
from dtdyn._engine.schemes import SchemeInfo

#: a stepper: (scheme, coefficients) -> advance(force_rows, H, xo, vo, ao) -> error estimate of
#: the run so far (not of the call: an estimate that propagates through the steps is not a sum
#: over calls; the DT-TMM plain sweep's steppers share it, start-up included). 0.0: none.
MakeAdvance = Callable[[SchemeInfo, dict], Callable]

QUANTITIES = ("x", "v", "a")


def _lag(name: str) -> int:
    return 0 if name[1:] == "0" else int(name[2:])


def history_from_states(names, states) -> np.ndarray:
    """H rows from full states [(x, v, a) at steps ..., n-1, n] (last is current)."""
    return np.array([states[-1 - _lag(nm)]["xva".index(nm[0])] for nm in names])


def check_quantities(quantities, allowed: tuple = QUANTITIES) -> tuple:
    q = tuple(quantities)
    bad = [x for x in q if x not in allowed]
    if bad or not q:
        raise ValueError(f"quantities must be a non-empty subset of {allowed}, got {quantities!r}")
    return q


def integrate(scheme: SchemeInfo, form: str, dt: float, force: np.ndarray, state0,
              make_advance: MakeAdvance, out_idx: np.ndarray, quantities=QUANTITIES,
              progress: bool = False) -> Response:
    """Run ``len(force) - 1`` steps from ``state0 = (x0, v0, a0)`` (full-length arrays)."""
    n_steps = force.shape[0] - 1
    n_out = out_idx.size
    validate.output_size(f"{scheme.name} response", n_steps + 1, n_out * len(quantities))
    store = {q: np.empty((n_steps + 1, n_out)) if q in quantities else None for q in QUANTITIES}
    for q, arr in zip(QUANTITIES, state0):
        if store[q] is not None:
            store[q][0] = arr[out_idx]
    t_start = time.perf_counter()
    err_est = 0.0
    step = 0
    states = [tuple(np.array(a, dtype=float) for a in state0)]
    n_start = min(scheme.startup_steps, n_steps)
    if n_start:
        avg = scheme.startup()
        advance = make_advance(avg, avg.coefficients(form, dt))
        for _ in range(n_start):
            H = history_from_states(avg.history, states)
            err_est = advance(force[step:step + 2], H, *_rows(store, step))
            states.append(tuple(H[avg.history.index(q + "0")].copy() for q in QUANTITIES))
            step += 1
    # a run shorter than the start-up never uses the lags; pad them with the initial state
    pad = max(_lag(nm) for nm in scheme.history) + 1 - len(states)
    H = history_from_states(scheme.history, [states[0]] * pad + states)
    advance = (_composite(scheme, form, dt, make_advance) if scheme.stages
               else make_advance(scheme, scheme.coefficients(form, dt)))
    # blocks of at most CHECK_BLOCK steps and CHECK_WORK DOF-steps: a response that leaves the
    # finite numbers stops at the end of its block, named by its first non-finite step; Ctrl-C
    # acts between blocks (a fraction of a second each); the bar moves per block
    block = max(1, min(CHECK_BLOCK, CHECK_WORK // max(1, H.shape[-1])))
    n_chunks = max(-(-(n_steps - step) // block), min(100, n_steps - step) if progress else 1)
    bounds = np.linspace(step, n_steps, max(n_chunks, 1) + 1).astype(int)
    bar = _progress(n_steps, step) if progress else None
    try:
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if hi > lo:
                err_est = advance(force[lo:hi + 1], H, *_rows(store, lo))
                _check_finite(scheme, dt, H, store, quantities, lo, hi)
                if bar is not None:
                    bar.update(hi - lo)
    finally:
        if bar is not None:
            bar.close()
    run_time = time.perf_counter() - t_start
    t = dt * np.arange(n_steps + 1)
    return Response(t, out_idx, store["x"], store["v"], store["a"],
                    info={"scheme": scheme.name, "params": dict(scheme.params), "form": form,
                          "dt": dt, "n_steps": n_steps, "run_time": run_time,
                          "error_estimate": err_est})


def _composite(scheme: SchemeInfo, form: str, dt: float, make_advance: MakeAdvance):
    """The advance of a composite scheme: per step, each stage's advance over that step's two
    force rows in turn (each shifts the history, so a stage's lags are the state before it);
    only the last stage writes the outputs."""
    stages = [make_advance(s, s.coefficients(form, dt)) for s in scheme.stages]

    def advance(force, H, xo, vo, ao):
        err = 0.0
        for i in range(force.shape[0] - 1):
            rows = force[i:i + 2]
            for stage in stages[:-1]:
                stage(rows, H, None, None, None)
            err = stages[-1](rows, H, *(None if o is None else o[i:] for o in (xo, vo, ao)))
        return err
    return advance


#: steps per block between the checks for non-finite values (and for Ctrl-C), and DOF-steps
#: per block (a chain of 1e5 masses runs blocks of 167 steps, ~0.1 s each)
CHECK_BLOCK = 4096
CHECK_WORK = 1 << 24


def _check_finite(scheme, dt, H, store, quantities, lo, hi) -> None:
    """FloatingPointError naming the first step of rows lo..hi whose stored values (or, when
    nothing of them is stored, the history at hi) are not finite."""
    bad_rows = [np.flatnonzero(~np.isfinite(store[q][lo:hi + 1]).all(axis=1)) for q in quantities]
    first = min((int(r[0]) + lo for r in bad_rows if r.size), default=None)
    if first is None and not np.isfinite(H).all():
        first = hi
    if first is not None:
        raise FloatingPointError(f"{scheme.name}: the response is not finite from step {first} "
                                 f"(t = {first * dt:.6g} s): the scheme is unstable at dt = "
                                 f"{dt!r} or the sweep overflowed")


def _rows(store, start):
    """Views of the output arrays whose row 0 is step ``start`` (rows 1.. get written)."""
    return tuple(None if store[q] is None else store[q][start:] for q in QUANTITIES)


def _progress(total, initial):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="step", mininterval=0.5)
