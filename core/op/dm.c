/* core/op/dm.c: the deformable mirrors: grids, active actuators with guard rings, expand / restrict
 * (SPEC §1, §5; see dm.h). */
#include "dm.h"

#include <math.h>

int wt_dm_alloc(wt_context *ctx, const wt_dm_params *p, wt_dm **out)
{
    int st = WT_OK;
    wt_dm *dm = NULL;
    *out = NULL;
    if (p->ndms < 1 || p->ndms > WT_DM_MAX || p->guard_rings < 0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_dm_alloc: %d DMs, %d guard rings; expected 1..%d DMs, rings >= 0",
                        p->ndms, p->guard_rings, WT_DM_MAX);
    WT_ALLOC(ctx, dm, 1, "DMs");
    dm->ctx = ctx;
    dm->ndms = p->ndms;
    const int G = p->guard_rings;
    for (int k = 0; k < p->ndms; k++) {
        wt_grid g = wt_grid_centred(p->actuators[k] + 2 * G, p->pitch[k]);
        dm->grid[k] = g;
        dm->altitude[k] = p->altitude[k];
        WT_ALLOC(ctx, dm->active[k], wt_grid_size(&g), "DM active mask");
        double rmax = 0.5 * p->diameter + p->altitude[k] * tan(p->field_radius);
        int count = 0;
        for (int iy = 0; iy < g.ny; iy++)
            for (int ix = 0; ix < g.nx; ix++) {
                double x = g.x0 + ix * g.dx, y = g.y0 + iy * g.dx;
                /* a tiny tolerance keeps actuators exactly on the circle in, whatever the rounding */
                int on = x * x + y * y <= rmax * rmax * (1.0 + 1e-12);
                if (G > 0 && !on) {
                    double h = G * g.dx * (1.0 - 1e-12), ex = fmax(0.0, fabs(x) - h), ey = fmax(0.0, fabs(y) - h);
                    on = ex * ex + ey * ey < rmax * rmax;
                }
                dm->active[k][ix + (int64_t)g.nx * iy] = (uint8_t)on;
                count += on;
            }
        if (count == 0) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "DM %d (dm.altitudes_m[%d] = %g) has no active actuator", k + 1, k,
                          p->altitude[k]);
            goto fail;
        }
        dm->nactive[k] = count;
        dm->offset[k] = dm->nact;
        dm->nact += count;
        dm->npoints += wt_grid_size(&g);
    }
    *out = dm;
    return WT_OK;
fail:
    wt_dm_free(dm);
    return st;
}

void wt_dm_free(wt_dm *dm)
{
    if (!dm) return;
    for (int k = 0; k < WT_DM_MAX; k++) wt_free(dm->ctx, dm->active[k]);
    wt_free(dm->ctx, dm);
}

int64_t wt_dm_grid_points(const wt_dm *dm) { return dm->npoints; }

void wt_dm_expand(const wt_dm *dm, const double *a, double *grids)
{
    int64_t p = 0, q = 0;
    for (int k = 0; k < dm->ndms; k++) {
        int64_t np = wt_grid_size(&dm->grid[k]);
        for (int64_t i = 0; i < np; i++) grids[p + i] = dm->active[k][i] ? a[q++] : 0.0;
        p += np;
    }
}

void wt_dm_restrict(const wt_dm *dm, const double *grids, double *a)
{
    int64_t p = 0, q = 0;
    for (int k = 0; k < dm->ndms; k++) {
        int64_t np = wt_grid_size(&dm->grid[k]);
        for (int64_t i = 0; i < np; i++)
            if (dm->active[k][i]) a[q++] = grids[p + i];
        p += np;
    }
}

void wt_dm_actuator_index(const wt_dm *dm, int64_t *index)
{
    int64_t p = 0, q = 0;
    for (int k = 0; k < dm->ndms; k++)
        for (int64_t i = 0; i < wt_grid_size(&dm->grid[k]); i++) index[p++] = dm->active[k][i] ? q++ : -1;
}

int wt_dm_influence_alloc(wt_context *ctx, const wt_dm *dm, double source_altitude, double theta_x, double theta_y,
                          const wt_grid *target, const uint8_t *mask, wt_projection **out)
{
    return wt_projection_alloc(ctx, dm->ndms, dm->grid, dm->altitude, source_altitude, theta_x, theta_y, target, mask,
                               1, out);
}
