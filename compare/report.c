/* compare/report.c: the files of `wavetomo compare` (SPEC §10) and their checks; see report.h. */
#include "compare/report.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/plot.h"
#include "core/io/h5.h"
#include "sim/adapt.h"
#include "sim/psf.h"

#define NP WT_COMPARE_NPART

static int cols(const wt_compare_cases *a) { return a->nv ? a->nv : 1; }
static const char *val(const wt_compare_cases *a, int v) { return a->nv ? a->values[v] : ""; }
/* The sweep value that is the reconstructors' oracle atmosphere (recon.atmosphere.source = "oracle"), −1 without
 * one: the run figure then has a companion with every case minus it */
static int oracle_value(const wt_compare_cases *a)
{
    if (a->nv < 2 || strcmp(a->key, "recon.atmosphere.source") != 0) return -1;
    for (int v = 0; v < a->nv; v++)
        if (strcmp(a->values[v], "\"oracle\"") == 0 || strcmp(a->values[v], "oracle") == 0) return v;
    return -1;
}

/* The run figure: a sweep of 2–5 values over 2–8 methods, long enough for a window (wt_plot_wfe_run) */
static int run_plot(const wt_compare_cases *a, long frames) { return a->nv >= 2 && a->nv <= 5 && a->nm <= 8 && frames >= 100; }
static int run_window(long frames) { return frames / 24 > 10 ? (int)(frames / 24) : 10; }

int wt_compare_check_outputs(wt_cli *cli, const wt_compare_cases *a)
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
    if ((st = wt_compare_check_map_outputs(cli, a, owner)) < 0) return st;
    if ((st = wt_compare_check_learned_outputs(cli, a, owner)) < 0) return st;
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) {
            snprintf(path, sizeof path, "%s/psf_%s_%d.png", a->out, a->methods[m], v);
            if ((st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
        }
    for (int v = 0; v < nv; v++) {
        snprintf(path, sizeof path, "%s/wfe_per_frame_%d.png", a->out, v);
        if ((st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
    }
    snprintf(path, sizeof path, "%s/wfe_over_run.png", a->out);
    if (a->nv >= 2 && (st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
    snprintf(path, sizeof path, "%s/wfe_minus_oracle.png", a->out);
    if (oracle_value(a) >= 0 && (st = wt_cli_check_text_output(cli, path, "\x89PNG", owner)) < 0) return st;
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
    {"strehl_psf", "", "PSF-peak Strehl (peak of the long-exposure PSF, psf/) [method, sweep value, evaluation "
     "direction]; 0 with sim.psf_interval_frames = 0", OFF(psf_strehl), 1},
    {"strehl_psf_on_axis", "", "PSF-peak Strehl on axis [method, sweep value]", OFF(psf_on_axis), 0},
    {"strehl_psf_field", "", "PSF-peak Strehl averaged over the field [method, sweep value]", OFF(psf_field), 0},
    {"psf_frames", "", "frames in the long-exposure PSFs (every sim.psf_interval_frames-th after the settle frames) [method, "
     "sweep value]", OFF(psf_frames), 0},
    {"time_psf", "ms", "wall time of the PSF images per simulated frame (part of time_per_frame) [method, "
     "sweep value]", OFF(psf_ms), 0},
    {"lgs_inloop_gain_along", "", "diffractive LGS: the centroiders' in-loop gain along the elongation (least-squares "
     "slope of measured on true slopes over the averaged frames, mean over the LGS; 0 without diffractive LGS) "
     "[method, sweep value]", OFF(lgs_gain_along), 0},
    {"lgs_inloop_gain_across", "", "the same across the elongation [method, sweep value]", OFF(lgs_gain_across), 0},
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
static int write_statistics(wt_h5_writer *w, const wt_compare_cases *a, const wt_compare_result *R,
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
                    wt_compare_paired(&R[wt_compare_case(a, i, v, 0)], &R[wt_compare_case(a, j, v, 0)], a->ns, k,
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

/* series/wfe_field [method, sweep value, seed, frame] (0: not run; the readers refuse NaN) and psf/<method>_<v>/ per seed (zeros: not
 * run) for the cases that kept them. */
static int write_extra(wt_cli *cli, wt_h5_writer *w, const wt_compare_cases *a, const wt_config *cfg, const wt_system *sys,
                       const wt_compare_result *R, const wt_compare_extra *X)
{
    int st = WT_OK, nm = a->nm, nv = cols(a), ns = a->ns, nc = nm * nv * ns, nd = sys->neval;
    long F = 0;
    for (int c = 0; c < nc; c++)
        if (R[c].done && X->wfe[c] && R[c].frames > F) F = (long)R[c].frames;
    if (F > 0) {
        double *buf = malloc((size_t)nc * F * sizeof *buf);
        if (!buf) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory writing the per-frame residuals");
        for (int c = 0; c < nc; c++)
            for (long t = 0; t < F; t++)
                buf[(size_t)c * F + t] = R[c].done && X->wfe[c] && t < (long)R[c].frames ? X->wfe[c][t] : 0.0;
        int64_t d[4] = {nm, nv, ns, F};
        st = wt_h5_write(w, "series/wfe_field", WT_H5_F64, WT_H5_F64, 4, d, buf, "nm",
                         "field-rms residual wavefront error of each frame, sqrt(mean over the directions of the "
                         "piston-removed variance) [method, sweep value, seed, frame]; 0: not run; the long-exposure "
                         "wfe_le_field averages the variance over the frames from settle_frames on");
        if (st >= 0) st = wt_h5_attr_write_int64(w, "series/wfe_field", "settle_frames", cfg->settle_frames);
        free(buf);
    }
    for (int c = 0; c < nc && st >= 0; c++) /* each case's learned record, as sim writes it (cases of this rank) */
        if (R[c].done && X->learned[c]) {
            char group[256];
            const int m = c / (nv * ns), v = c / ns % nv;
            snprintf(group, sizeof group, "learned/%s_%d/seed%d", a->methods[m], v, c % ns);
            st = wt_adapt_write(X->learned[c], w, group);
        }
    for (int m = 0; m < nm && st >= 0; m++)
        for (int v = 0; v < nv && st >= 0; v++) {
            int first = -1;
            for (int k = 0; k < ns; k++)
                if (R[wt_compare_case(a, m, v, k)].done && X->psf[wt_compare_case(a, m, v, k)] && first < 0) first = k;
            if (first < 0) continue;
            const wt_compare_result *r0 = &R[wt_compare_case(a, m, v, first)];
            const int n = (int)r0->psf_pixels;
            const size_t per = (size_t)nd * n * n;
            float *img = calloc((size_t)ns * per, sizeof *img);
            double *sp = calloc((size_t)ns * nd, sizeof *sp);
            if (!img || !sp) {
                free(img), free(sp);
                return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory writing the PSFs");
            }
            for (int k = 0; k < ns; k++) {
                const int c = wt_compare_case(a, m, v, k);
                if (!R[c].done || !X->psf[c] || (int)R[c].psf_pixels != n) continue;
                memcpy(img + per * k, X->psf[c], per * sizeof *img);
                memcpy(sp + (size_t)nd * k, R[c].psf_strehl, (size_t)nd * sizeof *sp);
            }
            char group[200];
            snprintf(group, sizeof group, "psf/%s_%d", a->methods[m], v);
            st = wt_psf_write_images(w, group, ns, nd, n, img, sp, cfg->eval_wavelength, r0->psf_pixel_lod,
                                     r0->psf_pixel_mas * 1e-3 * WT_ARCSEC, (long)r0->psf_frames, cfg->psf_interval,
                                     (int)r0->psf_fft);
            free(img), free(sp);
        }
    return st;
}

static int write_results(wt_cli *cli, const wt_compare_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                         const wt_system *sys, const wt_compare_result *R, const wt_compare_summary *S,
                         const wt_compare_extra *X, int argc, char **argv)
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
    if (st >= 0) st = write_extra(cli, w, a, cfg, sys, R, X);
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

/* --resume: the per-frame residuals and PSFs of the cases done (what write_extra wrote); a file without them
 * (sim.psf_interval_frames = 0) leaves them NULL. */
static int read_extra(wt_cli *cli, wt_h5_reader *r, const char *path, const wt_compare_cases *a, wt_compare_result *R,
                      int64_t frames, wt_compare_extra *X)
{
    int st = WT_OK, nm = a->nm, nv = cols(a), ns = a->ns, nc = nm * nv * ns, rank = 0;
    int64_t dims[WT_H5_MAX_RANK] = {0};
    for (int c = 0; c < nc; c++)
        if (R[c].done) R[c].frames = (double)frames;
    if (wt_h5_exists(r, "series/wfe_field") == 1) {
        int64_t e[4] = {nm, nv, ns, frames};
        double *buf = malloc((size_t)nc * frames * sizeof *buf);
        if (!buf) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory reading %s", path);
        st = wt_h5_read(r, "series/wfe_field", WT_H5_F64, 4, e, NULL, buf, (size_t)nc * frames);
        for (int c = 0; c < nc && st >= 0; c++) {
            if (!R[c].done) continue;
            if (!(X->wfe[c] = wt_malloc(cli->ctx, (size_t)frames, sizeof(double)))) st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory");
            else memcpy(X->wfe[c], buf + (size_t)c * frames, (size_t)frames * sizeof *buf);
        }
        free(buf);
    }
    for (int m = 0; m < nm && st >= 0; m++)
        for (int v = 0; v < nv && st >= 0; v++) {
            char name[256];
            snprintf(name, sizeof name, "psf/%s_%d/image", a->methods[m], v);
            if (wt_h5_exists(r, name) != 1) continue;
            if ((st = wt_h5_dims(r, name, &rank, dims)) < 0) break;
            if (rank != 4 || dims[0] != ns || dims[1] < 1 || dims[1] > WT_MAX_EVAL || dims[2] != dims[3] || dims[2] < 2) {
                st = WT_ERROR(cli->ctx, WT_ERR_FORMAT, "%s: dataset '%s' is not [seed, direction, n, n]", path, name);
                break;
            }
            const size_t per = (size_t)dims[1] * dims[2] * dims[3];
            float *img = malloc((size_t)ns * per * sizeof *img);
            if (!img) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory reading %s", path);
            st = wt_h5_read(r, name, WT_H5_F32, 4, dims, NULL, img, (size_t)ns * per);
            double lod = 0.0, mas = 0.0;
            int64_t fft = 0;
            if (st >= 0) st = wt_h5_attr_read_double(r, name, "pixel_lambda_over_d", &lod);
            if (st >= 0) st = wt_h5_attr_read_double(r, name, "pixel_mas", &mas);
            if (st >= 0) st = wt_h5_attr_read_int64(r, name, "fft_size", &fft);
            for (int k = 0; k < ns && st >= 0; k++) {
                const int c = wt_compare_case(a, m, v, k);
                if (!R[c].done) continue;
                if (!(X->psf[c] = wt_malloc(cli->ctx, per, sizeof(float)))) {
                    st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory");
                    break;
                }
                memcpy(X->psf[c], img + per * k, per * sizeof *img);
                R[c].psf_pixels = (double)dims[2], R[c].psf_pixel_lod = lod, R[c].psf_pixel_mas = mas;
                R[c].psf_fft = (double)fft;
            }
            free(img);
        }
    return st;
}

int wt_compare_read_previous(wt_cli *cli, const wt_compare_cases *a, const wt_compare_plan *want, wt_compare_result *R,
                         wt_compare_extra *X, int *ndone)
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
    if (st >= 0) st = read_extra(cli, r, path, a, R, have.frames, X);
    free(buf);
    free(done);
    wt_h5_close(r);
    return st;
}

/* "0.3821 ± 0.0042" with several seeds, "0.3821" with one (prec decimals). */
static void pm(FILE *f, const wt_compare_cases *a, int prec, double mean, double se)
{
    if (a->ns > 1) fprintf(f, "%.*f ± %.*f", prec, mean, prec, se);
    else fprintf(f, "%.*f", prec, mean);
}

/* report.md: the paired differences between the methods over the seeds, each marked resolved or within the
 * noise (|mean| < 2 SE). */
static void write_differences(FILE *f, const wt_compare_cases *a, const wt_compare_result *R)
{
    int nv = cols(a), noise = 0, total = 0;
    fprintf(f, "\n## Paired differences over the seeds\n\nEvery method ran on the same %d seeds, so each seed gives a "
               "difference A − B free of that realisation's luck; mean ± standard error over the seeds. *noise*: "
               "|mean| < 2 SE, the two methods are not told apart by these seeds.\n\n"
               "| A − B |%s%s%s Δ LE Strehl on-axis | Δ LE Strehl field | Δ WFE field [nm] |\n|---|%s---|---|---|\n",
            a->ns, a->nv ? " " : "", a->nv ? a->key : "", a->nv ? " |" : "", a->nv ? "---|" : "");
    for (int v = 0; v < nv; v++)
        for (int i = 0; i < a->nm; i++)
            for (int j = i + 1; j < a->nm; j++) {
                fprintf(f, "| %s − %s |", a->methods[i], a->methods[j]);
                if (a->nv) fprintf(f, " %s |", a->values[v]);
                for (int k = 0; k < WT_NMETRICS; k++) {
                    double d, se;
                    int n;
                    wt_compare_paired(&R[wt_compare_case(a, i, v, 0)], &R[wt_compare_case(a, j, v, 0)], a->ns, k, &d, &se, &n);
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

static int write_text(wt_cli *cli, const wt_compare_cases *a, const wt_config *cfg, const wt_compare_result *R,
                      const wt_compare_summary *S, const wt_compare_extra *X, int missing, int argc, char **argv)
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
                       "setup_s,reconstructor_memory_bytes,done%s,strehl_psf_on_axis,strehl_psf_field,psf_frames\n", key,
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
            if (cfg->psf_interval > 0)
                fprintf(f, "LE Strehl: the Maréchal exp(−σ²) of each frame's residual, averaged over the frames after the "
                           "settle window; PSF-peak Strehl: the peak of the long-exposure PSF at the same wavelength (every "
                           "%d frames after the settle window, normalised to the diffraction-limited peak). They agree at "
                           "high Strehl; at low Strehl they differ (docs/guide.md: which to use).\n\n", cfg->psf_interval);
            else
                fprintf(f, "LE Strehl: the Maréchal exp(−σ²) of each frame's residual, averaged over the frames after the "
                           "settle window; no PSFs (sim.psf_interval_frames = 0).\n\n");
            /* the swept key's column only with a sweep (without one it would hold nothing) */
            if (a->nv) fprintf(f, "| method | %s ", a->key);
            else fprintf(f, "| method ");
            fprintf(f, "| LE Strehl on-axis (Maréchal) | LE Strehl field (Maréchal) | PSF-peak Strehl on-axis "
                       "| PSF-peak Strehl field | WFE field [nm] | ms/frame | reconstruction ms "
                       "| reconstructor memory [MB] |\n|---%s|---|---|---|---|---|---|---|---|\n", a->nv ? "|---" : "");
        }
        for (int m = 0; m < a->nm; m++)
            for (int v = 0; v < nv; v++) {
                const wt_compare_summary *q = &S[m * nv + v];
                const wt_compare_result *r = &q->mean;
                const char *vs = a->nv ? a->values[v] : "";
                if (!doc && r->done)
                    fprintf(f, "%s,%s,%.5f,%.5f,%.2f,%.3f,%.3f,%.2f,%.0f,1", a->methods[m], vs, r->on_axis, r->field,
                            r->wfe_field, r->total, r->parts[2] + r->parts[3], r->setup, r->memory);
                else if (!doc)
                    fprintf(f, "%s,%s,,,,,,,,0", a->methods[m], vs);
                if (!doc && a->ns > 1)
                    fprintf(f, ",%d,%.5f,%.5f,%.2f", q->nseeds, q->se[WT_METRIC_ON_AXIS], q->se[WT_METRIC_FIELD],
                            q->se[WT_METRIC_WFE]);
                if (!doc && r->done && r->psf_frames > 0)
                    fprintf(f, ",%.5f,%.5f,%.0f", r->psf_on_axis, r->psf_field, r->psf_frames);
                else if (!doc)
                    fprintf(f, ",,,0");
                if (!doc) fprintf(f, "\n");
                else if (r->done) {
                    fprintf(f, "| %s | %s%s", a->methods[m], vs, a->nv ? " | " : "");
                    pm(f, a, 4, r->on_axis, q->se[WT_METRIC_ON_AXIS]);
                    fprintf(f, " | ");
                    pm(f, a, 4, r->field, q->se[WT_METRIC_FIELD]);
                    if (r->psf_frames > 0) fprintf(f, " | %.4f | %.4f | ", r->psf_on_axis, r->psf_field);
                    else fprintf(f, " | – | – | ");
                    pm(f, a, 1, r->wfe_field, q->se[WT_METRIC_WFE]);
                    fprintf(f, " | %.1f | %.2f | %.1f |\n", r->total, r->parts[2] + r->parts[3], r->memory / 1e6);
                } else
                    fprintf(f, "| %s | %s%smissing%s | | | | | | | |\n", a->methods[m], vs, a->nv ? " | " : "",
                            a->ns > 1 && q->nseeds ? " (some seeds)" : "");
            }
        if (doc && a->ns > 1 && a->nm > 1) write_differences(f, a, R);
        if (doc && S[0].mean.done && S[0].mean.lgs_gain_along != 0.0) {
            fprintf(f, "\nThe diffractive LGS centroiders' **in-loop gain** (measured slope per true slope, the average "
                       "gradient of the OPD each subaperture sampled; 1 when the reference I0 is the spot the loop "
                       "sees, lgs.wfs.reference_seeing), along / across the elongation:");
            for (int m = 0; m < a->nm; m++)
                for (int v = 0; v < nv; v++) {
                    const wt_compare_result *r = &S[m * nv + v].mean;
                    if (r->done) fprintf(f, " %s%s%s %.3f / %.3f;", a->methods[m], a->nv ? " " : "", val(a, v),
                                         r->lgs_gain_along, r->lgs_gain_across);
                }
            fprintf(f, "\n");
        }
        if (doc) {
            fprintf(f, "\n");
            if (a->nv > 1 && !missing) fprintf(f, "![LE Strehl against %s](strehl_vs_sweep.png)\n\n", a->key);
            wt_compare_maps_markdown(f, a, S, 0);
            if (!missing) fprintf(f, "\n\n![time per frame](time_per_frame.png)");
            wt_compare_maps_markdown(f, a, S, 1);
            fprintf(f, "\n\n## Convergence\n\nThe residual WFE of each frame (field rms, thin) and its running "
                       "long-exposure value from the settle window on (thick, ending at the WFE of the table); the "
                       "grey band is the settle window, left out of every average%s.\n\n", a->ns > 1 ? " (first seed)" : "");
            for (int v = 0; v < nv; v++) fprintf(f, "![residual WFE per frame%s%s](wfe_per_frame_%d.png) ", a->nv ? " " : "", val(a, v), v);
            if (run_plot(a, cfg->frames))
                fprintf(f, "\n\nEvery case over the run, one colour per method and one line style per value of %s: the "
                           "field WFE's rms over a trailing window of %d frames (for a model that changes during the "
                           "run: a learned atmosphere, a night, a sodium layer in time)%s.\n\n"
                           "![residual WFE over the run](wfe_over_run.png)",
                        a->key, run_window(cfg->frames), a->ns > 1 ? " (first seed)" : "");
            if (run_plot(a, cfg->frames) && oracle_value(a) >= 0)
                fprintf(f, "\n\nThe same curves minus each method's oracle (the truth compressed onto its layers): what "
                           "each model of the atmosphere costs, over the run.\n\n![each model against the oracle]"
                           "(wfe_minus_oracle.png)");
            wt_compare_learned_markdown(f, cli->ctx, a, cfg, R, X);
            int psfs = 0;
            for (int c = 0; c < a->nm * nv; c++) psfs += S[c].mean.done && S[c].mean.psf_frames > 0;
            if (psfs) {
                fprintf(f, "\n\n## Long-exposure PSFs\n\nOne panel per evaluation direction, placed as on the sky, log10 "
                           "of the PSF normalised to the diffraction-limited peak (so a panel's peak is its PSF-peak "
                           "Strehl, printed in it)%s; arrays in results.h5 psf/.\n\n", a->ns > 1 ? ", mean of the seeds" : "");
                for (int v = 0; v < nv; v++)
                    for (int m = 0; m < a->nm; m++)
                        if (S[m * nv + v].mean.done && S[m * nv + v].mean.psf_frames > 0)
                            fprintf(f, "![PSFs %s%s%s](psf_%s_%d.png) ", a->methods[m], a->nv ? " " : "", val(a, v),
                                    a->methods[m], v);
            }
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
/* The PSF mosaics (mean of the seeds done) and the per-frame residual curves (first seed done of each method). */
static int extra_plots(wt_cli *cli, const wt_compare_cases *a, const wt_system *sys, const wt_compare_result *R,
                       const wt_compare_summary *S, const wt_compare_extra *X, const double *coords)
{
    int st = WT_OK, nm = a->nm, nv = cols(a), ns = a->ns, g = sys->cfg->eval_grid, nd = sys->neval;
    char path[2200], title[256];
    for (int v = 0; v < nv && st >= 0; v++) {
        long F = 0;
        int first[WT_COMPARE_MAXM];
        for (int m = 0; m < nm; m++) {
            first[m] = -1;
            for (int k = ns - 1; k >= 0; k--)
                if (R[wt_compare_case(a, m, v, k)].done && X->wfe[wt_compare_case(a, m, v, k)]) first[m] = wt_compare_case(a, m, v, k);
            if (first[m] >= 0 && R[first[m]].frames > F) F = (long)R[first[m]].frames;
        }
        if (F < 2) continue;
        double *y = malloc((size_t)nm * F * sizeof *y);
        if (!y) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the residual curves");
        for (int m = 0; m < nm; m++)
            for (long t = 0; t < F; t++)
                y[(size_t)m * F + t] = first[m] >= 0 && t < (long)R[first[m]].frames ? X->wfe[first[m]][t] : NAN;
        snprintf(path, sizeof path, "%s/wfe_per_frame_%d.png", a->out, v);
        snprintf(title, sizeof title, "residual WFE per frame%s%s%s%s", a->nv ? ", " : "", a->nv ? a->key : "",
                 a->nv ? "=" : "", val(a, v));
        st = wt_plot_wfe_frames(cli->ctx, path, title, nm, (const char *const *)a->methods, F, y,
                                sys->cfg->settle_frames);
        free(y);
    }
    if (st >= 0 && run_plot(a, sys->cfg->frames)) { /* every (method, value) of the first seed done */
        const long F = sys->cfg->frames;
        double *y = malloc((size_t)nm * nv * F * sizeof *y);
        if (!y) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the run's curves");
        const char *vals[5];
        for (int v = 0; v < nv; v++) vals[v] = val(a, v);
        for (int m = 0; m < nm; m++)
            for (int v = 0; v < nv; v++) {
                int c = -1;
                for (int k = ns - 1; k >= 0; k--)
                    if (R[wt_compare_case(a, m, v, k)].done && X->wfe[wt_compare_case(a, m, v, k)]) c = wt_compare_case(a, m, v, k);
                for (long t = 0; t < F; t++)
                    y[((size_t)m * nv + v) * F + t] = c >= 0 && t < (long)R[c].frames ? X->wfe[c][t] : NAN;
            }
        snprintf(path, sizeof path, "%s/wfe_over_run.png", a->out);
        const char *dot = strrchr(a->key, '.');
        snprintf(title, sizeof title, "over the run, by %s", dot ? dot + 1 : a->key);
        const wt_night_config *night = &sys->cfg->night;
        wt_plot_run_axis axis = {0.0, 1.0 / sys->cfg->rate, "time [s]"};
        /* a night, or a sodium layer in time, is read in night time: frames stand for longer */
        if (night->source != WT_NIGHT_CFG_NONE || sys->cfg->sodium_sequence[0])
            axis = (wt_plot_run_axis){night->start / 60.0, night->compression / sys->cfg->rate / 60.0, "night time [min]"};
        st = wt_plot_wfe_run(cli->ctx, path, title, nm, (const char *const *)a->methods, nv, vals, F, y,
                             sys->cfg->settle_frames, run_window(F), &axis, -1);
        const int ref = oracle_value(a);
        if (st >= 0 && ref >= 0) {
            snprintf(path, sizeof path, "%s/wfe_minus_oracle.png", a->out);
            snprintf(title, sizeof title, "each model against the oracle");
            st = wt_plot_wfe_run(cli->ctx, path, title, nm, (const char *const *)a->methods, nv, vals, F, y,
                                 sys->cfg->settle_frames, run_window(F), &axis, ref);
        }
        free(y);
    }
    for (int c = 0; c < nm * nv && st >= 0; c++) {
        if (!S[c].mean.done || S[c].mean.psf_frames <= 0) continue;
        const int m = c / nv, v = c % nv, n = (int)lround(S[c].mean.psf_pixels);
        const size_t per = (size_t)nd * n * n;
        float *img = calloc(per, sizeof *img);
        if (!img) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the PSF mosaic");
        int k = 0;
        for (int s2 = 0; s2 < ns; s2++) {
            const int cc = wt_compare_case(a, m, v, s2);
            if (!R[cc].done || !X->psf[cc] || (int)R[cc].psf_pixels != n) continue;
            for (size_t i = 0; i < per; i++) img[i] += X->psf[cc][i];
            k++;
        }
        for (size_t i = 0; i < per && k > 1; i++) img[i] /= (float)k;
        snprintf(path, sizeof path, "%s/psf_%s_%d.png", a->out, a->methods[m], v);
        snprintf(title, sizeof title, "long-exposure PSFs, %s%s%s%s%s, %.0f nm", a->methods[m],
                 a->nv ? ", " : "", a->nv ? a->key : "", a->nv ? "=" : "", val(a, v), sys->cfg->eval_wavelength * 1e9);
        if (k) st = wt_plot_psf_mosaic(cli->ctx, path, title, g, coords, n, S[c].mean.psf_pixel_lod, img,
                                       S[c].mean.psf_strehl);
        free(img);
    }
    return st;
}

/* The sweep's axis: what the key is with its unit, and the key on a second line ("detected photons per
 * subaperture per frame [photons]\nlgs.wfs.photons"): the description's head (up to its first " (" or ";") when
 * short enough for the axis, else the key alone with its unit. */
static void axis_label(char *s, size_t n, const char *key)
{
    const char *unit = NULL, *desc = NULL;
    wt_config_key_doc(key, &unit, &desc);
    size_t len = desc ? strcspn(desc, ";") : 0;
    const char *paren = desc ? strstr(desc, " (") : NULL;
    if (paren && (size_t)(paren - desc) < len) len = (size_t)(paren - desc);
    char u[64] = "";
    if (unit && *unit) snprintf(u, sizeof u, " [%s]", unit);
    if (len > 0 && len <= 48) snprintf(s, n, "%.*s%s\nkey %s", (int)len, desc, u, key);
    else snprintf(s, n, "%s%s", key, u);
}

static int make_plots(wt_cli *cli, const wt_compare_cases *a, const wt_system *sys, const wt_compare_result *R,
                      const wt_compare_summary *S, const wt_compare_extra *X, int missing)
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
        char xlabel[256];
        axis_label(xlabel, sizeof xlabel, a->key);
        snprintf(path, sizeof path, "%s/strehl_vs_sweep.png", a->out);
        int logx = numeric && positive && x[nv - 1] / x[0] > 20.0;
        /* a sweep of words (false/true, "learned"/"given"): each value named under its point, its quotes dropped */
        char vnames[WT_COMPARE_MAXV][64];
        const char *vn[WT_COMPARE_MAXV];
        for (int v = 0; v < nv && !numeric; v++) {
            const char *s = a->values[v];
            const size_t len = strlen(s);
            if (len >= 2 && s[0] == '"' && s[len - 1] == '"') snprintf(vnames[v], sizeof vnames[v], "%.*s", (int)len - 2, s + 1);
            else snprintf(vnames[v], sizeof vnames[v], "%s", s);
            vn[v] = vnames[v];
        }
        if ((st = wt_plot_strehl_sweep_named(cli->ctx, path,
                                             a->ns > 1 ? "LE Strehl ± SE over seeds (on-axis solid, field dashed)"
                                                       : "LE Strehl (on-axis solid, field average dashed)",
                                             xlabel, nm, (const char *const *)a->methods, nv, x, numeric ? NULL : vn, on,
                                             fi, a->ns > 1 ? on_se : NULL, a->ns > 1 ? fi_se : NULL, logx)) < 0)
            return st;
    }
    double coords[16];
    for (int i = 0; i < g; i++) coords[i] = (i - 0.5 * (g - 1)) * sys->cfg->eval_spacing / WT_ARCSEC;
    if ((st = wt_compare_maps(cli, a, sys, S, coords)) < 0) return st;
    if ((st = extra_plots(cli, a, sys, R, S, X, coords)) < 0) return st;
    if ((st = wt_compare_learned_plots(cli, a, sys->cfg, R, X)) < 0) return st;
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

int wt_compare_write_all(wt_cli *cli, const wt_compare_cases *a, const wt_compare_plan *plan, const wt_config *cfg,
                     const wt_system *sys, const wt_compare_result *R, const wt_compare_extra *X, int argc, char **argv)
{
    int st, missing = 0, nmv = a->nm * cols(a);
    wt_compare_summary *S = malloc((size_t)nmv * sizeof *S);
    if (!S) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory summarising the seeds");
    for (int c = 0; c < nmv; c++) wt_compare_summarise(R + (size_t)c * a->ns, a->ns, &S[c]);
    for (int c = 0; c < nmv * a->ns; c++) missing += !R[c].done;
    if ((st = write_results(cli, a, plan, cfg, sys, R, S, X, argc, argv)) >= 0 &&
        (st = write_text(cli, a, cfg, R, S, X, missing, argc, argv)) >= 0)
        st = make_plots(cli, a, sys, R, S, X, missing);
    free(S);
    return st;
}
