/* compare/compare.c: one case of a comparison (SPEC §10) and the plan that identifies a set of cases.
 * LE Strehl by the Maréchal approximation over the frames after the settle period (SPEC §8, strehl.h). */
#include "compare.h"

#include <math.h>
#include <stddef.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "../core/base/sha256.h"
#include "../core/model/sensing.h"
#include "../core/model/tomography.h"
#include "../sim/psf.h"

const char *wt_compare_part_name(int k)
{
    static const char *const names[WT_COMPARE_NPART] = {"atmosphere", "sensors",  "reconstruction",
                                                        "fitting",    "control",  "evaluation"};
    return k >= 0 && k < WT_COMPARE_NPART ? names[k] : "?";
}

int wt_compare_run(wt_context *ctx, const wt_system *sys, int kind, const wt_mvm *mvm, double build_s, uint64_t seed,
                   wt_compare_frame_fn fn, void *user, wt_compare_result *res, wt_compare_series *ser)
{
    return wt_compare_run_rebuild(ctx, sys, kind, mvm, build_s, seed, NULL, NULL, fn, user, res, ser);
}

int wt_compare_run_rebuild(wt_context *ctx, const wt_system *sys, int kind, const wt_mvm *mvm, double build_s,
                           uint64_t seed, wt_adapt_rebuild_fn rebuild, void *rebuild_user, wt_compare_frame_fn fn,
                           void *user, wt_compare_result *res, wt_compare_series *ser)
{
    const wt_config *cfg = sys->cfg;
    wt_loop *lp = NULL;
    wt_psf *psf = NULL;
    memset(res, 0, sizeof *res);
    if (ser) ser->psf = NULL, ser->learned = NULL;
    wt_loop_options o = {.recon = kind, .mvm = mvm, .iterations = -1, .seed = seed, .noise = cfg->noise,
                         .rebuild = rebuild, .rebuild_user = rebuild_user};
    double t0 = wt_time_now();
    int st = wt_loop_alloc(ctx, sys, &o, &lp);
    if (st < 0) return st;
    wt_psf_params pp;
    wt_psf_params_from_config(cfg, &pp);
    if (pp.every > 0 &&
        (st = wt_psf_alloc(ctx, wt_loop_fine_grid(lp), wt_loop_pupil_mask(lp), sys->neval, &pp, &psf)) < 0)
        goto out;
    res->setup = wt_time_now() - t0 + build_s;
    double r0 = wt_time_now(), sum = 0.0, tpsf = 0.0;
    const double *maps[WT_MAX_EVAL];
    for (long t = 0; t < cfg->frames; t++) {
        if ((st = wt_loop_step(lp)) < 0) goto out;
        sum += wt_loop_field_strehl(lp);
        if (ser && ser->wfe) {
            const double *rms = wt_loop_rms(lp);
            double v = 0.0;
            for (int j = 0; j < sys->neval; j++) v += rms[j] * rms[j];
            ser->wfe[t] = sqrt(v / sys->neval) * 1e9;
        }
        if (psf) {
            const double p0 = wt_time_now();
            for (int j = 0; j < sys->neval; j++) maps[j] = wt_loop_residual(lp, j);
            wt_psf_frame(psf, t, maps);
            tpsf += wt_time_now() - p0;
        }
        if (fn && fn(user, t + 1, sum / (t + 1))) {
            st = WT_ERROR(ctx, WT_ERR_INTERRUPTED, "stopped at frame %ld of %d", t + 1, cfg->frames);
            goto out;
        }
    }
    double run = wt_time_now() - r0, fw = 0.0;
    const wt_strehl_le *le = wt_loop_le(lp);
    for (int j = 0; j < sys->neval; j++) {
        res->strehl[j] = wt_strehl_le_strehl(le, j);
        res->wfe[j] = wt_strehl_le_wfe(le, j) * 1e9;
        res->field += res->strehl[j] / sys->neval;
        fw += res->wfe[j] * res->wfe[j] / sys->neval;
    }
    res->on_axis = res->strehl[sys->eval_centre];
    res->wfe_field = sqrt(fw);
    res->frames = cfg->frames;
    int nlgs = 0;
    for (int i = 0; i < sys->nsensors; i++) {
        if (!sys->sensors[i].diffr || sys->sensors[i].kind != WT_SENSOR_LGS) continue;
        double al, ac;
        long fr;
        wt_sensing_gain_in_loop(sys->sensors[i].diffr, &al, &ac, &fr);
        if (fr < 1) continue;
        res->lgs_gain_along += al, res->lgs_gain_across += ac, nlgs++;
    }
    if (nlgs) res->lgs_gain_along /= nlgs, res->lgs_gain_across /= nlgs;
    if (psf) {
        for (int j = 0; j < sys->neval; j++) {
            res->psf_strehl[j] = wt_psf_strehl(psf, j);
            res->psf_field += res->psf_strehl[j] / sys->neval;
        }
        res->psf_on_axis = res->psf_strehl[sys->eval_centre];
        res->psf_frames = (double)wt_psf_frames(psf);
        res->psf_pixels = wt_psf_pixels(psf);
        res->psf_pixel_lod = wt_psf_pixel_lod(psf);
        res->psf_pixel_mas = wt_psf_pixel_scale(psf) / WT_ARCSEC * 1e3;
        res->psf_fft = wt_psf_fft_size(psf);
        res->psf_ms = tpsf / cfg->frames * 1e3;
        if (ser) {
            const size_t nn = (size_t)wt_psf_pixels(psf) * wt_psf_pixels(psf);
            WT_ALLOC(ctx, ser->psf, nn * sys->neval, "PSF images");
            for (int j = 0; j < sys->neval; j++) wt_psf_image(psf, j, ser->psf + nn * j);
        }
    }
    wt_loop_times tm = wt_loop_get_times(lp);
    double v[WT_COMPARE_NPART] = {tm.atmosphere, tm.sensors, tm.reconstruction, tm.fitting, tm.control, tm.evaluation};
    for (int k = 0; k < WT_COMPARE_NPART; k++) res->parts[k] = v[k] / cfg->frames * 1e3;
    res->total = run / cfg->frames * 1e3;
    /* R and RÂ in float32; the matrix-free operators as the tomography counts them */
    if (kind == WT_RECON_MVM) /* R and RA: 4 bytes an element in fp32, 2 in fp16/bf16 (+ the row scales) */
        res->memory = (cfg->mvm_precision ? 2.0 : 4.0) * (double)sys->nact * (double)(sys->nslopes + sys->nact) +
                      (cfg->mvm_precision ? 8.0 * (double)sys->nact : 0.0);
    else if (kind != WT_RECON_NONE) {
        wt_reconstructor *r = wt_loop_reconstructor(lp);
        res->memory = wt_tomography_bytes(wt_reconstructor_tomography(r)) + wt_precond_bytes(wt_reconstructor_precond(r));
    }
    if (ser && wt_loop_adapt(lp) && (st = wt_adapt_copy_record(wt_loop_adapt(lp), &ser->learned)) < 0) goto out;
    res->done = 1;
out:
fail:
    wt_psf_free(psf);
    wt_loop_free(lp);
    return st;
}

double wt_compare_metric(const wt_compare_result *r, int k)
{
    return k == WT_METRIC_ON_AXIS ? r->on_axis : k == WT_METRIC_FIELD ? r->field : r->wfe_field;
}

const char *wt_compare_metric_name(int k)
{
    return k == WT_METRIC_ON_AXIS ? "strehl_le_on_axis" : k == WT_METRIC_FIELD ? "strehl_le_field" : "wfe_le_field";
}

void wt_compare_mean_se(const double *x, int n, double *mean, double *se)
{
    double m = 0.0, ss = 0.0;
    for (int i = 0; i < n; i++) m += x[i];
    m = n > 0 ? m / n : 0.0;
    for (int i = 0; i < n; i++) ss += (x[i] - m) * (x[i] - m);
    *mean = m;
    *se = n > 1 ? sqrt(ss / (n - 1) / n) : 0.0;
}

/* wt_compare_summarise averages a result as an array of doubles up to `done`: it must stay all doubles there */
_Static_assert(offsetof(wt_compare_result, done) ==
                   sizeof(double) * (3 * WT_MAX_EVAL + 3 + WT_COMPARE_NPART + 3 + 11),
               "wt_compare_result: the fields before 'done' must be the doubles wt_compare_summarise averages");

void wt_compare_summarise(const wt_compare_result *r, int ns, wt_compare_summary *out)
{
    memset(out, 0, sizeof *out);
    double x[WT_COMPARE_MAXS];
    int n = 0;
    /* a result is all doubles but `done`: average the doubles field by field */
    const size_t nd = offsetof(wt_compare_result, done) / sizeof(double);
    double *acc = (double *)&out->mean;
    for (int s = 0; s < ns; s++) {
        if (!r[s].done) continue;
        const double *v = (const double *)&r[s];
        for (size_t i = 0; i < nd; i++) acc[i] += v[i];
        n++;
    }
    for (size_t i = 0; i < nd && n > 0; i++) acc[i] /= n;
    for (int k = 0; k < WT_NMETRICS; k++) {
        int j = 0;
        for (int s = 0; s < ns; s++)
            if (r[s].done) x[j++] = wt_compare_metric(&r[s], k);
        double m;
        wt_compare_mean_se(x, j, &m, &out->se[k]);
    }
    out->nseeds = n;
    out->mean.done = n == ns;
}

void wt_compare_paired(const wt_compare_result *a, const wt_compare_result *b, int ns, int k, double *mean, double *se,
                       int *n)
{
    double d[WT_COMPARE_MAXS];
    int j = 0;
    for (int s = 0; s < ns && s < WT_COMPARE_MAXS; s++)
        if (a[s].done && b[s].done) d[j++] = wt_compare_metric(&a[s], k) - wt_compare_metric(&b[s], k);
    wt_compare_mean_se(d, j, mean, se);
    *n = j;
}

static void join(char *dst, size_t n, int k, char *const *items)
{
    dst[0] = '\0';
    for (int i = 0; i < k; i++) snprintf(dst + strlen(dst), n - strlen(dst), "%s%s", i ? "," : "", items[i]);
}

void wt_compare_plan_make(wt_compare_plan *p, int nm, char *const *methods, const char *key, int nv,
                          char *const *values, int ns, const uint64_t *seeds, const wt_config *cfg)
{
    memset(p, 0, sizeof *p);
    join(p->methods, sizeof p->methods, nm, methods);
    snprintf(p->sweep_key, sizeof p->sweep_key, "%s", nv ? key : "");
    join(p->sweep_values, sizeof p->sweep_values, nv, values);
    wt_sha256_hex(cfg->canonical, strlen(cfg->canonical), p->config_sha256);
    p->seed = ns > 1 ? seeds[0] : cfg->seed;
    for (int s = 0; s < ns && ns > 1; s++)
        snprintf(p->seeds + strlen(p->seeds), sizeof p->seeds - strlen(p->seeds), "%s%llu", s ? "," : "",
                 (unsigned long long)seeds[s]);
    p->frames = cfg->frames;
}

static void append(char *dst, size_t n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void append(char *dst, size_t n, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    size_t used = strlen(dst);
    vsnprintf(dst + used, n - used, fmt, ap);
    va_end(ap);
}

int wt_compare_plan_check(wt_context *ctx, const char *source, const wt_compare_plan *stored,
                          const wt_compare_plan *want)
{
    char why[4096] = "";
#define DIFF(cond, ...)                                                                                     \
    if (cond) append(why, sizeof why, __VA_ARGS__)
    DIFF(strcmp(stored->methods, want->methods), "; methods '%s' there, '%s' now", stored->methods, want->methods);
    DIFF(strcmp(stored->sweep_key, want->sweep_key), "; sweep key '%s' there, '%s' now", stored->sweep_key,
         want->sweep_key);
    DIFF(strcmp(stored->sweep_values, want->sweep_values), "; sweep values '%s' there, '%s' now",
         stored->sweep_values, want->sweep_values);
    DIFF(strcmp(stored->seeds, want->seeds), "; seeds '%s' there, '%s' now", stored->seeds, want->seeds);
    DIFF(stored->seed != want->seed, "; seed (sim.seed) %llu there, %llu now", (unsigned long long)stored->seed,
         (unsigned long long)want->seed);
    DIFF(stored->frames != want->frames, "; frames (loop.frames) %lld there, %lld now", (long long)stored->frames,
         (long long)want->frames);
    DIFF(strcmp(stored->config_sha256, want->config_sha256), "; configuration (config_sha256 %.16s there, %.16s now)",
         stored->config_sha256, want->config_sha256);
#undef DIFF
    if (!why[0]) return WT_OK;
    return WT_ERROR(ctx, WT_ERR_FORMAT, "%s was made for other cases, cannot resume it: %s (run without --resume "
                    "into another directory, or repeat the first command's options)", source, why + 2);
}
