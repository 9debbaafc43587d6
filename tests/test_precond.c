/* tests/test_precond.c: the preconditioners of core/model/precond.h on the demo system: every kind is
 * symmetric positive definite (xᵀ P⁻¹ y = yᵀ P⁻¹ x to rounding, zᵀ P⁻¹ z > 0 on random vectors and on the
 * NGS modes, where the Woodbury term cancels most of B⁻¹), each is the inverse of the P it claims to be, the same
 * bits on any thread count, the single-precision storage close to the double, the kind names match the
 * configuration's list, and bad input and allocation failures are refused. The multilevel and fourier kinds'
 * own properties: test_precond_multilevel.c, test_precond_fourier.c. */
#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <string.h>
#include <unistd.h>

#include "core/base/sha256.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/op/noise.h"
#include "core/op/wavelet.h"
#include "precond_fixture.h"
#include "testmodel.h"
#include "testutil.h"

/* Symmetry and positive definiteness of P⁻¹ for every kind, both variants, both noise levels.
 *
 * Tolerance of the symmetry: P⁻¹ is applied as B⁻¹ r − Y K⁻¹ Yᵀ r; each term is evaluated with a relative
 * rounding error of a few unit roundoffs u per summand (dots of length n, triangular solves of order nc
 * and r), so |xᵀẑ − xᵀz| ≤ γ_n (|x|ᵀ|B⁻¹||y| + |xᵀY| |K⁻¹| |Yᵀy|), γ_n ≈ n u. The terms are of the order
 * of the diagonal part |x|ᵀ J⁻¹ |y|: B⁻¹ is J⁻¹ outside the coarse block, and Y K⁻¹ Yᵀ ≼ B⁻¹ because
 * P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ ≽ 0; the factor 16 covers the few operations per summand and the coarse block's
 * coupling. So the test asks |xᵀP⁻¹y − yᵀP⁻¹x| ≤ 16 n u · |x|ᵀ J⁻¹ |y| (|x|ᵀ|y| for none). multilevel's
 * B⁻¹ is not J⁻¹ on its layer blocks: there the scale takes |B_b⁻¹| itself (Σ_b |x_b|ᵀ |B_b⁻¹| |y_b|, each
 * block inverted here by LAPACK from wt_precond_block), whose entries exceed J⁻¹'s by up to the block's
 * condition. Measured: ≤ 2.4e-3 of that bound (coarse_ngs and multilevel, pcg3, low noise); a transposed
 * Woodbury factor or a wrong sign misses it by orders of magnitude. */
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
        if (kind == WT_PRECOND_FOURIER) { /* on wavelet coefficients: refused (its own tests below) */
            ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_INVALID);
            ck_assert_ptr_null(p);
            ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "unknowns must be the layers' values"));
            continue;
        }
        ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
        ck_assert_int_eq(wt_precond_kind_of(p), kind);
        ck_assert_str_eq(wt_precond_name(p), wt_precond_kind_name(kind));
        const double *jinv = wt_precond_jacobi_inverse(p);
        ck_assert(kind == WT_PRECOND_NONE ? jinv == NULL : jinv != NULL);
        double worst = 0.0;
        for (int trial = 0; trial < 4; trial++) {
            double a, b;
            random_pair(p, n, 100 + 2 * trial, x, y, px, py, &a, &b);
            double scale = 0.0;
            const int64_t nb = wt_precond_nblocks(p);
            int64_t idx[WT_MAX_LAYERS];
            double blk[WT_MAX_LAYERS * WT_MAX_LAYERS];
            int *inblock = calloc(n, sizeof *inblock);
            for (int64_t bb = 0; bb < nb; bb++) { /* multilevel: |x_b|ᵀ |B_b⁻¹| |y_b| */
                const lapack_int q = wt_precond_block(p, bb, idx, blk);
                ck_assert_int_eq(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', q, blk, q), 0);
                ck_assert_int_eq(LAPACKE_dpotri(LAPACK_COL_MAJOR, 'L', q, blk, q), 0);
                for (int a2 = 0; a2 < q; a2++) {
                    inblock[idx[a2]] = 1;
                    for (int c2 = 0; c2 < q; c2++) {
                        const double v = a2 >= c2 ? blk[a2 + q * c2] : blk[c2 + q * a2]; /* lower triangle */
                        scale += fabs(x[idx[a2]]) * fabs(v) * fabs(y[idx[c2]]);
                    }
                }
            }
            for (int64_t i = 0; i < n; i++)
                if (!inblock[i]) scale += fabs(x[i]) * (jinv ? jinv[i] : 1.0) * fabs(y[i]);
            free(inblock);
            const double bound = 16.0 * (double)n * 1.1e-16 * scale;
            ck_assert_msg(fabs(a - b) <= bound, "%s %s %s: xᵀP⁻¹y %.17g, yᵀP⁻¹x %.17g, |diff| %.3g > %.3g",
                          variant ? "cg9" : "pcg3", low ? "low noise" : "paper noise", wt_precond_kind_name(kind), a,
                          b, fabs(a - b), bound);
            worst = fmax(worst, fabs(a - b) / bound);
            ck_assert_msg(dot(x, px, n) > 0.0 && dot(y, py, n) > 0.0, "%s: zᵀP⁻¹z <= 0 on a random vector",
                          wt_precond_kind_name(kind));
        }
        ngs_modes_positive(&f, p, e, ax, ay);
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

START_TEST(test_threads_same_bits)
{
    const char *set[] = {"recon.pcg3.layer_size=[128, 32, 64]", "recon.pcg3.coarse_levels=1"};
    double *ref[4] = {NULL}, *out[4] = {NULL};
    int64_t n = 0, ns = 0;
    for (int th = 1; th <= 3; th++) {
        wt_context *ctx = tu_context();
        wt_context_set_threads(ctx, th);
        wt_config *cfg = NULL;
        wt_system *sys = NULL;
        wt_tomography *t = NULL;
        wt_precond *p = NULL;
        ck_assert_msg(wt_config_read(ctx, DEMO, 2, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
        wt_tomography_params tp;
        wt_tomography_params_from_config(cfg, &tp);
        ck_assert_msg(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_eq(wt_tomography_threads(t), th);
        ck_assert(wt_tomography_full_prior(t));
        const wt_precond_params pp = {.kind = WT_PRECOND_COARSE_NGS, .coarse_levels = 1};
        ck_assert_msg(wt_precond_alloc(ctx, t, &pp, &p) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_gt(wt_precond_rank(p), 0);
        n = wt_tomography_nunknowns(t);
        ns = sys->nslopes;
        ck_assert_int_ge(n, 16384);
        double *x = malloc(n * sizeof *x), *s = malloc(ns * sizeof *s);
        for (int k = 0; k < 4; k++) out[k] = calloc(n, sizeof *out[k]);
        tu_randn(x, n, 31);
        wt_tomography_apply(t, 1.0, x, out[0]);
        wt_precond_apply(p, x, out[1]);
        const wt_pcg_precond P = wt_precond_pcg(p);
        tu_randn(s, ns, 32);
        ck_assert_int_ge(wt_tomography_solve(t, P, s, out[2], 4, 0.0, NULL, NULL), 0);
        for (int64_t i = 0; i < ns; i++) s[i] *= 0.9;
        memcpy(out[3], out[2], n * sizeof *out[3]);
        ck_assert_int_ge(wt_tomography_solve_continue(t, P, s, out[3], 4, 0.0, NULL, NULL), 0);
        for (int k = 0; k < 4; k++) {
            if (th == 1) ref[k] = out[k];
            else {
                ck_assert_msg(memcmp(out[k], ref[k], n * sizeof *ref[k]) == 0, "%d threads: %s differs from 1 thread's",
                              th, (const char *[]){"M x", "P⁻¹ x", "the solve", "the continued solve"}[k]);
                free(out[k]);
            }
        }
        free(x), free(s);
        wt_precond_free(p);
        wt_tomography_free(t);
        wt_system_free(sys);
        wt_config_free(ctx, cfg);
        wt_context_free(ctx);
    }
    for (int k = 0; k < 4; k++) free(ref[k]);
}
END_TEST

/* The names are the configuration's list, in its order: the value recon.<variant>.preconditioner holds is
 * the kind. Unknown kinds and a coarse block beyond 4096 coefficients are refused with a message. */
/* From 16384 unknowns the operator, the preconditioner and the PCG run on the context's threads: the layers'
 * owners, the FFT and sensor tasks, coarse_ngs's split of J⁻¹, the coarse inverse's rows, the Woodbury blocks'
 * chunks and update. Every result must be one thread's bit for bit, on 2 and 3 threads (3: a thread with no
 * layer; a coarse row split that is not the 2-thread one): M x, P⁻¹ x, and two warm-started solves. The demo
 * with a 128² pcg3 layer (21504 unknowns; coarse_levels 1: 1344 coarse coefficients, all layers' NGS). */
/* coarse_ngs with its stored matrices in float (single: the coarse block's inverse and the NGS term's Y rounded once
 * each, the apply in double; the fp32 operator's preconditioner). The rounded inverse stays exactly symmetric
 * (each entry rounded once, both triangles alike) and Y K⁻¹ Yᵀ is symmetric for any Y: the same symmetry bound as
 * the double one's (test_symmetric_positive_definite). Definiteness: where Y K⁻¹ Yᵀ nearly cancels B⁻¹ (the NGS
 * modes, low noise) a rounding of Y by u moves P⁻¹ by ~u ‖B⁻¹‖, ~10⁻² of P⁻¹'s smallest eigenvalue there (NGS
 * weights ~10⁵): zᵀP⁻¹z > 0 on random vectors and on every NGS mode. Closeness: each stored entry moves by ≤ u, so
 * P⁻¹ x moves by ~u times |B_c⁻¹| |x| and |Y| K⁻¹ |Yᵀ x|, whose entries exceed the diagonal's J⁻¹ by the coarse
 * block's coupling (its inverse's off-diagonal mass): measured 1e-5 of ‖J⁻¹ x‖, i.e. ~170 u. Bound 1e-4 of
 * ‖J⁻¹ x‖: a block or column mixed up in the copies moves P⁻¹ x by O(1). */
START_TEST(test_single_storage)
{
    fixture f;
    setup(&f, 0, 1, 0, NULL); /* pcg3, low noise */
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *px = malloc(n * sizeof *px),
           *py = malloc(n * sizeof *py), *z64 = malloc(n * sizeof *z64), *jx = malloc(n * sizeof *jx),
           *ax = malloc(n * sizeof *ax), *ay = malloc(n * sizeof *ay), *e = calloc(ns, sizeof *e);
    wt_precond *p64 = NULL, *p32 = NULL;
    const wt_precond_params pp = {.kind = WT_PRECOND_COARSE_NGS, .coarse_levels = 2},
                            ps = {.kind = WT_PRECOND_COARSE_NGS, .coarse_levels = 2, .single = 1};
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p64) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &ps, &p32) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_int_gt(wt_precond_rank(p32), 0);
    ck_assert_int_gt(wt_precond_coarse_size(p32), 0);
    ck_assert_double_lt(wt_precond_bytes(p32), wt_precond_bytes(p64));
    const double *jinv = wt_precond_jacobi_inverse(p32);
    double worst = 0.0;
    for (int trial = 0; trial < 4; trial++) {
        double a, b;
        random_pair(p32, n, 300 + 2 * trial, x, y, px, py, &a, &b);
        double scale = 0.0;
        for (int64_t i = 0; i < n; i++) scale += fabs(x[i]) * jinv[i] * fabs(y[i]);
        ck_assert_double_le(fabs(a - b), 16.0 * (double)n * 1.1e-16 * scale);
        ck_assert(dot(x, px, n) > 0.0 && dot(y, py, n) > 0.0);
        wt_precond_apply(p64, x, z64);
        for (int64_t i = 0; i < n; i++) jx[i] = jinv[i] * x[i];
        const double d = tu_rel_diff(px, z64, n) * tu_norm(z64, n) / tu_norm(jx, n);
        ck_assert_double_gt(d, 0.0); /* (it is the float copy) */
        ck_assert_msg(d <= 1e-4, "single storage: |P32 x - P64 x| = %g of |J⁻¹ x|", d);
        worst = fmax(worst, d);
    }
    ngs_modes_positive(&f, p32, e, ax, ay);
    fprintf(stderr, "precond coarse_ngs single storage: |P32 x - P64 x| <= %.2g of |J^-1 x|; %.0f of %.0f bytes\n", worst,
            wt_precond_bytes(p32), wt_precond_bytes(p64));
    wt_precond_free(p64);
    wt_precond_free(p32);
    free(x), free(y), free(px), free(py), free(z64), free(jx), free(ax), free(ay), free(e);
    teardown(&f);
}
END_TEST

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
    /* a negative coarse_levels means "no coarse block" to fourier only */
    pp = (wt_precond_params){.kind = WT_PRECOND_COARSE_NGS, .coarse_levels = -1};
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_INVALID);
    ck_assert_ptr_null(p);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "coarse_levels -1"));
    /* 5 layers of 32²: all 3 levels would be 5120 coefficients */
    for (int kind = WT_PRECOND_COARSE_NGS; kind <= WT_PRECOND_MULTILEVEL; kind++) {
        pp = (wt_precond_params){.kind = kind, .coarse_levels = 3};
        ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_CONFIG);
        ck_assert_ptr_null(p);
        ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "coarse_levels 3"));
    }
    teardown(&f);
    /* the unknowns as the layers' values: only none and fourier; the DWT's kinds are refused */
    setup_space(&f, 0, 1, ONE_GRID);
    for (int kind = WT_PRECOND_JACOBI; kind <= WT_PRECOND_MULTILEVEL; kind++) {
        pp = (wt_precond_params){.kind = kind, .coarse_levels = 0};
        ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_INVALID);
        ck_assert_ptr_null(p);
        ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "only none and fourier"));
    }
    pp = (wt_precond_params){.kind = WT_PRECOND_FOURIER, .coarse_levels = 6}; /* 32 >> 0: the whole layer */
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_ERR_CONFIG);
    ck_assert_ptr_null(p);
    ck_assert_ptr_nonnull(strstr(wt_error_message(f.ctx), "at most 4096"));
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
        if (kind == WT_PRECOND_FOURIER) { /* on one grid, the unknowns the layers' values */
            teardown(&f);
            setup_space(&f, 0, 1, ONE_GRID);
        }
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
    TCase *tc_core = tcase_create("core");
    tcase_set_timeout(tc_core, 120);
    tcase_add_loop_test(tc_core, test_symmetric_positive_definite, 0, 4); /* {pcg3, cg9} x {paper, low noise} */
    tcase_add_test(tc_core, test_inverts_its_matrix);
    tcase_add_test(tc_core, test_threads_same_bits);
    tcase_add_test(tc_core, test_single_storage);
    tcase_add_test(tc_core, test_names_and_refusals);
    suite_add_tcase(s, tc_core);
    /* every kind's set-up, once per allocation it makes (~30 for multilevel): a few seconds here, several
     * minutes under AddressSanitizer on a loaded machine */
    TCase *tc_alloc = tcase_create("alloc");
    tcase_set_timeout(tc_alloc, 900);
    tcase_add_test(tc_alloc, test_allocation_failures);
    suite_add_tcase(s, tc_alloc);
    return s;
}

TU_MAIN
