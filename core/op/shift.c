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
    fftw_complex *m2;      /* n (n/2 + 1): the unit factor n m_x(k_x) · n m_y(k_y) on the half spectrum [k_y][k_x] (the
                            * integrator's); NULL with mx */
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
        fftw_free(y->m2);
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
        if (!(y->m2 = fftw_alloc_complex((size_t)n * (h + 1)))) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "shift: out of memory for layer %d's factors", l + 1);
            goto fail;
        }
        for (int ky = 0; ky < n; ky++)
            for (int kx = 0; kx <= h; kx++) {
                const double ar = n * y->mx[kx][0], ai = n * y->mx[kx][1], br = n * y->my[ky][0], bi = n * y->my[ky][1];
                fftw_complex *f = y->m2 + (size_t)ky * (h + 1) + kx;
                (*f)[0] = ar * br - ai * bi, (*f)[1] = ar * bi + ai * br;
            }
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
    /* (a team only for ~2¹³ moving points or more, as the integrator's: the same bits either way) */
    size_t pts = 0;
    for (int l = 0; l < s->L; l++) pts += s->lay[l].mx ? (size_t)s->lay[l].n * s->lay[l].n : 0;
    const int moving = wt_shift_nmoving(s), team = s->nthreads > 1 && moving > 1 && pts >= 8192;
#pragma omp parallel for schedule(dynamic, 1) num_threads(s->nthreads) if (team && !omp_in_parallel())
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

/* ---- the integrator with its state as the layers' spectra (shift.h) ----
 * Per layer (n × n, h = n/2) the half spectrum X[k_y][k_x], k_x = 0..h (row stride h + 1), of a real field u:
 *   forward: rows r and r + h as one complex row R = u_r + i u_{r+h}, DFT_x; the two rows' spectra from its Hermitian
 *            parts, X_r(k) = (R(k) + R*(n−k))/2, X_{r+h}(k) = (R(k) − R*(n−k))/(2i), k ≤ h; then DFT_y down the h + 1
 *            columns;
 *   inverse: IDFT_y down the columns; R(k) = X_r(k) + i X_{r+h}(k) for k ≤ h, X_r*(n−k) + i X_{r+h}*(n−k) above
 *            (each row's spectrum is Hermitian); IDFT_x; u_r = Re R / n², u_{r+h} = Im R / n² (the 1/n² folded into the
 *            spectrum before the inverse).
 * The ramps are wt_shift_alloc's, 1/n each folded in: n m_x(k_x) · n m_y(k_y) is the unit-modulus factor (real at
 * Nyquist, where a real field's two frequencies ±n/2 are one). Ring slot t mod (d + 1) holds Ẑ_t. */
/* Each layer's work is cut into PARTS parts (row pairs, then columns) whatever the thread count, so that a
 * large layer is shared by the threads and the arithmetic (each part's batched transforms) is the same on any of them. */
#define PARTS 2

typedef struct {
    int n;
    int64_t offset;
    fftw_complex *F;  /* n (h + 1): Φ̂, then the new state over n² for the inverse */
    fftw_complex *R;  /* h n: the x pass's row pairs */
    int r0[PARTS + 1], c0[PARTS + 1]; /* the parts' row pairs and columns */
    fftw_plan xf[PARTS], xb[PARTS], yf[PARTS], yb[PARTS];
} ilayer;

struct wt_shift_integrator {
    wt_context *ctx;
    int L, D, nthreads;
    long t;
    ilayer *lay;
    int *order;
    fftw_complex **ring; /* [D + 1][Σ_l n_l (h_l + 1)] the states' spectra, layer l from its ring offset */
    size_t *roff;        /* [L] layer l's offset in each slot */
    size_t nspec;
};

void wt_shift_integrator_free(wt_shift_integrator *it)
{
    if (!it) return;
    for (int l = 0; l < it->L && it->lay; l++) {
        ilayer *y = &it->lay[l];
        for (int p = 0; p < PARTS; p++) {
            if (y->xf[p]) fftw_destroy_plan(y->xf[p]);
            if (y->xb[p]) fftw_destroy_plan(y->xb[p]);
            if (y->yf[p]) fftw_destroy_plan(y->yf[p]);
            if (y->yb[p]) fftw_destroy_plan(y->yb[p]);
        }
        fftw_free(y->F);
        fftw_free(y->R);
    }
    for (int k = 0; k <= it->D && it->ring; k++) fftw_free(it->ring[k]);
    wt_free(it->ctx, it->ring);
    wt_free(it->ctx, it->roff);
    wt_free(it->ctx, it->lay);
    wt_free(it->ctx, it->order);
    wt_free(it->ctx, it);
}

void wt_shift_integrator_reset(wt_shift_integrator *it)
{
    for (int k = 0; k <= it->D; k++) memset(it->ring[k], 0, it->nspec * sizeof(fftw_complex));
    it->t = 0;
}

int wt_shift_integrator_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, int delay,
                              wt_shift_integrator **out)
{
    int st = WT_OK;
    wt_shift_integrator *it = NULL;
    *out = NULL;
    if (L < 1 || delay < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "shift: an integrator of %d layers and delay %d", L, delay);
    for (int l = 0; l < L; l++)
        if (g[l]->ny != g[l]->nx || g[l]->nx < 2 * PARTS || g[l]->nx % 2)
            return WT_ERROR(ctx, WT_ERR_INVALID, "shift: integrator layer %d grid %d x %d; need square, even and at least "
                            "%d", l + 1, g[l]->nx, g[l]->ny, 2 * PARTS);
    WT_ALLOC(ctx, it, 1, "layers' integrator");
    it->ctx = ctx;
    it->L = L, it->D = delay;
    it->nthreads = wt_context_threads(ctx) > 1 ? wt_context_threads(ctx) : 1;
    WT_ALLOC(ctx, it->lay, L, "layers' integrator");
    WT_ALLOC(ctx, it->order, L, "layers' integrator");
    WT_ALLOC(ctx, it->roff, L, "layers' integrator");
    for (int l = 0; l < L; l++) {
        const int n = g[l]->nx;
        it->roff[l] = it->nspec;
        it->nspec += (size_t)n * (n / 2 + 1);
        int k = l;
        while (k > 0 && it->lay[it->order[k - 1]].n < n) it->order[k] = it->order[k - 1], k--;
        it->order[k] = l;
        it->lay[l].n = n;
    }
    WT_ALLOC(ctx, it->ring, delay + 1, "layers' integrator");
    for (int k = 0; k <= delay; k++)
        if (!(it->ring[k] = fftw_alloc_complex(it->nspec))) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "shift: out of memory for the integrator's %zu spectral values", it->nspec);
            goto fail;
        }
    for (int l = 0; l < L; l++) {
        ilayer *y = &it->lay[l];
        const int n = y->n, h = n / 2, zs = h + 1, len[1] = {n};
        y->offset = offset[l];
        y->F = fftw_alloc_complex((size_t)n * zs);
        y->R = fftw_alloc_complex((size_t)h * n);
        if (!y->F || !y->R) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "shift: out of memory for the integrator's layer %d (%d x %d)", l + 1, n, n);
            goto fail;
        }
        for (int p = 0; p <= PARTS; p++) y->r0[p] = h * p / PARTS, y->c0[p] = zs * p / PARTS;
        for (int p = 0; p < PARTS; p++) {
            fftw_complex *R = y->R + (size_t)y->r0[p] * n, *F = y->F + y->c0[p];
            const int nr = y->r0[p + 1] - y->r0[p], nc = y->c0[p + 1] - y->c0[p];
            y->xf[p] = fftw_plan_many_dft(1, len, nr, R, NULL, 1, n, R, NULL, 1, n, FFTW_FORWARD, FFTW_ESTIMATE);
            y->xb[p] = fftw_plan_many_dft(1, len, nr, R, NULL, 1, n, R, NULL, 1, n, FFTW_BACKWARD, FFTW_ESTIMATE);
            y->yf[p] = fftw_plan_many_dft(1, len, nc, F, NULL, zs, 1, F, NULL, zs, 1, FFTW_FORWARD, FFTW_ESTIMATE);
            y->yb[p] = fftw_plan_many_dft(1, len, nc, F, NULL, zs, 1, F, NULL, zs, 1, FFTW_BACKWARD, FFTW_ESTIMATE);
            if (!y->xf[p] || !y->xb[p] || !y->yf[p] || !y->yb[p]) {
                st = WT_ERROR(ctx, WT_ERR_LIBRARY, "shift: FFTW plans of the integrator's layer %d (%d x %d) failed", l + 1,
                              n, n);
                goto fail;
            }
        }
    }
    wt_shift_integrator_reset(it);
    *out = it;
    return WT_OK;
fail:
    wt_shift_integrator_free(it);
    return st;
}

/* part p of the forward x pass: u's row pairs of the part → rows of y->F (their x spectra) */
static void spectrum_x(ilayer *y, int p, const double *u)
{
    const int n = y->n, h = n / 2, zs = h + 1;
    for (int r = y->r0[p]; r < y->r0[p + 1]; r++) {
        const double *a = u + (size_t)r * n, *b = u + (size_t)(r + h) * n;
        fftw_complex *z = y->R + (size_t)r * n;
        for (int x = 0; x < n; x++) z[x][0] = a[x], z[x][1] = b[x];
    }
    fftw_execute(y->xf[p]);
    for (int r = y->r0[p]; r < y->r0[p + 1]; r++) {
        const fftw_complex *z = y->R + (size_t)r * n;
        fftw_complex *xa = y->F + (size_t)r * zs, *xb = y->F + (size_t)(r + h) * zs;
        for (int k = 0; k <= h; k++) {
            const int m = k ? n - k : 0;
            const double pr = z[k][0], pi = z[k][1], qr = z[m][0], qi = -z[m][1]; /* R(k), R*(n − k) */
            xa[k][0] = 0.5 * (pr + qr), xa[k][1] = 0.5 * (pi + qi);
            xb[k][0] = 0.5 * (pi - qi), xb[k][1] = -0.5 * (pr - qr);
        }
    }
}

/* part p of the inverse x pass: rows of y->F (x spectra, 1/n² folded in) → u's row pairs of the part */
static void field_x(ilayer *y, int p, double *u)
{
    const int n = y->n, h = n / 2, zs = h + 1;
    for (int r = y->r0[p]; r < y->r0[p + 1]; r++) {
        const fftw_complex *xa = y->F + (size_t)r * zs, *xb = y->F + (size_t)(r + h) * zs;
        fftw_complex *z = y->R + (size_t)r * n;
        for (int k = 0; k <= h; k++) z[k][0] = xa[k][0] - xb[k][1], z[k][1] = xa[k][1] + xb[k][0];
        for (int k = h + 1; k < n; k++) {
            const int m = n - k;
            z[k][0] = xa[m][0] + xb[m][1], z[k][1] = -xa[m][1] + xb[m][0];
        }
    }
    fftw_execute(y->xb[p]);
    for (int r = y->r0[p]; r < y->r0[p + 1]; r++) {
        const fftw_complex *z = y->R + (size_t)r * n;
        double *a = u + (size_t)r * n, *b = u + (size_t)(r + h) * n;
        for (int x = 0; x < n; x++) a[x] = z[x][0], b[x] = z[x][1];
    }
}

/* part p of the columns: y->F's x spectra → Φ̂ (DFT_y), the update Ẑ_{t+d} = m_1 Ẑ_{t+d−1} + g m_d (Φ̂ − Ẑ_t) into zq
 * (m the shifts' unit factors, 1 for a layer that does not move), Ẑ_{t+d}/n² back to x spectra (IDFT_y) */
static void update_columns(ilayer *y, int p, const layer *s1, const layer *sd, double g, const fftw_complex *zt,
                           const fftw_complex *zp, fftw_complex *zq)
{
    const int n = y->n, zs = n / 2 + 1, c0 = y->c0[p], c1 = y->c0[p + 1];
    const double inv = 1.0 / ((double)n * n);
    static const fftw_complex one = {1.0, 0.0};
    fftw_execute(y->yf[p]);
    for (int ky = 0; ky < n; ky++)
        for (int kx = c0; kx < c1; kx++) {
            const size_t q = (size_t)ky * zs + kx;
            const double *f = s1->m2 ? s1->m2[q] : one, *d = sd->m2 ? sd->m2[q] : one;
            const double er = y->F[q][0] - zt[q][0], ei = y->F[q][1] - zt[q][1];
            const double vr = f[0] * zp[q][0] - f[1] * zp[q][1] + g * (d[0] * er - d[1] * ei);
            const double vi = f[0] * zp[q][1] + f[1] * zp[q][0] + g * (d[0] * ei + d[1] * er);
            zq[q][0] = vr, zq[q][1] = vi;
            y->F[q][0] = vr * inv, y->F[q][1] = vi * inv;
        }
    fftw_execute(y->yb[p]);
}

int wt_shift_integrator_step(wt_shift_integrator *it, const wt_shift *lead, const wt_shift *one, double g,
                             const double *phi, double *zn)
{
    if (lead->L != it->L || one->L != it->L)
        return WT_ERROR(it->ctx, WT_ERR_INVALID, "shift: shifts of %d and %d layers for an integrator of %d", lead->L,
                        one->L, it->L);
    for (int l = 0; l < it->L; l++)
        if (lead->lay[l].n != it->lay[l].n || one->lay[l].n != it->lay[l].n || lead->lay[l].offset != it->lay[l].offset ||
            one->lay[l].offset != it->lay[l].offset)
            return WT_ERROR(it->ctx, WT_ERR_INVALID, "shift: layer %d of the shifts is not the integrator's", l + 1);
    /* a team for layers of at least ~2¹³ points in all (E-ELT's PCG-3: 2.5·10⁴): below that, waking it costs more than
     * the work (the demo's 3 × 32² points); the bits are the same either way */
    size_t pts = 0;
    for (int l = 0; l < it->L; l++) pts += (size_t)it->lay[l].n * it->lay[l].n;
    const int D1 = it->D + 1, L = it->L, nt = pts >= 8192 ? it->nthreads : 1, T = PARTS * L;
    const fftw_complex *St = it->ring[it->t % D1], *Sp = it->ring[(it->t + it->D - 1) % D1];
    fftw_complex *Sn = it->ring[(it->t + it->D) % D1];
    /* three passes, each over every layer's parts (the largest layers first): rows, columns, rows */
#pragma omp parallel num_threads(nt) if (nt > 1 && !omp_in_parallel())
    {
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < T; i++) {
            ilayer *y = &it->lay[it->order[i / PARTS]];
            spectrum_x(y, i % PARTS, phi + y->offset);
        }
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < T; i++) {
            const int l = it->order[i / PARTS];
            update_columns(&it->lay[l], i % PARTS, &one->lay[l], &lead->lay[l], g, St + it->roff[l], Sp + it->roff[l],
                           Sn + it->roff[l]);
        }
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < T; i++) {
            ilayer *y = &it->lay[it->order[i / PARTS]];
            field_x(y, i % PARTS, zn + y->offset);
        }
    }
    it->t++;
    return WT_OK;
}

int wt_shift_layer_moves(const wt_shift *s, int l) { return l >= 0 && l < s->L && s->lay[l].mx != NULL; }

int wt_shift_nmoving(const wt_shift *s)
{
    int m = 0;
    for (int l = 0; l < s->L; l++) m += s->lay[l].mx != NULL;
    return m;
}
