/* tests/test_mvm_focus.c: the offline MVM builder (builder/mvm_build.c; SPEC §9)
 * with the LGS focus removal (recon.lgs_focus_removal): the normal matrix and R s against PCG, the LGS focus
 * ignored, the refusals and the model error; and with the LGS's common focus only (recon.lgs_focus_mode =
 * "common"): the weight's projection, the normal matrix, R s, the common focus ignored, the refusals. */
#include "mvm_fixture.h"

/* ---- LGS focus removal (recon.lgs_focus_removal) ----------------------------------------------------- */
static const char *const focus_on[] = {"recon.lgs_focus_removal=true"};

/* The factorised normal equations' solve of the right-hand side of random slopes (s, b, x: scratch) equals PCG run
 * to convergence (xp) within 1e-9 */
static void solve_matches_pcg(fixture *f, wt_mvm_normal *nm, double *s, double *b, double *x, double *xp,
                              unsigned long seed)
{
    test_slopes(f, s, seed);
    tu_tomo_rhs(f->t, s, b);
    ck_assert_int_eq(wt_mvm_normal_solve(nm, 1, b, x), WT_OK);
    wt_pcg_result res;
    ck_assert_int_eq(wt_tomography_solve(f->t, wt_precond_pcg(f->p), s, xp, 20000, 1e-12, NULL, &res), WT_OK);
    ck_assert_double_le(tu_rel_diff(x, xp, f->n), 1e-9);
}

/* The factorised M with the focus in the low rank (6 per LGS) is the matrix-free M (1e-12, as above), and its
 * solve is PCG's converged one (1e-9, as above). */
START_TEST(test_focus_normal_matches)
{
    fixture f;
    setup(&f, 0, 1, focus_on);
    wt_mvm_normal *nm = normal(&f);
    int rank = 6 * f.sys->nlgs;
    for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
    ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
    double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2),
           *s = malloc(f.ns * sizeof *s), *xp = calloc(f.n, sizeof *xp);
    tu_randn(x, f.n, 71);
    ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
    tu_tomo_apply(f.t, x, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
    solve_matches_pcg(&f, nm, s, y1, x, xp, 72);
    free(x), free(y1), free(y2), free(s), free(xp);
    wt_mvm_normal_free(nm);
    teardown(&f);
}
END_TEST

/* R s = the converged pcg3 with the focus removal (the bound of check_r_matches) */
START_TEST(test_r_matches_pcg3_focus) { check_r_matches(0, 1, focus_on); }
END_TEST

/* ph = x² + y² on the sensing grid (a focus); returns the scale that makes its slopes on the first LGS 10 times the
 * rms of the slopes s */
static double focus_phase(const fixture *f, const double *s, double *ph)
{
    const wt_grid *g = &f->sys->sense_grid;
    const double rms = tu_norm(s, f->ns) / sqrt((double)f->ns);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            ph[ix + (int64_t)g->nx * iy] = x * x + y * y;
        }
    const wt_sensor *l1 = &f->sys->sensors[0];
    double *fs = calloc(l1->nslopes, sizeof *fs);
    wt_shack_hartmann_apply(l1->sh, 1.0, ph, fs);
    const double a = 10.0 * rms / (tu_norm(fs, l1->nslopes) / sqrt((double)l1->nslopes));
    free(fs);
    return a;
}

/* The LGS slopes of a pure focus phase φ = a r² (on the sensors' sample grid, through each LGS's own Γ: what a
 * sodium altitude change puts on every LGS) added to the slopes: with the focus removal the right-hand side
 * changes by rounding only (Ĉ⁻¹ Γ φ = 0: the Fried slopes of a quadratic are exactly ∝ the subaperture centres),
 * so the converged reconstruction by rounding times M's conditioning (1e-9); without it the reconstruction moves
 * by O(1) of its size (the focus is 10 times the slopes' rms). */
START_TEST(test_focus_slopes_ignored)
{
    for (int on = 0; on < 2; on++) {
        fixture f;
        setup(&f, 0, on, focus_on);
        const wt_grid *g = &f.sys->sense_grid;
        double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s),
               *s2 = malloc(f.ns * sizeof *s2), *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2),
               *c1 = calloc(f.n, sizeof *c1), *c2 = calloc(f.n, sizeof *c2);
        test_slopes(&f, s, 81);
        memcpy(s2, s, f.ns * sizeof *s);
        const double a = focus_phase(&f, s, ph);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, a, ph, s2 + l->offset);
        }
        tu_tomo_rhs(f.t, s, b1);
        tu_tomo_rhs(f.t, s2, b2);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c1, 20000, 1e-12, NULL, &res), WT_OK);
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s2, c2, 20000, 1e-12, NULL, &res), WT_OK);
        if (on) {
            /* the rhs sums ~ns terms of the 10× larger slopes: rounding ~ns ε × 10 of b */
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
            ck_assert_double_le(tu_rel_diff(c2, c1, f.n), 1e-9);
        } else {
            ck_assert_double_gt(tu_rel_diff(c2, c1, f.n), 0.1);
        }
        free(ph), free(s), free(s2), free(b1), free(b2), free(c1), free(c2);
        teardown(&f);
    }
}
END_TEST

/* Without an NGS that measures focus (three 1x1 tip-tilt sensors) the key is refused, naming it. */
START_TEST(test_focus_refused_without_ngs_focus)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_tomography *t = NULL;
    const char *set[] = {"recon.prior=\"paper\"", "recon.lgs_focus_removal=true", "ngs.subapertures=[1, 1, 1]"};
    ck_assert_msg(wt_config_read(ctx, DEMO, 3, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_ERR_CONFIG);
    ck_assert_ptr_null(t);
    ck_assert_msg(strstr(wt_error_message(ctx), "recon.lgs_focus_removal") != NULL, "%s", wt_error_message(ctx));
    ck_assert_msg(strstr(wt_error_message(ctx), "2x2") != NULL, "%s", wt_error_message(ctx));
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The layer-binning model error with the focus removal: the same draws' slopes, less their focus, so each LGS's
 * σ²_e is smaller by Σ (fᵀs)² / (2 nsub · draws) — positive for these random screens — and still > 0. */
START_TEST(test_focus_model_error)
{
    static const char *const me[] = {"recon.model_error=true", "recon.lgs_focus_removal=true",
                                     "recon.lgs_focus_mode=\"common\""};
    fixture off, on, co;
    setup(&off, 0, 1, me);
    setup(&on, 0, 2, me);
    setup(&co, 0, 3, me);
    for (int m = 0; m < off.sys->nlgs; m++) {
        const double a = wt_tomography_model_error(off.t, m), b = wt_tomography_model_error(on.t, m),
                     c = wt_tomography_model_error(co.t, m);
        ck_assert_double_gt(a, 0.0);
        ck_assert_double_gt(b, 0.0);
        ck_assert_msg(b < a, "LGS %d: %g with the focus removed, %g without", m, b, a);
        /* the common mode takes 1/n_LGS of each LGS's focus power: exactly between (rounding of the sums) */
        ck_assert_double_le(fabs(c - (a - (a - b) / off.sys->nlgs)), 1e-12 * a);
    }
    teardown(&off);
    teardown(&on);
    teardown(&co);
}
END_TEST


/* ---- The LGS's common focus only (recon.lgs_focus_mode = "common") -------------------------------------------- */
static const char *const common_on[] = {"recon.lgs_focus_removal=true", "recon.lgs_focus_mode=\"common\""};

/* y = Ĉ⁻¹ x over every sensor as the tomography weighs: the sensors' own weights plus the LGS's coupling term */
static void weigh_all(const fixture *f, const double *x, double *y)
{
    memset(y, 0, f->ns * sizeof *y);
    for (int m = 0; m < f->sys->nsensors; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        wt_noise_apply_weight(wt_tomography_noise(f->t, m), 1.0, x + s->offset, y + s->offset);
    }
    wt_tomography_weight_common(f->t, x, y);
}

/* x ← P x on the LGS slopes: each LGS's tip and tilt, then the common direction f_c = (e_1 … e_n)/√n, removed */
static void project_common(const fixture *f, double *x)
{
    const double *e = wt_tomography_common_focus(f->t);
    double a = 0.0;
    for (int m = 0; m < f->sys->nlgs; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        for (int h = 0; h < 2; h++) {
            double mean = 0.0;
            for (int i = 0; i < s->nsub; i++) mean += x[s->offset + h * s->nsub + i] / s->nsub;
            for (int i = 0; i < s->nsub; i++) x[s->offset + h * s->nsub + i] -= mean;
        }
        for (int i = 0; i < s->nslopes; i++) a += e[s->offset + i] * x[s->offset + i];
    }
    for (int m = 0; m < f->sys->nlgs; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        for (int i = 0; i < s->nslopes; i++) x[s->offset + i] -= a / f->sys->nlgs * e[s->offset + i];
    }
}

/* The weight is P C̃⁻¹ P with P the orthogonal projector that removes each LGS's tip-tilt and their common focus:
 * against that product formed explicitly (1e-12: the rank-2 form's sums in another order), symmetric (xᵀ W y = yᵀ W x),
 * zero on the common focus f_c and on each LGS's tip (1e-12 of W's size on a unit vector), and not on a differential
 * focus (e_1 − e_2: it keeps most of its weight, > 0.5 of what the tip-tilt-only weight gives it). The stacked
 * patterns are unit per LGS and ⟂ that LGS's tip and tilt. */
START_TEST(test_common_weight_projection)
{
    fixture f, g;
    setup(&f, 0, 2, common_on);
    setup(&g, 0, 0, NULL);
    const double *e = wt_tomography_common_focus(f.t);
    ck_assert_ptr_nonnull(e);
    ck_assert_ptr_null(wt_tomography_common_focus(g.t));
    for (int m = 0; m < f.sys->nsensors; m++) ck_assert_ptr_null(wt_noise_focus(wt_tomography_noise(f.t, m)));
    const int64_t ns = f.ns;
    double *x = malloc(ns * sizeof *x), *y = malloc(ns * sizeof *y), *w1 = malloc(ns * sizeof *w1),
           *w2 = calloc(ns, sizeof *w2), *px = malloc(ns * sizeof *px), *v = malloc(ns * sizeof *v);
    for (int m = 0; m < f.sys->nlgs; m++) {
        const wt_sensor *s = &f.sys->sensors[m];
        double nn = 0.0, sx = 0.0, sy = 0.0;
        for (int i = 0; i < s->nsub; i++) sx += e[s->offset + i], sy += e[s->offset + s->nsub + i];
        for (int i = 0; i < s->nslopes; i++) nn += e[s->offset + i] * e[s->offset + i];
        ck_assert_double_le(fabs(nn - 1.0), 1e-12);
        ck_assert_double_le(fabs(sx) + fabs(sy), 1e-12);
    }
    tu_randn(x, ns, 301);
    tu_randn(y, ns, 302);
    weigh_all(&f, x, w1);
    memcpy(px, x, ns * sizeof *x);
    project_common(&f, px);
    memset(v, 0, ns * sizeof *v);
    for (int m = 0; m < f.sys->nsensors; m++) {
        const wt_sensor *s = &f.sys->sensors[m];
        if (m < f.sys->nlgs) wt_noise_apply_inv(wt_tomography_noise(f.t, m), 1.0, px + s->offset, v + s->offset);
        else wt_noise_apply_weight(wt_tomography_noise(f.t, m), 1.0, x + s->offset, v + s->offset);
    }
    project_common(&f, v); /* (only the LGS's part: the NGS's weights have no projection) */
    ck_assert_double_le(tu_rel_diff(w1, v, ns), 1e-12);
    weigh_all(&f, y, w2);
    const double xy = tu_dot(x, w2, ns), yx = tu_dot(y, w1, ns);
    ck_assert_double_le(fabs(xy - yx), 1e-12 * tu_norm(x, ns) * tu_norm(w2, ns));
    /* f_c and a tip: annihilated */
    const double big = tu_norm(w1, ns) / tu_norm(x, ns);
    memset(x, 0, ns * sizeof *x);
    for (int m = 0; m < f.sys->nlgs; m++)
        for (int i = 0; i < f.sys->sensors[m].nslopes; i++) x[f.sys->sensors[m].offset + i] = e[f.sys->sensors[m].offset + i] / sqrt((double)f.sys->nlgs);
    weigh_all(&f, x, w1);
    ck_assert_double_le(tu_norm(w1, ns), 1e-12 * big);
    memset(x, 0, ns * sizeof *x);
    for (int i = 0; i < f.sys->sensors[1].nsub; i++) x[f.sys->sensors[1].offset + i] = 1.0;
    weigh_all(&f, x, w1);
    ck_assert_double_le(tu_norm(w1, ns), 1e-12 * big * sqrt((double)f.sys->sensors[1].nsub));
    /* e_1 − e_2: kept */
    memset(x, 0, ns * sizeof *x);
    for (int q = 0; q < 2; q++)
        for (int i = 0; i < f.sys->sensors[q].nslopes; i++)
            x[f.sys->sensors[q].offset + i] = (q ? -1.0 : 1.0) * e[f.sys->sensors[q].offset + i];
    weigh_all(&f, x, w1);
    weigh_all(&g, x, w2);
    ck_assert_double_gt(tu_dot(x, w1, ns), 0.5 * tu_dot(x, w2, ns));
    free(x), free(y), free(w1), free(w2), free(px), free(v);
    teardown(&f);
    teardown(&g);
}
END_TEST

/* The factorised M with the common focus in the low rank (4 per LGS + 2 in all) is the matrix-free M (1e-12), its
 * solve PCG's converged one (1e-9); R s = the converged pcg3 (1e-5): the bounds of the tests above. The fp32
 * operator with the mode is the double one to float accuracy (1e-5 relative on a random c). */
START_TEST(test_common_normal_matches)
{
    fixture f;
    setup(&f, 0, 2, common_on);
    wt_mvm_normal *nm = normal(&f);
    int rank = 4 * f.sys->nlgs + 2;
    for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
    ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
    double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2),
           *s = malloc(f.ns * sizeof *s), *xp = calloc(f.n, sizeof *xp);
    tu_randn(x, f.n, 311);
    ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
    tu_tomo_apply(f.t, x, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
    fixture g;
    const char *const f32[] = {common_on[0], common_on[1], "recon.pcg3.operator_precision=\"fp32\""};
    setup(&g, 0, 3, f32);
    tu_tomo_apply(g.t, x, y1);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-5);
    teardown(&g);
    solve_matches_pcg(&f, nm, s, y1, x, xp, 312);
    free(x), free(y1), free(y2), free(s), free(xp);
    wt_mvm_normal_free(nm);
    teardown(&f);
}
END_TEST

START_TEST(test_r_matches_pcg3_common) { check_r_matches(0, 2, common_on); }
END_TEST

/* A focus a r² on every LGS, the same a (a sodium altitude change), 10× the slopes' rms: with the common mode the
 * right-hand side moves by rounding only (1e-11) and the converged reconstruction by 1e-9, in double and in fp32
 * (float rounding of 10× larger slopes: 1e-5 of b). A differential focus (+a, −a, +a, −a: the same size, zero common
 * part) moves the reconstruction by > 10 %: the LGS still see how focus differs between their lines of sight. */
START_TEST(test_common_slopes_ignored)
{
    for (int v = 0; v < 3; v++) { /* 0 double common, 1 fp32 common, 2 double common with the differential focus */
        fixture f;
        const char *const f32[] = {common_on[0], common_on[1], "recon.pcg3.operator_precision=\"fp32\""};
        setup(&f, 0, v == 1 ? 3 : 2, f32);
        const wt_grid *g = &f.sys->sense_grid;
        double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s),
               *s2 = malloc(f.ns * sizeof *s2), *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2),
               *c1 = calloc(f.n, sizeof *c1), *c2 = calloc(f.n, sizeof *c2);
        test_slopes(&f, s, 321);
        memcpy(s2, s, f.ns * sizeof *s);
        const double a = focus_phase(&f, s, ph);
        ck_assert_int_eq(f.sys->nlgs % 2, 0);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, v == 2 && (m & 1) ? -a : a, ph, s2 + l->offset);
        }
        tu_tomo_rhs(f.t, s, b1);
        tu_tomo_rhs(f.t, s2, b2);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c1, 20000, v == 1 ? 1e-6 : 1e-12, NULL, &res), WT_OK);
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s2, c2, 20000, v == 1 ? 1e-6 : 1e-12, NULL, &res), WT_OK);
        if (v == 0) {
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
            ck_assert_double_le(tu_rel_diff(c2, c1, f.n), 1e-9);
        } else if (v == 1) {
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-5);
        } else {
            ck_assert_double_gt(tu_rel_diff(c2, c1, f.n), 0.1);
        }
        free(ph), free(s), free(s2), free(b1), free(b2), free(c1), free(c2);
        teardown(&f);
    }
}
END_TEST


/* The same in space (cg9 with the fourier preconditioner: the adjoint by layers, adjoint_space): the right-hand side
 * ignores the same focus on every LGS (1e-11) and not a differential one (> 10 % of b) */
START_TEST(test_common_slopes_ignored_space)
{
    const char *const set[] = {common_on[0], common_on[1], "recon.cg9.preconditioner=\"fourier\"",
                               "recon.cg9.coarse_levels=0", "recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]",
                               "recon.cg9.prior=\"full\""};
    fixture f;
    setup(&f, 1, 6, set);
    const wt_grid *g = &f.sys->sense_grid;
    double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s), *s2 = malloc(f.ns * sizeof *s2),
           *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2);
    test_slopes(&f, s, 331);
    const double rms = tu_norm(s, f.ns) / sqrt((double)f.ns);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            ph[ix + (int64_t)g->nx * iy] = x * x + y * y;
        }
    const wt_sensor *l1 = &f.sys->sensors[0];
    double *fs = calloc(l1->nslopes, sizeof *fs);
    wt_shack_hartmann_apply(l1->sh, 1.0, ph, fs);
    const double a = 10.0 * rms / (tu_norm(fs, l1->nslopes) / sqrt((double)l1->nslopes));
    free(fs);
    tu_tomo_rhs(f.t, s, b1);
    for (int diff = 0; diff < 2; diff++) {
        memcpy(s2, s, f.ns * sizeof *s);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, (diff && (m & 1) ? -a : a), ph, s2 + l->offset);
        }
        memset(b2, 0, f.n * sizeof *b2);
        tu_tomo_rhs(f.t, s2, b2);
        if (diff) ck_assert_double_gt(tu_rel_diff(b2, b1, f.n), 0.1);
        else ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
    }
    free(ph), free(s), free(s2), free(b1), free(b2);
    teardown(&f);
}
END_TEST

/* recon.lgs_focus_mode without the removal is refused naming both keys; an unknown mode naming the choices */
START_TEST(test_common_mode_refused)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    const char *set[] = {"recon.lgs_focus_mode=\"common\""};
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 1, set, &cfg), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "recon.lgs_focus_mode") && strstr(wt_error_message(ctx), "recon.lgs_focus_removal"),
                  "%s", wt_error_message(ctx));
    const char *set2[] = {"recon.lgs_focus_removal=true", "recon.lgs_focus_mode=\"mean\""};
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 2, set2, &cfg), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "\"common\""), "%s", wt_error_message(ctx));
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mvm_focus");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_focus_normal_matches);
    tcase_add_test(tc, test_r_matches_pcg3_focus);
    tcase_add_test(tc, test_focus_slopes_ignored);
    tcase_add_test(tc, test_focus_refused_without_ngs_focus);
    tcase_add_test(tc, test_focus_model_error);
    tcase_add_test(tc, test_common_weight_projection);
    tcase_add_test(tc, test_common_normal_matches);
    tcase_add_test(tc, test_r_matches_pcg3_common);
    tcase_add_test(tc, test_common_slopes_ignored);
    tcase_add_test(tc, test_common_slopes_ignored_space);
    tcase_add_test(tc, test_common_mode_refused);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
