/* compare/compare.h: the reports: `wavetomo compare` (methods side by side in closed loop, compare/compare.c)
 * and `wavetomo budget` (the error budget, compare/budget.c). Each returns the process exit code. */
#ifndef WT_COMPARE_COMPARE_H
#define WT_COMPARE_COMPARE_H

int wt_cmd_compare(int argc, char **argv);
int wt_cmd_budget(int argc, char **argv);

#endif
