/* core/model/precond.h: the preconditioners of the tomography's PCG (paper §6.1; docs/design.md
 * "Preconditioner with the NGS low-rank term", "Coarse block of the preconditioner").
 *
 *   none        P = I                                   plain CG
 *   jacobi      P = J = diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D       the paper's modified Jacobi, exact diagonal
 *   jacobi_ngs  P = J + G Ĉ⁻¹_NGS Gᵀ                     plus the exact rank-r NGS term (Woodbury)
 *   coarse_ngs  P = B + G Ĉ⁻¹_NGS Gᵀ                     B = J with the coarse wavelet coefficients of all
 *                                                       layers as one exact block of the LGS + prior part of M
 *   multilevel  P = B_ml + G Ĉ⁻¹_NGS Gᵀ                  B_ml = coarse_ngs's exact coarse block, and below it,
 *                                                       per detail level, orientation and position, the
 *                                                       L x L block of the L layers' coefficients there
 *                                                       (docs/design.md "Multilevel preconditioner")
 *   fourier     P = B_F + G Ĉ⁻¹_NGS Gᵀ                    B_F = the exact block of the LGS + prior part of M on
 *                                                       the coarse space (each layer's coarsest scaling
 *                                                       functions) and, on its complement, the filter
 *                                                       F⁻¹ diag(1/λ_max A(k)) F: each spatial frequency of
 *                                                       every layer scaled by the inverse of the largest
 *                                                       eigenvalue of the L x L symbol A(k) of that part (the
 *                                                       layers' common mode); layers of one n x n grid, the
 *                                                       tomography's unknowns the layers' values
 *                                                       (wt_tomography_space: the full prior) (docs/design.md
 *                                                       "Fourier filter")
 *
 * where G = [Ãᵀ e_k] over the r NGS slopes. Every kind is symmetric positive definite; the PCG applies
 * z = P⁻¹ r. The preconditioner is built from a finished tomography through its public operators (the
 * operator's file knows none of them: a new kind grows this module only); the tomography's solve takes it
 * as the callback of core/solve/pcg.h (wt_precond_pcg).
 *
 * Set-up (wt_precond_alloc) allocates and applies M and its parts through the tomography's own workspace
 * (not concurrently with another use of that tomography); wt_precond_apply allocates nothing, runs OpenMP
 * regions on the tomography's thread count, and writes scratch inside the object: one caller at a time.
 */
#ifndef WT_PRECOND_H
#define WT_PRECOND_H

#include "../solve/pcg.h"
#include "tomography.h"

/* The kinds, in the order of the configuration's recon.<variant>.preconditioner list
 * ("none|jacobi|jacobi_ngs|coarse_ngs|multilevel|fourier": the value wt_recon_variant_config.preconditioner holds). */
enum { WT_PRECOND_NONE = 0, WT_PRECOND_JACOBI = 1, WT_PRECOND_JACOBI_NGS = 2, WT_PRECOND_COARSE_NGS = 3,
       WT_PRECOND_MULTILEVEL = 4, WT_PRECOND_FOURIER = 5, WT_PRECOND_NKINDS = 6 };

typedef struct wt_precond wt_precond;

typedef struct wt_precond_params {
    int kind;          /* WT_PRECOND_* */
    int coarse_levels; /* coarse_ngs, multilevel, fourier: detail levels in the coarse block besides the
                          scaling coefficients (fourier: the scaling functions of that many levels finer) [-];
                          fourier only: < 0 = no coarse block (the filter alone) */
    int single;        /* coarse_ngs: its two stored matrices (the coarse block's inverse, the NGS term's Y) in
                          float, applied in double (recon.<variant>.operator_precision = "fp32") */
    int updatable;     /* keep the parts that wt_precond_update needs (jacobi … coarse_ngs, fourier; set when the
                          reconstructor's atmosphere model will change: learned, or the oracle of a changing night) */
} wt_precond_params;

/* "none", "jacobi", "jacobi_ngs", "coarse_ngs", "multilevel", "fourier"; NULL for an unknown kind. */
const char *wt_precond_kind_name(int kind);
/* The kind of a name, -1 for anything else. */
int wt_precond_kind(const char *name);

/* Build the preconditioner of kind par->kind for the tomography t (not owned; must outlive the object).
 * Cost: jacobi a forward apply per layer and colour (coloured probing), the NGS term r applies of the adjoint,
 * coarse_ngs nc applies of M (the longest at E-ELT size, nc = 384; docs/results.md has the times), multilevel that
 * and L forward applies per colour of every detail level below the coarse block (~the cost of the Jacobi probing),
 * fourier L applies and L² FFTs.
 * WT_ERR_INVALID for an unknown kind, a negative coarse_levels (but fourier's), fourier on wavelet
 * coefficients or another kind but none on the layers' values (wt_tomography_space); WT_ERR_CONFIG when the
 * coarse block would exceed 4096 coefficients or (fourier) the layers are not on one grid; WT_ERR_NUMERIC
 * when a block is not positive definite. */
int wt_precond_alloc(wt_context *ctx, wt_tomography *t, const wt_precond_params *par, wt_precond **out);
void wt_precond_free(wt_precond *p);
/* The tomography's atmosphere model changed (wt_tomography_set_profile): P for the new model from the parts kept at
 * set-up (par->updatable), without applying M again (docs/design.md "A preconditioner for a new model"):
 *   M̃ = Σ_LGS s_m M̃_m + Σ_l c_l P_l,   s_m = the LGS's short-axis noise precision now / then (exact for the
 *   isotropic part of its weights: σ²_t = κσ² + σ²_e scales them whole), c_l = the layer's prior Cn² then / now
 *   (exact: a new model rescales every prior, wt_prior_rescale),
 * then the kind's own steps on M̃'s entries: J⁻¹, the coarse block's factor or inverse, the Fourier symbol's largest
 * eigenvalue per frequency, the NGS term's Y and K. A model whose LGS noise weights do not change (no layer-binning
 * model error) gives the preconditioner a rebuild would, to rounding; one that changes σ²_e keeps the elongation
 * term's share of set-up. On failure p is unchanged. WT_ERR_INVALID for a kind without parts (none, multilevel) or
 * one built without them (wt_precond_updatable). */
int wt_precond_update(wt_precond *p);
/* 1 when wt_precond_update can run on p */
int wt_precond_updatable(const wt_precond *p);

/* z = P⁻¹ r (n = wt_tomography_nunknowns values each; z overwritten, r and z distinct). */
void wt_precond_apply(const wt_precond *p, const double *r, double *z);
/* The same as the callback of core/solve/pcg.h (user: the wt_precond). */
void wt_precond_apply_cb(void *user, const double *r, double *z);
/* p as the tomography's solve takes it: {wt_precond_apply_cb, p}, or {NULL, NULL} for none and for
 * p = NULL (plain CG: the iterates P = I would give, without the copy). */
wt_pcg_precond wt_precond_pcg(const wt_precond *p);

int wt_precond_kind_of(const wt_precond *p);
const char *wt_precond_name(const wt_precond *p);
/* J⁻¹ (n values), the inverse modified Jacobi diagonal every kind but none is built on; NULL for none. */
const double *wt_precond_jacobi_inverse(const wt_precond *p);
/* Sizes of the parts: the rank r of the NGS term (0: none), the coefficients of the coarse block, and the
 * multilevel kind's layer blocks (0 for the other kinds). */
int wt_precond_rank(const wt_precond *p);
int wt_precond_coarse_size(const wt_precond *p);
int64_t wt_precond_nblocks(const wt_precond *p);
/* Block b of the multilevel kind (0 <= b < wt_precond_nblocks): its size q (<= the layers), and when idx /
 * block are not NULL, its q unknowns' indices (increasing) and the q x q block of B_ml it inverts (column-
 * major; the lower triangle of L Lᵀ, recomputed from the stored factor). For tests; -1 for a bad b. */
int wt_precond_block(const wt_precond *p, int64_t b, int64_t *idx, double *block);
/* Bytes the object holds (for reports); p = NULL gives 0. */
double wt_precond_bytes(const wt_precond *p);

#endif
