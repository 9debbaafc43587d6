/* runtime/control.h: the loop's control law, one for the simulator (sim/loop.c) and the per-frame API
 * (runtime/rtc.c, `wavetomo run`, Python) — SPEC §7, the paper's pseudo-open-loop control:
 *
 *   a_{t+d} = a_{t+d−1} + g (r_t − a_t)                                       (loop.gain), or
 *   a_{t+d} = a_{t+d−1} + G (r_t − a_t),   G = Σ_j g_j Π_j per band of the commands   (loop.gain_levels,
 *                                                                               core/op/scale_gain.h), or
 *   a_{t+d} = r_t   when the reconstructor runs the integrator on its layers (recon.predict_integrator = "layers"),
 *
 * r_t the reconstruction of frame t (from s_ol = s + Â a_t), a_t the commands applied during frame t, d the loop's
 * delay in frames: a queue of the last d + 1 command vectors, a_t at slot t mod (d + 1), all 0 at the start.
 * Plan and state in one object (one loop); allocates only in wt_control_alloc. */
#ifndef WT_CONTROL_H
#define WT_CONTROL_H

#include "../core/config/config.h"
#include "../core/op/scale_gain.h"
#include "../core/model/system.h"

typedef struct wt_control wt_control;

typedef struct wt_control_params {
    int delay;                       /* d ≥ 1 [frames] */
    double gain;                     /* g in (0, 1] */
    wt_scale_gain_params scale_gain; /* nbands > 0: G in place of g; 0: the single gain */
    int direct;                      /* 1: a_{t+d} = r_t, the reconstructor's result applied as it is (it runs the
                                      * integrator itself: recon.predict_integrator = "layers", reconstructor.h).
                                      * Set by the holder of the reconstructor from wt_reconstructor_integrates
                                      * (sim/loop.c, runtime/rtc.c): the reconstructor is the one place that decides */
} wt_control_params;

/* The law of a configuration: loop.delay, loop.gain, loop.gain_levels and loop.gain_basis (direct 0). */
wt_control_params wt_control_params_from_config(const wt_config *cfg);

/* For the actuators and DMs of sys (not owned: must outlive the object). WT_ERR_INVALID for a delay < 1 or a gain
 * outside [0, 1], and the scale gain's own refusals (core/op/scale_gain.h). */
int wt_control_alloc(wt_context *ctx, const wt_system *sys, const wt_control_params *par, wt_control **out);
void wt_control_free(wt_control *c);

/* a_t: the commands applied during the next frame t (nact values; valid until the next wt_control_step). */
const double *wt_control_applied(const wt_control *c);
/* Frame t done with reconstruction r and applied commands a_t (usually wt_control_applied's; a caller that applied
 * others gives those): queues a_{t+d} and returns it; t advances. r = NULL: a_{t+d} = 0 (no reconstructor). */
const double *wt_control_step(wt_control *c, const double *r, const double *a_t);
/* Every queued command 0, t = 0. */
void wt_control_reset(wt_control *c);
int wt_control_delay(const wt_control *c);
double wt_control_gain(const wt_control *c);
/* 1 when the scale-dependent gain G is in use */
int wt_control_scale_dependent(const wt_control *c);

#endif
