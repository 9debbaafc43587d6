/* tests/test_config_grid.c: the automatic reconstruction grids and sampling (core/config/config_grid.c): layer
 * grids of the presets and their combinations, oversampling, sensor and fitting points, the variants' priors. */
#include "testutil.h"

#include <unistd.h>

#include "config_fixture.h"
#include "core/base/sha256.h"
#include "core/config/config.h"
#include "core/model/system.h"

static wt_config *read_ok(wt_context *ctx, const char *file, int nov, const char *const *ov)
{
    wt_config *c = NULL;
    int st = read_preset(ctx, file, nov, ov, &c);
    ck_assert_msg(st == WT_OK, "%s: status %d: %s", file, st, wt_error_message(ctx));
    return c;
}

static void assert_grid(const wt_recon_variant_config *v, const double *spacing, const int *size)
{
    for (int l = 0; l < v->nlayers; l++) {
        ck_assert_msg(v->spacing[l] == spacing[l], "layer %d: spacing %.17g, want %.17g", l + 1, v->spacing[l], spacing[l]);
        ck_assert_msg(v->size[l] == size[l], "layer %d: size %d, want %d", l + 1, v->size[l], size[l]);
    }
}

/* Both keys left out ("auto" on the command line, since a preset's keys cannot be removed by --set): the
 * E-ELT's hand-tuned grids come back (pcg3 on the DM pitches 0.5/1/1 m, 128/64/64; cg9 128 x 0.5 m at all
 * nine altitudes, d = 0.5 m), so does the demo's pcg3 (32/16/32); the 42x42 preset is itself automatic (pcg3
 * 1/2/2 m, 64/32/32; cg9 at oversampling 2: 128 x 0.5 m from d = 1 m); and the configuration is the preset's
 * to the byte: the same canonical text and matrix hash, so an MVM built with either is accepted by the other. */
START_TEST(test_auto_grid_presets)
{
    wt_context *ctx = tu_context();
    const char *both[] = {"recon.pcg3.layer_spacing_m=auto", "recon.pcg3.layer_size=auto",
                          "recon.cg9.layer_spacing_m=auto", "recon.cg9.layer_size=auto"};
    static const struct {
        const char *file;
        double pcg3_spacing[3], cg9_spacing, cg9_base;
        int pcg3_size[3], cg9_size, cg9_same; /* cg9_same: the preset's cg9 grid is the automatic one */
        int preset_auto;                      /* the preset's own grids are automatic */
    } want[] = {{"eelt-mcao.cfg", {0.5, 1.0, 1.0}, 0.5, 0.5, {128, 64, 64}, 128, 1, 0},
                {"eelt-mcao-nea20-42.cfg", {1.0, 2.0, 2.0}, 0.5, 1.0, {64, 32, 32}, 128, 1, 1},
                {"demo.cfg", {0.5, 1.0, 1.0}, 0.5, 0.5, {32, 16, 32}, 32, 0, 0}};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) {
        wt_config *a = read_ok(ctx, want[i].file, 4, both), *e = read_ok(ctx, want[i].file, 0, NULL);
        assert_grid(&a->pcg3, want[i].pcg3_spacing, want[i].pcg3_size);
        ck_assert_int_eq(a->pcg3.grid_auto, WT_GRID_AUTO);
        ck_assert_int_eq(a->cg9.grid_auto, WT_GRID_AUTO);
        ck_assert_int_eq(e->pcg3.grid_auto, want[i].preset_auto ? WT_GRID_AUTO : WT_GRID_EXPLICIT);
        for (int l = 0; l < 3; l++) {
            ck_assert_int_eq(a->pcg3.grid_base_dm[l], l); /* the DM at the layer's altitude */
            ck_assert(a->pcg3.grid_base[l] == want[i].pcg3_spacing[l]);
        }
        const int nl = a->cg9.nlayers;
        for (int l = 0; l < nl && !strcmp(want[i].file, "demo.cfg"); l++) /* 12 km: the NGS at 80" need 64 */
            ck_assert_int_eq(a->cg9.size[l], l < nl - 1 ? want[i].cg9_size : 2 * want[i].cg9_size);
        for (int l = 0; l < nl; l++) {
            ck_assert(a->cg9.spacing[l] == want[i].cg9_spacing);
            ck_assert_int_eq(a->cg9.grid_base_dm[l], -1); /* d <= every DM pitch */
            ck_assert(a->cg9.grid_base[l] == want[i].cg9_base);
            if (want[i].cg9_same) ck_assert_int_eq(a->cg9.size[l], want[i].cg9_size);
        }
        if (want[i].cg9_same) {
            ck_assert_str_eq(a->canonical, e->canonical);
            ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
        }
        wt_config_free(ctx, a);
        wt_config_free(ctx, e);
    }
    /* the demo's pcg3 alone automatic: its preset grid, the same hash */
    wt_config *a = read_ok(ctx, "demo.cfg", 2, both), *e = read_ok(ctx, "demo.cfg", 0, NULL);
    ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
    ck_assert_str_eq(a->canonical, e->canonical);
    wt_config_free(ctx, a);
    wt_config_free(ctx, e);
    wt_context_free(ctx);
}
END_TEST

/* The oversampling divides the automatic spacing; the sizes follow (0.25 m on the demo). The canonical text
 * holds the chosen grid, not the oversampling, so the same grid given explicitly has the same text and
 * matrix hash, and the text reads back as the same values (a round trip). A spacing of 1/3 m is written with
 * the 15 digits the canonical text keeps, so that text reads back to the same bits. */
START_TEST(test_auto_grid_oversampling)
{
    wt_context *ctx = tu_context();
    const char *ov[] = {"recon.cg9.layer_spacing_m=auto", "recon.cg9.layer_size=auto", "recon.cg9.layer_oversampling=2"};
    wt_config *a = read_ok(ctx, "demo.cfg", 3, ov);
    for (int l = 0; l < a->cg9.nlayers; l++) {
        ck_assert(a->cg9.spacing[l] == 0.25);
        ck_assert(a->cg9.oversampling == 2.0);
    }
    const double s25[5] = {0.25, 0.25, 0.25, 0.25, 0.25};
    const int n25[5] = {64, 64, 64, 64, 128};
    assert_grid(&a->cg9, s25, n25);
    const char *ex[] = {"recon.cg9.layer_spacing_m=[0.25, 0.25, 0.25, 0.25, 0.25]", "recon.cg9.layer_size=[64, 64, 64, 64, 128]"};
    wt_config *e = read_ok(ctx, "demo.cfg", 2, ex);
    ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
    ck_assert_str_eq(a->canonical, e->canonical); /* the chosen grid, not the oversampling */
    wt_config *r = parse_ok(ctx, a->canonical, 0, NULL);
    ck_assert_str_eq(r->matrix_sha256, a->matrix_sha256);
    ck_assert_int_eq(r->cg9.grid_auto, WT_GRID_EXPLICIT);
    assert_grid(&r->cg9, a->cg9.spacing, a->cg9.size);
    wt_config_free(ctx, r);
    wt_config_free(ctx, a);
    wt_config_free(ctx, e);

    const char *third[] = {"recon.cg9.layer_spacing_m=auto", "recon.cg9.layer_size=auto", "recon.cg9.layer_oversampling=1.5"};
    a = read_ok(ctx, "demo.cfg", 3, third);
    ck_assert(a->cg9.spacing[0] == strtod("0.333333333333333", NULL));
    r = parse_ok(ctx, a->canonical, 0, NULL);
    assert_grid(&r->cg9, a->cg9.spacing, a->cg9.size);
    ck_assert_str_eq(r->matrix_sha256, a->matrix_sha256);
    wt_config_free(ctx, r);
    wt_config_free(ctx, a);
    wt_context_free(ctx);
}
END_TEST

/* One key of the two: a spacing without a size gives the smallest size for that spacing (the demo's cg9
 * 1 m layers at 6 km need only 16 points); a size without a spacing is refused, and so are an oversampling
 * beside a given spacing, a word other than "auto", and a grid beyond 8192 points; each message names the
 * keys. "auto" also reads from a file (a string). */
/* recon.sensor_points_per_subaperture left out (the presets): the fewest points q with d/q no coarser than
 * the finest layer of either variant: 1 on the E-ELT (0.5 m layers, d = 0.5 m) and on the 42x42 system with
 * 1 m layers (d = 1 m); 2 with the preset's 0.5 m cg9 layers, 4 for 0.3 m (ceil(1/0.3)); written into the canonical
 * text (same hash as the value given explicitly); an explicit value is kept. */
START_TEST(test_auto_sensor_points)
{
    wt_context *ctx = tu_context();
    wt_config *a = read_ok(ctx, "eelt-mcao.cfg", 0, NULL);
    ck_assert_int_eq(a->sensor_points, 1);
    wt_config_free(ctx, a);
    const char *metre[] = {"recon.cg9.layer_oversampling=1.0"};
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, metre);
    ck_assert_int_eq(a->sensor_points, 1);
    wt_config_free(ctx, a);
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 0, NULL); /* the preset: 0.5 m cg9 layers */
    ck_assert_int_eq(a->sensor_points, 2);
    const char *two[] = {"recon.sensor_points_per_subaperture=2"};
    wt_config *e = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, two);
    ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
    ck_assert_str_eq(a->canonical, e->canonical);
    wt_config_free(ctx, e);
    const char *one[] = {"recon.sensor_points_per_subaperture=1"};
    e = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, one);
    ck_assert_int_eq(e->sensor_points, 1);
    ck_assert_str_ne(a->matrix_sha256, e->matrix_sha256);
    wt_config_free(ctx, e);
    wt_config_free(ctx, a);
    /* bad values are refused naming the key: a word other than "auto", 0, beyond 16 */
    const char *bad[] = {"recon.sensor_points_per_subaperture=\"many\"", "recon.sensor_points_per_subaperture=0",
                         "recon.sensor_points_per_subaperture=17", "ngs.wfs.tilt=\"x\""};
    for (int i = 0; i < 4; i++) {
        wt_config *x = NULL;
        ck_assert_int_eq(read_preset(ctx, "eelt-mcao-nea20-42.cfg", 1, &bad[i], &x), WT_ERR_CONFIG);
        ck_assert_ptr_null(x);
        ck_assert_msg(strstr(wt_error_message(ctx), i < 3 ? "recon.sensor_points_per_subaperture" : "ngs.wfs.tilt"),
                      "%s: %s", bad[i], wt_error_message(ctx));
    }
    /* Z-tilt needs the lit-area model (the Fried model averages cell gradients: a G-tilt), refused at set-up */
    const char *zf[] = {"ngs.wfs.tilt=\"z\"", "recon.sensor_model=\"fried\""};
    a = read_ok(ctx, "demo.cfg", 2, zf);
    wt_system *sys = NULL;
    ck_assert_int_eq(wt_system_alloc(ctx, a, &sys), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "ngs.wfs.tilt"));
    wt_config_free(ctx, a);
    const char *third[] = {"recon.pcg3.layer_spacing_m=[0.3, 2.0, 2.0]", "recon.sensor_points_per_subaperture=auto"};
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 2, third);
    ck_assert_int_eq(a->sensor_points, 4); /* ceil(1 / 0.3) */
    wt_config_free(ctx, a);
    wt_context_free(ctx);
}
END_TEST

/* recon.cg9.fit_points_per_subaperture left out (the presets): the fewest q with d/q no coarser than half the
 * finer of the finest cg9 layer and the finest DM pitch: 2 on the E-ELT and the demo (0.5 m layers and DM,
 * d = 0.5 m), 4 on the 42x42 preset (0.5 m layers, 1 m DM, d = 1 m), 2 there with 1 m layers (min(1, 1)/2 =
 * 0.5 m), 8 with 0.25 m layers (1 / (0.5 · 0.25)); written into the canonical text
 * (same hash as the value given explicitly); an explicit value is kept; bad values are refused naming the key. */
START_TEST(test_auto_fit_points)
{
    wt_context *ctx = tu_context();
    const char *presets[] = {"eelt-mcao.cfg", "eelt-mcao-nea20.cfg", "demo.cfg", "eelt-mcao-nea20-42.cfg"};
    const int want[] = {2, 2, 2, 4};
    for (int i = 0; i < 4; i++) {
        wt_config *a = read_ok(ctx, presets[i], 0, NULL);
        ck_assert_msg(a->cg9.fit_sampling == want[i], "%s: %d", presets[i], a->cg9.fit_sampling);
        wt_config_free(ctx, a);
    }
    const char *metre[] = {"recon.cg9.layer_oversampling=1.0"};
    wt_config *a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, metre);
    ck_assert_int_eq(a->cg9.fit_sampling, 2);
    wt_config_free(ctx, a);
    const char *quarter[] = {"recon.cg9.layer_oversampling=4.0"};
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, quarter);
    ck_assert_int_eq(a->cg9.fit_sampling, 8);
    wt_config_free(ctx, a);
    const char *four[] = {"recon.cg9.fit_points_per_subaperture=4"};
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 0, NULL);
    wt_config *e = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, four);
    ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
    ck_assert_str_eq(a->canonical, e->canonical);
    wt_config_free(ctx, e);
    const char *two[] = {"recon.cg9.fit_points_per_subaperture=2"};
    e = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, two);
    ck_assert_int_eq(e->cg9.fit_sampling, 2);
    ck_assert_str_ne(a->canonical, e->canonical);
    wt_config_free(ctx, e);
    wt_config_free(ctx, a);
    const char *word[] = {"recon.cg9.fit_points_per_subaperture=\"auto\""};
    a = read_ok(ctx, "eelt-mcao-nea20-42.cfg", 1, word);
    ck_assert_int_eq(a->cg9.fit_sampling, 4);
    wt_config_free(ctx, a);
    const char *bad[] = {"recon.cg9.fit_points_per_subaperture=\"many\"", "recon.cg9.fit_points_per_subaperture=0",
                         "recon.cg9.fit_points_per_subaperture=17"};
    for (int i = 0; i < 3; i++) {
        wt_config *x = NULL;
        ck_assert_int_eq(read_preset(ctx, "eelt-mcao-nea20-42.cfg", 1, &bad[i], &x), WT_ERR_CONFIG);
        ck_assert_ptr_null(x);
        ck_assert_msg(strstr(wt_error_message(ctx), "recon.cg9.fit_points_per_subaperture"), "%s: %s", bad[i],
                      wt_error_message(ctx));
    }
    wt_context_free(ctx);
}
END_TEST

/* recon.<variant>.prior: given, it wins; left out (or "auto"), recon.prior when given, else the variant's
 * default (both full: config.h); the resolved value is written into the canonical text, so an
 * explicit value equal to the resolved one gives the same text and matrix hash, and another value another. */
START_TEST(test_variant_priors)
{
    wt_context *ctx = tu_context();
    const char *none[] = {"recon.prior=\"auto\""};
    wt_config *a = parse_ok(ctx, VALID, 1, none);
    ck_assert_int_eq(a->exact_prior, -1);
    ck_assert_int_eq(a->pcg3.prior, WT_PRIOR_DEFAULT_PCG3);
    ck_assert_int_eq(a->cg9.prior, WT_PRIOR_DEFAULT_CG9);
    const char *expl[] = {"recon.prior=\"auto\"", "recon.pcg3.prior=\"full\"", "recon.cg9.prior=\"full\""};
    wt_config *e = parse_ok(ctx, VALID, 3, expl);
    ck_assert_str_eq(a->canonical, e->canonical);
    ck_assert_str_eq(a->matrix_sha256, e->matrix_sha256);
    wt_config_free(ctx, e);
    const char *glob[] = {"recon.prior=\"exact\""};
    e = parse_ok(ctx, VALID, 1, glob);
    ck_assert_int_eq(e->pcg3.prior, WT_CFG_PRIOR_EXACT);
    ck_assert_int_eq(e->cg9.prior, WT_CFG_PRIOR_EXACT);
    ck_assert_str_ne(a->matrix_sha256, e->matrix_sha256);
    wt_config_free(ctx, e);
    const char *mixed[] = {"recon.prior=\"exact\"", "recon.cg9.prior=\"paper\""};
    e = parse_ok(ctx, VALID, 2, mixed);
    ck_assert_int_eq(e->pcg3.prior, WT_CFG_PRIOR_EXACT);
    ck_assert_int_eq(e->cg9.prior, WT_CFG_PRIOR_PAPER);
    ck_assert(strstr(e->canonical, "prior = \"paper\";") != NULL);
    wt_config_free(ctx, e);
    wt_config_free(ctx, a);
    const char *bad[] = {"recon.cg9.prior=\"diagonal\"", "recon.pcg3.prior=3"};
    for (int i = 0; i < 2; i++) {
        wt_config *x = NULL;
        ck_assert_int_eq(wt_config_parse(ctx, VALID, "test.cfg", 1, &bad[i], &x), WT_ERR_CONFIG);
        ck_assert_ptr_null(x);
        ck_assert_msg(strstr(wt_error_message(ctx), i ? "recon.pcg3.prior" : "recon.cg9.prior") &&
                          strstr(wt_error_message(ctx), "\"full\""), "%s: %s", bad[i], wt_error_message(ctx));
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_auto_grid_combinations)
{
    wt_context *ctx = tu_context();
    const char *sz[] = {"recon.cg9.layer_size=auto"};
    wt_config *c = read_ok(ctx, "demo.cfg", 1, sz);
    const double s[5] = {0.5, 0.5, 0.5, 1.0, 1.0};
    const int n[5] = {32, 32, 32, 16, 32};
    assert_grid(&c->cg9, s, n);
    ck_assert_int_eq(c->cg9.grid_auto, WT_GRID_AUTO_SIZE);
    ck_assert_int_eq(c->pcg3.grid_auto, WT_GRID_EXPLICIT);
    wt_config_free(ctx, c);

    static const struct {
        int nov;
        const char *ov[3];
        const char *want[3];
    } bad[] = {
        {1, {"recon.cg9.layer_spacing_m=auto"}, {"key 'recon.cg9.layer_size' is given but 'recon.cg9.layer_spacing_m' is left out", "demo.cfg:", ""}},
        {1, {"recon.pcg3.layer_oversampling=2"}, {"--set recon.pcg3.layer_oversampling=2", "'recon.pcg3.layer_spacing_m' (", "demo.cfg:"}},
        {2, {"recon.pcg3.layer_size=auto", "recon.pcg3.layer_oversampling=2"}, {"key 'recon.pcg3.layer_oversampling' is given with 'recon.pcg3.layer_spacing_m'", "", ""}},
        {1, {"recon.cg9.layer_size=automatic"}, {"key 'recon.cg9.layer_size'", "or \"auto\"", "\"automatic\""}},
        {2, {"recon.cg9.layer_size=auto", "recon.cg9.layer_spacing_m=[0.0005, 0.5, 0.5, 0.5, 0.5]"},
         {"'recon.cg9.layer_size' (left out: automatic) and 'recon.cg9.layer_spacing_m'", "layer 1 at 0 m", "more than the 8192"}},
        {3, {"recon.pcg3.layer_spacing_m=auto", "recon.pcg3.layer_size=auto", "recon.pcg3.layer_oversampling=0.1"},
         {"key 'recon.pcg3.layer_oversampling'", "out of range", ""}},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        c = (wt_config *)1;
        int st = read_preset(ctx, "demo.cfg", bad[i].nov, bad[i].ov, &c);
        ck_assert_msg(st == WT_ERR_CONFIG, "case %zu: status %d", i, st);
        ck_assert_ptr_null(c);
        for (int k = 0; k < 3; k++)
            ck_assert_msg(strstr(wt_error_message(ctx), bad[i].want[k]), "case %zu: \"%s\" lacks \"%s\"", i,
                          wt_error_message(ctx), bad[i].want[k]);
    }

    /* in a file: the string "auto", or the keys left out */
    int line;
    char *text = edit("layer_spacing_m = [0.5, 1.0, 1.0];", "layer_spacing_m = \"auto\";", NULL, &line);
    char *text2 = malloc(strlen(text) + 64);
    const char *from = strstr(text, "layer_size = [32, 16, 32];");
    ck_assert_ptr_nonnull(from);
    snprintf(text2, strlen(text) + 64, "%.*s%s", (int)(from - text), text, from + strlen("layer_size = [32, 16, 32];"));
    c = parse_ok(ctx, text2, 0, NULL);
    ck_assert_int_eq(c->pcg3.grid_auto, WT_GRID_AUTO);
    const double ps[3] = {0.5, 1.0, 1.0};
    const int pn[3] = {32, 16, 32};
    assert_grid(&c->pcg3, ps, pn);
    ck_assert_ptr_nonnull(strstr(c->canonical, "layer_size = [ 32, 16, 32 ]"));
    wt_config_free(ctx, c);
    free(text);
    free(text2);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("config_grid");
    TCase *tc_config = tcase_create("config");
    tcase_add_test(tc_config, test_auto_grid_presets);
    tcase_add_test(tc_config, test_auto_grid_oversampling);
    tcase_add_test(tc_config, test_auto_grid_combinations);
    tcase_add_test(tc_config, test_auto_sensor_points);
    tcase_add_test(tc_config, test_auto_fit_points);
    tcase_add_test(tc_config, test_variant_priors);
    suite_add_tcase(s, tc_config);
    return s;
}

TU_MAIN
