/* core/base/base.h: status codes, the context (error, allocator and log hooks), timers.
 *
 * Conventions (docs/design.md, docs/c-api.md):
 *  - every fallible function returns an int status: WT_OK = 0, errors < 0, warnings > 0;
 *  - the library never exits or prints; errors are recorded in the caller's wt_context with the
 *    file, line and a message, and handed to the context's error hook if one is set;
 *  - no global mutable state: everything a call needs (hooks, thread count) lives in the context,
 *    which the caller owns and passes to constructors; objects keep a pointer to it.
 */
#ifndef WT_BASE_H
#define WT_BASE_H

#include <stddef.h>
#include <stdint.h>
#include <stdarg.h>

/* The public part of this module: the status codes, the context and its hooks (wavetomo/context.h),
 * the version (wavetomo/version.h). What follows here is the library's internal side. */
#include "wavetomo/context.h"
#include "wavetomo/version.h"

#define WT_VERSION WT_VERSION_STRING

/* Record an error (or warning) and return its status. Use through WT_ERROR. */
int wt_error_set(wt_context *ctx, int status, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
#define WT_ERROR(ctx, status, ...) wt_error_set((ctx), (status), __FILE__, __LINE__, __VA_ARGS__)
void wt_log(wt_context *ctx, int level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Allocation through the context's hooks. Sizes are checked for overflow (n * size).
 * wt_free accepts NULL. wt_calloc zeroes. All return NULL on failure without recording an error;
 * use WT_ALLOC to record one. */
void *wt_malloc(wt_context *ctx, size_t n, size_t size);
void *wt_calloc(wt_context *ctx, size_t n, size_t size);
void wt_free(wt_context *ctx, void *ptr);
/* p = wt_calloc(ctx, n, sizeof *p) or record WT_ERR_NOMEM naming what, and goto label `fail`.
 * Requires an `int st` in scope. */
#define WT_ALLOC(ctx, p, n, what)                                                                 \
    do {                                                                                          \
        (p) = wt_calloc((ctx), (size_t)(n), sizeof *(p));                                         \
        if (!(p) && (size_t)(n) > 0) {                                                            \
            st = WT_ERROR((ctx), WT_ERR_NOMEM, "out of memory allocating %s (%zu bytes)", (what), \
                          (size_t)(n) * sizeof *(p));                                             \
            goto fail;                                                                            \
        }                                                                                         \
    } while (0)
/* A hot kernel compiled for the baseline x86-64 (SSE2) and, picked at load time when the CPU has them, for
 * AVX2 and AVX-512. Every clone does the same IEEE operations in the same order (ISO C mode: no contraction
 * into FMA), so the results do not depend on the CPU; only the vector width does. Empty where GCC's
 * target_clones is not available (clang, other systems). */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define WT_CPU_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define WT_CPU_CLONES
#endif

/* Evaluate a status expression; on error jump to `fail` keeping it in st. */
#define WT_TRY(expr)          \
    do {                      \
        st = (expr);          \
        if (st < 0) goto fail; \
    } while (0)

/* Monotonic wall clock [s]. */
double wt_time_now(void);
/* p rounded up to the next 64-byte boundary (a cache line; FFTW's and AVX-512's alignment): for arrays
 * allocated 8 doubles longer than they are used */
static inline double *wt_align64(double *p) { return (double *)(((uintptr_t)p + 63) & ~(uintptr_t)63); }

/* The calling thread's index in its OpenMP team and the team's size (0 and 1 outside a parallel region or
 * without OpenMP): the split of a parallel region's fixed pieces. */
void wt_thread_team(int *id, int *nt);
/* The calling thread's index in its OpenMP team (0 outside a parallel region or without OpenMP): a per-thread
 * workspace's slot. */
int wt_thread_id(void);

#endif
