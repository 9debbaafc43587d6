/* core/sim/wfs.c: the simulator's truth Shack–Hartmann sensors — average OPD gradient over the
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

#include "../op/pupil.h"

struct wt_wfs {
    wt_context *ctx;
    int n, p, m;        /* subapertures per side, fine points per subaperture side, big subapertures per side */
    double d;           /* subaperture side [m] */
    wt_grid grid;       /* fine grid (n p + 1)² of spacing d / p */
    int nsub;           /* valid (big) subapertures */
    int32_t *cell;      /* [nsub] index I + m J of valid big subaperture k */
    int32_t *rowptr;    /* [2 nsub + 1] CSR rows: s_x rows, then s_y rows */
    int32_t *col;       /* fine-grid point indices */
    double *val;        /* coefficients [1/m] */
    uint8_t *mask;      /* [(n p + 1)²] points read */
    int64_t npoints;
};

void wt_wfs_free(wt_wfs *w)
{
    if (!w) return;
    wt_context *ctx = w->ctx;
    wt_free(ctx, w->cell);
    wt_free(ctx, w->rowptr);
    wt_free(ctx, w->col);
    wt_free(ctx, w->val);
    wt_free(ctx, w->mask);
    wt_free(ctx, w);
}

/* keeps the fine grid index (n p + 1)² and the coefficient count within int32 */
#define MAX_FINE 16384

/* Illuminated fraction of the fine cell [x0, x0+s] x [y0, y0+s] of the annulus (radii ro, ri). */
static double cell_weight(double D, double obstruction, double ro, double ri, double x0, double y0, double s)
{
    const double x1 = x0 + s, y1 = y0 + s;
    const double nx = x0 > 0.0 ? x0 : (x1 < 0.0 ? x1 : 0.0), ny = y0 > 0.0 ? y0 : (y1 < 0.0 ? y1 : 0.0);
    const double fx = fmax(fabs(x0), fabs(x1)), fy = fmax(fabs(y0), fabs(y1));
    const double dmin2 = nx * nx + ny * ny, dmax2 = fx * fx + fy * fy;
    if (dmin2 >= ro * ro || dmax2 <= ri * ri) return 0.0;
    if (dmax2 <= ro * ro && dmin2 >= ri * ri) return 1.0;
    return wt_pupil_fraction(D, obstruction, x0, y0, s);
}

/* Accumulate the corner coefficients (in units of 1/(2 δf)) of big subaperture (I, J) into ax, ay
 * [(F+1)²] (F fine cells per side, local corner a + (F+1) b); returns Σ w. */
static double accumulate(const double *wcell, int nf, int F, int I, int J, double *ax, double *ay)
{
    const int L = F + 1;
    memset(ax, 0, sizeof *ax * (size_t)L * L);
    memset(ay, 0, sizeof *ay * (size_t)L * L);
    double W = 0.0;
    for (int b = 0; b < F; b++) {
        const double *wrow = wcell + (size_t)nf * (J * F + b) + (size_t)I * F;
        for (int a = 0; a < F; a++) {
            const double w = wrow[a];
            if (w == 0.0) continue;
            const int c = a + L * b;
            /* g_x = [(φ(a+1,b) + φ(a+1,b+1)) − (φ(a,b) + φ(a,b+1))] / (2 δf), g_y likewise */
            ax[c + 1] += w, ax[c + L + 1] += w, ax[c] -= w, ax[c + L] -= w;
            ay[c + L] += w, ay[c + L + 1] += w, ay[c] -= w, ay[c + 1] -= w;
            W += w;
        }
    }
    return W;
}

static int check_args(wt_context *ctx, double D, double obstruction, int n, double d, int p, const uint8_t *valid,
                      int m)
{
    if (!(D > 0.0) || !isfinite(D))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: pupil diameter D = %g m: need a finite D > 0", D);
    if (!(obstruction >= 0.0 && obstruction < 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: central obstruction %g of the diameter: need 0 <= obstruction < 1",
                        obstruction);
    if (n < 1 || n > MAX_FINE)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: n = %d subapertures per side: need 1 <= n <= %d", n, MAX_FINE);
    if (!(d > 0.0) || !(fabs(n * d - D) <= 1e-9 * D))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: subaperture side d = %g m with n = %d: need n d = D = %g m", d, n,
                        D);
    if (p < 1 || p > MAX_FINE / n)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: p = %d fine points per subaperture side: need 1 <= p <= %d "
                        "(n p <= %d)", p, MAX_FINE / n, MAX_FINE);
    if (m < 0 || m > n || (m > 0 && n % m != 0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: m = %d big subapertures per side must divide n = %d (or be 0 for "
                        "the %d x %d sensor itself)", m, n, n, n);
    if (!valid) return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: the valid-subaperture mask is NULL");
    int64_t nvalid = 0;
    for (int64_t k = 0; k < (int64_t)n * n; k++) nvalid += valid[k] != 0;
    if (nvalid == 0) return WT_ERROR(ctx, WT_ERR_INVALID, "wfs: none of the %d x %d subapertures is valid", n, n);
    return WT_OK;
}

int wt_wfs_alloc(wt_context *ctx, double diameter, double obstruction, int n, double d, int p,
                 const uint8_t *valid, int m, wt_wfs **out)
{
    int st = WT_OK;
    wt_wfs *w = NULL;
    double *wcell = NULL, *ax = NULL, *ay = NULL;
    uint8_t *bigvalid = NULL;
    *out = NULL;
    WT_TRY(check_args(ctx, diameter, obstruction, n, d, p, valid, m));
    const int M = m ? m : n, f = n / M; /* big subapertures per side; fine subapertures per big side */
    const int nf = n * p, F = f * p, L = F + 1, ng = nf + 1;
    const double df = d / p;

    WT_ALLOC(ctx, w, 1, "wfs");
    w->ctx = ctx;
    w->n = n;
    w->p = p;
    w->m = M;
    w->d = d;
    w->grid = wt_grid_centred(ng, df);
    WT_ALLOC(ctx, wcell, (size_t)nf * nf, "wfs cell weights (work space)");
    WT_ALLOC(ctx, ax, (size_t)L * L, "wfs coefficients (work space)");
    WT_ALLOC(ctx, ay, (size_t)L * L, "wfs coefficients (work space)");
    WT_ALLOC(ctx, bigvalid, (size_t)M * M, "wfs subaperture mask (work space)");

    /* Cell corners from the grid's own coordinates, so that cell edges are exactly the points the OPD
     * is sampled at. */
    const double ro = 0.5 * diameter, ri = 0.5 * obstruction * diameter;
    for (int b = 0; b < nf; b++)
        for (int a = 0; a < nf; a++)
            wcell[a + (size_t)nf * b] =
                cell_weight(diameter, obstruction, ro, ri, w->grid.x0 + a * df, w->grid.y0 + b * df, df);

    int nsub = 0;
    for (int J = 0; J < M; J++)
        for (int I = 0; I < M; I++) {
            int any = 0;
            for (int j = J * f; j < (J + 1) * f && !any; j++)
                for (int i = I * f; i < (I + 1) * f && !any; i++) any = valid[i + (size_t)n * j] != 0;
            bigvalid[I + M * J] = (uint8_t)any;
            nsub += any;
        }
    w->nsub = nsub;
    WT_ALLOC(ctx, w->cell, nsub, "wfs subaperture list");
    WT_ALLOC(ctx, w->rowptr, 2 * (size_t)nsub + 1, "wfs rows");
    WT_ALLOC(ctx, w->mask, (size_t)ng * ng, "wfs fine mask");

    /* pass 1: row lengths (and the illumination check); pass 2: fill */
    int64_t nnz_x = 0, nnz_y = 0;
    int k = 0;
    for (int J = 0; J < M; J++)
        for (int I = 0; I < M; I++) {
            if (!bigvalid[I + M * J]) continue;
            const double W = accumulate(wcell, nf, F, I, J, ax, ay);
            if (!(W > 0.0)) {
                st = WT_ERROR(ctx, WT_ERR_INVALID, "wfs: subaperture (%d, %d) of the %d x %d sensor is valid but "
                              "not illuminated (obstruction %g, D = %g m)", I, J, M, M, obstruction, diameter);
                goto fail;
            }
            int cx = 0, cy = 0;
            for (int q = 0; q < L * L; q++) cx += ax[q] != 0.0, cy += ay[q] != 0.0;
            w->rowptr[k + 1] = cx;
            w->rowptr[nsub + k + 1] = cy;
            nnz_x += cx, nnz_y += cy;
            w->cell[k++] = I + M * J;
        }
    if (nnz_x + nnz_y > INT32_MAX) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "wfs: %lld coefficients exceed the int32 index range (n = %d, p = %d)",
                      (long long)(nnz_x + nnz_y), n, p);
        goto fail;
    }
    for (int r = 0; r < 2 * nsub; r++) w->rowptr[r + 1] += w->rowptr[r];
    WT_ALLOC(ctx, w->col, nnz_x + nnz_y, "wfs coefficient indices");
    WT_ALLOC(ctx, w->val, nnz_x + nnz_y, "wfs coefficients");
    for (k = 0; k < nsub; k++) {
        const int I = w->cell[k] % M, J = w->cell[k] / M;
        const double W = accumulate(wcell, nf, F, I, J, ax, ay);
        const double scale = 1.0 / (2.0 * df * W);
        int32_t qx = w->rowptr[k], qy = w->rowptr[nsub + k];
        for (int b = 0; b < L; b++)
            for (int a = 0; a < L; a++) {
                const int q = a + L * b;
                const int32_t g = (I * F + a) + ng * (J * F + b);
                if (ax[q] != 0.0) {
                    w->col[qx] = g;
                    w->val[qx++] = ax[q] * scale;
                    w->mask[g] = 1;
                }
                if (ay[q] != 0.0) {
                    w->col[qy] = g;
                    w->val[qy++] = ay[q] * scale;
                    w->mask[g] = 1;
                }
            }
    }
    for (int64_t q = 0; q < (int64_t)ng * ng; q++) w->npoints += w->mask[q];
    wt_free(ctx, wcell);
    wt_free(ctx, ax);
    wt_free(ctx, ay);
    wt_free(ctx, bigvalid);
    *out = w;
    return WT_OK;
fail:
    wt_free(ctx, wcell);
    wt_free(ctx, ax);
    wt_free(ctx, ay);
    wt_free(ctx, bigvalid);
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
    return sizeof *w + (size_t)w->nsub * sizeof *w->cell + (2 * (size_t)w->nsub + 1) * sizeof *w->rowptr +
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
