/* sim/wfs.c: the simulator's truth Shack–Hartmann sensors — average OPD gradient over the
 * illuminated part of each subaperture on the fine simulation grid (SPEC §4 "Truth").
 *
 * s = Σ_c w_c g_c / Σ_c w_c over the fine cells c of a (big) subaperture, g_c the Fried gradient of
 * cell c (its 4 corners) and w_c its illuminated fraction. That is linear in the OPD, so alloc
 * accumulates, per slope, the coefficient of every fine corner (±w_c / (2 δf W) from each cell the
 * corner belongs to) and keeps the nonzero ones as a CSR row; measure is then one sparse gather-dot
 * per slope.
 *
 * Why it is small: a corner shared by fully lit cells gets +1 from the cells on one side and −1 from
 * the other, so inside a lit region the coefficients cancel — exactly, since full cells have w = 1
 * exactly (classified geometrically, below) and integer sums are exact in floating point. What is
 * left is the trapezoid rule of the divergence theorem, ∫_S ∇φ = ∮_∂S φ n: a fully lit LGS
 * subaperture reads only the 4p points of its own boundary (2(p+1) per axis), and the 1x1 NGS sensor
 * only the rim of the pupil. Hence the fine mask: the simulator skips the OPD at the other points
 * (for p = 4 about 9/16 of the interior of the pupil for an LGS sensor, nearly all of it for an NGS).
 *
 * Weights: a cell entirely inside the annulus gets w = 1, entirely outside 0 (decided from its nearest
 * and farthest points to the centre); only cells the rim crosses call wt_pupil_fraction, whose
 * closed form carries an absolute rounding error ~1e-11 for a cell of (0.125 m)² at R = 21 m (it
 * subtracts areas ~R²): harmless as a weight, but it would stop full cells from cancelling.
 * Coefficients are dropped only when exactly zero, so a tilt gives its slope to rounding whatever
 * the weights.
 */
#include "wfs.h"

#include <math.h>
#include <string.h>

#include "../core/op/pupil.h"
#include "../core/op/shack_hartmann.h"

struct wt_wfs {
    wt_context *ctx;
    int n, p, m;        /* subapertures per side, fine points per subaperture side, big subapertures per side */
    double d;           /* subaperture side [m] */
    wt_grid grid;       /* fine grid (n p + 1)² of spacing d / p */
    int nsub;           /* valid (big) subapertures */
    wt_shack_hartmann *sh; /* the lit-area average sensor on the fine grid (q = p); the arrays below are its */
    const int32_t *rowptr; /* [2 nsub + 1] CSR rows: s_x rows, then s_y rows */
    const int32_t *col;    /* fine-grid point indices */
    const double *val;     /* coefficients [1/m] */
    const uint8_t *mask;   /* [(n p + 1)²] points read */
    int64_t npoints;
};

void wt_wfs_free(wt_wfs *w)
{
    if (!w) return;
    wt_shack_hartmann_free(w->sh);
    wt_free(w->ctx, w);
}

int wt_wfs_alloc(wt_context *ctx, double diameter, double obstruction, int n, double d, int p,
                 const uint8_t *valid, int m, int tilt, wt_wfs **out)
{
    int st = WT_OK;
    wt_wfs *w = NULL;
    *out = NULL;
    WT_ALLOC(ctx, w, 1, "wfs");
    w->ctx = ctx;
    w->n = n;
    w->p = p;
    w->d = d;
    st = wt_shack_hartmann_alloc_lit(ctx, diameter, obstruction, n, d, p, valid, m, tilt, &w->sh);
    if (st < 0) {
        st = WT_ERROR(ctx, st, "wfs: %s", wt_error_message(ctx));
        goto fail;
    }
    w->m = m ? m : n;
    w->grid = wt_grid_centred(n * p + 1, d / p);
    w->nsub = wt_shack_hartmann_nsub(w->sh);
    wt_shack_hartmann_csr(w->sh, &w->rowptr, &w->col, &w->val);
    w->mask = wt_shack_hartmann_corner_mask(w->sh);
    for (int64_t q = 0; q < wt_grid_size(&w->grid); q++) w->npoints += w->mask[q];
    *out = w;
    return WT_OK;
fail:
    wt_wfs_free(w);
    return st;
}

wt_grid wt_wfs_grid(const wt_wfs *w) { return w->grid; }
const uint8_t *wt_wfs_fine_mask(const wt_wfs *w) { return w->mask; }
int64_t wt_wfs_npoints(const wt_wfs *w) { return w->npoints; }
int wt_wfs_nsub(const wt_wfs *w) { return w->nsub; }
int wt_wfs_nslopes(const wt_wfs *w) { return 2 * w->nsub; }
int64_t wt_wfs_nnz(const wt_wfs *w) { return w->rowptr[2 * w->nsub]; }

size_t wt_wfs_bytes(const wt_wfs *w)
{
    const size_t nnz = (size_t)w->rowptr[2 * w->nsub];
    return sizeof *w + (size_t)w->nsub * sizeof(int32_t) + (2 * (size_t)w->nsub + 1) * sizeof *w->rowptr +
           nnz * (sizeof *w->col + sizeof *w->val) + (size_t)wt_grid_size(&w->grid);
}

void wt_wfs_measure(const wt_wfs *w, const double *restrict opd, double *restrict slopes)
{
    const int32_t *restrict rowptr = w->rowptr, *restrict col = w->col;
    const double *restrict val = w->val;
    const int nr = 2 * w->nsub;
    for (int r = 0; r < nr; r++) {
        /* Σ val = 0 (each cell adds +w and −w twice), so Σ val φ = Σ val (φ − φ_first): a piston drops
         * out exactly (a flat OPD gives exact zeros) and the sum cancels less. */
        const int32_t q0 = rowptr[r], q1 = rowptr[r + 1];
        const double ref = opd[col[q0]];
        double acc = 0.0;
        for (int32_t q = q0 + 1; q < q1; q++) acc += val[q] * (opd[col[q]] - ref);
        slopes[r] = acc;
    }
}

int wt_wfs_add_tiptilt(const wt_wfs *w, wt_rng *rng, double rms, double *slopes)
{
    if (!(rms >= 0.0) || !isfinite(rms))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "wfs: LGS tip-tilt rms = %g rad: need a finite rms >= 0", rms);
    const double tx = rms * wt_rng_normal(rng);
    const double ty = rms * wt_rng_normal(rng);
    const int nsub = w->nsub;
    for (int k = 0; k < nsub; k++) {
        slopes[k] += tx;
        slopes[nsub + k] += ty;
    }
    return WT_OK;
}
