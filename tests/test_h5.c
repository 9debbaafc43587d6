/* tests/test_h5.c: the HDF5 layer (core/io/h5_write.c): round trips of every type and rank, row-block
 * matrices, appendable series, the atomic commit, poisoned and silent writers, allocation failures and HDF5's
 * error state (the files that must be refused: test_h5_refuse.c). */
#include "h5_fixture.h"

/* Element i of the round-trip data of type index t: exactly representable in that type (so equality
 * is exact), negative for the signed types, beyond 2^31 for int64, up to 255 for uint8. */
static double rt_value(int t, int64_t i)
{
    switch (t) {
    case 0: case 1: return (double)(i - 9) * 0.25;
    case 2: return (double)(i * 1000 - 20000);
    case 3: return 3.0e9 + (double)(i - 5);
    default: return (double)(i * 7 % 256);
    }
}

/* Every type and rank, with attributes, read back as double and in its own type. */
START_TEST(test_roundtrip_types)
{
    wt_context *ctx = tu_context();
    const int types[5] = {WT_H5_F64, WT_H5_F32, WT_H5_I32, WT_H5_I64, WT_H5_U8};
    const char *tn[5] = {"f64", "f32", "i32", "i64", "u8"};
    const int64_t shapes[WT_H5_MAX_RANK][WT_H5_MAX_RANK] = {{7, 0, 0, 0}, {4, 5, 0, 0}, {3, 2, 4, 0}, {2, 3, 2, 2}};
    double f64[24], back[24];
    float f32[24];
    int32_t i32[24];
    int64_t i64[24];
    uint8_t u8[24];
    void *bufs[5] = {f64, f32, i32, i64, u8};
    wt_h5_writer *w = NULL;
    wt_h5_reader *r = NULL;
    char name[64], *s = NULL;
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "rt.h5"), &w), WT_OK);
    for (int t = 0; t < 5; t++)
        for (int rank = 1; rank <= WT_H5_MAX_RANK; rank++) {
            for (int64_t i = 0; i < 24; i++) {
                double v = rt_value(t, i);
                f64[i] = v, f32[i] = (float)v, i32[i] = (int32_t)v, i64[i] = (int64_t)v, u8[i] = (uint8_t)v;
            }
            snprintf(name, sizeof name, "t/%s_r%d", tn[t], rank);
            ck_assert_int_eq(wt_h5_write(w, name, types[t], types[t], rank, shapes[rank - 1], bufs[t], "m",
                                         "round trip"), WT_OK);
            ck_assert_int_eq(wt_h5_attr_write_string(w, name, "note", name), WT_OK);
        }
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    ck_assert_int_eq(wt_h5_open(ctx, P(0, "rt.h5"), &r), WT_OK);
    for (int t = 0; t < 5; t++)
        for (int rank = 1; rank <= WT_H5_MAX_RANK; rank++) {
            int64_t n = 1, dims[WT_H5_MAX_RANK] = {0};
            int grank = -1;
            for (int k = 0; k < rank; k++) n *= shapes[rank - 1][k];
            snprintf(name, sizeof name, "t/%s_r%d", tn[t], rank);
            ck_assert_int_eq(wt_h5_dims(r, name, &grank, dims), WT_OK);
            ck_assert_int_eq(grank, rank);
            for (int k = 0; k < rank; k++) ck_assert_int_eq(dims[k], shapes[rank - 1][k]);
            /* as double: exact for every type but int64, which is refused (issue 10, class G) */
            int sd = wt_h5_read(r, name, WT_H5_F64, rank, shapes[rank - 1], NULL, back, 24);
            ck_assert_int_eq(sd, t == 3 ? WT_ERR_FORMAT : WT_OK);
            if (t == 3) assert_contains(wt_error_message(ctx), "is int64, refused as float64");
            for (int64_t i = 0; t != 3 && i < n; i++)
                ck_assert_msg(back[i] == rt_value(t, i), "%s[%lld]", name, (long long)i);
            const size_t esize[5] = {8, 4, 4, 8, 1};
            memset(bufs[t], 0xff, 24 * esize[t]); /* so a read that writes nothing cannot pass */
            ck_assert_int_eq(wt_h5_read(r, name, types[t], rank, NULL, NULL, bufs[t], 24), WT_OK);
            for (int64_t i = 0; i < n; i++) {
                double v = t == 0 ? f64[i] : t == 1 ? f32[i] : t == 2 ? i32[i] : t == 3 ? (double)i64[i] : u8[i];
                ck_assert_msg(v == rt_value(t, i), "%s[%lld] read as %s", name, (long long)i, tn[t]);
            }
            const char *attr[3][2] = {{"units", "m"}, {"description", "round trip"}, {"note", name}};
            for (int k = 0; k < 3; k++) {
                ck_assert_int_eq(wt_h5_attr_read_string(r, name, attr[k][0], &s), WT_OK);
                ck_assert_str_eq(s, attr[k][1]);
                wt_free(ctx, s);
            }
        }
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

/* Scalars, strings (a long multi-line UTF-8 text), attributes on root, group and dataset, groups
 * created on the way, attribute replacement, exists() on present and absent paths. */
START_TEST(test_scalars_strings_groups)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    size_t tl = 150000;
    char *text = malloc(tl + 1);
    for (size_t i = 0; i < tl; i++) text[i] = (char)(i % 61 == 60 ? '\n' : 'a' + (char)(i % 26));
    const char utf8[] = "\xce\xb1 = 1.0; /* \xce\xb1 */"; /* alpha, as a config comment might hold */
    memcpy(text + 100, utf8, sizeof utf8 - 1);
    text[tl] = '\0';
    const double third = 1.0 / 3.0;
    const int64_t big = ((int64_t)1 << 40) + 3;
    double d3[3] = {1, 2, 3};
    int64_t n3[1] = {3};
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "s.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_write_double(w, "params/alpha", third, "", "prior weight"), WT_OK);
    ck_assert_int_eq(wt_h5_write_int64(w, "params/seed", big, "", "seed"), WT_OK);
    ck_assert_int_eq(wt_h5_write_string(w, "config", text, "configuration text"), WT_OK);
    ck_assert_int_eq(wt_h5_group(w, "eval/maps"), WT_OK);
    ck_assert_int_eq(wt_h5_group(w, "eval"), WT_OK); /* existing group: fine */
    ck_assert_int_eq(wt_h5_write(w, "eval/strehl_le", WT_H5_F64, WT_H5_F64, 1, n3, d3, "", "Strehl"), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_string(w, "/", "variant", "old"), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_string(w, "/", "variant", "cg9"), WT_OK); /* replaced */
    ck_assert_int_eq(wt_h5_attr_write_double(w, "eval", "wavelength", 2.2e-6), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_int64(w, "eval/strehl_le", "settle", -50), WT_OK);
    ck_assert_int_eq(wt_h5_attr_write_string(w, "/", "empty", ""), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    wt_h5_reader *r = NULL;
    double v;
    int64_t k;
    char *s = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, P(0, "s.h5"), &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_double(r, "params/alpha", &v), WT_OK);
    ck_assert(v == third);
    ck_assert_int_eq(wt_h5_read_int64(r, "params/seed", &k), WT_OK);
    ck_assert(k == big);
    ck_assert_int_eq(wt_h5_read_string(r, "config", &s), WT_OK);
    ck_assert_uint_eq(strlen(s), tl);
    ck_assert(memcmp(s, text, tl) == 0);
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "variant", &s), WT_OK);
    ck_assert_str_eq(s, "cg9");
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "empty", &s), WT_OK);
    ck_assert_str_eq(s, "");
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "creator", &s), WT_OK);
    ck_assert_str_eq(s, "wavetomo " WT_VERSION);
    wt_free(ctx, s);
    ck_assert_int_eq(wt_h5_attr_read_double(r, "eval", "wavelength", &v), WT_OK);
    ck_assert(v == 2.2e-6);
    ck_assert_int_eq(wt_h5_attr_read_int64(r, "eval/strehl_le", "settle", &k), WT_OK);
    ck_assert(k == -50);
    ck_assert_int_eq(wt_h5_attr_read_int64(r, "/", "complete", &k), WT_OK);
    ck_assert(k == 1);
    /* the wrong kind of thing is refused, not converted */
    ck_assert_int_eq(wt_h5_attr_read_double(r, "/", "variant", &v), WT_ERR_FORMAT);
    ck_assert_int_eq(wt_h5_read_double(r, "eval/strehl_le", &v), WT_ERR_FORMAT);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "eval", "nope", &s), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), "'eval' has no attribute 'nope'");
    ck_assert_int_eq(wt_h5_exists(r, "/"), 1);
    ck_assert_int_eq(wt_h5_exists(r, "eval"), 1);
    ck_assert_int_eq(wt_h5_exists(r, "eval/maps"), 1);
    ck_assert_int_eq(wt_h5_exists(r, "eval/strehl_le"), 1);
    ck_assert_int_eq(wt_h5_exists(r, "eval/strehl_se"), 0);
    ck_assert_int_eq(wt_h5_exists(r, "nope/strehl_le"), 0);
    ck_assert_int_eq(wt_h5_exists(r, "eval/strehl_le/x"), 0);
    wt_h5_close(r);
    free(text);
    wt_context_free(ctx);
}
END_TEST

/* ---- row-block matrices and series --------------------------------------------------------------- */

/* A float32 matrix written from double rows in 7-row blocks, in a scrambled order that never aligns
 * with the 3-row chunks (280 kB rows): every element must read back as exactly (float)source. */
START_TEST(test_matrix_blocks)
{
    enum { ROWS = 50, COLS = 70000, B = 7 };
    wt_context *ctx = tu_context();
    double *a = malloc(sizeof *a * ROWS * COLS);
    float *back = malloc(sizeof *back * ROWS * COLS);
    tu_randn(a, (long)ROWS * COLS, 11);
    wt_h5_writer *w = NULL;
    wt_h5_matrix *m = NULL;
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "m.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_matrix_create(w, "R", WT_H5_F32, ROWS, COLS, "rad/m", "reconstructor", &m), WT_OK);
    const int order[8] = {3, 0, 7, 5, 1, 6, 2, 4}; /* block 7 is the short one (rows 49..49) */
    for (int k = 0; k < 8; k++) {
        int64_t r0 = (int64_t)order[k] * B, nr = r0 + B <= ROWS ? B : ROWS - r0;
        ck_assert_int_eq(wt_h5_matrix_write_rows(m, r0, nr, WT_H5_F64, a + r0 * COLS), WT_OK);
    }
    ck_assert_int_eq(wt_h5_matrix_write_rows(m, 45, 6, WT_H5_F64, a), WT_ERR_INVALID); /* past the end */
    assert_contains(wt_error_message(ctx), "rows 45..50, expected within 0..49");
    wt_error_clear(ctx);
    ck_assert_int_eq(wt_h5_commit(w), WT_ERR_INVALID); /* that failed call poisoned the writer */
    ck_assert(!file_exists(P(0, "m.h5")));

    /* again, cleanly, with the matrix closed early */
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "m.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_matrix_create(w, "R", WT_H5_F32, ROWS, COLS, "rad/m", "reconstructor", &m), WT_OK);
    for (int k = 0; k < 8; k++) {
        int64_t r0 = (int64_t)order[k] * B, nr = r0 + B <= ROWS ? B : ROWS - r0;
        ck_assert_int_eq(wt_h5_matrix_write_rows(m, r0, nr, WT_H5_F64, a + r0 * COLS), WT_OK);
    }
    ck_assert_int_eq(wt_h5_matrix_close(m), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    wt_h5_reader *r = NULL;
    const int64_t expect[2] = {ROWS, COLS};
    ck_assert_int_eq(wt_h5_open(ctx, P(0, "m.h5"), &r), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "R", WT_H5_F32, 2, expect, NULL, back, (size_t)ROWS * COLS), WT_OK);
    for (long i = 0; i < (long)ROWS * COLS; i++)
        if (back[i] != (float)a[i]) ck_abort_msg("R[%ld] = %g, expected %g", i, back[i], (float)a[i]);
    /* a block of rows as double: rows 10..12 */
    double *rows = malloc(sizeof *rows * 3 * COLS);
    ck_assert_int_eq(wt_h5_read_rows(r, "R", WT_H5_F64, 10, 3, rows), WT_OK);
    for (long i = 0; i < 3L * COLS; i++) ck_assert(rows[i] == (double)(float)a[10 * COLS + i]);
    ck_assert_int_eq(wt_h5_read_rows(r, "R", WT_H5_F64, 48, 3, rows), WT_ERR_INVALID);
    assert_contains(wt_error_message(ctx), "has 50 rows, rows 48..50 requested");
    wt_h5_close(r);
    free(rows);
    free(a);
    free(back);
    wt_context_free(ctx);
}
END_TEST

/* A matrix with a row never written is not published: commit fails naming it, and nothing is left. */
START_TEST(test_matrix_incomplete)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    wt_h5_matrix *m = NULL;
    float row[40] = {0};
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "inc.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_matrix_create(w, "R", WT_H5_F32, 10, 40, "", "x", &m), WT_OK);
    for (int i = 0; i < 10; i++)
        if (i != 6) ck_assert_int_eq(wt_h5_matrix_write_rows(m, i, 1, WT_H5_F32, row), WT_OK);
    ck_assert_int_eq(wt_h5_matrix_write_rows(m, 3, 1, WT_H5_F32, row), WT_OK); /* a rewrite adds nothing */
    ck_assert_int_eq(wt_h5_commit(w), WT_ERR_INVALID);
    assert_contains(wt_error_message(ctx), "matrix 'R' has 10 rows, only 9 were written (first missing: 6)");
    assert_contains(wt_error_message(ctx), P(0, "inc.h5"));
    ck_assert_int_eq(count_files(), 0);
    wt_context_free(ctx);
}
END_TEST

/* Telemetry-like series: 40 frames of 1000 float32 (from double, values exact in float), a 1-D
 * double series and an int32 series; whole reads and frame-by-frame reads agree with the source. */
START_TEST(test_series)
{
    enum { F = 40, N = 1000 };
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    wt_h5_series *s = NULL, *s1 = NULL, *si = NULL;
    double frame[N];
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "tel.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "telemetry/slopes", WT_H5_F32, N, "rad", "slopes", &s), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "eval/strehl", WT_H5_F64, 0, "", "Strehl per frame", &s1), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "telemetry/flags", WT_H5_I32, 3, "", "flags", &si), WT_OK);
    ck_assert_int_eq(wt_h5_series_append(si, WT_H5_F64, frame), WT_ERR_INVALID); /* lossy: refused */
    wt_h5_abort(w); /* that poisoned the writer; start over */
    ck_assert_int_eq(count_files(), 0);

    ck_assert_int_eq(wt_h5_create(ctx, P(0, "tel.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "telemetry/slopes", WT_H5_F32, N, "rad", "slopes", &s), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "eval/strehl", WT_H5_F64, 0, "", "Strehl per frame", &s1), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "telemetry/flags", WT_H5_I32, 3, "", "flags", &si), WT_OK);
    for (int f = 0; f < F; f++) {
        for (int j = 0; j < N; j++) frame[j] = f * 1000.0 + j - 0.5;
        double st = 1.0 / (f + 1.0);
        int32_t fl[3] = {f, -f, f * f};
        ck_assert_int_eq(wt_h5_series_append(s, WT_H5_F64, frame), WT_OK);
        ck_assert_int_eq(wt_h5_series_append(s1, WT_H5_F64, &st), WT_OK);
        ck_assert_int_eq(wt_h5_series_append(si, WT_H5_I32, fl), WT_OK);
    }
    ck_assert_int_eq(wt_h5_series_length(s), F);
    ck_assert_int_eq(wt_h5_series_close(s1), WT_OK); /* early close; the other two close at commit */
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);

    wt_h5_reader *r = NULL;
    int64_t dims[3], any2[2] = {-1, N}, any1[1] = {-1};
    float *all = malloc(sizeof *all * F * N);
    double strehl[F];
    int32_t flags[3 * F];
    ck_assert_int_eq(wt_h5_open(ctx, P(0, "tel.h5"), &r), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "telemetry/slopes", WT_H5_F32, 2, any2, dims, all, (size_t)F * N), WT_OK);
    ck_assert_int_eq(dims[0], F);
    ck_assert_int_eq(dims[1], N);
    for (int f = 0; f < F; f++)
        for (int j = 0; j < N; j++) ck_assert(all[f * N + j] == (float)(f * 1000.0 + j - 0.5));
    ck_assert_int_eq(wt_h5_read(r, "eval/strehl", WT_H5_F64, 1, any1, dims, strehl, F), WT_OK);
    ck_assert_int_eq(dims[0], F);
    for (int f = 0; f < F; f++) ck_assert(strehl[f] == 1.0 / (f + 1.0));
    ck_assert_int_eq(wt_h5_read(r, "telemetry/flags", WT_H5_I32, 2, NULL, dims, flags, 3 * F), WT_OK);
    ck_assert(flags[3 * 7 + 2] == 49 && flags[3 * 39 + 1] == -39);
    for (int f = F - 1; f >= 0; f -= 3) { /* frame by frame, as the runtime replays telemetry */
        float one[N];
        double sf;
        ck_assert_int_eq(wt_h5_read_rows(r, "telemetry/slopes", WT_H5_F32, f, 1, one), WT_OK);
        ck_assert(memcmp(one, all + f * N, sizeof one) == 0);
        ck_assert_int_eq(wt_h5_read_rows(r, "eval/strehl", WT_H5_F64, f, 1, &sf), WT_OK);
        ck_assert(sf == strehl[f]);
    }
    ck_assert_int_eq(wt_h5_read_rows(r, "telemetry/slopes", WT_H5_F32, F, 1, all), WT_ERR_INVALID);
    wt_h5_close(r);
    free(all);
    wt_context_free(ctx);
}
END_TEST

/* ---- refusals ------------------------------------------------------------------------------------ */

START_TEST(test_atomic_commit)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "run.h5");
    char tmp[600];
    wt_h5_writer *w = NULL;
    double x[4] = {1, 2, 3, 4};
    int64_t n4[1] = {4};
    write_small(ctx, p); /* an older result at the target */
    ck_assert_int_eq(wt_h5_create(ctx, p, &w), WT_OK);
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", p, (long)getpid());
    ck_assert_str_eq(wt_h5_temp_path(w), tmp);
    ck_assert_str_eq(wt_h5_target_path(w), p);
    ck_assert_int_eq(wt_h5_write(w, "x", WT_H5_F64, WT_H5_F64, 1, n4, x, "", "x"), WT_OK);
    ck_assert_int_eq(wt_h5_flush(w), WT_OK);
    ck_assert(file_exists(tmp));
    copy_file(tmp, P(1, "crashed.h5"));
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    ck_assert(!file_exists(tmp));
    ck_assert_int_eq(count_files(), 2);

    wt_h5_reader *r = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    ck_assert_int_eq(wt_h5_exists(r, "x"), 1);
    ck_assert_int_eq(wt_h5_exists(r, "R"), 0); /* the old file is gone */
    wt_h5_close(r);
    ck_assert_int_eq(wt_h5_open(ctx, P(1, "crashed.h5"), &r), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), P(1, "crashed.h5"));
    assert_contains(wt_error_message(ctx), "no root attribute 'complete'");
    unlink(P(1, "crashed.h5"));
    unlink(p);

    ck_assert_int_eq(wt_h5_create(ctx, p, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "x", WT_H5_F64, WT_H5_F64, 1, n4, x, "", "x"), WT_OK);
    ck_assert(file_exists(tmp) && !file_exists(p)); /* before commit: only the temporary */
    ck_assert_int_eq(wt_h5_attr_write_int64(w, "/", "complete", 1), WT_ERR_INVALID); /* reserved */
    wt_h5_abort(w);
    ck_assert_int_eq(count_files(), 0);
    wt_h5_abort(NULL);
    wt_context_free(ctx);
}
END_TEST

/* Undocumented or duplicate datasets and lossy writes are refused, and poison the writer. */
START_TEST(test_poisoned_writer)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w = NULL;
    double x[2] = {1.5, 2};
    int64_t n2[1] = {2};
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "p.h5"), &w), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "a", WT_H5_F64, WT_H5_F64, 1, n2, x, "m", "a"), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "a", WT_H5_F64, WT_H5_F64, 1, n2, x, "m", "again"), WT_ERR_INVALID);
    assert_contains(wt_error_message(ctx), "'a' already exists");
    ck_assert_int_eq(wt_h5_write(w, "b", WT_H5_F64, WT_H5_F64, 1, n2, x, NULL, "b"), WT_ERR_INVALID);
    ck_assert_int_eq(wt_h5_write(w, "c", WT_H5_F64, WT_H5_F64, 1, n2, x, "m", ""), WT_ERR_INVALID);
    ck_assert_int_eq(wt_h5_write(w, "d", WT_H5_I32, WT_H5_F64, 1, n2, x, "m", "d"), WT_ERR_INVALID);
    const int64_t n5[WT_H5_MAX_RANK + 1] = {2, 1, 1, 1, 1}; /* a rank past the limit */
    ck_assert_int_eq(wt_h5_write(w, "e", WT_H5_F64, WT_H5_F64, WT_H5_MAX_RANK + 1, n5, x, "m", "e"), WT_ERR_INVALID);
    ck_assert_int_eq(wt_h5_group(w, "a"), WT_ERR_INVALID); /* a dataset is not a group */
    assert_contains(wt_error_message(ctx), "'a' exists and is not a group");
    ck_assert_int_eq(wt_h5_write(w, "f", WT_H5_F64, WT_H5_F64, 1, n2, x, "m", "f"), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_ERR_INVALID);
    assert_contains(wt_error_message(ctx), "an earlier call failed");
    assert_contains(wt_error_message(ctx), "'a' already exists"); /* the first failure is the one named */
    ck_assert_int_eq(count_files(), 0);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_check_writable)
{
    wt_context *ctx = tu_context();
    ck_assert_int_eq(wt_h5_check_writable(ctx, P(0, "out.h5"), 1000), WT_OK);
    ck_assert_int_eq(count_files(), 0); /* the probe is gone */
    ck_assert_int_eq(wt_h5_check_writable(ctx, P(0, "missing/out.h5"), 0), WT_ERR_IO);
    assert_contains(wt_error_message(ctx), P(1, "missing"));
    assert_contains(wt_error_message(ctx), "does not exist");
    ck_assert_int_eq(wt_h5_check_writable(ctx, dir, 0), WT_ERR_IO); /* a directory is not a file name */
    ck_assert_int_eq(wt_h5_check_writable(ctx, P(0, "out.h5"), (int64_t)1 << 62), WT_ERR_IO);
    assert_contains(wt_error_message(ctx), "GB are free");
    wt_h5_writer *w = NULL;
    ck_assert_int_eq(wt_h5_create(ctx, P(0, "missing/out.h5"), &w), WT_ERR_IO);
    ck_assert_ptr_null(w);
    assert_contains(wt_error_message(ctx), P(0, "missing/out.h5"));
    wt_context_free(ctx);
}
END_TEST

/* HDF5 prints its error stack to stderr unless told not to: failing calls must print nothing. */
START_TEST(test_silent)
{
    wt_context *ctx = tu_context();
    const char *p = P(0, "ok.h5");
    write_small(ctx, p);
    copy_file(p, P(1, "cut.h5"));
    ck_assert_int_eq(truncate(P(1, "cut.h5"), file_size(p) / 2), 0);
    fflush(stderr);
    int saved = dup(2), fd = open(P(2, "stderr.txt"), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fd, 2);
    wt_h5_reader *r = NULL;
    wt_h5_writer *w = NULL;
    const int64_t bad[2] = {3, 3};
    float buf[600];
    int s1 = wt_h5_open(ctx, P(1, "cut.h5"), &r);
    int s2 = wt_h5_create(ctx, P(3, "missing/x.h5"), &w);
    int s3 = wt_h5_open(ctx, p, &r);
    int s4 = wt_h5_read(r, "R", WT_H5_F32, 2, bad, NULL, buf, 600);
    int s5 = wt_h5_read(r, "nope/R", WT_H5_F32, 2, NULL, NULL, buf, 600);
    int s6 = wt_h5_exists(r, "nope/R");
    wt_h5_close(r);
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    close(fd);
    ck_assert(s1 < 0 && s2 < 0 && s3 == WT_OK && s4 < 0 && s5 < 0 && s6 == 0);
    ck_assert_int_eq(file_size(P(2, "stderr.txt")), 0);
    wt_context_free(ctx);
}
END_TEST

/* Allocation failure at every allocation of a write + read cycle: each run ends in WT_ERR_NOMEM or
 * success, never leaves a temporary behind, and leaves the target only when commit succeeded. */
static int alloc_cycle(wt_context *ctx, const char *path)
{
    int st;
    wt_h5_writer *w = NULL;
    wt_h5_matrix *m = NULL;
    wt_h5_series *s = NULL;
    wt_h5_reader *r = NULL;
    char *text = NULL;
    float row[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    if ((st = wt_h5_create(ctx, path, &w)) < 0) return st;
    if ((st = wt_h5_matrix_create(w, "R", WT_H5_F32, 2, 8, "", "m", &m)) < 0 ||
        (st = wt_h5_matrix_write_rows(m, 0, 1, WT_H5_F32, row)) < 0 ||
        (st = wt_h5_matrix_write_rows(m, 1, 1, WT_H5_F32, row)) < 0 ||
        (st = wt_h5_series_create(w, "s", WT_H5_F32, 8, "", "s", &s)) < 0 ||
        (st = wt_h5_series_append(s, WT_H5_F32, row)) < 0 || (st = wt_h5_write_string(w, "c", "a = 1;", "c")) < 0) {
        wt_h5_abort(w);
        return st;
    }
    if ((st = wt_h5_commit(w)) < 0) return st;
    if ((st = wt_h5_open(ctx, path, &r)) < 0) return st;
    st = wt_h5_read_string(r, "c", &text);
    if (st == WT_OK) st = strcmp(text, "a = 1;") == 0 ? WT_OK : WT_ERR_FORMAT;
    wt_free(ctx, text);
    wt_h5_close(r);
    return st;
}

START_TEST(test_alloc_failures)
{
    char tmp[600];
    int k;
    for (k = 0; k < 100; k++) {
        tu_alloc fa = TU_ALLOC_INIT;
        tu_alloc_fail_nth(&fa, k);
        wt_context *ctx = tu_context();
        tu_alloc_install(ctx, &fa);
        int st = alloc_cycle(ctx, P(0, "a.h5"));
        snprintf(tmp, sizeof tmp, "%s.tmp-%ld", P(0, "a.h5"), (long)getpid());
        ck_assert_msg(!file_exists(tmp), "allocation %d: temporary left behind", k);
        if (!fa.failed) {
            ck_assert_int_eq(st, WT_OK);
            wt_context_free(ctx);
            break;
        }
        ck_assert_msg(st == WT_ERR_NOMEM, "allocation %d failed: status %d (%s)", k, st, wt_error_message(ctx));
        unlink(P(0, "a.h5"));
        wt_context_free(ctx);
    }
    ck_assert(k > 5 && k < 100); /* the cycle allocates a handful of times, and did complete */
}
END_TEST

/* HDF5's automatic error printing is the caller's setting: off inside our calls, restored after.
 * A counting handler must see none of our failures and still see a direct HDF5 failure afterwards.
 * Then files the API cannot write, forged with HDF5 directly: "complete" = 0 (refused) and a
 * variable-length string attribute written by HDF5 directly (ASCII, as h5py writes them). */
static int hdf5_prints;
static herr_t count_prints(hid_t stack, void *user)
{
    (void)stack, (void)user;
    hdf5_prints++;
    return 0;
}

START_TEST(test_hdf5_error_state)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    H5Eset_auto2(H5E_DEFAULT, count_prints, NULL);
    ck_assert_int_eq(wt_h5_open(ctx, P(0, "nope.h5"), &r), WT_ERR_IO);
    write_small(ctx, P(1, "ok.h5"));
    ck_assert_int_eq(wt_h5_open(ctx, P(1, "ok.h5"), &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_double(r, "nope/x", &(double){0}), WT_ERR_FORMAT);
    wt_h5_close(r);
    ck_assert_int_eq(hdf5_prints, 0);
    H5E_auto2_t f = NULL;
    void *u = NULL;
    H5Eget_auto2(H5E_DEFAULT, &f, &u);
    ck_assert(f == count_prints);
    ck_assert(H5Dopen2(-1, "x", H5P_DEFAULT) < 0);
    ck_assert_int_eq(hdf5_prints, 1);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);

    /* a file whose "complete" is not 1 (forged: commit always writes 1) is refused too */
    hid_t file = H5Fopen(P(1, "ok.h5"), H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t a = H5Aopen(file, "complete", H5P_DEFAULT);
    const int64_t zero = 0;
    ck_assert(file >= 0 && a >= 0 && H5Awrite(a, H5T_NATIVE_INT64, &zero) >= 0);
    H5Aclose(a);
    /* and a variable-length ASCII string, as h5py writes them (ours are UTF-8) */
    hid_t vt = H5Tcopy(H5T_C_S1), sp = H5Screate(H5S_SCALAR);
    const char *vl = "written by h5py";
    H5Tset_size(vt, H5T_VARIABLE);
    a = H5Acreate2(file, "vl", vt, sp, H5P_DEFAULT, H5P_DEFAULT);
    ck_assert(a >= 0 && H5Awrite(a, vt, &vl) >= 0);
    H5Aclose(a);
    H5Sclose(sp);
    H5Tclose(vt);
    H5Fclose(file);
    ck_assert_int_eq(wt_h5_open(ctx, P(1, "ok.h5"), &r), WT_ERR_FORMAT);
    assert_contains(wt_error_message(ctx), "root attribute 'complete' is 0, expected 1");
    file = H5Fopen(P(1, "ok.h5"), H5F_ACC_RDWR, H5P_DEFAULT);
    a = H5Aopen(file, "complete", H5P_DEFAULT);
    const int64_t one = 1;
    ck_assert(H5Awrite(a, H5T_NATIVE_INT64, &one) >= 0);
    H5Aclose(a);
    H5Fclose(file);
    char *text = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, P(1, "ok.h5"), &r), WT_OK);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "vl", &text), WT_OK);
    ck_assert_str_eq(text, vl);
    wt_free(ctx, text);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_version)
{
    const char *v = wt_h5_library_version();
    int a = -1, b = -1, c = -1;
    ck_assert_int_eq(sscanf(v, "%d.%d.%d", &a, &b, &c), 3);
    ck_assert(a == 1 && b >= 10 && c >= 0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("h5");
    TCase *tc = tcase_create("h5");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_roundtrip_types);
    tcase_add_test(tc, test_scalars_strings_groups);
    tcase_add_test(tc, test_matrix_blocks);
    tcase_add_test(tc, test_matrix_incomplete);
    tcase_add_test(tc, test_series);
    tcase_add_test(tc, test_atomic_commit);
    tcase_add_test(tc, test_poisoned_writer);
    tcase_add_test(tc, test_check_writable);
    tcase_add_test(tc, test_silent);
    tcase_add_test(tc, test_alloc_failures);
    tcase_add_test(tc, test_hdf5_error_state);
    tcase_add_test(tc, test_version);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
