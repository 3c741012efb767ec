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
 *
 * Iterative refinement (mats[4 + n_hist], NULL: none; a beam's uniform elements, layout at
 * BR_HEAD below): the double-precision solve and right side lose about eps N^3.5 of the low
 * modes of a beam of N elements (each element's stiffness, ~12 EI / h^3, is N^3 times the
 * beam's, and the rounding of every product K x and of every pivot is a random nodal force of
 * eps times it; docs/beam_conditioning.md). Each step then computes u as above, and BR_CORR
 * times the residual of the step's equation
 *
 *     r = F - K (q + p u) - C (s + r u) - M (b + alpha u),   C = alpha_R M + beta_R K + C_d,
 *
 * and u += A^-1 r with the same factors, before the update. The residual is taken element by
 * element, without the assembled K: x_e = q + p u + beta_R (s + r u) in double-double
 * (exact products by fma, Knuth's TwoSum), each element's deformation y = x_i - T x_{i+1}
 * (T = [[1, -h], [0, 1]]: the left node against the right node's rigid extension) from it
 * in double-double and rounded once, its end forces F^-1 y (F^-1 = the element stiffness's
 * left block) and -T^T F^-1 y in double; the inertia Me (b + alpha u + alpha_R (s + r u)) and
 * the nodes' springs, dampers and masses in double (their rounding is eps of a force that
 * does not cancel). The corrections contract by a factor rho (about eps times the element
 * stiffness's part of A against the low modes' A, 3e-4 for a 10,000-element cantilever at
 * dt = 1e-4): after correction c >= 2 the loop stops when the next, predicted as
 * e_c^2 / e_{c-1} (e_c = max |p du| / max |x| per component, the larger), is below BR_TOL,
 * or after BR_CORR of them. So no product of an element stiffness with a displacement is rounded:
 * rigid motions give y = 0 exactly, and the residual's rounding is eps of the element
 * forces, which are of the order of the beam's own. Double-double rather than long double:
 * a long double (64-bit mantissa, x86 only; double on MSVC and aarch64) x_e still leaves
 * eps_ld N^3.5 (1e-5 at 10,000 elements); double-double leaves the state's own rounding.
 * work then needs BC_REFINE_ROWS P doubles more (u, r, x_e hi and lo, the inertia's
 * argument: two rows each).
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

/* the refinement's data (mats[4 + n_hist]): a header of BR_HEAD doubles, then n_point
   nodal terms (dof, k, c, m: a node's springs, dampers and masses to the ground, dof = 2 i + c)
   and the n_held held dofs */
enum {
    BR_CORR,   /* the most corrections per step */
    BR_TOL,    /* ... fewer once the next one is predicted below this (relative to x) */
    BR_POINTS, /* n_point */
    BR_HELD,   /* n_held */
    BR_LEN,    /* h, the element length */
    BR_F00, BR_F01, BR_F11, /* F^-1, the element stiffness's block of its left node */
    BR_ALPHA, BR_BETA,      /* Rayleigh: C = alpha_R M + beta_R K + the dampers */
    BR_P, BR_R, BR_AU,      /* the step's p, r, alpha (the coefficients of u) */
    BR_ME,                  /* the element mass matrix, 4 x 4 row-major */
    BR_HEAD = BR_ME + 16
};
/* work rows of the refinement, P doubles each, after the step's own (the contract's) */
#define BC_REFINE_ROWS DTDYN_BLOCK_CHAIN_REFINE_ROWS

/* a + b = s + e exactly (Knuth's TwoSum: any order of magnitude) */
static inline double dd_two_sum(double a, double b, double *e)
{
    const double s = a + b, bb = s - a;
    *e = (a - (s - bb)) + (b - bb);
    return s;
}

/* (hi, lo) += a b: the product exact by fma, its sum by TwoSum, the low parts added */
static inline void dd_add_product(double a, double b, double *hi, double *lo)
{
    const double p = a * b, ep = fma(a, b, -p);
    double e;
    *hi = dd_two_sum(*hi, p, &e);
    *lo += e + ep;
}

/* x, v, a at the step's equation for DOF offset o (c P + i): q + p u, s + r u, b + alpha u in
   double-double (the L rows q, s, b over the history), rounded */
static void refine_point(long P, long n_hist, const double *restrict L, const double *restrict H,
                         const double *restrict R, long o, double u, double *out)
{
    long h, t;
    for (t = 0; t < 3; ++t) {
        double hi = 0.0, lo = 0.0;
        for (h = 0; h < n_hist; ++h)
            if (L[t * n_hist + h] != 0.0)
                dd_add_product(L[t * n_hist + h], H[h * 2 * P + o], &hi, &lo);
        dd_add_product(R[BR_P + t], u, &hi, &lo);
        out[t] = hi + lo;
    }
}

/* (hi, lo) = L_t H + c u over the 2 P entries of both components, double-double */
static void refine_row(long P, long n_hist, const double *restrict Lt, const double *restrict H,
                       double c, const double *restrict u, double *restrict hi,
                       double *restrict lo)
{
    long h, o;
    for (o = 0; o < 2 * P; ++o) {
        hi[o] = 0.0;
        lo[o] = 0.0;
    }
    for (h = 0; h < n_hist; ++h)
        if (Lt[h] != 0.0) {
            const double l = Lt[h], *restrict x = H + h * 2 * P;
            for (o = 0; o < 2 * P; ++o)
                dd_add_product(l, x[o], hi + o, lo + o);
        }
    for (o = 0; o < 2 * P; ++o)
        dd_add_product(c, u[o], hi + o, lo + o);
}

/* b = A^-1 b as dtdyn_block_chain_solve, each recurrence two nodes a round as the step's
   (block_chain.h's comment: GG from the factors); t: scratch, two rows of P */
static void refine_solve(long N, const double *restrict fac, double *restrict b,
                         double *restrict t)
{
    const long P = BC_STRIDE(N);
    const double *g00 = fac, *g01 = fac + P, *g10 = fac + 2 * P, *g11 = fac + 3 * P;
    const double *h00 = fac + 4 * P, *h01 = fac + 5 * P, *h10 = fac + 6 * P, *h11 = fac + 7 * P;
    const double *p00 = fac + 8 * P, *p01 = fac + 9 * P, *p11 = fac + 10 * P;
    double *b0 = b, *b1 = b + P, *t0 = t, *t1 = t + P, y0 = 0.0, y1 = 0.0;
    long j;
    if (N <= 0)
        return;
    for (j = 0; j + 1 < N; ++j) /* t_j = b_j - G_j b_{j+1} */
        BC_SUB(t0[j], t1[j], b0[j], b1[j], g00[j + 1], g01[j + 1], g10[j + 1], g11[j + 1],
               b0[j + 1], b1[j + 1])
    for (j = N - 1; j > 0; j -= 2) { /* y_j off the chain, y_{j-1} = t_{j-1} + GG_j y_{j+1} */
        const double yR0 = y0, yR1 = y1;
        BC_SUB(b0[j], b1[j], b0[j], b1[j], g00[j + 1], g01[j + 1], g10[j + 1], g11[j + 1], yR0,
               yR1)
        BC_ADD(y0, y1, t0[j - 1], t1[j - 1], h00[j], h01[j], h10[j], h11[j], yR0, yR1)
        b0[j - 1] = y0;
        b1[j - 1] = y1;
    }
    if (j == 0) /* node 0, when N is odd */
        BC_SUB(b0[0], b1[0], b0[0], b1[0], g00[1], g01[1], g10[1], g11[1], y0, y1)
    for (j = 0; j < N; ++j) { /* z = P^-1 y */
        const double z0 = p00[j] * b0[j] + p01[j] * b1[j];
        b1[j] = p01[j] * b0[j] + p11[j] * b1[j];
        b0[j] = z0;
    }
    t0[0] = b0[0];
    t1[0] = b1[0];
    for (j = 1; j < N; ++j) /* t'_j = z_j - G_{j-1}^T z_{j-1} */
        BC_SUB(t0[j], t1[j], b0[j], b1[j], g00[j], g10[j], g01[j], g11[j], b0[j - 1], b1[j - 1])
    y0 = y1 = 0.0; /* u_{j-1} */
    for (j = 0; j + 1 < N; j += 2) { /* u_j off the chain, u_{j+1} = t'_{j+1} + GG_j^T u_{j-1} */
        const double uL0 = y0, uL1 = y1;
        BC_SUB(b0[j], b1[j], b0[j], b1[j], g00[j], g10[j], g01[j], g11[j], uL0, uL1)
        BC_ADD(y0, y1, t0[j + 1], t1[j + 1], h00[j], h10[j], h01[j], h11[j], uL0, uL1)
        b0[j + 1] = y0;
        b1[j + 1] = y1;
    }
    if (j < N) /* the last node, when N is odd */
        BC_SUB(b0[j], b1[j], b0[j], b1[j], g00[j], g10[j], g01[j], g11[j], y0, y1)
}

/* r = F - K (q + p u) - C (s + r u) - M (b + alpha u) over nodes 0 .. N - 1 (block_chain.h's
   comment: element by element, the deformations from double-double), zero on the held DOFs,
   into Xh, and max |x + beta_R v| per component into xmax. u: two rows of P (component 0,
   then 1); f, Xh, Xl, Y: scratch, two rows of P each (the padding of u and of the history
   rows zero). */
static void refine_residual(long N, long n_hist, const double *restrict L, const double *restrict H,
                            const double *restrict R, long n_loaded, const long *restrict loaded,
                            const double *restrict f0, const double *restrict f1, double w0,
                            double w1, const double *restrict u, double *restrict f,
                            double *restrict Xh, double *restrict Xl, double *restrict Y,
                            double *xmax)
{
    const long P = BC_STRIDE(N), n_point = (long)R[BR_POINTS], n_held = (long)R[BR_HELD];
    const double h = R[BR_LEN], f00 = R[BR_F00], f01 = R[BR_F01], f11 = R[BR_F11];
    const double alpha = R[BR_ALPHA], beta = R[BR_BETA], *Me = R + BR_ME;
    const double *pts = R + BR_HEAD, *held = pts + 4 * n_point;
    const double *Lb = L + 2 * n_hist;
    double *restrict r = Xh, *restrict fw = f, *restrict fp = f + P;
    double m0 = 0.0, m1 = 0.0;
    double eq[3];
    long i, j, h_;
    /* v = s + r u (double-double: hi in f, lo in Y), x = q + p u, X = x + beta_R v */
    refine_row(P, n_hist, L + n_hist, H, R[BR_R], u, f, Y);
    refine_row(P, n_hist, L, H, R[BR_P], u, Xh, Xl);
    for (i = 0; i < 2 * P; ++i) {
        double hi = Xh[i], lo = Xl[i];
        dd_add_product(beta, f[i], &hi, &lo);
        Xh[i] = dd_two_sum(hi, lo + beta * Y[i], Xl + i);
    }
    for (i = 0; i < N; ++i) { /* max |X| per component, the corrections' scale */
        const double a0 = fabs(Xh[i]), a1 = fabs(Xh[P + i]);
        m0 = a0 > m0 ? a0 : m0;
        m1 = a1 > m1 ? a1 : m1;
    }
    xmax[0] = m0;
    xmax[1] = m1;
    /* Y = b + alpha u + alpha_R v (double: its rounding is eps of an inertia force) */
    for (i = 0; i < 2 * P; ++i)
        Y[i] = fma(R[BR_AU], u[i], alpha * (f[i] + Y[i]));
    for (h_ = 0; h_ < n_hist; ++h_)
        if (Lb[h_] != 0.0)
            for (i = 0; i < 2 * P; ++i)
                Y[i] = fma(Lb[h_], H[h_ * 2 * P + i], Y[i]);
    /* element i (nodes i, i + 1): its deformation y = x_i - T x_{i+1} from double-double,
       rounded once, its left end's force and moment F^-1 y */
    for (i = 0; i + 1 < N; ++i) {
        double e, yl, yw, yp;
        double yh = dd_two_sum(Xh[i], -Xh[i + 1], &e);
        yl = e + (Xl[i] - Xl[i + 1]);
        dd_add_product(h, Xh[P + i + 1], &yh, &yl);
        yw = yh + (yl + h * Xl[P + i + 1]);
        yh = dd_two_sum(Xh[P + i], -Xh[P + i + 1], &e);
        yp = yh + (e + (Xl[P + i] - Xl[P + i + 1]));
        fw[i] = f00 * yw + f01 * yp;
        fp[i] = f01 * yw + f11 * yp;
    }
    /* node i: minus element i's left end (F^-1 y and Me's rows 0, 1) and element i - 1's right
       end (-T^T F^-1 y and Me's rows 2, 3); the ends' missing elements as zeros */
    for (i = 0; i < P; ++i) {
        r[i] = 0.0;
        r[P + i] = 0.0;
    }
#define BR_LEFT(i) \
    { \
        const double a0 = Y[i], a1 = Y[P + i], a2 = Y[i + 1], a3 = Y[P + i + 1]; \
        r[i] -= fw[i] + (Me[0] * a0 + Me[1] * a1 + Me[2] * a2 + Me[3] * a3); \
        r[P + i] -= fp[i] + (Me[4] * a0 + Me[5] * a1 + Me[6] * a2 + Me[7] * a3); \
    }
#define BR_RIGHT(i) \
    { \
        const double a0 = Y[i - 1], a1 = Y[P + i - 1], a2 = Y[i], a3 = Y[P + i]; \
        r[i] -= (Me[8] * a0 + Me[9] * a1 + Me[10] * a2 + Me[11] * a3) - fw[i - 1]; \
        r[P + i] -= (Me[12] * a0 + Me[13] * a1 + Me[14] * a2 + Me[15] * a3) \
                    + (h * fw[i - 1] - fp[i - 1]); \
    }
    for (i = 0; i + 1 < N; ++i)
        BR_LEFT(i)
    for (i = 1; i < N; ++i)
        BR_RIGHT(i)
#undef BR_LEFT
#undef BR_RIGHT
    for (j = 0; j < n_loaded; ++j) {
        const long d = loaded[j];
        r[(d & 1) * P + (d >> 1)] += w0 * f0[j] + w1 * f1[j];
    }
    for (j = 0; j < n_point; ++j) { /* the nodes' springs, dampers and masses */
        const long d = (long)pts[4 * j], o = (d & 1) * P + (d >> 1);
        refine_point(P, n_hist, L, H, R, o, u[o], eq);
        r[o] -= pts[4 * j + 1] * eq[0] + pts[4 * j + 2] * eq[1] + pts[4 * j + 3] * eq[2];
    }
    for (j = 0; j < n_held; ++j) {
        const long d = (long)held[j];
        r[(d & 1) * P + (d >> 1)] = 0.0;
    }
}

/* x1, v1, a1 = L H + c_u u into H at nodes lo .. hi - 1 (u0, u1 from node lo), the lags
   shifted; X: six rows of BC_ROW scratch */
static void update_block(long P, long n_hist, const double *restrict L,
                         const double *restrict c_u, double *restrict H, long lo, long hi,
                         const double *restrict v0, const double *restrict v1, long n_shift,
                         const long *restrict shift, const long *restrict rows, int in_place,
                         double *const *X)
{
    const long m = hi - lo;
    long i, j, o;
    if (in_place) { /* x1, v1, a1 = L H + c_u u, written over x0, v0, a0 */
        update_in_place(P, L + 3 * n_hist, c_u, H, lo, m, v0, v1);
        return;
    }
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
    double *const X[6] = {T[6], T[7], T[8], T[9], T[10], T[11]};
    /* the refinement (NULL: none) and its rows after the step's work */
    const double *R = mats[4 + n_hist];
    const long n_corr = R ? (long)R[BR_CORR] : 0;
    const long base = DTDYN_BLOCK_CHAIN_ROWS * (P + DTDYN_BLOCK_CHAIN_GAP);
    double *ur = work + base, *rr = ur + 2 * P, *rXh = rr + 2 * P, *rXl = rXh + 2 * P;
    double *rY = rXl + 2 * P;
    long k, i, j, o, lo, c;
    if (N < 0 || n_work < base + (R ? BC_REFINE_ROWS * P : 0))
        return DTDYN_ERR_WORK;
    z0[-1] = 0.0;
    z1[-1] = 0.0;
    if (R) /* u's padding (nodes N ..), which the refinement's row loops read */
        for (i = 0; i < 2 * P; ++i)
            ur[i] = 0.0;
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
            if (R) { /* refined below: u kept, H not yet updated */
                for (j = 0; j < m; ++j) {
                    ur[lo + j] = v0[j];
                    ur[P + lo + j] = v1[j];
                }
                continue;
            }
            update_block(P, n_hist, L, c_u, H, lo, hi, v0, v1, n_shift, shift, rows, in_place,
                         X);
        }
        if (R) {
            double prev = 0.0;
            for (c = 0; c < n_corr; ++c) { /* u += A^-1 r, the residual in double-double */
                double xmax[2], d0 = 0.0, d1 = 0.0, e;
                refine_residual(N, n_hist, L, H, R, n_loaded, loaded, f0, f1, w0, w1, ur, rr,
                                rXh, rXl, rY, xmax);
                refine_solve(N, fac, rXh, rXl);
                for (i = 0; i < N; ++i) {
                    const double a0 = fabs(rXh[i]), a1 = fabs(rXh[P + i]);
                    ur[i] += rXh[i];
                    ur[P + i] += rXh[P + i];
                    d0 = a0 > d0 ? a0 : d0;
                    d1 = a1 > d1 ? a1 : d1;
                }
                d0 *= fabs(R[BR_P]);
                d1 *= fabs(R[BR_P]);
                d0 = d0 > 0.0 ? d0 / xmax[0] : 0.0;
                d1 = d1 > 0.0 ? d1 / xmax[1] : 0.0;
                e = d0 > d1 ? d0 : d1;
                if (e == 0.0 || (c > 0 && e * (e / prev) <= R[BR_TOL]))
                    break;
                prev = e;
            }
            for (lo = 0; lo < N; lo += BC_BLOCK) {
                const long hi = lo + BC_BLOCK < N ? lo + BC_BLOCK : N;
                update_block(P, n_hist, L, c_u, H, lo, hi, ur + lo, ur + P + lo, n_shift, shift,
                             rows, in_place, X);
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
