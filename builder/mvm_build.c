/* builder/mvm_build.c: the offline MVM builder (SPEC §9): the command maps E (pcg3 layer values, cg9 exact
 * fitting), then R = E M⁻¹ Ãᵀ Ĉ⁻¹ and RÂ by block solves with the factorised normal matrix M of
 * mvm_assemble.c (Ã) and mvm_normal.c (N, its factorisation and the Woodbury correction). */
#include "mvm_private.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "../core/op/noise.h"
#include "../core/op/projection.h"
#include "../core/op/shift.h"
#include "../core/model/fitting.h"
#include "../core/model/interaction.h"
#include "../core/model/params.h"
#include "../core/model/profile.h"
#include "../core/model/reconstructor.h"

/* ---- command maps E ------------------------------------------------------------------------------ */

/* The operators of one evaluation direction in fitting_operators: H_j, P_j and the products formed
 * from them, dropped after each direction (and on failure). */
typedef struct {
    wt_projection *hd, *pl;
    wt_sparse *H, *P, *Ht, *HtH, *HtP;
} direction_ops;

static void direction_ops_clear(direction_ops *d)
{
    wt_projection_free(d->hd);
    wt_projection_free(d->pl);
    wt_sparse_free(d->H);
    wt_sparse_free(d->P);
    wt_sparse_free(d->Ht);
    wt_sparse_free(d->HtH);
    wt_sparse_free(d->HtP);
    memset(d, 0, sizeof *d);
}

/* cg9: F = Σ_j H_jᵀ H_j + ε I on the active actuators (dense, Cholesky-factorised in place) and
 * A = Σ_j H_jᵀ P_j (nact x n layer points), with the operators of core/model/fitting.c (same
 * projections, same ε: taken from the wt_fitting of the tomography's layers). */
static int fitting_operators(wt_context *ctx, wt_tomography *t, const wt_fitting_params *fp, double **Fout,
                             wt_sparse **Aout)
{
    int st = WT_OK;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t nact = sys->nact, n = wt_tomography_nunknowns(t), ndm = wt_dm_grid_points(sys->dm);
    wt_grid grids[WT_MAX_LAYERS]; /* the layer projections P_j take the grids and altitudes as arrays */
    double alts[WT_MAX_LAYERS];
    wt_fitting *fit = NULL;
    direction_ops d = {0};
    wt_triplet *tr = NULL;
    int64_t *act = NULL;
    double *F = NULL;
    *Fout = NULL;
    *Aout = NULL;
    for (int l = 0; l < L; l++) {
        grids[l] = *wt_tomography_layer_grid(t, l);
        alts[l] = wt_tomography_layer_altitude(t, l);
    }
    WT_TRY(wt_fitting_alloc_for(ctx, t, fp, &fit));
    const wt_grid *sg = wt_fitting_sample_grid(fit);
    const uint8_t *smask = wt_fitting_sample_mask(fit);
    const double eps = wt_fitting_epsilon(fit);
    WT_ALLOC(ctx, act, ndm, "actuator map");
    wt_dm_actuator_index(sys->dm, act);
    WT_ALLOC(ctx, F, (size_t)nact * nact, "fitting matrix F");
    WT_TRY(wt_triplet_alloc(ctx, nact, n, 1 << 16, &tr));
    for (int j = 0; j < sys->neval; j++) {
        WT_TRY(wt_dm_influence_alloc(ctx, sys->dm, 0.0, sys->eval_x[j], sys->eval_y[j],
                                   sg, smask, &d.hd));
        WT_TRY(wt_projection_alloc(ctx, L, grids, alts, 0.0, sys->eval_x[j], sys->eval_y[j], sg, smask, 0, &d.pl));
        WT_TRY(wt_projection_assemble(d.hd, &d.H));
        WT_TRY(wt_projection_assemble(d.pl, &d.P));
        WT_TRY(wt_sparse_transpose(d.H, &d.Ht));
        WT_TRY(wt_sparse_multiply(d.Ht, d.H, &d.HtH));
        WT_TRY(wt_sparse_multiply(d.Ht, d.P, &d.HtP));
        const wt_sparse *HtH = d.HtH, *HtP = d.HtP;
        for (int64_t c = 0; c < ndm; c++) {
            if (act[c] < 0) continue;
            for (int64_t k = HtH->colptr[c]; k < HtH->colptr[c + 1]; k++)
                if (act[HtH->rowind[k]] >= 0) F[act[HtH->rowind[k]] + nact * act[c]] += HtH->val[k];
        }
        for (int64_t c = 0; c < n; c++)
            for (int64_t k = HtP->colptr[c]; k < HtP->colptr[c + 1]; k++)
                if (act[HtP->rowind[k]] >= 0) WT_TRY(wt_triplet_add(tr, act[HtP->rowind[k]], c, HtP->val[k]));
        direction_ops_clear(&d);
    }
    for (int64_t i = 0; i < nact; i++) F[i + nact * i] += eps;
    lapack_int info = LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', (lapack_int)nact, F, (lapack_int)nact);
    if (info != 0) {
        st = WT_ERROR(ctx, info < 0 ? WT_ERR_LIBRARY : WT_ERR_NUMERIC,
                      "LAPACKE_dpotrf of the %lld x %lld fitting matrix Σ HᵀH + εI returned %d (ε = %g; not positive "
                      "definite: raise recon.cg9.fit_regularization)",
                      (long long)nact, (long long)nact, (int)info, eps);
        goto fail;
    }
    WT_TRY(wt_triplet_compress(tr, Aout));
    *Fout = F;
    F = NULL;
fail:
    wt_fitting_free(fit);
    direction_ops_clear(&d);
    wt_triplet_free(tr);
    wt_free(ctx, act);
    wt_free(ctx, F);
    return st;
}

/* ---- the builder -------------------------------------------------------------------------------- */

static int layer_of(const wt_tomography *t, int64_t p)
{
    int l = 0;
    while (l + 1 < wt_tomography_nlayers(t) && p >= wt_tomography_layer_offset(t, l + 1)) l++;
    return l;
}

int wt_mvm_build(wt_context *ctx, wt_tomography *t, const wt_mvm_options *opt_in, wt_mvm **out)
{
    int st = WT_OK;
    wt_mvm_options opt;
    if (opt_in) opt = *opt_in;
    else wt_mvm_options_default(&opt);
    if (opt.block <= 0) opt.block = 256;
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = wt_tomography_nunknowns(t), ns = sys->nslopes, nact = sys->nact;
    const int L = wt_tomography_nlayers(t), nth = wt_context_threads(ctx);
    const int nb = (int)(opt.block < nact ? opt.block : (nact > 0 ? nact : 1));
    wt_mvm *mv = NULL;
    wt_mvm_stats stats = {0};
    wt_mvm_normal *nm = NULL;
    wt_interaction *ia = NULL;
    wt_sparse *Ahat = NULL, *Afit = NULL;
    wt_sparse *cmap = NULL;
    double *Fc = NULL, *X = NULL, *Zs = NULL, *Wt = NULL, *Fb = NULL, *work = NULL;
    double t0 = wt_time_now(), tt;
    double peak = 0.0;
    char detail[512];
    *out = NULL;
    if (opt.commands != WT_MVM_LAYER_VALUES && opt.commands != WT_MVM_FITTING)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_mvm_build: commands = %d, expected WT_MVM_LAYER_VALUES or WT_MVM_FITTING",
                        opt.commands);

    /* the command map first: a pcg3 layer/DM mismatch is a configuration error, found in milliseconds */
    if (opt.commands == WT_MVM_LAYER_VALUES) {
        WT_TRY(wt_reconstructor_command_map(ctx, t, &cmap));
    }
    WT_TRY(wt_interaction_alloc(ctx, sys, &ia));
    WT_TRY(wt_interaction_assemble(ia, &Ahat));
    wt_interaction_free(ia);
    ia = NULL;

    /* what the solve phase holds besides the factor: R, RÂ, Â, the block arrays (+ cg9's F and A) */
    const double out_bytes = 4.0 * (double)nact * ns + 4.0 * (double)nact * nact;
    double block_bytes = 8.0 * nb * (double)n + 16.0 * nb * (double)ns + 8.0 * nth * wt_mvm_priv_wavelet_work(t);
    double reserve = out_bytes + wt_mvm_priv_sparse_bytes(wt_sparse_nnz(Ahat), nact) + block_bytes;
    if (opt.commands == WT_MVM_FITTING) reserve += 8.0 * (double)nact * nact + 8.0 * (double)nact * nb;
    snprintf(detail, sizeof detail, "at least: R %.3g GB and RÂ %.3g GB in float32, Â, block workspace %.3g GB%s",
             4.0 * nact * ns / 1e9, 4.0 * nact * nact / 1e9, block_bytes / 1e9,
             opt.commands == WT_MVM_FITTING ? ", the dense fitting matrix" : "");
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &peak, "building the MVM", reserve, detail));

    if (opt.commands == WT_MVM_FITTING) {
        tt = wt_time_now();
        wt_mvm_priv_progress(&opt, "fitting", 0, 1);
        wt_fitting_params fp = {.regularization = opt.fit_regularization,
                                .sampling = opt.fit_sampling > 0 ? opt.fit_sampling : 1};
        WT_TRY(fitting_operators(ctx, t, &fp, &Fc, &Afit));
        reserve += wt_mvm_priv_sparse_bytes(wt_sparse_nnz(Afit), n);
        stats.t_fitting = wt_time_now() - tt;
        wt_mvm_priv_progress(&opt, "fitting", 1, 1);
    }

    WT_TRY(wt_mvm_normal_alloc(ctx, t, &opt, reserve, 0, &nm));
    {
        double tf = stats.t_fitting;
        wt_mvm_normal_stats(nm, &stats);
        stats.t_fitting = tf;
        if (peak > stats.peak_estimate) stats.peak_estimate = peak;
    }

    tt = wt_time_now();
    WT_TRY(wt_mvm_alloc(ctx, opt.commands, nact, ns, &mv));
    size_t ws = wt_mvm_priv_wavelet_work(t);
    WT_ALLOC(ctx, X, (size_t)n * nb, "right-hand side block");
    WT_ALLOC(ctx, Zs, (size_t)ns * nb, "slope block");
    WT_ALLOC(ctx, Wt, (size_t)ns * nb, "weighted slope block");
    WT_ALLOC(ctx, work, (size_t)nth * ws, "wavelet workspace");
    if (opt.commands == WT_MVM_FITTING) WT_ALLOC(ctx, Fb, (size_t)nact * nb, "fitting block");
    const wt_sparse *gp = wt_mvm_priv_normal_gp(nm);
    const int parts = opt.part_count > 1 ? opt.part_count : 1;
    if (parts > 1 && (opt.part_index < 0 || opt.part_index >= parts)) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "wt_mvm_build: part %d of %d", opt.part_index, parts);
        goto fail;
    }
    if (parts > 1) {
        memset(mv->R, 0, (size_t)nact * ns * sizeof *mv->R);
        memset(mv->RA, 0, (size_t)nact * nact * sizeof *mv->RA);
    }
    wt_mvm_priv_progress(&opt, "solve", 0, nact);
    for (int64_t i0 = 0, b = 0; i0 < nact; i0 += nb, b++) {
        const int cb = (int)(nact - i0 < nb ? nact - i0 : nb);
        if (b % parts != (parts > 1 ? opt.part_index : 0)) continue;
        /* X = Eᵀ[:, block]: coefficients of the command functionals */
        if (opt.commands == WT_MVM_FITTING) {
            /* Eᵀ = W Aᵀ F⁻¹: columns of F⁻¹, then Aᵀ, then W */
            memset(Fb, 0, (size_t)nact * cb * sizeof *Fb);
            for (int c = 0; c < cb; c++) Fb[(i0 + c) + nact * c] = 1.0;
            lapack_int info = LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', (lapack_int)nact, cb, Fc, (lapack_int)nact, Fb,
                                             (lapack_int)nact);
            if (info != 0) {
                st = WT_ERROR(ctx, WT_ERR_LIBRARY, "LAPACKE_dpotrs (fitting) returned %d", (int)info);
                goto fail;
            }
        }
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
        for (int c = 0; c < cb; c++) {
            double *x = X + (size_t)n * c, *wk = work + (size_t)wt_mvm_priv_thread() * ws;
            if (opt.commands == WT_MVM_LAYER_VALUES) {
                memset(x, 0, (size_t)n * sizeof *x);
                /* row i of S W⁻¹ = (W S[i, :]ᵀ)ᵀ: the actuator's layer weights, then W on the layers they touch */
                int touched[WT_MAX_LAYERS] = {0};
                for (int64_t k = cmap->colptr[i0 + c]; k < cmap->colptr[i0 + c + 1]; k++) {
                    x[cmap->rowind[k]] = cmap->val[k];
                    touched[layer_of(t, cmap->rowind[k])] = 1;
                }
                /* prediction: the weights on the layers moved back (S_dᵀ, below), each moving layer then dense */
                if (opt.predict_adjoint) continue;
                for (int l = 0; l < L; l++)
                    if (touched[l]) {
                        int64_t off = wt_tomography_layer_offset(t, l);
                        wt_wavelet_forward(wt_tomography_wavelet(t, l), x + off, x + off, wk);
                    }
            } else {
                const double *f = Fb + (size_t)nact * c;
                for (int64_t p = 0; p < n; p++) {
                    double s = 0.0;
                    for (int64_t k = Afit->colptr[p]; k < Afit->colptr[p + 1]; k++) s += Afit->val[k] * f[Afit->rowind[k]];
                    x[p] = s;
                }
                if (opt.predict_adjoint) continue;
                for (int l = 0; l < L; l++) {
                    int64_t off = wt_tomography_layer_offset(t, l);
                    wt_wavelet_forward(wt_tomography_wavelet(t, l), x + off, x + off, wk);
                }
            }
        }
        /* prediction: Eᵀ ← S_dᵀ Eᵀ on the layers' values, a column at a time (the shift runs its layers on the threads,
         * with its own per-thread scratch), then every layer to its coefficients */
        if (opt.predict_adjoint) {
            for (int c = 0; c < cb; c++) wt_shift_apply(opt.predict_adjoint, X + (size_t)n * c);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
            for (int c = 0; c < cb; c++) {
                double *x = X + (size_t)n * c, *wk = work + (size_t)wt_mvm_priv_thread() * ws;
                for (int l = 0; l < L; l++) {
                    int64_t off = wt_tomography_layer_offset(t, l);
                    wt_wavelet_forward(wt_tomography_wavelet(t, l), x + off, x + off, wk);
                }
            }
        }
        /* Y = M⁻¹ Eᵀ (in place) */
        WT_TRY(wt_mvm_normal_solve(nm, cb, X, X));
        /* Rᵀ[:, block] = Ĉ⁻¹ Γ P W⁻¹ Y,  RÂ rows = (Rᵀ[:, block])ᵀ Â */
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
        for (int c = 0; c < cb; c++) {
            double *y = X + (size_t)n * c, *z = Zs + (size_t)ns * c, *w = Wt + (size_t)ns * c;
            double *wk = work + (size_t)wt_mvm_priv_thread() * ws;
            for (int l = 0; l < L; l++) {
                int64_t off = wt_tomography_layer_offset(t, l);
                wt_wavelet_inverse(wt_tomography_wavelet(t, l), y + off, y + off, wk);
            }
            memset(z, 0, (size_t)ns * sizeof *z);
            memset(w, 0, (size_t)ns * sizeof *w);
            for (int64_t p = 0; p < n; p++) {
                double v = y[p];
                if (v == 0.0) continue;
                for (int64_t k = gp->colptr[p]; k < gp->colptr[p + 1]; k++) z[gp->rowind[k]] += gp->val[k] * v;
            }
            for (int m = 0; m < sys->nsensors; m++) {
                const wt_sensor *s = &sys->sensors[m];
                wt_noise_apply_weight(wt_tomography_noise(t, m), 1.0, z + s->offset, w + s->offset);
            }
            wt_tomography_weight_common(t, z, w); /* (recon.lgs_focus_mode = "common": the LGS's coupling term) */
            float *rrow = mv->R + (size_t)(i0 + c) * ns;
            for (int64_t k = 0; k < ns; k++) rrow[k] = (float)w[k];
            float *arow = mv->RA + (size_t)(i0 + c) * nact;
            for (int64_t a = 0; a < nact; a++) {
                double s = 0.0;
                for (int64_t k = Ahat->colptr[a]; k < Ahat->colptr[a + 1]; k++) s += Ahat->val[k] * w[Ahat->rowind[k]];
                arow[a] = (float)s;
            }
        }
        wt_mvm_priv_progress(&opt, "solve", i0 + cb, nact);
        if (opt.stop && i0 + cb < nact && opt.stop(opt.stop_user)) {
            st = WT_ERROR(ctx, WT_ERR_INTERRUPTED, "the MVM build was stopped after %lld of %lld rows",
                          (long long)(i0 + cb), (long long)nact);
            goto fail;
        }
    }
    stats.t_solve = wt_time_now() - tt;
    stats.t_total = wt_time_now() - t0;
    stats.cholmod_peak = wt_mvm_priv_normal_cholmod_peak(nm);
    mv->stats = stats;
    mv->predictive = opt.predict_adjoint != NULL;
    *out = mv;
    mv = NULL;
fail:
    wt_mvm_free(mv);
    wt_mvm_normal_free(nm);
    wt_interaction_free(ia);
    wt_sparse_free(Ahat);
    wt_sparse_free(Afit);
    wt_sparse_free(cmap);
    wt_free(ctx, Fc);
    wt_free(ctx, X);
    wt_free(ctx, Zs);
    wt_free(ctx, Wt);
    wt_free(ctx, Fb);
    wt_free(ctx, work);
    return st;
}

/* The matrix of variant `name` of cfg, with the model's r0, profile and wind replaced when natm > 0 (a sampled one
 * compressed as hats onto the variant's layers first). */
static int build_model(wt_context *ctx, const wt_system *sys, const wt_config *cfg, const char *name,
                       const wt_mvm_options *opt_in, double r0, int natm, const double *alt, const double *frac,
                       const double *vx, const double *vy, int sampled, wt_mvm **out)
{
    const double t0 = wt_time_now();
    const int cg9 = !strcmp(name, "cg9");
    const wt_recon_variant_config var = cg9 ? cfg->cg9 : cfg->pcg3; /* exact factorisation: no preconditioner */
    wt_mvm_options opt;
    if (opt_in) opt = *opt_in;
    else wt_mvm_options_default(&opt);
    opt.commands = cg9 ? WT_MVM_FITTING : WT_MVM_LAYER_VALUES;
    opt.fit_regularization = var.fit_regularization;
    opt.fit_sampling = var.fit_sampling;
    *out = NULL;
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    wt_reconstructor_params rp; /* the predictor's lead, and the configuration's wind */
    wt_reconstructor_params_from_config(cfg, cg9 ? WT_RECON_CG9 : WT_RECON_PCG3, -1, &rp);
    double wvx[WT_MAX_LAYERS], wvy[WT_MAX_LAYERS];
    for (int k = 0; k < rp.tomography.natm; k++) wvx[k] = rp.atm_vx[k], wvy[k] = rp.atm_vy[k];
    if (natm > 0) {
        if (natm > WT_MAX_LAYERS)
            return WT_ERROR(ctx, WT_ERR_INVALID, "MVM build: a model of %d layers (at most %d)", natm, WT_MAX_LAYERS);
        if (cfg->predict && (!vx || !vy))
            return WT_ERROR(ctx, WT_ERR_INVALID, "MVM build: key 'recon.predict' = true and a model without its wind");
        tp.r0 = r0;
        if (sampled) { /* the profile at the layers' own altitudes: the tomography's point compression keeps it */
            tp.natm = var.nlayers;
            for (int l = 0; l < var.nlayers; l++) tp.atm_altitude[l] = var.altitudes[l];
            wt_profile_compress_hats(natm, alt, frac, vx, vy, var.nlayers, var.altitudes, tp.atm_fraction,
                                     vx ? wvx : NULL, vy ? wvy : NULL);
        } else {
            tp.natm = natm;
            for (int k = 0; k < natm; k++) {
                tp.atm_altitude[k] = alt[k], tp.atm_fraction[k] = frac[k];
                if (vx && vy) wvx[k] = vx[k], wvy[k] = vy[k];
            }
        }
    }
    wt_tomography *t = NULL;
    wt_shift *adj = NULL;
    int st = wt_tomography_alloc(ctx, sys, &var, name, &tp, &t);
    if (st < 0) return st;
    /* the shift that pcg3 and cg9 make under recon.predict (core/model/reconstructor.c), moved back: the model's
     * profile and wind compressed onto the layers, over the configured lead */
    if (cfg->predict) {
        st = wt_predict_shift_alloc(ctx, t, tp.natm, tp.atm_altitude, tp.atm_fraction, wvx, wvy, -rp.predict_lead, &adj);
        opt.predict_adjoint = adj;
    }
    if (st >= 0) st = wt_mvm_build(ctx, t, &opt, out);
    wt_shift_free(adj);
    wt_tomography_free(t);
    /* built in float32 (the solves' output); stored and applied in the configured precision */
    if (st >= 0 && (st = wt_mvm_set_precision(*out, cfg->mvm_precision)) < 0) {
        wt_mvm_free(*out);
        *out = NULL;
    }
    if (st >= 0) (*out)->stats.t_total = wt_time_now() - t0;
    return st;
}

int wt_mvm_build_variant(wt_context *ctx, const wt_system *sys, const wt_config *cfg, const char *name,
                         const wt_mvm_options *opt_in, wt_mvm **out)
{
    return build_model(ctx, sys, cfg, name, opt_in, 0.0, 0, NULL, NULL, NULL, NULL, 0, out);
}

int wt_mvm_rebuild_model(void *user, double r0, int natm, const double *alt, const double *frac, const double *vx,
                         const double *vy, int sampled, wt_mvm **out)
{
    const wt_mvm_rebuilder *rb = user;
    if (natm < 1) return WT_ERROR(rb->ctx, WT_ERR_INVALID, "MVM rebuild: a model without layers");
    return build_model(rb->ctx, rb->sys, rb->sys->cfg, rb->variant, rb->opt, r0, natm, alt, frac, vx, vy, sampled, out);
}
