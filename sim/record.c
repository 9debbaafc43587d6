/* sim/record.c: the per-frame record of a closed-loop run and its result datasets (see record.h). */
#include "record.h"

#include <math.h>
#include <stdio.h>

#include "atmosphere.h"

/* frame/time columns: the loop's six parts and the whole step */
#define WT_RECORD_NSTAGES 7
static const char record_stage_columns[] = "atmosphere,sensors,reconstruction,fitting,control,evaluation,total";

struct wt_sim_record {
    wt_context *ctx;
    const wt_system *sys;
    long frames, t;                       /* room, frames recorded */
    double eval_wavelength;               /* [m] */
    double *se_field, *se_axis;           /* frames */
    float *rms_nm;                        /* frames x neval [nm] */
    float *time_ms;                       /* frames x WT_RECORD_NSTAGES [ms]: frame/time */
    wt_loop_times prev;                   /* the loop's cumulative times at the previous frame */
    float *fbuf;                          /* max(nslopes, nact): one telemetry row */
    wt_h5_series *slopes, *slopes_ol, *commands; /* telemetry (NULL: none) */
    int maps_every;                       /* residual maps every N-th frame (0: none) */
    float *maps;                          /* ndir x np: one frame's residual maps */
    wt_h5_series *maps_res, *maps_cmd, *maps_frame;
    int nl;                               /* a changing night: the truth's layers (0: no night) */
    double *night_t, *night_r0;           /* frames: night time [s], r0 [m] */
    double *night_f, *night_v, *night_d;  /* frames x nl: fractions, wind speed [m/s], direction [deg] */
};

int wt_sim_record_alloc(wt_context *ctx, const wt_system *sys, long frames, double eval_wavelength,
                        wt_h5_writer *tel, wt_sim_record **out)
{
    int st = WT_OK;
    wt_sim_record *r = NULL;
    *out = NULL;
    WT_ALLOC(ctx, r, 1, "run record");
    r->ctx = ctx;
    r->sys = sys;
    r->frames = frames;
    r->eval_wavelength = eval_wavelength;
    WT_ALLOC(ctx, r->se_field, frames, "per-frame field Strehl");
    WT_ALLOC(ctx, r->se_axis, frames, "per-frame on-axis Strehl");
    WT_ALLOC(ctx, r->rms_nm, (size_t)frames * sys->neval, "per-frame residual rms");
    WT_ALLOC(ctx, r->time_ms, (size_t)frames * WT_RECORD_NSTAGES, "per-frame stage times");
    WT_ALLOC(ctx, r->fbuf, sys->nslopes > sys->nact ? sys->nslopes : sys->nact, "telemetry row");
    if (sys->cfg->night.source != WT_NIGHT_CFG_NONE) { /* the truth's state per frame */
        r->nl = sys->cfg->nlayers;
        WT_ALLOC(ctx, r->night_t, frames, "per-frame night time");
        WT_ALLOC(ctx, r->night_r0, frames, "per-frame r0");
        WT_ALLOC(ctx, r->night_f, (size_t)frames * r->nl, "per-frame Cn2 fractions");
        WT_ALLOC(ctx, r->night_v, (size_t)frames * r->nl, "per-frame wind speeds");
        WT_ALLOC(ctx, r->night_d, (size_t)frames * r->nl, "per-frame wind directions");
    }
    if (tel) {
        WT_TRY(wt_h5_series_create(tel, "slopes", WT_H5_F32, sys->nslopes, "rad",
                                   "measured slopes s_t per frame (OPD gradient), ordering in layout/", &r->slopes));
        WT_TRY(wt_h5_series_create(tel, "slopes_ol", WT_H5_F32, sys->nslopes, "rad",
                                   "pseudo-open-loop slopes s_t + A^ a_t per frame", &r->slopes_ol));
        WT_TRY(wt_h5_series_create(tel, "commands", WT_H5_F32, sys->nact, "m",
                                   "DM commands a_t applied during the frame (actuator OPD), ordering in "
                                   "layout/actuator_index",
                                   &r->commands));
    }
    *out = r;
    return WT_OK;
fail:
    wt_sim_record_free(r);
    return st;
}

void wt_sim_record_free(wt_sim_record *r)
{
    if (!r) return;
    wt_free(r->ctx, r->se_field);
    wt_free(r->ctx, r->se_axis);
    wt_free(r->ctx, r->rms_nm);
    wt_free(r->ctx, r->time_ms);
    wt_free(r->ctx, r->fbuf);
    wt_free(r->ctx, r->maps);
    double *night[] = {r->night_t, r->night_r0, r->night_f, r->night_v, r->night_d};
    for (int k = 0; k < 5; k++) wt_free(r->ctx, night[k]);
    wt_free(r->ctx, r);
}

int wt_sim_record_maps(wt_sim_record *r, const wt_loop *lp, wt_h5_writer *tel, int every)
{
    int st = WT_OK;
    if (every < 1 || !tel) return WT_ERROR(r->ctx, WT_ERR_INVALID, "run record: maps every %d frames, telemetry %s", every,
                                           tel ? "open" : "missing");
    const wt_grid *g = wt_loop_fine_grid(lp);
    const int64_t np = wt_grid_size(g), nd = r->sys->neval;
    const int64_t dm[3] = {nd, g->ny, g->nx}, dp[2] = {g->ny, g->nx}, dc[1] = {r->sys->nact};
    WT_ALLOC(r->ctx, r->maps, (size_t)(nd * np), "residual maps");
    WT_TRY(wt_h5_write(tel, "maps/pupil", WT_H5_U8, WT_H5_U8, 2, dp, wt_loop_pupil_mask(lp), "",
                       "the pupil on the fine grid of maps/residual (1 inside; row = y)"));
    WT_TRY(wt_h5_attr_write_double(tel, "maps/pupil", "spacing_m", g->dx));
    WT_TRY(wt_h5_attr_write_int64(tel, "maps/pupil", "every", every));
    WT_TRY(wt_h5_series_create_shaped(tel, "maps/residual", WT_H5_F32, 3, dm, "m",
                                      "piston-removed residual OPD per recorded frame and evaluation direction (index as "
                                      "eval/theta_x) on the fine pupil grid of maps/pupil (row = y, 0 outside the pupil); "
                                      "its rms over the pupil is the frame's residual rms (RUN.h5 frame/rms)",
                                      &r->maps_res));
    WT_TRY(wt_h5_series_create_shaped(tel, "maps/commands", WT_H5_F32, 1, dc, "m",
                                      "DM commands a_t applied during each recorded frame (actuator OPD), ordering in "
                                      "layout/actuator_index", &r->maps_cmd));
    WT_TRY(wt_h5_series_create(tel, "maps/frame", WT_H5_I64, 0, "", "the frame index t of each recorded frame",
                               &r->maps_frame));
    r->maps_every = every;
fail:
    return st;
}

/* Frame t's residual maps (piston removed over the pupil, 0 outside), its commands and index */
static int append_maps(wt_sim_record *r, const wt_loop *lp, long t)
{
    const wt_grid *g = wt_loop_fine_grid(lp);
    const uint8_t *mask = wt_loop_pupil_mask(lp);
    const int64_t np = wt_grid_size(g);
    for (int j = 0; j < r->sys->neval; j++) {
        const double *res = wt_loop_residual(lp, j);
        double mean = 0.0;
        int64_t c = 0;
        for (int64_t i = 0; i < np; i++)
            if (mask[i]) mean += res[i], c++;
        mean /= c > 0 ? (double)c : 1.0;
        float *m = r->maps + (size_t)j * np;
        for (int64_t i = 0; i < np; i++) m[i] = mask[i] ? (float)(res[i] - mean) : 0.0f;
    }
    int st = wt_h5_series_append(r->maps_res, WT_H5_F32, r->maps);
    if (st < 0) return st;
    const double *a = wt_loop_applied(lp);
    for (int64_t i = 0; i < r->sys->nact; i++) r->fbuf[i] = (float)a[i];
    if ((st = wt_h5_series_append(r->maps_cmd, WT_H5_F32, r->fbuf)) < 0) return st;
    const int64_t ti = t;
    return wt_h5_series_append(r->maps_frame, WT_H5_I64, &ti);
}

int wt_sim_record_frame(wt_sim_record *r, const wt_loop *lp, double step)
{
    const wt_system *sys = r->sys;
    const long t = r->t;
    if (t >= r->frames) return WT_ERROR(r->ctx, WT_ERR_INVALID, "run record: room for %ld frames only", r->frames);
    const double *rms = wt_loop_rms(lp);
    r->se_field[t] = wt_loop_field_strehl(lp);
    r->se_axis[t] = wt_strehl_marechal(rms[sys->eval_centre], r->eval_wavelength);
    for (int j = 0; j < sys->neval; j++) r->rms_nm[(size_t)t * sys->neval + j] = (float)(rms[j] * 1e9);
    const wt_loop_times b = wt_loop_get_times(lp), a = r->prev;
    const double d[WT_RECORD_NSTAGES] = {b.atmosphere - a.atmosphere, b.sensors - a.sensors,
                                         b.reconstruction - a.reconstruction, b.fitting - a.fitting,
                                         b.control - a.control, b.evaluation - a.evaluation, step};
    for (int k = 0; k < WT_RECORD_NSTAGES; k++) r->time_ms[(size_t)t * WT_RECORD_NSTAGES + k] = (float)(d[k] * 1e3);
    r->prev = b;
    wt_night_sample ns;
    if (r->nl && wt_loop_truth_state(lp, &ns) && ns.nlayers == r->nl) {
        r->night_t[t] = ns.t;
        r->night_r0[t] = ns.r0;
        for (int l = 0; l < r->nl; l++) {
            const size_t i = (size_t)t * r->nl + l;
            r->night_f[i] = ns.fraction[l];
            r->night_v[i] = ns.wind_speed[l];
            r->night_d[i] = ns.wind_direction[l] * (180.0 / M_PI);
        }
    }
    if (r->maps_every && t % r->maps_every == 0) {
        int st = append_maps(r, lp, t);
        if (st < 0) return st;
    }
    r->t++;
    if (!r->slopes) return WT_OK;
    const double *src[3] = {wt_loop_slopes(lp), wt_loop_slopes_ol(lp), wt_loop_applied(lp)};
    wt_h5_series *dst[3] = {r->slopes, r->slopes_ol, r->commands};
    for (int k = 0; k < 3; k++) {
        int64_t n = k < 2 ? sys->nslopes : sys->nact;
        for (int64_t i = 0; i < n; i++) r->fbuf[i] = (float)src[k][i];
        int st = wt_h5_series_append(dst[k], WT_H5_F32, r->fbuf);
        if (st < 0) return st;
    }
    return WT_OK;
}

double wt_sim_record_field_strehl(const wt_sim_record *r, long t) { return r->se_field[t]; }

/* A changing night: the truth's state per frame (atmosphere.night). */
static int write_night(const wt_sim_record *r, wt_h5_writer *w)
{
    if (!r->nl) return WT_OK;
    int st;
    int64_t df[1] = {r->t}, dl[2] = {r->t, r->nl};
    if ((st = wt_h5_write(w, "frame/night_time", WT_H5_F64, WT_H5_F64, 1, df, r->night_t, "s",
                          "the night's time of each frame (atmosphere.night: start_s + frame x frame time x "
                          "compression), at which the truth's state below was evaluated")) < 0 ||
        (st = wt_h5_write(w, "frame/r0", WT_H5_F64, WT_H5_F64, 1, df, r->night_r0, "m",
                          "the truth's Fried parameter at 500 nm in each frame (the changing night)")) < 0 ||
        (st = wt_h5_write(w, "frame/cn2_fractions", WT_H5_F64, WT_H5_F64, 2, dl, r->night_f, "",
                          "the truth's Cn2 fraction of each layer in each frame (sum 1; layers in the order of "
                          "atmosphere.altitudes_m)")) < 0 ||
        (st = wt_h5_write(w, "frame/wind_speed", WT_H5_F64, WT_H5_F64, 2, dl, r->night_v, "m/s",
                          "the truth's wind speed of each layer in each frame")) < 0 ||
        (st = wt_h5_write(w, "frame/wind_direction", WT_H5_F64, WT_H5_F64, 2, dl, r->night_d, "deg",
                          "the truth's wind direction of each layer in each frame (towards, from +x towards +y)")) < 0)
        return st;
    return WT_OK;
}

int wt_sim_record_write(const wt_sim_record *r, wt_h5_writer *w, const wt_loop *lp, int settle_frames)
{
    int st;
    const wt_system *sys = r->sys;
    const long frames = r->t;
    const wt_strehl_le *le = wt_loop_le(lp);
    int nd = sys->neval;
    double sle[WT_MAX_EVAL], wfe[WT_MAX_EVAL], tx[WT_MAX_EVAL], ty[WT_MAX_EVAL], field = 0.0, fwfe = 0.0;
    for (int j = 0; j < nd; j++) {
        sle[j] = wt_strehl_le_strehl(le, j);
        wfe[j] = wt_strehl_le_wfe(le, j) * 1e9;
        tx[j] = sys->eval_x[j] / WT_ARCSEC;
        ty[j] = sys->eval_y[j] / WT_ARCSEC;
        field += sle[j] / nd;
        fwfe += wfe[j] * wfe[j] / nd;
    }
    int64_t dn[1] = {nd}, df[1] = {frames}, dr[2] = {frames, nd};
    if ((st = wt_h5_write_int64(w, "frames", frames, "", "frames simulated")) < 0) return st;
    if ((st = wt_h5_write_int64(w, "settle_frames", settle_frames, "",
                                "frames left out of the long-exposure averages")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "eval/wavelength", r->eval_wavelength * 1e9, "nm",
                                 "wavelength of the Strehl ratios (Marechal approximation)")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/theta_x", WT_H5_F64, WT_H5_F64, 1, dn, tx, "arcsec",
                          "evaluation direction x; index i + g*j of the g x g grid")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/theta_y", WT_H5_F64, WT_H5_F64, 1, dn, ty, "arcsec", "evaluation direction y")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/strehl_le", WT_H5_F64, WT_H5_F64, 1, dn, sle, "",
                          "long-exposure Strehl per evaluation direction (mean of the short-exposure Strehl after "
                          "the settle frames)")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/wfe_le", WT_H5_F64, WT_H5_F64, 1, dn, wfe, "nm",
                          "residual wavefront error per direction: sqrt of the mean piston-removed variance after "
                          "the settle frames")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "strehl_le_on_axis", sle[sys->eval_centre], "",
                                 "long-exposure Strehl in the central (on-axis) direction")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "strehl_le_field", field, "",
                                 "long-exposure Strehl averaged over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "wfe_le_field", sqrt(fwfe), "nm",
                                 "residual wavefront error, rms over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/strehl_field", WT_H5_F64, WT_H5_F64, 1, df, r->se_field, "",
                          "short-exposure Strehl per frame, averaged over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/strehl_on_axis", WT_H5_F64, WT_H5_F64, 1, df, r->se_axis, "",
                          "short-exposure Strehl per frame in the central direction")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/rms", WT_H5_F32, WT_H5_F32, 2, dr, r->rms_nm, "nm",
                          "piston-removed residual rms per frame and evaluation direction")) < 0)
        return st;
    int64_t dt[2] = {frames, WT_RECORD_NSTAGES};
    if ((st = wt_h5_write(w, "frame/time", WT_H5_F32, WT_H5_F32, 2, dt, r->time_ms, "ms",
                          "wall time of each frame per stage: atmosphere, sensors, reconstruction, fitting, "
                          "control, evaluation, total (the whole step; attribute columns)")) < 0 ||
        (st = wt_h5_attr_write_string(w, "frame/time", "columns", record_stage_columns)) < 0)
        return st;
    if ((st = write_night(r, w)) < 0) return st;
    wt_loop_times tm = wt_loop_get_times(lp);
    const char *names[] = {"atmosphere", "sensors", "reconstruction", "fitting", "control", "evaluation"};
    double vals[] = {tm.atmosphere, tm.sensors, tm.reconstruction, tm.fitting, tm.control, tm.evaluation};
    for (int k = 0; k < 6; k++) {
        char name[64];
        snprintf(name, sizeof name, "timing/%s", names[k]);
        if ((st = wt_h5_write_double(w, name, frames ? vals[k] / frames * 1e3 : 0.0, "ms",
                                     "mean wall time per frame of this part of the simulation")) < 0)
            return st;
    }
    const wt_adapt *ad = wt_loop_adapt(lp);
    if (ad && ((st = wt_h5_write_double(w, "timing/learning", frames ? tm.learning / frames * 1e3 : 0.0, "ms",
                                        "mean wall time per frame of the learning of the atmosphere: the accumulation, "
                                        "the estimates and the reconstructor's new models (in the total)")) < 0 ||
               (st = wt_adapt_write(ad, w, "learned")) < 0))
        return st;
    return WT_OK;
}

int wt_sim_write_dump(wt_context *ctx, wt_h5_writer *w, const wt_loop *lp, int nd)
{
    int st = WT_OK;
    const wt_atmosphere *atm = wt_loop_atmosphere(lp);
    wt_grid g = wt_atmosphere_grid(atm);
    double *buf = NULL;
    float *res = NULL;
    WT_ALLOC(ctx, buf, wt_grid_size(&g), "screen dump");
    for (int l = 0; l < wt_atmosphere_nlayers(atm); l++) {
        wt_atmosphere_layer_render(atm, l, buf);
        char name[64];
        snprintf(name, sizeof name, "screens/layer%d", l + 1);
        int64_t d[2] = {g.ny, g.nx};
        WT_TRY(wt_h5_write(w, name, WT_H5_F32, WT_H5_F64, 2, d, buf, "m",
                           "OPD screen of this atmospheric layer at frame 0 on its periodic grid (row = y)"));
        WT_TRY(wt_h5_attr_write_double(w, name, "altitude_m", wt_atmosphere_layer_altitude(atm, l)));
        WT_TRY(wt_h5_attr_write_double(w, name, "spacing_m", g.dx));
    }
    const wt_grid *f = wt_loop_fine_grid(lp);
    const uint8_t *mask = wt_loop_pupil_mask(lp);
    int64_t np = wt_grid_size(f);
    WT_ALLOC(ctx, res, (size_t)nd * np, "residual dump");
    for (int j = 0; j < nd; j++) {
        const double *r = wt_loop_residual(lp, j);
        double mean = 0.0;
        int64_t c = 0;
        for (int64_t i = 0; i < np; i++)
            if (mask[i]) mean += r[i], c++;
        mean = c ? mean / c : 0.0;
        for (int64_t i = 0; i < np; i++) res[(size_t)j * np + i] = mask[i] ? (float)(r[i] - mean) : NAN;
    }
    int64_t d[3] = {nd, f->ny, f->nx};
    WT_TRY(wt_h5_write(w, "residual", WT_H5_F32, WT_H5_F32, 3, d, res, "m",
                       "piston-removed residual OPD of the last frame per evaluation direction on the fine "
                       "pupil grid (row = y; NaN outside the pupil)"));
    WT_TRY(wt_h5_attr_write_double(w, "residual", "spacing_m", f->dx));
fail:
    wt_free(ctx, buf);
    wt_free(ctx, res);
    return st;
}
