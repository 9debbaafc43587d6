/* tests/test_interaction.c: the DM-to-slope interaction Â used by POLC (SPEC §7). */
#include "core/model/fitting.h"
#include "core/model/interaction.h"
#include "core/model/system.h"
#include "testutil.h"

START_TEST(test_adjoint_and_assembly)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_interaction *ia;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    ck_assert_int_eq(wt_interaction_alloc(ctx, sys, &ia), WT_OK);
    int64_t na = sys->nact, ns = sys->nslopes;
    double *a = malloc(na * sizeof *a), *s = malloc(ns * sizeof *s), *y = calloc(ns, sizeof *y),
           *z = calloc(na, sizeof *z), *y2 = calloc(ns, sizeof *y2);
    tu_randn(a, na, 1);
    tu_randn(s, ns, 2);
    wt_interaction_apply(ia, 1.5, a, y);
    wt_interaction_apply_t(ia, 1.5, s, z);
    /* ⟨Â a, s⟩ = ⟨a, Âᵀ s⟩ to rounding of ~1e4-term sums */
    ck_assert_rel(tu_dot(y, s, ns), tu_dot(a, z, na), 1e-12, 0.0);
    wt_sparse *A;
    ck_assert_int_eq(wt_interaction_assemble(ia, &A), WT_OK);
    ck_assert_int_eq(A->nrow, ns);
    ck_assert_int_eq(A->ncol, na);
    wt_sparse_apply(A, 1.5, a, y2);
    ck_assert_double_le(tu_rel_diff(y2, y, ns), 1e-13);
    wt_sparse_free(A);
    free(a), free(s), free(y), free(z), free(y2);
    wt_interaction_free(ia);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* A ramp a = x on the ground DM (conjugate to the pupil, so every guide star sees it unscaled):
 * every LGS subaperture whose four corners lie on active actuators measures s_x = 1, s_y = 0. */
START_TEST(test_ground_dm_ramp)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_interaction *ia;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    ck_assert_int_eq(wt_interaction_alloc(ctx, sys, &ia), WT_OK);
    ck_assert_double_eq(sys->dm->altitude[0], 0.0);
    ck_assert_double_eq(sys->dm->grid[0].dx, sys->d); /* ground DM on the Fried corner grid */
    double *grid = calloc(wt_dm_grid_points(sys->dm), sizeof *grid), *a = calloc(sys->nact, sizeof *a);
    const wt_grid *g = &sys->dm->grid[0];
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) grid[ix + g->nx * iy] = g->x0 + ix * g->dx;
    wt_dm_restrict(sys->dm, grid, a);
    double *s = calloc(sys->nslopes, sizeof *s);
    wt_interaction_apply(ia, 1.0, a, s);
    const wt_sensor *lgs = &sys->sensors[0];
    int checked = 0;
    for (int k = 0; k < lgs->nsub; k++) {
        double cx, cy;
        wt_shack_hartmann_centre(lgs->sh, k, &cx, &cy);
        /* corners at cx ± d/2: all active when within the active radius */
        double r = hypot(fabs(cx) + 0.5 * sys->d, fabs(cy) + 0.5 * sys->d);
        if (r > 0.5 * cfg->diameter) continue;
        ck_assert_double_eq_tol(s[lgs->offset + k], 1.0, 1e-12);
        ck_assert_double_eq_tol(s[lgs->offset + lgs->nsub + k], 0.0, 1e-12);
        checked++;
    }
    ck_assert_int_gt(checked, lgs->nsub / 2);
    free(grid), free(a), free(s);
    wt_interaction_free(ia);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("interaction");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_adjoint_and_assembly);
    tcase_add_test(tc, test_ground_dm_ramp);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
