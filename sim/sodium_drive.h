/* sim/sodium_drive.h: the sodium layer in time for the closed loop (SPEC §12 "The sodium layer changes
 * too"; docs/design.md "The sodium layer in time"): the truth's LGS spots follow a profile sequence
 * (core/optics/sodium.h) on the night's clock, and the real-time computer's reference follows a choice.
 *
 * Frame j (night time t_j = start + j Δt c, the clock of sim/night.h, with or without a night):
 *  - truth: every `sequence_update` of night time (counted in frames, ⌊update / (Δt c)⌉, from the run's first
 *    frame; 0: every frame) the LGS spot tables are rebuilt from the sequence's profile at t_j, and held until
 *    the next rebuild (wt_sensing_set_sodium), seen through the LGS focus stage when there is one (it moves at those
 *    rebuilds from the second on: sim/focus_stage.h);
 *  - reference `static`: the set-up's, never rebuilt (the default: nothing here runs, today's bits);
 *    `oracle`: every `reference_update` of night time from the first frame on (after the truth's rebuild of that
 *    frame), I0 and its derivatives of the spot model's current profile — what the truth renders — with the
 *    set-up's seeing, the centroider and its covariance with them (wt_sensing_rebuild_reference), then the pcg3 /
 *    cg9 noise weights C_E and preconditioner (wt_reconstructor_refresh_noise; an MVM keeps its C_E).
 *    `pixels`: every LGS subaperture's images, re-centred by their slopes, accumulated each frame from the first on
 *    (wt_sensing_pixels_start: the sensors' detect adds them); every `reference_update` of night time, from the
 *    first full period on (frame j = k·n, n = the cadence in frames ≥ WT_SENSING_PIXELS_MIN_FRAMES), the reference
 *    of the mean of the n frames before (wt_sensing_pixels_reference), then the same C_E refresh. Until the first
 *    rebuild the set-up's reference runs.
 * The matched filter's gain (`gain_update` > 0, any reference): every LGS frame's image is accumulated from the
 * first frame on (wt_sensing_gain_start); every `gain_update` of night time from the first full period on (after the
 * reference's rebuild of that frame, which keeps the old correction), each LGS filter's in-loop gain is measured on
 * the mean image of the frames before and its inverse applied to the slopes and C_E from then on
 * (wt_sensing_gain_update, core/model/sensing.h), then the C_E refresh.
 * The sensors are the system's: the drive leaves them at the set-up's profile and reference when freed
 * (wt_sensing_restore), so several loops may run on one system (compare, budget).
 */
#ifndef WT_SODIUM_DRIVE_H
#define WT_SODIUM_DRIVE_H

#include "../core/model/reconstructor.h"
#include "../core/model/system.h"
#include "focus_stage.h"

enum { WT_REFERENCE_STATIC = 0, WT_REFERENCE_ORACLE = 1, WT_REFERENCE_PIXELS = 2 };

typedef struct wt_sodium_drive wt_sodium_drive;

typedef struct wt_sodium_drive_params {
    const char *sequence;    /* the truth's profile in time (a file, sodium.h); NULL or "": the set-up's, fixed */
    double sequence_update;  /* night time between two rebuilds of the truth's spot tables [s]; 0: every frame */
    int reference;           /* WT_REFERENCE_STATIC, _ORACLE or _PIXELS */
    double reference_update; /* oracle, pixels: night time between two rebuilds [s] (≥ one frame's; pixels: ≥
                                WT_SENSING_PIXELS_MIN_FRAMES frames') */
    double gain_update;      /* the matched filter's gain from the pixels: night time between two estimates [s]
                                (≥ WT_SENSING_PIXELS_MIN_FRAMES frames'); 0: none */
    double start;            /* night time of frame 0 [s] */
    double frame_time;       /* Δt [s] */
    double compression;      /* c: night seconds per simulated second */
    long first_frame, frames; /* the run's frames first_frame … frames − 1 */
    const char *origin;      /* the keys that set the run's night times, for messages */
} wt_sodium_drive_params;

/* What it did: rebuilds of the truth's tables and of the reference, their wall times [s] (the reference's with its
 * C_E refresh, which is c_e_seconds of it); pixels: the frames' accumulation, accumulate_seconds over the LGS; the
 * matched filter's gain estimates. */
typedef struct wt_sodium_drive_stats {
    long truth_rebuilds, reference_rebuilds;
    double truth_seconds, reference_seconds, c_e_seconds, accumulate_seconds;
    long gain_updates;                 /* the matched filter's gain: estimates, */
    double gain_seconds;               /* their wall time with C_E's refresh, */
    double gain_accumulate_seconds;    /* the frames' accumulation over the LGS, */
    double gain_along, gain_across;    /* the last estimate along / across the elongation, mean of the LGS */
} wt_sodium_drive_stats;

/* Reads the sequence and checks it: it covers the run's night times and every LGS altitude (WT_ERR_CONFIG naming
 * the file, the keys). *out = NULL (and nothing to do) without a sequence and with a static reference, or without a
 * diffractive LGS. */
int wt_sodium_drive_alloc(wt_context *ctx, const wt_system *sys, const wt_sodium_drive_params *par,
                          wt_sodium_drive **out);
/* The frame's rebuilds (before its sensors); rec: the loop's reconstructor (its C_E follows an oracle), or NULL;
 * stage: the LGS focus stage (sim/focus_stage.h), moved at each rebuild of the truth's tables after the first and
 * built into them, or NULL. Outside parallel regions. */
int wt_sodium_drive_frame(wt_sodium_drive *d, long frame, wt_reconstructor *rec, wt_focus_stage *stage);
wt_sodium_drive_stats wt_sodium_drive_get_stats(const wt_sodium_drive *d);
/* Leaves the system's sensors at their set-up profile and reference. */
void wt_sodium_drive_free(wt_sodium_drive *d);

#endif
