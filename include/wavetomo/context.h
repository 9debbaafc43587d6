/* wavetomo/context.h: status codes and the context that carries errors, hooks and the thread count.
 *
 * Part of the public, stable interface (docs/c-api.md).
 *  - Every fallible call returns an int status: WT_OK = 0, errors < 0, warnings > 0 (the result is
 *    usable). wt_strerror names a status; the context holds the message of the last one recorded
 *    (wt_error_message), which says what went wrong and where (file, key, frame, index).
 *  - The library never exits, aborts or prints: it records errors in the caller's context and hands
 *    them to the context's error hook when one is set. There is no global mutable state: everything a
 *    call needs lives in the context, which the caller creates, owns and passes to constructors.
 *  - Allocation goes through the context's allocator (malloc/free unless replaced): a test can count
 *    or refuse allocations through it.
 * A context may be shared by objects used from different threads (its message is written under a
 * lock; the last error wins); give each thread its own context when each must read its own message.
 */
#ifndef WAVETOMO_CONTEXT_H
#define WAVETOMO_CONTEXT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

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

/* Human-readable name of a status code (a static string; never NULL). */
const char *wt_strerror(int status);

typedef struct wt_context wt_context;

/* Called for every error or warning recorded, with its status, the library source file and line, and
 * the message. */
typedef void (*wt_error_hook)(void *user, int status, const char *file, int line, const char *msg);
/* Called for log messages of level <= max_level (WT_LOG_*). */
typedef void (*wt_log_hook)(void *user, int level, const char *msg);
typedef void *(*wt_malloc_hook)(void *user, size_t size);
typedef void (*wt_free_hook)(void *user, void *ptr);

enum { WT_LOG_ERROR = 0, WT_LOG_WARN = 1, WT_LOG_INFO = 2, WT_LOG_DEBUG = 3 };

/* Create a context with default hooks: malloc/free, no error hook, no logging.
 * Returns NULL only when the context itself cannot be allocated. */
wt_context *wt_context_alloc(void);
/* Free a context (NULL is accepted). Every object made with it must be freed first. */
void wt_context_free(wt_context *ctx);

void wt_context_set_error_hook(wt_context *ctx, wt_error_hook hook, void *user);
void wt_context_set_log_hook(wt_context *ctx, wt_log_hook hook, void *user, int max_level);
/* Replace the allocator before creating objects with the context (a block is freed by the hook pair
 * that allocated it). */
void wt_context_set_allocator(wt_context *ctx, wt_malloc_hook m, wt_free_hook f, void *user);
/* Threads the library may use in its OpenMP regions (<= 0: all the machine offers). A positive count also
 * becomes OpenMP's default for the calling thread (omp_set_num_threads): the context-free kernels use that. */
void wt_context_set_threads(wt_context *ctx, int nthreads);
int wt_context_threads(const wt_context *ctx);

/* The last recorded message ("" if none; valid until the next error on ctx) and its status. */
const char *wt_error_message(const wt_context *ctx);
int wt_error_status(const wt_context *ctx);
void wt_error_clear(wt_context *ctx);

#ifdef __cplusplus
}
#endif

#endif
