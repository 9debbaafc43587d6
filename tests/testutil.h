/* tests/testutil.h: helpers shared by the Check suites: relative comparisons, random vectors, a
 * context whose errors are kept for inspection, and the main() every suite uses. */
#ifndef WT_TESTUTIL_H
#define WT_TESTUTIL_H

#include <check.h>
#include <stdarg.h>
#include <sys/wait.h>
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

/* The command-line suites' fixture: wt = the binary under test ($BIN/wavetomo, else bin/wavetomo) and
 * dir = a fresh directory /tmp/<prefix>XXXXXX, removed with everything in it by tu_cli_teardown. */
static inline void tu_cli_setup(char *wt, size_t nwt, char *dir, size_t ndir, const char *prefix)
{
    const char *bin = getenv("BIN");
    snprintf(wt, nwt, "%s/wavetomo", bin ? bin : "bin");
    snprintf(dir, ndir, "/tmp/%sXXXXXX", prefix);
    ck_assert_ptr_nonnull(mkdtemp(dir));
}

static inline void tu_cli_teardown(const char *dir)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
}

/* Run `wt fmt…` through the shell with its stdout and stderr in dir/stdout.txt and dir/stderr.txt; the exit
 * status (−1: killed). */
static inline int tu_run(const char *wt, const char *dir, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static inline int tu_run(const char *wt, const char *dir, const char *fmt, ...)
{
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(cmd, sizeof cmd, "%s ", wt);
    vsnprintf(cmd + n, sizeof cmd - (size_t)n, fmt, ap);
    va_end(ap);
    size_t l = strlen(cmd);
    snprintf(cmd + l, sizeof cmd - l, " > %s/stdout.txt 2> %s/stderr.txt", dir, dir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Whether dir/name (its first 64 kB) holds text. */
static inline int tu_file_has(const char *dir, const char *name, const char *text)
{
    char path[512];
    static char buf[65536];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    return strstr(buf, text) != NULL;
}

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

/* An allocator for a context that refuses chosen allocations and counts what it grants, for the
 * allocation-failure tests: every failure must surface as WT_ERR_NOMEM and leave `live` at 0.
 * Allocation requests are numbered from 0 in `count`; the request numbered `fail_at` is refused and,
 * unless `once` is set, so is every later one (a budget of fail_at allocations). Declare it with
 * TU_ALLOC_INIT (refuses nothing), then aim it with tu_alloc_budget or tu_alloc_fail_nth. */
typedef struct tu_alloc {
    long fail_at; /* number of the first request refused; < 0: none */
    int once;     /* nonzero: refuse request fail_at only; zero: refuse it and all after it */
    long count;   /* requests seen, refused ones included */
    long nalloc;  /* requests granted */
    long failed;  /* requests refused */
    long live;    /* granted blocks not yet freed */
} tu_alloc;

#define TU_ALLOC_INIT {.fail_at = -1}

static inline void *tu_alloc_malloc(void *user, size_t size)
{
    tu_alloc *a = user;
    long k = a->count++;
    if (a->fail_at >= 0 && (a->once ? k == a->fail_at : k >= a->fail_at)) {
        a->failed++;
        return NULL;
    }
    void *p = malloc(size);
    if (p) a->nalloc++, a->live++;
    return p;
}

static inline void tu_alloc_free(void *user, void *p)
{
    tu_alloc *a = user;
    if (p) a->live--;
    free(p);
}

/* Route ctx's allocations through a (which must outlive them, or be uninstalled first). */
static inline void tu_alloc_install(wt_context *ctx, tu_alloc *a)
{
    wt_context_set_allocator(ctx, tu_alloc_malloc, tu_alloc_free, a);
}

/* From now on grant k more requests and refuse all later ones; k < 0: refuse nothing. */
static inline void tu_alloc_budget(tu_alloc *a, long k)
{
    a->fail_at = k < 0 ? -1 : a->count + k;
    a->once = 0;
}

/* Refuse only the k-th request from now on (k = 0: the next one); the ones after it are granted. */
static inline void tu_alloc_fail_nth(tu_alloc *a, long k)
{
    a->fail_at = a->count + k;
    a->once = 1;
}

/* Assemble an operator under allocation budgets 0, 1, 2, … until it succeeds: every refused attempt
 * must report WT_ERR_NOMEM and leave its output NULL. `call` uses the wt_sparse * named A, e.g.
 * TU_ASSEMBLE_UNDER_BUDGETS(&fa, A, wt_projection_assemble(p, &A)). Lifts the budget afterwards. */
#define TU_ASSEMBLE_UNDER_BUDGETS(fa, A, call)                 \
    do {                                                       \
        for (int b_ = 0; b_ < 20; b_++) {                      \
            wt_sparse *A = (wt_sparse *)&A;                    \
            tu_alloc_budget((fa), b_);                         \
            int sa_ = (call);                                  \
            if (sa_ == WT_OK) {                                \
                wt_sparse_free(A);                             \
                break;                                         \
            }                                                  \
            ck_assert_int_eq(sa_, WT_ERR_NOMEM);               \
            ck_assert_ptr_null(A);                             \
        }                                                      \
        tu_alloc_budget((fa), -1);                             \
    } while (0)

/* Every suite file defines `Suite *make_suite(void)` and ends with TU_MAIN. */
Suite *make_suite(void);
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
