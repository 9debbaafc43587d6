/* tests/test_numbers.c: one line of a number table (core/base/numbers.h), the reader behind the profile files,
 * the night files and the sodium sequences: what it accepts, the values' bits, growth past its first room, and
 * each refusal's message (file, line, column, name, the field as written, what the file holds) and status. */
#include "core/base/numbers.h"
#include "testutil.h"

/* checked fixture: every test gets a fresh context and an empty number buffer, and leaves nothing behind */
static wt_context *ctx;
static double *v;
static long cap;
static void setup(void) { ctx = tu_context(), v = NULL, cap = 0; }
static void teardown(void)
{
    wt_free(ctx, v);
    wt_context_free(ctx);
}

static const char *const names[] = {"altitude [m]", "Cn2 fraction"};

/* the count of fields of `line` (a copy: the reader writes into its text) */
static long read_line(const char *line, const wt_numbers_where *w)
{
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", line);
    return wt_read_numbers(ctx, buf, w, &v, &cap);
}

START_TEST(test_fields)
{
    const wt_numbers_where w = {"p.txt", 3, 1, NULL, 0, "", WT_ERR_CONFIG};
    ck_assert_int_eq(read_line("", &w), 0);
    ck_assert_int_eq(read_line("  \t \r\n", &w), 0);
    ck_assert_int_eq(read_line("# only a comment 1 2 3\n", &w), 0);
    ck_assert_int_eq(read_line(" 1.5\t-2e3  0x10 7 # 8 9\n", &w), 4);
    /* strtod's values, to the bit: the reader must not round or rescale */
    ck_assert(v[0] == 1.5 && v[1] == -2000.0 && v[2] == 16.0 && v[3] == 7.0);
    ck_assert_int_eq(read_line("0.1 1e-300\r\n", &w), 2);
    ck_assert(v[0] == strtod("0.1", NULL) && v[1] == strtod("1e-300", NULL));
    /* the comment is cut from the text, the rest of it left as it was */
    char text[] = "4 5 # six";
    ck_assert_int_eq(wt_read_numbers(ctx, text, &w, &v, &cap), 2);
    ck_assert_str_eq(text, "4 5 ");
}
END_TEST

START_TEST(test_growth)
{
    /* 1000 fields: past the first room, every value kept in its place through each doubling */
    char *line = malloc(1000 * 8);
    ck_assert_ptr_nonnull(line);
    size_t k = 0;
    for (int i = 0; i < 1000; i++) k += (size_t)sprintf(line + k, "%d ", i - 500);
    const wt_numbers_where w = {"n.txt", 1, 1, NULL, 0, "", WT_ERR_CONFIG};
    ck_assert_int_eq(wt_read_numbers(ctx, line, &w, &v, &cap), 1000);
    ck_assert_int_ge(cap, 1000);
    for (int i = 0; i < 1000; i++) ck_assert(v[i] == (double)(i - 500));
    /* the buffer is reused by the next line: a short one does not shrink it */
    const long cap1 = cap;
    ck_assert_int_eq(read_line("1 2", &w), 2);
    ck_assert_int_eq(cap, cap1);
    free(line);
}
END_TEST

/* the refusal of `line`: its status and its message, exactly */
static void refused(const char *line, const wt_numbers_where *w, int status, const char *msg)
{
    ck_assert_int_eq(read_line(line, w), status);
    ck_assert_str_eq(wt_error_message(ctx), msg);
}

START_TEST(test_refusals)
{
    const wt_numbers_where w = {"p.txt", 7, 1, names, 2, "(a profile)", WT_ERR_CONFIG};
    refused("0 fast 3", &w, WT_ERR_CONFIG, "p.txt:7: column 2 (Cn2 fraction): 'fast' is not a finite number (a profile)");
    refused("0.5x 1", &w, WT_ERR_CONFIG, "p.txt:7: column 1 (altitude [m]): '0.5x' is not a finite number (a profile)");
    /* past the named columns: the number alone */
    refused("1 2 nan", &w, WT_ERR_CONFIG, "p.txt:7: column 3: 'nan' is not a finite number (a profile)");
    refused("1 2 3 inf", &w, WT_ERR_CONFIG, "p.txt:7: column 4: 'inf' is not a finite number (a profile)");
    /* out of double's range (ERANGE), not read as ±HUGE_VAL */
    refused("1e999", &w, WT_ERR_CONFIG, "p.txt:7: column 1 (altitude [m]): '1e999' is not a finite number (a profile)");
    /* a comma is no separator: the field is quoted whole */
    refused("1,2 3", &w, WT_ERR_CONFIG, "p.txt:7: column 1 (altitude [m]): '1,2' is not a finite number (a profile)");
    /* after a leading word (column0 2), no names, another status, nothing expected */
    const wt_numbers_where s = {"na.txt", 1, 2, NULL, 0, "", WT_ERR_INVALID};
    refused("80000 9e4x", &s, WT_ERR_INVALID, "na.txt:1: column 3: '9e4x' is not a finite number");
}
END_TEST

START_TEST(test_nomem)
{
    /* the first room refused: WT_ERR_NOMEM, nothing allocated, the buffer untouched */
    tu_alloc a = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &a);
    tu_alloc_budget(&a, 0);
    const wt_numbers_where w = {"p.txt", 2, 1, NULL, 0, "", WT_ERR_CONFIG};
    ck_assert_int_eq(read_line("1 2 3", &w), WT_ERR_NOMEM);
    ck_assert_ptr_null(v);
    ck_assert_int_eq(a.live, 0);
    /* the second room refused after 64 numbers: the first room kept for the caller to free */
    tu_alloc_budget(&a, 1);
    char line[1024] = "";
    for (int i = 0; i < 100; i++) strcat(line, "1 ");
    ck_assert_int_eq(read_line(line, &w), WT_ERR_NOMEM);
    ck_assert_ptr_nonnull(v);
    ck_assert_int_eq(a.live, 1);
    wt_free(ctx, v);
    v = NULL;
    ck_assert_int_eq(a.live, 0);
    wt_context_free(ctx); /* the allocator lives on this stack: the teardown gets a fresh context */
    ctx = tu_context();
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("numbers");
    TCase *tc = tcase_create("line");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_add_test(tc, test_fields);
    tcase_add_test(tc, test_growth);
    tcase_add_test(tc, test_refusals);
    tcase_add_test(tc, test_nomem);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
