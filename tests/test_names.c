/* tests/test_names.c: the nearest name for "did you mean" (core/base/names.h): the Levenshtein distance on known
 * pairs, and the suggestion's threshold max(2, len/4): a dropped letter, a doubled one and a transposition are
 * suggested, an unrelated word is not. */
#include "core/base/names.h"
#include "testutil.h"

#include <limits.h>

static int dist(const char *a, const char *b) { return wt_edit_distance(a, strlen(a), b, strlen(b)); }

START_TEST(test_distance)
{
    ck_assert_int_eq(dist("", ""), 0);
    ck_assert_int_eq(dist("", "abc"), 3);
    ck_assert_int_eq(dist("abc", ""), 3);
    ck_assert_int_eq(dist("kitten", "sitting"), 3);
    ck_assert_int_eq(dist("flaw", "lawn"), 2);
    ck_assert_int_eq(dist("gain", "gian"), 2); /* a transposition is two edits */
    ck_assert_int_eq(dist("delay", "delay"), 0);
    ck_assert_int_eq(dist("sitting", "kitten"), 3); /* symmetric */
    char longw[200];
    memset(longw, 'a', 199), longw[199] = '\0';
    ck_assert_int_eq(dist(longw, "a"), INT_MAX); /* longer than 127: no distance */
}
END_TEST

START_TEST(test_nearest)
{
    static const char *const names[] = {"loop.gain", "loop.delay", "loop.gain_levels", "recon.alpha"};
    ck_assert_int_eq(wt_nearest_name("loop.gian", names, 4), 0);      /* transposition: 2 edits */
    ck_assert_int_eq(wt_nearest_name("loop.dely", names, 4), 1);      /* dropped letter */
    ck_assert_int_eq(wt_nearest_name("loop.gain_levells", names, 4), 2); /* doubled letter */
    ck_assert_int_eq(wt_nearest_name("recon.alpha", names, 4), 3);    /* exact */
    ck_assert_int_eq(wt_nearest_name("telescope", names, 4), -1);     /* nothing close */
    /* the threshold grows with the word: 16 letters allow 4 edits, 8 letters only 2 */
    ck_assert_int_eq(wt_nearest_name("loop.gXXX_levels", names, 4), 2); /* 3 edits, 16 letters */
    static const char *const short_names[] = {"abcdefgh"};
    ck_assert_int_eq(wt_nearest_name("abcdeXYZ", short_names, 1), -1); /* 3 edits, 8 letters */
    ck_assert_int_eq(wt_nearest_name("abcdefXY", short_names, 1), 0);  /* 2 edits */
    ck_assert_int_eq(wt_nearest_name("x", names, 0), -1);              /* no names */
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("names");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_distance);
    tcase_add_test(tc, test_nearest);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
