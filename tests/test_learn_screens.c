/* tests/test_learn_screens.c: the identification's uncertainty that counts the screens seen (core/model/learn.h,
 * wt_learn_screen_factor): consecutive batches see the same turbulence until each layer has moved by the aperture
 * D, so the batches' spread / √B is scaled by √max(1, τ/t_b), τ = D Σ f_k / max(v_k, WT_LEARN_VMIN) / Σ f_k. */
#include <math.h>

#include "core/model/learn.h"
#include "testutil.h"

/* one layer: τ = D / v exactly, the factor √(τ / t_b) below τ and 1 from τ on; T / τ renewals */
START_TEST(test_one_layer)
{
    const double f[1] = {1.0}, v[1] = {10.0};
    double screens = -1.0;
    ck_assert_double_eq_tol(wt_learn_screen_factor(40.0, 1.0, 2.0, 1, f, v, &screens), 2.0, 1e-14);
    ck_assert_double_eq_tol(screens, 0.5, 1e-14);
    ck_assert_double_eq_tol(wt_learn_screen_factor(40.0, 0.25, 2.0, 1, f, v, NULL), 4.0, 1e-14);
    ck_assert_double_eq(wt_learn_screen_factor(40.0, 4.0, 16.0, 1, f, v, &screens), 1.0);
    ck_assert_double_eq_tol(screens, 4.0, 1e-14);
    ck_assert_double_eq(wt_learn_screen_factor(40.0, 8.0, 16.0, 1, f, v, NULL), 1.0);
}
END_TEST

/* the Cn²-weighted mean of 1/v (the slow layers set τ), fractions that do not sum to 1 normalised, an empty layer
 * ignored, a still layer (or one moving backwards) at WT_LEARN_VMIN */
START_TEST(test_profile)
{
    const double f[4] = {0.3, 0.0, 0.1, 0.2}, v[4] = {2.0, 0.0, 20.0, -5.0};
    const double tau = 10.0 * (0.3 / 2.0 + 0.1 / 20.0 + 0.2 / 5.0) / 0.6;
    double screens = 0.0;
    ck_assert_double_eq_tol(wt_learn_screen_factor(10.0, 0.1, 3.0, 4, f, v, &screens), sqrt(tau / 0.1), 1e-13);
    ck_assert_double_eq_tol(screens, 3.0 / tau, 1e-13);
    const double still[1] = {0.0}, one[1] = {1.0};
    ck_assert_double_eq_tol(wt_learn_screen_factor(10.0, 0.1, 1.0, 1, one, still, NULL),
                            sqrt(10.0 / WT_LEARN_VMIN / 0.1), 1e-13);
    /* no turbulence, no batches: nothing to scale */
    const double none[1] = {0.0};
    ck_assert_double_eq(wt_learn_screen_factor(10.0, 0.1, 1.0, 1, none, v, &screens), 1.0);
    ck_assert_double_eq(screens, 0.0);
    ck_assert_double_eq(wt_learn_screen_factor(10.0, 0.0, 1.0, 1, one, v, NULL), 1.0);
}
END_TEST

/* an estimate's r0 and fraction uncertainties scaled by the factor of its own frames and batches, and recorded */
START_TEST(test_estimate)
{
    wt_learn_estimate e = {0};
    e.nalt = 3, e.frames = 1000, e.nbatch = 4, e.sigma_factor = 1.0;
    e.r0_sigma = 0.002;
    for (int a = 0; a < e.nalt; a++) e.fraction_sigma[a] = 0.01 * (a + 1);
    const double f[2] = {0.5, 0.5}, v[2] = {5.0, 5.0};
    /* T = 2 s in 4 batches of 0.5 s, τ = 42 / 5 = 8.4 s: factor √16.8, 2 / 8.4 renewals */
    wt_learn_estimate_count_screens(&e, 42.0, 0.002, 2, f, v);
    const double k = sqrt(8.4 / 0.5);
    ck_assert_double_eq_tol(e.sigma_factor, k, 1e-13);
    ck_assert_double_eq_tol(e.screens, 2.0 / 8.4, 1e-13);
    ck_assert_double_eq_tol(e.r0_sigma, 0.002 * k, 1e-15);
    for (int a = 0; a < e.nalt; a++) ck_assert_double_eq_tol(e.fraction_sigma[a], 0.01 * (a + 1) * k, 1e-15);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("learn_screens");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_one_layer);
    tcase_add_test(tc, test_profile);
    tcase_add_test(tc, test_estimate);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
