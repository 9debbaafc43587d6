/* core/op/shack_hartmann.h: the Shack–Hartmann model Γ in Fried geometry (SPEC §4, paper eq. SH_op),
 * and the low-order NGS sensors that average it.
 *
 * Fried: n x n subapertures of side d over the (n+1) x (n+1) corner grid φ (index i + (n+1) j):
 *   s_x(i,j) = [(φ(i+1,j) + φ(i+1,j+1)) − (φ(i,j) + φ(i,j+1))] / (2d)
 *   s_y(i,j) = [(φ(i,j+1) + φ(i+1,j+1)) − (φ(i,j) + φ(i+1,j))] / (2d)
 * Slopes are OPD gradients [m/m = rad]. Only valid subapertures produce slopes. Slope vector layout:
 * [s_x of valid subapertures in index order, then s_y in the same order] — length 2 * nvalid.
 *
 * Averaged sensor (NGS 2x2, 1x1): m x m big subapertures over the same fine n x n cells; big
 * subaperture (I, J) reports the mean of the Fried slopes of the valid fine cells inside it; it is
 * valid when it holds at least one valid fine cell. Layout as above with m*m in place of n*n.
 */
#ifndef WT_SHACK_HARTMANN_H
#define WT_SHACK_HARTMANN_H

#include <stdint.h>

#include "../base/base.h"
#include "../la/sparse.h"

typedef struct wt_shack_hartmann wt_shack_hartmann;

/* valid: n*n flags of the fine subapertures (copied). */
int wt_shack_hartmann_alloc(wt_context *ctx, int n, double d, const uint8_t *valid, wt_shack_hartmann **out);
/* Averaged low-order sensor with m x m subapertures (n divisible by m) over fine cells `valid`. */
int wt_shack_hartmann_alloc_averaged(wt_context *ctx, int n, double d, const uint8_t *valid, int m,
                                     wt_shack_hartmann **out);
/* Lit-area average sensor (SPEC §4; the simulator's truth sensor, and the reconstructor's model when
 * recon.sensor_model = "lit"): on the sample grid (n q + 1)² of spacing δ = d/q covering [−D/2, D/2]²,
 *   s = Σ_c w_c g_c / Σ_c w_c   over the q x q sample cells c of each subaperture (the (n/m q)² of each
 * big subaperture when 1 ≤ m < n), g_c the Fried gradient of cell c and w_c its illuminated fraction of
 * the annulus (D, obstruction). Validity as the averaged sensor's (m = 0 or n: `valid` itself). With
 * q = 1 and a fully lit subaperture it is the Fried slope. Corners in the layout of a (n q + 1)² grid. */
enum { WT_SH_TILT_G = 0, WT_SH_TILT_Z = 1 };
/* tilt = WT_SH_TILT_Z instead makes each row the Z-tilt of its (big) subaperture: the slope of the
 * weighted least-squares plane a + b x + c y through the corner samples φ_k, weight w_k = Σ w_c / 4 over the
 * (up to 4) lit sample cells of the subaperture that touch corner k (the trapezoid rule of the lit area),
 *   [a b c]ᵀ = N⁻¹ Σ_k w_k [1 x_k y_k]ᵀ φ_k,   N = Σ_k w_k [1 x_k y_k]ᵀ[1 x_k y_k];
 * what other simulators' tip-tilt sensors report. G-tilt and Z-tilt agree on a plane and differ by the
 * gradient the higher modes (coma first) put into the average: G-tilt is what a centroid measures. */
int wt_shack_hartmann_alloc_lit(wt_context *ctx, double diameter, double obstruction, int n, double d, int q,
                                const uint8_t *valid, int m, int tilt, wt_shack_hartmann **out);
void wt_shack_hartmann_free(wt_shack_hartmann *s);

int wt_shack_hartmann_nsub(const wt_shack_hartmann *s);         /* valid (big) subapertures */
int wt_shack_hartmann_nslopes(const wt_shack_hartmann *s);      /* 2 * nsub */
int wt_shack_hartmann_ncorners(const wt_shack_hartmann *s);     /* (n q + 1)^2 */
int wt_shack_hartmann_sampling(const wt_shack_hartmann *s);     /* q: sample points per subaperture side */
/* The CSR rows of an averaged or lit sensor ([2 nsub + 1] row pointers, columns, coefficients [1/m]);
 * NULLs for the plain Fried sensor. */
void wt_shack_hartmann_csr(const wt_shack_hartmann *s, const int32_t **rowptr, const int32_t **col,
                           const double **val);
const uint8_t *wt_shack_hartmann_corner_mask(const wt_shack_hartmann *s); /* corners with a non-zero coefficient in Γ (for averaged sensors mostly the rim of the lit region) */
/* Centre of valid subaperture k in pupil coordinates [m] (the pupil spans [-n d/2, n d/2]²). */
void wt_shack_hartmann_centre(const wt_shack_hartmann *s, int k, double *x, double *y);

/* slopes <- slopes + alpha * Γ phase   (phase on the corner grid) */
void wt_shack_hartmann_apply(const wt_shack_hartmann *s, double alpha, const double *phase, double *slopes);
/* phase <- phase + alpha * Γᵀ slopes */
void wt_shack_hartmann_apply_t(const wt_shack_hartmann *s, double alpha, const double *slopes, double *phase);
/* Single-precision forms of apply and apply_t (the tomography's fp32 operator, recon.<variant>.operator_precision):
 * the same operator with its coefficients rounded to float at alloc and float arithmetic; not the double forms' bits. */
void wt_shack_hartmann_apply_f32(const wt_shack_hartmann *s, float alpha, const float *phase, float *slopes);   /* slopes += alpha Γ phase */
void wt_shack_hartmann_apply_t_f32(const wt_shack_hartmann *s, float alpha, const float *slopes, float *phase); /* phase += alpha Γᵀ slopes */
/* Γ: nslopes x ncorners. */
int wt_shack_hartmann_assemble(const wt_shack_hartmann *s, wt_sparse **out);

#endif
