/* rainflow.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_RAINFLOW_H
#define DTDYN_RAINFLOW_H
#include "c_api.h"
/*
 * Rainflow counting of a load record, ASTM E1049-85 (2011) section 5.4.4, in two O(n) passes.
 *
 * dtdyn_turning_points(n, x, tp): the indices of the reversals of x[0 .. n-1] into tp (n slots),
 * their number returned. The first and the last sample are reversals; an interior sample is one
 * where the slope changes sign. A run of equal samples (a plateau) counts as one point, at its
 * last sample; a plateau at the start belongs to sample 0 and is never an interior reversal.
 * The slope signs are compared directly (not their product, which underflows to zero for two
 * differences below 1e-154 and would hide a reversal). These are the reversals of the `rainflow`
 * package (rainflow.reversals), except that a record of two samples has both as reversals.
 *
 * dtdyn_rainflow(n_tp, x, tp, start, end, count, residue_size): the three-point stack count of
 * those reversals. With the three newest points on the stack forming the ranges
 * Y = |x2 - x1| (older) and X = |x3 - x2| (newer): while X >= Y, Y is a half cycle when it holds
 * the oldest point of the stack (which is dropped), else a full cycle (its two points are
 * dropped); then the next reversal is read. At the end each range left on the stack (the
 * residue) is a half cycle. Each cycle is written as the sample indices of its two points
 * (start, end: oldest first) and its count (0.5 or 1.0), in the order it is found; the number of
 * cycles is returned (at most n_tp - 1: each cycle drops a point, the residue's n_r points give
 * n_r - 1). The stack is kept in tp itself (it never grows past the reversal being read); on
 * return tp[0 .. *residue_size - 1] holds the residue's sample indices.
 */
#include <math.h>

long dtdyn_turning_points(long n, const double *restrict x, long *restrict tp)
{
    long k, m = 0;
    double xv, d_last;
    if (n <= 0)
        return 0;
    tp[m++] = 0;
    if (n == 1)
        return m;
    xv = x[1];
    d_last = x[1] - x[0]; /* 0 on a starting plateau: no reversal at its end */
    for (k = 2; k < n; ++k) {
        const double xn = x[k];
        double d;
        int turn;
        if (xn == xv) /* a plateau: its last sample stands for it */
            continue;
        d = xn - xv;
        turn = (d_last != 0.0) & ((d < 0.0) != (d_last < 0.0));
        tp[m] = k - 1; /* written always, kept when it is a reversal (no branch to mispredict) */
        m += turn;
        xv = xn;
        d_last = d;
    }
    tp[m++] = n - 1;
    return m;
}

long dtdyn_rainflow(long n_tp, const double *restrict x, long *restrict tp, long *restrict start,
                    long *restrict end, double *restrict count, long *restrict residue_size)
{
    long k, lo = 0, top = 0, c = 0;
    for (k = 0; k < n_tp; ++k) {
        tp[top++] = tp[k]; /* push the next reversal; top <= k + 1, so in place */
        while (top - lo >= 3) {
            const double x1 = x[tp[top - 3]], x2 = x[tp[top - 2]], x3 = x[tp[top - 1]];
            if (fabs(x3 - x2) < fabs(x2 - x1))
                break;
            if (top - lo == 3) { /* Y holds the starting point: a half cycle, drop that point */
                start[c] = tp[lo];
                end[c] = tp[lo + 1];
                count[c++] = 0.5;
                ++lo;
            } else { /* a full cycle: drop its two points, keep the newest */
                start[c] = tp[top - 3];
                end[c] = tp[top - 2];
                count[c++] = 1.0;
                tp[top - 3] = tp[top - 1];
                top -= 2;
            }
        }
    }
    for (k = lo; k + 1 < top; ++k) { /* the residue: half cycles */
        start[c] = tp[k];
        end[c] = tp[k + 1];
        count[c++] = 0.5;
    }
    for (k = lo; k < top; ++k)
        tp[k - lo] = tp[k];
    *residue_size = top - lo;
    return c;
}
#endif /* DTDYN_RAINFLOW_H */
