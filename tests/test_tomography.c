/* tests/test_tomography.c: the MAP normal operator, its right-hand side, the modified Jacobi diagonal,
 * (P)CG against a direct dense solve, the fitting step, and the E-ELT system sizes (SPEC §1, §5, §6). */
#include <lapacke.h>
#include <string.h>

#include "core/model/fitting.h"
#include "core/model/system.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/tomography.h"
#include "core/op/noise.h"
#include "core/op/projection.h"
#include "core/op/pupil.h"
#include "core/op/wavelet.h"
#include "testmodel.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
#define EELT "data/presets/eelt-mcao.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    wt_precond *p; /* the variant's preconditioner */
} fixture;

static void setup(fixture *f, const char *path, int cg9, int nset, const char *const *set)
{
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, path, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    f->t = NULL;
    f->p = NULL;
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    if (cg9 >= 0) {
        const wt_recon_variant_config *v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
        ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                      wt_error_message(f->ctx));
        const wt_precond_params pp = wt_precond_params_from_variant(v);
        ck_assert_msg(wt_precond_alloc(f->ctx, f->t, &pp, &f->p) == WT_OK, "%s", wt_error_message(f->ctx));
    }
}

static void teardown(fixture *f)
{
    wt_precond_free(f->p);
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

/* The NGS low-rank term of the preconditioner (jacobi_ngs): at low noise (NGS NEA 0.05 mas against LGS
 * 20 mas) the NGS part of M weighs ~10^5 times the LGS part along a dozen global modes; the Woodbury
 * correction makes them exact in P, so PCG-3 reduces the residual far more in its 4 iterations than the
 * diagonal does (M-norm error after 4 iterations from a random layer state: 3.9x smaller here; the test
 * asks for 2x), and both converge to the same solution (the preconditioner changes the path only). */
START_TEST(test_ngs_lowrank_preconditioner)
{
    const char *low[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.preconditioner=jacobi"};
    const char *lowr[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.preconditioner=jacobi_ngs"};
    fixture a, b;
    setup(&a, DEMO, 0, 4, low);
    setup(&b, DEMO, 0, 4, lowr);
    const int64_t n = wt_tomography_nunknowns(a.t), ns = a.sys->nslopes;
    double *s = malloc(ns * sizeof *s), *ca = calloc(n, sizeof *ca), *cb = calloc(n, sizeof *cb);
    double ha[5], hb[5];
    tu_randn(ca, n, 5); /* slopes of a random layer state: what the sensors would see */
    tu_tomo_slopes(a.t, ca, s);
    memset(ca, 0, n * sizeof *ca);
    wt_pcg_result ra, rb;
    ck_assert_int_eq(wt_tomography_solve(a.t, wt_precond_pcg(a.p), s, ca, 4, 0.0, ha, &ra), WT_OK);
    ck_assert_int_eq(wt_tomography_solve(b.t, wt_precond_pcg(b.p), s, cb, 4, 0.0, hb, &rb), WT_OK);
    /* the converged solution x*, then the M-norm errors of the two 4-iteration iterates */
    double *xs = calloc(n, sizeof *xs), *e = malloc(n * sizeof *e), *me = malloc(n * sizeof *me), err[2];
    ck_assert_int_eq(wt_tomography_solve(b.t, wt_precond_pcg(b.p), s, xs, 3000, 1e-12, NULL, NULL), WT_OK); /* reached 1e-12 */
    for (int k = 0; k < 2; k++) {
        const double *c = k ? cb : ca;
        for (int64_t i = 0; i < n; i++) e[i] = c[i] - xs[i];
        tu_tomo_apply(a.t, e, me);
        err[k] = sqrt(tu_dot(e, me, n));
    }
    tu_tomo_apply(a.t, xs, me);
    const double xn = sqrt(tu_dot(xs, me, n));
    ck_assert_msg(err[1] < 0.5 * err[0], "4 iterations: M-norm error %g with the NGS term, %g with Jacobi alone (|x*| %g)",
                  err[1], err[0], xn);
    /* the same fixed point: Jacobi alone, continued from the low-rank solution, finds nothing to change */
    memcpy(ca, xs, n * sizeof *ca);
    ck_assert_int_eq(wt_tomography_solve(a.t, wt_precond_pcg(a.p), s, ca, 10, 1e-11, NULL, &ra), WT_OK);
    ck_assert_int_eq(ra.iterations, 0);
    free(xs), free(e), free(me);
    free(s), free(ca), free(cb);
    teardown(&a);
    teardown(&b);
}
END_TEST

/* coarse_ngs: B = the Jacobi diagonal with the coarse coefficients of all layers as one exact block of
 * the LGS + prior part of M, the NGS by Woodbury around it. With coarse_levels = J the block is the whole
 * LGS + prior part, so P = M and PCG is exact after one iteration; with one coarse level, at low noise,
 * 4 iterations from a random layer state end nearer x* (M-norm) than jacobi_ngs's and at the same x*. */
START_TEST(test_coarse_preconditioner)
{
    const char *jn[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.preconditioner=jacobi_ngs"};
    const char *c1[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.preconditioner=coarse_ngs",
                        "recon.pcg3.coarse_levels=1"};
    const char *cj[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.preconditioner=coarse_ngs",
                        "recon.pcg3.coarse_levels=3"};
    fixture a, b, x;
    setup(&a, DEMO, 0, 4, jn);
    setup(&b, DEMO, 0, 5, c1);
    setup(&x, DEMO, 0, 5, cj);
    ck_assert_int_eq(x.cfg->wavelet_levels, 3);
    const int64_t n = wt_tomography_nunknowns(a.t), ns = a.sys->nslopes;
    double *s = malloc(ns * sizeof *s), *ca = calloc(n, sizeof *ca), *cb = calloc(n, sizeof *cb);
    tu_randn(ca, n, 5);
    tu_tomo_slopes(a.t, ca, s);
    memset(ca, 0, n * sizeof *ca);
    wt_pcg_result ra, rb, rx;
    /* P = M: one iteration (two allowed for rounding) */
    double *cx = calloc(n, sizeof *cx);
    ck_assert_int_eq(wt_tomography_solve(x.t, wt_precond_pcg(x.p), s, cx, 2, 1e-9, NULL, &rx), WT_OK);
    ck_assert_msg(rx.rel_resid < 1e-9, "exact block: relative residual %g after %d iterations", rx.rel_resid,
                  rx.iterations);
    ck_assert_int_le(rx.iterations, 2);
    ck_assert_int_eq(wt_tomography_solve(a.t, wt_precond_pcg(a.p), s, ca, 4, 0.0, NULL, &ra), WT_OK);
    ck_assert_int_eq(wt_tomography_solve(b.t, wt_precond_pcg(b.p), s, cb, 4, 0.0, NULL, &rb), WT_OK);
    double *xs = calloc(n, sizeof *xs), *e = malloc(n * sizeof *e), *me = malloc(n * sizeof *me), err[2];
    ck_assert_int_eq(wt_tomography_solve(a.t, wt_precond_pcg(a.p), s, xs, 3000, 1e-12, NULL, NULL), WT_OK);
    for (int k = 0; k < 2; k++) {
        const double *c = k ? cb : ca;
        for (int64_t i = 0; i < n; i++) e[i] = c[i] - xs[i];
        tu_tomo_apply(a.t, e, me);
        err[k] = sqrt(tu_dot(e, me, n));
    }
    fprintf(stderr, "coarse: 4-iteration M-norm error %g (coarse 1) vs %g (jacobi_ngs)\n", err[1], err[0]);
    ck_assert_msg(err[1] < 0.8 * err[0], "4 iterations: M-norm error %g with the coarse block, %g without", err[1], err[0]);
    /* the exact block's one-iteration solution is x* */
    for (int64_t i = 0; i < n; i++) e[i] = cx[i] - xs[i];
    tu_tomo_apply(a.t, e, me);
    double ex = sqrt(tu_dot(e, me, n));
    tu_tomo_apply(a.t, xs, me);
    ck_assert_double_lt(ex, 1e-7 * sqrt(tu_dot(xs, me, n)));
    free(xs), free(e), free(me), free(cx);
    free(s), free(ca), free(cb);
    teardown(&a);
    teardown(&b);
    teardown(&x);
}
END_TEST

START_TEST(test_eelt_sizes)
{
    /* SPEC §1: 5112 valid subapertures per LGS, 5525 + 1609 + 2161 = 9295 actuators, 61356 slopes (no guard
     * ring: the paper's active set) */
    fixture f;
    const char *paper[] = {"dm.guard_rings=0"};
    setup(&f, EELT, -1, 1, paper);
    ck_assert_int_eq(f.sys->nlgs, 6);
    ck_assert_int_eq(f.sys->nngs, 3);
    for (int m = 0; m < f.sys->nlgs; m++) ck_assert_int_eq(f.sys->sensors[m].nsub, 5112);
    ck_assert_int_eq(f.sys->sensors[6].nslopes, 8);
    ck_assert_int_eq(f.sys->sensors[7].nslopes, 2);
    ck_assert_int_eq(f.sys->nslopes, 61356);
    ck_assert_int_eq(f.sys->dm->nactive[0], 5525);
    ck_assert_int_eq(f.sys->dm->nactive[1], 1609);
    ck_assert_int_eq(f.sys->dm->nactive[2], 2161);
    ck_assert_int_eq(f.sys->nact, 9295);
    ck_assert_int_eq(f.sys->neval, 25);
    ck_assert_double_eq(f.sys->eval_x[f.sys->eval_centre], 0.0);
    ck_assert_double_eq(f.sys->eval_y[f.sys->eval_centre], 0.0);
    teardown(&f);
    /* the preset's guard ring (SPEC §5): grids 87, 49, 55; an actuator is active when its influence square
     * (half-width one pitch) reaches inside the metapupil disk: counted independently of the library */
    setup(&f, EELT, -1, 0, NULL);
    int want[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) {
        const int n = f.cfg->dm_actuators[k] + 2;
        const double p = f.cfg->dm_pitch[k], R = 21.0 + f.cfg->dm_altitude[k] * tan(84.853 * WT_ARCSEC);
        ck_assert_int_eq(f.sys->dm->grid[k].nx, n);
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) {
                double x = (ix - 0.5 * (n - 1)) * p, y = (iy - 0.5 * (n - 1)) * p;
                double ex = fmax(0.0, fabs(x) - p), ey = fmax(0.0, fabs(y) - p);
                want[k] += ex * ex + ey * ey < R * R;
            }
        ck_assert_int_eq(f.sys->dm->nactive[k], want[k]);
    }
    ck_assert_int_eq(want[0] + want[1] + want[2], 10027);
    teardown(&f);
}
END_TEST

/* The weighted form Ãᵀ Ĉ⁻¹ Ã built from slopes() and rhs() is symmetric, and M c = b(Ã c) + αDc:
 * checks that rhs is the adjoint of the forward model with a symmetric weight and that apply is their
 * composition. Rounding: sums of ~1e5 terms in double precision; 1e-12 relative is far below any real
 * defect. */
START_TEST(test_normal_operator_consistency)
{
    /* the diagonal prior (the full one: test_full_prior_operator) */
    const char *paper[] = {"recon.prior=\"paper\""};
    for (int v = 0; v < 2; v++) {
        fixture f;
        setup(&f, DEMO, v, 1, paper);
        int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
        double *c = malloc(n * sizeof *c), *c2 = malloc(n * sizeof *c2), *y = malloc(n * sizeof *y),
               *y2 = malloc(n * sizeof *y2), *s = malloc(ns * sizeof *s), *as = malloc(ns * sizeof *as),
               *b = malloc(n * sizeof *b);
        tu_randn(c, n, 11);
        tu_randn(c2, n, 12);
        tu_randn(s, ns, 13);
        /* ⟨c, b(Ã c2)⟩ = ⟨c2, b(Ã c)⟩: b(Ã·) = Ãᵀ Ĉ⁻¹ Ã is symmetric only if rhs is the exact adjoint
         * of slopes with a symmetric weight */
        tu_tomo_slopes(f.t, c2, as);
        tu_tomo_rhs(f.t, as, b);
        double lhs = tu_dot(c, b, n);
        tu_tomo_slopes(f.t, c, as);
        tu_tomo_rhs(f.t, as, y2);
        double rhs = tu_dot(c2, y2, n);
        ck_assert_rel(lhs, rhs, 1e-12, 0.0);
        /* M c = b(Ã c) + α D c */
        tu_tomo_apply(f.t, c, y);
        const double *ad = wt_tomography_alpha_prior(f.t);
        for (int64_t i = 0; i < n; i++) y2[i] += ad[i] * c[i];
        ck_assert_double_le(tu_rel_diff(y, y2, n), 1e-13);
        /* positive definite along random directions */
        ck_assert_double_gt(tu_dot(c, y, n), 0.0);
        /* linearity of the right-hand side */
        for (int64_t i = 0; i < ns; i++) as[i] = 2.0 * s[i];
        tu_tomo_rhs(f.t, s, b);
        tu_tomo_rhs(f.t, as, y2);
        for (int64_t i = 0; i < n; i++) b[i] *= 2.0;
        ck_assert_double_le(tu_rel_diff(y2, b, n), 1e-14);
        free(c), free(c2), free(y), free(y2), free(s), free(as), free(b);
        teardown(&f);
    }
}
END_TEST

/* Const operator, caller-owned workspaces: two threads applying one operator at once, each with its
 * own wt_tomography_work, give bit for bit what one caller gets (a shared scratch buffer would mix the
 * two inputs' intermediate layers and slopes within the 1000 applies). */
START_TEST(test_apply_two_threads_one_operator)
{
    fixture f;
    setup(&f, DEMO, 1, 0, NULL);
    const int64_t n = wt_tomography_nunknowns(f.t);
    enum { REPS = 500 };
    double *c[2], *ref[2], *got[2];
    for (int k = 0; k < 2; k++) {
        c[k] = malloc(n * sizeof *c[k]), ref[k] = calloc(n, sizeof *ref[k]), got[k] = calloc(n, sizeof *got[k]);
        tu_randn(c[k], n, 31 + k);
        wt_tomography_apply(f.t, 1.0, c[k], ref[k]);
    }
    wt_tomography_work *w[2];
    for (int k = 0; k < 2; k++) ck_assert_int_eq(wt_tomography_work_alloc(f.t, &w[k]), WT_OK);
    const wt_tomography *ct = f.t;
    int bad = 0;
#pragma omp parallel for num_threads(2) schedule(static, 1) reduction(+ : bad)
    for (int k = 0; k < 2; k++)
        for (int r = 0; r < REPS; r++) {
            memset(got[k], 0, (size_t)n * sizeof *got[k]);
            wt_tomography_apply_ws(ct, w[k], 1.0, c[k], got[k]);
            bad += memcmp(got[k], ref[k], (size_t)n * sizeof *got[k]) != 0;
        }
    ck_assert_int_eq(bad, 0);
    for (int k = 0; k < 2; k++) {
        wt_tomography_work_free(w[k]);
        free(c[k]), free(ref[k]), free(got[k]);
    }
    wt_tomography_work_free(NULL);
    teardown(&f);
}
END_TEST

static double *dense_normal(wt_tomography *t, int64_t n)
{
    double *A = malloc((size_t)n * n * sizeof *A), *e = calloc((size_t)n, sizeof *e);
    for (int64_t j = 0; j < n; j++) {
        e[j] = 1.0;
        tu_tomo_apply(t, e, A + (size_t)j * n);
        e[j] = 0.0;
    }
    free(e);
    return A;
}

START_TEST(test_pcg_matches_dense_solve)
{
    fixture f;
    setup(&f, DEMO, 0, 0, NULL);
    int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    double *A = dense_normal(f.t, n);
    /* the assembled matrix is symmetric to rounding */
    double asym = 0.0, amax = 0.0;
    for (int64_t j = 0; j < n; j++)
        for (int64_t i = 0; i < j; i++) {
            asym = fmax(asym, fabs(A[i + n * j] - A[j + n * i]));
            amax = fmax(amax, fabs(A[i + n * j]));
        }
    ck_assert_double_le(asym, 1e-12 * amax);
    double *s = malloc(ns * sizeof *s), *b = malloc(n * sizeof *b), *x = calloc(n, sizeof *x);
    tu_randn(s, ns, 21);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6; /* slope scale of real data [rad] */
    tu_tomo_rhs(f.t, s, b);
    double *xd = malloc(n * sizeof *xd);
    memcpy(xd, b, n * sizeof *xd);
    ck_assert_int_eq(LAPACKE_dposv(LAPACK_COL_MAJOR, 'L', n, 1, A, n, xd, n), 0);
    wt_pcg_result r;
    int st = wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, x, 3000, 1e-13, NULL, &r);
    ck_assert_msg(st == WT_OK, "PCG did not reach 1e-13 in 3000 iterations: %s (%d its, %g)",
                  wt_error_message(f.ctx), r.iterations, r.rel_resid);
    /* issue #2: within 1e-8 relative of the direct solve */
    ck_assert_double_le(tu_rel_diff(x, xd, n), 1e-8);
    free(A), free(s), free(b), free(x), free(xd);
    teardown(&f);
}
END_TEST

/* recon.prior = "full": M c = b(Ã c) + W α C⁻¹ Wᵀ c. Its prior part p(c) = M c − b(Ã c) is symmetric and
 * positive, its diagonal is what alpha_prior reports (the Jacobi preconditioners read it), it differs
 * from the diagonal form (the coupling is there), and PCG on it reaches the dense solve (1e-8, as
 * test_pcg_matches_dense_solve). Rounding as test_normal_operator_consistency. */
START_TEST(test_full_prior_operator)
{
    const char *set[] = {"recon.prior=\"full\""};
    fixture f;
    setup(&f, DEMO, 0, 1, set);
    ck_assert_int_eq(wt_tomography_full_prior(f.t), 1);
    int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    double *c = malloc(n * sizeof *c), *c2 = malloc(n * sizeof *c2), *p1 = malloc(n * sizeof *p1),
           *p2 = malloc(n * sizeof *p2), *as = malloc(ns * sizeof *as), *b = malloc(n * sizeof *b);
    tu_randn(c, n, 41);
    tu_randn(c2, n, 42);
    double *cs[2] = {c, c2}, *ps[2] = {p1, p2};
    for (int k = 0; k < 2; k++) { /* p(c) = M c − b(Ã c) */
        tu_tomo_apply(f.t, cs[k], ps[k]);
        tu_tomo_slopes(f.t, cs[k], as);
        tu_tomo_rhs(f.t, as, b);
        for (int64_t i = 0; i < n; i++) ps[k][i] -= b[i];
    }
    ck_assert_rel(tu_dot(c, p2, n), tu_dot(c2, p1, n), 1e-10, 0.0);
    ck_assert_double_gt(tu_dot(c, p1, n), 0.0);
    const double *ad = wt_tomography_alpha_prior(f.t);
    double off = 0.0, nrm = 0.0; /* the part of p(c) beyond its diagonal */
    for (int64_t i = 0; i < n; i++) off += pow(p1[i] - ad[i] * c[i], 2), nrm += p1[i] * p1[i];
    ck_assert_double_gt(off, 1e-2 * nrm);
    /* the diagonal on a few unit vectors of every part of the layers (coarse first, finest last) */
    double *e = calloc(n, sizeof *e), *y = malloc(n * sizeof *y), *yr = malloc(n * sizeof *yr);
    for (int64_t i = 0; i < n; i += n / 7 + 1) {
        e[i] = 1.0;
        tu_tomo_apply(f.t, e, y);
        tu_tomo_slopes(f.t, e, as);
        tu_tomo_rhs(f.t, as, yr);
        ck_assert_rel(y[i] - yr[i], ad[i], 1e-9, 0.0);
        e[i] = 0.0;
    }
    /* PCG reaches the dense solve */
    double *A = dense_normal(f.t, n), *s = malloc(ns * sizeof *s), *x = calloc(n, sizeof *x), *xd = malloc(n * sizeof *xd);
    tu_randn(s, ns, 43);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    tu_tomo_rhs(f.t, s, xd);
    ck_assert_int_eq(LAPACKE_dposv(LAPACK_COL_MAJOR, 'L', n, 1, A, n, xd, n), 0);
    wt_pcg_result r;
    int st = wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, x, 3000, 1e-13, NULL, &r);
    ck_assert_msg(st == WT_OK, "PCG: %s (%d its, %g)", wt_error_message(f.ctx), r.iterations, r.rel_resid);
    ck_assert_double_le(tu_rel_diff(x, xd, n), 1e-8);
    free(c), free(c2), free(p1), free(p2), free(as), free(b), free(e), free(y), free(yr), free(A), free(s), free(x), free(xd);
    teardown(&f);
}
END_TEST

/* out = W⁻¹ x, layer by layer (w: the largest layer's wavelet workspace) */
static void to_space(const wt_tomography *t, const double *x, double *out, double *w)
{
    for (int l = 0; l < wt_tomography_nlayers(t); l++) {
        const int64_t o = wt_tomography_layer_offset(t, l);
        wt_wavelet_inverse(wt_tomography_wavelet(t, l), x + o, out + o, w);
    }
}

/* The unknowns as the layers' values (wt_tomography_params.space, the fourier kind's): the operator is the
 * wavelet one conjugated by the orthonormal DWT, M_φ W⁻¹ c = W⁻¹ M c, b_φ = W⁻¹ b, Ã_φ W⁻¹ c = Ã c, and the
 * layers are the unknowns themselves (demo cg9, full prior). The two sides differ by the DWT pairs' rounding,
 * a few u log2(n²) of the vectors' norms: 1e-12 asked. Without the full prior the mode is refused. */
START_TEST(test_space_unknowns)
{
    fixture f;
    setup(&f, DEMO, 1, 0, NULL);
    ck_assert_int_eq(wt_tomography_full_prior(f.t), 1);
    ck_assert_int_eq(wt_tomography_space(f.t), 0);
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    tp.space = 1;
    wt_tomography *ts = NULL;
    ck_assert_msg(wt_tomography_alloc(f.ctx, f.sys, &f.cfg->cg9, "cg9", &tp, &ts) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_int_eq(wt_tomography_space(ts), 1);
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    ck_assert_int_eq(wt_tomography_nunknowns(ts), n);
    double *c = malloc(n * sizeof *c), *phi = malloc(n * sizeof *phi), *y = malloc(n * sizeof *y),
           *ys = malloc(n * sizeof *ys), *yw = malloc(n * sizeof *yw), *s = malloc(ns * sizeof *s),
           *sw = calloc(ns, sizeof *sw), *ss = calloc(ns, sizeof *ss), *w = NULL;
    size_t wsize = 0;
    for (int l = 0; l < wt_tomography_nlayers(f.t); l++)
        if (wt_wavelet_work_size(wt_tomography_wavelet(f.t, l)) > wsize) wsize = wt_wavelet_work_size(wt_tomography_wavelet(f.t, l));
    w = malloc(wsize * sizeof *w);
    tu_randn(c, n, 61);
    tu_randn(s, ns, 62);
    to_space(f.t, c, phi, w); /* φ = W⁻¹ c */
    /* M */
    tu_tomo_apply(f.t, c, y);
    tu_tomo_apply(ts, phi, ys);
    to_space(f.t, y, yw, w);
    ck_assert_double_le(tu_rel_diff(ys, yw, n), 1e-12);
    /* b */
    tu_tomo_rhs(f.t, s, y);
    tu_tomo_rhs(ts, s, ys);
    to_space(f.t, y, yw, w);
    ck_assert_double_le(tu_rel_diff(ys, yw, n), 1e-12);
    /* Ã and the layers */
    tu_tomo_slopes(f.t, c, sw);
    tu_tomo_slopes(ts, phi, ss);
    ck_assert_double_le(tu_rel_diff(ss, sw, ns), 1e-12);
    wt_tomography_layers(ts, phi, ys);
    ck_assert_int_eq(memcmp(ys, phi, n * sizeof *ys), 0);
    wt_tomography_free(ts);
    /* the diagonal prior needs the DWT: refused */
    const char *paper[] = {"recon.cg9.prior=\"paper\""};
    fixture g;
    setup(&g, DEMO, -1, 1, paper);
    wt_tomography_params_from_config(g.cfg, &tp);
    tp.space = 1;
    ts = (wt_tomography *)&g; /* must come back NULL */
    ck_assert_int_eq(wt_tomography_alloc(g.ctx, g.sys, &g.cfg->cg9, "cg9", &tp, &ts), WT_ERR_CONFIG);
    ck_assert_ptr_null(ts);
    ck_assert_ptr_nonnull(strstr(wt_error_message(g.ctx), "need the full prior"));
    teardown(&g);
    free(c), free(phi), free(y), free(ys), free(yw), free(s), free(sw), free(ss), free(w);
    teardown(&f);
}
END_TEST

START_TEST(test_jacobi_beats_cg)
{
    const char *none[] = {"recon.pcg3.preconditioner=\"none\""};
    fixture fj, fc;
    setup(&fj, DEMO, 0, 0, NULL);
    setup(&fc, DEMO, 0, 1, none);
    ck_assert_ptr_nonnull(wt_precond_jacobi_inverse(fj.p));
    ck_assert_ptr_null(wt_precond_jacobi_inverse(fc.p));
    int64_t n = wt_tomography_nunknowns(fj.t), ns = fj.sys->nslopes;
    double *s = malloc(ns * sizeof *s), *x = calloc(n, sizeof *x);
    tu_randn(s, ns, 31);
    wt_pcg_result rj, rc;
    ck_assert_int_eq(wt_tomography_solve(fj.t, wt_precond_pcg(fj.p), s, x, 5000, 1e-6, NULL, &rj), WT_OK);
    memset(x, 0, n * sizeof *x);
    ck_assert_int_eq(wt_tomography_solve(fc.t, wt_precond_pcg(fc.p), s, x, 5000, 1e-6, NULL, &rc), WT_OK);
    ck_assert_msg(rj.iterations < rc.iterations, "Jacobi PCG %d iterations, CG %d", rj.iterations, rc.iterations);
    free(s), free(x);
    teardown(&fj);
    teardown(&fc);
}
END_TEST

/* The exact diagonal of Σ_LGS Ã_mᵀ C̃_m⁻¹ Ã_m by brute force, one column Ã e_i per unknown: the probing's oracle */
static void diag_bruteforce(const fixture *f, double *diag)
{
    const int64_t n = wt_tomography_nunknowns(f->t), ns = f->sys->nslopes;
    double *e = calloc(n, sizeof *e), *s = malloc(ns * sizeof *s), *z = malloc(ns * sizeof *z);
    for (int64_t i = 0; i < n; i++) {
        e[i] = 1.0;
        memset(s, 0, ns * sizeof *s);
        wt_tomography_slopes(f->t, 1.0, e, s);
        e[i] = 0.0;
        double q = 0.0;
        for (int m = 0; m < f->sys->nlgs; m++) {
            const wt_sensor *sm = &f->sys->sensors[m];
            memset(z + sm->offset, 0, (size_t)sm->nslopes * sizeof *z);
            wt_noise_apply_inv(wt_tomography_noise(f->t, m), 1.0, s + sm->offset, z + sm->offset);
            for (int k = 0; k < sm->nslopes; k++) q += s[sm->offset + k] * z[sm->offset + k];
        }
        diag[i] = q;
    }
    free(e), free(s), free(z);
}

START_TEST(test_jacobi_probing_is_exact)
{
    /* the coloured probing must equal the brute-force diagonal (one apply per unknown) to rounding */
    for (int v = 0; v < 2; v++) {
        const char *set[] = {v ? "recon.cg9.preconditioner=\"jacobi\"" : "recon.alpha=1.0"};
        fixture f;
        setup(&f, DEMO, v, 1, set);
        int64_t n = wt_tomography_nunknowns(f.t);
        double *d = malloc(n * sizeof *d);
        diag_bruteforce(&f, d);
        const double *jinv = wt_precond_jacobi_inverse(f.p), *ad = wt_tomography_alpha_prior(f.t);
        double worst = 0.0;
        for (int64_t i = 0; i < n; i++) {
            double ref = d[i] + ad[i];
            worst = fmax(worst, fabs(1.0 / jinv[i] - ref) / ref);
        }
        ck_assert_msg(worst < 1e-10, "variant %d: worst relative error of the probed diagonal %g", v, worst);
        free(d);
        teardown(&f);
    }
}
END_TEST

/* A NaN or Inf slope (an LGS's, an NGS's, the last) is refused naming it, in double and in the fp32 operator (whose
 * test is on the right-hand side: solve()), and leaves the solver's state as it was: the next continued solve gives
 * the bits of one that never saw the bad frames. */
START_TEST(test_nan_slopes_rejected)
{
    const char *fp32[] = {"recon.pcg3.operator_precision=\"fp32\""};
    for (int v = 0; v < 2; v++) {
        fixture f, g;
        setup(&f, DEMO, 0, v, fp32);
        setup(&g, DEMO, 0, v, fp32);
        const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
        double *s = malloc(ns * sizeof *s), *x = calloc(n, sizeof *x), *y = calloc(n, sizeof *y);
        tu_randn(s, ns, 41);
        for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, x, 4, 0.0, NULL, NULL), WT_OK);
        ck_assert_int_eq(wt_tomography_solve(g.t, wt_precond_pcg(g.p), s, y, 4, 0.0, NULL, NULL), WT_OK);
        const int64_t ngs = f.sys->sensors[f.sys->nlgs].offset + 1;
        const int64_t at[3] = {17, ngs, ns - 1};
        const double bad[3] = {NAN, NAN, -INFINITY};
        for (int k = 0; k < 3; k++) {
            const double keep = s[at[k]];
            s[at[k]] = bad[k];
            ck_assert_int_eq(wt_tomography_solve_continue(f.t, wt_precond_pcg(f.p), s, x, 4, 0.0, NULL, NULL),
                             WT_ERR_NUMERIC);
            char want[64];
            snprintf(want, sizeof want, "slope %lld is %s", (long long)at[k], k < 2 ? "nan" : "-inf");
            ck_assert_msg(strstr(wt_error_message(f.ctx), want), "%s", wt_error_message(f.ctx));
            s[at[k]] = keep;
        }
        for (int64_t i = 0; i < ns; i++) s[i] *= 0.9;
        ck_assert_int_eq(wt_tomography_solve_continue(f.t, wt_precond_pcg(f.p), s, x, 4, 0.0, NULL, NULL), WT_OK);
        ck_assert_int_eq(wt_tomography_solve_continue(g.t, wt_precond_pcg(g.p), s, y, 4, 0.0, NULL, NULL), WT_OK);
        ck_assert_int_eq(memcmp(x, y, n * sizeof *x), 0);
        free(s), free(x), free(y);
        teardown(&f);
        teardown(&g);
    }
}
END_TEST

START_TEST(test_layer_grid_too_small_rejected)
{
    const char *set[] = {"recon.pcg3.layer_size=[8, 16, 32]", "recon.wavelet_levels=2"};
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 2, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "recon.pcg3 layer 1"));
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "does not cover"));
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The noise of a sensor given by an NEA with elongation on, and of partly lit subapertures
 * (lgs.wfs.lit_noise): σ² is NEA² (not widened by the elongation), each subaperture's variance factor
 * is 1/f with f its lit fraction of the annulus (f = 1: factor 1), the NGS sensors keep factor 1 (their
 * quadrants are alike), and the reconstructor's weight of a subaperture is the inverse of the truth's
 * covariance block at τ = 1 (here τ = 1 too, so model and truth agree block by block). */
START_TEST(test_nea_and_lit_noise)
{
    const char *set[] = {"lgs.wfs.nea_mas=30.0", "lgs.wfs.lit_noise=true", "ngs.wfs.lit_noise=true",
                         "recon.tau=1.0", "lgs.wfs.valid_fraction=0.3"};
    const double nea = 30e-3 * M_PI / (180.0 * 3600.0);
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 5, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_OK);
    int partial = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        ck_assert_ptr_nonnull(s->noise_scale);
        if (s->kind == WT_SENSOR_NGS) {
            for (int k = 0; k < s->nsub; k++) ck_assert_rel(s->noise_scale[k], 1.0, 1e-12, 0);
            continue;
        }
        ck_assert_rel(s->sigma2, nea * nea, 1e-14, 0);
        ck_assert_ptr_nonnull(s->beta);
        const double d = cfg->diameter / s->subapertures;
        for (int k = 0; k < s->nsub; k++) {
            double x, y, a, b, c;
            wt_shack_hartmann_centre(s->sh, k, &x, &y);
            double f = wt_pupil_fraction(cfg->diameter, cfg->obstruction, x - d / 2, y - d / 2, d);
            ck_assert_double_ge(f, 0.3 - 1e-12);
            ck_assert_rel(s->noise_scale[k], 1.0 / f, 1e-9, 0);
            partial += f < 0.999;
            /* model block × truth block = I: C̃_k = NEA²/f (I + ββᵀ/θf²) */
            double bx = s->beta[k], by = s->beta[s->nsub + k], g = 1.0 / (s->spot_fwhm * s->spot_fwhm);
            double v = nea * nea / f, ca = v * (1 + g * bx * bx), cb = v * g * bx * by, cc = v * (1 + g * by * by);
            wt_noise_inv_block(wt_tomography_noise(t, m), k, &a, &b, &c);
            ck_assert_rel(a * ca + b * cb, 1.0, 1e-10, 0);
            ck_assert_double_le(fabs(a * cb + b * cc), 1e-10);
            ck_assert_rel(b * cb + c * cc, 1.0, 1e-10, 0);
        }
    }
    ck_assert_int_gt(partial, 8); /* the rims of the 8 m demo pupil */
    wt_tomography_free(t);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* Fitting: layers at the DM altitudes on grids whose points include the actuators, filled with a DM
 * shape, are fitted exactly (up to ε and the unseen modes): compare the pupil-plane phase along every
 * evaluation direction. */
/* Tip-tilt and plate scale (issue 22): a quadratic φ = a|x|² on the highest pcg3 layer (altitude h) is, in
 * direction θ, a focus plus the field-dependent tilt 2 a h θ (a plate-scale mode). The LGS cannot see that
 * tilt (their global tip-tilt is removed by T) and see the focus almost alike from every altitude: without
 * NGS only the prior's split of the focus over the layers puts some of it at h. The NGS tip-tilt sensors
 * (NEA 0.05 mas) measure the tilt at three directions. From noise-free slopes of this layer, the tilt of
 * the reconstructed minus the true phase over the inner field (|θ| ≤ the LGS radius, where the layer is
 * seen; the field corners extrapolate beyond every guide star's footprint), relative to the largest true
 * tilt there, must drop to at most 0.4 of its no-NGS value for both NGS slope definitions (g and z are
 * equal on a quadratic): a broken NGS model, T projection or sign leaves it near the no-NGS value. Measured
 * (2026-11-25): 0.46 without NGS, 0.09 (G) and 0.16 (Z) with: the MAP does not give back a pure plate
 * scale exactly even from exact NGS tilts (its prior interpolates the field between the three NGS), a known
 * gap of the low-order path (docs/results.md §0e). The test runs with the paper's diagonal prior, where the
 * NGS path is what moves the figure. With the full prior (the default since session 11) the same converged
 * MAP gives 0.20 without NGS and 0.18 (G) / 0.16 (Z) with (6000 iterations to converge): it puts more of the
 * focus at h from the LGS alone, and the NGS move the inner field little (not yet understood: perhaps the
 * NGS tilts are explained by structure outside the LGS footprints), so there the figure cannot tell a working
 * NGS path from a broken one (docs/results.md §23). */
static double plate_scale_error(int tilt_z, int with_ngs)
{
    const char *set[] = {"lgs.wfs.nea_mas=5.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.prior=\"paper\"",
                         tilt_z ? "ngs.wfs.tilt=\"z\"" : "ngs.wfs.tilt=\"g\"", "ngs.azimuths_deg=[]", "ngs.subapertures=[]"};
    fixture f;
    setup(&f, DEMO, 0, with_ngs ? 5 : 7, set);
    const wt_system *sys = f.sys;
    const int L = wt_tomography_nlayers(f.t), top = L - 1;
    const int64_t n = wt_tomography_nunknowns(f.t), ns = sys->nslopes;
    int64_t np = 0;
    for (int l = 0; l < L; l++) np += wt_grid_size(wt_tomography_layer_grid(f.t, l));
    double *phi = calloc(np, sizeof *phi), *c = calloc(n, sizeof *c), *s = malloc(ns * sizeof *s);
    const double a = 2e-8, h = wt_tomography_layer_altitude(f.t, top); /* [m⁻¹]: 0.3 µm at the pupil edge */
    const wt_grid *g = wt_tomography_layer_grid(f.t, top);
    double *lay = phi + wt_tomography_layer_offset(f.t, top);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            lay[ix + (int64_t)g->nx * iy] = a * (x * x + y * y);
        }
    /* c_true = W φ on that layer (W⁻¹ W = I, so Ã c_true = Γ P φ exactly) */
    double *work = malloc(wt_wavelet_work_size(wt_tomography_wavelet(f.t, top)) * sizeof *work);
    wt_wavelet_forward(wt_tomography_wavelet(f.t, top), lay, c + wt_tomography_layer_offset(f.t, top), work);
    tu_tomo_slopes(f.t, c, s);
    memset(c, 0, n * sizeof *c);
    wt_pcg_result r;
    wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c, 2000, 1e-12, NULL, &r);
    double *rec = calloc(np, sizeof *rec);
    wt_tomography_layers(f.t, c, rec);
    for (int64_t i = 0; i < np; i++) rec[i] -= phi[i];
    wt_grid lg[WT_MAX_LAYERS];
    double alt[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++) lg[l] = *wt_tomography_layer_grid(f.t, l), alt[l] = wt_tomography_layer_altitude(f.t, l);
    const wt_grid *cg = &sys->corner_grid;
    const int64_t nc = wt_grid_size(cg);
    double worst = 0.0, tmax = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        if (hypot(sys->eval_x[j], sys->eval_y[j]) > f.cfg->lgs_radius * (1 + 1e-9)) continue;
        wt_projection *pr;
        ck_assert_int_eq(wt_projection_alloc(f.ctx, L, lg, alt, 0.0, sys->eval_x[j], sys->eval_y[j], cg, sys->corner_mask, 1, &pr),
                         WT_OK);
        double *e = calloc(nc, sizeof *e);
        wt_projection_apply(pr, 1.0, rec, e);
        /* least-squares plane of the error over the valid corners (centred normal equations) */
        double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, se = 0, sex = 0, sey = 0;
        for (int64_t k = 0; k < nc; k++) {
            if (!sys->corner_mask[k]) continue;
            const double x = cg->x0 + (k % cg->nx) * cg->dx, y = cg->y0 + (k / cg->nx) * cg->dx;
            sw += 1, sx += x, sy += y, sxx += x * x, sxy += x * y, syy += y * y, se += e[k], sex += e[k] * x, sey += e[k] * y;
        }
        const double mx = sx / sw, my = sy / sw, cxx = sxx - sw * mx * mx, cxy = sxy - sw * mx * my,
                     cyy = syy - sw * my * my, bx = sex - se * mx, by = sey - se * my, det = cxx * cyy - cxy * cxy;
        worst = fmax(worst, hypot((cyy * bx - cxy * by) / det, (cxx * by - cxy * bx) / det));
        tmax = fmax(tmax, 2.0 * a * h * hypot(sys->eval_x[j], sys->eval_y[j]));
        free(e);
        wt_projection_free(pr);
    }
    ck_assert_double_gt(tmax, 0.0);
    free(phi), free(c), free(s), free(rec), free(work);
    teardown(&f);
    return worst / tmax;
}

START_TEST(test_plate_scale_reconstructed)
{
    const double none = plate_scale_error(0, 0), eg = plate_scale_error(0, 1), ez = plate_scale_error(1, 1);
    printf("plate scale: inner-field tilt error / largest tilt: without NGS %.3f, NGS G-tilt %.3f, Z-tilt %.3f\n", none, eg, ez);
    ck_assert_double_ge(none, 0.3); /* the LGS see the focus, not its altitude: the prior splits it over the layers */
    ck_assert_double_le(eg, 0.4 * none);
    ck_assert_double_le(ez, 0.4 * none);
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

/* The layer-binning model error (recon.model_error, core/model/tomography.c): zero when every true layer
 * sits on a reconstruction altitude (cg9's layers are the atmosphere's), positive for the LGS of PCG-3
 * (the demo atmosphere has layers at 600, 2000, 6000 m between the DM altitudes), not given to the NGS;
 * its variance scales as r0^(-5/3) like the prior it is drawn from (the same fixed-seed draws); and it
 * enters the noise covariance as an isotropic term next to an unchanged elongation term:
 * C̃_i = (σ² + σ²_e) I + σ² (τ/θf²) β βᵀ. */
START_TEST(test_model_error)
{
    const char *on[] = {"recon.model_error=true"};
    const char *half_r0[] = {"recon.model_error=true", "atmosphere.r0_m=0.0645"};
    fixture f9, f3, fr;
    setup(&f9, DEMO, 1, 1, on);
    setup(&f3, DEMO, 0, 1, on);
    setup(&fr, DEMO, 0, 2, half_r0);
    const wt_system *sys = f3.sys;
    int nlgs = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        ck_assert_double_eq(wt_tomography_model_error(f9.t, m), 0.0);
        const double e2 = wt_tomography_model_error(f3.t, m);
        if (s->kind != WT_SENSOR_LGS) {
            ck_assert_double_eq(e2, 0.0);
            continue;
        }
        nlgs++;
        /* a few tens of mas: more than nothing, less than the slope rms of the whole atmosphere (~200 mas) */
        ck_assert_double_gt(sqrt(e2) / WT_ARCSEC * 1e3, 5.0);
        ck_assert_double_lt(sqrt(e2) / WT_ARCSEC * 1e3, 200.0);
        ck_assert_rel(wt_tomography_model_error(fr.t, m), e2 * pow(2.0, 5.0 / 3.0), 1e-9, 0.0);
        /* the covariance block of an elongated subaperture */
        const wt_noise *no = wt_tomography_noise(f3.t, m);
        const int nsub = s->nsub, i = nsub / 3;
        ck_assert_ptr_nonnull(s->beta);
        const double bx = s->beta[i], by = s->beta[nsub + i];
        const double g = f3.cfg->tau / (s->spot_fwhm * s->spot_fwhm);
        double *x = calloc((size_t)2 * nsub, sizeof *x), *y = calloc((size_t)2 * nsub, sizeof *y);
        x[i] = 1.0;
        wt_noise_apply_cov(no, 1.0, x, y);
        ck_assert_rel(y[i], s->sigma2 + e2 + s->sigma2 * g * bx * bx, 1e-12, 0.0);
        ck_assert_rel(y[nsub + i], s->sigma2 * g * bx * by, 1e-12, 1e-30);
        free(x), free(y);
    }
    ck_assert_int_eq(nlgs, f3.cfg->nlgs);
    teardown(&f9);
    teardown(&f3);
    teardown(&fr);
}
END_TEST

/* recon.pcg3.loop_noise_average: the measurement noise of every sensor (NGS too) scaled by the loop's noise
 * gain κ = Σh² (the demo: g 0.4, delay 2, κ = 7/18), elongation term included, and the model error added
 * unscaled: C̃_i = (κσ² + σ²_e) I + κσ² (τ/θf²) β βᵀ. */
START_TEST(test_loop_noise_average)
{
    const char *off[] = {"recon.model_error=true"};
    const char *on[] = {"recon.model_error=true", "recon.pcg3.loop_noise_average=true"};
    fixture a, b;
    setup(&a, DEMO, 0, 1, off);
    setup(&b, DEMO, 0, 2, on);
    const double k = wt_noise_loop_gain(b.cfg->gain, b.cfg->delay);
    ck_assert_rel(k, 7.0 / 18.0, 1e-12, 0.0); /* the demo's loop: g 0.4, delay 2 */
    for (int m = 0; m < b.sys->nsensors; m++) {
        const wt_sensor *s = &b.sys->sensors[m];
        const double e2 = wt_tomography_model_error(b.t, m);
        ck_assert_double_eq(e2, wt_tomography_model_error(a.t, m)); /* not averaged */
        const int nsub = s->nsub, i = nsub / 3;
        const double bx = s->beta ? s->beta[i] : 0.0, by = s->beta ? s->beta[nsub + i] : 0.0;
        const double g = b.cfg->tau / (s->spot_fwhm * s->spot_fwhm);
        double *x = calloc((size_t)2 * nsub, sizeof *x), *y = calloc((size_t)2 * nsub, sizeof *y);
        x[i] = 1.0;
        wt_noise_apply_cov(wt_tomography_noise(b.t, m), 1.0, x, y);
        ck_assert_rel(y[i], k * s->sigma2 + e2 + k * s->sigma2 * g * bx * bx, 1e-12, 0.0);
        ck_assert_rel(y[nsub + i], k * s->sigma2 * g * bx * by, 1e-12, 1e-30);
        free(x), free(y);
    }
    teardown(&a);
    teardown(&b);
}
END_TEST

/* The reconstructor's warm start as frames go by: continuing each solve from the last one's recursive
 * residual (wt_tomography_solve_continue) gives the warm-started iterates of wt_tomography_solve up to
 * rounding, for each preconditioner kind (Jacobi + NGS low rank, coarse block, plain Jacobi): 8 frames of
 * 4 iterations; the drift is ~(iterations + 1) ε per frame in r0, times at most the preconditioned
 * condition number in c: 1e-9 relative after 8 frames allows κ up to ~10^5 (measured: 2e-14 to 2e-13). A
 * continue on other
 * unknowns than the last solve's is a fresh solve, bit for bit. */
/* The frame profile (bench's "where a frame goes"): a solve of k iterations from a given start applies M k + 1
 * times (the initial residual) and the adjoint once more (the right-hand side), so the stages count k + 1 and
 * k + 2 calls; a stage's busiest thread is inside its region no longer than the region lasts; the timing changes
 * no value; stopped, nothing is counted. Both adjoint forms: by sensor groups (pcg3) and by layers (the unknowns
 * in space, cg9), where no inverse DWT runs. */
static void check_profile(wt_tomography *t, wt_pcg_precond P, const double *s, int space)
{
    const int64_t n = wt_tomography_nunknowns(t);
    double *c0 = calloc(n, sizeof *c0), *c1 = calloc(n, sizeof *c1);
    ck_assert_int_eq(wt_tomography_solve(t, P, s, c0, 3, 0.0, NULL, NULL), WT_OK);
    ck_assert_int_eq(wt_tomography_profile_start(t), WT_OK);
    ck_assert_int_eq(wt_tomography_solve(t, P, s, c1, 3, 0.0, NULL, NULL), WT_OK);
    wt_tomography_stage g[WT_TOMO_NSTAGES];
    wt_tomography_profile_stop(t, g);
    for (int64_t i = 0; i < n; i++) ck_assert(c0[i] == c1[i]);
    /* (the preconditioner: z₀ and one per iteration but the last; none for plain CG) */
    const long want[WT_TOMO_NSTAGES] = {space ? 0 : 4, 4, 5, 5, P.apply ? 3 : 0, 1};
    for (int k = 0; k < WT_TOMO_NSTAGES; k++) {
        ck_assert_msg(g[k].calls == want[k], "%s: %ld calls, expected %ld", wt_tomography_stage_name(k), g[k].calls,
                      want[k]);
        ck_assert(g[k].wall >= 0.0);
        if (want[k] == 0 || k >= WT_TOMO_STAGE_PRECOND) { /* (the preconditioner and the solve: wall only) */
            ck_assert(g[k].busy_min < 0.0 && g[k].busy_max < 0.0);
            continue;
        }
        ck_assert_msg(g[k].busy_min >= 0.0 && g[k].busy_min <= g[k].busy_max, "%s: busy %g / %g",
                      wt_tomography_stage_name(k), g[k].busy_min, g[k].busy_max);
        /* (a thread's time inside a region ends before the region's own end: 1 µs of clock slack a call) */
        ck_assert_msg(g[k].busy_max <= g[k].wall + 1e-6 * g[k].calls, "%s: busiest thread %g s > wall %g s",
                      wt_tomography_stage_name(k), g[k].busy_max, g[k].wall);
    }
    /* the stages lie inside the solve; the layers' transform is none of them */
    double inside = 0.0;
    for (int k = 0; k < WT_TOMO_STAGE_SOLVE; k++) inside += g[k].wall;
    ck_assert_msg(inside <= g[WT_TOMO_STAGE_SOLVE].wall, "stages %g s > their solve %g s", inside,
                  g[WT_TOMO_STAGE_SOLVE].wall);
    ck_assert_int_eq(wt_tomography_profile_start(t), WT_OK);
    wt_tomography_layers(t, c1, c0);
    wt_tomography_profile_stop(t, g);
    for (int k = 0; k < WT_TOMO_NSTAGES; k++) ck_assert_int_eq(g[k].calls, 0);
    ck_assert_int_eq(wt_tomography_solve(t, P, s, c1, 3, 0.0, NULL, NULL), WT_OK);
    wt_tomography_profile_stop(t, g);
    for (int k = 0; k < WT_TOMO_NSTAGES; k++) ck_assert_int_eq(g[k].calls, 0);
    ck_assert_ptr_null(wt_tomography_stage_name(WT_TOMO_NSTAGES));
    ck_assert_str_eq(wt_tomography_stage_name(WT_TOMO_STAGE_FORWARD), "forward");
    ck_assert_str_eq(wt_tomography_stage_name(WT_TOMO_STAGE_SOLVE), "solve");
    free(c0);
    free(c1);
}

/* recon.<variant>.operator_precision = "fp32": the sensors' part of M, S c = Σ Pᵀ Γᵀ Ĉ⁻¹ Γ P W⁻¹ c, in single
 * precision (the layers rounded to float, the chain in float, the groups' sums and everything else in double: the
 * prior's term p(c) = M64 c − S64 c too, whose size the bound below also takes, as a term in the sum that the
 * float chain's result is added to: ≤ 1e-5 ‖p(c)‖ is far more than that one addition's u).
 * Each of the chain's ~10 float stages rounds with u = 2^-24 ≈ 6e-8 relative to its absolute sums (the kernels'
 * own suites bound them: projection ≤ (L + 9) u, Γ and Γᵀ ≤ 8 u, Ĉ⁻¹ ≤ 11 u of the |terms|), ~60 u in all;
 * relative to |S c| the absolute sums are larger by the cancellations of Γ (neighbours' differences) and the
 * tip-tilt removal, at most ~30 for these random layers: ‖M32 c − M64 c‖ ≤ 1e-4 ‖S64 c‖ + 1e-5 ‖p(c)‖ (S64 c: the
 * double chain, rhs(slopes(c))). The float operator is symmetric to the same order, |⟨c2, M32 c⟩ − ⟨c, M32 c2⟩| ≤
 * 1e-4 (‖S c‖ ‖c2‖ + ‖S c2‖ ‖c‖) (Cauchy–Schwarz on each side's perturbation), and it is not the double one
 * (the fp32 path ran). A 4-iteration PCG on it (PCG-3's frame) moves by k ≈ 4 perturbations of that size,
 * each amplified by the short recurrence's conditioning (≲ 2 here): ≤ 1e-3 of the iterate. Cases: pcg3 and cg9 with
 * the full prior by sensor groups, pcg3 with the diagonal prior, the unknowns in space (the by-layers adjoint), and
 * a 128² layer on 2 threads (the groups on two threads). The right-hand side Ãᵀ Ĉ⁻¹ s runs the chain's adjoint
 * half in float too: within 1e-4 of the double one by the same count. */
static void check_fp32(wt_tomography *t64, wt_tomography *t32, wt_pcg_precond P64, wt_pcg_precond P32, int64_t ns)
{
    const int64_t n = wt_tomography_nunknowns(t64);
    ck_assert_int_eq(wt_tomography_nunknowns(t32), n);
    double *c = malloc(n * sizeof *c), *c2 = malloc(n * sizeof *c2), *y64 = malloc(n * sizeof *y64),
           *y32 = malloc(n * sizeof *y32), *sc = malloc(n * sizeof *sc), *sc2 = malloc(n * sizeof *sc2),
           *as = malloc(ns * sizeof *as), *y2 = malloc(n * sizeof *y2), *s = malloc(ns * sizeof *s),
           *x64 = calloc(n, sizeof *x64), *x32 = calloc(n, sizeof *x32), *b64 = malloc(n * sizeof *b64),
           *b32 = malloc(n * sizeof *b32);
    tu_randn(c, n, 71);
    tu_randn(c2, n, 72);
    for (int64_t i = 0; i < n; i++) c[i] *= 1e-7, c2[i] *= 1e-7; /* layer scale [m] */
    tu_tomo_slopes(t64, c, as);
    tu_tomo_rhs(t64, as, sc);
    tu_tomo_slopes(t64, c2, as);
    tu_tomo_rhs(t64, as, sc2);
    tu_tomo_apply(t64, c, y64);
    tu_tomo_apply(t32, c, y32);
    double d = 0.0;
    for (int64_t i = 0; i < n; i++) d += (y32[i] - y64[i]) * (y32[i] - y64[i]);
    d = sqrt(d);
    ck_assert_double_gt(d, 0.0);
    double pn = 0.0; /* ‖p(c)‖ */
    for (int64_t i = 0; i < n; i++) pn += (y64[i] - sc[i]) * (y64[i] - sc[i]);
    pn = sqrt(pn);
    ck_assert_msg(d <= 1e-4 * tu_norm(sc, n) + 1e-5 * pn, "fp32 operator: |M32 c - M64 c| = %g, |S c| = %g, |p(c)| = %g",
                  d, tu_norm(sc, n), pn);
    tu_tomo_apply(t32, c2, y2);
    ck_assert_double_le(fabs(tu_dot(c2, y32, n) - tu_dot(c, y2, n)),
                        1e-4 * (tu_norm(sc, n) * tu_norm(c2, n) + tu_norm(sc2, n) * tu_norm(c, n)));
    /* the right-hand side: the same float chain's adjoint half on the rounded slopes (the same bound) */
    tu_randn(s, ns, 73);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    tu_tomo_rhs(t64, s, b64);
    tu_tomo_rhs(t32, s, b32);
    ck_assert_double_gt(tu_rel_diff(b32, b64, n), 0.0);
    ck_assert_double_le(tu_rel_diff(b32, b64, n), 1e-4);
    /* PCG-3's frame: 4 iterations from zero */
    wt_pcg_result r;
    ck_assert_int_eq(wt_tomography_solve(t64, P64, s, x64, 4, 0.0, NULL, &r), WT_OK);
    ck_assert_int_eq(wt_tomography_solve(t32, P32, s, x32, 4, 0.0, NULL, &r), WT_OK);
    ck_assert_int_eq(r.iterations, 4);
    ck_assert_double_gt(tu_norm(x64, n), 0.0);
    ck_assert_double_le(tu_rel_diff(x32, x64, n), 1e-3);
    fprintf(stderr, "fp32 operator: |M32 c - M64 c| = %.2e of |S c|, %.2e of |p(c)|; rhs %.2e; 4-iteration PCG %.2e\n",
            d / tu_norm(sc, n), d / fmax(pn, 1e-300), tu_rel_diff(b32, b64, n), tu_rel_diff(x32, x64, n));
    free(c), free(c2), free(y64), free(y32), free(sc), free(sc2), free(as), free(y2), free(s), free(x64), free(x32);
    free(b64), free(b32);
}

START_TEST(test_single_precision_operator)
{
    const char *fp32[] = {"recon.pcg3.operator_precision=\"fp32\"", "recon.cg9.operator_precision=\"fp32\"",
                          "recon.pcg3.layer_size=[128, 32, 64]"};
    const char *paper[] = {"recon.prior=\"paper\"", "recon.pcg3.operator_precision=\"fp32\""};
    for (int v = 0; v < 3; v++) { /* pcg3 and cg9 (the full prior), pcg3 with the diagonal prior */
        fixture a, b;
        if (v < 2) {
            setup(&a, DEMO, v, 0, NULL);
            setup(&b, DEMO, v, 2, fp32);
        } else {
            setup(&a, DEMO, 0, 1, paper);
            setup(&b, DEMO, 0, 2, paper);
            ck_assert_int_eq(wt_tomography_full_prior(b.t), 0);
        }
        check_fp32(a.t, b.t, wt_precond_pcg(a.p), wt_precond_pcg(b.p), a.sys->nslopes);
        if (v == 1) { /* the unknowns in space: the by-layers adjoint */
            wt_tomography_params tp;
            wt_tomography_params_from_config(a.cfg, &tp);
            tp.space = 1;
            wt_tomography *s64 = NULL, *s32 = NULL;
            ck_assert_int_eq(wt_tomography_alloc(a.ctx, a.sys, &a.cfg->cg9, "cg9", &tp, &s64), WT_OK);
            ck_assert_int_eq(wt_tomography_alloc(b.ctx, b.sys, &b.cfg->cg9, "cg9", &tp, &s32), WT_OK);
            check_fp32(s64, s32, (wt_pcg_precond){NULL, NULL}, (wt_pcg_precond){NULL, NULL}, a.sys->nslopes);
            wt_tomography_free(s64);
            wt_tomography_free(s32);
        }
        teardown(&a);
        teardown(&b);
    }
    /* a 128² layer on 2 threads */
    fixture a, b;
    for (int k = 0; k < 2; k++) {
        fixture *f = k ? &b : &a;
        f->ctx = tu_context();
        wt_context_set_threads(f->ctx, 2);
        ck_assert_int_eq(wt_config_read(f->ctx, DEMO, k ? 3 : 1, k ? fp32 : fp32 + 2, &f->cfg), WT_OK);
        ck_assert_int_eq(wt_system_alloc(f->ctx, f->cfg, &f->sys), WT_OK);
        wt_tomography_params tp;
        wt_tomography_params_from_config(f->cfg, &tp);
        ck_assert_int_eq(wt_tomography_alloc(f->ctx, f->sys, &f->cfg->pcg3, "pcg3", &tp, &f->t), WT_OK);
        ck_assert_int_eq(wt_tomography_threads(f->t), 2);
        f->p = NULL;
    }
    check_fp32(a.t, b.t, (wt_pcg_precond){NULL, NULL}, (wt_pcg_precond){NULL, NULL}, a.sys->nslopes);
    teardown(&a);
    teardown(&b);
}
END_TEST

/* The fp32 operator's NGS term (G = [Pᵀ Γᵀ e_k], explicit, in double): with heavy NGS (NEA 0.02 mas against the
 * LGS's 20) the NGS part of M c is ~600 times the LGS part. A float rounding before the NGS weights (the forward's
 * φ) reaches M c only inside span(W G), the NGS's dozen modes, which the preconditioner holds exactly; one after
 * them (a float G, G w or W) spreads u ≈ 6e-8 of the large term over every mode: ~600 u off span(W G). So the fp32
 * operator's error off span(W G) must be of the float LGS chain's size alone: at most 16 u of ‖S_LGS c‖ (1e-6;
 * measured ~1e-7, and 1e-5 with G's values rounded to float). */
START_TEST(test_single_precision_ngs_term)
{
    const char *set[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.02", "recon.pcg3.operator_precision=\"fp32\""};
    fixture a, b;
    setup(&a, DEMO, 0, 2, set);
    setup(&b, DEMO, 0, 3, set);
    const wt_system *sys = a.sys;
    const int64_t n = wt_tomography_nunknowns(a.t), ns = sys->nslopes;
    double *c = malloc(n * sizeof *c), *y64 = malloc(n * sizeof *y64), *y32 = malloc(n * sizeof *y32),
           *s = malloc(ns * sizeof *s), *slgs = malloc(ns * sizeof *slgs), *blgs = malloc(n * sizeof *blgs),
           *e = calloc(ns, sizeof *e);
    double *Q = malloc((size_t)ns * n * sizeof *Q); /* (at most ns columns; the NGS's used) */
    tu_randn(c, n, 81);
    for (int64_t i = 0; i < n; i++) c[i] *= 1e-7;
    tu_tomo_apply(a.t, c, y64);
    tu_tomo_apply(b.t, c, y32);
    tu_tomo_slopes(a.t, c, s);
    memcpy(slgs, s, ns * sizeof *s);
    int q = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        if (sys->sensors[m].kind == WT_SENSOR_LGS) continue;
        for (int j = 0; j < sys->sensors[m].nslopes; j++) {
            const int64_t k = sys->sensors[m].offset + j;
            slgs[k] = 0.0;
            e[k] = 1.0; /* span(W G) = span of the NGS's unit slopes' right-hand sides (Ĉ⁻¹ invertible) */
            double *v = Q + (size_t)q * n;
            tu_tomo_rhs(a.t, e, v);
            e[k] = 0.0;
            for (int pass = 0; pass < 2; pass++) /* Gram–Schmidt, twice */
                for (int i = 0; i < q; i++) {
                    const double d = tu_dot(Q + (size_t)i * n, v, n);
                    for (int64_t x = 0; x < n; x++) v[x] -= d * Q[(size_t)i * n + x];
                }
            const double nv = tu_norm(v, n);
            ck_assert_double_gt(nv, 0.0);
            for (int64_t x = 0; x < n; x++) v[x] /= nv;
            q++;
        }
    }
    ck_assert_int_ge(q, 4);
    tu_tomo_rhs(a.t, slgs, blgs);
    double *d = y32; /* M32 c − M64 c, then off span(W G) */
    for (int64_t i = 0; i < n; i++) d[i] -= y64[i];
    const double dn = tu_norm(d, n);
    for (int i = 0; i < q; i++) {
        const double p = tu_dot(Q + (size_t)i * n, d, n);
        for (int64_t x = 0; x < n; x++) d[x] -= p * Q[(size_t)i * n + x];
    }
    const double lgs = tu_norm(blgs, n), all = tu_norm(y64, n), off = tu_norm(d, n);
    fprintf(stderr, "fp32 NGS term: |M c| / |S_LGS c| = %.3g; |M32 c - M64 c| = %.2e, off span(W G) %.2e of |S_LGS c|\n",
            all / lgs, dn / lgs, off / lgs);
    ck_assert_double_gt(all, 300.0 * lgs); /* the NGS do dominate: a float NGS term would fail the bound below */
    ck_assert_double_le(off, 1e-6 * lgs);
    free(c), free(y64), free(y32), free(s), free(slgs), free(blgs), free(e), free(Q);
    teardown(&a);
    teardown(&b);
}
END_TEST

/* Threads from 16384 unknowns or 8192 slopes: the 42 × 42 E-ELT geometry (6144 unknowns, 15516 slopes) runs on the
 * context's two threads, the demo (2304 unknowns, 1548 slopes) on one; M c and a 4-iteration solve have the same
 * bits on one and two threads. */
START_TEST(test_threads_for_slopes)
{
    double *ref[2] = {NULL, NULL};
    int64_t n = 0;
    for (int th = 1; th <= 2; th++) {
        fixture f;
        f.ctx = tu_context();
        wt_context_set_threads(f.ctx, th);
        ck_assert_msg(wt_config_read(f.ctx, "data/presets/eelt-mcao-nea20-42.cfg", 0, NULL, &f.cfg) == WT_OK, "%s",
                      wt_error_message(f.ctx));
        ck_assert_msg(wt_system_alloc(f.ctx, f.cfg, &f.sys) == WT_OK, "%s", wt_error_message(f.ctx));
        wt_tomography_params tp;
        wt_tomography_params_from_config(f.cfg, &tp);
        ck_assert_int_eq(wt_tomography_alloc(f.ctx, f.sys, &f.cfg->pcg3, "pcg3", &tp, &f.t), WT_OK);
        const wt_precond_params pp = wt_precond_params_from_variant(&f.cfg->pcg3);
        ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &f.p), WT_OK);
        n = wt_tomography_nunknowns(f.t);
        ck_assert_int_lt(n, 16384);
        ck_assert_int_ge(f.sys->nslopes, 8192);
        ck_assert_int_eq(wt_tomography_threads(f.t), th);
        double *c = malloc(n * sizeof *c), *s = malloc(f.sys->nslopes * sizeof *s);
        for (int k = 0; k < 2; k++) ref[k] = th == 1 ? calloc(n, sizeof *ref[k]) : ref[k];
        double *y = th == 1 ? ref[0] : calloc(n, sizeof *y), *x = th == 1 ? ref[1] : calloc(n, sizeof *x);
        tu_randn(c, n, 61);
        for (int64_t i = 0; i < n; i++) c[i] *= 1e-7;
        tu_tomo_apply(f.t, c, y);
        tu_randn(s, f.sys->nslopes, 62);
        for (int64_t i = 0; i < f.sys->nslopes; i++) s[i] *= 1e-6;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, x, 4, 0.0, NULL, NULL), WT_OK);
        if (th == 2) {
            ck_assert_int_eq(memcmp(y, ref[0], n * sizeof *y), 0);
            ck_assert_int_eq(memcmp(x, ref[1], n * sizeof *x), 0);
            free(y), free(x);
        }
        free(c), free(s);
        teardown(&f);
    }
    free(ref[0]), free(ref[1]);
    fixture d; /* the demo: one thread on a two-thread context */
    d.ctx = tu_context();
    wt_context_set_threads(d.ctx, 2);
    ck_assert_int_eq(wt_config_read(d.ctx, DEMO, 0, NULL, &d.cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(d.ctx, d.cfg, &d.sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(d.cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(d.ctx, d.sys, &d.cfg->pcg3, "pcg3", &tp, &d.t), WT_OK);
    d.p = NULL;
    ck_assert_int_lt(d.sys->nslopes, 8192);
    ck_assert_int_eq(wt_tomography_threads(d.t), 1);
    teardown(&d);
}
END_TEST

START_TEST(test_profile_counts_stages)
{
    fixture f;
    setup(&f, DEMO, 0, 0, NULL);
    const int64_t ns = f.sys->nslopes;
    double *s = malloc(ns * sizeof *s);
    tu_randn(s, ns, 5);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6;
    check_profile(f.t, wt_precond_pcg(f.p), s, 0);
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    tp.space = 1;
    wt_tomography *ts = NULL;
    ck_assert_msg(wt_tomography_alloc(f.ctx, f.sys, &f.cfg->cg9, "cg9", &tp, &ts) == WT_OK, "%s", wt_error_message(f.ctx));
    check_profile(ts, (wt_pcg_precond){NULL, NULL}, s, 1);
    wt_tomography_free(ts);
    free(s);
    teardown(&f);
    /* on threads (a 128² pcg3 layer: 21504 unknowns, where the applies run on the context's threads; 3: a thread
     * with no layer and no group): each thread's busy slot, none beyond the stage's wall */
    const char *set[] = {"recon.pcg3.layer_size=[128, 32, 64]"};
    for (int th = 2; th <= 3; th++) {
        fixture g;
        g.ctx = tu_context();
        wt_context_set_threads(g.ctx, th);
        ck_assert_msg(wt_config_read(g.ctx, DEMO, 1, set, &g.cfg) == WT_OK, "%s", wt_error_message(g.ctx));
        ck_assert_msg(wt_system_alloc(g.ctx, g.cfg, &g.sys) == WT_OK, "%s", wt_error_message(g.ctx));
        wt_tomography_params tp3;
        wt_tomography_params_from_config(g.cfg, &tp3);
        ck_assert_msg(wt_tomography_alloc(g.ctx, g.sys, &g.cfg->pcg3, "pcg3", &tp3, &g.t) == WT_OK, "%s",
                      wt_error_message(g.ctx));
        ck_assert_int_eq(wt_tomography_threads(g.t), th);
        g.p = NULL;
        double *s3 = malloc(g.sys->nslopes * sizeof *s3);
        tu_randn(s3, g.sys->nslopes, 6);
        for (int64_t i = 0; i < g.sys->nslopes; i++) s3[i] *= 1e-6;
        check_profile(g.t, (wt_pcg_precond){NULL, NULL}, s3, 0);
        free(s3);
        teardown(&g);
    }
}
END_TEST

START_TEST(test_solve_continue_matches_warm_start)
{
    const char *pre[][1] = {{"recon.pcg3.preconditioner=jacobi_ngs"}, {"recon.pcg3.preconditioner=coarse_ngs"},
                            {"recon.pcg3.preconditioner=jacobi"}};
    for (int k = 0; k < 3; k++) {
        fixture f;
        setup(&f, DEMO, 0, 1, pre[k]);
        const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
        double *s = malloc(ns * sizeof *s), *ds = malloc(ns * sizeof *ds), *truth = malloc(n * sizeof *truth);
        double *ca = calloc(n, sizeof *ca), *cb = calloc(n, sizeof *cb), *cc = calloc(n, sizeof *cc);
        tu_randn(truth, n, 11);
        tu_tomo_slopes(f.t, truth, s);
        double worst = 0.0;
        for (int frame = 0; frame < 8; frame++) {
            if (frame > 0) {
                tu_randn(ds, ns, 40 + frame);
                for (int64_t i = 0; i < ns; i++) s[i] += 0.1 * ds[i] * fabs(s[i]);
            }
            ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, ca, 4, 0.0, NULL, NULL), WT_OK);
            /* cb's solves alternate with ca's on the same object: continuing must notice that the last
             * solve was on other unknowns and start afresh (bit-identical to a warm-started solve) */
            memcpy(cc, cb, n * sizeof *cc);
            ck_assert_int_eq(wt_tomography_solve_continue(f.t, wt_precond_pcg(f.p), s, cb, 4, 0.0, NULL, NULL), WT_OK);
            ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, cc, 4, 0.0, NULL, NULL), WT_OK);
            for (int64_t i = 0; i < n; i++) ck_assert(cb[i] == cc[i]);
        }
        /* now continuing for real: one object, frames in a row */
        memset(ca, 0, n * sizeof *ca);
        memset(cb, 0, n * sizeof *cb);
        fixture g;
        setup(&g, DEMO, 0, 1, pre[k]);
        tu_tomo_slopes(f.t, truth, s);
        for (int frame = 0; frame < 8; frame++) {
            if (frame > 0) {
                tu_randn(ds, ns, 40 + frame);
                for (int64_t i = 0; i < ns; i++) s[i] += 0.1 * ds[i] * fabs(s[i]);
            }
            ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, ca, 4, 0.0, NULL, NULL), WT_OK);
            ck_assert_int_eq(wt_tomography_solve_continue(g.t, wt_precond_pcg(g.p), s, cb, 4, 0.0, NULL, NULL), WT_OK);
            const double e = tu_rel_diff(cb, ca, n);
            if (e > worst) worst = e;
        }
        fprintf(stderr, "continue: %s: largest relative difference from warm starts %g\n", pre[k][0], worst);
        ck_assert_msg(worst <= 1e-9, "%s: continued frames differ from warm starts by %g", pre[k][0], worst);
        ck_assert_msg(worst > 0.0, "%s: continuing changed nothing (was M applied anyway?)", pre[k][0]);
        free(s);
        free(ds);
        free(truth);
        free(ca);
        free(cb);
        free(cc);
        teardown(&g);
        teardown(&f);
    }
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
    Suite *s = suite_create("tomography");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 900);
    tcase_add_test(tc, test_eelt_sizes);
    tcase_add_test(tc, test_ngs_lowrank_preconditioner);
    tcase_add_test(tc, test_coarse_preconditioner);
    tcase_add_test(tc, test_normal_operator_consistency);
    tcase_add_test(tc, test_apply_two_threads_one_operator);
    tcase_add_test(tc, test_pcg_matches_dense_solve);
    tcase_add_test(tc, test_full_prior_operator);
    tcase_add_test(tc, test_space_unknowns);
    tcase_add_test(tc, test_jacobi_beats_cg);
    tcase_add_test(tc, test_jacobi_probing_is_exact);
    tcase_add_test(tc, test_nan_slopes_rejected);
    tcase_add_test(tc, test_layer_grid_too_small_rejected);
    tcase_add_test(tc, test_nea_and_lit_noise);
    tcase_add_test(tc, test_fitting_recovers_dm_shape);
    tcase_add_test(tc, test_plate_scale_reconstructed);
    tcase_add_test(tc, test_model_error);
    tcase_add_test(tc, test_loop_noise_average);
    tcase_add_test(tc, test_solve_continue_matches_warm_start);
    tcase_add_test(tc, test_fitting_continue_matches_warm_start);
    tcase_add_test(tc, test_profile_counts_stages);
    tcase_add_test(tc, test_single_precision_operator);
    tcase_add_test(tc, test_single_precision_ngs_term);
    tcase_add_test(tc, test_threads_for_slopes);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
