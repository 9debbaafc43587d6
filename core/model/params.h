/* core/model/params.h: the configuration side of model: the small parameter structs the numerical
 * constructors take (wt_tomography_params, wt_precond_params, wt_fitting_params, wt_reconstructor_params),
 * filled from a wt_config in one place, so that no numerical object reaches back into the whole
 * configuration for a value (α, τ, ε, …). */
#ifndef WT_PARAMS_H
#define WT_PARAMS_H

#include "../config/config.h"
#include "fitting.h"
#include "precond.h"
#include "reconstructor.h"
#include "tomography.h"

/* α, τ, the wavelet, the prior and the reconstructors' atmosphere (cfg->model: recon.atmosphere, never the simulated
 * one but as the oracle's copy); source = cfg->path (not copied). */
void wt_tomography_params_from_config(const wt_config *cfg, wt_tomography_params *par);
/* ε, the sampling and the solver of a variant's fitting step (cg9; pcg3 has none, sampling ≤ 0 becomes 1). */
wt_fitting_params wt_fitting_params_from_variant(const wt_recon_variant_config *var);
/* The preconditioner of a variant (recon.<variant>.preconditioner, coarse_levels). */
wt_precond_params wt_precond_params_from_variant(const wt_recon_variant_config *var);
/* The reconstructor of `kind` (WT_RECON_PCG3 or CG9; NONE: only warm_start) under cfg; iterations ≥ 0
 * overrides the variant's (P)CG iteration count. par->variant points into cfg (which must outlive the
 * reconstructor's allocation). */
void wt_reconstructor_params_from_config(const wt_config *cfg, int kind, int iterations, wt_reconstructor_params *par);
/* The MVM under recon.predict: its matrix holds the predictor (builder/mvm_build.h: the model's wind over the lead),
 * so the commands' integrator runs on it as on any MVM. Refused (WT_ERR_CONFIG, naming the key) with the layers'
 * integrator, the wind aligned on the layers' estimates (learn_wind = "aligned": the MVM forms none), or a run that
 * must not predict when no matrix is at hand to say whether it holds a predictor (no_predict; with a matrix the loop
 * checks wt_mvm.predictive). WT_OK for any other reconstructor or case. The loop (sim/loop_config.c), the commands
 * before their builds and the C API (runtime/rtc.c) refuse alike. */
int wt_reconstructor_check_mvm_predict(wt_context *ctx, const wt_config *cfg, int kind, int no_predict);

#endif
