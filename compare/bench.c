/* compare/bench.c: kernel timings of the reconstructor and the machine's scale (see bench.h). */
#include "bench.h"
#include <math.h>

#include "../core/la/half.h"

#include <cblas.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../core/base/rng.h"
#include "../core/la/half.h"
#include "../core/model/fitting.h"
#include "../core/model/precond.h"
#include "../core/model/profile.h"
#include "../core/model/sensing.h"
#include "../core/optics/centroid.h"
#include "../core/optics/sodium.h"
#include "../core/optics/spot.h"
#include "../core/model/tomography.h"
#include "../core/op/shift.h"
#include "../core/solve/mvm.h"
#include "../core/solve/pcg.h"

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

wt_bench_stats wt_bench_summarise(double *t, int n)
{
    qsort(t, (size_t)n, sizeof *t, cmp_double);
    wt_bench_stats s = {t[n / 2], t[n / 10], t[(9 * n) / 10], t[(99 * n) / 100]};
    return s;
}

/* STREAM triad: 24 bytes per element, arrays far larger than the caches. */
double wt_bench_triad_bandwidth(wt_context *ctx, int reps)
{
    const size_t n = 1 << 25; /* 3 x 256 MB */
    const int nth = wt_context_threads(ctx);
    double *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *c = malloc(n * sizeof *c);
    if (!a || !b || !c) {
        free(a), free(b), free(c);
        return 0.0;
    }
#pragma omp parallel for schedule(static) num_threads(nth)
    for (size_t i = 0; i < n; i++) a[i] = 0.0, b[i] = 1.0, c[i] = 2.0;
    double best = 1e30;
    for (int r = 0; r < reps; r++) {
        double t0 = wt_time_now();
#pragma omp parallel for schedule(static) num_threads(nth)
        for (size_t i = 0; i < n; i++) a[i] = b[i] + 0.5 * c[i];
        double t = wt_time_now() - t0;
        if (t < best) best = t;
    }
    double bw = 24.0 * (double)n / best;
    free(a), free(b), free(c);
    return bw;
}

double wt_bench_dgemm_rate(void)
{
    const int n = 2048;
    double *a = malloc((size_t)n * n * sizeof *a), *b = malloc((size_t)n * n * sizeof *b),
           *c = calloc((size_t)n * n, sizeof *c);
    if (!a || !b || !c) {
        free(a), free(b), free(c);
        return 0.0;
    }
    for (size_t i = 0; i < (size_t)n * n; i++) a[i] = 1.0 / (1.0 + (double)(i % 97)), b[i] = 1.0 / (1.0 + (double)(i % 89));
    double best = 1e30;
    for (int r = 0; r < 3; r++) {
        double t0 = wt_time_now();
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, n, n, 1.0, a, n, b, n, 0.0, c, n);
        double t = wt_time_now() - t0;
        if (t < best) best = t;
    }
    free(a), free(b), free(c);
    return 2.0 * n * (double)n * n / best;
}

/* The cg9 fitting step on the layers of coefficients c, reps times. */
static int time_fitting(wt_context *ctx, const wt_system *sys, wt_tomography *t, const wt_reconstructor_params *par,
                        const double *c, int reps, double *times, wt_bench_stats *out)
{
    wt_fitting *f = NULL;
    int st = wt_fitting_alloc_for(ctx, t, &par->fitting, &f);
    if (st < 0) return st;
    double *a = calloc((size_t)sys->nact, sizeof *a), *phi = malloc((size_t)wt_tomography_nunknowns(t) * sizeof *phi);
    if (a && phi) {
        wt_tomography_layers(t, c, phi);
        for (int r = 0; r < reps; r++) {
            double a0 = wt_time_now();
            wt_fitting_solve_continue(f, phi, a, par->fit_iterations, 0.0, NULL, NULL);
            times[r] = wt_time_now() - a0;
        }
        *out = wt_bench_summarise(times, reps);
    } else
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for the fitting");
    free(a);
    free(phi);
    wt_fitting_free(f);
    return st;
}

/* recon.predict's shift of t's layers (the reconstructor's make_shift: the model's wind compressed onto them as its
 * Cn², times the lead; tp's profile is the model's, cfg->model, under the oracle as with a given profile) on the estimate c's layers; at least 200 repetitions (a call is well under a frame) */
static int time_shift(wt_context *ctx, const wt_system *sys, wt_tomography *t, const wt_reconstructor_params *par,
                      const double *c, wt_bench_tomography *out)
{
    const int L = wt_tomography_nlayers(t);
    const wt_tomography_params *tp = &par->tomography;
    const double lead = par->predict_lead > 0.0 ? par->predict_lead : (double)sys->cfg->delay / sys->cfg->rate;
    const wt_grid *g[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++) g[l] = wt_tomography_layer_grid(t, l), off[l] = wt_tomography_layer_offset(t, l);
    /* the model's wind as wt_reconstructor_params_from_config reads it under recon.predict */
    const wt_config *cfg = sys->cfg;
    double vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS];
    for (int k = 0; k < cfg->model.nlayers; k++)
        vx[k] = cfg->model.wind_speed[k] * cos(cfg->model.wind_direction[k]),
        vy[k] = cfg->model.wind_speed[k] * sin(cfg->model.wind_direction[k]);
    /* over the lead, and a frame's shift of the state for the integrator on the layers */
    wt_shift *sh = NULL, *sh1 = NULL;
    int st = wt_predict_shift_alloc(ctx, t, tp->natm, tp->atm_altitude, tp->atm_fraction, vx, vy, lead, &sh);
    if (st >= 0)
        st = wt_predict_shift_alloc(ctx, t, tp->natm, tp->atm_altitude, tp->atm_fraction, vx, vy, 1.0 / cfg->rate, &sh1);
    if (st < 0) {
        wt_shift_free(sh);
        return st;
    }
    out->shift_moving = wt_shift_nmoving(sh);
    const int64_t n = wt_tomography_nunknowns(t);
    const int reps = 200;
    double *phi = malloc((size_t)n * sizeof *phi), *pred = malloc((size_t)n * sizeof *pred),
           *times = malloc(reps * sizeof *times);
    if (!phi || !pred || !times) st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for the shift's layers");
    if (st >= 0 && out->shift_moving) {
        wt_tomography_layers(t, c, phi);
        wt_shift_apply_to(sh, phi, pred); /* warm caches and pages */
        for (int r = 0; r < reps; r++) {
            const double a = wt_time_now();
            wt_shift_apply_to(sh, phi, pred);
            times[r] = wt_time_now() - a;
        }
        out->shift = wt_bench_summarise(times, reps);
        wt_shift_integrator *it = NULL;
        const double gain = par->integrator_gain > 0.0 ? par->integrator_gain : cfg->gain;
        if ((st = wt_shift_integrator_alloc(ctx, L, g, off, cfg->delay > 0 ? cfg->delay : 1, &it)) >= 0) {
            for (int r = 0; r < 8 && st >= 0; r++) st = wt_shift_integrator_step(it, sh, sh1, gain, phi, pred); /* a state */
            for (int r = 0; r < reps && st >= 0; r++) {
                const double a = wt_time_now();
                st = wt_shift_integrator_step(it, sh, sh1, gain, phi, pred);
                times[r] = wt_time_now() - a;
            }
            if (st >= 0) out->integrate = wt_bench_summarise(times, reps);
        }
        wt_shift_integrator_free(it);
        /* a moving n × n layer: four passes of n/2 complex transforms of length n (5 n log2 n each) and two of n²/2
         * complex products */
        for (int l = 0; l < L; l++) {
            const double m = (double)g[l]->nx * g[l]->nx;
            /* the integrator: every layer to its half spectrum and back (~n transforms each way) and ~20 flops a point
             * for the two factors and the update; φ and z_(t+d) once, the spectra Ẑ_t, Ẑ_(t+d−1) read, Ẑ_(t+d) written */
            out->integrate_flops += 10.0 * m * log2(g[l]->nx) + 20.0 * m;
            out->integrate_bytes += 40.0 * m;
            if (!wt_shift_layer_moves(sh, l)) continue;
            out->shift_flops += 10.0 * m * log2(g[l]->nx) + 6.0 * m;
            out->shift_bytes += 16.0 * m;
        }
    }
    free(phi);
    free(pred);
    free(times);
    wt_shift_free(sh);
    wt_shift_free(sh1);
    return st;
}

int wt_bench_tomography_run(wt_context *ctx, const wt_system *sys, const wt_reconstructor_params *par,
                            const char *name, int reps, wt_bench_tomography *out)
{
    const wt_recon_variant_config *v = par->variant;
    wt_tomography *t = NULL;
    wt_precond *pre = NULL;
    double *c = NULL, *y = NULL, *s = NULL, *times = NULL;
    memset(out, 0, sizeof *out);
    double t0 = wt_time_now();
    int st = wt_tomography_alloc(ctx, sys, v, name, &par->tomography, &t);
    if (st < 0) return st;
    if ((st = wt_precond_alloc(ctx, t, &par->precond, &pre)) < 0) goto out;
    out->setup = wt_time_now() - t0;
    const wt_pcg_precond P = wt_precond_pcg(pre);
    int64_t n = wt_tomography_nunknowns(t);
    out->nunknowns = n;
    c = malloc((size_t)n * sizeof *c), y = malloc((size_t)n * sizeof *y);
    s = malloc((size_t)sys->nslopes * sizeof *s), times = malloc((size_t)reps * sizeof *times);
    if (!c || !y || !s || !times) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory");
        goto out;
    }
    wt_rng rng;
    wt_rng_init(&rng, 7, 0);
    for (int64_t i = 0; i < n; i++) c[i] = wt_rng_normal(&rng) * 1e-7;
    for (int64_t i = 0; i < sys->nslopes; i++) s[i] = wt_rng_normal(&rng) * 1e-6;
    wt_tomography_cost(t, &out->flops, &out->bytes);

    wt_tomography_apply(t, 1.0, c, y); /* warm caches and pages */
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_tomography_apply(t, 1.0, c, y);
        times[r] = wt_time_now() - a;
    }
    out->apply = wt_bench_summarise(times, reps);

    const int preconditioned = par->precond.kind != WT_PRECOND_NONE;
    out->it_flops = out->flops + wt_pcg_flops_per_iteration(n, preconditioned);
    out->it_bytes = out->bytes + 8.0 * n * (preconditioned ? 12.0 : 11.0);
    /* one iteration = (time of 9 iterations − time of 1) / 8, from the same starting point: the
     * right-hand side and the initial residual cancel out */
    for (int r = 0; r < reps; r++) {
        memset(c, 0, (size_t)n * sizeof *c);
        double a = wt_time_now();
        wt_tomography_solve(t, P, s, c, 1, 0.0, NULL, NULL);
        double one = wt_time_now() - a;
        memset(c, 0, (size_t)n * sizeof *c);
        a = wt_time_now();
        wt_tomography_solve(t, P, s, c, 9, 0.0, NULL, NULL);
        times[r] = ((wt_time_now() - a) - one) / 8.0;
    }
    out->iteration = wt_bench_summarise(times, reps);

    /* a whole frame as the loop runs it: right-hand side, the initial residual (continued from the previous
     * solve, wt_tomography_solve_continue) and the configured iterations, warm-started */
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_tomography_solve_continue(t, P, s, c, par->iterations, 0.0, NULL, NULL);
        times[r] = wt_time_now() - a;
    }
    out->frame = wt_bench_summarise(times, reps);

    /* the frame's profile, on frames of their own (the timed ones above run without the extra clock reads) */
    if ((st = wt_tomography_profile_start(t)) < 0) goto out;
    for (int r = 0; r < reps; r++) wt_tomography_solve_continue(t, P, s, c, par->iterations, 0.0, NULL, NULL);
    wt_tomography_profile_stop(t, out->stage);
    out->prof_frames = reps;

    if ((st = time_shift(ctx, sys, t, par, c, out)) < 0) goto out;

    if (par->fit_iterations > 0) {
        if ((st = time_fitting(ctx, sys, t, par, c, reps, times, &out->fitting)) < 0) goto out;
        out->has_fitting = 1;
    }
out:
    free(c);
    free(y);
    free(s);
    free(times);
    wt_precond_free(pre);
    wt_tomography_free(t);
    return st;
}

/* The next frame's slopes: s ← 0.9 s + 0.44 n (stationary at 1 µrad rms per slope, frame-to-frame
 * correlation 0.9). */
static void next_slopes(wt_rng *rng, double *s, int64_t n)
{
    for (int64_t i = 0; i < n; i++) s[i] = 0.9 * s[i] + 0.4359 * 1e-6 * wt_rng_normal(rng);
}

int wt_bench_pair_run(wt_context *ctx, const wt_system *const sys[2], const wt_reconstructor_params par[2], int kind,
                      int warm, int pairs, wt_bench_pair *out)
{
    int st = WT_OK;
    wt_reconstructor *r[2] = {NULL, NULL};
    double *s[2] = {NULL, NULL}, *a[2] = {NULL, NULL}, *t = NULL;
    memset(out, 0, sizeof *out);
    if (kind != WT_RECON_PCG3 && kind != WT_RECON_CG9)
        return WT_ERROR(ctx, WT_ERR_INVALID, "bench: the paired mode times pcg3 or cg9, not %s", wt_reconstructor_name(kind));
    if (pairs < 1 || warm < 0) return WT_ERROR(ctx, WT_ERR_INVALID, "bench: %d pairs after %d warm frames", pairs, warm);
    for (int k = 0; k < 2; k++) {
        double t0 = wt_time_now();
        if ((st = wt_reconstructor_alloc(ctx, sys[k], kind, &par[k], &r[k])) < 0) goto out;
        out->setup[k] = wt_time_now() - t0;
        out->memory[k] = wt_reconstructor_bytes(r[k]);
        const wt_fitting *fit = wt_reconstructor_fitting(r[k]);
        if (fit) {
            out->has_fitting = 1;
            out->fit_solver[k] = wt_fitting_solver(fit);
            wt_fitting_stats_get(fit, &out->fit[k]);
        }
        s[k] = calloc((size_t)sys[k]->nslopes, sizeof *s[k]);
        a[k] = calloc((size_t)sys[k]->nact, sizeof *a[k]);
        if (!s[k] || !a[k]) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for the paired slopes");
            goto out;
        }
    }
    t = malloc(9 * (size_t)pairs * sizeof *t); /* frame, tomography, fitting of A and B; then the 3 ratios */
    if (!t) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for %d paired timings", pairs);
        goto out;
    }
    /* one generator per side with the same seed: the same slopes when the systems agree */
    wt_rng rng[2];
    for (int k = 0; k < 2; k++) {
        wt_rng_init(&rng[k], 20, 5);
        for (int64_t i = 0; i < sys[k]->nslopes; i++) s[k][i] = 1e-6 * wt_rng_normal(&rng[k]);
    }
    for (int f = -warm; f < pairs; f++) {
        if (f == 0) /* each side's stages over the timed pairs (two clock reads per region: ~1 µs a frame) */
            for (int k = 0; k < 2; k++)
                if ((st = wt_tomography_profile_start(wt_reconstructor_tomography(r[k]))) < 0) goto out;
        for (int j = 0; j < 2; j++) {
            const int k = (f & 1) ? 1 - j : j; /* A B, then B A */
            next_slopes(&rng[k], s[k], sys[k]->nslopes);
            const double t0 = wt_time_now();
            if ((st = wt_reconstructor_apply(r[k], s[k], a[k])) < 0) goto out;
            const double el = wt_time_now() - t0;
            if (f < 0) continue;
            double tt, tf;
            wt_reconstructor_last_times(r[k], &tt, &tf);
            t[(size_t)(3 * k) * pairs + f] = el;
            t[(size_t)(3 * k + 1) * pairs + f] = tt;
            t[(size_t)(3 * k + 2) * pairs + f] = tf;
        }
    }
    for (int k = 0; k < 2; k++) wt_tomography_profile_stop(wt_reconstructor_tomography(r[k]), out->stage[k]);
    for (int q = 0; q < 3; q++) /* the ratios before the sorts below reorder the samples */
        for (int f = 0; f < pairs; f++) {
            const double ta = t[(size_t)q * pairs + f], tb = t[(size_t)(3 + q) * pairs + f];
            t[(size_t)(6 + q) * pairs + f] = ta > 0.0 ? tb / ta : 0.0;
        }
    for (int k = 0; k < 2; k++) {
        out->frame[k] = wt_bench_summarise(t + (size_t)(3 * k) * pairs, pairs);
        out->tomography[k] = wt_bench_summarise(t + (size_t)(3 * k + 1) * pairs, pairs);
        out->fitting[k] = wt_bench_summarise(t + (size_t)(3 * k + 2) * pairs, pairs);
    }
    out->ratio_frame = wt_bench_summarise(t + (size_t)6 * pairs, pairs);
    out->ratio_tomography = wt_bench_summarise(t + (size_t)7 * pairs, pairs);
    out->ratio_fitting = wt_bench_summarise(t + (size_t)8 * pairs, pairs);
    out->command_diff = -1.0;
    if (sys[0]->nslopes == sys[1]->nslopes && sys[0]->nact == sys[1]->nact) {
        double d = 0.0, n = 0.0;
        for (int64_t i = 0; i < sys[0]->nact; i++) {
            d += (a[1][i] - a[0][i]) * (a[1][i] - a[0][i]);
            n += a[0][i] * a[0][i];
        }
        out->command_diff = n > 0.0 ? sqrt(d / n) : sqrt(d);
    }
out:
    for (int k = 0; k < 2; k++) {
        wt_reconstructor_free(r[k]);
        free(s[k]);
        free(a[k]);
    }
    free(t);
    return st;
}

int wt_bench_loop_run(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, const wt_loop_params *par,
                      int warm, int frames, wt_bench_loop *out)
{
    wt_loop *lp = NULL;
    memset(out, 0, sizeof *out);
    double t0 = wt_time_now();
    int st = wt_loop_alloc_params(ctx, sys, opt, par, &lp);
    if (st < 0) return st;
    out->setup = wt_time_now() - t0;
    for (int t = 0; t < warm && st >= 0; t++) st = wt_loop_step(lp);
    wt_loop_times a = wt_loop_get_times(lp);
    double *ft = malloc((size_t)frames * sizeof *ft);
    if (!ft && st >= 0) st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory");
    for (int t = 0; t < frames && st >= 0; t++) {
        double f0 = wt_time_now();
        st = wt_loop_step(lp);
        ft[t] = wt_time_now() - f0;
    }
    if (st >= 0) {
        wt_loop_times b = wt_loop_get_times(lp);
        out->frame = wt_bench_summarise(ft, frames);
        out->per_frame = (wt_loop_times){(b.atmosphere - a.atmosphere) / frames, (b.sensors - a.sensors) / frames,
                                         (b.reconstruction - a.reconstruction) / frames,
                                         (b.fitting - a.fitting) / frames, (b.control - a.control) / frames,
                                         (b.evaluation - a.evaluation) / frames, (b.learning - a.learning) / frames};
    }
    free(ft);
    wt_loop_free(lp);
    return st;
}

/* R (n_act x n_slopes float32) must be streamed once per frame, so a STREAM copy of the same byte count
 * (read + write of R's size) sets the scale. */
int wt_bench_mvm_apply(wt_context *ctx, int64_t nact, int64_t nslopes, int reps, wt_bench_mvm *out)
{
    const int64_t na = nact, ns = nslopes;
    const size_t n = (size_t)na * (size_t)ns;
    const int nth = wt_context_threads(ctx);
    memset(out, 0, sizeof *out);
    float *R = malloc(n * sizeof *R), *C = malloc(n * sizeof *C), *x = malloc((size_t)ns * sizeof *x),
          *y = malloc((size_t)na * sizeof *y), *y16 = malloc((size_t)na * sizeof *y16);
    uint16_t *H[2] = {malloc(n * sizeof(uint16_t)), malloc(n * sizeof(uint16_t))};
    float *Hc[2] = {malloc((size_t)na * sizeof(float)), malloc((size_t)na * sizeof(float))};
    double *tg = malloc((size_t)reps * sizeof *tg), *tc = malloc((size_t)reps * sizeof *tc);
    double *th[2] = {malloc((size_t)reps * sizeof(double)), malloc((size_t)reps * sizeof(double))};
    const int prec[2] = {WT_PREC_F16, WT_PREC_BF16};
    int st = WT_OK;
    if (!R || !C || !x || !y || !y16 || !tg || !tc || !H[0] || !H[1] || !Hc[0] || !Hc[1] || !th[0] || !th[1]) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for a %.2f GB matrix", 3.0 * (double)n * 4.0 / 1e9);
        goto out;
    }
#pragma omp parallel for schedule(static) num_threads(nth)
    for (size_t i = 0; i < n; i++) R[i] = C[i] = (float)((i * 2654435761u) % 1000) * 1e-3f;
    for (int64_t i = 0; i < ns; i++) x[i] = (float)(i % 7) * 1e-6f;
    /* the runtime's own apply (core/solve/mvm.h) on containers that borrow R and its 16-bit copies */
    const wt_mvm view = {.ctx = ctx, .commands = WT_MVM_LAYER_VALUES, .nact = na, .nslopes = ns, .R = R};
    wt_mvm v16[2];
    for (int k = 0; k < 2; k++) {
        wt_half_pack(prec[k], na, ns, R, H[k], Hc[k], nth);
        v16[k] = (wt_mvm){.ctx = ctx, .commands = WT_MVM_LAYER_VALUES, .nact = na, .nslopes = ns,
                          .precision = prec[k], .Rh = H[k], .Rc = Hc[k], .nthreads = nth};
    }
    double err[2] = {0, 0}, ymax = 0;
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_mvm_apply(&view, x, NULL, y);
        tg[r] = wt_time_now() - a;
        for (int k = 0; k < 2; k++) {
            a = wt_time_now();
            wt_mvm_apply(&v16[k], x, NULL, y16);
            th[k][r] = wt_time_now() - a;
            if (r == 0)
                for (int64_t i = 0; i < na; i++) {
                    err[k] = fmax(err[k], fabs((double)y16[i] - y[i]));
                    ymax = fmax(ymax, fabs((double)y[i]));
                }
        }
        a = wt_time_now();
#pragma omp parallel for schedule(static) num_threads(nth)
        for (size_t i = 0; i < n; i++) C[i] = R[i];
        tc[r] = wt_time_now() - a;
    }
    out->bytes = 4.0 * (double)n;
    out->sgemv = wt_bench_summarise(tg, reps);
    out->copy = wt_bench_summarise(tc, reps);
    for (int k = 0; k < 2; k++) {
        out->half[k] = wt_bench_summarise(th[k], reps);
        out->half_prec[k] = prec[k];
        out->half_error[k] = ymax > 0 ? err[k] / ymax : 0.0;
    }
out:
    free(R), free(C), free(x), free(y), free(y16), free(tg), free(tc);
    for (int k = 0; k < 2; k++) free(H[k]), free(Hc[k]), free(th[k]);
    return st;
}

int wt_bench_sensing_run(wt_context *ctx, const wt_system *sys, int kind, int reps, wt_bench_sensing *out)
{
    memset(out, 0, sizeof *out);
    int64_t maxslopes = 0;
    for (int i = 0; i < sys->nsensors; i++) {
        const wt_sensing *ws = sys->sensors[i].diffr;
        if (!ws || sys->sensors[i].kind != kind) continue;
        if (!out->nsensors) {
            out->np = ws->np, out->ns = ws->ns;
            wt_spot_cost(ws->spot, &out->flops, &out->bytes);
        }
        out->nsensors++;
        out->nsub += ws->nsub;
        out->setup += ws->setup_seconds;
        out->memory += (double)wt_sensing_memory(ws);
        if (2 * ws->nsub > maxslopes) maxslopes = 2 * ws->nsub;
    }
    if (!out->nsensors) return WT_OK;
    for (int i = 0; i < sys->nsensors; i++)
        if (sys->sensors[i].diffr && sys->sensors[i].kind == kind) {
            const wt_sensor_config *w = kind == WT_SENSOR_LGS ? &sys->cfg->lgs_wfs : &sys->cfg->ngs_wfs;
            out->N = w->fft_size, out->k = w->cells_per_pixel ? w->cells_per_pixel : 3;
            break;
        }
    double *sl = malloc((size_t)maxslopes * sizeof *sl), *tf = malloc(4 * (size_t)reps * sizeof *tf);
    if (!sl || !tf) {
        free(sl), free(tf);
        return WT_ERROR(ctx, WT_ERR_NOMEM, "bench: out of memory for the sensing timings");
    }
    double *ti = tf + reps, *tn = tf + 2 * reps, *tc = tf + 3 * reps;
    /* the OPD: fixed for the run (the sensors' own per-frame buffers, overwritten here) */
    for (int i = 0; i < sys->nsensors; i++) {
        wt_sensing *ws = sys->sensors[i].diffr;
        if (!ws || sys->sensors[i].kind != kind) continue;
        wt_rng r;
        wt_rng_init(&r, 11, (uint64_t)i);
        const size_t n = (size_t)ws->nsub * ws->np * ws->np;
        for (size_t j = 0; j < n; j++) ws->opd[j] = ws->amp[j] > 0.0f ? (float)(100e-9 * wt_rng_normal(&r)) : 0.0f;
    }
    struct timespec c0 = {0, 0}, c1;
    for (int f = -1; f < reps; f++) {
        if (f == 0) clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
        double a = 0, b = 0, c = 0;
        for (int i = 0; i < sys->nsensors; i++) {
            wt_sensing *ws = sys->sensors[i].diffr;
            if (!ws || sys->sensors[i].kind != kind) continue;
            const uint64_t stream = (UINT64_C(1) << 32) + 64 * (uint64_t)(f + 1) + (uint64_t)i;
            double t0 = wt_time_now();
            wt_spot_image(ws->spot, ws->opd, ws->img);
            double t1 = wt_time_now();
            wt_spot_noise(ws->spot, 1, stream, ws->img);
            double t2 = wt_time_now();
            wt_centroid_apply(ws->cen, ws->img, sl);
            double t3 = wt_time_now();
            a += t1 - t0, b += t2 - t1, c += t3 - t2;
        }
        if (f < 0) continue; /* warm: pages, caches */
        ti[f] = a, tn[f] = b, tc[f] = c, tf[f] = a + b + c;
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c1);
    out->cpu = ((double)(c1.tv_sec - c0.tv_sec) + 1e-9 * (double)(c1.tv_nsec - c0.tv_nsec)) / reps;
    out->frame = wt_bench_summarise(tf, reps);
    out->images = wt_bench_summarise(ti, reps);
    out->noise = wt_bench_summarise(tn, reps);
    out->centroid = wt_bench_summarise(tc, reps);
    free(sl), free(tf);
    return WT_OK;
}

static double cpu_now(void)
{
    struct timespec c;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c);
    return (double)c.tv_sec + 1e-9 * (double)c.tv_nsec;
}

int wt_bench_sodium_run(wt_context *ctx, const wt_system *sys, int reps, wt_bench_sodium *out)
{
    memset(out, 0, sizeof *out);
    int st = WT_OK;
    wt_sodium *na = NULL;
    double *tt = NULL, *tr = NULL;
    for (int i = 0; i < sys->nsensors; i++) {
        const wt_sensing *ws = sys->sensors[i].diffr;
        if (!ws || sys->sensors[i].kind != WT_SENSOR_LGS || !ws->sodium0) continue;
        if (!na) WT_TRY(wt_sodium_copy(ws->sodium0, &na));
        out->nsensors++, out->nsub += ws->nsub;
    }
    if (!out->nsensors) return WT_OK;
    for (int k = 0; k < na->n; k++) na->alt[k] += 500.0; /* a layer that rose (it still holds H: checked below) */
    WT_ALLOC(ctx, tt, reps, "bench timings");
    WT_ALLOC(ctx, tr, reps, "bench timings");
    double c0 = cpu_now();
    for (int f = 0; f < reps; f++) {
        const double t0 = wt_time_now();
        for (int i = 0; i < sys->nsensors; i++) {
            wt_sensing *ws = sys->sensors[i].diffr;
            if (ws && sys->sensors[i].kind == WT_SENSOR_LGS && ws->sodium0) WT_TRY(wt_sensing_set_sodium(ws, na));
        }
        tt[f] = wt_time_now() - t0;
    }
    out->cpu_tables = (cpu_now() - c0) / reps;
    for (int f = -1; f < reps; f++) {
        if (f == 0) c0 = cpu_now();
        const double t0 = wt_time_now();
        for (int i = 0; i < sys->nsensors; i++) {
            wt_sensing *ws = sys->sensors[i].diffr;
            if (!ws || sys->sensors[i].kind != WT_SENSOR_LGS || !ws->sodium0) continue;
            if (f < 0) WT_TRY(wt_spot_keep_reference(ws->spot));
            WT_TRY(wt_sensing_rebuild_reference(ws));
        }
        if (f < 0) out->full = wt_time_now() - t0;
        else tr[f] = wt_time_now() - t0;
    }
    out->cpu_reference = (cpu_now() - c0) / reps;
    out->tables = wt_bench_summarise(tt, reps);
    out->reference = wt_bench_summarise(tr, reps);
    /* the pixels' reference: frames of the set-up reference images with slopes of a fraction of a pixel */
    {
        double *ta = NULL, *tp = NULL, *sl = NULL;
        int64_t nmax = 0;
        for (int i = 0; i < sys->nsensors; i++)
            if (sys->sensors[i].diffr && sys->sensors[i].kind == WT_SENSOR_LGS && sys->sensors[i].diffr->nsub > nmax)
                nmax = sys->sensors[i].diffr->nsub;
        WT_ALLOC(ctx, ta, reps, "bench timings");
        WT_ALLOC(ctx, tp, reps, "bench timings");
        WT_ALLOC(ctx, sl, 2 * (size_t)nmax, "bench slopes");
        const double t0 = wt_time_now();
        for (int i = 0; i < sys->nsensors && st >= 0; i++) {
            wt_sensing *ws = sys->sensors[i].diffr;
            if (ws && sys->sensors[i].kind == WT_SENSOR_LGS && ws->sodium0) st = wt_sensing_pixels_start(ws);
        }
        out->pixels_start = wt_time_now() - t0;
        double ca = 0.0, cp = 0.0;
        for (int f = 0; f < reps && st >= 0; f++) {
            for (int rep = 0; rep < 2 && st >= 0; rep++) {
                const double a0 = wt_time_now(), c1 = cpu_now();
                for (int i = 0; i < sys->nsensors; i++) {
                    wt_sensing *ws = sys->sensors[i].diffr;
                    if (!ws || sys->sensors[i].kind != WT_SENSOR_LGS || !ws->sodium0) continue;
                    for (int k = 0; k < 2 * ws->nsub; k++) sl[k] = ws->pixel * (0.3 * ((k * 7 + f + rep) % 11) / 10.0 - 0.15);
                    wt_sensing_pixels_add(ws, ws->i0, sl);
                }
                if (rep == 0) ta[f] = wt_time_now() - a0, ca += cpu_now() - c1;
            }
            const double p0 = wt_time_now(), c1 = cpu_now();
            for (int i = 0; i < sys->nsensors && st >= 0; i++) {
                wt_sensing *ws = sys->sensors[i].diffr;
                if (ws && sys->sensors[i].kind == WT_SENSOR_LGS && ws->sodium0) st = wt_sensing_pixels_reference(ws);
            }
            tp[f] = wt_time_now() - p0, cp += cpu_now() - c1;
        }
        if (st >= 0) {
            out->accumulate = wt_bench_summarise(ta, reps);
            out->pixels = wt_bench_summarise(tp, reps);
            out->cpu_accumulate = ca / reps, out->cpu_pixels = cp / reps;
        }
        wt_free(ctx, ta), wt_free(ctx, tp), wt_free(ctx, sl);
    }
    /* the matched filter's gain from the pixels: frames of the reference images */
    if (st >= 0) {
        double *tg = NULL, cg = 0.0;
        WT_ALLOC(ctx, tg, reps, "bench timings");
        for (int i = 0; i < sys->nsensors && st >= 0; i++) {
            wt_sensing *ws = sys->sensors[i].diffr;
            if (ws && sys->sensors[i].kind == WT_SENSOR_LGS && ws->sodium0 && ws->cpar.method == WT_CENTROID_MF)
                st = wt_sensing_gain_start(ws);
        }
        for (int f = -1; f < reps && st >= 0; f++) {
            double dt = 0.0, c1 = cpu_now();
            for (int i = 0; i < sys->nsensors && st >= 0; i++) {
                wt_sensing *ws = sys->sensors[i].diffr;
                if (!ws || !ws->gain_acc) continue;
                const size_t npix = (size_t)ws->nsub * ws->ns * ws->ns;
                for (size_t q = 0; q < npix; q++) ws->gain_acc[q] = 2.0f * ws->i0[q];
                ws->gain_frames = 2;
                const double g0 = wt_time_now();
                st = wt_sensing_gain_update(ws, NULL, NULL);
                dt += wt_time_now() - g0;
            }
            if (f < 0) out->gain_first = dt;
            else tg[f] = dt, cg += cpu_now() - c1;
        }
        if (st >= 0) out->gain = wt_bench_summarise(tg, reps), out->cpu_gain = cg / reps;
        wt_free(ctx, tg);
    }
fail:
    for (int i = 0; i < sys->nsensors; i++) {
        wt_sensing *ws = sys->sensors[i].diffr;
        if (ws && sys->sensors[i].kind == WT_SENSOR_LGS) {
            const int s2 = wt_sensing_restore(ws);
            if (st >= 0 && s2 < 0) st = s2;
        }
    }
    wt_sodium_free(na);
    wt_free(ctx, tt);
    wt_free(ctx, tr);
    return st;
}
