/* compare/compare.c: `wavetomo compare`: closed-loop runs of several reconstructors (MVM, PCG-3,
 * CG-9, none) on identical turbulence and noise, optionally over a sweep of one configuration key,
 * with the side-by-side report: results.h5, summary.csv, report.md and PNG figures (SPEC §10). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli/cli.h"
#include "compare/plot.h"
#include "core/io/h5.h"
#include "core/build/mvm_build.h"
#include "core/la/half.h"
#include "core/model/tomography.h"
#include "core/sim/loop.h"

#define MAXM 4
#define MAXV 32
#define NPART 6

static void help(void)
{
    printf("usage: wavetomo compare --config FILE [--set key=value]... [--recon mvm,pcg3,cg9]\n"
           "                        [--sweep key=v1,v2,...] [--frames N] [--seed S] --out DIR\n"
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
           "The MVM (pcg3 layers) is built when missing or stale and cached in DIR/cache/ by the hash of\n"
           "the configuration keys that define it.\n"
           "\n"
           "The paper's experiments (SPEC §10), at the E-ELT size:\n"
           "  1. --recon cg9 --sweep recon.alpha=0.2,0.5,1,2,5,10,20,40\n"
           "  2. --recon pcg3 --sweep recon.pcg3.iterations=1,2,3,4,5,10\n"
           "  3. --recon mvm,pcg3,cg9 --sweep lgs.wfs.photons=20,50,100,150,200\n"
           "  4. --recon mvm,pcg3,cg9   (Strehl maps at 100 photons)\n");
}

typedef struct {
    char list[256], sweep[1024], *methods[MAXM], *values[MAXV], key[128];
    int nm, nv;
    const char *out, *seed;
    long frames;
} cmp_args;

static int cmp_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    cmp_args *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--recon") || !strcmp(o, "--sweep") || !strcmp(o, "--out") || !strcmp(o, "--seed") ||
        !strcmp(o, "--frames")) {
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
    } else
        return 0;
    if (!strcmp(o, "--out")) a->out = v;
    else if (!strcmp(o, "--seed")) a->seed = v;
    else if (!strcmp(o, "--frames")) {
        if (wt_cli_int(cli, o, v, 1, 10000000, &a->frames) < 0) return -1;
    } else if (!strcmp(o, "--recon")) {
        snprintf(a->list, sizeof a->list, "%s", v);
        if ((a->nm = wt_cli_split(cli, o, a->list, a->methods, MAXM)) < 0) return -1;
        for (int k = 0; k < a->nm; k++)
            if (wt_reconstructor_kind(a->methods[k]) < 0) {
                wt_cli_usage_error(cli, "--recon: unknown reconstructor '%s' (mvm, pcg3, cg9, none)", a->methods[k]);
                return -1;
            }
        if (a->nm <= 0) {
            wt_cli_usage_error(cli, "--recon expects 1 to %d names separated by commas, got '%s'", MAXM, v);
            return -1;
        }
    } else {
        const char *eq = strchr(v, '=');
        if (!eq || eq == v || (size_t)(eq - v) >= sizeof a->key) {
            wt_cli_usage_error(cli, "--sweep expects key=v1,v2,..., got '%s'", v);
            return -1;
        }
        memcpy(a->key, v, (size_t)(eq - v));
        a->key[eq - v] = '\0';
        snprintf(a->sweep, sizeof a->sweep, "%s", eq + 1);
        if ((a->nv = wt_cli_split(cli, o, a->sweep, a->values, MAXV)) < 0) return -1;
        if (a->nv <= 0) {
            wt_cli_usage_error(cli, "--sweep: 1 to %d values expected after '%s='", MAXV, a->key);
            return -1;
        }
    }
    return 1;
}

typedef struct {
    double strehl[WT_MAX_EVAL], wfe[WT_MAX_EVAL];
    double on_axis, field, wfe_field;
    double parts[NPART]; /* ms per frame */
    double total, setup, memory;
} run_result;

static const char *part_names[NPART] = {"atmosphere", "sensors", "reconstruction", "fitting", "control", "evaluation"};

int wt_cli_ensure_dir(wt_context *ctx, const char *path)
{
    char buf[2048];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1;; p++) {
        int end = *p == '\0';
        if (*p == '/' || end) {
            char c = *p;
            *p = '\0';
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return WT_ERROR(ctx, WT_ERR_IO, "cannot create the output directory '%s': %s", buf, strerror(errno));
            *p = c;
        }
        if (end) break;
    }
    struct stat sb;
    if (stat(path, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return WT_ERROR(ctx, WT_ERR_IO, "'%s' is not a directory", path);
    return WT_OK;
}

int wt_cli_mvm_cached(wt_cli *cli, const char *dir, wt_config *cfg, wt_system *sys, int argc, char **argv,
                      wt_mvm **out, double *build_s)
{
    char path[2048];
    int st;
    *build_s = 0.0;
    /* the precision is not part of the system's hash (one system, several storages): it names the file */
    snprintf(path, sizeof path, "%s/cache/mvm-pcg3-%.16s%s%s.h5", dir, cfg->matrix_sha256, cfg->mvm_precision ? "-" : "",
             cfg->mvm_precision ? wt_prec_name(cfg->mvm_precision) : "");
    FILE *f = fopen(path, "rb");
    if (f) {
        fclose(f);
        if (wt_mvm_read(cli->ctx, path, cfg, sys->nact, sys->nslopes, out, NULL) == WT_OK &&
            (*out)->precision != cfg->mvm_precision) {
            wt_mvm_free(*out);
            *out = NULL;
        } else if (*out) {
            if (!cli->quiet) fprintf(stderr, "%s: mvm from the cache %s\n", cli->prog, path);
            return WT_OK;
        }
        if (!cli->quiet) fprintf(stderr, "%s: rebuilding the stale or damaged %s\n", cli->prog, path);
    }
    wt_h5_writer *w = NULL;
    if (!cli->quiet) fprintf(stderr, "%s: building the MVM for %s (hash %.16s)\n", cli->prog, cfg->path, cfg->matrix_sha256);
    if ((st = wt_mvm_build_variant(cli->ctx, sys, cfg, "pcg3", NULL, out)) < 0) return st;
    *build_s = (*out)->stats.t_total;
    if ((st = wt_h5_create(cli->ctx, path, &w)) < 0) return st;
    if ((st = wt_cli_write_provenance(cli, w, cfg, argc, argv)) >= 0 && (st = wt_cli_write_layout(w, sys)) >= 0 &&
        (st = wt_mvm_write(w, *out, cfg, "pcg3")) >= 0) {
        st = wt_h5_commit(w);
        w = NULL;
    }
    wt_h5_abort(w);
    return st;
}

static int run_one(wt_cli *cli, const cmp_args *a, int mi, int vi, wt_config *cfg, wt_system *sys, int argc, char **argv,
                   run_result *res)
{
    int kind = wt_reconstructor_kind(a->methods[mi]), st;
    wt_mvm *mvm = NULL;
    wt_loop *lp = NULL;
    double build = 0.0;
    memset(res, 0, sizeof *res);
    if (kind == WT_RECON_MVM && (st = wt_cli_mvm_cached(cli, a->out, cfg, sys, argc, argv, &mvm, &build)) < 0) return st;
    wt_loop_options o = {.recon = kind, .mvm = mvm, .iterations = -1, .seed = cfg->seed, .noise = cfg->noise};
    double t0 = wt_time_now();
    if ((st = wt_loop_alloc(cli->ctx, sys, &o, &lp)) < 0) goto out;
    res->setup = wt_time_now() - t0 + build;
    char label[256];
    if (a->nv) snprintf(label, sizeof label, "%s %s=%s", a->methods[mi], a->key, a->values[vi]);
    else snprintf(label, sizeof label, "%s", a->methods[mi]);
    wt_progress pr;
    wt_progress_start(&pr, label, "frames", cfg->frames);
    if (cli->quiet) pr.enabled = 0;
    double r0 = wt_time_now(), sum = 0.0;
    for (long t = 0; t < cfg->frames; t++) {
        if ((st = wt_loop_step(lp)) < 0) goto out;
        sum += wt_loop_field_strehl(lp);
        char extra[64];
        snprintf(extra, sizeof extra, "field SE Strehl %.3f", sum / (t + 1));
        wt_progress_update(&pr, t + 1, extra);
    }
    wt_progress_end(&pr);
    double run = wt_time_now() - r0;
    const wt_strehl_le *le = wt_loop_le(lp);
    double fw = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        res->strehl[j] = wt_strehl_le_strehl(le, j);
        res->wfe[j] = wt_strehl_le_wfe(le, j) * 1e9;
        res->field += res->strehl[j] / sys->neval;
        fw += res->wfe[j] * res->wfe[j] / sys->neval;
    }
    res->on_axis = res->strehl[sys->eval_centre];
    res->wfe_field = sqrt(fw);
    wt_loop_times tm = wt_loop_get_times(lp);
    double v[NPART] = {tm.atmosphere, tm.sensors, tm.reconstruction, tm.fitting, tm.control, tm.evaluation};
    for (int k = 0; k < NPART; k++) res->parts[k] = v[k] / cfg->frames * 1e3;
    res->total = run / cfg->frames * 1e3;
    if (kind == WT_RECON_MVM) /* R and RA: 4 bytes an element in fp32, 2 in fp16/bf16 (+ the row scales) */
        res->memory = (cfg->mvm_precision ? 2.0 : 4.0) * (double)sys->nact * (double)(sys->nslopes + sys->nact) +
                      (cfg->mvm_precision ? 8.0 * (double)sys->nact : 0.0);
    else if (kind != WT_RECON_NONE) res->memory = wt_tomography_bytes(wt_reconstructor_tomography(wt_loop_reconstructor(lp)));
    if (!cli->quiet)
        fprintf(stderr, "  %-28s LE Strehl on-axis %.4f field %.4f, WFE %.1f nm, %.1f ms/frame (reconstruction %.2f ms)\n",
                label, res->on_axis, res->field, res->wfe_field, res->total, res->parts[2] + res->parts[3]);
out:
    wt_loop_free(lp);
    wt_mvm_free(mvm);
    return st;
}

static int write_results(wt_cli *cli, const cmp_args *a, const wt_config *cfg, const wt_system *sys, run_result *R,
                         int nv, int argc, char **argv)
{
    int st;
    char path[2048];
    wt_h5_writer *w = NULL;
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    if ((st = wt_h5_create(cli->ctx, path, &w)) < 0) return st;
    int nm = a->nm, nd = sys->neval;
    double *buf = malloc((size_t)nm * nv * (nd > NPART ? nd : NPART) * sizeof *buf);
    if (!buf) {
        wt_h5_abort(w);
        return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory writing %s", path);
    }
    char methods[256] = "", values[2048] = "";
    for (int m = 0; m < nm; m++) snprintf(methods + strlen(methods), sizeof methods - strlen(methods), "%s%s", m ? "," : "", a->methods[m]);
    for (int v = 0; v < nv; v++)
        snprintf(values + strlen(values), sizeof values - strlen(values), "%s%s", v ? "," : "", a->nv ? a->values[v] : "");
    st = wt_cli_write_provenance(cli, w, cfg, argc, argv);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "methods", methods);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_key", a->nv ? a->key : "");
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_values", values);
    int64_t d3[3] = {nm, nv, nd}, d2[2] = {nm, nv}, dp[3] = {nm, nv, NPART};
#define PUT3(name, field, units, desc)                                                                     \
    if (st >= 0) {                                                                                         \
        for (int m = 0; m < nm; m++)                                                                       \
            for (int v = 0; v < nv; v++)                                                                   \
                for (int j = 0; j < nd; j++) buf[((size_t)m * nv + v) * nd + j] = R[m * nv + v].field[j];  \
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 3, d3, buf, units, desc);                         \
    }
#define PUT2(name, field, units, desc)                                                                     \
    if (st >= 0) {                                                                                         \
        for (int m = 0; m < nm; m++)                                                                       \
            for (int v = 0; v < nv; v++) buf[(size_t)m * nv + v] = R[m * nv + v].field;                   \
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d2, buf, units, desc);                         \
    }
    PUT3("strehl_le", strehl, "", "LE Strehl [method, sweep value, evaluation direction]")
    PUT3("wfe_le", wfe, "nm", "residual WFE [method, sweep value, evaluation direction]")
    PUT2("strehl_le_on_axis", on_axis, "", "LE Strehl on axis [method, sweep value]")
    PUT2("strehl_le_field", field, "", "LE Strehl averaged over the field [method, sweep value]")
    PUT2("wfe_le_field", wfe_field, "nm", "residual WFE, rms over the field [method, sweep value]")
    PUT2("time_per_frame", total, "ms", "wall time per simulated frame [method, sweep value]")
    PUT2("setup_time", setup, "s", "set-up time incl. an MVM build [method, sweep value]")
    PUT2("reconstructor_memory", memory, "B", "memory of the reconstructor's matrices/operators [method, sweep value]")
#undef PUT2
#undef PUT3
    if (st >= 0) {
        for (int m = 0; m < nm; m++)
            for (int v = 0; v < nv; v++)
                for (int k = 0; k < NPART; k++) buf[((size_t)m * nv + v) * NPART + k] = R[m * nv + v].parts[k];
        st = wt_h5_write(w, "time_parts", WT_H5_F64, WT_H5_F64, 3, dp, buf, "ms",
                         "time per frame by part [method, sweep value, part]; parts in the attribute 'parts'");
    }
    if (st >= 0)
        st = wt_h5_attr_write_string(w, "time_parts", "parts", "atmosphere,sensors,reconstruction,fitting,control,evaluation");
    if (st >= 0) {
        double tx[WT_MAX_EVAL], ty[WT_MAX_EVAL];
        for (int j = 0; j < nd; j++) tx[j] = sys->eval_x[j] / WT_ARCSEC, ty[j] = sys->eval_y[j] / WT_ARCSEC;
        int64_t dn[1] = {nd};
        st = wt_h5_write(w, "eval/theta_x", WT_H5_F64, WT_H5_F64, 1, dn, tx, "arcsec", "evaluation direction x");
        if (st >= 0) st = wt_h5_write(w, "eval/theta_y", WT_H5_F64, WT_H5_F64, 1, dn, ty, "arcsec", "evaluation direction y");
    }
    free(buf);
    if (st < 0) {
        wt_h5_abort(w);
        return st;
    }
    return wt_h5_commit(w);
}

/* summary.csv and report.md through temporaries renamed at the end */
static int write_text_reports(wt_cli *cli, const cmp_args *a, const wt_config *cfg, const wt_system *sys,
                              const run_result *R, int nv, int argc, char **argv)
{
    char path[2048], tmp[2100];
    snprintf(path, sizeof path, "%s/summary.csv", a->out);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': %s", tmp, strerror(errno));
    fprintf(f, "method,%s,strehl_le_on_axis,strehl_le_field,wfe_field_nm,time_per_frame_ms,reconstruction_ms,"
               "setup_s,reconstructor_memory_bytes\n",
            a->nv ? a->key : "sweep");
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) {
            const run_result *r = &R[m * nv + v];
            fprintf(f, "%s,%s,%.5f,%.5f,%.2f,%.3f,%.3f,%.2f,%.0f\n", a->methods[m], a->nv ? a->values[v] : "", r->on_axis,
                    r->field, r->wfe_field, r->total, r->parts[2] + r->parts[3], r->setup, r->memory);
        }
    if (fclose(f) != 0 || rename(tmp, path) != 0) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s'", path);

    snprintf(path, sizeof path, "%s/report.md", a->out);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    f = fopen(tmp, "w");
    if (!f) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': %s", tmp, strerror(errno));
    fprintf(f, "# wavetomo comparison\n\n");
    fprintf(f, "System `%s` (config hash `%.16s`), %d frames at %.0f Hz (%d settle), seed %llu, Strehl at %.0f nm.\n\n",
            cfg->path, cfg->matrix_sha256, cfg->frames, cfg->rate, cfg->settle_frames, (unsigned long long)cfg->seed,
            cfg->eval_wavelength * 1e9);
    fprintf(f, "Command:\n\n```\nwavetomo");
    for (int i = 0; i < argc; i++) fprintf(f, " %s", argv[i]); /* argv[0] is the subcommand */
    fprintf(f, "\n```\n\nEvery run uses the same turbulence and noise (same seed). LE = long exposure.\n\n");
    fprintf(f, "| method | %s | LE Strehl on-axis | LE Strehl field | WFE field [nm] | ms/frame | reconstruction ms | "
               "reconstructor memory [MB] |\n|---|---|---|---|---|---|---|---|\n",
            a->nv ? a->key : "–");
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) {
            const run_result *r = &R[m * nv + v];
            fprintf(f, "| %s | %s | %.4f | %.4f | %.1f | %.1f | %.2f | %.1f |\n", a->methods[m], a->nv ? a->values[v] : "–",
                    r->on_axis, r->field, r->wfe_field, r->total, r->parts[2] + r->parts[3], r->memory / 1e6);
        }
    fprintf(f, "\n");
    if (a->nv > 1) fprintf(f, "![LE Strehl against %s](strehl_vs_sweep.png)\n\n", a->key);
    for (int v = 0; v < nv; v++)
        for (int m = 0; m < a->nm; m++)
            fprintf(f, "![%s%s%s](map_%s_%d.png) ", a->methods[m], a->nv ? " " : "", a->nv ? a->values[v] : "",
                    a->methods[m], v);
    fprintf(f, "\n\n![time per frame](time_per_frame.png)\n\nFiles: results.h5 (all numbers, see README), summary.csv.\n");
    (void)sys;
    if (fclose(f) != 0 || rename(tmp, path) != 0) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s'", path);
    return WT_OK;
}

static int make_plots(wt_cli *cli, const cmp_args *a, const wt_system *sys, const run_result *R, int nv)
{
    int st = WT_OK, nm = a->nm;
    char path[2048], title[256];
    double x[MAXV], on[MAXM * MAXV], fi[MAXM * MAXV];
    int numeric = 1, positive = 1;
    for (int v = 0; v < nv; v++) {
        char *end = NULL;
        x[v] = a->nv ? strtod(a->values[v], &end) : v;
        if (a->nv && (!end || *end)) numeric = 0;
        if (x[v] <= 0) positive = 0;
    }
    if (!numeric)
        for (int v = 0; v < nv; v++) x[v] = v + 1;
    for (int m = 0; m < nm; m++)
        for (int v = 0; v < nv; v++) on[m * nv + v] = R[m * nv + v].on_axis, fi[m * nv + v] = R[m * nv + v].field;
    if (a->nv > 1) {
        snprintf(path, sizeof path, "%s/strehl_vs_sweep.png", a->out);
        double span = x[nv - 1] / x[0];
        int logx = numeric && positive && span > 20.0;
        if ((st = wt_plot_strehl_sweep(cli->ctx, path, "LE Strehl (on-axis solid, field average dashed)", a->key, nm,
                                       (const char *const *)a->methods, nv, x, on, fi, logx)) < 0)
            return st;
    }
    int g = sys->cfg->eval_grid;
    double coords[16], vmin = 1.0, vmax = 0.0;
    for (int i = 0; i < g; i++) coords[i] = (i - 0.5 * (g - 1)) * sys->cfg->eval_spacing / WT_ARCSEC;
    for (int k = 0; k < nm * nv; k++)
        for (int j = 0; j < sys->neval; j++) vmin = fmin(vmin, R[k].strehl[j]), vmax = fmax(vmax, R[k].strehl[j]);
    for (int m = 0; m < nm; m++)
        for (int v = 0; v < nv; v++) {
            snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
            snprintf(title, sizeof title, "LE Strehl, %s%s%s%s", a->methods[m], a->nv ? ", " : "", a->nv ? a->key : "",
                     a->nv ? "=" : "");
            if (a->nv) snprintf(title + strlen(title), sizeof title - strlen(title), "%s", a->values[v]);
            if ((st = wt_plot_strehl_map(cli->ctx, path, title, g, coords, R[m * nv + v].strehl, vmin, vmax)) < 0)
                return st;
        }
    double times[MAXM * NPART];
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < NPART; k++) times[m * NPART + k] = R[m * nv + 0].parts[k];
    snprintf(path, sizeof path, "%s/time_per_frame.png", a->out);
    snprintf(title, sizeof title, "time per simulated frame%s%s%s", a->nv ? " (" : "", a->nv ? a->key : "",
             a->nv ? " first value)" : "");
    return wt_plot_time_bars(cli->ctx, path, title, nm, (const char *const *)a->methods, NPART, part_names, times);
}

int wt_cmd_compare(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo compare", help)) return 1;
    cmp_args a;
    memset(&a, 0, sizeof a);
    a.frames = -1;
    snprintf(a.list, sizeof a.list, "mvm,pcg3,cg9");
    a.nm = wt_cli_split(&cli, "--recon", a.list, a.methods, MAXM);
    int rc = wt_cli_parse(&cli, argc, argv, cmp_option, &a);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    if (!a.out || !cli.config_path) {
        rc = wt_cli_usage_error(&cli, "%s is required", !cli.config_path ? "--config FILE" : "--out DIR");
        wt_cli_done(&cli);
        return rc;
    }
    int nv = a.nv ? a.nv : 1, st = WT_OK, base_nset = cli.nset;
    char sweep_set[1200], cache[2100];
    if ((rc = wt_cli_run_overrides(&cli, a.frames, a.seed)) != 0) {
        wt_cli_done(&cli);
        return rc;
    }
    base_nset = cli.nset;
    run_result *R = calloc((size_t)a.nm * nv, sizeof *R);
    wt_config *cfg = NULL, *first = NULL;
    wt_system *sys = NULL, *first_sys = NULL;
    if (!R) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory");
        goto fail;
    }
    snprintf(cache, sizeof cache, "%s/cache", a.out);
    if ((st = wt_cli_ensure_dir(cli.ctx, a.out)) < 0 || (st = wt_cli_ensure_dir(cli.ctx, cache)) < 0) goto fail;
    {
        char probe[2200];
        snprintf(probe, sizeof probe, "%s/results.h5", a.out);
        if ((st = wt_cli_check_output(&cli, probe, 0, NULL, NULL)) < 0) goto fail;
    }
    for (int v = 0; v < nv; v++) {
        cli.nset = base_nset; /* drops the previous value's sweep (and settle) overrides */
        if (a.nv) {
            snprintf(sweep_set, sizeof sweep_set, "%s=%s", a.key, a.values[v]);
            cli.set[cli.nset++] = sweep_set;
        }
        if ((st = wt_cli_read_config(&cli, NULL, &cfg)) < 0) goto fail;
        if ((st = wt_system_alloc(cli.ctx, cfg, &sys)) < 0) goto fail;
        for (int m = 0; m < a.nm; m++)
            if ((st = run_one(&cli, &a, m, v, cfg, sys, argc, argv, &R[m * nv + v])) < 0) goto fail;
        if (v == 0) {
            first = cfg, first_sys = sys;
        } else {
            wt_system_free(sys);
            wt_config_free(cli.ctx, cfg);
        }
        cfg = NULL, sys = NULL;
    }
    if ((st = write_results(&cli, &a, first, first_sys, R, nv, argc, argv)) < 0) goto fail;
    if ((st = write_text_reports(&cli, &a, first, first_sys, R, nv, argc, argv)) < 0) goto fail;
    if ((st = make_plots(&cli, &a, first_sys, R, nv)) < 0) goto fail;
    printf("report: %s/report.md (results.h5, summary.csv, PNG figures in %s)\n", a.out, a.out);
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_system_free(first_sys);
    wt_config_free(cli.ctx, first);
    free(R);
    wt_cli_done(&cli);
    return rc;
}
