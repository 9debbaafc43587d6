/* core/op/scale_gain.h: the integrator gain of the POLC loop per spatial scale of the DM commands
 * (the paper's closing remark "the gain in the temporal control can be applied
 * scale-dependently").
 *
 *   a_{t+d} = a_{t+d−1} + G (R s_ol − a_t),   G = Σ_{j=0}^{L} g_j Π_j   (block-diagonal over the DMs)
 *
 * The bands Π_j come from nested spaces V_0 ⊂ V_1 ⊂ … ⊂ V_L = R^nact of each DM's commands. Each DM's
 * actuator grid is embedded, centred, in the smallest n x n grid with n a power of two; V_j is spanned by
 * the functions that are bilinear (1, x, y, xy) on each dyadic square of b_j = 2^(L+1−j) actuators of that
 * grid, restricted to the active actuators. With P_j the orthogonal projection onto V_j (per square: an
 * orthonormal basis of ≤ 4 vectors on its active actuators, Gram–Schmidt at set-up), Π_j = P_j − P_{j−1}
 * (P_{−1} = 0, P_L = I) and
 *   G = g_L I + Σ_{j<L} (g_j − g_{j+1}) P_j.
 * Band 0 holds what is bilinear over squares of 2^(L+1) actuators (piston, tip, tilt and the saddle of
 * each: exactly, whatever the edge of the active disk); band j > 0 what V_j adds to V_{j−1}, features of
 * about b_j actuator pitches; band L what is not bilinear over 4 x 4 squares (the ~n²/4 finest degrees of
 * freedom, like the finest detail level of a DWT). V_j ⊂ V_{j+1} because a bilinear function on a square
 * is bilinear on each of its four quarters, so the Π_j are orthogonal projections onto orthogonal
 * subspaces that sum to R^nact: G is symmetric with eigenvalues exactly {g_j}, and in its eigenbasis the
 * loop is L + 1 decoupled single-gain loops — stable wherever the single gain is (this is the discontinuous
 * bilinear multiwavelet basis of the active set: orthonormal, adapted to the disk, its details orthogonal
 * to every bilinear function on their square).
 *
 * The alternative basis (WT_SCALE_GAIN_DAUBECHIES, for comparison): G = M Wᵀ Λ W Mᵀ, with Mᵀ the
 * zero-padded embedding, W the orthonormal periodic Daubechies-N DWT to L levels (core/op/wavelet.h) and Λ
 * = g_0 on the scaling coefficients, g_j on the details of level L + 1 − j. Symmetric with eigenvalues in
 * [min g, max g], but the cut at the edge of the active disk (and the periodic wrap when the grid fills
 * n) is a step that puts much of a tilt into the detail bands: on the demo DMs 51 %, > 99 % and 31 % of it
 * (tests/test_scale_gain.c), against 0 % for the bilinear basis.
 *
 * All gains equal to g: G = g I exactly (the projection terms have coefficient 0 and are skipped), so the
 * bilinear basis gives the single-gain loop's bits; the Daubechies basis then gives g x to rounding
 * (force_transform) or the scalar product.
 * Plan once (allocates, may fail), apply many: wt_scale_gain_apply is const, allocates nothing and takes
 * a caller-owned workspace of wt_scale_gain_work_size() doubles (0 for the bilinear basis).
 */
#ifndef WT_SCALE_GAIN_H
#define WT_SCALE_GAIN_H

#include "../base/base.h"
#include "dm.h"

#define WT_SCALE_GAIN_MAX_BANDS 16 /* L + 1 <= 16: L = 15 levels need a 65536-point DM grid */

enum { WT_SCALE_GAIN_BILINEAR = 0, WT_SCALE_GAIN_DAUBECHIES = 1 };

typedef struct wt_scale_gain wt_scale_gain;

typedef struct wt_scale_gain_params {
    int nbands;                            /* L + 1 >= 2 */
    double gain[WT_SCALE_GAIN_MAX_BANDS];  /* g_0 (coarsest) … g_L (finest) [1], each in (0, 1] */
    int basis;                             /* WT_SCALE_GAIN_BILINEAR or _DAUBECHIES */
    int wavelet_order;                     /* Daubechies: N of W (2N taps) */
    int force_transform;                   /* Daubechies: 1 = transform even when the gains are all equal */
} wt_scale_gain_params;

/* Plans G for the DMs of dm (not owned; must outlive it). WT_ERR_INVALID with a message naming the
 * band or the DM when a gain is outside (0, 1], nbands is outside 2 … WT_SCALE_GAIN_MAX_BANDS, or a DM's
 * power-of-two grid n is too small: the bands need 2^(L+1) <= n (the coarsest squares, or the Daubechies
 * scaling block, at least 2 x 2). [out] *out (wt_scale_gain_free). */
int wt_scale_gain_alloc(wt_context *ctx, const wt_dm *dm, const wt_scale_gain_params *p, wt_scale_gain **out);
void wt_scale_gain_free(wt_scale_gain *g);

/* Doubles of workspace wt_scale_gain_apply needs. */
size_t wt_scale_gain_work_size(const wt_scale_gain *g);

/* y ← y + α G x (nact values each; x and y must not overlap). Allocates nothing. */
void wt_scale_gain_apply(const wt_scale_gain *g, double alpha, const double *x, double *y, double *work);

int wt_scale_gain_levels(const wt_scale_gain *g); /* L */
/* The power-of-two grid side DM k is embedded in. */
int wt_scale_gain_grid(const wt_scale_gain *g, int k);
/* Dimension of V_j (j = 0 … L; V_L = all actuators). */
int64_t wt_scale_gain_dim(const wt_scale_gain *g, int j);

#endif
