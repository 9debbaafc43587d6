/* compare/cmd_compare.c: `wavetomo compare`: closed-loop runs of several reconstructors (MVM, PCG-3,
 * CG-9, none) on identical turbulence and noise, optionally over a sweep of one configuration key and over
 * several seeds, with the side-by-side report (SPEC §10). The cases run in compare/compare.c, the files are
 * written by compare/report.c; this driver parses the options and walks the cases, stopping between frames on
 * SIGINT/SIGTERM with what is finished kept (--resume runs the rest).
 *
 * Under mpirun the cases are dealt to the ranks before any runs, the same way on every rank
 * (longest first to the least loaded rank, by the resource estimate); all the MVM cases that share a matrix
 * (same hash: one cache file) go to one rank, so no two ranks build or write the same cache file. A case's
 * numbers depend only on its configuration, seed and threads, not on the rank that runs it; rank 0 gathers
 * the results and writes every file. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/mpi.h"
#include "builder/cmd_build.h"
#include "builder/mvm_build.h"
#include "compare/cmd_compare.h"
#include "core/model/params.h"
#include "compare/report.h"
#include "compare/report_spots.h"
#include "core/io/h5.h"
#include "core/model/estimate.h"

static void help(void)
{
    printf("usage: wavetomo compare [--config] FILE [--set key=value]... [--recon mvm,pcg3,cg9]\n"
           "                        [--sweep key=v1,v2,...] [--seeds N] [--frames N] [--seed S] [--resume] --out DIR\n"
           "\n"
           "Runs the closed loop for each reconstructor and each value of the swept key on identical\n"
           "turbulence and noise (the same seed), and writes DIR/results.h5, DIR/summary.csv, DIR/report.md\n"
           "and PNG figures: LE Strehl against the swept key (on-axis solid, field average dashed), LE Strehl\n"
           "maps over the field per method with the guide stars marked, each method's residual WFE minus the\n"
           "first method's over the field (with two methods or more), the time per frame per method, the\n"
           "long-exposure PSFs over the field per method (log scale, PSF-peak Strehl in each panel;\n"
           "sim.psf_interval_frames) and the residual WFE of every frame per method with the settle window\n"
           "(the loop's convergence). A sweep of 2-5 values over 100 frames or more adds every case over the\n"
           "run (wfe_over_run.png; in night minutes for a changing night or sodium layer, atmosphere.night,\n"
           "lgs.sodium_sequence), and a sweep of recon.atmosphere.source with \"oracle\" among its values every\n"
           "case minus its method's oracle (wfe_minus_oracle.png: what each model of the atmosphere costs over\n"
           "the run).\n"
           "\n"
           "  --recon LIST   comma-separated, from mvm, pcg3, cg9, none (default mvm,pcg3,cg9)\n"
           "  --sweep K=V,.. a configuration key and its values (libconfig syntax each), e.g.\n"
           "                 --sweep lgs.wfs.photons=20,50,100,150,200\n"
           "  --frames N     frames per run (loop.frames)   --seed S   random seed (sim.seed)\n"
           "  --seeds N      run every case with the seeds S, S+1, ..., S+N-1 (S = sim.seed; --sweep sim.seed=a,b,..\n"
           "                 does the same with its seeds): the report gives each method's mean and standard error\n"
           "                 over the seeds and the paired differences between methods (same seeds), saying which\n"
           "                 are within the noise (|mean| < 2 SE); results.h5 keeps every seed's values (group seeds)\n"
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
           "  4. --recon mvm,pcg3,cg9   (Strehl maps at 100 photons)\n"
           "\n"
           "MPI: `mpirun -n K wavetomo compare ...` deals the cases (method x sweep value x seed) to K ranks; rank 0\n"
           "writes the files, equal to a serial run's (but the timings) when every rank uses the same --threads.\n");
}

static int cmp_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    wt_compare_cases *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--resume")) return a->resume = 1;
    if (strcmp(o, "--recon") && strcmp(o, "--sweep") && strcmp(o, "--out") && strcmp(o, "--seed") && strcmp(o, "--frames") &&
        strcmp(o, "--seeds"))
        return 0;
    if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
    if (!strcmp(o, "--out")) a->out = v;
    else if (!strcmp(o, "--seed")) a->seed = v;
    else if (!strcmp(o, "--frames")) return wt_cli_int(cli, o, v, 1, 10000000, &a->frames) < 0 ? -1 : 1;
    else if (!strcmp(o, "--seeds")) return wt_cli_int(cli, o, v, 1, WT_COMPARE_MAXS, &a->nseeds) < 0 ? -1 : 1;
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

/* --sweep sim.seed=a,b,... is a set of seeds, not a sweep: the cases get the statistics of --seeds. The first
 * seed becomes --seed (so the stored configuration names it). Returns 0 or 2 after a usage error. */
static int seed_sweep(wt_cli *cli, wt_compare_cases *a, char *first, size_t n)
{
    if (!a->nv || strcmp(a->key, "sim.seed")) return 0;
    if (a->nseeds || a->seed) return wt_cli_usage_error(cli, "--sweep sim.seed gives the seeds: no --seeds or --seed with it");
    for (int v = 0; v < a->nv; v++) {
        char *end = NULL;
        errno = 0;
        unsigned long long x = a->values[v][0] >= '0' && a->values[v][0] <= '9' ? strtoull(a->values[v], &end, 10) : 0;
        if (end && *end == 'L') end++;
        if (!end || *end || errno == ERANGE || x > (unsigned long long)INT64_MAX)
            return wt_cli_usage_error(cli, "--sweep sim.seed: '%s' is not a seed (an integer in [0, 2^63))", a->values[v]);
        a->seeds[v] = x;
        for (int u = 0; u < v; u++)
            if (a->seeds[u] == x) return wt_cli_usage_error(cli, "--sweep sim.seed: seed %llu twice", x);
    }
    a->ns = a->nv;
    snprintf(first, n, "%llu", (unsigned long long)a->seeds[0]);
    a->seed = first;
    a->nv = 0, a->key[0] = '\0';
    return 0;
}

typedef struct {
    wt_progress pr;
    char label[256], extra[64];
} case_progress;

static int on_frame(void *user, long frame, double mean)
{
    case_progress *p = user;
    snprintf(p->extra, sizeof p->extra, "Strehl %.3f so far (field average)", mean);
    wt_progress_update(&p->pr, frame, p->extra);
    return wt_interrupt_pending(); /* Ctrl-C: stop this case, keep the finished ones */
}

/* Configuration of sweep column v (the base overrides plus key=value). */
static int read_case(wt_cli *cli, const wt_compare_cases *a, int base_nset, int v, char *set, size_t n, wt_config **cfg)
{
    cli->nset = base_nset; /* drops the previous value's sweep (and settle) overrides */
    if (a->nv) snprintf(set, n, "%s=%s", a->key, a->values[v]), cli->set[cli->nset++] = set;
    int st = wt_cli_read_config(cli, NULL, cfg);
    cli->nset = base_nset;
    if (st < 0 && a->nv) {
        /* the reader names the override as --set KEY=VALUE; the user wrote it as one value of --sweep */
        char detail[1024], pre[1300];
        snprintf(detail, sizeof detail, "%s", wt_error_message(cli->ctx));
        snprintf(pre, sizeof pre, "--set %s: ", set);
        const char *d = strncmp(detail, pre, strlen(pre)) ? detail : detail + strlen(pre);
        st = WT_ERROR(cli->ctx, st, "--sweep %s: value %d ('%s'): %s", a->key, v + 1, a->values[v], d);
    }
    return st;
}

/* ... and its system. */
static int open_case(wt_cli *cli, const wt_compare_cases *a, int base_nset, int v, char *set, size_t n, wt_config **cfg,
                     wt_system **sys)
{
    int st = read_case(cli, a, base_nset, v, set, n, cfg);
    return st < 0 ? st : wt_system_alloc(cli->ctx, *cfg, sys);
}

/* What dealing the cases needs from each sweep value's configuration: the estimated run time of one case of
 * each method, the MVM build's, and the matrix hash (MVM cases of equal hash share one cache file). */
typedef struct {
    double run[WT_COMPARE_MAXM][WT_COMPARE_MAXV], build[WT_COMPARE_MAXV];
    char hash[WT_COMPARE_MAXV][80];
} case_costs;

/* Issue 10, C: every case's estimate (an MVM adds its build), before anything runs; -1: go on. */
static int estimate(wt_cli *cli, const wt_compare_cases *a, int base_nset, char *set, size_t n, case_costs *cc)
{
    wt_estimate total = {0}, e;
    for (int v = 0; v < (a->nv ? a->nv : 1); v++) {
        wt_config *cfg = NULL;
        int st = read_case(cli, a, base_nset, v, set, n, &cfg);
        if (st < 0) return wt_cli_fail(cli, st);
        /* the cache file's name: the matrix hash and the storage precision (cli/output.c) */
        snprintf(cc->hash[v], sizeof cc->hash[v], "%.64s-%d", cfg->matrix_sha256, cfg->mvm_precision);
        cc->build[v] = 0.0;
        for (int m = 0; m < a->nm; m++) {
            int kind = wt_reconstructor_kind(a->methods[m]);
            wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_SIM, kind, cfg->frames, 0}, &e);
            cc->run[m][v] = e.seconds;
            for (int s = 0; s < a->ns; s++) wt_estimate_add(&total, &e);
            if (kind != WT_RECON_MVM) continue;
            wt_estimate_resources(cfg, &(wt_estimate_request){WT_TASK_BUILD, WT_RECON_PCG3, 0, 0}, &e);
            cc->build[v] = e.seconds;
            wt_estimate_add(&total, &e);
        }
        wt_config_free(cli->ctx, cfg);
    }
    return wt_cli_resources(cli, &total);
}

/* Deal the cases not done to nranks ranks: owner[c] (-1 for the done ones). Units: one per case, but all
 * the MVM cases of one matrix hash form a single unit (one builder per cache file); longest unit first to
 * the least loaded rank (ties: the lower rank), identically on every rank. */
static int deal(wt_context *ctx, const wt_compare_cases *a, const case_costs *cc, const wt_compare_result *R, int nranks,
                int *owner)
{
    const int nv = a->nv ? a->nv : 1, nc = a->nm * nv * a->ns;
    typedef struct { double cost; int m, v, s; } unit; /* s < 0: the MVM unit of v's hash */
    unit *u = calloc((size_t)nc, sizeof *u);
    double load[1024] = {0};
    if (!u) return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory dealing the cases");
    if (nranks > 1024) nranks = 1024;
    int nu = 0;
    for (int c = 0; c < nc; c++) owner[c] = -1;
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) {
            int mvm = wt_reconstructor_kind(a->methods[m]) == WT_RECON_MVM, first = 1;
            for (int w = 0; w < v && mvm; w++) first &= strcmp(cc->hash[w], cc->hash[v]) != 0;
            if (mvm && !first) continue; /* in the unit of the first value with this hash */
            double cost = 0.0;
            int todo = 0;
            for (int w = v; w < nv; w++) {
                if (w != v && (!mvm || strcmp(cc->hash[w], cc->hash[v]))) continue;
                for (int s = 0; s < a->ns; s++) {
                    if (R[wt_compare_case(a, m, w, s)].done) continue;
                    if (!mvm) u[nu++] = (unit){cc->run[m][w], m, w, s};
                    else cost += cc->run[m][w], todo = 1;
                }
            }
            if (todo) u[nu++] = (unit){cost + cc->build[v], m, v, -1};
        }
    for (int i = 1; i < nu; i++) /* stable insertion sort, longest first */
        for (int j = i; j > 0 && u[j].cost > u[j - 1].cost; j--) {
            unit t = u[j];
            u[j] = u[j - 1], u[j - 1] = t;
        }
    for (int i = 0; i < nu; i++) {
        int r = 0;
        for (int k = 1; k < nranks; k++)
            if (load[k] < load[r]) r = k;
        load[r] += u[i].cost + 1e-9; /* ties of zero estimates still spread */
        if (u[i].s >= 0) {
            owner[wt_compare_case(a, u[i].m, u[i].v, u[i].s)] = r;
            continue;
        }
        for (int w = u[i].v; w < nv; w++)
            if (!strcmp(cc->hash[w], cc->hash[u[i].v]))
                for (int s = 0; s < a->ns; s++)
                    if (!R[wt_compare_case(a, u[i].m, w, s)].done) owner[wt_compare_case(a, u[i].m, w, s)] = r;
    }
    free(u);
    return WT_OK;
}

/* The seeds of method m at sweep value v that this rank runs: the MVM is loaded (or built and cached) once. */
static int run_cases(wt_cli *cli, const wt_compare_cases *a, int m, int v, const int *owner, int rank, wt_config *cfg,
                     wt_system *sys, int argc, char **argv, wt_compare_result *R, wt_compare_extra *X)
{
    int kind = wt_reconstructor_kind(a->methods[m]), st = WT_OK;
    wt_mvm *mvm = NULL;
    double build = 0.0;
    for (int s = 0; s < a->ns && st >= 0 && !wt_interrupt_pending(); s++) {
        int c = wt_compare_case(a, m, v, s);
        if (owner[c] != rank) continue;
        /* (what the MVM cannot do under recon.predict: refused before a build of minutes, as the loop would after it) */
        if (kind == WT_RECON_MVM && !mvm && (st = wt_reconstructor_check_mvm_predict(cli->ctx, cfg, kind, 0)) < 0) break;
        if (kind == WT_RECON_MVM && !mvm && (st = wt_build_mvm_cached(cli, a->out, cfg, sys, argc, argv, &mvm, &build)) < 0) {
            if (st == WT_ERR_INTERRUPTED && wt_interrupt_pending()) st = WT_OK; /* said once, with the cases kept */
            break;
        }
        case_progress p;
        snprintf(p.label, sizeof p.label, "%s%s%s%s%s", a->methods[m], a->nv ? " " : "", a->nv ? a->key : "",
                 a->nv ? "=" : "", a->nv ? a->values[v] : "");
        if (a->ns > 1)
            snprintf(p.label + strlen(p.label), sizeof p.label - strlen(p.label), " seed %llu", (unsigned long long)a->seeds[s]);
        wt_progress_start(&p.pr, p.label, "frames", cfg->frames);
        if (cli->quiet) p.pr.enabled = 0;
        wt_compare_result *res = &R[c];
        wt_free(cli->ctx, X->wfe[c]), wt_free(cli->ctx, X->psf[c]);
        wt_adapt_free(X->learned[c]);
        X->wfe[c] = NULL, X->psf[c] = NULL, X->learned[c] = NULL;
        if (!(X->wfe[c] = wt_malloc(cli->ctx, (size_t)cfg->frames, sizeof(double)))) {
            st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the per-frame residuals");
            break;
        }
        wt_compare_series ser = {.wfe = X->wfe[c]};
        wt_mvm_rebuilder rb = {cli->ctx, sys, mvm && mvm->commands == WT_MVM_FITTING ? "cg9" : "pcg3", NULL};
        const int learn = mvm != NULL; /* (the rebuild is used when it learns or follows a night) */
        st = wt_compare_run_rebuild(cli->ctx, sys, kind, mvm, build, a->seeds[s], learn ? wt_mvm_rebuild_model : NULL,
                                    learn ? &rb : NULL, on_frame, &p, res, &ser);
        X->psf[c] = ser.psf;
        X->learned[c] = ser.learned;
        build = 0.0; /* the build counts in the set-up of the first seed that used it */
        wt_progress_end(&p.pr);
        if (st >= 0 && !cli->quiet)
            fprintf(stderr, "  %-28s LE Strehl on-axis %.4f field %.4f, WFE %.1f nm, %.1f ms/frame (reconstruction %.2f ms)\n",
                    p.label, res->on_axis, res->field, res->wfe_field, res->total, res->parts[2] + res->parts[3]);
        if (st >= 0 && !cli->quiet && res->psf_frames > 0)
            fprintf(stderr, "  %-28s PSF-peak Strehl on-axis %.4f field %.4f (%.0f frames, %.2f ms/frame)\n", "",
                    res->psf_on_axis, res->psf_field, res->psf_frames, res->psf_ms);
    }
    wt_mvm_free(mvm);
    return st;
}

/* MPI: rank 0 collects each rank's status and the results of the cases it owned; the others send theirs.
 * *others_failed (rank 0): ranks that ended with an error (they printed it). */
static int gather(wt_mpi *mp, const wt_compare_cases *a, const int *owner, int status, wt_compare_result *R,
                  int *others_failed)
{
    const int nc = a->nm * (a->nv ? a->nv : 1) * a->ns;
    const size_t bytes = (size_t)nc * sizeof *R;
    *others_failed = 0;
    if (mp->size <= 1) return 0;
    if (mp->rank) return wt_mpi_send(mp, &status, sizeof status, 0, 11) < 0 || wt_mpi_send(mp, R, bytes, 0, 12) < 0 ? -1 : 0;
    wt_compare_result *tmp = malloc(bytes);
    if (!tmp) return fprintf(stderr, "wavetomo compare: error: out of memory gathering the results\n"), -1;
    for (int r = 1; r < mp->size; r++) {
        int st = 0;
        if (wt_mpi_recv(mp, &st, sizeof st, r, 11) < 0 || wt_mpi_recv(mp, tmp, bytes, r, 12) < 0) {
            free(tmp);
            return -1;
        }
        *others_failed += st < 0 && st != WT_ERR_INTERRUPTED;
        for (int c = 0; c < nc; c++)
            if (owner[c] == r && tmp[c].done) R[c] = tmp[c];
    }
    free(tmp);
    return 0;
}

/* MPI, after gather: the per-frame residuals and PSF images of the cases done by the other ranks, case by case
 * in index order (sizes from the gathered R: frames, psf_pixels). */
static int gather_extra(wt_mpi *mp, wt_context *ctx, const wt_compare_cases *a, const int *owner, const wt_compare_result *R,
                        int neval, wt_compare_extra *X)
{
    const int nc = a->nm * (a->nv ? a->nv : 1) * a->ns;
    if (mp->size <= 1) return 0;
    for (int c = 0; c < nc; c++) {
        if (owner[c] <= 0 || !R[c].done || (mp->rank && owner[c] != mp->rank)) continue;
        const size_t nw = (size_t)R[c].frames, np = (size_t)neval * (size_t)R[c].psf_pixels * (size_t)R[c].psf_pixels;
        if (mp->rank) {
            if (wt_mpi_send(mp, X->wfe[c], nw * sizeof(double), 0, 13) < 0 ||
                (np && wt_mpi_send(mp, X->psf[c], np * sizeof(float), 0, 14) < 0))
                return -1;
            continue;
        }
        wt_free(ctx, X->wfe[c]), wt_free(ctx, X->psf[c]);
        X->wfe[c] = wt_malloc(ctx, nw, sizeof(double));
        X->psf[c] = np ? wt_malloc(ctx, np, sizeof(float)) : NULL;
        if (!X->wfe[c] || (np && !X->psf[c]))
            return fprintf(stderr, "wavetomo compare: error: out of memory gathering the PSFs\n"), -1;
        if (wt_mpi_recv(mp, X->wfe[c], nw * sizeof(double), owner[c], 13) < 0 ||
            (np && wt_mpi_recv(mp, X->psf[c], np * sizeof(float), owner[c], 14) < 0))
            return -1;
    }
    return 0;
}

/* The paired differences on stdout: which are resolved and which are within the noise. */
static void print_differences(const wt_compare_cases *a, const wt_compare_result *R)
{
    const int nv = a->nv ? a->nv : 1;
    if (a->ns < 2 || a->nm < 2) return;
    printf("paired differences over %d seeds (mean ± standard error; 'noise': |mean| < 2 SE):\n", a->ns);
    for (int v = 0; v < nv; v++)
        for (int i = 0; i < a->nm; i++)
            for (int j = i + 1; j < a->nm; j++) {
                printf("  %s - %s%s%s%s%s:", a->methods[i], a->methods[j], a->nv ? " at " : "", a->nv ? a->key : "",
                       a->nv ? "=" : "", a->nv ? a->values[v] : "");
                for (int k = 0; k < WT_NMETRICS; k++) {
                    double d, se;
                    int n;
                    wt_compare_paired(&R[wt_compare_case(a, i, v, 0)], &R[wt_compare_case(a, j, v, 0)], a->ns, k, &d, &se, &n);
                    const char *name[] = {"on-axis", "field", "WFE nm"};
                    printf("  %s %+.4g ± %.2g%s", name[k], d, se, n < 2 ? " (n/a)" : fabs(d) < 2 * se ? " (noise)" : "");
                }
                printf("\n");
            }
}

static int compare_main(wt_mpi *mp, int argc, char **argv)
{
    wt_cli cli;
    char prog[64];
    snprintf(prog, sizeof prog, "wavetomo compare[rank %d]", mp->rank);
    if (wt_cli_init(&cli, mp->rank ? prog : "wavetomo compare", help)) return 1;
    wt_compare_cases a = {.list = "mvm,pcg3,cg9", .frames = -1, .ns = 1};
    char first_seed[32];
    a.nm = wt_cli_split(&cli, "--recon", a.list, a.methods, WT_COMPARE_MAXM);
    int rc = wt_cli_parse(&cli, argc, argv, cmp_option, &a);
    if (rc < 0 && (!a.out || !cli.config_path))
        rc = wt_cli_usage_error(&cli, "%s is required", !cli.config_path ? "a configuration (FILE or --config FILE)" : "--out DIR");
    if (rc < 0 && seed_sweep(&cli, &a, first_seed, sizeof first_seed) != 0) rc = 2;
    if (rc < 0 && wt_cli_run_overrides(&cli, a.frames, a.seed) != 0) rc = 2;
    if (rc >= 0) goto done;
    if (mp->rank) cli.quiet = 1; /* rank 0 speaks for the job; the others only report their errors */
    rc = 0;
    int nv = a.nv ? a.nv : 1, st = WT_OK, base_nset = cli.nset, ndone = 0, nc = 0, bad = 0, others = 0;
    char sweep_set[1200], cache[2100];
    wt_compare_result *R = NULL;
    wt_compare_extra X = {NULL, NULL, NULL};
    int *owner = NULL;
    case_costs *cc = calloc(1, sizeof *cc);
    wt_config *cfg = NULL, *first = NULL;
    wt_system *sys = NULL, *first_sys = NULL;
    wt_compare_plan plan;
    snprintf(cache, sizeof cache, "%s/cache", a.out);
    if (!cc) st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory");
    if (st < 0 || (st = read_case(&cli, &a, base_nset, 0, sweep_set, sizeof sweep_set, &first)) < 0) goto fail;
    if (a.nseeds) { /* --seeds N: sim.seed (after --seed) and the N - 1 next */
        if (first->seed > (uint64_t)INT64_MAX - (uint64_t)a.nseeds) {
            st = WT_ERROR(cli.ctx, WT_ERR_CONFIG, "--seeds %ld from sim.seed %llu passes 2^63", a.nseeds,
                          (unsigned long long)first->seed);
            goto fail;
        }
        a.ns = (int)a.nseeds;
        for (int s = 0; s < a.ns; s++) a.seeds[s] = first->seed + (uint64_t)s;
    } else if (a.ns == 1)
        a.seeds[0] = first->seed;
    nc = a.nm * nv * a.ns;
    R = calloc((size_t)nc, sizeof *R);
    owner = calloc((size_t)nc, sizeof *owner);
    X.wfe = calloc((size_t)nc, sizeof *X.wfe);
    X.psf = calloc((size_t)nc, sizeof *X.psf);
    X.learned = calloc((size_t)nc, sizeof *X.learned);
    if (!R || !owner || !X.wfe || !X.psf || !X.learned) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory");
        goto fail;
    }
    if ((rc = estimate(&cli, &a, base_nset, sweep_set, sizeof sweep_set, cc)) >= 0) goto cleanup;
    rc = 0;
    if ((st = wt_system_alloc(cli.ctx, first, &first_sys)) < 0) goto fail;
    wt_compare_plan_make(&plan, a.nm, a.methods, a.key, a.nv, a.values, a.ns, a.seeds, first);
    /* rank 0 owns the directory: it creates it, checks the outputs and reads what a previous run did; the
     * other ranks wait for its verdict and its list of done cases */
    /* a diffractive system: the pictures of its first diffractive LGS (else sensor) beside the report */
    int spots = -1;
    char results_h5[2200];
    snprintf(results_h5, sizeof results_h5, "%s/results.h5", a.out);
    for (int m = 0; m < first_sys->nsensors; m++)
        if (first_sys->sensors[m].diffr && (st = wt_spots_pick(cli.ctx, first_sys, NULL, &spots)) < 0) goto fail;
    if (mp->rank == 0 && ((st = wt_cli_ensure_dir(cli.ctx, a.out)) < 0 || (st = wt_cli_ensure_dir(cli.ctx, cache)) < 0 ||
                          (st = wt_compare_check_outputs(&cli, &a)) < 0 ||
                          (spots >= 0 && (st = wt_spots_check_outputs(&cli, first_sys, spots, a.out, results_h5)) < 0) ||
                          (a.resume && (st = wt_compare_read_previous(&cli, &a, &plan, R, &X, &ndone)) < 0)))
        bad = 1;
    if (wt_mpi_max_int(mp, &bad) < 0) bad = 1;
    if (st < 0) goto fail;
    if (bad || wt_mpi_bcast(mp, R, (size_t)nc * sizeof *R) < 0) goto quiet_fail;
    if (a.resume && !cli.quiet) fprintf(stderr, "%s: resuming: %d of %d cases done\n", cli.prog, ndone, nc);
    if ((st = deal(cli.ctx, &a, cc, R, mp->size, owner)) < 0) goto fail;
    if (mp->size > 1 && !cli.quiet) {
        int mine = 0, todo = 0;
        for (int c = 0; c < nc; c++) todo += owner[c] >= 0, mine += owner[c] == 0;
        fprintf(stderr, "%s: %d cases over %d MPI ranks (%d threads each); rank 0 runs %d\n", cli.prog, todo, mp->size,
                wt_context_threads(cli.ctx), mine);
    }
    wt_interrupt_defer(1);
    for (int v = 0; v < nv && !wt_interrupt_pending() && st >= 0; v++) {
        int todo = 0;
        for (int c = 0; c < nc; c++) todo += owner[c] == mp->rank && (c / a.ns) % nv == v;
        if (!todo) continue;
        if (v > 0 && (st = open_case(&cli, &a, base_nset, v, sweep_set, sizeof sweep_set, &cfg, &sys)) < 0) break;
        for (int m = 0; m < a.nm && !wt_interrupt_pending() && st >= 0; m++) {
            st = run_cases(&cli, &a, m, v, owner, mp->rank, v ? cfg : first, v ? sys : first_sys, argc, argv, R, &X);
            if (st == WT_ERR_INTERRUPTED) st = WT_OK;
        }
        wt_system_free(sys), wt_config_free(cli.ctx, cfg);
        cfg = NULL, sys = NULL;
    }
    /* a failed rank still hands in what it finished: rank 0 writes every finished case */
    if (st < 0) rc = wt_cli_fail(&cli, st), st = WT_OK;
    if (gather(mp, &a, owner, rc ? -1 : WT_OK, R, &others) < 0 ||
        gather_extra(mp, cli.ctx, &a, owner, R, first_sys->neval, &X) < 0)
        goto quiet_fail;
    if (mp->rank) goto cleanup;
    int sig = wt_interrupt_pending();
    if (spots >= 0) {
        char cmd[4096] = "wavetomo info";
        snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " %s", first->path);
        for (int i = 0; i < base_nset; i++) snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " --set '%s'", cli.set[i]);
        if (a.nv) /* the pictures are of the first sweep value's system */
            snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " --set '%s=%s'", a.key, a.values[0]);
        snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " --spots %s", a.out);
        if ((st = wt_spots_write(&cli, first_sys, spots, a.out, cmd, NULL)) < 0) goto fail;
        snprintf(a.spots, sizeof a.spots, "%s", first_sys->sensors[spots].name);
    }
    if ((st = wt_compare_write_all(&cli, &a, &plan, first, first_sys, R, &X, argc, argv)) < 0) goto fail;
    if (others) {
        fprintf(stderr, "%s: %d MPI rank(s) failed (messages above): the finished cases are in %s (rerun with --resume "
                        "for the rest)\n", cli.prog, others, a.out);
        rc = 1;
    }
    if (sig) {
        fprintf(stderr, "%s: interrupted by signal %d: the finished cases are in %s (rerun with --resume for the rest)\n",
                cli.prog, sig, a.out);
        rc = 128 + sig;
    } else if (!rc) {
        print_differences(&a, R);
        printf("report: %s/report.md (results.h5, summary.csv, PNG figures in %s)\n", a.out, a.out);
    }
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
    goto cleanup;
quiet_fail: /* rank 0 refused (and said why), or the MPI call printed its error */
    rc = 1;
cleanup:
    wt_interrupt_defer(0);
    wt_system_free(sys), wt_config_free(cli.ctx, cfg);
    wt_system_free(first_sys), wt_config_free(cli.ctx, first);
    for (int c = 0; c < nc && X.wfe; c++) wt_free(cli.ctx, X.wfe[c]);
    for (int c = 0; c < nc && X.psf; c++) wt_free(cli.ctx, X.psf[c]);
    for (int c = 0; c < nc && X.learned; c++) wt_adapt_free(X.learned[c]);
    free(X.wfe), free(X.psf), free(X.learned);
    free(R);
    free(owner);
    free(cc);
done:
    wt_cli_done(&cli);
    return rc;
}

int wt_cmd_compare(int argc, char **argv)
{
    wt_mpi mp;
    if (wt_mpi_begin(&mp)) return 1;
    int rc = compare_main(&mp, argc, argv);
    wt_mpi_end(&mp);
    return rc;
}
