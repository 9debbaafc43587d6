/* tests/test_atmosphere.c: the simulated atmosphere (SPEC §2, §3): von Kármán structure function of the
 * screens against quadrature theory, subharmonics, determinism, frozen flow and periodic wrap, variance per Cn²
 * fraction, bad input and allocation failure (the line-of-sight projection: test_atmosphere_project.c).
 *
 * Set WT_TEST_VERBOSE=1 to print the structure-function tables. */
#include "atmosphere_fixture.h"

#define LAMBDA0 500e-9

static int verbose(void) { return getenv("WT_TEST_VERBOSE") != NULL; }

/* ---------------------------------------------------------------------------------------------- */
/* Theory */

/* Φ(κ) for a unit fraction [m² per (cycles/m)²]. */
static double psd(double kappa2, double r0, double L0)
{
    double c = pow(LAMBDA0 / (2.0 * M_PI), 2) * 0.0229 * pow(r0, -5.0 / 3.0);
    double k02 = isinf(L0) ? 0.0 : 1.0 / (L0 * L0);
    return c * pow(kappa2 + k02, -11.0 / 6.0);
}

/* D(r) = 2 ∫ (1 − J0(2πκr)) Φ(κ) 2πκ dκ. Simpson on a log grid for κr ∈ [1e-12, 1] (the integrand
 * there is smooth in log κ; below 1e-12 it contributes < (1e-12)^(1/3) = 1e-4 relative even for
 * Kolmogorov), Simpson on a linear grid for κr ∈ [1, 2000] (step 0.02 in κr: ≤ 0.13 rad of J0's
 * phase), and the tail beyond κr = 2000 where 1 − J0 averages to 1: 4πC·(3/5)·K^(−5/3), whose
 * neglected J0 part is ≲ 1e-2 of a 1e-5 relative tail. */
static double vk_structure(double r, double r0, double L0)
{
    double s1 = 0.0, s2 = 0.0;
    const int N = 4000, M = 100000;
    double a = log(1e-12 / r), b = log(1.0 / r), h = (b - a) / N;
    for (int i = 0; i <= N; i++) {
        double k = exp(a + i * h);
        double g = 4.0 * M_PI * k * k * (1.0 - j0(2.0 * M_PI * k * r)) * psd(k * k, r0, L0);
        s1 += g * ((i == 0 || i == N) ? 1 : (i % 2 ? 4 : 2));
    }
    s1 *= h / 3.0;
    double K = 2000.0 / r, h2 = (K - 1.0 / r) / M;
    for (int i = 0; i <= M; i++) {
        double k = 1.0 / r + i * h2;
        double g = 4.0 * M_PI * k * (1.0 - j0(2.0 * M_PI * k * r)) * psd(k * k, r0, L0);
        s2 += g * ((i == 0 || i == M) ? 1 : (i % 2 ? 4 : 2));
    }
    s2 *= h2 / 3.0;
    double c = pow(LAMBDA0 / (2.0 * M_PI), 2) * 0.0229 * pow(r0, -5.0 / 3.0);
    return s1 + s2 + 4.0 * M_PI * c * 0.6 * pow(K, -5.0 / 3.0);
}

/* The quadrature itself: Kolmogorov limit D = 6.88 (λ0/2π)² (r/r0)^(5/3) (6.88 is 0.0229's
 * constant to 0.1 %: 2[(24/5)Γ(6/5)]^(5/6) = 6.8839), and the von Kármán saturation D(∞) = 2σ² with
 * σ² = ∫Φ d²κ = π C (6/5) L0^(5/3) in closed form. */
START_TEST(test_theory_quadrature)
{
    const double r0 = 0.129, s = pow(LAMBDA0 / (2.0 * M_PI), 2);
    for (double r = 0.05; r < 6.0; r *= 10.0) {
        double kol = 6.8839 * s * pow(r / r0, 5.0 / 3.0);
        ck_assert_rel(vk_structure(r, r0, INFINITY), kol, 2e-3, 0.0);
    }
    const double L0 = 25.0, c = s * 0.0229 * pow(r0, -5.0 / 3.0);
    double sigma2 = M_PI * c * 1.2 * pow(L0, 5.0 / 3.0);
    /* At r = 100 L0 the covariance is ~e^(−2π·100)-small. */
    ck_assert_rel(vk_structure(100.0 * L0, r0, L0), 2.0 * sigma2, 2e-3, 0.0);
    /* And it is well below saturation, and below Kolmogorov, at r = L0/10. */
    double d = vk_structure(2.5, r0, L0);
    ck_assert(d < 0.8 * 2.0 * sigma2 && d < 6.8839 * s * pow(2.5 / r0, 5.0 / 3.0));
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Helpers */

/* D[m] += mean over non-wrapped pairs along x and y of (s(x + mδ) − s(x))², m = 1..mmax. */
static void structure_function(const double *s, int n, int mmax, double *D)
{
    for (int m = 1; m <= mmax; m++) {
        double acc = 0.0;
        for (int j = 0; j < n; j++)
            for (int i = 0; i + m < n; i++) {
                double a = s[i + m + (long)n * j] - s[i + (long)n * j];
                double b = s[j + (long)n * (i + m)] - s[j + (long)n * i];
                acc += a * a + b * b;
            }
        D[m] = acc / (2.0 * n * (n - m));
    }
}

/* Mean and standard error over `nseeds` independent screens of D(mδ), m = 1..n/8. */
static void measure_sf(wt_context *ctx, int n, double delta, double L0, int nosh, int nseeds, uint64_t seed0,
                       double *mean, double *se)
{
    int mmax = n / 8;
    double *s = malloc(sizeof(double) * n * n), *D = calloc(mmax + 1, sizeof *D);
    double *s2 = calloc(mmax + 1, sizeof *s2);
    for (int m = 0; m <= mmax; m++) mean[m] = 0.0;
    for (int k = 0; k < nseeds; k++) {
        atm_setup su = one_layer(n, delta, L0, 0.0, 0.0, 0.0, seed0 + k, nosh);
        wt_atmosphere *atm = make_atm(ctx, &su);
        wt_atmosphere_layer_render(atm, 0, s);
        structure_function(s, n, mmax, D);
        for (int m = 1; m <= mmax; m++) mean[m] += D[m], s2[m] += D[m] * D[m];
        wt_atmosphere_free(atm);
    }
    for (int m = 1; m <= mmax; m++) {
        mean[m] /= nseeds;
        se[m] = sqrt(fmax(s2[m] / nseeds - mean[m] * mean[m], 0.0) / (nseeds - 1));
    }
    free(s), free(D), free(s2);
}

/* ---------------------------------------------------------------------------------------------- */
/* Structure function (SPEC §2) */

/* SPEC §2: mean D(r) within 10 % of theory for 2δ ≤ r ≤ L/8. Two screens: L = 32 m ≈ L0 (the
 * low-frequency end matters) and L = 128 m ≈ 5 L0 (the E-ELT ratio, 120 m screens). 48 screens give a
 * standard error ≤ 2.5 % at L/8 (see the table): the 10 % bound leaves room for the FFT method's
 * known few-% bias (missing power beyond Nyquist at r = 2δ: ~3 %). */
static void check_sf(int n, double delta, double L0)
{
    wt_context *ctx = tu_context();
    const int nseeds = 48, mmax = n / 8;
    double mean[64], se[64];
    measure_sf(ctx, n, delta, L0, 0, nseeds, 1000, mean, se);
    if (verbose()) printf("structure function n = %d, delta = %g m, L = %g m, L0 = %g m, %d screens\n"
                          "   r [m]   D_meas/D_th   std err\n", n, delta, n * delta, L0, nseeds);
    for (int m = 2; m <= mmax; m++) {
        double th = vk_structure(m * delta, 0.129, L0);
        if (verbose() && (m & (m - 1)) == 0) printf("%8.3f   %10.4f   %8.4f\n", m * delta, mean[m] / th, se[m] / th);
        ck_assert_msg(fabs(mean[m] / th - 1.0) < 0.10, "r = %g m: D_meas / D_theory = %.4f (std err %.4f)",
                      m * delta, mean[m] / th, se[m] / th);
        ck_assert(se[m] / th < 0.04); /* the comparison has the power it claims */
    }
    wt_context_free(ctx);
}

START_TEST(test_structure_function_small) { check_sf(256, 0.125, 25.0); }
END_TEST

START_TEST(test_structure_function_large) { check_sf(256, 0.5, 25.0); }
END_TEST

/* The subharmonics matter. With L0 = 100 m ≫ L = 32 m the grid part misses the power below 1/L; at
 * r = L/8 the expected structure functions are exact discrete sums,
 *   grid:  Σ_k 2 Φ_k Δκ² (1 − cos 2π κ_x r),   subharmonics:  Σ_pmn 2 Φ_pmn Δκ_p² (1 − cos 2π κ_x r),
 * (x direction; y is the same by symmetry). The grid sum falls > 10 % short of von Kármán and grid +
 * subharmonic sums are within 3 % of it (what Lane's 3 levels can do here). The screens must match
 * both sums: the grid part (wt_atmosphere_layer_data) and the subharmonic part (the rendered screen
 * minus the grid part, same screens) within 4 standard errors over 192 screens + 1 % (the
 * subharmonic part has only 24 random terms per screen, hence many screens: its standard error is
 * then ~7 % of itself). */
START_TEST(test_subharmonics_matter)
{
    wt_context *ctx = tu_context();
    const int n = 128, nseeds = 192, m = n / 8;
    const double delta = 0.25, L0 = 100.0, r = m * delta, dk = 1.0 / (n * delta);
    double grid_th = 0.0, sh_th = 0.0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            int kx = i <= n / 2 ? i : i - n, ky = j <= n / 2 ? j : j - n;
            if (!kx && !ky) continue;
            double w = psd(dk * dk * ((double)kx * kx + (double)ky * ky), 0.129, L0) * dk * dk;
            grid_th += 2.0 * w * (1.0 - cos(2.0 * M_PI * kx * dk * r));
        }
    for (int p = 1; p <= 3; p++) {
        double kp = dk / pow(3.0, p);
        for (int ky = -1; ky <= 1; ky++)
            for (int kx = -1; kx <= 1; kx++) {
                if (!kx && !ky) continue;
                double w = psd(kp * kp * (kx * kx + ky * ky), 0.129, L0) * kp * kp;
                sh_th += 2.0 * w * (1.0 - cos(2.0 * M_PI * kx * kp * r));
            }
    }
    const double th = vk_structure(r, 0.129, L0);
    double *full = malloc(sizeof(double) * n * n), D[2][64];
    double sg = 0, sg2 = 0, ss = 0, ss2 = 0, sf = 0;
    for (int k = 0; k < nseeds; k++) {
        atm_setup su = one_layer(n, delta, L0, 0.0, 0.0, 0.0, 2000 + k, 0);
        wt_atmosphere *atm = make_atm(ctx, &su);
        wt_atmosphere_layer_render(atm, 0, full);
        structure_function(full, n, m, D[0]);
        structure_function(wt_atmosphere_layer_data(atm, 0), n, m, D[1]);
        double g = D[1][m], sh = D[0][m] - D[1][m]; /* E[sh] = the subharmonic D: the parts are independent */
        sg += g, sg2 += g * g, ss += sh, ss2 += sh * sh, sf += D[0][m];
        wt_atmosphere_free(atm);
    }
    free(full);
    double mg = sg / nseeds, ms = ss / nseeds, mf = sf / nseeds;
    double seg = sqrt((sg2 / nseeds - mg * mg) / (nseeds - 1)), ses = sqrt((ss2 / nseeds - ms * ms) / (nseeds - 1));
    if (verbose())
        printf("subharmonics, L0 = %g m, r = L/8 = %g m, ratios to von Karman: grid part %.4f (expected %.4f, se "
               "%.4f), subharmonic part %.4f (expected %.4f, se %.4f), whole %.4f\n",
               L0, r, mg / th, grid_th / th, seg / th, ms / th, sh_th / th, ses / th, mf / th);
    ck_assert_msg(grid_th / th < 0.90, "grid-only expectation %.4f of theory", grid_th / th);
    ck_assert_msg(fabs((grid_th + sh_th) / th - 1.0) < 0.03, "grid + subharmonics expectation %.4f of theory",
                  (grid_th + sh_th) / th);
    ck_assert_msg(fabs(mg - grid_th) < 4.0 * seg + 0.01 * grid_th, "grid part %.4g vs expected %.4g", mg, grid_th);
    ck_assert_msg(fabs(ms - sh_th) < 4.0 * ses + 0.01 * sh_th, "subharmonic part %.4g vs expected %.4g", ms, sh_th);
    ck_assert_msg(fabs(mf / th - 1.0) < 0.10, "with subharmonics %.4f of theory", mf / th);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Determinism */


START_TEST(test_determinism)
{
    wt_context *ctx = tu_context();
    atm_setup s = three_layers(7);
    wt_atmosphere *a = make_atm(ctx, &s), *b = make_atm(ctx, &s);
    s.seed = 8;
    wt_atmosphere *c = make_atm(ctx, &s);
    const long nn = 128 * 128;
    double *ra = malloc(nn * sizeof *ra), *rb = malloc(nn * sizeof *rb);
    for (int l = 0; l < 3; l++) {
        ck_assert(memcmp(wt_atmosphere_layer_data(a, l), wt_atmosphere_layer_data(b, l), nn * sizeof(double)) == 0);
        wt_atmosphere_layer_render(a, l, ra);
        wt_atmosphere_layer_render(b, l, rb);
        ck_assert(memcmp(ra, rb, nn * sizeof(double)) == 0);
        /* another seed: an independent screen, ‖a − c‖ ≈ √2 ‖a‖ */
        ck_assert(tu_rel_diff(wt_atmosphere_layer_data(c, l), wt_atmosphere_layer_data(a, l), nn) > 0.5);
    }
    /* projections: bit-identical between the twins and between 1 and 2 threads */
    wt_grid t = wt_grid_centred(97, 0.125);
    long np = 97 * 97;
    double *p1 = calloc(np, sizeof *p1), *p2 = calloc(np, sizeof *p2), *p3 = calloc(np, sizeof *p3);
    wt_context_set_threads(ctx, 1);
    ck_assert_int_eq(wt_atmosphere_project(a, 0.31, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, p1), WT_OK);
    wt_context_set_threads(ctx, 2);
    ck_assert_int_eq(wt_atmosphere_project(b, 0.31, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, p2), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(a, 0.31, 90e3, 1e-4, -2e-4, &t, NULL, 1.0, p3), WT_OK);
    ck_assert(memcmp(p1, p2, np * sizeof *p1) == 0);
    ck_assert(memcmp(p1, p3, np * sizeof *p1) == 0);
    ck_assert(rms(p1, np) > 0.0);
    free(ra), free(rb), free(p1), free(p2), free(p3);
    wt_atmosphere_free(a), wt_atmosphere_free(b), wt_atmosphere_free(c);
    wt_context_free(ctx);
}
END_TEST

/* Layer ℓ comes from stream (seed, ℓ) alone: with 3 or 5 layers (other fractions) the same seed gives the
 * same unit screen, scaled by √f_ℓ; the grid part is the same with subharmonics on or off. Both are
 * the same products in the same order divided by different √f: agreement to 1e-14. */
START_TEST(test_stream_per_layer)
{
    wt_context *ctx = tu_context();
    atm_setup s3 = three_layers(11), s5 = three_layers(11), s3n = three_layers(11);
    s5.nl = 5;
    const double f5[5] = {0.1, 0.1, 0.1, 0.3, 0.4};
    for (int l = 0; l < 5; l++) s5.f[l] = f5[l], s5.h[l] = 1000.0 * l, s5.v[l] = 5, s5.dir[l] = 0;
    s3n.nosh = 1;
    wt_atmosphere *a = make_atm(ctx, &s3), *b = make_atm(ctx, &s5), *c = make_atm(ctx, &s3n);
    const long nn = 128 * 128;
    double *x = malloc(nn * sizeof *x), *y = malloc(nn * sizeof *y);
    for (int l = 0; l < 3; l++) {
        double fa = wt_atmosphere_layer_fraction(a, l), fb = wt_atmosphere_layer_fraction(b, l);
        ck_assert_rel(fb, f5[l], 1e-15, 0.0);
        wt_atmosphere_layer_render(a, l, x);
        wt_atmosphere_layer_render(b, l, y);
        for (long i = 0; i < nn; i++) x[i] /= sqrt(fa), y[i] /= sqrt(fb);
        ck_assert(tu_rel_diff(x, y, nn) < 1e-14);
        ck_assert(memcmp(wt_atmosphere_layer_data(a, l), wt_atmosphere_layer_data(c, l), nn * sizeof(double)) == 0);
    }
    free(x), free(y);
    wt_atmosphere_free(a), wt_atmosphere_free(b), wt_atmosphere_free(c);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Frozen flow and periodic wrap */

/* Grid part only, target = the screen grid, wind shift v t = (3δ, −5δ): out(i, j) = screen(i − 3, j + 5)
 * with the indices wrapped, at every point (the wrap included). Sample points sit on grid nodes up to
 * rounding of ~1e-13 cells, so values agree to 1e-12 of the rms. */
START_TEST(test_frozen_flow_integer_shift)
{
    wt_context *ctx = tu_context();
    const int n = 128;
    const double delta = 0.125, t = 0.02, sx = 3 * delta, sy = -5 * delta;
    atm_setup s = one_layer(n, delta, 25.0, 6000.0, hypot(sx, sy) / t, atan2(sy, sx), 5, 1);
    wt_atmosphere *atm = make_atm(ctx, &s);
    wt_grid g = wt_atmosphere_grid(atm);
    double *out = calloc((long)n * n, sizeof *out), *ref = malloc((long)n * n * sizeof *ref);
    const double *scr = wt_atmosphere_layer_data(atm, 0);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) ref[i + n * j] = scr[(i - 3 + n) % n + n * ((j + 5) % n)];
    ck_assert_int_eq(wt_atmosphere_project(atm, t, 0.0, 0.0, 0.0, &g, NULL, 1.0, out), WT_OK);
    ck_assert(max_abs_diff(out, ref, (long)n * n) <= 1e-12 * rms(ref, (long)n * n));
    free(out), free(ref);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* Frozen flow with subharmonics, any (non-integer) shift: projecting at t equals projecting at 0 with the
 * target shifted by −v t / c (c = 1 − h/H; with H = 0, c = 1 and the shift is −v t). Same layer wind for all
 * three layers so one shift serves all. Both compute c·x + θh − v t in a different order: ~1e-14 cells. */
START_TEST(test_frozen_flow_shift)
{
    wt_context *ctx = tu_context();
    atm_setup s = three_layers(21);
    for (int l = 0; l < 3; l++) s.v[l] = 12.0, s.dir[l] = 0.7;
    wt_atmosphere *atm = make_atm(ctx, &s);
    const double t = 0.373, vx = 12.0 * cos(0.7), vy = 12.0 * sin(0.7);
    wt_grid tg = wt_grid_centred(60, 0.2);
    wt_grid ts = tg;
    ts.x0 -= vx * t, ts.y0 -= vy * t;
    const long np = 3600;
    double *a = calloc(np, sizeof *a), *b = calloc(np, sizeof *b);
    ck_assert_int_eq(wt_atmosphere_project(atm, t, 0.0, 2e-4, -1e-4, &tg, NULL, 1.0, a), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, 2e-4, -1e-4, &ts, NULL, 1.0, b), WT_OK);
    ck_assert(max_abs_diff(a, b, np) <= 1e-11 * rms(b, np));
    /* and it did move: at t = 0 on the unshifted target the values differ */
    memset(b, 0, np * sizeof *b);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, 2e-4, -1e-4, &tg, NULL, 1.0, b), WT_OK);
    ck_assert(tu_rel_diff(a, b, np) > 0.1);
    wt_atmosphere_free(atm);

    /* LGS: one layer at 9 km, H = 90 km: target shift −v t / c */
    atm_setup s1 = one_layer(128, 0.125, 25.0, 9000.0, 20.0, 2.5, 22, 0);
    atm = make_atm(ctx, &s1);
    double c = 1.0 - 9000.0 / 90e3;
    ts = tg;
    ts.x0 -= 20.0 * cos(2.5) * t / c, ts.y0 -= 20.0 * sin(2.5) * t / c;
    memset(a, 0, np * sizeof *a), memset(b, 0, np * sizeof *b);
    ck_assert_int_eq(wt_atmosphere_project(atm, t, 90e3, 1e-4, 3e-4, &tg, NULL, 1.0, a), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 90e3, 1e-4, 3e-4, &ts, NULL, 1.0, b), WT_OK);
    ck_assert(max_abs_diff(a, b, np) <= 1e-11 * rms(b, np));
    free(a), free(b);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* Periodic wrap. Grid part only: a shift by exactly one period L = nδ gives the same values (1e-12: the
 * sample coordinates differ by rounding of L/δ). With subharmonics: the field is continuous across the
 * wrap. Target = the screen grid shifted by n/2 + 0.5 cells, so the seam lies between two target
 * columns; the rms over rows of the increment across the seam must match that of the other increments
 * (n = 128 rows of a Gaussian increment: ±30 % is > 3 standard errors). The same comparison on the
 * rendered grid (subharmonics baked in, which is not periodic) shows a seam step ≥ 2x: the check can fail. */
START_TEST(test_periodic_wrap)
{
    wt_context *ctx = tu_context();
    const int n = 128;
    const double delta = 0.125, L = n * delta;
    atm_setup s = one_layer(n, delta, 25.0, 0.0, 10.0, 0.0, 31, 1);
    wt_atmosphere *atm = make_atm(ctx, &s);
    wt_grid tg = wt_grid_centred(50, 0.17);
    const long np = 2500;
    double *a = calloc(np, sizeof *a), *b = calloc(np, sizeof *b);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.123, 0.0, 0.0, 0.0, &tg, NULL, 1.0, a), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.123 + L / 10.0, 0.0, 0.0, 0.0, &tg, NULL, 1.0, b), WT_OK);
    ck_assert(max_abs_diff(a, b, np) <= 1e-12 * rms(a, np));
    wt_atmosphere_free(atm);
    free(a), free(b);

    s.nosh = 0;
    s.v[0] = 0.0;
    atm = make_atm(ctx, &s);
    wt_grid g = wt_atmosphere_grid(atm);
    g.x0 += (n / 2 + 0.5) * delta;
    const long nn = (long)n * n;
    double *p = calloc(nn, sizeof *p), *r = malloc(nn * sizeof *r);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, 0.0, 0.0, &g, NULL, 1.0, p), WT_OK);
    wt_atmosphere_layer_render(atm, 0, r);
    /* target column i samples screen column i + n/2 + 0.5: the seam lies between columns n/2 − 1 and n/2 */
    const int seam_p = n / 2 - 1, seam_r = n - 1; /* rendered grid: between columns n − 1 and 0 */
    double seam = 0.0, other = 0.0, seamr = 0.0, otherr = 0.0;
    long cnt = 0;
    for (int j = 0; j < n; j++) {
        for (int i = 0; i < n; i++) {
            double dp = p[(i + 1) % n + n * j] - p[i + n * j], dr = r[(i + 1) % n + n * j] - r[i + n * j];
            if (i == seam_p) seam += dp * dp;
            else if (i != n - 1) other += dp * dp, cnt++;
            if (i == seam_r) seamr += dr * dr;
            else otherr += dr * dr;
        }
    }
    double ratio = sqrt(seam / n) / sqrt(other / cnt), ratior = sqrt(seamr / n) / sqrt(otherr / ((long)n * (n - 1)));
    if (verbose()) printf("wrap: seam/other increment rms %.3f (projected), %.3f (rendered grid)\n", ratio, ratior);
    ck_assert_msg(ratio > 0.7 && ratio < 1.3, "seam increment rms / other = %.3f", ratio);
    ck_assert_msg(ratior > 2.0, "rendered seam ratio %.3f: the wrap test would not notice a seam", ratior);
    free(p), free(r);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Variance per layer */

/* Total OPD variance of each layer's grid part over the E-ELT profile (fractions 0.026 … 0.5224) is
 * f_ℓ V with V = Σ_k Φ_k Δκ² (Parseval over the drawn frequencies). With w_k = Φ_k Δκ², the spatial
 * variance is ½Σ|a_k|² + ½ Re Σ a_k a_{−k} (a_k = c_k √w_k), whose variance is 2 Σ w_k²: relative standard
 * error σ = √(2Σw²)/Σw. Each layer must be within 4σ; L0 = 4 m on a 64 m screen keeps σ ≈ 4 %. A fraction
 * applied as √f or f² would miss by factors 1.4 … 40. */
START_TEST(test_variance_fraction)
{
    wt_context *ctx = tu_context();
    const double fr[9] = {0.5224, 0.026, 0.0444, 0.116, 0.0989, 0.0295, 0.0598, 0.043, 0.06};
    const double al[9] = {47, 140, 281, 562, 1125, 2250, 4500, 9000, 18000};
    atm_setup s = {.nl = 9, .r0 = 0.129, .L0 = 4.0, .delta = 0.25, .n = 256, .seed = 81};
    for (int l = 0; l < 9; l++) s.h[l] = al[l], s.f[l] = fr[l], s.v[l] = 10, s.dir[l] = l;
    wt_atmosphere *atm = make_atm(ctx, &s);
    const int n = 256;
    const double dk = 1.0 / (n * 0.25);
    double sw = 0.0, sw2 = 0.0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            int kx = i <= n / 2 ? i : i - n, ky = j <= n / 2 ? j : j - n;
            if (!kx && !ky) continue;
            double w = psd(dk * dk * ((double)kx * kx + (double)ky * ky), 0.129, 4.0) * dk * dk;
            sw += w, sw2 += w * w;
        }
    double sigma = sqrt(2.0 * sw2) / sw;
    ck_assert(sigma < 0.06);
    for (int l = 0; l < 9; l++) {
        const double *d = wt_atmosphere_layer_data(atm, l);
        double v = 0.0;
        for (long i = 0; i < (long)n * n; i++) v += d[i] * d[i];
        v /= (double)n * n;
        double ratio = v / (wt_atmosphere_layer_fraction(atm, l) * sw);
        if (verbose()) printf("layer %d: variance / (f V) = %.4f (sigma %.4f)\n", l, ratio, sigma);
        ck_assert_msg(fabs(ratio - 1.0) < 4.0 * sigma, "layer %d: variance / (f V) = %.4f", l, ratio);
    }
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------------------------------------- */
/* Sizes, bad input, allocation failure */

static int smooth5(int n)
{
    while (n % 2 == 0) n /= 2;
    while (n % 3 == 0) n /= 3;
    while (n % 5 == 0) n /= 5;
    return n == 1;
}

START_TEST(test_recommend_size)
{
    wt_context *ctx = tu_context();
    int n = 0;
    ck_assert_int_eq(wt_atmosphere_recommend_size(ctx, 57.0, 0.125, &n), WT_OK);
    ck_assert_int_eq(n, 960); /* 2·57/0.125 = 912 → 960 = 2⁶·3·5 */
    const double fps[4] = {1.0, 42.0, 57.3, 130.0}, ds[3] = {0.125, 0.25, 0.5};
    for (int a = 0; a < 4; a++)
        for (int b = 0; b < 3; b++) {
            ck_assert_int_eq(wt_atmosphere_recommend_size(ctx, fps[a], ds[b], &n), WT_OK);
            ck_assert(n >= 32 && n % 2 == 0 && smooth5(n) && n * ds[b] >= 2.0 * fps[a] - 1e-9);
            for (int m = 32; m < n; m += 2) /* nothing smaller qualifies */ ck_assert(!(smooth5(m) && m * ds[b] >= 2.0 * fps[a]));
        }
    ck_assert_int_eq(wt_atmosphere_recommend_size(ctx, 0.0, 0.125, &n), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "footprint = 0"));
    ck_assert_int_eq(wt_atmosphere_recommend_size(ctx, 10.0, -1.0, &n), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "delta = -1"));
    wt_context_free(ctx);
}
END_TEST

static void expect_bad(wt_context *ctx, atm_setup s, const char *needle)
{
    wt_atmosphere_params p = {s.nl, s.h, s.f, s.v, s.dir, s.r0, s.L0, s.n, s.delta, s.seed, s.nosh};
    wt_atmosphere *atm = (wt_atmosphere *)&p; /* must be reset to NULL */
    int st = wt_atmosphere_alloc(ctx, &p, &atm);
    ck_assert_msg(st == WT_ERR_INVALID, "expected WT_ERR_INVALID for '%s', got %d", needle, st);
    ck_assert_ptr_null(atm);
    ck_assert_msg(strstr(wt_error_message(ctx), needle), "message '%s' does not name '%s'", wt_error_message(ctx),
                  needle);
}

START_TEST(test_bad_input)
{
    wt_context *ctx = tu_context();
    atm_setup good = three_layers(1), s;
    s = good, s.nl = 0, expect_bad(ctx, s, "nlayers = 0");
    s = good, s.f[2] = -0.1, expect_bad(ctx, s, "fractions[2] = -0.1");
    s = good, s.f[0] = s.f[1] = s.f[2] = 0.0, expect_bad(ctx, s, "sum to 0");
    s = good, s.f[1] = NAN, expect_bad(ctx, s, "fractions[1] = nan");
    s = good, s.h[1] = -5.0, expect_bad(ctx, s, "altitudes[1] = -5");
    s = good, s.v[0] = -3.0, expect_bad(ctx, s, "wind_speed[0] = -3");
    s = good, s.dir[2] = INFINITY, expect_bad(ctx, s, "wind_direction[2] = inf");
    s = good, s.r0 = 0.0, expect_bad(ctx, s, "r0 = 0");
    s = good, s.r0 = -0.1, expect_bad(ctx, s, "r0 = -0.1");
    s = good, s.L0 = 0.0, expect_bad(ctx, s, "L0 = 0");
    s = good, s.L0 = NAN, expect_bad(ctx, s, "L0 = nan");
    s = good, s.delta = 0.0, expect_bad(ctx, s, "delta = 0");
    s = good, s.n = 254, expect_bad(ctx, s, "n = 254"); /* 2·127 */
    s = good, s.n = 125, expect_bad(ctx, s, "n = 125"); /* odd */
    s = good, s.n = 8, expect_bad(ctx, s, "n = 8");
    s = good, s.nosh = 2, expect_bad(ctx, s, "no_subharmonics = 2");
    wt_atmosphere *atm = NULL;
    ck_assert_int_eq(wt_atmosphere_alloc(ctx, NULL, &atm), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "params"));

    /* project */
    atm = make_atm(ctx, &good);
    wt_grid tg = wt_grid_centred(8, 0.5), bad = tg;
    double out[64] = {0};
    ck_assert_int_eq(wt_atmosphere_project(atm, 0, 10000.0, 0, 0, &tg, NULL, 1.0, out), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "source_altitude = 10000"));
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "layer 2"));
    ck_assert_int_eq(wt_atmosphere_project(atm, 0, -1.0, 0, 0, &tg, NULL, 1.0, out), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "source_altitude = -1"));
    ck_assert_int_eq(wt_atmosphere_project(atm, NAN, 0, 0, 0, &tg, NULL, 1.0, out), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "t = nan"));
    bad.dx = 0.0;
    ck_assert_int_eq(wt_atmosphere_project(atm, 0, 0, 0, 0, &bad, NULL, 1.0, out), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "dx = 0"));
    bad = tg, bad.nx = 0;
    ck_assert_int_eq(wt_atmosphere_project(atm, 0, 0, 0, 0, &bad, NULL, 1.0, out), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "0 x 8"));
    for (int i = 0; i < 64; i++) ck_assert(out[i] == 0.0); /* rejected calls wrote nothing */
    wt_atmosphere_free(atm);
    wt_atmosphere_free(NULL);
    wt_context_free(ctx);
}
END_TEST

/* Each allocation of alloc failing in turn gives WT_ERR_NOMEM, *out = NULL and nothing left allocated. */
START_TEST(test_alloc_failure)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    atm_setup s = three_layers(3);
    s.n = 32;
    wt_atmosphere *atm = make_atm(ctx, &s);
    ck_assert(fa.live > 0);
    ck_assert(wt_atmosphere_bytes(atm) >= 3 * 32 * 32 * sizeof(double));
    wt_atmosphere_free(atm);
    ck_assert_int_eq(fa.live, 0);
    int failures = 0;
    for (int k = 0; k < 20; k++) {
        tu_alloc_budget(&fa, k);
        wt_atmosphere_params p = {s.nl, s.h, s.f, s.v, s.dir, s.r0, s.L0, s.n, s.delta, s.seed, s.nosh};
        atm = NULL;
        int st = wt_atmosphere_alloc(ctx, &p, &atm);
        if (st == WT_OK) {
            wt_atmosphere_free(atm);
            break;
        }
        failures++;
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(atm);
        ck_assert_int_eq(fa.live, 0);
    }
    ck_assert(failures >= 4); /* the struct, the layer table, the screens, the work space */
    ck_assert_int_eq(fa.live, 0);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("atmosphere");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_theory_quadrature);
    tcase_add_test(tc, test_structure_function_small);
    tcase_add_test(tc, test_structure_function_large);
    tcase_add_test(tc, test_subharmonics_matter);
    tcase_add_test(tc, test_determinism);
    tcase_add_test(tc, test_stream_per_layer);
    tcase_add_test(tc, test_frozen_flow_integer_shift);
    tcase_add_test(tc, test_frozen_flow_shift);
    tcase_add_test(tc, test_periodic_wrap);
    tcase_add_test(tc, test_variance_fraction);
    tcase_add_test(tc, test_recommend_size);
    tcase_add_test(tc, test_bad_input);
    tcase_add_test(tc, test_alloc_failure);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
