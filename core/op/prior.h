/* core/op/prior.h: the diagonal wavelet prior D_ℓ of one reconstruction layer (SPEC §6, paper
 * eq. REG_WAV_penalty_discr).
 *
 * Paper form: D_λλ = (1/c_ℓ)(L0^(-11/3) + κ_λ^(11/3)) for detail coefficients, κ_λ [cycles/m] the
 * centre of the basis function's frequency band: 1/(√2 δ 2^l) for the x- and y-details of level l
 * (l = 1 finest; the paper's j = J − l), 1/(δ 2^l) for the diagonal ones — diagonal details carry ~3.7x
 * less variance than x/y details of the same level, so one κ per level cannot match both within a
 * factor 2. The approximation coefficients take their exact variance 1/(W C_φ Wᵀ)_λλ (no single κ
 * represents them for every J). c_ℓ is the geometric-mean fit over the 3J detail blocks of the exact
 * variances, so that α = 1 is the physical von Kármán prior (D⁻¹ within a factor 2 of the exact
 * variance at every level and orientation for the preset grids; tests/test_prior.c).
 * Exact form: D_λλ = 1 / (W C_φ Wᵀ)_λλ, evaluated by FFT for each level and orientation (periodic
 * stationarity makes it constant within a level and orientation).
 * Full form (not diagonal, a reference for the diagonal forms): the prior term is φᵀ C_φ⁻¹ φ with the
 * periodic stationary covariance itself, applied by FFT (wt_prior_apply_full: C_φ⁻¹ has the eigenvalues
 * L²/(n² Φ(κ_k)) on the DFT modes); its diagonal in the wavelet basis, diag(W C_φ⁻¹ Wᵀ), is what
 * wt_prior_diag returns (the Jacobi preconditioners read it).
 *
 * Von Kármán OPD spectrum of a layer with Cn² fraction f: Φ(κ) = (λ0/2π)² 0.0229 f r0^(-5/3)
 * (κ² + L0^(-2))^(-11/6), κ in cycles/m, λ0 = 500 nm (SPEC §2). Units of D: 1/m² (coefficients in m).
 */
#ifndef WT_PRIOR_H
#define WT_PRIOR_H

#include "../base/base.h"
#include "../la/fft.h"
#include "wavelet.h"

enum { WT_PRIOR_PAPER = 0, WT_PRIOR_EXACT = 1, WT_PRIOR_FULL = 4 };
/* Flag or-ed into kind: the variances are those of grid SAMPLES of the continuous screen, whose
 * spectrum carries the power above the grid's Nyquist frequency folded back (aliased):
 *   Φ_δ(κ) = Σ_{a,b} Φ(κ + (a, b)/δ),  |a|, |b| ≤ 4 (the rest of the sum is below 0.5 % at the finest level).
 * Without it the finest level's variance is the band-limited one, ~0.4 of what simulated screens show. */
enum { WT_PRIOR_ALIASED = 2 };

typedef struct wt_prior wt_prior;

/* w: the layer's wavelet plan (n, order, J); spacing δ [m]; r0 [m] at 500 nm of the whole atmosphere and
 * the layer's Cn² fraction (> 0); L0 [m]. fft: how WT_PRIOR_FULL plans its transforms (core/la/fft.h: NULL
 * = FFTW_ESTIMATE; a wisdom without this n x n pair is WT_ERR_CONFIG); the other kinds ignore it. */
int wt_prior_alloc(wt_context *ctx, const wt_wavelet *w, double spacing, double r0, double fraction, double L0,
                   int kind, wt_fft_wisdom *fft, wt_prior **out);
void wt_prior_free(wt_prior *p);
/* D_λλ for the n*n coefficients in the layout of core/op/wavelet.h [1/m²]; for WT_PRIOR_FULL the
 * diagonal of W C_φ⁻¹ Wᵀ. */
const double *wt_prior_diag(const wt_prior *p);
int wt_prior_kind(const wt_prior *p); /* WT_PRIOR_PAPER, WT_PRIOR_EXACT or WT_PRIOR_FULL (without the aliasing flag) */
/* WT_PRIOR_FULL only: out = alpha C_φ⁻¹ phi on the layer grid (n*n values in the layout of wt_grid; phi
 * and out distinct) [1/m² · m]. Allocates nothing; thread-safe with a work array of wt_prior_work_size
 * doubles per concurrent call. */
void wt_prior_apply_full(const wt_prior *p, double alpha, const double *phi, double *out, double *work);
size_t wt_prior_work_size(const wt_prior *p);
/* Exact variance (W C_φ Wᵀ)_λλ [m²] of a coefficient of level (1 … J+1) and orientation (0 … 3). */
double wt_prior_level_variance(const wt_prior *p, int level, int orient);
/* The fitted normalisation c_ℓ. */
double wt_prior_scale(const wt_prior *p);

/* The same prior for a layer of strength factor × f r0^(−5/3) (L0 unchanged): every variance times factor, D,
 * C_φ⁻¹ and its diagonal divided by it (the spectrum is linear in f r0^(−5/3); equal to a new wt_prior_alloc's
 * values to rounding). factor must be finite and > 0 (anything else is ignored). Allocates nothing. */
void wt_prior_rescale(wt_prior *p, double factor);

/* Von Kármán OPD power spectral density Φ(κ) [m² · m²] (per cycles/m squared). */
double wt_von_karman_psd(double kappa, double r0, double fraction, double L0);

#endif
