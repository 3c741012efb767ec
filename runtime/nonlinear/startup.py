r"""The element forces before t_0 for the force polynomials of modal_parabolic and modal_quintic.

Over the step [t_k, t_k + h] those methods take the element forces as the polynomial through
g_{k+1}, g_k, ..., g_{k+1-m} (m = 2: the parabola; m = 5: the quintic, whose embedded estimate
also needs nabla^6 g, back to g_{k-5}). At the first steps the polynomial reaches before t_0.
A structure at rest before t_0 has g_{-j} = g_0 there. A structure released at t_0 from
x_0, v_0 != 0 has no such past, and a constant one leaves the polynomial an O(h) error at the
first steps: a second-order part in the result of a third- or sixth-order method.

The past used instead is the motion's own smooth continuation: the equations of motion

    M q'' + C q' + K q + L^T g(L q, L q', z) = B f(t),   z' = z'(L q, L q', z),

integrated backwards from q(t_0) = x_0, q'(t_0) = v_0, z(t_0) = 0 to t_0 - j h (SciPy's DOP853,
rtol 1e-12), with f continued by the line of its first sample interval. Any smooth continuation
serves: the solution after t_0 does not depend on it, and the polynomial through smooth values
keeps its order.
"""
from __future__ import annotations

import numpy as np
import scipy.integrate

from dtdyn._engine import linalg
from dtdyn.nonlinear.reference import _System

#: relative tolerance of the backward integration (the reference's)
RTOL = 1e-12


def forces_before_start(M, C, K, L, elements, force_dofs, f, dt, q0, qd0, h, count):
    """g(t_0 - j h), j = 1 .. ``count``, as rows (count, n_elements): the backward continuation
    of the motion from q0, qd0 (module docstring). RuntimeError when the integration fails."""
    n = M.shape[0]
    solve_M = linalg.solver(M, "M", "the force polynomials' start needs a nonsingular mass "
                            "matrix")
    system = _System(M, C, K, solve_M, np.eye(n)[:, force_dofs], L, elements)
    f1 = f[1] if f.shape[0] > 1 else f[0]
    system.set_interval(f[0], f1, 1.0 / dt)
    s0 = np.concatenate([q0, qd0, np.zeros(system.nz)])
    span = count * h
    scale = max(np.abs(q0).max(initial=0.0), np.abs(qd0).max(initial=0.0) * span, 1e-300)
    atol = np.concatenate([np.full(n, scale), np.full(n, scale / span),
                           np.full(system.nz, scale)]) * RTOL
    times = -h * np.arange(1, count + 1)
    sol = scipy.integrate.solve_ivp(system.rhs, (0.0, -span), s0, method="DOP853", rtol=RTOL,
                                    atol=atol, t_eval=times)
    if sol.status != 0:
        raise RuntimeError(f"the element forces before t_0 (the backward continuation from x0, "
                           f"v0 over {count} steps of {h:.6g} s): {sol.message}")
    return system.element_forces(sol.y.T)
