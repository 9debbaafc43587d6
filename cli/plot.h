/* cli/plot.h: the PNG figures of a comparison report, drawn with PLplot (pngcairo driver).
 * Driver-level code: PLplot keeps global state, so these functions are not thread-safe and are only
 * called from the `wavetomo compare` driver. Each returns WT_OK or an error status with a message in
 * ctx naming the file. */
#ifndef WT_PLOT_H
#define WT_PLOT_H

#include "core/base/base.h"

/* LE Strehl against the swept value for each method: on-axis solid, field average dashed, one colour
 * per method, legend, axis labels (x label: the swept key's meaning and unit; a second line after a '\n', smaller), title. on_axis/field: [nmethods][nvalues]
 * row-major; on_err/field_err: the same shape, error bars ± the value (NULL: none). log_x: logarithmic x
 * axis (e.g. for α). */
int wt_plot_strehl_sweep(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nmethods,
                         const char *const *methods, int nvalues, const double *x, const double *on_axis,
                         const double *field, const double *on_err, const double *field_err, int log_x);
/* The same with the values named (names[nvalues], e.g. a categorical sweep's "false", "learned": each under its
 * point, at its x, and no numbers on the x axis); names NULL: wt_plot_strehl_sweep. */
int wt_plot_strehl_sweep_named(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nmethods,
                               const char *const *methods, int nvalues, const double *x, const char *const *names,
                               const double *on_axis, const double *field, const double *on_err, const double *field_err,
                               int log_x);

/* The guide stars drawn on the field maps: directions [arcsec] (x right, y up), LGS a star, NGS a triangle, with
 * a legend; the map's window widens to hold them. A NULL wt_plot_stars draws none. */
typedef struct wt_plot_stars {
    int nlgs, nngs;
    const double *lgs_x, *lgs_y; /* [nlgs] */
    const double *ngs_x, *ngs_y; /* [nngs] */
} wt_plot_stars;

/* cli/plot_maps.c: a g x g map of LE Strehl over the field (index i + g j, x = column, y = row, in arcsec at
 * positions coords[0..g-1]), with a colour bar, each cell's value printed and the guide stars (may be NULL); one PNG
 * per call. vmin/vmax fix the colour scale so that maps of several methods compare (pass the same range). */
int wt_plot_strehl_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                       const double *strehl, double vmin, double vmax, const wt_plot_stars *stars);

/* cli/plot_maps.c: the same map of a difference between two methods (diff[i + g j], NaN: missing) on a diverging
 * blue-white-red scale symmetric about zero ([-max|d|, max|d|]), the colour bar labelled bar_label (with its unit),
 * each cell printed with fmt (one number conversion, e.g. "%+.1f"). */
int wt_plot_diff_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                     const double *diff, const char *bar_label, const char *fmt, const wt_plot_stars *stars);

/* Stacked bars: time per frame of each method [ms], stacked by part
 * (nparts parts named parts[k], times[m * nparts + k]). */
int wt_plot_time_bars(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                      int nparts, const char *const *parts, const double *times);

/* Grouped bars: one group per x label (groups[k]), one bar per series (colour, legend), values
 * [k * nseries + s] (NaN or 0: no bar; negative: drawn hatched at its magnitude, and a line under the title says
 * so), each labelled with its
 * value; marks (may be NULL): a thick black tick at that height over the bar (e.g. an analytic estimate). */
int wt_plot_grouped_bars(wt_context *ctx, const char *path, const char *title, const char *ylabel, int ngroups,
                         const char *const *groups, int nseries, const char *const *series, const double *values,
                         const double *marks);

/* Long-exposure PSFs over the field: a g x g mosaic, panel i + g j at field column i (x right) and
 * row j (y up) as wt_plot_strehl_map, each the central part (at most WT_PLOT_PSF_SHOW pixels across) of the n x n
 * image img[(i + g j) n²] (pixel (ix, iy) at ix + n iy, x right, y up; sim/psf.h), in log10 over 5 decades
 * below the diffraction-limited peak (= 1), with the panel's PSF-peak Strehl strehl[i + g j] printed in it and a
 * colour bar; coords: the field positions [arcsec] of the g columns/rows; pixel_lod: the pixel [λ/D] (axis scale). */
#define WT_PLOT_PSF_SHOW 64
int wt_plot_psf_mosaic(wt_context *ctx, const char *path, const char *title, int g, const double *coords, int n,
                       double pixel_lod, const float *img, const double *strehl);

/* Residual WFE per frame [nm] of each method (wfe[m * nframes + t]; NaN: none), thin, with its running
 * long-exposure value sqrt(mean of wfe² over frames settle..t) thick from the settle frame on, on a log y axis;
 * the settle window [0, settle) shaded. */
int wt_plot_wfe_frames(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                       long nframes, const double *wfe, int settle);

/* Every case's residual over the run, smoothed: the rms of the field WFE over a trailing window of `window` frames
 * [nm] (wfe[(m * nvalues + v) * nframes + t], NaN: none) against x0 + t · dx in the unit of xname (simulated
 * seconds, or night minutes for a changing night), one colour per method, one line style per sweep value (values:
 * their labels); the settle window shaded. ref ≥ 0: each case minus its method's case at value ref (the oracle of a
 * learned atmosphere: what each model costs at a glance), the reference's own zero line left out. For the runs
 * whose model changes (a learned atmosphere, a night): which method follows, and when. */
typedef struct wt_plot_run_axis {
    double x0, dx;     /* x of frame 0 and per frame */
    const char *xname; /* "time [s]", "night time [min]" */
} wt_plot_run_axis;
int wt_plot_wfe_run(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                    int nvalues, const char *const *values, long nframes, const double *wfe, int settle, int window,
                    const wt_plot_run_axis *axis, int ref);

/* cli/plot_series.c: estimates over time against the truth, in npanels (1..4) stacked panels sharing the x axis
 * (xlabel under the last): in each, series s (1..8, names[s], one colour and marker in every panel) as markers at
 * (x[s][i], y[s][i]) joined by a thin line, with error bars ± e[s][i] (e or e[s] NULL, or a value ≤ 0: none), and
 * the truth as a thick black line through (tx[i], ty[i]) (nt < 2: none), optionally each series' own reference
 * dashed in its colour (nr[s] < 2: none; the legend names it `refname`). Non-finite points are skipped; a panel
 * without any finite value is an empty frame; at least one finite point overall. */
typedef struct wt_plot_series_panel {
    const char *ylabel;
    const int *n;                                  /* [nseries] points of each series in this panel (0: none) */
    const double *const *x, *const *y, *const *e; /* [nseries] arrays of n[s] values */
    int nt;                                        /* the truth's points */
    const double *tx, *ty;
    const int *nr;                                 /* NULL, or [nseries] points of each series' own reference, drawn
                                                      dashed in its colour (e.g. the truth as that method can hold it) */
    const double *const *rx, *const *ry;
} wt_plot_series_panel;
int wt_plot_series(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nseries,
                   const char *const *names, const char *refname, int npanels, const wt_plot_series_panel *panels);

/* ---- pupil pictures of one Shack–Hartmann sensor (`wavetomo info --spots`) ---------------------- */

/* Where the subapertures are: the valid subapertures' centres and side, the annulus outline, the launch. */
typedef struct wt_plot_pupil {
    int nsub;                     /* valid subapertures */
    const double *xc, *yc;        /* [nsub] centres in the pupil [m] (x right, y up) */
    double side;                  /* subaperture side d [m] */
    double diameter;              /* telescope diameter D [m] (outline) */
    double obstruction;           /* central obstruction as a fraction of D [-] (outline) */
    int has_launch;               /* 1: mark the laser launch position (launch_x, launch_y) [m] */
    double launch_x, launch_y;
} wt_plot_pupil;

/* Truncation levels the spot mosaic frames (fractions of a subaperture's flux outside its detector field). */
#define WT_PLOT_TRUNC_LEVELS 3
extern const double wt_plot_trunc_levels[WT_PLOT_TRUNC_LEVELS]; /* 0.001, 0.01, 0.1 */

/* The page of wt_plot_spots [px]: an integer number s >= 1 of screen pixels per detector pixel (s = 1 from
 * about 1000 detector pixels across the window on), one screen pixel of gap between cells, the window
 * holding the pupil and the launch; margins for the title, the colour bar and the legend. */
void wt_plot_spots_page(const wt_plot_pupil *p, int ns, int *width, int *height);

/* The spot mosaic: every valid subaperture's ns x ns image (img [nsub·ns²], pixel (ix, iy) at ix + ns·iy, x
 * right, y up, as core/optics/spot.h) in its cell over the pupil, on a linear grey scale of I / I_max
 * (I_max: the subaperture's own peak when normalise, else the brightest pixel of all; the colour bar says
 * which); subaperture k framed in the colour of the highest level of wt_plot_trunc_levels that trunc[k]
 * exceeds (trunc may be NULL); the launch marked. title and note: two lines above. Draws only the pixels
 * brighter than the scale's first step, merged in runs of one colour (the E-ELT's 84 x 84 x 16² pixels in
 * about a second). A big mosaic (s <= 2) gets three zoomed insets beside it: the subapertures nearest to the
 * launch, farthest from it, and the worst truncated (or those across the launch direction), marked on it. */
int wt_plot_spots(wt_context *ctx, const char *path, const char *title, const char *note, const wt_plot_pupil *p,
                  int ns, const float *img, int normalise, const double *trunc);

/* One or two maps of a value per subaperture over the pupil, side by side (1500 x 720 px; one: 900 x 650), each
 * with its colour bar (label: its meaning and units) and subtitle (a newline splits it in two lines); values[m][k]
 * of subaperture k (NaN: grey); the launch a star (the title may say so). The
 * colour range of map m is [range[2m], range[2m+1]] where finite (range may be NULL), else its values' range
 * (widened to ±1 % of the value when they are all equal). */
int wt_plot_pupil_maps(wt_context *ctx, const char *path, const char *title, const wt_plot_pupil *p, int nmaps,
                       const double *const *values, const double *range, const char *const *subtitles,
                       const char *const *bar_labels);

#endif
