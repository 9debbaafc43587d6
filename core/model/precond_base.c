/* core/model/precond_base.c: what the preconditioners are built from (precond.h), below every kind:
 *
 *   the columns of M̃ = Σ_LGS Ãᵀ C̃⁻¹ Ã + Σ_l P_l for a probe on one layer, whole or by parts (each LGS's, the
 *   prior's: the parts of an update, SPEC §12 "Updates"), the coloured probing's geometry, the dense Cholesky
 *   factorisation of a block, and the NGS term's kernels on its factor K and its blocked Y (P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ).
 */
#include "precond_base.h"

#include <math.h>
#include <string.h>

const char *const wt_precond__kind_names[WT_PRECOND_NKINDS] = {"none", "jacobi", "jacobi_ngs", "coarse_ngs", "multilevel", "fourier"};

/* Centre (in grid points, unwrapped) of the support of a periodic 1-D profile: the middle of the
 * complement of its largest circular run of zeros. */
double wt_precond__support_centre(const double *mag, int n)
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

/* What the coloured probing of M needs, from the tomography: the colouring's period s (the smallest power of
 * two ≥ 2N + 2 for Daubechies-N wavelets: probes that far apart do not overlap in M), the largest layer
 * grid, sensor slope count and wavelet workspace (the per-thread buffers). */
void wt_precond__probe_sizes(const wt_tomography *t, int *s, int64_t *maxn2, int64_t *maxsl, int64_t *wsize)
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

/* In-place Cholesky of the q x q SPD matrix A (column-major; lower triangle used and overwritten) */
int wt_precond__cholesky(wt_context *ctx, int q, double *A, const char *what)
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

int wt_precond__coarse_factor(wt_precond *p, int q, const char *what)
{
    /* symmetrise the rounding of the two triangles before the factorisation */
    for (int j = 0; j < q; j++)
        for (int i = j + 1; i < q; i++)
            p->c_L[i + (size_t)q * j] = 0.5 * (p->c_L[i + (size_t)q * j] + p->c_L[j + (size_t)q * i]);
    const int st = wt_precond__cholesky(p->ctx, q, p->c_L, what);
    if (st < 0) return st;
    /* Lᵀ into the (unused) upper triangle: column i above the diagonal = row i of L */
    for (int i = 0; i < q; i++)
        for (int k = 0; k < i; k++) p->c_L[k + (size_t)q * i] = p->c_L[i + (size_t)q * k];
    p->nc = q;
    return WT_OK;
}

/* col = M̃ e for an e that is non-zero on layer l only: Σ_LGS Ãᵀ C̃⁻¹ Ã e (the NGS slopes of Γ P W⁻¹ e set to
 * zero before the adjoint: the weight is block-diagonal per sensor, so this drops exactly their term) plus the
 * prior's column on layer l (α D, or the full prior's coupling of the layer's coefficients). sl: nslopes of
 * work. coarse_ngs's block and the fourier kind's symbol are measured this way. */
void wt_precond__lgs_prior_column(wt_tomography *t, int l, const double *e, double *sl, double *col)
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

/* K v = w in place by the Cholesky factor of K (lower, column-major) */
void wt_precond__lowrank_solve(const wt_precond *p, double *w)
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

WT_CPU_CLONES void wt_precond__yb_update(const wt_precond *p, const double *w, double *z, int64_t b0, int64_t b1)
{
    if (p->nlr == 12 && p->lr_Yb32) yb_update_blocks(12, 1, p, w, z, b0, b1);
    else if (p->nlr == 12) yb_update_blocks(12, 0, p, w, z, b0, b1);
    else if (p->lr_Yb32) yb_update_blocks(p->nlr, 1, p, w, z, b0, b1);
    else yb_update_blocks(p->nlr, 0, p, w, z, b0, b1);
}

double wt_precond__layer_cn2(const wt_tomography *t, int l)
{
    return wt_tomography_layer_fraction(t, l) * pow(wt_tomography_r0(t), -5.0 / 3.0);
}

int wt_precond__parts_begin(wt_precond *p, const wt_tomography *t)
{
    int st = WT_OK;
    const wt_system *sys = wt_tomography_system(t);
    p->parts = 1;
    p->nlgs = sys->nlgs;
    for (int m = 0; m < sys->nlgs; m++) p->part_prec[m] = wt_tomography_lgs_precision(t, m);
    for (int l = 0; l < wt_tomography_nlayers(t); l++) p->part_cn2[l] = wt_precond__layer_cn2(t, l);
    WT_ALLOC(p->ctx, p->part_sl, 2 * (size_t)sys->nslopes, "preconditioner parts' slopes");
fail:
    return st;
}

void wt_precond__part_columns(const wt_precond *p, wt_tomography *t, int l, const double *e, double *cols)
{
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = p->n;
    double *sl = p->part_sl, *slm = sl + sys->nslopes;
    memset(sl, 0, (size_t)sys->nslopes * sizeof *sl);
    wt_tomography_slopes(t, 1.0, e, sl);
    memset(slm, 0, (size_t)sys->nslopes * sizeof *slm);
    for (int m = 0; m < p->nlgs; m++) { /* the adjoint of LGS m's slopes alone (its weight is block-diagonal) */
        const wt_sensor *s = &sys->sensors[m];
        double *c = cols + (size_t)m * n;
        memcpy(slm + s->offset, sl + s->offset, (size_t)s->nslopes * sizeof *slm);
        memset(c, 0, (size_t)n * sizeof *c);
        wt_tomography_rhs(t, 1.0, slm, c);
        memset(slm + s->offset, 0, (size_t)s->nslopes * sizeof *slm);
    }
    double *pc = cols + (size_t)p->nlgs * n;
    memset(pc, 0, (size_t)n * sizeof *pc);
    const int64_t a = wt_tomography_layer_offset(t, l);
    wt_tomography_prior_apply_layer(t, l, e + a, pc + a);
}

