/* builder/cmd_learn.c: `wavetomo learn`: the Cn² profile and r0 identified from the pseudo-open-loop LGS slopes of a
 * telemetry file (SPEC §12, core/model/learn.h), compressed onto the reconstructors' layers, beside the truth
 * when the telemetry's configuration holds it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "builder/cmd_build.h"
#include "cli/cli.h"
#include "cli/plot.h"
#include "core/io/h5.h"
#include "core/model/learn.h"
#include "core/model/profile.h"
#include "core/model/system.h"
#include "core/base/rng.h"
#include "builder/cmd_learn_wind.h"

/* An estimate is the mean of its batches' cross-products: a batch of fewer frames than this gives a spread that
 * says little (the batch covariance of 4 frames is itself ±70 %). */
#define LEARN_MIN_BATCH_FRAMES 5
#define LEARN_DEFAULT_BATCHES 4
/* The default lags: the shortest moves a layer of LEARN_WIND_VMAX by at most one subaperture (the search's and
 * LM's start are within reach), then ×2 … ×16 (each stage refines the last one's v; the longest separates layers
 * by their relative motion and gives the precision: on the demo 6 … 96 frames beat 3 … 24 and 3 … 48,
 * docs/results.md §38) */
#define LEARN_WIND_VMAX 40.0
#define LEARN_WIND_NLAG 5
#define LEARN_BENCH_FITS 5     /* fits timed by --bench: the median of 5 */
#define LEARN_BENCH_FRAMES 20  /* frames accumulated by --bench (the fit's cost does not depend on them) */

static void help(void)
{
    printf("usage: wavetomo learn --telemetry TEL.h5 --out EST.h5 [--config CFG] [--frames N] [--batches B]\n"
           "                      [--png PROFILE.png] [--threads N] [--set key=value] [--quiet]\n"
           "       wavetomo learn --bench --config CFG [--frames N] [--threads N]\n"
           "\n"
           "Identifies r0 and the Cn2 profile from the pseudo-open-loop LGS slopes of a telemetry file written by\n"
           "`wavetomo sim --telemetry` (SPEC 12): the slope cross-covariance maps of every LGS pair (tip-tilt\n"
           "removed, by FFT), fitted by non-negative least squares with the cone-beam response maps of unit von\n"
           "Karman layers on an altitude grid (0, 0.5 km, then every 1 km to 20 km) at the configuration's\n"
           "recon.atmosphere L0. r0 is the total that fits each LGS's own map within two subapertures (each\n"
           "map less its mean there: the large scales, which a few seconds sample badly, cancel); the Cn2 at\n"
           "altitude is the fit's, the lowest altitude takes the rest. The truth is never read by the estimate.\n"
           "  --config F   the system (default: the configuration stored in the telemetry); refused when its LGS\n"
           "               geometry is not the telemetry's\n"
           "  --frames N   use the first N frames (default: all)\n"
           "  --batches B  split the frames into B batches (2-%d, default %d): the uncertainty is the spread of\n"
           "               the batch estimates / sqrt(B), times sqrt(tau / batch duration) when the batches are\n"
           "               shorter than the screens' renewal time tau = D sum f_k / v_k (each layer moving the\n"
           "               aperture D at recon.atmosphere's wind: until then batches see the same turbulence);\n"
           "               each batch needs at least %d frames\n"
           "  --png F      a bar chart of the estimated against the true profile on cg9's layers\n"
           "  --wind       also the wind of each layer holding >= 5 %% of the Cn2 (a minute on the demo, about an hour\n"
           "               at E-ELT size: the lagged maps' fit evaluates the response maps at many shifts)\n"
           "  --wind-png F a bar chart of the wind on the truth's layers (implies --wind): estimated and true speed,\n"
           "               the vector error, each layer's direction error\n"
           "  --lags K,..  the lags [frames] of the wind's time-lagged maps (implies --wind; default: k, 2k, 4k, 8k,\n"
           "               16k with k the frames in which %.0f m/s moves one subaperture, at loop.rate_hz)\n"
           "  --wind-threshold F  the Cn2 fraction a layer needs for its wind to be fitted (default %.2f)\n"
           "  --bench      time, on CFG's LGS geometry and synthetic frames (seed 1): accumulation per frame,\n"
           "               the response model's set-up (once per grid and L0) and a fit (median of %d)\n"
           "With --wind, the wind of each altitude holding >= 5 %% of the Cn2 (speed, direction of motion counter-clockwise from\n"
           "+x) from the time-lagged maps of frozen flow, with its uncertainty from the batches, per altitude, per\n"
           "reconstructor layer and on the truth's layers.\n"
           "Prints r0 and the profile on the grid and compressed onto pcg3's and cg9's layers, with the\n"
           "uncertainty, and the truth of the telemetry's configuration binned the same way beside; writes EST.h5\n"
           "(docs/formats.md).\n",
           WT_LEARN_MAX_BATCH, LEARN_DEFAULT_BATCHES, LEARN_MIN_BATCH_FRAMES, LEARN_WIND_VMAX, WT_LEARN_WIND_MIN_FRACTION,
           LEARN_BENCH_FITS);
}

typedef struct {
    const char *tel, *out, *png, *wind_png;
    long frames, batches;
    int bench, wind;
    int nlag, lags[WT_LEARN_MAX_LAG];
    double wind_min;
} learn_args;



static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* --bench: the costs of identification on the configuration's LGS geometry, from synthetic frames (a slope pattern
 * common to the LGS plus each LGS's own, both N(0, 1) µrad, seed 1: correlated, so the fit finds turbulence; the
 * times do not depend on the values): accumulation per frame, the model's set-up, a fit (median of 5). */
static int learn_bench(wt_cli *cli, long frames)
{
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_learn *L = NULL;
    wt_learn_model *M = NULL;
    double *s = NULL, *z = NULL, *tadd = NULL;
    int st;
    if ((st = wt_cli_read_config(cli, NULL, &cfg)) < 0) goto done;
    if ((st = wt_system_alloc(cli->ctx, cfg, &sys)) < 0) goto done;
    double tx[WT_MAX_GS], ty[WT_MAX_GS];
    for (int i = 0; i < sys->nlgs; i++) tx[i] = sys->sensors[i].theta_x, ty[i] = sys->sensors[i].theta_y;
    const wt_learn_geometry g = {sys->n, sys->d, sys->valid, sys->nlgs, tx, ty, sys->sensors[0].altitude};
    const long F = frames > 0 ? frames : LEARN_BENCH_FRAMES;
    if ((st = wt_learn_alloc(cli->ctx, &g, LEARN_DEFAULT_BATCHES, F / LEARN_DEFAULT_BATCHES, &L)) < 0) goto done;
    const int64_t ns = sys->sensors[0].nslopes, nl = ns * sys->nlgs;
    s = malloc((size_t)nl * sizeof *s), z = malloc((size_t)ns * sizeof *z), tadd = malloc((size_t)F * sizeof *tadd);
    if (!s || !z || !tadd) {
        st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the bench's frames");
        goto done;
    }
    wt_rng rng;
    wt_rng_init(&rng, 1, 0);
    for (long t = 0; t < F; t++) {
        for (int64_t k = 0; k < ns; k++) z[k] = 1e-6 * wt_rng_normal(&rng);
        for (int64_t k = 0; k < nl; k++) s[k] = z[k % ns] + 1e-6 * wt_rng_normal(&rng);
        const double t0 = wt_time_now();
        if ((st = wt_learn_add(L, s)) < 0) goto done;
        tadd[t] = wt_time_now() - t0;
    }
    qsort(tadd, (size_t)F, sizeof *tadd, cmp_double);
    double alt[WT_LEARN_MAX_ALT], tfit[LEARN_BENCH_FITS];
    const int na = wt_learn_default_grid(g.H, WT_LEARN_MAX_ALT, alt);
    double t0 = wt_time_now();
    if ((st = wt_learn_model_alloc(L, na, alt, cfg->model.L0, &M)) < 0) goto done;
    const double tmodel = wt_time_now() - t0;
    wt_learn_estimate e;
    for (int k = 0; k < LEARN_BENCH_FITS; k++) {
        t0 = wt_time_now();
        if ((st = wt_learn_fit_model(L, M, &e)) < 0) goto done;
        tfit[k] = wt_time_now() - t0;
    }
    qsort(tfit, LEARN_BENCH_FITS, sizeof *tfit, cmp_double);
    printf("learn bench: %s, %d x %d subapertures (%d valid), %d LGS, %d pairs, %d altitudes, %lld terms\n"
           "  accumulation %.2f ms per frame (median of %ld)\n"
           "  model set-up %.2f s (response maps and normal matrix, once per grid and L0)\n"
           "  fit %.3f s (median of %d; min %.3f, max %.3f)\n",
           cfg->path, sys->n, sys->n, (int)ns / 2, sys->nlgs, wt_learn_npairs(L), na, (long long)e.rows,
           1e3 * tadd[F / 2], F, tmodel, tfit[LEARN_BENCH_FITS / 2], LEARN_BENCH_FITS, tfit[0],
           tfit[LEARN_BENCH_FITS - 1]);
done:
    free(s), free(z), free(tadd);
    wt_learn_model_free(M);
    wt_learn_free(L);
    wt_system_free(sys);
    wt_config_free(cli->ctx, cfg);
    return st;
}

static int learn_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    learn_args *a = user;
    const char *o = argv[*i];
    const char **str = !strcmp(o, "--telemetry") ? &a->tel : !strcmp(o, "--out") ? &a->out
                       : !strcmp(o, "--png") ? &a->png : !strcmp(o, "--wind-png") ? &a->wind_png : NULL;
    if (str) {
        if (!(*str = wt_cli_value(cli, argc, argv, i))) return -1;
        if (str == &a->wind_png) a->wind = 1;
    } else if (!strcmp(o, "--bench")) {
        a->bench = 1;
    } else if (!strcmp(o, "--wind")) {
        a->wind = 1;
    } else if (!strcmp(o, "--wind-threshold")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        char *end;
        if (!v) return -1;
        a->wind_min = strtod(v, &end);
        if (*end || !(a->wind_min > 0 && a->wind_min < 1)) {
            wt_cli_usage_error(cli, "--wind-threshold %s: expected a Cn2 fraction in (0, 1)", v);
            return -1;
        }
    } else if (!strcmp(o, "--lags")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v) return -1;
        a->nlag = 0;
        for (const char *c = v; *c;) {
            char *end;
            long k = strtol(c, &end, 10);
            if (end == c || k < 1 || k > WT_LEARN_MAX_LAG_FRAMES || a->nlag == WT_LEARN_MAX_LAG ||
                (a->nlag > 0 && k <= a->lags[a->nlag - 1]) || (*end && *end != ',')) {
                wt_cli_usage_error(cli, "--lags %s: expected up to %d increasing frame counts 1-%d, comma-separated", v,
                                   WT_LEARN_MAX_LAG, WT_LEARN_MAX_LAG_FRAMES);
                return -1;
            }
            a->lags[a->nlag++] = (int)k, a->wind = 1;
            c = *end ? end + 1 : end;
        }
    } else if (!strcmp(o, "--frames") || !strcmp(o, "--batches")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v) return -1;
        if (o[2] == 'f' ? wt_cli_int(cli, o, v, 2, 100000000, &a->frames) < 0
                        : wt_cli_int(cli, o, v, 2, WT_LEARN_MAX_BATCH, &a->batches) < 0)
            return -1;
    } else
        return 0;
    return 1;
}

/* The keys that fix the LGS slopes' geometry: a telemetry recorded with another value is another system here */
static int same_lgs_system(wt_context *ctx, const wt_config *a, const wt_config *b, const char *tel)
{
    struct { const char *key; double x, y; } k[] = {
        {"telescope.diameter_m", a->diameter, b->diameter},
        {"telescope.obstruction", a->obstruction, b->obstruction},
        {"lgs.count", a->nlgs, b->nlgs},
        {"lgs.radius_arcsec", a->lgs_radius, b->lgs_radius},
        {"lgs.azimuth0_deg", a->lgs_azimuth0, b->lgs_azimuth0},
        {"lgs.altitude_m", a->lgs_altitude, b->lgs_altitude},
        {"lgs.wfs.subapertures", a->lgs_wfs.subapertures, b->lgs_wfs.subapertures},
        {"lgs.wfs.valid_fraction", a->lgs_wfs.valid_fraction, b->lgs_wfs.valid_fraction},
    };
    for (size_t i = 0; i < sizeof k / sizeof *k; i++)
        if (fabs(k[i].x - k[i].y) > 1e-12 * fmax(fabs(k[i].x), fabs(k[i].y)))
            return WT_ERROR(ctx, WT_ERR_FORMAT, "%s was recorded on another system than %s: %s differs", tel, a->path,
                            k[i].key);
    return WT_OK;
}

/* Write a profile group: altitudes, fractions and (sigma non-NULL) their uncertainty */
static int write_profile(wt_h5_writer *w, const char *grp, int n, const double *alt, const double *f, const double *sig,
                         const char *what)
{
    char name[256], desc[512];
    int64_t d1[1] = {n};
    int st;
    snprintf(name, sizeof name, "%s/altitude_m", grp);
    snprintf(desc, sizeof desc, "altitudes of %s", what);
    if ((st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 1, d1, alt, "m", desc)) < 0) return st;
    snprintf(name, sizeof name, "%s/cn2_fraction", grp);
    snprintf(desc, sizeof desc, "Cn2 fraction at each altitude of %s (sum 1)", what);
    if ((st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 1, d1, f, "", desc)) < 0) return st;
    if (!sig) return WT_OK;
    snprintf(name, sizeof name, "%s/cn2_fraction_sigma", grp);
    snprintf(desc, sizeof desc, "uncertainty of the Cn2 fractions of %s: spread of the batch estimates / sqrt(batches) "
             "x estimate/sigma_factor", what);
    return wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 1, d1, sig, "", desc);
}

/* The estimate compressed onto L layers at ralt as the learning loop hands it over (its grid's hats,
 * core/model/profile.h), its uncertainty from the batches compressed the same way */
static void compress_estimate(const wt_learn_estimate *e, int L, const double *ralt, double *f, double *sig)
{
    wt_profile_compress_hats(e->nalt, e->altitude, e->fraction, NULL, NULL, L, ralt, f, NULL, NULL);
    double s1[WT_MAX_LAYERS] = {0}, s2[WT_MAX_LAYERS] = {0}, fb[WT_MAX_LAYERS];
    for (int b = 0; b < (e->nbatch >= 2 ? e->nbatch : 0); b++) {
        wt_profile_compress_hats(e->nalt, e->altitude, e->batch_fraction[b], NULL, NULL, L, ralt, fb, NULL, NULL);
        for (int l = 0; l < L; l++) s1[l] += fb[l], s2[l] += fb[l] * fb[l];
    }
    for (int l = 0; l < L; l++)
        sig[l] = e->nbatch >= 2 ? e->sigma_factor *
                                      sqrt(fmax(0.0, (s2[l] - s1[l] * s1[l] / e->nbatch) / (e->nbatch - 1)) / e->nbatch)
                                : 0.0;
}

static void print_table(const char *title, int n, const double *alt, const double *f, const double *sig, const double *truth)
{
    printf("  %s\n    altitude [km]   estimate        %s\n", title, truth ? "truth (binned the same way)" : "");
    for (int k = 0; k < n; k++) {
        printf("    %8.2f        %.3f ± %.3f", alt[k] / 1e3, f[k], sig[k]);
        if (truth) printf("   %.3f", truth[k]);
        printf("\n");
    }
}

int wt_cmd_learn(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo learn", help)) return 1;
    learn_args args = {.batches = LEARN_DEFAULT_BATCHES, .wind_min = WT_LEARN_WIND_MIN_FRACTION};
    int rc = wt_cli_parse(&cli, argc, argv, learn_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    if (args.bench) {
        if (!cli.config_path) rc = wt_cli_usage_error(&cli, "--bench needs --config CFG (the LGS geometry)");
        else {
            const int bst = learn_bench(&cli, args.frames);
            if (bst < 0) rc = wt_cli_fail(&cli, bst);
        }
        wt_cli_done(&cli);
        return rc;
    }
    if (!args.tel || !args.out) {
        rc = wt_cli_usage_error(&cli, "give --telemetry TEL.h5 and --out EST.h5");
        wt_cli_done(&cli);
        return rc;
    }
    wt_h5_reader *tr = NULL;
    wt_h5_writer *w = NULL;
    wt_config *cfg = NULL, *tcfg = NULL;
    wt_system *sys = NULL;
    wt_learn *L = NULL;
    float *sf = NULL;
    double *sd = NULL;
    int st;
    if ((st = wt_cli_check_output(&cli, args.out, 0, args.tel, NULL)) < 0) goto fail;
    if ((st = wt_h5_open(cli.ctx, args.tel, &tr)) < 0) goto fail;
    if ((st = wt_cli_telemetry_config(&cli, tr, args.tel, &tcfg, &cfg)) < 0) goto fail;
    if (cfg) {
        if ((st = same_lgs_system(cli.ctx, cfg, tcfg, args.tel)) < 0) goto fail;
    }
    const wt_config *use = cfg ? cfg : tcfg;
    if ((st = wt_system_alloc(cli.ctx, use, &sys)) < 0) goto fail;
    if (sys->nlgs < 2) {
        st = WT_ERROR(cli.ctx, WT_ERR_CONFIG, "%s: %d LGS: the profile needs at least 2 (pairs of LGS resolve altitude)",
                      use->path, sys->nlgs);
        goto fail;
    }
    if (!wt_h5_exists(tr, "slopes_ol")) {
        st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s holds no pseudo-open-loop slopes (dataset 'slopes_ol'): the profile is "
                      "identified from s + A^ a, which needs them", args.tel);
        goto fail;
    }
    int64_t es[2] = {-1, sys->nslopes}, dims[2];
    if ((st = wt_h5_check_shape(tr, "slopes_ol", 2, es, dims)) < 0) goto fail;
    int64_t F = dims[0];
    if (args.frames > 0) {
        if (args.frames > F) {
            st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s holds %lld frames, fewer than --frames %ld", args.tel, (long long)F,
                          args.frames);
            goto fail;
        }
        F = args.frames;
    }
    if (F < (int64_t)args.batches * LEARN_MIN_BATCH_FRAMES) {
        st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s: %lld frames, fewer than an estimate of %ld batches needs (%ld: %d per "
                      "batch)", args.tel, (long long)F, args.batches, args.batches * LEARN_MIN_BATCH_FRAMES,
                      LEARN_MIN_BATCH_FRAMES);
        goto fail;
    }
    /* the LGS geometry: every LGS has the sensor's valid subapertures, their slopes the first nlgs blocks */
    double tx[WT_MAX_GS], ty[WT_MAX_GS];
    for (int i = 0; i < sys->nlgs; i++) tx[i] = sys->sensors[i].theta_x, ty[i] = sys->sensors[i].theta_y;
    const wt_learn_geometry g = {sys->n, sys->d, sys->valid, sys->nlgs, tx, ty, sys->sensors[0].altitude};
    /* the wind's lags (frames of the telemetry's rate) */
    const double dt = 1.0 / tcfg->rate;
    if (args.wind && args.nlag == 0) {
        const int k1 = (int)fmax(1.0, floor(sys->d / (LEARN_WIND_VMAX * dt)));
        for (int q = 0; q < LEARN_WIND_NLAG; q++) args.lags[args.nlag++] = k1 << q;
    }
    if (args.nlag > 0 && F < args.lags[args.nlag - 1] + 2) {
        st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s: %lld frames, too few for the wind's longest lag of %d frames (it "
                      "needs %d): give shorter --lags", args.tel, (long long)F, args.lags[args.nlag - 1],
                      args.lags[args.nlag - 1] + 2);
        goto fail;
    }
    if ((st = wt_learn_alloc_lagged(cli.ctx, &g, (int)args.batches, F / args.batches, args.nlag, args.lags, &L)) < 0)
        goto fail;
    const int64_t nl = sys->sensors[sys->nlgs - 1].offset + sys->sensors[sys->nlgs - 1].nslopes;
    sf = malloc((size_t)sys->nslopes * sizeof *sf);
    sd = malloc((size_t)nl * sizeof *sd);
    if (!sf || !sd) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory for the frame buffers");
        goto fail;
    }
    wt_progress pr;
    double tadd = 0;
    wt_progress_start(&pr, "frames", "frames", (long)F);
    if (cli.quiet) pr.enabled = 0;
    for (int64_t t = 0; t < F; t++) {
        if ((st = wt_h5_read_rows(tr, "slopes_ol", WT_H5_F32, t, 1, sf)) < 0) goto fail;
        for (int64_t k = 0; k < nl; k++) sd[k] = sf[k];
        const double ta = wt_time_now();
        if ((st = wt_learn_add(L, sd)) < 0) goto fail;
        tadd += wt_time_now() - ta;
        wt_progress_update(&pr, (long)(t + 1), NULL);
    }
    wt_progress_end(&pr);
    double alt[WT_LEARN_MAX_ALT];
    const int na = wt_learn_default_grid(g.H, WT_LEARN_MAX_ALT, alt);
    if (!cli.quiet) fprintf(stderr, "%s: fitting %d altitudes to %d LGS pairs ...\n", cli.prog, na, wt_learn_npairs(L));
    /* the estimate first: free(e) frees both */
    struct learn_result { wt_learn_estimate e; wt_learn_wind wind; } *res = malloc(sizeof *res);
    wt_learn_estimate *e = res ? &res->e : NULL;
    if (!e) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory for the estimate");
        goto fail;
    }
    const double t0 = wt_time_now();
    st = wt_learn_fit(L, na, alt, use->model.L0, e);
    const double tfit = wt_time_now() - t0;
    if (st < 0) {
        free(e);
        goto fail;
    }
    wt_learn_estimate_count_screens(e, sys->diameter, dt, use->model.nlayers, use->model.fraction,
                                    use->model.wind_speed);
    /* the truth (the telemetry's simulated atmosphere), binned onto the same grid and layers: for comparison only */
    double tgrid[WT_LEARN_MAX_ALT], t3[WT_MAX_LAYERS], t9[WT_MAX_LAYERS], e3[WT_MAX_LAYERS], s3[WT_MAX_LAYERS],
        e9[WT_MAX_LAYERS], s9[WT_MAX_LAYERS];
    wt_profile_compress(tcfg->nlayers, tcfg->layer_altitude, tcfg->layer_fraction, NULL, NULL, na, alt, tgrid, NULL, NULL);
    wt_profile_compress(tcfg->nlayers, tcfg->layer_altitude, tcfg->layer_fraction, NULL, NULL, use->pcg3.nlayers,
                        use->pcg3.altitudes, t3, NULL, NULL);
    wt_profile_compress(tcfg->nlayers, tcfg->layer_altitude, tcfg->layer_fraction, NULL, NULL, use->cg9.nlayers,
                        use->cg9.altitudes, t9, NULL, NULL);
    compress_estimate(e, use->pcg3.nlayers, use->pcg3.altitudes, e3, s3);
    compress_estimate(e, use->cg9.nlayers, use->cg9.altitudes, e9, s9);
    printf("learn: %lld frames of %s in %d batches, %d LGS pairs, %lld terms fitted (relative misfit %.3f)\n"
           "  accumulation %.3f ms per frame, fit %.2f s\n",
           (long long)e->frames, args.tel, e->nbatch, wt_learn_npairs(L), (long long)e->rows, e->residual,
           1e3 * tadd / (double)F, tfit);
    printf("  r0 (500 nm)  %.4f ± %.4f m   truth %.4f m (%+.1f %%); L0 %.1f m (fixed, recon.atmosphere)\n", e->r0,
           e->r0_sigma, tcfg->r0, 100 * (e->r0 / tcfg->r0 - 1), e->L0);
    printf("  r0 of the whole fit's total Cn2 %.4f m (%+.1f %%; r0 above is scaled on the autos within two subapertures)\n",
           e->r0_total, 100 * (e->r0_total / tcfg->r0 - 1));
    printf("  uncertainties: the %d batches' spread / sqrt(batches) x %.2f: the frames saw %.2f renewals of the screens "
           "(each layer moving the aperture's %.1f m at recon.atmosphere's wind)\n", e->nbatch, e->sigma_factor,
           e->screens, sys->diameter);
    print_table("Cn2 fractions on the altitude grid", na, alt, e->fraction, e->fraction_sigma, tgrid);
    print_table("compressed onto pcg3's layers", use->pcg3.nlayers, use->pcg3.altitudes, e3, s3, t3);
    print_table("compressed onto cg9's layers", use->cg9.nlayers, use->cg9.altitudes, e9, s9, t9);
    if (args.nlag > 0) {
        if (!cli.quiet) fprintf(stderr, "%s: fitting the wind to %d lags ...\n", cli.prog, args.nlag);
        const double tw = wt_time_now();
        wt_progress_phases pp = {.quiet = cli.quiet};
        wt_learn_set_progress(L, wt_progress_phase, &pp);
        st = wt_learn_wind_fit(L, e, dt, args.wind_min, &res->wind);
        wt_progress_phases_end(&pp);
        if (st < 0) goto fail_e;
        wt_learn_wind_print(&res->wind, use, tcfg, wt_time_now() - tw);
    }
    /* EST.h5 */
    if ((st = wt_h5_create(cli.ctx, args.out, &w)) < 0) goto fail_e;
    if ((st = write_profile(w, "estimate", na, alt, e->fraction, e->fraction_sigma, "the identification grid")) < 0) goto fail_e;
    {
        int64_t d1[1] = {na};
        if ((st = wt_h5_write(w, "estimate/cn2_r0", WT_H5_F64, WT_H5_F64, 1, d1, e->cn2, "m^-5/3",
                              "c_h = f_h r0^(-5/3) at 500 nm: the non-negative least-squares fit, the lowest altitude taking the "
                              "difference between the total of the autos' small offsets and the fit's")) < 0)
            goto fail_e;
    }
    if ((st = wt_h5_write_double(w, "estimate/r0_m", e->r0, "m", "Fried parameter at 500 nm, (sum c_h)^(-3/5): the "
                                 "total that fits the autos within 2 subapertures, each map less its mean there")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/r0_total_m", e->r0_total, "m", "r0 of the non-negative fit's own total "
                                 "(every offset: it follows the large scales' realisation)")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/r0_sigma_m", e->r0_sigma, "m",
                                 "uncertainty of r0: spread of the batch estimates / sqrt(batches) x sigma_factor")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/sigma_factor", e->sigma_factor, "",
                                 "sqrt(max(1, tau / batch duration)), tau = D sum_k f_k / max(v_k, 1 m/s) the screens' "
                                 "renewal time at recon.atmosphere's wind: consecutive batches see the same turbulence "
                                 "until it moved by the aperture D")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/screens", e->screens, "",
                                 "renewals of the screens the frames saw, T / tau")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/L0_m", e->L0, "m", "outer scale of the response maps (fixed)")) < 0 ||
        (st = wt_h5_write_double(w, "estimate/residual", e->residual, "",
                                 "weighted rms misfit of the fit over the weighted rms of the maps")) < 0 ||
        (st = wt_h5_write_int64(w, "estimate/frames", e->frames, "", "frames used")) < 0 ||
        (st = wt_h5_write_int64(w, "estimate/batches", e->nbatch, "", "batches of consecutive frames")) < 0)
        goto fail_e;
    if ((st = write_profile(w, "estimate/pcg3", use->pcg3.nlayers, use->pcg3.altitudes, e3, s3,
                            "the estimate compressed onto pcg3's layers")) < 0 ||
        (st = write_profile(w, "estimate/cg9", use->cg9.nlayers, use->cg9.altitudes, e9, s9,
                            "the estimate compressed onto cg9's layers")) < 0 ||
        (st = write_profile(w, "truth/grid", na, alt, tgrid, NULL,
                            "the telemetry's simulated atmosphere compressed onto the identification grid")) < 0 ||
        (st = write_profile(w, "truth/pcg3", use->pcg3.nlayers, use->pcg3.altitudes, t3, NULL,
                            "the telemetry's simulated atmosphere compressed onto pcg3's layers")) < 0 ||
        (st = write_profile(w, "truth/cg9", use->cg9.nlayers, use->cg9.altitudes, t9, NULL,
                            "the telemetry's simulated atmosphere compressed onto cg9's layers")) < 0 ||
        (st = write_profile(w, "truth/layers", tcfg->nlayers, tcfg->layer_altitude, tcfg->layer_fraction, NULL,
                            "the telemetry's simulated atmosphere (never read by the estimate)")) < 0 ||
        (st = wt_h5_write_double(w, "truth/r0_m", tcfg->r0, "m", "the simulated atmosphere's r0 at 500 nm")) < 0)
        goto fail_e;
    if (args.nlag > 0 && (st = wt_learn_wind_write(w, &res->wind, use, tcfg)) < 0) goto fail_e;
    if ((st = wt_cli_write_provenance(&cli, w, use, argc, argv)) < 0) goto fail_e;
    if ((st = wt_h5_attr_write_string(w, "/", "telemetry", args.tel)) < 0) goto fail_e;
    st = wt_h5_commit(w);
    w = NULL;
    if (st < 0) goto fail_e;
    printf("  estimate: %s\n", args.out);
    if (args.png) {
        /* estimate and truth side by side on cg9's layers (the finest of the two reconstructors') */
        char labels[WT_MAX_LAYERS][32], title[160];
        const char *groups[WT_MAX_LAYERS], *series[2] = {"estimate", "truth"};
        double v[2 * WT_MAX_LAYERS];
        for (int l = 0; l < use->cg9.nlayers; l++) {
            snprintf(labels[l], sizeof labels[l], "%.1f km", use->cg9.altitudes[l] / 1e3);
            groups[l] = labels[l], v[2 * l] = e9[l], v[2 * l + 1] = t9[l];
        }
        snprintf(title, sizeof title, "%lld frames: r0 %.3f +- %.3f m (truth %.3f)",
                 (long long)e->frames, e->r0, e->r0_sigma, tcfg->r0);
        if ((st = wt_plot_grouped_bars(cli.ctx, args.png, title, "Cn2 fraction", use->cg9.nlayers, groups, 2, series, v,
                                       NULL)) < 0)
            goto fail_e;
        printf("  plot: %s\n", args.png);
    }
    if (args.wind_png) {
        if ((st = wt_learn_wind_plot(cli.ctx, args.wind_png, &res->wind, tcfg)) < 0) goto fail_e;
        printf("  wind plot: %s\n", args.wind_png);
    }
    free(e);
    goto cleanup;
fail_e:
    free(e);
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_h5_abort(w);
    wt_h5_close(tr);
    free(sf), free(sd);
    wt_learn_free(L);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_config_free(cli.ctx, tcfg);
    wt_cli_done(&cli);
    return rc;
}
