/* compare/report.h: the files of `wavetomo compare` (SPEC §10): DIR/results.h5 (every number, the plan
 * of its cases and which are done), DIR/summary.csv, DIR/report.md and the PNG figures; the check of every
 * one of them before the runs, and the reading of a previous results.h5 for --resume. */
#ifndef WT_COMPARE_REPORT_H
#define WT_COMPARE_REPORT_H

#include "cli/cli.h"
#include "compare/compare.h"

typedef struct wt_compare_cases {
    char list[256], sweep[1024], key[128];
    char *methods[WT_COMPARE_MAXM], *values[WT_COMPARE_MAXV];
    int nm, nv;           /* methods; sweep values (0: no sweep, one column) */
    const char *out;      /* DIR */
    const char *seed;
    long frames;
    int resume;
    long nseeds;          /* --seeds N (0: not given) */
    int ns;               /* seeds per method and sweep value (1: the configuration's sim.seed) */
    uint64_t seeds[WT_COMPARE_MAXS];
    char spots[16];       /* the diffractive sensor whose pictures (compare/report_spots.h) are in DIR ("": none) */
} wt_compare_cases;

/* What the cases keep for the figures beside their numbers, per case (wt_compare_case index; NULL: none), all
 * allocated in the command's context: the field-rms residual of every frame [nm] (R[c].frames values), the
 * long-exposure PSFs [neval n n] (n = R[c].psf_pixels; sim/psf.h) and the learning loop's record of updates
 * (sim/adapt.h; kept by the rank that ran the case, not gathered over MPI nor read back by --resume). */
typedef struct wt_compare_extra {
    double **wfe;
    float **psf;
    struct wt_adapt **learned; /* the record of a loop that learned its atmosphere (sim's learned/; wt_adapt_free) */
} wt_compare_extra;

/* Index of the case (method m, sweep value v, seed s) in the per-seed result arrays. */
static inline int wt_compare_case(const wt_compare_cases *a, int m, int v, int s)
{
    return (m * (a->nv ? a->nv : 1) + v) * a->ns + s;
}

/* Every file the command writes in DIR: not an input, not a foreign file (unless --force). */
int wt_compare_check_outputs(wt_cli *cli, const wt_compare_cases *a);
/* --resume: read DIR/results.h5, refuse it when its plan is not `want` (naming what differs), and copy the
 * cases it has done into R (per seed, indexed by wt_compare_case). *ndone: how many. */
int wt_compare_read_previous(wt_cli *cli, const wt_compare_cases *a, const wt_compare_plan *want, wt_compare_result *R,
                         wt_compare_extra *X, int *ndone);
/* compare/report_maps.c: the maps over the evaluation field. check: their files (owner: results.h5);
 * markdown: their links in report.md (differences = 0: the Strehl maps', 1: the section of the differences); maps: draw them (each done case's LE Strehl on one scale, and each method's
 * residual WFE minus the first method's), the guide stars marked; coords: the g field positions [arcsec]. */
int wt_compare_check_map_outputs(wt_cli *cli, const wt_compare_cases *a, const char *owner);
void wt_compare_maps_markdown(FILE *f, const wt_compare_cases *a, const wt_compare_summary *S, int differences);
int wt_compare_maps(wt_cli *cli, const wt_compare_cases *a, const wt_system *sys, const wt_compare_summary *S,
                const double *coords);
/* compare/report_learned.c: the learned atmosphere (the cases whose loop estimated it: sim/adapt.h records).
 * check: its files learned_V.png (owner: results.h5); markdown: its section in report.md (a table of the estimates'
 * r0 and θ0 errors against the truth, the links), nothing without a record; plots: draw them. */
int wt_compare_check_learned_outputs(wt_cli *cli, const wt_compare_cases *a, const char *owner);
void wt_compare_learned_markdown(FILE *f, wt_context *ctx, const wt_compare_cases *a, const wt_config *cfg,
                                 const wt_compare_result *R, const wt_compare_extra *X);
int wt_compare_learned_plots(wt_cli *cli, const wt_compare_cases *a, const wt_config *cfg, const wt_compare_result *R,
                             const wt_compare_extra *X);
/* results.h5, summary.csv, report.md and the figures from the per-seed results R; with several seeds the
 * tables and curves show the mean ± standard error over the seeds and the paired differences between the
 * methods (compare/compare.h), results.h5 keeps every seed's values; cases not done are marked missing. */
int wt_compare_write_all(wt_cli *cli, const wt_compare_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                     const wt_system *sys, const wt_compare_result *R, const wt_compare_extra *X, int argc, char **argv);

#endif
