/* mck_loop.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_MCK_LOOP_H
#define DTDYN_MCK_LOOP_H
#include "c_api.h"
#include "stop.h"
#include "flush_subnormals.h"
/*
 * The time loop of mck_response and beam_response (any one-step or multistep scheme of the
 * generated table, either form), for dense and sparse M, C, K alike. Each DOF's x, v, a at the
 * equilibrium point are x = p u + q, v = r u + s, a = alpha u + b in the step's unknown u. Per
 * step, with the history H (n_hist rows of n: x0, v0, a0 and lags) and the scheme's coefficient
 * rows L (6 x n_hist: q, s, b, x1, v1, a1 expanded over the history rows, from
 * dttmm_sweep.expanded) and c_u (x1_u, v1_u, a1_u):
 *
 *     F = w0 f_k + w1 f_{k+1}                                   (on the loaded DOFs)
 *     u = (alpha M + r C + p K)^-1 (F - K q - C s - M b)        (factorized once)
 *     x1, v1, a1 = L_{x1,v1,a1} H + c_u u
 *
 * then the lags shift (H[dst] = H[src] for the pairs in order) and x0, v0, a0 take x1, v1, a1.
 * (The acceleration form has u = a_e, alpha = 1, b = 0: M is then not needed, val[2] NULL.)
 *
 * Only the products and the solve depend on the storage; they read
 *   idx = {K_ptr, K_idx, C_ptr, C_idx, M_ptr, M_idx, L_ptr, L_idx, U_ptr, U_idx, perm_r,
 *          perm_c},
 *   val = {K, C, M, L, U, U_diag}:
 * K, C and M each dense row-major n x n (its ptr NULL) or CSR (ptr n + 1, idx, val); the
 * factors, by ``solver``:
 *   0  dense: val[3] the LU of LAPACK's getrf, row-major, idx[10] its 0-based pivots;
 *   1  sparse as SuperLU's  Pr A Pc = L U  (L strictly lower, U strictly upper, both CSR;
 *      U_diag the reciprocals of U's diagonal; the unit diagonal of L implied; perm_r, perm_c
 *      as scipy's splu: (Pr b)[perm_r[i]] = b[i], x[i] = z[perm_c[i]]);
 *   2  block tridiagonal in 2 x 2 node blocks (n even, DOFs node by node), condensed from the
 *      last node (the matrix Riccati sweep of a beam, block_solve): val[3] P_i^-1, val[4] G_i,
 *      val[5] F_i, each 2 x 2 row-major.
 * Indices are long (64-bit).
 * Outputs (NULL: not stored) get row k + 1 of the stored DOFs. work: n_work >= DTDYN_MCK_ROWS n
 * doubles, rows of n (DTDYN_MCK_ROW_*, generated/c_api.h); nothing is allocated. Returns 0,
 * DTDYN_STOPPED when stopped, DTDYN_ERR_WORK (nothing written) when n_work is too short.
 */
#include <stddef.h>

/* y -= A x, A dense row-major (ptr NULL: val) or CSR (ptr, idx, val) */
static void sub_product(long n, const long *restrict ptr, const long *restrict idx,
                        const double *restrict val, const double *restrict x,
                        double *restrict y)
{
    long i, j;
    if (ptr == NULL) {
        for (i = 0; i < n; ++i) {
            const double *Ai = val + i * n;
            double acc = 0.0;
            for (j = 0; j < n; ++j)
                acc += Ai[j] * x[j];
            y[i] -= acc;
        }
        return;
    }
    for (i = 0; i < n; ++i) {
        double acc = 0.0;
        for (j = ptr[i]; j < ptr[i + 1]; ++j)
            acc += val[j] * x[idx[j]];
        y[i] -= acc;
    }
}

/* b = A^-1 b by the dense LU of getrf (rows interchanged in order, L y = b, U x = y) */
static void dense_solve(long n, const double *restrict LU, const long *restrict piv,
                        double *restrict b)
{
    long i, j;
    for (i = 0; i < n; ++i) {
        const long p = piv[i];
        if (p != i) {
            const double t = b[i];
            b[i] = b[p];
            b[p] = t;
        }
    }
    for (i = 1; i < n; ++i) { /* unit diagonal */
        double s = b[i];
        for (j = 0; j < i; ++j)
            s -= LU[i * n + j] * b[j];
        b[i] = s;
    }
    for (i = n - 1; i >= 0; --i) {
        double s = b[i];
        for (j = i + 1; j < n; ++j)
            s -= LU[i * n + j] * b[j];
        b[i] = s / LU[i * n + i];
    }
}

/* b = A^-1 b for A block tridiagonal in 2 x 2 node blocks D_i (diagonal), E_i = A[i, i + 1],
   F_i = A[i + 1, i], condensed from the last node N - 1 once per run:
       P_{N-1} = D_{N-1},   G_i = E_i P_{i+1}^-1,   P_i = D_i - G_i F_i
   (P_i: the dynamic stiffness of nodes i .. N - 1 condensed onto node i). Per solve the load
   is condensed the same way, y_i = b_i - G_i y_{i+1}, then u_0 = P_0^-1 y_0 and
   u_{i+1} = P_{i+1}^-1 (y_{i+1} - F_i u_i). Pinv, G, F: 4 doubles per node, row-major. */
static void block_solve(long n, const double *restrict Pinv, const double *restrict G,
                        const double *restrict F, double *restrict b)
{
    const long nodes = n / 2;
    long i;
    for (i = nodes - 2; i >= 0; --i) {
        const double *g = G + 4 * i, *y1 = b + 2 * i + 2;
        double *y = b + 2 * i;
        y[0] -= g[0] * y1[0] + g[1] * y1[1];
        y[1] -= g[2] * y1[0] + g[3] * y1[1];
    }
    for (i = 0; i < nodes; ++i) {
        const double *p = Pinv + 4 * i;
        double *y = b + 2 * i, t0 = y[0], t1 = y[1];
        if (i > 0) {
            const double *f = F + 4 * (i - 1), *u = b + 2 * i - 2;
            t0 -= f[0] * u[0] + f[1] * u[1];
            t1 -= f[2] * u[0] + f[3] * u[1];
        }
        y[0] = p[0] * t0 + p[1] * t1;
        y[1] = p[2] * t0 + p[3] * t1;
    }
}

/* b = A^-1 b by the sparse factors Pr A Pc = L U (row-oriented substitutions; z: n) */
static void sparse_solve(long n, const long *const *idx, const double *const *val,
                         double *restrict b, double *restrict z)
{
    const long *Lp = idx[6], *Lj = idx[7], *Up = idx[8], *Uj = idx[9];
    const long *perm_r = idx[10], *perm_c = idx[11];
    const double *Lx = val[3], *Ux = val[4], *Ud = val[5];
    long i, p;
    for (i = 0; i < n; ++i)
        z[perm_r[i]] = b[i];
    for (i = 0; i < n; ++i) { /* L y = Pr b */
        double acc = z[i];
        for (p = Lp[i]; p < Lp[i + 1]; ++p)
            acc -= Lx[p] * z[Lj[p]];
        z[i] = acc;
    }
    for (i = n - 1; i >= 0; --i) { /* U z = y; Ud holds 1 / diag(U) */
        double acc = z[i];
        for (p = Up[i]; p < Up[i + 1]; ++p)
            acc -= Ux[p] * z[Uj[p]];
        z[i] = acc * Ud[i];
    }
    for (i = 0; i < n; ++i)
        b[i] = z[perm_c[i]];
}

DTDYN_LOOP int mck_loop_run(int solver, long n, long n_hist, long n_steps, long n_loaded,
                            const long *restrict loaded, const double *restrict force,
                            const long *const *idx, const double *const *val,
                            const double *restrict L, const double *restrict c_u, double w0,
                            double w1, long n_shift, const long *restrict shift,
                            const long *restrict rows, double *restrict H, long n_out,
                            const long *restrict out_idx, double *restrict xo, double *restrict vo,
                            double *restrict ao, double *restrict work, long n_work)
{
    double *q = work + DTDYN_MCK_ROW_Q * n, *s = work + DTDYN_MCK_ROW_S * n;
    double *rhs = work + DTDYN_MCK_ROW_RHS * n, *upd = work + DTDYN_MCK_ROW_UPDATE * n;
    double *z = work + DTDYN_MCK_ROW_Z * n, *bm = work + DTDYN_MCK_ROW_B * n;
    long k, i, j, h, o;
    if (n < 0 || n_work < DTDYN_MCK_ROWS * n)
        return DTDYN_ERR_WORK;
    for (k = 0; k < n_steps; ++k) {
        const double *f0 = force + k * n_loaded, *f1 = f0 + n_loaded;
        if ((k & 1023) == 0 && dtdyn_stop_flag)
            return DTDYN_STOPPED;
        for (i = 0; i < n; ++i) { /* row by row over the history: each sum in the order of h */
            q[i] = 0.0;
            s[i] = 0.0;
            bm[i] = 0.0;
            rhs[i] = 0.0;
        }
        for (h = 0; h < n_hist; ++h) {
            const double lq = L[0 * n_hist + h], ls = L[1 * n_hist + h], *Hh = H + h * n;
            for (i = 0; i < n; ++i) {
                q[i] += lq * Hh[i];
                s[i] += ls * Hh[i];
            }
            if (val[2]) { /* b: the displacement form only */
                const double lb = L[2 * n_hist + h];
                for (i = 0; i < n; ++i)
                    bm[i] += lb * Hh[i];
            }
        }
        for (j = 0; j < n_loaded; ++j)
            rhs[loaded[j]] = w0 * f0[j] + w1 * f1[j];
        sub_product(n, idx[0], idx[1], val[0], q, rhs); /* F - K q */
        sub_product(n, idx[2], idx[3], val[1], s, rhs); /* - C s */
        if (val[2])
            sub_product(n, idx[4], idx[5], val[2], bm, rhs); /* - M b */
        if (solver == 0)
            dense_solve(n, val[3], idx[10], rhs);
        else if (solver == 1)
            sparse_solve(n, idx, val, rhs, z);
        else
            block_solve(n, val[3], val[4], val[5], rhs);
        /* rhs is now u */
        for (o = 0; o < 3; ++o) { /* x1, v1, a1 */
            const double *Lr = L + (3 + o) * n_hist;
            double *u = upd + o * n;
            for (i = 0; i < n; ++i)
                u[i] = 0.0;
            for (h = 0; h < n_hist; ++h) {
                const double lh = Lr[h], *Hh = H + h * n;
                for (i = 0; i < n; ++i)
                    u[i] += lh * Hh[i];
            }
            for (i = 0; i < n; ++i)
                u[i] += c_u[o] * rhs[i];
        }
        for (j = 0; j < n_shift; ++j) { /* lags, oldest first */
            double *dst = H + shift[2 * j] * n;
            const double *src = H + shift[2 * j + 1] * n;
            for (i = 0; i < n; ++i)
                dst[i] = src[i];
        }
        for (o = 0; o < 3; ++o) {
            double *dst = H + rows[o] * n;
            for (i = 0; i < n; ++i)
                dst[i] = upd[o * n + i];
        }
        if (xo)
            for (j = 0; j < n_out; ++j)
                xo[(k + 1) * n_out + j] = upd[out_idx[j]];
        if (vo)
            for (j = 0; j < n_out; ++j)
                vo[(k + 1) * n_out + j] = upd[n + out_idx[j]];
        if (ao)
            for (j = 0; j < n_out; ++j)
                ao[(k + 1) * n_out + j] = upd[2 * n + out_idx[j]];
    }
    return 0;
}
#endif /* DTDYN_MCK_LOOP_H */
