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
#include "precond.h"

#include <complex.h> /* before fftw3.h: fftw_complex is then double complex */
#include <fftw3.h>
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

#define WT_FOURIER_MAX_SC 64 /* the fourier kind's coarse square, side per layer at most */

struct wt_precond {
    wt_context *ctx;
    const wt_tomography *tomo; /* the fourier kind's wavelets and layer offsets */
    int kind;
    int64_t n;                /* unknowns */
    int nthreads;             /* the tomography's (small systems run serially) */
    double *jinv;             /* n: J⁻¹ (NULL for none) */
    /* NGS low-rank part (see lowrank_*): P = B + R C_n Rᵀ */
    int nlr;                  /* rank r: the NGS slopes (0: none) */
    double *lr_Y;             /* n x r: B⁻¹ R (coarse_ngs: freed once lr_Yb holds it) */
    double *lr_K;             /* r x r: Cholesky factor of Ĉ⁻¹_NGS + Rᵀ B⁻¹ R */
    double *lr_w;             /* r */
    double *lr_part;          /* r x WT_VEC_CHUNKS: the chunk sums of Yᵀ r */
    int64_t *lr_runs;         /* the row runs where Y is not all zero (wt_vec_runs) */
    int lr_nruns;
    /* coarse_ngs: Y by blocks of 8 rows, only the blocks with a non-zero (see lowrank_blocks) */
    int64_t lr_nblk;          /* kept blocks */
    int64_t *lr_blk;          /* lr_nblk: block b's first row is 8 lr_blk[b] */
    double *lr_Yb, *lr_Yb_raw; /* lr_nblk x r x 8 (block, column, row in the block), 64-byte aligned */
    float *lr_Yb32, *lr_Yb32_raw; /* single (wt_precond_params): the same in float, lr_Yb NULL */
    /* coarse block (coarse_ngs, see coarse_*): J replaced by B = J with the coarse coefficients' rows and
     * columns of the LGS + prior part of M, inverted exactly */
    int nc;                   /* coarse coefficients (0: none) */
    int64_t *c_idx;           /* nc: their indices in c */
    double *c_L;              /* nc x nc: Cholesky factor (lower, column-major) of that block, Lᵀ above */
    double *c_w;              /* nc */
    double *c_inv;            /* coarse_ngs: nc x nc, the block's inverse (L Lᵀ)⁻¹, symmetric, column-major */
    float *c_inv32;           /* single: the same in float, c_inv NULL */
    int64_t *c_free;          /* the runs [c_free[2j], c_free[2j+1]) of unknowns outside the coarse block */
    int c_nfree;
    /* layer blocks below the coarse square (multilevel, see compute_layer_blocks) */
    int64_t nb;               /* blocks (0: none) */
    int64_t *b_start;         /* nb + 1: block b's unknowns are b_idx[b_start[b] .. b_start[b + 1]) */
    int64_t *b_fac;           /* nb + 1: its factor starts at b_L[b_fac[b]] */
    int64_t *b_idx;           /* the unknowns of the blocks, block after block, layer order within one */
    double *b_L;              /* packed Cholesky factors, rows of L, each row's last entry 1 / L_aa */
    /* fourier (see fourier_*): the filter 1/(n² λ_max A(k)) on the half spectrum of every layer */
    int fd_n;                 /* layer side (0: not this kind) */
    int64_t fd_nk;            /* frequencies of the half spectrum, n (n/2 + 1) */
    double *fd_s;             /* fd_nk: the filter */
    double *fd_raw;           /* the allocation fd_buf lies in (fd_buf at its first 64-byte boundary) */
    double *fd_buf;           /* per thread: n² layer values, fd_nk complex values, WT_FOURIER_MAX_SC n of
                                 contraction work; 64-byte slices */
    size_t fd_slice;          /* doubles per thread in fd_buf */
    int fd_sc;                /* side of each layer's coarse square (coarse_basis; 0: no coarse block) */
    double *fd_B;             /* fd_sc x n: the 1-D basis of the coarse space, row i = φ_i */
    double *fd_cr, *fd_cphi;  /* nc: Qᵀ r and Qᵀ φ of the apply, layer after layer (sc² each, i + sc j) */
    /* fourier with the NGS term: Yᵀ r as Rᵀ u on the filtered layers (see fourier_ngs_dots) */
    int64_t *fd_rs_ptr;       /* L r + 1: the entries of column k on layer l are [ptr[l r + k], ptr[l r + k + 1]) */
    int32_t *fd_rs_idx;       /* their points in the layer */
    double *fd_rs_val;        /* the values of W⁻¹ R there */
    double *fd_rc;            /* nc x r: R's rows at the coarse coefficients */
    double *fd_dots;          /* L x r: the layers' R_sᵀ φ_l */
    fftw_plan fd_r2c, fd_c2r;
};

static const char *const kind_names[WT_PRECOND_NKINDS] = {"none", "jacobi", "jacobi_ngs", "coarse_ngs", "multilevel", "fourier"};

const char *wt_precond_kind_name(int kind) { return kind >= 0 && kind < WT_PRECOND_NKINDS ? kind_names[kind] : NULL; }

int wt_precond_kind(const char *name)
{
    for (int k = 0; k < WT_PRECOND_NKINDS; k++)
        if (name && !strcmp(name, kind_names[k])) return k;
    return -1;
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
 * with stride s: coefficients on a sub-lattice of stride s ≥ 2N+2 (N the Daubechies order) have images
 * Ã_m e_λ with disjoint supports in slope space, so one application per colour gives every entry, each
 * subaperture's 2x2 quadratic form attributed to the nearest probe. Buffers: field (n²), coef (n²), work
 * (wavelet), ph (max(ncg, 2n)), sl/z (max slopes). */
static void probe_block(const wt_tomography *t, int l, int level, int orient, int s, double *diag, double *coef,
                        double *field, double *work, double *ph, double *sl, double *z, int a0, int b0)
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
    double cx0 = support_centre(colmag, n), cy0 = support_centre(rowmag, n);

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
        }
    }
}

/* J⁻¹ = 1 / (diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D), the diagonal by probe_block over every layer, level,
 * orientation and colour (~1 s at E-ELT pcg3 size). */
/* What the coloured probing of M needs, from the tomography: the colouring's period s (the smallest power of
 * two ≥ 2N + 2 for Daubechies-N wavelets: probes that far apart do not overlap in M), the largest layer
 * grid, sensor slope count and wavelet workspace (the per-thread buffers). */
static void probe_sizes(const wt_tomography *t, int *s, int64_t *maxn2, int64_t *maxsl, int64_t *wsize)
{
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t), N = wt_wavelet_order(wt_tomography_wavelet(t, 0));
    *s = 1;
    while (*s < 2 * N + 2) *s *= 2;
    *maxn2 = *maxsl = *wsize = 0;
    for (int l = 0; l < L; l++) {
        if (wt_grid_size(wt_tomography_layer_grid(t, l)) > *maxn2) *maxn2 = wt_grid_size(wt_tomography_layer_grid(t, l));
        if ((int64_t)wt_wavelet_work_size(wt_tomography_wavelet(t, l)) > *wsize)
            *wsize = (int64_t)wt_wavelet_work_size(wt_tomography_wavelet(t, l));
    }
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].nslopes > *maxsl) *maxsl = sys->sensors[m].nslopes;
}

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
    probe_sizes(t, &s, &maxn2, &maxsl, &wsize);
    int64_t phn = ncg;
    for (int l = 0; l < L; l++)
        if (2 * wt_tomography_layer_grid(t, l)->nx > phn) phn = 2 * wt_tomography_layer_grid(t, l)->nx;
    int64_t per = 2 * maxn2 + wsize + phn + 2 * maxsl;
    int nth = p->nthreads;
    WT_ALLOC(ctx, diag, p->n, "Jacobi diagonal");
    WT_ALLOC(ctx, buf, (size_t)nth * per, "Jacobi probing workspace");

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
                        probe_block(t, l, level, orient, s, diag, coef, field, work, ph, sl, z, a0, b0);
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
/* cloned for AVX2/AVX-512 like the transforms (WT_CPU_CLONES: both solves' column updates vectorise) */
/* w ← (L Lᵀ)⁻¹ w in place, L (q x q) lower with Lᵀ above the diagonal */
static inline __attribute__((always_inline)) void chol_solves(const double *L, int q, double *w)
{
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
}

WT_CPU_CLONES static void coarse_solve(const wt_precond *p, const double *r, double *z)
{
    const int q = p->nc;
    if (q == 0) return;
    double *w = p->c_w;
    for (int i = 0; i < q; i++) w[i] = r[p->c_idx[i]];
    chol_solves(p->c_L, q, w);
    for (int i = 0; i < q; i++) z[p->c_idx[i]] = w[i];
}

/* coarse_ngs: the block's inverse, column j = (L Lᵀ)⁻¹ e_j, symmetrised (the preconditioner must be symmetric;
 * the solves' rounding is not), in place of the factor. An apply is then one matrix-vector product whose rows
 * split over the threads, where the two triangular solves were chains of 2q dependent columns on one thread
 * (at E-ELT size: 384², 1.2 MB that the operator evicts between applies, ~50 µs of an iteration). */
static int coarse_invert(wt_precond *p, int single)
{
    int st = WT_OK;
    const int q = p->nc;
    WT_ALLOC(p->ctx, p->c_inv, (size_t)q * q, "coarse block inverse");
    for (int j = 0; j < q; j++) {
        double *col = p->c_inv + (size_t)q * j;
        col[j] = 1.0;
        chol_solves(p->c_L, q, col);
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

/* Side of layer l's coarse square: the scaling block and the coarse_levels coarsest detail levels */
static int coarse_side(const wt_tomography *t, int l, int coarse_levels)
{
    const int J = wt_wavelet_levels(wt_tomography_wavelet(t, l)), k = coarse_levels < J ? coarse_levels : J;
    return wt_tomography_layer_grid(t, l)->nx >> (J - k);
}

/* col = M̃ e for an e that is non-zero on layer l only: Σ_LGS Ãᵀ C̃⁻¹ Ã e (the NGS slopes of Γ P W⁻¹ e set to
 * zero before the adjoint: the weight is block-diagonal per sensor, so this drops exactly their term) plus the
 * prior's column on layer l (α D, or the full prior's coupling of the layer's coefficients). sl: nslopes of
 * work. coarse_ngs's block and the fourier kind's symbol are measured this way. */
static void lgs_prior_column(wt_tomography *t, int l, const double *e, double *sl, double *col)
{
    const wt_system *sys = wt_tomography_system(t);
    memset(sl, 0, (size_t)sys->nslopes * sizeof *sl);
    wt_tomography_slopes(t, 1.0, e, sl);
    for (int m = sys->nlgs; m < sys->nsensors; m++)
        memset(sl + sys->sensors[m].offset, 0, (size_t)sys->sensors[m].nslopes * sizeof *sl);
    memset(col, 0, (size_t)wt_tomography_nunknowns(t) * sizeof *col);
    wt_tomography_rhs(t, 1.0, sl, col);
    const int64_t a = wt_tomography_layer_offset(t, l);
    wt_tomography_prior_apply_layer(t, l, e + a, col + a);
}

static int compute_coarse(wt_precond *p, wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t n = p->n;
    double *e = NULL, *sl = NULL, *col = NULL;
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
    /* column j of the LGS + prior part of M */
    for (int j = 0; j < q; j++) {
        e[p->c_idx[j]] = 1.0;
        int lj = 0;
        while (lj + 1 < L && p->c_idx[j] >= wt_tomography_layer_offset(t, lj + 1)) lj++;
        lgs_prior_column(t, lj, e, sl, col);
        for (int i = 0; i < q; i++) p->c_L[i + (size_t)q * j] = col[p->c_idx[i]];
        e[p->c_idx[j]] = 0.0;
    }
    /* symmetrise the rounding of the two triangles before the factorisation */
    for (int j = 0; j < q; j++)
        for (int i = j + 1; i < q; i++)
            p->c_L[i + (size_t)q * j] = 0.5 * (p->c_L[i + (size_t)q * j] + p->c_L[j + (size_t)q * i]);
    WT_TRY(cholesky(ctx, q, p->c_L, "coarse preconditioner"));
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
    return st;
}

/* ---- layer blocks below the coarse block (multilevel) -------------------------------------------
 *
 * What is left after the coarse block is the coupling of the layers at the finer scales. Every LGS sees the
 * sum of the layers along its line of sight, shifted by θ_m h_l (≤ 5.2 m at 18 km for the E-ELT's 60"
 * asterism, ≤ 0.33 m below 1.2 km) and scaled by the cone 1 − h_l/H: a wavelet of layer l and the one at
 * the same place and scale on layer l' land on nearly the same subapertures of every LGS whenever the shift
 * is small against the wavelet's size — the 5 ground layers at every level, all layers at the coarser ones.
 * Jacobi sees each alone, so the iterations must separate them; the prior alone tells them apart.
 * multilevel groups the unknowns by their place in the Mallat layout: block b holds, for one detail
 * position (x, y) (one level, orientation and translate), the coefficient at (x, y) of every layer whose
 * grid has it outside the coarse square, and B_ml holds the exact q x q block of
 *   M̃ = Σ_LGS Ãᵀ C̃⁻¹ Ã + α D            (C̃: the LGS noise without the tip-tilt removal, as J's)
 * on those unknowns (q ≤ L), the coarse block on the coarse square, and nothing between blocks: a block
 * Jacobi over a partition of the unknowns, whose blocks are principal submatrices of the SPD M̃, so B_ml is
 * SPD. Its diagonal is J's. A layer of another size pairs by its Mallat position, which is the same
 * physical place and scale when the layers span the same period (pcg3's 128 x 0.5 m and 64 x 1 m). The
 * entries come by J's coloured probing (probe_block), one forward apply per layer and colour: the images
 * of one layer's probes are disjoint, each subaperture's 2x2 form S_lᵀ C̃⁻¹ S_l' belongs to entry (l, l')
 * of the block whose probe is nearest to it on both layers, and to no block when the two nearest
 * probes differ (that entry lies between blocks). Each block is Cholesky-factored; apply: per block a
 * gather, two triangular solves of order q (2 q² flops) and a scatter, 2 L flops per unknown. */

/* Mallat position (x, y) of an n x n layer with coarse square side sc: the detail block side m (a power of
 * two), or 0 inside the coarse square */
static int detail_side(int x, int y, int sc)
{
    int v = x > y ? x : y;
    if (v < sc) return 0;
    int m = 1;
    while (2 * m <= v) m *= 2;
    return m;
}

/* Accumulates into the blocks (acc: q x q each, column-major, at a_off[b]) the entries of every block of
 * Mallat detail side m, orientation orient and colour (a0, b0) (stride se): the layers in lay[0..nl-1]
 * (those with this block outside their coarse square), their probe fields' support centres cx/cy. Buffers:
 * coef (maxn2), work (wavelet), fields (nl x maxn2), ph (ncg), sl/z (nl x maxsl each), key (nl). */
static void probe_layer_blocks(const wt_tomography *t, int m, int orient, int se, int a0, int b0, int nl,
                               const int *lay, const double *cx, const double *cy, const int *slot,
                               const int64_t *gid, int nmax, const int64_t *a_off, const int *gq, double *acc,
                               double *coef, double *work, double *fields, int64_t maxn2, double *ph, double *sl,
                               double *z, int64_t maxsl, int *key)
{
    const wt_system *sys = wt_tomography_system(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;
    const int nprobe = m / se;
    for (int a = 0; a < nl; a++) {
        const int l = lay[a], n = wt_tomography_layer_grid(t, l)->nx;
        memset(coef, 0, (size_t)n * n * sizeof *coef);
        for (int j = b0; j < m; j += se)
            for (int i = a0; i < m; i += se) coef[bx + i + (int64_t)n * (by + j)] = 1.0;
        wt_wavelet_inverse(wt_tomography_wavelet(t, l), coef, fields + a * maxn2, work);
    }
    for (int mm = 0; mm < sys->nlgs; mm++) {
        const wt_sensor *s_ = &sys->sensors[mm];
        for (int a = 0; a < nl; a++) {
            const int l = lay[a];
            memset(ph, 0, (size_t)ncg * sizeof *ph);
            wt_projection_apply(wt_tomography_projection(t, mm, l), 1.0, fields + a * maxn2, ph);
            double *sa = sl + a * maxsl, *za = z + a * maxsl;
            memset(sa, 0, (size_t)s_->nslopes * sizeof *sa);
            wt_shack_hartmann_apply(s_->sh, 1.0, ph, sa);
            memset(za, 0, (size_t)s_->nslopes * sizeof *za);
            wt_noise_apply_inv(wt_tomography_noise(t, mm), 1.0, sa, za);
        }
        for (int k = 0; k < s_->nsub; k++) {
            double x = 0.0, y = 0.0;
            int any = 0;
            for (int a = 0; a < nl; a++) {
                const double *sa = sl + a * maxsl;
                key[a] = -1;
                if (sa[k] == 0.0 && sa[s_->nsub + k] == 0.0) continue;
                if (!any) wt_shack_hartmann_centre(s_->sh, k, &x, &y);
                any = 1;
                int pi = 0, pj = 0;
                if (nprobe > 1) { /* the nearest probe on layer l, as probe_block attributes it */
                    const int l = lay[a];
                    const wt_grid *g = wt_tomography_layer_grid(t, l);
                    const double alt = wt_tomography_layer_altitude(t, l);
                    const double cone = s_->altitude > 0 ? 1.0 - alt / s_->altitude : 1.0;
                    const int n = g->nx, step = n / m;
                    const double gx = (cone * x + s_->theta_x * alt - g->x0) / g->dx;
                    const double gy = (cone * y + s_->theta_y * alt - g->y0) / g->dx;
                    const double period = (double)step * se;
                    pi = (int)lround((gx - cx[a] - (double)step * a0) / period);
                    pj = (int)lround((gy - cy[a] - (double)step * b0) / period);
                    pi = ((pi % nprobe) + nprobe) % nprobe;
                    pj = ((pj % nprobe) + nprobe) % nprobe;
                }
                key[a] = pi + nprobe * pj;
            }
            if (!any) continue;
            for (int a = 0; a < nl; a++) {
                if (key[a] < 0) continue;
                const int pi = key[a] % nprobe, pj = key[a] / nprobe;
                const int64_t b = gid[bx + a0 + (int64_t)se * pi + (int64_t)nmax * (by + b0 + (int64_t)se * pj)];
                const int q = gq[b];
                double *A = acc + a_off[b];
                const double *sa = sl + a * maxsl;
                for (int c = a; c < nl; c++) {
                    if (key[c] != key[a]) continue;
                    const double *zc = z + c * maxsl;
                    A[slot[a] + (int64_t)q * slot[c]] += sa[k] * zc[k] + sa[s_->nsub + k] * zc[s_->nsub + k];
                }
            }
        }
    }
}

/* The blocks of B_ml below the coarse square (sc[l]: each layer's coarse square side) */
static int compute_layer_blocks(wt_precond *p, const wt_tomography *t, const int *sc)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const double *alpha_d = wt_tomography_alpha_prior(t);
    int64_t *gid = NULL, *a_off = NULL;
    int *gq = NULL;
    double *acc = NULL, *buf = NULL;
    int nmax = 0;
    for (int l = 0; l < L; l++)
        if (wt_tomography_layer_grid(t, l)->nx > nmax) nmax = wt_tomography_layer_grid(t, l)->nx;
    /* the partition: one block per Mallat detail position of the largest grid that some layer has outside
     * its coarse square */
    WT_ALLOC(ctx, gid, (size_t)nmax * nmax, "multilevel block map");
    int64_t nb = 0, nidx = 0, nfac = 0, nacc = 0;
    for (int64_t xy = 0; xy < (int64_t)nmax * nmax; xy++) {
        const int x = (int)(xy % nmax), y = (int)(xy / nmax);
        int q = 0;
        for (int l = 0; l < L; l++) {
            const int n = wt_tomography_layer_grid(t, l)->nx;
            if (x < n && y < n && detail_side(x, y, sc[l])) q++;
        }
        gid[xy] = q ? nb++ : -1;
        nidx += q;
        nfac += q * (q + 1) / 2;
        nacc += (int64_t)q * q;
    }
    p->nb = nb;
    WT_ALLOC(ctx, p->b_start, nb + 1, "multilevel block starts");
    WT_ALLOC(ctx, p->b_fac, nb + 1, "multilevel factor starts");
    WT_ALLOC(ctx, p->b_idx, nidx > 0 ? nidx : 1, "multilevel block indices");
    WT_ALLOC(ctx, p->b_L, nfac > 0 ? nfac : 1, "multilevel block factors");
    WT_ALLOC(ctx, gq, nb > 0 ? nb : 1, "multilevel block sizes");
    WT_ALLOC(ctx, a_off, nb + 1, "multilevel block offsets");
    WT_ALLOC(ctx, acc, nacc > 0 ? nacc : 1, "multilevel blocks");
    {
        int64_t b = 0, i = 0, f = 0, o = 0;
        for (int64_t xy = 0; xy < (int64_t)nmax * nmax; xy++) {
            if (gid[xy] < 0) continue;
            const int x = (int)(xy % nmax), y = (int)(xy / nmax);
            p->b_start[b] = i;
            p->b_fac[b] = f;
            a_off[b] = o;
            int q = 0;
            for (int l = 0; l < L; l++) {
                const int n = wt_tomography_layer_grid(t, l)->nx;
                if (x < n && y < n && detail_side(x, y, sc[l]))
                    p->b_idx[i + q++] = wt_tomography_layer_offset(t, l) + x + (int64_t)n * y;
            }
            gq[b] = q;
            i += q;
            f += q * (q + 1) / 2;
            o += (int64_t)q * q;
            b++;
        }
        p->b_start[nb] = i;
        p->b_fac[nb] = f;
        a_off[nb] = o;
    }

    /* the probing, block side by block side (the layers' levels pair by side) */
    int s;
    int64_t maxn2, maxsl, wsize;
    probe_sizes(t, &s, &maxn2, &maxsl, &wsize);
    int64_t phn = ncg > 2 * nmax ? ncg : 2 * nmax;
    const int nth = p->nthreads;
    const int64_t per = maxn2 + wsize + (int64_t)L * maxn2 + phn + 2 * (int64_t)L * maxsl + L;
    WT_ALLOC(ctx, buf, (size_t)nth * per, "multilevel probing workspace");
    for (int m = nmax / 2; m >= 1; m /= 2)
        for (int orient = 1; orient <= 3; orient++) {
            int lay[WT_MAX_LAYERS], slot[WT_MAX_LAYERS], nl = 0;
            double cx[WT_MAX_LAYERS], cy[WT_MAX_LAYERS];
            for (int l = 0; l < L; l++) {
                const int n = wt_tomography_layer_grid(t, l)->nx;
                if (2 * m > n || m < sc[l]) continue; /* not in this grid, or in its coarse square */
                slot[nl] = nl;
                lay[nl] = l;
                /* the support centre of the block's k = 0 basis function, as probe_block finds it */
                double *coef = buf, *field = buf + maxn2, *work = buf + 2 * maxn2, *mag = work + wsize;
                const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;
                memset(coef, 0, (size_t)n * n * sizeof *coef);
                coef[bx + (int64_t)n * by] = 1.0;
                wt_wavelet_inverse(wt_tomography_wavelet(t, l), coef, field, work);
                memset(mag, 0, 2 * (size_t)n * sizeof *mag);
                for (int iy = 0; iy < n; iy++)
                    for (int ix = 0; ix < n; ix++) {
                        double v = fabs(field[ix + (int64_t)n * iy]);
                        mag[ix] += v;
                        mag[n + iy] += v;
                    }
                cx[nl] = support_centre(mag, n);
                cy[nl] = support_centre(mag + n, n);
                nl++;
            }
            if (nl == 0) continue;
            /* a layer's slot in its blocks: the layers in a block are those of lay[] (the same set for every
             * position of this side and orientation), in increasing order */
            const int se = s < m ? s : m;
#pragma omp parallel for collapse(2) schedule(dynamic, 1) num_threads(nth)
            for (int b0 = 0; b0 < se; b0++)
                for (int a0 = 0; a0 < se; a0++) {
                    double *base = buf + (size_t)wt_thread_id() * per;
                    double *coef = base, *work = coef + maxn2, *fields = work + wsize, *ph = fields + L * maxn2;
                    double *sl = ph + phn, *z = sl + L * maxsl;
                    int key[WT_MAX_LAYERS];
                    probe_layer_blocks(t, m, orient, se, a0, b0, nl, lay, cx, cy, slot, gid, nmax, a_off, gq, acc,
                                       coef, work, fields, maxn2, ph, sl, z, maxsl, key);
                }
        }
    /* the prior on the diagonal, the lower triangle from the upper, and the factors */
    for (int64_t b = 0; b < nb; b++) {
        const int q = gq[b];
        double *A = acc + a_off[b];
        for (int a = 0; a < q; a++) {
            A[a + (int64_t)q * a] += alpha_d[p->b_idx[p->b_start[b] + a]];
            for (int c = a + 1; c < q; c++) A[c + (int64_t)q * a] = A[a + (int64_t)q * c];
        }
        WT_TRY(cholesky(ctx, q, A, "multilevel layer block"));
        /* packed by rows of L: row a holds L[a][0..a], the last entry stored as 1/L[a][a] */
        double *F = p->b_L + p->b_fac[b];
        for (int a = 0, f = 0; a < q; a++) {
            for (int c = 0; c < a; c++) F[f++] = A[a + (int64_t)q * c];
            F[f++] = 1.0 / A[a + (int64_t)q * a];
        }
    }
fail:
    wt_free(ctx, gid);
    wt_free(ctx, a_off);
    wt_free(ctx, gq);
    wt_free(ctx, acc);
    wt_free(ctx, buf);
    return st;
}

/* z[b's unknowns] = B_b⁻¹ r[b's unknowns] for the blocks [b0, b1) */
WT_CPU_CLONES static void layer_blocks_apply(const wt_precond *p, const double *r, double *z, int64_t b0, int64_t b1)
{
    for (int64_t b = b0; b < b1; b++) {
        const int64_t *idx = p->b_idx + p->b_start[b];
        const int q = (int)(p->b_start[b + 1] - p->b_start[b]);
        const double *F = p->b_L + p->b_fac[b];
        double w[WT_MAX_LAYERS];
        for (int a = 0, f = 0; a < q; a++) { /* forward: L y = r */
            double v = r[idx[a]];
            for (int c = 0; c < a; c++) v -= F[f++] * w[c];
            w[a] = v * F[f++];
        }
        for (int a = q - 1; a >= 0; a--) { /* backward: Lᵀ x = y, row a of L is column a of Lᵀ */
            const double *row = F + (int64_t)a * (a + 1) / 2;
            const double v = (w[a] *= row[a]);
            for (int c = 0; c < a; c++) w[c] -= row[c] * v;
        }
        for (int a = 0; a < q; a++) z[idx[a]] = w[a];
    }
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
    if (p->nb > 0) layer_blocks_apply(p, r, z, 0, p->nb);
    else
        for (int64_t i = 0; i < p->n; i++) z[i] = p->jinv[i] * r[i];
    if (p->c_inv || p->c_inv32) coarse_inv_rows(p, r, z, 0, p->nc);
    else coarse_solve(p, r, z);
}

/* ---- Fourier-domain filter (fourier) -------------------------------------------------------------
 *
 * In the closed loop the few iterations of a frame chase a moving MAP (docs/results.md §25): what lags is
 * the layers' common mode at each spatial frequency, which every LGS sees and whose weight falls by orders
 * of magnitude from the fine to the coarse scales. On layers of one periodic n x n grid the LGS + prior
 * part M̃ (as coarse_ngs's block) is, away from the pupil's rim, close to a block convolution: each LGS sees
 * layer l shifted by θ_m h_l (and scaled by the cone about the centre), every layer's prior is circulant.
 * Its symbol A(k), an L x L Hermitian matrix per frequency, is measured from the operator itself: an
 * impulse at the grid's centre on each layer in turn, M̃ applied, the responses on every layer Fourier
 * transformed (L applies at set-up), symmetrised, A ← (A + Aᴴ)/2. The preconditioner scales each frequency
 * by the inverse of A(k)'s largest eigenvalue, the common mode's, the same on every layer:
 *   B_F⁻¹ = F⁻¹ diag(1/λ_max(A(k))) F        (F the 2-D DFT of each layer)
 * SPD: F⁻¹ diag(s) F with s(k) = s(−k) > 0 is a real symmetric circulant. Inverting A(k) exactly (FDPCG,
 * Yang, Vogel & Ellerbroek 2006) was measured worse in the loop: at the low frequencies the L − 6 layer-split
 * directions hold the prior alone, ~10⁶ below the data, and the rim's leakage into them is amplified as
 * much; flooring A's eigenvalues at τ λ_max got better as τ rose, best at τ = 1, this filter (§25). The
 * filter misses the pupil and the LGS tip-tilt removal, which shape the largest scales, where the NGS fix
 * the layers' tip-tilt: the coarse space V_c (each layer's scaling functions of the DWT's coarsest level,
 * coarse_levels = 0, or of coarse_levels levels finer) takes M̃'s exact block there instead:
 *   B⁻¹ = Q (Qᵀ M̃ Q)⁻¹ Qᵀ + Π_d F⁻¹ diag(s) F Π_d,    Π_d = I − Q Qᵀ,
 * Q an orthonormal basis of V_c (SPD: an SPD block on V_c beside a compression of an SPD operator on its
 * complement). 6 iterations went from 13 nm above the converged MAP to 1.5 below with it (§25).
 *
 * The kind works on the layers' values (the tomography's unknowns in space, wt_tomography_space): the
 * same steps as on the wavelet coefficients, W orthogonal, without the DWT pair per layer of each apply
 * of M and of B⁻¹. V_c is V_J' ⊗ V_J' on every layer (J' = J − coarse_levels), spanned by the products
 * φ_i(x) φ_j(y) of the sc = n / 2^J' periodic 1-D scaling functions of level J', which the wavelet's own
 * inverse transform gives (coarse_basis): Qᵀ x and Q c are two 1-D contractions, 2 sc n² flops each
 * (sc = 4 at E-ELT size). The NGS term is added by Woodbury as for the other kinds. Apply, whole layers
 * per thread (the same bits on any thread count): Qᵀ r, the filter on r − Q Qᵀ r (a real FFT pair), Qᵀ of
 * the result; then the coarse block's solve (144² at E-ELT size) and per layer the coarse correction. */

static int fourier_grid(wt_context *ctx, const wt_tomography *t)
{
    const wt_grid *g0 = wt_tomography_layer_grid(t, 0);
    for (int l = 0; l < wt_tomography_nlayers(t); l++) {
        const wt_grid *g = wt_tomography_layer_grid(t, l);
        if (g->nx != g0->nx || g->ny != g0->ny || g->dx != g0->dx || g->nx != g->ny)
            return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: the fourier preconditioner needs every layer on one "
                            "n x n grid of one spacing (recon.<variant>.layer_size, layer_spacing_m); layer %d is "
                            "%d x %d at %g m, layer 0 %d x %d at %g m", l, g->nx, g->ny, g->dx, g0->nx, g0->ny, g0->dx);
        if (wt_wavelet_levels(wt_tomography_wavelet(t, l)) != wt_wavelet_levels(wt_tomography_wavelet(t, 0)) ||
            wt_wavelet_order(wt_tomography_wavelet(t, l)) != wt_wavelet_order(wt_tomography_wavelet(t, 0)))
            return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: the fourier preconditioner needs one wavelet on every "
                            "layer; layer %d differs from layer 0", l);
    }
    return WT_OK;
}

static double *fourier_phi(const wt_precond *p, int id) { return p->fd_buf + (size_t)id * p->fd_slice; }
static fftw_complex *fourier_hat(const wt_precond *p, int id)
{
    return (fftw_complex *)(p->fd_buf + (size_t)id * p->fd_slice + (size_t)p->fd_n * p->fd_n);
}

/* C = Qᵀ X on one layer (C[i + sc j] = Σ_y φ_j(y) Σ_x φ_i(x) X[x + n y]): U_j = Σ_y φ_j(y) X[·, y] by rows
 * (vectorised along x, no reassociation), then the sc² short dots. u: sc n of work. */
WT_CPU_CLONES static void coarse_coef(const wt_precond *p, const double *X, double *C, double *u)
{
    const int n = p->fd_n, sc = p->fd_sc;
    const double *B = p->fd_B; /* sc x n: row i = φ_i */
    memset(u, 0, (size_t)sc * n * sizeof *u);
    for (int y = 0; y < n; y++)
        for (int j = 0; j < sc; j++) {
            const double b = B[(size_t)j * n + y];
            double *uj = u + (size_t)j * n;
            const double *xy = X + (size_t)n * y;
            for (int x = 0; x < n; x++) uj[x] += b * xy[x];
        }
    for (int j = 0; j < sc; j++)
        for (int i = 0; i < sc; i++) {
            double s = 0.0;
            for (int x = 0; x < n; x++) s += B[(size_t)i * n + x] * u[(size_t)j * n + x];
            C[i + sc * j] = s;
        }
}

/* X = S + Q C on one layer (X[x + n y] = S[x + n y] + Σ_i φ_i(x) g_i(y), g_i(y) = Σ_j C[i + sc j] φ_j(y)); S may be X
 * (X += Q C), the same operations in the same order either way */
WT_CPU_CLONES static void coarse_add_to(const wt_precond *p, const double *C, const double *S, double *X)
{
    const int n = p->fd_n, sc = p->fd_sc;
    const double *B = p->fd_B;
    double g[WT_FOURIER_MAX_SC];
    for (int y = 0; y < n; y++) {
        for (int i = 0; i < sc; i++) {
            double s = 0.0;
            for (int j = 0; j < sc; j++) s += C[i + sc * j] * B[(size_t)j * n + y];
            g[i] = s;
        }
        double *xy = X + (size_t)n * y;
        const double *sy = S + (size_t)n * y;
        for (int i = 0; i < sc; i++) {
            const double gi = g[i], *bi = B + (size_t)i * n, *src = i ? xy : sy;
            for (int x = 0; x < n; x++) xy[x] = src[x] + bi[x] * gi;
        }
    }
}

static void coarse_add(const wt_precond *p, const double *C, double *X) { coarse_add_to(p, C, X, X); }

/* The sc periodic 1-D scaling functions of level J' = J − coarse_levels on n points (fd_B, sc x n): the
 * wavelet's inverse transform of J' levels maps the unit coefficient (i, 0) of its approximation block to
 * φ_i(x) φ_0(y), whose sum over y is φ_i(x) (√2)^J' (each synthesis level multiplies a sum by Σh = √2).
 * Checked: orthonormal and the 2-D functions their products, to 1e-12 (else WT_ERR_NUMERIC). */
static int coarse_basis(wt_precond *p, const wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_wavelet *w0 = wt_tomography_wavelet(t, 0);
    const int n = p->fd_n, J = wt_wavelet_levels(w0), k = coarse_levels < J ? coarse_levels : J, Jc = J - k;
    const int sc = n >> Jc;
    wt_wavelet *wc = NULL;
    double *e = NULL, *f = NULL, *ww = NULL;
    if (sc > WT_FOURIER_MAX_SC)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: fourier with coarse_levels %d gives a coarse square of side %d "
                        "per layer; at most %d (lower coarse_levels)", coarse_levels, sc, WT_FOURIER_MAX_SC);
    p->fd_sc = sc;
    WT_ALLOC(ctx, p->fd_B, (size_t)sc * n, "fourier coarse basis");
    if (Jc == 0) { /* the whole layer: unit vectors */
        for (int i = 0; i < sc; i++) p->fd_B[(size_t)i * n + i] = 1.0;
        return WT_OK;
    }
    WT_TRY(wt_wavelet_alloc(ctx, n, wt_wavelet_order(w0), Jc, &wc));
    WT_ALLOC(ctx, e, (size_t)n * n, "fourier coarse probe");
    WT_ALLOC(ctx, f, (size_t)n * n, "fourier coarse function");
    WT_ALLOC(ctx, ww, wt_wavelet_work_size(wc), "fourier coarse work");
    const double norm = pow(sqrt(2.0), Jc);
    for (int i = 0; i < sc; i++) {
        e[i] = 1.0;
        wt_wavelet_inverse(wc, e, f, ww);
        e[i] = 0.0;
        for (int x = 0; x < n; x++) {
            double s = 0.0;
            for (int y = 0; y < n; y++) s += f[x + (size_t)n * y];
            p->fd_B[(size_t)i * n + x] = s / norm;
        }
    }
    double worst = 0.0;
    for (int i = 0; i < sc; i++)
        for (int j = 0; j < sc; j++) {
            double s = 0.0;
            for (int x = 0; x < n; x++) s += p->fd_B[(size_t)i * n + x] * p->fd_B[(size_t)j * n + x];
            worst = fmax(worst, fabs(s - (i == j)));
        }
    for (int i = 0; i < sc; i += sc > 1 ? sc - 1 : 1) { /* the first and the last 2-D function of each row */
        for (int j = 0; j < sc; j += sc > 1 ? sc - 1 : 1) {
            e[i + (size_t)n * j] = 1.0;
            wt_wavelet_inverse(wc, e, f, ww);
            e[i + (size_t)n * j] = 0.0;
            for (int y = 0; y < n; y++)
                for (int x = 0; x < n; x++)
                    worst = fmax(worst, fabs(f[x + (size_t)n * y] - p->fd_B[(size_t)i * n + x] * p->fd_B[(size_t)j * n + y]));
        }
    }
    if (!(worst <= 1e-12))
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "fourier preconditioner: the coarse space's 1-D basis (level %d of %d on %d "
                      "points) is off by %g (orthonormal products expected within 1e-12)", Jc, J, n, worst);
fail:
    wt_wavelet_free(wc);
    wt_free(ctx, e);
    wt_free(ctx, f);
    wt_free(ctx, ww);
    return st;
}

/* Qᵀ M̃ Q on V_c, Cholesky-factored in c_L (Lᵀ above the diagonal, as coarse_solve reads it): M̃ applied to
 * each product φ_i ⊗ φ_j on each layer (lgs_prior_column, nc applies at set-up), Qᵀ of the response */
static int fourier_coarse_block(wt_precond *p, wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t), n = p->fd_n, sc = p->fd_sc, sc2 = sc * sc, q = L * sc2;
    const int64_t m2 = (int64_t)n * n;
    double *e = NULL, *sl = NULL, *col = NULL, *u = NULL;
    if (q > 4096)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: fourier's coarse block has %d coefficients; at most 4096 "
                        "(lower coarse_levels)", q);
    WT_ALLOC(ctx, p->c_L, (size_t)q * q, "coarse block");
    WT_ALLOC(ctx, p->c_w, q, "coarse work");
    WT_ALLOC(ctx, e, p->n, "coarse probe");
    WT_ALLOC(ctx, sl, sys->nslopes, "coarse probe slopes");
    WT_ALLOC(ctx, col, p->n, "coarse column");
    WT_ALLOC(ctx, u, (size_t)sc * n, "coarse contraction");
    for (int lj = 0; lj < L; lj++) {
        const int64_t o = wt_tomography_layer_offset(t, lj);
        for (int j = 0; j < sc2; j++) {
            const double *bx = p->fd_B + (size_t)(j % sc) * n, *by = p->fd_B + (size_t)(j / sc) * n;
            for (int y = 0; y < n; y++)
                for (int x = 0; x < n; x++) e[o + x + (int64_t)n * y] = bx[x] * by[y];
            lgs_prior_column(t, lj, e, sl, col);
            for (int l = 0; l < L; l++)
                coarse_coef(p, col + wt_tomography_layer_offset(t, l), p->c_L + (size_t)q * (lj * sc2 + j) + l * sc2, u);
        }
        memset(e + o, 0, (size_t)m2 * sizeof *e);
    }
    for (int j = 0; j < q; j++) /* symmetrise the rounding of the two triangles before the factorisation */
        for (int i = j + 1; i < q; i++)
            p->c_L[i + (size_t)q * j] = 0.5 * (p->c_L[i + (size_t)q * j] + p->c_L[j + (size_t)q * i]);
    WT_TRY(cholesky(ctx, q, p->c_L, "fourier coarse block"));
    for (int i = 0; i < q; i++)
        for (int k = 0; k < i; k++) p->c_L[k + (size_t)q * i] = p->c_L[i + (size_t)q * k];
    p->nc = q;
    WT_ALLOC(ctx, p->fd_cr, q, "fourier coarse coefficients");
    WT_ALLOC(ctx, p->fd_cphi, q, "fourier coarse coefficients of the filtered layers");
fail:
    wt_free(ctx, e);
    wt_free(ctx, sl);
    wt_free(ctx, col);
    wt_free(ctx, u);
    return st;
}

static int compute_fourier(wt_precond *p, wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    double *e = NULL, *sl = NULL, *col = NULL;
    double complex *A = NULL;
    if (!wt_tomography_space(t))
        return WT_ERROR(ctx, WT_ERR_INVALID, "fourier preconditioner: the tomography's unknowns must be the layers' "
                        "values (wt_tomography_params.space = 1), not wavelet coefficients");
    WT_TRY(fourier_grid(ctx, t));
    const int n = wt_tomography_layer_grid(t, 0)->nx, nh = n / 2 + 1;
    const int64_t n2 = (int64_t)n * n, nk = (int64_t)n * nh;
    p->fd_n = n;
    p->fd_nk = nk;
    /* n² and 2 nk are multiples of 8 doubles for n ≥ 8: every thread's slices keep the first one's alignment,
     * which the plans were made for; then sc n of contraction work */
    p->fd_slice = (size_t)(n2 + 2 * nk + (int64_t)WT_FOURIER_MAX_SC * n);
    /* at a 64-byte boundary: the plans are made on it, and the learnt wisdom on arrays as aligned (core/la/fft.c) */
    WT_ALLOC(ctx, p->fd_raw, (size_t)p->nthreads * p->fd_slice + 8, "fourier preconditioner work");
    p->fd_buf = wt_align64(p->fd_raw);
    WT_ALLOC(ctx, p->fd_s, nk, "fourier preconditioner filter");
    WT_ALLOC(ctx, A, (size_t)nk * L * L, "fourier preconditioner symbol");
    WT_ALLOC(ctx, e, p->n, "fourier probe");
    WT_ALLOC(ctx, sl, sys->nslopes, "fourier probe slopes");
    WT_ALLOC(ctx, col, p->n, "fourier probe column");
    double *phi = fourier_phi(p, 0);
    fftw_complex *hat = fourier_hat(p, 0);
    /* FFTW's planner is global and not thread-safe: planned here, at set-up, as the tomography's prior (core/la/
     * fft.h: FFTW_ESTIMATE or its wisdom's measured plans; no array touched, the same algorithm every run) */
    WT_TRY(wt_fft_plan_pair(ctx, wt_tomography_fft(t), n, phi, hat, "fourier preconditioner", &p->fd_r2c,
                            &p->fd_c2r));
    const int64_t centre = n / 2 + (int64_t)n * (n / 2);
    for (int lp = 0; lp < L; lp++) {
        const int64_t o = wt_tomography_layer_offset(t, lp);
        e[o + centre] = 1.0;
        lgs_prior_column(t, lp, e, sl, col); /* M̃'s column, as coarse_ngs's block */
        e[o + centre] = 0.0;
        for (int l = 0; l < L; l++) {
            memcpy(phi, col + wt_tomography_layer_offset(t, l), (size_t)n2 * sizeof *phi);
            fftw_execute_dft_r2c(p->fd_r2c, phi, hat);
            /* the response of the impulse at (n/2, n/2): symbol = spectrum · e^{2πi k·(n/2, n/2)/n} = (−1)^(kx+ky) */
            for (int ky = 0; ky < n; ky++)
                for (int kx = 0; kx < nh; kx++) {
                    const int64_t k = kx + (int64_t)nh * ky;
                    A[(size_t)k * L * L + l + (size_t)L * lp] = (((kx + ky) & 1) ? -1.0 : 1.0) * hat[k];
                }
        }
    }
    for (int64_t k = 0; k < nk; k++) {
        double complex *a = A + (size_t)k * L * L; /* column-major, (l, l') at l + L l' */
        for (int j = 0; j < L; j++)
            for (int i = j; i < L; i++) a[i + L * j] = 0.5 * (a[i + L * j] + conj(a[j + L * i]));
        double ev[WT_MAX_LAYERS];
        const lapack_int info = LAPACKE_zheev(LAPACK_COL_MAJOR, 'N', 'L', L, (lapack_complex_double *)a, L, ev);
        if (info != 0 || !(ev[L - 1] > 0.0) || !isfinite(ev[L - 1])) {
            st = WT_ERROR(ctx, WT_ERR_NUMERIC, "fourier preconditioner: the largest eigenvalue of the %d x %d symbol "
                          "at frequency (%lld, %lld) is %g (LAPACK zheev info %d); expected positive", L, L,
                          (long long)(k % nh), (long long)(k / nh), info == 0 ? ev[L - 1] : NAN, (int)info);
            goto fail;
        }
        p->fd_s[k] = 1.0 / ((double)n2 * ev[L - 1]); /* the 1/n² of the unnormalised inverse FFT folded in */
    }
    if (coarse_levels >= 0) {
        WT_TRY(coarse_basis(p, t, coarse_levels));
        WT_TRY(fourier_coarse_block(p, t));
    }
fail:
    wt_free(ctx, A);
    wt_free(ctx, e);
    wt_free(ctx, sl);
    wt_free(ctx, col);
    return st;
}

/* With the NGS term, P⁻¹ r = u − Y K⁻¹ Yᵀ r with u = B⁻¹ r. Yᵀ r = Rᵀ u (B symmetric), and Rᵀ u needs no pass
 * over Y (n x r, 14 MB at E-ELT size): R's columns, the NGS slopes' adjoints, hold a few hundred values per
 * layer (the sensors' subaperture rims through the bilinear projection: ~70 000 for the E-ELT's 12 slopes),
 * and u_l = φ_l + Q (u_c − c_l) with φ_l the filtered layer and c_l = Qᵀ φ_l:
 *   Rᵀ u = Σ_l R_lᵀ φ_l + R_cᵀ (u_c − c),    R_c = Qᵀ R  (nc x r),
 * the sparse dots inside each layer's task, the coarse term after them. Only the update z −= Y w reads Y. */
static void lowrank_solve(const wt_precond *p, double *w);
WT_CPU_CLONES static void yb_update(const wt_precond *p, const double *w, double *z, int64_t b0, int64_t b1);

static void fourier_ngs_dots(const wt_precond *p, int l, const double *phi)
{
    const int q = p->nlr;
    for (int k = 0; k < q; k++) {
        double d = 0.0;
        for (int64_t e = p->fd_rs_ptr[l * q + k]; e < p->fd_rs_ptr[l * q + k + 1]; e++)
            d += p->fd_rs_val[e] * phi[p->fd_rs_idx[e]];
        p->fd_dots[l * q + k] = d;
    }
}

/* z = B⁻¹ r (ngs = 0) or P⁻¹ r (ngs = 1): whole layers per thread, the coarse solve and the Woodbury weights
 * on one, the coarse corrections by layers and the update by rows (allocates nothing; every value is
 * computed in one fixed order whatever thread runs it: the same bits on any thread count) */
static void fourier_apply(const wt_precond *p, const double *r, double *z, int ngs)
{
    const wt_tomography *t = p->tomo;
    const int L = wt_tomography_nlayers(t), q = ngs ? p->nlr : 0, sc2 = p->fd_sc * p->fd_sc;
    const int64_t nk = p->fd_nk, m2 = (int64_t)p->fd_n * p->fd_n;
#pragma omp parallel num_threads(p->nthreads)
    {
#pragma omp for schedule(dynamic, 1)
        for (int l = 0; l < L; l++) {
            const int id = wt_thread_id();
            double *phi = fourier_phi(p, id), *hat = (double *)fourier_hat(p, id);
            double *u = phi + p->fd_slice - (size_t)WT_FOURIER_MAX_SC * p->fd_n; /* the contractions' work */
            const int64_t o = wt_tomography_layer_offset(t, l);
            if (p->nc > 0) { /* the filter on Π_d r: Q's coefficients out, φ = r − Q c in one pass */
                double *c = p->fd_cr + (size_t)l * sc2, mc[WT_FOURIER_MAX_SC * WT_FOURIER_MAX_SC];
                coarse_coef(p, r + o, c, u);
                for (int i = 0; i < sc2; i++) mc[i] = -c[i];
                coarse_add_to(p, mc, r + o, phi);
            } else memcpy(phi, r + o, (size_t)m2 * sizeof *phi);
            fftw_execute_dft_r2c(p->fd_r2c, phi, (fftw_complex *)hat);
            for (int64_t k = 0; k < nk; k++) {
                hat[2 * k] *= p->fd_s[k];
                hat[2 * k + 1] *= p->fd_s[k];
            }
            /* FFTW runs the plan on z's layer when it has the planning arrays' alignment (64 bytes: the PCG's
             * vectors do); the same codelets either way, so the same bits */
            double *zl = ((uintptr_t)(z + o) & 63) == 0 ? z + o : phi;
            fftw_execute_dft_c2r(p->fd_c2r, (fftw_complex *)hat, zl);
            if (p->nc > 0) coarse_coef(p, zl, p->fd_cphi + (size_t)l * sc2, u);
            if (q > 0) fourier_ngs_dots(p, l, zl);
            if (zl != z + o) memcpy(z + o, phi, (size_t)m2 * sizeof *z);
        }
        if (p->nc > 0 || q > 0) {
#pragma omp single
            {
                if (p->nc > 0) { /* c_w = (Qᵀ M̃ Q)⁻¹ Qᵀ r − Qᵀ φ: the coarse correction of every layer */
                    double *w = p->c_w;
                    memcpy(w, p->fd_cr, (size_t)p->nc * sizeof *w);
                    chol_solves(p->c_L, p->nc, w);
                    for (int i = 0; i < p->nc; i++) w[i] -= p->fd_cphi[i];
                }
                if (q > 0) {
                    double *wv = p->lr_w;
                    for (int k = 0; k < q; k++) {
                        double d = 0.0;
                        for (int l = 0; l < L; l++) d += p->fd_dots[l * q + k];
                        for (int i = 0; i < p->nc; i++) d += p->fd_rc[i + (size_t)p->nc * k] * p->c_w[i];
                        wv[k] = d;
                    }
                    lowrank_solve(p, wv);
                }
            } /* (its barrier) */
            if (p->nc > 0) {
#pragma omp for schedule(dynamic, 1)
                for (int l = 0; l < L; l++) coarse_add(p, p->c_w + (size_t)l * sc2, z + wt_tomography_layer_offset(t, l));
            }
            if (q > 0) {
#ifdef _OPENMP
                const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
                const int nt = 1, id = 0;
#endif
                yb_update(p, p->lr_w, z, p->lr_nblk * id / nt, p->lr_nblk * (id + 1) / nt);
            }
        }
    }
}

/* B⁻¹ r of the kind: the Fourier filter, or J⁻¹ / the layer blocks below the coarse block's exact solve */
static void base_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->fd_n > 0) fourier_apply(p, r, z, 0);
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

/* K v = w in place by the Cholesky factor of K (lower, column-major) */
static void lowrank_solve(const wt_precond *p, double *w)
{
    const int q = p->nlr;
    for (int i = 0; i < q; i++) {
        double s = w[i];
        for (int k = 0; k < i; k++) s -= p->lr_K[i + (size_t)q * k] * w[k];
        w[i] = s / p->lr_K[i + (size_t)q * i];
    }
    for (int i = q - 1; i >= 0; i--) {
        double s = w[i];
        for (int k = i + 1; k < q; k++) s -= p->lr_K[k + (size_t)q * i] * w[k];
        w[i] = s / p->lr_K[i + (size_t)q * i];
    }
}

/* coarse_ngs's Woodbury term by blocks of 8 rows (lr_Yb: only the blocks where Y has a non-zero, each block's
 * r columns of 8 rows side by side). Yᵀ r: the kept blocks fall into WT_VEC_CHUNKS fixed chunks; in a chunk,
 * row e of every block (e < 8) adds into lane e of column k's sum, in block order, and the chunk's value is the
 * 8 lanes added pairwise in a fixed tree; the chunks are added in order (wt_vec_dot_many_finish). Which thread
 * runs a chunk changes nothing: the same bits for any thread count. B a compile-time constant (always inlined:
 * the B sums of 8 lanes stay in vector registers); a last block past n takes only its rows < n. The update
 * reads the same copy (one pass over ~1 MB each instead of a column-major Y and a row-major copy). */
typedef double yb_vec __attribute__((vector_size(64), aligned(8))); /* 8 rows (GCC/clang vectors: plain
                                                                     per-lane IEEE operations, any ISA) */
typedef float yb_vec32 __attribute__((vector_size(32), aligned(4))); /* 8 rows of the float copy (single) */

/* Column k of block b: 8 rows of Y, from the float copy (f32, converted: exact) or the double one (a macro: a
 * function returning the 64-byte vector by value would change the ABI off AVX-512) */
#define YB_COL(p, B, b, k, f32)                                                                                    \
    ((f32) ? __builtin_convertvector(((const yb_vec32 *)((p)->lr_Yb32 + (size_t)(b) * (B) * 8))[k], yb_vec)      \
           : ((const yb_vec *)((p)->lr_Yb + (size_t)(b) * (B) * 8))[k])

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

/* z ← z − Σ_k w_k Y_k on the kept blocks [b0, b1): each row takes the columns in order k = 0, 1, … (rows of
 * blocks not kept: Y is 0 there, z stays) */
static inline __attribute__((always_inline)) void yb_update_blocks(const int B, const int f32, const wt_precond *p,
                                                                   const double *restrict w, double *restrict z,
                                                                   int64_t b0, int64_t b1)
{
    const int64_t n = p->n;
    for (int64_t b = b0; b < b1; b++) {
        const int64_t i0 = 8 * p->lr_blk[b];
        if (i0 + 8 <= n) {
            yb_vec v = *(yb_vec *)(z + i0);
            for (int k = 0; k < B; k++) v -= w[k] * YB_COL(p, B, b, k, f32);
            *(yb_vec *)(z + i0) = v;
        } else
            for (int e = 0; e < n - i0; e++) {
                double v = z[i0 + e];
                for (int k = 0; k < B; k++) v -= w[k] * YB_COL(p, B, b, k, f32)[e];
                z[i0 + e] = v;
            }
    }
}

WT_CPU_CLONES static void yb_update(const wt_precond *p, const double *w, double *z, int64_t b0, int64_t b1)
{
    if (p->nlr == 12 && p->lr_Yb32) yb_update_blocks(12, 1, p, w, z, b0, b1);
    else if (p->nlr == 12) yb_update_blocks(12, 0, p, w, z, b0, b1);
    else if (p->lr_Yb32) yb_update_blocks(p->nlr, 1, p, w, z, b0, b1);
    else yb_update_blocks(p->nlr, 0, p, w, z, b0, b1);
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
        lowrank_solve(p, w);
        yb_update(p, w, z, p->lr_nblk * id / nt, p->lr_nblk * (id + 1) / nt);
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
        base_apply(p, r, z);
        return;
    }
    if (p->fd_n > 0) {
        fourier_apply(p, r, z, 1);
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
            for (int c = 0; c < 64; c++) layer_blocks_apply(p, r, z, p->nb * c / 64, p->nb * (c + 1) / 64);
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
            lowrank_solve(p, p->lr_w);
        } /* (its implicit barrier: w is ready for every thread, and every B⁻¹ r written) */
        wt_vec_sub_many_range(z, p->lr_Y, n, q, p->lr_w, p->lr_runs, p->lr_nruns, n * id / nt, n * (id + 1) / nt);
    }
}

/* fourier_apply's form of R (n x r, the layers' values): each column on each layer where it is not zero (the
 * adjoint leaves exact zeros off the NGS footprints' rims), and R_c = Qᵀ R (nc x r) */
static int fourier_ngs_columns(wt_precond *p, const wt_tomography *t, const double *R)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const int L = wt_tomography_nlayers(t), q = p->nlr, sc2 = p->fd_sc * p->fd_sc;
    const int64_t m2 = (int64_t)p->fd_n * p->fd_n;
    double *c = NULL, *u = NULL;
    WT_ALLOC(ctx, p->fd_rs_ptr, (size_t)L * q + 1, "fourier NGS column pointers");
    WT_ALLOC(ctx, p->fd_dots, (size_t)L * q, "fourier NGS dots");
    WT_ALLOC(ctx, p->fd_rc, (size_t)p->nc * q + 1, "fourier NGS coarse rows");
    int64_t nnz = 0;
    for (int pass = 0; pass < 2; pass++) { /* count, then fill */
        nnz = 0;
        for (int l = 0; l < L; l++)
            for (int k = 0; k < q; k++) {
                const double *f = R + (size_t)p->n * k + wt_tomography_layer_offset(t, l);
                if (pass) p->fd_rs_ptr[l * q + k] = nnz;
                for (int64_t i = 0; i < m2; i++)
                    if (f[i] != 0.0) {
                        if (pass) {
                            p->fd_rs_idx[nnz] = (int32_t)i;
                            p->fd_rs_val[nnz] = f[i];
                        }
                        nnz++;
                    }
            }
        if (!pass) {
            WT_ALLOC(ctx, p->fd_rs_idx, nnz + 1, "fourier NGS column points");
            WT_ALLOC(ctx, p->fd_rs_val, nnz + 1, "fourier NGS column values");
        }
    }
    p->fd_rs_ptr[(size_t)L * q] = nnz;
    if (p->nc > 0) {
        WT_ALLOC(ctx, c, sc2, "fourier NGS coarse coefficients");
        WT_ALLOC(ctx, u, (size_t)p->fd_sc * p->fd_n, "fourier NGS contraction");
        for (int k = 0; k < q; k++)
            for (int l = 0; l < L; l++) {
                coarse_coef(p, R + (size_t)p->n * k + wt_tomography_layer_offset(t, l), c, u);
                for (int i = 0; i < sc2; i++) p->fd_rc[l * sc2 + i + (size_t)p->nc * k] = c[i];
            }
    }
fail:
    wt_free(ctx, c);
    wt_free(ctx, u);
    return st;
}

static int compute_lowrank(wt_precond *p, wt_tomography *t, int single)
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
    WT_ALLOC(ctx, p->lr_Y, (size_t)n * q, "NGS preconditioner Y");
    WT_ALLOC(ctx, p->lr_K, (size_t)q * q, "NGS preconditioner K");
    WT_ALLOC(ctx, p->lr_w, q, "NGS preconditioner work");
    WT_ALLOC(ctx, p->lr_part, (size_t)q * WT_VEC_CHUNKS, "NGS preconditioner work");
    /* coarse_ngs and fourier keep Y by blocks of 8 rows (below); the others column-major, with its zero runs */
    const int blocked = p->kind == WT_PRECOND_COARSE_NGS || p->fd_n > 0;
    if (!blocked) WT_ALLOC(ctx, p->lr_runs, n + 1, "NGS preconditioner runs");
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
    for (int k = 0; k < q; k++) base_apply(p, R + (size_t)n * k, p->lr_Y + (size_t)n * k);
    if (!blocked) p->lr_nruns = wt_vec_runs(p->lr_Y, n, q, n, p->lr_runs);
    for (int k = 0; k < q; k++)
        for (int j = 0; j <= k; j++) {
            double v = cinv[j + (size_t)q * k] + wt_vec_dot(R + (size_t)j * n, p->lr_Y + (size_t)k * n, n);
            p->lr_K[j + (size_t)q * k] = p->lr_K[k + (size_t)q * j] = v;
        }
    /* in-place Cholesky, lower triangle (K is SPD: Ĉ⁻¹_NGS SPD, RᵀB⁻¹R semi-definite) */
    WT_TRY(cholesky(ctx, q, p->lr_K, "NGS preconditioner"));
    p->nlr = q;
    if (p->fd_n > 0) WT_TRY(fourier_ngs_columns(p, t, R));
    if (blocked) { /* Y by blocks of 8 rows, the blocks with a non-zero */
        const int64_t nb8 = (n + 7) / 8;
        WT_ALLOC(ctx, p->lr_blk, nb8, "NGS preconditioner blocks");
        for (int64_t b = 0; b < nb8; b++) {
            int nz = 0;
            for (int64_t i = 8 * b; i < 8 * b + 8 && i < n && !nz; i++)
                for (int k = 0; k < q && !nz; k++) nz = p->lr_Y[(size_t)k * n + i] != 0.0;
            if (nz) p->lr_blk[p->lr_nblk++] = b;
        }
        if (single) { /* the blocks in float, each value rounded once (64-byte aligned: 16 floats) */
            WT_ALLOC(ctx, p->lr_Yb32_raw, (size_t)p->lr_nblk * q * 8 + 16, "NGS preconditioner Y (blocks, float)");
            p->lr_Yb32 = p->lr_Yb32_raw + ((64 - (uintptr_t)p->lr_Yb32_raw % 64) % 64) / sizeof(float);
        } else {
            WT_ALLOC(ctx, p->lr_Yb_raw, (size_t)p->lr_nblk * q * 8 + 8, "NGS preconditioner Y (blocks)");
            p->lr_Yb = wt_align64(p->lr_Yb_raw);
        }
        for (int64_t b = 0; b < p->lr_nblk; b++)
            for (int k = 0; k < q; k++)
                for (int a = 0; a < 8; a++) {
                    const size_t at = ((size_t)b * q + k) * 8 + a;
                    const int64_t i = 8 * p->lr_blk[b] + a;
                    const double v = i < n ? p->lr_Y[(size_t)k * n + i] : 0.0; /* (rows past n: 0) */
                    if (single) p->lr_Yb32[at] = (float)v;
                    else p->lr_Yb[at] = v;
                }
        wt_free(ctx, p->lr_Y); /* the applies read the blocks only */
        p->lr_Y = NULL;
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
    if (p->kind == WT_PRECOND_FOURIER) WT_TRY(compute_fourier(p, t, par->coarse_levels));
    else if (p->kind >= WT_PRECOND_COARSE_NGS) WT_TRY(compute_coarse(p, t, par->coarse_levels));
    if (p->kind == WT_PRECOND_COARSE_NGS) WT_TRY(coarse_invert(p, par->single));
    if (p->kind == WT_PRECOND_MULTILEVEL) {
        int sc[WT_MAX_LAYERS];
        for (int l = 0; l < wt_tomography_nlayers(t); l++) sc[l] = coarse_side(t, l, par->coarse_levels);
        WT_TRY(compute_layer_blocks(p, t, sc));
    }
    if (p->kind >= WT_PRECOND_JACOBI_NGS) WT_TRY(compute_lowrank(p, t, par->single));
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
    return 8.0 * (double)p->n * ((p->jinv ? 1.0 : 0.0) + (p->lr_Y ? p->nlr : 0)) + (double)p->lr_nblk * ((p->lr_Yb32 ? 32.0 : 64.0) * p->nlr + 8.0) +
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
