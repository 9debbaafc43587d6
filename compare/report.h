/* compare/report.h: the files of `wavetomo compare` (SPEC §10): DIR/results.h5 (every number, the plan
 * of its cases and which are done), DIR/summary.csv, DIR/report.md and the PNG figures; the check of every
 * one of them before the runs, and the reading of a previous results.h5 for --resume. */
#ifndef WT_COMPARE_REPORT_H
#define WT_COMPARE_REPORT_H

#include "cli/cli.h"
#include "core/sim/compare.h"

typedef struct wt_cmp_cases {
    char list[256], sweep[1024], key[128];
    char *methods[WT_COMPARE_MAXM], *values[WT_COMPARE_MAXV];
    int nm, nv;           /* methods; sweep values (0: no sweep, one column) */
    const char *out;      /* DIR */
    const char *seed;
    long frames;
    int resume;
} wt_cmp_cases;

/* Every file the command writes in DIR: not an input, not a foreign file (unless --force). */
int wt_cmp_check_outputs(wt_cli *cli, const wt_cmp_cases *a);
/* --resume: read DIR/results.h5, refuse it when its plan is not `want` (naming what differs), and copy the
 * cases it has done into R ([method * columns + value]). *ndone: how many. */
int wt_cmp_read_previous(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *want, wt_compare_result *R,
                         int *ndone);
/* results.h5, summary.csv, report.md and the figures; cases not done are marked missing in each. */
int wt_cmp_write_all(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                     const wt_system *sys, const wt_compare_result *R, int argc, char **argv);

#endif
