/* tests/test_reconstructor.c: slopes → commands (core/model/reconstructor.h, paper §6.1): a fixed
 * number of (P)CG iterations from a zero start is homogeneous (R(2s) = 2R(s) bit for bit: scaling by
 * a power of two commutes with every rounding), a converged one is linear, the MVM reconstructor is the
 * stored matrix's own apply (core/solve/mvm.h), and none is zero. */
#include "core/build/mvm_build.h"
#include "core/model/params.h"
#include "core/model/reconstructor.h"
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

Suite *make_suite(void)
{
    Suite *s = suite_create("reconstructor");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_pcg3_homogeneous);
    tcase_add_test(tc, test_cg9_homogeneous);
    tcase_add_test(tc, test_pcg3_converged_linear);
    tcase_add_test(tc, test_mvm_and_none);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
