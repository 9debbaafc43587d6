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
 * field edge). N = Σ_j H_jᵀ H_j + ε I does not change from frame to frame, so it is solved either by CG
 * warm-started from the previous commands (WT_FIT_CG: each iteration applies every H_j and H_jᵀ), or
 * directly (WT_FIT_CHOLESKY): N assembled once at set-up as a sparse matrix on the active actuators and
 * factored by CHOLMOD (core/la/chol.h), a frame = the right-hand side Σ_j H_jᵀ P_j φ (matrix-free, as for CG)
 * and two triangular solves. The direct solve is the exact fit, which the CG's few iterations approach.
 */
#ifndef WT_FITTING_H
#define WT_FITTING_H

#include "../la/sparse.h"
#include "../op/grid.h"
#include "../solve/pcg.h"
#include "system.h"

typedef struct wt_fitting wt_fitting;

/* The solvers, in the order of the configuration's recon.cg9.fit_solver list "cg|cholesky". */
enum { WT_FIT_CG = 0, WT_FIT_CHOLESKY = 1 };

typedef struct wt_fitting_params {
    double regularization; /* ε relative to the mean diagonal of Σ_j H_jᵀ H_j */
    int sampling;          /* sample points per subaperture side: 1 = Fried corners, q > 1 = d/q pupil grid */
    int solver;            /* WT_FIT_CG (default, 0) or WT_FIT_CHOLESKY */
    int factor_float32;    /* WT_FIT_CHOLESKY: 1 = the solves read a float32 copy of L (accumulating in double) */
    int reference;         /* 1 = the frame's reference kernels (each direction through its own zeroed pupil buffer
                              by wt_projection_apply / apply_t, the Cholesky solves' plain loops): the same bits
                              as the fast ones (wt_projection_apply_rows / apply_t_side, a buffer per group, the
                              vectorised solves), slower (tests, the paired bench) */
} wt_fitting_params;

/* What the direct solver's set-up cost (all zero for WT_FIT_CG). */
typedef struct wt_fitting_stats {
    double t_assemble;     /* assembly of N from the 2 ndir sparse products H_jᵀ H_j [s] */
    double t_factorize;    /* CHOLMOD analysis + numeric factorisation + the solves' packed copy and plan [s] */
    int64_t nnz_matrix;    /* non-zeros of N (both triangles) */
    double nnz_factor;     /* non-zeros of its Cholesky factor L */
    double factor_bytes;   /* bytes CHOLMOD holds for L [bytes] */
    const char *ordering;  /* CHOLMOD's fill-reducing ordering ("AMD", "METIS", …) */
    double solve_bytes;    /* bytes of L the two solves read per frame (packed lower part, fp64 or fp32) */
    double split[3];       /* entries of L in the solves' two thread groups and their top part */
} wt_fitting_stats;

/* layers: the reconstruction layer grids and altitudes (the tomography's); nlayers = 0 makes a fitting
 * that only fits given maps (wt_fitting_solve_maps). par->solver WT_FIT_CHOLESKY assembles and factors N here
 * (seconds at E-ELT size: docs/results.md §15); an unknown solver is WT_ERR_INVALID, a factorisation that fails
 * WT_ERR_NUMERIC naming recon.cg9.fit_regularization. */
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
/* The normal equations solved for a: by CG warm-started from a (max_iter ≥ 0, rtol ≥ 0), or with the
 * Cholesky factor (max_iter, rtol and the initial a unused; res: 0 iterations, rel_resid 0, history[0] 0).
 * Allocates nothing (the factor's solve workspace is sized at set-up). */
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
/* Bytes the object holds (projection stencils estimated, workspaces, the Cholesky factor), for reports. */
double wt_fitting_bytes(const wt_fitting *f);
int wt_fitting_solver(const wt_fitting *f);
void wt_fitting_stats_get(const wt_fitting *f, wt_fitting_stats *stats);
/* The normal matrix N = Σ_j H_jᵀ H_j + ε I on the active actuators (nact x nact, CSC, both triangles;
 * allocates): the one the Cholesky solver factors, assembled from the sparse H_j (apply == assembled x). */
int wt_fitting_assemble(const wt_fitting *f, wt_sparse **out);
/* Fit given OPD maps instead of layers: maps holds ndir maps on the sample grid (nx*ny each, only the
 * sample points read), b = Σ H_jᵀ map_j; the solve is warm-started from a (CG) or direct (Cholesky). */
void wt_fitting_rhs_maps(wt_fitting *f, const double *maps, double *b);
int wt_fitting_solve_maps(wt_fitting *f, const double *maps, double *a, int max_iter, double rtol,
                          wt_pcg_result *res);
/* The sample grid and its mask (owned by the fitting). */
const wt_grid *wt_fitting_sample_grid(const wt_fitting *f);
const uint8_t *wt_fitting_sample_mask(const wt_fitting *f);
/* The sample grid and a new mask (*mask allocated with the context's allocator) of sampling q. */
int wt_fitting_sampling(wt_context *ctx, const wt_system *sys, int q, wt_grid *grid, uint8_t **mask);

#endif
