/* core/model/tomography.c: the wavelet MAP tomography object (paper eq. eqn_lse; SPEC §6): its layers, wavelets,
 * priors α D_ℓ, projections P_m, noise models Ĉ_m⁻¹ and workspaces, set up once, and the profile of its stages.
 *
 *   M c = Σ_m Ã_mᵀ Ĉ_m⁻¹ Ã_m c + α D c,   Ã_m = Γ_m P_m W⁻¹
 *
 * The operator M, its right-hand side and the solve are tomography_operator.c's (the fp32 stages
 * tomography_operator_f32.c's, the fp32 NGS term tomography_ngs.c's); what the atmosphere model sets,
 * tomography_model.c's; the cost model, tomography_cost.c's. */
#include "tomography_private.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../la/vec.h"
#include "../op/noise.h"
#include "../op/prior.h"
#include "../op/projection.h"
#include "../op/wavelet.h"

/* Below both the operator runs on one thread: its apply is too short for a parallel region to pay (below) */
enum { SERIAL_MAX_UNKNOWNS = 16384, SERIAL_MAX_SLOPES = 8192 };

int64_t wt_tomography_nunknowns(const wt_tomography *t) { return t->n; }
int wt_tomography_nlayers(const wt_tomography *t) { return t->L; }
const wt_grid *wt_tomography_layer_grid(const wt_tomography *t, int l) { return &t->grid[l]; }
double wt_tomography_layer_altitude(const wt_tomography *t, int l) { return t->alt[l]; }
double wt_tomography_layer_fraction(const wt_tomography *t, int l) { return t->frac[l]; }
double wt_tomography_model_error(const wt_tomography *t, int m) { return t->model_var[m]; }
double wt_tomography_subgrid_error(const wt_tomography *t, int m) { return t->subgrid_var[m]; }
int64_t wt_tomography_layer_offset(const wt_tomography *t, int l) { return t->off[l]; }
const wt_wavelet *wt_tomography_wavelet(const wt_tomography *t, int l) { return t->wav[l]; }
const double *wt_tomography_alpha_prior(const wt_tomography *t) { return t->alpha_d; }
int wt_tomography_full_prior(const wt_tomography *t) { return t->full_prior; }
int wt_tomography_space(const wt_tomography *t) { return t->space; }
wt_fft_wisdom *wt_tomography_fft(const wt_tomography *t) { return t->fft; }
const char *wt_tomography_variant(const wt_tomography *t) { return t->variant; }

const wt_projection *wt_tomography_projection(const wt_tomography *t, int m, int l) { return t->proj[m * t->L + l]; }
const wt_noise *wt_tomography_noise(const wt_tomography *t, int m) { return t->noise[m]; }
const wt_system *wt_tomography_system(const wt_tomography *t) { return t->sys; }
int wt_tomography_threads(const wt_tomography *t) { return t->nthreads; }

int wt_tomography_alloc(wt_context *ctx, const wt_system *sys, const wt_recon_variant_config *var,
                        const char *variant_name, const wt_tomography_params *par, wt_tomography **out)
{
    int st = WT_OK;
    wt_tomography *t = NULL;
    *out = NULL;
    WT_ALLOC(ctx, t, 1, "tomography");
    t->ctx = ctx;
    t->sys = sys;
    snprintf(t->variant, sizeof t->variant, "%s", variant_name);
    t->L = var->nlayers;
    t->iterations = var->iterations;
    t->tol = var->tolerance;
    for (int l = 0; l < t->L; l++) {
        t->alt[l] = var->altitudes[l];
        t->grid[l] = wt_grid_layer(var->size[l], var->spacing[l]);
        t->off[l + 1] = t->off[l] + wt_grid_size(&t->grid[l]);
    }
    t->n = t->off[t->L];
    for (int l = 0; l < t->L; l++) { /* insertion by size, stable */
        int k = l;
        for (; k > 0 && wt_grid_size(&t->grid[t->by_size[k - 1]]) < wt_grid_size(&t->grid[l]); k--)
            t->by_size[k] = t->by_size[k - 1];
        t->by_size[k] = l;
    }
    wt_tomography__bin_profile(t->L, t->alt, par->natm, par->atm_altitude, par->atm_fraction, t->frac);
    t->r0 = par->r0;
    t->L0 = par->L0;
    t->wavelet_order = par->wavelet_order;
    t->wavelet_levels = par->wavelet_levels;

    WT_ALLOC(ctx, t->alpha_d, t->n, "prior diagonal");
    t->alpha = par->alpha;
    const int kind = var->prior == WT_CFG_PRIOR_FULL ? WT_PRIOR_FULL : var->prior == WT_CFG_PRIOR_EXACT ? WT_PRIOR_EXACT
                                                                                                : WT_PRIOR_PAPER;
    const int prior_flags = kind | (par->prior_flags & WT_PRIOR_ALIASED);
    t->full_prior = kind == WT_PRIOR_FULL;
    t->space = par->space != 0;
    t->fp32 = var->operator_precision == 1;
    if (t->space && !t->full_prior) {
        st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: recon.%s: unknowns in space (the fourier preconditioner) need the full "
                      "prior (recon.%s.prior = \"full\"), got \"%s\"", par->source ? par->source : "tomography",
                      variant_name, variant_name, kind == WT_PRIOR_EXACT ? "exact" : "paper");
        goto fail;
    }
    if (par->fft_wisdom && *par->fft_wisdom)
        WT_TRY(wt_fft_wisdom_read(ctx, par->fft_wisdom, par->fft_wisdom_sha256, "recon.fft_wisdom", &t->fft));
    for (int l = 0; l < t->L; l++) {
        int levels = par->wavelet_levels;
        WT_TRY(wt_wavelet_alloc(ctx, t->grid[l].nx, par->wavelet_order, levels, &t->wav[l]));
        WT_TRY(wt_prior_alloc(ctx, t->wav[l], t->grid[l].dx, par->r0, t->frac[l], par->L0, prior_flags, t->fft,
                              &t->prior[l]));
        const double *d = wt_prior_diag(t->prior[l]);
        for (int64_t i = 0; i < wt_grid_size(&t->grid[l]); i++) t->alpha_d[t->off[l] + i] = par->alpha * d[i];
        size_t ws = wt_wavelet_work_size(t->wav[l]);
        if (ws > t->wsize) t->wsize = ws;
        if (wt_prior_work_size(t->prior[l]) > t->pwsize) t->pwsize = wt_prior_work_size(t->prior[l]);
    }

    t->S = sys->nsensors;
    t->ncg = wt_grid_size(&sys->sense_grid);
    WT_ALLOC(ctx, t->proj, (size_t)t->S * t->L, "projections");
    WT_ALLOC(ctx, t->projs, t->S, "projections");
    WT_ALLOC(ctx, t->noise, t->S, "noise models");
    /* loop_noise_average: the loop applies an average of the reconstructions over its memory (the POLC
     * integrator): white measurement noise reaches the command with variance κσ², κ = Σh² (0.389 for
     * g 0.4, delay 2), while the turbulence, and the model error that moves with it, stays nearly the
     * same over those few frames. The per-frame estimate whose loop average is best is then the MAP
     * with noise κσ² (a weaker prior against the noise, not against the model error). */
    t->kappa = var->loop_noise_average ? par->loop_noise_gain : 1.0;
    t->tau = par->tau;
    t->model_error = par->model_error != 0;
    t->subgrid_error = par->subgrid_error != 0;
    t->lgs_focus = par->lgs_focus_removal;
    if (t->lgs_focus) WT_TRY(wt_tomography__focus_check(t, par->source));
    WT_TRY(wt_tomography__common_alloc(t));
    wt_tomography__model_error_grid(t, var, par->wavelet_levels);
    if (par->model_error || par->subgrid_error) WT_TRY(wt_tomography__model_error(t, par->r0, par->natm, par->atm_altitude, par->atm_fraction));
    for (int m = 0; m < t->S; m++) {
        const wt_sensor *s = &sys->sensors[m];
        for (int l = 0; l < t->L; l++) {
            st = wt_projection_alloc(ctx, 1, &t->grid[l], &t->alt[l], s->altitude, s->theta_x, s->theta_y,
                                     &sys->sense_grid, wt_shack_hartmann_corner_mask(s->sh), 0,
                                     &t->proj[m * t->L + l]);
            if (st == WT_ERR_NOMEM) goto fail; /* not a grid too small: keep the allocation's own status */
            if (st < 0) {
                char detail[1024];
                snprintf(detail, sizeof detail, "%s", wt_error_message(ctx));
                st = WT_ERROR(ctx, WT_ERR_CONFIG,
                              "%s: recon.%s layer %d (layer_altitudes_m[%d] = %g m, layer_size[%d] = %d, "
                              "layer_spacing_m[%d] = %g m, i.e. %g m across) does not cover the footprint of "
                              "%s at that altitude; enlarge the layer grid. (%s)",
                              par->source ? par->source : "tomography", variant_name, l + 1, l, t->alt[l], l, t->grid[l].nx, l, t->grid[l].dx,
                              t->grid[l].nx * t->grid[l].dx, s->name, detail);
                goto fail;
            }
        }
        WT_TRY(wt_projection_alloc(ctx, t->L, t->grid, t->alt, s->altitude, s->theta_x, s->theta_y, &sys->sense_grid,
                                   wt_shack_hartmann_corner_mask(s->sh), 0, &t->projs[m]));
    }
    WT_TRY(wt_tomography__noise(t));

    t->stack = (wt_sensor_stack){.sys = sys, .nin = 1, .proj = t->projs, .in_offset = &t->zero_offset};

    /* A parallel region costs a few µs on an idle machine and a scheduler time slice when a thread is
     * descheduled: an operator below both SERIAL_MAX_UNKNOWNS and SERIAL_MAX_SLOPES (the demo's) is too small an
     * apply for threads to pay. The slopes count too: the sensors' part can dominate a small grid (the 42 × 42
     * geometry; docs/results.md §31). */
    t->nthreads = t->n < SERIAL_MAX_UNKNOWNS && sys->nslopes < SERIAL_MAX_SLOPES ? 1 : wt_context_threads(ctx);
    {
        double cost[2 * WT_MAX_GS];
        for (int m = 0; m < t->S; m++) cost[m] = (double)sys->sensors[m].nslopes + 1.0;
        wt_vec_groups(t->S, cost, t->group);
    }
    for (int m = 0; m < t->S; m++) {
        t->s32[m] = (uint8_t)(t->fp32 && sys->sensors[m].kind == WT_SENSOR_LGS);
        if (t->fp32 && !t->s32[m]) t->any64 = 1;
    }
    if (t->any64) WT_TRY(wt_tomography__ngs_explicit(t));
    { /* layer owners: largest first to the least loaded thread (lowest index on ties) */
        int64_t load[WT_MAX_LAYERS] = {0};
        const int nt = t->nthreads < WT_MAX_LAYERS ? t->nthreads : WT_MAX_LAYERS;
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            int best = 0;
            for (int j = 1; j < nt; j++)
                if (load[j] < load[best]) best = j;
            t->owner[l] = best;
            load[best] += wt_grid_size(&t->grid[l]);
        }
    }
    WT_TRY(wt_tomography_work_alloc(t, &t->work));
    WT_TRY(wt_pcg_alloc(ctx, t->n, &t->pcg));
    *out = t;
    return WT_OK;
fail:
    wt_tomography_free(t);
    return st;
}

void wt_tomography_free(wt_tomography *t)
{
    if (!t) return;
    wt_context *ctx = t->ctx;
    for (int l = 0; l < t->L; l++) {
        wt_wavelet_free(t->wav[l]);
        wt_prior_free(t->prior[l]);
    }
    wt_fft_wisdom_free(t->fft);
    if (t->proj)
        for (int i = 0; i < t->S * t->L; i++) wt_projection_free(t->proj[i]);
    if (t->projs)
        for (int m = 0; m < t->S; m++) wt_projection_free(t->projs[m]);
    if (t->noise)
        for (int m = 0; m < t->S; m++) wt_noise_free(t->noise[m]);
    wt_free(ctx, t->proj);
    wt_free(ctx, t->projs);
    wt_free(ctx, t->noise);
    wt_tomography__common_free(t);
    wt_free(ctx, t->alpha_d);
    wt_free(ctx, t->ngs_row);
    wt_free(ctx, t->ngs_ptr);
    wt_free(ctx, t->ngs_col);
    wt_free(ctx, t->ngs_val);
    wt_tomography_work_free(t->work);
    wt_pcg_free(t->pcg);
    wt_free(ctx, t);
}

int wt_tomography_work_alloc(const wt_tomography *t, wt_tomography_work **out)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    wt_tomography_work *w = NULL;
    *out = NULL;
    WT_ALLOC(ctx, w, 1, "tomography workspace");
    w->ctx = ctx;
    WT_ALLOC(ctx, w->phi_raw, t->n + 8, "layer workspace");
    w->phi = wt_align64(w->phi_raw);
    WT_ALLOC(ctx, w->acc, t->fp32 ? 0 : (size_t)WT_GROUPS * t->n, "adjoint accumulators"); /* (fp32: acc32) */
    WT_ALLOC(ctx, w->phase, (size_t)t->S * t->ncg, "phase workspace");
    WT_ALLOC(ctx, w->slopes, t->sys->nslopes, "slope workspace");
    WT_ALLOC(ctx, w->weighted, t->sys->nslopes, "weighted slope workspace");
    WT_ALLOC(ctx, w->wwork, (size_t)t->nthreads * t->wsize, "wavelet workspace");
    WT_ALLOC(ctx, w->b, t->n, "right-hand side");
    if (t->fp32) {
        const size_t r16 = 16; /* floats per 64 bytes */
        const size_t nn = ((size_t)t->n + r16 - 1) / r16 * r16, nc = ((size_t)t->ncg + r16 - 1) / r16 * r16;
        const size_t ns = ((size_t)t->sys->nslopes + r16 - 1) / r16 * r16;
        const size_t nl = (wt_tomography__max_layer(t) + r16 - 1) / r16 * r16;
        const size_t nw = (t->wsize + r16 - 1) / r16 * r16;
        const size_t total = nn * (1 + WT_GROUPS) + nc * (size_t)t->S + 2 * ns + (nl + nw) * (size_t)t->nthreads;
        WT_ALLOC(ctx, w->f32_raw, total + r16, "single-precision operator workspace");
        w->phi32 = (float *)wt_align64((double *)w->f32_raw); /* (malloc's pointer is 8-aligned) */
        w->acc32 = w->phi32 + nn;
        w->phase32 = w->acc32 + nn * WT_GROUPS;
        w->slopes32 = w->phase32 + nc * (size_t)t->S;
        w->weighted32 = w->slopes32 + ns;
        w->lay32 = w->weighted32 + ns;
        w->wwork32 = w->lay32 + nl * (size_t)t->nthreads;
    }
    if (t->full_prior) {
        WT_ALLOC(ctx, w->pphi_raw, t->n + 8, "full prior term");
        w->pphi = wt_align64(w->pphi_raw);
        WT_ALLOC(ctx, w->pwork, (size_t)t->nthreads * t->pwsize, "full prior workspace");
    }
    *out = w;
    return WT_OK;
fail:
    wt_tomography_work_free(w);
    return st;
}

void wt_tomography_work_free(wt_tomography_work *w)
{
    if (!w) return;
    wt_context *ctx = w->ctx;
    wt_free(ctx, w->phi_raw);
    wt_free(ctx, w->acc);
    wt_free(ctx, w->phase);
    wt_free(ctx, w->slopes);
    wt_free(ctx, w->weighted);
    wt_free(ctx, w->wwork);
    wt_free(ctx, w->b);
    wt_free(ctx, w->pphi_raw);
    wt_free(ctx, w->pwork);
    wt_free(ctx, w->f32_raw);
    wt_free(ctx, w->prof);
    wt_free(ctx, w);
}

static const char *stage_names[WT_TOMO_NSTAGES] = {"inverse DWT",      "forward",        "adjoint by sensor",
                                                    "adjoint by layer", "preconditioner", "solve"};

const char *wt_tomography_stage_name(int k) { return k >= 0 && k < WT_TOMO_NSTAGES ? stage_names[k] : NULL; }

int wt_tomography_profile_start(wt_tomography *t)
{
    int st = WT_OK;
    wt_tomography_work *w = t->work;
    const int64_t len = WT_TOMO_NSTAGES * wt_tomography__prof_stride(t);
    if (!w->prof) WT_ALLOC(t->ctx, w->prof, len, "profile");
    memset(w->prof, 0, (size_t)len * sizeof *w->prof);
    w->prof_on = 1;
fail:
    return st;
}

void wt_tomography_profile_stop(wt_tomography *t, wt_tomography_stage *out)
{
    wt_tomography_work *w = t->work;
    for (int k = 0; k < WT_TOMO_NSTAGES; k++) {
        const double *s = w->prof ? w->prof + k * wt_tomography__prof_stride(t) : NULL;
        out[k] = (wt_tomography_stage){0, 0.0, -1.0, -1.0};
        if (!s) continue;
        out[k].calls = (long)s[0];
        out[k].wall = s[1];
        /* the paper prior's forward runs in core/model/stack.c's region: its busy times are not measured */
        if (k == WT_TOMO_STAGE_FORWARD && !t->full_prior) continue;
        if (k == WT_TOMO_STAGE_INVERSE_DWT && t->space) continue;
        if (k == WT_TOMO_STAGE_PRECOND || k == WT_TOMO_STAGE_SOLVE) continue;
        for (int id = 0; id < t->nthreads; id++) {
            const double b = s[8 * (1 + id)];
            if (id == 0 || b < out[k].busy_min) out[k].busy_min = b;
            if (id == 0 || b > out[k].busy_max) out[k].busy_max = b;
        }
    }
    w->prof_on = 0;
}
