/* sturm.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_STURM_H
#define DTDYN_STURM_H
#include "c_api.h"
/*
 * Wittrick-Williams count for a chain: the number of eigenvalues of K phi = lambda M phi below
 * each trial lambda, from the signs of the pivots of K - lambda M (Sylvester's law of inertia).
 * Condensing the chain from the ground up, mass i sees through station i the stiffness
 *
 *     s_0 = k_0 + kg_0 - lambda m_0,   s_i = k_i s_{i-1} / (k_i + s_{i-1}) + kg_i - lambda m_i,
 *
 * (station i in series with what is below it, plus the spring kg_i from mass i to the ground,
 * less the inertia of mass i; kg = NULL: no such springs): the stable
 * (Riccati) sweep of the chain in the frequency domain. The pivots of K - lambda M are
 * d_i = s_i + k_{i+1} (k_N = 0), and the count is the number of negative d_i. A station with
 * k_i = 0 gives s_i = kg_i - lambda m_i: the chain splits there, and d_{i-1} = s_{i-1} is the
 * last pivot of the part below. The series form
 * adds positive terms where the textbook pivot a_i - lambda m_i - k_i^2 / d_{i-1} cancels,
 * which keeps the small eigenvalues of long chains accurate to a few ulps relative. A pivot
 * smaller in magnitude than pivmin is replaced by -pivmin (as LAPACK's dstebz does), so no
 * division overflows. O(N) per lambda, for n_lam trial values at once.
 *
 * The trial values run STURM_LANES at a time through one pass over the chain: each lane is a
 * chain of dependent divisions, and interleaving independent lanes hides their latency. The
 * last block repeats its last lambda in the unused lanes (computed, not stored).
 */
#include <math.h>

#define STURM_LANES 4

int dtdyn_sturm_counts(long N, const double *restrict k, const double *restrict kg,
                       const double *restrict m, double pivmin, long n_lam,
                       const double *restrict lam, long *restrict counts)
{
    long j0, i, b;
    for (j0 = 0; j0 < n_lam; j0 += STURM_LANES) {
        double l[STURM_LANES], s[STURM_LANES];
        long c[STURM_LANES];
        for (b = 0; b < STURM_LANES; ++b) {
            l[b] = lam[(j0 + b < n_lam) ? j0 + b : n_lam - 1];
            s[b] = k[0] + (kg ? kg[0] : 0.0) - l[b] * m[0];
            c[b] = 0;
        }
        for (i = 1; i < N; ++i) {
            const double kn = k[i], mn = m[i], kgn = kg ? kg[i] : 0.0;
            for (b = 0; b < STURM_LANES; ++b) {
                double d = s[b] + kn; /* pivot of mass i - 1 */
                if (d > -pivmin && d < pivmin)
                    d = -pivmin;
                c[b] += d < 0.0;
                s[b] = kn * s[b] / d + kgn - l[b] * mn; /* k_i s / (k_i + s) + kg_i - ... */
            }
        }
        for (b = 0; b < STURM_LANES && j0 + b < n_lam; ++b) {
            double d = s[b]; /* the last pivot: k_N = 0 */
            if (d > -pivmin && d < pivmin)
                d = -pivmin;
            counts[j0 + b] = c[b] + (d < 0.0);
        }
    }
    return 0;
}

/*
 * The count together with the first two derivatives of log|det(K - lambda M)| = sum log|d_i|,
 * for Laguerre's iteration on det(K - lambda M) (a polynomial of degree N in lambda with real
 * roots). Along the recursion (kg_i is constant), with g_i = k_i / d_{i-1},
 *
 *     s_i'  = g_i^2 s_{i-1}' - m_i,                     s_0' = -m_0,
 *     s_i'' = g_i^2 (s_{i-1}'' - 2 s_{i-1}'^2 / d_{i-1}),   s_0'' = 0,
 *
 * and d_i' = s_i', d_i'' = s_i'', so with u_i = d_i' / d_i and v_i = d_i'' / d_i
 *
 *     G = sum_i u_i = sum_r 1 / (lambda - lambda_r),
 *     H = sum_i (u_i^2 - v_i) = -G' = sum_r 1 / (lambda - lambda_r)^2.
 *
 * One division per station and lane, as in the count. A pivot replaced by -pivmin leaves no
 * derivative: G = NaN if it was not the last one (no step from this lambda), G = +inf and
 * H = 0 if it was the last (lambda is an eigenvalue to the last bit).
 */
int dtdyn_sturm_laguerre(long N, const double *restrict k, const double *restrict kg,
                         const double *restrict m, double pivmin, long n_lam,
                         const double *restrict lam, long *restrict counts,
                         double *restrict G, double *restrict H)
{
    long j0, i, b;
    for (j0 = 0; j0 < n_lam; j0 += STURM_LANES) {
        double l[STURM_LANES], s[STURM_LANES], s1[STURM_LANES], s2[STURM_LANES];
        double g1[STURM_LANES], h1[STURM_LANES];
        long c[STURM_LANES], hit[STURM_LANES];
        for (b = 0; b < STURM_LANES; ++b) {
            l[b] = lam[(j0 + b < n_lam) ? j0 + b : n_lam - 1];
            s[b] = k[0] + (kg ? kg[0] : 0.0) - l[b] * m[0];
            s1[b] = -m[0];
            s2[b] = 0.0;
            g1[b] = 0.0;
            h1[b] = 0.0;
            c[b] = 0;
            hit[b] = 0;
        }
        for (i = 1; i < N; ++i) {
            const double kn = k[i], mn = m[i], kgn = kg ? kg[i] : 0.0;
            for (b = 0; b < STURM_LANES; ++b) {
                double d = s[b] + kn; /* pivot of mass i - 1 */
                const long tiny = d > -pivmin && d < pivmin;
                d = tiny ? -pivmin : d;
                hit[b] |= tiny;
                c[b] += d < 0.0;
                const double rd = 1.0 / d, u = s1[b] * rd, v = s2[b] * rd, g = kn * rd;
                g1[b] += u;
                h1[b] += u * u - v;
                s[b] = kn * s[b] / d + kgn - l[b] * mn; /* as in the count, to the bit */
                s2[b] = g * g * (s2[b] - 2.0 * s1[b] * u);
                s1[b] = g * (kn * u) - mn;
            }
        }
        for (b = 0; b < STURM_LANES && j0 + b < n_lam; ++b) {
            double d = s[b]; /* the last pivot: k_N = 0 */
            const long tiny = d > -pivmin && d < pivmin;
            d = tiny ? -pivmin : d;
            counts[j0 + b] = c[b] + (d < 0.0);
            const double u = s1[b] / d, v = s2[b] / d;
            G[j0 + b] = hit[b] ? NAN : tiny ? INFINITY : g1[b] + u;
            H[j0 + b] = (hit[b] || !tiny) ? h1[b] + (u * u - v) : 0.0;
        }
    }
    return 0;
}
#endif /* DTDYN_STURM_H */
