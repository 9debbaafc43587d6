/* tests/test_learn_wind.c: the wind of each layer from the lagged cross-covariance maps (SPEC §12 "Wind";
 * core/model/learn.h wt_learn_wind_fit): a synthetic frozen-flow layer's wind, two layers parted by their motion, and
 * the refusals. */
#include "core/model/learn.h"
#include "sim/atmosphere.h"
#include "core/op/grid.h"
#include "learn_fixture.h"
#include "testutil.h"

/* F consecutive frames (frame time dt) of nl frozen-flow layers at h[] with fractions fr[] moving at speed[] towards
 * dir[] [rad], seen by the LGS of G as in simulate(), seed `seed` */
static void simulate_layers(wt_context *ctx, const geom *G, int nl, const double *h, const double *fr,
                            const double *speed, const double *dir, double r0, double L0, int F, double dt,
                            uint64_t seed, double *s)
{
    const int n = G->n, q = 4, np = n * q + 1, ns = geom_nsub(G);
    const double d = G->d;
    wt_grid tg = {np, np, d / q, -n * d / 2, -n * d / 2};
    double *opd = malloc(sizeof(double) * np * np);
    int sub[32 * 32];
    for (int k = 0, m = 0; k < n * n; k++)
        if (G->valid[k]) sub[m++] = k;
    /* no subharmonics: the large scales they add move with the layer too but cost 24 terms a point */
    wt_atmosphere_params ap = {nl, h, fr, speed, dir, r0, L0, 512, 0.125, seed, 1};
    wt_atmosphere *atm = NULL;
    ck_assert_int_eq(wt_atmosphere_alloc(ctx, &ap, &atm), WT_OK);
    for (int f = 0; f < F; f++) {
        double *sf = s + (size_t)f * G->nlgs * 2 * ns;
        for (int i = 0; i < G->nlgs; i++) {
            memset(opd, 0, sizeof(double) * np * np);
            ck_assert_int_eq(wt_atmosphere_project(atm, f * dt, 90e3, G->tx[i], G->ty[i], &tg, NULL, 1.0, opd), WT_OK);
            for (int k = 0; k < ns; k++) {
                int ix = sub[k] % n, iy = sub[k] / n;
                double gx = 0, gy = 0;
                for (int u = 0; u <= q; u++) {
                    double w = (u == 0 || u == q ? 0.5 : 1.0) / q;
                    gx += w * (opd[(ix * q + q) + np * (iy * q + u)] - opd[(ix * q) + np * (iy * q + u)]);
                    gy += w * (opd[(ix * q + u) + np * (iy * q + q)] - opd[(ix * q + u) + np * (iy * q)]);
                }
                sf[(size_t)i * 2 * ns + k] = gx / d, sf[(size_t)i * 2 * ns + ns + k] = gy / d;
            }
        }
    }
    wt_atmosphere_free(atm);
    free(opd);
}

/* the same for one layer at h */
static void simulate_flow(wt_context *ctx, const geom *G, double h, double speed, double dir, double r0, double L0,
                          int F, double dt, uint64_t seed, double *s)
{
    const double one = 1.0;
    simulate_layers(ctx, G, 1, &h, &one, &speed, &dir, r0, L0, F, dt, seed, s);
}

/* The K frames s (G's LGS) accumulated with lags {1, 3, 8} in 4 batches, the profile fitted on the default grid
 * (alt, *na) and the wind (frame time dt) fitted: the estimate into e, the wind into w; returns the accumulator. */
static wt_learn *fit_wind(wt_context *ctx, const geom *G, const double *s, int K, double L0, double dt, double *alt,
                          int *na, wt_learn_estimate *e, wt_learn_wind *w, const char *name)
{
    const int ns = geom_nsub(G), lags[3] = {1, 3, 8};
    wt_learn *L = NULL;
    ck_assert_int_eq(wt_learn_alloc_lagged(ctx, &G->g, 4, K / 4, 3, lags, &L), WT_OK);
    for (int t = 0; t < K; t++) ck_assert_int_eq(wt_learn_add(L, s + (size_t)t * G->nlgs * 2 * ns), WT_OK);
    *na = wt_learn_default_grid(90e3, WT_LEARN_MAX_ALT, alt);
    ck_assert_int_eq(wt_learn_fit(L, *na, alt, L0, e), WT_OK);
    const double t0 = wt_time_now();
    ck_assert_int_eq(wt_learn_wind_fit(L, e, dt, WT_LEARN_WIND_MIN_FRACTION, w), WT_OK);
    fprintf(stderr, "%s: the wind fit took %.2f s, %d split off, residual %.3f\n", name, wt_time_now() - t0, w->split,
            w->residual);
    return L;
}

/* A single frozen-flow layer (demo geometry, 4 LGS at 45″) has its wind found: at 3 km, 10 m/s towards 30°, and at
 * 8 km, 15 m/s towards 200° (a second direction, both components negative). Frame time 10 ms, lags 1, 3, 8
 * frames (shifts 0.1–1.2 m against d = 0.5 m), 600 frames (two screens of 300: a lag pair across the seam is of two
 * independent screens, zero mean, so it adds noise and no bias). The error expected: the batches' spread ~0.15–0.3
 * m/s per component (the screen is 64 m, the layer crosses it ~once, so the frames hold few independent samples of
 * the large scales); 0.5 m/s is the task's figure and ~2–3σ (the errors are ~0.1 m/s). The strongest bin is checked (the profile fit may give a
 * neighbouring bin ≥ 5 % too, and fits its own wind). */
START_TEST(test_wind)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 16, 4, 45.0);
    const int ns = geom_nsub(&G), per = 300, K = 2 * per;
    const double r0 = 0.15, L0 = 25.0, dt = 0.01;
    const double hs[2] = {3000.0, 8000.0}, vs[2] = {10.0, 15.0}, ds[2] = {30.0, 200.0};
    double *s = malloc(sizeof(double) * (size_t)K * G.nlgs * 2 * ns);
    for (int c = 0; c < 2; c++) {
        const double dir = ds[c] * M_PI / 180;
        for (int sd = 0; sd < 2; sd++)
            simulate_flow(ctx, &G, hs[c], vs[c], dir, r0, L0, per, dt, (uint64_t)(700 + 10 * c + sd),
                          s + (size_t)sd * per * G.nlgs * 2 * ns);
        double alt[WT_LEARN_MAX_ALT];
        int na;
        wt_learn_estimate e;
        wt_learn_wind w;
        wt_learn *L = fit_wind(ctx, &G, s, K, L0, dt, alt, &na, &e, &w, "test_wind");
        int best = 0;
        for (int a = 0; a < na; a++) {
            if (e.fraction[a] > e.fraction[best]) best = a;
            if (w.fitted[a])
                fprintf(stderr, "test_wind: %5.1f km  %.3f  v (%6.2f, %6.2f) ± (%.2f, %.2f) m/s, %5.2f m/s towards %6.1f° ± %.1f°\n",
                        alt[a] / 1e3, e.fraction[a], w.vx[a], w.vy[a], w.vx_sigma[a], w.vy_sigma[a], w.speed[a],
                        w.direction[a] * 180 / M_PI, w.direction_sigma[a] * 180 / M_PI);
        }
        fprintf(stderr, "test_wind: truth %g m/s towards %g° at %g km; residual %.3f, %d iterations, amplitude %.3f\n",
                vs[c], ds[c], hs[c] / 1e3, w.residual, w.iterations, w.amplitude[best]);
        const double ex = w.vx[best] - vs[c] * cos(dir), ey = w.vy[best] - vs[c] * sin(dir);
        ck_assert_msg(w.fitted[best] && hypot(ex, ey) <= 0.5, "wind error (%.2f, %.2f) m/s at %g km", ex, ey, alt[best]);
        ck_assert_int_eq(w.nbatch, 4);
        ck_assert(w.vx_sigma[best] > 0 && w.vx_sigma[best] < 0.5);
        /* onto one reconstruction layer at the layer's altitude: the fitted bins' weighted mean, near the truth */
        double rf, rvx, rvy, sx, sy;
        wt_learn_wind_compress(&w, 1, &hs[c], &rf, &rvx, &rvy, &sx, &sy);
        ck_assert(fabs(rf - 1.0) < 1e-12);
        ck_assert_msg(hypot(rvx - vs[c] * cos(dir), rvy - vs[c] * sin(dir)) <= 1.0, "compressed wind (%.2f, %.2f)", rvx, rvy);
        wt_learn_free(L);
    }
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* Two layers below the pairs' altitude resolution (d/θ = 0.5 m / 90″ ≈ 1.1 km here), at 0 and 500 m, moving
 * differently: 8 m/s towards 0° (70 % of the Cn²) and 8 m/s towards 120° (30 %). One wind for the peak is their
 * mixture (6.0 m/s towards 15°: 2.7 and 7 m/s from the two); the lagged maps part them (at the longest lag their
 * shifts, 0.64 m each, are 1.1 m apart: two subapertures), so each bin holding ≥ 2 % of the Cn² gets its own wind.
 * The tolerance: 1.5 m/s and 10°, about 3 times the weaker layer's batches' spread over 600 frames (0.4–1.4 m/s per
 * component, seeds 740–800; the stronger's 0.2–0.4, but both are pulled towards each other by their residual
 * overlap in altitude, ~0.55 m/s on the ground layer). */
START_TEST(test_wind_split)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 16, 4, 45.0);
    const int ns = geom_nsub(&G), per = 300, K = 2 * per;
    const double r0 = 0.15, L0 = 25.0, dt = 0.01;
    const double hs[2] = {0.0, 500.0}, fr[2] = {0.7, 0.3}, vs[2] = {8.0, 8.0}, ds[2] = {0.0, 120.0 * M_PI / 180};
    double *s = malloc(sizeof(double) * (size_t)K * G.nlgs * 2 * ns);
    for (int sd = 0; sd < 2; sd++)
        simulate_layers(ctx, &G, 2, hs, fr, vs, ds, r0, L0, per, dt, (uint64_t)(740 + sd), s + (size_t)sd * per * G.nlgs * 2 * ns);
    double alt[WT_LEARN_MAX_ALT];
    int na;
    wt_learn_estimate e;
    wt_learn_wind w;
    wt_learn *L = fit_wind(ctx, &G, s, K, L0, dt, alt, &na, &e, &w, "test_wind_split");
    for (int a = 0; a < na; a++)
        if (w.fitted[a] || e.fraction[a] > 0.01)
            fprintf(stderr, "test_wind_split: %5.2f km  %.3f  fitted %d  %5.2f m/s towards %6.1f° ± %.1f°, v ± (%.2f, %.2f), "
                    "amplitude %.2f\n", alt[a] / 1e3, e.fraction[a], w.fitted[a], w.speed[a], w.direction[a] * 180 / M_PI,
                    w.direction_sigma[a] * 180 / M_PI, w.vx_sigma[a], w.vy_sigma[a], w.amplitude[a]);
    for (int c = 0; c < 2; c++) {
        const int a = c; /* the grid's 0 and 0.5 km */
        ck_assert(fabs(alt[a] - hs[c]) < 1e-9);
        const double ex = w.vx[a] - vs[c] * cos(ds[c]), ey = w.vy[a] - vs[c] * sin(ds[c]);
        const double dd = remainder(w.direction[a] - ds[c], 2 * M_PI) * 180 / M_PI;
        ck_assert_msg(w.fitted[a] && hypot(ex, ey) <= 1.5 && fabs(dd) <= 10.0, "layer %d: wind error (%.2f, %.2f) m/s, %.1f°",
                      c, ex, ey, dd);
    }
    ck_assert_int_ge(w.split, 1);
    wt_learn_free(L);
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* The wind's refusals: no lags, too few frames for the longest lag, a bad frame time, a bad lag list */
START_TEST(test_wind_refusals)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 8, 2, 30.0);
    const int ns = geom_nsub(&G), lags[2] = {2, 5}, bad[2] = {5, 2};
    wt_learn *L = NULL;
    ck_assert_int_eq(wt_learn_alloc_lagged(ctx, &G.g, 1, 0, 2, bad, &L), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "lags must increase"));
    ck_assert_int_eq(wt_learn_alloc_lagged(ctx, &G.g, 1, 0, 2, lags, &L), WT_OK);
    ck_assert_int_eq(wt_learn_nlags(L), 2);
    ck_assert_int_eq(wt_learn_lag(L, 1), 5);
    double *s = malloc(sizeof(double) * G.nlgs * 2 * ns);
    wt_learn_estimate e = {0};
    e.nalt = 1, e.altitude[0] = 0, e.cn2[0] = 1, e.fraction[0] = 1, e.L0 = 25;
    wt_learn_wind w;
    for (int t = 0; t < 6; t++) {
        tu_randn(s, G.nlgs * 2 * ns, (unsigned long)(40 + t));
        ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    }
    ck_assert_int_eq(wt_learn_wind_fit(L, &e, 0.002, 0.05, &w), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "at least 7"));
    double map[15 * 15];
    ck_assert_int_eq(wt_learn_lag_map(L, -1, 1, 0, 1, WT_LEARN_XX, map, NULL), WT_OK);
    ck_assert_int_eq(wt_learn_lag_map(L, -1, 1, 0, 1, WT_LEARN_XY, map, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    ck_assert_int_eq(wt_learn_wind_fit(L, &e, 0.0, 0.05, &w), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "frame time"));
    wt_learn_reset(L);
    ck_assert_int_eq(wt_learn_lag_map(L, -1, 0, 0, 1, WT_LEARN_XX, map, NULL), WT_ERR_INVALID);
    wt_learn_free(L);
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 1, 0, &L), WT_OK);
    for (int t = 0; t < 3; t++) ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    ck_assert_int_eq(wt_learn_wind_fit(L, &e, 0.002, 0.05, &w), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "no lagged maps"));
    wt_learn_free(L);
    free(s);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("learn_wind");
    TCase *tw = tcase_create("wind");
    tcase_set_timeout(tw, 120);
    tcase_add_test(tw, test_wind);
    tcase_add_test(tw, test_wind_split);
    tcase_add_test(tw, test_wind_refusals);
    suite_add_tcase(s, tw);
    return s;
}

TU_MAIN
