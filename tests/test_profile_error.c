/* tests/test_profile_error.c: a controlled model error (recon.atmosphere.error_*; SPEC §12, core/config/config.h):
 * each error applied to the reconstructors' model only, its defaults, the matrix identity that follows it, and
 * the refusal of bad values. */
#include <float.h>

#include "core/config/config.h"
#include "core/model/params.h"
#include "core/model/profile.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "profile_fixture.h"

/* ---------------------------------------------------------------- a controlled model error (recon.atmosphere.error_*) */

/* Tolerances: the ground error is two products and a sum per layer (≤ 4 ulp of 1 over the demo's 5 layers); the
 * rest is exact (one product or one sum per number, compared with the same operation). */
#define ERR_SUM_TOL (16 * DBL_EPSILON)

static wt_config *demo_err(wt_context *ctx, const char *set)
{
    return demo_ok(ctx, 1, (const char *[]){set});
}

/* Each error does what its key says on the demo's 5-layer profile (0, 600, 2000, 6000, 12000 m; 0.55, 0.1, 0.1,
 * 0.15, 0.1), to the model only. */
START_TEST(test_model_error_each)
{
    wt_context *ctx = tu_context();
    wt_config *base = demo_ok(ctx, 0, NULL);
    const wt_model_atmosphere_config *b = &base->model;
    /* the ground layer (the lowest) + 0.2; the rest scaled by 0.25 / 0.45 */
    wt_config *c = demo_err(ctx, "recon.atmosphere.error_ground_fraction=0.2");
    double sum = 0.0;
    for (int l = 0; l < 5; l++) sum += c->model.fraction[l];
    ck_assert_double_eq_tol(sum, 1.0, ERR_SUM_TOL);
    ck_assert_double_eq_tol(c->model.fraction[0], 0.75, ERR_SUM_TOL);
    for (int l = 1; l < 5; l++) ck_assert_rel(c->model.fraction[l], b->fraction[l] * 0.25 / 0.45, ERR_SUM_TOL, 0.0);
    ck_assert(!memcmp(c->layer_fraction, base->layer_fraction, sizeof c->layer_fraction)); /* the truth stays */
    ck_assert(c->model.r0 == b->r0 && !memcmp(c->model.altitude, b->altitude, sizeof b->altitude));
    wt_config_free(ctx, c);
    /* a ground layer of three (≤ 2 km: 0.75) − 0.3: each of them × 0.6, the others × 0.55 / 0.25 */
    c = demo_ok(ctx, 2, (const char *[]){"recon.atmosphere.error_ground_fraction=-0.3",
                                         "recon.atmosphere.error_ground_top_m=2000.0"});
    sum = 0.0;
    for (int l = 0; l < 5; l++) {
        sum += c->model.fraction[l];
        ck_assert_rel(c->model.fraction[l], b->fraction[l] * (l < 3 ? 0.45 / 0.75 : 0.55 / 0.25), ERR_SUM_TOL, 0.0);
    }
    ck_assert_double_eq_tol(sum, 1.0, ERR_SUM_TOL);
    wt_config_free(ctx, c);
    /* r0 × 1.2; nothing else */
    c = demo_err(ctx, "recon.atmosphere.error_r0_scale=1.2");
    ck_assert(c->model.r0 == 1.2 * b->r0 && c->r0 == base->r0);
    ck_assert(!memcmp(c->model.fraction, b->fraction, sizeof b->fraction));
    wt_tomography_params tp;
    wt_tomography_params_from_config(c, &tp);
    ck_assert(tp.r0 == 1.2 * b->r0); /* what the reconstructors take */
    wt_config_free(ctx, c);
    /* the layers at or above 5 km (the default bottom) + 2 km: the first moment + 2 km x 0.25 */
    c = demo_err(ctx, "recon.atmosphere.error_high_shift_m=2000.0");
    double m0 = 0.0, m1 = 0.0;
    for (int l = 0; l < 5; l++) {
        ck_assert(c->model.altitude[l] == b->altitude[l] + (l >= 3 ? 2000.0 : 0.0));
        ck_assert(c->model.fraction[l] == b->fraction[l] && c->model.wind_speed[l] == b->wind_speed[l]);
        m0 += b->fraction[l] * b->altitude[l], m1 += c->model.fraction[l] * c->model.altitude[l];
    }
    ck_assert_rel(m1 - m0, 2000.0 * 0.25, 1e-12, 0.0);
    ck_assert(!memcmp(c->layer_altitude, base->layer_altitude, sizeof c->layer_altitude));
    wt_config_free(ctx, c);
    /* the layers at or above 1 km − 2 km: the 2 km layer meets the ground one and goes after it (stable order),
     * its fraction and wind with it; the first moment − 2 km x 0.35 */
    c = demo_ok(ctx, 2, (const char *[]){"recon.atmosphere.error_high_shift_m=-2000.0",
                                         "recon.atmosphere.error_high_bottom_m=1000.0"});
    static const int from[5] = {0, 2, 1, 3, 4}; /* model layer l is the demo's layer from[l] */
    m1 = 0.0;
    for (int l = 0; l < 5; l++) {
        const int o = from[l];
        ck_assert(c->model.altitude[l] == b->altitude[o] - (o >= 2 ? 2000.0 : 0.0));
        ck_assert(c->model.fraction[l] == b->fraction[o] && c->model.wind_speed[l] == b->wind_speed[o] &&
                  c->model.wind_direction[l] == b->wind_direction[o]);
        if (l) ck_assert(c->model.altitude[l] >= c->model.altitude[l - 1]);
        m1 += c->model.fraction[l] * c->model.altitude[l];
    }
    ck_assert_rel(m1 - m0, -2000.0 * 0.35, 1e-12, 0.0);
    wt_config_free(ctx, c);
    /* the wind: speeds × 1.5, directions + 30 deg; the prediction's wind vectors rotate and stretch alike */
    c = demo_ok(ctx, 3, (const char *[]){"recon.atmosphere.error_wind_speed_scale=1.5",
                                         "recon.atmosphere.error_wind_direction_deg=30.0", "recon.predict=true"});
    wt_config *p0 = demo_err(ctx, "recon.predict=true");
    wt_reconstructor_params ra, rb;
    wt_reconstructor_params_from_config(p0, WT_RECON_PCG3, -1, &ra);
    wt_reconstructor_params_from_config(c, WT_RECON_PCG3, -1, &rb);
    const double t = 30.0 * M_PI / 180.0;
    for (int l = 0; l < 5; l++) {
        ck_assert(c->model.wind_speed[l] == 1.5 * b->wind_speed[l]);
        ck_assert(c->model.wind_direction[l] == b->wind_direction[l] + 30.0 * (M_PI / 180.0));
        ck_assert(c->wind_speed[l] == base->wind_speed[l] && c->wind_direction[l] == base->wind_direction[l]);
        const double s = b->wind_speed[l];
        ck_assert_double_eq_tol(rb.atm_vx[l], 1.5 * (cos(t) * ra.atm_vx[l] - sin(t) * ra.atm_vy[l]), 1e-13 * s);
        ck_assert_double_eq_tol(rb.atm_vy[l], 1.5 * (sin(t) * ra.atm_vx[l] + cos(t) * ra.atm_vy[l]), 1e-13 * s);
    }
    ck_assert(c->model.r0 == b->r0 && !memcmp(c->model.fraction, b->fraction, sizeof b->fraction));
    wt_config_free(ctx, p0);
    wt_config_free(ctx, c);
    /* a given model takes the error as the oracle's does */
    const char *given[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.1", "recon.atmosphere.L0_m=25.0",
                           "recon.atmosphere.altitudes_m=[0.0, 9000.0]", "recon.atmosphere.cn2_fractions=[0.9, 0.1]",
                           "recon.atmosphere.wind_speed_mps=[5.0, 30.0]",
                           "recon.atmosphere.wind_direction_deg=[0.0, 90.0]",
                           "recon.atmosphere.error_ground_fraction=-0.1", "recon.atmosphere.error_r0_scale=0.8",
                           "recon.atmosphere.error_high_shift_m=1000.0"};
    c = demo_ok(ctx, 10, given);
    ck_assert(c->model.r0 == 0.8 * 0.1 && c->model.altitude[1] == 10000.0);
    ck_assert_double_eq_tol(c->model.fraction[0], 0.8, ERR_SUM_TOL);
    ck_assert_double_eq_tol(c->model.fraction[1], 0.2, ERR_SUM_TOL);
    wt_config_free(ctx, c);
    wt_config_free(ctx, base);
    wt_context_free(ctx);
}
END_TEST

/* No error = today's bits: each key left out, or given its value of no error (a sweep's 0), gives the same
 * canonical text, matrix identity and model; the qualifying keys alone change nothing either. */
START_TEST(test_model_error_defaults)
{
    wt_context *ctx = tu_context();
    wt_config *base = demo_ok(ctx, 0, NULL);
    const char *none[] = {"recon.atmosphere.error_ground_fraction=0.0", "recon.atmosphere.error_ground_top_m=700.0",
                          "recon.atmosphere.error_r0_scale=1.0",        "recon.atmosphere.error_high_shift_m=0.0",
                          "recon.atmosphere.error_high_bottom_m=1000.0", "recon.atmosphere.error_wind_speed_scale=1.0",
                          "recon.atmosphere.error_wind_direction_deg=0.0"};
    wt_config *c = demo_ok(ctx, 7, none);
    ck_assert_str_eq(c->canonical, base->canonical);
    ck_assert_str_eq(c->matrix_sha256, base->matrix_sha256);
    ck_assert(!memcmp(&c->model, &base->model, offsetof(wt_model_atmosphere_config, profile)));
    ck_assert(c->model.r0 == base->r0 && !memcmp(c->model.fraction, base->layer_fraction, sizeof c->model.fraction));
    wt_config_free(ctx, c);
    /* left out: the defaults of no error */
    ck_assert(base->model.error_ground_fraction == 0.0 && base->model.error_r0_scale == 1.0 &&
              base->model.error_high_shift == 0.0 && base->model.error_high_bottom == 5000.0 &&
              base->model.error_wind_speed_scale == 1.0 && base->model.error_wind_direction == 0.0);
    ck_assert_ptr_null(strstr(base->canonical, "error_"));
    /* a real error is in the canonical text, which reads back to the same model */
    c = demo_ok(ctx, 2, (const char *[]){"recon.atmosphere.error_high_shift_m=-1500.0",
                                         "recon.atmosphere.error_high_bottom_m=1000.0"});
    ck_assert_ptr_nonnull(strstr(c->canonical, "error_high_shift_m = -1500.0"));
    ck_assert_ptr_nonnull(strstr(c->canonical, "error_high_bottom_m = 1000.0"));
    wt_config *r = NULL;
    ck_assert_msg(wt_config_parse(ctx, c->canonical, "canonical", 0, NULL, &r) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(!memcmp(&r->model, &c->model, offsetof(wt_model_atmosphere_config, profile)));
    ck_assert_str_eq(r->matrix_sha256, c->matrix_sha256);
    wt_config_free(ctx, r);
    wt_config_free(ctx, c);
    wt_config_free(ctx, base);
    wt_context_free(ctx);
}
END_TEST

/* The errors of the profile and r0 make another matrix; the wind's do not (only prediction reads it). */
START_TEST(test_model_error_matrix_identity)
{
    wt_context *ctx = tu_context();
    char base[65], h[65];
    hash_of(ctx, 0, NULL, base);
    static const struct {
        const char *set;
        int same;
    } cases[] = {{"recon.atmosphere.error_ground_fraction=0.1", 0},
                 {"recon.atmosphere.error_r0_scale=0.8", 0},
                 {"recon.atmosphere.error_high_shift_m=2000.0", 0},
                 {"recon.atmosphere.error_wind_speed_scale=2.0", 1},
                 {"recon.atmosphere.error_wind_direction_deg=-50.0", 1},
                 {"recon.atmosphere.error_high_bottom_m=100.0", 1},
                 {"recon.atmosphere.error_ground_top_m=100.0", 1}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        hash_of(ctx, 1, &cases[i].set, h);
        ck_assert_msg((strcmp(h, base) == 0) == cases[i].same, "%s: the matrix hash %s", cases[i].set,
                      cases[i].same ? "changed" : "stayed");
    }
    wt_context_free(ctx);
}
END_TEST

/* Bad values: refused, naming the key and why. */
static const struct bad_error {
    const char *set[2];
    const char *msg[2];
} bad_errors[] = {
    {{"recon.atmosphere.error_ground_fraction=0.5"},
     {"key 'recon.atmosphere.error_ground_fraction': the model's ground layer (1 layer up to 0 m", "would hold 1.05, not a fraction in [0, 1]"}},
    {{"recon.atmosphere.error_ground_fraction=-0.6", "recon.atmosphere.error_ground_top_m=0.0"},
     {"--set recon.atmosphere.error_ground_fraction=-0.6", "would hold -0.05, not a fraction"}},
    {{"recon.atmosphere.error_ground_fraction=-0.8", "recon.atmosphere.error_ground_top_m=2000.0"},
     {"(3 layers up to 2000 m, error_ground_top_m = 2000 m) holds 0.75", "not a fraction in [0, 1]"}},
    {{"recon.atmosphere.error_ground_fraction=1.5"}, {"key 'recon.atmosphere.error_ground_fraction': value 1.5 is out of range", ""}},
    {{"recon.atmosphere.error_r0_scale=0.005"},
     {"key 'recon.atmosphere.error_r0_scale': the model's r0 would be 0.005 x 0.129 m", "outside recon.atmosphere.r0_m's range"}},
    {{"recon.atmosphere.error_r0_scale=0.0"}, {"key 'recon.atmosphere.error_r0_scale': value 0 is out of range", ""}},
    {{"recon.atmosphere.error_high_shift_m=-7000.0"},
     {"key 'recon.atmosphere.error_high_shift_m': it would move the model layer at 6000 m to -1000 m, below the ground", ""}},
    {{"recon.atmosphere.error_high_shift_m=80000.0"}, {"to 92000 m, at or above the LGS altitude", ""}},
    {{"recon.atmosphere.error_high_shift_m=1000.0", "recon.atmosphere.error_high_bottom_m=20000.0"},
     {"no model layer is at or above error_high_bottom_m = 20000 m (the highest is at 12000 m)", "would move nothing"}},
    {{"recon.atmosphere.error_wind_speed_scale=-1.0"}, {"key 'recon.atmosphere.error_wind_speed_scale': value -1 is out of range", ""}},
    {{"recon.atmosphere.error_wind_direction_deg=400.0"}, {"key 'recon.atmosphere.error_wind_direction_deg': value 400 is out of range", ""}},
};

START_TEST(test_model_error_bad_input)
{
    const struct bad_error *e = &bad_errors[_i];
    wt_context *ctx = tu_context();
    wt_config *c = NULL;
    const int n = e->set[1] ? 2 : 1;
    ck_assert_int_eq(read_demo(ctx, n, e->set, &c), WT_ERR_CONFIG);
    ck_assert_ptr_null(c);
    for (int i = 0; i < 2; i++)
        ck_assert_msg(strstr(wt_error_message(ctx), e->msg[i]), "case %d: '%s' not in: %s", _i, e->msg[i],
                      wt_error_message(ctx));
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("profile_error");
    TCase *tc = tcase_create("profile");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_model_error_each);
    tcase_add_test(tc, test_model_error_defaults);
    tcase_add_test(tc, test_model_error_matrix_identity);
    tcase_add_loop_test(tc, test_model_error_bad_input, 0, (int)(sizeof bad_errors / sizeof bad_errors[0]));
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
