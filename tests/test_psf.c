/* tests/test_psf.c: long-exposure PSFs (SPEC §8b; sim/psf.h): the diffraction-limited image of a disc and of
 * an annulus (peak 1, Parseval, the Airy FWHM), a tilt's shift, the PSF-peak Strehl of a small random residual
 * against the extended Maréchal exp(−σ²), the frames taken, no allocation per frame, the same bits for any
 * thread count and for the same seed of a closed loop, and refused parameters. */
#include "sim/loop.h"
#include "sim/psf.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

/* an n x n grid of spacing dx whose pupil is the annulus ε D/2 ≤ r ≤ D/2, D = n dx (points at cell centres) */
static int64_t annulus(int n, double eps, uint8_t *mask)
{
    int64_t c = 0;
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            const double x = ix - 0.5 * (n - 1), y = iy - 0.5 * (n - 1), r = sqrt(x * x + y * y);
            mask[ix + n * iy] = (uint8_t)(r <= 0.5 * n && r >= 0.5 * eps * n);
            c += mask[ix + n * iy];
        }
    return c;
}

/* the annular pupil's PSF normalised to its peak: [2J1(v)/v − ε² 2J1(εv)/(εv)]² / (1 − ε²)², v = π D θ / λ */
static double airy(double v, double eps)
{
    if (v < 1e-12) return 1.0;
    double a = 2.0 * j1(v) / v - (eps > 0.0 ? eps * eps * 2.0 * j1(eps * v) / (eps * v) : 0.0);
    return a * a / ((1.0 - eps * eps) * (1.0 - eps * eps));
}

/* its half-maximum v (bisection on the central lobe, v < 3.83) */
static double airy_half(double eps)
{
    double lo = 0.0, hi = 3.0;
    for (int i = 0; i < 200; i++) {
        double mid = 0.5 * (lo + hi);
        if (airy(mid, eps) > 0.5) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* A flat residual: peak 1 at the centre pixel; Σ over all N² pixels = N²/N_P (Parseval: Σ|FFT U|² = N² Σ|U|² =
 * N² N_P, over N_P²); float32 fields: relative rounding ~ log2(N) 2^-24 per value, 1e-5 is far above it. */
START_TEST(test_flat_peak_and_parseval)
{
    enum { n = 64 };
    static uint8_t mask[n * n];
    static double opd[n * n];
    const double dx = 0.125, lambda = 2.2e-6;
    const int64_t np = annulus(n, 0.28, mask);
    for (int i = 0; i < n * n; i++) opd[i] = 3e-6; /* a piston changes nothing */
    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_centred(n, dx);
    wt_psf_params par = {.wavelength = lambda, .diameter = n * dx, .every = 1, .settle = 0, .sampling = 2.0, .pixels = 128};
    wt_psf *p;
    ck_assert_msg(wt_psf_alloc(ctx, &g, mask, 1, &par, &p) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_psf_fft_size(p), 128);
    ck_assert_rel(wt_psf_pixel_lod(p), 0.5, 1e-14, 0.0); /* Nyquist: λ/(2D) */
    ck_assert_rel(wt_psf_pixel_scale(p), lambda / (128 * dx), 1e-14, 0.0);
    const double *maps[1] = {opd};
    wt_psf_add(p, maps);
    wt_psf_add(p, maps);
    static float img[128 * 128];
    wt_psf_image(p, 0, img);
    double sum = 0.0, mx = 0.0;
    int at = -1;
    for (int i = 0; i < 128 * 128; i++) {
        sum += img[i];
        if (img[i] > mx) mx = img[i], at = i;
    }
    ck_assert_int_eq(at, 64 + 128 * 64);
    ck_assert_rel(img[64 + 128 * 64], 1.0, 1e-5, 0.0);
    ck_assert_rel(wt_psf_strehl(p, 0), 1.0, 1e-5, 0.0);
    ck_assert_rel(sum, 128.0 * 128.0 / (double)np, 1e-5, 0.0);
    ck_assert_int_eq(wt_psf_frames(p), 2);
    wt_psf_free(p);
    wt_context_free(ctx);
}
END_TEST

/* The FWHM of the diffraction-limited image, for a disc (1.029 λ/D) and the E-ELT obstruction ε = 0.28
 * (narrower core: the analytic annulus pattern, its half maximum found by bisection), measured along x through
 * the centre at 16 pixels per λ/D by linear interpolation. Expected: the analytic value for the diameter D_eff
 * of the digitised pupil's area (π D_eff² (1 − ε²)/4 = N_P dx²). Tolerance: the linear interpolation's error,
 * h²/8 max|I''| / |I'| in v = π D θ/λ over the pixel h around the half maximum (from the analytic pattern), plus
 * dx/D for the rim's digitisation (the discrete rim departs from the circle by up to dx/2 at each side). */
START_TEST(test_airy_fwhm)
{
    enum { n = 64 };
    static uint8_t mask[n * n];
    static double opd[n * n];
    static float img[64 * 64];
    const double dx = 0.5, lambda = 1.65e-6, D = n * dx;
    const double eps_list[2] = {0.0, 0.28};
    for (int e = 0; e < 2; e++) {
        const double eps = eps_list[e];
        const int64_t np = annulus(n, eps, mask);
        wt_context *ctx = tu_context();
        wt_grid g = wt_grid_centred(n, dx);
        wt_psf_params par = {.wavelength = lambda, .diameter = D, .every = 1, .sampling = 16.0, .pixels = 64};
        wt_psf *p;
        ck_assert_msg(wt_psf_alloc(ctx, &g, mask, 1, &par, &p) == WT_OK, "%s", wt_error_message(ctx));
        const double *maps[1] = {opd};
        wt_psf_add(p, maps);
        wt_psf_image(p, 0, img);
        const int h = 32;
        const float *row = img + 64 * h;
        ck_assert_rel(row[h], 1.0, 1e-5, 0.0);
        int i = h;
        while (i < 63 && row[i] >= 0.5f) i++;
        const double xh = (i - 1) + (row[i - 1] - 0.5) / (row[i - 1] - row[i]);
        const double fwhm = 2.0 * (xh - h) * wt_psf_pixel_lod(p); /* [λ/D] */
        const double d_eff = sqrt(4.0 * (double)np * dx * dx / (M_PI * (1.0 - eps * eps)));
        const double vh = airy_half(eps), want = 2.0 * vh / M_PI * D / d_eff;
        /* interpolation bound from the analytic pattern over [vh − hv, vh + hv] */
        const double hv = M_PI * wt_psf_pixel_lod(p), dv = 1e-3;
        double d2 = 0.0;
        for (double v = vh - hv; v <= vh + hv; v += hv / 20)
            d2 = fmax(d2, fabs(airy(v + dv, eps) - 2 * airy(v, eps) + airy(v - dv, eps)) / (dv * dv));
        const double d1 = fabs(airy(vh + dv, eps) - airy(vh - dv, eps)) / (2 * dv);
        const double tol = hv * hv / 8.0 * d2 / d1 / vh + dx / D;
        if (e == 0) ck_assert_rel(2.0 * vh / M_PI, 1.029, 1e-3, 0.0); /* the textbook 1.03 λ/D */
        else ck_assert_double_lt(2.0 * vh / M_PI, 1.0);              /* the obstruction narrows the core */
        ck_assert_msg(fabs(fwhm - want) <= tol * want, "eps %g: FWHM %.5f λ/D vs %.5f (tol %.3g)", eps, fwhm, want, tol);
        wt_psf_free(p);
        wt_context_free(ctx);
    }
}
END_TEST

/* A pure tilt ∂φ/∂x = a moves the image by a / θ_p pixels: an integer number of pixels (3 in x, −5 in y) keeps
 * the peak at 1 (the field's ramp falls on an FFT bin). */
START_TEST(test_tilt_shift)
{
    enum { n = 48 };
    static uint8_t mask[n * n];
    static double opd[n * n];
    static float img[100 * 100];
    const double dx = 0.25, lambda = 2.2e-6;
    annulus(n, 0.0, mask);
    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_centred(n, dx);
    wt_psf_params par = {.wavelength = lambda, .diameter = n * dx, .every = 1, .sampling = 2.0, .pixels = 40};
    wt_psf *p;
    ck_assert_msg(wt_psf_alloc(ctx, &g, mask, 1, &par, &p) == WT_OK, "%s", wt_error_message(ctx));
    const int N = wt_psf_fft_size(p), mx = 3, my = -5;
    ck_assert_int_eq(N, 96);
    const double th = wt_psf_pixel_scale(p);
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) opd[ix + n * iy] = (mx * th) * (g.x0 + ix * dx) + (my * th) * (g.y0 + iy * dx);
    const double *maps[1] = {opd};
    wt_psf_add(p, maps);
    wt_psf_image(p, 0, img);
    int at = 0;
    for (int i = 0; i < 40 * 40; i++)
        if (img[i] > img[at]) at = i;
    ck_assert_int_eq(at % 40, 20 + mx);
    ck_assert_int_eq(at / 40, 20 + my);
    ck_assert_rel(img[at], 1.0, 1e-5, 0.0);
    wt_psf_free(p);
    wt_context_free(ctx);
}
END_TEST

/* A small random residual (white Gaussian phase, σ = 0.25 rad): the image's peak is |mean_P exp(iφ)|² exactly
 * (the centre pixel: the sum of the field), and the extended Maréchal exp(−σ²) approximates it. With m_k the
 * moments of the piston-removed phase, cos and sin to their Taylor terms give
 *   S = c² + s²,  c = 1 − m2/2 + m4/24 + e_c,  s = −m3/6 + e_s,  |e_c| ≤ m6/720,  |e_s| ≤ M5/120 (M5 = mean|φ|⁵),
 * so |S − exp(−m2)| ≤ |S₀ − exp(−m2)| + 2|c₀| m6/720 + (m6/720)² + 2|m3/6| M5/120 + (M5/120)² with S₀ = c₀² + s₀²
 * the Taylor part: the tolerance, computed from the sample; it is (m4 − 3m2²)/12 + m3²/36 + O(σ⁶) ≈ 1e-3 here
 * (a Gaussian sample has m4 ≈ 3m2², m3 ≈ 0), and the test also requires it to be that small. */
START_TEST(test_marechal_small_residual)
{
    enum { n = 64 };
    static uint8_t mask[n * n];
    static double opd[n * n];
    const double dx = 0.5, lambda = 2.2e-6, sigma = 0.25;
    const int64_t np = annulus(n, 0.28, mask);
    wt_rng rng;
    wt_rng_init(&rng, 17, 0);
    for (int i = 0; i < n * n; i++) opd[i] = mask[i] ? sigma * lambda / (2 * M_PI) * wt_rng_normal(&rng) : 1e9;
    double mean = 0.0, re = 0.0, im = 0.0;
    for (int i = 0; i < n * n; i++) mean += mask[i] ? opd[i] : 0.0;
    mean /= (double)np;
    double m2 = 0, m3 = 0, m4 = 0, M5 = 0, m6 = 0;
    for (int i = 0; i < n * n; i++) {
        if (!mask[i]) continue;
        const double f = 2 * M_PI * (opd[i] - mean) / lambda;
        m2 += f * f, m3 += f * f * f, m4 += pow(f, 4), M5 += pow(fabs(f), 5), m6 += pow(f, 6);
        re += cos(f), im += sin(f);
    }
    m2 /= np, m3 /= np, m4 /= np, M5 /= np, m6 /= np;
    const double exact = (re * re + im * im) / ((double)np * np);
    const double c0 = 1 - m2 / 2 + m4 / 24, s0 = -m3 / 6, S0 = c0 * c0 + s0 * s0, mar = exp(-m2);
    const double tol = fabs(S0 - mar) + 2 * fabs(c0) * m6 / 720 + pow(m6 / 720, 2) + 2 * fabs(s0) * M5 / 120 +
                       pow(M5 / 120, 2) + 1e-5;
    ck_assert_double_lt(tol, 3e-3);
    /* the code's Maréchal on the same map */
    ck_assert_rel(wt_strehl_marechal(wt_strehl_rms(opd, mask, n * n), lambda), mar, 1e-12, 0.0);

    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_centred(n, dx);
    wt_psf_params par = {.wavelength = lambda, .diameter = n * dx, .every = 1, .sampling = 2.0};
    wt_psf *p;
    ck_assert_msg(wt_psf_alloc(ctx, &g, mask, 1, &par, &p) == WT_OK, "%s", wt_error_message(ctx));
    const double *maps[1] = {opd};
    wt_psf_add(p, maps);
    const double s = wt_psf_strehl(p, 0);
    ck_assert_rel(s, exact, 1e-5, 0.0);
    ck_assert_msg(fabs(s - mar) <= tol, "PSF peak %.6f vs exp(-sigma^2) %.6f (tol %.3g)", s, mar, tol);
    wt_psf_free(p);
    wt_context_free(ctx);
}
END_TEST

/* The frames taken (t ≥ settle, every `every`), nothing allocated per frame (the allocator hook counts), the
 * same bits with 1 and 2 threads (each direction's sum is one thread's), allocation failures surfacing as
 * WT_ERR_NOMEM with nothing leaked, and refused parameters. */
START_TEST(test_frames_threads_alloc)
{
    enum { n = 32, ND = 5 };
    static uint8_t mask[n * n];
    static double opd[ND][n * n];
    static float a[ND][64 * 64], b[ND][64 * 64];
    annulus(n, 0.28, mask);
    const double *maps[ND];
    for (int j = 0; j < ND; j++) {
        tu_randn(opd[j], n * n, 100 + j);
        for (int i = 0; i < n * n; i++) opd[j][i] *= 300e-9;
        maps[j] = opd[j];
    }
    wt_grid g = wt_grid_centred(n, 0.25);
    wt_psf_params par = {.wavelength = 1.65e-6, .diameter = n * 0.25, .every = 3, .settle = 2, .sampling = 2.0};
    for (int threads = 1; threads <= 2; threads++) {
        wt_context *ctx = tu_context();
        wt_context_set_threads(ctx, threads);
        tu_alloc fa = TU_ALLOC_INIT;
        tu_alloc_install(ctx, &fa);
        wt_psf *p;
        ck_assert_msg(wt_psf_alloc(ctx, &g, mask, ND, &par, &p) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_eq(wt_psf_pixels(p), 64);
        const long before = fa.count;
        int taken = 0;
        for (long t = 0; t < 10; t++) taken += wt_psf_frame(p, t, maps);
        ck_assert_int_eq(taken, 3); /* frames 2, 5, 8 */
        ck_assert_int_eq(wt_psf_frames(p), 3);
        ck_assert_msg(fa.count == before, "%ld allocations in 10 frames", fa.count - before);
        for (int j = 0; j < ND; j++) wt_psf_image(p, j, threads == 1 ? a[j] : b[j]);
        wt_psf_free(p);
        ck_assert_int_eq(fa.live, 0);
        /* every allocation refused in turn: WT_ERR_NOMEM, nothing left behind */
        for (long k = 0;; k++) {
            tu_alloc_fail_nth(&fa, k);
            wt_psf *q = (wt_psf *)1;
            int st = wt_psf_alloc(ctx, &g, mask, ND, &par, &q);
            tu_alloc_budget(&fa, -1);
            if (st == WT_OK) {
                wt_psf_free(q);
                ck_assert_int_gt(k, 3);
                break;
            }
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            ck_assert_ptr_null(q);
        }
        ck_assert_int_eq(fa.live, 0);
        wt_context_free(ctx);
    }
    ck_assert_int_eq(memcmp(a, b, sizeof a), 0);
    /* refused parameters name themselves */
    wt_context *ctx = tu_context();
    wt_psf *q;
    wt_psf_params bad = par;
    bad.every = 0;
    ck_assert_int_eq(wt_psf_alloc(ctx, &g, mask, ND, &bad, &q), WT_ERR_INVALID);
    ck_assert(strstr(wt_error_message(ctx), "every 0"));
    bad = par, bad.pixels = 33;
    ck_assert_int_eq(wt_psf_alloc(ctx, &g, mask, ND, &bad, &q), WT_ERR_INVALID);
    bad = par, bad.pixels = 128; /* more than N = 64: N */
    ck_assert_int_eq(wt_psf_alloc(ctx, &g, mask, ND, &bad, &q), WT_OK);
    ck_assert_int_eq(wt_psf_pixels(q), wt_psf_fft_size(q));
    ck_assert_int_eq(wt_psf_pixels(q), 64);
    wt_psf_free(q);
    static uint8_t none[n * n];
    ck_assert_int_eq(wt_psf_alloc(ctx, &g, none, ND, &par, &q), WT_ERR_INVALID);
    wt_context_free(ctx);
}
END_TEST

/* The closed loop's images: the same seed gives the same bits, another seed other images; the PSF-peak Strehl
 * of a demo loop stays within (0, 1]. */
static void loop_psf(uint64_t seed, float *img, double *s, int *npix)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_loop *lp;
    wt_psf *p;
    ck_assert_msg(wt_config_read(ctx, DEMO, 0, NULL, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = seed, .noise = cfg->noise};
    ck_assert_msg(wt_loop_alloc(ctx, sys, &o, &lp) == WT_OK, "%s", wt_error_message(ctx));
    wt_psf_params par = {.wavelength = cfg->eval_wavelength, .diameter = cfg->diameter, .every = 2, .settle = 2, .sampling = 2.0};
    ck_assert_msg(wt_psf_alloc(ctx, wt_loop_fine_grid(lp), wt_loop_pupil_mask(lp), sys->neval, &par, &p) == WT_OK, "%s",
                  wt_error_message(ctx));
    const double *maps[WT_MAX_EVAL];
    for (long t = 0; t < 6; t++) {
        ck_assert_int_eq(wt_loop_step(lp), WT_OK);
        for (int j = 0; j < sys->neval; j++) maps[j] = wt_loop_residual(lp, j);
        wt_psf_frame(p, t, maps);
    }
    ck_assert_int_eq(wt_psf_frames(p), 2);
    *npix = wt_psf_pixels(p);
    wt_psf_image(p, sys->eval_centre, img);
    *s = wt_psf_strehl(p, sys->eval_centre);
    wt_psf_free(p);
    wt_loop_free(lp);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}

START_TEST(test_loop_same_seed)
{
    static float a[256 * 256], b[256 * 256], c[256 * 256];
    double sa, sb, sc;
    int na, nb, nc;
    loop_psf(1, a, &sa, &na);
    loop_psf(1, b, &sb, &nb);
    loop_psf(2, c, &sc, &nc);
    ck_assert_int_eq(na, nb);
    ck_assert_int_le(na, 256);
    ck_assert_int_eq(memcmp(a, b, (size_t)na * na * sizeof *a), 0);
    ck_assert_double_eq(sa, sb);
    ck_assert_int_ne(memcmp(a, c, (size_t)na * na * sizeof *a), 0);
    ck_assert(sa > 0.0 && sa <= 1.0 && sc > 0.0 && sc <= 1.0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("psf");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_flat_peak_and_parseval);
    tcase_add_test(tc, test_airy_fwhm);
    tcase_add_test(tc, test_tilt_shift);
    tcase_add_test(tc, test_marechal_small_residual);
    tcase_add_test(tc, test_frames_threads_alloc);
    tcase_add_test(tc, test_loop_same_seed);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
