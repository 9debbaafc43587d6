/* tests/test_heig.c: the largest eigenvalue of a small Hermitian matrix (core/la/heig.c) against LAPACK's zheev.
 *
 * Both are backward stable: each returns an eigenvalue of A + E with ‖E‖₂ ≤ c n ε ‖A‖₂, so they agree to
 * 2 c n ε ‖A‖₂ (Weyl). c = 32 leaves room over the Householder and bisection constants (a few units each) and
 * would still catch a wrong reflection (an error of the order of the entries) or a bracket stopped early. */
#include "testutil.h"

#include <complex.h>
#include <float.h>
#include <lapacke.h>

#include "core/la/heig.h"

/* A = U diag(lam) Uᴴ, U unitary (Gram-Schmidt of random complex columns), column-major n x n */
static void make_herm(int n, const double *lam, unsigned long seed, double complex *A)
{
    double complex U[WT_HEIG_MAX * WT_HEIG_MAX];
    double re[2 * WT_HEIG_MAX * WT_HEIG_MAX];
    tu_randn(re, 2L * n * n, seed);
    for (int j = 0; j < n; j++) {
        double complex *u = U + (size_t)n * j;
        for (int i = 0; i < n; i++) u[i] = re[2 * (i + n * j)] + I * re[2 * (i + n * j) + 1];
        for (int pass = 0; pass < 2; pass++) /* twice: orthogonal to rounding */
            for (int k = 0; k < j; k++) {
                double complex dot = 0.0;
                for (int i = 0; i < n; i++) dot += conj(U[i + (size_t)n * k]) * u[i];
                for (int i = 0; i < n; i++) u[i] -= dot * U[i + (size_t)n * k];
            }
        double nr = 0.0;
        for (int i = 0; i < n; i++) nr += creal(u[i] * conj(u[i]));
        for (int i = 0; i < n; i++) u[i] /= sqrt(nr);
    }
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double complex s = 0.0;
            for (int k = 0; k < n; k++) s += U[i + (size_t)n * k] * lam[k] * conj(U[j + (size_t)n * k]);
            A[i + (size_t)n * j] = s;
        }
}

/* |wt_heig_max − zheev's largest| / ‖A‖₂ (‖A‖₂ = max |λ|, from zheev) */
static double rel_err(int n, const double complex *A)
{
    double complex a[WT_HEIG_MAX * WT_HEIG_MAX], b[WT_HEIG_MAX * WT_HEIG_MAX];
    double ev[WT_HEIG_MAX];
    memcpy(a, A, sizeof(double complex) * n * n);
    memcpy(b, A, sizeof(double complex) * n * n);
    ck_assert_int_eq(LAPACKE_zheev(LAPACK_COL_MAJOR, 'N', 'L', n, (lapack_complex_double *)b, n, ev), 0);
    const double got = wt_heig_max(n, a, n), norm = fmax(fabs(ev[0]), fabs(ev[n - 1]));
    return norm > 0 ? fabs(got - ev[n - 1]) / norm : fabs(got);
}

START_TEST(test_random_spectra)
{
    double lam[WT_HEIG_MAX];
    double complex A[WT_HEIG_MAX * WT_HEIG_MAX];
    for (int n = 1; n <= 16; n++)
        for (int kind = 0; kind < 4; kind++)
            for (int s = 0; s < 8; s++) {
                tu_randn(lam, n, 100 + s + 10 * n);
                for (int i = 0; i < n; i++) {
                    if (kind == 1) lam[i] = pow(10.0, -6.0 * i / (n > 1 ? n - 1 : 1)); /* graded PD, as the symbol */
                    if (kind == 2) lam[i] = i < 2 ? 1.0 - 1e-13 * i : 1e-3 * fabs(lam[i]); /* a near-double top */
                    if (kind == 3) lam[i] = 1e-200 * (1.0 + fabs(lam[i])); /* the scaling: no underflow in the norms */
                }
                make_herm(n, lam, 7 + s + 31 * n + 97 * kind, A);
                const double e = rel_err(n, A);
                ck_assert_msg(e <= 64.0 * n * DBL_EPSILON, "n %d kind %d seed %d: relative error %g", n, kind, s, e);
            }
}
END_TEST

/* the reduction's skipped columns (x = 0) and the trivial sizes, the refusals */
START_TEST(test_special)
{
    double complex A[WT_HEIG_MAX * WT_HEIG_MAX] = {0};
    ck_assert(wt_heig_max(3, A, 3) == 0.0);
    /* tridiagonal with complex sub-diagonal: eigenvalues of [[2, 1-i], [1+i, 3]] and a decoupled 0.5 */
    double complex T[9] = {2.0, 1.0 + I, 0.0, 0.0 /*upper*/, 3.0, 0.0, 0.0, 0.0, 0.5};
    const double want = 2.5 + sqrt(0.25 + 2.0);
    ck_assert_double_eq_tol(wt_heig_max(3, T, 3), want, 8 * DBL_EPSILON * want);
    double complex one = -4.0;
    ck_assert(wt_heig_max(1, &one, 1) == -4.0);
    double complex d[4] = {1.0, 0.0, 0.0, 7.0}; /* diagonal: exact */
    ck_assert(wt_heig_max(2, d, 2) == 7.0);
    double complex bad[4] = {1.0, NAN, 0.0, 1.0};
    ck_assert(isnan(wt_heig_max(2, bad, 2)));
    ck_assert(isnan(wt_heig_max(0, bad, 2)));
    ck_assert(isnan(wt_heig_max(WT_HEIG_MAX + 1, A, WT_HEIG_MAX + 1)));
    /* the upper triangle is not read */
    double complex u[4] = {1.0, 0.0, 1e300, 1.0};
    ck_assert(wt_heig_max(2, u, 2) == 1.0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("heig");
    TCase *tc = tcase_create("heig");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_random_spectra);
    tcase_add_test(tc, test_special);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
