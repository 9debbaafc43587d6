/* tests/test_profile.c: truth and model apart (SPEC §12): the compression of a Cn² profile onto reconstruction
 * layers (core/model/profile.h), the reconstructors' atmosphere (recon.atmosphere: oracle, given, learned
 * refused), profile files (atmosphere.profile; core/config/config_atmosphere.c) and their refusals, and the
 * matrix identity that follows the model, not the truth. */
#include <float.h>
#include <unistd.h>

#include "core/config/config.h"
#include "core/model/params.h"
#include "core/model/profile.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "testutil.h"
#include "profile_fixture.h"

/* ---------------------------------------------------------------- the compression */

/* Inside the layers' range each profile layer is split as (1 − w) a_l + w a_{l+1} = h, w = (h − a_l)/(a_{l+1} − a_l):
 * the total is a sum of n pairs (1 − w) f + w f, each within 2 ulp of f, the first moment within a few ulp of the
 * largest altitude per layer. Tolerances: 8 (n + L) eps relative to Σ f and to Σ f a_max. */
START_TEST(test_compress_moments)
{
    wt_rng rng;
    wt_rng_init(&rng, 35, 0);
    const double ralt[9] = {47.0, 140.0, 281.0, 562.0, 1125.0, 2250.0, 4500.0, 9000.0, 18000.0};
    for (int trial = 0; trial < 200; trial++) {
        const int n = 1 + trial % WT_MAX_LAYERS, L = 2 + trial % 8;
        double alt[WT_MAX_LAYERS], f[WT_MAX_LAYERS], rf[WT_MAX_LAYERS], sum = 0.0, mom = 0.0;
        for (int k = 0; k < n; k++) { /* increasing altitudes inside [a_0, a_{L-1}] */
            alt[k] = ralt[0] + (ralt[L - 1] - ralt[0]) * (k + wt_rng_uniform(&rng)) / n;
            f[k] = wt_rng_uniform(&rng);
            sum += f[k];
            mom += f[k] * alt[k];
        }
        wt_profile_compress(n, alt, f, NULL, NULL, L, ralt, rf, NULL, NULL);
        double rsum = 0.0, rmom = 0.0;
        for (int l = 0; l < L; l++) {
            ck_assert_double_ge(rf[l], 0.0);
            rsum += rf[l];
            rmom += rf[l] * ralt[l];
        }
        const double tol = 8.0 * (n + L) * DBL_EPSILON;
        ck_assert_msg(fabs(rsum - sum) <= tol * sum, "trial %d: total %.17g vs %.17g", trial, rsum, sum);
        ck_assert_msg(fabs(rmom - mom) <= tol * sum * ralt[L - 1], "trial %d: first moment %.17g vs %.17g", trial,
                      rmom, mom);
    }
    /* outside the range: all of it to the end layer; the total is kept, the first moment moves by f (a_end − h) */
    const double alt[3] = {10.0, 5000.0, 26500.0}, f[3] = {0.5, 0.3, 0.2};
    double rf[3];
    wt_profile_compress(3, alt, f, NULL, NULL, 3, (const double[]){47.0, 4000.0, 18000.0}, rf, NULL, NULL);
    const double w = (5000.0 - 4000.0) / (18000.0 - 4000.0);
    ck_assert_double_eq(rf[0], 0.5);
    ck_assert_double_eq(rf[1], (1.0 - w) * 0.3);
    ck_assert_double_eq(rf[2], w * 0.3 + 0.2);
    const double moved = rf[0] * 47.0 + rf[1] * 4000.0 + rf[2] * 18000.0 - (0.5 * 10.0 + 0.3 * 5000.0 + 0.2 * 26500.0);
    ck_assert_rel(moved, 0.5 * (47.0 - 10.0) + 0.2 * (18000.0 - 26500.0), 1e-12, 1.0);
    /* a profile layer on a reconstruction altitude goes wholly there (w = 0 exactly) */
    wt_profile_compress(1, (const double[]){4000.0}, (const double[]){1.0}, NULL, NULL, 3,
                        (const double[]){0.0, 4000.0, 12700.0}, rf, NULL, NULL);
    ck_assert(rf[0] == 0.0 && rf[1] == 1.0 && rf[2] == 0.0);
}
END_TEST

/* The wind of a reconstruction layer is the Cn²-weighted mean of the wind VECTORS it absorbs. */
/* A grid's hats compressed onto layers (wt_profile_compress_hats), against the integrals done by hand: the bottom
 * half-hat of 0 km (next point 0.5 km) onto layers at 0 and 1 km gives ∫₀⁵⁰⁰ (1 − h/500)(1 − h/1000) dh / 250 = 5/6
 * and 1/6 (first moment 500/3 m: the half-hat's centre); an interior hat keeps its total and first moment on any
 * layers that span it, and on layers at an even grid's own points ∫ φ_k b_l = ∫ φ_k φ_l: 2/3 stays at its peak, 1/6 to
 * each neighbour. The winds are the Cn²-weighted ones. */
START_TEST(test_compress_hats)
{
    const double g[3] = {0.0, 500.0, 1500.0}, f1[3] = {1.0, 0.0, 0.0};
    const double r2[2] = {0.0, 1000.0};
    double rf[4], vx[4], vy[4];
    wt_profile_compress_hats(3, g, f1, NULL, NULL, 2, r2, rf, NULL, NULL);
    ck_assert_double_eq_tol(rf[0], 5.0 / 6.0, 1e-14);
    ck_assert_double_eq_tol(rf[1], 1.0 / 6.0, 1e-14);
    /* the middle hat (500 m; 0 and 1500 m on either side): total 1, first moment ∫ h φ / ∫ φ = (0 + 500 + 1500)/3 */
    const double f2[3] = {0.0, 1.0, 0.0}, r4[4] = {0.0, 300.0, 800.0, 2000.0};
    wt_profile_compress_hats(3, g, f2, NULL, NULL, 4, r4, rf, NULL, NULL);
    double tot = 0, mom = 0;
    for (int l = 0; l < 4; l++) tot += rf[l], mom += rf[l] * r4[l];
    ck_assert_double_eq_tol(tot, 1.0, 1e-14);
    ck_assert_double_eq_tol(mom, 2000.0 / 3.0, 1e-10);
    /* layers at an even grid itself: ∫ φ_1 φ_l / ∫ φ_1 = 2/3 at its peak, 1/6 to each neighbour */
    const double ge[3] = {0.0, 500.0, 1000.0};
    wt_profile_compress_hats(3, ge, f2, NULL, NULL, 3, ge, rf, NULL, NULL);
    ck_assert_double_eq_tol(rf[0], 1.0 / 6.0, 1e-14);
    ck_assert_double_eq_tol(rf[1], 2.0 / 3.0, 1e-14);
    ck_assert_double_eq_tol(rf[2], 1.0 / 6.0, 1e-14);
    /* wind: two points, each its own wind; the layer between them gets the Cn²-weighted mean */
    const double f3[3] = {0.5, 0.5, 0.0}, wx[3] = {10.0, 20.0, 0.0}, wy[3] = {0.0, 0.0, 5.0}, r1[1] = {400.0};
    wt_profile_compress_hats(3, g, f3, wx, wy, 1, r1, rf, vx, vy);
    ck_assert_double_eq_tol(rf[0], 1.0, 1e-14);
    ck_assert_double_eq_tol(vx[0], 15.0, 1e-12);
    ck_assert_double_eq_tol(vy[0], 0.0, 1e-14);
}
END_TEST

START_TEST(test_compress_wind)
{
    const double ralt[2] = {0.0, 1000.0}, alt[2] = {250.0, 750.0}, f[2] = {0.4, 0.6};
    const double vx[2] = {10.0, 0.0}, vy[2] = {0.0, 10.0};
    double rf[2], rx[2], ry[2];
    wt_profile_compress(2, alt, f, vx, vy, 2, ralt, rf, rx, ry);
    /* layer 0 absorbs 0.75 x 0.4 = 0.3 moving +x and 0.25 x 0.6 = 0.15 moving +y; layer 1 0.1 and 0.45 */
    ck_assert_rel(rf[0], 0.45, 4 * DBL_EPSILON, 0.0);
    ck_assert_rel(rf[1], 0.55, 4 * DBL_EPSILON, 0.0);
    ck_assert_rel(rx[0], 0.3 * 10.0 / 0.45, 8 * DBL_EPSILON, 0.0);
    ck_assert_rel(ry[0], 0.15 * 10.0 / 0.45, 8 * DBL_EPSILON, 0.0);
    ck_assert_rel(rx[1], 0.1 * 10.0 / 0.55, 8 * DBL_EPSILON, 0.0);
    ck_assert_rel(ry[1], 0.45 * 10.0 / 0.55, 8 * DBL_EPSILON, 0.0);
    /* vectors, not speeds: layer 0 absorbs (2/3)(1/3) of the first and (1/3)(2/3) of the second, which move
     * opposite ways, so it has no wind (to rounding); an empty layer has none */
    const double a2[2] = {100.0, 200.0}, f2[2] = {1.0 / 3.0, 2.0 / 3.0}, ox[2] = {7.0, -7.0}, oy[2] = {-3.0, 3.0};
    double r3[3];
    double x3[3], y3[3];
    wt_profile_compress(2, a2, f2, ox, oy, 3, (const double[]){0.0, 300.0, 5000.0}, r3, x3, y3);
    ck_assert_double_eq_tol(x3[0], 0.0, 1e-14);
    ck_assert_double_eq_tol(y3[0], 0.0, 1e-14);
    ck_assert(r3[2] == 0.0 && x3[2] == 0.0 && y3[2] == 0.0);
    /* the speed of one layer absorbed alone is kept exactly */
    wt_profile_compress(1, (const double[]){300.0}, (const double[]){1.0}, (const double[]){3.0},
                        (const double[]){4.0}, 3, (const double[]){0.0, 300.0, 5000.0}, r3, x3, y3);
    ck_assert(x3[1] == 3.0 && y3[1] == 4.0);
}
END_TEST

/* ---------------------------------------------------------------- oracle = the old way, bit for bit */

/* The reconstructor's parameters as they were filled before truth and model were apart: the simulated atmosphere
 * read directly. */
static void params_from_truth(const wt_config *cfg, wt_tomography_params *tp)
{
    wt_tomography_params_from_config(cfg, tp);
    tp->r0 = cfg->r0;
    tp->L0 = cfg->L0;
    tp->natm = cfg->nlayers;
    for (int k = 0; k < cfg->nlayers; k++) {
        tp->atm_altitude[k] = cfg->layer_altitude[k];
        tp->atm_fraction[k] = cfg->layer_fraction[k];
    }
}

/* The prior's binning before core/model/profile.c (tomography.c's bin_profile then), kept here as the reference. */
static void old_binning(const wt_config *cfg, const wt_recon_variant_config *v, double *frac)
{
    for (int l = 0; l < v->nlayers; l++) frac[l] = 0.0;
    for (int k = 0; k < cfg->nlayers; k++) {
        int l;
        double w;
        wt_profile_bin_altitude(v->nlayers, v->altitudes, cfg->layer_altitude[k], &l, &w);
        frac[l] += (1.0 - w) * cfg->layer_fraction[k];
        if (w > 0.0) frac[l + 1] += w * cfg->layer_fraction[k];
    }
    for (int l = 0; l < v->nlayers; l++)
        if (frac[l] < 1e-3) frac[l] = 1e-3;
}

/* Both variants' tomographies (their priors, fractions and model errors) equal to the bit. */
static void assert_same_tomography(wt_context *ctx, const wt_system *sys, const wt_config *cfg,
                                   const wt_tomography_params *a, const wt_tomography_params *b, int check_old)
{
    for (int v = 0; v < 2; v++) {
        const wt_recon_variant_config *var = v ? &cfg->cg9 : &cfg->pcg3;
        wt_tomography *ta = NULL, *tb = NULL;
        ck_assert_int_eq(wt_tomography_alloc(ctx, sys, var, v ? "cg9" : "pcg3", a, &ta), WT_OK);
        ck_assert_int_eq(wt_tomography_alloc(ctx, sys, var, v ? "cg9" : "pcg3", b, &tb), WT_OK);
        double old[WT_MAX_LAYERS];
        old_binning(cfg, var, old);
        for (int l = 0; l < var->nlayers; l++) {
            ck_assert(wt_tomography_layer_fraction(ta, l) == wt_tomography_layer_fraction(tb, l));
            if (check_old) ck_assert(wt_tomography_layer_fraction(ta, l) == old[l]);
        }
        const int64_t n = wt_tomography_nunknowns(ta);
        ck_assert(!memcmp(wt_tomography_alpha_prior(ta), wt_tomography_alpha_prior(tb), (size_t)n * sizeof(double)));
        for (int m = 0; m < sys->nsensors; m++)
            ck_assert(wt_tomography_model_error(ta, m) == wt_tomography_model_error(tb, m));
        wt_tomography_free(ta);
        wt_tomography_free(tb);
    }
}

static char profile_path[64];

START_TEST(test_oracle_bit_identical)
{
    wt_context *ctx = tu_context();
    /* relative to the configuration's directory, data/presets */
    const char *eso_set = "atmosphere.profile=\"../atmosphere/eso35-median.txt\"";
    char dirs[600] = "atmosphere.wind_direction_deg=[";
    for (int k = 0; k < 35; k++) snprintf(dirs + strlen(dirs), sizeof dirs - strlen(dirs), "%s%.1f", k ? "," : "", fmod(137.5 * k, 360.0));
    strcat(dirs, "]");
    /* the demo as shipped (its 5 layers = cg9's), and on the 35-layer truth with the layer-binning model error */
    const char *ov35[] = {eso_set, dirs, "recon.model_error=true"};
    for (int c = 0; c < 2; c++) {
        wt_config *cfg = demo_ok(ctx, c ? 3 : 0, ov35);
        ck_assert_int_eq(cfg->model.source, WT_MODEL_ORACLE);
        ck_assert_int_eq(cfg->nlayers, c ? 35 : 5);
        wt_system *sys = NULL;
        ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
        wt_tomography_params now, before;
        wt_tomography_params_from_config(cfg, &now);
        params_from_truth(cfg, &before);
        assert_same_tomography(ctx, sys, cfg, &now, &before, 1);
        wt_system_free(sys);
        wt_config_free(ctx, cfg);
    }
    wt_context_free(ctx);
}
END_TEST

/* The demo under the oracle and under a given model (the overrides ov), on the oracle's system, with the
 * reconstructors' parameters of each. */
typedef struct pair {
    wt_context *ctx;
    wt_config *oracle, *given;
    wt_system *sys;
    wt_tomography_params a, b;
} pair;

static void pair_alloc(pair *p, int nov, const char *const *ov)
{
    p->ctx = tu_context();
    p->oracle = demo_ok(p->ctx, 0, NULL);
    p->given = demo_ok(p->ctx, nov, ov);
    ck_assert_int_eq(p->given->model.source, WT_MODEL_GIVEN);
    ck_assert_int_eq(wt_system_alloc(p->ctx, p->oracle, &p->sys), WT_OK);
    wt_tomography_params_from_config(p->oracle, &p->a);
    wt_tomography_params_from_config(p->given, &p->b);
}

static void pair_free(pair *p)
{
    wt_system_free(p->sys);
    wt_config_free(p->ctx, p->oracle);
    wt_config_free(p->ctx, p->given);
    wt_context_free(p->ctx);
}

/* A given model with the truth's numbers is the oracle's model: the same reconstructor to the bit. */
START_TEST(test_given_as_oracle)
{
    const char *ov[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.129", "recon.atmosphere.L0_m=25.0",
                        "recon.atmosphere.altitudes_m=[0.0, 600.0, 2000.0, 6000.0, 12000.0]",
                        "recon.atmosphere.cn2_fractions=[0.55, 0.1, 0.1, 0.15, 0.1]",
                        "recon.atmosphere.wind_speed_mps=[8.0, 10.0, 12.0, 18.0, 25.0]",
                        "recon.atmosphere.wind_direction_deg=[0.0, 72.0, 144.0, 216.0, 288.0]"};
    pair p;
    pair_alloc(&p, 7, ov);
    assert_same_tomography(p.ctx, p.sys, p.oracle, &p.a, &p.b, 0);
    /* the model's numbers, not its source, are its identity; but the keys differ, so the hashes do */
    ck_assert_str_ne(p.oracle->matrix_sha256, p.given->matrix_sha256);
    pair_free(&p);
}
END_TEST

/* ---------------------------------------------------------------- a given model reaches the prior */

START_TEST(test_given_reaches_prior)
{
    /* a wrong profile: 90 % at the ground, the rest at 9 km; r0 half the truth's */
    const char *ov[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.0645", "recon.atmosphere.L0_m=25.0",
                        "recon.atmosphere.altitudes_m=[0.0, 9000.0]", "recon.atmosphere.cn2_fractions=[0.9, 0.1]",
                        "recon.atmosphere.wind_speed_mps=[5.0, 30.0]", "recon.atmosphere.wind_direction_deg=[0.0, 90.0]"};
    pair p;
    pair_alloc(&p, 7, ov);
    wt_context *ctx = p.ctx;
    const wt_config *given = p.given;
    const wt_system *sys = p.sys;
    const wt_tomography_params a = p.a, b = p.b;
    ck_assert(b.r0 == 0.0645 && b.natm == 2);
    for (int v = 0; v < 2; v++) {
        const wt_recon_variant_config *var = v ? &given->cg9 : &given->pcg3;
        wt_tomography *ta = NULL, *tb = NULL;
        ck_assert_int_eq(wt_tomography_alloc(ctx, sys, var, v ? "cg9" : "pcg3", &a, &ta), WT_OK);
        ck_assert_int_eq(wt_tomography_alloc(ctx, sys, var, v ? "cg9" : "pcg3", &b, &tb), WT_OK);
        double rf[WT_MAX_LAYERS];
        wt_profile_compress(2, given->model.altitude, given->model.fraction, NULL, NULL, var->nlayers, var->altitudes,
                            rf, NULL, NULL);
        for (int l = 0; l < var->nlayers; l++) {
            /* the prior's fraction is the given profile compressed (floored) */
            ck_assert(wt_tomography_layer_fraction(tb, l) == fmax(rf[l], WT_PRIOR_FRACTION_FLOOR));
            /* the prior weight of a layer ∝ r0^(5/3) / f (the von Karman PSD ∝ f r0^(-5/3)): per layer the
             * ratio of the two priors is (r0_b/r0_a)^(5/3) (f_a/f_b), to rounding */
            const double ratio = pow(0.0645 / 0.129, 5.0 / 3.0) * wt_tomography_layer_fraction(ta, l) /
                                 wt_tomography_layer_fraction(tb, l);
            const int64_t o = wt_tomography_layer_offset(ta, l), nl = wt_tomography_layer_offset(ta, l + 1) - o;
            for (int64_t i = 0; i < nl; i += 97)
                ck_assert_rel(wt_tomography_alpha_prior(tb)[o + i], ratio * wt_tomography_alpha_prior(ta)[o + i],
                              1e-12, 0.0);
        }
        wt_tomography_free(ta);
        wt_tomography_free(tb);
    }
    pair_free(&p);
}
END_TEST

/* ---------------------------------------------------------------- the matrix identity follows the model */

START_TEST(test_matrix_identity)
{
    wt_context *ctx = tu_context();
    char base[65], h[65];
    hash_of(ctx, 0, NULL, base);
    /* oracle: the truth's profile is the model's, its wind is not in any matrix; "oracle" written = left out */
    hash_of(ctx, 1, (const char *[]){"atmosphere.r0_m=0.15"}, h);
    ck_assert_str_ne(h, base);
    hash_of(ctx, 1, (const char *[]){"atmosphere.wind_speed_mps=[1.0, 2.0, 3.0, 4.0, 5.0]"}, h);
    ck_assert_str_eq(h, base);
    hash_of(ctx, 1, (const char *[]){"recon.atmosphere.source=\"oracle\""}, h);
    ck_assert_str_eq(h, base);
    /* given: the truth no longer makes the matrix, the model does */
    const char *g[8] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.129", "recon.atmosphere.L0_m=25.0",
                        "recon.atmosphere.altitudes_m=[0.0, 9000.0]", "recon.atmosphere.cn2_fractions=[0.9, 0.1]",
                        "recon.atmosphere.wind_speed_mps=[5.0, 30.0]", "recon.atmosphere.wind_direction_deg=[0.0, 90.0]"};
    char gbase[65];
    hash_of(ctx, 7, g, gbase);
    /* one more override each: does the matrix stay (1) or change (0)? */
    static const struct {
        const char *set;
        int same;
    } cases[] = {{"atmosphere.r0_m=0.2", 1},
                 {"atmosphere.cn2_fractions=[0.2, 0.2, 0.2, 0.2, 0.2]", 1},
                 {"recon.atmosphere.r0_m=0.1", 0},
                 {"recon.atmosphere.cn2_fractions=[0.8, 0.2]", 0},
                 {"recon.atmosphere.wind_speed_mps=[6.0, 31.0]", 1}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        g[7] = cases[i].set;
        hash_of(ctx, 8, g, h);
        ck_assert_msg((strcmp(h, gbase) == 0) == cases[i].same, "%s: the matrix hash %s", cases[i].set,
                      cases[i].same ? "changed" : "stayed");
    }
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------- profile files */

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fputs(text, f);
    fclose(f);
}

/* The demo whose truth is the file at profile_path (directions from the key when dirs is given). */
static int read_with_profile(wt_context *ctx, const char *dirs, wt_config **out)
{
    char p[128];
    snprintf(p, sizeof p, "atmosphere.profile=\"%s\"", profile_path);
    const char *ov[2] = {p, dirs};
    return read_demo(ctx, dirs ? 2 : 1, ov, out);
}

/* A profile file with the demo's 5 layers gives the configuration of the lists, to the bit and the hash; the
 * canonical text holds the lists (not the file) and reads back the same. */
START_TEST(test_profile_file_equals_lists)
{
    wt_context *ctx = tu_context();
    write_file(profile_path, "# the demo's profile\n"
                             "   0.0 0.55  8.0   0.0\n"
                             " 600.0 0.1  10.0  72.0   # boundary layer\n"
                             "\n"
                             "2000.0 0.1  12.0 144.0\n6000.0 0.15 18.0 216.0\n12000.0 0.1 25.0 288.0\n");
    wt_config *lists = demo_ok(ctx, 0, NULL), *file = NULL;
    ck_assert_msg(read_with_profile(ctx, NULL, &file) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(file->atm_profile, profile_path);
    ck_assert_int_eq(file->nlayers, 5);
    ck_assert(!memcmp(file->layer_altitude, lists->layer_altitude, sizeof lists->layer_altitude));
    ck_assert(!memcmp(file->layer_fraction, lists->layer_fraction, sizeof lists->layer_fraction));
    ck_assert(!memcmp(file->wind_speed, lists->wind_speed, sizeof lists->wind_speed));
    ck_assert(!memcmp(file->wind_direction, lists->wind_direction, sizeof lists->wind_direction));
    ck_assert_str_eq(file->matrix_sha256, lists->matrix_sha256);
    ck_assert_ptr_null(strstr(file->canonical, "profile"));
    wt_config *back = NULL;
    ck_assert_int_eq(wt_config_parse(ctx, file->canonical, "canonical", 0, NULL, &back), WT_OK);
    ck_assert(!memcmp(back->layer_fraction, file->layer_fraction, sizeof back->layer_fraction));
    ck_assert_str_eq(back->matrix_sha256, file->matrix_sha256);
    wt_config_free(ctx, back);
    /* without the direction column, the directions come from the key */
    write_file(profile_path, "0 0.55 8\n600 0.1 10\n2000 0.1 12\n6000 0.15 18\n12000 0.1 25\n");
    wt_config_free(ctx, file);
    ck_assert_int_eq(read_with_profile(ctx, "atmosphere.wind_direction_deg=[0.0, 72.0, 144.0, 216.0, 288.0]", &file),
                     WT_OK);
    ck_assert(!memcmp(file->wind_direction, lists->wind_direction, sizeof lists->wind_direction));
    ck_assert(!memcmp(file->layer_fraction, lists->layer_fraction, sizeof lists->layer_fraction));
    wt_config_free(ctx, file);
    wt_config_free(ctx, lists);
    wt_context_free(ctx);
}
END_TEST

/* The shipped ESO profile reads (35 layers, normalised) and its preset gives each variant its compressed model. */
START_TEST(test_eso35_preset)
{
    wt_context *ctx = tu_context();
    char path[256];
    snprintf(path, sizeof path, "%sdata/presets/eelt-mcao-eso35.cfg", root());
    wt_config *c = NULL;
    ck_assert_msg(wt_config_read(ctx, path, 0, NULL, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(c->nlayers, 35);
    ck_assert(c->r0 == 0.155 && c->L0 == 25.0);
    double s = 0.0;
    for (int l = 0; l < 35; l++) s += c->layer_fraction[l];
    ck_assert_double_eq_tol(s, 1.0, 64 * DBL_EPSILON);
    ck_assert(c->layer_altitude[0] == 30.0 && c->layer_altitude[34] == 26500.0 && c->wind_speed[9] == 7.0);
    ck_assert_int_eq(c->model.source, WT_MODEL_ORACLE);
    ck_assert_int_eq(c->model.nlayers, 35);
    ck_assert_int_eq(c->cg9.nlayers, 9);
    ck_assert_int_eq(c->pcg3.nlayers, 3);
    wt_config_free(ctx, c);
    wt_context_free(ctx);
}
END_TEST

/* Each bad profile file: WT_ERR_CONFIG, and a message naming the file and line and what is wrong. */
static const struct bad_profile {
    const char *text, *expect;
} bad_profiles[] = {
    {"0 0.5 8\n600 -0.1 10\n2000 0.6 12\n", ":2: the Cn2 fraction -0.1 is negative"},
    {"0 0.5 8\n600 0.2 10\n600 0.3 12\n", ":3: altitude 600 m is not above the previous layer's 600 m (line 2)"},
    {"0 0.5 8\n# a comment line\n600 0.2 10\n300 0.3 12\n", ":4: altitude 300 m is not above"},
    {"0 0.5 8\n600 0.3 10\n2000 0.1 12\n", "sum to 0.9; expected 1 within 0.001"},
    {"0 0.5 8\n600 0.5\n", ":2: 2 columns; expected 3 or 4"},
    {"0 0.5 8 0 1\n600 0.5 9 0 1\n", ":1: 5 columns; expected 3 or 4"},
    {"0 0.5 8\n600 0.5 fast\n", ":2: column 3 (wind speed [m/s]): 'fast' is not a finite number"},
    {"0 0.5 8\n600 0.5x 9\n", ":2: column 2 (Cn2 fraction): '0.5x' is not a finite number"},
    {"0 0.5 8 10\n600 0.5 9\n", ":2: 3 columns, but the first layer (line 1) has 4"},
    {"0 0.5 8\n600 0.5 2000\n", ":2: column 3 (wind speed [m/s]): 2000 is out of range"},
    {"# nothing but a comment\n\n", "no layer in the profile file"},
    {"0 0.5 8\n600 nan 9\n", ":2: column 2 (Cn2 fraction): 'nan' is not a finite number"},
};

START_TEST(test_profile_bad_input)
{
    wt_context *ctx = tu_context();
    const struct bad_profile *b = &bad_profiles[_i];
    write_file(profile_path, b->text);
    wt_config *c = NULL;
    const int st = read_with_profile(ctx, "atmosphere.wind_direction_deg=[0.0, 90.0]", &c);
    ck_assert_int_eq(st, WT_ERR_CONFIG);
    ck_assert_ptr_null(c);
    const char *msg = wt_error_message(ctx);
    ck_assert_msg(strstr(msg, profile_path) && strstr(msg, b->expect), "case %d: '%s' lacks '%s'", _i, msg, b->expect);
    ck_assert_msg(strstr(msg, "atmosphere.profile"), "case %d: '%s' does not name the key", _i, msg);
    wt_context_free(ctx);
}
END_TEST

/* Conflicting keys: the lists beside a profile at the same level, directions missing or doubled; a missing file;
 * learned without its start model, a learning key without learning; a given model's key under the oracle, a given model without its keys. */
START_TEST(test_model_refusals)
{
    wt_context *ctx = tu_context();
    wt_config *c = NULL;
    write_file(profile_path, "0 0.5 8\n600 0.5 10\n");
    /* the demo's body gives the lists, an override the profile: the profile replaces them, but not their
     * directions (the body's five are another atmosphere's) */
    ck_assert_int_eq(read_with_profile(ctx, NULL, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "has no wind direction column: give 'atmosphere.wind_direction_deg' "
                                                "(2 values"), "%s", wt_error_message(ctx));
    /* two overrides: the profile and the lists */
    char p[128];
    snprintf(p, sizeof p, "atmosphere.profile=\"%s\"", profile_path);
    const char *both[] = {p, "atmosphere.wind_direction_deg=[0.0, 9.0]", "atmosphere.cn2_fractions=[0.5, 0.5]"};
    ck_assert_int_eq(read_demo(ctx, 3, both, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "key 'atmosphere.cn2_fractions' is given beside 'atmosphere.profile'"),
                  "%s", wt_error_message(ctx));
    write_file(profile_path, "0 0.5 8 0\n600 0.5 10 90\n");
    ck_assert_int_eq(read_demo(ctx, 2, both, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "key 'atmosphere.wind_direction_deg' is given beside"), "%s",
                  wt_error_message(ctx));
    const char *missing[] = {"atmosphere.profile=\"/nonexistent/profile.txt\""};
    ck_assert_int_eq(read_demo(ctx, 1, missing, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "cannot open the profile file '/nonexistent/profile.txt'"), "%s",
                  wt_error_message(ctx));
    const char *learned[] = {"recon.atmosphere.source=\"learned\""};
    ck_assert_int_eq(read_demo(ctx, 1, learned, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "\"learned\" but key 'recon.atmosphere.r0_m' is missing") &&
                      strstr(wt_error_message(ctx), "the one it starts from"), "%s", wt_error_message(ctx));
    const char *update_oracle[] = {"recon.atmosphere.update_s=30.0"};
    ck_assert_int_eq(read_demo(ctx, 1, update_oracle, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "key 'recon.atmosphere.update_s' is for a learned model, but "
                                                "'recon.atmosphere.source' is \"oracle\""), "%s", wt_error_message(ctx));
    const char *oracle_r0[] = {"recon.atmosphere.r0_m=0.1"};
    ck_assert_int_eq(read_demo(ctx, 1, oracle_r0, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "'recon.atmosphere.source' is \"oracle\" (its default)"), "%s",
                  wt_error_message(ctx));
    /* an oracle chosen explicitly keeps another source's model unused (a sweep over the sources) */
    const char *oracle_kept[] = {"recon.atmosphere.source=\"oracle\"", "recon.atmosphere.r0_m=0.1",
                                 "recon.atmosphere.update_s=30.0"};
    ck_assert_msg(read_demo(ctx, 3, oracle_kept, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(c->model.source == WT_MODEL_ORACLE && c->model.r0 == c->r0);
    wt_config_free(ctx, c);
    c = NULL;
    const char *given_bare[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.1"};
    ck_assert_int_eq(read_demo(ctx, 2, given_bare, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "key 'recon.atmosphere.L0_m' is missing"), "%s", wt_error_message(ctx));
    const char *given_sum[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.1", "recon.atmosphere.L0_m=25.0",
                               "recon.atmosphere.altitudes_m=[0.0, 9000.0]", "recon.atmosphere.cn2_fractions=[0.5, 0.3]",
                               "recon.atmosphere.wind_speed_mps=[5.0, 30.0]",
                               "recon.atmosphere.wind_direction_deg=[0.0, 90.0]"};
    ck_assert_int_eq(read_demo(ctx, 7, given_sum, &c), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "the fractions sum to 0.8"), "%s", wt_error_message(ctx));
    /* a given model from a file, in atmosphere.profile's format */
    const char *given_file[] = {"recon.atmosphere.source=\"given\"", "recon.atmosphere.r0_m=0.1",
                                "recon.atmosphere.L0_m=25.0", NULL};
    char gp[128];
    snprintf(gp, sizeof gp, "recon.atmosphere.profile=\"%s\"", profile_path);
    given_file[3] = gp;
    ck_assert_msg(read_demo(ctx, 4, given_file, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(c->model.nlayers == 2 && c->model.altitude[1] == 600.0 && c->model.fraction[1] == 0.5);
    ck_assert_str_eq(c->model.profile, profile_path);
    wt_config_free(ctx, c);
    wt_context_free(ctx);
}
END_TEST

/* The command line: a bad profile stops `wavetomo info` with exit status ≠ 0 and the file:line message. */
START_TEST(test_profile_cli)
{
    char wt[512], dir[64], cmd[2048];
    tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_profile_");
    snprintf(cmd, sizeof cmd, "%s/bad.txt", dir);
    write_file(cmd, "0 0.5 8 0\n600 -0.5 10 0\n");
    snprintf(cmd, sizeof cmd, "%s info --config %sdata/presets/demo.cfg --set 'atmosphere.profile=\"%s/bad.txt\"' "
             "--no-nnz > %s/out.txt 2>&1", wt, root(), dir, dir);
    const int rc = system(cmd);
    ck_assert_int_ne(rc, 0);
    snprintf(cmd, sizeof cmd, "grep -q 'bad.txt:2: the Cn2 fraction -0.5 is negative' %s/out.txt", dir);
    ck_assert_int_eq(system(cmd), 0);
    tu_cli_teardown(dir);
}
END_TEST

static void setup(void)
{
    snprintf(profile_path, sizeof profile_path, "/tmp/wt_profile_XXXXXX");
    const int fd = mkstemp(profile_path);
    ck_assert_int_ge(fd, 0);
    close(fd);
}

static void teardown(void) { unlink(profile_path); }

Suite *make_suite(void)
{
    Suite *s = suite_create("profile");
    TCase *tc = tcase_create("profile");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_compress_moments);
    tcase_add_test(tc, test_compress_hats);
    tcase_add_test(tc, test_compress_wind);
    tcase_add_test(tc, test_oracle_bit_identical);
    tcase_add_test(tc, test_given_as_oracle);
    tcase_add_test(tc, test_given_reaches_prior);
    tcase_add_test(tc, test_matrix_identity);
    tcase_add_test(tc, test_profile_file_equals_lists);
    tcase_add_test(tc, test_eso35_preset);
    tcase_add_loop_test(tc, test_profile_bad_input, 0, (int)(sizeof bad_profiles / sizeof bad_profiles[0]));
    tcase_add_test(tc, test_model_refusals);
    tcase_add_test(tc, test_profile_cli);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
