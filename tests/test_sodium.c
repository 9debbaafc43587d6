/* tests/test_sodium.c: the sodium profile (core/optics/sodium.h, SPEC §4b): exact piecewise-linear
 * moments, the Gaussian constructor, the shipped default profile against what its header says, and every
 * file defect refused with the file and line; the profile in time (SPEC §12): interpolation, the shipped
 * sequences against their headers, every defect of a sequence file refused with the file and line. */
#include "testutil.h"

#include <unistd.h>

#include "core/optics/sodium.h"

/* Write `text` to a fresh temporary file; path into buf. */
static void write_tmp(char *buf, size_t n, const char *text)
{
    snprintf(buf, n, "/tmp/wt_sodium_XXXXXX");
    int fd = mkstemp(buf);
    ck_assert_int_ge(fd, 0);
    FILE *f = fdopen(fd, "w");
    ck_assert_ptr_nonnull(f);
    fputs(text, f);
    fclose(f);
}

START_TEST(t_moments_exact)
{
    /* a triangle 0 → 1 → 0 over [80, 100] km: centroid 90 km, FWHM 10 km, mass 10 km, exactly */
    wt_context *ctx = tu_context();
    double alt[3] = {80e3, 90e3, 100e3}, dens[3] = {0, 1, 0};
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_from_table(ctx, 3, alt, dens, "triangle", &na), WT_OK);
    ck_assert_rel(wt_sodium_mass(na), 10e3, 1e-14, 0);
    ck_assert_rel(wt_sodium_centroid(na), 90e3, 1e-14, 0);
    ck_assert_rel(wt_sodium_fwhm(na), 10e3, 1e-14, 0);
    wt_sodium_free(na);
    /* a right-angled triangle 1 → 0 over [80, 95] km: centroid a + w/3 = 85 km (exact for the linear piece) */
    double alt2[2] = {80e3, 95e3}, dens2[2] = {1, 0};
    ck_assert_int_eq(wt_sodium_from_table(ctx, 2, alt2, dens2, "ramp", &na), WT_OK);
    ck_assert_rel(wt_sodium_centroid(na), 85e3, 1e-14, 0);
    ck_assert_rel(wt_sodium_fwhm(na), 7.5e3, 1e-14, 0);
    ck_assert_int_eq(wt_sodium_check_covers(ctx, na, 90e3, "k"), WT_OK);
    ck_assert_int_eq(wt_sodium_check_covers(ctx, na, 96e3, "lgs.sodium_profile"), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lgs.sodium_profile"));
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "96000"));
    wt_sodium_free(na);
    wt_sodium_free(NULL);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_gaussian)
{
    /* sampled at FWHM/50 the linear interpolation changes the half-maximum crossing by ~(Δ²/8)|f''|/|f'|:
     * relative 1e-4; the centroid is exact by symmetry */
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_gaussian(ctx, 90e3, 10e3, &na), WT_OK);
    ck_assert_rel(wt_sodium_centroid(na), 90e3, 1e-12, 0);
    ck_assert_rel(wt_sodium_fwhm(na), 10e3, 1e-4, 0);
    wt_sodium_free(na);
    ck_assert_int_eq(wt_sodium_gaussian(ctx, 90e3, -1, &na), WT_ERR_INVALID);
    ck_assert_ptr_null(na);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_default_file)
{
    /* the shipped profile: its header states centroid 90.48 km and FWHM 10.41 km */
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    int st = wt_sodium_read(ctx, "data/sodium/default.txt", &na);
    ck_assert_msg(st == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_ge(na->n, 50);
    ck_assert_msg(fabs(wt_sodium_centroid(na) - 90.48e3) < 10, "centroid %g", wt_sodium_centroid(na));
    ck_assert_msg(fabs(wt_sodium_fwhm(na) - 10.41e3) < 10, "fwhm %g", wt_sodium_fwhm(na));
    double sum = 0;
    for (int i = 0; i < na->n; i++) sum += na->dens[i];
    ck_assert_rel(sum, 1.0, 1e-5, 0);
    ck_assert_int_eq(wt_sodium_check_covers(ctx, na, 90e3, "x"), WT_OK);
    wt_sodium_free(na);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_read_comments)
{
    wt_context *ctx = tu_context();
    char path[64];
    write_tmp(path, sizeof path, "# header\n\n 80000  0   # start\n90000\t1.5\r\n100000 0\n# end\n");
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, path, &na), WT_OK);
    ck_assert_int_eq(na->n, 3);
    ck_assert_rel(na->dens[1], 1.5, 0, 0);
    ck_assert_rel(wt_sodium_centroid(na), 90e3, 1e-14, 0);
    wt_sodium_free(na);
    unlink(path);
    wt_context_free(ctx);
}
END_TEST

/* a refusal's message names the file, (where there is one) the line, and the defect's word; then the file and the
 * context go */
static void refusal_message(wt_context *ctx, const char *path, const char *line_tag, const char *word)
{
    const char *m = wt_error_message(ctx);
    ck_assert_msg(strstr(m, path), "message does not name the file: %s", m);
    if (line_tag) {
        char tag[96];
        snprintf(tag, sizeof tag, "%s%s", path, line_tag);
        ck_assert_msg(strstr(m, tag), "message does not name %s: %s", tag, m);
    }
    if (word) ck_assert_msg(strstr(m, word), "message lacks '%s': %s", word, m);
    unlink(path);
    wt_context_free(ctx);
}

/* each defect: the status, and the message names the file and (where there is one) the line */
static void refused(const char *text, int status, const char *line_tag, const char *word)
{
    wt_context *ctx = tu_context();
    char path[64];
    write_tmp(path, sizeof path, text);
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, path, &na), status);
    ck_assert_ptr_null(na);
    refusal_message(ctx, path, line_tag, word);
}

START_TEST(t_defects)
{
    refused("", WT_ERR_INVALID, NULL, "no data");
    refused("# only a comment\n\n", WT_ERR_INVALID, NULL, "no data");
    refused("80000 0\n90000 abc\n", WT_ERR_INVALID, ":2", "not a finite number");
    refused("80000 0\n9e4x 1\n", WT_ERR_INVALID, ":2", "not a finite number");
    refused("80000 0\n90000 nan\n", WT_ERR_INVALID, ":2", "not a finite number");
    refused("80000 0\n90000\n", WT_ERR_INVALID, ":2", "one field");
    refused("80000 0\n90000 1 2\n", WT_ERR_INVALID, ":2", "more than two");
    refused("80000 0\n\n90000 -0.1\n", WT_ERR_INVALID, ":3", "negative");
    refused("80000 0\n90000 1\n85000 0\n", WT_ERR_INVALID, ":3", "strictly increasing");
    refused("80000 0\n90000 1\n90000 0\n", WT_ERR_INVALID, ":3", "strictly increasing");
    refused("80000 0\n90000 0\n", WT_ERR_INVALID, NULL, "zero");
    refused("80000 1\n", WT_ERR_INVALID, NULL, "at least 2");
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "/nonexistent/na.txt", &na), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "/nonexistent/na.txt"));
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_alloc_failure)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    for (int b = 0; b < 20; b++) {
        tu_alloc_budget(&fa, b);
        wt_sodium *na = NULL;
        int st = wt_sodium_read(ctx, "data/sodium/default.txt", &na);
        if (st == WT_OK) {
            wt_sodium_free(na);
            break;
        }
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(na);
        ck_assert_int_eq(fa.live, 0);
    }
    ck_assert_int_eq(fa.live, 0);
    wt_context_set_allocator(ctx, NULL, NULL, NULL);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_sequence_interpolation)
{
    wt_context *ctx = tu_context();
    char path[64];
    write_tmp(path, sizeof path,
              "# a sequence\naltitude_m 80000 90000 100000  # km\n\n0 0 1 0\n10\t0 0.5 0.5\r\n30 1 1 1e-300\n");
    wt_sodium_seq *q = NULL;
    ck_assert_msg(wt_sodium_seq_read(ctx, path, &q) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_sodium_seq_knots(q), 3);
    ck_assert_int_eq(wt_sodium_seq_nalt(q), 3);
    ck_assert(wt_sodium_seq_first(q) == 0.0 && wt_sodium_seq_last(q) == 30.0);
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_seq_profile(ctx, q, 10.0, &na), WT_OK);
    /* a knot's own numbers, bit for bit */
    ck_assert(na->alt[1] == 90000.0 && na->dens[0] == 0.0 && na->dens[1] == 0.5 && na->dens[2] == 0.5);
    ck_assert_int_eq(wt_sodium_seq_at(q, 30.0, na), WT_OK);
    ck_assert(na->dens[0] == 1.0 && na->dens[2] == 1e-300);
    /* linear between knots: t = 2.5 is a quarter of the way, t = 20 half */
    ck_assert_int_eq(wt_sodium_seq_at(q, 2.5, na), WT_OK);
    ck_assert_rel(na->dens[1], 0.875, 1e-15, 0);
    ck_assert_rel(na->dens[2], 0.125, 1e-15, 0);
    ck_assert_int_eq(wt_sodium_seq_at(q, 20.0, na), WT_OK);
    ck_assert_rel(na->dens[0], 0.5, 1e-15, 0);
    ck_assert_rel(na->dens[1], 0.75, 1e-15, 0);
    /* outside the span, and the run's cover */
    ck_assert_int_eq(wt_sodium_seq_at(q, 30.5, na), WT_ERR_INVALID);
    ck_assert_int_eq(wt_sodium_seq_at(q, -1.0, na), WT_ERR_INVALID);
    ck_assert_int_eq(wt_sodium_seq_check_covers(ctx, q, 0.0, 30.0, "keys"), WT_OK);
    ck_assert_int_eq(wt_sodium_seq_check_covers(ctx, q, 5.0, 31.0, "keys k"), WT_ERR_CONFIG);
    const char *m = wt_error_message(ctx);
    ck_assert_msg(strstr(m, path) && strstr(m, "keys k") && strstr(m, "31"), "%s", m);
    wt_sodium_free(na);
    wt_sodium_seq_free(q);
    unlink(path);
    wt_context_free(ctx);
}
END_TEST

/* The shipped sequences against their headers: the first knot is default.txt's numbers (bit for bit: a static
 * reference of the default profile is exact there), the drift's centroid rises by 1 km in 600 s, the sporadic
 * layer holds a third of the column from 180 s on. */
START_TEST(t_shipped_sequences)
{
    wt_context *ctx = tu_context();
    wt_sodium *def = NULL, *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "data/sodium/default.txt", &def), WT_OK);
    const char *files[] = {"data/sodium/drift-1km-10min.txt", "data/sodium/sporadic-2min.txt"};
    for (int f = 0; f < 2; f++) {
        wt_sodium_seq *q = NULL;
        ck_assert_msg(wt_sodium_seq_read(ctx, files[f], &q) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert(wt_sodium_seq_first(q) == 0.0 && wt_sodium_seq_last(q) == 1200.0);
        ck_assert_int_eq(wt_sodium_seq_profile(ctx, q, 0.0, &na), WT_OK);
        ck_assert_int_eq(na->n, def->n);
        for (int i = 0; i < def->n; i++) ck_assert(na->alt[i] == def->alt[i] && na->dens[i] == def->dens[i]);
        const double h0 = wt_sodium_centroid(na);
        ck_assert_int_eq(wt_sodium_seq_at(q, f ? 180.0 : 600.0, na), WT_OK);
        const double h1 = wt_sodium_centroid(na);
        if (f == 0) {
            ck_assert_msg(fabs(h1 - h0 - 1000.0) < 1.0, "drift %g m in 600 s", h1 - h0);
            ck_assert_int_eq(wt_sodium_seq_at(q, 1200.0, na), WT_OK);
            ck_assert_msg(fabs(wt_sodium_centroid(na) - h0 - 2000.0) < 1.0, "drift %g m in 1200 s",
                          wt_sodium_centroid(na) - h0);
        } else {
            /* the layer's mass is the profile's less the default's: a third of the column */
            ck_assert_rel(1.0 - wt_sodium_mass(def) / wt_sodium_mass(na), 1.0 / 3.0, 1e-5, 0);
            ck_assert_msg(fabs(h1 - 92822.0) < 5.0, "centroid %g m with the layer", h1);
            ck_assert_int_eq(wt_sodium_seq_at(q, 60.0, na), WT_OK);
            ck_assert(wt_sodium_centroid(na) == h0);
        }
        wt_sodium_free(na), na = NULL;
        wt_sodium_seq_free(q);
    }
    wt_sodium_free(def);
    wt_context_free(ctx);
}
END_TEST

static void seq_refused(const char *text, int status, const char *line_tag, const char *word)
{
    wt_context *ctx = tu_context();
    char path[64];
    write_tmp(path, sizeof path, text);
    wt_sodium_seq *q = NULL;
    ck_assert_int_eq(wt_sodium_seq_read(ctx, path, &q), status);
    ck_assert_ptr_null(q);
    refusal_message(ctx, path, line_tag, word);
}

START_TEST(t_sequence_defects)
{
    seq_refused("", WT_ERR_INVALID, NULL, "no profile");
    seq_refused("altitude_m 80000 90000\n# no knot\n", WT_ERR_INVALID, NULL, "no profile");
    seq_refused("80000 90000\n0 1 1\n", WT_ERR_INVALID, ":1", "altitude_m");
    seq_refused("altitude_m 80000\n0 1\n", WT_ERR_INVALID, ":1", "need 2");
    seq_refused("altitude_m 80000 90000 85000\n0 1 1 1\n", WT_ERR_INVALID, ":1", "strictly increasing");
    seq_refused("altitude_m 80000 80000\n0 1 1\n", WT_ERR_INVALID, ":1", "strictly increasing");
    seq_refused("altitude_m -1 90000\n0 1 1\n", WT_ERR_INVALID, ":1", "above the telescope");
    seq_refused("altitude_m 80000 9e4x\n0 1 1\n", WT_ERR_INVALID, ":1", "not a finite number");
    seq_refused("altitude_m 80000 90000\n0 1 1\n10 1\n", WT_ERR_INVALID, ":3", "expected 3");
    seq_refused("altitude_m 80000 90000\n0 1 1\n10 1 1 1\n", WT_ERR_INVALID, ":3", "expected 3");
    seq_refused("altitude_m 80000 90000\n0 1 1\n\n10 1 -0.5\n", WT_ERR_INVALID, ":4", "negative density");
    seq_refused("altitude_m 80000 90000\n10 1 1\n5 1 1\n", WT_ERR_INVALID, ":3", "strictly increasing");
    seq_refused("altitude_m 80000 90000\n10 1 1\n10 1 1\n", WT_ERR_INVALID, ":3", "strictly increasing");
    seq_refused("altitude_m 80000 90000\n0 0 0\n", WT_ERR_INVALID, ":2", "zero");
    seq_refused("altitude_m 80000 90000\n0 1 inf\n", WT_ERR_INVALID, ":2", "not a finite number");
    wt_context *ctx = tu_context();
    wt_sodium_seq *q = NULL;
    ck_assert_int_eq(wt_sodium_seq_read(ctx, "/nonexistent/seq.txt", &q), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "/nonexistent/seq.txt"));
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_sequence_alloc_failure)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    for (int b = 0; b < 40; b++) {
        tu_alloc_budget(&fa, b);
        wt_sodium_seq *q = NULL;
        int st = wt_sodium_seq_read(ctx, "data/sodium/sporadic-2min.txt", &q);
        if (st == WT_OK) {
            wt_sodium_seq_free(q);
            break;
        }
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(q);
        ck_assert_int_eq(fa.live, 0);
    }
    ck_assert_int_eq(fa.live, 0);
    wt_context_set_allocator(ctx, NULL, NULL, NULL);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("sodium");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, t_moments_exact);
    tcase_add_test(tc, t_gaussian);
    tcase_add_test(tc, t_default_file);
    tcase_add_test(tc, t_read_comments);
    tcase_add_test(tc, t_defects);
    tcase_add_test(tc, t_alloc_failure);
    tcase_add_test(tc, t_sequence_interpolation);
    tcase_add_test(tc, t_shipped_sequences);
    tcase_add_test(tc, t_sequence_defects);
    tcase_add_test(tc, t_sequence_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
