/* tests/test_mvm_predict.c: the predictive MVM (issue 36 item 1; builder/mvm_build.h `predict_adjoint`): R = E S_d M⁻¹
 * Ãᵀ Ĉ⁻¹, the commands of the layers moved by their wind over the loop's lead, as pcg3 and cg9 make them under
 * recon.predict. The test: the predictive MVM equals the predictive PCG-3 run to convergence on the same
 * slopes; and its identity holds the predictor (the wind and the lead), which a matrix without prediction does not. */
#include "mvm_fixture.h"

#include "builder/mvm_build.h"
#include "core/model/profile.h"
#include "core/model/reconstructor.h"
#include "core/op/shift.h"
#include "core/io/h5.h"
#include "core/solve/mvm.h"

/* The demo's model wind (5 layers, 8–25 m/s) over the lead of 2 frames at 500 Hz moves the layers by 1.6–10 cm of
 * their 0.5–1 m grids */
static wt_shift *predict_shift(fixture *f, int cg9, double sign)
{
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f->cfg, cg9 ? WT_RECON_CG9 : WT_RECON_PCG3, -1, &rp);
    ck_assert_double_gt(rp.predict_lead, 0.0);
    wt_shift *s = NULL;
    ck_assert_msg(wt_predict_shift_alloc(f->ctx, f->t, rp.tomography.natm, rp.tomography.atm_altitude,
                                         rp.tomography.atm_fraction, rp.atm_vx, rp.atm_vy, sign * rp.predict_lead,
                                         &s) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_int_gt(wt_shift_nmoving(s), 0);
    return s;
}

/* R s against the converged reconstructor whose layers are moved by S_d before the commands (pcg3: read at the
 * actuators; cg9: the fitting run to 1e-13): the bound of check_r_matches (float32 R, 1e-5). The commands without the
 * shift differ by far more (> 1e-3), so a builder that dropped the predictor fails. */
static void check_predictive(int cg9)
{
    fixture f;
    const char *set[] = {"recon.predict=true"};
    setup(&f, cg9, 1, set);
    wt_shift *adj = predict_shift(&f, cg9, -1.0), *fwd = predict_shift(&f, cg9, 1.0);
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    opt.commands = cg9 ? WT_MVM_FITTING : WT_MVM_LAYER_VALUES;
    opt.fit_regularization = f.cfg->cg9.fit_regularization;
    opt.fit_sampling = f.cfg->cg9.fit_sampling;
    opt.block = 100;
    opt.predict_adjoint = adj;
    wt_mvm *mv = NULL;
    ck_assert_msg(wt_mvm_build(f.ctx, f.t, &opt, &mv) == WT_OK, "%s", wt_error_message(f.ctx));
    double *s = malloc(f.ns * sizeof *s), *c = calloc(f.n, sizeof *c), *phi = malloc(f.n * sizeof *phi),
           *a = calloc(f.na, sizeof *a), *a0 = calloc(f.na, sizeof *a0), *ar = malloc(f.na * sizeof *ar);
    wt_fitting *fit = NULL;
    if (cg9) {
        wt_grid grids[WT_MAX_LAYERS];
        double alts[WT_MAX_LAYERS];
        const int L = wt_tomography_nlayers(f.t);
        for (int l = 0; l < L; l++) grids[l] = *wt_tomography_layer_grid(f.t, l), alts[l] = wt_tomography_layer_altitude(f.t, l);
        wt_fitting_params fp = {.regularization = f.cfg->cg9.fit_regularization, .sampling = f.cfg->cg9.fit_sampling};
        ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, L, grids, alts, &fp, &fit), WT_OK);
    }
    for (int trial = 0; trial < 2; trial++) {
        test_slopes(&f, s, 61 + trial);
        memset(c, 0, f.n * sizeof *c);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c, 20000, 1e-12, NULL, &res), WT_OK);
        wt_tomography_layers(f.t, c, phi);
        for (int moved = 0; moved < 2; moved++) {
            double *out = moved ? a : a0;
            if (moved) wt_shift_apply(fwd, phi);
            if (!cg9) pcg3_commands_of_layers(&f, phi, out);
            else {
                memset(out, 0, f.na * sizeof *out);
                ck_assert_int_eq(wt_fitting_solve(fit, phi, out, 20000, 1e-13, NULL, &res), WT_OK);
            }
        }
        apply_r(mv, s, ar);
        ck_assert_double_gt(tu_norm(a, f.na), 0.0);
        ck_assert_msg(tu_rel_diff(ar, a, f.na) <= 1e-5, "%s: R s is %g from the converged predictive commands",
                      cg9 ? "cg9" : "pcg3", tu_rel_diff(ar, a, f.na));
        ck_assert_msg(tu_rel_diff(a0, a, f.na) > 1e-3, "the shift moved the commands by %g only: the test cannot tell",
                      tu_rel_diff(a0, a, f.na));
    }
    wt_fitting_free(fit);
    free(s), free(c), free(phi), free(a), free(a0), free(ar);
    wt_shift_free(adj);
    wt_shift_free(fwd);
    wt_mvm_free(mv);
    teardown(&f);
}

START_TEST(test_predictive_r_pcg3) { check_predictive(0); }
END_TEST

START_TEST(test_predictive_r_cg9) { check_predictive(1); }
END_TEST

/* The demo predicting, with PCG-3 set to run to convergence (no warm start, relative residual 1e-11) on the paper's
 * prior (a quick MVM build): the configuration of the two tests against the converged reconstructor */
static void open_converging(wt_context *ctx, wt_config **cfg, wt_system **sys)
{
    const char *set[] = {"recon.predict=true", "recon.warm_start=false", "recon.pcg3.tolerance=1e-11",
                         "recon.prior=\"paper\""};
    ck_assert_msg(wt_config_read(ctx, DEMO, 4, set, cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, *cfg, sys) == WT_OK, "%s", wt_error_message(ctx));
}

/* Through the configuration, as `wavetomo build` and the loop make them: the MVM of recon.predict = true against the
 * PCG-3 reconstructor with recon.predict run to convergence (no warm start, 3000 iterations, relative residual 1e-11:
 * ~1e-7 in the solution on the demo, test_reconstructor.c) on the same slopes, 1e-5 (float32 R). The builder's
 * predictor is the reconstructor's: the same lead, the same wind compressed onto the same layers. */
START_TEST(test_predictive_mvm_equals_converged_pcg3)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    open_converging(ctx, &cfg, &sys);
    wt_mvm *m = NULL;
    ck_assert_msg(wt_mvm_build_variant(ctx, sys, cfg, "pcg3", NULL, &m) == WT_OK, "%s", wt_error_message(ctx));
    wt_reconstructor *rm = NULL, *rp = NULL;
    ck_assert_int_eq(wt_reconstructor_alloc_mvm(ctx, sys, m, &rm), WT_OK);
    wt_reconstructor_params par;
    wt_reconstructor_params_from_config(cfg, WT_RECON_PCG3, 3000, &par);
    ck_assert_double_gt(par.predict_lead, 0.0);
    ck_assert_msg(wt_reconstructor_alloc(ctx, sys, WT_RECON_PCG3, &par, &rp) == WT_OK, "%s", wt_error_message(ctx));
    const int64_t ns = sys->nslopes, na = sys->nact;
    double *s = malloc(ns * sizeof *s), *am = malloc(na * sizeof *am), *ap = malloc(na * sizeof *ap);
    tu_randn(s, ns, 9);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    ck_assert_int_eq(wt_reconstructor_apply(rm, s, am), WT_OK);
    ck_assert_int_eq(wt_reconstructor_apply(rp, s, ap), WT_OK);
    ck_assert_double_gt(tu_norm(ap, na), 0.0);
    ck_assert_msg(tu_rel_diff(am, ap, na) <= 1e-5, "the predictive MVM is %g from the converged predictive pcg3",
                  tu_rel_diff(am, ap, na));
    free(s), free(am), free(ap);
    wt_reconstructor_free(rm);
    wt_reconstructor_free(rp);
    wt_mvm_free(m);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* A learning loop's MVM (sim/adapt.h): rebuilt from an estimate on a grid of altitudes with its wind, it equals the
 * predictive PCG-3 that takes the same estimate (wt_reconstructor_set_model with the hats and winds compressed onto
 * its layers, as the loop hands it over) run to convergence, 1e-5 as above. The same rebuild with the wind reversed
 * is far from it (> 1e-3): the rebuild's predictor holds the estimate's wind, not the configuration's. Without a wind
 * the rebuild of a predictive matrix is refused. */
START_TEST(test_rebuilt_predictive_mvm_equals_converged_pcg3)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    open_converging(ctx, &cfg, &sys);
    enum { NG = 8 };
    const double grid[NG] = {0.0, 1000.0, 2000.0, 3000.0, 5000.0, 8000.0, 12000.0, 16000.0};
    const double frac[NG] = {0.40, 0.20, 0.05, 0.05, 0.10, 0.05, 0.10, 0.05};
    double vx[NG], vy[NG], rx[NG], ry[NG];
    for (int k = 0; k < NG; k++) { /* 6–34 m/s, none along the configuration's directions */
        const double v = 6.0 + 4.0 * k, d = 0.4 + 0.7 * k;
        vx[k] = v * cos(d), vy[k] = v * sin(d), rx[k] = -vx[k], ry[k] = -vy[k];
    }
    wt_mvm_rebuilder rb = {ctx, sys, "pcg3", NULL};
    wt_mvm *m = NULL, *mr = NULL;
    ck_assert_int_eq(wt_mvm_rebuild_model(&rb, 0.15, NG, grid, frac, NULL, NULL, 1, &m), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "recon.predict"));
    ck_assert_msg(wt_mvm_rebuild_model(&rb, 0.15, NG, grid, frac, vx, vy, 1, &m) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_mvm_rebuild_model(&rb, 0.15, NG, grid, frac, rx, ry, 1, &mr), WT_OK);
    wt_reconstructor *rm = NULL, *rmr = NULL, *rp = NULL;
    ck_assert_int_eq(wt_reconstructor_alloc_mvm(ctx, sys, m, &rm), WT_OK);
    ck_assert_int_eq(wt_reconstructor_alloc_mvm(ctx, sys, mr, &rmr), WT_OK);
    wt_reconstructor_params par;
    wt_reconstructor_params_from_config(cfg, WT_RECON_PCG3, 3000, &par);
    ck_assert_msg(wt_reconstructor_alloc(ctx, sys, WT_RECON_PCG3, &par, &rp) == WT_OK, "%s", wt_error_message(ctx));
    const int L = cfg->pcg3.nlayers;
    double rf[WT_MAX_LAYERS], rvx[WT_MAX_LAYERS], rvy[WT_MAX_LAYERS];
    wt_profile_compress_hats(NG, grid, frac, vx, vy, L, cfg->pcg3.altitudes, rf, rvx, rvy);
    ck_assert_msg(wt_reconstructor_set_model(rp, 0.15, L, cfg->pcg3.altitudes, rf, rvx, rvy) == WT_OK, "%s",
                  wt_error_message(ctx));
    const int64_t ns = sys->nslopes, na = sys->nact;
    double *s = malloc(ns * sizeof *s), *am = malloc(na * sizeof *am), *ar = malloc(na * sizeof *ar),
           *ap = malloc(na * sizeof *ap);
    tu_randn(s, ns, 10);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    ck_assert_int_eq(wt_reconstructor_apply(rm, s, am), WT_OK);
    ck_assert_int_eq(wt_reconstructor_apply(rmr, s, ar), WT_OK);
    ck_assert_int_eq(wt_reconstructor_apply(rp, s, ap), WT_OK);
    ck_assert_double_gt(tu_norm(ap, na), 0.0);
    ck_assert_msg(tu_rel_diff(am, ap, na) <= 1e-5, "the rebuilt predictive MVM is %g from the converged pcg3 of its model",
                  tu_rel_diff(am, ap, na));
    ck_assert_msg(tu_rel_diff(ar, ap, na) > 1e-3, "the reversed wind moved the rebuilt MVM by %g only",
                  tu_rel_diff(ar, ap, na));
    free(s), free(am), free(ar), free(ap);
    wt_reconstructor_free(rm);
    wt_reconstructor_free(rmr);
    wt_reconstructor_free(rp);
    wt_mvm_free(m);
    wt_mvm_free(mr);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The identity: recon.predict, its lead and the model's wind (and its error) change a predictive matrix's hash; without
 * prediction none of them is in it, so today's matrices keep theirs. A learned model, the layers' integrator and a run
 * that must not predict are refused for the MVM, naming the key. */
START_TEST(test_predictive_identity)
{
    wt_context *ctx = tu_context();
    const char *sets[][2] = {{"recon.predict=false", "loop.rate_hz=500.0"},
                             {"recon.predict=false", "recon.atmosphere.error_wind_speed_scale=1.5"},
                             {"recon.predict=true", "loop.rate_hz=500.0"},
                             {"recon.predict=true", "recon.atmosphere.error_wind_speed_scale=1.5"},
                             {"recon.predict=true", "loop.rate_hz=400.0"},
                             {"recon.predict=true", "recon.predict_lead_frames=3.0"},
                             {"recon.predict=true", "atmosphere.wind_speed_mps=[9.0, 10.0, 12.0, 18.0, 25.0]"}};
    enum { N = sizeof sets / sizeof *sets };
    char hash[N][80];
    for (int k = 0; k < N; k++) {
        wt_config *cfg = NULL;
        ck_assert_msg(wt_config_read(ctx, DEMO, 2, sets[k], &cfg) == WT_OK, "%d: %s", k, wt_error_message(ctx));
        snprintf(hash[k], sizeof hash[k], "%s", cfg->matrix_sha256);
        if (k == 2) {
            ck_assert_int_eq(wt_reconstructor_check_mvm_predict(ctx, cfg, WT_RECON_MVM, 0), WT_OK);
            ck_assert_int_eq(wt_reconstructor_check_mvm_predict(ctx, cfg, WT_RECON_MVM, 1), WT_ERR_CONFIG);
            ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "key 'recon.predict' = true"));
            ck_assert_int_eq(wt_reconstructor_check_mvm_predict(ctx, cfg, WT_RECON_PCG3, 1), WT_OK);
        }
        wt_config_free(ctx, cfg);
    }
    ck_assert_str_eq(hash[0], hash[1]); /* without prediction the wind is not the matrix's */
    for (int k = 2; k < N; k++) {
        ck_assert_msg(strcmp(hash[0], hash[k]), "setting %d: a predictive matrix has the hash of one without", k);
        for (int j = 2; j < k; j++) ck_assert_msg(strcmp(hash[j], hash[k]), "settings %d and %d: the same hash", j, k);
    }
    const char *bad[][2] = {{"recon.predict=true", "recon.predict_integrator=\"layers\""},
                            {"recon.predict=true", "recon.atmosphere.learn_wind=\"aligned\""}};
    const char *key[] = {"recon.predict_integrator", "recon.atmosphere.learn_wind"};
    const char *file[] = {DEMO, "data/presets/demo-learned.cfg"};
    for (int k = 0; k < 2; k++) {
        wt_config *cfg = NULL;
        ck_assert_msg(wt_config_read(ctx, file[k], 2, bad[k], &cfg) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_eq(wt_reconstructor_check_mvm_predict(ctx, cfg, WT_RECON_MVM, 0), WT_ERR_CONFIG);
        ck_assert_msg(strstr(wt_error_message(ctx), key[k]), "%s", wt_error_message(ctx));
        wt_config_free(ctx, cfg);
    }
    {   /* a learned model whose wind is the start model's: the rebuilds hold it (test above) */
        const char *ok[] = {"recon.predict=true"};
        wt_config *cfg = NULL;
        ck_assert_msg(wt_config_read(ctx, "data/presets/demo-learned.cfg", 1, ok, &cfg) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_msg(wt_reconstructor_check_mvm_predict(ctx, cfg, WT_RECON_MVM, 0) == WT_OK, "%s", wt_error_message(ctx));
        wt_config_free(ctx, cfg);
    }
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mvm_predict");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 600);
    tcase_add_test(tc, test_predictive_r_pcg3);
    tcase_add_test(tc, test_predictive_r_cg9);
    tcase_add_test(tc, test_predictive_mvm_equals_converged_pcg3);
    tcase_add_test(tc, test_rebuilt_predictive_mvm_equals_converged_pcg3);
    tcase_add_test(tc, test_predictive_identity);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
