/* tests/test_vec.c: the order-fixed vector kernels (core/la/vec.h): the dot product is the ordered sum of
 * WT_VEC_CHUNKS chunk sums (written out here as the definition), for every length, on 1 and 2 threads;
 * the batched dots and the fused column updates are the one-at-a-time kernels bit for bit. */
#include "testutil.h"

#include <float.h>
#include <math.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/la/vec.h"

static double dot_definition(const double *x, const double *y, int64_t n)
{
    const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS;
    double total = 0.0;
    for (int c = 0; c < WT_VEC_CHUNKS; c++) {
        double s = 0.0;
        for (int64_t i = (int64_t)c * len; i < n && i < (int64_t)(c + 1) * len; i++) s += x[i] * y[i];
        total += s;
    }
    return total;
}

START_TEST(test_dot_is_chunked_sum)
{
    const int64_t lens[] = {1, 7, 63, 64, 65, 500, 513, 24576, 24577, 40000, 70001};
    double *x = malloc(70001 * sizeof *x), *y = malloc(70001 * sizeof *y);
    tu_randn(x, 70001, 1);
    tu_randn(y, 70001, 2);
    for (size_t k = 0; k < sizeof lens / sizeof *lens; k++) {
        const double ref = dot_definition(x, y, lens[k]);
        for (int th = 1; th <= 2; th++) {
#ifdef _OPENMP
            omp_set_num_threads(th);
#endif
            const double d = wt_vec_dot(x, y, lens[k]);
            ck_assert_msg(memcmp(&d, &ref, sizeof d) == 0, "n %lld, %d threads: %.17g against %.17g",
                          (long long)lens[k], th, d, ref);
        }
    }
    free(x), free(y);
}
END_TEST

START_TEST(test_many_equal_single)
{
    const int64_t lens[] = {5, 130, 8193, 24576, 24599};
    const int qs[] = {1, 3, 12, 17, 33}; /* beyond WT_VEC_MANY: several passes */
    const int64_t ld = 24650;
    double *X = malloc(33 * ld * sizeof *X), *y = malloc(ld * sizeof *y), *z1 = malloc(ld * sizeof *z1),
           *z2 = malloc(ld * sizeof *z2), out[33], v[33];
    tu_randn(X, 33 * ld, 3);
    tu_randn(y, ld, 4);
    tu_randn(v, 33, 5);
    for (size_t a = 0; a < sizeof lens / sizeof *lens; a++)
        for (size_t b = 0; b < sizeof qs / sizeof *qs; b++)
            for (int th = 1; th <= 2; th++) {
                const int64_t n = lens[a];
                const int q = qs[b];
                wt_vec_dot_many(X, ld, q, y, n, NULL, 0, out, th);
                for (int k = 0; k < q; k++) {
                    const double ref = wt_vec_dot(X + k * ld, y, n);
                    ck_assert_msg(memcmp(&out[k], &ref, sizeof ref) == 0, "dot %d of %d, n %lld", k, q, (long long)n);
                }
                tu_randn(z1, n, 6);
                memcpy(z2, z1, n * sizeof *z1);
                wt_vec_sub_many(z1, X, ld, q, v, n, NULL, 0, th);
                for (int k = 0; k < q; k++)
                    for (int64_t i = 0; i < n; i++) z2[i] -= v[k] * X[k * ld + i];
                ck_assert_mem_eq(z1, z2, n * sizeof *z1);
            }
    free(X), free(y), free(z1), free(z2);
}
END_TEST

/* Columns that are zero on whole row ranges (as the NGS term of the PCG-3 preconditioner, ~60 % of its
 * rows): skipping those rows (wt_vec_runs) keeps the bits, the signs of zero included — z holds ±0 on
 * some of the skipped rows, where z − v·(±0) can flip a zero's sign. */
START_TEST(test_many_skip_zero_rows)
{
    const int64_t n = 24576, ld = 24600;
    const int q = 12;
    double *X = malloc(q * ld * sizeof *X), *y = malloc(n * sizeof *y), *z1 = malloc(n * sizeof *z1),
           *z2 = malloc(n * sizeof *z2), out[12], v[12];
    int64_t *runs = malloc((n + 1) * sizeof *runs);
    tu_randn(X, q * ld, 7);
    tu_randn(y, n, 8);
    tu_randn(v, q, 9);
    for (int k = 0; k < q; k++)
        for (int64_t i = 0; i < n; i++) {
            if ((i / 37) % 3 != 0 || i < 500 || i >= n - 300) X[k * ld + i] = (k % 2) ? -0.0 : 0.0; /* zero rows */
            else if ((i + k) % 5 == 0) X[k * ld + i] = 0.0; /* and zeros inside the runs */
        }
    const int nruns = wt_vec_runs(X, ld, q, n, runs);
    ck_assert_int_gt(nruns, 100);
    for (int j = 0; j < nruns; j++) ck_assert(runs[2 * j] < runs[2 * j + 1] && (j == 0 || runs[2 * j - 1] < runs[2 * j]));
    for (int th = 1; th <= 2; th++) {
        wt_vec_dot_many(X, ld, q, y, n, runs, nruns, out, th);
        for (int k = 0; k < q; k++) {
            const double ref = wt_vec_dot(X + k * ld, y, n);
            ck_assert_msg(memcmp(&out[k], &ref, sizeof ref) == 0, "dot %d: %.17g against %.17g", k, out[k], ref);
        }
        tu_randn(z1, n, 10);
        for (int64_t i = 0; i < n; i += 7) z1[i] = (i % 2) ? -0.0 : 0.0;
        memcpy(z2, z1, n * sizeof *z1);
        wt_vec_sub_many(z1, X, ld, q, v, n, runs, nruns, th);
        for (int k = 0; k < q; k++)
            for (int64_t i = 0; i < n; i++) z2[i] -= v[k] * X[k * ld + i];
        ck_assert_mem_eq(z1, z2, n * sizeof *z1);
    }
    free(X), free(y), free(z1), free(z2), free(runs);
}
END_TEST

/* wt_context_set_threads reaches the context-free kernels: with 1 thread asked for, a dot's parallel region
 * runs on one thread (it used to take OpenMP's default, the machine's count). */
START_TEST(test_context_threads_reach_kernels)
{
#ifdef _OPENMP
    omp_set_num_threads(2);
    wt_context *ctx = tu_context();
    wt_context_set_threads(ctx, 1);
    ck_assert_int_eq(omp_get_max_threads(), 1);
    int seen = 0;
#pragma omp parallel
    {
#pragma omp atomic
        seen++;
    }
    ck_assert_int_eq(seen, 1);
    wt_context_set_threads(ctx, 0); /* <= 0 leaves OpenMP's setting alone */
    ck_assert_int_eq(omp_get_max_threads(), 1);
    wt_context_free(ctx);
    omp_set_num_threads(2);
#endif
}
END_TEST

/* wt_vec_first_nonfinite: -1 on finite data (zeros of both signs, the largest double), else the first NaN or
 * ±Inf wherever it sits (the 8 lanes, the tail past the last whole 8), several of them: the first one */
START_TEST(test_first_nonfinite)
{
    const int64_t n = 8 * 37 + 5;
    double *x = malloc(n * sizeof *x);
    tu_randn(x, n, 3);
    x[3] = -0.0, x[4] = 0.0, x[5] = DBL_MAX, x[6] = -DBL_MAX;
    ck_assert_int_eq(wt_vec_first_nonfinite(x, n), -1);
    ck_assert_int_eq(wt_vec_first_nonfinite(x, 0), -1);
    const double bad[3] = {NAN, INFINITY, -INFINITY};
    const int64_t at[] = {0, 7, 8, 150, n - 6, n - 5, n - 1};
    for (int b = 0; b < 3; b++)
        for (size_t k = 0; k < sizeof at / sizeof *at; k++) {
            const double keep = x[at[k]];
            x[at[k]] = bad[b];
            ck_assert_int_eq(wt_vec_first_nonfinite(x, n), at[k]);
            ck_assert_int_eq(wt_vec_first_nonfinite(x, at[k]), -1); /* only the rows before it */
            x[n - 1 - (at[k] == n - 1)] = INFINITY; /* a second one after it (or just before the last) */
            ck_assert_int_eq(wt_vec_first_nonfinite(x, n), at[k] < n - 2 ? at[k] : n - 2);
            x[n - 1 - (at[k] == n - 1)] = 1.0;
            x[at[k]] = keep;
        }
    free(x);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("vec");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_dot_is_chunked_sum);
    tcase_add_test(tc, test_many_equal_single);
    tcase_add_test(tc, test_many_skip_zero_rows);
    tcase_add_test(tc, test_context_threads_reach_kernels);
    tcase_add_test(tc, test_first_nonfinite);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
