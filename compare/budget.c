/* compare/budget.c: the error budget (SPEC §11): loop runs that remove one cause each, the
 * tip-tilt and rim split of the closed-loop residual, and the analytic estimates (compare/budget.h). */
#include "budget.h"

#include <complex.h>
#include <errno.h>
#include <stdio.h>
#include <math.h>
#include <string.h>

#include "../core/io/h5.h"
#include "../core/model/profile.h"
#include "../core/model/reconstructor.h"
#include "../core/op/noise.h"
#include "../core/solve/mvm.h"
#include "../sim/loop.h"

const char *const wt_budget_term_names[WT_BUDGET_NTERMS] = {
    "fitting", "tomography", "noise_ol", "noise_cl", "servo", "servo_no_predict", "servo_predicted", "polc", "tiptilt",
    "rim", "interior", "total"};
const char *const wt_budget_term_desc[WT_BUDGET_NTERMS] = {
    "fitting: DMs fitted to the true turbulence over the evaluation directions (no sensors)",
    "tomography + aliasing + model error: open loop on noise-free slopes, minus fitting in quadrature",
    "noise propagation, open loop: open loop with noise minus without, in quadrature",
    "noise propagation, closed loop: closed loop with noise minus without, in quadrature",
    "servo lag: closed loop with exact POLC (the truth sensors' slopes of the DM shapes) minus instantaneous open loop (noise-free), in quadrature; with recon.predict the closed loop predicts (the open loop does not): the lag prediction leaves",
    "servo lag without prediction (recon.predict only): the same exact-POLC closed loop without the wind shift minus the instantaneous open loop, in quadrature",
    "lag removed by prediction (recon.predict only): servo_no_predict minus servo, in quadrature",
    "POLC model error: closed loop with the model's interaction Â minus with exact POLC (noise-free), in quadrature",
    "tip-tilt part of the closed-loop residual (with noise)",
    "closed-loop residual in the outer annulus of the pupil (its part of total^2)",
    "closed-loop residual inside the annulus (rim^2 + interior^2 = total^2)",
    "total: closed loop with noise (as `wavetomo sim`)"};
const char *const wt_budget_run_names[WT_BUDGET_NRUNS] = {"fitting",          "open_loop_noise_free",
                                                          "open_loop",        "closed_loop_noise_free",
                                                          "closed_loop",      "noise_only",
                                                          "closed_loop_noise_free_exact_polc",
                                                          "closed_loop_noise_free_exact_polc_no_predict"};

void wt_budget_options_default(wt_budget_options *o, uint64_t seed)
{
    memset(o, 0, sizeof *o);
    o->seed = seed;
    o->fit_iterations = 50;
    o->noise_draws = 8;
    o->warmup = 10;
    o->rim_width = 1.0;
}

/* ---------------------------------------------------------------- analytic estimates */

static double r0_at(const wt_config *cfg) { return cfg->r0 * pow(cfg->eval_wavelength / 500e-9, 1.2); }
static double rad2_to_nm(const wt_config *cfg, double rad2) { return sqrt(rad2) * cfg->eval_wavelength / (2.0 * M_PI) * 1e9; }

/* the DM nearest in altitude to h (the one that corrects a layer there; the first of two equally near) */
static int nearest_dm(const wt_config *cfg, double h)
{
    int k = 0;
    for (int q = 1; q < cfg->ndms; q++)
        if (fabs(cfg->dm_altitude[q] - h) < fabs(cfg->dm_altitude[k] - h)) k = q;
    return k;
}

double wt_budget_fitting_analytic(const wt_config *cfg, double kappa, int ground_only)
{
    const double r0 = r0_at(cfg);
    if (ground_only) return rad2_to_nm(cfg, kappa * pow(cfg->dm_pitch[0] / r0, 5.0 / 3.0));
    double s = 0.0;
    for (int l = 0; l < cfg->nlayers; l++) {
        const int k = nearest_dm(cfg, cfg->layer_altitude[l]); /* the DM nearest in altitude corrects the layer */
        s += cfg->layer_fraction[l] * pow(cfg->dm_pitch[k] / r0, 5.0 / 3.0);
    }
    return rad2_to_nm(cfg, kappa * s);
}

double wt_budget_greenwood(const wt_config *cfg)
{
    double s = 0.0;
    for (int l = 0; l < cfg->nlayers; l++) s += cfg->layer_fraction[l] * pow(fabs(cfg->wind_speed[l]), 5.0 / 3.0);
    return 0.427 * pow(s, 0.6) / r0_at(cfg);
}

/* |E(f)| of a_{t+d} = a_{t+d−1} + g (φ_t − a_t): E = 1 / (1 + g z^−d / (1 − z^−1)) */
static double rejection(double gain, double rate, int delay, double f)
{
    double complex zi = cexp(-2.0 * M_PI * I * f / rate);
    return cabs(1.0 / (1.0 + gain * cpow(zi, delay) / (1.0 - zi)));
}

double wt_budget_f3db(double gain, double rate, int delay)
{
    const double target = M_SQRT1_2;
    double lo = 1e-6 * rate, hi = lo;
    /* first crossing from below: |E| → 0 at f → 0 */
    while (hi < 0.5 * rate && rejection(gain, rate, delay, hi) < target) lo = hi, hi *= 1.05;
    if (hi >= 0.5 * rate) return 0.5 * rate;
    for (int it = 0; it < 60; it++) {
        double mid = 0.5 * (lo + hi);
        if (rejection(gain, rate, delay, mid) < target) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

double wt_budget_servo_analytic(const wt_config *cfg)
{
    double r = wt_budget_greenwood(cfg) / wt_budget_f3db(cfg->gain, cfg->rate, cfg->delay);
    return rad2_to_nm(cfg, pow(r, 5.0 / 3.0));
}

double wt_budget_servo_band_limited(const wt_config *cfg)
{
    enum { N = 400 }; /* midpoint rule; the integrand ~ κ^(−5/3) near 0 (|E|² ~ κ²) is integrable */
    const double r0 = r0_at(cfg), a = 0.0229 * pow(r0, -5.0 / 3.0), k0 = 1.0 / (cfg->L0 * cfg->L0);
    double s = 0.0;
    for (int l = 0; l < cfg->nlayers; l++) {
        const int k = nearest_dm(cfg, cfg->layer_altitude[l]);
        const double kc = 0.5 / cfg->dm_pitch[k], h = 2.0 * kc / N;
        const double vx = cfg->wind_speed[l] * cos(cfg->wind_direction[l]), vy = cfg->wind_speed[l] * sin(cfg->wind_direction[l]);
        double sl = 0.0;
        for (int iy = 0; iy < N; iy++)
            for (int ix = 0; ix < N; ix++) {
                double kx = -kc + (ix + 0.5) * h, ky = -kc + (iy + 0.5) * h, f = fabs(kx * vx + ky * vy);
                double e = f > 0.0 ? rejection(cfg->gain, cfg->rate, cfg->delay, fmin(f, 0.5 * cfg->rate)) : 0.0;
                sl += pow(kx * kx + ky * ky + k0, -11.0 / 6.0) * e * e;
            }
        s += cfg->layer_fraction[l] * a * sl * h * h;
    }
    return rad2_to_nm(cfg, s);
}

double wt_budget_servo_band_predicted(const wt_config *cfg, const wt_recon_variant_config *var)
{
    enum { N = 400 }; /* as wt_budget_servo_band_limited */
    const int n = cfg->nlayers, L = var ? var->nlayers : 0;
    const double r0 = r0_at(cfg), a = 0.0229 * pow(r0, -5.0 / 3.0), k0 = 1.0 / (cfg->L0 * cfg->L0), g = cfg->gain;
    const double tau = (cfg->predict_lead_frames > 0.0 ? cfg->predict_lead_frames : (double)cfg->delay) / cfg->rate;
    const int layers = cfg->predict_integrator == 1; /* the integrator on the layers (reconstructor.h) */
    double vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS], rf[WT_MAX_LAYERS], rvx[WT_MAX_LAYERS], rvy[WT_MAX_LAYERS];
    for (int l = 0; l < n; l++)
        vx[l] = cfg->wind_speed[l] * cos(cfg->wind_direction[l]), vy[l] = cfg->wind_speed[l] * sin(cfg->wind_direction[l]);
    if (var) wt_profile_compress(n, cfg->layer_altitude, cfg->layer_fraction, vx, vy, L, var->altitudes, rf, rvx, rvy);
    double s = 0.0;
    for (int l = 0; l < n; l++) {
        const int k = nearest_dm(cfg, cfg->layer_altitude[l]);
        /* the reconstruction layers this one is split onto, and their winds: P(κ) = Σ_j w_j exp(2πi κ·v̄_j τ) */
        int j = 0, nj = 1;
        double wj[2] = {1.0, 0.0}, ux[2] = {vx[l], 0.0}, uy[2] = {vy[l], 0.0};
        if (var) {
            double w;
            wt_profile_bin_altitude(L, var->altitudes, cfg->layer_altitude[l], &j, &w);
            wj[0] = 1.0 - w, wj[1] = w, ux[0] = rvx[j], uy[0] = rvy[j], nj = w > 0.0 ? 2 : 1;
            if (nj == 2) ux[1] = rvx[j + 1], uy[1] = rvy[j + 1];
        }
        const double kc = 0.5 / cfg->dm_pitch[k], h = 2.0 * kc / N;
        double sl = 0.0;
        for (int iy = 0; iy < N; iy++)
            for (int ix = 0; ix < N; ix++) {
                const double kx = -kc + (ix + 0.5) * h, ky = -kc + (iy + 0.5) * h;
                const double complex z = cexp(2.0 * M_PI * I * (kx * vx[l] + ky * vy[l]) / cfg->rate);
                const double complex zd = cpow(z, cfg->delay);
                double complex P = 0.0, c = 0.0;
                for (int q = 0; q < nj; q++) {
                    const double complex Pq = cexp(2.0 * M_PI * I * (kx * ux[q] + ky * uy[q]) * tau);
                    P += wj[q] * Pq;
                    if (layers) { /* the state moves by U_q a frame: c_q = g P_q / (z^d − U_q z^(d−1) + g P_q) */
                        const double complex U = cexp(2.0 * M_PI * I * (kx * ux[q] + ky * uy[q]) / cfg->rate);
                        c += wj[q] * g * Pq / (zd - U * zd / z + g * Pq);
                    }
                }
                if (!layers) c = g * P / (zd - zd / z + g);
                const double complex e = 1.0 - c;
                sl += pow(kx * kx + ky * ky + k0, -11.0 / 6.0) * creal(e * conj(e));
            }
        s += cfg->layer_fraction[l] * a * sl * h * h;
    }
    return rad2_to_nm(cfg, s);
}

double wt_budget_noise_gain(double gain, int delay) { return wt_noise_loop_gain(gain, delay); }

/* ---------------------------------------------------------------- measured terms */

/* The evaluation pupil: its points, their centred coordinates, the rim flags and the tip-tilt normal
 * matrix G = Σ [x y]ᵀ [x y]. */
typedef struct {
    int64_t n, *idx;
    double *x, *y;
    uint8_t *rim;
    double gxx, gxy, gyy;
} pupil_geom;

static void geom_free(wt_context *ctx, pupil_geom *g)
{
    wt_free(ctx, g->idx);
    wt_free(ctx, g->x);
    wt_free(ctx, g->y);
    wt_free(ctx, g->rim);
}

static int geom_init(wt_context *ctx, const wt_grid *fine, const uint8_t *mask, double rim_radius, pupil_geom *g)
{
    int st = WT_OK;
    memset(g, 0, sizeof *g);
    const int64_t nf = wt_grid_size(fine);
    for (int64_t k = 0; k < nf; k++) g->n += mask[k] != 0;
    WT_ALLOC(ctx, g->idx, g->n, "pupil points");
    WT_ALLOC(ctx, g->x, g->n, "pupil x");
    WT_ALLOC(ctx, g->y, g->n, "pupil y");
    WT_ALLOC(ctx, g->rim, g->n, "rim flags");
    double mx = 0.0, my = 0.0;
    int64_t p = 0;
    for (int64_t k = 0; k < nf; k++) {
        if (!mask[k]) continue;
        double x = fine->x0 + (double)(k % fine->nx) * fine->dx, y = fine->y0 + (double)(k / fine->nx) * fine->dx;
        g->idx[p] = k, g->x[p] = x, g->y[p] = y;
        g->rim[p] = hypot(x, y) > rim_radius;
        mx += x, my += y, p++;
    }
    mx /= (double)g->n, my /= (double)g->n;
    for (int64_t i = 0; i < g->n; i++) {
        g->x[i] -= mx, g->y[i] -= my;
        g->gxx += g->x[i] * g->x[i], g->gxy += g->x[i] * g->y[i], g->gyy += g->y[i] * g->y[i];
    }
    return WT_OK;
fail:
    geom_free(ctx, g);
    return st;
}

/* Sums over the directions of one frame: piston-removed σ² of the rim points and of the tip-tilt plane,
 * each as Σ/N per direction. The directions are computed in parallel and summed in index order, so
 * the sums do not depend on which thread took which direction (an OpenMP reduction with a dynamic
 * schedule did: test_budget's "same seed, same numbers" failed about one run in two on a loaded host). */
static void frame_stats(wt_context *ctx, const wt_loop *lp, int neval, const pupil_geom *g, double *rim, double *tt)
{
    double rj[WT_MAX_EVAL], qj[WT_MAX_EVAL];
#pragma omp parallel for schedule(dynamic, 1) num_threads(wt_context_threads(ctx))
    for (int j = 0; j < neval; j++) {
        const double *o = wt_loop_residual(lp, j);
        double m = 0.0, r = 0.0, bx = 0.0, by = 0.0;
        for (int64_t i = 0; i < g->n; i++) m += o[g->idx[i]];
        m /= (double)g->n;
        for (int64_t i = 0; i < g->n; i++) {
            double e = o[g->idx[i]] - m;
            if (g->rim[i]) r += e * e;
            bx += e * g->x[i], by += e * g->y[i];
        }
        /* least-squares plane c = G⁻¹ b; its variance cᵀ G c / N = bᵀ G⁻¹ b / N */
        double det = g->gxx * g->gyy - g->gxy * g->gxy;
        double q = (g->gyy * bx * bx - 2.0 * g->gxy * bx * by + g->gxx * by * by) / det;
        rj[j] = r / (double)g->n;
        qj[j] = q / (double)g->n;
    }
    double srim = 0.0, stt = 0.0;
    for (int j = 0; j < neval; j++) srim += rj[j], stt += qj[j];
    *rim += srim;
    *tt += stt;
}

typedef struct {
    const wt_budget_options *opt;
    int run, nruns;
} progress_state;

/* One loop run from frame `first` to `last` (exclusive); the statistics of frames ≥ settle. */
static int run_loop(wt_context *ctx, const wt_system *sys, const wt_loop_options *lo, long first, long last,
                    const char *label, progress_state *ps, wt_budget_run *out)
{
    const wt_config *cfg = sys->cfg;
    wt_loop *lp = NULL;
    pupil_geom g;
    int st = wt_loop_alloc(ctx, sys, lo, &lp);
    if (st < 0) return st;
    double t0 = wt_time_now();
    if ((st = geom_init(ctx, wt_loop_fine_grid(lp), wt_loop_pupil_mask(lp), 0.5 * cfg->diameter - ps->opt->rim_width,
                        &g)) < 0) {
        wt_loop_free(lp);
        return st;
    }
    double rim = 0.0, tt = 0.0;
    long n = 0;
    for (long t = first; t < last; t++) {
        if ((st = wt_loop_step(lp)) < 0) break;
        if (t >= cfg->settle_frames) {
            frame_stats(ctx, lp, sys->neval, &g, &rim, &tt);
            n++;
        }
        if (ps->opt->progress && t + 1 < last)
            ps->opt->progress(ps->opt->user, ps->run, ps->nruns, label, t - first + 1, last - first, NAN);
    }
    if (st >= 0) {
        const wt_strehl_le *le = wt_loop_le(lp);
        double v = 0.0;
        for (int j = 0; j < sys->neval; j++) v += pow(wt_strehl_le_wfe(le, j), 2) / sys->neval;
        const double f = n > 0 ? 1.0 / ((double)n * sys->neval) : 0.0;
        out->wfe = sqrt(v);
        out->rim = sqrt(rim * f);
        out->tiptilt = sqrt(tt * f);
        out->frames = n;
        int64_t nr = 0;
        for (int64_t i = 0; i < g.n; i++) nr += g.rim[i];
        out->rim_area = (double)nr / (double)g.n;
        out->seconds = wt_time_now() - t0;
        if (ps->opt->progress) ps->opt->progress(ps->opt->user, ps->run, ps->nruns, label, last - first, last - first, out->wfe * 1e9);
    }
    ps->run++;
    geom_free(ctx, &g);
    wt_loop_free(lp);
    return st;
}

/* The exact-POLC run needs geometric truth sensors (sim/loop.h true_polc). */
static int exact_polc(const wt_system *sys)
{
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].diffr) return 0;
    return 1;
}

int wt_budget_nruns(const wt_system *sys, int nmethods)
{
    return 1 + nmethods * ((sys->cfg->noise ? 5 : 2) + exact_polc(sys) * (sys->cfg->predict ? 2 : 1));
}

static double signed_square(double x) { return x * fabs(x); }
static double signed_root(double x) { return copysign(sqrt(fabs(x)), x); }

/* sign(a − b) √|a² − b²| of two rms values [m] → nm */
static double quad_diff(double a, double b) { return signed_root(a * a - b * b) * 1e9; }

/* the part of a signed quadrature term a [nm] that is not its signed part b: a² − b², signed */
static double quad_rest(double a, double b) { return signed_root(signed_square(a) - signed_square(b)); }

int wt_budget_compute(wt_context *ctx, const wt_system *sys, const wt_budget_options *opt, int nmethods,
                      const int *recon, const struct wt_mvm *const *mvm, const struct wt_mvm *const *mvm_plain,
                      wt_budget_result *res)
{
    const wt_config *cfg = sys->cfg;
    int st = WT_OK;
    if (opt->fit_iterations < 1 || opt->noise_draws < 1 || opt->warmup < 0 || !(opt->rim_width > 0.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "budget options: fit iterations %d, noise draws %d, warm-up %d, rim %g m",
                        opt->fit_iterations, opt->noise_draws, opt->warmup, opt->rim_width);
    const long frames = cfg->frames, settle = cfg->settle_frames;
    const long first = settle > opt->warmup ? settle - opt->warmup : 0;
    progress_state ps = {opt, 0, wt_budget_nruns(sys, nmethods)};
    char label[128];

    wt_budget_run fit;
    wt_loop_options fo = {.recon = WT_RECON_NONE, .iterations = -1, .seed = opt->seed, .open_loop = 1,
                          .perfect_fit = opt->fit_iterations, .first_frame = first};
    if ((st = run_loop(ctx, sys, &fo, first, frames, "fitting (true turbulence)", &ps, &fit)) < 0) return st;

    int olmode = opt->open_loop;
    if (olmode != 0 && olmode != WT_LOOP_OPEN_FLAT && olmode != WT_LOOP_OPEN_POLC)
        return WT_ERROR(ctx, WT_ERR_INVALID, "budget options: open_loop = %d: must be 0 (automatic), WT_LOOP_OPEN_FLAT or "
                        "WT_LOOP_OPEN_POLC", olmode);
    if (!olmode) {
        olmode = WT_LOOP_OPEN_FLAT;
        for (int i = 0; i < sys->nsensors; i++)
            if (sys->sensors[i].diffr) olmode = WT_LOOP_OPEN_POLC;
    }
    const double gain_n = wt_budget_noise_gain(cfg->gain, cfg->delay), servo_band = wt_budget_servo_band_limited(cfg);
    /* with prediction, the lag each atmospheric layer's own wind leaves: the same for every method */
    const double servo_own = cfg->predict ? wt_budget_servo_band_predicted(cfg, NULL) : NAN;
    for (int m = 0; m < nmethods; m++) {
        wt_budget_result *r = &res[m];
        memset(r, 0, sizeof *r);
        r->recon = recon[m];
        r->open_loop = olmode;
        r->run[WT_BUDGET_RUN_FIT] = fit;
        const char *name = wt_reconstructor_name(recon[m]);
        wt_loop_options base = {.recon = recon[m], .mvm = mvm ? mvm[m] : NULL, .iterations = -1, .seed = opt->seed};
        struct { int run, open, noise, turb, polc, no_predict; const char *what; } plan[] = {
            {WT_BUDGET_RUN_OL_NF, 1, 0, 1, 0, 1, "open loop, noise-free"},
            {WT_BUDGET_RUN_OL, 1, 1, 1, 0, 1, "open loop, noise"},
            {WT_BUDGET_RUN_NOISE, 1, 1, 0, 0, 1, "pure noise"},
            {WT_BUDGET_RUN_CL_NF, 0, 0, 1, 0, 0, "closed loop, noise-free"},
            {WT_BUDGET_RUN_CL_NF_POLC, 0, 0, 1, 1, 0, "closed loop, noise-free, exact POLC"},
            {WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT, 0, 0, 1, 1, 1, "closed loop, noise-free, exact POLC, no prediction"},
            {WT_BUDGET_RUN_CL, 0, 1, 1, 0, 0, "closed loop, noise"}};
        for (size_t k = 0; k < sizeof plan / sizeof plan[0]; k++) {
            if (plan[k].noise && !cfg->noise) continue; /* filled from the noise-free runs below */
            if (plan[k].polc && !exact_polc(sys)) continue;
            if (plan[k].run == WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT && !cfg->predict) continue;
            wt_loop_options lo = base;
            /* the instantaneous runs apply the frame's own reconstruction: nothing to predict (a shift there
             * would be an error of its own); the closed loops predict as configured, one exact-POLC run not */
            lo.no_predict = plan[k].no_predict;
            if (lo.no_predict && cfg->predict && recon[m] == WT_RECON_MVM) { /* the matrix without the predictor */
                if (!mvm_plain || !mvm_plain[m])
                    return WT_ERROR(ctx, WT_ERR_INVALID, "budget: %s with recon.predict needs its control matrix without "
                                    "the predictor for the runs that do not predict", name);
                lo.mvm = mvm_plain[m];
            }
            /* the pure-noise run keeps the flat open loop: without turbulence the sensors see a flat
             * wavefront either way. The pseudo-open loop carries its state from frame 0. */
            const int pseudo = plan[k].open && plan[k].turb && olmode == WT_LOOP_OPEN_POLC;
            lo.open_loop = !plan[k].open ? WT_LOOP_CLOSED : pseudo ? WT_LOOP_OPEN_POLC : WT_LOOP_OPEN_FLAT;
            lo.noise = plan[k].noise;
            lo.no_turbulence = !plan[k].turb;
            lo.true_polc = plan[k].polc;
            lo.first_frame = plan[k].open && !pseudo ? (plan[k].turb ? first : settle) : 0;
            long last = plan[k].turb ? frames : settle + opt->noise_draws;
            snprintf(label, sizeof label, "%s: %s", name, plan[k].what);
            if ((st = run_loop(ctx, sys, &lo, lo.first_frame, last, label, &ps, &r->run[plan[k].run])) < 0) return st;
        }
        if (!cfg->noise) {
            r->run[WT_BUDGET_RUN_OL] = r->run[WT_BUDGET_RUN_OL_NF];
            r->run[WT_BUDGET_RUN_CL] = r->run[WT_BUDGET_RUN_CL_NF];
        }
        const wt_budget_run *R = r->run;
        r->term[WT_BUDGET_FITTING] = R[WT_BUDGET_RUN_FIT].wfe * 1e9;
        r->term[WT_BUDGET_TOMOGRAPHY] = quad_diff(R[WT_BUDGET_RUN_OL_NF].wfe, R[WT_BUDGET_RUN_FIT].wfe);
        r->term[WT_BUDGET_NOISE_OL] = quad_diff(R[WT_BUDGET_RUN_OL].wfe, R[WT_BUDGET_RUN_OL_NF].wfe);
        r->term[WT_BUDGET_NOISE_CL] = quad_diff(R[WT_BUDGET_RUN_CL].wfe, R[WT_BUDGET_RUN_CL_NF].wfe);
        r->term[WT_BUDGET_SERVO_NO_PREDICT] = r->term[WT_BUDGET_SERVO_PREDICTED] = NAN;
        r->servo_tiptilt_no_predict = NAN;
        if (exact_polc(sys)) {
            r->term[WT_BUDGET_SERVO] = quad_diff(R[WT_BUDGET_RUN_CL_NF_POLC].wfe, R[WT_BUDGET_RUN_OL_NF].wfe);
            r->servo_tiptilt = quad_diff(R[WT_BUDGET_RUN_CL_NF_POLC].tiptilt, R[WT_BUDGET_RUN_OL_NF].tiptilt);
            if (cfg->predict) {
                r->servo_tiptilt_no_predict = quad_diff(R[WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT].tiptilt,
                                                        R[WT_BUDGET_RUN_OL_NF].tiptilt);
                r->term[WT_BUDGET_SERVO_NO_PREDICT] = quad_diff(R[WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT].wfe,
                                                                R[WT_BUDGET_RUN_OL_NF].wfe);
                r->term[WT_BUDGET_SERVO_PREDICTED] = quad_diff(R[WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT].wfe,
                                                               R[WT_BUDGET_RUN_CL_NF_POLC].wfe);
            }
            r->term[WT_BUDGET_POLC] = quad_diff(R[WT_BUDGET_RUN_CL_NF].wfe, R[WT_BUDGET_RUN_CL_NF_POLC].wfe);
        } else {
            r->term[WT_BUDGET_SERVO] = quad_diff(R[WT_BUDGET_RUN_CL_NF].wfe, R[WT_BUDGET_RUN_OL_NF].wfe);
            r->servo_tiptilt = quad_diff(R[WT_BUDGET_RUN_CL_NF].tiptilt, R[WT_BUDGET_RUN_OL_NF].tiptilt);
            r->term[WT_BUDGET_POLC] = NAN;
        }
        r->term[WT_BUDGET_TIPTILT] = R[WT_BUDGET_RUN_CL].tiptilt * 1e9;
        r->term[WT_BUDGET_RIM] = R[WT_BUDGET_RUN_CL].rim * 1e9;
        r->term[WT_BUDGET_INTERIOR] = quad_diff(R[WT_BUDGET_RUN_CL].wfe, R[WT_BUDGET_RUN_CL].rim);
        r->term[WT_BUDGET_TOTAL] = R[WT_BUDGET_RUN_CL].wfe * 1e9;
        for (int k = 0; k < WT_BUDGET_NTERMS; k++) r->analytic[k] = NAN;
        r->analytic[WT_BUDGET_FITTING] = wt_budget_fitting_analytic(cfg, 0.23, 0);
        r->analytic_hi[WT_BUDGET_FITTING] = wt_budget_fitting_analytic(cfg, 0.28, 0);
        r->analytic[WT_BUDGET_NOISE_OL] = R[WT_BUDGET_RUN_NOISE].wfe * 1e9;
        r->analytic[WT_BUDGET_NOISE_CL] = r->analytic[WT_BUDGET_NOISE_OL] * sqrt(gain_n);
        r->analytic[WT_BUDGET_SERVO] = wt_budget_servo_analytic(cfg);
        for (int k = 0; k < WT_BUDGET_NTERMS; k++)
            if (k != WT_BUDGET_FITTING) r->analytic_hi[k] = r->analytic[k];
        r->fitting_ground = wt_budget_fitting_analytic(cfg, 0.23, 1);
        r->servo_band = servo_band;
        r->servo_band_predicted = r->servo_band_own_winds = NAN;
        if (cfg->predict && recon[m] != WT_RECON_NONE) { /* (an MVM's layers are its variant's) */
            const int cg9 = recon[m] == WT_RECON_CG9 ||
                            (recon[m] == WT_RECON_MVM && mvm && mvm[m] && mvm[m]->commands == WT_MVM_FITTING);
            r->servo_band_predicted = wt_budget_servo_band_predicted(cfg, cg9 ? &cfg->cg9 : &cfg->pcg3);
            r->servo_band_own_winds = servo_own;
        }
        double s2 = signed_square(r->term[WT_BUDGET_FITTING]) + signed_square(r->term[WT_BUDGET_TOMOGRAPHY]) +
                    signed_square(r->term[WT_BUDGET_SERVO]) + (isfinite(r->term[WT_BUDGET_POLC]) ? signed_square(r->term[WT_BUDGET_POLC]) : 0.0) +
                    signed_square(r->term[WT_BUDGET_NOISE_OL]) * gain_n;
        r->sum = signed_root(s2);
        r->closure = r->term[WT_BUDGET_TOTAL] > 0.0 ? r->sum / r->term[WT_BUDGET_TOTAL] - 1.0 : 0.0;
    }
    return WT_OK;
}

/* ---------------------------------------------------------------- report */

int wt_budget_term_used(const wt_config *cfg, int k)
{
    return (k != WT_BUDGET_SERVO_NO_PREDICT && k != WT_BUDGET_SERVO_PREDICTED) || cfg->predict;
}

static void cell(FILE *f, double v) { isfinite(v) ? fprintf(f, " %.1f |", v) : fprintf(f, " – |"); }

int wt_budget_write_report(wt_context *ctx, const char *path, const wt_config *cfg, int nmethods,
                           const char *const *methods, const wt_budget_result *res, int argc, char **argv)
{
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f) return WT_ERROR(ctx, WT_ERR_IO, "cannot write '%s': %s", tmp, strerror(errno));
    fprintf(f, "# wavetomo error budget\n\nSystem `%s`, %d frames at %.0f Hz (%d settle), gain %g, delay %d, seed %llu, "
               "σ² averaged over the %d² evaluation directions at %.0f nm (piston removed).\n\nCommand:\n\n```\nwavetomo",
            cfg->path, cfg->frames, cfg->rate, cfg->settle_frames, cfg->gain, cfg->delay, (unsigned long long)cfg->seed,
            cfg->eval_grid, cfg->eval_wavelength * 1e9);
    for (int i = 0; i < argc; i++) fprintf(f, " %s", argv[i]);
    fprintf(f, "\n```\n\n");
    if (nmethods > 0 && res[0].open_loop == WT_LOOP_OPEN_POLC)
        fprintf(f, "Instantaneous runs: **pseudo-open loop** (the sensors see the turbulence minus the previous frame's "
                   "reconstruction, R (s + Â a) is applied to the same frame; the diffractive sensors stay in their "
                   "linear range, where a flat open loop would move the spots by the full turbulence).\n\n");
    else
        fprintf(f, "Instantaneous runs: **flat open loop** (the sensors see the turbulence with the DMs flat).\n\n");
    fprintf(f, "| term [nm] |");
    for (int m = 0; m < nmethods; m++) fprintf(f, " %s measured | %s analytic |", methods[m], methods[m]);
    fprintf(f, "\n|---|");
    for (int m = 0; m < nmethods; m++) fprintf(f, "---|---|");
    fprintf(f, "\n");
    for (int k = 0; k < WT_BUDGET_NTERMS; k++) {
        if (!wt_budget_term_used(cfg, k)) continue;
        fprintf(f, "| %s |", wt_budget_term_names[k]);
        for (int m = 0; m < nmethods; m++) {
            cell(f, res[m].term[k]);
            if (isfinite(res[m].analytic[k]) && res[m].analytic_hi[k] != res[m].analytic[k])
                fprintf(f, " %.1f–%.1f |", res[m].analytic[k], res[m].analytic_hi[k]);
            else
                cell(f, res[m].analytic[k]);
        }
        fprintf(f, "\n");
    }
    fprintf(f, "| quadrature sum |");
    for (int m = 0; m < nmethods; m++) fprintf(f, " %.1f | (%+.1f %% of total) |", res[m].sum, 100.0 * res[m].closure);
    fprintf(f, "\n\nTerms:\n\n");
    for (int k = 0; k < WT_BUDGET_NTERMS; k++)
        if (wt_budget_term_used(cfg, k)) fprintf(f, "- **%s**: %s.\n", wt_budget_term_names[k], wt_budget_term_desc[k]);
    const double gn = wt_budget_noise_gain(cfg->gain, cfg->delay);
    fprintf(f, "\nA negative quadrature difference means the removed cause helped (the run without it is worse).\n\n"
               "**Closure**: fitting² + tomography² + servo² + polc² + noise_OL² × Σh² (the integrator's noise gain, %.3f here; "
               "g/(2−g) = %.3f would hold for delay 1) against total², tolerance ±%.0f %% in nm:\n\n",
            gn, cfg->gain / (2.0 - cfg->gain), 100.0 * WT_BUDGET_CLOSURE_TOL);
    for (int m = 0; m < nmethods; m++) {
        const wt_budget_result *r = &res[m];
        int ok = fabs(r->closure) <= WT_BUDGET_CLOSURE_TOL;
        fprintf(f, "- %s: %.1f nm vs total %.1f nm (%+.1f %%): %s", methods[m], r->sum, r->term[WT_BUDGET_TOTAL],
                100.0 * r->closure, ok ? "closes" : "does **not** close");
        double ncl = r->analytic[WT_BUDGET_NOISE_CL], nm_ = r->term[WT_BUDGET_NOISE_CL];
        fprintf(f, "; closed-loop noise measured %.1f nm vs open-loop noise × √Σh² = %.1f nm", nm_,
                r->term[WT_BUDGET_NOISE_OL] * sqrt(gn));
        (void)ncl;
        if (!ok && r->term[WT_BUDGET_SERVO] < 0.0)
            fprintf(f, "; the servo term is negative: the integrator averages the open loop's frame-to-frame "
                       "reconstruction error, which the instantaneous run keeps in full");
        fprintf(f, ".\n");
    }
    const wt_budget_result *r0 = &res[0];
    fprintf(f, "\nAnalytic inputs: r0 = %.3f m at %.0f nm; fitting κ Σ_ℓ f_ℓ (p/r0)^(5/3) with each layer on the DM "
               "nearest in altitude, κ 0.23–0.28 (ground DM alone, κ 0.23: %.1f nm) — a single-direction estimate "
               "that leaves out the field's generalised fitting; servo: Greenwood (f_G/f_3dB)^(5/3) with f_G = %.2f Hz, "
               "integrator f_3dB = %.2f Hz (g %g, %g Hz, delay %d), and band-limited to the DMs' corrected "
               "frequencies %.1f nm (Greenwood counts the lag of all spatial frequencies); noise: the DM shape of %ld pure-noise reconstructions (%s).\n\n",
            cfg->r0 * pow(cfg->eval_wavelength / 500e-9, 1.2), cfg->eval_wavelength * 1e9, r0->fitting_ground,
            wt_budget_greenwood(cfg), wt_budget_f3db(cfg->gain, cfg->rate, cfg->delay), cfg->gain, cfg->rate,
            cfg->delay, r0->servo_band, r0->run[WT_BUDGET_RUN_NOISE].frames, cfg->noise ? "per method" : "noise off: none");
    for (int m = 0; m < nmethods; m++)
        if (isfinite(res[m].servo_band_predicted))
            fprintf(f, "With recon.predict (the integrator on the %s), %s: the band-limited lag (the same analytic form) with "
                       "each of its layers moved by the Cn²-weighted wind of the truth's layers it holds is %.1f nm, were each "
                       "atmospheric layer moved by its own wind %.1f nm: the compression's part, which no shift of the "
                       "reconstruction layers removes, %.1f nm in quadrature (of the %.1f nm without prediction).\n\n",
                    cfg->predict_integrator == 1 ? "layers" : "commands", methods[m], res[m].servo_band_predicted, res[m].servo_band_own_winds,
                    sqrt(fmax(res[m].servo_band_predicted * res[m].servo_band_predicted -
                              res[m].servo_band_own_winds * res[m].servo_band_own_winds, 0.0)), r0->servo_band);
    for (int m = 0; m < nmethods; m++) { /* the lag of the NGS-measured modes apart from the rest */
        const wt_budget_result *r = &res[m];
        const double s = r->term[WT_BUDGET_SERVO], tt = r->servo_tiptilt;
        fprintf(f, "%s: the servo term's tip-tilt part (the same runs' tip-tilt in quadrature) %.1f nm, the rest %.1f nm",
                methods[m], tt, quad_rest(s, tt));
        if (isfinite(r->servo_tiptilt_no_predict)) {
            const double n = r->term[WT_BUDGET_SERVO_NO_PREDICT], tn = r->servo_tiptilt_no_predict;
            fprintf(f, "; without prediction %.1f and %.1f nm", tn, quad_rest(n, tn));
        }
        fprintf(f, ".\n\n");
    }
    fprintf(f, "Runs (field WFE / tip-tilt / rim part, nm; frames averaged):\n\n| run |");
    for (int m = 0; m < nmethods; m++) fprintf(f, " %s |", methods[m]);
    fprintf(f, "\n|---|");
    for (int m = 0; m < nmethods; m++) fprintf(f, "---|");
    fprintf(f, "\n");
    for (int k = 0; k < WT_BUDGET_NRUNS; k++) {
        if (k == WT_BUDGET_RUN_CL_NF_POLC && !isfinite(r0->term[WT_BUDGET_POLC])) continue; /* not run */
        if (k == WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT && !isfinite(r0->term[WT_BUDGET_SERVO_NO_PREDICT])) continue;
        fprintf(f, "| %s |", wt_budget_run_names[k]);
        for (int m = 0; m < nmethods; m++) {
            const wt_budget_run *u = &res[m].run[k];
            fprintf(f, " %.1f / %.1f / %.1f (%ld) |", u->wfe * 1e9, u->tiptilt * 1e9, u->rim * 1e9, u->frames);
        }
        fprintf(f, "\n");
    }
    const wt_budget_run *cl = &r0->run[WT_BUDGET_RUN_CL];
    fprintf(f, "\nRim: the outer annulus holds %.1f %% of the pupil's points and %.1f %% of the closed loop's residual "
               "variance (%s).\n\n![error budget](budget.png)\n",
            100.0 * cl->rim_area, cl->wfe > 0 ? 100.0 * pow(cl->rim / cl->wfe, 2) : 0.0, methods[0]);
    if (fclose(f) != 0 || rename(tmp, path) != 0) return WT_ERROR(ctx, WT_ERR_IO, "cannot write '%s'", path);
    return WT_OK;
}

int wt_budget_write_h5(struct wt_h5_writer *w, int nmethods, const char *const *methods, const wt_budget_result *res)
{
    char name[256], desc[512], list[512] = "";
    int st = WT_OK;
    for (int m = 0; m < nmethods; m++) snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", m ? "," : "", methods[m]);
    st = wt_h5_attr_write_string(w, "/", "methods", list);
    if (st >= 0 && nmethods > 0)
        st = wt_h5_attr_write_string(w, "/", "open_loop", res[0].open_loop == WT_LOOP_OPEN_POLC ? "polc" : "flat");
    for (int m = 0; m < nmethods && st >= 0; m++) {
        const wt_budget_result *r = &res[m];
        for (int k = 0; k < WT_BUDGET_NTERMS && st >= 0; k++) {
            if ((k == WT_BUDGET_SERVO_NO_PREDICT || k == WT_BUDGET_SERVO_PREDICTED) && !isfinite(r->term[k])) continue;
            snprintf(name, sizeof name, "%s/%s", methods[m], wt_budget_term_names[k]);
            st = wt_h5_write_double(w, name, r->term[k], "nm", wt_budget_term_desc[k]);
            if (st >= 0 && isfinite(r->analytic[k])) st = wt_h5_attr_write_double(w, name, "analytic_nm", r->analytic[k]);
            if (st >= 0 && isfinite(r->analytic[k]) && r->analytic_hi[k] != r->analytic[k])
                st = wt_h5_attr_write_double(w, name, "analytic_hi_nm", r->analytic_hi[k]);
        }
        snprintf(name, sizeof name, "%s/servo", methods[m]);
        if (st >= 0) st = wt_h5_attr_write_double(w, name, "analytic_band_limited_nm", r->servo_band);
        if (st >= 0 && isfinite(r->servo_band_predicted))
            st = wt_h5_attr_write_double(w, name, "analytic_band_limited_predicted_nm", r->servo_band_predicted);
        if (st >= 0 && isfinite(r->servo_band_own_winds))
            st = wt_h5_attr_write_double(w, name, "analytic_band_limited_own_winds_nm", r->servo_band_own_winds);
        if (st >= 0) st = wt_h5_attr_write_double(w, name, "tiptilt_part_nm", r->servo_tiptilt);
        snprintf(name, sizeof name, "%s/servo_no_predict", methods[m]);
        if (st >= 0 && isfinite(r->servo_tiptilt_no_predict))
            st = wt_h5_attr_write_double(w, name, "tiptilt_part_nm", r->servo_tiptilt_no_predict);
        for (int k = 0; k < WT_BUDGET_NRUNS && st >= 0; k++) {
            const wt_budget_run *u = &r->run[k];
            if (k == WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT && !isfinite(r->term[WT_BUDGET_SERVO_NO_PREDICT])) continue;
            snprintf(name, sizeof name, "%s/runs/%s", methods[m], wt_budget_run_names[k]);
            snprintf(desc, sizeof desc, "field WFE of the run '%s' (attributes: its tip-tilt and rim parts [nm], frames, s)",
                     wt_budget_run_names[k]);
            st = wt_h5_write_double(w, name, u->wfe * 1e9, "nm", desc);
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "tiptilt_nm", u->tiptilt * 1e9);
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "rim_nm", u->rim * 1e9);
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "rim_area_fraction", u->rim_area);
            if (st >= 0) st = wt_h5_attr_write_int64(w, name, "frames", u->frames);
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "seconds", u->seconds);
        }
        snprintf(name, sizeof name, "%s/closure", methods[m]);
        if (st >= 0) st = wt_h5_write_double(w, name, r->closure, "", "quadrature sum of the terms / total - 1 (compare/budget.h)");
        snprintf(name, sizeof name, "%s/fitting_analytic_ground", methods[m]);
        if (st >= 0)
            st = wt_h5_write_double(w, name, r->fitting_ground, "nm", "kappa (p0/r0)^(5/3), the ground DM alone, kappa 0.23");
    }
    return st;
}
