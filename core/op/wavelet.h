/* core/op/wavelet.h: orthonormal periodic 2-D separable Daubechies DWT (W) and its inverse W⁻¹ = Wᵀ
 * (SPEC §6, paper §5: c = W φ, φ = W⁻¹ c).
 *
 * A plan is made once for an n x n grid (n a power of two), an order N (Daubechies-N, 2N taps,
 * N = 1 is Haar) and J levels (1 <= J <= log2 n). Applying it allocates nothing and is thread-safe:
 * the caller passes a workspace of wt_wavelet_work_size() doubles.
 *
 * Coefficient layout (Mallat): after J levels the n x n array holds the approximation block
 * [0, n/2^J)² and, for each level l = 1 (finest) … J (coarsest), three detail blocks of side
 * m = n/2^l: orientation 1 (x-detail: high-pass along x, low-pass along y) at ix ∈ [m, 2m), iy ∈ [0, m);
 * orientation 2 (y-detail) at ix ∈ [0, m), iy ∈ [m, 2m); orientation 3 (diagonal) at [m, 2m)².
 * Index = ix + n*iy, as every wt_grid.
 */
#ifndef WT_WAVELET_H
#define WT_WAVELET_H

#include "../base/base.h"

#define WT_WAVELET_MAX_ORDER 10

typedef struct wt_wavelet wt_wavelet;

/* The Daubechies-N low-pass (scaling) filter h[0..2N-1], Σh = √2, Σ h_k h_{k+2m} = δ_m,
 * N vanishing moments of the wavelet. Computed from the spectral factorisation (minimum phase).
 * h must hold 2*order doubles. */
int wt_wavelet_filter(wt_context *ctx, int order, double *h);

int wt_wavelet_alloc(wt_context *ctx, int n, int order, int levels, wt_wavelet **out);
void wt_wavelet_free(wt_wavelet *w);

int wt_wavelet_n(const wt_wavelet *w);
int wt_wavelet_levels(const wt_wavelet *w);
int wt_wavelet_order(const wt_wavelet *w);
/* Doubles of workspace the transforms need. */
size_t wt_wavelet_work_size(const wt_wavelet *w);

/* c = W x (n*n values each; x and c may be the same array). */
void wt_wavelet_forward(const wt_wavelet *w, const double *x, double *c, double *work);
/* x = W⁻¹ c = Wᵀ c (x and c may be the same array). */
void wt_wavelet_inverse(const wt_wavelet *w, const double *c, double *x, double *work);

/* Single precision (the tomography's fp32 operator): the same transforms on floats with the filters rounded to float
 * (~1e-7 relative per level; not the double forms' bits); work: wt_wavelet_work_size floats. */
void wt_wavelet_forward_f32(const wt_wavelet *w, const float *x, float *c, float *work);
void wt_wavelet_inverse_f32(const wt_wavelet *w, const float *c, float *x, float *work);
/* wt_wavelet_inverse_f32 of the double coefficients c, each rounded to float as it is read (the same bits as rounding
 * c first), without a float copy of c; x64 (or NULL): x in double as well, written row by row as the last level
 * makes it (the fp32 operator's layers for the full prior's FFTs). */
void wt_wavelet_inverse_f32_of64(const wt_wavelet *w, const double *c, float *x, double *x64, float *work);

/* Level and orientation of the coefficient at (ix, iy): *level = 1 … J for details (1 finest),
 * J + 1 for the approximation block; *orient = 0 approximation, 1 x-detail, 2 y-detail, 3 diagonal. */
void wt_wavelet_classify(const wt_wavelet *w, int ix, int iy, int *level, int *orient);

#endif
