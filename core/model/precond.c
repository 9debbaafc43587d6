/* core/model/precond.c: the preconditioners of the tomography's PCG (see precond.h):
 *
 *   J  = diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D                       exact, by coloured probing (paper's modified Jacobi)
 *   B  = J with the coarse coefficients' block of the LGS + prior part of M      (coarse_ngs)
 *   B_F⁻¹ = W F⁻¹ diag(1/λ_max A(k)) F Wᵀ beside the coarse block, A(k) the L x L symbol of that part per
 *         frequency                                                                          (fourier)
 *   P  = B + R C_n Rᵀ,  P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ,  Y = B⁻¹ R,  K = Ĉ⁻¹_NGS + Rᵀ B⁻¹ R   (Woodbury, the NGS term)
 *
 * Built only from the tomography's public operators (slopes Ã, the adjoint Ãᵀ Ĉ⁻¹, the projections, noise
 * models and wavelets it exposes), so the operator's file knows none of this. */
#include "precond_private.h"

#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../la/vec.h"
#include "../op/noise.h"
#include "../op/projection.h"
#include "../op/shack_hartmann.h"
#include "../op/wavelet.h"

const char *const wt_precond__kind_names[WT_PRECOND_NKINDS] = {"none", "jacobi", "jacobi_ngs", "coarse_ngs", "multilevel", "fourier"};

#define kind_names wt_precond__kind_names

const char *wt_precond_kind_name(int kind) { return kind >= 0 && kind < WT_PRECOND_NKINDS ? kind_names[kind] : NULL; }

int wt_precond_kind(const char *name)
{
    for (int k = 0; k < WT_PRECOND_NKINDS; k++)
        if (name && !strcmp(name, kind_names[k])) return k;
    return -1;
}


/* ---- modified Jacobi diagonal ------------------------------------------------------------------ */

/* Accumulates Σ_LGS ‖Ã_m e_λ‖²_{C̃⁻¹} for all coefficients of (layer l, level, orientation) coloured
 * with stride s: coefficients on a sub-lattice of stride s ≥ 2N+2 (N the Daubechies order) have images
 * Ã_m e_λ with disjoint supports in slope space, so one application per colour gives every entry, each
 * subaperture's 2x2 quadratic form attributed to the nearest probe. Buffers: field (n²), coef (n²), work
 * (wavelet), ph (max(ncg, 2n)), sl/z (max slopes). */
static void probe_block(const wt_tomography *t, int l, int level, int orient, int s, double *diag, double *coef,
                        double *field, double *work, double *ph, double *sl, double *z, int a0, int b0, double *parts, int64_t nall)
{
    const wt_system *sys = wt_tomography_system(t);
    const wt_grid *g = wt_tomography_layer_grid(t, l);
    const wt_wavelet *wav = wt_tomography_wavelet(t, l);
    const double alt = wt_tomography_layer_altitude(t, l);
    const int64_t off = wt_tomography_layer_offset(t, l), ncg = wt_grid_size(&sys->sense_grid);
    const int n = g->nx, J = wt_wavelet_levels(wav);
    const int lev = level > J ? J : level;
    const int m = n >> lev, step = 1 << lev;
    const int se = s < m ? s : m;
    const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;

    /* where the k = 0 basis function of this block sits: centre of its support */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    coef[bx + (int64_t)n * by] = 1.0;
    wt_wavelet_inverse(wav, coef, field, work);
    double *colmag = ph, *rowmag = ph + n; /* the caller sizes ph for max(ncg, 2n) */
    memset(colmag, 0, 2 * (size_t)n * sizeof *colmag);
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            double v = fabs(field[ix + (int64_t)n * iy]);
            colmag[ix] += v;
            rowmag[iy] += v;
        }
    double cx0 = wt_precond__support_centre(colmag, n), cy0 = wt_precond__support_centre(rowmag, n);

    /* the colour's probes */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    for (int j = b0; j < m; j += se)
        for (int i = a0; i < m; i += se) coef[bx + i + (int64_t)n * (by + j)] = 1.0;
    wt_wavelet_inverse(wav, coef, field, work);

    const int nprobe = m / se;
    for (int mm = 0; mm < sys->nlgs; mm++) {
        const wt_sensor *s_ = &sys->sensors[mm];
        memset(ph, 0, (size_t)ncg * sizeof *ph);
        wt_projection_apply(wt_tomography_projection(t, mm, l), 1.0, field, ph);
        memset(sl, 0, (size_t)s_->nslopes * sizeof *sl);
        wt_shack_hartmann_apply(s_->sh, 1.0, ph, sl);
        memset(z, 0, (size_t)s_->nslopes * sizeof *z);
        wt_noise_apply_inv(wt_tomography_noise(t, mm), 1.0, sl, z);
        double cone = s_->altitude > 0 ? 1.0 - alt / s_->altitude : 1.0;
        for (int k = 0; k < s_->nsub; k++) {
            double q = sl[k] * z[k] + sl[s_->nsub + k] * z[s_->nsub + k];
            if (q == 0.0) continue;
            int pi = 0, pj = 0;
            if (nprobe > 1) {
                double x, y;
                wt_shack_hartmann_centre(s_->sh, k, &x, &y);
                double gx = (cone * x + s_->theta_x * alt - g->x0) / g->dx;
                double gy = (cone * y + s_->theta_y * alt - g->y0) / g->dx;
                double period = (double)step * se;
                pi = (int)lround((gx - cx0 - (double)step * a0) / period);
                pj = (int)lround((gy - cy0 - (double)step * b0) / period);
                pi = ((pi % nprobe) + nprobe) % nprobe;
                pj = ((pj % nprobe) + nprobe) % nprobe;
            }
            int64_t lam = bx + a0 + (int64_t)se * pi + (int64_t)n * (by + b0 + (int64_t)se * pj);
            diag[off + lam] += q;
            if (parts) parts[(size_t)mm * nall + off + lam] += q; /* (the parts: each LGS alone) */
        }
    }
}

/* J⁻¹ = 1 / (diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D), the diagonal by probe_block over every layer, level,
 * orientation and colour (~1 s at E-ELT pcg3 size). */
static int compute_jacobi(wt_precond *p, const wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const double *alpha_d = wt_tomography_alpha_prior(t);
    double *diag = NULL, *buf = NULL;
    int s;
    int64_t maxn2, maxsl, wsize;
    wt_precond__probe_sizes(t, &s, &maxn2, &maxsl, &wsize);
    int64_t phn = ncg;
    for (int l = 0; l < L; l++)
        if (2 * wt_tomography_layer_grid(t, l)->nx > phn) phn = 2 * wt_tomography_layer_grid(t, l)->nx;
    int64_t per = 2 * maxn2 + wsize + phn + 2 * maxsl;
    int nth = p->nthreads;
    WT_ALLOC(ctx, diag, p->n, "Jacobi diagonal");
    WT_ALLOC(ctx, buf, (size_t)nth * per, "Jacobi probing workspace");
    if (p->parts) WT_ALLOC(ctx, p->pj, (size_t)sys->nlgs * p->n, "Jacobi diagonal's parts");

    for (int l = 0; l < L; l++) {
        int J = wt_wavelet_levels(wt_tomography_wavelet(t, l)), n = wt_tomography_layer_grid(t, l)->nx;
        for (int level = 1; level <= J + 1; level++) {
            int o0 = level <= J ? 1 : 0, o1 = level <= J ? 3 : 0;
            for (int orient = o0; orient <= o1; orient++) {
                int lev = level > J ? J : level, m = n >> lev, se = s < m ? s : m;
#pragma omp parallel for collapse(2) schedule(dynamic, 1) num_threads(nth)
                for (int b0 = 0; b0 < se; b0++)
                    for (int a0 = 0; a0 < se; a0++) {
                        double *base = buf + (size_t)wt_thread_id() * per;
                        double *coef = base, *field = coef + maxn2, *work = field + maxn2;
                        double *ph = work + wsize, *sl = ph + phn, *z = sl + maxsl;
                        probe_block(t, l, level, orient, s, diag, coef, field, work, ph, sl, z, a0, b0, p->pj, p->n);
                    }
            }
        }
    }
    WT_ALLOC(ctx, p->jinv, p->n, "inverse Jacobi diagonal");
    for (int64_t i = 0; i < p->n; i++) p->jinv[i] = 1.0 / (diag[i] + alpha_d[i]);
fail:
    wt_free(ctx, diag);
    wt_free(ctx, buf);
    return st;
}

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
 * solves run by columns (axpys that vectorise; a row-oriented solve is a chain of dependent adds: the
 * backward one took ~67 µs of an ~0.47 ms iteration that way). coarse_ngs then replaces the factor by the
 * block's inverse (coarse_invert): the same ~2 nc² flops as one product whose rows split over the threads.
 * The multilevel kind keeps the solves. The NGS stay in the Woodbury term, now around B: P = B + R C_n Rᵀ. */
WT_CPU_CLONES static void coarse_solve(const wt_precond *p, const double *r, double *z)
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
 * (at E-ELT size: 384², 1.2 MB that the operator evicts between applies, ~50 µs of an iteration). */
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
static int coarse_side(const wt_tomography *t, int l, int coarse_levels)
{
    const int J = wt_wavelet_levels(wt_tomography_wavelet(t, l)), k = coarse_levels < J ? coarse_levels : J;
    return wt_tomography_layer_grid(t, l)->nx >> (J - k);
}

static int compute_coarse(wt_precond *p, wt_tomography *t, int coarse_levels)
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
        side[l] = coarse_side(t, l, coarse_levels);
        q += side[l] * side[l];
    }
    if (q > 4096)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: %s with coarse_levels %d gives a block of %d "
                        "coefficients; at most 4096 (lower coarse_levels)", kind_names[p->kind], coarse_levels, q);
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
    /* symmetrise the rounding of the two triangles before the factorisation */
    for (int j = 0; j < q; j++)
        for (int i = j + 1; i < q; i++)
            p->c_L[i + (size_t)q * j] = 0.5 * (p->c_L[i + (size_t)q * j] + p->c_L[j + (size_t)q * i]);
    WT_TRY(wt_precond__cholesky(ctx, q, p->c_L, "coarse preconditioner"));
    /* Lᵀ into the (unused) upper triangle: column i above the diagonal = row i of L, so that the backward
     * solve runs by contiguous columns too */
    for (int i = 0; i < q; i++)
        for (int k = 0; k < i; k++) p->c_L[k + (size_t)q * i] = p->c_L[i + (size_t)q * k];
    p->nc = q;
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

/* z[c_idx[i]] = Σ_j (B_c⁻¹)_ij r[c_idx[j]] for the coarse rows i in [i0, i1) (coarse_ngs: the block's inverse
 * held explicitly). Each row's sum runs over j in order whatever rows a call takes: the same bits for any split
 * of the rows over threads. By blocks of 64 rows, the block's sums in registers/L1 while the columns stream. */
static inline __attribute__((always_inline)) void coarse_inv_block(const wt_precond *p, const double *r, double *z,
                                                                   int b0, int nb, const int f32)
{
    const int q = p->nc;
    double acc[64] = {0.0};
#define WT_COARSE_COLUMNS(T, M, NB)                                                                                   \
    for (int j = 0; j < q; j++) {                                                                                     \
        const double v = r[p->c_idx[j]];                                                                              \
        const T *restrict col = (M) + (size_t)q * j + b0;                                                             \
        for (int i = 0; i < (NB); i++) acc[i] += (double)col[i] * v;                                                  \
    }
    if (f32 && nb == 64) WT_COARSE_COLUMNS(float, p->c_inv32, 64)
    else if (f32) WT_COARSE_COLUMNS(float, p->c_inv32, nb)
    else if (nb == 64) WT_COARSE_COLUMNS(double, p->c_inv, 64)
    else WT_COARSE_COLUMNS(double, p->c_inv, nb)
#undef WT_COARSE_COLUMNS
    for (int i = 0; i < nb; i++) z[p->c_idx[b0 + i]] = acc[i];
}

WT_CPU_CLONES static void coarse_inv_rows(const wt_precond *p, const double *r, double *z, int i0, int i1)
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
    if (p->c_inv || p->c_inv32) coarse_inv_rows(p, r, z, 0, p->nc);
    else coarse_solve(p, r, z);
}

void wt_precond__base_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->fd_n > 0) wt_precond__fourier_apply(p, r, z, 0);
    else coarse_apply(p, r, z);
}

/* ---- NGS low-rank correction --------------------------------------------------------------------
 *
 * The NGS term of M is Σ_NGS Ãᵀ C̃⁻¹ Ã = G Ĉ⁻¹_NGS Gᵀ with G = [Ãᵀ e_k] over the r NGS slopes (r = 12
 * for one 2x2 and two 1x1 sensors): rank r, but weighted by NGS noise variances that can be 10⁵ times
 * smaller than the LGS ones (SPEC §11: 0.05 mas against 20 mas). A diagonal cannot describe it — the
 * NGS modes are global tip-tilt-like shapes — and the few PCG iterations then spend themselves on them
 * (PCG-3 at low noise lost its correction entirely). So P = B + G Ĉ⁻¹ Gᵀ = B + R C_n Rᵀ, with
 * R = G Ĉ⁻¹ = [Ãᵀ Ĉ⁻¹ e_k] (r right-hand sides) and C_n = (Ĉ⁻¹_NGS)⁻¹, is inverted by Woodbury:
 *   P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ,   Y = B⁻¹ R,   K = Ĉ⁻¹_NGS + Rᵀ B⁻¹ R   (r x r, Cholesky once),
 * which costs 4 r n flops per iteration on top of B⁻¹. */

/* coarse_ngs's Woodbury term by blocks of 8 rows (lr_Yb: only the blocks where Y has a non-zero, each block's
 * r columns of 8 rows side by side). Yᵀ r: the kept blocks fall into WT_VEC_CHUNKS fixed chunks; in a chunk,
 * row e of every block (e < 8) adds into lane e of column k's sum, in block order, and the chunk's value is the
 * 8 lanes added pairwise in a fixed tree; the chunks are added in order (wt_vec_dot_many_finish). Which thread
 * runs a chunk changes nothing: the same bits for any thread count. B a compile-time constant (always inlined:
 * the B sums of 8 lanes stay in vector registers); a last block past n takes only its rows < n. The update
 * reads the same copy (one pass over ~1 MB each instead of a column-major Y and a row-major copy). */
/* (yb_vec, yb_vec32 and YB_COL: precond_private.h) */

static inline __attribute__((always_inline)) void yb_dots_chunk(const int B, const int f32, const wt_precond *p,
                                                                const double *r, int64_t b0, int64_t b1,
                                                                double *restrict part, int c)
{
    const int64_t n = p->n;
    yb_vec acc[WT_VEC_MAX_MANY];
    for (int k = 0; k < B; k++) acc[k] = (yb_vec){0.0};
    for (int64_t b = b0; b < b1; b++) {
        const int64_t i0 = 8 * p->lr_blk[b];
        yb_vec rr = {0.0};
        if (i0 + 8 <= n) rr = *(const yb_vec *)(r + i0);
        else
            for (int e = 0; e < n - i0; e++) rr[e] = r[i0 + e]; /* lanes past n: Y 0 (never set) times 0, their
                                                                   sums stay +0 */
        for (int k = 0; k < B; k++) acc[k] += YB_COL(p, B, b, k, f32) * rr;
    }
    for (int k = 0; k < B; k++)
        part[(int64_t)k * WT_VEC_CHUNKS + c] =
            ((acc[k][0] + acc[k][1]) + (acc[k][2] + acc[k][3])) + ((acc[k][4] + acc[k][5]) + (acc[k][6] + acc[k][7]));
}

WT_CPU_CLONES static void yb_dots(const wt_precond *p, const double *r, int c0, int c1)
{
    const int64_t nb = p->lr_nblk;
    for (int c = c0; c < c1; c++) {
        const int64_t b0 = nb * c / WT_VEC_CHUNKS, b1 = nb * (c + 1) / WT_VEC_CHUNKS;
        if (p->nlr == 12 && p->lr_Yb32) yb_dots_chunk(12, 1, p, r, b0, b1, p->lr_part, c); /* the E-ELT's 3 NGS */
        else if (p->nlr == 12) yb_dots_chunk(12, 0, p, r, b0, b1, p->lr_part, c);
        else if (p->lr_Yb32) yb_dots_chunk(p->nlr, 1, p, r, b0, b1, p->lr_part, c);
        else yb_dots_chunk(p->nlr, 0, p, r, b0, b1, p->lr_part, c);
    }
}

/* coarse_ngs: z = J⁻¹ r off the coarse block, its inverse on it, minus Y K⁻¹ Yᵀ r. Every part splits over
 * the threads by fixed pieces (rows, coarse rows, chunks of blocks), one barrier between the dots and the
 * update; each thread solves the small K system itself (no serial section). */
static void coarse_ngs_apply(const wt_precond *p, const double *r, double *z)
{
    const int64_t n = p->n;
#pragma omp parallel num_threads(p->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        const int64_t i0 = n * id / nt, i1 = n * (id + 1) / nt;
        for (int j = 0; j < p->c_nfree; j++) {
            const int64_t lo = p->c_free[2 * j] > i0 ? p->c_free[2 * j] : i0;
            const int64_t hi = p->c_free[2 * j + 1] < i1 ? p->c_free[2 * j + 1] : i1;
            for (int64_t i = lo; i < hi; i++) z[i] = p->jinv[i] * r[i];
        }
        coarse_inv_rows(p, r, z, (int)((int64_t)p->nc * id / nt), (int)((int64_t)p->nc * (id + 1) / nt));
        yb_dots(p, r, WT_VEC_CHUNKS * id / nt, WT_VEC_CHUNKS * (id + 1) / nt);
#pragma omp barrier
        double w[WT_VEC_MAX_MANY];
        wt_vec_dot_many_finish(p->nlr, p->lr_part, w);
        wt_precond__lowrank_solve(p, w);
        wt_precond__yb_update(p, w, z, p->lr_nblk * id / nt, p->lr_nblk * (id + 1) / nt);
    }
}

/* z = P⁻¹ r = B⁻¹ r − Y K⁻¹ Yᵀ r. B⁻¹ r (coarse_apply: mostly the coarse block's two triangular solves,
 * serial chains) and Yᵀ r (the r dots, which read r and not z) are independent: on two threads they run
 * side by side, then both threads share the update of z. Y is zero on ~60 % of the rows (the fine
 * wavelet coefficients away from the NGS footprints' rims): its runs of non-zero rows are skipped. */
static void lowrank_apply(const wt_precond *p, const double *r, double *z)
{
    const int64_t n = p->n;
    const int q = p->nlr;
    if (q == 0) {
        wt_precond__base_apply(p, r, z);
        return;
    }
    if (p->fd_n > 0) {
        wt_precond__fourier_apply(p, r, z, 1);
        return;
    }
    if (p->lr_Yb || p->lr_Yb32) {
        coarse_ngs_apply(p, r, z);
        return;
    }
#pragma omp parallel num_threads(p->nthreads)
    {
#ifdef _OPENMP
        const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
        const int nt = 1, id = 0;
#endif
        if (p->nb > 0) {
            /* multilevel: the blocks in fixed chunks over the threads, the coarse solve on one of them (each
             * block's solve does not depend on the thread that runs it: the same bits on any thread count) */
#pragma omp single nowait
            coarse_solve(p, r, z);
#pragma omp for schedule(dynamic, 1) nowait
            for (int c = 0; c < 64; c++) wt_precond__layer_blocks_apply(p, r, z, p->nb * c / 64, p->nb * (c + 1) / 64);
        } else {
            /* no coarse block: J⁻¹ r split over the threads */
            for (int64_t i = n * id / nt; i < n * (id + 1) / nt; i++) z[i] = p->jinv[i] * r[i];
        }
        /* the dots' chunks split over the threads (the chunk sums land in fixed slots and are added in a fixed
         * order: the same bits as on one thread) */
        wt_vec_dot_many_part(p->lr_Y, n, q, r, n, p->lr_runs, p->lr_nruns, WT_VEC_CHUNKS * id / nt,
                             WT_VEC_CHUNKS * (id + 1) / nt, p->lr_part);
#pragma omp barrier
#pragma omp single
        {
            wt_vec_dot_many_finish(q, p->lr_part, p->lr_w);
            wt_precond__lowrank_solve(p, p->lr_w);
        } /* (its implicit barrier: w is ready for every thread, and every B⁻¹ r written) */
        wt_vec_sub_many_range(z, p->lr_Y, n, q, p->lr_w, p->lr_runs, p->lr_nruns, n * id / nt, n * (id + 1) / nt);
    }
}

/* Y = B⁻¹ R (B the kind's part before the NGS term, as it stands), K = Ĉ⁻¹_NGS + Rᵀ Y by Cholesky, and Y laid out
 * as the apply reads it: coarse_ngs and fourier by blocks of 8 rows, the blocks with a non-zero (in float when
 * single); the others column-major, with its zero runs. At set-up and at each update (p->nlr set). */
/* Rᵀ_j Y_k as wt_vec_dot(R_j, Y_k, n) sums it, from R_j's non-zeros on the layers (fourier's fd_rs): each of
 * WT_VEC_CHUNKS chunk sums is one chain in index order from 0, and a zero product leaves a chain's value as it is
 * (x + ±0 = x, +0 + −0 = +0), so the chains of the non-zeros alone are the same bits; then the ordered total. */
static double sparse_dot(const wt_precond *p, int j, const double *Yk)
{
    const wt_tomography *t = p->tomo;
    const int L = wt_tomography_nlayers(t), q = p->nlr;
    const int64_t len = wt_vec_chunk_len(p->n);
    double part[WT_VEC_CHUNKS] = {0.0};
    for (int l = 0; l < L; l++) {
        const int64_t o = wt_tomography_layer_offset(t, l);
        for (int64_t e = p->fd_rs_ptr[l * q + j]; e < p->fd_rs_ptr[l * q + j + 1]; e++) {
            const int64_t i = o + p->fd_rs_idx[e];
            part[i / len] += p->fd_rs_val[e] * Yk[i];
        }
    }
    return wt_vec_dot_finish(part);
}

int wt_precond__lowrank_factor(wt_precond *p, const double *R, const double *cinv)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const int64_t n = p->n;
    const int q = p->nlr, single = p->single;
    const int blocked = p->kind == WT_PRECOND_COARSE_NGS || p->fd_n > 0;
    double *Y = NULL;
    char *nz = NULL;
    WT_ALLOC(ctx, p->lr_K, (size_t)q * q, "NGS preconditioner K");
    if (!blocked) WT_ALLOC(ctx, p->lr_runs, n + 1, "NGS preconditioner runs");
    if (p->fd_rhat) { /* fourier's update: Y in the room kept for it (every entry written by the inverse FFTs) */
        Y = wt_align64(p->pu_Y_raw);
        WT_TRY(wt_precond__fourier_lowrank_Y(p, Y));
    } else {
        WT_ALLOC(ctx, p->lr_Y, (size_t)n * q, "NGS preconditioner Y");
        Y = p->lr_Y;
        for (int k = 0; k < q; k++) wt_precond__base_apply(p, R + (size_t)n * k, Y + (size_t)n * k);
    }
    if (!blocked) p->lr_nruns = wt_vec_runs(Y, n, q, n, p->lr_runs);
    for (int k = 0; k < q; k++)
        for (int j = 0; j <= k; j++) {
            const double d = p->fd_rs_ptr ? sparse_dot(p, j, Y + (size_t)k * n) : wt_vec_dot(R + (size_t)j * n, Y + (size_t)k * n, n);
            p->lr_K[j + (size_t)q * k] = p->lr_K[k + (size_t)q * j] = cinv[j + (size_t)q * k] + d;
        }
    /* in-place Cholesky, lower triangle (K is SPD: Ĉ⁻¹_NGS SPD, RᵀB⁻¹R semi-definite) */
    WT_TRY(wt_precond__cholesky(ctx, q, p->lr_K, "NGS preconditioner"));
    if (blocked) { /* Y by blocks of 8 rows, the blocks with a non-zero; each block's rows on one thread */
        const int64_t nb8 = (n + 7) / 8;
        WT_ALLOC(ctx, p->lr_blk, nb8, "NGS preconditioner blocks");
        WT_ALLOC(ctx, nz, nb8, "NGS preconditioner block flags");
#pragma omp parallel for schedule(static) num_threads(p->nthreads)
        for (int64_t b = 0; b < nb8; b++) {
            int z = 0;
            for (int64_t i = 8 * b; i < 8 * b + 8 && i < n && !z; i++)
                for (int k = 0; k < q && !z; k++) z = Y[(size_t)k * n + i] != 0.0;
            nz[b] = (char)z;
        }
        p->lr_nblk = 0;
        for (int64_t b = 0; b < nb8; b++)
            if (nz[b]) p->lr_blk[p->lr_nblk++] = b;
        /* (every entry written below: malloc, not calloc; 64-byte aligned: 16 floats or 8 doubles of slack; an
         * update takes the blocks the last one replaced when they are large enough) */
        const size_t bytes = ((size_t)p->lr_nblk * q * 8 + 16) * (single ? sizeof(float) : sizeof(double));
        void *mem = NULL;
        if (p->pu_spare && p->pu_spare_bytes >= bytes) {
            mem = p->pu_spare, p->lr_Yb_bytes = p->pu_spare_bytes;
            p->pu_spare = NULL, p->pu_spare_bytes = 0;
        } else if ((mem = wt_malloc(ctx, bytes, 1))) p->lr_Yb_bytes = bytes;
        if (!mem) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory allocating NGS preconditioner Y (blocks) (%zu bytes)", bytes);
            goto fail;
        }
        if (single) p->lr_Yb32_raw = mem;
        else p->lr_Yb_raw = mem;
        if (single) p->lr_Yb32 = p->lr_Yb32_raw + ((64 - (uintptr_t)p->lr_Yb32_raw % 64) % 64) / sizeof(float);
        else p->lr_Yb = wt_align64(p->lr_Yb_raw);
#pragma omp parallel for schedule(static) num_threads(p->nthreads)
        for (int64_t b = 0; b < p->lr_nblk; b++)
            for (int k = 0; k < q; k++)
                for (int a = 0; a < 8; a++) {
                    const size_t at = ((size_t)b * q + k) * 8 + a;
                    const int64_t i = 8 * p->lr_blk[b] + a;
                    const double v = i < n ? Y[(size_t)k * n + i] : 0.0; /* (rows past n: 0) */
                    if (single) p->lr_Yb32[at] = (float)v;
                    else p->lr_Yb[at] = v;
                }
        wt_free(ctx, p->lr_Y); /* the applies read the blocks only */
        p->lr_Y = NULL;
    }
fail:
    wt_free(ctx, nz);
    return st;
}

static int compute_lowrank(wt_precond *p, wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = p->n, ns = sys->nslopes;
    double *e = NULL, *we = NULL, *cinv = NULL;
    int q = 0, first = -1;
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].kind == WT_SENSOR_NGS) {
            if (first < 0) first = m;
            q += sys->sensors[m].nslopes;
        }
    if (q == 0 || q > 64) return WT_OK; /* no NGS (or an unusual many-slope NGS set: B alone) */
    const int64_t o0 = sys->sensors[first].offset; /* NGS slopes are the last, contiguous */
    double *R = NULL;
    WT_ALLOC(ctx, R, (size_t)n * q, "NGS preconditioner R");
    WT_ALLOC(ctx, p->lr_w, q, "NGS preconditioner work");
    WT_ALLOC(ctx, p->lr_part, (size_t)q * WT_VEC_CHUNKS, "NGS preconditioner work");
    WT_ALLOC(ctx, e, ns, "unit slope vector");
    WT_ALLOC(ctx, we, ns, "weighted unit slope vector");
    WT_ALLOC(ctx, cinv, (size_t)q * q, "NGS noise weight");
    for (int k = 0; k < q; k++) {
        e[o0 + k] = 1.0;
        wt_tomography_rhs(t, 1.0, e, R + (size_t)k * n); /* R was allocated zeroed: column k = Ãᵀ Ĉ⁻¹ e_k */
        /* column k of Ĉ⁻¹_NGS: the noise weight of each NGS sensor applied to e_k */
        memset(we, 0, (size_t)ns * sizeof *we);
        for (int m = first; m < sys->nsensors; m++) {
            const wt_sensor *s = &sys->sensors[m];
            wt_noise_apply_weight(wt_tomography_noise(t, m), 1.0, e + s->offset, we + s->offset);
        }
        for (int j = 0; j < q; j++) cinv[j + (size_t)q * k] = we[o0 + j];
        e[o0 + k] = 0.0;
    }
    p->nlr = q;
    WT_TRY(wt_precond__lowrank_factor(p, R, cinv));
    if (p->fd_n > 0) WT_TRY(wt_precond__fourier_ngs_columns(p, t, R));
    if (p->parts) { /* (the NGS's weights do not depend on the model: R and Ĉ⁻¹_NGS stay) */
        p->lr_R = R;
        p->lr_cinv = cinv;
        R = cinv = NULL;
    }
fail:
    wt_free(ctx, R);
    wt_free(ctx, e);
    wt_free(ctx, we);
    wt_free(ctx, cinv);
    return st;
}

/* ---- the interface ------------------------------------------------------------------------------ */

int wt_precond_alloc(wt_context *ctx, wt_tomography *t, const wt_precond_params *par, wt_precond **out)
{
    int st = WT_OK;
    wt_precond *p = NULL;
    *out = NULL;
    if (!wt_precond_kind_name(par->kind))
        return WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner kind %d: expected 0..%d (none, jacobi, jacobi_ngs, "
                        "coarse_ngs, multilevel, fourier)", par->kind, WT_PRECOND_NKINDS - 1);
    WT_ALLOC(ctx, p, 1, "preconditioner");
    p->ctx = ctx;
    p->kind = par->kind;
    p->n = wt_tomography_nunknowns(t);
    p->nthreads = wt_tomography_threads(t);
    p->tomo = t;
    p->single = par->single;
    if (par->updatable && p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_MULTILEVEL)
        WT_TRY(wt_precond__parts_begin(p, t));
    if (wt_tomography_space(t) && p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_FOURIER) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner %s: built on wavelet coefficients; this tomography's "
                      "unknowns are the layers' values (only none and fourier work there)", kind_names[p->kind]);
        goto fail;
    }
    if (p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_FOURIER) WT_TRY(compute_jacobi(p, t));
    if (par->coarse_levels < 0 && p->kind != WT_PRECOND_FOURIER && p->kind >= WT_PRECOND_COARSE_NGS) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner %s: coarse_levels %d; expected >= 0", kind_names[p->kind],
                      par->coarse_levels);
        goto fail;
    }
    if (p->kind == WT_PRECOND_FOURIER) WT_TRY(wt_precond__fourier(p, t, par->coarse_levels));
    else if (p->kind >= WT_PRECOND_COARSE_NGS) WT_TRY(compute_coarse(p, t, par->coarse_levels));
    if (p->kind == WT_PRECOND_COARSE_NGS) WT_TRY(wt_precond__coarse_invert(p, par->single));
    if (p->kind == WT_PRECOND_MULTILEVEL) {
        int sc[WT_MAX_LAYERS];
        for (int l = 0; l < wt_tomography_nlayers(t); l++) sc[l] = coarse_side(t, l, par->coarse_levels);
        WT_TRY(wt_precond__layer_blocks(p, t, sc));
    }
    if (p->kind >= WT_PRECOND_JACOBI_NGS) WT_TRY(compute_lowrank(p, t));
    *out = p;
    return WT_OK;
fail:
    wt_precond_free(p);
    return st;
}

void wt_precond_free(wt_precond *p)
{
    if (!p) return;
    wt_context *ctx = p->ctx;
    wt_free(ctx, p->jinv);
    wt_free(ctx, p->lr_Y);
    wt_free(ctx, p->lr_K);
    wt_free(ctx, p->lr_w);
    wt_free(ctx, p->lr_part);
    wt_free(ctx, p->lr_runs);
    wt_free(ctx, p->c_idx);
    wt_free(ctx, p->c_free);
    wt_free(ctx, p->c_L);
    wt_free(ctx, p->c_w);
    wt_free(ctx, p->c_inv);
    wt_free(ctx, p->c_inv32);
    wt_free(ctx, p->lr_blk);
    wt_free(ctx, p->lr_Yb_raw);
    wt_free(ctx, p->lr_Yb32_raw);
    wt_free(ctx, p->b_start);
    wt_free(ctx, p->b_fac);
    wt_free(ctx, p->b_idx);
    wt_free(ctx, p->b_L);
    wt_free(ctx, p->fd_s);
    wt_free(ctx, p->fd_raw);
    wt_free(ctx, p->fd_B);
    wt_free(ctx, p->fd_cr);
    wt_free(ctx, p->fd_cphi);
    wt_free(ctx, p->fd_rs_ptr);
    wt_free(ctx, p->fd_rs_idx);
    wt_free(ctx, p->fd_rs_val);
    wt_free(ctx, p->fd_rc);
    wt_free(ctx, p->fd_dots);
    wt_free(ctx, p->pj);
    wt_free(ctx, p->pc);
    wt_free(ctx, p->pa);
    wt_free(ctx, p->pp);
    wt_free(ctx, p->lr_R);
    wt_free(ctx, p->lr_cinv);
    wt_free(ctx, p->part_sl);
    wt_free(ctx, p->fd_rhat);
    wt_free(ctx, p->pu_Y_raw);
    wt_free(ctx, p->pu_spare);
    if (p->fd_r2c) fftw_destroy_plan(p->fd_r2c);
    if (p->fd_c2r) fftw_destroy_plan(p->fd_c2r);
    wt_free(ctx, p);
}

void wt_precond_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->kind == WT_PRECOND_NONE) memcpy(z, r, (size_t)p->n * sizeof *z);
    else if (p->kind == WT_PRECOND_JACOBI)
        for (int64_t i = 0; i < p->n; i++) z[i] = p->jinv[i] * r[i];
    else lowrank_apply(p, r, z); /* B⁻¹ alone when there is no NGS term (and no coarse block: J⁻¹) */
}

void wt_precond_apply_cb(void *user, const double *r, double *z) { wt_precond_apply(user, r, z); }

wt_pcg_precond wt_precond_pcg(const wt_precond *p)
{
    wt_pcg_precond none = {NULL, NULL};
    if (!p || p->kind == WT_PRECOND_NONE) return none;
    /* the callback's user is not const; apply changes only the scratch p points to */
    return (wt_pcg_precond){wt_precond_apply_cb, (void *)p};
}

int wt_precond_kind_of(const wt_precond *p) { return p->kind; }
const char *wt_precond_name(const wt_precond *p) { return kind_names[p->kind]; }
const double *wt_precond_jacobi_inverse(const wt_precond *p) { return p->jinv; }
int wt_precond_rank(const wt_precond *p) { return p->nlr; }
int wt_precond_coarse_size(const wt_precond *p) { return p->nc; }
int64_t wt_precond_nblocks(const wt_precond *p) { return p->nb; }

int wt_precond_block(const wt_precond *p, int64_t b, int64_t *idx, double *block)
{
    if (b < 0 || b >= p->nb) return -1;
    const int q = (int)(p->b_start[b + 1] - p->b_start[b]);
    const double *F = p->b_L + p->b_fac[b];
    if (idx)
        for (int a = 0; a < q; a++) idx[a] = p->b_idx[p->b_start[b] + a];
    if (block) /* (L Lᵀ)_ac = Σ_k≤min(a,c) L_ak L_ck, L_aa = 1 / the stored last entry of row a */
        for (int a = 0; a < q; a++)
            for (int c = 0; c < q; c++) {
                const double *ra = F + (int64_t)a * (a + 1) / 2, *rc = F + (int64_t)c * (c + 1) / 2;
                const int k1 = a < c ? a : c;
                double v = 0.0;
                for (int k = 0; k <= k1; k++)
                    v += (k == a ? 1.0 / ra[a] : ra[k]) * (k == c ? 1.0 / rc[c] : rc[k]);
                block[a + (int64_t)q * c] = v;
            }
    return q;
}

double wt_precond_bytes(const wt_precond *p)
{
    if (!p) return 0.0;
    const int L = wt_tomography_nlayers(p->tomo);
    const double parts = !p->parts ? 0.0
                                   : 8.0 * (double)p->nlgs * (p->pj ? (double)p->n : 0.0) +
                                         8.0 * (p->pc ? (double)(p->nlgs + 1) * p->nc * p->nc : 0.0) +
                                         16.0 * (p->pa ? (double)p->fd_nk * (p->nlgs * L * (L + 1) / 2 + L) : 0.0) +
                                         8.0 * (p->lr_R ? (double)p->nlr * (p->n + p->nlr) : 0.0) +
                                         16.0 * (p->fd_rhat ? (double)p->nlr * L * p->fd_nk : 0.0) +
                                         8.0 * (p->pu_Y_raw ? (double)p->nlr * p->n : 0.0) + (double)p->pu_spare_bytes;
    return parts + 8.0 * (double)p->n * ((p->jinv ? 1.0 : 0.0) + (p->lr_Y ? p->nlr : 0)) + (double)p->lr_nblk * ((p->lr_Yb32 ? 32.0 : 64.0) * p->nlr + 8.0) +
           8.0 * (double)p->nlr * (p->nlr + WT_VEC_CHUNKS + 1) + 16.0 * (double)p->c_nfree +
           16.0 * (double)p->lr_nruns + (double)p->nc * ((p->c_inv32 ? 4.0 : 8.0) * p->nc + 16.0) +
           (p->nb > 0 ? 8.0 * (double)(2 * (p->nb + 1) + p->b_start[p->nb] + p->b_fac[p->nb]) : 0.0) +
           (p->fd_n > 0 ? 8.0 * ((double)p->fd_nk + (double)p->nthreads * (double)p->fd_slice +
                                 (double)p->fd_sc * p->fd_n + 2.0 * p->nc)
                        : 0.0) +
           (p->fd_rs_ptr ? 12.0 * (double)p->fd_rs_ptr[wt_tomography_nlayers(p->tomo) * p->nlr] +
                               8.0 * (double)p->nlr * (p->nc + wt_tomography_nlayers(p->tomo))
                         : 0.0);
}
