/* nl_chain.h: hand-written C, compiled as it is (dtdyn/_engine/csrc); generated/nl_chain.c
   adds the entry point of the signature spec (dtdyn.derive.c_api) */
/*
 * Nonlinear response of a DT-TMM chain with localized elements over a whole record: the loop of
 * dtdyn.nonlinear.chain in C. Per (sub)step, with the chain history H (nh x N rows):
 *
 *     H <- sweep(H; loads L(f_a, g_k), L(f_b, 0))     the scheme's stable DT-TMM step, g_{k+1} = 0
 *     Q  = W(H)                                      element deformations [y; y']
 *     r(u) = [w - Q - Dwg g(u); z - z_old - h/2 (z'(u) + z'_old)] = 0 by Newton, u = [w; z]
 *     H <- H + sum_e g_e U_e                         U_e: the step's response to element e's
 *                                                    unit load pair from rest
 *
 * L(f, g) puts the external forces on their masses and -g_e, +g_e on the element's nodes i, j;
 * W(H)_e = x_i - x_j (and v_i - v_j when an element needs y'). The sweep is the generated chain
 * kernel of the scheme, called through a pointer one step at a time; after the first call it
 * reuses the Riccati factors left in its work (DTDYN_SWEEP_REUSE). The residual, its Jacobian, g and
 * z' come from `nl_residual` (CasADi code generation of the element laws, appended to this
 * source). Newton accepts u by the rule of every backend (newton_solve in newton.h; with dims'
 * newton = DTDYN_NEWTON_KEPT_LU, newton_kept: the LU factors kept from step to step).
 * Returns 0; DTDYN_STOPPED (stop.h) when stopped; 1 when Newton failed (not converged in
 * max_iter iterations, singular Jacobian or non-finite) at step fail[0] with residual
 * stats[3]; 4 when the chain kernel failed; DTDYN_ERR_WORK (nothing written) when work or
 * iwork is shorter than it needs (dtdyn_nl_chain_work, nl_residual_work).
 */
#ifndef DTDYN_NL_CHAIN_H
#define DTDYN_NL_CHAIN_H
#include "c_api.h"
#include <math.h>
#include <string.h>

#include "stop.h"
#include "flush_subnormals.h"

#include "nl_elements.h"

/*
 * dims: N, nh, n_loaded, nf (force columns), ne, nw, nz, no, n_samples, S, max_iter, form,
 *       ix, iv, ia (the rows of x0, v0, a0 in H), newton (DTDYN_NEWTON_PLAIN: newton_solve;
 *       DTDYN_NEWTON_KEPT_LU: newton_kept, the LU factors kept from step to step).
 * idx:  loaded (n_loaded), pf (nf), pi (ne), pj (ne; -1: ground) as positions in loaded;
 *       ei, ej (ne; -1: ground) as masses; outputs (no).
 * mats: m, k, c, kg, cg (the chain kernel's), params (the scheme's), U (ne x nh x N), par ([Dwg; h], Dwg nw x ne
 *       column-major), force (n_samples x nf, linear between samples).
 * state: H, u (nw + nz: the last solution), g (ne), rate (nz); updated in place.
 * out:  x, v, a (n_samples x no each), then g (n_samples x ne) and z (n_samples x nz), NULL
 *       when not stored.
 * stats: [max iterations, total iterations, max final residual, failing residual, LU
 *       factorizations of newton_kept (0 with newton_solve)].
 * work: n_work >= dtdyn_nl_chain_work(dims) doubles: DTDYN_CHAIN_ROWS_STABLE N (chain kernel)
 *       + 2 n_loaded + nw + 2 nz + (nw + nz)(nw + nz + 1) + ne + nz, with newton_kept
 *       (nw + nz)(nw + nz + 1) more (nl_chain_scratch), then the CasADi work; iwork:
 *       n_iwork >= CasADi's (nl_residual_work).
 */
/* the doubles of nl_chain_run's work before CasADi's: the chain kernel's rows, the loads of
   the step's two ends (frc), then Q, z_old, z'_old, r, J, g, z', with newton_kept its step d
   and the kept factors */
static long nl_chain_scratch(const long *dims)
{
    return DTDYN_CHAIN_ROWS_STABLE * dims[0] + 2 * dims[2]
           + nl_scratch(dims[4], dims[5], dims[6], dims[15] == DTDYN_NEWTON_KEPT_LU);
}

long dtdyn_nl_chain_work(const long *dims)
{
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    return nl_chain_scratch(dims) + (long)sz_w;
}

DTDYN_LOOP int nl_chain_run(const long *dims, chain_fn sweep, const long *const *idx,
                            const double *const *mats, double *restrict H, double *restrict u,
                            double *restrict g, double *restrict rate, double *const *out, double h,
                            double tol, double *stats, long *fail, double *restrict work,
                            long n_work, nl_int *restrict iwork, long n_iwork)
{
    const long N = dims[0], nh = dims[1], nl = dims[2], nf = dims[3], ne = dims[4];
    const long nw = dims[5], nz = dims[6], no = dims[7], n_samples = dims[8], S = dims[9];
    const long max_iter = dims[10], ix = dims[12], iv = dims[13], ia = dims[14];
    const long nu = nw + nz, size = nh * N;
    const int kept = dims[15] == DTDYN_NEWTON_KEPT_LU;
    const int form = (int)dims[11];
    const long *loaded = idx[0], *pf = idx[1], *pi = idx[2], *pj = idx[3], *ei = idx[4];
    const long *ej = idx[5], *outs = idx[6];
    const double *m = mats[0], *k = mats[1], *c = mats[2], *kg = mats[3], *cg = mats[4];
    const double *params = mats[5], *U = mats[6], *par = mats[7], *force = mats[8];
    double *cwork = work, *frc = cwork + DTDYN_CHAIN_ROWS_STABLE * N, *Q = frc + 2 * nl, *cw;
    long piv[kept && nu > 0 ? nu : 1];
    nl_step st;
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    long n, j, e, o;
    cw = nl_step_init(&st, ne, nw, nz, max_iter, kept, h, tol, par, par, u, g, rate, Q, piv);
    (void)lu_apply_t; /* newton.c's transposed solve: nl_loop.c's estimate */
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    if (N < 0 || cw - work != nl_chain_scratch(dims) || n_work < dtdyn_nl_chain_work(dims)
        || n_iwork < (long)sz_iw)
        return DTDYN_ERR_WORK;
    stats[0] = stats[1] = stats[2] = stats[3] = stats[4] = 0.0;
    for (n = 0; n < n_samples; ++n) {
        const double *f0 = force + n * nf, *f1 = f0 + nf;
        for (o = 0; o < no; ++o) {
            out[0][n * no + o] = H[ix * N + outs[o]];
            out[1][n * no + o] = H[iv * N + outs[o]];
            out[2][n * no + o] = H[ia * N + outs[o]];
        }
        if (out[3])
            copy(ne, g, out[3] + n * ne);
        if (out[4])
            copy(nz, u + nw, out[4] + n * nz);
        if (n + 1 == n_samples)
            break;
        if ((n & 63) == 0 && dtdyn_stop_flag) /* a sample sweeps the whole chain */
            return DTDYN_STOPPED;
        for (j = 0; j < S; ++j) {
            const double ca = (double)j / (double)S, cb = (double)(j + 1) / (double)S;
            nl_loads(nl, nf, ne, pf, pi, pj, f0, f1, ca, cb, g, frc);
            if (sweep(form, (n == 0 && j == 0) ? DTDYN_SWEEP_STABLE : DTDYN_SWEEP_REUSE, N, 1, m, k, c, kg, cg, h, params, nl, loaded,
                      frc, H, 0, NULL, NULL, NULL, NULL, cwork, DTDYN_CHAIN_ROWS_STABLE * N, NULL, NULL,
                      1))
                return 4;
            for (e = 0; e < ne; ++e) {
                Q[e] = H[ix * N + ei[e]] - (ej[e] >= 0 ? H[ix * N + ej[e]] : 0.0);
                if (nw > ne)
                    Q[ne + e] = H[iv * N + ei[e]] - (ej[e] >= 0 ? H[iv * N + ej[e]] : 0.0);
            }
            if (nl_solve(&st, iwork, cw, stats)) {
                fail[0] = n * S + j;
                return 1;
            }
            nl_add_forces(size, ne, g, U, H);
        }
    }
    return 0;
}
#endif /* DTDYN_NL_CHAIN_H */
