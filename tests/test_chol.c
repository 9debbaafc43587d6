/* tests/test_chol.c: the single right-hand-side solves of core/la/chol.h (wt_chol_prepare_one,
 * wt_chol_solve_one) on a sparse SPD matrix shaped like the fitting's (a 2-D grid with couplings a few
 * points long, a second coarser grid coupled to it, and isolated unknowns: a forest of elimination trees):
 * backward stable in fp64, within the factor's rounding in fp32, the same bits on 1 and 2 threads and for
 * b = x, and the refusals. */
#include <omp.h>

#include "core/la/chol.h"
#include "testutil.h"

/* The test matrix: g x g fine grid (3x3 stencil, coupling 2 points away too), a (g/2) x (g/2) coarse grid coupled
 * to the 4 fine points under it and to its neighbours, and `iso` isolated unknowns; diagonally dominant (SPD). */
static wt_sparse *test_matrix(wt_context *ctx, int g, int iso, int64_t *n_out)
{
    const int h = g / 2;
    const int64_t nf = (int64_t)g * g, nc = (int64_t)h * h, n = nf + nc + iso;
    wt_triplet *t;
    ck_assert_int_eq(wt_triplet_alloc(ctx, n, n, 16 * n, &t), WT_OK);
    wt_rng r;
    wt_rng_init(&r, 77, 0);
    double *rowsum = calloc(n, sizeof *rowsum);
#define COUPLE(a, b)                                                     \
    do {                                                                 \
        const double v_ = -0.1 - 0.9 * wt_rng_uniform(&r);               \
        ck_assert_int_eq(wt_triplet_add(t, (a), (b), v_), WT_OK);        \
        ck_assert_int_eq(wt_triplet_add(t, (b), (a), v_), WT_OK);        \
        rowsum[a] += fabs(v_), rowsum[b] += fabs(v_);                    \
    } while (0)
    for (int y = 0; y < g; y++)
        for (int x = 0; x < g; x++) {
            const int64_t i = x + (int64_t)g * y;
            const int dx[6] = {1, 1, 0, -1, 2, 0}, dy[6] = {0, 1, 1, 1, 0, 2};
            for (int k = 0; k < 6; k++) {
                const int xx = x + dx[k], yy = y + dy[k];
                if (xx >= 0 && xx < g && yy < g) COUPLE(i, xx + (int64_t)g * yy);
            }
        }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < h; x++) {
            const int64_t c = nf + x + (int64_t)h * y;
            for (int k = 0; k < 4; k++) COUPLE(c, (2 * x + k % 2) + (int64_t)g * (2 * y + k / 2));
            if (x + 1 < h) COUPLE(c, c + 1);
            if (y + 1 < h) COUPLE(c, c + h);
        }
#undef COUPLE
    for (int64_t i = 0; i < n; i++) ck_assert_int_eq(wt_triplet_add(t, i, i, rowsum[i] + 0.01 + wt_rng_uniform(&r)), WT_OK);
    wt_sparse *a;
    ck_assert_int_eq(wt_triplet_compress(t, &a), WT_OK);
    wt_triplet_free(t);
    free(rowsum);
    *n_out = n;
    return a;
}

/* ‖b − A x‖ / (‖A‖₁ ‖x‖₁) */
static double backward_error(const wt_sparse *a, const double *b, const double *x)
{
    const int64_t n = a->nrow;
    double *r = malloc(n * sizeof *r), anorm = 0.0, xn = 0.0, rn = 0.0;
    memcpy(r, b, n * sizeof *r);
    wt_sparse_apply(a, -1.0, x, r);
    for (int64_t c = 0; c < n; c++) {
        double s = 0.0;
        for (int64_t k = a->colptr[c]; k < a->colptr[c + 1]; k++) s += fabs(a->val[k]);
        anorm = fmax(anorm, s);
        xn += fabs(x[c]);
        rn += fabs(r[c]);
    }
    free(r);
    return rn / (anorm * xn);
}

/* fp64: backward stable, η ≤ n u (Higham's bound for the Cholesky solve is c·w·u with w the longest column of L,
 * ≤ n); the same solution as CHOLMOD's solve to κ·η. fp32: the factor rounded to float is the exact factor of a
 * matrix within ~2 u_f ‖A‖ of A, so η ≤ 4 u_f = 2.4e-7. Both: identical bits with the plan made for 1 or 2
 * threads and run on 1 or 2, and with b and x the same array. */
START_TEST(test_solve_one)
{
    wt_context *ctx = tu_context();
    int64_t n;
    wt_sparse *a = test_matrix(ctx, 40, 25, &n);
    wt_chol *c;
    ck_assert_int_eq(wt_chol_analyze(ctx, a, &c), WT_OK);
    double *b = malloc(n * sizeof *b), *x0 = malloc(n * sizeof *x0), *x1 = malloc(n * sizeof *x1),
           *x2 = malloc(n * sizeof *x2);
    tu_randn(b, n, 5);
    ck_assert_int_eq(wt_chol_solve_one(c, b, x1), WT_ERR_INVALID); /* no plan */
    ck_assert_int_eq(wt_chol_prepare_one(c, 0, 2), WT_ERR_INVALID); /* not factored */
    ck_assert_int_eq(wt_chol_factorize(c, a), WT_OK);
    ck_assert_int_eq(wt_chol_solve(c, 1, b, n, x0, n), WT_OK);
    const double u = 1.1e-16, uf = 6.0e-8;
    for (int f32 = 0; f32 < 2; f32++) {
        ck_assert_int_eq(wt_chol_prepare_one(c, f32, 2), WT_OK);
        double g0, g1, top;
        wt_chol_split(c, &g0, &g1, &top);
        ck_assert(g0 > 0 && g1 > 0 && top > 0);
        ck_assert_double_gt(wt_chol_one_bytes(c), 0.0);
        omp_set_num_threads(2);
        ck_assert_int_eq(wt_chol_solve_one(c, b, x1), WT_OK);
        omp_set_num_threads(1);
        ck_assert_int_eq(wt_chol_prepare_one(c, f32, 1), WT_OK);
        ck_assert_int_eq(wt_chol_solve_one(c, b, x2), WT_OK);
        ck_assert_int_eq(memcmp(x1, x2, n * sizeof *x1), 0);
        memcpy(x2, b, n * sizeof *x2);
        ck_assert_int_eq(wt_chol_solve_one(c, x2, x2), WT_OK);
        ck_assert_int_eq(memcmp(x1, x2, n * sizeof *x1), 0);
        /* the reference kernels (plain loops) and the fast ones (vector lanes, the forward block's y carried in
         * registers) do the same operations in the same order: the same bits, on one thread and on two (the
         * 1045 unknowns have supernodes with and without rows below, of 1 to ~40 columns: every loop's main
         * part and tail) */
        for (int nt = 1; nt <= 2; nt++) {
            ck_assert_int_eq(wt_chol_prepare_one(c, f32, nt), WT_OK);
            omp_set_num_threads(nt);
            wt_chol_one_reference(c, 1);
            ck_assert_int_eq(wt_chol_solve_one(c, b, x2), WT_OK);
            wt_chol_one_reference(c, 0);
            ck_assert_int_eq(memcmp(x1, x2, n * sizeof *x1), 0);
        }
        omp_set_num_threads(1);
        const double eta = backward_error(a, b, x1), bound = f32 ? 4.0 * uf : (double)n * u;
        fprintf(stderr, "chol solve_one %s: backward error %.3g (bound %.3g), vs CHOLMOD's solve %.3g\n",
                f32 ? "fp32" : "fp64", eta, bound, tu_rel_diff(x1, x0, n));
        ck_assert_double_le(eta, bound);
        ck_assert_double_le(backward_error(a, b, x0), (double)n * u);
    }
    /* a new factorisation drops the plan */
    ck_assert_int_eq(wt_chol_factorize(c, a), WT_OK);
    ck_assert_int_eq(wt_chol_solve_one(c, b, x1), WT_ERR_INVALID);
    ck_assert_double_eq(wt_chol_one_bytes(c), 0.0);
    free(b), free(x0), free(x1), free(x2);
    wt_chol_free(c);
    wt_sparse_free(a);
    wt_context_free(ctx);
}
END_TEST

/* A matrix of one supernode and a diagonal one (no tree to split): still solved exactly. */
START_TEST(test_solve_one_small)
{
    wt_context *ctx = tu_context();
    for (int dense = 0; dense < 2; dense++) {
        const int n = 6;
        wt_triplet *t;
        ck_assert_int_eq(wt_triplet_alloc(ctx, n, n, 64, &t), WT_OK);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                if (i == j) ck_assert_int_eq(wt_triplet_add(t, i, j, 10.0 + i), WT_OK);
                else if (dense) ck_assert_int_eq(wt_triplet_add(t, i, j, 1.0 / (1.0 + i + j)), WT_OK);
        wt_sparse *a;
        ck_assert_int_eq(wt_triplet_compress(t, &a), WT_OK);
        wt_triplet_free(t);
        wt_chol *c;
        ck_assert_int_eq(wt_chol_analyze(ctx, a, &c), WT_OK);
        ck_assert_int_eq(wt_chol_factorize(c, a), WT_OK);
        ck_assert_int_eq(wt_chol_prepare_one(c, 0, 2), WT_OK);
        double b[6] = {1, -2, 3, 0.5, 0, 7}, x[6];
        ck_assert_int_eq(wt_chol_solve_one(c, b, x), WT_OK);
        ck_assert_double_le(backward_error(a, b, x), 6.0 * 1.1e-16);
        wt_chol_free(c);
        wt_sparse_free(a);
    }
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("chol");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_solve_one);
    tcase_add_test(tc, test_solve_one_small);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
