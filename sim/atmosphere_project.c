/* sim/atmosphere_project.c: the line-of-sight OPD of the frozen-flow screens (atmosphere.c).
 *
 * SPEC §2 (frozen flow, bilinear interpolation with periodic wrap) and §3 (the cone factor and the shift of paper
 * eqs. P^NGS, P^LGS): a target point r seen from a source at altitude H (0: infinity) in direction θ samples
 * layer ℓ at time t at
 *
 *   c r + θ h_ℓ − v_ℓ t − s_ℓ,   c = 1 − h_ℓ / H,
 *
 * the periodic screen bilinearly interpolated plus the subharmonic field evaluated exactly there, added layer by
 * layer in layer order (scaled by the layer's drift factor: wt_atmosphere_set_drift). A reference kernel that
 * defines every bit point by point, a fast one with the same arithmetic per block of points, and a batch of lines
 * of sight that reads each band of screen rows once. */
#include "atmosphere_private.h"

#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#else
static inline int omp_in_parallel(void) { return 0; }
#endif


/* u mod n in [0, n). fmod is exact, where u − n floor(u / n) loses the result for |u| ≫ n and then
 * indexes outside the screen (a wind of 1e22 m/s); a non-finite u maps to 0. */
static inline double wrap(double u, int n)
{
    u = fmod(u, n);
    if (u < 0.0) u += n;
    return u >= 0.0 && u < n ? u : 0.0; /* u = −tiny rounds up to n; NaN */
}

/* What every target row shares for one layer in one call. */
typedef struct layer_call {
    const atm_layer *ly;
    double c;      /* cone factor 1 − h/H */
    double ax, ay; /* θh − v t [m]: the sample point is c r + (ax, ay) */
    double b;      /* screen cells per target step */
    const sh_step *q; /* subharmonic rotations for the step c dx */
} layer_call;

/* Everything but q, which the caller points at wt_atmosphere__sh_step_init(…, c dx) (shared by the layer calls with
 * the same cone factor in a batch). */
static void layer_call_init(const wt_atmosphere *atm, int l, double t, double H, double thx, double thy,
                            const wt_grid *tg, layer_call *lc)
{
    const atm_layer *ly = &atm->layers[l];
    lc->ly = ly;
    lc->c = H > 0.0 ? 1.0 - ly->altitude / H : 1.0;
    lc->ax = thx * ly->altitude - ly->vx * t - ly->sx;
    lc->ay = thy * ly->altitude - ly->vy * t - ly->sy;
    lc->b = lc->c * tg->dx / atm->delta;
    lc->q = NULL;
}

static void layer_call_step(const wt_atmosphere *atm, const wt_grid *tg, double c, sh_step *q)
{
    if (atm->sh_levels) wt_atmosphere__sh_step_init(atm->sh_levels, 1.0 / (atm->n * atm->delta), c * tg->dx, q);
}

/* The masked points of one target row: the span [lo, hi] the kernels sample (the whole row without a
 * mask) and the masked points per block of SH_CHUNK from lo. It depends on the mask only, so a batch
 * computes it once per (mask, row) for all layers and lines of sight (span_memo). */
#define SPAN_BLOCKS 64
typedef struct row_span {
    int lo, hi;               /* lo > hi: no masked point */
    int nb;                   /* blocks counted in cnt (0: more than SPAN_BLOCKS; the kernel counts) */
    const uint8_t *mk;        /* the row's mask (NULL: all points) */
    uint8_t cnt[SPAN_BLOCKS]; /* masked points of block (k − lo) / SH_CHUNK */
} row_span;

static void row_span_init(const uint8_t *mask, int nx, int iy, row_span *sp)
{
    const uint8_t *mk = mask ? mask + (int64_t)iy * nx : NULL;
    int lo = 0, hi = nx - 1;
    sp->mk = mk, sp->nb = 0;
    if (mk) {
        while (lo < nx && !mk[lo]) lo++;
        while (hi >= lo && !mk[hi]) hi--;
        const int nb = hi < lo ? 0 : (hi - lo) / SH_CHUNK + 1;
        if (nb <= SPAN_BLOCKS) {
            sp->nb = nb;
            for (int bk = 0; bk < nb; bk++) {
                const int k0 = lo + bk * SH_CHUNK, m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
                int cnt = 0;
                for (int k = 0; k < m; k++) cnt += mk[k0 + k] != 0;
                sp->cnt[bk] = (uint8_t)cnt;
            }
        }
    }
    sp->lo = lo, sp->hi = hi;
}

/* What one (layer, target row) shares between the lines of sight of a batch: the y part of a row start
 * (the screen row position w and the subharmonic g0, G_p) depends on the layer and py only, the x part
 * (the position u0 and E_p) on px0 only. They are looked up by the bits of py and px0 (the same
 * arguments give the same fmod and libm results, so sharing is exact). The E-ELT's 25 evaluation
 * directions on a 5 x 5 grid have 5 distinct py and 5 distinct px0 per row and layer: 10 sets of 3
 * sincos and one fmod instead of 50. When full, the next ones are computed without sharing. */
#define ROW_MEMO 16
typedef struct row_memo {
    int ny, nx;
    uint64_t ykey[ROW_MEMO], xkey[ROW_MEMO];
    double w[ROW_MEMO], u0[ROW_MEMO];
    sh_row y[ROW_MEMO], x[ROW_MEMO]; /* y: g0, gr, gi; x: er, ei */
} row_memo;

static inline uint64_t dbits(double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

/* What both row kernels start from: the row's span, the unwrapped screen position u0 of point lo along
 * x, the screen rows r0, r1 (index j, j1 = j + 1 mod n) and weight fy along y, and the subharmonic row
 * state. */
typedef struct row_start {
    int lo, hi, j1;
    const uint8_t *mk; /* the row's mask (NULL: all points) */
    double *o;         /* the row's output */
    double u0, fy;
    const double *r0, *r1;
    sh_row s;
} row_start;

/* 0: the row has no masked point. mm: the memo of this (layer, row), or NULL. */
static inline int row_start_init(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg,
                                 const row_span *sp, double *out, int iy, row_memo *mm, row_start *r)
{
    if (sp->lo > sp->hi) return 0;
    const int n = atm->n, lo = sp->lo, levels = atm->sh_levels;
    const double inv = 1.0 / atm->delta, c = lc->c, dk = 1.0 / (n * atm->delta);
    const double px0 = c * (tg->x0 + lo * tg->dx) + lc->ax, py = c * (tg->y0 + iy * tg->dx) + lc->ay;
    double w, u0;
    sh_row *s = &r->s;
    *s = (sh_row){0};
    if (mm) {
        const uint64_t ky = dbits(py), kx = dbits(px0);
        int a = 0, b = 0;
        while (a < mm->ny && mm->ykey[a] != ky) a++;
        if (a < mm->ny) {
            w = mm->w[a];
            s->g0 = mm->y[a].g0;
            memcpy(s->gr, mm->y[a].gr, sizeof s->gr);
            memcpy(s->gi, mm->y[a].gi, sizeof s->gi);
        } else {
            w = wrap((py - atm->grid.y0) * inv, n);
            if (levels) wt_atmosphere__sh_row_y(lc->ly, levels, dk, py, s);
            if (a < ROW_MEMO) mm->ykey[a] = ky, mm->w[a] = w, mm->y[a] = *s, mm->ny++;
        }
        while (b < mm->nx && mm->xkey[b] != kx) b++;
        if (b < mm->nx) {
            u0 = mm->u0[b];
            memcpy(s->er, mm->x[b].er, sizeof s->er);
            memcpy(s->ei, mm->x[b].ei, sizeof s->ei);
        } else {
            u0 = wrap((px0 - atm->grid.x0) * inv, n);
            if (levels) wt_atmosphere__sh_row_x(levels, dk, px0, s);
            if (b < ROW_MEMO) mm->xkey[b] = kx, mm->u0[b] = u0, mm->x[b] = *s, mm->nx++;
        }
    } else {
        w = wrap((py - atm->grid.y0) * inv, n);
        u0 = wrap((px0 - atm->grid.x0) * inv, n);
        if (levels) wt_atmosphere__sh_row_init(lc->ly, levels, dk, py, px0, s);
    }
    const int j = (int)w;
    r->lo = lo, r->hi = sp->hi, r->mk = sp->mk, r->o = out + (int64_t)iy * tg->nx;
    r->u0 = u0;
    r->j1 = j + 1 == n ? 0 : j + 1;
    r->fy = w - j;
    r->r0 = lc->ly->screen + (int64_t)n * j, r->r1 = lc->ly->screen + (int64_t)n * r->j1;
    return 1;
}

/* The reference (point by point, the definition of every bit): target row iy, one layer:
 * out[row] += alpha · screen on the masked points. */
static void project_row_reference(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg,
                                  const row_span *sp, double alpha, double *out, int iy, row_memo *mm, int set)
{
    (void)mm; /* the definition computes every row's set-up itself */
    const int n = atm->n;
    row_start r;
    if (!row_start_init(atm, lc, tg, sp, out, iy, NULL, &r)) return;
    const int lo = r.lo, hi = r.hi;
    const uint8_t *mk = r.mk;
    double *o = r.o;
    const double u0 = r.u0, fy = r.fy, b = lc->b, *r0 = r.r0, *r1 = r.r1;
    int off = 0; /* multiple of n taken off the unwrapped index: u grows monotonically along the row */
    sh_row s = r.s;
    for (int k0 = lo; k0 <= hi; k0 += SH_CHUNK) {
        const int m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
        double shv[SH_CHUNK];
        if (atm->sh_levels) wt_atmosphere__sh_row_block(lc->q, &s, m, shv);
        else for (int k = 0; k < m; k++) shv[k] = 0.0;
        for (int k = 0; k < m; k++) {
            const int ix = k0 + k;
            const double u = u0 + (ix - lo) * b;
            const int iu = (int)u;
            const double fx = u - iu;
            int i = iu - off;
            while (i >= n) i -= n, off += n;
            const int i1 = i + 1 == n ? 0 : i + 1;
            const double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
            if (!mk || mk[ix]) o[ix] = (set ? 0.0 : o[ix]) + alpha * (a0 + fy * (a1 - a0) + shv[k]);
        }
    }
}

/* E_p advanced by one block without evaluating it (a block with no masked point): the same rotation
 * as the end of wt_atmosphere__sh_row_block, so the blocks after it see the same E_p bit for bit. */
static inline void sh_row_skip(const sh_step *q, sh_row *s)
{
    for (int p = 0; p < q->levels; p++) {
        double er = s->er[p], ei = s->ei[p];
        s->er[p] = er * q->rr[p] - ei * q->ri[p];
        s->ei[p] = er * q->ri[p] + ei * q->rr[p];
    }
}

/* One block of a unit row (see project_row): levels SHL or 0, masked or not, one fx for the block or
 * one per point, adding to the output or setting it (set: 0 + the term, the bits of adding to a zeroed
 * output). Compile-time flags: each combination is its own branch-free loop. */
typedef struct unit_args {
    const double *p0, *p1;   /* the two screen rows from the block's first cell */
    const uint8_t *bm;       /* the block's mask (NULL: all points) */
    double *o;               /* the block's output */
    double u0, fy, alpha, g0, fx;
    double ar[SHL], ai[SHL]; /* the block's subharmonic coefficients */
    const double *pr[SHL], *pi[SHL];
    int d0, c0, m;
} unit_args;

static inline __attribute__((always_inline)) void unit_block(const unit_args *a, const int levels,
                                                             const int masked, const int fxc, const int set)
{
    const double *restrict p0 = a->p0, *restrict p1 = a->p1;
    const uint8_t *restrict bm = a->bm;
    double *restrict o = a->o;
    const double u0 = a->u0, fy = a->fy, alpha = a->alpha, g0 = a->g0, fxb = a->fx;
    const double ar0 = a->ar[0], ar1 = a->ar[1], ar2 = a->ar[2], ai0 = a->ai[0], ai1 = a->ai[1], ai2 = a->ai[2];
    const double *restrict pr0 = a->pr[0], *restrict pr1 = a->pr[1], *restrict pr2 = a->pr[2];
    const double *restrict pi0 = a->pi[0], *restrict pi1 = a->pi[1], *restrict pi2 = a->pi[2];
    const int d0 = a->d0, c0 = a->c0, m = a->m;
    for (int k = 0; k < m; k++) {
        const double fx = fxc ? fxb : (u0 + (double)(d0 + k)) - (double)(c0 + k);
        double sv = 0.0;
        if (levels) {
            sv = g0;
            sv += ar0 * pr0[k] - ai0 * pi0[k];
            sv += ar1 * pr1[k] - ai1 * pi1[k];
            sv += ar2 * pr2[k] - ai2 * pi2[k];
        }
        const double a0 = p0[k] + fx * (p0[k + 1] - p0[k]), a1 = p1[k] + fx * (p1[k + 1] - p1[k]);
        const double v = a0 + fy * (a1 - a0) + sv;
        const double o0 = set ? 0.0 : o[k];
        if (masked) o[k] = bm[k] ? o0 + alpha * v : o[k];
        else o[k] = o0 + alpha * v;
    }
}

/* The fast path of project_row_reference, with the same arithmetic on every computed point (so the
 * same bits; tests/test_atmosphere.c compares them) but organised per block of SH_CHUNK points:
 *  - a block with no masked point evaluates nothing (the NGS sensors read only the pupil rim, the LGS
 *    sensors ~7/16 of the points), it only steps the subharmonic rotation;
 *  - the sample index along the row is iu mod n (iu = ⌊u⌋ ≥ 0 grows along the row), so a block whose
 *    iu stay within one period and off its last cell needs no wrap test: a branch-free loop the
 *    compiler vectorises; blocks across the seam and sparse blocks take the point-by-point loop.
 * Sparse blocks evaluate only their masked points: in unit rows (below) those with fewer than a
 * quarter of their points masked, elsewhere those with at most half (the LGS rows between subaperture
 * corners, every 4th point).
 *
 * Unit rows. Where one target step is exactly one screen cell (b = 1: the lines of sight from
 * infinity, NGS and evaluation directions, 4/5 of all samples at E-ELT size), u_k = fl(u0 + k) and
 * ⌊u_k⌋ = ⌊u0⌋ + k for every k as long as the fraction of u0 is farther from 0 and 1 than the rounding
 * of u0 + k (≤ half an ulp of the row's largest u): then the cell index and the weight fx = u_k − ⌊u_k⌋
 * need no conversion back from u, the screen reads are contiguous, and the subharmonic sum, the
 * bilinear weights and the accumulation run in one loop without intermediate arrays; each value is
 * still formed by the same operations in the same order. Cloned for AVX2 and AVX-512 (WT_CPU_CLONES: wider
 * vectors, hardware gathers; the same bits on every CPU). */
WT_CPU_CLONES
static void project_row(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg, const row_span *sp,
                        double alpha, double *out, int iy, row_memo *mm, int set)
{
    const int n = atm->n, levels = atm->sh_levels;
    row_start r;
    if (!row_start_init(atm, lc, tg, sp, out, iy, mm, &r)) return;
    const int lo = r.lo, hi = r.hi;
    const uint8_t *mk = r.mk;
    double *o = r.o;
    const double u0 = r.u0, fy = r.fy, b = lc->b, *r0 = r.r0, *r1 = r.r1;
    /* The sparse points (NGS rims, LGS rows between subaperture corners) read scattered screen cells
     * that miss every cache: their cells in the next screen row, which the next target row reads, are
     * prefetched (dense blocks measured no gain from it). */
    const double *r2 = lc->ly->screen + (int64_t)n * (r.j1 + 1 == n ? 0 : r.j1 + 1);
    sh_row s = r.s;
    int unit = 0, iu0 = 0;
    if (b == 1.0) {
        iu0 = (int)u0;
        const double f = u0 - iu0, eps = (u0 + (hi - lo) + 2.0) * 0x1p-52;
        unit = f > eps && f < 1.0 - eps;
    }
    for (int k0 = lo; k0 <= hi; k0 += SH_CHUNK) {
        const int m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
        int cnt = m;
        if (mk) {
            const int bk = (k0 - lo) / SH_CHUNK;
            if (bk < sp->nb) cnt = sp->cnt[bk];
            else {
                cnt = 0;
                for (int k = 0; k < m; k++) cnt += mk[k0 + k] != 0;
            }
            if (cnt == 0) {
                if (levels) sh_row_skip(lc->q, &s);
                continue;
            }
        }
        const int d0 = k0 - lo; /* (ix − lo) of the block's first point */
        if (unit && 4 * cnt >= m) {
            const int c0 = iu0 + d0, i0 = c0 < n ? c0 : c0 % n; /* the block's first cell, wrapped */
            if (i0 + m <= n - 1) {
                unit_args ua = {.p0 = r0 + i0, .p1 = r1 + i0, .bm = mk && cnt < m ? mk + k0 : NULL, .o = o + k0,
                                .u0 = u0, .fy = fy, .alpha = alpha, .g0 = s.g0, .d0 = d0, .c0 = c0, .m = m};
                if (levels == SHL) {
                    wt_atmosphere__sh_row_coef(lc->q, &s, ua.ar, ua.ai);
                    for (int p = 0; p < SHL; p++) ua.pr[p] = lc->q->pr[p], ua.pi[p] = lc->q->pi[p];
                }
                /* one fx for the block when its cells lie in one binade [2^e, 2^(e+1)): there
                 * fl(c + f) = c + (f rounded to the binade's ulp) for every integer c */
                const int fxc = c0 >= 1 && ((c0 ^ (c0 + m - 1)) <= c0);
                if (fxc) ua.fx = (u0 + (double)d0) - (double)c0;
                if (levels == SHL) {
                    /* each combination of the flags is its own loop (masked, one fx, set) */
                    switch ((ua.bm != NULL) << 2 | fxc << 1 | (set != 0)) {
                    case 0: unit_block(&ua, SHL, 0, 0, 0); break;
                    case 1: unit_block(&ua, SHL, 0, 0, 1); break;
                    case 2: unit_block(&ua, SHL, 0, 1, 0); break;
                    case 3: unit_block(&ua, SHL, 0, 1, 1); break;
                    case 4: unit_block(&ua, SHL, 1, 0, 0); break;
                    case 5: unit_block(&ua, SHL, 1, 0, 1); break;
                    case 6: unit_block(&ua, SHL, 1, 1, 0); break;
                    default: unit_block(&ua, SHL, 1, 1, 1); break;
                    }
                } else {
                    unit_block(&ua, 0, ua.bm != NULL, 0, set);
                }
                continue;
            }
        }
        const int iu_a = (int)(u0 + d0 * b), iu_b = (int)(u0 + (d0 + m - 1) * b);
        const int q0 = iu_a < n ? 0 : iu_a / n;
        if (2 * cnt > m && iu_b - q0 * n <= n - 2) {
            double shv[SH_CHUNK], val[SH_CHUNK];
            if (levels) wt_atmosphere__sh_row_block(lc->q, &s, m, shv);
            else for (int k = 0; k < m; k++) shv[k] = 0.0;
            const int oc = q0 * n;
            double fxv[SH_CHUNK];
            int iv[SH_CHUNK], steps = 0;
            for (int k = 0; k < m; k++) {
                const double u = u0 + (d0 + k) * b;
                const int iu = (int)u;
                fxv[k] = u - iu;
                iv[k] = iu - oc;
            }
            for (int k = 0; k < m; k++) steps += iv[k] != iv[0] + k;
            if (steps == 0) { /* one screen cell per point */
                const double *restrict p0 = r0 + iv[0], *restrict p1 = r1 + iv[0];
                for (int k = 0; k < m; k++) {
                    const double a0 = p0[k] + fxv[k] * (p0[k + 1] - p0[k]), a1 = p1[k] + fxv[k] * (p1[k + 1] - p1[k]);
                    val[k] = a0 + fy * (a1 - a0) + shv[k];
                }
            } else {
                for (int k = 0; k < m; k++) {
                    const int i = iv[k];
                    const double a0 = r0[i] + fxv[k] * (r0[i + 1] - r0[i]), a1 = r1[i] + fxv[k] * (r1[i + 1] - r1[i]);
                    val[k] = a0 + fy * (a1 - a0) + shv[k];
                }
            }
            if (cnt == m)
                for (int k = 0; k < m; k++) o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * val[k];
            else
                for (int k = 0; k < m; k++)
                    if (mk[k0 + k]) o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * val[k];
            continue;
        }
        /* point by point (sparse blocks, the seam): the subharmonic sum of the masked points only, in
         * the order of wt_atmosphere__sh_row_block */
        double ar[SHL] = {0}, ai[SHL] = {0};
        if (levels) wt_atmosphere__sh_row_coef(lc->q, &s, ar, ai);
        for (int k = 0; k < m; k++) {
            if (mk && !mk[k0 + k]) continue;
            double sv = 0.0;
            if (levels) {
                sv = s.g0;
                for (int p = 0; p < levels; p++) sv += ar[p] * lc->q->pr[p][k] - ai[p] * lc->q->pi[p][k];
            }
            const double u = u0 + (d0 + k) * b;
            const int iu = (int)u;
            const double fx = u - iu;
            const int i = iu < n ? iu : iu % n, i1 = i + 1 == n ? 0 : i + 1;
            __builtin_prefetch(r2 + i);
            const double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
            o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * (a0 + fy * (a1 - a0) + sv);
        }
    }
}

/* The checks of wt_atmosphere_project and wt_atmosphere_project_reference. */
static int check_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                         double theta_y, const wt_grid *target, double *out)
{
    const char *fn = "wt_atmosphere_project";
    if (!atm) return WT_ERR_INVALID;
    wt_context *ctx = atm->ctx;
    if (!target || !out) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: %s is NULL", fn, !target ? "target" : "out");
    if (target->nx < 1 || target->ny < 1 || !(target->dx > 0.0) || !isfinite(target->dx) ||
        !isfinite(target->x0) || !isfinite(target->y0))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: target grid %d x %d, dx = %g m, origin (%g, %g) m; expected >= 1 x 1 points, a "
                        "finite dx > 0 and a finite origin",
                        fn, target->nx, target->ny, target->dx, target->x0, target->y0);
    /* The unwrapped screen index along a row must fit an int. */
    if ((double)target->nx * target->dx / atm->delta > 1e9)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: target rows span %g m, over 1e9 screen cells of %g m", fn,
                        target->nx * target->dx, atm->delta);
    if (!isfinite(t) || !isfinite(theta_x) || !isfinite(theta_y))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: t = %g s, theta = (%g, %g) rad; expected finite values", fn,
                        t, theta_x, theta_y);
    if (!(source_altitude >= 0.0) || !isfinite(source_altitude))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: source_altitude = %g m; expected 0 (infinity) or a finite altitude > 0", fn,
                        source_altitude);
    if (source_altitude > 0.0)
        for (int l = 0; l < atm->nlayers; l++)
            if (!(atm->layers[l].altitude < source_altitude))
                return WT_ERROR(ctx, WT_ERR_INVALID,
                                "%s: source_altitude = %g m is not above layer %d at %g m", fn, source_altitude,
                                l, atm->layers[l].altitude);
    return WT_OK;
}

/* The projection with row kernel `row`. Layers outer, rows inner: the per-layer set-up (subharmonic
 * rotations) is done once per thread. The static schedule gives each thread the same rows for every
 * layer, so `nowait` is safe and every point adds its layers in layer order whatever the thread count
 * (bit-identical results). */
typedef void (*row_kernel)(const wt_atmosphere *, const layer_call *, const wt_grid *, const row_span *, double,
                           double *, int, row_memo *, int);

static int project_with(row_kernel row, const wt_atmosphere *atm, double t, double source_altitude,
                        double theta_x, double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                        double *out)
{
    int st = check_project(atm, t, source_altitude, theta_x, theta_y, target, out);
    if (st < 0 || alpha == 0.0) return st;
    const int ny = target->ny, nl = atm->nlayers;
    const int nth = wt_context_threads(atm->ctx);
    (void)nth;
#pragma omp parallel num_threads(nth) if (nth > 1 && ny > 1 && !omp_in_parallel())
    for (int l = 0; l < nl; l++) {
        layer_call lc;
        sh_step q;
        layer_call_init(atm, l, t, source_altitude, theta_x, theta_y, target, &lc);
        layer_call_step(atm, target, lc.c, &q);
        lc.q = &q;
#pragma omp for schedule(static) nowait
        for (int iy = 0; iy < ny; iy++) {
            row_span sp;
            row_span_init(mask, target->nx, iy, &sp);
            row(atm, &lc, target, &sp, alpha * lc.ly->scale, out, iy, NULL, 0);
        }
    }
    return WT_OK;
}

int wt_atmosphere_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                          double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                          double *out)
{
    return project_with(project_row, atm, t, source_altitude, theta_x, theta_y, target, mask, alpha, out);
}

int wt_atmosphere_project_reference(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                                    double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                                    double *out)
{
    return project_with(project_row_reference, atm, t, source_altitude, theta_x, theta_y, target, mask, alpha,
                        out);
}

/* Batched: bands of BAND_ROWS target rows, and in each band every layer for every line of sight. The
 * lines of sight of one frame see nearly the same part of a layer (the E-ELT footprints differ by θh,
 * at most 15 m of 57 m at 18 km), so a band's screen rows are read from memory once for all of them
 * and then from cache, where one call per line of sight read each layer's footprint again (~0.7 MB
 * per line of sight and layer, 200 MB per E-ELT frame). Each point still adds its layers in layer
 * order, so the result is that of one wt_atmosphere_project per line of sight, bit for bit, for any
 * schedule. The set-up is per (line of sight, layer) with one subharmonic step per distinct cone
 * factor; beyond BATCH_PAIRS pairs or BATCH_STEPS factors it falls back to one call per line of sight. */
#define BAND_ROWS 8
#define BATCH_PAIRS 512
#define BATCH_STEPS 24
#define MANY_LAYERS 16

/* The spans of one target row by mask (the E-ELT's 34 lines of sight have 10 distinct masks). */
#define SPAN_MEMO 16
typedef struct span_memo {
    int n;
    const uint8_t *key[SPAN_MEMO];
    row_span v[SPAN_MEMO];
} span_memo;

static const row_span *span_lookup(span_memo *m, const uint8_t *mask, int nx, int iy, row_span *tmp)
{
    for (int k = 0; k < m->n; k++)
        if (m->key[k] == mask) return &m->v[k];
    row_span *sp = m->n < SPAN_MEMO ? &m->v[m->n] : tmp;
    row_span_init(mask, nx, iy, sp);
    if (m->n < SPAN_MEMO) m->key[m->n++] = mask;
    return sp;
}

/* The masked points of the outputs with `set` are zeroed (where the batch does not set them itself). */
static void zero_set_outputs(int nlos, const wt_atmosphere_los *los, const wt_grid *target)
{
    const int64_t np = wt_grid_size(target);
    for (int i = 0; i < nlos; i++)
        if (los[i].set)
            for (int64_t k = 0; k < np; k++)
                if (!los[i].mask || los[i].mask[k]) los[i].out[k] = 0.0;
}

int wt_atmosphere_project_many(const wt_atmosphere *atm, double t, int nlos, const wt_atmosphere_los *los,
                               const wt_grid *target, double alpha)
{
    if (!atm) return WT_ERR_INVALID;
    if (nlos < 0 || (nlos > 0 && !los))
        return WT_ERROR(atm->ctx, WT_ERR_INVALID, "wt_atmosphere_project_many: %d lines of sight at %p", nlos,
                        (const void *)los);
    for (int i = 0; i < nlos; i++) {
        int st = check_project(atm, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target, los[i].out);
        if (st < 0) return st;
    }
    if (nlos == 0) return WT_OK;
    const int nl = atm->nlayers, ny = target->ny;
    if (alpha == 0.0) {
        zero_set_outputs(nlos, los, target);
        return WT_OK;
    }
    layer_call lc[BATCH_PAIRS];
    sh_step q[BATCH_STEPS];
    double qc[BATCH_STEPS];
    int nq = 0, fit = (int64_t)nlos * nl <= BATCH_PAIRS && nl <= MANY_LAYERS;
    for (int i = 0; fit && i < nlos; i++)
        for (int l = 0; fit && l < nl; l++) {
            layer_call *c = &lc[i * nl + l];
            layer_call_init(atm, l, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target, c);
            int k = 0;
            while (k < nq && qc[k] != c->c) k++;
            if (k == nq) {
                if (nq == BATCH_STEPS) {
                    fit = 0;
                    break;
                }
                qc[nq] = c->c;
                layer_call_step(atm, target, c->c, &q[nq++]);
            }
            c->q = &q[k];
        }
    if (!fit) {
        zero_set_outputs(nlos, los, target);
        for (int i = 0; i < nlos; i++) {
            int st = wt_atmosphere_project(atm, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target,
                                           los[i].mask, alpha, los[i].out);
            if (st < 0) return st;
        }
        return WT_OK;
    }
    const int nb = (ny + BAND_ROWS - 1) / BAND_ROWS, nth = wt_context_threads(atm->ctx);
    (void)nth;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) if (nth > 1 && nb > 1 && !omp_in_parallel())
    for (int bd = 0; bd < nb; bd++) {
        const int y0 = bd * BAND_ROWS, y1 = y0 + BAND_ROWS < ny ? y0 + BAND_ROWS : ny;
        span_memo spm;
        row_memo mm[MANY_LAYERS];
        for (int iy = y0; iy < y1; iy++) {
            spm.n = 0;
            for (int l = 0; l < nl; l++) mm[l].ny = mm[l].nx = 0;
            for (int i = 0; i < nlos; i++) {
                row_span tmp;
                const row_span *sp = span_lookup(&spm, los[i].mask, target->nx, iy, &tmp);
                for (int l = 0; l < nl; l++)
                    project_row(atm, &lc[i * nl + l], target, sp, alpha * lc[i * nl + l].ly->scale, los[i].out, iy, &mm[l],
                                l == 0 && los[i].set);
            }
        }
    }
    return WT_OK;
}
