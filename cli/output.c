/* cli/output.c: provenance and layout groups written into every output file, so that a file read
 * years later says what made it and how its vectors are ordered. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "core/io/h5.h"
#include "core/model/profile.h"
#include "core/model/system.h"

int wt_cli_write_provenance(wt_cli *cli, struct wt_h5_writer *w, const wt_config *cfg, int argc, char **argv)
{
    (void)cli;
    int st;
    char cmd[4096] = "wavetomo ";
    size_t used = strlen(cmd); /* argv[0] is the subcommand */
    for (int i = 0; i < argc && used + 2 < sizeof cmd; i++) {
        int k = snprintf(cmd + used, sizeof cmd - used, "%s%s", i ? " " : "", argv[i]);
        if (k < 0) break;
        used += (size_t)k;
    }
    char when[64];
    time_t now = time(NULL);
    struct tm tmv;
    gmtime_r(&now, &tmv);
    strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    if ((st = wt_h5_attr_write_string(w, "/", "wavetomo_version", WT_VERSION)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "created_utc", when)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "command_line", cmd)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "config_path", cfg->path)) < 0) return st;
    if ((st = wt_h5_attr_write_int64(w, "/", "seed", (int64_t)cfg->seed)) < 0) return st;
    return wt_h5_write_string(w, "config", cfg->canonical,
                              "the effective configuration (libconfig text, after --set overrides) of this run");
}

/* One profile as four (n,) datasets under group g: altitude, Cn² fraction, wind speed and direction. */
static int write_profile(wt_h5_writer *w, const char *g, int n, const double *alt, const double *frac,
                         const double *vx, const double *vy, const char *what)
{
    double speed[WT_MAX_LAYERS], dir[WT_MAX_LAYERS];
    for (int l = 0; l < n; l++) {
        speed[l] = hypot(vx[l], vy[l]);
        dir[l] = fmod(atan2(vy[l], vx[l]) * 180.0 / M_PI + 360.0, 360.0);
    }
    const int64_t d[1] = {n};
    const char *name[4] = {"altitude_m", "cn2_fraction", "wind_speed_mps", "wind_direction_deg"};
    const double *v[4] = {alt, frac, speed, dir};
    const char *unit[4] = {"m", "", "m/s", "deg"};
    const char *desc[4] = {"altitude of each layer", "Cn2 fraction of each layer (sum 1)", "wind speed of each layer",
                           "direction each layer moves towards, from +x towards +y, in [0, 360)"};
    for (int q = 0; q < 4; q++) {
        char path[96], text[320];
        snprintf(path, sizeof path, "%s/%s", g, name[q]);
        snprintf(text, sizeof text, "%s: %s", what, desc[q]);
        const int st = wt_h5_write(w, path, WT_H5_F64, WT_H5_F64, 1, d, v[q], unit[q], text);
        if (st < 0) return st;
    }
    return WT_OK;
}

/* SPEC §12: the simulated atmosphere ("atmosphere/") and the reconstructors' ("model_atmosphere/": its source, r0
 * and L0, and per variant the profile compressed onto the variant's layers, the prior's fractions before their
 * floor), so that a file says what each side knew. */
static int write_atmospheres(wt_h5_writer *w, const wt_config *cfg)
{
    double vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS], f[WT_MAX_LAYERS], cx[WT_MAX_LAYERS], cy[WT_MAX_LAYERS];
    static const char *const src[] = {"oracle", "given", "learned"};
    int st;
    for (int l = 0; l < cfg->nlayers; l++) {
        vx[l] = cfg->wind_speed[l] * cos(cfg->wind_direction[l]);
        vy[l] = cfg->wind_speed[l] * sin(cfg->wind_direction[l]);
    }
    if ((st = write_profile(w, "atmosphere", cfg->nlayers, cfg->layer_altitude, cfg->layer_fraction, vx, vy,
                            "the simulation's truth")) < 0 ||
        (st = wt_h5_attr_write_double(w, "atmosphere", "r0_m", cfg->r0)) < 0 ||
        (st = wt_h5_attr_write_double(w, "atmosphere", "L0_m", cfg->L0)) < 0 ||
        (st = wt_h5_attr_write_string(w, "atmosphere", "profile", cfg->atm_profile)) < 0)
        return st;
    const wt_model_atmosphere_config *m = &cfg->model;
    for (int l = 0; l < m->nlayers; l++) {
        vx[l] = m->wind_speed[l] * cos(m->wind_direction[l]);
        vy[l] = m->wind_speed[l] * sin(m->wind_direction[l]);
    }
    for (int k = 0; k < 2; k++) {
        const wt_recon_variant_config *v = k ? &cfg->cg9 : &cfg->pcg3;
        char g[64];
        snprintf(g, sizeof g, "model_atmosphere/%s", k ? "cg9" : "pcg3");
        wt_profile_compress(m->nlayers, m->altitude, m->fraction, vx, vy, v->nlayers, v->altitudes, f, cx, cy);
        if ((st = write_profile(w, g, v->nlayers, v->altitudes, f, cx, cy,
                                "the reconstructor's atmosphere compressed onto the variant's layers (SPEC §12)")) < 0)
            return st;
    }
    if ((st = wt_h5_attr_write_string(w, "model_atmosphere", "source", src[m->source])) < 0 ||
        (st = wt_h5_attr_write_double(w, "model_atmosphere", "r0_m", m->r0)) < 0 ||
        (st = wt_h5_attr_write_double(w, "model_atmosphere", "L0_m", m->L0)) < 0 ||
        (st = wt_h5_attr_write_string(w, "model_atmosphere", "profile", m->profile)) < 0)
        return st;
    return WT_OK;
}

int wt_cli_write_layout(struct wt_h5_writer *w, const struct wt_system *sys)
{
    int st;
    wt_context *ctx = sys->ctx;
    int64_t ns = sys->nsensors;
    int64_t *off = calloc((size_t)ns, sizeof *off), *cnt = calloc((size_t)ns, sizeof *cnt);
    int32_t *act = calloc((size_t)sys->nact * 3, sizeof *act);
    double *axy = calloc((size_t)sys->nact * 2, sizeof *axy);
    char names[1024] = "";
    if (!off || !cnt || !act || !axy) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory writing the layout");
        goto out;
    }
    for (int m = 0; m < ns; m++) {
        off[m] = sys->sensors[m].offset;
        cnt[m] = sys->sensors[m].nslopes;
        strncat(names, sys->sensors[m].name, sizeof names - strlen(names) - 2);
        if (m + 1 < ns) strcat(names, ",");
    }
    int64_t q = 0;
    for (int k = 0; k < sys->dm->ndms; k++) {
        const wt_grid *g = &sys->dm->grid[k];
        for (int iy = 0; iy < g->ny; iy++)
            for (int ix = 0; ix < g->nx; ix++) {
                if (!sys->dm->active[k][ix + (int64_t)g->nx * iy]) continue;
                act[3 * q] = k;
                act[3 * q + 1] = ix;
                act[3 * q + 2] = iy;
                axy[2 * q] = g->x0 + ix * g->dx;
                axy[2 * q + 1] = g->y0 + iy * g->dx;
                q++;
            }
    }
    int64_t d1[1] = {ns}, d2[2] = {sys->nact, 3}, d3[2] = {sys->nact, 2};
    if ((st = wt_h5_write(w, "layout/sensor_slope_offset", WT_H5_I64, WT_H5_I64, 1, d1, off, "",
                          "first slope of each sensor in a slope vector (sensors in the order of the attribute "
                          "'sensors'); each sensor's block is [s_x of its valid subapertures..., s_y...]")) < 0)
        goto out;
    if ((st = wt_h5_write(w, "layout/sensor_slope_count", WT_H5_I64, WT_H5_I64, 1, d1, cnt, "",
                          "slopes of each sensor (2 x valid subapertures)")) < 0)
        goto out;
    if ((st = wt_h5_attr_write_string(w, "layout", "sensors", names)) < 0) goto out;
    if ((st = wt_h5_write(w, "layout/actuator_index", WT_H5_I32, WT_H5_I32, 2, d2, act, "",
                          "for each command: DM number (0-based), actuator column ix and row iy on that DM's grid")) < 0)
        goto out;
    if ((st = wt_h5_write(w, "layout/actuator_position", WT_H5_F64, WT_H5_F64, 2, d3, axy, "m",
                          "for each command: actuator position (x, y) in the DM's conjugate plane")) < 0)
        goto out;
    for (int m = 0; m < ns; m++) {
        const wt_sensor *s = &sys->sensors[m];
        double *c = malloc((size_t)s->nsub * 2 * sizeof *c);
        if (!c) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory writing the layout");
            goto out;
        }
        for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &c[2 * k], &c[2 * k + 1]);
        char name[64];
        snprintf(name, sizeof name, "layout/%s/subaperture_centre", s->name);
        int64_t d[2] = {s->nsub, 2};
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d, c, "m",
                         "centre (x, y) in the pupil of each valid subaperture, in slope order");
        free(c);
        if (st < 0) goto out;
        snprintf(name, sizeof name, "layout/%s", s->name);
        if ((st = wt_h5_attr_write_double(w, name, "theta_x_arcsec", s->theta_x / WT_ARCSEC)) < 0) goto out;
        if ((st = wt_h5_attr_write_double(w, name, "theta_y_arcsec", s->theta_y / WT_ARCSEC)) < 0) goto out;
        if ((st = wt_h5_attr_write_double(w, name, "source_altitude_m", s->altitude)) < 0) goto out;
        /* noise_sigma_mas: σ of the config (NEA or photon model) of a fully lit subaperture, per axis, for the
         * unelongated spot; noise_rms_mas: the rms of the simulated noise over all slopes, with the
         * elongation (τ = 1) and the lit-fraction factors (SPEC §4) */
        if ((st = wt_h5_attr_write_double(w, name, "noise_sigma_mas", sqrt(s->sigma2) / WT_ARCSEC * 1e3)) < 0)
            goto out;
        double v = 0.0;
        for (int k = 0; k < s->nsub; k++) {
            double b2 = s->beta ? s->beta[k] * s->beta[k] + s->beta[s->nsub + k] * s->beta[s->nsub + k] : 0.0;
            v += (s->noise_scale ? s->noise_scale[k] : 1.0) * (1.0 + 0.5 * b2 / (s->spot_fwhm * s->spot_fwhm));
        }
        if ((st = wt_h5_attr_write_double(w, name, "noise_rms_mas", sqrt(s->sigma2 * v / s->nsub) / WT_ARCSEC * 1e3)) < 0)
            goto out;
    }
    st = write_atmospheres(w, sys->cfg);
out:
    free(off);
    free(cnt);
    free(act);
    free(axy);
    return st;
}

int wt_cli_ensure_dir(wt_context *ctx, const char *path)
{
    char buf[2048];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1;; p++) {
        int end = *p == '\0';
        if (*p == '/' || end) {
            char c = *p;
            *p = '\0';
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return WT_ERROR(ctx, WT_ERR_IO, "cannot create the output directory '%s': %s", buf, strerror(errno));
            *p = c;
        }
        if (end) break;
    }
    struct stat sb;
    if (stat(path, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return WT_ERROR(ctx, WT_ERR_IO, "'%s' is not a directory", path);
    return WT_OK;
}

int wt_cli_telemetry_config(wt_cli *cli, struct wt_h5_reader *tr, const char *tel, wt_config **tcfg, wt_config **cfg)
{
    *tcfg = NULL, *cfg = NULL;
    if (!wt_h5_exists(tr, "config"))
        return WT_ERROR(cli->ctx, WT_ERR_FORMAT, "%s holds no dataset 'config' (the system it was recorded on): not a "
                        "telemetry file of `wavetomo sim --telemetry`", tel);
    char *text = NULL, name[1100];
    int st = wt_h5_read_string(tr, "config", &text);
    if (st < 0) return st;
    snprintf(name, sizeof name, "%s:config", tel);
    /* without --config the stored configuration is the one in use: the --set overrides apply to it (a key that
     * changes the matrices then refuses a --matrix built without it, as for --config) */
    const int nov = cli->config_path ? 0 : cli->nset;
    st = wt_config_parse(cli->ctx, text, name, nov, nov ? cli->set : NULL, tcfg);
    wt_free(cli->ctx, text);
    if (st >= 0 && cli->config_path) st = wt_cli_read_config(cli, NULL, cfg);
    return st;
}
