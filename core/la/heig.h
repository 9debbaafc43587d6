/* core/la/heig.h: the largest eigenvalue of a small Hermitian matrix (the fourier preconditioner's symbol per
 * frequency, core/model/precond_update.c: thousands of problems of order ≤ WT_HEIG_MAX, where LAPACK's zheev
 * spends most of its time outside the arithmetic).
 *
 * The matrix A is scaled by a power of two (exact) to max |a_ij| in [1/2, 1), reduced to a real symmetric
 * tridiagonal T = Hᴴ A H by n − 2 Householder reflections (LAPACK zhetd2's lower variant: d, e real), and T's
 * largest eigenvalue is found by Laguerre's iteration from the Gershgorin bound (monotone from above, cubic), its
 * last bracket confirmed and bisected with Sturm counts (the LDLᵀ pivots of T − x I, Kahan's; LAPACK dstebz's
 * pivmin guard) until it is below 2 ε its bound. Both steps are backward stable: the result is an eigenvalue of A + E with ‖E‖ ≤ c n ε ‖A‖, so
 * |λ − λ_max(A)| ≤ c n ε ‖A‖ (Weyl), as zheev's; for A positive definite ‖A‖ = λ_max, a relative error of
 * ~n ε (tests/test_heig.c: within 64 n ε of zheev's on random and graded matrices).
 */
#ifndef WT_LA_HEIG_H
#define WT_LA_HEIG_H

#include <complex.h>

#define WT_HEIG_MAX 64

/* λ_max of the n x n Hermitian matrix whose lower triangle a holds (column-major, leading dimension lda; the
 * upper triangle and the diagonal's imaginary parts are not read). a is overwritten. Returns NaN when n is
 * outside [1, WT_HEIG_MAX] or an entry is not finite. */
double wt_heig_max(int n, double complex *a, int lda);

#endif
