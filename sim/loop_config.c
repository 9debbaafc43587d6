/* sim/loop_config.c: the configuration side of the closed loop (see loop.h): wt_config → the
 * loop's parameters (SPEC §2–§8 keys: rate, delay, gain (gain_levels), simulation sampling, profile, evaluation), so that
 * the loop itself reads no configuration. Calls go one way: this file → loop.c. */
#include "loop.h"

#include <math.h>
#include <string.h>

#include "../runtime/control.h"
#include "../core/model/params.h"
#include "../core/solve/mvm.h"


void wt_loop_night_params(const wt_config *cfg, wt_night_params *p)
{
    const wt_night_config *nc = &cfg->night; /* the night's reference is the configured atmosphere */
    *p = (wt_night_params){.source = nc->source == WT_NIGHT_CFG_FILE     ? WT_NIGHT_FILE
                                     : nc->source == WT_NIGHT_CFG_RANDOM ? WT_NIGHT_RANDOM
                                                                         : WT_NIGHT_NONE,
                           .nlayers = cfg->nlayers, .r0 = cfg->r0, .fraction = cfg->layer_fraction,
                           .wind_speed = cfg->wind_speed, .wind_direction = cfg->wind_direction,
                           .frame_time = 1.0 / cfg->rate, .start = nc->start, .compression = nc->compression,
                           .frames = cfg->frames,
                           .origin = "keys atmosphere.night.*, loop.frames and loop.rate_hz",
                           .file = nc->file, .seed = nc->seed, .correlation_time = nc->correlation_time,
                           .step = nc->step, .r0_rms = nc->r0_rms, .fraction_rms = nc->fraction_rms,
                           .wind_speed_rms = nc->wind_speed_rms, .wind_direction_rms = nc->wind_direction_rms};
}

void wt_loop_params_from_config(const wt_config *cfg, const wt_loop_options *opt, wt_loop_params *par)
{
    memset(par, 0, sizeof *par);
    par->rate = cfg->rate;
    {
        const wt_control_params cp = wt_control_params_from_config(cfg); /* the law every loop and frame API uses */
        par->delay = cp.delay;
        par->gain = cp.gain;
        par->scale_gain = cp.scale_gain;
    }
    par->points_per_subaperture = cfg->points_per_subaperture;
    par->diameter = cfg->diameter;
    par->obstruction = cfg->obstruction;
    par->atmosphere = (wt_atmosphere_params){.nlayers = cfg->nlayers,
                                             .altitudes = cfg->layer_altitude,
                                             .fractions = cfg->layer_fraction,
                                             .wind_speed = cfg->wind_speed,
                                             .wind_direction = cfg->wind_direction,
                                             .r0 = cfg->r0,
                                             .L0 = cfg->L0};
    wt_loop_night_params(cfg, &par->night);
    const wt_night_config *nc = &cfg->night;
    par->sodium = (wt_sodium_drive_params){.sequence = cfg->sodium_sequence,
                                           .sequence_update = cfg->sodium_sequence_update,
                                           .reference = cfg->lgs_reference == 2   ? WT_REFERENCE_PIXELS
                                                      : cfg->lgs_reference == 1 ? WT_REFERENCE_ORACLE
                                                                                : WT_REFERENCE_STATIC,
                                           .reference_update = cfg->lgs_reference_update,
                                           .gain_update = cfg->lgs_gain_update,
                                           .start = nc->start, .frame_time = 1.0 / cfg->rate,
                                           .compression = nc->compression, .frames = cfg->frames,
                                           .origin = "keys atmosphere.night.start_s, atmosphere.night.compression, "
                                                     "loop.frames and loop.rate_hz"};
    par->lgs_tt_jitter = cfg->lgs_tt_jitter;
    par->lgs_focus_stage_gain = cfg->lgs_focus_stage ? cfg->lgs_focus_stage_gain : 0.0;
    par->eval_wavelength = cfg->eval_wavelength;
    par->settle_frames = cfg->settle_frames;
    wt_reconstructor_params_from_config(cfg, opt->recon, opt->iterations, &par->recon);
    if (opt->no_predict) par->recon.predict_lead = 0.0;
    /* the layers' integrator is the closed loop's law; the open loops apply each frame's own reconstruction */
    if (opt->no_predict || opt->open_loop) par->recon.integrator_gain = 0.0;
    par->perfect_fit = wt_fitting_params_from_variant(&cfg->cg9);
    const wt_model_atmosphere_config *m = &cfg->model;
    const int follow = m->source == WT_MODEL_ORACLE && nc->source != WT_NIGHT_CFG_NONE; /* the oracle in a night */
    if ((m->source == WT_MODEL_LEARNED || (follow && opt->recon != WT_RECON_NONE)) && !opt->open_loop) {
        /* in night time: a frame is 1 / rate times the night's compression (atmosphere.night.compression) */
        par->learn = (wt_adapt_params){.every = lround(m->update_s * cfg->rate / cfg->night.compression),
                                       .frame_night = cfg->night.compression / cfg->rate,
                                       .L0 = m->L0,
                                       .latency = m->mvm_latency_s,
                                       .cumulative = m->learn_window == 1,
                                       .run_frames = cfg->frames,
                                       .memory = m->learn_memory,
                                       .nstart = m->nlayers,
                                       .grid_layers = m->learn_grid == 1,
                                       .follow_truth = follow,
                                       .ntruth = cfg->nlayers,
                                       .learn_wind = m->source == WT_MODEL_LEARNED && m->learn_wind == 1,
                                       .frame_dt = 1.0 / cfg->rate};
        for (int k = 0; k < cfg->nlayers; k++) par->learn.truth_alt[k] = cfg->layer_altitude[k];
        /* the layers the estimate is compressed onto: the variant's (an MVM's are pcg3's, what it is built from) */
        const wt_recon_variant_config *v = opt->recon == WT_RECON_CG9 ? &cfg->cg9 : &cfg->pcg3;
        par->learn.nrecon = v->nlayers;
        for (int k = 0; k < v->nlayers; k++) par->learn.recon_alt[k] = v->altitudes[k];
        par->recon.precond.updatable = 1; /* the model changes: its preconditioner is updated, not rebuilt */
        /* its wind: the start model's, as vectors (the learned profile takes it at the nearest altitude) */
        for (int k = 0; k < m->nlayers; k++) {
            par->learn.start_alt[k] = m->altitude[k];
            par->learn.start_vx[k] = m->wind_speed[k] * cos(m->wind_direction[k]);
            par->learn.start_vy[k] = m->wind_speed[k] * sin(m->wind_direction[k]);
        }
        par->learn_max_updates = par->learn.every > 0 ? cfg->frames / par->learn.every + 1 : 1;
    }
}

int wt_loop_alloc(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, wt_loop **out)
{
    const int st = wt_reconstructor_check_mvm_predict(ctx, sys->cfg, opt->recon, opt->mvm ? 0 : opt->no_predict);
    if (st < 0) return st;
    if (opt->recon == WT_RECON_MVM && opt->mvm) { /* the matrix's predictor is the run's: held in R, or not */
        const int predicts = sys->cfg->predict && !opt->no_predict;
        if (opt->mvm->predictive != predicts)
            return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'recon.predict' = %s: this %s with a control matrix %s the "
                            "layers' prediction (build the MVM %s recon.predict)", sys->cfg->path,
                            sys->cfg->predict ? "true" : "false", predicts ? "run predicts" : "run must not predict",
                            opt->mvm->predictive ? "that holds" : "without", predicts ? "with" : "without");
    }
    wt_loop_params par;
    wt_loop_params_from_config(sys->cfg, opt, &par);
    return wt_loop_alloc_params(ctx, sys, opt, &par, out);
}
