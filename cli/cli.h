/* cli/cli.h: what every wavetomo subcommand shares: the context with its hooks, the common options
 * (--config, --set, --threads), error reporting and the terminal progress line. Drivers are thin: they
 * read options, call the library, write files; numerical loops live in core/. */
#ifndef WT_CLI_H
#define WT_CLI_H

#include <stdio.h>

#include "core/base/base.h"
#include "core/io/config.h"

#define WT_CLI_MAX_SET 256

typedef struct wt_cli {
    wt_context *ctx;
    const char *prog;           /* "wavetomo info" … for messages */
    const char *config_path;
    int nset;
    const char *set[WT_CLI_MAX_SET];
    int threads;                /* 0: all */
    int quiet;
} wt_cli;

/* Create the context (log to stderr unless quiet). Returns NULL on allocation failure. */
int wt_cli_init(wt_cli *cli, const char *prog);
void wt_cli_done(wt_cli *cli);

/* Handle a common option at argv[*i] (--config F, --set k=v, --threads N, --quiet); advances *i past
 * its value. Returns 1 if handled, 0 if not a common option, -1 on a usage error (message printed). */
int wt_cli_common_option(wt_cli *cli, int argc, char **argv, int *i);
/* Print "PROG: error: <message>" for a failed status and return the process exit code (1). */
int wt_cli_fail(wt_cli *cli, int status);
/* Usage error: print the message and a hint to --help; returns 2. */
int wt_cli_usage_error(wt_cli *cli, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Read the configuration named by --config (or `path`) with the --set overrides. */
int wt_cli_read_config(wt_cli *cli, const char *path, wt_config **cfg);

/* Terminal progress line on stderr (only when stderr is a terminal): "label  done/total  rate/s  ETA". */
typedef struct wt_progress {
    int enabled;
    const char *label;
    const char *unit;
    long total;
    double start, last;
} wt_progress;
void wt_progress_start(wt_progress *p, const char *label, const char *unit, long total);
/* extra: optional text appended to the line (e.g. running Strehl), may be NULL */
void wt_progress_update(wt_progress *p, long done, const char *extra);
void wt_progress_end(wt_progress *p);

/* Subcommands */
int wt_cmd_info(int argc, char **argv);
int wt_cmd_bench(int argc, char **argv);



/* Shared pieces of the self-documenting output files (RUN.h5, TEL.h5, MATRIX.h5). */
struct wt_h5_writer;
struct wt_system;
/* Root attributes (wavetomo and HDF5 versions, creation time, command line, seed) and the dataset
 * "config" (the canonical configuration text the run used). */
int wt_cli_write_provenance(wt_cli *cli, struct wt_h5_writer *w, const wt_config *cfg, int argc, char **argv);
/* The slope and actuator orderings: group "layout". */
int wt_cli_write_layout(struct wt_h5_writer *w, const struct wt_system *sys);

int wt_cmd_sim(int argc, char **argv);

#endif
