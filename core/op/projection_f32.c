/* core/op/projection_f32.c: the layer projections P and Pᵀ (SPEC §3, projection.h) in single precision, for the
 * tomography's fp32 operator (recon.<variant>.operator_precision = "fp32", docs/design.md "Single-precision
 * operator"): the same bilinear stencils as projection.c, their weights rounded to float once at alloc.
 *
 * Why a second set of kernels and not the double ones on converted data: the double kernels' speed is set by how
 * many target points an AVX-512 register holds (8) and, for Pᵀ, by the add latency of its per-column running
 * sums. In float P takes 16 points a block; Pᵀ is rebuilt as two passes (the tables' comment below,
 * wt_projection_f32_free): the target rows into their layer rows by contiguous vector adds, then one fixed 1-D
 * transposed interpolation along x per layer row, a few lane permutes per 16 columns (a 16-point in-block prefix-sum
 * form gains less: its lane moves bound it). Short runs (the NGS models' rims, a lit-area model's subaperture edges) keep scalar loops: Pᵀ as fast
 * as the double one there, P slower than its two-lane form (the NGS are 3 of 9 sensors and a fifth of the work).
 * Accuracy: float's unit roundoff 2^-24 ≈ 6e-8 per operation; a point adds ≤ 4 layers × 4 terms, a layer value the
 * terms of the few target points of its cells: relative errors ~1e-6, far below the noise the tomography weighs.
 */
#include <string.h>

#include "projection.h"
#include "projection_private.h"

/* the kernels shared with projection.c, in float */
#define REAL float
#define K(name) name##_f32
#include "projection_kernels.inc"
#undef REAL
#undef K

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

/* The identity stencil's Pᵀ: contiguous, vectorised (scalar, a store and a load 4 KiB apart, as the workspace's
 * page-aligned arrays are, falsely wait on each other: 4K aliasing) */
WT_CPU_CLONES static void aligned_run(float a0, const float *restrict y, int n, float *restrict r)
{
    for (int i = 0; i < n; i++) r[i] += a0 * y[i];
}

/* One layer's Pᵀ on points [ix, hi) of one run: the identity stencil's contiguous form, or projection.c's column
 * pairs (projection_kernels.inc) */
static inline __attribute__((always_inline)) void scatter_run(const row_f32 *q, float *restrict r0, float *restrict r1,
                                                              const float *restrict y, int ix, int hi)
{
    if (ix >= hi) return;
    /* the row's fields in locals: the stores into the layer would otherwise make the compiler reload them */
    const float a0 = q->a0, a1 = q->a1;
    const int32_t *restrict cb = q->cb;
    const float *restrict w0 = q->w0, *restrict w1 = q->w1;
    if (q->al) { /* (a short run's own loop: the clone's dispatch costs more than its few points) */
        if (hi - ix >= 16) aligned_run(a0, y + ix, hi - ix, r0 + cb[ix]);
        else
            for (float *restrict r = r0 + cb[ix] - ix; ix < hi; ix++) r[ix] += a0 * y[ix];
        return;
    }
    t_pairs_f32(cb, w0, w1, y, a0, a1, ix, hi, r0, r1);
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

/* The transpose's tables (wt_proj_t32, projection_private.h). Pᵀ is separable like P: a target row's values go to
 * its two stencil rows with the row weights (contiguous vector adds into U, one row per layer row), then each U row
 * goes to its layer row through the 1-D transposed interpolation along x, which is the same for every row and so a
 * fixed table: layer column j takes the points whose column stencil is (j, j + 1) with weight w0, and those whose
 * stencil is (j − 1, j) with w1, at most K of them (2–3 each where the layer is twice the target's spacing).
 * Half as many U rows as target rows pass the 1-D step, and the step is K permutes of three registers of U per 16
 * columns instead of the prefix sums' dozens of lane moves per 16 points. */
enum { T32_UMAX = 16384, T32_KMAX = 8 }; /* U on the stack (64 KB), entries per column */

void wt_projection_f32_free(wt_projection *p)
{
    if (!p->t32) return;
    for (int l = 0; l < p->nlayers; l++) {
        wt_free(p->ctx, p->t32[l].urow);
        wt_free(p->ctx, p->t32[l].base);
        wt_free(p->ctx, p->t32[l].idx);
        wt_free(p->ctx, p->t32[l].hi);
        wt_free(p->ctx, p->t32[l].wt);
    }
    wt_free(p->ctx, p->t32);
    p->t32 = NULL;
}

static int t32_layer(wt_projection *p, int l, int64_t loff, wt_proj_t32 *T)
{
    int st = WT_OK;
    const int tnx = p->tnx, tny = p->tny, cx0 = p->cx0, cx1 = p->cx1, lnx = p->lnx[l];
    const int32_t *cb = p->cbase + (size_t)l * tnx;
    const float *w0 = p->cw0f + (size_t)l * tnx, *w1 = p->cw1f + (size_t)l * tnx;
    if (p->aligned[l] || cx1 <= cx0) return WT_OK; /* (the identity's transpose is a contiguous add) */
    for (int ix = cx0 + 1; ix < cx1; ix++)
        if (cb[ix] < cb[ix - 1]) return WT_OK; /* not monotone: no table */
    /* U rows: the stencil rows of every run's target row */
    int32_t rmin = INT32_MAX, rmax = -1;
    for (int32_t r = 0; r < p->nrun; r++) {
        const int32_t row = (int32_t)((p->rbase[(size_t)l * tny + p->run_row[r]] - loff) / lnx);
        rmin = row < rmin ? row : rmin;
        rmax = row + 1 > rmax ? row + 1 : rmax;
    }
    T->loff = loff;
    T->r_lo = rmin;
    T->nrow = rmax - rmin + 1;
    T->ustride = ((cx1 - cx0) + 48 + 15) / 16 * 16; /* a block reads 48 values from its base */
    if ((int64_t)T->nrow * T->ustride > T32_UMAX) return WT_OK;
    T->c0 = cb[cx0];
    T->ncol = cb[cx1 - 1] + 2 - T->c0;
    T->nblk = (T->ncol + 15) / 16;
    /* K: the most entries of a column */
    int K = 0;
    for (int j = 0; j < T->ncol; j++) {
        int k = 0;
        for (int ix = cx0; ix < cx1; ix++) k += cb[ix] - T->c0 == j || cb[ix] - T->c0 == j - 1;
        K = k > K ? k : K;
    }
    if (K > T32_KMAX) return WT_OK;
    T->K = K;
    WT_ALLOC(p->ctx, T->urow, tny, "projection fp32 transpose rows");
    WT_ALLOC(p->ctx, T->base, T->nblk, "projection fp32 transpose table");
    WT_ALLOC(p->ctx, T->idx, (size_t)T->nblk * K * 16, "projection fp32 transpose table");
    WT_ALLOC(p->ctx, T->hi, (size_t)T->nblk * K, "projection fp32 transpose table");
    WT_ALLOC(p->ctx, T->wt, (size_t)T->nblk * K * 16, "projection fp32 transpose table");
    for (int iy = 0; iy < tny; iy++)
        T->urow[iy] = (int32_t)((p->rbase[(size_t)l * tny + iy] - loff) / lnx) - T->r_lo;
    for (int b = 0; b < T->nblk; b++) {
        /* the block's first entry: the first point of column c0 + 16 b − 1 (or of c0 + 16 b) */
        int first = cx1;
        for (int ix = cx0; ix < cx1; ix++)
            if (cb[ix] - T->c0 >= 16 * b - 1) {
                first = ix;
                break;
            }
        T->base[b] = first - cx0;
        for (int e = 0; e < 16; e++) {
            const int j = 16 * b + e;
            int k = 0;
            for (int ix = cx0; ix < cx1 && j < T->ncol; ix++) {
                const int d = cb[ix] - T->c0;
                if (d != j && d != j - 1) continue;
                const int rel = ix - first;
                if (rel < 0 || rel >= 48) { /* beyond three registers: no table */
                    T->ok = 0;
                    return WT_OK;
                }
                const size_t q = ((size_t)b * K + k) * 16 + e;
                T->idx[q] = rel;
                T->wt[q] = d == j ? w0[ix] : w1[ix];
                if (rel >= 32) T->hi[(size_t)b * K + k] |= (uint16_t)(1u << e);
                k++;
            }
            /* padding: weight 0 on the block's first value (idx 0, wt 0 from the allocation's zeros) */
        }
    }
    T->ok = 1;
    return WT_OK;
fail:
    return st;
}

int wt_projection_f32_setup(wt_projection *p, const wt_grid *layers)
{
    int st = WT_OK;
    WT_ALLOC(p->ctx, p->t32, p->nlayers, "projection fp32 transpose tables");
    int64_t loff = 0;
    for (int l = 0; l < p->nlayers; l++) {
        WT_TRY(t32_layer(p, l, loff, &p->t32[l]));
        loff += wt_grid_size(&layers[l]);
    }
    return WT_OK;
fail:
    wt_projection_f32_free(p);
    return st;
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

/* One layer's Pᵀ through its tables (wt_proj_t32; the comment above wt_projection_f32_free) */
__attribute__((target("avx512f"))) static void layer_t_u(const wt_projection *p, int l, float alpha,
                                                        const float *restrict points, float *restrict layers)
{
    const wt_proj_t32 *T = &p->t32[l];
    const int tnx = p->tnx, cx0 = p->cx0, lnx = p->lnx[l];
    float U[T32_UMAX] __attribute__((aligned(64)));
    memset(U, 0, (size_t)T->nrow * T->ustride * sizeof *U);
    /* the target rows into U: u0 += α rw0 y, u1 += α rw1 y along each run */
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        const size_t kr = (size_t)l * p->tny + iy;
        const __m512 A0 = _mm512_set1_ps(alpha * p->rw0f[kr]), A1 = _mm512_set1_ps(alpha * p->rw1f[kr]);
        float *u0 = U + (size_t)T->urow[iy] * T->ustride - cx0, *u1 = u0 + T->ustride;
        const float *y = points + (int64_t)iy * tnx;
        for (int ix = lo; ix < hi; ix += 16) {
            const __mmask16 in = hi - ix >= 16 ? (__mmask16)0xFFFFu : (__mmask16)((1u << (hi - ix)) - 1u);
            const __m512 v = _mm512_maskz_loadu_ps(in, y + ix);
            _mm512_mask_storeu_ps(u0 + ix, in, _mm512_fmadd_ps(A0, v, _mm512_maskz_loadu_ps(in, u0 + ix)));
            _mm512_mask_storeu_ps(u1 + ix, in, _mm512_fmadd_ps(A1, v, _mm512_maskz_loadu_ps(in, u1 + ix)));
        }
    }
    /* each U row into its layer row along x */
    const int K = T->K;
    for (int R = 0; R < T->nrow; R++) {
        const float *u = U + (size_t)R * T->ustride;
        float *row = layers + T->loff + (int64_t)(T->r_lo + R) * lnx + T->c0;
        for (int b = 0; b < T->nblk; b++) {
            const float *src = u + T->base[b];
            const __m512 Y0 = _mm512_loadu_ps(src), Y1 = _mm512_loadu_ps(src + 16), Y2 = _mm512_loadu_ps(src + 32);
            __m512 acc = _mm512_setzero_ps();
            const int32_t *ib = T->idx + (size_t)b * K * 16;
            const float *wb = T->wt + (size_t)b * K * 16;
            for (int k = 0; k < K; k++) {
                const __m512i id = _mm512_loadu_si512((const void *)(ib + 16 * k));
                __m512 v = _mm512_permutex2var_ps(Y0, id, Y1);
                v = _mm512_mask_permutexvar_ps(v, T->hi[(size_t)b * K + k], id, Y2);
                acc = _mm512_fmadd_ps(_mm512_loadu_ps(wb + 16 * k), v, acc);
            }
            const int nc = T->ncol - 16 * b;
            const __mmask16 m = nc >= 16 ? (__mmask16)0xFFFFu : (__mmask16)((1u << nc) - 1u);
            _mm512_mask_storeu_ps(row + 16 * b, m, _mm512_add_ps(_mm512_maskz_loadu_ps(m, row + 16 * b), acc));
        }
    }
}

/* Layer by layer: the tables where they exist and the runs are long (p->narrow), else the scalar scatter */
__attribute__((target("avx512f"))) static void apply_t_avx512(const wt_projection *p, float alpha,
                                                             const float *restrict points, float *restrict layers)
{
    if (!p->narrow) { /* short runs (the NGS models' rims, the lit sensors' subaperture edges): per run, the layers */
        apply_t_scalar(p, alpha, points, layers);
        return;
    }
    for (int l = 0; l < p->nlayers; l++) {
        if (p->t32 && p->t32[l].ok) {
            layer_t_u(p, l, alpha, points, layers);
            continue;
        }
        for (int32_t r = 0; r < p->nrun; r++) {
            const int iy = p->run_row[r];
            row_f32 q;
            row_setup(p, l, iy, alpha, layers, &q);
            scatter_run(&q, (float *)q.r0, (float *)q.r1, points + (int64_t)iy * p->tnx, p->run_lo[r], p->run_hi[r]);
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
    if (__builtin_cpu_supports("avx512f")) {
        apply_t_avx512(p, alpha, points, layers);
        return;
    }
#endif
    apply_t_scalar(p, alpha, points, layers);
}
