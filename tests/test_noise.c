/* tests/test_noise.c: the Shack–Hartmann noise model (core/op/noise.c): C̃ and its inverse, the
 * tip-tilt and focus projections and the LGS weight Ĉ⁻¹, in double and in float (the assembled matrix, the
 * formulas, sampling and rejected input: test_noise_model.c). */
#include "noise_fixture.h"

/* x − (I − T) x = T x */
static void apply_T(const wt_noise *n, const double *x, double *tx)
{
    int ns = wt_noise_nslopes(n);
    double *u = malloc((size_t)ns * sizeof *u);
    memcpy(u, x, (size_t)ns * sizeof *u);
    wt_noise_remove_tt(n, u);
    for (int i = 0; i < ns; i++) tx[i] = x[i] - u[i];
    free(u);
}

START_TEST(test_cov_inverse)
{
    /* C̃ C̃⁻¹ x = x and C̃⁻¹ C̃ x = x. The blocks have condition number 1 + γ|β|² ≲ 100, so the round
     * trip loses at most ~100 ε ≈ 2e-14 per entry: 1e-12 leaves margin and still catches any wrong
     * inverse-block formula (which errs at O(1)). */
    wt_context *ctx = tu_context();
    const int nsub = 1000, ns = 2 * nsub;
    wt_noise *n = make_noise(ctx, nsub, 0.8, 0);
    ck_assert_int_eq(wt_noise_nslopes(n), ns);
    double *x = malloc(ns * sizeof *x), *y = calloc(ns, sizeof *y), *z = calloc(ns, sizeof *z);
    tu_randn(x, ns, 11);
    wt_noise_apply_inv(n, 1.0, x, y);
    wt_noise_apply_cov(n, 1.0, y, z);
    ck_assert_double_le(tu_rel_diff(z, x, ns), 1e-12);
    memset(y, 0, ns * sizeof *y);
    memset(z, 0, ns * sizeof *z);
    wt_noise_apply_cov(n, 1.0, x, y);
    wt_noise_apply_inv(n, 1.0, y, z);
    ck_assert_double_le(tu_rel_diff(z, x, ns), 1e-12);
    /* the blocks must really couple x and y (else the test above proves little) */
    double a, b, c;
    wt_noise_inv_block(n, 3, &a, &b, &c);
    ck_assert_double_gt(fabs(b), 1e-3 * fmin(a, c));
    /* y <- y + α A x accumulates: 2 C̃⁻¹ x − C̃⁻¹ x = C̃⁻¹ x */
    double *w = calloc(ns, sizeof *w), *v = calloc(ns, sizeof *v);
    wt_noise_apply_inv(n, 2.0, x, w);
    wt_noise_apply_inv(n, -1.0, x, w);
    wt_noise_apply_inv(n, 1.0, x, v);
    ck_assert_double_le(tu_rel_diff(w, v, ns), 1e-15 * 10);
    free(w), free(v), free(x), free(y), free(z);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_inv_block_hand)
{
    /* One block from the hand formula σ²(I + (τ/θf²)ββᵀ); inv_block times it must be I. */
    wt_context *ctx = tu_context();
    double beta[2] = {3e-5, -2e-5}, s2 = 2e-13, tau = 0.8, g = tau / (LGS_FWHM * LGS_FWHM);
    wt_noise *n = NULL;
    ck_assert_int_eq(wt_noise_alloc(ctx, 1, s2, LGS_FWHM, beta, tau, 0, &n), WT_OK);
    double C11 = s2 * (1 + g * beta[0] * beta[0]), C12 = s2 * g * beta[0] * beta[1],
           C22 = s2 * (1 + g * beta[1] * beta[1]);
    double a, b, c;
    wt_noise_inv_block(n, 0, &a, &b, &c);
    /* products of O(1) quantities, each exact to a few ulp */
    ck_assert_rel(a * C11 + b * C12, 1.0, 1e-14, 1.0);
    ck_assert_rel(a * C12 + b * C22, 0.0, 1e-14, 1.0);
    ck_assert_rel(b * C12 + c * C22, 1.0, 1e-14, 1.0);
    /* apply_cov gives the same block */
    double x[2] = {1, 0}, y[2] = {0, 0};
    wt_noise_apply_cov(n, 1.0, x, y);
    ck_assert_rel(y[0], C11, 1e-14, 0);
    ck_assert_rel(y[1], C12, 1e-14, 0);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_tt_projection)
{
    wt_context *ctx = tu_context();
    const int nsub = 357, ns = 2 * nsub;
    wt_noise *n = make_noise(ctx, nsub, 0.8, 1);
    double *x = malloc(ns * sizeof *x), *y = malloc(ns * sizeof *y), *tx = malloc(ns * sizeof *tx),
           *ty = malloc(ns * sizeof *ty), *ttx = malloc(ns * sizeof *ttx);
    tu_randn(x, ns, 21);
    tu_randn(y, ns, 22);
    for (int i = 0; i < ns; i++) x[i] += 3.0; /* a non-zero mean, so T x is not trivially 0 */
    apply_T(n, x, tx);
    apply_T(n, y, ty);
    apply_T(n, tx, ttx);
    /* T² = T (round-off of a mean over n terms: ~n ε relative) */
    ck_assert_double_le(tu_rel_diff(ttx, tx, ns), 1e-13);
    /* Tᵀ = T: <Tx, y> = <x, Ty> */
    ck_assert_rel(tu_dot(tx, y, ns), tu_dot(x, ty, ns), 1e-12, 0);
    /* T x must be the means: x-part constant, y-part constant */
    double mx = 0, my = 0;
    for (int i = 0; i < nsub; i++) mx += x[i], my += x[nsub + i];
    mx /= nsub, my /= nsub;
    ck_assert_rel(tx[5], mx, 1e-13, 0);
    ck_assert_rel(tx[nsub + 5], my, 1e-13, 0);

    /* a global tip-tilt s_x = a, s_y = b is removed exactly (to round-off relative to |a|, |b|) */
    const double a = 3.7e-6, b = -1.3e-6;
    for (int i = 0; i < nsub; i++) x[i] = a, x[nsub + i] = b;
    wt_noise_remove_tt(n, x);
    for (int i = 0; i < nsub; i++) {
        ck_assert_double_le(fabs(x[i]), 1e-14 * fabs(a));
        ck_assert_double_le(fabs(x[nsub + i]), 1e-14 * fabs(b));
    }
    /* a zero-mean vector (per axis) is unchanged */
    tu_randn(x, ns, 23);
    double sx = 0, sy = 0;
    for (int i = 0; i < nsub; i++) sx += x[i], sy += x[nsub + i];
    for (int i = 0; i < nsub; i++) x[i] -= sx / nsub, x[nsub + i] -= sy / nsub;
    memcpy(y, x, ns * sizeof *x);
    wt_noise_remove_tt(n, y);
    ck_assert_double_le(tu_rel_diff(y, x, ns), 1e-14);
    free(x), free(y), free(tx), free(ty), free(ttx);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_weight)
{
    /* Ĉ⁻¹ = (I − T) C̃⁻¹ (I − T), with C̃⁻¹ taken from the assembled sparse matrix (independent of the
     * O(n) trick in apply_weight); symmetric; kills a global tip-tilt; equals C̃⁻¹ when remove_tt = 0. */
    wt_context *ctx = tu_context();
    const int nsub = 640, ns = 2 * nsub;
    wt_noise *n = make_noise(ctx, nsub, 0.8, 1);
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_noise_assemble_inv(n, &A), WT_OK);
    double *x = malloc(ns * sizeof *x), *y0 = malloc(ns * sizeof *y0), *y = malloc(ns * sizeof *y),
           *u = malloc(ns * sizeof *u), *v = calloc(ns, sizeof *v), *ref = malloc(ns * sizeof *ref);
    tu_randn(x, ns, 31);
    for (int i = 0; i < nsub; i++) x[i] += 2.0, x[nsub + i] -= 1.0;
    tu_randn(y0, ns, 32);
    const double alpha = -0.7;
    memcpy(y, y0, ns * sizeof *y);
    wt_noise_apply_weight(n, alpha, x, y);
    memcpy(u, x, ns * sizeof *u);
    wt_noise_remove_tt(n, u);
    wt_sparse_apply(A, 1.0, u, v);
    wt_noise_remove_tt(n, v);
    for (int i = 0; i < ns; i++) ref[i] = y0[i] + alpha * v[i];
    /* sums over n terms of entries ~1/σ²: round-off ~n ε relative */
    ck_assert_double_le(tu_rel_diff(y, ref, ns), 1e-12);

    /* symmetry: <Ĉ⁻¹x, z> = <x, Ĉ⁻¹z> */
    double *z = malloc(ns * sizeof *z), *wx = calloc(ns, sizeof *wx), *wz = calloc(ns, sizeof *wz);
    tu_randn(z, ns, 33);
    wt_noise_apply_weight(n, 1.0, x, wx);
    wt_noise_apply_weight(n, 1.0, z, wz);
    ck_assert_rel(tu_dot(wx, z, ns), tu_dot(x, wz, ns), 1e-12, 0);
    /* its range has no tip-tilt: the output has zero mean per axis */
    double sx = 0, sy = 0, s = 0;
    for (int i = 0; i < nsub; i++) sx += wx[i], sy += wx[nsub + i], s += fabs(wx[i]) + fabs(wx[nsub + i]);
    ck_assert_double_le(fabs(sx), 1e-13 * s);
    ck_assert_double_le(fabs(sy), 1e-13 * s);
    /* a global tip-tilt input gives zero */
    for (int i = 0; i < nsub; i++) z[i] = 1e-6, z[nsub + i] = 2e-6;
    memset(wz, 0, ns * sizeof *wz);
    wt_noise_apply_weight(n, 1.0, z, wz);
    memset(v, 0, ns * sizeof *v);
    wt_noise_apply_inv(n, 1.0, z, v); /* scale of what it would be without the projection */
    ck_assert_double_le(tu_norm(wz, ns), 1e-13 * tu_norm(v, ns));

    /* without the projection the weight is C̃⁻¹ */
    wt_noise *n0 = make_noise(ctx, nsub, 0.8, 0);
    memset(wx, 0, ns * sizeof *wx);
    memset(v, 0, ns * sizeof *v);
    wt_noise_apply_weight(n0, 1.0, x, wx);
    wt_noise_apply_inv(n0, 1.0, x, v);
    ck_assert_double_le(tu_rel_diff(wx, v, ns), 1e-15);
    wt_noise_free(n0);

    free(x), free(y0), free(y), free(u), free(v), free(ref), free(z), free(wx), free(wz);
    wt_sparse_free(A);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

/* The batched weight (the adjoint's three LGS of a group side by side) is the single weight bit for bit,
 * for a batch that mixes sizes and sensors without the tip-tilt removal (they go alone). */
START_TEST(test_weight_many)
{
    wt_context *ctx = tu_context();
    enum { K = 7 };
    const int nsub[K] = {300, 300, 300, 300, 300, 120, 300}, tt[K] = {1, 1, 1, 1, 1, 1, 0};
    wt_noise *ns[K];
    double *x[K], *y1[K], *y2[K];
    for (int j = 0; j < K; j++) {
        ns[j] = make_noise(ctx, nsub[j], 0.8 - 0.1 * j, tt[j]);
        x[j] = malloc(2 * (size_t)nsub[j] * sizeof *x[j]);
        y1[j] = malloc(2 * (size_t)nsub[j] * sizeof *y1[j]);
        y2[j] = malloc(2 * (size_t)nsub[j] * sizeof *y2[j]);
        tu_randn(x[j], 2 * nsub[j], 30 + j);
        tu_randn(y1[j], 2 * nsub[j], 40 + j);
        memcpy(y2[j], y1[j], 2 * (size_t)nsub[j] * sizeof *y2[j]);
    }
    wt_noise_apply_weight_many((const wt_noise *const *)ns, K, -0.7, (const double *const *)x, y1);
    for (int j = 0; j < K; j++) {
        wt_noise_apply_weight(ns[j], -0.7, x[j], y2[j]);
        ck_assert_mem_eq(y1[j], y2[j], 2 * (size_t)nsub[j] * sizeof *y1[j]);
        wt_noise_free(ns[j]);
        free(x[j]), free(y1[j]), free(y2[j]);
    }
    wt_context_free(ctx);
}
END_TEST

/* The overwriting weight (the adjoint's, without clearing its slopes first) is the accumulating one on +0 bit
 * for bit: batches of 1 to 4, a size change, a sensor without the tip-tilt removal; x with exact zeros of both
 * signs (where 0 + v and v differ) and y full of NaN before (every entry written). */
START_TEST(test_set_weight_many)
{
    wt_context *ctx = tu_context();
    enum { K = 8 };
    const int nsub[K] = {300, 300, 300, 300, 300, 120, 300, 301}, tt[K] = {1, 1, 1, 1, 1, 1, 0, 1};
    wt_noise *ns[K];
    double *x[K], *y1[K], *y2[K];
    for (int j = 0; j < K; j++) {
        const size_t n2 = 2 * (size_t)nsub[j];
        ns[j] = make_noise(ctx, nsub[j], 0.8 - 0.1 * j, tt[j]);
        x[j] = malloc(n2 * sizeof *x[j]);
        y1[j] = malloc(n2 * sizeof *y1[j]);
        y2[j] = calloc(n2, sizeof *y2[j]);
        tu_randn(x[j], n2, 50 + j);
        for (size_t i = 0; i < n2; i += 11) x[j][i] = (i / 11) % 2 ? -0.0 : 0.0;
        for (size_t i = 0; i < n2; i++) y1[j][i] = NAN;
    }
    wt_noise_set_weight_many((const wt_noise *const *)ns, K, (const double *const *)x, y1);
    wt_noise_apply_weight_many((const wt_noise *const *)ns, K, 1.0, (const double *const *)x, y2);
    for (int j = 0; j < K; j++) {
        ck_assert_mem_eq(y1[j], y2[j], 2 * (size_t)nsub[j] * sizeof *y1[j]);
        wt_noise_free(ns[j]);
        free(x[j]), free(y1[j]), free(y2[j]);
    }
    wt_context_free(ctx);
}
END_TEST

/* The float weight (wt_noise_set_weight_many_f32) against the double one. Its rounding, per slope, with
 * ε = 2⁻²⁴ the float unit roundoff and the input x the same floats on both paths (exact in double). For block i
 * let u = x_i − mx, v = x_{m+i} − my (mx, my the exact means; 0 without the tip-tilt removal) and
 *     Px_i = |ia|(|u| + |mx|) + |ib|(|v| + |my|),   Py_i = |ib|(|u| + |mx|) + |ic|(|v| + |my|),
 * P̄x, P̄y their means over the sensor. With the removal the float path rounds, to first order in ε:
 *   the means of x, summed in double (≪ ε) and rounded to float: |mxf − mx| ≤ ε|mx|;
 *   u32 = fl(x_i − mxf): off by ε|u| + ε|mx|;  the blocks rounded at alloc: ε|ia| …;  two products, one sum: 2ε;
 *   so each v_x = ia u + ib v is off by at most 4ε Px_i (block, subtraction of the mean, product, sum);
 *   the mean of v_x, summed in double from those: 4ε P̄x, and its rounding to float: ε|mean v_x| ≤ ε P̄x;
 *   the final fl(v_x − mean): ε(|v_x| + |mean|) ≤ ε(Px_i + P̄x);
 * in all |y32 − y| ≤ ε (5 Px_i + 6 P̄x), and the same with Py for the y half. Without the removal u, v are x
 * exact and only the block, the two products and the sum round: 3ε Px_i. FMA contraction (off in ISO C mode)
 * would only remove roundings. The second-order terms, and the double path's own error (below (m + 6) κ 2⁻⁵³
 * of the same sizes, κ ≤ 100 the blocks' spread: < 2⁻¹³ ε for m ≤ 640), stay under the slack factor 1 + 2⁻¹⁰.
 * A wrong sign, a lost mean or a lost ib errs by the size of a product, ~2²⁴ times more. */
static const double F32_EPS = 0x1p-24, F32_SLACK = 1.0 + 0x1p-10;

/* Px_i, Py_i of the bound above for sensor n (remove_tt = tt) and input x (2 nsub floats) into p[2 nsub],
 * and their means into pbar[2]. */
static void f32_sizes(const wt_noise *n, int tt, const float *x, double *p, double *pbar)
{
    const int m = wt_noise_nslopes(n) / 2;
    double mx = 0.0, my = 0.0;
    if (tt) {
        for (int i = 0; i < m; i++) mx += x[i], my += x[m + i];
        mx /= m, my /= m;
    }
    pbar[0] = pbar[1] = 0.0;
    for (int i = 0; i < m; i++) {
        double a, b, c;
        wt_noise_inv_block(n, i, &a, &b, &c);
        const double su = fabs(x[i] - mx) + fabs(mx), sv = fabs(x[m + i] - my) + fabs(my);
        p[i] = fabs(a) * su + fabs(b) * sv;
        p[m + i] = fabs(b) * su + fabs(c) * sv;
        pbar[0] += p[i], pbar[1] += p[m + i];
    }
    pbar[0] /= m, pbar[1] /= m;
}

/* The per-slope bound on |y32 − y| into tol[2 nsub]. */
static void f32_weight_bound(const wt_noise *n, int tt, const float *x, double *tol)
{
    const int m = wt_noise_nslopes(n) / 2;
    double pbar[2];
    f32_sizes(n, tt, x, tol, pbar);
    for (int i = 0; i < 2 * m; i++)
        tol[i] = F32_SLACK * F32_EPS * (tt ? 5.0 * tol[i] + 6.0 * pbar[i / m] : 3.0 * tol[i]);
}

/* 2 nsub float slopes: normal draws plus a tip-tilt (ox, oy), so that the means matter. */
static float *f32_slopes(int nsub, unsigned long seed, double ox, double oy)
{
    double *d = malloc(2 * (size_t)nsub * sizeof *d);
    float *x = malloc(2 * (size_t)nsub * sizeof *x);
    tu_randn(d, 2 * nsub, seed);
    for (int i = 0; i < nsub; i++) x[i] = (float)(d[i] + ox), x[nsub + i] = (float)(d[nsub + i] + oy);
    free(d);
    return x;
}

/* y32 = W32 x for one sensor (the batch of one). */
static void f32_weight1(const wt_noise *n, const float *x, float *y)
{
    wt_noise_set_weight_many_f32(&n, 1, &x, &y);
}

/* k = 1…5 sensors in one call, of two sizes (640: whole blocks of the kernel's lanes; 301: a tail), with and
 * without the tip-tilt removal, elongated (τ > 0, so ib matters), x with a tip-tilt: every slope within the
 * bound of the double weight (y filled with NaN before, so an unwritten slope fails too). */
START_TEST(test_set_weight_many_f32)
{
    wt_context *ctx = tu_context();
    enum { KMAX = 5 };
    for (int k = 1; k <= KMAX; k++) {
        wt_noise *ns[KMAX];
        int nsub[KMAX], tt[KMAX];
        float *x[KMAX], *y[KMAX];
        double *xd[KMAX], *yd[KMAX];
        for (int j = 0; j < k; j++) {
            nsub[j] = j % 2 ? 301 : 640;
            tt[j] = (j + k) % 3 != 0;
            const size_t n2 = 2 * (size_t)nsub[j];
            ns[j] = make_noise(ctx, nsub[j], 0.8 - 0.1 * j, tt[j]);
            x[j] = f32_slopes(nsub[j], 100 + 10 * k + j, 1.5 + j, -2.0 + 0.5 * j);
            y[j] = malloc(n2 * sizeof *y[j]);
            xd[j] = malloc(n2 * sizeof *xd[j]);
            yd[j] = malloc(n2 * sizeof *yd[j]);
            for (size_t i = 0; i < n2; i++) xd[j][i] = x[j][i], y[j][i] = NAN;
        }
        wt_noise_set_weight_many_f32((const wt_noise *const *)ns, k, (const float *const *)x, y);
        wt_noise_set_weight_many((const wt_noise *const *)ns, k, (const double *const *)xd, yd);
        for (int j = 0; j < k; j++) {
            const int n2 = 2 * nsub[j];
            double *tol = malloc(n2 * sizeof *tol);
            f32_weight_bound(ns[j], tt[j], x[j], tol);
            for (int i = 0; i < n2; i++)
                ck_assert_msg(fabs(y[j][i] - yd[j][i]) <= tol[i],
                              "k %d sensor %d slope %d: %.9g vs %.17g, |diff| %.3g > %.3g", k, j, i, (double)y[j][i],
                              yd[j][i], fabs(y[j][i] - yd[j][i]), tol[i]);
            free(tol);
            wt_noise_free(ns[j]);
            free(x[j]), free(y[j]), free(xd[j]), free(yd[j]);
        }
    }
    wt_context_free(ctx);
}
END_TEST

/* The float weight's range has no tip-tilt, and a global tip-tilt in x changes nothing, to float rounding.
 * Sums: y32_i = fl(v_i − d) with d the float mean of the v_i, so Σ y32 = (Σ v − m d) + Σ δ_i y32_i: the first
 * is the rounding of d, ≤ ε |Σ v| ≤ ε Σ Px (first order), the second ≤ ε Σ |y32|; the double summations add
 * m 2⁻⁵³ ≪ ε of the same. Invariance: x holds multiples of 2⁻¹² below 8 in size and the tip-tilt (a, b) is
 * 195/8, −141/8, so x + (a, b) is exact in float and both inputs have the same exact weight; each result is
 * within its own bound of it (the one of x + (a, b) larger through its means). Sensors of 640, 301 and 9
 * subapertures (the last all tail). */
START_TEST(test_set_weight_f32_tip_tilt)
{
    wt_context *ctx = tu_context();
    const int sizes[3] = {640, 301, 9};
    const double a = 195.0 / 8.0, b = -141.0 / 8.0;
    for (int s = 0; s < 3; s++) {
        const int m = sizes[s], n2 = 2 * m;
        wt_noise *n = make_noise(ctx, m, 0.8, 1);
        float *x = f32_slopes(m, 200 + s, 0.7, -0.4), *x2 = malloc(n2 * sizeof *x2), *y = malloc(n2 * sizeof *y),
              *y2 = malloc(n2 * sizeof *y2);
        double *p = malloc(n2 * sizeof *p), *tol = malloc(n2 * sizeof *tol), *tol2 = malloc(n2 * sizeof *tol2), pbar[2];
        for (int i = 0; i < n2; i++) x[i] = (float)(ldexp(nearbyint(ldexp(x[i], 12)), -12));
        for (int i = 0; i < n2; i++) ck_assert_double_lt(fabs(x[i]), 8.0);
        f32_weight1(n, x, y);

        f32_sizes(n, 1, x, p, pbar);
        double sum[2] = {0.0, 0.0}, abs_y[2] = {0.0, 0.0};
        for (int i = 0; i < n2; i++) sum[i / m] += y[i], abs_y[i / m] += fabs(y[i]);
        for (int h = 0; h < 2; h++) {
            const double bound = F32_SLACK * F32_EPS * (abs_y[h] + m * pbar[h]);
            ck_assert_msg(fabs(sum[h]) <= bound, "nsub %d half %d: sum %.3g > %.3g", m, h, sum[h], bound);
        }

        for (int i = 0; i < m; i++) {
            x2[i] = (float)(x[i] + a), x2[m + i] = (float)(x[m + i] + b);
            ck_assert_double_eq((double)x2[i] - a, x[i]); /* exact: the same exact weight */
            ck_assert_double_eq((double)x2[m + i] - b, x[m + i]);
        }
        f32_weight1(n, x2, y2);
        f32_weight_bound(n, 1, x, tol);
        f32_weight_bound(n, 1, x2, tol2);
        for (int i = 0; i < n2; i++)
            ck_assert_msg(fabs((double)y2[i] - y[i]) <= tol[i] + tol2[i], "nsub %d slope %d: %.9g vs %.9g, > %.3g", m,
                          i, (double)y2[i], (double)y[i], tol[i] + tol2[i]);
        wt_noise_free(n);
        free(x), free(x2), free(y), free(y2), free(p), free(tol), free(tol2);
    }
    wt_context_free(ctx);
}
END_TEST

/* <W32 x, z> = <x, W32 z> (in double) to the rounding of W32: each side is within Σ tol_i(x) |z_i| (resp.
 * Σ tol_i(z) |x_i|) of the exact <W x, z>, plus its double sum's 2m 2⁻⁵³ of Σ |terms| (the products of two floats
 * are exact in double). With and
 * without the tip-tilt removal; x and z with different tip-tilts, so a missing or one-sided projection (the
 * weight C̃⁻¹ (I − T) or (I − T) C̃⁻¹) or a sign error in one off-diagonal term is seen. */
START_TEST(test_set_weight_f32_symmetric)
{
    wt_context *ctx = tu_context();
    for (int tt = 0; tt <= 1; tt++) {
        const int m = 301, n2 = 2 * m;
        wt_noise *n = make_noise(ctx, m, 0.8, tt);
        float *x = f32_slopes(m, 300 + tt, 1.2, 0.3), *z = f32_slopes(m, 310 + tt, -0.6, 2.1),
              *wx = malloc(n2 * sizeof *wx), *wz = malloc(n2 * sizeof *wz);
        double *tx = malloc(n2 * sizeof *tx), *tz = malloc(n2 * sizeof *tz);
        f32_weight1(n, x, wx);
        f32_weight1(n, z, wz);
        f32_weight_bound(n, tt, x, tx);
        f32_weight_bound(n, tt, z, tz);
        double d1 = 0.0, d2 = 0.0, a1 = 0.0, a2 = 0.0, bound = 0.0;
        for (int i = 0; i < n2; i++) {
            d1 += (double)wx[i] * z[i], a1 += fabs((double)wx[i] * z[i]);
            d2 += (double)x[i] * wz[i], a2 += fabs((double)x[i] * wz[i]);
            bound += tx[i] * fabs(z[i]) + tz[i] * fabs(x[i]);
        }
        bound += F32_SLACK * n2 * 0x1p-53 * (a1 + a2);
        ck_assert_msg(fabs(d1 - d2) <= bound, "remove_tt %d: <Wx, z> = %.17g, <x, Wz> = %.17g, rel diff %.3g > %.3g",
                      tt, d1, d2, fabs(d1 - d2) / fabs(d1), bound / fabs(d1));
        wt_noise_free(n);
        free(x), free(z), free(wx), free(wz), free(tx), free(tz);
    }
    wt_context_free(ctx);
}
END_TEST


/* The LGS focus removal (recon.lgs_focus_removal): T = T_tt + f fᵀ on the centres of a 2-D set of subapertures.
 * (I − T) annihilates tip, tilt and the focus slope pattern (x_i, y_i) of any offset and scale, is idempotent and
 * symmetric; the weight Ĉ⁻¹ = (I − T) C̃⁻¹ (I − T) against the assembled C̃⁻¹ sandwiched by (I − T) (1e-12: n ε
 * of sums over n terms); set_weight_many gives apply_weight's bits, the float weight agrees to float rounding; a
 * sensor with one subaperture, or without the tip-tilt removal, is refused. Each bound is O(ε) relative to the
 * vectors involved; any missing projection term errs at O(1). */
START_TEST(test_focus_projection)
{
    wt_context *ctx = tu_context();
    const int side = 24;
    int nsub = 0;
    double *cx = malloc(side * side * sizeof *cx), *cy = malloc(side * side * sizeof *cy);
    for (int j = 0; j < side; j++)
        for (int i = 0; i < side; i++) {
            const double x = (i - 11.3) * 0.5, y = (j - 12.1) * 0.5, r = hypot(x, y); /* an annulus, off-centre */
            if (r < 5.5 && r > 1.2) cx[nsub] = x, cy[nsub] = y, nsub++;
        }
    const int ns = 2 * nsub;
    wt_noise *n = make_noise(ctx, nsub, 0.8, 1);
    ck_assert_ptr_null(wt_noise_focus(n));
    ck_assert_int_eq(wt_noise_set_focus(n, cx, cy), WT_OK);
    const double *f = wt_noise_focus(n);
    ck_assert_ptr_nonnull(f);
    ck_assert_rel(tu_norm(f, ns), 1.0, 1e-14, 0);
    double *x = malloc(ns * sizeof *x), *y = malloc(ns * sizeof *y), *z = malloc(ns * sizeof *z),
           *u = malloc(ns * sizeof *u), *v = calloc(ns, sizeof *v), *ref = malloc(ns * sizeof *ref);
    /* tip a, tilt b, focus c (s = c (x_i, y_i)): all removed, relative to their size */
    const double a = 3.7e-6, b = -1.3e-6, c = 2.2e-6;
    for (int i = 0; i < nsub; i++) x[i] = a + c * cx[i], x[nsub + i] = b + c * cy[i];
    const double sz = tu_norm(x, ns);
    wt_noise_remove_tt(n, x);
    ck_assert_double_le(tu_norm(x, ns), 1e-14 * sz);
    /* idempotent and symmetric on random vectors with large tip, tilt and focus parts */
    tu_randn(x, ns, 61);
    tu_randn(z, ns, 62);
    for (int i = 0; i < nsub; i++) x[i] += 5.0 + 3.0 * cx[i], x[nsub + i] -= 2.0 - 3.0 * cy[i];
    memcpy(y, x, ns * sizeof *y);
    wt_noise_remove_tt(n, y);
    memcpy(u, y, ns * sizeof *u);
    wt_noise_remove_tt(n, u);
    for (int i = 0; i < ns; i++) u[i] -= y[i];
    ck_assert_double_le(tu_norm(u, ns), 1e-13 * tu_norm(x, ns)); /* rounding of the first pass's sums, n ε of x */
    double sxx = 0.0, sxy = 0.0, sfx = 0.0;
    for (int i = 0; i < nsub; i++) sxx += y[i], sxy += y[nsub + i], sfx += f[i] * y[i] + f[nsub + i] * y[nsub + i];
    ck_assert_double_le(fabs(sxx) + fabs(sxy) + fabs(sfx), 1e-13 * tu_norm(x, ns) * sqrt(nsub));
    memcpy(u, z, ns * sizeof *u);
    wt_noise_remove_tt(n, u);
    ck_assert_rel(tu_dot(y, z, ns), tu_dot(x, u, ns), 1e-12, 1e-12 * tu_norm(x, ns) * tu_norm(z, ns));
    /* the weight: (I − T) C̃⁻¹ (I − T) against the assembled C̃⁻¹ */
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_noise_assemble_inv(n, &A), WT_OK);
    const double alpha = -0.7;
    tu_randn(z, ns, 63);
    memcpy(ref, z, ns * sizeof *ref);
    memcpy(y, z, ns * sizeof *y);
    wt_noise_apply_weight(n, alpha, x, y);
    memcpy(u, x, ns * sizeof *u);
    wt_noise_remove_tt(n, u);
    wt_sparse_apply(A, 1.0, u, v);
    wt_noise_remove_tt(n, v);
    for (int i = 0; i < ns; i++) ref[i] += alpha * v[i];
    ck_assert_double_le(tu_rel_diff(y, ref, ns), 1e-12);
    /* the weight of a pure tip + tilt + focus is zero to rounding */
    for (int i = 0; i < nsub; i++) u[i] = a + c * cx[i], u[nsub + i] = b + c * cy[i];
    memset(y, 0, ns * sizeof *y);
    wt_noise_apply_weight(n, 1.0, u, y);
    memset(v, 0, ns * sizeof *v);
    wt_noise_apply_inv(n, 1.0, u, v);
    ck_assert_double_le(tu_norm(y, ns), 1e-13 * tu_norm(v, ns));
    /* set_weight_many: apply_weight's bits (on y cleared to +0) */
    double *w1 = calloc(ns, sizeof *w1), *w2 = malloc(ns * sizeof *w2);
    wt_noise_apply_weight(n, 1.0, x, w1);
    const wt_noise *nn[1] = {n};
    const double *xs[1] = {x};
    double *ws[1] = {w2};
    wt_noise_set_weight_many(nn, 1, xs, ws);
    ck_assert_mem_eq(w1, w2, ns * sizeof *w1);
    /* the float weight: within float rounding of the double one (sums of n terms ~ n 2⁻²⁴ of their sizes) */
    float *xf = malloc(ns * sizeof *xf), *yf = malloc(ns * sizeof *yf);
    for (int i = 0; i < ns; i++) xf[i] = (float)x[i];
    const float *xfs[1] = {xf};
    float *yfs[1] = {yf};
    wt_noise_set_weight_many_f32(nn, 1, xfs, yfs);
    double err = 0.0, scale = 0.0;
    for (int i = 0; i < ns; i++) err = fmax(err, fabs((double)yf[i] - w1[i])), scale = fmax(scale, fabs(w1[i]));
    memset(v, 0, ns * sizeof *v);
    wt_noise_apply_inv(n, 1.0, x, v);
    for (int i = 0; i < ns; i++) scale = fmax(scale, fabs(v[i]));
    ck_assert_double_le(err, 1e-5 * scale);
    /* refused: one subaperture (a tip-tilt sensor), and a weight without the tip-tilt removal */
    wt_noise *one = make_noise(ctx, 1, 0.8, 1), *plain = make_noise(ctx, nsub, 0.8, 0);
    ck_assert_int_eq(wt_noise_set_focus(one, cx, cy), WT_ERR_INVALID);
    ck_assert_ptr_null(wt_noise_focus(one));
    ck_assert_int_eq(wt_noise_set_focus(plain, cx, cy), WT_ERR_INVALID);
    ck_assert_int_eq(wt_noise_focus_pattern(1, cx, cy, u), 0);
    wt_noise_free(one);
    wt_noise_free(plain);
    wt_sparse_free(A);
    free(x), free(y), free(z), free(u), free(v), free(ref), free(w1), free(w2), free(xf), free(yf), free(cx), free(cy);
    wt_noise_free(n);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("noise");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_cov_inverse);
    tcase_add_test(tc, test_inv_block_hand);
    tcase_add_test(tc, test_tt_projection);
    tcase_add_test(tc, test_weight);
    tcase_add_test(tc, test_focus_projection);
    tcase_add_test(tc, test_weight_many);
    tcase_add_test(tc, test_set_weight_many);
    tcase_add_test(tc, test_set_weight_many_f32);
    tcase_add_test(tc, test_set_weight_f32_tip_tilt);
    tcase_add_test(tc, test_set_weight_f32_symmetric);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
