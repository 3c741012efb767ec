/* fma_peak.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
#ifndef DTDYN_FMA_PEAK_H
#define DTDYN_FMA_PEAK_H
#include "c_api.h"
/*
 * The multiply-add peak of one core for the 4-lane vectors of the generated loops (nl_loop.c,
 * modal_states.c), which `dtdyn bench` divides each loop's achieved flop rate by: `rounds` rounds
 * of 12 independent chains a <- a x + y of 4 doubles each (as many independent chains as two
 * multiply-add units with a latency of up to 6 cycles can keep busy), as fused multiply-adds
 * where the CPU has them (as the loops' VFMA), else as a multiply and an add: 96 flops a round,
 * a multiply-add counted as 2. Returns the sum of the chains, so that their work is kept.
 */
#if defined(__FMA__) && defined(__AVX__)
#include <immintrin.h>
#endif

typedef double peak_v4 __attribute__((vector_size(32), aligned(8)));

double dtdyn_fma_peak(long rounds)
{
    enum { CHAINS = 12 };
    const peak_v4 x = {0.999999, 0.9999991, 0.9999992, 0.9999993};
    const peak_v4 y = {1e-6, 2e-6, 3e-6, 4e-6};
    peak_v4 a[CHAINS];
    double s = 0.0;
    long k;
    int i;
    for (i = 0; i < CHAINS; ++i)
        a[i] = (peak_v4){i, i + 0.25, i + 0.5, i + 0.75};
    for (k = 0; k < rounds; ++k)
        for (i = 0; i < CHAINS; ++i)
#if defined(__FMA__) && defined(__AVX__)
            a[i] = (peak_v4)_mm256_fmadd_pd((__m256d)a[i], (__m256d)x, (__m256d)y);
#else
            a[i] = a[i] * x + y;
#endif
    for (i = 0; i < CHAINS; ++i)
        s += (a[i][0] + a[i][1]) + (a[i][2] + a[i][3]);
    return s;
}
#endif /* DTDYN_FMA_PEAK_H */
