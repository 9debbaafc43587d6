/* builder/mvm_build.h: the offline MVM control matrix of the wavelet MAP tomography (SPEC §9, §7; paper
 * eq. eqn_lse solved once for every actuator instead of once per frame).
 *
 *   commands = E c,   c = M⁻¹ Ãᵀ Ĉ⁻¹ s,   M = Σ_m Ã_mᵀ Ĉ_m⁻¹ Ã_m + α D            (wt_tomography)
 *   R = E M⁻¹ Ãᵀ Ĉ⁻¹   (n_act x n_slopes),   stored as Rᵀ = Ĉ⁻¹ Ã Y with Y = M⁻¹ Eᵀ,
 *   RÂ = R · Â          (n_act x n_act; Â the DM-to-slope interaction, POLC: R s_ol = R s + RÂ a)
 *
 * E maps wavelet coefficients to actuator commands:
 *   pcg3 (WT_MVM_LAYER_VALUES): the layer values at the active actuators, E = S W⁻¹ with S the sparse
 *     layers → commands map of wt_reconstructor_command_map (the selection of the layer point under each
 *     actuator, plus the linear altitude split of layers between DMs; WT_ERR_CONFIG when a DM gets none);
 *   cg9 (WT_MVM_FITTING): the fitting step of core/model/fitting.h solved exactly,
 *     E = F⁻¹ Σ_j H_jᵀ P_j W⁻¹,  F = Σ_j H_jᵀ H_j + ε I  (dense n_act x n_act, LAPACK Cholesky).
 *
 * How M is factorised (the "normal" object below). M is split into a sparse SPD part and a low-rank
 * symmetric correction,  M = N + B Q Bᵀ :
 *   N = Σ_LGS Ã_mᵀ C̃_m⁻¹ Ã_m + α D   sparse: LGS rows of Ã are local (a few hundred non-zeros each);
 *       assembled as GᵀG + αD with G = Lᵀ Ã_LGS (C̃⁻¹ = L Lᵀ per 2x2 subaperture block), factorised
 *       by CHOLMOD (supernodal, core/la/chol.h);
 *   LGS tip-tilt removal: Ĉ⁻¹ − C̃⁻¹ = −U Vᵀ − V Uᵀ + U (UᵀV) Uᵀ with U the two normalised tip/tilt
 *       columns of the sensor (and its unit focus pattern with recon.lgs_focus_removal: U orthonormal, three
 *       columns) and V = C̃⁻¹ U, i.e. [U V] [[UᵀV, −I], [−I, 0]] [U V]ᵀ: rank 4 per LGS (6 with the focus),
 *       indefinite, never densified;
 *   NGS: their slopes average the pupil (a 1x1 sensor's row touches every coefficient), so
 *       Ã_ngsᵀ C̃⁻¹ Ã_ngs would make N dense; they go into the correction too (rank = their slopes).
 * Hence B = [Ã_mᵀU_m, Ã_mᵀV_m (LGS m) …, Ã_ngsᵀ] (n x r, r = 4 nLGS + NGS slopes, 36 at E-ELT) and Q
 * block-diagonal. Solves use the Sherman–Morrison–Woodbury identity in the form that needs no Q⁻¹,
 *   M⁻¹ = N⁻¹ − Z K⁻¹ Q Zᵀ,   Z = N⁻¹ B,  K = I + Q Bᵀ Z  (r x r, LU with pivoting),
 * chosen over CHOLMOD's update/downdate because the correction is indefinite (a downdate after an
 * update) and dense in its columns, which would touch all of L for every rank-1 step, while SMW costs
 * one n x r block solve at set-up and two thin GEMMs per block of right-hand sides.
 * The full prior (recon.<variant>.prior = "full": α W C_φ⁻¹ Wᵀ, every pair of a layer's coefficients
 * coupled) makes N dense: it is formed as an n x n array (the sparse GᵀG, then each layer's prior block
 * column by column from the tomography's own prior apply) and factorised by LAPACK's dpotrf; solves by
 * dpotrs; the Woodbury correction is the same. n² doubles: 4.8 GB for pcg3 at E-ELT size (24576
 * unknowns), 174 GB for cg9 (refused by the budget, naming the prior).
 *
 * Memory: the build checks an estimate of its peak against opt->memory_budget before each large
 * allocation (the sparse Ã and N from exact symbolic counts, the factor from CHOLMOD's symbolic
 * analysis, R, RÂ, the block workspace) and refuses with WT_ERR_NOMEM naming the bytes needed and the
 * budget. Right-hand sides are processed in blocks of opt->block columns, so no n_unknowns x n_act or
 * n_unknowns x n_slopes matrix is ever formed.
 *
 * Threads: the assembly and the per-block steps run OpenMP regions (wt_context_threads); CHOLMOD's
 * factorisation and solves run in the BLAS (OpenBLAS threads). Everything here allocates: it is the
 * offline planner, not a per-frame path.
 */
#ifndef WT_MVM_BUILD_H
#define WT_MVM_BUILD_H

#include "../core/la/sparse.h"
#include "../core/model/tomography.h"
#include "../core/solve/mvm.h"

/* Progress: phase name ("assemble", "normal", "factorize", "solve", …), work done out of total. */
typedef void (*wt_mvm_progress_fn)(void *user, const char *phase, int64_t done, int64_t total);

typedef struct wt_mvm_options {
    int commands;              /* WT_MVM_LAYER_VALUES (pcg3) or WT_MVM_FITTING (cg9) */
    double fit_regularization; /* relative ε of the fitting step (WT_MVM_FITTING; cfg->cg9.fit_regularization) */
    int fit_sampling;          /* fitting sample points per subaperture side (cfg->cg9.fit_sampling; ≤ 0: 1) */
    double memory_budget;      /* bytes the build may hold at its peak; ≤ 0: no limit */
    int block;                 /* right-hand sides per solve block; ≤ 0: 256 */
    int part_index, part_count; /* part_count > 1: solve only the blocks b (rows b·block … of R and RÂ) with
                                   b % part_count == part_index, the other rows stay zero; every part does
                                   the same assembly and factorisation, so a block's rows are bit for bit
                                   those of a whole build (`mpirun wavetomo build`: one part per rank) */
    /* recon.predict: S_dᵀ, the adjoint of the layers' shift over the lead (wt_predict_shift_alloc with −lead), on the
     * tomography's layers. R = E S_d M⁻¹ Ãᵀ Ĉ⁻¹: the commands of the layers moved by their wind, as pcg3 and cg9 make
     * them; each command's layer weights Eᵀ e_i go through S_dᵀ (every layer that moves becomes dense). NULL: none. */
    struct wt_shift *predict_adjoint;
    wt_mvm_progress_fn progress; /* NULL: none */
    void *progress_user;
    /* Polled between solve blocks (seconds apart at E-ELT size, where the solve is most of a build of minutes):
     * non-zero stops the build with WT_ERR_INTERRUPTED and nothing returned. NULL: never. */
    int (*stop)(void *user);
    void *stop_user;
} wt_mvm_options;

/* commands = WT_MVM_LAYER_VALUES, no budget, block 256, no progress. */
void wt_mvm_options_default(wt_mvm_options *opt);

/* ---- the factorised normal matrix M = N + B Q Bᵀ ------------------------------------------------ */

typedef struct wt_mvm_normal wt_mvm_normal;

/* Assemble N and B, Q from the tomography's own operators, analyse, factorise, and precompute Z and K.
 * reserve: bytes the caller will hold alongside the factor (added to the budget checks).
 * keep_matrix: keep N after factorising so that wt_mvm_normal_apply works (tests); 0 frees it.
 * Uses opt->memory_budget, opt->progress and opt->block (the solve scratch). */
int wt_mvm_normal_alloc(wt_context *ctx, wt_tomography *t, const wt_mvm_options *opt, double reserve, int keep_matrix,
                        wt_mvm_normal **out);
void wt_mvm_normal_free(wt_mvm_normal *nm);
int64_t wt_mvm_normal_size(const wt_mvm_normal *nm);
int wt_mvm_normal_rank(const wt_mvm_normal *nm);
/* Statistics of the assembly and factorisation (the t_solve/t_fitting fields stay 0). */
void wt_mvm_normal_stats(const wt_mvm_normal *nm, wt_mvm_stats *stats);
/* y = M x = N x + B Q Bᵀ x (needs keep_matrix; WT_ERR_INVALID otherwise). Allocates nothing. */
int wt_mvm_normal_apply(const wt_mvm_normal *nm, const double *x, double *y);
/* X = M⁻¹ B for nrhs columns (column-major, leading dimension n; b and x may be the same array). */
int wt_mvm_normal_solve(wt_mvm_normal *nm, int64_t nrhs, const double *b, double *x);

/* ---- operators the builder assembles (exposed for tests) ----------------------------------------- */

/* Ã = Γ P W⁻¹ of every sensor, stacked in system slope order: nslopes x nunknowns, CSC. */
int wt_mvm_assemble_atilde(wt_context *ctx, wt_tomography *t, wt_sparse **out);

/* ---- the control matrix (the container and its apply: core/solve/mvm.h) ------------------------- */

/* Build R and RÂ for the tomography t (its variant's layers, α, τ, prior) with the command map of
 * opt->commands. Slope order: the system's (LGS first, then NGS; [s_x…, s_y…] per sensor); actuator
 * order: DM by DM, active actuators in grid-index order. WT_ERR_NOMEM when the estimated peak exceeds
 * opt->memory_budget (the message names both), WT_ERR_CONFIG for a pcg3 layer/DM mismatch,
 * WT_ERR_NUMERIC / WT_ERR_LIBRARY from the factorisations. */
int wt_mvm_build(wt_context *ctx, wt_tomography *t, const wt_mvm_options *opt, wt_mvm **out);

/* The MVM of the reconstruction variant `name` ("pcg3" or "cg9") of cfg, as `wavetomo build`, `compare`
 * and the tests make it: the tomography of cfg->pcg3 or cfg->cg9 with cfg's α, τ, wavelet and prior
 * (core/model/params.h), without its Jacobi diagonal (the factorisation is exact), the command map of the
 * variant (cg9: the fitting with the variant's ε and sampling), then wt_mvm_build with opt (NULL:
 * defaults; its commands and fitting fields are set here). stats.t_total covers it all. */
int wt_mvm_build_variant(wt_context *ctx, const wt_system *sys, const wt_config *cfg, const char *name,
                         const wt_mvm_options *opt, wt_mvm **out);

/* The same for a learned atmosphere model (sim/adapt.h's rebuild callback, which the drivers pass to a learning
 * MVM loop: sim cannot call this module): the variant's tomography with the model's r0 and natm-layer profile
 * (alt [m], frac) in place of the configuration's — when `sampled` (an estimate on a grid), its hats compressed onto
 * the variant's layers as PCG-3 and CG-9 take it (wt_profile_compress_hats) — the rest as wt_mvm_build_variant with
 * sys->cfg. Under recon.predict the predictor inside R moves each layer by the model's wind (vx, vy [m/s] per
 * altitude, compressed with the profile as PCG-3's and CG-9's set_model does: the same shift), over the
 * configuration's lead; vx, vy may be NULL only without prediction. user: a wt_mvm_rebuilder. */
typedef struct wt_mvm_rebuilder {
    wt_context *ctx;
    const wt_system *sys;          /* its configuration is the rest of the model */
    const char *variant;           /* "pcg3" or "cg9": the variant of the matrix the loop starts with */
    const wt_mvm_options *opt;     /* NULL: defaults */
} wt_mvm_rebuilder;
int wt_mvm_rebuild_model(void *user, double r0, int natm, const double *alt, const double *frac, const double *vx,
                         const double *vy, int sampled, wt_mvm **out);

#endif
