/* nl_loop.h: hand-written C, compiled as it is (dtdyn/_engine/csrc); generated/nl_loop.c
   adds the entry point of the signature spec (dtdyn.derive.c_api) */
/*
 * Nonlinear forced response over a whole record: a linear discrete model with localized
 * nonlinear forces, one small Newton solve per (sub)step. With the state x_k, force f_k and the
 * element forces g_k = g(w_k, z_k) (derivation: generated/nonlinear.md),
 *
 *     w_k = Cw x_k + Dwf f_k + Dwg g_k          (w: element deformations [y; y'])
 *     z_k = z_{k-1} + h/2 (z'(w_k, z_k) + z'_{k-1})   (internal states, trapezoidal rule)
 *     out_k = Co x_k + Dof f_k + Dog g_k        (stored at the samples only)
 *     x_{k+1} = A x_k + Bf f_k + Bg g_k
 *
 * The unknowns u = [w; z] solve r(u) = [w - Q_k - Dwg g(u); z - z_{k-1} - h/2 (z'(u) +
 * z'_{k-1})] = 0, Q_k = Cw x_k + Dwf f_k. The residual, its Jacobian dr/du, g and z' come from
 * `nl_residual` (CasADi code generation of the element laws, appended to this source).
 * Between samples the force is linear: f at sub-step j of sample n is f_n + (j/S)(f_{n+1} - f_n).
 *
 * Newton accepts u by the rule of every backend (newton_solve in newton.h): |r|_inf <= tol s_r
 * or the next Newton step |J^-1 r|_inf <= tol s_u, s_r = the largest |Q|_inf or |u|_inf and
 * s_u = the largest |u|_inf accepted so far (s_r raised by Q before a step). Matrices are
 * column-major; par holds Dwg, then h. Returns 0, or 1 when Newton failed at step fail[0] (sub-step
 * index) with residual stats[3] (non-finite, singular Jacobian or max_iter iterations), 3 (see
 * below) when the step is beyond its stability limit, DTDYN_STOPPED (stop.h) when stopped,
 * DTDYN_ERR_WORK (nothing written) when work or iwork is shorter than it needs (dtdyn_nl_work).
 */
#ifndef DTDYN_NL_LOOP_H
#define DTDYN_NL_LOOP_H
#include "c_api.h"
#include <float.h>
#include <math.h>

#ifdef __GNUC__
/* hidden: the call stays inside this library (no interposition), so it can be inlined */
int nl_residual(const double **arg, double **res, nl_int *iw, double *w, int mem)
    __attribute__((visibility("hidden")));
#endif
#include "stop.h"
#include "flush_subnormals.h"

/* y += A x with A column-major (rows x cols): independent axpys, no long add chains */
static inline void matvec_add(long rows, long cols, const double *restrict A,
                              const double *restrict x, double *restrict y)
{
    long i, j;
    for (j = 0; j < cols; ++j) {
        const double xj = x[j];
        const double *a = A + j * rows;
        for (i = 0; i < rows; ++i)
            y[i] += a[i] * xj;
    }
}

#include "newton.h"

/*
 * newton_solve at the compile-time sizes of this loop (NL_NW + NL_NZ unknowns, NL_NE
 * elements): the same tests and results; the small loops unrolled, the LU without calls.
 * Returns the iterations or -1 (as newton_solve).
 *
 * Up to 2 unknowns each iteration solves with J at its iterate in closed form (newton_solve's
 * iterates). Above, the LU of J costs ~NU^3 / 3 multiply-adds against ~NU^2 for a solve with its
 * factors, so the factors are kept from iteration to iteration and from step to step (lu_keep):
 * modified Newton, u <- u - J_f^-1 r(u), J_f the Jacobian where they were formed. They are formed
 * anew at the current iterate when the iteration does not contract (|d_i| > CONTRACT |d_{i-1}|)
 * and at every iteration from REUSE_ITERS on (plain Newton from there, so that a step plain
 * Newton solves within max_iter is not refused). The residual test is the rule's; the step test
 * |J_f^-1 r| <= tol s_u accepts with factors formed at this iterate (the rule's), or after an
 * iteration that contracted by CONTRACT (the remaining error is then below |d| / (1 - CONTRACT)):
 * never on the first iteration with older factors, whose Jacobian may belong to another state of
 * the elements (a contact that has opened since). lu->formed counts the factorizations.
 */
#ifndef NL_LU_REUSE
#define NL_LU_REUSE 0
#endif
enum { NU_ = NL_NW + NL_NZ, NE_ = NL_NE, REUSE_ITERS = NL_LU_REUSE ? 4 : 0 };
#define CONTRACT 0.25

typedef struct {
    double f[NU_ > 2 ? NU_ * NU_ : 1];
    long piv[NU_ > 2 ? NU_ : 1];
    int have;
    double formed;
} lu_keep;

/* d = -J_f^-1 r into d (lu_apply), after forming the factors at J when asked to (fresh) or
   when there are none; 1 when J is singular. *fresh: the factors are J's */
static inline int lu_step(lu_keep *restrict lu, const double *restrict J,
                          const double *restrict r, double *restrict d, int *fresh)
{
    if (*fresh || !lu->have) {
        copy(NU_ * NU_, J, lu->f);
        lu->have = 0;
        if (lu_factor(NU_, lu->f, lu->piv))
            return 1;
        lu->have = 1;
        lu->formed += 1.0;
        *fresh = 1;
    }
    copy(NU_, r, d);
    lu_apply(NU_, lu->f, lu->piv, d);
    return 0;
}

static inline long newton_fixed(double *restrict u, double *restrict r, double *restrict J,
                                double scale_r, double scale_u, double tol, long max_iter,
                                const double **arg, double **res, nl_int *iw, double *w,
                                double *rn, double *theta, lu_keep *restrict lu)
{
    /* as fmax(scale, DBL_MIN), without the library call */
    const double lim_r = tol * (scale_r > DBL_MIN ? scale_r : DBL_MIN);
    const double lim_u = tol * (scale_u > DBL_MIN ? scale_u : DBL_MIN);
    long it;
    int i, k;
    double dprev = INFINITY;
    for (it = 0;; ++it) {
        double m = 0.0, th = 0.0, d = 0.0;
        nl_residual(arg, res, iw, w, 0);
        for (i = 0; i < NU_; ++i) {
            const double a = fabs(r[i]);
            m = (a > m || a != a) ? a : m;
        }
        if (!(m < INFINITY))
            return -1;
        *rn = m;
        for (i = 0; i < NE_; ++i) {
            double row = 0.0;
            for (k = 0; k < NE_; ++k)
                row += fabs(J[k * NU_ + i] - (i == k ? 1.0 : 0.0));
            th = row > th ? row : th;
        }
        *theta = th;
        if (m <= lim_r)
            return it;
        if (NU_ <= 2) { /* d = -J^-1 r in closed form: one division on the critical path */
            if (NU_ == 1) {
                if (!(fabs(J[0]) > 0.0))
                    return -1;
                r[0] = -r[0] / J[0];
            } else {
                const double det = J[0] * J[NU_ + 1] - J[NU_] * J[1];
                const double r0 = r[0], r1 = r[NU_ - 1];
                double inv;
                if (!(fabs(det) > 0.0))
                    return -1;
                inv = 1.0 / det;
                r[0] = -(J[NU_ + 1] * r0 - J[NU_] * r1) * inv;
                r[NU_ - 1] = -(J[0] * r1 - J[1] * r0) * inv;
            }
            for (i = 0; i < NU_; ++i) {
                const double a = fabs(r[i]);
                d = (a > d || a != a) ? a : d;
            }
            if (d <= lim_u)
                return it;
            if (it == max_iter)
                return -1;
            for (i = 0; i < NU_; ++i)
                u[i] += r[i];
            continue;
        }
        {
            /* J_f d = -r with the kept factors (J stays the Jacobian at u: the modal loop's
               estimate uses it); formed anew when the iteration does not contract */
            double dv[NU_];
            int fresh = it >= REUSE_ITERS, ok;
            if (lu_step(lu, J, r, dv, &fresh))
                return -1;
            d = norm_inf(NU_, dv);
            if (!fresh && it > 0 && !(d <= CONTRACT * dprev)) {
                fresh = 1;
                if (lu_step(lu, J, r, dv, &fresh))
                    return -1;
                d = norm_inf(NU_, dv);
            }
            ok = fresh || it > 0; /* older factors: accepted after a contracting iteration */
            copy(NU_, dv, r);
            if (ok && d <= lim_u)
                return it;
            if (it == max_iter)
                return -1;
            for (i = 0; i < NU_; ++i)
                u[i] += r[i];
            dprev = d;
        }
    }
}
/*
 * One step's Newton solve (newton_fixed) with the loops' bookkeeping: the residual scale raised
 * by Q before and by the accepted u after, the statistics (stats[0..2, 4]: most and summed
 * iterations, largest residual and theta), and the failures: 1 (no convergence, or non-finite
 * element forces or rates: stats[3] the residual), 3 (theta = |B0 dg/dy|_inf, the elements'
 * stiffness, beyond theta_limit: stats[3] theta), else 0.
 */
static inline int solve_step(double *restrict u, double *restrict r, double *restrict J,
                             const double *restrict Q, double *scale, double *scale_u,
                             double tol, long max_iter, const double **arg, double **res,
                             nl_int *iw, double *w, double theta_limit, double *stats,
                             lu_keep *restrict lu)
{
    double rn = INFINITY, theta = 0.0;
    long it;
    *scale = grow(*scale, norm_inf(NL_NW, Q));
    it = newton_fixed(u, r, J, *scale, *scale_u, tol, max_iter, arg, res, iw, w, &rn, &theta,
                      lu);
    if (it < 0 || !(norm_inf(NL_NE, res[2]) < INFINITY)
        || !(norm_inf(NL_NZ, res[3]) < INFINITY)) {
        stats[3] = rn;
        return 1;
    }
    *scale_u = grow(*scale_u, norm_inf(NU_, u));
    *scale = grow(*scale, *scale_u);
    stats[1] += (double)it;
    if ((double)it > stats[0])
        stats[0] = (double)it;
    if (rn > stats[2])
        stats[2] = rn;
    if (theta > stats[4])
        stats[4] = theta;
    if (theta > theta_limit) {
        stats[3] = theta;
        return 3;
    }
    return 0;
}

#ifdef NL_NM
/*
 * The modal path of dtdyn_nl_run (compiled with NL_NM, NL_NH, NL_NST). The state is
 * x = [eta; g_{k-1}; ...; g_{k-NH/NE}]: NL_NM modal rows (a 2 x 2 rotation per oscillating mode,
 * 1 x 1 per real pole: A's modal block T is tridiagonal) and the element forces' history, whose
 * columns of A are H. The linear part of a step does not depend on the step's own element
 * forces, so it is formed once per step, before its Newton solve, and only g's columns follow:
 *
 *     eta_k = L_k + Bg g_{k-1},     L_{k+1} = T eta_k + [H Bf] [g_{k-1}; ...; g_{k-NH/NE}; f_k],
 *     Q_k = Cw L_k + Dwf f_k + (Cw Bg) g_{k-1}
 *
 * (Cw's history columns are zero): between two Newton solves only (Cw Bg) g_{k-1} lies on the
 * path from one step's element forces to the next step's Q. The modal rows are computed as
 * vectors of 4 (rows padded with zeros to NMP, outputs to NOP), in an order that puts T's 2 x 2
 * blocks first, so that T y = dia y + off y[partner] with the partner in the same vector.
 *
 * With NL_EXPLICIT (modal_explicit) the force polynomial is extrapolated from g_{k-1}, ...,
 * so Dwg = 0 and w_k = Q_k: without internal states a step evaluates the element laws once at
 * u = Q_k (explicit_step), with them Newton solves z only; theta is |(Cw Bg) dg/dy|
 * (explicit_theta).
 *
 * The embedded estimate (NST > 0, modal_quintic and modal_explicit) carries the local error of
 * the force polynomial, Eg nabla^{NST-1} g_k (nabla^{NST-1} g_k = sum_i stencil_i g_{k-i}),
 * through the dynamics linearized at the solution: with e_k the error of eta_k, Q_k errs by
 * Cw e_k, u_k by J^-1 [Cw e_k; 0] (J = dr/du, the Newton Jacobian at the accepted u) and g_k by
 * dg_k = K_k Cw e_k, K_k = dg/du J^-1 [I; 0] (the elements' tangent stiffness), so that
 *
 *     e_k = T e_{k-1} + Bs dg_{k-1} + Eg nabla^{NST-1} g_k,     Bs = Bg + sum_i H_i
 *
 * (Bs: g's weights over the steps of its polynomial summed, for an error that changes slowly
 * over them); stats[5 + i] = max over the samples of |Co_m e + Dog dg|_i. The recursion forms
 * Cw e_k from the previous step (generated/nonlinear.md):
 *
 *     Cw e_k = (Cw T) e_{k-1} + (Cw Bs) dg_{k-1} + (Cw Eg) nabla^{NST-1} g_k,
 *
 * so that the loop-carried path from dg_{k-1} to dg_k is two small products, not the sum over
 * the modes. The loop copies J, dg/du and g of each step into a block of EB steps (work +
 * dims[13]); at the block's end `estimate_prep` forms its gains K_k and differences (independent,
 * out of line), and during the next block the loop runs the recursion over it, one step of the
 * estimate (estimate_step; e and dg kept at the samples) after each step of the solution. In a
 * pass of its own the recursion is bound by its latency (each step's error feeds the next through
 * the elements' tangent stiffness); inside the loop the processor overlaps its chain with the
 * solution's, and it costs about its instructions (on P4 about half the time of the pass).
 *
 * mats beyond the general ones (column-major, modal rows padded to NMP, output rows to NOP):
 * T = [dia; off] (2 NMP), [H Bf] (NMP x (NH + NF)), Eg (NMP x NE), the stencil
 * (NST), Bg (NMP x NE), Bs (NMP x NE), Cw^T (NMP x NW), Cw Bg (NW x NE), [Co Dof Dog]
 * (NOP x (NM + NF + NE)), (Cw T)^T (NMP x NW), Cw Eg (NW x NE), Cw Bs (NW x NE), the forces
 * before t_0 ((NST - 1) x NE: g_{1-NST} .. g_{-1}, for the first steps' differences), |Cw Bg|
 * on the y rows (NEP x NE, explicit_rows). res[4] of
 * nl_residual: dg/du (NE x (NW + NZ)). dims[13], dims[14]: the estimate's blocks (offset in
 * work, EB steps): two sets (the block being stepped, the one whose recursion runs along) of
 * J (EB NU^2), dg/du (EB NE NU), g ((EB + NST - 1) NE), K (EB NW NEP4), nabla^{NST-1} g (EB NE);
 * then the samples' e and dg of a block (EB (NMP + NEP4)), whose outputs Co_m e + Dog dg
 * `estimate_outs` forms once per block: out of the steps' loop, the samples independent (in the
 * loop, one sample's four rows cost P4 about 3 ns per step at 1 sub-step). The recursion runs in
 * a basis of its own (`estimate_basis`) where outputs of one kind read half its rows.
 */
typedef double v4 __attribute__((vector_size(32), aligned(8))); /* 4 rows, loads unaligned */
#if defined(__FMA__) && defined(__AVX__)
#include <immintrin.h>
/* a * b + c in one rounding: the modal rows' products and sums fuse (about 15% of P4's loop),
   against the library's -ffp-contract=off (the loops are compared with the CasADi backend to the
   Newton tolerance, not bitwise; the Newton solve and the element laws stay unfused) */
#define VFMA(a, b, c) ((v4)_mm256_fmadd_pd((__m256d)(a), (__m256d)(b), (__m256d)(c)))
#else
#define VFMA(a, b, c) ((a) * (b) + (c))
#endif
#define VSPLAT(x) ((v4){(x), (x), (x), (x)})
enum { NMV = (NL_NM + 3) / 4, NMP = 4 * NMV, NOV = (NL_NO + 3) / 4, NOP = 4 * NOV };

/* y (+)= sum_c A_c x_c over nc padded columns of nv vectors each, as fused multiply-adds: one
   chain onto y for up to 3 columns, two partial sums (even and odd columns) beyond */
static inline void vmatvec(int nv, int nc, const double *restrict A, const double *restrict x,
                           v4 *restrict y, int add)
{
    const v4 z = {0.0, 0.0, 0.0, 0.0};
    int v, c;
    for (v = 0; v < nv; ++v) {
        v4 s0 = add ? y[v] : z, s1 = z;
        for (c = 0; c < nc; ++c) {
            const v4 a = *(const v4 *)(A + (c * nv + v) * 4);
            if (nc <= 3 || (c & 1) == 0)
                s0 = VFMA(a, VSPLAT(x[c]), s0);
            else
                s1 = VFMA(a, VSPLAT(x[c]), s1);
        }
        y[v] = nc <= 3 ? s0 : s0 + s1;
    }
}

/* sum of the 4 lanes of a * b over nv vectors */
static inline double vdot(int nv, const double *restrict a, const v4 *restrict b)
{
    v4 s = *(const v4 *)a * b[0];
    int v;
    for (v = 1; v < nv; ++v)
        s = VFMA(*(const v4 *)(a + 4 * v), b[v], s);
    return (s[0] + s[1]) + (s[2] + s[3]);
}

/* y_i = vdot of the rows A + i NMP (NMP doubles each) with x, for i < n, two rows at a time: their
   lanes summed pairwise together, (s0 + s1) + (s2 + s3) per row as in vdot */
static inline void vdots(int n, const double *restrict A, const v4 *restrict x,
                         double *restrict y)
{
    int i, v;
    for (i = 0; i + 1 < n; i += 2) {
        const double *a = A + i * NMP, *b = a + NMP;
        v4 s = *(const v4 *)a * x[0], t = *(const v4 *)b * x[0], lo, hi;
        for (v = 1; v < NMV; ++v) {
            s = VFMA(*(const v4 *)(a + 4 * v), x[v], s);
            t = VFMA(*(const v4 *)(b + 4 * v), x[v], t);
        }
        lo = (v4){s[0], t[0], s[2], t[2]};
        hi = (v4){s[1], t[1], s[3], t[3]};
        lo += hi;
        y[i] = lo[0] + lo[2];
        y[i + 1] = lo[1] + lo[3];
    }
    if (i < n)
        y[i] = vdot(NMV, A + i * NMP, x);
}

/* T y = dia y + off y[partner]: the 2 x 2 blocks come first, so a row's partner is the other
   lane of its pair (lanes 0-1, 2-3); off = 0 on the real poles' rows */
static inline void vblock(const double *restrict T, const v4 *restrict y, v4 *restrict out)
{
    int v;
    for (v = 0; v < NMV; ++v) {
        const v4 a = y[v], b = {a[1], a[0], a[3], a[2]};
        out[v] = VFMA(*(const v4 *)(T + 4 * v), a, *(const v4 *)(T + NMP + 4 * v) * b);
    }
}

/* *mx = the running max of |*a| per lane; a NaN lane stays NaN */
typedef long long v4i __attribute__((vector_size(32), aligned(8)));
static inline void vmax_abs(v4 *restrict mx, const v4 *restrict a)
{
    const v4i magnitude = {0x7fffffffffffffffLL, 0x7fffffffffffffffLL, 0x7fffffffffffffffLL,
                           0x7fffffffffffffffLL};
    const v4 m = (v4)((v4i)*a & magnitude);
    const v4i take = (m > *mx) | (m != m);
    *mx = (v4)(((v4i)m & take) | ((v4i)*mx & ~take));
}

/*
 * K = dg/du J^-1 [I; 0] (NE x NW, column-major) from J (NU x NU) and dg/du (NE x NU): J^-1 in
 * closed form up to NU = 2, else from one LU with partial pivoting of a copy of J, K^T solved
 * with its transpose (NE solves of NU^2 against NW solves and the product).
 */
static inline void tangent_gain(const double *restrict J, const double *restrict Gu,
                                double *restrict K)
{
    enum { nu = NL_NW + NL_NZ, ne = NL_NE, nw = NL_NW };
    int i, c, r;
    if (nu > 2) { /* K^T = [I 0] J^-T (dg/du)^T: one LU, NE transposed solves */
        double Jf[nu > 2 ? nu * nu : 1], y[nu];
        long piv[nu];
        copy(nu * nu, J, Jf);
        lu_factor(nu, Jf, piv);
        for (i = 0; i < ne; ++i) {
            for (c = 0; c < nu; ++c)
                y[c] = -Gu[c * ne + i]; /* lu_apply_t solves J^T d = -rhs */
            lu_apply_t(nu, Jf, piv, y);
            for (r = 0; r < nw; ++r)
                K[r * ne + i] = y[r];
        }
        return;
    }
    {
        double Ji[nu * nw]; /* the first NW columns of J^-1, column-major */
        if (nu == 1) {
            Ji[0] = 1.0 / J[0];
        } else {
            const double inv = 1.0 / (J[0] * J[nu + 1] - J[nu] * J[1]);
            Ji[0] = J[nu + 1] * inv;
            Ji[1] = -J[1] * inv;
            if (nw == 2) {
                Ji[nu] = -J[nu] * inv;
                Ji[nu + 1] = J[0] * inv;
            }
        }
        for (r = 0; r < nw; ++r)
            for (i = 0; i < ne; ++i) {
                double s = 0.0;
                for (c = 0; c < nu; ++c)
                    s += Gu[c * ne + i] * Ji[r * nu + c];
                K[r * ne + i] = s;
            }
    }
}

/*
 * The explicit force polynomial (NL_EXPLICIT, modal_explicit): Dwg = 0, so w_k = Q_k. Its
 * stability measure is the weight of g_k on the next step's displacements, theta =
 * |(Cw Bg) dg/dy|_inf (y rows and columns; generated/nonlinear.md). Each element's force depends
 * on its own deformation only, so dg/dy is diagonal and theta = max_i sum_k |Cw Bg|_ik |g_k'|
 * (CBa = |Cw Bg| on the y rows, ne x ne, its rows padded to NEP). `explicit_rows` gives the
 * rows sum_k |Cw Bg|_ik |g_k'| + 0 g_i as NEV vectors: NaN where g_i or a g_k' is not finite.
 */
enum { NEV = (NL_NE + 3) / 4, NEP = 4 * NEV };

static inline void explicit_rows(const double *restrict g, const double *restrict Gu,
                                 const double *restrict CBa, v4 *restrict rows)
{
    int v, k, l;
    for (v = 0; v < NEV; ++v) {
        v4 gv = VSPLAT(0.0);
        for (l = 0; l < 4 && 4 * v + l < NL_NE; ++l)
            gv[l] = g[4 * v + l];
        rows[v] = gv * 0.0;
        for (k = 0; k < NL_NE; ++k)
            rows[v] = VFMA(*(const v4 *)(CBa + (k * NEV + v) * 4),
                           VSPLAT(fabs(Gu[k * NL_NE + k])), rows[v]);
    }
}

/* theta from the rows: the largest, NaN when a row is not finite (0 * sum) */
static inline double explicit_theta(const double *restrict rows)
{
    double th = rows[0], sum = rows[0];
    int i;
    for (i = 1; i < NL_NE; ++i) {
        th = rows[i] > th ? rows[i] : th;
        sum += rows[i];
    }
    return th + 0.0 * sum;
}

#if defined(NL_EXPLICIT) && NL_NZ == 0
/*
 * The explicit polynomial without internal states takes no Newton solve: u = Q_k exactly (arg[0]
 * is Q) and the element laws are evaluated once a step (no iterations counted). Its checks do not
 * branch at every step: each step stores its rows (explicit_rows) in a block of TB steps, and
 * keeps, lane by lane, their running largest value and whether every one so far was within
 * theta_limit (a NaN is not); at the block's end `explicit_block` reads the block's largest
 * theta from the first, and only when the second failed looks for the first step beyond, so
 * that a failure is found within TB steps and reported at its own step (the steps after it are
 * discarded with the run).
 */
enum { TB = 256 };

static inline void explicit_step(const double *restrict g, const double *restrict Gu,
                                 const double *restrict CBa, const double **arg, double **res,
                                 nl_int *iw, double *w, double theta_limit,
                                 double *restrict tb, v4i *restrict ok, v4 *restrict mx)
{
    v4 rows[NEV];
    int v;
    nl_residual(arg, res, iw, w, 0);
    explicit_rows(g, Gu, CBa, rows);
    for (v = 0; v < NEV; ++v) {
        const v4i take = rows[v] > mx[v];
        *(v4 *)(tb + 4 * v) = rows[v];
        ok[v] &= (v4i)(rows[v] <= VSPLAT(theta_limit));
        mx[v] = (v4)(((v4i)rows[v] & take) | ((v4i)mx[v] & ~take));
    }
}

/* The block's check (explicit_step; ok and mx start the next block): 0 with *th_max raised to
   the block's largest theta, or the failure of its first step beyond theta_limit (1: element
   forces not finite, stats[3] inf; 3: stats[3] theta), fail[0] its step index. Inlined: out of
   line, GCC lays the loop out so that P4's step takes ~0.7 ns longer (measured) */
#ifdef __GNUC__
__attribute__((always_inline))
#endif
static inline int explicit_block(long nb, long first, const double *restrict tb,
                                 v4i *restrict ok, v4 *restrict mx, double theta_limit,
                                 double *th_max, double *stats, long *fail)
{
    long k;
    int v, l, bad = 0;
    double th = 0.0, seen = *th_max;
    for (v = 0; v < NEV; ++v) {
        for (l = 0; l < 4 && 4 * v + l < NL_NE; ++l)
            seen = mx[v][l] > seen ? mx[v][l] : seen;
        bad |= !(ok[v][0] & ok[v][1] & ok[v][2] & ok[v][3]);
        ok[v] = (v4i){-1, -1, -1, -1};
        mx[v] = VSPLAT(0.0);
    }
    for (k = 0; bad && k < nb; ++k) {
        th = explicit_theta(tb + k * NEP);
        if (!(th <= theta_limit))
            break;
        *th_max = th > *th_max ? th : *th_max;
    }
    if (!bad || k == nb) {
        *th_max = seen;
        return 0;
    }
    fail[0] = first + k;
    stats[3] = th == th ? th : INFINITY;
    stats[4] = stats[4] > *th_max ? stats[4] : *th_max;
    return th == th ? 3 : 1;
}
#endif

enum { NWV = (NL_NW + 3) / 4, NEV4 = (NL_NE + 3) / 4, NEP4 = 4 * NEV4 };
/* The explicit polynomial without internal states or velocities: u = y, and each element's force
   depends on its own deformation only (explicit_rows), so K_k = dg/dy is diagonal: the loop keeps
   its diagonal, and dg_k = K_k Cw e_k is a product lane by lane (NWV = NEV4) */
#if defined(NL_EXPLICIT) && NL_NZ == 0 && NL_NW == NL_NE
#define DIAGONAL_GAIN 1
#else
#define DIAGONAL_GAIN 0
#endif

/*
 * The embedded estimate (modal_run's comment). `estimate_prep`, once per block of nb steps: the
 * gains K_k, their columns padded to NEP4 rows (the loop writes them itself for the explicit
 * polynomial without internal states, whose K_k is dg/du), and the differences
 * nabla^{NST-1} g_k (g_k at row k + NST - 1 of Gb); then the last NST - 1 forces copied to the
 * front of Gn, the next block's g.
 */
#ifdef __GNUC__
/* out of line (it runs once per block). An estimate, not the solution, so its products and sums
   may fuse (fma; GCC here, clang's pragma in the body) */
#ifdef __clang__
#define ESTIMATE_ATTRIBUTES __attribute__((noinline))
#else
#define ESTIMATE_ATTRIBUTES __attribute__((noinline, optimize("fp-contract=fast")))
#endif
static void estimate_prep(long nb, const double *restrict stencil, const double *restrict Jb,
                          const double *restrict Gub, double *restrict Gb, double *restrict Kb,
                          double *restrict Db, double *restrict Gn) ESTIMATE_ATTRIBUTES;
#endif
static void estimate_prep(long nb, const double *restrict stencil, const double *restrict Jb,
                          const double *restrict Gub, double *restrict Gb, double *restrict Kb,
                          double *restrict Db, double *restrict Gn)
{
    enum { ne = NL_NE, nw = NL_NW, nu = NL_NW + NL_NZ, nst = NL_NST };
    long k, c;
#ifdef __clang__
#pragma clang fp contract(fast)
#endif
#if defined(NL_EXPLICIT) && NL_NZ == 0
    (void)Jb, (void)Gub, (void)Kb; /* K_k = dg/du: the loop wrote it */
#else
    for (k = 0; k < nb; ++k) { /* K_k, its columns padded to NEP4 rows */
        double *Kp = Kb + k * nw * NEP4, K[ne * nw];
        long r, i;
        tangent_gain(Jb + k * nu * nu, Gub + k * ne * nu, K);
        for (r = 0; r < nw; ++r)
            for (i = 0; i < NEP4; ++i)
                Kp[r * NEP4 + i] = i < ne ? K[r * ne + i] : 0.0;
    }
#endif
    for (k = 0; k < nb * ne; ++k) {
        double s = stencil[0] * Gb[k + (nst - 1) * ne];
        for (c = 1; c < nst; ++c)
            s += stencil[c] * Gb[k + (nst - 1 - c) * ne];
        Db[k] = s;
    }
    for (k = 0; k + 1 < nst; ++k)
        copy(ne, Gb + (nb + k) * ne, Gn + k * ne);
}

/* y = [<A_0, x>, <A_1, x>, ...] for the NW rows A + i NMP, 4 rows to a vector: the rows' products
   summed pairwise across lanes (lanes 0 + 1 and 2 + 3, then the two halves) */
static inline void vdots4(const double *restrict A, const v4 *restrict x, v4 *restrict y)
{
    int q, l, v;
    for (q = 0; q < NWV; ++q) {
        v4 p[4], t0, t1;
        for (l = 0; l < 4; ++l) {
            const double *a = A + (4 * q + l) * NMP;
            p[l] = VSPLAT(0.0);
            if (4 * q + l < NL_NW) {
                p[l] = *(const v4 *)a * x[0];
                for (v = 1; v < NMV; ++v)
                    p[l] = VFMA(*(const v4 *)(a + 4 * v), x[v], p[l]);
            }
        }
        t0 = (v4){p[0][0], p[1][0], p[0][2], p[1][2]} + (v4){p[0][1], p[1][1], p[0][3], p[1][3]};
        t1 = (v4){p[2][0], p[3][0], p[2][2], p[3][2]} + (v4){p[2][1], p[3][1], p[2][3], p[3][3]};
        y[q] = (v4){t0[0], t0[1], t1[0], t1[1]} + (v4){t0[2], t0[3], t1[2], t1[3]};
    }
}

/*
 * One step of the estimate's recursion (a row of a block: its differences dn, its gains K with
 * their columns padded to NEP4), e and dg (NEV4 vectors) carried:
 *     Cw e_k = (Cw Eg) dn_k + (Cw Bs) dg_{k-1} + (Cw T) e_{k-1},   dg_k = K_k Cw e_k,
 *     e_k = T e_{k-1} + Eg dn_k + Bs dg_{k-1}
 * (the terms of dg_{k-1} last but one, those of e_{k-1} last: the paths from the previous step
 * short). em: T, Eg, Bs and (Cw T)^T in the estimate's basis (estimate_basis); cw: the columns
 * of Cw Eg, then of Cw Bs, padded to 4 NWV rows.
 */
static inline void estimate_step(const double *const *em, const v4 *restrict cw,
                                 const double *restrict dn, const double *restrict K,
                                 v4 *restrict e, v4 *restrict dg)
{
    enum { ne = NL_NE, nw = NL_NW };
    const double *Tb = em[0], *Eg = em[1], *Bs = em[2], *CTw = em[3];
    v4 ce[NWV], bd[ne], y[NWV];
    int q, c, v;
    for (c = 0; c < ne; ++c)
        bd[c] = VSPLAT(dg[c / 4][c % 4]);
    vdots4(CTw, e, y);
    for (q = 0; q < NWV; ++q) {
        v4 s = cw[q] * VSPLAT(dn[0]);
        for (c = 1; c < ne; ++c)
            s = VFMA(cw[c * NWV + q], VSPLAT(dn[c]), s);
        for (c = 0; c < ne; ++c)
            s = VFMA(cw[(ne + c) * NWV + q], bd[c], s);
        ce[q] = s + y[q];
    }
    for (v = 0; v < NMV; ++v) {
        const v4 x = e[v], xp = {x[1], x[0], x[3], x[2]};
        v4 s = *(const v4 *)(Tb + NMP + 4 * v) * xp;
        for (c = 0; c < ne; ++c)
            s = VFMA(*(const v4 *)(Eg + (c * NMV + v) * 4), VSPLAT(dn[c]), s);
        for (c = 0; c < ne; ++c)
            s = VFMA(*(const v4 *)(Bs + (c * NMV + v) * 4), bd[c], s);
        e[v] = VFMA(*(const v4 *)(Tb + 4 * v), x, s);
    }
#if DIAGONAL_GAIN
    (void)nw;
    for (q = 0; q < NEV4; ++q)
        dg[q] = *(const v4 *)(K + q * 4) * ce[q];
#else
    for (q = 0; q < NEV4; ++q) {
        v4 s = *(const v4 *)(K + q * 4) * VSPLAT(ce[0][0]);
        for (c = 1; c < nw; ++c)
            s = VFMA(*(const v4 *)(K + (c * NEV4 + q) * 4), VSPLAT(ce[c / 4][c % 4]), s);
        dg[q] = s;
    }
#endif
}

/* the running largest and smallest values, lane by lane, of y: NaN lanes of y skipped */
static inline void vrange(v4 *restrict mx, v4 *restrict mn, const v4 *restrict y)
{
#if defined(__FMA__) && defined(__AVX__)
    *mx = (v4)_mm256_max_pd((__m256d)*y, (__m256d)*mx);
    *mn = (v4)_mm256_min_pd((__m256d)*y, (__m256d)*mn);
#else
    typedef long long v4m __attribute__((vector_size(32), aligned(8)));
    const v4m up = *y > *mx, down = *y < *mn;
    *mx = (v4)(((v4m)*y & up) | ((v4m)*mx & ~up));
    *mn = (v4)(((v4m)*y & down) | ((v4m)*mn & ~down));
#endif
}

/* the running largest and smallest values (mx, mn: NOV vectors) of Co_m e + Dog dg over m samples
   of ob (each [e (NMP); dg (NEP4)]), from the columns of [Co_m Dog] (NOP rows, estimate_basis):
   once per block, out of the steps' loop, its samples independent of each other. Columns that
   are zero are left out: every second one of Co_m (stride 2) and Dog (dog 0) where
   estimate_basis found them so (kind) */
#ifdef __GNUC__
__attribute__((always_inline))
#endif
static inline void outs_rows(long m, const double *restrict Co, const double *restrict ob,
                             v4 *restrict mx, v4 *restrict mn, const int stride, const int dog)
{
    enum { nx = NMP + NEP4 };
    long k;
    int q, c;
    for (k = 0; k < m; ++k) {
        const double *o = ob + k * nx;
        for (q = 0; q < NOV; ++q) {
            v4 s0 = *(const v4 *)(Co + 4 * q) * VSPLAT(o[0]), s1;
            for (c = stride; c < NL_NM; c += stride)
                s0 = VFMA(*(const v4 *)(Co + c * NOP + 4 * q), VSPLAT(o[c]), s0);
            if (dog) {
                s1 = *(const v4 *)(Co + NL_NM * NOP + 4 * q) * VSPLAT(o[NMP]);
                for (c = 1; c < NL_NE; ++c)
                    s1 = VFMA(*(const v4 *)(Co + (NL_NM + c) * NOP + 4 * q),
                              VSPLAT(o[NMP + c]), s1);
                s0 += s1;
            }
            vrange(mx + q, mn + q, &s0);
        }
    }
}

#ifdef __GNUC__
static void estimate_outs(long m, const double *restrict Co, const double *restrict ob,
                          v4 *restrict mx, v4 *restrict mn, int kind) ESTIMATE_ATTRIBUTES;
#endif
static void estimate_outs(long m, const double *restrict Co, const double *restrict ob,
                          v4 *restrict mx, v4 *restrict mn, int kind)
{
    if (kind == 2)
        outs_rows(m, Co, ob, mx, mn, 2, 0);
    else if (kind == 1)
        outs_rows(m, Co, ob, mx, mn, 1, 0);
    else
        outs_rows(m, Co, ob, mx, mn, 1, 1);
}

/*
 * The estimate's basis: em = T (dia; off), Eg, Bs, (Cw T)^T and [Co_m Dog] (mats' layouts) for
 * estimate_step and estimate_outs. The outputs read a 2 x 2 block's rows (a, b) through
 * Co_a e_a + Co_b e_b. Where these two columns are parallel on every output row (outputs of one
 * kind, x say, read a mode through one combination of its pair), the estimate can carry
 * e'_a = alpha e_a + beta e_b (alpha, beta: the pair's entries on its largest output row) and
 * e'_b = e_b (e_a when |beta| > |alpha|): e' = R e, T' = R T R^-1 (again a 2 x 2 block),
 * Eg' = R Eg, Bs' = R Bs, (Cw T)' = (Cw T) R^-1 and Co' = Co R^-1, whose column b is zero (set
 * so: the columns parallel to 64 ulps of the pair's largest entry squared). The same recursion
 * in other coordinates (its numbers differ by rounding), whose outputs take half the products.
 * Used only when every second column of Co' is zero and so is Dog (P4's x: kind 2); else the
 * matrices as given, kind 1 when Dog is zero, 0 otherwise.
 */
static int estimate_basis(const double *const *mats, double *restrict Te, double *restrict Ege,
                          double *restrict Bse, double *restrict CTe, double *restrict Coe)
{
    enum { nm = NL_NM, ne = NL_NE, nw = NL_NW, no = NL_NO, nf = NL_NF };
    const double *T = mats[10], *Eg = mats[12], *Bs = mats[15], *CT = mats[19], *Co = mats[18];
    double R[NMV * 2][2][2], Ri[NMV * 2][2][2];
    int i, c, q, dog = 1, all = 1;
    copy(2 * NMP, T, Te);
    copy(ne * NMP, Eg, Ege);
    copy(ne * NMP, Bs, Bse);
    copy(nw * NMP, CT, CTe);
    copy(nm * NOP, Co, Coe);
    copy(ne * NOP, Co + (nm + nf) * NOP, Coe + nm * NOP);
    for (c = 0; c < ne * NOP; ++c)
        dog &= Coe[nm * NOP + c] == 0.0;
    for (q = 0; 2 * q + 1 < nm && all && dog; ++q) { /* the pairs' R, R^-1 */
        const int a = 2 * q, b = a + 1;
        double big = -1.0, al = 0.0, be = 0.0;
        int top = 0;
        for (i = 0; i < no; ++i) {
            const double w = fabs(Co[a * NOP + i]) + fabs(Co[b * NOP + i]);
            if (w > big) {
                big = w;
                top = i;
            }
        }
        if (big == 0.0 || (T[NMP + a] == 0.0 && T[NMP + b] == 0.0)) {
            /* not read, or two real poles (R = I): column b must be zero as it is */
            for (i = 0; i < no; ++i)
                all &= Co[b * NOP + i] == 0.0;
            R[q][0][0] = R[q][1][1] = Ri[q][0][0] = Ri[q][1][1] = 1.0;
            R[q][0][1] = R[q][1][0] = Ri[q][0][1] = Ri[q][1][0] = 0.0;
            continue;
        }
        al = Co[a * NOP + top];
        be = Co[b * NOP + top];
        if (!(big < INFINITY)) {
            all = 0;
            break;
        }
        for (i = 0; i < no; ++i) /* parallel: |alpha Co_b - beta Co_a| within 64 ulps */
            all &= fabs(al * Co[b * NOP + i] - be * Co[a * NOP + i]) <= 0x1p-46 * big * big;
        R[q][0][0] = al;
        R[q][0][1] = be;
        if (fabs(al) >= fabs(be)) { /* e' = (alpha e_a + beta e_b, e_b) */
            R[q][1][0] = 0.0;
            R[q][1][1] = 1.0;
            Ri[q][0][0] = 1.0 / al;
            Ri[q][0][1] = -be / al;
            Ri[q][1][0] = 0.0;
            Ri[q][1][1] = 1.0;
        } else { /* e' = (alpha e_a + beta e_b, e_a) */
            R[q][1][0] = 1.0;
            R[q][1][1] = 0.0;
            Ri[q][0][0] = 0.0;
            Ri[q][0][1] = 1.0;
            Ri[q][1][0] = 1.0 / be;
            Ri[q][1][1] = -al / be;
        }
    }
    if (!(all && dog) || (nm & 1)) /* every second column zero, or the matrices as given */
        return dog;
    for (q = 0; 2 * q + 1 < nm; ++q) {
        const int a = 2 * q, b = a + 1;
        double (*r)[2] = R[q], (*ri)[2] = Ri[q];
        double t[2][2], u[2][2], tt[2][2];
        int j, l;
        tt[0][0] = T[a];
        tt[0][1] = T[NMP + a];
        tt[1][0] = T[NMP + b];
        tt[1][1] = T[b];
        for (i = 0; i < 2; ++i) /* T' = R T R^-1 */
            for (j = 0; j < 2; ++j)
                t[i][j] = r[i][0] * tt[0][j] + r[i][1] * tt[1][j];
        for (i = 0; i < 2; ++i)
            for (j = 0; j < 2; ++j)
                u[i][j] = t[i][0] * ri[0][j] + t[i][1] * ri[1][j];
        Te[a] = u[0][0];
        Te[NMP + a] = u[0][1];
        Te[NMP + b] = u[1][0];
        Te[b] = u[1][1];
        for (c = 0; c < ne; ++c) { /* R Eg, R Bs */
            const double *x[2] = {Eg + c * NMP, Bs + c * NMP};
            double *y[2] = {Ege + c * NMP, Bse + c * NMP};
            for (l = 0; l < 2; ++l) {
                const double xa = x[l][a], xb = x[l][b];
                y[l][a] = r[0][0] * xa + r[0][1] * xb;
                y[l][b] = r[1][0] * xa + r[1][1] * xb;
            }
        }
        for (c = 0; c < nw; ++c) { /* (Cw T) R^-1 */
            const double xa = CT[c * NMP + a], xb = CT[c * NMP + b];
            CTe[c * NMP + a] = xa * ri[0][0] + xb * ri[1][0];
            CTe[c * NMP + b] = xa * ri[0][1] + xb * ri[1][1];
        }
        for (i = 0; i < NOP; ++i) { /* Co R^-1: column b zero */
            const double xa = Co[a * NOP + i], xb = Co[b * NOP + i];
            Coe[a * NOP + i] = xa * ri[0][0] + xb * ri[1][0];
            Coe[b * NOP + i] = 0.0;
        }
    }
    return 2;
}

static int modal_run(const long *dims, const double *const *mats, const double *restrict force,
                     double *restrict x, double *restrict u, double *restrict g,
                     double *restrict rate, double *restrict out, double tol,
                     double theta_limit, double *stats, long *fail, double *restrict work,
                     nl_int *restrict iwork)
{
    enum { nf = NL_NF, ne = NL_NE, nw = NL_NW, nz = NL_NZ, no = NL_NO, nu = NL_NW + NL_NZ };
    enum { nm = NL_NM, nh = NL_NH, nst = NL_NST };
    const long n_samples = dims[6], S = dims[7], max_iter = dims[8], nzo = dims[9];
    const long eb = nst > 0 ? dims[14] : 0; /* the estimate's block: EB steps */
    const double *Dwf = mats[4], *Dwg = mats[5], *par = mats[6];
    const double *Tb = mats[10], *HB = mats[11];
    const double *Bgm = mats[14], *CwT = mats[16], *CB = mats[17];
    const double *Cout = mats[18];
#ifdef NL_EXPLICIT
    const double *CBa = mats[23];
#endif
    const double h = par[nw * ne];
    double f[nf + 1], Q[nw + 1], zold[nz + 1], rold[nz + 1], r[nu + 1], J[nu * nu + 1];
    double Gu[ne * nu + 1]; /* dg/du at the accepted u (the estimate's) */
    v4 eta[NMV], Lx[NMV], ov[NOV];
    double CL[nw + 1];
    /* the force history g_{k-1}, ..., g_{k-NH/NE} (the columns H of [H Bf]) as a ring: g_k is
       written at ring + ih and ring + ih + nh, so ring + ih always holds the history in order */
    double ring[2 * nh + 1];
    long ih = 0;
    double *cw = work;  /* CasADi work */
    /* the estimate (the comment above): two sets of a block's J, dg/du, g (after NST - 1
       earlier), K, differences (sets[p]: the block being stepped, sets[1 - p]: the one whose
       recursion runs along once have), the samples' e and dg Ob (nout of them); e, dg and the
       largest and smallest outputs carried; the columns of Cw Eg and Cw Bs as vectors; sc: steps
       to the next sample */
    enum { nx = NMP + NEP4 };
    const long set = eb * (nu * nu + ne * nu + NEP4 * nw + ne) + (eb + (nst > 0 ? nst - 1 : 0)) * ne;
    double *sets[2][5], *Ob = work + (nst > 0 ? dims[13] : 0) + 2 * set;
    v4 e[NMV], dgv[NEV4], mx[NOV], mn[NOV], cwv[2 * ne * NWV + 1];
    /* the estimate's T, Eg, Bs, (Cw T)^T and [Co_m Dog] (estimate_basis), its outputs' kind */
    double Te[2 * NMP], Ege[ne * NMP], Bse[ne * NMP], CTe[nw * NMP], Coe[(nm + ne) * NOP];
    const double *em[4] = {Te, Ege, Bse, CTe};
    const int okind = nst > 0 ? estimate_basis(mats, Te, Ege, Bse, CTe, Coe) : 0;
    long kb = 0, p = 0, have = 0, sc = 1, nout = 0;
    const double *arg[5];
    double *res[5];
    lu_keep lu; /* the kept LU factors (newton_fixed), their count in stats[5 + no] */
    double scale = 0.0, scale_u = 0.0;
    double th_max = 0.0; /* the explicit polynomial's largest theta (explicit_theta) */
#if defined(NL_EXPLICIT) && NL_NZ == 0
    double tb[TB * NEP]; /* the rows of the steps not checked yet (explicit_step) */
    v4i ok[NEV];
    v4 mx_th[NEV];
    long kt = 0;
#endif
    long n, j, i, k, c;
    int rc;
    arg[0] = u; arg[1] = Q; arg[2] = zold; arg[3] = rold; arg[4] = par;
    res[0] = r; res[1] = J; res[2] = g; res[3] = rate; res[4] = Gu;
#if defined(NL_EXPLICIT) && NL_NZ == 0
    /* r = w - Q = 0 and J = I: neither is evaluated (the estimate copies this J); the laws
       are evaluated at u = Q itself (u gets Q at the end) */
    arg[0] = Q;
    res[0] = res[1] = 0;
    for (i = 0; i < nu * nu; ++i)
        J[i] = i % (nu + 1) == 0 ? 1.0 : 0.0;
    (void)Dwg, (void)h, (void)tol, (void)max_iter, (void)scale, (void)scale_u;
#endif
    for (i = 0; i < 6 + no; ++i)
        stats[i] = 0.0;
    lu.have = 0;
    lu.formed = 0.0;
    /* L_0 = eta_0 - Bg g_{-1}, g_{-1} = g (the forces given): every step then reads g_{k-1}
       where the element laws left it, in g (also the linear predictor's) */
    for (v4 *p = Lx; p < Lx + NMV; ++p)
        *p = (v4){0.0, 0.0, 0.0, 0.0};
    copy(nm, x, (double *)Lx);
    for (i = 0; i < NMV; ++i)
        for (c = 0; c < ne; ++c)
            Lx[i] -= *(const v4 *)(Bgm + (c * NMV + i) * 4) * g[c];
    copy(nh, x + nm, ring);
    copy(nh, x + nm, ring + nh);
    vdots(nw, CwT, Lx, CL);
    zero(nw, Q); /* (written at every step; the explicit loop's u after the last) */
    for (i = 0; i < NMV; ++i)
        e[i] = (v4){0.0, 0.0, 0.0, 0.0};
    for (i = 0; i < NOV; ++i)
        mx[i] = mn[i] = (v4){0.0, 0.0, 0.0, 0.0};
#if defined(NL_EXPLICIT) && NL_NZ == 0
    for (i = 0; i < NEV; ++i) {
        ok[i] = (v4i){-1, -1, -1, -1};
        mx_th[i] = VSPLAT(0.0);
    }
#endif
    for (c = 0; c < 2; ++c) {
        double *b = work + (nst > 0 ? dims[13] : 0) + c * set;
        sets[c][0] = b;
        sets[c][1] = b + eb * nu * nu;
        sets[c][2] = sets[c][1] + eb * ne * nu;
        sets[c][3] = sets[c][2] + (eb + (nst > 0 ? nst - 1 : 0)) * ne;
        sets[c][4] = sets[c][3] + eb * NEP4 * nw;
        zero(eb * NEP4 * nw, sets[c][3]); /* K's padding */
    }
    for (k = 0; k + 1 < nst; ++k) /* g before t_0, oldest first */
        copy(ne, mats[22] + k * ne, sets[0][2] + k * ne);
    for (c = 0; c < 2 * ne * NWV; ++c) /* the columns of Cw Eg and Cw Bs, padded */
        for (i = 0; i < 4; ++i) {
            const long col = c / NWV, row = 4 * (c % NWV) + i;
            cwv[c][i] = row < nw ? (col < ne ? mats[20][col * nw + row]
                                            : mats[21][(col - ne) * nw + row]) : 0.0;
        }
    for (i = 0; i < NEV4; ++i)
        dgv[i] = VSPLAT(0.0);
    n = 0;
    j = 0;
    while (n < n_samples) {
        for (;;) {
            const double *f0 = force + n * nf;
            const double *f1 = (n + 1 < n_samples) ? f0 + nf : f0;
            const long nsub = (n + 1 < n_samples) ? S : 1;
            if (j == 0 && (n & 1023) == 0 && dtdyn_stop_flag)
                return DTDYN_STOPPED;
            if (j == 0) { /* the sample itself: f_n (no division on the way) */
                copy(nf, f0, f);
            } else {
                const double cf = (double)j / (double)S;
                for (i = 0; i < nf; ++i)
                    f[i] = f0[i] + cf * (f1[i] - f0[i]);
            }
            /* eta_k = L_k + Bg g_{k-1}; Q_k = (Cw L_k + Dwf f_k) + (Cw Bg) g_{k-1} */
            for (i = 0; i < NMV; ++i)
                eta[i] = Lx[i];
            vmatvec(NMV, ne, Bgm, g, eta, 1);
            for (i = 0; i < nw; ++i) { /* sums started from their first terms (no 0 + x) */
                double a = nf > 0 ? Dwf[i] * f[0] : 0.0, b = CB[i] * g[0];
                for (c = 1; c < nf; ++c)
                    a += Dwf[c * nw + i] * f[c];
                for (c = 1; c < ne; ++c)
                    b += CB[c * nw + i] * g[c];
                Q[i] = (a + CL[i]) + b;
            }
#if !defined(NL_EXPLICIT) || NL_NZ > 0
            /* the linear predictor u = [Q + Dwg g_{k-1}; z_{k-1} + h z'_{k-1}] */
            for (i = 0; i < nw; ++i) {
                double b = 0.0;
                for (c = 0; c < ne; ++c)
                    b += Dwg[c * nw + i] * g[c];
                u[i] = Q[i] + b;
            }
            copy(nz, u + nw, zold);
            copy(nz, rate, rold);
            for (i = 0; i < nz; ++i)
                u[nw + i] = zold[i] + h * rold[i];
#endif
            /* the next step's linear part: L_{k+1} = T eta_k + [H Bf] [history; f_k], Cw L_{k+1};
               f_k and the older history first, g_{k-1} (known last) added to them */
            vmatvec(NMV, nh - ne, HB + ne * NMP, ring + ih + ne, Lx, 0);
            vmatvec(NMV, nf, HB + nh * NMP, f, Lx, NL_NH > NL_NE);
            if (nh > 0)
                vmatvec(NMV, ne, HB, ring + ih, Lx, 1); /* g_{k-1} (the smooth past at k = 0) */
            {
                v4 t[NMV];
                vblock(Tb, eta, t);
                for (i = 0; i < NMV; ++i)
                    Lx[i] = t[i] + Lx[i];
            }
            vdots(nw, CwT, Lx, CL);
            /* Newton under the shared acceptance rule (newton_solve), scale fixed per step */
#if defined(NL_EXPLICIT) && NL_NZ == 0
            explicit_step(g, Gu, CBa, arg, res, iwork, cw, theta_limit, tb + kt * NEP, ok,
                          mx_th);
            rc = 0;
            if (++kt == TB) {
                rc = explicit_block(kt, n * S + j + 1 - kt, tb, ok, mx_th, theta_limit, &th_max,
                                    stats, fail);
                if (rc)
                    return rc;
                kt = 0;
            }
#elif defined(NL_EXPLICIT) /* Newton for the internal states only (w = Q) */
            rc = solve_step(u, r, J, Q, &scale, &scale_u, tol, max_iter, arg, res, iwork, cw,
                            INFINITY, stats, &lu);
            if (!rc) {
                v4 rows[NEV];
                double th;
                explicit_rows(g, Gu, CBa, rows);
                th = explicit_theta((const double *)rows);
                th_max = th > th_max ? th : th_max;
                if (!(th <= theta_limit)) {
                    stats[3] = th;
                    rc = 3;
                }
            }
#else
            rc = solve_step(u, r, J, Q, &scale, &scale_u, tol, max_iter, arg, res, iwork, cw,
                            theta_limit, stats, &lu);
#endif
            if (rc) {
                fail[0] = n * S + j;
                stats[4] = stats[4] > th_max ? stats[4] : th_max;
                return rc;
            }
            if (nst > 0) { /* the estimate: J, dg/du (K) and g of this step into the block, one
                              step of the block before's recursion */
#if !defined(NL_EXPLICIT) || NL_NZ > 0
                copy(nu * nu, J, sets[p][0] + kb * nu * nu);
#endif
#if DIAGONAL_GAIN
                for (c = 0; c < ne; ++c) /* K_k = dg/dy: its diagonal (padded: zeros, kept) */
                    sets[p][3][kb * nw * NEP4 + c] = Gu[c * ne + c];
#elif defined(NL_EXPLICIT) && NL_NZ == 0
                for (c = 0; c < nw; ++c) /* K_k = dg/du, its columns padded (zeros, kept) */
                    copy(ne, Gu + c * ne, sets[p][3] + (kb * nw + c) * NEP4);
#else
                copy(ne * nu, Gu, sets[p][1] + kb * ne * nu);
#endif
                copy(ne, g, sets[p][2] + (kb + nst - 1) * ne);
                if (have) { /* the block before: its step kb */
                    estimate_step(em, cwv, sets[1 - p][4] + kb * ne,
                                  sets[1 - p][3] + kb * nw * NEP4, e, dgv);
                    if (--sc == 0) { /* a sample: e and dg kept for estimate_outs */
                        double *o = Ob + nout++ * nx;
                        sc = S;
                        for (i = 0; i < NMV; ++i)
                            *(v4 *)(o + 4 * i) = e[i];
                        for (i = 0; i < NEV4; ++i)
                            *(v4 *)(o + NMP + 4 * i) = dgv[i];
                    }
                }
                ++kb;
            }
            if (j == 0) { /* Co eta + Dof f + Dog g */
                double *o = out + n * (no + nzo);
                vmatvec(NOV, nm, Cout, (const double *)eta, ov, 0);
                vmatvec(NOV, nf, Cout + nm * NOP, f, ov, 1);
                vmatvec(NOV, ne, Cout + (nm + nf) * NOP, g, ov, 1);
                for (i = 0; i < no; ++i)
                    o[i] = ov[i / 4][i % 4];
                copy(nzo, u + nw, o + no);
            }
            /* the history: g_k in front (one slot back in the ring) */
            if (nh > 0) {
                ih = (ih == 0 ? nh : ih) - ne;
                copy(ne, g, ring + ih);
                copy(ne, g, ring + ih + nh);
            }
            if (++j == nsub) {
                j = 0;
                if (++n == n_samples)
                    break;
            }
            if (nst > 0 && kb == eb)
                break;
        }
        if (nst > 0 && kb == eb) { /* out of the steps' loop: no call inside it */
            double **c = sets[p];
            estimate_prep(eb, mats[13], c[0], c[1], c[2], c[3], c[4], sets[1 - p][2]);
            estimate_outs(nout, Coe, Ob, mx, mn, okind);
            nout = 0;
            p = 1 - p;
            have = 1;
            kb = 0;
        }
    }
#if defined(NL_EXPLICIT) && NL_NZ == 0
    rc = explicit_block(kt, (n_samples - 1) * S + 1 - kt, tb, ok, mx_th, theta_limit, &th_max, stats,
                        fail);
    if (rc)
        return rc;
#endif
    stats[4] = stats[4] > th_max ? stats[4] : th_max;
    if (nst > 0) {
        /* the rest of the block before, then this one's kb steps */
        for (k = have ? kb : eb; k < eb; ++k) {
            estimate_step(em, cwv, sets[1 - p][4] + k * ne, sets[1 - p][3] + k * nw * NEP4, e,
                          dgv);
            if (--sc == 0) {
                double *o = Ob + nout++ * nx;
                sc = S;
                for (i = 0; i < NMV; ++i)
                    *(v4 *)(o + 4 * i) = e[i];
                for (i = 0; i < NEV4; ++i)
                    *(v4 *)(o + NMP + 4 * i) = dgv[i];
            }
        }
        estimate_outs(nout, Coe, Ob, mx, mn, okind);
        nout = 0;
        if (kb > 0) {
            double **c = sets[p];
            estimate_prep(kb, mats[13], c[0], c[1], c[2], c[3], c[4], sets[1 - p][2]);
            for (k = 0; k < kb; ++k) {
                estimate_step(em, cwv, c[4] + k * ne, c[3] + k * nw * NEP4, e, dgv);
                if (--sc == 0) {
                    double *o = Ob + nout++ * nx;
                    sc = S;
                    for (i = 0; i < NMV; ++i)
                        *(v4 *)(o + 4 * i) = e[i];
                    for (i = 0; i < NEV4; ++i)
                        *(v4 *)(o + NMP + 4 * i) = dgv[i];
                }
            }
            estimate_outs(nout, Coe, Ob, mx, mn, okind);
        }
        { /* max |out| = max(largest, -smallest); NaN when e or dg is not finite in the end
             (the maxima skip a NaN, but once there it stays: every lane reaches dg) */
            double bad = 0.0;
            for (i = 0; i < NMV; ++i)
                for (c = 0; c < 4; ++c)
                    bad += e[i][c] * 0.0;
            for (i = 0; i < NEV4; ++i)
                for (c = 0; c < 4; ++c)
                    bad += dgv[i][c] * 0.0;
            for (i = 0; i < no; ++i) {
                const double a = mx[i / 4][i % 4], b = -mn[i / 4][i % 4];
                stats[5 + i] = (a > b ? a : b) + bad;
            }
        }
    }
#if defined(NL_EXPLICIT) && NL_NZ == 0
    copy(nw, Q, u);
#endif
    stats[5 + no] = lu.formed;
    /* the state at the last sample */
    copy(nm, (const double *)eta, x);
    copy(nh, ring + ih, x + nm);
    return 0;
}
#endif

/*
 * The doubles of nl_loop_run's work for these dims: CasADi's work (nl_residual_work), then, with
 * the embedded estimate (NL_NST > 0), its blocks of dims[14] steps from dims[13] (modal_run's
 * layout: two sets of J, dg/du, g after NST - 1 earlier ones, K, the differences; then the
 * samples' e and dg). -1 when they would overlap CasADi's work.
 */
long dtdyn_nl_work(const long *dims)
{
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
#ifdef NL_NM
    if (NL_NST > 0) {
        enum { ne = NL_NE, nw = NL_NW, nu = NL_NW + NL_NZ, nst = NL_NST };
        const long eb = dims[14];
        if (dims[13] < (long)sz_w || eb < 0)
            return -1;
        return dims[13] + 2 * (eb * (nu * nu + ne * nu + NEP4 * nw + ne) + (eb + nst - 1) * ne)
               + eb * (NMP + NEP4);
    }
#endif
    (void)dims;
    return (long)sz_w;
}

/*
 * dims: ns, nf, ne, nw, nz, no (checked against the compile-time sizes NL_NS .. NL_NO, which
 * let the compiler unroll the small products), n_samples, substeps, max_iter, nzo; with the
 * modal path (NL_NM) also NM, NH, NST and the estimate's block (its offset in work, EB steps).
 * A row of out holds no + nzo values: Co x + Dof f + Dog g, then the first nzo internal
 * states z.
 * mats (column-major): A, Bf, Bg, Cw, Dwf, Dwg, par = [Dwg; h], Co, Dof, Dog (then the modal
 * path's, see modal_run).
 * state: x (ns), u (nw + nz: last solution), g (ne), rate (nz); all updated in place.
 * stats: [max iterations, total iterations, max final residual, failing residual or theta,
 * max theta] (then the modal estimate's, no values), then the LU factorizations formed
 * (newton_fixed). work: n_work >= dtdyn_nl_work(dims) doubles; iwork: n_iwork >= CasADi's
 * (nl_residual_work); DTDYN_ERR_WORK otherwise, checked after the sizes. Returns 3 when theta = |B0 dg/dy|_inf (displacement rows and columns) exceeds
 * theta_limit (the method's stability limit for the elements' tangent
 * stiffness) at step fail[0].
 */
DTDYN_LOOP int nl_loop_run(const long *dims, const double *const *mats,
                           const double *restrict force, double *restrict x, double *restrict u,
                           double *restrict g, double *restrict rate, double *restrict out,
                           double tol, double theta_limit, double *stats, long *fail,
                           double *restrict work, long n_work, nl_int *restrict iwork,
                           long n_iwork)
{
    enum { ns = NL_NS, nf = NL_NF, ne = NL_NE, nw = NL_NW, nz = NL_NZ, no = NL_NO };
    const long n_samples = dims[6], S = dims[7], max_iter = dims[8], nzo = dims[9];
    enum { nu = NL_NW + NL_NZ };
    const double *A = mats[0], *Bf = mats[1], *Bg = mats[2], *Cw = mats[3], *Dwf = mats[4];
    const double *Dwg = mats[5], *par = mats[6], *Co = mats[7], *Dof = mats[8];
    const double *Dog = mats[9];
    double f[nf + 1], Q[nw + 1], zold[nz + 1], rold[nz + 1], r[nu + 1], J[nu * nu + 1];
    double xn[ns];
    double *cw = work; /* CasADi work */
    const double *arg[5];
    double *res[5];
    lu_keep lu;
    double scale = 0.0, scale_u = 0.0;
    nl_int sz_arg, sz_res, sz_iw, sz_w;
    long n, j, i, need;
    int rc;
    arg[0] = u; arg[1] = Q; arg[2] = zold; arg[3] = rold; arg[4] = par;
    res[0] = r; res[1] = J; res[2] = g; res[3] = rate; res[4] = 0;
    (void)newton_solve; /* newton.c's general solver: nl_chain.c's; this loop has newton_fixed */
    (void)lu_apply_t;   /* the modal path's estimate (tangent_gain) */
    stats[0] = stats[1] = stats[2] = stats[3] = stats[4] = stats[5 + no] = 0.0;
    lu.have = 0;
    lu.formed = 0.0;
    if (dims[0] != ns || dims[1] != nf || dims[2] != ne || dims[3] != nw || dims[4] != nz ||
        dims[5] != no)
        return 2; /* compiled for other sizes */
#ifdef NL_NM
    if (dims[10] != NL_NM || dims[11] != NL_NH || dims[12] != NL_NST || NL_NM + NL_NH != ns ||
        (NL_NST > 0 && dims[14] < 1))
        return 2;
#endif
    nl_residual_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    need = dtdyn_nl_work(dims);
    if (need < 0 || n_work < need || n_iwork < (long)sz_iw)
        return DTDYN_ERR_WORK;
#ifdef NL_NM
    return modal_run(dims, mats, force, x, u, g, rate, out, tol, theta_limit, stats, fail, work,
                     iwork);
#endif
    for (n = 0; n < n_samples; ++n) {
        const double *f0 = force + n * nf;
        const double *f1 = (n + 1 < n_samples) ? f0 + nf : f0;
        const long nsub = (n + 1 < n_samples) ? S : 1;
        if ((n & 1023) == 0 && dtdyn_stop_flag)
            return DTDYN_STOPPED;
        for (j = 0; j < nsub; ++j) {
            const double c = (double)j / (double)S;
            for (i = 0; i < nf; ++i)
                f[i] = f0[i] + c * (f1[i] - f0[i]);
            /* Q = Cw x + Dwf f; predictor u = [Q + Dwg g_prev; z_prev + h z'_prev] */
            zero(nw, Q);
            matvec_add(nw, ns, Cw, x, Q);
            matvec_add(nw, nf, Dwf, f, Q);
            copy(nw, Q, u);
            matvec_add(nw, ne, Dwg, g, u);
            copy(nz, u + nw, zold);
            copy(nz, rate, rold);
            for (i = 0; i < nz; ++i)
                u[nw + i] = zold[i] + par[nw * ne] * rold[i];
            /* Newton under the shared acceptance rule (newton_solve), scale fixed per step */
            rc = solve_step(u, r, J, Q, &scale, &scale_u, tol, max_iter, arg, res, iwork, cw,
                            theta_limit, stats, &lu);
            if (rc) {
                fail[0] = n * S + j;
                return rc;
            }
            if (j == 0) {
                double *o = out + n * (no + nzo);
                zero(no, o);
                matvec_add(no, ns, Co, x, o);
                matvec_add(no, nf, Dof, f, o);
                matvec_add(no, ne, Dog, g, o);
                copy(nzo, u + nw, o + no);
            }
            if (n + 1 < n_samples) {
                zero(ns, xn);
                matvec_add(ns, ns, A, x, xn);
                matvec_add(ns, nf, Bf, f, xn);
                matvec_add(ns, ne, Bg, g, xn);
                copy(ns, xn, x);
            }
        }
    }
    stats[5 + no] = lu.formed;
    return 0;
}
#endif /* DTDYN_NL_LOOP_H */
