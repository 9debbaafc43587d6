/* compare/report_learned.c: the learned atmosphere in the compare report (SPEC §12 "Updates"; cli/plot_series.c
 * draws it): for each sweep value, every learning method's estimates of r0 and of the isoplanatic angle over the
 * run, against the truth's, and a table of their errors.
 *
 *   θ0 = 0.314 r0 / h̄,   h̄ = (Σ_k f_k h_k^{5/3})^{3/5}      (Fried's isoplanatic angle at 500 nm)
 *
 * over the estimate's altitudes (the learning grid's, with its fractions f_k) or the truth's layers (their
 * fractions at that night time), both as configured (no zenith scaling on either side, so they compare). θ0 puts
 * the profile's height into one number an AO engineer reads: the anisoplanatism the tomography has to undo, and
 * the moment a profiler most often gets wrong (an estimate that lifts Cn² to the high bins shrinks it).
 * With the layers' winds learned (recon.atmosphere.learn_wind), a third panel: the layers' effective wind
 *   v̄ = (Σ_l f_l |v_l|^{5/3} / Σ_l f_l)^{3/5}                  (τ0 = 0.314 r0 / v̄)
 * of each method's reconstruction layers (their estimated winds, the update's profile compressed onto them as the
 * loop hands it over: hats), against the truth's own layers' v̄ and, dashed, the oracle's: the truth compressed onto
 * the same layers (SPEC §12: Cn²-weighted mean wind vectors), which is all those layers can hold — vector means of
 * layers moving apart are slower than their speeds, so a compressed model's v̄ sits below the truth's.
 * The truth is the configured atmosphere, or its night (sim/night.h, the same parameters as the loop's:
 * wt_loop_night_params) at each update's night time; a sweep over an atmosphere.* key changes the truth per value,
 * so the truth is left out then (the base configuration's would be another one's). The records are those the
 * cases of this process kept (report.h wt_compare_extra: not read back by --resume), the first seed that has one. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/plot.h"
#include "compare/report.h"
#include "core/model/profile.h"
#include "core/model/system.h"
#include "sim/adapt.h"
#include "sim/loop.h"
#include "sim/night.h"

enum { NTRUTH = 200 }; /* points of the truth's line over the run */

static int cols(const wt_compare_cases *a) { return a->nv ? a->nv : 1; }

/* The record of method m at value v that estimated (not the oracle following a night), first seed; NULL: none. */
static const wt_adapt *record(const wt_compare_cases *a, const wt_compare_result *R, const wt_compare_extra *X, int m,
                              int v)
{
    for (int s = 0; s < a->ns; s++) {
        const int c = wt_compare_case(a, m, v, s);
        const wt_adapt *r = X && X->learned ? X->learned[c] : NULL;
        if (R[c].done && r && !wt_adapt_follows_truth(r) && wt_adapt_nupdates(r) > 0) return r;
    }
    return NULL;
}

static int has_records(const wt_compare_cases *a, const wt_compare_result *R, const wt_compare_extra *X, int v)
{
    for (int m = 0; m < a->nm; m++)
        if (record(a, R, X, m, v)) return 1;
    return 0;
}

/* θ0 [arcsec] of r0 [m] and n layers at alt [m] with fractions f (NaN when h̄ = 0: all at the ground). */
static double theta0(double r0, int n, const double *alt, const double *f)
{
    double s = 0.0;
    for (int k = 0; k < n; k++) s += f[k] * pow(fabs(alt[k]), 5.0 / 3.0);
    return s > 0.0 ? 0.314 * r0 / pow(s, 0.6) / WT_ARCSEC : NAN;
}

/* v̄ [m/s] of n layers with fractions f (any sum) and winds (vx, vy) */
static double vbar(int n, const double *f, const double *vx, const double *vy)
{
    double s = 0, t = 0;
    for (int k = 0; k < n; k++) s += f[k] * pow(hypot(vx[k], vy[k]), 5.0 / 3.0), t += f[k];
    return t > 0 ? pow(s / t, 0.6) : NAN;
}

/* The truth at night time t: r0, θ0, v̄ of its own layers, and the oracle's v̄ on the nl layers at lalt (nl = 0:
 * none). The night's state, or the configured atmosphere (night NULL). */
typedef struct {
    double r0, theta0, vbar, oracle_vbar;
} truth_state;
static int truth_at(const wt_config *cfg, const wt_night *night, double t, int nl, const double *lalt, truth_state *ts)
{
    const int n = cfg->nlayers;
    double f[WT_MAX_LAYERS], sp[WT_MAX_LAYERS], dir[WT_MAX_LAYERS], vx[WT_MAX_LAYERS], vy[WT_MAX_LAYERS];
    ts->r0 = cfg->r0;
    memcpy(f, cfg->layer_fraction, (size_t)n * sizeof *f);
    memcpy(sp, cfg->wind_speed, (size_t)n * sizeof *sp);
    memcpy(dir, cfg->wind_direction, (size_t)n * sizeof *dir);
    if (night && wt_night_state(night, t, &ts->r0, f, sp, dir) < 0) return -1;
    for (int k = 0; k < n; k++) vx[k] = sp[k] * cos(dir[k]), vy[k] = sp[k] * sin(dir[k]);
    ts->theta0 = theta0(ts->r0, n, cfg->layer_altitude, f);
    ts->vbar = vbar(n, f, vx, vy);
    ts->oracle_vbar = NAN;
    if (nl > 0) {
        double rf[WT_MAX_LAYERS], rvx[WT_MAX_LAYERS], rvy[WT_MAX_LAYERS];
        wt_profile_compress(n, cfg->layer_altitude, f, vx, vy, nl, lalt, rf, rvx, rvy);
        ts->oracle_vbar = vbar(nl, rf, rvx, rvy);
    }
    return 0;
}

/* An update's v̄ on the record's wind layers (NaN without them): its grid profile compressed as the loop hands it
 * over (hats), its layers' winds */
static double update_vbar(const wt_adapt *r, const wt_adapt_update *u)
{
    const double *lalt = NULL;
    const int nl = wt_adapt_wind_layers(r, &lalt);
    if (nl < 1 || u->nwind != nl) return NAN;
    double rf[WT_MAX_LAYERS];
    wt_profile_compress_hats(u->nalt, u->altitude, u->fraction, NULL, NULL, nl, lalt, rf, NULL, NULL);
    return vbar(nl, rf, u->wind_vx, u->wind_vy);
}

/* The run's clock as the report's run figure reads it: night minutes for a night or a sodium sequence. */
static int night_minutes(const wt_config *cfg)
{
    return cfg->night.source != WT_NIGHT_CFG_NONE || cfg->sodium_sequence[0];
}

static int truth_known(const wt_compare_cases *a) { return !(a->nv && strncmp(a->key, "atmosphere.", 11) == 0); }

/* The night of the configuration (NULL without one, or when it cannot be made: the truth is then left out). */
static wt_night *open_night(wt_context *ctx, const wt_config *cfg)
{
    wt_night_params p;
    wt_loop_night_params(cfg, &p);
    wt_night *n = NULL;
    if (p.source == WT_NIGHT_NONE || wt_night_alloc(ctx, &p, &n) < 0) return NULL;
    return n;
}

int wt_compare_check_learned_outputs(wt_cli *cli, const wt_compare_cases *a, const char *owner)
{
    char path[2200];
    int st = WT_OK;
    for (int v = 0; v < cols(a) && st >= 0; v++) {
        snprintf(path, sizeof path, "%s/learned_%d.png", a->out, v);
        st = wt_cli_check_text_output(cli, path, "\x89PNG", owner);
    }
    return st;
}

/* Whether method m's record at value v holds the layers' winds (learn_wind) */
static int has_wind(const wt_adapt *r) { return r && wt_adapt_wind_layers(r, NULL) > 0; }

void wt_compare_learned_markdown(FILE *f, wt_context *ctx, const wt_compare_cases *a, const wt_config *cfg,
                                 const wt_compare_result *R, const wt_compare_extra *X)
{
    const int nv = cols(a), known = truth_known(a);
    int any = 0, wind = 0;
    for (int v = 0; v < nv; v++) any |= has_records(a, R, X, v);
    if (!any) return;
    for (int m = 0; m < a->nm; m++)
        for (int v = 0; v < nv; v++) wind |= has_wind(record(a, R, X, m, v));
    wt_night *night = known && cfg->night.source != WT_NIGHT_CFG_NONE ? open_night(ctx, cfg) : NULL;
    const int have_truth = known && (cfg->night.source == WT_NIGHT_CFG_NONE || night);
    fprintf(f, "\n\n## The learned atmosphere\n\nEach learning method's estimates%s over the run: r0 at 500 nm with its "
               "stated uncertainty, and the isoplanatic angle θ0 = 0.314 r0 / (Σ f h^(5/3))^(3/5) of the estimated "
               "profile on the learning grid%s%s (records in results.h5 learned/).",
            a->ns > 1 ? " (first seed)" : "",
            have_truth ? ", against the truth's (thick black)" : known ? "" : " (the truth changes with the sweep: not drawn)",
            wind ? "; with the layers' winds learned, their effective wind v̄ = (Σ f |v|^(5/3))^(3/5) (τ0 = 0.314 r0 "
                   "/ v̄), and dashed the oracle's: the truth compressed onto the method's layers, all they can hold"
                 : "");
    if (have_truth) {
        fprintf(f, " Errors against the truth at each estimate's time, mean and rms over the estimates:\n\n"
                   "| method |%s estimates | r0 error, mean / rms | θ0 error, mean / rms |%s\n|---|%s---|---|---|%s\n",
                a->nv ? " value |" : "", wind ? " v̄ against the oracle's, mean / rms |" : "", a->nv ? "---|" : "",
                wind ? "---|" : "");
        for (int m = 0; m < a->nm; m++)
            for (int v = 0; v < nv; v++) {
                const wt_adapt *r = record(a, R, X, m, v);
                if (!r) continue;
                const wt_adapt_update *u = wt_adapt_updates(r);
                const double *lalt = NULL;
                const int n = wt_adapt_nupdates(r), nl = wt_adapt_wind_layers(r, &lalt);
                double e[3][2] = {{0}};
                int k[3] = {0};
                for (int i = 0; i < n; i++) {
                    truth_state ts;
                    if (truth_at(cfg, night, u[i].night, nl, lalt, &ts) < 0) continue;
                    const double d[3] = {u[i].r0 / ts.r0 - 1.0,
                                         theta0(u[i].r0, u[i].nalt, u[i].altitude, u[i].fraction) / ts.theta0 - 1.0,
                                         update_vbar(r, &u[i]) / ts.oracle_vbar - 1.0};
                    for (int q = 0; q < 3; q++)
                        if (isfinite(d[q])) e[q][0] += d[q], e[q][1] += d[q] * d[q], k[q]++;
                }
                fprintf(f, "| %s |%s%s%s %d |", a->methods[m], a->nv ? " " : "", a->nv ? a->values[v] : "",
                        a->nv ? " |" : "", n);
                for (int q = 0; q < 2 + wind; q++) {
                    if (k[q]) fprintf(f, " %+.1f %% / %.1f %% |", 100 * e[q][0] / k[q], 100 * sqrt(e[q][1] / k[q]));
                    else fprintf(f, " – |");
                }
                fprintf(f, "\n");
            }
        fprintf(f, "\n");
    } else
        fprintf(f, "\n\n");
    for (int v = 0; v < nv; v++)
        if (has_records(a, R, X, v))
            fprintf(f, "![the learned atmosphere%s%s](learned_%d.png) ", a->nv ? " " : "", a->nv ? a->values[v] : "", v);
    wt_night_free(night);
}

int wt_compare_learned_plots(wt_cli *cli, const wt_compare_cases *a, const wt_config *cfg, const wt_compare_result *R,
                             const wt_compare_extra *X)
{
    enum { NB = 5 }; /* per method: x, r0, its σ, θ0, v̄ of each update */
    const int nv = cols(a), nm = a->nm, minutes = night_minutes(cfg), known = truth_known(a);
    const double xs = minutes ? 1.0 / 60.0 : 1.0;
    int st = WT_OK;
    wt_night *night = known && cfg->night.source != WT_NIGHT_CFG_NONE ? open_night(cli->ctx, cfg) : NULL;
    const int have_truth = known && (cfg->night.source == WT_NIGHT_CFG_NONE || night);
    /* the truth over the run's clock, frame 0 to the last frame */
    const double c = minutes ? cfg->night.compression : 1.0, t0 = minutes ? cfg->night.start : 0.0,
                 t1 = t0 + (double)(cfg->frames - 1) / cfg->rate * c;
    double tx[NTRUTH], tr[NTRUTH], tt[NTRUTH], tv[NTRUTH], ov[WT_COMPARE_MAXM][NTRUTH];
    int nt = 0;
    for (int i = 0; i < NTRUTH && have_truth; i++) {
        truth_state ts;
        const double t = t0 + (t1 - t0) * i / (NTRUTH - 1);
        if (truth_at(cfg, night, t, 0, NULL, &ts) == 0) tx[nt] = t * xs, tr[nt] = ts.r0, tt[nt] = ts.theta0, tv[nt++] = ts.vbar;
    }
    for (int v = 0; v < nv && st >= 0; v++) {
        if (!has_records(a, R, X, v)) continue;
        double *buf[WT_COMPARE_MAXM][NB] = {{0}};
        int n[WT_COMPARE_MAXM] = {0}, nr[WT_COMPARE_MAXM] = {0}, k = 0, wind = 0;
        const char *names[WT_COMPARE_MAXM];
        const double *x[WT_COMPARE_MAXM], *y0[WT_COMPARE_MAXM], *e0[WT_COMPARE_MAXM], *y1[WT_COMPARE_MAXM],
            *y2[WT_COMPARE_MAXM], *rx[WT_COMPARE_MAXM], *ry[WT_COMPARE_MAXM];
        for (int m = 0; m < nm && st >= 0; m++) {
            const wt_adapt *r = record(a, R, X, m, v);
            if (!r) continue;
            const wt_adapt_update *u = wt_adapt_updates(r);
            n[k] = wt_adapt_nupdates(r);
            for (int q = 0; q < NB; q++)
                if (!(buf[k][q] = malloc((size_t)n[k] * sizeof(double))))
                    st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the learned atmosphere's figure");
            for (int i = 0; i < n[k] && st >= 0; i++)
                buf[k][0][i] = u[i].night * xs, buf[k][1][i] = u[i].r0, buf[k][2][i] = u[i].r0_sigma,
                buf[k][3][i] = theta0(u[i].r0, u[i].nalt, u[i].altitude, u[i].fraction), buf[k][4][i] = update_vbar(r, &u[i]);
            const double *lalt = NULL;
            const int nl = wt_adapt_wind_layers(r, &lalt);
            wind |= nl > 0;
            for (int i = 0; i < nt && nl > 0; i++) { /* the oracle on this method's layers */
                truth_state ts;
                ov[k][i] = truth_at(cfg, night, tx[i] / xs, nl, lalt, &ts) == 0 ? ts.oracle_vbar : NAN;
            }
            nr[k] = nl > 0 ? nt : 0;
            names[k] = a->methods[m], x[k] = buf[k][0], y0[k] = buf[k][1], e0[k] = buf[k][2], y1[k] = buf[k][3];
            y2[k] = buf[k][4], rx[k] = tx, ry[k] = ov[k];
            k++;
        }
        if (st >= 0) {
            const wt_plot_series_panel p[3] = {
                {.ylabel = "r0 at 500 nm [m]", .n = n, .x = x, .y = y0, .e = e0, .nt = nt, .tx = tx, .ty = tr},
                {.ylabel = "θ0 at 500 nm [arcsec]", .n = n, .x = x, .y = y1, .nt = nt, .tx = tx, .ty = tt},
                {.ylabel = "layers' wind v̄ [m/s]", .n = n, .x = x, .y = y2, .nt = nt, .tx = tx, .ty = tv,
                 .nr = nr, .rx = rx, .ry = ry}};
            char path[2200], title[256];
            const char *dot = a->nv ? strrchr(a->key, '.') : NULL;
            snprintf(path, sizeof path, "%s/learned_%d.png", a->out, v);
            snprintf(title, sizeof title, "the learned atmosphere%s%s%s%s%s", a->nv ? ", " : "",
                     a->nv ? (dot ? dot + 1 : a->key) : "", a->nv ? "=" : "", a->nv ? a->values[v] : "",
                     have_truth ? "" : " (truth not drawn)");
            st = wt_plot_series(cli->ctx, path, title, minutes ? "night time [min]" : "time [s]", k, names,
                                "oracle", 2 + wind, p);
        }
        for (int q = 0; q < nm; q++)
            for (int i = 0; i < NB; i++) free(buf[q][i]);
    }
    wt_night_free(night);
    return st;
}
