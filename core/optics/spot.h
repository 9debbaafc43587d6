/* core/optics/spot.h: diffractive Shack–Hartmann spot images, detector and noise (SPEC §4b).
 *
 * Per subaperture s and frame (SPEC §4b "Per subaperture", "LGS source", "Detector"):
 *   U = A·exp(2πi·OPD/λ) on the n_p × n_p pupil samples (dx = d/n_p), zero-padded to N × N;
 *   PSF(θ) = |FFT_forward(U)|² at θ = (k − N/2)·θ_f, θ_f = λ/(N dx) (Nyquist: θ_f ≤ λ/(2d) ⟺ N ≥ 2 n_p);
 *   image(P) = ∫_{pixel P} (PSF ⊛ S)(θ) dθ at the Ns × Ns pixel centres ((P − (Ns−1)/2)·p per axis),
 *   S the source kernel: δ for a point source; for an LGS the sodium line — each altitude h of the
 *   profile at β(h) = (r − l)(1/h − 1/H) — convolved with the uplink Gaussian (FWHM given). β is the
 *   gradient at r of the path length from the point (l, h) of the beam, |x − l|²/(2h), less that from
 *   its focus (l, H): the spot of a point at h is where an OPD of that path-length difference moves it
 *   (the sign below; tested against that OPD). On the sky the point is seen at the mirrored angle
 *   (r − l)(1/H − 1/h) (SPEC §4b): the detector frame of wavetomo, in which an OPD tilt θ·x moves the
 *   spot to +θ, is the image plane's, inverted; exact parallax, not its linearisation (r − l)(h − H)/H²;
 *   normalised so that the whole subaperture receives photons × lit fraction (before the detector's
 *   field truncates it); noisy frame = Poisson(I + B) + N(0, σe²) − B.
 * Sign: a tilt OPD = θ·x moves the spot to +x (forward FFT, exp(−2πi k·x/N)); tested.
 *
 * How (the design, and what it costs in accuracy):
 *  1. A small Nyquist FFT per subaperture (n_p = 16, N = 32 at d = 0.5 m, 589 nm: θ_f = 0.12″, field
 *     λ/dx = 3.9″), as two batches of 1-D transforms (the n_p non-zero rows, then the N columns).
 *  2. The PSF samples, each taken as a box of side θ_f, spread onto a lattice of cells of side c = p/k
 *     (k odd, cells_per_pixel) aligned with the pixel centres, by the overlap of the box with the
 *     linear-interpolation tent of each lattice point: mass and first moment are kept exactly, so the
 *     spot moves linearly and smoothly with the tilt. (Plain overlap binning would not: a spot narrower
 *     than a cell moves in steps of c.)
 *  3. The image as the direct linear sum image(P) = Σ_cells cell_q · K_s(kP − q), with K_s(o) = the mass
 *     of the source kernel inside a pixel whose centre is o cells from the point: exact (the pixel edges
 *     fall on cell edges because k is odd), precomputed per subaperture at alloc (stored in k² phase
 *     tables so that the inner loop runs over contiguous pixels). Linear, so no wrap-around, and the
 *     detector's truncation is exact.
 *  Accuracy: the box adds a blur of variance θ_f²/12 per axis and the tent c²/6 on average over the
 *  sub-cell positions: v = θ_f²/12 + c²/6. It is taken back from the source's Gaussian (the table uses
 *  σ² = σ_uplink² − v), so the images have the exact second moments whenever the uplink spot is wider
 *  than √v; wt_spot_blur gives what is left otherwise. At the E-ELT numbers (θ_f = 0.12″, p = 1.1″,
 *  k = 3: c = 0.37″) √v = 0.15″ against an uplink σ of 0.42″ (1″ FWHM): nothing is left, and the
 *  residual is a shape difference (tent vs Gaussian), measured in tests/test_spot.c against a
 *  brute-force fine computation. The reference I0 and its derivatives are made by the same model.
 *  The FFT field λ/dx = n_p λ/d is periodic: a spot whose tilt plus half-width exceeds λ/(2 dx) wraps
 *  around, and the diffraction tails beyond ±λ/(2 dx) fold back — ~4/(π² n_p) of the flux for a square
 *  subaperture (2.5 % at n_p = 16), which lowers the CoG's tilt gain by about as much (the centroider's
 *  calibrated gain absorbs it; a larger n_p widens the field).
 *
 * Data layouts and units:
 *  - subaperture s has its centre (xc[s], yc[s]) [m] in the pupil (origin at the pupil centre);
 *  - pupil sample (i, j), 0 ≤ i, j < n_p, of subaperture s is at x = xc + (i + ½ − n_p/2)·d/n_p,
 *    y = yc + (j + ½ − n_p/2)·d/n_p and stored at [s·n_p² + i + n_p·j] in the amplitude and OPD arrays;
 *  - amplitude A ∈ [0, 1] (the caller's pupil: for an annulus, 1 inside and 0 outside, or the lit fraction
 *    of each sample's square); OPD in metres;
 *  - image of subaperture s: pixel (ix, iy) at [s·Ns² + ix + Ns·iy], float32 photo-electrons, pixel ix at
 *    angle (ix − (Ns−1)/2)·p [rad] (likewise y).
 *
 * Randomness (stream rule): the noise of subaperture s is drawn from wt_rng_init(seed, WT_SPOT_STREAM(base,
 * s)) with `base` the caller's stream for the sensor and frame (the loop's 2³² + 64t + m). The map
 * (base, s) ↦ 2⁶³ + base·2²⁰ + s is one-to-one for base < 2⁴³ and s < 2²⁰ (both checked), and its values
 * are ≥ 2⁶³, above every stream the rest of wavetomo uses: no two (frame, sensor, subaperture) share a
 * stream, and the pixels do not depend on the thread count.
 *
 * Threads: alloc plans (FFTW_ESTIMATE: deterministic plans, no timing) and allocates one workspace per
 * thread of the context; the per-frame calls run an OpenMP loop over subapertures, allocate nothing and
 * may be called concurrently on different images only from outside a parallel region (they share the
 * workspaces).
 */
#ifndef WT_SPOT_H
#define WT_SPOT_H

#include <stddef.h>
#include <stdint.h>

#include "core/base/base.h"
#include "core/base/rng.h"
#include "core/optics/sodium.h"

#define WT_SPOT_STREAM(base, s) ((UINT64_C(1) << 63) | ((uint64_t)(base) << 20) | (uint64_t)(s))

typedef struct wt_spot_params {
    double wavelength;   /* λ [m] */
    double subap_side;   /* d [m] */
    int pupil_samples;   /* n_p: pupil samples across d (≥ 2) */
    int fft_size;        /* N: even, ≥ 2 n_p (Nyquist) */
    int npix;            /* Ns: detector pixels per side */
    double pixel;        /* p: pixel side [rad] */
    int cells_per_pixel; /* k: odd ≥ 1 (0: the default 3); the rebinning lattice c = p/k */
    double photons;      /* photo-electrons per fully lit subaperture per frame */
    double background;   /* B: background per pixel per frame [photo-electrons] */
    double read_noise;   /* σe: read noise per pixel [electrons rms] */
    double uplink_fwhm;  /* FWHM of the Gaussian source (the LGS uplink spot, or an extended NGS) [rad]; 0: none */
    /* LGS (sodium != NULL): the line source of the sodium profile */
    const wt_sodium *sodium; /* borrowed during alloc only */
    double lgs_altitude;     /* H: the altitude the sensor is focused at [m]; must lie within the profile */
    double launch_x, launch_y; /* l: launch telescope position in the pupil [m] */
} wt_spot_params;

typedef struct wt_spot wt_spot;

/* Validate, plan the FFTs, precompute the per-subaperture source/pixel tables. nsub subapertures with
 * centres xc, yc [m]; amp [nsub·n_p²] the amplitudes (NULL: all 1, copied); lit [nsub] the lit fraction of
 * each (NULL: mean of A² over the samples). Refuses (WT_ERR_INVALID, naming *.wfs.* keys) a sampling
 * coarser than Nyquist, bad sizes, an LGS altitude outside the profile. Allocates; *out owns everything. */
int wt_spot_alloc(wt_context *ctx, const wt_spot_params *par, int nsub, const double *xc, const double *yc,
                  const float *amp, const double *lit, wt_spot **out);
void wt_spot_free(wt_spot *s);

/* A new sodium profile for an LGS spot (one built with a profile): its source ⊛ pixel tables rebuilt, the same
 * numbers as wt_spot_alloc with that profile (the subapertures in parallel, each alone: any thread count gives the
 * same tables). Everything else (FFTs, rebinning, amplitudes, fluxes) stays. The images and references made after
 * it are of the new profile. Refused (WT_ERR_INVALID): an NGS spot, a profile that does not contain the LGS
 * altitude. Allocates its scratch (threads × ~(3 k Lp)² doubles). Outside parallel regions only. */
int wt_spot_set_sodium(wt_spot *s, const wt_sodium *na);
/* The same with the sensor's focus stage and centring (sim/focus_stage.h): every point of the source of the
 * subaperture at r moved by 2 c r + (tx, ty) [rad] (c [1/m], r from the pupil centre) — a WFS re-conjugated and
 * steered so, exactly (it moves the source as seen by the sensor, not the wavefront, so no FFT field limits it).
 * stage NULL or all zero: wt_spot_set_sodium's tables, bit for bit. */
int wt_spot_set_sodium_staged(wt_spot *s, const wt_sodium *na, const double stage[3]);

/* Noise-free images of every subaperture for the OPD [nsub·n_p²] (m, float or double), into
 * img [nsub·Ns²]. Allocates nothing. */
int wt_spot_image(const wt_spot *s, const float *opd, float *img);
int wt_spot_image_d(const wt_spot *s, const double *opd, float *img);

/* In place: img ← Poisson(img + B) + N(0, σe²) − B per pixel, subaperture s from the stream
 * WT_SPOT_STREAM(base_stream, s) of seed. img must be noise-free (≥ 0). Allocates nothing. */
int wt_spot_noise(const wt_spot *s, uint64_t seed, uint64_t base_stream, float *img);

/* The seeing the reference carries: the mean short-exposure, tilt-removed OTF of each subaperture
 * (core/optics/seeing.h) for the atmosphere r0 (at 500 nm) [m], L0 [m]. */
typedef struct wt_spot_seeing {
    double r0; /* Fried parameter at 500 nm [m] */
    double L0; /* outer scale [m] */
    double grid; /* the spacing of a simulation grid that renders the phase [m] (seeing.h); 0: none (the sky) */
    double blur[3]; /* a Gaussian the spot is convolved with besides, its covariance {Σxx, Σxy, Σyy} [rad²] (a jitter:
                       the OTF times exp(−2π² νᵀΣν), ν = u/λ the lag in cycles per radian); zeros: none */
    double scale;   /* the structure function times this, the seeing's strength (r0 → r0 scale^(−3/5)); 0: 1 */
    const unsigned char *only; /* [nsub] 0: that subaperture's images are left as they are (not made); NULL: all */
} wt_spot_seeing;

/* The noise-free reference I0 and its derivatives dI0/dθx, dI0/dθy [e-/rad] by central differences of a
 * tilt ±dtheta [rad] (≤ 0: λ/(20 d)) applied to the OPD; each [nsub·Ns²]; any may be NULL. see = NULL: a
 * flat wavefront (the diffraction-limited spot); otherwise the mean spot under that seeing (each image's
 * autocorrelation multiplied by the subaperture's W(u): exact for the mean of |FFT|², seeing.h). Allocates
 * its seeing tables (~n_p² + threads·(N² + 10 n_p²) numbers) and frees them. */
int wt_spot_reference(wt_spot *s, double dtheta, const wt_spot_seeing *see, float *i0, float *didx,
                      float *didy);
/* From now on wt_spot_reference keeps the rebinned cells of its five images per subaperture (5 M² floats each: they
 * do not depend on the sodium profile) and, called again with the same dtheta and seeing, makes the images from
 * them with the current tables (wt_spot_set_sodium) instead of FFTs: the same bits, ~the cost of five direct sums
 * per subaperture. (The first call after this one computes everything, as always.) */
int wt_spot_keep_reference(wt_spot *s);

/* trunc[s] = 1 − Σ_pixels img_s / (photons × lit_s): the fraction of the subaperture's flux outside the
 * detector field, for a noise-free image (0 for a dark subaperture). */
void wt_spot_truncation(const wt_spot *s, const float *img, double *trunc);

/* The variance per axis [rad²] by which the images are wider than exact ones: the rebinning blur
 * θ_f²/12 + c²/6 less the uplink Gaussian's variance it was taken from (0 when the uplink is wider). */
double wt_spot_blur(const wt_spot *s);

/* The whole subaperture's flux photons × lit fraction [e-]. */
double wt_spot_flux(const wt_spot *s, int isub);
int wt_spot_nsub(const wt_spot *s);
int wt_spot_npix(const wt_spot *s);
/* Bytes the object holds (tables, workspaces). */
size_t wt_spot_memory(const wt_spot *s);
/* Rough flops per subaperture per noise-free image, and bytes of table read (for the bench). */
void wt_spot_cost(const wt_spot *s, double *flops, double *bytes);

/* An exact Poisson deviate of mean mu ≥ 0: inversion (sequential search) for mu < 10, PTRS transformed
 * rejection (Hörmann 1993, Insurance Math. Econom. 12, 39) above. */
double wt_poisson(wt_rng *rng, double mu);

#endif
