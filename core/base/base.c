/* core/base/base.c: status names, the context and its hooks, timers. */
#include "base.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

struct wt_context {
    wt_error_hook error_hook;
    void *error_user;
    wt_log_hook log_hook;
    void *log_user;
    int log_max_level;
    wt_malloc_hook malloc_hook;
    wt_free_hook free_hook;
    void *alloc_user;
    int nthreads;
    int last_status;
    char message[2048];
};

const char *wt_strerror(int status)
{
    switch (status) {
    case WT_OK: return "success";
    case WT_WARN_MAXITER: return "iteration cap reached";
    case WT_WARN_BREAKDOWN: return "iterative solver stopped at a breakdown (residual reported)";
    case WT_ERR_NOMEM: return "out of memory";
    case WT_ERR_INVALID: return "invalid argument";
    case WT_ERR_CONFIG: return "configuration error";
    case WT_ERR_IO: return "input/output error";
    case WT_ERR_LIBRARY: return "external library error";
    case WT_ERR_NUMERIC: return "numerical error";
    case WT_ERR_FORMAT: return "file format error";
    case WT_ERR_INTERRUPTED: return "interrupted by a signal";
    default: return status < 0 ? "unknown error" : "unknown warning";
    }
}

wt_context *wt_context_alloc(void)
{
    wt_context *ctx = calloc(1, sizeof *ctx);
    if (!ctx) return NULL;
    ctx->log_max_level = -1;
    return ctx;
}

void wt_context_free(wt_context *ctx) { free(ctx); }

void wt_context_set_error_hook(wt_context *ctx, wt_error_hook hook, void *user)
{
    ctx->error_hook = hook;
    ctx->error_user = user;
}

void wt_context_set_log_hook(wt_context *ctx, wt_log_hook hook, void *user, int max_level)
{
    ctx->log_hook = hook;
    ctx->log_user = user;
    ctx->log_max_level = max_level;
}

void wt_context_set_allocator(wt_context *ctx, wt_malloc_hook m, wt_free_hook f, void *user)
{
    ctx->malloc_hook = m;
    ctx->free_hook = f;
    ctx->alloc_user = user;
}

/* The vector and sparse kernels (core/la) take no context, so their OpenMP regions follow OpenMP's own
 * setting: set it too, or a caller that asks for 1 thread still gets the machine's count there. */
void wt_context_set_threads(wt_context *ctx, int nthreads)
{
    ctx->nthreads = nthreads;
#ifdef _OPENMP
    if (nthreads > 0) omp_set_num_threads(nthreads);
#endif
}

int wt_context_threads(const wt_context *ctx)
{
    if (ctx && ctx->nthreads > 0) return ctx->nthreads;
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

void wt_thread_team(int *id, int *nt)
{
#ifdef _OPENMP
    *id = omp_get_thread_num();
    *nt = omp_get_num_threads();
#else
    *id = 0;
    *nt = 1;
#endif
}

int wt_thread_id(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

int wt_error_set(wt_context *ctx, int status, const char *file, int line, const char *fmt, ...)
{
    if (!ctx) return status;
    /* Formatted into a local buffer first: a message may quote the previous one
     * (WT_ERROR(ctx, st, "%s: %s", path, wt_error_message(ctx))), and a thread inside a parallel region
     * must not write the shared buffer while another does: the copy and the hook are one critical
     * section, so the context holds one whole message (the last one written). */
    char buf[sizeof ctx->message];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
#pragma omp critical(wt_context_error)
    {
        memcpy(ctx->message, buf, sizeof buf);
        ctx->last_status = status;
        if (ctx->error_hook) ctx->error_hook(ctx->error_user, status, file, line, ctx->message);
    }
    return status;
}

const char *wt_error_message(const wt_context *ctx) { return ctx ? ctx->message : ""; }
int wt_error_status(const wt_context *ctx) { return ctx ? ctx->last_status : WT_OK; }

void wt_error_clear(wt_context *ctx)
{
    ctx->message[0] = '\0';
    ctx->last_status = WT_OK;
}

void wt_log(wt_context *ctx, int level, const char *fmt, ...)
{
    if (!ctx || !ctx->log_hook || level > ctx->log_max_level) return;
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    ctx->log_hook(ctx->log_user, level, buf);
}

void *wt_malloc(wt_context *ctx, size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size) return NULL;
    size_t bytes = n * size;
    if (bytes == 0) bytes = 1; /* a valid, freeable pointer for empty arrays */
    if (ctx && ctx->malloc_hook) return ctx->malloc_hook(ctx->alloc_user, bytes);
    return malloc(bytes);
}

void *wt_calloc(wt_context *ctx, size_t n, size_t size)
{
    void *p = wt_malloc(ctx, n, size);
    if (p) memset(p, 0, n * size);
    return p;
}

void wt_free(wt_context *ctx, void *ptr)
{
    if (!ptr) return;
    if (ctx && ctx->free_hook) ctx->free_hook(ctx->alloc_user, ptr);
    else free(ptr);
}

double wt_time_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

const char *wt_version(void) { return WT_VERSION_STRING; }
int wt_version_number(void) { return WT_VERSION_NUMBER; }
