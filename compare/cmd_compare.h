/* compare/cmd_compare.h: the experiments' commands: `wavetomo compare` (methods side by side in closed loop,
 * compare/cmd_compare.c), `wavetomo budget` (the error budget, compare/cmd_budget.c) and `wavetomo bench` (kernel
 * timings, compare/cmd_bench.c). Each returns the process exit code. */
#ifndef WT_COMPARE_CMD_COMPARE_H
#define WT_COMPARE_CMD_COMPARE_H

int wt_cmd_compare(int argc, char **argv);
int wt_cmd_budget(int argc, char **argv);
int wt_cmd_bench(int argc, char **argv);

#endif
