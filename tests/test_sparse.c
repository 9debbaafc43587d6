/* tests/test_sparse.c: CSC assembly, transpose, products and sums against dense arithmetic. */
#include "core/la/sparse.h"
#include "testutil.h"

static void dense_of(const wt_sparse *a, double *d)
{
    memset(d, 0, sizeof(double) * a->nrow * a->ncol);
    for (int64_t c = 0; c < a->ncol; c++)
        for (int64_t k = a->colptr[c]; k < a->colptr[c + 1]; k++) d[a->rowind[k] + a->nrow * c] += a->val[k];
}

static wt_sparse *random_sparse(wt_context *ctx, int m, int n, double density, unsigned long seed, int dups)
{
    wt_rng r;
    wt_rng_init(&r, seed, 0);
    wt_triplet *t;
    ck_assert_int_eq(wt_triplet_alloc(ctx, m, n, 4, &t), WT_OK);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < m; i++)
            if (wt_rng_uniform(&r) < density) {
                ck_assert_int_eq(wt_triplet_add(t, i, j, wt_rng_normal(&r)), WT_OK);
                if (dups) ck_assert_int_eq(wt_triplet_add(t, i, j, 1.0), WT_OK);
            }
    wt_sparse *a;
    ck_assert_int_eq(wt_triplet_compress(t, &a), WT_OK);
    wt_triplet_free(t);
    return a;
}

START_TEST(test_triplet_sums_duplicates_and_sorts)
{
    wt_context *ctx = tu_context();
    wt_triplet *t;
    ck_assert_int_eq(wt_triplet_alloc(ctx, 3, 2, 1, &t), WT_OK);
    ck_assert_int_eq(wt_triplet_add(t, 2, 0, 1.0), WT_OK);
    ck_assert_int_eq(wt_triplet_add(t, 0, 0, 2.0), WT_OK);
    ck_assert_int_eq(wt_triplet_add(t, 2, 0, 3.0), WT_OK);
    ck_assert_int_eq(wt_triplet_add(t, 1, 1, 5.0), WT_OK);
    ck_assert_int_eq(wt_triplet_add(t, 1, 1, -5.0), WT_OK); /* cancels: dropped */
    ck_assert_int_eq(wt_triplet_add(t, 3, 0, 1.0), WT_ERR_INVALID);
    wt_sparse *a;
    ck_assert_int_eq(wt_triplet_compress(t, &a), WT_OK);
    ck_assert_int_eq(wt_sparse_nnz(a), 2);
    ck_assert_int_eq(a->rowind[0], 0);
    ck_assert_int_eq(a->rowind[1], 2);
    ck_assert_double_eq(a->val[1], 4.0);
    ck_assert_int_eq(a->colptr[2], 2);
    wt_sparse_free(a);
    wt_triplet_free(t);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_products_match_dense)
{
    wt_context *ctx = tu_context();
    const int m = 37, k = 23, n = 31;
    wt_sparse *a = random_sparse(ctx, m, k, 0.2, 1, 1), *b = random_sparse(ctx, k, n, 0.15, 2, 0);
    double da[37 * 23], db[23 * 31], dc[37 * 31], ref[37 * 31] = {0};
    dense_of(a, da);
    dense_of(b, db);
    for (int j = 0; j < n; j++)
        for (int p = 0; p < k; p++)
            for (int i = 0; i < m; i++) ref[i + m * j] += da[i + m * p] * db[p + k * j];
    wt_sparse *c, *at;
    ck_assert_int_eq(wt_sparse_multiply(a, b, &c), WT_OK);
    dense_of(c, dc);
    ck_assert_double_le(tu_rel_diff(dc, ref, m * n), 1e-15);
    for (int j = 0; j < n; j++)
        for (int64_t q = c->colptr[j] + 1; q < c->colptr[j + 1]; q++) ck_assert_int_lt(c->rowind[q - 1], c->rowind[q]);
    ck_assert_int_eq(wt_sparse_transpose(a, &at), WT_OK);
    double x[37], y1[23] = {0}, y2[23] = {0};
    tu_randn(x, m, 5);
    wt_sparse_apply_t(a, 2.0, x, y1);
    wt_sparse_apply(at, 2.0, x, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, k), 1e-15);
    wt_sparse *bad;
    ck_assert_int_eq(wt_sparse_multiply(a, a, &bad), WT_ERR_INVALID);
    wt_sparse_free(a);
    wt_sparse_free(b);
    wt_sparse_free(c);
    wt_sparse_free(at);
    wt_context_free(ctx);
}
END_TEST

/* αA + βB against the dense sum: every element is one or two products and one add, so equal to the dense
 * formula exactly; canonical (sorted, no zeros: B − B cancels to an empty matrix); sizes checked. */
START_TEST(test_add_matches_dense)
{
    wt_context *ctx = tu_context();
    const int m = 29, n = 17;
    wt_sparse *a = random_sparse(ctx, m, n, 0.3, 3, 0), *b = random_sparse(ctx, m, n, 0.25, 4, 1), *c, *z, *bad;
    double da[29 * 17], db[29 * 17], dc[29 * 17];
    dense_of(a, da);
    dense_of(b, db);
    ck_assert_int_eq(wt_sparse_add(a, 2.0, b, -0.5, &c), WT_OK);
    dense_of(c, dc);
    for (int i = 0; i < m * n; i++) ck_assert_double_eq(dc[i], 2.0 * da[i] + -0.5 * db[i]);
    for (int j = 0; j < n; j++)
        for (int64_t q = c->colptr[j]; q < c->colptr[j + 1]; q++) {
            if (q > c->colptr[j]) ck_assert_int_lt(c->rowind[q - 1], c->rowind[q]);
            ck_assert_double_ne(c->val[q], 0.0);
        }
    ck_assert_int_eq(wt_sparse_add(b, 1.0, b, -1.0, &z), WT_OK);
    ck_assert_int_eq(wt_sparse_nnz(z), 0);
    wt_sparse *at;
    ck_assert_int_eq(wt_sparse_transpose(a, &at), WT_OK);
    ck_assert_int_eq(wt_sparse_add(a, 1.0, at, 1.0, &bad), WT_ERR_INVALID);
    wt_sparse_free(a), wt_sparse_free(b), wt_sparse_free(c), wt_sparse_free(z), wt_sparse_free(at);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("sparse");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_triplet_sums_duplicates_and_sorts);
    tcase_add_test(tc, test_products_match_dense);
    tcase_add_test(tc, test_add_matches_dense);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
