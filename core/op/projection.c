/* core/op/projection.c: layer projections P by bilinear interpolation, their adjoint and assembly.
 *
 * SPEC §3 and the paper's P^NGS / P^LGS: target point r samples layer ℓ at (1 − h_ℓ/H) r + θ h_ℓ
 * (H = 0: source at infinity, no cone factor). The adjoint is the transposed interpolation (scatter).
 *
 * Why the stencils are stored per target column and per target row rather than per point: the map
 * r ↦ s r + θ h is separable (its x part depends only on the target column ix, its y part only on the
 * row iy), so the bilinear stencil of point (ix, iy) in layer ℓ is the tensor product of a column
 * stencil (base index, two weights) and a row stencil. Storing the factors costs O(L (nx + ny)) instead
 * of O(L · points) and produces bit-for-bit the same weights as per-point precomputation would; the
 * apply loop then reads only the layer values and the target row, with the few KB of tables in L1.
 * Masked target points are stored as runs [lo, hi) per row, so apply never tests a mask. Along a run
 * the stencil columns advance monotonically, which apply_t exploits to write each layer column once
 * per run instead of once per point (the plain scatter chains every update through the previous store;
 * see the loop). The same trick in apply (reuse the y-interpolated column while the stencil stays put)
 * saves loads but adds a data-dependent branch, which wins or loses with the machine's state, so apply
 * keeps the plain gather.
 *
 * Weights are kept as (w0, w1) pairs instead of one fraction f (w0 = 1 − f, w1 = f) so that
 * clamp_outside needs no special path: a stencil corner beyond the grid simply gets weight 0 (the
 * zero-extended layer), with its base index pulled back inside the grid.
 *
 * No OpenMP inside: the tomography calls projections of different sensors from its own parallel
 * region, and a nested team would oversubscribe the cores; one call is too little work for a team of its own.
 */
#include "projection.h"
#include "projection_private.h"

#include <math.h>
#include <stdint.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#define WT_PROJ_SSE2 1
#endif

/* the kernels shared with projection_f32.c, in double */
#define REAL double
#define K(name) name##_f64
#include "projection_kernels.inc"
#undef REAL
#undef K

/* A coordinate within this many cells of the first/last grid line is treated as on it: such a point
 * is on the edge up to rounding of (1 − h/H) r + θh, and the weight it would put outside is < 1e-9. */
#define EDGE_SLACK 1e-9

/* 1-D linear stencil of grid coordinate u (in cells from point 0) on n ≥ 2 points. Returns 1 when
 * both stencil points lie inside the grid. Otherwise returns 0 and, when clamping, keeps only the
 * in-grid corner(s) with base pulled back into [0, n − 2]. */
static int stencil_1d(double u, int n, int clamp, int32_t *base, double *w0, double *w1)
{
    if (u < 0.0 && u > -EDGE_SLACK) u = 0.0;
    if (u > n - 1 && u < n - 1 + EDGE_SLACK) u = n - 1;
    if (u >= 0.0 && u <= n - 1) {
        double fl = floor(u);
        int32_t i0 = (int32_t)fl;
        double f = u - fl;
        if (i0 == n - 1) { /* exactly on the last grid line: the last cell with f = 1 */
            i0 = n - 2;
            f = 1.0;
        }
        *base = i0;
        *w0 = 1.0 - f;
        *w1 = f;
        return 1;
    }
    *base = 0;
    *w0 = *w1 = 0.0;
    if (!clamp) return 0;
    if (u > -1.0 && u < 0.0) { /* corners −1 (outside) and 0 (weight u + 1) */
        *base = 0;
        *w0 = u + 1.0;
    } else if (u > n - 1 && u < n) { /* corners n − 1 (weight n − u) and n (outside) */
        *base = n - 2;
        *w1 = (double)n - u;
    }
    return 0;
}

void wt_projection_free(wt_projection *p)
{
    if (!p) return;
    wt_context *ctx = p->ctx;
    wt_free(ctx, p->lnx);
    wt_free(ctx, p->cbase);
    wt_free(ctx, p->cw0);
    wt_free(ctx, p->cw1);
    wt_free(ctx, p->cw01);
    wt_free(ctx, p->rbase);
    wt_free(ctx, p->rw0);
    wt_free(ctx, p->rw1);
    wt_free(ctx, p->f32);
    wt_projection_f32_free(p);
    wt_free(ctx, p->run_row);
    wt_free(ctx, p->run_lo);
    wt_free(ctx, p->run_hi);
    wt_free(ctx, p->aligned);
    wt_free(ctx, p);
}

static int check_args(wt_context *ctx, int nlayers, const wt_grid *layers, const double *altitudes,
                      double H, double theta_x, double theta_y, const wt_grid *target)
{
    if (nlayers < 1 || !layers || !altitudes || !target)
        return WT_ERROR(ctx, WT_ERR_INVALID, "projection: need nlayers >= 1 (got %d) and non-NULL layers, "
                        "altitudes and target", nlayers);
    if (target->nx < 1 || target->ny < 1 || !(target->dx > 0.0) || !isfinite(target->x0) || !isfinite(target->y0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "projection: target grid %d x %d, spacing %g m, origin (%g, %g) m: "
                        "need at least 1 x 1 points, a positive spacing and a finite origin",
                        target->nx, target->ny, target->dx, target->x0, target->y0);
    if (!(H >= 0.0) || !isfinite(H))
        return WT_ERROR(ctx, WT_ERR_INVALID, "projection: source altitude %g m: need >= 0 (0 = infinity)", H);
    if (!isfinite(theta_x) || !isfinite(theta_y))
        return WT_ERROR(ctx, WT_ERR_INVALID, "projection: direction (%g, %g) rad is not finite", theta_x, theta_y);
    int64_t nin = 0;
    for (int l = 0; l < nlayers; l++) {
        const wt_grid *g = &layers[l];
        if (g->nx < 2 || g->ny < 2 || !(g->dx > 0.0) || !isfinite(g->x0) || !isfinite(g->y0))
            return WT_ERROR(ctx, WT_ERR_INVALID, "projection: layer %d grid %d x %d, spacing %g m, origin (%g, %g) m: "
                            "need at least 2 x 2 points (bilinear), a positive spacing and a finite origin",
                            l, g->nx, g->ny, g->dx, g->x0, g->y0);
        double h = altitudes[l];
        if (!(h >= 0.0) || !isfinite(h) || (H > 0.0 && h >= H))
            return WT_ERROR(ctx, WT_ERR_INVALID, "projection: layer %d altitude %g m: need 0 <= h%s (source at %g m)",
                            l, h, H > 0.0 ? " < H" : "", H);
        nin += wt_grid_size(g);
    }
    if (nin > INT32_MAX || wt_grid_size(target) > INT32_MAX)
        return WT_ERROR(ctx, WT_ERR_INVALID, "projection: %lld layer points or %lld target points exceed the "
                        "32-bit index range", (long long)nin, (long long)wt_grid_size(target));
    return WT_OK;
}

int wt_projection_alloc(wt_context *ctx, int nlayers, const wt_grid *layers, const double *altitudes,
                        double source_altitude, double theta_x, double theta_y, const wt_grid *target,
                        const uint8_t *mask, int clamp_outside, wt_projection **out)
{
    int st = WT_OK;
    wt_projection *p = NULL;
    uint8_t *cok = NULL, *rok = NULL;
    *out = NULL;
    WT_TRY(check_args(ctx, nlayers, layers, altitudes, source_altitude, theta_x, theta_y, target));
    const int tnx = target->nx, tny = target->ny;
    WT_ALLOC(ctx, p, 1, "projection");
    p->ctx = ctx;
    p->nlayers = nlayers;
    p->tnx = tnx;
    p->tny = tny;
    WT_ALLOC(ctx, p->lnx, nlayers, "projection layer sizes");
    WT_ALLOC(ctx, p->cbase, (size_t)nlayers * tnx, "projection column stencils");
    WT_ALLOC(ctx, p->cw0, (size_t)nlayers * tnx, "projection column weights");
    WT_ALLOC(ctx, p->cw1, (size_t)nlayers * tnx, "projection column weights");
    WT_ALLOC(ctx, p->cw01, 2 * (size_t)nlayers * tnx, "projection column weights");
    WT_ALLOC(ctx, p->rbase, (size_t)nlayers * tny, "projection row stencils");
    WT_ALLOC(ctx, p->rw0, (size_t)nlayers * tny, "projection row weights");
    WT_ALLOC(ctx, p->rw1, (size_t)nlayers * tny, "projection row weights");
    WT_ALLOC(ctx, p->aligned, nlayers, "projection layer flags");
    WT_ALLOC(ctx, cok, (size_t)nlayers * tnx, "projection scratch");
    WT_ALLOC(ctx, rok, (size_t)nlayers * tny, "projection scratch");

    /* runs of masked points, row by row */
    int64_t nrun = 0;
    for (int pass = 0; pass < 2; pass++) {
        nrun = 0;
        for (int iy = 0; iy < tny; iy++) {
            const uint8_t *m = mask ? mask + (int64_t)iy * tnx : NULL;
            for (int ix = 0; ix < tnx;) {
                if (m && !m[ix]) {
                    ix++;
                    continue;
                }
                int lo = ix;
                while (ix < tnx && (!m || m[ix])) ix++;
                if (pass == 1) {
                    p->run_row[nrun] = iy;
                    p->run_lo[nrun] = lo;
                    p->run_hi[nrun] = ix;
                }
                nrun++;
            }
        }
        if (pass == 0) {
            p->nrun = (int32_t)nrun;
            WT_ALLOC(ctx, p->run_row, nrun, "projection runs");
            WT_ALLOC(ctx, p->run_lo, nrun, "projection runs");
            WT_ALLOC(ctx, p->run_hi, nrun, "projection runs");
        }
    }

    p->cx0 = tnx;
    p->cx1 = 0;
    for (int64_t r = 0; r < nrun; r++) {
        if (p->run_lo[r] < p->cx0) p->cx0 = p->run_lo[r];
        if (p->run_hi[r] > p->cx1) p->cx1 = p->run_hi[r];
    }
    int64_t offset = 0;
    for (int l = 0; l < nlayers; l++) {
        const wt_grid *g = &layers[l];
        const double h = altitudes[l];
        const double scale = source_altitude > 0.0 ? 1.0 - h / source_altitude : 1.0; /* cone factor */
        p->lnx[l] = g->nx;
        for (int ix = 0; ix < tnx; ix++) {
            double X = scale * (target->x0 + ix * target->dx) + theta_x * h;
            size_t k = (size_t)l * tnx + ix;
            cok[k] = (uint8_t)stencil_1d((X - g->x0) / g->dx, g->nx, clamp_outside, &p->cbase[k], &p->cw0[k], &p->cw1[k]);
        }
        for (int ix = 0; ix < tnx; ix++) {
            size_t k = (size_t)l * tnx + ix;
            p->cw01[2 * k] = p->cw0[k];
            p->cw01[2 * k + 1] = p->cw1[k];
        }
        for (int iy = 0; iy < tny; iy++) {
            double Y = scale * (target->y0 + iy * target->dx) + theta_y * h;
            size_t k = (size_t)l * tny + iy;
            int32_t b;
            rok[k] = (uint8_t)stencil_1d((Y - g->y0) / g->dx, g->ny, clamp_outside, &b, &p->rw0[k], &p->rw1[k]);
            p->rbase[k] = (int32_t)(offset + (int64_t)b * g->nx);
        }
        offset += wt_grid_size(g);
    }
    p->nin = offset;
    {
        const size_t nc = (size_t)nlayers * tnx, nr = (size_t)nlayers * tny;
        WT_ALLOC(ctx, p->f32, 2 * (nc + nr), "projection single-precision weights");
        p->cw0f = p->f32;
        p->cw1f = p->cw0f + nc;
        p->rw0f = p->cw1f + nc;
        p->rw1f = p->rw0f + nr;
        for (size_t k = 0; k < nc; k++) {
            p->cw0f[k] = (float)p->cw0[k];
            p->cw1f[k] = (float)p->cw1[k];
        }
        for (size_t k = 0; k < nr; k++) {
            p->rw0f[k] = (float)p->rw0[k];
            p->rw1f[k] = (float)p->rw1[k];
        }
    }

    for (int l = 0; l < nlayers; l++) {
        int al = 1;
        for (int64_t r = 0; r < nrun && al; r++) {
            const size_t kr = (size_t)l * tny + p->run_row[r];
            if (!(p->rw0[kr] == 1.0 && p->rw1[kr] == 0.0)) al = 0;
            for (int ix = p->run_lo[r]; ix < p->run_hi[r] && al; ix++) {
                const size_t kc = (size_t)l * tnx + ix;
                if (!(p->cw0[kc] == 1.0 && p->cw1[kc] == 0.0) || (ix > p->run_lo[r] && p->cbase[kc] != p->cbase[kc - 1] + 1))
                    al = 0;
            }
        }
        p->aligned[l] = (uint8_t)al;
        p->any_aligned |= al;
    }
    /* the 8-point blocks need long runs: below 16 points a run on average (the NGS models' rims, ~4) most points
     * would take the scalar tail, slower than the two-lane kernel */
    int64_t npts = 0;
    for (int64_t r = 0; r < nrun; r++) npts += p->run_hi[r] - p->run_lo[r];
    p->narrow = npts >= 16 * nrun;
    for (int64_t r = 0; r < nrun && p->narrow; r++)
        for (int l = 0; l < nlayers && p->narrow; l++) {
            if (p->aligned[l]) continue;
            const int32_t *cb = p->cbase + (size_t)l * tnx;
            for (int ix = p->run_lo[r]; ix < p->run_hi[r] && p->narrow; ix++)
                if ((ix + 1 < p->run_hi[r] && cb[ix + 1] < cb[ix]) || (ix + 7 < p->run_hi[r] && cb[ix + 7] - cb[ix] > 6))
                    p->narrow = 0;
        }
    if (!clamp_outside) {
        /* point (ix, iy) is covered iff its column and its row stencils are; report the first one not */
        for (int64_t r = 0; r < nrun; r++) {
            int iy = p->run_row[r];
            for (int l = 0; l < nlayers; l++) {
                for (int ix = p->run_lo[r]; ix < p->run_hi[r]; ix++) {
                    if (cok[(size_t)l * tnx + ix] && rok[(size_t)l * tny + iy]) continue;
                    const wt_grid *g = &layers[l];
                    double h = altitudes[l];
                    double scale = source_altitude > 0.0 ? 1.0 - h / source_altitude : 1.0;
                    double x = target->x0 + ix * target->dx, y = target->y0 + iy * target->dx;
                    st = WT_ERROR(ctx, WT_ERR_INVALID,
                                  "projection: layer %d (altitude %g m) does not cover the footprint: target point "
                                  "(%g, %g) m samples it at (%g, %g) m, outside the layer grid [%g, %g] x [%g, %g] m "
                                  "(source altitude %g m, direction (%g, %g) rad)",
                                  l, h, x, y, scale * x + theta_x * h, scale * y + theta_y * h, g->x0,
                                  g->x0 + (g->nx - 1) * g->dx, g->y0, g->y0 + (g->ny - 1) * g->dx, source_altitude,
                                  theta_x, theta_y);
                    goto fail;
                }
            }
        }
    }
    if (!clamp_outside) WT_TRY(wt_projection_f32_setup(p, layers));
    wt_free(ctx, cok);
    wt_free(ctx, rok);
    *out = p;
    return WT_OK;
fail:
    wt_free(ctx, cok);
    wt_free(ctx, rok);
    wt_projection_free(p);
    return st;
}

int64_t wt_projection_nin(const wt_projection *p) { return p->nin; }
int64_t wt_projection_nout(const wt_projection *p) { return (int64_t)p->tnx * p->tny; }

#if defined(__GNUC__) && !defined(__clang__)
/* GCC vectorises apply's loop with gather instructions, slower than the scalar loop on AMD Zen (a gather
 * is several loads' worth of micro-ops); the scalar loop already issues close to the load/store ports' bound of
 * memory operations per cycle. */
#define WT_SCALAR_LOOPS __attribute__((optimize("no-tree-vectorize")))
#else
#define WT_SCALAR_LOOPS
#endif

/* One run's stencil rows of layers [l0, l0 + nl) (nl ≤ 4): the layer rows r0, r1 (bottom, top) with
 * their weights α rw0, α rw1, and the layers' column tables. */
typedef struct {
    const double *r0[4], *r1[4];
    const int32_t *cb[4];
    const double *w0[4], *w1[4];
    double a0[4], a1[4];
    int al[4]; /* p->aligned of the layer */
} run_rows;

static inline __attribute__((always_inline)) void run_setup(const wt_projection *p, int l0, int nl, int iy, double alpha,
                                                            const double *layers, run_rows *q)
{
    for (int k = 0; k < nl; k++) {
        const int l = l0 + k;
        const size_t kr = (size_t)l * p->tny + iy;
        q->r0[k] = layers + p->rbase[kr];
        q->r1[k] = q->r0[k] + p->lnx[l];
        q->a0[k] = alpha * p->rw0[kr];
        q->a1[k] = alpha * p->rw1[kr];
        q->cb[k] = p->cbase + (size_t)l * p->tnx;
        q->w0[k] = p->cw0 + (size_t)l * p->tnx;
        q->w1[k] = p->cw1 + (size_t)l * p->tnx;
        q->al[k] = p->aligned[l];
    }
}

/* Layer k's term at target point ix: the scalar definition of the apply's arithmetic (unused where the
 * two-lane kernel runs and the AVX-512 one is not built: clang, the fuzz build).
 * An aligned layer's term is a0 r0[j]: with u = (1, 0) and a = (α, 0) the definition is
 * α (r0[j] + 0·r0[j+1]) + 0·(…), which for finite values is α r0[j] exactly unless that is zero, and then a
 * zero whose sign may differ; added to the accumulator it gives the same bits unless the accumulator holds
 * −0 (never, where it starts from a cleared array: a sum that starts at +0 never becomes −0). */
static inline __attribute__((always_inline)) double aligned_term(const run_rows *q, int k, int ix)
{
    return q->a0[k] * q->r0[k][q->cb[k][ix]];
}

static inline __attribute__((always_inline, unused)) double run_term(const run_rows *q, int k, int ix)
{
    if (q->al[k]) return aligned_term(q, k, ix);
    const int32_t j = q->cb[k][ix];
    const double u0 = q->w0[k][ix], u1 = q->w1[k][ix];
    return q->a0[k] * (u0 * q->r0[k][j] + u1 * q->r0[k][j + 1]) + q->a1[k] * (u0 * q->r1[k][j] + u1 * q->r1[k][j + 1]);
}

/* Layers [l0, l0 + NL) of every run, layers innermost: each target point adds its NL terms in layer
 * order, as the layer-by-layer passes would (the same additions in the same order), while its row
 * value stays in a register and the NL layers' independent loads overlap. NL is a compile-time
 * constant at each call (always inlined from the switch below). */
WT_SCALAR_LOOPS static inline __attribute__((always_inline)) void apply_layers(const int NL, const wt_projection *p, int l0,
                                                               double alpha, const double *restrict layers,
                                                               double *restrict points)
{
    const int tnx = p->tnx;
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        double *restrict y = points + (int64_t)iy * tnx;
        run_rows q;
        run_setup(p, l0, NL, iy, alpha, layers, &q);
#ifdef WT_PROJ_SSE2
        /* run_term in two lanes: (w0, w1) times the row pairs (r[j], r[j + 1]) of the bottom and top rows,
         * the two products of each row added across lanes, times (a0, a1), added across lanes: the same
         * IEEE operations on the same operands, half the multiplies */
        const double *w01[4];
        __m128d a01[4];
        for (int k = 0; k < NL; k++) {
            w01[k] = p->cw01 + 2 * ((size_t)(l0 + k) * tnx);
            a01[k] = _mm_set_pd(q.a1[k], q.a0[k]);
        }
        for (int ix = lo; ix < hi; ix++) {
            __m128d acc = _mm_load_sd(y + ix);
            for (int k = 0; k < NL; k++) {
                if (q.al[k]) {
                    acc = _mm_add_sd(acc, _mm_set_sd(aligned_term(&q, k, ix)));
                    continue;
                }
                const int32_t j = q.cb[k][ix];
                const __m128d w = _mm_loadu_pd(w01[k] + 2 * ix);
                const __m128d pb = _mm_mul_pd(w, _mm_loadu_pd(q.r0[k] + j)), pt = _mm_mul_pd(w, _mm_loadu_pd(q.r1[k] + j));
                const __m128d st = _mm_mul_pd(_mm_add_pd(_mm_unpacklo_pd(pb, pt), _mm_unpackhi_pd(pb, pt)), a01[k]);
                acc = _mm_add_sd(acc, _mm_add_sd(st, _mm_unpackhi_pd(st, st)));
            }
            _mm_store_sd(y + ix, acc);
        }
#else
        for (int ix = lo; ix < hi; ix++) {
            double acc = y[ix];
            for (int k = 0; k < NL; k++) acc += run_term(&q, k, ix);
            y[ix] = acc;
        }
#endif
    }
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#include <immintrin.h>
#define WT_PROJ_AVX512 1
/* AVX-512, 8 target points at a time: along a run the stencil columns advance by less than a cell per
 * point wherever the layer is coarser than the target grid (the DMs seen by the evaluation, the 1 m
 * layers seen by the sensors), so 8 points use at most 8 consecutive layer values of each stencil row:
 * one (masked, no read past what the scalar loop reads) load of those, and a lane permutation picks each
 * point's r[j] and r[j + 1]. Per lane the arithmetic is the scalar expression's, in its order, and the
 * layers are added per point in layer order; a block where a layer's columns span more than 6 cells
 * (not met where p->narrow is 0, which keeps the two-lane kernel: the 0.5 m ground layer under the
 * 0.5 m corners, where this one is slower: its blocks span more cells) computes that layer's 8 terms by the scalar expression. */
__attribute__((target("avx512f"))) static void apply_layers_avx512(const wt_projection *p, int l0, int nl, double alpha,
                                                                  const double *restrict layers, double *restrict points)
{
    const int tnx = p->tnx;
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        double *restrict y = points + (int64_t)iy * tnx;
        run_rows q;
        run_setup(p, l0, nl, iy, alpha, layers, &q);
        int ix = lo;
        for (; ix + 8 <= hi; ix += 8) {
            __m512d acc = _mm512_loadu_pd(y + ix);
            for (int k = 0; k < nl; k++) {
                const int32_t J = q.cb[k][ix], span = q.cb[k][ix + 7] - J;
                __m512d term;
                if (q.al[k]) { /* aligned_term, 8 contiguous values */
                    term = _mm512_mul_pd(_mm512_set1_pd(q.a0[k]), _mm512_loadu_pd(q.r0[k] + J));
                } else if (span <= 6) {
                    const __mmask8 m = (__mmask8)((1u << (span + 2)) - 1u);
                    const __m512d b = _mm512_maskz_loadu_pd(m, q.r0[k] + J), t = _mm512_maskz_loadu_pd(m, q.r1[k] + J);
                    const __m256i d32 = _mm256_sub_epi32(_mm256_loadu_si256((const __m256i *)(q.cb[k] + ix)), _mm256_set1_epi32(J));
                    const __m512i d = _mm512_cvtepi32_epi64(d32), d1 = _mm512_add_epi64(d, _mm512_set1_epi64(1));
                    const __m512d u0 = _mm512_loadu_pd(q.w0[k] + ix), u1 = _mm512_loadu_pd(q.w1[k] + ix);
                    const __m512d sb = _mm512_add_pd(_mm512_mul_pd(u0, _mm512_permutexvar_pd(d, b)),
                                                     _mm512_mul_pd(u1, _mm512_permutexvar_pd(d1, b)));
                    const __m512d st = _mm512_add_pd(_mm512_mul_pd(u0, _mm512_permutexvar_pd(d, t)),
                                                     _mm512_mul_pd(u1, _mm512_permutexvar_pd(d1, t)));
                    term = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(q.a0[k]), sb), _mm512_mul_pd(_mm512_set1_pd(q.a1[k]), st));
                } else {
                    double tv[8];
                    for (int e = 0; e < 8; e++) tv[e] = run_term(&q, k, ix + e);
                    term = _mm512_loadu_pd(tv);
                }
                acc = _mm512_add_pd(acc, term);
            }
            _mm512_storeu_pd(y + ix, acc);
        }
        for (; ix < hi; ix++) {
            double acc = y[ix];
            for (int k = 0; k < nl; k++) acc += run_term(&q, k, ix);
            y[ix] = acc;
        }
    }
}
#endif

WT_SCALAR_LOOPS
void wt_projection_apply(const wt_projection *p, double alpha, const double *restrict layers, double *restrict points)
{
#ifdef WT_PROJ_AVX512
    if (p->narrow && __builtin_cpu_supports("avx512f")) {
        for (int l0 = 0; l0 < p->nlayers; l0 += 4)
            apply_layers_avx512(p, l0, p->nlayers - l0 < 4 ? p->nlayers - l0 : 4, alpha, layers, points);
        return;
    }
#endif
    for (int l0 = 0; l0 < p->nlayers;) {
        switch (p->nlayers - l0) {
        case 1: apply_layers(1, p, l0, alpha, layers, points); l0 += 1; break;
        case 2: apply_layers(2, p, l0, alpha, layers, points); l0 += 2; break;
        case 3: apply_layers(3, p, l0, alpha, layers, points); l0 += 3; break;
        default: apply_layers(4, p, l0, alpha, layers, points); l0 += 4; break;
        }
    }
}

/* ---- wt_projection_apply by layer rows (projection.h) ---------------------------------------------------- */

/* layers of the rows pass (its slots live on the stack); more go through wt_projection_apply, the same bits */
#define WT_PROJ_ROWS_MAX 32

int64_t wt_projection_rows_work(const wt_projection *p) { return 2 * (int64_t)p->nlayers * p->tnx; }

/* X[ix] = u0 R[j] + u1 R[j + 1] (j = cbase, u = the column weights) for ix in [cx0, cx1): the bracket of
 * run_term, its operations in its order */
WT_SCALAR_LOOPS static void xrow_plain(const int32_t *restrict cb, const double *restrict w0,
                                       const double *restrict w1, const double *restrict row, int cx0, int cx1,
                                       double *restrict X)
{
    for (int ix = cx0; ix < cx1; ix++) {
        const int32_t j = cb[ix];
        X[ix] = w0[ix] * row[j] + w1[ix] * row[j + 1];
    }
}

#ifdef WT_PROJ_AVX512
/* The same 8 columns at a time where their stencils span at most 6 cells (one masked load of the row and a
 * lane permutation, as apply_layers_avx512 does); elsewhere the scalar expression. */
__attribute__((target("avx512f"))) static void xrow_avx512(const int32_t *restrict cb, const double *restrict w0,
                                                          const double *restrict w1, const double *restrict row,
                                                          int cx0, int cx1, double *restrict X)
{
    int ix = cx0;
    for (; ix + 8 <= cx1; ix += 8) {
        const int32_t J = cb[ix], span = cb[ix + 7] - J;
        if (span >= 0 && span <= 6) {
            const __mmask8 m = (__mmask8)((1u << (span + 2)) - 1u);
            const __m512d b = _mm512_maskz_loadu_pd(m, row + J);
            const __m256i d32 = _mm256_sub_epi32(_mm256_loadu_si256((const __m256i *)(cb + ix)), _mm256_set1_epi32(J));
            const __m512i d = _mm512_cvtepi32_epi64(d32), d1 = _mm512_add_epi64(d, _mm512_set1_epi64(1));
            const __m512d u0 = _mm512_loadu_pd(w0 + ix), u1 = _mm512_loadu_pd(w1 + ix);
            _mm512_storeu_pd(X + ix, _mm512_add_pd(_mm512_mul_pd(u0, _mm512_permutexvar_pd(d, b)),
                                                   _mm512_mul_pd(u1, _mm512_permutexvar_pd(d1, b))));
        } else {
            xrow_plain(cb, w0, w1, row, ix, ix + 8, X);
        }
    }
    xrow_plain(cb, w0, w1, row, ix, cx1, X);
}
#endif

/* The rows pass: per target row, every layer's two X rows brought up to date (the previous target row's
 * often serve: the upper one becomes the lower one), then y += a0 X_R + a1 X_{R+1} per layer along each run
 * (contiguous: the compiler vectorises it, in the AVX-512 build of this function with 512-bit lanes). */
static inline __attribute__((always_inline)) void apply_rows_body(const wt_projection *p, double alpha,
                                                                  const double *restrict layers,
                                                                  double *restrict points, double *restrict work,
                                                                  int accumulate, int avx512)
{
    const int nl = p->nlayers, tnx = p->tnx, tny = p->tny, cx0 = p->cx0, cx1 = p->cx1;
    int64_t key[2 * WT_PROJ_ROWS_MAX];   /* the layer offset of the row X slot (l, s) holds, −1: none */
    double *slot[2 * WT_PROJ_ROWS_MAX];
    for (int l = 0; l < nl; l++)
        for (int s = 0; s < 2; s++) {
            key[2 * l + s] = -1;
            slot[2 * l + s] = work + (size_t)(2 * l + s) * tnx;
        }
    for (int32_t r = 0; r < p->nrun;) {
        const int iy = p->run_row[r];
        int32_t r1 = r;
        while (r1 < p->nrun && p->run_row[r1] == iy) r1++;
        double *X0[WT_PROJ_ROWS_MAX], *X1[WT_PROJ_ROWS_MAX];
        for (int l = 0; l < nl; l++) {
            const int64_t k0 = p->rbase[(size_t)l * tny + iy], k1 = k0 + p->lnx[l];
            int64_t *kk = key + 2 * l;
            double **ss = slot + 2 * l;
            if (kk[1] == k0) { /* the previous upper row is this lower one */
                double *t = ss[0];
                ss[0] = ss[1], ss[1] = t;
                kk[0] = k0, kk[1] = -1;
            }
            const int32_t *cb = p->cbase + (size_t)l * tnx;
            const double *w0 = p->cw0 + (size_t)l * tnx, *w1 = p->cw1 + (size_t)l * tnx;
            for (int s = 0; s < 2; s++) {
                const int64_t want = s ? k1 : k0;
                if (kk[s] == want) continue;
#ifdef WT_PROJ_AVX512
                if (avx512) xrow_avx512(cb, w0, w1, layers + want, cx0, cx1, ss[s]);
                else
#endif
                    xrow_plain(cb, w0, w1, layers + want, cx0, cx1, ss[s]);
                kk[s] = want;
            }
            X0[l] = ss[0];
            X1[l] = ss[1];
        }
        double *restrict y = points + (int64_t)iy * tnx;
        for (; r < r1; r++) {
            const int lo = p->run_lo[r], hi = p->run_hi[r];
            for (int l = 0; l < nl; l++) {
                const size_t kr = (size_t)l * tny + iy;
                const double a0 = alpha * p->rw0[kr], a1 = alpha * p->rw1[kr];
                const double *restrict x0 = X0[l], *restrict x1 = X1[l];
                if (l == 0 && !accumulate) /* 0 + term: what a zeroed y accumulates, signed zeros included */
                    for (int ix = lo; ix < hi; ix++) y[ix] = 0.0 + (a0 * x0[ix] + a1 * x1[ix]);
                else
                    for (int ix = lo; ix < hi; ix++) y[ix] += a0 * x0[ix] + a1 * x1[ix];
            }
        }
    }
    (void)avx512;
}

#ifdef WT_PROJ_AVX512
__attribute__((target("avx512f"))) static void apply_rows_avx512(const wt_projection *p, double alpha,
                                                                const double *restrict layers,
                                                                double *restrict points, double *restrict work,
                                                                int accumulate)
{
    apply_rows_body(p, alpha, layers, points, work, accumulate, 1);
}
#endif

void wt_projection_apply_rows(const wt_projection *p, double alpha, const double *restrict layers,
                              double *restrict points, double *restrict work, int accumulate)
{
    if (p->nlayers > WT_PROJ_ROWS_MAX) {
        if (!accumulate)
            for (int32_t r = 0; r < p->nrun; r++)
                for (int ix = p->run_lo[r]; ix < p->run_hi[r]; ix++) points[(int64_t)p->run_row[r] * p->tnx + ix] = 0.0;
        wt_projection_apply(p, alpha, layers, points);
        return;
    }
#ifdef WT_PROJ_AVX512
    if (__builtin_cpu_supports("avx512f")) {
        apply_rows_avx512(p, alpha, layers, points, work, accumulate);
        return;
    }
#endif
    apply_rows_body(p, alpha, layers, points, work, accumulate, 0);
}

/* apply_t's loop below for an aligned layer (p->aligned): the run's points map one to one onto consecutive layer
 * points, each carried by s0 alone (s0 = 0 + 1·y, the zero-weight sums stay +0), so r0[j] += a0 (0 + y): the same
 * bits, contiguous. The updates of the loop with zero weights (r1 and the column after the run, each += ±0) are
 * left out: they change nothing unless the layer holds −0, which an array cleared to +0 and added to never does. */
WT_CPU_CLONES static void aligned_t(double a0, const double *restrict y, int n, double *restrict r0)
{
    for (int i = 0; i < n; i++) r0[i] += a0 * (0.0 + y[i]);
}

WT_SCALAR_LOOPS
void wt_projection_apply_t(const wt_projection *p, double alpha, const double *restrict points, double *restrict layers)
{
    /* layer by layer (running the layers side by side per point, as apply does, is slower on the E-ELT LGS: the
     * per-layer column state then no longer fits the registers) */
    const int nl = p->nlayers, tnx = p->tnx, tny = p->tny;
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        const double *restrict y = points + (int64_t)iy * tnx;
        for (int l = 0; l < nl; l++) {
            const size_t kr = (size_t)l * tny + iy;
            double *r0 = layers + p->rbase[kr], *r1 = r0 + p->lnx[l];
            const double a0 = alpha * p->rw0[kr], a1 = alpha * p->rw1[kr];
            const int32_t *restrict cb = p->cbase + (size_t)l * tnx;
            if (p->aligned[l]) {
                aligned_t(a0, y + lo, hi - lo, r0 + cb[lo]);
                continue;
            }
            const double *restrict w0 = p->cw0 + (size_t)l * tnx, *restrict w1 = p->cw1 + (size_t)l * tnx;
            t_pairs_f64(cb, w0, w1, y, a0, a1, lo, hi, r0, r1);
        }
    }
}

/* apply_t with the layers side by side (NL ≤ 4 at compile time): each layer's column-pair sums are one
 * dependency chain along the run (two adds per point, each waiting on the last); run one layer after
 * another, a point costs the chain's add latency per layer, side by side the layers' chains overlap. Layer
 * k's updates go to its own part of the layers array in the order of apply_t, hence the same bits. */
WT_SCALAR_LOOPS static inline __attribute__((always_inline)) void apply_t_side(const int NL, const wt_projection *p,
                                                                               double alpha,
                                                                               const double *restrict points,
                                                                               double *restrict layers)
{
    const int tnx = p->tnx, tny = p->tny;
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r], lo = p->run_lo[r], hi = p->run_hi[r];
        const double *restrict y = points + (int64_t)iy * tnx;
        double *r0[4], *r1[4], a0[4], a1[4], s0[4], s1[4];
        const int32_t *cb[4];
        const double *w0[4], *w1[4];
        int32_t jc[4];
        for (int k = 0; k < NL; k++) {
            const size_t kr = (size_t)k * tny + iy;
            r0[k] = layers + p->rbase[kr];
            r1[k] = r0[k] + p->lnx[k];
            a0[k] = alpha * p->rw0[kr];
            a1[k] = alpha * p->rw1[kr];
            cb[k] = p->cbase + (size_t)k * tnx;
            w0[k] = p->cw0 + (size_t)k * tnx;
            w1[k] = p->cw1 + (size_t)k * tnx;
            jc[k] = cb[k][lo];
            s0[k] = s1[k] = 0.0;
        }
        for (int ix = lo; ix < hi; ix++) {
            const double yv = y[ix];
            for (int k = 0; k < NL; k++) {
                const int32_t j = cb[k][ix];
                if (j != jc[k]) {
                    r0[k][jc[k]] += a0[k] * s0[k];
                    r1[k][jc[k]] += a1[k] * s0[k];
                    if (j == jc[k] + 1) {
                        s0[k] = s1[k];
                    } else {
                        r0[k][jc[k] + 1] += a0[k] * s1[k];
                        r1[k][jc[k] + 1] += a1[k] * s1[k];
                        s0[k] = 0.0;
                    }
                    s1[k] = 0.0;
                    jc[k] = j;
                }
                s0[k] += w0[k][ix] * yv;
                s1[k] += w1[k][ix] * yv;
            }
        }
        for (int k = 0; k < NL; k++) {
            r0[k][jc[k]] += a0[k] * s0[k];
            r1[k][jc[k]] += a1[k] * s0[k];
            r0[k][jc[k] + 1] += a0[k] * s1[k];
            r1[k][jc[k] + 1] += a1[k] * s1[k];
        }
    }
}

void wt_projection_apply_t_side(const wt_projection *p, double alpha, const double *restrict points,
                                double *restrict layers)
{
    switch (p->nlayers) {
    case 1: apply_t_side(1, p, alpha, points, layers); break;
    case 2: apply_t_side(2, p, alpha, points, layers); break;
    case 3: apply_t_side(3, p, alpha, points, layers); break;
    case 4: apply_t_side(4, p, alpha, points, layers); break;
    default: wt_projection_apply_t(p, alpha, points, layers); break;
    }
}

int wt_projection_assemble(const wt_projection *p, wt_sparse **out)
{
    int st = WT_OK;
    wt_triplet *t = NULL;
    *out = NULL;
    const int nl = p->nlayers, tnx = p->tnx, tny = p->tny;
    int64_t npts = 0;
    for (int32_t r = 0; r < p->nrun; r++) npts += p->run_hi[r] - p->run_lo[r];
    WT_TRY(wt_triplet_alloc(p->ctx, wt_projection_nout(p), p->nin, 4 * npts * nl, &t));
    for (int32_t r = 0; r < p->nrun; r++) {
        const int iy = p->run_row[r];
        for (int ix = p->run_lo[r]; ix < p->run_hi[r]; ix++) {
            const int64_t row = (int64_t)iy * tnx + ix;
            for (int l = 0; l < nl; l++) {
                const size_t kr = (size_t)l * tny + iy, kc = (size_t)l * tnx + ix;
                const int64_t c00 = (int64_t)p->rbase[kr] + p->cbase[kc], c01 = c00 + p->lnx[l];
                const double wr[2] = {p->rw0[kr], p->rw1[kr]}, wc[2] = {p->cw0[kc], p->cw1[kc]};
                WT_TRY(wt_triplet_add(t, row, c00, wr[0] * wc[0]));
                WT_TRY(wt_triplet_add(t, row, c00 + 1, wr[0] * wc[1]));
                WT_TRY(wt_triplet_add(t, row, c01, wr[1] * wc[0]));
                WT_TRY(wt_triplet_add(t, row, c01 + 1, wr[1] * wc[1]));
            }
        }
    }
    WT_TRY(wt_triplet_compress(t, out));
fail:
    wt_triplet_free(t);
    return st;
}
