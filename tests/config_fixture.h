/* tests/config_fixture.h: what the configuration suites share (test_config_read.c, test_config_canonical.c,
 * test_config_grid.c): a small valid system as text, reading a preset or a text, and editing one line of the text. */
#ifndef WT_TESTS_CONFIG_FIXTURE_H
#define WT_TESTS_CONFIG_FIXTURE_H

#include <stdlib.h>
#include <string.h>

#include "core/config/config.h"
#include "testutil.h"

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

/* Presets live in data/presets of the source tree; tests run from its root (make test) or from tests/. */
static inline int read_preset(wt_context *ctx, const char *file, int nov, const char *const *ov, wt_config **out)
{
    char path[256];
    snprintf(path, sizeof path, "data/presets/%s", file);
    FILE *f = fopen(path, "r");
    if (!f) snprintf(path, sizeof path, "../data/presets/%s", file);
    else fclose(f);
    return wt_config_read(ctx, path, nov, ov, out);
}

static inline wt_config *parse_ok(wt_context *ctx, const char *text, int nov, const char *const *ov)
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

/* VALID with the first `old` replaced by `new` (malloc'd); *line = the line of `old` in VALID. */
static inline char *edit(const char *old, const char *new, const char *line_of, int *line)
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

#endif
