/* tests/test_centroid.c: the centroiders of core/optics/centroid.c (CoG, thresholded CoG, matched filter):
 * response to tilt and the calibrated gain, gains against finite differences, the noise formulas of
 * SPEC §4/§4b against noise draws, the analytic (set-up) covariance against the Monte-Carlo calibration,
 * thread-count independence, no allocation per frame, and rejected input.
 *
 * Spots are made here: pixel-integrated (rotated, anisotropic) Gaussians, integrated exactly (erf) across
 * the conditional axis and by Simpson's rule along the other, with analytic derivatives; noise draws use
 * an exact Poisson sampler by inversion written here (independent of the library's). */
#include "testutil.h"

#include "core/optics/centroid.h"

#define ARCSEC (M_PI / (180.0 * 3600.0)) /* [rad] */
static const double PIX = 1.0 * ARCSEC; /* pixel scale p of every test [rad] */

/* ---------- spots ---------- */

typedef struct spot {
    double flux;   /* photo-electrons of the whole (untruncated) spot */
    double sl, ss; /* rms width along and across the elongation [rad] */
    double ang;    /* direction of the elongation from +x [rad] */
    double tx, ty; /* centre [rad] */
} spot;

/* Normal cdf and pdf of N(0, s²) */
static double ncdf(double z, double s) { return 0.5 * erfc(-z / (s * M_SQRT2)); }
static double npdf(double z, double s) { return exp(-0.5 * z * z / (s * s)) / (s * sqrt(2.0 * M_PI)); }

/* Image (and derivatives w.r.t. the centre, NULL: not wanted) of a spot on ns x ns pixels of scale PIX.
 * The spot density is the marginal N(0, Σxx) in u = x − tx times the conditional y − ty | u ~
 * N(k u, sc²), k = Σxy/Σxx, sc² = Σyy − Σxy²/Σxx: the pixel's y extent integrates exactly (Φ), the x
 * extent by Simpson's rule over 64 intervals (error ~ (p/64)⁴ f'''' , < 1e-8 for widths ≳ p/2). The limits in
 * u move with tx, so ∂I/∂tx is the integrand at the two x edges (Leibniz); ∂I/∂ty differentiates Φ. */
static void render(const spot *s, int ns, float *img, float *dx, float *dy)
{
    const double ca = cos(s->ang), sa = sin(s->ang);
    const double sxx = s->sl * s->sl * ca * ca + s->ss * s->ss * sa * sa;
    const double syy = s->sl * s->sl * sa * sa + s->ss * s->ss * ca * ca;
    const double sxy = (s->sl * s->sl - s->ss * s->ss) * ca * sa;
    const double sx = sqrt(sxx), k = sxy / sxx, sc = sqrt(syy - sxy * sxy / sxx);
    const double c0 = 0.5 * (ns - 1);
    enum { NQ = 64 };
    for (int iy = 0; iy < ns; iy++) {
        const double ylo = (iy - c0 - 0.5) * PIX - s->ty, yhi = ylo + PIX;
        for (int ix = 0; ix < ns; ix++) {
            const double ulo = (ix - c0 - 0.5) * PIX - s->tx, h = PIX / NQ;
            double in = 0.0, iny = 0.0, edge[2] = {0.0, 0.0};
            for (int q = 0; q <= NQ; q++) {
                const double u = ulo + q * h, w = (q == 0 || q == NQ) ? 1.0 : (q % 2 ? 4.0 : 2.0);
                const double fx = npdf(u, sx);
                const double f = fx * (ncdf(yhi - k * u, sc) - ncdf(ylo - k * u, sc));
                in += w * f;
                iny += w * fx * (npdf(ylo - k * u, sc) - npdf(yhi - k * u, sc));
                if (q == 0) edge[0] = f;
                if (q == NQ) edge[1] = f;
            }
            const int j = ix + ns * iy;
            img[j] = (float)(s->flux * in * h / 3.0);
            if (dx) dx[j] = (float)(-s->flux * (edge[1] - edge[0]));
            if (dy) dy[j] = (float)(s->flux * iny * h / 3.0);
        }
    }
}

/* A sensor of nsub spots: ref, dx, dy each nsub·ns² (malloc'd; free with free). */
static void render_sensor(const spot *s, int nsub, int ns, float **ref, float **dx, float **dy)
{
    const size_t npix = (size_t)ns * ns;
    *ref = malloc(npix * nsub * sizeof **ref);
    *dx = malloc(npix * nsub * sizeof **dx);
    *dy = malloc(npix * nsub * sizeof **dy);
    for (int i = 0; i < nsub; i++) render(&s[i], ns, *ref + npix * i, *dx + npix * i, *dy + npix * i);
}

/* ---------- noise draws ---------- */

/* Exact Poisson deviate by inversion of the cdf from 0 (O(mu) per draw: fine for the means here, < 200). */
static double tpoisson(wt_rng *r, double mu)
{
    if (mu <= 0.0) return 0.0;
    double u = wt_rng_uniform(r), p = exp(-mu), f = p;
    long k = 0;
    while (u > f && p > 0.0) {
        k++;
        p *= mu / k;
        f += p;
    }
    return (double)k;
}

/* d = Poisson(I + B) + N(0, σe²) − B; photons = 0 leaves the photon noise out (d = I + N(0, σe²)). */
static void draw(wt_rng *r, const float *img, size_t n, double b, double se, int photons, float *d)
{
    for (size_t j = 0; j < n; j++) {
        double v = photons ? tpoisson(r, img[j] + b) - b : img[j];
        if (se > 0.0) v += se * wt_rng_normal(r);
        d[j] = (float)v;
    }
}

static wt_centroid_params params(int method, double b, double se)
{
    wt_centroid_params p = {.method = method, .pixel = PIX, .background = b, .read_noise = se};
    return p;
}

static wt_centroid *make(wt_context *ctx, const wt_centroid_params *p, int nsub, int ns, const float *ref,
                         const float *dx, const float *dy)
{
    wt_centroid *c = NULL;
    int st = wt_centroid_alloc(ctx, p, nsub, ns, ref, dx, dy, &c);
    ck_assert_msg(st == WT_OK, "alloc: %s", wt_error_message(ctx));
    return c;
}

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

/* The tCoG calibrated at the operating noise (noise_calibrated, centroid.h) against noisy frames: an
 * elongated spot of 100 e- on 10² pixels (σl = 2p, σs = 0.8p at 30°) with 3 e- read noise and a threshold
 * of f × peak. Over N Monte-Carlo frames (the library's own exact Poisson + Gaussian draws) the mean slope
 * of I0 must be ~0 (the reference is the expected estimator's value) and the mean response to a tilt of
 * ±0.25p the tilt (the gain is its derivative): within 4 % of the tilt + 4 standard errors. The Gaussian
 * approximation of the clipped pixels is what limits it (Poisson skew at a few e-). Measured: response
 * 1.004 / 0.998 of the tilt at f = 0.15 / 0.3, bias −0.003p (standard error 0.005p). The noise-free
 * calibration is checked to be off by more than that, or the test would show nothing: its response is
 * 0.476 / 0.472 (the clipped read noise of the empty pixels halves the tCoG's gain at these thresholds). */
static void tcog_mc(double f, int calibrated, double *bias, double *resp, double *se)
{
    wt_context *ctx = tu_context();
    const int ns = 10, nd = 20000;
    const double th = 0.25 * PIX;
    spot sp[3] = {{.flux = 100, .sl = 2.0 * PIX, .ss = 0.8 * PIX, .ang = 0.5}};
    sp[1] = sp[0], sp[2] = sp[0];
    sp[1].tx = th, sp[2].tx = -th;
    float *ref, *dx, *dy, *imgs;
    render_sensor(sp, 1, ns, &ref, &dx, &dy);
    float *r3, *d3x, *d3y;
    render_sensor(sp, 3, ns, &r3, &d3x, &d3y);
    imgs = r3;
    wt_centroid_params p = params(WT_CENTROID_TCOG, 0, 3.0);
    p.threshold_noise = 0.0;
    p.threshold_peak = f;
    p.apply_gain = 1;
    p.noise_calibrated = calibrated;
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    wt_centroid *c3 = NULL;
    /* the same calibration for all three images: three subapertures sharing subaperture 0's reference */
    float *rr = malloc(3 * ns * ns * sizeof *rr), *rx = malloc(3 * ns * ns * sizeof *rx), *ry = malloc(3 * ns * ns * sizeof *ry);
    for (int k = 0; k < 3; k++) {
        memcpy(rr + k * ns * ns, ref, ns * ns * sizeof *rr);
        memcpy(rx + k * ns * ns, dx, ns * ns * sizeof *rx);
        memcpy(ry + k * ns * ns, dy, ns * ns * sizeof *ry);
    }
    ck_assert(wt_centroid_alloc(ctx, &p, 3, ns, rr, rx, ry, &c3) == WT_OK);
    double cov[9], mean[6];
    ck_assert(wt_centroid_noise_mc(c3, imgs, nd, 11, cov, mean) == WT_OK);
    *bias = mean[0];
    *resp = 0.5 * (mean[1] - mean[2]);
    *se = sqrt(cov[0] / nd);
    wt_centroid_free(c), wt_centroid_free(c3);
    free(rr), free(rx), free(ry), free(ref), free(dx), free(dy), free(r3), free(d3x), free(d3y);
    wt_context_free(ctx);
}

START_TEST(test_tcog_noise_calibrated)
{
    const double th = 0.25 * PIX;
    for (int q = 0; q < 2; q++) {
        const double f = q ? 0.3 : 0.15;
        double b1, r1, s1, b0, r0, s0;
        tcog_mc(f, 1, &b1, &r1, &s1);
        tcog_mc(f, 0, &b0, &r0, &s0);
        ck_assert_msg(fabs(b1) < 0.04 * th + 4 * s1, "f %g: bias %g p", f, b1 / PIX);
        ck_assert_msg(fabs(r1 - th) < 0.04 * th + 4 * s1, "f %g: response %g of the tilt", f, r1 / th);
        ck_assert_msg(fabs(r0 - th) > 0.04 * th + 4 * s0 || fabs(b0) > 0.04 * th + 4 * s0, "f %g: the noise-free "
                      "calibration is as good (bias %g p, response %g)", f, b0 / PIX, r0 / th);
    }
}
END_TEST

START_TEST(test_cov_formula)
{
    /* The set-up covariance against the formulas of centroid.h written out here, on an off-centre
     * elongated spot (so the reference centroid (x0, y0) ≠ 0 and the gain is not diagonal): CoG over a
     * 6² window of 8², Σ_ab = Σ_W (a_j − a0)(b_j − b0) V_j / N0², then g⁻¹ Σ g⁻ᵀ with the reported gain;
     * the MF's R C Rᵀ against the top-left 2x2 of (Gᵀ C⁻¹ G)⁻¹ (equal when C is the noise: the float rows
     * round to ~1e-7). Double sums of the same terms: 1e-10 for the CoG. */
    wt_context *ctx = tu_context();
    const int ns = 8;
    const double b = 2.0, se = 1.5;
    spot s0 = {.flux = 700, .sl = 2.2 * PIX, .ss = 0.9 * PIX, .ang = 0.7, .tx = 1.2 * PIX, .ty = -0.8 * PIX};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_COG, b, se);
    p.window = 6;
    p.apply_gain = 1;
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double n0 = 0, x0 = 0, y0 = 0, sxx = 0, sxy = 0, syy = 0, g[4], cov[3];
    for (int pass = 0; pass < 2; pass++)
        for (int iy = 1; iy < 7; iy++)
            for (int ix = 1; ix < 7; ix++) {
                const double i0 = ref[ix + ns * iy], x = (ix - 3.5) * PIX, y = (iy - 3.5) * PIX;
                if (pass == 0) {
                    n0 += i0, x0 += x * i0, y0 += y * i0;
                } else {
                    const double v = i0 + b + se * se, ax = x - x0 / n0, ay = y - y0 / n0;
                    sxx += ax * ax * v, sxy += ax * ay * v, syy += ay * ay * v;
                }
            }
    sxx /= n0 * n0, sxy /= n0 * n0, syy /= n0 * n0;
    ck_assert_msg(hypot(x0, y0) / n0 > 0.5 * PIX, "the reference centroid should be off-centre");
    wt_centroid_gain(c, 0, g);
    const double det = g[0] * g[3] - g[1] * g[2], h[4] = {g[3] / det, -g[1] / det, -g[2] / det, g[0] / det};
    /* h Σ hᵀ */
    const double exx = h[0] * (h[0] * sxx + h[1] * sxy) + h[1] * (h[0] * sxy + h[1] * syy);
    const double exy = h[2] * (h[0] * sxx + h[1] * sxy) + h[3] * (h[0] * sxy + h[1] * syy);
    const double eyy = h[2] * (h[2] * sxx + h[3] * sxy) + h[3] * (h[2] * sxy + h[3] * syy);
    wt_centroid_noise_cov(c, cov);
    ck_assert_rel(cov[0], exx, 1e-10, 0);
    ck_assert_rel(cov[2], eyy, 1e-10, 0);
    ck_assert_double_eq_tol(cov[1], exy, 1e-10 * sqrt(exx * eyy));
    wt_centroid_free(c);

    /* MF: M = Gᵀ C⁻¹ G (2x2), its inverse */
    double m[3] = {0};
    for (int j = 0; j < ns * ns; j++) {
        const double v = ref[j] + b + se * se;
        m[0] += (double)dx[j] * dx[j] / v, m[1] += (double)dx[j] * dy[j] / v, m[2] += (double)dy[j] * dy[j] / v;
    }
    const double dm = m[0] * m[2] - m[1] * m[1];
    wt_centroid_params pm = params(WT_CENTROID_MF, b, se);
    c = make(ctx, &pm, 1, ns, ref, dx, dy);
    wt_centroid_noise_cov(c, cov);
    ck_assert_rel(cov[0], m[2] / dm, 1e-6, 0);
    ck_assert_rel(cov[2], m[0] / dm, 1e-6, 0);
    ck_assert_double_eq_tol(cov[1], -m[1] / dm, 1e-6 * sqrt(m[0] * m[2]) / dm);
    wt_centroid_free(c);
    free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

/* Sample variance of x (n values). */
static double sample_var(const double *x, int n, double *mean)
{
    double m = 0, v = 0;
    for (int i = 0; i < n; i++) m += x[i];
    m /= n;
    for (int i = 0; i < n; i++) v += (x[i] - m) * (x[i] - m);
    if (mean) *mean = m;
    return v / (n - 1);
}

START_TEST(test_photon_noise_cog)
{
    /* Photon noise only, a well-sampled Gaussian (θf = 4p, σ = 1.70p) fully on 16² pixels, N = 1000:
     * SPEC §4's σ² = θf²/(8 ln2 N) is the CoG variance of the unpixelated spot, σ_spot²/N; the pixels add
     * their own variance p²/12 (Sheppard), so the linearised CoG variance is (σ_spot² + p²/12)/N, 2.9 % above
     * the SPEC form: that is the model error. K = 5000 draws, x and y pooled (10000 nearly independent
     * values): the variance estimate has a relative sd √(2/10⁴) = 1.4 %, so 10 % against SPEC's form holds
     * the 2.9 % plus 5 sd; the exact linearisation (whose remaining error, the ratio's second order 1/N,
     * is 0.1 %) holds within 5 sd = 7 %. The set-up's analytic variance is the latter to its 1e-3 (Sheppard's
     * correction is itself exact only up to the Gaussian tails of the pixel sums: measured < 1e-4). */
    wt_context *ctx = tu_context();
    const int ns = 16, k = 5000;
    const double fwhm = 4 * PIX, sig = fwhm / (2 * sqrt(2 * log(2.0))), n = 1000;
    spot s0 = {.flux = n, .sl = sig, .ss = sig};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_COG, 0, 0);
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double *x = malloc(2 * k * sizeof *x), sl[2];
    float *d = malloc(ns * ns * sizeof *d);
    wt_rng r;
    wt_rng_init(&r, 11, 0);
    for (int q = 0; q < k; q++) {
        draw(&r, ref, ns * ns, 0, 0, 1, d);
        wt_centroid_apply(c, d, sl);
        x[q] = sl[0];
        x[k + q] = sl[1];
    }
    const double v = sample_var(x, 2 * k, NULL);
    const double spec = fwhm * fwhm / (8 * log(2.0) * n), lin = (sig * sig + PIX * PIX / 12) / n;
    ck_assert_rel(v, spec, 0.10, 0);
    ck_assert_rel(v, lin, 0.07, 0);
    double cov[3];
    wt_centroid_noise_cov(c, cov);
    ck_assert_rel(cov[0], lin, 1e-3, 0);
    ck_assert_rel(cov[2], lin, 1e-3, 0);
    ck_assert_double_eq_tol(cov[1], 0.0, 1e-6 * lin);
    wt_centroid_free(c);
    free(x), free(d), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_read_noise_cog)
{
    /* Read noise only (d = I0 + N(0, σe²), no photon noise), CoG over all Ns² = 16² pixels, N = 1000,
     * σe = 3. Linearising Σ x d / Σ d around I0 (centroid 0) gives σ² = σe² Σ x_j² / N² with
     * Σ x_j² = p² Ns · Ns(Ns² − 1)/12, i.e. p²σe²Ns²(Ns² − 1)/(12 N²): that is the exact first order.
     * SPEC §4's p²σe²Ns⁴/(12N²) is its large-Ns limit (relative error 1/Ns² = 0.4 % here); the ratio's
     * second order adds ~3 Ns²σe²/N² = 0.7 %. K = 5000 draws pooled over x and y: sd 1.4 %. Hence
     * 10 % against SPEC's form, 7 % (5 sd) against the linearisation. */
    wt_context *ctx = tu_context();
    const int ns = 16, k = 5000;
    const double sig = 1.7 * PIX, n = 1000, se = 3;
    spot s0 = {.flux = n, .sl = sig, .ss = sig};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    wt_centroid_params p = params(WT_CENTROID_COG, 0, se);
    wt_centroid *c = make(ctx, &p, 1, ns, ref, dx, dy);
    double *x = malloc(2 * k * sizeof *x), sl[2];
    float *d = malloc(ns * ns * sizeof *d);
    wt_rng r;
    wt_rng_init(&r, 12, 0);
    for (int q = 0; q < k; q++) {
        draw(&r, ref, ns * ns, 0, se, 0, d);
        wt_centroid_apply(c, d, sl);
        x[q] = sl[0];
        x[k + q] = sl[1];
    }
    const double v = sample_var(x, 2 * k, NULL), n2 = (double)ns * ns;
    const double spec = PIX * PIX * se * se * n2 * n2 / (12 * n * n);
    const double lin = PIX * PIX * se * se * n2 * (n2 - 1) / (12 * n * n);
    ck_assert_rel(v, spec, 0.10, 0);
    ck_assert_rel(v, lin, 0.07, 0);
    /* the set-up's covariance carries photon and read noise: (σ_spot² + p²/12)/N + the read term */
    double cov[3];
    wt_centroid_noise_cov(c, cov);
    ck_assert_rel(cov[0], (sig * sig + PIX * PIX / 12) / n + lin, 1e-3, 0);
    wt_centroid_free(c);
    free(x), free(d), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_mf_unbiased_better)
{
    /* An elongated spot (σl = 3p, σs = 0.8p at 30°) of 100 photons on 16² pixels with σe = 1: the MF's
     * mean over K = 2000 draws at a tilt of (0.1p, −0.05p) is the tilt within 3 sd/√K per axis (its bias
     * is third order in the tilt for a symmetric spot, ~1e-4 p here, far below 3 sd/√K ~ 0.02p), and its
     * variance is below the gain-corrected CoG's on the same draws (the CoG's wide window collects the read
     * noise of every empty pixel; the MF weights pixels by signal/noise). */
    wt_context *ctx = tu_context();
    const int ns = 16, k = 2000;
    spot s0 = {.flux = 100, .sl = 3 * PIX, .ss = 0.8 * PIX, .ang = M_PI / 6};
    float *ref, *dx, *dy;
    render_sensor(&s0, 1, ns, &ref, &dx, &dy);
    spot s1 = s0;
    s1.tx = 0.1 * PIX;
    s1.ty = -0.05 * PIX;
    float *img = malloc(ns * ns * sizeof *img), *d = malloc(ns * ns * sizeof *d);
    render(&s1, ns, img, NULL, NULL);
    wt_centroid_params pm = params(WT_CENTROID_MF, 0, 1), pc = params(WT_CENTROID_COG, 0, 1);
    pm.apply_gain = pc.apply_gain = 1;
    wt_centroid *mf = make(ctx, &pm, 1, ns, ref, dx, dy), *cog = make(ctx, &pc, 1, ns, ref, dx, dy);
    double *x = malloc(4 * k * sizeof *x), sl[2];
    wt_rng r;
    wt_rng_init(&r, 13, 0);
    for (int q = 0; q < k; q++) {
        draw(&r, img, ns * ns, 0, 1, 1, d);
        wt_centroid_apply(mf, d, sl);
        x[q] = sl[0], x[k + q] = sl[1];
        wt_centroid_apply(cog, d, sl);
        x[2 * k + q] = sl[0], x[3 * k + q] = sl[1];
    }
    double mx, my, cx, cy;
    const double vx = sample_var(x, k, &mx), vy = sample_var(x + k, k, &my);
    const double wx = sample_var(x + 2 * k, k, &cx), wy = sample_var(x + 3 * k, k, &cy);
    ck_assert_msg(fabs(mx - s1.tx) < 3 * sqrt(vx / k), "MF mean x %g vs %g (sd/√K %g)", mx, s1.tx, sqrt(vx / k));
    ck_assert_msg(fabs(my - s1.ty) < 3 * sqrt(vy / k), "MF mean y %g vs %g (sd/√K %g)", my, s1.ty, sqrt(vy / k));
    ck_assert_msg(vx + vy < wx + wy, "MF variance %g not below CoG %g", vx + vy, wx + wy);
    ck_assert_msg(vx < wx && vy < wy, "per axis: MF %g %g, CoG %g %g", vx, vy, wx, wy);
    wt_centroid_free(mf);
    wt_centroid_free(cog);
    free(x), free(img), free(d), free(ref), free(dx), free(dy);
    wt_context_free(ctx);
}
END_TEST

/* The subaperture classes of the covariance test: unelongated, elongated at three angles (one off-centre),
 * truncated (off-centre). */
enum { NCLASS = 5, CNS = 10 };
static void classes(spot *s)
{
    const double n = 500;
    s[0] = (spot){.flux = n, .sl = 1.0 * PIX, .ss = 1.0 * PIX};
    s[1] = (spot){.flux = n, .sl = 2.0 * PIX, .ss = 0.8 * PIX, .ang = 0};
    s[2] = (spot){.flux = n, .sl = 2.0 * PIX, .ss = 0.8 * PIX, .ang = 35 * M_PI / 180, .tx = 0.3 * PIX, .ty = -0.2 * PIX};
    s[3] = (spot){.flux = n, .sl = 2.0 * PIX, .ss = 0.8 * PIX, .ang = 80 * M_PI / 180};
    s[4] = (spot){.flux = n, .sl = 4.0 * PIX, .ss = 0.8 * PIX, .ang = 45 * M_PI / 180, .tx = 0.5 * PIX, .ty = 0.4 * PIX};
}

START_TEST(test_cov_analytic_vs_mc)
{
    /* The set-up (analytic, first-order) covariance against the Monte-Carlo calibration (exact Poisson +
     * Gaussian) per class, for every centroider with the gain applied. N = 500, B = 1, σe = 2 on 10²
     * pixels. K = 8000 draws: a variance estimate has relative sd √(2/K) = 1.6 %, so 15 % holds 3 sd plus
     * ~10 % of model error. The MF is linear: MC = analytic up to the sampling (measured within 2.5 sd on
     * three seeds). The CoG adds the ratio's second order (~3 Var(Σd)/N², measured +2…5 %); the tCoG also
     * the Gaussian approximation of the Poisson pixels near the threshold, whose right skew puts more of
     * them above T than the model does (measured +3…10 %, largest on the truncated spot whose inverse gain
     * amplifies it). Σxy is compared on the scale √(ΣxxΣyy). */
    wt_context *ctx = tu_context();
    spot s[NCLASS];
    classes(s);
    float *ref, *dx, *dy;
    render_sensor(s, NCLASS, CNS, &ref, &dx, &dy);
    const int k = 8000;
    const char *name[] = {"CoG", "CoG window 8", "tCoG", "MF", "MF+flux"};
    for (int m = 0; m < 5; m++) {
        wt_centroid_params p = params(m == 0 || m == 1 ? WT_CENTROID_COG : m == 2 ? WT_CENTROID_TCOG : WT_CENTROID_MF,
                                      1.0, 2.0);
        p.apply_gain = 1;
        p.window = m == 1 ? 8 : 0;
        p.threshold_noise = 3.0;
        p.mf_flux = m == 4;
        wt_centroid *c = make(ctx, &p, NCLASS, CNS, ref, dx, dy);
        double ca[3 * NCLASS], cm[3 * NCLASS], mean[2 * NCLASS];
        wt_centroid_noise_cov(c, ca);
        ck_assert_int_eq(wt_centroid_noise_mc(c, ref, k, 99, cm, mean), WT_OK);
        for (int i = 0; i < NCLASS; i++) {
            const double axx = ca[i], axy = ca[NCLASS + i], ayy = ca[2 * NCLASS + i];
            const double mxx = cm[i], mxy = cm[NCLASS + i], myy = cm[2 * NCLASS + i];
            ck_assert_msg(fabs(mxx - axx) <= 0.15 * axx && fabs(myy - ayy) <= 0.15 * ayy &&
                              fabs(mxy - axy) <= 0.15 * sqrt(axx * ayy),
                          "%s class %d: analytic {%.4g %.4g %.4g}, MC {%.4g %.4g %.4g} [p²]", name[m], i, axx / (PIX * PIX),
                          axy / (PIX * PIX), ayy / (PIX * PIX), mxx / (PIX * PIX), mxy / (PIX * PIX), myy / (PIX * PIX));
        }
        wt_centroid_free(c);
    }
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
    tcase_add_test(tc, test_tcog_noise_calibrated);
    tcase_add_test(tc, test_cov_formula);
    tcase_add_test(tc, test_photon_noise_cog);
    tcase_add_test(tc, test_read_noise_cog);
    tcase_add_test(tc, test_mf_unbiased_better);
    tcase_add_test(tc, test_cov_analytic_vs_mc);
    tcase_add_test(tc, test_threads);
    tcase_add_test(tc, test_no_alloc_per_frame);
    tcase_add_test(tc, test_alloc_failure);
    tcase_add_test(tc, test_bad_input);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
