/* cli/plot_private.h: what the figure files of compare/ share (cli/plot.c: the report's figures,
 * cli/plot_pupil.c: the pupil pictures of a sensor): the PLplot job (a stream of its own drawn to a
 * temporary PNG and renamed onto the path; see plot.c's header), the colours and the label helpers. */
#ifndef WT_PLOT_PRIVATE_H
#define WT_PLOT_PRIVATE_H

#include <plplot.h>
#include <stddef.h>

#include "core/base/base.h"

/* Page size [px]: wide enough for a legend beside the axes, readable when scaled to a report column. */
enum { PAGE_W = 900, PAGE_H = 650 };

/* cmap0 (the discrete colours). 0 is the background. */
enum { C_BG = 0, C_FG = 1, C_GRID = 2, C_MISSING = 3, C_WHITE = 4, C_PAL = 5, N_PAL = 10 };
extern const PLINT wt_plot_cmap0[C_PAL + N_PAL][3];

/* Viridis control points for cmap1 (perceptually uniform, readable in grey): position, r, g, b. */
enum { N_VIRIDIS = 9 };
extern const double wt_plot_viridis[N_VIRIDIS][4];

enum { LABEL_MAX = 256, ERRMSG_MAX = 2048 };

typedef struct wt_plot_job {
    wt_context *ctx;
    const char *path;
    char tmp[4096 + 32];
    PLINT prev_stream;
    int stream_open;
    PLINT errcode;          /* set to nonzero by plabort through plsError */
    char errmsg[ERRMSG_MAX]; /* plabort's message (it writes without a bound: keep this generous) */
} wt_plot_job;


/* Check the path, create the temporary, open a fresh stream on it and start a page of w x h px (900 x 650
 * for wt_plot_job_begin); wt_plot_job_end closes the stream, checks the PNG and renames it onto the path; wt_plot_job_abort drops
 * the stream and the temporary after an error. */
int wt_plot_job_begin_size(wt_plot_job *j, wt_context *ctx, const char *path, int w, int h);
int wt_plot_job_begin(wt_plot_job *j, wt_context *ctx, const char *path);
int wt_plot_job_end(wt_plot_job *j);
void wt_plot_job_abort(wt_plot_job *j);
/* '#' doubled (PLplot's escape character); truncates to the buffer. */
const char *wt_plot_escape(char *dst, size_t n, const char *src);
/* Axes with a light grid; x label, y label and title of the current viewport. */
void wt_plot_axes(const char *xopt, const char *yopt, const char *xgrid, const char *ygrid);
void wt_plot_labels(const char *xlabel, const char *ylabel, const char *title);
/* A labelled shaded colour bar of cmap1 from vmin to vmax right of the viewport (plot.c). */
void wt_plot_colour_bar(double vmin, double vmax, const char *label, double tick, double offset, double yoff,
                        double width, double length);
/* Relative luminance of cmap1 (wt_plot_viridis) at t in [0, 1]: black or white text on it. */
double wt_plot_viridis_luminance(double t);
const char *wt_plot_pname(const char *path);

#endif
