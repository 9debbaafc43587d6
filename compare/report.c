/* compare/report.c: the files of `wavetomo compare` (SPEC §10) and their checks; see report.h. */
#include "compare/report.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare/plot.h"
#include "core/io/h5.h"

#define NP WT_COMPARE_NPART

static int cols(const wt_cmp_cases *a) { return a->nv ? a->nv : 1; }
static const char *val(const wt_cmp_cases *a, int v) { return a->nv ? a->values[v] : ""; }

int wt_cmp_check_outputs(wt_cli *cli, const wt_cmp_cases *a)
{
    char path[2200], owner[2200];
    int st, nv = cols(a);
    snprintf(owner, sizeof owner, "%s/results.h5", a->out);
    if ((st = wt_cli_check_output(cli, owner, 0, NULL, NULL)) < 0) return st;
    snprintf(path, sizeof path, "%s/summary.csv", a->out);
    if ((st = wt_cli_check_text_output(cli, path, "method,", NULL)) < 0) return st;
    snprintf(path, sizeof path, "%s/report.md", a->out);
    if ((st = wt_cli_check_text_output(cli, path, "# wavetomo comparison", NULL)) < 0) return st;
    snprintf(path, sizeof path, "%s/strehl_vs_sweep.png", a->out);
    if ((st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
    snprintf(path, sizeof path, "%s/time_per_frame.png", a->out);
    if ((st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) {
            snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
            if ((st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
        }
    return WT_OK;
}

/* The per-case arrays of results.h5: name, units, description, and where each value sits in a result. */
typedef struct {
    const char *name, *units, *desc;
    size_t off; /* offsetof the field in wt_compare_result */
    int per_dir;
} field;

#define OFF(f) offsetof(wt_compare_result, f)
static const field fields[] = {
    {"strehl_le", "", "LE Strehl [method, sweep value, evaluation direction]", OFF(strehl), 1},
    {"wfe_le", "nm", "residual WFE [method, sweep value, evaluation direction]", OFF(wfe), 1},
    {"strehl_le_on_axis", "", "LE Strehl on axis [method, sweep value]", OFF(on_axis), 0},
    {"strehl_le_field", "", "LE Strehl averaged over the field [method, sweep value]", OFF(field), 0},
    {"wfe_le_field", "nm", "residual WFE, rms over the field [method, sweep value]", OFF(wfe_field), 0},
    {"time_per_frame", "ms", "wall time per simulated frame [method, sweep value]", OFF(total), 0},
    {"setup_time", "s", "set-up time incl. an MVM build [method, sweep value]", OFF(setup), 0},
    {"reconstructor_memory", "B", "memory of the reconstructor's matrices/operators [method, sweep value]", OFF(memory), 0},
    {"time_parts", "ms", "time per frame by part [method, sweep value, part]; parts in the attribute 'parts'", OFF(parts), 2},
};
#define NFIELDS ((int)(sizeof fields / sizeof *fields))

static int width(const field *f, int nd) { return f->per_dir == 1 ? nd : f->per_dir == 2 ? NP : 1; }

static int write_results(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                         const wt_system *sys, const wt_compare_result *R, int argc, char **argv)
{
    int st, nm = a->nm, nv = cols(a), nd = sys->neval;
    char path[2200];
    wt_h5_writer *w = NULL;
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    double *buf = malloc((size_t)nm * nv * (nd > NP ? nd : NP) * sizeof *buf);
    if (!buf) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory writing %s", path);
    if ((st = wt_h5_create(cli->ctx, path, &w)) < 0) goto out;
    st = wt_cli_write_provenance(cli, w, cfg, argc, argv);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "methods", plan->methods);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_key", plan->sweep_key);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_values", plan->sweep_values);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "config_sha256", plan->config_sha256);
    if (st >= 0) st = wt_h5_attr_write_int64(w, "/", "frames", plan->frames);
    for (int k = 0; k < NFIELDS && st >= 0; k++) {
        const field *f = &fields[k];
        int nw = width(f, nd);
        for (int c = 0; c < nm * nv; c++)
            for (int j = 0; j < nw; j++) buf[(size_t)c * nw + j] = ((const double *)((const char *)&R[c] + f->off))[j];
        int64_t d[3] = {nm, nv, nw};
        st = wt_h5_write(w, f->name, WT_H5_F64, WT_H5_F64, f->per_dir ? 3 : 2, d, buf, f->units, f->desc);
    }
    if (st >= 0) {
        char parts[128] = "";
        for (int k = 0; k < NP; k++) snprintf(parts + strlen(parts), sizeof parts - strlen(parts), "%s%s", k ? "," : "", wt_compare_part_name(k));
        st = wt_h5_attr_write_string(w, "time_parts", "parts", parts);
    }
    if (st >= 0) {
        int64_t d2[2] = {nm, nv}, done[WT_COMPARE_MAXM * WT_COMPARE_MAXV];
        for (int c = 0; c < nm * nv; c++) done[c] = R[c].done;
        st = wt_h5_write(w, "done", WT_H5_I64, WT_H5_I64, 2, d2, done, "",
                         "1: the case ran to its last frame; 0: missing (interrupted; its numbers are 0), "
                         "`compare --resume` runs it [method, sweep value]");
    }
    if (st >= 0) {
        double tx[WT_MAX_EVAL], ty[WT_MAX_EVAL];
        for (int j = 0; j < nd; j++) tx[j] = sys->eval_x[j] / WT_ARCSEC, ty[j] = sys->eval_y[j] / WT_ARCSEC;
        int64_t dn[1] = {nd};
        st = wt_h5_write(w, "eval/theta_x", WT_H5_F64, WT_H5_F64, 1, dn, tx, "arcsec", "evaluation direction x");
        if (st >= 0) st = wt_h5_write(w, "eval/theta_y", WT_H5_F64, WT_H5_F64, 1, dn, ty, "arcsec", "evaluation direction y");
    }
    if (st >= 0) {
        st = wt_h5_commit(w);
        w = NULL;
    }
out:
    wt_h5_abort(w);
    free(buf);
    return st;
}

int wt_cmp_read_previous(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *want, wt_compare_result *R,
                         int *ndone)
{
    char path[2200], *s = NULL;
    wt_h5_reader *r = NULL;
    wt_compare_plan have;
    int64_t seed = 0, ndir = 0, dims[3];
    int st, nm = a->nm, nv = cols(a), rank;
    double *buf = NULL;
    *ndone = 0;
    memset(&have, 0, sizeof have);
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    if ((st = wt_h5_open(cli->ctx, path, &r)) < 0) return st;
    struct { const char *name; char *dst; size_t n; } attrs[] = {
        {"methods", have.methods, sizeof have.methods}, {"sweep_key", have.sweep_key, sizeof have.sweep_key},
        {"sweep_values", have.sweep_values, sizeof have.sweep_values},
        {"config_sha256", have.config_sha256, sizeof have.config_sha256}};
    for (int k = 0; k < 4 && st >= 0; k++) {
        if ((st = wt_h5_attr_read_string(r, "/", attrs[k].name, &s)) >= 0) snprintf(attrs[k].dst, attrs[k].n, "%s", s);
        wt_free(cli->ctx, s);
        s = NULL;
    }
    if (st >= 0) st = wt_h5_attr_read_int64(r, "/", "seed", &seed);
    if (st >= 0) st = wt_h5_attr_read_int64(r, "/", "frames", &have.frames);
    have.seed = (uint64_t)seed;
    if (st >= 0) st = wt_compare_plan_check(cli->ctx, path, &have, want);
    if (st >= 0) st = wt_h5_dims(r, "strehl_le", &rank, dims);
    ndir = dims[2];
    if (st >= 0 && (rank != 3 || ndir < 1 || ndir > WT_MAX_EVAL))
        st = WT_ERROR(cli->ctx, WT_ERR_FORMAT, "%s: dataset 'strehl_le' has an unexpected shape", path);
    int64_t done[WT_COMPARE_MAXM * WT_COMPARE_MAXV], e2[2] = {nm, nv};
    if (st >= 0) st = wt_h5_read(r, "done", WT_H5_I64, 2, e2, NULL, done, (size_t)nm * nv);
    if (st >= 0 && !(buf = malloc((size_t)nm * nv * (ndir > NP ? ndir : NP) * sizeof *buf)))
        st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory reading %s", path);
    for (int k = 0; k < NFIELDS && st >= 0; k++) {
        const field *f = &fields[k];
        int nw = f->per_dir == 1 ? (int)ndir : width(f, 0);
        int64_t e[3] = {nm, nv, nw};
        if ((st = wt_h5_read(r, f->name, WT_H5_F64, f->per_dir ? 3 : 2, e, NULL, buf, (size_t)nm * nv * nw)) < 0) break;
        for (int c = 0; c < nm * nv; c++)
            if (done[c] == 1)
                memcpy((char *)&R[c] + f->off, buf + (size_t)c * nw, (size_t)nw * sizeof *buf);
    }
    for (int c = 0; c < nm * nv && st >= 0; c++)
        if (done[c] == 1) R[c].done = 1, ++*ndone;
    free(buf);
    wt_h5_close(r);
    return st;
}

static int write_text(wt_cli *cli, const wt_cmp_cases *a, const wt_config *cfg, const wt_compare_result *R,
                      int missing, int argc, char **argv)
{
    char path[2200], tmp[2300];
    int nv = cols(a);
    const char *key = a->nv ? a->key : "sweep";
    for (int doc = 0; doc < 2; doc++) {
        snprintf(path, sizeof path, "%s/%s", a->out, doc ? "report.md" : "summary.csv");
        snprintf(tmp, sizeof tmp, "%s.tmp", path);
        FILE *f = fopen(tmp, "w");
        if (!f) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s': %s", tmp, strerror(errno));
        if (!doc)
            fprintf(f, "method,%s,strehl_le_on_axis,strehl_le_field,wfe_field_nm,time_per_frame_ms,reconstruction_ms,"
                       "setup_s,reconstructor_memory_bytes,done\n", key);
        else {
            fprintf(f, "# wavetomo comparison\n\nSystem `%s` (config hash `%.16s`), %d frames at %.0f Hz (%d settle), seed "
                       "%llu, Strehl at %.0f nm.\n\nCommand:\n\n```\nwavetomo", cfg->path, cfg->matrix_sha256, cfg->frames,
                    cfg->rate, cfg->settle_frames, (unsigned long long)cfg->seed, cfg->eval_wavelength * 1e9);
            for (int i = 0; i < argc; i++) fprintf(f, " %s", argv[i]); /* argv[0] is the subcommand */
            fprintf(f, "\n```\n\nEvery run uses the same turbulence and noise (same seed). LE = long exposure.\n\n");
            if (missing)
                fprintf(f, "**Incomplete: %d of %d cases are missing (interrupted); `--resume` with the same options runs "
                           "them.**\n\n", missing, a->nm * nv);
            fprintf(f, "| method | %s | LE Strehl on-axis | LE Strehl field | WFE field [nm] | ms/frame | reconstruction ms "
                       "| reconstructor memory [MB] |\n|---|---|---|---|---|---|---|---|\n", a->nv ? a->key : "–");
        }
        for (int m = 0; m < a->nm; m++)
            for (int v = 0; v < nv; v++) {
                const wt_compare_result *r = &R[m * nv + v];
                const char *vs = a->nv ? a->values[v] : (doc ? "–" : "");
                if (!doc && r->done)
                    fprintf(f, "%s,%s,%.5f,%.5f,%.2f,%.3f,%.3f,%.2f,%.0f,1\n", a->methods[m], vs, r->on_axis, r->field,
                            r->wfe_field, r->total, r->parts[2] + r->parts[3], r->setup, r->memory);
                else if (!doc)
                    fprintf(f, "%s,%s,,,,,,,,0\n", a->methods[m], vs);
                else if (r->done)
                    fprintf(f, "| %s | %s | %.4f | %.4f | %.1f | %.1f | %.2f | %.1f |\n", a->methods[m], vs, r->on_axis,
                            r->field, r->wfe_field, r->total, r->parts[2] + r->parts[3], r->memory / 1e6);
                else
                    fprintf(f, "| %s | %s | missing | | | | | |\n", a->methods[m], vs);
            }
        if (doc) {
            fprintf(f, "\n");
            if (a->nv > 1 && !missing) fprintf(f, "![LE Strehl against %s](strehl_vs_sweep.png)\n\n", a->key);
            for (int v = 0; v < nv; v++)
                for (int m = 0; m < a->nm; m++)
                    if (R[m * nv + v].done)
                        fprintf(f, "![%s%s%s](map_%s_%d.png) ", a->methods[m], a->nv ? " " : "", val(a, v), a->methods[m], v);
            if (!missing) fprintf(f, "\n\n![time per frame](time_per_frame.png)");
            fprintf(f, "\n\nFiles: results.h5 (all numbers, see README), summary.csv.\n");
        }
        if (fclose(f) != 0 || rename(tmp, path) != 0) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s'", path);
    }
    return WT_OK;
}

/* The figures; the sweep curve and the time bars only when every case is done (no holes in a curve). */
static int make_plots(wt_cli *cli, const wt_cmp_cases *a, const wt_system *sys, const wt_compare_result *R, int missing)
{
    int st, nm = a->nm, nv = cols(a), g = sys->cfg->eval_grid;
    char path[2200], title[256];
    double x[WT_COMPARE_MAXV], on[WT_COMPARE_MAXM * WT_COMPARE_MAXV], fi[WT_COMPARE_MAXM * WT_COMPARE_MAXV];
    int numeric = 1, positive = 1;
    for (int v = 0; v < nv; v++) {
        char *end = NULL;
        x[v] = a->nv ? strtod(a->values[v], &end) : v;
        if (a->nv && (!end || *end)) numeric = 0;
        if (x[v] <= 0) positive = 0;
    }
    for (int v = 0; v < nv && !numeric; v++) x[v] = v + 1;
    for (int c = 0; c < nm * nv; c++) on[c] = R[c].on_axis, fi[c] = R[c].field;
    if (a->nv > 1 && !missing) {
        snprintf(path, sizeof path, "%s/strehl_vs_sweep.png", a->out);
        int logx = numeric && positive && x[nv - 1] / x[0] > 20.0;
        if ((st = wt_plot_strehl_sweep(cli->ctx, path, "LE Strehl (on-axis solid, field average dashed)", a->key, nm,
                                       (const char *const *)a->methods, nv, x, on, fi, logx)) < 0)
            return st;
    }
    double coords[16], vmin = 1.0, vmax = 0.0;
    for (int i = 0; i < g; i++) coords[i] = (i - 0.5 * (g - 1)) * sys->cfg->eval_spacing / WT_ARCSEC;
    for (int c = 0; c < nm * nv; c++)
        for (int j = 0; j < sys->neval && R[c].done; j++) vmin = fmin(vmin, R[c].strehl[j]), vmax = fmax(vmax, R[c].strehl[j]);
    for (int c = 0; c < nm * nv; c++) {
        if (!R[c].done) continue;
        int m = c / nv, v = c % nv;
        snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
        snprintf(title, sizeof title, "LE Strehl, %s%s%s%s%s", a->methods[m], a->nv ? ", " : "", a->nv ? a->key : "",
                 a->nv ? "=" : "", val(a, v));
        if ((st = wt_plot_strehl_map(cli->ctx, path, title, g, coords, R[c].strehl, vmin, vmax)) < 0) return st;
    }
    if (missing) return WT_OK;
    double times[WT_COMPARE_MAXM * NP];
    const char *names[NP];
    for (int k = 0; k < NP; k++) names[k] = wt_compare_part_name(k);
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < NP; k++) times[m * NP + k] = R[m * nv].parts[k];
    snprintf(path, sizeof path, "%s/time_per_frame.png", a->out);
    snprintf(title, sizeof title, "time per simulated frame%s%s%s", a->nv ? " (" : "", a->nv ? a->key : "",
             a->nv ? " first value)" : "");
    return wt_plot_time_bars(cli->ctx, path, title, nm, (const char *const *)a->methods, NP, names, times);
}

int wt_cmp_write_all(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                     const wt_system *sys, const wt_compare_result *R, int argc, char **argv)
{
    int st, missing = 0;
    for (int c = 0; c < a->nm * cols(a); c++) missing += !R[c].done;
    if ((st = write_results(cli, a, plan, cfg, sys, R, argc, argv)) < 0) return st;
    if ((st = write_text(cli, a, cfg, R, missing, argc, argv)) < 0) return st;
    return make_plots(cli, a, sys, R, missing);
}
