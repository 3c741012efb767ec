"""state_space_response (generated C loop) against scipy.signal.dlsim, measured in one run.

A 50-state model (25-DOF chain, Newmark discrete state space) driven by white noise on every
DOF over 100,000 steps. Times: median [min, max] of repeats after a warm-up, BLAS pinned to one
thread (dtdyn.app.pin_blas, threadpoolctl).
Writes docs/state_space_speed.md.
Usage: python benchmarks/state_space_speed.py
"""
from __future__ import annotations

import contextlib
import io
import pathlib

import numpy as np
import scipy.signal as sig

from dtdyn.linear._chain import chain_matrices
from dtdyn.app import measure, pin_blas
from dtdyn.linear._state_space import newmark_ss, state_space_response


def timed(fn, repeats):
    """(Timing: median and spread of ``repeats`` calls after a warm-up, last result)."""
    out, t = measure(fn, repeats)
    return t, out


def main():
    n_dof, n_steps, dt = 25, 100_000, 1e-3
    M, C, K = chain_matrices(np.ones(n_dof), np.full(n_dof, 1e4), np.full(n_dof, 2.0), sparse=False)
    model = newmark_ss(M, C, K, dt, num_damp=1e-4)
    A, B, Cm, D = model
    u = np.random.default_rng(0).standard_normal((n_steps, n_dof))
    t_c, r = timed(lambda: state_space_response(model, u), 5)  # from rest at t_0
    y_c = np.hstack([r.x, r.v])
    t_np, _ = timed(lambda: state_space_response(model, u[:20_000], backend="numpy"), 3)
    x0 = model.initial_state(f0=u[0])  # the same start for dlsim (the state is shifted)
    t_ref, (_, y_ref, _) = timed(lambda: sig.dlsim((A, B, Cm, D, dt), u, x0=x0), 3)
    diff = np.max(np.abs(y_c - y_ref)) / np.max(np.abs(y_ref))
    print(f"{A.shape[0]}-state model, {n_steps} steps, {B.shape[1]} inputs, {Cm.shape[0]} outputs")
    print(f"   state_space_response (C)  {t_c.format():>26s}  ({t_c / n_steps * 1e9:.0f} ns/step)")
    print(f"   scipy.signal.dlsim        {t_ref.format():>26s}  "
          f"({t_ref / n_steps * 1e9:.0f} ns/step)")
    print(f"   NumPy fallback loop       {t_np.scaled(n_steps / 20_000).format():>26s}  "
          "(extrapolated from 20,000 steps)")
    print(f"   speed-up over dlsim {t_ref / t_c:.1f}x (target >= 10x); max relative difference "
          f"{diff:.1e} (target <= 1e-12)")


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        main()
    print(buf.getvalue(), end="")
    doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "state_space_speed.md"
    doc.write_text("# State-space time loop speed\n\n"
                   "Output of `python benchmarks/state_space_speed.py`"
                   " (2-core shared machine; ratios measured in one run):\n\n```\n"
                   + buf.getvalue() + "```\n")
