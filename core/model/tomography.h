/* core/model/tomography.h: the wavelet MAP tomography of paper §6.1 (SPEC §6).
 *
 *   M c = Σ_m Ã_mᵀ Ĉ_m⁻¹ Ã_m c + α D c,     b = Σ_m Ã_mᵀ Ĉ_m⁻¹ s_m          (paper eq. eqn_lse)
 *   Ã_m = Γ_m P_m W⁻¹,  Ĉ_m⁻¹ = (I − T) C̃_m⁻¹ (I − T) for LGS, C̃_m⁻¹ for NGS  (eq. widehatc)
 *
 * The operator, its right-hand side and the (P)CG solve; the preconditioners (the modified Jacobi
 * J = diag(Σ_LGS Ã_mᵀ C̃_m⁻¹ Ã_m) + α D and those built on it) are core/model/precond.h's, built from this
 * object's public operators and handed to the solve as a callback.
 *
 * Reconstruction layers: one per altitude of the chosen variant (recon.pcg3 or recon.cg9), each a
 * periodic n x n grid of spacing δ (wt_grid_layer) with its own DWT plan and prior D_ℓ. The prior needs
 * the Cn² fraction of each reconstruction layer: the model's profile (wt_tomography_params: the truth's for the
 * oracle, the user's for a given model) compressed onto the reconstruction altitudes (core/model/profile.h,
 * SPEC §12); a floor of WT_PRIOR_FRACTION_FLOOR keeps a layer that receives nothing regularised.
 * Unknowns: wavelet coefficients of the layers, concatenated layer by layer (Mallat layout each); or, with
 * wt_tomography_params.space (the fourier preconditioner's, which needs the full prior), the layers' values
 * themselves, φ = W⁻¹ c: M_φ = W⁻¹ M W, b_φ = W⁻¹ b. W is orthogonal, so (P)CG on (M_φ, W⁻¹ P⁻¹ W) takes the
 * same steps as on (M, P⁻¹) in exact arithmetic; the operator skips its DWT pair per layer (the full prior and
 * the data term both act on φ), the preconditioner its own.
 *
 * Workspaces (GSL's habit): wt_tomography_apply_ws takes a const operator and a caller-owned
 * wt_tomography_work, so two threads with one workspace each can apply one operator at once. The other
 * calls (solve, rhs, slopes, layers, the workspace-less apply) use the object's own workspace and are
 * not thread-safe per object. All run OpenMP regions inside. Set-up and wt_tomography_work_alloc
 * allocate; apply, rhs and solve allocate nothing.
 */
#ifndef WT_TOMOGRAPHY_H
#define WT_TOMOGRAPHY_H

#include "../la/fft.h"
#include "../op/grid.h"
#include "../op/wavelet.h"
#include "../solve/pcg.h"
#include "stack.h"
#include "system.h"

typedef struct wt_tomography wt_tomography;

/* The least Cn² fraction a reconstruction layer's prior is given: a layer that the profile leaves (nearly) empty
 * would have an infinite prior weight, a layer the data could not move. */
#define WT_PRIOR_FRACTION_FLOOR 1e-3

/* What the MAP problem takes besides the system and the variant's layers: passed in, never looked up
 * (wt_tomography_params_from_config in core/model/params.h fills it from a configuration). */
typedef struct wt_tomography_params {
    double alpha;          /* prior weight α */
    double tau;            /* elongation weight τ of the reconstructor's noise model C̃ */
    int wavelet_order;     /* Daubechies order N (2N taps) */
    int wavelet_levels;    /* J */
    int prior_flags;       /* WT_PRIOR_ALIASED or 0 (core/op/prior.h); the kind is the variant's prior */
    double r0;             /* Fried parameter at 500 nm [m] */
    double L0;             /* outer scale [m] */
    int natm;              /* the model's Cn² profile (SPEC §12: the reconstructor's atmosphere, the truth's only
                              for the oracle), compressed onto the reconstruction layers: */
    double atm_altitude[WT_MAX_LAYERS]; /* [m] */
    double atm_fraction[WT_MAX_LAYERS]; /* fractions, sum 1 */
    int model_error;       /* 1: LGS σ² plus the layer-binning model error (recon.model_error) */
    int subgrid_error;     /* 1: the LGS κσ² floored at the slope variance beyond the layer grids' Nyquist
                              (recon.subgrid_error) */
    int lgs_focus_removal; /* 1: the LGS weights remove each LGS's focus as well as tip-tilt (recon.lgs_focus_removal);
                              2: only the focus common to all LGS (recon.lgs_focus_mode = "common"): the
                              focus (1) or the LGS's common focus (2) then comes from the NGS, of which one at least
                              must measure it (2x2) */
    double loop_noise_gain; /* κ = Σh², the integrator's noise gain (wt_noise_loop_gain): with the variant's
                               loop_noise_average the sensors' σ² is multiplied by it, the model error not */
    const char *source;    /* where the parameters came from, for messages (the configuration file) */
    int space;             /* 1: the unknowns are the layers' values (needs the full prior), 0: wavelet coefficients */
    const char *fft_wisdom; /* NULL or "": FFTW_ESTIMATE; else the FFTW wisdom file the full prior's and the fourier
                               preconditioner's transforms are planned from (recon.fft_wisdom; core/la/fft.h) */
    const char *fft_wisdom_sha256; /* NULL, "" or the SHA-256 (hex) the file must still have */
} wt_tomography_params;

/* var: the reconstructor variant (cfg->pcg3 or cfg->cg9): layers, iterations, tolerance; par: α,
 * τ, the wavelet, the prior. A layer grid that does not cover some sensor's footprint is a
 * WT_ERR_CONFIG naming the variant, the layer and the sensor. */
int wt_tomography_alloc(wt_context *ctx, const wt_system *sys, const wt_recon_variant_config *var,
                        const char *variant_name, const wt_tomography_params *par, wt_tomography **out);
void wt_tomography_free(wt_tomography *t);

int64_t wt_tomography_nunknowns(const wt_tomography *t);
int wt_tomography_nlayers(const wt_tomography *t);
const wt_grid *wt_tomography_layer_grid(const wt_tomography *t, int l);
double wt_tomography_layer_altitude(const wt_tomography *t, int l);
double wt_tomography_layer_fraction(const wt_tomography *t, int l);
/* The layer-binning model error added to sensor m's noise variance per axis [rad²] (recon.model_error). */
double wt_tomography_model_error(const wt_tomography *t, int m);
/* The sub-grid model error of sensor m per axis [rad²] (recon.subgrid_error), the floor of its measurement noise in
 * the weight: C̃ uses max(κσ², σ²_g) + σ²_e (core/model/tomography_model.c); 0 when off and for the NGS. */
double wt_tomography_subgrid_error(const wt_tomography *t, int m);
/* σ²_g of every sensor [rad² per axis; 0 for the NGS] for a profile of natm layers (r0 at 500 nm, altitudes [m],
 * fractions summing to 1) on this tomography's layers, whether recon.subgrid_error is on or not (`wavetomo info`). */
void wt_tomography_subgrid_variances(const wt_tomography *t, double r0, int natm, const double *alt, const double *frac,
                                     double *var);
/* Sensor m's short-axis noise precision Σ_i 1/λ_min(C̃_i) over its subapertures [rad⁻²], C̃_i its weight's 2x2 block
 * before the tip-tilt removal: what a new model's σ²_e scales (wt_precond_update). */
double wt_tomography_lgs_precision(const wt_tomography *t, int m);
int64_t wt_tomography_layer_offset(const wt_tomography *t, int l);
const wt_wavelet *wt_tomography_wavelet(const wt_tomography *t, int l);
/* The operators the tomography is built from (for the MVM builder, which assembles the same ones):
 * the projection of layer l onto sensor m's Fried corner grid, and sensor m's noise model (τ as
 * configured; Ĉ⁻¹ with the tip-tilt removal for LGS). */
const struct wt_projection *wt_tomography_projection(const wt_tomography *t, int m, int l);
const struct wt_noise *wt_tomography_noise(const wt_tomography *t, int m);
const wt_system *wt_tomography_system(const wt_tomography *t);
/* recon.lgs_focus_mode = "common": the LGS weight is the sensors' own (wt_tomography_noise) plus a term coupling
 * the LGS (core/model/tomography_focus.c). weight_common adds that term of Ĉ⁻¹ x to y (x, y: every sensor's slopes;
 * nothing without the mode); common_focus is the stacked unit focus patterns (e_1, …, e_n) over the LGS's slopes
 * (the first of the slope vector; f_c = that / √n), or NULL without the mode. */
void wt_tomography_weight_common(const wt_tomography *t, const double *x, double *y);
const double *wt_tomography_common_focus(const wt_tomography *t);
/* α D (ncoef values). */
const double *wt_tomography_alpha_prior(const wt_tomography *t);
/* 1 when the prior is the full (non-diagonal) form: alpha_prior is then only its diagonal, and no sparse
 * assembly of the operator (the MVM) can hold it. */
int wt_tomography_full_prior(const wt_tomography *t);
/* 1 when the unknowns are the layers' values (wt_tomography_params.space), 0 for wavelet coefficients */
int wt_tomography_space(const wt_tomography *t);
/* The wisdom the tomography's transforms were planned from (NULL: FFTW_ESTIMATE), for the preconditioner's. */
wt_fft_wisdom *wt_tomography_fft(const wt_tomography *t);
const char *wt_tomography_variant(const wt_tomography *t); /* "pcg3" or "cg9" (as allocated) */
/* y += the prior part of M times c, for c nonzero in layer l only (y: that layer's n_l coefficients, c the
 * same): α D c, or with the full prior α W C_φ⁻¹ Wᵀ c. Set-up use (the preconditioners' exact blocks): it
 * uses the object's own workspace. */
void wt_tomography_prior_apply_layer(wt_tomography *t, int l, const double *c, double *y);
/* The same on a caller's work array of wt_tomography_prior_layer_work(t) doubles: thread-safe, one array
 * per concurrent call (the MVM builder forms the dense prior blocks column by column on its threads). */
void wt_tomography_prior_apply_layer_ws(const wt_tomography *t, int l, const double *c, double *y, double *ws);
size_t wt_tomography_prior_layer_work(const wt_tomography *t);
/* The OpenMP threads the applies run on (1 below ~16k unknowns, where a parallel region does not pay). */
int wt_tomography_threads(const wt_tomography *t);

/* Where an apply's time goes (bench: a frame's profile). The stages of M (and of the right-hand side, which
 * runs the adjoint's two), each one parallel region: */
enum {
    WT_TOMO_STAGE_INVERSE_DWT = 0,     /* φ = W⁻¹ c per layer (none in space) */
    WT_TOMO_STAGE_FORWARD = 1,         /* Γ P φ per sensor, and the full prior's FFTs per layer */
    WT_TOMO_STAGE_ADJOINT_SENSORS = 2, /* per sensor: the noise weight, Γᵀ, Pᵀ into its group's accumulator */
    WT_TOMO_STAGE_ADJOINT_LAYERS = 3,  /* per layer: the groups' sum, the prior's term, W */
    WT_TOMO_STAGE_PRECOND = 4,         /* the solves' preconditioner applies (their own regions; wall only) */
    WT_TOMO_STAGE_SOLVE = 5,           /* whole wt_tomography_solve* calls, the stages above included (wall only):
                                          what they leave is the PCG's vector work and the slopes' check */
    WT_TOMO_NSTAGES = 6
};
typedef struct wt_tomography_stage {
    long calls;
    double wall;               /* summed wall time of the stage's region, on the calling thread [s] */
    double busy_min, busy_max; /* the least and most busy thread's summed time inside it [s]; < 0: not
                                  measured (a region outside this module: the paper prior's forward, the
                                  preconditioner, the solve) */
} wt_tomography_stage;
/* Zero the stages and time every later apply on the object's own workspace (wt_tomography_apply, _rhs,
 * _solve, _solve_continue; not _layers or _slopes; two clock reads per region and thread, the same results)
 * until wt_tomography_profile_stop, which copies them to out (WT_TOMO_NSTAGES entries) and stops timing. */
int wt_tomography_profile_start(wt_tomography *t);
void wt_tomography_profile_stop(wt_tomography *t, wt_tomography_stage *out);
/* "inverse DWT", "forward", ..., "solve" (NULL past the last) */
const char *wt_tomography_stage_name(int k);

/* What one application of M writes: one per concurrent caller. Allocates n (2 + WT_GROUPS) + S·ncg +
 * 2 nslopes + nthreads·wsize doubles; _free(NULL) is a no-op. */
typedef struct wt_tomography_work wt_tomography_work;
int wt_tomography_work_alloc(const wt_tomography *t, wt_tomography_work **out);
void wt_tomography_work_free(wt_tomography_work *w);

/* The operators accumulate, y ← y + α A x, as core/op does. */
/* y ← y + α M c with the caller's workspace w (t is not modified; the result is bit-identical to
 * wt_tomography_apply's) */
void wt_tomography_apply_ws(const wt_tomography *t, wt_tomography_work *w, double alpha, const double *c, double *y);
/* y ← y + α M c with the object's own workspace (one caller at a time) */
void wt_tomography_apply(wt_tomography *t, double alpha, const double *c, double *y);
/* s ← s + α Ã c: the model slopes of every sensor (system order) */
void wt_tomography_slopes(wt_tomography *t, double alpha, const double *c, double *s);
/* b ← b + α Σ Ã_mᵀ Ĉ_m⁻¹ s_m (s: all slopes, system order) */
void wt_tomography_rhs(wt_tomography *t, double alpha, const double *s, double *b);
/* Solve M c = b(s) by PCG with the preconditioner P (wt_precond_pcg of core/model/precond.h; {NULL, NULL}:
 * plain CG), warm-started from c. max_iter / rtol override the variant's when ≥ 0. history: NULL or
 * max_iter + 1 doubles. */
int wt_tomography_solve(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter, double rtol,
                        double *history, wt_pcg_result *res);
/* wt_tomography_solve continuing the previous solve on t (the reconstructor's warm start): c must hold
 * that solve's result, unchanged. M c is then the previous right-hand side minus the previous recursive
 * residual (wt_pcg_solve_rhs), which saves the initial apply of M: 4 + 1 → 4 applies in a PCG-3 frame.
 * Differs from wt_tomography_solve by the recursive residual's rounding drift only (not the same bits).
 * The first solve, and one after an error, applies M as wt_tomography_solve does. */
int wt_tomography_solve_continue(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter,
                                 double rtol, double *history, wt_pcg_result *res);
/* Spatial layers φ = W⁻¹ c (same length as c, layer by layer on their grids). */
void wt_tomography_layers(wt_tomography *t, const double *c, double *phi);

/* A new atmosphere model (SPEC §12 "Updates": the loop that learns its atmosphere): r0 [m] and the natm-layer Cn²
 * profile (altitudes [m] increasing, fractions ≥ 0, normalised here), compressed onto the layers as at set-up; the
 * outer scale stays. Rescales every layer's prior to its new strength f_ℓ r0^(−5/3) (exact: the von Kármán
 * spectrum is linear in it at fixed L0), recomputes the layer-binning model error (recon.model_error; a unit layer
 * is drawn once per new altitude and kept, its term linear in f r0^(−5/3)) and the sensors' noise weights. The
 * next solve starts from M c (not the previous residual). A preconditioner built on the old model must be rebuilt
 * (wt_precond_alloc). On error the object is unchanged. Allocates (the noise models; a new altitude's draws). */
int wt_tomography_set_profile(wt_tomography *t, double r0, int natm, const double *alt, const double *frac);
/* The sensors' noise weights rebuilt from the system's sensors as they are now (a diffractive sensor whose
 * reference, so its covariance C_E, was rebuilt: core/model/sensing.h), with the model's σ²_e, κ and τ as they are;
 * core/model/tomography_noise.c. The next solve starts from M c; a preconditioner must be rebuilt. Allocates the
 * noise models. On error (out of memory, a block not positive definite) some sensors may keep their old weights. */
int wt_tomography_refresh_noise(wt_tomography *t);
double wt_tomography_r0(const wt_tomography *t);

/* Bytes the object holds (operators, prior, workspace; the preconditioner's are wt_precond_bytes): for reports. */
double wt_tomography_bytes(const wt_tomography *t);

/* Work per application of M: floating-point operations and bytes moved (estimates for reports). */
void wt_tomography_cost(const wt_tomography *t, double *flops, double *bytes);



/* Non-zeros of the sparse operators of each sensor m: Γ_m P_m (slopes x layer points, all layers) and
 * Ã_m = Γ_m P_m W⁻¹ (slopes x coefficients, counted symbolically, never stored). Arrays of nsensors. */
int wt_tomography_count_nnz(wt_tomography *t, int64_t *nnz_gp, int64_t *nnz_a);

#endif
