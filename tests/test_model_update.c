/* tests/test_model_update.c: a new atmosphere model taken at the next frame (SPEC §12 "Updates"): the prior
 * rescaled to a new strength equals a prior built for it; a tomography given a new profile applies the same M as
 * one built with that profile; the model error is linear in f r0^(−5/3) and vanishes for layers on the
 * reconstruction altitudes; a reconstructor given a new model reconstructs as one built with it; bad models are
 * refused and leave the old one in place. */
#include "testmodel.h"
#include "testutil.h"

#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"
#include "core/op/prior.h"
#include "core/op/wavelet.h"

#define DEMO "data/presets/demo.cfg"

/* rescaling the prior by the strength ratio equals the prior of the new strength, to rounding (every quantity is
 * proportional to 1 / (f r0^(−5/3)): a few ulps through pow and the exact variances' FFT sums) */
START_TEST(t_prior_rescale)
{
    wt_context *ctx = tu_context();
    wt_wavelet *w = NULL;
    ck_assert_int_eq(wt_wavelet_alloc(ctx, 32, 3, 3, &w), WT_OK);
    const int kinds[3] = {WT_PRIOR_PAPER, WT_PRIOR_EXACT, WT_PRIOR_FULL};
    const double r0a = 0.15, fa = 0.3, r0b = 0.11, fb = 0.05, L0 = 25.0;
    const double factor = (fb * pow(r0b, -5.0 / 3.0)) / (fa * pow(r0a, -5.0 / 3.0));
    double *phi = malloc(32 * 32 * sizeof *phi), *y1 = malloc(32 * 32 * sizeof *y1), *y2 = malloc(32 * 32 * sizeof *y2);
    tu_randn(phi, 32 * 32, 7);
    for (int k = 0; k < 3; k++) {
        wt_prior *a = NULL, *b = NULL;
        ck_assert_int_eq(wt_prior_alloc(ctx, w, 0.5, r0a, fa, L0, kinds[k], NULL, &a), WT_OK);
        ck_assert_int_eq(wt_prior_alloc(ctx, w, 0.5, r0b, fb, L0, kinds[k], NULL, &b), WT_OK);
        wt_prior_rescale(a, factor);
        ck_assert_double_lt(tu_rel_diff(wt_prior_diag(a), wt_prior_diag(b), 32 * 32), 1e-12);
        ck_assert_rel(wt_prior_scale(a), wt_prior_scale(b), 1e-12, 0.0);
        ck_assert_rel(wt_prior_level_variance(a, 2, 1), wt_prior_level_variance(b, 2, 1), 1e-12, 0.0);
        if (kinds[k] == WT_PRIOR_FULL) {
            double *work = malloc(wt_prior_work_size(a) * sizeof *work);
            wt_prior_apply_full(a, 1.0, phi, y1, work);
            wt_prior_apply_full(b, 1.0, phi, y2, work);
            ck_assert_double_lt(tu_rel_diff(y1, y2, 32 * 32), 1e-12);
            free(work);
        }
        wt_prior_rescale(a, NAN); /* ignored */
        ck_assert_double_lt(tu_rel_diff(wt_prior_diag(a), wt_prior_diag(b), 32 * 32), 1e-12);
        wt_prior_free(a);
        wt_prior_free(b);
    }
    free(phi), free(y1), free(y2);
    wt_wavelet_free(w);
    wt_context_free(ctx);
}
END_TEST

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
} sysfix;

static void sys_open(sysfix *f, int nset, const char *const *set)
{
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, DEMO, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
}

static void sys_close(sysfix *f)
{
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

/* a model unlike the demo's truth: 4 layers between its altitudes, another r0 */
static const double B_ALT[4] = {0.0, 1500.0, 7000.0, 14000.0}, B_FRAC[4] = {0.3, 0.3, 0.25, 0.15}, B_R0 = 0.09;

static wt_tomography *tomo_with(sysfix *f, int cg9, const double *alt, const double *frac, int natm, double r0)
{
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    if (alt) {
        tp.natm = natm;
        tp.r0 = r0;
        for (int k = 0; k < natm; k++) tp.atm_altitude[k] = alt[k], tp.atm_fraction[k] = frac[k];
    }
    wt_tomography *t = NULL;
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, cg9 ? &f->cfg->cg9 : &f->cfg->pcg3, cg9 ? "cg9" : "pcg3", &tp, &t) ==
                      WT_OK, "%s", wt_error_message(f->ctx));
    return t;
}

/* without the model error, a tomography given profile B applies the M of one built with B (the priors' rounding),
 * and given its first profile back, its own first M */
START_TEST(t_set_profile_equals_fresh)
{
    sysfix f;
    sys_open(&f, 0, NULL);
    for (int cg9 = 0; cg9 < 2; cg9++) {
        wt_tomography *a = tomo_with(&f, cg9, NULL, NULL, 0, 0), *b = tomo_with(&f, cg9, B_ALT, B_FRAC, 4, B_R0);
        const int64_t n = wt_tomography_nunknowns(a);
        double *x = malloc(n * sizeof *x), *ya = malloc(n * sizeof *ya), *yb = malloc(n * sizeof *yb),
               *y0 = malloc(n * sizeof *y0);
        tu_randn(x, n, 11);
        tu_tomo_apply(a, x, y0);
        ck_assert_int_eq(wt_tomography_set_profile(a, B_R0, 4, B_ALT, B_FRAC), WT_OK);
        for (int l = 0; l < wt_tomography_nlayers(a); l++)
            ck_assert_double_eq(wt_tomography_layer_fraction(a, l), wt_tomography_layer_fraction(b, l));
        ck_assert_double_eq(wt_tomography_r0(a), B_R0);
        tu_tomo_apply(a, x, ya);
        tu_tomo_apply(b, x, yb);
        ck_assert_msg(tu_rel_diff(ya, yb, n) < 1e-12, "%s: |M_set − M_B| / |M_B| = %g", cg9 ? "cg9" : "pcg3",
                      tu_rel_diff(ya, yb, n));
        const wt_config *c = f.cfg;
        ck_assert_int_eq(wt_tomography_set_profile(a, c->r0, c->nlayers, c->layer_altitude, c->layer_fraction), WT_OK);
        tu_tomo_apply(a, x, ya);
        ck_assert_double_lt(tu_rel_diff(ya, y0, n), 1e-12);
        free(x), free(ya), free(yb), free(y0);
        wt_tomography_free(a);
        wt_tomography_free(b);
    }
    sys_close(&f);
}
END_TEST

/* the model error of a new profile: linear in f r0^(−5/3) (to rounding: the unit layers are drawn once), zero for a
 * profile whose layers sit on the reconstruction altitudes; a bad profile is refused and changes nothing */
START_TEST(t_set_profile_model_error)
{
    const char *on[] = {"recon.model_error=true"};
    sysfix f;
    sys_open(&f, 1, on);
    wt_tomography *t = tomo_with(&f, 0, NULL, NULL, 0, 0);
    const wt_system *sys = f.sys;
    ck_assert_int_eq(wt_tomography_set_profile(t, B_R0, 4, B_ALT, B_FRAC), WT_OK);
    double e1[16], e2[16];
    for (int m = 0; m < sys->nsensors; m++) e1[m] = wt_tomography_model_error(t, m);
    ck_assert_int_eq(wt_tomography_set_profile(t, B_R0 / 2, 4, B_ALT, B_FRAC), WT_OK);
    for (int m = 0; m < sys->nsensors; m++) {
        e2[m] = wt_tomography_model_error(t, m);
        if (sys->sensors[m].kind != WT_SENSOR_LGS) {
            ck_assert_double_eq(e2[m], 0.0);
            continue;
        }
        ck_assert_double_gt(e1[m], 0.0);
        ck_assert_rel(e2[m], e1[m] * pow(2.0, 5.0 / 3.0), 1e-12, 0.0);
    }
    /* doubling the fraction of one layer and halving the others' leaves a linear combination: the sum of parts */
    const double one[1] = {1.0};
    double parts[16] = {0};
    for (int k = 0; k < 4; k++) {
        ck_assert_int_eq(wt_tomography_set_profile(t, B_R0, 1, &B_ALT[k], one), WT_OK);
        for (int m = 0; m < sys->nsensors; m++) parts[m] += B_FRAC[k] * wt_tomography_model_error(t, m);
    }
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].kind == WT_SENSOR_LGS) ck_assert_rel(parts[m], e1[m], 1e-12, 0.0);
    /* the layers on pcg3's own altitudes: nothing to bin */
    const double on_alt[3] = {0.0, 4000.0, 12700.0}, on_frac[3] = {0.5, 0.3, 0.2};
    ck_assert_int_eq(wt_tomography_set_profile(t, 0.12, 3, on_alt, on_frac), WT_OK);
    for (int m = 0; m < sys->nsensors; m++) ck_assert_double_eq(wt_tomography_model_error(t, m), 0.0);
    /* refusals: the object keeps its model */
    const double bad_alt[2] = {3000.0, 1000.0}, bad_frac[2] = {0.5, -0.1}, ok2[2] = {0.5, 0.5}, alt2[2] = {0, 1000};
    ck_assert_int_eq(wt_tomography_set_profile(t, 0.12, 2, bad_alt, ok2), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "increasing"));
    ck_assert_int_eq(wt_tomography_set_profile(t, 0.12, 2, alt2, bad_frac), WT_ERR_INVALID);
    ck_assert_int_eq(wt_tomography_set_profile(t, -1.0, 2, alt2, ok2), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "r0"));
    ck_assert_double_eq(wt_tomography_r0(t), 0.12);
    for (int m = 0; m < sys->nsensors; m++) ck_assert_double_eq(wt_tomography_model_error(t, m), 0.0);
    wt_tomography_free(t);
    sys_close(&f);
}
END_TEST

/* a reconstructor given model B reconstructs as one built with B: the same operator (to rounding), the same
 * preconditioner rebuilt from it, both solves from zero (a few ulps grown over the iterations) */
START_TEST(t_reconstructor_set_model)
{
    sysfix f;
    sys_open(&f, 0, NULL);
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9; kind++) {
        wt_reconstructor_params pa, pb;
        wt_reconstructor_params_from_config(f.cfg, kind, -1, &pa);
        pb = pa;
        pb.tomography.natm = 4;
        pb.tomography.r0 = B_R0;
        for (int k = 0; k < 4; k++) pb.tomography.atm_altitude[k] = B_ALT[k], pb.tomography.atm_fraction[k] = B_FRAC[k];
        wt_reconstructor *ra = NULL, *rb = NULL;
        ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, kind, &pa, &ra), WT_OK);
        ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, kind, &pb, &rb), WT_OK);
        const int64_t ns = f.sys->nslopes, na = f.sys->nact;
        double *s = malloc(ns * sizeof *s), *a1 = malloc(na * sizeof *a1), *a2 = malloc(na * sizeof *a2);
        tu_randn(s, ns, 3);
        for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
        ck_assert_int_eq(wt_reconstructor_apply(ra, s, a1), WT_OK); /* a state to keep or drop */
        ck_assert_int_eq(wt_reconstructor_set_model(ra, B_R0, 4, B_ALT, B_FRAC, NULL, NULL), WT_OK);
        wt_reconstructor_reset(ra);
        ck_assert_int_eq(wt_reconstructor_apply(ra, s, a1), WT_OK);
        ck_assert_int_eq(wt_reconstructor_apply(rb, s, a2), WT_OK);
        ck_assert_msg(tu_rel_diff(a1, a2, na) < 1e-9, "%s: %g", wt_reconstructor_name(kind), tu_rel_diff(a1, a2, na));
        double tm = -1, tp = -1;
        wt_reconstructor_last_update_times(ra, &tm, &tp);
        ck_assert(tm >= 0.0 && tp >= 0.0);
        free(s), free(a1), free(a2);
        wt_reconstructor_free(ra);
        wt_reconstructor_free(rb);
    }
    /* the MVM and none take no model */
    wt_reconstructor *rn = NULL;
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, WT_RECON_NONE, NULL, &rn), WT_OK);
    ck_assert_int_eq(wt_reconstructor_set_model(rn, B_R0, 4, B_ALT, B_FRAC, NULL, NULL), WT_ERR_INVALID);
    wt_reconstructor_free(rn);
    sys_close(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("model_update");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, t_prior_rescale);
    tcase_add_test(tc, t_set_profile_equals_fresh);
    tcase_add_test(tc, t_set_profile_model_error);
    tcase_add_test(tc, t_reconstructor_set_model);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
