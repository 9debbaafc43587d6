/* core/model/fitting.h: the DM fitting step (paper eq. fit_step_min; SPEC §5).
 *
 *   a = argmin_a Σ_j ‖H_j a − P_j φ‖² + ε ‖a‖²,   i.e.  (Σ_j H_jᵀ H_j + ε I) a = Σ_j H_jᵀ P_j φ
 *
 * over the evaluation directions θ_j (sources at infinity), on the Fried corner grid of the pupil
 * (the corners of valid subapertures). H_j: the DMs seen along θ_j (bilinear influence, actuator
 * grids at their conjugate altitudes; actuators outside the active set are held at zero); P_j: the
 * reconstruction layers along θ_j. ε = fit_regularization × mean diag(Σ_j H_jᵀ H_j): a small Tikhonov
 * term that fixes the components the directions do not see (piston split between DMs, waffle at the
 * field edge). Solved by CG, warm-started from the previous commands.
 */
#ifndef WT_FITTING_H
#define WT_FITTING_H

#include "../op/grid.h"
#include "../solve/pcg.h"
#include "system.h"

typedef struct wt_fitting wt_fitting;

/* layers: the reconstruction layer grids and altitudes (the tomography's); regularization: relative ε. */
int wt_fitting_alloc(wt_context *ctx, const wt_system *sys, int nlayers, const wt_grid *layers,
                     const double *altitudes, double regularization, wt_fitting **out);
/* The fitting of a tomography's reconstruction layers (its grids and altitudes). */
struct wt_tomography;
int wt_fitting_alloc_for(wt_context *ctx, const struct wt_tomography *t, double regularization, wt_fitting **out);
void wt_fitting_free(wt_fitting *f);

/* y = (Σ H_jᵀ H_j + ε I) a   (a, y: sys->nact active actuators) */
void wt_fitting_apply(wt_fitting *f, const double *a, double *y);
/* b = Σ H_jᵀ P_j φ  (φ: spatial layers concatenated) */
void wt_fitting_rhs(wt_fitting *f, const double *phi, double *b);
/* CG on the normal equations, warm-started from a. max_iter ≥ 0, rtol ≥ 0. */
int wt_fitting_solve(wt_fitting *f, const double *phi, double *a, int max_iter, double rtol, double *history,
                     wt_pcg_result *res);
double wt_fitting_epsilon(const wt_fitting *f);

/* Scatter active-actuator commands onto the full DM grids (concatenated) and back. */
void wt_dm_expand(const wt_system *sys, const double *a, double *grids);
void wt_dm_restrict(const wt_system *sys, const double *grids, double *a);
int64_t wt_dm_grid_points(const wt_system *sys);

#endif
