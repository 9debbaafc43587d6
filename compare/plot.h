/* compare/plot.h: the PNG figures of a comparison report, drawn with PLplot (pngcairo driver).
 * Driver-level code: PLplot keeps global state, so these functions are not thread-safe and are only
 * called from the `wavetomo compare` driver. Each returns WT_OK or an error status with a message in
 * ctx naming the file. */
#ifndef WT_PLOT_H
#define WT_PLOT_H

#include "core/base/base.h"

/* LE Strehl against the swept value for each method: on-axis solid, field average dashed, one colour
 * per method, legend, axis labels (x label = the swept key), title. on_axis/field: [nmethods][nvalues]
 * row-major; on_err/field_err: the same shape, error bars ± the value (NULL: none). log_x: logarithmic x
 * axis (e.g. for α). */
int wt_plot_strehl_sweep(wt_context *ctx, const char *path, const char *title, const char *xlabel, int nmethods,
                         const char *const *methods, int nvalues, const double *x, const double *on_axis,
                         const double *field, const double *on_err, const double *field_err, int log_x);

/* A g x g map of LE Strehl over the field (index i + g j, x = column, y = row, in arcsec at positions
 * coords[0..g-1]), with a colour bar and each cell's value printed; one PNG per call. vmin/vmax fix
 * the colour scale so that maps of several methods compare (pass the same range). */
int wt_plot_strehl_map(wt_context *ctx, const char *path, const char *title, int g, const double *coords,
                       const double *strehl, double vmin, double vmax);

/* Stacked bars: time per frame of each method [ms], stacked by part
 * (nparts parts named parts[k], times[m * nparts + k]). */
int wt_plot_time_bars(wt_context *ctx, const char *path, const char *title, int nmethods, const char *const *methods,
                      int nparts, const char *const *parts, const double *times);

/* Grouped bars: one group per x label (groups[k]), one bar per series (colour, legend), values
 * [k * nseries + s] (NaN or 0: no bar; negative: drawn hatched at its magnitude), each labelled with its
 * value; marks (may be NULL): a thick black tick at that height over the bar (e.g. an analytic estimate). */
int wt_plot_grouped_bars(wt_context *ctx, const char *path, const char *title, const char *ylabel, int ngroups,
                         const char *const *groups, int nseries, const char *const *series, const double *values,
                         const double *marks);

#endif
