/* tests/test_precond_multilevel.c: the multilevel preconditioner (core/model/precond_multilevel.c): its layer
 * blocks are the exact blocks of M̃ on a partition of the unknowns, it lowers the condition number (Lanczos from
 * the CG coefficients) and its PCG reaches the dense Cholesky solution. */
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

/* M̃ e_j restricted to the LGS part with C̃ (no tip-tilt removal), the sum the layer blocks are made of:
 * out[i] = Σ_LGS ⟨Ã e_i, C̃⁻¹ Ã e_j⟩ for the q indices idx, and bnd[i] = Σ |Ã e_i| |C̃⁻¹ Ã e_j| (the sum of
 * the summands' magnitudes, for the rounding bound). S: q x nslopes scratch, W the same. */
static void brute_block(fixture *f, int q, const int64_t *idx, double *out, double *bnd, double *S, double *W)
{
    const int64_t n = wt_tomography_nunknowns(f->t), ns = f->sys->nslopes;
    double *e = calloc(n, sizeof *e);
    for (int a = 0; a < q; a++) {
        e[idx[a]] = 1.0;
        memset(S + a * ns, 0, ns * sizeof *S);
        wt_tomography_slopes(f->t, 1.0, e, S + a * ns);
        e[idx[a]] = 0.0;
        memset(W + a * ns, 0, ns * sizeof *W);
        for (int m = 0; m < f->sys->nlgs; m++) {
            const wt_sensor *s = &f->sys->sensors[m];
            wt_noise_apply_inv(wt_tomography_noise(f->t, m), 1.0, S + a * ns + s->offset, W + a * ns + s->offset);
        }
    }
    const int64_t nl = f->sys->sensors[f->sys->nlgs - 1].offset + f->sys->sensors[f->sys->nlgs - 1].nslopes;
    for (int a = 0; a < q; a++)
        for (int c = 0; c < q; c++) {
            double v = 0.0, m = 0.0;
            for (int64_t k = 0; k < nl; k++) {
                v += S[a * ns + k] * W[c * ns + k];
                m += fabs(S[a * ns + k] * W[c * ns + k]);
            }
            out[a + q * c] = v;
            bnd[a + q * c] = m;
        }
    free(e);
}

/* The multilevel kind's blocks partition the unknowns outside the coarse square (each exactly once, none
 * inside it), hold the layers of one Mallat position each, and are the exact blocks of
 * M̃ = Σ_LGS Ãᵀ C̃⁻¹ Ã + α D there: the probing's entries against brute force (one slopes apply per unknown).
 * Bound: the probe sums the same summands in another order, |Δ| ≤ 2 γ_K Σ|summands| with K the LGS slopes
 * (γ_K = K u / (1 − K u) for each order); the block read back from its Cholesky factor, L Lᵀ = A + E with
 * |E_ac| ≤ γ_{q+1} (|L||Lᵀ|)_ac ≤ γ_{q+1} √(A_aa A_cc) (the rows of L have the norms √A_aa). A probe
 * attributed to the wrong block, or a cross-layer entry left out, misses by the size of the entry. Both
 * variants (cg9's layers of two sizes pair by Mallat position), low noise. */
START_TEST(test_multilevel_blocks_exact)
{
    fixture f;
    setup(&f, _i, 1, 0, NULL);
    const int64_t n = wt_tomography_nunknowns(f.t), ns = f.sys->nslopes;
    const int L = wt_tomography_nlayers(f.t);
    const wt_precond_params pp = {.kind = WT_PRECOND_MULTILEVEL, .coarse_levels = 1};
    wt_precond *p = NULL;
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
    const int64_t nb = wt_precond_nblocks(p);
    ck_assert_int_gt(nb, 0);
    ck_assert_int_eq(wt_precond_block(p, -1, NULL, NULL), -1);
    ck_assert_int_eq(wt_precond_block(p, nb, NULL, NULL), -1);
    /* the partition */
    int *seen = calloc(n, sizeof *seen);
    int64_t idx[WT_MAX_LAYERS], covered = 0;
    for (int64_t b = 0; b < nb; b++) {
        const int q = wt_precond_block(p, b, idx, NULL);
        ck_assert(q >= 1 && q <= L);
        int xy = -1;
        for (int a = 0; a < q; a++) {
            ck_assert_int_eq(seen[idx[a]]++, 0);
            int l = 0;
            while (l + 1 < L && wt_tomography_layer_offset(f.t, l + 1) <= idx[a]) l++;
            const int64_t k = idx[a] - wt_tomography_layer_offset(f.t, l);
            const int nx = wt_tomography_layer_grid(f.t, l)->nx, x = (int)(k % nx), y = (int)(k / nx);
            const int pos = x + 4096 * y; /* one Mallat position per block */
            if (a == 0) xy = pos;
            ck_assert_int_eq(pos, xy);
        }
        covered += q;
    }
    ck_assert_int_eq(covered + wt_precond_coarse_size(p), n);
    /* the entries, on every 7th block (all levels and orientations), plus the last */
    double *S = malloc((size_t)L * ns * sizeof *S), *W = malloc((size_t)L * ns * sizeof *W);
    double blk[WT_MAX_LAYERS * WT_MAX_LAYERS], ref[WT_MAX_LAYERS * WT_MAX_LAYERS], bnd[WT_MAX_LAYERS * WT_MAX_LAYERS];
    const double *alpha_d = wt_tomography_alpha_prior(f.t);
    const int64_t nl = f.sys->sensors[f.sys->nlgs - 1].offset + f.sys->sensors[f.sys->nlgs - 1].nslopes;
    const double u = 1.1e-16, gK = nl * u / (1.0 - nl * u);
    double worst = 0.0;
    int cross = 0;
    for (int64_t b = 0; b < nb; b = (b + 7 < nb || b == nb - 1) ? b + 7 : nb - 1) {
        const int q = wt_precond_block(p, b, idx, blk);
        brute_block(&f, q, idx, ref, bnd, S, W);
        const double gq = (q + 1) * u / (1.0 - (q + 1) * u);
        for (int a = 0; a < q; a++) ref[a + q * a] += alpha_d[idx[a]];
        for (int a = 0; a < q; a++)
            for (int c = 0; c < q; c++) {
                const double bound = 2.0 * gK * (bnd[a + q * c] + (a == c ? alpha_d[idx[a]] : 0.0)) +
                                     gq * sqrt(ref[a + q * a] * ref[c + q * c]);
                const double d = fabs(blk[a + q * c] - ref[a + q * c]);
                ck_assert_msg(d <= bound, "block %ld (%d x %d), entry (%d, %d): %.17g, brute force %.17g, |diff| %.3g > %.3g",
                              (long)b, q, q, a, c, blk[a + q * c], ref[a + q * c], d, bound);
                worst = fmax(worst, d / bound);
                if (a != c && fabs(ref[a + q * c]) > 1e-3 * sqrt(ref[a + q * a] * ref[c + q * c])) cross++;
            }
        if (b == nb - 1) break;
    }
    /* the layers are coupled: many off-diagonal entries are not negligible (else the blocks are J) */
    ck_assert_int_gt(cross, 10);
    fprintf(stderr, "multilevel blocks %s: %ld blocks, worst entry %.2g of the bound, %d coupled pairs\n",
            _i ? "cg9" : "pcg3", (long)nb, worst, cross);
    free(seen), free(S), free(W);
    wt_precond_free(p);
    teardown(&f);
}
END_TEST

/* The multilevel blocks lower κ(P⁻¹M) below the kinds it is built on, jacobi_ngs and coarse_ngs with the same
 * coarse block, on the demo's pcg3 and cg9 systems at low noise (the NGS weigh 10^5 times the LGS: the hard
 * case). κ from the Lanczos tridiagonal of a converged PCG (lanczos_kappa); on pcg3 (n = 2304) checked
 * against the dense eigenvalues of Lᵀ M L, P⁻¹ = L Lᵀ (P⁻¹ assembled by n applies): the Ritz values lie
 * inside the spectrum, and at convergence reach its ends to a few per cent. */
START_TEST(test_multilevel_condition)
{
    fixture f;
    setup(&f, _i, 1, 0, NULL);
    const int64_t n = wt_tomography_nunknowns(f.t);
    double *b = malloc(n * sizeof *b);
    tu_randn(b, n, 31);
    double kappa[WT_PRECOND_NKINDS] = {0};
    for (int kind = WT_PRECOND_JACOBI_NGS; kind <= WT_PRECOND_MULTILEVEL; kind++) {
        const wt_precond_params pp = {.kind = kind, .coarse_levels = 1};
        wt_precond *p = NULL;
        ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
        int its = 0;
        kappa[kind] = lanczos_kappa(&f, p, b, 6000, &its);
        fprintf(stderr, "condition %s low noise %-10s: kappa %.4g (%d CG iterations)\n", _i ? "cg9" : "pcg3",
                wt_precond_kind_name(kind), kappa[kind], its);
        if (_i == 0 && kind == WT_PRECOND_MULTILEVEL) {
            double *A = malloc((size_t)n * n * sizeof *A), *Z = malloc((size_t)n * n * sizeof *Z),
                   *e = calloc(n, sizeof *e), *w = malloc(n * sizeof *w);
            for (int64_t j = 0; j < n; j++) {
                e[j] = 1.0;
                tu_tomo_apply(f.t, e, A + n * j);
                wt_precond_apply(p, e, Z + n * j);
                e[j] = 0.0;
            }
            const lapack_int N = (lapack_int)n;
            ck_assert_int_eq(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', N, Z, N), 0); /* P⁻¹ = L Lᵀ */
            for (int64_t j = 0; j < n; j++)
                for (int64_t i = 0; i < j; i++) Z[i + n * j] = 0.0;
            cblas_dtrmm(CblasColMajor, CblasRight, CblasLower, CblasNoTrans, CblasNonUnit, N, N, 1.0, Z, N, A, N);
            cblas_dtrmm(CblasColMajor, CblasLeft, CblasLower, CblasTrans, CblasNonUnit, N, N, 1.0, Z, N, A, N);
            ck_assert_int_eq(LAPACKE_dsyev(LAPACK_COL_MAJOR, 'N', 'L', N, A, N, w), 0);
            const double kd = w[n - 1] / w[0];
            fprintf(stderr, "condition pcg3 low noise multilevel: dense %.4g (eigenvalues %.4g .. %.4g), Lanczos %.4g\n",
                    kd, w[0], w[n - 1], kappa[kind]);
            ck_assert(w[0] > 0.0);
            ck_assert_double_le(kappa[kind], kd * (1.0 + 1e-6));
            ck_assert_double_ge(kappa[kind], 0.9 * kd);
            free(A), free(Z), free(e), free(w);
        }
        wt_precond_free(p);
    }
    ck_assert_double_lt(kappa[WT_PRECOND_MULTILEVEL], kappa[WT_PRECOND_COARSE_NGS]);
    ck_assert_double_lt(kappa[WT_PRECOND_MULTILEVEL], kappa[WT_PRECOND_JACOBI_NGS]);
    free(b);
    teardown(&f);
}
END_TEST

/* The multilevel PCG reaches the direct solution of the same normal equations, within what the condition
 * number and the rounding allow (direct_gap). pcg3, low noise. */
START_TEST(test_multilevel_reaches_direct)
{
    fixture f;
    setup(&f, 0, 1, 0, NULL);
    const wt_precond_params pp = {.kind = WT_PRECOND_MULTILEVEL, .coarse_levels = 1};
    wt_precond *p = NULL;
    ck_assert_msg(wt_precond_alloc(f.ctx, f.t, &pp, &p) == WT_OK, "%s", wt_error_message(f.ctx));
    ck_assert_double_le(direct_gap(&f, p, 3000), 1.0);
    wt_precond_free(p);
    teardown(&f);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("precond_multilevel");
    TCase *tc_core = tcase_create("core");
    tcase_set_timeout(tc_core, 120);
    tcase_add_loop_test(tc_core, test_multilevel_blocks_exact, 0, 2); /* pcg3, cg9 */
    tcase_add_loop_test(tc_core, test_multilevel_condition, 0, 2);
    tcase_add_test(tc_core, test_multilevel_reaches_direct);
    suite_add_tcase(s, tc_core);
    return s;
}

TU_MAIN
