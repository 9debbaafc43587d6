/* builder/mvm_normal.c: the factorised MAP normal matrix of the MVM builder (SPEC §9, §7; paper eq.
 * eqn_lse): N = Σ_LGS Ã_mᵀ C̃_m⁻¹ Ã_m + α D assembled column by column (Ã from mvm_assemble.c) and
 * factorised by CHOLMOD, the LGS tip-tilt removal and the NGS as the low-rank B Q Bᵀ, and solves with
 * M = N + B Q Bᵀ by Sherman–Morrison–Woodbury (the derivation is in mvm_build.h). With the full prior
 * (α W C_φ⁻¹ Wᵀ, dense on every layer) N is formed dense and factorised by LAPACK instead. */
#include "mvm_private.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "../core/la/chol.h"
#include "../core/op/noise.h"

/* ---- N = Gᵀ G + α D (upper triangle) ------------------------------------------------------------
 * The two rows of G of one subaperture (x and y, mixed by Lᵀ) have the same pattern
 * (wt_mvm_priv_atilde_column emits both of a touched pair), so Gᵀ is stored by pairs: one row list, two
 * value arrays. The product then walks each index list once for both rows, halving the index traffic
 * of both passes. */

typedef struct {
    int64_t npairs;
    int64_t *colptr, *rowind; /* pair p: rowind[colptr[p] … colptr[p+1]), rows (unknowns) sorted */
    double *vx, *vy;
} pair_transpose;

static void pair_transpose_free(wt_context *ctx, pair_transpose *f)
{
    wt_free(ctx, f->colptr);
    wt_free(ctx, f->rowind);
    wt_free(ctx, f->vx);
    wt_free(ctx, f->vy);
    memset(f, 0, sizeof *f);
}

static double pair_transpose_bytes(int64_t nnz, int64_t npairs) { return 24.0 * (double)nnz / 2.0 + 8.0 * (npairs + 1); }

/* pair_of: pair index of each x-row (−1 for y-rows); partner: the other row of the pair. */
static int pair_transpose_alloc(wt_context *ctx, const wt_sparse *G, const int64_t *pair_of, const int64_t *partner,
                                int64_t npairs, pair_transpose *f)
{
    int st = WT_OK;
    int64_t *last = NULL;
    memset(f, 0, sizeof *f);
    f->npairs = npairs;
    WT_ALLOC(ctx, f->colptr, npairs + 1, "paired transpose");
    for (int64_t k = 0; k < wt_sparse_nnz(G); k++)
        if (pair_of[G->rowind[k]] >= 0) f->colptr[pair_of[G->rowind[k]] + 1]++;
    for (int64_t p = 0; p < npairs; p++) f->colptr[p + 1] += f->colptr[p];
    int64_t nnz = f->colptr[npairs];
    WT_ALLOC(ctx, f->rowind, nnz, "paired transpose");
    WT_ALLOC(ctx, f->vx, nnz, "paired transpose");
    WT_ALLOC(ctx, f->vy, nnz, "paired transpose");
    WT_ALLOC(ctx, last, npairs + 1, "paired transpose cursor");
    memcpy(last, f->colptr, (size_t)npairs * sizeof *last);
    for (int64_t j = 0; j < G->ncol; j++) {
        /* x-rows come first in a column only within a sensor, so take the x entries, then the y */
        for (int64_t k = G->colptr[j]; k < G->colptr[j + 1]; k++) {
            int64_t p = pair_of[G->rowind[k]];
            if (p < 0) continue;
            f->rowind[last[p]] = j;
            f->vx[last[p]++] = G->val[k];
        }
        for (int64_t k = G->colptr[j]; k < G->colptr[j + 1]; k++) {
            int64_t r = G->rowind[k];
            if (pair_of[r] >= 0) continue;
            int64_t p = pair_of[partner[r]];
            f->vy[last[p] - 1] = G->val[k]; /* the pair's entry of column j was the last one written */
        }
    }
    wt_free(ctx, last);
    return WT_OK;
fail:
    wt_free(ctx, last);
    pair_transpose_free(ctx, f);
    return st;
}

typedef struct {
    const wt_sparse *G;       /* nslopes_lgs x n */
    const pair_transpose *F;  /* Gᵀ by pairs */
    const int64_t *pair_of, *partner;
    const double *alpha_d;
} ncol_ctx;

static int64_t normal_column(const void *cv, int64_t j, wt_mvm_priv_col_work *w, int64_t *rows, double *vals)
{
    const ncol_ctx *c = cv;
    const wt_sparse *G = c->G;
    const pair_transpose *F = c->F;
    double *gval = w->out; /* G(:, j) scattered by row (sized ≥ the LGS rows) */
    int64_t cnt = 0;
    w->mark[j] = j; /* the diagonal always exists: α D > 0 */
    w->list[cnt++] = j;
    w->acc[j] = c->alpha_d[j];
    if (vals)
        for (int64_t kg = G->colptr[j]; kg < G->colptr[j + 1]; kg++) gval[G->rowind[kg]] = G->val[kg];
    for (int64_t kg = G->colptr[j]; kg < G->colptr[j + 1]; kg++) {
        int64_t p = c->pair_of[G->rowind[kg]];
        if (p < 0) continue;
        double gx = vals ? G->val[kg] : 0.0, gy = vals ? gval[c->partner[G->rowind[kg]]] : 0.0;
        for (int64_t q = F->colptr[p]; q < F->colptr[p + 1]; q++) {
            int64_t i = F->rowind[q];
            if (i > j) break; /* upper triangle only; the lists are sorted */
            if (w->mark[i] != j) {
                w->mark[i] = j;
                w->list[cnt++] = i;
                w->acc[i] = 0.0;
            }
            if (vals) w->acc[i] += gx * F->vx[q] + gy * F->vy[q];
        }
    }
    return wt_mvm_priv_emit(w, j, cnt, rows, vals, w->acc);
}

/* ---- the normal object -------------------------------------------------------------------------- */

struct wt_mvm_normal {
    wt_context *ctx;
    wt_tomography *t;
    const wt_system *sys;
    int64_t n, ns;
    int nth;
    wt_sparse *gp;      /* Γ P: nslopes x n (kept: the builder maps layers to slopes with it) */
    wt_sparse *N;       /* upper triangle of N (NULL unless keep_matrix; sparse path) */
    wt_chol *chol;      /* sparse path: CHOLMOD's factor of N */
    double *L;          /* dense path (full prior): n x n column-major, N's Cholesky factor in the lower triangle */
    double *Nd;         /* dense path with keep_matrix: N's lower triangle */
    int r;              /* rank of the correction */
    double *B, *Z;      /* n x r each: B and N⁻¹ B */
    double *Q;          /* r x r */
    double *K;          /* r x r: LU of I + Q Bᵀ Z */
    lapack_int *ipiv;
    int maxblock;
    double *s1, *s2;    /* r x maxblock scratch */
    wt_mvm_stats stats;
};

int64_t wt_mvm_normal_size(const wt_mvm_normal *nm) { return nm->n; }
int wt_mvm_normal_rank(const wt_mvm_normal *nm) { return nm->r; }
void wt_mvm_normal_stats(const wt_mvm_normal *nm, wt_mvm_stats *stats) { *stats = nm->stats; }
const wt_sparse *wt_mvm_priv_normal_gp(const wt_mvm_normal *nm) { return nm->gp; }

double wt_mvm_priv_normal_cholmod_peak(const wt_mvm_normal *nm)
{
    if (!nm->chol) return 0.0;
    wt_chol_info ci;
    wt_chol_info_get(nm->chol, &ci);
    return ci.peak_bytes;
}

void wt_mvm_normal_free(wt_mvm_normal *nm)
{
    if (!nm) return;
    wt_context *ctx = nm->ctx;
    wt_sparse_free(nm->gp);
    wt_sparse_free(nm->N);
    wt_chol_free(nm->chol);
    wt_free(ctx, nm->L);
    wt_free(ctx, nm->Nd);
    wt_free(ctx, nm->B);
    wt_free(ctx, nm->Z);
    wt_free(ctx, nm->Q);
    wt_free(ctx, nm->K);
    wt_free(ctx, nm->ipiv);
    wt_free(ctx, nm->s1);
    wt_free(ctx, nm->s2);
    wt_free(ctx, nm);
}

/* phi = (Γ P)ᵀ z, then c = W phi layer by layer: one column of Ãᵀ z. */
static void adjoint_column(const wt_mvm_normal *nm, const double *z, double *c, double *work)
{
    const wt_sparse *gp = nm->gp;
    for (int64_t p = 0; p < gp->ncol; p++) {
        double s = 0.0;
        for (int64_t k = gp->colptr[p]; k < gp->colptr[p + 1]; k++) s += gp->val[k] * z[gp->rowind[k]];
        c[p] = s;
    }
    for (int l = 0; l < wt_tomography_nlayers(nm->t); l++) {
        int64_t off = wt_tomography_layer_offset(nm->t, l);
        wt_wavelet_forward(wt_tomography_wavelet(nm->t, l), c + off, c + off, work);
    }
}

/* X = N⁻¹ B (nrhs columns, leading dimensions ldb, ldx ≥ n; b and x may be the same array): CHOLMOD's
 * factor, or the dense one by LAPACK (dpotrs works in place, so b is copied to x first). */
static int factor_solve(const wt_mvm_normal *nm, int64_t nrhs, const double *b, int64_t ldb, double *x, int64_t ldx)
{
    if (!nm->L) return wt_chol_solve(nm->chol, nrhs, b, ldb, x, ldx);
    const int64_t n = nm->n;
    if (x != b)
        for (int64_t j = 0; j < nrhs; j++) memcpy(x + j * ldx, b + j * ldb, (size_t)n * sizeof *x);
    lapack_int info = LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', (lapack_int)n, (lapack_int)nrhs, nm->L, (lapack_int)n, x,
                                     (lapack_int)ldx);
    if (info != 0) return WT_ERROR(nm->ctx, WT_ERR_LIBRARY, "LAPACKE_dpotrs (dense normal matrix) returned %d", (int)info);
    return WT_OK;
}

/* The dense path of the full prior: L = the lower triangle of N (its sparse upper triangle Nu holds
 * GᵀG + α diag(W C_φ⁻¹ Wᵀ)) with each layer's diagonal block replaced by the whole α W C_φ⁻¹ Wᵀ,
 * formed column by column by the tomography's own prior apply (so the matrix is the operator's, to
 * rounding), then factorised in place by LAPACK's blocked Cholesky (OpenBLAS threads). */
static int dense_factor(wt_mvm_normal *nm, const wt_sparse *Nu, int keep_matrix)
{
    int st = WT_OK;
    wt_context *ctx = nm->ctx;
    const int64_t n = nm->n;
    const double *ad = wt_tomography_alpha_prior(nm->t);
    double *e = NULL;
    WT_ALLOC(ctx, nm->L, (size_t)n * n, "dense normal matrix");
    for (int64_t j = 0; j < n; j++)
        for (int64_t k = Nu->colptr[j]; k < Nu->colptr[j + 1]; k++) nm->L[j + (size_t)n * Nu->rowind[k]] = Nu->val[k];
    int64_t nmax = 0;
    for (int l = 0; l < wt_tomography_nlayers(nm->t); l++) {
        int64_t nl = wt_tomography_layer_offset(nm->t, l + 1) - wt_tomography_layer_offset(nm->t, l);
        if (nl > nmax) nmax = nl;
    }
    /* per thread: a unit vector, the column, the prior apply's work (each column independent: same bits on
     * any number of threads) */
    const size_t pw = wt_tomography_prior_layer_work(nm->t), stride = 2 * (size_t)nmax + pw;
    WT_ALLOC(ctx, e, (size_t)nm->nth * stride, "prior column workspace");
    for (int l = 0; l < wt_tomography_nlayers(nm->t); l++) {
        const int64_t a = wt_tomography_layer_offset(nm->t, l), nl = wt_tomography_layer_offset(nm->t, l + 1) - a;
#pragma omp parallel for schedule(dynamic, 16) num_threads(nm->nth)
        for (int64_t j = 0; j < nl; j++) {
            double *u = e + (size_t)wt_mvm_priv_thread() * stride, *yc = u + nmax;
            memset(u, 0, (size_t)nl * sizeof *u);
            memset(yc, 0, (size_t)nl * sizeof *yc);
            u[j] = 1.0;
            wt_tomography_prior_apply_layer_ws(nm->t, l, u, yc, yc + nmax);
            yc[j] -= ad[a + j]; /* N's diagonal already holds the prior's diagonal */
            double *col = nm->L + (size_t)n * (a + j) + a;
            for (int64_t i = j; i < nl; i++) col[i] += yc[i];
        }
    }
    if (keep_matrix) {
        WT_ALLOC(ctx, nm->Nd, (size_t)n * n, "dense normal matrix copy");
        memcpy(nm->Nd, nm->L, (size_t)n * n * sizeof *nm->Nd);
    }
    lapack_int info = LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', (lapack_int)n, nm->L, (lapack_int)n);
    if (info != 0) {
        st = WT_ERROR(ctx, info < 0 ? WT_ERR_LIBRARY : WT_ERR_NUMERIC,
                      "LAPACKE_dpotrf of the dense %lld x %lld MAP normal matrix (full prior) returned %d%s",
                      (long long)n, (long long)n, (int)info,
                      info > 0 ? " (not positive definite at that column: check recon.alpha and the noise model)" : "");
        goto fail;
    }
fail:
    wt_free(ctx, e);
    return st;
}

/* The rank of B Q Bᵀ: 2k per LGS (k = 2 tip and tilt, 3 with each LGS's focus removed), one per NGS slope, and 2
 * for the LGS's common focus (u_c, v_c) */
static int lowrank_rank(const wt_tomography *t)
{
    const wt_system *sys = wt_tomography_system(t);
    int r = 0;
    for (int m = 0; m < sys->nlgs; m++) r += wt_noise_focus(wt_tomography_noise(t, m)) ? 6 : 4;
    for (int m = sys->nlgs; m < sys->nsensors; m++) r += sys->sensors[m].nslopes;
    if (wt_tomography_common_focus(t)) r += 2;
    return r;
}

/* B = [Ãᵀ U_m, Ãᵀ V_m per LGS, Ã_ngsᵀ], Q block-diagonal (see mvm_build.h). */
static int build_lowrank(wt_mvm_normal *nm)
{
    int st = WT_OK;
    wt_context *ctx = nm->ctx;
    const wt_system *sys = nm->sys;
    const int64_t ns = nm->ns, n = nm->n;
    double *zs = NULL, *work = NULL;
    int r = lowrank_rank(nm->t);
    nm->r = r;
    WT_ALLOC(ctx, nm->B, (size_t)n * r, "low-rank columns B");
    WT_ALLOC(ctx, nm->Z, (size_t)n * r, "low-rank solves N⁻¹ B");
    WT_ALLOC(ctx, nm->Q, (size_t)r * r, "low-rank core Q");
    WT_ALLOC(ctx, nm->K, (size_t)r * r, "Woodbury capacitance");
    WT_ALLOC(ctx, nm->ipiv, r, "Woodbury pivots");
    WT_ALLOC(ctx, zs, (size_t)ns * r, "low-rank slope vectors");
    double *Q = nm->Q;
    int c = 0, ctt[2 * WT_MAX_GS]; /* LGS m's tip column (tilt: the next) */
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        const wt_noise *no = wt_tomography_noise(nm->t, m);
        const int ms = s->nsub;
        if (s->kind == WT_SENSOR_LGS) {
            /* columns c..c+2k−1: U = [u_x, u_y(, f)] the normalised tip and tilt (and the unit focus pattern when
             * it is removed too: k = 3), V = C̃⁻¹ U */
            const double *f = wt_noise_focus(no);
            const int k = f ? 3 : 2;
            ctt[m] = c;
            double u = 1.0 / sqrt((double)ms);
            double *U[3], *V[3];
            for (int a = 0; a < k; a++) {
                U[a] = zs + (size_t)(c + a) * ns + s->offset;
                V[a] = zs + (size_t)(c + k + a) * ns + s->offset;
            }
            for (int i = 0; i < ms; i++) {
                U[0][i] = u;
                U[1][ms + i] = u;
            }
            if (f) memcpy(U[2], f, 2 * (size_t)ms * sizeof *f);
            for (int a = 0; a < k; a++) wt_noise_apply_inv(no, 1.0, U[a], V[a]);
            double g[3][3] = {{0}};
            for (int a = 0; a < k; a++)
                for (int b = 0; b < k; b++)
                    for (int i = 0; i < 2 * ms; i++) g[a][b] += U[a][i] * V[b][i];
            /* Q_m = [[UᵀV, −I], [−I, 0]] (UᵀV symmetric as C̃⁻¹ is) */
            for (int a = 0; a < k; a++) {
                for (int b = 0; b < k; b++) Q[(c + a) + (size_t)r * (c + b)] = 0.5 * (g[a][b] + g[b][a]);
                Q[(c + a) + (size_t)r * (c + k + a)] = -1.0;
                Q[(c + k + a) + (size_t)r * (c + a)] = -1.0;
            }
            c += 2 * k;
        } else {
            /* one column per NGS slope, Q_m = C̃_m⁻¹ (2x2 blocks) */
            for (int k = 0; k < 2 * ms; k++) zs[(size_t)(c + k) * ns + s->offset + k] = 1.0;
            for (int i = 0; i < ms; i++) {
                double a, b, cc;
                wt_noise_inv_block(no, i, &a, &b, &cc);
                Q[(c + i) + (size_t)r * (c + i)] = a;
                Q[(c + i) + (size_t)r * (c + ms + i)] = b;
                Q[(c + ms + i) + (size_t)r * (c + i)] = b;
                Q[(c + ms + i) + (size_t)r * (c + ms + i)] = cc;
            }
            c += 2 * ms;
        }
    }
    const double *fc = wt_tomography_common_focus(nm->t);
    if (fc) {
        /* the LGS's common focus: one more U column u_c = (e_1, …, e_n)/√n across the LGS (⟂ every LGS's tip and
         * tilt, so U stays orthonormal) and v_c = C̃⁻¹ u_c; Q's UᵀV couples u_c to each LGS's tip and tilt columns */
        double *uc = zs + (size_t)c * ns, *vc = zs + (size_t)(c + 1) * ns;
        const double sn = 1.0 / sqrt((double)sys->nlgs);
        double gcc = 0.0;
        for (int m = 0; m < sys->nlgs; m++) {
            const wt_sensor *s = &sys->sensors[m];
            const int ms = s->nsub;
            for (int i = 0; i < 2 * ms; i++) uc[s->offset + i] = sn * fc[s->offset + i];
            wt_noise_apply_inv(wt_tomography_noise(nm->t, m), 1.0, uc + s->offset, vc + s->offset);
            const double u = 1.0 / sqrt((double)ms);
            double gx = 0.0, gy = 0.0; /* tip_mᵀ v_c, tilt_mᵀ v_c (= u_cᵀ C̃⁻¹ tip_m, C̃⁻¹ symmetric) */
            for (int i = 0; i < ms; i++) {
                gx += u * vc[s->offset + i];
                gy += u * vc[s->offset + ms + i];
            }
            for (int i = 0; i < 2 * ms; i++) gcc += uc[s->offset + i] * vc[s->offset + i];
            Q[ctt[m] + (size_t)r * c] = Q[c + (size_t)r * ctt[m]] = gx;
            Q[ctt[m] + 1 + (size_t)r * c] = Q[c + (size_t)r * (ctt[m] + 1)] = gy;
        }
        Q[c + (size_t)r * c] = gcc;
        Q[c + (size_t)r * (c + 1)] = -1.0;
        Q[(c + 1) + (size_t)r * c] = -1.0;
        c += 2;
    }
    size_t ws = wt_mvm_priv_wavelet_work(nm->t);
    WT_ALLOC(ctx, work, (size_t)nm->nth * ws, "wavelet workspace");
#pragma omp parallel for schedule(dynamic, 1) num_threads(nm->nth)
    for (int k = 0; k < r; k++)
        adjoint_column(nm, zs + (size_t)k * ns, nm->B + (size_t)k * n, work + wt_mvm_priv_thread() * ws);

    /* Z = N⁻¹ B, K = I + Q (Bᵀ Z), LU */
    WT_TRY(factor_solve(nm, r, nm->B, n, nm->Z, n));
    double *btz = zs; /* reuse: r x r ≤ ns x r */
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, r, r, (int)n, 1.0, nm->B, (int)n, nm->Z, (int)n, 0.0, btz, r);
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, r, r, r, 1.0, Q, r, btz, r, 0.0, nm->K, r);
    for (int i = 0; i < r; i++) nm->K[i + (size_t)r * i] += 1.0;
    lapack_int info = LAPACKE_dgetrf(LAPACK_COL_MAJOR, r, r, nm->K, r, nm->ipiv);
    if (info != 0) {
        st = WT_ERROR(ctx, info < 0 ? WT_ERR_LIBRARY : WT_ERR_NUMERIC,
                      "LAPACKE_dgetrf of the %d x %d Woodbury capacitance I + Q Bᵀ N⁻¹ B returned %d (singular: "
                      "the MAP normal matrix is not invertible)",
                      r, r, (int)info);
        goto fail;
    }
fail:
    wt_free(ctx, zs);
    wt_free(ctx, work);
    return st;
}

int wt_mvm_normal_alloc(wt_context *ctx, wt_tomography *t, const wt_mvm_options *opt_in, double reserve,
                        int keep_matrix, wt_mvm_normal **out)
{
    int st = WT_OK;
    wt_mvm_options opt;
    if (opt_in) opt = *opt_in;
    else wt_mvm_options_default(&opt);
    if (opt.block <= 0) opt.block = 256;
    wt_mvm_normal *nm = NULL;
    wt_mvm_priv_templates *tp = NULL;
    wt_mvm_priv_col_pool pool = {0};
    wt_sparse *G = NULL, *N = NULL;
    pair_transpose F = {0};
    double *w3 = NULL;
    int64_t *partner = NULL, *pair_of = NULL, *colptr = NULL;
    uint8_t *is_x = NULL;
    char detail[512];
    double t0 = wt_time_now(), tt = t0;
    *out = NULL;

    WT_ALLOC(ctx, nm, 1, "MVM normal matrix");
    nm->ctx = ctx;
    nm->t = t;
    nm->sys = wt_tomography_system(t);
    nm->n = wt_tomography_nunknowns(t);
    nm->ns = nm->sys->nslopes;
    nm->nth = wt_context_threads(ctx);
    nm->maxblock = opt.block;
    const wt_system *sys = nm->sys;
    const int64_t n = nm->n;
    wt_mvm_stats *S = &nm->stats;
    S->nunknowns = n;
    S->nslopes = nm->ns;
    S->nact = sys->nact;
    const int rank = lowrank_rank(t);
    const double lowrank_bytes = 16.0 * (double)n * rank;
    /* The full prior couples every pair of a layer's coefficients: N is dense (n² doubles, a copy with
     * keep_matrix), refused here, before any assembly, when that cannot fit. */
    const int dense = wt_tomography_full_prior(t);
    const double dense_bytes = dense ? 8.0 * (double)n * (double)n * (keep_matrix ? 2.0 : 1.0) : 0.0;
    if (dense) {
        snprintf(detail, sizeof detail,
                 "the dense %lld x %lld normal matrix of recon.%s.prior = \"full\" %.3g GB, low rank %.3g GB, reserved "
                 "for R, RÂ and the blocks %.3g GB; the diagonal priors \"paper\" and \"exact\" keep it sparse",
                 (long long)n, (long long)n, wt_tomography_variant(t), dense_bytes / 1e9, lowrank_bytes / 1e9,
                 reserve / 1e9);
        WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N", reserve + dense_bytes + lowrank_bytes,
                                        detail));
    }

    /* Γ P, the basis templates, and the 2x2 Cholesky factors of the LGS weights */
    wt_mvm_priv_progress(&opt, "assemble", 0, 2 * n);
    WT_TRY(wt_mvm_priv_assemble_gp(ctx, t, &nm->gp));
    WT_TRY(wt_mvm_priv_templates_alloc(ctx, t, &tp));
    const int64_t nl = sys->nlgs > 0 ? sys->sensors[sys->nlgs - 1].offset + sys->sensors[sys->nlgs - 1].nslopes : 0;
    WT_ALLOC(ctx, w3, 3 * (size_t)(nl > 0 ? nl : 1), "LGS weight factors");
    WT_ALLOC(ctx, partner, nl > 0 ? nl : 1, "slope partners");
    WT_ALLOC(ctx, pair_of, nl > 0 ? nl : 1, "slope pairs");
    WT_ALLOC(ctx, is_x, nl > 0 ? nl : 1, "slope axes");
    int64_t npairs = 0;
    for (int m = 0; m < sys->nlgs; m++) {
        const wt_sensor *s = &sys->sensors[m];
        for (int i = 0; i < s->nsub; i++) {
            double a, b, c;
            wt_noise_inv_block(wt_tomography_noise(t, m), i, &a, &b, &c);
            int64_t x = s->offset + i, y = x + s->nsub;
            /* C̃_i⁻¹ = [[a, b], [b, c]] = L Lᵀ: l11 = √a, l21 = b/√a, l22 = √(det/a) */
            w3[x] = sqrt(a);
            w3[nl + x] = b / sqrt(a);
            w3[2 * nl + x] = sqrt((a * c - b * b) / a);
            partner[x] = y;
            partner[y] = x;
            pair_of[x] = npairs++;
            pair_of[y] = -1;
            is_x[x] = 1;
        }
    }
    const double gp_bytes = wt_mvm_priv_sparse_bytes(wt_sparse_nnz(nm->gp), n);

    /* G = Lᵀ Ã_LGS: count, check, fill */
    WT_TRY(wt_mvm_priv_pool_alloc(ctx, nm->nth, nl > n ? nl : n, &pool));
    wt_mvm_priv_acol_ctx ac = {nm->gp, tp, nl, 1, w3, w3 + nl, w3 + 2 * nl, partner, is_x};
    WT_ALLOC(ctx, colptr, n + 1, "column counts");
    wt_mvm_priv_count_columns(&pool, n, wt_mvm_priv_atilde_column, &ac, colptr, &opt, "assemble", 0, 2 * n);
    S->nnz_a = colptr[n];
    double g_bytes = wt_mvm_priv_sparse_bytes(S->nnz_a, n), f_bytes = pair_transpose_bytes(S->nnz_a, npairs);
    snprintf(detail, sizeof detail, "Γ P %.3g GB, Lᵀ Ã_LGS %.3g GB (%lld non-zeros) and its transpose %.3g GB",
             gp_bytes / 1e9, g_bytes / 1e9, (long long)S->nnz_a, f_bytes / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "assembling Ã", gp_bytes + g_bytes + f_bytes,
                                    detail));
    snprintf(detail, sizeof detail, "at least: the %.3g GB reserved for R, RÂ and the block workspace, Γ P, low rank",
             reserve / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "solving", reserve + gp_bytes + lowrank_bytes,
                                    detail));
    WT_TRY(wt_sparse_alloc(ctx, nl, n, S->nnz_a, &G));
    memcpy(G->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    wt_mvm_priv_fill_columns(&pool, G, wt_mvm_priv_atilde_column, &ac, &opt, "assemble", n, 2 * n);
    wt_mvm_priv_templates_free(ctx, tp);
    tp = NULL;
    WT_TRY(pair_transpose_alloc(ctx, G, pair_of, partner, npairs, &F));
    S->t_assemble = wt_time_now() - tt;
    tt = wt_time_now();

    /* N = Gᵀ G + α D, upper triangle */
    ncol_ctx nc = {G, &F, pair_of, partner, wt_tomography_alpha_prior(t)};
    wt_mvm_priv_progress(&opt, "normal", 0, 2 * n);
    wt_mvm_priv_count_columns(&pool, n, normal_column, &nc, colptr, &opt, "normal", 0, 2 * n);
    S->nnz_normal = colptr[n];
    double n_bytes = wt_mvm_priv_sparse_bytes(S->nnz_normal, n);
    snprintf(detail, sizeof detail, "Γ P %.3g GB, Lᵀ Ã_LGS and transpose %.3g GB, N %.3g GB (%lld non-zeros)",
             gp_bytes / 1e9, (g_bytes + f_bytes) / 1e9, n_bytes / 1e9, (long long)S->nnz_normal);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "forming N",
                                    gp_bytes + g_bytes + f_bytes + n_bytes, detail));
    /* the factor holds at least the pattern of N's upper triangle, and CHOLMOD copies N once */
    snprintf(detail, sizeof detail,
             "at least: N %.3g GB, CHOLMOD's permuted copy of it, a factor of ≥ %lld non-zeros %.3g GB, Γ P %.3g GB",
             n_bytes / 1e9, (long long)S->nnz_normal, 8.0 * S->nnz_normal / 1e9, gp_bytes / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N",
                                    gp_bytes + 2.0 * n_bytes + 8.0 * S->nnz_normal, detail));
    WT_TRY(wt_sparse_alloc(ctx, n, n, S->nnz_normal, &N));
    memcpy(N->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    if (dense) {
        snprintf(detail, sizeof detail, "N sparse %.3g GB and dense %.3g GB, Γ P %.3g GB, low rank %.3g GB, reserved %.3g GB",
                 n_bytes / 1e9, dense_bytes / 1e9, gp_bytes / 1e9, lowrank_bytes / 1e9, reserve / 1e9);
        WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N",
                                        reserve + gp_bytes + n_bytes + dense_bytes + lowrank_bytes, detail));
    }
    wt_mvm_priv_fill_columns(&pool, N, normal_column, &nc, &opt, "normal", n, 2 * n);
    wt_mvm_priv_pool_free(&pool);
    wt_sparse_free(G);
    G = NULL;
    pair_transpose_free(ctx, &F);
    S->t_normal = wt_time_now() - tt;
    tt = wt_time_now();

    if (dense) {
        /* the full prior: N dense, factorised by LAPACK (its bytes were checked with the sparse N above) */
        wt_mvm_priv_progress(&opt, "factorize", 0, 1);
        S->nnz_factor = 0.5 * (double)n * (double)(n + 1);
        S->factor_bytes = dense_bytes;
        S->factor_flops = (double)n * n * n / 3.0;
        S->ordering = "dense (LAPACK)";
        S->t_analyze = 0.0;
        WT_TRY(dense_factor(nm, N, keep_matrix));
        wt_sparse_free(N);
        N = NULL;
        S->t_factorize = wt_time_now() - tt;
        wt_mvm_priv_progress(&opt, "factorize", 1, 1);
    } else {
        /* symbolic analysis: the factor's size is known before its memory is committed */
        wt_mvm_priv_progress(&opt, "analyze", 0, 1);
        WT_TRY(wt_chol_analyze(ctx, N, &nm->chol));
        wt_chol_info ci;
        wt_chol_info_get(nm->chol, &ci);
        S->nnz_factor = ci.nnz_factor;
        S->factor_bytes = ci.factor_bytes;
        S->factor_flops = ci.flops;
        S->ordering = ci.ordering;
        S->t_analyze = wt_time_now() - tt;
        wt_mvm_priv_progress(&opt, "analyze", 1, 1);
        snprintf(detail, sizeof detail,
                 "N %.3g GB, CHOLMOD's factorisation %.3g GB (factor %.3g GB of %.4g non-zeros, %s ordering, plus its "
                 "permuted copy of N and workspace), Γ P %.3g GB",
                 n_bytes / 1e9, ci.factorize_bytes / 1e9, ci.factor_bytes / 1e9, ci.nnz_factor, ci.ordering, gp_bytes / 1e9);
        WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N",
                                        gp_bytes + n_bytes + ci.factorize_bytes, detail));
        double solve_ws = wt_chol_solve_bytes(n, opt.block > rank ? opt.block : rank) + 16.0 * rank * opt.block;
        double final_bytes = reserve + gp_bytes + ci.factor_bytes + lowrank_bytes + solve_ws + (keep_matrix ? n_bytes : 0.0);
        snprintf(detail, sizeof detail,
                 "Cholesky factor %.3g GB, low rank %.3g GB, solve workspace %.3g GB, Γ P %.3g GB, reserved for the caller "
                 "(R, RÂ, blocks) %.3g GB",
                 ci.factor_bytes / 1e9, lowrank_bytes / 1e9, solve_ws / 1e9, gp_bytes / 1e9, reserve / 1e9);
        WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "solving", final_bytes, detail));

        tt = wt_time_now();
        wt_mvm_priv_progress(&opt, "factorize", 0, 1);
        WT_TRY(wt_chol_factorize(nm->chol, N));
        S->t_factorize = wt_time_now() - tt;
        wt_mvm_priv_progress(&opt, "factorize", 1, 1);
        if (keep_matrix) nm->N = N;
        else wt_sparse_free(N);
        N = NULL;
    }
    tt = wt_time_now();
    WT_TRY(build_lowrank(nm));
    WT_ALLOC(ctx, nm->s1, (size_t)nm->r * nm->maxblock, "Woodbury scratch");
    WT_ALLOC(ctx, nm->s2, (size_t)nm->r * nm->maxblock, "Woodbury scratch");
    S->rank = nm->r;
    S->t_lowrank = wt_time_now() - tt;
    S->cholmod_peak = wt_mvm_priv_normal_cholmod_peak(nm);
    *out = nm;
    nm = NULL;
fail:
    wt_mvm_priv_pool_free(&pool);
    wt_mvm_priv_templates_free(ctx, tp);
    wt_sparse_free(G);
    pair_transpose_free(ctx, &F);
    wt_sparse_free(N);
    wt_free(ctx, w3);
    wt_free(ctx, partner);
    wt_free(ctx, pair_of);
    wt_free(ctx, is_x);
    wt_free(ctx, colptr);
    wt_mvm_normal_free(nm);
    return st;
}

int wt_mvm_normal_apply(const wt_mvm_normal *nm, const double *x, double *y)
{
    const int r = nm->r, n = (int)nm->n;
    if (nm->Nd) {
        cblas_dsymv(CblasColMajor, CblasLower, n, 1.0, nm->Nd, n, x, 1, 0.0, y, 1);
    } else if (nm->N) {
        const wt_sparse *N = nm->N;
        memset(y, 0, (size_t)nm->n * sizeof *y);
        for (int64_t j = 0; j < nm->n; j++)
            for (int64_t k = N->colptr[j]; k < N->colptr[j + 1]; k++) {
                int64_t i = N->rowind[k];
                y[i] += N->val[k] * x[j];
                if (i != j) y[j] += N->val[k] * x[i];
            }
    } else {
        return WT_ERROR(nm->ctx, WT_ERR_INVALID, "wt_mvm_normal_apply: N was not kept (keep_matrix = 0 at alloc)");
    }
    cblas_dgemv(CblasColMajor, CblasTrans, n, r, 1.0, nm->B, n, x, 1, 0.0, nm->s1, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, r, r, 1.0, nm->Q, r, nm->s1, 1, 0.0, nm->s2, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, n, r, 1.0, nm->B, n, nm->s2, 1, 1.0, y, 1);
    return WT_OK;
}

int wt_mvm_normal_solve(wt_mvm_normal *nm, int64_t nrhs, const double *b, double *x)
{
    int st;
    const int r = nm->r;
    const int64_t n = nm->n;
    for (int64_t j0 = 0; j0 < nrhs; j0 += nm->maxblock) {
        int nb = (int)(nrhs - j0 < nm->maxblock ? nrhs - j0 : nm->maxblock);
        double *xb = x + j0 * n;
        /* x = N⁻¹ b, then x −= Z K⁻¹ Q (Bᵀ x) */
        if ((st = factor_solve(nm, nb, b + j0 * n, n, xb, n)) < 0) return st;
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, r, nb, (int)n, 1.0, nm->B, (int)n, xb, (int)n, 0.0, nm->s1, r);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, r, nb, r, 1.0, nm->Q, r, nm->s1, r, 0.0, nm->s2, r);
        lapack_int info = LAPACKE_dgetrs(LAPACK_COL_MAJOR, 'N', r, nb, nm->K, r, nm->ipiv, nm->s2, r);
        if (info != 0) return WT_ERROR(nm->ctx, WT_ERR_LIBRARY, "LAPACKE_dgetrs (Woodbury correction) returned %d", (int)info);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)n, nb, r, -1.0, nm->Z, (int)n, nm->s2, r, 1.0, xb, (int)n);
    }
    return WT_OK;
}
