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
/* layers <- layers + alpha * Pᵀ points (scatter; serial within one call, thread-safe across calls
 * that write different layer arrays) */
void wt_projection_apply_t(const wt_projection *p, double alpha, const double *points, double *layers);
/* The explicit matrix P: nout x nin. */
int wt_projection_assemble(const wt_projection *p, wt_sparse **out);

#endif
