/* compare/report_spots.c: the spot mosaic, the gain/truncation maps and spots.md of one diffractive sensor; see
 * spots.h. */
#include "compare/report_spots.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli/plot.h"
#include "core/model/sensing.h"
#include "core/model/system.h"
#include "core/optics/centroid.h"

static const char *const centroider_name[] = {"centre of gravity (cog)", "thresholded centre of gravity (tcog)",
                                              "matched filter (mf)"};

static const wt_sensor_config *wfs_config(const wt_system *sys, const wt_sensor *s)
{
    return s->kind == WT_SENSOR_LGS ? &sys->cfg->lgs_wfs : &sys->cfg->ngs_wfs;
}

int wt_spots_pick(wt_context *ctx, const wt_system *sys, const char *name, int *index)
{
    char have[256] = "";
    int first = -1, first_lgs = -1;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        if (!s->diffr) continue;
        if (first < 0) first = m;
        if (first_lgs < 0 && s->kind == WT_SENSOR_LGS) first_lgs = m;
        snprintf(have + strlen(have), sizeof have - strlen(have), "%s%s", *have ? ", " : "", s->name);
        if (name && !strcasecmp(name, s->name)) {
            *index = m;
            return WT_OK;
        }
    }
    if (first < 0)
        return WT_ERROR(ctx, WT_ERR_CONFIG,
                        "%s: --spots draws the spot images of a diffractive sensor, and every sensor of this system is "
                        "geometric (lgs.wfs.model and ngs.wfs.model = \"geometric\"); set lgs.wfs.model = "
                        "\"diffractive\" (--set, or a preset such as data/presets/demo-diffractive.cfg)",
                        sys->source);
    if (name)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: --sensor %s: no such diffractive sensor; the diffractive sensors are %s",
                        sys->source, name, have);
    *index = first_lgs >= 0 ? first_lgs : first;
    return WT_OK;
}

static void file_names(const wt_system *sys, int index, const char *dir, char *spots, char *gain, char *md, size_t n)
{
    const char *nm = sys->sensors[index].name;
    snprintf(spots, n, "%s/spots_%s.png", dir, nm);
    snprintf(gain, n, "%s/gain_%s.png", dir, nm);
    snprintf(md, n, "%s/spots.md", dir);
}

/* dir/spots.md starts with our signature */
static int md_is_ours(const char *md)
{
    char head[64] = "";
    FILE *f = fopen(md, "rb");
    if (!f) return 0;
    size_t len = strlen(WT_SPOTS_SIGNATURE), got = fread(head, 1, len, f);
    fclose(f);
    return got == len && !memcmp(head, WT_SPOTS_SIGNATURE, len);
}

int wt_spots_check_outputs(wt_cli *cli, const wt_system *sys, int index, const char *dir, const char *owner)
{
    char png[2][2300], md[2300];
    file_names(sys, index, dir, png[0], png[1], md, sizeof md);
    int st = wt_cli_check_text_output(cli, md, WT_SPOTS_SIGNATURE, NULL);
    for (int i = 0; i < 2 && st >= 0; i++) {
        struct stat sb;
        if (!owner && !cli->force && lstat(png[i], &sb) == 0 && !md_is_ours(md))
            return WT_ERROR(cli->ctx, WT_ERR_IO, "'%s' exists and is not a wavetomo output (no wavetomo spots.md beside "
                            "it); refusing to replace it: choose another directory, or give --force", png[i]);
        st = wt_cli_check_text_output(cli, png[i], "\x89PNG", owner);
    }
    return st;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* min, median, max of v[0..n) (NaN skipped) */
static void range3(const double *v, int n, double *work, double out[3])
{
    int k = 0;
    for (int i = 0; i < n; i++)
        if (!isnan(v[i])) work[k++] = v[i];
    if (!k) {
        out[0] = out[1] = out[2] = NAN;
        return;
    }
    qsort(work, (size_t)k, sizeof *work, cmp_double);
    out[0] = work[0], out[2] = work[k - 1];
    out[1] = k % 2 ? work[k / 2] : 0.5 * (work[k / 2 - 1] + work[k / 2]);
}

static int write_md(wt_cli *cli, const wt_system *sys, int index, const char *md, const char *command,
                    const char *gain_what, const double g3[3], const double gcfg3[3], const int *levels,
                    const wt_spots_when *when, const double off3[3])
{
    const wt_sensor *s = &sys->sensors[index];
    const wt_sensing *ws = s->diffr;
    const wt_sensor_config *w = wfs_config(sys, s);
    const wt_config *cfg = sys->cfg;
    char tmp[2400];
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", md, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': %s", tmp, strerror(errno));
    const int lgs = s->kind == WT_SENSOR_LGS;
    fprintf(f, "%s: %s\n\n", WT_SPOTS_SIGNATURE, s->name);
    fprintf(f, "System `%s` (config hash `%.16s`). Sensor %s (%s, direction %.1f, %.1f arcsec): %d x %d subapertures of "
               "%g m, %d valid; %d x %d pixels of %g arcsec (field %.1f arcsec) at %.0f nm; %g photons per subaperture "
               "and frame, read noise %g e-, background %g e- per pixel; centroider: %s%s.",
            cfg->path, cfg->matrix_sha256, s->name, lgs ? "laser guide star" : "natural guide star",
            s->theta_x / WT_ARCSEC, s->theta_y / WT_ARCSEC, s->subapertures, s->subapertures, ws->side, ws->nsub, ws->ns,
            ws->ns, ws->pixel / WT_ARCSEC, ws->ns * ws->pixel / WT_ARCSEC, w->wavelength * 1e9, w->photons,
            w->read_noise_e, w->background_e, centroider_name[w->centroider],
            w->apply_gain ? ", gain applied" : ", gain not applied");
    if (lgs)
        fprintf(f, " Sodium layer at %.0f km (%s), uplink spot %g arcsec FWHM, launch at (%.2f, %.2f) m.",
                s->altitude / 1e3, cfg->sodium_profile[0] ? cfg->sodium_profile : "Gaussian of lgs.sodium_fwhm_m",
                cfg->uplink_fwhm / WT_ARCSEC, s->launch_x, s->launch_y);
    if (when)
        fprintf(f, "\n\n**At night time %.1f s of the truth's sodium sequence `%s`**: the spots are those the truth "
                   "renders then; the centroider is the set-up's, built on the reference of the set-up profile (a static "
                   "reference, lgs.wfs.reference = \"static\"), so its gain and the slope it reads on a spot that holds "
                   "still (its false signal) show what the sodium layer's change does to it.",
                when->night_s, when->sequence);
    fprintf(f, "\n\nMade by:\n\n```\n%s\n```\n\n", command);
    fprintf(f, "| number | value |\n|---|---|\n");
    fprintf(f, "| median NEA (sqrt of the mean of the 2x2 noise covariance's eigenvalues) | %.1f mas |\n",
            ws->nea_median / WT_ARCSEC * 1e3);
    if (!when)
        fprintf(f, "| worst truncation (flux outside the detector field, noise-free I0) | %.2f %% (subaperture %d at %.2f, "
                   "%.2f m) |\n", 100.0 * ws->worst_trunc, ws->worst_sub, ws->xc[ws->worst_sub], ws->yc[ws->worst_sub]);
    else
        fprintf(f, "| the static centroider's slope along the elongation on the still spots (false signal): min / median / "
                   "max | %.1f / %.1f / %.1f mas |\n", off3[0], off3[1], off3[2]);
    for (int l = 0; l < WT_PLOT_TRUNC_LEVELS; l++)
        fprintf(f, "| subapertures truncated by more than %g %% | %d of %d |\n", 100.0 * wt_plot_trunc_levels[l],
                levels[l], ws->nsub);
    fprintf(f, "| %s: min / median / max | %.3f / %.3f / %.3f |\n", gain_what, g3[0], g3[1], g3[2]);
    if (gcfg3)
        fprintf(f, "| the configured centroider's gain along the elongation: min / median / max | %.3f / %.3f / %.3f |\n",
                gcfg3[0], gcfg3[1], gcfg3[2]);
    fprintf(f, "\n![spot images of %s](spots_%s.png)\n\n", s->name, s->name);
    fprintf(f, "**spots_%s.png**: %s of every valid subaperture, its %d x %d pixels drawn in the subaperture's cell "
               "over the pupil (x right, y up, as the pupil; a pixel's x and y angles increase the same way). Linear "
               "grey scale of I / I_max, I_max the subaperture's own peak, so every spot is visible whatever its lit "
               "fraction. ",
            s->name,
            when ? "the noise-free mean image at that night time (the reference's seeing, the profile of that time)"
                 : "the noise-free mean image I0 (flat wavefront: what the centroider is calibrated on)",
            ws->ns, ws->ns);
    if (lgs)
        fprintf(f, "An LGS spot is elongated along the line from the launch (the blue star) to its subaperture, by about "
                   "the distance times the sodium layer's thickness over H^2: the farthest subapertures have the "
                   "longest spots. ");
    fprintf(f, "A coloured frame marks a subaperture whose spot loses more than 0.1 %% (yellow), 1 %% (orange) or 10 %% "
               "(red) of its flux outside the detector field.\n\n");
    fprintf(f, "![centroid gain of %s](gain_%s.png)\n\n", s->name, s->name);
    fprintf(f, "**gain_%s.png**, left: %s per subaperture [rad of slope per rad of tilt]: 1 = the centroid follows a "
               "tilt exactly; a truncated or elongated spot whose CoG loses flux at the field edge responds less (< 1). "
               "%s Right: %s.\n",
            s->name, gain_what,
            when ? "On its own reference the configured centroider's gain is 1 (with its gain applied); below 1 the "
                   "spots have changed under it (a longer or shifted spot than the reference's)."
            : w->centroider == WT_CENTROID_MF
                ? "The configured matched filter's gain is 1 by construction (it is built from I0's derivatives), so "
                  "the map shows what a plain CoG over the whole detector would give on the same images: where the "
                  "field truncates the spots."
                : w->apply_gain ? "The centroider applies the inverse of its calibrated 2x2 gain to every slope."
                                : "The gain is not applied (lgs/ngs.wfs.apply_gain = false): the slopes are this "
                                  "much too small.",
            when ? "the slope the static centroider reads on each still spot, along the elongation [mas]: the spots' "
                   "shift since the set-up, (r - l)(1/h - 1/h0) to first order, which every LGS reads as focus and "
                   "tip-tilt"
                 : "the truncation per subaperture [%]");
    if (fclose(f) != 0 || rename(tmp, md) != 0) {
        int e = errno;
        remove(tmp);
        return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': %s", md, strerror(e));
    }
    return WT_OK;
}

int wt_spots_write(wt_cli *cli, const wt_system *sys, int index, const char *dir, const char *command,
                   const wt_spots_when *when)
{
    wt_context *ctx = cli->ctx;
    const wt_sensor *s = &sys->sensors[index];
    const wt_sensing *ws = s->diffr;
    if (!ws) return WT_ERROR(ctx, WT_ERR_INVALID, "spots: sensor %s is not diffractive", s->name);
    const wt_sensor_config *w = wfs_config(sys, s);
    const int nsub = ws->nsub, lgs = s->kind == WT_SENSOR_LGS;
    char png_s[2300], png_g[2300], md[2300], cmd[2600], title[256], note[512];
    file_names(sys, index, dir, png_s, png_g, md, sizeof md);
    int st = wt_cli_ensure_dir(ctx, dir);
    if (st < 0) return st;
    double *gpar = NULL, *gcfg = NULL, *tpc = NULL, *work = NULL, *off = NULL, *trunc_now = NULL;
    float *img_now = NULL;
    WT_ALLOC(ctx, gpar, nsub, "gain map");
    WT_ALLOC(ctx, tpc, nsub, "truncation map");
    WT_ALLOC(ctx, work, nsub, "gain statistics");
    const int mf = w->centroider == WT_CENTROID_MF && !when;
    if (mf) WT_ALLOC(ctx, gcfg, nsub, "gain map");
    if (when) {
        /* the spots of the profile then, through the set-up's centroider: its gain and its false slope */
        WT_ALLOC(ctx, off, nsub, "false slopes");
        WT_ALLOC(ctx, trunc_now, nsub, "truncations");
        WT_ALLOC(ctx, img_now, (size_t)nsub * ws->ns * ws->ns, "spot images");
        WT_TRY(wt_sensing_response_now(ws, s->launch_x, s->launch_y, img_now, off, gpar, NULL, trunc_now));
        for (int k = 0; k < nsub; k++) off[k] *= 1e3 / WT_ARCSEC;
    } else {
        /* the MF's own gain is the identity: show the CoG's on the same images (and keep the MF's for the table) */
        WT_TRY(wt_sensing_gain_along(ws, mf, s->launch_x, s->launch_y, gpar, NULL));
        if (mf) WT_TRY(wt_sensing_gain_along(ws, 0, s->launch_x, s->launch_y, gcfg, NULL));
    }
    const double *trunc = when ? trunc_now : ws->trunc;
    const float *images = when ? img_now : ws->i0;
    int levels[WT_PLOT_TRUNC_LEVELS] = {0};
    for (int k = 0; k < nsub; k++) {
        tpc[k] = 100.0 * fmax(trunc[k], 0.0); /* a rounding below 0 is none */
        for (int l = 0; l < WT_PLOT_TRUNC_LEVELS; l++) levels[l] += trunc[k] > wt_plot_trunc_levels[l];
    }

    wt_plot_pupil pp = {.nsub = nsub, .xc = ws->xc, .yc = ws->yc, .side = ws->side, .diameter = sys->diameter,
                        .obstruction = sys->obstruction, .has_launch = lgs, .launch_x = s->launch_x,
                        .launch_y = s->launch_y};
    const char *base = strrchr(sys->cfg->path, '/');
    base = base ? base + 1 : sys->cfg->path;
    if (when)
        snprintf(title, sizeof title, "%s noise-free spot images at night time %.0f s (%dx%d pixels of %g\")", s->name,
                 when->night_s, ws->ns, ws->ns, ws->pixel / WT_ARCSEC);
    else
        snprintf(title, sizeof title, "%s noise-free spot images I0 (%dx%d pixels of %g\")", s->name, ws->ns, ws->ns,
                 ws->pixel / WT_ARCSEC);
    snprintf(note, sizeof note, "%.200s: %s, %g photons, median NEA %.0f mas", base,
             mf ? "matched filter" : w->centroider == WT_CENTROID_TCOG ? "tCoG" : "CoG", w->photons,
             ws->nea_median / WT_ARCSEC * 1e3);
    WT_TRY(wt_plot_spots(ctx, png_s, title, note, &pp, ws->ns, images, 1, trunc));

    const char *gain_what = when ? (lgs ? "the static centroider's gain along the elongation on these spots"
                                        : "the static centroider's smaller gain eigenvalue on these spots")
                            : mf ? (lgs ? "gain along the elongation of a CoG over the whole detector"
                                        : "smaller gain eigenvalue of a CoG over the whole detector")
                                 : (lgs ? "the centroider's gain along the elongation" : "the centroider's smaller gain eigenvalue");
    char sub0[256], bar0[128];
    double g3[3], gc3[3], t3[3], off3[3] = {0, 0, 0};
    if (when) range3(off, nsub, work, off3);
    range3(gpar, nsub, work, g3);
    range3(tpc, nsub, work, t3);
    if (mf) range3(gcfg, nsub, work, gc3);
    snprintf(sub0, sizeof sub0, "%s%s\nmin %.3f, median %.3f, max %.3f", mf ? "whole-detector CoG: " : when ? "static reference: " : "",
             lgs ? "gain along the elongation" : "smaller gain eigenvalue", g3[0], g3[1], g3[2]);
    snprintf(bar0, sizeof bar0, "%s gain [rad/rad]", mf ? "CoG" : "centroid");
    char sub1[128];
    snprintf(sub1, sizeof sub1, "truncation: flux outside the detector field\nmedian %.3f %%, max %.2f %%", t3[1], t3[2]);
    if (when)
        snprintf(sub1, sizeof sub1, "false slope along the elongation (a still spot)\nmin %.1f, median %.1f, max %.1f mas",
                 off3[0], off3[1], off3[2]);
    const double *maps[2] = {gpar, when ? off : tpc};
    const char *subs[2] = {sub0, sub1}, *bars[2] = {bar0, when ? "false slope [mas]" : "truncation [%]"};
    if (when)
        snprintf(title, sizeof title, "%s at %.0f s: the static reference's gain and false slope%s", s->name,
                 when->night_s, lgs ? "; ★ launch" : "");
    else
        snprintf(title, sizeof title, "%s: centroid gain and truncation per subaperture%s%s", s->name,
                 mf ? " (the configured matched filter's gain is 1)" : "", lgs ? "; ★ launch" : "");
    /* truncation from 0, to at least 0.1 % (the first frame level): a clean sensor reads as one colour */
    const double range[4] = {NAN, NAN, when ? NAN : 0.0, when ? NAN : fmax(t3[2], 100.0 * wt_plot_trunc_levels[0])};
    WT_TRY(wt_plot_pupil_maps(ctx, png_g, title, &pp, 2, maps, range, subs, bars));

    if (!command) {
        snprintf(cmd, sizeof cmd, "wavetomo info %s --spots %s", sys->cfg->path, dir);
        command = cmd;
    }
    WT_TRY(write_md(cli, sys, index, md, command, gain_what, g3, mf ? gc3 : NULL, levels, when, off3));
fail:
    wt_free(ctx, off);
    wt_free(ctx, trunc_now);
    wt_free(ctx, img_now);
    wt_free(ctx, gpar);
    wt_free(ctx, gcfg);
    wt_free(ctx, tpc);
    wt_free(ctx, work);
    return st;
}
