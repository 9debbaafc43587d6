/* core/op/noise.h: the Shack–Hartmann noise model C_E of one sensor (SPEC §4, paper eq.
 * elongation_matrix and widehatc).
 *
 * Per-axis variance (Gaussian spot FWHM θf, N photons, read noise σe, Ns x Ns pixels of scale p):
 *     σ² = θf² / (8 ln2 N) + p² σe² Ns⁴ / (12 N²)      [rad²]       (or σ² = NEA² when given)
 * 2x2 block of subaperture i, elongation vector β_i [rad]:  C̃_i = σ_i² (I + (τ/θf²) β_i β_iᵀ),
 * σ_i² = σ² c_i with c_i = 1, or the variance factor of a partly lit subaperture (fewer photons).
 * σ (NEA) is the per-axis noise of the unelongated spot: the short axis of an elongated one; along the
 * elongation the variance is σ_i² (1 + τ|β_i|²/θf²).
 * LGS tip-tilt removal:  Ĉ⁻¹ = (I − T) C̃⁻¹ (I − T),  T the orthogonal projection onto the sensor's
 * global tip and tilt, i.e. onto span{(1…1, 0…0), (0…0, 1…1)} in the [s_x…, s_y…] layout.
 * LGS focus removal (optional, wt_noise_set_focus): T = T_tt + f fᵀ, f the unit focus slope pattern
 * (x_i − x̄, y_i − ȳ)/‖·‖ over the valid subaperture centres, orthogonal to tip and tilt by construction.
 * Slope layout as core/op/shack_hartmann.h: block i couples s_x[i] and s_y[i] = slope[nsub + i].
 */
#ifndef WT_NOISE_H
#define WT_NOISE_H

#include "../base/base.h"
#include "../base/rng.h"
#include "../la/sparse.h"

/* σ² per axis [rad²] from the photon/read-noise model; nea > 0 [rad] overrides it (σ² = nea²).
 * Returns +inf when photons ≤ 0 and no NEA is given (wt_noise_alloc rejects it). A noise-free truth is
 * the simulator's switch (sim.noise), not a zero variance in the reconstructor's model. */
double wt_noise_variance(double photons, double read_noise_e, double spot_fwhm, double pixel, int pixels,
                         double nea);

/* Elongation vectors of an LGS sensor (SPEC §4): β_i = (r_i − l) Δh_Na / H², r_i the subaperture centre,
 * l the launch position [m]. beta: 2*nsub, [βx…, βy…]. */
void wt_noise_elongation(int nsub, const double *cx, const double *cy, double launch_x, double launch_y,
                         double sodium_fwhm, double lgs_altitude, double *beta);

/* The integrator's noise gain Σ_k h_k²: the variance of the command a_t that a unit-variance white
 * measurement error puts through a_{t+d} = a_{t+d−1} + g (x_t − a_t) (the POLC loop of sim/loop.c),
 * i.e. the factor by which the loop averages measurement noise over its memory. g/(2 − g) for delay 1;
 * 0.389 for g = 0.4, delay 2. gain in (0, 1], delay 1 or 2 (the config's ranges, for which the loop is stable). */
double wt_noise_loop_gain(double gain, int delay);

typedef struct wt_noise wt_noise;

/* nsub subapertures, per-axis σ² [rad²] (> 0), spot FWHM θf [rad], elongation vectors beta (2*nsub,
 * copied; NULL: none), τ ∈ [0, 1], remove_tt: 1 for the LGS tip-tilt projection in the weight. */
int wt_noise_alloc(wt_context *ctx, int nsub, double sigma2, double spot_fwhm, const double *beta, double tau,
                   int remove_tt, wt_noise **out);
/* The same with per-subaperture variance factors c_i (nsub, each finite and > 0; NULL: all 1). */
int wt_noise_alloc_scaled(wt_context *ctx, int nsub, double sigma2, const double *scale, double spot_fwhm,
                          const double *beta, double tau, int remove_tt, wt_noise **out);
/* The noise model from explicit 2x2 covariance blocks (a diffractive sensor's centroider, calibrated at set-up:
 * core/optics/centroid.h): cov 3·nsub [Σxx of every subaperture…, Σxy…, Σyy…] [rad²], each block symmetric
 * positive definite and finite. τ acts as in the paper's model, on the part of each block beyond its short
 * axis: C̃_i = λ_i I + τ (Σ_i − λ_i I), λ_i the smaller eigenvalue of Σ_i (τ = 1: the calibrated block;
 * τ = 0: an isotropic one with the short-axis variance, as σ² I is the unelongated spot's). For a block
 * σ²(I + ββᵀ/θf²) this is exactly wt_noise_alloc's C̃_i. */
int wt_noise_alloc_blocks(wt_context *ctx, int nsub, const double *cov, double tau, int remove_tt, wt_noise **out);
/* Per-axis variance factor of a subaperture that collects `lit` (0 < lit ≤ 1) of the photons of a fully
 * lit one: σ²(N lit)/σ²(N) for the photon/read model (arguments as wt_noise_variance), 1/lit for an NEA. */
double wt_noise_lit_factor(double photons, double read_noise_e, double spot_fwhm, double pixel, int pixels,
                           double nea, double lit);
/* Mean per-axis variance over subapertures and axes, (tr C̃_i)/2 averaged over i [rad²]. */
double wt_noise_mean_variance(const wt_noise *n);
void wt_noise_free(wt_noise *n);
int wt_noise_nslopes(const wt_noise *n);

/* y <- y + alpha * C̃ x */
void wt_noise_apply_cov(const wt_noise *n, double alpha, const double *x, double *y);
/* y <- y + alpha * C̃⁻¹ x */
void wt_noise_apply_inv(const wt_noise *n, double alpha, const double *x, double *y);
/* y <- y + alpha * Ĉ⁻¹ x  (= C̃⁻¹ x when remove_tt is 0). x and y must not alias. */
void wt_noise_apply_weight(const wt_noise *n, double alpha, const double *x, double *y);
/* wt_noise_apply_weight(ns[j], alpha, x[j], y[j]) for j < k, bit for bit. Sensors of one size (the
 * LGS) run side by side: the weight's sums over the subapertures are serial chains, one sensor alone
 * waits on the adder's latency (~3 cycles per subaperture), k of them share that wait. */
void wt_noise_apply_weight_many(const wt_noise *const *ns, int k, double alpha, const double *const *x,
                                double *const *y);
/* y[j] = Ĉ⁻¹ x[j] for j < k, overwritten: bit for bit what clearing y[j] to +0 and wt_noise_apply_weight_many(ns, k,
 * 1.0, x, y) give, with the products and the final update as contiguous (vectorised) passes and only the sums
 * as chains. x[j] and y[j] must not alias. */
void wt_noise_set_weight_many(const wt_noise *const *ns, int k, const double *const *x, double *const *y);
/* Single-precision form of wt_noise_set_weight_many (the tomography's fp32 operator): y_j = Ĉ_j⁻¹ x_j overwritten,
 * the blocks rounded to float at alloc, float products, the tip-tilt means summed in double. Float accuracy, not
 * the double path's bits: per slope within ~6·2⁻²⁴ of the sizes of the block products and the means (the bound
 * tests/test_noise.c derives). Sensors of any sizes, with or without the tip-tilt removal; x[j] and y[j] must not
 * alias. */
void wt_noise_set_weight_many_f32(const wt_noise *const *ns, int k, const float *const *x, float *const *y);
/* x <- (I − T) x: remove the global tip and tilt (and the focus, when set) in place. */
void wt_noise_remove_tt(const wt_noise *n, double *x);
/* f (2 nsub) = the unit focus slope pattern (cx_i − c̄x, cy_i − c̄y)/‖·‖ of the subapertures centred at (cx, cy):
 * a quadratic phase's Fried slopes are ∝ the centres, and the means removed make it orthogonal to tip and tilt.
 * Returns 1, or 0 (f undefined) when there is no such pattern (one subaperture: a tip-tilt sensor). */
int wt_noise_focus_pattern(int nsub, const double *cx, const double *cy, double *f);
/* Adds the focus of the subapertures centred at (cx, cy) (nsub each, the sensor's order) to T (LGS focus removal,
 * recon.lgs_focus_removal): n must have the tip-tilt removal, and the centres a focus pattern. */
int wt_noise_set_focus(wt_noise *n, const double *cx, const double *cy);
/* The unit focus pattern T removes (2 nsub), or NULL when the focus is not removed. */
const double *wt_noise_focus(const wt_noise *n);
/* The inverse 2x2 block of subaperture i: {a, b, c} with C̃_i⁻¹ = [[a, b], [b, c]]. */
void wt_noise_inv_block(const wt_noise *n, int i, double *a, double *b, double *c);
/* x <- x + a draw of N(0, C̃) (2x2 Cholesky per block). */
void wt_noise_sample(const wt_noise *n, wt_rng *rng, double *x);
/* C̃⁻¹ as a sparse matrix (nslopes x nslopes, 2x2 blocks). */
int wt_noise_assemble_inv(const wt_noise *n, wt_sparse **out);

#endif
