/* builder/cmd_learn_wind.c: the wind of `wavetomo learn` (SPEC §12 "Wind", core/model/learn.h): per altitude of the
 * identification grid, compressed onto the reconstructors' layers and onto the truth's layers (a reconstruction
 * layer's wind = the Cn²-weighted mean of the vectors it absorbs, core/model/profile.h), the truth beside. */
#include "builder/cmd_learn_wind.h"

#include <math.h>
#include <stdio.h>

#include "cli/plot.h"
#include "core/model/profile.h"

#define DEG (180.0 / M_PI)

/* the truth's wind vectors per layer */
static void truth_vectors(const wt_config *t, double *vx, double *vy)
{
    for (int k = 0; k < t->nlayers; k++)
        vx[k] = t->wind_speed[k] * cos(t->wind_direction[k]), vy[k] = t->wind_speed[k] * sin(t->wind_direction[k]);
}

static double dir_of(double vx, double vy) { return fmod(atan2(vy, vx) + 2 * M_PI, 2 * M_PI); }

/* estimate (and its spread) against the truth on nl layers at ralt */
static void print_layers(const char *title, const wt_learn_wind *wd, const wt_config *t, int nl, const double *ralt)
{
    double f[WT_MAX_LAYERS], vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS], sx[WT_MAX_LAYERS], sy[WT_MAX_LAYERS];
    double tvx[WT_MAX_LAYERS], tvy[WT_MAX_LAYERS], tf[WT_MAX_LAYERS], rvx[WT_MAX_LAYERS], rvy[WT_MAX_LAYERS];
    wt_learn_wind_compress(wd, nl, ralt, f, vx, vy, sx, sy);
    truth_vectors(t, tvx, tvy);
    wt_profile_compress(t->nlayers, t->layer_altitude, t->layer_fraction, tvx, tvy, nl, ralt, tf, rvx, rvy);
    printf("  %s\n    altitude [km]  Cn2 est/truth   wind estimate [m/s, deg]             truth [m/s, deg]   error "
           "[m/s, deg]\n", title);
    for (int l = 0; l < nl; l++) {
        const double s = hypot(vx[l], vy[l]), ts = hypot(rvx[l], rvy[l]);
        const double dd = fmod(dir_of(vx[l], vy[l]) - dir_of(rvx[l], rvy[l]) + 3 * M_PI, 2 * M_PI) - M_PI;
        printf("    %8.2f       %.3f / %.3f   %6.2f towards %6.1f (±%.2f, ±%.2f)   %6.2f towards %6.1f   %5.2f %6.1f\n",
               ralt[l] / 1e3, f[l], tf[l], s, dir_of(vx[l], vy[l]) * DEG, sx[l], sy[l], ts, dir_of(rvx[l], rvy[l]) * DEG,
               hypot(vx[l] - rvx[l], vy[l] - rvy[l]), dd * DEG);
    }
}

void wt_learn_wind_print(const wt_learn_wind *wd, const wt_config *use, const wt_config *tcfg, double fit_s)
{
    printf("  wind: lags");
    for (int q = 0; q < wd->nlag; q++) printf(" %d", wd->lag[q]);
    printf(" frames of %.3g ms, relative misfit %.3f, %d iterations, %d layer(s) dropped (past 60 m/s), %d split off (a peak's strong bins with their own wind), fit %.2f s\n",
           1e3 * wd->dt, wd->residual, wd->iterations, wd->dropped, wd->split, fit_s);
    /* the truth binned onto the grid the same way (each truth layer split between its two nearest altitudes) */
    double tvx[WT_MAX_LAYERS], tvy[WT_MAX_LAYERS], gf[WT_LEARN_MAX_ALT], gvx[WT_LEARN_MAX_ALT], gvy[WT_LEARN_MAX_ALT];
    truth_vectors(tcfg, tvx, tvy);
    wt_profile_compress(tcfg->nlayers, tcfg->layer_altitude, tcfg->layer_fraction, tvx, tvy, wd->nalt, wd->altitude, gf,
                        gvx, gvy);
    printf("    altitude [km]  Cn2      speed [m/s]      direction [deg]   (vx, vy) [m/s]     amplitude   truth binned "
           "[m/s, deg]\n");
    for (int a = 0; a < wd->nalt; a++)
        if (wd->fitted[a])
            printf("    %8.2f       %.3f   %6.2f ± %.2f    %6.1f ± %.1f     (%6.2f, %6.2f)   %.3f      %.3f: %6.2f towards "
                   "%6.1f\n", wd->altitude[a] / 1e3, wd->fraction[a], wd->speed[a], wd->speed_sigma[a],
                   wd->direction[a] * DEG, wd->direction_sigma[a] * DEG, wd->vx[a], wd->vy[a], wd->amplitude[a], gf[a],
                   hypot(gvx[a], gvy[a]), dir_of(gvx[a], gvy[a]) * DEG);
    print_layers("wind on pcg3's layers (Cn2-weighted over the fitted altitudes)", wd, tcfg, use->pcg3.nlayers,
                 use->pcg3.altitudes);
    print_layers("wind on cg9's layers", wd, tcfg, use->cg9.nlayers, use->cg9.altitudes);
    print_layers("wind on the truth's layers", wd, tcfg, tcfg->nlayers, tcfg->layer_altitude);
}

static int vec(wt_h5_writer *w, const char *grp, const char *name, int n, const double *v, const char *units,
               const char *desc, const char *what)
{
    char path[256], d[512];
    int64_t d1[1] = {n};
    snprintf(path, sizeof path, "%s/%s", grp, name);
    snprintf(d, sizeof d, "%s %s", desc, what);
    return wt_h5_write(w, path, WT_H5_F64, WT_H5_F64, 1, d1, v, units, d);
}

/* the estimate's wind (with sigma) or the truth's (sigma NULL) on nl layers at ralt, into group grp */
static int write_layers(wt_h5_writer *w, const char *grp, const wt_learn_wind *wd, const wt_config *t, int nl,
                        const double *ralt, const char *what)
{
    double f[64], vx[64], vy[64], sx[64], sy[64], s[64], dr[64], tvx[64], tvy[64];
    if (wd)
        wt_learn_wind_compress(wd, nl, ralt, f, vx, vy, sx, sy);
    else {
        truth_vectors(t, tvx, tvy);
        wt_profile_compress(t->nlayers, t->layer_altitude, t->layer_fraction, tvx, tvy, nl, ralt, f, vx, vy);
    }
    for (int l = 0; l < nl; l++) s[l] = hypot(vx[l], vy[l]), dr[l] = dir_of(vx[l], vy[l]);
    int st;
    if ((st = vec(w, grp, "wind_vx_mps", nl, vx, "m/s", "x component of the wind (Cn2-weighted mean of the vectors "
                  "absorbed) of", what)) < 0 ||
        (st = vec(w, grp, "wind_vy_mps", nl, vy, "m/s", "y component of the wind of", what)) < 0 ||
        (st = vec(w, grp, "wind_speed_mps", nl, s, "m/s", "wind speed of", what)) < 0 ||
        (st = vec(w, grp, "wind_direction_rad", nl, dr, "rad", "wind direction (of motion, counter-clockwise from +x, "
                  "[0, 2pi)) of", what)) < 0)
        return st;
    if (!wd) return WT_OK;
    if ((st = vec(w, grp, "wind_vx_sigma_mps", nl, sx, "m/s", "uncertainty of wind_vx (spread of the batches / "
                  "sqrt(batches)) of", what)) < 0 ||
        (st = vec(w, grp, "wind_vy_sigma_mps", nl, sy, "m/s", "uncertainty of wind_vy of", what)) < 0)
        return st;
    return WT_OK;
}

int wt_learn_wind_write(wt_h5_writer *w, const wt_learn_wind *wd, const wt_config *use, const wt_config *tcfg)
{
    const int na = wd->nalt;
    double fit[WT_LEARN_MAX_ALT], lag[WT_LEARN_MAX_LAG];
    for (int a = 0; a < na; a++) fit[a] = wd->fitted[a];
    for (int q = 0; q < wd->nlag; q++) lag[q] = wd->lag[q];
    const char *g = "estimate/wind", *at = "each altitude of the identification grid (0 where not fitted)";
    int st;
    int64_t dl[1] = {wd->nlag};
    if ((st = vec(w, g, "altitude_m", na, wd->altitude, "m", "the altitudes of", "the identification grid")) < 0 ||
        (st = vec(w, g, "fitted", na, fit, "", "1 where the altitude holds >= 5 % of the Cn2 and its wind was fitted, "
                  "0 elsewhere:", "the flags of the grid")) < 0 ||
        (st = vec(w, g, "vx_mps", na, wd->vx, "m/s", "x component of the wind at", at)) < 0 ||
        (st = vec(w, g, "vy_mps", na, wd->vy, "m/s", "y component of the wind at", at)) < 0 ||
        (st = vec(w, g, "speed_mps", na, wd->speed, "m/s", "wind speed at", at)) < 0 ||
        (st = vec(w, g, "direction_rad", na, wd->direction, "rad", "wind direction (of motion, counter-clockwise from "
                  "+x, [0, 2pi)) at", at)) < 0 ||
        (st = vec(w, g, "vx_sigma_mps", na, wd->vx_sigma, "m/s", "uncertainty (spread of the batches / sqrt(batches)) "
                  "of vx at", at)) < 0 ||
        (st = vec(w, g, "vy_sigma_mps", na, wd->vy_sigma, "m/s", "uncertainty of vy at", at)) < 0 ||
        (st = vec(w, g, "speed_sigma_mps", na, wd->speed_sigma, "m/s", "uncertainty of the speed at", at)) < 0 ||
        (st = vec(w, g, "direction_sigma_rad", na, wd->direction_sigma, "rad", "uncertainty of the direction at", at)) < 0 ||
        (st = wt_h5_write(w, "estimate/wind/lags_frames", WT_H5_F64, WT_H5_F64, 1, dl, lag, "frames",
                          "the lags of the time-lagged cross-covariance maps fitted")) < 0 ||
        (st = vec(w, g, "amplitude", na, wd->amplitude, "", "the layer's Cn2 in the lagged maps over the profile "
                  "fit's (1: the same) at", at)) < 0 ||
        (st = wt_h5_write_double(w, "estimate/wind/frame_time_s", wd->dt, "s", "frame time (1 / loop.rate_hz of the "
                                 "telemetry)")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/wind/residual", wd->residual, "", "weighted rms misfit of the wind fit "
                                 "over the weighted rms of the lagged maps")) < 0 ||
        (st = wt_h5_write_int64(w, "estimate/wind/layers_dropped", wd->dropped, "", "layers left out of the fit: "
                                "their wind ran past 60 m/s (their altitudes not fitted)")) < 0 ||
        (st = wt_h5_write_int64(w, "estimate/wind/layers_split", wd->split, "", "layers added by giving each bin of "
                                "a peak that holds >= 2 % of the Cn2 its own wind (sub-resolution layers parted by "
                                "their motion)")) < 0)
        return st;
    if ((st = write_layers(w, "estimate/pcg3", wd, tcfg, use->pcg3.nlayers, use->pcg3.altitudes,
                           "pcg3's layers (the estimate)")) < 0 ||
        (st = write_layers(w, "estimate/cg9", wd, tcfg, use->cg9.nlayers, use->cg9.altitudes,
                           "cg9's layers (the estimate)")) < 0 ||
        (st = write_layers(w, "estimate/truth_layers", wd, tcfg, tcfg->nlayers, tcfg->layer_altitude,
                           "the truth's layer altitudes (the estimate compressed onto them)")) < 0 ||
        (st = write_layers(w, "truth/pcg3", NULL, tcfg, use->pcg3.nlayers, use->pcg3.altitudes,
                           "pcg3's layers (the truth compressed)")) < 0 ||
        (st = write_layers(w, "truth/cg9", NULL, tcfg, use->cg9.nlayers, use->cg9.altitudes,
                           "cg9's layers (the truth compressed)")) < 0 ||
        (st = write_layers(w, "truth/layers", NULL, tcfg, tcfg->nlayers, tcfg->layer_altitude,
                           "the truth's layers")) < 0)
        return st;
    return WT_OK;
}

int wt_learn_wind_plot(wt_context *ctx, const char *path, const wt_learn_wind *wd, const wt_config *t)
{
    const int nl = t->nlayers;
    double f[WT_MAX_LAYERS], vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS], tvx[WT_MAX_LAYERS], tvy[WT_MAX_LAYERS];
    double v[3 * WT_MAX_LAYERS];
    char labels[WT_MAX_LAYERS][48], title[200];
    const char *groups[WT_MAX_LAYERS], *series[3] = {"estimate", "truth", "error"};
    wt_learn_wind_compress(wd, nl, t->layer_altitude, f, vx, vy, NULL, NULL);
    truth_vectors(t, tvx, tvy);
    int met = 0, due = 0;
    for (int l = 0; l < nl; l++) {
        const double err = hypot(vx[l] - tvx[l], vy[l] - tvy[l]);
        const double dd = fmod(dir_of(vx[l], vy[l]) - dir_of(tvx[l], tvy[l]) + 3 * M_PI, 2 * M_PI) - M_PI;
        /* the label: altitude, the truth's Cn² share, the direction error */
        snprintf(labels[l], sizeof labels[l], "%.2g km %+.0f deg", t->layer_altitude[l] / 1e3, dd * DEG);
        groups[l] = labels[l];
        v[3 * l] = hypot(vx[l], vy[l]), v[3 * l + 1] = t->wind_speed[l], v[3 * l + 2] = err;
        if (t->layer_fraction[l] >= WT_LEARN_WIND_MIN_FRACTION) due++, met += err <= 1.0 && fabs(dd) * DEG <= 10.0;
    }
    snprintf(title, sizeof title, "wind: %d/%d layers (>= 5%% Cn2) within 1 m/s, 10 deg", met, due);
    return wt_plot_grouped_bars(ctx, path, title, "m/s", nl, groups, 3, series, v, NULL);
}
