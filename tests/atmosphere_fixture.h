/* tests/atmosphere_fixture.h: what the atmosphere suites share (test_atmosphere.c, test_atmosphere_project.c):
 * an atmosphere set up from a few numbers (one layer, three layers), rms and largest difference. */
#ifndef WT_TESTS_ATMOSPHERE_FIXTURE_H
#define WT_TESTS_ATMOSPHERE_FIXTURE_H

#include "testutil.h"

#include <stdint.h>

#include "core/op/grid.h"
#include "sim/atmosphere.h"

typedef struct atm_setup {
    int nl;
    double h[9], f[9], v[9], dir[9];
    double r0, L0, delta;
    int n, nosh;
    uint64_t seed;
} atm_setup;

static inline wt_atmosphere *make_atm(wt_context *ctx, const atm_setup *s)
{
    wt_atmosphere_params p = {s->nl, s->h, s->f, s->v, s->dir, s->r0, s->L0, s->n, s->delta, s->seed, s->nosh};
    wt_atmosphere *atm = NULL;
    int st = wt_atmosphere_alloc(ctx, &p, &atm);
    ck_assert_msg(st == WT_OK && atm, "wt_atmosphere_alloc: %s", wt_error_message(ctx));
    return atm;
}

static inline atm_setup one_layer(int n, double delta, double L0, double h, double speed, double dir, uint64_t seed,
                           int nosh)
{
    atm_setup s = {.nl = 1, .r0 = 0.129, .L0 = L0, .delta = delta, .n = n, .nosh = nosh, .seed = seed};
    s.h[0] = h, s.f[0] = 1.0, s.v[0] = speed, s.dir[0] = dir;
    return s;
}

static inline double rms(const double *x, long n)
{
    double s = 0.0;
    for (long i = 0; i < n; i++) s += x[i] * x[i];
    return sqrt(s / n);
}

static inline double max_abs_diff(const double *a, const double *b, long n)
{
    double m = 0.0;
    for (long i = 0; i < n; i++) m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

static inline atm_setup three_layers(uint64_t seed)
{
    atm_setup s = {.nl = 3, .r0 = 0.129, .L0 = 25.0, .delta = 0.125, .n = 128, .seed = seed};
    const double h[3] = {0.0, 4000.0, 12000.0}, f[3] = {0.5, 0.3, 0.2}, v[3] = {10, 15, 30}, d[3] = {0.3, 2.0, -1.0};
    for (int l = 0; l < 3; l++) s.h[l] = h[l], s.f[l] = f[l], s.v[l] = v[l], s.dir[l] = d[l];
    return s;
}

#endif
