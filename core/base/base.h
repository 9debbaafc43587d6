/* core/base/base.h: status codes, the context (error, allocator and log hooks), timers.
 *
 * Conventions (docs/design.md):
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

#define WT_VERSION "0.1.0"

enum {
    WT_OK = 0,
    /* warnings (> 0): the result is usable */
    WT_WARN_MAXITER = 1,   /* an iterative solver stopped at its iteration cap before its tolerance */
    WT_WARN_BREAKDOWN = 2, /* an iterative solver stopped early at a breakdown at rounding level (pᵀAp or rᵀz
                              no longer > 0): the last iterate is kept and its residual reported */
    /* errors (< 0) */
    WT_ERR_NOMEM = -1,     /* an allocation failed */
    WT_ERR_INVALID = -2,   /* a bad argument or inconsistent sizes */
    WT_ERR_CONFIG = -3,    /* a configuration file or override is malformed or out of range */
    WT_ERR_IO = -4,        /* a file could not be read or written */
    WT_ERR_LIBRARY = -5,   /* an external library (HDF5, CHOLMOD, FFTW, LAPACK) reported a failure */
    WT_ERR_NUMERIC = -6,   /* NaN/Inf, breakdown, loss of positive definiteness */
    WT_ERR_FORMAT = -7,    /* a file has the wrong shape, type or provenance */
    WT_ERR_INTERRUPTED = -8 /* stopped by SIGINT/SIGTERM/SIGHUP at a point where the caller keeps what is done */
};

/* Human-readable name of a status code; never NULL. */
const char *wt_strerror(int status);

typedef struct wt_context wt_context;

typedef void (*wt_error_hook)(void *user, int status, const char *file, int line, const char *msg);
typedef void (*wt_log_hook)(void *user, int level, const char *msg);
typedef void *(*wt_malloc_hook)(void *user, size_t size);
typedef void (*wt_free_hook)(void *user, void *ptr);

enum { WT_LOG_ERROR = 0, WT_LOG_WARN = 1, WT_LOG_INFO = 2, WT_LOG_DEBUG = 3 };

/* Create a context with default hooks: malloc/free, no error hook, no logging.
 * Returns NULL only when the context itself cannot be allocated. */
wt_context *wt_context_alloc(void);
void wt_context_free(wt_context *ctx);

void wt_context_set_error_hook(wt_context *ctx, wt_error_hook hook, void *user);
void wt_context_set_log_hook(wt_context *ctx, wt_log_hook hook, void *user, int max_level);
/* Replace the allocator (tests count allocations or inject failures with it). */
void wt_context_set_allocator(wt_context *ctx, wt_malloc_hook m, wt_free_hook f, void *user);
/* Threads the library may use in its OpenMP regions (<= 0: all the machine offers). A positive count also
 * becomes OpenMP's default for the calling thread (omp_set_num_threads): the context-free kernels use that. */
void wt_context_set_threads(wt_context *ctx, int nthreads);
int wt_context_threads(const wt_context *ctx);

/* Record an error (or warning) and return its status. Use through WT_ERROR. */
int wt_error_set(wt_context *ctx, int status, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
#define WT_ERROR(ctx, status, ...) wt_error_set((ctx), (status), __FILE__, __LINE__, __VA_ARGS__)
/* The last recorded message ("" if none) and its status. */
const char *wt_error_message(const wt_context *ctx);
int wt_error_status(const wt_context *ctx);
void wt_error_clear(wt_context *ctx);

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

#endif
