/* tests/test_config_canonical.c: the canonical form of a configuration (core/config/config_text.c,
 * config_schema.c): the same system written another way gives the same text, the matrix and noise hashes follow
 * exactly the keys that change them (profiles, wisdom, sodium), and every key of the reference has its line. */
#include "testutil.h"

#include <unistd.h>

#include "config_fixture.h"
#include "core/base/sha256.h"
#include "core/config/config.h"
#include "core/model/system.h"

/* The same system: groups and keys in another order, comments of all three kinds, other spacing,
 * integers where numbers are expected, ( ) lists instead of [ ] arrays, a bare integer seed. */
static const char REORDERED[] =
    "# the same system, shuffled\n"
    "recon = { cg9 = { fit_regularization = 0.001; fit_iterations = 4; preconditioner = \"none\";\n"
    "                  tolerance = 0; iterations = 10; layer_size = [32,32,32,32,32];\n"
    "                  layer_spacing_m = (0.5, 0.5, 0.5, 1, 1); layer_altitudes_m = (0, 600, 2000, 6000, 12000); };\n"
    "  pcg3 = { preconditioner = \"jacobi\"; tolerance = 0.0; iterations = 4; layer_size = [32, 16, 32];\n"
    "           layer_spacing_m = (0.5, 1, 1); layer_altitudes_m = (0, 4000, 12700); };\n"
    "  warm_start = true; prior = \"paper\"; wavelet_levels = 3; wavelet_order = 3; tau = 0.80; alpha = 1; };\n"
    "sim = { noise = true; seed = 1; points_per_subaperture = 4; };   // C++ comment\n"
    "loop = { gain = 0.4; delay_frames = 2; frames = 200; rate_hz = 500; };\n"
    "/* C comment */ evaluation = { settle_frames = 20; wavelength_nm = 2.2e3; spacing_arcsec = 30; grid = 5; };\n"
    "dm = { field_radius_arcsec = 84.853; actuators = [17, 13, 21]; pitch_m = (0.5, 1, 1); altitudes_m = (0, 4000, 12700); };\n"
    "ngs = { wfs = { pixels = 4; pixel_arcsec = 0.05; spot_fwhm_arcsec = 0.1; read_noise_e = 5; photons = 500; };\n"
    "        subapertures = [2, 1, 1]; azimuths_deg = (30, 150, 270); radius_arcsec = 80; };\n"
    "lgs = { wfs = { pixels = 4; pixel_arcsec = 1; spot_fwhm_arcsec = 1.1; read_noise_e = 3; photons = 100;\n"
    "                valid_fraction = 0.5; subapertures = 16; };\n"
    "        tt_jitter_arcsec = 0.2; launch_radius_m = 4.5; sodium_fwhm_m = 1e4; altitude_m = 9e4;\n"
    "        azimuth0_deg = 0; radius_arcsec = 45; count = 4; };\n"
    "atmosphere = { wind_direction_deg = (0, 72, 144, 216, 288); wind_speed_mps = (8, 10, 12, 18, 25);\n"
    "   cn2_fractions = [0.55, 0.10, 0.10, 0.15, 0.10]; altitudes_m = (0, 600, 2000, 6000, 12000);\n"
    "   L0_m = 25; r0_m = 0.129; };\n"
    "telescope = { obstruction = 0.28; diameter_m = 8; };\n";

/* Everything but the owned pointers, for a whole-struct comparison (both were calloc'd, so padding is 0). */
static void assert_same_values(const wt_config *a, const wt_config *b)
{
    wt_config x, y;
    memcpy(&x, a, sizeof x);
    memcpy(&y, b, sizeof y);
    x.canonical = y.canonical = NULL;
    x.matrix_text = y.matrix_text = NULL;
    memset(x.path, 0, sizeof x.path);
    memset(y.path, 0, sizeof y.path);
    ck_assert_msg(memcmp(&x, &y, sizeof x) == 0, "typed values differ");
}

START_TEST(test_canonical)
{
    wt_context *ctx = tu_context();
    wt_config *a = parse_ok(ctx, VALID, 0, NULL);
    wt_config *b = parse_ok(ctx, REORDERED, 0, NULL);
    ck_assert_str_eq(a->canonical, b->canonical);
    assert_same_values(a, b);

    /* the canonical text reads back to itself and to the same values */
    wt_config *c = parse_ok(ctx, a->canonical, 0, NULL);
    ck_assert_str_eq(c->canonical, a->canonical);
    assert_same_values(a, c);

    /* one value changed, in the file or by --set: another text */
    const char *ov[] = {"atmosphere.r0_m=0.13"};
    wt_config *d = parse_ok(ctx, VALID, 1, ov);
    ck_assert_str_ne(d->canonical, a->canonical);
    ck_assert(strstr(d->canonical, "r0_m = 0.13;") != NULL);
    const char *ov2[] = {"sim.seed=2"};
    wt_config *e = parse_ok(ctx, VALID, 1, ov2);
    ck_assert_str_ne(e->canonical, a->canonical);
    /* an optional key only appears once given */
    ck_assert(strstr(a->canonical, "nea_mas") == NULL);
    const char *ov3[] = {"ngs.wfs.nea_mas=5.0"};
    wt_config *f = parse_ok(ctx, VALID, 1, ov3);
    ck_assert(strstr(f->canonical, "nea_mas = 5.0;") != NULL);
    wt_config *g = parse_ok(ctx, f->canonical, 0, NULL);
    assert_same_values(f, g);
    wt_config *cs[] = {a, b, c, d, e, f, g};
    for (int i = 0; i < 7; i++) wt_config_free(ctx, cs[i]);
    wt_context_free(ctx);
}
END_TEST

/* The matrix identity (SPEC §9): keys that change R change the hash; the simulation-only keys do not. */
START_TEST(test_matrix_hash)
{
    wt_context *ctx = tu_context();
    const char *path = "data/presets/demo.cfg";
    wt_config *base, *c;
    ck_assert_int_eq(wt_config_read(ctx, path, 0, NULL, &base), WT_OK);
    ck_assert_int_eq(strlen(base->matrix_sha256), 64);
    const char *same[] = {"sim.seed=7", "loop.gain=0.3", "atmosphere.wind_speed_mps=[1.0, 2.0, 3.0, 4.0, 5.0]",
                          "recon.pcg3.iterations=9", "lgs.tt_jitter_arcsec=0.5", "loop.frames=50",
                          "loop.gain_levels=[0.6, 0.4]"};
    const char *differ[] = {"recon.alpha=2.0", "lgs.wfs.photons=50.0", "recon.tau=0.5", "dm.field_radius_arcsec=80.0",
                            "atmosphere.r0_m=0.15", "evaluation.spacing_arcsec=20.0"};
    for (size_t i = 0; i < sizeof same / sizeof *same; i++) {
        ck_assert_int_eq(wt_config_read(ctx, path, 1, &same[i], &c), WT_OK);
        ck_assert_msg(!strcmp(c->matrix_sha256, base->matrix_sha256), "%s changed the matrix hash", same[i]);
        ck_assert_str_ne(c->canonical, base->canonical);
        wt_config_free(ctx, c);
    }
    for (size_t i = 0; i < sizeof differ / sizeof *differ; i++) {
        ck_assert_int_eq(wt_config_read(ctx, path, 1, &differ[i], &c), WT_OK);
        ck_assert_msg(strcmp(c->matrix_sha256, base->matrix_sha256), "%s left the matrix hash unchanged", differ[i]);
        wt_config_free(ctx, c);
    }
    /* with a variant's loop_noise_average the loop's gain and delay set the noise model: then they are hashed */
    const char *avg[] = {"recon.pcg3.loop_noise_average=true", "loop.gain=0.3"};
    wt_config *a0, *a1;
    ck_assert_int_eq(wt_config_read(ctx, path, 1, avg, &a0), WT_OK);
    ck_assert_int_eq(wt_config_read(ctx, path, 2, avg, &a1), WT_OK);
    ck_assert_str_ne(a0->matrix_sha256, base->matrix_sha256);
    ck_assert_str_ne(a1->matrix_sha256, a0->matrix_sha256);
    wt_config_free(ctx, a0);
    wt_config_free(ctx, a1);
    wt_config_free(ctx, base);
    wt_context_free(ctx);
}
END_TEST

/* The sodium profile enters the matrix identity by its contents (lgs.sodium_profile_sha256), not by its name:
 * an edited profile changes the hash (an MVM built with the old one is refused), the same bytes under another
 * name do not; a stored text keeps the recorded hash, and the sensors refuse a file that no longer has it. */
static void write_profile(const char *path, double mid)
{
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fprintf(f, "# test profile\n80000 0\n85000 0.6\n90000 %.17g\n95000 0.4\n100000 0\n", mid);
    ck_assert_int_eq(fclose(f), 0);
}

static wt_config *read_with_profile(wt_context *ctx, const char *file, const char *model)
{
    char set[600], mset[80];
    snprintf(set, sizeof set, "lgs.sodium_profile=\"%s\"", file);
    snprintf(mset, sizeof mset, "lgs.wfs.model=\"%s\"", model);
    const char *ov[] = {set, mset};
    wt_config *c = NULL;
    const int st = read_preset(ctx, "demo-diffractive.cfg", 2, ov, &c);
    ck_assert_msg(st == WT_OK, "status %d: %s", st, wt_error_message(ctx));
    return c;
}

/* sim.noise enters the matrix identity exactly when a diffractive sensor uses the tCoG (calibrated at the
 * operating noise when the simulation has noise: core/optics/centroid.h), for the LGS or the NGS. */
START_TEST(test_noise_hash_tcog)
{
    wt_context *ctx = tu_context();
    struct { const char *lgs, *ngs; int in; } cases[] = {
        {"mf", "tcog", 1}, {"tcog", "cog", 1}, {"mf", "cog", 0}, {"cog", "mf", 0}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char l[64], n[64];
        snprintf(l, sizeof l, "lgs.wfs.centroider=\"%s\"", cases[i].lgs);
        snprintf(n, sizeof n, "ngs.wfs.centroider=\"%s\"", cases[i].ngs);
        const char *on[] = {l, n, "sim.noise=true"}, *off[] = {l, n, "sim.noise=false"};
        wt_config *a = NULL, *b = NULL;
        ck_assert_int_eq(read_preset(ctx, "demo-diffractive.cfg", 3, on, &a), WT_OK);
        ck_assert_int_eq(read_preset(ctx, "demo-diffractive.cfg", 3, off, &b), WT_OK);
        ck_assert_msg((strcmp(a->matrix_sha256, b->matrix_sha256) != 0) == cases[i].in,
                      "lgs %s, ngs %s: sim.noise %s the matrix hash", cases[i].lgs, cases[i].ngs,
                      cases[i].in ? "left" : "changed");
        /* the geometric model of the same sensors: never */
        const char *gon[] = {l, n, "sim.noise=true", "lgs.wfs.model=\"geometric\"", "ngs.wfs.model=\"geometric\""};
        const char *goff[] = {l, n, "sim.noise=false", "lgs.wfs.model=\"geometric\"", "ngs.wfs.model=\"geometric\""};
        wt_config *c = NULL, *d = NULL;
        ck_assert_int_eq(read_preset(ctx, "demo-diffractive.cfg", 5, gon, &c), WT_OK);
        ck_assert_int_eq(read_preset(ctx, "demo-diffractive.cfg", 5, goff, &d), WT_OK);
        ck_assert_str_eq(c->matrix_sha256, d->matrix_sha256);
        wt_config_free(ctx, a), wt_config_free(ctx, b), wt_config_free(ctx, c), wt_config_free(ctx, d);
    }
    wt_context_free(ctx);
}
END_TEST

/* recon.fft_wisdom chooses how FFTs are planned, not what the matrices are: its file's SHA-256 is recorded in
 * the canonical text (every output says which plans ran), the matrix identity ignores both keys; a stored text
 * keeps the recorded hash whatever the file holds now (the reconstructor's set-up checks it: test_fft); a
 * missing file leaves the hash empty here (the set-up refuses it naming the file). */
START_TEST(test_fft_wisdom_keys)
{
    wt_context *ctx = tu_context();
    char path[64] = "/tmp/wt_wis_XXXXXX", set[128], want[65];
    const int fd = mkstemp(path);
    ck_assert(fd >= 0);
    close(fd);
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fputs("(fftw-3.3.10 fftw_wisdom #x0 #x0 #x0 #x0\n)\n", f);
    ck_assert_int_eq(fclose(f), 0);
    ck_assert_int_eq(wt_sha256_file(path, want), 0);
    snprintf(set, sizeof set, "recon.fft_wisdom=\"%s\"", path);
    const char *ov[] = {set};
    wt_config *plain = NULL, *c = NULL, *r = NULL, *gone = NULL;
    ck_assert_int_eq(read_preset(ctx, "demo.cfg", 0, NULL, &plain), WT_OK);
    ck_assert_int_eq(read_preset(ctx, "demo.cfg", 1, ov, &c), WT_OK);
    ck_assert_str_eq(plain->fft_wisdom, "");
    ck_assert_str_eq(plain->fft_wisdom_sha256, "");
    ck_assert_str_eq(c->fft_wisdom, path);
    ck_assert_str_eq(c->fft_wisdom_sha256, want);
    ck_assert_ptr_nonnull(strstr(c->canonical, want));
    ck_assert_ptr_null(strstr(c->matrix_text, "fft_wisdom"));
    ck_assert_str_eq(c->matrix_sha256, plain->matrix_sha256);
    f = fopen(path, "a");
    fputs(" ", f);
    fclose(f);
    r = parse_ok(ctx, c->canonical, 0, NULL);
    ck_assert_str_eq(r->fft_wisdom_sha256, want);
    remove(path);
    ck_assert_int_eq(read_preset(ctx, "demo.cfg", 1, ov, &gone), WT_OK);
    ck_assert_str_eq(gone->fft_wisdom_sha256, "");
    /* "" turns a stored file off (the same as left out); a path key without that flag still refuses "" */
    const char *off[] = {"recon.fft_wisdom=\"\""}, *na[] = {"lgs.sodium_profile=\"\""};
    wt_config *e = parse_ok(ctx, c->canonical, 1, off), *x = NULL;
    ck_assert_str_eq(e->fft_wisdom, "");
    ck_assert_int_eq(wt_config_parse(ctx, c->canonical, NAME, 1, na, &x), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lgs.sodium_profile"));
    wt_config_free(ctx, e);
    wt_config_free(ctx, plain), wt_config_free(ctx, c), wt_config_free(ctx, r), wt_config_free(ctx, gone);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_sodium_profile_hash)
{
    wt_context *ctx = tu_context();
    char a[64] = "/tmp/wt_na_a_XXXXXX", b[64] = "/tmp/wt_na_b_XXXXXX", want[65], bytes[4096];
    int fa = mkstemp(a), fb = mkstemp(b);
    ck_assert(fa >= 0 && fb >= 0);
    close(fa), close(fb);
    write_profile(a, 1.0);
    write_profile(b, 1.0);
    FILE *f = fopen(a, "rb");
    const size_t n = fread(bytes, 1, sizeof bytes, f);
    fclose(f);
    wt_sha256_hex(bytes, n, want);

    wt_config *c1 = read_with_profile(ctx, a, "diffractive");
    ck_assert_str_eq(c1->sodium_profile_sha256, want);
    ck_assert_ptr_nonnull(strstr(c1->canonical, want));   /* recorded in the canonical text */
    ck_assert_ptr_nonnull(strstr(c1->matrix_text, want)); /* and in the matrix identity */
    ck_assert_ptr_null(strstr(c1->matrix_text, a));       /* by contents, not by name */
    wt_config *same = read_with_profile(ctx, b, "diffractive");
    ck_assert_str_eq(same->matrix_sha256, c1->matrix_sha256);

    /* one density changed: another matrix */
    write_profile(a, 0.9);
    wt_config *c2 = read_with_profile(ctx, a, "diffractive");
    ck_assert_str_ne(c2->sodium_profile_sha256, c1->sodium_profile_sha256);
    ck_assert_str_ne(c2->matrix_sha256, c1->matrix_sha256);

    /* the geometric model ignores the file: not hashed, the matrix does not depend on it */
    wt_config *g1 = read_with_profile(ctx, a, "geometric");
    write_profile(a, 1.0);
    wt_config *g2 = read_with_profile(ctx, a, "geometric");
    ck_assert_str_eq(g1->sodium_profile_sha256, "");
    ck_assert_str_eq(g1->matrix_sha256, g2->matrix_sha256);

    /* the stored text reads back to the recorded hash whatever the file holds now; the sensors check it */
    write_profile(a, 0.9);
    wt_config *r = parse_ok(ctx, c1->canonical, 0, NULL);
    ck_assert_str_eq(r->sodium_profile_sha256, c1->sodium_profile_sha256);
    ck_assert_str_eq(r->matrix_sha256, c1->matrix_sha256);
    wt_system *sys = NULL;
    ck_assert_int_eq(wt_system_alloc(ctx, r, &sys), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lgs.sodium_profile_sha256"));
    ck_assert_ptr_null(sys);
    /* "auto" takes the file as it is now */
    const char *au = "lgs.sodium_profile_sha256=auto";
    wt_config *r2 = parse_ok(ctx, c1->canonical, 1, &au);
    ck_assert_str_eq(r2->matrix_sha256, c2->matrix_sha256);
    ck_assert_int_eq(wt_system_alloc(ctx, r2, &sys), WT_OK);
    wt_system_free(sys);
    /* a malformed hash is refused naming the key */
    const char *bad = "lgs.sodium_profile_sha256=\"abc\"";
    wt_config *x = NULL;
    ck_assert_int_eq(wt_config_parse(ctx, c1->canonical, NAME, 1, &bad, &x), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lgs.sodium_profile_sha256"));

    wt_config_free(ctx, c1);
    wt_config_free(ctx, c2);
    wt_config_free(ctx, same);
    wt_config_free(ctx, g1);
    wt_config_free(ctx, g2);
    wt_config_free(ctx, r);
    wt_config_free(ctx, r2);
    unlink(a);
    unlink(b);
    wt_context_free(ctx);
}
END_TEST

/* Every key of a full canonical text has a line in the reference, with its unit where it has one. */
START_TEST(test_reference)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wt_config_print_reference(f);
    fclose(f);
    wt_context *ctx = tu_context();
    /* so that the optional keys appear too (the stochastic night's: all but atmosphere.night.file) */
    const char *ov[] = {"lgs.wfs.nea_mas=1.0", "ngs.wfs.nea_mas=1.0", "atmosphere.night.source=\"random\"",
                        "atmosphere.night.start_s=10.0", "atmosphere.night.compression=100.0",
                        "atmosphere.night.seed=3", "atmosphere.night.correlation_time_s=600.0",
                        "atmosphere.night.step_s=5.0", "atmosphere.night.r0_log_rms=0.1",
                        "atmosphere.night.fraction_log_rms=0.2", "atmosphere.night.wind_speed_log_rms=0.1",
                        "atmosphere.night.wind_direction_rms_deg=5.0"};
    wt_config *c = parse_ok(ctx, VALID, (int)(sizeof ov / sizeof *ov), ov);
    char group[4][64], path[256];
    int depth = 0, nkeys = 0, nlines = 0;
    for (const char *s = buf; *s; s++) nlines += *s == '\n';
    for (char *line = strtok(c->canonical, "\n"); line; line = strtok(NULL, "\n")) {
        char name[64];
        while (*line == ' ') line++;
        if (!strncmp(line, "};", 2)) {
            depth--;
            continue;
        }
        ck_assert_int_eq(sscanf(line, "%63s", name), 1);
        path[0] = '\0';
        for (int i = 0; i < depth; i++) strcat(strcat(path, group[i]), ".");
        strcat(path, name);
        if (strstr(line, "= {")) {
            snprintf(group[depth++], sizeof group[0], "%s", name);
            continue;
        }
        nkeys++;
        const char *at = buf;
        while (at && !((at == buf || at[-1] == '\n') && !strncmp(at, path, strlen(path)) && at[strlen(path)] == ' '))
            at = strchr(at + 1, path[0]);
        ck_assert_msg(at != NULL, "no reference line for %s", path);
        const char *u = strrchr(path, '_');
        if (u && strcmp(u, "_e") && strcmp(u, "_fractions") && !strstr(path, "warm_start") && !strstr(path, "_size") &&
            !strstr(path, "_order") && !strstr(path, "_levels") && !strstr(path, "_frames") && !strstr(path, "_fraction") &&
            !strstr(path, "_iterations") && !strstr(path, "_regularization") && !strstr(path, "_subaperture") && !strstr(path, "_rings") && !strstr(path, "_aliasing") && !strstr(path, "_model") && !strstr(path, "lit_noise") && !strstr(path, "model_error") && !strstr(path, "subgrid_error") && !strstr(path, "focus_removal") && !strstr(path, "_precision") && !strstr(path, "noise_average") && !strstr(path, "_solver") && !strstr(path, "_kernels") && !strstr(path, "_integrator") &&
            /* the diffractive sensor's keys without a unit (counts, switches, seeds, ratios) */
            !strstr(path, "apply_gain") && !strstr(path, "tcog_threshold_") && !strstr(path, "_pixels") &&
            !strstr(path, "_samples") && !strstr(path, "cells_per_pixel") && !strstr(path, "calibration") &&
            !strstr(path, "_sha256") && !strstr(path, "reference_seeing") &&
            /* the stochastic night's rms of a logarithm (a ratio); a dimensionless factor (error_*_scale) */
            !strstr(path, "_log_rms") && !strstr(path, "_scale")) {
            char unit[32];
            snprintf(unit, sizeof unit, "[%s]", !strcmp(u, "_mps") ? "m/s" : !strcmp(u, "_hz") ? "Hz" : u + 1);
            char ref[512];
            snprintf(ref, sizeof ref, "%.*s", (int)strcspn(at, "\n"), at);
            ck_assert_msg(strstr(ref, unit) != NULL, "%s: unit %s not in its line", path, unit);
        }
    }
    /* one line per key, no more; the two layer_oversampling keys never reach the canonical text (the grid
     * they chose does), nor do lgs.sodium_profile, recon.fft_wisdom and their hashes, loop.gain_levels and
     * loop.gain_basis when left out (the demo), nor the profile files (their lists do) and the given model's seven
     * keys under the oracle (the demo's: its source is there), nor the learned model's six, nor
     * atmosphere.night.file for a stochastic night, nor the seven keys of a model error (recon.atmosphere.error_*)
     * without one, nor the four of the sodium layer in time (lgs.sodium_sequence*, lgs.wfs.reference*: diffractive
     * LGS only) and the matched filter's gain from the pixels (lgs.wfs.gain_update_s, the same), nor recon.lgs_focus_mode left out (the removal's mode, read only beside it), nor sim.psf_wavelengths_nm and
     * sim.telemetry_maps_interval_frames when left out, nor the LGS focus stage's two (lgs.wfs.focus_stage*: diffractive
     * LGS with the removal only) */
    ck_assert_int_eq(nkeys + 40, nlines);
    ck_assert_ptr_nonnull(strstr(buf, "\natmosphere.night.file "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.atmosphere.error_high_shift_m "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.atmosphere.source "));
    ck_assert_ptr_nonnull(strstr(buf, "\natmosphere.profile "));
    ck_assert_ptr_nonnull(strstr(buf, "\nloop.gain_levels "));
    ck_assert_ptr_nonnull(strstr(buf, "\nloop.gain_basis "));
    ck_assert_ptr_nonnull(strstr(buf, "\nlgs.sodium_profile "));
    ck_assert_ptr_nonnull(strstr(buf, "\nlgs.sodium_profile_sha256 "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.fft_wisdom "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.fft_wisdom_sha256 "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.pcg3.layer_oversampling "));
    ck_assert_ptr_nonnull(strstr(buf, "\nrecon.cg9.layer_oversampling "));
    wt_config_free(ctx, c);
    wt_context_free(ctx);
    free(buf);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("config_canonical");
    TCase *tc_config = tcase_create("config");
    tcase_add_test(tc_config, test_canonical);
    tcase_add_test(tc_config, test_matrix_hash);
    tcase_add_test(tc_config, test_sodium_profile_hash);
    tcase_add_test(tc_config, test_fft_wisdom_keys);
    tcase_add_test(tc_config, test_noise_hash_tcog);
    tcase_add_test(tc_config, test_reference);
    suite_add_tcase(s, tc_config);
    return s;
}

TU_MAIN
