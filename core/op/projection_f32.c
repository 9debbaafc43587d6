/* core/op/projection_f32.c: the layer projections P and Pᵀ (SPEC §3, projection.h) in single precision, for the
 * tomography's fp32 operator (recon.<variant>.operator_precision = "fp32", docs/design.md "Single-precision
 * operator"): the same bilinear stencils as projection.c, their weights rounded to float once at alloc.
 *
 * Why a second set of kernels and not the double ones on converted data: the double kernels' speed is set by how
 * many target points an AVX-512 register holds (8) and, for Pᵀ, by the add latency of its per-column running
 * sums; in float a register holds 16 points, and Pᵀ becomes a vector kernel too:
 *   Pᵀ's row pass in 16-point blocks: S0, S1 = inclusive prefix sums of w0 y and w1 y over the block; along a run
 *   the stencil columns d_e = j_e − j_0 are non-decreasing, so layer column k takes
 *       c_k = (S0 at the last point of column k) − (S0 at the last point of column k − 1)
 *           + (S1 at the last point of column k − 1) − (S1 at the last point of column k − 2),
 *   the ends of the columns picked by one compress instruction; the block's columns are kept in a register window
 *   and written out once they are left behind (a store that the next block would load again stalls the
 *   store-to-load forwarding).
 * Accuracy: float's unit roundoff 2^-24 ≈ 6e-8 per operation; a point adds ≤ 4 layers × 4 terms, a layer value the
 * terms of the few target points of its cells: relative errors ~1e-6, far below the noise the tomography weighs.
 */
#include <string.h>

#include "projection.h"
#include "projection_private.h"

/* A GCC-vectorised loop over the stencils would gather, slower than the scalar loop (projection.c) */
#if defined(__GNUC__) && !defined(__clang__)
#define WT_F32_SCALAR __attribute__((optimize("no-tree-vectorize")))
#else
#define WT_F32_SCALAR
#endif

/* One run's stencil rows of one layer in float */
typedef struct {
    const float *r0, *r1;
    const int32_t *cb;
    const float *w0, *w1;
    float a0, a1;
    int al;
} row_f32;

static inline __attribute__((always_inline)) void row_setup(const wt_projection *p, int l, int iy, float alpha,
                                                            const float *layers, row_f32 *q)
{
    const size_t kr = (size_t)l * p->tny + iy;
    q->r0 = layers + p->rbase[kr];
    q->r1 = q->r0 + p->lnx[l];
    q->a0 = alpha * p->rw0f[kr];
    q->a1 = alpha * p->rw1f[kr];
    q->cb = p->cbase + (size_t)l * p->tnx;
    q->w0 = p->cw0f + (size_t)l * p->tnx;
    q->w1 = p->cw1f + (size_t)l * p->tnx;
    q->al = p->aligned[l];
}

static inline __attribute__((always_inline)) float term_f32(const row_f32 *q, int ix)
{
    const int32_t j = q->cb[ix];
    if (q->al) return q->a0 * q->r0[j];
    const float u0 = q->w0[ix], u1 = q->w1[ix];
    return q->a0 * (u0 * q->r0[j] + u1 * q->r0[j + 1]) + q->a1 * (u0 * q->r1[j] + u1 * q->r1[j + 1]);
}

/* Layers in groups of up to 4 per pass over a run, as projection.c's apply_layers (the point's sum in a register) */
enum { GROUP = 4 };

/* Layer by layer (the tomography's projections hold one layer each), so the stencil state stays in registers */
WT_F32_SCALAR static void apply_scalar(const wt_projection *p, float alpha, const float *restrict layers,
                                       float *restrict points)
{
    for (int l = 0; l < p->nlayers; l++)
        for (int32_t r = 0; r < p->nrun; r++) {
            const int iy = p->run_row[r];
            float *restrict y = points + (int64_t)iy * p->tnx;
            row_f32 q;
            row_setup(p, l, iy, alpha, layers, &q);
            const float a0 = q.a0, a1 = q.a1, *restrict r0 = q.r0, *restrict r1 = q.r1;
            const int32_t *restrict cb = q.cb;
            if (q.al) {
                for (int ix = p->run_lo[r]; ix < p->run_hi[r]; ix++) y[ix] += a0 * r0[cb[ix]];
                continue;
            }
            const float *restrict w0 = q.w0, *restrict w1 = q.w1;
            for (int ix = p->run_lo[r]; ix < p->run_hi[r]; ix++) {
                const int32_t j = cb[ix];
                const float u0 = w0[ix], u1 = w1[ix];
                y[ix] += a0 * (u0 * r0[j] + u1 * r0[j + 1]) + a1 * (u0 * r1[j] + u1 * r1[j + 1]);
            }
        }
}

/* One layer's Pᵀ on points [ix, hi) of one run: as projection.c's apply_t, the sums of the current column pair
 * (jc, jc + 1) in registers and a column written once the run has left it (scattering every point would chain each
 * update through the previous store) */
/* The identity stencil's Pᵀ: contiguous, vectorised (scalar, a store and a load 4 KiB apart, as the workspace's
 * page-aligned arrays are, falsely wait on each other: ×8 slower) */
WT_CPU_CLONES static void aligned_run(float a0, const float *restrict y, int n, float *restrict r)
{
    for (int i = 0; i < n; i++) r[i] += a0 * y[i];
}

WT_F32_SCALAR static void scatter_run(const row_f32 *q, float *restrict r0, float *restrict r1, const float *restrict y,
                                      int ix, int hi)
{
    if (ix >= hi) return;
    /* the row's fields in locals: the stores into the layer would otherwise make the compiler reload them */
    const float a0 = q->a0, a1 = q->a1;
    const int32_t *restrict cb = q->cb;
    const float *restrict w0 = q->w0, *restrict w1 = q->w1;
    if (q->al) {
        aligned_run(a0, y + ix, hi - ix, r0 + cb[ix]);
        return;
    }
    int32_t jc = cb[ix];
    float s0 = 0.0f, s1 = 0.0f;
    for (; ix < hi; ix++) {
        const int32_t j = cb[ix];
        if (j != jc) {
            r0[jc] += a0 * s0;
            r1[jc] += a1 * s0;
            if (j == jc + 1) {
                s0 = s1;
            } else {
                r0[jc + 1] += a0 * s1;
                r1[jc + 1] += a1 * s1;
                s0 = 0.0f;
            }
            s1 = 0.0f;
            jc = j;
        }
        s0 += w0[ix] * y[ix];
        s1 += w1[ix] * y[ix];
    }
    r0[jc] += a0 * s0;
    r1[jc] += a1 * s0;
    r0[jc + 1] += a0 * s1;
    r1[jc + 1] += a1 * s1;
}

WT_F32_SCALAR static void apply_t_scalar(const wt_projection *p, float alpha, const float *restrict points,
                                         float *restrict layers)
{
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r];
        const float *y = points + (int64_t)iy * p->tnx;
        for (int l = 0; l < p->nlayers; l++) {
            row_f32 q;
            row_setup(p, l, iy, alpha, layers, &q);
            scatter_run(&q, (float *)q.r0, (float *)q.r1, y, p->run_lo[r], p->run_hi[r]);
        }
    }
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#include <immintrin.h>
#define WT_F32_AVX512 1

/* 16 target points a block, layers [l0, l0 + nl) innermost: along a run a narrow layer's 16 points read at most
 * 16 consecutive values of each stencil row (p->narrow: ≤ 6 cells over 8 points, so ≤ 14 over 16); one masked load
 * of those and a lane permutation give each point its r[j], r[j + 1]. */
__attribute__((target("avx512f"))) static void apply_avx512(const wt_projection *p, int l0, int nl, float alpha,
                                                           const float *restrict layers, float *restrict points)
{
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        float *restrict y = points + (int64_t)iy * p->tnx;
        row_f32 q[GROUP];
        for (int k = 0; k < nl; k++) row_setup(p, l0 + k, iy, alpha, layers, &q[k]);
        for (int ix = lo; ix < hi; ix += 16) {
            const int n = hi - ix < 16 ? hi - ix : 16; /* the run's last block may be short: masked lanes */
            const __mmask16 in = n == 16 ? (__mmask16)0xFFFFu : (__mmask16)((1u << n) - 1u);
            __m512 acc = _mm512_maskz_loadu_ps(in, y + ix);
            for (int k = 0; k < nl; k++) {
                const row_f32 *s = &q[k];
                const int32_t J = s->cb[ix], span = s->cb[ix + n - 1] - J;
                __m512 term;
                if (s->al) {
                    term = _mm512_mul_ps(_mm512_set1_ps(s->a0), _mm512_maskz_loadu_ps(in, s->r0 + J));
                } else if (span <= 14) {
                    const __mmask16 m = (__mmask16)((1u << (span + 2)) - 1u);
                    const __m512 b = _mm512_maskz_loadu_ps(m, s->r0 + J), t = _mm512_maskz_loadu_ps(m, s->r1 + J);
                    /* lanes past the run: column J (in range), weight 0 */
                    const __m512i d = _mm512_maskz_sub_epi32(in, _mm512_maskz_loadu_epi32(in, s->cb + ix), _mm512_set1_epi32(J));
                    const __m512i d1 = _mm512_add_epi32(d, _mm512_set1_epi32(1));
                    const __m512 u0 = _mm512_maskz_loadu_ps(in, s->w0 + ix), u1 = _mm512_maskz_loadu_ps(in, s->w1 + ix);
                    const __m512 sb = _mm512_fmadd_ps(u1, _mm512_permutexvar_ps(d1, b), _mm512_mul_ps(u0, _mm512_permutexvar_ps(d, b)));
                    const __m512 st = _mm512_fmadd_ps(u1, _mm512_permutexvar_ps(d1, t), _mm512_mul_ps(u0, _mm512_permutexvar_ps(d, t)));
                    term = _mm512_fmadd_ps(_mm512_set1_ps(s->a1), st, _mm512_mul_ps(_mm512_set1_ps(s->a0), sb));
                } else {
                    float tv[16] = {0};
                    for (int e = 0; e < n; e++) tv[e] = term_f32(s, ix + e);
                    term = _mm512_loadu_ps(tv);
                }
                acc = _mm512_add_ps(acc, term);
            }
            _mm512_mask_storeu_ps(y + ix, in, acc);
        }
    }
}

/* v shifted up by s lanes (lane e takes v[e − s], zeros below): valignd with a zero vector */
#define SHIFT_UP(v, s) _mm512_castsi512_ps(_mm512_alignr_epi32(_mm512_castps_si512(v), _mm512_setzero_si512(), 16 - (s)))

/* inclusive prefix sum over the 16 lanes */
__attribute__((target("avx512f"))) static inline __m512 prefix16(__m512 v)
{
    v = _mm512_add_ps(v, SHIFT_UP(v, 1));
    v = _mm512_add_ps(v, SHIFT_UP(v, 2));
    v = _mm512_add_ps(v, SHIFT_UP(v, 4));
    return _mm512_add_ps(v, SHIFT_UP(v, 8));
}

/* layer row r += a · win lanes [0, n) (columns c0 …) */
__attribute__((target("avx512f"))) static inline void flush(float *r, int32_t c0, __m512 a, __m512 win, int n)
{
    if (n <= 0) return;
    const __mmask16 m = n >= 16 ? (__mmask16)0xFFFFu : (__mmask16)((1u << n) - 1u);
    _mm512_mask_storeu_ps(r + c0, m, _mm512_fmadd_ps(a, win, _mm512_maskz_loadu_ps(m, r + c0)));
}

/* One layer's Pᵀ on one run [lo, hi) of target row y, by 16-point blocks (the file's comment). The columns' sums
 * are kept in a window of two registers, columns [Jb, Jb + 16) and [Jb + 16, Jb + 32), and the first is written out
 * when the blocks have left it: each 16 columns of a layer row are read and written once per run, at addresses
 * that no other store of the run overlaps (an overlapping earlier store stalls the load behind it). From the first
 * block whose columns span more than 14 cells (none where p->narrow holds) to the run's end: the scalar scatter. */
__attribute__((target("avx512f"))) static void run_t_avx512(const row_f32 *q, float *r0, float *r1, const float *y,
                                                           int lo, int hi)
{
    if (q->al) { /* the identity stencil: contiguous */
        scatter_run(q, r0, r1, y, lo, hi);
        return;
    }
    const __m512i iota = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
    const __m512 A0 = _mm512_set1_ps(q->a0), A1 = _mm512_set1_ps(q->a1);
    __m512 wlo = _mm512_setzero_ps(), whi = _mm512_setzero_ps();
    int32_t Jb = lo < hi ? q->cb[lo] : 0, top = Jb; /* window start; columns [Jb, top) touched */
    int ix = lo;
    for (; ix < hi; ix += 16) {
        const int n = hi - ix < 16 ? hi - ix : 16; /* the run's last block may be short: masked lanes */
        const __mmask16 in = n == 16 ? (__mmask16)0xFFFFu : (__mmask16)((1u << n) - 1u);
        const int32_t J = q->cb[ix], span = q->cb[ix + n - 1] - J;
        if (span > 14) break;
        const __m512 v = _mm512_maskz_loadu_ps(in, y + ix);
        /* lanes past the run: the last point's column (no new column), value 0 */
        const __m512i d = _mm512_mask_blend_epi32(in, _mm512_set1_epi32(span),
                                                  _mm512_sub_epi32(_mm512_maskz_loadu_epi32(in, q->cb + ix), _mm512_set1_epi32(J)));
        /* the last point of each column: d_e ≠ d_{e+1}, and point 15 */
        const __m512i dn = _mm512_permutexvar_epi32(_mm512_min_epi32(_mm512_add_epi32(iota, _mm512_set1_epi32(1)),
                                                                     _mm512_set1_epi32(15)), d);
        const __mmask16 ends = (__mmask16)(_mm512_cmpneq_epi32_mask(d, dn) | 0x8000u);
        /* every column in [J, J + span] has a point where the layer is no finer than the target (p->narrow's ≤ 6
         * cells over 8 points: a step of under one cell per point); else the scalar scatter from here */
        if (__builtin_popcount(ends) != span + 1) break;
        const __m512 S0 = prefix16(_mm512_mul_ps(_mm512_maskz_loadu_ps(in, q->w0 + ix), v));
        const __m512 S1 = prefix16(_mm512_mul_ps(_mm512_maskz_loadu_ps(in, q->w1 + ix), v));
        const __mmask16 have = (__mmask16)((1u << (span + 1)) - 1u);
        const __m512 G0 = _mm512_maskz_compress_ps(ends, S0), G1 = _mm512_maskz_compress_ps(ends, S1);
        const __m512 D0 = _mm512_maskz_sub_ps(have, G0, SHIFT_UP(G0, 1));
        const __m512 D1 = _mm512_maskz_sub_ps(have, G1, SHIFT_UP(G1, 1));
        const __m512 c = _mm512_add_ps(D0, SHIFT_UP(D1, 1)); /* columns J … J + span + 1 */
        const int ncol = span + 2;
        while (J - Jb >= 16) { /* the low register's columns are complete */
            flush(r0, Jb, A0, wlo, top - Jb);
            flush(r1, Jb, A1, wlo, top - Jb);
            wlo = whi;
            whi = _mm512_setzero_ps();
            Jb += 16;
        }
        const int o = J - Jb; /* 0 ≤ o < 16: c's lane e is window column o + e */
        wlo = _mm512_add_ps(wlo, _mm512_maskz_permutexvar_ps((__mmask16)(0xFFFFu << o),
                                                             _mm512_sub_epi32(iota, _mm512_set1_epi32(o)), c));
        if (o > 0)
            whi = _mm512_add_ps(whi, _mm512_maskz_permutexvar_ps((__mmask16)(0xFFFFu >> (16 - o)),
                                                                 _mm512_add_epi32(iota, _mm512_set1_epi32(16 - o)), c));
        if (J + ncol > top) top = J + ncol;
    }
    flush(r0, Jb, A0, wlo, top - Jb);
    flush(r1, Jb, A1, wlo, top - Jb);
    flush(r0, Jb + 16, A0, whi, top - Jb - 16);
    flush(r1, Jb + 16, A1, whi, top - Jb - 16);
    scatter_run(q, r0, r1, y, ix, hi);
}

__attribute__((target("avx512f"))) static void apply_t_avx512(const wt_projection *p, float alpha,
                                                             const float *restrict points, float *restrict layers)
{
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r];
        const float *y = points + (int64_t)iy * p->tnx;
        for (int l = 0; l < p->nlayers; l++) {
            row_f32 q;
            row_setup(p, l, iy, alpha, layers, &q);
            run_t_avx512(&q, (float *)q.r0, (float *)q.r1, y, p->run_lo[r], p->run_hi[r]);
        }
    }
}
#endif

void wt_projection_apply_f32(const wt_projection *p, float alpha, const float *restrict layers, float *restrict points)
{
#ifdef WT_F32_AVX512
    if (p->narrow && __builtin_cpu_supports("avx512f")) {
        for (int l0 = 0; l0 < p->nlayers; l0 += GROUP)
            apply_avx512(p, l0, p->nlayers - l0 < GROUP ? p->nlayers - l0 : GROUP, alpha, layers, points);
        return;
    }
#endif
    apply_scalar(p, alpha, layers, points);
}

void wt_projection_apply_t_f32(const wt_projection *p, float alpha, const float *restrict points, float *restrict layers)
{
#ifdef WT_F32_AVX512
    if (p->narrow && __builtin_cpu_supports("avx512f")) {
        apply_t_avx512(p, alpha, points, layers);
        return;
    }
#endif
    apply_t_scalar(p, alpha, points, layers);
}
