/* core/model/tomography.c: normal operator, right-hand side, modified Jacobi diagonal and (P)CG solve
 * of the wavelet MAP tomography (paper eq. eqn_lse; SPEC §6). */
#include "tomography.h"
#include "sensing.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../la/vec.h"
#include "../op/noise.h"
#include "../op/prior.h"
#include "../op/projection.h"
#include "../op/wavelet.h"
#include "../base/rng.h"

struct wt_tomography {
    wt_context *ctx;
    const wt_system *sys;
    char variant[16];
    int L;
    wt_grid grid[WT_MAX_LAYERS];
    double alt[WT_MAX_LAYERS], frac[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS + 1];
    wt_wavelet *wav[WT_MAX_LAYERS];
    wt_prior *prior[WT_MAX_LAYERS];
    int64_t n;
    double *alpha_d;
    double *jinv;
    /* NGS low-rank part of the preconditioner (see lowrank_*): P = J + R C_n Rᵀ */
    int nlr;                  /* rank r: the NGS slopes (0: plain Jacobi) */
    double *lr_Y;             /* n x r: J⁻¹ R */
    double *lr_K;             /* r x r: Cholesky factor of Ĉ⁻¹_NGS + Rᵀ J⁻¹ R */
    double *lr_w;             /* r */
    double *lr_part;          /* r x WT_VEC_CHUNKS: the chunk sums of Yᵀ r */
    int64_t *lr_runs;         /* the row runs where Y is not all zero (wt_vec_runs) */
    int lr_nruns;
    /* coarse block of the preconditioner (coarse_ngs, see coarse_*): J replaced by B = J with the
     * coarse coefficients' rows and columns of the LGS + prior part of M, inverted exactly */
    int nc;                   /* coarse coefficients (0: none) */
    int64_t *c_idx;           /* nc: their indices in c */
    double *c_L;              /* nc x nc: Cholesky factor (lower, column-major) of that block */
    double *c_w;              /* nc */
    int iterations;
    double tol;
    int S;                    /* sensors */
    wt_projection **proj;     /* S x L: sensor m, layer l at [m * L + l] */
    wt_projection **projs;    /* S: sensor m, all L layers in one (the applies run the layers per point) */
    wt_sensor_stack stack;    /* Σ_m Γ_m P_m over projs (a view) */
    int64_t zero_offset;
    wt_noise **noise;         /* S: the reconstructor's model (τ as configured) */
    double model_var[2 * WT_MAX_GS];  /* S: layer-binning model error added to σ² [rad²] (model_error) */
    int64_t ncg;              /* corner grid points */
    int nthreads;
    int group[2 * WT_MAX_GS];  /* sensor → accumulator group (fixed: results independent of threads) */
    size_t wsize;             /* wavelet workspace per thread (doubles) */
    wt_tomography_work *work; /* the object's own workspace: solve, set-up, the workspace-less applies */
    wt_pcg *pcg;
};

/* What one application of the operators writes (GSL's workspaces): the operator itself stays const. */
struct wt_tomography_work {
    wt_context *ctx;
    double *phi;      /* n: spatial layers / adjoint sum */
    double *acc;      /* WT_GROUPS x n adjoint accumulators */
    double *phase;    /* S x ncg */
    double *slopes;   /* nslopes */
    double *weighted; /* nslopes */
    double *wwork;    /* nthreads x wsize wavelet workspace */
    double *b;        /* n: the applies' scratch, the solve's right-hand side */
};

static int thread_id(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

void wt_tomography_bin_altitude(int L, const double *alt, double h, int *l, double *w)
{
    *l = 0;
    *w = 0.0;
    if (h <= alt[0]) return;
    if (h >= alt[L - 1]) {
        *l = L - 1;
        return;
    }
    while (!(h >= alt[*l] && h < alt[*l + 1])) (*l)++;
    *w = (h - alt[*l]) / (alt[*l + 1] - alt[*l]);
}

/* Bin the atmosphere's Cn² profile onto the reconstruction altitudes (wt_tomography_bin_altitude); floor 1e-3. */
static void bin_profile(const wt_tomography_params *par, int L, const double *alt, double *frac)
{
    for (int l = 0; l < L; l++) frac[l] = 0.0;
    for (int k = 0; k < par->natm; k++) {
        int l;
        double w;
        wt_tomography_bin_altitude(L, alt, par->atm_altitude[k], &l, &w);
        frac[l] += (1.0 - w) * par->atm_fraction[k];
        if (w > 0.0) frac[l + 1] += w * par->atm_fraction[k];
    }
    for (int l = 0; l < L; l++)
        if (frac[l] < 1e-3) frac[l] = 1e-3;
}

int64_t wt_tomography_nunknowns(const wt_tomography *t) { return t->n; }
int wt_tomography_nlayers(const wt_tomography *t) { return t->L; }
const wt_grid *wt_tomography_layer_grid(const wt_tomography *t, int l) { return &t->grid[l]; }
double wt_tomography_layer_altitude(const wt_tomography *t, int l) { return t->alt[l]; }
double wt_tomography_layer_fraction(const wt_tomography *t, int l) { return t->frac[l]; }
double wt_tomography_model_error(const wt_tomography *t, int m) { return t->model_var[m]; }
int64_t wt_tomography_layer_offset(const wt_tomography *t, int l) { return t->off[l]; }
const wt_wavelet *wt_tomography_wavelet(const wt_tomography *t, int l) { return t->wav[l]; }
const double *wt_tomography_alpha_prior(const wt_tomography *t) { return t->alpha_d; }
const wt_projection *wt_tomography_projection(const wt_tomography *t, int m, int l) { return t->proj[m * t->L + l]; }
const wt_noise *wt_tomography_noise(const wt_tomography *t, int m) { return t->noise[m]; }
const wt_system *wt_tomography_system(const wt_tomography *t) { return t->sys; }
const double *wt_tomography_jacobi_inverse(const wt_tomography *t) { return t->jinv; }

/* ---- Layer-binning model error of the LGS slopes (recon.model_error) ---------------------------------
 *
 * The prior puts the Cn² of a true layer at altitude h on the two nearest reconstruction layers
 * (wt_tomography_bin_altitude): the model sees the layer's screen φ as (1 − w) φ at h_l plus w φ at h_{l+1}. Sensor m
 * then predicts Γ_m[(1 − w) P_m(h_l) + w P_m(h_{l+1})] φ where it measures Γ_m P_m(h) φ; the difference
 * (sub-metre structure seen through the shifts (h − h_l)θ_m and the LGS cone (h − h_l) r / H) cannot be
 * explained by any layer of the model, and at low noise the MAP explains it anyway with wrong
 * structure on the other layers. So it is treated as noise ("tomographic error as noise"): its variance
 * per slope, averaged over the sensor's slopes with their global tip-tilt removed (the weight removes
 * it), is added to σ²:
 *   σ²_e,m = Σ_k E|(I − T) Γ_m [P_m(h_k) − (1 − w_k) P_m(h_l) − w_k P_m(h_{l+1})] φ_k|² / (2 nsub),
 * φ_k drawn from the layer's exact wavelet prior (Cn² fraction f_k) on the finest reconstruction
 * spacing, WT_MODEL_ERROR_DRAWS draws per layer with a fixed seed (the reconstructor stays a
 * deterministic function of the configuration). Zero when every true layer sits on a reconstruction
 * altitude (cg9's default layers). Only the LGS: the NGS are the only tip-tilt/low-order sensors and
 * average over 21–42 m, where the linear split is accurate (SPEC §6; docs/design.md). */
enum { WT_MODEL_ERROR_DRAWS = 4 };

static int model_error(wt_tomography *t, const wt_recon_variant_config *var, const wt_tomography_params *par,
                       double *var_e)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    wt_wavelet *wav = NULL;
    wt_prior *prior = NULL;
    wt_projection *proj[3] = {NULL, NULL, NULL};
    double *c = NULL, *phi = NULL, *work = NULL, *ph = NULL, *sl = NULL;
    for (int m = 0; m < t->S; m++) var_e[m] = 0.0;
    /* one sample grid for every true layer: the finest spacing, as wide as the widest layer */
    double dx = var->spacing[0], width = 0.0;
    for (int l = 0; l < t->L; l++) {
        if (var->spacing[l] < dx) dx = var->spacing[l];
        if (var->size[l] * var->spacing[l] > width) width = var->size[l] * var->spacing[l];
    }
    int n = 1 << par->wavelet_levels;
    while (n * dx < width - 1e-9) n *= 2;
    const wt_grid g = wt_grid_layer(n, dx);
    const int64_t np = wt_grid_size(&g);
    int nslopes_max = 0;
    for (int m = 0; m < t->S; m++)
        if (sys->sensors[m].nslopes > nslopes_max) nslopes_max = sys->sensors[m].nslopes;
    WT_TRY(wt_wavelet_alloc(ctx, n, par->wavelet_order, par->wavelet_levels, &wav));
    WT_ALLOC(ctx, c, np, "model-error coefficients");
    WT_ALLOC(ctx, phi, (size_t)WT_MODEL_ERROR_DRAWS * np, "model-error screens");
    WT_ALLOC(ctx, work, wt_wavelet_work_size(wav), "model-error wavelet workspace");
    WT_ALLOC(ctx, ph, t->ncg, "model-error phase");
    WT_ALLOC(ctx, sl, nslopes_max, "model-error slopes");
    for (int k = 0; k < par->natm; k++) {
        const double h = par->atm_altitude[k], f = par->atm_fraction[k];
        int l;
        double w;
        wt_tomography_bin_altitude(t->L, t->alt, h, &l, &w);
        if (f <= 0.0 || (w == 0.0 && fabs(h - t->alt[l]) <= 1e-6 * fmax(1.0, h))) continue;
        WT_TRY(wt_prior_alloc(ctx, wav, dx, par->r0, f, par->L0, WT_PRIOR_EXACT, &prior));
        const double *d = wt_prior_diag(prior);
        wt_rng rng;
        wt_rng_init(&rng, 0x6d6f64656c657272ULL, (uint64_t)k); /* fixed: "modelerr", one stream per layer */
        for (int r = 0; r < WT_MODEL_ERROR_DRAWS; r++) {
            for (int64_t i = 0; i < np; i++) c[i] = wt_rng_normal(&rng) / sqrt(d[i]);
            wt_wavelet_inverse(wav, c, phi + (size_t)r * np, work);
        }
        wt_prior_free(prior);
        prior = NULL;
        const double alt3[3] = {h, t->alt[l], w > 0.0 ? t->alt[l + 1] : t->alt[l]};
        const double wt3[3] = {1.0, -(1.0 - w), -w};
        for (int m = 0; m < t->S; m++) {
            const wt_sensor *s = &sys->sensors[m];
            if (s->kind != WT_SENSOR_LGS) continue;
            for (int q = 0; q < 3; q++)
                WT_TRY(wt_projection_alloc(ctx, 1, &g, &alt3[q], s->altitude, s->theta_x, s->theta_y, &sys->sense_grid,
                                           wt_shack_hartmann_corner_mask(s->sh), 0, &proj[q]));
            double sum = 0.0;
            for (int r = 0; r < WT_MODEL_ERROR_DRAWS; r++) {
                memset(ph, 0, (size_t)t->ncg * sizeof *ph);
                for (int q = 0; q < 3; q++)
                    if (wt3[q] != 0.0) wt_projection_apply(proj[q], wt3[q], phi + (size_t)r * np, ph);
                memset(sl, 0, (size_t)s->nslopes * sizeof *sl);
                wt_shack_hartmann_apply(s->sh, 1.0, ph, sl);
                for (int axis = 0; axis < 2; axis++) { /* (I − T): the global tip and tilt removed */
                    double *v = sl + (size_t)axis * s->nsub, mean = 0.0;
                    for (int i = 0; i < s->nsub; i++) mean += v[i];
                    mean /= s->nsub;
                    for (int i = 0; i < s->nsub; i++) sum += (v[i] - mean) * (v[i] - mean);
                }
            }
            var_e[m] += sum / ((double)s->nslopes * WT_MODEL_ERROR_DRAWS);
            for (int q = 0; q < 3; q++) {
                wt_projection_free(proj[q]);
                proj[q] = NULL;
            }
        }
    }
fail:
    for (int q = 0; q < 3; q++) wt_projection_free(proj[q]);
    wt_prior_free(prior);
    wt_wavelet_free(wav);
    wt_free(ctx, c);
    wt_free(ctx, phi);
    wt_free(ctx, work);
    wt_free(ctx, ph);
    wt_free(ctx, sl);
    return st;
}

static int compute_jacobi(wt_tomography *t);
static int compute_coarse(wt_tomography *t, int coarse_levels);
static int compute_lowrank(wt_tomography *t);

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
    bin_profile(par, t->L, t->alt, t->frac);

    WT_ALLOC(ctx, t->alpha_d, t->n, "prior diagonal");
    for (int l = 0; l < t->L; l++) {
        int levels = par->wavelet_levels;
        WT_TRY(wt_wavelet_alloc(ctx, t->grid[l].nx, par->wavelet_order, levels, &t->wav[l]));
        WT_TRY(wt_prior_alloc(ctx, t->wav[l], t->grid[l].dx, par->r0, t->frac[l], par->L0, par->prior_flags,
                              &t->prior[l]));
        const double *d = wt_prior_diag(t->prior[l]);
        for (int64_t i = 0; i < wt_grid_size(&t->grid[l]); i++) t->alpha_d[t->off[l] + i] = par->alpha * d[i];
        size_t ws = wt_wavelet_work_size(t->wav[l]);
        if (ws > t->wsize) t->wsize = ws;
    }

    t->S = sys->nsensors;
    t->ncg = wt_grid_size(&sys->sense_grid);
    WT_ALLOC(ctx, t->proj, (size_t)t->S * t->L, "projections");
    WT_ALLOC(ctx, t->projs, t->S, "projections");
    WT_ALLOC(ctx, t->noise, t->S, "noise models");
    if (par->model_error) WT_TRY(model_error(t, var, par, t->model_var));
    /* loop_noise_average: the loop applies an average of the reconstructions over its memory (the POLC
     * integrator): white measurement noise reaches the command with variance κσ², κ = Σh² (0.389 for
     * g 0.4, delay 2), while the turbulence, and the model error that moves with it, stays nearly the
     * same over those few frames. The per-frame estimate whose loop average is best is then the MAP
     * with noise κσ² (a weaker prior against the noise, not against the model error). */
    const double kappa = var->loop_noise_average ? par->loop_noise_gain : 1.0;
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
        /* C̃_i = κσ²(I + (τ/θf²) β βᵀ) + σ²_e I = σ²_t (I + (τ κσ²/σ²_t / θf²) β βᵀ), σ²_t = κσ² + σ²_e:
         * the model error is isotropic, the elongation term keeps its size; κ (loop_noise_average, else 1)
         * scales the measurement noise only. With lit_noise as well, the per-subaperture factor c_i scales
         * σ²_t whole (the model error of a partly lit subaperture is taken as larger in the same
         * proportion: both options are off by default). */
        if (s->diffr) {
            /* a diffractive sensor: the centroider's calibrated 2x2 blocks Σ_i (sensing.h), κΣ_i + σ²_e I; τ
             * scales the part beyond the short axis, κ(Σ_i − λ_i I), which the isotropic model error leaves as
             * it is (the same rule as the paper's model above) */
            const int ns = s->nsub;
            double *cov = wt_malloc(ctx, 3 * (size_t)ns, sizeof *cov);
            if (!cov) {
                st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for %s's noise blocks", s->name);
                goto fail;
            }
            for (int i = 0; i < ns; i++) {
                cov[i] = kappa * s->diffr->cov[i] + t->model_var[m];
                cov[ns + i] = kappa * s->diffr->cov[ns + i];
                cov[2 * ns + i] = kappa * s->diffr->cov[2 * ns + i] + t->model_var[m];
            }
            st = wt_noise_alloc_blocks(ctx, ns, cov, par->tau, s->kind == WT_SENSOR_LGS, &t->noise[m]);
            wt_free(ctx, cov);
            if (st < 0) goto fail;
            continue;
        }
        const double s2n = kappa * s->sigma2, s2t = s2n + t->model_var[m];
        WT_TRY(wt_noise_alloc_scaled(ctx, s->nsub, s2t, s->noise_scale, s->spot_fwhm, s->beta,
                                     par->tau * (s2n / s2t), s->kind == WT_SENSOR_LGS, &t->noise[m]));
    }

    t->stack = (wt_sensor_stack){.sys = sys, .nin = 1, .proj = t->projs, .in_offset = &t->zero_offset};

    /* A parallel region costs a few µs on an idle machine and a scheduler time slice when a thread is
     * descheduled: below ~16k unknowns (an apply of well under 0.1 ms) threads do not pay. */
    t->nthreads = t->n < 16384 ? 1 : wt_context_threads(ctx);
    {
        double cost[2 * WT_MAX_GS];
        for (int m = 0; m < t->S; m++) cost[m] = (double)sys->sensors[m].nslopes + 1.0;
        wt_vec_groups(t->S, cost, t->group);
    }
    WT_TRY(wt_tomography_work_alloc(t, &t->work));
    WT_TRY(wt_pcg_alloc(ctx, t->n, &t->pcg));
    if (var->jacobi) WT_TRY(compute_jacobi(t));
    if (var->jacobi == 3) WT_TRY(compute_coarse(t, var->coarse_levels));
    if (var->jacobi >= 2) WT_TRY(compute_lowrank(t));
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
    if (t->proj)
        for (int i = 0; i < t->S * t->L; i++) wt_projection_free(t->proj[i]);
    if (t->projs)
        for (int m = 0; m < t->S; m++) wt_projection_free(t->projs[m]);
    if (t->noise)
        for (int m = 0; m < t->S; m++) wt_noise_free(t->noise[m]);
    wt_free(ctx, t->proj);
    wt_free(ctx, t->projs);
    wt_free(ctx, t->noise);
    wt_free(ctx, t->alpha_d);
    wt_free(ctx, t->jinv);
    wt_free(ctx, t->lr_Y);
    wt_free(ctx, t->lr_K);
    wt_free(ctx, t->lr_w);
    wt_free(ctx, t->lr_part);
    wt_free(ctx, t->lr_runs);
    wt_free(ctx, t->c_idx);
    wt_free(ctx, t->c_L);
    wt_free(ctx, t->c_w);
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
    WT_ALLOC(ctx, w->phi, t->n, "layer workspace");
    WT_ALLOC(ctx, w->acc, (size_t)WT_GROUPS * t->n, "adjoint accumulators");
    WT_ALLOC(ctx, w->phase, (size_t)t->S * t->ncg, "phase workspace");
    WT_ALLOC(ctx, w->slopes, t->sys->nslopes, "slope workspace");
    WT_ALLOC(ctx, w->weighted, t->sys->nslopes, "weighted slope workspace");
    WT_ALLOC(ctx, w->wwork, (size_t)t->nthreads * t->wsize, "wavelet workspace");
    WT_ALLOC(ctx, w->b, t->n, "right-hand side");
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
    wt_free(ctx, w->phi);
    wt_free(ctx, w->acc);
    wt_free(ctx, w->phase);
    wt_free(ctx, w->slopes);
    wt_free(ctx, w->weighted);
    wt_free(ctx, w->wwork);
    wt_free(ctx, w->b);
    wt_free(ctx, w);
}

/* phi = W⁻¹ c layer by layer */
static void inverse_dwt(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi)
{
#pragma omp parallel for schedule(dynamic, 1) num_threads(t->nthreads)
    for (int l = 0; l < t->L; l++)
        wt_wavelet_inverse(t->wav[l], c + t->off[l], phi + t->off[l], w->wwork + (size_t)thread_id() * t->wsize);
}

/* slopes = Γ P φ for every sensor */
static void forward_slopes(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *slopes)
{
    wt_sensor_stack_set(&t->stack, 1.0, phi, slopes, w->phase, t->nthreads);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m. Each accumulator group takes its sensors in index order and the
 * groups are summed in order, so the result does not depend on the threads (core/la/vec.h). */
static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c);

static void adjoint_slopes(const wt_tomography *t, wt_tomography_work *w, const double *slopes, double *c)
{
    adjoint_prior(t, w, slopes, NULL, c);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m (+ α D cx when cx is given). The group sum, the transform and the prior term
 * of a layer run in one task (the same per-element operations as three passes). */
static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c)
{
    const wt_system *sys = t->sys;
    const int64_t n = t->n;
#pragma omp parallel for schedule(static) num_threads(t->nthreads)
    for (int g = 0; g < WT_GROUPS; g++) {
        double *acc = w->acc + (size_t)g * n;
        memset(acc, 0, (size_t)n * sizeof *acc);
        /* the group's weights first, side by side (wt_noise_apply_weight_many), then its adjoints in order */
        const wt_noise *nz[2 * WT_MAX_GS];
        const double *x[2 * WT_MAX_GS];
        double *ws[2 * WT_MAX_GS];
        int k = 0;
        for (int m = 0; m < t->S; m++) {
            if (t->group[m] != g) continue;
            const wt_sensor *s = &sys->sensors[m];
            nz[k] = t->noise[m];
            x[k] = slopes + s->offset;
            ws[k] = w->weighted + s->offset;
            memset(ws[k], 0, (size_t)s->nslopes * sizeof *ws[k]);
            k++;
        }
        wt_noise_apply_weight_many(nz, k, 1.0, x, ws);
        for (int m = 0; m < t->S; m++)
            if (t->group[m] == g)
                wt_sensor_stack_apply_t_sensor(&t->stack, m, 1.0, w->weighted + sys->sensors[m].offset, acc,
                                               w->phase + (size_t)m * t->ncg);
    }
#pragma omp parallel for schedule(dynamic, 1) num_threads(t->nthreads)
    for (int l = 0; l < t->L; l++) {
        const int64_t a = t->off[l], b = t->off[l + 1];
        for (int64_t i = a; i < b; i++) { /* wt_vec_sum_groups, groups in order */
            double v = w->acc[i];
            for (int g = 1; g < WT_GROUPS; g++) v += w->acc[(int64_t)g * n + i];
            w->phi[i] = v;
        }
        wt_wavelet_forward(t->wav[l], w->phi + a, c + a, w->wwork + (size_t)thread_id() * t->wsize);
        if (cx)
            for (int64_t i = a; i < b; i++) c[i] += t->alpha_d[i] * cx[i];
    }
}

/* y = M c, overwritten: the operator of the PCG (wt_linop_fn), with no extra pass */
static void normal(const wt_tomography *t, wt_tomography_work *w, const double *c, double *y)
{
    inverse_dwt(t, w, c, w->phi);
    forward_slopes(t, w, w->phi, w->slopes);
    adjoint_prior(t, w, w->slopes, c, y);
}

/* The public forms accumulate (y ← y + α A x, as core/op does); w->b is their scratch (in the object's
 * own workspace it is also the solve's right-hand side, recomputed by every solve). */
void wt_tomography_apply_ws(const wt_tomography *t, wt_tomography_work *w, double alpha, const double *c, double *y)
{
    normal(t, w, c, w->b);
    for (int64_t i = 0; i < t->n; i++) y[i] += alpha * w->b[i];
}

void wt_tomography_apply(wt_tomography *t, double alpha, const double *c, double *y)
{
    wt_tomography_apply_ws(t, t->work, alpha, c, y);
}

void wt_tomography_rhs(wt_tomography *t, double alpha, const double *s, double *b)
{
    wt_tomography_work *w = t->work;
    adjoint_slopes(t, w, s, w->b);
    for (int64_t i = 0; i < t->n; i++) b[i] += alpha * w->b[i];
}

void wt_tomography_slopes(wt_tomography *t, double alpha, const double *c, double *s)
{
    wt_tomography_work *w = t->work;
    inverse_dwt(t, w, c, w->phi);
    wt_sensor_stack_apply(&t->stack, alpha, w->phi, s, w->phase, t->nthreads);
}

void wt_tomography_layers(wt_tomography *t, const double *c, double *phi) { inverse_dwt(t, t->work, c, phi); }

static void apply_cb(void *user, const double *x, double *y)
{
    const wt_tomography *t = user;
    normal(t, t->work, x, y);
}

/* ---- NGS low-rank correction of the Jacobi preconditioner ----------------------------------------
 *
 * The NGS term of M is Σ_NGS Ãᵀ C̃⁻¹ Ã = G Ĉ⁻¹_NGS Gᵀ with G = [Ãᵀ e_k] over the r NGS slopes (r = 12
 * for one 2x2 and two 1x1 sensors): rank r, but weighted by NGS noise variances that can be 10⁵ times
 * smaller than the LGS ones (SPEC §11: 0.05 mas against 20 mas). A diagonal cannot describe it — the
 * NGS modes are global tip-tilt-like shapes — and the few PCG iterations then spend themselves on them
 * (PCG-3 at low noise lost its correction entirely). So P = J + G Ĉ⁻¹ Gᵀ = J + R C_n Rᵀ, with
 * R = G Ĉ⁻¹ = [Ãᵀ Ĉ⁻¹ e_k] (r right-hand sides) and C_n = (Ĉ⁻¹_NGS)⁻¹, is inverted by Woodbury:
 *   P⁻¹ = J⁻¹ − Y K⁻¹ Yᵀ,   Y = J⁻¹ R,   K = Ĉ⁻¹_NGS + Rᵀ J⁻¹ R   (r x r, Cholesky once),
 * which costs 4 r n flops per iteration on top of the diagonal. */
/* ---- coarse block of the preconditioner (coarse_ngs) --------------------------------------------
 *
 * Jacobi treats every wavelet coefficient alone. At the coarse scales that is far from M: every LGS sees
 * the 3 layers' large-scale structure almost alike (their footprints overlap), so the layers' coarse
 * coefficients are strongly coupled and the few iterations leave the layer-difference modes behind
 * (at low noise the 4-iteration PCG-3 is 20-25 nm from its exact MAP, docs/results.md §0d). B replaces
 * J on the coarse coefficients of all layers together (each layer's top-left s x s square of the Mallat
 * layout, s = n / 2^(J − coarse_levels): the scaling block and the coarse_levels coarsest detail
 * levels, 8 m apart for both the 0.5 m and the 1 m E-ELT layers at coarse_levels 2) by the exact block
 * of the LGS + prior part of M; its Cholesky factor is computed once (nc applies of M at set-up) and
 * costs two triangular solves, ~2 nc² flops, per iteration (nc = 384 on the E-ELT pcg3 layers). Both
 * solves run by columns (axpys that vectorise; a row-oriented solve is a chain of dependent adds: the
 * backward one took ~67 µs of an ~0.47 ms iteration that way). The NGS stay in the Woodbury term, now around B: P = B + R C_n Rᵀ. */
/* cloned for AVX2/AVX-512 like the transforms (WT_CPU_CLONES: both solves' column updates vectorise) */
WT_CPU_CLONES static void coarse_apply(wt_tomography *t, const double *r, double *z)
{
    const int64_t n = t->n;
    for (int64_t i = 0; i < n; i++) z[i] = t->jinv[i] * r[i];
    const int q = t->nc;
    if (q == 0) return;
    double *w = t->c_w;
    const double *L = t->c_L;
    for (int i = 0; i < q; i++) w[i] = r[t->c_idx[i]];
    for (int i = 0; i < q; i++) { /* forward: L y = w (column-oriented) */
        const double v = (w[i] /= L[i + (size_t)q * i]);
        const double *col = L + (size_t)q * i;
        for (int k = i + 1; k < q; k++) w[k] -= col[k] * v;
    }
    for (int i = q - 1; i >= 0; i--) { /* backward: Lᵀ x = y (column-oriented on Lᵀ, held above the diagonal) */
        const double v = (w[i] /= L[i + (size_t)q * i]);
        const double *col = L + (size_t)q * i;
        for (int k = 0; k < i; k++) w[k] -= col[k] * v;
    }
    for (int i = 0; i < q; i++) z[t->c_idx[i]] = w[i];
}

/* In-place Cholesky of the q x q SPD matrix A (column-major; lower triangle used and overwritten) */
static int cholesky(wt_context *ctx, int q, double *A, const char *what)
{
    for (int j = 0; j < q; j++) {
        double d = A[j + (size_t)q * j];
        for (int k = 0; k < j; k++) d -= A[j + (size_t)q * k] * A[j + (size_t)q * k];
        if (!(d > 0.0) || !isfinite(d))
            return WT_ERROR(ctx, WT_ERR_NUMERIC, "tomography: the %s matrix is not positive definite (pivot %d = %g)",
                            what, j, d);
        A[j + (size_t)q * j] = sqrt(d);
        for (int i = j + 1; i < q; i++) {
            double s = A[i + (size_t)q * j];
            for (int k = 0; k < j; k++) s -= A[i + (size_t)q * k] * A[j + (size_t)q * k];
            A[i + (size_t)q * j] = s / A[j + (size_t)q * j];
        }
    }
    return WT_OK;
}

static int compute_coarse(wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    const int64_t n = t->n;
    double *e = NULL, *phi = NULL, *col = NULL;
    int q = 0;
    int side[WT_MAX_LAYERS];
    for (int l = 0; l < t->L; l++) {
        const int J = wt_wavelet_levels(t->wav[l]), k = coarse_levels < J ? coarse_levels : J;
        side[l] = t->grid[l].nx >> (J - k);
        q += side[l] * side[l];
    }
    if (q > 4096)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: coarse_ngs with coarse_levels %d gives a block of %d "
                        "coefficients; at most 4096 (lower coarse_levels)", coarse_levels, q);
    WT_ALLOC(ctx, t->c_idx, q, "coarse indices");
    WT_ALLOC(ctx, t->c_L, (size_t)q * q, "coarse block");
    WT_ALLOC(ctx, t->c_w, q, "coarse work");
    WT_ALLOC(ctx, e, n, "coarse probe");
    WT_ALLOC(ctx, phi, n, "coarse probe layers");
    WT_ALLOC(ctx, col, n, "coarse column");
    {
        int k = 0;
        for (int l = 0; l < t->L; l++)
            for (int j = 0; j < side[l]; j++)
                for (int i = 0; i < side[l]; i++) t->c_idx[k++] = t->off[l] + i + (int64_t)t->grid[l].nx * j;
    }
    /* column j of the LGS + prior part of M: the NGS slopes of Γ P W⁻¹ e_j set to zero before the adjoint
     * (the weight is block-diagonal per sensor, so this drops exactly their term) */
    for (int j = 0; j < q; j++) {
        e[t->c_idx[j]] = 1.0;
        double *sl = t->work->slopes;
        inverse_dwt(t, t->work, e, phi);
        forward_slopes(t, t->work, phi, sl);
        for (int m = sys->nlgs; m < sys->nsensors; m++)
            memset(sl + sys->sensors[m].offset, 0, (size_t)sys->sensors[m].nslopes * sizeof *sl);
        adjoint_slopes(t, t->work, sl, col);
        col[t->c_idx[j]] += t->alpha_d[t->c_idx[j]];
        for (int i = 0; i < q; i++) t->c_L[i + (size_t)q * j] = col[t->c_idx[i]];
        e[t->c_idx[j]] = 0.0;
    }
    /* symmetrise the rounding of the two triangles before the factorisation */
    for (int j = 0; j < q; j++)
        for (int i = j + 1; i < q; i++)
            t->c_L[i + (size_t)q * j] = 0.5 * (t->c_L[i + (size_t)q * j] + t->c_L[j + (size_t)q * i]);
    WT_TRY(cholesky(ctx, q, t->c_L, "coarse preconditioner"));
    /* Lᵀ into the (unused) upper triangle: column i above the diagonal = row i of L, so that the backward
     * solve runs by contiguous columns too */
    for (int i = 0; i < q; i++)
        for (int k = 0; k < i; k++) t->c_L[k + (size_t)q * i] = t->c_L[i + (size_t)q * k];
    t->nc = q;
fail:
    wt_free(ctx, e);
    wt_free(ctx, phi);
    wt_free(ctx, col);
    return st;
}

/* K v = w in place by the Cholesky factor of K (lower, column-major) */
static void lowrank_solve(const wt_tomography *t, double *w)
{
    const int q = t->nlr;
    for (int i = 0; i < q; i++) {
        double s = w[i];
        for (int k = 0; k < i; k++) s -= t->lr_K[i + (size_t)q * k] * w[k];
        w[i] = s / t->lr_K[i + (size_t)q * i];
    }
    for (int i = q - 1; i >= 0; i--) {
        double s = w[i];
        for (int k = i + 1; k < q; k++) s -= t->lr_K[k + (size_t)q * i] * w[k];
        w[i] = s / t->lr_K[i + (size_t)q * i];
    }
}

/* z = P⁻¹ r = B⁻¹ r − Y K⁻¹ Yᵀ r. B⁻¹ r (coarse_apply: mostly the coarse block's two triangular solves,
 * serial chains) and Yᵀ r (the r dots, which read r and not z) are independent: on two threads they run
 * side by side, then both threads share the update of z. Y is zero on ~60 % of the rows (the fine
 * wavelet coefficients away from the NGS footprints' rims): its runs of non-zero rows are skipped. */
static void lowrank_precond(void *user, const double *r, double *z)
{
    wt_tomography *t = user;
    const int64_t n = t->n;
    const int q = t->nlr;
    if (q == 0) {
        coarse_apply(t, r, z);
        return;
    }
#pragma omp parallel num_threads(t->nthreads)
    {
#ifdef _OPENMP
        const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
        const int nt = 1, id = 0;
#endif
        if (t->nc > 0) {
            if (id == 0) coarse_apply(t, r, z);
            if (id == (nt > 1 ? 1 : 0)) {
                wt_vec_dot_many_part(t->lr_Y, n, q, r, n, t->lr_runs, t->lr_nruns, 0, WT_VEC_CHUNKS, t->lr_part);
                wt_vec_dot_many_finish(q, t->lr_part, t->lr_w);
                lowrank_solve(t, t->lr_w);
            }
#pragma omp barrier
        } else {
            /* no coarse block: J⁻¹ r and the dots' chunks split over the threads (the chunk sums land in fixed
             * slots and are added in a fixed order: the same bits as on one thread) */
            for (int64_t i = n * id / nt; i < n * (id + 1) / nt; i++) z[i] = t->jinv[i] * r[i];
            wt_vec_dot_many_part(t->lr_Y, n, q, r, n, t->lr_runs, t->lr_nruns, WT_VEC_CHUNKS * id / nt,
                                 WT_VEC_CHUNKS * (id + 1) / nt, t->lr_part);
#pragma omp barrier
#pragma omp single
            {
                wt_vec_dot_many_finish(q, t->lr_part, t->lr_w);
                lowrank_solve(t, t->lr_w);
            } /* (its implicit barrier: w is ready for every thread) */
        }
        wt_vec_sub_many_range(z, t->lr_Y, n, q, t->lr_w, t->lr_runs, t->lr_nruns, n * id / nt, n * (id + 1) / nt);
    }
}

static int compute_lowrank(wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    const int64_t n = t->n, ns = sys->nslopes;
    double *e = NULL, *we = NULL, *cinv = NULL;
    int q = 0, first = -1;
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].kind == WT_SENSOR_NGS) {
            if (first < 0) first = m;
            q += sys->sensors[m].nslopes;
        }
    if (q == 0 || q > 64) return WT_OK; /* no NGS (or an unusual many-slope NGS set: Jacobi alone) */
    const int64_t o0 = sys->sensors[first].offset; /* NGS slopes are the last, contiguous */
    double *R = NULL;
    WT_ALLOC(ctx, R, (size_t)n * q, "NGS preconditioner R");
    WT_ALLOC(ctx, t->lr_Y, (size_t)n * q, "NGS preconditioner Y");
    WT_ALLOC(ctx, t->lr_K, (size_t)q * q, "NGS preconditioner K");
    WT_ALLOC(ctx, t->lr_w, q, "NGS preconditioner work");
    WT_ALLOC(ctx, t->lr_part, (size_t)q * WT_VEC_CHUNKS, "NGS preconditioner work");
    WT_ALLOC(ctx, t->lr_runs, n + 1, "NGS preconditioner runs");
    WT_ALLOC(ctx, e, ns, "unit slope vector");
    WT_ALLOC(ctx, we, ns, "weighted unit slope vector");
    WT_ALLOC(ctx, cinv, (size_t)q * q, "NGS noise weight");
    for (int k = 0; k < q; k++) {
        e[o0 + k] = 1.0;
        adjoint_slopes(t, t->work, e, R + (size_t)k * n);
        /* column k of Ĉ⁻¹_NGS: the noise weight of each NGS sensor applied to e_k */
        memset(we, 0, (size_t)ns * sizeof *we);
        for (int m = first; m < sys->nsensors; m++) {
            const wt_sensor *s = &sys->sensors[m];
            wt_noise_apply_weight(t->noise[m], 1.0, e + s->offset, we + s->offset);
        }
        for (int j = 0; j < q; j++) cinv[j + (size_t)q * k] = we[o0 + j];
        e[o0 + k] = 0.0;
    }
    for (int k = 0; k < q; k++) coarse_apply(t, R + (size_t)n * k, t->lr_Y + (size_t)n * k);
    t->lr_nruns = wt_vec_runs(t->lr_Y, n, q, n, t->lr_runs);
    for (int k = 0; k < q; k++)
        for (int j = 0; j <= k; j++) {
            double v = cinv[j + (size_t)q * k] + wt_vec_dot(R + (size_t)j * n, t->lr_Y + (size_t)k * n, n);
            t->lr_K[j + (size_t)q * k] = t->lr_K[k + (size_t)q * j] = v;
        }
    /* in-place Cholesky, lower triangle (K is SPD: Ĉ⁻¹_NGS SPD, RᵀB⁻¹R semi-definite) */
    WT_TRY(cholesky(ctx, q, t->lr_K, "NGS preconditioner"));
    t->nlr = q;
fail:
    wt_free(ctx, R);
    wt_free(ctx, e);
    wt_free(ctx, we);
    wt_free(ctx, cinv);
    return st;
}

static int solve(wt_tomography *t, const double *s, double *c, int continuing, int max_iter, double rtol,
                 double *history, wt_pcg_result *res)
{
    for (int64_t i = 0; i < t->sys->nslopes; i++)
        if (!isfinite(s[i]))
            return WT_ERROR(t->ctx, WT_ERR_NUMERIC, "tomography: slope %lld is %g (NaN or Inf)", (long long)i, s[i]);
    adjoint_slopes(t, t->work, s, wt_pcg_rhs(t->pcg));
    const int lowrank = t->nlr > 0 || t->nc > 0;
    return wt_pcg_solve_rhs(t->pcg, apply_cb, t, lowrank ? NULL : t->jinv, lowrank ? lowrank_precond : NULL, t, c,
                            continuing, max_iter >= 0 ? max_iter : t->iterations, rtol >= 0 ? rtol : t->tol, history,
                            res);
}

int wt_tomography_solve(wt_tomography *t, const double *s, double *c, int max_iter, double rtol, double *history,
                        wt_pcg_result *res)
{
    return solve(t, s, c, 0, max_iter, rtol, history, res);
}

int wt_tomography_solve_continue(wt_tomography *t, const double *s, double *c, int max_iter, double rtol,
                                 double *history, wt_pcg_result *res)
{
    return solve(t, s, c, 1, max_iter, rtol, history, res);
}

/* ---- modified Jacobi diagonal ------------------------------------------------------------------ */

/* Centre (in grid points, unwrapped) of the support of a periodic 1-D profile: the middle of the
 * complement of its largest circular run of zeros. */
static double support_centre(const double *mag, int n)
{
    int best_len = 0, best_end = -1;
    for (int start = 0; start < n; start++) {
        if (mag[start] != 0.0) continue;
        if (mag[(start + n - 1) % n] == 0.0 && best_len > 0 && start != 0) continue;
        int len = 0;
        while (len < n && mag[(start + len) % n] == 0.0) len++;
        if (len > best_len) {
            best_len = len;
            best_end = start + len; /* first non-zero after the gap */
        }
    }
    if (best_len == 0) return 0.5 * (n - 1);
    double width = n - best_len; /* support occupies [best_end, best_end + width) */
    return best_end + 0.5 * (width - 1);
}

/* Accumulates Σ_LGS ‖Ã_m e_λ‖²_{C̃⁻¹} for all coefficients of (layer l, level, orientation) coloured
 * with stride s. Buffers: field (n²), coef (n²), work (wavelet), ph (ncg), sl/z (max slopes). */
static void probe_block(wt_tomography *t, int l, int level, int orient, int s, double *diag, double *coef,
                        double *field, double *work, double *ph, double *sl, double *z, int a0, int b0)
{
    const wt_system *sys = t->sys;
    const wt_grid *g = &t->grid[l];
    const int n = g->nx, J = wt_wavelet_levels(t->wav[l]);
    const int lev = level > J ? J : level;
    const int m = n >> lev, step = 1 << lev;
    const int se = s < m ? s : m;
    const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;

    /* where the k = 0 basis function of this block sits: centre of its support */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    coef[bx + (int64_t)n * by] = 1.0;
    wt_wavelet_inverse(t->wav[l], coef, field, work);
    double *colmag = ph, *rowmag = ph + n; /* the caller sizes ph for max(ncg, 2n) */
    memset(colmag, 0, 2 * (size_t)n * sizeof *colmag);
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            double v = fabs(field[ix + (int64_t)n * iy]);
            colmag[ix] += v;
            rowmag[iy] += v;
        }
    double cx0 = support_centre(colmag, n), cy0 = support_centre(rowmag, n);

    /* the colour's probes */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    for (int j = b0; j < m; j += se)
        for (int i = a0; i < m; i += se) coef[bx + i + (int64_t)n * (by + j)] = 1.0;
    wt_wavelet_inverse(t->wav[l], coef, field, work);

    const int nprobe = m / se;
    for (int mm = 0; mm < sys->nlgs; mm++) {
        const wt_sensor *s_ = &sys->sensors[mm];
        memset(ph, 0, (size_t)t->ncg * sizeof *ph);
        wt_projection_apply(t->proj[mm * t->L + l], 1.0, field, ph);
        memset(sl, 0, (size_t)s_->nslopes * sizeof *sl);
        wt_shack_hartmann_apply(s_->sh, 1.0, ph, sl);
        memset(z, 0, (size_t)s_->nslopes * sizeof *z);
        wt_noise_apply_inv(t->noise[mm], 1.0, sl, z);
        double cone = s_->altitude > 0 ? 1.0 - t->alt[l] / s_->altitude : 1.0;
        for (int k = 0; k < s_->nsub; k++) {
            double q = sl[k] * z[k] + sl[s_->nsub + k] * z[s_->nsub + k];
            if (q == 0.0) continue;
            int pi = 0, pj = 0;
            if (nprobe > 1) {
                double x, y;
                wt_shack_hartmann_centre(s_->sh, k, &x, &y);
                double gx = (cone * x + s_->theta_x * t->alt[l] - g->x0) / g->dx;
                double gy = (cone * y + s_->theta_y * t->alt[l] - g->y0) / g->dx;
                double period = (double)step * se;
                pi = (int)lround((gx - cx0 - (double)step * a0) / period);
                pj = (int)lround((gy - cy0 - (double)step * b0) / period);
                pi = ((pi % nprobe) + nprobe) % nprobe;
                pj = ((pj % nprobe) + nprobe) % nprobe;
            }
            int64_t lam = bx + a0 + (int64_t)se * pi + (int64_t)n * (by + b0 + (int64_t)se * pj);
            diag[t->off[l] + lam] += q;
        }
    }
}

static int compute_jacobi(wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    double *diag = NULL, *buf = NULL;
    int N = wt_wavelet_order(t->wav[0]);
    int s = 1;
    while (s < 2 * N + 2) s *= 2;
    int64_t maxn2 = 0, maxsl = 0;
    for (int l = 0; l < t->L; l++)
        if (wt_grid_size(&t->grid[l]) > maxn2) maxn2 = wt_grid_size(&t->grid[l]);
    for (int m = 0; m < t->sys->nsensors; m++)
        if (t->sys->sensors[m].nslopes > maxsl) maxsl = t->sys->sensors[m].nslopes;
    int64_t phn = t->ncg > 2 * t->grid[0].nx ? t->ncg : 2 * t->grid[0].nx;
    for (int l = 0; l < t->L; l++)
        if (2 * t->grid[l].nx > phn) phn = 2 * t->grid[l].nx;
    int64_t per = 2 * maxn2 + (int64_t)t->wsize + phn + 2 * maxsl;
    int nth = t->nthreads;
    WT_ALLOC(ctx, diag, t->n, "Jacobi diagonal");
    WT_ALLOC(ctx, buf, (size_t)nth * per, "Jacobi probing workspace");

    for (int l = 0; l < t->L; l++) {
        int J = wt_wavelet_levels(t->wav[l]), n = t->grid[l].nx;
        for (int level = 1; level <= J + 1; level++) {
            int o0 = level <= J ? 1 : 0, o1 = level <= J ? 3 : 0;
            for (int orient = o0; orient <= o1; orient++) {
                int lev = level > J ? J : level, m = n >> lev, se = s < m ? s : m;
#pragma omp parallel for collapse(2) schedule(dynamic, 1) num_threads(nth)
                for (int b0 = 0; b0 < se; b0++)
                    for (int a0 = 0; a0 < se; a0++) {
                        double *base = buf + (size_t)thread_id() * per;
                        double *coef = base, *field = coef + maxn2, *work = field + maxn2;
                        double *ph = work + t->wsize, *sl = ph + phn, *z = sl + maxsl;
                        probe_block(t, l, level, orient, s, diag, coef, field, work, ph, sl, z, a0, b0);
                    }
            }
        }
    }
    WT_ALLOC(ctx, t->jinv, t->n, "inverse Jacobi diagonal");
    for (int64_t i = 0; i < t->n; i++) t->jinv[i] = 1.0 / (diag[i] + t->alpha_d[i]);
    wt_free(ctx, diag);
    wt_free(ctx, buf);
    return WT_OK;
fail:
    wt_free(ctx, diag);
    wt_free(ctx, buf);
    return st;
}

int wt_tomography_diag_bruteforce(wt_tomography *t, double *diag)
{
    int st = WT_OK;
    double *e = NULL, *phi = NULL, *z = NULL;
    wt_context *ctx = t->ctx;
    WT_ALLOC(ctx, e, t->n, "probe");
    WT_ALLOC(ctx, phi, t->n, "probe field");
    WT_ALLOC(ctx, z, t->sys->nslopes, "probe slopes");
    for (int64_t i = 0; i < t->n; i++) {
        e[i] = 1.0;
        inverse_dwt(t, t->work, e, phi);
        e[i] = 0.0;
        forward_slopes(t, t->work, phi, t->work->slopes);
        double q = 0.0;
        for (int m = 0; m < t->sys->nlgs; m++) {
            const wt_sensor *s = &t->sys->sensors[m];
            memset(z + s->offset, 0, (size_t)s->nslopes * sizeof *z);
            wt_noise_apply_inv(t->noise[m], 1.0, t->work->slopes + s->offset, z + s->offset);
            for (int k = 0; k < s->nslopes; k++) q += t->work->slopes[s->offset + k] * z[s->offset + k];
        }
        diag[i] = q;
    }
fail:
    wt_free(ctx, e);
    wt_free(ctx, phi);
    wt_free(ctx, z);
    return st;
}

double wt_tomography_bytes(const wt_tomography *t)
{
    /* vectors of n: α D, J⁻¹, φ, b, the group accumulators, the 4 PCG vectors and its 2 right-hand sides */
    double b = 8.0 * (double)t->n * (4.0 + (t->jinv ? 1.0 : 0.0) + 2.0 + 6.0);
    b += 8.0 * (double)t->S * (double)t->ncg + 16.0 * (double)t->sys->nslopes + 8.0 * t->nthreads * (double)t->wsize;
    /* projection stencils: ~24 bytes per masked point and layer, plus the separable tables */
    b += 24.0 * (double)t->sys->ncorners * t->S * t->L;
    return b;
}

void wt_tomography_cost(const wt_tomography *t, double *flops, double *bytes)
{
    const wt_system *sys = t->sys;
    double f = 0.0, b = 0.0;
    for (int l = 0; l < t->L; l++) {
        /* one DWT level on an m x m block: rows and columns, 2 filters of 2N taps, 2 flops a tap */
        int N = wt_wavelet_order(t->wav[l]), J = wt_wavelet_levels(t->wav[l]);
        double m2 = (double)wt_grid_size(&t->grid[l]), lev = 0.0;
        for (int j = 0; j < J; j++) lev += m2 / (double)(1 << (2 * j));
        f += 2.0 * 8.0 * N * lev;             /* forward + inverse */
        b += 2.0 * 2.0 * 8.0 * lev * 2.0;     /* read + write each level, both passes, both transforms */
        f += 2.0 * m2;                        /* α D c */
        b += 3.0 * 8.0 * m2;
    }
    /* per sensor: bilinear projection (4 mult-adds per point and layer) and its transpose; Fried (4
     * adds + 1 scale per slope) and transpose; the 2x2 weight (~8 flops per subaperture + T) */
    for (int m = 0; m < sys->nsensors; m++) {
        double pts = (double)sys->ncorners, sl = sys->sensors[m].nslopes;
        f += 2.0 * 8.0 * pts * t->L + 2.0 * 5.0 * sl + 12.0 * sl;
        /* stencil (index 4 B + 2 weights 16 B) and 4 layer values per point and layer, both passes;
         * the corner phase and slopes a few times each */
        b += 2.0 * pts * t->L * (20.0 + 4.0 * 8.0) + 4.0 * 8.0 * pts + 6.0 * 8.0 * sl;
    }
    *flops = f;
    *bytes = b;
}

int wt_tomography_count_nnz(wt_tomography *t, int64_t *nnz_gp, int64_t *nnz_a)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    const int S = t->S, L = t->L;
    wt_sparse **gp = NULL;
    int64_t *mark = NULL;
    double *buf = NULL;
    int nth = t->nthreads;
    WT_ALLOC(ctx, gp, (size_t)S * L, "Γ P products");
    for (int m = 0; m < S; m++) {
        wt_sparse *G = NULL;
        WT_TRY(wt_shack_hartmann_assemble(sys->sensors[m].sh, &G));
        nnz_gp[m] = 0;
        nnz_a[m] = 0;
        for (int l = 0; l < L; l++) {
            wt_sparse *P = NULL;
            st = wt_projection_assemble(t->proj[m * L + l], &P);
            if (st < 0) {
                wt_sparse_free(G);
                goto fail;
            }
            st = wt_sparse_multiply(G, P, &gp[m * L + l]);
            wt_sparse_free(P);
            if (st < 0) {
                wt_sparse_free(G);
                goto fail;
            }
            nnz_gp[m] += wt_sparse_nnz(gp[m * L + l]);
        }
        wt_sparse_free(G);
    }
    /* per thread: a row mark per sensor slope block, a coefficient vector and its basis function */
    int64_t maxsl = 0, maxn2 = 0;
    for (int m = 0; m < S; m++)
        if (sys->sensors[m].nslopes > maxsl) maxsl = sys->sensors[m].nslopes;
    for (int l = 0; l < L; l++)
        if (wt_grid_size(&t->grid[l]) > maxn2) maxn2 = wt_grid_size(&t->grid[l]);
    WT_ALLOC(ctx, mark, (size_t)nth * S * maxsl, "symbolic marks");
    WT_ALLOC(ctx, buf, (size_t)nth * (2 * maxn2 + t->wsize), "symbolic workspace");
    for (size_t i = 0; i < (size_t)nth * S * maxsl; i++) mark[i] = -1;
    for (int l = 0; l < L; l++) {
        const int64_t nl = wt_grid_size(&t->grid[l]);
        int64_t counts[2 * WT_MAX_GS] = {0};
#pragma omp parallel num_threads(nth)
        {
            int tid = thread_id();
            int64_t local[2 * WT_MAX_GS] = {0};
            int64_t *mk = mark + (size_t)tid * S * maxsl;
            double *e = buf + (size_t)tid * (2 * maxn2 + t->wsize), *psi = e + maxn2, *work = psi + maxn2;
#pragma omp for schedule(dynamic, 64)
            for (int64_t lam = 0; lam < nl; lam++) {
                memset(e, 0, (size_t)nl * sizeof *e);
                e[lam] = 1.0;
                wt_wavelet_inverse(t->wav[l], e, psi, work);
                int64_t tag = t->off[l] + lam;
                for (int m = 0; m < S; m++) {
                    const wt_sparse *G = gp[m * L + l];
                    int64_t *mm = mk + (size_t)m * maxsl;
                    for (int64_t p = 0; p < nl; p++) {
                        if (psi[p] == 0.0) continue;
                        for (int64_t k = G->colptr[p]; k < G->colptr[p + 1]; k++)
                            if (mm[G->rowind[k]] != tag) {
                                mm[G->rowind[k]] = tag;
                                local[m]++;
                            }
                    }
                }
            }
#pragma omp critical
            for (int m = 0; m < S; m++) counts[m] += local[m];
        }
        for (int m = 0; m < S; m++) nnz_a[m] += counts[m];
    }
fail:
    if (gp)
        for (int i = 0; i < S * L; i++) wt_sparse_free(gp[i]);
    wt_free(ctx, gp);
    wt_free(ctx, mark);
    wt_free(ctx, buf);
    return st;
}
