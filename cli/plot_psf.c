/* cli/plot_psf.c: the report's long-exposure PSF figures, PLplot (the job, colours and helpers of plot.c):
 * the mosaic of long-exposure PSFs over the field (sim/psf.h, SPEC §8b) and the residual WFE of every frame
 * with its running long-exposure value (SPEC §8), the settle window shaded. Nothing is computed here but the
 * log scale, the running mean and the axis ranges. */
#include "cli/plot.h"
#include "cli/plot_private.h"

#include <math.h>
#include <plplot.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { PSF_MAX_GRID = 15, PSF_DECADES = 5, PSF_PAGE = 960 };

int wt_plot_psf_mosaic(wt_context *ctx, const char *path, const char *title, int g, const double *coords, int n,
                       double pixel_lod, const float *img, const double *strehl)
{
    if (g < 1 || g > PSF_MAX_GRID || n < 2 || n % 2 || !(pixel_lod > 0.0) || !isfinite(pixel_lod))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': PSF mosaic of %d x %d panels of %d pixels (%g lambda/D); "
                        "expected 1..%d panels per side, an even n >= 2 and a positive pixel", wt_plot_pname(path), g, g,
                        n, pixel_lod, PSF_MAX_GRID);
    if (!coords || !img || !strehl)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': PSF mosaic with a NULL array", wt_plot_pname(path));
    const long np = (long)n * n;
    for (long i = 0; i < np * g * g; i++)
        if (!isfinite(img[i]) || img[i] < 0.0f)
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': PSF value %ld of panel %ld is %g; expected finite and >= 0",
                            wt_plot_pname(path), i % np, i / np, (double)img[i]);
    const int s = n < WT_PLOT_PSF_SHOW ? n : WT_PLOT_PSF_SHOW, off = n / 2 - s / 2;
    const double half = 0.5 * s * pixel_lod; /* panel half-width [λ/D] */
    PLFLT **z = NULL;
    plAlloc2dGrid(&z, s, s);
    if (!z) return WT_ERROR(ctx, WT_ERR_NOMEM, "plot '%s': out of memory for a panel", wt_plot_pname(path));

    wt_plot_job j;
    int st = wt_plot_job_begin_size(&j, ctx, path, PSF_PAGE, PSF_PAGE - 40);
    if (st < 0) {
        plFree2dGrid(z, s, s);
        return st;
    }
    const double x0 = 0.10, x1 = 0.84, y0 = 0.10, y1 = 0.90, gap = 0.006;
    const double w = (x1 - x0) / g, h = (y1 - y0) / g;
    char txt[LABEL_MAX];
    for (int r = 0; r < g; r++)
        for (int c = 0; c < g; c++) {
            const float *p = img + np * (c + (long)g * r);
            for (int ix = 0; ix < s; ix++)
                for (int iy = 0; iy < s; iy++) {
                    const double v = p[(off + ix) + (long)n * (off + iy)];
                    z[ix][iy] = v > 0.0 ? fmax(log10(v), -PSF_DECADES) : -PSF_DECADES;
                }
            plvpor(x0 + c * w + gap, x0 + (c + 1) * w - gap, y0 + r * h + gap, y0 + (r + 1) * h - gap);
            plwind(-half, half, -half, half);
            plimage((PLFLT_MATRIX)z, s, s, -half, half, -half, half, -PSF_DECADES, 0.0, -half, half, -half, half);
            plcol0(C_FG);
            plbox("bc", 0.0, 0, "bc", 0.0, 0);
            plcol0(C_WHITE);
            plschr(0.0, fmax(0.45, fmin(1.0, 5.0 / g)));
            snprintf(txt, sizeof txt, "%.3f", strehl[c + g * r]);
            plmtex("t", -1.3, 0.05, 0.0, txt);
            plschr(0.0, 1.15);
        }
    plFree2dGrid(z, s, s);
    /* the whole mosaic's frame: field positions of the outer panels and the title */
    plvpor(x0, x1, y0, y1);
    plwind(0.0, 1.0, 0.0, 1.0);
    plcol0(C_FG);
    for (int i = 0; i < g && g <= 9; i++) {
        snprintf(txt, sizeof txt, "%g\"", coords[i]);
        plmtex("b", 1.2, (i + 0.5) / g, 0.5, txt);
        plmtex("lv", 0.5, (i + 0.5) / g, 1.0, txt);
    }
    snprintf(txt, sizeof txt, "field x; a panel: +-%.1f lambda/D (%.3g lambda/D per pixel)", half, pixel_lod);
    wt_plot_labels(txt, "field y", title);
    /* colour bar: log10 of I / I_diffraction-limited peak */
    wt_plot_colour_bar(-PSF_DECADES, 0.0, "log10 PSF (diffraction-limited peak = 0)", 1.0, 0.03, 0.0, 0.035, 1.0);
    return wt_plot_job_end(&j);
}

int wt_plot_wfe_frames(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                       long nframes, const double *wfe, int settle)
{
    enum { MAXM = 16 };
    if (nmethods < 1 || nmethods > MAXM || nframes < 2 || nframes > 100000000 || settle < 0 || settle >= nframes)
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': residual curves of %d methods x %ld frames, settle %d; expected "
                        "1..%d methods, 2 or more frames and settle below them", wt_plot_pname(path), nmethods, nframes,
                        settle, MAXM);
    if (!methods || !wfe) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': residual curves with a NULL array", wt_plot_pname(path));
    double lo = INFINITY, hi = 0.0;
    for (long i = 0; i < nmethods * nframes; i++) {
        if (isnan(wfe[i])) continue;
        if (!isfinite(wfe[i]) || wfe[i] <= 0.0)
            return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': residual of method %ld at frame %ld is %g nm; expected > 0 "
                            "(NaN: none)", wt_plot_pname(path), i / nframes, i % nframes, wfe[i]);
        lo = fmin(lo, wfe[i]), hi = fmax(hi, wfe[i]);
    }
    if (!(hi > 0.0)) return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': no residual to draw", wt_plot_pname(path));
    const double ylo = floor(log10(lo) * 10.0) / 10.0 - 0.05, yhi = ceil(log10(hi) * 10.0) / 10.0 + 0.05;
    double *x = malloc((size_t)nframes * sizeof *x), *y = malloc((size_t)nframes * sizeof *y);
    if (!x || !y) {
        free(x), free(y);
        return WT_ERROR(ctx, WT_ERR_NOMEM, "plot '%s': out of memory", wt_plot_pname(path));
    }
    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) {
        free(x), free(y);
        return st;
    }
    plvpor(0.11, 0.68, 0.12, 0.90);
    plwind(0.0, (double)nframes, ylo, yhi);
    if (settle > 0) { /* the settle window, left out of the long-exposure averages */
        PLFLT fx[4] = {0.0, settle, settle, 0.0}, fy[4] = {ylo, ylo, yhi, yhi};
        plcol0(C_MISSING);
        plfill(4, fx, fy);
    }
    /* a log axis labelled at 1, 2, 3, 5 x 10^k nm (PLplot's "l" labels the decades only) */
    wt_plot_axes("bcnst", "bc", "g", "");
    for (int e = (int)floor(ylo); e <= (int)ceil(yhi); e++)
        for (int k = 0; k < 4; k++) {
            static const double mant[4] = {1.0, 2.0, 3.0, 5.0};
            const double v = mant[k] * pow(10.0, e), ly = log10(v);
            if (ly < ylo || ly > yhi) continue;
            char lab[32];
            snprintf(lab, sizeof lab, "%g", v);
            plcol0(C_GRID);
            pljoin(0.0, ly, (double)nframes, ly);
            plcol0(C_FG);
            plmtex("lv", 0.6, (ly - ylo) / (yhi - ylo), 1.0, lab);
        }
    wt_plot_labels("frame", "", title);
    plmtex("l", 4.8, 0.5, 0.5, "residual WFE, field rms [nm]");
    for (long t = 0; t < nframes; t++) x[t] = (double)t;
    for (int m = 0; m < nmethods; m++) {
        const double *wm = wfe + (long)m * nframes;
        for (long t = 0; t < nframes; t++) y[t] = isnan(wm[t]) ? NAN : log10(wm[t]);
        plcol0(C_PAL + m % N_PAL);
        plwidth(0.7);
        pllsty(1);
        for (long t = 0; t + 1 < nframes; t++) /* per frame, thin (a NaN breaks it) */
            if (isfinite(y[t]) && isfinite(y[t + 1])) pljoin(x[t], y[t], x[t + 1], y[t + 1]);
        /* the running long-exposure value: sqrt of the mean of wfe² from the settle frame on */
        double acc = 0.0;
        long k = 0;
        for (long t = 0; t < nframes; t++) {
            if (t < settle || isnan(wm[t])) {
                y[t] = NAN;
                continue;
            }
            acc += wm[t] * wm[t], k++;
            y[t] = log10(sqrt(acc / k));
        }
        plwidth(2.4);
        long a0 = settle;
        while (a0 < nframes && !isfinite(y[a0])) a0++;
        long a1 = a0;
        while (a1 < nframes && isfinite(y[a1])) a1++;
        if (a1 - a0 >= 2) plline((PLINT)(a1 - a0), x + a0, y + a0);
    }
    plwidth(1.0);
    /* legend: the methods (thick), and what thin and thick mean */
    PLINT opt[MAXM + 3], tcol[MAXM + 3], lcol[MAXM + 3], lsty[MAXM + 3], bcol[MAXM + 3], bpat[MAXM + 3];
    PLFLT lwid[MAXM + 3], bscale[MAXM + 3], bwid[MAXM + 3];
    const char *text[MAXM + 3];
    char buf[MAXM][LABEL_MAX];
    int nl = 0;
    for (int m = 0; m < nmethods; m++, nl++) {
        text[nl] = wt_plot_escape(buf[m], sizeof buf[m], methods[m]);
        opt[nl] = PL_LEGEND_LINE, tcol[nl] = C_FG, lcol[nl] = C_PAL + m % N_PAL, lsty[nl] = 1, lwid[nl] = 2.4;
    }
    text[nl] = "each frame", opt[nl] = PL_LEGEND_LINE, tcol[nl] = C_FG, lcol[nl] = C_FG, lsty[nl] = 1, lwid[nl++] = 0.7;
    text[nl] = "running LE", opt[nl] = PL_LEGEND_LINE, tcol[nl] = C_FG, lcol[nl] = C_FG, lsty[nl] = 1,
    lwid[nl++] = 2.4;
    if (settle > 0)
        text[nl] = "settle window", opt[nl] = PL_LEGEND_COLOR_BOX, tcol[nl] = C_FG, lcol[nl] = C_FG, lsty[nl] = 1,
        lwid[nl++] = 1.0;
    for (int i = 0; i < nl; i++) bcol[i] = C_MISSING, bpat[i] = 0, bscale[i] = 0.8, bwid[i] = 1.0;
    PLFLT lw, lh;
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.10, C_BG, C_GRID, 1, 0, 0, nl,
             opt, 1.0, 0.95, 2.0, 0.0, tcol, text, bcol, bpat, bscale, bwid, lcol, lsty, lwid, NULL, NULL, NULL, NULL);
    free(x), free(y);
    return wt_plot_job_end(&j);
}

/* A sweep value as a label: a libconfig string without its quotes (into out, returned) */
static const char *unquote(char *out, size_t size, const char *value)
{
    const size_t n = strlen(value);
    const int q = n >= 2 && value[0] == '"' && value[n - 1] == '"';
    snprintf(out, size, "%.*s", q ? (int)n - 2 : (int)n, value + q);
    return out;
}

int wt_plot_wfe_run(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                    int nvalues, const char *const *values, long nframes, const double *wfe, int settle, int window,
                    const wt_plot_run_axis *axis, int ref)
{
    enum { MAXM = 8, MAXV = 5 };
    const double dt = axis ? axis->dx : 0.0, x0 = axis ? axis->x0 : 0.0;
    if (nmethods < 1 || nmethods > MAXM || nvalues < 1 || nvalues > MAXV || nframes < 2 || window < 1 ||
        window > nframes || settle < 0 || settle >= nframes || !(dt > 0.0) || !isfinite(x0) || !axis->xname ||
        ref < -1 || ref >= nvalues || (ref >= 0 && nvalues < 2))
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': %d methods x %d values x %ld frames, window %d, settle %d, dx %g, "
                        "reference value %d; expected 1..%d methods, 1..%d values, a window within the frames, dx > 0 and "
                        "a reference among 2 or more values", wt_plot_pname(path), nmethods, nvalues, nframes, window,
                        settle, dt, ref, MAXM, MAXV);
    const long nc = (long)nmethods * nvalues, np = nframes - window + 1;
    double *y = malloc((size_t)nc * np * sizeof *y), *x = malloc((size_t)np * sizeof *x);
    if (!y || !x) {
        free(y), free(x);
        return WT_ERROR(ctx, WT_ERR_NOMEM, "plot '%s': out of memory", wt_plot_pname(path));
    }
    double lo = INFINITY, hi = -INFINITY;
    for (long c = 0; c < nc; c++) { /* the trailing window's rms: point i covers frames i … i + window − 1 */
        const double *w = wfe + c * nframes;
        double acc = 0.0;
        long bad = 0;
        for (long t = 0; t < nframes; t++) {
            if (isfinite(w[t])) acc += w[t] * w[t];
            else bad++;
            if (t >= window) {
                if (isfinite(w[t - window])) acc -= w[t - window] * w[t - window];
                else bad--;
            }
            if (t >= window - 1) {
                y[c * np + t - window + 1] = bad ? NAN : sqrt(fmax(acc, 0.0) / window);
            }
        }
    }
    if (ref >= 0) /* each case minus its method's reference (the reference itself kept: it is not drawn) */
        for (int m = 0; m < nmethods; m++)
            for (int v = 0; v < nvalues; v++)
                for (long i = 0; i < np && v != ref; i++)
                    y[((long)m * nvalues + v) * np + i] -= y[((long)m * nvalues + ref) * np + i];
    for (long c = 0; c < nc; c++)
        for (long i = 0; i < np && (ref < 0 || c % nvalues != ref); i++)
            if (isfinite(y[c * np + i])) lo = fmin(lo, y[c * np + i]), hi = fmax(hi, y[c * np + i]);
    if (!(hi >= lo) || (ref < 0 && !(hi > 0.0))) {
        free(y), free(x);
        return WT_ERROR(ctx, WT_ERR_INVALID, "plot '%s': no residual to draw", wt_plot_pname(path));
    }
    if (ref >= 0) lo = fmin(lo, 0.0), hi = fmax(hi, 0.0); /* the reference's zero in view */
    for (long i = 0; i < np; i++) x[i] = x0 + (double)(i + window) * dt;
    const double pad = 0.05 * (hi - lo) + 1.0, ylo = ref >= 0 ? lo - pad : fmax(0.0, lo - pad), yhi = hi + pad;
    wt_plot_job j;
    int st = wt_plot_job_begin(&j, ctx, path);
    if (st < 0) {
        free(y), free(x);
        return st;
    }
    plvpor(0.11, 0.66, 0.12, 0.90);
    plwind(x0, x0 + (double)nframes * dt, ylo, yhi);
    if (settle > 0) {
        PLFLT fx[4] = {x0, x0 + settle * dt, x0 + settle * dt, x0}, fy[4] = {ylo, ylo, yhi, yhi};
        plcol0(C_MISSING);
        plfill(4, fx, fy);
    }
    wt_plot_axes("bcnstg", "bcnstgv", "g", "");
    char xl[96];
    snprintf(xl, sizeof xl, "%s (the end of a trailing %d-frame window)", axis->xname, window);
    wt_plot_labels(xl, "", title);
    if (ref >= 0) {
        char yl[LABEL_MAX + 64], bare[LABEL_MAX];
        snprintf(yl, sizeof yl, "field WFE over the window minus %s's [nm]", unquote(bare, sizeof bare, values[ref]));
        plmtex("l", 4.2, 0.5, 0.5, yl);
        plcol0(C_FG);
        pljoin(x0, 0.0, x0 + (double)nframes * dt, 0.0);
    } else
        plmtex("l", 4.2, 0.5, 0.5, "residual WFE, field rms over the window [nm]");
    static const PLINT style[MAXV] = {1, 3, 2, 4, 5}; /* solid, long dashes, short dashes, … (PLplot's 1 … 8) */
    for (long c = 0; c < nc; c++) {
        if (ref >= 0 && c % nvalues == ref) continue; /* its zero line is drawn above */
        plcol0(C_PAL + (int)(c / nvalues) % N_PAL);
        pllsty(style[c % nvalues]);
        plwidth(1.8);
        for (long i = 0; i + 1 < np; i++)
            if (isfinite(y[c * np + i]) && isfinite(y[c * np + i + 1]))
                pljoin(x[i], y[c * np + i], x[i + 1], y[c * np + i + 1]);
    }
    plwidth(1.0);
    pllsty(1);
    /* legend: the methods' colours, then the values' line styles */
    PLINT opt[MAXM + MAXV], tcol[MAXM + MAXV], lcol[MAXM + MAXV], lsty[MAXM + MAXV], bcol[MAXM + MAXV], bpat[MAXM + MAXV];
    PLFLT lwid[MAXM + MAXV], bscale[MAXM + MAXV], bwid[MAXM + MAXV];
    const char *text[MAXM + MAXV];
    char buf[MAXM + MAXV][LABEL_MAX];
    int nl = 0;
    for (int m = 0; m < nmethods; m++, nl++) {
        text[nl] = wt_plot_escape(buf[nl], sizeof buf[nl], methods[m]);
        opt[nl] = PL_LEGEND_LINE, tcol[nl] = C_FG, lcol[nl] = C_PAL + m % N_PAL, lsty[nl] = 1, lwid[nl] = 2.4;
    }
    for (int v = 0; v < nvalues && nvalues > 1; v++) {
        if (v == ref) continue; /* drawn as the zero line */
        char bare[LABEL_MAX];
        text[nl] = wt_plot_escape(buf[nl], sizeof buf[nl], unquote(bare, sizeof bare, values[v]));
        opt[nl] = PL_LEGEND_LINE, tcol[nl] = C_FG, lcol[nl] = C_FG, lsty[nl] = style[v], lwid[nl] = 1.8;
        nl++;
    }
    for (int i = 0; i < nl; i++) bcol[i] = C_MISSING, bpat[i] = 0, bscale[i] = 0.8, bwid[i] = 1.0;
    PLFLT lw, lh;
    pllegend(&lw, &lh, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
             PL_POSITION_OUTSIDE | PL_POSITION_RIGHT | PL_POSITION_VIEWPORT, 0.03, 0.0, 0.10, C_BG, C_GRID, 1, 0, 0, nl,
             opt, 1.0, 0.95, 2.0, 0.0, tcol, text, bcol, bpat, bscale, bwid, lcol, lsty, lwid, NULL, NULL, NULL, NULL);
    free(y), free(x);
    return wt_plot_job_end(&j);
}
