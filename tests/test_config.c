/* tests/test_config.c: the configuration reader (core/config/config_read.c): presets, canonical text, --set
 * overrides, and a table of malformed inputs that must each be refused with a precise message. */
#include "testutil.h"

#include <unistd.h>

#include "core/base/sha256.h"
#include "core/config/config.h"
#include "core/model/system.h"

#define NAME "t.cfg"

/* A small valid system, one key per line so that a test can break one line and know its number. */
static const char VALID[] =
    "telescope = { diameter_m = 8.0; obstruction = 0.28; };\n"
    "atmosphere = {\n"
    "  r0_m = 0.129;\n"
    "  L0_m = 25.0;\n"
    "  altitudes_m = [0.0, 600.0, 2000.0, 6000.0, 12000.0];\n"
    "  cn2_fractions = [0.55, 0.1, 0.1, 0.15, 0.1];\n"
    "  wind_speed_mps = [8.0, 10.0, 12.0, 18.0, 25.0];\n"
    "  wind_direction_deg = [0.0, 72.0, 144.0, 216.0, 288.0];\n"
    "};\n"
    "lgs = {\n"
    "  count = 4;\n"
    "  radius_arcsec = 45.0;\n"
    "  azimuth0_deg = 0.0;\n"
    "  altitude_m = 90000.0;\n"
    "  sodium_fwhm_m = 10000.0;\n"
    "  launch_radius_m = 4.5;\n"
    "  tt_jitter_arcsec = 0.2;\n"
    "  wfs = {\n"
    "    subapertures = 16;\n"
    "    valid_fraction = 0.5;\n"
    "    photons = 100.0;\n"
    "    read_noise_e = 3.0;\n"
    "    spot_fwhm_arcsec = 1.1;\n"
    "    pixel_arcsec = 1.0;\n"
    "    pixels = 4;\n"
    "  };\n"
    "};\n"
    "ngs = {\n"
    "  radius_arcsec = 80.0;\n"
    "  azimuths_deg = [30.0, 150.0, 270.0];\n"
    "  subapertures = [2, 1, 1];\n"
    "  wfs = { photons = 500.0; read_noise_e = 5.0; spot_fwhm_arcsec = 0.1; pixel_arcsec = 0.05; pixels = 4; };\n"
    "};\n"
    "dm = {\n"
    "  altitudes_m = [0.0, 4000.0, 12700.0];\n"
    "  pitch_m = [0.5, 1.0, 1.0];\n"
    "  actuators = [17, 13, 21];\n"
    "  field_radius_arcsec = 84.853;\n"
    "};\n"
    "evaluation = {\n"
    "  grid = 5;\n"
    "  spacing_arcsec = 30.0;\n"
    "  wavelength_nm = 2200.0;\n"
    "  settle_frames = 20;\n"
    "};\n"
    "loop = {\n"
    "  rate_hz = 500.0;\n"
    "  frames = 200;\n"
    "  delay_frames = 2;\n"
    "  gain = 0.4;\n"
    "};\n"
    "sim = { points_per_subaperture = 4; seed = 1; noise = true; };\n"
    "recon = {\n"
    "  alpha = 1.0;\n"
    "  tau = 0.8;\n"
    "  wavelet_order = 3;\n"
    "  wavelet_levels = 3;\n"
    "  prior = \"paper\";\n"
    "  warm_start = true;\n"
    "  pcg3 = {\n"
    "    layer_altitudes_m = [0.0, 4000.0, 12700.0];\n"
    "    layer_spacing_m = [0.5, 1.0, 1.0];\n"
    "    layer_size = [32, 16, 32];\n"
    "    iterations = 4;\n"
    "    tolerance = 0.0;\n"
    "    preconditioner = \"jacobi\";\n"
    "  };\n"
    "  cg9 = {\n"
    "    layer_altitudes_m = [0.0, 600.0, 2000.0, 6000.0, 12000.0];\n"
    "    layer_spacing_m = [0.5, 0.5, 0.5, 1.0, 1.0];\n"
    "    layer_size = [32, 32, 32, 32, 32];\n"
    "    iterations = 10;\n"
    "    tolerance = 0.0;\n"
    "    preconditioner = \"none\";\n"
    "    fit_iterations = 4;\n"
    "    fit_regularization = 1e-3;\n"
    "  };\n"
    "};\n";

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

/* Presets live in data/presets of the source tree; tests run from its root (make test) or from tests/. */
static int read_preset(wt_context *ctx, const char *file, int nov, const char *const *ov, wt_config **out)
{
    char path[256];
    snprintf(path, sizeof path, "data/presets/%s", file);
    FILE *f = fopen(path, "r");
    if (!f) snprintf(path, sizeof path, "../data/presets/%s", file);
    else fclose(f);
    return wt_config_read(ctx, path, nov, ov, out);
}

static wt_config *parse_ok(wt_context *ctx, const char *text, int nov, const char *const *ov)
{
    wt_config *cfg = NULL;
    int st = wt_config_parse(ctx, text, NAME, nov, ov, &cfg);
    ck_assert_msg(st == WT_OK, "status %d: %s", st, wt_error_message(ctx));
    ck_assert_ptr_nonnull(cfg);
    ck_assert_ptr_nonnull(cfg->canonical);
    return cfg;
}

/* Unit conversions are one multiplication each, so the stored values equal the expression below to
 * the last bit or within one rounding of the product (2 ulp). */
#define ULP2 4.5e-16

START_TEST(test_eelt_preset)
{
    wt_context *ctx = tu_context();
    wt_config *c = NULL;
    int st = read_preset(ctx, "eelt-mcao.cfg", 0, NULL, &c);
    ck_assert_msg(st == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(strstr(c->path, "eelt-mcao.cfg") != NULL);
    ck_assert_rel(c->diameter, 42.0, ULP2, 0);
    ck_assert_rel(c->obstruction, 0.28, ULP2, 0);
    ck_assert_rel(c->r0, 0.129, ULP2, 0);
    ck_assert_int_eq(c->nlayers, 9);
    ck_assert_rel(c->layer_altitude[0], 47.0, ULP2, 0);
    ck_assert_rel(c->layer_altitude[8], 18000.0, ULP2, 0);
    /* the SPEC fractions sum to 1 in decimal; normalising changes them by rounding only */
    double sum = 0.0;
    for (int i = 0; i < 9; i++) sum += c->layer_fraction[i];
    ck_assert_rel(sum, 1.0, 1e-15, 0);
    ck_assert_rel(c->layer_fraction[0], 0.5224, 1e-15, 0);
    ck_assert_rel(c->wind_speed[7], 40.0, ULP2, 0);
    ck_assert_rel(c->wind_direction[1], 40.0 * M_PI / 180.0, ULP2, 0);
    ck_assert_int_eq(c->nlgs, 6);
    ck_assert_rel(c->lgs_radius, 60.0 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->lgs_radius, 2.908882086657216e-4, 1e-15, 0); /* 60" in rad, independent of WT_ARCSEC */
    ck_assert_rel(c->lgs_altitude, 90000.0, ULP2, 0);
    ck_assert_rel(c->sodium_fwhm, 10000.0, ULP2, 0);
    ck_assert_rel(c->launch_radius, 22.0, ULP2, 0);
    ck_assert_rel(c->lgs_tt_jitter, 0.2 * WT_ARCSEC, ULP2, 0);
    ck_assert_int_eq(c->lgs_wfs.subapertures, 84);
    ck_assert_rel(c->diameter / c->lgs_wfs.subapertures, 0.5, ULP2, 0);
    ck_assert_rel(c->lgs_wfs.photons, 100.0, ULP2, 0);
    ck_assert_rel(c->lgs_wfs.spot_fwhm, 1.1 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->lgs_wfs.pixel, 1.0 * WT_ARCSEC, ULP2, 0);
    ck_assert_int_eq(c->lgs_wfs.pixels, 4);
    ck_assert(c->lgs_wfs.nea < 0.0); /* absent: photon model */
    ck_assert_int_eq(c->nngs, 3);
    ck_assert_rel(c->ngs_radius, 80.0 * WT_ARCSEC, ULP2, 0);
    ck_assert_int_eq(c->ngs_subapertures[0], 2);
    ck_assert_int_eq(c->ngs_subapertures[1], 1);
    ck_assert_int_eq(c->ngs_subapertures[2], 1);
    ck_assert_rel(c->ngs_wfs.pixel, 0.05 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->ngs_wfs.read_noise_e, 5.0, ULP2, 0);
    ck_assert(c->ngs_wfs.nea < 0.0);
    ck_assert_int_eq(c->ndms, 3);
    ck_assert_rel(c->dm_altitude[2], 12700.0, ULP2, 0);
    ck_assert_int_eq(c->dm_actuators[0], 85);
    ck_assert_int_eq(c->dm_actuators[1], 47);
    ck_assert_int_eq(c->dm_actuators[2], 53);
    /* 84.853" is sqrt(2)*60" rounded to 5 digits: relative error < 0.5e-3/84.85 */
    ck_assert_rel(c->dm_field_radius, sqrt(2.0) * 60.0 * WT_ARCSEC, 6e-6, 0);
    ck_assert_int_eq(c->eval_grid, 5);
    ck_assert_rel(c->eval_spacing, 30.0 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->eval_wavelength, 2.2e-6, ULP2, 0);
    ck_assert_int_eq(c->settle_frames, 50);
    ck_assert_rel(c->rate, 500.0, ULP2, 0);
    ck_assert_int_eq(c->frames, 500);
    ck_assert_int_eq(c->delay, 2);
    ck_assert_rel(c->gain, 0.4, ULP2, 0);
    ck_assert_int_eq(c->points_per_subaperture, 4);
    ck_assert_uint_eq(c->seed, 1);
    ck_assert_int_eq(c->noise, 1);
    ck_assert_rel(c->alpha, 1.0, ULP2, 0);
    ck_assert_rel(c->tau, 0.8, ULP2, 0);
    ck_assert_int_eq(c->wavelet_order, 3);
    ck_assert_int_eq(c->wavelet_levels, 5);
    ck_assert_int_eq(c->exact_prior, -1); /* left out: each variant's default */
    ck_assert_int_eq(c->pcg3.prior, WT_CFG_PRIOR_FULL);
    ck_assert_int_eq(c->cg9.prior, WT_CFG_PRIOR_FULL);
    ck_assert_int_eq(c->warm_start, 1);
    ck_assert_int_eq(c->pcg3.nlayers, 3);
    ck_assert_int_eq(c->pcg3.size[0], 128);
    ck_assert_int_eq(c->pcg3.size[2], 64);
    ck_assert_rel(c->pcg3.spacing[1], 1.0, ULP2, 0);
    ck_assert_int_eq(c->pcg3.iterations, 4);
    ck_assert_int_eq(c->pcg3.operator_precision, 1); /* fp32 (docs/results.md §30) */
    ck_assert_int_eq(c->cg9.operator_precision, 0);
    ck_assert_int_eq(c->pcg3.preconditioner, 3); /* coarse_ngs (docs/results.md §0d.2) */
    ck_assert_int_eq(c->pcg3.coarse_levels, 2);
    ck_assert_int_eq(c->pcg3.fit_iterations, 0);
    ck_assert_int_eq(c->cg9.nlayers, 9);
    for (int i = 0; i < 9; i++) {
        ck_assert_rel(c->cg9.altitudes[i], c->layer_altitude[i], ULP2, 0);
        /* 0.5 m at every altitude (docs/results.md §0b; the paper's 1 m above 3 km is coarser than the
         * subapertures' footprints there) */
        ck_assert_rel(c->cg9.spacing[i], 0.5, ULP2, 0);
        ck_assert_int_eq(c->cg9.size[i], 128);
    }
    /* the fourier preconditioner (index 5 of none|jacobi|jacobi_ngs|coarse_ngs|multilevel|fourier), 8
     * iterations, the scaling functions as its coarse block (docs/results.md §33) */
    ck_assert_int_eq(c->cg9.iterations, 8);
    ck_assert_int_eq(c->cg9.preconditioner, 5);
    ck_assert_int_eq(c->cg9.coarse_levels, 0);
    ck_assert_int_eq(c->cg9.fit_iterations, 10);
    ck_assert_rel(c->cg9.fit_regularization, 1e-3, ULP2, 0);
    ck_assert_int_eq(c->cg9.fit_sampling, 2);
    ck_assert_int_eq(c->dm_guard_rings, 1);
    ck_assert_int_eq(c->lit_sensor_model, 1);
    ck_assert_int_eq(c->sensor_points, 1);
    ck_assert_int_eq(c->prior_aliasing, 0);
    /* PCG-3's noise model: model error + the loop's noise average (docs/results.md §0d.2); cg9 keeps one frame's */
    ck_assert_int_eq(c->model_error, 1);
    ck_assert_int_eq(c->pcg3.loop_noise_average, 1);
    ck_assert_int_eq(c->cg9.loop_noise_average, 0);
    wt_config_free(ctx, c);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_demo_preset)
{
    wt_context *ctx = tu_context();
    wt_config *c = NULL;
    int st = read_preset(ctx, "demo.cfg", 0, NULL, &c);
    ck_assert_msg(st == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_rel(c->diameter, 8.0, ULP2, 0);
    ck_assert_rel(c->diameter / c->lgs_wfs.subapertures, 0.5, ULP2, 0);
    ck_assert_int_eq(c->nlgs, 4);
    ck_assert_rel(c->lgs_radius, 45.0 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->launch_radius, 4.5, ULP2, 0);
    ck_assert(c->sodium_fwhm > 0.0);
    ck_assert_int_eq(c->nngs, 3);
    ck_assert_int_eq(c->nlayers, 5);
    double sum = 0.0;
    for (int i = 0; i < c->nlayers; i++) sum += c->layer_fraction[i];
    ck_assert_rel(sum, 1.0, 1e-15, 0);
    ck_assert_int_eq(c->ndms, 3);
    ck_assert_int_eq(c->dm_actuators[0], 17);
    ck_assert_int_eq(c->dm_actuators[1], 13);
    ck_assert_int_eq(c->dm_actuators[2], 21);
    ck_assert_int_eq(c->pcg3.size[0], 32);
    ck_assert_int_eq(c->pcg3.size[1], 16);
    ck_assert_int_eq(c->pcg3.size[2], 32);
    ck_assert_rel(c->pcg3.spacing[0], 0.5, ULP2, 0);
    ck_assert_int_eq(c->cg9.nlayers, c->nlayers);
    for (int i = 0; i < c->nlayers; i++) {
        ck_assert_rel(c->cg9.altitudes[i], c->layer_altitude[i], ULP2, 0);
        ck_assert_int_eq(c->cg9.size[i], 32);
        ck_assert_rel(c->cg9.spacing[i], c->layer_altitude[i] < 3000.0 ? 0.5 : 1.0, ULP2, 0);
    }
    ck_assert_int_eq(c->wavelet_levels, 3);
    ck_assert_int_eq(c->frames, 200);
    ck_assert_int_eq(c->settle_frames, 20);
    ck_assert_rel(c->dm_field_radius, 84.853 * WT_ARCSEC, ULP2, 0);
    wt_config_free(ctx, c);
    wt_context_free(ctx);
}
END_TEST

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

START_TEST(test_overrides)
{
    wt_context *ctx = tu_context();
    wt_config *base = parse_ok(ctx, VALID, 0, NULL);
    const char *ov[] = {"atmosphere.r0_m=0.2",          "loop.frames=123",
                        "dm.pitch_m=[0.25, 1.0, 2.0]",  "recon.prior=exact",
                        "recon.cg9.preconditioner=\"jacobi\"", "sim.noise=false",
                        "lgs.wfs.nea_mas=20",           " loop.gain = 0.5; ",
                        "sim.seed=7",                   "sim.seed=9",
                        "atmosphere.cn2_fractions=[0.505, 0.1, 0.1, 0.2, 0.1]"};
    wt_config *c = parse_ok(ctx, VALID, (int)(sizeof ov / sizeof ov[0]), ov);
    ck_assert_rel(c->r0, 0.2, ULP2, 0);
    ck_assert_int_eq(c->frames, 123);
    ck_assert_rel(c->dm_pitch[0], 0.25, ULP2, 0);
    ck_assert_rel(c->dm_pitch[2], 2.0, ULP2, 0);
    ck_assert_int_eq(base->exact_prior, 0);
    ck_assert_int_eq(c->exact_prior, 1);
    ck_assert_int_eq(base->cg9.preconditioner, 0);
    ck_assert_int_eq(c->cg9.preconditioner, 1);
    ck_assert_int_eq(base->noise, 1);
    ck_assert_int_eq(c->noise, 0);
    ck_assert(base->lgs_wfs.nea < 0.0);
    ck_assert_rel(c->lgs_wfs.nea, 20e-3 * WT_ARCSEC, ULP2, 0);
    ck_assert_rel(c->gain, 0.5, ULP2, 0);
    ck_assert_uint_eq(c->seed, 9); /* the last of two overrides of one key wins */
    /* the sum 1.005 is within 1 %: the fractions are divided by it */
    ck_assert_rel(c->layer_fraction[0], 0.505 / 1.005, 1e-15, 0);
    ck_assert_rel(c->layer_fraction[3], 0.2 / 1.005, 1e-15, 0);
    ck_assert(strstr(c->canonical, "prior = \"exact\";") != NULL);
    ck_assert(strstr(c->canonical, "noise = false;") != NULL);
    /* untouched keys keep their file values */
    ck_assert_rel(c->L0, base->L0, 0, 0);
    ck_assert_int_eq(c->dm_actuators[1], base->dm_actuators[1]);
    wt_config_free(ctx, c);
    wt_config_free(ctx, base);

    /* refused overrides: status, the override named with --set, and what is wrong */
    static const struct {
        const char *ov, *want1, *want2;
    } bad[] = {
        {"atmosphere.r00=0.1", "--set atmosphere.r00=0.1: unknown key 'atmosphere.r00'", "did you mean 'atmosphere.r0_m'?"},
        {"loop.rate=400", "unknown key 'loop.rate'", "did you mean 'loop.rate_hz'?"},
        {"atmosphere.r0_m=-1", "--set atmosphere.r0_m=-1: key 'atmosphere.r0_m': value -1 is out of range", "in [0.001, 10000] [m]"},
        {"loop.frames=abc", "--set loop.frames=abc: cannot read the value", "syntax error"},
        {"lgs.wfs=3", "--set lgs.wfs=3: 'lgs.wfs' is a group", "lgs.wfs.<key>"},
        {"loop.frames", "--set loop.frames: expected key=value", ""},
        {"dm.pitch_m=[0.5, 1, 1]", "mismatched element type", "write 1.0, not 1"},
        {"loop.frames=1; lgs = 3", "--set loop.frames=1; lgs = 3: expected one value", ""},
        {"recon.prior=best", "--set recon.prior=best: key 'recon.prior': value \"best\" is not accepted", "\"paper\", \"exact\""},
        /* the scale-dependent gain (core/op/scale_gain.h): each gain in (0, 1], 2 or more bands, no more than the
         * smallest DM grid holds (DM 2: 13 + 2 guard = 15 actuators in 16 points: squares of 16, 4 bands) */
        {"loop.gain_levels=[0.6, 0.0]", "key 'loop.gain_levels', element [1]: value 0 is out of range", "(0, 1]"},
        {"loop.gain_levels=[0.6, 1.2]", "key 'loop.gain_levels', element [1]: value 1.2 is out of range", "(0, 1]"},
        {"loop.gain_levels=[0.6]", "key 'loop.gain_levels': has 1 elements", "2..16"},
        {"loop.gain_levels=0.6", "key 'loop.gain_levels': expected a list", "got a number 0.6"},
        {"loop.gain_levels=[0.6, 0.5, 0.4, 0.4, 0.3]", "key 'loop.gain_levels' has 5 values, but DM 2's grid of 15",
         "expected 2 ... 4 values"},
        {"loop.gain_basis=\"haar\"", "key 'loop.gain_basis': value \"haar\" is not accepted", "\"bilinear\", \"daubechies\""},
        {"loop.gain_basis=\"daubechies\"", "key 'loop.gain_basis' is given without 'loop.gain_levels'", ""},
        {"sim.psf_interval_frames=2000000", "--set sim.psf_interval_frames=2000000: key 'sim.psf_interval_frames': value 2000000 is out of range", "[0, 1000000]"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        wt_config *x = (wt_config *)1;
        int st = wt_config_parse(ctx, VALID, NAME, 1, &bad[i].ov, &x);
        ck_assert_msg(st == WT_ERR_CONFIG, "%s: status %d", bad[i].ov, st);
        ck_assert_ptr_null(x);
        const char *m = wt_error_message(ctx);
        ck_assert_msg(strstr(m, bad[i].want1) && strstr(m, bad[i].want2), "%s: message \"%s\"", bad[i].ov, m);
    }
    wt_context_free(ctx);
}
END_TEST

/* loop.gain_levels / loop.gain_basis: optional; left out, the single gain (no band, nothing in the canonical
 * text, so today's files keep their text and hashes); given, read in order and written to the text. */
START_TEST(test_gain_levels)
{
    wt_context *ctx = tu_context();
    wt_config *base = parse_ok(ctx, VALID, 0, NULL);
    ck_assert_int_eq(base->ngain_levels, 0);
    ck_assert_int_eq(base->gain_basis, 0);
    ck_assert_ptr_null(strstr(base->canonical, "gain_levels"));
    ck_assert_ptr_null(strstr(base->canonical, "gain_basis"));
    const char *ov[] = {"loop.gain_levels=[0.6, 0.5, 0.4, 0.3]", "loop.gain_basis=\"daubechies\""};
    wt_config *c = parse_ok(ctx, VALID, 1, ov);
    ck_assert_int_eq(c->ngain_levels, 4);
    ck_assert_rel(c->gain_levels[0], 0.6, ULP2, 0);
    ck_assert_rel(c->gain_levels[3], 0.3, ULP2, 0);
    ck_assert_int_eq(c->gain_basis, 0);
    ck_assert_ptr_nonnull(strstr(c->canonical, "gain_levels"));
    ck_assert_str_eq(c->matrix_sha256, base->matrix_sha256);
    wt_config_free(ctx, c);
    c = parse_ok(ctx, VALID, 2, ov);
    ck_assert_int_eq(c->gain_basis, 1);
    ck_assert_ptr_nonnull(strstr(c->canonical, "gain_basis = \"daubechies\""));
    wt_config_free(ctx, c);
    wt_config_free(ctx, base);
    wt_context_free(ctx);
}
END_TEST

/* VALID with the first `old` replaced by `new` (malloc'd); *line = the line of `old` in VALID. */
static char *edit(const char *old, const char *new, const char *line_of, int *line)
{
    const char *p = strstr(VALID, old);
    ck_assert_msg(p != NULL, "'%s' not in VALID", old);
    const char *q = line_of ? strstr(VALID, line_of) : p;
    ck_assert_ptr_nonnull(q);
    *line = 1;
    for (const char *s = VALID; s < q; s++) *line += *s == '\n';
    size_t n = strlen(VALID) - strlen(old) + strlen(new) + 1;
    char *t = malloc(n);
    ck_assert_ptr_nonnull(t);
    snprintf(t, n, "%.*s%s%s", (int)(p - VALID), VALID, new, p + strlen(old));
    return t;
}

static const struct bad_case {
    const char *what, *old, *new;
    int with_line;          /* the message starts with "t.cfg:LINE:" (else "t.cfg:") */
    const char *line_of;    /* the line reported is this text's, not the edited one's */
    const char *want[3];    /* substrings of the message */
} bad_cases[] = {
    {"syntax error", "r0_m = 0.129;", "r0_m = = 0.129;", 1, NULL, {"syntax error", "", ""}},
    {"mixed array", "pitch_m = [0.5, 1.0, 1.0];", "pitch_m = [0.5, 1, 1];", 1, NULL, {"syntax error", "mismatched element type", "1.0, not 1"}},
    {"missing key", "  pitch_m = [0.5, 1.0, 1.0];\n", "", 0, NULL, {"t.cfg: missing key 'dm.pitch_m'", "[m]", "1..8"}},
    {"misspelled key", "r0_m = 0.129;", "r0 = 0.129;", 1, NULL, {"unknown key 'atmosphere.r0'", "(did you mean 'atmosphere.r0_m'?)", ""}},
    {"unit left out", "rate_hz = 500.0;", "rate = 500.0;", 1, NULL, {"unknown key 'loop.rate'", "did you mean 'loop.rate_hz'?", ""}},
    {"unrelated key: no suggestion", "telescope = { diameter_m = 8.0;", "telescope = { colour = 1; diameter_m = 8.0;", 1, NULL,
     {"unknown key 'telescope.colour'; `wavetomo info --keys` lists the accepted keys", "", ""}},
    {"misspelled group", "atmosphere = {", "atmosphre = {", 1, NULL, {"unknown group 'atmosphre'", "did you mean 'atmosphere'?", ""}},
    {"key in a nested group", "photons = 100.0;", "photon = 100.0;", 1, NULL, {"unknown key 'lgs.wfs.photon'", "'lgs.wfs.photons'", ""}},
    {"string for integer", "frames = 200;", "frames = \"abc\";", 1, NULL, {"key 'loop.frames': expected an integer, got a string \"abc\"", "", ""}},
    {"number for integer", "actuators = [17, 13, 21];", "actuators = (17, 13.5, 21);", 1, NULL, {"key 'dm.actuators', element [1]: expected an integer, got a number 13.5", "", ""}},
    {"integer for boolean", "noise = true;", "noise = 1;", 1, NULL, {"key 'sim.noise': expected a boolean", "got an integer 1", ""}},
    {"scalar for list", "pitch_m = [0.5, 1.0, 1.0];", "pitch_m = 0.5;", 1, NULL, {"key 'dm.pitch_m': expected a list", "got a number 0.5", ""}},
    {"group for scalar", "  r0_m = 0.129;", "  r0_m = { v = 0.129; };", 1, NULL, {"key 'atmosphere.r0_m': expected a number", "got a group", ""}},
    {"r0 out of range", "r0_m = 0.129;", "r0_m = -0.1;", 1, NULL, {"key 'atmosphere.r0_m': value -0.1 is out of range; expected a number in [0.001, 10000] [m]", "", ""}},
    {"gain out of range", "gain = 0.4;", "gain = 1.5;", 1, NULL, {"key 'loop.gain': value 1.5 is out of range", "(0, 1]", ""}},
    {"too many LGS", "count = 4;", "count = 17;", 1, NULL, {"key 'lgs.count': value 17 is out of range", "[0, 16]", ""}},
    {"list element out of range", "pitch_m = [0.5, 1.0, 1.0];", "pitch_m = [0.5, -1.0, 1.0];", 1, NULL, {"key 'dm.pitch_m', element [1]: value -1 is out of range", "in (0, 100] [m]", ""}},
    {"NGS sensor size", "subapertures = [2, 1, 1];", "subapertures = [2, 3, 1];", 1, NULL, {"key 'ngs.subapertures', element [1]: value 3", "[1, 2]", ""}},
    {"even evaluation grid", "grid = 5;", "grid = 4;", 1, NULL, {"key 'evaluation.grid': value 4 is even", "odd integer", ""}},
    {"delay", "delay_frames = 2;", "delay_frames = 3;", 1, NULL, {"key 'loop.delay_frames': value 3 is out of range", "[1, 2]", ""}},
    {"zero NEA", "pixels = 4;\n  };", "nea_mas = 0.0; pixels = 4;\n  };", 1, NULL, {"key 'lgs.wfs.nea_mas': value 0 is out of range", "[mas]", ""}},
    {"list lengths", "wind_speed_mps = [8.0, 10.0, 12.0, 18.0, 25.0];", "wind_speed_mps = [8.0, 10.0, 12.0, 18.0];", 1, NULL,
     {"key 'atmosphere.wind_speed_mps' has 4 elements but 'atmosphere.altitudes_m' has 5", "", ""}},
    {"too many DMs", "actuators = [17, 13, 21];", "actuators = [17, 13, 21, 5, 5, 5, 5, 5, 5];", 1, NULL, {"key 'dm.actuators': has 9 elements; expected 1..8", "", ""}},
    {"altitudes not increasing", "altitudes_m = [0.0, 600.0, 2000.0, 6000.0, 12000.0];", "altitudes_m = [0.0, 600.0, 500.0, 6000.0, 12000.0];", 1, NULL,
     {"key 'atmosphere.altitudes_m', element [2]: value 500 is not above the previous element 600", "strictly increasing", ""}},
    {"fractions sum", "cn2_fractions = [0.55, 0.1, 0.1, 0.15, 0.1];", "cn2_fractions = [0.5, 0.1, 0.1, 0.15, 0.1];", 1, NULL,
     {"key 'atmosphere.cn2_fractions': the fractions sum to 0.95", "expected 1 within 1 %", ""}},
    {"LGS below a layer", "altitude_m = 90000.0;", "altitude_m = 10000.0;", 1, NULL,
     {"key 'lgs.altitude_m': value 10000 is not above 'atmosphere.altitudes_m' element [4] = 12000", "an LGS below a layer", ""}},
    {"LGS below a reconstruction layer", "layer_altitudes_m = [0.0, 4000.0, 12700.0];", "layer_altitudes_m = [0.0, 4000.0, 95000.0];", 1,
     "altitude_m = 90000.0;", {"'recon.pcg3.layer_altitudes_m' element [2] = 95000", "an LGS below a layer", ""}},
    {"layer size not a power of two", "layer_size = [32, 32, 32, 32, 32];", "layer_size = [32, 32, 32, 32, 24];", 1, NULL,
     {"key 'recon.cg9.layer_size', element [4]: value 24 is not a power of two", "", ""}},
    {"layer size below 2^J", "wavelet_levels = 3;", "wavelet_levels = 5;", 1, "layer_size = [32, 16, 32];",
     {"key 'recon.pcg3.layer_size', element [1]: value 16 is smaller than 2^recon.wavelet_levels = 2^5 = 32", "t.cfg:", ""}},
    {"unknown prior", "prior = \"paper\";", "prior = \"papr\";", 1, NULL, {"key 'recon.prior': value \"papr\" is not accepted", "\"paper\", \"exact\"", ""}},
    {"unknown preconditioner", "preconditioner = \"jacobi\";", "preconditioner = \"ilu\";", 1, NULL, {"key 'recon.pcg3.preconditioner': value \"ilu\"", "\"none\", \"jacobi\", \"jacobi_ngs\"", "\"coarse_ngs\", \"multilevel\""}},
    {"unknown fitting solver", "    fit_iterations = 4;\n", "    fit_iterations = 4; fit_solver = \"lu\";\n", 1, NULL,
     {"key 'recon.cg9.fit_solver': value \"lu\"", "\"cg\", \"cholesky\"", ""}},
    {"fitting solver not a string", "    fit_iterations = 4;\n", "    fit_iterations = 4; fit_solver = 1;\n", 1, NULL,
     {"recon.cg9.fit_solver", "", ""}},
    {"unknown fitting kernels", "    fit_iterations = 4;\n", "    fit_iterations = 4; fit_kernels = \"simd\";\n", 1, NULL,
     {"key 'recon.cg9.fit_kernels': value \"simd\"", "\"fast\", \"reference\"", ""}},
    {"unknown operator precision", "preconditioner = \"jacobi\";", "preconditioner = \"jacobi\"; operator_precision = \"fp16\";", 1, NULL,
     {"key 'recon.pcg3.operator_precision': value \"fp16\"", "\"fp64\", \"fp32\"", ""}},
    {"settle past the end", "settle_frames = 20;", "settle_frames = 200;", 1, NULL, {"key 'evaluation.settle_frames': value 200 is not below 'loop.frames' = 200", "", ""}},
    {"negative seed", "seed = 1;", "seed = -3;", 1, NULL, {"key 'sim.seed': value -3 is out of range", ">= 0", ""}},
    {"negative PSF interval", "seed = 1;", "seed = 1; psf_interval_frames = -1;", 1, NULL,
     {"key 'sim.psf_interval_frames': value -1 is out of range", "[0, 1000000]", ""}},
    {"PSF interval not an integer", "seed = 1;", "seed = 1; psf_interval_frames = 2.5;", 1, NULL, {"sim.psf_interval_frames", "", ""}},
    {"odd PSF image", "seed = 1;", "seed = 1; psf_pixels = 65;", 1, NULL, {"key 'sim.psf_pixels': value 65 is odd", "", ""}},
    {"PSF image too small", "seed = 1;", "seed = 1; psf_pixels = 4;", 1, NULL,
     {"key 'sim.psf_pixels': value 4 is out of range", "[8, 4096]", ""}},
    {"duplicate key", "r0_m = 0.129;", "r0_m = 0.129; r0_m = 0.2;", 1, NULL, {"syntax error", "duplicate", ""}},
};

/* A file may carry its own overrides (a preset that @includes another): they apply after the file's
 * settings and before the command line's, and a bad one is refused naming the file and the override. */
START_TEST(test_file_overrides)
{
    wt_context *ctx = tu_context();
    size_t n = strlen(VALID) + 256;
    char *text = malloc(n);
    snprintf(text, n, "%soverrides = [\"loop.gain = 0.7\", \"sim.seed = 5\"];\n", VALID);
    const char *ov[] = {"sim.seed=9"};
    wt_config *c = parse_ok(ctx, text, 1, ov);
    ck_assert_rel(c->gain, 0.7, ULP2, 0);
    ck_assert_uint_eq(c->seed, 9); /* the command line wins */
    ck_assert(strstr(c->canonical, "overrides") == NULL);
    wt_config_free(ctx, c);
    static const char *const bad[] = {"overrides = [\"loop.gain = 7.0\"];\n", "overrides = 3;\n",
                                      "overrides = [\"no.such.key = 1\"];\n"};
    static const char *const what[] = {"overrides \"loop.gain = 7.0\"", "'overrides' must be a list",
                                       "unknown key 'no.such.key'"};
    for (int i = 0; i < 3; i++) {
        snprintf(text, n, "%s%s", VALID, bad[i]);
        wt_config *cfg = NULL;
        int st = wt_config_parse(ctx, text, NAME, 0, NULL, &cfg);
        ck_assert_int_eq(st, WT_ERR_CONFIG);
        ck_assert_ptr_null(cfg);
        ck_assert_msg(strstr(wt_error_message(ctx), what[i]) && strstr(wt_error_message(ctx), NAME), "%s",
                      wt_error_message(ctx));
    }
    free(text);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_bad_inputs)
{
    const struct bad_case *b = &bad_cases[_i];
    wt_context *ctx = tu_context();
    int line;
    char *text = edit(b->old, b->new, b->line_of, &line);
    wt_config *cfg = (wt_config *)1;
    int st = wt_config_parse(ctx, text, NAME, 0, NULL, &cfg);
    const char *m = wt_error_message(ctx);
    ck_assert_msg(st == WT_ERR_CONFIG, "%s: status %d (%s)", b->what, st, m);
    ck_assert_ptr_null(cfg);
    char loc[64];
    if (b->with_line) snprintf(loc, sizeof loc, NAME ":%d: ", line);
    else snprintf(loc, sizeof loc, NAME ": ");
    ck_assert_msg(!strncmp(m, loc, strlen(loc)), "%s: message \"%s\" does not start with \"%s\"", b->what, m, loc);
    for (int i = 0; i < 3; i++)
        ck_assert_msg(strstr(m, b->want[i]) != NULL, "%s: message \"%s\" lacks \"%s\"", b->what, m, b->want[i]);
    free(text);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_files)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = (wt_config *)1;
    int st = wt_config_read(ctx, "/nonexistent-dir/missing.cfg", 0, NULL, &cfg);
    ck_assert_int_eq(st, WT_ERR_IO);
    ck_assert_ptr_null(cfg);
    ck_assert(strstr(wt_error_message(ctx), "'/nonexistent-dir/missing.cfg'") != NULL);

    /* a file: line numbers name the file; reading it equals parsing its text */
    char path[] = "/tmp/wt_test_config_XXXXXX";
    int fd = mkstemp(path);
    ck_assert_int_ge(fd, 0);
    FILE *f = fdopen(fd, "w");
    fputs(VALID, f);
    fclose(f);
    st = wt_config_read(ctx, path, 0, NULL, &cfg);
    ck_assert_msg(st == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(cfg->path, path);
    wt_config *p = parse_ok(ctx, VALID, 0, NULL);
    ck_assert_str_eq(cfg->canonical, p->canonical);
    wt_config_free(ctx, cfg);
    wt_config_free(ctx, p);
    const char *ov[] = {"loop.gain=2"};
    st = wt_config_read(ctx, path, 1, ov, &cfg);
    ck_assert_int_eq(st, WT_ERR_CONFIG);
    ck_assert(strstr(wt_error_message(ctx), "--set loop.gain=2: key 'loop.gain': value 2 is out of range") != NULL);
    f = fopen(path, "w");
    fputs("telescope = { diameter_m = 8.0;\n\n  obstruction = -0.5; };\n", f);
    fclose(f);
    st = wt_config_read(ctx, path, 0, NULL, &cfg);
    ck_assert_int_eq(st, WT_ERR_CONFIG);
    char want[128];
    snprintf(want, sizeof want, "%s:3: key 'telescope.obstruction': value -0.5 is out of range", path);
    ck_assert_msg(strstr(wt_error_message(ctx), want) != NULL, "%s", wt_error_message(ctx));
    remove(path);
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
            !strstr(path, "_iterations") && !strstr(path, "_regularization") && !strstr(path, "_subaperture") && !strstr(path, "_rings") && !strstr(path, "_aliasing") && !strstr(path, "_model") && !strstr(path, "lit_noise") && !strstr(path, "model_error") && !strstr(path, "subgrid_error") && !strstr(path, "focus_removal") && !strstr(path, "_precision") && !strstr(path, "noise_average") && !strstr(path, "_solver") && !strstr(path, "_kernels") &&
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
     * LGS only), nor recon.lgs_focus_mode left out (the removal's mode, read only beside it), nor sim.psf_wavelengths_nm and
     * sim.telemetry_maps_interval_frames when left out */
    ck_assert_int_eq(nkeys + 37, nlines);
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

/* ---------------------------------------------------------------- automatic layer grids */

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

/* Allocation failure at each of the reader's allocations: WT_ERR_NOMEM, nothing returned, no leak
 * (the sanitizer build checks the last part). */
START_TEST(test_alloc_failure)
{
    const char *ov[] = {"loop.frames=300"};
    int failures = 0;
    for (int n = 0; n < 50; n++) {
        wt_context *ctx = tu_context();
        tu_alloc fa = TU_ALLOC_INIT;
        tu_alloc_budget(&fa, n);
        tu_alloc_install(ctx, &fa);
        wt_config *cfg = (wt_config *)1;
        int st = wt_config_parse(ctx, VALID, NAME, 1, ov, &cfg);
        if (st == WT_OK) {
            ck_assert_int_eq(cfg->frames, 300);
            wt_config_free(ctx, cfg);
            ck_assert_int_eq(fa.live, 0);
            wt_context_free(ctx);
            break;
        }
        failures++;
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(cfg);
        ck_assert_int_eq(fa.live, 0);
        wt_context_free(ctx);
    }
    ck_assert_int_ge(failures, 2); /* the override text, the struct and the canonical text are allocated */
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("config");
    TCase *tc = tcase_create("config");
    tcase_add_test(tc, test_eelt_preset);
    tcase_add_test(tc, test_demo_preset);
    tcase_add_test(tc, test_canonical);
    tcase_add_test(tc, test_matrix_hash);
    tcase_add_test(tc, test_sodium_profile_hash);
    tcase_add_test(tc, test_fft_wisdom_keys);
    tcase_add_test(tc, test_noise_hash_tcog);
    tcase_add_test(tc, test_overrides);
    tcase_add_test(tc, test_gain_levels);
    tcase_add_test(tc, test_file_overrides);
    tcase_add_loop_test(tc, test_bad_inputs, 0, (int)(sizeof bad_cases / sizeof bad_cases[0]));
    tcase_add_test(tc, test_files);
    tcase_add_test(tc, test_reference);
    tcase_add_test(tc, test_auto_grid_presets);
    tcase_add_test(tc, test_auto_grid_oversampling);
    tcase_add_test(tc, test_auto_grid_combinations);
    tcase_add_test(tc, test_auto_sensor_points);
    tcase_add_test(tc, test_auto_fit_points);
    tcase_add_test(tc, test_variant_priors);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
