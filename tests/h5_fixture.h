/* tests/h5_fixture.h: what the HDF5 suites share (test_h5.c, test_h5_refuse.c): a scratch directory per test,
 * paths in it, file copies and sizes, message checks, and a small committed file. */
#ifndef WT_TESTS_H5_FIXTURE_H
#define WT_TESTS_H5_FIXTURE_H

#include "testutil.h"

#include "core/io/h5.h"

#include <dirent.h>
#include <hdf5.h> /* only to check HDF5's error-printing state and to forge a file the API cannot write */
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>


/* ---- helpers: a scratch directory per test, file copies ---------------------------------------- */

static char dir[256];
static char path_buf[8][512];

static inline void setup(void)
{
    snprintf(dir, sizeof dir, "/tmp/wt_h5_XXXXXX");
    ck_assert_ptr_nonnull(mkdtemp(dir));
}

static inline void teardown(void)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char p[600];
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            unlink(p);
        }
    closedir(d);
    rmdir(dir);
}

/* A path in the scratch directory (up to 8 live at once). */
static inline const char *P(int slot, const char *name)
{
    snprintf(path_buf[slot], sizeof path_buf[slot], "%s/%s", dir, name);
    return path_buf[slot];
}

static inline int file_exists(const char *p)
{
    struct stat sb;
    return stat(p, &sb) == 0;
}

static inline int count_files(void)
{
    int n = 0;
    DIR *d = opendir(dir);
    ck_assert_ptr_nonnull(d);
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    closedir(d);
    return n;
}

static inline long file_size(const char *p)
{
    struct stat sb;
    ck_assert_int_eq(stat(p, &sb), 0);
    return (long)sb.st_size;
}

static inline void copy_file(const char *src, const char *dst)
{
    FILE *a = fopen(src, "rb"), *b = fopen(dst, "wb");
    ck_assert(a && b);
    char buf[1 << 16];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, a)) > 0) ck_assert_uint_eq(fwrite(buf, 1, n, b), n);
    fclose(a);
    fclose(b);
}

static inline void assert_contains(const char *msg, const char *part)
{
    ck_assert_msg(strstr(msg, part) != NULL, "message \"%s\" does not contain \"%s\"", msg, part);
}

/* A committed file with a 20 x 30 float32 matrix "R" (values r * 100 + c, exact in float). */
static inline void write_small(wt_context *ctx, const char *path)
{
    wt_h5_writer *w = NULL;
    float a[20 * 30];
    int64_t dims[2] = {20, 30};
    for (int i = 0; i < 20 * 30; i++) a[i] = (float)((i / 30) * 100 + i % 30);
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write(w, "R", WT_H5_F32, WT_H5_F32, 2, dims, a, "rad/m", "test matrix"), WT_OK);
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
}

/* ---- round trips --------------------------------------------------------------------------------- */

#endif
