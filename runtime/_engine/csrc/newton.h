/* newton.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_NEWTON_H
#define DTDYN_NEWTON_H
#include "c_api.h"
/* Small dense helpers of the per-step Newton solves (included by nl_loop.c, nl_chain.c and
   nl_stations.c). */
#include <float.h>
/* LU with partial pivoting of J (column-major n x n) in place: the multipliers below the
   diagonal, U on and above it, the row swapped into row k at step k in piv[k]. 1 when J is
   singular (a zero pivot column), else 0. */
static int lu_factor(long n, double *restrict J, long *restrict piv)
{
    long i, j, k, p;
    for (k = 0; k < n; ++k) {
        double best = fabs(J[k * n + k]);
        p = k;
        for (i = k + 1; i < n; ++i)
            if (fabs(J[k * n + i]) > best) {
                best = fabs(J[k * n + i]);
                p = i;
            }
        if (!(best > 0.0))
            return 1;
        piv[k] = p;
        if (p != k) {
            double t;
            for (j = 0; j < n; ++j) {
                t = J[j * n + k]; J[j * n + k] = J[j * n + p]; J[j * n + p] = t;
            }
        }
        /* the multipliers, then the trailing columns one at a time (contiguous: each entry
           meets the same operations, in the same order, as in a row-by-row update) */
        for (i = k + 1; i < n; ++i)
            J[k * n + i] = J[k * n + i] / J[k * n + k];
        for (j = k + 1; j < n; ++j) {
            const double u = J[j * n + k];
            for (i = k + 1; i < n; ++i)
                J[j * n + i] -= J[k * n + i] * u;
        }
    }
    return 0;
}

/* d = -J^-1 r in place on r, from lu_factor's J and piv: the row swaps, then L and U (each
   value of r meets the same operations in the same order as in an elimination that carries r
   along: the swaps move a value together with its multipliers) */
static void lu_apply(long n, const double *restrict J, const long *restrict piv,
                     double *restrict r)
{
    long i, j, k;
    for (k = 0; k < n; ++k)
        if (piv[k] != k) {
            const double t = r[k];
            r[k] = r[piv[k]];
            r[piv[k]] = t;
        }
    for (k = 0; k < n; ++k)
        for (i = k + 1; i < n; ++i)
            r[i] -= J[k * n + i] * r[k];
    for (i = n - 1; i >= 0; --i) {
        double s = r[i];
        for (j = i + 1; j < n; ++j)
            s -= J[j * n + i] * r[j];
        r[i] = s / J[i * n + i];
    }
    for (i = 0; i < n; ++i)
        r[i] = -r[i];
}

/* d = -J^-T r in place on r, from lu_factor's J and piv (P J = L U, so J^T = U^T L^T P):
   U^T, then L^T, then the row swaps in reverse order */
static void lu_apply_t(long n, const double *restrict J, const long *restrict piv,
                       double *restrict r)
{
    long i, j, k;
    for (i = 0; i < n; ++i) {
        double s = r[i];
        for (j = 0; j < i; ++j)
            s -= J[i * n + j] * r[j];
        r[i] = s / J[i * n + i];
    }
    for (i = n - 1; i >= 0; --i) {
        double s = r[i];
        for (j = i + 1; j < n; ++j)
            s -= J[i * n + j] * r[j];
        r[i] = s;
    }
    for (k = n - 1; k >= 0; --k)
        if (piv[k] != k) {
            const double t = r[k];
            r[k] = r[piv[k]];
            r[piv[k]] = t;
        }
    for (i = 0; i < n; ++i)
        r[i] = -r[i];
}

/* Solve J d = -r in place (J column-major n x n, from CasADi, overwritten by its factors) by LU
   with partial pivoting; 1 when J is singular. */
static int lu_solve(long n, double *restrict J, double *restrict r)
{
    long piv[n > 0 ? n : 1];
    if (lu_factor(n, J, piv))
        return 1;
    lu_apply(n, J, piv, r);
    return 0;
}

static double norm_inf(long n, const double *v)
{
    double m = 0.0;
    long i;
    for (i = 0; i < n; ++i) {
        const double a = fabs(v[i]);
        if (a != a)
            return INFINITY;
        if (a > m)
            m = a;
    }
    return m;
}

static inline void copy(long n, const double *restrict src, double *restrict dst)
{
    long i;
    for (i = 0; i < n; ++i)
        dst[i] = src[i];
}

static inline void zero(long n, double *restrict dst)
{
    long i;
    for (i = 0; i < n; ++i)
        dst[i] = 0.0;
}

/* s raised to v when v is larger and finite (a non-finite iterate never loosens the tests) */
static inline double grow(double s, double v)
{
    return (v > s && v < INFINITY) ? v : s;
}

/* |J_yy - I|_inf over the first ne rows and columns of J (n x n, column-major): how far the
 * elements' block of the iteration is from contracting (docs/newton.md). */
static inline double gain_contraction(long nu, long ne, const double *restrict J)
{
    double theta = 0.0;
    long i, k;
    for (i = 0; i < ne; ++i) {
        double row = 0.0;
        for (k = 0; k < ne; ++k)
            row += fabs(J[k * nu + i] - (i == k ? 1.0 : 0.0));
        if (row > theta)
            theta = row;
    }
    return theta;
}

/*
 * One step's Newton iteration under the acceptance rule of every backend (docs/newton.md):
 * u is accepted when
 *
 *     |r(u)|_inf <= tol s_r   (residual test)   or   |J(u)^-1 r(u)|_inf <= tol s_u   (step test),
 *
 * s_r = max(scale_r, DBL_MIN) the size of the residual's terms, s_u = max(scale_u, DBL_MIN)
 * that of the unknowns. The step test accepts a residual at its round-off floor (stiff
 * elements); the step that passes it is not taken, so r, J, g and z' stay those of u.
 * nl_residual evaluates them through arg/res (wired by the caller to u, r, J, g, z'). *theta =
 * |J_yy - I|_inf over the first ne rows and columns of the accepted u. Returns the iterations,
 * or -1 when u is not accepted (non-finite r, singular J, or neither test passed after
 * max_iter steps); *rn = |r(u)|_inf of the last u.
 */
static long newton_solve(long nu, long ne, double *restrict u, double *restrict r,
                         double *restrict J, double scale_r, double scale_u, double tol,
                         long max_iter,
                         const double **arg, double **res, nl_int *iw, double *w, double *rn,
                         double *theta)
{
    const double lim_r = tol * fmax(scale_r, DBL_MIN), lim_u = tol * fmax(scale_u, DBL_MIN);
    long it, i;
    for (it = 0;; ++it) {
        nl_residual(arg, res, iw, w, 0);
        *rn = norm_inf(nu, r);
        if (!(*rn < INFINITY))
            return -1;
        *theta = gain_contraction(nu, ne, J);
        if (*rn <= lim_r)
            return it;
        if (lu_solve(nu, J, r))
            return -1;
        if (norm_inf(nu, r) <= lim_u)
            return it;
        if (it == max_iter)
            return -1;
        for (i = 0; i < nu; ++i)
            u[i] += r[i];
    }
}

/*
 * newton_solve with the LU factors of the Newton matrix kept from iteration to iteration and
 * from step to step, at runtime sizes (the chain and station loops with DTDYN_NEWTON_KEPT_LU;
 * nl_loop.h's newton_fixed is the same at compile-time sizes): modified Newton,
 * u <- u - J_f^-1 r(u), J_f the Jacobian where the factors were formed. They are formed anew,
 * at the current iterate, when the iteration does not contract (|d_i| > KEPT_CONTRACT
 * |d_{i-1}|) and at every iteration from KEPT_FRESH_ITERS on (plain Newton from there, so that
 * a step plain Newton solves within max_iter is not refused). The residual test is the rule's;
 * the step test |J_f^-1 r| <= tol s_u accepts with factors formed at this iterate (the rule's),
 * or after an iteration that contracted by KEPT_CONTRACT (the remaining error is then below
 * |d| / (1 - KEPT_CONTRACT)): never on the first iteration with older factors, whose Jacobian
 * may belong to another state of the elements (a contact that has opened since). J stays the
 * Jacobian at u. An LU costs ~nu^3 / 3 multiply-adds, a solve with its factors ~nu^2.
 */
enum { KEPT_FRESH_ITERS = 4 };
#define KEPT_CONTRACT 0.25

typedef struct {
    double *f;     /* nu x nu: lu_factor's factors of J_f */
    long *piv;     /* nu: its row swaps */
    int have;      /* f and piv hold factors */
    double formed; /* factorizations so far */
} lu_kept;

/* d = -J_f^-1 r (r unchanged), after forming the factors at J when asked to (*fresh) or when
   there are none; 1 when J is singular. *fresh: the factors are J's */
static inline int lu_kept_step(long nu, lu_kept *restrict lu, const double *restrict J,
                               const double *restrict r, double *restrict d, int *fresh)
{
    if (*fresh || !lu->have) {
        copy(nu * nu, J, lu->f);
        lu->have = 0;
        if (lu_factor(nu, lu->f, lu->piv))
            return 1;
        lu->have = 1;
        lu->formed += 1.0;
        *fresh = 1;
    }
    copy(nu, r, d);
    lu_apply(nu, lu->f, lu->piv, d);
    return 0;
}

/* newton_solve's arguments and result, with the kept factors lu and d (nu doubles: the step) */
static inline long newton_kept(long nu, long ne, double *restrict u, double *restrict r,
                               double *restrict J, double scale_r, double scale_u, double tol,
                               long max_iter, const double **arg, double **res, nl_int *iw,
                               double *w, double *rn, double *theta, lu_kept *restrict lu,
                               double *restrict d)
{
    const double lim_r = tol * fmax(scale_r, DBL_MIN), lim_u = tol * fmax(scale_u, DBL_MIN);
    double dprev = INFINITY;
    long it, i;
    for (it = 0;; ++it) {
        double dn;
        int fresh = it >= KEPT_FRESH_ITERS;
        nl_residual(arg, res, iw, w, 0);
        *rn = norm_inf(nu, r);
        if (!(*rn < INFINITY))
            return -1;
        *theta = gain_contraction(nu, ne, J);
        if (*rn <= lim_r)
            return it;
        if (lu_kept_step(nu, lu, J, r, d, &fresh))
            return -1;
        dn = norm_inf(nu, d);
        if (!fresh && it > 0 && !(dn <= KEPT_CONTRACT * dprev)) {
            fresh = 1;
            if (lu_kept_step(nu, lu, J, r, d, &fresh))
                return -1;
            dn = norm_inf(nu, d);
        }
        /* older factors: accepted after a contracting iteration only */
        if ((fresh || it > 0) && dn <= lim_u)
            return it;
        if (it == max_iter)
            return -1;
        for (i = 0; i < nu; ++i)
            u[i] += d[i];
        dprev = dn;
    }
}
#endif /* DTDYN_NEWTON_H */
