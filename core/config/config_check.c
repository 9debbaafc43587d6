/* core/config/config_check.c: what a configuration's keys say together (SPEC §1, §9): the checks no single key's
 * range can make (the Cn² fractions summing to 1, every layer below the LGS, a layer grid of at least 2^J points,
 * the gain bands that fit the DMs, the diffractive sensor's detector and FFT sampling), and the values chosen from
 * several keys when the file leaves them out or says "auto" (the layer grids, the sensor and fit points per
 * subaperture, the priors, the files' SHA-256), written into the tree so that the canonical text
 * (config_canonical.c) gives them as if the file had. Runs after every key is loaded (config_read.c). */
#include "config_private.h"

#include "../base/sha256.h"

#include <libconfig.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define WT_SH_TILT_Z_CFG 1 /* ngs.wfs.tilt = "z" (WT_SH_TILT_Z of core/op/shack_hartmann.h) */

typedef wt_config_priv_state pstate;

#define FAIL(ps, k, s, ...) wt_config_priv_fail((ps), wt_config_priv_where((ps), (k), (s), loc, sizeof loc), __VA_ARGS__)

static int check_below_lgs(pstate *ps, const wt_config *cfg, const char *path, const double *alt, int n)
{
    char loc[512], oth[512], a[40], b[40];
    int kl = wt_config_priv_find_key("lgs.altitude_m"), kk = wt_config_priv_find_key(path);
    for (int i = 0; i < n; i++)
        if (!(alt[i] < cfg->lgs_altitude))
            return FAIL(ps, kl, ps->set[kl], "key 'lgs.altitude_m': value %s is not above '%s' element [%d] = %s "
                        "(%s): an LGS below a layer; the sodium layer must be above every atmosphere, DM and "
                        "reconstruction layer", wt_config_priv_fmt_num(cfg->lgs_altitude, a, sizeof a), path, i,
                        wt_config_priv_fmt_num(alt[i], b, sizeof b), wt_config_priv_where_elem(ps, kk, i, oth, sizeof oth));
    return WT_OK;
}

static int check_sizes(pstate *ps, const wt_config *cfg, const char *path, const wt_recon_variant_config *v)
{
    char loc[512], oth[512];
    int k = wt_config_priv_find_key(path), kj = wt_config_priv_find_key("recon.wavelet_levels");
    long long need = 1LL << cfg->wavelet_levels;
    for (int i = 0; i < v->nlayers; i++)
        if (v->size[i] < need)
            return FAIL(ps, k, config_setting_get_elem(ps->set[k], (unsigned)i),
                        "key '%s', element [%d]: value %d is smaller than 2^recon.wavelet_levels = 2^%d = %lld (%s); "
                        "a layer grid needs at least 2^J points per side", path, i, v->size[i], cfg->wavelet_levels,
                        need, wt_config_priv_where(ps, kj, ps->set[kj], oth, sizeof oth));
    return WT_OK;
}

/* recon.<name>.layer_spacing_m / layer_size / layer_oversampling: which are given decides what is chosen
 * (config_grid.c). Both given: as written. Spacing given, size left out: the size follows from the spacing.
 * Both left out: both chosen, the spacing divided by layer_oversampling. Refused: a size without its
 * spacing (it fixes neither the resolution nor the extent) and an oversampling beside a given spacing (it
 * would be ignored). */
static int resolve_grid(pstate *ps, wt_config *cfg, const char *name, wt_recon_variant_config *v)
{
    char loc[512], oth[512], sp[64], sz[64], os[64];
    snprintf(sp, sizeof sp, "recon.%s.layer_spacing_m", name);
    snprintf(sz, sizeof sz, "recon.%s.layer_size", name);
    snprintf(os, sizeof os, "recon.%s.layer_oversampling", name);
    const int ks = wt_config_priv_find_key(sp), kz = wt_config_priv_find_key(sz), ko = wt_config_priv_find_key(os);
    const int gs = ps->set[ks] != NULL, gz = ps->set[kz] != NULL, go = ps->set[ko] != NULL;
    v->grid_auto = WT_GRID_EXPLICIT;
    if (gs && go)
        return FAIL(ps, ko, ps->set[ko], "key '%s' is given with '%s' (%s): the oversampling divides only the "
                    "automatic spacing; leave out one of them", os, sp, wt_config_priv_where(ps, ks, ps->set[ks], oth, sizeof oth));
    if (!gs && gz)
        return FAIL(ps, kz, ps->set[kz], "key '%s' is given but '%s' is left out (or \"auto\"): a size alone fixes "
                    "neither the resolution nor the extent of a layer; give both, only '%s' (the size then follows "
                    "from it), or neither (both chosen from the system)", sz, sp, sp);
    if (gs && gz) return WT_OK;
    v->grid_auto = gs ? WT_GRID_AUTO_SIZE : WT_GRID_AUTO;
    int st = wt_config_priv_layer_grid(ps->ctx, cfg, name, !gs, v);
    if (st == WT_OK && !gs) st = wt_config_priv_write_list(ps, ks, v->spacing, NULL, v->nlayers);
    if (st == WT_OK) st = wt_config_priv_write_list(ps, kz, NULL, v->size, v->nlayers);
    /* the canonical text gives the chosen grid and not the oversampling: it must read back (wavetomo run
     * parses a stored one), and an oversampling beside a given spacing is refused above */
    ps->set[ko] = NULL;
    return st;
}

/* The value chosen for key k (left out, or "auto") written into the tree in place of the word "auto", so that the
 * canonical text gives it as if the file had: the integer iv, or the string str when it is not NULL. */
static int write_chosen(pstate *ps, int k, int iv, const char *str)
{
    const char *leaf;
    config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, wt_config_priv_keys[k].path, &leaf), *s = NULL;
    if (g && config_setting_get_member(g, leaf)) config_setting_remove(g, leaf); /* the word "auto" */
    if (g) s = config_setting_add(g, leaf, str ? CONFIG_TYPE_STRING : CONFIG_TYPE_INT);
    if (!s || !(str ? config_setting_set_string(s, str) : config_setting_set_int(s, iv)))
        return WT_ERROR(ps->ctx, WT_ERR_NOMEM, "%s: libconfig could not add the chosen '%s'", ps->name,
                        wt_config_priv_keys[k].path);
    ps->set[k] = s;
    return WT_OK;
}

/* recon.sensor_points_per_subaperture left out (or "auto"): the smallest q with d/q ≤ the finest layer
 * spacing of both variants (within the 15 digits of the canonical text), at most the schema's 16; written
 * into the canonical text like the automatic grids. */
static int resolve_sensor_points(pstate *ps, wt_config *cfg)
{
    const int k = wt_config_priv_find_key("recon.sensor_points_per_subaperture");
    if (ps->set[k]) return WT_OK;
    double dmin = INFINITY;
    for (int i = 0; i < cfg->pcg3.nlayers; i++) dmin = fmin(dmin, cfg->pcg3.spacing[i]);
    for (int i = 0; i < cfg->cg9.nlayers; i++) dmin = fmin(dmin, cfg->cg9.spacing[i]);
    const double d = cfg->diameter / cfg->lgs_wfs.subapertures;
    int q = (int)ceil(d / dmin * (1.0 - 1e-12));
    cfg->sensor_points = q < 1 ? 1 : q > 16 ? 16 : q;
    return write_chosen(ps, k, cfg->sensor_points, NULL);
}

/* recon.cg9.fit_points_per_subaperture left out (or "auto"): the smallest q with d/q ≤ half the finer of the
 * finest cg9 layer spacing and the finest DM pitch (within the 15 digits of the canonical text), at most the
 * schema's 16: two samples per cell of the finest grid the fit reads or writes, so that the sampled least
 * squares ‖H a − P φ‖² approaches the integral over the pupil (docs/results.md §18); written into the
 * canonical text like the automatic grids. The E-ELT and demo presets: q = 2, the 42x42 preset: q = 4. */
static int resolve_fit_points(pstate *ps, wt_config *cfg)
{
    const int k = wt_config_priv_find_key("recon.cg9.fit_points_per_subaperture");
    if (ps->set[k]) return WT_OK;
    double fine = INFINITY;
    for (int i = 0; i < cfg->cg9.nlayers; i++) fine = fmin(fine, cfg->cg9.spacing[i]);
    for (int i = 0; i < cfg->ndms; i++) fine = fmin(fine, cfg->dm_pitch[i]);
    const double d = cfg->diameter / cfg->lgs_wfs.subapertures;
    int q = isfinite(fine) ? (int)ceil(d / (0.5 * fine) * (1.0 - 1e-12)) : 2;
    cfg->cg9.fit_sampling = q < 1 ? 1 : q > 16 ? 16 : q;
    return write_chosen(ps, k, cfg->cg9.fit_sampling, NULL);
}

/* recon.<variant>.prior left out (or "auto"): recon.prior when given, else the variant's default
 * (WT_PRIOR_DEFAULT_*, config.h); written into the canonical text like the automatic grids, so the text
 * (and an MVM's identity) says which prior each variant used. */
static int resolve_priors(pstate *ps, wt_config *cfg)
{
    static const char *const words[] = {"paper", "exact", "full"};
    const int kg = wt_config_priv_find_key("recon.prior");
    if (!ps->set[kg]) cfg->exact_prior = -1;
    for (int v = 0; v < 2; v++) {
        const int k = wt_config_priv_find_key(v ? "recon.cg9.prior" : "recon.pcg3.prior");
        wt_recon_variant_config *var = v ? &cfg->cg9 : &cfg->pcg3;
        if (ps->set[k]) continue;
        var->prior = ps->set[kg] ? cfg->exact_prior : v ? WT_PRIOR_DEFAULT_CG9 : WT_PRIOR_DEFAULT_PCG3;
        const int st = write_chosen(ps, k, 0, words[var->prior]);
        if (st < 0) return st;
    }
    return WT_OK;
}

/* A file's SHA-256 key (lgs.sodium_profile_sha256, recon.fft_wisdom_sha256) left out (or "auto") while its
 * file is used: the SHA-256 of the file's bytes, written into the canonical text. For the sodium profile this
 * makes the matrix hash follow the profile's contents (an MVM built with one profile is refused after the file
 * changes); for the FFT wisdom, every output records which plans ran. A file that cannot be hashed here
 * (missing, unreadable, not a regular file) leaves the key out: the code that reads the file refuses it with
 * the reason (core/model/sensing.c, core/la/fft.c), and nothing runs without it. A given value (the canonical
 * text of a telemetry or matrix file, read back where the relative path may not resolve) is kept: it records
 * the file the system was made with; the reader checks the file against it. */
static int resolve_file_sha256(pstate *ps, const char *key, int used, const char *file, char hex[65])
{
    const int k = wt_config_priv_find_key(key);
    if (ps->set[k] || !used || !file[0]) return WT_OK;
    if (wt_sha256_file(file, hex) != 0) {
        hex[0] = '\0';
        return WT_OK;
    }
    return write_chosen(ps, k, 0, hex);
}

/* loop.gain_levels: L + 1 values need every DM's grid (actuators + 2 guard rings per side), embedded in
 * the smallest power of two n, to hold squares (or a Daubechies scaling block) of 2^(L+1) actuators:
 * L + 1 <= log2 n (core/op/scale_gain.h). loop.gain_basis means nothing without them. */
static int check_gain_levels(pstate *ps, const wt_config *cfg)
{
    char loc[512], oth[512];
    const int k = wt_config_priv_find_key("loop.gain_levels"), kb = wt_config_priv_find_key("loop.gain_basis");
    if (cfg->ngain_levels == 0) {
        if (ps->set[kb])
            return FAIL(ps, kb, ps->set[kb], "key 'loop.gain_basis' is given without 'loop.gain_levels': it chooses "
                        "the bands of a scale-dependent gain; give the gains or leave it out");
        return WT_OK;
    }
    for (int d = 0; d < cfg->ndms; d++) {
        const int side = cfg->dm_actuators[d] + 2 * cfg->dm_guard_rings;
        int n = 1, lmax = 0;
        while (n < side) n *= 2, lmax++;
        if (cfg->ngain_levels > lmax)
            return FAIL(ps, k, ps->set[k], "key 'loop.gain_levels' has %d values, but DM %d's grid of %d actuators "
                        "per side ('dm.actuators' [%d] = %d at %s, plus 2 x 'dm.guard_rings' = %d) embeds in %d "
                        "points, whose coarsest band of %d values would need squares of %d; expected 2 ... %d values",
                        cfg->ngain_levels, d + 1, side, d, cfg->dm_actuators[d],
                        wt_config_priv_where_elem(ps, wt_config_priv_find_key("dm.actuators"), d, oth, sizeof oth), cfg->dm_guard_rings, n,
                        cfg->ngain_levels, 1 << cfg->ngain_levels, lmax);
    }
    return WT_OK;
}

int wt_config_priv_check_consistency(pstate *ps, wt_config *cfg)
{
    char loc[512], oth[512];
    int st, k;
    double sum = 0.0;
    for (int i = 0; i < cfg->nlayers; i++) sum += cfg->layer_fraction[i];
    k = wt_config_priv_find_key("atmosphere.cn2_fractions");
    if (!(fabs(sum - 1.0) <= 0.01))
        return FAIL(ps, k, ps->set[k], "key 'atmosphere.cn2_fractions': the fractions sum to %.6g; expected 1 within 1 %% "
                    "(they are then normalised to sum exactly 1)", sum);
    for (int i = 0; i < cfg->nlayers; i++) cfg->layer_fraction[i] /= sum;
    if ((st = wt_config_priv_resolve_model(ps, cfg)) < 0) return st;
    if ((st = wt_config_priv_check_night(ps, cfg)) < 0) return st;
    if ((st = wt_config_priv_check_sodium(ps, cfg)) < 0) return st;

    k = wt_config_priv_find_key("evaluation.settle_frames");
    if (cfg->settle_frames >= cfg->frames)
        return FAIL(ps, k, ps->set[k], "key 'evaluation.settle_frames': value %d is not below 'loop.frames' = %d (%s); "
                    "no frame would be left to average", cfg->settle_frames, cfg->frames,
                    wt_config_priv_where_elem(ps, wt_config_priv_find_key("loop.frames"), -1, oth, sizeof oth));

    if (cfg->nlgs + cfg->nngs == 0)
        return wt_config_priv_fail(ps, ps->name, "'lgs.count' is 0 and 'ngs.azimuths_deg' is empty: the system has no guide star");

    if (cfg->nlgs > 0) {
        if ((st = check_below_lgs(ps, cfg, "atmosphere.altitudes_m", cfg->layer_altitude, cfg->nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "dm.altitudes_m", cfg->dm_altitude, cfg->ndms)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.pcg3.layer_altitudes_m", cfg->pcg3.altitudes, cfg->pcg3.nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.cg9.layer_altitudes_m", cfg->cg9.altitudes, cfg->cg9.nlayers)) < 0 ||
            (st = check_below_lgs(ps, cfg, "recon.atmosphere.altitudes_m", cfg->model.altitude,
                                  cfg->model.source != WT_MODEL_ORACLE ? cfg->model.nlayers : 0)) < 0)
            return st;
    }
    if ((st = resolve_grid(ps, cfg, "pcg3", &cfg->pcg3)) < 0 || (st = resolve_grid(ps, cfg, "cg9", &cfg->cg9)) < 0)
        return st;
    if ((st = check_sizes(ps, cfg, "recon.pcg3.layer_size", &cfg->pcg3)) < 0 ||
        (st = check_sizes(ps, cfg, "recon.cg9.layer_size", &cfg->cg9)) < 0)
        return st;
    if ((st = resolve_sensor_points(ps, cfg)) < 0) return st;
    {   /* the mode says which focus the removal takes out: without the removal it would be ignored */
        const int km = wt_config_priv_find_key("recon.lgs_focus_mode");
        if (ps->set[km] && !cfg->lgs_focus_removal)
            return FAIL(ps, km, ps->set[km], "key 'recon.lgs_focus_mode' is given but 'recon.lgs_focus_removal' is "
                        "false: the mode chooses which LGS focus the removal projects out; set "
                        "recon.lgs_focus_removal = true, or leave the mode out");
    }
    if ((st = resolve_fit_points(ps, cfg)) < 0) return st;
    if ((st = resolve_priors(ps, cfg)) < 0) return st;
    if ((st = resolve_file_sha256(ps, "lgs.sodium_profile_sha256",
                                  cfg->nlgs > 0 && cfg->lgs_wfs.model == WT_WFS_DIFFRACTIVE, cfg->sodium_profile,
                                  cfg->sodium_profile_sha256)) < 0 ||
        (st = resolve_file_sha256(ps, "recon.fft_wisdom_sha256", 1, cfg->fft_wisdom, cfg->fft_wisdom_sha256)) < 0)
        return st;
    if ((st = check_gain_levels(ps, cfg)) < 0) return st;
    if (cfg->predict_integrator == 1 && cfg->ngain_levels > 0) {
        const int ki = wt_config_priv_find_key("recon.predict_integrator");
        return FAIL(ps, ki, ps->set[ki], "key 'recon.predict_integrator' = \"layers\" runs the integrator on the layers "
                    "with the single gain loop.gain; it cannot take 'loop.gain_levels' (a gain per scale of the DM "
                    "commands): leave one of the two out");
    }

    for (int t = 0; t < 2; t++) {
        const char *pre = t ? "ngs.wfs" : "lgs.wfs";
        const wt_sensor_config *w = t ? &cfg->ngs_wfs : &cfg->lgs_wfs;
        char a[96], b[96];
        if ((t ? cfg->nngs : cfg->nlgs) == 0 || w->model != WT_WFS_DIFFRACTIVE) continue;
        snprintf(a, sizeof a, "%s.fft_size", pre);
        snprintf(b, sizeof b, "%s.pupil_samples", pre);
        k = wt_config_priv_find_key(a);
        if (w->fft_size % 2 || w->fft_size < 2 * w->pupil_samples)
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the FFT sampling is too coarse or odd for '%s' = %d; "
                        "expected an even number >= %d (2 x %s: Nyquist sampling of the wavelength over the "
                        "subaperture side)", a, w->fft_size, b, w->pupil_samples, 2 * w->pupil_samples, b);
        snprintf(a, sizeof a, "%s.window_pixels", pre);
        snprintf(b, sizeof b, "%s.pixels", pre);
        k = wt_config_priv_find_key(a);
        if (w->window_pixels > w->pixels || (w->window_pixels > 0 && (w->pixels - w->window_pixels) % 2))
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the window must fit the detector '%s' = %d with an even "
                        "difference (it is centred), or be 0 (the whole detector)", a, w->window_pixels, b, w->pixels);
        if (w->centroider == 2 && w->window_pixels != 0 && w->window_pixels != w->pixels)
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: the matched filter ('%s.centroider' = \"mf\") uses every "
                        "pixel; expected 0 or '%s' = %d", a, w->window_pixels, pre, b, w->pixels);
        k = wt_config_priv_find_key(b);
        if (w->pixels > 256) /* WT_CENTROID_MAX_PIXELS of core/optics/centroid.h */
            return FAIL(ps, k, ps->set[k], "key '%s' = %d: a diffractive detector has at most 256 pixels per side",
                        b, w->pixels);
        snprintf(a, sizeof a, "%s.nea_mas", pre);
        k = wt_config_priv_find_key(a);
        if (ps->set[k])
            return FAIL(ps, k, ps->set[k], "key '%s' is a geometric-model key (it replaces the photon/read-noise "
                        "model); with '%s.model' = \"diffractive\" the noise comes from the pixels: leave it out", a, pre);
        if (t && w->tilt == WT_SH_TILT_Z_CFG) {
            k = wt_config_priv_find_key("ngs.wfs.tilt");
            return FAIL(ps, k, ps->set[k], "key 'ngs.wfs.tilt' = \"z\" concerns the geometric model; with "
                        "'ngs.wfs.model' = \"diffractive\" an NGS measures what its centroider measures (a G-tilt): "
                        "use \"g\" or the geometric model");
        }
    }

    /* the NGS sensors have no keys of their own for these */
    cfg->ngs_wfs.valid_fraction = cfg->lgs_wfs.valid_fraction;
    cfg->ngs_wfs.subapertures = 0;
    return WT_OK;
}
