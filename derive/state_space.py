"""Newmark discrete-time state space in block form (SHARPy's newmark_ss).

With y = [q; q'] and the Newmark relations

    q1 = q0 + dt v0 + dt^2 ((1/2 - beta) a0 + beta a1),   v1 = v0 + dt ((1 - gamma) a0 + gamma a1),

SHARPy eliminates the accelerations with a = M^-1 (f - C v - K q). Here the two relations are
multiplied on the left by M instead, and M a_i = f_i - C v_i - K q_i substituted, which gives

    E1 y_{n+1} = E0 y_n + G0 f_n + G1 f_{n+1},     E1 = diag(M, M) Ass1, E0 = diag(M, M) Ass0, ...

with no inverse of M anywhere. det E1 = det M det(M + gamma dt C + beta dt^2 K), so E1 is
singular exactly when M is: with massless DOFs no [q; q'] model exists, and the runtime
realizes the Newmark recursion with the state [q; q'; q''] instead. M, C, K, the identity and
the vectors are non-commutative symbols; each block comes out as sum(scalar * {I, M, C, K}).
"""
from __future__ import annotations

import sympy as sp

from .integrators import beta, dt, gamma

Mm, Cm, Km, Im = sp.symbols("M C K I", commutative=False)
q0, q1, v0, v1, a0, a1, f0, f1 = sp.symbols("q0 q1 v0 v1 a0 a1 f0 f1", commutative=False)
HALF = sp.Rational(1, 2)
MATRICES = (Im, Mm, Cm, Km)


def _block(expr, vec):
    """Coefficient of the vector ``vec`` in a linear non-commutative expression, as
    {matrix name: scalar}: sum(scalar * matrix) is the block."""
    out = {}
    for term in sp.Add.make_args(sp.expand(expr)):
        c, nc = term.args_cnc()
        if not nc or nc[-1] != vec:
            continue
        left = nc[:-1]
        if len(left) > 1:
            raise ValueError(f"term {term} is not matrix * vector")
        name = str(left[0]) if left else "I"
        out[name] = sp.simplify(out.get(name, 0) + sp.Mul(*c))
    return {k: v for k, v in out.items() if v != 0}


def newmark_rows():
    """The two block rows, M-multiplied, as expressions that vanish: row(q), row(v)."""
    Ma = {a0: f0 - Cm * v0 - Km * q0, a1: f1 - Cm * v1 - Km * q1}  # M a_i
    row_q = (Mm * q1 - Mm * q0 - dt * Mm * v0
             - dt**2 * ((HALF - beta) * Ma[a0] + beta * Ma[a1]))
    row_v = Mm * v1 - Mm * v0 - dt * ((1 - gamma) * Ma[a0] + gamma * Ma[a1])
    return row_q, row_v


def newmark_blocks() -> dict:
    """{"E1": 2x2 blocks, "E0": ..., "G0": 2x1, "G1": 2x1}; each block {matrix: scalar}.

    Rows: E1 y_{n+1} - E0 y_n - G0 f_n - G1 f_{n+1} = row(q), row(v) above.
    """
    rows = newmark_rows()
    neg = lambda d: {k: -v for k, v in d.items()}  # noqa: E731
    return {
        "E1": [[_block(r, q1), _block(r, v1)] for r in rows],
        "E0": [[neg(_block(r, q0)), neg(_block(r, v0))] for r in rows],
        "G0": [[neg(_block(r, f0))] for r in rows],
        "G1": [[neg(_block(r, f1))] for r in rows],
    }


def sharpy_alpha_params():
    """SHARPy's parameterization: gamma = 1/2 + alpha, beta = (1 + alpha)^2 / 4,
    alpha = num_damp."""
    num_damp = sp.Symbol("num_damp")
    return num_damp, {gamma: HALF + num_damp, beta: (1 + num_damp) ** 2 / 4}
