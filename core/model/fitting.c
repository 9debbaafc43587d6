/* core/model/fitting.c: DM fitting over the evaluation directions (paper eq. fit_step_min):
 *
 *   (Σ_j H_jᵀ H_j + ε I) a = Σ_j H_jᵀ P_j φ,
 *
 * by warm-started CG on the matrix-free operator, or by the Cholesky factor of the assembled matrix
 * (CHOLMOD, core/la/chol.h): the matrix is the same every frame, so the factor is computed once. */
#include "fitting.h"

#include <stdio.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../la/chol.h"
#include "../la/vec.h"
#include "tomography.h"
#include "../op/projection.h"
#include "../op/pupil.h"

struct wt_fitting {
    wt_context *ctx;
    const wt_system *sys;
    int ndir, L;
    wt_grid sample;         /* the pupil-plane grid the fit is sampled on */
    uint8_t *mask;          /* its sample points */
    wt_projection **dm;     /* ndir: H_j (all DM grids, concatenated) */
    wt_projection **layer;  /* ndir: P_j (all layers, concatenated) */
    int64_t nlayer_pts, ndm_pts, ncg;
    double eps;
    int nthreads;
    double *grids;          /* ndm_pts: expanded commands */
    double *ygrid;          /* ndm_pts: Σ Hᵀ H on the grids */
    double *acc;            /* WT_GROUPS x ndm_pts */
    int *group;             /* direction → accumulator group */
    double *pupil;          /* WT_GROUPS x ncg (fast) or ndir x ncg (reference): P_j φ or H_j a on the samples */
    double *rowwork;        /* WT_GROUPS x nrowwork: wt_projection_apply_rows' layer rows (fast) */
    int64_t nrowwork;
    double *b;              /* nact: the public forms' scratch, the maps solve's right-hand side */
    wt_pcg *pcg;
    int solver;             /* WT_FIT_CG or WT_FIT_CHOLESKY */
    wt_chol *chol;          /* WT_FIT_CHOLESKY: the factor of N */
    int factor_float32;     /* its solves read a float32 copy of L */
    int reference;          /* the frame's reference kernels (wt_fitting_params.reference) */
    wt_fitting_stats stats;
};

/* out = Σ_j H_jᵀ S_j in, on the full DM grids: S_j = H_j (normal operator, in = DM grids) or P_j
 * (right-hand side, in = layers). Fixed groups of directions keep the sum's order (core/la/vec.h). */
static void project_back(wt_fitting *f, wt_projection *const *src, const double *in, double *out)
{
    const int64_t nd = f->ndm_pts;
#pragma omp parallel for schedule(static) num_threads(f->nthreads)
    for (int g = 0; g < WT_GROUPS; g++) {
        double *acc = f->acc + (size_t)g * nd;
        memset(acc, 0, (size_t)nd * sizeof *acc);
        for (int j = 0; j < f->ndir; j++) {
            if (f->group[j] != g) continue;
            /* a group's directions one after another through the group's buffer (228 KB at E-ELT: it stays in
             * the core's L2 between P_j and H_jᵀ); the reference kernels give each direction its own (25
             * buffers, 5.7 MB, streamed through memory): the same values, the same bits */
            double *pu = f->pupil + (size_t)(f->reference ? j : g) * f->ncg;
            if (f->reference) {
                memset(pu, 0, (size_t)f->ncg * sizeof *pu);
                wt_projection_apply(src[j], 1.0, in, pu);
            } else { /* the sample points overwritten (H_jᵀ reads no other) */
                wt_projection_apply_rows(src[j], 1.0, in, pu, f->rowwork + (size_t)g * f->nrowwork, 0);
            }
            if (f->reference) wt_projection_apply_t(f->dm[j], 1.0, pu, acc);
            else wt_projection_apply_t_side(f->dm[j], 1.0, pu, acc);
        }
    }
    wt_vec_sum_groups(f->acc, nd, out);
}

static void normal_grids(wt_fitting *f, const double *grids, double *out) { project_back(f, f->dm, grids, out); }

/* y = (Σ H_jᵀ H_j + ε I) a, overwritten: the operator of the CG */
static void normal(wt_fitting *f, const double *a, double *y)
{
    wt_dm_expand(f->sys->dm, a, f->grids);
    normal_grids(f, f->grids, f->ygrid);
    wt_dm_restrict(f->sys->dm, f->ygrid, y);
    for (int64_t i = 0; i < f->sys->nact; i++) y[i] += f->eps * a[i];
}

static void apply_cb(void *user, const double *x, double *y) { normal((wt_fitting *)user, x, y); }

/* The public forms accumulate (y ← y + α A x); f->b, the solve's right-hand side, is their scratch. */
void wt_fitting_apply(wt_fitting *f, double alpha, const double *a, double *y)
{
    normal(f, a, f->b);
    for (int64_t i = 0; i < f->sys->nact; i++) y[i] += alpha * f->b[i];
}

static void rhs(wt_fitting *f, const double *phi, double *b)
{
    project_back(f, f->layer, phi, f->grids);
    wt_dm_restrict(f->sys->dm, f->grids, b);
}

void wt_fitting_rhs(wt_fitting *f, double alpha, const double *phi, double *b)
{
    rhs(f, phi, f->b);
    for (int64_t i = 0; i < f->sys->nact; i++) b[i] += alpha * f->b[i];
}

void wt_fitting_rhs_maps(wt_fitting *f, const double *maps, double *b)
{
    const int64_t nd = f->ndm_pts;
#pragma omp parallel for schedule(static) num_threads(f->nthreads)
    for (int g = 0; g < WT_GROUPS; g++) {
        double *acc = f->acc + (size_t)g * nd;
        memset(acc, 0, (size_t)nd * sizeof *acc);
        for (int j = 0; j < f->ndir; j++)
            if (f->group[j] == g) wt_projection_apply_t(f->dm[j], 1.0, maps + (size_t)j * f->ncg, acc);
    }
    wt_vec_sum_groups(f->acc, nd, f->grids);
    wt_dm_restrict(f->sys->dm, f->grids, b);
}

/* a = N⁻¹ b by the factor (b and a distinct or the same); res and history as a CG that converged at once */
static int direct(wt_fitting *f, const double *b, double *a, double *history, wt_pcg_result *res)
{
    if (res) *res = (wt_pcg_result){0, 0.0};
    if (history) history[0] = 0.0;
    return wt_chol_solve_one(f->chol, b, a);
}

int wt_fitting_solve_maps(wt_fitting *f, const double *maps, double *a, int max_iter, double rtol,
                          wt_pcg_result *res)
{
    wt_fitting_rhs_maps(f, maps, f->b);
    if (f->chol) return direct(f, f->b, a, NULL, res);
    return wt_pcg_solve(f->pcg, apply_cb, f, NULL, f->b, a, max_iter, rtol, NULL, res);
}

const wt_grid *wt_fitting_sample_grid(const wt_fitting *f) { return &f->sample; }
const uint8_t *wt_fitting_sample_mask(const wt_fitting *f) { return f->mask; }

int wt_fitting_sampling(wt_context *ctx, const wt_system *sys, int q, wt_grid *grid, uint8_t **mask)
{
    int st = WT_OK;
    *mask = NULL;
    if (q < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "fitting sampling %d: expected >= 1 point per subaperture", q);
    /* q = 1: the Fried corners of the valid subapertures (the sensors' own sample points); q > 1: the
     * points of the d/q grid inside the pupil annulus, the points the evaluation weights */
    *grid = q == 1 ? sys->corner_grid : wt_grid_centred(sys->n * q + 1, sys->d / q);
    uint8_t *m = NULL;
    WT_ALLOC(ctx, m, wt_grid_size(grid), "fitting sample mask");
    if (q == 1) memcpy(m, sys->corner_mask, (size_t)wt_grid_size(grid));
    else wt_pupil_mask_points(sys->diameter, sys->obstruction, grid, m);
    *mask = m;
    return WT_OK;
fail:
    return st;
}


static int solve(wt_fitting *f, const double *phi, double *a, int continuing, int max_iter, double rtol,
                 double *history, wt_pcg_result *res)
{
    if (f->chol) {
        rhs(f, phi, f->b);
        return direct(f, f->b, a, history, res);
    }
    rhs(f, phi, wt_pcg_rhs(f->pcg));
    return wt_pcg_solve_rhs(f->pcg, apply_cb, f, NULL, NULL, NULL, a, continuing, max_iter, rtol, history, res);
}

int wt_fitting_solve(wt_fitting *f, const double *phi, double *a, int max_iter, double rtol, double *history,
                     wt_pcg_result *res)
{
    return solve(f, phi, a, 0, max_iter, rtol, history, res);
}

int wt_fitting_solve_continue(wt_fitting *f, const double *phi, double *a, int max_iter, double rtol,
                              double *history, wt_pcg_result *res)
{
    return solve(f, phi, a, 1, max_iter, rtol, history, res);
}

double wt_fitting_epsilon(const wt_fitting *f) { return f->eps; }
int wt_fitting_solver(const wt_fitting *f) { return f->solver; }
void wt_fitting_stats_get(const wt_fitting *f, wt_fitting_stats *stats) { *stats = f->stats; }

int wt_fitting_assemble(const wt_fitting *f, wt_sparse **out)
{
    int st = WT_OK;
    wt_context *ctx = f->ctx;
    const wt_system *sys = f->sys;
    const int64_t ndm = f->ndm_pts;
    wt_sparse *sum = NULL, *H = NULL, *Ht = NULL, *HtH = NULL, *t = NULL;
    wt_triplet *tr = NULL;
    int64_t *act = NULL;
    *out = NULL;
    /* Σ_j H_jᵀ H_j on the full DM grids, direction after direction (a running sum: the 25 products side by
     * side would hold ~6 times the sum's non-zeros) */
    for (int j = 0; j < f->ndir; j++) {
        WT_TRY(wt_projection_assemble(f->dm[j], &H));
        WT_TRY(wt_sparse_transpose(H, &Ht));
        WT_TRY(wt_sparse_multiply(Ht, H, &HtH));
        wt_sparse_free(H);
        wt_sparse_free(Ht);
        H = Ht = NULL;
        if (!sum) {
            sum = HtH;
        } else {
            WT_TRY(wt_sparse_add(sum, 1.0, HtH, 1.0, &t));
            wt_sparse_free(sum);
            wt_sparse_free(HtH);
            sum = t;
            t = NULL;
        }
        HtH = NULL;
    }
    /* the active actuators' rows and columns, + ε on the diagonal (wt_dm_restrict ∘ · ∘ wt_dm_expand + εI) */
    WT_ALLOC(ctx, act, ndm, "fitting actuator map");
    wt_dm_actuator_index(sys->dm, act);
    WT_TRY(wt_triplet_alloc(ctx, sys->nact, sys->nact, (sum ? wt_sparse_nnz(sum) : 0) + sys->nact, &tr));
    for (int64_t c = 0; c < ndm; c++) {
        if (act[c] < 0) continue;
        for (int64_t k = sum ? sum->colptr[c] : 0; k < (sum ? sum->colptr[c + 1] : 0); k++)
            if (act[sum->rowind[k]] >= 0) WT_TRY(wt_triplet_add(tr, act[sum->rowind[k]], act[c], sum->val[k]));
        WT_TRY(wt_triplet_add(tr, act[c], act[c], f->eps));
    }
    WT_TRY(wt_triplet_compress(tr, out));
fail:
    wt_sparse_free(sum);
    wt_sparse_free(H);
    wt_sparse_free(Ht);
    wt_sparse_free(HtH);
    wt_sparse_free(t);
    wt_triplet_free(tr);
    wt_free(ctx, act);
    return st;
}

/* WT_FIT_CHOLESKY's set-up: N assembled, analysed and factored; one solve sizes CHOLMOD's workspace so that
 * no frame allocates. */
static int factorize(wt_fitting *f, double regularization)
{
    int st = WT_OK;
    wt_sparse *N = NULL;
    double t0 = wt_time_now();
    WT_TRY(wt_fitting_assemble(f, &N));
    f->stats.t_assemble = wt_time_now() - t0;
    f->stats.nnz_matrix = wt_sparse_nnz(N);
    t0 = wt_time_now();
    WT_TRY(wt_chol_analyze(f->ctx, N, &f->chol));
    st = wt_chol_factorize(f->chol, N);
    if (st == WT_ERR_NUMERIC) {
        char detail[1024];
        snprintf(detail, sizeof detail, "%s", wt_error_message(f->ctx));
        st = WT_ERROR(f->ctx, WT_ERR_NUMERIC, "fitting: the normal matrix Σ HᵀH + εI (ε = %g, recon.cg9.fit_regularization "
                      "= %g) is not positive definite: raise recon.cg9.fit_regularization (%s)", f->eps, regularization,
                      detail);
    }
    if (st < 0) goto fail;
    WT_TRY(wt_chol_prepare_one(f->chol, f->factor_float32, f->nthreads > 1 ? 2 : 1));
    wt_chol_one_reference(f->chol, f->reference);
    f->stats.t_factorize = wt_time_now() - t0;
    wt_chol_info info;
    wt_chol_info_get(f->chol, &info);
    f->stats.nnz_factor = info.nnz_factor;
    f->stats.factor_bytes = info.factor_bytes + wt_chol_one_bytes(f->chol);
    f->stats.ordering = info.ordering;
    f->stats.solve_bytes = wt_chol_one_bytes(f->chol);
    wt_chol_split(f->chol, &f->stats.split[0], &f->stats.split[1], &f->stats.split[2]);
fail:
    wt_sparse_free(N);
    return st;
}

double wt_fitting_bytes(const wt_fitting *f)
{
    /* projection stencils: ~24 bytes per sample point, per DM (H_j) and per layer (P_j), per direction, as
     * wt_tomography_bytes counts them; the grids' workspaces; the CG's 4 vectors and 2 right-hand sides */
    int64_t npts = 0;
    for (int64_t i = 0; i < f->ncg; i++) npts += f->mask[i] != 0;
    const double nd = (double)f->ndm_pts, na = (double)f->sys->nact;
    return 24.0 * (double)npts * f->ndir * (f->sys->dm->ndms + f->L) + 8.0 * nd * (2.0 + WT_GROUPS) +
           8.0 * (f->reference ? f->ndir : WT_GROUPS) * (double)f->ncg + 8.0 * na * 7.0 + (double)f->ncg + f->stats.factor_bytes +
           (f->chol ? 8.0 * 5.0 * na : 0.0); /* the solves' vectors: y, the two buffers, the workspaces */
}

int wt_fitting_alloc(wt_context *ctx, const wt_system *sys, int nlayers, const wt_grid *layers,
                     const double *altitudes, const wt_fitting_params *par, wt_fitting **out)
{
    const double regularization = par->regularization;
    int st = WT_OK;
    wt_fitting *f = NULL;
    *out = NULL;
    if (par->solver != WT_FIT_CG && par->solver != WT_FIT_CHOLESKY)
        return WT_ERROR(ctx, WT_ERR_INVALID, "fitting solver %d: expected %d (cg) or %d (cholesky) "
                        "(recon.cg9.fit_solver)", par->solver, WT_FIT_CG, WT_FIT_CHOLESKY);
    WT_ALLOC(ctx, f, 1, "fitting");
    f->solver = par->solver;
    f->factor_float32 = par->factor_float32 != 0;
    f->reference = par->reference != 0;
    f->ctx = ctx;
    f->sys = sys;
    f->ndir = sys->neval;
    f->L = nlayers;
    WT_TRY(wt_fitting_sampling(ctx, sys, par->sampling, &f->sample, &f->mask));
    f->ncg = wt_grid_size(&f->sample);
    f->ndm_pts = wt_dm_grid_points(sys->dm);
    for (int l = 0; l < nlayers; l++) f->nlayer_pts += wt_grid_size(&layers[l]);
    /* small DM sets: serial is faster than a parallel region (see core/model/tomography.c) */
    f->nthreads = f->ndm_pts < 4096 ? 1 : wt_context_threads(ctx);
    WT_ALLOC(ctx, f->dm, f->ndir, "fitting DM projections");
    WT_ALLOC(ctx, f->layer, f->ndir, "fitting layer projections");
    for (int j = 0; j < f->ndir; j++) {
        /* DMs may be seen beyond their actuator grid at the field corners: zero influence there */
        WT_TRY(wt_dm_influence_alloc(ctx, sys->dm, 0.0, sys->eval_x[j],
                                   sys->eval_y[j], &f->sample, f->mask, &f->dm[j]));
        if (nlayers == 0) continue; /* a fit of given maps only (wt_fitting_solve_maps) */
        st = wt_projection_alloc(ctx, nlayers, layers, altitudes, 0.0, sys->eval_x[j], sys->eval_y[j],
                                 &f->sample, f->mask, 0, &f->layer[j]);
        if (st < 0) {
            char detail[1024]; /* the message is formatted into the buffer it quotes: copy it first */
            snprintf(detail, sizeof detail, "%s", wt_error_message(ctx));
            st = WT_ERROR(ctx, WT_ERR_CONFIG,
                          "%s: the cg9 reconstruction layers do not cover evaluation direction %d (%.1f\", %.1f\"): %s",
                          sys->source, j + 1, sys->eval_x[j] / WT_ARCSEC, sys->eval_y[j] / WT_ARCSEC, detail);
            goto fail;
        }
    }
    WT_ALLOC(ctx, f->grids, f->ndm_pts, "fitting grids");
    WT_ALLOC(ctx, f->ygrid, f->ndm_pts, "fitting grids");
    WT_ALLOC(ctx, f->acc, (size_t)WT_GROUPS * f->ndm_pts, "fitting accumulators");
    WT_ALLOC(ctx, f->group, f->ndir, "fitting groups");
    {
        double *cost = NULL;
        WT_ALLOC(ctx, cost, f->ndir, "fitting group costs");
        for (int j = 0; j < f->ndir; j++) cost[j] = 1.0;
        wt_vec_groups(f->ndir, cost, f->group);
        wt_free(ctx, cost);
    }
    WT_ALLOC(ctx, f->pupil, (size_t)(f->reference ? f->ndir : WT_GROUPS) * f->ncg, "fitting pupil workspace");
    for (int j = 0; j < f->ndir; j++) {
        if (wt_projection_rows_work(f->dm[j]) > f->nrowwork) f->nrowwork = wt_projection_rows_work(f->dm[j]);
        if (f->layer[j] && wt_projection_rows_work(f->layer[j]) > f->nrowwork) f->nrowwork = wt_projection_rows_work(f->layer[j]);
    }
    WT_ALLOC(ctx, f->rowwork, (size_t)WT_GROUPS * f->nrowwork, "fitting row workspace");
    WT_ALLOC(ctx, f->b, sys->nact, "fitting right-hand side");
    WT_TRY(wt_pcg_alloc(ctx, sys->nact, &f->pcg));

    /* ε relative to the mean diagonal of Σ H_jᵀ H_j: probe the diagonal with unit actuators spread
     * far enough apart that their influence functions never overlap in the pupil (stride 3 > 2). */
    {
        double *a = NULL, *y = NULL, *diag_grid = NULL;
        WT_ALLOC(ctx, a, sys->nact, "fitting probe");
        y = wt_calloc(ctx, (size_t)f->ndm_pts, sizeof *y);
        diag_grid = wt_calloc(ctx, (size_t)f->ndm_pts, sizeof *diag_grid);
        if (!y || !diag_grid) {
            wt_free(ctx, a);
            wt_free(ctx, y);
            wt_free(ctx, diag_grid);
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory probing the fitting diagonal");
            goto fail;
        }
        /* exact diagonal Σ_j Σ_points w² by probing one DM at a time on a stride-3 lattice: two probes
         * on the same DM never share a pupil point; different DMs are probed separately */
        double sum = 0.0;
        int64_t p0 = 0;
        for (int k = 0; k < sys->dm->ndms; k++) {
            const wt_grid *g = &sys->dm->grid[k];
            for (int oy = 0; oy < 3; oy++)
                for (int ox = 0; ox < 3; ox++) {
                    memset(f->grids, 0, (size_t)f->ndm_pts * sizeof *f->grids);
                    for (int iy = oy; iy < g->ny; iy += 3)
                        for (int ix = ox; ix < g->nx; ix += 3)
                            if (sys->dm->active[k][ix + (int64_t)g->nx * iy]) f->grids[p0 + ix + (int64_t)g->nx * iy] = 1.0;
                    /* ⟨e_i, Hᵀ H e_i⟩ = ‖H e_i‖²; with non-overlapping probes Hᵀ H (Σ e_i) at i gives it */
                    normal_grids(f, f->grids, y);
                    for (int64_t i = 0; i < wt_grid_size(g); i++)
                        if (f->grids[p0 + i] != 0.0) diag_grid[p0 + i] = y[p0 + i];
                }
            p0 += wt_grid_size(g);
        }
        wt_dm_restrict(sys->dm, diag_grid, a);
        for (int64_t i = 0; i < sys->nact; i++) sum += a[i];
        f->eps = regularization * sum / (double)sys->nact;
        wt_free(ctx, a);
        wt_free(ctx, y);
        wt_free(ctx, diag_grid);
    }
    if (f->solver == WT_FIT_CHOLESKY) WT_TRY(factorize(f, regularization));
    *out = f;
    return WT_OK;
fail:
    wt_fitting_free(f);
    return st;
}

int wt_fitting_alloc_for(wt_context *ctx, const wt_tomography *t, const wt_fitting_params *par, wt_fitting **out)
{
    wt_grid grids[WT_MAX_LAYERS];
    double alts[WT_MAX_LAYERS];
    const int L = wt_tomography_nlayers(t);
    for (int l = 0; l < L; l++) {
        grids[l] = *wt_tomography_layer_grid(t, l);
        alts[l] = wt_tomography_layer_altitude(t, l);
    }
    return wt_fitting_alloc(ctx, wt_tomography_system(t), L, grids, alts, par, out);
}

void wt_fitting_free(wt_fitting *f)
{
    if (!f) return;
    wt_context *ctx = f->ctx;
    for (int j = 0; j < f->ndir; j++) {
        if (f->dm) wt_projection_free(f->dm[j]);
        if (f->layer) wt_projection_free(f->layer[j]);
    }
    wt_free(ctx, f->dm);
    wt_free(ctx, f->layer);
    wt_free(ctx, f->mask);
    wt_free(ctx, f->grids);
    wt_free(ctx, f->ygrid);
    wt_free(ctx, f->acc);
    wt_free(ctx, f->group);
    wt_free(ctx, f->pupil);
    wt_free(ctx, f->rowwork);
    wt_free(ctx, f->b);
    wt_pcg_free(f->pcg);
    wt_chol_free(f->chol);
    wt_free(ctx, f);
}
