/* tests/timing/scale_gain_time.c: per-frame time of the loop's integrator update with a scale-dependent gain
 * (core/op/scale_gain.h) on the DMs of a configuration (default: the E-ELT preset, 3 DMs, 10027 actuators),
 * both bases and 2 … 5 bands, against the single gain's update; and the set-up time. Not a test (no timing in
 * the suites); build and run by hand:
 *   make build/libwavetomo.a && gcc -std=c11 -D_DEFAULT_SOURCE -O3 -fopenmp -I. tests/timing/scale_gain_time.c \
 *       build/libwavetomo.a $(pkg-config --libs openblas lapacke libconfig) -lm -o build/scale_gain_time \
 *       && build/scale_gain_time [CONFIG]
 * Median and p99 over 2000 updates, one thread (the update runs outside the parallel regions). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base/base.h"
#include "core/config/config.h"
#include "core/op/dm.h"
#include "core/op/scale_gain.h"

#define REPS 2000

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "data/presets/eelt-mcao.cfg";
    wt_context *ctx = wt_context_alloc();
    wt_config *cfg = NULL;
    wt_dm *dm = NULL;
    if (wt_config_read(ctx, path, 0, NULL, &cfg) < 0) {
        fprintf(stderr, "%s\n", wt_error_message(ctx));
        return 1;
    }
    wt_dm_params dp = {.ndms = cfg->ndms, .guard_rings = cfg->dm_guard_rings, .field_radius = cfg->dm_field_radius,
                       .diameter = cfg->diameter};
    for (int k = 0; k < cfg->ndms; k++) {
        dp.altitude[k] = cfg->dm_altitude[k];
        dp.pitch[k] = cfg->dm_pitch[k];
        dp.actuators[k] = cfg->dm_actuators[k];
    }
    if (wt_dm_alloc(ctx, &dp, &dm) < 0) {
        fprintf(stderr, "%s\n", wt_error_message(ctx));
        return 1;
    }
    const int64_t n = dm->nact;
    double *x = malloc(n * sizeof *x), *y = calloc(n, sizeof *y), *prev = calloc(n, sizeof *prev), t[REPS];
    for (int64_t i = 0; i < n; i++) x[i] = (double)((i * 7919) % 1000) / 1000.0 - 0.5;
    printf("%s: %d DMs, %lld actuators; grids", path, dm->ndms, (long long)n);
    for (int k = 0; k < dm->ndms; k++) printf(" %dx%d", dm->grid[k].nx, dm->grid[k].ny);
    printf("\n");

    for (int r = 0; r < REPS; r++) { /* the single gain: next = prev + g (a_rec - a_t) */
        double t0 = wt_time_now();
        for (int64_t i = 0; i < n; i++) y[i] = prev[i] + 0.4 * x[i];
        t[r] = wt_time_now() - t0;
    }
    qsort(t, REPS, sizeof *t, cmp);
    printf("single gain                  median %8.1f us  p99 %8.1f us\n", 1e6 * t[REPS / 2], 1e6 * t[REPS * 99 / 100]);

    for (int basis = 0; basis < 2; basis++)
        for (int nb = 2; nb <= 5; nb++) {
            wt_scale_gain_params p = {.nbands = nb, .basis = basis, .wavelet_order = cfg->wavelet_order};
            for (int j = 0; j < nb; j++) p.gain[j] = 0.6 - 0.1 * j;
            wt_scale_gain *sg = NULL;
            double t0 = wt_time_now();
            if (wt_scale_gain_alloc(ctx, dm, &p, &sg) < 0) {
                printf("%s, %d bands: %s\n", basis ? "daubechies" : "bilinear", nb, wt_error_message(ctx));
                continue;
            }
            const double setup = wt_time_now() - t0;
            double *work = malloc((wt_scale_gain_work_size(sg) + 1) * sizeof *work);
            for (int r = 0; r < REPS; r++) {
                t0 = wt_time_now();
                memcpy(y, prev, n * sizeof *y);
                wt_scale_gain_apply(sg, 1.0, x, y, work);
                t[r] = wt_time_now() - t0;
            }
            qsort(t, REPS, sizeof *t, cmp);
            printf("%-10s %d bands (L = %d)    median %8.1f us  p99 %8.1f us  set-up %.1f ms  dim V_0 %lld\n",
                   basis ? "daubechies" : "bilinear", nb, nb - 1, 1e6 * t[REPS / 2], 1e6 * t[REPS * 99 / 100],
                   1e3 * setup, (long long)wt_scale_gain_dim(sg, 0));
            free(work);
            wt_scale_gain_free(sg);
        }
    free(x), free(y), free(prev);
    wt_dm_free(dm);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
    return 0;
}
