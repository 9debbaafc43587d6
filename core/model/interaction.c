/* core/model/interaction.c: DM-to-slope interaction Â = Γ H (SPEC §7). */
#include "interaction.h"

#include <string.h>

#include "../op/projection.h"
#include "fitting.h"
#include "stack.h"

static const int64_t zero_offset = 0;

struct wt_interaction {
    wt_context *ctx;
    const wt_system *sys;
    wt_projection **h;  /* per sensor: DM grids → corner grid */
    wt_sensor_stack stack; /* Σ_m Γ_m H_m over h (one input: the concatenated DM grids) */
    int64_t ncg, ndm;
    double *grids;      /* ndm */
    double *phase;      /* nsensors x ncg */
};

int wt_interaction_alloc(wt_context *ctx, const wt_system *sys, wt_interaction **out)
{
    int st = WT_OK;
    wt_interaction *ia = NULL;
    *out = NULL;
    WT_ALLOC(ctx, ia, 1, "interaction");
    ia->ctx = ctx;
    ia->sys = sys;
    ia->ncg = wt_grid_size(&sys->sense_grid);
    ia->ndm = wt_dm_grid_points(sys->dm);
    WT_ALLOC(ctx, ia->h, sys->nsensors, "interaction projections");
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        WT_TRY(wt_dm_influence_alloc(ctx, sys->dm, s->altitude, s->theta_x, s->theta_y,
                                   &sys->sense_grid, wt_shack_hartmann_corner_mask(s->sh), &ia->h[m]));
    }
    ia->stack = (wt_sensor_stack){.sys = sys, .nin = 1, .proj = ia->h, .in_offset = &zero_offset};
    WT_ALLOC(ctx, ia->grids, ia->ndm, "interaction grids");
    WT_ALLOC(ctx, ia->phase, (size_t)sys->nsensors * ia->ncg, "interaction phase");
    *out = ia;
    return WT_OK;
fail:
    wt_interaction_free(ia);
    return st;
}

void wt_interaction_free(wt_interaction *ia)
{
    if (!ia) return;
    if (ia->h)
        for (int m = 0; m < ia->sys->nsensors; m++) wt_projection_free(ia->h[m]);
    wt_free(ia->ctx, ia->h);
    wt_free(ia->ctx, ia->grids);
    wt_free(ia->ctx, ia->phase);
    wt_free(ia->ctx, ia);
}

int64_t wt_interaction_grids_size(const wt_interaction *ia) { return ia->ndm; }
int64_t wt_interaction_phase_size(const wt_interaction *ia) { return (int64_t)ia->sys->nsensors * ia->ncg; }

void wt_interaction_apply_ws(const wt_interaction *ia, double alpha, const double *a, double *s, double *grids,
                             double *phase, int nthreads)
{
    const wt_system *sys = ia->sys;
    wt_dm_expand(sys->dm, a, grids);
    wt_sensor_stack_apply(&ia->stack, alpha, grids, s, phase, sys->nslopes > 16384 ? nthreads : 1);
}

void wt_interaction_apply(wt_interaction *ia, double alpha, const double *a, double *s)
{
    wt_interaction_apply_ws(ia, alpha, a, s, ia->grids, ia->phase, wt_context_threads(ia->ctx));
}

void wt_interaction_apply_t_ws(const wt_interaction *ia, double alpha, const double *s, double *a, double *grids,
                               double *phase)
{
    const wt_system *sys = ia->sys;
    /* serial over sensors: every sensor scatters into the same DM grids */
    memset(grids, 0, (size_t)ia->ndm * sizeof *grids);
    for (int m = 0; m < sys->nsensors; m++)
        wt_sensor_stack_apply_t_sensor(&ia->stack, m, alpha, s + sys->sensors[m].offset, grids, phase);
    /* a += restriction of the grids to the active actuators */
    int64_t p = 0, q = 0;
    for (int k = 0; k < sys->dm->ndms; k++) {
        int64_t np = wt_grid_size(&sys->dm->grid[k]);
        for (int64_t i = 0; i < np; i++)
            if (sys->dm->active[k][i]) a[q++] += grids[p + i];
        p += np;
    }
}

void wt_interaction_apply_t(wt_interaction *ia, double alpha, const double *s, double *a)
{
    wt_interaction_apply_t_ws(ia, alpha, s, a, ia->grids, ia->phase);
}

int wt_interaction_assemble(wt_interaction *ia, wt_sparse **out)
{
    int st = WT_OK;
    const wt_system *sys = ia->sys;
    wt_context *ctx = ia->ctx;
    wt_triplet *tr = NULL;
    wt_sparse *G = NULL, *H = NULL, *GH = NULL;
    int64_t *col_of_grid = NULL;
    *out = NULL;
    /* grid point → active actuator column, or −1 */
    WT_ALLOC(ctx, col_of_grid, ia->ndm, "actuator map");
    wt_dm_actuator_index(sys->dm, col_of_grid);
    WT_TRY(wt_triplet_alloc(ctx, sys->nslopes, sys->nact, 1 << 20, &tr));
    for (int m = 0; m < sys->nsensors; m++) {
        WT_TRY(wt_shack_hartmann_assemble(sys->sensors[m].sh, &G));
        WT_TRY(wt_projection_assemble(ia->h[m], &H));
        WT_TRY(wt_sparse_multiply(G, H, &GH));
        for (int64_t c = 0; c < GH->ncol; c++) {
            if (col_of_grid[c] < 0) continue;
            for (int64_t k = GH->colptr[c]; k < GH->colptr[c + 1]; k++)
                WT_TRY(wt_triplet_add(tr, sys->sensors[m].offset + GH->rowind[k], col_of_grid[c], GH->val[k]));
        }
        wt_sparse_free(G);
        wt_sparse_free(H);
        wt_sparse_free(GH);
        G = H = GH = NULL;
    }
    WT_TRY(wt_triplet_compress(tr, out));
fail:
    wt_sparse_free(G);
    wt_sparse_free(H);
    wt_sparse_free(GH);
    wt_triplet_free(tr);
    wt_free(ctx, col_of_grid);
    return st;
}
