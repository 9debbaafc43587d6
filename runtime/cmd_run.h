/* runtime/cmd_run.h: `wavetomo run`, a reconstructor over the frames of a telemetry file (runtime/cmd_run.c).
 * Returns the process exit code. */
#ifndef WT_RUNTIME_CMD_RUN_H
#define WT_RUNTIME_CMD_RUN_H

int wt_cmd_run(int argc, char **argv);

#endif
