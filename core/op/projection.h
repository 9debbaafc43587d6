/* core/op/projection.h: the layer projections P (paper eq. ngsproj and P^LGS; SPEC §3) and the DM
 * influence along a direction (SPEC §5), by bilinear interpolation, with their adjoints.
 *
 *   y(r) = Σ_ℓ  layer_ℓ( (1 − h_ℓ/H) r + θ h_ℓ )      for every unmasked point r of the target grid,
 *
 * H the source altitude (H = 0 means a source at infinity: NGS, science directions, DMs seen by an
 * NGS), θ = (θx, θy) the direction [rad]. The layers are any stack of wt_grid (reconstruction layers,
 * atmospheric screens on a grid, DM actuator grids — bilinear interpolation of actuator values *is*
 * the piecewise-bilinear DM influence). Layer values are concatenated: layer ℓ starts at offset
 * Σ_{k<ℓ} nx_k ny_k. Points are the full target grid array (nx*ny); only masked points are written or
 * read. A sample point outside its layer grid is an error at alloc time (the layer grid does not cover
 * the footprint), unless `clamp_outside` is set, in which case such a point takes zero from that
 * layer (a DM seen beyond its edge).
 */
#ifndef WT_PROJECTION_H
#define WT_PROJECTION_H

#include <stdint.h>

#include "../base/base.h"
#include "../la/sparse.h"
#include "grid.h"

typedef struct wt_projection wt_projection;

/* layers: nlayers grids with altitudes [m]; target: the pupil-plane grid with mask (NULL: all points;
 * the mask is copied). Precomputes the interpolation stencils. */
int wt_projection_alloc(wt_context *ctx, int nlayers, const wt_grid *layers, const double *altitudes,
                        double source_altitude, double theta_x, double theta_y, const wt_grid *target,
                        const uint8_t *mask, int clamp_outside, wt_projection **out);
void wt_projection_free(wt_projection *p);

int64_t wt_projection_nin(const wt_projection *p);  /* Σ layer points */
int64_t wt_projection_nout(const wt_projection *p); /* target grid points (nx*ny) */

/* points <- points + alpha * P layers */
void wt_projection_apply(const wt_projection *p, double alpha, const double *layers, double *points);
/* The same, bit for bit, computed layer row by layer row: every term of apply is
 *   a0 (u0 r0[j] + u1 r0[j+1]) + a1 (u0 r1[j] + u1 r1[j+1])
 * (u: the column stencil, a: the row stencil, r0, r1: the two layer rows), and its bracket X_R = u0 R[j] +
 * u1 R[j+1] depends on the layer row R and the target column only; a layer row is read by the ~h/d target
 * rows of its cell (2 for the fitting's 0.25 m samples of 0.5 m layers) and by the target rows of the cell
 * below, so each X_R is computed once (along the whole row), kept while target rows need it, and a target
 * point adds a0 X_R + a1 X_{R+1} per layer, in layer order: the same operations on the same operands.
 * Faster where target rows outnumber layer rows (the fitting: 4x fewer interpolations along x, and the
 * rest contiguous vector arithmetic). work: wt_projection_rows_work(p) doubles (2 rows per layer) of the
 * caller's (no allocation). accumulate = 0: the masked points are overwritten with the values a zeroed array
 * would accumulate (0 + the terms: the same bits, signed zeros included; the other points are not touched),
 * so the caller need not clear points. */
int64_t wt_projection_rows_work(const wt_projection *p);
void wt_projection_apply_rows(const wt_projection *p, double alpha, const double *layers, double *points,
                              double *work, int accumulate);
/* layers <- layers + alpha * Pᵀ points (scatter; serial within one call, thread-safe across calls
 * that write different layer arrays) */
void wt_projection_apply_t(const wt_projection *p, double alpha, const double *points, double *layers);
/* The same as wt_projection_apply_t, bit for bit, with up to 4 layers side by side per point (more: one after
 * another, as apply_t): faster where the per-point sums along a run, one dependency chain per layer, bound
 * the loop (the fitting's 3 DMs). */
void wt_projection_apply_t_side(const wt_projection *p, double alpha, const double *points, double *layers);
/* Single precision (projection_f32.c; the tomography's fp32 operator): points += α P layers and layers += α Pᵀ points
 * with the weights rounded to float and float arithmetic, 16 points per AVX-512 block where the stencils are narrow
 * (not the double forms' bits: ~1e-6 relative). Thread use as the double forms. */
void wt_projection_apply_f32(const wt_projection *p, float alpha, const float *layers, float *points);
void wt_projection_apply_t_f32(const wt_projection *p, float alpha, const float *points, float *layers);
/* The explicit matrix P: nout x nin. */
int wt_projection_assemble(const wt_projection *p, wt_sparse **out);

#endif
