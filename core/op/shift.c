/* core/op/shift.c: layers moved by a Fourier phase ramp (shift.h). */
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
    fftw_complex *ramp; /* n × (n/2 + 1): e^{−2πi k·s/(nδ)} / n² (the c2r's scale folded in) */
    fftw_plan r2c, c2r;
} layer;

struct wt_shift {
    wt_context *ctx;
    int L, nthreads;
    layer *lay;
    double *work;       /* per thread: the largest n² */
    fftw_complex *spec; /* per thread: the largest n (n/2 + 1) */
    size_t nwork, nspec;
};

void wt_shift_free(wt_shift *s)
{
    if (!s) return;
    for (int l = 0; l < s->L && s->lay; l++) {
        if (s->lay[l].r2c) fftw_destroy_plan(s->lay[l].r2c);
        if (s->lay[l].c2r) fftw_destroy_plan(s->lay[l].c2r);
        fftw_free(s->lay[l].ramp);
    }
    wt_free(s->ctx, s->lay);
    fftw_free(s->work);
    fftw_free(s->spec);
    wt_free(s->ctx, s);
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
    /* the layers run on the context's threads, one layer each: a work pair per thread (the plans are
     * executed on any thread's arrays with FFTW's new-array functions; fftw_alloc aligns them alike) */
    s->nthreads = wt_context_threads(ctx) > 1 ? wt_context_threads(ctx) : 1;
    s->nwork = (size_t)nmax * nmax, s->nspec = (size_t)nmax * (nmax / 2 + 1);
    s->work = fftw_alloc_real(s->nwork * s->nthreads);
    s->spec = fftw_alloc_complex(s->nspec * s->nthreads);
    if (!s->work || !s->spec) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "shift: out of memory for the %d x %d work arrays", nmax, nmax);
        goto fail;
    }
    for (int l = 0; l < L; l++) {
        layer *y = &s->lay[l];
        const int n = g[l]->nx, nh = n / 2 + 1;
        y->n = n;
        y->offset = offset[l];
        if (sx[l] == 0.0 && sy[l] == 0.0) continue;
        y->ramp = fftw_alloc_complex((size_t)n * nh);
        y->r2c = fftw_plan_dft_r2c_2d(n, n, s->work, s->spec, FFTW_ESTIMATE);
        y->c2r = fftw_plan_dft_c2r_2d(n, n, s->spec, s->work, FFTW_ESTIMATE);
        if (!y->ramp || !y->r2c || !y->c2r) {
            st = WT_ERROR(ctx, WT_ERR_LIBRARY, "shift: FFTW plans or ramp for layer %d (%d x %d) failed", l + 1, n, n);
            goto fail;
        }
        /* row-major n × n: the r2c's last (contiguous) index is x, the first y; frequencies k ∈ (−n/2, n/2] */
        const double ax = 2.0 * M_PI * sx[l] / (n * g[l]->dx), ay = 2.0 * M_PI * sy[l] / (n * g[l]->dx);
        for (int iy = 0; iy < n; iy++) {
            const int ky = iy <= n / 2 ? iy : iy - n;
            /* along an axis at its Nyquist frequency the ramp is its real part (the mean of ±n/2, which a
             * real field's spectrum cannot tell apart) */
            const double fyr = cos(ay * ky), fyi = iy == n / 2 ? 0.0 : -sin(ay * ky);
            for (int ix = 0; ix < nh; ix++) {
                const double fxr = cos(ax * ix), fxi = ix == n / 2 ? 0.0 : -sin(ax * ix);
                y->ramp[(size_t)iy * nh + ix][0] = (fxr * fyr - fxi * fyi) / ((double)n * n);
                y->ramp[(size_t)iy * nh + ix][1] = (fxr * fyi + fxi * fyr) / ((double)n * n);
            }
        }
    }
    *out = s;
    return WT_OK;
fail:
    wt_shift_free(s);
    return st;
}

void wt_shift_apply(wt_shift *s, double *phi)
{
    const int moving = wt_shift_nmoving(s);
#pragma omp parallel for schedule(dynamic, 1) num_threads(s->nthreads) if (s->nthreads > 1 && moving > 1 && !omp_in_parallel())
    for (int l = 0; l < s->L; l++) {
        const layer *y = &s->lay[l];
        if (!y->ramp) continue;
        const int t = wt_thread_id();
        double *w = s->work + s->nwork * t;
        fftw_complex *sp = s->spec + s->nspec * t;
        const size_t n2 = (size_t)y->n * y->n, nc = (size_t)y->n * (y->n / 2 + 1);
        double *p = phi + y->offset;
        memcpy(w, p, n2 * sizeof *p);
        fftw_execute_dft_r2c(y->r2c, w, sp);
        for (size_t q = 0; q < nc; q++) {
            const double a = sp[q][0], b = sp[q][1], c = y->ramp[q][0], d = y->ramp[q][1];
            sp[q][0] = a * c - b * d;
            sp[q][1] = a * d + b * c;
        }
        fftw_execute_dft_c2r(y->c2r, sp, w);
        memcpy(p, w, n2 * sizeof *p);
    }
}

int wt_shift_nmoving(const wt_shift *s)
{
    int m = 0;
    for (int l = 0; l < s->L; l++) m += s->lay[l].ramp != NULL;
    return m;
}
