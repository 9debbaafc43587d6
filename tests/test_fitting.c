/* tests/test_fitting.c: the DM fitting step (paper eq. fit_step_min, SPEC §5; core/model/fitting.h):
 * its regularisation ε is the stated fraction of the true mean diagonal of Σ_j H_jᵀ H_j (the probing
 * that computes it must not let two probes share a sample point), and a shape the DMs can make is
 * fitted exactly, on both the Fried-corner and the finer pupil sampling. */
#include "core/model/fitting.h"
#include "core/model/params.h"
#include "core/model/system.h"
#include "testmodel.h"
#include "testutil.h"

/* ε against the brute-force diagonal: F e_i = (Σ H_jᵀ H_j + ε I) e_i, so F_ii − ε is the diagonal. */
static void check_epsilon(int sampling)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_fitting *fit;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    const double reg = 1e-3;
    const wt_fitting_params fp = {.regularization = reg, .sampling = sampling};
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    const int64_t na = sys->nact;
    const double eps = wt_fitting_epsilon(fit);
    double *e = calloc(na, sizeof *e), *y = malloc(na * sizeof *y), sum = 0.0;
    for (int64_t i = 0; i < na; i++) {
        e[i] = 1.0;
        tu_fitting_apply(fit, na, e, y);
        e[i] = 0.0;
        sum += y[i] - eps; /* a guard-ring actuator may see no sample point: 0, and ε holds it */
    }
    /* the same sums in another order: rounding only */
    ck_assert_rel(eps, reg * sum / (double)na, 1e-12, 0.0);
    free(e), free(y);
    wt_fitting_free(fit);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}

START_TEST(test_epsilon_fried) { check_epsilon(1); }
END_TEST

START_TEST(test_epsilon_pupil_grid) { check_epsilon(2); }
END_TEST

/* maps_j = H_j a0 for random commands a0: the DMs can make them exactly, so the fit must reproduce
 * them in every direction (to the bias of a tiny ε and the CG tolerance). */
START_TEST(test_representable_maps)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_fitting *fit;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    const wt_fitting_params fp = {.regularization = 1e-10, .sampling = 2};
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    const wt_grid *sg = wt_fitting_sample_grid(fit);
    const uint8_t *mask = wt_fitting_sample_mask(fit);
    const int64_t na = sys->nact, np = wt_grid_size(sg), nd = wt_dm_grid_points(sys->dm);
    double *a0 = malloc(na * sizeof *a0), *a = calloc(na, sizeof *a), *g0 = calloc(nd, sizeof *g0),
           *g1 = calloc(nd, sizeof *g1), *maps = calloc((size_t)sys->neval * np, sizeof *maps),
           *m1 = calloc(np, sizeof *m1);
    tu_randn(a0, na, 7);
    wt_dm_expand(sys->dm, a0, g0);
    wt_projection *h[WT_MAX_EVAL];
    for (int j = 0; j < sys->neval; j++) {
        ck_assert_int_eq(wt_dm_influence_alloc(ctx, sys->dm, 0.0, sys->eval_x[j], sys->eval_y[j], sg, mask, &h[j]),
                         WT_OK);
        wt_projection_apply(h[j], 1.0, g0, maps + (size_t)j * np);
    }
    wt_pcg_result r;
    ck_assert_int_ge(wt_fitting_solve_maps(fit, maps, a, 3000, 1e-13, &r), WT_OK);
    wt_dm_expand(sys->dm, a, g1);
    double worst = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        memset(m1, 0, np * sizeof *m1);
        wt_projection_apply(h[j], 1.0, g1, m1);
        worst = fmax(worst, tu_rel_diff(m1, maps + (size_t)j * np, np));
        wt_projection_free(h[j]);
    }
    /* ε = 1e-10 of the mean diagonal biases the fit by O(1e-10 κ); CG stops at 1e-13 of ‖b‖ */
    ck_assert_msg(worst < 1e-6, "fitted DM phase differs from the representable target by %g (%d iterations)", worst,
                  r.iterations);
    free(a0), free(a), free(g0), free(g1), free(maps), free(m1);
    wt_fitting_free(fit);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The model operators accumulate like core/op's: y ← y + α A x leaves y's old value in (fitting F,
 * tomography M, Ã and the right-hand side). */
START_TEST(test_operators_accumulate)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_fitting *fit;
    wt_tomography *t;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    const wt_fitting_params fp = {.regularization = 1e-3, .sampling = 1};
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_OK);
    const int64_t na = sys->nact, n = wt_tomography_nunknowns(t), ns = sys->nslopes, big = n > ns ? n : ns;
    double *x = malloc(big * sizeof *x), *y0 = malloc(big * sizeof *y0), *ax = malloc(big * sizeof *ax),
           *y = malloc(big * sizeof *y);
    tu_randn(x, big, 11);
    tu_randn(y0, big, 12);
    /* fitting: y0 − 0.5 F x */
    tu_fitting_apply(fit, na, x, ax);
    memcpy(y, y0, na * sizeof *y);
    wt_fitting_apply(fit, -0.5, x, y);
    for (int64_t i = 0; i < na; i++) ck_assert_double_eq(y[i], y0[i] + -0.5 * ax[i]);
    /* tomography M, Ã, rhs */
    tu_tomo_apply(t, x, ax);
    memcpy(y, y0, n * sizeof *y);
    wt_tomography_apply(t, 2.0, x, y);
    for (int64_t i = 0; i < n; i++) ck_assert_double_eq(y[i], y0[i] + 2.0 * ax[i]);
    tu_tomo_slopes(t, x, ax);
    memcpy(y, y0, ns * sizeof *y);
    wt_tomography_slopes(t, 3.0, x, y);
    for (int64_t i = 0; i < ns; i++) ck_assert_double_eq_tol(y[i], y0[i] + 3.0 * ax[i], 1e-12 * (fabs(y0[i]) + 3.0 * fabs(ax[i])));
    tu_tomo_rhs(t, x, ax);
    memcpy(y, y0, n * sizeof *y);
    wt_tomography_rhs(t, 1.0, x, y);
    for (int64_t i = 0; i < n; i++) ck_assert_double_eq(y[i], y0[i] + ax[i]);
    free(x), free(y0), free(ax), free(y);
    wt_tomography_free(t);
    wt_fitting_free(fit);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("fitting");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_epsilon_fried);
    tcase_add_test(tc, test_epsilon_pupil_grid);
    tcase_add_test(tc, test_representable_maps);
    tcase_add_test(tc, test_operators_accumulate);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
