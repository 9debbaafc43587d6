/* core/model/sensing_gain.c: the matched filter's gain measured on the loop's own pixels (sensing.h,
 * lgs.wfs.gain_update_s; docs/design.md "The matched filter's gain from the loop's pixels").
 *
 * The in-loop gain. For frames whose spots are the images I(t_f) of tilts t_f (Gaussian, the noise independent of
 * t), the least-squares slope of the filter's output s_f = R (I(t_f) − I0) on t_f is, by Stein's lemma,
 *   G = E[∂s/∂t] = R ∂M/∂θ,   M = E[I(t)] the frames' mean image as detected (not re-centred),
 * whatever the spots' width and jitter. The derivative of an undersampled mean image is not in its pixels (a spline's
 * of the demo's ~1.2″ spots on 1.1″ pixels catches 0.2–0.4 of a change of width), so M is fitted by the spot model:
 *   M_k ≈ I_k(α, Σ) = the spot of the tables' profile with the seeing of r0 α^(−3/5) (the reference's seeing scaled
 *                     by α in D ∝ r0^(−5/3); α = 1: the reference) convolved with a Gaussian N(0, Σ) (jitter),
 * the tables' profile being the set-up's, or under a sodium sequence the truth's current one, which the oracle's
 * reference is made of (the configuration allows no other reference then),
 * one (α, Σxx, Σxy, Σyy) per sensor (the atmosphere's residual and the loop's jitter are the sensor's, the
 * elongation each subaperture's and in the model), by Gauss–Newton on Σ_k,q (M − I)² / V, V = max(M, 0) + B + σe²
 * a frame's pixel variance, from the reference (α = 1, Σ = 0; α = 0 fixed for a reference without seeing), α ≥ 0 and
 * Σ ⪰ 0 kept by clipping; then
 *   G_k = R_k ∂I_k(α̂, Σ̂)/∂θ  (the model's own derivatives),   s ← G_k⁻¹ s,   C_k ← G_k⁻¹ C_k G_k⁻ᵀ.
 * R_k ∂I/∂θ is the filter's output on I0 + δ ∂I/∂θ (the filter is linear: s = R (d − I0)), so the centroider's own
 * per-frame path measures it. */
#include "sensing.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../optics/spot.h"

#ifdef _OPENMP
#include <omp.h>
#else
#define omp_in_parallel() 1
#endif

/* a gain outside this range is no loop's: the frames were not the spots of this reference */
#define GAIN_MIN 0.25
#define GAIN_MAX 4.0
/* Gauss–Newton: iterations (from the reference; from the last estimate), and the steps of the model's finite
 * differences (α; Σ in pixels²) */
#define FIT_ITERATIONS 4
#define FIT_ITERATIONS_WARM 2
#define STEP_ALPHA 0.05
#define STEP_BLUR 0.02
/* the fit's subapertures: at most about this many of the fully lit ones */
#define FIT_SUBAPERTURES 512

int wt_sensing_gain_start(wt_sensing *ws)
{
    wt_context *ctx = ws->ctx;
    if (!ws->lgs || ws->cpar.method != WT_CENTROID_MF)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "diffractive sensor: the gain from the loop's pixels is the matched filter's of an LGS "
                        "(lgs.wfs.centroider = \"mf\")");
    const size_t npix = (size_t)ws->nsub * ws->ns * ws->ns;
    int st = WT_OK;
    wt_sensing_gain_stop(ws);
    WT_ALLOC(ctx, ws->gain_acc, npix, "gain accumulator");
    ws->gain_frames = 0;
    ws->gain_seconds = 0.0;
    ws->gain_fits = 0; /* a loop's first fit starts from the reference */
    return WT_OK;
fail:
    return st;
}

void wt_sensing_gain_stop(wt_sensing *ws)
{
    wt_free(ws->ctx, ws->gain_acc);
    ws->gain_acc = NULL;
    ws->gain_frames = 0;
}

/* the model's images (and derivatives when dx, dy) at p = {α, Σxx, Σxy, Σyy / p²}, of the subapertures `only` says
 * (NULL: all) */
static int model(wt_sensing *ws, const double p[4], const unsigned char *only, float *img, float *dx, float *dy)
{
    const double p2 = ws->pixel * ws->pixel;
    /* α = 0: no seeing (a strength the subaperture cannot tell from none) */
    const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid,
                                .blur = {p[1] * p2, p[2] * p2, p[3] * p2},
                                .scale = ws->seeing && p[0] > 1e-9 ? p[0] : 1e-9, .only = only};
    return wt_spot_reference(ws->spot, 0.0, &see, img, dx, dy);
}

/* α ≥ 0 and Σ ⪰ 0: a negative eigenvalue of Σ set to 0 */
static void clip(double p[4])
{
    if (p[0] < 0.0) p[0] = 0.0;
    const double a = p[1], b = p[2], c = p[3], m = 0.5 * (a + c), r = hypot(0.5 * (a - c), b);
    double l1 = m + r, l2 = m - r;
    if (l2 >= 0.0) return;
    if (l1 <= 0.0) {
        p[1] = p[2] = p[3] = 0.0;
        return;
    }
    /* keep the eigenvector of l1: Σ = l1 v vᵀ */
    const double th = 0.5 * atan2(2.0 * b, a - c), vx = cos(th), vy = sin(th);
    l2 = 0.0;
    p[1] = l1 * vx * vx, p[2] = l1 * vx * vy, p[3] = l1 * vy * vy;
}

/* Gauss–Newton fit of the model to the mean image m (nsub Ns²): p in, p out */
static int fit(wt_sensing *ws, const float *m, int iterations, double p[4])
{
    wt_context *ctx = ws->ctx;
    const int npar = ws->seeing ? 4 : 3, off = 4 - npar; /* without seeing: α stays 0 */
    const int nsub = ws->nsub, np2 = ws->np * ws->np;
    const size_t n2 = (size_t)ws->ns * ws->ns, npix = (size_t)nsub * n2;
    const double v0 = ws->cpar.background + ws->cpar.read_noise * ws->cpar.read_noise;
    int st = WT_OK, nfull = 0;
    float *img = NULL;
    unsigned char *only = NULL;
    WT_ALLOC(ctx, img, (size_t)(npar + 1) * npix, "gain model images");
    WT_ALLOC(ctx, only, nsub, "gain fit subapertures");
    /* the fully lit subapertures (their seeing is one table's, so each model costs their images only), every
     * ⌈n / FIT_SUBAPERTURES⌉-th of them: the sensor's few parameters need no more */
    for (int k = 0; k < nsub; k++) {
        int full = 1;
        for (int q = 0; q < np2 && full; q++) full = ws->amp[(size_t)k * np2 + q] == 1.0f;
        only[k] = (unsigned char)full, nfull += full;
    }
    const int every = (nfull + FIT_SUBAPERTURES - 1) / FIT_SUBAPERTURES;
    for (int k = 0, c = 0; k < nsub; k++)
        if (only[k]) only[k] = c++ % every == 0;
    if (nfull == 0) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "diffractive sensor: no fully lit subaperture to fit the spot model on");
        goto fail;
    }
    for (int it = 0; it < iterations; it++) {
        WT_TRY(model(ws, p, only, img, NULL, NULL));
        double h[4];
        for (int j = 0; j < npar; j++) {
            double q[4] = {p[0], p[1], p[2], p[3]};
            h[j] = off + j == 0 ? STEP_ALPHA : STEP_BLUR;
            q[off + j] += h[j];
            WT_TRY(model(ws, q, only, img + (size_t)(j + 1) * npix, NULL, NULL));
        }
        double A[16] = {0}, b[4] = {0};
        for (size_t q = 0; q < npix; q++) {
            if (!only[q / n2]) { /* the subaperture's pixels at once */
                q += n2 - 1;
                continue;
            }
            const double w = 1.0 / ((m[q] > 0.0f ? m[q] : 0.0) + v0 + 1e-3), r = (double)m[q] - img[q];
            double J[4];
            for (int j = 0; j < npar; j++) J[j] = ((double)img[(size_t)(j + 1) * npix + q] - img[q]) / h[j];
            for (int i = 0; i < npar; i++) {
                b[i] += w * J[i] * r;
                for (int j = 0; j <= i; j++) A[i * npar + j] += w * J[i] * J[j];
            }
        }
        for (int i = 0; i < npar; i++)
            for (int j = 0; j < i; j++) A[j * npar + i] = A[i * npar + j];
        if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'L', npar, 1, A, npar, b, 1) != 0) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "diffractive sensor: the spot model's fit to the loop's mean image is singular (the images "
                          "do not tell the seeing from the jitter); the old gain correction is kept");
            goto fail;
        }
        for (int j = 0; j < npar; j++) p[off + j] += b[j];
        clip(p);
    }
fail:
    wt_free(ctx, img);
    wt_free(ctx, only);
    return st;
}

int wt_sensing_gain_update(wt_sensing *ws, double *along, double *across)
{
    wt_context *ctx = ws->ctx;
    if (!ws->gain_acc) return WT_ERROR(ctx, WT_ERR_INVALID, "diffractive sensor: no pixels accumulated for a gain");
    if (ws->gain_frames < WT_SENSING_PIXELS_MIN_FRAMES)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "diffractive sensor: the gain from the loop's pixels needs at least %d frames, %ld were "
                        "accumulated; the old correction is kept",
                        WT_SENSING_PIXELS_MIN_FRAMES, ws->gain_frames);
    const int nsub = ws->nsub;
    const size_t npix = (size_t)nsub * ws->ns * ws->ns;
    const double inv_n = 1.0 / (double)ws->gain_frames, delta = 0.1 * ws->pixel;
    const double *cov0 = ws->gain_cov0 ? ws->gain_cov0 : ws->cov; /* the covariance of the filter alone */
    int st = WT_OK;
    float *img = NULL;
    double *s = NULL, *hk = NULL, *cov = NULL, *nea = NULL;
    WT_ALLOC(ctx, img, 3 * npix, "gain images");
    WT_ALLOC(ctx, s, 4 * (size_t)nsub, "gain slopes");
    WT_ALLOC(ctx, hk, 4 * (size_t)nsub, "gain corrections");
    WT_ALLOC(ctx, cov, 3 * (size_t)nsub, "noise covariance");
    WT_ALLOC(ctx, nea, nsub, "NEA");
    for (size_t q = 0; q < npix; q++) img[q] = (float)(ws->gain_acc[q] * inv_n);
    const double p2 = ws->pixel * ws->pixel;
    double p[4] = {ws->seeing ? 1.0 : 0.0, 0.0, 0.0, 0.0};
    if (ws->gain_fits > 0) /* from the last estimate's model: the spots change slowly */
        p[0] = ws->gain_model[0], p[1] = ws->gain_model[1] / p2, p[2] = ws->gain_model[2] / p2, p[3] = ws->gain_model[3] / p2;
    WT_TRY(fit(ws, img, ws->gain_fits > 0 ? FIT_ITERATIONS_WARM : FIT_ITERATIONS, p));
    /* I0 + δ ∂I/∂θx and I0 + δ ∂I/∂θy of the fitted model, through the filter in force */
    WT_TRY(model(ws, p, NULL, img, img + npix, img + 2 * npix));
    for (size_t q = 0; q < npix; q++) {
        img[q] = ws->i0[q] + (float)delta * img[npix + q];
        img[npix + q] = ws->i0[q] + (float)delta * img[2 * npix + q];
    }
    wt_centroid_apply(ws->cen, img, s);
    wt_centroid_apply(ws->cen, img + npix, s + 2 * (size_t)nsub);
    double mean[2] = {0.0, 0.0};
    for (int k = 0; k < nsub; k++) {
        const double gxx = s[k] / delta, gyx = s[nsub + k] / delta, gxy = s[2 * nsub + k] / delta,
                     gyy = s[3 * nsub + k] / delta, det = gxx * gyy - gxy * gyx;
        double ex, ey;
        wt_sensing__direction(ws, k, &ex, &ey);
        const double gp = ex * (gxx * ex + gxy * ey) + ey * (gyx * ex + gyy * ey);
        const double gq = -ey * (-gxx * ey + gxy * ex) + ex * (-gyx * ey + gyy * ex);
        if (!(isfinite(det) && gp >= GAIN_MIN && gp <= GAIN_MAX && gq >= GAIN_MIN && gq <= GAIN_MAX && det > 0.0)) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "diffractive sensor: the matched filter's gain from the loop's pixels is %g along and %g "
                          "across the elongation in subaperture %d (%ld frames; the fitted spot: seeing × %g, jitter "
                          "{%g, %g, %g} pixels²): outside [%g, %g], the frames are not this reference's spots; the old "
                          "correction is kept",
                          gp, gq, k, ws->gain_frames, p[0], p[1], p[2], p[3], GAIN_MIN, GAIN_MAX);
            goto fail;
        }
        mean[0] += gp / nsub, mean[1] += gq / nsub;
        double *h = hk + 4 * (size_t)k;
        h[0] = gyy / det, h[1] = -gxy / det, h[2] = -gyx / det, h[3] = gxx / det;
    }
    wt_sensing__gain_cov(nsub, hk, cov0, cov);
    double median = 0.0, mean_var = 0.0;
    const int bad = wt_sensing__nea_stats(nsub, cov, nea, &median, &mean_var);
    if (bad >= 0) {
        st = WT_ERROR(ctx, WT_ERR_INVALID,
                      "diffractive sensor: the gain correction gives subaperture %d a covariance that is not positive "
                      "definite; the old correction is kept", bad);
        goto fail;
    }
    /* everything computed: commit */
    if (!ws->gain_cov0) {
        WT_ALLOC(ctx, ws->gain_cov0, 3 * (size_t)nsub, "the filter's covariance");
        memcpy(ws->gain_cov0, ws->cov, 3 * (size_t)nsub * sizeof *ws->cov);
    }
    if (!ws->gain_corr) {
        ws->gain_corr = hk, hk = NULL;
    } else
        memcpy(ws->gain_corr, hk, 4 * (size_t)nsub * sizeof *hk);
    memcpy(ws->cov, cov, 3 * (size_t)nsub * sizeof *cov);
    ws->nea_median = median, ws->mean_var = mean_var;
    ws->reference_changed = 1; /* restore rebuilds the set-up's filter and covariance */
    ws->gain_est[0] = mean[0], ws->gain_est[1] = mean[1];
    ws->gain_fits++;
    ws->gain_model[0] = p[0], ws->gain_model[1] = p[1] * p2, ws->gain_model[2] = p[2] * p2, ws->gain_model[3] = p[3] * p2;
    if (along) *along = mean[0];
    if (across) *across = mean[1];
    memset(ws->gain_acc, 0, npix * sizeof *ws->gain_acc);
    ws->gain_frames = 0;
fail:
    wt_free(ctx, img);
    wt_free(ctx, s);
    wt_free(ctx, hk);
    wt_free(ctx, cov);
    wt_free(ctx, nea);
    return st;
}
