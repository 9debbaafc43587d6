/* tests/test_wind_align.c: the wind of a layer from its aligned estimates (core/model/wind_align.h). A periodic von
 * Kármán layer in frozen flow, moved every frame by the project's exact Fourier shift (core/op/shift.h), gives its wind
 * to rounding (the estimator has no bias for a pure shift: tolerance 0.5 m/s, the issue's, and 2° in direction); two
 * layers on two grids each get their own; a layer seen through a footprint (a disc, as the reconstruction's layers
 * are) within 0.5 m/s; independent noise frames give no wind, or one within its stated uncertainty; bad parameters
 * and too few snapshots are refused with a message. */
#include "testutil.h"

#include "frozen_flow.h"

static void check_wind(const wt_wind_estimate *e, double vx, double vy, double tol, double tol_deg)
{
    ck_assert_int_eq(e->valid, 1);
    const double err = hypot(e->vx - vx, e->vy - vy);
    double dang = fabs(atan2(e->vy, e->vx) - atan2(vy, vx)) * 180.0 / M_PI;
    if (dang > 180.0) dang = 360.0 - dang;
    ck_assert_msg(err < tol && dang < tol_deg, "wind (%.4f, %.4f) m/s ± (%.4f, %.4f), truth (%.4f, %.4f): off by %.4f "
                  "m/s and %.3f deg (rho %.3f, %d lags)", e->vx, e->vy, e->sigma_x, e->sigma_y, vx, vy, err, dang,
                  e->rho, e->nlag_used);
}

/* a pure periodic shift: the weighted correlation is exactly Σ c cos(2π k·(s − s_true)/n), so its maximum is the
 * truth to rounding; 0.5 m/s is the tolerance, the estimator does far better (checked at 1e-6 m/s) */
START_TEST(t_periodic_exact)
{
    const scene sc = {.L = 2, .n = {32, 16}, .d = {0.5, 1.0}, .vx = {7.3, -12.0}, .vy = {-4.1, 18.0}, .frozen = 1.0,
                      .frames = 400};
    wt_wind_estimate e[2];
    run(&sc, 11, e);
    for (int l = 0; l < 2; l++) {
        check_wind(&e[l], sc.vx[l], sc.vy[l], 1e-6, 1e-4);
        ck_assert_int_eq(e[l].nlag_used, 4);
        ck_assert(e[l].rho > 0.999);
    }
}
END_TEST

/* the layer seen through a disc of half the grid (a footprint of 32 points that the turbulence moves through), the
 * estimator's taper on the same radius, white noise of 0.2 the layer's rms: what is left of the overlap's pull
 * towards zero (−2 % to 0 % of the speed here, tests/bias_wind_align.c) within the 0.5 m/s and 3° */
START_TEST(t_footprint_noise)
{
    const scene sc = {.L = 1, .n = {64}, .d = {0.5}, .vx = {9.0}, .vy = {6.0}, .frozen = 1.0, .window = 32.0,
                      .noise = 0.2, .frames = 800};
    wt_wind_estimate e[1];
    run(&sc, 5, e);
    check_wind(&e[0], sc.vx[0], sc.vy[0], 0.5, 3.0);
    ck_assert(e[0].sigma_x > 0.0 && e[0].sigma_y > 0.0);
}
END_TEST

/* independent noise frames: no clear peak (no estimate), or a wind within 4 of its stated uncertainties */
START_TEST(t_noise_only)
{
    const scene sc = {.L = 1, .n = {32}, .d = {0.5}, .noise = 1.0, .frozen = 0.0, .frames = 400};
    for (unsigned long seed = 1; seed <= 3; seed++) {
        wt_wind_estimate e[1];
        run(&sc, seed, e);
        ck_assert_msg(e[0].valid == 0 || (fabs(e[0].vx) < 4.0 * e[0].sigma_x && fabs(e[0].vy) < 4.0 * e[0].sigma_y),
                      "noise alone: wind (%g, %g) ± (%g, %g) m/s, rho %g", e[0].vx, e[0].vy, e[0].sigma_x, e[0].sigma_y,
                      e[0].rho);
        if (e[0].valid == 0) ck_assert(e[0].rho < WT_WIND_ALIGN_RHO_MIN);
    }
}
END_TEST

START_TEST(t_refusals)
{
    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_layer(16, 0.5), godd = wt_grid_layer(15, 0.5);
    const wt_grid *gp[1] = {&g}, *go[1] = {&godd};
    const int64_t off[1] = {0};
    wt_wind_align *w = NULL;
    wt_wind_align_params p = params(400);
    p.stride = 0;
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w), WT_ERR_INVALID);
    ck_assert_ptr_null(w);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "every 0 frames"));
    p = params(400);
    p.lag[0] = 0;
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lag 1 is 0"));
    p = params(400);
    p.lag[2] = 2;
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "increasing"));
    p = params(400);
    p.nbatch = 1;
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w), WT_ERR_INVALID);
    p = params(400);
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, go, off, NULL, NULL, &p, &w), WT_ERR_INVALID);
    /* too few snapshots: the shortest lag has no pair yet */
    ck_assert_int_eq(wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w), WT_OK);
    double phi[256] = {0};
    wt_wind_estimate e;
    ck_assert_int_eq(wt_wind_align_estimate(w, &e), WT_ERR_INVALID);
    ck_assert_int_eq(wt_wind_align_add(w, 0, phi), WT_OK);
    ck_assert_int_eq(wt_wind_align_add(w, 2, phi), WT_OK); /* (not a snapshot frame: ignored) */
    ck_assert_int_eq(wt_wind_align_estimate(w, &e), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "1 snapshots"));
    ck_assert_int_eq(wt_wind_align_add(w, 8, phi), WT_ERR_INVALID); /* a gap: frame 4 missing */
    wt_wind_align_reset(w);
    ck_assert_int_eq(wt_wind_align_snapshots(w), 0);
    wt_wind_align_free(w);
    /* allocation failures surface as WT_ERR_NOMEM and leak nothing */
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    for (int b = 0; b < 40; b++) {
        tu_alloc_budget(&fa, b);
        w = NULL;
        const int st = wt_wind_align_alloc(ctx, 1, gp, off, NULL, NULL, &p, &w);
        if (st == WT_OK) {
            wt_wind_align_free(w);
            break;
        }
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(w);
    }
    tu_alloc_budget(&fa, -1);
    ck_assert_int_eq(fa.live, 0);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("wind_align");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, t_periodic_exact);
    tcase_add_test(tc, t_footprint_noise);
    tcase_add_test(tc, t_noise_only);
    tcase_add_test(tc, t_refusals);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
