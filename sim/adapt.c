/* sim/adapt.c: the loop that learns its atmosphere (see adapt.h; SPEC §12 "Identification from the loop's own
 * data" and "Updates"). */
#include "adapt.h"
#include "../core/model/profile.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/io/h5.h"
#include "../core/model/wind_align.h"
#include "../core/solve/mvm.h"

struct wt_adapt {
    wt_context *ctx;
    const wt_system *sys;
    int kind;
    wt_adapt_params par;
    double tx[WT_MAX_GS], ty[WT_MAX_GS];
    wt_learn_geometry g;
    wt_learn *L;
    wt_learn_model *M;        /* the response maps and normal matrix of the learning grid: computed once */
    double model_setup;       /* its wall time [s] */
    double merge;             /* grid_layers: the merge separation of the grid [m] (0: the default grid) */
    long since;               /* frames accumulated since the last estimate */
    int na;
    double alt[WT_MAX_LAYERS + WT_LEARN_MAX_ALT];      /* the learning grid, or (follow_truth) the truth's layers */
    double vx[WT_MAX_LAYERS + WT_LEARN_MAX_ALT], vy[WT_MAX_LAYERS + WT_LEARN_MAX_ALT]; /* their wind */
    wt_learn_estimate *est;
    double cavg[WT_LEARN_MAX_ALT];  /* the memory's average of c = f r0^(−5/3) per altitude (nup > 0) */
    wt_adapt_rebuild_fn rebuild;
    void *rebuild_user;
    wt_adapt_update *up;
    int nup, maxup;
    struct wt_mvm *owned;     /* mvm: the matrix in use when it was built here (else the caller's) */
    struct wt_mvm *pending;   /* mvm: built, in the loop from night time pending_ready on */
    double pending_ready;
    int pending_update;
    int waiting;              /* mvm: an estimate waiting for the build machine (−1: none) */
    double tacc, tbuild;
    wt_wind_align *wind;      /* learn_wind: the layers' wind estimator (wt_adapt_wind_alloc), else NULL */
    int nwl;                  /* its layers, their altitudes [m] */
    double wind_alt[WT_MAX_LAYERS];
};

static int learn_alloc(wt_adapt *a)
{
    const long span = a->par.cumulative ? a->par.run_frames : a->par.every;
    return wt_learn_alloc(a->ctx, &a->g, WT_ADAPT_BATCHES, span / WT_ADAPT_BATCHES > 0 ? span / WT_ADAPT_BATCHES : 1, &a->L);
}

int wt_adapt_alloc(wt_context *ctx, const wt_system *sys, int kind, const wt_adapt_params *par, wt_adapt_rebuild_fn rebuild,
                   void *rebuild_user, long max_updates, wt_adapt **out)
{
    int st = WT_OK;
    wt_adapt *a = NULL;
    *out = NULL;
    if (sys->nlgs < 2 && !par->follow_truth)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: recon.atmosphere.source = \"learned\" needs at least 2 LGS (pairs of LGS "
                        "resolve altitude), the system has %d", sys->cfg ? sys->cfg->path : "system", sys->nlgs);
    if (par->every < (par->follow_truth ? 1 : WT_ADAPT_MIN_FRAMES))
        return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'recon.atmosphere.update_s': an estimate every %ld frames; one "
                        "estimate needs at least %d (%d batches of 25)", sys->cfg ? sys->cfg->path : "system", par->every,
                        par->follow_truth ? 1 : WT_ADAPT_MIN_FRAMES, WT_ADAPT_BATCHES);
    if (par->follow_truth && (par->ntruth < 1 || par->ntruth > WT_MAX_LAYERS))
        return WT_ERROR(ctx, WT_ERR_INVALID, "adapt: a truth of %d layers", par->ntruth);
    if (kind != WT_RECON_PCG3 && kind != WT_RECON_CG9 && kind != WT_RECON_MVM)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "a learned atmosphere is for pcg3, cg9 and mvm, not %s",
                        wt_reconstructor_name(kind));
    if (par->learn_wind && kind != WT_RECON_PCG3 && kind != WT_RECON_CG9)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'recon.atmosphere.learn_wind' = \"aligned\" measures the wind of the "
                        "reconstruction layers for prediction: pcg3 and cg9 only, not %s (the MVM does not predict)",
                        sys->cfg ? sys->cfg->path : "system", wt_reconstructor_name(kind));
    if (kind == WT_RECON_MVM && !rebuild)
        return WT_ERROR(ctx, WT_ERR_INVALID, "a learning MVM loop needs a rebuild callback (the driver's)");
    if (par->nstart < 1 || par->nstart > WT_MAX_LAYERS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "adapt: %d start layers", par->nstart);
    WT_ALLOC(ctx, a, 1, "learning loop");
    a->ctx = ctx;
    a->sys = sys;
    a->kind = kind;
    a->par = *par;
    for (int i = 0; i < sys->nlgs; i++) a->tx[i] = sys->sensors[i].theta_x, a->ty[i] = sys->sensors[i].theta_y;
    a->g = (wt_learn_geometry){sys->n, sys->d, sys->valid, sys->nlgs, a->tx, a->ty, sys->sensors[0].altitude};
    if (par->follow_truth) {
        a->na = par->ntruth;
        for (int k = 0; k < a->na; k++) a->alt[k] = par->truth_alt[k];
    } else {
        WT_TRY(learn_alloc(a));
        a->na = par->grid_layers ? wt_learn_grid_with_layers(&a->g, par->nrecon, par->recon_alt, WT_LEARN_MAX_ALT, a->alt,
                                                             &a->merge)
                                 : wt_learn_default_grid(a->g.H, WT_LEARN_MAX_ALT, a->alt);
        if (a->na < 1) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'recon.atmosphere.learn_grid': the default grid and the "
                          "reconstructor's %d layers do not fit in %d altitudes", sys->cfg ? sys->cfg->path : "system",
                          par->nrecon, WT_LEARN_MAX_ALT);
            goto fail;
        }
        const double t0 = wt_time_now();
        WT_TRY(wt_learn_model_alloc(a->L, a->na, a->alt, par->L0, &a->M));
        a->model_setup = wt_time_now() - t0;
    }
    for (int k = 0; k < a->na; k++) { /* the start model's wind at the nearest of its layers */
        int best = 0;
        for (int j = 1; j < par->nstart; j++)
            if (fabs(par->start_alt[j] - a->alt[k]) < fabs(par->start_alt[best] - a->alt[k])) best = j;
        a->vx[k] = par->start_vx[best], a->vy[k] = par->start_vy[best];
    }
    WT_ALLOC(ctx, a->est, 1, "profile estimate");
    a->maxup = max_updates > 0 ? (int)max_updates : 1;
    WT_ALLOC(ctx, a->up, a->maxup, "update record");
    a->rebuild = rebuild;
    a->rebuild_user = rebuild_user;
    a->waiting = -1;
    *out = a;
    return WT_OK;
fail:
    wt_adapt_free(a);
    return st;
}

void wt_adapt_free(wt_adapt *a)
{
    if (!a) return;
    wt_learn_model_free(a->M);
    wt_learn_free(a->L);
    wt_mvm_free(a->owned);
    wt_mvm_free(a->pending);
    wt_wind_align_free(a->wind);
    wt_free(a->ctx, a->est);
    wt_free(a->ctx, a->up);
    wt_free(a->ctx, a);
}

/* the matrix of update u, built now (night time `start`: when the build machine takes it) */
static int start_build(wt_adapt *a, int u, double start)
{
    wt_adapt_update *p = &a->up[u];
    const double t0 = wt_time_now();
    struct wt_mvm *m = NULL;
    const int st = a->rebuild(a->rebuild_user, p->r0, p->nalt, p->altitude, p->fraction, p->vx, p->vy,
                              !a->par.follow_truth, &m);
    if (st < 0) return st;
    p->build_s = wt_time_now() - t0;
    a->tbuild += p->build_s;
    a->pending = m;
    a->pending_ready = start + (a->par.latency >= 0.0 ? a->par.latency : p->build_s);
    a->pending_update = u;
    return WT_OK;
}

/* ---- learn_wind: the reconstruction layers' own winds (core/model/wind_align.h) ---- */

int wt_adapt_wind_alloc(wt_adapt *a, wt_reconstructor *rec)
{
    if (!a->par.learn_wind || a->par.follow_truth) return WT_OK;
    wt_tomography *tm = wt_reconstructor_tomography(rec);
    if (!tm) return WT_ERROR(a->ctx, WT_ERR_INVALID, "adapt: the layers' wind needs a pcg3 or cg9 reconstructor");
    const wt_system *sys = a->sys;
    const int L = wt_tomography_nlayers(tm);
    const wt_grid *g[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS];
    double rad[WT_MAX_LAYERS], th = 0.0;
    for (int i = 0; i < sys->nlgs; i++) th = fmax(th, hypot(a->tx[i], a->ty[i]));
    const double H = sys->sensors[0].altitude, D = sys->diameter;
    for (int l = 0; l < L; l++) {
        /* the taper: out to the LGS beams' union at the layer (the pupil shrunk by the cone, moved by the
         * farthest LGS), within the grid */
        const double h = wt_tomography_layer_altitude(tm, l);
        g[l] = wt_tomography_layer_grid(tm, l);
        off[l] = wt_tomography_layer_offset(tm, l);
        rad[l] = fmin(0.5 * D * (1.0 - (H > 0.0 ? h / H : 0.0)) + th * h, 0.5 * g[l]->nx * g[l]->dx);
        a->wind_alt[l] = h;
    }
    a->nwl = L;
    const long span = a->par.cumulative ? a->par.run_frames : a->par.every;
    wt_wind_align_params p = {.stride = WT_ADAPT_WIND_STRIDE, .nlag = 4, .lag = {1, 2, 4, 8}, .nbatch = WT_ADAPT_BATCHES,
                              .frame_dt = a->par.frame_dt};
    p.batch_snapshots = span / WT_ADAPT_WIND_STRIDE / WT_ADAPT_BATCHES;
    return wt_wind_align_alloc(a->ctx, L, g, off, rad, wt_tomography_fft(tm), &p, &a->wind);
}

/* The layers' winds after this update into u: the estimate where it is clear, the reconstructor's current wind
 * elsewhere; the estimator starts again for an interval's estimate */
static int wind_update(wt_adapt *a, const wt_reconstructor *rec, wt_adapt_update *u)
{
    wt_wind_estimate e[WT_MAX_LAYERS];
    const int st = wt_wind_align_estimate(a->wind, e);
    if (st < 0) return st;
    wt_reconstructor_layer_wind(rec, u->wind_vx, u->wind_vy);
    u->nwind = a->nwl;
    for (int l = 0; l < a->nwl; l++) {
        u->wind_valid[l] = e[l].valid;
        if (!e[l].valid) continue;
        u->wind_vx[l] = e[l].vx, u->wind_vy[l] = e[l].vy;
        u->wind_sx[l] = e[l].sigma_x, u->wind_sy[l] = e[l].sigma_y;
    }
    if (!a->par.cumulative) wt_wind_align_reset(a->wind);
    return WT_OK;
}

int wt_adapt_frame(wt_adapt *a, long t, const double *s_ol, const wt_night_sample *truth, wt_reconstructor *rec)
{
    int st = WT_OK;
    if (!a->par.follow_truth) {
        const double t0 = wt_time_now();
        st = wt_learn_add(a->L, s_ol);
        if (st >= 0 && a->wind) st = wt_wind_align_add(a->wind, t, wt_reconstructor_layers(rec));
        a->tacc += wt_time_now() - t0;
        if (st < 0) return WT_ERROR(a->ctx, st, "frame %ld: %s", t, wt_error_message(a->ctx));
    }
    if (++a->since < a->par.every) return WT_OK;
    a->since = 0;
    if (a->nup == a->maxup) return WT_ERROR(a->ctx, WT_ERR_INVALID, "adapt: more than %d updates", a->maxup);
    wt_adapt_update *u = &a->up[a->nup];
    memset(u, 0, sizeof *u);
    u->frame = t;
    u->night = (double)(t + 1) * a->par.frame_night;
    u->applied_frame = -1;
    if (a->par.follow_truth) { /* the oracle: the truth's state of this frame */
        if (!truth || truth->nlayers != a->na)
            return WT_ERROR(a->ctx, WT_ERR_INVALID, "frame %ld: the oracle follows the night, but the truth's state %s",
                            t, truth ? "has another layer count" : "is missing");
        u->r0 = truth->r0;
        u->nalt = a->na;
        for (int k = 0; k < a->na; k++) {
            u->altitude[k] = a->alt[k], u->fraction[k] = truth->fraction[k];
            a->vx[k] = truth->wind_speed[k] * cos(truth->wind_direction[k]);
            a->vy[k] = truth->wind_speed[k] * sin(truth->wind_direction[k]);
        }
    } else {
        const double tf = wt_time_now();
        st = wt_learn_fit_model(a->L, a->M, a->est);
        u->fit_s = wt_time_now() - tf;
        if (st < 0) return WT_ERROR(a->ctx, st, "frame %ld: the profile estimate from the last %ld frames: %s", t,
                                    a->par.every, wt_error_message(a->ctx));
        if (!a->par.cumulative) wt_learn_reset(a->L); /* the next estimate: the next frames only */
        {   /* its uncertainty counts the screens the frames saw, at the grid's wind (core/model/learn.h) */
            double speed[WT_MAX_LAYERS + WT_LEARN_MAX_ALT];
            const int n = a->est->nalt < a->na ? a->est->nalt : a->na;
            for (int k = 0; k < n; k++) speed[k] = hypot(a->vx[k], a->vy[k]);
            wt_learn_estimate_count_screens(a->est, a->sys->diameter, a->par.frame_dt, n, a->est->fraction, speed);
        }
        const wt_learn_estimate *e = a->est;
        /* the memory: c = f r0^(−5/3) per altitude averaged over the estimates (the maps are linear in it) */
        const double w = a->nup == 0 || a->par.memory <= 1.0 ? 1.0 : 1.0 / a->par.memory;
        double sum = 0.0;
        for (int k = 0; k < e->nalt; k++) sum += a->cavg[k] = (1.0 - w) * a->cavg[k] + w * e->cn2[k];
        u->r0_raw = e->r0;
        u->r0 = w == 1.0 ? e->r0 : pow(sum, -3.0 / 5.0);
        u->r0_sigma = e->r0_sigma;
        u->nalt = e->nalt;
        for (int k = 0; k < e->nalt; k++)
            u->altitude[k] = e->altitude[k], u->fraction[k] = w == 1.0 ? e->fraction[k] : a->cavg[k] / sum;
        if (a->wind && (st = wind_update(a, rec, u)) < 0)
            return WT_ERROR(a->ctx, st, "frame %ld: the layers' wind: %s", t, wt_error_message(a->ctx));
    }
    for (int k = 0; k < u->nalt; k++) u->vx[k] = a->vx[k], u->vy[k] = a->vy[k];
    const int idx = a->nup++;
    if (a->kind != WT_RECON_MVM) {
        /* an estimate samples a continuous profile on its grid: its hats compressed onto the layers
         * (core/model/profile.h), handed over as a profile at the layers' own altitudes; the oracle's truth is layers */
        const wt_tomography *tm = wt_reconstructor_tomography(rec);
        const int L = wt_tomography_nlayers(tm);
        double ralt[WT_MAX_LAYERS], rf[WT_MAX_LAYERS], rvx[WT_MAX_LAYERS], rvy[WT_MAX_LAYERS];
        for (int l = 0; l < L; l++) ralt[l] = wt_tomography_layer_altitude(tm, l);
        if (a->par.follow_truth) st = wt_reconstructor_set_model(rec, u->r0, u->nalt, u->altitude, u->fraction, a->vx, a->vy);
        else {
            wt_profile_compress_hats(u->nalt, u->altitude, u->fraction, a->vx, a->vy, L, ralt, rf, rvx, rvy);
            st = wt_reconstructor_set_model(rec, u->r0, L, ralt, rf, rvx, rvy);
        }
        if (st < 0)
            return WT_ERROR(a->ctx, st, "frame %ld: the learned model: %s", t, wt_error_message(a->ctx));
        if (a->wind && (st = wt_reconstructor_set_layer_wind(rec, u->wind_vx, u->wind_vy)) < 0)
            return WT_ERROR(a->ctx, st, "frame %ld: the layers' learned wind: %s", t, wt_error_message(a->ctx));
        wt_reconstructor_last_update_times(rec, &u->model_s, &u->precond_s);
        u->applied_frame = t + 1;
        return WT_OK;
    }
    if (!a->pending) return start_build(a, idx, u->night);
    a->waiting = idx; /* (a waiting estimate it replaces is never built) */
    return WT_OK;
}

int wt_adapt_swap(wt_adapt *a, long t, wt_reconstructor **rec)
{
    const double now = (double)t * a->par.frame_night;
    while (a->pending && now + 1e-6 * a->par.frame_night >= a->pending_ready) { /* (the frame at the ready time
                                                                                    itself, whatever the rounding) */
        wt_reconstructor *r = NULL;
        int st = wt_reconstructor_alloc_mvm(a->ctx, a->sys, a->pending, &r);
        if (st < 0) return st;
        wt_reconstructor_free(*rec);
        *rec = r;
        wt_mvm_free(a->owned);
        a->owned = a->pending;
        a->pending = NULL;
        a->up[a->pending_update].applied_frame = t;
        if (a->waiting >= 0) { /* the build machine is free from pending_ready on */
            const int w = a->waiting;
            a->waiting = -1;
            if ((st = start_build(a, w, a->pending_ready)) < 0) return st;
        }
    }
    return WT_OK;
}

int wt_adapt_nupdates(const wt_adapt *a) { return a->nup; }
int wt_adapt_follows_truth(const wt_adapt *a) { return a->par.follow_truth; }
const wt_adapt_update *wt_adapt_updates(const wt_adapt *a) { return a->up; }
double wt_adapt_accumulate_seconds(const wt_adapt *a) { return a->tacc; }
double wt_adapt_wind_seconds(const wt_adapt *a) { return a->wind ? wt_wind_align_seconds(a->wind) : 0.0; }
int wt_adapt_wind_layers(const wt_adapt *a, const double **alt)
{
    if (alt) *alt = a->wind_alt;
    return a->nwl;
}
double wt_adapt_build_seconds(const wt_adapt *a) { return a->tbuild; }
double wt_adapt_model_setup_seconds(const wt_adapt *a) { return a->model_setup; }

/* learn_wind: the layers' winds per update under learned/wind_* */
static int wind_write(const wt_adapt *a, wt_h5_writer *w, int n, const char *group)
{
    int st = WT_OK;
    char path[256];
#define NAME(s) (snprintf(path, sizeof path, "%s/%s", group, s), path)
    const int L = a->nwl;
    double *v = NULL;
    int64_t *iv = NULL;
    WT_ALLOC(a->ctx, v, (size_t)(n > 0 ? n : 1) * L, "wind record");
    WT_ALLOC(a->ctx, iv, (size_t)(n > 0 ? n : 1) * L, "wind record");
    const int64_t d2[2] = {n, L}, dl[1] = {L};
    WT_TRY(wt_h5_write(w, NAME("wind_altitude"), WT_H5_F64, WT_H5_F64, 1, dl, a->wind_alt, "m",
                       "the reconstruction layers whose wind is measured on their own estimates (learn_wind = aligned)"));
#define ROWS(name, expr, unit, desc)                                                                                   \
    do {                                                                                                               \
        for (int u = 0; u < n; u++)                                                                                    \
            for (int l = 0; l < L; l++) {                                                                              \
                const wt_adapt_update *p = &a->up[u];                                                                  \
                v[(size_t)u * L + l] = (expr);                                                                         \
            }                                                                                                          \
        WT_TRY(wt_h5_write(w, NAME(name), WT_H5_F64, WT_H5_F64, 2, d2, v, unit, desc));                           \
    } while (0)
    ROWS("wind_vx", p->wind_vx[l], "m/s", "each layer's wind after the update, x [update, layer of wind_altitude] (the "
         "estimate where wind_valid, else the wind it kept)");
    ROWS("wind_vy", p->wind_vy[l], "m/s", "the same, y");
    ROWS("wind_speed", hypot(p->wind_vx[l], p->wind_vy[l]), "m/s", "the same, speed");
    ROWS("wind_direction", atan2(p->wind_vy[l], p->wind_vx[l]) * 180.0 / M_PI, "deg", "the same, direction of motion "
         "counter-clockwise from +x");
    ROWS("wind_sigma_x", p->wind_sx[l], "m/s", "the estimate's uncertainty, x: the spread of its batches' estimates / "
         "sqrt(batches) (0: not estimated)");
    ROWS("wind_sigma_y", p->wind_sy[l], "m/s", "the same, y");
#undef ROWS
    for (int u = 0; u < n; u++)
        for (int l = 0; l < L; l++) iv[(size_t)u * L + l] = a->up[u].wind_valid[l];
    WT_TRY(wt_h5_write(w, NAME("wind_valid"), WT_H5_I64, WT_H5_I64, 2, d2, iv, "", "1: the layer's wind estimated at "
                       "this update; 0: no clear correlation peak, the wind kept"));
#undef NAME
fail:
    wt_free(a->ctx, v);
    wt_free(a->ctx, iv);
    return st;
}

int wt_adapt_copy_record(const wt_adapt *a, wt_adapt **out)
{
    int st = WT_OK;
    wt_adapt *c = NULL;
    *out = NULL;
    WT_ALLOC(a->ctx, c, 1, "learning record");
    *c = *a;
    c->L = NULL, c->M = NULL, c->est = NULL, c->owned = NULL, c->pending = NULL, c->up = NULL, c->wind = NULL;
    c->maxup = a->nup > 0 ? a->nup : 1;
    WT_ALLOC(a->ctx, c->up, c->maxup, "learning record");
    if (a->nup > 0) memcpy(c->up, a->up, (size_t)a->nup * sizeof *a->up);
    *out = c;
    return WT_OK;
fail:
    wt_adapt_free(c);
    return st;
}

int wt_adapt_write(const wt_adapt *a, wt_h5_writer *w, const char *group)
{
    int st = WT_OK;
    char path[256];
#define NAME(s) (snprintf(path, sizeof path, "%s/%s", group, s), path)
    const int n = a->nup, na = a->na;
    double *v = NULL;
    int64_t *iv = NULL;
    WT_ALLOC(a->ctx, v, (size_t)(n > 0 ? n : 1) * (na > 0 ? na : 1), "update record");
    WT_ALLOC(a->ctx, iv, n > 0 ? n : 1, "update record");
    const int64_t d1[1] = {n}, d2[2] = {n, na}, dg[1] = {na};
    WT_TRY(wt_h5_write_int64(w, NAME("every_frames"), a->par.every, "frames", a->par.follow_truth
                             ? "frames between two updates of the oracle's model to the truth's state (a changing night; "
                               "recon.atmosphere.update_s)"
                             : "frames between two estimates (recon.atmosphere.update_s)"));
    WT_TRY(wt_h5_write(w, NAME("altitude"), WT_H5_F64, WT_H5_F64, 1, dg, a->alt, "m", "the learning grid's altitudes"));
    if (a->par.grid_layers && !a->par.follow_truth)
        WT_TRY(wt_h5_write_double(w, NAME("grid_merge_m"), a->merge, "m", "a default grid point closer than this to "
                                  "a reconstructor altitude was dropped (recon.atmosphere.learn_grid = \"layers\")"));
    WT_TRY(wt_h5_write_double(w, NAME("model_setup_s"), a->model_setup, "s", "wall time of the learning grid's "
                              "response maps and normal matrix (once, at the start)"));
#define COL(name, field, unit, desc)                                                                                    \
    do {                                                                                                               \
        for (int u = 0; u < n; u++) v[u] = a->up[u].field;                                                           \
        WT_TRY(wt_h5_write(w, NAME(name), WT_H5_F64, WT_H5_F64, 1, d1, v, unit, desc));                          \
    } while (0)
    COL("night_s", night, "s", "night time of each estimate (after its last frame)");
    COL("r0", r0, "m", "estimated r0 at 500 nm");
    COL("r0_sigma", r0_sigma, "m", "the estimate's uncertainty: spread of the batches' estimates / sqrt(batches), times "
                                   "sqrt(max(1, tau / batch)) for the screens the frames saw (tau = D sum f / v at the "
                                   "learning grid's wind; core/model/learn.h)");
    COL("r0_raw", r0_raw, "m", "this estimate alone (r0 is after the memory's average, recon.atmosphere.learn_memory)");
    COL("fit_s", fit_s, "s", "wall time of the fit");
    COL("model_s", model_s, "s", "pcg3/cg9: wall time of the reconstructor's new model (priors, model error, noise)");
    COL("precond_s", precond_s, "s", "pcg3/cg9: wall time of the preconditioner rebuilt for it");
    COL("build_s", build_s, "s", "mvm: wall time of its control matrix's build (0: never built)");
#undef COL
    for (int u = 0; u < n; u++)
        for (int k = 0; k < na; k++) v[(size_t)u * na + k] = a->up[u].fraction[k];
    WT_TRY(wt_h5_write(w, NAME("fraction"), WT_H5_F64, WT_H5_F64, 2, d2, v, "", "estimated Cn2 fractions [update, "
                       "altitude of the grid's altitude beside it]"));
    if (a->nwl > 0) WT_TRY(wind_write(a, w, n, group));
    for (int u = 0; u < n; u++) iv[u] = a->up[u].frame;
    WT_TRY(wt_h5_write(w, NAME("frame"), WT_H5_I64, WT_H5_I64, 1, d1, iv, "", "the frame after which each estimate "
                       "was made"));
    for (int u = 0; u < n; u++) iv[u] = a->up[u].applied_frame;
    WT_TRY(wt_h5_write(w, NAME("applied_frame"), WT_H5_I64, WT_H5_I64, 1, d1, iv, "", "the first frame that used it "
                       "(pcg3/cg9: the next; mvm: when its build was finished; -1: never, replaced while waiting)"));
#undef NAME
fail:
    wt_free(a->ctx, v);
    wt_free(a->ctx, iv);
    return st;
}
