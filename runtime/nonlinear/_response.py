"""Nonlinear forced response: a linear discretization plus localized nonlinear elements.

    M q'' + C q' + K q + L^T g(L q, L q', z) = f,   z' = z'(L q', z)    (runtime/elements.py)

The linear step of each scheme (the shifted discrete model with the element forces as extra
inputs, and the per-step problem w - Q_k - Dwg g(w, z) = 0) is built in
`dtdyn.nonlinear._linear_step`; this module solves that problem at every step of the record.

Backends: "c" (generated loop dtdyn_nl_run of generated/nl_loop.c, with the element laws'
residual and Jacobian from CasADi code generation; compiled once and cached), "casadi" (the same
step as a CasADi rootfinder inside Function.mapaccum over the record; `compiled=True` generates
and compiles it). Both check every step: a Newton failure raises NewtonError naming the step,
the time and the residual; a modal step beyond its stability limit for the elements' tangent
stiffness (THETA_LIMIT) raises DtdynStepStabilityError.

Newton acceptance, the same rule in every backend (C loops: newton_solve of newton.c; CasADi:
its residual test on r / s_r while it iterates, both tests after the run; the chain's Python
loop: chain.newton_solve):
u is accepted when

    |r(u)|_inf <= tol s_r    or    |J(u)^-1 r(u)|_inf <= tol s_u,

s_r = the largest |Q|_inf or |u|_inf and s_u = the largest |u|_inf of the solutions accepted so
far (s_r raised by Q before a step; both fixed during its iterations). The residual test is
relative to the size of the residual's terms; the step test, relative to the size of the
unknowns, accepts a residual at its round-off floor, eps |J| |u| for a stiff element (a gap of
1e12 N/m), where no iterate can do better but the solution is known to tol.
"""
from __future__ import annotations

import ctypes
import time
from dataclasses import dataclass
from functools import lru_cache, partial
from importlib import resources

import numpy as np

from dtdyn._engine import cbuild
from dtdyn._engine import linalg
from dtdyn._engine import validate
from dtdyn.nonlinear._elements import casadi_ops, element_matrix  # noqa: F401 (tests' NL.)
from dtdyn._engine.result import Response
from dtdyn._engine.errors import DtdynStepStabilityError, NewtonError
from dtdyn._engine.extras import require
from dtdyn.nonlinear._linear_step import EXPLICIT, POLYNOMIAL, THETA_LIMIT, LinearStep
from dtdyn.nonlinear._linear_step import linear_step  # noqa: F401 (the tests' NL.linear_step)

# ----------------------------------------------------------------------------------------------
# the per-step residual of the elements (CasADi SX), shared by both backends


@dataclass(frozen=True)
class _Sizes:
    ne: int  # elements
    nw: int  # element kinematics w = [y; y'] (y' only when some element uses it)
    nz: int  # internal states
    need_v: bool


def _sizes(elements) -> _Sizes:
    ne = len(elements)
    need_v = any(el.uses_velocity for el in elements)
    return _Sizes(ne, ne * (2 if need_v else 1), sum(el.n_internal for el in elements), need_v)


def _residual_expressions(elements, sz: _Sizes):
    """SX symbols and expressions of r(u; Q, z_old, z'_old, [Dwg; h]) (module docstring)."""
    ca = require("casadi", "nonlinear", "nonlinear_mck_response")
    ops = casadi_ops()
    u = ca.SX.sym("u", sz.nw + sz.nz)
    Q = ca.SX.sym("Q", sz.nw)
    zold = ca.SX.sym("zold", sz.nz)
    rold = ca.SX.sym("rold", sz.nz)
    par = ca.SX.sym("par", sz.nw * sz.ne + 1)  # Dwg column-major, then h
    Dwg = ca.reshape(par[:sz.nw * sz.ne], sz.nw, sz.ne)
    h = par[sz.nw * sz.ne]
    y = u[:sz.ne]
    vy = u[sz.ne:2 * sz.ne] if sz.need_v else ca.SX.zeros(sz.ne)
    z = u[sz.nw:] if sz.nz else ca.SX(0, 1)  # CasADi slices an empty range as 1x0
    g, rate, k = [], [], 0
    for e, el in enumerate(elements):
        ze = [z[k + i] for i in range(el.n_internal)]
        g.append(el.force(y[e], vy[e], ze, ops))
        rate += list(el.rate(y[e], vy[e], ze, ops))
        k += el.n_internal
    g = ca.vertcat(*g)
    rate = ca.vertcat(*rate) if rate else ca.SX(0, 1)
    r = ca.vertcat(u[:sz.nw] - Q - ca.mtimes(Dwg, g), z - zold - 0.5 * h * (rate + rold))
    return dict(u=u, Q=Q, zold=zold, rold=rold, par=par, r=r, g=g, rate=rate)


def _residual_function(elements, sz: _Sizes, tangent: bool = False):
    """nl_residual(u, Q, z_old, z'_old, par) -> (r, dr/du, g, z'[, dg/du]): ``tangent`` adds
    the elements' tangent dg/du (the modal loop's estimate carries its error with it)."""
    ca = require("casadi", "nonlinear", "nonlinear_mck_response")
    e = _residual_expressions(elements, sz)
    J = ca.densify(ca.jacobian(e["r"], e["u"]))
    outs = [e["r"], J, e["g"], e["rate"]]
    if tangent:
        outs.append(ca.densify(ca.jacobian(e["g"], e["u"])))
    return ca.Function("nl_residual", [e["u"], e["Q"], e["zold"], e["rold"], e["par"]], outs)


def _forces_at_rest(elements, sz: _Sizes, y=None, yd=None):
    """g and z' at t_0: the elements' deformations y, y' (zero: at rest) with z = 0."""
    from dtdyn.nonlinear._elements import NUMPY_OPS
    y = np.zeros(len(elements)) if y is None else y
    yd = np.zeros(len(elements)) if yd is None else yd
    g = np.array([float(el.force(y[e], yd[e], np.zeros(el.n_internal), NUMPY_OPS))
                  for e, el in enumerate(elements)])
    rate = [float(r) for e, el in enumerate(elements)
            for r in el.rate(y[e], yd[e], np.zeros(el.n_internal), NUMPY_OPS)]
    return g, np.array(rate)


# ----------------------------------------------------------------------------------------------
# backend "c": generated loop + CasADi-generated residual


#: the C loops keep the LU factors of the Newton Jacobian from step to step (modified Newton,
#: nl_loop.c's newton_fixed) from this many unknowns u = [w; z] on, where the factorization
#: (~nu^3 / 3) outweighs the evaluation and the solve; below, every iteration solves with the
#: Jacobian at its iterate (the CasADi backend's steps). None: never (benchmarks/newton_reuse.py)
LU_REUSE_MIN: int | None = 12


@lru_cache(maxsize=32)
def _c_runner(elements, dims, explicit=False, reuse=False):
    """(runner or None, construct time, compile time) for these elements and sizes (ns, nf, ne,
    nw, nz, no[, nm, nh, nst]: the modal path of the loop, whose residual function also
    gives dg/du; ``explicit``: modal_explicit's step, NL_EXPLICIT; ``reuse``: the Newton
    Jacobian's LU factors kept, NL_LU_REUSE); cached, so a second run pays neither."""
    t0 = time.perf_counter()
    sz = _sizes(elements)
    fn = _residual_function(elements, sz, tangent=len(dims) > 6)
    sizes = "".join(f"#define NL_{k} {int(v)}\n" for k, v in zip(("NS", "NF", "NE", "NW", "NZ",
                                                                     "NO", "NM", "NH", "NST"),
                                                                    dims))
    sizes += "#define NL_EXPLICIT 1\n" if explicit else ""
    sizes += "#define NL_LU_REUSE 1\n" if reuse else ""
    loop = resources.files("dtdyn.generated").joinpath("nl_loop.c").read_text()
    source = sizes + loop + "\n" + _c_source(fn)
    t1 = time.perf_counter()
    lib = cbuild.load_library(source, "nl_loop")
    t2 = time.perf_counter()
    if lib is None:
        return None, t1 - t0, t2 - t1
    run = cbuild.bind(lib, "dtdyn_nl_run")
    cbuild.bind(lib, "dtdyn_nl_work")  # the doubles of its work, from the loop's own layout
    return (run, int(fn.sz_w()), int(fn.sz_iw()), lib), t1 - t0, t2 - t1


def _p(a):
    return a.ctypes.data_as(ctypes.c_void_p)


def _pad_rows(a):
    """``a`` with its rows padded by zeros to a multiple of 4 (the C loop's vectors)."""
    a = np.asarray(a, dtype=float)
    n = -(-a.shape[0] // 4) * 4
    return np.vstack([a, np.zeros((n - a.shape[0], a.shape[1]))])


def _modal_mats(step: LinearStep, md, past=None) -> list:
    """The modal path's matrices (nl_loop.c, modal_run): the modal rows in the order ``perm``
    (T's 2 x 2 blocks first) and padded, as the output rows, to a multiple of 4: [dia off], [H Bf],
    Eg, the stencil, Bg, Bs = Bg + sum_i H_i (g's weights summed: the estimate's), Cw^T, Cw Bg,
    [Co Dof Dog]; the estimate's Cw e_k from e_{k-1}: (Cw T)^T, Cw Eg, Cw Bs; its forces
    before t_0, oldest first (``past``: g_{-1}, g_{-2}, ... as rows); and |Cw Bg| on the y rows
    (ne x ne, its rows padded to a multiple of 4: modal_explicit's theta). ``past`` None:
    None in its place (`_past`, each run's)."""
    nm, nh, ne, p = md["nm"], md["nh"], step.Bg.shape[1], md["perm"]
    Bg, Cw = step.Bg[:nm][p], step.Cw[:, :nm][:, p]
    H, Eg = md["H"][p], md["Eg"][p]
    Bs = Bg + sum(H[:, i:i + ne] for i in range(0, nh, ne))
    T = np.diag(md["dia"])
    pair = np.flatnonzero(md["off"])
    T[pair, pair ^ 1] = md["off"][pair]  # T y = dia y + off y[partner] (modal_structure)
    return [_pad_rows(np.column_stack([md["dia"], md["off"]])),
            _pad_rows(np.hstack([H, step.Bf[:nm][p]])), _pad_rows(Eg),
            np.concatenate([md["stencil"], [0.0]]), _pad_rows(Bg), _pad_rows(Bs),
            _pad_rows(Cw.T), Cw @ Bg,
            _pad_rows(np.hstack([step.Co[:, :nm][:, p], step.Dof, step.Dog])),
            _pad_rows((Cw @ T).T), Cw @ Eg, Cw @ Bs,
            None if past is None else _past(md, past), _pad_rows(np.abs(Cw @ Bg)[:ne])]


#: the place of the forces before t_0 in the C loop's matrices (`_modal_mats`, nl_loop.h)
PAST = 22


def _past(md, past):
    """The modal loop's forces before t_0, oldest first, then 0 (``past``: g_{-1}, g_{-2},
    ... as rows)."""
    return np.append(past[md["stencil"].size - 2::-1] if md["stencil"].size else [], 0.0)


def _c_mats(step: LinearStep) -> list:
    """The C loop's matrices of ``step`` in column-major order, the forces before t_0 (the
    modal path's mats[PAST], each run's) None."""
    par = np.concatenate([step.Dwg.ravel(order="F"), [step.h]])
    mats = [step.A, step.Bf, step.Bg, step.Cw, step.Dwf, step.Dwg, par, step.Co, step.Dof,
            step.Dog]
    if step.modal is not None:  # the modal path: only the modal rows and columns (nl_loop.c)
        mats += _modal_mats(step, step.modal)
    return [None if m is None else np.asfortranarray(m, dtype=float) for m in mats]


#: steps per block of the modal loop's embedded estimate (nl_loop.c, estimate_prep and modal_run)
ESTIMATE_BLOCK = 128


def _c_addresses(mats) -> tuple:
    """(``mats``, their data addresses): what `_run_c` passes the loop (None: 0)."""
    return mats, [0 if m is None else m.ctypes.data for m in mats]


def _run_c(runner, step: LinearStep, sz, force, S, tol, max_iter, x, u, g, rate, theta_limit,
           nzo, past, mats=None):
    """One run of the C loop (``mats``: `_c_mats` of ``step`` and their addresses, as a
    solver keeps them (`_c_addresses`); made when None)."""
    run, n_w, n_iw, lib = runner
    ns, nf, no = step.A.shape[0], force.shape[1], step.Co.shape[0]
    n_samples = force.shape[0]
    md = step.modal
    nst = 0 if md is None else md["stencil"].size
    extra = [] if md is None else [md["nm"], md["nh"], nst, n_w + 1, ESTIMATE_BLOCK]
    dims = np.array([ns, nf, sz.ne, sz.nw, sz.nz, no, n_samples, S, max_iter, nzo] + extra,
                    dtype=np.int64)
    mats, addresses = _c_addresses(_c_mats(step)) if mats is None else mats
    ptrs = (ctypes.c_void_p * len(addresses))(*addresses)
    if md is not None:
        before = np.asfortranarray(_past(md, past), dtype=float)  # kept alive to the run's end
        ptrs[PAST] = before.ctypes.data
        # the loop's modal rows in the order perm, copied back after the run
        xa, x = x, x.copy()
        x[:md["nm"]] = xa[md["perm"]]
    out = np.empty((n_samples, no + nzo))
    stats = np.zeros(6 + no)  # then the estimate's largest |error| per output row, the LUs
    fail = np.zeros(1, dtype=np.int64)
    # CasADi's work, then the estimate's block from dims[13] (nl_loop.c sizes it: dtdyn_nl_work)
    work = np.zeros(max(lib.dtdyn_nl_work(_p(dims)), 1))
    iwork = np.zeros(n_iw + 1, dtype=np.int64)
    args = (_p(dims), ctypes.cast(ptrs, ctypes.c_void_p), _p(force), _p(x), _p(u), _p(g),
            _p(rate), _p(out), tol, theta_limit, _p(stats), _p(fail), _p(work), work.size,
            _p(iwork), iwork.size)
    kernel = []  # the C loop's own run time
    if md is None:  # the dense step's products
        work = n_samples * S * (ns + sz.nw) ** 2
    else:  # the modal rows' products with the history, inputs, forces and Cw; the outputs
        work = (n_samples * S * md["nm"] * (md["nh"] + nf + 2 * sz.ne + sz.nw)
                + n_samples * no * (md["nm"] + nf + sz.ne))
    rc = cbuild.interruptible(lib, lambda: run(*args), work=work, timing=kernel)
    if md is not None:
        xa[md["perm"]] = x[:md["nm"]]
        xa[md["nm"]:] = x[md["nm"]:]
    return rc, out, stats, int(fail[0]), kernel[0]


# ----------------------------------------------------------------------------------------------
# backend "casadi": rootfinder per sub-step, mapaccum over the record


#: samples per inner mapaccum block, and inner blocks per call of the record function: a call
#: runs at most BLOCK * CHUNK_BLOCKS samples, so its graph and work arrays are bounded
BLOCK = 256
CHUNK_BLOCKS = 16


_RECORDS: dict = {}


def _casadi_record(elements, step: LinearStep, S, n_blocks, solver, tol, max_iter, compiled,
                   with_theta, nzo=0, explicit=False):
    """F(x_aug, [f_n; f_{n+1}] columns) -> (x_aug', out columns, check columns), check =
    [|r| per sub-step; rho = min(|r| / s_r, |J^-1 r| / s_u) per sub-step; theta per sub-step
    (``with_theta`` only; ``explicit``: modal_explicit's, |(Cw Bg) dg/dy|)].

    x_aug = [x; u; g; z'; s_r; s_u] (state, last solution, forces, rates, scales of the
    acceptance rule); one column per sample, the
    chunk of n_blocks * BLOCK samples (the record padded at its end); the step's matrices
    are constants of the graph.
    Returns (function, construct time, compile time); cached per process.
    """
    import hashlib

    ca = require("casadi", "nonlinear", "nonlinear_mck_response")
    mats = [step.A, step.Bf, step.Bg, step.Cw, step.Dwf, step.Dwg, step.Co, step.Dof, step.Dog]
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(m).tobytes() for m in mats)
                            + repr([m.shape for m in mats] + [step.h]).encode()).hexdigest()
    key = (elements, digest, S, n_blocks, solver, tol, max_iter, compiled, with_theta, nzo,
           explicit)
    if key in _RECORDS:
        return _RECORDS[key][0], 0.0, 0.0
    t0 = time.perf_counter()
    ns, nf = step.A.shape[0], step.Bf.shape[1]
    sz = _sizes(elements)
    e = _residual_expressions(elements, sz)
    nu = sz.nw + sz.nz
    # the rootfinder's residual is r / s_r, so CasADi's absolute test on it (abstol) is the
    # shared rule's residual test (module docstring) with the C loop's scale; its step test is
    # off (CasADi's is absolute): at a residual's round-off floor it iterates to max_iter, and
    # the check after the run applies both tests of the rule to the u it returns. Failures are
    # not raised inside CasADi; plain Newton steps, as the C loop takes them (CasADi's "newton"
    # would add a line search)
    sr_ = ca.SX.sym("sr")
    p = ca.vertcat(e["Q"], e["zold"], e["rold"], e["par"], sr_)
    opts = {"abstol": tol, "abstolStep": 1e-300, "max_iter": max_iter, "error_on_fail": False,
            "show_eval_warnings": False, **({"line_search": False} if solver == "newton" else {})}
    rf = ca.rootfinder("rf", solver, {"x": e["u"], "p": p, "g": e["r"] / sr_}, opts)
    J = ca.densify(ca.jacobian(e["r"], e["u"]))
    # theta = |J_yy - I|_inf = |B0 dg/dy|_inf, as the C loop measures it; the explicit
    # polynomial (no B0): |(Cw Bg) dg/dy|_inf
    if explicit:
        dgdy = ca.densify(ca.jacobian(e["g"], e["u"]))[:, :sz.ne]
        J_yy = ca.mtimes(ca.DM((step.Cw @ step.Bg)[:sz.ne]), dgdy)
    else:
        J_yy = J[:sz.ne, :sz.ne] - ca.SX.eye(sz.ne)
    post = ca.Function("post", [e["u"], e["Q"], e["zold"], e["rold"], e["par"]],
                       [e["r"], J, e["g"], e["rate"], ca.mmax(ca.sum2(ca.fabs(J_yy)))])
    MX = ca.MX
    A, Bf, Bg, Cw, Dwf, Dwg, Co, Dof, Dog = (ca.DM(m) for m in mats)
    h = step.h
    xa = MX.sym("xa", ns + nu + sz.ne + sz.nz + 2)
    ff = MX.sym("ff", 2 * nf)
    def part(v, start, size):  # CasADi slices an empty range as 1x0; keep columns
        return v[start:start + size] if size else MX(0, 1)

    def grow(s, v):  # as grow() of newton.c: a non-finite v never raises the scale
        return ca.if_else(v < np.inf, ca.fmax(s, v), s)

    x, u = xa[:ns], xa[ns:ns + nu]
    g, rate = xa[ns + nu:ns + nu + sz.ne], part(xa, ns + nu + sz.ne, sz.nz)
    scale, scale_u = xa[-2], xa[-1]
    tiny = np.finfo(float).tiny
    par = ca.vertcat(ca.vec(Dwg), h)
    resid, rho, thetas, out = [], [], [], None
    for j in range(S):
        f = ff[:nf] + (j / S) * (ff[nf:] - ff[:nf])
        Q = ca.mtimes(Cw, x) + ca.mtimes(Dwf, f)
        zold = part(u, sz.nw, sz.nz)
        guess = ca.vertcat(Q + ca.mtimes(Dwg, g), zold + h * rate)
        scale = grow(scale, ca.norm_inf(Q))
        sr, su = ca.fmax(scale, tiny), ca.fmax(scale_u, tiny)
        u = rf(guess, ca.vertcat(Q, zold, rate, par, sr))
        r, Jv, g, rate, theta = post(u, Q, zold, rate, par)
        resid.append(ca.norm_inf(r))
        # the step test only where the residual test fails (as newton_solve: a Jacobian that is
        # not finite at an accepted u, e.g. Bouc-Wen's |z|^0 at z = 0, is never solved)
        rr = ca.norm_inf(r) / sr
        rho.append(ca.if_else(rr <= tol, rr,
                              ca.fmin(rr, ca.norm_inf(ca.solve(Jv, r, "qr")) / su)))
        if explicit and not sz.nz:  # no Newton: a force that is not finite fails the step
            rho[-1] = ca.if_else(ca.sum1(ca.fabs(g)) < np.inf, rho[-1], np.nan)
        thetas.append(theta)
        scale_u = grow(scale_u, ca.norm_inf(u))
        scale = ca.fmax(scale, scale_u)
        if j == 0:  # the outputs at the sample, then its first nzo internal states
            out = ca.vertcat(ca.mtimes(Co, x) + ca.mtimes(Dof, f) + ca.mtimes(Dog, g),
                             part(u, sz.nw, nzo))
        x = ca.mtimes(A, x) + ca.mtimes(Bf, f) + ca.mtimes(Bg, g)
    checks = resid + rho + (thetas if with_theta else [])
    one = ca.Function("nl_step", [xa, ff], [ca.vertcat(x, u, g, rate, scale, scale_u), out,
                                             ca.vertcat(*checks)])
    inner = one.mapaccum("nl_block", BLOCK, [0], [0])
    record = inner.mapaccum("nl_record", n_blocks, [0], [0])
    t1 = time.perf_counter()
    if compiled:
        record = _compile_casadi(record)
    _RECORDS[key] = (record,)
    return record, t1 - t0, time.perf_counter() - t1


def _compile_casadi(fn):
    """CasADi code generation of ``fn``, compiled through cbuild's cache, loaded as external.

    Only the "fast_newton" rootfinder can be code-generated (CasADi's "newton" cannot)."""
    ca = require("casadi", "nonlinear", "nonlinear_mck_response")
    lib = cbuild.load_library(_c_source(fn), fn.name())
    if lib is None:
        return fn
    return ca.external(fn.name(), lib._name)


def _c_source(fn) -> str:
    """C source of the CasADi Function ``fn`` (no header): compiled alone, or appended to a
    generated loop that calls it (nl_loop.c, nl_chain.c)."""
    ca = require("casadi", "nonlinear", "nonlinear_mck_response")
    cg = ca.CodeGenerator(fn.name(), {"with_header": False})
    cg.add(fn)
    return cg.dump()


def _run_casadi(elements, step, sz, f, S, solver, tol, max_iter, compiled, xa, method, fs,
                nzo=0):
    """Run the record in chunks of at most CHUNK_BLOCKS * BLOCK samples, the state carried from
    chunk to chunk, so memory is one chunk plus the outputs whatever the record's length; every
    chunk is checked before the next runs (the first failure raises, as in the C loop).

    Returns (out, largest final residual, largest theta or None, build, compile, run times)."""
    n = f.shape[0]
    n_blocks = min(CHUNK_BLOCKS, -(-n // BLOCK))
    chunk = n_blocks * BLOCK
    with_theta = method in THETA_LIMIT
    limit = THETA_LIMIT.get(method, np.inf)
    record, t_build, t_compile = _casadi_record(elements, step, S, n_blocks, solver, tol,
                                                max_iter, compiled, with_theta, nzo,
                                                method in EXPLICIT)
    out = np.empty((n, step.Co.shape[0] + nzo))
    worst, theta, t_run = 0.0, -np.inf, 0.0
    last_step = (n - 1) * S  # the last sample runs one step, as in the C loop
    for start in range(0, n, chunk):
        seg = f[start:start + chunk + 1]
        seg = np.vstack([seg, np.repeat(seg[-1:], chunk + 1 - seg.shape[0], axis=0)])
        t0 = time.perf_counter()
        xs, o, check = record(xa, np.hstack([seg[:-1], seg[1:]]).T)
        t_run += time.perf_counter() - t0
        xa = xs[:, -1]  # the state after the chunk's last sample
        m = min(chunk, n - start)
        out[start:start + m] = np.asarray(o).T[:m]
        check = np.asarray(check)[:, :m]
        # (sample, sub-step j) -> step sample S + j; a step is accepted by the shared rule
        # (module docstring): rho = min(|r| / s_r, |J^-1 r| / s_u) <= tol
        k0, keep = start * S, min(m * S, last_step - start * S + 1)
        resid, rho, thetas = (check[i * S:(i + 1) * S].T.ravel()[:keep] for i in range(3))
        bad = ~(rho <= tol)
        bad |= np.repeat(~np.isfinite(out[start:start + m]).all(axis=1), S)[:keep]
        bad = np.flatnonzero(bad)
        unstable = np.flatnonzero(thetas > limit)
        if unstable.size and (not bad.size or unstable[0] < bad[0]):
            _stability_error(method, k0 + int(unstable[0]), S, fs, float(thetas[unstable[0]]))
        if bad.size:
            evaluated = method in EXPLICIT and not sz.nz  # as the C loop: |g| is not finite
            _newton_error(k0 + int(bad[0]), S, fs,
                          np.inf if evaluated else float(resid[bad[0]]), max_iter, evaluated)
        worst = max(worst, float(resid.max()))
        if thetas.size:
            theta = max(theta, float(thetas.max()))
    return out, worst, (theta if with_theta else None), t_build, t_compile, t_run


# ----------------------------------------------------------------------------------------------
# public entry point

#: accuracy targets: the default cap on the sub-steps per sample, MAX_SUBSTEPS or as many as
#: keep the record's DOF-steps (DOFs x sub-steps x samples) within STEP_BUDGET
MAX_SUBSTEPS, STEP_BUDGET = 256, 10**8

#: what a nonlinear run can store: motion of the output DOFs, element forces, internal states
QUANTITIES = ("x", "v", "a", "g", "z")



# noqa below: the accuracy targets' dispatch (methods, sub-steps per record) stays here; a run
# is one solver (`dtdyn.nonlinear._solver.MatricesNonlinearSolver`) and one run
def nonlinear_mck_response(M, C, K, force, dt, *, elements, force_dofs=None, scheme=None,  # noqa: C901
                       substeps=1, outputs=None, quantities=("x", "v", "a"), modes=None,
                       backend="c", tol=1e-12, max_iter=30, solver="newton", compiled=False,
                       ground_acceleration=None, ground_velocity=None,
                       ground_displacement=None, influence=None, x0=None, v0=None,
                       accuracy=None, estimate=None, max_substeps=None,
                       **scheme_params) -> Response:
    """Forced response of M q'' + C q' + K q + L^T g = f with localized nonlinear elements.

    The equivalent of the source's ``nonlindxmck(F, fs, M, C, K, FD, nID, modes, resps)``.

    Parameters
    ----------
    M, C, K : (n, n) array_like
        The linear part (M nonsingular for the modal methods).

    force : array_like, shape (n_steps + 1, len(force_dofs))
        Force samples at t_k = k dt, linear between samples; the system starts at rest.

    dt : float
        Sample step, s.

    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen` (dtdyn.nonlinear._elements).

    force_dofs : sequence of int, optional
        0-based loaded DOFs (all DOFs when None).

    scheme : str, optional
        "modal_ramp", "modal_parabolic", "modal_quintic" (the element forces as the polynomial
        of degree 5 through the last six steps: sixth order, stable up to theta = 0.222, and an
        embedded error estimate in ``info["error_estimate"]`` with every run of the C
        backend: the next term of the polynomial carried by the dynamics linearized with the
        elements' tangent stiffness, relative to the largest |value| of each stored x, v, a),
        "modal_explicit" (the element forces extrapolated over the step by the polynomial of
        degree 6 through the last seven samples: seventh order, one evaluation of the element
        laws per step and no Newton solve, stable up to theta = |(Cw Bg) dg/dy| = 0.264, about
        a tenth of the quintic's stiffness; the same embedded estimate), or a one-step scheme
        of the integrator library ("newmark", "average_acceleration", "hht",
        "generalized_alpha", "wilson", ...); its parameters as keywords.
        Default: "modal_ramp", or with ``accuracy`` "auto": modal_explicit, then modal_quintic,
        driven by their embedded estimates; when an estimate is not confirmed by the next run
        (kinks, hysteresis, a start far from the asymptotic range) or a run fails (the explicit
        method beyond its stability limit), the next of them, then the Richardson sequence of
        modal_ramp from ``substeps``; "average_acceleration" when M is singular, and
        modal_ramp's sequence on the casadi backend (no embedded estimate there).
        ``info["scheme"]`` names the method that ran (docs/accuracy.md).

    substeps : int
        Steps per sample (h = dt / substeps); the force is interpolated linearly.

    outputs : sequence of int, optional
        Response DOFs (all by default).

    quantities : subset of ("x", "v", "a", "g", "z")
        What is stored; the others are None in the result. "g": the element forces, one
        column per element, at the samples (for the alpha methods, those of the step's
        equilibrium point); "z": the elements' internal states (Bouc-Wen z), one column each.

    modes : sequence of int, optional
        Modal schemes only: the modes kept (indices into the modes sorted by |s|).

    backend : {"c", "casadi"}
        "c": the generated loop (falls back to "casadi", with one warning, without a compiler).

    tol : float
        Newton accepts u = [w; z] when |r|_inf <= tol * (the largest |u|_inf or |Q|_inf of
        the record so far) or the next Newton step |J^-1 r|_inf <= tol * (the largest
        |u|_inf so far), in every backend.

    max_iter : int
        Newton iterations per step before NewtonError.

    solver : {"newton", "fast_newton"}
        CasADi rootfinder plugin (backend "casadi").

    compiled : bool
        Backend "casadi": generate C for the whole record function and compile it (cached).

    ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
        Support acceleration at the force's times, linear between samples: the DOFs are then
        relative to the support, loaded by f - M r a_g, and the result adds ``a_abs``
        (``force`` may be None).

    ground_velocity, ground_displacement : array_like, optional
        Instead of ``ground_acceleration`` (one ground record at most): the support velocity
        (m/s) or displacement (m), shaped like it, turned direction by direction into the
        acceleration record linear between samples whose motion passes through it
        (`ground_acceleration_from`); a displacement record also gives ``x_abs = x + r u_g``.

    influence : (N,) or (N, n_dir) array_like, optional
        r, each DOF's motion per unit support motion (default: ones).

    x0, v0 : (N,) array_like, optional
        Displacement and velocity at t_0 (rest when None); the elements start from the
        deformations they give, their internal states z from 0. The force polynomials of
        modal_parabolic, modal_quintic and modal_explicit then take the element forces before
        t_0 from the motion's smooth continuation (`dtdyn.nonlinear._startup`), so that they
        keep their order from the first step.

    accuracy : float, optional
        A target for the relative error instead of a sub-step count (distinct from ``tol``,
        the Newton tolerance of each step). With "modal_quintic" or "modal_explicit" (C
        backend) each run's embedded estimate decides: S_0 = ``substeps``, then
        S (estimate / accuracy)^(1/p) * 1.2 rounded up (p = 6, 7) until the estimate is
        <= ``accuracy`` and confirmed by the next run; a record of at least 16,000 samples
        is checked on its first 2,000 instead (to the target / 10) and then runs once, its
        own estimate trusted when it meets the target (`_accuracy.reach_embedded`,
        ``info["estimate_window"]``). Otherwise the
        record is run at S_0 = ``substeps``, 2 S_0,
        4 S_0, ... and the first solution whose error estimate is <= ``accuracy`` is returned.
        With p the scheme's order (modal_ramp 2, modal_parabolic 3, a one-step scheme its
        table order) and d_k = x_k - x_{k-1} between successive runs, the Richardson estimates
        are

            |e_k| ~ |d_k| / (2^p - 1),      x_R,k = x_k + d_k / (2^p - 1),
            |e_R,k| ~ |x_R,k - x_R,k-1| / (2^q - 1),

        q the observed order of x_R when it is within 0.25 of an integer p + 2 .. 2 p, else
        min(p + 1, observed order) (`accuracy.extrapolation_order`),

        |.| the largest |difference| over time and columns relative to the largest |value|,
        taken over the stored quantities (x, v, a, g, z). The extrapolation x_R is used only
        when the observed order log2(|d_{k-1}| / |d_k|) is within 0.25 of p and that of x_R
        (four levels) is at least p + 0.5; the plain estimate uses min(p, observed order)
        (`dtdyn.nonlinear._accuracy`). ``info`` then holds
        ``error_estimate``, ``substeps`` (of the returned run), ``extrapolated``,
        ``observed_order``, ``accuracy_met``, the times summed over every run, and
        ``estimate_time`` (the estimates' own work). A run that
        fails (NewtonError, a modal step beyond its stability limit) restarts at twice its
        sub-steps; when every run fails, the last failure's type is raised naming the target
        and the sub-steps tried.

    estimate : bool, optional
        True without a target: also run ``substeps`` / 2 (``substeps`` even) or 2 ``substeps``
        (odd) and report the estimate of this run's error in ``info["error_estimate"]`` (a
        number); when the ``substeps`` / 2 run fails (NewtonError, a modal step beyond its
        stability limit) the 2 ``substeps`` one is used. modal_quintic and modal_explicit on
        the C backend estimate within their own run (embedded) unless ``estimate=False``,
        which skips that work (30 % to 40 % of their run on P4). With ``accuracy`` the
        estimate is always reported (``estimate=True`` adds nothing; False is an error).

    max_substeps : int, optional
        ``accuracy`` only: the most sub-steps tried (default: as many as keep DOFs x
        sub-steps x samples within 10^8, at least 256); beyond them a DtdynAccuracyWarning
        names the target, the estimate reached and the sub-steps, and the best solution is
        returned.

    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    Response
        ``t``, ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)); ``info`` holds the
        scheme, the construction, compile and run times, and the Newton statistics (iterations
        per step, largest final residual).

    Raises
    ------
    NewtonError
        A step did not converge (or went non-finite): the message names the step, its time and
        the residual. More ``substeps`` (or a ``Gap`` with ``smoothing``) usually cure it.
    DtdynStepStabilityError
        A modal step beyond its stability limit for the elements' tangent stiffness.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.eye(2), 0.1 * np.eye(2), np.array([[2e3, -1e3], [-1e3, 1e3]])
    >>> r = dd.nonlinear_mck_response(M, C, K, np.ones(2001), 1e-3, force_dofs=[1],
    ...                           elements=[dd.Cubic(0, k3=1e6)], scheme="modal_parabolic")
    >>> r.x.shape
    (2001, 2)
    """
    if estimate is not None and not isinstance(estimate, (bool, np.bool_)):
        raise ValueError(f"estimate must be True or False, got {estimate!r} (a relative error "
                         f"target is accuracy=...)")
    estimate = None if estimate is None else bool(estimate)
    if accuracy is not None and estimate is False:
        raise ValueError("estimate=False with accuracy: an accuracy target always estimates "
                         "(drop estimate, or give substeps instead of accuracy)")
    if scheme is None:
        scheme = "modal_ramp" if accuracy is None else "auto"
    if scheme == "auto" and (accuracy is None or scheme_params):
        raise ValueError("scheme 'auto' picks the method for an accuracy target: it needs "
                         "accuracy=... and takes no scheme parameters"
                         + (f" (got {', '.join(sorted(scheme_params))})" if scheme_params else ""))
    if accuracy is not None or estimate:
        from dtdyn.nonlinear import _accuracy as acc
        target = None if accuracy is None else acc.check_accuracy(accuracy)
        S0 = validate.step_count("substeps", substeps)
        # the record's steps: the force's or the ground's
        record = next((r for r in (force, ground_acceleration, ground_velocity,
                                   ground_displacement) if r is not None), None)
        n_steps = np.shape(record)[0] - 1 if np.ndim(record) else 0
        if max_substeps is None:
            max_substeps = max(MAX_SUBSTEPS,
                               STEP_BUDGET // max(n_steps * np.shape(M)[0], 1))
        cap = validate.step_count("max_substeps", max_substeps)
        auto = scheme == "auto"
        if auto:
            scheme = (acc.AUTO_SINGULAR_M if not _invertible(M) else
                      acc.AUTO if backend == "c" else acc.AUTO_THEN)
            if modes is not None and scheme == acc.AUTO_SINGULAR_M:
                raise ValueError(f"modes = {modes!r} selects modal filters, but M is singular: "
                                 f"scheme 'auto' runs {acc.AUTO_SINGULAR_M!r} on all DOFs "
                                 "(remove modes)")
        acc.scheme_order(scheme, scheme_params)

        def run(S, method=scheme, window=None, estimate=None):
            """The run at S sub-steps; ``window``: of the record's first samples only;
            ``estimate=False``: without its embedded estimate (a run that only confirms)."""
            def cut(r):
                return r if window is None or r is None else np.asarray(r)[:window]
            return nonlinear_mck_response(
                M, C, K, cut(force), dt, elements=elements, force_dofs=force_dofs,
                scheme=method, substeps=S, outputs=outputs, quantities=quantities, modes=modes,
                backend=backend, tol=tol, max_iter=max_iter, solver=solver, compiled=compiled,
                ground_acceleration=cut(ground_acceleration),
                ground_velocity=cut(ground_velocity),
                ground_displacement=cut(ground_displacement), influence=influence, x0=x0,
                v0=v0, estimate=estimate, **scheme_params)
        if S0 > cap and target is not None:
            raise ValueError(f"substeps ({S0}) must be <= max_substeps ({cap}) with accuracy")
        if scheme in POLYNOMIAL and backend == "c":  # its runs estimate themselves
            if target is None:
                return run(S0)
            then = (partial(run, method=acc.AUTO_THEN), acc.AUTO_THEN, {}) if auto else None
            after = (partial(run, method=acc.AUTO_NEXT), acc.AUTO_NEXT) if auto else None
            # one run of the record trusted after a window only for smooth element laws: a
            # kink the window does not reach would leave the record's estimate unchecked
            window = acc.probe_window(n_steps + 1) if _smooth(elements) else None
            probe = None if window is None else (partial(run, window=window), window)
            return acc.reach_embedded(run, target, S0, cap, scheme, scheme_params, then, after,
                                      probe)
        if target is None:
            return acc.estimate_only(run, S0, scheme, scheme_params)
        # the polynomial methods' nominal order (6, 7) is trusted only as far as the runs show it
        return acc.reach(run, target, S0, cap, scheme, scheme_params,
                         observed=scheme in POLYNOMIAL)
    from dtdyn.linear._mck import Matrices
    from dtdyn.nonlinear._solver import LAZY, MatricesNonlinearSolver

    t0 = time.perf_counter()
    solver_ = MatricesNonlinearSolver(
        Matrices(M, C, K), dt, elements=elements, scheme=scheme, substeps=substeps,
        outputs=outputs, quantities=quantities, modes=modes, backend=backend, tol=tol,
        max_iter=max_iter, solver=solver, compiled=compiled, estimate=estimate, force_dofs=LAZY,
        **scheme_params)
    t1 = time.perf_counter()
    res = solver_.run(force, force_dofs=force_dofs, x0=x0, v0=v0,
                      ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
                      ground_displacement=ground_displacement, influence=influence)
    res.info["setup_time"] += t1 - t0  # the solver's construction is this call's setup too
    return res


def _smooth(elements) -> bool:
    """Whether every element's law is smooth in its deformations (Cubic, Polynomial, a Gap with
    smoothing > 0): not a Gap's kink, Bouc-Wen's sign(y') or a Law, which may hold either."""
    from dtdyn.nonlinear._elements import Cubic, Gap, Polynomial
    try:
        return all(isinstance(el, (Cubic, Polynomial))
                   or (isinstance(el, Gap) and el.smoothing > 0) for el in elements)
    except TypeError:  # not a sequence: the run names the problem
        return False


def _invertible(M) -> bool:
    """M nonsingular by `linalg.dense_lu`'s test; True when M is not a square matrix of
    numbers (the run then names the problem)."""
    try:
        A = linalg.square_matrix("M", M)
    except (TypeError, ValueError):
        return True
    try:
        linalg.dense_lu(A, "M")
    except ValueError:
        return False
    return True


def _stability_error(method, k, S, fs, theta):
    n, j = divmod(k, S)
    where = f"sample {n}" + (f", sub-step {j} of {S}" if S > 1 else "")
    limit = THETA_LIMIT[method]
    more = int(np.ceil(S * np.sqrt(theta / limit)))
    measure = "|(Cw Bg) dg/dy|" if method in EXPLICIT else "|B0 dg/dy|"
    raise DtdynStepStabilityError(
        f"scheme {method!r} is unstable at step {k} ({where}, t = {k / (fs * S):.6g} s): the "
        f"elements' tangent stiffness gives theta = {measure} = {theta:.3g} > {limit:g}; use "
        f"substeps >= {more} or an unconditionally stable scheme (scheme='newmark')")


def _newton_error(k, S, fs, resid, max_iter, evaluated=False):
    """NewtonError at step k; ``evaluated``: the step had no Newton solve (modal_explicit
    without internal states), its element forces were not finite (resid: their largest |g|)."""
    n, j = divmod(k, S)
    where = f"sample {n}" + (f", sub-step {j} of {S}" if S > 1 else "")
    if evaluated:
        raise NewtonError(f"the element forces are not finite at step {k} ({where}, "
                          f"t = {k / (fs * S):.6g} s): |g| = {resid:.3g}; try more substeps")
    raise NewtonError(f"Newton did not converge at step {k} ({where}, t = {k / (fs * S):.6g} s): "
                      f"residual {resid:.3g} after at most {max_iter} iterations; try more "
                      "substeps (or smoothing for a Gap)")


# the solver of Matrices with elements, registered for dtdyn.linear (`_solver.register`)
from dtdyn.nonlinear import _solver as _solver  # noqa: E402,F401
