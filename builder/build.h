/* builder/build.h: `wavetomo build`, the offline MVM builder (the planner: CHOLMOD factorisation, control
 * matrix MATRIX.h5). Returns the process exit code. */
#ifndef WT_BUILDER_BUILD_H
#define WT_BUILDER_BUILD_H

int wt_cmd_build(int argc, char **argv);

#endif
