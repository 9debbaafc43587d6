/* tests/test_mvm.c: the offline MVM builder (builder/mvm_build.c, core/la/chol.c; SPEC §9): the assembled
 * Ã against the matrix-free slopes, the factorised M = N + B Q Bᵀ against the matrix-free normal
 * operator and PCG, R s against the converged matrix-free reconstructors (pcg3 and cg9), RÂ, the
 * orderings, the memory budget and the error paths (the LGS focus removal: test_mvm_focus.c). */
#include "mvm_fixture.h"

/* Ã assembled column by column from the wavelet templates equals the matrix-free Γ P W⁻¹. Both are
 * sums of a few hundred double products per slope: 1e-12 relative is rounding, any wrong template
 * shift, layer offset, sensor row offset or weight is O(1). */
START_TEST(test_atilde_matches_slopes)
{
    for (int v = 0; v < 2; v++) {
        fixture f;
        setup(&f, v, 0, NULL);
        wt_sparse *A = NULL;
        ck_assert_msg(wt_mvm_assemble_atilde(f.ctx, f.t, &A) == WT_OK, "%s", wt_error_message(f.ctx));
        ck_assert_int_eq(A->nrow, f.ns);
        ck_assert_int_eq(A->ncol, f.n);
        double *c = malloc(f.n * sizeof *c), *y1 = calloc(f.ns, sizeof *y1), *y2 = malloc(f.ns * sizeof *y2);
        tu_randn(c, f.n, 21 + v);
        wt_sparse_apply(A, 1.0, c, y1);
        tu_tomo_slopes(f.t, c, y2);
        ck_assert_double_gt(tu_norm(y2, f.ns), 0.0);
        ck_assert_double_le(tu_rel_diff(y1, y2, f.ns), 1e-12);
        /* per sensor too, so that a small sensor (the NGS) cannot hide in the norm of the LGS */
        for (int m = 0; m < f.sys->nsensors; m++) {
            const wt_sensor *s = &f.sys->sensors[m];
            ck_assert_msg(tu_rel_diff(y1 + s->offset, y2 + s->offset, s->nslopes) <= 1e-12, "variant %d sensor %s", v,
                          s->name);
        }
        /* every column sorted (CHOLMOD and the builder rely on it) */
        for (int64_t j = 0; j < A->ncol; j++)
            for (int64_t k = A->colptr[j] + 1; k < A->colptr[j + 1]; k++) ck_assert(A->rowind[k] > A->rowind[k - 1]);
        free(c);
        free(y1);
        free(y2);
        wt_sparse_free(A);
        teardown(&f);
    }
}
END_TEST

/* The full prior (α W C_φ⁻¹ Wᵀ on every layer) makes N dense: the builder forms and factorises it by
 * LAPACK instead of CHOLMOD. The tests below run both paths: v = 0, 1 pcg3 / cg9 with the diagonal
 * prior, v = 2, 3 the same with the full one. */
static const char *const full_prior[2][1] = {{"recon.pcg3.prior=\"full\""}, {"recon.cg9.prior=\"full\""}};
static void setup_v(fixture *f, int v) { setup(f, v & 1, v >> 1, v >> 1 ? full_prior[v & 1] : NULL); }


/* N + B Q Bᵀ is the matrix-free M (tip-tilt removal and NGS in the low-rank part): same sums in another
 * order, 1e-12 relative. The rank is 4 per LGS plus the NGS slopes. With the full prior the dense N's
 * layer blocks are the operator's own prior columns (FFT round trips: rounding 1e-15 of the prior). */
START_TEST(test_normal_apply_matches)
{
    for (int v = 0; v < 4; v++) {
        fixture f;
        setup_v(&f, v);
        ck_assert_int_eq(wt_tomography_full_prior(f.t), v >> 1);
        wt_mvm_normal *nm = normal(&f);
        int rank = 4 * f.sys->nlgs;
        for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
        ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
        ck_assert_int_eq(wt_mvm_normal_size(nm), f.n);
        double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2);
        for (int trial = 0; trial < 2; trial++) {
            tu_randn(x, f.n, 31 + trial);
            ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
            tu_tomo_apply(f.t, x, y2);
            ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
        }
        wt_mvm_stats st;
        wt_mvm_normal_stats(nm, &st);
        ck_assert_int_gt(st.nnz_normal, f.n);
        ck_assert_double_ge(st.nnz_factor, (double)st.nnz_normal); /* L holds at least N's upper pattern */
        if (v >> 1) {
            ck_assert_str_eq(st.ordering, "dense (LAPACK)");
            ck_assert_double_eq(st.nnz_factor, 0.5 * (double)f.n * (double)(f.n + 1));
        }
        free(x);
        free(y1);
        free(y2);
        wt_mvm_normal_free(nm);
        teardown(&f);
    }
}
END_TEST

/* M⁻¹ b by CHOLMOD (LAPACK with the full prior) + Woodbury equals PCG run to 1e-12. The direct solve's own residual through the
 * matrix-free M must be at rounding level (1e-10 allows κ ~ 1e5 times ε); the two solutions agree to
 * 1e-9 (PCG's residual 1e-12 times the condition number of M). Several right-hand sides at once check
 * the block path. */
START_TEST(test_normal_solve_matches_pcg)
{
    for (int v = 0; v < 4; v++) {
        fixture f;
        setup_v(&f, v);
        wt_mvm_normal *nm = normal(&f);
        const int k = 3;
        double *s = malloc(f.ns * sizeof *s), *b = malloc(k * f.n * sizeof *b), *x = malloc(k * f.n * sizeof *x),
               *xp = calloc(f.n, sizeof *xp), *r = malloc(f.n * sizeof *r);
        for (int j = 0; j < k; j++) {
            test_slopes(&f, s, 41 + 7 * j);
            tu_tomo_rhs(f.t, s, b + j * f.n);
        }
        ck_assert_int_eq(wt_mvm_normal_solve(nm, k, b, x), WT_OK);
        for (int j = 0; j < k; j++) {
            tu_tomo_apply(f.t, x + j * f.n, r);
            ck_assert_double_le(tu_rel_diff(r, b + j * f.n, f.n), 1e-10);
        }
        test_slopes(&f, s, 41 + 7 * (k - 1));
        wt_pcg_result res;
        int st = wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, xp, 20000, 1e-12, NULL, &res);
        ck_assert_msg(st == WT_OK, "PCG did not converge: %d its, %g", res.iterations, res.rel_resid);
        ck_assert_double_le(tu_rel_diff(x + (k - 1) * f.n, xp, f.n), 1e-9);
        free(s);
        free(b);
        free(x);
        free(xp);
        free(r);
        wt_mvm_normal_free(nm);
        teardown(&f);
    }
}
END_TEST


START_TEST(test_r_matches_pcg3) { check_r_matches(0, 0, NULL); }
END_TEST

/* The same with layers between the DMs (1 m layers at 1 and 8 km, split onto the DMs around them and
 * interpolated at DM 1's 0.5 m actuators): the MVM stays the exact MAP of the PCG-3 system. */
static const char *const pcg3_split[] = {"recon.pcg3.layer_altitudes_m=[0.0, 1000.0, 4000.0, 8000.0, 12700.0]",
                                         "recon.pcg3.layer_spacing_m=[0.5, 1.0, 1.0, 1.0, 1.0]",
                                         "recon.pcg3.layer_size=[32, 16, 16, 32, 32]"};
START_TEST(test_r_matches_pcg3_split) { check_r_matches(0, 3, pcg3_split); }
END_TEST

START_TEST(test_r_matches_cg9) { check_r_matches(1, 0, NULL); }
END_TEST

/* The full prior: the dense path's R is the converged matrix-free MAP with the full prior, both variants. */
START_TEST(test_r_matches_full_prior)
{
    check_r_matches(0, 1, full_prior[0]);
    check_r_matches(1, 1, full_prior[1]);
}
END_TEST

/* The pcg3 system with the paper's prior ("pcg3" test case), and its MVM too ("pcg3_matrix"): checked fixtures,
 * made in each test's own process. Not unchecked ones, made once before the forks: the set-up runs OpenMP
 * regions, and GCC's OpenMP thread pool does not survive fork (a test's first parallel region then waits on the
 * parent's threads forever). */
static fixture F;
static wt_mvm *MV;
static void pcg3_setup(void) { setup(&F, 0, 0, NULL); }
static void pcg3_teardown(void) { teardown(&F); }
static void pcg3_matrix_setup(void)
{
    pcg3_setup();
    build(&F, 0, &MV);
}
static void pcg3_matrix_teardown(void)
{
    wt_mvm_free(MV);
    pcg3_teardown();
}

/* RÂ = R · Â with the dense Â: the builder forms it from the double-precision rows before rounding,
 * so the difference to float R times Â is float rounding of R (6e-8) amplified by cancellation in the
 * sums; 1e-5 relative per row. */
START_TEST(test_ra_matches)
{
    fixture f = F;
    const wt_mvm *mv = MV;
    wt_interaction *ia = NULL;
    ck_assert_int_eq(wt_interaction_alloc(f.ctx, f.sys, &ia), WT_OK);
    double *ahat = calloc(f.ns * f.na, sizeof *ahat), *e = calloc(f.na, sizeof *e), *rf = malloc(f.ns * f.na * sizeof *rf),
           *ref = malloc(f.na * f.na * sizeof *ref), *got = malloc(f.na * sizeof *got);
    for (int64_t k = 0; k < f.na; k++) { /* dense Â column by column, matrix-free */
        e[k] = 1.0;
        wt_interaction_apply(ia, 1.0, e, ahat + k * f.ns);
        e[k] = 0.0;
    }
    for (int64_t i = 0; i < f.na * f.ns; i++) rf[i] = mv->R[i];
    /* ref = R Â: (na x ns row-major) · (ns x na column-major) */
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, (int)f.na, (int)f.na, (int)f.ns, 1.0, rf, (int)f.ns, ahat,
                (int)f.ns, 0.0, ref, (int)f.na);
    for (int64_t i = 0; i < f.na; i++) {
        for (int64_t k = 0; k < f.na; k++) got[k] = mv->RA[i * f.na + k];
        ck_assert_msg(tu_rel_diff(got, ref + i * f.na, f.na) <= 1e-5, "row %lld: %g", (long long)i,
                      tu_rel_diff(got, ref + i * f.na, f.na));
    }
    free(ahat);
    free(e);
    free(rf);
    free(ref);
    free(got);
    wt_interaction_free(ia);
}
END_TEST

/* Orderings: rows follow the actuators DM by DM in grid order, columns the slopes sensor by sensor.
 * A ground-DM actuator's command depends most on the ground-layer gradient next to it, so in an LGS
 * block of its row the subaperture of largest weight |R_x| + |R_y| is usually one of the four that
 * share the actuator's corner (0.35 m away; 84 % of the cases on the demo, the rest pulled elsewhere by
 * the global tip-tilt and the other layers); a transposed or shuffled layout makes that a 4/nsub
 * chance. Checked on the interior actuators of DM 1 (the rim is distorted by the pupil edge),
 * requiring 70 %. */
START_TEST(test_orderings)
{
    fixture f = F;
    const wt_mvm *mv = MV;
    ck_assert_int_eq(mv->nact, f.sys->nact);
    ck_assert_int_eq(mv->nslopes, f.sys->nslopes);
    const wt_grid *dg = &f.sys->dm->grid[0];
    const double rin = 0.5 * f.cfg->obstruction * f.cfg->diameter + 1.0, rout = 0.5 * f.cfg->diameter - 1.0;
    int good = 0, total = 0;
    int64_t q = 0;
    for (int iy = 0; iy < dg->ny; iy++)
        for (int ix = 0; ix < dg->nx; ix++) {
            if (!f.sys->dm->active[0][ix + dg->nx * iy]) continue;
            int64_t i = q++;
            double x = dg->x0 + ix * dg->dx, y = dg->y0 + iy * dg->dx, r = hypot(x, y);
            if (r < rin || r > rout) continue;
            for (int m = 0; m < f.sys->nlgs; m++) {
                const wt_sensor *s = &f.sys->sensors[m];
                const float *row = mv->R + i * f.ns + s->offset;
                int best = 0;
                double bw = -1.0;
                for (int k = 0; k < s->nsub; k++) {
                    double w = fabs(row[k]) + fabs(row[s->nsub + k]);
                    if (w > bw) bw = w, best = k;
                }
                double cx, cy;
                wt_shack_hartmann_centre(s->sh, best, &cx, &cy);
                good += hypot(cx - x, cy - y) <= 0.75 * f.sys->d;
                total++;
            }
        }
    ck_assert_int_gt(total, 20);
    ck_assert_msg(good >= 0.7 * total, "only %d of %d largest weights next to their actuator", good, total);
}
END_TEST

/* The memory estimate refuses before allocating: a 1 MB budget stops at the first check, a budget one
 * byte below the build's own peak estimate stops at a later one; both name the bytes. */
START_TEST(test_budget_refuses)
{
    fixture f = F;
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    wt_mvm *mv = NULL;
    opt.memory_budget = 1e6;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_NOMEM);
    ck_assert_ptr_null(mv);
    const char *msg = wt_error_message(f.ctx);
    ck_assert_msg(strstr(msg, "bytes") && strstr(msg, "1000000"), "message: %s", msg);
    opt.memory_budget = 0.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_OK);
    double peak = mv->stats.peak_estimate;
    ck_assert_double_gt(peak, 4.0 * f.na * f.ns); /* R alone */
    ck_assert_double_gt(mv->stats.nnz_factor, 0.0);
    ck_assert_double_gt(mv->stats.t_total, 0.0);
    wt_mvm_free(mv);
    mv = NULL;
    opt.memory_budget = floor(peak) - 1.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_NOMEM);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "bytes"), "message: %s", wt_error_message(f.ctx));
    opt.memory_budget = peak + 1.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_OK);
    wt_mvm_free(mv);
}
END_TEST

/* A stop request between solve blocks ends the build with WT_ERR_INTERRUPTED, nothing returned, the message
 * naming the rows done; polled once per block but the last, so a stop that never fires costs the same bits. */
static int stop_after(void *user)
{
    int *calls = user;
    return ++*calls >= 2;
}
START_TEST(test_stop_between_blocks)
{
    fixture f = F;
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    opt.block = 8; /* several blocks on the test system */
    ck_assert_int_gt(f.na, 3 * opt.block);
    int calls = 0;
    opt.stop = stop_after, opt.stop_user = &calls;
    wt_mvm *mv = NULL;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_INTERRUPTED);
    ck_assert_ptr_null(mv);
    ck_assert_int_eq(calls, 2);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "after 16 of"), "message: %s", wt_error_message(f.ctx));
}
END_TEST

/* pcg3 needs a layer reaching every DM (a layer goes to the DMs around its altitude): layers at 0 and
 * 4 km only leave the 12.7 km DM 3 without any, refused naming the DM before any heavy work. */
START_TEST(test_pcg3_layer_mismatch_refused)
{
    const char *set[] = {"recon.pcg3.layer_altitudes_m=[0.0, 4000.0]", "recon.pcg3.layer_spacing_m=[0.5, 1.0]",
                         "recon.pcg3.layer_size=[32, 16]"};
    fixture f;
    setup(&f, 0, 3, set);
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    wt_mvm *mv = NULL;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "DM 3"), "message: %s", wt_error_message(f.ctx));
    teardown(&f);
}
END_TEST

/* CHOLMOD's failures come back as statuses naming the call: an indefinite matrix is WT_ERR_NUMERIC.
 * A small SPD one is solved to rounding. */
START_TEST(test_chol_errors_and_solve)
{
    wt_context *ctx = tu_context();
    wt_triplet *tr = NULL;
    wt_sparse *a = NULL;
    wt_chol *ch = NULL;
    /* [[1, 2], [2, 1]]: eigenvalues 3 and −1 */
    ck_assert_int_eq(wt_triplet_alloc(ctx, 2, 2, 3, &tr), WT_OK);
    wt_triplet_add(tr, 0, 0, 1.0);
    wt_triplet_add(tr, 0, 1, 2.0);
    wt_triplet_add(tr, 1, 1, 1.0);
    ck_assert_int_eq(wt_triplet_compress(tr, &a), WT_OK);
    wt_triplet_free(tr);
    ck_assert_int_eq(wt_chol_analyze(ctx, a, &ch), WT_OK);
    ck_assert_int_eq(wt_chol_factorize(ch, a), WT_ERR_NUMERIC);
    ck_assert_msg(strstr(wt_error_message(ctx), "cholmod_l_factorize"), "%s", wt_error_message(ctx));
    double b[2] = {1, 1}, x[2];
    ck_assert_int_eq(wt_chol_solve(ch, 1, b, 2, x, 2), WT_ERR_INVALID);
    wt_chol_free(ch);
    wt_sparse_free(a);
    /* [[4, 1], [1, 3]] x = [1, 2]: x = [1/11, 7/11] */
    ck_assert_int_eq(wt_triplet_alloc(ctx, 2, 2, 3, &tr), WT_OK);
    wt_triplet_add(tr, 0, 0, 4.0);
    wt_triplet_add(tr, 0, 1, 1.0);
    wt_triplet_add(tr, 1, 1, 3.0);
    ck_assert_int_eq(wt_triplet_compress(tr, &a), WT_OK);
    wt_triplet_free(tr);
    ck_assert_int_eq(wt_chol_analyze(ctx, a, &ch), WT_OK);
    ck_assert_int_eq(wt_chol_factorize(ch, a), WT_OK);
    b[1] = 2.0;
    ck_assert_int_eq(wt_chol_solve(ch, 1, b, 2, x, 2), WT_OK);
    ck_assert_rel(x[0], 1.0 / 11.0, 1e-14, 0.0);
    ck_assert_rel(x[1], 7.0 / 11.0, 1e-14, 0.0);
    wt_chol_info ci;
    wt_chol_info_get(ch, &ci);
    ck_assert_double_eq(ci.nnz_factor, 3.0);
    ck_assert_int_eq(ci.factorized, 1);
    wt_chol_free(ch);
    wt_sparse_free(a);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mvm");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_chol_errors_and_solve);
    tcase_add_test(tc, test_atilde_matches_slopes);
    tcase_add_test(tc, test_normal_apply_matches);
    tcase_add_test(tc, test_normal_solve_matches_pcg);
    tcase_add_test(tc, test_r_matches_pcg3);
    tcase_add_test(tc, test_r_matches_pcg3_split);
    tcase_add_test(tc, test_r_matches_cg9);
    tcase_add_test(tc, test_r_matches_full_prior);
    tcase_add_test(tc, test_pcg3_layer_mismatch_refused);
    suite_add_tcase(s, tc);
    TCase *tm = tcase_create("pcg3_matrix");
    tcase_set_timeout(tm, 300);
    tcase_add_checked_fixture(tm, pcg3_matrix_setup, pcg3_matrix_teardown);
    tcase_add_test(tm, test_ra_matches);
    tcase_add_test(tm, test_orderings);
    suite_add_tcase(s, tm);
    TCase *tp = tcase_create("pcg3");
    tcase_set_timeout(tp, 300);
    tcase_add_checked_fixture(tp, pcg3_setup, pcg3_teardown);
    tcase_add_test(tp, test_budget_refuses);
    tcase_add_test(tp, test_stop_between_blocks);
    suite_add_tcase(s, tp);
    return s;
}

TU_MAIN
