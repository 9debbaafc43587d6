/* core/model/precond_update.c: the preconditioner for a new atmosphere model without applying M again (SPEC §12
 * "Updates"; docs/design.md "A preconditioner for a new model").
 *
 * Every kind but multilevel is built from entries of the LGS + prior part of M,
 *   M̃ = Σ_LGS Ãᵀ_m C̃_m⁻¹ Ã_m + Σ_l P_l          (P_l: layer l's prior, α D_l or α φᵀ C_φ⁻¹ φ),
 * read by probing (J's diagonal), by columns (the coarse block) or by its Fourier symbol (fourier). A new model
 * (wt_tomography_set_profile) changes two things in it:
 *   the priors, P_l → c_l P_l with c_l = (f_l r0^(−5/3)) then / now, exactly (wt_prior_rescale: the von Kármán
 *   spectrum is linear in f r0^(−5/3));
 *   each LGS's weights through its layer-binning model error, C̃_i = κΣ_i + σ²_e I: the isotropic part scales as
 *   1/σ²_t, the elongation's part does not. The update takes s_m = Σ_i 1/λ_min(C̃_i) now / then (exact for a
 *   round spot and for the short axis of every spot; without a model error nothing changes: s_m = 1).
 * So at set-up (wt_precond_params.updatable) each LGS's part of those entries and the prior's are kept apart, and
 *   M̃_new = Σ_m s_m M̃_m + Σ_l c_l P_l
 * feeds the kind's own steps: J⁻¹ = 1/diag, the coarse block's Cholesky factor (and inverse), the symbol's largest
 * eigenvalue per frequency, then the NGS term's Y = B⁻¹ R and K = Ĉ⁻¹_NGS + Rᵀ Y (R and Ĉ_NGS do not depend on the
 * model). Cost: O(nlgs n) for J, O(nc³) for the block, nk λ_max of order L for the symbol (core/la/heig.h: only the
 * largest eigenvalue is used, not zheev's all), Y = B⁻¹ R from the spectra of R kept at set-up (fourier: one
 * inverse FFT per NGS column and layer, precond_fourier.c) or r applies of B⁻¹ — no apply of M, no FFT of a probe. */
#include "precond_lowrank.h"

#include <lapacke.h>
#include <math.h>
#include <string.h>

#include "../la/heig.h"
#include "../op/noise.h"

int wt_precond_updatable(const wt_precond *p) { return p && (p->kind == WT_PRECOND_NONE || p->parts); }

/* J⁻¹ = 1 / (Σ_m s_m diag_m + α D) (α D the tomography's, already the new model's) */
static int update_jacobi(wt_precond *q, const wt_tomography *t, const double *s)
{
    int st = WT_OK;
    const int64_t n = q->n;
    const double *ad = wt_tomography_alpha_prior(t);
    WT_ALLOC(q->ctx, q->jinv, n, "inverse Jacobi diagonal");
    for (int64_t i = 0; i < n; i++) {
        double d = 0.0;
        for (int m = 0; m < q->nlgs; m++) d += s[m] * q->pj[(size_t)m * n + i];
        q->jinv[i] = 1.0 / (d + ad[i]);
    }
fail:
    return st;
}

/* The coarse block Σ_m s_m B_m + c_l P (each column's prior part scaled by its layer's c: the prior couples no two
 * layers), factored by LAPACK (blocked, on OpenBLAS's threads: the set-up's column loop is ~nc³ unvectorised flops
 * here) into what the kind applies: coarse_ngs the inverse (symmetric, both triangles), fourier the factor L with Lᵀ
 * above the diagonal */
static int update_coarse(wt_precond *q, const wt_tomography *t, const double *s, const double *c)
{
    int st = WT_OK;
    const int nc = q->nc, L = wt_tomography_nlayers(t);
    const size_t q2 = (size_t)nc * nc;
    double *A = NULL;
    WT_ALLOC(q->ctx, A, q2, "coarse block");
    for (int j = 0; j < nc; j++) {
        int lj = 0; /* the column's layer: coarse_ngs by its unknown's index, fourier by its place (sc² per layer) */
        if (q->fd_n > 0) lj = j / (q->fd_sc * q->fd_sc);
        else
            while (lj + 1 < L && q->c_idx[j] >= wt_tomography_layer_offset(t, lj + 1)) lj++;
        for (int i = j; i < nc; i++) { /* the lower triangle, each entry the mean of its two (as set-up's) */
            const size_t at = i + (size_t)nc * j, ta = j + (size_t)nc * i;
            double v = c[lj] * q->pc[(size_t)q->nlgs * q2 + at], w = c[lj] * q->pc[(size_t)q->nlgs * q2 + ta];
            for (int m = 0; m < q->nlgs; m++) v += s[m] * q->pc[(size_t)m * q2 + at], w += s[m] * q->pc[(size_t)m * q2 + ta];
            A[at] = i == j ? v : 0.5 * (v + w);
        }
    }
    lapack_int info = LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', nc, A, nc);
    if (info == 0 && q->kind == WT_PRECOND_COARSE_NGS) info = LAPACKE_dpotri(LAPACK_COL_MAJOR, 'L', nc, A, nc);
    if (info != 0) {
        st = WT_ERROR(q->ctx, WT_ERR_NUMERIC, "coarse preconditioner (update): the %d x %d block is not positive definite "
                      "(LAPACK %s info %d)", nc, nc, "dpotrf/dpotri", (int)info);
        goto fail;
    }
    for (int j = 0; j < nc; j++) /* the lower triangle mirrored above the diagonal */
        for (int i = j + 1; i < nc; i++) A[j + (size_t)nc * i] = A[i + (size_t)nc * j];
    if (q->kind != WT_PRECOND_COARSE_NGS) {
        q->c_L = A;
        return WT_OK;
    }
    if (q->single) {
        WT_ALLOC(q->ctx, q->c_inv32, q2, "coarse block inverse (float)");
        for (size_t i = 0; i < q2; i++) q->c_inv32[i] = (float)A[i];
    } else {
        q->c_inv = A;
        A = NULL;
    }
fail:
    wt_free(q->ctx, A);
    return st;
}

/* The filter 1 / (n² λ_max A(k)), A(k) = Σ_m s_m A_m(k) + diag(c_l P_l(k)) per frequency, on the threads */
static int update_fourier(wt_precond *q, const wt_tomography *t, const double *s, const double *c)
{
    int st = WT_OK;
    const int L = wt_tomography_nlayers(t), T = L * (L + 1) / 2, n = q->fd_n, nh = n / 2 + 1;
    const int64_t nk = q->fd_nk;
    const double n2 = (double)n * n;
    double complex *work = NULL;
    WT_ALLOC(q->ctx, q->fd_s, nk, "fourier preconditioner filter");
    WT_ALLOC(q->ctx, work, (size_t)q->nthreads * L * L, "fourier symbol (update)");
    int64_t bad = -1; /* the first frequency whose symbol is not positive definite */
    double bad_lmax = 0.0;
#pragma omp parallel for schedule(static) num_threads(q->nthreads)
    for (int64_t k = 0; k < nk; k++) {
        double complex *a = work + (size_t)wt_thread_id() * L * L; /* column-major, the lower triangle */
        for (int j = 0; j < L; j++)
            for (int i = j; i < L; i++) {
                const int tri = j * (2 * L - j + 1) / 2 + (i - j);
                double complex v = i == j ? c[j] * q->pp[(size_t)k * L + j] : 0.0;
                for (int m = 0; m < q->nlgs; m++) v += s[m] * q->pa[((size_t)m * nk + k) * T + tri];
                a[i + L * j] = v;
            }
        const double lmax = wt_heig_max(L, a, L); /* zheev's to ~L ε λ_max (core/la/heig.h), at ~1/3 its cost */
        if (!(lmax > 0.0) || !isfinite(lmax)) {
#pragma omp critical(wt_precond_update_bad)
            if (bad < 0 || k < bad) bad = k, bad_lmax = lmax;
            continue;
        }
        q->fd_s[k] = 1.0 / (n2 * lmax);
    }
    if (bad >= 0) {
        st = WT_ERROR(q->ctx, WT_ERR_NUMERIC, "fourier preconditioner (update): the %d x %d symbol at frequency (%lld, "
                      "%lld) has the largest eigenvalue %g; expected positive", L, L, (long long)(bad % nh),
                      (long long)(bad / nh), bad_lmax);
        goto fail;
    }
    if (q->nc > 0) WT_TRY(update_coarse(q, t, s, c));
fail:
    wt_free(q->ctx, work);
    return st;
}

/* The arrays an update replaces (the rest of the object, its workspaces and the parts, stay shared) */
static void drop_replaced(wt_precond *p)
{
    wt_context *ctx = p->ctx;
    wt_free(ctx, p->jinv);
    wt_free(ctx, p->c_L);
    wt_free(ctx, p->c_inv);
    wt_free(ctx, p->c_inv32);
    wt_free(ctx, p->fd_s);
    wt_free(ctx, p->lr_Y);
    wt_free(ctx, p->lr_K);
    wt_free(ctx, p->lr_runs);
    wt_free(ctx, p->lr_blk);
    wt_free(ctx, p->lr_Yb_raw);
    wt_free(ctx, p->lr_Yb32_raw);
}

int wt_precond_update(wt_precond *p)
{
    int st = WT_OK;
    if (p->kind == WT_PRECOND_NONE) return WT_OK;
    if (!p->parts)
        return WT_ERROR(p->ctx, WT_ERR_INVALID, "preconditioner %s: %s (rebuild it for the new model)",
                        wt_precond__kind_names[p->kind], p->kind == WT_PRECOND_MULTILEVEL
                            ? "the multilevel kind's layer blocks have no update"
                            : "built without the parts of an update (wt_precond_params.updatable)");
    const wt_tomography *t = p->tomo;
    double s[2 * WT_MAX_GS], c[WT_MAX_LAYERS];
    for (int m = 0; m < p->nlgs; m++) s[m] = wt_tomography_lgs_precision(t, m) / p->part_prec[m];
    for (int l = 0; l < wt_tomography_nlayers(t); l++) c[l] = p->part_cn2[l] / wt_precond__layer_cn2(t, l);
    /* the new state beside the old one: p stays whole until every step has succeeded */
    wt_precond q = *p;
    q.jinv = q.c_L = q.c_inv = q.fd_s = q.lr_Y = q.lr_K = NULL;
    q.c_inv32 = NULL;
    q.lr_runs = q.lr_blk = NULL;
    q.lr_nruns = 0;
    q.lr_nblk = 0;
    q.lr_Yb_raw = q.lr_Yb = NULL;
    q.lr_Yb32_raw = q.lr_Yb32 = NULL;
    if (p->pj) WT_TRY(update_jacobi(&q, t, s));
    if (p->fd_n > 0) WT_TRY(update_fourier(&q, t, s, c));
    else if (p->pc) WT_TRY(update_coarse(&q, t, s, c));
    if (p->nlr > 0) WT_TRY(wt_precond__lowrank_factor(&q, p->lr_R, p->lr_cinv));
    /* the blocks replaced become the next update's room (the spare not taken, if any, is returned) */
    void *old = p->lr_Yb_raw ? (void *)p->lr_Yb_raw : (void *)p->lr_Yb32_raw;
    if (old) {
        wt_free(p->ctx, q.pu_spare);
        q.pu_spare = old, q.pu_spare_bytes = p->lr_Yb_bytes;
        p->lr_Yb_raw = NULL, p->lr_Yb32_raw = NULL;
    }
    drop_replaced(p);
    *p = q;
    return WT_OK;
fail:
    if (p->pu_spare && ((void *)q.lr_Yb_raw == p->pu_spare || (void *)q.lr_Yb32_raw == p->pu_spare))
        q.lr_Yb_raw = NULL, q.lr_Yb32_raw = NULL; /* taken from p's spare, which p keeps */
    drop_replaced(&q);
    return st;
}
