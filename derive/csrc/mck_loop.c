/*
 * The time loop of simulate_mck for dense M, C, K (acceleration form of any one-step or
 * multistep scheme of the generated table). Per step, with the history H (n_hist rows of n:
 * x0, v0, a0 and lags) and the scheme's coefficient rows L (5 x n_hist: q, s, x1, v1, a1
 * expanded over the history rows, from dttmm_sweep.expanded) and c_u (x1_u, v1_u, a1_u):
 *
 *     F   = w0 f_k + w1 f_{k+1}                 (on the loaded DOFs)
 *     a_e = (M + r C + p K)^-1 (F - K q - C s),  q = L_q H, s = L_s H   (prefactored LU)
 *     x1, v1, a1 = L_{x1,v1,a1} H + c_u a_e
 *
 * then the lags shift (H[dst] = H[src] for the pairs in order) and x0, v0, a0 take x1, v1, a1.
 * K, C and LU are row-major n x n; LU and piv as LAPACK's getrf (0-based pivots). Outputs
 * (NULL: not stored) get row k + 1 of the stored DOFs. Returns 0, DTDYN_STOPPED when stopped.
 */
#include <stddef.h>

static void lu_apply(long n, const double *restrict LU, const long *restrict piv,
                     double *restrict b)
{
    long i, j;
    for (i = 0; i < n; ++i) { /* the row interchanges of getrf, in order */
        const long p = piv[i];
        if (p != i) {
            const double t = b[i];
            b[i] = b[p];
            b[p] = t;
        }
    }
    for (i = 1; i < n; ++i) { /* L y = b, unit diagonal */
        double s = b[i];
        for (j = 0; j < i; ++j)
            s -= LU[i * n + j] * b[j];
        b[i] = s;
    }
    for (i = n - 1; i >= 0; --i) { /* U x = y */
        double s = b[i];
        for (j = i + 1; j < n; ++j)
            s -= LU[i * n + j] * b[j];
        b[i] = s / LU[i * n + i];
    }
}

int dtdyn_mck_loop(long n, long n_hist, long n_steps, long n_loaded, const long *restrict loaded,
                   const double *restrict force, const double *restrict K,
                   const double *restrict C, const double *restrict LU,
                   const long *restrict piv, const double *restrict L,
                   const double *restrict c_u, double w0, double w1, long n_shift,
                   const long *restrict shift, const long *restrict rows, double *restrict H,
                   long n_out, const long *restrict out_idx, double *restrict xo,
                   double *restrict vo, double *restrict ao, double *restrict work)
{
    double *q = work, *s = work + n, *rhs = work + 2 * n, *upd = work + 3 * n;
    long k, i, j, h, o;
    for (k = 0; k < n_steps; ++k) {
        const double *f0 = force + k * n_loaded, *f1 = f0 + n_loaded;
        if ((k & 1023) == 0 && dtdyn_stop_flag)
            return DTDYN_STOPPED;
        for (i = 0; i < n; ++i) {
            double qi = 0.0, si = 0.0;
            for (h = 0; h < n_hist; ++h) {
                qi += L[0 * n_hist + h] * H[h * n + i];
                si += L[1 * n_hist + h] * H[h * n + i];
            }
            q[i] = qi;
            s[i] = si;
            rhs[i] = 0.0;
        }
        for (j = 0; j < n_loaded; ++j)
            rhs[loaded[j]] = w0 * f0[j] + w1 * f1[j];
        for (i = 0; i < n; ++i) {
            double acc = rhs[i];
            const double *Ki = K + i * n, *Ci = C + i * n;
            for (j = 0; j < n; ++j)
                acc -= Ki[j] * q[j] + Ci[j] * s[j];
            rhs[i] = acc;
        }
        lu_apply(n, LU, piv, rhs); /* rhs is now a_e */
        for (o = 0; o < 3; ++o) {  /* x1, v1, a1 */
            const double *Lr = L + (2 + o) * n_hist;
            double *u = upd + o * n;
            for (i = 0; i < n; ++i) {
                double acc = 0.0;
                for (h = 0; h < n_hist; ++h)
                    acc += Lr[h] * H[h * n + i];
                u[i] = acc + c_u[o] * rhs[i];
            }
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
