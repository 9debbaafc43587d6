/* core/op/dm.h: the deformable mirrors (SPEC §1, §5): actuator grids, the active actuators (with guard
 * rings), and the scatter / gather between the command vector a (active actuators only, DM by DM, in
 * grid-index order) and the full actuator grids. The influence functions are piecewise bilinear: the
 * DM grids are seen along a direction through core/op/projection.h (H_θ, flag 1).
 *
 * Active set of DM k at altitude h: every actuator within R = D/2 + h tan θc of the centre; with G guard
 * rings also every actuator whose square of half-width G·pitch reaches inside that disk (G = 1 adds the
 * actuators whose bilinear influence touches the metapupil). The grid grows by G actuators on each side.
 */
#ifndef WT_DM_H
#define WT_DM_H

#include "../base/base.h"
#include "grid.h"
#include "projection.h"

#define WT_DM_MAX 8

/* What the DMs are built from (filled from the configuration's dm.* keys). */
typedef struct wt_dm_params {
    int ndms;
    double altitude[WT_DM_MAX]; /* conjugation altitude [m] */
    double pitch[WT_DM_MAX];    /* actuator pitch [m] */
    int actuators[WT_DM_MAX];   /* actuators per side, without the guard rings */
    int guard_rings;            /* G ≥ 0 */
    double field_radius;        /* θc [rad] */
    double diameter;            /* pupil diameter D [m] */
} wt_dm_params;

/* The DMs as plain data (read the fields; made by wt_dm_alloc). */
typedef struct wt_dm {
    wt_context *ctx;
    int ndms;
    wt_grid grid[WT_DM_MAX];    /* actuator grids (centred, pitch = spacing) */
    double altitude[WT_DM_MAX]; /* [m] */
    uint8_t *active[WT_DM_MAX]; /* active mask of each grid */
    int nactive[WT_DM_MAX];
    int64_t offset[WT_DM_MAX];  /* first actuator of DM k in the command vector */
    int64_t nact;               /* active actuators, all DMs */
    int64_t npoints;            /* grid points, all DMs */
} wt_dm;

/* WT_ERR_CONFIG naming the DM when one has no active actuator, WT_ERR_INVALID for bad sizes. */
int wt_dm_alloc(wt_context *ctx, const wt_dm_params *p, wt_dm **out);
void wt_dm_free(wt_dm *dm);

/* grids (npoints, concatenated DM grids) ← a scattered onto the active points, 0 elsewhere. */
void wt_dm_expand(const wt_dm *dm, const double *a, double *grids);
/* a (nact) ← the active points of grids: the transpose of wt_dm_expand. */
void wt_dm_restrict(const wt_dm *dm, const double *grids, double *a);
/* Grid points of all DMs (= dm->npoints). */
int64_t wt_dm_grid_points(const wt_dm *dm);
/* H_θ: the DM shapes (concatenated grids) seen from a source at source_altitude (0: infinity) in
 * direction (theta_x, theta_y) [rad], on the target grid's masked points: the bilinear influence,
 * clamped to the grid edge (core/op/projection.h, clamp_outside = 1). [out] *out (wt_projection_free). */
int wt_dm_influence_alloc(wt_context *ctx, const wt_dm *dm, double source_altitude, double theta_x, double theta_y,
                          const wt_grid *target, const uint8_t *mask, wt_projection **out);
/* index[p] = the actuator of concatenated grid point p, or -1 when p is not active (npoints values). */
void wt_dm_actuator_index(const wt_dm *dm, int64_t *index);

#endif
