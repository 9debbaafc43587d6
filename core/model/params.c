/* core/model/params.c: wt_config → the parameter structs of model (see params.h). */
#include "params.h"

#include <math.h>
#include <string.h>

#include "../op/noise.h"
#include "../op/prior.h"

void wt_tomography_params_from_config(const wt_config *cfg, wt_tomography_params *par)
{
    memset(par, 0, sizeof *par);
    par->alpha = cfg->alpha;
    par->tau = cfg->tau;
    par->wavelet_order = cfg->wavelet_order;
    par->wavelet_levels = cfg->wavelet_levels;
    par->prior_flags = cfg->prior_aliasing ? WT_PRIOR_ALIASED : 0; /* the kind is the variant's (wt_tomography_alloc) */
    /* the reconstructor's own atmosphere (recon.atmosphere), never the simulated one: the oracle's is a copy of it */
    const wt_model_atmosphere_config *m = &cfg->model;
    par->r0 = m->r0;
    par->L0 = m->L0;
    par->natm = m->nlayers;
    for (int k = 0; k < m->nlayers; k++) {
        par->atm_altitude[k] = m->altitude[k];
        par->atm_fraction[k] = m->fraction[k];
    }
    par->model_error = cfg->model_error;
    par->subgrid_error = cfg->subgrid_error;
    par->lgs_focus_removal = cfg->lgs_focus_removal ? (cfg->lgs_focus_mode == 1 ? 2 : 1) : 0;
    par->loop_noise_gain = wt_noise_loop_gain(cfg->gain, cfg->delay);
    par->source = cfg->path;
    par->fft_wisdom = cfg->fft_wisdom;
    par->fft_wisdom_sha256 = cfg->fft_wisdom_sha256;
}

wt_fitting_params wt_fitting_params_from_variant(const wt_recon_variant_config *var)
{
    wt_fitting_params fp = {.regularization = var->fit_regularization,
                            .sampling = var->fit_sampling > 0 ? var->fit_sampling : 1,
                            .solver = var->fit_solver,
                            .factor_float32 = var->fit_factor_precision == 1,
                            .reference = var->fit_kernels == 1};
    return fp;
}

wt_precond_params wt_precond_params_from_variant(const wt_recon_variant_config *var)
{
    wt_precond_params pp = {.kind = var->preconditioner, .coarse_levels = var->coarse_levels,
                            .single = var->operator_precision == 1};
    return pp;
}

void wt_reconstructor_params_from_config(const wt_config *cfg, int kind, int iterations, wt_reconstructor_params *par)
{
    memset(par, 0, sizeof *par);
    par->warm_start = cfg->warm_start;
    if (kind != WT_RECON_PCG3 && kind != WT_RECON_CG9) return;
    const wt_recon_variant_config *v = kind == WT_RECON_PCG3 ? &cfg->pcg3 : &cfg->cg9;
    par->variant = v;
    par->iterations = iterations >= 0 ? iterations : v->iterations;
    par->tolerance = v->tolerance;
    par->fit_iterations = v->fit_iterations;
    wt_tomography_params_from_config(cfg, &par->tomography);
    par->precond = wt_precond_params_from_variant(v);
    par->tomography.space = v->preconditioner == WT_PRECOND_FOURIER; /* fourier filters the layers' values */
    par->fitting = wt_fitting_params_from_variant(v);
    if (cfg->predict) {
        par->predict_lead = (cfg->predict_lead_frames > 0.0 ? cfg->predict_lead_frames : (double)cfg->delay) / cfg->rate;
        for (int k = 0; k < cfg->model.nlayers; k++) {
            par->atm_vx[k] = cfg->model.wind_speed[k] * cos(cfg->model.wind_direction[k]);
            par->atm_vy[k] = cfg->model.wind_speed[k] * sin(cfg->model.wind_direction[k]);
        }
        if (cfg->predict_integrator == 1)
            par->integrator_gain = cfg->gain, par->integrator_delay = cfg->delay, par->frame_s = 1.0 / cfg->rate;
    }
}

int wt_reconstructor_check_mvm_predict(wt_context *ctx, const wt_config *cfg, int recon, int no_predict)
{
    if (recon != WT_RECON_MVM || !cfg->predict) return WT_OK;
    const char *why = NULL;
    if (cfg->predict_integrator == 1)
        why = "key 'recon.predict_integrator' = \"layers\": the MVM has no layers to run the integrator on (use "
              "\"commands\")";
    else if (cfg->model.source == WT_MODEL_LEARNED && cfg->model.learn_wind)
        why = "key 'recon.atmosphere.learn_wind' = \"aligned\": the wind is measured on the reconstruction layers' "
              "estimates, which the MVM does not form (its rebuilds take the start model's wind, learn_wind = "
              "\"start\")";
    else if (no_predict)
        why = "a run without prediction would apply a matrix with the predictor inside it (the budget gives such "
              "runs the same system's matrix built without recon.predict)";
    if (!why) return WT_OK;
    return WT_ERROR(ctx, WT_ERR_CONFIG, "%s: key 'recon.predict' = true with the MVM: %s", cfg->path, why);
}
