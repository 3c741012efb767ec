/* nl_elements.h: hand-written C, compiled as it is (dtdyn/_engine/csrc), included by
   nl_chain.h and nl_stations.h */
/*
 * The elements' part of a (sub)step of the condensed loops, the same around every linear step
 * (nl_chain.h: a chain's DT-TMM sweep; nl_stations.h: a beam's block chain or a shaft's tree):
 *
 *     loads    L(f_a, g_k), L(f_b, 0) on the loaded DOFs                         (nl_loads)
 *     Newton   r(u) = [w - Q - Dwg g(u); z - z_old - h/2 (z'(u) + z'_old)] = 0, from the
 *              predictor u = [Q + Dwg g_k; z_k + h z'_k]                         (nl_solve)
 *     history  H <- H + sum_e g_e U_e                                           (nl_add_forces)
 *
 * Newton accepts u by the rule of every backend (newton_solve in newton.h, or newton_kept with
 * its LU factors kept from step to step). The scratch (nl_scratch doubles): Q, z_old, z'_old,
 * r, J, g, z', then with newton_kept its step d and the kept factors.
 */
#ifndef DTDYN_NL_ELEMENTS_H
#define DTDYN_NL_ELEMENTS_H
#include <math.h>

#include "newton.h"

typedef struct {
    long ne, nw, nz, nu, max_iter;
    int kept;                /* newton_kept (1) or newton_solve (0) */
    double h, tol;
    double scale, scale_u;   /* the sizes of the residual's terms and of the unknowns so far */
    const double *Dwg;       /* nw x ne, column-major */
    double *u, *g, *rate;    /* the state: the last solution [w; z], g, z' */
    double *Q, *zold, *rold, *r, *J, *gn, *rn_, *d;
    const double *arg[5];    /* nl_residual's arguments and results */
    double *res[4];
    lu_kept lu;
} nl_step;

/* the doubles of the scratch for ne elements, nw deformations, nz internal states */
static long nl_scratch(long ne, long nw, long nz, int kept)
{
    const long nu = nw + nz;
    return nw + nz + nz + nu + nu * nu + ne + nz + (kept ? nu + nu * nu : 0);
}

/* s over the scratch sc (nl_scratch doubles) and the state u, g, rate; piv: nu longs for the
   kept factors' row swaps (kept); returns the end of the scratch */
static double *nl_step_init(nl_step *s, long ne, long nw, long nz, long max_iter, int kept,
                            double h, double tol, const double *Dwg, const double *par,
                            double *u, double *g, double *rate, double *sc, long *piv)
{
    s->ne = ne, s->nw = nw, s->nz = nz, s->nu = nw + nz, s->max_iter = max_iter;
    s->kept = kept, s->h = h, s->tol = tol, s->scale = 0.0, s->scale_u = 0.0, s->Dwg = Dwg;
    s->u = u, s->g = g, s->rate = rate;
    s->Q = sc, s->zold = s->Q + nw, s->rold = s->zold + nz, s->r = s->rold + nz;
    s->J = s->r + s->nu, s->gn = s->J + s->nu * s->nu, s->rn_ = s->gn + ne, s->d = s->rn_ + nz;
    s->arg[0] = u, s->arg[1] = s->Q, s->arg[2] = s->zold, s->arg[3] = s->rold, s->arg[4] = par;
    s->res[0] = s->r, s->res[1] = s->J, s->res[2] = s->gn, s->res[3] = s->rn_;
    s->lu.f = kept ? s->d + s->nu : NULL;
    s->lu.piv = piv;
    s->lu.have = 0;
    s->lu.formed = 0.0;
    return s->d + (kept ? s->nu + s->nu * s->nu : 0);
}

/* the loads of a (sub)step's two ends on the nl loaded DOFs (frc: two rows of nl): the forces
   f0 + c (f1 - f0) at c = ca and cb on their positions pf, and on the first end the elements'
   forces g, -g_e on pi[e] and +g_e on pj[e] (-1: the ground) */
static void nl_loads(long nl, long nf, long ne, const long *pf, const long *pi, const long *pj,
                     const double *f0, const double *f1, double ca, double cb, const double *g,
                     double *frc)
{
    long i, e;
    zero(2 * nl, frc);
    for (i = 0; i < nf; ++i) {
        frc[pf[i]] += f0[i] + ca * (f1[i] - f0[i]);
        frc[nl + pf[i]] += f0[i] + cb * (f1[i] - f0[i]);
    }
    for (e = 0; e < ne; ++e) {
        frc[pi[e]] -= g[e];
        if (pj[e] >= 0)
            frc[pj[e]] += g[e];
    }
}

/*
 * Newton from the predictor, at the deformations s->Q the caller has set; iw and w: CasADi's
 * work. stats, as the loops report them: [max iterations, total iterations, max final residual,
 * failing residual, LU factorizations of newton_kept]. Returns 0 (g and z' then the accepted
 * u's), or 1 when Newton failed (stats[3]: its last residual).
 */
static int nl_solve(nl_step *s, nl_int *iw, double *w, double *stats)
{
    const long ne = s->ne, nw = s->nw, nz = s->nz, nu = s->nu;
    double rn = INFINITY, theta = 0.0;
    long i, e, it;
    copy(nz, s->u + nw, s->zold);
    copy(nz, s->rate, s->rold);
    for (i = 0; i < nw; ++i) {
        double sum = s->Q[i];
        for (e = 0; e < ne; ++e)
            sum += s->Dwg[e * nw + i] * s->g[e];
        s->u[i] = sum;
    }
    for (i = 0; i < nz; ++i)
        s->u[nw + i] = s->zold[i] + s->h * s->rold[i];
    s->scale = grow(s->scale, norm_inf(nw, s->Q));
    if (s->kept)
        it = newton_kept(nu, 0, s->u, s->r, s->J, s->scale, s->scale_u, s->tol, s->max_iter,
                         s->arg, s->res, iw, w, &rn, &theta, &s->lu, s->d);
    else
        it = newton_solve(nu, 0, s->u, s->r, s->J, s->scale, s->scale_u, s->tol, s->max_iter,
                          s->arg, s->res, iw, w, &rn, &theta);
    stats[4] = s->lu.formed;
    if (it < 0 || !(norm_inf(ne, s->gn) < INFINITY)) {
        stats[3] = rn;
        return 1;
    }
    s->scale_u = grow(s->scale_u, norm_inf(nu, s->u));
    s->scale = grow(s->scale, s->scale_u);
    stats[1] += (double)it;
    if ((double)it > stats[0])
        stats[0] = (double)it;
    if (rn > stats[2])
        stats[2] = rn;
    copy(ne, s->gn, s->g);
    copy(nz, s->rn_, s->rate);
    return 0;
}

/* H (size doubles) += sum_e g_e U_e, U_e the step's response to element e's unit load pair */
static void nl_add_forces(long size, long ne, const double *g, const double *U, double *H)
{
    long t, e;
    if (ne == 1) { /* one element: a vector loop */
        const double g0 = g[0];
        for (t = 0; t < size; ++t)
            H[t] += g0 * U[t];
        return;
    }
    for (t = 0; t < size; ++t) {
        double sum = 0.0;
        for (e = 0; e < ne; ++e)
            sum += g[e] * U[e * size + t];
        H[t] += sum;
    }
}
#endif /* DTDYN_NL_ELEMENTS_H */
