/* tests/bias_wind_align.c: the bias and scatter of the layers' wind estimate (core/model/wind_align.h) on synthetic
 * frozen flow: a periodic von Kármán layer moved every frame by the exact Fourier shift (core/op/shift.h), seen on
 * the whole grid or through a disc footprint (the estimator's taper on its radius), white noise added; 3 seeds per
 * case. Not a test suite (docs/results.md quotes it). Build and run from the top directory after `make`:
 *   cc -std=c11 -D_DEFAULT_SOURCE -O2 -fopenmp -I. -Iinclude tests/bias_wind_align.c build/libwavetomo.a \
 *      -lfftw3 -lopenblas -llapacke -lcholmod -lhdf5_serial -lconfig -lm -o /tmp/bias_wind_align && /tmp/bias_wind_align
 */
#include <stdio.h>
#include <stdlib.h>

#include "core/base/base.h"

static wt_context *tu_context(void) { return wt_context_alloc(); }
#define ck_assert_int_eq(a, b)                                      \
    do {                                                            \
        if ((a) != (b)) {                                           \
            fprintf(stderr, "%s failed\n", #a);                      \
            exit(1);                                                \
        }                                                           \
    } while (0)

#include "frozen_flow.h"

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
