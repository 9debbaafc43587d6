/* core/model/wind_align.h: the wind of each reconstructed layer from the shift that best aligns its estimates at t
 * and t + τ (SPEC §12 "Wind", the cheap alternative to the lagged LGS maps of learn_wind.c).
 *
 * Under frozen flow a layer is φ_t(x) = φ_0(x − v t). On its periodic n × n grid of spacing δ (the reconstruction's
 * layers), with X_t(k) its 2-D DFT, X_{t+τ}(k) = X_t(k) e^{−2πi k·s/n}, s = v τ / δ [grid points]. Every `stride`-th
 * frame (a snapshot) each layer, times a fixed taper T (1 inside half the footprint's radius R, a raised cosine to 0 at
 * R; none: the whole periodic grid), is transformed and, for each lag τ_q = lag_q · stride frames, the cross-spectrum
 * and the auto-spectrum are accumulated (in B consecutive batches of snapshots):
 *     S_q(k) = Σ_t X_{t+τ_q}(k) conj(X_t(k)),      P(k) = Σ_t |X_t(k)|².
 * The inverse transform of S_q is the lag-τ_q cross-correlation c_q(δ); for a stationary layer seen through T its
 * expectation is A(δ) C(δ − s_q), A = T ⋆ T the taper's overlap and C the layer's covariance, whose maximum is at
 * zero. So the estimate maximises the overlap-normalised correlation, continuous in s (the trigonometric
 * interpolation of both sums: no parabola through sampled points, no bias for a pure shift):
 *     R_q(s) = c_q(s) / A(s),   c_q(s) = Σ_k Re[S_q(k) e^{+2πi k·s/n}],   A(s) = Σ_k |T̂(k)|² e^{+2πi k·s/n}
 * (k = 0 and the Nyquist row and column left out of c: a real field cannot give their direction). Without the
 * division the overlap, which falls with the shift, pulls the peak towards zero (a third of the speed on a
 * 16-point footprint); with it, and the taper's soft edge, what is left is within the scatter: −6 % to 0 % of the
 * speed on a 16-point footprint, −2 % to 0 % on 32, 0 to +1 % on 64 (tests/bias_wind_align.c, docs/results.md). A whitened (phase-correlation or
 * coherence-weighted) sum sharpens the peak, but it weights the small scales, where a reconstruction's estimate
 * holds a part that does not move with the wind (measured on the demo: speeds 25–50 % low), so the plain sum,
 * dominated by the large scales the tomography resolves best, is used. The lags are one velocity u [points per
 * snapshot], s_q = u lag_q: u starts from the integer peak of the shortest lag's R (two inverse FFTs, within a quarter
 * of the grid and where A is at least half its peak), is refined by Newton's method on log R_0, then each longer lag
 * joins, G(u) = Σ_q log R_q(u lag_q), while its peak stays clear: the correlation coefficient at the fitted shift
 *     ρ_q = (R_q(s_q)/N_q) / (R_P(0)/N),   R_P(0) = Σ_k P(k) / A(0)   (N_q pairs, N snapshots)
 * at least WT_WIND_ALIGN_RHO_MIN (the longest lags carry the most phase per unit of wind until the layer has moved
 * out of the overlap or the estimates have decorrelated). A layer whose shortest lag's peak is not clear has no
 * estimate (valid 0). v = u δ / (stride Δt), Δt the real time of a frame. The uncertainty: the batches' estimates
 * (each from its own sums, the same lags, from the whole estimate) spread / √B.
 *
 * What it measures: the power-weighted motion of whatever the layer's estimate holds. A layer that absorbs several
 * truth layers (PCG-3's at the DM altitudes, or CG-9's below the altitude resolution) moves with a mixture, close to
 * the Cn²-weighted mean wind of SPEC §12's compression when their spectra are alike.
 *
 * Set-up allocates (FFTW plans, the ring of the last lag_max snapshots' spectra, B · nlag cross-spectra per layer);
 * _add and _reset allocate nothing; _estimate allocates nothing (inverse FFTs on the set-up's work arrays).
 */
#ifndef WT_WIND_ALIGN_H
#define WT_WIND_ALIGN_H

#include <stdint.h>

#include "../base/base.h"
#include "../la/fft.h"
#include "../op/grid.h"

#define WT_WIND_ALIGN_MAX_LAGS 8
#define WT_WIND_ALIGN_MAX_BATCH 16
/* a lag's correlation coefficient at its fitted shift below this: its peak is not clear (for noise alone ρ is
 * ~ 1/√(pairs · frequencies); a turbulent layer's estimate, dominated by its large scales, is above 0.9) */
#define WT_WIND_ALIGN_RHO_MIN 0.3
/* the taper is flat out to this fraction of its radius, then a raised cosine */
#define WT_WIND_ALIGN_TAPER_FLAT 0.5

typedef struct wt_wind_align_params {
    int stride;            /* frames between two snapshots (every stride-th frame is transformed) [frames], ≥ 1 */
    int nlag;              /* lags, 1 … WT_WIND_ALIGN_MAX_LAGS */
    int lag[WT_WIND_ALIGN_MAX_LAGS]; /* each in snapshots, increasing, ≥ 1 (lag τ_q = lag[q] · stride frames) */
    int nbatch;            /* batches for the uncertainty, 2 … WT_WIND_ALIGN_MAX_BATCH */
    long batch_snapshots;  /* snapshots per batch: snapshot j goes to batch min(j / batch_snapshots, nbatch − 1) */
    double frame_dt;       /* real time of one frame [s] (1 / the loop's rate; not the night's time) */
} wt_wind_align_params;

typedef struct wt_wind_align wt_wind_align;

/* L layers, layer l on the periodic square grid g[l] (nx = ny even, ≥ 4; spacing δ_l [m]), stored from offset[l] in
 * the layers' vector. radius: NULL, or each layer's footprint radius R [m] about x = y = 0 (≤ 0: no taper). fft: NULL (FFTW_ESTIMATE) or the wisdom the tomography plans from (core/la/fft.h). Errors:
 * WT_ERR_INVALID naming the parameter (stride or a lag < 1, lags not increasing, fewer than 2 batches, a grid that
 * is not square and even). */
int wt_wind_align_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, const double *radius,
                        wt_fft_wisdom *fft, const wt_wind_align_params *par, wt_wind_align **out);
void wt_wind_align_free(wt_wind_align *w);

/* Frame t's layers phi (the pseudo-open-loop estimate, before any prediction shift): taken when t is a multiple of
 * stride, else ignored. Frames must come in increasing order; a gap in the snapshots (a frame t skipped) is
 * WT_ERR_INVALID. Allocates nothing. */
int wt_wind_align_add(wt_wind_align *w, long t, const double *phi);
/* Forget every snapshot (a loop that estimates from its last T seconds). */
void wt_wind_align_reset(wt_wind_align *w);
/* Snapshots accumulated since the last reset. */
long wt_wind_align_snapshots(const wt_wind_align *w);

typedef struct wt_wind_estimate {
    int valid;             /* 1: estimated; 0: the shortest lag's peak is not clear (noise, or a layer that left
                              the footprint within one lag), vx, vy, sigma 0 */
    double vx, vy;         /* wind [m/s] (direction of motion) */
    double sigma_x, sigma_y; /* uncertainty [m/s]: the batches' spread / √B (0 with fewer than 2 batches filled) */
    double rho;            /* the shortest lag's correlation coefficient at its fitted shift */
    int nlag_used;         /* the lags whose peak was clear (the first nlag_used of the parameters') */
} wt_wind_estimate;

/* The wind of every layer into est[0 … L−1]. WT_ERR_INVALID (with how many there are and how many it needs) when
 * fewer than lag[0] + 1 snapshots have been accumulated since the reset, so that no pair exists. Allocates nothing. */
int wt_wind_align_estimate(wt_wind_align *w, wt_wind_estimate *est);

/* Summed wall time of _add [s]. */
double wt_wind_align_seconds(const wt_wind_align *w);

#endif
