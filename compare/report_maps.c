/* compare/report_maps.c: the report's maps over the evaluation field (cli/plot_maps.c draws them): each
 * method's LE Strehl map on one colour scale, and for two methods or more each method's residual WFE minus the
 * first listed method's, per evaluation direction,
 *     d_j = σ_j(method) − σ_j(reference)   [nm],
 * on the same seeds (so a paired difference: the turbulence and noise cancel, what is left is the methods'), with
 * the guide stars' directions drawn on every map. WFE rather than Strehl for the difference: it has a unit and
 * stays linear where the Strehl saturates or vanishes. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli/plot.h"
#include "compare/report.h"
#include "core/model/system.h"

static int cols(const wt_compare_cases *a) { return a->nv ? a->nv : 1; }
static const char *val(const wt_compare_cases *a, int v) { return a->nv ? a->values[v] : ""; }

/* ", photons=100" of sweep column v (the key's last part: the titles stay within the page; empty without a
 * sweep) and ", mean of N seeds" */
static void suffix(char *s, size_t n, const wt_compare_cases *a, int v)
{
    const char *dot = a->nv ? strrchr(a->key, '.') : NULL;
    snprintf(s, n, "%s%s%s%s", a->nv ? ", " : "", a->nv ? (dot ? dot + 1 : a->key) : "", a->nv ? "=" : "", val(a, v));
    if (a->ns > 1) snprintf(s + strlen(s), n - strlen(s), ", mean of %d seeds", a->ns);
}

int wt_compare_check_map_outputs(wt_cli *cli, const wt_compare_cases *a, const char *owner)
{
    char path[2200];
    int st = WT_OK;
    for (int m = 0; m < a->nm && st >= 0; m++)
        for (int v = 0; v < cols(a) && st >= 0; v++) {
            snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
            st = wt_cli_check_text_output(cli, path, "\x89PNG", owner);
            if (m > 0 && st >= 0) {
                snprintf(path, sizeof path, "%s/diff_%s_%s_%d.png", a->out, a->methods[m], a->methods[0], v);
                st = wt_cli_check_text_output(cli, path, "\x89PNG", owner);
            }
        }
    return st;
}

static int both_done(const wt_compare_cases *a, const wt_compare_summary *S, int m, int v)
{
    return m > 0 && S[m * cols(a) + v].mean.done && S[v].mean.done;
}

void wt_compare_maps_markdown(FILE *f, const wt_compare_cases *a, const wt_compare_summary *S, int differences)
{
    const int nv = cols(a);
    for (int v = 0; v < nv && !differences; v++)
        for (int m = 0; m < a->nm; m++)
            if (S[m * nv + v].mean.done)
                fprintf(f, "![%s%s%s](map_%s_%d.png) ", a->methods[m], a->nv ? " " : "", val(a, v), a->methods[m], v);
    if (!differences) return;
    int any = 0;
    for (int v = 0; v < nv; v++)
        for (int m = 1; m < a->nm; m++) any |= both_done(a, S, m, v);
    if (!any) return;
    fprintf(f, "\n\n## Differences between methods\n\nThe residual WFE of each method minus %s's in every evaluation "
               "direction [nm], on the same turbulence and noise (%s): blue where it does better than %s, red where "
               "worse, white where they agree; ★ the LGS, ▲ the NGS.\n\n",
            a->methods[0], a->ns > 1 ? "the same seeds, mean of the paired differences" : "the same seed", a->methods[0]);
    for (int v = 0; v < nv; v++)
        for (int m = 1; m < a->nm; m++)
            if (both_done(a, S, m, v))
                fprintf(f, "![%s − %s%s%s](diff_%s_%s_%d.png) ", a->methods[m], a->methods[0], a->nv ? " " : "",
                        val(a, v), a->methods[m], a->methods[0], v);
}

int wt_compare_maps(wt_cli *cli, const wt_compare_cases *a, const wt_system *sys, const wt_compare_summary *S,
                const double *coords)
{
    const int nm = a->nm, nv = cols(a), g = sys->cfg->eval_grid, nd = sys->neval;
    double gx[2][2 * WT_MAX_GS], gy[2][2 * WT_MAX_GS];
    wt_plot_stars stars = {0, 0, gx[0], gy[0], gx[1], gy[1]};
    for (int i = 0; i < sys->nsensors; i++) { /* the sensors' directions, as on the sky */
        const int k = sys->sensors[i].kind == WT_SENSOR_LGS ? 0 : 1;
        int *n = k ? &stars.nngs : &stars.nlgs;
        gx[k][*n] = sys->sensors[i].theta_x / WT_ARCSEC, gy[k][*n] = sys->sensors[i].theta_y / WT_ARCSEC, (*n)++;
    }
    char path[2200], title[256], sfx[192];
    double vmin = 1.0, vmax = 0.0, d[WT_MAX_EVAL];
    for (int c = 0; c < nm * nv; c++)
        for (int j = 0; j < nd && S[c].mean.done; j++)
            vmin = fmin(vmin, S[c].mean.strehl[j]), vmax = fmax(vmax, S[c].mean.strehl[j]);
    int st = WT_OK;
    for (int c = 0; c < nm * nv && st >= 0; c++) {
        if (!S[c].mean.done) continue;
        const int m = c / nv, v = c % nv;
        suffix(sfx, sizeof sfx, a, v);
        snprintf(path, sizeof path, "%s/map_%s_%d.png", a->out, a->methods[m], v);
        snprintf(title, sizeof title, "LE Strehl, %s%s", a->methods[m], sfx);
        st = wt_plot_strehl_map(cli->ctx, path, title, g, coords, S[c].mean.strehl, vmin, vmax, &stars);
    }
    for (int v = 0; v < nv && st >= 0; v++)
        for (int m = 1; m < nm && st >= 0; m++) {
            if (!both_done(a, S, m, v)) continue;
            for (int j = 0; j < nd; j++) d[j] = S[m * nv + v].mean.wfe[j] - S[v].mean.wfe[j];
            suffix(sfx, sizeof sfx, a, v);
            snprintf(path, sizeof path, "%s/diff_%s_%s_%d.png", a->out, a->methods[m], a->methods[0], v);
            snprintf(title, sizeof title, "WFE %s − %s (> 0: %s worse)%s", a->methods[m], a->methods[0], a->methods[m],
                     sfx);
            st = wt_plot_diff_map(cli->ctx, path, title, g, coords, d, "WFE difference [nm]", "%+.1f", &stars);
        }
    return st;
}
