/* tests/test_base.c: the foundation's context (core/base/base.h, include/wavetomo/context.h): an error is recorded
 * with its status and whole message and reaches the hook with the source file and line, a message may quote the
 * previous one, the log hook sees only its levels, and the allocator refuses an overflowing n x size, routes
 * through the context's hooks, zeroes for calloc and gives a freeable pointer for an empty array. */
#include "core/base/base.h"
#include "testutil.h"

#include <stdint.h>

/* checked fixture: a fresh context for every test */
static wt_context *ctx;
static void setup(void) { ctx = tu_context(); }
static void teardown(void) { wt_context_free(ctx); }

typedef struct seen {
    int calls, status, line, level;
    char file[256], msg[2048];
} seen;

static void error_hook(void *user, int status, const char *file, int line, const char *msg)
{
    seen *s = user;
    s->calls++, s->status = status, s->line = line;
    snprintf(s->file, sizeof s->file, "%s", file);
    snprintf(s->msg, sizeof s->msg, "%s", msg);
}

START_TEST(test_error)
{
    ck_assert_int_eq(wt_error_status(ctx), WT_OK);
    ck_assert_str_eq(wt_error_message(ctx), "");
    seen s = {0};
    wt_context_set_error_hook(ctx, error_hook, &s);
    const int line = __LINE__ + 1;
    ck_assert_int_eq(WT_ERROR(ctx, WT_ERR_CONFIG, "key '%s': %d is out of range", "loop.delay", 7), WT_ERR_CONFIG);
    ck_assert_int_eq(wt_error_status(ctx), WT_ERR_CONFIG);
    ck_assert_str_eq(wt_error_message(ctx), "key 'loop.delay': 7 is out of range");
    ck_assert_int_eq(s.calls, 1);
    ck_assert_int_eq(s.status, WT_ERR_CONFIG);
    ck_assert_int_eq(s.line, line);
    ck_assert_str_eq(s.file, __FILE__);
    ck_assert_str_eq(s.msg, "key 'loop.delay': 7 is out of range");
    /* a message that quotes the previous one (the drivers' "PATH: previous message") */
    WT_ERROR(ctx, WT_ERR_IO, "run.h5: %s", wt_error_message(ctx));
    ck_assert_str_eq(wt_error_message(ctx), "run.h5: key 'loop.delay': 7 is out of range");
    ck_assert_int_eq(wt_error_status(ctx), WT_ERR_IO);
    /* a long message is cut, not overrun, and stays a terminated string */
    char big[5000];
    memset(big, 'x', sizeof big - 1), big[sizeof big - 1] = '\0';
    WT_ERROR(ctx, WT_ERR_INVALID, "%s", big);
    const size_t len = strlen(wt_error_message(ctx));
    ck_assert(len > 1000 && len < sizeof big - 1);
    /* no context: the status still comes back */
    ck_assert_int_eq(WT_ERROR(NULL, WT_ERR_NOMEM, "nothing records this"), WT_ERR_NOMEM);
    ck_assert_str_eq(wt_error_message(NULL), "");
    /* every status has a name, and different ones differ */
    ck_assert_str_ne(wt_strerror(WT_ERR_CONFIG), wt_strerror(WT_ERR_IO));
    ck_assert_ptr_nonnull(wt_strerror(WT_OK));
}
END_TEST

static void log_hook(void *user, int level, const char *msg)
{
    seen *s = user;
    s->calls++, s->level = level;
    snprintf(s->msg, sizeof s->msg, "%s", msg);
}

START_TEST(test_log)
{
    wt_log(ctx, WT_LOG_ERROR, "no hook: nothing happens");
    seen s = {0};
    wt_context_set_log_hook(ctx, log_hook, &s, WT_LOG_WARN);
    wt_log(ctx, WT_LOG_INFO, "below the level: dropped");
    ck_assert_int_eq(s.calls, 0);
    wt_log(ctx, WT_LOG_WARN, "frame %d of %d", 3, 10);
    ck_assert_int_eq(s.calls, 1);
    ck_assert_int_eq(s.level, WT_LOG_WARN);
    ck_assert_str_eq(s.msg, "frame 3 of 10");
}
END_TEST

START_TEST(test_alloc)
{
    /* n x size beyond SIZE_MAX is refused before any allocation, not wrapped to a small block */
    tu_alloc a = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &a);
    ck_assert_ptr_null(wt_malloc(ctx, SIZE_MAX / 8 + 2, 8));
    ck_assert_ptr_null(wt_calloc(ctx, (size_t)1 << 33, (size_t)1 << 33));
    ck_assert_int_eq(a.count, 0);
    /* through the hooks, and back to them */
    double *p = wt_calloc(ctx, 1000, sizeof *p);
    ck_assert_ptr_nonnull(p);
    ck_assert_int_eq(a.live, 1);
    for (int i = 0; i < 1000; i++) ck_assert(p[i] == 0.0);
    wt_free(ctx, p);
    ck_assert_int_eq(a.live, 0);
    /* an empty array is a real, freeable block */
    void *e = wt_malloc(ctx, 0, 8);
    ck_assert_ptr_nonnull(e);
    wt_free(ctx, e);
    wt_free(ctx, NULL);
    ck_assert_int_eq(a.live, 0);
    /* a refusal is NULL (WT_ALLOC records the message) */
    tu_alloc_budget(&a, 0);
    ck_assert_ptr_null(wt_malloc(ctx, 4, 8));
    ck_assert_int_eq(a.failed, 1);
    wt_context_free(ctx); /* the allocator lives on this stack: the teardown gets a fresh context */
    ctx = tu_context();
}
END_TEST

START_TEST(test_align)
{
    double buf[16];
    for (int k = 0; k < 8; k++) {
        double *q = wt_align64(buf + k);
        ck_assert_int_eq((uintptr_t)q % 64, 0);
        ck_assert(q >= buf + k && q < buf + k + 8); /* the next boundary, never past it */
    }
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("base");
    TCase *tc = tcase_create("context");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_add_test(tc, test_error);
    tcase_add_test(tc, test_log);
    tcase_add_test(tc, test_alloc);
    tcase_add_test(tc, test_align);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
