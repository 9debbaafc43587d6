/* runtime/runtime.h: `wavetomo run` (a reconstructor over telemetry, runtime/run.c) and `wavetomo learn` (the
 * profile identified from telemetry, runtime/learn.c). Each returns the process exit code. */
#ifndef WT_RUNTIME_RUNTIME_H
#define WT_RUNTIME_RUNTIME_H

int wt_cmd_run(int argc, char **argv);
int wt_cmd_learn(int argc, char **argv);

#endif
