/* tests/test_centroid.c: the centroiders of core/optics/centroid.c (CoG, thresholded CoG, matched filter):
 * response to tilt and the calibrated gain, gains against finite differences, thread-count independence, no
 * allocation per frame, and rejected input (the noise formulas against noise draws: test_centroid_noise.c).
 *
 * Spots are made here: pixel-integrated (rotated, anisotropic) Gaussians, integrated exactly (erf) across
 * the conditional axis and by Simpson's rule along the other, with analytic derivatives; noise draws use
 * an exact Poisson sampler by inversion written here (independent of the library's). */
#include "centroid_fixture.h"

/* ---------- tests ---------- */

START_TEST(test_tilt_cog)
{
    /* An unelongated spot (σ = 1.2 p) on 16² pixels: the CoG over the whole detector is unbiased up to
     * the truncation at ±6.7σ and the pixel sampling (Poisson summation: relative ~exp(−2π²σ²/p²) ~ 1e-12),
     * so the gain is within 2 % of 1 (measured ~1e-6) and a tilt moves the centroid by g θ: the pixels' CoG of
     * a shifted Gaussian is linear in the shift to the same order; 1e-4 of |θ| covers float32 images. */
    wt_context *ctx = tu_context();
    const int ns = 16;
    spot s0 = {.flux = 1000, .sl = 1.2 * PIX, .ss = 1.2 * PIX};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_COG, 0, 0);
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double g[4];
    wt_centroid_gain(c, 0, g);
    ck_assert_msg(fabs(g[0] - 1) < 0.02 && fabs(g[3] - 1) < 0.02 && fabs(g[1]) < 0.02 && fabs(g[2]) < 0.02,
                  "gain {%g %g; %g %g}", g[0], g[1], g[2], g[3]);
    const double th[2] = {0.3 * PIX, -0.2 * PIX};
    spot s1 = s0;
    s1.tx = th[0];
    s1.ty = th[1];
    float *img = malloc(ns * ns * sizeof *img);
    render(&s1, ns, img, NULL, NULL);
    double sl[2];
    wt_centroid_apply(c, img, sl);
    const double nt = hypot(th[0], th[1]);
    ck_assert_double_eq_tol(sl[0], g[0] * th[0] + g[1] * th[1], 1e-4 * nt);
    ck_assert_double_eq_tol(sl[1], g[2] * th[0] + g[3] * th[1], 1e-4 * nt);
    /* the reference itself gives zero */
    wt_centroid_apply(c, ref, sl);
    ck_assert_double_eq_tol(sl[0], 0.0, 1e-9 * PIX);
    ck_assert_double_eq_tol(sl[1], 0.0, 1e-9 * PIX);
    wt_centroid_free(c);
    free(img), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

/* The CoG of noisy pixels stays within the hull of the window's pixel centres (centroid.h): a frame whose
 * window sum is a small positive number beside large moments (negative pixels from read noise) would put
 * the ratio far outside the window; it is clamped per axis to ±(Nw−1)p/2, relative to the reference
 * centroid. A noise-free spot near the window's edge is not touched (all weights ≥ 0), so the clamp is
 * not a limit on the linear range. */
START_TEST(test_cog_clamped_to_window)
{
    wt_context *ctx = tu_context();
    const int ns = 8, nw = 6;
    spot s0 = {.flux = 100, .sl = 0.8 * PIX, .ss = 0.8 * PIX, .tx = 0.1 * PIX, .ty = -0.2 * PIX};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_COG, 0, 3.0);
    p.window = nw;
    p.apply_gain = 0;
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double sl[2], r[2];
    wt_centroid_apply(c, ref, r); /* zero: the reference */
    /* the raw reference centroid x0: the CoG of I0 in the window, computed here */
    double n0 = 0, x0 = 0, y0 = 0;
    const int off = (ns - nw) / 2;
    for (int iy = off; iy < off + nw; iy++)
        for (int ix = off; ix < off + nw; ix++) {
            const double w = ref[ix + ns * iy];
            n0 += w, x0 += (ix - 0.5 * (ns - 1)) * PIX * w, y0 += (iy - 0.5 * (ns - 1)) * PIX * w;
        }
    x0 /= n0, y0 /= n0;
    /* +50 e- at the window's right column (row 3), −49.9 at its left column (row 4): sum 0.1, moment along
     * x ~ 50·5p: the unclamped ratio is ~2500 p */
    float *img = calloc(ns * ns, sizeof *img);
    img[(off + nw - 1) + ns * 3] = 50.0f;
    img[off + ns * 4] = -49.9f;
    wt_centroid_apply(c, img, sl);
    const double h = 0.5 * (nw - 1) * PIX;
    ck_assert_double_eq_tol(sl[0], h - x0, 1e-12 * PIX);
    ck_assert_msg(sl[1] >= -h - y0 - 1e-12 * PIX && sl[1] <= h - y0 + 1e-12 * PIX, "y %g outside the hull", sl[1]);
    /* the mirror image: clamped at the other side */
    memset(img, 0, ns * ns * sizeof *img);
    img[(off + nw - 1) + ns * 3] = -49.9f;
    img[off + ns * 4] = 50.0f;
    wt_centroid_apply(c, img, sl);
    ck_assert_double_eq_tol(sl[0], -h - x0, 1e-12 * PIX);
    /* a noise-free spot centred 2 pixels off (near the window's edge) is its plain CoG, not clamped */
    spot s1 = s0;
    s1.tx = 2.0 * PIX;
    render(&s1, ns, img, NULL, NULL);
    double m = 0, mx = 0;
    for (int iy = off; iy < off + nw; iy++)
        for (int ix = off; ix < off + nw; ix++) m += img[ix + ns * iy], mx += (ix - 0.5 * (ns - 1)) * PIX * img[ix + ns * iy];
    wt_centroid_apply(c, img, sl);
    ck_assert_double_eq_tol(sl[0], mx / m - x0, 1e-9 * PIX);
    wt_centroid_free(c);
    free(img), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_truncated_gain)
{
    /* An elongated spot (σl = 3p at 30°) truncated by an 8² detector: the CoG sees only the inner part of
     * the elongation, its gain along it is well below 1 (~0.6); the calibrated inverse gain restores the
     * slope. The CoG response of a symmetric spot is odd in θ, so at θ = 0.05p the linearisation is exact
     * to O(θ²/σ²) relative, ~3e-4: 1e-2 of |θ| catches a gain that is wrong by a percent. */
    wt_context *ctx = tu_context();
    const int ns = 8;
    const double ang = M_PI / 6, e[2] = {cos(ang), sin(ang)};
    spot s0 = {.flux = 1000, .sl = 3 * PIX, .ss = 0.7 * PIX, .ang = ang};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    float *img = malloc(ns * ns * sizeof *img);
    const double amp = 0.05 * PIX;
    spot s1 = s0;
    s1.tx = amp * e[0];
    s1.ty = amp * e[1];
    render(&s1, ns, img, NULL, NULL);
    for (int method = WT_CENTROID_COG; method <= WT_CENTROID_TCOG; method++) {
        wt_centroid_params p = params(method, 0, 0);
        p.threshold_peak = 0.05;
        wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
        double g[4], sl[2];
        wt_centroid_gain(c, 0, g);
        const double gl = e[0] * (g[0] * e[0] + g[1] * e[1]) + e[1] * (g[2] * e[0] + g[3] * e[1]);
        const double gs = -e[1] * (g[0] * -e[1] + g[1] * e[0]) + e[0] * (g[2] * -e[1] + g[3] * e[0]);
        ck_assert_msg(gl < 0.9, "method %d: gain along the elongation %g, expected < 0.9", method, gl);
        ck_assert_msg(gs > 0.95, "method %d: gain across it %g, expected ≈ 1", method, gs);
        wt_centroid_apply(c, img, sl);
        const double along = sl[0] * e[0] + sl[1] * e[1];
        ck_assert_double_eq_tol(along, gl * amp, 1e-2 * amp);
        wt_centroid_free(c);
        p.apply_gain = 1;
        c = make(ctx, &p, 1, ns, ref, dx, dy);
        wt_centroid_apply(c, img, sl);
        ck_assert_double_eq_tol(sl[0], s1.tx, 1e-2 * amp);
        ck_assert_double_eq_tol(sl[1], s1.ty, 1e-2 * amp);
        wt_centroid_free(c);
    }
    free(img), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_gain_fd)
{
    /* The reported gain (from the derivative images) against central finite differences of the
     * estimator on re-rendered spots, for an off-centre, truncated, elongated reference (no symmetry to
     * hide a sign or an index error). Central differences with h = 2e-3 p err by O(h²) ~ 1e-5; float32
     * images put ~6e-8 p of rounding into each centroid, 2e-5 of the difference 2h g: 2e-4 of max|g|
     * covers both. The MF's gain is the identity by construction (R G = I up to the float rows). */
    wt_context *ctx = tu_context();
    const int ns = 10;
    spot s0 = {.flux = 800, .sl = 2.5 * PIX, .ss = 0.8 * PIX, .ang = 1.1, .tx = 0.4 * PIX, .ty = -0.3 * PIX};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    const double h = 2e-3 * PIX;
    float *ip = malloc(ns * ns * sizeof *ip), *im = malloc(ns * ns * sizeof *im);
    for (int method = WT_CENTROID_COG; method <= WT_CENTROID_MF; method++) {
        wt_centroid_params p = params(method, 1.0, 2.0);
        p.threshold_noise = 3.0;
        p.window = method == WT_CENTROID_MF ? 0 : 8;
        wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
        double g[4];
        wt_centroid_gain(c, 0, g);
        const double gmax = fmax(fmax(fabs(g[0]), fabs(g[1])), fmax(fabs(g[2]), fabs(g[3])));
        for (int k = 0; k < 2; k++) {
            spot sp = s0, sm = s0;
            if (k == 0) sp.tx += h, sm.tx -= h;
            else sp.ty += h, sm.ty -= h;
            render(&sp, ns, ip, NULL, NULL);
            render(&sm, ns, im, NULL, NULL);
            double a[2], b[2];
            wt_centroid_apply(c, ip, a);
            wt_centroid_apply(c, im, b);
            for (int r = 0; r < 2; r++)
                ck_assert_msg(fabs((a[r] - b[r]) / (2 * h) - g[2 * r + k]) < 2e-4 * gmax,
                              "method %d: d s_%d / d θ_%d: FD %.8g, gain %.8g", method, r, k, (a[r] - b[r]) / (2 * h),
                              g[2 * r + k]);
        }
        if (method == WT_CENTROID_MF) {
            /* R G = I: the float rows' rounding (6e-8 relative) summed over 100 pixels */
            ck_assert_double_eq_tol(g[0], 1.0, 1e-5);
            ck_assert_double_eq_tol(g[3], 1.0, 1e-5);
            ck_assert_double_eq_tol(g[1], 0.0, 1e-5);
            ck_assert_double_eq_tol(g[2], 0.0, 1e-5);
        }
        wt_centroid_free(c);
    }
    free(ip), free(im), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_mf_flux_column)
{
    /* With the I0 column (mf_flux = 1) R I0 = 0 exactly (R G = [I 0]), so a flux change of 20 % gives
     * zero slopes up to the float rows' rounding (measured 1e-8 p; bound 1e-6 p); without it the
     * off-centre, partly truncated reference (no symmetry) responds to flux (measured 3e-3 p; bound 1e-3 p):
     * the column is what makes the difference. */
    wt_context *ctx = tu_context();
    const int ns = 10;
    spot s0 = {.flux = 500, .sl = 2 * PIX, .ss = 0.9 * PIX, .ang = 0.4, .tx = 0.6 * PIX, .ty = 0.2 * PIX};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    float *img = malloc(ns * ns * sizeof *img);
    for (int j = 0; j < ns * ns; j++) img[j] = 1.2f * ref[j];
    double sl[2];
    wt_centroid_params p = params(WT_CENTROID_MF, 0.5, 1.5);
    p.mf_flux = 1;
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    wt_centroid_apply(c, img, sl);
    ck_assert_double_eq_tol(sl[0], 0.0, 1e-6 * PIX);
    ck_assert_double_eq_tol(sl[1], 0.0, 1e-6 * PIX);
    wt_centroid_free(c);
    p.mf_flux = 0;
    c = make(ctx, &p, 1, ns, ref, dx, dy);
    wt_centroid_apply(c, img, sl);
    ck_assert_msg(hypot(sl[0], sl[1]) > 1e-3 * PIX, "without the flux column: %g %g", sl[0], sl[1]);
    wt_centroid_free(c);
    free(img), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_threshold)
{
    /* The threshold T = k √(σe² + B) + f max I0, and the tCoG equal to a CoG of max(d − T, 0) computed
     * by hand on an arbitrary image (relative to the reference's own thresholded centroid). */
    wt_context *ctx = tu_context();
    const int ns = 6;
    spot s0 = {.flux = 400, .sl = 1.5 * PIX, .ss = 1.0 * PIX, .ang = 0.3};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_TCOG, 4.0, 3.0);
    p.threshold_noise = 2.5;
    p.threshold_peak = 0.1;
    p.window = 4;
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double peak = 0;
    for (int j = 0; j < ns * ns; j++) peak = fmax(peak, ref[j]);
    const double t = 2.5 * sqrt(9.0 + 4.0) + 0.1 * peak;
    ck_assert_double_eq_tol(wt_centroid_threshold(c, 0), t, 1e-12 * t);
    float img[36];
    wt_rng r;
    wt_rng_init(&r, 5, 0);
    for (int j = 0; j < 36; j++) img[j] = (float)(ref[j] + 10 * wt_rng_normal(&r));
    /* by hand: the window is pixels 1..4 of 6 */
    double mom[2][3] = {{0}};
    for (int k = 0; k < 2; k++) {
        const float *a = k ? img : ref;
        for (int iy = 1; iy < 5; iy++)
            for (int ix = 1; ix < 5; ix++) {
                const double w = fmax(a[ix + ns * iy] - t, 0.0);
                mom[k][0] += w;
                mom[k][1] += (ix - 2.5) * PIX * w;
                mom[k][2] += (iy - 2.5) * PIX * w;
            }
    }
    double sl[2];
    wt_centroid_apply(c, img, sl);
    ck_assert_double_eq_tol(sl[0], mom[1][1] / mom[1][0] - mom[0][1] / mom[0][0], 1e-12 * PIX);
    ck_assert_double_eq_tol(sl[1], mom[1][2] / mom[1][0] - mom[0][2] / mom[0][0], 1e-12 * PIX);
    /* nothing above the threshold: zero slopes */
    for (int j = 0; j < 36; j++) img[j] = (float)(0.5 * t);
    wt_centroid_apply(c, img, sl);
    ck_assert(sl[0] == 0.0 && sl[1] == 0.0);
    wt_centroid_free(c);
    free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

/* nsub random spots around the classes, offset and rotated */
static void random_sensor(int nsub, int ns, float **ref, float **dx, float **dy)
{
    spot *s = malloc(nsub * sizeof *s);
    wt_rng r;
    wt_rng_init(&r, 21, 0);
    for (int i = 0; i < nsub; i++) {
        s[i] = (spot){.flux = 200 + 800 * wt_rng_uniform(&r), .sl = (1 + 2 * wt_rng_uniform(&r)) * PIX,
                      .ss = (0.7 + 0.3 * wt_rng_uniform(&r)) * PIX, .ang = M_PI * wt_rng_uniform(&r),
                      .tx = 0.5 * (wt_rng_uniform(&r) - 0.5) * PIX, .ty = 0.5 * (wt_rng_uniform(&r) - 0.5) * PIX};
    }
    render_sensor(s, nsub, ns, ref, dx, dy);
    free(s);
}

START_TEST(test_threads)
{
    /* Slopes and the Monte-Carlo calibration bit-identical with 1 and 2 threads, every centroider. The
     * apply shares blocks of 64 subapertures among the threads: 150 makes 3 blocks, the last partial. */
    wt_context *ctx = tu_context();
    const int nsub = 150, ns = 8;
    float *ref, *dx, *dy;
    random_sensor(nsub, ns, &ref, &dx, &dy);
    float *img = malloc((size_t)nsub * ns * ns * sizeof *img);
    wt_rng r;
    wt_rng_init(&r, 3, 0);
    draw(&r, ref, (size_t)nsub * ns * ns, 1.0, 2.0, 1, img);
    for (int m = WT_CENTROID_COG; m <= WT_CENTROID_MF; m++) {
        double sl[2][2 * nsub], cv[2][3 * nsub], mn[2][2 * nsub];
        for (int t = 0; t < 2; t++) {
            wt_context_set_threads(ctx, t + 1);
            wt_centroid_params p = params(m, 1.0, 2.0);
            p.threshold_noise = 3;
            p.apply_gain = 1;
            wt_centroid *c = make(ctx, &p, nsub, ns, ref, dx, dy);
            wt_centroid_apply(c, img, sl[t]);
            ck_assert_int_eq(wt_centroid_noise_mc(c, ref, 20, 7, cv[t], mn[t]), WT_OK);
            wt_centroid_free(c);
        }
        ck_assert(memcmp(sl[0], sl[1], sizeof sl[0]) == 0);
        ck_assert(memcmp(cv[0], cv[1], sizeof cv[0]) == 0);
        ck_assert(memcmp(mn[0], mn[1], sizeof mn[0]) == 0);
    }
    free(img), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_no_alloc_per_frame)
{
    /* The per-frame apply makes no allocation (counted through the context's allocator). */
    wt_context *ctx = tu_context();
    tu_alloc a = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &a);
    wt_context_set_threads(ctx, 2);
    const int nsub = 20, ns = 8;
    float *ref, *dx, *dy;
    random_sensor(nsub, ns, &ref, &dx, &dy);
    double sl[2 * nsub];
    for (int m = WT_CENTROID_COG; m <= WT_CENTROID_MF; m++) {
        wt_centroid_params p = params(m, 0.5, 1.0);
        p.apply_gain = 1;
        wt_centroid *c = make(ctx, &p, nsub, ns, ref, dx, dy);
        const long before = a.count;
        for (int f = 0; f < 3; f++) wt_centroid_apply(c, ref, sl);
        ck_assert_int_eq(a.count, before);
        wt_centroid_free(c);
    }
    ck_assert_int_eq(a.live, 0);
    free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_alloc_failure)
{
    /* Every allocation of alloc and noise_mc refused in turn: WT_ERR_NOMEM, *out NULL, nothing leaked. */
    wt_context *ctx = tu_context();
    const int nsub = 3, ns = 6;
    float *ref, *dx, *dy;
    random_sensor(nsub, ns, &ref, &dx, &dy);
    int failures = 0;
    for (int k = 0; k < 20; k++) {
        tu_alloc f = TU_ALLOC_INIT;
        tu_alloc_fail_nth(&f, k);
        tu_alloc_install(ctx, &f);
        wt_centroid_params p = params(WT_CENTROID_MF, 0.5, 1.0);
        wt_centroid *c = NULL;
        double cov[3 * nsub];
        int st = wt_centroid_alloc(ctx, &p, nsub, ns, ref, dx, dy, &c);
        if (st != WT_OK) ck_assert_ptr_null(c);
        if (st == WT_OK) st = wt_centroid_noise_mc(c, ref, 3, 1, cov, NULL);
        if (st != WT_OK) {
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            failures++;
        }
        wt_centroid_free(c);
        ck_assert_int_eq(f.live, 0);
        if (f.count <= k) break;
    }
    ck_assert_int_ge(failures, 7);
    wt_context_set_allocator(ctx, NULL, NULL, NULL);
    free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

/* alloc must fail with WT_ERR_INVALID, leave *out NULL and name `what` in its message. */
static void expect_reject(wt_context *ctx, const wt_centroid_params *p, int nsub, int ns, const float *ref,
                          const float *dx, const float *dy, const char *what)
{
    wt_centroid *c = (wt_centroid *)&c;
    int st = wt_centroid_alloc(ctx, p, nsub, ns, ref, dx, dy, &c);
    ck_assert_int_eq(st, WT_ERR_INVALID);
    ck_assert_ptr_null(c);
    ck_assert_msg(strstr(wt_error_message(ctx), what), "message '%s' does not name '%s'", wt_error_message(ctx),
                  what);
    wt_error_clear(ctx);
}

START_TEST(test_bad_input)
{
    wt_context *ctx = tu_context();
    const int nsub = 2, ns = 8, npix = nsub * ns * ns;
    float *ref, *dx, *dy;
    random_sensor(nsub, ns, &ref, &dx, &dy);
    float *bad = malloc(npix * sizeof *bad);
    wt_centroid_params p = params(WT_CENTROID_COG, 0, 1);

    p.window = 10; /* Nw > Ns */
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "window");
    p.window = 5; /* not centred */
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "even");
    p.window = 0;
    p.read_noise = -1;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "read_noise");
    p.read_noise = NAN;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "read_noise");
    p.read_noise = 1;
    p.pixel = 0;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "pixel");
    p.pixel = PIX;
    p.background = -0.1;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "background");
    p.background = 0;
    p.threshold_peak = 1.0;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "threshold_peak");
    p.threshold_peak = 0;
    p.noise_calibrated = 2;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "noise_calibrated");
    p.noise_calibrated = 0;
    p.method = 7;
    expect_reject(ctx, &p, nsub, ns, ref, dx, dy, "method");
    p.method = WT_CENTROID_COG;
    expect_reject(ctx, &p, 0, ns, ref, dx, dy, "nsub");
    expect_reject(ctx, &p, nsub, 0, ref, dx, dy, "ns");
    expect_reject(ctx, NULL, nsub, ns, ref, dx, dy, "par");
    expect_reject(ctx, &p, nsub, ns, NULL, dx, dy, "ref");

    /* NaN in a reference image, negative intensity, Inf in a derivative: named with the pixel */
    memcpy(bad, ref, npix * sizeof *bad);
    bad[ns * ns + 3 + ns * 2] = NAN;
    expect_reject(ctx, &p, nsub, ns, bad, dx, dy, "ref[");
    expect_reject(ctx, &p, nsub, ns, bad, dx, dy, "subaperture 1, pixel (3, 2)");
    bad[ns * ns + 3 + ns * 2] = -1;
    expect_reject(ctx, &p, nsub, ns, bad, dx, dy, "ref[");
    memcpy(bad, dx, npix * sizeof *bad);
    bad[5] = INFINITY;
    expect_reject(ctx, &p, nsub, ns, ref, bad, dy, "dref_x[");

    /* zero-flux reference with the MF (and with the CoG) */
    memcpy(bad, ref, npix * sizeof *bad);
    memset(bad + ns * ns, 0, ns * ns * sizeof *bad);
    wt_centroid_params pm = params(WT_CENTROID_MF, 0, 1);
    expect_reject(ctx, &pm, nsub, ns, bad, dx, dy, "zero flux");
    expect_reject(ctx, &pm, nsub, ns, bad, dx, dy, "subaperture 1");
    expect_reject(ctx, &p, nsub, ns, bad, dx, dy, "no flux");
    /* the MF with a window, a derivative that is zero (singular MF, singular gain) */
    pm.window = 6;
    expect_reject(ctx, &pm, nsub, ns, ref, dx, dy, "window");
    pm.window = 0;
    memset(bad, 0, npix * sizeof *bad);
    expect_reject(ctx, &pm, nsub, ns, ref, dx, bad, "singular");
    p.apply_gain = 1;
    expect_reject(ctx, &p, nsub, ns, ref, dx, bad, "singular");
    /* a threshold above the peak leaves nothing */
    wt_centroid_params pt = params(WT_CENTROID_TCOG, 0, 1);
    pt.threshold_noise = 1e6;
    expect_reject(ctx, &pt, nsub, ns, ref, dx, dy, "threshold");

    /* Monte-Carlo arguments */
    wt_centroid *c = make(ctx, &p, nsub, ns, ref, dx, dy);
    double cov[3 * nsub];
    ck_assert_int_eq(wt_centroid_noise_mc(c, ref, 1, 1, cov, NULL), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "ndraws"));
    memcpy(bad, ref, npix * sizeof *bad);
    bad[0] = NAN;
    ck_assert_int_eq(wt_centroid_noise_mc(c, bad, 10, 1, cov, NULL), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "images["));
    wt_centroid_free(c);
    wt_centroid_free(NULL);
    free(bad), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("centroid");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_tilt_cog);
    tcase_add_test(tc, test_cog_clamped_to_window);
    tcase_add_test(tc, test_truncated_gain);
    tcase_add_test(tc, test_gain_fd);
    tcase_add_test(tc, test_mf_flux_column);
    tcase_add_test(tc, test_threshold);
    tcase_add_test(tc, test_threads);
    tcase_add_test(tc, test_no_alloc_per_frame);
    tcase_add_test(tc, test_alloc_failure);
    tcase_add_test(tc, test_bad_input);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
