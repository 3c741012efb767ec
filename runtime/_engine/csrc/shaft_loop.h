/*
 * The DT-TMM time loop of a torsional tree (disks, shafts, gears, branches), written once for
 * every scheme and form: shaft_<scheme>.c defines the scheme's derived expressions as the
 * SHAFT_* macros and includes this file once per form (SHAFT_RUN names the function); the
 * macros are undefined at the end. See shaft_<scheme>.c for the arguments.
 *
 * The station expressions are the chain's (dtdyn.derive.dttmm; a torsional station is a chain
 * station with J for m, dtdyn.derive.shaft checks it); the tree adds the gear factors and the
 * junction sums: the Riccati factors S and the R terms are summed from the leaves to the root
 * (times gS and gR of each child), the unknowns u go from the root to the leaves (times gu).
 */
#include "c_api.h"
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#ifndef DTDYN_SHAFT_HELPERS
#define DTDYN_SHAFT_HELPERS
#include "sorted_loads.h"
#include "flush_subnormals.h"
#endif

#ifndef SHAFT_BLOCK
/* stations per block (its temporaries: 2 blocks of doubles, in L1) */
#define SHAFT_BLOCK 256
#endif

/* the terms of station t (block lo..): gR (hD Delta + g (F - beta)) in th, (F - beta) - Delta
   in tw; PA: the index of the parent (a root: its own, with GQ = 0), GQ the gear factor of
   q, s from the parent, GR of R to it; GROUND: spring-dampers to the ground present. Written
   per case, so that the plain stations' loop is a plain vector loop. */
#define SHAFT_TERMS(GROUND, PA, GQ, GR, FE) \
    { \
        double qn, sn, qp, sp, Fb, Dn; \
        { \
            const long i = t; \
            qn = SHAFT_Q; \
            sn = SHAFT_SV; \
            Fb = SHAFT_MB; /* beta = m a + k_g x + c_g v */ \
        } \
        { \
            const long i = PA; \
            qp = (GQ) * (SHAFT_Q); \
            sp = (GQ) * (SHAFT_SV); \
        } \
        if (GROUND) \
            Fb += kg[t] * qn + cg[t] * sn; \
        Fb = ((FE) ? Fe[t] : 0.0) - Fb; \
        Dn = k[t] * (qn - qp) + c[t] * (sn - sp); \
        th[t - lo] = (GR) * (hDelta[t] * Dn + g[t] * Fb); \
        tw[t - lo] = Fb - Dn; \
    }

static int SHAFT_RUN(int sweep, long N, long n_steps, const long *parent, const double *gu,
                            const double *gS, const double *gR, const double *m, const double *k,
                            const double *c, const double *kg, const double *cg, double dt,
                            const double *params, long n_loaded, const long *loaded,
                            const double *force, double *hist, long n_out, const long *out_idx,
                            double *xo, double *vo, double *ao, double *work)
{
    SHAFT_CONSTANTS /* the scheme's parameters and coefficients at this dt */
    SHAFT_HISTORY   /* its history rows */
    double *Fe = work, *b = work + N, *RR = work + 2 * N, *u = work + 3 * N;
    double *SR = work + 4 * N, *g = work + 5 * N, *hDelta = work + 6 * N, *den = work + 7 * N;
    /* per station once per run: gq = gu (0 at a root), ggu = g gu, gRg = gR g; jf = 1 where a
       child other than station n + 1 hangs (its R arrives through RR, its u is read from u);
       lone: the stations that are not plain line stations (a plain station hangs on station
       n - 1 without a gear and carries no other child), ascending; n_lone of them */
    double *gq = work + 8 * N, *ggu = work + 9 * N, *gRg = work + 10 * N, *jf = work + 11 * N;
    long *lone = (long *)(work + 12 * N), n_lone = 0, cur;
    /* a few loaded stations (fewer than N / 8): their indices ascending and once each; the
       plain stations' terms loop then skips the force row and those stations are redone */
    long *byidx = (long *)(work + 14 * N), n_byidx = 0, cl;
    int few = n_loaded * 8 < N;
    unsigned char *plain = (unsigned char *)(work + 13 * N);
    double th[SHAFT_BLOCK], tw[SHAFT_BLOCK], Rc, uc;
    long n, i, j, t, lo, hi, step;
    (void)dt; (void)params; (void)alpha_u;
    if (sweep == DTDYN_SWEEP_REUSE) { /* the factors a previous call left in work */
        n_lone = (long)SR[0];
        goto factored;
    }
    memset(SR, 0, (size_t)N * sizeof(double));
    memset(jf, 0, (size_t)N * sizeof(double));
    for (n = N - 1; n >= 0; --n) { /* Riccati factors: S from the leaves to the root */
        const double mu = kg ? m[n] * alpha_u + kg[n] * p + cg[n] * r : m[n] * alpha_u;
        const double kp = k[n] * p + c[n] * r;
        const double S_L = SHAFT_S_L;
        const long pa = parent[n];
        g[n] = SHAFT_G;
        hDelta[n] = SHAFT_HD;
        den[n] = 1.0 / (SHAFT_DEN); /* its reciprocal: a product per station and step */
        gq[n] = pa >= 0 ? gu[n] : 0.0;
        ggu[n] = pa >= 0 ? g[n] * gu[n] : 0.0;
        gRg[n] = gR[n] * g[n];
        if (pa >= 0) {
            SR[pa] += gS[n] * S_L;
            if (pa != n - 1)
                jf[pa] = 1.0;
        }
    }
    for (n = 0; n < N; ++n) {
        plain[n] = n > 0 && parent[n] == n - 1 && gu[n] == 1.0 && gR[n] == 1.0 && jf[n] == 0.0;
        if (!plain[n])
            lone[n_lone++] = n;
    }
    memset(Fe, 0, (size_t)N * sizeof(double));
    memset(RR, 0, (size_t)N * sizeof(double));
    if (N > 0) /* SR is read by the factors alone: it keeps n_lone for a later call */
        SR[0] = (double)n_lone;
factored:
    if (few)
        n_byidx = dtdyn_sorted_loads(n_loaded, loaded, byidx);
    for (step = 0; step < n_steps; ++step) {
        for (j = 0; j < n_loaded; ++j)
            Fe[loaded[j]] = w0 * force[step * n_loaded + j] + w1 * force[(step + 1) * n_loaded + j];
        /* leaves to root, block by block (SHAFT_BLOCK stations, temporaries in L1): the terms
           gR (hD Delta + g (F - beta)) and (F - beta) - Delta, a vector loop as for plain
           stations and the lone ones redone; then R_L = gR g R_R + gR h, R_R the sum of the
           children's R_L: the child n + 1 hands its term over in a register (Rc), the others
           through RR (cleared once read); b keeps R_R + ((F - beta) - Delta) for the forward
           pass. Two plain stations take one round (one fma latency):
           R_L of n - 1 = g_{n-1} g_n R_R + (g_{n-1} th_n + th_{n-1}); forward alike. */
        Rc = 0.0;
        cur = n_lone - 1;
        cl = n_byidx - 1;
        for (hi = N; hi > 0; hi = lo) {
            lo = hi > SHAFT_BLOCK ? hi - SHAFT_BLOCK : 0;
            if (kg) {
                if (few)
                    for (t = lo ? lo : 1; t < hi; ++t)
                        SHAFT_TERMS(1, t - 1, 1.0, 1.0, 0)
                else
                    for (t = lo ? lo : 1; t < hi; ++t)
                        SHAFT_TERMS(1, t - 1, 1.0, 1.0, 1)
                for (; cur >= 0 && lone[cur] >= lo; --cur) {
                    t = lone[cur];
                    SHAFT_TERMS(1, parent[t] >= 0 ? parent[t] : t, gq[t], gR[t], 1)
                }
                for (; cl >= 0 && byidx[cl] >= lo; --cl)
                    if (plain[t = byidx[cl]])
                        SHAFT_TERMS(1, t - 1, 1.0, 1.0, 1)
            } else {
                if (few)
                    for (t = lo ? lo : 1; t < hi; ++t)
                        SHAFT_TERMS(0, t - 1, 1.0, 1.0, 0)
                else
                    for (t = lo ? lo : 1; t < hi; ++t)
                        SHAFT_TERMS(0, t - 1, 1.0, 1.0, 1)
                for (; cur >= 0 && lone[cur] >= lo; --cur) {
                    t = lone[cur];
                    SHAFT_TERMS(0, parent[t] >= 0 ? parent[t] : t, gq[t], gR[t], 1)
                }
                for (; cl >= 0 && byidx[cl] >= lo; --cl)
                    if (plain[t = byidx[cl]])
                        SHAFT_TERMS(0, t - 1, 1.0, 1.0, 1)
            }
            for (n = hi - 1; n >= lo; --n) {
                long pa;
                double R_R = Rc, R_L;
                if (plain[n]) {
                    b[n] = Rc + tw[n - lo];
                    if (n > lo && plain[n - 1]) {
                        b[n - 1] = fma(g[n], Rc, th[n - lo]) + tw[n - 1 - lo];
                        Rc = fma(g[n - 1] * g[n], Rc, fma(g[n - 1], th[n - lo], th[n - 1 - lo]));
                        --n;
                    } else {
                        Rc = fma(g[n], Rc, th[n - lo]);
                    }
                    continue;
                }
                pa = parent[n];
                if (jf[n] != 0.0) {
                    R_R += RR[n];
                    RR[n] = 0.0;
                }
                b[n] = R_R + tw[n - lo];
                R_L = fma(gRg[n], R_R, th[n - lo]);
                Rc = 0.0;
                if (pa == n - 1)
                    Rc = R_L;
                else if (pa >= 0)
                    RR[pa] += R_L;
            }
        }
        /* root to leaves: u_n = g gu u_parent + b_n / den_n (den holds 1 / den_n), then the
           new states */
        uc = 0.0;
        for (lo = 0; lo < N; lo = hi) {
            hi = lo + SHAFT_BLOCK < N ? lo + SHAFT_BLOCK : N;
            for (i = lo; i < hi; ++i)
                th[i - lo] = b[i] * den[i];
            for (n = lo; n < hi; ++n) {
                if (plain[n]) {
                    if (n + 1 < hi && plain[n + 1]) {
                        tw[n - lo] = fma(g[n], uc, th[n - lo]);
                        uc = fma(g[n + 1] * g[n], uc, fma(g[n + 1], th[n - lo], th[n + 1 - lo]));
                        ++n;
                    } else {
                        uc = fma(g[n], uc, th[n - lo]);
                    }
                } else {
                    const long pa = parent[n];
                    const double up = pa == n - 1 ? uc : pa >= 0 ? u[pa] : 0.0;
                    uc = fma(ggu[n], up, th[n - lo]);
                    if (jf[n] != 0.0)
                        u[n] = uc;
                }
                tw[n - lo] = uc;
            }
            for (i = lo; i < hi; ++i) {
                const double un = tw[i - lo];
                SHAFT_UPDATE
            }
        }
        for (j = 0; j < n_out; ++j) {
            const long o = out_idx[j], row = (step + 1) * n_out + j;
            if (xo) xo[row] = x0[o];
            if (vo) vo[row] = v0[o];
            if (ao) ao[row] = a0[o];
        }
    }
    return 0;
}

/* the next form defines its own */
#undef SHAFT_RUN
#undef SHAFT_TERMS
#undef SHAFT_CONSTANTS
#undef SHAFT_HISTORY
#undef SHAFT_S_L
#undef SHAFT_G
#undef SHAFT_DEN
#undef SHAFT_Q
#undef SHAFT_SV
#undef SHAFT_B
#undef SHAFT_MB
#undef SHAFT_HD
#undef SHAFT_UPDATE
