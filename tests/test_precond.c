/* tests/test_precond.c: the preconditioners of core/model/precond.h on the demo system: every kind is
 * symmetric positive definite (xᵀ P⁻¹ y = yᵀ P⁻¹ x to rounding, zᵀ P⁻¹ z > 0 on random vectors and on the
 * NGS modes, where the Woodbury term cancels most of B⁻¹), each is the inverse of the P it claims to be,
 * the kind names match the configuration's list, and bad input and allocation failures are refused. */
#include <string.h>

#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "testmodel.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
/* SPEC §11's low-noise case: the NGS weigh ~10^5 times the LGS along a dozen global modes, the hardest
 * case for the Woodbury term's cancellation */
static const char *const LOW[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0"};

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    const wt_recon_variant_config *v;
} fixture;

static void setup(fixture *f, int cg9, int low, int nextra, const char *const *extra)
{
    const char *set[8];
    int nset = 0;
    for (int i = 0; low && i < 3; i++) set[nset++] = LOW[i];
    for (int i = 0; i < nextra; i++) set[nset++] = extra[i];
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, DEMO, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    f->v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, f->v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                  wt_error_message(f->ctx));
}

static void teardown(fixture *f)
{
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static double dot(const double *x, const double *y, int64_t n) { return tu_dot(x, y, (long)n); }

/* Symmetry and positive definiteness of P⁻¹ for every kind, both variants, both noise levels.
 *
 * Tolerance of the symmetry: P⁻¹ is applied as B⁻¹ r − Y K⁻¹ Yᵀ r; each term is evaluated with a relative
 * rounding error of a few unit roundoffs u per summand (dots of length n, triangular solves of order nc
 * and r), so |xᵀẑ − xᵀz| ≤ γ_n (|x|ᵀ|B⁻¹||y| + |xᵀY| |K⁻¹| |Yᵀy|), γ_n ≈ n u. The terms are of the order
 * of the diagonal part |x|ᵀ J⁻¹ |y|: B⁻¹ is J⁻¹ outside the coarse block, and Y K⁻¹ Yᵀ ≼ B⁻¹ because
 * P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ ≽ 0; the factor 16 covers the few operations per summand and the coarse block's
 * coupling. So the test asks |xᵀP⁻¹y − yᵀP⁻¹x| ≤ 16 n u · |x|ᵀ J⁻¹ |y| (|x|ᵀ|y| for none). Measured:
 * ≤ 2.4e-3 of that bound (coarse_ngs, pcg3, low noise); a transposed Woodbury factor or a wrong sign
 * misses it by orders of magnitude. */
START_TEST(test_symmetric_positive_definite)
{
    const int variant = _i / 2, low = _i % 2;
    fixture f;
    setup(&f, variant, low, 0, NULL);
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *px = malloc(n * sizeof *px),
           *py = malloc(n * sizeof *py), *ax = malloc(n * sizeof *ax), *ay = malloc(n * sizeof *ay),
           *e = calloc(ns, sizeof *e);
    for (int kind = 0; kind < WT_PRECOND_NKINDS; kind++) {
        const wt_precond_params pp = {.kind = kind, .coarse_levels = 2};
        wt_precond *p = NULL;
        ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
        ck_assert_int_eq(wt_precond_kind_of(p), kind);
        ck_assert_str_eq(wt_precond_name(p), wt_precond_kind_name(kind));
        const double *jinv = wt_precond_jacobi_inverse(p);
        ck_assert(kind == WT_PRECOND_NONE ? jinv == NULL : jinv != NULL);
        double worst = 0.0;
        for (int trial = 0; trial < 4; trial++) {
            tu_randn(x, n, 100 + 2 * trial);
            tu_randn(y, n, 101 + 2 * trial);
            wt_precond_apply(p, x, px);
            wt_precond_apply(p, y, py);
            const double a = dot(x, py, n), b = dot(y, px, n);
            double scale = 0.0;
            for (int64_t i = 0; i < n; i++) scale += fabs(x[i]) * (jinv ? jinv[i] : 1.0) * fabs(y[i]);
            const double bound = 16.0 * (double)n * 1.1e-16 * scale;
            ck_assert_msg(fabs(a - b) <= bound, "%s %s %s: xᵀP⁻¹y %.17g, yᵀP⁻¹x %.17g, |diff| %.3g > %.3g",
                          variant ? "cg9" : "pcg3", low ? "low noise" : "paper noise", wt_precond_kind_name(kind), a,
                          b, fabs(a - b), bound);
            worst = fmax(worst, fabs(a - b) / bound);
            ck_assert_msg(dot(x, px, n) > 0.0 && dot(y, py, n) > 0.0, "%s: zᵀP⁻¹z <= 0 on a random vector",
                          wt_precond_kind_name(kind));
        }
        /* the NGS modes G e_k = Ãᵀ Ĉ⁻¹ e_k: where Y K⁻¹ Yᵀ nearly cancels B⁻¹, the place a loss of definiteness
         * would show */
        for (int m = f.sys->nlgs; m < f.sys->nsensors; m++)
            for (int k = 0; k < f.sys->sensors[m].nslopes; k++) {
                const int64_t o = f.sys->sensors[m].offset + k;
                e[o] = 1.0;
                tu_tomo_rhs(f.t, e, ax);
                e[o] = 0.0;
                wt_precond_apply(p, ax, ay);
                ck_assert_msg(dot(ax, ay, n) > 0.0, "%s: zᵀP⁻¹z = %g on NGS mode %d of %s", wt_precond_kind_name(kind),
                              dot(ax, ay, n), k, f.sys->sensors[m].name);
            }
        fprintf(stderr, "precond %s %s %-10s: worst asymmetry %.2g of the bound\n", variant ? "cg9" : "pcg3",
                low ? "low  " : "paper", wt_precond_kind_name(kind), worst);
        wt_precond_free(p);
    }
    free(x), free(y), free(px), free(py), free(ax), free(ay), free(e);
    teardown(&f);
}
END_TEST

/* Each kind inverts the P it claims to be. jacobi: P⁻¹ = J⁻¹ exactly (one product per element).
 * jacobi_ngs: P x = J x + Σ_NGS Ãᵀ Ĉ⁻¹ Ã x (the NGS slopes of Ã x alone, through the adjoint), and P⁻¹ P x = x
 * to κ(P)-scaled rounding: the Woodbury form loses about log10 of the NGS-to-LGS weight ratio (10^5 at low
 * noise) in digits along the NGS modes, so 1e-8 relative leaves a margin of ~100 over the 1e-10 it
 * reaches. coarse_ngs with coarse_levels = J: the block is all of the LGS + prior part, so P = M and
 * P⁻¹ M x = x to the same tolerance. */
START_TEST(test_inverts_its_matrix)
{
    const char *all[] = {"recon.pcg3.coarse_levels=3"};
    fixture f;
    setup(&f, 0, 1, 1, all);
    ck_assert_int_eq(f.cfg->wavelet_levels, 3);
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    double *x = malloc(n * sizeof *x), *px = malloc(n * sizeof *px), *z = malloc(n * sizeof *z),
           *s = malloc(ns * sizeof *s);
    tu_randn(x, n, 7);
    wt_precond *p = NULL;
    /* jacobi */
    wt_precond_params pp = {.kind = WT_PRECOND_JACOBI, .coarse_levels = 3};
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_OK);
    const double *jinv = wt_precond_jacobi_inverse(p);
    wt_precond_apply(p, x, z);
    for (int64_t i = 0; i < n; i++) ck_assert_double_eq(z[i], jinv[i] * x[i]);
    ck_assert_int_eq(wt_precond_rank(p), 0);
    ck_assert_int_eq(wt_precond_coarse_size(p), 0);
    wt_precond_free(p);
    /* jacobi_ngs */
    pp.kind = WT_PRECOND_JACOBI_NGS;
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_OK);
    ck_assert_int_eq(wt_precond_rank(p), f.sys->nslopes - f.sys->sensors[f.sys->nlgs].offset); /* the NGS slopes */
    tu_tomo_slopes(f.t, x, s);
    for (int m = 0; m < f.sys->nlgs; m++) memset(s + f.sys->sensors[m].offset, 0, f.sys->sensors[m].nslopes * sizeof *s);
    tu_tomo_rhs(f.t, s, px);
    jinv = wt_precond_jacobi_inverse(p);
    for (int64_t i = 0; i < n; i++) px[i] += x[i] / jinv[i];
    wt_precond_apply(p, px, z);
    ck_assert_double_le(tu_rel_diff(z, x, n), 1e-8);
    wt_precond_free(p);
    /* coarse_ngs over all levels: P = M */
    pp.kind = WT_PRECOND_COARSE_NGS;
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_OK);
    ck_assert_int_eq(wt_precond_coarse_size(p), n);
    tu_tomo_apply(f.t, x, px);
    wt_precond_apply(p, px, z);
    ck_assert_double_le(tu_rel_diff(z, x, n), 1e-8);
    /* the callback form is the same apply, and none is plain CG */
    const wt_pcg_precond cb = wt_precond_pcg(p);
    ck_assert_ptr_eq(cb.user, p);
    cb.apply(cb.user, px, x); /* overwrites x */
    ck_assert_int_eq(memcmp(x, z, n * sizeof *x), 0);
    ck_assert_ptr_null(wt_precond_pcg(NULL).apply);
    wt_precond_free(p);
    pp.kind = WT_PRECOND_NONE;
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_OK);
    ck_assert_ptr_null(wt_precond_pcg(p).apply);
    wt_precond_apply(p, px, z);
    ck_assert_int_eq(memcmp(z, px, n * sizeof *z), 0);
    ck_assert_double_eq(wt_precond_bytes(p), 0.0);
    wt_precond_free(p);
    wt_precond_free(NULL);
    free(x), free(px), free(z), free(s);
    teardown(&f);
}
END_TEST

/* The names are the configuration's list, in its order: the value recon.<variant>.preconditioner holds is
 * the kind. Unknown kinds and a coarse block beyond 4096 coefficients are refused with a message. */
START_TEST(test_names_and_refusals)
{
    ck_assert_int_eq(wt_precond_kind("coarse_ngs"), WT_PRECOND_COARSE_NGS);
    ck_assert_int_eq(wt_precond_kind("ilu"), -1);
    ck_assert_int_eq(wt_precond_kind(NULL), -1);
    ck_assert_ptr_null(wt_precond_kind_name(WT_PRECOND_NKINDS));
    ck_assert_ptr_null(wt_precond_kind_name(-1));
    for (int k = 0; k < WT_PRECOND_NKINDS; k++) {
        char set[96];
        snprintf(set, sizeof set, "recon.cg9.preconditioner=\"%s\"", wt_precond_kind_name(k));
        const char *sets[] = {set};
        wt_context *ctx = tu_context();
        wt_config *cfg = NULL;
        ck_assert_int_eq(wt_config_read(ctx, DEMO, 1, sets, &cfg), WT_OK);
        ck_assert_int_eq(cfg->cg9.preconditioner, k);
        ck_assert_int_eq(wt_precond_kind(wt_precond_kind_name(k)), k);
        ck_assert_int_eq(wt_precond_params_from_variant(&cfg->cg9).kind, k);
        wt_config_free(ctx, cfg);
        wt_context_free(ctx);
    }
    fixture f;
    setup(&f, 1, 0, 0, NULL);
    wt_precond *p = (wt_precond *)&f; /* must come back NULL */
    wt_precond_params pp = {.kind = 7, .coarse_levels = 2};
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_INVALID);
    ck_assert_ptr_null(p);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "preconditioner kind 7"));
    /* 5 layers of 32²: all 3 levels would be 5120 coefficients */
    pp = (wt_precond_params){.kind = WT_PRECOND_COARSE_NGS, .coarse_levels = 3};
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_CONFIG);
    ck_assert_ptr_null(p);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "coarse_levels 3"));
    teardown(&f);
}
END_TEST

/* Every allocation failure of the set-up surfaces as WT_ERR_NOMEM and leaves nothing allocated. */
START_TEST(test_allocation_failures)
{
    fixture f;
    setup(&f, 0, 0, 0, NULL);
    tu_alloc fa = TU_ALLOC_INIT;
    for (int kind = WT_PRECOND_JACOBI; kind < WT_PRECOND_NKINDS; kind++) {
        const wt_precond_params pp = {.kind = kind, .coarse_levels = 1};
        for (int b = 0; b < 40; b++) {
            wt_precond *p = NULL;
            tu_alloc_install(f.ctx, &fa);
            fa.live = 0;
            tu_alloc_budget(&fa, b);
            const int st = wt_precond_alloc(f.ctx, f.t, &pp, &p);
            tu_alloc_budget(&fa, -1);
            if (st == WT_OK) {
                wt_precond_free(p);
                ck_assert_int_eq(fa.live, 0);
                break;
            }
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            ck_assert_ptr_null(p);
            ck_assert_int_eq(fa.live, 0);
            ck_assert_int_lt(b, 39);
        }
    }
    wt_context_set_allocator(f.ctx, NULL, NULL, NULL);
    teardown(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("precond");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_loop_test(tc, test_symmetric_positive_definite, 0, 4); /* {pcg3, cg9} x {paper, low noise} */
    tcase_add_test(tc, test_inverts_its_matrix);
    tcase_add_test(tc, test_names_and_refusals);
    tcase_add_test(tc, test_allocation_failures);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
