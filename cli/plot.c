/* cli/plot.c: the PNG figures of a comparison report (Strehl sweeps, field maps, timing bars), PLplot.
 *
 * Figures of SPEC §1 (`compare/`: side-by-side Strehl reports of the reconstructors). The numbers come
 * from the closed loop (LE Strehl in K band, SPEC §8); nothing is computed here but axis ranges.
 *
 * PLplot keeps its streams in a global table, prints to stderr, and in some failures calls exit() or
 * prompts on stdin (an unknown device, an output file it cannot open). So each figure:
 *  - checks everything PLplot would trip on first: the inputs, the output directory, that the
 *    pngcairo driver is loaded, and creates the temporary file itself so PLplot's fopen cannot fail;
 *  - draws on a stream of its own (plmkstrm ... plend1), leaving the caller's current stream as found;
 *  - routes PLplot's recoverable errors (plabort) into a buffer with plsError, so they surface as
 *    WT_ERR_LIBRARY instead of stderr text;
 *  - draws to "PATH.tmp-<pid>", checks the PNG is complete (cairo ignores write errors), and renames it
 *    onto PATH, so PATH is either the old file or the whole new one.
 */
#include "cli/plot.h"
#include "cli/plot_private.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <plplot.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

const PLINT wt_plot_cmap0[C_PAL + N_PAL][3] = {
    {255, 255, 255}, {0, 0, 0}, {205, 205, 205}, {200, 200, 200}, {255, 255, 255},
    /* a colour-blind-safe qualitative palette (Okabe-Ito, then Tableau) for methods and parts */
    {0, 114, 178}, {230, 159, 0}, {0, 158, 115}, {204, 121, 167}, {213, 94, 0},
    {86, 180, 233}, {120, 120, 120}, {148, 103, 189}, {140, 86, 75}, {188, 189, 34},
};
const double wt_plot_viridis[N_VIRIDIS][4] = {
    {0.000, 68, 1, 84},     {0.125, 71, 44, 122},  {0.250, 59, 81, 139},   {0.375, 44, 113, 142},
    {0.500, 33, 144, 141},  {0.625, 39, 173, 129}, {0.750, 92, 200, 99},   {0.875, 170, 220, 50},
    {1.000, 253, 231, 37},
};

/* Markers per method: filled for on-axis, open for the field average (a Unicode glyph pair). */
enum { N_MARK = 4 };
static const char *const mark_filled[N_MARK] = {"●", "■", "▲", "◆"};
static const char *const mark_open[N_MARK] = {"○", "□", "△", "◇"};

/* '#' starts a PLplot escape sequence; a literal one is "##". Truncates to the buffer. */
const char *wt_plot_escape(char *dst, size_t n, const char *src)
{
    size_t k = 0;
    if (!src) src = "";
    for (; *src && k + 2 < n; src++) {
        if (*src == '#') dst[k++] = '#';
        dst[k++] = *src;
    }
    dst[k] = '\0';
    return dst;
}

/* plabort's message ends in a newline; the context's messages do not. */
static const char *trimmed(char *msg)
{
    size_t n = strlen(msg);
    while (n > 0 && (msg[n - 1] == '\n' || msg[n - 1] == ' ')) msg[--n] = '\0';
    while (*msg == '\n') msg++;
    return msg;
}

/* The directory part of path (for the "does not exist" message); "." when there is none. */
static void dir_of(const char *path, char *dir, size_t n)
{
    const char *slash = strrchr(path, '/');
    if (!slash) {
        snprintf(dir, n, ".");
    } else if (slash == path) {
        snprintf(dir, n, "/");
    } else {
        size_t len = (size_t)(slash - path);
        if (len >= n) len = n - 1;
        memcpy(dir, path, len);
        dir[len] = '\0';
    }
}

static int has_pngcairo(void)
{
    enum { NDEV = 128 };
    const char *menu[NDEV], *name[NDEV];
    const char **pm = menu, **pn = name;
    int ndev = NDEV;
    plgFileDevs(&pm, &pn, &ndev);
    for (int i = 0; i < ndev; i++)
        if (name[i] && strcmp(name[i], "pngcairo") == 0) return 1;
    return 0;
}

/* After an error inside a figure: close the stream and drop the temporary. */
void wt_plot_job_abort(wt_plot_job *j)
{
    if (j->stream_open) {
        plend1();
        plsstrm(j->prev_stream);
        j->stream_open = 0;
    }
    if (j->tmp[0]) remove(j->tmp);
}

/* Check the path, create the temporary, open a fresh PLplot stream on it and start a page of w x h px. */
int wt_plot_job_begin_size(wt_plot_job *j, wt_context *ctx, const char *path, int w, int h)
{
    memset(j, 0, sizeof *j);
    j->ctx = ctx;
    j->path = path;
    if (!path || !*path) return WT_ERROR(ctx, WT_ERR_INVALID, "plot: output path is empty");
    /* plsfnam would read "%n" as a family member number and write another file ("-", stdout, cannot
     * happen: the temporary has a suffix) */
    if (strstr(path, "%n"))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': the path may not contain \"%%n\" (PLplot family syntax)",
                        path);
    if (strlen(path) > 4096) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%.64s...': path longer than 4096 bytes", path);

    char dir[4096];
    struct stat sb;
    dir_of(path, dir, sizeof dir);
    if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return WT_ERROR(ctx, WT_ERR_IO, "plot '%s': output directory '%s' does not exist", path, dir);
    if (stat(path, &sb) == 0 && S_ISDIR(sb.st_mode))
        return WT_ERROR(ctx, WT_ERR_IO, "plot '%s': the path is a directory", path);

    snprintf(j->tmp, sizeof j->tmp, "%s.tmp-%ld", path, (long)getpid());
    int fd = open(j->tmp, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (fd < 0)
        return WT_ERROR(ctx, WT_ERR_IO, "plot '%s': cannot create the temporary '%s': %s", path, j->tmp,
                        strerror(errno));
    close(fd);

    if (!has_pngcairo()) {
        remove(j->tmp);
        return WT_ERROR(ctx, WT_ERR_LIBRARY,
                        "plot '%s': PLplot has no pngcairo driver (install the Debian package plplot-driver-cairo)",
                        path);
    }

    PLINT strm = -1;
    plgstrm(&j->prev_stream);
    plmkstrm(&strm);
    if (strm < 0) {
        plsstrm(j->prev_stream);
        remove(j->tmp);
        return WT_ERROR(ctx, WT_ERR_LIBRARY, "plot '%s': plmkstrm could not create a PLplot stream", path);
    }
    j->stream_open = 1;
    plsError(&j->errcode, j->errmsg);
    plsdev("pngcairo");
    plsfnam(j->tmp);
    plspage(0.0, 0.0, w, h, 0, 0);
    PLINT r[C_PAL + N_PAL], g[C_PAL + N_PAL], b[C_PAL + N_PAL];
    for (int i = 0; i < C_PAL + N_PAL; i++) r[i] = wt_plot_cmap0[i][0], g[i] = wt_plot_cmap0[i][1], b[i] = wt_plot_cmap0[i][2];
    plscmap0(r, g, b, C_PAL + N_PAL);
    PLFLT pos[N_VIRIDIS], cr[N_VIRIDIS], cg[N_VIRIDIS], cb[N_VIRIDIS];
    for (int i = 0; i < N_VIRIDIS; i++)
        pos[i] = wt_plot_viridis[i][0], cr[i] = wt_plot_viridis[i][1] / 255.0, cg[i] = wt_plot_viridis[i][2] / 255.0,
        cb[i] = wt_plot_viridis[i][3] / 255.0;
    plscmap1n(256);
    plscmap1l(1, N_VIRIDIS, pos, cr, cg, cb, NULL);
    plinit();
    if (j->errcode) {
        int st = WT_ERROR(ctx, WT_ERR_LIBRARY, "plot '%s': plinit failed: %s", path, trimmed(j->errmsg));
        wt_plot_job_abort(j);
        return st;
    }
    pladv(0);
    plschr(0.0, 1.15);
    plwidth(1.0);
    plcol0(C_FG);
    return WT_OK;
}

int wt_plot_job_begin(wt_plot_job *j, wt_context *ctx, const char *path)
{
    return wt_plot_job_begin_size(j, ctx, path, PAGE_W, PAGE_H);
}

/* PNG = signature, chunks, IEND last: a short write (cairo ignores fwrite errors) loses the IEND. */
static int png_complete(const char *file)
{
    static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
    unsigned char head[8], tail[12];
    int ok = 0;
    FILE *f = fopen(file, "rb");
    if (!f) return 0;
    if (fread(head, 1, 8, f) == 8 && memcmp(head, sig, 8) == 0 && fseek(f, -12, SEEK_END) == 0 &&
        fread(tail, 1, 12, f) == 12 && memcmp(tail, iend, 12) == 0)
        ok = 1;
    if (ok) ok = fsync(fileno(f)) == 0 || errno == EINVAL;
    fclose(f);
    return ok;
}

/* Close the stream (PLplot writes the PNG here), check it, rename onto the path. */
int wt_plot_job_end(wt_plot_job *j)
{
    plend1();
    plsstrm(j->prev_stream);
    j->stream_open = 0;
    if (j->errcode) {
        remove(j->tmp);
        return WT_ERROR(j->ctx, WT_ERR_LIBRARY, "plot '%s': PLplot reported: %s", j->path, trimmed(j->errmsg));
    }
    if (!png_complete(j->tmp)) {
        remove(j->tmp);
        return WT_ERROR(j->ctx, WT_ERR_IO, "plot '%s': the PNG written to '%s' is incomplete (disk full?)", j->path,
                        j->tmp);
    }
    if (rename(j->tmp, j->path) != 0) {
        int e = errno;
        remove(j->tmp);
        return WT_ERROR(j->ctx, WT_ERR_IO, "plot '%s': cannot rename the temporary '%s' onto it: %s", j->path, j->tmp,
                        strerror(e));
    }
    return WT_OK;
}

/* Axes with a light grid under them: the grid pass in grey, the frame and labels in black. */
void wt_plot_axes(const char *xopt, const char *yopt, const char *xgrid, const char *ygrid)
{
    plcol0(C_GRID);
    pllsty(1);
    plwidth(0.8);
    plbox(xgrid, 0.0, 0, ygrid, 0.0, 0);
    plcol0(C_FG);
    plwidth(1.2);
    plbox(xopt, 0.0, 0, yopt, 0.0, 0);
    plwidth(1.0);
}

void wt_plot_labels(const char *xlabel, const char *ylabel, const char *title)
{
    char xb[LABEL_MAX], yb[LABEL_MAX], tb[LABEL_MAX];
    plcol0(C_FG);
    plmtex("b", 3.0, 0.5, 0.5, wt_plot_escape(xb, sizeof xb, xlabel));
    plmtex("l", 3.8, 0.5, 0.5, wt_plot_escape(yb, sizeof yb, ylabel));
    plschr(0.0, 1.35);
    plmtex("t", 1.6, 0.5, 0.5, wt_plot_escape(tb, sizeof tb, title));
    plschr(0.0, 1.15);
}

/* Polyline through the finite points; a NaN (a missing run) breaks the line. */
static void line_with_gaps(int n, const double *x, const double *y)
{
    int k = 0;
    while (k < n) {
        while (k < n && !isfinite(y[k])) k++;
        int start = k;
        while (k < n && isfinite(y[k])) k++;
        if (k - start >= 2) plline(k - start, x + start, y + start);
    }
}

static void markers_finite(int n, const double *x, const double *y, const char *glyph)
{
    for (int k = 0; k < n; k++)
        if (isfinite(y[k])) plstring(1, &x[k], &y[k], glyph);
}

/* Bounds that keep every buffer on the stack: beyond them a figure is unreadable anyway. */
enum { MAX_SERIES = 16, MAX_VALUES = 4096, MAX_GRID = 64 };

/* Colour of cmap1 at t in [0,1] (same control points as the map) -> relative luminance in [0,1],
 * to choose black or white text on a cell. */
double wt_plot_viridis_luminance(double t)
{
    int k = 0;
    while (k < N_VIRIDIS - 2 && t > wt_plot_viridis[k + 1][0]) k++;
    double w = (t - wt_plot_viridis[k][0]) / (wt_plot_viridis[k + 1][0] - wt_plot_viridis[k][0]);
    w = fmin(fmax(w, 0.0), 1.0);
    double c[3];
    for (int i = 0; i < 3; i++) c[i] = ((1.0 - w) * wt_plot_viridis[k][i + 1] + w * wt_plot_viridis[k + 1][i + 1]) / 255.0;
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

const char *wt_plot_pname(const char *path) { return path ? path : "(null)"; }

/* Vertical error bars y ± e at the finite points (the standard error over seeds). */
static void error_bars(int n, const double *x, const double *y, const double *e)
{
    for (int k = 0; k < n; k++) {
        if (!isfinite(y[k]) || !isfinite(e[k]) || e[k] <= 0.0) continue;
        PLFLT px = x[k], lo = y[k] - e[k], hi = y[k] + e[k];
        plerry(1, &px, &lo, &hi);
    }
}

int wt_plot_strehl_sweep(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nmethods,
                         const char *const *methods, int nvalues, const double *x, const double *on_axis,
                         const double *field, const double *on_err, const double *field_err, int log_x)
{
    return wt_plot_strehl_sweep_named(ctx, path, title, xlabel, nmethods, methods, nvalues, x, NULL, on_axis, field, on_err,
                                      field_err, log_x);
}

int wt_plot_strehl_sweep_named(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nmethods,
                               const char *const *methods, int nvalues, const double *x, const char *const *names,
                               const double *on_axis, const double *field, const double *on_err, const double *field_err,
                               int log_x)
{
    if (nmethods < 1 || nmethods > MAX_SERIES || nvalues < 1 || nvalues > MAX_VALUES)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': Strehl sweep of %d methods x %d values; expected 1..%d x 1..%d",
                        wt_plot_pname(path), nmethods, nvalues, MAX_SERIES, MAX_VALUES);
    if (!methods || !x || !on_axis || !field)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': Strehl sweep with a NULL array", wt_plot_pname(path));
    double px[MAX_VALUES];
    double xmin = INFINITY, xmax = -INFINITY, ymax = 0.0;
    for (int k = 0; k < nvalues; k++) {
        if (!isfinite(x[k]) || (log_x && x[k] <= 0.0))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': swept value x[%d] = %g; expected finite%s", wt_plot_pname(path), k,
                            x[k], log_x ? " and > 0 for a log axis" : "");
        px[k] = log_x ? log10(x[k]) : x[k]; /* plbox "l" labels a log10 world axis */
        xmin = fmin(xmin, px[k]), xmax = fmax(xmax, px[k]);
    }
    /* NaN = that method was not run at that value (drawn as a gap); an infinity or a negative is a bug */
    for (long i = 0; i < (long)nmethods * nvalues; i++) {
        if (isinf(on_axis[i]) || isinf(field[i]) || on_axis[i] < 0.0 || field[i] < 0.0)
            return WT_ERROR(ctx, WT_ERR_INVALID,
                            "plot '%s': Strehl of method %ld at x[%ld] is %g on-axis, %g field; expected >= 0, or NaN "
                            "for a missing run",
                            wt_plot_pname(path), i / nvalues, i % nvalues, on_axis[i], field[i]);
        if (isfinite(on_axis[i])) ymax = fmax(ymax, on_axis[i] + (on_err && isfinite(on_err[i]) ? on_err[i] : 0.0));
        if (isfinite(field[i])) ymax = fmax(ymax, field[i] + (field_err && isfinite(field_err[i]) ? field_err[i] : 0.0));
    }
    for (int m = 0; m < nmethods; m++)
        if (!methods[m]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': method name %d is NULL", wt_plot_pname(path), m);
    double pad = xmax > xmin ? 0.04 * (xmax - xmin) : (log_x ? 0.25 : fmax(0.5, 0.1 * fabs(xmin)));
    xmin -= pad, xmax += pad;
    ymax = ymax > 0.0 ? 1.1 * ymax : 1.0; /* room above the best curve, 0 kept as the floor */

    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) return st;

    plvpor(0.10, 0.68, 0.14, 0.90);
    plwind(xmin, xmax, 0.0, ymax);
    wt_plot_axes(names ? "bc" : log_x ? "bcnstl" : "bcnst", "bcnstv", names ? "" : log_x ? "gl" : "g", "g");
    for (int k = 0; names && k < nvalues; k++) { /* the values' own names under their points */
        char lab[LABEL_MAX];
        plmtex("b", 1.6, (px[k] - xmin) / (xmax - xmin), 0.5, wt_plot_escape(lab, sizeof lab, names[k] ? names[k] : "?"));
    }
    /* a second line of the x label (after a newline), smaller: the key under its meaning */
    char first[LABEL_MAX], second[LABEL_MAX];
    const char *nl = strchr(xlabel, '\n');
    snprintf(first, sizeof first, "%.*s", nl ? (int)(nl - xlabel) : (int)strlen(xlabel), xlabel);
    wt_plot_labels(first, "LE Strehl", "");
    { /* the title centred on the page, not on the axes (the legend takes the right third): a long one fits */
        char tb[LABEL_MAX];
        plschr(0.0, 1.35);
        plmtex("t", 1.6, (0.5 - 0.10) / (0.68 - 0.10), 0.5, wt_plot_escape(tb, sizeof tb, title));
        plschr(0.0, 1.15);
    }
    if (nl) {
        plschr(0.0, 0.95);
        plmtex("b", 5.2, 0.5, 0.5, wt_plot_escape(second, sizeof second, nl + 1));
        plschr(0.0, 1.15);
    }

    for (int m = 0; m < nmethods; m++) {
        const double *on = on_axis + (long)m * nvalues, *fa = field + (long)m * nvalues;
        plcol0(C_PAL + m % N_PAL);
        plwidth(2.2);
        pllsty(1);
        line_with_gaps(nvalues, px, on);
        pllsty(3);
        line_with_gaps(nvalues, px, fa);
        pllsty(1);
        plwidth(1.0);
        markers_finite(nvalues, px, on, mark_filled[m % N_MARK]);
        markers_finite(nvalues, px, fa, mark_open[m % N_MARK]);
        if (on_err) error_bars(nvalues, px, on, on_err + (long)m * nvalues);
        if (field_err) error_bars(nvalues, px, fa, field_err + (long)m * nvalues);
    }

    /* legend "METHOD on-axis" / "METHOD field", outside the axes on the right */
    enum { NL = 2 * MAX_SERIES };
    PLINT opt[NL], tcol[NL], lcol[NL], lsty[NL], snum[NL];
    PLFLT lwid[NL], sscale[NL];
    const char *text[NL], *sym[NL];
    char buf[NL][LABEL_MAX];
    for (int m = 0; m < nmethods; m++) {
        char name[LABEL_MAX - 16];
        wt_plot_escape(name, sizeof name, methods[m]);
        for (int f = 0; f < 2; f++) {
            int i = 2 * m + f;
            snprintf(buf[i], LABEL_MAX, "%s %s", name, f ? "field" : "on-axis");
            opt[i] = PL_LEGEND_LINE | PL_LEGEND_SYMBOL;
            tcol[i] = C_FG;
            lcol[i] = C_PAL + m % N_PAL;
            lsty[i] = f ? 3 : 1;
            lwid[i] = 2.2;
            snum[i] = 2;
            sscale[i] = 1.0;
            text[i] = buf[i];
            sym[i] = f ? mark_open[m % N_MARK] : mark_filled[m % N_MARK];
        }
    }
    PLFLT lw, lh;
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.12, C_BG,
             C_GRID, 1, 0, 0, 2 * nmethods, opt, 1.0, 0.95, 2.0, 0.0, tcol, text, NULL, NULL, NULL, NULL, lcol, lsty,
             lwid, lcol, sscale, snum, sym);
    return wt_plot_job_end(&j);
}

/* A shaded colour bar of cmap1 from vmin to vmax right of the viewport (offset and yoff from it, width x
 * length in viewport units), labelled, ticks every `tick` (0: PLplot's choice). Many thin levels rather than
 * PL_COLORBAR_GRADIENT: the cairo driver of PLplot 5.15 leaks the cairo pattern of every plgradient call. */
void wt_plot_colour_bar(double vmin, double vmax, const char *label, double tick, double offset, double yoff,
                        double width, double length)
{
    enum { NLEV = 101 };
    PLFLT levels[NLEV];
    for (int i = 0; i < NLEV; i++) levels[i] = vmin + (vmax - vmin) * i / (NLEV - 1.0);
    char buf[LABEL_MAX];
    PLINT label_opts[1] = {PL_COLORBAR_LABEL_RIGHT};
    const char *labels[1] = {wt_plot_escape(buf, sizeof buf, label)};
    const char *axis_opts[1] = {"bcvtm"};
    PLFLT ticks[1] = {tick};
    PLINT sub_ticks[1] = {0};
    PLINT n_values[1] = {NLEV};
    const PLFLT *values[1] = {levels};
    PLFLT cw, ch;
    plcol0(C_FG);
    plcolorbar(&cw, &ch, PL_COLORBAR_SHADE, PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, offset, yoff,
               width, length, C_BG, C_FG, 1, 0.0, 0.0, 0, 0.0, 1, label_opts, labels, 1, axis_opts, ticks, sub_ticks,
               n_values, values);
}

/* "12.3" with about three significant digits, for the totals over the bars. */
static void fmt_ms(char *s, size_t n, double v)
{
    snprintf(s, n, v < 10.0 ? "%.2f ms" : v < 100.0 ? "%.1f ms" : "%.0f ms", v);
}

int wt_plot_time_bars(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                      int nparts, const char *const *parts, const double *times)
{
    if (nmethods < 1 || nmethods > MAX_SERIES || nparts < 1 || nparts > MAX_SERIES)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': time bars of %d methods x %d parts; expected 1..%d x 1..%d",
                        wt_plot_pname(path), nmethods, nparts, MAX_SERIES, MAX_SERIES);
    if (!methods || !parts || !times)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': time bars with a NULL array", wt_plot_pname(path));
    for (int m = 0; m < nmethods; m++)
        if (!methods[m]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': method name %d is NULL", wt_plot_pname(path), m);
    for (int k = 0; k < nparts; k++)
        if (!parts[k]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': part name %d is NULL", wt_plot_pname(path), k);
    double total[MAX_SERIES], tmax = 0.0;
    for (int m = 0; m < nmethods; m++) {
        total[m] = 0.0;
        for (int k = 0; k < nparts; k++) {
            double t = times[(long)m * nparts + k];
            if (!isfinite(t) || t < 0.0)
                return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': time of %s / %s is %g ms; expected finite and >= 0",
                                wt_plot_pname(path), methods[m], parts[k], t);
            total[m] += t;
        }
        tmax = fmax(tmax, total[m]);
    }
    double ymax = tmax > 0.0 ? 1.12 * tmax : 1.0; /* room for the totals printed over the bars */
    double xmin = 0.4, xmax = nmethods + 0.6, half = 0.3;

    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) return st;

    plvpor(0.10, 0.72, 0.12, 0.90);
    plwind(xmin, xmax, 0.0, ymax);
    wt_plot_axes("bc", "bcnstv", "", "g");
    wt_plot_labels("", "time per frame [ms]", title);

    char txt[LABEL_MAX];
    for (int m = 0; m < nmethods; m++) {
        double xc = m + 1.0, y0 = 0.0;
        for (int k = 0; k < nparts; k++) {
            double t = times[(long)m * nparts + k];
            if (t <= 0.0) continue;
            PLFLT fx[5] = {xc - half, xc + half, xc + half, xc - half, xc - half};
            PLFLT fy[5] = {y0, y0, y0 + t, y0 + t, y0};
            plcol0(C_PAL + k % N_PAL);
            plfill(4, fx, fy);
            plcol0(C_WHITE);
            plline(5, fx, fy);
            y0 += t;
        }
        PLFLT ox[5] = {xc - half, xc + half, xc + half, xc - half, xc - half}, oy[5] = {0, 0, y0, y0, 0};
        plcol0(C_FG);
        if (y0 > 0.0) plline(5, ox, oy);
        fmt_ms(txt, sizeof txt, total[m]);
        /* plptex centres the text on the point: lift it by about one character height */
        plptex(xc, total[m] + 0.045 * ymax, 1.0, 0.0, 0.5, txt);
        plmtex("b", 1.8, (xc - xmin) / (xmax - xmin), 0.5, wt_plot_escape(txt, sizeof txt, methods[m]));
    }

    /* legend of parts, listed top-down like the stack */
    PLINT opt[MAX_SERIES], tcol[MAX_SERIES], bcol[MAX_SERIES], bpat[MAX_SERIES];
    PLFLT bscale[MAX_SERIES], bwid[MAX_SERIES];
    const char *text[MAX_SERIES];
    char buf[MAX_SERIES][LABEL_MAX];
    for (int i = 0; i < nparts; i++) {
        int k = nparts - 1 - i;
        opt[i] = PL_LEGEND_COLOR_BOX;
        tcol[i] = C_FG;
        bcol[i] = C_PAL + k % N_PAL;
        bpat[i] = 0;
        bscale[i] = 0.9;
        bwid[i] = 1.0;
        text[i] = wt_plot_escape(buf[i], LABEL_MAX, parts[k]);
    }
    PLFLT lw, lh;
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.06, C_BG,
             C_GRID, 1, 0, 0, nparts, opt, 1.0, 0.95, 2.0, 0.0, tcol, text, bcol, bpat, bscale, bwid, NULL, NULL, NULL,
             NULL, NULL, NULL, NULL);
    return wt_plot_job_end(&j);
}

int wt_plot_grouped_bars(wt_context *ctx, const char *path, const char *title, const char *ylabel, int ngroups,
                         const char *const *groups, int nseries, const char *const *series, const double *values,
                         const double *marks)
{
    if (ngroups < 1 || ngroups > MAX_SERIES || nseries < 1 || nseries > MAX_SERIES)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': bars of %d groups x %d series; expected 1..%d x 1..%d",
                        wt_plot_pname(path), ngroups, nseries, MAX_SERIES, MAX_SERIES);
    if (!groups || !series || !values)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': grouped bars with a NULL array", wt_plot_pname(path));
    for (int k = 0; k < ngroups; k++)
        if (!groups[k]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': group name %d is NULL", wt_plot_pname(path), k);
    for (int s = 0; s < nseries; s++)
        if (!series[s]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': series name %d is NULL", wt_plot_pname(path), s);
    double vmax = 0.0;
    for (int i = 0; i < ngroups * nseries; i++) {
        if (isfinite(values[i])) vmax = fmax(vmax, fabs(values[i]));
        if (marks && isfinite(marks[i])) vmax = fmax(vmax, fabs(marks[i]));
    }
    int negative = 0;
    for (int i = 0; i < ngroups * nseries; i++) negative |= isfinite(values[i]) && values[i] < 0.0;
    /* headroom for the values, written upwards over the bars (side by side they run into each other) */
    double ymax = vmax > 0.0 ? 1.22 * vmax : 1.0;
    double xmin = 0.4, xmax = ngroups + 0.6, w = 0.8 / nseries;

    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) return st;
    plvpor(0.10, 0.76, 0.20, 0.90);
    plwind(xmin, xmax, 0.0, ymax);
    wt_plot_axes("bc", "bcnstv", "", "g");
    wt_plot_labels("", ylabel, title);

    char txt[LABEL_MAX];
    plschr(0.0, 0.8);
    for (int k = 0; k < ngroups; k++) {
        for (int s = 0; s < nseries; s++) {
            double v = values[k * nseries + s], x0 = k + 1.0 - 0.4 + s * w;
            if (isfinite(v) && v != 0.0) {
                /* a negative quadrature difference is drawn as its magnitude, hatched */
                PLFLT fx[5] = {x0, x0 + w, x0 + w, x0, x0}, fy[5] = {0, 0, fabs(v), fabs(v), 0};
                plcol0(C_PAL + s % N_PAL);
                if (v < 0.0) plpsty(3);
                plfill(4, fx, fy);
                plpsty(0);
                plcol0(C_FG);
                plline(5, fx, fy);
                snprintf(txt, sizeof txt, ymax < 10.0 ? "%.2f" : "%.0f", v); /* fractions: two decimals */
                plptex(x0 + 0.5 * w, fabs(v) + 0.015 * ymax, 0.0, 1.0, 0.0, txt);
            }
            double m = marks ? marks[k * nseries + s] : NAN;
            if (isfinite(m)) {
                PLFLT mx[2] = {x0, x0 + w}, my[2] = {fabs(m), fabs(m)};
                plcol0(C_FG);
                plwidth(3.0);
                plline(2, mx, my);
                plwidth(1.0);
            }
        }
    }
    plschr(0.0, 1.15);
    plcol0(C_FG);
    /* group names slanted, ending under their group, so that long names of neighbouring groups stay apart: drawn in
     * a viewport stretched down to the page's foot (the same world y scale), as PLplot clips text to the viewport */
    plvpor(0.0, 0.76, 0.0, 0.90);
    plwind(xmin - (xmax - xmin) * 0.10 / 0.66, xmax, -ymax * 0.20 / 0.70, ymax);
    /* plptex's direction is in world units: 30 degrees on the page is (cos 30 / px per x, sin 30 / px per y) */
    const double dx = cos(M_PI / 6) * (xmax - xmin) / (0.66 * PAGE_W), dy = sin(M_PI / 6) * ymax / (0.70 * PAGE_H);
    for (int k = 0; k < ngroups; k++)
        plptex(k + 1.0, -0.03 * ymax, dx, dy, 1.0, wt_plot_escape(txt, sizeof txt, groups[k]));
    if (negative) { /* the bars show magnitudes: say which are negative */
        plschr(0.0, 0.95);
        plmtex("b", -1.2, 0.5, 0.5, "hatched: a negative value (the label's sign), drawn at its magnitude");
        plschr(0.0, 1.15);
    }
    plvpor(0.10, 0.76, 0.20, 0.90); /* the legend beside the bars */
    plwind(xmin, xmax, 0.0, ymax);

    PLINT opt[MAX_SERIES + 1], tcol[MAX_SERIES + 1], bcol[MAX_SERIES + 1], bpat[MAX_SERIES + 1], lcol[MAX_SERIES + 1],
        lsty[MAX_SERIES + 1];
    PLFLT bscale[MAX_SERIES + 1], bwid[MAX_SERIES + 1], lwid[MAX_SERIES + 1];
    const char *text[MAX_SERIES + 1];
    char buf[MAX_SERIES][LABEL_MAX];
    int n = 0;
    for (int s = 0; s < nseries; s++, n++) {
        opt[n] = PL_LEGEND_COLOR_BOX;
        tcol[n] = C_FG, bcol[n] = C_PAL + s % N_PAL, bpat[n] = 0, bscale[n] = 0.9, bwid[n] = 1.0;
        lcol[n] = C_FG, lsty[n] = 1, lwid[n] = 1.0;
        text[n] = wt_plot_escape(buf[s], LABEL_MAX, series[s]);
    }
    if (marks) {
        opt[n] = PL_LEGEND_LINE;
        tcol[n] = C_FG, bcol[n] = C_FG, bpat[n] = 0, bscale[n] = 0.9, bwid[n] = 1.0;
        lcol[n] = C_FG, lsty[n] = 1, lwid[n] = 3.0;
        text[n++] = "analytic";
    }
    PLFLT lw, lh;
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.06, C_BG, C_GRID, 1, 0, 0,
             n, opt, 1.0, 0.95, 2.0, 0.0, tcol, text, bcol, bpat, bscale, bwid, lcol, lsty, lwid, NULL, NULL, NULL,
             NULL);
    return wt_plot_job_end(&j);
}
