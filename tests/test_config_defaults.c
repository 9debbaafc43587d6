/* tests/test_config_defaults.c: a new system in a short file (examples/my-system.cfg): the keys left out take the
 * default their reference text documents, every missing required key is named in one error, and a group
 * redefined after @include points to the file's `overrides` list. */
#include "testutil.h"

#include <libconfig.h>

#include "core/config/config.h"

/* Source-tree files: tests run from its root (make test) or from tests/. */
static void src_path(const char *rel, char *buf, size_t n)
{
    snprintf(buf, n, "%s", rel);
    FILE *f = fopen(buf, "r");
    if (!f) snprintf(buf, n, "../%s", rel);
    else fclose(f);
}

static wt_config *read_minimal(wt_context *ctx)
{
    char path[256];
    src_path("examples/my-system.cfg", path, sizeof path);
    wt_config *c = NULL;
    int st = wt_config_read(ctx, path, 0, NULL, &c);
    ck_assert_msg(st == WT_OK, "%s: %s", path, wt_error_message(ctx));
    return c;
}

/* Every "(optional, default V)" of `wavetomo info --keys` with a value V in the minimal file's canonical text
 * (the keys it leaves out, filled as if written) is that value: the documentation cannot drift from the code. */
START_TEST(test_documented_defaults)
{
    wt_context *ctx = tu_context();
    wt_config *c = read_minimal(ctx);
    config_t cf;
    config_init(&cf);
    ck_assert_msg(config_read_string(&cf, c->canonical), "canonical text: %s", config_error_text(&cf));
    char *ref = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&ref, &len);
    wt_config_print_reference(f);
    fclose(f);
    int checked = 0;
    for (char *line = strtok(ref, "\n"); line; line = strtok(NULL, "\n")) {
        char key[128], val[64];
        const char *d = strstr(line, "(optional, default ");
        if (!d || sscanf(line, "%127s", key) != 1 || sscanf(d + 19, "%63[^ ,:;)]", val) != 1) continue;
        const config_setting_t *s = config_lookup(&cf, key);
        if (!s || config_setting_is_aggregate(s)) continue; /* an optional key without a value, or a list */
        switch (config_setting_type(s)) {
        case CONFIG_TYPE_BOOL:
            ck_assert_msg(!strcmp(val, config_setting_get_bool(s) ? "true" : "false"), "%s: documented %s", key, val);
            break;
        case CONFIG_TYPE_STRING:
            ck_assert_msg(!strcmp(val, config_setting_get_string(s)), "%s = \"%s\", documented %s", key,
                          config_setting_get_string(s), val);
            break;
        default: {
            char *end;
            const double want = strtod(val, &end);
            ck_assert_msg(*end == '\0', "%s: documented default '%s' is not a number", key, val);
            const double got = config_setting_type(s) == CONFIG_TYPE_FLOAT ? config_setting_get_float(s)
                                                                            : (double)config_setting_get_int64(s);
            ck_assert_msg(got == want, "%s = %.17g, documented %s", key, got, val);
        }
        }
        checked++;
    }
    /* the diffractive sensors' and the new keys' defaults: more than 60 keys are checked */
    ck_assert_int_ge(checked, 60);
    free(ref);
    config_destroy(&cf);

    /* the defaults that reach wt_config in internal units, and the lists taken from other keys */
    ck_assert_rel(c->lgs_altitude, 90000.0, 1e-15, 0);
    ck_assert_rel(c->lgs_tt_jitter, 0.2 * WT_ARCSEC, 1e-15, 0);
    ck_assert_rel(c->ngs_wfs.pixel, 0.05 * WT_ARCSEC, 1e-15, 0);
    ck_assert_rel(c->eval_wavelength, 2200e-9, 1e-15, 0);
    ck_assert_int_eq(c->frames, 200);
    ck_assert_int_eq(c->settle_frames, 20);
    ck_assert_uint_eq(c->seed, 1);
    ck_assert_int_eq(c->pcg3.nlayers, c->ndms);
    for (int l = 0; l < c->ndms; l++) ck_assert(c->pcg3.altitudes[l] == c->dm_altitude[l]);
    ck_assert_int_eq(c->cg9.nlayers, c->nlayers);
    for (int l = 0; l < c->nlayers; l++) ck_assert(c->cg9.altitudes[l] == c->layer_altitude[l]);
    wt_config_free(ctx, c);
    wt_context_free(ctx);
}
END_TEST

/* A default fills only what is left out: a file that writes each default explicitly has the same canonical text
 * and matrix identity (a matrix built from a full file is accepted for the short one), and --set on the key a
 * list default comes from moves the list too. */
START_TEST(test_defaults_as_if_written)
{
    wt_context *ctx = tu_context();
    wt_config *a = read_minimal(ctx);
    char path[256];
    src_path("examples/my-system.cfg", path, sizeof path);
    const char *ov[] = {"loop.gain=0.4", "lgs.launch_radius_m=0.0", "recon.pcg3.layer_altitudes_m=[0.0, 10000.0]",
                        "recon.cg9.iterations=20", "sim.seed=1"};
    wt_config *b = NULL;
    ck_assert_msg(wt_config_read(ctx, path, 5, ov, &b) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(a->canonical, b->canonical);
    ck_assert_str_eq(a->matrix_sha256, b->matrix_sha256);
    wt_config_free(ctx, b);
    const char *dm[] = {"dm.altitudes_m=[0.0, 8000.0]"};
    ck_assert_msg(wt_config_read(ctx, path, 1, dm, &b) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(b->pcg3.altitudes[1] == 8000.0);
    ck_assert_str_ne(a->matrix_sha256, b->matrix_sha256);
    wt_config_free(ctx, b);
    wt_config_free(ctx, a);
    wt_context_free(ctx);
}
END_TEST

/* Every missing required key in one message, each by name; a key given is not listed. */
START_TEST(test_missing_keys_listed)
{
    wt_context *ctx = tu_context();
    static const char text[] = "telescope = { diameter_m = 8.0; };\n"
                               "lgs = { count = 4; wfs = { subapertures = 16; }; };\n";
    wt_config *c = NULL;
    ck_assert_int_eq(wt_config_parse(ctx, text, "t.cfg", 0, NULL, &c), WT_ERR_CONFIG);
    ck_assert_ptr_null(c);
    const char *m = wt_error_message(ctx);
    static const char *const missing[] = {"telescope.obstruction", "atmosphere.r0_m", "atmosphere.L0_m",
                                          "atmosphere.altitudes_m", "atmosphere.cn2_fractions",
                                          "atmosphere.wind_speed_mps", "atmosphere.wind_direction_deg",
                                          "lgs.radius_arcsec", "lgs.azimuth0_deg", "lgs.wfs.photons",
                                          "ngs.radius_arcsec", "ngs.azimuths_deg", "ngs.subapertures",
                                          "ngs.wfs.photons", "dm.altitudes_m", "dm.pitch_m", "dm.actuators",
                                          "dm.field_radius_arcsec"};
    const int n = (int)(sizeof missing / sizeof *missing);
    char want[64];
    snprintf(want, sizeof want, "t.cfg: %d missing keys: ", n);
    ck_assert_msg(strstr(m, want) != NULL, "%s", m);
    for (int i = 0; i < n; i++) {
        snprintf(want, sizeof want, "'%s'", missing[i]);
        ck_assert_msg(strstr(m, want) != NULL, "%s not in: %s", want, m);
    }
    ck_assert_msg(strstr(m, "'lgs.count'") == NULL && strstr(m, "'telescope.diameter_m'") == NULL, "%s", m);
    ck_assert_msg(strstr(m, "loop.") == NULL, "a key with a default is listed: %s", m);
    wt_context_free(ctx);
}
END_TEST

/* A group of an @included file defined again: the syntax error names the file and line and says to use
 * overrides; the same change through overrides reads. */
START_TEST(test_duplicate_points_to_overrides)
{
    wt_context *ctx = tu_context();
    char demo[256], abs[4096], path[] = "/tmp/wt_test_defaults_XXXXXX";
    src_path("data/presets/demo.cfg", demo, sizeof demo);
    ck_assert_ptr_nonnull(realpath(demo, abs));
    int fd = mkstemp(path);
    ck_assert_int_ge(fd, 0);
    FILE *f = fdopen(fd, "w");
    fprintf(f, "@include \"%s\"\n\nloop = { gain = 0.3; };\n", abs);
    fclose(f);
    wt_config *c = NULL;
    ck_assert_int_eq(wt_config_read(ctx, path, 0, NULL, &c), WT_ERR_CONFIG);
    const char *m = wt_error_message(ctx);
    char want[128];
    snprintf(want, sizeof want, "%s:3: syntax error", path);
    ck_assert_msg(strstr(m, want) != NULL, "%s", m);
    ck_assert_msg(strstr(m, "duplicate") && strstr(m, "overrides = [") && strstr(m, "@include"), "%s", m);
    ck_assert_msg(strstr(m, abs) != NULL, "the included file is not named: %s", m);
    f = fopen(path, "w");
    fprintf(f, "@include \"%s\"\noverrides = [ \"loop.gain = 0.3\" ];\n", abs);
    fclose(f);
    ck_assert_msg(wt_config_read(ctx, path, 0, NULL, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(c->gain == 0.3);
    wt_config_free(ctx, c);
    remove(path);
    wt_context_free(ctx);
}
END_TEST

/* docs/guide.md shows examples/my-system.cfg: each of the file's settings lines is in the guide. */
START_TEST(test_guide_shows_example)
{
    char path[256], line[512];
    src_path("docs/guide.md", path, sizeof path);
    FILE *g = fopen(path, "r");
    ck_assert_ptr_nonnull(g);
    char *guide = NULL;
    size_t n = 0;
    ck_assert(getdelim(&guide, &n, '\0', g) > 0);
    fclose(g);
    src_path("examples/my-system.cfg", path, sizeof path);
    FILE *f = fopen(path, "r");
    ck_assert_ptr_nonnull(f);
    int lines = 0;
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '#' || line[0] == '\n') continue;
        ck_assert_msg(strstr(guide, line) != NULL, "docs/guide.md lacks the example's line: %s", line);
        lines++;
    }
    ck_assert_int_ge(lines, 10);
    fclose(f);
    free(guide);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("config_defaults");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_documented_defaults);
    tcase_add_test(tc, test_defaults_as_if_written);
    tcase_add_test(tc, test_missing_keys_listed);
    tcase_add_test(tc, test_duplicate_points_to_overrides);
    tcase_add_test(tc, test_guide_shows_example);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
