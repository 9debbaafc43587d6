/* builder/cmd_learn_wind.h: the wind part of `wavetomo learn` (builder/cmd_learn_wind.c): its tables and datasets. */
#ifndef WT_BUILDER_CMD_LEARN_WIND_H
#define WT_BUILDER_CMD_LEARN_WIND_H

#include "core/config/config.h"
#include "core/io/h5.h"
#include "core/model/learn.h"

/* Print the wind per fitted altitude, per reconstructor layer (pcg3's, cg9's) and on the truth's layers (tcfg's),
 * the truth's wind compressed the same way beside; fit_s the fit's time [s] */
void wt_learn_wind_print(const wt_learn_wind *wd, const wt_config *use, const wt_config *tcfg, double fit_s);
/* Write group estimate/wind (per altitude), estimate/{pcg3,cg9}/wind_*, truth/{grid,pcg3,cg9,layers}/wind_* */
int wt_learn_wind_write(wt_h5_writer *w, const wt_learn_wind *wd, const wt_config *use, const wt_config *tcfg);
/* A bar chart at path (PNG) of the wind on the truth tcfg's layers (the estimate compressed onto them as printed):
 * the estimated and the true speed and the vector error, each layer labelled with its direction error, the title counting the layers with >= 5 % of the Cn² within 1 m/s and 10 deg. */
int wt_learn_wind_plot(wt_context *ctx, const char *path, const wt_learn_wind *wd, const wt_config *tcfg);

#endif
