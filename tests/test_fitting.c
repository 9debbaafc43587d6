/* tests/test_fitting.c: the DM fitting step (paper eq. fit_step_min, SPEC §5; core/model/fitting.h):
 * its regularisation ε is the stated fraction of the true mean diagonal of Σ_j H_jᵀ H_j (the probing
 * that computes it must not let two probes share a sample point), a shape the DMs can make is
 * fitted exactly, on both the Fried-corner and the finer pupil sampling, by both solvers; the assembled
 * normal matrix is the operator, and the Cholesky fit equals the converged CG fit within κ(N)·rounding; after the
 * tomography's solve, the fit recovers a DM shape, and a continued fit equals a warm-started one. */
#include <lapacke.h>

#include "core/model/fitting.h"
#include "core/model/params.h"
#include "core/model/system.h"
#include "testmodel.h"
#include "testutil.h"
#include "tomography_fixture.h"

/* The demo system with its defaults: the set-up of the "core" test case, a checked fixture (each test gets its
 * own, made in its own process). */
typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
} sysfix;
static sysfix F;

static void demo_setup(void)
{
    F.ctx = tu_context();
    ck_assert_int_eq(wt_config_read(F.ctx, "data/presets/demo.cfg", 0, NULL, &F.cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(F.ctx, F.cfg, &F.sys), WT_OK);
}

static void demo_teardown(void)
{
    wt_system_free(F.sys);
    wt_config_free(F.ctx, F.cfg);
    wt_context_free(F.ctx);
}

/* ε against the brute-force diagonal: F e_i = (Σ H_jᵀ H_j + ε I) e_i, so F_ii − ε is the diagonal. */
static void check_epsilon(int sampling)
{
    wt_context *ctx = F.ctx;
    const wt_system *sys = F.sys;
    wt_fitting *fit;
    const double reg = 1e-3;
    const wt_fitting_params fp = {.regularization = reg, .sampling = sampling};
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    const int64_t na = sys->nact;
    const double eps = wt_fitting_epsilon(fit);
    double *e = calloc(na, sizeof *e), *y = malloc(na * sizeof *y), sum = 0.0;
    for (int64_t i = 0; i < na; i++) {
        e[i] = 1.0;
        tu_fitting_apply(fit, na, e, y);
        e[i] = 0.0;
        sum += y[i] - eps; /* a guard-ring actuator may see no sample point: 0, and ε holds it */
    }
    /* the same sums in another order: rounding only */
    ck_assert_rel(eps, reg * sum / (double)na, 1e-12, 0.0);
    free(e), free(y);
    wt_fitting_free(fit);
}

START_TEST(test_epsilon_fried) { check_epsilon(1); }
END_TEST

START_TEST(test_epsilon_pupil_grid) { check_epsilon(2); }
END_TEST

/* maps_j = H_j a0 for random commands a0: the DMs can make them exactly, so the fit must reproduce
 * them in every direction (to the bias of a tiny ε and the CG tolerance). */
START_TEST(test_representable_maps)
{
    wt_context *ctx = F.ctx;
    const wt_system *sys = F.sys;
    wt_fitting *fit;
    const wt_fitting_params fp = {.regularization = 1e-10, .sampling = 2, .solver = _i}; /* CG, then Cholesky */
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    const wt_grid *sg = wt_fitting_sample_grid(fit);
    const uint8_t *mask = wt_fitting_sample_mask(fit);
    const int64_t na = sys->nact, np = wt_grid_size(sg), nd = wt_dm_grid_points(sys->dm);
    double *a0 = malloc(na * sizeof *a0), *a = calloc(na, sizeof *a), *g0 = calloc(nd, sizeof *g0),
           *g1 = calloc(nd, sizeof *g1), *maps = calloc((size_t)sys->neval * np, sizeof *maps),
           *m1 = calloc(np, sizeof *m1);
    tu_randn(a0, na, 7);
    wt_dm_expand(sys->dm, a0, g0);
    wt_projection *h[WT_MAX_EVAL];
    for (int j = 0; j < sys->neval; j++) {
        ck_assert_int_eq(wt_dm_influence_alloc(ctx, sys->dm, 0.0, sys->eval_x[j], sys->eval_y[j], sg, mask, &h[j]),
                         WT_OK);
        wt_projection_apply(h[j], 1.0, g0, maps + (size_t)j * np);
    }
    wt_pcg_result r;
    ck_assert_int_ge(wt_fitting_solve_maps(fit, maps, a, 3000, 1e-13, &r), WT_OK);
    wt_dm_expand(sys->dm, a, g1);
    double worst = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        memset(m1, 0, np * sizeof *m1);
        wt_projection_apply(h[j], 1.0, g1, m1);
        worst = fmax(worst, tu_rel_diff(m1, maps + (size_t)j * np, np));
        wt_projection_free(h[j]);
    }
    /* ε = 1e-10 of the mean diagonal biases the fit by O(1e-10 κ); CG stops at 1e-13 of ‖b‖ (Cholesky: exact
     * to O(κ n u)) */
    ck_assert_msg(worst < 1e-6, "fitted DM phase differs from the representable target by %g (%d iterations)", worst,
                  r.iterations);
    free(a0), free(a), free(g0), free(g1), free(maps), free(m1);
    wt_fitting_free(fit);
}
END_TEST

/* The model operators accumulate like core/op's: y ← y + α A x leaves y's old value in (fitting F,
 * tomography M, Ã and the right-hand side). */
START_TEST(test_operators_accumulate)
{
    wt_context *ctx = F.ctx;
    const wt_config *cfg = F.cfg;
    const wt_system *sys = F.sys;
    wt_fitting *fit;
    wt_tomography *t;
    const wt_fitting_params fp = {.regularization = 1e-3, .sampling = 1};
    ck_assert_int_eq(wt_fitting_alloc(ctx, sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_OK);
    const int64_t na = sys->nact, n = wt_tomography_nunknowns(t), ns = sys->nslopes, big = n > ns ? n : ns;
    double *x = malloc(big * sizeof *x), *y0 = malloc(big * sizeof *y0), *ax = malloc(big * sizeof *ax),
           *y = malloc(big * sizeof *y);
    tu_randn(x, big, 11);
    tu_randn(y0, big, 12);
    /* fitting: y0 − 0.5 F x */
    tu_fitting_apply(fit, na, x, ax);
    memcpy(y, y0, na * sizeof *y);
    wt_fitting_apply(fit, -0.5, x, y);
    for (int64_t i = 0; i < na; i++) ck_assert_double_eq(y[i], y0[i] + -0.5 * ax[i]);
    /* tomography M, Ã, rhs */
    tu_tomo_apply(t, x, ax);
    memcpy(y, y0, n * sizeof *y);
    wt_tomography_apply(t, 2.0, x, y);
    for (int64_t i = 0; i < n; i++) ck_assert_double_eq(y[i], y0[i] + 2.0 * ax[i]);
    tu_tomo_slopes(t, x, ax);
    memcpy(y, y0, ns * sizeof *y);
    wt_tomography_slopes(t, 3.0, x, y);
    for (int64_t i = 0; i < ns; i++) ck_assert_double_eq_tol(y[i], y0[i] + 3.0 * ax[i], 1e-12 * (fabs(y0[i]) + 3.0 * fabs(ax[i])));
    tu_tomo_rhs(t, x, ax);
    memcpy(y, y0, n * sizeof *y);
    wt_tomography_rhs(t, 1.0, x, y);
    for (int64_t i = 0; i < n; i++) ck_assert_double_eq(y[i], y0[i] + ax[i]);
    free(x), free(y0), free(ax), free(y);
    wt_tomography_free(t);
    wt_fitting_free(fit);
}
END_TEST

/* wt_fitting_assemble: the sparse N the Cholesky solver factors is the operator: N x = apply(x) to the rounding
 * of sums in another order (~1e-15 relative; 1e-13 asked), symmetric to the same, and ε on the diagonal. */
START_TEST(test_assembled_equals_apply)
{
    const sysfix f = F;
    const wt_fitting_params fp = {.regularization = 1e-3, .sampling = 2};
    wt_fitting *fit;
    ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    wt_sparse *N;
    ck_assert_int_eq(wt_fitting_assemble(fit, &N), WT_OK);
    const int64_t na = f.sys->nact;
    ck_assert_int_eq(N->nrow, na);
    ck_assert_int_eq(N->ncol, na);
    double *x = malloc(na * sizeof *x), *y = calloc(na, sizeof *y), *z = malloc(na * sizeof *z),
           *d = calloc((size_t)na * na, sizeof *d);
    for (int t = 0; t < 3; t++) {
        tu_randn(x, na, 40 + t);
        memset(y, 0, na * sizeof *y);
        wt_sparse_apply(N, 1.0, x, y);
        tu_fitting_apply(fit, na, x, z);
        ck_assert_double_le(tu_rel_diff(y, z, na), 1e-13);
    }
    for (int64_t c = 0; c < na; c++)
        for (int64_t k = N->colptr[c]; k < N->colptr[c + 1]; k++) d[N->rowind[k] + na * c] = N->val[k];
    double asym = 0.0, dmax = 0.0;
    for (int64_t c = 0; c < na; c++) {
        dmax = fmax(dmax, d[c + na * c]);
        ck_assert_double_ge(d[c + na * c], wt_fitting_epsilon(fit)); /* Σ HᵀH ≽ 0 on the diagonal, + ε */
        for (int64_t r = 0; r < c; r++) asym = fmax(asym, fabs(d[r + na * c] - d[c + na * r]));
    }
    ck_assert_double_le(asym, 1e-14 * dmax);
    free(x), free(y), free(z), free(d);
    wt_sparse_free(N);
    wt_fitting_free(fit);
}
END_TEST

/* The Cholesky fit equals the converged CG fit on the demo's cg9 layers. Tolerance from the conditioning:
 * for a backward-stable solve of N a = b the forward error is ≤ κ(N) · (backward error), so
 *   ‖a_chol − a*‖ ≤ κ c n u ‖a*‖          (Cholesky: backward error ≤ c n u ‖N‖, c = 3 taken; with the factor
 *                                          read in fp32, + 4 u_f: L rounded to float is the exact factor of a
 *                                          matrix within ~2 u_f ‖N‖ of N, test_chol)
 *   ‖a_cg − a*‖ ≤ κ ‖b − N a_cg‖ / ‖b‖ ‖a*‖ (CG: its true relative residual, recomputed here),
 * and the test asks ‖a_chol − a_cg‖ ≤ κ (3 n u [+ 4 u_f] + ρ_cg) ‖a_cg‖, with κ = λmax/λmin of N from LAPACK's dsyev
 * on the assembled N (1.5e4 here, ε = 1e-3 of the mean diagonal). CG: warm-started from 0, up to 2000 iterations
 * to 1e-13. Measured: 1.5e-11 relative against a bound of 5e-9. The reconstructor's form (continue) gives the
 * same direct solve. */
START_TEST(test_cholesky_equals_converged_cg)
{
    const sysfix f = F;
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    wt_tomography *t;
    ck_assert_int_eq(wt_tomography_alloc(f.ctx, f.sys, &f.cfg->cg9, "cg9", &tp, &t), WT_OK);
    wt_fitting_params fp = wt_fitting_params_from_variant(&f.cfg->cg9);
    ck_assert_int_eq(fp.solver, WT_FIT_CHOLESKY); /* the preset's (and the schema's) default */
    ck_assert_int_eq(fp.factor_float32, 1);
    fp.solver = WT_FIT_CG;
    wt_fitting *fcg, *fch;
    ck_assert_int_eq(wt_fitting_alloc_for(f.ctx, t, &fp, &fcg), WT_OK);
    fp.solver = WT_FIT_CHOLESKY;
    fp.factor_float32 = _i;
    ck_assert_int_eq(wt_fitting_alloc_for(f.ctx, t, &fp, &fch), WT_OK);
    ck_assert_int_eq(wt_fitting_solver(fch), WT_FIT_CHOLESKY);
    wt_fitting_stats fs;
    wt_fitting_stats_get(fch, &fs);
    ck_assert(fs.nnz_factor > 0 && fs.factor_bytes > 0 && fs.nnz_matrix > 0 && fs.ordering);
    ck_assert_double_gt(wt_fitting_bytes(fch), wt_fitting_bytes(fcg));
    /* the layers of random coefficients (the tomography's W⁻¹ of a seeded draw) */
    const int64_t n = wt_tomography_nunknowns(t), na = f.sys->nact;
    double *c = malloc(n * sizeof *c), *phi = malloc(n * sizeof *phi), *acg = calloc(na, sizeof *acg),
           *ach = malloc(na * sizeof *ach), *ach2 = malloc(na * sizeof *ach2), *b = calloc(na, sizeof *b),
           *r = malloc(na * sizeof *r);
    tu_randn(c, n, 3);
    wt_tomography_layers(t, c, phi);
    wt_pcg_result res;
    ck_assert_int_eq(wt_fitting_solve(fcg, phi, acg, 2000, 1e-13, NULL, &res), WT_OK);
    for (int64_t i = 0; i < na; i++) ach[i] = 1.0; /* the direct solve ignores the start */
    double hist[1] = {-1.0};
    ck_assert_int_eq(wt_fitting_solve(fch, phi, ach, 5, 0.5, hist, &res), WT_OK);
    ck_assert_int_eq(res.iterations, 0);
    ck_assert_double_eq(hist[0], 0.0);
    ck_assert_int_eq(wt_fitting_solve_continue(fch, phi, ach2, 10, 0.0, NULL, NULL), WT_OK);
    ck_assert_int_eq(memcmp(ach, ach2, na * sizeof *ach), 0);
    /* the reference kernels (recon.cg9.fit_kernels = "reference": a pupil buffer per direction, the plain
     * solve loops) give the same bits as the fast ones, the right-hand side and the commands */
    {
        wt_fitting *fref;
        fp.reference = 1;
        ck_assert_int_eq(wt_fitting_alloc_for(f.ctx, t, &fp, &fref), WT_OK);
        fp.reference = 0;
        double *bf = calloc(na, sizeof *bf), *br = calloc(na, sizeof *br);
        wt_fitting_rhs(fch, 1.0, phi, bf);
        wt_fitting_rhs(fref, 1.0, phi, br);
        ck_assert_int_eq(memcmp(bf, br, na * sizeof *bf), 0);
        memset(bf, 0, na * sizeof *bf), memset(br, 0, na * sizeof *br);
        wt_fitting_apply(fch, 0.7, acg, bf); /* the normal operator (CG's) through H_j instead of P_j */
        wt_fitting_apply(fref, 0.7, acg, br);
        ck_assert_int_eq(memcmp(bf, br, na * sizeof *bf), 0);
        ck_assert_int_eq(wt_fitting_solve(fref, phi, ach2, 5, 0.5, NULL, NULL), WT_OK);
        ck_assert_int_eq(memcmp(ach, ach2, na * sizeof *ach), 0);
        free(bf), free(br);
        wt_fitting_free(fref);
    }
    /* CG's true residual */
    wt_fitting_rhs(fcg, 1.0, phi, b);
    tu_fitting_apply(fcg, na, acg, r);
    for (int64_t i = 0; i < na; i++) r[i] = b[i] - r[i];
    const double rho = tu_norm(r, na) / tu_norm(b, na);
    /* κ(N) from the assembled matrix */
    wt_sparse *N;
    ck_assert_int_eq(wt_fitting_assemble(fch, &N), WT_OK);
    double *d = calloc((size_t)na * na, sizeof *d), *w = malloc(na * sizeof *w);
    for (int64_t col = 0; col < na; col++)
        for (int64_t k = N->colptr[col]; k < N->colptr[col + 1]; k++) d[N->rowind[k] + na * col] = N->val[k];
    ck_assert_int_eq(LAPACKE_dsyev(LAPACK_COL_MAJOR, 'N', 'U', (lapack_int)na, d, (lapack_int)na, w), 0);
    const double kappa = w[na - 1] / w[0];
    ck_assert_double_gt(w[0], 0.0);
    const double tol = kappa * (3.0 * (double)na * 1.1e-16 + (_i ? 4.0 * 6.0e-8 : 0.0) + rho),
                 got = tu_rel_diff(ach, acg, na);
    fprintf(stderr, "fitting, factor in %s: kappa %.3g, CG residual %.3g, |a_chol - a_cg| / |a_cg| = %.3g (bound %.3g)\n",
            _i ? "fp32" : "fp64", kappa, rho, got, tol);
    ck_assert_msg(got <= tol, "Cholesky vs converged CG: %.3g > %.3g (kappa %.3g, CG residual %.3g)", got, tol, kappa,
                  rho);
    free(c), free(phi), free(acg), free(ach), free(ach2), free(b), free(r), free(d), free(w);
    wt_sparse_free(N);
    wt_fitting_free(fcg);
    wt_fitting_free(fch);
    wt_tomography_free(t);
}
END_TEST

/* Refused: an unknown solver (naming the key), a matrix that is not positive definite (ε < 0: the message
 * names recon.cg9.fit_regularization); every allocation failure of the Cholesky set-up is WT_ERR_NOMEM with
 * nothing left allocated. */
START_TEST(test_cholesky_refusals)
{
    const sysfix f = F;
    wt_fitting *fit = (wt_fitting *)&f;
    wt_fitting_params fp = {.regularization = 1e-3, .sampling = 1, .solver = 2};
    ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, 0, NULL, NULL, &fp, &fit), WT_ERR_INVALID);
    ck_assert_ptr_null(fit);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "recon.cg9.fit_solver"));
    fp = (wt_fitting_params){.regularization = -0.5, .sampling = 1, .solver = WT_FIT_CHOLESKY};
    ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, 0, NULL, NULL, &fp, &fit), WT_ERR_NUMERIC);
    ck_assert_ptr_null(fit);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "recon.cg9.fit_regularization"));
    /* the set-up's allocations counted once; then each of the last 60 (the assembly and the factorisation:
     * the CG set-up before them is the existing code's) and the first 10 refused in turn */
    tu_alloc fa = TU_ALLOC_INIT;
    fp.regularization = 1e-3;
    tu_alloc_install(f.ctx, &fa);
    ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, 0, NULL, NULL, &fp, &fit), WT_OK);
    const long total = fa.count;
    wt_fitting_free(fit);
    ck_assert_int_eq(fa.live, 0);
    ck_assert_int_gt(total, 70);
    for (long b = 0; b < total; b++) {
        if (b == 10) b = total - 60;
        fit = (wt_fitting *)&f;
        fa.count = 0;
        fa.live = 0;
        tu_alloc_fail_nth(&fa, b);
        const int st = wt_fitting_alloc(f.ctx, f.sys, 0, NULL, NULL, &fp, &fit);
        ck_assert_msg(st == WT_ERR_NOMEM, "allocation %ld of %ld refused: status %d", b, total, st);
        ck_assert_ptr_null(fit);
        ck_assert_int_eq(fa.live, 0);
    }
    wt_context_set_allocator(f.ctx, NULL, NULL, NULL);
}
END_TEST

START_TEST(test_fitting_recovers_dm_shape)
{
    const char *set[] = {"recon.cg9.fit_regularization=1e-9"};
    fixture f;
    setup(&f, DEMO, -1, 1, set);
    const wt_system *sys = f.sys;
    wt_grid layers[WT_MAX_DMS];
    double alts[WT_MAX_DMS];
    int64_t off[WT_MAX_DMS + 1] = {0};
    for (int k = 0; k < sys->dm->ndms; k++) {
        /* a layer grid at the DM pitch, large enough to hold the actuator grid */
        int n = 64;
        layers[k] = wt_grid_layer(n, sys->dm->grid[k].dx);
        alts[k] = sys->dm->altitude[k];
        off[k + 1] = off[k] + wt_grid_size(&layers[k]);
    }
    wt_fitting *fit;
    const wt_fitting_params fp = {.regularization = 1e-9, .sampling = 1};
    ck_assert_int_eq(wt_fitting_alloc(f.ctx, sys, sys->dm->ndms, layers, alts, &fp, &fit), WT_OK);
    int64_t na = sys->nact;
    double *a0 = malloc(na * sizeof *a0), *a = calloc(na, sizeof *a), *grid = calloc(wt_dm_grid_points(sys->dm), sizeof *grid);
    double *phi = calloc(off[sys->dm->ndms], sizeof *phi);
    tu_randn(a0, na, 41);
    wt_dm_expand(sys->dm, a0, grid);
    int64_t p = 0;
    for (int k = 0; k < sys->dm->ndms; k++) {
        const wt_grid *g = &sys->dm->grid[k];
        for (int iy = 0; iy < g->ny; iy++)
            for (int ix = 0; ix < g->nx; ix++) {
                double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
                int lx = (int)lround((x - layers[k].x0) / layers[k].dx), ly = (int)lround((y - layers[k].y0) / layers[k].dx);
                phi[off[k] + lx + (int64_t)layers[k].nx * ly] = grid[p + ix + (int64_t)g->nx * iy];
            }
        p += wt_grid_size(g);
    }
    /* symmetry of the fitting operator */
    double *u = malloc(na * sizeof *u), *v = malloc(na * sizeof *v), *fu = malloc(na * sizeof *fu), *fv = malloc(na * sizeof *fv);
    tu_randn(u, na, 42);
    tu_randn(v, na, 43);
    tu_fitting_apply(fit, na, u, fu);
    tu_fitting_apply(fit, na, v, fv);
    ck_assert_rel(tu_dot(u, fv, na), tu_dot(v, fu, na), 1e-12, 0.0);
    wt_pcg_result r;
    wt_fitting_solve(fit, phi, a, 2000, 1e-12, NULL, &r);
    /* compare H_j a with H_j a0 in every direction */
    double *ga = calloc(wt_dm_grid_points(sys->dm), sizeof *ga);
    wt_dm_expand(sys->dm, a, ga);
    double worst = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        wt_projection *h;
        ck_assert_int_eq(wt_projection_alloc(f.ctx, sys->dm->ndms, sys->dm->grid, sys->dm->altitude, 0.0, sys->eval_x[j],
                                             sys->eval_y[j], &sys->corner_grid, sys->corner_mask, 1, &h),
                         WT_OK);
        int64_t nc = wt_grid_size(&sys->corner_grid);
        double *p1 = calloc(nc, sizeof *p1), *p2 = calloc(nc, sizeof *p2);
        wt_projection_apply(h, 1.0, ga, p1);
        wt_projection_apply(h, 1.0, grid, p2);
        worst = fmax(worst, tu_rel_diff(p1, p2, nc));
        free(p1), free(p2);
        wt_projection_free(h);
    }
    /* ε = 1e-9 of the mean diagonal perturbs the solution by O(1e-9 κ); 1e-5 leaves room for the
     * weakly seen corners */
    ck_assert_msg(worst < 1e-5, "fitted DM phase differs from the true one by %g", worst);
    free(a0), free(a), free(grid), free(phi), free(u), free(v), free(fu), free(fv), free(ga);
    wt_fitting_free(fit);
    teardown(&f);
}
END_TEST

/* The fitting's warm start continued (wt_fitting_solve_continue), as the reconstructor runs it frame after
 * frame: the CG-9 fitting of drifting layers gives the warm-started solutions up to rounding (8 frames of
 * 10 iterations; bound as for the tomography above), and after a wt_fitting_solve_maps on the same
 * object, or on other commands, the next continue is a fresh warm-started solve, bit for bit. */
START_TEST(test_fitting_continue_matches_warm_start)
{
    fixture f, g;
    setup(&f, DEMO, 1, 0, NULL);
    setup(&g, DEMO, 1, 0, NULL);
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    wt_fitting *fa, *fb;
    const wt_fitting_params fp = {.regularization = f.cfg->cg9.fit_regularization, .sampling = 2};
    ck_assert_int_eq(wt_fitting_alloc_for(f.ctx, f.t, &fp, &fa), WT_OK);
    ck_assert_int_eq(wt_fitting_alloc_for(g.ctx, g.t, &fp, &fb), WT_OK);
    const int64_t n = wt_tomography_nunknowns(f.t), na = f.sys->nact;
    double *c = malloc(n * sizeof *c), *dc = malloc(n * sizeof *dc), *phi = malloc(n * sizeof *phi);
    double *aa = calloc(na, sizeof *aa), *ab = calloc(na, sizeof *ab), *ac = calloc(na, sizeof *ac);
    tu_randn(c, n, 61);
    double worst = 0.0;
    for (int frame = 0; frame < 8; frame++) {
        if (frame > 0) {
            tu_randn(dc, n, 70 + frame);
            for (int64_t i = 0; i < n; i++) c[i] += 0.1 * dc[i];
        }
        wt_tomography_layers(f.t, c, phi);
        ck_assert_int_eq(wt_fitting_solve(fa, phi, aa, 10, 0.0, NULL, NULL), WT_OK);
        ck_assert_int_eq(wt_fitting_solve_continue(fb, phi, ab, 10, 0.0, NULL, NULL), WT_OK);
        const double e = tu_rel_diff(ab, aa, na);
        if (e > worst) worst = e;
    }
    fprintf(stderr, "fitting continue: largest relative difference from warm starts %g\n", worst);
    ck_assert_msg(worst <= 1e-9 && worst > 0.0, "continued fittings differ from warm starts by %g", worst);
    /* a maps solve in between (its own commands) leaves nothing to continue from */
    const wt_grid *sg = wt_fitting_sample_grid(fb);
    double *maps = calloc((size_t)wt_grid_size(sg) * f.sys->neval, sizeof *maps);
    ck_assert_int_ge(wt_fitting_solve_maps(fb, maps, ac, 2, 0.0, NULL), WT_OK);
    memcpy(aa, ab, na * sizeof *aa);
    ck_assert_int_eq(wt_fitting_solve_continue(fb, phi, ab, 10, 0.0, NULL, NULL), WT_OK);
    ck_assert_int_eq(wt_fitting_solve(fa, phi, aa, 10, 0.0, NULL, NULL), WT_OK);
    for (int64_t i = 0; i < na; i++) ck_assert(aa[i] == ab[i]);
    free(c), free(dc), free(phi), free(aa), free(ab), free(ac), free(maps);
    wt_fitting_free(fa);
    wt_fitting_free(fb);
    teardown(&g);
    teardown(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("fitting");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_checked_fixture(tc, demo_setup, demo_teardown);
    tcase_add_test(tc, test_epsilon_fried);
    tcase_add_test(tc, test_epsilon_pupil_grid);
    tcase_add_loop_test(tc, test_representable_maps, WT_FIT_CG, WT_FIT_CHOLESKY + 1);
    tcase_add_test(tc, test_assembled_equals_apply);
    tcase_add_loop_test(tc, test_cholesky_equals_converged_cg, 0, 2); /* factor read in fp64, fp32 */
    tcase_add_test(tc, test_cholesky_refusals);
    tcase_add_test(tc, test_operators_accumulate);
    suite_add_tcase(s, tc);
    TCase *tt = tcase_create("tomography"); /* the fitting after the tomography's solve */
    tcase_set_timeout(tt, 900);
    tcase_add_test(tt, test_fitting_recovers_dm_shape);
    tcase_add_test(tt, test_fitting_continue_matches_warm_start);
    suite_add_tcase(s, tt);
    return s;
}

TU_MAIN
