/* core/la/half.c: 16-bit float storage and its GEMV with float32 accumulation (see half.h).
 *
 * The conversions are written with integer operations on the bit patterns (exact, no FPU mode
 * dependence). The GEMV has an AVX2 + F16C + FMA kernel, chosen at run time so that the portable build
 * (no -march=native) still reads 2 bytes per element at full vector width; the scalar kernel serves
 * other CPUs and the tails. */
#include "half.h"

#include <math.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#include <immintrin.h>
#define WT_HALF_X86 1
#endif

const char *wt_prec_name(int prec)
{
    return prec == WT_PREC_F16 ? "fp16" : prec == WT_PREC_BF16 ? "bf16" : "fp32";
}

static uint32_t bits_of(float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

static float float_of(uint32_t u)
{
    float v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static uint16_t bf16_from_float(float v)
{
    uint32_t u = bits_of(v);
    if ((u & 0x7fffffffu) > 0x7f800000u) return (uint16_t)((u >> 16) | 0x0040u); /* NaN stays NaN (quiet) */
    /* round to nearest even on the 16 bits dropped; a carry into the exponent is the right result,
     * up to Inf for the largest values */
    u += 0x7fffu + ((u >> 16) & 1u);
    return (uint16_t)(u >> 16);
}

static uint16_t f16_from_float(float v)
{
    const uint32_t u = bits_of(v);
    const uint16_t sign = (uint16_t)((u >> 16) & 0x8000u);
    const uint32_t a = u & 0x7fffffffu;
    if (a > 0x7f800000u) return (uint16_t)(sign | 0x7e00u); /* NaN */
    if (a >= 0x477ff000u) return (uint16_t)(sign | 0x7c00u); /* ≥ 65520 rounds to Inf (65504 is the largest) */
    if (a < 0x38800000u) {
        /* below 2^-14: an fp16 subnormal m 2^-24 with m = round(|v| 2^24), ties to even */
        if (a < 0x33000000u) return sign; /* ≤ 2^-25: rounds to 0 (2^-25 itself ties to the even 0) */
        const uint32_t e = a >> 23, mant = (a & 0x7fffffu) | 0x800000u; /* |v| = mant 2^(e-150) */
        const uint32_t shift = 126u - e;                                 /* 14..24 bits dropped from mant 2^(e-150+24) */
        uint32_t m = mant >> shift;
        const uint32_t rem = mant & ((1u << shift) - 1u), half = 1u << (shift - 1u);
        if (rem > half || (rem == half && (m & 1u))) m++;
        return (uint16_t)(sign | m); /* m = 1024 is the smallest normal, as it should be */
    }
    /* normal: rebias the exponent (127 -> 15) and round the 13 dropped mantissa bits to nearest even */
    uint32_t r = a - 0x38000000u;
    r += 0xfffu + ((r >> 13) & 1u);
    return (uint16_t)(sign | (r >> 13));
}

uint16_t wt_half_from_float(int prec, float v)
{
    return prec == WT_PREC_BF16 ? bf16_from_float(v) : f16_from_float(v);
}

static float f16_to_float(uint16_t h)
{
    const uint32_t sign = (uint32_t)(h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
    if (e == 0x1fu) return float_of(sign | 0x7f800000u | (m << 13)); /* Inf, NaN */
    if (e == 0) {
        /* subnormal or zero: m 2^-24, exact in float32 */
        const float v = (float)m * 0x1p-24f;
        return sign ? -v : v;
    }
    return float_of(sign | ((e + 112u) << 23) | (m << 13));
}

float wt_half_to_float(int prec, uint16_t h)
{
    return prec == WT_PREC_BF16 ? float_of((uint32_t)h << 16) : f16_to_float(h);
}

int wt_half_is_nonfinite(int prec, uint16_t h)
{
    return prec == WT_PREC_BF16 ? (h & 0x7f80u) == 0x7f80u : (h & 0x7c00u) == 0x7c00u;
}

void wt_half_pack(int prec, int64_t rows, int64_t cols, const float *A, uint16_t *H, float *c, int nthreads)
{
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1)
    for (int64_t i = 0; i < rows; i++) {
        const float *a = A + i * cols;
        uint16_t *h = H + i * cols;
        float amax = 0.0f;
        for (int64_t j = 0; j < cols; j++) amax = fmaxf(amax, fabsf(a[j]));
        int k = 0;
        if (amax > 0.0f) {
            (void)frexpf(amax, &k); /* amax = f 2^k, f in [0.5, 1) */
            k -= 15;                /* amax / 2^k in [2^14, 2^15) */
        }
        const float ci = ldexpf(1.0f, k), inv = ldexpf(1.0f, -k);
        c[i] = ci;
        for (int64_t j = 0; j < cols; j++) h[j] = wt_half_from_float(prec, a[j] * inv); /* exact scaling */
    }
}

/* Σ_j H_j x_j over n elements, in 32 float32 lanes (element j in lane j mod 32), then the lanes summed
 * in a fixed order. */
static float dot_scalar(int prec, int64_t n, const uint16_t *h, const float *x)
{
    float lane[32] = {0};
    int64_t j = 0;
    for (; j + 32 <= n; j += 32)
        for (int l = 0; l < 32; l++) lane[l] += wt_half_to_float(prec, h[j + l]) * x[j + l];
    for (int l = 0; j < n; j++, l++) lane[l] += wt_half_to_float(prec, h[j]) * x[j];
    float s = 0.0f;
    for (int l = 0; l < 32; l++) s += lane[l];
    return s;
}

#ifdef WT_HALF_X86
__attribute__((target("avx2,fma,f16c"))) static inline __m256 load8(int prec, const uint16_t *h)
{
    const __m128i v = _mm_loadu_si128((const __m128i *)(const void *)h);
    if (prec == WT_PREC_BF16) return _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_cvtepu16_epi32(v), 16));
    return _mm256_cvtph_ps(v);
}

__attribute__((target("avx2,fma,f16c"))) static float dot_avx2(int prec, int64_t n, const uint16_t *h, const float *x)
{
    __m256 s0 = _mm256_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
    int64_t j = 0;
    for (; j + 32 <= n; j += 32) {
        s0 = _mm256_fmadd_ps(load8(prec, h + j), _mm256_loadu_ps(x + j), s0);
        s1 = _mm256_fmadd_ps(load8(prec, h + j + 8), _mm256_loadu_ps(x + j + 8), s1);
        s2 = _mm256_fmadd_ps(load8(prec, h + j + 16), _mm256_loadu_ps(x + j + 16), s2);
        s3 = _mm256_fmadd_ps(load8(prec, h + j + 24), _mm256_loadu_ps(x + j + 24), s3);
    }
    float lane[32];
    _mm256_storeu_ps(lane, s0);
    _mm256_storeu_ps(lane + 8, s1);
    _mm256_storeu_ps(lane + 16, s2);
    _mm256_storeu_ps(lane + 24, s3);
    for (int l = 0; j < n; j++, l++) lane[l] += wt_half_to_float(prec, h[j]) * x[j];
    float s = 0.0f;
    for (int l = 0; l < 32; l++) s += lane[l];
    return s;
}

/* Four rows at once, the same 32 lanes per row as dot_avx2 (two accumulators of 8 per row, each taking
 * two of the four 8-element slices of a 32-element block, in the same order): why — one row at a time
 * is one memory stream per core, which the hardware prefetcher keeps at ~9 GB/s on the EPYC host (the
 * 16-bit GEMV read 18.7 GB/s on 2 cores against 30 GB/s for OpenBLAS's fp32 sgemv, which walks several
 * rows together); four rows are four streams, and each x slice loaded serves four rows. */
__attribute__((target("avx2,fma,f16c"))) static inline void dot4_avx2(int prec, int64_t n, const uint16_t *h,
                                                                      int64_t ld, const float *x, float *out)
{
    const uint16_t *h0 = h, *h1 = h + ld, *h2 = h + 2 * ld, *h3 = h + 3 * ld;
    __m256 a0 = _mm256_setzero_ps(), b0 = a0, a1 = a0, b1 = a0, a2 = a0, b2 = a0, a3 = a0, b3 = a0;
    __m256 c0 = a0, d0 = a0, c1 = a0, d1 = a0, c2 = a0, d2 = a0, c3 = a0, d3 = a0;
    int64_t j = 0;
    for (; j + 32 <= n; j += 32) {
        const __m256 x0 = _mm256_loadu_ps(x + j), x1 = _mm256_loadu_ps(x + j + 8);
        a0 = _mm256_fmadd_ps(load8(prec, h0 + j), x0, a0);
        a1 = _mm256_fmadd_ps(load8(prec, h1 + j), x0, a1);
        a2 = _mm256_fmadd_ps(load8(prec, h2 + j), x0, a2);
        a3 = _mm256_fmadd_ps(load8(prec, h3 + j), x0, a3);
        b0 = _mm256_fmadd_ps(load8(prec, h0 + j + 8), x1, b0);
        b1 = _mm256_fmadd_ps(load8(prec, h1 + j + 8), x1, b1);
        b2 = _mm256_fmadd_ps(load8(prec, h2 + j + 8), x1, b2);
        b3 = _mm256_fmadd_ps(load8(prec, h3 + j + 8), x1, b3);
        const __m256 x2 = _mm256_loadu_ps(x + j + 16), x3 = _mm256_loadu_ps(x + j + 24);
        c0 = _mm256_fmadd_ps(load8(prec, h0 + j + 16), x2, c0);
        c1 = _mm256_fmadd_ps(load8(prec, h1 + j + 16), x2, c1);
        c2 = _mm256_fmadd_ps(load8(prec, h2 + j + 16), x2, c2);
        c3 = _mm256_fmadd_ps(load8(prec, h3 + j + 16), x2, c3);
        d0 = _mm256_fmadd_ps(load8(prec, h0 + j + 24), x3, d0);
        d1 = _mm256_fmadd_ps(load8(prec, h1 + j + 24), x3, d1);
        d2 = _mm256_fmadd_ps(load8(prec, h2 + j + 24), x3, d2);
        d3 = _mm256_fmadd_ps(load8(prec, h3 + j + 24), x3, d3);
    }
    const __m256 acc[4][4] = {{a0, b0, c0, d0}, {a1, b1, c1, d1}, {a2, b2, c2, d2}, {a3, b3, c3, d3}};
    const uint16_t *rows[4] = {h0, h1, h2, h3};
    for (int r = 0; r < 4; r++) {
        float lane[32];
        for (int q = 0; q < 4; q++) _mm256_storeu_ps(lane + 8 * q, acc[r][q]);
        for (int64_t k = j, l = 0; k < n; k++, l++) lane[l] += wt_half_to_float(prec, rows[r][k]) * x[k];
        float s = 0.0f;
        for (int l = 0; l < 32; l++) s += lane[l];
        out[r] = s;
    }
}

__attribute__((target("avx2,fma,f16c"))) static void rows_avx2(int prec, int64_t r0, int64_t r1, int64_t cols,
                                                               const uint16_t *H, const float *x, float *d)
{
    int64_t i = r0;
    if (prec == WT_PREC_BF16)
        for (; i + 4 <= r1; i += 4) dot4_avx2(WT_PREC_BF16, cols, H + i * cols, cols, x, d + (i - r0));
    else
        for (; i + 4 <= r1; i += 4) dot4_avx2(WT_PREC_F16, cols, H + i * cols, cols, x, d + (i - r0));
    for (; i < r1; i++) d[i - r0] = dot_avx2(prec, cols, H + i * cols, x);
}

static int have_avx2(void)
{
    /* F16C from CPUID leaf 1 (ECX bit 29): clang's __builtin_cpu_supports does not know "f16c" */
    unsigned a, b, c, d;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __get_cpuid(1, &a, &b, &c, &d) &&
           (c & (1u << 29));
}
#endif

void wt_half_gemv(int prec, int64_t rows, int64_t cols, const uint16_t *H, const float *c, const float *x, float beta,
                  float *y, int nthreads)
{
    int fast = 0;
#ifdef WT_HALF_X86
    fast = have_avx2();
#endif
    /* blocks of rows: the fast kernel takes four at a time; static schedule, so each thread walks one
     * contiguous part of H */
    enum { BLOCK = 64 };
    const int64_t nblocks = (rows + BLOCK - 1) / BLOCK;
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1)
    for (int64_t b = 0; b < nblocks; b++) {
        const int64_t r0 = b * BLOCK, r1 = r0 + BLOCK < rows ? r0 + BLOCK : rows;
        float d[BLOCK];
#ifdef WT_HALF_X86
        if (fast)
            rows_avx2(prec, r0, r1, cols, H, x, d);
        else
#endif
            for (int64_t i = r0; i < r1; i++) d[i - r0] = dot_scalar(prec, cols, H + i * cols, x);
        for (int64_t i = r0; i < r1; i++) y[i] = (beta == 0.0f ? 0.0f : beta * y[i]) + c[i] * d[i - r0];
    }
}
