/* sim/loop.c: closed-loop MCAO simulation with POLC (SPEC §7, paper Algorithm POLC), with a single
 * integrator gain g or one per wavelet scale of the commands (G, core/op/scale_gain.h). */
#include "loop.h"

#include <math.h>
#include <string.h>

#include "../runtime/control.h"
#include "../core/model/fitting.h"
#include "../core/model/interaction.h"
#include "../core/model/sensing.h"
#include "../core/op/noise.h"
#include "../core/op/projection.h"
#include "../core/op/pupil.h"
#include "atmosphere.h"
#include "focus_stage.h"
#include "wfs.h"

#define NOISE_STREAM_BASE (1ULL << 32)
#define EVAL_GROUP 4 /* evaluation directions per work item of the closed loop's sensor/evaluation region */

struct wt_loop {
    wt_context *ctx;
    const wt_system *sys;
    wt_loop_params par;
    wt_loop_options opt;
    wt_atmosphere *atm;
    wt_night *night;              /* the truth's changing night (NULL: the atmosphere fixed) */
    wt_grid fine;                 /* fine simulation grid over the pupil */
    int64_t nfine;
    uint8_t *pupil;               /* fine points inside the annulus */
    int nlos;                     /* lines of sight: sensors then evaluation directions */
    wt_wfs **wfs;                 /* per sensor: truth Shack–Hartmann */
    wt_noise **noise;             /* per sensor: truth noise (τ = 1) */
    uint8_t **dmask;              /* per diffractive sensor: the fine points its pupil samples read (else NULL) */
    wt_projection **dm;           /* per line of sight: DMs on the fine grid (with ground: DMs 1.. only) */
    int ground;                   /* 1: DM 0 is at altitude 0: its term is the same along every line of sight */
    wt_projection *dm0;           /* ground: DM 0 on the union of the lines of sight's masks */
    double *t0;                   /* ground: its term of this frame, 0 + H_0 (-a) (nfine) */
    int64_t **runs;               /* ground: per line of sight, its masked runs (start, end) in the fine grid */
    int *nruns;
    double *opd;                  /* nlos x nfine */
    wt_atmosphere_los *los;       /* per line of sight: source, mask and OPD map for the batched projection */
    double *dm_grids;             /* expanded applied commands */
    wt_interaction *ia;
    wt_reconstructor *rec;
    wt_control *ctl;              /* the control law: the delay's command queue and the integrator (g or G) */
    double *s, *s_ol, *a_rec, *applied;
    double *rms;                  /* ndir */
    double field_strehl;
    wt_strehl_le le;
    long t;
    wt_loop_times times;
    wt_fitting *fit;              /* perfect_fit: the fitting of given maps */
    double *maps;                 /* perfect_fit: true OPD along each evaluation direction on its samples */
    double *dm_opd;               /* true_polc: per sensor, −(the DM shapes along its line of sight) (nsensors x nfine) */
    double *s_dm;                 /* true_polc: the truth sensors' slopes of dm_opd (nslopes) */
    wt_adapt *adapt;              /* the closed loop learns its atmosphere (par.learn.every > 0), else NULL */
    wt_sodium_drive *sodium;      /* the sodium sequence / the loop's LGS reference (NULL: fixed, static) */
    wt_focus_stage *stage;        /* the LGS WFS focus stage and tip-tilt centring (NULL: none) */
};

static double los_altitude(const wt_loop *lp, int i) { return i < lp->sys->nsensors ? lp->sys->sensors[i].altitude : 0.0; }

static void los_direction(const wt_loop *lp, int i, double *tx, double *ty)
{
    const wt_system *sys = lp->sys;
    if (i < sys->nsensors) {
        *tx = sys->sensors[i].theta_x;
        *ty = sys->sensors[i].theta_y;
    } else {
        *tx = sys->eval_x[i - sys->nsensors];
        *ty = sys->eval_y[i - sys->nsensors];
    }
}

static const uint8_t *los_mask(const wt_loop *lp, int i)
{
    if (i >= lp->sys->nsensors) return lp->pupil;
    return lp->dmask[i] ? lp->dmask[i] : wt_wfs_fine_mask(lp->wfs[i]);
}

/* The DM projections. A DM at altitude 0 is seen the same way from every source and direction
 * (cone factor 1, shift θ·0): its bilinear term at a fine point is the same number along every line of
 * sight. When DM 0 is such a DM its term is computed once per frame on the union of the masks (t0) and
 * added to each map before the other DMs' terms, so each point still gets its terms in DM order:
 * o + t (the per-line-of-sight projection) and o + (0 + t) (t0) are the same number since o is never
 * -0 (the atmosphere sets the maps to 0 + its first term). */
static int dm_alloc(wt_loop *lp)
{
    wt_context *ctx = lp->ctx;
    const wt_dm *dm = lp->sys->dm;
    int st = WT_OK;
    uint8_t *all = NULL;
    WT_ALLOC(ctx, lp->dm, lp->nlos, "DM projections");
    lp->ground = dm->ndms >= 1 && dm->altitude[0] == 0.0;
    for (int i = 0; i < lp->nlos; i++) {
        double tx, ty;
        los_direction(lp, i, &tx, &ty);
        if (!lp->ground)
            WT_TRY(wt_dm_influence_alloc(ctx, dm, los_altitude(lp, i), tx, ty, &lp->fine, los_mask(lp, i), &lp->dm[i]));
        else if (dm->ndms > 1)
            WT_TRY(wt_projection_alloc(ctx, dm->ndms - 1, dm->grid + 1, dm->altitude + 1, los_altitude(lp, i), tx, ty,
                                       &lp->fine, los_mask(lp, i), 1, &lp->dm[i]));
    }
    if (!lp->ground) return WT_OK;
    const int64_t nf = lp->nfine;
    WT_ALLOC(ctx, all, nf, "DM mask union");
    WT_ALLOC(ctx, lp->runs, lp->nlos, "DM runs");
    WT_ALLOC(ctx, lp->nruns, lp->nlos, "DM runs");
    for (int i = 0; i < lp->nlos; i++) {
        const uint8_t *m = los_mask(lp, i);
        int n = 0;
        for (int pass = 0; pass < 2; pass++) {
            n = 0;
            for (int64_t row = 0; row < nf; row += lp->fine.nx)
                for (int64_t k = row; k < row + lp->fine.nx;) {
                    if (!m[k]) {
                        k++;
                        continue;
                    }
                    int64_t a = k;
                    while (k < row + lp->fine.nx && m[k]) all[k++] = 1;
                    if (pass) lp->runs[i][2 * n] = a, lp->runs[i][2 * n + 1] = k;
                    n++;
                }
            if (!pass) WT_ALLOC(ctx, lp->runs[i], 2 * (size_t)n + 1, "DM runs");
        }
        lp->nruns[i] = n;
    }
    WT_TRY(wt_projection_alloc(ctx, 1, dm->grid, dm->altitude, 0.0, 0.0, 0.0, &lp->fine, all, 1, &lp->dm0));
    WT_ALLOC(ctx, lp->t0, nf, "ground DM term");
fail:
    wt_free(ctx, all);
    return st;
}

/* t0 = 0 + the ground DM's term of the applied commands (after wt_dm_expand) */
static void dm_ground(wt_loop *lp)
{
    if (!lp->ground) return;
    memset(lp->t0, 0, (size_t)lp->nfine * sizeof *lp->t0);
    wt_projection_apply(lp->dm0, -1.0, lp->dm_grids, lp->t0);
}

/* o −= the DM shapes along line of sight i, on its masked points */
static void dm_subtract(const wt_loop *lp, int i, double *o)
{
    if (!lp->ground) {
        wt_projection_apply(lp->dm[i], -1.0, lp->dm_grids, o);
        return;
    }
    const int64_t *r = lp->runs[i];
    const double *restrict t0 = lp->t0;
    for (int k = 0; k < lp->nruns[i]; k++)
        for (int64_t p = r[2 * k]; p < r[2 * k + 1]; p++) o[p] += t0[p];
    if (lp->dm[i]) wt_projection_apply(lp->dm[i], -1.0, lp->dm_grids + wt_grid_size(&lp->sys->dm->grid[0]), o);
}

int wt_loop_alloc_params(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, const wt_loop_params *par,
                         wt_loop **out)
{
    int st = WT_OK;
    wt_loop *lp = NULL;
    *out = NULL;
    WT_ALLOC(ctx, lp, 1, "closed loop");
    lp->ctx = ctx;
    lp->sys = sys;
    lp->par = *par;
    lp->opt = *opt;
    lp->nlos = sys->nsensors + sys->neval;

    /* fine grid: p points per subaperture, subaperture corners on fine points */
    const int p = par->points_per_subaperture;
    lp->fine = wt_grid_centred(sys->n * p + 1, sys->d / p);
    lp->nfine = wt_grid_size(&lp->fine);
    WT_ALLOC(ctx, lp->pupil, lp->nfine, "pupil mask");
    wt_pupil_mask_points(par->diameter, par->obstruction, &lp->fine, lp->pupil);

    /* atmosphere: one periodic screen size for all layers, twice the widest footprint */
    double thmax = 0.0;
    for (int i = 0; i < lp->nlos; i++) {
        double tx, ty;
        los_direction(lp, i, &tx, &ty);
        thmax = fmax(thmax, hypot(tx, ty));
    }
    wt_atmosphere_params ap = par->atmosphere;
    double htop = ap.altitudes[ap.nlayers - 1];
    int n = 0;
    WT_TRY(wt_atmosphere_recommend_size(ctx, par->diameter + 2.0 * htop * thmax + 2.0 * lp->fine.dx, lp->fine.dx, &n));
    ap.n = n;
    ap.delta = lp->fine.dx;
    ap.seed = opt->seed;
    ap.no_subharmonics = 0;
    WT_TRY(wt_atmosphere_alloc(ctx, &ap, &lp->atm));
    if (par->night.source != WT_NIGHT_NONE) WT_TRY(wt_night_alloc(ctx, &par->night, &lp->night));

    WT_ALLOC(ctx, lp->wfs, sys->nsensors, "truth sensors");
    WT_ALLOC(ctx, lp->noise, sys->nsensors, "truth noise");
    WT_ALLOC(ctx, lp->dmask, sys->nsensors, "diffractive sensor masks");
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        if (s->diffr) {
            /* the diffractive truth: the system's spot and centroider (core/model/sensing.h), fed by the OPD
             * interpolated from the fine grid at its pupil samples */
            WT_ALLOC(ctx, lp->dmask[m], lp->nfine, "diffractive sensor mask");
            WT_TRY(wt_sensing_fine_mask(s->diffr, &lp->fine, lp->dmask[m]));
            continue;
        }
        WT_TRY(wt_wfs_alloc(ctx, par->diameter, par->obstruction, sys->n, sys->d, p, sys->valid,
                            s->kind == WT_SENSOR_LGS ? 0 : s->subapertures, s->tilt, &lp->wfs[m]));
        if (wt_wfs_nslopes(lp->wfs[m]) != s->nslopes) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "%s: truth sensor has %d slopes, the model %d", s->name,
                          wt_wfs_nslopes(lp->wfs[m]), s->nslopes);
            goto fail;
        }
        /* the truth elongation is the physical one: τ = 1 (SPEC §4) */
        WT_TRY(wt_noise_alloc_scaled(ctx, s->nsub, s->sigma2, s->noise_scale, s->spot_fwhm, s->beta, 1.0, 0,
                                     &lp->noise[m]));
    }
    WT_TRY(dm_alloc(lp));
    WT_ALLOC(ctx, lp->opd, (size_t)lp->nlos * lp->nfine, "OPD maps");
    WT_ALLOC(ctx, lp->los, lp->nlos, "lines of sight");
    for (int i = 0; i < lp->nlos; i++) {
        wt_atmosphere_los *l = &lp->los[i];
        los_direction(lp, i, &l->theta_x, &l->theta_y);
        l->source_altitude = los_altitude(lp, i);
        l->mask = los_mask(lp, i);
        l->out = lp->opd + (size_t)i * lp->nfine;
        l->set = 1;
    }
    WT_ALLOC(ctx, lp->dm_grids, wt_dm_grid_points(sys->dm), "DM grids");
    WT_TRY(wt_interaction_alloc(ctx, sys, &lp->ia));
    if (opt->recon == WT_RECON_MVM) {
        if (!opt->mvm) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "the mvm reconstructor needs a control matrix");
            goto fail;
        }
        WT_TRY(wt_reconstructor_alloc_mvm(ctx, sys, opt->mvm, &lp->rec));
    } else {
        WT_TRY(wt_reconstructor_alloc(ctx, sys, opt->recon, &par->recon, &lp->rec));
    }
    {
        const wt_control_params cp = {.delay = par->delay, .gain = par->gain, .scale_gain = par->scale_gain,
                                      .direct = lp->rec && wt_reconstructor_integrates(lp->rec)};
        WT_TRY(wt_control_alloc(ctx, sys, &cp, &lp->ctl));
    }
    WT_ALLOC(ctx, lp->s, sys->nslopes, "slopes");
    WT_ALLOC(ctx, lp->s_ol, sys->nslopes, "pseudo-open-loop slopes");
    WT_ALLOC(ctx, lp->a_rec, sys->nact, "reconstructed commands");
    WT_ALLOC(ctx, lp->applied, sys->nact, "applied commands");
    WT_ALLOC(ctx, lp->rms, sys->neval, "residual rms");
    wt_strehl_le_init(&lp->le, sys->neval);
    if (opt->open_loop < WT_LOOP_CLOSED || opt->open_loop > WT_LOOP_OPEN_POLC) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "open_loop = %d: must be WT_LOOP_CLOSED, _OPEN_FLAT or _OPEN_POLC",
                      opt->open_loop);
        goto fail;
    }
    if (opt->first_frame < 0 || (opt->first_frame > 0 && opt->open_loop != WT_LOOP_OPEN_FLAT) ||
        (opt->perfect_fit && opt->open_loop != WT_LOOP_OPEN_FLAT)) {
        st = WT_ERROR(ctx, WT_ERR_INVALID,
                      "first_frame %ld / perfect_fit %d: options of the flat open loop only (open_loop = %d)",
                      opt->first_frame, opt->perfect_fit, opt->open_loop);
        goto fail;
    }
    if (opt->true_polc) {
        for (int m = 0; m < sys->nsensors; m++)
            if (sys->sensors[m].diffr || opt->open_loop) {
                st = WT_ERROR(ctx, WT_ERR_INVALID, "true_polc: a closed loop of geometric sensors only (%s)",
                              opt->open_loop ? "open loop" : sys->sensors[m].name);
                goto fail;
            }
        WT_ALLOC(ctx, lp->dm_opd, (size_t)sys->nsensors * lp->nfine, "true POLC maps");
        WT_ALLOC(ctx, lp->s_dm, sys->nslopes, "true POLC slopes");
    }
    if (par->learn.every > 0 && opt->open_loop == WT_LOOP_CLOSED)
        WT_TRY(wt_adapt_alloc(ctx, sys, opt->recon, &par->learn, opt->rebuild, opt->rebuild_user, par->learn_max_updates,
                              &lp->adapt));
    if (lp->adapt) WT_TRY(wt_adapt_wind_alloc(lp->adapt, lp->rec));
    lp->t = opt->first_frame;
    {
        wt_sodium_drive_params sp = par->sodium;
        sp.first_frame = opt->first_frame;
        WT_TRY(wt_sodium_drive_alloc(ctx, sys, &sp, &lp->sodium));
    }
    if (par->lgs_focus_stage_gain > 0.0 && opt->open_loop == WT_LOOP_CLOSED)
        WT_TRY(wt_focus_stage_alloc(ctx, sys, par->lgs_focus_stage_gain, par->settle_frames, &lp->stage));
    if (opt->perfect_fit > 0) {
        WT_TRY(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &par->perfect_fit, &lp->fit));
        WT_ALLOC(ctx, lp->maps, (size_t)sys->neval * wt_grid_size(wt_fitting_sample_grid(lp->fit)), "fitting maps");
    }
    *out = lp;
    return WT_OK;
fail:
    wt_loop_free(lp);
    return st;
}

void wt_loop_free(wt_loop *lp)
{
    if (!lp) return;
    wt_context *ctx = lp->ctx;
    wt_atmosphere_free(lp->atm);
    wt_night_free(lp->night);
    wt_sodium_drive_free(lp->sodium);
    wt_focus_stage_free(lp->stage);
    if (lp->wfs)
        for (int m = 0; m < lp->sys->nsensors; m++) wt_wfs_free(lp->wfs[m]);
    if (lp->dmask)
        for (int m = 0; m < lp->sys->nsensors; m++) wt_free(ctx, lp->dmask[m]);
    wt_free(ctx, lp->dmask);
    if (lp->noise)
        for (int m = 0; m < lp->sys->nsensors; m++) wt_noise_free(lp->noise[m]);
    if (lp->dm)
        for (int i = 0; i < lp->nlos; i++) wt_projection_free(lp->dm[i]);
    if (lp->runs)
        for (int i = 0; i < lp->nlos; i++) wt_free(ctx, lp->runs[i]);
    wt_free(ctx, lp->runs);
    wt_free(ctx, lp->nruns);
    wt_projection_free(lp->dm0);
    wt_free(ctx, lp->t0);
    wt_control_free(lp->ctl);
    wt_free(ctx, lp->wfs);
    wt_free(ctx, lp->noise);
    wt_free(ctx, lp->dm);
    wt_free(ctx, lp->pupil);
    wt_free(ctx, lp->opd);
    wt_free(ctx, lp->los);
    wt_free(ctx, lp->dm_grids);
    wt_interaction_free(lp->ia);
    wt_reconstructor_free(lp->rec);
    wt_adapt_free(lp->adapt); /* (after the reconstructor: it may hold the matrix the adapt built) */
    wt_free(ctx, lp->s);
    wt_free(ctx, lp->s_ol);
    wt_free(ctx, lp->a_rec);
    wt_free(ctx, lp->applied);
    wt_free(ctx, lp->rms);
    wt_fitting_free(lp->fit);
    wt_free(ctx, lp->maps);
    wt_free(ctx, lp->dm_opd);
    wt_free(ctx, lp->s_dm);
    wt_free(ctx, lp);
}


/* o = the turbulence along line of sight i at `time` on the fine grid (masked points; zero without it) */
static int turbulence(const wt_loop *lp, int i, double time, double *o)
{
    double tx, ty;
    los_direction(lp, i, &tx, &ty);
    const uint8_t *mask = los_mask(lp, i);
    for (int64_t k = 0; k < lp->nfine; k++)
        if (mask[k]) o[k] = 0.0;
    if (lp->opt.no_turbulence) return WT_OK;
    return wt_atmosphere_project(lp->atm, time, los_altitude(lp, i), tx, ty, &lp->fine, mask, 1.0, o);
}

/* Sensor i measures the OPD o of frame t: its slopes in lp->s, with noise and LGS tip-tilt when on */
static void sense(wt_loop *lp, int i, long t, const double *o)
{
    const wt_sensor *s = &lp->sys->sensors[i];
    double *sl = lp->s + s->offset;
    if (s->diffr) {
        /* the LGS jitter is a tilt of the OPD (it moves the spots), from the same stream as the geometric
         * sensor's; the images, their noise and the centroider run in sense_diffractive */
        double jx = 0.0, jy = 0.0;
        if (lp->opt.noise && s->kind == WT_SENSOR_LGS && lp->par.lgs_tt_jitter > 0.0) {
            wt_rng rng;
            wt_rng_init(&rng, lp->opt.seed, NOISE_STREAM_BASE + 64ULL * (uint64_t)t + (uint64_t)i);
            jx = lp->par.lgs_tt_jitter * wt_rng_normal(&rng);
            jy = lp->par.lgs_tt_jitter * wt_rng_normal(&rng);
        }
        wt_sensing_sample(s->diffr, &lp->fine, o, jx, jy);
        return;
    }
    wt_wfs_measure(lp->wfs[i], o, sl);
    if (lp->opt.noise) {
        wt_rng rng;
        wt_rng_init(&rng, lp->opt.seed, NOISE_STREAM_BASE + 64ULL * (uint64_t)t + (uint64_t)i);
        wt_noise_sample(lp->noise[i], &rng, sl);
        if (s->kind == WT_SENSOR_LGS && lp->par.lgs_tt_jitter > 0.0)
            wt_wfs_add_tiptilt(lp->wfs[i], &rng, lp->par.lgs_tt_jitter, sl);
    }
}

/* The diffractive sensors of frame t, after sense() sampled their OPD: images, noise (subaperture s of
 * sensor m from WT_SPOT_STREAM(2^32 + 64 t + m, s)), centroider. Outside parallel regions (the spot and
 * centroider run their own OpenMP loops over subapertures); allocates nothing. */
static int sense_diffractive(wt_loop *lp, long t, int nsens)
{
    const wt_system *sys = lp->sys;
    for (int i = 0; i < nsens; i++) {
        const wt_sensor *s = &sys->sensors[i];
        if (!s->diffr) continue;
        /* without turbulence (the reconstruction of pure noise) the spots are the reference, the mean spot in
         * the loop, so that the noise is the centroider's at its operating point (the LGS jitter, a tilt the
         * reconstructor removes, is left out there) */
        const uint64_t stream = NOISE_STREAM_BASE + 64ULL * (uint64_t)t + (uint64_t)i;
        int st = lp->opt.no_turbulence
                     ? wt_sensing_detect_reference(s->diffr, lp->opt.noise, lp->opt.seed, stream, lp->s + s->offset)
                     : wt_sensing_detect(s->diffr, lp->opt.noise, lp->opt.seed, stream, lp->s + s->offset);
        if (st < 0) return st;
    }
    return WT_OK;
}

/* Evaluation of a frame: field Strehl, and the long-exposure sums after the settle period */
static void evaluate(wt_loop *lp)
{
    const wt_system *sys = lp->sys;
    double fs = 0.0;
    for (int j = 0; j < sys->neval; j++) fs += wt_strehl_marechal(lp->rms[j], lp->par.eval_wavelength);
    lp->field_strehl = fs / sys->neval;
    if (lp->t >= lp->par.settle_frames) wt_strehl_le_add(&lp->le, lp->rms, lp->par.eval_wavelength);
}

/* Instantaneous open loop (budget modes): the sensors see the turbulence of frame t with the DMs flat;
 * a_t = R s_t, or the fit of the true turbulence along the evaluation directions, is applied to the
 * evaluation of the same frame. */
static int step_open_loop(wt_loop *lp)
{
    const wt_system *sys = lp->sys;
    const long t = lp->t;
    const double time = (double)t / lp->par.rate;
    const int64_t nf = lp->nfine;
    const int nsens = lp->opt.perfect_fit ? 0 : sys->nsensors;
    int err = WT_OK;
    double t0 = wt_time_now();
#pragma omp parallel for schedule(dynamic, 1) reduction(min : err)
    for (int i = 0; i < lp->nlos; i++) {
        if (i < sys->nsensors && i >= nsens) continue;
        double *o = lp->opd + (size_t)i * nf;
        int e = turbulence(lp, i, time, o);
        if (e < err) err = e;
        if (i < nsens) sense(lp, i, t, o);
    }
    if (err < 0) return err;
    if ((err = sense_diffractive(lp, t, nsens)) < 0) return err;
    double t1 = wt_time_now();
    lp->times.sensors += t1 - t0;
    if (lp->opt.perfect_fit) {
        const wt_grid *g = wt_fitting_sample_grid(lp->fit);
        const uint8_t *m = wt_fitting_sample_mask(lp->fit);
        const int64_t ng = wt_grid_size(g);
#pragma omp parallel for schedule(dynamic, 1) reduction(min : err)
        for (int j = 0; j < sys->neval; j++) {
            double *o = lp->maps + (size_t)j * ng;
            memset(o, 0, (size_t)ng * sizeof *o);
            int e = lp->opt.no_turbulence ? WT_OK
                                          : wt_atmosphere_project(lp->atm, time, 0.0, sys->eval_x[j], sys->eval_y[j], g, m, 1.0, o);
            if (e < err) err = e;
        }
        if (err < 0) return err;
        /* warm start: a_rec still holds the previous frame's fit */
        err = wt_fitting_solve_maps(lp->fit, lp->maps, lp->a_rec, lp->opt.perfect_fit, 0.0, NULL);
        lp->times.fitting += wt_time_now() - t1;
    } else {
        memcpy(lp->s_ol, lp->s, (size_t)sys->nslopes * sizeof *lp->s_ol);
        err = wt_reconstructor_apply(lp->rec, lp->s_ol, lp->a_rec);
        lp->times.reconstruction += wt_time_now() - t1;
    }
    if (err < 0) return err;
    double t2 = wt_time_now();
    memcpy(lp->applied, lp->a_rec, (size_t)sys->nact * sizeof *lp->applied);
    wt_dm_expand(sys->dm, lp->applied, lp->dm_grids);
    dm_ground(lp);
#pragma omp parallel for schedule(dynamic, 1)
    for (int j = 0; j < sys->neval; j++) {
        double *o = lp->opd + (size_t)(sys->nsensors + j) * nf;
        dm_subtract(lp, sys->nsensors + j, o);
        lp->rms[j] = wt_strehl_rms(o, lp->pupil, nf);
    }
    evaluate(lp);
    lp->times.evaluation += wt_time_now() - t2;
    lp->t++;
    return WT_OK;
}

/* The turbulence of `time` along every line of sight into lp->opd, in one batched projection (each layer
 * read once per row band for all lines of sight; the same bits as one projection per line of sight), or
 * zero on the masked points without turbulence; its time goes to times.atmosphere. */
static int project_all(wt_loop *lp, double time)
{
    const double t0 = wt_time_now();
    int err = WT_OK;
    if (!lp->opt.no_turbulence) /* sets the masked points (los[i].set) */
        err = wt_atmosphere_project_many(lp->atm, time, lp->nlos, lp->los, &lp->fine, 1.0);
    else
        for (int i = 0; i < lp->nlos; i++)
            for (int64_t k = 0; k < lp->nfine; k++)
                if (lp->los[i].mask[k]) lp->los[i].out[k] = 0.0;
    lp->times.atmosphere += wt_time_now() - t0;
    return err;
}

/* Instantaneous pseudo-open loop (WT_LOOP_OPEN_POLC, loop.h): the sensors see φ_t minus the previous
 * frame's reconstruction a_{t−1} (lp->applied), â_t = R (s_t + Â a_{t−1}) is evaluated against φ_t in the
 * same frame and applied in the next. The sensors' residual is a closed loop's (the change of φ over one
 * frame plus the reconstruction error), so a diffractive sensor works in its linear range. */
static int step_polc_instant(wt_loop *lp)
{
    const wt_system *sys = lp->sys;
    const long t = lp->t;
    const double time = (double)t / lp->par.rate;
    const int64_t nf = lp->nfine;
    int err = WT_OK;
    wt_dm_expand(sys->dm, lp->applied, lp->dm_grids);
    if ((err = project_all(lp, time)) < 0) return err;
    double t1 = wt_time_now();
    dm_ground(lp);
#pragma omp parallel for schedule(dynamic, 1) num_threads(wt_context_threads(lp->ctx))
    for (int i = 0; i < sys->nsensors; i++) {
        double *o = lp->opd + (size_t)i * nf;
        dm_subtract(lp, i, o);
        sense(lp, i, t, o);
    }
    if ((err = sense_diffractive(lp, t, sys->nsensors)) < 0) return err;
    double t2 = wt_time_now();
    lp->times.sensors += t2 - t1;
    memcpy(lp->s_ol, lp->s, (size_t)sys->nslopes * sizeof *lp->s_ol);
    wt_interaction_apply(lp->ia, 1.0, lp->applied, lp->s_ol);
    if ((err = wt_reconstructor_apply(lp->rec, lp->s_ol, lp->a_rec)) < 0) return err;
    double t3 = wt_time_now();
    lp->times.reconstruction += t3 - t2;
    if (lp->opt.recon == WT_RECON_NONE) memset(lp->a_rec, 0, (size_t)sys->nact * sizeof *lp->a_rec);
    for (int64_t k = 0; k < sys->nact; k++)
        if (!isfinite(lp->a_rec[k]))
            return WT_ERROR(lp->ctx, WT_ERR_NUMERIC, "frame %ld: command %lld is %g (the pseudo-open loop diverged)", t,
                            (long long)k, lp->a_rec[k]);
    memcpy(lp->applied, lp->a_rec, (size_t)sys->nact * sizeof *lp->applied);
    wt_dm_expand(sys->dm, lp->applied, lp->dm_grids);
    dm_ground(lp);
#pragma omp parallel for schedule(dynamic, 1) num_threads(wt_context_threads(lp->ctx))
    for (int j = 0; j < sys->neval; j++) {
        double *o = lp->opd + (size_t)(sys->nsensors + j) * nf;
        dm_subtract(lp, sys->nsensors + j, o);
        lp->rms[j] = wt_strehl_rms(o, lp->pupil, nf);
    }
    evaluate(lp);
    lp->times.evaluation += wt_time_now() - t3;
    lp->t++;
    return WT_OK;
}

int wt_loop_step(wt_loop *lp)
{
    /* a changing night: the truth's screens scaled and moved to this frame's state */
    if (lp->night) {
        const int e = wt_night_drive(lp->night, lp->atm, lp->t);
        if (e < 0) return e;
    }
    /* the sodium layer: the truth's spots of this frame's profile, the reference rebuilt when it is time */
    if (lp->sodium) {
        const int e = wt_sodium_drive_frame(lp->sodium, lp->t, lp->opt.recon == WT_RECON_NONE ? NULL : lp->rec, lp->stage);
        if (e < 0) return e;
    }
    /* the diffractive sensors' in-loop gains count the frames the Strehl averages */
    if (lp->t == lp->par.settle_frames)
        for (int i = 0; i < lp->sys->nsensors; i++)
            if (lp->sys->sensors[i].diffr) wt_sensing_gain_reset(lp->sys->sensors[i].diffr);
    if (lp->opt.open_loop == WT_LOOP_OPEN_POLC) return step_polc_instant(lp);
    if (lp->opt.open_loop) return step_open_loop(lp);
    const wt_system *sys = lp->sys;
    const long t = lp->t;
    const double time = (double)t / lp->par.rate;
    const int64_t nf = lp->nfine;
    int st = WT_OK;

    /* a learning MVM loop: the matrix of an earlier estimate whose build is finished by now */
    if (lp->adapt && (st = wt_adapt_swap(lp->adapt, t, &lp->rec)) < 0) return st;

    /* a_t: the commands applied during this frame */
    memcpy(lp->applied, wt_control_applied(lp->ctl), (size_t)sys->nact * sizeof *lp->applied);
    wt_dm_expand(sys->dm, lp->applied, lp->dm_grids);

    /* 1. the turbulence along every line of sight (project_all) */
    double c_sens = 0.0, c_eval = 0.0;
    int err = project_all(lp, time);
    if (err < 0) return err;
    double t1 = wt_time_now();

    /* 2.–3. every line of sight in one parallel region: minus the DMs, then the truth sensor with its
     * noise, or the residual rms of the evaluation directions, EVAL_GROUP at a time (the rms sums of a
     * group run side by side: wt_strehl_rms_many). The groups come first, the sensors fill in after them.
     * Per-part CPU times are summed over the threads and the region's wall time is split in their
     * proportion. */
    dm_ground(lp);
    const int ngroups = (sys->neval + EVAL_GROUP - 1) / EVAL_GROUP;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : c_sens, c_eval) num_threads(wt_context_threads(lp->ctx))
    for (int item = 0; item < ngroups + sys->nsensors; item++) {
        double a1 = wt_time_now();
        if (item < ngroups) {
            const int j0 = item * EVAL_GROUP, m = sys->neval - j0 < EVAL_GROUP ? sys->neval - j0 : EVAL_GROUP;
            const double *maps[EVAL_GROUP];
            for (int j = j0; j < j0 + m; j++) {
                const int i = sys->nsensors + j;
                double *o = lp->opd + (size_t)i * nf;
                dm_subtract(lp, i, o);
                maps[j - j0] = o;
            }
            wt_strehl_rms_many(maps, lp->pupil, nf, m, lp->rms + j0);
            c_eval += wt_time_now() - a1;
        } else {
            const int i = item - ngroups;
            double *o = lp->opd + (size_t)i * nf;
            if (lp->opt.true_polc) {
                /* the truth sensor's slopes of −(DM shapes): its own (exact, linear) interaction */
                double *z = lp->dm_opd + (size_t)i * nf;
                memset(z, 0, (size_t)nf * sizeof *z);
                dm_subtract(lp, i, z);
                wt_wfs_measure(lp->wfs[i], z, lp->s_dm + sys->sensors[i].offset);
            }
            dm_subtract(lp, i, o);
            sense(lp, i, t, o);
            c_sens += wt_time_now() - a1;
        }
    }
    double t2 = wt_time_now(), csum = c_sens + c_eval;
    if (csum > 0.0) {
        lp->times.sensors += (t2 - t1) * c_sens / csum;
        lp->times.evaluation += (t2 - t1) * c_eval / csum;
    }
    if ((st = sense_diffractive(lp, t, sys->nsensors)) < 0) return st;
    if (lp->stage) wt_focus_stage_measure(lp->stage, t, lp->s); /* (it moves at the truth's next rebuild) */
    lp->times.sensors += wt_time_now() - t2;
    t2 = wt_time_now();

    evaluate(lp);
    double t2e = wt_time_now();
    lp->times.evaluation += t2e - t2;

    /* 4. POLC: s_ol = s + Â a_t;  a_{t+d} = a_{t+d-1} + g (R s_ol − a_t), or G (R s_ol − a_t) */
    memcpy(lp->s_ol, lp->s, (size_t)sys->nslopes * sizeof *lp->s_ol);
    if (lp->opt.true_polc)
        for (int64_t k = 0; k < sys->nslopes; k++) lp->s_ol[k] -= lp->s_dm[k];
    else
        wt_interaction_apply(lp->ia, 1.0, lp->applied, lp->s_ol);
    double t3 = wt_time_now();
    lp->times.control += t3 - t2e;
    st = wt_reconstructor_apply(lp->rec, lp->s_ol, lp->a_rec);
    if (st < 0) return st;
    double t4 = wt_time_now();
    double tt, tf;
    wt_reconstructor_last_times(lp->rec, &tt, &tf);
    lp->times.reconstruction += (t4 - t3) - tf;
    lp->times.fitting += tf;
    if (lp->adapt) { /* this frame's s_ol into the estimate; an estimate made now is used from the next frame */
        const double b0 = wt_adapt_build_seconds(lp->adapt);
        wt_night_sample truth; /* (the oracle following a night takes the truth's state of this frame) */
        const int has_truth = wt_loop_truth_state(lp, &truth);
        if ((st = wt_adapt_frame(lp->adapt, t, lp->s_ol, has_truth ? &truth : NULL, lp->rec)) < 0) return st;
        const double t5 = wt_time_now();
        lp->times.learning += t5 - t4 - (wt_adapt_build_seconds(lp->adapt) - b0); /* (a build: latency, simulated) */
        t4 = t5; /* (the control's time below leaves it out) */
    }
    const double *next = wt_control_step(lp->ctl, lp->opt.recon == WT_RECON_NONE ? NULL : lp->a_rec, lp->applied);
    lp->times.control += wt_time_now() - t4;
    for (int64_t k = 0; k < sys->nact; k++)
        if (!isfinite(next[k]))
            return WT_ERROR(lp->ctx, WT_ERR_NUMERIC, "frame %ld: command %lld is %g (the loop diverged)", t,
                            (long long)k, next[k]);
    lp->t++;
    return WT_OK;
}

long wt_loop_frames_done(const wt_loop *lp) { return lp->t; }
const double *wt_loop_slopes(const wt_loop *lp) { return lp->s; }
const double *wt_loop_slopes_ol(const wt_loop *lp) { return lp->s_ol; }
const double *wt_loop_applied(const wt_loop *lp) { return lp->applied; }
const double *wt_loop_rms(const wt_loop *lp) { return lp->rms; }
double wt_loop_field_strehl(const wt_loop *lp) { return lp->field_strehl; }
const wt_strehl_le *wt_loop_le(const wt_loop *lp) { return &lp->le; }
wt_loop_times wt_loop_get_times(const wt_loop *lp) { return lp->times; }
const wt_grid *wt_loop_fine_grid(const wt_loop *lp) { return &lp->fine; }
const uint8_t *wt_loop_pupil_mask(const wt_loop *lp) { return lp->pupil; }
const double *wt_loop_residual(const wt_loop *lp, int j)
{
    return lp->opd + (size_t)(lp->sys->nsensors + j) * lp->nfine;
}
const struct wt_atmosphere *wt_loop_atmosphere(const wt_loop *lp) { return lp->atm; }
const wt_sodium_drive *wt_loop_sodium(const wt_loop *lp) { return lp->sodium; }
const wt_focus_stage *wt_loop_focus_stage(const wt_loop *lp) { return lp->stage; }

int wt_loop_truth_state(const wt_loop *lp, wt_night_sample *out)
{
    if (!lp->night) return 0;
    *out = wt_night_current(lp->night);
    return 1;
}
wt_reconstructor *wt_loop_reconstructor(wt_loop *lp) { return lp->rec; }
const wt_adapt *wt_loop_adapt(const wt_loop *lp) { return lp->adapt; }
