/* tests/test_plot.c: the report figures (cli/plot): complete PNGs of the requested size, nothing left
 * behind on refusal, repeatable output when several figures are drawn in one process. */
#include <dirent.h>
#include <plplot.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli/plot.h"
#include "testutil.h"

/* A 900 x 650 PNG of a few lines and fills compresses to tens of kB; a blank page is ~5 kB and a
 * truncated or empty file far less. 2 kB separates "something was drawn" from "nothing was written". */
#define MIN_PNG_BYTES 2048

static const char *const methods[3] = {"MVM", "PCG-3", "CG-9"};
static const char *const parts[6] = {"slopes", "POLC", "tomography", "fitting", "DM", "Strehl"};

/* Under AddressSanitizer: pango keeps a process-wide font cache built by fontconfig, reported as leaked
 * at exit. It is allocated once (the same ~98 kB after 1, 4 or 16 rounds of all three figures), so
 * it is suppressed by module; a leak that grows with the number of plots, in PLplot or here, is not. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libfontconfig.so\n"; }
const char *__lsan_default_options(void);
const char *__lsan_default_options(void) { return "print_suppressions=0"; }

/* ---- file helpers ---- */

static char *make_dir(void)
{
    static char tmpl[64];
    snprintf(tmpl, sizeof tmpl, "/tmp/wt_test_plot_XXXXXX");
    char *d = mkdtemp(tmpl);
    ck_assert_ptr_nonnull(d);
    return d;
}

static void remove_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char p[512];
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (remove(p) != 0) rmdir(p);
    }
    closedir(d);
    rmdir(dir);
}

/* Number of entries of dir whose name contains needle ("" counts all). */
static int count_entries(const char *dir, const char *needle)
{
    DIR *d = opendir(dir);
    ck_assert_ptr_nonnull(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") && strstr(e->d_name, needle)) n++;
    closedir(d);
    return n;
}

/* The whole file in a malloc'ed buffer (NULL if unreadable). */
static unsigned char *slurp(const char *path, long *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)*n + 1);
    ck_assert_ptr_nonnull(b);
    ck_assert_int_eq((long)fread(b, 1, (size_t)*n, f), *n);
    fclose(f);
    return b;
}

/* A complete PNG (signature, IHDR first, IEND last) of w x h pixels and more than MIN_PNG_BYTES. */
static void assert_png(const char *path, unsigned w, unsigned h)
{
    static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    long n = 0;
    unsigned char *b = slurp(path, &n);
    ck_assert_msg(b != NULL, "%s was not written", path);
    ck_assert_msg(n > MIN_PNG_BYTES, "%s has only %ld bytes", path, n);
    ck_assert_msg(memcmp(b, sig, 8) == 0, "%s lacks the PNG signature", path);
    ck_assert_msg(memcmp(b + 12, "IHDR", 4) == 0, "%s: first chunk is not IHDR", path);
    unsigned pw = (unsigned)b[16] << 24 | (unsigned)b[17] << 16 | (unsigned)b[18] << 8 | b[19];
    unsigned ph = (unsigned)b[20] << 24 | (unsigned)b[21] << 16 | (unsigned)b[22] << 8 | b[23];
    ck_assert_uint_eq(pw, w);
    ck_assert_uint_eq(ph, h);
    ck_assert_msg(memcmp(b + n - 8, "IEND", 4) == 0, "%s does not end with IEND (truncated)", path);
    free(b);
}

static int same_bytes(const char *a, const char *b)
{
    long na = 0, nb = 0;
    unsigned char *x = slurp(a, &na), *y = slurp(b, &nb);
    ck_assert_ptr_nonnull(x);
    ck_assert_ptr_nonnull(y);
    int same = na == nb && memcmp(x, y, (size_t)na) == 0;
    free(x), free(y);
    return same;
}

/* ---- realistic inputs: 3 methods x 5 sweep values, a 5x5 map, 3 methods x 6 parts ---- */

static const double alpha[5] = {0.1, 0.3, 1.0, 3.0, 10.0};

static void sweep_data(double *on, double *fa, double shift)
{
    for (int m = 0; m < 3; m++)
        for (int k = 0; k < 5; k++) {
            on[m * 5 + k] = 0.55 + 0.05 * m - 0.02 * (k - 2) * (k - 2) + shift;
            fa[m * 5 + k] = on[m * 5 + k] - 0.12 - 0.03 * m;
        }
}

static const double coords[5] = {-30.0, -15.0, 0.0, 15.0, 30.0};

static void map_data(double *s, double peak)
{
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++) s[i + 5 * j] = peak - 2e-4 * (coords[i] * coords[i] + coords[j] * coords[j]);
}

static const double times[18] = {0.2, 0.1, 1.5, 0.0, 0.05, 0.3, 0.2, 0.1, 3.2, 0.4, 0.05, 0.3,
                                 0.2, 0.1, 6.5, 1.2, 0.05, 0.3};

static int draw_sweep(wt_context *ctx, const char *path, double shift)
{
    double on[15], fa[15];
    sweep_data(on, fa, shift);
    return wt_plot_strehl_sweep(ctx, path, "LE Strehl vs alpha (K band)", "recon.alpha", 3, methods, 5, alpha, on, fa,
                                NULL, NULL, 1);
}

static int draw_map(wt_context *ctx, const char *path, double peak)
{
    double s[25];
    map_data(s, peak);
    return wt_plot_strehl_map(ctx, path, "PCG-3 LE Strehl over the field", 5, coords, s, 0.2, 0.7, NULL);
}

static int draw_bars(wt_context *ctx, const char *path)
{
    return wt_plot_time_bars(ctx, path, "Time per frame", 3, methods, 6, parts, times);
}

/* ---- tests ---- */

START_TEST(test_sweep_writes_png)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    snprintf(path, sizeof path, "%s/sweep.png", dir);
    ck_assert_int_eq(draw_sweep(ctx, path, 0.0), WT_OK);
    assert_png(path, 900, 650);
    ck_assert_int_eq(count_entries(dir, ""), 1); /* the temporary was renamed, not copied */

    /* linear x axis too, and a NaN (a run that was not made) drawn as a gap */
    double on[15], fa[15];
    sweep_data(on, fa, 0.0);
    on[2] = NAN, fa[7] = NAN;
    snprintf(path, sizeof path, "%s/sweep_lin.png", dir);
    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "t", "iterations", 3, methods, 5, alpha, on, fa, NULL, NULL, 0), WT_OK);
    assert_png(path, 900, 650);
    /* a sweep of words: each value named under its point (and a NULL name drawn as "?", not a crash) */
    const double at[5] = {1, 2, 3, 4, 5};
    const char *names[5] = {"static", "oracle", "pixels", NULL, "#x"};
    snprintf(path, sizeof path, "%s/sweep_named.png", dir);
    ck_assert_int_eq(wt_plot_strehl_sweep_named(ctx, path, "t", "lgs.wfs.reference", 3, methods, 5, at, names, on, fa, NULL,
                                                NULL, 0), WT_OK);
    assert_png(path, 900, 650);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_map_writes_png)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    snprintf(path, sizeof path, "%s/map.png", dir);
    ck_assert_int_eq(draw_map(ctx, path, 0.6), WT_OK);
    assert_png(path, 900, 650);
    ck_assert_int_eq(count_entries(dir, ""), 1);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_bars_write_png)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    snprintf(path, sizeof path, "%s/time.png", dir);
    ck_assert_int_eq(draw_bars(ctx, path), WT_OK);
    assert_png(path, 900, 650);
    ck_assert_int_eq(count_entries(dir, ""), 1);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Guide stars on the maps (an LGS ring inside the cells, an NGS ring outside them, which widens the window) and
 * the difference map: each is drawn (the stars change the picture, a difference and its opposite give different
 * pictures, an all-zero difference draws); bad stars and a format without exactly one number are refused. */
static const double lgs_x[4] = {22.5, 0.0, -22.5, 0.0}, lgs_y[4] = {0.0, 22.5, 0.0, -22.5};
static const double ngs_x[3] = {40.0, -20.0, -20.0}, ngs_y[3] = {0.0, 34.64, -34.64};
START_TEST(test_stars_and_difference_map)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), a[256], b[256];
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(b, sizeof b, "%s/b.png", dir);
    const wt_plot_stars stars = {4, 3, lgs_x, lgs_y, ngs_x, ngs_y};
    double s[25], d[25], nd[25], z[25] = {0};
    map_data(s, 0.6);
    for (int i = 0; i < 25; i++) d[i] = 10.0 * (s[i] - 0.5), nd[i] = -d[i];
    ck_assert_int_eq(wt_plot_strehl_map(ctx, a, "with stars", 5, coords, s, 0.2, 0.7, &stars), WT_OK);
    assert_png(a, 900, 650);
    ck_assert_int_eq(wt_plot_strehl_map(ctx, b, "with stars", 5, coords, s, 0.2, 0.7, NULL), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "the guide stars do not change the map");
    ck_assert_int_eq(wt_plot_diff_map(ctx, a, "difference", 5, coords, d, "WFE difference [nm]", "%+.1f", &stars), WT_OK);
    assert_png(a, 900, 650);
    ck_assert_int_eq(wt_plot_diff_map(ctx, b, "difference", 5, coords, nd, "WFE difference [nm]", "%+.1f", &stars), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "a difference and its opposite draw the same picture");
    ck_assert_int_eq(wt_plot_diff_map(ctx, b, "none", 5, coords, z, "WFE difference [nm]", "%+.1f", NULL), WT_OK);
    ck_assert_int_eq(wt_plot_diff_map(ctx, b, "t", 5, coords, d, "x", "no number", NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_diff_map(ctx, b, "t", 5, coords, d, "x", "%f %f", NULL), WT_ERR_INVALID);
    const double bad[1] = {NAN};
    const wt_plot_stars nan_star = {1, 0, bad, lgs_y, NULL, NULL};
    ck_assert_int_eq(wt_plot_strehl_map(ctx, b, "t", 5, coords, s, 0.2, 0.7, &nan_star), WT_ERR_INVALID);
    ck_assert(strstr(wt_error_message(ctx), "guide star 0"));
    ck_assert_int_eq(count_entries(dir, "tmp"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* The run figure against a reference value (the oracle of a learned atmosphere): drawn in night minutes; the
 * reference, not drawn itself, is subtracted (changing only its data changes the picture); the plain figure
 * differs from it; a reference outside the values, or with one value, is refused with nothing written. */
START_TEST(test_run_minus_reference)
{
    enum { NM = 2, NV = 3, NF = 150 };
    wt_context *ctx = tu_context();
    char *dir = make_dir(), a[256], b[256];
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(b, sizeof b, "%s/b.png", dir);
    static const char *const vals[NV] = {"\"learned\"", "\"oracle\"", "\"given\""};
    static double w[NM * NV * NF];
    for (int c = 0; c < NM * NV; c++)
        for (int t = 0; t < NF; t++) w[c * NF + t] = 300.0 + 10.0 * (c % NV) + 20.0 * sin(0.1 * t + c);
    const wt_plot_run_axis night = {0.0, 2.4 / 60.0, "night time [min]"};
    ck_assert_int_eq(wt_plot_wfe_run(ctx, a, "against the oracle", NM, methods, NV, vals, NF, w, 10, 10, &night, 1), WT_OK);
    assert_png(a, 900, 650);
    ck_assert_int_eq(wt_plot_wfe_run(ctx, b, "over the run", NM, methods, NV, vals, NF, w, 10, 10, &night, -1), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "the figure against the reference is the plain one");
    for (int t = 0; t < NF; t++) w[1 * NF + t] += 5.0 * cos(0.05 * t); /* method 0's reference only */
    ck_assert_int_eq(wt_plot_wfe_run(ctx, b, "against the oracle", NM, methods, NV, vals, NF, w, 10, 10, &night, 1), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "the reference's data do not reach the picture");
    char c[256];
    snprintf(c, sizeof c, "%s/c.png", dir);
    ck_assert_int_eq(wt_plot_wfe_run(ctx, c, "t", NM, methods, NV, vals, NF, w, 10, 10, &night, NV), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_wfe_run(ctx, c, "t", NM, methods, 1, vals, NF, w, 10, 10, &night, 0), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_wfe_run(ctx, c, "t", NM, methods, NV, vals, NF, w, 10, 10, NULL, -1), WT_ERR_INVALID);
    ck_assert(access(c, F_OK) != 0);
    ck_assert_int_eq(count_entries(dir, "tmp"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Estimates against the truth (the compare report's learned atmosphere): two panels of 720 px, the data reach the
 * picture, and what cannot be drawn is refused with nothing left behind. */
START_TEST(test_series_against_truth)
{
    enum { NS = 2, NU = 6, NT = 50 };
    wt_context *ctx = tu_context();
    char *dir = make_dir(), a[256], b[256], c[256];
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(b, sizeof b, "%s/b.png", dir);
    snprintf(c, sizeof c, "%s/c.png", dir);
    static const char *const names[NS] = {"pcg3", "mvm"};
    double x[NS][NU], r[NS][NU], e[NS][NU], th[NS][NU], tx[NT], tr[NT], tt[NT];
    for (int s = 0; s < NS; s++)
        for (int i = 0; i < NU; i++)
            x[s][i] = 4.0 * (i + 1), r[s][i] = 0.12 - 0.003 * i + 0.002 * s, e[s][i] = 0.01, th[s][i] = 1.8 + 0.05 * i;
    for (int i = 0; i < NT; i++) tx[i] = 30.0 * i / (NT - 1), tr[i] = 0.129 - 0.001 * tx[i], tt[i] = 2.15;
    const int n[NS] = {NU, NU};
    const double *px[NS] = {x[0], x[1]}, *pr[NS] = {r[0], r[1]}, *pe[NS] = {e[0], e[1]}, *pt[NS] = {th[0], th[1]};
    wt_plot_series_panel p[2] = {{.ylabel = "r0 [m]", .n = n, .x = px, .y = pr, .e = pe, .nt = NT, .tx = tx, .ty = tr},
                                 {.ylabel = "θ0 [arcsec]", .n = n, .x = px, .y = pt, .nt = NT, .tx = tx, .ty = tt}};
    ck_assert_msg(wt_plot_series(ctx, a, "learned", "night time [min]", NS, names, NULL, 2, p) == WT_OK, "%s",
                  wt_error_message(ctx));
    assert_png(a, 900, 720);
    th[1][3] = 2.4; /* one estimate of the second series, bottom panel */
    ck_assert_int_eq(wt_plot_series(ctx, b, "learned", "night time [min]", NS, names, NULL, 2, p), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "one estimate changed and the picture did not");
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", 0, names, NULL, 2, p), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", NS, names, NULL, 5, p), WT_ERR_INVALID);
    const int none[NS] = {0, 0};
    wt_plot_series_panel q[1] = {{.ylabel = "r0", .n = none, .x = px, .y = pr, .nt = NT, .tx = tx, .ty = tr}};
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", NS, names, NULL, 1, q), WT_ERR_INVALID); /* no estimate at all */
    q[0].n = n, q[0].tx = NULL;
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", NS, names, NULL, 1, q), WT_ERR_INVALID); /* a truth without its x */
    q[0].tx = tx;
    const int nr[NS] = {NT, NT};
    const double *rx[NS] = {tx, tx}, *ry[NS] = {tt, NULL};
    q[0].nr = nr, q[0].rx = rx, q[0].ry = ry;
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", NS, names, "oracle", 1, q), WT_ERR_INVALID); /* a reference without y */
    ry[1] = tr; /* each series' own reference, dashed: drawn, and it reaches the picture */
    ck_assert_int_eq(wt_plot_series(ctx, c, "t", "x", NS, names, "oracle", 1, q), WT_OK);
    ck_assert_int_eq(wt_plot_series(ctx, b, "t", "x", NS, names, "oracle", 1, q), WT_OK);
    ry[1] = tt;
    ck_assert_int_eq(wt_plot_series(ctx, b, "t", "x", NS, names, "oracle", 1, q), WT_OK);
    ck_assert_msg(!same_bytes(b, c), "a reference line changed and the picture did not");
    remove(c);
    ck_assert(access(c, F_OK) != 0);
    ck_assert_int_eq(count_entries(dir, "tmp"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* The data reach the picture: different values give different bytes (a plot that ignored its inputs,
 * or drew them outside the window, would not change). */
START_TEST(test_data_change_the_image)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), a[256], b[256];
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(b, sizeof b, "%s/b.png", dir);
    ck_assert_int_eq(draw_map(ctx, a, 0.6), WT_OK);
    ck_assert_int_eq(draw_map(ctx, b, 0.5), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "maps of different Strehl values are identical");
    ck_assert_int_eq(draw_sweep(ctx, a, 0.0), WT_OK);
    ck_assert_int_eq(draw_sweep(ctx, b, -0.1), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "sweeps of different Strehl values are identical");
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* A missing output directory is refused before PLplot sees the path (PLplot would prompt on stdin for
 * another name), with a message naming the directory, and no file appears. */
START_TEST(test_missing_directory_refused)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), missing[256], path[300];
    snprintf(missing, sizeof missing, "%s/no/such/dir", dir);
    snprintf(path, sizeof path, "%s/fig.png", missing);
    double on[15], fa[15], s[25];
    sweep_data(on, fa, 0.0);
    map_data(s, 0.6);
    int st[3] = {
        wt_plot_strehl_sweep(ctx, path, "t", "x", 3, methods, 5, alpha, on, fa, NULL, NULL, 0),
        wt_plot_strehl_map(ctx, path, "t", 5, coords, s, 0.2, 0.7, NULL),
        wt_plot_time_bars(ctx, path, "t", 3, methods, 6, parts, times),
    };
    for (int i = 0; i < 3; i++) ck_assert_int_eq(st[i], WT_ERR_IO);
    ck_assert_msg(strstr(wt_error_message(ctx), missing) != NULL, "message '%s' does not name '%s'",
                  wt_error_message(ctx), missing);
    struct stat sb;
    ck_assert_int_ne(stat(path, &sb), 0);
    ck_assert_int_eq(count_entries(dir, ""), 0);

    /* a path whose parent is a regular file is refused the same way */
    snprintf(missing, sizeof missing, "%s/file", dir);
    FILE *f = fopen(missing, "w");
    ck_assert_ptr_nonnull(f);
    fclose(f);
    snprintf(path, sizeof path, "%s/fig.png", missing);
    ck_assert_int_eq(draw_bars(ctx, path), WT_ERR_IO);
    ck_assert_int_eq(count_entries(dir, ""), 1);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Each figure opens and closes its own stream: all three twice in one process give complete files,
 * byte-identical the second time (no state carried over: colour maps, line style, character size),
 * and the caller's current stream is the same before and after. */
START_TEST(test_twice_in_one_process)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), p[6][256];
    const char *names[6] = {"s1.png", "m1.png", "t1.png", "s2.png", "m2.png", "t2.png"};
    for (int i = 0; i < 6; i++) snprintf(p[i], sizeof p[i], "%s/%s", dir, names[i]);

    PLINT caller = -1, after = -1;
    plmkstrm(&caller); /* a stream of the caller's, never initialised: must stay current */
    ck_assert_int_ge(caller, 1);
    for (int r = 0; r < 2; r++) {
        ck_assert_int_eq(draw_sweep(ctx, p[3 * r], 0.0), WT_OK);
        ck_assert_int_eq(draw_map(ctx, p[3 * r + 1], 0.6), WT_OK);
        ck_assert_int_eq(draw_bars(ctx, p[3 * r + 2]), WT_OK);
    }
    plgstrm(&after);
    ck_assert_int_eq(after, caller);
    plend1();
    for (int i = 0; i < 6; i++) assert_png(p[i], 900, 650);
    for (int i = 0; i < 3; i++) ck_assert_msg(same_bytes(p[i], p[i + 3]), "%s differs from %s", names[i], names[i + 3]);
    ck_assert_int_eq(count_entries(dir, ".tmp-"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* An existing file is replaced whole (rename), and a path that is a directory is refused. */
START_TEST(test_replace_and_directory_path)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    snprintf(path, sizeof path, "%s/fig.png", dir);
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fputs("old contents", f);
    fclose(f);
    ck_assert_int_eq(draw_bars(ctx, path), WT_OK);
    assert_png(path, 900, 650);
    ck_assert_int_eq(count_entries(dir, ""), 1);

    snprintf(path, sizeof path, "%s/sub.png", dir);
    ck_assert_int_eq(mkdir(path, 0755), 0);
    ck_assert_int_eq(draw_map(ctx, path, 0.6), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), path));
    struct stat sb;
    ck_assert_int_eq(stat(path, &sb), 0);
    ck_assert(S_ISDIR(sb.st_mode));
    ck_assert_int_eq(count_entries(dir, ".tmp-"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Inputs PLplot would draw wrongly or choke on are refused as WT_ERR_INVALID, before any file exists. */
START_TEST(test_invalid_inputs_refused)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256], bad[256];
    snprintf(path, sizeof path, "%s/fig.png", dir);
    double on[15], fa[15], s[25], x[5], c[5], t[18];
    sweep_data(on, fa, 0.0);
    map_data(s, 0.6);
    memcpy(x, alpha, sizeof x);
    memcpy(c, coords, sizeof c);
    memcpy(t, times, sizeof t);

    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "t", "x", 0, methods, 5, x, on, fa, NULL, NULL, 0), WT_ERR_INVALID);
    x[0] = 0.0; /* no log of 0 */
    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "t", "x", 3, methods, 5, x, on, fa, NULL, NULL, 1), WT_ERR_INVALID);
    x[0] = alpha[0];
    on[4] = INFINITY;
    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "t", "x", 3, methods, 5, x, on, fa, NULL, NULL, 1), WT_ERR_INVALID);
    on[4] = 0.5;
    const char *const nullname[3] = {"MVM", NULL, "CG-9"};
    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "t", "x", 3, nullname, 5, x, on, fa, NULL, NULL, 1), WT_ERR_INVALID);

    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "t", 5, c, s, 0.7, 0.6, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "t", 5, c, s, 0.2, NAN, NULL), WT_ERR_INVALID);
    c[3] = c[2]; /* cells need increasing coordinates */
    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "t", 5, c, s, 0.2, 0.7, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "t", 0, coords, s, 0.2, 0.7, NULL), WT_ERR_INVALID);

    t[7] = -1.0;
    ck_assert_int_eq(wt_plot_time_bars(ctx, path, "t", 3, methods, 6, parts, t), WT_ERR_INVALID);
    t[7] = NAN;
    ck_assert_int_eq(wt_plot_time_bars(ctx, path, "t", 3, methods, 6, parts, t), WT_ERR_INVALID);

    /* PLplot would read "%n" as a family member number and write elsewhere */
    snprintf(bad, sizeof bad, "%s/fig%%n.png", dir);
    ck_assert_int_eq(draw_bars(ctx, bad), WT_ERR_INVALID);

    ck_assert_int_eq(count_entries(dir, ""), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Label text with '#' (PLplot's escape character), a single-cell map, a degenerate colour range and a
 * single-point sweep still draw. */
START_TEST(test_edge_inputs_draw)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    snprintf(path, sizeof path, "%s/one.png", dir);
    double s1 = 0.4, c1 = 0.0;
    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "on-axis #1", 1, &c1, &s1, 0.0, 1.0, NULL), WT_OK);
    assert_png(path, 900, 650);
    /* a degenerate colour range (all maps equal: min = max) is drawn, not refused */
    ck_assert_int_eq(wt_plot_strehl_map(ctx, path, "uniform", 1, &c1, &s1, 0.4, 0.4, NULL), WT_OK);
    assert_png(path, 900, 650);
    snprintf(path, sizeof path, "%s/single.png", dir);
    const char *const m1[1] = {"run #2"};
    double xv = 5.0, on = 0.3, fa = 0.2;
    ck_assert_int_eq(wt_plot_strehl_sweep(ctx, path, "#", "#x", 1, m1, 1, &xv, &on, &fa, NULL, NULL, 1), WT_OK);
    assert_png(path, 900, 650);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* ---- the pupil pictures of a sensor (cli/plot_pupil.c) ---- */

/* n x n subapertures of side d over a disc of diameter n d, each an ns x ns Gaussian spot elongated along the
 * direction from the launch (lx, 0); trunc grows with the distance. */
typedef struct {
    int nsub, ns;
    double xc[4096], yc[4096], trunc[4096];
    float *img;
    wt_plot_pupil p;
} pupil_data;

static void make_pupil(pupil_data *q, int n, int ns)
{
    const double d = 0.5, D = n * d, lx = 0.5 * D + 0.5;
    q->nsub = 0, q->ns = ns;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            const double x = (i + 0.5 - 0.5 * n) * d, y = (j + 0.5 - 0.5 * n) * d;
            if (hypot(x, y) > 0.5 * D || hypot(x, y) < 0.15 * D) continue;
            q->xc[q->nsub] = x, q->yc[q->nsub] = y;
            q->trunc[q->nsub] = 0.002 * hypot(x - lx, y) / d; /* up to ~0.1 x n: every frame level is used */
            q->nsub++;
        }
    q->img = malloc((size_t)q->nsub * ns * ns * sizeof *q->img);
    ck_assert_ptr_nonnull(q->img);
    for (int k = 0; k < q->nsub; k++) {
        const double ux = q->xc[k] - lx, uy = q->yc[k], r = hypot(ux, uy), len = 0.4 + 0.08 * r / d;
        for (int iy = 0; iy < ns; iy++)
            for (int ix = 0; ix < ns; ix++) {
                const double x = ix - 0.5 * (ns - 1), y = iy - 0.5 * (ns - 1);
                const double a = (x * ux + y * uy) / r, b = (-x * uy + y * ux) / r;
                q->img[(size_t)k * ns * ns + ix + ns * iy] = (float)(100.0 * exp(-0.5 * (a * a / (len * len) + b * b / 0.36)));
            }
    }
    q->p = (wt_plot_pupil){.nsub = q->nsub, .xc = q->xc, .yc = q->yc, .side = d, .diameter = D, .obstruction = 0.3,
                           .has_launch = 1, .launch_x = lx, .launch_y = 0.0};
}

START_TEST(test_spots_and_maps_write_png)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    static pupil_data q;
    /* a small sensor (magnified cells) and a big one (one screen px per detector px, with the insets) */
    const int sizes[2][2] = {{12, 8}, {60, 16}};
    for (int c = 0; c < 2; c++) {
        make_pupil(&q, sizes[c][0], sizes[c][1]);
        int w = 0, h = 0;
        wt_plot_spots_page(&q.p, q.ns, &w, &h);
        ck_assert_int_ge(w, 900);
        ck_assert_int_ge(h, 700);
        snprintf(path, sizeof path, "%s/spots%d.png", dir, c);
        const double t0 = wt_time_now();
        ck_assert_msg(wt_plot_spots(ctx, path, "LGS1 #spots", "note", &q.p, q.ns, q.img, 1, q.trunc) == WT_OK, "%s",
                      wt_error_message(ctx));
        /* the 60 x 60 x 16² case (~2800 cells, 960² pixels) well inside the E-ELT's "a few seconds" */
        ck_assert_msg(wt_time_now() - t0 < 20.0, "the mosaic took %.1f s", wt_time_now() - t0);
        assert_png(path, (unsigned)w, (unsigned)h);
        double *g = malloc((size_t)q.nsub * sizeof *g);
        for (int k = 0; k < q.nsub; k++) g[k] = 1.0 - q.trunc[k];
        g[0] = NAN; /* a missing value is drawn grey */
        const double *maps[2] = {g, q.trunc}, range[4] = {NAN, NAN, 0.0, NAN};
        const char *subs[2] = {"gain\nline 2", "truncation"}, *bars[2] = {"gain [rad/rad]", "truncation [-]"};
        snprintf(path, sizeof path, "%s/gain%d.png", dir, c);
        ck_assert_msg(wt_plot_pupil_maps(ctx, path, "maps", &q.p, 2, maps, range, subs, bars) == WT_OK, "%s",
                      wt_error_message(ctx));
        assert_png(path, 1500, 720);
        snprintf(path, sizeof path, "%s/one%d.png", dir, c);
        ck_assert_int_eq(wt_plot_pupil_maps(ctx, path, "one map", &q.p, 1, maps, NULL, subs, bars), WT_OK);
        assert_png(path, 900, 650);
        free(g);
        free(q.img);
    }
    ck_assert_int_eq(count_entries(dir, ".tmp-"), 0);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* Bad inputs to the pupil pictures are refused before any file exists. */
START_TEST(test_spots_invalid_refused)
{
    wt_context *ctx = tu_context();
    char *dir = make_dir(), path[256];
    static pupil_data q;
    make_pupil(&q, 8, 6);
    snprintf(path, sizeof path, "%s/s.png", dir);
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &q.p, 0, q.img, 1, q.trunc), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &q.p, q.ns, NULL, 1, q.trunc), WT_ERR_INVALID);
    q.img[7] = NAN;
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &q.p, q.ns, q.img, 1, q.trunc), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "pixel 7"));
    q.img[7] = 0.0f;
    q.trunc[3] = INFINITY;
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &q.p, q.ns, q.img, 1, q.trunc), WT_ERR_INVALID);
    q.trunc[3] = 0.0;
    wt_plot_pupil bad = q.p;
    bad.side = 0.0;
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &bad, q.ns, q.img, 1, q.trunc), WT_ERR_INVALID);
    bad = q.p, bad.nsub = 0;
    ck_assert_int_eq(wt_plot_spots(ctx, path, "t", "n", &bad, q.ns, q.img, 1, q.trunc), WT_ERR_INVALID);
    const double *maps[1] = {q.trunc}, range[2] = {1.0, 0.0};
    ck_assert_int_eq(wt_plot_pupil_maps(ctx, path, "t", &q.p, 3, maps, NULL, NULL, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_pupil_maps(ctx, path, "t", &q.p, 1, maps, range, NULL, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(count_entries(dir, ""), 0);
    free(q.img);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

/* The PSF mosaic and the per-frame residual curves (cli/plot_psf.c, issue 21 §5): complete PNGs of their
 * sizes, the data reaching the picture (another Strehl / another curve gives other bytes), nothing written on a
 * refusal (an odd or oversized image, a negative or NaN PSF value, a settle window past the frames, a residual
 * of 0 nm on the log axis). */
static void psf_data(float *img, int g, int n, double width)
{
    for (int p = 0; p < g * g; p++)
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) {
                const double x = ix - n / 2, y = iy - n / 2, r2 = (x * x + y * y) / (width * width);
                img[(size_t)p * n * n + ix + (size_t)n * iy] = (float)(0.5 * exp(-r2) + 1e-4 / (1.0 + r2));
            }
}

START_TEST(test_psf_and_wfe_figures)
{
    enum { G = 3, NPX = 32, F = 60 };
    wt_context *ctx = tu_context();
    char *dir = make_dir(), a[256], b[256];
    snprintf(a, sizeof a, "%s/psf_a.png", dir);
    snprintf(b, sizeof b, "%s/psf_b.png", dir);
    static float img[G * G * NPX * NPX];
    double st[G * G], c3[G] = {-30.0, 0.0, 30.0}, w[2 * F];
    for (int i = 0; i < G * G; i++) st[i] = 0.5;
    psf_data(img, G, NPX, 1.5);
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "PSFs", G, c3, NPX, 0.5, img, st), WT_OK);
    assert_png(a, 960, 920);
    st[4] = 0.25; /* another Strehl printed in a panel, and another core */
    psf_data(img, G, NPX, 2.5);
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, b, "PSFs", G, c3, NPX, 0.5, img, st), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "mosaics of different PSFs are identical");
    for (int m = 0; m < 2; m++)
        for (int t = 0; t < F; t++) w[m * F + t] = 400.0 + 1200.0 * exp(-t / 3.0) + 10.0 * m + 5.0 * sin(t);
    snprintf(a, sizeof a, "%s/wfe_a.png", dir);
    snprintf(b, sizeof b, "%s/wfe_b.png", dir);
    const char *const two[2] = {"pcg3", "cg9"};
    ck_assert_int_eq(wt_plot_wfe_frames(ctx, a, "WFE", 2, two, F, w, 20), WT_OK);
    assert_png(a, 900, 650);
    w[F + 30] = NAN; /* a frame missing breaks the line: still drawn */
    ck_assert_int_eq(wt_plot_wfe_frames(ctx, b, "WFE", 2, two, F, w, 20), WT_OK);
    ck_assert_msg(!same_bytes(a, b), "curves of different residuals are identical");
    ck_assert_int_eq(count_entries(dir, ""), 4);

    snprintf(a, sizeof a, "%s/refused.png", dir);
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "t", G, c3, NPX + 1, 0.5, img, st), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "t", 16, c3, NPX, 0.5, img, st), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "t", G, c3, NPX, 0.0, img, st), WT_ERR_INVALID);
    img[5] = -1.0f;
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "t", G, c3, NPX, 0.5, img, st), WT_ERR_INVALID);
    img[5] = NAN;
    ck_assert_int_eq(wt_plot_psf_mosaic(ctx, a, "t", G, c3, NPX, 0.5, img, st), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_wfe_frames(ctx, a, "t", 2, two, F, w, F), WT_ERR_INVALID);
    w[3] = 0.0;
    ck_assert_int_eq(wt_plot_wfe_frames(ctx, a, "t", 2, two, F, w, 20), WT_ERR_INVALID);
    ck_assert_int_eq(wt_plot_wfe_frames(ctx, a, "t", 0, two, F, w, 20), WT_ERR_INVALID);
    ck_assert_int_eq(count_entries(dir, ""), 4);
    remove_dir(dir);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("plot");
    TCase *tc = tcase_create("plot");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_sweep_writes_png);
    tcase_add_test(tc, test_map_writes_png);
    tcase_add_test(tc, test_stars_and_difference_map);
    tcase_add_test(tc, test_run_minus_reference);
    tcase_add_test(tc, test_series_against_truth);
    tcase_add_test(tc, test_bars_write_png);
    tcase_add_test(tc, test_data_change_the_image);
    tcase_add_test(tc, test_missing_directory_refused);
    tcase_add_test(tc, test_twice_in_one_process);
    tcase_add_test(tc, test_replace_and_directory_path);
    tcase_add_test(tc, test_invalid_inputs_refused);
    tcase_add_test(tc, test_edge_inputs_draw);
    tcase_add_test(tc, test_spots_and_maps_write_png);
    tcase_add_test(tc, test_spots_invalid_refused);
    tcase_add_test(tc, test_psf_and_wfe_figures);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
