/* cli/plot_pupil.c: pictures of one Shack–Hartmann sensor over the pupil: the mosaic of
 * its subapertures' spot images, and maps of a value per subaperture (centroid gain, truncation). PLplot,
 * through the job of plot.c (own stream, temporary PNG renamed onto the path; see plot.c's header).
 *
 * Speed: PLplot's cairo driver has no fast image path (plimage fills one polygon per cell: ~3 s for the
 * E-ELT's 1344² detector pixels), so the mosaic is drawn as one black fill per subaperture and then, row by
 * row, runs of pixels that fall in the same one of the 256 grey levels (the dark ones skipped): the PNG is
 * pixel for pixel what plimage would draw, with a fraction of the fills. */
#include "cli/plot.h"
#include "cli/plot_private.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

const double wt_plot_trunc_levels[WT_PLOT_TRUNC_LEVELS] = {0.001, 0.01, 0.1};

/* cmap0 slots this file recolours on its own stream (plot.c's palette entries it does not use here) */
enum { C_TRUNC = C_PAL + 6, C_LAUNCH = C_PAL + 0 };
static const PLINT trunc_rgb[WT_PLOT_TRUNC_LEVELS][3] = {{240, 228, 66}, {230, 159, 0}, {213, 0, 0}};

enum { GREY_LEVELS = 256, MAX_NS = 256 };

/* Zoomed insets beside the mosaic: up to INSETS windows of INSET_CELLS subapertures across (near the launch,
 * farthest from it, the worst truncated), so that the spots' shape reads at a glance on a page shown small. */
enum { INSETS = 3, INSET_CELLS = 5, C_INSET = C_PAL + 5 };

/* Geometry of the mosaic's page: half-width of the square window [m], screen px per detector px, cell pitch
 * and viewport side [px], margins and page [px]. */
typedef struct {
    double half;
    int s, pitch, vp, left, bottom, width, height;
    int inset, inset_x, inset_gap; /* side of a zoomed inset, its column's left edge, the gap between insets [px] */
    double font; /* factor of the character heights (PLplot scales them with the page) */
} spots_layout;

/* Character height h (relative to PLplot's default) times the figure's factor f. */
static void chr(double f, double h) { plschr(0.0, f * h); }

static double window_half(const wt_plot_pupil *p)
{
    double r = 0.5 * p->diameter;
    for (int k = 0; k < p->nsub; k++) r = fmax(r, fmax(fabs(p->xc[k]), fabs(p->yc[k])) + 0.5 * p->side);
    if (p->has_launch) r = fmax(r, fmax(fabs(p->launch_x), fabs(p->launch_y)) + p->side);
    return r + 0.25 * p->side;
}

static void layout(const wt_plot_pupil *p, int ns, spots_layout *L)
{
    L->half = window_half(p);
    const double cells = 2.0 * L->half / p->side;
    L->s = (int)floor(1000.0 / (cells * ns));
    if (L->s < 1) L->s = 1;
    L->pitch = L->s * ns + 1; /* one px of gap between neighbouring cells */
    L->vp = (int)ceil(cells * L->pitch);
    /* the text and the margins grow as the square root of the page: legible when a big page is shown smaller */
    const double t = fmax(1.0, sqrt((L->vp + 190.0) / 1031.0));
    L->left = (int)(110 * t), L->bottom = (int)(90 * t);
    L->inset_gap = (int)(50 * t);
    /* insets only where the mosaic's detector pixels are single screen pixels (a big sensor) */
    L->inset = L->s <= 2 ? (L->vp - 2 * L->inset_gap) / INSETS : 0;
    L->inset_x = L->left + L->vp + (L->inset ? (int)(40 * t) : 0);
    L->width = L->inset_x + L->inset + (int)((L->inset ? 660 : 480) * t);
    L->height = L->vp + L->bottom + (int)(120 * t);
    L->font = t * 1031.0 / L->height;
}

void wt_plot_spots_page(const wt_plot_pupil *p, int ns, int *width, int *height)
{
    spots_layout L;
    layout(p, ns, &L);
    *width = L.width, *height = L.height;
}

static int check_pupil(wt_context *ctx, const char *path, const wt_plot_pupil *p)
{
    if (!p || p->nsub < 1 || !p->xc || !p->yc)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': no subaperture to draw", wt_plot_pname(path));
    if (!(p->side > 0.0) || !isfinite(p->side) || !(p->diameter > 0.0) || !isfinite(p->diameter) ||
        !(p->obstruction >= 0.0 && p->obstruction < 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': subaperture side %g m, diameter %g m, obstruction %g; expected "
                        "d > 0, D > 0, 0 <= obstruction < 1", wt_plot_pname(path), p->side, p->diameter, p->obstruction);
    for (int k = 0; k < p->nsub; k++)
        if (!isfinite(p->xc[k]) || !isfinite(p->yc[k]) || fabs(p->xc[k]) > 1e4 || fabs(p->yc[k]) > 1e4)
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': subaperture %d centre (%g, %g) m", wt_plot_pname(path), k,
                            p->xc[k], p->yc[k]);
    if (p->has_launch && (!isfinite(p->launch_x) || !isfinite(p->launch_y) || fabs(p->launch_x) > 1e4 ||
                          fabs(p->launch_y) > 1e4))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': launch position (%g, %g) m", wt_plot_pname(path), p->launch_x,
                        p->launch_y);
    /* a window of more than ~4000 subapertures across would need a page PLplot cannot hold */
    if (window_half(p) / p->side > 2000.0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': %g subapertures across the window; expected at most 4000",
                        wt_plot_pname(path), 2.0 * window_half(p) / p->side);
    return WT_OK;
}

/* The annulus outline (thin, grey) and the launch marker with its label. */
static void draw_outline_launch(const wt_plot_pupil *p, PLINT outline_col, double f, int label)
{
    plcol0(outline_col);
    plwidth(0.8);
    plarc(0.0, 0.0, 0.5 * p->diameter, 0.5 * p->diameter, 0.0, 360.0, 0.0, 0);
    if (p->obstruction > 0.0)
        plarc(0.0, 0.0, 0.5 * p->obstruction * p->diameter, 0.5 * p->obstruction * p->diameter, 0.0, 360.0, 0.0, 0);
    plwidth(1.0);
    if (p->has_launch) {
        PLFLT lx = p->launch_x, ly = p->launch_y;
        plcol0(C_LAUNCH);
        chr(f, 1.6);
        plstring(1, &lx, &ly, "★");
        chr(f, 0.9);
        if (!label) {
            chr(f, 1.15);
            return;
        }
        /* the label on the side towards the pupil centre, so that it stays inside the window */
        double r = hypot(lx, ly), ux = r > 0 ? -lx / r : 0.0, uy = r > 0 ? -ly / r : 1.0;
        plptex(lx + 1.6 * p->side * ux, ly + 1.6 * p->side * uy, 1.0, 0.0, 0.5, "launch");
        chr(f, 1.15);
    }
}

/* A shaded colour bar of cmap1 right of the viewport (wt_plot_colour_bar), 0.04 wide. */
static void colour_bar(double vmin, double vmax, const char *label, double offset, double yoff, double length)
{
    wt_plot_colour_bar(vmin, vmax, label, 0.0, offset, yoff, 0.04, length);
}

/* The cells of the subapertures that overlap the window w = {x0, x1, y0, y1} [m]: a black square each (a
 * screen px m [m] inside the cell's edges), then the runs of its pixels (of side pm [m]) in one grey level. */
static void draw_cells(const wt_plot_pupil *p, int ns, const float *img, int normalise, double gmax, double m, double pm,
                       const double w[4])
{
    const size_t npix = (size_t)ns * ns;
    pl_cmd(PLESC_START_RASTERIZE, NULL); /* no antialiasing seams between the fills, and faster */
    for (int k = 0; k < p->nsub; k++) {
        if (p->xc[k] + p->side < w[0] || p->xc[k] - p->side > w[1] || p->yc[k] + p->side < w[2] ||
            p->yc[k] - p->side > w[3])
            continue;
        const float *im = img + (size_t)k * npix;
        const double x0 = p->xc[k] - 0.5 * p->side + 0.5 * m, y0 = p->yc[k] - 0.5 * p->side + 0.5 * m;
        const double side = ns * pm;
        PLFLT fx[4] = {x0, x0 + side, x0 + side, x0}, fy[4] = {y0, y0, y0 + side, y0 + side};
        plcol1(0.5 / GREY_LEVELS);
        plfill(4, fx, fy);
        double imax = 0.0;
        if (normalise)
            for (size_t i = 0; i < npix; i++) imax = fmax(imax, im[i]);
        else imax = gmax;
        if (!(imax > 0.0)) continue;
        for (int iy = 0; iy < ns; iy++) {
            int ix = 0;
            while (ix < ns) {
                const double t = fmax(im[ix + (size_t)ns * iy], 0.0f) / imax;
                int lev = (int)(t * GREY_LEVELS), e = ix + 1;
                if (lev >= GREY_LEVELS) lev = GREY_LEVELS - 1;
                while (e < ns) {
                    const double te = fmax(im[e + (size_t)ns * iy], 0.0f) / imax;
                    int le = (int)(te * GREY_LEVELS);
                    if (le >= GREY_LEVELS) le = GREY_LEVELS - 1;
                    if (le != lev) break;
                    e++;
                }
                if (lev > 0) {
                    PLFLT rx[4] = {x0 + ix * pm, x0 + e * pm, x0 + e * pm, x0 + ix * pm};
                    PLFLT ry[4] = {y0 + iy * pm, y0 + iy * pm, y0 + (iy + 1) * pm, y0 + (iy + 1) * pm};
                    plcol1((lev + 0.5) / GREY_LEVELS);
                    plfill(4, rx, ry);
                }
                ix = e;
            }
        }
    }
    pl_cmd(PLESC_END_RASTERIZE, NULL);
}

/* The truncation frames of the cells in the window (the lowest level first, so the highest stays on top);
 * count[l]: the subapertures framed at level l (when not NULL). */
static void draw_frames(const wt_plot_pupil *p, const double *trunc, double m, double width, const double w[4],
                        int *count)
{
    for (int l = 0; l < WT_PLOT_TRUNC_LEVELS; l++) {
        plcol0(C_TRUNC + l);
        plwidth(width);
        for (int k = 0; k < p->nsub; k++) {
            int lev = -1;
            for (int q = 0; q < WT_PLOT_TRUNC_LEVELS; q++)
                if (trunc[k] > wt_plot_trunc_levels[q]) lev = q;
            if (lev != l) continue;
            if (count) count[l]++;
            if (p->xc[k] + p->side < w[0] || p->xc[k] - p->side > w[1] || p->yc[k] + p->side < w[2] ||
                p->yc[k] - p->side > w[3])
                continue;
            const double a = 0.5 * p->side - 0.5 * m;
            PLFLT fx[5] = {p->xc[k] - a, p->xc[k] + a, p->xc[k] + a, p->xc[k] - a, p->xc[k] - a};
            PLFLT fy[5] = {p->yc[k] - a, p->yc[k] - a, p->yc[k] + a, p->yc[k] + a, p->yc[k] - a};
            plline(5, fx, fy);
        }
    }
    plwidth(1.0);
}

int wt_plot_spots(wt_context *ctx, const char *path, const char *title, const char *note, const wt_plot_pupil *p,
                  int ns, const float *img, int normalise, const double *trunc)
{
    int st = check_pupil(ctx, path, p);
    if (st < 0) return st;
    if (ns < 1 || ns > MAX_NS || !img)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': %d x %d pixels per subaperture%s; expected 1..%d",
                        wt_plot_pname(path), ns, ns, img ? "" : " (no images)", MAX_NS);
    const size_t npix = (size_t)ns * ns;
    double gmax = 0.0;
    for (size_t i = 0; i < (size_t)p->nsub * npix; i++) {
        if (!isfinite(img[i]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': pixel %zu of subaperture %zu is %g; expected finite",
                            wt_plot_pname(path), i % npix, i / npix, (double)img[i]);
        gmax = fmax(gmax, img[i]);
    }
    if (trunc)
        for (int k = 0; k < p->nsub; k++)
            if (!isfinite(trunc[k]))
                return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': truncation of subaperture %d is %g; expected finite",
                                wt_plot_pname(path), k, trunc[k]);
    spots_layout L;
    layout(p, ns, &L);

    wt_plot_job j;
    if ((st = wt_plot_job_begin_size(&j, ctx, path, L.width, L.height)) < 0) return st;
    chr(L.font, 1.15);
    /* grey scale, black = no light, on this stream only */
    PLFLT pos[2] = {0.0, 1.0}, grey[2] = {0.0, 1.0};
    plscmap1n(GREY_LEVELS);
    plscmap1l(1, 2, pos, grey, grey, grey, NULL);
    for (int l = 0; l < WT_PLOT_TRUNC_LEVELS; l++) plscol0(C_TRUNC + l, trunc_rgb[l][0], trunc_rgb[l][1], trunc_rgb[l][2]);

    plvpor((double)L.left / L.width, (double)(L.left + L.vp) / L.width, (double)L.bottom / L.height,
           (double)(L.bottom + L.vp) / L.height);
    plwind(-L.half, L.half, -L.half, L.half);

    const double m = p->side / L.pitch, pm = L.s * m; /* metres per screen px, per detector px */
    const double all[4] = {-L.half, L.half, -L.half, L.half};
    draw_cells(p, ns, img, normalise, gmax, m, pm, all);
    int count[WT_PLOT_TRUNC_LEVELS] = {0};
    double worst = 0.0;
    if (trunc) {
        draw_frames(p, trunc, m, L.s > 2 ? 2.5 : 1.6, all, count);
        for (int k = 0; k < p->nsub; k++) worst = fmax(worst, trunc[k]);
    }
    draw_outline_launch(p, C_MISSING, L.font, 0);
    chr(L.font, 0.9);
    wt_plot_axes("bcnst", "bcnstv", "", "");
    char tb[LABEL_MAX], nb[LABEL_MAX];
    plcol0(C_FG);
    plmtex("b", 3.0, 0.5, 0.5, "pupil x [m]");
    plmtex("l", 3.2, 0.5, 0.5, "pupil y [m]");
    chr(L.font, 1.1);
    plmtex("t", 3.0, 0.0, 0.0, wt_plot_escape(tb, sizeof tb, title));
    chr(L.font, 0.8);
    plmtex("t", 1.2, 0.0, 0.0, wt_plot_escape(nb, sizeof nb, note));
    /* the insets: nearest to the launch (or the centre), farthest from it, the worst truncated */
    int pick[INSETS], ni = 0;
    {
        const double cx = p->has_launch ? p->launch_x : 0.0, cy = p->has_launch ? p->launch_y : 0.0;
        /* u: the unit vector from the centre to the launch; side: the largest offset across it (the elongation
         * at an angle) */
        const double r = hypot(cx, cy), ux = r > 0.0 ? cx / r : 1.0, uy = r > 0.0 ? cy / r : 0.0;
        int near = 0, far = 0, bad = -1, side = 0;
        for (int k = 0; k < p->nsub; k++) {
            const double d = hypot(p->xc[k] - cx, p->yc[k] - cy);
            if (d < hypot(p->xc[near] - cx, p->yc[near] - cy)) near = k;
            if (d > hypot(p->xc[far] - cx, p->yc[far] - cy)) far = k;
            if (ux * p->yc[k] - uy * p->xc[k] > ux * p->yc[side] - uy * p->xc[side]) side = k;
            if (trunc && trunc[k] > 0.0 && (bad < 0 || trunc[k] > trunc[bad])) bad = k;
        }
        pick[ni++] = near;
        if (far != near) pick[ni++] = far;
        /* the worst truncated when it is in a higher frame level than the farthest, else the one across */
        int level_bad = -1, level_far = -1;
        for (int q = 0; q < WT_PLOT_TRUNC_LEVELS && bad >= 0; q++) {
            if (trunc[bad] > wt_plot_trunc_levels[q]) level_bad = q;
            if (trunc[far] > wt_plot_trunc_levels[q]) level_far = q;
        }
        const int third = bad >= 0 && level_bad > level_far ? bad : side;
        if (third != near && third != far) pick[ni++] = third;
    }
    const double ih = 0.5 * INSET_CELLS * p->side;
    for (int i = 0; i < ni && L.inset > 0; i++) {
        const int k = pick[i];
        const double w[4] = {p->xc[k] - ih, p->xc[k] + ih, p->yc[k] - ih, p->yc[k] + ih};
        char lab[8], it[LABEL_MAX];
        snprintf(lab, sizeof lab, "%c", 'a' + i);
        /* where it is on the mosaic */
        plvpor((double)L.left / L.width, (double)(L.left + L.vp) / L.width, (double)L.bottom / L.height,
               (double)(L.bottom + L.vp) / L.height);
        plwind(-L.half, L.half, -L.half, L.half);
        PLFLT bx[5] = {w[0], w[1], w[1], w[0], w[0]}, by[5] = {w[2], w[2], w[3], w[3], w[2]};
        plcol0(C_INSET);
        plwidth(2.0);
        plline(5, bx, by);
        plwidth(1.0);
        chr(L.font, 0.9);
        plptex(w[0] - 0.6 * p->side, w[3] + 0.6 * p->side, 1.0, 0.0, 0.5, lab);
        /* the inset, top down in the column */
        const int top = L.bottom + L.vp - i * (L.inset + L.inset_gap);
        plvpor((double)L.inset_x / L.width, (double)(L.inset_x + L.inset) / L.width,
               (double)(top - L.inset) / L.height, (double)top / L.height);
        plwind(w[0], w[1], w[2], w[3]);
        PLFLT wx[4] = {w[0], w[1], w[1], w[0]}, wy[4] = {w[2], w[2], w[3], w[3]};
        plcol0(C_BG);
        plfill(4, wx, wy);
        draw_cells(p, ns, img, normalise, gmax, m, pm, w);
        if (trunc) draw_frames(p, trunc, m, 2.5, w, NULL);
        plcol0(C_INSET);
        plwidth(3.0);
        plbox("bc", 0.0, 0, "bc", 0.0, 0);
        plwidth(1.0);
        plcol0(C_FG);
        chr(L.font, 0.75);
        const double dl = p->has_launch ? hypot(p->xc[k] - p->launch_x, p->yc[k] - p->launch_y) : hypot(p->xc[k], p->yc[k]);
        snprintf(it, sizeof it, "%s: (%.2f, %.2f) m", lab, p->xc[k], p->yc[k]);
        plmtex("t", 1.6, 0.0, 0.0, it);
        if (trunc) snprintf(it, sizeof it, "%.1f m from the %s; truncation %.2f %%", dl, p->has_launch ? "launch" : "centre",
                            100.0 * trunc[k]);
        else snprintf(it, sizeof it, "%.1f m from the %s", dl, p->has_launch ? "launch" : "centre");
        plmtex("t", 0.4, 0.0, 0.0, it);
    }
    plvpor((double)L.left / L.width, (double)(L.left + L.vp) / L.width, (double)L.bottom / L.height,
           (double)(L.bottom + L.vp) / L.height);
    plwind(-L.half, L.half, -L.half, L.half);

    /* colour bar and legend right of the insets' column */
    const double right = (double)(L.inset_x + L.inset - L.left - L.vp) / L.vp;
    chr(L.font, 0.9);
    colour_bar(0.0, 1.0, normalise ? "I / I_max (each subaperture's peak)" : "I / I_max (the brightest pixel)", right + (L.inset ? 0.2 : 0.06), 0.2, 0.45);

    /* legend: the frames and the launch */
    enum { NL = WT_PLOT_TRUNC_LEVELS + 2 };
    PLINT opt[NL], tcol[NL], lcol[NL], lsty[NL], snum[NL];
    PLFLT lwid[NL], sscale[NL];
    const char *text[NL], *sym[NL];
    char buf[NL][LABEL_MAX];
    int n = 0;
    if (trunc) {
        for (int l = WT_PLOT_TRUNC_LEVELS - 1; l >= 0; l--, n++) {
            snprintf(buf[n], LABEL_MAX, "truncation > %g %%: %d", 100.0 * wt_plot_trunc_levels[l], count[l]);
            opt[n] = PL_LEGEND_LINE, tcol[n] = C_FG, lcol[n] = C_TRUNC + l, lsty[n] = 1, lwid[n] = 3.0;
            snum[n] = 0, sscale[n] = 1.0, sym[n] = "", text[n] = buf[n];
        }
        if (worst < 1e-4) snprintf(buf[n], LABEL_MAX, "worst: < 0.01 %%");
        else snprintf(buf[n], LABEL_MAX, "worst: %.2f %%", 100.0 * worst);
        opt[n] = PL_LEGEND_NONE, tcol[n] = C_FG, lcol[n] = C_FG, lsty[n] = 1, lwid[n] = 1.0;
        snum[n] = 0, sscale[n] = 1.0, sym[n] = "", text[n] = buf[n];
        n++;
    }
    if (p->has_launch) {
        snprintf(buf[n], LABEL_MAX, "laser launch");
        opt[n] = PL_LEGEND_SYMBOL, tcol[n] = C_FG, lcol[n] = C_LAUNCH, lsty[n] = 1, lwid[n] = 1.0;
        snum[n] = 1, sscale[n] = 1.4, sym[n] = "★", text[n] = buf[n];
        n++;
    }
    if (n > 0) {
        PLFLT lw, lh;
        chr(L.font, 0.8);
        pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
                 PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, right + (L.inset ? 0.12 : 0.05), -0.3, 0.06,
                 C_BG, C_GRID, 1, 0, 0, n, opt, 1.0, 0.85 * L.font, 2.0, 0.0, tcol, text, NULL, NULL, NULL, NULL, lcol, lsty,
                 lwid, lcol, sscale, snum, sym);
    }
    return wt_plot_job_end(&j);
}

int wt_plot_pupil_maps(wt_context *ctx, const char *path, const char *title, const wt_plot_pupil *p, int nmaps,
                       const double *const *values, const double *range, const char *const *subtitles,
                       const char *const *bar_labels)
{
    int st = check_pupil(ctx, path, p);
    if (st < 0) return st;
    if (nmaps < 1 || nmaps > 2 || !values)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': %d maps; expected 1 or 2", wt_plot_pname(path), nmaps);
    double vmin[2], vmax[2];
    for (int q = 0; q < nmaps; q++) {
        if (!values[q]) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': map %d is NULL", wt_plot_pname(path), q);
        vmin[q] = INFINITY, vmax[q] = -INFINITY;
        for (int k = 0; k < p->nsub; k++) {
            const double v = values[q][k];
            if (isinf(v))
                return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': map %d, subaperture %d is %g; expected finite (NaN: "
                                "missing)", wt_plot_pname(path), q, k, v);
            if (isfinite(v)) vmin[q] = fmin(vmin[q], v), vmax[q] = fmax(vmax[q], v);
        }
        if (!(vmin[q] <= vmax[q])) vmin[q] = 0.0, vmax[q] = 1.0; /* all missing */
        if (range && isfinite(range[2 * q])) vmin[q] = range[2 * q];
        if (range && isfinite(range[2 * q + 1])) vmax[q] = range[2 * q + 1];
        if (!(vmin[q] <= vmax[q]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': map %d colour range [%g, %g]", wt_plot_pname(path), q,
                            vmin[q], vmax[q]);
        if (vmax[q] - vmin[q] <= 1e-12 * fmax(1.0, fabs(vmax[q]))) {
            const double h = vmax[q] != 0.0 ? 0.01 * fabs(vmax[q]) : 0.01;
            vmin[q] -= h, vmax[q] += h;
        }
    }
    const double half = window_half(p);
    enum { MAPS_W = 1500, MAPS_H = 720 };
    wt_plot_job j;
    if ((st = wt_plot_job_begin_size(&j, ctx, path, nmaps == 2 ? MAPS_W : PAGE_W, nmaps == 2 ? MAPS_H : PAGE_H)) < 0)
        return st;
    char buf[LABEL_MAX];
    for (int q = 0; q < nmaps; q++) {
        const double x0 = nmaps == 2 ? 0.06 + 0.5 * q : 0.10;
        plvpas(x0, x0 + (nmaps == 2 ? 0.33 : 0.60), 0.13, 0.80, 1.0);
        plwind(-half, half, -half, half);
        for (int k = 0; k < p->nsub; k++) {
            const double v = values[q][k], a = 0.5 * p->side;
            PLFLT fx[4] = {p->xc[k] - a, p->xc[k] + a, p->xc[k] + a, p->xc[k] - a};
            PLFLT fy[4] = {p->yc[k] - a, p->yc[k] - a, p->yc[k] + a, p->yc[k] + a};
            if (isnan(v)) plcol0(C_MISSING);
            else plcol1(fmin(fmax((v - vmin[q]) / (vmax[q] - vmin[q]), 0.0), 1.0));
            plfill(4, fx, fy);
        }
        plschr(0.0, 0.8);
        draw_outline_launch(p, C_FG, 0.8, 0);
        wt_plot_axes("bcnst", "bcnstv", "", "");
        plcol0(C_FG);
        plmtex("b", 2.6, 0.5, 0.5, "pupil x [m]");
        plmtex("l", 3.2, 0.5, 0.5, "pupil y [m]");
        /* the subtitle, on two lines at a newline */
        plschr(0.0, 0.8);
        if (subtitles && subtitles[q]) {
            wt_plot_escape(buf, sizeof buf, subtitles[q]);
            char *nl = strchr(buf, '\n');
            if (nl) *nl = '\0';
            plmtex("t", nl ? 2.2 : 1.0, 0.5, 0.5, buf);
            if (nl) plmtex("t", 0.8, 0.5, 0.5, nl + 1);
        }
        plschr(0.0, 0.85);
        colour_bar(vmin[q], vmax[q], bar_labels && bar_labels[q] ? bar_labels[q] : "", 0.04, 0.0, 0.8);
    }
    plvpor(0.0, 1.0, 0.0, 1.0);
    plwind(0.0, 1.0, 0.0, 1.0);
    plschr(0.0, 1.05);
    plcol0(C_FG);
    plmtex("t", -1.6, 0.5, 0.5, wt_plot_escape(buf, sizeof buf, title));
    plschr(0.0, 1.15);
    return wt_plot_job_end(&j);
}
