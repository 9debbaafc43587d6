/* tests/test_precond.c: the preconditioners of core/model/precond.h on the demo system: every kind is
 * symmetric positive definite (xᵀ P⁻¹ y = yᵀ P⁻¹ x to rounding, zᵀ P⁻¹ z > 0 on random vectors and on the
 * NGS modes, where the Woodbury term cancels most of B⁻¹), each is the inverse of the P it claims to be,
 * the multilevel kind's layer blocks are the exact blocks of M̃ on a partition of the unknowns, lower the
 * condition number (Lanczos from the CG coefficients) and its PCG reaches the dense Cholesky solution, the
 * kind names match the configuration's list, and bad input and allocation failures are refused. The fourier
 * kind (layers on one grid) is SPD, is its filter (a Fourier mode in, the same mode times one factor on every
 * layer out), lowers the condition number and its PCG reaches the dense solution. */
#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <string.h>
#include <unistd.h>

#include "core/base/sha256.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/op/noise.h"
#include "core/op/wavelet.h"
#include "core/model/tomography.h"
#include "testmodel.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
/* SPEC §11's low-noise case: the NGS weigh ~10^5 times the LGS along a dozen global modes, the hardest
 * case for the Woodbury term's cancellation */
static const char *const LOW[] = {"lgs.wfs.nea_mas=20.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0"};
/* the demo's cg9 layers on one grid (32 x 1 m), as the fourier kind needs; and without NGS */
static const char *const ONE_GRID[] = {"recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]", "ngs.azimuths_deg=[]",
                                       "ngs.subapertures=[]"};

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    const wt_recon_variant_config *v;
} fixture;

static void setup_basis(fixture *f, int cg9, int low, int nextra, const char *const *extra, int space)
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
    tp.space = space;
    f->v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, f->v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                  wt_error_message(f->ctx));
}

static void setup(fixture *f, int cg9, int low, int nextra, const char *const *extra)
{
    setup_basis(f, cg9, low, nextra, extra, 0);
}

/* the fourier kind's: cg9's unknowns as the layers' values */
static void setup_space(fixture *f, int low, int nextra, const char *const *extra)
{
    setup_basis(f, 1, low, nextra, extra, 1);
}

static void teardown(fixture *f)
{
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static double dot(const double *x, const double *y, int64_t n) { return tu_dot(x, y, (long)n); }

/* Random x, y (seeds s, s + 1): P⁻¹ x and P⁻¹ y into px, py, and *a = xᵀ P⁻¹ y, *b = yᵀ P⁻¹ x */
static void random_pair(const wt_precond *p, int64_t n, unsigned s, double *x, double *y, double *px, double *py,
                        double *a, double *b)
{
    tu_randn(x, n, s);
    tu_randn(y, n, s + 1);
    wt_precond_apply(p, x, px);
    wt_precond_apply(p, y, py);
    *a = dot(x, py, n);
    *b = dot(y, px, n);
}

/* zᵀ P⁻¹ z > 0 on the NGS modes G e_k = Ãᵀ Ĉ⁻¹ e_k: where Y K⁻¹ Yᵀ nearly cancels B⁻¹, the place a loss of
 * definiteness would show (e: zeroed slopes; ax, ay: n values of work) */
static void ngs_modes_positive(fixture *f, const wt_precond *p, double *e, double *ax, double *ay)
{
    const int64_t n = wt_tomography_nunknowns(f->t);
    for (int m = f->sys->nlgs; m < f->sys->nsensors; m++)
        for (int k = 0; k < f->sys->sensors[m].nslopes; k++) {
            const int64_t o = f->sys->sensors[m].offset + k;
            e[o] = 1.0;
            tu_tomo_rhs(f->t, e, ax);
            e[o] = 0.0;
            wt_precond_apply(p, ax, ay);
            ck_assert_msg(dot(ax, ay, n) > 0.0, "%s: zᵀP⁻¹z = %g on NGS mode %d of %s", wt_precond_name(p),
                          dot(ax, ay, n), k, f->sys->sensors[m].name);
        }
}

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

/* Preconditioned CG on M x = b from zero, to convergence, by hand, keeping its coefficients α_j, β_j: the
 * Lanczos tridiagonal of P⁻¹M (T_jj = 1/α_j + β_{j−1}/α_{j−1}, T_j,j+1 = √β_j / α_j), whose extreme
 * eigenvalues are the extreme Ritz values: κ(P⁻¹M) from inside, accurate once CG has converged (its
 * Krylov space then holds the extreme eigenvectors' components of b to the residual's accuracy). */
static double lanczos_kappa(fixture *f, const wt_precond *p, const double *b, int kmax, int *its)
{
    const int64_t n = wt_tomography_nunknowns(f->t);
    double *x = calloc(n, sizeof *x), *r = malloc(n * sizeof *r), *z = malloc(n * sizeof *z),
           *d = malloc(n * sizeof *d), *q = malloc(n * sizeof *q);
    double *al = malloc(kmax * sizeof *al), *be = malloc(kmax * sizeof *be);
    memcpy(r, b, n * sizeof *r);
    wt_precond_apply(p, r, z);
    memcpy(d, z, n * sizeof *d);
    double rz = dot(r, z, n);
    const double b0 = tu_norm(b, n);
    int k = 0;
    for (; k < kmax; k++) {
        tu_tomo_apply(f->t, d, q);
        al[k] = rz / dot(d, q, n);
        for (int64_t i = 0; i < n; i++) {
            x[i] += al[k] * d[i];
            r[i] -= al[k] * q[i];
        }
        wt_precond_apply(p, r, z);
        const double rz1 = dot(r, z, n);
        be[k] = rz1 / rz;
        rz = rz1;
        for (int64_t i = 0; i < n; i++) d[i] = z[i] + be[k] * d[i];
        if (tu_norm(r, n) < 1e-11 * b0) {
            k++;
            break;
        }
    }
    double *T = malloc(k * sizeof *T), *E = malloc(k * sizeof *E);
    for (int j = 0; j < k; j++) {
        T[j] = 1.0 / al[j] + (j > 0 ? be[j - 1] / al[j - 1] : 0.0);
        if (j + 1 < k) E[j] = sqrt(be[j]) / al[j];
    }
    ck_assert_int_eq(LAPACKE_dstev(LAPACK_COL_MAJOR, 'N', k, T, E, NULL, 1), 0); /* ascending */
    const double kappa = T[k - 1] / T[0];
    ck_assert(T[0] > 0.0);
    *its = k;
    free(x), free(r), free(z), free(d), free(q), free(al), free(be), free(T), free(E);
    return kappa;
}

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

/* The PCG solution x_p (preconditioner p, to a recursive residual ‖b − M x_p‖ ≤ τ‖b‖, τ = 1e-13, in at most
 * maxit iterations) against the dense Cholesky solution x_d (LAPACK dpotrf/dpotrs of M assembled column by
 * column, n applies) of the same normal equations, for slopes of a seeded draw at the scale of real data: their
 * gap in M's own norm ‖v‖_M = √(vᵀMv), the norm CG minimises, relative to ‖x_d‖_M, divided by the bound
 * the rounding and the condition number allow (≤ 1 passes; both printed).
 * The bound: x_p − x_d = M⁻¹(r_d − r_p) for the true residuals r = b − M x, and for any r,
 * ‖M⁻¹r‖_M² = rᵀM⁻¹r ≤ ‖r‖²/λ_min while ‖x‖_M² = bᵀM⁻¹b ≥ ‖b‖²/λ_max, so
 *     ‖x_p − x_d‖_M / ‖x_d‖_M ≤ √κ₂(M) (‖r_p‖ + ‖r_d‖) / ‖b‖.
 * ‖r_p‖ ≤ τ‖b‖ plus the drift of CG's recursive residual from the true one; the Cholesky solve is backward
 * stable, (M + ΔM) x_d = b, so ‖r_d‖ ≤ ‖ΔM‖ ‖x_d‖. Both roundings are sums of n (Cholesky) and of k ≤ n
 * (CG's updates) terms, of order √n u ‖M‖ ‖x_d‖ each (the probabilistic rounding bound, λ√n u with λ = 1:
 * Higham & Mary, SIAM J. Sci. Comput. 41, 2019); the residual measured is 1.1 u ‖M‖₂‖x_d‖ for the direct
 * solve, 0.99 τ‖b‖ for the PCG. Hence the bound
 *     √κ₁(M) (τ + 2 √n u ‖M‖₁ ‖x_d‖ / ‖b‖),
 * with the 1-norms (LAPACK dlansy and dpocon's estimate of κ₁) for the 2-norms: for a symmetric M,
 * ‖M‖₂ ≤ ‖M‖₁ and κ₂ ≤ κ₁ (pcg3 low noise: κ₁ 1.8e10 against κ₂ 3.6e9 from the dense eigenvalues). Nothing
 * in it depends on the threads: only the rounding's draw does (the 2-norm gap, 1.1e-8 on one thread and 8.7e-9
 * on two, is the dense solve's u κ₂ error along M's smallest eigenvectors, which the M-norm weighs by λ_min). */
static double direct_gap(fixture *f, const wt_precond *p, int maxit)
{
    const double tau = 1e-13, u = DBL_EPSILON / 2;
    const int64_t n = wt_tomography_nunknowns(f->t), ns = f->sys->nslopes;
    const lapack_int N = (lapack_int)n;
    double *A = malloc((size_t)n * n * sizeof *A), *e = calloc(n, sizeof *e);
    for (int64_t j = 0; j < n; j++) {
        e[j] = 1.0;
        tu_tomo_apply(f->t, e, A + n * j);
        e[j] = 0.0;
    }
    double *s = malloc(ns * sizeof *s), *x = calloc(n, sizeof *x), *xd = malloc(n * sizeof *xd),
           *b = malloc(n * sizeof *b), *Mv = malloc(n * sizeof *Mv);
    tu_randn(s, ns, 41);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6; /* slope scale of real data [rad] */
    tu_tomo_rhs(f->t, s, b);
    memcpy(xd, b, n * sizeof *xd);
    const double norm1 = LAPACKE_dlansy(LAPACK_COL_MAJOR, '1', 'L', N, A, N);
    double rcond = 0.0;
    ck_assert_int_eq(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', N, A, N), 0);
    ck_assert_int_eq(LAPACKE_dpocon(LAPACK_COL_MAJOR, 'L', N, A, N, norm1, &rcond), 0);
    ck_assert_int_eq(LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', N, 1, A, N, xd, N), 0);
    ck_assert(rcond > 0.0);
    wt_pcg_result r;
    const int st = wt_tomography_solve(f->t, wt_precond_pcg(p), s, x, maxit, tau, NULL, &r);
    ck_assert_msg(st == WT_OK, "%s PCG did not reach %g in %d iterations: %s (%d its, %g)", wt_precond_name(p), tau,
                  maxit, wt_error_message(f->ctx), r.iterations, r.rel_resid);
    const double gap2 = tu_rel_diff(x, xd, n);
    tu_tomo_apply(f->t, xd, Mv);
    const double xm = sqrt(dot(xd, Mv, n));
    for (int64_t i = 0; i < n; i++) x[i] -= xd[i];
    tu_tomo_apply(f->t, x, Mv);
    const double gap = sqrt(fmax(dot(x, Mv, n), 0.0)) / xm;
    const double bound = sqrt(1.0 / rcond) * (tau + 2.0 * sqrt((double)n) * u * norm1 * tu_norm(xd, n) / tu_norm(b, n));
    fprintf(stderr, "%s PCG: %d iterations to %g; from the dense Cholesky solution %.2g in M's norm (bound %.2g, "
            "kappa_1 %.3g), %.2g in the 2-norm\n", wt_precond_name(p), r.iterations, tau, gap, bound, 1.0 / rcond, gap2);
    free(A), free(e), free(s), free(x), free(xd), free(b), free(Mv);
    return gap / bound;
}

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
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_loop_test(tc, test_symmetric_positive_definite, 0, 4); /* {pcg3, cg9} x {paper, low noise} */
    tcase_add_test(tc, test_inverts_its_matrix);
    tcase_add_loop_test(tc, test_multilevel_blocks_exact, 0, 2); /* pcg3, cg9 */
    tcase_add_loop_test(tc, test_multilevel_condition, 0, 2);
    tcase_add_test(tc, test_multilevel_reaches_direct);
    tcase_add_loop_test(tc, test_fourier_spd, 0, 3); /* paper (no coarse block), low noise (coarse_levels 0, 1) */
    tcase_add_test(tc, test_fourier_filter);
    tcase_add_test(tc, test_fourier_condition_and_direct);
    tcase_add_test(tc, test_threads_same_bits);
    tcase_add_test(tc, test_single_storage);
    tcase_add_test(tc, test_names_and_refusals);
    tcase_add_test(tc, test_fft_wisdom);
    suite_add_tcase(s, tc);
    /* every kind's set-up, once per allocation it makes (~30 for multilevel): a few seconds here, several
     * minutes under AddressSanitizer on a loaded machine */
    TCase *ta = tcase_create("alloc");
    tcase_set_timeout(ta, 900);
    tcase_add_test(ta, test_allocation_failures);
    suite_add_tcase(s, ta);
    return s;
}

TU_MAIN
