/* tests/test_estimate.c: the resource estimate counts what it is asked to run (core/model/estimate.h): a (P)CG
 * iteration override (`sim --iters`, `run --iters`) enters its run time linearly, as the flops per iteration say,
 * and ≤ 0 means the configuration's own count. */
#include "testutil.h"

#include "core/model/estimate.h"
#include "core/model/reconstructor.h"

#define DEMO "data/presets/demo.cfg"

START_TEST(t_iterations_counted)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    ck_assert_msg(wt_config_read(ctx, DEMO, 0, NULL, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9; kind++) {
        const int own = kind == WT_RECON_CG9 ? cfg->cg9.iterations : cfg->pcg3.iterations;
        double t[4];
        const int iters[4] = {0, own, 1000 + own, 2000 + own};
        for (int k = 0; k < 4; k++) {
            wt_estimate e;
            wt_estimate_resources(cfg, &(wt_estimate_request){.task = WT_TASK_SIM, .recon = kind, .frames = 100,
                                                              .iterations = iters[k]},
                                  &e);
            t[k] = e.seconds;
        }
        ck_assert_double_eq(t[0], t[1]); /* ≤ 0: the variant's own count */
        ck_assert_double_gt(t[2], t[1]);
        /* linear in the iterations: equal steps of 1000 add equal time (to the rounding of the sums) */
        ck_assert_msg(fabs((t[3] - t[2]) / (t[2] - t[1]) - 1.0) < 1e-9, "%s: %g, %g, %g s", wt_reconstructor_name(kind),
                      t[1], t[2], t[3]);
    }
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("estimate");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, t_iterations_counted);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
