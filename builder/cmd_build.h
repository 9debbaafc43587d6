/* builder/cmd_build.h: the offline side's commands: `wavetomo build`, the MVM builder (the planner: CHOLMOD
 * factorisation, control matrix MATRIX.h5; builder/cmd_build.c), `wavetomo learn`, the profile a matrix is built for,
 * identified from telemetry (builder/cmd_learn.c), and the matrix cache the comparison commands share. Each command
 * returns the process exit code. */
#ifndef WT_BUILDER_CMD_BUILD_H
#define WT_BUILDER_CMD_BUILD_H

#include "cli/cli.h"

int wt_cmd_build(int argc, char **argv);
int wt_cmd_learn(int argc, char **argv);

/* The MVM (pcg3 layers) of cfg: read from DIR/cache/mvm-pcg3-<hash>.h5 when it matches, else built and
 * cached there (DIR/cache must exist); *build_s: the build time (0 from the cache). */
struct wt_mvm;
struct wt_system;
int wt_build_mvm_cached(wt_cli *cli, const char *dir, wt_config *cfg, struct wt_system *sys, int argc, char **argv,
                        struct wt_mvm **out, double *build_s);

#endif
