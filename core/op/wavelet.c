/* core/op/wavelet.c: periodic orthonormal 2-D Daubechies DWT W and its inverse W⁻¹ = Wᵀ.
 *
 * Implements SPEC §6 (orthonormal separable Daubechies-N DWT, periodic boundary, J levels) and the
 * paper's §5 change of variables c = W φ, φ = W⁻¹ c. The filters come from Daubechies' spectral
 * factorisation (Ten Lectures, §6.1): |m0(ξ)|² = cos^{2N}(ξ/2) P(sin²(ξ/2)) with
 * P(y) = Σ_{k<N} C(N−1+k, k) y^k; each root of P gives a pair z, 1/z through z + 1/z = 2 − 4y and the
 * minimum-phase factor keeps |z| < 1.
 *
 * One level on a block of side m: a_k = Σ_i h_i x_{(2k+i) mod m}, d_k = Σ_i g_i x_{(2k+i) mod m},
 * g_i = (−1)^i h_{2N−1−i}, first along x (rows), then along y (columns); the inverse is the transpose,
 * in reverse order. Periodisation keeps the rows orthonormal for every even m, including m < 2N.
 */
#include "wavelet.h"

#include <complex.h>
#include <lapacke.h>
#include <math.h>
#include <string.h>

#define MAXTAPS (2 * WT_WAVELET_MAX_ORDER)

struct wt_wavelet {
    wt_context *ctx;
    int n;      /* grid side (power of two) */
    int order;  /* Daubechies N */
    int levels; /* J */
    double h[MAXTAPS]; /* low-pass, 2N taps */
    double g[MAXTAPS]; /* high-pass g_i = (−1)^i h_{2N−1−i} */
    float h32[MAXTAPS], g32[MAXTAPS]; /* the filters rounded to float (the single-precision forms) */
};

/* ---------------------------------------------------------------------------------------------- */
/* Filters                                                                                        */
/* ---------------------------------------------------------------------------------------------- */

typedef long double complex cld;

/* P(y) and P'(y) by Horner; c holds the d+1 coefficients, ascending. */
static void poly_eval(const long double *c, int d, cld y, cld *p, cld *dp)
{
    cld v = c[d], dv = 0.0L;
    for (int k = d - 1; k >= 0; k--) {
        dv = dv * y + v;
        v = v * y + c[k];
    }
    *p = v;
    *dp = dv;
}

int wt_wavelet_filter(wt_context *ctx, int order, double *h)
{
    if (order < 1 || order > WT_WAVELET_MAX_ORDER)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wavelet order %d is not available: Daubechies-N needs N in 1 ... %d", order,
                        WT_WAVELET_MAX_ORDER);
    if (!h) return WT_ERROR(ctx, WT_ERR_INVALID, "wavelet filter output h is NULL");
    const int N = order, L = 2 * N, d = N - 1;

    /* The roots are found in double (LAPACK) and then everything else runs in long double, so that
     * the product expansion does not lose the last bits orthonormality needs at N = 10. */
    long double pc[WT_WAVELET_MAX_ORDER];
    for (int k = 0; k <= d; k++) {
        long double b = 1.0L; /* C(N−1+k, k), exact in long double */
        for (int j = 1; j <= k; j++) b = b * (long double)(N - 1 + j) / (long double)j;
        pc[k] = b;
    }

    cld zk[WT_WAVELET_MAX_ORDER];
    if (d > 0) {
        /* Companion matrix of the monic P / pc[d] (column-major): ones on the subdiagonal, the last
         * column −pc[k]/pc[d]. */
        double A[(WT_WAVELET_MAX_ORDER - 1) * (WT_WAVELET_MAX_ORDER - 1)];
        double wr[WT_WAVELET_MAX_ORDER], wi[WT_WAVELET_MAX_ORDER];
        memset(A, 0, sizeof A);
        for (int i = 1; i < d; i++) A[i + d * (i - 1)] = 1.0;
        for (int i = 0; i < d; i++) A[i + d * (d - 1)] = (double)(-pc[i] / pc[d]);
        lapack_int info = LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', d, A, d, wr, wi, NULL, 1, NULL, 1);
        if (info != 0)
            return WT_ERROR(ctx, WT_ERR_LIBRARY,
                            "LAPACKE_dgeev failed (info %d) on the degree-%d Daubechies polynomial for N = %d",
                            (int)info, d, N);
        for (int k = 0; k < d; k++) {
            cld y = (long double)wr[k] + (long double)wi[k] * I;
            /* Newton polish: the roots are simple, so a few steps reach long-double accuracy. */
            for (int it = 0; it < 8; it++) {
                cld p, dp;
                poly_eval(pc, d, y, &p, &dp);
                if (dp == 0.0L) break;
                cld step = p / dp;
                y -= step;
                if (cabsl(step) <= 1e-18L * cabsl(y)) break;
            }
            /* z² − b z + 1 = 0 with b = 2 − 4y: take the large root stably, its reciprocal is the one
             * inside the unit circle (minimum phase). */
            cld b = 2.0L - 4.0L * y;
            cld s = csqrtl(b * b - 4.0L);
            cld zbig = cabsl(b + s) >= cabsl(b - s) ? 0.5L * (b + s) : 0.5L * (b - s);
            zk[k] = 1.0L / zbig;
        }
    }

    /* H(z) ∝ (1 + z)^N Π (z − z_k), ascending powers of z. */
    cld p[MAXTAPS];
    for (int i = 0; i < L; i++) p[i] = 0.0L;
    p[0] = 1.0L;
    int deg = 0;
    for (int k = 0; k < N; k++, deg++)
        for (int i = deg + 1; i >= 1; i--) p[i] += p[i - 1];
    for (int k = 0; k < d; k++, deg++) {
        for (int i = deg + 1; i >= 1; i--) p[i] = p[i - 1] - zk[k] * p[i];
        p[0] = -zk[k] * p[0];
    }

    /* Σ h_k z^{-k} carries the zeros inside the disc when h_k is the coefficient of z^{2N−1−k}; this is
     * the ordering of Daubechies' table (db2 starts with (1+√3)/(4√2)). The sign makes Σh > 0. */
    long double hr[MAXTAPS], sum = 0.0L;
    for (int k = 0; k < L; k++) {
        hr[k] = creall(p[L - 1 - k]);
        sum += hr[k];
    }
    long double scale = sqrtl(2.0L) / sum;
    for (int k = 0; k < L; k++) h[k] = (double)(hr[k] * scale);
    return WT_OK;
}

/* ---------------------------------------------------------------------------------------------- */
/* Plan                                                                                           */
/* ---------------------------------------------------------------------------------------------- */

int wt_wavelet_alloc(wt_context *ctx, int n, int order, int levels, wt_wavelet **out)
{
    int st = WT_OK;
    wt_wavelet *w = NULL;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_wavelet_alloc: out is NULL");
    *out = NULL;
    if (n < 2 || n > (1 << 16) || (n & (n - 1)) != 0)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wavelet grid side n = %d is not supported: n must be a power of two in 2 ... 65536", n);
    int lmax = 0;
    while ((1 << lmax) < n) lmax++;
    if (levels < 1 || levels > lmax)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wavelet levels J = %d is out of range for n = %d: need 1 <= J <= log2(n) = %d",
                        levels, n, lmax);
    if (order < 1 || order > WT_WAVELET_MAX_ORDER)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wavelet order %d is not available: Daubechies-N needs N in 1 ... %d", order,
                        WT_WAVELET_MAX_ORDER);
    WT_ALLOC(ctx, w, 1, "wavelet plan");
    w->ctx = ctx;
    w->n = n;
    w->order = order;
    w->levels = levels;
    WT_TRY(wt_wavelet_filter(ctx, order, w->h));
    for (int i = 0; i < 2 * order; i++) w->g[i] = ((i & 1) ? -1.0 : 1.0) * w->h[2 * order - 1 - i];
    for (int i = 0; i < 2 * order; i++) {
        w->h32[i] = (float)w->h[i];
        w->g32[i] = (float)w->g[i];
    }
    *out = w;
    return WT_OK;
fail:
    wt_wavelet_free(w);
    return st;
}

void wt_wavelet_free(wt_wavelet *w)
{
    if (!w) return;
    wt_free(w->ctx, w);
}

int wt_wavelet_n(const wt_wavelet *w) { return w->n; }
int wt_wavelet_levels(const wt_wavelet *w) { return w->levels; }
int wt_wavelet_order(const wt_wavelet *w) { return w->order; }

/* An m x m block (m <= n) for the intermediate of one level, plus two periodically extended half rows
 * of at most n/2 + N − 1 values each. */
size_t wt_wavelet_work_size(const wt_wavelet *w)
{
    return (size_t)w->n * (size_t)w->n + (size_t)w->n + 2 * (size_t)WT_WAVELET_MAX_ORDER;
}

/* ---------------------------------------------------------------------------------------------- */
/* Kernels. Each is written for a tap count known at compile time (always inlined into a switch over */
/* N) so the tap loops unroll and the loops over a row vectorise.                                  */
/* ---------------------------------------------------------------------------------------------- */

#define WT_INLINE static inline __attribute__((always_inline))

/* The kernels in double (wavelet.h's transforms) and in float (the tomography's fp32 operator) */
#define REAL double
#define CREAL double
#define K(name) name##_f64
#define HF(w) (w)->h
#define GF(w) (w)->g
#include "wavelet_kernels.inc"
#undef REAL
#undef CREAL
#undef K
#undef HF
#undef GF
#define REAL float
#define CREAL float
#define K(name) name##_f32
#define HF(w) (w)->h32
#define GF(w) (w)->g32
#include "wavelet_kernels.inc"
#undef CREAL
#undef K
/* the float inverse of double coefficients (wt_wavelet_inverse_f32_of64) */
#define CREAL double
#define K(name) name##_f32c
#define WT_INVERSE_ONLY
#include "wavelet_kernels.inc"
#undef WT_INVERSE_ONLY
#undef REAL
#undef CREAL
#undef K
#undef HF
#undef GF

#define WT_DISPATCH(fn, N, ...)          \
    switch (N) {                         \
    case 1: fn(1, __VA_ARGS__); break;   \
    case 2: fn(2, __VA_ARGS__); break;   \
    case 3: fn(3, __VA_ARGS__); break;   \
    case 4: fn(4, __VA_ARGS__); break;   \
    case 5: fn(5, __VA_ARGS__); break;   \
    case 6: fn(6, __VA_ARGS__); break;   \
    case 7: fn(7, __VA_ARGS__); break;   \
    case 8: fn(8, __VA_ARGS__); break;   \
    case 9: fn(9, __VA_ARGS__); break;   \
    default: fn(10, __VA_ARGS__); break; \
    }

/* The transforms are cloned for AVX2 and AVX-512 (WT_CPU_CLONES, core/base/base.h: the same bits on every
 * CPU). */

WT_CPU_CLONES
void wt_wavelet_forward(const wt_wavelet *w, const double *x, double *c, double *work)
{
    WT_DISPATCH(forward_n_f64, w->order, w, x, c, work);
}

WT_CPU_CLONES
void wt_wavelet_inverse(const wt_wavelet *w, const double *c, double *x, double *work)
{
    WT_DISPATCH(inverse_n_f64, w->order, w, c, x, NULL, work);
}

WT_CPU_CLONES
void wt_wavelet_forward_f32(const wt_wavelet *w, const float *x, float *c, float *work)
{
    WT_DISPATCH(forward_n_f32, w->order, w, x, c, work);
}

WT_CPU_CLONES
void wt_wavelet_inverse_f32(const wt_wavelet *w, const float *c, float *x, float *work)
{
    WT_DISPATCH(inverse_n_f32, w->order, w, c, x, NULL, work);
}

WT_CPU_CLONES
void wt_wavelet_inverse_f32_of64(const wt_wavelet *w, const double *c, float *x, double *x64, float *work)
{
    WT_DISPATCH(inverse_n_f32c, w->order, w, c, x, x64, work);
}

void wt_wavelet_classify(const wt_wavelet *w, int ix, int iy, int *level, int *orient)
{
    /* The finest level whose block [m, 2m) contains ix or iy, m = n/2^l. */
    int m = w->n / 2;
    for (int l = 1; l <= w->levels; l++, m /= 2) {
        if (ix >= m || iy >= m) {
            *level = l;
            *orient = (ix >= m) + 2 * (iy >= m);
            return;
        }
    }
    *level = w->levels + 1;
    *orient = 0;
}
