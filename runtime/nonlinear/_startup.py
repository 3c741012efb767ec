r"""The element forces before t_0 for the force polynomials of modal_parabolic, modal_quintic and
modal_explicit.

Over the step [t_k, t_k + h] those methods take the element forces as the polynomial through
g_{k+1}, g_k, ..., g_{k+1-m} (m = 2: the parabola; m = 5: the quintic, whose embedded estimate
also needs nabla^6 g, back to g_{k-5}), or through g_k, ..., g_{k-6} (modal_explicit, its
estimate back to g_{k-7}). At the first steps the polynomial reaches before t_0.
A structure at rest before t_0 has g_{-j} = g_0 there. A structure released at t_0 from
x_0, v_0 != 0 has no such past, and a constant one leaves the polynomial an O(h) error at the
first steps: a second-order part in the result of a third- or sixth-order method.

The past used instead continues the motion's own forces smoothly: the equations of motion

    M q'' + C q' + K q + L^T g(L q, L q', z) = B f(t),   z' = z'(L q, L q', z),

from q(t_0) = x_0, q'(t_0) = v_0, z(t_0) = 0 with f continued by the line of its first sample
interval, are integrated forwards over n h (SciPy's DOP853, rtol 1e-12; forwards, where damping
decays: backwards a stiff damped mode grows like e^{zeta omega n h}), and the polynomial of degree
n through g(t_0), ..., g(t_0 + n h) is evaluated at t_0 - j h. Its error there is
O(h^{n+1} g^{(n+1)}), an order above the method's, and the solution after t_0 does not depend
on which smooth continuation is used.
"""
from __future__ import annotations


import numpy as np

from dtdyn._engine import linalg
from dtdyn._engine.errors import DtdynAccuracyWarning
from dtdyn._engine.public import warn
from dtdyn.nonlinear._reference import _System

#: relative tolerance of the integration (the reference's)
RTOL = 1e-12
#: right-hand side evaluations allowed per step h of the continuation (DOP853 takes 12 a step)
RHS_PER_STEP = 12 * 400


class _TooMuchWork(Exception):
    pass


def extrapolation_weights(count: int) -> np.ndarray:
    """W (count, count + 1): g(t_0 - j h) = sum_i W[j - 1, i] g(t_0 + i h), j = 1 .. count, by
    the Lagrange polynomial of degree ``count`` on the nodes 0 .. count."""
    nodes = np.arange(count + 1.0)
    W = np.ones((count, count + 1))
    for j in range(1, count + 1):
        for i in range(count + 1):
            others = np.delete(nodes, i)
            W[j - 1, i] = np.prod((-j - others) / (nodes[i] - others))
    return W


def forces_before_start(M, C, K, L, elements, force_dofs, f, dt, q0, qd0, h, count):
    """g(t_0 - j h), j = 1 .. ``count``, as rows (count, n_elements) (module docstring); None,
    with a DtdynAccuracyWarning, when the integration fails or needs more than RHS_PER_STEP
    evaluations a step (the caller keeps the constant past)."""
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
    budget = RHS_PER_STEP * count

    def rhs(t, s):
        if system.n_rhs > budget:
            raise _TooMuchWork
        return system.rhs(t, s)
    why = None
    import scipy.integrate  # deferred: `import dtdyn` does not load scipy.integrate
    try:
        sol = scipy.integrate.solve_ivp(rhs, (0.0, span), s0, method="DOP853", rtol=RTOL,
                                        atol=atol, t_eval=h * np.arange(count + 1))
        if sol.status != 0:
            why = sol.message
    except _TooMuchWork:
        why = f"more than {budget} right-hand sides (a stiff model)"
    if why is None:
        g = system.element_forces(sol.y.T)
        past = extrapolation_weights(count) @ g
        if np.all(np.isfinite(past)):
            return past
        why = "not finite"
    warn(f"the element forces before t_0 (the continuation from x0, v0 over {count} "
         f"steps of {h:.6g} s): {why}; the force polynomials start from the constant "
         f"past g_0, so their first steps are of lower order", DtdynAccuracyWarning)
    return None
