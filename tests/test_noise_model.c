/* tests/test_noise_model.c: the Shack–Hartmann noise model (core/op/noise.c): the assembled matrix, the variance
 * and elongation formulas and the loop gain against hand computations, sampling statistics, the NEA along the
 * short axis, the blocks' allocation, and rejected input. */
#include "noise_fixture.h"

START_TEST(test_assemble)
{
    wt_context *ctx = tu_context();
    const int nsub = 300, ns = 2 * nsub;
    wt_noise *n = make_noise(ctx, nsub, 0.8, 1);
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_noise_assemble_inv(n, &A), WT_OK);
    ck_assert_int_eq(A->nrow, ns);
    ck_assert_int_eq(A->ncol, ns);
    ck_assert_int_eq(wt_sparse_nnz(A), 4 * nsub); /* 2x2 blocks, all off-diagonals non-zero here */
    double *x = malloc(ns * sizeof *x), *y = calloc(ns, sizeof *y), *z = calloc(ns, sizeof *z);
    tu_randn(x, ns, 41);
    wt_sparse_apply(A, 1.0, x, y);
    wt_noise_apply_inv(n, 1.0, x, z);
    ck_assert_double_le(tu_rel_diff(y, z, ns), 1e-15);
    /* block i sits at rows/cols (i, nsub + i) */
    double a, b, c;
    wt_noise_inv_block(n, 17, &a, &b, &c);
    int64_t col = nsub + 17, found = 0;
    for (int64_t k = A->colptr[col]; k < A->colptr[col + 1]; k++) {
        if (A->rowind[k] == 17) {
            ck_assert_double_eq(A->val[k], b);
            found++;
        }
        if (A->rowind[k] == nsub + 17) {
            ck_assert_double_eq(A->val[k], c);
            found++;
        }
    }
    ck_assert_int_eq(found, 2);
    ck_assert_int_eq(A->colptr[col + 1] - A->colptr[col], 2);
    free(x), free(y), free(z);
    wt_sparse_free(A);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_variance_formula)
{
    /* E-ELT LGS: θf = 1.1″, p = 1″, Ns = 4, N = 100, σe = 3. By hand, in arcsec²:
     *   θf²/(8 ln2 N) = 1.21 / (800 × 0.693147) = 0.00218208
     *   p² σe² Ns⁴/(12 N²) = 1 × 9 × 256 / 120000 = 0.0192
     *   σ² = 0.0213821 arcsec² = 5.02574e-13 rad², σ = 0.146226″ = 146.23 mas rms per axis. */
    double s2 = wt_noise_variance(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, 0.0);
    ck_assert_rel(s2 / (ARCSEC * ARCSEC), 0.00218208 + 0.0192, 1e-6, 0); /* 6 digits typed */
    ck_assert_rel(s2, 5.02574e-13, 1e-5, 0);
    ck_assert_rel(sqrt(s2) / ARCSEC * 1e3, 146.226, 1e-5, 0);
    /* photon-noise term alone (σe = 0) scales as 1/N, read-noise term as 1/N² */
    ck_assert_rel(wt_noise_variance(50.0, 0.0, LGS_FWHM, LGS_PIXEL, 4, 0.0),
                  2.0 * wt_noise_variance(100.0, 0.0, LGS_FWHM, LGS_PIXEL, 4, 0.0), 1e-15, 0);
    /* NEA overrides: 10 mas rms → (10 mas)² */
    double nea = 0.010 * ARCSEC;
    ck_assert_rel(wt_noise_variance(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, nea), nea * nea, 1e-15, 0);
    /* no photons, no NEA: no information */
    ck_assert(isinf(wt_noise_variance(0.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, 0.0)));
}
END_TEST

/* The loop's noise gain against the variances of the closed forms: delay 1 is an AR(1) of coefficient
 * 1 − g driven by g n, Σh² = g/(2 − g); delay 2 the AR(2) y_t = y_{t−1} − g y_{t−2} + g n_{t−2}, whose
 * variance (1 − φ2) σ² / ((1 + φ2)((1 − φ2)² − φ1²)) with φ1 = 1, φ2 = −g is g(1 + g)/((1 − g)(2 + g));
 * g = 1, delay 1 passes each frame's noise whole. */
START_TEST(test_loop_gain)
{
    for (double g = 0.1; g < 0.95; g += 0.1) {
        ck_assert_rel(wt_noise_loop_gain(g, 1), g / (2.0 - g), 1e-12, 0.0);
        ck_assert_rel(wt_noise_loop_gain(g, 2), g * (1.0 + g) / ((1.0 - g) * (2.0 + g)), 1e-12, 0.0);
    }
    ck_assert_rel(wt_noise_loop_gain(0.4, 2), 7.0 / 18.0, 1e-12, 0.0);
    ck_assert_rel(wt_noise_loop_gain(1.0, 1), 1.0, 1e-15, 0.0);
}
END_TEST

START_TEST(test_elongation_hand)
{
    /* Launch at (22, 0) m, Δh = 10 km, H = 90 km: β = (r − l) Δh / H².
     * r = (21, 0):  β = (−1 × 1e4 / 8.1e9, 0) = (−1.2345679e-6, 0) rad = −0.2546″ (a short spot);
     * r = (−21, 5): β = (−43, 5) × 1e4 / 8.1e9 = (−5.3086420e-5, 6.1728395e-6) rad (−10.95″ along x). */
    double cx[2] = {21.0, -21.0}, cy[2] = {0.0, 5.0}, beta[4];
    wt_noise_elongation(2, cx, cy, 22.0, 0.0, 10e3, 90e3, beta);
    ck_assert_rel(beta[0], -1.2345679e-6, 1e-7, 0);
    ck_assert_double_eq(beta[2], 0.0);
    ck_assert_rel(beta[1], -5.3086420e-5, 1e-7, 0);
    ck_assert_rel(beta[3], 6.1728395e-6, 1e-7, 0);
    ck_assert_rel(beta[1] / ARCSEC, -10.9499, 1e-5, 0);
    /* zero sodium thickness: no elongation */
    wt_noise_elongation(2, cx, cy, 22.0, 0.0, 0.0, 90e3, beta);
    for (int i = 0; i < 4; i++) ck_assert_double_eq(beta[i], 0.0);
}
END_TEST

START_TEST(test_sampling)
{
    /* 200000 draws of a 2-subaperture sensor: block 0 round, block 1 strongly elongated (τ = 1, the
     * truth). The sample covariance S = (1/N) Σ x xᵀ (mean known to be 0) has standard errors
     * sd(S_ii) = √(2/N) C_ii and sd(S_ij) = √((C_ii C_jj + C_ij²)/N); each entry must be within 6 of them
     * (a false alarm has probability ~1e-8 per entry, a wrong factor misses by hundreds). */
    wt_context *ctx = tu_context();
    const double s2 = sigma2_lgs(), g = 1.0 / (LGS_FWHM * LGS_FWHM);
    double beta[4] = {0.0, -3.0e-5, 0.0, 2.0e-5}; /* [βx0, βx1, βy0, βy1] */
    wt_noise *n = NULL;
    ck_assert_int_eq(wt_noise_alloc(ctx, 2, s2, LGS_FWHM, beta, 1.0, 0, &n), WT_OK);
    /* hand covariance in the order (x0, x1, y0, y1) */
    double C[4][4] = {{0}};
    C[0][0] = C[2][2] = s2;
    C[1][1] = s2 * (1 + g * beta[1] * beta[1]);
    C[3][3] = s2 * (1 + g * beta[3] * beta[3]);
    C[1][3] = C[3][1] = s2 * g * beta[1] * beta[3];
    const int N = 200000;
    double S[4][4] = {{0}};
    wt_rng rng;
    wt_rng_init(&rng, 12345, 3);
    for (int k = 0; k < N; k++) {
        double x[4] = {0, 0, 0, 0};
        wt_noise_sample(n, &rng, x);
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) S[i][j] += x[i] * x[j];
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            S[i][j] /= N;
            double se = (i == j) ? sqrt(2.0 / N) * C[i][i] : sqrt((C[i][i] * C[j][j] + C[i][j] * C[i][j]) / N);
            ck_assert_msg(fabs(S[i][j] - C[i][j]) <= 6.0 * se, "S[%d][%d] = %g vs C = %g (se %g)", i, j, S[i][j],
                          C[i][j], se);
        }
    /* the elongated block is really correlated (ρ ≈ −0.8), so the check above has teeth */
    ck_assert_double_lt(C[1][3] / sqrt(C[1][1] * C[3][3]), -0.5);
    /* sampling adds to x */
    double x[4] = {1, 1, 1, 1};
    wt_rng_init(&rng, 1, 1);
    wt_noise_sample(n, &rng, x);
    wt_rng_init(&rng, 1, 1);
    double z[4] = {0, 0, 0, 0};
    wt_noise_sample(n, &rng, z);
    for (int i = 0; i < 4; i++) ck_assert_double_eq(x[i], 1.0 + z[i]);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

static void expect_reject(wt_context *ctx, int nsub, double s2, double fwhm, const double *beta, double tau,
                          const char *word)
{
    wt_noise *n = (wt_noise *)&n; /* must be overwritten with NULL */
    wt_error_clear(ctx);
    int st = wt_noise_alloc(ctx, nsub, s2, fwhm, beta, tau, 1, &n);
    ck_assert_int_eq(st, WT_ERR_INVALID);
    ck_assert_ptr_null(n);
    ck_assert_msg(strstr(wt_error_message(ctx), word) != NULL, "message '%s' does not name '%s'",
                  wt_error_message(ctx), word);
    ck_assert_msg(strstr(wt_error_message(ctx), "expected") != NULL, "message '%s' does not say what is accepted",
                  wt_error_message(ctx));
}

START_TEST(test_nea_is_short_axis)
{
    /* The NEA is the per-axis noise of the unelongated spot (SPEC §4, README): with elongation the
     * variance across β stays NEA² (times the lit factor c) and along β grows to NEA² c (1 + |β|²/θf²)
     * in the truth (τ = 1). 200000 draws: the sample variances have standard error √(2/N) var, each
     * checked within 6 of it (a wrong meaning, e.g. NEA of the elongated spot, misses by a factor ~2). */
    wt_context *ctx = tu_context();
    const double nea = 30e-3 * ARCSEC;
    /* the NEA replaces the photon model whatever the photons */
    ck_assert_double_eq(wt_noise_variance(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, nea), nea * nea);
    ck_assert_double_eq(wt_noise_variance(1.0, 30.0, LGS_FWHM, LGS_PIXEL, 4, nea), nea * nea);
    /* subaperture 0 fully lit and elongated at 30° (|β| = 1.5 θf), 1 lit at 40 % and elongated at 120° */
    const double b0 = 1.5 * LGS_FWHM, b1 = 0.8 * LGS_FWHM, lit1 = 0.4;
    double beta[4] = {b0 * cos(M_PI / 6), b1 * cos(2 * M_PI / 3), b0 * sin(M_PI / 6), b1 * sin(2 * M_PI / 3)};
    double scale[2] = {wt_noise_lit_factor(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, nea, 1.0),
                       wt_noise_lit_factor(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, nea, lit1)};
    ck_assert_double_eq(scale[0], 1.0);
    ck_assert_rel(scale[1], 1.0 / lit1, 1e-15, 0);
    wt_noise *n = NULL;
    ck_assert_int_eq(wt_noise_alloc_scaled(ctx, 2, nea * nea, scale, LGS_FWHM, beta, 1.0, 0, &n), WT_OK);
    const int N = 200000;
    double along[2] = {0, 0}, across[2] = {0, 0};
    wt_rng rng;
    wt_rng_init(&rng, 777, 1);
    for (int k = 0; k < N; k++) {
        double x[4] = {0, 0, 0, 0};
        wt_noise_sample(n, &rng, x);
        for (int i = 0; i < 2; i++) {
            double b = hypot(beta[i], beta[2 + i]), ux = beta[i] / b, uy = beta[2 + i] / b;
            double a = x[i] * ux + x[2 + i] * uy, c = -x[i] * uy + x[2 + i] * ux;
            along[i] += a * a;
            across[i] += c * c;
        }
    }
    double mean_var = 0.0;
    for (int i = 0; i < 2; i++) {
        double b2 = beta[i] * beta[i] + beta[2 + i] * beta[2 + i];
        double va = nea * nea * scale[i] * (1.0 + b2 / (LGS_FWHM * LGS_FWHM)), vc = nea * nea * scale[i];
        mean_var += 0.5 * (va + vc) / 2;
        ck_assert_msg(fabs(across[i] / N - vc) <= 6.0 * sqrt(2.0 / N) * vc, "sub %d across: %g vs %g", i,
                      across[i] / N, vc);
        ck_assert_msg(fabs(along[i] / N - va) <= 6.0 * sqrt(2.0 / N) * va, "sub %d along: %g vs %g", i,
                      along[i] / N, va);
    }
    /* (tr C̃)/2 averaged over subapertures: what the result file reports as noise_rms_mas² */
    ck_assert_rel(wt_noise_mean_variance(n), mean_var, 1e-14, 0);
    /* the photon model: f N photons, σ² = θf²/(8 ln2 f N) + p² σe² Ns⁴/(12 f² N²) */
    double f = 0.3, v1 = wt_noise_variance(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, 0.0);
    double vf = LGS_FWHM * LGS_FWHM / (8 * log(2.0) * 30.0) + LGS_PIXEL * LGS_PIXEL * 9.0 * 256.0 / (12.0 * 900.0);
    ck_assert_rel(wt_noise_lit_factor(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, 0.0, f), vf / v1, 1e-14, 0);
    /* a bad factor is refused */
    wt_noise *bad = NULL;
    scale[1] = 0.0;
    ck_assert_int_eq(wt_noise_alloc_scaled(ctx, 2, nea * nea, scale, LGS_FWHM, beta, 1.0, 0, &bad), WT_ERR_INVALID);
    ck_assert_ptr_null(bad);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

/* wt_noise_alloc_blocks (diffractive sensors' calibrated covariances): the blocks σ²(I + ββᵀ/θf²) given
 * explicitly reproduce wt_noise_alloc's model for every τ (τ scales the part beyond the short axis σ²,
 * exactly the paper's τ/θf² ββᵀ), to rounding (1e-12 relative: a few operations per block, condition
 * ≲ 100); the inverse blocks invert; a block that is not positive definite, or NaN, is refused naming its
 * subaperture. */
START_TEST(test_alloc_blocks)
{
    wt_context *ctx = tu_context();
    const int nsub = 500, ns = 2 * nsub;
    double *beta = malloc(ns * sizeof *beta), *cov = malloc(3 * nsub * sizeof *cov);
    make_beta(nsub, beta, 9);
    const double s2 = sigma2_lgs(), g = 1.0 / (LGS_FWHM * LGS_FWHM);
    for (int i = 0; i < nsub; i++) {
        const double bx = beta[i], by = beta[nsub + i];
        cov[i] = s2 * (1 + g * bx * bx), cov[nsub + i] = s2 * g * bx * by, cov[2 * nsub + i] = s2 * (1 + g * by * by);
    }
    const double taus[] = {0.0, 0.4, 0.8, 1.0};
    for (int t = 0; t < 4; t++) {
        wt_noise *a = NULL, *b = NULL;
        ck_assert_int_eq(wt_noise_alloc(ctx, nsub, s2, LGS_FWHM, beta, taus[t], 1, &a), WT_OK);
        ck_assert_int_eq(wt_noise_alloc_blocks(ctx, nsub, cov, taus[t], 1, &b), WT_OK);
        double *x = malloc(ns * sizeof *x), *ya = calloc(ns, sizeof *ya), *yb = calloc(ns, sizeof *yb), *z = calloc(ns, sizeof *z);
        tu_randn(x, ns, 30 + t);
        wt_noise_apply_cov(a, 1.0, x, ya);
        wt_noise_apply_cov(b, 1.0, x, yb);
        ck_assert_double_le(tu_rel_diff(yb, ya, ns), 1e-12);
        memset(ya, 0, ns * sizeof *ya), memset(yb, 0, ns * sizeof *yb);
        wt_noise_apply_weight(a, 1.0, x, ya);
        wt_noise_apply_weight(b, 1.0, x, yb);
        ck_assert_double_le(tu_rel_diff(yb, ya, ns), 1e-12);
        memset(yb, 0, ns * sizeof *yb);
        wt_noise_apply_inv(b, 1.0, x, yb);
        wt_noise_apply_cov(b, 1.0, yb, z);
        ck_assert_double_le(tu_rel_diff(z, x, ns), 1e-12);
        free(x), free(ya), free(yb), free(z);
        wt_noise_free(a), wt_noise_free(b);
    }
    wt_noise *n = NULL;
    cov[nsub + 17] = sqrt(cov[17] * cov[2 * nsub + 17]); /* singular block */
    ck_assert_int_eq(wt_noise_alloc_blocks(ctx, nsub, cov, 0.8, 1, &n), WT_ERR_INVALID);
    ck_assert_ptr_null(n);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "subaperture 17"));
    cov[nsub + 17] = NAN;
    ck_assert_int_eq(wt_noise_alloc_blocks(ctx, nsub, cov, 0.8, 1, &n), WT_ERR_INVALID);
    free(beta), free(cov);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_bad_input)
{
    wt_context *ctx = tu_context();
    const double s2 = 1e-13, f = LGS_FWHM;
    double beta[4] = {1e-6, 2e-6, NAN, 0};
    expect_reject(ctx, 0, s2, f, NULL, 0.8, "nsub");
    expect_reject(ctx, -3, s2, f, NULL, 0.8, "nsub");
    expect_reject(ctx, 2, 0.0, f, NULL, 0.8, "sigma2");
    expect_reject(ctx, 2, -1e-13, f, NULL, 0.8, "sigma2");
    expect_reject(ctx, 2, NAN, f, NULL, 0.8, "sigma2");
    expect_reject(ctx, 2, INFINITY, f, NULL, 0.8, "sigma2");
    expect_reject(ctx, 2, s2, f, NULL, -0.1, "tau");
    expect_reject(ctx, 2, s2, f, NULL, 1.1, "tau");
    expect_reject(ctx, 2, s2, f, NULL, NAN, "tau");
    expect_reject(ctx, 2, s2, 0.0, NULL, 0.8, "FWHM");
    expect_reject(ctx, 2, s2, -f, NULL, 0.8, "FWHM");
    expect_reject(ctx, 2, s2, f, beta, 0.8, "elongation");
    /* the edges of the accepted ranges are accepted */
    wt_noise *n = NULL;
    ck_assert_int_eq(wt_noise_alloc(ctx, 1, s2, f, NULL, 0.0, 0, &n), WT_OK);
    wt_noise_free(n);
    ck_assert_int_eq(wt_noise_alloc(ctx, 1, s2, f, NULL, 1.0, 0, &n), WT_OK);
    wt_noise_free(n);
    wt_noise_free(NULL);
    wt_context_free(ctx);
}
END_TEST

/* Allocation failure: every allocation of alloc and assemble_inv fails in turn; each must report
 * WT_ERR_NOMEM and leak nothing (ASan run). */
START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    double beta[6] = {1e-6, 2e-6, 3e-6, -1e-6, 0, 1e-6};
    int failures = 0;
    for (int k = 0; k < 20; k++) {
        tu_alloc f = TU_ALLOC_INIT;
        tu_alloc_fail_nth(&f, k);
        tu_alloc_install(ctx, &f);
        wt_noise *n = NULL;
        wt_sparse *A = NULL;
        int st = wt_noise_alloc(ctx, 3, 1e-13, LGS_FWHM, beta, 0.8, 1, &n);
        if (st == WT_OK) st = wt_noise_assemble_inv(n, &A);
        if (st != WT_OK) {
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            ck_assert_ptr_null(A);
            failures++;
        }
        wt_sparse_free(A);
        wt_noise_free(n);
        if (f.count <= k) break; /* every allocation has been made to fail once */
    }
    ck_assert_int_ge(failures, 3);
    wt_context_free(ctx);
}
END_TEST
Suite *make_suite(void)
{
    Suite *s = suite_create("noise_model");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_assemble);
    tcase_add_test(tc, test_variance_formula);
    tcase_add_test(tc, test_elongation_hand);
    tcase_add_test(tc, test_loop_gain);
    tcase_add_test(tc, test_sampling);
    tcase_add_test(tc, test_nea_is_short_axis);
    tcase_add_test(tc, test_alloc_blocks);
    tcase_add_test(tc, test_bad_input);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
