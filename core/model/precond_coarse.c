/* core/model/precond_coarse.c: the coarse block of the preconditioners (coarse_ngs, multilevel; precond.h):
 *
 *   B = J with the coarse coefficients' block of the LGS + prior part of M,   B⁻¹ by its Cholesky factor
 *   (multilevel) or its explicit inverse (coarse_ngs),
 *
 * and z = B⁻¹ r, the kind's part before the NGS term (wt_precond__base_apply: this block, the multilevel layer
 * blocks or the fourier kind's B_F). */
#include "precond_coarse.h"
#include "precond_fourier.h"
#include "precond_multilevel.h"

#include <string.h>


/* ---- coarse block (coarse_ngs) ------------------------------------------------------------------
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
 * solves run by columns (axpys that vectorise; a row-oriented solve is a chain of dependent adds, a visible part
 * of an iteration at E-ELT size). coarse_ngs then replaces the factor by the
 * block's inverse (coarse_invert): the same ~2 nc² flops as one product whose rows split over the threads.
 * The multilevel kind keeps the solves. The NGS stay in the Woodbury term, now around B: P = B + R C_n Rᵀ. */
WT_CPU_CLONES void wt_precond__coarse_solve(const wt_precond *p, const double *r, double *z)
{
    const int q = p->nc;
    if (q == 0) return;
    double *w = p->c_w;
    for (int i = 0; i < q; i++) w[i] = r[p->c_idx[i]];
    wt_precond__chol_solves(p->c_L, q, w);
    for (int i = 0; i < q; i++) z[p->c_idx[i]] = w[i];
}

/* coarse_ngs: the block's inverse, column j = (L Lᵀ)⁻¹ e_j, symmetrised (the preconditioner must be symmetric;
 * the solves' rounding is not), in place of the factor. An apply is then one matrix-vector product whose rows
 * split over the threads, where the two triangular solves were chains of 2q dependent columns on one thread
 * (at E-ELT size 384², 1.2 MB, which the operator evicts from the caches between applies). */
int wt_precond__coarse_invert(wt_precond *p, int single)
{
    int st = WT_OK;
    const int q = p->nc;
    WT_ALLOC(p->ctx, p->c_inv, (size_t)q * q, "coarse block inverse");
    for (int j = 0; j < q; j++) {
        double *col = p->c_inv + (size_t)q * j;
        col[j] = 1.0;
        wt_precond__chol_solves(p->c_L, q, col);
    }
    for (int j = 0; j < q; j++)
        for (int i = j + 1; i < q; i++) {
            const double v = 0.5 * (p->c_inv[i + (size_t)q * j] + p->c_inv[j + (size_t)q * i]);
            p->c_inv[i + (size_t)q * j] = p->c_inv[j + (size_t)q * i] = v;
        }
    wt_free(p->ctx, p->c_L);
    p->c_L = NULL;
    if (single) { /* (each entry rounded once: the copy stays symmetric) */
        WT_ALLOC(p->ctx, p->c_inv32, (size_t)q * q, "coarse block inverse (float)");
        for (size_t i = 0; i < (size_t)q * q; i++) p->c_inv32[i] = (float)p->c_inv[i];
        wt_free(p->ctx, p->c_inv);
        p->c_inv = NULL;
    }
fail:
    return st;
}


/* Side of layer l's coarse square: the scaling block and the coarse_levels coarsest detail levels */
int wt_precond__coarse_side(const wt_tomography *t, int l, int coarse_levels)
{
    const int J = wt_wavelet_levels(wt_tomography_wavelet(t, l)), k = coarse_levels < J ? coarse_levels : J;
    return wt_tomography_layer_grid(t, l)->nx >> (J - k);
}

int wt_precond__coarse(wt_precond *p, wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t n = p->n;
    double *e = NULL, *sl = NULL, *col = NULL, *cols = NULL;
    int q = 0;
    int side[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++) {
        side[l] = wt_precond__coarse_side(t, l, coarse_levels);
        q += side[l] * side[l];
    }
    if (q > WT_PRECOND_COARSE_MAX)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: %s with coarse_levels %d gives a block of %d "
                        "coefficients; at most %d (lower coarse_levels)", wt_precond__kind_names[p->kind], coarse_levels, q,
                        WT_PRECOND_COARSE_MAX);
    WT_ALLOC(ctx, p->c_idx, q, "coarse indices");
    WT_ALLOC(ctx, p->c_L, (size_t)q * q, "coarse block");
    WT_ALLOC(ctx, p->c_w, q, "coarse work");
    WT_ALLOC(ctx, e, n, "coarse probe");
    WT_ALLOC(ctx, sl, sys->nslopes, "coarse probe slopes");
    WT_ALLOC(ctx, col, n, "coarse column");
    {
        int k = 0;
        for (int l = 0; l < L; l++)
            for (int j = 0; j < side[l]; j++)
                for (int i = 0; i < side[l]; i++)
                    p->c_idx[k++] = wt_tomography_layer_offset(t, l) + i + (int64_t)wt_tomography_layer_grid(t, l)->nx * j;
    }
    if (p->parts) {
        WT_ALLOC(ctx, p->pc, (size_t)(p->nlgs + 1) * q * q, "coarse block's parts");
        WT_ALLOC(ctx, cols, (size_t)(p->nlgs + 1) * n, "coarse parts' columns");
    }
    /* column j of the LGS + prior part of M */
    for (int j = 0; j < q; j++) {
        e[p->c_idx[j]] = 1.0;
        int lj = 0;
        while (lj + 1 < L && p->c_idx[j] >= wt_tomography_layer_offset(t, lj + 1)) lj++;
        wt_precond__lgs_prior_column(t, lj, e, sl, col);
        for (int i = 0; i < q; i++) p->c_L[i + (size_t)q * j] = col[p->c_idx[i]];
        if (p->parts) {
            wt_precond__part_columns(p, t, lj, e, cols);
            for (int m = 0; m <= p->nlgs; m++)
                for (int i = 0; i < q; i++) p->pc[(size_t)m * q * q + i + (size_t)q * j] = cols[(size_t)m * n + p->c_idx[i]];
        }
        e[p->c_idx[j]] = 0.0;
    }
    WT_TRY(wt_precond__coarse_factor(p, q, "coarse preconditioner"));
    /* the runs of unknowns outside the block (J⁻¹ r there, beside the coarse solve on another thread) */
    for (int64_t i = 0; i < n; i++) e[i] = 0.0;
    for (int j = 0; j < q; j++) e[p->c_idx[j]] = 1.0;
    WT_ALLOC(ctx, p->c_free, 2 * (size_t)(q + 1), "coarse block complement");
    for (int64_t i = 0; i < n;) {
        if (e[i] != 0.0) {
            i++;
            continue;
        }
        p->c_free[2 * p->c_nfree] = i;
        while (i < n && e[i] == 0.0) i++;
        p->c_free[2 * p->c_nfree++ + 1] = i;
    }
fail:
    wt_free(ctx, e);
    wt_free(ctx, sl);
    wt_free(ctx, col);
    wt_free(ctx, cols);
    return st;
}

/* acc[i] += Σ_j M[q j + b0 + i] r[c_idx[j]] for i < nb, j in order (M: q x q column-major, M32 when f32, its
 * values converted to double exactly, else M64). f32 and nb are constants where it is inlined: one loop each. */
static inline __attribute__((always_inline)) void coarse_columns(const wt_precond *p, const double *r,
                                                                 const float *M32, const double *M64, const int f32,
                                                                 int b0, const int nb, double *acc)
{
    const int q = p->nc;
    if (f32)
        for (int j = 0; j < q; j++) {
            const double v = r[p->c_idx[j]];
            const float *restrict col = M32 + (size_t)q * j + b0;
            for (int i = 0; i < nb; i++) acc[i] += (double)col[i] * v;
        }
    else
        for (int j = 0; j < q; j++) {
            const double v = r[p->c_idx[j]];
            const double *restrict col = M64 + (size_t)q * j + b0;
            for (int i = 0; i < nb; i++) acc[i] += (double)col[i] * v;
        }
}

/* z[c_idx[i]] = Σ_j (B_c⁻¹)_ij r[c_idx[j]] for the coarse rows i in [i0, i1) (coarse_ngs: the block's inverse
 * held explicitly). Each row's sum runs over j in order whatever rows a call takes: the same bits for any split
 * of the rows over threads. By blocks of 64 rows, the block's sums in registers/L1 while the columns stream. */
static inline __attribute__((always_inline)) void coarse_inv_block(const wt_precond *p, const double *r, double *z,
                                                                   int b0, int nb, const int f32)
{
    double acc[64] = {0.0};
    if (f32 && nb == 64) coarse_columns(p, r, p->c_inv32, NULL, 1, b0, 64, acc);
    else if (f32) coarse_columns(p, r, p->c_inv32, NULL, 1, b0, nb, acc);
    else if (nb == 64) coarse_columns(p, r, NULL, p->c_inv, 0, b0, 64, acc);
    else coarse_columns(p, r, NULL, p->c_inv, 0, b0, nb, acc);
    for (int i = 0; i < nb; i++) z[p->c_idx[b0 + i]] = acc[i];
}

WT_CPU_CLONES void wt_precond__coarse_inv_rows(const wt_precond *p, const double *r, double *z, int i0, int i1)
{
    for (int b0 = i0; b0 < i1; b0 += 64) {
        const int nb = i1 - b0 < 64 ? i1 - b0 : 64;
        if (p->c_inv32) coarse_inv_block(p, r, z, b0, nb, 1);
        else coarse_inv_block(p, r, z, b0, nb, 0);
    }
}

/* z = B⁻¹ r on one thread: J⁻¹ (coarse_ngs, jacobi_ngs) or the layer blocks (multilevel) below the coarse
 * block's exact solve (coarse_ngs: its inverse) */
static void coarse_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->nb > 0) wt_precond__layer_blocks_apply(p, r, z, 0, p->nb);
    else
        for (int64_t i = 0; i < p->n; i++) z[i] = p->jinv[i] * r[i];
    if (p->c_inv || p->c_inv32) wt_precond__coarse_inv_rows(p, r, z, 0, p->nc);
    else wt_precond__coarse_solve(p, r, z);
}

void wt_precond__base_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->fd_n > 0) wt_precond__fourier_apply(p, r, z, 0);
    else coarse_apply(p, r, z);
}
