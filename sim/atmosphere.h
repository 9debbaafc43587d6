/* sim/atmosphere.h: the simulated atmosphere (truth turbulence): frozen-flow von Kármán layers
 * and their OPD along a line of sight (SPEC §2 and §3).
 *
 * Each layer ℓ (altitude h_ℓ, Cn² fraction f_ℓ, wind v_ℓ) is a random OPD screen with the spectrum
 *   Φ_ℓ(κ) = (λ0/2π)² · 0.0229 · f_ℓ · r0^(-5/3) · (κ² + L0^(-2))^(-11/6)   [m² per (cycles/m)²],
 * κ in cycles/m, λ0 = 500 nm, r0 the Fried parameter of the whole atmosphere at 500 nm.
 * A screen is the sum of two independent parts:
 *  - the FFT part: a periodic n x n grid of spacing δ (period L = nδ), every frequency k/L except 0
 *    with a complex Gaussian amplitude √Φ(κ)/L (FFTW);
 *  - the subharmonic part (Lane et al. 1992, in the standard form of Schmidt 2010, listing 9.3;
 *    see also Johansson & Gavel 1994): 3 levels p = 1..3 of 3 x 3
 *    frequencies (m, n)/(3^p L), (m, n) ≠ (0, 0), amplitude √Φ(κ)/(3^p L), its mean over the
 *    screen grid removed. It is kept as its 24 Fourier terms and evaluated exactly wherever the
 *    screen is sampled, instead of being added to the grid: the grid part then stays exactly
 *    periodic, so frozen flow wraps around forever without a seam, and the subharmonic part is a
 *    smooth field (period 27 L) that is continuous everywhere.
 * The screen's piston (mean over the grid) is zero.
 *
 * Line of sight (frozen flow, SPEC §3): a source at altitude H (0 = infinity) in direction θ sees
 *   φ(r, t) = Σ_ℓ screen_ℓ( (1 − h_ℓ/H) r + θ h_ℓ − v_ℓ t ),
 * the grid part by bilinear interpolation with periodic wrap.
 *
 * Randomness: layer ℓ draws from wt_rng stream (seed, ℓ): first the n² grid amplitudes, then the
 * subharmonic ones. A layer's random pattern (its screen / √f_ℓ) thus depends on (seed, ℓ) only — not
 * on the other layers, the thread count or whether subharmonics are on — and the same seed gives
 * bit-identical screens.
 *
 * Coordinates: the screen grid of every layer is wt_grid_layer(n, δ): point i at (i − n/2) δ.
 * Wind direction: the direction the layer moves towards, counter-clockwise from +x [rad].
 */
#ifndef WT_ATMOSPHERE_H
#define WT_ATMOSPHERE_H

#include <stddef.h>
#include <stdint.h>

#include "../core/base/base.h"
#include "../core/op/grid.h"

#define WT_ATMOSPHERE_SUBHARMONIC_LEVELS 3

typedef struct wt_atmosphere wt_atmosphere;

typedef struct wt_atmosphere_params {
    int nlayers;
    const double *altitudes;      /* [nlayers] layer altitudes h_ℓ [m], ≥ 0 */
    const double *fractions;      /* [nlayers] Cn² fractions, ≥ 0; normalised here to sum 1 */
    const double *wind_speed;     /* [nlayers] [m/s], ≥ 0 */
    const double *wind_direction; /* [nlayers] direction of motion [rad] from +x towards +y */
    double r0;                    /* Fried parameter of the whole atmosphere at 500 nm [m] */
    double L0;                    /* outer scale [m] (INFINITY: Kolmogorov) */
    int n;                        /* screen points per side: even, ≥ 16, only prime factors 2, 3, 5, 7 */
    double delta;                 /* screen spacing δ [m] */
    uint64_t seed;
    int no_subharmonics;          /* 0 (default): add the 3 subharmonic levels; 1: grid part only */
} wt_atmosphere_params;

/* Validate the parameters and generate every layer's screen (FFTW, planned with FFTW_ESTIMATE).
 * Allocates n² doubles per layer plus, during generation only, 3 n² doubles of work space.
 * FFTW's planner is global and not thread-safe: do not call this concurrently with other FFTW
 * planning. Errors: WT_ERR_INVALID naming the bad value, WT_ERR_NOMEM, WT_ERR_LIBRARY (FFTW plan). */
int wt_atmosphere_alloc(wt_context *ctx, const wt_atmosphere_params *params, wt_atmosphere **out);
void wt_atmosphere_free(wt_atmosphere *atm);

/* Recommended screen size for a footprint of diameter `footprint` [m] (the largest region any line of
 * sight samples on one layer) at spacing δ: the smallest even n with prime factors 2, 3, 5 only and
 * n δ ≥ 2 · footprint (at least 32). Why twice: a periodic screen repeats itself at distance L, so
 * its structure function is exact only for r ≪ L (SPEC §2 validates r ≤ L/8, and is close to it up
 * to ~L/4 with the subharmonics); with L ≥ 2 · footprint no two points of a footprint are closer than
 * L/2 to being periodic images of each other. */
int wt_atmosphere_recommend_size(wt_context *ctx, double footprint, double delta, int *n);

/* out[p] += alpha · φ(r_p, t) for every point p of `target` with mask[p] ≠ 0 (mask NULL: all points);
 * other points are left untouched. t [s]; source_altitude H [m] (0: infinity; otherwise H must exceed
 * every layer's altitude); theta_x, theta_y [rad]; out has target->nx * target->ny entries.
 * Allocates nothing. OpenMP over target rows with the context's thread count when called outside a
 * parallel region; serial inside one (the open-loop budget modes parallelise over lines of sight; the
 * closed loop uses wt_atmosphere_project_many). The result does not depend on the thread count.
 * Errors: WT_ERR_INVALID. */
int wt_atmosphere_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                          double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                          double *out);

/* One line of sight of wt_atmosphere_project_many: its source (as in wt_atmosphere_project), mask
 * (NULL: all points) and output (target->nx * target->ny values, added to; with set = 1 the masked
 * points are overwritten instead: the same bits as zeroing them first, without the pass over the
 * output that zeroing takes). */
typedef struct wt_atmosphere_los {
    double source_altitude, theta_x, theta_y;
    const uint8_t *mask;
    double *out;
    int set;
} wt_atmosphere_los;

/* wt_atmosphere_project for each of nlos lines of sight at the same t, on the same target grid, bit for
 * bit, but in one pass over the layers (row bands, all lines of sight per band: each layer's screen is
 * read from memory once per band instead of once per line of sight). Outputs must not overlap.
 * Allocates nothing; OpenMP over row bands as wt_atmosphere_project over rows. Errors: WT_ERR_INVALID
 * (the first bad line of sight; nothing is written then). */
int wt_atmosphere_project_many(const wt_atmosphere *atm, double t, int nlos, const wt_atmosphere_los *los,
                               const wt_grid *target, double alpha);

/* The same projection computed point by point, the plain form of the arithmetic that
 * wt_atmosphere_project reorganises: both give the same bits (tests/test_atmosphere.c). For tests. */
int wt_atmosphere_project_reference(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                                    double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                                    double *out);

/* A changing truth (sim/night.h): from now on layer ℓ's screen is scaled by scale[ℓ] and sampled at
 * θh − v_ℓ t − (shift_x, shift_y)[ℓ] [m] (the displacement its changing wind adds to frozen flow). NULL arrays:
 * 1 and 0, today's (x − 0 and α·1 are exact: the same bits as without a drift). Allocates nothing; not while a
 * projection runs. */
void wt_atmosphere_set_drift(wt_atmosphere *atm, const double *scale, const double *shift_x, const double *shift_y);

int wt_atmosphere_nlayers(const wt_atmosphere *atm);
/* The screen grid wt_grid_layer(n, δ) shared by all layers. */
wt_grid wt_atmosphere_grid(const wt_atmosphere *atm);
/* Bytes held by the atmosphere (screens and tables). */
size_t wt_atmosphere_bytes(const wt_atmosphere *atm);
/* Layer ℓ (0 ≤ ℓ < nlayers, not checked): altitude [m], normalised Cn² fraction, wind vector [m/s]. */
double wt_atmosphere_layer_altitude(const wt_atmosphere *atm, int layer);
double wt_atmosphere_layer_fraction(const wt_atmosphere *atm, int layer);
void wt_atmosphere_layer_wind(const wt_atmosphere *atm, int layer, double *vx, double *vy);
/* The periodic grid part of layer ℓ's screen at t = 0: n*n values [m], index i + n*j (owned by atm).
 * It excludes the subharmonics; its mean is zero. */
const double *wt_atmosphere_layer_data(const wt_atmosphere *atm, int layer);
/* The whole screen of layer ℓ at t = 0 on its grid (grid part + subharmonics; not periodic):
 * out[n*n] [m]; its mean is zero. Allocates nothing. */
void wt_atmosphere_layer_render(const wt_atmosphere *atm, int layer, double *out);

#endif
