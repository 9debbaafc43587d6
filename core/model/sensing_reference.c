/* core/model/sensing_reference.c: the diffractive sensor when the sodium layer changes (sensing.h, SPEC §12 "The
 * sodium layer changes too"): the truth's spot tables of a new profile, a reference rebuilt in the loop (the
 * oracle's from the spot model; any other from given images), and the way back to the set-up's state. */
#include "sensing.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../optics/sodium.h"
#include "../optics/spot.h"

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int wt_sensing_set_sodium(wt_sensing *ws, const wt_sodium *na)
{
    if (!ws->lgs) return WT_ERROR(ws->ctx, WT_ERR_INVALID, "diffractive sensor: a sodium profile for an NGS");
    const int st = wt_spot_set_sodium(ws->spot, na);
    if (st < 0) return st;
    ws->sodium_changed = 1;
    return WT_OK;
}

int wt_sensing_set_reference(wt_sensing *ws, const float *i0, const float *dix, const float *diy)
{
    wt_context *ctx = ws->ctx;
    const int nsub = ws->nsub, ns = ws->ns;
    int st = WT_OK;
    wt_centroid *cen = NULL;
    double *cov = NULL, *trunc = NULL, *nea = NULL;
    WT_TRY(wt_centroid_alloc(ctx, &ws->cpar, nsub, ns, i0, dix, diy, &cen));
    WT_ALLOC(ctx, cov, 3 * (size_t)nsub, "noise covariance");
    WT_ALLOC(ctx, trunc, nsub, "truncations");
    WT_ALLOC(ctx, nea, nsub, "NEA");
    if (ws->calibration == 1) WT_TRY(wt_centroid_noise_mc(cen, i0, ws->calibration_draws, ws->calibration_seed, cov, NULL));
    else wt_centroid_noise_cov(cen, cov);
    double mean_var = 0.0;
    for (int k = 0; k < nsub; k++) {
        const double a = cov[k], b = cov[nsub + k], c = cov[2 * nsub + k];
        if (!(isfinite(a) && isfinite(b) && isfinite(c) && a > 0.0 && c > 0.0 && a * c - b * b > 0.0)) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "diffractive sensor: the rebuilt reference gives subaperture %d a centroid noise covariance "
                          "{%g, %g, %g} rad^2 that is not positive definite; the old reference is kept",
                          k, a, b, c);
            goto fail;
        }
        nea[k] = sqrt(0.5 * (a + c));
        mean_var += 0.5 * (a + c) / nsub;
    }
    qsort(nea, (size_t)nsub, sizeof *nea, cmp_double);
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
    ws->nea_median = nsub % 2 ? nea[nsub / 2] : 0.5 * (nea[nsub / 2 - 1] + nea[nsub / 2]);
    ws->mean_var = mean_var;
    ws->reference_changed = 1;
fail:
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

int wt_sensing_restore(wt_sensing *ws)
{
    int st = WT_OK;
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
