/* core/op/shift.c: layers moved by a Fourier phase ramp (shift.h).
 *
 * The shift is separable, S = S_y S_x, each factor a 1-D ramp along its axis (the 2-D ramp of shift.h is their
 * product, Nyquist rows and columns included). Each factor is a real operator (its ramp is Hermitian:
 * conj m(k) = m(−k), real at Nyquist), so it maps a + i b to S a + i S b: two real rows (or columns) go through
 * one complex transform of length n. Complex 1-D transforms are what FFTW's codelets do well without
 * measured plans (FFTW_ESTIMATE picks slow real-to-complex algorithms at n = 128, where a measured plan is ~1.5x
 * faster; its complex ones are within a few % of measured), so the shift needs no wisdom and no planning
 * time, and its bits do not depend on a measurement.
 *
 * Per layer (n × n, h = n/2), on one thread, with two scratch arrays of that thread:
 *   x pass: R[r] = row r + i row r+h (r < h); R ← IDFT_x(m_x · DFT_x(R)); its real and imaginary parts, the rows
 *           shifted along x, are stored as the y pass wants them: Z[y][c] = u[y][c] + i u[y][c+h] (c < h);
 *   y pass: Z ← IDFT_y(m_y · DFT_y(Z)) down the columns; out[y][c] = Re Z[y][c], out[y][c+h] = Im Z[y][c].
 * Z's rows are h + 1 complex long: at a power-of-two stride the column transforms' accesses fall in a few cache
 * sets. The layers run on the context's threads, one layer each, the largest first; a layer's arithmetic is the
 * same on any thread, so its bits do not depend on the thread count. */
#include "shift.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#else
static int omp_in_parallel(void) { return 0; }
#endif

typedef struct {
    int n;
    int64_t offset;
    fftw_complex *mx, *my; /* n each: the x and y ramps over k = 0..n−1 (k > n/2 is k − n), 1/n folded in; NULL:
                            * the layer does not move */
    fftw_plan rf, rb;      /* x pass: h transforms of length n, contiguous rows of R, in place */
    fftw_plan cf, cb;      /* y pass: h transforms of length n down the columns of Z (stride h + 1), in place */
} layer;

struct wt_shift {
    wt_context *ctx;
    int L, nthreads;
    layer *lay;
    int *order;        /* the layers, largest first (the schedule hands them out in this order) */
    fftw_complex *rbuf; /* per thread: R, the largest h × n */
    fftw_complex *zbuf; /* per thread: Z, the largest n × (h + 1) */
    size_t nr, nz;
};

void wt_shift_free(wt_shift *s)
{
    if (!s) return;
    for (int l = 0; l < s->L && s->lay; l++) {
        layer *y = &s->lay[l];
        if (y->rf) fftw_destroy_plan(y->rf);
        if (y->rb) fftw_destroy_plan(y->rb);
        if (y->cf) fftw_destroy_plan(y->cf);
        if (y->cb) fftw_destroy_plan(y->cb);
        fftw_free(y->mx);
        fftw_free(y->my);
    }
    wt_free(s->ctx, s->lay);
    wt_free(s->ctx, s->order);
    fftw_free(s->rbuf);
    fftw_free(s->zbuf);
    wt_free(s->ctx, s);
}

/* e^{−i a k} / n over the DFT's k = 0..n−1 (frequency k − n above n/2); at Nyquist its real part (the mean of
 * ±n/2, which a real field's spectrum cannot tell apart) */
static void ramp(int n, double a, fftw_complex *m)
{
    for (int k = 0; k < n; k++) {
        const int f = k <= n / 2 ? k : k - n;
        m[k][0] = cos(a * f) / n;
        m[k][1] = k == n / 2 ? 0.0 : -sin(a * f) / n;
    }
}

int wt_shift_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, const double *sx,
                   const double *sy, wt_shift **out)
{
    int st = WT_OK;
    wt_shift *s = NULL;
    *out = NULL;
    int nmax = 0;
    for (int l = 0; l < L; l++) {
        const int n = g[l]->nx;
        if (g[l]->ny != n || n < 2 || n % 2)
            return WT_ERROR(ctx, WT_ERR_INVALID, "shift: layer %d grid %d x %d; need square and even", l + 1, g[l]->nx,
                            g[l]->ny);
        if (!isfinite(sx[l]) || !isfinite(sy[l]) || hypot(sx[l], sy[l]) > 0.25 * n * g[l]->dx)
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "shift: layer %d moves by (%g, %g) m over the lead time, more than a quarter of its %g m grid "
                            "(or not finite): its content would wrap round (recon.predict, the model's wind, loop.rate_hz)",
                            l + 1, sx[l], sy[l], n * g[l]->dx);
        if (n > nmax) nmax = n;
    }
    WT_ALLOC(ctx, s, 1, "shift");
    s->ctx = ctx;
    s->L = L;
    WT_ALLOC(ctx, s->lay, L, "shift layers");
    WT_ALLOC(ctx, s->order, L, "shift layer order");
    /* the plans are executed on any thread's scratch with FFTW's new-array functions: fftw_alloc aligns every
     * thread's part alike (whole complex numbers apart) */
    s->nthreads = wt_context_threads(ctx) > 1 ? wt_context_threads(ctx) : 1;
    s->nr = (size_t)(nmax / 2) * nmax, s->nz = (size_t)nmax * (nmax / 2 + 1);
    s->rbuf = fftw_alloc_complex(s->nr * s->nthreads);
    s->zbuf = fftw_alloc_complex(s->nz * s->nthreads);
    if (!s->rbuf || !s->zbuf) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "shift: out of memory for the %d x %d work arrays", nmax, nmax);
        goto fail;
    }
    for (int l = 0; l < L; l++) {
        layer *y = &s->lay[l];
        const int n = g[l]->nx, h = n / 2;
        y->n = n;
        y->offset = offset[l];
        /* largest first, ties in layer order (an insertion into the sorted prefix) */
        int k = l;
        while (k > 0 && s->lay[s->order[k - 1]].n < n) s->order[k] = s->order[k - 1], k--;
        s->order[k] = l;
        if (sx[l] == 0.0 && sy[l] == 0.0) continue;
        y->mx = fftw_alloc_complex(n);
        y->my = fftw_alloc_complex(n);
        const int len[1] = {n};
        y->rf = fftw_plan_many_dft(1, len, h, s->rbuf, NULL, 1, n, s->rbuf, NULL, 1, n, FFTW_FORWARD, FFTW_ESTIMATE);
        y->rb = fftw_plan_many_dft(1, len, h, s->rbuf, NULL, 1, n, s->rbuf, NULL, 1, n, FFTW_BACKWARD, FFTW_ESTIMATE);
        y->cf = fftw_plan_many_dft(1, len, h, s->zbuf, NULL, h + 1, 1, s->zbuf, NULL, h + 1, 1, FFTW_FORWARD,
                                   FFTW_ESTIMATE);
        y->cb = fftw_plan_many_dft(1, len, h, s->zbuf, NULL, h + 1, 1, s->zbuf, NULL, h + 1, 1, FFTW_BACKWARD,
                                   FFTW_ESTIMATE);
        if (!y->mx || !y->my || !y->rf || !y->rb || !y->cf || !y->cb) {
            st = WT_ERROR(ctx, WT_ERR_LIBRARY, "shift: FFTW plans or ramps for layer %d (%d x %d) failed", l + 1, n, n);
            goto fail;
        }
        /* row-major n × n: x is the contiguous index */
        ramp(n, 2.0 * M_PI * sx[l] / (n * g[l]->dx), y->mx);
        ramp(n, 2.0 * M_PI * sy[l] / (n * g[l]->dx), y->my);
    }
    *out = s;
    return WT_OK;
fail:
    wt_shift_free(s);
    return st;
}

static inline void cmul(fftw_complex z, const fftw_complex m)
{
    const double a = z[0], b = z[1];
    z[0] = a * m[0] - b * m[1];
    z[1] = a * m[1] + b * m[0];
}

/* One moving layer, in → out (the same array or apart), with one thread's scratch R and Z */
static void shift_layer(const layer *y, const double *in, double *out, fftw_complex *R, fftw_complex *Z)
{
    const int n = y->n, h = n / 2, zs = h + 1;
    for (int r = 0; r < h; r++) {
        const double *a = in + (size_t)r * n, *b = in + (size_t)(r + h) * n;
        fftw_complex *z = R + (size_t)r * n;
        for (int x = 0; x < n; x++) z[x][0] = a[x], z[x][1] = b[x];
    }
    fftw_execute_dft(y->rf, R, R);
    for (int r = 0; r < h; r++) {
        fftw_complex *z = R + (size_t)r * n;
        for (int k = 0; k < n; k++) cmul(z[k], y->mx[k]);
    }
    fftw_execute_dft(y->rb, R, R);
    for (int r = 0; r < h; r++) {
        const fftw_complex *w = R + (size_t)r * n;
        fftw_complex *za = Z + (size_t)r * zs, *zb = Z + (size_t)(r + h) * zs;
        for (int c = 0; c < h; c++) {
            za[c][0] = w[c][0], za[c][1] = w[c + h][0];
            zb[c][0] = w[c][1], zb[c][1] = w[c + h][1];
        }
    }
    fftw_execute_dft(y->cf, Z, Z);
    for (int k = 0; k < n; k++) {
        fftw_complex *z = Z + (size_t)k * zs;
        for (int c = 0; c < h; c++) cmul(z[c], y->my[k]);
    }
    fftw_execute_dft(y->cb, Z, Z);
    for (int r = 0; r < n; r++) {
        const fftw_complex *z = Z + (size_t)r * zs;
        double *o = out + (size_t)r * n;
        for (int c = 0; c < h; c++) o[c] = z[c][0], o[c + h] = z[c][1];
    }
}

void wt_shift_apply_to(wt_shift *s, const double *in, double *out)
{
    const int moving = wt_shift_nmoving(s);
#pragma omp parallel for schedule(dynamic, 1) num_threads(s->nthreads) if (s->nthreads > 1 && moving > 1 && !omp_in_parallel())
    for (int i = 0; i < s->L; i++) {
        const layer *y = &s->lay[s->order[i]];
        const double *p = in + y->offset;
        double *q = out + y->offset;
        if (!y->mx) {
            if (q != p) memcpy(q, p, (size_t)y->n * y->n * sizeof *q);
            continue;
        }
        const int t = wt_thread_id();
        shift_layer(y, p, q, s->rbuf + s->nr * t, s->zbuf + s->nz * t);
    }
}

void wt_shift_apply(wt_shift *s, double *phi) { wt_shift_apply_to(s, phi, phi); }

/* The two shifts as one schedule of 2L layer tasks (each shift's own per-thread scratch, so two tasks of the two
 * objects on one thread never share it): with PCG-3's 3 layers on 2 threads, 3 layer-times instead of 2 + 2. Each
 * layer's arithmetic is wt_shift_apply_to's, so the bits are those of the two calls in sequence. */
void wt_shift_integrate(wt_shift *lead, wt_shift *one, double g, const double *phi, const double *zt, const double *zp,
                        double *zn, double *e, int64_t n)
{
    for (int64_t k = 0; k < n; k++) e[k] = phi[k] - zt[k];
    const int L = lead->L, nt = lead->nthreads < one->nthreads ? lead->nthreads : one->nthreads;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1 && !omp_in_parallel())
    for (int i = 0; i < 2 * L; i++) {
        wt_shift *s = i % 2 ? one : lead; /* the largest layers first, of both */
        const layer *y = &s->lay[s->order[i / 2]];
        const double *p = (i % 2 ? zp : e) + y->offset;
        double *q = (i % 2 ? zn : e) + y->offset;
        if (!y->mx) {
            if (q != p) memcpy(q, p, (size_t)y->n * y->n * sizeof *q);
            continue;
        }
        const int t = wt_thread_id();
        shift_layer(y, p, q, s->rbuf + s->nr * t, s->zbuf + s->nz * t);
    }
    for (int64_t k = 0; k < n; k++) zn[k] += g * e[k];
}

int wt_shift_nmoving(const wt_shift *s)
{
    int m = 0;
    for (int l = 0; l < s->L; l++) m += s->lay[l].mx != NULL;
    return m;
}
