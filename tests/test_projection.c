/* tests/test_projection.c: layer projections P (NGS and LGS, SPEC §3): adjoint, assembly, geometry
 * (altitude 0, cone factor, NGS shift), coverage errors and clamping. */
#include "testutil.h"

#include "core/la/sparse.h"
#include "core/op/projection.h"
#include "core/op/pupil.h"

#define ARCSEC (M_PI / (180.0 * 3600.0))

/* The E-ELT-like stack of SPEC §6: 128² @ 0.5 m at 0 m, 64² @ 1 m at 4 and 12.7 km. */
static const double alts3[3] = {0.0, 4000.0, 12700.0};
static void layers3(wt_grid g[3])
{
    g[0] = wt_grid_layer(128, 0.5);
    g[1] = wt_grid_layer(64, 1.0);
    g[2] = wt_grid_layer(64, 1.0);
}

/* The LGS corner grid 85 x 85 at 0.5 m and its valid-corner mask (84 x 84 subapertures, SPEC §1). */
static wt_grid corner_grid(uint8_t *mask)
{
    uint8_t v[84 * 84];
    ck_assert_int_eq(wt_pupil_valid_subapertures(42.0, 0.28, 84, 0.5, v), 5112);
    wt_pupil_corner_mask(84, v, mask);
    return wt_grid_centred(85, 0.5);
}

/* Six layers every 2.5 km, alternately 128² at 0.5 m and 64² at 1 m (both interpolation stencils). */
static void mixed_layers(wt_grid g[6], double h[6])
{
    for (int l = 0; l < 6; l++) {
        g[l] = wt_grid_layer(l % 2 ? 64 : 128, l % 2 ? 1.0 : 0.5);
        h[l] = 2500.0 * l;
    }
}

static wt_projection *make(wt_context *ctx, int nl, const wt_grid *g, const double *h, double H, double tx, double ty,
                           const wt_grid *t, const uint8_t *mask, int clamp)
{
    wt_projection *p = NULL;
    int st = wt_projection_alloc(ctx, nl, g, h, H, tx, ty, t, mask, clamp, &p);
    ck_assert_msg(st == WT_OK, "alloc failed: %s", wt_error_message(ctx));
    return p;
}

/* ⟨P x, y⟩ = ⟨x, Pᵀ y⟩: both sides sum the same ~4·L·npts products in different orders, so they
 * agree to ~ npts·ε·‖Px‖‖y‖ ≲ 1e-12 ‖Px‖‖y‖ (npts ≤ 7225). */
static void check_adjoint(const wt_projection *p, unsigned long seed)
{
    long nin = wt_projection_nin(p), nout = wt_projection_nout(p);
    double *x = malloc(nin * sizeof *x), *y = malloc(nout * sizeof *y);
    double *px = calloc(nout, sizeof *px), *pty = calloc(nin, sizeof *pty);
    tu_randn(x, nin, seed);
    tu_randn(y, nout, seed + 1);
    wt_projection_apply(p, 1.0, x, px);
    wt_projection_apply_t(p, 1.0, y, pty);
    double lhs = tu_dot(px, y, nout), rhs = tu_dot(x, pty, nin);
    ck_assert(tu_norm(px, nout) > 0.0);
    ck_assert_rel(lhs, rhs, 1e-12, tu_norm(px, nout) * tu_norm(y, nout));
    free(x), free(y), free(px), free(pty);
}

/* apply (accumulating, with α) == y0 + α · assembled matrix × x. Weights and sums differ only in
 * rounding order (products w_r·w_c formed before or after the sum): 1e-13 relative. */
static void check_assembled(const wt_projection *p, unsigned long seed)
{
    long nin = wt_projection_nin(p), nout = wt_projection_nout(p);
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_projection_assemble(p, &A), WT_OK);
    ck_assert_int_eq(A->nrow, nout);
    ck_assert_int_eq(A->ncol, nin);
    double *x = malloc(nin * sizeof *x), *y = malloc(nout * sizeof *y), *z = malloc(nout * sizeof *z);
    double *u = malloc(nout * sizeof *u), *v = malloc(nin * sizeof *v), *w = malloc(nin * sizeof *w);
    tu_randn(x, nin, seed);
    tu_randn(y, nout, seed + 1);
    memcpy(z, y, nout * sizeof *z);
    wt_projection_apply(p, -0.7, x, y);
    wt_sparse_apply(A, -0.7, x, z);
    ck_assert_double_le(tu_rel_diff(y, z, nout), 1e-13);
    tu_randn(u, nout, seed + 2);
    tu_randn(v, nin, seed + 3);
    memcpy(w, v, nin * sizeof *w);
    wt_projection_apply_t(p, 1.3, u, v);
    wt_sparse_apply_t(A, 1.3, u, w);
    ck_assert_double_le(tu_rel_diff(v, w, nin), 1e-13);
    wt_sparse_free(A);
    free(x), free(y), free(z), free(u), free(v), free(w);
}

START_TEST(test_adjoint_and_assembly)
{
    wt_context *ctx = tu_context();
    wt_grid g[3];
    layers3(g);
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    wt_projection *lgs = make(ctx, 3, g, alts3, 90000.0, 30 * ARCSEC, -20 * ARCSEC, &t, mask, 0);
    wt_projection *ngs = make(ctx, 3, g, alts3, 0.0, -45 * ARCSEC, 60 * ARCSEC, &t, mask, 0);
    wt_projection *all = make(ctx, 3, g, alts3, 0.0, 10 * ARCSEC, 0.0, &t, NULL, 0);
    ck_assert_int_eq(wt_projection_nin(lgs), 128 * 128 + 2 * 64 * 64);
    ck_assert_int_eq(wt_projection_nout(lgs), 85 * 85);
    check_adjoint(lgs, 11);
    check_adjoint(ngs, 21);
    check_adjoint(all, 31);
    check_assembled(lgs, 41);
    check_assembled(ngs, 51);
    check_assembled(all, 61);
    /* a clamped projection that hangs over a small layer's edge */
    wt_grid small[2] = {wt_grid_centred(41, 0.5), wt_grid_layer(32, 1.0)};
    double hs[2] = {0.0, 9000.0};
    wt_projection *cl = make(ctx, 2, small, hs, 90000.0, 25 * ARCSEC, 5 * ARCSEC, &t, mask, 1);
    check_adjoint(cl, 71);
    check_assembled(cl, 81);
    wt_projection_free(lgs);
    wt_projection_free(ngs);
    wt_projection_free(all);
    wt_projection_free(cl);
    wt_projection_free(NULL);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_masked_points_untouched)
{
    wt_context *ctx = tu_context();
    wt_grid g[3];
    layers3(g);
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    wt_projection *p = make(ctx, 3, g, alts3, 90000.0, 30 * ARCSEC, 0.0, &t, mask, 0);
    long nin = wt_projection_nin(p);
    double *x = malloc(nin * sizeof *x), *y = malloc(85 * 85 * sizeof *y);
    tu_randn(x, nin, 5);
    for (int k = 0; k < 85 * 85; k++) y[k] = -1.0;
    wt_projection_apply(p, 1.0, x, y);
    int changed = 0;
    for (int k = 0; k < 85 * 85; k++) {
        if (!mask[k]) ck_assert(y[k] == -1.0);
        else changed += y[k] != -1.0;
    }
    ck_assert_int_eq(changed, 5328);
    /* Pᵀ ignores unmasked points: NaN there must not leak into the layers */
    for (int k = 0; k < 85 * 85; k++) y[k] = mask[k] ? 1.0 : NAN;
    for (long k = 0; k < nin; k++) x[k] = 0.0;
    wt_projection_apply_t(p, 1.0, y, x);
    for (long k = 0; k < nin; k++) ck_assert(isfinite(x[k]));
    free(x), free(y);
    wt_projection_free(p);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_ground_layer_same_everywhere)
{
    /* A layer at h = 0 is seen identically from every direction and source altitude: the sample point
     * is (1 − 0/H) r + θ·0 = r exactly, so the outputs must be bit-identical. */
    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_layer(128, 0.5);
    double h = 0.0;
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    double *x = malloc(128 * 128 * sizeof *x), *y0 = calloc(85 * 85, sizeof *y0), *y1 = calloc(85 * 85, sizeof *y1);
    tu_randn(x, 128 * 128, 7);
    wt_projection *ref = make(ctx, 1, &g, &h, 0.0, 0.0, 0.0, &t, mask, 0);
    wt_projection_apply(ref, 1.0, x, y0);
    const double dirs[4][3] = {{0.0, 60 * ARCSEC, 0.0}, {90000.0, 60 * ARCSEC, 0.0}, {90000.0, -30 * ARCSEC, 45 * ARCSEC},
                               {0.0, 0.0, -80 * ARCSEC}};
    for (int k = 0; k < 4; k++) {
        wt_projection *p = make(ctx, 1, &g, &h, dirs[k][0], dirs[k][1], dirs[k][2], &t, mask, 0);
        memset(y1, 0, 85 * 85 * sizeof *y1);
        wt_projection_apply(p, 1.0, x, y1);
        for (int i = 0; i < 85 * 85; i++) ck_assert(y1[i] == y0[i]);
        wt_projection_free(p);
    }
    /* the target points at h = 0 fall on layer grid points: the values are the layer's own */
    int ix = 42 + 10, iy = 42 - 6; /* target point (5, -3) m; layer index (5/0.5 + 64, -3/0.5 + 64) */
    ck_assert(mask[ix + 85 * iy]);
    ck_assert(y0[ix + 85 * iy] == x[(10 + 64) + 128 * (-6 + 64)]);
    wt_projection_free(ref);
    free(x), free(y0), free(y1);
    wt_context_free(ctx);
}
END_TEST

/* fill a layer with f(X, Y) at its grid points */
static void fill(const wt_grid *g, double *v, double a, double b, double c, double e)
{
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            double X = g->x0 + ix * g->dx, Y = g->y0 + iy * g->dx;
            v[ix + g->nx * iy] = a * X + b * Y + c * X * Y + e;
        }
}

START_TEST(test_cone_and_shift)
{
    /* Bilinear interpolation reproduces any a X + b Y + c XY + e exactly (it is the tensor product of
     * two linear interpolations), so the projections are exact up to rounding: ~ε·|f| with
     * |f| ≤ |a|·32 + |b|·32 + |c|·32² + |e| — 1e-13 relative to that scale. */
    wt_context *ctx = tu_context();
    wt_grid g[3];
    layers3(g);
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    const double H = 90000.0, tx = 30 * ARCSEC, ty = -17 * ARCSEC;
    for (int l = 0; l < 3; l++) {
        const double h = alts3[l], a = 1.7e-6, b = -0.6e-6, c = 2.3e-8, e = 4e-7;
        double *v = malloc(wt_grid_size(&g[l]) * sizeof *v);
        double *y = calloc(85 * 85, sizeof *y);
        double scale = fabs(a) * 32 + fabs(b) * 32 + fabs(c) * 1024 + fabs(e);
        /* LGS, linear layer: (1 − h/H)(a x + b y) + (a θx + b θy) h */
        fill(&g[l], v, a, b, 0.0, 0.0);
        wt_projection *lgs = make(ctx, 1, &g[l], &h, H, tx, ty, &t, mask, 0);
        wt_projection_apply(lgs, 1.0, v, y);
        for (int iy = 0; iy < 85; iy++)
            for (int ix = 0; ix < 85; ix++) {
                if (!mask[ix + 85 * iy]) continue;
                double x = t.x0 + ix * t.dx, yy = t.y0 + iy * t.dx;
                double want = (1 - h / H) * (a * x + b * yy) + (a * tx + b * ty) * h;
                ck_assert_rel(y[ix + 85 * iy], want, 1e-13, scale);
            }
        /* NGS, bilinear layer: f(r + θh) */
        fill(&g[l], v, a, b, c, e);
        memset(y, 0, 85 * 85 * sizeof *y);
        wt_projection *ngs = make(ctx, 1, &g[l], &h, 0.0, tx, ty, &t, mask, 0);
        wt_projection_apply(ngs, 1.0, v, y);
        for (int iy = 0; iy < 85; iy++)
            for (int ix = 0; ix < 85; ix++) {
                if (!mask[ix + 85 * iy]) continue;
                double X = t.x0 + ix * t.dx + tx * h, Y = t.y0 + iy * t.dx + ty * h;
                ck_assert_rel(y[ix + 85 * iy], a * X + b * Y + c * X * Y + e, 1e-13, scale);
            }
        wt_projection_free(lgs);
        wt_projection_free(ngs);
        free(v), free(y);
    }
    /* all three layers at once: the sum of the three single-layer results */
    long nin = 128 * 128 + 2 * 64 * 64;
    double *v = malloc(nin * sizeof *v), *y = calloc(85 * 85, sizeof *y);
    fill(&g[0], v, 1e-6, 0, 0, 0);
    fill(&g[1], v + 128 * 128, 1e-6, 0, 0, 0);
    fill(&g[2], v + 128 * 128 + 64 * 64, 1e-6, 0, 0, 0);
    wt_projection *p = make(ctx, 3, g, alts3, H, tx, ty, &t, mask, 0);
    wt_projection_apply(p, 2.0, v, y);
    for (int k = 0; k < 85 * 85; k++) {
        if (!mask[k]) continue;
        double x = t.x0 + (k % 85) * t.dx, want = 0;
        for (int l = 0; l < 3; l++) want += 2.0 * 1e-6 * ((1 - alts3[l] / H) * x + tx * alts3[l]);
        ck_assert_rel(y[k], want, 1e-13, 1e-6 * 32 * 6);
    }
    wt_projection_free(p);
    free(v), free(y);
    wt_context_free(ctx);
}
END_TEST

/* A multi-layer apply runs the layers per point (in groups of 4, projection.c): each point must add its
 * layers' terms in layer order, i.e. give the bits of the single-layer applies in a row, for 1–6
 * layers (the grouping), with and without clamping (a DM seen beyond its edge), from a random y with
 * α ≠ 1. (That the two-lane kernel is the scalar expression bit for bit is checked end to end by the
 * command hashes of make regress-commands.) */
START_TEST(test_layers_per_point_bits)
{
    wt_context *ctx = tu_context();
    uint8_t mask[85 * 85];
    const wt_grid t = corner_grid(mask);
    wt_grid g[6];
    double h[6];
    mixed_layers(g, h);
    for (int clamp = 0; clamp <= 1; clamp++)
        for (int nl = 1; nl <= 6; nl++) {
            const double H = clamp ? 0.0 : 90000.0, tx = 25 * ARCSEC, ty = -40 * ARCSEC;
            wt_projection *p = make(ctx, nl, g, h, H, tx, ty, &t, mask, clamp);
            const long nin = wt_projection_nin(p), nout = wt_projection_nout(p);
            double *x = malloc(nin * sizeof *x), *y = malloc(nout * sizeof *y), *ref = malloc(nout * sizeof *ref);
            tu_randn(x, nin, 60 + nl);
            tu_randn(y, nout, 70 + nl);
            memcpy(ref, y, nout * sizeof *y);
            wt_projection_apply(p, -0.83, x, y);
            long off = 0;
            for (int l = 0; l < nl; l++) {
                wt_projection *q = make(ctx, 1, &g[l], &h[l], H, tx, ty, &t, mask, clamp);
                wt_projection_apply(q, -0.83, x + off, ref);
                wt_projection_free(q);
                off += wt_grid_size(&g[l]);
            }
            ck_assert_mem_eq(y, ref, nout * sizeof *y);
            free(x), free(y), free(ref);
            wt_projection_free(p);
        }
    wt_context_free(ctx);
}
END_TEST

/* An aligned layer (the ground layer under the corner grid: the same spacing, origins 22 points apart) is read and
 * written contiguously; it must give the bits of the bilinear definition, whose zero weights add ±0 terms:
 *   apply:   y += a0 (1·x[j] + 0·x[j+1]) + a1 (1·x[j+nx] + 0·x[j+nx+1]),  a0 = α, a1 = α·0,
 *   apply_t: the column-pair sums s0 = Σ 1·y, s1 = Σ 0·y along each run, each column written when left behind
 *            (the loop of wt_projection_apply_t for any layer, restated here).
 * x and y hold exact zeros of both signs among random values (the cases where a ±0 term could show); y and the
 * layers start without −0, as every caller's cleared arrays do. Checked alone and under two 1 m layers (the LGS
 * stack; the AVX-512 kernel where the machine has it). */
static void aligned_reference(int nl, const wt_grid *g, const double *h, double H, const wt_grid *t,
                              const uint8_t *mask, double alpha, const double *x, const double *y0, double *y)
{
    wt_context *ctx = tu_context();
    memcpy(y, y0, (size_t)wt_grid_size(t) * sizeof *y);
    /* the ground layer's term first (layer order), by the definition; the others by their own one-layer apply */
    for (int iy = 0; iy < t->ny; iy++)
        for (int ix = 0; ix < t->nx; ix++) {
            const long k = (long)iy * t->nx + ix;
            if (!mask[k]) continue;
            const long j = (long)(iy + 22) * 128 + ix + 22;
            const double a0 = alpha * 1.0, a1 = alpha * 0.0;
            y[k] += a0 * (1.0 * x[j] + 0.0 * x[j + 1]) + a1 * (1.0 * x[j + 128] + 0.0 * x[j + 129]);
        }
    double *tmp = malloc((size_t)wt_grid_size(t) * sizeof *tmp);
    long off = wt_grid_size(&g[0]);
    for (int l = 1; l < nl; l++) { /* the point's sum continues in layer order: add layer l's term to it */
        wt_projection *q = make(ctx, 1, &g[l], &h[l], H, 0.0, 0.0, t, mask, 0);
        memcpy(tmp, y, (size_t)wt_grid_size(t) * sizeof *y);
        wt_projection_apply(q, alpha, x + off, tmp);
        memcpy(y, tmp, (size_t)wt_grid_size(t) * sizeof *y);
        wt_projection_free(q);
        off += wt_grid_size(&g[l]);
    }
    free(tmp);
    wt_context_free(ctx);
}

START_TEST(test_aligned_layer_bits)
{
    wt_context *ctx = tu_context();
    uint8_t mask[85 * 85];
    const wt_grid t = corner_grid(mask);
    wt_grid g[3];
    layers3(g);
    const long nt = 85 * 85;
    for (int nl = 1; nl <= 3; nl += 2) {
        wt_projection *p = make(ctx, nl, g, alts3, 90000.0, 0.0, 0.0, &t, mask, 0);
        const long nin = wt_projection_nin(p);
        double *x = malloc(nin * sizeof *x), *y0 = malloc(nt * sizeof *y0), *y = malloc(nt * sizeof *y);
        double *ref = malloc(nt * sizeof *ref), *u = malloc(nin * sizeof *u), *v = malloc(nin * sizeof *v);
        tu_randn(x, nin, 90 + nl);
        tu_randn(y0, nt, 95 + nl);
        for (long i = 0; i < nin; i += 7) x[i] = (i / 7) % 2 ? -0.0 : 0.0;
        for (long i = 0; i < nt; i += 5) y0[i] = 0.0;
        for (int cleared = 0; cleared <= 1; cleared++) {
            if (cleared) memset(y0, 0, nt * sizeof *y0);
            memcpy(y, y0, nt * sizeof *y);
            wt_projection_apply(p, -0.83, x, y);
            aligned_reference(nl, g, alts3, 90000.0, &t, mask, -0.83, x, y0, ref);
            ck_assert_mem_eq(y, ref, nt * sizeof *y);
        }
        if (nl == 1) {
            /* the transpose: the general loop (s0, s1 per column pair) on the ground layer's stencil */
            tu_randn(y, nt, 97);
            for (long i = 0; i < nt; i += 5) y[i] = (i / 5) % 2 ? -0.0 : 0.0;
            tu_randn(u, nin, 98);
            memcpy(v, u, nin * sizeof *u);
            wt_projection_apply_t(p, 1.7, y, u);
            const double a0 = 1.7 * 1.0, a1 = 1.7 * 0.0;
            for (int iy = 0; iy < 85; iy++)
                for (int lo = 0; lo < 85;) {
                    if (!mask[iy * 85 + lo]) {
                        lo++;
                        continue;
                    }
                    int hi = lo;
                    while (hi < 85 && mask[iy * 85 + hi]) hi++;
                    double *r0 = v + (long)(iy + 22) * 128 + 22, *r1 = r0 + 128;
                    int jc = lo;
                    double s0 = 0.0, s1 = 0.0;
                    for (int ix = lo; ix < hi; ix++) {
                        if (ix != jc) { /* j = jc + 1 */
                            r0[jc] += a0 * s0;
                            r1[jc] += a1 * s0;
                            s0 = s1;
                            s1 = 0.0;
                            jc = ix;
                        }
                        s0 += 1.0 * y[iy * 85 + ix];
                        s1 += 0.0 * y[iy * 85 + ix];
                    }
                    r0[jc] += a0 * s0;
                    r1[jc] += a1 * s0;
                    r0[jc + 1] += a0 * s1;
                    r1[jc + 1] += a1 * s1;
                    lo = hi;
                }
            ck_assert_mem_eq(u, v, nin * sizeof *u);
        }
        free(x), free(y0), free(y), free(ref), free(u), free(v);
        wt_projection_free(p);
    }
    wt_context_free(ctx);
}
END_TEST

/* wt_projection_apply_rows (X rows along x computed once, then combined along y) and wt_projection_apply_t_side
 * (layers side by side per point) do the operations of apply and apply_t on the same operands in the same
 * order: the same bits. Geometries: the fitting's (0.25 m samples in the pupil, 0.5 m layers, sources at
 * infinity, 1 to 9 layers; DMs of 0.5 and 1 m seen beyond their edge, clamped), the LGS cone on the 0.5 m
 * corners (0.5 and 1 m layers, a layer row read by one or two target rows), and 33 layers (beyond the rows
 * pass's 32: apply's loops). accumulate = 0 overwrites the sample points with what a zeroed array
 * accumulates and leaves the others as they were. */
static void check_rows_side(const wt_projection *p, const uint8_t *mask, unsigned long seed)
{
    const long nin = wt_projection_nin(p), nout = wt_projection_nout(p);
    double *x = malloc(nin * sizeof *x), *y = malloc(nout * sizeof *y), *ref = malloc(nout * sizeof *ref);
    double *work = malloc(wt_projection_rows_work(p) * sizeof *work);
    double *u = malloc(nin * sizeof *u), *v = malloc(nin * sizeof *v);
    tu_randn(x, nin, seed);
    tu_randn(y, nout, seed + 1);
    memcpy(ref, y, nout * sizeof *y);
    wt_projection_apply(p, -0.83, x, ref);
    wt_projection_apply_rows(p, -0.83, x, y, work, 1);
    ck_assert_mem_eq(y, ref, nout * sizeof *y);
    /* overwrite: the sample points as on a zeroed array, the rest (here NaN) untouched */
    for (long i = 0; i < nout; i++) y[i] = NAN, ref[i] = 0.0;
    wt_projection_apply(p, 0.61, x, ref);
    wt_projection_apply_rows(p, 0.61, x, y, work, 0);
    for (long i = 0; i < nout; i++)
        if (!mask || mask[i]) ck_assert_mem_eq(&y[i], &ref[i], sizeof *y);
        else ck_assert(isnan(y[i]));
    /* the adjoint side by side */
    tu_randn(y, nout, seed + 2);
    tu_randn(u, nin, seed + 3);
    memcpy(v, u, nin * sizeof *u);
    wt_projection_apply_t(p, 1.7, y, u);
    wt_projection_apply_t_side(p, 1.7, y, v);
    ck_assert_mem_eq(u, v, nin * sizeof *u);
    free(x), free(y), free(ref), free(work), free(u), free(v);
}

START_TEST(test_rows_and_side_bits)
{
    wt_context *ctx = tu_context();
    /* the fitting: 169² samples every 0.25 m in the 42 m pupil, 9 layers of 128² at 0.5 m up to 18 km, and the
     * DMs (85² at 0.5 m, 47² and 53² at 1 m, clamped) along the field's corner and centre directions */
    const wt_grid fine = wt_grid_centred(169, 0.25);
    uint8_t *pm = malloc(169 * 169);
    wt_pupil_mask_points(42.0, 0.28, &fine, pm);
    const double alts9[9] = {47.0, 140.0, 281.0, 562.0, 1125.0, 2250.0, 4500.0, 9000.0, 18000.0};
    wt_grid g9[9];
    for (int l = 0; l < 9; l++) g9[l] = wt_grid_layer(128, 0.5);
    const double dirs[3][2] = {{-60 * ARCSEC, 60 * ARCSEC}, {0.0, 0.0}, {30 * ARCSEC, -17 * ARCSEC}};
    for (int d = 0; d < 3; d++)
        for (int nl = 1; nl <= 9; nl += (nl < 4 ? 1 : 5)) { /* 1, 2, 3, 4, 9 */
            wt_projection *p = make(ctx, nl, g9 + 9 - nl, alts9 + 9 - nl, 0.0, dirs[d][0], dirs[d][1], &fine, pm, 0);
            check_rows_side(p, pm, 100 + 10 * d + nl);
            wt_projection_free(p);
        }
    const wt_grid dm[3] = {wt_grid_centred(85, 0.5), wt_grid_centred(47, 1.0), wt_grid_centred(53, 1.0)};
    const double dmh[3] = {0.0, 4000.0, 12700.0};
    for (int d = 0; d < 3; d++) {
        wt_projection *p = make(ctx, 3, dm, dmh, 0.0, dirs[d][0] * 1.41, dirs[d][1] * 1.41, &fine, pm, 1);
        check_rows_side(p, pm, 200 + d);
        wt_projection_free(p);
    }
    /* the LGS cone on the corners, 0.5 and 1 m layers; clamped (no mask) and covered (mask) */
    uint8_t mask[85 * 85];
    const wt_grid t = corner_grid(mask);
    wt_grid g[6];
    double h[6];
    mixed_layers(g, h);
    for (int clamp = 0; clamp <= 1; clamp++) {
        wt_projection *p = make(ctx, 6, g, h, clamp ? 0.0 : 90000.0, 25 * ARCSEC, -40 * ARCSEC, &t, clamp ? NULL : mask, clamp);
        check_rows_side(p, clamp ? NULL : mask, 300 + clamp);
        wt_projection_free(p);
    }
    /* 33 small layers, clamped */
    wt_grid g33[33];
    double h33[33];
    for (int l = 0; l < 33; l++) g33[l] = wt_grid_layer(32, 1.0), h33[l] = 300.0 * l;
    wt_projection *p = make(ctx, 33, g33, h33, 0.0, 10 * ARCSEC, 20 * ARCSEC, &t, mask, 1);
    check_rows_side(p, mask, 400);
    wt_projection_free(p);
    free(pm);
    wt_context_free(ctx);
}
END_TEST

/* The single-precision forms (wt_projection_apply_f32, _apply_t_f32) against the double ones, element by element,
 * with bounds from float's unit roundoff u = 2^-24 (the double results are exact by comparison):
 *   apply: a point's value is y0 + Σ over L layers of a term of 4 products of a rounded layer value (u), rounded
 *     weights (2u) and α's product with the row weight (u), summed in 3 adds, the L terms added in turn: each
 *     product's error ≤ 6u of its size and the sums add ≤ (L + 3) u of the absolute sum, so
 *       |y32 − y64| ≤ (L + 9) u (|y0| + |α| (|P| |x|))            (|P| |x| from the assembled matrix);
 *   apply_t: a layer value is either the scalar column-pair sums (as the double form) or, on narrow layers, the
 *     two-pass form: U = Σ over the ≤ 4 target rows of its layer row of a·y (a = α × row weight, each add ≤ u of
 *     the running |sum|), then Σ over ≤ 8 entries of w U (≤ 9 u of Σ|w||U|), added to v0 (u); with |a|, |w| ≤ |α|, 1
 *     and ≤ 8 · 4 = 32 terms of |α| max|y| per layer value, its error ≤ u (|v0| + |α| max|y| (32 · (4 + 9) + …)),
 *     and the scalar form's sums of ≤ 6 points per column pair bound the same way, so
 *       |v32 − v64| ≤ u (2 |v0| + 1600 |α| max|y|),
 *     loose against a typical rounding but not against a missing term, a wrong weight or a column off by one
 *     (errors of O(|α| |y|)).
 * Geometries: the LGS cone on the 0.5 m corners with its 0.5 m ground layer aligned and two 1 m layers (the
 * AVX-512 blocks where the machine has them), an NGS, the unmasked grid, the six mixed layers (0.5 m layers
 * under 0.5 m points at a cone factor: not narrow, the scalar forms), a clamped pair over a small layer's edge,
 * and runs shorter than a block (a 9-point-wide mask). */
static void check_f32(const wt_projection *p, unsigned long seed)
{
    const long nin = wt_projection_nin(p), nout = wt_projection_nout(p);
    const double u = ldexp(1.0, -24), alpha = -0.83;
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_projection_assemble(p, &A), WT_OK);
    double *x = malloc(nin * sizeof *x), *y = malloc(nout * sizeof *y), *ax = calloc(nout, sizeof *ax);
    float *x32 = malloc(nin * sizeof *x32), *y32 = malloc(nout * sizeof *y32);
    tu_randn(x, nin, seed);
    tu_randn(y, nout, seed + 1);
    for (long i = 0; i < nin; i++) x[i] = x32[i] = (float)x[i]; /* the same inputs on both sides */
    for (long i = 0; i < nout; i++) y[i] = y32[i] = (float)y[i];
    for (int64_t c = 0; c < A->ncol; c++) /* |P| |x| */
        for (int64_t k = A->colptr[c]; k < A->colptr[c + 1]; k++) ax[A->rowind[k]] += fabs(A->val[k] * x[c]);
    long maxnnz = 0; /* the layers a point reads: 4 stencil entries each */
    {
        long *cnt = calloc(nout, sizeof *cnt);
        for (int64_t k = 0; k < A->colptr[A->ncol]; k++) cnt[A->rowind[k]]++;
        for (long i = 0; i < nout; i++) maxnnz = cnt[i] > maxnnz ? cnt[i] : maxnnz;
        free(cnt);
    }
    const int L = (int)((maxnnz + 3) / 4);
    double *y0 = malloc(nout * sizeof *y0);
    memcpy(y0, y, nout * sizeof *y);
    wt_projection_apply(p, alpha, x, y);
    wt_projection_apply_f32(p, (float)alpha, x32, y32);
    ck_assert(tu_norm(ax, nout) > 0.0);
    for (long i = 0; i < nout; i++)
        ck_assert_msg(fabs(y32[i] - y[i]) <= (L + 9) * u * (fabs(y0[i]) + fabs(alpha) * ax[i]),
                      "apply_f32 point %ld: %.9g vs %.9g (bound %.3g)", i, y32[i], y[i],
                      (L + 9) * u * (fabs(y0[i]) + fabs(alpha) * ax[i]));
    /* the transpose */
    double *v = malloc(nin * sizeof *v), *v0 = malloc(nin * sizeof *v0);
    float *v32 = malloc(nin * sizeof *v32);
    tu_randn(y, nout, seed + 2);
    tu_randn(v, nin, seed + 3);
    double ymax = 0.0;
    for (long i = 0; i < nout; i++) y[i] = y32[i] = (float)y[i], ymax = fmax(ymax, fabs(y[i]));
    for (long i = 0; i < nin; i++) v[i] = v0[i] = v32[i] = (float)v[i];
    wt_projection_apply_t(p, alpha, y, v);
    wt_projection_apply_t_f32(p, (float)alpha, y32, v32);
    double moved = 0.0;
    for (long i = 0; i < nin; i++) {
        moved = fmax(moved, fabs(v[i] - v0[i]));
        ck_assert_msg(fabs(v32[i] - v[i]) <= u * (2.0 * fabs(v0[i]) + 1600.0 * fabs(alpha) * ymax),
                      "apply_t_f32 layer point %ld: %.9g vs %.9g", i, v32[i], v[i]);
    }
    ck_assert(moved > 0.1); /* the transpose did something */
    wt_sparse_free(A);
    free(x), free(y), free(ax), free(x32), free(y32), free(y0), free(v), free(v0), free(v32);
}

START_TEST(test_single_precision)
{
    wt_context *ctx = tu_context();
    wt_grid g[3];
    layers3(g);
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    wt_projection *ps[6];
    ps[0] = make(ctx, 3, g, alts3, 90000.0, 30 * ARCSEC, -20 * ARCSEC, &t, mask, 0);
    ps[1] = make(ctx, 3, g, alts3, 0.0, -45 * ARCSEC, 60 * ARCSEC, &t, mask, 0);
    ps[2] = make(ctx, 3, g, alts3, 0.0, 10 * ARCSEC, 0.0, &t, NULL, 0);
    wt_grid g6[6];
    double h6[6];
    mixed_layers(g6, h6);
    ps[3] = make(ctx, 6, g6, h6, 90000.0, 25 * ARCSEC, -40 * ARCSEC, &t, mask, 0);
    wt_grid small[2] = {wt_grid_centred(41, 0.5), wt_grid_layer(32, 1.0)};
    double hs[2] = {0.0, 9000.0};
    ps[4] = make(ctx, 2, small, hs, 90000.0, 25 * ARCSEC, 5 * ARCSEC, &t, mask, 1);
    /* runs of 9 points: every block is a masked short one */
    uint8_t band[85 * 85];
    for (int i = 0; i < 85 * 85; i++) band[i] = (uint8_t)(i % 85 >= 30 && i % 85 < 39);
    ps[5] = make(ctx, 3, g, alts3, 90000.0, 30 * ARCSEC, -20 * ARCSEC, &t, band, 0);
    for (int k = 0; k < 6; k++) {
        check_f32(ps[k], 500 + 10 * (unsigned long)k);
        wt_projection_free(ps[k]);
    }
    /* one layer per projection, as the tomography holds them: each of the LGS stack's */
    for (int l = 0; l < 3; l++) {
        wt_projection *p = make(ctx, 1, &g[l], &alts3[l], 90000.0, 30 * ARCSEC, -20 * ARCSEC, &t, mask, 0);
        check_f32(p, 600 + (unsigned long)l);
        wt_projection_free(p);
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_outside_rejected)
{
    wt_context *ctx = tu_context();
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    /* layer 1 (32 x 32 at 1 m, spanning [-16, 15] m) cannot cover the 42 m pupil */
    wt_grid g[2] = {wt_grid_layer(128, 0.5), wt_grid_layer(32, 1.0)};
    double h[2] = {0.0, 4000.0};
    wt_projection *p = (wt_projection *)&p; /* must be reset to NULL on failure */
    int st = wt_projection_alloc(ctx, 2, g, h, 90000.0, 0.0, 0.0, &t, mask, 0, &p);
    ck_assert_int_eq(st, WT_ERR_INVALID);
    ck_assert_ptr_null(p);
    const char *msg = wt_error_message(ctx);
    ck_assert_msg(strstr(msg, "layer 1") && strstr(msg, "altitude 4000 m") && strstr(msg, "[-16, 15]"), "message: %s", msg);
    /* a point exactly on the last grid line is inside: the 85 x 85 target on an identical layer grid */
    wt_grid same = wt_grid_centred(85, 0.5);
    double h0 = 0.0;
    double *v = malloc(85 * 85 * sizeof *v), *y = calloc(85 * 85, sizeof *y);
    tu_randn(v, 85 * 85, 3);
    p = make(ctx, 1, &same, &h0, 0.0, 0.0, 0.0, &same, NULL, 0);
    wt_projection_apply(p, 1.0, v, y);
    for (int k = 0; k < 85 * 85; k++) ck_assert(y[k] == v[k]);
    check_adjoint(p, 5);
    check_assembled(p, 6); /* assembly rejects any stencil index beyond the layer, even at weight 0 */
    wt_projection_free(p);
    /* a millimetre further (0.002 cells, beyond rounding slack) is not */
    wt_grid shifted = same;
    shifted.x0 += 1e-3;
    ck_assert_int_eq(wt_projection_alloc(ctx, 1, &shifted, &h0, 0.0, 0.0, 0.0, &same, NULL, 0, &p), WT_ERR_INVALID);
    ck_assert(strstr(wt_error_message(ctx), "layer 0"));
    /* bad arguments */
    double hbad = 95000.0;
    ck_assert_int_eq(wt_projection_alloc(ctx, 1, &g[0], &hbad, 90000.0, 0.0, 0.0, &t, mask, 0, &p), WT_ERR_INVALID);
    ck_assert_int_eq(wt_projection_alloc(ctx, 0, g, h, 0.0, 0.0, 0.0, &t, mask, 0, &p), WT_ERR_INVALID);
    wt_grid one = {1, 5, 1.0, 0.0, 0.0};
    ck_assert_int_eq(wt_projection_alloc(ctx, 1, &one, &h0, 0.0, 0.0, 0.0, &t, mask, 0, &p), WT_ERR_INVALID);
    ck_assert_int_eq(wt_projection_alloc(ctx, 1, &g[0], &h0, 0.0, NAN, 0.0, &t, mask, 0, &p), WT_ERR_INVALID);
    free(v), free(y);
    wt_context_free(ctx);
}
END_TEST

/* hat function of linear interpolation: the weight of a grid point t cells away */
static double hat(double t) { return fmax(0.0, 1.0 - fabs(t)); }

START_TEST(test_clamp)
{
    /* A 41 x 41 layer at 0.5 m spanning [-10, 10] m, seen shifted by θh = (0.1, −0.35) m, so that the
     * edge stencils have unequal weights (0.2/0.8, 0.7/0.3). With clamp_outside the result must be the
     * interpolation of the zero-extended layer, computed independently as Σ_ij v_ij hat(Δx) hat(Δy).
     * Both evaluate the same two-term sums per axis: 1e-13 relative to the O(1) values. */
    wt_context *ctx = tu_context();
    wt_grid g = wt_grid_centred(41, 0.5), t = wt_grid_centred(85, 0.5);
    double h = 1000.0, thx = 0.1 / h, thy = -0.35 / h;
    double *v = malloc(41 * 41 * sizeof *v), *y = calloc(85 * 85, sizeof *y);
    tu_randn(v, 41 * 41, 17);
    wt_projection *p = NULL;
    ck_assert_int_eq(wt_projection_alloc(ctx, 1, &g, &h, 0.0, thx, thy, &t, NULL, 0, &p), WT_ERR_INVALID);
    p = make(ctx, 1, &g, &h, 0.0, thx, thy, &t, NULL, 1);
    wt_projection_apply(p, 1.0, v, y);
    int zero = 0;
    for (int iy = 0; iy < 85; iy++)
        for (int ix = 0; ix < 85; ix++) {
            double X = t.x0 + ix * t.dx + thx * h, Y = t.y0 + iy * t.dx + thy * h, want = 0.0;
            for (int j = 0; j < 41; j++) {
                double hy = hat((Y - (g.y0 + j * g.dx)) / g.dx);
                if (hy == 0.0) continue;
                for (int i = 0; i < 41; i++) want += v[i + 41 * j] * hat((X - (g.x0 + i * g.dx)) / g.dx) * hy;
            }
            ck_assert_rel(y[ix + 85 * iy], want, 1e-13, 1.0);
            zero += y[ix + 85 * iy] == 0.0;
        }
    /* per axis 40 target points sample inside [-10, 10] and one on each side partly: 42 x 42 lit */
    ck_assert_int_eq(zero, 85 * 85 - 42 * 42);
    wt_projection_free(p);
    free(v), free(y);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_allocation)
{
    /* Every allocation failure in alloc and assemble is reported as WT_ERR_NOMEM and leaks nothing;
     * apply and apply_t allocate nothing. */
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    wt_grid g[3];
    layers3(g);
    uint8_t mask[85 * 85];
    wt_grid t = corner_grid(mask);
    int k, ok = 0;
    for (k = 0; k < 100 && !ok; k++) {
        wt_projection *p = (wt_projection *)&p;
        tu_alloc_budget(&fa, k);
        int st = wt_projection_alloc(ctx, 3, g, alts3, 90000.0, 30 * ARCSEC, 0.0, &t, mask, 0, &p);
        if (st == WT_OK) {
            ok = 1;
            tu_alloc_budget(&fa, -1);
            long nin = wt_projection_nin(p);
            double *x = calloc(nin, sizeof *x), *y = calloc(85 * 85, sizeof *y);
            long before = fa.nalloc;
            wt_projection_apply(p, 1.0, x, y);
            wt_projection_apply_t(p, 1.0, y, x);
            ck_assert_int_eq(fa.nalloc, before);
            TU_ASSEMBLE_UNDER_BUDGETS(&fa, A, wt_projection_assemble(p, &A));
            wt_projection_free(p);
            free(x), free(y);
        } else {
            ck_assert_int_eq(st, WT_ERR_NOMEM);
            ck_assert_ptr_null(p);
        }
        ck_assert_int_eq(fa.live, 0);
    }
    ck_assert_msg(ok && k > 5, "alloc never succeeded or made too few allocations (%d)", k);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("projection");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_adjoint_and_assembly);
    tcase_add_test(tc, test_masked_points_untouched);
    tcase_add_test(tc, test_ground_layer_same_everywhere);
    tcase_add_test(tc, test_cone_and_shift);
    tcase_add_test(tc, test_layers_per_point_bits);
    tcase_add_test(tc, test_aligned_layer_bits);
    tcase_add_test(tc, test_rows_and_side_bits);
    tcase_add_test(tc, test_single_precision);
    tcase_add_test(tc, test_outside_rejected);
    tcase_add_test(tc, test_clamp);
    tcase_add_test(tc, test_allocation);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
