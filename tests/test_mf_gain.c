/* tests/test_mf_gain.c: the matched filter's gain measured on the loop's own pixels (lgs.wfs.gain_update_s, issue 37
 * item 0 "or calibrated on turbulent frames"; core/model/sensing.h "wt_sensing_gain_*", core/model/sensing_gain.c):
 * Stein's identity on jittered spots, the reference's own spots, the closed loop's gain after the correction, the
 * refusals. */
#include <math.h>
#include <string.h>

#include "core/base/rng.h"
#include "core/model/sensing.h"
#include "core/optics/centroid.h"
#include "pixels_fixture.h"
#include "sim/loop.h"
#include "testutil.h"

/* nfr noise-free frames of the flat-wavefront spot at tilts drawn N(0, sig²) per subaperture and axis; *est the
 * estimate along / across the elongation, *reg the regression of the filter's slopes on the tilts (the in-loop
 * gain as the loop measures it). */
static void jitter_run(rig *r, double sig, int nfr, double est[2], double reg[2])
{
    wt_sensing *ws = r->ws;
    const int nsub = ws->nsub;
    double *th = calloc(2 * (size_t)nsub, sizeof *th), *sl = calloc(2 * (size_t)nsub, sizeof *sl);
    wt_rng g;
    wt_rng_init(&g, 5, 0);
    ck_assert_int_eq(wt_sensing_gain_start(ws), WT_OK);
    wt_sensing_gain_reset(ws);
    for (int f = 0; f < nfr; f++) {
        for (int q = 0; q < 2 * nsub; q++) th[q] = sig * wt_rng_normal(&g);
        set_tilt(ws, th, 0.0, 0.0);
        ck_assert_int_eq(wt_sensing_detect(ws, 0, 0, 0, sl), WT_OK);
    }
    long n = 0;
    wt_sensing_gain_in_loop(ws, &reg[0], &reg[1], &n);
    ck_assert_int_eq(n, nfr);
    ck_assert_msg(wt_sensing_gain_update(ws, &est[0], &est[1]) == WT_OK, "%s", wt_error_message(r->ctx));
    ck_assert_int_eq(ws->gain_frames, 0);
    ck_assert_int_eq(wt_sensing_restore(ws), WT_OK);
    ck_assert_ptr_null(ws->gain_corr);
    free(th), free(sl);
}

/* Stein's identity: for Gaussian tilts the regression of the filter's output on the tilt is R ∂M/∂θ, M the frames'
 * mean image. Frames: the flat wavefront's spot jittered by σ, 64 frames on the demo's first LGS (192 subapertures),
 * against (a) a reference without seeing (σ = 0.2″ and 0.5″: the jitter alone makes the gain 0.51–0.89) and (b) the
 * default reference with the subaperture's seeing (σ = 0.01″: spots narrower than the reference, gain 1.16–1.21;
 * 0.2″: 1.04). The estimate (the spot model fitted to M, its derivatives through the filter) is within 0.02 of the
 * regression on each axis (measured ≤ 0.011: the model's finite-difference Jacobian and the 64 frames' sampling of
 * both sides, 12 288 tilts each, ~0.003 at the widest jitter). The derivative of M's own pixels (a cubic spline,
 * anchored on the reference's) caught only 0.2–0.4 of these changes (0.976 for 0.895 at 0.2″): it would fail. */
START_TEST(test_stein_identity)
{
    const double as = WT_ARCSEC;
    const struct { int seeing; double sig, lo; } c[4] = {{0, 0.2, 0.95}, {0, 0.5, 0.7}, {1, 0.01, 1.1}, {1, 0.2, 1.02}};
    for (int i = 0; i < 4; i++) {
        const char *set[] = {"lgs.wfs.reference_seeing=\"none\""};
        rig r;
        rig_open_with(&r, c[i].seeing ? 0 : 1, set);
        double e[2], m[2];
        jitter_run(&r, c[i].sig * as, 64, e, m);
        for (int a = 0; a < 2; a++)
            ck_assert_msg(fabs(e[a] - m[a]) < 0.02, "case %d axis %d: estimate %.4f, regression %.4f", i, a, e[a], m[a]);
        /* the case's power: the gain is far from 1 */
        ck_assert_msg(c[i].lo < 1.0 ? m[0] < c[i].lo : m[0] > c[i].lo, "case %d: regression %.4f", i, m[0]);
        rig_close(&r);
    }
}
END_TEST

/* Frames that are the reference I0 itself (noise-free, no jitter): the fit stays at the reference's model, so the
 * gain is the identity (to the float rounding of the filter's output, ~1e-6) and the slopes are the uncorrected
 * filter's; the covariance is the set-up's. Fewer than 2 frames are refused, naming the minimum, the old correction
 * kept. */
START_TEST(test_reference_spots_give_identity)
{
    rig r;
    rig_open_with(&r, 0, NULL);
    wt_sensing *ws = r.ws;
    const int nsub = ws->nsub;
    const size_t npix = (size_t)nsub * ws->ns * ws->ns;
    double *cov0 = malloc(3 * (size_t)nsub * sizeof *cov0);
    memcpy(cov0, ws->cov, 3 * (size_t)nsub * sizeof *cov0);
    ck_assert_int_eq(wt_sensing_gain_start(ws), WT_OK);
    for (size_t q = 0; q < npix; q++) ws->gain_acc[q] = ws->i0[q];
    ws->gain_frames = 1;
    ck_assert_int_eq(wt_sensing_gain_update(ws, NULL, NULL), WT_ERR_INVALID);
    ck_assert_msg(strstr(wt_error_message(r.ctx), "at least 2"), "%s", wt_error_message(r.ctx));
    ck_assert_ptr_null(ws->gain_corr);
    for (size_t q = 0; q < npix; q++) ws->gain_acc[q] = 3.0f * ws->i0[q];
    ws->gain_frames = 3;
    double a = 0, c = 0;
    ck_assert_msg(wt_sensing_gain_update(ws, &a, &c) == WT_OK, "%s", wt_error_message(r.ctx));
    ck_assert_msg(fabs(a - 1) < 1e-4 && fabs(c - 1) < 1e-4, "gain %.7f / %.7f", a, c);
    ck_assert_ptr_nonnull(ws->gain_corr);
    for (int k = 0; k < nsub; k++) {
        const double *h = ws->gain_corr + 4 * (size_t)k;
        ck_assert_msg(fabs(h[0] - 1) < 1e-4 && fabs(h[1]) < 1e-4 && fabs(h[2]) < 1e-4 && fabs(h[3] - 1) < 1e-4,
                      "subaperture %d: H {%g, %g; %g, %g}", k, h[0], h[1], h[2], h[3]);
    }
    for (size_t q = 0; q < 3 * (size_t)nsub; q++) ck_assert_double_eq_tol(ws->cov[q], cov0[q], 1e-3 * fabs(cov0[q]) + 1e-30);
    ck_assert_int_eq(wt_sensing_restore(ws), WT_OK);
    for (size_t q = 0; q < 3 * (size_t)nsub; q++) ck_assert_double_eq(ws->cov[q], cov0[q]);
    free(cov0);
    rig_close(&r);
}
END_TEST

/* An oracle's rebuilt reference keeps the correction in force (its covariance H C Hᵀ with C the new filter's own,
 * kept as gain_cov0) and restore drops it, back to the set-up's covariance bit for bit. Jittered spots (0.2″, against
 * the reference without seeing) give a correction far from the identity (gain ~0.86–0.89), so a dropped or
 * untransformed covariance differs by ~25 %. */
START_TEST(test_rebuild_keeps_correction)
{
    const char *set[] = {"lgs.wfs.reference_seeing=\"none\""};
    rig r;
    rig_open_with(&r, 1, set);
    wt_sensing *ws = r.ws;
    const int nsub = ws->nsub;
    double *cov0 = malloc(3 * (size_t)nsub * sizeof *cov0), *own = malloc(3 * (size_t)nsub * sizeof *own);
    double *want = malloc(3 * (size_t)nsub * sizeof *want), *th = calloc(2 * (size_t)nsub, sizeof *th);
    double *sl = calloc(2 * (size_t)nsub, sizeof *sl);
    memcpy(cov0, ws->cov, 3 * (size_t)nsub * sizeof *cov0);
    wt_rng g;
    wt_rng_init(&g, 9, 0);
    ck_assert_int_eq(wt_sensing_gain_start(ws), WT_OK);
    for (int f = 0; f < 16; f++) {
        for (int q = 0; q < 2 * nsub; q++) th[q] = 0.2 * WT_ARCSEC * wt_rng_normal(&g);
        set_tilt(ws, th, 0.0, 0.0);
        ck_assert_int_eq(wt_sensing_detect(ws, 0, 0, 0, sl), WT_OK);
    }
    double a = 0, c = 0;
    ck_assert_msg(wt_sensing_gain_update(ws, &a, &c) == WT_OK, "%s", wt_error_message(r.ctx));
    ck_assert_msg(a < 0.95 && c < 0.95, "gain %g / %g", a, c);
    ck_assert_int_eq(wt_sensing_rebuild_reference(ws), WT_OK);
    ck_assert_ptr_nonnull(ws->gain_corr);
    wt_centroid_noise_cov(ws->cen, own);
    wt_sensing__gain_cov(nsub, ws->gain_corr, own, want);
    for (size_t q = 0; q < 3 * (size_t)nsub; q++) {
        ck_assert_double_eq(ws->gain_cov0[q], own[q]);
        ck_assert_double_eq(ws->cov[q], want[q]);
    }
    ck_assert_msg(fabs(ws->cov[0] / cov0[0] - 1.0) > 0.1, "covariance %g against the set-up's %g", ws->cov[0], cov0[0]);
    ck_assert_int_eq(wt_sensing_restore(ws), WT_OK);
    ck_assert_ptr_null(ws->gain_corr);
    for (size_t q = 0; q < 3 * (size_t)nsub; q++) ck_assert_double_eq(ws->cov[q], cov0[q]);
    free(cov0), free(own), free(want), free(th), free(sl);
    rig_close(&r);
}
END_TEST

/* The demo's closed loop (PCG-3, 200 frames, noise) whose LGS filters are re-measured every 0.1 s (50 frames): its
 * in-loop gain — the regression of the measured slopes on the true ones over the averaged frames — is within 3 % of 1
 * on both axes (the target; 0.991 / 0.974 without the correction, measured 0.993 / 0.991 with it); the
 * system is left at its set-up (the covariance's bits). */
START_TEST(test_loop_gain_near_one)
{
    const char *set[] = {"lgs.wfs.gain_update_s=0.1"};
    wt_context *ctx = tu_context();
    wt_context_set_threads(ctx, 2);
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_loop *lp = NULL;
    ck_assert_msg(wt_config_read(ctx, DDEMO, 1, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    const wt_sensing *ws = NULL;
    for (int m = 0; m < sys->nsensors && !ws; m++)
        if (sys->sensors[m].diffr && sys->sensors[m].kind == WT_SENSOR_LGS) ws = sys->sensors[m].diffr;
    double *cov0 = malloc(3 * (size_t)ws->nsub * sizeof *cov0);
    memcpy(cov0, ws->cov, 3 * (size_t)ws->nsub * sizeof *cov0);
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = 1, .noise = 1};
    ck_assert_msg(wt_loop_alloc(ctx, sys, &o, &lp) == WT_OK, "%s", wt_error_message(ctx));
    for (long t = 0; t < cfg->frames; t++) ck_assert_msg(wt_loop_step(lp) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_sodium_drive_get_stats(wt_loop_sodium(lp)).gain_updates, 3);
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensing *s = sys->sensors[m].diffr;
        if (!s || sys->sensors[m].kind != WT_SENSOR_LGS) continue;
        double a, c;
        long n;
        wt_sensing_gain_in_loop(s, &a, &c, &n);
        ck_assert_msg(fabs(a - 1) < 0.03 && fabs(c - 1) < 0.03, "%s: in-loop gain %.4f / %.4f (%ld frames)",
                      sys->sensors[m].name, a, c, n);
    }
    wt_loop_free(lp);
    for (size_t q = 0; q < 3 * (size_t)ws->nsub; q++) ck_assert_double_eq(ws->cov[q], cov0[q]);
    free(cov0);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The key refused, naming it and what it needs: with a thresholded CoG, shorter than two frames (1 frame of 2 ms),
 * with a sodium sequence and a static reference (the oracle's is accepted), with geometric LGS sensors, and
 * negative. */
START_TEST(test_gain_refusals)
{
    const struct { const char *a, *b, *word; } bad[] = {
        {"lgs.wfs.centroider=\"tcog\"", "lgs.wfs.gain_update_s=0.1", "centroider"},
        {"lgs.wfs.gain_update_s=0.002", NULL, "at least 2"},
        {"lgs.sodium_sequence=\"../sodium/drift-1km-10min.txt\"", "lgs.wfs.gain_update_s=0.1", "oracle"},
        {"lgs.wfs.model=\"geometric\"", "lgs.wfs.gain_update_s=0.1", "diffractive"},
        {"lgs.wfs.gain_update_s=-1.0", NULL, "lgs.wfs.gain_update_s"}};
    wt_context *ctx = tu_context();
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        const char *set[] = {bad[i].a, bad[i].b};
        wt_config *cfg = NULL;
        ck_assert_int_eq(wt_config_read(ctx, DDEMO, bad[i].b ? 2 : 1, set, &cfg), WT_ERR_CONFIG);
        const char *m = wt_error_message(ctx);
        ck_assert_msg(strstr(m, bad[i].word) && strstr(m, "gain_update_s"), "case %zu: %s", i, m);
    }
    const char *ok[] = {"lgs.sodium_sequence=\"../sodium/drift-1km-10min.txt\"", "lgs.wfs.gain_update_s=0.1",
                        "lgs.wfs.reference=\"oracle\"", "atmosphere.night.compression=10.0"};
    wt_config *cfg = NULL;
    ck_assert_msg(wt_config_read(ctx, DDEMO, 4, ok, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mf_gain");
    TCase *tc = tcase_create("the matched filter's gain from the pixels");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_stein_identity);
    tcase_add_test(tc, test_reference_spots_give_identity);
    tcase_add_test(tc, test_rebuild_keeps_correction);
    tcase_add_test(tc, test_loop_gain_near_one);
    tcase_add_test(tc, test_gain_refusals);
    suite_add_tcase(s, tc);
    return s;
}
TU_MAIN
