/* core/op/shack_hartmann.c: the Shack–Hartmann model Γ in Fried geometry and the averaged low-order
 * sensors built on it, with adjoints and assembly.
 *
 * SPEC §4 and the paper's eq. SH_op: on the (n+1) x (n+1) corner grid of spacing d,
 *   s_x(i,j) = [(φ(i+1,j) + φ(i+1,j+1)) − (φ(i,j) + φ(i,j+1))] / (2d), s_y likewise.
 * The NGS 2x2 and 1x1 sensors (SPEC §4) average the Fried slopes of the valid fine cells inside each
 * big subaperture. That average is a fixed linear combination of corner values, so it is precomputed
 * at alloc as a small CSR matrix: apply stays const, thread-safe and allocation-free, and the interior
 * corners whose contributions telescope away (they are +1 for one cell and −1 for its neighbour) drop
 * out exactly, because coefficients are accumulated as integer counts before scaling.
 *
 * The corner mask reports the corners with a nonzero coefficient in Γ — the phase points the slopes
 * actually read. For the Fried sensor that is every corner of a valid subaperture; for an averaged
 * sensor it is mostly the rim of the illuminated region of each big subaperture.
 *
 * The Fried sensor stores its valid cells as runs along rows, so apply reads two contiguous corner
 * rows per run and apply_t writes each corner once (gather form): for n = 84 they take 2.4 and 3.1 µs
 * against 5.9 and 33 µs for a per-cell gather/scatter, whose scatter chains through store forwarding.
 */
#include "shack_hartmann.h"

#include <math.h>
#include <stdint.h>

struct wt_shack_hartmann {
    wt_context *ctx;
    int n;          /* fine subapertures per side; corner grid (n+1) x (n+1) */
    double d;       /* fine subaperture side [m] */
    int m;          /* big subapertures per side (averaged sensor); 0 for the plain Fried sensor */
    int nsub;       /* valid (big) subapertures */
    int32_t *cell;  /* [nsub] index i + side*j of valid subaperture k, side = n (Fried) or m */
    int32_t nrun;    /* Fried: runs of consecutive valid subapertures within a row */
    int32_t *run_corner, *run_len, *run_k; /* [nrun] lower-left corner of the first cell, cells, first k */
    int32_t *rowptr; /* averaged: [2 nsub + 1] CSR rows (s_x rows, then s_y rows) */
    int32_t *colind; /* averaged: corner-grid indices */
    double *val;     /* averaged: coefficients [1/m] */
    uint8_t *corner_mask; /* [(n+1)^2] corners with a nonzero coefficient */
};

void wt_shack_hartmann_free(wt_shack_hartmann *s)
{
    if (!s) return;
    wt_context *ctx = s->ctx;
    wt_free(ctx, s->cell);
    wt_free(ctx, s->run_corner);
    wt_free(ctx, s->run_len);
    wt_free(ctx, s->run_k);
    wt_free(ctx, s->rowptr);
    wt_free(ctx, s->colind);
    wt_free(ctx, s->val);
    wt_free(ctx, s->corner_mask);
    wt_free(ctx, s);
}

/* keeps (n+1)^2 and the averaged sensor's 2 (n+m)^2 CSR entries within int32 */
#define MAX_N 4096

static int check_common(wt_context *ctx, int n, double d, const uint8_t *valid)
{
    if (n < 1 || n > MAX_N || !(d > 0.0) || !isfinite(d) || !valid)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann: n = %d subapertures per side, side d = %g m: need "
                        "1 <= n <= %d, a finite d > 0 and a non-NULL valid mask", n, d, MAX_N);
    int64_t nvalid = 0;
    for (int64_t k = 0; k < (int64_t)n * n; k++) nvalid += valid[k] != 0;
    if (nvalid == 0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann: none of the %d x %d subapertures is valid", n, n);
    return WT_OK;
}

int wt_shack_hartmann_alloc(wt_context *ctx, int n, double d, const uint8_t *valid, wt_shack_hartmann **out)
{
    int st = WT_OK;
    wt_shack_hartmann *s = NULL;
    *out = NULL;
    WT_TRY(check_common(ctx, n, d, valid));
    const int nc = n + 1;
    int nsub = 0;
    for (int k = 0; k < n * n; k++) nsub += valid[k] != 0;
    WT_ALLOC(ctx, s, 1, "shack_hartmann");
    s->ctx = ctx;
    s->n = n;
    s->d = d;
    s->m = 0;
    s->nsub = nsub;
    int nrun = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) nrun += valid[i + n * j] && (i == 0 || !valid[i - 1 + n * j]);
    s->nrun = nrun;
    WT_ALLOC(ctx, s->cell, nsub, "shack_hartmann subaperture list");
    WT_ALLOC(ctx, s->run_corner, nrun, "shack_hartmann runs");
    WT_ALLOC(ctx, s->run_len, nrun, "shack_hartmann runs");
    WT_ALLOC(ctx, s->run_k, nrun, "shack_hartmann runs");
    WT_ALLOC(ctx, s->corner_mask, (size_t)nc * nc, "shack_hartmann corner mask");
    int k = 0, r = -1;
    for (int j = 0; j < n; j++) {
        for (int i = 0; i < n; i++) {
            if (!valid[i + n * j]) continue;
            int c = i + nc * j;
            if (i == 0 || !valid[i - 1 + n * j]) {
                r++;
                s->run_corner[r] = c;
                s->run_k[r] = k;
            }
            s->run_len[r]++;
            s->cell[k] = i + n * j;
            s->corner_mask[c] = s->corner_mask[c + 1] = s->corner_mask[c + nc] = s->corner_mask[c + nc + 1] = 1;
            k++;
        }
    }
    *out = s;
    return WT_OK;
fail:
    wt_shack_hartmann_free(s);
    return st;
}

int wt_shack_hartmann_alloc_averaged(wt_context *ctx, int n, double d, const uint8_t *valid, int m,
                                     wt_shack_hartmann **out)
{
    int st = WT_OK;
    wt_shack_hartmann *s = NULL;
    int *cx = NULL, *cy = NULL;
    *out = NULL;
    WT_TRY(check_common(ctx, n, d, valid));
    if (m < 1 || n % m != 0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann: %d x %d big subapertures must tile the %d x %d fine "
                        "cells (need m >= 1 dividing n)", m, m, n, n);
    const int nc = n + 1, f = n / m, fc = f + 1; /* fine cells per big side; local corners per side */
    int nsub = 0;
    for (int J = 0; J < m; J++)
        for (int I = 0; I < m; I++) {
            int any = 0;
            for (int b = 0; b < f && !any; b++)
                for (int a = 0; a < f && !any; a++) any = valid[(I * f + a) + n * (J * f + b)] != 0;
            nsub += any;
        }
    WT_ALLOC(ctx, s, 1, "shack_hartmann");
    s->ctx = ctx;
    s->n = n;
    s->d = d;
    s->m = m;
    s->nsub = nsub;
    /* each row has at most (f+1)^2 entries */
    const size_t cap = (size_t)nsub * fc * fc;
    WT_ALLOC(ctx, s->cell, nsub, "shack_hartmann subaperture list");
    WT_ALLOC(ctx, s->rowptr, 2 * (size_t)nsub + 1, "shack_hartmann rows");
    WT_ALLOC(ctx, s->colind, 2 * cap, "shack_hartmann columns");
    WT_ALLOC(ctx, s->val, 2 * cap, "shack_hartmann coefficients");
    WT_ALLOC(ctx, s->corner_mask, (size_t)nc * nc, "shack_hartmann corner mask");
    WT_ALLOC(ctx, cx, (size_t)fc * fc, "shack_hartmann scratch");
    WT_ALLOC(ctx, cy, (size_t)fc * fc, "shack_hartmann scratch");

    /* x rows fill [0, cap), y rows fill [cap, 2 cap) and are moved behind the x rows at the end */
    int64_t nx_nz = 0, ny_nz = 0;
    int32_t *ycol = s->colind + cap;
    double *yval = s->val + cap;
    int k = 0;
    for (int J = 0; J < m; J++) {
        for (int I = 0; I < m; I++) {
            int nv = 0;
            for (int q = 0; q < fc * fc; q++) cx[q] = cy[q] = 0;
            for (int b = 0; b < f; b++) {
                for (int a = 0; a < f; a++) {
                    if (!valid[(I * f + a) + n * (J * f + b)]) continue;
                    nv++;
                    int c = a + fc * b;
                    cx[c + 1]++, cx[c + fc + 1]++, cx[c]--, cx[c + fc]--;
                    cy[c + fc]++, cy[c + fc + 1]++, cy[c]--, cy[c + 1]--;
                }
            }
            if (nv == 0) continue;
            const double scale = 1.0 / (2.0 * d * nv); /* mean over nv cells of (Σ ± φ) / (2d) */
            s->cell[k] = I + m * J;
            s->rowptr[k] = (int32_t)nx_nz;
            s->rowptr[nsub + k] = (int32_t)ny_nz;
            for (int b = 0; b < fc; b++) {
                for (int a = 0; a < fc; a++) {
                    int q = a + fc * b;
                    int32_t col = (I * f + a) + nc * (J * f + b);
                    if (cx[q]) {
                        s->colind[nx_nz] = col;
                        s->val[nx_nz++] = cx[q] * scale;
                        s->corner_mask[col] = 1;
                    }
                    if (cy[q]) {
                        ycol[ny_nz] = col;
                        yval[ny_nz++] = cy[q] * scale;
                        s->corner_mask[col] = 1;
                    }
                }
            }
            k++;
        }
    }
    /* shift the y block down behind the x block */
    for (int64_t q = 0; q < ny_nz; q++) {
        s->colind[nx_nz + q] = ycol[q];
        s->val[nx_nz + q] = yval[q];
    }
    for (int q = 0; q < nsub; q++) s->rowptr[nsub + q] += (int32_t)nx_nz;
    s->rowptr[2 * nsub] = (int32_t)(nx_nz + ny_nz);
    wt_free(ctx, cx);
    wt_free(ctx, cy);
    *out = s;
    return WT_OK;
fail:
    wt_free(ctx, cx);
    wt_free(ctx, cy);
    wt_shack_hartmann_free(s);
    return st;
}

int wt_shack_hartmann_nsub(const wt_shack_hartmann *s) { return s->nsub; }
int wt_shack_hartmann_nslopes(const wt_shack_hartmann *s) { return 2 * s->nsub; }
int wt_shack_hartmann_ncorners(const wt_shack_hartmann *s) { return (s->n + 1) * (s->n + 1); }
const uint8_t *wt_shack_hartmann_corner_mask(const wt_shack_hartmann *s) { return s->corner_mask; }

void wt_shack_hartmann_centre(const wt_shack_hartmann *s, int k, double *x, double *y)
{
    if (k < 0 || k >= s->nsub) {
        *x = *y = NAN;
        return;
    }
    const int side = s->m ? s->m : s->n;
    const double w = s->d * s->n / side; /* (big) subaperture side [m] */
    const int i = s->cell[k] % side, j = s->cell[k] / side;
    *x = -0.5 * s->n * s->d + (i + 0.5) * w;
    *y = -0.5 * s->n * s->d + (j + 0.5) * w;
}

void wt_shack_hartmann_apply(const wt_shack_hartmann *s, double alpha, const double *restrict phase,
                             double *restrict slopes)
{
    const int nsub = s->nsub;
    if (s->m == 0) {
        /* a run of valid cells reads two contiguous corner rows: b (bottom) and t (top) */
        const int nc = s->n + 1;
        const double a = alpha / (2.0 * s->d);
        for (int32_t r = 0; r < s->nrun; r++) {
            const double *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
            double *restrict sx = slopes + s->run_k[r], *restrict sy = sx + nsub;
            const int len = s->run_len[r];
            for (int i = 0; i < len; i++) {
                const double d1 = t[i + 1] - b[i], d2 = b[i + 1] - t[i]; /* the two diagonals */
                sx[i] += a * (d1 + d2);
                sy[i] += a * (d1 - d2);
            }
        }
        return;
    }
    for (int r = 0; r < 2 * nsub; r++) {
        double acc = 0.0;
        for (int32_t q = s->rowptr[r]; q < s->rowptr[r + 1]; q++) acc += s->val[q] * phase[s->colind[q]];
        slopes[r] += alpha * acc;
    }
}

void wt_shack_hartmann_apply_t(const wt_shack_hartmann *s, double alpha, const double *restrict slopes,
                               double *restrict phase)
{
    const int nsub = s->nsub;
    if (s->m == 0) {
        /* Gather form: corner i of a run's bottom row takes −(s_x + s_y) from the cell to its right and
         * (s_x − s_y) from the cell to its left; the top row (s_y − s_x) and (s_x + s_y). Writing each
         * corner once (instead of scattering every cell to its four corners) avoids chaining each
         * update through the previous cell's store and lets the loop vectorise. */
        const int nc = s->n + 1;
        const double a = alpha / (2.0 * s->d);
        for (int32_t r = 0; r < s->nrun; r++) {
            double *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
            const double *restrict sx = slopes + s->run_k[r], *restrict sy = sx + nsub;
            const int len = s->run_len[r];
            b[0] -= a * (sx[0] + sy[0]);
            t[0] += a * (sy[0] - sx[0]);
            for (int i = 1; i < len; i++) {
                b[i] += a * ((sx[i - 1] - sy[i - 1]) - (sx[i] + sy[i]));
                t[i] += a * ((sx[i - 1] + sy[i - 1]) + (sy[i] - sx[i]));
            }
            b[len] += a * (sx[len - 1] - sy[len - 1]);
            t[len] += a * (sx[len - 1] + sy[len - 1]);
        }
        return;
    }
    for (int r = 0; r < 2 * nsub; r++) {
        const double t = alpha * slopes[r];
        for (int32_t q = s->rowptr[r]; q < s->rowptr[r + 1]; q++) phase[s->colind[q]] += s->val[q] * t;
    }
}

int wt_shack_hartmann_assemble(const wt_shack_hartmann *s, wt_sparse **out)
{
    int st = WT_OK;
    wt_triplet *t = NULL;
    *out = NULL;
    const int nsub = s->nsub, nc = s->n + 1;
    const int64_t nnz = s->m ? s->rowptr[2 * nsub] : 8 * (int64_t)nsub;
    WT_TRY(wt_triplet_alloc(s->ctx, 2 * (int64_t)nsub, (int64_t)nc * nc, nnz, &t));
    if (s->m == 0) {
        const double a = 1.0 / (2.0 * s->d);
        for (int k = 0; k < nsub; k++) {
            const int64_t c = s->cell[k] + s->cell[k] / s->n; /* i + (n+1) j */
            WT_TRY(wt_triplet_add(t, k, c, -a));
            WT_TRY(wt_triplet_add(t, k, c + nc, -a));
            WT_TRY(wt_triplet_add(t, k, c + 1, a));
            WT_TRY(wt_triplet_add(t, k, c + nc + 1, a));
            WT_TRY(wt_triplet_add(t, nsub + k, c, -a));
            WT_TRY(wt_triplet_add(t, nsub + k, c + 1, -a));
            WT_TRY(wt_triplet_add(t, nsub + k, c + nc, a));
            WT_TRY(wt_triplet_add(t, nsub + k, c + nc + 1, a));
        }
    } else {
        for (int r = 0; r < 2 * nsub; r++)
            for (int32_t q = s->rowptr[r]; q < s->rowptr[r + 1]; q++) WT_TRY(wt_triplet_add(t, r, s->colind[q], s->val[q]));
    }
    WT_TRY(wt_triplet_compress(t, out));
fail:
    wt_triplet_free(t);
    return st;
}
