/* core/config/config_canonical.c: the canonical text of a configuration and its matrix identity (SPEC §9):
 *
 *   canonical = every effective key in schema order, one type per key;   matrix_text = its keys that can change
 *   the reconstructor's matrices (R, RÂ);   matrix_sha256 = SHA-256(matrix_text),
 *
 * so that comments, layout, key order and number spelling do not change them, and a stored MVM is refused for a
 * system it was not built for. Runs last, after the checks (config_check.c). */
#include "config_private.h"

#include "../base/sha256.h"

#include <libconfig.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef wt_config_priv_state pstate;

/* Keys that cannot change the reconstructor's matrices (R, RÂ): the simulation truth only (wind, LGS
 * jitter, seed, noise switch; the truth's profile too unless it is the oracle's model: config_atmosphere.c), the loop, the long-exposure bookkeeping, and how an iterative solver
 * stops. Everything else is hashed into the matrix's identity (SPEC §9). The loop's gain and delay
 * enter the noise model when a variant's loop_noise_average is on, and then only. */
static int affects_matrix(const pstate *ps, const char *path)
{
    const int model = wt_config_priv_model_affects_matrix(ps, path);
    if (model >= 0) return model;
    /* recon.predict puts the layers' shift over the lead, delay_frames (or predict_lead_frames) / rate_hz, into R */
    {
        const int predict = wt_config_priv_predicting(ps);
        if (!strcmp(path, "recon.predict") || !strcmp(path, "recon.predict_lead_frames") || !strcmp(path, "loop.rate_hz"))
            return predict;
        if (predict && !strcmp(path, "loop.delay_frames")) return 1;
    }
    if (!strcmp(path, "loop.gain") || !strcmp(path, "loop.delay_frames")) {
        int on = 0;
        for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++)
            if (strstr(wt_config_priv_keys[k].path, ".loop_noise_average") && ps->set[k])
                on |= config_setting_get_bool(ps->set[k]);
        return on;
    }
    /* a diffractive LGS reference "rendered" on the simulation grid takes the grid's spacing */
    if (!strcmp(path, "sim.points_per_subaperture")) {
        const int km = wt_config_priv_find_key("lgs.wfs.model"), kr = wt_config_priv_find_key("lgs.wfs.reference_seeing");
        const char *m = km >= 0 && ps->set[km] ? config_setting_get_string(ps->set[km]) : NULL;
        const char *r = kr >= 0 && ps->set[kr] ? config_setting_get_string(ps->set[kr]) : NULL;
        return m && r && !strcmp(m, "diffractive") && !strcmp(r, "rendered");
    }
    /* a diffractive tCoG is calibrated at the operating noise when the simulation has noise (its reference
     * and gain, so its covariance: core/optics/centroid.h), so sim.noise shapes the noise model then */
    if (!strcmp(path, "sim.noise")) {
        int on = 0;
        for (const char *t = "ln"; *t; t++) {
            const int km = wt_config_priv_find_key(*t == 'l' ? "lgs.wfs.model" : "ngs.wfs.model");
            const int kc = wt_config_priv_find_key(*t == 'l' ? "lgs.wfs.centroider" : "ngs.wfs.centroider");
            const char *m = km >= 0 && ps->set[km] ? config_setting_get_string(ps->set[km]) : NULL;
            const char *c = kc >= 0 && ps->set[kc] ? config_setting_get_string(ps->set[kc]) : NULL;
            on |= m && c && !strcmp(m, "diffractive") && !strcmp(c, "tcog");
        }
        return on;
    }
    /* the diffractive sensor's keys shape the noise model only when that sensor type is diffractive */
    static const char *const diffr[] = {".model", ".centroider", ".apply_gain", ".tcog_threshold", ".window_pixels",
                                        ".background_e", ".pupil_samples", ".fft_size", ".cells_per_pixel",
                                        ".wavelength_nm", ".noise_calibration", ".calibration_"};
    /* the sodium layer in time and the loop's reference: the truth and the loop only; the set-up reference (the
     * MVM's noise model) is lgs.sodium_profile's (SPEC §12 "The sodium layer changes too") */
    if (!strncmp(path, "lgs.sodium_sequence", 19) || !strcmp(path, "lgs.wfs.reference") ||
        !strcmp(path, "lgs.wfs.reference_update_s") || !strncmp(path, "lgs.wfs.focus_stage", 19) ||
        !strcmp(path, "lgs.wfs.gain_update_s"))
        return 0;
    /* the profile enters by its contents (lgs.sodium_profile_sha256) and by its name only when they could
     * not be hashed: the same bytes under another name give the same matrix, an edited file another */
    if (!strcmp(path, "lgs.sodium_profile")) {
        const int kh = wt_config_priv_find_key("lgs.sodium_profile_sha256");
        if (kh >= 0 && ps->set[kh]) return 0;
    }
    const int lgs_only = !strcmp(path, "lgs.uplink_fwhm_arcsec") || !strcmp(path, "lgs.wfs.reference_seeing") || !strcmp(path, "lgs.sodium_profile") ||
                         !strcmp(path, "lgs.sodium_profile_sha256");
    for (size_t i = 0; i < sizeof diffr / sizeof *diffr && !lgs_only; i++)
        if ((!strncmp(path, "lgs.wfs.", 8) || !strncmp(path, "ngs.wfs.", 8)) && strstr(path, diffr[i]))
            goto diffractive;
    if (lgs_only) goto diffractive;
    static const char *const skip[] = {"sim.", "loop.", "evaluation.settle_frames", "evaluation.wavelength_nm",
                                       "lgs.tt_jitter_arcsec", "recon.warm_start", "recon.predict",
                                       "recon.pcg3.iterations", "recon.pcg3.tolerance", "recon.pcg3.preconditioner",
                                       "recon.pcg3.coarse_levels", "recon.cg9.iterations", "recon.cg9.tolerance",
                                       "recon.cg9.preconditioner", "recon.cg9.coarse_levels",
                                       "recon.cg9.fit_iterations", "recon.cg9.fit_solver", "recon.cg9.fit_factor_precision",
                                       "recon.cg9.fit_kernels", "recon.pcg3.operator_precision",
                                       "recon.cg9.operator_precision",
                                       "recon.mvm_precision", "recon.fft_wisdom"};
    for (size_t i = 0; i < sizeof skip / sizeof *skip; i++)
        if (!strncmp(path, skip[i], strlen(skip[i]))) return 0;
    return 1;
diffractive: {
    const int k = wt_config_priv_find_key(path[0] == 'l' ? "lgs.wfs.model" : "ngs.wfs.model");
    const char *m = k >= 0 && ps->set[k] ? config_setting_get_string(ps->set[k]) : NULL;
    return m && !strcmp(m, "diffractive");
}
}

/* The effective settings in schema order with one type per key (floats as floats, lists as arrays),
 * so comments, layout, key order, 42 vs 42.0 and [..] vs (..) do not change the text. Floats are
 * written by libconfig with 15 significant digits. */
static int build_text(pstate *ps, int matrix_only, char **text)
{
    config_t out;
    char *buf = NULL;
    size_t len = 0;
    int st = WT_OK;
    config_init(&out);
    config_set_options(&out, CONFIG_OPTION_SEMICOLON_SEPARATORS);
    config_set_tab_width(&out, 2);
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS && st == WT_OK; k++) {
        const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
        const config_setting_t *s = ps->set[k];
        if (!s || (matrix_only && !affects_matrix(ps, ks->path))) continue;
        const char *leaf;
        config_setting_t *g = wt_config_priv_ensure_parent(&out, ks->path, &leaf), *d = NULL;
        static const int ctype[] = {CONFIG_TYPE_INT, CONFIG_TYPE_INT64, CONFIG_TYPE_FLOAT, CONFIG_TYPE_BOOL,
                                    CONFIG_TYPE_STRING, CONFIG_TYPE_ARRAY, CONFIG_TYPE_ARRAY, CONFIG_TYPE_STRING};
        if (g) d = config_setting_add(g, leaf, ctype[ks->type]);
        if (!d) {
            st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "libconfig could not add '%s' to the canonical text", ks->path);
            break;
        }
        switch (ks->type) {
        case K_INT: config_setting_set_int(d, (int)config_setting_get_int64(s)); break;
        case K_INT64: config_setting_set_int64(d, config_setting_get_int64(s)); break;
        case K_FLOAT: config_setting_set_float(d, wt_config_priv_num(s)); break;
        case K_BOOL: config_setting_set_bool(d, config_setting_get_bool(s)); break;
        case K_ENUM:
        case K_STR: config_setting_set_string(d, config_setting_get_string(s)); break;
        default:
            for (int i = 0; i < config_setting_length(s); i++) {
                const config_setting_t *e = config_setting_get_elem(s, (unsigned)i);
                if (!(ks->type == K_INTS ? config_setting_set_int_elem(d, -1, (int)config_setting_get_int64(e))
                                         : config_setting_set_float_elem(d, -1, wt_config_priv_num(e))))
                    st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "libconfig could not add '%s' to the canonical text", ks->path);
            }
        }
    }
    FILE *f = st == WT_OK ? open_memstream(&buf, &len) : NULL;
    if (st == WT_OK && !f) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "open_memstream failed for the canonical text");
    if (f) {
        config_write(&out, f);
        if (fclose(f) != 0 || !buf) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "writing the canonical text failed");
    }
    config_destroy(&out);
    if (st == WT_OK) {
        *text = wt_malloc(ps->ctx, len + 1, 1);
        if (!*text) st = WT_ERROR(ps->ctx, WT_ERR_NOMEM, "out of memory for the canonical text (%zu bytes)", len + 1);
        else memcpy(*text, buf, len + 1);
    }
    free(buf); /* open_memstream's buffer comes from malloc, not from the context's allocator */
    return st;
}

int wt_config_priv_build_canonical(pstate *ps, wt_config *cfg)
{
    int st = build_text(ps, 0, &cfg->canonical);
    if (st == WT_OK) st = build_text(ps, 1, &cfg->matrix_text);
    if (st == WT_OK) wt_sha256_hex(cfg->matrix_text, strlen(cfg->matrix_text), cfg->matrix_sha256);
    return st;
}
