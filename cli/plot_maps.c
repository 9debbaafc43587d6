/* cli/plot_maps.c: the report's maps over the evaluation field (PLplot; the job, colours and helpers of
 * cli/plot_private.h): the LE Strehl of one method on viridis, and the difference of a field quantity between
 * two methods on a diverging map centred on zero, both with the guide stars' directions marked.
 *
 * Cell (i, j) is the evaluation direction (coords[i], coords[j]) of the g x g grid (index i + g j); its edges lie
 * halfway between directions, the outer ones mirrored. The window is the cells', widened (square, centred) to hold
 * every guide star with a margin: an NGS asterism is often wider than the evaluation field.
 * A difference map's colour scale is symmetric, [-A, A] with A = max |d|, so that white is "no difference" and
 * the two signs look alike in strength.
 */
#include "cli/plot.h"
#include "cli/plot_private.h"

#include <math.h>
#include <plplot.h>
#include <stdio.h>
#include <string.h>

enum { MAX_GRID = 64, MAX_STARS = 64 };

/* Blue (< 0) - white (0) - red (> 0), ColorBrewer RdBu: readable in grey as |d|, safe for red-green blindness. */
enum { N_DIVERGING = 5 };
static const double diverging[N_DIVERGING][4] = {
    {0.00, 33, 102, 172}, {0.25, 146, 197, 222}, {0.50, 247, 247, 247}, {0.75, 244, 165, 130}, {1.00, 178, 24, 43},
};

/* Marker glyphs and their colours (cmap0): an LGS a star, an NGS a triangle, each on a white halo so that it
 * stays visible on any cell colour. */
static const char *const lgs_glyph = "★", *const ngs_glyph = "▲";
enum { C_LGS = C_PAL + 4, C_NGS = C_PAL + 7 }; /* vermilion, purple: apart from viridis and from RdBu */

typedef struct {
    const char *bar_label; /* colour bar */
    const char *fmt;       /* cell text */
    int diverging;         /* 0: viridis on [vmin, vmax]; 1: RdBu on [vmin, vmax] = [-A, A] */
} map_style;

static int check_stars(wt_context *ctx, const char *path, const wt_plot_stars *s)
{
    if (!s) return WT_OK;
    if (s->nlgs < 0 || s->nngs < 0 || s->nlgs > MAX_STARS || s->nngs > MAX_STARS ||
        (s->nlgs && (!s->lgs_x || !s->lgs_y)) || (s->nngs && (!s->ngs_x || !s->ngs_y)))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': guide stars %d LGS, %d NGS (at most %d each, with positions)",
                        wt_plot_pname(path), s->nlgs, s->nngs, MAX_STARS);
    for (int k = 0; k < s->nlgs + s->nngs; k++) {
        const double x = k < s->nlgs ? s->lgs_x[k] : s->ngs_x[k - s->nlgs];
        const double y = k < s->nlgs ? s->lgs_y[k] : s->ngs_y[k - s->nlgs];
        if (!isfinite(x) || !isfinite(y) || fabs(x) > 1e5 || fabs(y) > 1e5)
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': guide star %d at (%g, %g) arcsec", wt_plot_pname(path), k, x, y);
    }
    return WT_OK;
}

static int check_map(wt_context *ctx, const char *path, int g, const double *coords, const double *v)
{
    if (g < 1 || g > MAX_GRID)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': field map of %d x %d cells; expected 1..%d per side",
                        wt_plot_pname(path), g, g, MAX_GRID);
    if (!coords || !v) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': field map with a NULL array", wt_plot_pname(path));
    for (int i = 0; i < g; i++)
        if (!isfinite(coords[i]) || (i > 0 && !(coords[i] > coords[i - 1])))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': field coordinate %d = %g [arcsec]; expected finite and "
                            "increasing", wt_plot_pname(path), i, coords[i]);
    for (long i = 0; i < (long)g * g; i++)
        if (isinf(v[i]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': value of cell %ld is %g; expected finite (NaN: missing)",
                            wt_plot_pname(path), i, v[i]);
    return WT_OK;
}

static void draw_glyphs(int n, const double *x, const double *y, const char *glyph, PLINT col)
{
    for (int k = 0; k < n; k++) {
        PLFLT px = x[k], py = y[k];
        plschr(0.0, 1.85);
        plcol0(C_WHITE);
        plstring(1, &px, &py, glyph);
        plschr(0.0, 1.3);
        plcol0(col);
        plstring(1, &px, &py, glyph);
    }
    plschr(0.0, 1.15);
}

/* The legend of the markers, below the colour bar. */
static void stars_legend(const wt_plot_stars *s)
{
    PLINT opt[2], tcol[2], scol[2], snum[2];
    PLFLT sscale[2];
    const char *text[2], *sym[2];
    int n = 0;
    if (s->nlgs) opt[n] = PL_LEGEND_SYMBOL, tcol[n] = C_FG, scol[n] = C_LGS, snum[n] = 1, sscale[n] = 1.4,
                 text[n] = "LGS", sym[n++] = lgs_glyph;
    if (s->nngs) opt[n] = PL_LEGEND_SYMBOL, tcol[n] = C_FG, scol[n] = C_NGS, snum[n] = 1, sscale[n] = 1.4,
                 text[n] = "NGS", sym[n++] = ngs_glyph;
    if (!n) return;
    PLFLT lw, lh;
    plschr(0.0, 1.0);
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_BOTTOM | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.06, C_BG,
             C_GRID, 1, 0, 0, n, opt, 0.8, 1.0, 1.6, 0.0, tcol, text, NULL, NULL, NULL, NULL, NULL, NULL, NULL, scol,
             sscale, snum, sym);
    plschr(0.0, 1.15);
}

/* Text colour over a cell of colour position t in [0, 1]: dark on light, white on dark. */
static PLINT text_colour(const map_style *m, double t)
{
    if (m->diverging) return fabs(t - 0.5) > 0.36 ? C_WHITE : C_FG;
    return wt_plot_viridis_luminance(t) > 0.45 ? C_FG : C_WHITE;
}

static int field_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                     const double *v, double vmin, double vmax, const wt_plot_stars *stars, const map_style *m)
{
    double e[MAX_GRID + 1];
    if (g == 1) {
        e[0] = coords[0] - 0.5, e[1] = coords[0] + 0.5;
    } else {
        for (int i = 1; i < g; i++) e[i] = 0.5 * (coords[i - 1] + coords[i]);
        e[0] = 2.0 * coords[0] - e[1];
        e[g] = 2.0 * coords[g - 1] - e[g - 1];
    }
    /* the window: the cells, widened to every star plus 8 % of the cells' span */
    const double c0 = 0.5 * (e[0] + e[g]), pad = 0.08 * (e[g] - e[0]);
    double half = 0.5 * (e[g] - e[0]);
    for (int k = 0; stars && k < stars->nlgs + stars->nngs; k++) {
        const double x = k < stars->nlgs ? stars->lgs_x[k] : stars->ngs_x[k - stars->nlgs];
        const double y = k < stars->nlgs ? stars->lgs_y[k] : stars->ngs_y[k - stars->nlgs];
        half = fmax(half, fmax(fabs(x - c0), fabs(y - c0)) + pad);
    }
    const double w0 = c0 - half, w1 = c0 + half;

    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) return st;
    if (m->diverging) {
        PLFLT pos[N_DIVERGING], cr[N_DIVERGING], cg[N_DIVERGING], cb[N_DIVERGING];
        for (int i = 0; i < N_DIVERGING; i++)
            pos[i] = diverging[i][0], cr[i] = diverging[i][1] / 255.0, cg[i] = diverging[i][2] / 255.0,
            cb[i] = diverging[i][3] / 255.0;
        plscmap1l(1, N_DIVERGING, pos, cr, cg, cb, NULL);
    }
    plvpas(0.08, 0.78, 0.12, 0.90, 1.0);
    plwind(w0, w1, w0, w1);
    for (int r = 0; r < g; r++)
        for (int c = 0; c < g; c++) {
            const double x = v[c + (long)g * r];
            PLFLT fx[4] = {e[c], e[c + 1], e[c + 1], e[c]}, fy[4] = {e[r], e[r], e[r + 1], e[r + 1]};
            if (isnan(x)) plcol0(C_MISSING);
            else plcol1(fmin(fmax((x - vmin) / (vmax - vmin), 0.0), 1.0));
            plfill(4, fx, fy);
        }
    /* seams so that neighbouring cells of close colour stay distinct; the cells' outline when the window is wider */
    plcol0(m->diverging ? C_GRID : C_WHITE);
    plwidth(1.5);
    for (int i = 1; i < g; i++) {
        pljoin(e[i], e[0], e[i], e[g]);
        pljoin(e[0], e[i], e[g], e[i]);
    }
    if (w0 < e[0] || w1 > e[g]) {
        plcol0(C_GRID);
        PLFLT ox[5] = {e[0], e[g], e[g], e[0], e[0]}, oy[5] = {e[0], e[0], e[g], e[g], e[0]};
        plline(5, ox, oy);
    }
    plwidth(1.0);
    if (g <= 9) { /* label the evaluation directions themselves: they need not be multiples of a tick step */
        wt_plot_axes("bc", "bc", "", "");
        for (int i = 0; i < g; i++) {
            char s[32];
            const double f = (coords[i] - w0) / (w1 - w0);
            snprintf(s, sizeof s, "%g", coords[i]);
            plmtex("b", 1.4, f, 0.5, s);
            plmtex("lv", 0.6, f, 1.0, s);
        }
    } else {
        wt_plot_axes("bcnst", "bcnstv", "", "");
    }
    wt_plot_labels("field x [arcsec]", "field y [arcsec]", title);

    /* each value in its cell; character height follows the cell so 8x8 maps stay legible, a little smaller with
     * the stars so that a star on a cell's edge leaves its neighbours' numbers readable */
    const int marked = stars && stars->nlgs + stars->nngs > 0;
    plschr(0.0, fmax(0.4, marked ? fmin(1.0, 5.5 / g) : fmin(1.25, 7.5 / g)));
    for (int r = 0; r < g; r++)
        for (int c = 0; c < g; c++) {
            const double x = v[c + (long)g * r];
            char s[32];
            if (isnan(x)) {
                snprintf(s, sizeof s, "n/a");
                plcol0(C_FG);
            } else {
                snprintf(s, sizeof s, m->fmt, x);
                plcol0(text_colour(m, fmin(fmax((x - vmin) / (vmax - vmin), 0.0), 1.0)));
            }
            plptex(0.5 * (e[c] + e[c + 1]), 0.5 * (e[r] + e[r + 1]), 1.0, 0.0, 0.5, s);
        }
    plschr(0.0, 1.15);
    if (stars) {
        draw_glyphs(stars->nlgs, stars->lgs_x, stars->lgs_y, lgs_glyph, C_LGS);
        draw_glyphs(stars->nngs, stars->ngs_x, stars->ngs_y, ngs_glyph, C_NGS);
    }
    plcol0(C_FG);
    wt_plot_colour_bar(vmin, vmax, m->bar_label, 0.0, 0.05, marked ? -0.09 : 0.0, 0.05, marked ? 0.8 : 1.0);
    if (marked) stars_legend(stars);
    return wt_plot_job_end(&j);
}

int wt_plot_strehl_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                       const double *strehl, double vmin, double vmax, const wt_plot_stars *stars)
{
    int st = check_map(ctx, path, g, coords, strehl);
    if (st < 0 || (st = check_stars(ctx, path, stars)) < 0) return st;
    if (!isfinite(vmin) || !isfinite(vmax) || vmin > vmax)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': colour range [%g, %g]; expected finite vmin <= vmax",
                        wt_plot_pname(path), vmin, vmax);
    if (vmin == vmax) vmin -= 0.05, vmax += 0.05; /* a uniform field (min = max over the maps): one mid colour */
    const map_style m = {"LE Strehl", "%.3f", 0};
    return field_map(ctx, path, title, g, coords, strehl, vmin, vmax, stars, &m);
}

int wt_plot_diff_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                     const double *diff, const char *bar_label, const char *fmt, const wt_plot_stars *stars)
{
    int st = check_map(ctx, path, g, coords, diff);
    if (st < 0 || (st = check_stars(ctx, path, stars)) < 0) return st;
    if (!bar_label || !fmt || strchr(fmt, '%') == NULL || strchr(strchr(fmt, '%') + 1, '%'))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': a difference map needs a colour bar label and one number format",
                        wt_plot_pname(path));
    double a = 0.0;
    for (long i = 0; i < (long)g * g; i++)
        if (!isnan(diff[i])) a = fmax(a, fabs(diff[i]));
    if (a == 0.0) a = 1.0; /* no difference at all: every cell white, a unit scale */
    const map_style m = {bar_label, fmt, 1};
    return field_map(ctx, path, title, g, coords, diff, -a, a, stars, &m);
}
