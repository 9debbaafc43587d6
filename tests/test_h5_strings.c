/* tests/test_h5_strings.c: how strings are stored. Every string dataset and attribute is written as a
 * variable-length UTF-8 string, the type h5py and other readers decode to text (a fixed-length one comes back
 * as bytes); and the readers still read the fixed-length strings of files written before (ASCII or UTF-8,
 * NUL-terminated or padded), so that an older RUN.h5, TEL.h5 or matrix keeps working and is still recognised as
 * a wavetomo output that a new run may replace. */
#include "testutil.h"

#include "core/io/h5.h"

#include <hdf5.h> /* to look at the stored types and to forge an older file */
#include <unistd.h>

static char path[256];

static void setup(void)
{
    snprintf(path, sizeof path, "/tmp/wt_h5s_%d.h5", (int)getpid());
}

static void teardown(void) { unlink(path); }

/* 1 when the object's type is a variable-length UTF-8 string. */
static int is_vlen_utf8(hid_t type)
{
    return H5Tget_class(type) == H5T_STRING && H5Tis_variable_str(type) > 0 && H5Tget_cset(type) == H5T_CSET_UTF8;
}

START_TEST(test_strings_are_vlen_utf8)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    const char *text = "recon = \"pcg3\"; # \xce\xb1 = 0.5\n"; /* a UTF-8 alpha, as a comment may hold */
    int64_t n = 2;
    double v[2] = {1, 2};
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write_string(w, "config", text, "the configuration"), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "x", WT_H5_F64, WT_H5_F64, 1, &n, v, "nm", "values"), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_string(w, "/", "recon", "pcg3"), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_string(w, "x", "note", ""), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    ck_assert(f >= 0);
    hid_t d = H5Dopen2(f, "config", H5P_DEFAULT), t = H5Dget_type(d);
    ck_assert_msg(is_vlen_utf8(t), "the string dataset 'config' is not variable-length UTF-8");
    H5Tclose(t);
    H5Dclose(d);
    static const char *const attrs[][2] = {{"/", "recon"}, {"/", "creator"}, {"/", "hdf5_version"}, {"x", "units"},
                                           {"x", "description"}, {"x", "note"}, {"config", "description"}};
    for (size_t i = 0; i < sizeof attrs / sizeof attrs[0]; i++) {
        hid_t a = H5Aopen_by_name(f, attrs[i][0], attrs[i][1], H5P_DEFAULT, H5P_DEFAULT);
        ck_assert_msg(a >= 0, "no attribute %s of %s", attrs[i][1], attrs[i][0]);
        t = H5Aget_type(a);
        ck_assert_msg(is_vlen_utf8(t), "the attribute %s of %s is not a variable-length UTF-8 string", attrs[i][1],
                      attrs[i][0]);
        H5Tclose(t);
        H5Aclose(a);
    }
    H5Fclose(f);

    wt_h5_reader *r = NULL;
    char *s = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, path, &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_string(r, "config", &s), WT_OK);
    ck_assert_str_eq(s, text);
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "recon", &s), WT_OK);
    ck_assert_str_eq(s, "pcg3");
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "x", "note", &s), WT_OK);
    ck_assert_str_eq(s, "");
    wt_free(ctx, s);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

/* A fixed-length string type of `len` bytes, cset and padding as given. */
static hid_t fixed_type(size_t len, H5T_cset_t cset, H5T_str_t pad)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    ck_assert(t >= 0 && H5Tset_size(t, len) >= 0 && H5Tset_cset(t, cset) >= 0 && H5Tset_strpad(t, pad) >= 0);
    return t;
}

static void put_fixed_attr(hid_t obj, const char *name, const char *value, H5T_cset_t cset, H5T_str_t pad)
{
    size_t len = strlen(value) + (pad == H5T_STR_NULLTERM);
    char buf[256] = "";
    ck_assert_uint_lt(len, sizeof buf);
    memcpy(buf, value, strlen(value));
    hid_t t = fixed_type(len ? len : 1, cset, pad), sp = H5Screate(H5S_SCALAR);
    if (H5Aexists(obj, name) > 0) H5Adelete(obj, name);
    hid_t a = H5Acreate2(obj, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
    ck_assert(a >= 0 && H5Awrite(a, t, buf) >= 0);
    H5Aclose(a);
    H5Sclose(sp);
    H5Tclose(t);
}

/* A file as wavetomo wrote it before strings were variable-length (fixed-length, NUL-terminated UTF-8), and
 * a fixed-length string of another writer (ASCII, NUL-padded): all read back as the text. */
START_TEST(test_reads_fixed_length_strings)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    int64_t n = 1;
    double v = 3;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "x", WT_H5_F64, WT_H5_F64, 1, &n, &v, "nm", "values"), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    ck_assert(f >= 0);
    const char *text = "lgs = { wfs = { photons = 100; }; }; # \xce\xbc";
    hid_t t = fixed_type(strlen(text) + 1, H5T_CSET_UTF8, H5T_STR_NULLTERM), sp = H5Screate(H5S_SCALAR);
    hid_t d = H5Dcreate2(f, "config", t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ck_assert(d >= 0 && H5Dwrite(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, text) >= 0);
    put_fixed_attr(d, "description", "the configuration", H5T_CSET_UTF8, H5T_STR_NULLTERM);
    H5Dclose(d);
    H5Sclose(sp);
    H5Tclose(t);
    hid_t x = H5Dopen2(f, "x", H5P_DEFAULT);
    put_fixed_attr(x, "units", "nm", H5T_CSET_UTF8, H5T_STR_NULLTERM);
    put_fixed_attr(x, "empty", "", H5T_CSET_UTF8, H5T_STR_NULLTERM);
    H5Dclose(x);
    put_fixed_attr(f, "recon", "cg9", H5T_CSET_UTF8, H5T_STR_NULLTERM);
    put_fixed_attr(f, "ascii_nullpad", "fp32", H5T_CSET_ASCII, H5T_STR_NULLPAD);
    put_fixed_attr(f, "creator", "wavetomo 0.1.0", H5T_CSET_UTF8, H5T_STR_NULLTERM);
    H5Fclose(f);
    /* an older output is still ours to replace (its creator fixed-length) */
    ck_assert_int_eq(wt_h5_check_replaceable(ctx, path, 0), WT_OK);

    wt_h5_reader *r = NULL;
    char *s = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, path, &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_string(r, "config", &s), WT_OK);
    ck_assert_str_eq(s, text);
    wt_free(ctx, s);
    static const char *const want[][3] = {
        {"/", "recon", "cg9"}, {"/", "ascii_nullpad", "fp32"}, {"x", "units", "nm"}, {"x", "empty", ""}};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        ck_assert_int_eq(wt_h5_attr_read_string(r, want[i][0], want[i][1], &s), WT_OK);
        ck_assert_str_eq(s, want[i][2]);
        wt_free(ctx, s);
    }
    wt_h5_close(r);
    /* and a file of someone else's, fixed-length or variable-length, is not */
    f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    put_fixed_attr(f, "creator", "h5py", H5T_CSET_ASCII, H5T_STR_NULLTERM);
    H5Fclose(f);
    ck_assert_int_eq(wt_h5_check_replaceable(ctx, path, 0), WT_ERR_IO);
    wt_context_free(ctx);
}
END_TEST

/* The writer's own files (variable-length creator) may be replaced; a variable-length creator of another
 * program may not. */
START_TEST(test_replaceable_vlen_creator)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write_string(w, "config", "a = 1;", "config"), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    ck_assert_int_eq(wt_h5_check_replaceable(ctx, path, 0), WT_OK);
    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT), t = H5Tcopy(H5T_C_S1), sp = H5Screate(H5S_SCALAR);
    const char *other = "another program";
    ck_assert(f >= 0 && H5Tset_size(t, H5T_VARIABLE) >= 0 && H5Adelete(f, "creator") >= 0);
    hid_t a = H5Acreate2(f, "creator", t, sp, H5P_DEFAULT, H5P_DEFAULT);
    ck_assert(a >= 0 && H5Awrite(a, t, &other) >= 0);
    H5Aclose(a), H5Sclose(sp), H5Tclose(t), H5Fclose(f);
    ck_assert_int_eq(wt_h5_check_replaceable(ctx, path, 0), WT_ERR_IO);
    ck_assert_int_eq(wt_h5_check_replaceable(ctx, path, 1), WT_OK); /* --force */
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("h5_strings");
    TCase *tc = tcase_create("h5_strings");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_strings_are_vlen_utf8);
    tcase_add_test(tc, test_reads_fixed_length_strings);
    tcase_add_test(tc, test_replaceable_vlen_creator);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
