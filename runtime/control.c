/* runtime/control.c: the loop's control law (control.h): the delay's command queue and the integrator, with one
 * gain g or the scale-dependent G = Σ_j g_j Π_j (core/op/scale_gain.h). */
#include "control.h"

#include <string.h>

struct wt_control {
    wt_context *ctx;
    int64_t nact;
    int delay;
    double gain;
    int direct;              /* a_{t+d} = r_t */
    long t;                  /* frames stepped */
    double **ring;           /* delay + 1 command vectors: a_t at slot t mod (delay + 1) */
    wt_scale_gain *sg;       /* G (else NULL) */
    double *gerr, *gwork;    /* sg: r − a_t and G's workspace */
};

_Static_assert(WT_MAX_GAIN_BANDS == WT_SCALE_GAIN_MAX_BANDS, "loop.gain_levels must fit wt_scale_gain_params");

wt_control_params wt_control_params_from_config(const wt_config *cfg)
{
    wt_control_params p;
    memset(&p, 0, sizeof p);
    p.delay = cfg->delay;
    p.gain = cfg->gain;
    if (cfg->ngain_levels > 0) {
        p.scale_gain.nbands = cfg->ngain_levels;
        memcpy(p.scale_gain.gain, cfg->gain_levels, (size_t)cfg->ngain_levels * sizeof *cfg->gain_levels);
        p.scale_gain.basis = cfg->gain_basis ? WT_SCALE_GAIN_DAUBECHIES : WT_SCALE_GAIN_BILINEAR;
        p.scale_gain.wavelet_order = cfg->wavelet_order;
    }
    return p;
}

int wt_control_alloc(wt_context *ctx, const wt_system *sys, const wt_control_params *par, wt_control **out)
{
    int st = WT_OK;
    wt_control *c = NULL;
    *out = NULL;
    if (par->delay < 1 || !(par->gain >= 0.0 && par->gain <= 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "control: delay %d and gain %g; expected a delay >= 1 frame and a gain in "
                        "[0, 1] (loop.delay, loop.gain)", par->delay, par->gain);
    if (par->scale_gain.nbands > 0 && par->direct)
        return WT_ERROR(ctx, WT_ERR_INVALID, "control: a gain per scale of the commands with the integrator on the "
                        "layers (loop.gain_levels with recon.predict_integrator = \"layers\")");
    WT_ALLOC(ctx, c, 1, "control law");
    c->ctx = ctx;
    c->nact = sys->nact;
    c->delay = par->delay;
    c->gain = par->gain;
    c->direct = par->direct;
    if (par->scale_gain.nbands > 0) {
        WT_TRY(wt_scale_gain_alloc(ctx, sys->dm, &par->scale_gain, &c->sg));
        WT_ALLOC(ctx, c->gerr, sys->nact, "scale-dependent gain");
        WT_ALLOC(ctx, c->gwork, wt_scale_gain_work_size(c->sg) + 1, "scale-dependent gain");
    }
    WT_ALLOC(ctx, c->ring, c->delay + 1, "command queue");
    for (int k = 0; k <= c->delay; k++) WT_ALLOC(ctx, c->ring[k], sys->nact, "command queue");
    *out = c;
    return WT_OK;
fail:
    wt_control_free(c);
    return st;
}

void wt_control_free(wt_control *c)
{
    if (!c) return;
    if (c->ring)
        for (int k = 0; k <= c->delay; k++) wt_free(c->ctx, c->ring[k]);
    wt_free(c->ctx, c->ring);
    wt_scale_gain_free(c->sg);
    wt_free(c->ctx, c->gerr);
    wt_free(c->ctx, c->gwork);
    wt_free(c->ctx, c);
}

const double *wt_control_applied(const wt_control *c) { return c->ring[c->t % (c->delay + 1)]; }

const double *wt_control_step(wt_control *c, const double *r, const double *a_t)
{
    const int D1 = c->delay + 1;
    const double *prev = c->ring[(c->t + c->delay - 1) % D1];
    double *next = c->ring[(c->t + c->delay) % D1];
    if (!r) {
        memset(next, 0, (size_t)c->nact * sizeof *next);
    } else if (c->direct) {
        memcpy(next, r, (size_t)c->nact * sizeof *next);
    } else if (c->sg) {
        /* G = g I (all gains equal) adds (1 g) e_k to prev_k: the single gain's bits */
        for (int64_t k = 0; k < c->nact; k++) c->gerr[k] = r[k] - a_t[k];
        memcpy(next, prev, (size_t)c->nact * sizeof *next);
        wt_scale_gain_apply(c->sg, 1.0, c->gerr, next, c->gwork);
    } else {
        for (int64_t k = 0; k < c->nact; k++) next[k] = prev[k] + c->gain * (r[k] - a_t[k]);
    }
    c->t++;
    return next;
}

void wt_control_reset(wt_control *c)
{
    for (int k = 0; k <= c->delay; k++) memset(c->ring[k], 0, (size_t)c->nact * sizeof *c->ring[k]);
    c->t = 0;
}

int wt_control_delay(const wt_control *c) { return c->delay; }
double wt_control_gain(const wt_control *c) { return c->gain; }
int wt_control_scale_dependent(const wt_control *c) { return c->sg != NULL; }
