/* tests/test_spot.c: diffractive Shack–Hartmann images (core/optics/spot.h, SPEC §4b): the diffraction
 * FWHM of a square subaperture, the tilt sign and scale, LGS elongation length and direction, flux and
 * truncation, the rebinning blur against a brute-force fine computation, the reference derivatives, the
 * Poisson sampler, the detector-noise variance, thread-count independence, no allocation per frame, and
 * bad input. */
#include "testutil.h"

#include <fftw3.h>

#include "core/optics/sodium.h"
#include "core/optics/spot.h"

#define LAM 589e-9
#define DSUB 0.5
#define AS (M_PI / 180.0 / 3600.0) /* one arcsecond [rad] */

static wt_spot_params base_params(void)
{
    wt_spot_params p = {0};
    p.wavelength = LAM;
    p.subap_side = DSUB;
    p.pupil_samples = 16;
    p.fft_size = 32;
    p.npix = 16;
    p.pixel = 1.1 * AS;
    p.cells_per_pixel = 3;
    p.photons = 1000;
    return p;
}

static wt_spot *make(wt_context *ctx, const wt_spot_params *p, int nsub, const double *xc, const double *yc,
                     const float *amp)
{
    wt_spot *s = NULL;
    int st = wt_spot_alloc(ctx, p, nsub, xc, yc, amp, NULL, &s);
    ck_assert_msg(st == WT_OK, "spot alloc: %s", wt_error_message(ctx));
    return s;
}

/* centre of gravity and variance of one image, per axis [rad] */
static void moments(const float *img, int Ns, double p, double *cx, double *cy, double *vx, double *vy)
{
    double s = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
    for (int iy = 0; iy < Ns; iy++)
        for (int ix = 0; ix < Ns; ix++) {
            double v = img[ix + Ns * iy], x = (ix - 0.5 * (Ns - 1)) * p, y = (iy - 0.5 * (Ns - 1)) * p;
            s += v, sx += v * x, sy += v * y, sxx += v * x * x, syy += v * y * y;
        }
    *cx = sx / s, *cy = sy / s;
    if (vx) *vx = sxx / s - *cx * *cx;
    if (vy) *vy = syy / s - *cy * *cy;
}

/* FWHM of a 1-D profile f[0..n) of spacing p: outermost half-maximum crossings, linear interpolation */
static double fwhm1(const double *f, int n, double p)
{
    double pk = 0;
    for (int i = 0; i < n; i++) pk = fmax(pk, f[i]);
    double h = 0.5 * pk, lo = 0, hi = 0;
    for (int i = 1; i < n; i++)
        if (f[i] >= h) {
            lo = i - 1 + (h - f[i - 1]) / (f[i] - f[i - 1]);
            break;
        }
    for (int i = n - 2; i >= 0; i--)
        if (f[i] >= h) {
            hi = i + (f[i] - h) / (f[i] - f[i + 1]);
            break;
        }
    return (hi - lo) * p;
}

START_TEST(t_diffraction_fwhm)
{
    /* Unaberrated, unobstructed square subaperture, point source, pixels of λ/(10d): the PSF along x is
     * sinc²(θd/λ), whose FWHM is 0.88589 λ/d (sinc²(x) = 1/2 at x = 0.44295). The image adds the pixel
     * box and the rebinning blur, σ² = p²/12 + θ_f²/12 + c²/6 ≈ 0.0023 (λ/d)²: < 1 % on the FWHM,
     * and n_p = 16 samples make the aperture a Dirichlet kernel, +~0.1 %. Tolerance 2 % (brief: 5 %). */
    wt_context *ctx = tu_context();
    wt_spot_params p = base_params();
    p.fft_size = 128;
    p.npix = 41;
    p.pixel = 0.1 * LAM / DSUB;
    double xc = 0, yc = 0;
    wt_spot *s = make(ctx, &p, 1, &xc, &yc, NULL);
    float opd[256] = {0}, img[41 * 41];
    ck_assert_int_eq(wt_spot_image(s, opd, img), WT_OK);
    double row[41], col[41];
    for (int i = 0; i < 41; i++) row[i] = img[i + 41 * 20], col[i] = img[20 + 41 * i];
    ck_assert_rel(fwhm1(row, 41, p.pixel), 0.88589 * LAM / DSUB, 0.02, 0);
    ck_assert_rel(fwhm1(col, 41, p.pixel), 0.88589 * LAM / DSUB, 0.02, 0);
    /* the peak is the centre pixel: a flat wavefront is centred */
    for (int i = 0; i < 41 * 41; i++) ck_assert(img[i] <= img[20 + 41 * 20]);
    wt_spot_free(s);
    wt_context_free(ctx);
}
END_TEST

/* Gaussian pupil amplitude exp(−r²/(2w²)), w = d/6: the PSF is a Gaussian of σ = λ/(2√2 π w) = 0.675 λ/d
 * without sinc tails, so the CoG over a field of ±4 λ/d is the spot's centre to ~1e-4. */
static void gaussian_amp(float *amp, int np)
{
    for (int j = 0; j < np; j++)
        for (int i = 0; i < np; i++) {
            double x = (i + 0.5 - 0.5 * np) / np, y = (j + 0.5 - 0.5 * np) / np; /* in units of d */
            amp[i + np * j] = (float)exp(-(x * x + y * y) * 18.0);                 /* w = d/6 */
        }
}

START_TEST(t_tilt_sign_and_scale)
{
    /* OPD = θx·x + θy·y moves the CoG by (θx, θy) (SPEC §4b sign: +∂OPD/∂x → +x) within 2 % */
    wt_context *ctx = tu_context();
    wt_spot_params p = base_params();
    p.fft_size = 64;
    p.npix = 33;
    p.pixel = 0.25 * LAM / DSUB;
    double xc = 3.0, yc = -2.0; /* the centre must not matter */
    float amp[256];
    gaussian_amp(amp, 16);
    wt_spot *s = make(ctx, &p, 1, &xc, &yc, amp);
    const double tx = 0.7 * LAM / DSUB, ty = -0.4 * LAM / DSUB;
    float opd[256], img[33 * 33];
    double dopd[256];
    for (int j = 0; j < 16; j++)
        for (int i = 0; i < 16; i++) {
            double x = (i + 0.5 - 8) * DSUB / 16, y = (j + 0.5 - 8) * DSUB / 16;
            dopd[i + 16 * j] = tx * x + ty * y + 1e-6; /* + piston */
            opd[i + 16 * j] = (float)dopd[i + 16 * j];
        }
    double cx, cy;
    ck_assert_int_eq(wt_spot_image(s, opd, img), WT_OK);
    moments(img, 33, p.pixel, &cx, &cy, NULL, NULL);
    ck_assert_rel(cx, tx, 0.02, 0);
    ck_assert_rel(cy, ty, 0.02, 0);
    ck_assert_int_eq(wt_spot_image_d(s, dopd, img), WT_OK);
    moments(img, 33, p.pixel, &cx, &cy, NULL, NULL);
    ck_assert_rel(cx, tx, 0.02, 0);
    ck_assert_rel(cy, ty, 0.02, 0);
    wt_spot_free(s);
    wt_context_free(ctx);
}
END_TEST

/* The exact centroid of the line source, (r − l)·(E[1/h] − 1/H) per unit of (r − l), E over the
 * piecewise-linear profile (a fine midpoint rule: 1e-9 relative) */
static double line_centroid(const wt_sodium *na, double H)
{
    double m = 0, s = 0;
    for (int i = 0; i + 1 < na->n; i++)
        for (int j = 0; j < 1000; j++) {
            const double t = (j + 0.5) / 1000, h = na->alt[i] + t * (na->alt[i + 1] - na->alt[i]);
            const double w = (na->dens[i] + t * (na->dens[i + 1] - na->dens[i])) * (na->alt[i + 1] - na->alt[i]);
            m += w, s += w / h;
        }
    return s / m - 1.0 / H;
}

START_TEST(t_elongation)
{
    /* LGS: a Gaussian sodium layer of FWHM 10 km at H = 90 km seen from |r − l| = 20 m spreads the spot
     * along (r − l) with FWHM |r − l|(1/85 km − 1/95 km) = 5.11″ (|r − l|·Δh/H² = 5.09″ to first order).
     * Its convolution with the PSF (0.21″), the pixel (0.25″), the uplink (0.1″) and the rebinning (0.09″)
     * widens that by < 0.2 % (quadrature), so the measured FWHM along x must match within 3 %; across, it
     * stays below 0.6″. The exact parallax (1/h − 1/H) is not linear in h: the symmetric layer's spot
     * has its centroid at (r − l)(E[1/h] − 1/H) ≈ (r − l)σ²/H³ = 0.10″, which the CoG must find within 1 %
     * (the CoG is exact for the line, all of which the field holds). */
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_gaussian(ctx, 90e3, 10e3, &na), WT_OK);
    wt_spot_params p = base_params();
    p.npix = 160; /* a 40″ field: the profile's table (H ± 25 km) lies within it */
    p.pixel = 0.25 * AS;
    p.uplink_fwhm = 0.1 * AS;
    p.sodium = na;
    p.lgs_altitude = 90e3;
    p.launch_x = 1.0, p.launch_y = 2.0;
    double xc = 21.0, yc = 2.0; /* r − l = (20, 0) */
    wt_spot *s = make(ctx, &p, 1, &xc, &yc, NULL);
    float opd[256] = {0}, *img = malloc(160 * 160 * sizeof *img);
    ck_assert_int_eq(wt_spot_image(s, opd, img), WT_OK);
    double px[160] = {0}, py[160] = {0};
    for (int iy = 0; iy < 160; iy++)
        for (int ix = 0; ix < 160; ix++) px[ix] += img[ix + 160 * iy], py[iy] += img[ix + 160 * iy];
    const double want = 20.0 * (1.0 / 85e3 - 1.0 / 95e3);
    ck_assert_rel(fwhm1(px, 160, p.pixel), want, 0.03, 0);
    ck_assert_double_lt(fwhm1(py, 160, p.pixel), 0.6 * AS);
    double cx, cy;
    moments(img, 160, p.pixel, &cx, &cy, NULL, NULL);
    ck_assert_rel(cx, 20.0 * line_centroid(na, 90e3), 0.01, 0);
    ck_assert_double_lt(fabs(cy), 0.001 * AS);
    wt_spot_free(s);
    wt_sodium_free(na);

    /* The layer 1 km higher (LGS focus still at 90 km), seen from r − l = (12, −16): the spot moves by
     * |r − l|(E[1/h] − 1/H) ≈ −|r − l|·Δh/H² = −0.50″ along (0.6, −0.8), i.e. towards the launch, as the
     * focus of a farther source does (t_sodium_shift_is_focus); 1 % tolerance as above. */
    ck_assert_int_eq(wt_sodium_gaussian(ctx, 91e3, 10e3, &na), WT_OK);
    p.sodium = na;
    xc = 13.0, yc = -14.0;
    s = make(ctx, &p, 1, &xc, &yc, NULL);
    ck_assert_int_eq(wt_spot_image(s, opd, img), WT_OK);
    moments(img, 160, p.pixel, &cx, &cy, NULL, NULL);
    const double shift = 20.0 * line_centroid(na, 90e3);
    ck_assert_double_lt(shift, 0.0);
    ck_assert_rel(cx, 0.6 * shift, 0.01, 0);
    ck_assert_rel(cy, -0.8 * shift, 0.01, 0);
    wt_spot_free(s);
    wt_sodium_free(na);
    free(img);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_flux_and_truncation)
{
    /* no truncation: Σ pixels = photons × lit fraction (float sums of ~1e3 terms: 1e-5); a half-lit
     * subaperture (amplitude 0 on half its samples) gets half. Truncation: a 6-pixel detector's reported
     * truncation equals the flux a 40-pixel detector (same pixel centres) puts outside its central 6 × 6. */
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "data/sodium/default.txt", &na), WT_OK);
    wt_spot_params p = base_params();
    p.npix = 40;
    p.uplink_fwhm = 1.0 * AS;
    p.sodium = na;
    p.lgs_altitude = 90e3;
    p.launch_x = 22.0;
    double xc[3] = {-10.0, 10.25, 0.0}, yc[3] = {5.0, 0.25, 0.0};
    float amp[3 * 256];
    for (int i = 0; i < 3 * 256; i++) amp[i] = 1.0f;
    for (int j = 0; j < 16; j++)
        for (int i = 0; i < 8; i++) amp[256 + i + 16 * j] = 0.0f; /* subaperture 1: left half dark */
    wt_spot *big = make(ctx, &p, 3, xc, yc, amp);
    float opd[3 * 256] = {0}, *img = malloc(3 * 40 * 40 * sizeof *img), img6[3 * 36];
    ck_assert_int_eq(wt_spot_image(big, opd, img), WT_OK);
    const double lit[3] = {1.0, 0.5, 1.0};
    double tr[3];
    wt_spot_truncation(big, img, tr);
    for (int k = 0; k < 3; k++) {
        ck_assert_rel(wt_spot_flux(big, k), 1000 * lit[k], 1e-15, 0);
        ck_assert_msg(fabs(tr[k]) < 2e-5, "subaperture %d: truncation %g on a 44\" field", k, tr[k]);
    }
    p.npix = 6;
    wt_spot *small = make(ctx, &p, 3, xc, yc, amp);
    ck_assert_int_eq(wt_spot_image(small, opd, img6), WT_OK);
    wt_spot_truncation(small, img6, tr);
    for (int k = 0; k < 3; k++) {
        double in = 0;
        for (int iy = 17; iy < 23; iy++)
            for (int ix = 17; ix < 23; ix++) {
                in += img[k * 1600 + ix + 40 * iy];
                ck_assert_rel(img6[k * 36 + (ix - 17) + 6 * (iy - 17)], img[k * 1600 + ix + 40 * iy], 1e-4, 1e-3);
            }
        ck_assert_rel(tr[k], 1.0 - in / (1000 * lit[k]), 1e-4, 1e-5);
        ck_assert_msg(tr[k] > 0.002, "subaperture %d: truncation %g", k, tr[k]); /* spots of 3-9″ on 6.6″ */
    }
    wt_spot_free(big);
    wt_spot_free(small);
    wt_sodium_free(na);
    free(img);
    wt_context_free(ctx);
}
END_TEST

/* Brute force: the PSF of the same pupil samples at a 16× finer sampling (FFT 512²), each fine sample a
 * point, integrated exactly over each pixel against a Gaussian source: image = X·PSF·Yᵀ with
 * X[P][i] = Φ((x_P + p/2 − θ_i)/σ) − Φ((x_P − p/2 − θ_i)/σ). */
static void brute_image(const double *opd, int np, double p, int Ns, double sigma, double flux, double *img)
{
    const int Nf = 512;
    fftw_complex *F = fftw_malloc(sizeof(fftw_complex) * Nf * Nf);
    memset(F, 0, sizeof(fftw_complex) * Nf * Nf);
    for (int j = 0; j < np; j++)
        for (int i = 0; i < np; i++) {
            double ph = 2 * M_PI / LAM * opd[i + np * j];
            F[i + Nf * j][0] = cos(ph), F[i + Nf * j][1] = sin(ph);
        }
    fftw_plan pl = fftw_plan_dft_2d(Nf, Nf, F, F, FFTW_FORWARD, FFTW_ESTIMATE);
    fftw_execute(pl);
    fftw_destroy_plan(pl);
    const double thf = LAM / (Nf * DSUB / np);
    double *P = malloc(sizeof(double) * Nf * Nf), tot = 0;
    for (int j = 0; j < Nf; j++)
        for (int i = 0; i < Nf; i++) {
            const double *z = F[(i + Nf / 2) % Nf + Nf * ((j + Nf / 2) % Nf)];
            P[i + Nf * j] = z[0] * z[0] + z[1] * z[1];
            tot += P[i + Nf * j];
        }
    double *X = malloc(sizeof(double) * Ns * Nf), *T = malloc(sizeof(double) * Ns * Nf);
    for (int a = 0; a < Ns; a++)
        for (int i = 0; i < Nf; i++) {
            double xP = (a - 0.5 * (Ns - 1)) * p, th = (i - Nf / 2) * thf;
            X[a * Nf + i] = 0.5 * erfc(-(xP + p / 2 - th) / (sigma * M_SQRT2)) - 0.5 * erfc(-(xP - p / 2 - th) / (sigma * M_SQRT2));
        }
    for (int a = 0; a < Ns; a++) /* T[a][j] = Σ_i X[a][i] P[i, j] */
        for (int j = 0; j < Nf; j++) {
            double t = 0;
            for (int i = 0; i < Nf; i++) t += X[a * Nf + i] * P[i + Nf * j];
            T[a * Nf + j] = t;
        }
    for (int b = 0; b < Ns; b++)
        for (int a = 0; a < Ns; a++) {
            double t = 0;
            for (int j = 0; j < Nf; j++) t += X[b * Nf + j] * T[a * Nf + j];
            img[a + Ns * b] = t * flux / tot;
        }
    free(X), free(T), free(P);
    fftw_free(F);
}

START_TEST(t_rebinning_accuracy)
{
    /* An aberrated subaperture (defocus + astigmatism + coma, ~λ/3 rms, a 0.2 λ/d tilt) and a Gaussian
     * source of FWHM 0.8″ on 0.5″ pixels. The rebinning blur v = θ_f²/12 + c²/6 (spot.h) is taken from
     * the source's Gaussian, so the image's variance must match the brute force's to a fraction of v
     * (25 %: v is an average over sub-cell positions; the spot is ~2 cells wide at k = 1), the CoG must
     * be kept (the tent keeps first moments), and the pixels must agree to a relative L2 error that
     * shrinks with c: measured 5.8 %, 0.20 %, 0.12 % for k = 1, 3, 5 (without the compensation: 20 %,
     * 2.5 %, 1.1 %); bounds 8 %, 0.4 %, 0.25 %. */
    const int np = 16, Ns = 16;
    const double p = 0.5 * AS, sigma = 0.8 * AS / 2.3548;
    double opd[256];
    for (int j = 0; j < np; j++)
        for (int i = 0; i < np; i++) {
            double x = (i + 0.5 - 8) / 8.0, y = (j + 0.5 - 8) / 8.0; /* [−1, 1] */
            opd[i + np * j] = 60e-9 * (x * x + y * y) + 40e-9 * (x * x - y * y) + 30e-9 * x * (x * x + y * y) +
                              0.2 * LAM / DSUB * DSUB / 2 * y; /* and a tilt of 0.2 λ/d in y */
        }
    double *bf = malloc(sizeof(double) * Ns * Ns);
    brute_image(opd, np, p, Ns, sigma, 1000.0, bf);
    float bff[256];
    for (int i = 0; i < Ns * Ns; i++) bff[i] = (float)bf[i];
    double bcx, bcy, bvx, bvy;
    moments(bff, Ns, p, &bcx, &bcy, &bvx, &bvy);
    const int ks[3] = {1, 3, 5};
    const double tol[3] = {0.08, 0.004, 0.0025};
    for (int t = 0; t < 3; t++) {
        wt_context *ctx = tu_context();
        wt_spot_params par = base_params();
        par.npix = Ns;
        par.pixel = p;
        par.cells_per_pixel = ks[t];
        par.uplink_fwhm = 0.8 * AS;
        double xc = 0, yc = 0;
        wt_spot *s = make(ctx, &par, 1, &xc, &yc, NULL);
        float img[256];
        ck_assert_int_eq(wt_spot_image_d(s, opd, img), WT_OK);
        double cx, cy, vx, vy, d2 = 0, n2 = 0;
        moments(img, Ns, p, &cx, &cy, &vx, &vy);
        for (int i = 0; i < Ns * Ns; i++) d2 += (img[i] - bf[i]) * (img[i] - bf[i]), n2 += bf[i] * bf[i];
        const double thf = LAM / (32 * DSUB / 16), c = p / ks[t], blur = thf * thf / 12 + c * c / 6;
        ck_assert_msg(fabs(cx - bcx) < 0.005 * AS && fabs(cy - bcy) < 0.005 * AS, "k=%d: CoG moved", ks[t]);
        ck_assert_double_eq(wt_spot_blur(s), 0);
        ck_assert_msg(fabs(vx - bvx) < 0.25 * blur && fabs(vy - bvy) < 0.25 * blur, "k=%d: variance excess %g %g vs v %g",
                      ks[t], vx - bvx, vy - bvy, blur);
        ck_assert_msg(sqrt(d2 / n2) < tol[t], "k=%d: relative L2 error %g > %g", ks[t], sqrt(d2 / n2), tol[t]);
        wt_spot_free(s);
        wt_context_free(ctx);
    }
    free(bf);
}
END_TEST

START_TEST(t_reference)
{
    /* I0 is the flat image; dI0/dθx moves the CoG at rate 1: Σ x dI/dθx / Σ I0 = 1 within 1 % on a wide
     * detector for a subaperture without diffraction tails (Gaussian amplitude; central difference of a
     * smooth function: O(δ²) error), and Σ dI/dθ = 0 (flux is constant) */
    wt_context *ctx = tu_context();
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_read(ctx, "data/sodium/default.txt", &na), WT_OK);
    wt_spot_params p = base_params();
    p.npix = 80;
    p.pixel = 0.5 * AS; /* σ_spot ≥ 0.42″: the CoG's pixelisation ripple ~exp(−2π²σ²/p²) < 1e-6 */
    p.uplink_fwhm = 1.0 * AS;
    p.sodium = na;
    p.lgs_altitude = 90e3;
    double xc[2] = {-8.0, 0.25}, yc[2] = {3.0, -6.0};
    float amp[512];
    gaussian_amp(amp, 16);
    for (int i = 256; i < 512; i++) amp[i] = 1.0f;
    wt_spot *s = make(ctx, &p, 2, xc, yc, amp);
    const int n = 2 * 6400;
    float *i0 = malloc(n * sizeof(float)), *dx = malloc(n * sizeof(float)), *dy = malloc(n * sizeof(float));
    float *flat = malloc(n * sizeof(float)), opd[512] = {0};
    ck_assert_int_eq(wt_spot_reference(s, 0, NULL, i0, dx, dy), WT_OK);
    ck_assert_int_eq(wt_spot_image(s, opd, flat), WT_OK);
    ck_assert_mem_eq(i0, flat, n * sizeof(float));
    for (int k = 0; k < 2; k++) {
        double s0 = 0, sxx = 0, syy = 0, sxy = 0, sdx = 0;
        for (int iy = 0; iy < 80; iy++)
            for (int ix = 0; ix < 80; ix++) {
                int q = k * 6400 + ix + 80 * iy;
                double x = (ix - 39.5) * p.pixel, y = (iy - 39.5) * p.pixel;
                s0 += i0[q], sxx += x * dx[q], syy += y * dy[q], sxy += y * dx[q], sdx += dx[q];
            }
        /* subaperture 1 is a uniform square: its sinc² tails beyond the periodic FFT field (±8 λ/d)
         * fold back, ~4/(π² n_p) = 2.5 % of the flux, lowering the gain by about that (spot.h): 4 % */
        const double gtol = k == 0 ? 0.01 : 0.04;
        ck_assert_rel(sxx / s0, 1.0, gtol, 0);
        ck_assert_rel(syy / s0, 1.0, gtol, 0);
        ck_assert_double_lt(fabs(sxy / s0), 0.01);
        ck_assert_double_lt(fabs(sdx) * p.pixel / s0, 1e-3);
    }
    free(i0), free(dx), free(dy), free(flat);
    wt_spot_free(s);
    wt_sodium_free(na);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_poisson)
{
    /* mean and variance of n = 2e5 draws within 5 standard errors: var(mean) = μ/n, var(s²) ≈ (μ + 2μ²)/n
     * (Poisson: fourth central moment μ + 3μ²); and the frequencies of k against the pmf (5σ each) on both
     * sides of the method switch at 10 */
    const double mus[7] = {0.05, 0.7, 3.0, 9.99, 10.0, 31.5, 1234.5};
    const long n = 200000;
    for (int t = 0; t < 7; t++) {
        wt_rng r;
        wt_rng_init(&r, 11, (uint64_t)t);
        const double mu = mus[t];
        double s = 0, s2 = 0;
        long cnt[64] = {0};
        for (long i = 0; i < n; i++) {
            double k = wt_poisson(&r, mu);
            ck_assert(k >= 0 && k == floor(k));
            s += k, s2 += k * k;
            if (k < 64) cnt[(int)k]++;
        }
        double m = s / n, v = s2 / n - m * m;
        ck_assert_msg(fabs(m - mu) < 5 * sqrt(mu / n), "mu %g: mean %g", mu, m);
        ck_assert_msg(fabs(v - mu) < 5 * sqrt((mu + 2 * mu * mu) / n), "mu %g: variance %g", mu, v);
        if (mu < 40)
            for (int k = 0; k < 64; k++) {
                double pk = exp(-mu + k * log(mu) - lgamma(k + 1.0));
                ck_assert_msg(fabs(cnt[k] - n * pk) < 5 * sqrt(n * pk) + 2, "mu %g: P(%d) %ld vs %g", mu, k, cnt[k], n * pk);
            }
    }
    wt_rng r;
    wt_rng_init(&r, 1, 1);
    ck_assert(wt_poisson(&r, 0.0) == 0.0);
    ck_assert(wt_poisson(&r, -1.0) == 0.0);
}
END_TEST

START_TEST(t_noise_variance)
{
    /* per pixel over 2000 frames: mean ≈ I (the background is subtracted), variance ≈ I + B + σe², each
     * within 5 standard errors (var(s²) = (μ4 − σ⁴)/n with μ4 = λ + 3λ² + 6λσe² + 3σe⁴, λ = I + B) */
    wt_context *ctx = tu_context();
    wt_spot_params p = base_params();
    p.npix = 6;
    p.photons = 300;
    p.background = 2.0;
    p.read_noise = 1.5;
    p.uplink_fwhm = 1.2 * AS;
    double xc[2] = {0, 1}, yc[2] = {0, 0};
    wt_spot *s = make(ctx, &p, 2, xc, yc, NULL);
    float I[72], img[72];
    ck_assert_int_eq(wt_spot_reference(s, 0, NULL, I, NULL, NULL), WT_OK);
    const int n = 2000;
    double m1[72] = {0}, m2[72] = {0};
    for (int t = 0; t < n; t++) {
        memcpy(img, I, sizeof img);
        ck_assert_int_eq(wt_spot_noise(s, 5, (UINT64_C(1) << 32) + 64 * (uint64_t)t + 3, img), WT_OK);
        for (int q = 0; q < 72; q++) m1[q] += img[q], m2[q] += (double)img[q] * img[q];
    }
    double ratio = 0;
    for (int q = 0; q < 72; q++) {
        double m = m1[q] / n, v = (m2[q] - n * m * m) / (n - 1);
        double lam = I[q] + p.background, se2 = p.read_noise * p.read_noise, var = lam + se2;
        double mu4 = lam + 3 * lam * lam + 6 * lam * se2 + 3 * se2 * se2;
        ck_assert_msg(fabs(m - I[q]) < 5 * sqrt(var / n), "pixel %d: mean %g vs %g", q, m, I[q]);
        ck_assert_msg(fabs(v - var) < 5 * sqrt((mu4 - var * var) / n), "pixel %d: var %g vs %g", q, v, var);
        ratio += v / var;
    }
    /* all 72 together: the mean ratio within 5σ of 1 (σ ≈ sqrt(2/n)/sqrt(72) bounded by the Gaussian case
     * plus the Poisson excess kurtosis, ≤ sqrt(3/n/72)) */
    ck_assert_double_lt(fabs(ratio / 72 - 1), 5 * sqrt(3.0 / n / 72));
    /* the stream rule refuses a base stream that would collide */
    ck_assert_int_eq(wt_spot_noise(s, 5, UINT64_C(1) << 43, img), WT_ERR_INVALID);
    wt_spot_free(s);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_threads_and_no_alloc)
{
    /* the same seed gives the same pixels with 1 and 2 threads (noise-free and noisy, bit for bit), and the
     * per-frame calls allocate nothing through the context */
    wt_sodium *na = NULL;
    wt_context *c1 = tu_context(), *c2 = tu_context();
    wt_context_set_threads(c1, 1);
    wt_context_set_threads(c2, 2);
    ck_assert_int_eq(wt_sodium_read(c1, "data/sodium/default.txt", &na), WT_OK);
    wt_spot_params p = base_params();
    p.uplink_fwhm = 1.0 * AS;
    p.sodium = na;
    p.lgs_altitude = 90e3;
    p.launch_x = -22.0;
    p.background = 1;
    p.read_noise = 3;
    const int ns = 100;
    double xc[100], yc[100];
    for (int i = 0; i < ns; i++) xc[i] = -20 + 0.5 * (i % 10), yc[i] = 0.5 * (i / 10);
    wt_spot *s1 = make(c1, &p, ns, xc, yc, NULL), *s2 = make(c2, &p, ns, xc, yc, NULL);
    float *opd = malloc(sizeof(float) * ns * 256), *a = malloc(sizeof(float) * ns * 256), *b = malloc(sizeof(float) * ns * 256);
    wt_rng r;
    wt_rng_init(&r, 3, 0);
    for (int i = 0; i < ns * 256; i++) opd[i] = (float)(50e-9 * wt_rng_normal(&r));
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(c1, &fa);
    tu_alloc_install(c2, &fa);
    ck_assert_int_eq(wt_spot_image(s1, opd, a), WT_OK);
    ck_assert_int_eq(wt_spot_image(s2, opd, b), WT_OK);
    ck_assert_mem_eq(a, b, sizeof(float) * ns * 256);
    ck_assert_int_eq(wt_spot_noise(s1, 42, (UINT64_C(1) << 32) + 64 * 7 + 2, a), WT_OK);
    ck_assert_int_eq(wt_spot_noise(s2, 42, (UINT64_C(1) << 32) + 64 * 7 + 2, b), WT_OK);
    ck_assert_mem_eq(a, b, sizeof(float) * ns * 256);
    ck_assert_int_eq(wt_spot_reference(s2, 0, NULL, a, b, opd), WT_OK);
    ck_assert_int_eq(fa.count, 0);
    wt_context_set_allocator(c1, NULL, NULL, NULL);
    wt_context_set_allocator(c2, NULL, NULL, NULL);
    free(opd), free(a), free(b);
    wt_spot_free(s1), wt_spot_free(s2);
    wt_sodium_free(na);
    wt_context_free(c1), wt_context_free(c2);
}
END_TEST

START_TEST(t_kernel_reference_values)
{
    /* The image kernel (field, FFT, rebinning, direct sum) against values recorded before its loops were
     * restructured (the x pass gathering per cell, the direct sum blocked in registers: the same additions
     * in the same order, bit-identical on the machine that recorded them; the LGS cases with the exact parallax,
     * spot.h). Five cases: LGS and point
     * sources, Ns 7/10/16/20 (below, at and past the 16-pixel block; rows not a multiple of 4), k = 1/3/5,
     * partly lit and half-amplitude subapertures. Σ I, Σ I·w (w = 1…7 cycling) and Σ I² within 1e-5
     * relative: float rounding of sums of ≤ ~10³ terms is ~1e-6; an error of one cell or pixel would move
     * them by ≥ 1e-3. */
    static const struct {
        int lgs, np, N, Ns;
        double pix;
        int k;
        double lam, s0, s1, s2;
    } C[5] = {
        {1, 16, 32, 10, 1.10, 3, 589e-9, 1915.38375113, 7701.60477711, 30938.2893443},
        {1, 16, 32, 16, 1.10, 3, 589e-9, 1965.59249565, 7855.09285984, 31016.8184661},
        {1, 8, 24, 20, 0.70, 5, 589e-9, 1989.09124274, 7629.81671339, 26381.2824299},
        {0, 16, 32, 16, 0.05, 1, 1650e-9, 835.154255867, 3338.81586126, 860.252693694},
        {0, 12, 28, 7, 0.30, 3, 1650e-9, 1271.05331, 5019.18056743, 34928.663851},
    };
    wt_context *ctx = tu_context();
    wt_context_set_threads(ctx, 2);
    const int nsub = 5;
    const double xc[5] = {-4, 3, 10, 14.5, 0.2}, yc[5] = {1, -7, 2, 5, 14.2};
    for (int t = 0; t < 5; t++) {
        const int np = C[t].np, Ns = C[t].Ns;
        float *amp = malloc(sizeof(float) * nsub * np * np), *opd = malloc(sizeof(float) * nsub * np * np);
        wt_rng r;
        wt_rng_init(&r, 3, 0);
        for (int i = 0; i < nsub * np * np; i++) {
            amp[i] = (i / (np * np) == 3 && (i % np) < np / 3) ? 0.0f : ((i / (np * np) == 4) ? 0.5f : 1.0f);
            opd[i] = (float)(150e-9 * wt_rng_normal(&r));
        }
        wt_sodium *na = NULL;
        if (C[t].lgs) ck_assert_int_eq(wt_sodium_gaussian(ctx, 90e3, 10e3, &na), WT_OK);
        wt_spot_params p = {0};
        p.wavelength = C[t].lam, p.subap_side = 0.5, p.pupil_samples = np, p.fft_size = C[t].N, p.npix = Ns;
        p.pixel = C[t].pix * AS, p.cells_per_pixel = C[t].k, p.photons = 500, p.read_noise = 3, p.background = 0.2;
        p.uplink_fwhm = C[t].lgs ? 1.0 * AS : 0, p.sodium = na, p.lgs_altitude = 90e3, p.launch_x = 22, p.launch_y = 3;
        wt_spot *s = make(ctx, &p, nsub, xc, yc, amp);
        float *img = malloc(sizeof(float) * nsub * Ns * Ns);
        ck_assert_int_eq(wt_spot_image(s, opd, img), WT_OK);
        double s0 = 0, s1 = 0, s2 = 0;
        for (int i = 0; i < nsub * Ns * Ns; i++) s0 += img[i], s1 += img[i] * (i % 7 + 1), s2 += (double)img[i] * img[i];
        ck_assert_msg(fabs(s0 / C[t].s0 - 1) < 1e-5 && fabs(s1 / C[t].s1 - 1) < 1e-5 && fabs(s2 / C[t].s2 - 1) < 1e-5,
                      "case %d: %.12g %.12g %.12g vs %.12g %.12g %.12g", t, s0, s1, s2, C[t].s0, C[t].s1, C[t].s2);
        wt_spot_free(s);
        wt_sodium_free(na);
        free(amp), free(opd), free(img);
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_poisson_small_mu_shortcut)
{
    /* wt_poisson skips the exp for u ≤ (1 − μ)(1 − 2⁻⁴⁸) (k = 0 since e^{−μ} ≥ 1 − μ): the deviates must be
     * those of the plain sequential search from the same stream, draw for draw */
    const double mus[6] = {1e-6, 1e-3, 0.05, 0.5, 0.999, 4.0};
    for (int t = 0; t < 6; t++) {
        wt_rng a, b;
        wt_rng_init(&a, 5, (uint64_t)t);
        wt_rng_init(&b, 5, (uint64_t)t);
        const double mu = mus[t];
        for (long i = 0; i < 200000; i++) {
            double u = wt_rng_uniform(&b), pk = exp(-mu), F = pk, k = 0;
            while (u > F && k < 1000) {
                k += 1;
                pk *= mu / k;
                F += pk;
            }
            ck_assert_msg(wt_poisson(&a, mu) == k, "mu %g draw %ld", mu, i);
        }
    }
}
END_TEST

START_TEST(t_bad_input)
{
    wt_context *ctx = tu_context();
    wt_spot *s = NULL;
    double xc = 0, yc = 0;
    wt_spot_params p = base_params();
    p.fft_size = 30; /* < 2 × 16 */
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_ERR_INVALID);
    ck_assert_ptr_null(s);
    const char *m = wt_error_message(ctx);
    ck_assert_msg(strstr(m, "*.wfs.fft_size") && strstr(m, "*.wfs.pupil_samples") && strstr(m, "is 32"), "%s", m);
    p = base_params();
    p.fft_size = 34 + 1; /* odd */
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_ERR_INVALID);
    p = base_params();
    p.cells_per_pixel = 4;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_ERR_INVALID);
    p = base_params();
    p.pixel = 0;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_ERR_INVALID);
    p = base_params();
    float amp[256] = {0};
    amp[3] = 1.5f;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, amp, NULL, &s), WT_ERR_INVALID);
    /* an LGS focused outside its sodium profile */
    wt_sodium *na = NULL;
    ck_assert_int_eq(wt_sodium_gaussian(ctx, 90e3, 5e3, &na), WT_OK);
    p.sodium = na;
    p.lgs_altitude = 120e3;
    ck_assert_int_eq(wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "sodium"));
    ck_assert_ptr_null(s);
    wt_sodium_free(na);
    /* allocation failures: every refused budget reports NOMEM and leaks nothing */
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    p = base_params();
    for (int b = 0; b < 40; b++) {
        tu_alloc_budget(&fa, b);
        int st = wt_spot_alloc(ctx, &p, 1, &xc, &yc, NULL, NULL, &s);
        if (st == WT_OK) break;
        ck_assert_int_eq(st, WT_ERR_NOMEM);
        ck_assert_ptr_null(s);
        ck_assert_int_eq(fa.live, 0);
    }
    ck_assert_ptr_nonnull(s);
    wt_spot_free(s);
    ck_assert_int_eq(fa.live, 0);
    wt_context_set_allocator(ctx, NULL, NULL, NULL);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("spot");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, t_diffraction_fwhm);
    tcase_add_test(tc, t_tilt_sign_and_scale);
    tcase_add_test(tc, t_elongation);
    tcase_add_test(tc, t_flux_and_truncation);
    tcase_add_test(tc, t_rebinning_accuracy);
    tcase_add_test(tc, t_reference);
    tcase_add_test(tc, t_poisson);
    tcase_add_test(tc, t_noise_variance);
    tcase_add_test(tc, t_threads_and_no_alloc);
    tcase_add_test(tc, t_bad_input);
    tcase_add_test(tc, t_kernel_reference_values);
    tcase_add_test(tc, t_poisson_small_mu_shortcut);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
