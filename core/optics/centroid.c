/* core/optics/centroid.c: Shack–Hartmann centroiders (CoG, thresholded CoG, matched filter), their gains and
 * their noise covariance, and a Monte-Carlo noise calibration.
 *
 * Implements SPEC §4b (centroiders, gain = ∂s/∂θ at zero per subaperture, the centroider's own 2x2 noise
 * covariance as the reconstructor's C_E) and the matched filter of Gilles & Ellerbroek (Appl. Opt. 45,
 * 6568, 2006): s = R (d − I0), R = rows 1–2 of (Gᵀ C⁻¹ G)⁻¹ Gᵀ C⁻¹, G = [∂I0/∂θx, ∂I0/∂θy (, I0)],
 * C = diag(I0 + B + σe²), noise covariance R C Rᵀ = top-left 2x2 of (Gᵀ C⁻¹ G)⁻¹. The formulas of every
 * estimator and of its first-order noise propagation are in centroid.h.
 *
 * Everything per subaperture is computed at set-up (reference centroid, gain and its inverse, MF rows,
 * covariance); the per-frame apply reads the images once and allocates nothing.
 */
#include "centroid.h"

#include <limits.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../base/rng.h"
#include "spot.h" /* wt_poisson: the detector's exact Poisson deviate */

struct wt_centroid {
    wt_context *ctx;
    wt_centroid_params par;
    int nsub, ns;
    int nw, off;   /* window side Nw [pixels] and its first pixel index (Ns − Nw)/2 */
    double c0;     /* (Ns − 1)/2: the detector centre in pixel indices */
    double *ref_s; /* 2·nsub: the raw estimator on I0, subtracted from every slope: CoG/tCoG reference
                      centroid, MF R·I0 (zero up to rounding; subtracted so I0 gives exactly 0) [rad] */
    double *gain;  /* 4·nsub: ∂s/∂θ row-major [rad/rad] */
    double *ginv;  /* 4·nsub: its inverse (apply_gain only) */
    double *cov;   /* 3·nsub: [Σxx…, Σxy…, Σyy…] [rad²] */
    double *thr;   /* nsub: tCoG threshold T [e⁻] */
    float *rows;   /* MF: 2·Ns² per subaperture, R's x row then its y row [rad/e⁻] */
};

/* ---------- small 2x2 helpers (row-major {a, b, c, d}) ---------- */

/* out = A S Aᵀ for a symmetric S = {sxx, sxy, syy}. */
static void sandwich(const double *a, double sxx, double sxy, double syy, double *oxx, double *oxy, double *oyy)
{
    const double t00 = a[0] * sxx + a[1] * sxy, t01 = a[0] * sxy + a[1] * syy;
    const double t10 = a[2] * sxx + a[3] * sxy, t11 = a[2] * sxy + a[3] * syy;
    *oxx = t00 * a[0] + t01 * a[1];
    *oxy = t00 * a[2] + t01 * a[3];
    *oyy = t10 * a[2] + t11 * a[3];
}

/* ---------- the per-subaperture estimators ---------- */

/* R·d for the MF rows rx, ry (npix each): the products go into 8 lanes (pixel j into lane j mod 8), summed
 * in a fixed order at the end. The lanes are independent elementwise sums, which the compiler vectorises
 * (one serial chain would wait on the adder's latency at every pixel); the order does not depend on the
 * vector width, so the bits do not depend on the CPU. */
static inline void mf_dot(const float *restrict rx, const float *restrict ry, const float *restrict d, size_t npix,
                          double *ox, double *oy)
{
    enum { L = 8 };
    double ax[L] = {0}, ay[L] = {0};
    size_t j = 0;
    for (; j + L <= npix; j += L)
        for (size_t k = 0; k < L; k++) {
            ax[k] += (double)rx[j + k] * (double)d[j + k];
            ay[k] += (double)ry[j + k] * (double)d[j + k];
        }
    for (int k = 0; j < npix; j++, k++) {
        ax[k] += (double)rx[j] * (double)d[j];
        ay[k] += (double)ry[j] * (double)d[j];
    }
    double sx = 0.0, sy = 0.0;
    for (int k = 0; k < L; k++) {
        sx += ax[k];
        sy += ay[k];
    }
    *ox = sx;
    *oy = sy;
}

/* The raw estimator of subaperture i on one image, relative to its value on I0 (no gain correction). */
static inline void raw_one(const wt_centroid *c, int i, const float *img, double *sx, double *sy)
{
    const int ns = c->ns;
    if (c->par.method == WT_CENTROID_MF) {
        const size_t npix = (size_t)ns * (size_t)ns;
        const float *rx = c->rows + 2 * npix * (size_t)i, *ry = rx + npix;
        double ax, ay;
        mf_dot(rx, ry, img, npix, &ax, &ay);
        *sx = ax - c->ref_s[i];
        *sy = ay - c->ref_s[c->nsub + i];
        return;
    }
    /* CoG / tCoG: per column of the window, Σ_iy w and Σ_iy (iy − c0) w (elementwise across the row, so
     * it vectorises), then the moments from the columns; T = 0 and no clipping for the plain CoG */
    const int tcog = c->par.method == WT_CENTROID_TCOG, nw = c->nw;
    const double t = c->thr[i];
    double cs[WT_CENTROID_MAX_PIXELS], cy[WT_CENTROID_MAX_PIXELS];
    for (int k = 0; k < nw; k++) cs[k] = cy[k] = 0.0;
    for (int iy = c->off; iy < c->off + nw; iy++) {
        const float *restrict row = img + (size_t)ns * (size_t)iy + c->off;
        const double yy = (double)iy - c->c0;
        if (tcog)
            for (int k = 0; k < nw; k++) {
                double v = (double)row[k] - t;
                v = v > 0.0 ? v : 0.0;
                cs[k] += v;
                cy[k] += yy * v;
            }
        else
            for (int k = 0; k < nw; k++) {
                const double v = (double)row[k];
                cs[k] += v;
                cy[k] += yy * v;
            }
    }
    double s = 0.0, mx = 0.0, my = 0.0;
    for (int k = 0; k < nw; k++) {
        s += cs[k];
        mx += ((double)(c->off + k) - c->c0) * cs[k];
        my += cy[k];
    }
    if (s <= 0.0) { /* nothing above zero (threshold) in the window: no measurement, hold zero */
        *sx = *sy = 0.0;
        return;
    }
    /* The centroid of non-negative weights lies within the hull of the window's pixel centres. Read and
     * background noise make pixels negative, and at low flux Σ_W d comes near zero while the moments do
     * not: the ratio then lands anywhere (measured: 267″ on an 11″ window, demo-diffractive at 100 e⁻ and
     * 3 e⁻ read noise over 10² pixels), a heavy tail that no covariance describes and that makes a linear
     * reconstructor's loop diverge. A real-time computer clamps such values; so does this estimator. A
     * noise-free image (all weights ≥ 0) is never clamped. */
    const double h = 0.5 * (nw - 1);
    double ux = mx / s, uy = my / s;
    ux = ux > h ? h : (ux < -h ? -h : ux);
    uy = uy > h ? h : (uy < -h ? -h : uy);
    *sx = c->par.pixel * ux - c->ref_s[i];
    *sy = c->par.pixel * uy - c->ref_s[c->nsub + i];
}

static inline void slope_one(const wt_centroid *c, int i, const float *img, double *sx, double *sy)
{
    double x, y;
    raw_one(c, i, img, &x, &y);
    if (c->par.apply_gain) {
        const double *g = c->ginv + 4 * (size_t)i;
        *sx = g[0] * x + g[1] * y;
        *sy = g[2] * x + g[3] * y;
    } else {
        *sx = x;
        *sy = y;
    }
}

/* Subapertures [i0, i1) of a frame. Cloned for AVX2/AVX-512 (WT_CPU_CLONES, core/base/base.h): the lanes
 * of mf_dot and the column sums are elementwise, so every clone gives the same bits. */
WT_CPU_CLONES
static void apply_range(const wt_centroid *c, int i0, int i1, const float *images, double *slopes)
{
    const size_t npix = (size_t)c->ns * (size_t)c->ns;
    for (int i = i0; i < i1; i++) slope_one(c, i, images + npix * (size_t)i, &slopes[i], &slopes[c->nsub + i]);
}

void wt_centroid_apply(const wt_centroid *c, const float *images, double *slopes)
{
    /* blocks of 64 subapertures (one dispatch of the clone each); a subaperture's sums are the same in
     * the same order whatever thread computes it */
    enum { B = 64 };
    const int nb = (c->nsub + B - 1) / B, nth = wt_context_threads(c->ctx);
    /* no more threads than blocks: a small sensor (a test's single subaperture) forks no idle thread, whose
     * wake-up costs more than the work on a busy machine */
#pragma omp parallel for schedule(static) num_threads(nth < nb ? nth : nb)
    for (int b = 0; b < nb; b++) apply_range(c, b * B, b * B + B < c->nsub ? b * B + B : c->nsub, images, slopes);
}

/* ---------- set-up ---------- */

/* Y = max(X − T, 0) for X ~ N(mu, var): its mean and variance (mu' = mu − T, a = mu'/σ):
 *   E[Y] = mu' Φ(a) + σ φ(a),   Var[Y] = mu'² Φ(a)(1 − Φ(a)) + σ² Φ(a) + mu' σ φ(a)(1 − 2Φ(a)) − σ² φ(a)²,
 * written with Φ and 1 − Φ separately (the smaller of the two from erfc, the other as 1 minus it) so the
 * variance of a pixel far above T does not come from the difference of two large numbers. dm: dE[Y]/dμ
 * when var = μ + c (Poisson plus a constant), for the noise-calibrated gain. */
static void clipped_moments(double mu, double var, double t, double *m, double *v, double *dm)
{
    const double mp = mu - t;
    if (!(var > 0.0)) {
        *m = mp > 0.0 ? mp : 0.0;
        *v = 0.0;
        *dm = mp > 0.0 ? 1.0 : 0.0;
        return;
    }
    const double sd = sqrt(var), a = mp / sd;
    const double tail = 0.5 * erfc(fabs(a) / M_SQRT2); /* ≤ 1/2 */
    const double cdf = a >= 0.0 ? 1.0 - tail : tail, ccdf = a >= 0.0 ? tail : 1.0 - tail;
    const double pdf = exp(-0.5 * a * a) / sqrt(2.0 * M_PI);
    *m = mp * cdf + sd * pdf;
    /* d E[Y]/dμ with var = μ + c (the pixel's Poisson part follows its mean): ∂/∂μ' = Φ(a), ∂/∂σ = φ(a),
     * dσ/dμ = 1/(2σ) */
    *dm = cdf + pdf / (2.0 * sd);
    const double vv = mp * mp * cdf * ccdf + var * cdf + mp * sd * pdf * (ccdf - cdf) - var * pdf * pdf;
    *v = vv > 0.0 ? vv : 0.0;
}

/* CoG / tCoG set-up of subaperture i: threshold, reference centroid, gain, raw (uncorrected) covariance. */
static int setup_cog(wt_centroid *c, int i, const float *r, const float *dx, const float *dy, double *work,
                     double *cxx, double *cxy, double *cyy)
{
    const int ns = c->ns, tcog = c->par.method == WT_CENTROID_TCOG;
    const double p = c->par.pixel, noise_var = c->par.background + c->par.read_noise * c->par.read_noise;
    double t = 0.0;
    if (tcog) {
        double peak = 0.0;
        for (size_t j = 0; j < (size_t)ns * (size_t)ns; j++) peak = r[j] > peak ? r[j] : peak;
        t = c->par.threshold_noise * sqrt(noise_var) + c->par.threshold_peak * peak;
    }
    c->thr[i] = t;
    /* reference weights w0_j = I0_j (CoG) or max(I0_j − T, 0) (tCoG): the estimator on I0 */
    double n0 = 0.0, x0 = 0.0, y0 = 0.0;
    for (int iy = c->off; iy < c->off + c->nw; iy++)
        for (int ix = c->off; ix < c->off + c->nw; ix++) {
            double w = (double)r[ix + ns * iy] - t;
            w = w > 0.0 ? w : 0.0;
            n0 += w;
            x0 += (ix - c->c0) * p * w;
            y0 += (iy - c->c0) * p * w;
        }
    if (!(n0 > 0.0))
        return WT_ERROR(c->ctx, WT_ERR_INVALID,
                        "centroid: ref: subaperture %d has no flux %s in the %dx%d window (sum %g e-)", i,
                        tcog ? "above the threshold" : "", c->nw, c->nw, n0);
    x0 /= n0;
    y0 /= n0;
    c->ref_s[i] = x0;
    c->ref_s[c->nsub + i] = y0;
    /* gain: ∂s/∂θ_k = Σ (x_j − x0) ∂w_j/∂θ_k / n0, with ∂w_j/∂θ = ∂I0_j/∂θ on the pixels that count
     * (all of the window for the CoG, I0_j > T for the tCoG) */
    double g[4] = {0.0, 0.0, 0.0, 0.0};
    /* noise: CoG propagates V_j = I0_j + B + σe² through the linearised ratio around I0; the tCoG through
     * the clipped pixels' Gaussian-approximation moments (centroid.h) */
    double m0 = 0.0, mx = 0.0, my = 0.0;
    for (int iy = c->off; iy < c->off + c->nw; iy++)
        for (int ix = c->off; ix < c->off + c->nw; ix++) {
            const int j = ix + ns * iy;
            const double xj = (ix - c->c0) * p, yj = (iy - c->c0) * p;
            if (!tcog || (double)r[j] > t) {
                g[0] += (xj - x0) * dx[j];
                g[1] += (xj - x0) * dy[j];
                g[2] += (yj - y0) * dx[j];
                g[3] += (yj - y0) * dy[j];
            }
            if (tcog) { /* the clipped pixel's mean, variance and dE/dμ, kept in work for the loops below */
                double m, v, dm;
                clipped_moments(r[j], r[j] + noise_var, t, &m, &v, &dm);
                work[3 * j] = m;
                work[3 * j + 1] = v;
                work[3 * j + 2] = dm;
                m0 += m;
                mx += xj * m;
                my += yj * m;
            }
        }
    for (int k = 0; k < 4; k++) g[k] /= n0;
    /* centre and normalisation of the noise propagation: I0's for the CoG, the clipped means' for tCoG */
    double nn = n0, xc = x0, yc = y0;
    if (tcog) {
        nn = m0;
        xc = mx / m0;
        yc = my / m0;
    }
    if (tcog && c->par.noise_calibrated) {
        /* the expected estimator at the operating flux and noise: its value on I0 is the reference, its
         * derivative Σ (x_j − x_c) dE[w_j]/dμ_j ∂I0_j/∂θ / Σ E[w_j] the gain (what a calibration of the
         * reference slopes and of the centroid gain with noisy frames measures) */
        if (!(m0 > 0.0))
            return WT_ERROR(c->ctx, WT_ERR_INVALID, "centroid: ref: subaperture %d: the clipped pixels' mean flux is %g e-",
                            i, m0);
        c->ref_s[i] = xc;
        c->ref_s[c->nsub + i] = yc;
        for (int k = 0; k < 4; k++) g[k] = 0.0;
        for (int iy = c->off; iy < c->off + c->nw; iy++)
            for (int ix = c->off; ix < c->off + c->nw; ix++) {
                const int j = ix + ns * iy;
                const double xj = (ix - c->c0) * p - xc, yj = (iy - c->c0) * p - yc, dm = work[3 * j + 2];
                g[0] += xj * dm * dx[j];
                g[1] += xj * dm * dy[j];
                g[2] += yj * dm * dx[j];
                g[3] += yj * dm * dy[j];
            }
        for (int k = 0; k < 4; k++) g[k] /= m0;
    }
    memcpy(c->gain + 4 * (size_t)i, g, sizeof g);
    double sxx = 0.0, sxy = 0.0, syy = 0.0;
    for (int iy = c->off; iy < c->off + c->nw; iy++)
        for (int ix = c->off; ix < c->off + c->nw; ix++) {
            const int j = ix + ns * iy;
            const double xj = (ix - c->c0) * p - xc, yj = (iy - c->c0) * p - yc;
            const double v = tcog ? work[3 * j + 1] : r[j] + noise_var;
            sxx += xj * xj * v;
            sxy += xj * yj * v;
            syy += yj * yj * v;
        }
    *cxx = sxx / (nn * nn);
    *cxy = sxy / (nn * nn);
    *cyy = syy / (nn * nn);
    return WT_OK;
}

/* MF set-up of subaperture i: R (stored in float), R·I0, gain R·[∂I0/∂θx ∂I0/∂θy], raw covariance R C Rᵀ. */
static int setup_mf(wt_centroid *c, int i, const float *r, const float *dx, const float *dy, double *cxx,
                    double *cxy, double *cyy)
{
    const size_t npix = (size_t)c->ns * (size_t)c->ns;
    const int k = 2 + (c->par.mf_flux != 0);
    const double noise_var = c->par.background + c->par.read_noise * c->par.read_noise;
    double peak = 0.0, flux = 0.0;
    for (size_t j = 0; j < npix; j++) {
        peak = r[j] > peak ? r[j] : peak;
        flux += r[j];
    }
    if (!(flux > 0.0))
        return WT_ERROR(c->ctx, WT_ERR_INVALID,
                        "centroid: ref: subaperture %d has zero flux: the matched filter needs a reference spot", i);
    /* A pixel with V = 0 (I0 = B = σe = 0) would get an infinite weight; it carries neither signal nor
     * noise, so a floor far below any real variance (1e-9 of the peak) only keeps C⁻¹ finite. */
    const double vfloor = 1e-9 * peak;
    /* M = Gᵀ C⁻¹ G (k x k, symmetric) */
    double m[3][3] = {{0}};
    for (size_t j = 0; j < npix; j++) {
        double v = r[j] + noise_var;
        v = v > vfloor ? v : vfloor;
        const double gj[3] = {dx[j], dy[j], r[j]};
        for (int a = 0; a < k; a++)
            for (int b = 0; b <= a; b++) m[a][b] += gj[a] * gj[b] / v;
    }
    /* Cholesky M = L Lᵀ; a pivot at rounding level means dependent columns (no derivative, zero flux) */
    double l[3][3] = {{0}};
    for (int a = 0; a < k; a++) {
        for (int b = 0; b <= a; b++) {
            double s = m[a][b];
            for (int q = 0; q < b; q++) s -= l[a][q] * l[b][q];
            if (a == b) {
                if (!(s > 1e-12 * m[a][a]))
                    return WT_ERROR(c->ctx, WT_ERR_INVALID,
                                    "centroid: ref/dref_x/dref_y: subaperture %d gives a singular matched-filter "
                                    "matrix G^T C^-1 G (pivot %d: %g of %g): its columns are linearly dependent "
                                    "or zero",
                                    i, a, s, m[a][a]);
                l[a][a] = sqrt(s);
            } else {
                l[a][b] = s / l[b][b];
            }
        }
    }
    /* M⁻¹ = L⁻ᵀ L⁻¹: invert L (lower), then multiply */
    double li[3][3] = {{0}}, minv[3][3] = {{0}};
    for (int a = 0; a < k; a++) {
        li[a][a] = 1.0 / l[a][a];
        for (int b = 0; b < a; b++) {
            double s = 0.0;
            for (int q = b; q < a; q++) s += l[a][q] * li[q][b];
            li[a][b] = -s / l[a][a];
        }
    }
    for (int a = 0; a < k; a++)
        for (int b = 0; b < k; b++) {
            double s = 0.0;
            for (int q = (a > b ? a : b); q < k; q++) s += li[q][a] * li[q][b];
            minv[a][b] = s;
        }
    /* R_aj = Σ_q M⁻¹_aq G_jq / V_j, a = x, y; stored in float (the per-frame path streams it) */
    float *rx = c->rows + 2 * npix * (size_t)i, *ry = rx + npix;
    for (size_t j = 0; j < npix; j++) {
        double v = r[j] + noise_var;
        v = v > vfloor ? v : vfloor;
        const double gj[3] = {dx[j], dy[j], r[j]};
        double ax = 0.0, ay = 0.0;
        for (int q = 0; q < k; q++) {
            ax += minv[0][q] * gj[q];
            ay += minv[1][q] * gj[q];
        }
        rx[j] = (float)(ax / v);
        ry[j] = (float)(ay / v);
    }
    /* everything below from the stored float rows: what the per-frame path applies. R·I0 by the same
     * kernel as raw_one, so the reference image gives exactly zero. */
    double sx, sy, g[4] = {0.0, 0.0, 0.0, 0.0}, sxx = 0.0, sxy = 0.0, syy = 0.0;
    mf_dot(rx, ry, r, npix, &sx, &sy);
    for (size_t j = 0; j < npix; j++) {
        const double v = r[j] + noise_var, ax = rx[j], ay = ry[j];
        g[0] += ax * dx[j];
        g[1] += ax * dy[j];
        g[2] += ay * dx[j];
        g[3] += ay * dy[j];
        sxx += ax * ax * v;
        sxy += ax * ay * v;
        syy += ay * ay * v;
    }
    c->ref_s[i] = sx;
    c->ref_s[c->nsub + i] = sy;
    memcpy(c->gain + 4 * (size_t)i, g, sizeof g);
    *cxx = sxx;
    *cxy = sxy;
    *cyy = syy;
    return WT_OK;
}

static int check_finite_param(wt_context *ctx, const char *name, double v, double lo, int lo_open, double hi)
{
    if (!isfinite(v) || v < lo || (lo_open && v == lo) || v > hi)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: %s = %g: must be finite and %s %g%s", name, v,
                        lo_open ? ">" : ">=", lo, hi < INFINITY ? " (and below its upper bound)" : "");
    return WT_OK;
}

/* Every value of one input image array finite (and ≥ 0 for the reference intensities). */
static int check_images(wt_context *ctx, const char *name, const float *a, int nsub, int ns, int nonneg)
{
    const size_t npix = (size_t)ns * (size_t)ns, n = npix * (size_t)nsub;
    if (!a) return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: %s is NULL", name);
    for (size_t q = 0; q < n; q++) {
        const float v = a[q];
        if (isfinite(v) && (!nonneg || v >= 0.0f)) continue;
        const int i = (int)(q / npix), j = (int)(q % npix);
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: %s[%zu] (subaperture %d, pixel (%d, %d)) = %g: must be %s",
                        name, q, i, j % ns, j / ns, (double)v, nonneg ? "finite and >= 0" : "finite");
    }
    return WT_OK;
}

static int check_params(wt_context *ctx, const wt_centroid_params *par, int nsub, int ns)
{
    int st;
    if (!par) return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: par is NULL");
    if (par->method != WT_CENTROID_COG && par->method != WT_CENTROID_TCOG && par->method != WT_CENTROID_MF)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: method = %d: must be WT_CENTROID_COG (0), _TCOG (1) or _MF (2)",
                        par->method);
    /* 4·nsub indexes the gains in int arithmetic */
    if (nsub < 1 || nsub > INT_MAX / 4)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: nsub = %d: must be in [1, %d]", nsub, INT_MAX / 4);
    if (ns < 1 || ns > WT_CENTROID_MAX_PIXELS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: ns = %d: must be in [1, %d]", ns, WT_CENTROID_MAX_PIXELS);
    if (par->window < 0 || par->window > ns)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: window Nw = %d: must be in [0, Ns = %d] (0: the whole detector)",
                        par->window, ns);
    if (par->window > 0 && (ns - par->window) % 2 != 0)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "centroid: window Nw = %d: Ns - Nw = %d must be even for the window to be centred on the detector",
                        par->window, ns - par->window);
    if (par->method == WT_CENTROID_MF && par->window != 0 && par->window != ns)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "centroid: window Nw = %d with the matched filter: it weights every pixel by its noise, "
                        "use 0 or Ns = %d", par->window, ns);
    if (par->mf_flux != 0 && par->mf_flux != 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: mf_flux = %d: must be 0 or 1", par->mf_flux);
    if (par->noise_calibrated != 0 && par->noise_calibrated != 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: noise_calibrated = %d: must be 0 or 1", par->noise_calibrated);
    if (par->apply_gain != 0 && par->apply_gain != 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: apply_gain = %d: must be 0 or 1", par->apply_gain);
    if ((st = check_finite_param(ctx, "pixel", par->pixel, 0.0, 1, INFINITY)) < 0) return st;
    if ((st = check_finite_param(ctx, "background", par->background, 0.0, 0, INFINITY)) < 0) return st;
    if ((st = check_finite_param(ctx, "read_noise", par->read_noise, 0.0, 0, INFINITY)) < 0) return st;
    if ((st = check_finite_param(ctx, "threshold_noise", par->threshold_noise, 0.0, 0, INFINITY)) < 0) return st;
    if (!(par->threshold_peak >= 0.0 && par->threshold_peak < 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: threshold_peak = %g: must be in [0, 1) (a fraction of the peak)",
                        par->threshold_peak);
    return WT_OK;
}

void wt_centroid_free(wt_centroid *c)
{
    if (!c) return;
    wt_context *ctx = c->ctx;
    wt_free(ctx, c->ref_s);
    wt_free(ctx, c->gain);
    wt_free(ctx, c->ginv);
    wt_free(ctx, c->cov);
    wt_free(ctx, c->thr);
    wt_free(ctx, c->rows);
    wt_free(ctx, c);
}

int wt_centroid_alloc(wt_context *ctx, const wt_centroid_params *par, int nsub, int ns, const float *ref,
                      const float *dref_x, const float *dref_y, wt_centroid **out)
{
    int st = WT_OK;
    wt_centroid *c = NULL;
    double *work = NULL; /* tCoG: the clipped pixels' mean, variance and dE/dμ, 3·Ns² */
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: out is NULL");
    *out = NULL;
    if ((st = check_params(ctx, par, nsub, ns)) < 0) return st;
    if ((st = check_images(ctx, "ref", ref, nsub, ns, 1)) < 0) return st;
    if ((st = check_images(ctx, "dref_x", dref_x, nsub, ns, 0)) < 0) return st;
    if ((st = check_images(ctx, "dref_y", dref_y, nsub, ns, 0)) < 0) return st;

    WT_ALLOC(ctx, c, 1, "the centroider");
    c->ctx = ctx;
    c->par = *par;
    c->nsub = nsub;
    c->ns = ns;
    c->nw = par->window > 0 ? par->window : ns;
    c->off = (ns - c->nw) / 2;
    c->c0 = 0.5 * (ns - 1);
    const size_t npix = (size_t)ns * (size_t)ns;
    WT_ALLOC(ctx, c->ref_s, 2 * (size_t)nsub, "the reference slopes");
    WT_ALLOC(ctx, c->gain, 4 * (size_t)nsub, "the gains");
    WT_ALLOC(ctx, c->ginv, 4 * (size_t)nsub, "the inverse gains");
    WT_ALLOC(ctx, c->cov, 3 * (size_t)nsub, "the noise covariance");
    WT_ALLOC(ctx, c->thr, (size_t)nsub, "the thresholds");
    if (par->method == WT_CENTROID_MF) WT_ALLOC(ctx, c->rows, 2 * npix * (size_t)nsub, "the matched-filter rows");
    if (par->method == WT_CENTROID_TCOG) WT_ALLOC(ctx, work, 3 * npix, "the threshold workspace");

    /* Set-up is serial (the first error stops it, with its message): a fraction of a second for an E-ELT LGS of
     * 16² pixels, the tCoG's the longest (an erfc per pixel). */
    for (int i = 0; i < nsub; i++) {
        const float *r = ref + npix * (size_t)i, *dx = dref_x + npix * (size_t)i, *dy = dref_y + npix * (size_t)i;
        double cxx, cxy, cyy;
        if (par->method == WT_CENTROID_MF)
            WT_TRY(setup_mf(c, i, r, dx, dy, &cxx, &cxy, &cyy));
        else
            WT_TRY(setup_cog(c, i, r, dx, dy, work, &cxx, &cxy, &cyy));
        double *g = c->gain + 4 * (size_t)i, *gi = c->ginv + 4 * (size_t)i;
        if (par->apply_gain) {
            /* a gain that does not resolve both axes cannot be inverted: relative determinant test */
            const double det = g[0] * g[3] - g[1] * g[2];
            const double scale = fmax(fmax(fabs(g[0]), fabs(g[1])), fmax(fabs(g[2]), fabs(g[3])));
            if (!(fabs(det) > 1e-6 * scale * scale) || !isfinite(det)) {
                st = WT_ERROR(ctx, WT_ERR_INVALID,
                              "centroid: apply_gain: the gain of subaperture %d is singular ({%g, %g; %g, %g}, det %g): "
                              "the estimator does not respond to both axes; check dref_x/dref_y or set apply_gain = 0",
                              i, g[0], g[1], g[2], g[3], det);
                goto fail;
            }
            gi[0] = g[3] / det;
            gi[1] = -g[1] / det;
            gi[2] = -g[2] / det;
            gi[3] = g[0] / det;
            sandwich(gi, cxx, cxy, cyy, &cxx, &cxy, &cyy);
        } else {
            gi[0] = gi[3] = 1.0;
            gi[1] = gi[2] = 0.0;
        }
        c->cov[i] = cxx;
        c->cov[nsub + i] = cxy;
        c->cov[2 * nsub + i] = cyy;
    }
    wt_free(ctx, work);
    *out = c;
    return WT_OK;
fail:
    wt_free(ctx, work);
    wt_centroid_free(c);
    return st;
}

int wt_centroid_nsub(const wt_centroid *c) { return c->nsub; }
size_t wt_centroid_memory(const wt_centroid *c)
{
    size_t b = sizeof *c + (size_t)c->nsub * (2 + 4 + 4 + 3 + 1) * sizeof(double);
    if (c->rows) b += 2 * (size_t)c->nsub * c->ns * c->ns * sizeof(float);
    return b;
}
int wt_centroid_pixels(const wt_centroid *c) { return c->ns; }
double wt_centroid_threshold(const wt_centroid *c, int i) { return c->thr[i]; }

void wt_centroid_gain(const wt_centroid *c, int i, double g[4]) { memcpy(g, c->gain + 4 * (size_t)i, 4 * sizeof *g); }

void wt_centroid_noise_cov(const wt_centroid *c, double *cov) { memcpy(cov, c->cov, 3 * (size_t)c->nsub * sizeof *cov); }

/* ---------- Monte-Carlo calibration ---------- */

int wt_centroid_noise_mc(const wt_centroid *c, const float *images, int ndraws, uint64_t seed, double *cov,
                         double *mean)
{
    int st = WT_OK;
    wt_context *ctx = c->ctx;
    const int nsub = c->nsub, ns = c->ns;
    const size_t npix = (size_t)ns * (size_t)ns;
    if (ndraws < 2) return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: noise_mc: ndraws = %d: must be >= 2", ndraws);
    if (!cov) return WT_ERROR(ctx, WT_ERR_INVALID, "centroid: noise_mc: cov is NULL");
    if ((st = check_images(ctx, "images", images, nsub, ns, 1)) < 0) return st;
    const int nth = wt_context_threads(ctx);
    float *work = NULL;
    WT_ALLOC(ctx, work, npix * (size_t)nth, "the Monte-Carlo images");
    const double b = c->par.background, se = c->par.read_noise;
#pragma omp parallel num_threads(nth)
    {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        float *d = work + npix * (size_t)tid;
#pragma omp for schedule(dynamic, 1) /* a subaperture is ndraws·Ns² draws: chunks of one balance */
        for (int i = 0; i < nsub; i++) {
            const float *img = images + npix * (size_t)i;
            wt_rng rng;
            wt_rng_init(&rng, seed, (uint64_t)i);
            /* Welford's running mean and co-moments: no cancellation for slopes far from zero */
            double mx = 0.0, my = 0.0, qxx = 0.0, qxy = 0.0, qyy = 0.0;
            for (int n = 0; n < ndraws; n++) {
                for (size_t j = 0; j < npix; j++) {
                    double v = wt_poisson(&rng, (double)img[j] + b) - b;
                    if (se > 0.0) v += se * wt_rng_normal(&rng);
                    d[j] = (float)v;
                }
                double sx, sy;
                slope_one(c, i, d, &sx, &sy);
                const double ex = sx - mx, ey = sy - my;
                mx += ex / (n + 1);
                my += ey / (n + 1);
                qxx += ex * (sx - mx);
                qxy += ex * (sy - my);
                qyy += ey * (sy - my);
            }
            cov[i] = qxx / (ndraws - 1);
            cov[nsub + i] = qxy / (ndraws - 1);
            cov[2 * nsub + i] = qyy / (ndraws - 1);
            if (mean) {
                mean[i] = mx;
                mean[nsub + i] = my;
            }
        }
    }
    wt_free(ctx, work);
    return WT_OK;
fail:
    return st;
}
