"""The reference problems for the tests: P1-P4 live in dtdyn.app._problems (one home); this adds the
tests' own helpers."""
import numpy as np

from dtdyn.app._problems import p1, p2, p3, p4  # noqa: F401  (re-exported for the tests)

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
