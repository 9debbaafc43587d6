/* sim/focus_stage.h: the LGS wavefront sensors' focus stage and tip-tilt centring, the truth's optics that keep
 * each LGS's spots on its matched filter's reference when the sodium layer moves (SPEC §12 "The sodium layer
 * changes too"; docs/design.md "The sodium layer in time").
 *
 * A centroid change Δh of the sodium layer moves the spot of subaperture r of an LGS launched from l by
 * β = (r − l)(1/(H + Δh) − 1/H) ≈ −(r − l) Δh/H² (core/optics/spot.h): on the slopes, the gradient of the OPD
 *     φ(r) = −Δh/(2H²) |r|² + (Δh/H²) l·r,
 * a focus common to every LGS and a tilt of each one's own. With the LGS focus removed from the tomography
 * (recon.lgs_focus_removal) the loop no longer drives that focus into the DMs, so the spots stay where the drift
 * puts them, and a static reference's matched filter leaves its linear range (§48.2: 1–2 pixels at 43 m from
 * the launch for 1–2 km). A real LGS WFS follows the sodium with a focus stage (a trombone that re-conjugates it)
 * and centres each spot with the launch telescope's steering mirror; both move the source as the sensor sees it,
 * not the science path's wavefront. Here they move every point of the source of subaperture r by
 *     δ_m(r) = 2 c r + t_m      (r from the pupil centre [m]; c [1/m], t_m [rad]: the slopes of c|r|² + t_m·r),
 * in the truth's spot tables (core/optics/spot.h wt_spot_set_sodium_staged: exact, and free of the FFT field that
 * an OPD tilt of 2″ would wrap around), so the stage moves when the tables are rebuilt: at the sodium sequence's
 * cadence (sim/sodium_drive.h), from the measured LGS slopes s_m of the frames since the last move (closed loop:
 * the residual, the stage's own term included), averaged over those frames:
 *     c_m = Σ_k (r_k − r̄)·s_k / (2 Σ_k |r_k − r̄|²)      (the least-squares focus coefficient of LGS m),
 *     t̂_m = (mean s_x, mean s_y),
 *     c ← c − g ⟨mean_m c_m⟩,   t_m ← t_m − g ⟨t̂_m⟩        (integrators of gain g per move).
 * The focus is one for all LGS (a sodium centroid change is common to them; a stage that followed each LGS's own
 * focus would remove the differences between the LGS that recon.lgs_focus_mode = "common" keeps in the tomography);
 * the tilt is each one's. What the stage puts on the slopes is focus and tip-tilt of each LGS, which the tomography
 * projects out anyway (needs recon.lgs_focus_removal): it changes the loop only through the centroiders' linearity.
 * c is reported as the sodium altitude change it compensates, Δh = 2 H² c (H the LGS altitude).
 */
#ifndef WT_FOCUS_STAGE_H
#define WT_FOCUS_STAGE_H

#include "../core/model/system.h"

typedef struct wt_focus_stage wt_focus_stage;

/* What the stage did: its focus as Δh = 2 H² c [m] now and averaged over the frames from `from_frame` on, the rms
 * over the LGS and those frames of |t_m| [rad], and its moves. */
typedef struct wt_focus_stage_stats {
    double dh_now, dh_mean, tilt_rms;
    long frames_averaged, moves;
} wt_focus_stage_stats;

/* A stage on every diffractive LGS of sys, gain g ∈ (0, 1] (WT_ERR_INVALID otherwise), averaging its statistics
 * from frame `from_frame` on. *out = NULL when the system has no diffractive LGS. */
int wt_focus_stage_alloc(wt_context *ctx, const wt_system *sys, double gain, long from_frame, wt_focus_stage **out);
/* Sensor i's stage {t_x, t_y, c} [rad, rad, 1/m]; zeros for a sensor without one. fs NULL: zeros. */
void wt_focus_stage_terms(const wt_focus_stage *fs, int i, double stage[3]);
/* Frame t's measured slopes (the system's concatenated vector) into the sums of the next move */
void wt_focus_stage_measure(wt_focus_stage *fs, long t, const double *slopes);
/* One move of the integrators from the frames measured since the last (none: no move) */
void wt_focus_stage_move(wt_focus_stage *fs);
wt_focus_stage_stats wt_focus_stage_get_stats(const wt_focus_stage *fs);
void wt_focus_stage_free(wt_focus_stage *fs);

#endif
