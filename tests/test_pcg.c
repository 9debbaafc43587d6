/* tests/test_pcg.c: CG and Jacobi PCG on operators with known solutions. */
#include "core/solve/pcg.h"
#include "testutil.h"

/* A = tridiag(-1, 2 + shift_i, -1): SPD, with a diagonal that varies over 4 decades so that Jacobi helps. */
typedef struct {
    int n;
    const double *d;
} tri;

static void tri_apply(void *user, const double *x, double *y)
{
    const tri *t = user;
    for (int i = 0; i < t->n; i++) {
        double v = t->d[i] * x[i];
        if (i > 0) v -= x[i - 1];
        if (i + 1 < t->n) v -= x[i + 1];
        y[i] = v;
    }
}

static void make(int n, double *d)
{
    for (int i = 0; i < n; i++) d[i] = 2.0 + pow(10.0, 4.0 * i / (n - 1.0));
}

/* The operator of size n (diagonal into d), a random solution xs from seed and its b = A xs. */
static tri known_problem(int n, unsigned long seed, double *d, double *xs, double *b)
{
    make(n, d);
    tri t = {n, d};
    tu_randn(xs, n, seed);
    tri_apply(&t, xs, b);
    return t;
}

START_TEST(test_converges_to_known_solution)
{
    const int n = 400;
    double d[400], xs[400], b[400], x[400];
    tri t = known_problem(n, 1, d, xs, b);
    wt_context *ctx = tu_context();
    wt_pcg *p;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &p), WT_OK);
    for (int pre = 0; pre < 2; pre++) {
        double inv[400];
        for (int i = 0; i < n; i++) inv[i] = 1.0 / d[i];
        memset(x, 0, sizeof x);
        wt_pcg_result r;
        int st = wt_pcg_solve(p, tri_apply, &t, pre ? inv : NULL, b, x, 2000, 1e-13, NULL, &r);
        ck_assert_int_eq(st, WT_OK);
        /* ‖x − x*‖/‖x*‖ ≤ κ(A)·rtol; κ ≈ 1e4 here */
        ck_assert_double_le(tu_rel_diff(x, xs, n), 1e-8);
        ck_assert_double_le(r.rel_resid, 1e-13);
    }
    wt_pcg_free(p);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_jacobi_needs_fewer_iterations)
{
    const int n = 400;
    double d[400], b[400], x[400], inv[400];
    make(n, d);
    for (int i = 0; i < n; i++) inv[i] = 1.0 / d[i];
    tri t = {n, d};
    tu_randn(b, n, 2);
    wt_context *ctx = tu_context();
    wt_pcg *p;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &p), WT_OK);
    wt_pcg_result rc, rp;
    memset(x, 0, sizeof x);
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, NULL, b, x, 5000, 1e-10, NULL, &rc), WT_OK);
    memset(x, 0, sizeof x);
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, inv, b, x, 5000, 1e-10, NULL, &rp), WT_OK);
    ck_assert_int_lt(rp.iterations, rc.iterations);
    wt_pcg_free(p);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_warm_start_history_and_cap)
{
    const int n = 200;
    double d[200], xs[200], b[200], x[200], hist[6];
    tri t = known_problem(n, 3, d, xs, b);
    wt_context *ctx = tu_context();
    wt_pcg *p;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &p), WT_OK);
    /* starting at the solution: zero initial residual, converged before any iteration */
    memcpy(x, xs, sizeof x);
    wt_pcg_result r;
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, NULL, b, x, 5, 1e-12, hist, &r), WT_OK);
    ck_assert_int_eq(r.iterations, 0);
    ck_assert_double_le(hist[0], 1e-14);
    /* from zero with a cap of 5 and a tight tolerance: a warning, 5 iterations, a decreasing A-norm
     * error is not guaranteed in the residual, but the history has 6 finite entries starting at 1 */
    memset(x, 0, sizeof x);
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, NULL, b, x, 5, 1e-14, hist, &r), WT_WARN_MAXITER);
    ck_assert_int_eq(r.iterations, 5);
    ck_assert_double_eq_tol(hist[0], 1.0, 1e-15);
    for (int k = 0; k <= 5; k++) ck_assert(isfinite(hist[k]));
    ck_assert_double_eq_tol(hist[5], r.rel_resid, 1e-15);
    /* rtol = 0 means "run the cap", which is not a warning */
    memset(x, 0, sizeof x);
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, NULL, b, x, 3, 0.0, NULL, &r), WT_OK);
    ck_assert_int_eq(r.iterations, 3);
    wt_pcg_free(p);
    wt_context_free(ctx);
}
END_TEST

static void neg_apply(void *user, const double *x, double *y)
{
    int n = *(const int *)user;
    for (int i = 0; i < n; i++) y[i] = -x[i];
}

START_TEST(test_rejects_indefinite_and_nan)
{
    int n = 10;
    double b[10], x[10] = {0};
    tu_randn(b, n, 4);
    wt_context *ctx = tu_context();
    wt_pcg *p;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &p), WT_OK);
    ck_assert_int_eq(wt_pcg_solve(p, neg_apply, &n, NULL, b, x, 10, 1e-8, NULL, NULL), WT_ERR_NUMERIC);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "positive definite"));
    b[3] = NAN;
    ck_assert_int_eq(wt_pcg_solve(p, neg_apply, &n, NULL, b, x, 10, 1e-8, NULL, NULL), WT_ERR_NUMERIC);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "NaN"));
    wt_pcg *q;
    ck_assert_int_eq(wt_pcg_alloc(ctx, 0, &q), WT_ERR_INVALID);
    wt_pcg_free(p);
    wt_context_free(ctx);
}
END_TEST

/* Issue 10: tolerance 0 and thousands of iterations. Past convergence the residual sits at rounding level
 * and rᵀz or pᵀAp stops being > 0 (formerly "pᵀAp = NaN", an error); now the solve stops cleanly with
 * WT_OK or WT_WARN_BREAKDOWN, keeps a converged x and reports a finite residual. */
START_TEST(test_tolerance_zero_stops_cleanly)
{
    const int n = 400;
    double d[400], xs[400], b[400], x[400], inv[400];
    tri t = known_problem(n, 3, d, xs, b);
    for (int i = 0; i < n; i++) inv[i] = 1.0 / d[i];
    wt_context *ctx = tu_context();
    wt_pcg *p;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &p), WT_OK);
    int broke = 0;
    for (int pre = 0; pre < 2; pre++) {
        wt_pcg_result r;
        memset(x, 0, sizeof x);
        int st = wt_pcg_solve(p, tri_apply, &t, pre ? inv : NULL, b, x, 20000, 0.0, NULL, &r);
        ck_assert_msg(st == WT_OK || st == WT_WARN_BREAKDOWN, "status %d: %s", st, wt_error_message(ctx));
        broke += st == WT_WARN_BREAKDOWN;
        if (st == WT_WARN_BREAKDOWN) ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "relative residual"));
        ck_assert(isfinite(r.rel_resid));
        ck_assert_double_le(r.rel_resid, 1e-12); /* converged to rounding level (κ ≈ 1e4, ε = 2e-16) */
        ck_assert_double_le(tu_rel_diff(x, xs, n), 1e-9);
        ck_assert_int_lt(r.iterations, 20000);   /* it stopped, rather than running on rounding noise */
        /* and at ε² of ‖b‖ at the latest (pcg.c WT_PCG_ROUNDING): CG's bound ‖r_k‖ ≤ 2 √κ ρ^k ‖r_0‖, ρ = (√κ − 1) /
         * (√κ + 1), κ ≤ 1e4 here, reaches it within log(2·100/ε²) / −log ρ iterations (~4000); running on to a
         * subnormal rᵀz took ~2.5x that */
        const double rho = (100.0 - 1.0) / (100.0 + 1.0), eps2 = 0x1p-104;
        ck_assert_double_le(r.iterations, log(200.0 / eps2) / -log(rho) + 1.0);
        printf("tolerance 0, %s: %d iterations, relative residual %.3g\n", pre ? "Jacobi" : "none", r.iterations, r.rel_resid);
    }
    ck_assert_int_ge(broke, 1); /* the case this guards against does happen here */
    /* an operator that is not positive definite is still an error at the first iteration */
    for (int i = 0; i < n; i++) d[i] = -d[i] - 4.0;
    memset(x, 0, sizeof x);
    ck_assert_int_eq(wt_pcg_solve(p, tri_apply, &t, NULL, b, x, 10, 0.0, NULL, NULL), WT_ERR_NUMERIC);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "not positive definite"));
    wt_pcg_free(p);
    wt_context_free(ctx);
}
END_TEST

/* The operator of known_problem, counting its applies. */
typedef struct {
    tri t;
    int applies;
} counted;

static void counted_apply(void *user, const double *x, double *y)
{
    counted *c = user;
    c->applies++;
    tri_apply(&c->t, x, y);
}

/* A closed loop's frames: b drifts, each frame runs 4 iterations warm-started from the last. Continuing
 * (A x = b_prev − r_prev) saves exactly one apply per frame and gives the warm-started iterates up to the
 * recursive residual's rounding drift: per frame ~(iterations + 1) ε ‖A‖ ‖x‖ in r0, amplified by at most
 * κ(J⁻¹A) in x; with κ(J⁻¹A) ≲ 10 here and 30 frames, 1e-12 relative is a bound with a margin of ~10². */
START_TEST(test_continue_saves_an_apply)
{
    const int n = 300, frames = 30, it = 4;
    double d[300], xs[300], b[300], xa[300], xb[300], inv[300], drift[300];
    counted ca = {known_problem(n, 5, d, xs, b), 0}, cb = ca;
    for (int i = 0; i < n; i++) inv[i] = 1.0 / d[i];
    wt_context *ctx = tu_context();
    wt_pcg *pa, *pb;
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &pa), WT_OK);
    ck_assert_int_eq(wt_pcg_alloc(ctx, n, &pb), WT_OK);
    memset(xa, 0, sizeof xa);
    memset(xb, 0, sizeof xb);
    double worst = 0.0;
    for (int f = 0; f < frames; f++) {
        if (f > 0) {
            tu_randn(drift, n, 100 + f);
            for (int i = 0; i < n; i++) b[i] += 0.05 * drift[i];
        }
        const int a0 = ca.applies, b0 = cb.applies;
        ck_assert_int_eq(wt_pcg_solve(pa, counted_apply, &ca, inv, b, xa, it, 0.0, NULL, NULL), WT_OK);
        memcpy(wt_pcg_rhs(pb), b, sizeof b);
        ck_assert_int_eq(wt_pcg_solve_rhs(pb, counted_apply, &cb, inv, NULL, NULL, xb, 1, it, 0.0, NULL, NULL), WT_OK);
        ck_assert_int_eq(ca.applies - a0, it + 1);
        ck_assert_int_eq(cb.applies - b0, f > 0 ? it : it + 1);
        if (f == 0)
            for (int i = 0; i < n; i++) ck_assert(xa[i] == xb[i]); /* nothing to continue: wt_pcg_solve's bits */
        double e = tu_rel_diff(xb, xa, n);
        if (e > worst) worst = e;
    }
    ck_assert_msg(worst <= 1e-12, "continued frames differ from warm starts by %g", worst);
    ck_assert_double_gt(tu_rel_diff(xa, xs, n), 1e-6); /* the frames stop early: a drift test, not a convergence one */

    /* a failed solve leaves nothing to continue from: the next one applies A again, as a fresh solve does */
    double nanb[300];
    memcpy(nanb, b, sizeof b);
    nanb[7] = NAN;
    memcpy(wt_pcg_rhs(pb), nanb, sizeof nanb);
    ck_assert_int_eq(wt_pcg_solve_rhs(pb, counted_apply, &cb, inv, NULL, NULL, xb, 1, it, 0.0, NULL, NULL), WT_ERR_NUMERIC);
    memcpy(xa, xb, sizeof xa);
    int b0 = cb.applies;
    memcpy(wt_pcg_rhs(pb), b, sizeof b);
    ck_assert_int_eq(wt_pcg_solve_rhs(pb, counted_apply, &cb, inv, NULL, NULL, xb, 1, it, 0.0, NULL, NULL), WT_OK);
    ck_assert_int_eq(cb.applies - b0, it + 1);
    ck_assert_int_eq(wt_pcg_solve(pa, counted_apply, &ca, inv, b, xa, it, 0.0, NULL, NULL), WT_OK);
    for (int i = 0; i < n; i++) ck_assert(xa[i] == xb[i]);
    /* so does a solve of another right-hand side on the same workspace (the fitting's maps solve) */
    double other[300];
    memset(other, 0, sizeof other);
    ck_assert_int_eq(wt_pcg_solve(pb, counted_apply, &cb, inv, b, other, it, 0.0, NULL, NULL), WT_OK);
    b0 = cb.applies;
    memcpy(wt_pcg_rhs(pb), b, sizeof b);
    ck_assert_int_eq(wt_pcg_solve_rhs(pb, counted_apply, &cb, inv, NULL, NULL, xb, 1, it, 0.0, NULL, NULL), WT_OK);
    ck_assert_int_eq(cb.applies - b0, it + 1);
    wt_pcg_free(pa);
    wt_pcg_free(pb);
    wt_context_free(ctx);
}
END_TEST

/* From 16384 unknowns the iteration's dots and updates run on the context's threads (PCG-3's 24576): the
 * iterates must be those of one thread bit for bit (the dots as fixed chunk sums), for 2 and 3 threads (3 does not
 * divide the chunk groups evenly), fresh and continued solves, with and without Jacobi. */
START_TEST(test_threads_same_bits)
{
    enum { N = 20000, FR = 3, IT = 5 };
    double *d = malloc(N * sizeof *d), *xs = malloc(N * sizeof *xs), *b = malloc(N * sizeof *b);
    double *inv = malloc(N * sizeof *inv), *x[3], *drift = malloc(N * sizeof *drift);
    tri t = known_problem(N, 9, d, xs, b);
    for (int i = 0; i < N; i++) inv[i] = 1.0 / d[i];
    for (int pre = 0; pre < 2; pre++) {
        for (int k = 0; k < 3; k++) {
            wt_context *ctx = tu_context();
            wt_context_set_threads(ctx, k + 1);
            wt_pcg *p;
            ck_assert_int_eq(wt_pcg_alloc(ctx, N, &p), WT_OK);
            x[k] = calloc(N, sizeof *x[k]);
            for (int f = 0; f < FR; f++) {
                double *rhs = wt_pcg_rhs(p);
                tu_randn(drift, N, 200 + f);
                for (int i = 0; i < N; i++) rhs[i] = b[i] + 0.05 * f * drift[i];
                ck_assert_int_eq(wt_pcg_solve_rhs(p, tri_apply, &t, pre ? inv : NULL, NULL, NULL, x[k], 1, IT, 0.0, NULL,
                                                  NULL), WT_OK);
            }
            wt_pcg_free(p);
            wt_context_free(ctx);
        }
        ck_assert_double_gt(tu_rel_diff(x[0], xs, N), 1e-6); /* still iterating: not a fixed point that any order hits */
        ck_assert_mem_eq(x[0], x[1], N * sizeof *x[0]);
        ck_assert_mem_eq(x[0], x[2], N * sizeof *x[0]);
        for (int k = 0; k < 3; k++) free(x[k]);
    }
    free(d), free(xs), free(b), free(inv), free(drift);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("pcg");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_converges_to_known_solution);
    tcase_add_test(tc, test_threads_same_bits);
    tcase_add_test(tc, test_tolerance_zero_stops_cleanly);
    tcase_add_test(tc, test_jacobi_needs_fewer_iterations);
    tcase_add_test(tc, test_warm_start_history_and_cap);
    tcase_add_test(tc, test_rejects_indefinite_and_nan);
    tcase_add_test(tc, test_continue_saves_an_apply);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
