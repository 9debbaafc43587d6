/* core/model/sensing_reference.c: the diffractive sensor when the sodium layer changes (sensing.h, SPEC §12 "The
 * sodium layer changes too"): the truth's spot tables of a new profile, a reference rebuilt in the loop (the
 * oracle's from the spot model, the one of the loop's own pixels, any other from given images), and the way back to
 * the set-up's state. The pixels' reference: with M = Σ_f J_f / n, J_f frame f's image shifted by −s_f / p (s_f the
 * set-up filter's slopes of it; shift.h: cubic B-spline, accumulated as T_u I_f and interpolated once), Δ = M − I0_s
 * (I0_s the set-up image) and σ² = (max(M, 0) + B + σe²)/n per pixel, I0 = max(I0_s + Δ (1 − k²σ²/Δ²)₊, 0), and
 * ∂I0/∂θ = S(I0)/p + ∂I0_s/∂θ − S(I0_s)/p (sensing.h). */
#include "sensing.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../optics/image_shift.h"
#include "../optics/sodium.h"
#include "../optics/spot.h"

#ifdef _OPENMP
#include <omp.h>
#else
#define omp_in_parallel() 1
#endif

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int wt_sensing__nea_stats(int nsub, const double *cov, double *nea, double *median, double *mean_var)
{
    double mv = 0.0;
    for (int k = 0; k < nsub; k++) {
        const double a = cov[k], b = cov[nsub + k], c = cov[2 * nsub + k];
        if (!(isfinite(a) && isfinite(b) && isfinite(c) && a > 0.0 && c > 0.0 && a * c - b * b > 0.0)) return k;
        nea[k] = sqrt(0.5 * (a + c));
        mv += 0.5 * (a + c) / nsub;
    }
    qsort(nea, (size_t)nsub, sizeof *nea, cmp_double);
    *median = nsub % 2 ? nea[nsub / 2] : 0.5 * (nea[nsub / 2 - 1] + nea[nsub / 2]);
    *mean_var = mv;
    return -1;
}

void wt_sensing__gain_cov(int nsub, const double *hk, const double *c0, double *c)
{
    for (int k = 0; k < nsub; k++) {
        const double *h = hk + 4 * (size_t)k, a = c0[k], b = c0[nsub + k], d = c0[2 * nsub + k];
        const double u0 = h[0] * a + h[1] * b, u1 = h[0] * b + h[1] * d, v0 = h[2] * a + h[3] * b, v1 = h[2] * b + h[3] * d;
        c[k] = u0 * h[0] + u1 * h[1], c[nsub + k] = u0 * h[2] + u1 * h[3], c[2 * nsub + k] = v0 * h[2] + v1 * h[3];
    }
}

int wt_sensing_set_sodium_staged(wt_sensing *ws, const wt_sodium *na, const double stage[3])
{
    if (!ws->lgs) return WT_ERROR(ws->ctx, WT_ERR_INVALID, "diffractive sensor: a sodium profile for an NGS");
    const int st = wt_spot_set_sodium_staged(ws->spot, na ? na : ws->sodium0, stage);
    if (st < 0) return st;
    ws->sodium_changed = 1;
    return WT_OK;
}

int wt_sensing_set_sodium(wt_sensing *ws, const wt_sodium *na) { return wt_sensing_set_sodium_staged(ws, na, NULL); }

int wt_sensing_set_reference(wt_sensing *ws, const float *i0, const float *dix, const float *diy)
{
    wt_context *ctx = ws->ctx;
    const int nsub = ws->nsub, ns = ws->ns;
    int st = WT_OK;
    wt_centroid *cen = NULL;
    double *cov = NULL, *trunc = NULL, *nea = NULL, *raw = NULL;
    WT_TRY(wt_centroid_alloc(ctx, &ws->cpar, nsub, ns, i0, dix, diy, &cen));
    WT_ALLOC(ctx, cov, 3 * (size_t)nsub, "noise covariance");
    WT_ALLOC(ctx, trunc, nsub, "truncations");
    WT_ALLOC(ctx, nea, nsub, "NEA");
    if (ws->calibration == 1) WT_TRY(wt_centroid_noise_mc(cen, i0, ws->calibration_draws, ws->calibration_seed, cov, NULL));
    else wt_centroid_noise_cov(cen, cov);
    /* a gain correction in force stays (wt_sensing_gain_update), applied to the new filter's covariance */
    if (ws->gain_corr) {
        WT_ALLOC(ctx, raw, 3 * (size_t)nsub, "noise covariance");
        memcpy(raw, cov, 3 * (size_t)nsub * sizeof *cov);
        wt_sensing__gain_cov(nsub, ws->gain_corr, raw, cov);
    }
    double mean_var = 0.0, median = 0.0;
    const int bad = wt_sensing__nea_stats(nsub, cov, nea, &median, &mean_var);
    if (bad >= 0) {
        st = WT_ERROR(ctx, WT_ERR_INVALID,
                      "diffractive sensor: the rebuilt reference gives subaperture %d a centroid noise covariance "
                      "{%g, %g, %g} rad^2 that is not positive definite; the old reference is kept",
                      bad, cov[bad], cov[nsub + bad], cov[2 * nsub + bad]);
        goto fail;
    }
    /* everything computed: the new reference replaces the old one whole */
    wt_spot_truncation(ws->spot, i0, trunc);
    ws->worst_trunc = 0.0, ws->worst_sub = 0;
    for (int k = 0; k < nsub; k++)
        if (trunc[k] > ws->worst_trunc) ws->worst_trunc = trunc[k], ws->worst_sub = k;
    if (i0 != ws->i0) memcpy(ws->i0, i0, (size_t)nsub * ns * ns * sizeof *i0);
    wt_centroid_free(ws->cen);
    ws->cen = cen, cen = NULL;
    wt_free(ctx, ws->cov);
    ws->cov = cov, cov = NULL;
    wt_free(ctx, ws->trunc);
    ws->trunc = trunc, trunc = NULL;
    ws->nea_median = median;
    ws->mean_var = mean_var;
    ws->reference_changed = 1;
    if (raw) memcpy(ws->gain_cov0, raw, 3 * (size_t)nsub * sizeof *raw); /* the new filter's own */
fail:
    wt_free(ctx, raw);
    wt_centroid_free(cen);
    wt_free(ctx, cov);
    wt_free(ctx, trunc);
    wt_free(ctx, nea);
    return st;
}

int wt_sensing_rebuild_reference(wt_sensing *ws)
{
    wt_context *ctx = ws->ctx;
    const size_t npix = (size_t)ws->nsub * ws->ns * ws->ns;
    int st = WT_OK;
    float *i0 = NULL, *dix = NULL, *diy = NULL;
    WT_ALLOC(ctx, i0, npix, "reference images");
    WT_ALLOC(ctx, dix, npix, "reference derivatives");
    WT_ALLOC(ctx, diy, npix, "reference derivatives");
    {
        const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid};
        WT_TRY(wt_spot_reference(ws->spot, 0.0, ws->seeing ? &see : NULL, i0, dix, diy));
    }
    WT_TRY(wt_sensing_set_reference(ws, i0, dix, diy));
fail:
    wt_free(ctx, i0);
    wt_free(ctx, dix);
    wt_free(ctx, diy);
    return st;
}

/* the set-up reference i0 and its derivatives, the spot tables set back to the set-up profile first (a loop's start) */
static int setup_reference(wt_sensing *ws, float *i0, float *dx, float *dy)
{
    const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid};
    int st = ws->sodium_changed ? wt_spot_set_sodium(ws->spot, ws->sodium0) : WT_OK;
    if (st < 0 || (st = wt_spot_reference(ws->spot, 0.0, ws->seeing ? &see : NULL, i0, dx, dy)) < 0) return st;
    ws->sodium_changed = 0;
    return WT_OK;
}

/* dx, dy less the derivatives of i0's spline / p: the anchor of the pixels' derivatives; tmp: threads × (work + Ns²) */
static void unspline(const wt_sensing *ws, const float *i0, float *dx, float *dy, double *tmp)
{
    const int nsub = ws->nsub, ns = ws->ns, nth = wt_context_threads(ws->ctx);
    const size_t n2 = (size_t)ns * ns, wk = (size_t)wt_image_shift_work(ns) + n2;
    const double p = ws->pixel;
#pragma omp parallel for schedule(static, 64) num_threads(nth) if (nth > 1 && nsub > 64 && !omp_in_parallel())
    for (int k = 0; k < nsub; k++) {
        double *w = tmp + wk * (size_t)wt_thread_id();
        float *sx = (float *)(w + (size_t)wt_image_shift_work(ns)), *sy = sx + n2; /* the scratch's last n2 doubles */
        wt_image_shift_derivative(ns, i0 + n2 * k, sx, sy, w);
        for (size_t q = 0; q < n2; q++)
            dx[n2 * k + q] = (float)(dx[n2 * k + q] - sx[q] / p), dy[n2 * k + q] = (float)(dy[n2 * k + q] - sy[q] / p);
    }
}

int wt_sensing_pixels_start(wt_sensing *ws)
{
    wt_context *ctx = ws->ctx;
    const size_t n2 = (size_t)ws->ns * ws->ns;
    const int nth = wt_context_threads(ctx);
    int st = WT_OK;
    wt_sensing_pixels_stop(ws);
    const size_t E2 = (size_t)wt_image_shift_side(ws->ns) * wt_image_shift_side(ws->ns);
    WT_ALLOC(ctx, ws->pix_acc, (size_t)ws->nsub * E2, "pixel reference accumulator");
    WT_ALLOC(ctx, ws->pix_s0, 2 * (size_t)ws->nsub, "pixel reference slopes");
    WT_ALLOC(ctx, ws->pix_tmp, ((size_t)wt_image_shift_work(ws->ns) + n2) * (nth > 0 ? nth : 1), "pixel reference scratch");
    memset(ws->pix_acc, 0, (size_t)ws->nsub * E2 * sizeof *ws->pix_acc);
    ws->pix_frames = 0;
    ws->pix_seconds = 0.0;
    /* the anchor: the set-up reference's derivatives (the spot model's, of the set-up profile) less its spline's */
    {
        const size_t npix = (size_t)ws->nsub * n2;
        float *i0 = NULL;
        WT_ALLOC(ctx, ws->pix_anchor, 3 * npix, "pixel reference anchor");
        WT_ALLOC(ctx, i0, npix, "set-up reference");
        float *dx = ws->pix_anchor, *dy = ws->pix_anchor + npix;
        if ((st = setup_reference(ws, i0, dx, dy)) < 0 ||
            (st = wt_centroid_alloc(ctx, &ws->cpar, ws->nsub, ws->ns, i0, dx, dy, &ws->pix_cen0)) < 0) {
            wt_free(ctx, i0);
            goto fail;
        }
        unspline(ws, i0, dx, dy, ws->pix_tmp);
        memcpy(ws->pix_anchor + 2 * npix, i0, npix * sizeof *i0);
        wt_free(ctx, i0);
    }
    return WT_OK;
fail:
    wt_sensing_pixels_stop(ws);
    return st;
}

void wt_sensing_pixels_stop(wt_sensing *ws)
{
    wt_free(ws->ctx, ws->pix_acc);
    wt_free(ws->ctx, ws->pix_tmp);
    wt_free(ws->ctx, ws->pix_anchor);
    wt_free(ws->ctx, ws->pix_s0);
    wt_centroid_free(ws->pix_cen0);
    ws->pix_acc = NULL, ws->pix_tmp = NULL, ws->pix_anchor = NULL, ws->pix_s0 = NULL, ws->pix_cen0 = NULL;
    ws->pix_frames = 0;
}

void wt_sensing_pixels_add(wt_sensing *ws, const float *images, const double *slopes)
{
    const double t0 = wt_time_now();
    const int nsub = ws->nsub, ns = ws->ns, nth = wt_context_threads(ws->ctx);
    const size_t n2 = (size_t)ns * ns, E2 = (size_t)wt_image_shift_side(ns) * wt_image_shift_side(ns);
    const size_t wk = (size_t)wt_image_shift_work(ns) + n2;
    const double inv_p = 1.0 / ws->pixel;
    /* the spot of slope s sits at +s: moved back by −s / p pixels */
#pragma omp parallel for schedule(static, 64) num_threads(nth) if (nth > 1 && nsub > 64 && !omp_in_parallel())
    for (int k = 0; k < nsub; k++)
        wt_image_shift_accumulate(ns, images + n2 * k, -slopes[k] * inv_p, -slopes[nsub + k] * inv_p, ws->pix_acc + E2 * k,
                            (float *)(ws->pix_tmp + wk * (size_t)wt_thread_id()));
    ws->pix_frames++;
    ws->pix_seconds += wt_time_now() - t0;
}

int wt_sensing_pixels_reference(wt_sensing *ws)
{
    wt_context *ctx = ws->ctx;
    if (!ws->pix_acc) return WT_ERROR(ctx, WT_ERR_INVALID, "diffractive sensor: no pixels accumulated for a reference");
    if (ws->pix_frames < WT_SENSING_PIXELS_MIN_FRAMES)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "diffractive sensor: a reference from the loop's pixels needs at least %d frames, %ld were "
                        "accumulated; the old reference is kept",
                        WT_SENSING_PIXELS_MIN_FRAMES, ws->pix_frames);
    const int nsub = ws->nsub, ns = ws->ns, nth = wt_context_threads(ctx);
    const size_t n2 = (size_t)ns * ns, npix = (size_t)nsub * n2, E2 = (size_t)wt_image_shift_side(ns) * wt_image_shift_side(ns);
    const size_t wk = (size_t)wt_image_shift_work(ns) + n2;
    const double inv_n = 1.0 / (double)ws->pix_frames, inv_p = 1.0 / ws->pixel;
    const double v0 = ws->cpar.background + ws->cpar.read_noise * ws->cpar.read_noise; /* a pixel's variance less I */
    const double k2 = WT_SENSING_PIXELS_SHRINK * WT_SENSING_PIXELS_SHRINK;
    int st = WT_OK;
    float *i0 = NULL, *dix = NULL, *diy = NULL;
    WT_ALLOC(ctx, i0, npix, "reference images");
    WT_ALLOC(ctx, dix, npix, "reference derivatives");
    WT_ALLOC(ctx, diy, npix, "reference derivatives");
#pragma omp parallel for schedule(static, 64) num_threads(nth) if (nth > 1 && nsub > 64 && !omp_in_parallel())
    for (int k = 0; k < nsub; k++) {
        float *a = i0 + n2 * k, *dx = dix + n2 * k, *dy = diy + n2 * k;
        double *w = ws->pix_tmp + wk * (size_t)wt_thread_id();
        /* the mean, ≥ 0, then the derivatives of that */
        wt_image_shift_mean(ns, ws->pix_acc + E2 * k, inv_n, a, w);
        /* the change from the set-up image, shrunk by its noise (positive-part James–Stein per pixel: Δ (1 − k²σ²/Δ²)₊,
         * σ² = (mean + B + σe²)/n the variance of an n-frame mean): a change the noise could have made is taken
         * for none, so the derivatives are not the noise's (an unchanged spot gives the set-up reference back); then
         * ≥ 0 */
        const float *is = ws->pix_anchor + 2 * npix + n2 * k;
        for (size_t q = 0; q < n2; q++) {
            const double d = (double)a[q] - is[q], v = k2 * ((a[q] > 0.0f ? a[q] : 0.0) + v0) * inv_n;
            const double f = d * d > v ? 1.0 - v / (d * d) : 0.0, m = is[q] + f * d;
            a[q] = m > 0.0 ? (float)m : 0.0f;
        }
        wt_image_shift_derivative(ns, a, dx, dy, w);
        const float *ax = ws->pix_anchor + n2 * k, *ay = ws->pix_anchor + npix + n2 * k;
        for (size_t q = 0; q < n2; q++) dx[q] = (float)(dx[q] * inv_p + ax[q]), dy[q] = (float)(dy[q] * inv_p + ay[q]);
    }
    WT_TRY(wt_sensing_set_reference(ws, i0, dix, diy));
    memset(ws->pix_acc, 0, (size_t)nsub * E2 * sizeof *ws->pix_acc);
    ws->pix_frames = 0;
fail:
    wt_free(ctx, i0);
    wt_free(ctx, dix);
    wt_free(ctx, diy);
    return st;
}

int wt_sensing_restore(wt_sensing *ws)
{
    int st = WT_OK;
    wt_sensing_pixels_stop(ws);
    wt_free(ws->ctx, ws->gain_acc); /* (wt_sensing_gain_stop; sensing_gain.c is above this file) */
    ws->gain_acc = NULL, ws->gain_frames = 0;
    /* a correction in force set reference_changed: dropped here, the set-up's filter is rebuilt below */
    wt_free(ws->ctx, ws->gain_corr);
    wt_free(ws->ctx, ws->gain_cov0);
    ws->gain_corr = NULL, ws->gain_cov0 = NULL;
    if (ws->sodium_changed) {
        if ((st = wt_spot_set_sodium(ws->spot, ws->sodium0)) < 0) return st;
        ws->sodium_changed = 0;
    }
    if (ws->reference_changed) {
        if ((st = wt_sensing_rebuild_reference(ws)) < 0) return st;
        ws->reference_changed = 0;
    }
    return WT_OK;
}
