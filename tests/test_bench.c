/* tests/test_bench.c: the paired mode of compare/bench.h (issue 20 §5): both sides see the same slopes
 * (two identical configurations give the same commands, bit for bit), the per-pair ratios are summarised
 * like the timings, two systems of different sizes are paired without comparing commands, and bad
 * arguments are refused; the single-configuration run's frame profile counts the stages a frame runs. Timings are not checked against values: the host decides them. */
#include "core/model/params.h"
#include "compare/bench.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg[2];
    wt_system *sys[2];
    wt_reconstructor_params par[2];
} fixture;

static void setup(fixture *f, int kind, const char *a, const char *b)
{
    f->ctx = tu_context();
    const char *set[2] = {a, b};
    for (int k = 0; k < 2; k++) {
        ck_assert_msg(wt_config_read(f->ctx, DEMO, set[k] ? 1 : 0, &set[k], &f->cfg[k]) == WT_OK, "%s",
                      wt_error_message(f->ctx));
        ck_assert_msg(wt_system_alloc(f->ctx, f->cfg[k], &f->sys[k]) == WT_OK, "%s", wt_error_message(f->ctx));
        wt_reconstructor_params_from_config(f->cfg[k], kind, -1, &f->par[k]);
    }
}

static void teardown(fixture *f)
{
    for (int k = 0; k < 2; k++) {
        wt_system_free(f->sys[k]);
        wt_config_free(f->ctx, f->cfg[k]);
    }
    wt_context_free(f->ctx);
}

static void check_stats(const wt_bench_stats *s, int positive)
{
    ck_assert(s->p10 <= s->med && s->med <= s->p90 && s->p90 <= s->p99);
    if (positive) ck_assert_double_gt(s->p10, 0.0);
}

START_TEST(test_same_configuration_same_commands)
{
    fixture f;
    setup(&f, WT_RECON_CG9, NULL, NULL);
    const wt_system *const sys[2] = {f.sys[0], f.sys[1]};
    wt_bench_pair b;
    ck_assert_msg(wt_bench_pair_run(f.ctx, sys, f.par, WT_RECON_CG9, 2, 7, &b) == WT_OK, "%s", wt_error_message(f.ctx));
    /* the same slopes and the same deterministic reconstructor: the same bits */
    ck_assert_double_eq(b.command_diff, 0.0);
    for (int k = 0; k < 2; k++) {
        check_stats(&b.frame[k], 1);
        check_stats(&b.tomography[k], 1);
        check_stats(&b.fitting[k], 1);
        ck_assert_double_gt(b.setup[k], 0.0);
        ck_assert_double_gt(b.memory[k], 0.0);
        /* every frame holds its two parts, so every order statistic of the frames dominates theirs */
        ck_assert_double_ge(b.frame[k].med, fmax(b.tomography[k].med, b.fitting[k].med));
        ck_assert_double_ge(b.frame[k].p90, fmax(b.tomography[k].p90, b.fitting[k].p90));
        /* each side's profile covers its timed frames only (not the warm ones), one solve each, and the same
         * counts on both sides (the same configuration) */
        ck_assert_int_eq(b.stage[k][WT_TOMO_STAGE_SOLVE].calls, 7);
        for (int g = 0; g < WT_TOMO_NSTAGES; g++) ck_assert_int_eq(b.stage[k][g].calls, b.stage[0][g].calls);
        ck_assert_int_gt(b.stage[k][WT_TOMO_STAGE_ADJOINT_SENSORS].calls, 7);
    }
    check_stats(&b.ratio_frame, 1);
    check_stats(&b.ratio_tomography, 1);
    check_stats(&b.ratio_fitting, 1);
    teardown(&f);
}
END_TEST

START_TEST(test_different_configurations)
{
    /* different preconditioners on one system: the commands differ (4 iterations do not converge) */
    fixture f;
    setup(&f, WT_RECON_PCG3, "recon.pcg3.preconditioner=\"jacobi\"", "recon.pcg3.preconditioner=\"coarse_ngs\"");
    const wt_system *const sys[2] = {f.sys[0], f.sys[1]};
    wt_bench_pair b;
    ck_assert_int_eq(wt_bench_pair_run(f.ctx, sys, f.par, WT_RECON_PCG3, 0, 4, &b), WT_OK);
    ck_assert_double_gt(b.command_diff, 1e-6);
    ck_assert_double_eq(b.fitting[0].med, 0.0); /* pcg3 has no fitting */
    teardown(&f);
    /* two systems of different sizes: timed side by side, commands not compared */
    setup(&f, WT_RECON_PCG3, NULL, "lgs.wfs.subapertures=8");
    ck_assert_int_ne(f.sys[0]->nslopes, f.sys[1]->nslopes);
    const wt_system *const sys2[2] = {f.sys[0], f.sys[1]};
    ck_assert_int_eq(wt_bench_pair_run(f.ctx, sys2, f.par, WT_RECON_PCG3, 1, 3, &b), WT_OK);
    ck_assert_double_eq(b.command_diff, -1.0);
    teardown(&f);
}
END_TEST

/* The frame profile of wt_bench_tomography_run: its frames continue the previous solve (no apply of M for the
 * initial residual), so a k-iteration frame applies M k times, the adjoint k + 1 times (the right-hand side) and
 * the preconditioner k times (z₀ and one per iteration but the last); the stages and the preconditioner's share
 * never exceed the frames that hold them. */
START_TEST(test_frame_profile)
{
    fixture f;
    setup(&f, WT_RECON_PCG3, NULL, NULL);
    wt_bench_tomography b;
    const int reps = 3, k = f.par[0].iterations;
    ck_assert_int_eq(wt_bench_tomography_run(f.ctx, f.sys[0], &f.par[0], "pcg3", reps, &b), WT_OK);
    ck_assert_int_eq(b.prof_frames, reps);
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_INVERSE_DWT].calls, reps * k);
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_FORWARD].calls, reps * k);
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_ADJOINT_SENSORS].calls, reps * (k + 1));
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_ADJOINT_LAYERS].calls, reps * (k + 1));
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_PRECOND].calls, reps * k);
    ck_assert_int_eq(b.stage[WT_TOMO_STAGE_SOLVE].calls, reps);
    double sum = 0.0;
    for (int g = 0; g < WT_TOMO_STAGE_SOLVE; g++) sum += b.stage[g].wall;
    ck_assert_msg(sum <= b.stage[WT_TOMO_STAGE_SOLVE].wall, "stages %g s > their frames %g s", sum,
                  b.stage[WT_TOMO_STAGE_SOLVE].wall);
    teardown(&f);
}
END_TEST

START_TEST(test_refusals)
{
    fixture f;
    setup(&f, WT_RECON_PCG3, NULL, NULL);
    const wt_system *const sys[2] = {f.sys[0], f.sys[1]};
    wt_bench_pair b;
    ck_assert_int_eq(wt_bench_pair_run(f.ctx, sys, f.par, WT_RECON_NONE, 1, 3, &b), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "pcg3 or cg9"));
    ck_assert_int_eq(wt_bench_pair_run(f.ctx, sys, f.par, WT_RECON_PCG3, 1, 0, &b), WT_ERR_INVALID);
    ck_assert_int_eq(wt_bench_pair_run(f.ctx, sys, f.par, WT_RECON_PCG3, -1, 3, &b), WT_ERR_INVALID);
    teardown(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("bench");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_same_configuration_same_commands);
    tcase_add_test(tc, test_different_configurations);
    tcase_add_test(tc, test_refusals);
    tcase_add_test(tc, test_frame_profile);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
