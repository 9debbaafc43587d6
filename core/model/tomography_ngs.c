/* core/model/tomography_ngs.c: the fp32 operator's NGS term (SPEC §6): the NGS's part of M as the explicit matrix
 *
 *   G = [Pᵀ Γᵀ e_k]  over the NGS slopes k,    their slopes Gᵀ φ,   their adjoint G (Ĉ⁻¹ s),
 *
 * in double beside the LGS's float operator (tomography_operator_f32.c); CSR by layer point, made at set-up. */
#include "tomography_private.h"

#include <string.h>

/* The fp32 operator's NGS term. At low noise the NGS weigh ~10⁵ times the LGS, so their part stays double
 * (tomography_operator.c's layers_dwt says why); as the chain Γ P, Ĉ⁻¹, Γᵀ, Pᵀ it was the double work of every apply, its projections scalar (short
 * runs) and their transposes in the layers' stage after a barrier: a tenth of an E-ELT frame. An NGS has
 * few slopes (12 for the E-ELT's three), so its part is the explicit rank-r matrix G = [Pᵀ Γᵀ e_k] (the same
 * linear map; its columns live on the footprints' rims: ~1/8 of the layers' points), applied as Gᵀ φ (slopes) and
 * G w (the weighted slopes onto the layers' sum). Built here column by column with the double adjoint: twice, to
 * count the entries per point and then to fill them in. */
int wt_tomography__ngs_explicit(wt_tomography *t)
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
void wt_tomography__ngs_adjoint(const wt_tomography *t, const double *wv, int64_t i0, int64_t i1, double *sum)
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
void wt_tomography__ngs_forward(const wt_tomography *t, const float *phi32, double *slopes)
{
    for (int m = 0; m < t->S; m++)
        if (!t->s32[m]) memset(slopes + t->sys->sensors[m].offset, 0, (size_t)t->sys->sensors[m].nslopes * sizeof *slopes);
    for (int64_t r = 0; r < t->ngs_nrow; r++) {
        const double x = phi32[t->ngs_row[r]];
        for (int64_t q = t->ngs_ptr[r]; q < t->ngs_ptr[r + 1]; q++) slopes[t->ngs_col[q]] += t->ngs_val[q] * x;
    }
}
