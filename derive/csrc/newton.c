/* Small dense helpers of the per-step Newton solves (included by nl_loop.c and nl_chain.c). */
/* Solve J d = -r in place (J column-major n x n, from CasADi) by LU with partial pivoting. */
static int lu_solve(long n, double *restrict J, double *restrict r)
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
        if (p != k) {
            double t;
            for (j = 0; j < n; ++j) {
                t = J[j * n + k]; J[j * n + k] = J[j * n + p]; J[j * n + p] = t;
            }
            t = r[k]; r[k] = r[p]; r[p] = t;
        }
        for (i = k + 1; i < n; ++i) {
            const double l = J[k * n + i] / J[k * n + k];
            J[k * n + i] = l;
            for (j = k + 1; j < n; ++j)
                J[j * n + i] -= l * J[j * n + k];
            r[i] -= l * r[k];
        }
    }
    for (i = n - 1; i >= 0; --i) {
        double s = r[i];
        for (j = i + 1; j < n; ++j)
            s -= J[j * n + i] * r[j];
        r[i] = s / J[i * n + i];
    }
    for (i = 0; i < n; ++i)
        r[i] = -r[i];
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
