/* tests/test_precond_update.c: the preconditioner for a new atmosphere model from the parts kept at set-up
 * (wt_precond_update, core/model/precond_update.c).
 *
 * Without a layer-binning model error a new model changes only the priors, by exact per-layer factors: the updated
 * preconditioner then equals one rebuilt from the new operator up to the rounding of sums taken in another order
 * (entries within ~10 ulps, amplified by the solves through the coarse block's condition number, < 1e4 on the demo:
 * 1e-10 relative). With a model error the LGS weights' elongation term keeps its set-up share: the update is then
 * an SPD approximation, and the PCG with it reaches the same MAP as with the rebuilt one. Kinds without parts are
 * refused, and a reconstructor falls back to a rebuild for them. */
#include "testmodel.h"
#include "testutil.h"

#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/precond_base.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"

#define DEMO "data/presets/demo.cfg"

/* a model unlike the demo's truth: 4 layers between its altitudes, another r0 */
static const double B_ALT[4] = {0.0, 1500.0, 7000.0, 14000.0}, B_FRAC[4] = {0.3, 0.3, 0.25, 0.15}, B_R0 = 0.09;

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    int no_coarse; /* fourier: the filter alone (coarse_levels < 0, which no configuration sets) */
} fix;

/* the demo's system and the tomography of pcg3 (cg9 = 0) or cg9, with the overrides set */
static void open_fix(fix *f, int cg9, int nset, const char *const *set)
{
    *f = (fix){0};
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, DEMO, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    const wt_recon_variant_config *v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    tp.space = v->preconditioner == WT_PRECOND_FOURIER;
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                  wt_error_message(f->ctx));
}

static void close_fix(fix *f)
{
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static wt_precond *precond(fix *f, int cg9, int updatable)
{
    wt_precond_params pp = wt_precond_params_from_variant(cg9 ? &f->cfg->cg9 : &f->cfg->pcg3);
    pp.updatable = updatable;
    if (f->no_coarse) pp.coarse_levels = -1;
    wt_precond *p = NULL;
    ck_assert_msg(wt_precond_alloc(f->ctx, f->t, &pp, &p) == WT_OK, "%s", wt_error_message(f->ctx));
    return p;
}

/* |P_a⁻¹ r − P_b⁻¹ r| / |P_b⁻¹ r| for a random r */
static double apply_diff(const wt_precond *a, const wt_precond *b, int64_t n)
{
    double *r = malloc(n * sizeof *r), *za = malloc(n * sizeof *za), *zb = malloc(n * sizeof *zb);
    tu_randn(r, n, 5);
    wt_precond_apply(a, r, za);
    wt_precond_apply(b, r, zb);
    const double d = tu_rel_diff(za, zb, n);
    free(r), free(za), free(zb);
    return d;
}

/* tol: 1e-10 in double (above); the fp32 kind stores its coarse inverse and Y in float, each entry within 2^-24 of
 * the double one, and the Woodbury term's cancellation (the NGS weights are ~1e5 the LGS's) amplifies that ~1e2 */
static const struct {
    int cg9, no_coarse;
    double tol;
    const char *set[4];
    int nset;
} CASES[] = {
    {0, 0, 1e-10, {"recon.pcg3.preconditioner=\"jacobi\""}, 1},
    {0, 0, 1e-10, {"recon.pcg3.preconditioner=\"jacobi_ngs\""}, 1},
    {0, 0, 1e-10, {"recon.pcg3.preconditioner=\"coarse_ngs\""}, 1},
    {0, 0, 1e-5, {"recon.pcg3.preconditioner=\"coarse_ngs\"", "recon.pcg3.operator_precision=\"fp32\""}, 2},
    {1, 0, 1e-10, {"recon.cg9.preconditioner=\"fourier\"", "recon.cg9.coarse_levels=0",
                   "recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]"}, 3},
    {1, 1, 1e-10, {"recon.cg9.preconditioner=\"fourier\"", "recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]"}, 2},
};

/* no model error: the update is a rebuild, to rounding; and it did change P (the old one is far from the new) */
START_TEST(t_update_equals_rebuild)
{
    fix f;
    open_fix(&f, CASES[_i].cg9, CASES[_i].nset, CASES[_i].set);
    const int cg9 = CASES[_i].cg9;
    f.no_coarse = CASES[_i].no_coarse;
    const int64_t n = wt_tomography_nunknowns(f.t);
    wt_precond *pu = precond(&f, cg9, 1), *p0 = precond(&f, cg9, 0);
    ck_assert(wt_precond_updatable(pu));
    ck_assert(!wt_precond_updatable(p0));
    ck_assert_int_eq(wt_tomography_set_profile(f.t, B_R0, 4, B_ALT, B_FRAC), WT_OK);
    ck_assert_msg(wt_precond_update(pu) == WT_OK, "%s", wt_error_message(f.ctx));
    wt_precond *pf = precond(&f, cg9, 0);
    const double d_new = apply_diff(pu, pf, n), d_old = apply_diff(p0, pf, n);
    ck_assert_msg(d_new < CASES[_i].tol, "case %d (%s): updated against rebuilt %g", _i, wt_precond_name(pf), d_new);
    ck_assert_msg(d_old > 1e-2, "case %d: the model's change moved P by only %g", _i, d_old);
    /* and back to the first model: the first preconditioner */
    const wt_config *c = f.cfg;
    ck_assert_int_eq(wt_tomography_set_profile(f.t, c->r0, c->nlayers, c->layer_altitude, c->layer_fraction), WT_OK);
    ck_assert_int_eq(wt_precond_update(pu), WT_OK);
    ck_assert_double_lt(apply_diff(pu, p0, n), CASES[_i].tol);
    wt_precond_free(pu);
    wt_precond_free(p0);
    wt_precond_free(pf);
    close_fix(&f);
}
END_TEST

/* with the model error (pcg3's LGS weights change by σ²_e): the update stays SPD and the PCG reaches the MAP it
 * reaches with the rebuilt preconditioner (both converged to 1e-12 of the right-hand side's norm: their solutions
 * agree to cond(M)·1e-12, the demo's M about 1e3 in the preconditioned norm: 1e-8) */
START_TEST(t_update_with_model_error)
{
    const char *set[2] = {"recon.model_error=true", "recon.pcg3.preconditioner=\"coarse_ngs\""};
    fix f;
    open_fix(&f, 0, 2, set);
    const int64_t n = wt_tomography_nunknowns(f.t);
    wt_precond *pu = precond(&f, 0, 1);
    ck_assert_int_eq(wt_tomography_set_profile(f.t, B_R0, 4, B_ALT, B_FRAC), WT_OK);
    ck_assert_double_gt(wt_tomography_model_error(f.t, 0), 0.0);
    ck_assert_int_eq(wt_precond_update(pu), WT_OK);
    wt_precond *pf = precond(&f, 0, 0);
    const wt_system *sys = f.sys;
    double *s = malloc(sys->nslopes * sizeof *s), *cu = calloc(n, sizeof *cu), *cf = calloc(n, sizeof *cf);
    tu_randn(s, sys->nslopes, 9);
    wt_pcg_result ru, rf;
    ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(pu), s, cu, 2000, 1e-12, NULL, &ru), WT_OK);
    ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(pf), s, cf, 2000, 1e-12, NULL, &rf), WT_OK);
    ck_assert_msg(tu_rel_diff(cu, cf, n) < 1e-8, "MAP with the updated / rebuilt preconditioner: %g (%d / %d iterations)",
                  tu_rel_diff(cu, cf, n), ru.iterations, rf.iterations);
    /* an approximation, not the rebuild: close, but the elongation's share is set-up's */
    const double d = apply_diff(pu, pf, n);
    ck_assert_msg(d < 0.2, "updated against rebuilt %g", d);
    free(s), free(cu), free(cf);
    wt_precond_free(pu);
    wt_precond_free(pf);
    close_fix(&f);
}
END_TEST

/* multilevel keeps no parts: refused with a message, and a reconstructor rebuilds it; a preconditioner built without
 * its parts is refused too */
START_TEST(t_update_refused)
{
    const char *set[1] = {"recon.pcg3.preconditioner=\"multilevel\""};
    fix f;
    open_fix(&f, 0, 1, set);
    wt_precond *p = precond(&f, 0, 1);
    ck_assert(!wt_precond_updatable(p));
    ck_assert_int_eq(wt_precond_update(p), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "multilevel"));
    wt_precond_free(p);
    wt_reconstructor_params par;
    wt_reconstructor_params_from_config(f.cfg, WT_RECON_PCG3, -1, &par);
    par.precond.updatable = 1;
    wt_reconstructor *r = NULL;
    ck_assert_int_eq(wt_reconstructor_alloc(f.ctx, f.sys, WT_RECON_PCG3, &par, &r), WT_OK);
    ck_assert_msg(wt_reconstructor_set_model(r, B_R0, 4, B_ALT, B_FRAC, NULL, NULL) == WT_OK, "%s",
                  wt_error_message(f.ctx));
    wt_reconstructor_free(r);
    close_fix(&f);
    const char *set2[1] = {"recon.pcg3.preconditioner=\"jacobi_ngs\""};
    open_fix(&f, 0, 1, set2);
    p = precond(&f, 0, 0);
    ck_assert_int_eq(wt_precond_update(p), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "without the parts"));
    wt_precond_free(p);
    close_fix(&f);
}
END_TEST

/* fourier's NGS term in the update: Y = B⁻¹ R from the spectra kept at set-up and K's dots over R's non-zeros are
 * the bits of the plain path (nlr applies of B⁻¹, dense dots), which the same update takes when the spectra and the
 * sparse columns are hidden; with and without the coarse block, twice (the second update reuses the blocks) */
START_TEST(t_fourier_ngs_same_bits)
{
    const char *set[3] = {"recon.cg9.preconditioner=\"fourier\"", "recon.cg9.coarse_levels=0",
                          "recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]"};
    fix f;
    open_fix(&f, 1, 3, set);
    f.no_coarse = _i;
    const int64_t n = wt_tomography_nunknowns(f.t);
    wt_precond *pa = precond(&f, 1, 1), *pb = precond(&f, 1, 1);
    ck_assert_ptr_nonnull(pa->fd_rhat);
    ck_assert_int_gt(pa->nlr, 0);
    ck_assert_int_eq(pa->nc > 0, !_i);
    double *r = malloc(n * sizeof *r), *za = aligned_alloc(64, n * sizeof *za), *zb = aligned_alloc(64, n * sizeof *zb);
    tu_randn(r, n, 11);
    for (int pass = 0; pass < 2; pass++) {
        if (pass) ck_assert_int_eq(wt_tomography_set_profile(f.t, f.cfg->r0, f.cfg->nlayers, f.cfg->layer_altitude,
                                                             f.cfg->layer_fraction), WT_OK);
        else ck_assert_int_eq(wt_tomography_set_profile(f.t, B_R0, 4, B_ALT, B_FRAC), WT_OK);
        ck_assert_int_eq(wt_precond_update(pa), WT_OK);
        double complex *rhat = pb->fd_rhat;
        int64_t *ptr = pb->fd_rs_ptr;
        pb->fd_rhat = NULL, pb->fd_rs_ptr = NULL;
        const int ok = wt_precond_update(pb);
        pb->fd_rhat = rhat, pb->fd_rs_ptr = ptr;
        ck_assert_int_eq(ok, WT_OK);
        wt_precond_apply(pa, r, za);
        wt_precond_apply(pb, r, zb);
        ck_assert_msg(memcmp(za, zb, n * sizeof *za) == 0, "pass %d: %g", pass, tu_rel_diff(za, zb, n));
        ck_assert_mem_eq(pa->lr_K, pb->lr_K, (size_t)pa->nlr * pa->nlr * sizeof *pa->lr_K);
    }
    free(r), free(za), free(zb);
    wt_precond_free(pa);
    wt_precond_free(pb);
    close_fix(&f);
}
END_TEST

/* a reconstructor that updates its preconditioner reconstructs as one built with the new model (no model error:
 * the same preconditioner to rounding, the same few iterations) */
START_TEST(t_reconstructor_update)
{
    fix f;
    open_fix(&f, 0, 0, NULL);
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9; kind++) {
        wt_reconstructor_params pa, pb;
        wt_reconstructor_params_from_config(f.cfg, kind, -1, &pa);
        pa.precond.updatable = 1;
        pb = pa;
        pb.precond.updatable = 0;
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
        ck_assert_int_eq(wt_reconstructor_set_model(ra, B_R0, 4, B_ALT, B_FRAC, NULL, NULL), WT_OK);
        ck_assert_int_eq(wt_reconstructor_apply(ra, s, a1), WT_OK);
        ck_assert_int_eq(wt_reconstructor_apply(rb, s, a2), WT_OK);
        ck_assert_msg(tu_rel_diff(a1, a2, na) < 1e-9, "%s: %g", wt_reconstructor_name(kind), tu_rel_diff(a1, a2, na));
        free(s), free(a1), free(a2);
        wt_reconstructor_free(ra);
        wt_reconstructor_free(rb);
    }
    close_fix(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("precond_update");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_loop_test(tc, t_update_equals_rebuild, 0, (int)(sizeof CASES / sizeof CASES[0]));
    tcase_add_test(tc, t_update_with_model_error);
    tcase_add_loop_test(tc, t_fourier_ngs_same_bits, 0, 2);
    tcase_add_test(tc, t_update_refused);
    tcase_add_test(tc, t_reconstructor_update);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
