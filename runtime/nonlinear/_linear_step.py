"""The linear part of every nonlinear step: a discrete model of one (sub)step h with the
element forces as extra inputs.

Every scheme is a linear discrete model of the (sub)step h = dt / S, written with the
element forces as extra inputs (u = [f; g], the g columns carrying -L^T), and shifted so that the
state x_k is known before step k is solved (as `discrete_state_space` and SHARPy do):

    w_k = Cw x_k + Dwf f_k + Dwg g_k,   x_{k+1} = A x_k + Bf f_k + Bg g_k,

w = [y; y'] the element deformations. Each step solves the small nonlinear system
w - Q_k - Dwg g(w, z) = 0 (with the internal states' trapezoidal update) for w and z only:
the source's x_nl(n) + B0 g(x_nl(n)) = Q(n) (derivation and the modal B0 in
generated/nonlinear.md). Schemes:

- "modal_ramp": modal digital filters, ramp invariant (Ahlin, Josefsson & Magnevall): one
  complex first-order recursion per kept mode, exact for a force linear between samples, the
  nonlinear force treated as linear over the step (second order in h).
- "modal_parabolic": the same filters with the element forces interpolated by the parabola
  through g_{k-1}, g_k, g_{k+1} (third order in h, same per-step problem; dtdyn's addition).
- "modal_quintic": the same filters with the element forces interpolated by the polynomial of
  degree 5 through g_{k-4}, ..., g_{k+1} (sixth order in h, same per-step problem, stable up to
  theta = 0.222), with an embedded error estimate: the next term of the polynomial,
  nabla^6 g_{k+1}, is the local error of each step; the linear modal dynamics carry it along
  (dtdyn's addition).
- "modal_explicit": the same filters with the element forces extrapolated over the step by the
  polynomial of degree 6 through g_{k-6}, ..., g_k (seventh order in h): the step's response does
  not depend on its own element forces (Dwg = 0), so each step evaluates the element laws once,
  with no Newton solve (internal states still solve their own update); stable up to
  theta = |(Cw Bg) dg/dy| = 0.264 (Omega_t = 0.48), with the same embedded estimate as
  modal_quintic (dtdyn's addition).
- any one-step scheme of the integrator library on M, C, K ("newmark", "average_acceleration",
  "hht", "generalized_alpha", ...): the effective nonlinear system of the scheme; HHT and
  generalized-alpha evaluate the nonlinear forces like the external ones, averaged between
  t_n and t_{n+1} (alpha_f g_n + (1 - alpha_f) g_{n+1}).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dtdyn._engine import validate
from dtdyn.generated.scheme_table import METHODS, TABLE

MULTISTEP = tuple(name for name, row in TABLE.items() if row["startup_steps"])
#: the nonlinear modal methods (generated/scheme_table.py METHODS, from dtdyn.derive.nonlinear)
MODAL = tuple(METHODS)
#: the modal methods whose force polynomial has its own tables (generated/nl_modal.py)
POLYNOMIAL = tuple(name for name, row in METHODS.items() if row["polynomial"])
#: the modal methods whose step does not depend on its own element forces (Dwg = 0)
EXPLICIT = tuple(name for name, row in METHODS.items() if row["explicit"])

#: largest theta = |B0 dg/dy|_inf (the elements' tangent stiffness k_t as seen by the step; y
#: rows and columns only: velocity terms and internal states are not counted) a method stays
#: stable at (METHODS' theta_limit: derived by dtdyn.derive.nonlinear.polynomial_stability, the
#: ramp 2 (Omega_t = sqrt 12), the quintic 0.222 (Omega_t = 1.61); the parabola, which grows
#: from theta = 0 on, held to 0.01). The explicit modal_explicit has no B0: its theta is
#: |(Cw Bg) dg/dy|, the weight of g_k on the next step's y (0.264, Omega_t = 0.48).
#: The implicit schemes (average acceleration, HHT, generalized-alpha) have no such limit.
THETA_LIMIT = {name: row["theta_limit"] for name, row in METHODS.items()}

@dataclass
class LinearStep:
    """The shifted linear model of one (sub)step (module docstring).

    Inputs u = [f; g]. The shifted initial state is x_0 = X0f f_0 + X0g g_0 + X0x q_0 +
    X0v q'_0 (x_0 = z_0 - Gamma1 u_0, z_0 the scheme's history at t_0; q_0 = q'_0 = 0: at rest).
    """

    h: float
    A: np.ndarray
    Bf: np.ndarray
    Bg: np.ndarray
    Cw: np.ndarray
    Dwf: np.ndarray
    Dwg: np.ndarray
    Co: np.ndarray
    Dof: np.ndarray
    Dog: np.ndarray
    X0f: np.ndarray
    X0g: np.ndarray
    X0x: np.ndarray
    X0v: np.ndarray
    #: modal methods: the structure the C loop uses (`modal_structure`), else None
    modal: dict | None = None


def _shifted(Phi, G0, G1, S, Z0, Zx, Zv, L, out, need_v, nf, h, direct=None) -> LinearStep:
    """LinearStep of z_{k+1} = Phi z_k + G0 u_k + G1 u_{k+1}, [q; q'; q''] = S z + direct u.

    Shifted state x = z - G1 u (A = Phi, B = G0 + Phi G1, D = S G1); z_0 = Z0 u_0 + Zx q_0 +
    Zv q'_0.
    """
    n = L.shape[1]
    q, v, a = S[:n], S[n:2 * n], S[2 * n:]
    W = np.vstack([L @ q] + ([L @ v] if need_v else []))
    O = np.vstack([q[out], v[out], a[out]])
    B = G0 + Phi @ G1
    Dw, Do = W @ G1, O @ G1
    if direct is not None:
        Do = Do + np.vstack([direct[:n][out], direct[n:2 * n][out], direct[2 * n:][out]])
    X0 = Z0 - G1
    c = np.ascontiguousarray
    return LinearStep(h, c(Phi), c(B[:, :nf]), c(B[:, nf:]), c(W), c(Dw[:, :nf]), c(Dw[:, nf:]),
                      c(O), c(Do[:, :nf]), c(Do[:, nf:]), c(X0[:, :nf]), c(X0[:, nf:]), c(Zx),
                      c(Zv))


def _modal_step(M, C, K, h, U, L, out, modes, need_v, nf, forces=False,
                estimate=True) -> LinearStep:
    """Ramp-invariant modal model: eta_k = lam eta_{k-1} + N0 p_k + N1 p_{k-1}, p = X_f U u.

    Displacement q = sum_r w_r Re(psi_r eta_r) (w = 2 for a conjugate pair, 1 for a real pole),
    velocity with psi_r s_r, acceleration with psi_r s_r^2 plus the direct term
    sum_r w_r Re(s_r R_r) u (= M^-1 with all modes). ``forces="parabolic"`` adds
    N2 X_f U_g (g_k - 2 g_{k-1} + g_{k-2}) (generated/nl_modal.py), the state then carrying
    g_{k-1} (g_{-1} = g_0 at rest); ``forces`` = a method of POLYNOMIAL weighs its nodes
    g_{k+j} by W_j (generated/nl_modal.py, polynomial_coefficients; modal_quintic g_{k-4} ..
    g_{k+1}, modal_explicit g_{k-6} .. g_k), the state carrying the past ones g_{k-1}, g_{k-2},
    ..., and adds the estimate's input E X_f U_g (step.modal["Eg"]; ``estimate=False``: none).
    """
    from scipy.linalg import block_diag

    from dtdyn.generated.modal_filters import forced_coefficients
    from dtdyn.generated.nl_modal import parabola_coefficient

    from dtdyn.modal._model import _pair_poles, modal_factors
    s_all, Psi_q, X_f, X_x = modal_factors(M, C, K, initial=True)
    X_v = X_f @ M  # eta_0 = X_x q_0 + X_v q'_0
    keep, osc = _pair_poles(s_all)
    order = np.argsort(np.abs(s_all[keep]), kind="stable")
    idx, osc = keep[order], osc[order]
    if modes is not None:
        sel = np.sort(validate.dof_indices("modes", modes, idx.size))
        idx, osc = idx[sel], osc[sel]
    s = np.where(osc, s_all[idx], s_all[idx].real)
    N1, N0 = forced_coefficients("ramp", s, np.ones_like(s), h)  # old input, new input
    N2 = parabola_coefficient(s, h) if forces == "parabolic" else np.zeros_like(s)
    polynomial = forces in POLYNOMIAL
    if polynomial:  # W_j of g_{k+j} and the estimate's E
        from dtdyn.generated.nl_modal import POLYNOMIALS, polynomial_coefficients
        W, E = polynomial_coefficients(forces, s, h)
        past = [j for j in POLYNOMIALS[forces][0] if j < 0][::-1]  # g_{k-1}, g_{k-2}, ...
    lam = np.exp(s * h)
    P = X_f[idx] @ U
    ne, nu = L.shape[0], U.shape[1]
    psi = Psi_q[:, idx] * np.where(osc, 2.0, 1.0)
    Sc = np.vstack([psi, psi * s, psi * s**2])
    direct = np.vstack([np.zeros((2 * L.shape[1], nu)), ((psi * s) @ P).real])
    A_blocks, rows = [], {"G0": [], "G1": [], "G2": [], "S": [], "Zx": [], "Zv": [], "E": []}
    for r in range(idx.size):
        l, g0, g1, g2 = lam[r], N1[r] * P[r], N0[r] * P[r], N2[r] * P[r, nf:]
        g0[nf:] -= 2.0 * g2
        g1[nf:] += g2
        e = np.zeros(ne, dtype=complex)
        if polynomial:  # G2: the weights of g_{k-1}, g_{k-2}, ... side by side
            g0[nf:] = W[0][r] * P[r, nf:]
            g1[nf:] = W[1][r] * P[r, nf:] if 1 in W else 0.0
            g2 = np.concatenate([W[j][r] * P[r, nf:] for j in past])
            e = E[r] * P[r, nf:]
        parts = {"G0": g0, "G1": g1, "G2": g2, "S": Sc[:, r], "Zx": X_x[idx[r]],
                 "Zv": X_v[idx[r]], "E": e}
        if osc[r]:  # real state (Re eta, Im eta)
            A_blocks.append(np.array([[l.real, -l.imag], [l.imag, l.real]]))
            for k, v in parts.items():
                rows[k] += [v.real, -v.imag if k == "S" else v.imag]
        else:
            A_blocks.append(np.array([[l.real]]))
            for k, v in parts.items():
                rows[k].append(v.real)
    Phi = block_diag(*A_blocks)
    G0, G1, G2, S, Zx, Zv, Eg = (np.array(rows[k]) for k in ("G0", "G1", "G2", "S", "Zx", "Zv",
                                                               "E"))
    S = S.T
    Z0 = np.zeros_like(G1)
    nm = Phi.shape[0]
    if forces:  # state [eta; g_{k-1}; ...; g_{k-n_past}], shifted by ne each step
        nh = G2.shape[1]
        E_g = np.hstack([np.zeros((ne, nf)), np.eye(ne)])
        shift = np.zeros((nh, nm + nh))
        shift[ne:, nm:nm + nh - ne] = np.eye(nh - ne)
        Phi = np.block([[Phi, G2], [shift]])
        G0 = np.vstack([G0, E_g, np.zeros((nh - ne, nu))])
        G1 = np.vstack([G1, np.zeros((nh, nu))])
        S = np.hstack([S, np.zeros((S.shape[0], nh))])
        Z0 = np.vstack([Z0, np.tile(E_g, (nh // ne, 1))])
        Zx, Zv = (np.vstack([Z, np.zeros((nh, Z.shape[1]))]) for Z in (Zx, Zv))
    step = _shifted(Phi, G0, G1, S, Z0, Zx, Zv, L, out, need_v, nf, h, direct)
    if polynomial and estimate:
        step.modal = modal_structure(step, nm, Eg, POLYNOMIALS[forces][5])
    else:
        step.modal = modal_structure(step, nm, np.zeros((nm, ne)), np.zeros(0))
    return step


def modal_structure(step: LinearStep, nm: int, Eg, stencil) -> dict | None:
    """What the C loop's modal path needs of a modal step (generated/nl_loop.c, modal_run): A's
    modal block T, block diagonal with 2 x 2 blocks (oscillating modes) and 1 x 1 blocks (real
    poles), as the order of its rows that puts the 2 x 2 blocks first (``perm``) and, in that
    order, its diagonal and each row's partner entry (T y = dia y + off y[partner], the partner
    of row 2i being 2i + 1 and the other way round); A's history columns H, the estimate's input
    Eg and difference stencil (rows in A's order). None when the step does not have that shape
    (then the loop takes the general path)."""
    A, ns, ne = step.A, step.A.shape[0], step.Bg.shape[1]
    nh = ns - nm
    Am = A[:nm, :nm]
    shift = np.zeros((nh, ns))
    if nh:
        shift[ne:, nm:ns - ne] = np.eye(nh - ne)
    bg_hist = np.vstack([np.eye(ne), np.zeros((nh - ne, ne))]) if nh else np.zeros((0, ne))
    if (not np.array_equal(A[nm:], shift) or not np.array_equal(step.Bg[nm:], bg_hist)
            or np.any(step.Bf[nm:]) or np.any(step.Cw[:, nm:]) or np.any(step.Co[:, nm:])):
        return None
    pairs, singles, i = [], [], 0
    while i < nm:
        if i + 1 < nm and (Am[i, i + 1] != 0 or Am[i + 1, i] != 0):
            pairs += [i, i + 1]
            i += 2
        else:
            singles.append(i)
            i += 1
    perm = np.array(pairs + singles, dtype=int)
    Tp = Am[np.ix_(perm, perm)]
    partner = np.arange(nm)
    npair = len(pairs)
    partner[:npair] = np.arange(npair) ^ 1
    off = np.where(np.arange(nm) < npair, Tp[np.arange(nm), partner], 0.0)
    rebuilt = np.diag(np.diag(Tp))
    rebuilt[np.arange(nm), partner] += off
    if not np.array_equal(rebuilt, Tp):  # a coupling outside the blocks
        return None
    return {"nm": nm, "nh": nh, "perm": perm, "dia": np.diag(Tp).copy(), "off": off,
            "H": A[:nm, nm:], "Eg": np.asarray(Eg, float).reshape(nm, ne),
            "stencil": np.asarray(stencil, float)}


def _scheme_step(M, C, K, h, U, L, out, scheme, params, need_v, nf) -> LinearStep:
    """The scheme's one-step model (`scheme_blocks`), history [x0; v0; a0] per DOF, with
    a_0 = M^+ U u_0 at rest (M^+: pseudo-inverse, = M^-1 when M is nonsingular)."""
    from dtdyn.linear._state_space import scheme_blocks
    from dtdyn._engine.schemes import get_scheme
    if get_scheme(scheme, **params).startup_steps:
        raise ValueError(f"scheme {scheme!r} is a multistep scheme whose start-up is not a single "
                         "linear step; use 'newmark', 'hht', 'generalized_alpha' or 'modal_ramp'")
    Phi, G0, G1, S = scheme_blocks(M, C, K, h, scheme, acceleration=True, **params)
    n = M.shape[0]
    G0, G1 = G0 @ U, G1 @ U
    Minv = np.linalg.pinv(M)
    Z0 = np.zeros_like(G1)
    Z0[2 * n:3 * n] = Minv @ U
    # history [x0; v0; a0] at t_0 from q_0, q'_0: a_0 = M^+ (U u_0 - K q_0 - C q'_0)
    eye, zero = np.eye(n), np.zeros((n, n))
    Zx, Zv = np.vstack([eye, zero, -Minv @ K]), np.vstack([zero, eye, -Minv @ C])
    return _shifted(Phi, G0, G1, S, Z0, Zx, Zv, L, out, need_v, nf, h)


def linear_step(method, M, C, K, h, force_dofs, L, outputs, modes=None, need_v=False,
                estimate=True, **scheme_params) -> LinearStep:
    """The shifted linear model of one step h for ``method`` (module docstring); ``estimate``:
    the polynomial methods' embedded estimate (False: their loop skips it)."""
    n = M.shape[0]
    U = np.hstack([np.eye(n)[:, force_dofs], -L.T])  # DOF forces of u = [f; g]
    if method in MODAL:
        if scheme_params:
            raise ValueError(f"scheme {method!r} takes no scheme parameters, got "
                             f"{', '.join(sorted(scheme_params))}")
        # the force polynomial: degree 1 the ramp itself, 2 the parabola (its N2), else tables
        row = METHODS[method]
        forces = method if row["polynomial"] else {1: False, 2: "parabolic"}[row["degree"]]
        return _modal_step(M, C, K, h, U, L, outputs, modes, need_v, len(force_dofs),
                           forces=forces, estimate=estimate)
    if modes is not None:
        raise ValueError(f"modes selects modal filters; scheme {method!r} integrates all DOFs")
    return _scheme_step(M, C, K, h, U, L, outputs, method, scheme_params, need_v,
                        len(force_dofs))
