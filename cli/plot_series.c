/* cli/plot_series.c: estimates over time against the truth (cli/plot.h wt_plot_series), PLplot.
 *
 * Stacked panels that share one x axis: in each, every series as markers joined by a thin line with error bars
 * y ± e, one colour per series (the same in every panel), and the truth as a thick black line. The axis ranges
 * hold every finite value and bar; nothing else is computed here. The job (stream, temporary, rename) is
 * plot.c's (plot_private.h). */
#include "cli/plot.h"
#include "cli/plot_private.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum { MAX_SERIES_S = 8, MAX_PANELS = 4 };

static const char *const glyph[4] = {"●", "■", "▲", "◆"};

/* A series' marker size: each one smaller than the one before, so that equal estimates (two methods that learn
 * from the same pseudo-open-loop slopes) stay visible, the later inside the earlier. */
static double size(int s) { return fmax(1.0 - 0.22 * s, 0.4); }

static void widen(double v, double *lo, double *hi)
{
    if (isfinite(v)) *lo = fmin(*lo, v), *hi = fmax(*hi, v);
}

static int check(wt_context *ctx, const char *path, int nseries, const char *const *names, int npanels,
                 const wt_plot_series_panel *p)
{
    if (nseries < 1 || nseries > MAX_SERIES_S || npanels < 1 || npanels > MAX_PANELS || !names || !p)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': %d series in %d panels; expected 1..%d series in 1..%d panels",
                        wt_plot_pname(path), nseries, npanels, MAX_SERIES_S, MAX_PANELS);
    int any = 0;
    for (int k = 0; k < npanels; k++) {
        if (!p[k].n || !p[k].x || !p[k].y || p[k].nt < 0 || (p[k].nt > 0 && (!p[k].tx || !p[k].ty)))
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': panel %d lacks its counts, x, y or truth arrays",
                            wt_plot_pname(path), k + 1);
        for (int s = 0; s < nseries; s++) {
            if (p[k].n[s] < 0 || (p[k].n[s] > 0 && (!p[k].x[s] || !p[k].y[s])))
                return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': panel %d, series '%s': %d points without arrays",
                                wt_plot_pname(path), k + 1, names[s] ? names[s] : "?", p[k].n[s]);
            for (int i = 0; i < p[k].n[s]; i++) any += isfinite(p[k].x[s][i]) && isfinite(p[k].y[s][i]);
            if (p[k].nr && p[k].nr[s] > 0 && (!p[k].rx || !p[k].ry || !p[k].rx[s] || !p[k].ry[s]))
                return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': panel %d, series '%s': a reference of %d points without "
                                "arrays", wt_plot_pname(path), k + 1, names[s] ? names[s] : "?", p[k].nr[s]);
        }
    }
    if (!any) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': no finite estimate to draw", wt_plot_pname(path));
    return WT_OK;
}

int wt_plot_series(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nseries,
                   const char *const *names, const char *refname, int npanels, const wt_plot_series_panel *p)
{
    int st = check(ctx, path, nseries, names, npanels, p);
    if (st < 0) return st;
    double xlo = INFINITY, xhi = -INFINITY, ylo[MAX_PANELS], yhi[MAX_PANELS];
    for (int k = 0; k < npanels; k++) {
        ylo[k] = INFINITY, yhi[k] = -INFINITY;
        for (int s = 0; s < nseries; s++)
            for (int i = 0; i < p[k].n[s]; i++) {
                const double e = p[k].e && p[k].e[s] && isfinite(p[k].e[s][i]) ? fabs(p[k].e[s][i]) : 0.0;
                if (!isfinite(p[k].x[s][i]) || !isfinite(p[k].y[s][i])) continue;
                widen(p[k].x[s][i], &xlo, &xhi);
                widen(p[k].y[s][i] - e, &ylo[k], &yhi[k]);
                widen(p[k].y[s][i] + e, &ylo[k], &yhi[k]);
            }
        for (int i = 0; i < p[k].nt; i++)
            if (isfinite(p[k].ty[i])) widen(p[k].tx[i], &xlo, &xhi), widen(p[k].ty[i], &ylo[k], &yhi[k]);
        for (int s = 0; p[k].nr && s < nseries; s++)
            for (int i = 0; i < p[k].nr[s]; i++)
                if (isfinite(p[k].ry[s][i])) widen(p[k].rx[s][i], &xlo, &xhi), widen(p[k].ry[s][i], &ylo[k], &yhi[k]);
        if (!(yhi[k] >= ylo[k])) ylo[k] = 0.0, yhi[k] = 1.0; /* a panel with nothing finite: an empty frame */
        const double pad = yhi[k] > ylo[k] ? 0.08 * (yhi[k] - ylo[k]) : 0.1 * fmax(fabs(yhi[k]), 1e-30);
        ylo[k] -= pad, yhi[k] += pad;
    }
    if (xhi == xlo) xlo -= 0.5, xhi += 0.5;
    const double xpad = 0.03 * (xhi - xlo);
    xlo -= xpad, xhi += xpad;

    wt_plot_job j;
    if ((st = wt_plot_job_begin_size(&j, ctx, path, PAGE_W, 120 + 300 * npanels)) < 0) return st;
    const double top = 0.92, bottom = 0.11, gap = 0.03, h = (top - bottom - gap * (npanels - 1)) / npanels;
    char tb[LABEL_MAX], yb[LABEL_MAX];
    for (int k = 0; k < npanels; k++) {
        const double y1 = top - k * (h + gap), y0 = y1 - h;
        plschr(0.0, 1.0);
        plvpor(0.14, 0.70, y0, y1);
        plwind(xlo, xhi, ylo[k], yhi[k]);
        const int last = k == npanels - 1;
        plsyax(6, 0); /* r0's 0.13 m as it is, not 1.3 with a ×10⁻¹ above the panel */
        wt_plot_axes(last ? "bcnstg" : "bcstg", "bcnstgv", "g", "g");
        plcol0(C_FG);
        plmtex("l", 5.4, 0.5, 0.5, wt_plot_escape(yb, sizeof yb, p[k].ylabel ? p[k].ylabel : ""));
        if (last) plmtex("b", 3.0, 0.5, 0.5, wt_plot_escape(yb, sizeof yb, xlabel ? xlabel : ""));
        if (k == 0) {
            plschr(0.0, 1.25); /* from the panel's left edge: a long title runs over the legend's column, not off the page */
            plmtex("t", 1.5, 0.0, 0.0, wt_plot_escape(tb, sizeof tb, title ? title : ""));
            plschr(0.0, 1.0);
        }
        if (p[k].nt >= 2) { /* the truth: thick black, broken where it is not finite */
            plcol0(C_FG);
            plwidth(3.0);
            for (int i = 0; i + 1 < p[k].nt; i++)
                if (isfinite(p[k].ty[i]) && isfinite(p[k].ty[i + 1]))
                    pljoin(p[k].tx[i], p[k].ty[i], p[k].tx[i + 1], p[k].ty[i + 1]);
            plwidth(1.0);
        }
        for (int s = 0; p[k].nr && s < nseries; s++) { /* each series' reference: dashed in its colour */
            plcol0(C_PAL + s % N_PAL);
            pllsty(2);
            plwidth(1.6);
            for (int i = 0; i + 1 < p[k].nr[s]; i++)
                if (isfinite(p[k].ry[s][i]) && isfinite(p[k].ry[s][i + 1]))
                    pljoin(p[k].rx[s][i], p[k].ry[s][i], p[k].rx[s][i + 1], p[k].ry[s][i + 1]);
            pllsty(1);
            plwidth(1.0);
        }
        for (int s = 0; s < nseries; s++) {
            const double *x = p[k].x[s], *y = p[k].y[s], *e = p[k].e ? p[k].e[s] : NULL;
            plcol0(C_PAL + s % N_PAL);
            plwidth(1.2);
            for (int i = 0; i + 1 < p[k].n[s]; i++)
                if (isfinite(x[i]) && isfinite(y[i]) && isfinite(x[i + 1]) && isfinite(y[i + 1]))
                    pljoin(x[i], y[i], x[i + 1], y[i + 1]);
            for (int i = 0; i < p[k].n[s]; i++) {
                if (!isfinite(x[i]) || !isfinite(y[i])) continue;
                if (e && isfinite(e[i]) && e[i] > 0.0) {
                    PLFLT px = x[i], lo = y[i] - e[i], hi = y[i] + e[i];
                    plerry(1, &px, &lo, &hi);
                }
                PLFLT px = x[i], py = y[i];
                plschr(0.0, size(s));
                plstring(1, &px, &py, glyph[s % 4]);
                plschr(0.0, 1.0);
            }
            plwidth(1.0);
        }
        if (k == 0) { /* the legend beside the top panel: the series, then the truth */
            enum { NLEG = MAX_SERIES_S + 2 };
            PLINT opt[NLEG], tcol[NLEG], lcol[NLEG], lsty[NLEG], bcol[NLEG], bpat[NLEG], scol[NLEG], snum[NLEG];
            PLFLT lwid[NLEG], bscale[NLEG], bwid[NLEG], sscale[NLEG];
            const char *text[NLEG], *sym[NLEG];
            char buf[NLEG][LABEL_MAX];
            int nl = 0, truth = 0, refs = 0;
            for (int q = 0; q < npanels; q++) {
                truth |= p[q].nt >= 2;
                for (int s = 0; p[q].nr && s < nseries; s++) refs |= p[q].nr[s] >= 2;
            }
            for (int s = 0; s < nseries; s++, nl++) {
                text[nl] = wt_plot_escape(buf[nl], sizeof buf[nl], names[s] ? names[s] : "");
                opt[nl] = PL_LEGEND_LINE | PL_LEGEND_SYMBOL, lcol[nl] = scol[nl] = C_PAL + s % N_PAL, lwid[nl] = 1.2;
                sym[nl] = glyph[s % 4], snum[nl] = 1, sscale[nl] = size(s);
            }
            if (truth) {
                text[nl] = "truth", opt[nl] = PL_LEGEND_LINE, lcol[nl] = scol[nl] = C_FG, lwid[nl] = 3.0;
                sym[nl] = "", snum[nl] = 0, sscale[nl] = 1.0;
                nl++;
            }
            for (int i = 0; i < nl; i++) lsty[i] = 1;
            if (refs) {
                text[nl] = wt_plot_escape(buf[nl], sizeof buf[nl], refname ? refname : "reference");
                opt[nl] = PL_LEGEND_LINE, lcol[nl] = scol[nl] = C_FG, lwid[nl] = 1.6, lsty[nl] = 2;
                sym[nl] = "", snum[nl] = 0, sscale[nl] = 1.0;
                nl++;
            }
            for (int i = 0; i < nl; i++) tcol[i] = C_FG, bcol[i] = C_MISSING, bpat[i] = 0, bscale[i] = 0.8, bwid[i] = 1.0;
            PLFLT lw, lh;
            pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
                     PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.10,
                     C_BG, C_GRID, 1, 0, 0, nl, opt, 1.0, 0.95, 2.0, 0.0, tcol, text, bcol, bpat, bscale, bwid, lcol,
                     lsty, lwid, scol, sscale, snum, sym);
        }
    }
    return wt_plot_job_end(&j);
}
