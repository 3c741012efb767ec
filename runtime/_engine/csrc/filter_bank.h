/* filter_bank.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_FILTER_BANK_H
#define DTDYN_FILTER_BANK_H
#include "c_api.h"
#include "stop.h"
#include "flush_subnormals.h"
/*
 * A bank of parallel second-order sections (transposed direct form II):
 *   v_n = b0 x_n + s1;  s1 = b1 x_n - a1 v_n + s2;  s2 = b2 x_n - a2 v_n
 * where v_n is the section output. Section k reads input row in_col[k] of xt (n_in x n: one
 * contiguous row per input) and adds its output to row out_col[k] of yt (n_out x n, zeroed by the
 * caller), so every pass reads and writes contiguously. The record is cut into blocks of
 * BLOCK samples; in each block every section runs in turn, its state carried in `state`
 * (2 n_sec, zeroed by the caller), so the block's inputs and outputs stay in cache. Each output
 * still receives its sections' outputs in the order k = 0, 1, ... (the sums do not depend on
 * BLOCK). Returns 0, or DTDYN_STOPPED (stop.c, included before this file) when stopped.
 */
#include <stddef.h>

#define BLOCK 2048

DTDYN_LOOP int filter_bank_run(long n, long n_in, long n_out, long n_sec,
                               const double *restrict sos, const long *restrict in_col,
                               const long *restrict out_col, const double *restrict xt,
                               double *restrict yt, double *restrict state)
{
    long b, k, i;
    (void)n_in;
    (void)n_out;
    for (b = 0; b < n; b += BLOCK) {
        const long end = (b + BLOCK < n) ? b + BLOCK : n;
        for (k = 0; k < n_sec; ++k) {
            if (dtdyn_stop_flag) /* per section: a block of many sections is long */
                return DTDYN_STOPPED;
            const double b0 = sos[5 * k], b1 = sos[5 * k + 1], b2 = sos[5 * k + 2];
            const double a1 = sos[5 * k + 3], a2 = sos[5 * k + 4];
            const double *xi = xt + in_col[k] * n;
            double *yo = yt + out_col[k] * n;
            double s1 = state[2 * k], s2 = state[2 * k + 1];
            for (i = b; i < end; ++i) {
                const double xn = xi[i];
                const double v = b0 * xn + s1;
                s1 = b1 * xn - a1 * v + s2;
                s2 = b2 * xn - a2 * v;
                yo[i] += v;
            }
            state[2 * k] = s1;
            state[2 * k + 1] = s2;
        }
    }
    return 0;
}
#endif /* DTDYN_FILTER_BANK_H */
