/* core/config/config_derived.c: load-time checks of the quantities derived from several keys (SPEC §1-§3).
 *
 * Each key is in its own range (config_schema.c), but a combination can still ask for what the code
 * cannot run: a layer that moves farther than the pupil in one frame (frozen flow of SPEC §2 with no
 * correlation left between frames, and a shift v t that loses the screen index's precision), a phase
 * screen wider than the atmosphere accepts (its side 2 (D + 2 h_top θ_max) / δ, δ = D / (n_sub p), as
 * sim/loop.c sizes it), or more reconstruction unknowns than an index or a vector can hold. These are
 * refused here, before any allocation, naming every key involved and its value.
 */
#include "config_private.h"

#include <math.h>

#define MAX_SCREEN 32768            /* the atmosphere's largest screen side (sim/atmosphere.c) */
#define MAX_UNKNOWNS (1L << 28)     /* reconstruction unknowns of one variant: 2 GiB per double vector */

static int check_variant(wt_context *ctx, const wt_config *cfg, const char *name, const wt_recon_variant_config *v)
{
    long total = 0;
    for (int l = 0; l < v->nlayers; l++) total += (long)v->size[l] * v->size[l];
    if (total > MAX_UNKNOWNS)
        return WT_ERROR(ctx, WT_ERR_CONFIG,
                        "%s: key 'recon.%s.layer_size': the layers hold %ld unknowns in all (sum of size^2), more "
                        "than the %ld accepted (one vector of them would take %.1f GiB)",
                        cfg->path, name, total, MAX_UNKNOWNS, (double)total * 8.0 / (1 << 30));
    return WT_OK;
}

int wt_config_priv_check_derived(wt_context *ctx, const wt_config *cfg)
{
    /* one PSF band (one FITS file, named by its nm) per wavelength */
    for (int a = 0; a < cfg->npsf_wavelengths; a++)
        for (int b = 0; b < a; b++)
            if (fabs(cfg->psf_wavelength[a] - cfg->psf_wavelength[b]) < 1e-15)
                return WT_ERROR(ctx, WT_ERR_CONFIG,
                                "%s: key 'sim.psf_wavelengths_nm' elements [%d] and [%d] are both %g nm: give each "
                                "wavelength once", cfg->path, b, a, cfg->psf_wavelength[a] * 1e9);
    /* frozen flow: the shift per frame v / rate against the pupil */
    for (int l = 0; l < cfg->nlayers; l++) {
        double shift = cfg->wind_speed[l] / cfg->rate;
        if (!(shift <= cfg->diameter))
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "%s: keys 'atmosphere.wind_speed_mps' element [%d] = %g m/s and 'loop.rate_hz' = %g Hz: "
                            "the layer moves %g m per frame, more than the pupil ('telescope.diameter_m' = %g m); "
                            "nothing of the turbulence would be seen twice (lower the wind or raise the rate)",
                            cfg->path, l, cfg->wind_speed[l], cfg->rate, shift, cfg->diameter);
    }

    /* the phase screen: the widest line of sight at the top layer, sampled at the simulation grid */
    const int g = cfg->eval_grid;
    double eval = 0.5 * (g - 1) * cfg->eval_spacing * M_SQRT2;
    double thmax = fmax(fmax(cfg->nlgs ? cfg->lgs_radius : 0.0, cfg->nngs ? cfg->ngs_radius : 0.0), eval);
    double htop = cfg->layer_altitude[cfg->nlayers - 1];
    double ncells = (double)cfg->lgs_wfs.subapertures * cfg->points_per_subaperture;
    double delta = cfg->diameter / ncells;
    double side = 2.0 * (cfg->diameter + 2.0 * htop * thmax + 2.0 * delta) / delta;
    if (!(side <= MAX_SCREEN))
        return WT_ERROR(ctx, WT_ERR_CONFIG,
                        "%s: the simulated phase screens would need %.0f points per side, more than the %d "
                        "accepted: 'telescope.diameter_m' = %g m sampled at %g m ('lgs.wfs.subapertures' = %d x "
                        "'sim.points_per_subaperture' = %d), widened by the top layer ('atmosphere.altitudes_m' "
                        "up to %g m) seen at %g arcsec (the widest of 'lgs.radius_arcsec', 'ngs.radius_arcsec' "
                        "and the corner of the 'evaluation.grid' x 'evaluation.spacing_arcsec' grid)",
                        cfg->path, side, MAX_SCREEN, cfg->diameter, delta, cfg->lgs_wfs.subapertures,
                        cfg->points_per_subaperture, htop, thmax / WT_ARCSEC);

    int st = check_variant(ctx, cfg, "pcg3", &cfg->pcg3);
    if (st == WT_OK) st = check_variant(ctx, cfg, "cg9", &cfg->cg9);
    return st;
}
