/* core/optics/centroid.h: Shack–Hartmann centroiders on detector images, their gains and their noise
 * covariance (SPEC §4b; matched filter of Gilles & Ellerbroek, Appl. Opt. 45, 6568, 2006).
 *
 * Data contract with the image module (core/optics/spot.c):
 *  - one subaperture = Ns x Ns float32 pixels in photo-electrons, pixel (ix, iy) at ix + Ns·iy, its centre
 *    at the angle x = (ix − (Ns−1)/2)·p, y = (iy − (Ns−1)/2)·p [rad]; a sensor = nsub consecutive images;
 *  - a positive slope θx (OPD gradient, rad) moves the spot towards +x; the set-up receives per subaperture
 *    the noise-free reference I0 (flat wavefront) and its derivatives ∂I0/∂θx, ∂I0/∂θy [e⁻/rad];
 *  - detector: d = Poisson(I + B) + N(0, σe²) − B, so E[d] = I and Var[d] = V = I + B + σe²;
 *  - slopes out [rad]: [s_x of every subaperture…, s_y…] (docs/design.md "Conventions").
 *
 * Estimators (x_j, y_j the pixel angles, W the window of Nw x Nw pixels centred on the detector):
 *  - CoG:   s = Σ_W x_j d_j / Σ_W d_j, clamped per axis to the hull of the window's pixel centres
 *           (±(Nw−1)p/2): noise makes pixels negative, and where Σ_W d nears zero the ratio leaves the
 *           window, a heavy tail no covariance describes (centroid.c); a noise-free image is never clamped;
 *  - tCoG:  the same with d_j replaced by max(d_j − T, 0), T a fixed threshold per subaperture [e⁻]
 *           (non-negative weights: the clamp never acts):
 *             T = threshold_noise · √(σe² + B) + threshold_peak · max_j I0_j.
 *           The first term is a multiple of the noise of an empty pixel (after background subtraction):
 *           k ≈ 3 removes the read/background noise of the pixels the spot does not reach, which is what
 *           makes a plain CoG over a wide window noisy (SPEC §4's Ns⁴ term). The second term is a fraction
 *           of the reference peak, for the photon-limited case where σe = B = 0 and the first term is
 *           zero. T is fixed at set-up (not a fraction of each frame's peak) so the estimator is a fixed
 *           function of the pixels: linearisable, and the same rule in the set-up's noise model and in
 *           every frame;
 *  - MF:    s = R (d − I0), G = [∂I0/∂θx, ∂I0/∂θy (, I0)], C = diag(V), R = rows 1–2 of
 *           (Gᵀ C⁻¹ G)⁻¹ Gᵀ C⁻¹; the optional I0 column (mf_flux) makes s blind to a change of flux.
 * Every estimator reports its slope relative to its value on I0 (CoG, tCoG: minus the reference centroid;
 * the MF is zero there by construction), so a flat wavefront gives zero slopes.
 *
 * Gain: the 2x2 response g = ∂s/∂θ at zero [rad/rad], from the derivative images (the linearisation of
 * the estimator; the identity for the MF by construction).
 * Noise calibration (tCoG, noise_calibrated): clipping turns zero-mean noise into positive weight — an empty
 * pixel's E[max(d − T, 0)] > 0 — so at a low threshold the mean tCoG of I0 is pulled towards the window's
 * centre and its response to a tilt is diluted, both against the noise-free linearisation: a bias and a gain
 * error at the operating flux (measured: the E-ELT loop at 100 e⁻ with T = 0.1 × peak diverged). With
 * noise_calibrated the reference is the expected estimator's value on I0, (x_c, y_c) = Σ (x_j, y_j) E[w_j] /
 * Σ E[w_j], and the gain its derivative, g_ab = Σ (a_j − a_c) (dE[w_j]/dμ_j) ∂I0_j/∂θ_b / Σ E[w_j], both
 * under the Gaussian approximation below (dE[w]/dμ = Φ(α) + φ(α)/(2σ), σ² = μ + B + σe²): what calibrating
 * the reference slopes and the centroid gain on noisy frames at the operating flux measures. A noise-free
 * simulation keeps the noise-free calibration (a noisy one would bias it). With apply_gain the slopes are g⁻¹ s, which
 * restores the slope of a truncated (elongated) spot whose CoG gain is < 1.
 *
 * Noise covariance (2x2 per subaperture, [rad²]), first-order propagation of V through the estimator
 * (then g⁻¹ Σ g⁻ᵀ when the gain is applied):
 *  - CoG:  Σ_ab = Σ_W (a_j − a0)(b_j − b0) V_j / N0²,  N0 = Σ_W I0_j, (x0, y0) the reference centroid
 *          (exact to first order; the ratio's second order adds ~3 Var(Σ_W d)/N0², a few % at low flux with
 *          read noise over a wide window). Read noise alone over the whole detector: p²σe²Ns²(Ns² − 1)/(12 N²),
 *          of which SPEC §4's p²σe²Ns⁴/(12 N²) is the large-Ns limit;
 *  - tCoG: the same with the clipped pixels w_j = max(d_j − T, 0) under a Gaussian approximation of d_j
 *          (mean I0_j, variance V_j): N0 = Σ E[w_j], (x0, y0) = Σ (x_j, y_j) E[w_j] / N0 and Var[w_j]
 *          in place of V_j — for pixels far above T this is the plain linearisation around I0's
 *          above-threshold pixels, for pixels far below it they drop out, and the pixels near T (which a
 *          linearisation around I0 would count fully or not at all) get their clipped variance. Against
 *          the Monte-Carlo covariance (tests/test_centroid.c, T = 3√(σe² + B)) this is within ~8 % (the rest:
 *          the right skew of the Poisson pixels near T), where the plain linearisation around I0's
 *          above-threshold pixels overestimates the short-axis variance of an elongated spot by ~35 %. The
 *          gain stays the noise-free linearisation (step at T), the one a calibration on I0 measures;
 *  - MF:   R C Rᵀ = the top-left 2x2 of (Gᵀ C⁻¹ G)⁻¹ (computed as R C Rᵀ from the stored R).
 * wt_centroid_noise_mc is the Monte-Carlo alternative and check (exact Poisson + Gaussian draws).
 */
#ifndef WT_CENTROID_H
#define WT_CENTROID_H

#include <stdint.h>

#include "../base/base.h"

enum {
    WT_CENTROID_COG = 0,  /* centre of gravity over a window */
    WT_CENTROID_TCOG = 1, /* thresholded centre of gravity over a window */
    WT_CENTROID_MF = 2    /* matched filter (Gilles & Ellerbroek 2006) */
};

/* Largest detector side Ns [pixels]: far beyond any Shack–Hartmann subaperture (4–32 in practice); the
 * per-frame CoG keeps two column sums of this length on the stack. */
#define WT_CENTROID_MAX_PIXELS 256

typedef struct wt_centroid_params {
    int method;             /* WT_CENTROID_COG, _TCOG or _MF */
    int window;             /* Nw: CoG/tCoG window of Nw x Nw pixels centred on the detector, Ns − Nw even;
                               0: the whole detector. The MF uses every pixel (0 or Ns only) */
    double threshold_noise; /* tCoG: k in T = k √(σe² + B) + f max I0 [-], ≥ 0 */
    double threshold_peak;  /* tCoG: f in the same, in [0, 1) [-] */
    int mf_flux;            /* MF: 1 adds the I0 column to G (slopes blind to flux changes) */
    int apply_gain;         /* 1: slopes and covariance are corrected by the inverse gain g⁻¹ */
    int noise_calibrated;   /* tCoG: 1 calibrates the reference slope and the gain on the expected estimator
                               under the noise (see "Noise calibration" above), 0 on the noise-free I0 */
    double pixel;           /* p: pixel scale [rad], > 0 */
    double background;      /* B: background per pixel per frame [e⁻], ≥ 0 */
    double read_noise;      /* σe: read noise per pixel [e⁻ rms], ≥ 0 */
} wt_centroid_params;

typedef struct wt_centroid wt_centroid;

/* Build the centroider of one sensor at set-up: nsub subapertures of ns x ns pixels; ref, dref_x, dref_y:
 * nsub·ns² each (I0 [e⁻], ∂I0/∂θx and ∂I0/∂θy [e⁻/rad]), read and not kept. Validates everything (finite
 * values, I0 ≥ 0 with positive flux in the window, sizes, a non-singular gain when it is applied, a
 * non-singular MF normal matrix) and records an error naming the argument. Computes the reference
 * centroids, gains, the MF rows and the analytic noise covariance. Allocates; *out = NULL on error. */
int wt_centroid_alloc(wt_context *ctx, const wt_centroid_params *par, int nsub, int ns, const float *ref,
                      const float *dref_x, const float *dref_y, wt_centroid **out);
void wt_centroid_free(wt_centroid *c);

int wt_centroid_nsub(const wt_centroid *c);
/* Bytes the object holds (per-subaperture references, gains, covariances, thresholds, MF rows). */
size_t wt_centroid_memory(const wt_centroid *c);
int wt_centroid_pixels(const wt_centroid *c); /* Ns */
/* tCoG threshold T of subaperture i [e⁻] (0 for CoG and MF). */
double wt_centroid_threshold(const wt_centroid *c, int i);

/* Per frame: images nsub·ns² [e⁻, background subtracted] -> slopes 2·nsub [rad], [s_x…, s_y…].
 * Allocates nothing, OpenMP over subapertures with the context's thread count, the result does not depend
 * on it. A CoG/tCoG window with no positive signal gives zero slopes for that subaperture; NaN in an image
 * propagates to its slopes (frames are not validated). */
void wt_centroid_apply(const wt_centroid *c, const float *images, double *slopes);

/* The estimator's gain of subaperture i, g = ∂s/∂θ at zero, row-major {∂sx/∂θx, ∂sx/∂θy, ∂sy/∂θx,
 * ∂sy/∂θy} [rad/rad], before any gain correction (the correction makes it the identity). */
void wt_centroid_gain(const wt_centroid *c, int i, double g[4]);

/* The analytic noise covariance of the slopes wt_centroid_apply returns (after the gain correction when
 * it is applied), computed at set-up: cov 3·nsub [rad²], [Σxx of every subaperture…, Σxy…, Σyy…]. */
void wt_centroid_noise_cov(const wt_centroid *c, double *cov);

/* Monte-Carlo calibration: ndraws (≥ 2) noisy frames d = Poisson(I + B) + N(0, σe²) − B around the images
 * `images` (nsub·ns², e.g. the reference I0; finite, ≥ 0), through wt_centroid_apply's estimator.
 * Subaperture i draws from wt_rng (seed, stream i), so the result does not depend on the thread count.
 * cov 3·nsub as wt_centroid_noise_cov (sample covariance, ndraws − 1 in the denominator); mean 2·nsub
 * [s_x…, s_y…] (NULL: not wanted). Allocates a workspace (ns² floats per thread). Cost: ndraws·nsub·ns²
 * pixel draws, a Poisson and a normal deviate each (minutes for an E-ELT LGS of 16² pixels with ndraws = 1000;
 * SPOT_MC_NS of core/model/estimate.c is the rate). A set-up tool
 * and the check of the analytic covariance, not a per-frame path. */
int wt_centroid_noise_mc(const wt_centroid *c, const float *images, int ndraws, uint64_t seed, double *cov,
                         double *mean);

#endif
