/* core/model/params.c: wt_config → the parameter structs of model (see params.h). */
#include "params.h"

#include <string.h>

#include "../op/prior.h"

void wt_tomography_params_from_config(const wt_config *cfg, wt_tomography_params *par)
{
    memset(par, 0, sizeof *par);
    par->alpha = cfg->alpha;
    par->tau = cfg->tau;
    par->wavelet_order = cfg->wavelet_order;
    par->wavelet_levels = cfg->wavelet_levels;
    par->prior_flags = (cfg->exact_prior ? WT_PRIOR_EXACT : WT_PRIOR_PAPER) | (cfg->prior_aliasing ? WT_PRIOR_ALIASED : 0);
    par->r0 = cfg->r0;
    par->L0 = cfg->L0;
    par->natm = cfg->nlayers;
    for (int k = 0; k < cfg->nlayers; k++) {
        par->atm_altitude[k] = cfg->layer_altitude[k];
        par->atm_fraction[k] = cfg->layer_fraction[k];
    }
    par->model_error = cfg->model_error;
    par->source = cfg->path;
}

wt_fitting_params wt_fitting_params_from_variant(const wt_recon_variant_config *var)
{
    wt_fitting_params fp = {.regularization = var->fit_regularization,
                            .sampling = var->fit_sampling > 0 ? var->fit_sampling : 1};
    return fp;
}
