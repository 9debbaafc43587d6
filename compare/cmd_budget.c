/* compare/cmd_budget.c: `wavetomo budget`: the error budget of SPEC §11 (compare/budget.h) for one or more
 * reconstructors: DIR/results.h5, DIR/report.md and DIR/budget.png. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "compare/cmd_compare.h"
#include "builder/cmd_build.h"
#include "cli/cli.h"
#include "cli/plot.h"
#include "core/io/h5.h"
#include "core/solve/mvm.h"
#include "core/model/params.h"
#include "core/model/reconstructor.h"
#include "compare/budget.h"
#include "core/model/estimate.h"

#define MAXM 3

static void help(void)
{
    printf("usage: wavetomo budget [--config] FILE [--set key=value]... [--recon cg9,pcg3,mvm] [--frames N]\n"
           "                       [--seed S] [--threads N] --out DIR\n"
           "\n"
           "Error budget of the residual over the field (mean over the evaluation directions, frames after\n"
           "the settle period), each term measured by runs on the same seed that remove one cause: fitting\n"
           "(the DMs fitted to the true turbulence, no sensors), tomography + aliasing + model error (open\n"
           "loop, noise-free, no delay), noise (open loop and closed loop), servo lag (closed loop with exact\n"
           "POLC vs open loop), the POLC model error (the model's interaction vs exact POLC), tip-tilt and\n"
           "pupil rim (outer 1 m) of the closed loop, and the total (closed loop with noise),\n"
           "with the analytic estimates and a quadrature closure check. Writes DIR/results.h5,\n"
           "DIR/report.md and DIR/budget.png. Per method: 6 runs (3 without noise), plus one fitting run.\n"
           "With recon.predict = true the instantaneous runs do not predict, and one more closed loop (exact\n"
           "POLC, no prediction) splits the servo lag: servo_no_predict, servo_predicted (the lag prediction\n"
           "removed) and servo (what it leaves); the report adds the analytic, band-limited lag with the\n"
           "method's layers moved by their compressed winds and with each atmospheric layer moved by its own:\n"
           "their difference is the part no shift of the method's layers removes.\n"
           "\n"
           "  --recon LIST   comma-separated, from cg9, pcg3, mvm (default cg9); mvm is built or read from\n"
           "                 DIR/cache/ as `wavetomo compare` does (with recon.predict two matrices: with the\n"
           "                 predictor, and without it for the runs that do not predict)\n"
           "  --frames N     frames per closed-loop run (loop.frames)   --seed S   random seed (sim.seed)\n"
           "  --open-loop M  the instantaneous runs: flat (the sensors see the turbulence, DMs flat) or polc\n"
           "                 (they see it minus the previous frame's reconstruction: a diffractive sensor's\n"
           "                 spot stays in its centroider's linear range); default polc with a diffractive\n"
           "                 sensor, else flat\n"
           "  --dry-run      print the estimated peak memory and run time and the keys that drive them; stop\n"
           "  --max-memory S refuse up front when the estimate exceeds S bytes (4G, 512M; default MemAvailable)\n");
}

typedef struct {
    char list[128], *methods[MAXM];
    int nm;
    const char *out, *seed;
    long frames;
    int quiet, open_loop;
    double start;
    wt_progress pr; /* the current run's progress line */
    char text[192];
} budget_args;

static int option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    budget_args *a = user;
    const char *o = argv[*i], *v;
    if (strcmp(o, "--recon") && strcmp(o, "--out") && strcmp(o, "--seed") && strcmp(o, "--frames") &&
        strcmp(o, "--open-loop"))
        return 0;
    if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
    if (!strcmp(o, "--out")) a->out = v;
    else if (!strcmp(o, "--open-loop")) {
        if (!strcmp(v, "flat")) a->open_loop = WT_LOOP_OPEN_FLAT;
        else if (!strcmp(v, "polc")) a->open_loop = WT_LOOP_OPEN_POLC;
        else return wt_cli_usage_error(cli, "--open-loop expects flat or polc, got '%s'", v), -1;
    }
    else if (!strcmp(o, "--seed")) a->seed = v;
    else if (!strcmp(o, "--frames")) return wt_cli_int(cli, o, v, 2, 10000000, &a->frames) < 0 ? -1 : 1;
    else {
        snprintf(a->list, sizeof a->list, "%s", v);
        a->nm = 0;
        for (char *t = strtok(a->list, ","); t; t = strtok(NULL, ",")) {
            int k = wt_reconstructor_kind(t);
            if (a->nm == MAXM || k < 0 || k == WT_RECON_NONE) {
                wt_cli_usage_error(cli, "--recon expects 1 to %d of cg9, pcg3, mvm, got '%s'", MAXM, v);
                return -1;
            }
            a->methods[a->nm++] = t;
        }
        if (!a->nm) return wt_cli_usage_error(cli, "--recon: no reconstructor in '%s'", v), -1;
    }
    return 1;
}

/* stderr: a progress line per run on a terminal, and a line when each run ends with the time left */
static void progress(void *user, int run, int nruns, const char *label, long done, long total, double wfe)
{
    budget_args *a = user;
    if (a->quiet) return;
    if (done == 1) {
        snprintf(a->text, sizeof a->text, "run %d/%d %s", run + 1, nruns, label);
        wt_progress_start(&a->pr, a->text, "frames", total);
    }
    wt_progress_update(&a->pr, done, NULL);
    if (done == total) {
        wt_progress_end(&a->pr);
        double el = wt_time_now() - a->start;
        fprintf(stderr, "wavetomo budget: run %d/%d (%s, %ld frames): field WFE %.1f nm; %.0f s elapsed, ~%.0f s left\n",
                run + 1, nruns, label, total, wfe, el, el / (run + 1) * (nruns - run - 1));
    }
}

static int write_h5(wt_cli *cli, const budget_args *a, const wt_config *cfg, const wt_budget_result *R, int argc,
                    char **argv)
{
    char path[2048];
    wt_h5_writer *w = NULL;
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    int st = wt_h5_create(cli->ctx, path, &w);
    if (st >= 0 && (st = wt_cli_write_provenance(cli, w, cfg, argc, argv)) >= 0 &&
        (st = wt_budget_write_h5(w, a->nm, (const char *const *)a->methods, R)) >= 0)
        return wt_h5_commit(w);
    wt_h5_abort(w);
    return st;
}

/* Issue 10, C: per method 6 closed/open-loop runs and one fitting run (an MVM adds its build); -1: go on. */
static int estimate(wt_cli *cli, const budget_args *a, const wt_config *cfg)
{
    wt_estimate total = {0}, e;
    for (int m = 0; m < a->nm; m++) {
        int kind = wt_reconstructor_kind(a->methods[m]);
        wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_SIM, kind, cfg->frames, 0}, &e);
        e.seconds *= 7.0;
        wt_estimate_add(&total, &e);
        if (kind != WT_RECON_MVM) continue;
        wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_BUILD, WT_RECON_PCG3, 0, 0}, &e);
        wt_estimate_add(&total, &e);
        if (cfg->predict) wt_estimate_add(&total, &e); /* and its matrix without the predictor */
    }
    return wt_cli_resources(cli, &total);
}

int wt_cmd_budget(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo budget", help)) return 1;
    budget_args a = {.list = "cg9", .nm = 1, .frames = -1};
    a.methods[0] = a.list;
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_mvm *mvm[MAXM] = {NULL}, *plain[MAXM] = {NULL};
    wt_config *cfg_plain = NULL; /* recon.predict with an MVM: the configuration of its matrix without the predictor */
    wt_budget_result R[MAXM];
    int kinds[MAXM], st;
    int rc = wt_cli_parse(&cli, argc, argv, option, &a);
    if (rc < 0 && (!a.out || !cli.config_path))
        rc = wt_cli_usage_error(&cli, "%s is required", !cli.config_path ? "a configuration (FILE or --config FILE)" : "--out DIR");
    if (rc < 0 && (rc = wt_cli_run_overrides(&cli, a.frames, a.seed)) == 0) rc = -1;
    if (rc >= 0) goto done;
    a.quiet = cli.quiet;
    a.start = wt_time_now();
    char path[2100];
    snprintf(path, sizeof path, "%s/cache", a.out);
    if ((st = wt_cli_read_config(&cli, NULL, &cfg)) < 0) goto fail;
    if ((rc = estimate(&cli, &a, cfg)) >= 0) goto cleanup;
    if ((st = wt_system_alloc(cli.ctx, cfg, &sys)) < 0 || (st = wt_cli_ensure_dir(cli.ctx, path)) < 0) goto fail;
    for (int m = 0; m < a.nm; m++) {
        double build;
        kinds[m] = wt_reconstructor_kind(a.methods[m]);
        /* (before a build of minutes: what the MVM cannot do under prediction) */
        if ((st = wt_reconstructor_check_mvm_predict(cli.ctx, cfg, kinds[m], 0)) < 0) goto fail;
        if (kinds[m] != WT_RECON_MVM) continue;
        if ((st = wt_build_mvm_cached(&cli, a.out, cfg, sys, argc, argv, &mvm[m], &build)) < 0) goto fail;
        if (!cfg->predict) continue;
        /* the budget's instantaneous runs and its closed loop without prediction apply the matrix without the
         * predictor: the same system with recon.predict = false (its own identity, cached beside) */
        if (!cfg_plain) {
            if (cli.nset >= WT_CLI_MAX_SET) {
                st = WT_ERROR(cli.ctx, WT_ERR_INVALID, "too many --set overrides (at most %d with an MVM under "
                              "recon.predict)", WT_CLI_MAX_SET - 1);
                goto fail;
            }
            cli.set[cli.nset++] = "recon.predict=false";
            st = wt_cli_read_config(&cli, NULL, &cfg_plain);
            cli.nset--;
            if (st < 0) goto fail;
        }
        if ((st = wt_build_mvm_cached(&cli, a.out, cfg_plain, sys, argc, argv, &plain[m], &build)) < 0) goto fail;
    }
    wt_budget_options o;
    wt_budget_options_default(&o, cfg->seed);
    o.progress = progress;
    o.user = &a;
    o.open_loop = a.open_loop;
    if ((st = wt_budget_compute(cli.ctx, sys, &o, a.nm, kinds, (const wt_mvm *const *)mvm, (const wt_mvm *const *)plain, R)) < 0) goto fail;
    if ((st = write_h5(&cli, &a, cfg, R, argc, argv)) < 0) goto fail;
    snprintf(path, sizeof path, "%s/report.md", a.out);
    if ((st = wt_budget_write_report(cli.ctx, path, cfg, a.nm, (const char *const *)a.methods, R, argc, argv)) < 0) goto fail;
    double val[WT_BUDGET_NTERMS * MAXM], mark[WT_BUDGET_NTERMS * MAXM];
    const char *names[WT_BUDGET_NTERMS];
    int nt = 0; /* the terms measured under this configuration */
    for (int k = 0; k < WT_BUDGET_NTERMS; k++) {
        if (!wt_budget_term_used(cfg, k)) continue;
        names[nt] = wt_budget_term_names[k];
        for (int m = 0; m < a.nm; m++) val[nt * a.nm + m] = R[m].term[k], mark[nt * a.nm + m] = R[m].analytic[k];
        nt++;
    }
    snprintf(path, sizeof path, "%s/budget.png", a.out);
    if ((st = wt_plot_grouped_bars(cli.ctx, path, "error budget over the field", "WFE [nm]", nt, names, a.nm,
                                   (const char *const *)a.methods, val, mark)) < 0)
        goto fail;
    printf("report: %s/report.md (results.h5, budget.png)\n", a.out);
    rc = 0;
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    for (int m = 0; m < a.nm; m++) wt_mvm_free(mvm[m]), wt_mvm_free(plain[m]);
    wt_config_free(cli.ctx, cfg_plain);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
done:
    wt_cli_done(&cli);
    return rc;
}
