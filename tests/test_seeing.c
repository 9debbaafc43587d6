/* tests/test_seeing.c: the von Kármán structure function and a subaperture's mean short-exposure seeing
 * (core/optics/seeing.h): the Kolmogorov limit 6.88 (ρ/r0)^(5/3), the outer scale's saturation at twice
 * the phase variance, the rendered spectrum below the sky's; W(0) = 1, W even, no seeing for r0 → ∞;
 * the reference image with seeing against the Monte-Carlo mean of images of Gaussian phase screens with
 * the same covariance (the exactness of the OTF route); the elongation's sense against the OPD of the
 * path-length difference of a source at another altitude (spot.h); a new sodium profile's spots where the
 * launch geometry puts them, and the reference rebuilt from kept cells (SPEC §12 "The sodium layer changes"). */
#include "testutil.h"

#include <lapacke.h>

#include "core/optics/seeing.h"
#include "core/optics/sodium.h"
#include "core/optics/spot.h"

#define AS (M_PI / 180.0 / 3600.0)
#define K500 (2.0 * M_PI / 500e-9)

START_TEST(t_kolmogorov_limit)
{
    /* D_φ(ρ) = 2 ∫ 0.0229 r0^(−5/3) κ^(−11/3) (1 − cos 2πκ·ρ) d²κ = 6.8851 (ρ/r0)^(5/3): the classical pair
     * 0.022896 ↔ 6.88388 scaled by 0.0229/0.022896; the quadrature (Simpson in ln κ, tail in closed form)
     * must hold it to 1e-3 */
    const double r0 = 0.15;
    for (double rho = 0.001; rho < 2.0; rho *= 3.7) {
        const double d = K500 * K500 * wt_seeing_structure(rho, r0, INFINITY, 0.0);
        ck_assert_rel(d, 6.8851 * pow(rho / r0, 5.0 / 3.0), 1e-3, 0);
    }
    ck_assert_double_eq(wt_seeing_structure(0.0, r0, 25.0, 0.0), 0.0);
}
END_TEST

START_TEST(t_outer_scale_saturates)
{
    /* σ² = ∫ Φ d²κ = 2π c ∫ κ (κ² + L0⁻²)^(−11/6) dκ = 2π c (3/5) L0^(5/3), c = (λ0/2π)² 0.0229 r0^(−5/3):
     * D(ρ) → 2σ² for ρ ≫ L0 (the covariance decays as e^(−2πρ/L0)); at ρ = 40 L0 within 1e-3. Below L0 the
     * von Kármán D is below Kolmogorov's, and a rendering grid only removes power. */
    const double r0 = 0.129, L0 = 25.0, c = 0.0229 * pow(r0, -5.0 / 3.0) / (K500 * K500);
    const double sig2 = 2.0 * M_PI * c * 0.6 * pow(L0, 5.0 / 3.0);
    ck_assert_rel(wt_seeing_structure(40.0 * L0, r0, L0, 0.0), 2.0 * sig2, 1e-3, 0);
    for (double rho = 0.01; rho < 10.0; rho *= 2.5) {
        const double vk = wt_seeing_structure(rho, r0, L0, 0.0);
        ck_assert_double_lt(vk, wt_seeing_structure(rho, r0, INFINITY, 0.0));
        ck_assert_double_lt(wt_seeing_structure(rho, r0, L0, 0.125), vk);
    }
}
END_TEST

START_TEST(t_otf_properties)
{
    /* W(0) = 1 and W(−u) = W(u) on a fully and a partly lit subaperture; 0 < W ≤ 1 where lit pairs exist
     * (an average of exponentials of −D̃/2 ≤ 0); W → 1 for a weak atmosphere (r0 = 1e4 m: D̃ ~ 1e-7 rad²) */
    wt_context *ctx = tu_context();
    const int np = 8, N = 16;
    double Dl[64], *work = malloc(wt_seeing_work_size(np) * sizeof *work);
    float amp[64], W[256];
    for (int t = 0; t < 2; t++) {
        for (int i = 0; i < 64; i++) amp[i] = t == 0 ? 1.0f : (i % 8 < 3 ? 0.0f : (i % 8 == 3 ? 0.4f : 1.0f));
        ck_assert_int_eq(wt_seeing_lag_table(ctx, np, 0.5 / np, 589e-9, 0.129, 25.0, 0.0, Dl), WT_OK);
        wt_seeing_otf(np, 0, Dl, amp, N, W, work);
        ck_assert_rel(W[0], 1.0, 1e-6, 0);
        for (int uy = -(np - 1); uy < np; uy++)
            for (int ux = -(np - 1); ux < np; ux++) {
                const float a = W[(ux + N) % N + N * ((uy + N) % N)], b = W[(-ux + N) % N + N * ((-uy + N) % N)];
                ck_assert_rel(a, b, 1e-6, 1e-12);
                ck_assert_float_le(a, 1.0f + 1e-6f);
                if (t == 0) ck_assert_float_gt(a, 0.0f);
            }
        ck_assert_int_eq(wt_seeing_lag_table(ctx, np, 0.5 / np, 589e-9, 1e4, 25.0, 0.0, Dl), WT_OK);
        wt_seeing_otf(np, 1, Dl, amp, N, W, work);
        for (int q = 0; q < N * N; q++)
            if (W[q] != 0.0f) ck_assert_rel(W[q], 1.0, 1e-6, 0);
    }
    /* bad input named */
    ck_assert_int_eq(wt_seeing_lag_table(ctx, np, 0.5 / np, 589e-9, -1.0, 25.0, 0.0, Dl), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "r0"));
    free(work);
    wt_context_free(ctx);
}
END_TEST

/* second moments of an image about its centroid, per axis [rad²], and its sum */
static void moments2(const float *img, int Ns, double p, double *s, double *vx, double *vy)
{
    double s0 = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
    for (int iy = 0; iy < Ns; iy++)
        for (int ix = 0; ix < Ns; ix++) {
            const double v = img[ix + Ns * iy], x = (ix - 0.5 * (Ns - 1)) * p, y = (iy - 0.5 * (Ns - 1)) * p;
            s0 += v, sx += v * x, sy += v * y, sxx += v * x * x, syy += v * y * y;
        }
    *s = s0, *vx = sxx / s0 - (sx / s0) * (sx / s0), *vy = syy / s0 - (sy / s0) * (sy / s0);
}

START_TEST(t_reference_is_mean_of_screens)
{
    /* The reference with seeing is E|FFT(A e^{ikφ̃})|² imaged: draw φ̃ = (I − T) L z (C = L Lᵀ the OPD
     * covariance on the 8 × 8 samples from the lag table, T removing the piston and the G-tilt), image each draw
     * with the same spot model, and average 4000 of them. Pixel by pixel the mean must agree with the
     * reference within 5 standard errors of the mean (estimated from the draws themselves) plus 2e-4 of
     * the peak (the float pipeline); the flat-wavefront reference must not (the seeing is resolved). */
    wt_context *ctx = tu_context();
    const int np = 8, N = 16, Ns = 12, n = np * np, draws = 4000;
    const double lam = 589e-9, d = 0.5, r0 = 0.129, L0 = 25.0, k = 2 * M_PI / lam;
    wt_spot_params p = {0};
    p.wavelength = lam, p.subap_side = d, p.pupil_samples = np, p.fft_size = N, p.npix = Ns;
    p.pixel = 0.4 * AS, p.cells_per_pixel = 3, p.photons = 1000, p.uplink_fwhm = 0.5 * AS;
    double xc = 0, yc = 0;
    wt_spot *s = NULL;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_OK);
    float *ref = malloc(Ns * Ns * sizeof *ref), *flat = malloc(Ns * Ns * sizeof *flat), *img = malloc(Ns * Ns * sizeof *img);
    const wt_spot_seeing see = {.r0 = r0, .L0 = L0, .grid = 0.0};
    ck_assert_int_eq(wt_spot_reference(s, 0, &see, ref, NULL, NULL), WT_OK);
    ck_assert_int_eq(wt_spot_reference(s, 0, NULL, flat, NULL, NULL), WT_OK);
    /* the OPD covariance, C_ab = B(0) − D_ab/2 with B(0) = σ² (positive definite) */
    double Dl[64], *C = malloc((size_t)n * n * sizeof *C), *L = malloc((size_t)n * n * sizeof *L);
    ck_assert_int_eq(wt_seeing_lag_table(ctx, np, d / np, lam, r0, L0, 0.0, Dl), WT_OK);
    const double c0 = 0.0229 * pow(r0, -5.0 / 3.0) / (K500 * K500), sig2 = 2 * M_PI * c0 * 0.6 * pow(L0, 5.0 / 3.0);
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++)
            C[a + (size_t)n * b] = k * k * sig2 - 0.5 * Dl[abs(a % np - b % np) + np * abs(a / np - b / np)];
    memcpy(L, C, (size_t)n * n * sizeof *L);
    ck_assert_int_eq(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', n, L, n), 0);
    double *m1 = calloc(Ns * Ns, sizeof *m1), *m2 = calloc(Ns * Ns, sizeof *m2), z[64], phi[64], opd[64];
    wt_rng r;
    wt_rng_init(&r, 17, 0);
    for (int t = 0; t < draws; t++) {
        for (int a = 0; a < n; a++) z[a] = wt_rng_normal(&r);
        for (int a = 0; a < n; a++) {
            double v = 0;
            for (int b = 0; b <= a; b++) v += L[a + (size_t)n * b] * z[b];
            phi[a] = v;
        }
        /* less the piston and the G-tilt (the mean difference of neighbouring samples), as the reference */
        double mp = 0, gx = 0, gy = 0;
        for (int a = 0; a < n; a++) {
            mp += phi[a] / n;
            if (a % np + 1 < np) gx += (phi[a + 1] - phi[a]) / (np * (np - 1));
            if (a / np + 1 < np) gy += (phi[a + np] - phi[a]) / (np * (np - 1));
        }
        for (int a = 0; a < n; a++) {
            const double x = a % np - 0.5 * (np - 1), y = a / np - 0.5 * (np - 1);
            opd[a] = (phi[a] - mp - gx * x - gy * y) / k;
        }
        ck_assert_int_eq(wt_spot_image_d(s, opd, img), WT_OK);
        for (int q = 0; q < Ns * Ns; q++) m1[q] += img[q], m2[q] += (double)img[q] * img[q];
    }
    double peak = 0, off_flat = 0;
    for (int q = 0; q < Ns * Ns; q++) peak = fmax(peak, ref[q]);
    for (int q = 0; q < Ns * Ns; q++) {
        const double mean = m1[q] / draws, se = sqrt(fmax(m2[q] / draws - mean * mean, 0) / draws);
        ck_assert_msg(fabs(mean - ref[q]) <= 5 * se + 2e-4 * peak, "pixel %d: mean of draws %g, reference %g (se %g)", q,
                      mean, ref[q], se);
        off_flat = fmax(off_flat, fabs(mean - flat[q]) / (5 * se + 2e-4 * peak));
    }
    ck_assert_double_gt(off_flat, 3.0);
    double s0, vx, vy, f0, fx, fy;
    moments2(ref, Ns, p.pixel, &s0, &vx, &vy);
    moments2(flat, Ns, p.pixel, &f0, &fx, &fy);
    ck_assert_rel(s0, f0, 1e-4, 0); /* the seeing moves no flux */
    ck_assert_double_gt(vx, fx);
    free(C), free(L), free(m1), free(m2), free(ref), free(flat), free(img);
    wt_spot_free(s);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_sodium_shift_is_focus)
{
    /* The spot of a thin sodium layer at h (focus at H) lies where the OPD of the path-length difference
     * of a point source at (l, h) against one at (l, H), |x − l|² … = √(|x − l|² + h²) − √(|x − l|² + H²),
     * moves the spot of a thin layer at H: both are the gradient (r − l)(1/h − 1/H) (spot.h). Subaperture
     * 3 m from the launch, h − H = ±5 km: shifts of ∓0.36″, inside the FFT's 3.9″ field. The CoG is exact
     * for both, so they agree to the sampling of the curvature across the subaperture (< 1e-3); the
     * linear parallax (h − H)/H² would differ by 6 % and the mirrored sense by 200 %. */
    wt_context *ctx = tu_context();
    const double H = 90e3, lx = 20.0, ly = -1.0, xc = 17.6, yc = 0.8;
    wt_spot_params p = {0};
    p.wavelength = 589e-9, p.subap_side = 0.5, p.pupil_samples = 16, p.fft_size = 32, p.npix = 24;
    p.pixel = 0.25 * AS, p.cells_per_pixel = 3, p.photons = 1000, p.uplink_fwhm = 0.5 * AS;
    p.lgs_altitude = H, p.launch_x = lx, p.launch_y = ly;
    for (int sg = -1; sg <= 1; sg += 2) {
        const double h = H + sg * 5e3;
        /* thin triangles (±20 m) at h and at H on a table that contains H */
        double alt[5], dens[5] = {0, 0, 1, 0, 0};
        wt_sodium *nh = NULL, *nH = NULL;
        for (int w = 0; w < 2; w++) {
            const double c = w ? H : h;
            alt[0] = fmin(h, H) - 6e3, alt[1] = c - 20, alt[2] = c, alt[3] = c + 20, alt[4] = fmax(h, H) + 6e3;
            ck_assert_int_eq(wt_sodium_from_table(ctx, 5, alt, dens, "thin", w ? &nH : &nh), WT_OK);
        }
        wt_spot *sh = NULL, *sH = NULL;
        p.sodium = nh;
        ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &sh), WT_OK);
        p.sodium = nH;
        ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &sH), WT_OK);
        double opd0[256] = {0}, opd[256];
        for (int j = 0; j < 16; j++)
            for (int i = 0; i < 16; i++) {
                const double x = xc + (i + 0.5 - 8) * 0.5 / 16 - lx, y = yc + (j + 0.5 - 8) * 0.5 / 16 - ly;
                opd[i + 16 * j] = sqrt(x * x + y * y + h * h) - sqrt(x * x + y * y + H * H) - (h - H);
            }
        const double want[2] = {(xc - lx) * (1 / h - 1 / H), (yc - ly) * (1 / h - 1 / H)};
        /* the OPD's spot goes through the FFT, whose periodic field folds the diffraction tails back and
         * lowers the CoG's response to a tilt by ~4/(π² n_p) (spot.h): divide by that response, measured
         * with a pure tilt of the same size (the curvature across 0.5 m is 1e-4 of the tilt) */
        double tilt[256];
        for (int j = 0; j < 16; j++)
            for (int i = 0; i < 16; i++)
                tilt[i + 16 * j] = want[0] * (i + 0.5 - 8) * 0.5 / 16 + want[1] * (j + 0.5 - 8) * 0.5 / 16;
        float a[576], b[576], c[576];
        ck_assert_int_eq(wt_spot_image_d(sh, opd0, a), WT_OK);
        ck_assert_int_eq(wt_spot_image_d(sH, opd, b), WT_OK);
        ck_assert_int_eq(wt_spot_image_d(sH, tilt, c), WT_OK);
        double ca[2] = {0}, cb[2] = {0}, cc[2] = {0}, sa = 0, sb = 0, sc = 0;
        for (int q = 0; q < 576; q++) {
            const double x = (q % 24 - 11.5) * p.pixel, y = (q / 24 - 11.5) * p.pixel;
            sa += a[q], ca[0] += a[q] * x, ca[1] += a[q] * y;
            sb += b[q], cb[0] += b[q] * x, cb[1] += b[q] * y;
            sc += c[q], cc[0] += c[q] * x, cc[1] += c[q] * y;
        }
        for (int ax = 0; ax < 2; ax++) {
            ck_assert_rel(ca[ax] / sa, want[ax], 2e-3, 1e-3 * AS);
            ck_assert_rel(cb[ax] / sb / (cc[ax] / sc / want[ax]), want[ax], 2e-3, 1e-3 * AS);
        }
        wt_spot_free(sh), wt_spot_free(sH), wt_sodium_free(nh), wt_sodium_free(nH);
    }
    wt_context_free(ctx);
}
END_TEST

/* ⟨1/h⟩ of the piecewise-linear profile by the midpoint rule on 2000 steps per segment (the integrand's
 * curvature across a 0.5 km segment at 90 km makes it exact to ~1e-12) */
static double mean_inv_h(const wt_sodium *na)
{
    double m = 0, m1 = 0;
    for (int i = 0; i + 1 < na->n; i++)
        for (int j = 0; j < 2000; j++) {
            const double t = (j + 0.5) / 2000, h = na->alt[i] + t * (na->alt[i + 1] - na->alt[i]);
            const double f = (na->dens[i] + t * (na->dens[i + 1] - na->dens[i])) * (na->alt[i + 1] - na->alt[i]);
            m += f, m1 += f / h;
        }
    return m1 / m;
}

START_TEST(t_new_profile_moves_spots)
{
    /* The spots of a sodium profile that rose by 1 km (wt_spot_set_sodium on the same object): every spot's
     * centroid moves by (r − l)(⟨1/h⟩₁ − ⟨1/h⟩₀) (spot.h: each altitude at (r − l)(1/h − 1/H)), towards the
     * launch, proportional to the distance from it: the focus of a source that moved away. The images of a
     * flat wavefront, on a field (24 × 0.5″) that holds the longest spot (35 m from the launch, ~9″) whole; the
     * CoG of the pixels is then the source's centroid exactly but for the kernel's midpoint line sampling
     * (< 1e-3 of the shift). Back to the first profile: the first images, bit for bit. */
    wt_context *ctx = tu_context();
    const double H = 90e3, lx = 4.0, ly = -3.0;
    const double xc[5] = {-21.0, -2.0, 5.0, 12.0, 31.0}, yc[5] = {3.0, 14.0, -3.0, -9.0, 8.0};
    wt_sodium *n0 = NULL, *n1 = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "data/sodium/default.txt", &n0), WT_OK);
    ck_assert_int_eq(wt_sodium_copy(n0, &n1), WT_OK);
    for (int i = 0; i < n1->n; i++) n1->alt[i] += 1000.0;
    wt_spot_params p = {0};
    p.wavelength = 589e-9, p.subap_side = 0.5, p.pupil_samples = 16, p.fft_size = 32, p.npix = 48;
    p.pixel = 0.5 * AS, p.cells_per_pixel = 3, p.photons = 1000, p.uplink_fwhm = 1.0 * AS;
    p.lgs_altitude = H, p.launch_x = lx, p.launch_y = ly, p.sodium = n0;
    wt_spot *sp = NULL;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 5, xc, yc, NULL, NULL, &sp), WT_OK);
    const int ns2 = 48 * 48;
    float *a = malloc(5 * ns2 * sizeof *a), *b = malloc(5 * ns2 * sizeof *b), *c = malloc(5 * ns2 * sizeof *c);
    double opd[5 * 256] = {0};
    ck_assert_int_eq(wt_spot_image_d(sp, opd, a), WT_OK);
    ck_assert_int_eq(wt_spot_set_sodium(sp, n1), WT_OK);
    ck_assert_int_eq(wt_spot_image_d(sp, opd, b), WT_OK);
    const double dinv = mean_inv_h(n1) - mean_inv_h(n0);
    for (int k = 0; k < 5; k++) {
        double ca[2] = {0}, cb[2] = {0}, sa = 0, sb = 0;
        for (int q = 0; q < ns2; q++) {
            const double x = (q % 48 - 23.5) * p.pixel, y = (q / 48 - 23.5) * p.pixel;
            sa += a[k * ns2 + q], ca[0] += a[k * ns2 + q] * x, ca[1] += a[k * ns2 + q] * y;
            sb += b[k * ns2 + q], cb[0] += b[k * ns2 + q] * x, cb[1] += b[k * ns2 + q] * y;
        }
        const double want[2] = {(xc[k] - lx) * dinv, (yc[k] - ly) * dinv};
        for (int ax = 0; ax < 2; ax++)
            ck_assert_msg(fabs(cb[ax] / sb - ca[ax] / sa - want[ax]) < 1e-3 * fabs(want[ax]) + 1e-4 * AS,
                          "subaperture %d axis %d: moved %g arcsec, the geometry says %g", k, ax,
                          (cb[ax] / sb - ca[ax] / sa) / AS, want[ax] / AS);
        /* towards the launch: the shift is along −(r − l) */
        ck_assert((cb[0] / sb - ca[0] / sa) * (xc[k] - lx) + (cb[1] / sb - ca[1] / sa) * (yc[k] - ly) < 0);
    }
    ck_assert_int_eq(wt_spot_set_sodium(sp, n0), WT_OK);
    ck_assert_int_eq(wt_spot_image_d(sp, opd, c), WT_OK);
    ck_assert_int_eq(memcmp(a, c, 5 * ns2 * sizeof *a), 0);
    /* a profile that does not hold the LGS altitude, and an NGS spot, are refused */
    for (int i = 0; i < n1->n; i++) n1->alt[i] += 20000.0;
    ck_assert_int_eq(wt_spot_set_sodium(sp, n1), WT_ERR_INVALID);
    wt_spot *ngs = NULL;
    p.sodium = NULL;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, xc, yc, NULL, NULL, &ngs), WT_OK);
    ck_assert_int_eq(wt_spot_set_sodium(ngs, n0), WT_ERR_INVALID);
    wt_spot_free(ngs), wt_spot_free(sp), wt_sodium_free(n0), wt_sodium_free(n1);
    free(a), free(b), free(c);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_reference_from_kept_cells)
{
    /* The oracle's reference (wt_spot_keep_reference, then wt_spot_reference after wt_spot_set_sodium) against
     * the reference of a spot built with the new profile from the start: the same bits, with the seeing and
     * without it (another seeing than the kept cells' is computed anew), partly lit subapertures included. */
    wt_context *ctx = tu_context();
    const double xc[3] = {-3.0, 1.0, 6.5}, yc[3] = {2.0, -1.0, 0.25};
    wt_sodium *n0 = NULL, *n1 = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "data/sodium/default.txt", &n0), WT_OK);
    ck_assert_int_eq(wt_sodium_copy(n0, &n1), WT_OK);
    for (int i = 0; i < n1->n; i++) n1->dens[i] *= 1.0 + 0.5 * sin(i * 0.3); /* another shape */
    wt_spot_params p = {0};
    p.wavelength = 589e-9, p.subap_side = 0.5, p.pupil_samples = 8, p.fft_size = 16, p.npix = 12;
    p.pixel = 0.8 * AS, p.cells_per_pixel = 3, p.photons = 500, p.uplink_fwhm = 1.0 * AS;
    p.lgs_altitude = 90e3, p.launch_x = 4.0, p.launch_y = 0.0, p.sodium = n0;
    float amp[3 * 64];
    for (int q = 0; q < 3 * 64; q++) amp[q] = q >= 128 && (q % 8) < 3 ? 0.0f : 1.0f; /* the third partly lit */
    wt_spot *kept = NULL, *fresh = NULL;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 3, xc, yc, amp, NULL, &kept), WT_OK);
    p.sodium = n1;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 3, xc, yc, amp, NULL, &fresh), WT_OK);
    const int n = 3 * 144;
    float r[2][3][3 * 144];
    const wt_spot_seeing see = {.r0 = 0.12, .L0 = 25.0, .grid = 0.0};
    ck_assert_int_eq(wt_spot_keep_reference(kept), WT_OK);
    ck_assert_int_eq(wt_spot_reference(kept, 0.0, &see, r[0][0], r[0][1], r[0][2]), WT_OK); /* cells kept */
    ck_assert_int_eq(wt_spot_set_sodium(kept, n1), WT_OK);
    for (int pass = 0; pass < 2; pass++) {
        const wt_spot_seeing *sv = pass ? NULL : &see;
        ck_assert_int_eq(wt_spot_reference(kept, 0.0, sv, r[0][0], r[0][1], r[0][2]), WT_OK);
        ck_assert_int_eq(wt_spot_reference(fresh, 0.0, sv, r[1][0], r[1][1], r[1][2]), WT_OK);
        for (int i = 0; i < 3; i++) ck_assert_int_eq(memcmp(r[0][i], r[1][i], n * sizeof(float)), 0);
    }
    wt_spot_free(kept), wt_spot_free(fresh), wt_sodium_free(n0), wt_sodium_free(n1);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("seeing");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, t_kolmogorov_limit);
    tcase_add_test(tc, t_outer_scale_saturates);
    tcase_add_test(tc, t_otf_properties);
    tcase_add_test(tc, t_reference_is_mean_of_screens);
    tcase_add_test(tc, t_sodium_shift_is_focus);
    tcase_add_test(tc, t_new_profile_moves_spots);
    tcase_add_test(tc, t_reference_from_kept_cells);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
