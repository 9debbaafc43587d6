/* tests/test_adapt.c: the loop that learns its atmosphere (sim/adapt.h, SPEC §12 "Updates"): a learned run
 * that starts from the truth's profile is the oracle's run, bit for bit, until its first estimate, which it uses
 * from the next frame on; a learning MVM loop applies its old matrix until the new one's build latency has passed
 * (bit for bit the never-rebuilt loop's frames), then the new one; too few frames per estimate, a reconstructor
 * that cannot learn and an MVM without its rebuild are refused. */
#include "builder/mvm_build.h"
#include "core/model/profile.h"
#include "core/model/system.h"
#include "core/io/h5.h"
#include "compare/compare.h"
#include "sim/loop.h"

#include <unistd.h>
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
#define N(a) ((int)(sizeof a / sizeof *a))

/* the demo's own truth as the start model (recon.atmosphere.* of a learned source), estimates every 100 frames */
#define START_TRUTH                                                                                                     \
    "recon.atmosphere.r0_m=0.129", "recon.atmosphere.L0_m=25.0",                                                     \
        "recon.atmosphere.altitudes_m=[0.0, 600.0, 2000.0, 6000.0, 12000.0]",                                        \
        "recon.atmosphere.cn2_fractions=[0.55, 0.1, 0.1, 0.15, 0.1]",                                                \
        "recon.atmosphere.wind_speed_mps=[8.0, 10.0, 12.0, 18.0, 25.0]",                                             \
        "recon.atmosphere.wind_direction_deg=[0.0, 72.0, 144.0, 216.0, 288.0]"
#define START_WRONG                                                                                                     \
    "recon.atmosphere.r0_m=0.2", "recon.atmosphere.L0_m=25.0", "recon.atmosphere.altitudes_m=[0.0, 10000.0]",       \
        "recon.atmosphere.cn2_fractions=[0.9, 0.1]", "recon.atmosphere.wind_speed_mps=[8.0, 20.0]",                  \
        "recon.atmosphere.wind_direction_deg=[0.0, 90.0]"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_loop *lp;
    wt_mvm *mvm;
    wt_mvm_rebuilder rb;
} run;

static int open_run(run *r, int recon, int nset, const char *const *set, int with_rebuild)
{
    memset(r, 0, sizeof *r);
    r->ctx = tu_context();
    ck_assert_msg(wt_config_read(r->ctx, DEMO, nset, set, &r->cfg) == WT_OK, "%s", wt_error_message(r->ctx));
    ck_assert_msg(wt_system_alloc(r->ctx, r->cfg, &r->sys) == WT_OK, "%s", wt_error_message(r->ctx));
    wt_loop_options o = {.recon = recon, .iterations = -1, .seed = r->cfg->seed, .noise = r->cfg->noise};
    if (recon == WT_RECON_MVM) {
        ck_assert_msg(wt_mvm_build_variant(r->ctx, r->sys, r->cfg, "pcg3", NULL, &r->mvm) == WT_OK, "%s",
                      wt_error_message(r->ctx));
        o.mvm = r->mvm;
        r->rb = (wt_mvm_rebuilder){r->ctx, r->sys, "pcg3", NULL};
        if (with_rebuild) o.rebuild = wt_mvm_rebuild_model, o.rebuild_user = &r->rb;
    }
    return wt_loop_alloc(r->ctx, r->sys, &o, &r->lp);
}

static void close_run(run *r)
{
    wt_loop_free(r->lp);
    wt_mvm_free(r->mvm);
    wt_system_free(r->sys);
    wt_config_free(r->ctx, r->cfg);
    wt_context_free(r->ctx);
}

static int same_frame(const run *a, const run *b)
{
    return !memcmp(wt_loop_rms(a->lp), wt_loop_rms(b->lp), (size_t)a->sys->neval * sizeof(double));
}

START_TEST(t_learned_start_equals_oracle)
{
    const char *oracle[] = {"loop.frames=110"};
    const char *learned[] = {"loop.frames=110", "recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.2",
                             START_TRUTH};
    run o, l;
    ck_assert_int_eq(open_run(&o, WT_RECON_PCG3, N(oracle), oracle, 0), WT_OK);
    ck_assert_msg(open_run(&l, WT_RECON_PCG3, N(learned), learned, 0) == WT_OK, "%s", wt_error_message(l.ctx));
    ck_assert_ptr_null(wt_loop_adapt(o.lp));
    ck_assert_ptr_nonnull(wt_loop_adapt(l.lp));
    int differ = 0;
    for (int t = 0; t < 110; t++) {
        ck_assert_int_eq(wt_loop_step(o.lp), WT_OK);
        ck_assert_msg(wt_loop_step(l.lp) == WT_OK, "%s", wt_error_message(l.ctx));
        /* the estimate after frame 99 is used from frame 100 on: its commands reach the DMs 2 frames later */
        if (t < 102) ck_assert_msg(same_frame(&o, &l), "frame %d differs before the first estimate is applied", t);
        else differ += !same_frame(&o, &l);
    }
    ck_assert_int_gt(differ, 0);
    const wt_adapt *a = wt_loop_adapt(l.lp);
    ck_assert_int_eq(wt_adapt_nupdates(a), 1);
    const wt_adapt_update *u = wt_adapt_updates(a);
    ck_assert_int_eq(u[0].frame, 99);
    ck_assert_int_eq(u[0].applied_frame, 100);
    ck_assert_double_eq_tol(u[0].night, 0.2, 1e-12);
    /* 100 frames (0.2 s, the ground layer moves 1.6 m): an estimate of r0 within a factor 1.5 of the truth */
    ck_assert_msg(u[0].r0 > 0.129 / 1.5 && u[0].r0 < 0.129 * 1.5, "r0 %g", u[0].r0);
    double sum = 0.0;
    for (int k = 0; k < u[0].nalt; k++) sum += u[0].fraction[k];
    ck_assert_double_eq_tol(sum, 1.0, 1e-12);
    close_run(&o);
    close_run(&l);
}
END_TEST

/* the memory: the model's total Cn² r0^(−5/3) is the exponential average of the estimates' (weight 1/3 on the
 * newest), to rounding */
START_TEST(t_learned_memory)
{
    const char *set[] = {"loop.frames=200", "recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.2",
                         "recon.atmosphere.learn_memory=3.0", START_WRONG};
    run r;
    ck_assert_msg(open_run(&r, WT_RECON_PCG3, N(set), set, 0) == WT_OK, "%s", wt_error_message(r.ctx));
    for (int t = 0; t < 200; t++) ck_assert_msg(wt_loop_step(r.lp) == WT_OK, "%s", wt_error_message(r.ctx));
    const wt_adapt_update *u = wt_adapt_updates(wt_loop_adapt(r.lp));
    ck_assert_int_eq(wt_adapt_nupdates(wt_loop_adapt(r.lp)), 2);
    ck_assert_double_eq(u[0].r0, u[0].r0_raw);
    const double c = (2.0 / 3.0) * pow(u[0].r0_raw, -5.0 / 3.0) + (1.0 / 3.0) * pow(u[1].r0_raw, -5.0 / 3.0);
    ck_assert_double_eq_tol(u[1].r0, pow(c, -3.0 / 5.0), 1e-12 * u[1].r0);
    double sum = 0.0;
    for (int k = 0; k < u[1].nalt; k++) sum += u[1].fraction[k];
    ck_assert_double_eq_tol(sum, 1.0, 1e-12);
    close_run(&r);
}
END_TEST

/* mvm: the estimate after frame 99 (night 0.2 s) is built and in the loop 0.1 s later: frame 150 */
START_TEST(t_mvm_swap_after_latency)
{
    const char *given[] = {"loop.frames=160", "recon.atmosphere.source=\"given\"", START_WRONG};
    const char *learned[] = {"loop.frames=160", "recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.2",
                             "recon.atmosphere.mvm_latency_s=0.1", START_WRONG};
    run g, l;
    ck_assert_msg(open_run(&g, WT_RECON_MVM, N(given), given, 0) == WT_OK, "%s", wt_error_message(g.ctx));
    ck_assert_msg(open_run(&l, WT_RECON_MVM, N(learned), learned, 1) == WT_OK, "%s", wt_error_message(l.ctx));
    const wt_reconstructor *first = wt_loop_reconstructor(l.lp);
    int differ = 0;
    for (int t = 0; t < 160; t++) {
        ck_assert(wt_loop_reconstructor(l.lp) == first || t > 150);
        ck_assert_int_eq(wt_loop_step(g.lp), WT_OK);
        ck_assert_msg(wt_loop_step(l.lp) == WT_OK, "%s", wt_error_message(l.ctx));
        /* the old matrix until frame 149; the new one's commands reach the DMs from frame 152 */
        if (t < 152) ck_assert_msg(same_frame(&g, &l), "frame %d differs while the old matrix is applied", t);
        else differ += !same_frame(&g, &l);
    }
    ck_assert_int_gt(differ, 0);
    ck_assert(wt_loop_reconstructor(l.lp) != first);
    const wt_adapt_update *u = wt_adapt_updates(wt_loop_adapt(l.lp));
    ck_assert_int_eq(wt_adapt_nupdates(wt_loop_adapt(l.lp)), 1);
    ck_assert_int_eq(u[0].applied_frame, 150);
    ck_assert_double_gt(u[0].build_s, 0.0);
    close_run(&g);
    close_run(&l);
}
END_TEST

/* A learning MVM takes an estimate as PCG-3 does (core/model/profile.h): the grid's hats compressed onto its layers.
 * The matrix rebuilt from a sampled grid profile is, bit for bit, the one built from that profile's hat compression
 * at the layers' altitudes, and not the one of the grid's points (which send all of 0 km's Cn² to the 0 km layer). */
START_TEST(t_mvm_rebuild_hats)
{
    run r;
    const char *none[] = {"loop.frames=30"};
    ck_assert_msg(open_run(&r, WT_RECON_MVM, N(none), none, 1) == WT_OK, "%s", wt_error_message(r.ctx));
    const double grid[] = {0.0, 1000.0, 2000.0, 3000.0, 5000.0, 8000.0, 12000.0, 16000.0};
    const double frac[] = {0.40, 0.20, 0.05, 0.05, 0.10, 0.05, 0.10, 0.05};
    const int n = N(grid), L = r.cfg->pcg3.nlayers;
    double hats[WT_MAX_LAYERS];
    wt_profile_compress_hats(n, grid, frac, NULL, NULL, L, r.cfg->pcg3.altitudes, hats, NULL, NULL);
    wt_mvm *m[3] = {NULL, NULL, NULL};
    ck_assert_msg(wt_mvm_rebuild_model(&r.rb, 0.15, n, grid, frac, NULL, NULL, 1, &m[0]) == WT_OK, "%s", wt_error_message(r.ctx));
    ck_assert_int_eq(wt_mvm_rebuild_model(&r.rb, 0.15, L, r.cfg->pcg3.altitudes, hats, NULL, NULL, 0, &m[1]), WT_OK);
    ck_assert_int_eq(wt_mvm_rebuild_model(&r.rb, 0.15, n, grid, frac, NULL, NULL, 0, &m[2]), WT_OK);
    const int64_t ns = m[0]->nslopes, na = m[0]->nact;
    float *s = malloc((size_t)ns * sizeof *s), *y[3];
    for (int64_t j = 0; j < ns; j++) s[j] = (float)sin(0.37 * (double)j + 0.1);
    for (int k = 0; k < 3; k++) {
        y[k] = malloc((size_t)na * sizeof *y[k]);
        wt_mvm_apply(m[k], s, NULL, y[k]);
    }
    ck_assert_msg(!memcmp(y[0], y[1], (size_t)na * sizeof(float)), "sampled rebuild != rebuild from its hats");
    double d = 0.0, n1 = 0.0;
    for (int64_t i = 0; i < na; i++) d += pow(y[0][i] - y[2][i], 2), n1 += pow(y[1][i], 2);
    /* the hats move 1/6 of the 1 km point's Cn² below 0.5 km, a visible change of the ground/4 km split */
    ck_assert_msg(d > 1e-6 * n1, "hats and points gave the same matrix (rel. diff %g)", sqrt(d / n1));
    for (int k = 0; k < 3; k++) free(y[k]), wt_mvm_free(m[k]);
    free(s);
    close_run(&r);
}
END_TEST

/* the oracle in a changing night takes the truth's state every `every` frames (demo-night: 6 s of night a frame, an
 * update every 60 s = 10 frames), pcg3 at the next frame */
START_TEST(t_oracle_follows_night)
{
    const char *set[] = {"loop.frames=35", "atmosphere.night.source=\"file\"",
                         "atmosphere.night.file=\"../nights/demo-ground-doubling.txt\"",
                         "atmosphere.night.compression=3000.0"};
    run r;
    ck_assert_msg(open_run(&r, WT_RECON_PCG3, N(set), set, 0) == WT_OK, "%s", wt_error_message(r.ctx));
    const wt_adapt *a = wt_loop_adapt(r.lp);
    ck_assert_ptr_nonnull(a);
    ck_assert(wt_adapt_follows_truth(a));
    double r0[35], f0[35];
    for (int t = 0; t < 35; t++) {
        ck_assert_msg(wt_loop_step(r.lp) == WT_OK, "%s", wt_error_message(r.ctx));
        wt_night_sample s;
        ck_assert(wt_loop_truth_state(r.lp, &s));
        r0[t] = s.r0, f0[t] = s.fraction[0];
    }
    ck_assert_int_eq(wt_adapt_nupdates(a), 3);
    const wt_adapt_update *u = wt_adapt_updates(a);
    for (int k = 0; k < 3; k++) {
        ck_assert_int_eq(u[k].frame, 10 * k + 9);
        ck_assert_int_eq(u[k].applied_frame, 10 * k + 10);
        ck_assert_double_eq(u[k].r0, r0[10 * k + 9]);
        ck_assert_double_eq(u[k].fraction[0], f0[10 * k + 9]);
        ck_assert_double_eq_tol(u[k].night, (10 * k + 10) * 6.0, 1e-9);
    }
    ck_assert_double_lt(u[2].r0, u[0].r0); /* (the night's r0 falls) */
    close_run(&r);
}
END_TEST

/* compare's case keeps the loop's record of updates (wt_compare_series.learned): the sim loop's own, bit for bit, and
 * written under a case's group as sim writes it; with learn_grid = layers the learning grid holds pcg3's layer at
 * 12.7 km */
START_TEST(t_compare_keeps_record)
{
    const char *set[] = {"loop.frames=110", "recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.2",
                         "recon.atmosphere.learn_grid=\"layers\"", START_WRONG};
    run r;
    ck_assert_msg(open_run(&r, WT_RECON_PCG3, N(set), set, 0) == WT_OK, "%s", wt_error_message(r.ctx));
    for (int t = 0; t < 110; t++) ck_assert_msg(wt_loop_step(r.lp) == WT_OK, "%s", wt_error_message(r.ctx));
    const wt_adapt_update *u = wt_adapt_updates(wt_loop_adapt(r.lp));
    ck_assert_int_eq(wt_adapt_nupdates(wt_loop_adapt(r.lp)), 1);
    int has = 0;
    for (int k = 0; k < u[0].nalt; k++) has += u[0].altitude[k] == 12700.0;
    ck_assert_int_eq(has, 1);
    double *wfe = malloc(110 * sizeof *wfe);
    wt_compare_series ser = {.wfe = wfe};
    wt_compare_result res;
    ck_assert_msg(wt_compare_run(r.ctx, r.sys, WT_RECON_PCG3, NULL, 0.0, r.cfg->seed, NULL, NULL, &res, &ser) == WT_OK,
                  "%s", wt_error_message(r.ctx));
    ck_assert_ptr_nonnull(ser.learned);
    ck_assert_int_eq(wt_adapt_nupdates(ser.learned), 1);
    const wt_adapt_update *c = wt_adapt_updates(ser.learned);
    ck_assert_int_eq(c[0].frame, u[0].frame);
    ck_assert_int_eq(c[0].nalt, u[0].nalt);
    ck_assert_double_eq(c[0].r0, u[0].r0);
    ck_assert_int_eq(memcmp(c[0].fraction, u[0].fraction, (size_t)u[0].nalt * sizeof *u[0].fraction), 0);
    char path[] = "/tmp/wt-test-adapt-XXXXXX";
    const int fd = mkstemp(path);
    ck_assert_int_ge(fd, 0);
    close(fd);
    wt_h5_writer *w = NULL;
    ck_assert_int_eq(wt_h5_create(r.ctx, path, &w), WT_OK);
    ck_assert_msg(wt_adapt_write(ser.learned, w, "learned/pcg3_0/seed0") == WT_OK, "%s", wt_error_message(r.ctx));
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    wt_h5_reader *h = NULL;
    ck_assert_int_eq(wt_h5_open(r.ctx, path, &h), WT_OK);
    double r0 = 0.0;
    const int64_t one[1] = {1};
    ck_assert_msg(wt_h5_read(h, "learned/pcg3_0/seed0/r0", WT_H5_F64, 1, one, NULL, &r0, 1) == WT_OK, "%s",
                  wt_error_message(r.ctx));
    ck_assert_double_eq(r0, u[0].r0);
    wt_h5_close(h);
    remove(path);
    wt_adapt_free(ser.learned);
    wt_free(r.ctx, ser.psf); /* (sim.psf_interval_frames defaults to 10: the run keeps PSFs) */
    free(wfe);
    close_run(&r);
}
END_TEST

/* learn_wind = aligned: each of PCG-3's layers gets a wind estimated on its own estimates at every update (recorded
 * with its uncertainty), the reconstructor predicts with exactly that wind, and its ground layer (what it absorbs
 * moves at 6.3 m/s towards 16°, the Cn²-weighted mean) moves the right way: within 45° of 0° (a loose bound: 100
 * frames of a 16-point footprint; docs/results.md §45 has the accuracy) */
START_TEST(t_learned_wind)
{
    const char *set[] = {"loop.frames=200", "recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.2",
                         "recon.atmosphere.learn_wind=\"aligned\"", "recon.predict=true", START_WRONG};
    run r;
    ck_assert_msg(open_run(&r, WT_RECON_PCG3, N(set), set, 0) == WT_OK, "%s", wt_error_message(r.ctx));
    for (int t = 0; t < 200; t++) ck_assert_msg(wt_loop_step(r.lp) == WT_OK, "%s", wt_error_message(r.ctx));
    const wt_adapt_update *u = wt_adapt_updates(wt_loop_adapt(r.lp));
    ck_assert_int_eq(wt_adapt_nupdates(wt_loop_adapt(r.lp)), 2);
    double vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS];
    wt_reconstructor_layer_wind(wt_loop_reconstructor(r.lp), vx, vy);
    for (int k = 0; k < 2; k++) {
        ck_assert_int_eq(u[k].nwind, 3);
        ck_assert_int_eq(u[k].wind_valid[0], 1);
        ck_assert(u[k].wind_sx[0] > 0.0 && u[k].wind_sy[0] > 0.0);
        ck_assert_msg(fabs(atan2(u[k].wind_vy[0], u[k].wind_vx[0])) < M_PI / 4, "ground layer's wind (%g, %g) m/s",
                      u[k].wind_vx[0], u[k].wind_vy[0]);
    }
    for (int l = 0; l < 3; l++) {
        ck_assert_double_eq(vx[l], u[1].wind_vx[l]);
        ck_assert_double_eq(vy[l], u[1].wind_vy[l]);
    }
    close_run(&r);
}
END_TEST

START_TEST(t_refusals)
{
    run r;
    /* 0.1 s at 500 Hz: 50 frames, fewer than an estimate needs */
    const char *few[] = {"recon.atmosphere.source=\"learned\"", "recon.atmosphere.update_s=0.1", START_WRONG};
    ck_assert_int_eq(open_run(&r, WT_RECON_PCG3, N(few), few, 0), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(r.ctx), "'recon.atmosphere.update_s'") &&
                      strstr(wt_error_message(r.ctx), "every 50 frames"), "%s", wt_error_message(r.ctx));
    close_run(&r);
    const char *ok[] = {"recon.atmosphere.source=\"learned\"", START_WRONG};
    ck_assert_int_eq(open_run(&r, WT_RECON_NONE, N(ok), ok, 0), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(r.ctx), "not none"));
    close_run(&r);
    ck_assert_int_eq(open_run(&r, WT_RECON_MVM, N(ok), ok, 0), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(r.ctx), "rebuild"));
    close_run(&r);
    const char *aligned[] = {"recon.atmosphere.source=\"learned\"", "recon.atmosphere.learn_wind=\"aligned\"",
                             START_WRONG};
    ck_assert_int_eq(open_run(&r, WT_RECON_MVM, N(aligned), aligned, 1), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(r.ctx), "'recon.atmosphere.learn_wind'") &&
                      strstr(wt_error_message(r.ctx), "not mvm"), "%s", wt_error_message(r.ctx));
    close_run(&r);
    const char *oracle[] = {"recon.atmosphere.learn_wind=\"aligned\""};
    {
        wt_context *ctx = tu_context();
        wt_config *cfg = NULL;
        ck_assert_int_eq(wt_config_read(ctx, DEMO, 1, oracle, &cfg), WT_ERR_CONFIG);
        ck_assert_msg(strstr(wt_error_message(ctx), "learn_wind"), "%s", wt_error_message(ctx));
        wt_context_free(ctx);
    }
    const char *one_lgs[] = {"recon.atmosphere.source=\"learned\"", "lgs.count=1", START_WRONG};
    if (open_run(&r, WT_RECON_PCG3, N(one_lgs), one_lgs, 0) != WT_OK)
        ck_assert_ptr_nonnull(strstr(wt_error_message(r.ctx), "at least 2 LGS"));
    else
        ck_abort_msg("a learned model with 1 LGS was accepted");
    close_run(&r);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("adapt");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, t_learned_start_equals_oracle);
    tcase_add_test(tc, t_mvm_swap_after_latency);
    tcase_add_test(tc, t_mvm_rebuild_hats);
    tcase_add_test(tc, t_oracle_follows_night);
    tcase_add_test(tc, t_learned_memory);
    tcase_add_test(tc, t_learned_wind);
    tcase_add_test(tc, t_refusals);
    tcase_add_test(tc, t_compare_keeps_record);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
