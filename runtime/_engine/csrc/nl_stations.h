/* nl_stations.h: hand-written C, compiled as it is (dtdyn/_engine/csrc); generated/nl_stations.c
   adds the entry point of the signature spec (dtdyn.derive.c_api) */
/*
 * Nonlinear response of a beam or a shaft (tree) with localized elements over a whole record:
 * the loop of dtdyn.nonlinear._chain.condensed_response in C, as nl_chain.h is for chains, around
 * the model's own linear step. Per (sub)step, with the model's history H (nh rows of n doubles):
 *
 *     H <- step(H; loads L(f_a, g_k), L(f_b, 0))     the linear step, g_{k+1} = 0
 *     Q  = W(H)                                      element deformations [y; y']
 *     r(u) = [w - Q - Dwg g(u); z - z_old - h/2 (z'(u) + z'_old)] = 0 by Newton, u = [w; z]
 *     H <- H + sum_e g_e U_e                         U_e: the step's response to element e's
 *                                                    unit load pair from rest
 *
 * The step (dims[0]):
 *   DTDYN_NL_STATIONS_BEAM: block_chain_loop_run (block_chain.h, beam_response's kernel) for
 *     one step, on its layout: a history row is 2 P doubles (P = BC_STRIDE(N), N nodes;
 *     component 0 of every node, then component 1), with 8 zeros before H's first row (the
 *     caller's buffer); the effective matrix factorized once by the caller
 *     (dtdyn_block_chain_factor, in the operator's mats);
 *   DTDYN_NL_STATIONS_SHAFT: the tree sweep dtdyn_shaft_<scheme> (shaft_response's kernel),
 *     called through a pointer for one step; a history row is N doubles (disks).
 * The element law's residual, its Jacobian, g and z' come from `nl_residual` (CasADi's code
 * generation, appended to this source); Newton accepts u by the rule of every backend
 * (newton_solve in newton.h, or newton_kept with its LU factors kept: dims' newton). Returns
 * 0; DTDYN_STOPPED (stop.h) when stopped; 1 when Newton failed at step fail[0] with residual
 * stats[3]; 4 when the step kernel failed (its code in fail[0]); DTDYN_ERR_WORK (nothing
 * written) when work or iwork is shorter than it needs (dtdyn_nl_stations_work,
 * nl_residual_work).
 */
#ifndef DTDYN_NL_STATIONS_H
#define DTDYN_NL_STATIONS_H
#include "c_api.h"
#include <math.h>
#include <stddef.h>

#include "stop.h"
#include "flush_subnormals.h"
#include "block_chain.h"
#include "nl_elements.h"

/*
 * dims: kind (DTDYN_NL_STATIONS_BEAM or _SHAFT), N (nodes or disks), nh, n_loaded, nf (force
 *       columns), ne, nw, nz, no, n_samples, S, max_iter, ix, iv, ia (the rows of x0, v0, a0 in
 *       H), then the beam's n_shift (its scheme's lags) or the shaft's form (DTDYN_FORM_*),
 *       then newton (DTDYN_NEWTON_PLAIN: newton_solve; DTDYN_NEWTON_KEPT_LU: newton_kept),
 *       then the beam's refinement (1: its operator's mats hold the refinement's data,
 *       block_chain.h, and the step's work has BC_REFINE_ROWS P doubles more; 0: not).
 * idx:  loaded (n_loaded, ascending: the step's DOFs, the beam's as node-system indices
 *       2 i + c), pf (nf), pi (ne), pj (ne; -1: ground) as positions in loaded; ei, ej (ne; -1:
 *       ground), outs (no) as offsets in a history row; then the beam's shift (n_shift pairs)
 *       and rows (3), or the shaft's parent (N).
 * mats: U (ne x nh x n), par ([Dwg; h], Dwg nw x ne column-major), force (n_samples x nf,
 *       linear between samples); then the beam's L (6 x nh), c_u (3), {w0, w1} and its
 *       operator's 4 + nh matrices (K, C, M, fac, B_0 ..; block_chain.h), or the shaft's gu,
 *       gS, gR, m, k, c, kg, cg, params (dtdyn_shaft_<scheme>'s arguments).
 * state: H, u (nw + nz: the last solution), g (ne), rate (nz); updated in place.
 * out:  x, v, a (n_samples x no each), then g (n_samples x ne) and z (n_samples x nz), NULL
 *       when not stored.
 * stats: [max iterations, total iterations, max final residual, failing residual, LU
 *        factorizations of newton_kept (0 with newton_solve)].
 * work: n_work >= dtdyn_nl_stations_work(dims) doubles: the step's (the beam's
 *       DTDYN_BLOCK_CHAIN_ROWS (P + DTDYN_BLOCK_CHAIN_GAP) (+ BC_REFINE_ROWS P refined),
 *       64-byte aligned as the caller gives
 *       work; the shaft's DTDYN_SHAFT_ROWS N), then 2 n_loaded + nw + 2 nz + (nw + nz)(nw + nz
 *       + 1) + ne + nz, with newton_kept (nw + nz)(nw + nz + 1) more (nl_stations_scratch),
 *       then the CasADi work; iwork: n_iwork >= CasADi's (nl_residual_work).
 */

/* doubles of a history row */
static long nl_stations_row(const long *dims)
{
    return dims[0] == DTDYN_NL_STATIONS_BEAM ? 2 * BC_STRIDE(dims[1]) : dims[1];
}

/* the step kernel's work */
static long nl_stations_step_work(const long *dims)
{
    if (dims[0] == DTDYN_NL_STATIONS_BEAM) /* with the refinement's rows when refined */
        return DTDYN_BLOCK_CHAIN_ROWS * (BC_STRIDE(dims[1]) + DTDYN_BLOCK_CHAIN_GAP)
               + (dims[17] ? BC_REFINE_ROWS * BC_STRIDE(dims[1]) : 0);
    return DTDYN_SHAFT_ROWS * dims[1];
}

/* the doubles of the work before CasADi's: the step's, the loads of the step's two ends (frc),
   then Q, z_old, z'_old, r, J, g, z', with newton_kept its step d and the kept factors */
static long nl_stations_scratch(const long *dims)
{
    return nl_stations_step_work(dims) + 2 * dims[3]
           + nl_scratch(dims[5], dims[6], dims[7], dims[16] == DTDYN_NEWTON_KEPT_LU);
}

long dtdyn_nl_stations_work(const long *dims)
{
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    return nl_stations_scratch(dims) + (long)sz_w;
}

/* one linear step of the model from H with the loads frc (two rows: the step's ends) */
static int nl_stations_step(const long *dims, shaft_fn sweep, const long *const *idx,
                            const double *const *mats, const double *frc, double *H, double h,
                            double *swork, int first)
{
    const long N = dims[1], nh = dims[2], nl = dims[3];
    if (dims[0] == DTDYN_NL_STATIONS_BEAM)
        return block_chain_loop_run(N, nh, 1, nl, idx[0], frc, mats + 6, mats[3], mats[4],
                                    mats[5][0], mats[5][1], dims[15], idx[7], idx[8], H, 0, NULL,
                                    NULL, NULL, NULL, swork, nl_stations_step_work(dims));
    /* the tree's Riccati factors once, in swork (the beam's: in the operator) */
    return sweep((int)dims[15], first ? DTDYN_SWEEP_STABLE : DTDYN_SWEEP_REUSE, N, 1, idx[7],
                 mats[3], mats[4], mats[5], mats[6], mats[7], mats[8], mats[9], mats[10], h,
                 mats[11], nl, idx[0], frc, H, 0, NULL, NULL, NULL, NULL, swork,
                 nl_stations_step_work(dims));
}

DTDYN_LOOP int nl_stations_run(const long *dims, shaft_fn sweep, const long *const *idx,
                               const double *const *mats, double *restrict H,
                               double *restrict u, double *restrict g, double *restrict rate,
                               double *const *out, double h, double tol, double *stats,
                               long *fail, double *restrict work, long n_work,
                               nl_int *restrict iwork, long n_iwork)
{
    const long nh = dims[2], nl = dims[3], nf = dims[4], ne = dims[5];
    const long nw = dims[6], nz = dims[7], no = dims[8], n_samples = dims[9], S = dims[10];
    const long max_iter = dims[11], ix = dims[12], iv = dims[13], ia = dims[14];
    const long n = nl_stations_row(dims), nu = nw + nz, size = nh * n;
    const int kept = dims[16] == DTDYN_NEWTON_KEPT_LU;
    const long *pf = idx[1], *pi = idx[2], *pj = idx[3], *ei = idx[4], *ej = idx[5];
    const long *outs = idx[6];
    const double *U = mats[0], *par = mats[1], *force = mats[2];
    double *swork = work, *frc = swork + nl_stations_step_work(dims), *Q = frc + 2 * nl, *cw;
    long piv[kept && nu > 0 ? nu : 1];
    nl_step st;
    const double *xs = H + ix * n, *vs = H + iv * n, *as = H + ia * n;
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    long k, j, e, o;
    int rc;
    cw = nl_step_init(&st, ne, nw, nz, max_iter, kept, h, tol, par, par, u, g, rate, Q, piv);
    (void)lu_apply_t; /* newton.h's transposed solve: nl_loop.c's estimate */
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    if (dims[1] < 0 || (dims[0] != DTDYN_NL_STATIONS_BEAM && sweep == NULL)
        || cw - work != nl_stations_scratch(dims) || n_work < dtdyn_nl_stations_work(dims)
        || n_iwork < (long)sz_iw)
        return DTDYN_ERR_WORK;
    stats[0] = stats[1] = stats[2] = stats[3] = stats[4] = 0.0;
    for (k = 0; k < n_samples; ++k) {
        const double *f0 = force + k * nf, *f1 = f0 + nf;
        for (o = 0; o < no; ++o) {
            out[0][k * no + o] = xs[outs[o]];
            out[1][k * no + o] = vs[outs[o]];
            out[2][k * no + o] = as[outs[o]];
        }
        if (out[3])
            copy(ne, g, out[3] + k * ne);
        if (out[4])
            copy(nz, u + nw, out[4] + k * nz);
        if (k + 1 == n_samples)
            break;
        if ((k & 63) == 0 && dtdyn_stop_flag) /* a sample sweeps the whole model */
            return DTDYN_STOPPED;
        for (j = 0; j < S; ++j) {
            const double ca = (double)j / (double)S, cb = (double)(j + 1) / (double)S;
            nl_loads(nl, nf, ne, pf, pi, pj, f0, f1, ca, cb, g, frc);
            rc = nl_stations_step(dims, sweep, idx, mats, frc, H, h, swork, k == 0 && j == 0);
            if (rc) {
                fail[0] = rc;
                return 4;
            }
            for (e = 0; e < ne; ++e) {
                Q[e] = xs[ei[e]] - (ej[e] >= 0 ? xs[ej[e]] : 0.0);
                if (nw > ne)
                    Q[ne + e] = vs[ei[e]] - (ej[e] >= 0 ? vs[ej[e]] : 0.0);
            }
            if (nl_solve(&st, iwork, cw, stats)) {
                fail[0] = k * S + j;
                return 1;
            }
            nl_add_forces(size, ne, g, U, H);
        }
    }
    return 0;
}
#endif /* DTDYN_NL_STATIONS_H */
