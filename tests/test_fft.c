/* tests/test_fft.c: the FFT plans of core/la/fft.c: a learnt pair transforms (round trip, agreement with
 * FFTW_ESTIMATE's to rounding), a wisdom file written and read back plans the same algorithm (the same bits on
 * the same input), the caller's FFTW wisdom is left as it was, and a wisdom without the size, a missing,
 * empty, binary or foreign file and a changed SHA-256 are refused naming the file. */
#include "testutil.h"

#include <fftw3.h>
#include <unistd.h>

#include "core/base/sha256.h"
#include "core/la/fft.h"

enum { N = 16 };
#define NK (N * (N / 2 + 1))

typedef struct {
    double *re, *x, *y;
    fftw_complex *c;
} arrays;

static arrays arrays_alloc(void)
{
    arrays a = {fftw_malloc(N * N * sizeof(double)), fftw_malloc(N * N * sizeof(double)),
                fftw_malloc(N * N * sizeof(double)), fftw_malloc(NK * sizeof(fftw_complex))};
    ck_assert(a.re && a.x && a.y && a.c);
    tu_randn(a.x, N * N, 7);
    return a;
}

static void arrays_free(arrays *a)
{
    fftw_free(a->re), fftw_free(a->x), fftw_free(a->y), fftw_free(a->c);
}

/* y = c2r(r2c(x)) / N² with the pair (the identity up to rounding); also spec = r2c(x) when non-NULL. */
static void round_trip(fftw_plan r2c, fftw_plan c2r, arrays *a, fftw_complex *spec)
{
    memcpy(a->re, a->x, N * N * sizeof(double));
    fftw_execute_dft_r2c(r2c, a->re, a->c);
    if (spec) memcpy(spec, a->c, NK * sizeof(fftw_complex));
    fftw_execute_dft_c2r(c2r, a->c, a->y);
    for (int i = 0; i < N * N; i++) a->y[i] /= (double)(N * N);
}

static void temp_path(char *path, size_t n, const char *tag)
{
    snprintf(path, n, "/tmp/wt_fft_%s_XXXXXX", tag);
    const int fd = mkstemp(path);
    ck_assert(fd >= 0);
    close(fd);
}

static void write_text(const char *path, const char *text, size_t len)
{
    FILE *f = fopen(path, "wb");
    ck_assert_ptr_nonnull(f);
    ck_assert_uint_eq(fwrite(text, 1, len, f), len);
    ck_assert_int_eq(fclose(f), 0);
}

/* Learn the N x N pair, write it, read it back: the plans from the file are the learnt ones (same bits), both
 * agree with FFTW_ESTIMATE's to rounding (an FFT's error is O(ε log N) relative), and round-trip. */
START_TEST(test_wisdom_round_trip)
{
    wt_context *ctx = tu_context();
    arrays a = arrays_alloc();
    fftw_complex *s_learn = fftw_malloc(NK * sizeof *s_learn), *s_read = fftw_malloc(NK * sizeof *s_read),
                 *s_est = fftw_malloc(NK * sizeof *s_est);
    double *y_learn = malloc(N * N * sizeof *y_learn);
    wt_fft_wisdom *learner = NULL, *read = NULL;
    fftw_plan f = NULL, b = NULL;

    ck_assert_int_eq(wt_fft_wisdom_learner(ctx, &learner), WT_OK);
    ck_assert_str_eq(wt_fft_wisdom_text(learner), "");
    ck_assert_int_eq(wt_fft_wisdom_learn(ctx, learner, N), WT_OK);
    ck_assert_int_eq(wt_fft_plan_pair(ctx, learner, N, a.re, a.c, "test", &f, &b), WT_OK);
    ck_assert_int_eq(strncmp(wt_fft_wisdom_text(learner), "(fftw-", 6), 0);
    char hex[65];
    wt_sha256_hex(wt_fft_wisdom_text(learner), strlen(wt_fft_wisdom_text(learner)), hex);
    ck_assert_str_eq(wt_fft_wisdom_sha256(learner), hex);
    round_trip(f, b, &a, s_learn);
    ck_assert_double_le(tu_rel_diff(a.y, a.x, N * N), 1e-14);
    memcpy(y_learn, a.y, N * N * sizeof *y_learn);
    fftw_destroy_plan(f), fftw_destroy_plan(b);

    char path[64];
    temp_path(path, sizeof path, "ok");
    ck_assert_int_eq(wt_fft_wisdom_write(ctx, learner, path), WT_OK);
    char file_hex[65];
    ck_assert_int_eq(wt_sha256_file(path, file_hex), 0);
    ck_assert_str_eq(file_hex, hex);
    ck_assert_int_eq(wt_fft_wisdom_read(ctx, path, hex, "test.key", &read), WT_OK);
    ck_assert_str_eq(wt_fft_wisdom_sha256(read), hex);
    ck_assert_int_eq(wt_fft_plan_pair(ctx, read, N, a.re, a.c, "test", &f, &b), WT_OK);
    round_trip(f, b, &a, s_read);
    ck_assert_int_eq(memcmp(s_read, s_learn, NK * sizeof *s_read), 0);
    ck_assert_int_eq(memcmp(a.y, y_learn, N * N * sizeof *y_learn), 0);
    fftw_destroy_plan(f), fftw_destroy_plan(b);
    /* a read wisdom does not learn */
    ck_assert_int_eq(wt_fft_wisdom_learn(ctx, read, N), WT_ERR_INVALID);

    ck_assert_int_eq(wt_fft_plan_pair(ctx, NULL, N, a.re, a.c, "test", &f, &b), WT_OK);
    round_trip(f, b, &a, s_est);
    ck_assert_double_le(tu_rel_diff((double *)s_read, (double *)s_est, 2 * NK), 1e-14);
    fftw_destroy_plan(f), fftw_destroy_plan(b);

    remove(path);
    wt_fft_wisdom_free(learner);
    wt_fft_wisdom_free(read);
    fftw_free(s_learn), fftw_free(s_read), fftw_free(s_est);
    free(y_learn);
    arrays_free(&a);
    wt_context_free(ctx);
}
END_TEST

/* The process's own FFTW wisdom (a host program's) is the same before and after planning from a file. */
START_TEST(test_caller_store_kept)
{
    wt_context *ctx = tu_context();
    arrays a = arrays_alloc();
    fftw_complex *z = fftw_malloc(12 * sizeof *z);
    fftw_plan own = fftw_plan_dft_1d(12, z, z, FFTW_FORWARD, FFTW_MEASURE);
    ck_assert_ptr_nonnull(own);
    char *before = fftw_export_wisdom_to_string();
    wt_fft_wisdom *w = NULL;
    fftw_plan f = NULL, b = NULL;
    ck_assert_int_eq(wt_fft_wisdom_learner(ctx, &w), WT_OK);
    ck_assert_int_eq(wt_fft_wisdom_learn(ctx, w, N), WT_OK);
    ck_assert_int_eq(wt_fft_plan_pair(ctx, w, N, a.re, a.c, "test", &f, &b), WT_OK);
    char *after = fftw_export_wisdom_to_string();
    ck_assert_str_eq(after, before);
    /* and the learner holds the pair only: none of the host's entries (one line each, with the problem's hash) */
    int entries = 0;
    for (char *line = strtok(before, "\n"); line; line = strtok(NULL, "\n"))
        if (!strncmp(line, "  (", 3)) {
            entries++;
            ck_assert_msg(!strstr(wt_fft_wisdom_text(w), line), "the learner took the host's entry %s", line);
        }
    ck_assert_int_gt(entries, 0);
    free(before), free(after);
    fftw_destroy_plan(f), fftw_destroy_plan(b), fftw_destroy_plan(own);
    wt_fft_wisdom_free(w);
    fftw_free(z);
    arrays_free(&a);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_refusals)
{
    wt_context *ctx = tu_context();
    wt_fft_wisdom *w = NULL, *r = NULL;
    fftw_plan f = (fftw_plan)1, b = (fftw_plan)1;
    double *re = fftw_malloc(2 * N * 2 * N * sizeof *re);
    fftw_complex *c = fftw_malloc(2 * N * (N + 1) * sizeof *c);
    char path[64], msg[1024];
    temp_path(path, sizeof path, "bad");

    /* a wisdom of 16 x 16 asked for 32 x 32: named file and size, no plans left */
    ck_assert_int_eq(wt_fft_wisdom_learner(ctx, &w), WT_OK);
    ck_assert_int_eq(wt_fft_wisdom_learn(ctx, w, N), WT_OK);
    ck_assert_int_eq(wt_fft_wisdom_write(ctx, w, path), WT_OK);
    ck_assert_int_eq(wt_fft_wisdom_read(ctx, path, NULL, "recon.fft_wisdom", &r), WT_OK);
    ck_assert_int_eq(wt_fft_plan_pair(ctx, r, 2 * N, re, c, "prior (full)", &f, &b), WT_ERR_CONFIG);
    snprintf(msg, sizeof msg, "%s", wt_error_message(ctx));
    ck_assert_msg(strstr(msg, path) && strstr(msg, "32 x 32") && strstr(msg, "prior (full)"), "%s", msg);
    ck_assert(f == NULL && b == NULL);
    wt_fft_wisdom_free(r);
    r = NULL;

    /* another SHA-256 than recorded */
    const char *other = "0000000000000000000000000000000000000000000000000000000000000000";
    ck_assert_int_eq(wt_fft_wisdom_read(ctx, path, other, "recon.fft_wisdom", &r), WT_ERR_FORMAT);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "recon.fft_wisdom_sha256"));
    ck_assert_ptr_null(r);

    /* not wisdom: text, empty, binary; a missing file */
    const struct { const char *text; size_t len; int st; const char *word; } bad[] = {
        {"hello\n", 6, WT_ERR_FORMAT, "not FFTW"}, {"", 0, WT_ERR_FORMAT, "empty"},
        {"(fftw-3\0x", 9, WT_ERR_FORMAT, "binary"}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        write_text(path, bad[i].text, bad[i].len);
        ck_assert_int_eq(wt_fft_wisdom_read(ctx, path, NULL, "recon.fft_wisdom", &r), bad[i].st);
        ck_assert_msg(strstr(wt_error_message(ctx), path) && strstr(wt_error_message(ctx), bad[i].word), "%s",
                      wt_error_message(ctx));
        ck_assert_ptr_null(r);
    }
    remove(path);
    ck_assert_int_eq(wt_fft_wisdom_read(ctx, path, NULL, "recon.fft_wisdom", &r), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), path));
    ck_assert_int_eq(wt_fft_plan_pair(ctx, NULL, 0, re, c, "test", &f, &b), WT_ERR_INVALID);

    wt_fft_wisdom_free(w);
    fftw_free(re), fftw_free(c);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("fft");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_wisdom_round_trip);
    tcase_add_test(tc, test_caller_store_kept);
    tcase_add_test(tc, test_refusals);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
