/* tests/frozen_flow.h: synthetic frozen flow for the wind estimator (core/model/wind_align.h), shared by the suite
 * tests/test_wind_align.c and the bias tool tests/bias_wind_align.c: a periodic von Kármán screen, the scene of
 * layers moved every frame by the exact Fourier shift (core/op/shift.h), and its run through an estimator. The
 * includer provides tu_context() and ck_assert_int_eq (testutil.h, or the bias tool's stand-ins). */
#ifndef WT_TESTS_FROZEN_FLOW_H
#define WT_TESTS_FROZEN_FLOW_H

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/base/rng.h"
#include "core/model/wind_align.h"
#include "core/op/shift.h"

#define DT 0.002 /* a frame at 500 Hz [s] */

/* A periodic von Kármán screen (L0 25 m) on n × n points of spacing d, unit rms, into x (row-major, x fastest) */
static void screen(int n, double d, unsigned long seed, double *x)
{
    const int nh = n / 2 + 1;
    fftw_complex *c = fftw_alloc_complex((size_t)n * nh);
    double *re = fftw_alloc_real((size_t)n * n);
    fftw_plan p = fftw_plan_dft_c2r_2d(n, n, c, re, FFTW_ESTIMATE);
    wt_rng r;
    wt_rng_init(&r, seed, 7);
    const double L = n * d, f0 = 1.0 / 25.0;
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < nh; ix++) {
            const double fx = ix / L, fy = (iy <= n / 2 ? iy : iy - n) / L;
            const double a = ix == 0 && iy == 0 ? 0.0 : pow(fx * fx + fy * fy + f0 * f0, -11.0 / 12.0);
            c[(size_t)iy * nh + ix][0] = a * wt_rng_normal(&r);
            c[(size_t)iy * nh + ix][1] = a * wt_rng_normal(&r);
        }
    fftw_execute(p);
    double s = 0.0;
    for (int i = 0; i < n * n; i++) s += re[i] * re[i];
    for (int i = 0; i < n * n; i++) x[i] = re[i] / sqrt(s / (n * n));
    fftw_destroy_plan(p);
    fftw_free(c);
    fftw_free(re);
}

typedef struct {
    int L;
    int n[2];
    double d[2], vx[2], vy[2];
    double window;  /* > 0: the estimate is the layer times a disc of this diameter [points]; 0: the whole grid */
    double noise;   /* independent white noise per frame, rms (relative to the unit-rms layer) */
    double frozen;  /* 0: no layer, noise alone */
    long frames;
} scene;

static wt_wind_align_params params(long frames)
{
    wt_wind_align_params p = {.stride = 4, .nlag = 4, .lag = {1, 2, 4, 8}, .nbatch = 4, .frame_dt = DT};
    p.batch_snapshots = frames / p.stride / p.nbatch;
    return p;
}

/* Run the scene through an estimator; est: L estimates */
static void run(const scene *sc, unsigned long seed, wt_wind_estimate *est)
{
    wt_context *ctx = tu_context();
    wt_grid g[2];
    const wt_grid *gp[2];
    int64_t off[2] = {0, 0}, N = 0;
    double sx[2], sy[2];
    for (int l = 0; l < sc->L; l++) {
        g[l] = wt_grid_layer(sc->n[l], sc->d[l]);
        gp[l] = &g[l];
        off[l] = N;
        N += (int64_t)sc->n[l] * sc->n[l];
        sx[l] = sc->vx[l] * DT, sy[l] = sc->vy[l] * DT;
    }
    double *phi = malloc(N * sizeof *phi), *seen = malloc(N * sizeof *seen);
    for (int l = 0; l < sc->L; l++) screen(sc->n[l], sc->d[l], seed + 10 * l, phi + off[l]);
    wt_shift *sh = NULL;
    ck_assert_int_eq(wt_shift_alloc(ctx, sc->L, gp, off, sx, sy, &sh), WT_OK);
    wt_wind_align_params p = params(sc->frames);
    const double rad[2] = {0.5 * sc->window * sc->d[0], 0.5 * sc->window * sc->d[1]};
    wt_wind_align *w = NULL;
    ck_assert_int_eq(wt_wind_align_alloc(ctx, sc->L, gp, off, sc->window > 0.0 ? rad : NULL, NULL, &p, &w), WT_OK);
    wt_rng r;
    wt_rng_init(&r, seed, 3);
    for (long t = 0; t < sc->frames; t++) {
        for (int l = 0; l < sc->L; l++) {
            const int n = sc->n[l];
            for (int iy = 0; iy < n; iy++)
                for (int ix = 0; ix < n; ix++) {
                    const int64_t i = off[l] + (int64_t)iy * n + ix;
                    const double rx = ix - n / 2, ry = iy - n / 2;
                    const double win = sc->window <= 0.0 || 4.0 * (rx * rx + ry * ry) <= sc->window * sc->window;
                    seen[i] = win * sc->frozen * phi[i] + sc->noise * wt_rng_normal(&r);
                }
        }
        ck_assert_int_eq(wt_wind_align_add(w, t, seen), WT_OK);
        wt_shift_apply(sh, phi); /* the next frame: the layers moved by v Δt */
    }
    ck_assert_int_eq(wt_wind_align_estimate(w, est), WT_OK);
    wt_wind_align_free(w);
    wt_shift_free(sh);
    free(phi);
    free(seen);
    wt_context_free(ctx);
}

#endif
