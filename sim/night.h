/* sim/night.h: a changing night for the simulation truth (SPEC §12 "A changing night"): the truth's r0,
 * Cn² fractions and winds as functions of the night's time, and the per-frame drive of the atmosphere's
 * screens by them.
 *
 * A night is a sequence of states (knots) s_k = (t_k, r0_k, f_ℓk, v_ℓk, d_ℓk) for the truth's layers ℓ,
 * t_k strictly increasing, evaluated at a night time t in [t_0, t_last] by linear interpolation between the
 * two knots around it (w = (t − t_k)/(t_{k+1} − t_k)):
 *   r0(t) = r0_k + w (r0_{k+1} − r0_k)                      (Fried parameter at 500 nm [m])
 *   f_ℓ(t) ∝ f_ℓk + w (f_ℓ,k+1 − f_ℓk), renormalised to Σ_ℓ f_ℓ = 1
 *   v_ℓ(t) = v_ℓk + w (v_ℓ,k+1 − v_ℓk)                       (wind speed [m/s])
 *   d_ℓ(t) = d_ℓk + w Δ, Δ the difference d_ℓ,k+1 − d_ℓk taken along the shorter arc, in (−π, π]
 *                                                            (wind direction [rad], not wrapped)
 * At a knot the state is the knot's (exactly; its fractions normalised). The knots come from
 *  - a night file (WT_NIGHT_FILE; format below), or
 *  - the stochastic model (WT_NIGHT_RANDOM): knots every `step` seconds from t = 0, where each layer's
 *    fraction, r0, each layer's wind speed and its direction follow independent Ornstein–Uhlenbeck
 *    processes z (stationary variance 1, correlation time τ: E[z(t) z(t + s)] → e^{−|s|/τ}), started at
 *    z(0) = 0 and sampled exactly at the knots: z_{k+1} = a z_k + √(1 − a²) ξ_k, a = e^{−step/τ},
 *    ξ_k ~ N(0, 1). The state at a knot is
 *      r0 = r0_ref e^{σ_r0 z},  f_ℓ ∝ f_ℓ,ref e^{σ_f z_ℓ} (renormalised),  v_ℓ = v_ℓ,ref e^{σ_v z'_ℓ},
 *      d_ℓ = d_ℓ,ref + σ_d z''_ℓ,
 *    the reference (configured) state is its median, and at t = 0 the night is the reference state.
 *    Randomness: each process draws from its own wt_rng stream of `seed`: r0 stream 0, layer ℓ's fraction
 *    stream 1 + ℓ, its wind speed 1 + WT_NIGHT_MAX_LAYERS + ℓ, its direction 1 + 2 WT_NIGHT_MAX_LAYERS + ℓ:
 *    a layer's walk depends on (seed, step, τ, ℓ) only, and the same seed gives the same numbers.
 *
 * Night file: plain text, one state a line: night time [s], r0 [m], then for each of the truth's layers
 * (in the order of its altitudes) its Cn² fraction, wind speed [m/s] and wind direction [deg] (the direction
 * the layer moves towards, from +x towards +y): 2 + 3 n columns for n layers. '#' starts a comment, blank
 * lines are skipped, fields are separated by blanks. Refused with FILE:LINE: a field that is not a finite
 * number, a line of another column count (a layer count other than the truth's), a time not above the previous
 * line's, r0 ≤ 0, a negative fraction or fractions that do not sum to 1 within WT_NIGHT_SUM_TOL, a negative
 * wind speed, a direction outside [−360, 360] deg, a positive fraction of a layer whose reference fraction is 0
 * (its screen has no power to scale up), a first time after the run's first night time or a last time before
 * its last one (both times said); naming the file: no state.
 *
 * The truth (SPEC §2 with a night): the screens are generated once with the reference state (the configured
 * r0_ref, f_ℓ,ref; L0 fixed over the night); in frame j (night time t_j = start + j Δt c, Δt the frame time,
 * c the compression: the night's clock runs c times faster than the turbulence's) layer ℓ's screen is scaled by
 *   g_ℓ(t_j) = sqrt( f_ℓ(t_j) r0(t_j)^(−5/3) / (f_ℓ,ref r0_ref^(−5/3)) )    (its spectrum Φ_ℓ ∝ f_ℓ r0^(−5/3))
 * and sampled at θh − v_ℓ,ref t − D_ℓ(j), t = j Δt the frame's time, with the extra displacement
 *   D_ℓ(j) = Σ_{i<j} (v_ℓ(t_i) − v_ℓ,ref) Δt,   v as vectors (speed, direction),
 * so that a layer moves by v_ℓ(t_j) Δt from frame j to j + 1 (the turbulence moves with the real frame time,
 * whatever c). A night that keeps the reference state gives D = 0 and g = 1 exactly: today's bits. The number
 * of layers and their altitudes are the truth's, fixed over the night.
 */
#ifndef WT_NIGHT_H
#define WT_NIGHT_H

#include <stdint.h>

#include "../core/base/base.h"
#include "atmosphere.h"

#define WT_NIGHT_MAX_LAYERS 64 /* the truth's layers at most (the configuration's WT_MAX_LAYERS) */
#define WT_NIGHT_SUM_TOL 1e-3  /* a night file's fractions must sum to 1 within this (as a profile file's) */
#define WT_NIGHT_MAX_VALUES 50000000 /* knots x (2 + 3 layers): 400 MB, far beyond any night (a units mistake) */

enum { WT_NIGHT_NONE = 0, WT_NIGHT_FILE = 1, WT_NIGHT_RANDOM = 2 };

typedef struct wt_night wt_night;

typedef struct wt_night_params {
    int source;                   /* WT_NIGHT_FILE or WT_NIGHT_RANDOM */
    int nlayers;                  /* the truth's layers, 1 .. WT_NIGHT_MAX_LAYERS */
    /* the reference state: the one the truth's screens were generated with (the configured atmosphere) */
    double r0;                    /* [m] */
    const double *fraction;       /* [nlayers] ≥ 0, normalised here */
    const double *wind_speed;     /* [nlayers] [m/s] */
    const double *wind_direction; /* [nlayers] [rad] */
    /* the run */
    double frame_time;            /* Δt [s] > 0 */
    double start;                 /* night time of frame 0 [s] ≥ 0 */
    double compression;           /* c > 0: night seconds per simulated second */
    long frames;                  /* frames the night must cover (≥ 1): up to night time start + (frames − 1) Δt c */
    const char *origin;           /* for messages: where the night was asked for (a configuration key), or NULL */
    /* WT_NIGHT_FILE */
    const char *file;             /* the night file (read once, here) */
    /* WT_NIGHT_RANDOM */
    uint64_t seed;
    double correlation_time;      /* τ [s] > 0 */
    double step;                  /* knot spacing [s] > 0 */
    double r0_rms;                /* σ_r0: rms of ln r0 [1] ≥ 0 */
    double fraction_rms;          /* σ_f: rms of ln f_ℓ [1] ≥ 0 */
    double wind_speed_rms;        /* σ_v: rms of ln v_ℓ [1] ≥ 0 */
    double wind_direction_rms;    /* σ_d: rms of d_ℓ [rad] ≥ 0 */
} wt_night_params;

/* The truth's state at one night time. The arrays belong to whoever fills the struct (wt_night_current:
 * the night). */
typedef struct wt_night_sample {
    double t;                     /* night time [s] */
    double r0;                    /* Fried parameter at 500 nm [m] */
    int nlayers;
    const double *fraction;       /* [nlayers] Cn² fractions, sum 1 */
    const double *wind_speed;     /* [nlayers] [m/s] */
    const double *wind_direction; /* [nlayers] [rad], direction of motion from +x towards +y (not wrapped) */
} wt_night_sample;

/* Validate p, read the night file or draw the stochastic knots, check that they cover the run's night times.
 * Allocates the knots (file: its states; random: ⌊(last night time)/step⌋ + 2 knots) and the drive's state.
 * Errors: WT_ERR_INVALID (a bad parameter, named), WT_ERR_IO (the file cannot be opened or read), WT_ERR_CONFIG
 * (the file's contents, FILE:LINE; a night that does not cover the run), WT_ERR_NOMEM. */
int wt_night_alloc(wt_context *ctx, const wt_night_params *p, wt_night **out);
void wt_night_free(wt_night *night);

int wt_night_nlayers(const wt_night *night);
/* Night time of frame j: start + j Δt c [s]. */
double wt_night_time(const wt_night *night, long frame);
/* The same clock without a night (the sodium layer's sequence reads it too): start + j Δt c [s]. */
double wt_night_clock(double start, double frame_time, double compression, long frame);

/* The state at night time t [s] (the interpolation above): r0 [m] into *r0, and per layer fraction (sum 1),
 * wind speed [m/s] and direction [rad] into the caller's arrays of nlayers values (any may be NULL). Allocates
 * nothing; reads the night only (thread-safe). Errors: WT_ERR_INVALID when t is not finite or outside the
 * knots' span [t_0, t_last] (the message says both). */
int wt_night_state(const wt_night *night, double t, double *r0, double *fraction, double *wind_speed,
                   double *wind_direction);

/* g_ℓ = sqrt(f_ℓ r0^(−5/3) / (f_ℓ,ref r0_ref^(−5/3))) for nlayers layers into scale (0 where f_ℓ,ref = 0):
 * the factor that turns a screen generated for (r0_ref, f_ℓ,ref) into one of (r0, f_ℓ) with the same random
 * pattern (L0 fixed). */
void wt_night_screen_scale(int nlayers, double r0_ref, const double *fraction_ref, double r0, const double *fraction,
                           double *scale);

/* The truth of frame j (frames in increasing order; a skipped frame's wind is integrated all the same): the
 * state at wt_night_time(night, j) becomes wt_night_current, and atm's layers are scaled by g_ℓ and displaced
 * by D_ℓ(j) (wt_atmosphere_set_drift). atm must be the truth made with the night's reference state (its layer
 * count is checked). Allocates nothing. Errors: WT_ERR_INVALID (a frame before the last one driven, another
 * layer count, a night time outside the knots). */
int wt_night_drive(wt_night *night, wt_atmosphere *atm, long frame);

/* The state of the last frame driven (before any: that of frame 0's night time, computed at alloc). The
 * arrays are the night's, valid until its next drive or free. */
wt_night_sample wt_night_current(const wt_night *night);

#endif
