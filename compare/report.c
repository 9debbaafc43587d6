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

/* Every field of the results res[0..n) as datasets GROUP/NAME of dims pre[0..npre) (+ the direction or part). */
static int write_fields(wt_h5_writer *w, const char *group, const wt_compare_result *const *res, int n,
                        const int64_t *pre, int npre, int nd, double *buf)
{
    int st = WT_OK;
    char name[128], desc[400];
    for (int k = 0; k < NFIELDS && st >= 0; k++) {
        const field *f = &fields[k];
        int nw = width(f, nd);
        for (int c = 0; c < n; c++)
            for (int j = 0; j < nw; j++) buf[(size_t)c * nw + j] = ((const double *)((const char *)res[c] + f->off))[j];
        int64_t d[WT_H5_MAX_RANK];
        for (int i = 0; i < npre; i++) d[i] = pre[i];
        d[npre] = nw;
        snprintf(name, sizeof name, "%s%s%s", group, *group ? "/" : "", f->name);
        snprintf(desc, sizeof desc, "%s%s", f->desc, *group ? "; here per seed: a seed index after the sweep value's "
                                                           "(seeds in the root attribute 'seeds')" : "");
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, npre + (f->per_dir ? 1 : 0), d, buf, f->units, desc);
    }
    if (st >= 0) {
        char parts[128] = "";
        for (int k = 0; k < NP; k++) snprintf(parts + strlen(parts), sizeof parts - strlen(parts), "%s%s", k ? "," : "", wt_compare_part_name(k));
        snprintf(name, sizeof name, "%s%stime_parts", group, *group ? "/" : "");
        st = wt_h5_attr_write_string(w, name, "parts", parts);
    }
    return st;
}

/* With several seeds: the standard errors of the means and the paired differences between the methods. */
static int write_statistics(wt_h5_writer *w, const wt_cmp_cases *a, const wt_compare_result *R,
                            const wt_compare_summary *S, double *buf)
{
    int st = WT_OK, nm = a->nm, nv = cols(a), np = nm * (nm - 1) / 2;
    char name[128], pairs[512] = "";
    for (int k = 0; k < WT_NMETRICS && st >= 0; k++) {
        for (int c = 0; c < nm * nv; c++) buf[c] = S[c].se[k];
        int64_t d[2] = {nm, nv};
        snprintf(name, sizeof name, "stderr/%s", wt_compare_metric_name(k));
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d, buf, k == WT_METRIC_WFE ? "nm" : "",
                         "standard error of the mean over the seeds (sample standard deviation / sqrt(seeds done)) "
                         "[method, sweep value]; the mean is the dataset of the same name at the root");
    }
    for (int i = 0, p = 0; i < nm; i++)
        for (int j = i + 1; j < nm; j++, p++)
            snprintf(pairs + strlen(pairs), sizeof pairs - strlen(pairs), "%s%s-%s", p ? "," : "", a->methods[i], a->methods[j]);
    for (int k = 0; k < WT_NMETRICS && st >= 0 && np > 0; k++) {
        double *se = buf + (size_t)np * nv;
        for (int i = 0, p = 0; i < nm; i++)
            for (int j = i + 1; j < nm; j++, p++)
                for (int v = 0; v < nv; v++) {
                    int n;
                    wt_compare_paired(&R[wt_cmp_case(a, i, v, 0)], &R[wt_cmp_case(a, j, v, 0)], a->ns, k,
                                      &buf[p * nv + v], &se[p * nv + v], &n);
                }
        int64_t d[2] = {np, nv};
        snprintf(name, sizeof name, "difference/%s", wt_compare_metric_name(k));
        st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d, buf, k == WT_METRIC_WFE ? "nm" : "",
                         "paired difference A - B over the seeds done by both, mean [pair, sweep value]; pairs "
                         "in the group attribute 'pairs'");
        snprintf(name, sizeof name, "difference/%s_se", wt_compare_metric_name(k));
        if (st >= 0)
            st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d, se, k == WT_METRIC_WFE ? "nm" : "",
                             "standard error of the paired difference [pair, sweep value]; within the noise when "
                             "|mean| < 2 SE");
    }
    if (st >= 0 && np > 0) st = wt_h5_attr_write_string(w, "difference", "pairs", pairs);
    return st;
}

static int write_results(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                         const wt_system *sys, const wt_compare_result *R, const wt_compare_summary *S, int argc,
                         char **argv)
{
    int st, nm = a->nm, nv = cols(a), nd = sys->neval, ns = a->ns, nc = nm * nv * ns;
    char path[2200];
    wt_h5_writer *w = NULL;
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    double *buf = malloc((size_t)nc * (nd > NP ? nd : NP) * sizeof *buf);
    const wt_compare_result **res = malloc((size_t)nc * sizeof *res);
    int64_t *done = malloc((size_t)nc * sizeof *done);
    if (!buf || !res || !done) {
        free(buf), free(res), free(done);
        return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory writing %s", path);
    }
    if ((st = wt_h5_create(cli->ctx, path, &w)) < 0) goto out;
    st = wt_cli_write_provenance(cli, w, cfg, argc, argv);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "methods", plan->methods);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_key", plan->sweep_key);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "sweep_values", plan->sweep_values);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "seeds", plan->seeds);
    if (st >= 0) st = wt_h5_attr_write_string(w, "/", "config_sha256", plan->config_sha256);
    if (st >= 0) st = wt_h5_attr_write_int64(w, "/", "frames", plan->frames);
    /* the root datasets: per method and sweep value, the mean over the seeds (the value itself with one) */
    for (int c = 0; c < nm * nv; c++) res[c] = &S[c].mean;
    int64_t d2[2] = {nm, nv}, ds[3] = {nm, nv, ns};
    if (st >= 0) st = write_fields(w, "", res, nm * nv, d2, 2, nd, buf);
    if (st >= 0) {
        for (int c = 0; c < nm * nv; c++) done[c] = S[c].mean.done;
        st = wt_h5_write(w, "done", WT_H5_I64, WT_H5_I64, 2, d2, done, "",
                         "1: the case ran to its last frame (with several seeds: every seed did); 0: missing "
                         "(interrupted; its numbers are 0 or the mean of the seeds done), `compare --resume` runs it "
                         "[method, sweep value]");
    }
    if (ns > 1 && st >= 0) { /* every seed's own values, and the statistics */
        for (int c = 0; c < nc; c++) res[c] = &R[c], done[c] = R[c].done;
        st = write_fields(w, "seeds", res, nc, ds, 3, nd, buf);
        if (st >= 0)
            st = wt_h5_write(w, "seeds/done", WT_H5_I64, WT_H5_I64, 3, ds, done, "",
                             "1: the run of this seed is done [method, sweep value, seed]");
        if (st >= 0) st = write_statistics(w, a, R, S, buf);
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
    free(res);
    free(done);
    return st;
}

int wt_cmp_read_previous(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *want, wt_compare_result *R,
                         int *ndone)
{
    char path[2200], name[128], *s = NULL;
    wt_h5_reader *r = NULL;
    wt_compare_plan have;
    int64_t seed = 0, ndir = 0, dims[WT_H5_MAX_RANK] = {0};
    int st, nm = a->nm, nv = cols(a), ns = a->ns, nc = nm * nv * ns, rank = 1;
    const char *group = ns > 1 ? "seeds/" : "";
    double *buf = NULL;
    int64_t *done = NULL;
    *ndone = 0;
    memset(&have, 0, sizeof have);
    snprintf(path, sizeof path, "%s/results.h5", a->out);
    if ((st = wt_h5_open(cli->ctx, path, &r)) < 0) return st;
    struct { const char *name; char *dst; size_t n; } attrs[] = {
        {"methods", have.methods, sizeof have.methods}, {"sweep_key", have.sweep_key, sizeof have.sweep_key},
        {"sweep_values", have.sweep_values, sizeof have.sweep_values},
        {"config_sha256", have.config_sha256, sizeof have.config_sha256}, {"seeds", have.seeds, sizeof have.seeds}};
    for (int k = 0; k < 5 && st >= 0; k++) {
        if ((st = wt_h5_attr_read_string(r, "/", attrs[k].name, &s)) >= 0) snprintf(attrs[k].dst, attrs[k].n, "%s", s);
        wt_free(cli->ctx, s);
        s = NULL;
    }
    if (st >= 0) st = wt_h5_attr_read_int64(r, "/", "seed", &seed);
    if (st >= 0) st = wt_h5_attr_read_int64(r, "/", "frames", &have.frames);
    have.seed = (uint64_t)seed;
    if (st >= 0) st = wt_compare_plan_check(cli->ctx, path, &have, want);
    snprintf(name, sizeof name, "%sstrehl_le", group);
    if (st >= 0) st = wt_h5_dims(r, name, &rank, dims);
    ndir = dims[rank - 1];
    /* [method, sweep value(, seed), direction] */
    const int npre = ns > 1 ? 3 : 2;
    if (st >= 0 && (rank != npre + 1 || ndir < 1 || ndir > WT_MAX_EVAL))
        st = WT_ERROR(cli->ctx, WT_ERR_FORMAT, "%s: dataset '%s' has rank %d, expected %d (method, sweep value%s, "
                      "direction; a file of an older wavetomo cannot be resumed)", path, name, rank, npre + 1,
                      ns > 1 ? ", seed" : "");
    int64_t e[4] = {nm, nv, ns, 0};
    if (st >= 0 && (!(buf = malloc((size_t)nc * (ndir > NP ? ndir : NP) * sizeof *buf)) ||
                    !(done = malloc((size_t)nc * sizeof *done))))
        st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory reading %s", path);
    snprintf(name, sizeof name, "%sdone", group);
    if (st >= 0) st = wt_h5_read(r, name, WT_H5_I64, npre, e, NULL, done, (size_t)nc);
    for (int k = 0; k < NFIELDS && st >= 0; k++) {
        const field *f = &fields[k];
        int nw = f->per_dir == 1 ? (int)ndir : width(f, 0);
        e[npre] = nw;
        snprintf(name, sizeof name, "%s%s", group, f->name);
        if ((st = wt_h5_read(r, name, WT_H5_F64, npre + (f->per_dir ? 1 : 0), e, NULL, buf, (size_t)nc * nw)) < 0) break;
        for (int c = 0; c < nc; c++)
            if (done[c] == 1)
                memcpy((char *)&R[c] + f->off, buf + (size_t)c * nw, (size_t)nw * sizeof *buf);
    }
    for (int c = 0; c < nc && st >= 0; c++)
        if (done[c] == 1) R[c].done = 1, ++*ndone;
    free(buf);
    free(done);
    wt_h5_close(r);
    return st;
}

/* "0.3821 ± 0.0042" with several seeds, "0.3821" with one (prec decimals). */
static void pm(FILE *f, const wt_cmp_cases *a, int prec, double mean, double se)
{
    if (a->ns > 1) fprintf(f, "%.*f ± %.*f", prec, mean, prec, se);
    else fprintf(f, "%.*f", prec, mean);
}

/* report.md: the paired differences between the methods over the seeds, each marked resolved or within the
 * noise (|mean| < 2 SE). */
static void write_differences(FILE *f, const wt_cmp_cases *a, const wt_compare_result *R)
{
    int nv = cols(a), noise = 0, total = 0;
    fprintf(f, "\n## Paired differences over the seeds\n\nEvery method ran on the same %d seeds, so each seed gives a "
               "difference A − B free of that realisation's luck; mean ± standard error over the seeds. *noise*: "
               "|mean| < 2 SE, the two methods are not told apart by these seeds.\n\n"
               "| A − B | %s | Δ LE Strehl on-axis | Δ LE Strehl field | Δ WFE field [nm] |\n|---|---|---|---|---|\n",
            a->ns, a->nv ? a->key : "–");
    for (int v = 0; v < nv; v++)
        for (int i = 0; i < a->nm; i++)
            for (int j = i + 1; j < a->nm; j++) {
                fprintf(f, "| %s − %s | %s |", a->methods[i], a->methods[j], a->nv ? a->values[v] : "–");
                for (int k = 0; k < WT_NMETRICS; k++) {
                    double d, se;
                    int n;
                    wt_compare_paired(&R[wt_cmp_case(a, i, v, 0)], &R[wt_cmp_case(a, j, v, 0)], a->ns, k, &d, &se, &n);
                    int in = n >= 2 && fabs(d) < 2.0 * se;
                    noise += in, total++;
                    if (n < 2) fprintf(f, " %d seed%s done |", n, n == 1 ? "" : "s");
                    else fprintf(f, " %+.*f ± %.*f%s |", k == WT_METRIC_WFE ? 1 : 4, d, k == WT_METRIC_WFE ? 1 : 4, se,
                                 in ? " *noise*" : "");
                }
                fprintf(f, "\n");
            }
    fprintf(f, "\n%d of %d differences are within the noise.\n", noise, total);
}

static int write_text(wt_cli *cli, const wt_cmp_cases *a, const wt_config *cfg, const wt_compare_result *R,
                      const wt_compare_summary *S, int missing, int argc, char **argv)
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
                       "setup_s,reconstructor_memory_bytes,done%s\n", key,
                    a->ns > 1 ? ",seeds_done,strehl_le_on_axis_se,strehl_le_field_se,wfe_field_nm_se" : "");
        else {
            fprintf(f, "# wavetomo comparison\n\nSystem `%s` (config hash `%.16s`), %d frames at %.0f Hz (%d settle), seed "
                       "%llu, Strehl at %.0f nm.\n\nCommand:\n\n```\nwavetomo", cfg->path, cfg->matrix_sha256, cfg->frames,
                    cfg->rate, cfg->settle_frames, (unsigned long long)cfg->seed, cfg->eval_wavelength * 1e9);
            for (int i = 0; i < argc; i++) fprintf(f, " %s", argv[i]); /* argv[0] is the subcommand */
            if (a->ns > 1) {
                fprintf(f, "\n```\n\nEvery method and sweep value ran on the same %d seeds (", a->ns);
                for (int s = 0; s < a->ns; s++) fprintf(f, "%s%llu", s ? ", " : "", (unsigned long long)a->seeds[s]);
                fprintf(f, "): each seed its own turbulence and noise. Figures: mean ± standard error over the seeds. "
                           "LE = long exposure.\n\n");
            } else
                fprintf(f, "\n```\n\nEvery run uses the same turbulence and noise (same seed). LE = long exposure.\n\n");
            if (missing)
                fprintf(f, "**Incomplete: %d of %d runs are missing (interrupted); `--resume` with the same options runs "
                           "them.**\n\n", missing, a->nm * nv * a->ns);
            fprintf(f, "| method | %s | LE Strehl on-axis | LE Strehl field | WFE field [nm] | ms/frame | reconstruction ms "
                       "| reconstructor memory [MB] |\n|---|---|---|---|---|---|---|---|\n", a->nv ? a->key : "–");
        }
        for (int m = 0; m < a->nm; m++)
            for (int v = 0; v < nv; v++) {
                const wt_compare_summary *q = &S[m * nv + v];
                const wt_compare_result *r = &q->mean;
                const char *vs = a->nv ? a->values[v] : (doc ? "–" : "");
                if (!doc && r->done)
                    fprintf(f, "%s,%s,%.5f,%.5f,%.2f,%.3f,%.3f,%.2f,%.0f,1", a->methods[m], vs, r->on_axis, r->field,
                            r->wfe_field, r->total, r->parts[2] + r->parts[3], r->setup, r->memory);
                else if (!doc)
                    fprintf(f, "%s,%s,,,,,,,,0", a->methods[m], vs);
                if (!doc && a->ns > 1)
                    fprintf(f, ",%d,%.5f,%.5f,%.2f", q->nseeds, q->se[WT_METRIC_ON_AXIS], q->se[WT_METRIC_FIELD],
                            q->se[WT_METRIC_WFE]);
                if (!doc) fprintf(f, "\n");
                else if (r->done) {
                    fprintf(f, "| %s | %s | ", a->methods[m], vs);
                    pm(f, a, 4, r->on_axis, q->se[WT_METRIC_ON_AXIS]);
                    fprintf(f, " | ");
                    pm(f, a, 4, r->field, q->se[WT_METRIC_FIELD]);
                    fprintf(f, " | ");
                    pm(f, a, 1, r->wfe_field, q->se[WT_METRIC_WFE]);
                    fprintf(f, " | %.1f | %.2f | %.1f |\n", r->total, r->parts[2] + r->parts[3], r->memory / 1e6);
                } else
                    fprintf(f, "| %s | %s | missing%s | | | | | |\n", a->methods[m], vs,
                            a->ns > 1 && q->nseeds ? " (some seeds)" : "");
            }
        if (doc && a->ns > 1 && a->nm > 1) write_differences(f, a, R);
        if (doc) {
            fprintf(f, "\n");
            if (a->nv > 1 && !missing) fprintf(f, "![LE Strehl against %s](strehl_vs_sweep.png)\n\n", a->key);
            for (int v = 0; v < nv; v++)
                for (int m = 0; m < a->nm; m++)
                    if (S[m * nv + v].mean.done)
                        fprintf(f, "![%s%s%s](map_%s_%d.png) ", a->methods[m], a->nv ? " " : "", val(a, v), a->methods[m], v);
            if (!missing) fprintf(f, "\n\n![time per frame](time_per_frame.png)");
            if (a->spots[0])
                fprintf(f, "\n\n## Diffractive sensor %s\n\nNoise-free spot images and centroid gain of the first "
                           "diffractive sensor (what they show: [spots.md](spots.md)).\n\n![spot images of %s](spots_%s.png)"
                           "\n\n![centroid gain and truncation of %s](gain_%s.png)",
                        a->spots, a->spots, a->spots, a->spots, a->spots);
            fprintf(f, "\n\nFiles: results.h5 (all numbers, docs/formats.md), summary.csv.\n");
        }
        if (fclose(f) != 0 || rename(tmp, path) != 0) return WT_ERROR(cli->ctx, WT_ERR_IO, "cannot write '%s'", path);
    }
    return WT_OK;
}

/* The figures; the sweep curve and the time bars only when every case is done (no holes in a curve). */
static int make_plots(wt_cli *cli, const wt_cmp_cases *a, const wt_system *sys, const wt_compare_summary *S, int missing)
{
    int st, nm = a->nm, nv = cols(a), g = sys->cfg->eval_grid;
    char path[2200], title[256];
    double x[WT_COMPARE_MAXV], on[WT_COMPARE_MAXM * WT_COMPARE_MAXV], fi[WT_COMPARE_MAXM * WT_COMPARE_MAXV];
    double on_se[WT_COMPARE_MAXM * WT_COMPARE_MAXV], fi_se[WT_COMPARE_MAXM * WT_COMPARE_MAXV];
    int numeric = 1, positive = 1;
    for (int v = 0; v < nv; v++) {
        char *end = NULL;
        x[v] = a->nv ? strtod(a->values[v], &end) : v;
        if (a->nv && (!end || *end)) numeric = 0;
        if (x[v] <= 0) positive = 0;
    }
    for (int v = 0; v < nv && !numeric; v++) x[v] = v + 1;
    for (int c = 0; c < nm * nv; c++)
        on[c] = S[c].mean.on_axis, fi[c] = S[c].mean.field, on_se[c] = S[c].se[WT_METRIC_ON_AXIS],
        fi_se[c] = S[c].se[WT_METRIC_FIELD];
    if (a->nv > 1 && !missing) {
        snprintf(path, sizeof path, "%s/strehl_vs_sweep.png", a->out);
        int logx = numeric && positive && x[nv - 1] / x[0] > 20.0;
        if ((st = wt_plot_strehl_sweep(cli->ctx, path,
                                       a->ns > 1 ? "LE Strehl ± SE over seeds (on-axis solid, field dashed)"
                                                 : "LE Strehl (on-axis solid, field average dashed)",
                                       a->key, nm, (const char *const *)a->methods, nv, x, on, fi,
                                       a->ns > 1 ? on_se : NULL, a->ns > 1 ? fi_se : NULL, logx)) < 0)
            return st;
    }
    double coords[16], vmin = 1.0, vmax = 0.0;
    for (int i = 0; i < g; i++) coords[i] = (i - 0.5 * (g - 1)) * sys->cfg->eval_spacing / WT_ARCSEC;
    for (int c = 0; c < nm * nv; c++)
        for (int j = 0; j < sys->neval && S[c].mean.done; j++)
            vmin = fmin(vmin, S[c].mean.strehl[j]), vmax = fmax(vmax, S[c].mean.strehl[j]);
    for (int c = 0; c < nm * nv; c++) {
        if (!S[c].mean.done) continue;
        int m = c / nv, v = c % nv;
        snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
        snprintf(title, sizeof title, "LE Strehl, %s%s%s%s%s", a->methods[m], a->nv ? ", " : "", a->nv ? a->key : "",
                 a->nv ? "=" : "", val(a, v));
        if (a->ns > 1) snprintf(title + strlen(title), sizeof title - strlen(title), ", mean of %d seeds", a->ns);
        if ((st = wt_plot_strehl_map(cli->ctx, path, title, g, coords, S[c].mean.strehl, vmin, vmax)) < 0) return st;
    }
    if (missing) return WT_OK;
    double times[WT_COMPARE_MAXM * NP];
    const char *names[NP];
    for (int k = 0; k < NP; k++) names[k] = wt_compare_part_name(k);
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < NP; k++) times[m * NP + k] = S[m * nv].mean.parts[k];
    snprintf(path, sizeof path, "%s/time_per_frame.png", a->out);
    snprintf(title, sizeof title, "time per simulated frame%s%s%s", a->nv ? " (" : "", a->nv ? a->key : "",
             a->nv ? " first value)" : "");
    return wt_plot_time_bars(cli->ctx, path, title, nm, (const char *const *)a->methods, NP, names, times);
}

int wt_cmp_write_all(wt_cli *cli, const wt_cmp_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                     const wt_system *sys, const wt_compare_result *R, int argc, char **argv)
{
    int st, missing = 0, nmv = a->nm * cols(a);
    wt_compare_summary *S = malloc((size_t)nmv * sizeof *S);
    if (!S) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory summarising the seeds");
    for (int c = 0; c < nmv; c++) wt_compare_summarise(R + (size_t)c * a->ns, a->ns, &S[c]);
    for (int c = 0; c < nmv * a->ns; c++) missing += !R[c].done;
    if ((st = write_results(cli, a, plan, cfg, sys, R, S, argc, argv)) >= 0 &&
        (st = write_text(cli, a, cfg, R, S, missing, argc, argv)) >= 0)
        st = make_plots(cli, a, sys, S, missing);
    free(S);
    return st;
}
