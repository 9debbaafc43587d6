/* tests/test_rng.c: the random numbers (core/base/rng.h): xoshiro256** against its published generator (the
 * reference recurrence, state {1, 2, 3, 4}), the (seed, stream) seeding that every draw of wavetomo rests on
 * (the same pair, the same sequence; another stream, an unrelated one), and the uniform and normal deviates'
 * range and moments, with tolerances of 6 standard errors of the estimate. */
#include "core/base/rng.h"
#include "testutil.h"

#include <math.h>

START_TEST(test_reference)
{
    /* xoshiro256** (Blackman & Vigna) from the state {1, 2, 3, 4}: its first outputs */
    wt_rng r = {.s = {1, 2, 3, 4}};
    const uint64_t want[6] = {11520ULL, 0ULL, 1509978240ULL, 1215971899390074240ULL, 1216172134540287360ULL,
                              607988272756665600ULL};
    for (int i = 0; i < 6; i++) ck_assert_uint_eq(wt_rng_u64(&r), want[i]);
}
END_TEST

START_TEST(test_streams)
{
    wt_rng a, b, c, d;
    wt_rng_init(&a, 42, 7);
    wt_rng_init(&b, 42, 7);
    wt_rng_init(&c, 42, 8);
    wt_rng_init(&d, 43, 7);
    int same_c = 0, same_d = 0;
    for (int i = 0; i < 1000; i++) {
        const uint64_t x = wt_rng_u64(&a);
        ck_assert_uint_eq(x, wt_rng_u64(&b));
        same_c += x == wt_rng_u64(&c);
        same_d += x == wt_rng_u64(&d);
    }
    ck_assert_int_eq(same_c, 0);
    ck_assert_int_eq(same_d, 0);
    /* neighbouring streams are uncorrelated: |corr| of their uniforms within 6 / sqrt(N) */
    const int n = 100000;
    double sxy = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
    wt_rng_init(&a, 1, 0);
    wt_rng_init(&c, 1, 1);
    for (int i = 0; i < n; i++) {
        const double x = wt_rng_uniform(&a), y = wt_rng_uniform(&c);
        sx += x, sy += y, sxy += x * y, sxx += x * x, syy += y * y;
    }
    const double cov = sxy / n - sx / n * sy / n;
    const double corr = cov / sqrt((sxx / n - sx / n * sx / n) * (syy / n - sy / n * sy / n));
    ck_assert_double_le(fabs(corr), 6.0 / sqrt(n));
}
END_TEST

START_TEST(test_moments)
{
    const int n = 200000;
    wt_rng r;
    wt_rng_init(&r, 2026, 3);
    double s = 0, ss = 0;
    for (int i = 0; i < n; i++) {
        const double u = wt_rng_uniform(&r);
        ck_assert(u >= 0.0 && u < 1.0);
        s += u, ss += u * u;
    }
    /* uniform: mean 1/2 (standard error sqrt(1/12 n)), variance 1/12 (sqrt(1/180 n)) */
    ck_assert_double_le(fabs(s / n - 0.5), 6.0 * sqrt(1.0 / (12.0 * n)));
    ck_assert_double_le(fabs(ss / n - s / n * s / n - 1.0 / 12.0), 6.0 * sqrt(1.0 / (180.0 * n)));
    /* normal: mean 0 (1/sqrt(n)), variance 1 (sqrt(2/n)), fourth moment 3 (sqrt(96/n)) */
    double m1 = 0, m2 = 0, m4 = 0;
    for (int i = 0; i < n; i++) {
        const double x = wt_rng_normal(&r);
        ck_assert(isfinite(x));
        m1 += x, m2 += x * x, m4 += x * x * x * x;
    }
    m1 /= n, m2 /= n, m4 /= n;
    ck_assert_double_le(fabs(m1), 6.0 / sqrt(n));
    ck_assert_double_le(fabs(m2 - 1.0), 6.0 * sqrt(2.0 / n));
    ck_assert_double_le(fabs(m4 - 3.0), 6.0 * sqrt(96.0 / n));
    /* a copy is the same generator from there on (a plain value, the Box–Muller spare included) */
    (void)wt_rng_normal(&r);
    wt_rng copy = r;
    for (int i = 0; i < 5; i++) ck_assert(wt_rng_normal(&r) == wt_rng_normal(&copy));
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("rng");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_reference);
    tcase_add_test(tc, test_streams);
    tcase_add_test(tc, test_moments);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
