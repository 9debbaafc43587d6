/* tests/test_wfs.c: the simulator's truth Shack–Hartmann sensors (SPEC §4 "Truth"): exactness on
 * piston, tilt and quadratics, the illuminated-part average against an independent evaluation and a
 * continuous integral, agreement with the reconstructor's Fried model (counts, layout, values), the
 * fine mask, the LGS tip-tilt draw, and bad input. */
#include "testutil.h"

#include <stdint.h>

#include "core/op/pupil.h"
#include "core/op/shack_hartmann.h"
#include "sim/wfs.h"

/* the E-ELT LGS sensor (SPEC §1) on the default fine grid */
#define N 84
#define DIAM 42.0
#define OBS 0.28
#define DSUB 0.5
#define P 4

static void eelt_valid(uint8_t *v) { ck_assert_int_eq(wt_pupil_valid_subapertures(DIAM, OBS, N, 0.5, v), 5112); }

static wt_wfs *make(wt_context *ctx, double D, double obs, int n, int p, const uint8_t *v, int m)
{
    wt_wfs *w = NULL;
    int st = wt_wfs_alloc(ctx, D, obs, n, D / n, p, v, m, WT_SH_TILT_G, &w);
    ck_assert_msg(st == WT_OK, "wfs alloc failed: %s", wt_error_message(ctx));
    return w;
}

/* The valid big subapertures of an m x m sensor (m = 0: n x n) in index order, by the model's rule
 * (at least one valid fine subaperture), as the lower-left fine subaperture (i0, j0) of each and the
 * fine subapertures per side f. Returns the count. */
static int big_list(int n, const uint8_t *valid, int m, int *i0, int *j0, int *f)
{
    const int M = m ? m : n;
    *f = n / M;
    int k = 0;
    for (int J = 0; J < M; J++)
        for (int I = 0; I < M; I++) {
            int any = 0;
            for (int j = J * *f; j < (J + 1) * *f; j++)
                for (int i = I * *f; i < (I + 1) * *f; i++) any |= valid[i + n * j] != 0;
            if (!any) continue;
            i0[k] = I * *f, j0[k] = J * *f;
            k++;
        }
    return k;
}

/* ---- analytic OPDs ---- */

typedef struct {
    double a, b, cxx, cxy, cyy, c0; /* φ = a x + b y + cxx x² + cxy x y + cyy y² + c0 */
} quad;
static double quad_val(const quad *q, double x, double y)
{
    return q->a * x + q->b * y + q->cxx * x * x + q->cxy * x * y + q->cyy * y * y + q->c0;
}
static void quad_grad(const quad *q, double x, double y, double *gx, double *gy)
{
    *gx = q->a + 2.0 * q->cxx * x + q->cxy * y;
    *gy = q->b + q->cxy * x + 2.0 * q->cyy * y;
}

#define NCOS 3
typedef struct {
    double A[NCOS], kx[NCOS], ky[NCOS], psi[NCOS]; /* φ = Σ A cos(kx x + ky y + ψ) */
} cosines;
static double cos_val(const cosines *c, double x, double y)
{
    double s = 0.0;
    for (int i = 0; i < NCOS; i++) s += c->A[i] * cos(c->kx[i] * x + c->ky[i] * y + c->psi[i]);
    return s;
}

/* Sample a quadratic on an (n p + 1)² grid of spacing h centred on the origin (the fine grid). */
static void sample_quad(const quad *q, int np, double h, double *opd)
{
    const double x0 = -0.5 * np * h;
    for (int j = 0; j <= np; j++)
        for (int i = 0; i <= np; i++) opd[i + (np + 1) * j] = quad_val(q, x0 + i * h, x0 + j * h);
}
static void sample_cos(const cosines *c, int np, double h, double *opd)
{
    const double x0 = -0.5 * np * h;
    for (int j = 0; j <= np; j++)
        for (int i = 0; i <= np; i++) opd[i + (np + 1) * j] = cos_val(c, x0 + i * h, x0 + j * h);
}

/* The definition, evaluated directly: Σ w g / Σ w over the fine cells of each valid big subaperture,
 * g the Fried gradient of the cell's corners, w = wt_pupil_fraction of the cell (no classification). */
static void brute_force(double D, double obs, int n, int p, const uint8_t *valid, int m, const double *opd,
                        double *slopes)
{
    int i0[N * N], j0[N * N], f;
    const int nk = big_list(n, valid, m, i0, j0, &f);
    const int np = n * p, ng = np + 1;
    const double h = D / np;
    for (int k = 0; k < nk; k++) {
        double sw = 0.0, sx = 0.0, sy = 0.0;
        for (int b = j0[k] * p; b < (j0[k] + f) * p; b++)
            for (int a = i0[k] * p; a < (i0[k] + f) * p; a++) {
                const double w = wt_pupil_fraction(D, obs, -0.5 * D + a * h, -0.5 * D + b * h, h);
                const double *c = opd + a + (size_t)ng * b;
                sx += w * ((c[1] + c[ng + 1]) - (c[0] + c[ng])) / (2.0 * h);
                sy += w * ((c[ng] + c[ng + 1]) - (c[0] + c[1])) / (2.0 * h);
                sw += w;
            }
        slopes[k] = sx / sw;
        slopes[nk + k] = sy / sw;
    }
}

START_TEST(test_counts_and_layout)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N];
    eelt_valid(v);
    const int ms[3] = {0, 2, 1}, want[3] = {10224, 8, 2};
    for (int t = 0; t < 3; t++) {
        wt_wfs *w = make(ctx, DIAM, OBS, N, P, v, ms[t]);
        wt_shack_hartmann *sh = NULL;
        ck_assert_int_eq(ms[t] ? wt_shack_hartmann_alloc_averaged(ctx, N, DSUB, v, ms[t], &sh)
                               : wt_shack_hartmann_alloc(ctx, N, DSUB, v, &sh), WT_OK);
        ck_assert_int_eq(wt_wfs_nslopes(w), want[t]);
        ck_assert_int_eq(wt_wfs_nslopes(w), wt_shack_hartmann_nslopes(sh));
        ck_assert_int_eq(wt_wfs_nsub(w), wt_shack_hartmann_nsub(sh));
        const wt_grid g = wt_wfs_grid(w);
        ck_assert_int_eq(g.nx, N * P + 1);
        ck_assert_int_eq(g.ny, N * P + 1);
        ck_assert_rel(g.dx, DSUB / P, 1e-15, 0.0);
        ck_assert_rel(g.x0, -0.5 * DIAM, 1e-15, 0.0);
        ck_assert_rel(g.y0, -0.5 * DIAM, 1e-15, 0.0);
        /* the mask's count is what npoints says, and the telescoping leaves out the interior: for the
         * LGS sensor the (p-1)² points strictly inside each fully lit subaperture are not read */
        int64_t cnt = 0;
        const uint8_t *mk = wt_wfs_fine_mask(w);
        for (int64_t q = 0; q < wt_grid_size(&g); q++) cnt += mk[q] != 0;
        ck_assert_int_eq(cnt, wt_wfs_npoints(w));
        ck_assert_int_lt(wt_wfs_npoints(w), wt_grid_size(&g));
        if (ms[t] == 0) {
            static int i0[N * N], j0[N * N];
            int f, nfull = 0;
            const int nk = big_list(N, v, 0, i0, j0, &f);
            for (int k = 0; k < nk; k++) {
                if (wt_pupil_fraction(DIAM, OBS, -0.5 * DIAM + i0[k] * DSUB, -0.5 * DIAM + j0[k] * DSUB, DSUB) < 1.0)
                    continue;
                nfull++;
                for (int b = 0; b <= P; b++)
                    for (int a = 0; a <= P; a++) {
                        const int inner = a > 0 && a < P && b > 0 && b < P;
                        ck_assert_int_eq(mk[(i0[k] * P + a) + g.nx * (j0[k] * P + b)], !inner);
                    }
            }
            ck_assert_int_gt(nfull, 4000);
        }
        ck_assert_int_ge(wt_wfs_nnz(w), 2 * wt_wfs_nslopes(w));
        ck_assert(wt_wfs_bytes(w) > (size_t)wt_wfs_nnz(w) * 12);
        wt_shack_hartmann_free(sh);
        wt_wfs_free(w);
    }
    /* m = n is the LGS-type sensor itself */
    wt_wfs *a = make(ctx, DIAM, OBS, N, P, v, 0), *b = make(ctx, DIAM, OBS, N, P, v, N);
    ck_assert_int_eq(wt_wfs_nnz(a), wt_wfs_nnz(b));
    ck_assert_mem_eq(wt_wfs_fine_mask(a), wt_wfs_fine_mask(b), (size_t)(N * P + 1) * (N * P + 1));
    wt_wfs_free(a);
    wt_wfs_free(b);

    /* A big subaperture that is lit but holds no valid fine subaperture is not valid (the model's
     * rule), even though its lit area would give a slope: 8 x 8 over 4 m, no obstruction, 4 x 4 big
     * subapertures of 2 x 2; clear the valid flags of big subaperture (0, 0) (its fine (1, 0) is lit). */
    uint8_t sv[64];
    wt_pupil_valid_subapertures(4.0, 0.0, 8, 0.5, sv);
    sv[0] = sv[1] = sv[8] = sv[9] = 0;
    ck_assert(wt_pupil_fraction(4.0, 0.0, -1.5, -2.0, 0.5) > 0.0);
    wt_wfs *w = make(ctx, 4.0, 0.0, 8, 3, sv, 4);
    wt_shack_hartmann *sh = NULL;
    ck_assert_int_eq(wt_shack_hartmann_alloc_averaged(ctx, 8, 0.5, sv, 4, &sh), WT_OK);
    ck_assert_int_eq(wt_wfs_nsub(w), wt_shack_hartmann_nsub(sh));
    ck_assert_int_eq(wt_wfs_nsub(w), 15);
    wt_shack_hartmann_free(sh);
    wt_wfs_free(w);
    wt_context_free(ctx);
}
END_TEST

/* Piston and tilt are reproduced exactly. A piston: Σ val = 0 and measure differences against one
 * point of each row, so every term is exactly 0 — a flat OPD gives exact zeros, and measure
 * overwrites whatever the output held. A tilt: each cell's Fried gradient is exactly (a, b), any
 * weighted mean of it too; rounding of φ ~ 21|a| over differences of ~δf|a| leaves ~1e-14. */
START_TEST(test_piston_and_tilt)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N];
    eelt_valid(v);
    const int ng = N * P + 1;
    double *opd = malloc(sizeof *opd * ng * ng), *s = malloc(sizeof *s * 2 * N * N);
    const int ms[3] = {0, 2, 1};
    for (int t = 0; t < 3; t++) {
        wt_wfs *w = make(ctx, DIAM, OBS, N, P, v, ms[t]);
        const int ns = wt_wfs_nslopes(w), nsub = ns / 2;
        for (int q = 0; q < ng * ng; q++) opd[q] = 3.7e-6;
        for (int r = 0; r < ns; r++) s[r] = 1e300;
        wt_wfs_measure(w, opd, s);
        for (int r = 0; r < ns; r++) ck_assert_msg(s[r] == 0.0, "sensor m=%d slope %d = %g for a piston", ms[t], r, s[r]);

        const quad tilt = {2.3e-6, -1.1e-6, 0, 0, 0, 5e-6};
        sample_quad(&tilt, N * P, DSUB / P, opd);
        wt_wfs_measure(w, opd, s);
        for (int k = 0; k < nsub; k++) {
            ck_assert_rel(s[k], tilt.a, 1e-12, 0.0);
            ck_assert_rel(s[nsub + k], tilt.b, 1e-12, 0.0);
        }
        wt_wfs_free(w);
    }
    free(opd);
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* The definition on random data: the sensor equals the direct evaluation of Σ w g / Σ w (brute_force)
 * for an LGS-type and every averaged sensor of a small annular system, with p = 3 so that fine cells
 * are cut by the rim in every way. The two differ in summation order (telescoped coefficients vs cell
 * by cell) and in the weights of fully lit and unlit cells (exact 1 and 0 vs wt_pupil_fraction's
 * ~1e-11 absolute rounding): relative 1e-10 of the largest fine-cell gradient bounds both. The OPD is
 * NaN outside the fine mask, so a point read but not in the mask poisons a slope. */
START_TEST(test_definition_random)
{
    wt_context *ctx = tu_context();
    const int n = 8, p = 3, np = n * p, ng = np + 1;
    const double D = 4.0, obs = 0.3, h = D / np;
    uint8_t v[64];
    ck_assert_int_gt(wt_pupil_valid_subapertures(D, obs, n, 0.5, v), 0);
    double opd[ng * ng], full[ng * ng], s[128], s2[128], ref[128];
    tu_randn(full, ng * ng, 7);
    double gmax = 0.0; /* largest fine-cell gradient: differences of N(0,1) values over δf */
    for (int q = 0; q < ng * ng; q++) gmax = fmax(gmax, fabs(full[q]));
    gmax *= 2.0 / h;
    const int ms[5] = {0, 1, 2, 4, 8};
    for (int t = 0; t < 5; t++) {
        wt_wfs *w = make(ctx, D, obs, n, p, v, ms[t]);
        const int ns = wt_wfs_nslopes(w);
        const uint8_t *mk = wt_wfs_fine_mask(w);
        for (int q = 0; q < ng * ng; q++) opd[q] = mk[q] ? full[q] : NAN;
        wt_wfs_measure(w, opd, s);
        wt_wfs_measure(w, full, s2);
        brute_force(D, obs, n, p, v, ms[t], full, ref);
        for (int r = 0; r < ns; r++) {
            ck_assert_msg(isfinite(s[r]), "m=%d slope %d reads a point outside the fine mask", ms[t], r);
            ck_assert_msg(s[r] == s2[r], "m=%d slope %d depends on points outside the mask", ms[t], r);
            ck_assert_msg(fabs(s[r] - ref[r]) <= 1e-10 * gmax, "m=%d slope %d: %.17g vs definition %.17g", ms[t], r,
                          s[r], ref[r]);
        }
        wt_wfs_free(w);
    }
    wt_context_free(ctx);
}
END_TEST

/* Exact average over the lit part of [x0, x0+s]² of the linear gradient field of q: midpoint rule in x
 * (K points), the chord's lit intervals in y exactly, ∫ (g0 + gx' x + gy' y) dy in closed form. The
 * integrand in x is continuous and piecewise smooth (kinks where the rim crosses y0 or y0+s): the
 * midpoint error is O((s/K)²) of the integrand's scale, ~1e-11 relative for K = 2e5. */
static void continuous_average(double D, double obs, double x0, double y0, double s, const quad *q, double *gx,
                               double *gy)
{
    const int K = 200000;
    const double ro = 0.5 * D, ri = 0.5 * obs * D, hx = s / K, y1 = y0 + s;
    double area = 0.0, ix = 0.0, iy = 0.0;
    for (int k = 0; k < K; k++) {
        const double x = x0 + (k + 0.5) * hx;
        if (fabs(x) >= ro) continue;
        const double so = sqrt(ro * ro - x * x), si = fabs(x) < ri ? sqrt(ri * ri - x * x) : 0.0;
        /* lit: [max(y0, −so), min(y1, so)] minus (−si, si) */
        double iv[2][2] = {{fmax(y0, -so), fmin(y1, -si)}, {fmax(y0, si), fmin(y1, so)}};
        if (si == 0.0) iv[0][1] = fmin(y1, so), iv[1][0] = iv[1][1] = 0.0;
        for (int u = 0; u < 2; u++) {
            const double ya = iv[u][0], yb = iv[u][1];
            if (!(yb > ya)) continue;
            double g0x, g0y;
            quad_grad(q, x, 0.0, &g0x, &g0y); /* g(x, y) = g(x, 0) + (cxy, 2 cyy) y */
            area += (yb - ya) * hx;
            ix += (g0x * (yb - ya) + q->cxy * 0.5 * (yb * yb - ya * ya)) * hx;
            iy += (g0y * (yb - ya) + 2.0 * q->cyy * 0.5 * (yb * yb - ya * ya)) * hx;
        }
    }
    *gx = ix / area;
    *gy = iy / area;
}

/* Quadratic OPD. Fried on a cell is exact for quadratics at the cell centre ((x1² − x0²)/δ = 2 x_c,
 * and the xy term averages the two rows), and ∇φ is linear, so:
 *  - a fully lit subaperture (equal weights) gives exactly ∇φ at its centre;
 *  - every subaperture, lit or cut, gives Σ w_c ∇φ(r_c) / Σ w_c over its fine-cell centres r_c —
 *    checked for all LGS, 2x2 and 1x1 slopes (1e-10: the weights' rounding, see test_definition_random);
 *  - against the continuous average over the lit part: both are ∇φ at a centroid (the weighted cell
 *    centres vs the true lit centroid), which differ by Σ_c A_c (r_c − ρ_c) / A over the cut cells
 *    (A_c = w_c δf² lit area, ρ_c its centroid, r_c the cell centre). Per axis |r_c − ρ_c| ≤ δf/2
 *    (both in the cell) and = (1 − w_c)|ρ_unlit − ρ_c| ≤ (1 − w_c) δf, so
 *    |discrete − continuous|_x ≤ (|H_xx| + |H_xy|) δf Σ_c A_c min(1/2, 1 − w_c) / A.
 *    Checked on cut subapertures (lit 50–70 %) of the outer and inner rim near the diagonal x = y, where
 *    H (all entries > 0) does not cancel the centroid shift; the test also asserts that the centre
 *    gradient misses the continuous value by more than 3 times that bound (a sensor averaging over
 *    the whole subaperture instead of its lit part would fail). */
START_TEST(test_quadratic)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N];
    eelt_valid(v);
    const int ng = N * P + 1;
    const double h = DSUB / P;
    double *opd = malloc(sizeof *opd * ng * ng), *s = malloc(sizeof *s * 2 * N * N);
    static int i0[N * N], j0[N * N];
    const quad q = {1.3e-7, -0.4e-7, 2.1e-8, 1.7e-8, 1.2e-8, 1e-6};
    sample_quad(&q, N * P, h, opd);
    const double gscale = 2.0 * 21.0 * 2.1e-8 + 1.3e-7; /* largest |∇φ| over the pupil, roughly */

    const int ms[3] = {0, 2, 1};
    for (int t = 0; t < 3; t++) {
        wt_wfs *w = make(ctx, DIAM, OBS, N, P, v, ms[t]);
        wt_wfs_measure(w, opd, s);
        int f;
        const int nk = big_list(N, v, ms[t], i0, j0, &f);
        ck_assert_int_eq(2 * nk, wt_wfs_nslopes(w));
        int nfull = 0;
        for (int k = 0; k < nk; k++) {
            const double bx = -0.5 * DIAM + i0[k] * DSUB, by = -0.5 * DIAM + j0[k] * DSUB, side = f * DSUB;
            double sw = 0.0, sx = 0.0, sy = 0.0;
            for (int b = 0; b < f * P; b++)
                for (int a = 0; a < f * P; a++) {
                    const double wc = wt_pupil_fraction(DIAM, OBS, bx + a * h, by + b * h, h);
                    double gx, gy;
                    quad_grad(&q, bx + (a + 0.5) * h, by + (b + 0.5) * h, &gx, &gy);
                    sx += wc * gx, sy += wc * gy, sw += wc;
                }
            ck_assert_rel(s[k], sx / sw, 1e-10, gscale);
            ck_assert_rel(s[nk + k], sy / sw, 1e-10, gscale);
            if (wt_pupil_fraction(DIAM, OBS, bx, by, side) >= 1.0 - 1e-9) {
                double gx, gy;
                quad_grad(&q, bx + 0.5 * side, by + 0.5 * side, &gx, &gy);
                ck_assert_rel(s[k], gx, 1e-12, gscale);
                ck_assert_rel(s[nk + k], gy, 1e-12, gscale);
                nfull++;
            }
        }
        if (ms[t] == 0) ck_assert_int_gt(nfull, 4000);
        wt_wfs_free(w);
    }

    /* continuous check on cut LGS subapertures: nearest the diagonal on the outer and the inner rim */
    wt_wfs *w = make(ctx, DIAM, OBS, N, P, v, 0);
    wt_wfs_measure(w, opd, s);
    int f;
    const int nk = big_list(N, v, 0, i0, j0, &f);
    for (int rim = 0; rim < 2; rim++) {
        int best = -1;
        double best_diag = -1.0;
        for (int k = 0; k < nk; k++) {
            const double x0 = -0.5 * DIAM + i0[k] * DSUB, y0 = -0.5 * DIAM + j0[k] * DSUB;
            const double xc = x0 + 0.25, yc = y0 + 0.25, r = hypot(xc, yc);
            const double fr = wt_pupil_fraction(DIAM, OBS, x0, y0, DSUB);
            if (fr < 0.5 || fr > 0.7 || xc * yc < 0.0 || (rim == 0 ? r < 15.0 : r > 10.0)) continue;
            const double diag = fmin(fabs(xc), fabs(yc)) / fmax(fabs(xc), fabs(yc));
            if (diag > best_diag) best_diag = diag, best = k;
        }
        ck_assert_int_ge(best, 0);
        const double x0 = -0.5 * DIAM + i0[best] * DSUB, y0 = -0.5 * DIAM + j0[best] * DSUB;
        double cx, cy, area = 0.0, apart = 0.0;
        continuous_average(DIAM, OBS, x0, y0, DSUB, &q, &cx, &cy);
        for (int b = 0; b < P; b++)
            for (int a = 0; a < P; a++) {
                const double wc = wt_pupil_fraction(DIAM, OBS, x0 + a * h, y0 + b * h, h);
                area += wc * h * h;
                apart += wc * h * h * fmin(0.5, 1.0 - wc);
            }
        const double c = h * apart / area;
        const double tolx = (2.0 * fabs(q.cxx) + fabs(q.cxy)) * c + 1e-9 * gscale;
        const double toly = (fabs(q.cxy) + 2.0 * fabs(q.cyy)) * c + 1e-9 * gscale;
        ck_assert_msg(fabs(s[best] - cx) <= tolx, "rim %d: s_x %.10g vs continuous %.10g, bound %.3g", rim, s[best],
                      cx, tolx);
        ck_assert_msg(fabs(s[nk + best] - cy) <= toly, "rim %d: s_y %.10g vs continuous %.10g, bound %.3g", rim,
                      s[nk + best], cy, toly);
        double gx, gy;
        quad_grad(&q, x0 + 0.25, y0 + 0.25, &gx, &gy);
        ck_assert_msg(hypot(gx - cx, gy - cy) > 3.0 * hypot(tolx, toly),
                      "rim %d: the centre gradient is within 3 bounds of the lit average: the test cannot tell", rim);
    }
    wt_wfs_free(w);
    free(opd);
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* Truth vs the reconstructor's model on a smooth OPD (three long-period cosines, periods 20–55 m),
 * slope by slope, at E-ELT size: LGS, NGS 2x2 and 1x1. A (big) subaperture's truth is T = Σ_s α_s T_s
 * over its coarse subapertures s (α_s ∝ lit area, T_s the truth of s alone) and the model is
 * M = Σ_s μ_s F_s (μ_s ∝ valid flag, F_s the coarse Fried slope). So T − M = E + Σ_s α_s (T_s − F_s),
 * E = Σ_s (α_s − μ_s) F_s computed here exactly (zero for the LGS sensor), and:
 *  - s fully lit: T_s and F_s are the p-panel and 1-panel trapezoid means over y of Δ_xφ(y)/d, whose
 *    second derivative is ≤ Σ|A| |k_x| k_y², so |T_s − F_s| ≤ (d² + δf²)/12 · Σ|A| |k_x| k_y²;
 *  - s cut by the rim: both are averages of ∂_xφ over points of s (a Fried slope is the mean of the
 *    exact differences along two cell edges), so |T_s − F_s| ≤ osc_s ∂_xφ ≤ Σ|A| |k_x| |k| d√2.
 * (y likewise.) Slack 1e-9 of the slope scale for the weights' rounding. A shifted or transposed
 * layout breaks the fully lit bound by orders of magnitude (neighbours differ by ~|A| k² d). */
START_TEST(test_model_agreement)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N];
    eelt_valid(v);
    const int ng = N * P + 1, nc = N + 1;
    const double h = DSUB / P;
    cosines c;
    const double per[NCOS] = {20.0, 33.0, 55.0}, dir[NCOS] = {0.3, 1.9, 4.0}, amp[NCOS] = {1e-6, 0.7e-6, 0.5e-6},
                 psi[NCOS] = {0.4, 1.1, 2.5};
    double sk = 0.0, ex_full = 0.0, ey_full = 0.0, ex_cut = 0.0, ey_cut = 0.0;
    for (int i = 0; i < NCOS; i++) {
        const double k = 2.0 * M_PI / per[i];
        c.A[i] = amp[i], c.kx[i] = k * cos(dir[i]), c.ky[i] = k * sin(dir[i]), c.psi[i] = psi[i];
        ex_full += amp[i] * fabs(c.kx[i]) * c.ky[i] * c.ky[i];
        ey_full += amp[i] * fabs(c.ky[i]) * c.kx[i] * c.kx[i];
        ex_cut += amp[i] * fabs(c.kx[i]) * k;
        ey_cut += amp[i] * fabs(c.ky[i]) * k;
        sk += amp[i] * k;
    }
    const double tf = (DSUB * DSUB + h * h) / 12.0, tc = DSUB * M_SQRT2;
    ex_full *= tf, ey_full *= tf, ex_cut *= tc, ey_cut *= tc;
    double *opd = malloc(sizeof *opd * ng * ng), *phi = malloc(sizeof *phi * nc * nc);
    double *T = malloc(sizeof *T * 2 * N * N), *M = malloc(sizeof *M * 2 * N * N);
    static int i0[N * N], j0[N * N];
    sample_cos(&c, N * P, h, opd);
    sample_cos(&c, N, DSUB, phi);

    const int ms[3] = {0, 2, 1};
    for (int t = 0; t < 3; t++) {
        wt_wfs *w = make(ctx, DIAM, OBS, N, P, v, ms[t]);
        wt_shack_hartmann *sh = NULL;
        ck_assert_int_eq(ms[t] ? wt_shack_hartmann_alloc_averaged(ctx, N, DSUB, v, ms[t], &sh)
                               : wt_shack_hartmann_alloc(ctx, N, DSUB, v, &sh), WT_OK);
        const int ns = wt_wfs_nslopes(w);
        ck_assert_int_eq(ns, wt_shack_hartmann_nslopes(sh));
        wt_wfs_measure(w, opd, T);
        for (int r = 0; r < ns; r++) M[r] = 0.0;
        wt_shack_hartmann_apply(sh, 1.0, phi, M);
        int f;
        const int nk = big_list(N, v, ms[t], i0, j0, &f);
        ck_assert_int_eq(2 * nk, ns);
        double dn = 0.0, mn = 0.0;
        for (int k = 0; k < nk; k++) {
            double sa = 0.0, sm = 0.0, ax = 0.0, ay = 0.0, mx = 0.0, my = 0.0, bx = 0.0, by = 0.0;
            for (int j = j0[k]; j < j0[k] + f; j++)
                for (int i = i0[k]; i < i0[k] + f; i++) {
                    const double fr = wt_pupil_fraction(DIAM, OBS, -0.5 * DIAM + i * DSUB, -0.5 * DIAM + j * DSUB, DSUB);
                    const double *p = phi + i + nc * j;
                    const double Fx = ((p[1] + p[nc + 1]) - (p[0] + p[nc])) / (2.0 * DSUB);
                    const double Fy = ((p[nc] + p[nc + 1]) - (p[0] + p[1])) / (2.0 * DSUB);
                    const int vs = v[i + N * j] != 0;
                    sa += fr, sm += vs;
                    ax += fr * Fx, ay += fr * Fy, mx += vs * Fx, my += vs * Fy;
                    bx += fr * (fr >= 1.0 - 1e-9 ? ex_full : ex_cut);
                    by += fr * (fr >= 1.0 - 1e-9 ? ey_full : ey_cut);
                }
            const double Ex = ax / sa - mx / sm, Ey = ay / sa - my / sm;
            const double tolx = bx / sa + 1e-9 * sk, toly = by / sa + 1e-9 * sk;
            ck_assert_msg(fabs(T[k] - M[k] - Ex) <= tolx, "m=%d subaperture %d: s_x truth %.10g model %.10g E %.3g, "
                          "bound %.3g", ms[t], k, T[k], M[k], Ex, tolx);
            ck_assert_msg(fabs(T[nk + k] - M[nk + k] - Ey) <= toly, "m=%d subaperture %d: s_y truth %.10g model "
                          "%.10g E %.3g, bound %.3g", ms[t], k, T[nk + k], M[nk + k], Ey, toly);
            dn += (T[k] - M[k]) * (T[k] - M[k]) + (T[nk + k] - M[nk + k]) * (T[nk + k] - M[nk + k]);
            mn += M[k] * M[k] + M[nk + k] * M[nk + k];
        }
        /* The per-slope bounds above are the test. For the record, ‖T − M‖/‖M‖ is 2.4e-3 (LGS), 2.8e-3
         * (2x2, of which ‖E‖ 2.0e-3) and 1.3e-3 (1x1, ‖E‖ 5.7e-4); the fully lit LGS subapertures reach
         * 0.88 of their bound, the cut ones 0.12 (the oscillation bound is loose). Their aggregate,
         * ‖|E| + bound‖/‖M‖, is 7 %, 6 % and 14 %: the relative error is certainly below that. */
        ck_assert(sqrt(dn / mn) < 0.15);
        wt_shack_hartmann_free(sh);
        wt_wfs_free(w);
    }
    free(opd);
    free(phi);
    free(T);
    free(M);
    wt_context_free(ctx);
}
END_TEST

/* The LGS tip-tilt draw. Over K = 20000 frames the sample mean of t_x has standard deviation rms/√K and
 * the sample variance rms² √(2/K) (normal data): 5 of those bound them with a false-alarm probability
 * < 1e-6 each; the x–y correlation likewise within 5/√K. Every s_x moves by the same t_x, bit for bit,
 * and the amounts are the rng's next two normals times rms. */
/* A screen the reconstructor can represent — bilinear on its sample grid (the 0.5 m corners, the lit
 * model at q = 1) — measured by the truth sensor on the fine grid (p = 4) and by the model, valid
 * fraction 0.3 as in the low-noise preset, LGS and NGS 2x2 and 1x1. In a 0.5 m cell the bilinear
 * ∂xφ is linear in y, from the bottom-edge difference Δ0/d to the top-edge one Δ1/d; every fine cell's
 * Fried slope is its mean over that fine cell, so the truth of the cell is Δ0/d + t (Δ1 − Δ0)/d with
 * t ∈ [0, 1] the lit centroid's height, and the model's Fried slope is t = 1/2. Both weight the cells by
 * the same lit area. Hence: fully lit subapertures reproduce the truth exactly (to rounding), and a big
 * subaperture differs by at most Σ_c w_c |Δ1 − Δ0|_c / (2d) / Σ_c w_c over its partly lit cells. */
START_TEST(test_representable_screen)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N];
    ck_assert_int_gt(wt_pupil_valid_subapertures(DIAM, OBS, N, 0.3, v), 5112);
    const int nc = N + 1, np = N * P, ng = np + 1;
    double *pc = malloc((size_t)nc * nc * sizeof *pc), *pf = malloc((size_t)ng * ng * sizeof *pf);
    tu_randn(pc, nc * nc, 91);
    for (int i = 0; i < nc * nc; i++) pc[i] *= 1e-7; /* ~0.1 µm per corner: slopes ~2e-7 rad */
    for (int j = 0; j < ng; j++)
        for (int i = 0; i < ng; i++) {
            int I = i / P < N ? i / P : N - 1, J = j / P < N ? j / P : N - 1;
            double u = (double)(i - I * P) / P, w = (double)(j - J * P) / P;
            const double *c = pc + I + nc * J;
            pf[i + (size_t)ng * j] = (1 - u) * (1 - w) * c[0] + u * (1 - w) * c[1] + (1 - u) * w * c[nc] + u * w * c[nc + 1];
        }
    for (int m = 0; m <= 2; m++) {
        wt_wfs *t = make(ctx, DIAM, OBS, N, P, v, m);
        wt_shack_hartmann *s = NULL;
        ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, DIAM, OBS, N, DSUB, 1, v, m, WT_SH_TILT_G, &s), WT_OK);
        const int nsub = wt_shack_hartmann_nsub(s);
        ck_assert_int_eq(wt_wfs_nsub(t), nsub);
        double *st = calloc(2 * (size_t)nsub, sizeof *st), *sm = calloc(2 * (size_t)nsub, sizeof *sm);
        wt_wfs_measure(t, pf, st);
        wt_shack_hartmann_apply(s, 1.0, pc, sm);
        int i0[N * N], j0[N * N], f, nfull = 0;
        ck_assert_int_eq(big_list(N, v, m, i0, j0, &f), nsub);
        double worst = 0.0;
        for (int k = 0; k < nsub; k++) {
            double sw = 0.0, bx = 0.0, by = 0.0, scale = 0.0;
            int partial = 0;
            for (int j = j0[k]; j < j0[k] + f; j++)
                for (int i = i0[k]; i < i0[k] + f; i++) {
                    if (!v[i + N * j] && m == 0) continue;
                    double w = wt_pupil_fraction(DIAM, OBS, -0.5 * DIAM + i * DSUB, -0.5 * DIAM + j * DSUB, DSUB);
                    const double *c = pc + i + nc * j;
                    double e = fabs(c[nc + 1] - c[nc] - c[1] + c[0]) / (2.0 * DSUB); /* |Δ1 − Δ0| / 2d, both axes */
                    sw += w;
                    scale = fmax(scale, fabs(c[1] - c[0]) / DSUB + fabs(c[nc] - c[0]) / DSUB);
                    if (w < 1.0 - 1e-12) bx += w * e, by += w * e, partial = 1;
                }
            bx /= sw, by /= sw;
            const double tol = 1e-11 * scale;
            ck_assert_msg(fabs(st[k] - sm[k]) <= bx + tol, "m = %d sub %d x: truth %g model %g bound %g", m, k, st[k],
                          sm[k], bx);
            ck_assert_msg(fabs(st[nsub + k] - sm[nsub + k]) <= by + tol, "m = %d sub %d y: truth %g model %g bound %g",
                          m, k, st[nsub + k], sm[nsub + k], by);
            if (!partial) nfull++;
            else if (bx > 0.0) worst = fmax(worst, fabs(st[k] - sm[k]) / bx);
        }
        if (m == 0) {
            ck_assert_int_gt(nfull, 4800);
            ck_assert_double_gt(worst, 0.3); /* the bound is reached in part: the rim cells do differ */
        }
        free(st), free(sm);
        wt_shack_hartmann_free(s);
        wt_wfs_free(t);
    }
    free(pc), free(pf);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_tiptilt)
{
    wt_context *ctx = tu_context();
    const int n = 8;
    uint8_t v[64];
    wt_pupil_valid_subapertures(4.0, 0.3, n, 0.5, v);
    wt_wfs *w = make(ctx, 4.0, 0.3, n, 2, v, 0);
    const int ns = wt_wfs_nslopes(w), nsub = ns / 2;
    double s[128], before[128];
    const double rms = 9.7e-7; /* 0.2 arcsec */
    const int K = 20000;
    wt_rng rng;
    wt_rng_init(&rng, 2024, 3);
    double mx = 0.0, my = 0.0, vx = 0.0, vy = 0.0, cxy = 0.0;
    for (int it = 0; it < K; it++) {
        for (int r = 0; r < ns; r++) s[r] = 0.0;
        ck_assert_int_eq(wt_wfs_add_tiptilt(w, &rng, rms, s), WT_OK);
        for (int k = 1; k < nsub; k++) ck_assert(s[k] == s[0] && s[nsub + k] == s[nsub]);
        mx += s[0], my += s[nsub];
        vx += s[0] * s[0], vy += s[nsub] * s[nsub], cxy += s[0] * s[nsub];
    }
    mx /= K, my /= K;
    vx = vx / K - mx * mx, vy = vy / K - my * my, cxy = cxy / K - mx * my;
    ck_assert_msg(fabs(mx) <= 5.0 * rms / sqrt(K) && fabs(my) <= 5.0 * rms / sqrt(K), "means %g %g", mx, my);
    ck_assert_msg(fabs(vx - rms * rms) <= 5.0 * rms * rms * sqrt(2.0 / K), "var x %g vs %g", vx, rms * rms);
    ck_assert_msg(fabs(vy - rms * rms) <= 5.0 * rms * rms * sqrt(2.0 / K), "var y %g vs %g", vy, rms * rms);
    ck_assert_msg(fabs(cxy) <= 5.0 * rms * rms / sqrt(K), "x-y covariance %g", cxy);

    /* on real slopes: the shift is the same for every x (and every y) slope, and is rms times the
     * next two normals of the generator */
    const int ng = n * 2 + 1;
    double opd[ng * ng];
    tu_randn(opd, ng * ng, 11);
    for (int q = 0; q < ng * ng; q++) opd[q] *= 1e-6;
    wt_wfs_measure(w, opd, s);
    memcpy(before, s, sizeof s);
    wt_rng copy = rng;
    const double tx = rms * wt_rng_normal(&copy), ty = rms * wt_rng_normal(&copy);
    ck_assert_int_eq(wt_wfs_add_tiptilt(w, &rng, rms, s), WT_OK);
    for (int k = 0; k < nsub; k++) {
        ck_assert(s[k] == before[k] + tx);
        ck_assert(s[nsub + k] == before[nsub + k] + ty);
    }
    ck_assert(tx != ty);
    /* zero rms: nothing moves */
    memcpy(before, s, sizeof s);
    ck_assert_int_eq(wt_wfs_add_tiptilt(w, &rng, 0.0, s), WT_OK);
    ck_assert_mem_eq(s, before, sizeof(double) * ns);
    /* a negative rms is refused and leaves the slopes alone */
    ck_assert_int_eq(wt_wfs_add_tiptilt(w, &rng, -1e-6, s), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "rms = -1e-06"));
    ck_assert_mem_eq(s, before, sizeof(double) * ns);
    wt_wfs_free(w);
    wt_context_free(ctx);
}
END_TEST

static void expect_error(wt_context *ctx, double D, double obs, int n, double d, int p, const uint8_t *v, int m,
                         const char *needle)
{
    static wt_wfs *const sentinel = (wt_wfs *)1; /* alloc must reset *out to NULL */
    wt_wfs *w = sentinel;
    wt_error_clear(ctx);
    ck_assert_int_eq(wt_wfs_alloc(ctx, D, obs, n, d, p, v, m, WT_SH_TILT_G, &w), WT_ERR_INVALID);
    ck_assert_ptr_null(w);
    ck_assert_msg(strstr(wt_error_message(ctx), needle), "message '%s' does not name '%s'", wt_error_message(ctx),
                  needle);
}

START_TEST(test_bad_input)
{
    wt_context *ctx = tu_context();
    static uint8_t v[N * N], none[N * N];
    eelt_valid(v);
    expect_error(ctx, DIAM, OBS, N, DSUB, 0, v, 0, "p = 0");
    expect_error(ctx, DIAM, OBS, N, DSUB, -3, v, 0, "p = -3");
    expect_error(ctx, DIAM, OBS, N, DSUB, 1000, v, 0, "p = 1000");
    expect_error(ctx, DIAM, OBS, N, DSUB, P, v, 5, "m = 5");
    expect_error(ctx, DIAM, OBS, N, DSUB, P, v, 168, "m = 168");
    expect_error(ctx, DIAM, OBS, N, DSUB, P, v, -1, "m = -1");
    expect_error(ctx, 0.0, OBS, N, DSUB, P, v, 0, "D = 0");
    expect_error(ctx, DIAM, 1.0, N, DSUB, P, v, 0, "obstruction 1");
    expect_error(ctx, DIAM, -0.1, N, DSUB, P, v, 0, "obstruction -0.1");
    expect_error(ctx, DIAM, OBS, 0, DSUB, P, v, 0, "n = 0");
    expect_error(ctx, DIAM, OBS, N, 0.4, P, v, 0, "d = 0.4");
    expect_error(ctx, DIAM, OBS, N, DSUB, P, NULL, 0, "NULL");
    expect_error(ctx, DIAM, OBS, N, DSUB, P, none, 0, "none of the 84 x 84");
    /* a subaperture flagged valid outside the pupil has nothing to average */
    static uint8_t bad[N * N];
    memcpy(bad, v, sizeof bad);
    bad[0] = 1;
    expect_error(ctx, DIAM, OBS, N, DSUB, P, bad, 0, "subaperture (0, 0)");
    /* ... but an NGS quadrant that holds it is lit elsewhere: fine */
    wt_wfs *w = make(ctx, DIAM, OBS, N, P, bad, 2);
    wt_wfs_free(w);
    wt_wfs_free(NULL);
    wt_context_free(ctx);
}
END_TEST

/* Every allocation failure is reported as WT_ERR_NOMEM and leaks nothing. */
START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    uint8_t v[64];
    wt_pupil_valid_subapertures(4.0, 0.3, 8, 0.5, v);
    const int ms[2] = {0, 2};
    for (int t = 0; t < 2; t++) {
        int budget = 0, st;
        do {
            tu_alloc fa = TU_ALLOC_INIT;
            tu_alloc_budget(&fa, budget);
            tu_alloc_install(ctx, &fa);
            wt_wfs *w = NULL;
            st = wt_wfs_alloc(ctx, 4.0, 0.3, 8, 0.5, 3, v, ms[t], WT_SH_TILT_G, &w);
            if (st == WT_OK) {
                ck_assert_ptr_nonnull(w);
                wt_wfs_free(w);
            } else {
                ck_assert_int_eq(st, WT_ERR_NOMEM);
                ck_assert_ptr_null(w);
            }
            ck_assert_int_eq(fa.live, 0);
            budget++;
        } while (st != WT_OK && budget < 100);
        ck_assert_int_eq(st, WT_OK);
        ck_assert_int_gt(budget, 3);
    }
    wt_context_set_allocator(ctx, NULL, NULL, NULL);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("wfs");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_counts_and_layout);
    tcase_add_test(tc, test_piston_and_tilt);
    tcase_add_test(tc, test_definition_random);
    tcase_add_test(tc, test_quadratic);
    tcase_add_test(tc, test_model_agreement);
    tcase_add_test(tc, test_representable_screen);
    tcase_add_test(tc, test_tiptilt);
    tcase_add_test(tc, test_bad_input);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
