/* sim/focus_stage.c: the LGS WFS focus stage and tip-tilt centring (focus_stage.h for the equations). */
#include "focus_stage.h"

#include <math.h>

struct wt_focus_stage {
    wt_context *ctx;
    const wt_system *sys;
    double gain;
    long from_frame;
    double focus;           /* c [1/m], common to the LGS */
    double *tilt;           /* t_m: 2 per sensor of sys (zero for sensors without a stage) */
    double *xbar;           /* r̄: 2 per sensor */
    double *inv_norm;       /* 1 / (2 Σ_k |r_k − r̄|²) per sensor; 0: no stage */
    double *cx;             /* subaperture centres of every staged sensor, laid out as its slopes ([x…, y…]) */
    double altitude;        /* H of the staged LGS (their mean, for the report) */
    double sum_focus, *sum_tilt; /* the measurements since the last move, and their count */
    long measured;
    double dh_sum, tilt_sq; /* the statistics from from_frame on */
    long frames, tilt_terms, moves;
};

int wt_focus_stage_alloc(wt_context *ctx, const wt_system *sys, double gain, long from_frame, wt_focus_stage **out)
{
    int st = WT_OK, nstaged = 0;
    *out = NULL;
    for (int i = 0; i < sys->nsensors; i++) nstaged += sys->sensors[i].diffr && sys->sensors[i].kind == WT_SENSOR_LGS;
    if (!nstaged) return WT_OK;
    if (!(gain > 0.0 && gain <= 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "LGS focus stage: gain %g outside (0, 1]", gain);
    wt_focus_stage *fs = NULL;
    WT_ALLOC(ctx, fs, 1, "LGS focus stage");
    fs->ctx = ctx, fs->sys = sys, fs->gain = gain, fs->from_frame = from_frame;
    WT_ALLOC(ctx, fs->tilt, 2 * (size_t)sys->nsensors, "LGS focus stage tilts");
    WT_ALLOC(ctx, fs->sum_tilt, 2 * (size_t)sys->nsensors, "LGS focus stage sums");
    WT_ALLOC(ctx, fs->xbar, 2 * (size_t)sys->nsensors, "LGS focus stage centres");
    WT_ALLOC(ctx, fs->inv_norm, (size_t)sys->nsensors, "LGS focus stage norms");
    WT_ALLOC(ctx, fs->cx, (size_t)sys->nslopes, "subaperture centres");
    for (int i = 0; i < sys->nsensors; i++) {
        const wt_sensor *s = &sys->sensors[i];
        if (!s->diffr || s->kind != WT_SENSOR_LGS) continue;
        double *x = fs->cx + s->offset, *y = x + s->nsub, mx = 0.0, my = 0.0, q = 0.0;
        for (int k = 0; k < s->nsub; k++) {
            wt_shack_hartmann_centre(s->sh, k, &x[k], &y[k]);
            mx += x[k], my += y[k];
        }
        mx /= s->nsub, my /= s->nsub;
        for (int k = 0; k < s->nsub; k++) q += (x[k] - mx) * (x[k] - mx) + (y[k] - my) * (y[k] - my);
        if (!(q > 0.0)) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "LGS focus stage: %s has %d subaperture(s), too few to measure focus",
                          s->name, s->nsub);
            goto fail;
        }
        fs->xbar[2 * i] = mx, fs->xbar[2 * i + 1] = my, fs->inv_norm[i] = 0.5 / q;
        fs->altitude += s->altitude / nstaged;
    }
    *out = fs;
    return WT_OK;
fail:
    wt_focus_stage_free(fs);
    return st;
}

void wt_focus_stage_terms(const wt_focus_stage *fs, int i, double stage[3])
{
    const int on = fs && fs->inv_norm[i] > 0.0;
    stage[0] = on ? fs->tilt[2 * i] : 0.0;
    stage[1] = on ? fs->tilt[2 * i + 1] : 0.0;
    stage[2] = on ? fs->focus : 0.0;
}

void wt_focus_stage_measure(wt_focus_stage *fs, long t, const double *slopes)
{
    const wt_system *sys = fs->sys;
    double c = 0.0;
    int n = 0;
    for (int i = 0; i < sys->nsensors; i++) {
        if (!(fs->inv_norm[i] > 0.0)) continue;
        const wt_sensor *s = &sys->sensors[i];
        const double *sx = slopes + s->offset, *sy = sx + s->nsub, *x = fs->cx + s->offset, *y = x + s->nsub;
        const double mx = fs->xbar[2 * i], my = fs->xbar[2 * i + 1];
        double f = 0.0, ax = 0.0, ay = 0.0;
        for (int k = 0; k < s->nsub; k++) {
            f += (x[k] - mx) * sx[k] + (y[k] - my) * sy[k];
            ax += sx[k], ay += sy[k];
        }
        c += f * fs->inv_norm[i], n++;
        fs->sum_tilt[2 * i] += ax / s->nsub, fs->sum_tilt[2 * i + 1] += ay / s->nsub;
        if (t >= fs->from_frame) {
            fs->tilt_sq += fs->tilt[2 * i] * fs->tilt[2 * i] + fs->tilt[2 * i + 1] * fs->tilt[2 * i + 1];
            fs->tilt_terms++;
        }
    }
    fs->sum_focus += c / n;
    fs->measured++;
    if (t >= fs->from_frame) fs->dh_sum += 2.0 * fs->altitude * fs->altitude * fs->focus, fs->frames++;
}

void wt_focus_stage_move(wt_focus_stage *fs)
{
    if (fs->measured < 1) return;
    const double g = fs->gain / (double)fs->measured;
    fs->focus -= g * fs->sum_focus;
    for (int i = 0; i < 2 * fs->sys->nsensors; i++) fs->tilt[i] -= g * fs->sum_tilt[i], fs->sum_tilt[i] = 0.0;
    fs->sum_focus = 0.0;
    fs->measured = 0;
    fs->moves++;
}

wt_focus_stage_stats wt_focus_stage_get_stats(const wt_focus_stage *fs)
{
    const double h2 = 2.0 * fs->altitude * fs->altitude;
    return (wt_focus_stage_stats){.dh_now = h2 * fs->focus,
                                  .dh_mean = fs->frames ? fs->dh_sum / fs->frames : 0.0,
                                  .tilt_rms = fs->tilt_terms ? sqrt(fs->tilt_sq / fs->tilt_terms) : 0.0,
                                  .frames_averaged = fs->frames,
                                  .moves = fs->moves};
}

void wt_focus_stage_free(wt_focus_stage *fs)
{
    if (!fs) return;
    wt_free(fs->ctx, fs->tilt);
    wt_free(fs->ctx, fs->sum_tilt);
    wt_free(fs->ctx, fs->xbar);
    wt_free(fs->ctx, fs->inv_norm);
    wt_free(fs->ctx, fs->cx);
    wt_free(fs->ctx, fs);
}
