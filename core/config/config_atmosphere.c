/* core/config/config_atmosphere.c: the truth's atmosphere from a profile file, and the reconstructors' own
 * atmosphere (recon.atmosphere; SPEC §12 "Truth and model are separate objects").
 *
 * A profile file (atmosphere.profile for the truth, recon.atmosphere.profile for a given model) is plain text,
 * one layer a line: altitude [m], Cn² fraction, wind speed [m/s], and optionally the wind direction [deg] (the
 * direction the layer moves towards, from +x towards +y); '#' starts a comment, blank lines are skipped, fields
 * are separated by blanks. Refused with FILE:LINE: a field that is not a finite number, a line with fewer than 3
 * or more than 4 columns or with other columns than the first layer's, a negative fraction, an altitude not above
 * the previous one, a value outside its key's range, more than WT_MAX_LAYERS layers; and, naming the file, no
 * layer, or fractions that do not sum to 1 within WT_PROFILE_SUM_TOL (a truncated or mistyped table is likelier
 * than a deliberate one; within it they are normalised to 1 as the configuration's lists are). The values are
 * rounded to the 15 significant digits of the canonical text, where they are written as the group's lists: a
 * stored configuration reads back to the same bits without the file.
 *
 * The model may then be given a controlled error (recon.atmosphere.error_*: sensitivity experiments; see
 * apply_errors below). The truth is never touched.
 */
#include "config_private.h"

#include "../base/numbers.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A profile's fractions must sum to 1 within this: the ESO 35-layer table sums to 1 within 4e-7 (values of 6
 * digits); a missing line of the smallest layer of a real profile (~4e-4) is still seen. */
#define WT_PROFILE_SUM_TOL 1e-3

/* the columns of a profile file and the keys whose range (and list) each one fills */
enum { COL_ALT, COL_FRAC, COL_SPEED, COL_DIR, NCOL };
static const char *const col_key[NCOL] = {"altitudes_m", "cn2_fractions", "wind_speed_mps", "wind_direction_deg"};
static const char *const col_name[NCOL] = {"altitude [m]", "Cn2 fraction", "wind speed [m/s]",
                                           "wind direction [deg]"};

typedef struct profile {
    int n;                           /* layers */
    int ncol;                        /* 3, or 4 with directions */
    double v[NCOL][WT_MAX_LAYERS];   /* the columns in the file's units */
} profile;

/* The value rounded to the 15 significant digits the canonical text keeps (config_canonical.c's build_text). */
static double round15(double x)
{
    char b[40];
    snprintf(b, sizeof b, "%.15g", x);
    return strtod(b, NULL);
}

/* Reads and checks profile file `path` (key: the configuration key that named it, at loc) for group `group`. */
static int read_profile(wt_config_priv_state *ps, const char *path, const char *key, const char *loc, const char *group,
                        profile *p)
{
    wt_context *ctx = ps->ctx;
    int st = WT_OK, lineno = 0, first_line = 0, prev_line = 0;
    char *line = NULL;
    size_t cap = 0;
    double *v = NULL; /* a line's numbers (wt_read_numbers) */
    long vcap = 0;
    double sum = 0.0;
    const wt_config_priv_key_spec *ks[NCOL];
    for (int c = 0; c < NCOL; c++) {
        char k[96];
        snprintf(k, sizeof k, "%s.%s", group, col_key[c]);
        ks[c] = &wt_config_priv_keys[wt_config_priv_find_key(k)];
    }
    char tail[1280]; /* what every message of a line ends with */
    snprintf(tail, sizeof tail, "(the profile of key '%s' at %s)", key, loc);
    memset(p, 0, sizeof *p);
    FILE *f = fopen(path, "r");
    if (!f)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key '%s': cannot open the profile file '%s': %s", loc, key, path,
                        strerror(errno));
    while (getline(&line, &cap, f) >= 0) {
        lineno++;
        const wt_numbers_where w = {path, lineno, 1, col_name, NCOL, tail, WT_ERR_CONFIG};
        const long nf = wt_read_numbers(ctx, line, &w, &v, &vcap);
        if (nf < 0) {
            st = (int)nf;
            goto out;
        }
        if (nf == 0) continue;
        if (nf < NCOL - 1 || nf > NCOL) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG,
                          "%s:%d: %ld column%s; expected 3 or 4: altitude [m], Cn2 fraction, wind speed [m/s] and an "
                          "optional wind direction [deg] %s", path, lineno, nf, nf == 1 ? "" : "s",
                          tail);
            goto out;
        }
        if (p->n == 0) p->ncol = (int)nf, first_line = lineno;
        else if (nf != p->ncol) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: %ld columns, but the first layer (line %d) has %d: every line "
                          "must have the same columns %s", path, lineno, nf, first_line, p->ncol,
                          tail);
            goto out;
        }
        if (p->n == WT_MAX_LAYERS) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: more than %d layers %s", path, lineno,
                          WT_MAX_LAYERS, tail);
            goto out;
        }
        if (v[COL_FRAC] < 0.0) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: the Cn2 fraction %g is negative %s", path, lineno,
                          v[COL_FRAC], tail);
            goto out;
        }
        if (p->n > 0 && !(v[COL_ALT] > p->v[COL_ALT][p->n - 1])) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: altitude %g m is not above the previous layer's %g m (line %d): "
                          "the altitudes must be strictly increasing %s", path, lineno, v[COL_ALT],
                          p->v[COL_ALT][p->n - 1], prev_line, tail);
            goto out;
        }
        for (int c = 0; c < nf; c++) {
            if (v[c] < ks[c]->lo || v[c] > ks[c]->hi) {
                st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s:%d: column %d (%s): %g is out of range; expected [%g, %g] as "
                              "'%s' %s", path, lineno, c + 1, col_name[c], v[c], ks[c]->lo, ks[c]->hi,
                              ks[c]->path, tail);
                goto out;
            }
            p->v[c][p->n] = round15(v[c]);
        }
        sum += p->v[COL_FRAC][p->n];
        prev_line = lineno;
        p->n++;
    }
    if (ferror(f)) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: reading the profile file failed: %s (key '%s' at %s)", path,
                      strerror(errno), key, loc);
        goto out;
    }
    if (p->n == 0) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: no layer in the profile file (key '%s' at %s)", path, key, loc);
        goto out;
    }
    if (!(fabs(sum - 1.0) <= WT_PROFILE_SUM_TOL))
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: the Cn2 fractions of its %d layers (lines %d-%d) sum to %.9g; expected 1 "
                      "within %g (key '%s' at %s)", path, p->n, first_line, prev_line, sum, WT_PROFILE_SUM_TOL, key, loc);
out:
    free(line); /* getline's buffer comes from malloc */
    wt_free(ctx, v);
    fclose(f);
    return st;
}

/* How key k was set: -1 not at all, 0 in the file's body, 1 by an override (the file's or --set). */
static int how_set(const wt_config_priv_state *ps, int k, const char *path)
{
    if (!config_lookup(ps->cf, path)) return -1;
    return ps->ovidx[k] >= 0;
}

/* group.profile → the group's lists (wt_config_priv_expand_profiles). A profile given by an override replaces the
 * lists the file's body (or an @included file) gives: a preset derived from another changes its atmosphere so.
 * Refused: a profile beside lists given at the same level (the file's body, or overrides), and, without a
 * direction column, a profile override whose directions are not an override too (the base file's would be
 * another atmosphere's). */
static int expand_one(wt_config_priv_state *ps, const char *group)
{
    char key[96], loc[1100], oth[1100], lk[NCOL][96];
    snprintf(key, sizeof key, "%s.profile", group);
    const int kp = wt_config_priv_find_key(key);
    const config_setting_t *s = config_lookup(ps->cf, key);
    if (!s) return WT_OK;
    wt_config_priv_where(ps, kp, s, loc, sizeof loc);
    const char *str = config_setting_type(s) == CONFIG_TYPE_STRING ? config_setting_get_string(s) : NULL;
    if (!str || !*str)
        return wt_config_priv_fail(ps, loc, "key '%s': expected a string (a file path)", key);
    char path[1024];
    const int rel = str[0] != '/' && ps->incdir && *ps->incdir;
    if ((size_t)snprintf(path, sizeof path, "%s%s", rel ? ps->incdir : "", str) >= sizeof path)
        return wt_config_priv_fail(ps, loc, "key '%s': the path \"%s\" is too long", key, str);
    const int over = ps->ovidx[kp] >= 0;
    profile p;
    int st = read_profile(ps, path, key, loc, group, &p);
    if (st < 0) return st;
    int kc[NCOL];
    for (int c = 0; c < NCOL; c++) {
        snprintf(lk[c], sizeof lk[c], "%s.%s", group, col_key[c]);
        kc[c] = wt_config_priv_find_key(lk[c]);
        const int how = how_set(ps, kc[c], lk[c]);
        const config_setting_t *x = config_lookup(ps->cf, lk[c]);
        if (c == COL_DIR && p.ncol < NCOL) { /* the directions are the configuration's */
            if (how < 0 || (over && how == 0))
                return wt_config_priv_fail(ps, loc, "key '%s': the profile file %s has no wind direction column: give "
                                           "'%s' (%d values [deg], one per layer%s), or a fourth column in the file",
                                           key, path, lk[c], p.n, over ? ", by an override as the profile is" : "");
            continue;
        }
        if (how < 0) continue;
        if (!over || how == 1)
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, kc[c], x, oth, sizeof oth),
                                       "key '%s' is given beside '%s' (%s), whose file gives the %s: leave out one "
                                       "of them", lk[c], key, loc, c == COL_DIR ? "directions" : "layers");
        /* the profile override replaces the base's list */
        const char *leaf;
        config_setting_t *g = wt_config_priv_ensure_parent(ps->cf, lk[c], &leaf);
        if (g) config_setting_remove(g, leaf);
    }
    for (int c = 0; c < p.ncol; c++)
        if ((st = wt_config_priv_write_list(ps, kc[c], p.v[c], NULL, p.n)) < 0) return st;
    return WT_OK;
}

int wt_config_priv_expand_profiles(wt_config_priv_state *ps)
{
    int st = expand_one(ps, "atmosphere");
    return st < 0 ? st : expand_one(ps, "recon.atmosphere");
}

static const char *const model_keys[] = {"recon.atmosphere.r0_m",           "recon.atmosphere.L0_m",
                                         "recon.atmosphere.profile",        "recon.atmosphere.altitudes_m",
                                         "recon.atmosphere.cn2_fractions",  "recon.atmosphere.wind_speed_mps",
                                         "recon.atmosphere.wind_direction_deg"};
enum { NMODEL_KEYS = sizeof model_keys / sizeof *model_keys };

/* ---------------------------------------------------------------- a controlled model error */

/* The keys of recon.atmosphere.error_* (sensitivity experiments: what a wrong profile costs each reconstructor).
 * Each changes the model only, after the oracle's or the given profile is formed, in this order: r0; the ground
 * layer's fraction (on the profile's altitudes); the high layers' altitudes; the wind. A key left out, or given
 * with its value of no error, changes nothing and is left out of the canonical text (so a sweep's 0 is the
 * error-free run, matrix identity included); the two keys that qualify another (error_ground_top_m,
 * error_high_bottom_m) likewise when that one is. The high layers' bottom is a key, not a constant: what is
 * "high" depends on the profile and on the reconstructor's layers (5 km, the default, is above the boundary
 * layer and PCG-3's 4 km DM). */
enum { E_GROUND, E_GROUND_TOP, E_R0, E_SHIFT, E_BOTTOM, E_SPEED, E_DIR, NERR };
static const char *const err_keys[NERR] = {
    "recon.atmosphere.error_ground_fraction", "recon.atmosphere.error_ground_top_m",
    "recon.atmosphere.error_r0_scale",        "recon.atmosphere.error_high_shift_m",
    "recon.atmosphere.error_high_bottom_m",   "recon.atmosphere.error_wind_speed_scale",
    "recon.atmosphere.error_wind_direction_deg"};

/* "LOC: key 'K': text" for error key e. */
static int err_fail(wt_config_priv_state *ps, int e, const char *text)
{
    char loc[1100];
    const int k = wt_config_priv_find_key(err_keys[e]);
    wt_config_priv_where(ps, k, ps->set[k], loc, sizeof loc);
    return wt_config_priv_fail(ps, loc, "key '%s': %s", err_keys[e], text);
}

static int apply_errors(wt_config_priv_state *ps, wt_config *cfg)
{
    wt_model_atmosphere_config *m = &cfg->model;
    int k[NERR];
    for (int e = 0; e < NERR; e++) k[e] = wt_config_priv_find_key(err_keys[e]);
    /* no error: out of the canonical text (and of the matrix identity) */
    if (m->error_ground_fraction == 0.0) ps->set[k[E_GROUND]] = NULL;
    if (!ps->set[k[E_GROUND]]) ps->set[k[E_GROUND_TOP]] = NULL;
    if (m->error_r0_scale == 1.0) ps->set[k[E_R0]] = NULL;
    if (m->error_high_shift == 0.0) ps->set[k[E_SHIFT]] = NULL;
    if (!ps->set[k[E_SHIFT]]) ps->set[k[E_BOTTOM]] = NULL;
    if (m->error_wind_speed_scale == 1.0) ps->set[k[E_SPEED]] = NULL;
    if (m->error_wind_direction == 0.0) ps->set[k[E_DIR]] = NULL;
    for (int e = 0; e < NERR; e++) /* and as if left out: the canonical text reads back to the same numbers */
        if (!ps->set[k[e]]) *(double *)((char *)cfg + wt_config_priv_keys[k[e]].off) = wt_config_priv_keys[k[e]].def;
    char msg[600];
    if (ps->set[k[E_R0]]) {
        const wt_config_priv_key_spec *r0k = &wt_config_priv_keys[wt_config_priv_find_key("recon.atmosphere.r0_m")];
        const double r0 = m->error_r0_scale * m->r0;
        if (!(r0 >= r0k->lo && r0 <= r0k->hi)) {
            snprintf(msg, sizeof msg, "the model's r0 would be %g x %g m = %g m, outside recon.atmosphere.r0_m's range "
                     "[%g, %g] m", m->error_r0_scale, m->r0, r0, r0k->lo, r0k->hi);
            return err_fail(ps, E_R0, msg);
        }
        m->r0 = r0;
    }
    if (ps->set[k[E_GROUND]]) {
        /* the ground layers' fraction G becomes G + e, each ground layer scaled by (G + e)/G, the others by
         * (1 − G − e)/(1 − G): the profile's shape within each part is kept, the total stays 1 */
        double g = 0.0, o = 0.0;
        int ng = 0;
        for (int l = 0; l < m->nlayers; l++) {
            const int ground = l == 0 || m->altitude[l] <= m->error_ground_top;
            if (ground) g += m->fraction[l], ng++;
            else o += m->fraction[l];
        }
        const double g1 = g + m->error_ground_fraction;
        if (!(g1 >= 0.0 && g1 <= 1.0) || (g == 0.0 && g1 > 0.0) || (o == 0.0 && g1 < 1.0)) {
            snprintf(msg, sizeof msg, "the model's ground layer (%d layer%s up to %g m, error_ground_top_m = %g m) holds "
                     "%.6g of the Cn2, the other layers %.6g; with this error it would hold %.6g, %s", ng,
                     ng > 1 ? "s" : "", m->altitude[ng - 1], m->error_ground_top, g, o, g1,
                     !(g1 >= 0.0 && g1 <= 1.0) ? "not a fraction in [0, 1]"
                     : g == 0.0                ? "but it holds no Cn2 to scale"
                                               : "but no other layer holds Cn2 to take the rest");
            return err_fail(ps, E_GROUND, msg);
        }
        const double sg = g > 0.0 ? g1 / g : 0.0, so = o > 0.0 ? (1.0 - g1) / o : 0.0;
        for (int l = 0; l < m->nlayers; l++)
            m->fraction[l] *= l == 0 || m->altitude[l] <= m->error_ground_top ? sg : so;
    }
    if (ps->set[k[E_SHIFT]]) {
        int moved = 0;
        for (int l = 0; l < m->nlayers; l++) {
            if (!(m->altitude[l] >= m->error_high_bottom)) continue;
            const double h = m->altitude[l] + m->error_high_shift;
            if (h < 0.0 || (cfg->nlgs > 0 && h >= cfg->lgs_altitude)) {
                snprintf(msg, sizeof msg, "it would move the model layer at %g m to %g m, %s", m->altitude[l], h,
                         h < 0.0 ? "below the ground" : "at or above the LGS altitude (lgs.altitude_m)");
                return err_fail(ps, E_SHIFT, msg);
            }
            m->altitude[l] = h;
            moved++;
        }
        if (!moved) {
            snprintf(msg, sizeof msg, "no model layer is at or above error_high_bottom_m = %g m (the highest is at %g "
                     "m): the shift would move nothing", m->error_high_bottom, m->altitude[m->nlayers - 1]);
            return err_fail(ps, E_SHIFT, msg);
        }
        /* in order of altitude again (stable: layers that meet keep their order) */
        for (int i = 1; i < m->nlayers; i++)
            for (int j = i; j > 0 && m->altitude[j - 1] > m->altitude[j]; j--) {
                double *col[4] = {m->altitude, m->fraction, m->wind_speed, m->wind_direction};
                for (int c = 0; c < 4; c++) {
                    const double t = col[c][j];
                    col[c][j] = col[c][j - 1];
                    col[c][j - 1] = t;
                }
            }
    }
    for (int l = 0; l < m->nlayers; l++) {
        if (ps->set[k[E_SPEED]]) m->wind_speed[l] *= m->error_wind_speed_scale;
        if (ps->set[k[E_DIR]]) m->wind_direction[l] += m->error_wind_direction;
    }
    return WT_OK;
}

int wt_config_priv_resolve_model(wt_config_priv_state *ps, wt_config *cfg)
{
    char loc[1100], oth[1100];
    wt_model_atmosphere_config *m = &cfg->model;
    const int ks = wt_config_priv_find_key("recon.atmosphere.source");
    wt_config_priv_where(ps, ks, ps->set[ks], oth, sizeof oth);
    /* a model's keys under another source by default are a mistake; under a source chosen explicitly they are a model
     * kept for another source (a --sweep recon.atmosphere.source=oracle,given,learned) and wait unused */
    const int explicit_src = ps->ovidx[ks] >= 0 || config_setting_source_line(ps->set[ks]) > 0;
    static const char *const learn_keys[] = {"recon.atmosphere.update_s", "recon.atmosphere.mvm_latency_s",
                                             "recon.atmosphere.learn_window", "recon.atmosphere.learn_memory",
                                             "recon.atmosphere.learn_grid", "recon.atmosphere.learn_wind"};
    for (int i = 0; i < 6; i++) {
        const int k = wt_config_priv_find_key(learn_keys[i]);
        /* the oracle in a changing night follows the truth every update_s (an MVM after its latency) */
        const int night_oracle = i < 2 && m->source == WT_MODEL_ORACLE && cfg->night.source != WT_NIGHT_CFG_NONE;
        if (m->source != WT_MODEL_LEARNED && ps->set[k] && !explicit_src && !night_oracle)
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, k, ps->set[k], loc, sizeof loc),
                                       "key '%s' is for a learned model, but 'recon.atmosphere.source' is \"%s\"",
                                       learn_keys[i], m->source == WT_MODEL_ORACLE ? "oracle" : "given");
    }
    for (int i = 0; i < NMODEL_KEYS; i++) {
        const int k = wt_config_priv_find_key(model_keys[i]);
        if (m->source == WT_MODEL_ORACLE && ps->set[k] && !explicit_src)
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, k, ps->set[k], loc, sizeof loc),
                                       "key '%s' is given but 'recon.atmosphere.source' is \"oracle\" (%s): the oracle "
                                       "takes the truth's profile, r0 and L0; set source = \"given\" to use your own",
                                       model_keys[i], ps->ovidx[ks] >= 0 || config_setting_source_line(ps->set[ks]) > 0
                                                         ? oth : "its default");
        if (m->source != WT_MODEL_ORACLE && !ps->set[k] && i != 2)
            return wt_config_priv_fail(ps, oth, "'recon.atmosphere.source' is \"%s\" but key '%s' is missing: a %s "
                                       "model needs r0_m, L0_m and its layers (altitudes_m, cn2_fractions, "
                                       "wind_speed_mps, wind_direction_deg, or a profile file)%s",
                                       m->source == WT_MODEL_GIVEN ? "given" : "learned", model_keys[i],
                                       m->source == WT_MODEL_GIVEN ? "given" : "learned",
                                       m->source == WT_MODEL_GIVEN ? "" : ": the one it starts from");
    }
    /* the profile files are in the canonical text as their lists */
    ps->set[wt_config_priv_find_key("atmosphere.profile")] = NULL;
    ps->set[wt_config_priv_find_key("recon.atmosphere.profile")] = NULL;
    if (m->source == WT_MODEL_ORACLE) { /* the truth, as loaded and normalised: the same doubles */
        m->r0 = cfg->r0;
        m->L0 = cfg->L0;
        m->nlayers = cfg->nlayers;
        for (int l = 0; l < cfg->nlayers; l++) {
            m->altitude[l] = cfg->layer_altitude[l];
            m->fraction[l] = cfg->layer_fraction[l];
            m->wind_speed[l] = cfg->wind_speed[l];
            m->wind_direction[l] = cfg->wind_direction[l];
        }
        return apply_errors(ps, cfg);
    }
    double sum = 0.0; /* the same rule as the truth's lists (config_check.c) */
    for (int l = 0; l < m->nlayers; l++) sum += m->fraction[l];
    const int kf = wt_config_priv_find_key("recon.atmosphere.cn2_fractions");
    if (!(fabs(sum - 1.0) <= 0.01))
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kf, ps->set[kf], loc, sizeof loc),
                                   "key 'recon.atmosphere.cn2_fractions': the fractions sum to %.6g; expected 1 within "
                                   "1 %% (they are then normalised to sum exactly 1)", sum);
    for (int l = 0; l < m->nlayers; l++) m->fraction[l] /= sum;
    return apply_errors(ps, cfg);
}

int wt_config_priv_check_night(wt_config_priv_state *ps, const wt_config *cfg)
{
    static const char *const walk[] = {"seed", "correlation_time_s", "step_s", "r0_log_rms", "fraction_log_rms",
                                       "wind_speed_log_rms", "wind_direction_rms_deg"};
    char loc[1100], oth[1100], key[96];
    const int ks = wt_config_priv_find_key("atmosphere.night.source"), kf = wt_config_priv_find_key("atmosphere.night.file");
    const int src = cfg->night.source;
    const char *name[] = {"none", "file", "random"};
    wt_config_priv_where(ps, ks, ps->set[ks], oth, sizeof oth);
    if (src == WT_NIGHT_CFG_FILE && !ps->set[kf])
        return wt_config_priv_fail(ps, oth, "'atmosphere.night.source' is \"file\" but key 'atmosphere.night.file' is "
                                   "missing: give the night's states (data/nights/ has some), or source = \"random\"");
    for (int i = -3; i < (int)(sizeof walk / sizeof *walk); i++) {
        if (i < 0) snprintf(key, sizeof key, "atmosphere.night.%s", i == -3 ? "file" : i == -2 ? "start_s" : "compression");
        else snprintf(key, sizeof key, "atmosphere.night.%s", walk[i]);
        const int k = wt_config_priv_find_key(key);
        /* the night's clock (start_s, compression) also times a sodium sequence */
        const int ok = i == -3 ? src == WT_NIGHT_CFG_FILE
                       : i < 0 ? src != WT_NIGHT_CFG_NONE || cfg->sodium_sequence[0]
                               : src == WT_NIGHT_CFG_RANDOM;
        if (ps->set[k] && !ok)
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, k, ps->set[k], loc, sizeof loc),
                                       "key '%s' is given but 'atmosphere.night.source' is \"%s\" (%s): it %s", key,
                                       name[src], ps->set[ks] ? oth : "its default",
                                       i == -3   ? "is the states of source = \"file\""
                                       : i < 0   ? "means nothing without a night (source = \"file\" or \"random\")"
                                                 : "is a key of the stochastic night (source = \"random\")");
    }
    return WT_OK;
}

int wt_config_priv_check_sodium(wt_config_priv_state *ps, const wt_config *cfg)
{
    char loc[1100], oth[1100];
    const int kq = wt_config_priv_find_key("lgs.sodium_sequence"), ku = wt_config_priv_find_key("lgs.sodium_sequence_update_s");
    const int kr = wt_config_priv_find_key("lgs.wfs.reference"), kt = wt_config_priv_find_key("lgs.wfs.reference_update_s");
    const int kf = wt_config_priv_find_key("lgs.wfs.focus_stage"), kg = wt_config_priv_find_key("lgs.wfs.focus_stage_gain");
    const int kn = wt_config_priv_find_key("lgs.wfs.gain_update_s");
    const int diffr = cfg->nlgs > 0 && cfg->lgs_wfs.model == WT_WFS_DIFFRACTIVE;
    const int keys[6] = {kq, kr, kt, kf, kg, kn};
    for (int i = 0; i < 6; i++)
        if (ps->set[keys[i]] && !diffr)
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, keys[i], ps->set[keys[i]], loc, sizeof loc),
                                       "key '%s' is for diffractive LGS sensors (lgs.wfs.model = \"diffractive\", "
                                       "lgs.count > 0): the geometric sensors have no spots and no reference",
                                       wt_config_priv_keys[keys[i]].path);
    /* the stage takes each LGS's focus and tip-tilt out of what it measures: the tomography must not need them */
    if (cfg->lgs_focus_stage && !cfg->lgs_focus_removal)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kf, ps->set[kf], loc, sizeof loc),
                                   "key 'lgs.wfs.focus_stage' = true needs 'recon.lgs_focus_removal' = true: the stage "
                                   "takes the LGS focus out of the slopes, so the focus must come from the NGS");
    if (cfg->lgs_focus_stage && !cfg->sodium_sequence[0])
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kf, ps->set[kf], loc, sizeof loc),
                                   "key 'lgs.wfs.focus_stage' = true needs 'lgs.sodium_sequence': the stage moves when "
                                   "the truth's spot tables are rebuilt from the sequence (lgs.sodium_sequence_update_s)");
    if (ps->set[kg] && !cfg->lgs_focus_stage)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kg, ps->set[kg], loc, sizeof loc),
                                   "key 'lgs.wfs.focus_stage_gain' is given but 'lgs.wfs.focus_stage' is not true: "
                                   "there is no stage to drive");
    if (ps->set[ku] && !cfg->sodium_sequence[0])
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, ku, ps->set[ku], loc, sizeof loc),
                                   "key 'lgs.sodium_sequence_update_s' is given without 'lgs.sodium_sequence': there is "
                                   "no sequence to follow");
    if (ps->set[kt] && cfg->lgs_reference == 0)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kt, ps->set[kt], loc, sizeof loc),
                                   "key 'lgs.wfs.reference_update_s' is given but 'lgs.wfs.reference' is \"static\" "
                                   "(%s): a static reference is never rebuilt",
                                   ps->set[kr] ? wt_config_priv_where(ps, kr, ps->set[kr], oth, sizeof oth) : "its default");
    if (cfg->lgs_gain_update > 0.0 && cfg->lgs_wfs.centroider != 2) /* WT_CENTROID_MF */
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kn, ps->set[kn], loc, sizeof loc),
                                   "key 'lgs.wfs.gain_update_s' measures the matched filter's gain: it needs "
                                   "'lgs.wfs.centroider' = \"mf\"");
    /* the gain's fit models the spots with the reference's profile, which the spot tables hold: the set-up's, or under
     * a sequence the truth's current one, which only the oracle's reference knows */
    if (cfg->lgs_gain_update > 0.0 && cfg->sodium_sequence[0] && cfg->lgs_reference != 1)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kn, ps->set[kn], loc, sizeof loc),
                                   "key 'lgs.wfs.gain_update_s' fits the loop's spots with the reference's sodium "
                                   "profile, and with 'lgs.sodium_sequence' only lgs.wfs.reference = \"oracle\" has "
                                   "the profile the spots are made of (a %s reference's is not): use the oracle or "
                                   "set lgs.wfs.gain_update_s = 0",
                                   cfg->lgs_reference == 2 ? "pixels" : "static");
    /* a cadence is counted in frames: one shorter than a frame would be a rebuild per frame under another name */
    const double frame_night = cfg->night.compression / cfg->rate;
    if (cfg->lgs_gain_update > 0.0 && lround(cfg->lgs_gain_update / frame_night) < 2)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kn, ps->set[kn], loc, sizeof loc),
                                   "key 'lgs.wfs.gain_update_s' = %g s of night is %ld frame(s) of %g s (1 / "
                                   "loop.rate_hz x atmosphere.night.compression): the matched filter's gain is measured "
                                   "on the mean image of one period's frames and needs at least 2; give at least %g s",
                                   cfg->lgs_gain_update, lround(cfg->lgs_gain_update / frame_night), frame_night,
                                   2.0 * frame_night);
    const struct { int k; double v; int on; } cad[2] = {{ku, cfg->sodium_sequence_update, cfg->sodium_sequence_update > 0.0},
                                                        {kt, cfg->lgs_reference_update, cfg->lgs_reference != 0}};
    for (int i = 0; i < 2; i++)
        if (cad[i].on && cad[i].v < frame_night * (1.0 - 1e-9))
            return wt_config_priv_fail(ps, wt_config_priv_where(ps, cad[i].k, ps->set[cad[i].k], loc, sizeof loc),
                                       "key '%s' = %g s of night is shorter than one frame's night time, 1 / "
                                       "loop.rate_hz x atmosphere.night.compression = %g s: give at least that%s",
                                       wt_config_priv_keys[cad[i].k].path, cad[i].v, frame_night,
                                       i == 0 ? " (or 0: every frame)" : "");
    /* pixels: the mean of the frames of one period (WT_SENSING_PIXELS_MIN_FRAMES of core/model/sensing.h, 2) */
    if (cfg->lgs_reference == 2 && lround(cfg->lgs_reference_update / frame_night) < 2)
        return wt_config_priv_fail(ps, wt_config_priv_where(ps, kt, ps->set[kt], loc, sizeof loc),
                                   "key 'lgs.wfs.reference_update_s' = %g s of night is %ld frame(s) of %g s (1 / "
                                   "loop.rate_hz x atmosphere.night.compression): the reference from the loop's pixels "
                                   "(lgs.wfs.reference = \"pixels\") is the mean image of one period's frames and needs "
                                   "at least 2; give at least %g s",
                                   cfg->lgs_reference_update, lround(cfg->lgs_reference_update / frame_night),
                                   frame_night, 2.0 * frame_night);
    return WT_OK;
}

int wt_config_priv_predicting(const wt_config_priv_state *ps)
{
    const int kp = wt_config_priv_find_key("recon.predict");
    return kp >= 0 && ps->set[kp] && config_setting_get_bool(ps->set[kp]);
}

int wt_config_priv_model_affects_matrix(const wt_config_priv_state *ps, const char *path)
{
    /* the night changes the truth only: the reconstructors' matrices never see it (SPEC §12) */
    if (!strncmp(path, "atmosphere.night.", 17)) return 0;
    /* the model's numbers make the matrix, not how they were specified; only recon.predict reads the wind: with it the
     * model's wind (the truth's under the oracle) and its error are in the identity of a predictive MVM, without it
     * they are not; nor are the learning's keys (the loop's matrices are rebuilt from each estimate) */
    const int predict = wt_config_priv_predicting(ps);
    const int ks = wt_config_priv_find_key("recon.atmosphere.source");
    const char *src = ps->set[ks] ? config_setting_get_string(ps->set[ks]) : NULL;
    const int oracle = !src || !strcmp(src, "oracle");
    if (!strncmp(path, "recon.atmosphere.wind_", 22) || !strncmp(path, "recon.atmosphere.error_wind_", 28))
        return predict;
    if (!strncmp(path, "atmosphere.wind_", 16)) return predict && oracle;
    if (!strcmp(path, "recon.atmosphere.source") ||
        !strcmp(path, "recon.atmosphere.update_s") || !strcmp(path, "recon.atmosphere.mvm_latency_s") ||
        !strcmp(path, "recon.atmosphere.learn_window") || !strcmp(path, "recon.atmosphere.learn_memory") ||
        !strcmp(path, "recon.atmosphere.learn_grid") ||
        !strcmp(path, "recon.atmosphere.learn_wind") ||
        !strcmp(path, "recon.atmosphere.profile") || !strcmp(path, "atmosphere.profile"))
        return 0;
    if (!strncmp(path, "recon.atmosphere.", 17)) return 1;
    if (strncmp(path, "atmosphere.", 11)) return -1;
    /* the truth's r0, L0 and profile make the matrix only as the oracle's model */
    return oracle;
}
