"""DT-TMM chains with localized nonlinear elements: O(N) per step on long chains.

The linear step of a chain (`simulate_chain`'s stable DT-TMM sweep) is linear in the loads, so
with the element forces g as loads -L^T g (runtime/elements.py) the state after a step is

    H_{k+1} = H_lin + sum_e g_e U_e,

H_lin the sweep with g_{k+1} = 0 (g_k known), U_e the step's response to the unit load pair of
element e at t_{k+1} from rest (one sweep per element, once per run). The element deformations
then satisfy w - Dwg g(w, z) = Q with Q = W(H_lin), Dwg = [W(U_e)]: the condensed per-step
problem of generated/nonlinear.md, here with K_eff^-1 L^T applied by the sweep instead of a
factorization. Each step costs one sweep over the chain (O(N), generated C kernel), a Newton
solve in the element unknowns (the CasADi residual of dtdyn.runtime.nonlinear) and an O(N n_e)
update. For short chains `nonlinear_response(method=scheme)` on `chain_matrices` is faster.
"""
from __future__ import annotations

import time

import numpy as np

from . import kernels, validate
from .chain import chain_parameters
from .elements import check_elements
from .nonlinear import NewtonError, _forces_at_rest, _residual_function, _sizes
from .result import Response
from .schemes import get_scheme


def nonlinear_chain_response(mass, stiffness, damping, force, fs, force_dofs, elements,
                             outputs=None, scheme="newmark", form="displacement", substeps=1,
                             backend="c", tol=1e-12, max_iter=30, **scheme_params) -> Response:
    """Forced response of a chain with nonlinear elements by the DT-TMM (module docstring).

    Parameters as `simulate_chain` (chain data, ``scheme``, ``form``, ``backend``) and
    `nonlinear_response` (``force`` of shape (n_samples, len(force_dofs)) at t_n = n / fs, linear
    between samples; ``elements``; ``substeps``; ``tol``, ``max_iter``). One-step schemes only.

    Returns
    -------
    Response
        ``t``, ``x``, ``v``, ``a`` of shape (n_samples, len(outputs)); ``info`` with the run time
        and the Newton statistics.
    """
    t0 = time.perf_counter()
    m, k, c = chain_parameters(mass, stiffness, damping)
    N = m.size
    fs = validate.positive_scalar("fs", fs)
    force_dofs = validate.dof_indices("force_dofs", force_dofs, N, default_all=False)
    outputs = validate.dof_indices("outputs", outputs, N)
    elements = check_elements(elements)
    if not elements:
        raise ValueError("elements is empty: use simulate_chain for a linear chain")
    for e, el in enumerate(elements):
        for name, d in (("i", el.i), ("j", el.j)):
            if d is not None and d >= N:
                raise ValueError(f"elements[{e}] ({type(el).__name__}).{name} = {d} is outside "
                                 f"the chain's masses 0..{N - 1}")
    S = validate.step_count("substeps", substeps)
    f = validate.force_record(force, force_dofs.size)
    info = get_scheme(scheme, **scheme_params)
    if info.startup_steps:
        raise ValueError(f"scheme {info.name!r} is multistep; the nonlinear chain needs a "
                         "one-step scheme (newmark, hht, generalized_alpha, ...)")
    h = 1.0 / (fs * S)
    sz = _sizes(elements)
    fn = _residual_evaluator(elements, sz, backend)

    # loads at the loaded masses: external forces and -L^T g
    ei = np.array([el.i for el in elements])
    ej = np.array([-1 if el.j is None else el.j for el in elements])
    loaded = np.unique(np.concatenate([force_dofs, ei, ej[ej >= 0]]))
    pos = {d: n for n, d in enumerate(loaded)}
    pf = np.array([pos[d] for d in force_dofs])
    pi = np.array([pos[d] for d in ei])
    pj = np.array([pos[d] if d >= 0 else -1 for d in ej])

    def loads(fv, gv):
        row = np.zeros(loaded.size)
        np.add.at(row, pf, fv)
        np.add.at(row, pi, -gv)
        np.add.at(row, pj[pj >= 0], gv[pj >= 0])
        return row

    names = info.history
    ix, iv, ia = (names.index(q + "0") for q in "xva")

    def kin(H):  # w = [y; y'] of the elements from the chain state
        x, v = H[ix], H[iv]
        y = x[ei] - np.where(ej >= 0, x[np.maximum(ej, 0)], 0.0)
        if not sz.need_v:
            return y
        return np.concatenate([y, v[ei] - np.where(ej >= 0, v[np.maximum(ej, 0)], 0.0)])

    advance = kernels.chain_advance(backend, info, info.coefficients(form, h), form, "stable",
                                    m, k, c, h, loaded, np.zeros(0, dtype=np.int64))
    zero_row = np.zeros(loaded.size)
    U = []
    for e in range(sz.ne):
        H = np.zeros((len(names), N))
        unit = np.zeros(sz.ne)
        unit[e] = 1.0
        advance(np.vstack([zero_row, loads(np.zeros(force_dofs.size), unit)]), H, None, None,
                None)
        U.append(H)
    U = np.array(U)  # (ne, nh, N)
    Dwg = np.array([kin(Ue) for Ue in U]).T  # (nw, ne)
    par = np.concatenate([Dwg.ravel(order="F"), [h]])

    g, rate = _forces_at_rest(elements, sz)
    H = np.zeros((len(names), N))
    H[ia] = np.bincount(loaded, loads(f[0], g), minlength=N) / m
    u = np.concatenate([kin(H), np.zeros(sz.nz)])
    n_samples = f.shape[0]
    store = {q: np.empty((n_samples, outputs.size)) for q in "xva"}
    t1 = time.perf_counter()
    scale, iters, worst, total = 0.0, 0, 0.0, 0
    for n in range(n_samples):
        for q, i in zip("xva", (ix, iv, ia)):
            store[q][n] = H[i, outputs]
        if n + 1 == n_samples:
            break
        for j in range(S):
            fa = f[n] + (j / S) * (f[n + 1] - f[n])
            fb = f[n] + ((j + 1) / S) * (f[n + 1] - f[n])
            advance(np.vstack([loads(fa, g), loads(fb, np.zeros(sz.ne))]), H, None, None, None)
            Q = kin(H)
            zold, rold = u[sz.nw:].copy(), rate
            u = np.concatenate([Q + Dwg @ g, zold + h * rold])
            scale = max(scale, np.abs(Q).max(initial=0.0))
            for it in range(max_iter + 1):
                r, J, g_new, rate_new = fn(u, Q, zold, rold, par)
                rn = np.abs(r).max(initial=0.0)
                scale = max(scale, np.abs(u).max(initial=0.0))
                if rn <= tol * scale or not np.isfinite(rn) or it == max_iter:
                    break
                u = u - np.linalg.solve(J, r)
            total += it
            iters = max(iters, it)
            kk = n * S + j
            if not (rn <= tol * scale) or not np.isfinite(g_new).all():
                where = f"sample {n}" + (f", sub-step {j} of {S}" if S > 1 else "")
                raise NewtonError(f"Newton did not converge at step {kk + 1} ({where}, t = "
                                  f"{(kk + 1) * h:.6g} s): residual {rn:.3g} after at most "
                                  f"{max_iter} iterations; try more substeps")
            worst = max(worst, rn)
            g, rate = g_new, rate_new
            H += np.tensordot(g, U, axes=1)
    t2 = time.perf_counter()
    return Response(np.arange(n_samples) / fs, outputs, x=store["x"], v=store["v"],
                    a=store["a"],
                    info={"method": f"DT-TMM {info.name} ({form} form, stable sweep)",
                          "substeps": S, "backend": backend, "fs": fs,
                          "elements": [el.describe() for el in elements],
                          "setup_time": t1 - t0, "run_time": t2 - t1,
                          "newton_iterations": {"max": iters,
                                                "mean": total / max((n_samples - 1) * S, 1)},
                          "max_residual": worst})


def _residual_evaluator(elements, sz, backend):
    """(u, Q, z_old, z'_old, par) -> (r, J, g, z') as float arrays: the CasADi residual of
    dtdyn.runtime.nonlinear, code-generated and called through ctypes (a few us per call) when
    C is available, else the CasADi Function."""
    import ctypes

    import casadi as ca

    from . import cbuild
    fn = _residual_function(elements, sz)
    nu = sz.nw + sz.nz
    lib = None
    if backend == "c":
        cg = ca.CodeGenerator("nl_residual", {"with_header": False})
        cg.add(fn)
        lib = cbuild.load_library(cg.dump(), "nl_residual")
    if lib is None:
        def evaluate(u, Q, zold, rold, par):
            r, J, g, rate = (np.asarray(a, dtype=float) for a in fn(u, Q, zold, rold, par))
            return r.ravel(), J, g.ravel(), rate.ravel()
        return evaluate
    c_fn = lib.nl_residual
    c_fn.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
    c_fn.restype = ctypes.c_int
    ins = [np.zeros(nu), np.zeros(sz.nw), np.zeros(max(sz.nz, 1)), np.zeros(max(sz.nz, 1)),
           np.zeros(sz.nw * sz.ne + 1)]
    outs = [np.zeros(nu), np.zeros((nu, nu), order="F"), np.zeros(sz.ne), np.zeros(max(sz.nz, 1))]
    arg = (ctypes.c_void_p * 5)(*[a.ctypes.data for a in ins])
    res = (ctypes.c_void_p * 4)(*[a.ctypes.data for a in outs])
    w = np.zeros(int(fn.sz_w()) + 1)
    iw = np.zeros(int(fn.sz_iw()) + 1, dtype=np.int64)

    def evaluate(u, Q, zold, rold, par):
        ins[0][:] = u
        ins[1][:] = Q
        ins[2][:sz.nz] = zold
        ins[3][:sz.nz] = rold
        ins[4][:] = par
        c_fn(arg, res, iw.ctypes.data, w.ctypes.data, 0)
        return (outs[0].copy(), np.array(outs[1]), outs[2].copy(), outs[3][:sz.nz].copy())
    return evaluate
