/* core/model/reconstructor.h: slopes → DM commands, the R of the POLC loop (paper §6.1, SPEC §5–§7).
 *
 *  pcg3: layers at the DM altitudes (and optionally between them), modified Jacobi PCG (recon.pcg3);
 *        commands = the reconstructed layer values at the active actuator positions, a layer between two
 *        DM altitudes split linearly between those DMs (wt_reconstructor_command_map; no fitting step).
 *  cg9:  layers at the atmosphere altitudes, CG (recon.cg9), then the fitting step by CG over the
 *        evaluation directions (recon.cg9.fit_iterations).
 *  none: commands 0 (the uncorrected baseline).
 *  mvm:  a stored control matrix (core/solve/mvm.h): a = R s_ol, one float32 GEMV through OpenBLAS
 *        (memory-bound: it streams n_act x n_slopes x 4 bytes per frame).
 * Both iterative variants warm-start from the previous frame's solution (recon.warm_start).
 */
#ifndef WT_RECONSTRUCTOR_H
#define WT_RECONSTRUCTOR_H

#include "fitting.h"
#include "precond.h"
#include "system.h"
#include "tomography.h"

enum { WT_RECON_NONE = 0, WT_RECON_PCG3 = 1, WT_RECON_CG9 = 2, WT_RECON_MVM = 3 };

struct wt_mvm;

typedef struct wt_reconstructor wt_reconstructor;

/* Parse "pcg3" | "cg9" | "none" | "mvm"; returns -1 for anything else. */
int wt_reconstructor_kind(const char *name);
const char *wt_reconstructor_name(int kind);

/* What an iterative reconstructor uses, filled from a configuration by wt_reconstructor_params_from_config
 * (core/model/params.c): the reconstructor reads no configuration. */
typedef struct wt_reconstructor_params {
    int warm_start;                         /* 1: each frame starts from the previous frame's solution */
    int iterations;                         /* (P)CG iterations per frame */
    double tolerance;                       /* relative residual to stop at [1]; 0: always `iterations` */
    int fit_iterations;                     /* cg9: CG iterations of the fitting step */
    const wt_recon_variant_config *variant; /* layers, grids, preconditioner (not owned; read at alloc only) */
    wt_tomography_params tomography;        /* α, τ, wavelet, prior, profile */
    wt_precond_params precond;              /* the tomography's preconditioner: kind, coarse levels */
    wt_fitting_params fitting;              /* cg9: ε and the sampling of the fitting */
    double predict_lead;                    /* the layers moved by their wind over this time [s]; 0: not */
    double atm_vx[WT_MAX_LAYERS], atm_vy[WT_MAX_LAYERS]; /* the model's wind per layer of tomography.atm_* [m/s] */
    /* with predict_lead > 0, integrator_gain > 0 (recon.predict_integrator = "layers"): the loop's integrator runs on
     * the layers, z_{t+d} = S_1 z_{t+d-1} + g S_d (phi_t - z_t), S_τ each layer moved by its wind over τ frames
     * (S_d over predict_lead), z_t the state whose commands are applied during frame t; apply returns the commands
     * of z_{t+d}, which the control applies as they are (wt_control_params.direct). Under frozen flow with the right
     * wind the state keeps up with the layers, so the integrator's averaging (1/g frames) adds no lag. */
    double integrator_gain;                 /* g in (0, 1]; 0: the integrator is the control's, on the commands */
    int integrator_delay;                   /* d ≥ 1 [frames] */
    double frame_s;                         /* a frame [s]: S_1 */
} wt_reconstructor_params;

/* recon.predict's shift of t's layers (core/op/shift.h): the model's wind (natm layers at alt [m] with Cn² fractions frac
 * and wind vx, vy [m/s]) compressed onto t's layers as their Cn² (wt_profile_compress), over `lead` seconds; a negative
 * lead moves them back, the adjoint of the positive one (the builder's predictive MVM, R = E S_d M⁻¹ Ãᵀ Ĉ⁻¹, applies
 * S_dᵀ to each command's layer weights). The reconstructors' own prediction is this shift (with the layers' winds of
 * wt_reconstructor_set_layer_wind when set). */
typedef struct wt_shift wt_shift;
int wt_predict_shift_alloc(wt_context *ctx, const wt_tomography *t, int natm, const double *alt, const double *frac,
                           const double *vx, const double *vy, double lead, wt_shift **out);

/* kind WT_RECON_NONE, PCG3 or CG9 (par is not read for NONE except warm_start, and may then be NULL). */
int wt_reconstructor_alloc(wt_context *ctx, const wt_system *sys, int kind, const wt_reconstructor_params *par,
                           wt_reconstructor **out);
/* The MVM reconstructor around a matrix built for sys (not owned: it must outlive the reconstructor). */
int wt_reconstructor_alloc_mvm(wt_context *ctx, const wt_system *sys, const struct wt_mvm *m, wt_reconstructor **out);
void wt_reconstructor_free(wt_reconstructor *r);
/* The pcg3 command map (also the MVM builder's), a = S φ: returns Sᵀ (layer points x active actuators,
 * CSC: column i holds actuator i's weights). A layer at a DM's altitude goes to that DM; a layer between
 * two DM altitudes is split linearly between them (wt_profile_bin_altitude, the prior's Cn² rule),
 * one outside their range goes to the end DM; each share is the layer's bilinear interpolation at the
 * actuator positions (one point with weight 1 when the actuator is a layer point). WT_ERR_CONFIG naming
 * the DM when a DM receives no layer or an actuator falls off a layer grid. */
struct wt_sparse;
int wt_reconstructor_command_map(wt_context *ctx, const wt_tomography *t, struct wt_sparse **out);

/* a = R s_ol: a has sys->nact entries (overwritten). Not thread-safe per object (warm-start state). With the
 * layers' integrator (wt_reconstructor_integrates) a is the commands of frame t + d instead, and each call is a frame. */
int wt_reconstructor_apply(wt_reconstructor *r, const double *s_ol, double *a);
/* Wall time [s] of the last apply's tomography and fitting parts; the last (P)CG result. */
void wt_reconstructor_last_times(const wt_reconstructor *r, double *tomography, double *fitting);
wt_pcg_result wt_reconstructor_last_pcg(const wt_reconstructor *r);
/* Bytes the reconstructor holds (tomography, preconditioner, fitting, command map, its vectors; for mvm
 * the matrices), for reports. */
double wt_reconstructor_bytes(const wt_reconstructor *r);
/* The tomography object and its preconditioner (NULL for none and mvm). */
wt_tomography *wt_reconstructor_tomography(wt_reconstructor *r);
wt_precond *wt_reconstructor_precond(wt_reconstructor *r);
/* The fitting (cg9; NULL otherwise). */
const wt_fitting *wt_reconstructor_fitting(const wt_reconstructor *r);
/* A new atmosphere model for pcg3 / cg9 (SPEC §12 "Updates": the loop that learns its atmosphere takes it at the
 * next frame): r0 [m], the natm-layer Cn² profile (altitudes [m] increasing, fractions ≥ 0) and, for prediction, the
 * wind of each layer (vx, vy [m/s]; NULL: kept when the layers are the same, else zero). The tomography's priors,
 * model error and noise weights (wt_tomography_set_profile), the preconditioner rebuilt, the prediction's shifts.
 * The warm start stays. On error the reconstructor keeps its old model. WT_ERR_INVALID for mvm and none. */
int wt_reconstructor_set_model(wt_reconstructor *r, double r0, int natm, const double *alt, const double *frac,
                               const double *vx, const double *vy);
/* The noise weights C_E of pcg3 / cg9 rebuilt from the system's sensors as they are now (a diffractive LGS reference
 * rebuilt in the loop, core/model/sensing.h), the preconditioner with them; the model and the warm start stay.
 * WT_OK and nothing done for mvm and none (an MVM keeps the C_E it was built with). */
int wt_reconstructor_refresh_noise(wt_reconstructor *r);
/* Wall time [s] of the last set_model's parts: the tomography's model, the preconditioner (and the shifts). */
void wt_reconstructor_last_update_times(const wt_reconstructor *r, double *model, double *precond);
/* The reconstructed layers of the last apply, φ = W⁻¹ c (wt_tomography_layers: layer by layer on the grids of
 * wt_tomography_layer_grid, from wt_tomography_layer_offset), before any prediction shift: the pseudo-open-loop
 * estimate of the layers (read-only; pcg3 and cg9 only, valid until the next apply). */
const double *wt_reconstructor_layers(const wt_reconstructor *r);
/* The wind [m/s] of each of the tomography's layers that prediction moves them by: the model's winds compressed onto
 * the layers (SPEC §12), or those set by wt_reconstructor_set_layer_wind. vx, vy: wt_tomography_nlayers values. */
void wt_reconstructor_layer_wind(const wt_reconstructor *r, double *vx, double *vy);
/* The wind of each reconstruction layer directly (vx, vy [m/s], one per layer; NULL: back to the model's compressed
 * winds), e.g. measured on the layers themselves (core/model/wind_align.h); it stays through later set_model calls.
 * Prediction's shifts are rebuilt (refused, the old winds kept, when a layer would move by a quarter of its grid).
 * WT_ERR_INVALID for mvm and none. */
int wt_reconstructor_set_layer_wind(wt_reconstructor *r, const double *vx, const double *vy);
/* Forget the warm-start state (the next apply starts from zero). */
void wt_reconstructor_reset(wt_reconstructor *r);
/* 1 when apply runs the loop's integrator on the layers (wt_reconstructor_params.integrator_gain): its result is the
 * commands of frame t + d, to be applied as they are. */
int wt_reconstructor_integrates(const wt_reconstructor *r);
/* The layers' integrator back to its start: every state 0, as the control's queue of commands (no-op without it). */
void wt_reconstructor_reset_integrator(wt_reconstructor *r);

#endif
