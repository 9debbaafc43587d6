/* tests/test_reconstructor.c: slopes → commands (core/model/reconstructor.h, paper §6.1): a fixed
 * number of (P)CG iterations from a zero start is homogeneous (R(2s) = 2R(s) bit for bit: scaling by
 * a power of two commutes with every rounding), a converged one is linear, the MVM reconstructor is the
 * stored matrix's own apply (core/solve/mvm.h), and none is zero. */
#include "builder/mvm_build.h"
#include "core/la/sparse.h"
#include "core/model/reconstructor.h"
#include "core/model/params.h"
#include "runtime/control.h"
#include "testutil.h"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
} fixture;

static void setup(fixture *f, int nset, const char **set)
{
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, "data/presets/demo.cfg", nset, set, &f->cfg) == WT_OK, "%s",
                  wt_error_message(f->ctx));
    ck_assert_int_eq(wt_system_alloc(f->ctx, f->cfg, &f->sys), WT_OK);
}

static void teardown(fixture *f)
{
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static void apply(wt_reconstructor *r, const double *s, double *a)
{
    wt_reconstructor_reset(r);
    ck_assert_int_ge(wt_reconstructor_apply(r, s, a), WT_OK);
}

static void check_homogeneous(int kind)
{
    fixture f;
    const char *set[] = {"recon.warm_start=false"};
    setup(&f, 1, set);
    const int64_t ns = f.sys->nslopes, na = f.sys->nact;
    wt_reconstructor *r;
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f.cfg, kind, -1, &rp);
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, kind, &rp, &r), WT_OK);
    double *s = malloc(ns * sizeof *s), *s2 = malloc(ns * sizeof *s2), *a = malloc(na * sizeof *a),
           *a2 = malloc(na * sizeof *a2);
    tu_randn(s, ns, 3);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6, s2[i] = 2.0 * s[i];
    apply(r, s, a);
    apply(r, s2, a2);
    ck_assert_double_gt(tu_norm(a, na), 0.0);
    for (int64_t i = 0; i < na; i++) ck_assert_msg(a2[i] == 2.0 * a[i], "actuator %lld: %.17g vs 2 x %.17g", (long long)i, a2[i], a[i]);
    /* without warm start the same slopes give the same commands again */
    apply(r, s, a2);
    ck_assert(!memcmp(a, a2, na * sizeof *a));
    free(s), free(s2), free(a), free(a2);
    wt_reconstructor_free(r);
    teardown(&f);
}

START_TEST(test_pcg3_homogeneous) { check_homogeneous(WT_RECON_PCG3); }
END_TEST

START_TEST(test_cg9_homogeneous) { check_homogeneous(WT_RECON_CG9); }
END_TEST

/* PCG-3 run to convergence is the linear map M⁻¹ Ãᵀ Ĉ⁻¹ s read at the actuators:
 * R(s1 + s2) = R s1 + R s2 to the solver tolerance. */
START_TEST(test_pcg3_converged_linear)
{
    fixture f;
    const char *set[] = {"recon.warm_start=false", "recon.pcg3.tolerance=1e-11"};
    setup(&f, 2, set);
    const int64_t ns = f.sys->nslopes, na = f.sys->nact;
    wt_reconstructor *r;
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f.cfg, WT_RECON_PCG3, 3000, &rp);
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, WT_RECON_PCG3, &rp, &r), WT_OK);
    double *s1 = malloc(ns * sizeof *s1), *s2 = malloc(ns * sizeof *s2), *s3 = malloc(ns * sizeof *s3),
           *a1 = malloc(na * sizeof *a1), *a2 = malloc(na * sizeof *a2), *a3 = malloc(na * sizeof *a3);
    tu_randn(s1, ns, 4);
    tu_randn(s2, ns, 5);
    for (int64_t i = 0; i < ns; i++) s1[i] *= 1e-6, s2[i] *= 1e-6, s3[i] = s1[i] + s2[i];
    apply(r, s1, a1);
    apply(r, s2, a2);
    apply(r, s3, a3);
    for (int64_t i = 0; i < na; i++) a1[i] += a2[i];
    /* each solve stops at a relative residual 1e-11; the condition number of M (~1e4 on the demo)
     * turns that into ~1e-7 in the solution */
    ck_assert_double_le(tu_rel_diff(a1, a3, na), 1e-6);
    free(s1), free(s2), free(s3), free(a1), free(a2), free(a3);
    wt_reconstructor_free(r);
    teardown(&f);
}
END_TEST

/* pcg3's layers → commands map with a layer between the DMs (wt_reconstructor_command_map): a plane
 * φ = 1 + 0.3 x − 0.2 y [rad, x, y in m] on the 1 km layer only, between DM 1 (0 m) and DM 2 (4 km),
 * must give DM 1 (1 − 1/4) φ and DM 2 (1/4) φ at every actuator (the linear altitude split of the prior;
 * bilinear interpolation of the 1 m layer at the 0.5 m actuators is exact on a plane) and DM 3 nothing.
 * A wrong weight, a swapped DM, an interpolation off by a point or a dropped actuator is O(0.1). A DM
 * that no layer reaches is refused naming it. */
START_TEST(test_pcg3_command_map_split)
{
    fixture f;
    const char *set[] = {"recon.pcg3.layer_altitudes_m=[0.0, 1000.0, 4000.0, 12700.0]",
                         "recon.pcg3.layer_spacing_m=[0.5, 1.0, 1.0, 1.0]", "recon.pcg3.layer_size=[32, 16, 16, 32]"};
    setup(&f, 3, set);
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    wt_tomography *t = NULL;
    ck_assert_msg(wt_tomography_alloc(f.ctx, f.sys, &f.cfg->pcg3, "pcg3", &tp, &t) == WT_OK, "%s", wt_error_message(f.ctx));
    wt_sparse *st = NULL;
    ck_assert_msg(wt_reconstructor_command_map(f.ctx, t, &st) == WT_OK, "%s", wt_error_message(f.ctx));
    const int64_t n = wt_tomography_nunknowns(t), na = f.sys->nact;
    ck_assert_int_eq(st->nrow, n);
    ck_assert_int_eq(st->ncol, na);
    double *phi = calloc(n, sizeof *phi), *a = calloc(na, sizeof *a);
    const wt_grid *lg = wt_tomography_layer_grid(t, 1);
    double *layer = phi + wt_tomography_layer_offset(t, 1);
    for (int iy = 0; iy < lg->ny; iy++)
        for (int ix = 0; ix < lg->nx; ix++)
            layer[ix + lg->nx * iy] = 1.0 + 0.3 * (lg->x0 + ix * lg->dx) - 0.2 * (lg->y0 + iy * lg->dx);
    wt_sparse_apply_t(st, 1.0, phi, a);
    const wt_dm *dm = f.sys->dm;
    const double share[3] = {0.75, 0.25, 0.0};
    int64_t q = 0;
    for (int k = 0; k < dm->ndms; k++) {
        const wt_grid *dg = &dm->grid[k];
        for (int iy = 0; iy < dg->ny; iy++)
            for (int ix = 0; ix < dg->nx; ix++) {
                if (!dm->active[k][ix + (int64_t)dg->nx * iy]) continue;
                double want = share[k] * (1.0 + 0.3 * (dg->x0 + ix * dg->dx) - 0.2 * (dg->y0 + iy * dg->dx));
                ck_assert_msg(fabs(a[q] - want) <= 1e-12, "DM %d actuator (%d, %d): %.15g, want %.15g", k + 1, ix, iy,
                              a[q], want);
                q++;
            }
    }
    ck_assert_int_eq(q, na);
    free(phi), free(a);
    wt_sparse_free(st);
    wt_tomography_free(t);
    teardown(&f);

    /* layers at 0 and 4 km only: DM 3 (12.7 km) gets nothing */
    const char *bad[] = {"recon.pcg3.layer_altitudes_m=[0.0, 4000.0]", "recon.pcg3.layer_spacing_m=[0.5, 1.0]",
                         "recon.pcg3.layer_size=[32, 16]"};
    setup(&f, 3, bad);
    wt_reconstructor *r = NULL;
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f.cfg, WT_RECON_PCG3, -1, &rp);
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, WT_RECON_PCG3, &rp, &r), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "DM 3"), "message: %s", wt_error_message(f.ctx));
    teardown(&f);
}
END_TEST

/* mvm: a = R s_ol in float32, exactly what wt_mvm_apply gives; none: a = 0. */
START_TEST(test_mvm_and_none)
{
    fixture f;
    setup(&f, 0, NULL);
    const int64_t ns = f.sys->nslopes, na = f.sys->nact;
    wt_mvm *m;
    ck_assert_int_eq(wt_mvm_build_variant(f.ctx, f.sys, f.cfg, "pcg3", NULL, &m), WT_OK);
    wt_reconstructor *r, *z;
    ck_assert_int_eq(wt_reconstructor_alloc_mvm(f.ctx, f.sys, m, &r), WT_OK);
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, WT_RECON_NONE, NULL, &z), WT_OK);
    double *s = malloc(ns * sizeof *s), *a = malloc(na * sizeof *a);
    float *sf = malloc(ns * sizeof *sf), *af = malloc(na * sizeof *af);
    tu_randn(s, ns, 6);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6, sf[i] = (float)s[i];
    ck_assert_int_eq(wt_reconstructor_apply(r, s, a), WT_OK);
    wt_mvm_apply(m, sf, NULL, af);
    for (int64_t i = 0; i < na; i++) ck_assert(a[i] == (double)af[i]);
    ck_assert_double_gt(tu_norm(a, na), 0.0);
    /* a non-finite slope is refused before the GEMV */
    s[ns / 2] = NAN;
    ck_assert_int_eq(wt_reconstructor_apply(r, s, a), WT_ERR_NUMERIC);
    ck_assert_int_eq(wt_reconstructor_apply(z, s, a), WT_OK);
    for (int64_t i = 0; i < na; i++) ck_assert(a[i] == 0.0);
    free(s), free(a), free(sf), free(af);
    wt_reconstructor_free(r);
    wt_reconstructor_free(z);
    wt_mvm_free(m);
    teardown(&f);
}
END_TEST

/* recon.predict: with the model's wind zero the commands keep their bits (no layer moves: the same as without
 * prediction); with the demo's wind they change (by ≥ 1e-3 relative: the layers move by 2–8 cm of their 0.5–1 m
 * grids over the 4 ms lead, a few % of a random field's point-to-point difference). The shift itself is tested
 * exactly in test_shift. */
static void commands(const char *const *set, int nset, int kind, double *a, int64_t *na_out)
{
    fixture f;
    setup(&f, nset, (const char **)set);
    const int64_t ns = f.sys->nslopes;
    wt_reconstructor *r;
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f.cfg, kind, -1, &rp);
    ck_assert_msg(wt_reconstructor_alloc(f.ctx, f.sys, kind, &rp, &r) == WT_OK, "%s", wt_error_message(f.ctx));
    double *s = malloc(ns * sizeof *s);
    tu_randn(s, ns, 5);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    apply(r, s, a);
    *na_out = f.sys->nact;
    free(s);
    wt_reconstructor_free(r);
    teardown(&f);
}

START_TEST(test_predict)
{
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9; kind++) {
        double *a0 = malloc(20000 * sizeof *a0), *a1 = malloc(20000 * sizeof *a1), *a2 = malloc(20000 * sizeof *a2);
        int64_t na;
        const char *base[] = {"recon.warm_start=false"};
        const char *still[] = {"recon.warm_start=false", "recon.predict=true",
                               "atmosphere.wind_speed_mps=[0.0, 0.0, 0.0, 0.0, 0.0]"};
        const char *still0[] = {"recon.warm_start=false", "atmosphere.wind_speed_mps=[0.0, 0.0, 0.0, 0.0, 0.0]"};
        const char *moving[] = {"recon.warm_start=false", "recon.predict=true"};
        commands(still0, 2, kind, a0, &na);
        ck_assert_int_le(na, 20000);
        commands(still, 3, kind, a1, &na);
        ck_assert_msg(!memcmp(a0, a1, na * sizeof *a0), "%s: zero wind with recon.predict changed the commands",
                      wt_reconstructor_name(kind));
        commands(base, 1, kind, a0, &na);
        commands(moving, 2, kind, a2, &na);
        ck_assert_msg(tu_rel_diff(a2, a0, na) > 1e-3, "%s: the wind moved nothing (%g)", wt_reconstructor_name(kind),
                      tu_rel_diff(a2, a0, na));
        /* recon.predict_lead_frames: the loop's delay (2 frames) given explicitly keeps the bits; a lead of 4 frames
         * moves each layer as the delay does at twice the wind (v τ: the products differ by powers of two only) */
        const char *lead2[] = {"recon.warm_start=false", "recon.predict=true", "recon.predict_lead_frames=2.0"};
        commands(lead2, 3, kind, a1, &na);
        ck_assert_msg(!memcmp(a1, a2, na * sizeof *a1), "%s: lead = delay changed the bits", wt_reconstructor_name(kind));
        const char *lead4[] = {"recon.warm_start=false", "recon.predict=true", "recon.predict_lead_frames=4.0"};
        const char *fast[] = {"recon.warm_start=false", "recon.predict=true",
                              "atmosphere.wind_speed_mps=[16.0, 20.0, 24.0, 36.0, 50.0]"};
        commands(lead4, 3, kind, a1, &na);
        commands(fast, 3, kind, a0, &na);
        ck_assert_msg(!memcmp(a0, a1, na * sizeof *a0), "%s: a lead of 4 frames is not twice the wind over 2",
                      wt_reconstructor_name(kind));
        ck_assert_double_gt(tu_rel_diff(a1, a2, na), 1e-3);
        free(a0), free(a1), free(a2);
    }
}
END_TEST

/* recon.predict_integrator = "layers" (the loop's integrator on the layers, reconstructor.h) against the control's
 * integrator on the commands, frame by frame over 8 frames of random slopes (the commands a_{t+2} each queues), delay 2, gain 0.4: with every wind zero
 * the two laws are one (z_{t+d} = z_{t+d−1} + g (φ_t − z_t) and a = F z, F linear: pcg3's command map, cg9's
 * Cholesky fitting), so the commands agree to rounding (1e-12 relative: a few roundings of each product); with the
 * demo's wind they differ (the state moves by the wind every frame, by 2–8 cm of the 0.5–1 m grids: ≥ 1e-3). */
static void run_law(const char *const *set, int nset, int kind, int K, double *out, int64_t *na_out, int *integrates)
{
    fixture f;
    setup(&f, nset, (const char **)set);
    const int64_t ns = f.sys->nslopes, na = f.sys->nact;
    wt_reconstructor *r;
    wt_reconstructor_params rp;
    wt_reconstructor_params_from_config(f.cfg, kind, -1, &rp);
    ck_assert_msg(wt_reconstructor_alloc(f.ctx, f.sys, kind, &rp, &r) == WT_OK, "%s", wt_error_message(f.ctx));
    wt_control *c;
    *integrates = wt_reconstructor_integrates(r);
    /* the reconstructor integrates exactly when the configuration asks for it; the control then applies its result
     * (as sim/loop.c and runtime/rtc.c set it) */
    ck_assert_int_eq(*integrates, f.cfg->predict && f.cfg->predict_integrator == 1);
    wt_control_params cp = wt_control_params_from_config(f.cfg);
    cp.direct = *integrates;
    ck_assert_int_eq(wt_control_alloc(f.ctx, f.sys, &cp, &c), WT_OK);
    double *s = malloc(ns * sizeof *s), *rec = malloc(na * sizeof *rec);
    for (int t = 0; t < K; t++) {
        tu_randn(s, ns, 40 + t);
        for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
        ck_assert_int_ge(wt_reconstructor_apply(r, s, rec), WT_OK);
        const double *next = wt_control_step(c, rec, wt_control_applied(c));
        memcpy(out + (size_t)t * na, next, na * sizeof *out);
    }
    *na_out = na;
    free(s), free(rec);
    wt_control_free(c);
    wt_reconstructor_free(r);
    teardown(&f);
}

START_TEST(test_predict_integrator)
{
    const int K = 8;
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9; kind++) {
        double *a0 = malloc((size_t)K * 20000 * sizeof *a0), *a1 = malloc((size_t)K * 20000 * sizeof *a1);
        int64_t na;
        int i0, i1;
        const char *cmd0[] = {"recon.predict=true", "recon.cg9.fit_solver=\"cholesky\"",
                              "atmosphere.wind_speed_mps=[0.0, 0.0, 0.0, 0.0, 0.0]"};
        const char *lay0[] = {"recon.predict=true", "recon.cg9.fit_solver=\"cholesky\"",
                              "atmosphere.wind_speed_mps=[0.0, 0.0, 0.0, 0.0, 0.0]", "recon.predict_integrator=\"layers\""};
        run_law(cmd0, 3, kind, K, a0, &na, &i0);
        ck_assert_int_le(na, 20000);
        run_law(lay0, 4, kind, K, a1, &na, &i1);
        ck_assert(!i0 && i1);
        for (int t = 0; t < K; t++) {
            const double *x = a0 + (size_t)t * na, *y = a1 + (size_t)t * na;
            ck_assert_msg(tu_rel_diff(y, x, na) < 1e-12, "%s, frame %d: the laws differ by %g with no wind",
                          wt_reconstructor_name(kind), t, tu_rel_diff(y, x, na));
        }
        const char *lay[] = {"recon.predict=true", "recon.cg9.fit_solver=\"cholesky\"", "recon.predict_integrator=\"layers\""};
        const char *cmd[] = {"recon.predict=true", "recon.cg9.fit_solver=\"cholesky\""};
        run_law(cmd, 2, kind, K, a0, &na, &i0);
        run_law(lay, 3, kind, K, a1, &na, &i1);
        const double *x = a0 + (size_t)(K - 1) * na, *y = a1 + (size_t)(K - 1) * na;
        ck_assert_msg(tu_rel_diff(y, x, na) > 1e-3, "%s: the layers' integrator moved nothing (%g)",
                      wt_reconstructor_name(kind), tu_rel_diff(y, x, na));
        /* without recon.predict the key changes nothing: the commands' law, bit for bit */
        const char *off[] = {"recon.cg9.fit_solver=\"cholesky\"", "recon.predict_integrator=\"layers\""};
        const char *off0[] = {"recon.cg9.fit_solver=\"cholesky\""};
        run_law(off0, 1, kind, K, a0, &na, &i0);
        run_law(off, 2, kind, K, a1, &na, &i1);
        ck_assert(!i1 && !memcmp(a0, a1, (size_t)K * na * sizeof *a0));
        free(a0), free(a1);
    }
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("reconstructor");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_pcg3_homogeneous);
    tcase_add_test(tc, test_cg9_homogeneous);
    tcase_add_test(tc, test_pcg3_converged_linear);
    tcase_add_test(tc, test_mvm_and_none);
    tcase_add_test(tc, test_pcg3_command_map_split);
    tcase_add_test(tc, test_predict);
    tcase_add_test(tc, test_predict_integrator);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
