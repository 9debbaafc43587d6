/* core/model/fitting.h: the DM fitting step (paper eq. fit_step_min; SPEC §5).
 *
 *   a = argmin_a Σ_j ‖H_j a − P_j φ‖² + ε ‖a‖²,   i.e.  (Σ_j H_jᵀ H_j + ε I) a = Σ_j H_jᵀ P_j φ
 *
 * over the evaluation directions θ_j (sources at infinity), sampled on a pupil-plane grid: the Fried
 * corner grid of the valid subapertures (sampling 1), or every point of the d/q grid inside the pupil
 * (sampling q > 1; a fit sampled only at the 0.5 m corners leaves the DM free between them). H_j: the DMs seen along θ_j (bilinear influence, actuator
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

typedef struct wt_fitting_params {
    double regularization; /* ε relative to the mean diagonal of Σ_j H_jᵀ H_j */
    int sampling;          /* sample points per subaperture side: 1 = Fried corners, q > 1 = d/q pupil grid */
} wt_fitting_params;

/* layers: the reconstruction layer grids and altitudes (the tomography's); nlayers = 0 makes a fitting
 * that only fits given maps (wt_fitting_solve_maps). */
int wt_fitting_alloc(wt_context *ctx, const wt_system *sys, int nlayers, const wt_grid *layers,
                     const double *altitudes, const wt_fitting_params *par, wt_fitting **out);
/* The fitting of a tomography's reconstruction layers (its grids and altitudes). */
struct wt_tomography;
int wt_fitting_alloc_for(wt_context *ctx, const struct wt_tomography *t, const wt_fitting_params *par, wt_fitting **out);
void wt_fitting_free(wt_fitting *f);

/* y ← y + α (Σ H_jᵀ H_j + ε I) a   (a, y: sys->nact active actuators; uses the object's workspace) */
void wt_fitting_apply(wt_fitting *f, double alpha, const double *a, double *y);
/* b ← b + α Σ H_jᵀ P_j φ  (φ: spatial layers concatenated) */
void wt_fitting_rhs(wt_fitting *f, double alpha, const double *phi, double *b);
/* CG on the normal equations, warm-started from a. max_iter ≥ 0, rtol ≥ 0. */
int wt_fitting_solve(wt_fitting *f, const double *phi, double *a, int max_iter, double rtol, double *history,
                     wt_pcg_result *res);
/* wt_fitting_solve continuing the previous one on f (the reconstructor's warm start): a must hold that
 * solve's result, unchanged; the initial apply of the normal operator is replaced by the previous
 * right-hand side minus the previous recursive residual (wt_pcg_solve_rhs): 11 → 10 applies for 10
 * iterations, the same solution up to rounding. A first solve, one after wt_fitting_solve_maps or an error,
 * or one on other commands than the last, applies the operator as wt_fitting_solve does. */
int wt_fitting_solve_continue(wt_fitting *f, const double *phi, double *a, int max_iter, double rtol,
                              double *history, wt_pcg_result *res);
double wt_fitting_epsilon(const wt_fitting *f);
/* Bytes the object holds (projection stencils estimated, workspaces), for reports. */
double wt_fitting_bytes(const wt_fitting *f);
/* Fit given OPD maps instead of layers: maps holds ndir maps on the sample grid (nx*ny each, only the
 * sample points read), b = Σ H_jᵀ map_j; the solve is warm-started from a. */
void wt_fitting_rhs_maps(wt_fitting *f, const double *maps, double *b);
int wt_fitting_solve_maps(wt_fitting *f, const double *maps, double *a, int max_iter, double rtol,
                          wt_pcg_result *res);
/* The sample grid and its mask (owned by the fitting). */
const wt_grid *wt_fitting_sample_grid(const wt_fitting *f);
const uint8_t *wt_fitting_sample_mask(const wt_fitting *f);
/* The sample grid and a new mask (*mask allocated with the context's allocator) of sampling q. */
int wt_fitting_sampling(wt_context *ctx, const wt_system *sys, int q, wt_grid *grid, uint8_t **mask);

#endif
