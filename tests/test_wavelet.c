/* tests/test_wavelet.c: Daubechies filters and the periodic 2-D DWT (core/op/wavelet.c).
 *
 * Tolerances: a transform value is a sum of 2N products per pass, two passes per level, J levels, so
 * its rounding error is a few tens of ulps at most (N = 10, J = 7: ~ 2·20·7 = 280 terms on the path,
 * error ~ √280 · 1.1e-16 ≈ 2e-15 relative). The bounds below (1e-13 round trip and Parseval, 1e-12
 * adjoint) leave a margin of ~50 while any real bug (a wrong tap, a misplaced block, a wrong wrap)
 * gives O(1) errors.
 */
#include "testutil.h"

#include <lapacke.h>

#include "core/op/wavelet.h"

/* ---------------------------------------------------------------------------------------------- */
/* Filters                                                                                        */
/* ---------------------------------------------------------------------------------------------- */

START_TEST(test_filter_properties)
{
    wt_context *ctx = tu_context();
    for (int N = 1; N <= WT_WAVELET_MAX_ORDER; N++) {
        const int L = 2 * N;
        double h[2 * WT_WAVELET_MAX_ORDER], g[2 * WT_WAVELET_MAX_ORDER];
        ck_assert_int_eq(wt_wavelet_filter(ctx, N, h), WT_OK);
        for (int k = 0; k < L; k++) g[k] = ((k & 1) ? -1.0 : 1.0) * h[L - 1 - k];

        double s = 0.0;
        for (int k = 0; k < L; k++) s += h[k];
        /* 2N additions of O(1) values: a few ulps. */
        ck_assert_rel(s, sqrt(2.0), 1e-14, 0.0);

        /* Σ_k h_k h_{k+2m} = δ_m: sums of at most 20 products of numbers <= 1. */
        for (int m = 0; m < N; m++) {
            double o = 0.0;
            for (int k = 0; k + 2 * m < L; k++) o += h[k] * h[k + 2 * m];
            ck_assert_msg(fabs(o - (m == 0)) < 1e-13, "N=%d: sum h_k h_(k+2*%d) = %.17g", N, m, o);
        }

        /* N vanishing moments: Σ k^p g_k = 0 for p < N. The terms reach 19^9 ≈ 3e11, so the sum is
         * compared with Σ|k^p g_k| (cancellation leaves ~ L·eps of it). */
        for (int p = 0; p < N; p++) {
            double m = 0.0, a = 0.0;
            for (int k = 0; k < L; k++) {
                double t = pow((double)k, (double)p) * g[k];
                m += t;
                a += fabs(t);
            }
            ck_assert_msg(fabs(m) <= 1e-10 * a, "N=%d: moment %d of g = %.3g (scale %.3g)", N, p, m, a);
        }
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_filter_closed_forms)
{
    wt_context *ctx = tu_context();
    double h[20];
    ck_assert_int_eq(wt_wavelet_filter(ctx, 1, h), WT_OK);
    ck_assert_double_eq_tol(h[0], 1.0 / sqrt(2.0), 1e-15);
    ck_assert_double_eq_tol(h[1], 1.0 / sqrt(2.0), 1e-15);

    ck_assert_int_eq(wt_wavelet_filter(ctx, 2, h), WT_OK);
    const double r3 = sqrt(3.0), q = 4.0 * sqrt(2.0);
    const double db2[4] = {(1 + r3) / q, (3 + r3) / q, (3 - r3) / q, (1 - r3) / q};
    for (int k = 0; k < 4; k++) ck_assert_double_eq_tol(h[k], db2[k], 1e-15);

    /* Daubechies' published db3 and db4 (Ten Lectures, Table 6.1, 16 digits): the minimum-phase
     * choice of roots and the ordering, checked where more than one spectral factor exists. The
     * table's rounding (<= 5e-17) plus one ulp of the computed value (1.1e-16) stay under 3e-16. */
    static const double db3[6] = {0.3326705529500826,  0.8068915093110925,  0.4598775021184915,
                                  -0.1350110200102545, -0.0854412738820267, 0.0352262918857095};
    static const double db4[8] = {0.2303778133088964,  0.7148465705529154, 0.6308807679298587,
                                  -0.0279837694168599, -0.1870348117190931, 0.0308413818355607,
                                  0.0328830116668852,  -0.0105974017850690};
    ck_assert_int_eq(wt_wavelet_filter(ctx, 3, h), WT_OK);
    for (int k = 0; k < 6; k++) ck_assert_double_eq_tol(h[k], db3[k], 3e-16);
    ck_assert_int_eq(wt_wavelet_filter(ctx, 4, h), WT_OK);
    for (int k = 0; k < 8; k++) ck_assert_double_eq_tol(h[k], db4[k], 3e-16);
    wt_context_free(ctx);
}
END_TEST

/* Minimum phase for every order: Q(w) = Σ h_k w^{L−1−k} (the zeros of Σ h_k z^{-k}) is (1 + w)^N times
 * a polynomial whose N − 1 roots lie strictly inside the unit circle. The N-fold root at −1 is divided
 * out first because its computed location is only good to eps^{1/N}. */
START_TEST(test_filter_minimum_phase)
{
    wt_context *ctx = tu_context();
    for (int N = 2; N <= WT_WAVELET_MAX_ORDER; N++) {
        const int L = 2 * N;
        double h[20], q[20];
        ck_assert_int_eq(wt_wavelet_filter(ctx, N, h), WT_OK);
        /* q ascending in w: coefficient of w^j is h_{L−1−j}. */
        for (int j = 0; j < L; j++) q[j] = h[L - 1 - j];
        int deg = L - 1;
        for (int r = 0; r < N; r++) {
            /* Synthetic division by (w + 1), from the top; the remainder must vanish. */
            double qq[20], carry = 0.0;
            for (int j = deg; j >= 1; j--) {
                qq[j - 1] = q[j] - carry;
                carry = qq[j - 1];
            }
            double rem = q[0] - carry;
            ck_assert_msg(fabs(rem) < 1e-10, "N=%d: (1+w)^%d does not divide Q (remainder %.3g)", N, r + 1,
                          rem);
            deg--;
            memcpy(q, qq, sizeof(double) * (size_t)(deg + 1));
        }
        ck_assert_int_eq(deg, N - 1);
        double A[100] = {0}, wr[10], wi[10];
        for (int i = 1; i < deg; i++) A[i + deg * (i - 1)] = 1.0;
        for (int i = 0; i < deg; i++) A[i + deg * (deg - 1)] = -q[i] / q[deg];
        ck_assert_int_eq(LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', deg, A, deg, wr, wi, NULL, 1, NULL, 1), 0);
        for (int i = 0; i < deg; i++)
            ck_assert_msg(hypot(wr[i], wi[i]) < 1.0 - 1e-3, "N=%d: zero %g%+gi outside the unit disc", N,
                          wr[i], wi[i]);
    }
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Transforms                                                                                     */
/* ---------------------------------------------------------------------------------------------- */

typedef struct {
    wt_context *ctx;
    wt_wavelet *w;
    double *work;
} plan;

static plan plan_make(int n, int order, int levels)
{
    plan p;
    p.ctx = tu_context();
    ck_assert_int_eq(wt_wavelet_alloc(p.ctx, n, order, levels, &p.w), WT_OK);
    ck_assert_int_eq(wt_wavelet_n(p.w), n);
    ck_assert_int_eq(wt_wavelet_order(p.w), order);
    ck_assert_int_eq(wt_wavelet_levels(p.w), levels);
    /* Exactly the advertised size, so a sanitizer build catches any overrun. */
    p.work = malloc(sizeof(double) * wt_wavelet_work_size(p.w));
    ck_assert_ptr_nonnull(p.work);
    return p;
}

static void plan_done(plan *p)
{
    free(p->work);
    wt_wavelet_free(p->w);
    wt_context_free(p->ctx);
}

static int ilog2(int n)
{
    int l = 0;
    while ((1 << l) < n) l++;
    return l;
}

/* The spec formula, written directly with mod indexing: a_k = Σ_i h_i x_{(2k+i) mod m} into [0, m/2),
 * d_k with g into [m/2, m); v is read with stride s. */
static void ref_step(const double *h, const double *g, int L, int m, double *v, long s, double *tmp)
{
    for (int k = 0; k < m / 2; k++) {
        double a = 0.0, d = 0.0;
        for (int i = 0; i < L; i++) {
            double xv = v[((2 * k + i) % m) * s];
            a += h[i] * xv;
            d += g[i] * xv;
        }
        tmp[k] = a;
        tmp[k + m / 2] = d;
    }
    for (int k = 0; k < m; k++) v[k * s] = tmp[k];
}

static void ref_forward(int N, int n, int J, const double *x, double *c)
{
    const int L = 2 * N;
    double h[20], g[20], tmp[1024];
    wt_context *ctx = tu_context();
    ck_assert_int_eq(wt_wavelet_filter(ctx, N, h), WT_OK);
    wt_context_free(ctx);
    for (int k = 0; k < L; k++) g[k] = ((k & 1) ? -1.0 : 1.0) * h[L - 1 - k];
    memcpy(c, x, sizeof(double) * (size_t)n * n);
    for (int l = 0, m = n; l < J; l++, m /= 2) {
        for (int iy = 0; iy < m; iy++) ref_step(h, g, L, m, c + (long)iy * n, 1, tmp);
        for (int ix = 0; ix < m; ix++) ref_step(h, g, L, m, c + ix, n, tmp);
    }
}

/* The plan against the direct formula: catches layout, orientation, wrap (m < 2N) and tap errors that
 * round-trip tests cannot see (any orthogonal map round-trips). */
START_TEST(test_forward_matches_reference)
{
    const int ns[] = {4, 16, 64};
    for (int N = 1; N <= WT_WAVELET_MAX_ORDER; N++) {
        for (int a = 0; a < 3; a++) {
            const int n = ns[a], nn = n * n;
            for (int J = 1; J <= ilog2(n); J++) {
                plan p = plan_make(n, N, J);
                double *x = malloc(sizeof(double) * nn), *c = malloc(sizeof(double) * nn),
                       *r = malloc(sizeof(double) * nn);
                tu_randn(x, nn, 100 + N);
                wt_wavelet_forward(p.w, x, c, p.work);
                ref_forward(N, n, J, x, r);
                double e = tu_rel_diff(c, r, nn);
                ck_assert_msg(e < 1e-13, "N=%d n=%d J=%d: forward differs from the formula by %.3g", N, n,
                              J, e);
                free(x);
                free(c);
                free(r);
                plan_done(&p);
            }
        }
    }
}
END_TEST

START_TEST(test_roundtrip_and_parseval)
{
    const int ns[] = {8, 32, 128};
    for (int N = 1; N <= WT_WAVELET_MAX_ORDER; N++) {
        for (int a = 0; a < 3; a++) {
            const int n = ns[a], nn = n * n, lmax = ilog2(n);
            const int Js[] = {1, (1 + lmax) / 2, lmax};
            for (int b = 0; b < 3; b++) {
                const int J = Js[b];
                plan p = plan_make(n, N, J);
                double *x = malloc(sizeof(double) * nn), *x0 = malloc(sizeof(double) * nn),
                       *c = malloc(sizeof(double) * nn), *c0 = malloc(sizeof(double) * nn),
                       *y = malloc(sizeof(double) * nn);
                tu_randn(x0, nn, 1000 * N + 10 * a + b);
                memcpy(x, x0, sizeof(double) * nn);

                /* Separate buffers: the inputs must come back untouched. */
                wt_wavelet_forward(p.w, x, c, p.work);
                ck_assert_msg(memcmp(x, x0, sizeof(double) * nn) == 0, "forward modified its input");
                ck_assert_rel(tu_norm(c, nn), tu_norm(x0, nn), 1e-13, 0.0);
                memcpy(c0, c, sizeof(double) * nn);
                wt_wavelet_inverse(p.w, c, y, p.work);
                ck_assert_msg(memcmp(c, c0, sizeof(double) * nn) == 0, "inverse modified its input");
                double e = tu_rel_diff(y, x0, nn);
                ck_assert_msg(e < 1e-13, "N=%d n=%d J=%d: round trip error %.3g", N, n, J, e);

                /* In place (x and c the same array) must give the same coefficients and values. */
                wt_wavelet_forward(p.w, x, x, p.work);
                ck_assert_msg(tu_rel_diff(x, c0, nn) < 1e-15, "N=%d n=%d J=%d: in-place forward differs",
                              N, n, J);
                wt_wavelet_inverse(p.w, x, x, p.work);
                e = tu_rel_diff(x, x0, nn);
                ck_assert_msg(e < 1e-13, "N=%d n=%d J=%d: in-place round trip error %.3g", N, n, J, e);

                /* W⁻¹ is also a left inverse: W W⁻¹ c = c. */
                wt_wavelet_inverse(p.w, c0, y, p.work);
                wt_wavelet_forward(p.w, y, y, p.work);
                ck_assert_rel(tu_norm(y, nn), tu_norm(c0, nn), 1e-13, 0.0);
                ck_assert_msg(tu_rel_diff(y, c0, nn) < 1e-13, "N=%d n=%d J=%d: W W^-1 != I", N, n, J);

                free(x);
                free(x0);
                free(c);
                free(c0);
                free(y);
                plan_done(&p);
            }
        }
    }
}
END_TEST

/* The single-precision forms (wt_wavelet_forward_f32, wt_wavelet_inverse_f32) against the double ones on the same
 * (float) input. A pass computes each output as 2N products and adds in float, error ≤ (2N + 1) u Σ_i |h_i| |x_i|
 * (u = 2^-24), whose norm over the outputs is ≤ (2N + 1) u ‖h‖₁ ‖x‖ ≤ (2N + 1) √(2N) u ‖x‖ (‖h‖₂ = 1); the later
 * passes are orthonormal, so 2J passes and the filters' own rounding to float (≤ u ‖h‖₁ per pass more) give
 *   ‖W32 x − W x‖ ≤ 2J (2N + 2) √(2N) u ‖x‖,
 * the same for W⁻¹; in place as well as into another array. */
START_TEST(test_single_precision)
{
    const double u = ldexp(1.0, -24);
    const int ns[] = {8, 64, 128};
    for (int N = 1; N <= WT_WAVELET_MAX_ORDER; N += 2) {
        for (int a = 0; a < 3; a++) {
            const int n = ns[a], nn = n * n, J = ilog2(n) < 5 ? ilog2(n) : 5;
            plan p = plan_make(n, N, J);
            double *x = malloc(sizeof(double) * nn), *c = malloc(sizeof(double) * nn), *y = malloc(sizeof(double) * nn);
            float *x32 = malloc(sizeof(float) * nn), *c32 = malloc(sizeof(float) * nn), *y32 = malloc(sizeof(float) * nn);
            float *work32 = malloc(sizeof(float) * wt_wavelet_work_size(p.w));
            tu_randn(x, nn, 7000 + 10 * N + a);
            for (int i = 0; i < nn; i++) x[i] = x32[i] = (float)x[i];
            const double bound = 2.0 * J * (2 * N + 2) * sqrt(2.0 * N) * u;
            wt_wavelet_forward(p.w, x, c, p.work);
            wt_wavelet_forward_f32(p.w, x32, c32, work32);
            for (int i = 0; i < nn; i++) y[i] = c32[i];
            double e = tu_rel_diff(y, c, nn);
            ck_assert_msg(e > 0.0 && e <= bound, "N=%d n=%d J=%d: forward f32 error %.3g (bound %.3g)", N, n, J, e, bound);
            /* the inverse, on the double coefficients rounded to float */
            for (int i = 0; i < nn; i++) c[i] = c32[i] = (float)c[i];
            wt_wavelet_inverse(p.w, c, x, p.work);
            wt_wavelet_inverse_f32(p.w, c32, y32, work32);
            for (int i = 0; i < nn; i++) y[i] = y32[i];
            e = tu_rel_diff(y, x, nn);
            ck_assert_msg(e > 0.0 && e <= bound, "N=%d n=%d J=%d: inverse f32 error %.3g (bound %.3g)", N, n, J, e, bound);
            /* of double coefficients (rounded as read): the bits of rounding them first, and x in double alike */
            double *c64 = malloc(sizeof(double) * nn), *x64 = malloc(sizeof(double) * nn);
            float *z32 = malloc(sizeof(float) * nn);
            tu_randn(c64, nn, 7500 + 10 * N + a);
            for (int i = 0; i < nn; i++) c32[i] = (float)c64[i];
            wt_wavelet_inverse_f32(p.w, c32, y32, work32);
            wt_wavelet_inverse_f32_of64(p.w, c64, z32, x64, work32);
            ck_assert_mem_eq(z32, y32, sizeof(float) * nn);
            for (int i = 0; i < nn; i++) ck_assert(x64[i] == (double)y32[i]);
            wt_wavelet_inverse_f32_of64(p.w, c64, z32, NULL, work32);
            ck_assert_mem_eq(z32, y32, sizeof(float) * nn);
            /* in place: the same values */
            wt_wavelet_inverse_f32(p.w, c32, c32, work32);
            ck_assert_mem_eq(c32, y32, sizeof(float) * nn);
            free(x), free(c), free(y), free(x32), free(c32), free(y32), free(work32), free(c64), free(x64), free(z32);
            plan_done(&p);
        }
    }
}
END_TEST

START_TEST(test_adjoint)
{
    const int cases[][3] = {{64, 3, 5}, {32, 1, 5}, {16, 10, 4}, {128, 6, 3}};
    for (int t = 0; t < 4; t++) {
        const int n = cases[t][0], nn = n * n;
        plan p = plan_make(n, cases[t][1], cases[t][2]);
        double *x = malloc(sizeof(double) * nn), *y = malloc(sizeof(double) * nn),
               *wx = malloc(sizeof(double) * nn), *wiy = malloc(sizeof(double) * nn);
        tu_randn(x, nn, 7 + t);
        tu_randn(y, nn, 70 + t);
        wt_wavelet_forward(p.w, x, wx, p.work);
        wt_wavelet_inverse(p.w, y, wiy, p.work);
        /* Both sides are O(n) sums of O(1) products; relative to ‖x‖‖y‖ (Cauchy–Schwarz scale). */
        double lhs = tu_dot(wx, y, nn), rhs = tu_dot(x, wiy, nn);
        double scale = tu_norm(x, nn) * tu_norm(y, nn);
        ck_assert_msg(fabs(lhs - rhs) <= 1e-12 * scale, "n=%d: <Wx,y> = %.17g, <x,W^-1 y> = %.17g", n, lhs,
                      rhs);
        free(x);
        free(y);
        free(wx);
        free(wiy);
        plan_done(&p);
    }
}
END_TEST

/* db1, one level, against a 2-D Haar step written from its definition on 2x2 blocks. */
START_TEST(test_haar_step)
{
    const int n = 8, nn = n * n, m = n / 2;
    plan p = plan_make(n, 1, 1);
    double x[64], c[64], r[64];
    tu_randn(x, nn, 42);
    wt_wavelet_forward(p.w, x, c, p.work);
    for (int ky = 0; ky < m; ky++)
        for (int kx = 0; kx < m; kx++) {
            double x00 = x[2 * kx + n * (2 * ky)], x10 = x[2 * kx + 1 + n * (2 * ky)];
            double x01 = x[2 * kx + n * (2 * ky + 1)], x11 = x[2 * kx + 1 + n * (2 * ky + 1)];
            r[kx + n * ky] = 0.5 * (x00 + x10 + x01 + x11);           /* approximation */
            r[kx + m + n * ky] = 0.5 * (x00 - x10 + x01 - x11);       /* 1: difference along x */
            r[kx + n * (ky + m)] = 0.5 * (x00 + x10 - x01 - x11);     /* 2: difference along y */
            r[kx + m + n * (ky + m)] = 0.5 * (x00 - x10 - x01 + x11); /* 3: diagonal */
        }
    for (int i = 0; i < nn; i++) ck_assert_double_eq_tol(c[i], r[i], 1e-14);
    plan_done(&p);
}
END_TEST

/* W⁻¹ e_λ' with λ' = λ moved one coefficient along x (or y) inside its block is W⁻¹ e_λ shifted
 * periodically by 2^l grid points (2^J for the approximation). Exact up to rounding: the same taps
 * are summed, only at other indices. */
static void check_shift(plan *p, int l, int o, int kx, int ky, int along_y, double *e, double *b0, double *b1)
{
    const int n = wt_wavelet_n(p->w), J = wt_wavelet_levels(p->w), nn = n * n;
    const int m = (o == 0) ? n >> J : n >> l;          /* block side */
    const int ox = (o & 1) ? m : 0, oy = (o & 2) ? m : 0; /* block origin */
    const int sh = (o == 0) ? 1 << J : 1 << l;
    const int kx1 = along_y ? kx : (kx + 1) % m, ky1 = along_y ? (ky + 1) % m : ky;

    memset(e, 0, sizeof(double) * nn);
    e[ox + kx + n * (oy + ky)] = 1.0;
    int lev, ori;
    wt_wavelet_classify(p->w, ox + kx, oy + ky, &lev, &ori);
    ck_assert_int_eq(lev, o == 0 ? J + 1 : l);
    ck_assert_int_eq(ori, o);
    wt_wavelet_inverse(p->w, e, b0, p->work);
    memset(e, 0, sizeof(double) * nn);
    e[ox + kx1 + n * (oy + ky1)] = 1.0;
    wt_wavelet_inverse(p->w, e, b1, p->work);
    /* b1(ix, iy) = b0(ix − sh, iy) (or along y). */
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            int sx = along_y ? ix : (ix - sh + n) % n, sy = along_y ? (iy - sh + n) % n : iy;
            ck_assert_msg(fabs(b1[ix + n * iy] - b0[sx + n * sy]) <= 1e-14,
                          "l=%d o=%d k=(%d,%d) %s: shift mismatch at (%d,%d): %.17g vs %.17g", l, o, kx, ky,
                          along_y ? "y" : "x", ix, iy, b1[ix + n * iy], b0[sx + n * sy]);
        }
    /* Unit norm: the basis is orthonormal. */
    ck_assert_rel(tu_norm(b0, nn), 1.0, 1e-14, 0.0);
}

START_TEST(test_shift_property)
{
    const int cases[][3] = {{32, 3, 4}, {32, 10, 5}, {16, 1, 3}, {64, 2, 6}};
    for (int t = 0; t < 4; t++) {
        const int n = cases[t][0], J = cases[t][2], nn = n * n;
        plan p = plan_make(n, cases[t][1], J);
        double *e = malloc(sizeof(double) * nn), *b0 = malloc(sizeof(double) * nn),
               *b1 = malloc(sizeof(double) * nn);
        for (int l = 1; l <= J; l++) {
            const int m = n >> l;
            for (int o = 1; o <= 3; o++)
                for (int ay = 0; ay < 2; ay++) {
                    /* a position near the start, one in the middle, and the last (wraps to 0) */
                    check_shift(&p, l, o, 0, m - 1, ay, e, b0, b1);
                    check_shift(&p, l, o, m / 2, m / 3, ay, e, b0, b1);
                    check_shift(&p, l, o, m - 1, 0, ay, e, b0, b1);
                }
        }
        const int ma = n >> J;
        for (int ay = 0; ay < 2; ay++) {
            check_shift(&p, J, 0, 0, 0, ay, e, b0, b1);
            check_shift(&p, J, 0, ma - 1, ma / 2, ay, e, b0, b1);
        }
        free(e);
        free(b0);
        free(b1);
        plan_done(&p);
    }
}
END_TEST

START_TEST(test_classify_counts)
{
    const int cases[][2] = {{64, 5}, {128, 7}, {8, 1}, {2, 1}};
    for (int t = 0; t < 4; t++) {
        const int n = cases[t][0], J = cases[t][1];
        plan p = plan_make(n, 3, J);
        int cnt[10][4];
        memset(cnt, 0, sizeof cnt);
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) {
                int l = -1, o = -1;
                wt_wavelet_classify(p.w, ix, iy, &l, &o);
                ck_assert(l >= 1 && l <= J + 1);
                ck_assert(o >= 0 && o <= 3);
                ck_assert((o == 0) == (l == J + 1));
                /* the layout of the header: orientation 1 has ix in the upper half of its block */
                if (o) {
                    int m = n >> l;
                    ck_assert_int_eq(ix >= m && ix < 2 * m, (o & 1) != 0);
                    ck_assert_int_eq(iy >= m && iy < 2 * m, (o & 2) != 0);
                } else {
                    ck_assert(ix < (n >> J) && iy < (n >> J));
                }
                cnt[l][o]++;
            }
        for (int l = 1; l <= J; l++)
            for (int o = 1; o <= 3; o++) ck_assert_int_eq(cnt[l][o], (n >> l) * (n >> l));
        ck_assert_int_eq(cnt[J + 1][0], (n >> J) * (n >> J));
        plan_done(&p);
    }
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Errors                                                                                         */
/* ---------------------------------------------------------------------------------------------- */

static void expect_reject(wt_context *ctx, int st, const char *value)
{
    ck_assert_int_eq(st, WT_ERR_INVALID);
    ck_assert_int_eq(wt_error_status(ctx), WT_ERR_INVALID);
    ck_assert_msg(strstr(wt_error_message(ctx), value) != NULL, "message \"%s\" does not name %s",
                  wt_error_message(ctx), value);
    wt_error_clear(ctx);
}

START_TEST(test_bad_input)
{
    wt_context *ctx = tu_context();
    double h[22];
    static int sentinel;
    wt_wavelet *w = (wt_wavelet *)&sentinel; /* never dereferenced: alloc must reset it to NULL */
    expect_reject(ctx, wt_wavelet_filter(ctx, 0, h), "order 0");
    expect_reject(ctx, wt_wavelet_filter(ctx, 11, h), "order 11");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 64, 0, 3, &w), "order 0");
    ck_assert_ptr_null(w);
    expect_reject(ctx, wt_wavelet_alloc(ctx, 64, 11, 3, &w), "order 11");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 48, 3, 3, &w), "n = 48");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 1, 3, 1, &w), "n = 1");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 0, 3, 1, &w), "n = 0");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 32, 3, 6, &w), "J = 6");
    expect_reject(ctx, wt_wavelet_alloc(ctx, 32, 3, 0, &w), "J = 0");
    ck_assert_ptr_null(w);
    /* the boundary values are accepted */
    ck_assert_int_eq(wt_wavelet_alloc(ctx, 32, 3, 5, &w), WT_OK);
    wt_wavelet_free(w);
    ck_assert_int_eq(wt_wavelet_alloc(ctx, 2, 10, 1, &w), WT_OK);
    wt_wavelet_free(w);
    wt_wavelet_free(NULL);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_budget(&fa, 0); /* every allocation fails */
    tu_alloc_install(ctx, &fa);
    wt_wavelet *w = NULL;
    ck_assert_int_eq(wt_wavelet_alloc(ctx, 64, 3, 5, &w), WT_ERR_NOMEM);
    ck_assert_ptr_null(w);
    ck_assert_int_eq(wt_error_status(ctx), WT_ERR_NOMEM);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("wavelet");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_filter_properties);
    tcase_add_test(tc, test_filter_closed_forms);
    tcase_add_test(tc, test_filter_minimum_phase);
    tcase_add_test(tc, test_forward_matches_reference);
    tcase_add_test(tc, test_roundtrip_and_parseval);
    tcase_add_test(tc, test_single_precision);
    tcase_add_test(tc, test_adjoint);
    tcase_add_test(tc, test_haar_step);
    tcase_add_test(tc, test_shift_property);
    tcase_add_test(tc, test_classify_counts);
    tcase_add_test(tc, test_bad_input);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
