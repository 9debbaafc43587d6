/* tests/test_focus_stage.c: the LGS WFS focus stage and tip-tilt centring (sim/focus_stage.h) — it follows the
 * focus and tilt that a moving sodium layer puts on each LGS as the launch geometry predicts, leaves the system's
 * sensors as it found them, and its keys' refusals. */
#include <math.h>

#include "core/model/sensing.h"
#include "core/model/system.h"
#include "core/optics/sodium.h"
#include "sim/focus_stage.h"
#include "sim/loop.h"
#include "testutil.h"

#define DDEMO "data/presets/demo-diffractive.cfg"

/* A rigid rise Δh of the sodium layer moves the spot of subaperture r of an LGS launched from l by
 * (r − l)(1/h̄' − 1/h̄) (core/optics/spot.h, h̄ the centroid: exact for the centroid of a thin layer, and within
 * ~(σ/h̄)² ≈ 0.3 % for the shipped layers' spread), the slopes of the OPD −½ (1/h̄ − 1/h̄')|r|² + (1/h̄ − 1/h̄') l·r.
 * The stage must cancel it: c = ½ (1/h̄ − 1/h̄') and t_m = −(1/h̄ − 1/h̄') l_m. Noise-free, r0 = 20 m (the
 * turbulence's focus and tilt ~10⁻³ of the drift's), tables and stage moved every frame, gain 1: the stage in
 * force at the last frame F − 1 is the drift measured at frame F − 2 (its tables were F − 2's), up to the
 * centroider's gain on the focus pattern (≲ 5 %); 10 % holds that, while a wrong sign runs away and a wrong
 * factor of 2 (the slope of |r|² is 2 r) misses by 50 %. */
START_TEST(test_stage_follows_the_drift)
{
    enum { F = 40 };
    const char *set[] = {"loop.frames=40", "evaluation.settle_frames=10", "atmosphere.r0_m=20.0", "lgs.tt_jitter_arcsec=0.0",
                         "lgs.sodium_sequence=\"../sodium/drift-1km-10min.txt\"", "atmosphere.night.compression=2500.0",
                         "recon.lgs_focus_removal=true", "lgs.wfs.focus_stage=true", "lgs.wfs.focus_stage_gain=1.0"};
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_loop *lp = NULL;
    ck_assert_msg(wt_config_read(ctx, DDEMO, 9, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = 1, .noise = 0};
    ck_assert_msg(wt_loop_alloc(ctx, sys, &o, &lp) == WT_OK, "%s", wt_error_message(ctx));
    const wt_focus_stage *fs = wt_loop_focus_stage(lp);
    ck_assert_ptr_nonnull(fs);
    for (int t = 0; t < F; t++) ck_assert_msg(wt_loop_step(lp) == WT_OK, "%s", wt_error_message(ctx));

    /* the drift's centroids at night times 0 and (F − 2) · 5 s (the frame the last move measured) */
    wt_sodium_seq *seq = NULL;
    wt_sodium *na0 = NULL, *na1 = NULL;
    ck_assert_int_eq(wt_sodium_seq_read(ctx, cfg->sodium_sequence, &seq), WT_OK);
    ck_assert_int_eq(wt_sodium_seq_profile(ctx, seq, 0.0, &na0), WT_OK);
    ck_assert_int_eq(wt_sodium_seq_profile(ctx, seq, (F - 2) * 5.0, &na1), WT_OK);
    const double d = 1.0 / wt_sodium_centroid(na0) - 1.0 / wt_sodium_centroid(na1);
    ck_assert(d > 0.0);
    int nlgs = 0;
    for (int i = 0; i < sys->nsensors; i++) {
        const wt_sensor *s = &sys->sensors[i];
        double sg[3];
        wt_focus_stage_terms(fs, i, sg);
        const double tx = sg[0], ty = sg[1], c = sg[2];
        if (s->kind != WT_SENSOR_LGS) {
            ck_assert(tx == 0.0 && ty == 0.0 && c == 0.0);
            continue;
        }
        nlgs++;
        ck_assert_msg(fabs(c - 0.5 * d) <= 0.1 * 0.5 * d, "%s: focus %g, the geometry %g", s->name, c, 0.5 * d);
        const double px = -d * s->launch_x, py = -d * s->launch_y, l = hypot(px, py);
        ck_assert(l > 0.0);
        ck_assert_msg(hypot(tx - px, ty - py) <= 0.1 * l, "%s: tilt (%g, %g), the geometry (%g, %g)", s->name, tx, ty, px,
                      py);
    }
    ck_assert_int_gt(nlgs, 0);
    const wt_focus_stage_stats st = wt_focus_stage_get_stats(fs);
    ck_assert_int_eq(st.frames_averaged, F - 10);
    ck_assert_int_eq(st.moves, F - 1);

    /* the sensors are the system's: a freed loop leaves them at their set-up tables, without a stage */
    wt_loop_free(lp);
    for (int i = 0; i < sys->nsensors; i++)
        if (sys->sensors[i].diffr) ck_assert_int_eq(sys->sensors[i].diffr->sodium_changed, 0);
    wt_sodium_free(na0), wt_sodium_free(na1), wt_sodium_seq_free(seq);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* Each refusal names the key: the stage without the LGS focus removal (it takes the LGS focus out of the slopes) or
 * without a sodium sequence (it moves with the truth's tables), its gain without it or out of (0, 1], and either
 * key on geometric LGS (no spots to keep centred). */
START_TEST(test_stage_refusals)
{
    const struct { const char *a, *b, *word; } bad[] = {
        {"lgs.wfs.focus_stage=true", NULL, "recon.lgs_focus_removal"},
        {"lgs.wfs.focus_stage=true", "recon.lgs_focus_removal=true", "lgs.sodium_sequence"},
        {"lgs.wfs.focus_stage_gain=0.5", "recon.lgs_focus_removal=true", "no stage"},
        {"lgs.wfs.focus_stage_gain=0.0", "lgs.wfs.focus_stage=true", "lgs.wfs.focus_stage_gain"},
        {"lgs.wfs.focus_stage_gain=1.5", "lgs.wfs.focus_stage=true", "lgs.wfs.focus_stage_gain"},
        {"lgs.wfs.model=\"geometric\"", "lgs.wfs.focus_stage=true", "diffractive"},
    };
    wt_context *ctx = tu_context();
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        const char *set[3] = {bad[i].a, bad[i].b, "recon.lgs_focus_removal=true"};
        const int n = !bad[i].b ? 1 : i >= 3 ? 3 : 2;
        wt_config *cfg = NULL;
        ck_assert_int_eq(wt_config_read(ctx, DDEMO, n, set, &cfg), WT_ERR_CONFIG);
        ck_assert_msg(strstr(wt_error_message(ctx), bad[i].word), "case %zu: %s", i, wt_error_message(ctx));
    }
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("focus_stage");
    TCase *tc = tcase_create("LGS focus stage");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_stage_follows_the_drift);
    tcase_add_test(tc, test_stage_refusals);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
