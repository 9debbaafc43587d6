/* tests/bias_wind_align.c: the bias and scatter of the layers' wind estimate (core/model/wind_align.h) on synthetic
 * frozen flow: a periodic von Kármán layer moved every frame by the exact Fourier shift (core/op/shift.h), seen on
 * the whole grid or through a disc footprint (the estimator's taper on its radius), white noise added; 3 seeds per
 * case. Not a test suite (docs/results.md quotes it). Build and run from the top directory after `make`:
 *   cc -std=c11 -D_DEFAULT_SOURCE -O2 -fopenmp -I. -Iinclude tests/bias_wind_align.c build/libwavetomo.a \
 *      -lfftw3 -lopenblas -llapacke -lcholmod -lhdf5_serial -lconfig -lm -o /tmp/bias_wind_align && /tmp/bias_wind_align
 */
#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base/base.h"
#include "core/base/rng.h"
#include "core/model/wind_align.h"
#include "core/op/shift.h"

static wt_context *tu_context(void) { return wt_context_alloc(); }
#define ck_assert_int_eq(a, b)                                      \
    do {                                                            \
        if ((a) != (b)) {                                           \
            fprintf(stderr, "%s failed\n", #a);                      \
            exit(1);                                                \
        }                                                           \
    } while (0)

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

int main(void)
{
    static const struct { int n; double win, noise, vx, vy; long frames; } c[] = {
        {32, 0, 0.0, 7.3, -4.1, 400},   {32, 0, 0.0, 25.0, 10.0, 400}, {32, 0, 0.2, 9.0, 6.0, 800},
        {32, 16, 0.2, 9.0, 6.0, 800},   {64, 32, 0.2, 9.0, 6.0, 800},  {128, 64, 0.2, 9.0, 6.0, 800},
        {64, 32, 0.2, 25.0, -10.0, 800}, {64, 32, 0.0, 3.0, 1.0, 800},  {64, 32, 1.0, 9.0, 6.0, 800}};
    printf("grid  footprint  noise  wind [m/s]       frames  seed  estimate [m/s]      sigma [m/s]     rho   lags  "
           "error [m/s]  speed error\n");
    for (size_t k = 0; k < sizeof c / sizeof *c; k++) {
        const scene sc = {.L = 1, .n = {c[k].n}, .d = {0.5}, .vx = {c[k].vx}, .vy = {c[k].vy}, .frozen = 1.0,
                          .window = c[k].win, .noise = c[k].noise, .frames = c[k].frames};
        for (unsigned long seed = 1; seed <= 3; seed++) {
            wt_wind_estimate e[1];
            run(&sc, seed, e);
            const double v = hypot(c[k].vx, c[k].vy);
            printf("%4d  %9.0f  %5.1f  (%5.1f, %5.1f)  %6ld  %4lu  (%7.3f, %7.3f)  (%6.3f, %6.3f)  %.3f  %d  %11.3f  %+9.1f %%\n",
                   c[k].n, c[k].win, c[k].noise, c[k].vx, c[k].vy, c[k].frames, seed, e[0].vx, e[0].vy, e[0].sigma_x,
                   e[0].sigma_y, e[0].rho, e[0].nlag_used, hypot(e[0].vx - c[k].vx, e[0].vy - c[k].vy),
                   100.0 * (hypot(e[0].vx, e[0].vy) - v) / v);
        }
    }
    return 0;
}
