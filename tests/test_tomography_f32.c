/* tests/test_tomography_f32.c: the single-precision operator (recon.<variant>.operator_precision = "fp32";
 * core/model/tomography_operator_f32.c) against the double one, and its NGS term in double (tomography_ngs.c). */
#include <lapacke.h>
#include <string.h>

#include "core/model/fitting.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/op/noise.h"
#include "core/op/projection.h"
#include "core/op/pupil.h"
#include "core/op/wavelet.h"
#include "testmodel.h"
#include "testutil.h"
#include "tomography_fixture.h"

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

Suite *make_suite(void)
{
    Suite *s = suite_create("tomography_f32");
    TCase *tc_core = tcase_create("core");
    tcase_set_timeout(tc_core, 900);
    tcase_add_test(tc_core, test_single_precision_operator);
    tcase_add_test(tc_core, test_single_precision_ngs_term);
    suite_add_tcase(s, tc_core);
    return s;
}

TU_MAIN
