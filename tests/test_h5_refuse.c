/* tests/test_h5_refuse.c: the HDF5 layer (core/io/h5_read.c): files that must be refused (wrong shape, claimed
 * dimensions that overflow, a corrupt chunk index, missing, not HDF5, truncated, corrupt), each with a message
 * naming the file, and the opening of a file image. */
#include "h5_fixture.h"

START_TEST(test_shape_mismatch)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "shape.h5");
    char want[700];
    float buf[20 * 30];
    int32_t ib[20 * 30];
    write_small(ctx, p);
    wt_h5_reader *r = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    const int64_t e1[2] = {20, 31}, e2[1] = {600}, e3[2] = {-1, 31}, e4[2] = {-1, 30};
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, e1, NULL, buf, 600), WT_ERR_FORMAT);
    snprintf(want, sizeof want, "%s: dataset 'R' has shape 20 x 30, expected 20 x 31", p);
    ck_assert_str_eq(wt_error_message(ctx), want);
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 1, e2, NULL, buf, 600), WT_ERR_FORMAT);
    snprintf(want, sizeof want, "%s: dataset 'R' has shape 20 x 30, expected 600", p);
    ck_assert_str_eq(wt_error_message(ctx), want);
    ck_assert_int_eq(wt_h5_check_shape(r, "R", 2, e3, NULL), WT_ERR_FORMAT);
    snprintf(want, sizeof want, "%s: dataset 'R' has shape 20 x 30, expected any x 31", p);
    ck_assert_str_eq(wt_error_message(ctx), want);
    int64_t got[2] = {0, 0};
    ck_assert_int_eq(wt_h5_check_shape(r, "R", 2, e4, got), WT_OK);
    ck_assert(got[0] == 20 && got[1] == 30);
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, e4, NULL, buf, 599), WT_ERR_INVALID); /* buffer too small */
    assert_contains(wt_error_message(ctx), "600 elements, the buffer holds 599");
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_I32, 2, e4, NULL, ib, 600), WT_ERR_FORMAT); /* float -> int */
    assert_contains(wt_error_message(ctx), "is float32, refused as int32");
    ck_assert_int_eq(wt_h5_read(r, "Rhat", WT_H5_F32, 2, e4, NULL, buf, 600), WT_ERR_FORMAT);
    snprintf(want, sizeof want, "%s: no dataset 'Rhat'", p);
    ck_assert_str_eq(wt_error_message(ctx), want);
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, e4, NULL, buf, 600), WT_OK);
    ck_assert(buf[599] == 1929.0f);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

/* Dimensions a file may claim (found by tests/fuzz/fuzz_h5_recipe): an empty dataset of rank 4 whose other
 * dimensions multiply past 2^63 (31e9 x 27e9 x 0) is read as empty, rows of 0 elements included, with no
 * integer overflow on the way (UBSan in `make debug-test` caught the old row count); a dataset of more
 * than 2^63 elements is refused by both readers, naming the file. */
START_TEST(test_claimed_dims_overflow)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "dims.h5");
    write_small(ctx, p);
    {
        hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
        ck_assert(f >= 0);
        const hsize_t de[4] = {1, 31000000217ULL, 27000000189ULL, 0}, dh[3] = {2, 4000000000ULL, 4000000000ULL};
        const hsize_t ce[4] = {1, 1, 1, 1}, ch[3] = {1, 1, 1};
        const hsize_t *dims[2] = {de, dh}, *chunk[2] = {ce, ch};
        const int rank[2] = {4, 3};
        const char *name[2] = {"E", "H"};
        for (int k = 0; k < 2; k++) {
            hid_t sp = H5Screate_simple(rank[k], dims[k], NULL), pl = H5Pcreate(H5P_DATASET_CREATE), d;
            ck_assert(sp >= 0 && pl >= 0 && H5Pset_chunk(pl, rank[k], chunk[k]) >= 0);
            ck_assert((d = H5Dcreate2(f, name[k], H5T_IEEE_F64LE, sp, H5P_DEFAULT, pl, H5P_DEFAULT)) >= 0);
            H5Dclose(d), H5Pclose(pl), H5Sclose(sp);
        }
        H5Fclose(f);
    }
    wt_h5_reader *r = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    double buf[4] = {0};
    int64_t got[4];
    ck_assert_msg(wt_h5_read(r, "E", WT_H5_F64, 4, NULL, got, buf, 4) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(got[1] == 31000000217LL && got[3] == 0);
    ck_assert_msg(wt_h5_read_rows(r, "E", WT_H5_F64, 0, 1, buf) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_lt(wt_h5_read(r, "H", WT_H5_F64, 3, NULL, got, buf, 4), 0);
    ck_assert_int_lt(wt_h5_read_rows(r, "H", WT_H5_F64, 0, 1, buf), 0);
    assert_contains(wt_error_message(ctx), p);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

/* A chunk index that claims a 3.5 GB chunk in a 13 kB file (tests/data/corrupt_chunk_index.h5, found by
 * tests/fuzz/fuzz_mvm: HDF5 allocated the claimed size before reading) is refused before HDF5 reads it. */
START_TEST(test_corrupt_chunk_index)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    const char *p = "tests/data/corrupt_chunk_index.h5";
    ck_assert_msg(wt_h5_open(ctx, p, &r) == WT_OK, "%s", wt_error_message(ctx));
    float buf[60];
    const int64_t e[2] = {6, 10};
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, e, NULL, buf, 60), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), "dataset 'R' claims to store 3469235456 bytes in a file of 12911 bytes");
    ck_assert_int_eq(wt_h5_read_rows(r, "R", WT_H5_F32, 0, 1, buf), WT_ERR_FORMAT);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_missing_and_not_hdf5)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, P(0, "nope.h5"), &r), WT_ERR_IO);
    ck_assert_ptr_null(r);
    assert_contains(wt_error_message(ctx), P(0, "nope.h5"));
    assert_contains(wt_error_message(ctx), "No such file");
    FILE *f = fopen(P(1, "text.h5"), "w");
    fputs("telescope = { diameter_m = 39.0; };\n", f);
    fclose(f);
    ck_assert_int_eq(wt_h5_open(ctx, P(1, "text.h5"), &r), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), P(1, "text.h5"));
    assert_contains(wt_error_message(ctx), "not an HDF5 file");
    ck_assert_int_eq(wt_h5_open(ctx, dir, &r), WT_ERR_IO); /* a directory */
    wt_context_free(ctx);
}
END_TEST

/* A valid ~4 MB file cut at several lengths (half, as a disk-full writer would leave it, and near
 * both ends) is refused at open, cleanly, naming the file. */
START_TEST(test_truncated)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "big.h5");
    wt_h5_writer *w = NULL;
    wt_h5_matrix *m = NULL;
    float *row = malloc(sizeof *row * 1000);
    for (int j = 0; j < 1000; j++) row[j] = (float)j;
    ck_assert_int_eq(wt_h5_create(ctx, p, &w), WT_OK);
    ck_assert_int_eq(wt_h5_matrix_create(w, "R", WT_H5_F32, 1000, 1000, "", "x", &m), WT_OK);
    for (int i = 0; i < 1000; i++) ck_assert_int_eq(wt_h5_matrix_write_rows(m, i, 1, WT_H5_F32, row), WT_OK);
    ck_assert_int_eq(wt_h5_write_string(w, "config", "a = 1;", "config"), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    long size = file_size(p);
    ck_assert(size > 4000000);
    const long cuts[6] = {size / 2, size - 1, size - 4096, 3 * size / 4, 4096, 0};
    for (int k = 0; k < 6; k++) {
        wt_h5_reader *r = NULL;
        copy_file(p, P(1, "cut.h5"));
        ck_assert_int_eq(truncate(P(1, "cut.h5"), cuts[k]), 0);
        wt_error_clear(ctx);
        int st = wt_h5_open(ctx, P(1, "cut.h5"), &r);
        ck_assert_msg(st == WT_ERR_FORMAT || st == WT_ERR_IO, "cut at %ld of %ld: status %d", cuts[k], size, st);
        ck_assert_ptr_null(r);
        assert_contains(wt_error_message(ctx), P(1, "cut.h5"));
    }
    free(row);
    wt_context_free(ctx);
}
END_TEST

/* A file read from memory (wt_h5_open_image, the fuzz targets' way in) gives what the file gives, and
 * is refused for the same reasons: no signature, a cut image, a missing "complete". */
START_TEST(test_open_image)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "img.h5");
    write_small(ctx, p);
    long size = file_size(p);
    ck_assert(size > 0);
    unsigned char *img = malloc((size_t)size);
    FILE *f = fopen(p, "rb");
    ck_assert_ptr_nonnull(f);
    ck_assert_int_eq(fread(img, 1, (size_t)size, f), (size_t)size);
    fclose(f);
    wt_h5_reader *r = NULL;
    float a[20 * 30];
    ck_assert_msg(wt_h5_open_image(ctx, "mem.h5", img, (size_t)size, &r) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(wt_h5_path(r), "mem.h5");
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, NULL, NULL, a, 600), WT_OK);
    ck_assert(a[31] == 101.0f && a[599] == 1929.0f);
    wt_h5_close(r);
    /* a cut image: the superblock's end of file is beyond the bytes given */
    ck_assert_int_eq(wt_h5_open_image(ctx, "mem.h5", img, (size_t)size / 2, &r), WT_ERR_FORMAT);
    ck_assert_ptr_null(r);
    assert_contains(wt_error_message(ctx), "mem.h5");
    img[1] ^= 1; /* no signature */
    ck_assert_int_eq(wt_h5_open_image(ctx, "mem.h5", img, (size_t)size, &r), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), "not an HDF5 file");
    ck_assert_int_eq(wt_h5_open_image(ctx, "mem.h5", img, 3, &r), WT_ERR_FORMAT);
    free(img);
    wt_context_free(ctx);
}
END_TEST

/* One flipped byte in the data of R: the file opens (its metadata is intact) but reading R fails its
 * Fletcher32 checksum instead of returning a wrong matrix. */
START_TEST(test_corrupt_data)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "corrupt.h5");
    write_small(ctx, p); /* row 7 = 700, 701, ... */
    long n = file_size(p);
    unsigned char *bytes = malloc((size_t)n);
    FILE *f = fopen(p, "rb");
    ck_assert_int_eq((long)fread(bytes, 1, (size_t)n, f), n);
    fclose(f);
    float pat[4] = {700, 701, 702, 703};
    long at = -1;
    for (long i = 0; i + 16 <= n && at < 0; i++)
        if (memcmp(bytes + i, pat, 16) == 0) at = i;
    ck_assert_msg(at >= 0, "row 7 not found in the file");
    bytes[at + 5] ^= 0x10;
    f = fopen(p, "wb");
    fwrite(bytes, 1, (size_t)n, f);
    fclose(f);
    wt_h5_reader *r = NULL;
    float buf[600];
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, NULL, NULL, buf, 600), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), p);
    assert_contains(wt_error_message(ctx), "dataset 'R'");
    ck_assert_int_eq(wt_h5_read_rows(r, "R", WT_H5_F32, 7, 1, buf), WT_ERR_FORMAT);
    wt_h5_close(r);
    free(bytes);
    wt_context_free(ctx);
}
END_TEST

/* The life of the temporary: the target appears only at commit; a copy of the temporary taken
 * before commit (a crashed writer) is refused for lacking "complete"; abort leaves nothing; a commit
 * replaces an older target. */
Suite *make_suite(void)
{
    Suite *s = suite_create("h5_refuse");
    TCase *tc = tcase_create("h5");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_shape_mismatch);
    tcase_add_test(tc, test_missing_and_not_hdf5);
    tcase_add_test(tc, test_truncated);
    tcase_add_test(tc, test_open_image);
    tcase_add_test(tc, test_corrupt_data);
    tcase_add_test(tc, test_claimed_dims_overflow);
    tcase_add_test(tc, test_corrupt_chunk_index);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
