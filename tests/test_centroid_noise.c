/* tests/test_centroid_noise.c: the centroiders of core/optics/centroid.c against noise: the tCoG calibrated at
 * the operating noise, the noise formulas of SPEC §4/§4b against noise draws (photon and read noise, the
 * matched filter unbiased and better), and the analytic (set-up) covariance against the Monte-Carlo calibration.
 * Spots and noise draws: centroid_fixture.h. */
#include "centroid_fixture.h"

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

Suite *make_suite(void)
{
    Suite *s = suite_create("centroid_noise");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_tcog_noise_calibrated);
    tcase_add_test(tc, test_cov_formula);
    tcase_add_test(tc, test_photon_noise_cog);
    tcase_add_test(tc, test_read_noise_cog);
    tcase_add_test(tc, test_mf_unbiased_better);
    tcase_add_test(tc, test_cov_analytic_vs_mc);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
