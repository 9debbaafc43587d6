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
 * rows per run and apply_t writes each corner once (gather form), several times faster than a per-cell
 * gather/scatter, whose scatter chains each update through store forwarding.
 *
 * The fp32 forms (the tomography's single-precision operator) run the same three paths on float copies
 * of the coefficients, rounded once at alloc so that the applies convert nothing and stay const; their
 * run kernels take the Fried form (two diagonals per cell, the transpose as a gather) for the lit cells
 * too, since they need not reproduce the CSR's operation order. They have twice the lanes of the double
 * ones, but on the E-ELT pupil's runs (~47 cells) the per-run vector tails keep the gain nearer 1.5.
 */
#include "shack_hartmann.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "pupil.h"

struct wt_shack_hartmann {
    wt_context *ctx;
    int n;          /* fine subapertures per side; corner grid (n+1) x (n+1) */
    double d;       /* fine subaperture side [m] */
    int m;          /* big subapertures per side (averaged and lit sensors); 0 for the plain Fried sensor */
    int q;          /* sample points per subaperture side: the corner grid is (n q + 1)² of spacing d/q */
    int lit;        /* 1: lit-area average sensor (wt_shack_hartmann_alloc_lit) */
    int nsub;       /* valid (big) subapertures */
    int32_t *cell;  /* [nsub] index i + side*j of valid subaperture k, side = n (Fried) or m */
    int32_t nrun;    /* Fried: runs of consecutive valid subapertures within a row */
    int32_t *run_corner, *run_len, *run_k; /* [nrun] lower-left corner of the first cell, cells, first k */
    int32_t *rowptr; /* averaged: [2 nsub + 1] CSR rows (s_x rows, then s_y rows) */
    int32_t *colind; /* averaged: corner-grid indices */
    double *val;     /* averaged: coefficients [1/m] */
    double *quad_u;  /* lit with q = 1 and m = n: [nsub] u_k, every row k being ±u_k at the cell's 4 corners
                        (see quad_setup); its valid cells are the runs run_* above. NULL otherwise. */
    float *val32;    /* the fp32 forms': val rounded to float (averaged and lit sensors without quad_u); else NULL */
    float *quad_u32; /* the fp32 forms': quad_u rounded to float; NULL without quad_u */
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
    wt_free(ctx, s->quad_u);
    wt_free(ctx, s->val32);
    wt_free(ctx, s->quad_u32);
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

/* The fp32 forms' coefficients of an averaged or lit sensor (the Fried sensor has only 1/(2d)): quad_u's
 * when its run kernels apply, else the CSR values. Called last by the allocs, once val and quad_u are final. */
static int f32_setup(wt_shack_hartmann *s)
{
    int st = WT_OK;
    if (s->quad_u) {
        WT_ALLOC(s->ctx, s->quad_u32, s->nsub, "shack_hartmann fp32 coefficients");
        for (int k = 0; k < s->nsub; k++) s->quad_u32[k] = (float)s->quad_u[k];
    } else {
        const int32_t nnz = s->rowptr[2 * s->nsub];
        WT_ALLOC(s->ctx, s->val32, nnz, "shack_hartmann fp32 coefficients");
        for (int32_t q = 0; q < nnz; q++) s->val32[q] = (float)s->val[q];
    }
    return WT_OK;
fail:
    return st;
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
    s->q = 1;
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
    s->q = 1;
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
    WT_TRY(f32_setup(s));
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

/* the lit sensor: keeps the sample grid index (n q + 1)² and the coefficient count within int32 */
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

static int check_lit_args(wt_context *ctx, double D, double obstruction, int n, double d, int p, const uint8_t *valid,
                      int m)
{
    if (!(D > 0.0) || !isfinite(D))
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): pupil diameter D = %g m: need a finite D > 0", D);
    if (!(obstruction >= 0.0 && obstruction < 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): central obstruction %g of the diameter: need 0 <= obstruction < 1",
                        obstruction);
    if (n < 1 || n > MAX_FINE)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): n = %d subapertures per side: need 1 <= n <= %d", n, MAX_FINE);
    if (!(d > 0.0) || !(fabs(n * d - D) <= 1e-9 * D))
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): subaperture side d = %g m with n = %d: need n d = D = %g m", d, n,
                        D);
    if (p < 1 || p > MAX_FINE / n)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): p = %d fine points per subaperture side: need 1 <= p <= %d "
                        "(n p <= %d)", p, MAX_FINE / n, MAX_FINE);
    if (m < 0 || m > n || (m > 0 && n % m != 0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): m = %d big subapertures per side must divide n = %d (or be 0 for "
                        "the %d x %d sensor itself)", m, n, n, n);
    if (!valid) return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): the valid-subaperture mask is NULL");
    int64_t nvalid = 0;
    for (int64_t k = 0; k < (int64_t)n * n; k++) nvalid += valid[k] != 0;
    if (nvalid == 0) return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): none of the %d x %d subapertures is valid", n, n);
    return WT_OK;
}

/* The lit sensor with one sample cell per subaperture (q = 1, m = n: the reconstructor's model): each row
 * has the 4 corners of its cell, in CSR order (0,0), (1,0), (0,1), (1,1), with the values
 * x: (−u, u, −u, u), y: (−u, −u, u, u), u = w / (2 δ w) rounded once (the corner coefficients are ±w
 * exactly, then scaled). Stored as u per cell and runs of cells along grid rows, the applies read
 * contiguous corner rows and vectorise, in exactly the CSR's floating-point operations (below); the
 * general CSR loops take 1.8 cycles per coefficient (gathers; the transpose scatters through store
 * forwarding). A sensor whose rows do not all have that form keeps the CSR path. */
static int quad_setup(wt_shack_hartmann *s)
{
    wt_context *ctx = s->ctx;
    const int n = s->n, nsub = s->nsub, ng = n + 1;
    if (s->q != 1 || s->m != n) return WT_OK;
    for (int k = 0; k < nsub; k++) {
        const int32_t c = s->cell[k] % n + ng * (s->cell[k] / n), cols[4] = {c, c + 1, c + ng, c + ng + 1};
        const int32_t qx = s->rowptr[k], qy = s->rowptr[nsub + k];
        if (s->rowptr[k + 1] - qx != 4 || s->rowptr[nsub + k + 1] - qy != 4) return WT_OK;
        const double u = s->val[qx + 1];
        const double vx[4] = {-u, u, -u, u}, vy[4] = {-u, -u, u, u};
        for (int e = 0; e < 4; e++)
            if (s->colind[qx + e] != cols[e] || s->colind[qy + e] != cols[e] || memcmp(&s->val[qx + e], &vx[e], sizeof u) ||
                memcmp(&s->val[qy + e], &vy[e], sizeof u))
                return WT_OK;
    }
    int st = WT_OK, nrun = 0;
    for (int k = 0; k < nsub; k++) nrun += k == 0 || s->cell[k] != s->cell[k - 1] + 1 || s->cell[k] % n == 0;
    WT_ALLOC(ctx, s->quad_u, nsub, "shack_hartmann (lit) coefficients");
    WT_ALLOC(ctx, s->run_corner, nrun, "shack_hartmann (lit) runs");
    WT_ALLOC(ctx, s->run_len, nrun, "shack_hartmann (lit) runs");
    WT_ALLOC(ctx, s->run_k, nrun, "shack_hartmann (lit) runs");
    for (int k = 0, r = -1; k < nsub; k++) {
        s->quad_u[k] = s->val[s->rowptr[k] + 1];
        if (k == 0 || s->cell[k] != s->cell[k - 1] + 1 || s->cell[k] % n == 0) {
            r++;
            s->run_corner[r] = s->cell[k] % n + ng * (s->cell[k] / n);
            s->run_k[r] = k;
            s->run_len[r] = 0;
        }
        s->run_len[r]++;
    }
    s->nrun = nrun;
    return WT_OK;
fail:
    wt_free(ctx, s->quad_u);
    s->quad_u = NULL;
    return st;
}

/* Z-tilt rows of big subaperture (I, J) (see the header): ax, ay [(F+1)²] become the plane slopes' corner
 * coefficients in units of 1/(2 δf), as accumulate() gives the G-tilt's; returns Σ w. */
static double accumulate_ztilt(const double *wcell, int nf, int F, int I, int J, double *ax, double *ay)
{
    const int L = F + 1;
    memset(ax, 0, sizeof *ax * (size_t)L * L);
    memset(ay, 0, sizeof *ay * (size_t)L * L);
    double W = 0.0;
    for (int b = 0; b < F; b++) {
        const double *wrow = wcell + (size_t)nf * (J * F + b) + (size_t)I * F;
        for (int a = 0; a < F; a++) {
            const double w = 0.25 * wrow[a];
            const int c = a + L * b;
            ax[c] += w, ax[c + 1] += w, ax[c + L] += w, ax[c + L + 1] += w; /* corner weights, in ax for now */
            W += wrow[a];
        }
    }
    if (!(W > 0.0)) return W;
    /* moments about the subaperture centre, coordinates in units of δf */
    const double h = 0.5 * F;
    double s0 = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
    for (int b = 0; b < L; b++)
        for (int a = 0; a < L; a++) {
            const double w = ax[a + L * b], x = a - h, y = b - h;
            s0 += w, sx += w * x, sy += w * y, sxx += w * x * x, sxy += w * x * y, syy += w * y * y;
        }
    /* rows 2 and 3 of the inverse of the symmetric 3×3 N (cofactors) */
    const double c00 = sxx * syy - sxy * sxy, c01 = -(sx * syy - sxy * sy), c02 = sx * sxy - sxx * sy;
    const double c11 = s0 * syy - sy * sy, c12 = -(s0 * sxy - sx * sy), c22 = s0 * sxx - sx * sx;
    const double det = s0 * c00 + sx * c01 + sy * c02;
    for (int b = 0; b < L; b++)
        for (int a = 0; a < L; a++) {
            const int q = a + L * b;
            const double w = ax[q], x = a - h, y = b - h;
            /* slope per δf, times 2 W: the caller scales by 1 / (2 δf W) */
            ax[q] = 2.0 * W * w * (c01 + c11 * x + c12 * y) / det;
            ay[q] = 2.0 * W * w * (c02 + c12 * x + c22 * y) / det;
        }
    return W;
}

int wt_shack_hartmann_alloc_lit(wt_context *ctx, double diameter, double obstruction, int n, double d, int p,
                                const uint8_t *valid, int m, int tilt, wt_shack_hartmann **out)
{
    int st = WT_OK;
    wt_shack_hartmann *w = NULL;
    double *wcell = NULL, *ax = NULL, *ay = NULL;
    uint8_t *bigvalid = NULL;
    *out = NULL;
    WT_TRY(check_lit_args(ctx, diameter, obstruction, n, d, p, valid, m));
    if (tilt != WT_SH_TILT_G && tilt != WT_SH_TILT_Z)
        return WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): tilt = %d: need WT_SH_TILT_G (0) or WT_SH_TILT_Z (1)", tilt);
    double (*const acc)(const double *, int, int, int, int, double *, double *) =
        tilt == WT_SH_TILT_Z ? accumulate_ztilt : accumulate;
    const int M = m ? m : n, f = n / M; /* big subapertures per side; fine subapertures per big side */
    const int nf = n * p, F = f * p, L = F + 1, ng = nf + 1;
    const double df = d / p;

    WT_ALLOC(ctx, w, 1, "shack_hartmann (lit)");
    w->ctx = ctx;
    w->n = n;
    w->q = p;
    w->m = M;
    w->d = d;
    w->lit = 1;
    const wt_grid grid = wt_grid_centred(ng, df);
    WT_ALLOC(ctx, wcell, (size_t)nf * nf, "sensor cell weights (work space)");
    WT_ALLOC(ctx, ax, (size_t)L * L, "sensor coefficients (work space)");
    WT_ALLOC(ctx, ay, (size_t)L * L, "sensor coefficients (work space)");
    WT_ALLOC(ctx, bigvalid, (size_t)M * M, "sensor subaperture mask (work space)");

    /* Cell corners from the grid's own coordinates, so that cell edges are exactly the points the OPD
     * is sampled at. */
    const double ro = 0.5 * diameter, ri = 0.5 * obstruction * diameter;
    for (int b = 0; b < nf; b++)
        for (int a = 0; a < nf; a++)
            wcell[a + (size_t)nf * b] =
                cell_weight(diameter, obstruction, ro, ri, grid.x0 + a * df, grid.y0 + b * df, df);

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
    WT_ALLOC(ctx, w->cell, nsub, "sensor subaperture list");
    WT_ALLOC(ctx, w->rowptr, 2 * (size_t)nsub + 1, "sensor rows");
    WT_ALLOC(ctx, w->corner_mask, (size_t)ng * ng, "sensor sample mask");

    /* pass 1: row lengths (and the illumination check); pass 2: fill */
    int64_t nnz_x = 0, nnz_y = 0;
    int k = 0;
    for (int J = 0; J < M; J++)
        for (int I = 0; I < M; I++) {
            if (!bigvalid[I + M * J]) continue;
            const double W = acc(wcell, nf, F, I, J, ax, ay);
            if (!(W > 0.0)) {
                st = WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): subaperture (%d, %d) of the %d x %d sensor is valid but "
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
        st = WT_ERROR(ctx, WT_ERR_INVALID, "shack_hartmann (lit): %lld coefficients exceed the int32 index range (n = %d, p = %d)",
                      (long long)(nnz_x + nnz_y), n, p);
        goto fail;
    }
    for (int r = 0; r < 2 * nsub; r++) w->rowptr[r + 1] += w->rowptr[r];
    WT_ALLOC(ctx, w->colind, nnz_x + nnz_y, "sensor coefficient indices");
    WT_ALLOC(ctx, w->val, nnz_x + nnz_y, "sensor coefficients");
    for (k = 0; k < nsub; k++) {
        const int I = w->cell[k] % M, J = w->cell[k] / M;
        const double W = acc(wcell, nf, F, I, J, ax, ay);
        const double scale = 1.0 / (2.0 * df * W);
        int32_t qx = w->rowptr[k], qy = w->rowptr[nsub + k];
        for (int b = 0; b < L; b++)
            for (int a = 0; a < L; a++) {
                const int q = a + L * b;
                const int32_t g = (I * F + a) + ng * (J * F + b);
                if (ax[q] != 0.0) {
                    w->colind[qx] = g;
                    w->val[qx++] = ax[q] * scale;
                    w->corner_mask[g] = 1;
                }
                if (ay[q] != 0.0) {
                    w->colind[qy] = g;
                    w->val[qy++] = ay[q] * scale;
                    w->corner_mask[g] = 1;
                }
            }
    }
    WT_TRY(quad_setup(w));
    WT_TRY(f32_setup(w));
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
    wt_shack_hartmann_free(w);
    return st;
}

int wt_shack_hartmann_nsub(const wt_shack_hartmann *s) { return s->nsub; }
int wt_shack_hartmann_nslopes(const wt_shack_hartmann *s) { return 2 * s->nsub; }
int wt_shack_hartmann_ncorners(const wt_shack_hartmann *s) { return (s->n * s->q + 1) * (s->n * s->q + 1); }
int wt_shack_hartmann_sampling(const wt_shack_hartmann *s) { return s->q; }
void wt_shack_hartmann_csr(const wt_shack_hartmann *s, const int32_t **rowptr, const int32_t **col,
                           const double **val)
{
    *rowptr = s->m ? s->rowptr : NULL;
    *col = s->m ? s->colind : NULL;
    *val = s->m ? s->val : NULL;
}
const uint8_t *wt_shack_hartmann_corner_mask(const wt_shack_hartmann *s) { return s->corner_mask; }

void wt_shack_hartmann_centre(const wt_shack_hartmann *s, int k, double *x, double *y)
{
    if (k < 0 || k >= s->nsub) {
        *x = *y = NAN;
        return;
    }
    const int side = s->m ? s->m : s->n; /* the lit sensor of n x n subapertures has m = n */
    const double w = s->d * s->n / side; /* (big) subaperture side [m] */
    const int i = s->cell[k] % side, j = s->cell[k] / side;
    *x = -0.5 * s->n * s->d + (i + 0.5) * w;
    *y = -0.5 * s->n * s->d + (j + 0.5) * w;
}

/* The applies are cloned for AVX2 and AVX-512 (WT_CPU_CLONES, core/base/base.h: the same bits on every CPU). Their
 * Fried and CSR kernels are written once (shack_hartmann_kernels.inc), in double and in float. */
#define REAL double
#define K(name) name##_f64
#include "shack_hartmann_kernels.inc"
#undef REAL
#undef K
#define REAL float
#define K(name) name##_f32
#include "shack_hartmann_kernels.inc"
#undef REAL
#undef K

WT_CPU_CLONES
void wt_shack_hartmann_apply(const wt_shack_hartmann *s, double alpha, const double *restrict phase,
                             double *restrict slopes)
{
    const int nsub = s->nsub;
    if (s->m == 0) {
        fried_apply_f64(s, alpha / (2.0 * s->d), phase, slopes);
        return;
    }
    if (s->quad_u) {
        /* the CSR rows' arithmetic: acc = 0 + v0 φ00, + v1 φ10, + v2 φ01, + v3 φ11; slope += α acc */
        const int nc = s->n + 1;
        for (int32_t r = 0; r < s->nrun; r++) {
            const double *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
            const double *restrict u = s->quad_u + s->run_k[r];
            double *restrict sx = slopes + s->run_k[r], *restrict sy = sx + nsub;
            const int len = s->run_len[r];
            for (int i = 0; i < len; i++) {
                const double up = u[i], um = -u[i];
                double ax = 0.0 + um * b[i];
                ax += up * b[i + 1];
                ax += um * t[i];
                ax += up * t[i + 1];
                double ay = 0.0 + um * b[i];
                ay += um * b[i + 1];
                ay += up * t[i];
                ay += up * t[i + 1];
                sx[i] += alpha * ax;
                sy[i] += alpha * ay;
            }
        }
        return;
    }
    csr_apply_f64(2 * nsub, s->rowptr, s->colind, s->val, alpha, phase, slopes);
}

WT_CPU_CLONES
void wt_shack_hartmann_apply_t(const wt_shack_hartmann *s, double alpha, const double *restrict slopes,
                               double *restrict phase)
{
    const int nsub = s->nsub;
    if (s->m == 0) {
        fried_apply_t_f64(s, alpha / (2.0 * s->d), slopes, phase);
        return;
    }
    if (s->quad_u) {
        /* The CSR transpose adds v (α s_r) to each of row r's corners, rows in order: all x rows, then all
         * y rows. Corner (i, j) thus takes, per axis, the cells (i−1, j−1), (i, j−1), (i−1, j), (i, j) in
         * that (row) order: the top-row update of cell row j − 1's runs, then the bottom-row update of
         * cell row j's. Runs are visited in row order, one axis after the other, so every corner sees
         * the same additions in the same order as the scatter, and each loop over a corner row vectorises. */
        const int nc = s->n + 1;
        for (int axis = 0; axis < 2; axis++) {
            /* x: corners (0,0) −u, (1,0) +u, (0,1) −u, (1,1) +u; y: (0,0) −u, (1,0) −u, (0,1) +u, (1,1) +u */
            const double s10 = axis ? -1.0 : 1.0, s01 = -s10;
            for (int32_t r = 0; r < s->nrun; r++) {
                double *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
                const double *restrict u = s->quad_u + s->run_k[r];
                const double *restrict sl = slopes + (size_t)axis * nsub + s->run_k[r];
                const int len = s->run_len[r];
                /* bottom corners: cell i − 1 as its (1,0) corner, then cell i as its (0,0) corner */
                b[0] += -u[0] * (alpha * sl[0]);
                for (int i = 1; i < len; i++) b[i] = (b[i] + s10 * u[i - 1] * (alpha * sl[i - 1])) + -u[i] * (alpha * sl[i]);
                b[len] += s10 * u[len - 1] * (alpha * sl[len - 1]);
                /* top corners: cell i − 1 as its (1,1) corner (+u), then cell i as its (0,1) corner */
                t[0] += s01 * u[0] * (alpha * sl[0]);
                for (int i = 1; i < len; i++) t[i] = (t[i] + u[i - 1] * (alpha * sl[i - 1])) + s01 * u[i] * (alpha * sl[i]);
                t[len] += u[len - 1] * (alpha * sl[len - 1]);
            }
        }
        return;
    }
    csr_apply_t_f64(2 * nsub, s->rowptr, s->colind, s->val, alpha, slopes, phase);
}

/* The fp32 forms. A lit cell's rows are its Fried rows times u_k (u = 1/(2d) for the Fried sensor), so
 * its kernels are the Fried ones with u_k per cell; the scale is rounded to float once per call (Fried)
 * or at alloc (quad_u32, val32). */

WT_CPU_CLONES
void wt_shack_hartmann_apply_f32(const wt_shack_hartmann *s, float alpha, const float *restrict phase,
                                 float *restrict slopes)
{
    const int nsub = s->nsub, nc = s->n + 1;
    if (s->m == 0) {
        fried_apply_f32(s, (float)(alpha / (2.0 * s->d)), phase, slopes);
        return;
    }
    if (s->quad_u32) {
        for (int32_t r = 0; r < s->nrun; r++) {
            const float *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
            const float *restrict u = s->quad_u32 + s->run_k[r];
            float *restrict sx = slopes + s->run_k[r], *restrict sy = sx + nsub;
            const int len = s->run_len[r];
            for (int i = 0; i < len; i++) {
                const float d1 = t[i + 1] - b[i], d2 = b[i + 1] - t[i], au = alpha * u[i];
                sx[i] += au * (d1 + d2);
                sy[i] += au * (d1 - d2);
            }
        }
        return;
    }
    csr_apply_f32(2 * nsub, s->rowptr, s->colind, s->val32, alpha, phase, slopes);
}

WT_CPU_CLONES
void wt_shack_hartmann_apply_t_f32(const wt_shack_hartmann *s, float alpha, const float *restrict slopes,
                                   float *restrict phase)
{
    const int nsub = s->nsub, nc = s->n + 1;
    if (s->m == 0) {
        fried_apply_t_f32(s, (float)(alpha / (2.0 * s->d)), slopes, phase);
        return;
    }
    if (s->quad_u32) {
        /* the same gather with each cell's slopes scaled by its u */
        for (int32_t r = 0; r < s->nrun; r++) {
            float *restrict b = phase + s->run_corner[r], *restrict t = b + nc;
            const float *restrict u = s->quad_u32 + s->run_k[r];
            const float *restrict sx = slopes + s->run_k[r], *restrict sy = sx + nsub;
            const int len = s->run_len[r];
            b[0] -= alpha * (u[0] * (sx[0] + sy[0]));
            t[0] += alpha * (u[0] * (sy[0] - sx[0]));
            for (int i = 1; i < len; i++) {
                b[i] += alpha * (u[i - 1] * (sx[i - 1] - sy[i - 1]) - u[i] * (sx[i] + sy[i]));
                t[i] += alpha * (u[i - 1] * (sx[i - 1] + sy[i - 1]) + u[i] * (sy[i] - sx[i]));
            }
            b[len] += alpha * (u[len - 1] * (sx[len - 1] - sy[len - 1]));
            t[len] += alpha * (u[len - 1] * (sx[len - 1] + sy[len - 1]));
        }
        return;
    }
    csr_apply_t_f32(2 * nsub, s->rowptr, s->colind, s->val32, alpha, slopes, phase);
}

int wt_shack_hartmann_assemble(const wt_shack_hartmann *s, wt_sparse **out)
{
    int st = WT_OK;
    wt_triplet *t = NULL;
    *out = NULL;
    const int nsub = s->nsub, nc = s->n * s->q + 1;
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
