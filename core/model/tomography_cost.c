/* core/model/tomography_cost.c: what the tomography costs (SPEC §6; docs/benchmarks.md): the bytes it holds, the
 * flops and bytes of one apply of M (DWT 16 N per coefficient and level, the projections' 16 flops per corner
 * point, layer and sensor, the prior's FFTs), and the non-zeros of the sparse Γ_m P_m and Ã_m = Γ_m P_m W⁻¹ that
 * the matrix-free operator never stores. Estimates for reports: nothing here runs in a frame. */
#include "tomography_private.h"

#include <math.h>
#include <string.h>

#include "../la/sparse.h"
#include "../la/vec.h"
#include "../op/projection.h"
#include "../op/shack_hartmann.h"
#include "../op/wavelet.h"

double wt_tomography_bytes(const wt_tomography *t)
{
    /* vectors of n: α D, φ, b, the group accumulators, the 4 PCG vectors and its 2 right-hand sides (the
     * preconditioner's are wt_precond_bytes) */
    double b = 8.0 * (double)t->n * (4.0 + (t->fp32 ? 0.0 : 2.0) + 6.0);
    b += 8.0 * (double)t->S * (double)t->ncg + 16.0 * (double)t->sys->nslopes + 8.0 * t->nthreads * (double)t->wsize;
    if (t->fp32) /* the float layers, group accumulators, phases, slopes, layer sums and wavelet work */
        b += 4.0 * ((1.0 + WT_GROUPS) * (double)t->n + (double)t->S * (double)t->ncg + 2.0 * (double)t->sys->nslopes +
                    (double)t->nthreads * ((double)wt_tomography__max_layer(t) + (double)t->wsize));
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
