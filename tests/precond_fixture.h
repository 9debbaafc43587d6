/* tests/precond_fixture.h: what the preconditioner suites share (test_precond.c, test_precond_multilevel.c,
 * test_precond_fourier.c): the demo's tomography (pcg3 or cg9, the paper's or the low-noise case, the layers in
 * the wavelet basis or in space), random vector pairs and the NGS modes for the SPD checks, the condition number
 * by Lanczos from the CG coefficients, and the distance of PCG from the dense solution. */
#ifndef WT_TESTS_PRECOND_FIXTURE_H
#define WT_TESTS_PRECOND_FIXTURE_H

#include <lapacke.h>
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

static inline void setup_basis(fixture *f, int cg9, int low, int nextra, const char *const *extra, int space)
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

static inline void setup(fixture *f, int cg9, int low, int nextra, const char *const *extra)
{
    setup_basis(f, cg9, low, nextra, extra, 0);
}

/* the fourier kind's: cg9's unknowns as the layers' values */
static inline void setup_space(fixture *f, int low, int nextra, const char *const *extra)
{
    setup_basis(f, 1, low, nextra, extra, 1);
}

static inline void teardown(fixture *f)
{
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static inline double dot(const double *x, const double *y, int64_t n) { return tu_dot(x, y, (long)n); }

/* Random x, y (seeds s, s + 1): P⁻¹ x and P⁻¹ y into px, py, and *a = xᵀ P⁻¹ y, *b = yᵀ P⁻¹ x */
static inline void random_pair(const wt_precond *p, int64_t n, unsigned s, double *x, double *y, double *px, double *py,
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
static inline void ngs_modes_positive(fixture *f, const wt_precond *p, double *e, double *ax, double *ay)
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

/* Preconditioned CG on M x = b from zero, to convergence, by hand, keeping its coefficients α_j, β_j: the
 * Lanczos tridiagonal of P⁻¹M (T_jj = 1/α_j + β_{j−1}/α_{j−1}, T_j,j+1 = √β_j / α_j), whose extreme
 * eigenvalues are the extreme Ritz values: κ(P⁻¹M) from inside, accurate once CG has converged (its
 * Krylov space then holds the extreme eigenvectors' components of b to the residual's accuracy). */
static inline double lanczos_kappa(fixture *f, const wt_precond *p, const double *b, int kmax, int *its)
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
static inline double direct_gap(fixture *f, const wt_precond *p, int maxit)
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

#endif
