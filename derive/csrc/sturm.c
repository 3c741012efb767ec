/*
 * Wittrick-Williams count for a chain: the number of eigenvalues of K phi = lambda M phi below
 * each trial lambda, from the signs of the pivots of K - lambda M (Sylvester's law of inertia).
 * Condensing the chain from the ground up, mass i sees through station i the stiffness
 *
 *     s_0 = k_0 - lambda m_0,   s_i = k_i s_{i-1} / (k_i + s_{i-1}) - lambda m_i,
 *
 * (station i in series with what is below it, less the inertia of mass i): the stable
 * (Riccati) sweep of the chain in the frequency domain. The pivots of K - lambda M are
 * d_i = s_i + k_{i+1} (k_N = 0), and the count is the number of negative d_i. The series form
 * adds positive terms where the textbook pivot a_i - lambda m_i - k_i^2 / d_{i-1} cancels,
 * which keeps the small eigenvalues of long chains accurate to a few ulps relative. A pivot
 * smaller in magnitude than pivmin is replaced by -pivmin (as LAPACK's dstebz does), so no
 * division overflows. O(N) per lambda, for n_lam trial values at once.
 */
int dtdyn_sturm_counts(long N, const double *restrict k, const double *restrict m,
                       double pivmin, long n_lam, const double *restrict lam,
                       long *restrict counts)
{
    long j, i;
    for (j = 0; j < n_lam; ++j) {
        const double l = lam[j];
        double s = k[0] - l * m[0];
        long c = 0;
        for (i = 1; i <= N; ++i) {
            const double kn = (i < N) ? k[i] : 0.0;
            double d = s + kn; /* pivot of mass i - 1 */
            if (d > -pivmin && d < pivmin)
                d = -pivmin;
            c += d < 0.0;
            if (i < N)
                s = kn * s / d - l * m[i]; /* k_i s / (k_i + s) - lambda m_i */
        }
        counts[j] = c;
    }
    return 0;
}
