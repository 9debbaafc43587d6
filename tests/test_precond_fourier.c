/* tests/test_precond_fourier.c: the fourier preconditioner (core/model/precond_fourier.c; layers on one grid): it
 * is SPD, is its filter (a Fourier mode in, the same mode times one factor on every layer out), lowers the condition
 * number and its PCG reaches the dense solution; its FFT plans from wisdom give the same preconditioner. */
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

/* The fourier kind, with its NGS term (demo cg9 on one grid; paper noise with the filter alone, low noise
 * with the coarse block of the scaling coefficients; the unknowns the layers' values): symmetric and positive
 * definite. Its B⁻¹ applies a real FFT pair per layer around the filter s(k) > 0 and the coarse space's
 * orthonormal projections; each is backward stable with an error of a few u log2(n²) relative to the
 * vector's norm, so a product
 * xᵀ P⁻¹ y carries an error of order u log2(n²) ‖x‖ ‖y‖ ‖B⁻¹‖, and the Woodbury term's two products
 * (Y K⁻¹ Yᵀ ≼ B⁻¹) as much. The test asks |xᵀP⁻¹y − yᵀP⁻¹x| ≤ 16 n u ‖x‖ ‖y‖ ‖P⁻¹‖₂ (the other kinds'
 * 16 n u, ‖P⁻¹‖₂ by 30 power iterations, a lower bound of ‖B⁻¹‖), and zᵀ P⁻¹ z > 0 on random vectors and on
 * the NGS modes. */
START_TEST(test_fourier_spd)
{
    fixture f;
    const int low = _i > 0, coarse = _i - 1; /* paper: the filter alone; low noise: coarse_levels 0, 1 */
    setup_space(&f, low, 1, ONE_GRID);
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    const wt_precond_params pp = {.kind = WT_PRECOND_FOURIER, .coarse_levels = coarse};
    wt_precond *p = NULL;
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_str_eq(wt_precond_name(p), "fourier");
    ck_assert_int_gt(wt_precond_rank(p), 0);
    { /* the coarse space: (n >> (J − coarse_levels))² per layer */
        const int J = wt_wavelet_levels(wt_tomography_wavelet(f.t, 0)), N = wt_tomography_layer_grid(f.t, 0)->nx;
        const int sc = coarse < 0 ? 0 : N >> (J - coarse);
        ck_assert_int_eq(wt_precond_coarse_size(p), wt_tomography_nlayers(f.t) * sc * sc);
    }
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *px = malloc(n * sizeof *px),
           *py = malloc(n * sizeof *py), *e = calloc(ns, sizeof *e);
    tu_randn(x, n, 7);
    double norm = 0.0;
    for (int it = 0; it < 30; it++) {
        const double nx = sqrt(dot(x, x, n));
        for (int64_t i = 0; i < n; i++) x[i] /= nx;
        wt_precond_apply(p, x, px);
        norm = sqrt(dot(px, px, n));
        memcpy(x, px, n * sizeof *x);
    }
    ck_assert(norm > 0.0 && isfinite(norm));
    for (int trial = 0; trial < 4; trial++) {
        double a, b;
        random_pair(p, n, 200 + 2 * trial, x, y, px, py, &a, &b);
        const double bound = 16.0 * (double)n * 1.1e-16 * sqrt(dot(x, x, n) * dot(y, y, n)) * norm;
        ck_assert_msg(fabs(a - b) <= bound, "fourier: xᵀP⁻¹y %.17g, yᵀP⁻¹x %.17g, |diff| %.3g > %.3g", a, b,
                      fabs(a - b), bound);
        ck_assert(dot(x, px, n) > 0.0 && dot(y, py, n) > 0.0);
        if (trial == 0) fprintf(stderr, "precond fourier %s, coarse_levels %d: asymmetry %.2g of the bound\n",
                                low ? "low" : "paper", coarse, fabs(a - b) / bound);
    }
    ngs_modes_positive(&f, p, e, x, px);
    wt_precond_free(p);
    free(x), free(y), free(px), free(py), free(e);
    teardown(&f);
}
END_TEST

/* Without NGS and without the coarse block (coarse_levels < 0), B_F⁻¹ is the filter itself: a Fourier mode cos(2π k·x/n) on any layer comes back as the same
 * mode times s(k) > 0, the same factor on every layer (a wrong frequency layout of the half spectrum, a lost
 * 1/n² or a layer's own scaling would break one of the three), to the transforms' rounding: the DWT and FFT
 * pairs leave errors of a few u log2(n²) ‖φ‖ at every frequency, which the filter scales by up to its
 * largest value ‖B⁻¹‖₂ (estimated by 30 power iterations), so the residual off the mode is asked to stay
 * below 64 u log2(n²) ‖B⁻¹‖₂ ‖φ‖, and the factors of the layers to agree within 1e-12 (one frequency's
 * s(k), the same number on every layer, up to the transforms' relative rounding). And the same bits on 1
 * and 2 threads. */
START_TEST(test_fourier_filter)
{
    static const char *const sets[] = {"recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]", "ngs.azimuths_deg=[]",
                                       "ngs.subapertures=[]"};
    fixture f;
    setup_space(&f, 1, 3, sets);
    const int64_t n = wt_tomography_nunknowns(f.t);
    const wt_grid *g = wt_tomography_layer_grid(f.t, 0);
    const int N = g->nx, L = wt_tomography_nlayers(f.t);
    const wt_precond_params pp = {.kind = WT_PRECOND_FOURIER, .coarse_levels = -1};
    wt_precond *p = NULL;
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_int_eq(wt_precond_rank(p), 0);
    double *phi = malloc(N * N * sizeof *phi), *c = calloc(n, sizeof *c), *z = malloc(n * sizeof *z),
           *zphi = malloc(N * N * sizeof *zphi);
    double nrm = 0.0;
    {
        double *v = malloc(n * sizeof *v), *pv = malloc(n * sizeof *pv);
        tu_randn(v, n, 9);
        for (int it = 0; it < 30; it++) {
            const double nv = sqrt(tu_dot(v, v, (long)n));
            for (int64_t i = 0; i < n; i++) v[i] /= nv;
            wt_precond_apply(p, v, pv);
            nrm = sqrt(tu_dot(pv, pv, (long)n));
            memcpy(v, pv, n * sizeof *v);
        }
        free(v), free(pv);
    }
    const double tol = 64.0 * 1.1e-16 * log2((double)N * N) * nrm;
    static const int freq[][2] = {{1, 0}, {0, 3}, {5, -2}, {16, 16}, {-7, 11}};
    for (int fi = 0; fi < 5; fi++) {
        double factor0 = 0.0;
        for (int l = 0; l < L; l++) {
            for (int iy = 0; iy < N; iy++)
                for (int ix = 0; ix < N; ix++)
                    phi[ix + N * iy] = cos(2.0 * M_PI * (freq[fi][0] * ix + freq[fi][1] * iy) / N + 0.3);
            memset(c, 0, n * sizeof *c);
            const int64_t o = wt_tomography_layer_offset(f.t, l);
            memcpy(c + o, phi, (size_t)N * N * sizeof *c); /* the unknowns are the values */
            wt_precond_apply(p, c, z);
            for (int l2 = 0; l2 < L; l2++)
                if (l2 != l)
                    for (int64_t i = 0; i < (int64_t)N * N; i++)
                        ck_assert_double_eq(z[wt_tomography_layer_offset(f.t, l2) + i], 0.0);
            memcpy(zphi, z + o, (size_t)N * N * sizeof *z);
            const double factor = tu_dot(zphi, phi, (long)N * N) / tu_dot(phi, phi, (long)N * N);
            double res = 0.0;
            for (int64_t i = 0; i < (int64_t)N * N; i++) res += pow(zphi[i] - factor * phi[i], 2);
            res = sqrt(res / tu_dot(phi, phi, (long)N * N));
            ck_assert_msg(factor > 0.0 && res <= tol, "fourier: mode (%d, %d) on layer %d: factor %g, residual %g",
                          freq[fi][0], freq[fi][1], l, factor, res);
            if (l == 0) factor0 = factor;
            ck_assert_msg(fabs(factor - factor0) <= 1e-12 * factor0, "fourier: mode (%d, %d): layer %d %.17g, layer 0 %.17g",
                          freq[fi][0], freq[fi][1], l, factor, factor0);
        }
    }
    /* the same bits on 1 and 2 threads (whole layers per thread) */
    double *r = malloc(n * sizeof *r), *z1 = malloc(n * sizeof *z1);
    tu_randn(r, n, 5);
    wt_precond_apply(p, r, z);
    wt_precond_free(p);
    wt_tomography_free(f.t);
    wt_context_set_threads(f.ctx, 2);
    wt_tomography_params tp;
    wt_tomography_params_from_config(f.cfg, &tp);
    tp.space = 1;
    ck_assert_int_eq(wt_tomography_alloc(f.ctx, f.sys, f.v, "cg9", &tp, &f.t), WT_OK);
    ck_assert_int_eq(wt_precond_alloc(f.ctx, f.t, &pp, &p), WT_OK);
    wt_precond_apply(p, r, z1);
    ck_assert_int_eq(memcmp(z, z1, n * sizeof *z), 0);
    wt_precond_free(p);
    free(phi), free(c), free(z), free(zphi), free(r), free(z1);
    teardown(&f);
}
END_TEST

/* The fourier kind lowers the condition number of M (Lanczos from the CG coefficients, as above; demo cg9 on
 * one grid, low noise, with the NGS term) below plain CG's and below jacobi_ngs's (measured 6.1e4 against
 * 2.3e5 and 1.3e9), and its PCG reaches the dense Cholesky solution of the same normal equations within what
 * the condition number and the rounding allow (direct_gap). */
START_TEST(test_fourier_condition_and_direct)
{
    fixture f, fs; /* wavelet coefficients (none, jacobi_ngs), the layers' values (fourier): κ(M) is the same */
    setup(&f, 1, 1, 1, ONE_GRID);
    setup_space(&fs, 1, 1, ONE_GRID);
    const int64_t n = wt_tomography_nunknowns(f.t);
    double *b = malloc(n * sizeof *b);
    tu_randn(b, n, 31);
    double kappa[WT_PRECOND_NKINDS] = {0};
    const int kinds[] = {WT_PRECOND_NONE, WT_PRECOND_JACOBI_NGS, WT_PRECOND_FOURIER};
    wt_precond *p = NULL;
    for (int i = 0; i < 3; i++) {
        fixture *fi = i == 2 ? &fs : &f;
        const wt_precond_params pp = {.kind = kinds[i], .coarse_levels = 0};
        ck_assert_msg(wt_precond_alloc(fi->ctx, fi->t, &pp, &p) == WT_OK, "%s", wt_error_message(fi->ctx));
        int its = 0;
        kappa[kinds[i]] = lanczos_kappa(fi, p, b, 8000, &its);
        fprintf(stderr, "condition cg9 one grid low noise %-10s: kappa %.4g (%d CG iterations)\n",
                wt_precond_kind_name(kinds[i]), kappa[kinds[i]], its);
        if (i < 2) wt_precond_free(p);
    }
    ck_assert_double_lt(kappa[WT_PRECOND_FOURIER], kappa[WT_PRECOND_NONE]);
    ck_assert_double_lt(kappa[WT_PRECOND_FOURIER], kappa[WT_PRECOND_JACOBI_NGS]);
    ck_assert_double_le(direct_gap(&fs, p, 6000), 1.0);
    wt_precond_free(p);
    free(b);
    teardown(&f);
    teardown(&fs);
}
END_TEST

/* recon.fft_wisdom: the fourier kind on a space tomography (whose full prior and filter both run the n x n
 * pair) planned from a wisdom file gives M x and P⁻¹ x equal to the FFTW_ESTIMATE plans' up to the transforms'
 * rounding — another algorithm rounds differently by O(u log2 n²) per transform, amplified in P⁻¹ by the
 * filter's and the Woodbury term's conditioning (on this machine the demo's 32 x 32 measured plans happen to
 * round as ESTIMATE's: 0) — and the same bits
 * from a second set-up with the same file; the SHA-256 the configuration records is the file's; a wisdom
 * without the layers' size is refused naming the key. */
static void fft_wisdom_file(const wt_config *cfg, int size_only, char *path, size_t np)
{
    wt_context *ctx = tu_context();
    wt_fft_wisdom *w = NULL;
    ck_assert_int_eq(wt_fft_wisdom_learner(ctx, &w), WT_OK);
    ck_assert_int_eq(wt_fft_wisdom_learn(ctx, w, size_only ? size_only : cfg->cg9.size[0]), WT_OK);
    snprintf(path, np, "/tmp/wt_wisdom_XXXXXX");
    const int fd = mkstemp(path);
    ck_assert(fd >= 0);
    close(fd);
    ck_assert_int_eq(wt_fft_wisdom_write(ctx, w, path), WT_OK);
    wt_fft_wisdom_free(w);
    wt_context_free(ctx);
}

START_TEST(test_fft_wisdom)
{
    fixture a, b, c;
    setup_space(&a, 1, 1, ONE_GRID);
    char path[64], set[128];
    fft_wisdom_file(a.cfg, 0, path, sizeof path);
    snprintf(set, sizeof set, "recon.fft_wisdom=\"%s\"", path);
    const char *extra[] = {ONE_GRID[0], set};
    setup_space(&b, 1, 2, extra);
    setup_space(&c, 1, 2, extra);
    char hex[65];
    ck_assert_int_eq(wt_sha256_file(path, hex), 0);
    ck_assert_str_eq(b.cfg->fft_wisdom_sha256, hex);
    ck_assert_ptr_null(wt_tomography_fft(a.t));
    ck_assert_str_eq(wt_fft_wisdom_sha256(wt_tomography_fft(b.t)), hex);
    const wt_precond_params pp = {.kind = WT_PRECOND_FOURIER, .coarse_levels = 0};
    wt_precond *pa = NULL, *pb = NULL, *pc = NULL;
    ck_assert_int_eq(wt_precond_alloc(a.ctx, a.t, &pp, &pa), WT_OK);
    ck_assert_int_eq(wt_precond_alloc(b.ctx, b.t, &pp, &pb), WT_OK);
    ck_assert_int_eq(wt_precond_alloc(c.ctx, c.t, &pp, &pc), WT_OK);
    const int64_t n = wt_tomography_nunknowns(a.t);
    double *x = malloc(n * sizeof *x), *ya = malloc(n * sizeof *ya), *yb = malloc(n * sizeof *yb),
           *yc = malloc(n * sizeof *yc);
    tu_randn(x, n, 77);
    tu_tomo_apply(a.t, x, ya);
    tu_tomo_apply(b.t, x, yb);
    tu_tomo_apply(c.t, x, yc);
    ck_assert_double_le(tu_rel_diff(yb, ya, n), 1e-13);
    ck_assert_int_eq(memcmp(yb, yc, n * sizeof *yb), 0);
    wt_precond_apply(pa, x, ya);
    wt_precond_apply(pb, x, yb);
    wt_precond_apply(pc, x, yc);
    fprintf(stderr, "fft wisdom: P⁻¹ x against FFTW_ESTIMATE's: %.2g relative\n", tu_rel_diff(yb, ya, n));
    ck_assert_double_le(tu_rel_diff(yb, ya, n), 1e-12);
    ck_assert_int_eq(memcmp(yb, yc, n * sizeof *yb), 0);
    wt_precond_free(pa), wt_precond_free(pb), wt_precond_free(pc);
    teardown(&b), teardown(&c);
    remove(path);

    /* a wisdom of another size */
    fft_wisdom_file(a.cfg, a.cfg->cg9.size[0] / 2, path, sizeof path);
    snprintf(set, sizeof set, "recon.fft_wisdom=\"%s\"", path);
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_tomography *t = NULL;
    const char *sets[] = {ONE_GRID[0], set};
    ck_assert_int_eq(wt_config_read(a.ctx, DEMO, 2, sets, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(a.ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(a.ctx, sys, &cfg->cg9, "cg9", &tp, &t), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(a.ctx), "recon.fft_wisdom") && strstr(wt_error_message(a.ctx), path),
                  "%s", wt_error_message(a.ctx));
    ck_assert_ptr_null(t);
    remove(path);
    wt_system_free(sys);
    wt_config_free(a.ctx, cfg);
    free(x), free(ya), free(yb), free(yc);
    teardown(&a);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("precond_fourier");
    TCase *tc_core = tcase_create("core");
    tcase_set_timeout(tc_core, 120);
    tcase_add_loop_test(tc_core, test_fourier_spd, 0, 3); /* paper (no coarse block), low noise (coarse_levels 0, 1) */
    tcase_add_test(tc_core, test_fourier_filter);
    tcase_add_test(tc_core, test_fourier_condition_and_direct);
    tcase_add_test(tc_core, test_fft_wisdom);
    suite_add_tcase(s, tc_core);
    return s;
}

TU_MAIN
