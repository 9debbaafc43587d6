/* tests/test_night.c: a changing night for the truth (sim/night.h, SPEC §12 "A changing night"): the
 * interpolation of a night file's states (exact at the knots, linear between), the stochastic model's walks
 * (stationary log-variance, correlation, same seed same numbers), the screens' scale, the integration of a
 * changing wind, time compression, the night's keys and the loop's record of the truth's state, and the bad
 * inputs (FILE:LINE messages, nothing allocated). */
#include <unistd.h>

#include "core/config/config.h"
#include "core/io/h5.h"
#include "core/model/system.h"
#include "sim/atmosphere.h"
#include "sim/loop.h"
#include "sim/night.h"
#include "sim/record.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
#define DEG (M_PI / 180.0)

static char dir[64];

static void setup(void)
{
    snprintf(dir, sizeof dir, "/tmp/wtnightXXXXXX");
    ck_assert_ptr_nonnull(mkdtemp(dir));
}

static void teardown(void) { tu_cli_teardown(dir); }

/* dir/name holding text; its path into path */
static const char *put(const char *name, const char *text, char *path, size_t n)
{
    snprintf(path, n, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fputs(text, f);
    fclose(f);
    return path;
}

/* The two-layer reference of the file tests: r0 0.1 m, fractions 0.5/0.5, 10 and 20 m/s towards 0 and 350 deg. */
static const double ref_f[2] = {0.5, 0.5}, ref_v[2] = {10.0, 20.0}, ref_d[2] = {0.0, 350.0 * DEG};

static wt_night_params file_params(const char *path, long frames)
{
    return (wt_night_params){.source = WT_NIGHT_FILE, .nlayers = 2, .r0 = 0.1, .fraction = ref_f, .wind_speed = ref_v,
                             .wind_direction = ref_d, .frame_time = 0.01, .start = 0.0, .compression = 100.0,
                             .frames = frames, .file = path};
}

/* three states; between 100 s and 300 s the first layer turns from 90 to -60 deg (the shorter arc: -150 deg) and
 * the second from 10 to 20 deg; between 0 and 100 s the second turns from 350 to 10 deg (+20 deg across 0) */
static const char THREE[] = "# t r0 | f v d | f v d\n"
                            "0    0.1   0.5 10 0      0.5 20 350\n"
                            "\n"
                            "100  0.2   0.25 20 90    0.75 10 10   # a comment\n"
                            "300  0.15  0.75 10 -60   0.25 30 20\n";

/* ---------------------------------------------------------------------------------------------- */
/* Interpolation */

START_TEST(test_knots_exact)
{
    wt_context *ctx = tu_context();
    char path[256];
    wt_night *n = NULL;
    wt_night_params p = file_params(put("three.txt", THREE, path, sizeof path), 300); /* last frame at 299 s */
    ck_assert_msg(wt_night_alloc(ctx, &p, &n) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_night_nlayers(n), 2);
    const double kt[3] = {0, 100, 300}, kr0[3] = {0.1, 0.2, 0.15};
    const double kf[3][2] = {{0.5, 0.5}, {0.25, 0.75}, {0.75, 0.25}}, kv[3][2] = {{10, 20}, {20, 10}, {10, 30}};
    const double kd[3][2] = {{0, 350}, {90, 10}, {-60, 20}};
    for (int k = 0; k < 3; k++) {
        double r0, f[2], v[2], d[2];
        ck_assert_int_eq(wt_night_state(n, kt[k], &r0, f, v, d), WT_OK);
        /* at a knot its own numbers, bit for bit (these fractions sum to exactly 1) */
        ck_assert(r0 == kr0[k]);
        for (int l = 0; l < 2; l++) {
            ck_assert(f[l] == kf[k][l] && v[l] == kv[k][l]);
            ck_assert(d[l] == kd[k][l] * DEG);
        }
    }
    /* outside the states: refused, naming both ends */
    ck_assert_int_eq(wt_night_state(n, -1.0, NULL, NULL, NULL, NULL), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "0 s to 300 s"));
    ck_assert_int_eq(wt_night_state(n, 300.5, NULL, NULL, NULL, NULL), WT_ERR_INVALID);
    ck_assert_int_eq(wt_night_state(n, NAN, NULL, NULL, NULL, NULL), WT_ERR_INVALID);
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

/* Between the knots every quantity is linear in t: a + w (b − a), the fractions renormalised, the directions
 * along the shorter arc. Tolerance: a few ulps of the values (one rounding each in w, b − a, the product, the
 * sum and the renormalisation). */
START_TEST(test_linear_between)
{
    wt_context *ctx = tu_context();
    char path[256];
    wt_night *n = NULL;
    wt_night_params p = file_params(put("three.txt", THREE, path, sizeof path), 300);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_OK);
    const double eps = 8 * 0x1p-52;
    double r0, f[2], v[2], d[2];
    /* the midpoint of the first interval: the direction 350 → 10 deg passes through 0 (360) */
    ck_assert_int_eq(wt_night_state(n, 50.0, &r0, f, v, d), WT_OK);
    ck_assert_rel(r0, 0.15, eps, 0.0);
    ck_assert_rel(f[0], 0.375, eps, 0.0);
    ck_assert_rel(f[1], 0.625, eps, 0.0);
    ck_assert_rel(v[0], 15.0, eps, 0.0);
    ck_assert_rel(v[1], 15.0, eps, 0.0);
    ck_assert_rel(d[0], 45.0 * DEG, eps, 0.0);
    ck_assert_rel(d[1], 360.0 * DEG, eps, 0.0);
    /* at random times of the second interval against the formula */
    wt_rng rng;
    wt_rng_init(&rng, 11, 0);
    for (int i = 0; i < 50; i++) {
        const double t = 100.0 + 200.0 * wt_rng_uniform(&rng), w = (t - 100.0) / 200.0;
        ck_assert_int_eq(wt_night_state(n, t, &r0, f, v, d), WT_OK);
        ck_assert_rel(r0, 0.2 + w * (0.15 - 0.2), eps, 0.0);
        ck_assert_rel(f[0], 0.25 + w * 0.5, eps, 0.0);
        ck_assert_rel(f[0] + f[1], 1.0, eps, 0.0);
        ck_assert_rel(v[0], 20.0 - 10.0 * w, eps, 0.0);
        ck_assert_rel(v[1], 10.0 + 20.0 * w, eps, 0.0);
        ck_assert_rel(d[0], (90.0 - 150.0 * w) * DEG, eps, M_PI); /* the operands' scale: π */
        ck_assert_rel(d[1], (10.0 + 10.0 * w) * DEG, eps, 0.0);
    }
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* The stochastic model */

#define RW_LAYERS 4
static const double rw_f[RW_LAYERS] = {0.4, 0.3, 0.2, 0.1}, rw_v[RW_LAYERS] = {5, 10, 20, 30},
                    rw_d[RW_LAYERS] = {0.1, 1.0, -2.0, 3.0};

static wt_night_params random_params(uint64_t seed, double tau, double step, double end)
{
    return (wt_night_params){.source = WT_NIGHT_RANDOM, .nlayers = RW_LAYERS, .r0 = 0.15, .fraction = rw_f,
                             .wind_speed = rw_v, .wind_direction = rw_d, .frame_time = 1.0, .start = 0.0,
                             .compression = end / 1000.0, .frames = 1001, .seed = seed, .correlation_time = tau,
                             .step = step, .r0_rms = 0.2, .fraction_rms = 0.3, .wind_speed_rms = 0.25,
                             .wind_direction_rms = 0.15};
}

/* Sample statistics of a unit Ornstein–Uhlenbeck series sampled every step (AR(1) with a = e^{−step/τ}): with N
 * samples, the mean has variance (1 + a)/(1 − a)/N, the sample variance 2 (1 + a²)/(1 − a²)/N and the lag-1
 * correlation about (1 − a²)/N. Bounds: 5 standard deviations (one series of this seed: no retries). */
static void check_unit_walk(const double *x, long N, double a, const char *what)
{
    double m = 0.0, s2 = 0.0, c1 = 0.0;
    for (long i = 0; i < N; i++) m += x[i] / N;
    for (long i = 0; i < N; i++) s2 += (x[i] - m) * (x[i] - m) / N;
    for (long i = 0; i + 1 < N; i++) c1 += (x[i] - m) * (x[i + 1] - m) / (N - 1);
    c1 /= s2;
    const double sm = sqrt((1 + a) / (1 - a) / N), sv = sqrt(2 * (1 + a * a) / (1 - a * a) / N), sc = sqrt((1 - a * a) / N);
    ck_assert_msg(fabs(m) < 5 * sm, "%s: mean %g, bound %g", what, m, 5 * sm);
    ck_assert_msg(fabs(s2 - 1.0) < 5 * sv, "%s: variance %g, expected 1 +- %g", what, s2, 5 * sv);
    ck_assert_msg(fabs(c1 - a) < 5 * sc, "%s: lag-1 correlation %g, expected %g +- %g", what, c1, a, 5 * sc);
}

START_TEST(test_random_stationary)
{
    wt_context *ctx = tu_context();
    const double tau = 20.0, step = 10.0, a = exp(-step / tau);
    const long nk = 100000, burn = 100; /* after 100 steps the start's memory is a^200 = e^-100 */
    wt_night *n = NULL;
    wt_night_params p = random_params(42, tau, step, (double)(nk - 1) * step);
    ck_assert_msg(wt_night_alloc(ctx, &p, &n) == WT_OK, "%s", wt_error_message(ctx));
    const long N = nk - burn;
    double *x = malloc((size_t)N * (2 + 3 * RW_LAYERS) * sizeof *x);
    double r0, f[RW_LAYERS], v[RW_LAYERS], d[RW_LAYERS];
    /* night time 0: the reference itself (its fractions normalised as the atmosphere's are) */
    ck_assert_int_eq(wt_night_state(n, 0.0, &r0, f, v, d), WT_OK);
    ck_assert(r0 == 0.15);
    double fs = 0.0;
    for (int l = 0; l < RW_LAYERS; l++) fs += rw_f[l];
    for (int l = 0; l < RW_LAYERS; l++) ck_assert(f[l] == rw_f[l] / fs && v[l] == rw_v[l] && d[l] == rw_d[l]);
    /* the unit walks recovered at the knots: ln(r0/r0_ref)/σ, ln(v/v_ref)/σ_v, (d − d_ref)/σ_d, and the
     * fractions' log-ratio of two layers, (ln(f_0/f_1) − ln(f_0,ref/f_1,ref))/σ_f = z_0 − z_1 (variance 2) */
    for (long k = burn; k < nk; k++) {
        ck_assert_int_eq(wt_night_state(n, (double)k * step, &r0, f, v, d), WT_OK);
        const long i = k - burn;
        x[i] = log(r0 / 0.15) / 0.2;
        for (int l = 0; l < RW_LAYERS; l++) {
            x[(1 + l) * N + i] = log(v[l] / rw_v[l]) / 0.25;
            x[(1 + RW_LAYERS + l) * N + i] = (d[l] - rw_d[l]) / 0.15;
        }
        x[(1 + 2 * RW_LAYERS) * N + i] = (log(f[0] / f[1]) - log(rw_f[0] / rw_f[1])) / 0.3 / sqrt(2.0);
    }
    check_unit_walk(x, N, a, "ln r0");
    for (int l = 0; l < RW_LAYERS; l++) {
        check_unit_walk(x + (1 + l) * N, N, a, "ln v");
        check_unit_walk(x + (1 + RW_LAYERS + l) * N, N, a, "direction");
    }
    check_unit_walk(x + (1 + 2 * RW_LAYERS) * N, N, a, "ln f0/f1");
    free(x);
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_random_seed)
{
    wt_context *ctx = tu_context();
    wt_night *a = NULL, *b = NULL, *c = NULL, *e = NULL;
    wt_night_params p = random_params(7, 300.0, 10.0, 3600.0);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &a), WT_OK);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &b), WT_OK);
    p.seed = 8;
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &c), WT_OK);
    /* a layer's walk depends on its own streams only: one layer fewer leaves the others' winds unchanged */
    p.seed = 7;
    p.nlayers = RW_LAYERS - 1;
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &e), WT_OK);
    double sa[1 + 3 * RW_LAYERS], sb[1 + 3 * RW_LAYERS], sc[1 + 3 * RW_LAYERS], se[1 + 3 * RW_LAYERS];
    int differ = 0;
    for (double t = 0.0; t <= 3600.0; t += 123.4) {
        double *s[4] = {sa, sb, sc, se};
        wt_night *nn[4] = {a, b, c, e};
        for (int i = 0; i < 4; i++) {
            const int nl = i == 3 ? RW_LAYERS - 1 : RW_LAYERS;
            ck_assert_int_eq(wt_night_state(nn[i], t, s[i], s[i] + 1, s[i] + 1 + nl, s[i] + 1 + 2 * nl), WT_OK);
        }
        ck_assert(memcmp(sa, sb, sizeof sa) == 0); /* same seed, same numbers */
        differ += memcmp(sa, sc, sizeof sa) != 0;
        for (int l = 0; l < RW_LAYERS - 1; l++) {
            ck_assert(sa[1 + RW_LAYERS + l] == se[1 + (RW_LAYERS - 1) + l]);
            ck_assert(sa[1 + 2 * RW_LAYERS + l] == se[1 + 2 * (RW_LAYERS - 1) + l]);
        }
    }
    ck_assert_int_ge(differ, 29); /* every time but 0, where both are the reference */
    wt_night_free(a), wt_night_free(b), wt_night_free(c), wt_night_free(e);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* The truth: screens and winds */

static wt_atmosphere *atm2(wt_context *ctx, double r0, const double *f, const double *v, const double *d)
{
    const double h[2] = {0.0, 8000.0};
    wt_atmosphere_params p = {2, h, f, v, d, r0, 25.0, 64, 0.25, 5, 0};
    wt_atmosphere *a = NULL;
    ck_assert_msg(wt_atmosphere_alloc(ctx, &p, &a) == WT_OK, "%s", wt_error_message(ctx));
    return a;
}

static double rms(const double *x, long n)
{
    double s = 0.0;
    for (long i = 0; i < n; i++) s += x[i] * x[i];
    return sqrt(s / n);
}

/* A screen generated for (r0, f) scaled by g = sqrt(f' r0'^(-5/3) / (f r0^(-5/3))) is the screen of (r0', f')
 * with the same random pattern: the amplitudes √Φ ∝ √f r0^(-5/6) of every frequency. The fresh atmosphere
 * rounds its amplitudes once, the scaled one twice: agreement to 1e-13 relative. */
START_TEST(test_screen_scale)
{
    wt_context *ctx = tu_context();
    const double f0[2] = {0.6, 0.4}, f1[2] = {0.3, 0.7}, v[2] = {10, 20}, d[2] = {0.3, 2.0};
    const double r00 = 0.15, r01 = 0.1;
    wt_atmosphere *a = atm2(ctx, r00, f0, v, d), *b = atm2(ctx, r01, f1, v, d);
    double g[2];
    wt_night_screen_scale(2, r00, f0, r01, f1, g);
    for (int l = 0; l < 2; l++) ck_assert_rel(g[l], sqrt(f1[l] / f0[l] * pow(r01 / r00, -5.0 / 3.0)), 1e-15, 0.0);
    wt_grid t = wt_grid_centred(33, 0.25);
    const long np = 33 * 33;
    double *pa = calloc(np, sizeof *pa), *pb = calloc(np, sizeof *pb), *p1 = calloc(np, sizeof *p1);
    /* layer by layer: one layer's scale alone multiplies its rms by g_l (the other kept at 0) */
    for (int l = 0; l < 2; l++) {
        double s1[2] = {l == 0, l == 1}, sg[2] = {l == 0 ? g[0] : 0.0, l == 1 ? g[1] : 0.0};
        memset(p1, 0, np * sizeof *p1), memset(pa, 0, np * sizeof *pa);
        wt_atmosphere_set_drift(a, s1, NULL, NULL);
        ck_assert_int_eq(wt_atmosphere_project(a, 0.2, 0.0, 1e-4, 0.0, &t, NULL, 1.0, p1), WT_OK);
        wt_atmosphere_set_drift(a, sg, NULL, NULL);
        ck_assert_int_eq(wt_atmosphere_project(a, 0.2, 0.0, 1e-4, 0.0, &t, NULL, 1.0, pa), WT_OK);
        ck_assert_rel(rms(pa, np) / rms(p1, np), g[l], 1e-14, 0.0);
    }
    /* both layers: the OPD of the new state's fresh atmosphere */
    memset(pa, 0, np * sizeof *pa);
    wt_atmosphere_set_drift(a, g, NULL, NULL);
    ck_assert_int_eq(wt_atmosphere_project(a, 0.2, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, pa), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(b, 0.2, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, pb), WT_OK);
    ck_assert_msg(tu_rel_diff(pa, pb, np) < 1e-13, "scaled vs fresh: %g", tu_rel_diff(pa, pb, np));
    /* no drift (NULL): today's bits */
    wt_atmosphere *c = atm2(ctx, r00, f0, v, d);
    wt_atmosphere_set_drift(a, NULL, NULL, NULL);
    memset(pa, 0, np * sizeof *pa), memset(pb, 0, np * sizeof *pb);
    ck_assert_int_eq(wt_atmosphere_project(a, 0.37, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, pa), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(c, 0.37, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, pb), WT_OK);
    ck_assert(memcmp(pa, pb, np * sizeof *pa) == 0);
    free(pa), free(pb), free(p1);
    wt_atmosphere_free(a), wt_atmosphere_free(b), wt_atmosphere_free(c);
    wt_context_free(ctx);
}
END_TEST

/* the projections of two atmospheres at frame time t, batched as the loop does */
static void project2(wt_atmosphere *a, wt_atmosphere *b, double t, double *pa, double *pb)
{
    wt_grid g = wt_grid_centred(33, 0.25);
    wt_atmosphere_los la = {90e3, 2e-4, -1e-4, NULL, pa, 1}, lb = {90e3, 2e-4, -1e-4, NULL, pb, 1};
    ck_assert_int_eq(wt_atmosphere_project_many(a, t, 1, &la, &g, 1.0), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project_many(b, t, 1, &lb, &g, 1.0), WT_OK);
}

/* A night that keeps the reference state (a constant wind, fractions that normalise exactly) moves the layers
 * exactly as frozen flow does today, bit for bit, frame after frame. */
START_TEST(test_wind_constant)
{
    wt_context *ctx = tu_context();
    char path[256];
    const double f[2] = {0.5, 0.5}, v[2] = {10.0, 20.0}, d[2] = {0.0, 350.0 * DEG};
    put("same.txt", "0 0.1 0.5 10 0 0.5 20 350\n1000 0.1 0.5 10 0 0.5 20 350\n", path, sizeof path);
    wt_night *n = NULL;
    wt_night_params p = file_params(path, 100);
    p.compression = 7.3;
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_OK);
    wt_atmosphere *a = atm2(ctx, 0.1, f, v, d), *b = atm2(ctx, 0.1, f, v, d);
    const long np = 33 * 33;
    double *pa = calloc(np, sizeof *pa), *pb = calloc(np, sizeof *pb);
    for (long j = 0; j < 100; j += 1 + j / 10) { /* skipped frames too */
        ck_assert_int_eq(wt_night_drive(n, a, j), WT_OK);
        project2(a, b, (double)j * p.frame_time, pa, pb);
        ck_assert_msg(memcmp(pa, pb, np * sizeof *pa) == 0, "frame %ld", j);
        wt_night_sample s = wt_night_current(n);
        ck_assert(s.t == (double)j * 0.01 * 7.3 && s.r0 == 0.1 && s.nlayers == 2 && s.wind_speed[1] == 20.0);
    }
    ck_assert_int_eq(wt_night_drive(n, a, 5), WT_ERR_INVALID); /* back in time */
    free(pa), free(pb);
    wt_atmosphere_free(a), wt_atmosphere_free(b);
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

/* A changing wind is integrated frame by frame, D(j) = Σ_{i<j} (v(t_i) − v_ref) Δt: with the speed ramping from
 * 10 to 30 m/s over the night and the direction kept, the layer is where one moving at the mean speed
 * Σ_{i<j} v(t_i) Δt / t_j is at t_j. Positions agree to ~1e-12 m (sums of j terms), the OPD to 1e-9. The
 * state of frame j is that of night time start + j Δt c (time compression). */
START_TEST(test_wind_changing)
{
    wt_context *ctx = tu_context();
    char path[256];
    const double f[2] = {0.5, 0.5}, v[2] = {10.0, 20.0}, d[2] = {0.0, 350.0 * DEG};
    put("ramp.txt", "0 0.1 0.5 10 0 0.5 20 350\n1000 0.1 0.5 30 0 0.5 20 350\n", path, sizeof path);
    wt_night *n = NULL;
    wt_night_params p = file_params(path, 1001);
    p.start = 0.5, p.compression = 50.0; /* night time 0.5 + 0.5 j s */
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_OK);
    wt_atmosphere *a = atm2(ctx, 0.1, f, v, d);
    const long np = 33 * 33;
    double *pa = calloc(np, sizeof *pa), *pb = calloc(np, sizeof *pb), sum = 0.0;
    for (long j = 0; j <= 1000; j++) {
        ck_assert_int_eq(wt_night_drive(n, a, j), WT_OK);
        wt_night_sample s = wt_night_current(n);
        const double tn = 0.5 + (double)j * 0.01 * 50.0;
        ck_assert(s.t == tn);
        ck_assert_rel(s.wind_speed[0], 10.0 + 20.0 * tn / 1000.0, 1e-14, 0.0);
        if (j % 250 == 0 && j > 0) {
            const double t = (double)j * 0.01, vm[2] = {sum / t, 20.0};
            wt_atmosphere *b = atm2(ctx, 0.1, f, vm, d);
            project2(a, b, t, pa, pb);
            ck_assert_msg(tu_rel_diff(pa, pb, np) < 1e-9, "frame %ld: %g", j, tu_rel_diff(pa, pb, np));
            wt_atmosphere_free(b);
        }
        sum += s.wind_speed[0] * 0.01;
    }
    free(pa), free(pb);
    wt_atmosphere_free(a);
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Bad input */

START_TEST(test_bad_files)
{
    wt_context *ctx = tu_context();
    const struct {
        const char *text, *want[3];
        long frames; /* the run: frames of 1 s at night time (frames − 1) */
        int status;
    } cases[] = {
        {"0 0.1 0.5 10 0 0.5 20 350\n50 0.1 0.5 10 0 0.5 20 350\n", {"x.txt:2:", "at 50 s", "299 s"}, 300, WT_ERR_CONFIG},
        {"10 0.1 0.5 10 0 0.5 20 350\n500 0.1 0.5 10 0 0.5 20 350\n", {"x.txt:1:", "at 10 s", "first night time 0 s"}, 300,
         WT_ERR_CONFIG},
        {"0 0.1 -0.5 10 0 1.5 20 350\n", {"x.txt:1:", "layer 1", "negative"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.5 20 350\n5 0 0.5 10 0 0.5 20 350\n", {"x.txt:2:", "r0 = 0 m"}, 1, WT_ERR_CONFIG},
        {"0 -0.1 0.5 10 0 0.5 20 350\n", {"x.txt:1:", "r0 = -0.1 m"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.5 20 350\n0 0.1 0.5 10 0 0.5 20 350\n", {"x.txt:2:", "not after the previous", "line 1"}, 1,
         WT_ERR_CONFIG},
        {"# three layers\n0 0.1 0.4 10 0 0.3 20 350 0.3 5 5\n", {"x.txt:2:", "11 columns; expected 8", "2 layers"}, 1,
         WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.5 20\n", {"x.txt:1:", "7 columns; expected 8"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 nan 0 0.5 20 350\n", {"x.txt:1:", "column 4", "'nan' is not a finite number"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.5 20 abc\n", {"x.txt:1:", "column 8", "'abc'"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.4 20 350\n", {"x.txt:1:", "sum to 0.9"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 -10 0 0.5 20 350\n", {"x.txt:1:", "wind speed -10 m/s is negative"}, 1, WT_ERR_CONFIG},
        {"0 0.1 0.5 10 0 0.5 20 400\n", {"x.txt:1:", "layer 2", "400 deg"}, 1, WT_ERR_CONFIG},
        {"# nothing\n\n", {"x.txt: no state"}, 1, WT_ERR_CONFIG},
    };
    char path[256];
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        put("x.txt", cases[i].text, path, sizeof path);
        wt_night_params p = file_params(path, cases[i].frames);
        p.frame_time = 1.0, p.compression = 1.0;
        wt_night *n = (wt_night *)&p;
        ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), cases[i].status);
        ck_assert_ptr_null(n);
        for (int k = 0; k < 3 && cases[i].want[k]; k++)
            ck_assert_msg(strstr(wt_error_message(ctx), cases[i].want[k]), "case %zu: '%s' not in: %s", i,
                          cases[i].want[k], wt_error_message(ctx));
    }
    /* a layer whose configured fraction is 0 cannot gain power: its screen is zero */
    const double fz[2] = {1.0, 0.0};
    put("x.txt", "0 0.1 1 10 0 0 20 350\n100 0.1 0.9 10 0 0.1 20 350\n", path, sizeof path);
    wt_night_params p = file_params(path, 10);
    p.fraction = fz;
    wt_night *n = NULL;
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "x.txt:2: layer 2"));
    /* a missing file */
    p = file_params("/nonexistent/night.txt", 10);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "/nonexistent/night.txt"));
    /* bad parameters */
    p = random_params(1, 0.0, 10.0, 100.0);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_ERR_INVALID);
    p = random_params(1, 100.0, 1e-6, 1e6); /* 1e12 knots */
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "step too small"));
    /* the drive: an atmosphere of other layers */
    p = random_params(1, 100.0, 10.0, 100.0);
    ck_assert_int_eq(wt_night_alloc(ctx, &p, &n), WT_OK);
    wt_atmosphere *a = atm2(ctx, 0.1, ref_f, ref_v, ref_d);
    ck_assert_int_eq(wt_night_drive(n, a, 0), WT_ERR_INVALID);
    wt_atmosphere_free(a);
    wt_night_free(n);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    char path[256];
    put("three.txt", THREE, path, sizeof path);
    int failures = 0;
    for (int src = 0; src < 2; src++)
        for (int k = 0; k < 40; k++) {
            tu_alloc_budget(&fa, k);
            wt_night_params p = src ? random_params(3, 100.0, 10.0, 500.0) : file_params(path, 300);
            wt_night *n = NULL;
            int st = wt_night_alloc(ctx, &p, &n);
            if (st == WT_OK) {
                wt_night_free(n);
                break;
            }
            failures++;
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            ck_assert_ptr_null(n);
            ck_assert_int_eq(fa.live, 0);
        }
    tu_alloc_budget(&fa, -1);
    ck_assert(failures >= 20);
    ck_assert_int_eq(fa.live, 0);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* The keys and the loop */

START_TEST(test_keys)
{
    wt_context *ctx = tu_context();
    wt_config *base = NULL, *c = NULL;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 0, NULL, &base), WT_OK);
    ck_assert_int_eq(base->night.source, WT_NIGHT_CFG_NONE);
    ck_assert_ptr_null(strstr(base->canonical, "night")); /* no night: today's canonical text */
    /* the night changes the truth only: never the matrix identity */
    const char *rnd[] = {"atmosphere.night.source=\"random\"", "atmosphere.night.r0_log_rms=0.5",
                         "atmosphere.night.compression=100.0", "atmosphere.night.seed=9"};
    ck_assert_msg(wt_config_read(ctx, DEMO, 4, rnd, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(c->matrix_sha256, base->matrix_sha256);
    ck_assert_ptr_nonnull(strstr(c->canonical, "night"));
    ck_assert(c->night.source == WT_NIGHT_CFG_RANDOM && c->night.r0_rms == 0.5 && c->night.seed == 9);
    ck_assert(c->night.step == 10.0 && c->night.correlation_time == 1800.0 && c->night.start == 0.0);
    ck_assert_rel(c->night.wind_direction_rms, 10.0 * DEG, 1e-15, 0.0);
    wt_config_free(ctx, c);
    ck_assert_msg(wt_config_read(ctx, "data/presets/demo-night.cfg", 0, NULL, &c) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(c->matrix_sha256, base->matrix_sha256);
    ck_assert(c->night.source == WT_NIGHT_CFG_FILE && c->night.compression == 3000.0);
    ck_assert_ptr_nonnull(strstr(c->night.file, "demo-ground-doubling.txt"));
    wt_config_free(ctx, c);
    /* keys that do not go together */
    const struct {
        const char *ov[3], *want;
    } bad[] = {
        {{"atmosphere.night.source=\"file\""}, "key 'atmosphere.night.file' is missing"},
        {{"atmosphere.night.start_s=10.0"}, "means nothing without a night"},
        {{"atmosphere.night.source=\"random\"", "atmosphere.night.file=\"x.txt\""}, "is the states of source = \"file\""},
        {{"atmosphere.night.source=\"file\"", "atmosphere.night.file=\"x.txt\"", "atmosphere.night.step_s=5.0"},
         "a key of the stochastic night"},
        {{"atmosphere.night.compression=0.0"}, "atmosphere.night.compression"},
        {{"atmosphere.night.source=\"sometimes\""}, "atmosphere.night.source"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        c = NULL;
        const int nov = bad[i].ov[2] ? 3 : bad[i].ov[1] ? 2 : 1;
        ck_assert_int_eq(wt_config_read(ctx, DEMO, nov, bad[i].ov, &c), WT_ERR_CONFIG);
        ck_assert_ptr_null(c);
        ck_assert_msg(strstr(wt_error_message(ctx), bad[i].want), "case %zu: %s", i, wt_error_message(ctx));
    }
    wt_config_free(ctx, base);
    wt_context_free(ctx);
}
END_TEST

/* Closed loops on the demo: a night that keeps the configured state gives today's commands bit for bit; the
 * demo night's loop exposes and records the truth's state of every frame. */
typedef struct {
    wt_config *cfg;
    wt_system *sys;
    wt_loop *lp;
} demo_loop;

static demo_loop demo_open(wt_context *ctx, const char *path, int nset, const char *const *set)
{
    demo_loop d = {0};
    ck_assert_msg(wt_config_read(ctx, path, nset, set, &d.cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, d.cfg, &d.sys) == WT_OK, "%s", wt_error_message(ctx));
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = d.cfg->seed, .noise = d.cfg->noise};
    ck_assert_msg(wt_loop_alloc(ctx, d.sys, &o, &d.lp) == WT_OK, "%s", wt_error_message(ctx));
    return d;
}

static void demo_close(wt_context *ctx, demo_loop *d)
{
    wt_loop_free(d->lp);
    wt_system_free(d->sys);
    wt_config_free(ctx, d->cfg);
}

START_TEST(test_loop_static_night)
{
    wt_context *ctx = tu_context();
    char path[256], ov[300];
    put("demo-static.txt",
        "0    0.129  0.55 8 0  0.1 10 72  0.1 12 144  0.15 18 216  0.1 25 288\n"
        "1e4  0.129  0.55 8 0  0.1 10 72  0.1 12 144  0.15 18 216  0.1 25 288\n",
        path, sizeof path);
    snprintf(ov, sizeof ov, "atmosphere.night.file=\"%s\"", path);
    const char *plain[] = {"loop.frames=8", "evaluation.settle_frames=2"};
    const char *night[] = {"loop.frames=8", "evaluation.settle_frames=2", "atmosphere.night.source=\"file\"", ov,
                           "atmosphere.night.compression=500.0"};
    demo_loop a = demo_open(ctx, DEMO, 2, plain), b = demo_open(ctx, DEMO, 5, night);
    wt_night_sample s;
    ck_assert_int_eq(wt_loop_truth_state(a.lp, &s), 0);
    for (int t = 0; t < 8; t++) {
        ck_assert_int_eq(wt_loop_step(a.lp), WT_OK);
        ck_assert_int_eq(wt_loop_step(b.lp), WT_OK);
        ck_assert(memcmp(wt_loop_applied(a.lp), wt_loop_applied(b.lp), a.sys->nact * sizeof(double)) == 0);
        ck_assert(memcmp(wt_loop_slopes(a.lp), wt_loop_slopes(b.lp), a.sys->nslopes * sizeof(double)) == 0);
        ck_assert_int_eq(wt_loop_truth_state(b.lp, &s), 1);
        ck_assert(s.t == t * 0.002 * 500.0 && s.r0 == 0.129 && s.fraction[0] == 0.55);
    }
    demo_close(ctx, &a);
    demo_close(ctx, &b);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_loop_record)
{
    wt_context *ctx = tu_context();
    const char *set[] = {"loop.frames=6", "evaluation.settle_frames=2", "atmosphere.night.start_s=600.0"};
    demo_loop d = demo_open(ctx, "data/presets/demo-night.cfg", 3, set);
    wt_sim_record *rec = NULL;
    ck_assert_int_eq(wt_sim_record_alloc(ctx, d.sys, 6, d.cfg->eval_wavelength, NULL, &rec), WT_OK);
    /* the night of the loop's configuration, evaluated on its own */
    wt_loop_params par;
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1};
    wt_loop_params_from_config(d.cfg, &o, &par);
    wt_night *n = NULL;
    ck_assert_int_eq(wt_night_alloc(ctx, &par.night, &n), WT_OK);
    const int nl = d.cfg->nlayers;
    double r0[6], f[6][5], v[6][5], dd[6][5];
    for (int t = 0; t < 6; t++) {
        ck_assert_int_eq(wt_loop_step(d.lp), WT_OK);
        ck_assert_int_eq(wt_sim_record_frame(rec, d.lp, 0.0), WT_OK);
        ck_assert_int_eq(wt_night_state(n, 600.0 + t * 0.002 * 3000.0, &r0[t], f[t], v[t], dd[t]), WT_OK);
    }
    ck_assert(r0[5] < r0[0] && f[5][0] > f[0][0] && v[5][4] > v[0][4]); /* the ground grows, the jet speeds up */
    char path[256];
    snprintf(path, sizeof path, "%s/run.h5", dir);
    wt_h5_writer *w = NULL;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_msg(wt_sim_record_write(rec, w, d.lp, 2) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    wt_h5_reader *r = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, path, &r), WT_OK);
    double rt[6], rr0[6], rf[30], rv[30], rd[30];
    int64_t e1[1] = {6}, e2[2] = {6, nl};
    ck_assert_int_eq(wt_h5_read(r, "frame/night_time", WT_H5_F64, 1, e1, NULL, rt, 6), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "frame/r0", WT_H5_F64, 1, e1, NULL, rr0, 6), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "frame/cn2_fractions", WT_H5_F64, 2, e2, NULL, rf, 30), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "frame/wind_speed", WT_H5_F64, 2, e2, NULL, rv, 30), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "frame/wind_direction", WT_H5_F64, 2, e2, NULL, rd, 30), WT_OK);
    for (int t = 0; t < 6; t++) {
        ck_assert(rt[t] == 600.0 + t * 0.002 * 3000.0 && rr0[t] == r0[t]);
        for (int l = 0; l < nl; l++) {
            ck_assert(rf[t * nl + l] == f[t][l] && rv[t * nl + l] == v[t][l]);
            ck_assert_rel(rd[t * nl + l], dd[t][l] / DEG, 1e-15, 1e-12);
        }
    }
    wt_h5_close(r);
    wt_night_free(n);
    wt_sim_record_free(rec);
    demo_close(ctx, &d);
    wt_context_free(ctx);
}
END_TEST

/* The demo night's preset cannot run past its night: the message names the file, both times. */
START_TEST(test_loop_not_covered)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_loop *lp = NULL;
    const char *set[] = {"atmosphere.night.compression=1e5"};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo-night.cfg", 1, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_loop_options o = {.recon = WT_RECON_NONE, .iterations = -1, .seed = 1};
    ck_assert_int_eq(wt_loop_alloc(ctx, sys, &o, &lp), WT_ERR_CONFIG);
    ck_assert_ptr_null(lp);
    const char *m = wt_error_message(ctx);
    ck_assert_msg(strstr(m, "demo-ground-doubling.txt:") && strstr(m, "at 3600 s") && strstr(m, "39800 s"), "%s", m);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("night");
    TCase *tc = tcase_create("core");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_knots_exact);
    tcase_add_test(tc, test_linear_between);
    tcase_add_test(tc, test_random_stationary);
    tcase_add_test(tc, test_random_seed);
    tcase_add_test(tc, test_screen_scale);
    tcase_add_test(tc, test_wind_constant);
    tcase_add_test(tc, test_wind_changing);
    tcase_add_test(tc, test_bad_files);
    tcase_add_test(tc, test_alloc_failure);
    tcase_add_test(tc, test_keys);
    tcase_add_test(tc, test_loop_static_night);
    tcase_add_test(tc, test_loop_record);
    tcase_add_test(tc, test_loop_not_covered);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
