/* sim/loop.h: the closed-loop end-to-end MCAO simulation, frame by frame (SPEC §2–§8, paper
 * Algorithm POLC).
 *
 * Frame t (time t/rate): every sensor sees the atmosphere at t minus the DM shape a_t applied during
 * the frame (SPEC §3, §5; cone geometry for the LGS), measured by the truth Shack–Hartmann model on the
 * fine grid (average gradient over the illuminated part, SPEC §4), plus noise (photon + read, elongated
 * 2x2 covariance with τ = 1) and a random tip-tilt per LGS. The evaluation directions give the residual
 * OPD and its Strehl (SPEC §8). Pseudo-open-loop control with a delay of d frames (d = 2 in the paper):
 *   s_ol = s_t + Â a_t,   a_{t+d} = a_{t+d−1} + g (R s_ol − a_t),
 * or, with a gain per spatial scale, G = Σ_j g_j Π_j in place of g (core/op/scale_gain.h).
 *
 * Budget modes (wt_loop_options.open_loop …): the instantaneous open loop evaluates a_t = R s_t (or the
 * best fit to the true turbulence) in the frame it was measured, with the DMs flat in the sensors or (the
 * pseudo-open-loop form) the previous reconstruction in them; the closed-loop path does not change.
 *
 * Randomness: the atmosphere draws from wt_rng streams (seed, layer); the noise of sensor m in frame t
 * from stream (seed, 2^32 + 64 t + m). The same seed gives bit-identical results for any thread count.
 */
#ifndef WT_LOOP_H
#define WT_LOOP_H

#include "../core/model/fitting.h"
#include "../core/model/reconstructor.h"
#include "../core/model/system.h"
#include "adapt.h"
#include "atmosphere.h"
#include "night.h"
#include "../core/op/scale_gain.h"
#include "sodium_drive.h"
#include "strehl.h"

typedef struct wt_loop wt_loop;

enum { WT_LOOP_CLOSED = 0, WT_LOOP_OPEN_FLAT = 1, WT_LOOP_OPEN_POLC = 2 };

typedef struct wt_loop_options {
    int recon;          /* WT_RECON_NONE / PCG3 / CG9 / MVM */
    const struct wt_mvm *mvm; /* WT_RECON_MVM: the control matrix (not owned; must outlive the loop) */
    int iterations;     /* (P)CG iterations override, < 0: the config's */
    uint64_t seed;      /* random seed (the driver passes the config's unless overridden) */
    int noise;          /* 0: noise-free sensors (no photon/read noise, no LGS tip-tilt) */
    /* Error-budget modes (compare/budget.h); all zero: the closed loop above. */
    int open_loop;      /* WT_LOOP_OPEN_FLAT (1): instantaneous open loop: the sensors see the turbulence
                         * alone (DMs flat), and the commands reconstructed from them are applied to the
                         * same frame's evaluation (no delay, no integrator, no POLC).
                         * WT_LOOP_OPEN_POLC (2): instantaneous pseudo-open loop: the sensors see the
                         * turbulence minus the previous frame's reconstruction (a closed loop's small
                         * residual, inside a diffractive sensor's linear range), â_t = R (s_t + Â a_{t−1})
                         * is applied to the same frame's evaluation and becomes a_t (gain 1, no delay).
                         * With linear sensors whose Â is the truth's it is the flat open loop; with spots
                         * and centroiders it is the open loop they can actually measure. Runs from frame 0
                         * (first_frame 0): its state is the previous reconstruction. */
    int perfect_fit;    /* > 0 (open loop only): no sensors, no reconstructor: the DMs are fitted to the
                         * true turbulence along the evaluation directions by the cg9 fitting (its sampling,
                         * ε and the guard ring) with this many CG iterations, warm-started */
    int no_turbulence;  /* 1: no atmosphere (the reconstruction of pure noise) */
    long first_frame;   /* open loop: the first frame run (frames before the settle period carry nothing
                         * to later open-loop frames but the warm start) */
    int true_polc;      /* 1 (closed loop, geometric sensors): POLC adds the truth sensors' measurement of the
                         * applied DM shapes, s_ol = s − S(−H a), in place of the model's Â a: the pseudo-open-
                         * loop slopes are then exactly those of the turbulence, so the closed loop differs
                         * from the open loop by the delay and the integrator only (budget: servo vs POLC) */
    int no_predict;     /* 1: the reconstructor without recon.predict's shift (the budget's instantaneous runs, which
                         * have no delay to predict over, and its closed loop without prediction) */
    wt_adapt_rebuild_fn rebuild; /* a learning MVM loop (recon.atmosphere.source = "learned"): builds the matrix of
                                  * an estimate (the driver's: builder/ is above this module); else NULL */
    void *rebuild_user;
} wt_loop_options;

/* Cumulative wall time per part [s]. */
typedef struct wt_loop_times {
    double atmosphere, sensors, reconstruction, fitting, control, evaluation;
    double learning;    /* a learned model: the accumulation, the estimates and the model updates (not the MVM's
                           builds, which are simulated as latency) */
} wt_loop_times;

/* What the loop uses of the system description, filled from a configuration by wt_loop_params_from_config
 * (sim/loop_config.c): the loop reads no configuration. */
typedef struct wt_loop_params {
    double rate;                     /* frame rate [Hz] */
    int delay;                       /* frames between measurement and application */
    double gain;                     /* integrator gain g [1] */
    wt_scale_gain_params scale_gain; /* nbands > 0: G = Σ_j g_j Π_j per wavelet band of the commands
                                      * (core/op/scale_gain.h) in place of g; 0: the single gain */
    int points_per_subaperture;      /* simulation grid points per LGS subaperture side */
    double diameter;                 /* pupil diameter D [m] */
    double obstruction;              /* central obstruction, fraction of D */
    wt_atmosphere_params atmosphere; /* the profile (arrays not owned, read at alloc); the loop sets n, delta
                                      * and seed */
    double lgs_tt_jitter;            /* random LGS tip-tilt per axis per frame [rad rms] */
    double eval_wavelength;          /* Strehl wavelength [m] */
    int settle_frames;               /* frames left out of the long-exposure averages */
    wt_reconstructor_params recon;   /* the iterative reconstructor of opt->recon (opt->iterations applied) */
    wt_fitting_params perfect_fit;   /* the cg9 fitting of the perfect_fit budget mode */
    wt_adapt_params learn;           /* learn.every > 0: the closed loop learns its atmosphere (sim/adapt.h) */
    long learn_max_updates;          /* room for its updates' record */
    wt_night_params night;           /* source WT_NIGHT_NONE: the atmosphere fixed; else the truth's changing night
                                      * (sim/night.h), whose reference state must be `atmosphere`'s and
                                      * frame_time 1 / rate */
    wt_sodium_drive_params sodium;   /* the truth's sodium sequence and the LGS reference in the loop
                                      * (sim/sodium_drive.h); none and static: nothing runs */
    double lgs_focus_stage_gain;     /* > 0: the diffractive LGS's focus stage and tip-tilt centring with this
                                      * integrator gain (sim/focus_stage.h; closed loop only); 0: none */
} wt_loop_params;

/* Builds the atmosphere, truth sensors, reconstructor and control from par. sys must outlive it. */
int wt_loop_alloc_params(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, const wt_loop_params *par,
                         wt_loop **out);

/* sim/loop_config.c, the configuration side of the loop: par from cfg and opt, and
 * wt_loop_alloc_params with the parameters of sys's configuration (sys and its config must outlive it). */
void wt_loop_params_from_config(const wt_config *cfg, const wt_loop_options *opt, wt_loop_params *par);
/* The truth's night as the configuration asks for it (atmosphere.night.*; source WT_NIGHT_NONE without one): the
 * part of wt_loop_params_from_config that the compare report reads too (its pointers into cfg). */
void wt_loop_night_params(const wt_config *cfg, wt_night_params *p);
int wt_loop_alloc(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, wt_loop **out);
void wt_loop_free(wt_loop *lp);

/* Run one frame. Allocates nothing. */
int wt_loop_step(wt_loop *lp);

long wt_loop_frames_done(const wt_loop *lp);
/* Of the last frame: measured slopes s_t, pseudo-open-loop slopes s_ol (nslopes), the commands a_t
 * applied during it (nact), the residual rms per evaluation direction [m] and their short-exposure
 * Strehl. */
const double *wt_loop_slopes(const wt_loop *lp);
const double *wt_loop_slopes_ol(const wt_loop *lp);
const double *wt_loop_applied(const wt_loop *lp);
const double *wt_loop_rms(const wt_loop *lp);
double wt_loop_field_strehl(const wt_loop *lp); /* field-average short-exposure Strehl of the last frame */
/* Long-exposure accumulators (frames after the settle period). */
const wt_strehl_le *wt_loop_le(const wt_loop *lp);
wt_loop_times wt_loop_get_times(const wt_loop *lp);
/* Fine evaluation grid and pupil mask; residual OPD of direction j in the last frame [m]. */
const wt_grid *wt_loop_fine_grid(const wt_loop *lp);
const uint8_t *wt_loop_pupil_mask(const wt_loop *lp);
const double *wt_loop_residual(const wt_loop *lp, int j);
/* The truth's state of the last frame run (before any: of frame 0) when a night drives it (params.night):
 * 1 and *out (its arrays the loop's, valid until the next step); 0 without a night (the truth is then
 * params.atmosphere, fixed). */
int wt_loop_truth_state(const wt_loop *lp, wt_night_sample *out);
/* The sodium layer's drive (NULL when the profile is fixed and the reference static). */
const wt_sodium_drive *wt_loop_sodium(const wt_loop *lp);
/* The LGS focus stage (NULL without lgs_focus_stage_gain or a diffractive LGS). */
const wt_focus_stage *wt_loop_focus_stage(const wt_loop *lp);
/* The atmosphere (screens, for dumps). */
const struct wt_atmosphere *wt_loop_atmosphere(const wt_loop *lp);
wt_reconstructor *wt_loop_reconstructor(wt_loop *lp);
/* The learning of the atmosphere (NULL unless the closed loop learns). */
const wt_adapt *wt_loop_adapt(const wt_loop *lp);

#endif
