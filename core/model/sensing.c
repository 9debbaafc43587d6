/* core/model/sensing.c: the diffractive sensor of one WFS: spot + centroider from the system geometry, its
 * noise covariance for the reconstructor, and the per-frame truth path (SPEC §4b; see sensing.h). */
#include "sensing.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "../base/sha256.h"
#include "../op/pupil.h"
#include "../optics/centroid.h"
#include "../optics/sodium.h"
#include "../optics/spot.h"

#ifdef _OPENMP
#include <omp.h>
#else
#define omp_in_parallel() 1
#endif

/* the message of the optics module, prefixed with the sensor and the keys */
static int rewrap(wt_context *ctx, int st, const wt_sensing_geometry *g, const char *keys)
{
    char detail[1024];
    snprintf(detail, sizeof detail, "%s", wt_error_message(ctx));
    return WT_ERROR(ctx, st < 0 ? st : WT_ERR_CONFIG, "%s: %s (%s): %s", g->source ? g->source : "sensing", g->name,
                    keys, detail);
}

int wt_sensing_alloc(wt_context *ctx, const wt_config *cfg, const wt_sensor_config *w, const wt_sensing_geometry *g,
                     wt_sensing **out)
{
    int st = WT_OK;
    wt_sensing *ws = NULL;
    wt_sodium *na = NULL;
    double *lit = NULL, *tmp = NULL;
    float *dix = NULL, *diy = NULL;
    const char *pre = g->lgs ? "lgs.wfs" : "ngs.wfs";
    const double t0 = wt_time_now();
    *out = NULL;
    if (g->nsub <= 0 || !g->xc || !g->yc || !(g->side > 0.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: %s: no subaperture for the diffractive sensor", g->source, g->name);
    WT_ALLOC(ctx, ws, 1, "diffractive sensor");
    ws->ctx = ctx;
    ws->lgs = g->lgs;
    ws->nsub = g->nsub;
    ws->np = w->pupil_samples;
    ws->ns = w->pixels;
    ws->side = g->side;
    ws->pixel = w->pixel;
    ws->launch_x = g->launch_x;
    ws->launch_y = g->launch_y;
    ws->seeing = g->lgs && cfg->lgs_reference_seeing > 0;
    /* "rendered": the phase as the simulation renders it, on screens of the simulation grid's spacing
     * read by bilinear interpolation (seeing.h); "tilt_removed": the sky's */
    ws->seeing_grid = cfg->lgs_reference_seeing == 2 ? g->side / cfg->points_per_subaperture : 0.0;
    /* the centroider is the real-time computer's: its reference knows the reconstructor's atmosphere */
    ws->r0 = cfg->model.r0;
    ws->L0 = cfg->model.L0;
    const int nsub = g->nsub, np = ws->np, ns = ws->ns;
    const size_t nsamp = (size_t)nsub * np * np, npix = (size_t)nsub * ns * ns;

    /* the sodium line */
    if (g->lgs && cfg->sodium_profile[0]) {
        if ((st = wt_sodium_read(ctx, cfg->sodium_profile, &na)) < 0 ||
            (st = wt_sodium_check_covers(ctx, na, g->altitude, "lgs.sodium_profile")) < 0) {
            char detail[1024];
            snprintf(detail, sizeof detail, "%s", wt_error_message(ctx));
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'lgs.sodium_profile' = \"%s\" (with lgs.altitude_m = %g m): %s",
                          g->source, cfg->sodium_profile, g->altitude, detail);
            goto fail;
        }
        /* the profile the configuration's hash (and so the matrix hash) was taken from, or recorded with */
        char now[65];
        if (cfg->sodium_profile_sha256[0] &&
            (wt_sha256_file(cfg->sodium_profile, now) != 0 || strcmp(now, cfg->sodium_profile_sha256) != 0)) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG,
                          "%s: key 'lgs.sodium_profile' = \"%s\": the file's contents changed: its SHA-256 is %.12s…, the "
                          "configuration's 'lgs.sodium_profile_sha256' is %.12s… (the profile it was read or recorded "
                          "with); a matrix or telemetry made with that profile does not describe this one (to take the "
                          "file as it is now: --set lgs.sodium_profile_sha256=auto)",
                          g->source, cfg->sodium_profile, now[0] ? now : "unreadable", cfg->sodium_profile_sha256);
            goto fail;
        }
    } else if (g->lgs && cfg->sodium_fwhm > 0.0) {
        WT_TRY(wt_sodium_gaussian(ctx, g->altitude, cfg->sodium_fwhm, &na));
    }

    /* amplitudes: each sample's lit fraction; lit: the subaperture's, relative to the best-lit one */
    WT_ALLOC(ctx, ws->xc, nsub, "subaperture centres");
    WT_ALLOC(ctx, ws->yc, nsub, "subaperture centres");
    WT_ALLOC(ctx, ws->amp, nsamp, "pupil amplitudes");
    WT_ALLOC(ctx, lit, nsub, "lit fractions");
    {
        const double d = g->side, dx = d / np;
        double fmax = 0.0;
        for (int k = 0; k < nsub; k++) {
            ws->xc[k] = g->xc[k];
            ws->yc[k] = g->yc[k];
            const double x0 = g->xc[k] - 0.5 * d, y0 = g->yc[k] - 0.5 * d;
            const double f = wt_pupil_fraction(g->diameter, g->obstruction, x0, y0, d);
            lit[k] = f;
            if (f > fmax) fmax = f;
            float *a = ws->amp + (size_t)k * np * np;
            for (int j = 0; j < np; j++)
                for (int i = 0; i < np; i++)
                    a[i + np * j] = f >= 1.0 ? 1.0f
                                             : (float)wt_pupil_fraction(g->diameter, g->obstruction, x0 + i * dx,
                                                                        y0 + j * dx, dx);
        }
        for (int k = 0; k < nsub; k++) lit[k] /= fmax;
    }

    wt_spot_params sp = {.wavelength = w->wavelength,
                         .subap_side = g->side,
                         .pupil_samples = np,
                         .fft_size = w->fft_size,
                         .npix = ns,
                         .pixel = w->pixel,
                         .cells_per_pixel = w->cells_per_pixel,
                         .photons = w->photons,
                         .background = w->background_e,
                         .read_noise = w->read_noise_e,
                         .uplink_fwhm = g->lgs ? cfg->uplink_fwhm : 0.0,
                         .sodium = na,
                         .lgs_altitude = g->altitude,
                         .launch_x = g->launch_x,
                         .launch_y = g->launch_y};
    if ((st = wt_spot_alloc(ctx, &sp, nsub, ws->xc, ws->yc, ws->amp, lit, &ws->spot)) < 0) {
        char keys[256];
        snprintf(keys, sizeof keys, "%s.pupil_samples, fft_size, pixels, pixel_arcsec, wavelength_nm%s", pre,
                 g->lgs ? ", lgs.sodium_profile" : "");
        st = rewrap(ctx, st, g, keys);
        goto fail;
    }

    /* the reference and its derivatives, the truncation */
    WT_ALLOC(ctx, ws->i0, npix, "reference images");
    WT_ALLOC(ctx, dix, npix, "reference derivatives");
    WT_ALLOC(ctx, diy, npix, "reference derivatives");
    WT_ALLOC(ctx, ws->trunc, nsub, "truncations");
    {
        /* a reference the loop rebuilds from the truth's profile (lgs.wfs.reference = oracle) reuses the
         * rebinned cells of this one: only the profile's tables change (spot.h) */
        if (g->lgs && na && cfg->lgs_reference == 1) WT_TRY(wt_spot_keep_reference(ws->spot));
        const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid};
        WT_TRY(wt_spot_reference(ws->spot, 0.0, ws->seeing ? &see : NULL, ws->i0, dix, diy));
    }
    wt_spot_truncation(ws->spot, ws->i0, ws->trunc);
    for (int k = 0; k < nsub; k++)
        if (ws->trunc[k] > ws->worst_trunc) ws->worst_trunc = ws->trunc[k], ws->worst_sub = k;
    if (ws->worst_trunc > WT_SENSING_TRUNC_REFUSE) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG,
                      "%s: %s: the detector field (%s.pixels = %d x %s.pixel_arcsec = %g arcsec) holds only %.1f %% of "
                      "subaperture %d's spot (centre %.2f, %.2f m); refused above %.0f %% truncation: widen the field, "
                      "or shorten the spots (lgs.sodium_fwhm_m / lgs.sodium_profile, lgs.launch_radius_m, "
                      "lgs.uplink_fwhm_arcsec)",
                      g->source, g->name, pre, ns, pre, w->pixel / WT_ARCSEC, 100.0 * (1.0 - ws->worst_trunc),
                      ws->worst_sub, ws->xc[ws->worst_sub], ws->yc[ws->worst_sub], 100.0 * WT_SENSING_TRUNC_REFUSE);
        goto fail;
    }
    if (ws->worst_trunc > WT_SENSING_TRUNC_WARN)
        wt_log(ctx, WT_LOG_WARN,
               "%s: %s: the detector field (%s.pixels = %d x %s.pixel_arcsec = %g arcsec) truncates %.1f %% of "
               "subaperture %d's spot flux (more than %.0f %%; refused above %.0f %%)",
               g->source, g->name, pre, ns, pre, w->pixel / WT_ARCSEC, 100.0 * ws->worst_trunc, ws->worst_sub,
               100.0 * WT_SENSING_TRUNC_WARN, 100.0 * WT_SENSING_TRUNC_REFUSE);

    ws->cpar = (wt_centroid_params){.method = w->centroider,
                             .window = w->window_pixels,
                             .threshold_noise = w->threshold_noise,
                             .threshold_peak = w->threshold_peak,
                             .mf_flux = 0,
                             .apply_gain = w->apply_gain,
                             /* calibrated at the operating flux and noise when the simulation has noise */
                             .noise_calibrated = w->centroider == WT_CENTROID_TCOG && cfg->noise,
                             .pixel = w->pixel,
                             .background = w->background_e,
                             .read_noise = w->read_noise_e};
    ws->calibration = w->noise_calibration;
    ws->calibration_draws = w->calibration_draws;
    ws->calibration_seed = w->calibration_seed;
    if ((st = wt_centroid_alloc(ctx, &ws->cpar, nsub, ns, ws->i0, dix, diy, &ws->cen)) < 0) {
        char keys[256];
        snprintf(keys, sizeof keys, "%s.centroider, window_pixels, apply_gain, tcog_threshold_*", pre);
        st = rewrap(ctx, st, g, keys);
        goto fail;
    }
    WT_ALLOC(ctx, ws->cov, 3 * (size_t)nsub, "noise covariance");
    if (w->noise_calibration == 1) WT_TRY(wt_centroid_noise_mc(ws->cen, ws->i0, w->calibration_draws,
                                                               w->calibration_seed, ws->cov, NULL));
    else wt_centroid_noise_cov(ws->cen, ws->cov);
    WT_ALLOC(ctx, tmp, nsub, "NEA");
    const int bad = wt_sensing__nea_stats(nsub, ws->cov, tmp, &ws->nea_median, &ws->mean_var);
    if (bad >= 0) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG,
                      "%s: %s: subaperture %d's centroid noise covariance {%g, %g, %g} rad^2 is not positive "
                      "definite (%s.centroider, photons, read_noise_e, background_e)",
                      g->source, g->name, bad, ws->cov[bad], ws->cov[nsub + bad], ws->cov[2 * nsub + bad], pre);
        goto fail;
    }

    WT_ALLOC(ctx, ws->opd, nsamp, "sample OPD");
    WT_ALLOC(ctx, ws->img, npix, "images");
    ws->setup_seconds = wt_time_now() - t0;
    ws->sodium0 = na;
    na = NULL;
    *out = ws;
fail:
    wt_sodium_free(na);
    wt_free(ctx, lit);
    wt_free(ctx, tmp);
    wt_free(ctx, dix);
    wt_free(ctx, diy);
    if (st < 0) wt_sensing_free(ws);
    return st;
}

void wt_sensing_free(wt_sensing *ws)
{
    if (!ws) return;
    wt_context *ctx = ws->ctx;
    wt_spot_free(ws->spot);
    wt_centroid_free(ws->cen);
    wt_free(ctx, ws->xc);
    wt_free(ctx, ws->yc);
    wt_free(ctx, ws->amp);
    wt_free(ctx, ws->cov);
    wt_free(ctx, ws->trunc);
    wt_free(ctx, ws->i0);
    wt_free(ctx, ws->opd);
    wt_free(ctx, ws->img);
    wt_sensing_pixels_stop(ws);
    wt_free(ctx, ws->gain_acc); /* (sensing_gain.c calls this file, not the reverse) */
    wt_free(ctx, ws->gain_corr);
    wt_free(ctx, ws->gain_cov0);
    wt_sodium_free(ws->sodium0);
    wt_free(ctx, ws);
}

/* The fine cell (iu, iv) and weights of position (x, y); 0 when outside the grid. */
static inline int locate(const wt_grid *f, double x, double y, int *iu, int *iv, double *fu, double *fv)
{
    const double u = (x - f->x0) / f->dx, v = (y - f->y0) / f->dx;
    int a = (int)floor(u), b = (int)floor(v);
    if (a == f->nx - 1 && u - a < 1e-9) a--; /* a sample on the last grid line */
    if (b == f->ny - 1 && v - b < 1e-9) b--;
    if (a < 0 || b < 0 || a >= f->nx - 1 || b >= f->ny - 1) return 0;
    *iu = a, *iv = b, *fu = u - a, *fv = v - b;
    return 1;
}

int wt_sensing_fine_mask(const wt_sensing *ws, const wt_grid *fine, uint8_t *mask)
{
    const int np = ws->np;
    const double dx = ws->side / np;
    for (int k = 0; k < ws->nsub; k++)
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++) {
                if (ws->amp[(size_t)k * np * np + i + np * j] <= 0.0f) continue;
                const double x = ws->xc[k] + (i + 0.5 - 0.5 * np) * dx, y = ws->yc[k] + (j + 0.5 - 0.5 * np) * dx;
                int iu, iv;
                double fu, fv;
                if (!locate(fine, x, y, &iu, &iv, &fu, &fv))
                    return WT_ERROR(ws->ctx, WT_ERR_INVALID, "diffractive sensor: pupil sample (%g, %g) m outside the "
                                    "simulation grid", x, y);
                const int64_t p = iu + (int64_t)fine->nx * iv;
                mask[p] = mask[p + 1] = mask[p + fine->nx] = mask[p + fine->nx + 1] = 1;
            }
    return WT_OK;
}

void wt_sensing_sample(wt_sensing *ws, const wt_grid *fine, const double *fine_opd, double tx, double ty)
{
    const int np = ws->np;
    const double dx = ws->side / np;
    const int64_t nx = fine->nx;
    for (int k = 0; k < ws->nsub; k++) {
        const float *a = ws->amp + (size_t)k * np * np;
        float *o = ws->opd + (size_t)k * np * np;
        for (int j = 0; j < np; j++) {
            const double y = ws->yc[k] + (j + 0.5 - 0.5 * np) * dx;
            for (int i = 0; i < np; i++) {
                if (a[i + np * j] <= 0.0f) {
                    o[i + np * j] = 0.0f;
                    continue;
                }
                const double x = ws->xc[k] + (i + 0.5 - 0.5 * np) * dx;
                int iu = 0, iv = 0;
                double fu = 0.0, fv = 0.0;
                locate(fine, x, y, &iu, &iv, &fu, &fv); /* inside: checked by wt_sensing_fine_mask */
                const double *p = fine_opd + iu + nx * iv;
                const double v = (1.0 - fv) * ((1.0 - fu) * p[0] + fu * p[1]) + fv * ((1.0 - fu) * p[nx] + fu * p[nx + 1]);
                o[i + np * j] = (float)(v + tx * x + ty * y);
            }
        }
    }
}

void wt_sensing__direction(const wt_sensing *ws, int k, double *ex, double *ey)
{
    const double dx = ws->xc[k] - ws->launch_x, dy = ws->yc[k] - ws->launch_y, r = hypot(dx, dy);
    if (ws->lgs && r > 1e-9) *ex = dx / r, *ey = dy / r;
    else *ex = 1.0, *ey = 0.0;
}

/* subapertures from which a frame's gain sums take a thread team (fewer: the region costs more than the sums) */
enum { GAIN_PARALLEL_MIN = 256 };

/* the sums of wt_sensing_gain_in_loop for this frame's slopes */
static void gain_accumulate(wt_sensing *ws, const double *slopes)
{
    const int np = ws->np, nsub = ws->nsub;
    const double dx = ws->side / np;
    double sum[4] = {0};
#pragma omp parallel for schedule(static) reduction(+ : sum[:4]) if (nsub > GAIN_PARALLEL_MIN && !omp_in_parallel())
    for (int k = 0; k < nsub; k++) {
        const float *a = ws->amp + (size_t)k * np * np, *o = ws->opd + (size_t)k * np * np;
        double gx = 0, wx = 0, gy = 0, wy = 0;
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++) {
                const int p = i + np * j;
                if (i + 1 < np) {
                    const double w = (double)a[p] * a[p + 1];
                    gx += w * ((double)o[p + 1] - o[p]), wx += w;
                }
                if (j + 1 < np) {
                    const double w = (double)a[p] * a[p + np];
                    gy += w * ((double)o[p + np] - o[p]), wy += w;
                }
            }
        if (!(wx > 0 && wy > 0)) continue;
        gx /= wx * dx, gy /= wy * dx;
        double ex, ey;
        wt_sensing__direction(ws, k, &ex, &ey);
        const double sx = slopes[k], sy = slopes[nsub + k];
        const double gp = ex * gx + ey * gy, sp = ex * sx + ey * sy, gq = -ey * gx + ex * gy, sq = -ey * sx + ex * sy;
        sum[0] += sp * gp, sum[1] += gp * gp, sum[2] += sq * gq, sum[3] += gq * gq;
    }
    for (int i = 0; i < 4; i++) ws->gain_sum[i] += sum[i];
    ws->gain_sum[4] += 1.0;
}

void wt_sensing_gain_reset(wt_sensing *ws)
{
    memset(ws->gain_sum, 0, sizeof ws->gain_sum);
    ws->gain_on = 1;
}

void wt_sensing_gain_in_loop(const wt_sensing *ws, double *along, double *across, long *frames)
{
    const double *g = ws->gain_sum;
    *along = g[1] > 0 ? g[0] / g[1] : NAN;
    *across = g[3] > 0 ? g[2] / g[3] : NAN;
    *frames = (long)g[4];
}

/* the frame's images to the gain's accumulator (wt_sensing_gain_start), as detected */
static void gain_add(wt_sensing *ws)
{
    if (!ws->gain_acc) return;
    const double t0 = wt_time_now();
    const size_t n = (size_t)ws->nsub * ws->ns * ws->ns;
    float *restrict acc = ws->gain_acc;
    const float *restrict im = ws->img;
#pragma omp parallel for schedule(static) num_threads(wt_context_threads(ws->ctx)) if (n > 65536 && !omp_in_parallel())
    for (size_t q = 0; q < n; q++) acc[q] += im[q];
    ws->gain_frames++;
    ws->gain_seconds += wt_time_now() - t0;
}

void wt_sensing__gain_correct(const wt_sensing *ws, double *slopes)
{
    if (!ws->gain_corr) return;
    const int nsub = ws->nsub;
    for (int k = 0; k < nsub; k++) {
        const double *h = ws->gain_corr + 4 * (size_t)k, sx = slopes[k], sy = slopes[nsub + k];
        slopes[k] = h[0] * sx + h[1] * sy, slopes[nsub + k] = h[2] * sx + h[3] * sy;
    }
}

int wt_sensing_detect(wt_sensing *ws, int noise, uint64_t seed, uint64_t base_stream, double *slopes)
{
    int st = wt_spot_image(ws->spot, ws->opd, ws->img);
    if (st < 0) return st;
    if (noise && (st = wt_spot_noise(ws->spot, seed, base_stream, ws->img)) < 0) return st;
    wt_centroid_apply(ws->cen, ws->img, slopes);
    wt_sensing__gain_correct(ws, slopes);
    if (ws->gain_on) gain_accumulate(ws, slopes);
    gain_add(ws);
    if (ws->pix_acc) {
        /* re-centred on the set-up filter's slopes, not the loop's (sensing.h pix_cen0) */
        const double t0 = wt_time_now();
        wt_centroid_apply(ws->pix_cen0, ws->img, ws->pix_s0);
        ws->pix_seconds += wt_time_now() - t0;
        wt_sensing_pixels_add(ws, ws->img, ws->pix_s0);
    }
    return WT_OK;
}

int wt_sensing_detect_reference(wt_sensing *ws, int noise, uint64_t seed, uint64_t base_stream, double *slopes)
{
    memcpy(ws->img, ws->i0, (size_t)ws->nsub * ws->ns * ws->ns * sizeof *ws->img);
    int st = noise ? wt_spot_noise(ws->spot, seed, base_stream, ws->img) : WT_OK;
    if (st < 0) return st;
    wt_centroid_apply(ws->cen, ws->img, slopes);
    wt_sensing__gain_correct(ws, slopes);
    gain_add(ws); /* the reference's spots: a gain estimate of them is the identity */
    return WT_OK;
}

size_t wt_sensing_memory(const wt_sensing *ws)
{
    const size_t nsub = (size_t)ws->nsub, n2 = (size_t)ws->np * ws->np, s2 = (size_t)ws->ns * ws->ns;
    size_t b = sizeof *ws + wt_spot_memory(ws->spot) + wt_centroid_memory(ws->cen);
    b += nsub * (2 * sizeof(double) + 2 * n2 * sizeof(float) + 2 * s2 * sizeof(float) + 4 * sizeof(double));
    if (ws->pix_acc) /* E² = (Ns + 8)², the anchor and set-up image; the set-up filter and its slopes */
        b += nsub * (4 * s2 + 16 * (size_t)ws->ns + 64) * sizeof(float) + wt_centroid_memory(ws->pix_cen0) +
             2 * nsub * sizeof(double);
    if (ws->gain_acc) b += 3 * nsub * s2 * sizeof(float); /* the sum and the anchor */
    if (ws->gain_corr) b += 7 * nsub * sizeof(double);
    return b;
}

/* g resolved along e and e_perp, or its symmetric part's eigenvalues when there is no direction */
static void resolve_gain(const double g[4], double ex, double ey, int have_dir, double *par, double *perp)
{
    if (have_dir) {
        *par = ex * (g[0] * ex + g[1] * ey) + ey * (g[2] * ex + g[3] * ey);
        *perp = ey * (g[0] * ey - g[1] * ex) - ex * (g[2] * ey - g[3] * ex);
        return;
    }
    const double a = g[0], b = 0.5 * (g[1] + g[2]), c = g[3];
    const double m = 0.5 * (a + c), r = sqrt(0.25 * (a - c) * (a - c) + b * b);
    *par = m - r, *perp = m + r;
}

int wt_sensing_gain_along(const wt_sensing *ws, int cog, double lx, double ly, double *g_par, double *g_perp)
{
    wt_context *ctx = ws->ctx;
    const int nsub = ws->nsub, ns = ws->ns;
    wt_centroid *c = ws->cen, *tmp = NULL;
    float *dix = NULL, *diy = NULL;
    int st = WT_OK;
    if (cog) { /* the same reference through a whole-detector CoG, gain not applied (it is what we report) */
        const size_t npix = (size_t)nsub * ns * ns;
        WT_ALLOC(ctx, dix, npix, "reference derivatives");
        WT_ALLOC(ctx, diy, npix, "reference derivatives");
        const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid};
        WT_TRY(wt_spot_reference(ws->spot, 0.0, ws->seeing ? &see : NULL, NULL, dix, diy));
        wt_centroid_params cp = {.method = WT_CENTROID_COG, .pixel = ws->pixel};
        WT_TRY(wt_centroid_alloc(ctx, &cp, nsub, ns, ws->i0, dix, diy, &tmp));
        c = tmp;
    }
    for (int k = 0; k < nsub; k++) {
        double g[4], par, perp;
        wt_centroid_gain(c, k, g);
        const double dx = ws->xc[k] - lx, dy = ws->yc[k] - ly, r = hypot(dx, dy);
        const int dir = ws->lgs && r > 1e-9;
        resolve_gain(g, dir ? dx / r : 0.0, dir ? dy / r : 0.0, dir, &par, &perp);
        if (g_par) g_par[k] = par;
        if (g_perp) g_perp[k] = perp;
    }
fail:
    wt_centroid_free(tmp);
    wt_free(ctx, dix);
    wt_free(ctx, diy);
    return st;
}

int wt_sensing_response_now(const wt_sensing *ws, double lx, double ly, float *img, double *offset_par, double *g_par,
                            double *g_perp, double *trunc)
{
    wt_context *ctx = ws->ctx;
    const int nsub = ws->nsub, ns = ws->ns;
    const size_t npix = (size_t)nsub * ns * ns;
    const double eps = 0.01 * ws->pixel; /* the MF is linear in the image (any ε); a CoG nearly so at 1 % */
    float *im = NULL, *dix = NULL, *diy = NULL, *tmp = NULL;
    double *s = NULL;
    int st = WT_OK;
    WT_ALLOC(ctx, im, npix, "spot image");
    WT_ALLOC(ctx, dix, npix, "spot derivatives");
    WT_ALLOC(ctx, diy, npix, "spot derivatives");
    WT_ALLOC(ctx, tmp, npix, "spot image");
    WT_ALLOC(ctx, s, 6 * (size_t)nsub, "slopes");
    const wt_spot_seeing see = {.r0 = ws->r0, .L0 = ws->L0, .grid = ws->seeing_grid};
    WT_TRY(wt_spot_reference(ws->spot, 0.0, ws->seeing ? &see : NULL, im, dix, diy));
    wt_centroid_apply(ws->cen, im, s);
    for (int a = 0; a < 2; a++) {
        const float *d = a ? diy : dix;
        for (size_t q = 0; q < npix; q++) tmp[q] = im[q] + (float)eps * d[q];
        wt_centroid_apply(ws->cen, tmp, s + (size_t)(2 + 2 * a) * nsub);
    }
    for (int k = 0; k < nsub; k++) {
        const double *s0 = s, *sx = s + 2 * (size_t)nsub, *sy = s + 4 * (size_t)nsub;
        const double g[4] = {(sx[k] - s0[k]) / eps, (sy[k] - s0[k]) / eps, (sx[nsub + k] - s0[nsub + k]) / eps,
                             (sy[nsub + k] - s0[nsub + k]) / eps};
        const double dx = ws->xc[k] - lx, dy = ws->yc[k] - ly, r = hypot(dx, dy);
        const int dir = ws->lgs && r > 1e-9;
        double par, perp;
        resolve_gain(g, dir ? dx / r : 0.0, dir ? dy / r : 0.0, dir, &par, &perp);
        if (g_par) g_par[k] = par;
        if (g_perp) g_perp[k] = perp;
        if (offset_par) offset_par[k] = dir ? (dx * s0[k] + dy * s0[nsub + k]) / r : s0[k];
    }
    if (trunc) wt_spot_truncation(ws->spot, im, trunc);
    if (img) memcpy(img, im, npix * sizeof *img);
fail:
    wt_free(ctx, im), wt_free(ctx, dix), wt_free(ctx, diy), wt_free(ctx, tmp), wt_free(ctx, s);
    return st;
}
