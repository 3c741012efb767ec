"""The reference problems for the tests: P1-P4 are `dtdyn.problem` (one home, dtdyn.app); this adds
the tests' own helpers."""
import textwrap

import numpy as np

from dtdyn import problem


def p1() -> dict:
    """P1, `dtdyn.problem("P1")`: one DOF under a unit step."""
    return problem("P1")


def p2() -> dict:
    """P2, `dtdyn.problem("P2")`: the 2-DOF chain."""
    return problem("P2")


def p3() -> dict:
    """P3, `dtdyn.problem("P3")`: the undamped 15-DOF chain of Kumar & Sankar (1986)."""
    return problem("P3")


def p4(n_samples: int = 100_000) -> dict:
    """P4, `dtdyn.problem("P4")`: the nonlinear 4-DOF chain under ``n_samples`` of white noise."""
    return problem("P4", n_samples=n_samples)


_KEYS = ("mass", "stiffness", "damping", "dt", "T", "force_dofs")
P1, P2, P3 = ({k: p[k] for k in _KEYS if k in p} for p in (p1(), p2(), p3()))
P3["dt"] = None
PROBLEMS = {"P1": P1, "P2": P2, "P3": P3}


def uniform_chain(n, m=1.0, k=1e4, c=1.0):
    return dict(mass=np.full(n, m), stiffness=np.full(n, k), damping=np.full(n, c),
                force_dofs=[n - 1])


def rel_error(x, ref):
    """max over time and outputs of |x - ref|, relative to max |ref|."""
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


def chain_scene(n, steps, dt=1e-4) -> str:
    """The fault suite's chain scene (TOML): n unit masses on 1e6 springs, a step on the last
    one, x of mass 0 stored."""
    ones = ", ".join(["1.0"] * n)
    return textwrap.dedent(f"""\
        [model]
        mass = [{ones}]
        stiffness = [{", ".join(["1e6"] * n)}]
        damping = [{ones}]
        [[load]]
        dof = {n - 1}
        kind = "step"
        [time]
        dt = {dt}
        duration = {steps * dt!r}
        [output]
        outputs = [0]
        quantities = ["x"]
        """)
