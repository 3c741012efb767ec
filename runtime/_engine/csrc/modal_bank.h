/* modal_bank.h: hand-written C, compiled as it is (dtdyn/_engine/csrc) */
/*
 * The modal filters' bank for chunks of MODAL_LANES = 4, 8 or 16 states (modal_filters.h, whose
 * comment describes the recursion, the layout and the outputs): included once per chunk size,
 * with MODAL_LANES defined before each inclusion, it defines states_block_<L>, outputs_dot_<L>,
 * outputs_axpy_<L> and run_<L> (L = MODAL_LANES), and undefines MODAL_LANES. The loops over the
 * L states of a chunk have a constant trip count, so the states of a chunk stay in registers,
 * held as vectors of 4 (chunk 4) or 8 doubles (modal_vw_<L>). No include guard: each inclusion
 * is another chunk size.
 */
#ifndef MODAL_LANES
#error "modal_bank.h: define MODAL_LANES (4, 8 or 16) before including it"
#endif
#define MODAL_PASTE_(name, lanes) name##_##lanes
#define MODAL_PASTE(name, lanes) MODAL_PASTE_(name, lanes)
/* name_<L>: this chunk size's function */
#define MODAL_FN(name) MODAL_PASTE(name, MODAL_LANES)

static inline void MODAL_FN(states_block)(long nb, long m, long n_in,
                                          const double *restrict coef, const double *restrict x,
                                          double *restrict e, double *restrict ec)
{
#if MODAL_LANES == 4
    typedef v4d vw;
    enum { W = 4, V = MODAL_LANES / W }; /* vectors of W states per chunk */
#else
    typedef v8d vw;
    enum { W = 8, V = MODAL_LANES / W }; /* vectors of W states per chunk */
#endif
    const double *d_re = coef, *d_im = coef + m, *g = coef + 2 * m;
    const long gs = n_in * m; /* stride between the four input-weight arrays */
    long c, k, i, v;
    for (c = 0; c < m; c += MODAL_LANES) {
        vw er[V], ei[V], dr[V], di[V];
        double *restrict rows = ec + c * 2 * MODAL_BLOCK;
        for (v = 0; v < V; ++v) {
            er[v] = *(const vw *)(e + c + W * v);
            ei[v] = *(const vw *)(e + m + c + W * v);
            dr[v] = *(const vw *)(d_re + c + W * v);
            di[v] = *(const vw *)(d_im + c + W * v);
        }
        for (k = 0; k < nb; ++k) {
            const double *xa = x + k * n_in, *xb = xa + n_in;
            double *restrict row = rows + k * 2 * MODAL_LANES;
            vw ur[V], ui[V];
            for (v = 0; v < V; ++v) {
                ur[v] = (vw){0.0};
                ui[v] = (vw){0.0};
            }
            for (i = 0; i < n_in; ++i) {
                const double a = xa[i], b = xb[i];
                const double *g0r = g + i * m + c, *g0i = g0r + gs, *g1r = g0i + gs;
                const double *g1i = g1r + gs;
                for (v = 0; v < V; ++v) {
                    ur[v] += *(const vw *)(g0r + W * v) * a + *(const vw *)(g1r + W * v) * b;
                    ui[v] += *(const vw *)(g0i + W * v) * a + *(const vw *)(g1i + W * v) * b;
                }
            }
            for (v = 0; v < V; ++v) {
                const vw inc_re = dr[v] * er[v] - di[v] * ei[v] + ur[v];
                const vw inc_im = dr[v] * ei[v] + di[v] * er[v] + ui[v];
                er[v] += inc_re;
                ei[v] += inc_im;
                *(vw *)(row + W * v) = er[v];
                *(vw *)(row + MODAL_LANES + W * v) = ei[v];
            }
        }
        for (v = 0; v < V; ++v) {
            *(vw *)(e + c + W * v) = er[v];
            *(vw *)(e + m + c + W * v) = ei[v];
        }
    }
}

/* y[k][o] = sum over the chunks and parts of row . wt[o] (MODAL_LANES partial sums) */
static void MODAL_FN(outputs_dot)(long nb, long m, long n_out, int im_out,
                                  const double *restrict wt, const double *restrict ec,
                                  double *restrict y)
{
    long k, o, c, l, h;
    for (k = 0; k < nb; ++k)
        for (o = 0; o < n_out; ++o) {
            const double *wo = wt + o * 2 * m;
            double acc[MODAL_LANES], s[MODAL_LANES / 2];
            for (l = 0; l < MODAL_LANES; ++l)
                acc[l] = 0.0;
            for (c = 0; c < m; c += MODAL_LANES) {
                const double *row = ec + c * 2 * MODAL_BLOCK + k * 2 * MODAL_LANES;
                for (l = 0; l < MODAL_LANES; ++l)
                    acc[l] += row[l] * wo[c + l];
                if (im_out)
                    for (l = 0; l < MODAL_LANES; ++l)
                        acc[l] += row[MODAL_LANES + l] * wo[m + c + l];
            }
            for (l = 0; l < MODAL_LANES / 2; ++l) /* pairwise: halves added until one is left */
                s[l] = acc[l] + acc[MODAL_LANES / 2 + l];
            for (h = MODAL_LANES / 4; h >= 1; h /= 2)
                for (l = 0; l < h; ++l)
                    s[l] = s[l] + s[h + l];
            y[k * n_out + o] = s[0];
        }
}

/* y[k][:] += e * w[p][:] over the state parts p in order, four at a time (w: 2m x n_out) */
static void MODAL_FN(outputs_axpy)(long nb, long m, long n_out, int im_out,
                                   const double *restrict w, const double *restrict ec,
                                   double *restrict y)
{
    const long parts = im_out ? 2 : 1;
    long k, o, c, h, l;
    for (k = 0; k < nb; ++k) {
        double *restrict yk = y + k * n_out;
        for (o = 0; o < n_out; ++o)
            yk[o] = 0.0;
        for (c = 0; c < m; c += MODAL_LANES)
            for (h = 0; h < parts; ++h) {
                const double *row = ec + c * 2 * MODAL_BLOCK + k * 2 * MODAL_LANES
                                    + h * MODAL_LANES;
                const double *wc = w + (h * m + c) * n_out;
                for (l = 0; l < MODAL_LANES; l += 4) {
                    const double e0 = row[l], e1 = row[l + 1], e2 = row[l + 2];
                    const double e3 = row[l + 3];
                    const double *w0 = wc + l * n_out, *w1 = w0 + n_out, *w2 = w1 + n_out;
                    const double *w3 = w2 + n_out;
                    for (o = 0; o < n_out; ++o)
                        yk[o] = yk[o] + e0 * w0[o] + e1 * w1[o] + e2 * w2[o] + e3 * w3[o];
                }
            }
    }
}

/* dtdyn_modal_filters with chunks of MODAL_LANES states */
static void MODAL_FN(run)(long n, long m, long n_in, long n_out, int im_out,
                          const double *restrict coef, const double *restrict wt,
                          const double *restrict x, double *restrict e, double *restrict y,
                          double *restrict ec, const double *restrict w, int axpy)
{
    long b;
    for (b = 0; b < n; b += MODAL_BLOCK) {
        const long nb = (n - b < MODAL_BLOCK) ? n - b : MODAL_BLOCK;
        if (dtdyn_stop_flag)
            return;
        if (n_in == 1) /* the common case, with the input loop unrolled */
            MODAL_FN(states_block)(nb, m, 1, coef, x + b, e, ec);
        else
            MODAL_FN(states_block)(nb, m, n_in, coef, x + b * n_in, e, ec);
        if (axpy)
            MODAL_FN(outputs_axpy)(nb, m, n_out, im_out, w, ec, y + b * n_out);
        else
            MODAL_FN(outputs_dot)(nb, m, n_out, im_out, wt, ec, y + b * n_out);
    }
}

#undef MODAL_FN
#undef MODAL_PASTE
#undef MODAL_PASTE_
#undef MODAL_LANES
