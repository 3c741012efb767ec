/*
 * The DT-TMM time loop of a chain, written once for every scheme and form: chain_<scheme>.c
 * defines the scheme's derived expressions as the CHAIN_* macros and includes this file once
 * per form (CHAIN_RUN names the function); the macros are undefined at the end. See
 * chain_<scheme>.c for the arguments.
 */
#ifndef DTDYN_CHAIN_HELPERS
#define DTDYN_CHAIN_HELPERS
#include "c_api.h"
#include <math.h>
#include <float.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* a pair of doubles (the two error histories); alignment 8, as the arrays NumPy allocates */
typedef double pair __attribute__((vector_size(16), aligned(8)));

/* Error-free transformations (Veltkamp split, no fma: the NumPy backend runs the same steps). */
static void two_prod(double a, double b, double *p, double *e)
{
    const double ta = 134217729.0 * a, tb = 134217729.0 * b;
    const double ah = ta - (ta - a), al = a - ah, bh = tb - (tb - b), bl = b - bh;
    *p = a * b;
    *e = ((ah * bh - *p) + ah * bl + al * bh) + al * bl;
}

static void two_sum(double a, double b, double *s, double *e)
{
    const double t = a + b, bb = t - a;
    *s = t;
    *e = (a - (t - bb)) + (b - bb);
}

/* a x + b y in double-double arithmetic (x = xh + xl, y = yh + yl) */
static void dd_axpy(double a, double xh, double xl, double b, double yh, double yl, double *rh,
                    double *rl)
{
    double p, pe, q, qe, t, te;
    two_prod(a, xh, &p, &pe);
    two_prod(b, yh, &q, &qe);
    two_sum(p, q, &t, &te);
    te += pe + qe + a * xl + b * yl;
    two_sum(t, te, rh, rl);
}

#include "sorted_loads.h"
#include "flush_subnormals.h"

/* +1 or -1 from the step index j (the top bit of splitmix64 of j) */
static double step_sign(uint64_t j)
{
    uint64_t z = (j + 1u) * UINT64_C(0x9E3779B97F4A7C15);
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    z ^= z >> 31;
    return (z >> 63) ? 1.0 : -1.0;
}
/* stations per block of the stable sweep (its temporaries: 3 blocks of doubles, in L1) */
#define CHAIN_BLOCK 256

/* The stable sweep on two threads (threads = 2): the chain splits at station P into a lower part
   0 .. P-1 (a second thread) and an upper part P .. N-1 (the calling thread). Each part runs the
   back pass from R = 0 at its top: exact for the upper part, which hands R at P over; the lower
   part's b lacks R_P's share, Gd_n R_P with Gd_n = (1 / den_n) g_{n+1} ... g_{P-1} (computed
   once per call), added in its forward pass, which then hands u_{P-1} over to the upper part's
   forward pass. Per step: upper back -> lower forward -> upper forward -> next upper back, the
   lower back pass running beside the upper forward pass; the upper part gets this fraction of
   the stations (the path through it is the longer). */
#define CHAIN_UPPER_FRACTION 0.40
#include <pthread.h>
#include <sched.h>

/* a value handed from one thread to the other once per step (one slot: the producer cannot run
   a step ahead of the consumer's read, see CHAIN_STABLE) */
typedef struct {
    long step;   /* the step whose value val is, plus 1 (0: none yet) */
    double val;
} chain_flag;

static void chain_post(chain_flag *f, long step, double val)
{
    f->val = val;
    __atomic_store_n(&f->step, step + 1, __ATOMIC_RELEASE);
}

static double chain_wait(chain_flag *f, long step)
{
    long spins = 0;
    while (__atomic_load_n(&f->step, __ATOMIC_ACQUIRE) != step + 1)
        if (++spins > 4096)
            sched_yield();   /* the other thread is descheduled: give it the core */
    return f->val;
}

/* the stable sweep's arguments, shared by the threads of a split (CHAIN_STABLE) */
typedef struct {
    long N, n_steps, n_loaded, n_out, n_byidx, split;
    const double *m, *k, *c, *kg, *cg, *params, *force;
    double dt;
    const long *loaded, *out_idx, *byidx;
    double *hist, *xo, *vo, *ao, *work;
    int few;
    chain_flag R, u;   /* R at P (upper -> lower), u_{P-1} (lower -> upper) */
} chain_args;

#define CHAIN_CAT_(a, b) a##_##b
#define CHAIN_CAT(a, b) CHAIN_CAT_(a, b)
#endif

/* mu of mass n: m alpha + k_g p + c_g r; kg and cg are NULL for a chain without ground elements
   (then mu = m alpha and beta = m b, as many operations as a plain chain needs) */
#define GROUNDED_MU(n) (kg ? m[n] * alpha_u + kg[n] * p + cg[n] * r : m[n] * alpha_u)
/* kappa of station n: k p + c r */
#define KAPPA(n) (k[n] * p + c[n] * r)

/* the stable sweep's terms of station t (in block lo..): h = ((mu - S_R) Delta + kappa (F - beta))
   / den in th, g = kappa / den in tg (from kappa = k p + c r and the rows hm = mu - S_R and
   1 / den: the back pass reads no g row) and (F - beta) - Delta in tw; GROUND: the station has
   a spring-damper to the ground (kg, cg), LEFT: it has a mass to its left (t > 0); FE: read its
   external force (0: none, where a few masses are loaded the loop skips the force row and
   redoes those masses). Written out per case, so that the block loop is a plain vector loop. */
#define CHAIN_TERMS(GROUND, LEFT, FE) \
    { \
        double qn, sn, qm = 0.0, sm = 0.0, Fb, Dn; \
        { \
            const long i = t; \
            qn = CHAIN_Q; \
            sn = CHAIN_SV; \
            Fb = CHAIN_MB; /* beta = m a + k_g x + c_g v */ \
        } \
        if (LEFT) { \
            const long i = t - 1; \
            qm = CHAIN_Q; \
            sm = CHAIN_SV; \
        } \
        if (GROUND) \
            Fb += kg[t] * qn + cg[t] * sn; \
        Fb = ((FE) ? Fe[t] : 0.0) - Fb; \
        Dn = k[t] * (qn - qm) + c[t] * (sn - sm); \
        { \
            const double kp = KAPPA(t); \
            th[t - lo] = den[t] * (hm[t] * Dn + kp * Fb); \
            tg[t - lo] = kp * den[t]; \
        } \
        tw[t - lo] = Fb - Dn; \
    }

#define CHAIN_STABLE CHAIN_CAT(CHAIN_RUN, stable)
#define CHAIN_LOWER CHAIN_CAT(CHAIN_RUN, lower)

/* The stable sweep's time loop over the stations plo .. phi - 1 of part (0: the whole chain; 1,
   2: the lower and upper parts of a split at A->split, see CHAIN_UPPER_FRACTION), in two passes
   over them (header of dtdyn.derive.dttmm), block by block (CHAIN_BLOCK stations, temporaries
   in L1): back, R_L = g R_R + h, keeping (R_R + ((F - beta) - Delta)) / den in b (den holds
   1 / den_n: it is read in this pass, with hm, for h and g); forward, u_n = g u_{n-1} + b_n,
   and the stations' new states. Each pass reads each row once: the sweep at N = 1e5 is bound
   by memory traffic. The terms before and the update after the recurrences are vector loops;
   each recurrence takes four stations a round, x_{n-4} = (g_{n-4} .. g_{n-1}) x_n + (the same
   recurrence from 0 over the four), each station's x one fma from the round's x_n (back;
   forward alike), so that one fma latency is paid per four stations. */
static void CHAIN_STABLE(chain_args *A, int part)
{
    const long N = A->N, n_steps = A->n_steps, n_loaded = A->n_loaded, n_out = A->n_out;
    const double *m = A->m, *k = A->k, *c = A->c, *kg = A->kg, *cg = A->cg;
    const double *params = A->params, *force = A->force, dt = A->dt;
    const long *loaded = A->loaded, *out_idx = A->out_idx, *byidx = A->byidx;
    double *hist = A->hist, *work = A->work, *xo = A->xo, *vo = A->vo, *ao = A->ao;
    const int few = A->few;
    CHAIN_CONSTANTS
    CHAIN_STATE     /* the history rows (no error histories: the stable sweep) */
    double *Fe = work, *b = work + 3 * N, *g = work + 6 * N, *hm = work + 7 * N;
    double *Gd = work + 8 * N, *den = work + DTDYN_CHAIN_ROW_DEN * N;
    const long P = A->split, plo = part == 2 ? P : 0, phi = part == 1 ? P : N;
    long n, i, j, step, top = A->n_byidx;
    double th[CHAIN_BLOCK], tw[CHAIN_BLOCK], tg[CHAIN_BLOCK];
    (void)dt; (void)params; (void)alpha_u; (void)m;
    while (top > 0 && byidx[top - 1] >= phi)
        --top;   /* byidx[.. top - 1]: the loaded stations below phi */
    if (part == 1) {   /* Gd_n = (1 / den_n) g_{n+1} ... g_{P-1}, g = kappa / den as below */
        double G = 1.0;
        for (n = P - 1; n >= 0; --n) {
            Gd[n] = den[n] * G;
            G *= KAPPA(n) * den[n];
        }
    }
    for (step = 0; step < n_steps; ++step) {
        double R_R = 0.0, un = 0.0, R_P = 0.0;
        long lo, hi, t, cur = top - 1;
        for (j = 0; j < n_loaded; ++j)
            if (loaded[j] >= plo && loaded[j] < phi)
                Fe[loaded[j]] = w0 * force[step * n_loaded + j]
                                + w1 * force[(step + 1) * n_loaded + j];
        for (hi = phi; hi > plo; hi = lo) {
            lo = hi - plo > CHAIN_BLOCK ? hi - CHAIN_BLOCK : plo;
            if (lo == 0) {   /* station 0: joined to the ground (q, s of its left: 0) */
                t = 0;
                if (kg)
                    CHAIN_TERMS(1, 0, 1)
                else
                    CHAIN_TERMS(0, 0, 1)
            }
            if (kg && few)
                for (t = lo ? lo : 1; t < hi; ++t)
                    CHAIN_TERMS(1, 1, 0)
            else if (kg)
                for (t = lo ? lo : 1; t < hi; ++t)
                    CHAIN_TERMS(1, 1, 1)
            else if (few)
                for (t = lo ? lo : 1; t < hi; ++t)
                    CHAIN_TERMS(0, 1, 0)
            else
                for (t = lo ? lo : 1; t < hi; ++t)
                    CHAIN_TERMS(0, 1, 1)
            for (; few && cur >= 0 && byidx[cur] >= lo; --cur) {  /* the loaded masses */
                t = byidx[cur];
                if (t == 0)
                    continue;  /* done above, with its force */
                if (kg)
                    CHAIN_TERMS(1, 1, 1)
                else
                    CHAIN_TERMS(0, 1, 1)
            }
            for (n = hi - 1; n - 3 >= lo; n -= 4) {   /* four stations a round (above) */
                const double *gg = tg + n - 3 - lo, *hh = th + n - 3 - lo;
                const double *ww = tw + n - 3 - lo, *dd = den + n - 3;
                const double R_in = R_R, g2 = gg[2] * gg[3], g1 = gg[1] * g2;
                const double c2 = fma(gg[2], hh[3], hh[2]), c1 = fma(gg[1], c2, hh[1]);
                b[n] = (R_in + ww[3]) * dd[3];
                b[n - 1] = (fma(gg[3], R_in, hh[3]) + ww[2]) * dd[2];
                b[n - 2] = (fma(g2, R_in, c2) + ww[1]) * dd[1];
                b[n - 3] = (fma(g1, R_in, c1) + ww[0]) * dd[0];
                R_R = fma(gg[0] * g1, R_in, fma(gg[0], c1, hh[0]));
            }
            for (; n >= lo; --n) {
                b[n] = (R_R + tw[n - lo]) * den[n];
                R_R = fma(tg[n - lo], R_R, th[n - lo]);
            }
        }
        if (part == 2) {   /* hand R at P over; take u_{P-1} */
            chain_post(&A->R, step, R_R);
            un = chain_wait(&A->u, step);
        } else if (part == 1) {
            R_P = chain_wait(&A->R, step);
        }
        for (lo = plo; lo < phi; lo = hi) {
            const double *bb = b + lo;   /* b_n at bb[n - lo]: with R_P's share in the lower part */
            hi = lo + CHAIN_BLOCK < phi ? lo + CHAIN_BLOCK : phi;
            if (part == 1) {
                for (i = lo; i < hi; ++i)
                    th[i - lo] = fma(Gd[i], R_P, b[i]);
                bb = th;
            }
            for (n = lo; n + 3 < hi; n += 4) {
                const double *gg = g + n, *hh = bb + (n - lo);
                double *uu = tw + n - lo;
                const double u_in = un, g1 = gg[0] * gg[1], g2 = g1 * gg[2];
                const double c1 = fma(gg[1], hh[0], hh[1]), c2 = fma(gg[2], c1, hh[2]);
                uu[0] = fma(gg[0], u_in, hh[0]);
                uu[1] = fma(g1, u_in, c1);
                uu[2] = fma(g2, u_in, c2);
                un = uu[3] = fma(g2 * gg[3], u_in, fma(gg[3], c2, hh[3]));
            }
            for (; n < hi; ++n) {
                un = fma(g[n], un, bb[n - lo]);
                tw[n - lo] = un;
            }
            for (i = lo; i < hi; ++i) {
                const double un = tw[i - lo];
                CHAIN_UPDATE
            }
        }
        if (part == 1)
            chain_post(&A->u, step, un);
        for (j = 0; j < n_out; ++j) {
            const long o = out_idx[j], row = (step + 1) * n_out + j;
            if (o < plo || o >= phi)
                continue;
            if (xo) xo[row] = x0[o];
            if (vo) vo[row] = v0[o];
            if (ao) ao[row] = a0[o];
        }
    }
}

static void *CHAIN_LOWER(void *A)
{
    dtdyn_flush_on();   /* this thread's mode: subnormals flushed, as the caller's */
    CHAIN_STABLE((chain_args *)A, 1);
    return NULL;
}

static int CHAIN_RUN(int sweep, long N, long n_steps, const double *m, const double *k,
                            const double *c, const double *kg, const double *cg, double dt, const double *params, long n_loaded,
                            const long *loaded, const double *force, double *hist, long n_out,
                            const long *out_idx, double *xo, double *vo, double *ao, double *work,
                            double *ehist, double *err, int threads)
{
    const int reuse = sweep == DTDYN_SWEEP_REUSE; /* the stable sweep with the factors already in work */
    if (reuse)
        sweep = 0;
    CHAIN_CONSTANTS /* the scheme's parameters and coefficients at this dt */
    CHAIN_HISTORY   /* its history rows (and their error histories) */
    double *Fe = work, *q = work + N, *s = work + 2 * N, *b = work + 3 * N, *Dl = work + 4 * N;
    double *SR = work + 5 * N, *g = work + 6 * N, *hm = work + 7 * N, *R = work + 8 * N;
    double *u = work + 9 * N, *Pu = work + 10 * N, *den = work + DTDYN_CHAIN_ROW_DEN * N;
    /* plain sweep only: the error histories' unknown, terms and Riccati R (pairs); the
       coefficients of the zero-force step; the station matrix entries per run and per step
       (DTDYN_CHAIN_ROWS_PLAIN rows in all: generated/c_api.h, from dtdyn.derive.c_api) */
    pair *eu = (pair *)(work + DTDYN_CHAIN_ROW_PAIRS * N);
    pair *eb = (pair *)(work + (DTDYN_CHAIN_ROW_PAIRS + 2) * N);
    pair *eDl = (pair *)(work + (DTDYN_CHAIN_ROW_PAIRS + 4) * N);
    pair *eR = (pair *)(work + (DTDYN_CHAIN_ROW_PAIRS + 6) * N);
    CHAIN_PLAIN_ROWS
    double PfN = 1.0, epsP = 0.0, emax = sweep ? err[0] : 0.0, xmax = sweep ? err[1] : 0.0;
    uint64_t jstep = sweep ? (uint64_t)err[2] : 0u;
    long n, i, j, step, n_byidx = 0, *byidx = (long *)q;
    int few = 0;
    (void)dt; (void)params; (void)alpha_u; (void)q; (void)b; (void)R; (void)Pu; (void)SR; (void)g;
    (void)hm; (void)den;
    (void)eu; (void)eb; (void)eDl; (void)eR;
    CHAIN_PLAIN_VOIDS
    if (!reuse) {   /* Riccati factors: the stable sweep, and the plain sweep's error estimate */
        double S_R = 0.0;
        for (n = N - 1; n >= 0; --n) {
            const double mu = GROUNDED_MU(n), kp = KAPPA(n);
            double S_L;
            SR[n] = S_R;
            g[n] = CHAIN_G;
            S_L = CHAIN_S_L;
            den[n] = 1.0 / (CHAIN_DEN); /* its reciprocal: a product per station and step */
            hm[n] = mu - S_R;           /* = hD den (dtdyn.derive.dttmm) */
            if (sweep) {
                CHAIN_ERROR_STEP
            }
            S_R = S_L;
        }
    }
    if (sweep) {
        double P_u = 0.0, P_f = 1.0;
        for (n = 0; n < N; ++n) {
            const double mu = GROUNDED_MU(n), kp = KAPPA(n);
            CHAIN_PLAIN_RUN
            (void)mu; (void)kp;
            const double nu = CHAIN_USE0 * P_u + CHAIN_USE1 * P_f;
            P_f = CHAIN_USE3 * P_u + CHAIN_USE4 * P_f;
            P_u = nu;
            Pu[n] = P_u;
        }
        PfN = P_f;
        {   /* eps_P: the rounding error of P_f,N against the same product in double-double */
            double uh = 0.0, ul = 0.0, fh = 1.0, fl = 0.0;
            for (n = 0; n < N; ++n) {
                double nh, nl, gh, gl;
                dd_axpy(CHAIN_USE0, uh, ul, CHAIN_USE1, fh, fl, &nh, &nl);
                dd_axpy(CHAIN_USE3, uh, ul, CHAIN_USE4, fh, fl, &gh, &gl);
                uh = nh;
                ul = nl;
                fh = gh;
                fl = gl;
            }
            epsP = ((PfN - fh) - fl) / fh;
            if (!isfinite(epsP))
                epsP = DBL_EPSILON;  /* the product overflowed: an eps-sized systematic part */
        }
    }
    memset(Fe, 0, (size_t)N * sizeof(double));
    if (sweep == 0 && n_loaded * 8 < N) {
        /* a few loaded masses: their indices ascending and once each (in the q row, which the
           stable sweep does not use); the terms loop then skips the force row */
        few = 1;
        n_byidx = dtdyn_sorted_loads(n_loaded, loaded, byidx);
    }
    if (sweep == 0) {
        chain_args A = {N, n_steps, n_loaded, n_out, n_byidx, N, m, k, c, kg, cg, params, force,
                        dt, loaded, out_idx, byidx, hist, xo, vo, ao, work, few,
                        {0, 0.0}, {0, 0.0}};
        pthread_t lower;
        if (threads >= 2 && N >= 2) {
            A.split = N - (long)(CHAIN_UPPER_FRACTION * (double)N);
            A.split = A.split < 1 ? 1 : A.split > N - 1 ? N - 1 : A.split;
            if (pthread_create(&lower, NULL, CHAIN_LOWER, &A) == 0) {
                CHAIN_STABLE(&A, 2);
                pthread_join(lower, NULL);
                return 0;
            }
            A.split = N;   /* no second thread: one part */
        }
        CHAIN_STABLE(&A, 0);
        return 0;
    }
    for (step = 0; step < n_steps; ++step) {
        for (j = 0; j < n_loaded; ++j)
            Fe[loaded[j]] = w0 * force[step * n_loaded + j] + w1 * force[(step + 1) * n_loaded + j];
        for (i = 0; i < N; ++i) {
            q[i] = CHAIN_Q;
            s[i] = CHAIN_SV;
            b[i] = CHAIN_MB;  /* beta = m a + k_g x + c_g v */
        }
        if (kg)
            for (i = 0; i < N; ++i)
                b[i] += kg[i] * q[i] + cg[i] * s[i];
        for (n = 0; n < N; ++n) {
            const double qp = n ? q[n - 1] : 0.0, sp = n ? s[n - 1] : 0.0;
            Dl[n] = k[n] * (q[n] - qp) + c[n] * (s[n] - sp);
        }
        const pair zero2 = {0.0, 0.0};
        double Q_u = 0.0, Q_f = 0.0, z_u = 0.0, z_f, f1;
        pair kick, eup = zero2, eqp = zero2, esp = zero2;
        /* the error histories' terms (error estimate, see the header); their Riccati passes
           run inside the solution's two passes (independent recurrences) */
        for (i = 0; i < N; ++i) {
            const pair eq = CHAIN_EQ;
            const pair es = CHAIN_ES;
            eb[i] = m[i] * (CHAIN_EB);
            if (kg)
                eb[i] += kg[i] * eq + cg[i] * es;
            eDl[i] = k[i] * (eq - eqp) + c[i] * (es - esp);
            eqp = eq;
            esp = es;
        }
        for (n = 0; n < N; ++n) {
            const long nb = N - 1 - n;
            const double mu = GROUNDED_MU(n), kp = KAPPA(n);
            double nu;
            (void)mu; (void)kp;
            CHAIN_PLAIN_STEP
            nu = CHAIN_USE0 * Q_u + CHAIN_USE1 * Q_f + CHAIN_USE2;
            Q_f = CHAIN_USE3 * Q_u + CHAIN_USE4 * Q_f + CHAIN_USE5;
            Q_u = nu;
            eR[nb] = g[nb] * (nb + 1 < N ? eR[nb + 1] : zero2) + hD[nb] * eDl[nb] + hb[nb] * eb[nb];
        }
        z_f = f1 = -Q_f / PfN;
        kick[0] = -epsP * f1;
        kick[1] = CHAIN_RANDOM_SPREAD * step_sign(jstep++) * DBL_EPSILON * f1;
        for (n = 0; n < N; ++n) {
            const double nu = CHAIN_USE0 * z_u + CHAIN_USE1 * z_f + CHAIN_USE2;
            z_f = CHAIN_USE3 * z_u + CHAIN_USE4 * z_f + CHAIN_USE5;
            z_u = nu;
            u[n] = z_u;
            eup = g[n] * eup + fR[n] * (n + 1 < N ? eR[n + 1] : zero2) + fD[n] * eDl[n] + fb[n] * eb[n];
            eu[n] = eup + kick * Pu[n];
        }
        double ms = 0.0, mr = 0.0;
        for (i = 0; i < N; ++i) {
            const pair ex1 = CHAIN_EX1;
            const pair ev1 = CHAIN_EV1;
            const pair ea1 = CHAIN_EA1;
            const double un = u[i];
            CHAIN_UPDATE
            CHAIN_ERROR_SHIFT
            if (fabs(x0[i]) > xmax) xmax = fabs(x0[i]);
            if (fabs(ex1[0]) > ms) ms = fabs(ex1[0]);
            if (fabs(ex1[1]) > mr) mr = fabs(ex1[1]);
        }
        if (ms + mr > emax) emax = ms + mr;
        for (j = 0; j < n_out; ++j) {
            const long o = out_idx[j], row = (step + 1) * n_out + j;
            if (xo) xo[row] = x0[o];
            if (vo) vo[row] = v0[o];
            if (ao) ao[row] = a0[o];
        }
    }
    if (sweep) {
        err[0] = emax;
        err[1] = xmax;
        err[2] = (double)jstep;
    }
    return 0;
}

/* the next form defines its own */
#undef GROUNDED_MU
#undef KAPPA
#undef CHAIN_STABLE
#undef CHAIN_LOWER
#undef CHAIN_TERMS
#undef CHAIN_RUN
#undef CHAIN_CONSTANTS
#undef CHAIN_HISTORY
#undef CHAIN_STATE
#undef CHAIN_PLAIN_ROWS
#undef CHAIN_PLAIN_VOIDS
#undef CHAIN_G
#undef CHAIN_S_L
#undef CHAIN_DEN
#undef CHAIN_ERROR_STEP
#undef CHAIN_PLAIN_RUN
#undef CHAIN_PLAIN_STEP
#undef CHAIN_USE0
#undef CHAIN_USE1
#undef CHAIN_USE2
#undef CHAIN_USE3
#undef CHAIN_USE4
#undef CHAIN_USE5
#undef CHAIN_Q
#undef CHAIN_SV
#undef CHAIN_B
#undef CHAIN_MB
#undef CHAIN_EQ
#undef CHAIN_ES
#undef CHAIN_EB
#undef CHAIN_RANDOM_SPREAD
#undef CHAIN_UPDATE
#undef CHAIN_EX1
#undef CHAIN_EV1
#undef CHAIN_EA1
#undef CHAIN_ERROR_SHIFT
