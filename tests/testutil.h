/* tests/testutil.h: helpers shared by the Check suites: relative comparisons, random vectors, a
 * context whose errors are kept for inspection, and the main() every suite uses. */
#ifndef WT_TESTUTIL_H
#define WT_TESTUTIL_H

#include <check.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base/base.h"
#include "core/base/rng.h"

/* |a - b| <= rtol * max(|a|, |b|, floor): relative agreement with an absolute floor for zeros. */
#define ck_assert_rel(a, b, rtol, floor)                                                         \
    do {                                                                                         \
        double a_ = (a), b_ = (b), s_ = fmax(fmax(fabs(a_), fabs(b_)), (floor));                \
        ck_assert_msg(fabs(a_ - b_) <= (rtol) * s_, "%s = %.17g vs %s = %.17g: rel diff %.3g > %.3g", \
                      #a, a_, #b, b_, fabs(a_ - b_) / s_, (double)(rtol));                       \
    } while (0)

static inline double tu_dot(const double *x, const double *y, long n)
{
    double s = 0.0;
    for (long i = 0; i < n; i++) s += x[i] * y[i];
    return s;
}

static inline double tu_norm(const double *x, long n) { return sqrt(tu_dot(x, x, n)); }

/* ||x - y|| / ||y|| */
static inline double tu_rel_diff(const double *x, const double *y, long n)
{
    double d = 0.0, s = 0.0;
    for (long i = 0; i < n; i++) {
        d += (x[i] - y[i]) * (x[i] - y[i]);
        s += y[i] * y[i];
    }
    return s > 0 ? sqrt(d / s) : sqrt(d);
}

static inline void tu_randn(double *x, long n, unsigned long seed)
{
    wt_rng r;
    wt_rng_init(&r, seed, 0);
    for (long i = 0; i < n; i++) x[i] = wt_rng_normal(&r);
}

/* A context for tests: no hooks; the last error message is read back with wt_error_message. */
static inline wt_context *tu_context(void)
{
    wt_context *ctx = wt_context_alloc();
    ck_assert_ptr_nonnull(ctx);
    return ctx;
}

/* Every suite file defines `Suite *make_suite(void)` and ends with TU_MAIN. */
#define TU_MAIN                                              \
    int main(void)                                           \
    {                                                        \
        SRunner *sr = srunner_create(make_suite());          \
        srunner_run_all(sr, CK_NORMAL);                      \
        int nf = srunner_ntests_failed(sr);                  \
        srunner_free(sr);                                    \
        return nf == 0 ? EXIT_SUCCESS : EXIT_FAILURE;        \
    }

#endif
