/* core/model/sensing.h: the diffractive sensor of one WFS (SPEC §4b, docs/design.md "Diffractive sensing"):
 * the spot model (core/optics/spot.h) and the centroider (core/optics/centroid.h) built from the system
 * geometry and the configuration, the centroider's noise covariance that the reconstructor uses as C_E, and
 * the per-frame truth path (OPD on the pupil samples -> images -> noise -> centroider -> slopes).
 *
 * One object per diffractive sensor, built once by wt_system_alloc and shared by the reconstructor's noise
 * model (cov) and the simulator's truth (the loop): the spot tables (~70 MB per E-ELT LGS) exist once.
 *
 * Geometry: subaperture k (the valid subapertures of the sensor's Shack–Hartmann model, in its order) of
 * side d has its centre (xc[k], yc[k]); its n_p x n_p pupil samples are cell-centred at spacing d/n_p
 * (spot.h's layout). Amplitude of a sample: its lit fraction of the annulus (wt_pupil_fraction of the
 * sample's square); lit[k]: the subaperture's lit fraction relative to the sensor's best-lit subaperture (1
 * for a fully lit LGS subaperture; for the NGS 1x1/2x2 sensors `photons` is the star's per (big)
 * subaperture whatever the pupil's shape, as the geometric lit_noise option).
 *
 * The OPD on the samples: bilinear interpolation of the simulator's fine grid (sim.points_per_subaperture
 * points per LGS subaperture side; the fine-grid OPD is what the geometric truth sensor reads too), only at
 * lit samples; wt_sensing_fine_mask says which fine points that reads.
 *
 * Threads: wt_sensing_sample is serial and touches only this object's OPD buffer (the loop calls it for
 * several sensors from one parallel region); wt_sensing_detect runs the spot and centroider OpenMP loops
 * and must be called from outside a parallel region, one sensor at a time (the spot workspaces are per
 * object, per thread). Neither allocates.
 */
#ifndef WT_SENSING_H
#define WT_SENSING_H

#include <stdint.h>

#include "../base/base.h"
#include "../config/config.h"
#include "../op/grid.h"
#include "../optics/centroid.h"

typedef struct wt_spot wt_spot;
typedef struct wt_sodium wt_sodium;

/* The truncation limits of the detector field : above WARN of a spot's flux
 * outside the field (worst subaperture of the noise-free reference), a warning naming the keys; above
 * REFUSE, refused. */
#define WT_SENSING_TRUNC_WARN 0.5
#define WT_SENSING_TRUNC_REFUSE 0.9

typedef struct wt_sensing_geometry {
    int lgs;                   /* 1: LGS (sodium line + uplink), 0: NGS (point source) */
    const char *name;          /* "LGS1", … for messages */
    const char *source;        /* the configuration file, for messages */
    int nsub;                  /* valid subapertures */
    const double *xc, *yc;     /* [nsub] centres [m] (read, not kept) */
    double side;               /* subaperture side d [m] */
    double diameter, obstruction; /* the annulus */
    double altitude;           /* LGS focus altitude H [m] */
    double launch_x, launch_y; /* LGS launch position [m] */
} wt_sensing_geometry;

typedef struct wt_sensing {
    wt_context *ctx;
    int lgs, nsub, np, ns;
    double side;
    double pixel;              /* detector pixel p [rad] */
    int seeing;                /* 1: the reference carries the tilt-removed seeing of r0, L0 (LGS only) */
    double r0, L0;             /* that seeing's Fried parameter at 500 nm and outer scale [m]: the reconstructor's
                                  atmosphere's (recon.atmosphere), not the truth's */
    double seeing_grid;        /* the simulation grid that renders it [m]; 0: the sky's (unlimited) spectrum */
    wt_spot *spot;             /* owned */
    wt_centroid *cen;          /* owned */
    double *xc, *yc;           /* [nsub] centres [m] */
    float *amp;                /* [nsub n_p²] amplitudes (the mask of lit samples) */
    double *cov;               /* [3 nsub] the centroider's noise covariance [rad²] (analytic or Monte Carlo, after
                                  the gain correction when applied): the reconstructor's C_E (before τ) */
    double *trunc;             /* [nsub] flux fraction outside the detector field, noise-free reference */
    float *i0;                 /* [nsub Ns²] noise-free reference images I0 [e-] */
    double nea_median;         /* median over subapertures of sqrt((λ1 + λ2)/2) [rad] */
    double mean_var;           /* mean over subapertures of (Σxx + Σyy)/2 [rad²] */
    double worst_trunc;        /* max of trunc */
    int worst_sub;             /* its subaperture */
    double setup_seconds;      /* wall time of the set-up */
    double launch_x, launch_y; /* LGS launch position [m] (the elongation's direction) */
    double gain_sum[5];        /* in-loop gain sums since the last reset: Σ s∥g∥, Σ g∥², Σ s⊥g⊥, Σ g⊥², frames */
    int gain_on;               /* 1 once reset: the frames after it are counted (none before: no cost) */
    float *opd;                /* [nsub n_p²] per-frame OPD on the samples [m] */
    float *img;                /* [nsub Ns²] per-frame images */
    /* what a reference rebuilt in the loop needs (wt_sensing_set_reference) and what undoes it (restore) */
    wt_centroid_params cpar;   /* the centroider's parameters */
    int calibration, calibration_draws; /* noise_calibration (1: Monte Carlo) and its draws */
    uint64_t calibration_seed;
    wt_sodium *sodium0;        /* LGS: the set-up profile (owned), which the reference of the set-up is made of */
    int sodium_changed;        /* the spot tables are another profile's (wt_sensing_set_sodium) */
    int reference_changed;     /* the reference is not the set-up's (wt_sensing_set_reference) */
    /* the reference from the loop's own pixels (wt_sensing_pixels_*); pix_acc NULL: not accumulating */
    float *pix_acc;            /* [nsub E²] Σ of every frame's image since the last rebuild, re-centred by its slopes
                                  before interpolation (core/optics/image_shift.h: T_u I on E = Ns + 2 margins) */
    double *pix_tmp;           /* [threads (wt_image_shift_work(Ns) + Ns²)] scratch of the shifts */
    float *pix_anchor;         /* [3 nsub Ns²] the set-up reference's derivatives less those of its pixels' spline
                                  (x, y), and its image */
    wt_centroid *pix_cen0;     /* the set-up reference's centroider: the frames are re-centred on its slopes, a zero
                                  that stays put (docs/design.md "The reference from the loop's own pixels") */
    double *pix_s0;            /* [2 nsub] its slopes of the current frame */
    long pix_frames;           /* frames in pix_acc */
    double pix_seconds;        /* wall time of the accumulation since wt_sensing_pixels_start */
    /* the matched filter's gain measured on the loop's own pixels (sensing_gain.c); gain_acc NULL: not accumulating */
    float *gain_acc;           /* [nsub Ns²] Σ of every frame's image as detected since the last estimate */
    long gain_frames;          /* frames in gain_acc */
    double gain_seconds;       /* wall time of the accumulation since wt_sensing_gain_start */
    double *gain_corr;         /* [4 nsub] the correction H_k applied to every slope (row-major); NULL: none */
    double *gain_cov0;         /* [3 nsub] the covariance of the centroider in force before H (with gain_corr) */
    double gain_est[2];        /* the last estimate's gain along / across the elongation (mean of subapertures) */
    double gain_model[4];      /* the last fitted spot model: seeing strength α, blur {Σxx, Σxy, Σyy} [rad²] */
    long gain_fits;            /* estimates made (the next fit starts from the last's model) */
} wt_sensing;

/* Build the sensor of `w` (cfg->lgs_wfs or cfg->ngs_wfs, with model diffractive) for geometry g: sodium
 * profile (lgs.sodium_profile or a Gaussian of lgs.sodium_fwhm_m), spot model, reference I0 and its
 * derivatives, centroider, truncation check, noise covariance. Errors name the configuration keys (and the
 * profile file). */
int wt_sensing_alloc(wt_context *ctx, const wt_config *cfg, const wt_sensor_config *w, const wt_sensing_geometry *g,
                     wt_sensing **out);
void wt_sensing_free(wt_sensing *ws);

/* mask[fine] |= 1 for the fine-grid points the samples' bilinear interpolation reads. The fine grid must
 * cover every lit sample (WT_ERR_INVALID otherwise). */
int wt_sensing_fine_mask(const wt_sensing *ws, const wt_grid *fine, uint8_t *mask);
/* The OPD on the samples from the fine-grid map fine_opd (valid at the points of wt_sensing_fine_mask), plus
 * the tilt (tx, ty) [rad] (an OPD tx·x + ty·y: the spots move by (tx, ty)). Serial, allocates nothing. */
void wt_sensing_sample(wt_sensing *ws, const wt_grid *fine, const double *fine_opd, double tx, double ty);
/* Images of the sampled OPD, with noise when `noise` (subaperture s from WT_SPOT_STREAM(base_stream, s) of
 * seed), through the centroider: slopes[2 nsub] [rad] ([s_x…, s_y…]). Outside parallel regions only. */
int wt_sensing_detect(wt_sensing *ws, int noise, uint64_t seed, uint64_t base_stream, double *slopes);
/* The centroider's in-loop gain: every wt_sensing_detect compares each lit subaperture's slope s with the
 * true slope g of the OPD it sampled (the average gradient over the lit samples, amplitude-weighted finite
 * differences: the shift of the spot's centroid), both resolved along e_k (the unit vector from the launch
 * position to the subaperture, the elongation; x for an NGS) and across it; the gain is the least-squares
 * slope of s on g over subapertures and frames, Σ s g / Σ g² (noise in s, independent of g, leaves it
 * unbiased). A matched filter whose reference is the spot it sees has gain 1; a reference narrower than
 * the in-loop spot gives less. Counted from the first reset on (the loop resets at its settle frame; before any
 * reset nothing is computed, so the bench and the budget pay nothing). Reset and read: */
void wt_sensing_gain_reset(wt_sensing *ws);
/* *along, *across: the gains (NaN when no true slope was seen); *frames: the frames accumulated. */
void wt_sensing_gain_in_loop(const wt_sensing *ws, double *along, double *across, long *frames);

/* The same at the sensor's operating point: the reference I0 (the mean spot in the loop, with the seeing of
 * lgs.wfs.reference_seeing) instead of the image of the sampled OPD, with noise when `noise`. For the
 * reconstruction of pure noise: the centroider's noise where the loop holds it (the flat wavefront's spot is
 * narrower than the loop's and its noise smaller). A gain correction in force applies, and the images count in the
 * gain's accumulator as wt_sensing_detect's do (their estimate is the identity). Outside parallel regions only. */
int wt_sensing_detect_reference(wt_sensing *ws, int noise, uint64_t seed, uint64_t base_stream, double *slopes);

/* ---- the sodium layer in time and a reference that follows it (SPEC §12 "The sodium layer changes too") ----
 * The spot model (the truth's images) and the centroider (the real-time computer's reference I0, its derivatives,
 * the matched filter and its covariance C_E) are separate: the truth's profile may change without the reference. */

/* The truth's sodium profile (an LGS): the spot tables rebuilt (wt_spot_set_sodium), the images from now on of
 * na; the reference, centroider and covariance stay. Outside parallel regions only. */
int wt_sensing_set_sodium(wt_sensing *ws, const wt_sodium *na);
/* The same seen through the sensor's focus stage and centring {tx, ty, c} (core/optics/spot.h
 * wt_spot_set_sodium_staged; sim/focus_stage.h); na NULL: the set-up profile. wt_sensing_restore leaves no stage. */
int wt_sensing_set_sodium_staged(wt_sensing *ws, const wt_sodium *na, const double stage[3]);
/* A new reference: the centroider rebuilt from i0, dix, diy (nsub Ns² each; copied), with the set-up's parameters
 * and calibration (analytic or Monte Carlo: the same draws and seed), so the covariance cov (the reconstructor's C_E,
 * which follows once its noise weights are rebuilt: wt_reconstructor_refresh_noise), nea_median, mean_var, trunc,
 * worst_* anew. On error the sensor keeps its old reference. The hook of every reference the loop rebuilds. */
int wt_sensing_set_reference(wt_sensing *ws, const float *i0, const float *dix, const float *diy);
/* (sensing_reference.c, for the set-up and every rebuilt reference) the NEA statistics of the nsub 2×2 centroid noise
 * covariances cov ([xx | xy | yy], rad²): nea[k] = √(½ tr C_k) sorted (nea: nsub doubles of work), their median and
 * the mean per-axis variance ½ tr C_k. Returns −1, or the first subaperture whose C_k is not finite positive
 * definite (nothing written to median and mean_var then). */
int wt_sensing__nea_stats(int nsub, const double *cov, double *nea, double *median, double *mean_var);
/* The oracle's reference: I0 and its derivatives of the spot model's current profile (the truth's, as it renders
 * it) with the set-up's seeing, through wt_sensing_set_reference. From the set-up profile it gives the set-up's
 * reference bit for bit. Allocates 3 nsub Ns² floats for its duration. Outside parallel regions only. */
int wt_sensing_rebuild_reference(wt_sensing *ws);
/* The reference from the loop's own pixels (lgs.wfs.reference = pixels; docs/design.md "The reference from the loop's
 * own pixels"). After wt_sensing_pixels_start every wt_sensing_detect adds each subaperture's image (noisy, as the
 * detector reads it) re-centred by the slope the set-up reference's matched filter measures on it (a fixed zero: each
 * mean keeps part of the slopes it was re-centred on, and with the filter in force that part would compound from
 * rebuild to rebuild) — shifted by (−s_x, −s_y) / p pixels, cubic B-spline
 * (core/optics/image_shift.h) — to an accumulator. wt_sensing_pixels_reference then makes the reference of the mean of the
 * n frames accumulated: per pixel the set-up image plus the change Δ = mean − I0_set-up shrunk by its noise,
 * Δ (1 − k²σ²/Δ²)₊ with σ² = (max(mean, 0) + B + σe²)/n and k = WT_SENSING_PIXELS_SHRINK (a change the noise could
 * have made is taken for none: the derivatives below would otherwise carry the mean's noise, and a filter on noisy
 * derivatives reads low), then
 * max(·, 0) (the expected image is ≥ 0, and the matched filter's variance I0 + B + σe² must stay positive with
 * neither background nor read noise), and its derivatives
 *   ∂I0/∂θ = [S(I0) + ∂I0_set-up/∂θ − S(I0_set-up)],  S(I) = the derivative images of I's spline (shift.h) / p:
 * the derivatives of the mean image, anchored on the set-up reference's. Why anchored: the LGS spots are undersampled
 * (~1.2″ on 1.1″ pixels), and no interpolation of pixel values gives the pixel-integrated spot's derivative — S alone
 * is 35–50 % off the spot model's on the demo's set-up reference and the loop's matched filter then reads 0.79 / 0.83
 * of the true slopes (0.86 / 0.88 anchored; docs/results.md); anchored, S errs only on the change of the mean image
 * from the set-up's, the same image gives the set-up's derivatives bit for bit, and the spot model's correction for
 * the pixels is the one a real system's model of its spot would supply. (Each frame is re-centred on its own noisy
 * slope, so aligned on its own noise too: a sharper mean, to second order in the noise. Its first-order term,
 * (1/p) Σ_axes S_a(R_a ⊙ V), was tried and taken out again: at the demo's flux the bias is below the reference's own
 * noise after 256 frames — tests/test_pixels.c — and the term made that error larger.)
 * Then they are handed to wt_sensing_set_reference (centroider, covariance,
 * NEA, truncation: the same path as the oracle's); the accumulator restarts. Refused (WT_ERR_INVALID, the old
 * reference kept) with fewer than WT_SENSING_PIXELS_MIN_FRAMES frames. The mean of n noisy frames leaves in I0 a
 * noise whose matched-filter slope is ~NEA/√n per subaperture, held until the next rebuild (a static error the
 * loop does not average): one frame would put a whole frame's noise there; two is the least that halves it. */
#define WT_SENSING_PIXELS_MIN_FRAMES 2
/* k of the shrinkage above, in standard deviations of the n-frame mean: a pure-noise change passes |Δ| > kσ 0.3 % of
 * the time at k = 3 (32 % at k = 1, where it kept ~0.55 of the noise). Chosen by measurement (docs/results.md §70): of
 * k = 1, 2, 3 on the demo's fixed profile, drift and sporadic layer (2 seeds each) 3 is the best mean on each, and on
 * the E-ELT the in-loop gain along the elongation goes 0.75 (k = 1) → 1.03 (k = 2) on the drift. */
#define WT_SENSING_PIXELS_SHRINK 3.0
int wt_sensing_pixels_start(wt_sensing *ws);
int wt_sensing_pixels_reference(wt_sensing *ws);
/* Stops the accumulation and frees it (restore does it too). */
void wt_sensing_pixels_stop(wt_sensing *ws);
/* Adds images (nsub Ns², e.g. ws->img) re-centred by slopes [rad] ([s_x…, s_y…]) to the accumulator, one frame
 * (wt_sensing_detect's step; for the tests). Outside parallel regions only. */
void wt_sensing_pixels_add(wt_sensing *ws, const float *images, const double *slopes);

/* ---- the matched filter's gain from the loop's own pixels (lgs.wfs.gain_update_s; sensing_gain.c) ----
 * A matched filter reads a spot that is not its reference with a gain ≠ 1 (docs/design.md "The matched filter's gain
 * from the loop's pixels"). For spots I(t_f) at Gaussian tilts t_f (noise independent of t) the regression of the
 * filter's output on t is, by Stein's lemma, R ∂M/∂θ with M the frames' mean image as detected. M is fitted by the
 * spot model (the tables' profile, the reference's seeing scaled in strength, a Gaussian jitter: one set per sensor,
 * sensing_gain.c), and each subaperture's 2×2 gain G_k is the filter in force's response to the fitted model's
 * derivatives; the slopes are then G_k⁻¹ s and the covariance G_k⁻¹ C G_k⁻ᵀ (the reconstructor's C_E follows after
 * wt_reconstructor_refresh_noise).
 * start: the accumulation of every wt_sensing_detect's (and detect_reference's) images from now on (an LGS with the
 * matched filter: WT_ERR_INVALID otherwise); update: the estimate of the frames since the last (≥
 * WT_SENSING_PIXELS_MIN_FRAMES; on refusal the old correction is kept), applied from the next frame on, the
 * accumulator restarted; *along, *across (NULL: not wanted) the gain along and across the elongation, mean of the
 * subapertures, before the correction. A new reference (wt_sensing_set_reference: the oracle's) keeps the correction,
 * applied to its covariance, until the next estimate (the profile changes slowly, and the seeing's mismatch the
 * correction holds is the same). stop frees the accumulation; restore undoes the correction. */
int wt_sensing_gain_start(wt_sensing *ws);
int wt_sensing_gain_update(wt_sensing *ws, double *along, double *across);
void wt_sensing_gain_stop(wt_sensing *ws);
/* (sensing.c) H_k s_k for every subaperture, when a correction is in force; the elongation's unit vector of
 * subaperture k (from the launch position for an LGS, else x) */
void wt_sensing__gain_correct(const wt_sensing *ws, double *slopes);
/* (sensing_reference.c) c = H c0 Hᵀ per subaperture, hk [4 nsub] row-major, c0 and c [3 nsub] ([xx | xy | yy]) */
void wt_sensing__gain_cov(int nsub, const double *hk, const double *c0, double *c);
void wt_sensing__direction(const wt_sensing *ws, int k, double *ex, double *ey);

/* Back to the set-up's profile and reference (each only when changed; bit for bit): a loop leaves the system as it
 * found it for the next (compare and budget run several loops on one system). */
int wt_sensing_restore(wt_sensing *ws);

/* Bytes the sensor holds: spot tables and workspaces, centroider, reference images, per-frame buffers. */
size_t wt_sensing_memory(const wt_sensing *ws);

/* The calibrated gain per subaperture resolved along the elongation (for the pictures of `wavetomo info --spots`):
 * g the 2x2 gain g = ∂s/∂θ of wt_centroid_gain (before any correction), e_k the unit vector from the launch
 * position (lx, ly) [m] to the subaperture's centre (the direction its LGS spot is elongated in):
 *   g_par[k] = e_kᵀ g e_k, g_perp[k] = e_⊥ᵀ g e_⊥ [rad/rad];
 * for an NGS (or a centre on the launch) the smaller and the larger eigenvalue of (g + gᵀ)/2 instead.
 * cog = 0: the configured centroider's gain (the identity for the matched filter); cog = 1: the gain a
 * centre of gravity over the whole detector would have on the same reference I0 (built here from the spot
 * model's derivative images: allocates nsub·Ns² floats twice and a temporary centroider, ~two image
 * computations). Either output may be NULL. */
int wt_sensing_gain_along(const wt_sensing *ws, int cog, double lx, double ly, double *g_par, double *g_perp);
/* The spot of the current tables (after wt_sensing_set_sodium: the truth's profile now) as the configured
 * centroider, built on its own reference, reads it: img (nsub·Ns², NULL: not wanted) the noise-free mean image
 * with the reference's seeing; offset_par[k] = e_kᵀ s(img) the slope it measures on that image along the
 * elongation (its false signal: 0 on its own reference) [rad]; g_par, g_perp its gain on that image's tilt,
 * g = (s(img + ε ∂img/∂θ) − s(img))/ε (ε = 1 % of a pixel), resolved as wt_sensing_gain_along, after its gain
 * correction when it applies one (so 1 on its own reference); trunc[k] the flux outside the field. Any output
 * NULL: not wanted. Allocates ~5 nsub·Ns² floats. */
int wt_sensing_response_now(const wt_sensing *ws, double lx, double ly, float *img, double *offset_par, double *g_par,
                            double *g_perp, double *trunc);

#endif
