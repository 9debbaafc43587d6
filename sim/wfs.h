/* sim/wfs.h: the simulator's truth Shack–Hartmann sensors (SPEC §4, "Truth (simulation)").
 *
 * A truth slope is the average OPD gradient over the ILLUMINATED part of a subaperture, computed on the
 * fine simulation grid, not the Fried model Γ (core/op/shack_hartmann.h) that the reconstructor assumes:
 *  - fine grid: wt_grid_centred(n p + 1, δf), δf = d / p, covering [-D/2, D/2]² (D = n d); p fine
 *    cells per subaperture side, so subaperture corners are fine grid points;
 *  - fine cell c: Fried gradient g_c from its 4 corner OPD values, weight w_c = its illuminated
 *    fraction (wt_pupil_fraction, exact);
 *  - slope of a (big) subaperture S:  s = Σ_{c ∈ S} w_c g_c / Σ_{c ∈ S} w_c     [rad = m/m].
 * Sensors, with exactly the model's validity and slope layout ([s_x of valid subapertures in index
 * order…, then s_y…]):
 *  - LGS type (m = 0 or m = n): n x n subapertures, those flagged in `valid` (index i + n j);
 *  - averaged NGS type (1 ≤ m < n, m | n): m x m big subapertures of n/m fine subapertures per side;
 *    big subaperture (I, J), index I + m J, is valid when it holds at least one valid fine subaperture
 *    (the rule of wt_shack_hartmann_alloc_averaged); its slope averages over the illuminated part of
 *    the WHOLE big subaperture, including the lit parts of fine subapertures below the valid threshold.
 *
 * The slopes are a fixed linear map of the OPD, precomputed at alloc as a sparse matrix. Inside a lit
 * region the fine Fried gradients telescope (Σ w g over fully lit cells is a trapezoid-rule boundary
 * integral, the discrete divergence theorem), so a slope reads only the OPD on the rim of its lit area
 * and on the boundary of its subaperture: wt_wfs_fine_mask says which fine points, so that the
 * simulator computes the OPD only there. Noise is not added here (wt_noise_sample does it, τ = 1); the
 * random LGS tip-tilt of SPEC §4 is wt_wfs_add_tiptilt.
 */
#ifndef WT_WFS_H
#define WT_WFS_H

#include <stddef.h>
#include <stdint.h>

#include "../core/base/base.h"
#include "../core/base/rng.h"
#include "../core/op/grid.h"

typedef struct wt_wfs wt_wfs;

/* [in] diameter D [m] > 0, obstruction ε ∈ [0, 1) (inner diameter ε D), n subapertures per side, side
 * d [m] with n d = D (relative 1e-9), p ≥ 1 fine points per subaperture side, valid[n*n] the LGS
 * valid-subaperture mask (not kept), m: 0 or n for the LGS-type sensor, else 1 ≤ m < n dividing n; tilt
 * WT_SH_TILT_G (the average gradient above) or WT_SH_TILT_Z (the least-squares plane over the lit area,
 * core/op/shack_hartmann.h; its slopes read every lit point, so the fine mask is the whole lit area).
 * Every valid (big) subaperture must be illuminated somewhere. [out] *out, owned by the caller.
 * Allocates the sensor and, during alloc only, (n p)² + 2 (n p / m' + 1)² doubles of work space
 * (m' = m or n). Errors: WT_ERR_INVALID naming the value, WT_ERR_NOMEM. */
int wt_wfs_alloc(wt_context *ctx, double diameter, double obstruction, int n, double d, int p,
                 const uint8_t *valid, int m, int tilt, wt_wfs **out);
void wt_wfs_free(wt_wfs *w);

/* The fine grid wt_grid_centred(n p + 1, d / p) the OPD lives on. */
wt_grid wt_wfs_grid(const wt_wfs *w);
/* [(n p + 1)²] 1 for the fine points whose OPD the slopes depend on (owned by w). */
const uint8_t *wt_wfs_fine_mask(const wt_wfs *w);
int64_t wt_wfs_npoints(const wt_wfs *w); /* set points of the fine mask */
int wt_wfs_nsub(const wt_wfs *w);        /* valid (big) subapertures */
int wt_wfs_nslopes(const wt_wfs *w);     /* 2 nsub */
int64_t wt_wfs_nnz(const wt_wfs *w);     /* coefficients of the linear map (measure costs 2 nnz flops) */
size_t wt_wfs_bytes(const wt_wfs *w);    /* memory held by the sensor */

/* slopes[2 nsub] <- the truth slopes of opd [(n p + 1)²] on the fine grid [m] (overwritten). Reads only
 * the points of the fine mask. const: allocates nothing, thread-safe on distinct outputs. */
void wt_wfs_measure(const wt_wfs *w, const double *opd, double *slopes);

/* One frame's random LGS tip-tilt (SPEC §4): draws t_x, t_y ~ N(0, rms²) from rng (two normals, in
 * that order) and adds t_x to every s_x and t_y to every s_y of slopes[2 nsub]. rms [rad] per axis.
 * Allocates nothing. Errors: WT_ERR_INVALID for a negative or non-finite rms (slopes untouched). */
int wt_wfs_add_tiptilt(const wt_wfs *w, wt_rng *rng, double rms, double *slopes);

#endif
