/* modal_filters.h: hand-written C, compiled as it is (dtdyn/_engine/csrc); generated/modal_states.c
   adds the derived increments (in its comment) and the entry point of the signature spec */
#ifndef DTDYN_MODAL_FILTERS_H
#define DTDYN_MODAL_FILTERS_H
#include "c_api.h"
#include "stop.h"
#include "flush_subnormals.h"
/*
 * The per-mode form of the modal filters: m complex states eta_j = e_re[j] + i e_im[j], one per
 * mode (and residue factor), each updated once per sample in increment form,
 *   eta_j <- eta_j + (d_j eta_j + sum_i g0_ij x_{n-1,i} + g1_ij x_{n,i}),  d_j = e^{s_j T} - 1,
 * whose real and imaginary increments are derived by dtdyn.derive.modal_filters.increment_form
 * (generated/modal_states.c prints them), with x_a = x_{n-1}, x_b = x_n (several inputs add
 * their g terms). The increment is summed first and added to the state last. Then the outputs
 *   y_{n,o} = sum_j wt[o][j] e_re[j] + wt[o][m + j] e_im[j]   (wt = [Re W, -Im W]^T)
 * with only the first sum when im_out = 0 (every weight real: real mode shapes).
 *
 * Layout. The states are advanced in chunks of LANES = 4, 8 or 16 (dtdyn_modal_filters_lanes:
 * the smallest that holds m, 16 from 9 states on; the caller pads m with zero states to a
 * multiple of it), so the loops over the LANES states of a chunk have a constant trip count:
 * the states of a chunk stay in registers and are advanced together, sample after sample. The
 * kernel is compiled once per chunk size (modal_bank.h, included once per size: functions
 * suffixed _4, _8, _16), the states of a chunk held as vectors of 4 (chunk 4) or 8 doubles; zero
 * states add exact zeros, so every chunk size gives the same numbers. The record is cut into
 * blocks of MODAL_BLOCK samples (DTDYN_MODAL_BLOCK, generated/c_api.h); for each block the
 * recursion writes the states of chunk c at sample k as one row (re[LANES], im[LANES]) of ec,
 * then the outputs are formed from these rows: for few outputs as dot products over the states
 * (LANES partial sums added pairwise at the end), otherwise output row by output row, four
 * states at a time, in the order of the states.
 *
 * coef: d_re[m], d_im[m], then g0_re, g0_im, g1_re, g1_im, each n_in x m (row i: input i).
 * wt: n_out x 2m. x: (n + 1) x n_in, row 0 = x_{-1} (0 at rest). e: the 2m states (re[m],
 * then im[m]), in and out. y: n x n_out. work: n_work >= dtdyn_modal_filters_work(m, n_out) =
 * 2 m (DTDYN_MODAL_BLOCK + n_out) doubles (ec, then the weights transposed). Returns 0,
 * DTDYN_ERR_WORK (nothing written) when n_work is too short, or -1 when m is not a multiple of
 * dtdyn_modal_filters_lanes(m).
 */
#include <stddef.h>

#define MODAL_BLOCK DTDYN_MODAL_BLOCK
/* four and eight doubles, operated on lane by lane (GCC and clang vector extension); loads
   unaligned */
typedef double v4d __attribute__((vector_size(32), aligned(8)));
typedef double v8d __attribute__((vector_size(64), aligned(8)));
/* from this many outputs on, the outputs are accumulated across outputs, not as dot products
   (measured on P3's 15 modes, 1,000,000 samples: dot products 22 / 37 / 41 ms at 4 / 6 / 8
   outputs against 37 / 43 / 56 ms, equal at 12) */
#define AXPY_OUTPUTS 12

#define MODAL_LANES 4
#include "modal_bank.h"
#define MODAL_LANES 8
#include "modal_bank.h"
#define MODAL_LANES 16
#include "modal_bank.h"

int dtdyn_modal_filters_lanes(long m)
{
    return m <= 4 ? 4 : m <= 8 ? 8 : 16;
}

long dtdyn_modal_filters_work(long m, long n_out)
{
    return 2 * m * MODAL_BLOCK + 2 * m * n_out;
}

DTDYN_LOOP int modal_filters_run(long n, long m, long n_in, long n_out, int im_out,
                                 const double *restrict coef, const double *restrict wt,
                                 const double *restrict x, double *restrict e, double *restrict y,
                                 double *restrict work, long n_work)
{
    double *ec = work, *w = work + 2 * m * MODAL_BLOCK;
    const int axpy = n_out >= AXPY_OUTPUTS, lanes = dtdyn_modal_filters_lanes(m);
    long o, p;
    if (m < 0 || n_out < 0 || n_work < dtdyn_modal_filters_work(m, n_out))
        return DTDYN_ERR_WORK;
    if (m % lanes != 0)
        return -1;
    if (axpy)
        for (p = 0; p < 2 * m; ++p)
            for (o = 0; o < n_out; ++o)
                w[p * n_out + o] = wt[o * 2 * m + p];
    if (lanes == 4)
        run_4(n, m, n_in, n_out, im_out, coef, wt, x, e, y, ec, w, axpy);
    else if (lanes == 8)
        run_8(n, m, n_in, n_out, im_out, coef, wt, x, e, y, ec, w, axpy);
    else
        run_16(n, m, n_in, n_out, im_out, coef, wt, x, e, y, ec, w, axpy);
    return dtdyn_stop_flag ? DTDYN_STOPPED : 0;
}
#endif /* DTDYN_MODAL_FILTERS_H */
