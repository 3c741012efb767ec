/* ss_response.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_SS_RESPONSE_H
#define DTDYN_SS_RESPONSE_H
#include "c_api.h"
#include "flush_subnormals.h"
/*
 * The sequential part of a discrete state-space response: X[n + 1] = A X[n] + w_n for
 * n = 0..n_steps-1 (w_n = B u_n is formed beforehand, as is y = C x + D u afterwards, by
 * matrix-matrix products over a block of steps). A comes transposed (column-major):
 * At[j * ns + i] = A[i][j], so the inner loop is a contiguous axpy the compiler vectorizes
 * without reassociating sums. X: (n_steps + 1) x ns, row 0 holds x_0 on entry; each new state
 * is written in place in its row. w: n_steps x ns.
 */
#include <stddef.h>

DTDYN_LOOP int ss_states_run(long ns, long n_steps, const double *restrict At,
                             const double *restrict w, double *restrict X)
{
    long n, i, j;
    for (n = 0; n < n_steps; ++n) {
        const double *x = X + n * ns, *wn = w + n * ns;
        double *restrict out = X + (n + 1) * ns;
        for (i = 0; i < ns; ++i)
            out[i] = wn[i];
        /* four columns per pass; each out[i] still adds its terms in order j = 0, 1, ... */
        for (j = 0; j + 4 <= ns; j += 4) {
            const double x0 = x[j], x1 = x[j + 1], x2 = x[j + 2], x3 = x[j + 3];
            const double *c0 = At + j * ns, *c1 = c0 + ns, *c2 = c1 + ns, *c3 = c2 + ns;
            for (i = 0; i < ns; ++i)
                out[i] = out[i] + c0[i] * x0 + c1[i] * x1 + c2[i] * x2 + c3[i] * x3;
        }
        for (; j < ns; ++j) {
            const double xj = x[j];
            const double *col = At + j * ns;
            for (i = 0; i < ns; ++i)
                out[i] += col[i] * xj;
        }
    }
    return 0;
}
#endif /* DTDYN_SS_RESPONSE_H */
