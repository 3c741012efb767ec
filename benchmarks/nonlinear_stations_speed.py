"""Nonlinear beams and shafts against their linear runs: the cost of the elements (#31).

A cantilever `Beam` (3 m, E I = 1.68e6 N m^2, 20 kg/m) of 1,000 and 10,000 elements, a cubic
spring to the ground at the tip (k3 = 1e12 N/m^3: at the record's amplitude it carries more than
the load), a 30 Hz sine of 1 kN at the tip, 2,000 steps of 0.1 ms; and a torsional tree of
1,000 and 10,000 disks (a main line, J = 1 kg m^2, k_t = 1e4 N m/rad, c_t = 1 N m s/rad, with a
branch of the same disks geared 2:1 at the main line's quarter), a cubic spring to the ground at
the branch's end disk (k3 = 1e6 N m/rad^3), a 5 Hz sine of 50 N m there, 2,000 steps of 1 ms.
Newmark average acceleration, displacement form. Each pair: `nonlinear_beam_response` against
`beam_response` (`nonlinear_shaft_response` against `shaft_response`) on the same model and
record, both storing the loaded DOF, called in turn (dtdyn.app._timing.interleaved), median
[min, max] of 5 after a warm-up, wall time of the whole call (setup included), BLAS pinned to one
thread. The ratio is of the medians; the goal is at most 1.5. Both beam runs take the default
`refine="auto"`: the 10,000-element ones refine every step's solve (docs/beam_conditioning.md),
the 1,000-element ones do not.

    python benchmarks/nonlinear_stations_speed.py     (writes docs/nonlinear_stations_speed.md)
"""
import contextlib
import io
import pathlib

import numpy as np

import dtdyn as dd
from dtdyn.app._timing import interleaved, pin_blas

STEPS = 2000


def beam_case(n):
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=n)
    tip = beam.dof(f"w{n}")
    f = 1000.0 * np.sin(2 * np.pi * 30 * 1e-4 * np.arange(STEPS + 1))
    kw = dict(force_dofs=[tip], outputs=[tip])
    return ("beam", lambda: dd.beam_response(beam, f, 1e-4, **kw),
            lambda: dd.nonlinear_beam_response(beam, f, 1e-4, elements=[dd.Cubic(tip, k3=1e12)],
                                               **kw))


def shaft_case(n):
    h = n // 2
    branch = dd.Branch(h // 2, np.ones(n - h), np.full(n - h, 1e4), np.ones(n - h), ratio=2.0,
                       name="b")
    shaft = dd.Shaft(np.ones(h), np.full(h, 1e4), np.ones(h), branches=[branch])
    end = shaft.dof(f"b.{n - h - 1}")
    f = 50.0 * np.sin(2 * np.pi * 5 * 1e-3 * np.arange(STEPS + 1))
    kw = dict(force_dofs=[end], outputs=[end])
    return ("shaft", lambda: dd.shaft_response(shaft, f, 1e-3, **kw),
            lambda: dd.nonlinear_shaft_response(shaft, f, 1e-3, elements=[dd.Cubic(end, k3=1e6)],
                                                **kw))


def main():
    print(f"{STEPS} steps, Newmark average acceleration; time of the whole call, median [min, "
          "max] of 5\n")
    print("| model | stations | linear | nonlinear (1 cubic spring) | ratio | Newton iterations "
          "per step | loop |")
    print("|---|---|---|---|---|---|---|")
    for make in (beam_case, shaft_case):
        for n in (1000, 10000):
            name, linear, nonlinear = make(n)
            t = interleaved({"linear": linear, "nonlinear": nonlinear}, 5)
            r = nonlinear()
            it = r.info["newton_iterations"]
            print(f"| {name} | {n:,} | {t['linear'].format()} | {t['nonlinear'].format()} | "
                  f"{t['nonlinear'] / t['linear']:.2f} | {it['mean']:.2f} (max {it['max']}) | "
                  f"{r.info['loop']} |")


if __name__ == "__main__":
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pin_blas(1) as pin:
        print(f"{pin.describe()}\n")
        main()
    print(buf.getvalue(), end="")
    doc = pathlib.Path(__file__).resolve().parents[1] / "docs" / "nonlinear_stations_speed.md"
    doc.write_text("# Nonlinear beams and shafts: the cost of the elements\n\nOutput of "
                   "`python benchmarks/nonlinear_stations_speed.py` (2-core shared machine; the "
                   "ratios are measured in one run):\n\n" + buf.getvalue())
