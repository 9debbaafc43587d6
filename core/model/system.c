/* core/model/system.c: geometry of the MCAO system from its configuration (SPEC §1, §4, §5, §8). */
#include "system.h"

#include <math.h>
#include <stdio.h>

#include "../op/noise.h"
#include "../op/pupil.h"
#include "sensing.h"

static int add_sensor(wt_system *sys, const wt_config *cfg, int kind, int index, double tx, double ty, int m)
{
    wt_context *ctx = sys->ctx;
    int st = WT_OK;
    wt_sensor *s = &sys->sensors[sys->nsensors];
    s->kind = kind;
    s->index = index;
    s->theta_x = tx;
    s->theta_y = ty;
    snprintf(s->name, sizeof s->name, "%s%d", kind == WT_SENSOR_LGS ? "LGS" : "NGS", index + 1);
    const wt_sensor_config *w = kind == WT_SENSOR_LGS ? &cfg->lgs_wfs : &cfg->ngs_wfs;
    s->spot_fwhm = w->spot_fwhm;
    s->tilt = kind == WT_SENSOR_LGS ? WT_SH_TILT_G : w->tilt;
    s->sigma2 = wt_noise_variance(w->photons, w->read_noise_e, w->spot_fwhm, w->pixel, w->pixels, w->nea);
    if (kind == WT_SENSOR_LGS) {
        s->altitude = cfg->lgs_altitude;
        s->subapertures = sys->n;
        double az = atan2(ty, tx);
        s->launch_x = cfg->launch_radius * cos(az);
        s->launch_y = cfg->launch_radius * sin(az);
        if (cfg->lit_sensor_model)
            WT_TRY(wt_shack_hartmann_alloc_lit(ctx, cfg->diameter, cfg->obstruction, sys->n, sys->d, sys->sense_q,
                                               sys->valid, 0, WT_SH_TILT_G, &s->sh));
        else WT_TRY(wt_shack_hartmann_alloc(ctx, sys->n, sys->d, sys->valid, &s->sh));
    } else {
        s->altitude = 0.0;
        s->subapertures = m;
        if (sys->n % m != 0)
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "%s: ngs.subapertures = %d does not divide lgs.wfs.subapertures = %d (the NGS sensor "
                            "averages the fine Fried cells)",
                            cfg->path, m, sys->n);
        if (cfg->lit_sensor_model)
            WT_TRY(wt_shack_hartmann_alloc_lit(ctx, cfg->diameter, cfg->obstruction, sys->n, sys->d, sys->sense_q,
                                               sys->valid, m, s->tilt, &s->sh));
        else if (s->tilt == WT_SH_TILT_Z)
            return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: ngs.wfs.tilt = \"z\" needs recon.sensor_model = \"lit\" (the Fried "
                            "model averages cell gradients: a G-tilt)", cfg->path);
        else WT_TRY(wt_shack_hartmann_alloc_averaged(ctx, sys->n, sys->d, sys->valid, m, &s->sh));
    }
    s->nsub = wt_shack_hartmann_nsub(s->sh);
    s->nslopes = wt_shack_hartmann_nslopes(s->sh);
    s->offset = sys->nslopes;
    sys->nslopes += s->nslopes;
    sys->nsensors++;
    if (w->model == WT_WFS_DIFFRACTIVE) {
        /* the diffractive sensor: spot + centroider on the valid subapertures of the model, in its order */
        double *cx = NULL, *cy = NULL;
        WT_ALLOC(ctx, cx, s->nsub, "subaperture centres");
        cy = wt_calloc(ctx, (size_t)s->nsub, sizeof *cy);
        if (!cy) {
            wt_free(ctx, cx);
            return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for subaperture centres");
        }
        for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &cx[k], &cy[k]);
        const wt_sensing_geometry g = {.lgs = kind == WT_SENSOR_LGS,
                                       .name = s->name,
                                       .source = cfg->path,
                                       .nsub = s->nsub,
                                       .xc = cx,
                                       .yc = cy,
                                       .side = cfg->diameter / s->subapertures,
                                       .diameter = cfg->diameter,
                                       .obstruction = cfg->obstruction,
                                       .altitude = s->altitude,
                                       .launch_x = s->launch_x,
                                       .launch_y = s->launch_y};
        st = wt_sensing_alloc(ctx, cfg, w, &g, &s->diffr);
        wt_free(ctx, cx);
        wt_free(ctx, cy);
        if (st < 0) return st;
        s->sigma2 = s->diffr->mean_var;
        return WT_OK;
    }
    if (w->lit_noise) {
        /* f relative to the sensor's best-lit subaperture: 1 for a fully lit LGS subaperture, and for the NGS
         * quadrants or the whole pupil (their photons are the star's, whatever the pupil's shape) */
        const double side = cfg->diameter / s->subapertures;
        double fmax = 0.0;
        WT_ALLOC(ctx, s->noise_scale, s->nsub, "noise variance factors");
        for (int k = 0; k < s->nsub; k++) {
            double x, y;
            wt_shack_hartmann_centre(s->sh, k, &x, &y);
            s->noise_scale[k] = wt_pupil_fraction(cfg->diameter, cfg->obstruction, x - 0.5 * side, y - 0.5 * side, side);
            if (s->noise_scale[k] > fmax) fmax = s->noise_scale[k];
        }
        for (int k = 0; k < s->nsub; k++)
            s->noise_scale[k] = wt_noise_lit_factor(w->photons, w->read_noise_e, w->spot_fwhm, w->pixel, w->pixels,
                                                    w->nea, s->noise_scale[k] / fmax);
    }
    if (kind == WT_SENSOR_LGS && cfg->sodium_fwhm > 0.0) {
        double *cx = NULL, *cy = NULL;
        WT_ALLOC(ctx, s->beta, 2 * s->nsub, "elongation vectors");
        WT_ALLOC(ctx, cx, s->nsub, "subaperture centres");
        cy = wt_calloc(ctx, (size_t)s->nsub, sizeof *cy);
        if (!cy) {
            wt_free(ctx, cx);
            return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for subaperture centres");
        }
        for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &cx[k], &cy[k]);
        wt_noise_elongation(s->nsub, cx, cy, s->launch_x, s->launch_y, cfg->sodium_fwhm, cfg->lgs_altitude, s->beta);
        wt_free(ctx, cx);
        wt_free(ctx, cy);
    }
    return WT_OK;
fail:
    return st;
}

_Static_assert(WT_DM_MAX == WT_MAX_DMS, "core/op/dm.h and core/config/config.h must agree on the DM count");

int wt_system_alloc(wt_context *ctx, const wt_config *cfg, wt_system **out)
{
    int st = WT_OK;
    wt_system *sys = NULL;
    *out = NULL;
    WT_ALLOC(ctx, sys, 1, "system");
    sys->ctx = ctx;
    sys->cfg = cfg;
    sys->source = cfg->path;
    sys->diameter = cfg->diameter;
    sys->obstruction = cfg->obstruction;

    /* Fine Shack–Hartmann sampling: the LGS sensor's; a config without LGS still needs a grid for the
     * NGS averaging, and uses lgs.wfs.subapertures for it. */
    sys->n = cfg->lgs_wfs.subapertures;
    sys->d = cfg->diameter / sys->n;
    WT_ALLOC(ctx, sys->valid, (size_t)sys->n * sys->n, "valid-subaperture mask");
    sys->nvalid = wt_pupil_valid_subapertures(cfg->diameter, cfg->obstruction, sys->n, cfg->lgs_wfs.valid_fraction,
                                              sys->valid);
    if (sys->nvalid <= 0) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: no valid subaperture (lgs.wfs.subapertures = %d, valid_fraction = %g)",
                      cfg->path, sys->n, cfg->lgs_wfs.valid_fraction);
        goto fail;
    }
    sys->corner_grid = wt_grid_centred(sys->n + 1, sys->d);
    WT_ALLOC(ctx, sys->corner_mask, (size_t)(sys->n + 1) * (sys->n + 1), "corner mask");
    wt_pupil_corner_mask(sys->n, sys->valid, sys->corner_mask);
    for (int64_t i = 0; i < wt_grid_size(&sys->corner_grid); i++) sys->ncorners += sys->corner_mask[i];
    /* the reconstructor's sensor model samples the layers on this grid (SPEC §4): the Fried corners, or
     * q points per subaperture side for the lit-area average model */
    sys->sense_q = cfg->lit_sensor_model ? cfg->sensor_points : 1;
    sys->sense_grid = wt_grid_centred(sys->n * sys->sense_q + 1, sys->d / sys->sense_q);

    for (int k = 0; k < cfg->nlgs; k++) {
        double az = cfg->lgs_azimuth0 + 2.0 * M_PI * k / cfg->nlgs;
        WT_TRY(add_sensor(sys, cfg, WT_SENSOR_LGS, k, cfg->lgs_radius * cos(az), cfg->lgs_radius * sin(az), 0));
        sys->nlgs++;
    }
    for (int k = 0; k < cfg->nngs; k++) {
        double az = cfg->ngs_azimuth[k];
        WT_TRY(add_sensor(sys, cfg, WT_SENSOR_NGS, k, cfg->ngs_radius * cos(az), cfg->ngs_radius * sin(az),
                          cfg->ngs_subapertures[k]));
        sys->nngs++;
    }

    /* DMs (core/op/dm.h: grids, active actuators with the guard rings) */
    {
        wt_dm_params dp = {.ndms = cfg->ndms,
                           .guard_rings = cfg->dm_guard_rings,
                           .field_radius = cfg->dm_field_radius,
                           .diameter = cfg->diameter};
        for (int k = 0; k < cfg->ndms; k++) {
            dp.altitude[k] = cfg->dm_altitude[k];
            dp.pitch[k] = cfg->dm_pitch[k];
            dp.actuators[k] = cfg->dm_actuators[k];
        }
        if ((st = wt_dm_alloc(ctx, &dp, &sys->dm)) < 0) {
            char detail[1024];
            snprintf(detail, sizeof detail, "%s", wt_error_message(ctx));
            st = WT_ERROR(ctx, st, "%s: %s", cfg->path, detail);
            goto fail;
        }
        sys->nact = sys->dm->nact;
    }

    int g = cfg->eval_grid;
    sys->neval = g * g;
    for (int j = 0; j < g; j++)
        for (int i = 0; i < g; i++) {
            sys->eval_x[i + g * j] = (i - 0.5 * (g - 1)) * cfg->eval_spacing;
            sys->eval_y[i + g * j] = (j - 0.5 * (g - 1)) * cfg->eval_spacing;
        }
    sys->eval_centre = (g / 2) + g * (g / 2);
    *out = sys;
    return WT_OK;
fail:
    wt_system_free(sys);
    return st;
}

void wt_system_free(wt_system *sys)
{
    if (!sys) return;
    wt_context *ctx = sys->ctx;
    for (int k = 0; k < sys->nsensors; k++) {
        wt_shack_hartmann_free(sys->sensors[k].sh);
        wt_free(ctx, sys->sensors[k].beta);
        wt_free(ctx, sys->sensors[k].noise_scale);
        wt_sensing_free(sys->sensors[k].diffr);
    }
    /* a sensor that failed half-way was not counted: free its parts too */
    if (sys->nsensors < 2 * WT_MAX_GS) {
        wt_shack_hartmann_free(sys->sensors[sys->nsensors].sh);
        wt_free(ctx, sys->sensors[sys->nsensors].beta);
        wt_free(ctx, sys->sensors[sys->nsensors].noise_scale);
        wt_sensing_free(sys->sensors[sys->nsensors].diffr);
    }
    wt_dm_free(sys->dm);
    wt_free(ctx, sys->valid);
    wt_free(ctx, sys->corner_mask);
    wt_free(ctx, sys);
}
