/* block_chain.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_BLOCK_CHAIN_H
#define DTDYN_BLOCK_CHAIN_H
#include "c_api.h"
#include "stop.h"
#include "flush_subnormals.h"
/*
 * The time loop of a chain of nodes with two DOFs each whose M, C, K are symmetric and block
 * tridiagonal in 2 x 2 node blocks (a beam: [w, psi] per node, beam_response), any scheme of
 * the generated table in either form: the step of mck_loop.c,
 *
 *     F = w0 f_k + w1 f_{k+1}                                   (on the loaded DOFs)
 *     u = (alpha M + r C + p K)^-1 (F - K q - C s - M b)
 *     x1, v1, a1 = L_{x1,v1,a1} H + c_u u,   then the lags shift,
 *
 * with q, s, b = L_{q,s,b} H the scheme's history terms (L: 6 x n_hist rows q, s, b, x1, v1,
 * a1 over the history rows, dttmm_sweep.expanded; c_u: x1_u, v1_u, a1_u), written for the
 * blocks: no CSR, no indirect indexing. The right side is formed either from q, s, b and
 * K, C, M, or (mats[0] NULL) as F - sum_h B_h H_h with the caller's B_h = L_q[h] K +
 * L_s[h] C + L_b[h] M, which saves the pass for q, s, b (beam_response: the one-step
 * schemes, whose terms do not cancel). The effective matrix A = alpha M + r C + p K is solved
 * by the matrix Riccati sweep, condensed from the last node once per run
 * (dtdyn_block_chain_factor):
 *
 *     P_{N-1} = D_{N-1},   G_i = E_i P_{i+1}^-1,   P_i = D_i - G_i E_i^T,
 *
 * and every step y_i = g_i - G_i y_{i+1} from the last node (g: the right side), then u from
 * the first, u_i = z_i - G_{i-1}^T u_{i-1} with z_i = P_i^-1 y_i (P_i^-1 E_{i-1}^T = G_{i-1}^T,
 * A being symmetric). Each recurrence advances two nodes a round, so that one pair of
 * dependent multiply-adds is paid per two nodes:
 *
 *     y_{i-1} = (g_{i-1} - G_{i-1} g_i) + GG_i y_{i+1},
 *     u_{i+1} = (z_{i+1} - G_i^T z_i) + GG_i^T u_{i-1},        GG_i = G_{i-1} G_i,
 *
 * with GG_i once per run and the terms in parentheses formed by vector loops; the node between
 * follows from y_{i+1} (u_{i-1}) off the dependency chain. The step runs block by block
 * (BC_BLOCK nodes, temporaries in L1): back, the history terms (with one node either side),
 * the right side, the sweep's terms, the recurrence and z; forward, the terms, the recurrence
 * and the update of the history. Only the recurrences are scalar.
 *
 * Storage, nodes 0 .. N - 1: every per-node quantity is a row of P = BC_STRIDE(N) doubles
 * (N + 1 rounded up to DTDYN_BLOCK_CHAIN_ALIGN = 8), rows starting on 64-byte boundaries
 * (DOF 2 i + c of the node system is component c of node i):
 *   a matrix (K, C, M; and A for the factorization): 7 rows, D_i as d00, d01, d11
 *     (symmetric), then E as e00, e01, e10, e11 with E[i + 1] = A[node i, node i + 1] and
 *     E[0] = E[N] = 0;
 *   the factors (fac): 11 rows, G as g00, g01, g10, g11 with G[i + 1] = G_i (G[0] = G[N] = 0),
 *     GG as four rows with GG[i] = G_{i-1} G_i (GG[0] = GG[N] = 0), then P_i^-1 as p00, p01,
 *     p11;
 *   the history H: n_hist pairs of rows, component 0 of every node, then component 1; the
 *     padding of each row (nodes N ..) zero, and 8 zeros before the first row (the products
 *     from H read them as nodes -1 and N, times a zero E);
 *   loaded, out_idx: DOF indices 2 i + c, loaded ascending.
 * mats = {K, C, M (NULL: b = 0, the acceleration form), fac, B_0 .. B_{n_hist-1}}: with K,
 *   the right side from the history terms; with K NULL, from the B_h (NULL: row h does not
 *   enter). work: n_work >= DTDYN_BLOCK_CHAIN_ROWS (P + DTDYN_BLOCK_CHAIN_GAP) doubles (z, its
 *   two components, each row after a gap whose last double is z[-1] = 0; generated/c_api.h).
 * Outputs (NULL: not stored) get row k + 1 of the stored DOFs. Returns 0, DTDYN_STOPPED when
 * stopped, DTDYN_ERR_WORK (nothing written) when n_work is too short.
 */
#include <math.h>
#include <stddef.h>

/* nodes per block of a step, blocks from node 0 (its temporaries: 12 rows of BC_ROW doubles,
   in L1) */
#define BC_BLOCK 256
#define BC_ROW (BC_BLOCK + 8)
/* the stride of every per-node array: N + 1 rounded up to DTDYN_BLOCK_CHAIN_ALIGN doubles
   (generated/c_api.h; 8: 64 bytes) */
#define BC_ALIGN DTDYN_BLOCK_CHAIN_ALIGN
#define BC_STRIDE(N) (((N) + BC_ALIGN) / BC_ALIGN * BC_ALIGN)

/* the factors of A (layout above) into fac; returns -1, or the node whose condensed pivot is
   singular (|det P_i| <= 1e-14 max|P_i|^2 or not finite) */
int dtdyn_block_chain_factor(long N, const double *restrict A, double *restrict fac)
{
    const long P = BC_STRIDE(N);
    const double *d00 = A, *d01 = A + P, *d11 = A + 2 * P;
    const double *e00 = A + 3 * P, *e01 = A + 4 * P, *e10 = A + 5 * P, *e11 = A + 6 * P;
    double *g00 = fac, *g01 = fac + P, *g10 = fac + 2 * P, *g11 = fac + 3 * P;
    double *h00 = fac + 4 * P, *h01 = fac + 5 * P, *h10 = fac + 6 * P, *h11 = fac + 7 * P;
    double *p00 = fac + 8 * P, *p01 = fac + 9 * P, *p11 = fac + 10 * P;
    long i, c;
    for (c = 0; c < 8 * P; ++c)
        fac[c] = 0.0;
    for (i = N - 1; i >= 0; --i) {
        double a = d00[i], b = d01[i], d = d11[i], det;
        if (i < N - 1) { /* G_i = E_i P_{i+1}^-1, P_i = D_i - G_i E_i^T */
            const long j = i + 1;
            const double x00 = g00[j] = e00[j] * p00[j] + e01[j] * p01[j];
            const double x01 = g01[j] = e00[j] * p01[j] + e01[j] * p11[j];
            const double x10 = g10[j] = e10[j] * p00[j] + e11[j] * p01[j];
            const double x11 = g11[j] = e10[j] * p01[j] + e11[j] * p11[j];
            a -= x00 * e00[j] + x01 * e01[j];
            b -= x00 * e10[j] + x01 * e11[j];
            d -= x10 * e10[j] + x11 * e11[j];
        }
        /* singular against the product of its own diagonal: a test that does not depend on
           the units of the two DOFs (N/m and N m per rad) nor on a held DOF's unit entry */
        det = a * d - b * b;
        if (!isfinite(det) || fabs(det) <= 1e-14 * fabs(a * d) || det == 0.0)
            return (int)i;
        p00[i] = d / det;
        p01[i] = -b / det;
        p11[i] = a / det;
    }
    for (i = 1; i < N; ++i) { /* GG_i = G_{i-1} G_i */
        h00[i] = g00[i] * g00[i + 1] + g01[i] * g10[i + 1];
        h01[i] = g00[i] * g01[i + 1] + g01[i] * g11[i + 1];
        h10[i] = g10[i] * g00[i + 1] + g11[i] * g10[i + 1];
        h11[i] = g10[i] * g01[i + 1] + g11[i] * g11[i + 1];
    }
    return -1;
}

/* b = A^-1 b by the factors of dtdyn_block_chain_factor (b: two rows of P, component 0 of
   every node, then component 1): y_i = b_i - G_i y_{i+1} from the last node, then
   u_i = P_i^-1 y_i - G_{i-1}^T u_{i-1} from the first */
int dtdyn_block_chain_solve(long N, const double *restrict fac, double *restrict b)
{
    const long P = BC_STRIDE(N);
    const double *g00 = fac, *g01 = fac + P, *g10 = fac + 2 * P, *g11 = fac + 3 * P;
    const double *p00 = fac + 8 * P, *p01 = fac + 9 * P, *p11 = fac + 10 * P;
    double *b0 = b, *b1 = b + P, y0 = 0.0, y1 = 0.0, u0 = 0.0, u1 = 0.0;
    long i;
    for (i = N - 1; i >= 0; --i) {
        const double t0 = b0[i] - (g00[i + 1] * y0 + g01[i + 1] * y1);
        const double t1 = b1[i] - (g10[i + 1] * y0 + g11[i + 1] * y1);
        b0[i] = y0 = t0;
        b1[i] = y1 = t1;
    }
    for (i = 0; i < N; ++i) {
        const double t0 = p00[i] * b0[i] + p01[i] * b1[i] - (g00[i] * u0 + g10[i] * u1);
        const double t1 = p01[i] * b0[i] + p11[i] * b1[i] - (g01[i] * u0 + g11[i] * u1);
        b0[i] = u0 = t0;
        b1[i] = u1 = t1;
    }
    return 0;
}

/* n_out of the rows of L (q, s, b, or x1, v1, a1; n_hist each) over the history at nodes
   lo .. hi - 1, component c of output o into out[2 o + c] from index 0. BC_TERMS(NH, NO): the
   loop for NH history rows and NO outputs, unrolled, every row of H read once per node (the
   multistep schemes: 5 and 7 rows); other sizes take terms_any, a loop over each output's
   nonzero terms. */
#define BC_TERMS(NH, NO) \
    static void terms_##NH##_##NO(long P, const double *restrict L, const double *restrict H, \
                                  long lo, long hi, double *const *out) \
    { \
        long c, j, h, o; \
        for (c = 0; c < 2; ++c) { \
            const double *x = H + c * P + lo; \
            double *restrict t0 = out[c], *restrict t1 = out[2 + c]; \
            double *restrict t2 = NO > 2 ? out[4 + c] : NULL; \
            for (j = 0; j < hi - lo; ++j) { \
                double v[NH], acc[NO]; \
                for (h = 0; h < NH; ++h) \
                    v[h] = x[h * 2 * P + j]; \
                for (o = 0; o < NO; ++o) { \
                    acc[o] = L[o * NH] * v[0]; \
                    for (h = 1; h < NH; ++h) \
                        acc[o] = fma(L[o * NH + h], v[h], acc[o]); \
                } \
                t0[j] = acc[0]; \
                t1[j] = acc[1]; \
                if (NO > 2) \
                    t2[j] = acc[NO - 1]; \
            } \
        } \
    }
BC_TERMS(5, 2)
BC_TERMS(5, 3)
BC_TERMS(7, 2)
BC_TERMS(7, 3)

static void terms_any(long P, long n_hist, int n_out, const double *restrict L,
                      const double *restrict H, long lo, long hi, double *const *out)
{
    long c, j, h, o;
    for (c = 0; c < 2; ++c)
        for (o = 0; o < n_out; ++o) {
            double *restrict t = out[2 * o + c];
            for (j = 0; j < hi - lo; ++j)
                t[j] = 0.0;
            for (h = 0; h < n_hist; ++h) {
                const double l = L[o * n_hist + h], *x = H + h * 2 * P + c * P + lo;
                if (l != 0.0)
                    for (j = 0; j < hi - lo; ++j)
                        t[j] = fma(l, x[j], t[j]);
            }
        }
}

static void history_terms(long P, long n_hist, int n_out, const double *restrict L,
                          const double *restrict H, long lo, long hi, double *const *out)
{
#define BC_CASE(NH) \
    if (n_hist == NH) { \
        if (n_out == 2) \
            terms_##NH##_2(P, L, H, lo, hi, out); \
        else \
            terms_##NH##_3(P, L, H, lo, hi, out); \
        return; \
    }
    BC_CASE(5)
    BC_CASE(7)
#undef BC_CASE
    terms_any(P, n_hist, n_out, L, H, lo, hi, out);
}

/* x1, v1, a1 = L H + c_u u written over rows 0, 1, 2 of H (the one-step schemes: no lags) at
   nodes lo .. lo + m - 1, in one pass (each node's rows read before they are written) */
static void update_in_place(long P, const double *restrict L, const double *restrict c_u,
                            double *restrict H, long lo, long m, const double *restrict u0,
                            const double *restrict u1)
{
    long c, j, o;
    for (c = 0; c < 2; ++c) {
        double *restrict x = H + c * P + lo, *restrict v = x + 2 * P, *restrict a = x + 4 * P;
        const double *restrict u = c ? u1 : u0;
        for (j = 0; j < m; ++j) {
            const double h[3] = {x[j], v[j], a[j]};
            double acc[3];
            for (o = 0; o < 3; ++o)
                acc[o] = fma(c_u[o], u[j], fma(L[3 * o + 2], h[2],
                                               fma(L[3 * o + 1], h[1], L[3 * o] * h[0])));
            x[j] = acc[0];
            v[j] = acc[1];
            a[j] = acc[2];
        }
    }
}

/* a0, a1 += (X v) at local node j (X a matrix in the layout above from node lo; v0, v1 with one
   node either side: v[j + 1] is node lo + j): E[i]^T v_{i-1} + D_i v_i + E[i + 1] v_{i+1} */
#define BC_ROW_PRODUCT(X, v0, v1) \
    { \
        const double *d00 = X + lo, *d01 = X + P + lo, *d11 = X + 2 * P + lo; \
        const double *e00 = X + 3 * P + lo, *e01 = X + 4 * P + lo, *e10 = X + 5 * P + lo; \
        const double *e11 = X + 6 * P + lo; \
        a0 = fma(e00[j], v0[j], a0); \
        a1 = fma(e01[j], v0[j], a1); \
        a0 = fma(e10[j], v1[j], a0); \
        a1 = fma(e11[j], v1[j], a1); \
        a0 = fma(d00[j], v0[j + 1], a0); \
        a1 = fma(d01[j], v0[j + 1], a1); \
        a0 = fma(d01[j], v1[j + 1], a0); \
        a1 = fma(d11[j], v1[j + 1], a1); \
        a0 = fma(e00[j + 1], v0[j + 2], a0); \
        a1 = fma(e10[j + 1], v0[j + 2], a1); \
        a0 = fma(e01[j + 1], v1[j + 2], a0); \
        a1 = fma(e11[j + 1], v1[j + 2], a1); \
    }

/* r -= K q + C s (+ M b) at nodes lo .. lo + m - 1 (T: q0, q1, s0, s1, b0, b1 with one node
   either side) */
static void sub_products(long P, const double *restrict K, const double *restrict C,
                         const double *restrict M, long lo, long m, double *const *T,
                         double *restrict r0, double *restrict r1)
{
    const double *restrict q0 = T[0], *restrict q1 = T[1], *restrict s0 = T[2];
    const double *restrict s1 = T[3], *restrict b0 = T[4], *restrict b1 = T[5];
    long j;
    if (M)
        for (j = 0; j < m; ++j) {
            double a0 = 0.0, a1 = 0.0;
            BC_ROW_PRODUCT(K, q0, q1)
            BC_ROW_PRODUCT(C, s0, s1)
            BC_ROW_PRODUCT(M, b0, b1)
            r0[j] -= a0;
            r1[j] -= a1;
        }
    else
        for (j = 0; j < m; ++j) {
            double a0 = 0.0, a1 = 0.0;
            BC_ROW_PRODUCT(K, q0, q1)
            BC_ROW_PRODUCT(C, s0, s1)
            r0[j] -= a0;
            r1[j] -= a1;
        }
}

/* r -= B x at nodes lo .. lo + m - 1 for B in the matrix layout and x a history row pair read
   in place (x0, x1 from node lo - 1: the zero padding around the rows stands for nodes -1
   and N) */
static void sub_product(long P, const double *restrict B, long lo, long m,
                        const double *restrict x0, const double *restrict x1,
                        double *restrict r0, double *restrict r1)
{
    long j;
    for (j = 0; j < m; ++j) {
        double a0 = 0.0, a1 = 0.0;
        BC_ROW_PRODUCT(B, x0, x1)
        r0[j] -= a0;
        r1[j] -= a1;
    }
}

/* x = z - B y (transposed: z - B^T y) for 2 x 2 B (b00, b01, b10, b11) and 2-vectors */
#define BC_SUB(x0, x1, z0, z1, b00, b01, b10, b11, y0, y1) \
    { \
        x0 = (z0) - ((b00) * (y0) + (b01) * (y1)); \
        x1 = (z1) - ((b10) * (y0) + (b11) * (y1)); \
    }
#define BC_ADD(x0, x1, z0, z1, b00, b01, b10, b11, y0, y1) \
    { \
        x0 = fma(b00, y0, fma(b01, y1, z0)); \
        x1 = fma(b10, y0, fma(b11, y1, z1)); \
    }

DTDYN_LOOP int block_chain_loop_run(long N, long n_hist, long n_steps, long n_loaded,
                                    const long *restrict loaded, const double *restrict force,
                                    const double *const *mats, const double *restrict L,
                                    const double *restrict c_u, double w0, double w1, long n_shift,
                                    const long *restrict shift, const long *restrict rows,
                                    double *restrict H, long n_out, const long *restrict out_idx,
                                    double *restrict xo, double *restrict vo, double *restrict ao,
                                    double *restrict work, long n_work)
{
    const long P = BC_STRIDE(N);
    const double *K = mats[0], *C = mats[1], *M = mats[2], *fac = mats[3];
    const double *g00 = fac, *g01 = fac + P, *g10 = fac + 2 * P, *g11 = fac + 3 * P;
    const double *h00 = fac + 4 * P, *h01 = fac + 5 * P, *h10 = fac + 6 * P, *h11 = fac + 7 * P;
    const double *p00 = fac + 8 * P, *p01 = fac + 9 * P, *p11 = fac + 10 * P;
    const int n_terms = M ? 3 : 2; /* the history terms: q, s (and b) */
    /* the update in place (x1, v1, a1 into rows 0, 1, 2 and no lags): one pass */
    const int in_place = n_hist == 3 && n_shift == 0 && rows[0] == 0 && rows[1] == 1
                         && rows[2] == 2;
    /* z[-1] = 0: the gap's last double before each row */
    double *z0 = work + DTDYN_BLOCK_CHAIN_GAP;
    double *z1 = work + (P + DTDYN_BLOCK_CHAIN_GAP) + DTDYN_BLOCK_CHAIN_GAP;
    double T[12][BC_ROW] __attribute__((aligned(64)));
    long k, i, j, o, lo;
    if (N < 0 || n_work < DTDYN_BLOCK_CHAIN_ROWS * (P + DTDYN_BLOCK_CHAIN_GAP))
        return DTDYN_ERR_WORK;
    z0[-1] = 0.0;
    z1[-1] = 0.0;
    for (k = 0; k < n_steps; ++k) {
        const double *f0 = force + k * n_loaded, *f1 = f0 + n_loaded;
        double y0 = 0.0, y1 = 0.0, u0 = 0.0, u1 = 0.0;
        long jl = n_loaded;
        if ((k & 1023) == 0 && dtdyn_stop_flag)
            return DTDYN_STOPPED;
        /* back: from the last block to the first */
        for (lo = (N - 1) / BC_BLOCK * BC_BLOCK; lo >= 0; lo -= BC_BLOCK) {
            const long hi = lo + BC_BLOCK < N ? lo + BC_BLOCK : N, m = hi - lo;
            const long first = lo > 0 ? lo - 1 : 0, last = hi < N ? hi + 1 : N;
            double *Tq[6], *r0 = T[6], *r1 = T[7], *t0 = T[8], *t1 = T[9];
            double *v0 = T[10], *v1 = T[11];
            if (K) {
                for (o = 0; o < 6; ++o) /* node lo - 1 at index 0 */
                    Tq[o] = T[o] + (first - (lo - 1));
                history_terms(P, n_hist, n_terms, L, H, first, last, Tq);
                for (o = 0; o < 6; ++o) {
                    if (lo == 0) /* node -1 */
                        T[o][0] = 0.0;
                    if (hi == N) /* node N */
                        T[o][m + 1] = 0.0;
                }
            }
            for (j = 0; j < m; ++j) {
                r0[j] = 0.0;
                r1[j] = 0.0;
            }
            for (; jl > 0 && loaded[jl - 1] >= 2 * lo; --jl) {
                const long d = loaded[jl - 1];
                (d & 1 ? r1 : r0)[(d >> 1) - lo] = w0 * f0[jl - 1] + w1 * f1[jl - 1];
            }
            if (K) {
                double *Tv[6] = {T[0], T[1], T[2], T[3], T[4], T[5]};
                sub_products(P, K, C, M, lo, m, Tv, r0, r1); /* F - K q - C s - M b */
            } else {
                for (o = 0; o < n_hist; ++o) /* F - sum_h B_h H_h */
                    if (mats[4 + o])
                        sub_product(P, mats[4 + o], lo, m, H + o * 2 * P + lo - 1,
                                    H + o * 2 * P + P + lo - 1, r0, r1);
            }
            for (j = 0; j + 1 < m; ++j) { /* t_i = g_i - G_i g_{i+1} */
                const long n = lo + j + 1;
                BC_SUB(t0[j], t1[j], r0[j], r1[j], g00[n], g01[n], g10[n], g11[n], r0[j + 1],
                       r1[j + 1])
            }
            for (j = m - 1; j > 0; j -= 2) { /* nodes j - 1, j from y at j + 1 (y0, y1) */
                const long n = lo + j;
                const double yR0 = y0, yR1 = y1;
                BC_SUB(v0[j], v1[j], r0[j], r1[j], g00[n + 1], g01[n + 1], g10[n + 1],
                       g11[n + 1], yR0, yR1)
                BC_ADD(y0, y1, t0[j - 1], t1[j - 1], h00[n], h01[n], h10[n], h11[n], yR0, yR1)
                v0[j - 1] = y0;
                v1[j - 1] = y1;
            }
            if (j == 0) { /* node lo, when m is odd */
                const double yR0 = y0, yR1 = y1;
                BC_SUB(y0, y1, r0[0], r1[0], g00[lo + 1], g01[lo + 1], g10[lo + 1], g11[lo + 1],
                       yR0, yR1)
                v0[0] = y0;
                v1[0] = y1;
            }
            for (j = 0; j < m; ++j) { /* z = P^-1 y */
                const long n = lo + j;
                z0[n] = p00[n] * v0[j] + p01[n] * v1[j];
                z1[n] = p01[n] * v0[j] + p11[n] * v1[j];
            }
        }
        /* forward, block by block: the recurrence for u, then the update */
        for (lo = 0; lo < N; lo += BC_BLOCK) {
            const long hi = lo + BC_BLOCK < N ? lo + BC_BLOCK : N, m = hi - lo;
            double *t0 = T[0], *t1 = T[1], *v0 = T[2], *v1 = T[3];
            for (j = 0; j < m; ++j) { /* t'_k = z_k - G_{k-1}^T z_{k-1} */
                const long n = lo + j;
                BC_SUB(t0[j], t1[j], z0[n], z1[n], g00[n], g10[n], g01[n], g11[n], z0[n - 1],
                       z1[n - 1])
            }
            for (j = 0; j + 1 < m; j += 2) { /* nodes j, j + 1 from u at j - 1 (u0, u1) */
                const long n = lo + j;
                const double uL0 = u0, uL1 = u1;
                BC_SUB(v0[j], v1[j], z0[n], z1[n], g00[n], g10[n], g01[n], g11[n], uL0, uL1)
                BC_ADD(u0, u1, t0[j + 1], t1[j + 1], h00[n], h10[n], h01[n], h11[n], uL0, uL1)
                v0[j + 1] = u0;
                v1[j + 1] = u1;
            }
            if (j < m) { /* the last node, when m is odd */
                const long n = lo + j;
                const double uL0 = u0, uL1 = u1;
                BC_SUB(u0, u1, z0[n], z1[n], g00[n], g10[n], g01[n], g11[n], uL0, uL1)
                v0[j] = u0;
                v1[j] = u1;
            }
            if (in_place) { /* x1, v1, a1 = L H + c_u u, written over x0, v0, a0 */
                update_in_place(P, L + 3 * n_hist, c_u, H, lo, m, v0, v1);
            } else {
                double *X[6] = {T[6], T[7], T[8], T[9], T[10], T[11]};
                history_terms(P, n_hist, 3, L + 3 * n_hist, H, lo, hi, X);
                for (o = 0; o < 3; ++o) {
                    const double cu = c_u[o];
                    for (j = 0; j < m; ++j) {
                        X[2 * o][j] = fma(cu, v0[j], X[2 * o][j]);
                        X[2 * o + 1][j] = fma(cu, v1[j], X[2 * o + 1][j]);
                    }
                }
                for (j = 0; j < n_shift; ++j) { /* lags, oldest first */
                    double *dst = H + shift[2 * j] * 2 * P;
                    const double *src = H + shift[2 * j + 1] * 2 * P;
                    for (i = lo; i < hi; ++i) {
                        dst[i] = src[i];
                        dst[P + i] = src[P + i];
                    }
                }
                for (o = 0; o < 3; ++o) {
                    double *dst = H + rows[o] * 2 * P + lo;
                    for (j = 0; j < m; ++j) {
                        dst[j] = X[2 * o][j];
                        dst[P + j] = X[2 * o + 1][j];
                    }
                }
            }
        }
        for (o = 0; o < 3; ++o) {
            double *out = o == 0 ? xo : o == 1 ? vo : ao;
            const double *src = H + rows[o] * 2 * P;
            if (out)
                for (j = 0; j < n_out; ++j) {
                    const long d = out_idx[j];
                    out[(k + 1) * n_out + j] = src[(d & 1) * P + (d >> 1)];
                }
        }
    }
    return 0;
}
#endif /* DTDYN_BLOCK_CHAIN_H */
