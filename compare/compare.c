/* compare/compare.c: `wavetomo compare`: closed-loop runs of several reconstructors (MVM, PCG-3,
 * CG-9, none) on identical turbulence and noise, optionally over a sweep of one configuration key,
 * with the side-by-side report (SPEC §10). The cases run in core/sim/compare.c, the files are written by
 * compare/report.c; this driver parses the options and walks the cases, stopping between frames on
 * SIGINT/SIGTERM with what is finished kept (--resume runs the rest). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare/report.h"
#include "core/io/h5.h"
#include "core/model/estimate.h"

static void help(void)
{
    printf("usage: wavetomo compare --config FILE [--set key=value]... [--recon mvm,pcg3,cg9]\n"
           "                        [--sweep key=v1,v2,...] [--frames N] [--seed S] [--resume] --out DIR\n"
           "\n"
           "Runs the closed loop for each reconstructor and each value of the swept key on identical\n"
           "turbulence and noise (the same seed), and writes DIR/results.h5, DIR/summary.csv, DIR/report.md\n"
           "and PNG figures: LE Strehl against the swept key (on-axis solid, field average dashed), LE Strehl\n"
           "maps over the field per method, and the time per frame per method.\n"
           "\n"
           "  --recon LIST   comma-separated, from mvm, pcg3, cg9, none (default mvm,pcg3,cg9)\n"
           "  --sweep K=V,.. a configuration key and its values (libconfig syntax each), e.g.\n"
           "                 --sweep lgs.wfs.photons=20,50,100,150,200\n"
           "  --frames N     frames per run (loop.frames)   --seed S   random seed (sim.seed)\n"
           "  --resume       run only the cases DIR/results.h5 lacks (after an interruption); refused when\n"
           "                 DIR/results.h5 was made with other methods, sweep, seed, frames or configuration\n"
           "Ctrl-C (SIGINT, SIGTERM, SIGHUP) stops the running case and writes every file with the cases\n"
           "finished so far (results.h5 'done', summary.csv and report.md name the missing ones), then exits\n"
           "with 128 + the signal number; a second signal ends it at once (no file written).\n"
           "  --dry-run      print the estimated peak memory and run time of all the cases (an MVM adds its\n"
           "                 build) and the keys that drive them; stop\n"
           "  --max-memory S refuse up front when the estimate exceeds S bytes (4G, 512M; default MemAvailable)\n"
           "The MVM (pcg3 layers) is built when missing or stale and cached in DIR/cache/ by the hash of\n"
           "the configuration keys that define it.\n"
           "\n"
           "The paper's experiments (SPEC §10), at the E-ELT size:\n"
           "  1. --recon cg9 --sweep recon.alpha=0.2,0.5,1,2,5,10,20,40\n"
           "  2. --recon pcg3 --sweep recon.pcg3.iterations=1,2,3,4,5,10\n"
           "  3. --recon mvm,pcg3,cg9 --sweep lgs.wfs.photons=20,50,100,150,200\n"
           "  4. --recon mvm,pcg3,cg9   (Strehl maps at 100 photons)\n");
}

static int cmp_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    wt_cmp_cases *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--resume")) return a->resume = 1;
    if (strcmp(o, "--recon") && strcmp(o, "--sweep") && strcmp(o, "--out") && strcmp(o, "--seed") && strcmp(o, "--frames"))
        return 0;
    if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
    if (!strcmp(o, "--out")) a->out = v;
    else if (!strcmp(o, "--seed")) a->seed = v;
    else if (!strcmp(o, "--frames")) return wt_cli_int(cli, o, v, 1, 10000000, &a->frames) < 0 ? -1 : 1;
    else if (!strcmp(o, "--recon")) {
        snprintf(a->list, sizeof a->list, "%s", v);
        if ((a->nm = wt_cli_split(cli, o, a->list, a->methods, WT_COMPARE_MAXM)) < 0) return -1;
        for (int k = 0; k < a->nm; k++)
            if (wt_reconstructor_kind(a->methods[k]) < 0)
                return wt_cli_usage_error(cli, "--recon: unknown reconstructor '%s' (mvm, pcg3, cg9, none)", a->methods[k]), -1;
    } else {
        const char *eq = strchr(v, '=');
        if (!eq || eq == v || (size_t)(eq - v) >= sizeof a->key)
            return wt_cli_usage_error(cli, "--sweep expects key=v1,v2,..., got '%s'", v), -1;
        snprintf(a->key, sizeof a->key, "%.*s", (int)(eq - v), v);
        snprintf(a->sweep, sizeof a->sweep, "%s", eq + 1);
        if ((a->nv = wt_cli_split(cli, o, a->sweep, a->values, WT_COMPARE_MAXV)) < 0) return -1;
    }
    return 1;
}

typedef struct {
    wt_progress pr;
    char label[256], extra[64];
} case_progress;

static int on_frame(void *user, long frame, double mean)
{
    case_progress *p = user;
    snprintf(p->extra, sizeof p->extra, "field SE Strehl %.3f", mean);
    wt_progress_update(&p->pr, frame, p->extra);
    return wt_interrupt_pending(); /* Ctrl-C: stop this case, keep the finished ones */
}

/* Configuration and system of sweep column v (the base overrides plus key=value). */
static int open_case(wt_cli *cli, const wt_cmp_cases *a, int base_nset, int v, char *set, size_t n, wt_config **cfg,
                     wt_system **sys)
{
    cli->nset = base_nset; /* drops the previous value's sweep (and settle) overrides */
    if (a->nv) snprintf(set, n, "%s=%s", a->key, a->values[v]), cli->set[cli->nset++] = set;
    int st = wt_cli_read_config(cli, NULL, cfg);
    return st < 0 ? st : wt_system_alloc(cli->ctx, *cfg, sys);
}

/* Issue 10, C: every case's estimate (an MVM adds its build), before anything runs; -1: go on. */
static int estimate(wt_cli *cli, const wt_cmp_cases *a, int base_nset, char *set, size_t n)
{
    wt_estimate total = {0}, e;
    for (int v = 0; v < (a->nv ? a->nv : 1); v++) {
        wt_config *cfg = NULL;
        cli->nset = base_nset;
        if (a->nv) snprintf(set, n, "%s=%s", a->key, a->values[v]), cli->set[cli->nset++] = set;
        int st = wt_cli_read_config(cli, NULL, &cfg);
        if (st < 0) return wt_cli_fail(cli, st);
        for (int m = 0; m < a->nm; m++) {
            int kind = wt_reconstructor_kind(a->methods[m]);
            wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_SIM, kind, cfg->frames}, &e);
            wt_estimate_add(&total, &e);
            if (kind != WT_RECON_MVM) continue;
            wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_BUILD, WT_RECON_PCG3, 0}, &e);
            wt_estimate_add(&total, &e);
        }
        wt_config_free(cli->ctx, cfg);
    }
    cli->nset = base_nset;
    return wt_cli_resources(cli, &total);
}

static int run_case(wt_cli *cli, const wt_cmp_cases *a, int m, int v, wt_config *cfg, wt_system *sys, int argc,
                    char **argv, wt_compare_result *res)
{
    int kind = wt_reconstructor_kind(a->methods[m]), st;
    wt_mvm *mvm = NULL;
    double build = 0.0;
    if (kind == WT_RECON_MVM && (st = wt_cli_mvm_cached(cli, a->out, cfg, sys, argc, argv, &mvm, &build)) < 0) return st;
    case_progress p;
    snprintf(p.label, sizeof p.label, "%s%s%s%s%s", a->methods[m], a->nv ? " " : "", a->nv ? a->key : "", a->nv ? "=" : "",
             a->nv ? a->values[v] : "");
    wt_progress_start(&p.pr, p.label, "frames", cfg->frames);
    p.pr.enabled &= !cli->quiet;
    st = wt_compare_run(cli->ctx, sys, kind, mvm, build, on_frame, &p, res);
    wt_progress_end(&p.pr);
    wt_mvm_free(mvm);
    if (st >= 0 && !cli->quiet)
        fprintf(stderr, "  %-28s LE Strehl on-axis %.4f field %.4f, WFE %.1f nm, %.1f ms/frame (reconstruction %.2f ms)\n",
                p.label, res->on_axis, res->field, res->wfe_field, res->total, res->parts[2] + res->parts[3]);
    return st;
}

int wt_cmd_compare(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo compare", help)) return 1;
    wt_cmp_cases a = {.list = "mvm,pcg3,cg9", .frames = -1};
    a.nm = wt_cli_split(&cli, "--recon", a.list, a.methods, WT_COMPARE_MAXM);
    int rc = wt_cli_parse(&cli, argc, argv, cmp_option, &a);
    if (rc < 0 && (!a.out || !cli.config_path))
        rc = wt_cli_usage_error(&cli, "%s is required", !cli.config_path ? "--config FILE" : "--out DIR");
    if (rc < 0 && wt_cli_run_overrides(&cli, a.frames, a.seed) != 0) rc = 2;
    if (rc >= 0) goto done;
    rc = 0;
    int nv = a.nv ? a.nv : 1, st = WT_OK, base_nset = cli.nset, ndone = 0;
    char sweep_set[1200], cache[2100];
    wt_compare_result *R = calloc((size_t)a.nm * nv, sizeof *R);
    wt_config *cfg = NULL, *first = NULL;
    wt_system *sys = NULL, *first_sys = NULL;
    wt_compare_plan plan;
    snprintf(cache, sizeof cache, "%s/cache", a.out);
    if (!R) st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory");
    if (st >= 0 && (rc = estimate(&cli, &a, base_nset, sweep_set, sizeof sweep_set)) >= 0) goto cleanup;
    rc = 0;
    if (st < 0 || (st = open_case(&cli, &a, base_nset, 0, sweep_set, sizeof sweep_set, &first, &first_sys)) < 0) goto fail;
    wt_compare_plan_make(&plan, a.nm, a.methods, a.key, a.nv, a.values, first);
    if ((st = wt_cli_ensure_dir(cli.ctx, a.out)) < 0 || (st = wt_cli_ensure_dir(cli.ctx, cache)) < 0 ||
        (st = wt_cmp_check_outputs(&cli, &a)) < 0)
        goto fail;
    if (a.resume && (st = wt_cmp_read_previous(&cli, &a, &plan, R, &ndone)) < 0) goto fail;
    if (a.resume && !cli.quiet) fprintf(stderr, "%s: resuming: %d of %d cases done\n", cli.prog, ndone, a.nm * nv);
    wt_interrupt_defer(1);
    for (int v = 0; v < nv && !wt_interrupt_pending(); v++) {
        int todo = 0;
        for (int m = 0; m < a.nm; m++) todo += !R[m * nv + v].done;
        if (!todo) continue;
        if (v > 0 && (st = open_case(&cli, &a, base_nset, v, sweep_set, sizeof sweep_set, &cfg, &sys)) < 0) goto fail;
        for (int m = 0; m < a.nm && !wt_interrupt_pending(); m++)
            if (!R[m * nv + v].done &&
                (st = run_case(&cli, &a, m, v, v ? cfg : first, v ? sys : first_sys, argc, argv, &R[m * nv + v])) < 0 &&
                st != WT_ERR_INTERRUPTED)
                goto fail;
        wt_system_free(sys), wt_config_free(cli.ctx, cfg);
        cfg = NULL, sys = NULL;
    }
    int sig = wt_interrupt_pending();
    if ((st = wt_cmp_write_all(&cli, &a, &plan, first, first_sys, R, argc, argv)) < 0) goto fail;
    if (sig) {
        fprintf(stderr, "%s: interrupted by signal %d: the finished cases are in %s (rerun with --resume for the rest)\n",
                cli.prog, sig, a.out);
        rc = 128 + sig;
    } else
        printf("report: %s/report.md (results.h5, summary.csv, PNG figures in %s)\n", a.out, a.out);
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_interrupt_defer(0);
    wt_system_free(sys), wt_config_free(cli.ctx, cfg);
    wt_system_free(first_sys), wt_config_free(cli.ctx, first);
    free(R);
done:
    wt_cli_done(&cli);
    return rc;
}
