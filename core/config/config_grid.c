/* core/config/config_grid.c: the automatic reconstruction layer grids (SPEC §6).
 *
 * When `recon.<variant>.layer_spacing_m` and `layer_size` are left out (or "auto"), each layer at altitude h
 * gets (docs/design.md, "Choices where the sources are silent"):
 *
 *   spacing δ = δ0 / layer_oversampling, with
 *     pcg3: δ0 = the pitch of the DM(s) its commands are read at: the DM at h, or the finer of the two DMs
 *           around h (the split of core/model/reconstructor.c, wt_reconstructor_command_map), the end DM
 *           outside their range. SPEC §5: pcg3's layers live on the actuator grids.
 *     cg9:  δ0 = min(d, that same pitch), d the LGS subaperture side. A layer need not be finer than what
 *           the sensors see of it (an LGS subaperture covers d (1 − h/H) of it, docs/results.md §0c: 0.25 m
 *           gives nothing over 0.5 m on the E-ELT) nor than the DMs that chiefly correct it (those conjugated
 *           near it): a DM finer than d far from h would refine every layer for no information, which is
 *           why the smallest pitch of all DMs is not used.
 *   size n = the smallest power of two >= max(4, 2^J) whose grid (points (i − n/2) δ, i = 0 … n−1, as
 *           wt_grid_layer) holds every point the operators read on the layer:
 *     - every sensor's sample grid, [−D/2, D/2]² (the Fried corner grid or the lit model's finer grid,
 *       core/model/system.c), seen from the LGS with the cone factor, (1 − h/H) r + θ h, and from each NGS,
 *       r + θ h (core/model/tomography.c builds these projections and refuses a layer that misses one);
 *     - every evaluation direction's sample grid, r + θ h with r in [−D/2, D/2]² (the cg9 fitting,
 *       core/model/fitting.c; counted for pcg3 too: its layers are its estimate over the field);
 *     - pcg3: the active actuators of the DMs the layer is read at (wt_reconstructor_command_map).
 *     The bilinear projection needs both stencil points inside the grid: a coordinate X is held when
 *     −n δ/2 <= X <= (n/2 − 1) δ. The periodic wavelet needs a power of two >= 2^J (core/op/wavelet.c); it
 *     wraps the layer, and no margin is added for that (the hand-tuned E-ELT grids had none either).
 *
 * The extents are bounds of the bounding box [−D/2, D/2]² of the pupil's sample points: the valid corners
 * reach x = ±D/2 on the axes (the subapertures there are lit far beyond any valid fraction < 1), and the
 * projection's coverage test is separable (a point is held iff its column and its row are), so covering the
 * box is what covering the masked points requires; tests/test_system.c checks the choice against the real
 * operators (covers; n/2 does not) on the E-ELT, 42×42 and demo presets.
 *
 * This file reads only wt_config (the config module knows base only): the DM active rule below is
 * core/op/dm.c's, written again, and the test above catches a change of one without the other.
 */
#include "config_private.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define MAX_SIZE 8192   /* the schema's upper bound of layer_size */
#define SLACK 1e-10     /* [cells]: tighter than the projection's 1e-9, so what is accepted here passes there */

typedef struct {
    double lo[2], hi[2]; /* bounding box of the points read on the layer [m] (x, y) */
} box;

static void box_add(box *b, double x0, double x1, double y0, double y1)
{
    b->lo[0] = fmin(b->lo[0], x0);
    b->hi[0] = fmax(b->hi[0], x1);
    b->lo[1] = fmin(b->lo[1], y0);
    b->hi[1] = fmax(b->hi[1], y1);
}

/* The pupil's sample square [−D/2, D/2]² seen from a source at altitude H (0: infinity) in direction θ. */
static void add_footprint(box *b, double D, double h, double H, double tx, double ty)
{
    double s = H > 0.0 ? 1.0 - h / H : 1.0, r = 0.5 * D * s;
    box_add(b, -r + tx * h, r + tx * h, -r + ty * h, r + ty * h);
}

/* The active actuators of DM k (core/op/dm.c wt_dm_alloc: the grid of actuators + 2G points of its pitch,
 * centred; active within D/2 + h tan θc of the centre, or with the guard rings when the square of half-width
 * G·pitch around the actuator reaches inside that disk). Returns the number of active actuators. */
static int add_actuators(box *b, const wt_config *cfg, int k)
{
    const int G = cfg->dm_guard_rings, m = cfg->dm_actuators[k] + 2 * G;
    const double p = cfg->dm_pitch[k], x0 = -0.5 * (m - 1) * p;
    const double rmax = 0.5 * cfg->diameter + cfg->dm_altitude[k] * tan(cfg->dm_field_radius);
    int count = 0;
    for (int iy = 0; iy < m; iy++)
        for (int ix = 0; ix < m; ix++) {
            double x = x0 + ix * p, y = x0 + iy * p;
            int on = x * x + y * y <= rmax * rmax * (1.0 + 1e-12);
            if (G > 0 && !on) {
                double hg = G * p * (1.0 - 1e-12), ex = fmax(0.0, fabs(x) - hg), ey = fmax(0.0, fabs(y) - hg);
                on = ex * ex + ey * ey < rmax * rmax;
            }
            if (on) {
                box_add(b, x, x, y, y);
                count++;
            }
        }
    return count;
}

/* The DMs layer altitude h is read at (pcg3) or chiefly corrected by: wt_profile_bin_altitude's rule on
 * the DM altitudes sorted: the DM at h, the two around it (both with a weight > 0), or the end DM. */
static int fed_dms(const wt_config *cfg, double h, int *dms)
{
    int order[WT_MAX_DMS], K = cfg->ndms;
    for (int k = 0; k < K; k++) order[k] = k;
    for (int i = 1; i < K; i++)
        for (int j = i; j > 0 && cfg->dm_altitude[order[j]] < cfg->dm_altitude[order[j - 1]]; j--) {
            int o = order[j];
            order[j] = order[j - 1];
            order[j - 1] = o;
        }
    if (h <= cfg->dm_altitude[order[0]]) {
        dms[0] = order[0];
        return 1;
    }
    if (h >= cfg->dm_altitude[order[K - 1]]) {
        dms[0] = order[K - 1];
        return 1;
    }
    int l = 0;
    while (!(h >= cfg->dm_altitude[order[l]] && h < cfg->dm_altitude[order[l + 1]])) l++;
    dms[0] = order[l];
    if (h == cfg->dm_altitude[order[l]]) return 1; /* weight 0 on the DM above */
    dms[1] = order[l + 1];
    return 2;
}

/* The shortest decimal text libconfig writes (15 significant digits) read back: the canonical text of a
 * configuration that gives the chosen spacing explicitly reads as exactly this value. */
static double canonical_double(double v)
{
    char buf[40];
    snprintf(buf, sizeof buf, "%.15g", v);
    return strtod(buf, NULL);
}

/* Is coordinate range [lo, hi] held by n points of spacing δ at (i − n/2) δ (both bilinear stencil points)? */
static int holds(double lo, double hi, int n, double delta)
{
    return lo / delta >= -0.5 * n - SLACK && hi / delta <= 0.5 * n - 1.0 + SLACK;
}

int wt_config_priv_layer_grid(wt_context *ctx, const wt_config *cfg, const char *name, int auto_spacing,
                              wt_recon_variant_config *v)
{
    const int pcg3 = name[0] == 'p';
    const double d = cfg->diameter / cfg->lgs_wfs.subapertures;
    const int g = cfg->eval_grid;
    int minimum = 4;
    while (minimum < (1L << 30) && minimum < (1L << cfg->wavelet_levels)) minimum *= 2;
    for (int l = 0; l < v->nlayers; l++) {
        const double h = v->altitudes[l];
        int dms[2], nd = fed_dms(cfg, h, dms), kmin = dms[0];
        if (nd == 2 && cfg->dm_pitch[dms[1]] < cfg->dm_pitch[kmin]) kmin = dms[1];
        if (auto_spacing) {
            double p = cfg->dm_pitch[kmin];
            v->grid_base_dm[l] = pcg3 || p < d ? kmin : -1;
            v->grid_base[l] = pcg3 || p < d ? p : d;
            v->spacing[l] = canonical_double(v->grid_base[l] / v->oversampling);
        }
        const double delta = v->spacing[l];

        box b = {{HUGE_VAL, HUGE_VAL}, {-HUGE_VAL, -HUGE_VAL}};
        for (int k = 0; k < cfg->nlgs; k++) {
            double az = cfg->lgs_azimuth0 + 2.0 * M_PI * k / cfg->nlgs; /* as core/model/system.c */
            add_footprint(&b, cfg->diameter, h, cfg->lgs_altitude, cfg->lgs_radius * cos(az), cfg->lgs_radius * sin(az));
        }
        for (int k = 0; k < cfg->nngs; k++)
            add_footprint(&b, cfg->diameter, h, 0.0, cfg->ngs_radius * cos(cfg->ngs_azimuth[k]),
                          cfg->ngs_radius * sin(cfg->ngs_azimuth[k]));
        for (int j = 0; j < g; j++)
            for (int i = 0; i < g; i++)
                add_footprint(&b, cfg->diameter, h, 0.0, (i - 0.5 * (g - 1)) * cfg->eval_spacing,
                              (j - 0.5 * (g - 1)) * cfg->eval_spacing);
        if (pcg3)
            for (int q = 0; q < nd; q++) add_actuators(&b, cfg, dms[q]);

        int n = minimum;
        while (n <= MAX_SIZE && !(holds(b.lo[0], b.hi[0], n, delta) && holds(b.lo[1], b.hi[1], n, delta))) n *= 2;
        if (n > MAX_SIZE) {
            double need = 2.0 * fmax(fmax(-b.lo[0], b.hi[0] + delta), fmax(-b.lo[1], b.hi[1] + delta)) / delta;
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "%s: keys 'recon.%s.layer_size' (left out: automatic) and 'recon.%s.layer_spacing_m'%s: "
                            "layer %d at %g m ('recon.%s.layer_altitudes_m' element [%d]) needs %.0f points of %g m "
                            "to cover its footprints, more than the %d accepted; %s",
                            cfg->path, name, name, auto_spacing ? " (automatic)" : "", l + 1, h, name, l, need, delta,
                            MAX_SIZE, auto_spacing ? "lower the variant's 'layer_oversampling'" : "give a coarser spacing");
        }
        v->size[l] = n;
    }
    return WT_OK;
}
