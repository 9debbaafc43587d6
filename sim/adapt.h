/* sim/adapt.h: the loop that learns its atmosphere (SPEC §12 "Updates"; recon.atmosphere.source = "learned").
 *
 * Every frame the LGS part of the pseudo-open-loop slopes s_ol = s + Â a (the reconstructor's own input: the truth is
 * never read) goes into the cross-covariance accumulator of core/model/learn.h. Every `every` frames (the update
 * interval T in night time over the night time of a frame) the Cn² profile and r0 are fitted on the learning grid
 * (its response maps computed once, at alloc: wt_learn_model)
 * from the frames since the last estimate, and the accumulator starts again (a night changes: an estimate is of
 * its last T); or, cumulative, from every frame since the start (a static night). What the estimate replaces:
 *   pcg3, cg9: the reconstructor's model at the next frame (wt_reconstructor_set_model: priors, model error,
 *              noise weights, preconditioner, prediction shifts); its wall time is reported, not simulated;
 *   mvm:       a new control matrix built from the estimate by the driver's rebuild callback (builder/ is above
 *              this module), swapped in when the build would be finished: `latency` night seconds after the
 *              estimate (< 0: the build's measured wall time on this machine); the old matrix is applied
 *              meanwhile. One build at a time, as on one build machine: an estimate made while a build runs
 *              waits and is built when that one is done (a newer one replaces a waiting one).
 * The wind of the model (prediction): each learned altitude takes the wind of the start model's layer nearest in
 * altitude (the oracle: the truth's of that frame; the MVM's rebuild puts it in its predictor, so a new wind is a
 * new matrix, after its latency) (the lagged maps' fit, wt_learn_wind_fit, takes minutes on the demo); with learn_wind (pcg3, cg9) the
 * reconstruction layers' own winds are measured on their estimates (core/model/wind_align.h: every
 * WT_ADAPT_WIND_STRIDE-th frame's layers, before any prediction shift) and set at each update
 * (wt_reconstructor_set_layer_wind): a layer's estimate holds what the layer absorbs, so its measured wind is already
 * the mixture that SPEC §12's compression (the Cn²-weighted mean wind) stands for, and no mapping between the learned
 * altitudes and the layers is needed; a layer without a clear estimate keeps the wind it had.
 * The oracle in a changing night (follow_truth): no estimate; every `every` frames the model becomes the truth's
 * state of that frame (its layers, fractions, r0 and wind, sim/night.h), taken as a learned one is (pcg3 and
 * cg9 at the next frame, the MVM after its latency): what a perfect profiler would give.
 */
#ifndef WT_ADAPT_H
#define WT_ADAPT_H

#include "../core/model/learn.h"
#include "../core/model/reconstructor.h"
#include "../core/model/system.h"
#include "night.h"

struct wt_mvm;

/* Build a control matrix for the model (r0 [m], natm layers at alt [m] with fractions frac and wind vx, vy [m/s]:
 * the predictor's under recon.predict): *out owned by the caller of the callback afterwards (wt_mvm_free). sampled:
 * the profile is an estimate that samples a continuous one on a grid (compressed as hats onto the matrix's layers,
 * core/model/profile.h), not layers (the oracle's). */
typedef int (*wt_adapt_rebuild_fn)(void *user, double r0, int natm, const double *alt, const double *frac,
                                   const double *vx, const double *vy, int sampled, struct wt_mvm **out);

typedef struct wt_adapt_params {
    long every;               /* frames between estimates (≥ WT_ADAPT_MIN_FRAMES) */
    int cumulative;           /* 0: each estimate from the frames since the previous one (a night that changes);
                                 1: from every frame since the start (a static night: the estimate converges) */
    long run_frames;          /* cumulative: the run's frames (its WT_ADAPT_BATCHES batches are quarters of the run) */
    double memory;            /* ≥ 1: the model's Cn² per altitude c = f r0^(−5/3) is the exponential average of the
                                 estimates', weight 1/memory on the newest (1: each estimate alone) */
    double frame_night;       /* night time of one frame [s] (1/rate times the night's time compression) */
    double L0;                /* outer scale of the fit [m] (the model's: not fitted) */
    double latency;           /* mvm: night seconds from an estimate to its matrix in the loop; < 0: measured */
    int follow_truth;         /* 1: the oracle following a changing night (no estimate; the truth's state) */
    int ntruth;               /* follow_truth: the truth's layers and their altitudes [m] */
    double truth_alt[WT_MAX_LAYERS];
    int grid_layers;          /* 1: the learning grid holds the reconstructor's altitudes recon_alt too
                                 (wt_learn_grid_with_layers); 0: the default grid alone */
    int nrecon;               /* the reconstructor's layers (grid_layers) */
    double recon_alt[WT_MAX_LAYERS]; /* [m] */
    int nstart;               /* the start model's layers: their wind goes to the learned altitudes */
    double start_alt[WT_MAX_LAYERS], start_vx[WT_MAX_LAYERS], start_vy[WT_MAX_LAYERS]; /* [m], [m/s] */
    int learn_wind;           /* 1: the layers' winds aligned on their estimates (pcg3, cg9; wt_adapt_wind_alloc) */
    double frame_dt;          /* learn_wind: real time of one frame [s] (1 / the loop's rate) */
} wt_adapt_params;

/* learn_wind: a snapshot of the layers every this many frames, lags of 1, 2, 4, 8 snapshots (the longest 80 ms at
 * 500 Hz: a layer at 25 m/s moves 2 m, a few points, still well inside its footprint) */
#define WT_ADAPT_WIND_STRIDE 5

/* An estimate needs this many frames: WT_ADAPT_BATCHES batches (its uncertainty) of at least 25 each. */
#define WT_ADAPT_BATCHES 4
#define WT_ADAPT_MIN_FRAMES (WT_ADAPT_BATCHES * 25)

/* What each update did (the run's record). */
typedef struct wt_adapt_update {
    long frame;               /* the frame after which the estimate was made */
    double night;             /* its night time [s] */
    double r0, r0_sigma;      /* the estimate, after the memory's average [m] */
    double r0_raw;            /* this estimate alone [m] */
    int nalt;
    double altitude[WT_MAX_LAYERS + WT_LEARN_MAX_ALT], fraction[WT_MAX_LAYERS + WT_LEARN_MAX_ALT];
    double vx[WT_MAX_LAYERS + WT_LEARN_MAX_ALT], vy[WT_MAX_LAYERS + WT_LEARN_MAX_ALT]; /* the model's wind there [m/s] */
    double fit_s;             /* wall time of the fit [s] */
    double model_s, precond_s; /* pcg3/cg9: wall time of the new model, of the preconditioner [s] */
    double build_s;           /* mvm: wall time of the matrix's build [s] (0 while waiting) */
    long applied_frame;       /* the first frame that used it (−1: never, e.g. replaced while waiting) */
    int nwind;                /* learn_wind: the reconstruction layers, and each one's wind after this update: */
    double wind_vx[WT_MAX_LAYERS], wind_vy[WT_MAX_LAYERS];     /* [m/s] */
    double wind_sx[WT_MAX_LAYERS], wind_sy[WT_MAX_LAYERS];     /* its uncertainty (0: not estimated) [m/s] */
    int wind_valid[WT_MAX_LAYERS];                             /* 1: estimated now; 0: kept (no clear peak) */
} wt_adapt_update;

typedef struct wt_adapt wt_adapt;

/* sys's LGS (≥ 2) are the first nlgs sensors, their slopes the first blocks (core/model/system.h). kind: the
 * loop's reconstructor. rebuild (mvm only, else NULL). max_updates: room in the record (a run's frames / every). */
int wt_adapt_alloc(wt_context *ctx, const wt_system *sys, int kind, const wt_adapt_params *par, wt_adapt_rebuild_fn rebuild,
                   void *rebuild_user, long max_updates, wt_adapt **out);
void wt_adapt_free(wt_adapt *a);
/* learn_wind: the layers' wind estimator for rec (the loop's pcg3 or cg9 reconstructor, the same object for the run),
 * after wt_adapt_alloc; a no-op without learn_wind. Allocates. */
int wt_adapt_wind_alloc(wt_adapt *a, wt_reconstructor *rec);

/* Frame t measured s_ol: accumulate it; after the `every`-th frame since the last estimate, fit (follow_truth: take
 * `truth`, the truth's state of frame t, required then) and update rec (pcg3/cg9) or start/queue an MVM build.
 * Allocates only on an update. */
int wt_adapt_frame(wt_adapt *a, long t, const double *s_ol, const wt_night_sample *truth, wt_reconstructor *rec);
/* mvm: before frame t runs, a matrix whose build is finished by then (in night time) is swapped in: *rec replaced
 * by a reconstructor of it (the old one freed) and the matrix before it freed. No-op otherwise. */
int wt_adapt_swap(wt_adapt *a, long t, wt_reconstructor **rec);

int wt_adapt_nupdates(const wt_adapt *a);
int wt_adapt_follows_truth(const wt_adapt *a); /* 1: the oracle following a night (no estimates) */
const wt_adapt_update *wt_adapt_updates(const wt_adapt *a);
double wt_adapt_accumulate_seconds(const wt_adapt *a); /* summed wall time of the accumulation [s] */
double wt_adapt_wind_seconds(const wt_adapt *a);       /* learn_wind: the layers' part of it [s] (0 without) */
/* learn_wind: the reconstruction layers whose winds the updates hold (wt_adapt_update.wind_*), their altitudes [m]
 * into *alt (the object's); 0 without learn_wind. */
int wt_adapt_wind_layers(const wt_adapt *a, const double **alt);
double wt_adapt_build_seconds(const wt_adapt *a);      /* summed wall time of the MVM builds [s] */
double wt_adapt_model_setup_seconds(const wt_adapt *a); /* the learning grid's response maps, at alloc [s] */
/* The updates into w under the group `group` ("learned" in sim's file; one row per update: frame, night time, r0 and its
 * uncertainty, the profile on the learning grid, the wall times, the frame that first used it), self-documenting. */
struct wt_h5_writer;
int wt_adapt_write(const wt_adapt *a, struct wt_h5_writer *w, const char *group);
/* A copy of a's record only (what wt_adapt_write writes; the accumulator, its model and any matrix left behind), to
 * outlive the loop that owns a (compare keeps one per case); wt_adapt_free frees it. */
int wt_adapt_copy_record(const wt_adapt *a, wt_adapt **out);

#endif
