/* cli/cli.h: what every wavetomo subcommand shares: the context with its hooks, the common options
 * (--config, --set, --threads), error reporting and the terminal progress line. Drivers are thin: they
 * read options, call the library, write files; numerical loops live in core/. */
#ifndef WT_CLI_H
#define WT_CLI_H

#include <stdio.h>

#include "core/base/base.h"
#include "core/config/config.h"

#define WT_CLI_MAX_SET 256

typedef struct wt_cli {
    wt_context *ctx;
    const char *prog;           /* "wavetomo info" … for messages */
    void (*help)(void);         /* prints the command's --help text */
    const char *config_path;
    int nset;
    const char *set[WT_CLI_MAX_SET];
    int threads;                /* 0: all */
    int quiet;
    long frames;                /* --frames of the run commands (0: the config's) */
    char frames_set[64], seed_set[64], settle_set[64]; /* storage of the overrides they become */
    int force;                  /* --force: replace an existing file that is not a wavetomo output */
    int dry_run;                /* --dry-run: print the resource estimate and stop */
    double max_memory;          /* --max-memory SIZE [bytes]; 0: the memory available */
    int noutputs;               /* outputs checked so far (wt_cli_check_output) */
    char outputs[4][4096];      /* their resolved paths */
    char preset_path[4096];     /* a preset name resolved to its file (wt_cli_read_config) */
} wt_cli;

/* Create the context (log to stderr unless quiet). Non-zero on allocation failure (message printed). */
int wt_cli_init(wt_cli *cli, const char *prog, void (*help)(void));
void wt_cli_done(wt_cli *cli);

/* Handle a common option at argv[*i] (--config F, --set k=v, --threads N, --quiet); advances *i past
 * its value. Returns 1 if handled, 0 if not a common option, -1 on a usage error (message printed). */
int wt_cli_common_option(wt_cli *cli, int argc, char **argv, int *i);
/* A command's own arguments: return 1 when argv[*i] was taken (advancing *i past a value it consumed),
 * 0 when it is not one of the command's (an "unknown option" / "unexpected argument" error follows),
 * or -1 after reporting a usage error with wt_cli_usage_error. */
typedef int (*wt_cli_option_fn)(wt_cli *cli, int argc, char **argv, int *i, void *user);
/* Parse argv[1..]: the common options, --help/-h (prints cli->help), then `fn` for the rest, and a word that
 * neither took (not starting with '-') as CONFIG, the same as --config. Returns -1 to go on with the command,
 * or the exit code to stop with (0 after --help, 2 on a usage error). */
int wt_cli_parse(wt_cli *cli, int argc, char **argv, wt_cli_option_fn fn, void *user);
/* CONFIG, positional or --config: arg becomes *path the first time (1); a second one is a usage error naming
 * both (-1). */
int wt_cli_config_arg(wt_cli *cli, const char *arg, const char **path);
/* The value of option argv[*i]: argv[*i + 1] (advancing *i), or NULL after reporting a usage error. */
const char *wt_cli_value(wt_cli *cli, int argc, char **argv, int *i);
/* Parse an integer in [lo, hi] for option `name`; reports a usage error and returns -1 when it is not. */
int wt_cli_int(wt_cli *cli, const char *name, const char *text, long lo, long hi, long *out);
/* A finite number in [lo, hi], the whole text (no overflow to Inf, no trailing text); -1 after a usage
 * error naming the option. */
int wt_cli_double(wt_cli *cli, const char *name, const char *text, double lo, double hi, double *out);
/* Split s in place at commas into items (at most max); an empty item ("1,,3", a trailing comma) or too
 * many items is a usage error naming the option: returns -1, else the number of items. */
int wt_cli_split(wt_cli *cli, const char *name, char *s, char **items, int max);
/* Before writing output `path`: refuse when it is the configuration (--config) or in1/in2
 * (other inputs, may be NULL) — same device and inode, or the same resolved path — or an output checked
 * before; refuse to replace an existing file that is not a wavetomo output unless --force; then
 * wt_h5_check_writable(path, bytes). Returns a status (message in the context), like the library. */
int wt_cli_check_output(wt_cli *cli, const char *path, int64_t bytes, const char *in1, const char *in2);
/* The same for a text or image output (summary.csv, report.md, a PNG): an existing file is replaced only
 * when it starts with `signature` and, when `owner` is given, that file is a wavetomo HDF5 output. */
int wt_cli_check_text_output(wt_cli *cli, const char *path, const char *signature, const char *owner);
/* Issue 10, C: the resource estimate of the command (core/model/estimate.h) before it allocates: with
 * --dry-run print it to stdout and return 0 (exit code: stop); refuse it (message naming the estimate and
 * its keys, return 1) when it exceeds --max-memory or the memory available now (MemAvailable); else
 * print its first line on stderr (unless --quiet) and return -1: go on. */
struct wt_estimate;
int wt_cli_resources(wt_cli *cli, const struct wt_estimate *e);
/* The same for one command: task WT_TASK_* and reconstructor WT_RECON_* on cfg for its loop.frames, with
 * `iterations` (P)CG iterations per frame (≤ 0: the variant's; --iters). */
int wt_cli_estimate(wt_cli *cli, const wt_config *cfg, int task, int recon, int iterations);
/* Print "PROG: error: <message>" for a failed status and return the process exit code (1). */
int wt_cli_fail(wt_cli *cli, int status);
/* Usage error: print the message and a hint to --help; returns 2. */
int wt_cli_usage_error(wt_cli *cli, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* The run shortcuts --frames N and --seed S (NULL/≤ 0: not given) become the overrides loop.frames and
 * sim.seed, so the stored configuration says what ran. Returns 0, or 2 after a usage error. */
int wt_cli_run_overrides(wt_cli *cli, long frames, const char *seed);
/* Read the configuration named by --config (or `path`) with the --set overrides. When --frames made
 * the run too short for evaluation.settle_frames, the settle period becomes frames/2 (with a note). */
int wt_cli_read_config(wt_cli *cli, const char *path, wt_config **cfg);

/* Progress on stderr, "label  done/total  rate/s  ETA": a line rewritten in place on a terminal, else (a log) a
 * line every WT_PROGRESS_LOG_S seconds of the run. enabled: 1 terminal, 2 log. */
#define WT_PROGRESS_LOG_S 60.0
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
/* Progress through a library's named phases (the callbacks of builder/mvm_build.h and core/model/learn.h: phase,
 * steps done, of total): a new phase ends the last one's line. Start with {.quiet = cli.quiet}; pass the object as
 * the callback's user. */
typedef struct wt_progress_phases {
    wt_progress pr;
    char phase[48];
    int quiet;
} wt_progress_phases;
void wt_progress_phase(void *user, const char *phase, int64_t done, int64_t total);
void wt_progress_phases_end(wt_progress_phases *pp);




/* Shared pieces of the self-documenting output files (RUN.h5, TEL.h5, MATRIX.h5). */
struct wt_h5_writer;
struct wt_system;
/* Root attributes (wavetomo and HDF5 versions, creation time, command line, seed) and the dataset
 * "config" (the canonical configuration text the run used). */
int wt_cli_write_provenance(wt_cli *cli, struct wt_h5_writer *w, const wt_config *cfg, int argc, char **argv);
/* The slope and actuator orderings: group "layout"; and the truth's and the reconstructors' atmospheres:
 * groups "atmosphere" and "model_atmosphere" (docs/formats.md). */
int wt_cli_write_layout(struct wt_h5_writer *w, const struct wt_system *sys);

/* The configurations of a telemetry file (run, learn): *tcfg = the one it was recorded with (its dataset
 * "config"; without --config the --set overrides apply to it), *cfg = --config's (NULL without one: the caller
 * compares the two as its use requires). A file without "config" is refused, naming it. Both owned by the
 * caller (wt_config_free). */
struct wt_h5_reader;
int wt_cli_telemetry_config(wt_cli *cli, struct wt_h5_reader *tr, const char *tel, wt_config **tcfg, wt_config **cfg);

/* mkdir -p: the directory and its missing parents (cli/output.c). */
int wt_cli_ensure_dir(wt_context *ctx, const char *path);

#endif
