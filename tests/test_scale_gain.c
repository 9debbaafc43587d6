/* tests/test_scale_gain.c: the scale-dependent integrator gain G = Σ_j g_j Π_j (core/op/scale_gain.h), both
 * bases: equal gains give g x (bit for bit for the bilinear basis, to rounding through the Daubechies
 * transform); G is symmetric, with eigenvalues exactly the g_j (bilinear, multiplicities dim V_j − dim V_{j−1})
 * or in [min g, max g] (Daubechies) — the full matrix on the demo DMs, LAPACK; piston, tilt and saddle get
 * the coarse gain exactly (bilinear) or within the leakage the zero-padded embedding implies (Daubechies),
 * a smooth bump nearly so, the checkerboard the fine gain; bad parameters refused; allocation failures. */
#include <float.h>
#include <lapacke.h>

#include "core/config/config.h"
#include "core/op/dm.h"
#include "core/op/wavelet.h"
#include "core/op/scale_gain.h"
#include "testutil.h"

/* The demo preset's DMs (data/presets/demo.cfg): 19x19, 15x15, 23x23 grids with one guard ring, embedded
 * in 32, 16 and 32 points: at most 4 bands (L = 3), the coarsest squares 16 x 16. */
static wt_dm *demo_dms(wt_context *ctx)
{
    wt_dm_params p = {.ndms = 3,
                      .altitude = {0.0, 4000.0, 12700.0},
                      .pitch = {0.5, 1.0, 1.0},
                      .actuators = {17, 13, 21},
                      .guard_rings = 1,
                      .field_radius = 84.853 * WT_ARCSEC,
                      .diameter = 8.0};
    wt_dm *dm = NULL;
    ck_assert_msg(wt_dm_alloc(ctx, &p, &dm) == WT_OK, "%s", wt_error_message(ctx));
    return dm;
}

#define BIL WT_SCALE_GAIN_BILINEAR
#define DAU WT_SCALE_GAIN_DAUBECHIES
#define ORDER 3
#define LEVELS 3
/* Rounding of one forward + inverse DWT: each of the 2L one-dimensional passes per axis sums 2N
 * products, so a coefficient carries about 4 L · 2N roundings of relative size ε (a bound; the measured
 * error is ~10x smaller). */
#define DWT_TOL (4.0 * LEVELS * 2 * ORDER * DBL_EPSILON)
/* Rounding of the bilinear projections: per level, dot products over a square of at most b² = 256
 * actuators (b = 2^(L+1) = 16) with orthonormal columns: ≤ b² ε each, L levels. */
#define BIL_TOL (LEVELS * 256.0 * DBL_EPSILON)

static wt_scale_gain *make(wt_context *ctx, const wt_dm *dm, int basis, const double *g, int nb, int force)
{
    wt_scale_gain_params p = {.nbands = nb, .basis = basis, .wavelet_order = ORDER, .force_transform = force};
    for (int j = 0; j < nb; j++) p.gain[j] = g[j];
    wt_scale_gain *sg = NULL;
    ck_assert_msg(wt_scale_gain_alloc(ctx, dm, &p, &sg) == WT_OK, "%s", wt_error_message(ctx));
    return sg;
}

/* y = G x */
static void apply(const wt_scale_gain *sg, const wt_dm *dm, const double *x, double *y, double *work)
{
    memset(y, 0, (size_t)dm->nact * sizeof *y);
    wt_scale_gain_apply(sg, 1.0, x, y, work);
}

static double *work_for(const wt_scale_gain *sg) { return malloc((wt_scale_gain_work_size(sg) + 1) * sizeof(double)); }

/* Equal gains: the single-gain loop's next_k = prev_k + g e_k, bit for bit (bilinear: the projection terms
 * have coefficient 0; Daubechies: the scalar product unless forced). */
START_TEST(test_equal_gains_scalar_bits)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    const long n = dm->nact;
    double *x = malloc(n * sizeof *x), *prev = malloc(n * sizeof *prev), *y = malloc(n * sizeof *y);
    for (int basis = 0; basis < 2; basis++)
        for (int nb = 2; nb <= 4; nb++) {
            const double g[] = {0.4, 0.4, 0.4, 0.4};
            wt_scale_gain *sg = make(ctx, dm, basis, g, nb, 0);
            double *work = work_for(sg);
            tu_randn(x, n, 1);
            tu_randn(prev, n, 2);
            memcpy(y, prev, n * sizeof *y);
            wt_scale_gain_apply(sg, 1.0, x, y, work);
            for (long i = 0; i < n; i++) ck_assert_msg(y[i] == prev[i] + 0.4 * x[i], "basis %d, actuator %ld", basis, i);
            free(work);
            wt_scale_gain_free(sg);
        }
    free(x), free(prev), free(y);
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

/* Daubechies forced through the transform with equal gains: g x to the DWT's rounding. */
START_TEST(test_equal_gains_transform)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    const long n = dm->nact;
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *gx = malloc(n * sizeof *gx);
    for (int nb = 2; nb <= LEVELS + 1; nb++) {
        const double g[] = {0.37, 0.37, 0.37, 0.37};
        wt_scale_gain *sg = make(ctx, dm, DAU, g, nb, 1);
        ck_assert_int_eq(wt_scale_gain_levels(sg), nb - 1);
        ck_assert_int_eq(wt_scale_gain_grid(sg, 0), 32);
        ck_assert_int_eq(wt_scale_gain_grid(sg, 1), 16);
        ck_assert_int_eq(wt_scale_gain_grid(sg, 2), 32);
        double *work = work_for(sg);
        tu_randn(x, n, 3);
        apply(sg, dm, x, y, work);
        for (long i = 0; i < n; i++) gx[i] = 0.37 * x[i];
        ck_assert_msg(tu_rel_diff(y, gx, n) <= DWT_TOL, "L = %d: |Gx - gx| / |gx| = %.3g > %.3g", nb - 1,
                      tu_rel_diff(y, gx, n), DWT_TOL);
        free(work);
        wt_scale_gain_free(sg);
    }
    free(x), free(y), free(gx);
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

/* The whole matrix G on the demo DMs (759 actuators), gains 0.7 / 0.5 / 0.3 / 0.1: symmetric to rounding;
 * random Rayleigh quotients in [0.1, 0.7]; its eigenvalues (LAPACK dsyev, error ~ n ε |G| on top of G's own
 * rounding) in [0.1, 0.7], and for the bilinear basis exactly g_j with multiplicity dim V_j − dim V_{j−1}. */
START_TEST(test_symmetric_spectrum)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    const double g[] = {0.7, 0.5, 0.3, 0.1};
    const long n = dm->nact;
    double *G = malloc((size_t)n * n * sizeof *G), *e = calloc(n, sizeof *e), *ev = malloc(n * sizeof *ev);
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *gx = malloc(n * sizeof *gx),
           *gy = malloc(n * sizeof *gy);
    for (int basis = 0; basis < 2; basis++) {
        const double tol = basis == BIL ? BIL_TOL : DWT_TOL;
        wt_scale_gain *sg = make(ctx, dm, basis, g, 4, 0);
        double *work = work_for(sg);
        for (long j = 0; j < n; j++) {
            e[j] = 1.0;
            apply(sg, dm, e, G + (size_t)j * n, work); /* column j */
            e[j] = 0.0;
        }
        double asym = 0.0;
        for (long i = 0; i < n; i++)
            for (long j = 0; j < i; j++) asym = fmax(asym, fabs(G[i + (size_t)j * n] - G[j + (size_t)i * n]));
        ck_assert_msg(asym <= tol, "basis %d: max |G_ij - G_ji| = %.3g > %.3g", basis, asym, tol);
        for (int r = 0; r < 20; r++) {
            tu_randn(x, n, 100 + r);
            tu_randn(y, n, 200 + r);
            apply(sg, dm, x, gx, work);
            apply(sg, dm, y, gy, work);
            const double a = tu_dot(y, gx, n), b = tu_dot(x, gy, n), s = tu_norm(x, n) * tu_norm(y, n);
            ck_assert_msg(fabs(a - b) <= tol * s, "basis %d: yᵀGx = %.17g, xᵀGy = %.17g", basis, a, b);
            const double q = tu_dot(x, gx, n) / tu_dot(x, x, n);
            ck_assert_msg(q >= 0.1 - tol && q <= 0.7 + tol, "basis %d: Rayleigh quotient %.17g", basis, q);
        }
        ck_assert_int_eq(LAPACKE_dsyev(LAPACK_COL_MAJOR, 'N', 'U', (lapack_int)n, G, (lapack_int)n, ev), 0);
        const double etol = tol + 16.0 * n * DBL_EPSILON * 0.7;
        ck_assert_msg(ev[0] >= 0.1 - etol && ev[n - 1] <= 0.7 + etol, "basis %d: spectrum [%.17g, %.17g]", basis,
                      ev[0], ev[n - 1]);
        if (basis == BIL) { /* ascending: band 3 (0.1) first, band 0 (0.7) last */
            long i = 0;
            for (int j = 3; j >= 0; j--) {
                const int64_t mult = wt_scale_gain_dim(sg, j) - (j > 0 ? wt_scale_gain_dim(sg, j - 1) : 0);
                ck_assert(mult > 0);
                for (int64_t c = 0; c < mult; c++, i++)
                    ck_assert_msg(fabs(ev[i] - g[j]) <= etol, "eigenvalue %ld = %.17g, expected g_%d = %g", i, ev[i],
                                  j, g[j]);
            }
            ck_assert_int_eq(i, n);
        } else { /* the zero-padded DWT's spectrum fills the interval: every band meets the active set */
            ck_assert_msg(ev[0] < 0.1 + 1e-2 && ev[n - 1] > 0.7 - 1e-2, "spectrum [%.6g, %.6g]", ev[0], ev[n - 1]);
        }
        free(work);
        wt_scale_gain_free(sg);
    }
    free(x), free(y), free(gx), free(gy);
    free(G), free(e), free(ev);
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

/* |P x|² / |x|² for P the least-squares projection onto {1, x, y, xy} over DM k's active actuators
 * (LAPACK dgels: the residual of the fit), an implementation independent of the module's Gram–Schmidt. */
static double bilinear_fit_share(const wt_dm *dm, int k, const double *xk)
{
    const wt_grid *gr = &dm->grid[k];
    const int m = dm->nactive[k];
    double *A = malloc((size_t)m * 4 * sizeof *A), *b = malloc(m * sizeof *b), xx = 0.0;
    int i = 0;
    for (int iy = 0; iy < gr->ny; iy++)
        for (int ix = 0; ix < gr->nx; ix++) {
            if (!dm->active[k][ix + gr->nx * iy]) continue;
            const double px = gr->x0 + ix * gr->dx, py = gr->y0 + iy * gr->dx;
            A[i] = 1.0, A[i + m] = px, A[i + 2 * m] = py, A[i + 3 * m] = px * py;
            b[i] = xk[i], xx += xk[i] * xk[i];
            i++;
        }
    ck_assert_int_eq(LAPACKE_dgels(LAPACK_COL_MAJOR, 'N', m, 4, 1, A, m, b, m), 0);
    double rr = 0.0;
    for (i = 4; i < m; i++) rr += b[i] * b[i]; /* dgels leaves the residual's coordinates in b[4 … m) */
    free(A), free(b);
    return 1.0 - rr / xx;
}

/* Maps on each DM's active actuators, alone (the other DMs zero): piston, tilt, saddle xy, a smooth bump
 * (1 − r²/R²)² that vanishes with its slope at the edge of the active disk, and the checkerboard. With
 * gains 0.6 on band 0 and 0.3 on the others, G x − 0.6 x = −0.3 (I − Π_0) x: xᵀGx/xᵀx = 0.3 + 0.3 f0 with
 * f0 = |Π_0 x|²/|x|², and |G x − 0.6 x| = 0.3 sqrt(1 − f0) |x| (Π_0 an orthogonal projection; Daubechies:
 * an upper bound, its Π_0 = M Wᵀ Λ_0 W Mᵀ is not idempotent).
 * Bilinear: piston, tilt and saddle are bilinear over every square, f0 = 1 to rounding; the bump is smooth
 * and, where the coarsest squares (16 actuators) tile the DM two or more across, nearly bilinear on each
 * (measured f0 0.99 on DMs 1 and 3) > 0.95; on DM 2 one square holds the whole 15x15 grid, band 0 is the
 * global fit by 1, x, y, xy, and f0 is that fit's share (0.54: the bump is radial).
 * Daubechies: f0 of the tilt is what the zero-padded, periodic embedding keeps (measured 0.49, 0.0035,
 * 0.69 on the three DMs: the edge is a step, and DM 2's grid fills its 16 points so the periodic wrap
 * is one more) — recorded, not bounded below: that leakage is why the bilinear basis is the default.
 * Both: the checkerboard (the finest pattern) has f0 < 0.01. */
START_TEST(test_coarse_and_fine_modes)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    const double g[] = {0.6, 0.3, 0.3, 0.3};
    const long n = dm->nact;
    double *x = calloc(n, sizeof *x), *gx = malloc(n * sizeof *gx);
    for (int basis = 0; basis < 2; basis++) {
        const double tol = basis == BIL ? BIL_TOL : DWT_TOL;
        wt_scale_gain *sg = make(ctx, dm, basis, g, 4, 0);
        double *work = work_for(sg);
        for (int k = 0; k < dm->ndms; k++) {
            const wt_grid *gr = &dm->grid[k];
            double rmax = 0.0;
            for (int iy = 0; iy < gr->ny; iy++)
                for (int ix = 0; ix < gr->nx; ix++)
                    if (dm->active[k][ix + gr->nx * iy])
                        rmax = fmax(rmax, hypot(gr->x0 + ix * gr->dx, gr->y0 + iy * gr->dx));
            for (int mode = 0; mode < 5; mode++) {
                memset(x, 0, n * sizeof *x);
                double *xk = x + dm->offset[k];
                long i = 0;
                for (int iy = 0; iy < gr->ny; iy++)
                    for (int ix = 0; ix < gr->nx; ix++) {
                        if (!dm->active[k][ix + gr->nx * iy]) continue;
                        const double px = gr->x0 + ix * gr->dx, py = gr->y0 + iy * gr->dx;
                        const double r2 = (px * px + py * py) / (1.0001 * rmax * rmax);
                        xk[i++] = mode == 0   ? 1.0
                                  : mode == 1 ? px + 0.3 * py
                                  : mode == 2 ? px * py
                                  : mode == 3 ? (1.0 - r2) * (1.0 - r2)
                                              : ((ix + iy) & 1 ? 1.0 : -1.0);
                    }
                apply(sg, dm, x, gx, work);
                const double xx = tu_dot(x, x, n), q = tu_dot(x, gx, n) / xx, f0 = (q - 0.3) / 0.3;
                double d = 0.0;
                for (long j = 0; j < n; j++) d += (gx[j] - 0.6 * x[j]) * (gx[j] - 0.6 * x[j]);
                const double leak = sqrt(d / xx);
                if (basis == BIL)
                    ck_assert_msg(fabs(leak - 0.3 * sqrt(fmax(0.0, 1.0 - f0))) <= sqrt(tol),
                                  "DM %d mode %d: |Gx - 0.6x|/|x| = %.6g, 0.3 sqrt(1 - f0) = %.6g", k + 1, mode, leak,
                                  0.3 * sqrt(fmax(0.0, 1.0 - f0)));
                else
                    ck_assert_msg(leak <= 0.3 * sqrt(fmax(0.0, 1.0 - f0)) + tol, "DM %d mode %d: leakage %.6g", k + 1,
                                  mode, leak);
                if (basis == BIL && mode <= 2)
                    ck_assert_msg(leak <= tol, "DM %d mode %d: bilinear map leaks %.3g", k + 1, mode, leak);
                if (basis == BIL && mode == 3) {
                    if (wt_scale_gain_grid(sg, k) >= 4 << LEVELS) /* two or more coarsest squares across */
                        ck_assert_msg(f0 > 0.95, "DM %d: bump coarse share %.4f", k + 1, f0);
                    else /* one square holds the DM: band 0 is its global bilinear fit, computed here by LAPACK */
                        ck_assert_msg(fabs(f0 - bilinear_fit_share(dm, k, xk)) <= 1e-10, "DM %d: bump f0 %.12f vs the "
                                      "least-squares share %.12f", k + 1, f0, bilinear_fit_share(dm, k, xk));
                }
                if (mode == 4) ck_assert_msg(f0 < 0.01, "basis %d DM %d: checkerboard coarse share %.4f", basis, k + 1, f0);
                if (getenv("WT_TEST_VERBOSE"))
                    printf("basis %d DM %d mode %d: coarse share f0 %.4f, gain %.4f\n", basis, k + 1, mode, f0, q);
            }
        }
        free(work);
        wt_scale_gain_free(sg);
    }
    free(x), free(gx);
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_bad_parameters)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    for (int basis = 0; basis < 2; basis++) {
        wt_scale_gain *sg = (wt_scale_gain *)&sg;
        wt_scale_gain_params p = {.nbands = 4, .gain = {0.6, 0.4, 0.0, 0.4}, .basis = basis, .wavelet_order = ORDER};
        ck_assert_int_eq(wt_scale_gain_alloc(ctx, dm, &p, &sg), WT_ERR_INVALID);
        ck_assert_ptr_null(sg);
        ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "band 2"));
        p.gain[2] = 1.2;
        ck_assert_int_eq(wt_scale_gain_alloc(ctx, dm, &p, &sg), WT_ERR_INVALID);
        p = (wt_scale_gain_params){.nbands = 1, .gain = {0.4}, .basis = basis, .wavelet_order = ORDER};
        ck_assert_int_eq(wt_scale_gain_alloc(ctx, dm, &p, &sg), WT_ERR_INVALID);
        /* 5 bands: squares of 32, but DM 2's 15x15 grid embeds in 16 points */
        p = (wt_scale_gain_params){.nbands = 5, .gain = {0.6, 0.5, 0.4, 0.4, 0.3}, .basis = basis, .wavelet_order = ORDER};
        ck_assert_int_eq(wt_scale_gain_alloc(ctx, dm, &p, &sg), WT_ERR_INVALID);
        ck_assert_msg(strstr(wt_error_message(ctx), "DM 2") && strstr(wt_error_message(ctx), "at most 4 bands"), "%s",
                      wt_error_message(ctx));
    }
    wt_scale_gain *sg = (wt_scale_gain *)&sg;
    wt_scale_gain_params p = {.nbands = 3, .gain = {0.6, 0.5, 0.4}, .basis = 2};
    ck_assert_int_eq(wt_scale_gain_alloc(ctx, dm, &p, &sg), WT_ERR_INVALID);
    p.basis = DAU; /* a bad wavelet order surfaces from the wavelet plan */
    ck_assert_int_lt(wt_scale_gain_alloc(ctx, dm, &p, &sg), 0);
    ck_assert_ptr_null(sg);
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

/* Every allocation failure of the plan surfaces as WT_ERR_NOMEM and leaks nothing. */
START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    wt_dm *dm = demo_dms(ctx);
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    for (int basis = 0; basis < 2; basis++) {
        wt_scale_gain_params p = {.nbands = 4, .gain = {0.6, 0.5, 0.4, 0.3}, .basis = basis, .wavelet_order = ORDER};
        const long live0 = fa.live;
        int ok = 0;
        for (long b = 0; b < 200 && !ok; b++) {
            wt_scale_gain *sg = NULL;
            tu_alloc_budget(&fa, b);
            int st = wt_scale_gain_alloc(ctx, dm, &p, &sg);
            if (st == WT_OK) {
                ok = 1;
                wt_scale_gain_free(sg);
            } else {
                ck_assert_int_eq(st, WT_ERR_NOMEM);
                ck_assert_ptr_null(sg);
            }
            ck_assert_int_eq(fa.live, live0);
        }
        ck_assert(ok);
        tu_alloc_budget(&fa, -1);
    }
    wt_dm_free(dm);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("scale_gain");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_equal_gains_scalar_bits);
    tcase_add_test(tc, test_equal_gains_transform);
    tcase_add_test(tc, test_symmetric_spectrum);
    tcase_add_test(tc, test_coarse_and_fine_modes);
    tcase_add_test(tc, test_bad_parameters);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
