/* core/model/tomography.c: normal operator, right-hand side and (P)CG solve
 * of the wavelet MAP tomography (paper eq. eqn_lse; SPEC §6). */
#include "tomography_private.h"
#include "profile.h"
#include "sensing.h"

#include <math.h>
#include <stdint.h>
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


/* A stage's slots in w->prof: calls and wall, then nthreads busy times 8 doubles apart (no two threads write
 * one cache line) */
static int64_t prof_stride(const wt_tomography *t) { return 8 * (1 + (int64_t)t->nthreads); }
static double prof_t0(const wt_tomography_work *w) { return w->prof_on ? wt_time_now() : 0.0; }
/* one call of stage k that ran from t0 to t1 (t1 < 0: now) */
static void prof_wall_to(const wt_tomography *t, wt_tomography_work *w, int k, double t0, double t1)
{
    if (!w->prof_on) return;
    double *s = w->prof + k * prof_stride(t);
    s[0] += 1.0;
    s[1] += (t1 < 0.0 ? wt_time_now() : t1) - t0;
}
static void prof_wall(const wt_tomography *t, wt_tomography_work *w, int k, double t0) { prof_wall_to(t, w, k, t0, -1.0); }
static void prof_busy(const wt_tomography *t, wt_tomography_work *w, int k, int id, double t0)
{
    if (w->prof_on && id < t->nthreads) w->prof[k * prof_stride(t) + 8 * (1 + id)] += wt_time_now() - t0;
}


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

/* y += α W C_φ⁻¹ Wᵀ c on layer l (or α D c for a diagonal prior), on the given work arrays. */
static void prior_layer(const wt_tomography *t, int l, const double *c, double *y, double *phi, double *q,
                        double *wwork, double *pwork)
{
    const int64_t a = t->off[l], nl = t->off[l + 1] - a;
    if (!t->full_prior) {
        for (int64_t i = 0; i < nl; i++) y[i] += t->alpha_d[a + i] * c[i];
        return;
    }
    if (t->space) { /* (space needs the full prior: checked at set-up) */
        wt_prior_apply_full(t->prior[l], t->alpha, c, q, pwork);
        for (int64_t i = 0; i < nl; i++) y[i] += q[i];
        return;
    }
    wt_wavelet_inverse(t->wav[l], c, phi, wwork);
    wt_prior_apply_full(t->prior[l], t->alpha, phi, q, pwork);
    wt_wavelet_forward(t->wav[l], q, phi, wwork);
    for (int64_t i = 0; i < nl; i++) y[i] += phi[i];
}

void wt_tomography_prior_apply_layer(wt_tomography *t, int l, const double *c, double *y)
{
    wt_tomography_work *w = t->work;
    if (!t->full_prior) prior_layer(t, l, c, y, NULL, NULL, NULL, NULL); /* no workspace (pphi may be NULL) */
    else prior_layer(t, l, c, y, w->phi + t->off[l], w->pphi + t->off[l], w->wwork, w->pwork);
}

static size_t max_layer(const wt_tomography *t)
{
    int64_t nmax = 0;
    for (int l = 0; l < t->L; l++)
        if (t->off[l + 1] - t->off[l] > nmax) nmax = t->off[l + 1] - t->off[l];
    return (size_t)nmax;
}

size_t wt_tomography_prior_layer_work(const wt_tomography *t) { return 2 * max_layer(t) + t->wsize + t->pwsize; }

void wt_tomography_prior_apply_layer_ws(const wt_tomography *t, int l, const double *c, double *y, double *ws)
{
    const size_t nmax = max_layer(t);
    prior_layer(t, l, c, y, ws, ws + nmax, ws + 2 * nmax, ws + 2 * nmax + t->wsize);
}

const wt_projection *wt_tomography_projection(const wt_tomography *t, int m, int l) { return t->proj[m * t->L + l]; }
const wt_noise *wt_tomography_noise(const wt_tomography *t, int m) { return t->noise[m]; }
const wt_system *wt_tomography_system(const wt_tomography *t) { return t->sys; }
int wt_tomography_threads(const wt_tomography *t) { return t->nthreads; }

/* The fp32 operator's NGS term. At low noise the NGS weigh ~10⁵ times the LGS, so their part stays double (layers_dwt
 * says why); as the chain Γ P, Ĉ⁻¹, Γᵀ, Pᵀ it was the double work of every apply, its projections scalar (short
 * runs) and their transposes in the layers' stage after a barrier: ~0.16 ms of a 1.5 ms E-ELT frame. An NGS has
 * few slopes (12 for the E-ELT's three), so its part is the explicit rank-r matrix G = [Pᵀ Γᵀ e_k] (the same
 * linear map; its columns live on the footprints' rims: ~1/8 of the layers' points), applied as Gᵀ φ (slopes) and
 * G w (the weighted slopes onto the layers' sum). Built here column by column with the double adjoint: twice, to
 * count the entries per point and then to fill them in. */
static int ngs_explicit(wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    const int64_t n = t->n;
    double *col = NULL, *e = NULL, *phase = NULL;
    int64_t *count = NULL, *fill = NULL, *at = NULL;
    WT_ALLOC(ctx, col, n, "NGS term column");
    WT_ALLOC(ctx, e, sys->nslopes, "NGS term unit slopes");
    WT_ALLOC(ctx, phase, t->ncg, "NGS term phase");
    WT_ALLOC(ctx, count, n, "NGS term counts");
    for (int pass = 0; pass < 2; pass++) {
        for (int m = 0; m < t->S; m++) {
            if (t->s32[m]) continue;
            const wt_sensor *s = &sys->sensors[m];
            for (int j = 0; j < s->nslopes; j++) {
                const int64_t k = s->offset + j;
                e[k] = 1.0;
                memset(col, 0, (size_t)n * sizeof *col);
                memset(phase, 0, (size_t)t->ncg * sizeof *phase);
                wt_sensor_stack_phase_t(&t->stack, m, 1.0, e + s->offset, phase);
                for (int l = 0; l < t->L; l++) wt_projection_apply_t(t->proj[m * t->L + l], 1.0, phase, col + t->off[l]);
                e[k] = 0.0;
                for (int64_t i = 0; i < n; i++) {
                    if (col[i] == 0.0) continue;
                    if (pass == 0) count[i]++;
                    else {
                        const int64_t q = fill[at[i]]++;
                        t->ngs_col[q] = (int32_t)k;
                        t->ngs_val[q] = col[i];
                    }
                }
            }
        }
        if (pass == 1) break;
        int64_t nnz = 0;
        for (int64_t i = 0; i < n; i++) {
            if (count[i]) t->ngs_nrow++;
            nnz += count[i];
        }
        WT_ALLOC(ctx, t->ngs_row, t->ngs_nrow, "NGS term rows");
        WT_ALLOC(ctx, t->ngs_ptr, t->ngs_nrow + 1, "NGS term row starts");
        WT_ALLOC(ctx, t->ngs_col, nnz, "NGS term slopes");
        WT_ALLOC(ctx, t->ngs_val, nnz, "NGS term values");
        WT_ALLOC(ctx, fill, t->ngs_nrow, "NGS term fill");
        WT_ALLOC(ctx, at, n, "NGS term row of a point");
        for (int64_t i = 0, r = 0; i < n; i++)
            if (count[i]) {
                t->ngs_row[r] = i;
                at[i] = r;
                t->ngs_ptr[r + 1] = t->ngs_ptr[r] + count[i];
                fill[r] = t->ngs_ptr[r];
                r++;
            }
    }
fail:
    wt_free(ctx, col);
    wt_free(ctx, e);
    wt_free(ctx, phase);
    wt_free(ctx, count);
    wt_free(ctx, fill);
    wt_free(ctx, at);
    return st;
}

/* The NGS term's rows for the layer points [i0, i1): [*r0, *r1) */
static void ngs_rows(const wt_tomography *t, int64_t i0, int64_t i1, int64_t *r0, int64_t *r1)
{
    int64_t lo = 0, hi = t->ngs_nrow; /* first row >= i0 */
    while (lo < hi) {
        const int64_t mid = lo + (hi - lo) / 2;
        if (t->ngs_row[mid] < i0) lo = mid + 1;
        else hi = mid;
    }
    *r0 = lo;
    hi = t->ngs_nrow; /* first row >= i1 */
    while (lo < hi) {
        const int64_t mid = lo + (hi - lo) / 2;
        if (t->ngs_row[mid] < i1) lo = mid + 1;
        else hi = mid;
    }
    *r1 = lo;
}

/* sum[i − i0] += Σ_k G_ik wv_k for the layer points [i0, i1) (wv: the weighted slopes, indexed as the slopes) */
static void ngs_adjoint(const wt_tomography *t, const double *wv, int64_t i0, int64_t i1, double *sum)
{
    int64_t r0, r1;
    ngs_rows(t, i0, i1, &r0, &r1);
    for (int64_t r = r0; r < r1; r++) {
        double v = 0.0;
        for (int64_t q = t->ngs_ptr[r]; q < t->ngs_ptr[r + 1]; q++) v += t->ngs_val[q] * wv[t->ngs_col[q]];
        sum[t->ngs_row[r] - i0] += v;
    }
}

/* The NGS's slopes Gᵀ φ (φ: the float layers) into slopes (at their indices; the others untouched) */
static void ngs_forward(const wt_tomography *t, const float *phi32, double *slopes)
{
    for (int m = 0; m < t->S; m++)
        if (!t->s32[m]) memset(slopes + t->sys->sensors[m].offset, 0, (size_t)t->sys->sensors[m].nslopes * sizeof *slopes);
    for (int64_t r = 0; r < t->ngs_nrow; r++) {
        const double x = phi32[t->ngs_row[r]];
        for (int64_t q = t->ngs_ptr[r]; q < t->ngs_ptr[r + 1]; q++) slopes[t->ngs_col[q]] += t->ngs_val[q] * x;
    }
}

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
    t->lgs_focus = par->lgs_focus_removal != 0;
    if (t->lgs_focus) WT_TRY(wt_tomography__focus_check(t, par->source));
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
     * descheduled: below ~16k unknowns and ~8k slopes (an apply of well under 0.1 ms: the demo's 0.04) threads do not
     * pay. The slopes count too: the sensors' part can dominate a small grid (the 42 × 42 geometry: 6144 unknowns,
     * 15516 slopes, 0.48 ms an apply on one thread; on two, the frame ×0.67: docs/results.md §31). */
    t->nthreads = t->n < 16384 && sys->nslopes < 8192 ? 1 : wt_context_threads(ctx);
    {
        double cost[2 * WT_MAX_GS];
        for (int m = 0; m < t->S; m++) cost[m] = (double)sys->sensors[m].nslopes + 1.0;
        wt_vec_groups(t->S, cost, t->group);
    }
    for (int m = 0; m < t->S; m++) {
        t->s32[m] = (uint8_t)(t->fp32 && sys->sensors[m].kind == WT_SENSOR_LGS);
        if (t->fp32 && !t->s32[m]) t->any64 = 1;
    }
    if (t->any64) WT_TRY(ngs_explicit(t));
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
        const size_t ns = ((size_t)t->sys->nslopes + r16 - 1) / r16 * r16, nl = (max_layer(t) + r16 - 1) / r16 * r16;
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
    const int64_t len = WT_TOMO_NSTAGES * prof_stride(t);
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
        const double *s = w->prof ? w->prof + k * prof_stride(t) : NULL;
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

/* The thread that handles layer l in a team of nt: its fixed owner (the same thread every apply, so that a
 * layer's coefficients, values and FFT stay in one core's cache; any thread gives the same bits), folded onto a
 * smaller team (a nested or reduced one) */
static int owner_of(const wt_tomography *t, int l, int nt) { return t->owner[l] % nt; }

/* phi = W⁻¹ c layer by layer; with phi32 (the fp32 operator) the transform in float instead: c rounded to float,
 * phi32 = W⁻¹ c in float, and phi = phi32 in double for the full prior's FFTs. In space phi is c itself: only the
 * rounding to phi32 runs.
 * The fp32 operator runs the LGS's forward (P, Γ) and adjoint in float; the NGS's part (their explicit term, Gᵀ φ
 * from the float layers, Ĉ⁻¹, G w) and everything after the sum stay double. At low noise the NGS weigh ~10⁵ times
 * the LGS: a float rounding before their weights reaches the NGS term only through the NGS's dozen global modes
 * (the rows of Ĉ⁻¹ Γ P), which the preconditioner's Woodbury term holds exactly; one after them (a float Γᵀ, Pᵀ,
 * accumulator or DWT) spreads 1e-7 of that large term over every mode, and moved the low-noise field WFE by
 * +0.07 nm (docs/results.md §30; test_tomography test_single_precision_ngs_term). */
static size_t lay32_size(const wt_tomography *t);
/* Thread id's part (of nt; inside a parallel region): its layers */
static void layers_dwt_team(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi, float *phi32,
                            int id, int nt)
{
    const double b0 = prof_t0(w);
    for (int l = 0; l < t->L; l++) {
        if (owner_of(t, l, nt) != id) continue;
        const int64_t a = t->off[l], b = t->off[l + 1];
        if (!phi32) {
            wt_wavelet_inverse(t->wav[l], c + a, phi + a, w->wwork + (size_t)id * t->wsize);
        } else if (t->space) {
            for (int64_t i = a; i < b; i++) phi32[i] = (float)c[i];
        } else /* (c rounded as it is read; phi, the double copy the full prior's FFTs read, row by row) */
            wt_wavelet_inverse_f32_of64(t->wav[l], c + a, phi32 + a, t->full_prior ? phi + a : NULL,
                                        w->wwork32 + (size_t)id * t->wsize);
    }
    prof_busy(t, w, WT_TOMO_STAGE_INVERSE_DWT, id, b0);
}

static void layers_dwt(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi, float *phi32)
{
    if (t->space) { /* the unknowns are the values */
        if (phi != c) memcpy(phi, c, (size_t)t->n * sizeof *phi);
        if (!phi32) return;
    }
    const double t0 = prof_t0(w);
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        layers_dwt_team(t, w, c, phi, phi32, id, nt);
    }
    prof_wall(t, w, WT_TOMO_STAGE_INVERSE_DWT, t0);
}

static void inverse_dwt(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi)
{
    layers_dwt(t, w, c, phi, NULL);
}

/* floats per thread in w->lay32 (a layer's float sum, by layers): the largest layer,
 * rounded to 64 bytes */
static size_t lay32_size(const wt_tomography *t) { return (max_layer(t) + 15) / 16 * 16; }

/* slopes = Γ P φ for every sensor */
static void forward_slopes(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *slopes)
{
    const double t0 = prof_t0(w);
    wt_sensor_stack_set(&t->stack, 1.0, phi, slopes, w->phase, t->nthreads);
    prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t0);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m. Each accumulator group takes its sensors in index order and the
 * groups are summed in order, so the result does not depend on the threads (core/la/vec.h). */
static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c);
static void adjoint_run(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                        double *c, int f32);

/* The right-hand side's adjoint: in float too with the fp32 operator (the measurements rounded to float: ~1e-7 of
 * b, where the noise is ~1e-1) */
static void adjoint_slopes(const wt_tomography *t, wt_tomography_work *w, const double *slopes, double *c)
{
    adjoint_run(t, w, slopes, NULL, c, t->fp32);
}

/* In space with at least two layers per thread the adjoint runs by layers (adjoint_space), else by sensor groups */
static int by_layers(const wt_tomography *t) { return t->space && t->L >= 2 * t->nthreads; }

/* The unknowns in space (fourier): the result is the sum itself, so the adjoint splits by layers instead of by
 * sensor groups: every sensor's weighted slopes and Γᵀ first (one task per sensor, into its own phase), then per
 * layer the prior's term (or 0) and the sensors' projections in index order (one task per layer). No group
 * accumulators to zero and add (2 x 1.2 MB each at E-ELT size); any thread gives the same bits. With fewer
 * layers than twice the threads the split would idle a thread: pcg3 keeps the groups. With cx and the full
 * prior, c holds the prior's term on entry (normal: forward_slopes_prior wrote it there) and the sensors' terms
 * are added to it. */
static void adjoint_space(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c)
{
    const wt_system *sys = t->sys;
    const double t0 = prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        const int id = wt_thread_id();
        double b0 = prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m < t->S; m++) {
            const wt_sensor *s = &sys->sensors[m];
            const wt_noise *nz = t->noise[m];
            const double *x = slopes + s->offset;
            double *ws = w->weighted + s->offset;
            wt_noise_set_weight_many(&nz, 1, &x, &ws);
            wt_sensor_stack_phase_t(&t->stack, m, 1.0, ws, w->phase + (size_t)m * t->ncg);
        }
        prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
#pragma omp barrier
#pragma omp master
        t1 = prof_t0(w);
        if (w->prof_on) { /* every thread's stage starts after t1: a busy time within the stage's wall */
#pragma omp barrier
        }
        b0 = prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            const int64_t a = t->off[l], nl = t->off[l + 1] - a;
            if (!(cx && t->full_prior)) memset(c + a, 0, (size_t)nl * sizeof *c);
            /* (else c already holds the prior's term: forward_slopes_prior wrote it there) */
            for (int m = 0; m < t->S; m++) wt_projection_apply_t(t->proj[m * t->L + l], 1.0, w->phase + (size_t)m * t->ncg, c + a);
        }
        prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
    }
    prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1); /* (the master's clock after the sensors' barrier) */
    prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m (+ α D cx when cx is given; with the full prior + W w->pphi, the α C_φ⁻¹ φ of
 * cx's layers, which normal() leaves there). The group sum, the transform and the prior term of a layer run
 * in one task (the same per-element operations as three passes). */
/* One accumulator group's share of the adjoint: its accumulator cleared, the group's weights side by side
 * (wt_noise_set_weight_many), then its sensors' Γᵀ and Pᵀ in index order */
static void adjoint_group(const wt_tomography *t, wt_tomography_work *w, int g, const double *slopes)
{
    const wt_system *sys = t->sys;
    double *acc = w->acc + (size_t)g * t->n;
    memset(acc, 0, (size_t)t->n * sizeof *acc);
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
        k++;
    }
    wt_noise_set_weight_many(nz, k, x, ws);
    for (int m = 0; m < t->S; m++)
        if (t->group[m] == g)
            wt_sensor_stack_apply_t_sensor(&t->stack, m, 1.0, w->weighted + sys->sensors[m].offset, acc,
                                           w->phase + (size_t)m * t->ncg);
}

/* The adjoint's last stage: the groups' sum (in group order; from the float accumulators w->acc32 with f32, the
 * fp32 operator's), the prior's term and (f32) the NGS term in equal element shares, then each layer's W on its
 * owner */
static void adjoint_layers_team(const wt_tomography *t, wt_tomography_work *w, const double *cx, double *c, int f32,
                                int id, int nt)
{
    const int64_t n = t->n;
    double *sum = t->space ? c : w->phi; /* in space the sum is the result */
    const double b0 = prof_t0(w);
    /* the sums element by element, in equal shares of all layers (by layers, the 128² layer's owner had twice the
     * other thread's part: half the stage's time went to one thread waiting), then each layer's W on its owner */
    const int64_t i0 = n * id / nt, i1 = n * (id + 1) / nt;
    if (f32) /* the groups' float sums (LGS), added in double */
        for (int64_t i = i0; i < i1; i++) {
            double v = w->acc32[i];
            for (int g = 1; g < WT_GROUPS; g++) v += w->acc32[(int64_t)g * n + i];
            sum[i] = v;
        }
    else
        for (int64_t i = i0; i < i1; i++) { /* wt_vec_sum_groups, groups in order */
            double v = w->acc[i];
            for (int g = 1; g < WT_GROUPS; g++) v += w->acc[(int64_t)g * n + i];
            sum[i] = v;
        }
    if (cx && t->full_prior)
        for (int64_t i = i0; i < i1; i++) sum[i] += w->pphi[i];
    if (f32 && t->any64) ngs_adjoint(t, w->weighted, i0, i1, sum + i0); /* the fp32 operator's NGS, in double */
    if (!t->space) {
#pragma omp barrier
        for (int l = 0; l < t->L; l++) {
            if (owner_of(t, l, nt) != id) continue;
            const int64_t a = t->off[l], b = t->off[l + 1];
            wt_wavelet_forward(t->wav[l], w->phi + a, c + a, w->wwork + (size_t)id * t->wsize);
            if (cx && !t->full_prior)
                for (int64_t i = a; i < b; i++) c[i] += t->alpha_d[i] * cx[i];
        }
    }
    prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
}

static void adjoint_space_f32(const wt_tomography *t, wt_tomography_work *w, const double *s, const double *cx,
                              double *c);
static void adjoint_group_f32(const wt_tomography *t, wt_tomography_work *w, int g, const double *s);

/* The adjoint by sensor groups then by layers (or by layers alone, by_layers), in double or, with f32, the fp32
 * operator's (slopes: then NULL for the forward's float slopes, or the double ones to round: the right-hand side) */
static void adjoint_run(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                        double *c, int f32)
{
    if (by_layers(t)) {
        if (f32) adjoint_space_f32(t, w, slopes, cx, c);
        else adjoint_space(t, w, slopes, cx, c);
        return;
    }
    /* the groups and then the layers' stage in one parallel region (as dwt_forward_f32) */
    const double t0 = prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
#pragma omp for schedule(static) nowait
        for (int g = 0; g < WT_GROUPS; g++) {
            const double b0 = prof_t0(w);
            if (f32) adjoint_group_f32(t, w, g, slopes);
            else adjoint_group(t, w, g, slopes);
            prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
        }
#pragma omp barrier
#pragma omp master
        t1 = prof_t0(w);
        if (w->prof_on) { /* every thread's stage starts after t1: a busy time within the stage's wall */
#pragma omp barrier
        }
        adjoint_layers_team(t, w, cx, c, f32, id, nt);
    }
    prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1);
    prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}

static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c)
{
    adjoint_run(t, w, slopes, cx, c, 0);
}

/* slopes = Γ P φ for every sensor and w->pphi = α C_φ⁻¹ φ on every layer (the full prior's term, which the
 * adjoint adds back): independent tasks, each writing its own output, so any thread may run any of them (the
 * same bits on any thread count). The layers' FFTs first, largest first (layer 0, 128², is ~60 µs, as long as
 * several sensors): with one dynamic loop the other thread takes the small layers and then the sensors, where
 * a loop over the layers alone (transform + FFT per layer) left it idle for half of the large layer's task. */
static void forward_slopes_prior(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *slopes,
                                 double *pphi)
{
    const double t0 = prof_t0(w);
#pragma omp parallel num_threads(t->nthreads)
    {
        const double b0 = prof_t0(w);
        int id, nt;
        wt_thread_team(&id, &nt);
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            if (owner_of(t, l, nt) == id)
                wt_prior_apply_full(t->prior[l], t->alpha, phi + t->off[l], pphi + t->off[l],
                                    w->pwork + (size_t)id * t->pwsize);
        }
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m < t->S; m++)
            wt_sensor_stack_set_sensor(&t->stack, m, 1.0, phi, slopes, w->phase + (size_t)m * t->ncg);
        prof_busy(t, w, WT_TOMO_STAGE_FORWARD, id, b0);
    }
    prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t0);
}

/* The fp32 operator (t->fp32): the same stages as the double one below, the LGS's part in float: w->phi32 → Γ P
 * → w->slopes32 → Ĉ⁻¹ → Γᵀ → Pᵀ into float group accumulators (or per-layer float sums, by layers), which the
 * layers' stage adds up in double; the NGS's in double through their explicit term (ngs_explicit): Gᵀ φ as one
 * more task of the forward, Ĉ⁻¹ in the groups' stage, G w in the layers' stage's sum (layers_dwt says why). */

/* slopes32 = Γ P phi32 for every LGS, the NGS's slopes Gᵀ phi32 into w->slopes; with pphi (the full prior) also
 * pphi = α C_φ⁻¹ φ per layer, first (as forward_slopes_prior) */
static void forward_f32_team(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *pphi, int id,
                             int nt)
{
    const double b0 = prof_t0(w);
    for (int k = 0; pphi && k < t->L; k++) {
        const int l = t->by_size[k];
        if (owner_of(t, l, nt) == id)
            wt_prior_apply_full(t->prior[l], t->alpha, phi + t->off[l], pphi + t->off[l],
                                w->pwork + (size_t)id * t->pwsize);
    }
#pragma omp for schedule(dynamic, 1) nowait
    for (int m = 0; m <= t->S; m++) /* the LGS, then (m = S) the NGS term's Gᵀ φ into the double slopes */
        if (m == t->S) {
            if (t->any64) ngs_forward(t, w->phi32, w->slopes);
        } else if (t->s32[m])
            wt_sensor_stack_set_sensor_f32(&t->stack, m, 1.0f, w->phi32, w->slopes32, w->phase32 + (size_t)m * t->ncg);
    prof_busy(t, w, WT_TOMO_STAGE_FORWARD, id, b0);
}

/* The fp32 operator's first two stages in one parallel region (a region's start and end cost ~3 µs on this host,
 * a barrier ~1.5): the layers' transforms (phi32; phi in double for the full prior's FFTs), then the forward.
 * In space phi is c and only its rounding runs. */
static void dwt_forward_f32(const wt_tomography *t, wt_tomography_work *w, const double *c, double *pphi)
{
    double *phi = t->space ? (double *)c : w->phi;
    const double t0 = prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        layers_dwt_team(t, w, c, phi, w->phi32, id, nt);
#pragma omp barrier
#pragma omp master
        t1 = prof_t0(w);
        if (w->prof_on) { /* every thread's stage starts after t1: a busy time within the stage's wall */
#pragma omp barrier
        }
        forward_f32_team(t, w, phi, pphi, id, nt);
    }
    prof_wall_to(t, w, WT_TOMO_STAGE_INVERSE_DWT, t0, t1);
    prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t1);
}

/* The float weights of the k sensors ms (LGS) in one call (wt_noise_set_weight_many_f32) */
static void weigh_f32(const wt_tomography *t, wt_tomography_work *w, int k, const int *ms)
{
    const wt_noise *nz[2 * WT_MAX_GS];
    const float *x[2 * WT_MAX_GS];
    float *ws[2 * WT_MAX_GS];
    for (int q = 0; q < k; q++) {
        const int64_t off = t->sys->sensors[ms[q]].offset;
        nz[q] = t->noise[ms[q]];
        x[q] = w->slopes32 + off;
        ws[q] = w->weighted32 + off;
    }
    wt_noise_set_weight_many_f32(nz, k, x, ws);
}

/* Sensor m's slopes s (double: the right-hand side's measurements) rounded into w->slopes32 */
static void round_slopes(const wt_tomography *t, wt_tomography_work *w, int m, const double *s)
{
    const int64_t a = t->sys->sensors[m].offset, b = a + t->sys->sensors[m].nslopes;
    for (int64_t i = a; i < b; i++) w->slopes32[i] = (float)s[i];
}

/* The double weights of the NGS of group g (g < 0: every NGS), of s or (NULL) of the forward's slopes (ngs_forward),
 * into w->weighted (the NGS term's G applies them in the layers' stage) */
static void weigh_ngs(const wt_tomography *t, wt_tomography_work *w, int g, const double *s)
{
    const wt_noise *nz[2 * WT_MAX_GS];
    const double *x[2 * WT_MAX_GS];
    double *ws[2 * WT_MAX_GS];
    int k = 0;
    for (int m = 0; m < t->S; m++) {
        if ((g >= 0 && t->group[m] != g) || t->s32[m]) continue;
        nz[k] = t->noise[m];
        x[k] = (s ? s : w->slopes) + t->sys->sensors[m].offset;
        ws[k] = w->weighted + t->sys->sensors[m].offset;
        k++;
    }
    wt_noise_set_weight_many(nz, k, x, ws);
}

/* One group's share of the fp32 adjoint; s: the slopes to round first (the right-hand side), or NULL (the operator:
 * its forward left them in w->slopes32) */
static void adjoint_group_f32(const wt_tomography *t, wt_tomography_work *w, int g, const double *s)
{
    const wt_system *sys = t->sys;
    float *acc = w->acc32 + (size_t)g * t->n;
    memset(acc, 0, (size_t)t->n * sizeof *acc);
    int ms[2 * WT_MAX_GS], k = 0;
    for (int m = 0; m < t->S; m++)
        if (t->group[m] == g && t->s32[m]) ms[k++] = m;
    for (int q = 0; s && q < k; q++) round_slopes(t, w, ms[q], s);
    weigh_f32(t, w, k, ms);
    for (int q = 0; q < k; q++)
        wt_sensor_stack_apply_t_sensor_f32(&t->stack, ms[q], 1.0f, w->weighted32 + sys->sensors[ms[q]].offset, acc,
                                           w->phase32 + (size_t)ms[q] * t->ncg);
    if (t->any64) weigh_ngs(t, w, g, s);
}

/* adjoint_space in float: every sensor's weights and Γᵀ, then per layer the sensors' Pᵀ into a float sum that
 * is added (or, without the full prior's term there, copied) into c */
static void adjoint_space_f32(const wt_tomography *t, wt_tomography_work *w, const double *s, const double *cx,
                              double *c)
{
    const double t0 = prof_t0(w);
    double t1 = t0;
    const size_t nl32 = lay32_size(t);
#pragma omp parallel num_threads(t->nthreads)
    {
        const int id = wt_thread_id();
        double b0 = prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m <= t->S; m++) { /* the LGS, then (m = S) every NGS's double weights */
            if (m == t->S) {
                if (t->any64) weigh_ngs(t, w, -1, s);
            } else if (t->s32[m]) {
                if (s) round_slopes(t, w, m, s);
                weigh_f32(t, w, 1, &m);
                wt_sensor_stack_phase_t_f32(&t->stack, m, 1.0f, w->weighted32 + t->sys->sensors[m].offset,
                                            w->phase32 + (size_t)m * t->ncg);
            }
        }
        prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
#pragma omp barrier
#pragma omp master
        t1 = prof_t0(w);
        if (w->prof_on) { /* every thread's stage starts after t1: a busy time within the stage's wall */
#pragma omp barrier
        }
        b0 = prof_t0(w);
        float *sum = w->lay32 + (size_t)id * nl32;
#pragma omp for schedule(dynamic, 1) nowait
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            const int64_t a = t->off[l], nl = t->off[l + 1] - a;
            memset(sum, 0, (size_t)nl * sizeof *sum);
            for (int m = 0; m < t->S; m++)
                if (t->s32[m]) wt_projection_apply_t_f32(t->proj[m * t->L + l], 1.0f, w->phase32 + (size_t)m * t->ncg, sum);
            if (cx && t->full_prior)
                for (int64_t i = 0; i < nl; i++) c[a + i] += sum[i];
            else
                for (int64_t i = 0; i < nl; i++) c[a + i] = sum[i];
            if (t->any64) ngs_adjoint(t, w->weighted, a, a + nl, c + a); /* the NGS's term, in double */
        }
        prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
    }
    prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1);
    prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}


static void normal_f32(const wt_tomography *t, wt_tomography_work *w, const double *c, double *y)
{
    dwt_forward_f32(t, w, c, t->full_prior ? (by_layers(t) ? y : w->pphi) : NULL);
    adjoint_run(t, w, NULL, c, y, 1);
}

/* y = M c, overwritten: the operator of the PCG (wt_linop_fn), with no extra pass */
static void normal(const wt_tomography *t, wt_tomography_work *w, const double *c, double *y)
{
    if (t->fp32) {
        normal_f32(t, w, c, y);
        return;
    }
    const double *phi = c;
    if (!t->space) {
        inverse_dwt(t, w, c, w->phi);
        phi = w->phi;
    }
    /* adjoint_space adds the sensors' terms onto the prior's, so the prior's term goes straight to y (a copy of
     * y's size less per apply; the same values in the same order) */
    if (t->full_prior) forward_slopes_prior(t, w, phi, w->slopes, by_layers(t) ? y : w->pphi);
    else forward_slopes(t, w, phi, w->slopes);
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

/* (neither is a stage of M or of the solve: the profile leaves them out) */
void wt_tomography_slopes(wt_tomography *t, double alpha, const double *c, double *s)
{
    wt_tomography_work *w = t->work;
    const int on = w->prof_on;
    w->prof_on = 0;
    inverse_dwt(t, w, c, w->phi);
    wt_sensor_stack_apply(&t->stack, alpha, w->phi, s, w->phase, t->nthreads);
    w->prof_on = on;
}

void wt_tomography_layers(wt_tomography *t, const double *c, double *phi)
{
    const int on = t->work->prof_on;
    t->work->prof_on = 0;
    inverse_dwt(t, t->work, c, phi);
    t->work->prof_on = on;
}

static void apply_cb(void *user, const double *x, double *y)
{
    const wt_tomography *t = user;
    normal(t, t->work, x, y);
}

/* The preconditioner's callback with the profile's clock around it (wt_tomography_profile_start) */
typedef struct timed_precond {
    const wt_tomography *t;
    wt_pcg_precond inner;
} timed_precond;

static void timed_precond_apply(void *user, const double *r, double *z)
{
    const timed_precond *tp = user;
    const double t0 = prof_t0(tp->t->work);
    tp->inner.apply(tp->inner.user, r, z);
    prof_wall(tp->t, tp->t->work, WT_TOMO_STAGE_PRECOND, t0);
}

static int solve(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int continuing, int max_iter,
                 double rtol, double *history, wt_pcg_result *res)
{
    const double t0 = prof_t0(t->work);
    /* A NaN or Inf slope reaches the right-hand side (every slope has a weight and a non-empty Γᵀ, Pᵀ; NaN · 0 is
     * NaN): its n values are tested instead of the 2.5 times as many slopes (~20 µs of a frame), and the slopes
     * searched only then; the solver's state is not touched (its next right-hand side is a buffer of its own) */
    double *b = wt_pcg_rhs(t->pcg);
    adjoint_slopes(t, t->work, s, b);
    if (wt_vec_first_nonfinite(b, t->n) >= 0) {
        const int64_t bad = wt_vec_first_nonfinite(s, t->sys->nslopes);
        if (bad >= 0)
            return WT_ERROR(t->ctx, WT_ERR_NUMERIC, "tomography: slope %lld is %g (NaN or Inf)", (long long)bad, s[bad]);
        return WT_ERROR(t->ctx, WT_ERR_NUMERIC, "tomography: the right-hand side of finite slopes is not finite (a "
                        "slope beyond the operator's range%s)", t->fp32 ? ", e.g. above float's 3.4e38" : "");
    }
    timed_precond tp = {t, P};
    if (t->work->prof_on && P.apply) P = (wt_pcg_precond){timed_precond_apply, &tp};
    if (t->fresh) continuing = 0, t->fresh = 0;
    const int st = wt_pcg_solve_rhs(t->pcg, apply_cb, t, NULL, P.apply, P.user, c, continuing,
                                    max_iter >= 0 ? max_iter : t->iterations, rtol >= 0 ? rtol : t->tol, history, res);
    prof_wall(t, t->work, WT_TOMO_STAGE_SOLVE, t0);
    return st;
}

int wt_tomography_solve(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter, double rtol,
                        double *history, wt_pcg_result *res)
{
    return solve(t, P, s, c, 0, max_iter, rtol, history, res);
}

int wt_tomography_solve_continue(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter,
                                 double rtol, double *history, wt_pcg_result *res)
{
    return solve(t, P, s, c, 1, max_iter, rtol, history, res);
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
    /* vectors of n: α D, φ, b, the group accumulators, the 4 PCG vectors and its 2 right-hand sides (the
     * preconditioner's are wt_precond_bytes) */
    double b = 8.0 * (double)t->n * (4.0 + (t->fp32 ? 0.0 : 2.0) + 6.0);
    b += 8.0 * (double)t->S * (double)t->ncg + 16.0 * (double)t->sys->nslopes + 8.0 * t->nthreads * (double)t->wsize;
    if (t->fp32) /* the float layers, group accumulators, phases, slopes, layer sums and wavelet work */
        b += 4.0 * ((1.0 + WT_GROUPS) * (double)t->n + (double)t->S * (double)t->ncg + 2.0 * (double)t->sys->nslopes +
                    (double)t->nthreads * ((double)max_layer(t) + (double)t->wsize));
    /* projection stencils: ~24 bytes per masked point and layer, plus the separable tables */
    b += 24.0 * (double)t->sys->ncorners * t->S * t->L;
    if (t->ngs_nrow) /* the fp32 operator's NGS term: 12 bytes an entry, 16 a row */
        b += 12.0 * (double)t->ngs_ptr[t->ngs_nrow] + 16.0 * (double)t->ngs_nrow;
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
        if (!t->space) {                      /* (in space: no transforms) */
            f += 2.0 * 8.0 * N * lev;         /* forward + inverse */
            /* read + write each level, both passes, both transforms (fp32: the inverse in float) */
            b += 2.0 * 2.0 * (t->fp32 ? 6.0 : 8.0) * lev * 2.0;
        }
        if (t->full_prior) {
            /* α C⁻¹ φ: a real FFT and its inverse (~2.5 m² log₂ m² flops each), the complex scaling; the
             * copies in and out and the transforms' passes over the layer and its half spectrum */
            f += 5.0 * m2 * log2(m2) + 3.0 * m2;
            b += 6.0 * 8.0 * m2;
        } else {
            f += 2.0 * m2; /* α D c */
            b += 3.0 * 8.0 * m2;
        }
    }
    /* per sensor: bilinear projection (4 mult-adds per point and layer) and its transpose; Fried (4
     * adds + 1 scale per slope) and transpose; the 2x2 weight (~8 flops per subaperture + T) */
    for (int m = 0; m < sys->nsensors; m++) {
        double pts = (double)sys->ncorners, sl = sys->sensors[m].nslopes;
        if (t->fp32 && !t->s32[m]) { /* an NGS of the fp32 operator: in the explicit term below, and its weights */
            f += 12.0 * sl;
            b += 3.0 * 8.0 * sl;
            continue;
        }
        f += 2.0 * 8.0 * pts * t->L + 2.0 * 5.0 * sl + 12.0 * sl;
        /* stencil (index 4 B + 2 weights) and 4 layer values per point and layer, both passes; the corner phase and
         * slopes a few times each; e bytes a value: 8, or 4 in fp32 */
        const double e = t->fp32 ? 4.0 : 8.0;
        b += 2.0 * pts * t->L * (4.0 + 2.0 * e + 4.0 * e) + 4.0 * e * pts + 6.0 * e * sl;
    }
    if (t->ngs_nrow) { /* Gᵀ φ and G w: a mult-add per entry each; the entries (12 B) and rows (16 B) twice, and the
                          layer values they touch (4 B read, 8 B read + write) */
        const double nnz = (double)t->ngs_ptr[t->ngs_nrow], nr = (double)t->ngs_nrow;
        f += 4.0 * nnz;
        b += 2.0 * (12.0 * nnz + 16.0 * nr) + 20.0 * nr;
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
            int tid = wt_thread_id();
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
