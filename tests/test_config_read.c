/* tests/test_config_read.c: reading the configuration (core/config/config_read.c, config_text.c): the presets'
 * values, --set and file overrides, the loop's gain levels, and a table of malformed inputs that must each be refused
 * with a precise message; allocation failures. */
#include "testutil.h"

#include <unistd.h>

#include "config_fixture.h"
#include "core/base/sha256.h"
#include "core/config/config.h"
#include "core/model/system.h"

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
        {"recon.predict_integrator=\"state\"", "key 'recon.predict_integrator': value \"state\" is not accepted",
         "\"commands\", \"layers\""},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        wt_config *x = (wt_config *)1;
        int st = wt_config_parse(ctx, VALID, NAME, 1, &bad[i].ov, &x);
        ck_assert_msg(st == WT_ERR_CONFIG, "%s: status %d", bad[i].ov, st);
        ck_assert_ptr_null(x);
        const char *m = wt_error_message(ctx);
        ck_assert_msg(strstr(m, bad[i].want1) && strstr(m, bad[i].want2), "%s: message \"%s\"", bad[i].ov, m);
    }
    /* the integrator on the layers has one gain: not with a gain per scale of the commands */
    const char *both[] = {"loop.gain_levels=[0.6, 0.4]", "recon.predict_integrator=\"layers\""};
    wt_config *x = (wt_config *)1;
    ck_assert_int_eq(wt_config_parse(ctx, VALID, NAME, 2, both, &x), WT_ERR_CONFIG);
    ck_assert_ptr_null(x);
    ck_assert_msg(strstr(wt_error_message(ctx), "key 'recon.predict_integrator' = \"layers\"") &&
                      strstr(wt_error_message(ctx), "loop.gain_levels"), "%s", wt_error_message(ctx));
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
    Suite *s = suite_create("config_read");
    TCase *tc_config = tcase_create("config");
    tcase_add_test(tc_config, test_eelt_preset);
    tcase_add_test(tc_config, test_demo_preset);
    tcase_add_test(tc_config, test_overrides);
    tcase_add_test(tc_config, test_gain_levels);
    tcase_add_test(tc_config, test_file_overrides);
    tcase_add_loop_test(tc_config, test_bad_inputs, 0, (int)(sizeof bad_cases / sizeof bad_cases[0]));
    tcase_add_test(tc_config, test_files);
    tcase_add_test(tc_config, test_alloc_failure);
    suite_add_tcase(s, tc_config);
    return s;
}

TU_MAIN
