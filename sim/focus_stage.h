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
 * and centres each spot with the launch telescope's steering mirror; both act on the light the sensor sees,
 * not on the science path. Here they are an OPD added to what each diffractive LGS samples:
 *     ψ_m(r) = c |r|² + t_m·r       (r from the pupil centre [m]; c [1/m], t_m [rad]),
 * driven by the frame's measured LGS slopes s_m (closed loop: the residual, the stage's own term included):
 *     c_m = Σ_k (r_k − r̄)·s_k / (2 Σ_k |r_k − r̄|²)      (the least-squares focus coefficient of LGS m),
 *     t̂_m = (mean s_x, mean s_y),
 *     c ← c − g mean_m c_m,   t_m ← t_m − g t̂_m          (integrators of gain g, applied from the next frame).
 * The focus is one for all LGS (a sodium centroid change is common to them; a stage that followed each LGS's own
 * focus would remove the differences between the LGS that recon.lgs_focus_mode = "common" keeps in the tomography);
 * the tilt is each one's. What the stage puts on the slopes is focus and tip-tilt of each LGS, which the tomography
 * projects out anyway (needs recon.lgs_focus_removal): it changes the loop only through the centroiders' linearity.
 * c is reported as the sodium altitude change it compensates, Δh = 2 H² c.
 */
#ifndef WT_FOCUS_STAGE_H
#define WT_FOCUS_STAGE_H

#include "../core/model/system.h"

typedef struct wt_focus_stage wt_focus_stage;

/* What the stage did: its focus as Δh = 2 H² c [m] (H the LGS altitude) now and averaged over the frames from
 * `from_frame` on (wt_focus_stage_update's count), and the rms over the LGS and those frames of |t_m| [rad]. */
typedef struct wt_focus_stage_stats {
    double dh_now, dh_mean, tilt_rms;
    long frames_averaged;
} wt_focus_stage_stats;

/* A stage on every diffractive LGS of sys, gain g ∈ (0, 1] (WT_ERR_INVALID otherwise), averaging its statistics
 * from frame `from_frame` on. *out = NULL when the system has no diffractive LGS. */
int wt_focus_stage_alloc(wt_context *ctx, const wt_system *sys, double gain, long from_frame, wt_focus_stage **out);
/* The OPD ψ of sensor i (an index into sys->sensors): *tx, *ty [rad] and *focus [1/m]; zeros for a sensor
 * without a stage. Read-only: may be called from a parallel region. */
void wt_focus_stage_terms(const wt_focus_stage *fs, int i, double *tx, double *ty, double *focus);
/* One integrator step from frame t's measured slopes (the system's concatenated vector) */
void wt_focus_stage_update(wt_focus_stage *fs, long t, const double *slopes);
wt_focus_stage_stats wt_focus_stage_get_stats(const wt_focus_stage *fs);
void wt_focus_stage_free(wt_focus_stage *fs);

#endif
