/* tests/test_shack_hartmann.c: the Fried model Γ and the averaged NGS sensors (SPEC §4): adjoint,
 * assembly, exactness on linear and quadratic phases, averaging, masks, centres, errors; the fp32 forms
 * against the double ones. */
#include "testutil.h"

#include "core/la/sparse.h"
#include "core/op/pupil.h"
#include "core/op/shack_hartmann.h"

#define N 84
#define D_SUB 0.5

static void eelt_valid(uint8_t *v) { ck_assert_int_eq(wt_pupil_valid_subapertures(42.0, 0.28, N, 0.5, v), 5112); }

static wt_shack_hartmann *make(wt_context *ctx, int n, double d, const uint8_t *v, int m)
{
    wt_shack_hartmann *s = NULL;
    int st = m ? wt_shack_hartmann_alloc_averaged(ctx, n, d, v, m, &s) : wt_shack_hartmann_alloc(ctx, n, d, v, &s);
    ck_assert_msg(st == WT_OK, "alloc failed: %s", wt_error_message(ctx));
    return s;
}

/* φ(x, y) on the corner grid of an n x n sensor of side d (corner (i, j) at (−nd/2 + i d, …)) */
static void fill_phase(int n, double d, double *phi, double a, double b, double cxx, double cxy, double cyy, double p)
{
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            double x = -0.5 * n * d + i * d, y = -0.5 * n * d + j * d;
            phi[i + (n + 1) * j] = a * x + b * y + cxx * x * x + cxy * x * y + cyy * y * y + p;
        }
}

START_TEST(test_counts_and_masks)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N], c[(N + 1) * (N + 1)];
    eelt_valid(v);
    wt_shack_hartmann *s = make(ctx, N, D_SUB, v, 0);
    ck_assert_int_eq(wt_shack_hartmann_nsub(s), 5112);
    ck_assert_int_eq(wt_shack_hartmann_nslopes(s), 10224);
    ck_assert_int_eq(wt_shack_hartmann_ncorners(s), 85 * 85);
    wt_pupil_corner_mask(N, v, c);
    ck_assert_mem_eq(wt_shack_hartmann_corner_mask(s), c, sizeof c);
    /* centre of the first valid subaperture: row j = 0 is empty; the first valid cell in index order
     * decides it, so recompute from the mask */
    int first = 0;
    while (!v[first]) first++;
    double x, y;
    wt_shack_hartmann_centre(s, 0, &x, &y);
    ck_assert_rel(x, -21.0 + (first % N + 0.5) * D_SUB, 1e-15, 1.0);
    ck_assert_rel(y, -21.0 + (first / N + 0.5) * D_SUB, 1e-15, 1.0);
    wt_shack_hartmann_centre(s, 5112, &x, &y);
    ck_assert(isnan(x) && isnan(y));
    wt_shack_hartmann_free(s);

    /* averaged 2 x 2 on the E-ELT pupil: all four quadrants are valid, centres at (±10.5, ±10.5) */
    s = make(ctx, N, D_SUB, v, 2);
    ck_assert_int_eq(wt_shack_hartmann_nsub(s), 4);
    const double want[4][2] = {{-10.5, -10.5}, {10.5, -10.5}, {-10.5, 10.5}, {10.5, 10.5}};
    for (int k = 0; k < 4; k++) {
        wt_shack_hartmann_centre(s, k, &x, &y);
        ck_assert_rel(x, want[k][0], 1e-15, 0);
        ck_assert_rel(y, want[k][1], 1e-15, 0);
    }
    wt_shack_hartmann_free(s);

    /* 1 x 1 over a fully valid 4 x 4: the mean x slope telescopes to the right column minus the left
     * column, the mean y slope to top minus bottom, so only the 16 rim corners of the 5 x 5 grid are
     * read and the 9 interior ones drop out exactly. */
    uint8_t full[16], bigc[25];
    memset(full, 1, sizeof full);
    s = make(ctx, 4, 1.0, full, 1);
    memcpy(bigc, wt_shack_hartmann_corner_mask(s), 25);
    int nread = 0;
    for (int k = 0; k < 25; k++) nread += bigc[k];
    ck_assert_int_eq(nread, 16);
    ck_assert(!bigc[6] && !bigc[12] && !bigc[18] && bigc[0] && bigc[4] && bigc[24]);
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_shack_hartmann_assemble(s, &A), WT_OK);
    /* s_x row: corners (4, j) get +1/(2·1·16) · (1 or 2), (0, j) the negatives; (4, 0) and (4, 4) once */
    ck_assert_int_eq(wt_sparse_nnz(A), 2 * 10);
    wt_sparse_free(A);
    wt_shack_hartmann_free(s);
    wt_context_free(ctx);
}
END_TEST

/* ⟨Γφ, s⟩ = ⟨φ, Γᵀs⟩ to ~ n·ε·‖Γφ‖‖s‖ (n ≤ 2·10⁴ terms): 1e-12 relative. */
static void check_adjoint_assembly(const wt_shack_hartmann *s, unsigned long seed)
{
    long nc = wt_shack_hartmann_ncorners(s), ns = wt_shack_hartmann_nslopes(s);
    double *phi = malloc(nc * sizeof *phi), *sl = malloc(ns * sizeof *sl);
    double *gphi = calloc(ns, sizeof *gphi), *gts = calloc(nc, sizeof *gts);
    tu_randn(phi, nc, seed);
    tu_randn(sl, ns, seed + 1);
    wt_shack_hartmann_apply(s, 1.0, phi, gphi);
    wt_shack_hartmann_apply_t(s, 1.0, sl, gts);
    ck_assert(tu_norm(gphi, ns) > 0);
    ck_assert_rel(tu_dot(gphi, sl, ns), tu_dot(phi, gts, nc), 1e-12, tu_norm(gphi, ns) * tu_norm(sl, ns));

    /* apply (accumulating, α ≠ 1) == y0 + α A x: same products summed in another order → 1e-13 */
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_shack_hartmann_assemble(s, &A), WT_OK);
    ck_assert_int_eq(A->nrow, ns);
    ck_assert_int_eq(A->ncol, nc);
    double *y1 = malloc(ns * sizeof *y1), *y2 = malloc(ns * sizeof *y2);
    double *z1 = malloc(nc * sizeof *z1), *z2 = malloc(nc * sizeof *z2);
    tu_randn(y1, ns, seed + 2);
    memcpy(y2, y1, ns * sizeof *y2);
    tu_randn(z1, nc, seed + 3);
    memcpy(z2, z1, nc * sizeof *z2);
    wt_shack_hartmann_apply(s, 2.5, phi, y1);
    wt_sparse_apply(A, 2.5, phi, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, ns), 1e-13);
    wt_shack_hartmann_apply_t(s, -0.4, sl, z1);
    wt_sparse_apply_t(A, -0.4, sl, z2);
    ck_assert_double_le(tu_rel_diff(z1, z2, nc), 1e-13);
    wt_sparse_free(A);
    free(phi), free(sl), free(gphi), free(gts), free(y1), free(y2), free(z1), free(z2);
}

START_TEST(test_adjoint_and_assembly)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    for (int m = 0; m <= 2; m++) { /* Fried, 1 x 1, 2 x 2 */
        wt_shack_hartmann *s = make(ctx, N, D_SUB, v, m);
        check_adjoint_assembly(s, 100 + m);
        wt_shack_hartmann_free(s);
    }
    /* a ragged mask, with a 3 x 3 averaged sensor whose corner block is empty (invalid) */
    uint8_t r[12 * 12];
    wt_rng g;
    wt_rng_init(&g, 9, 0);
    for (int k = 0; k < 144; k++) r[k] = wt_rng_uniform(&g) < 0.6;
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) r[i + 12 * j] = 0;
    wt_shack_hartmann *s = make(ctx, 12, 0.7, r, 3);
    ck_assert_int_eq(wt_shack_hartmann_nsub(s), 8);
    check_adjoint_assembly(s, 200);
    wt_shack_hartmann_free(s);
    s = make(ctx, 12, 0.7, r, 0);
    check_adjoint_assembly(s, 300);
    wt_shack_hartmann_free(s);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_linear_and_quadratic_phase)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    wt_shack_hartmann *s = make(ctx, N, D_SUB, v, 0);
    const int nsub = wt_shack_hartmann_nsub(s);
    double *phi = malloc((N + 1) * (N + 1) * sizeof *phi), *sl = malloc(2 * nsub * sizeof *sl);

    /* tilt + piston: s = (a, b) everywhere. Rounding: φ ~ 21|a| + |p| is differenced over d = 0.5,
     * so errors are ~ ε·(21|a| + |p|)/d ≈ 1e-14 |a| — 1e-12 relative to the slope. */
    const double a = 3.1e-6, b = -1.2e-6;
    fill_phase(N, D_SUB, phi, a, b, 0, 0, 0, 5e-6);
    memset(sl, 0, 2 * nsub * sizeof *sl);
    wt_shack_hartmann_apply(s, 1.0, phi, sl);
    for (int k = 0; k < nsub; k++) {
        ck_assert_rel(sl[k], a, 1e-12, 0);
        ck_assert_rel(sl[nsub + k], b, 1e-12, 0);
    }

    /* Fried is exact at the subaperture centre for quadratics: for x², s_x = 2[(x_c + d/2)² −
     * (x_c − d/2)²]/(2d) = 2 x_c; for xy, s_x = d (y_c − d/2 + y_c + d/2)/(2d) = y_c; y² cancels.
     * Rounding: φ ≤ (|cxx| + |cxy| + |cyy|)·21²·2 differenced over d → ~1e-12 of the slope scale
     * 2·21·(|cxx| + |cxy| + |cyy|). */
    const double cxx = 2e-7, cxy = -3e-7, cyy = 1.5e-7;
    fill_phase(N, D_SUB, phi, a, b, cxx, cxy, cyy, 0);
    memset(sl, 0, 2 * nsub * sizeof *sl);
    wt_shack_hartmann_apply(s, 1.0, phi, sl);
    double scale = 2 * 21 * (fabs(cxx) + fabs(cxy) + fabs(cyy)) + fabs(a) + fabs(b);
    for (int k = 0; k < nsub; k++) {
        double x, y;
        wt_shack_hartmann_centre(s, k, &x, &y);
        ck_assert_rel(sl[k], a + 2 * cxx * x + cxy * y, 1e-12, scale);
        ck_assert_rel(sl[nsub + k], b + cxy * x + 2 * cyy * y, 1e-12, scale);
    }
    free(phi), free(sl);
    wt_shack_hartmann_free(s);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_averaged_is_mean)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    wt_shack_hartmann *fine = make(ctx, N, D_SUB, v, 0);
    const int nf = wt_shack_hartmann_nsub(fine);
    double *phi = malloc((N + 1) * (N + 1) * sizeof *phi), *sf = calloc(2 * nf, sizeof *sf);
    tu_randn(phi, (N + 1) * (N + 1), 77);
    wt_shack_hartmann_apply(fine, 1.0, phi, sf);
    for (int m = 1; m <= 2; m++) {
        wt_shack_hartmann *big = make(ctx, N, D_SUB, v, m);
        const int nb = wt_shack_hartmann_nsub(big);
        ck_assert_int_eq(nb, m * m);
        double *sb = calloc(2 * nb, sizeof *sb), mean[2][4] = {{0}}, cnt[4] = {0};
        wt_shack_hartmann_apply(big, 1.0, phi, sb);
        /* the mean of the fine Fried slopes over the valid cells of each big subaperture */
        for (int k = 0; k < nf; k++) {
            double x, y;
            wt_shack_hartmann_centre(fine, k, &x, &y);
            int I = (int)floor((x + 21.0) / (42.0 / m)), J = (int)floor((y + 21.0) / (42.0 / m));
            mean[0][I + m * J] += sf[k];
            mean[1][I + m * J] += sf[nf + k];
            cnt[I + m * J] += 1;
        }
        /* the averaged rows are the same sum reordered (telescoped terms cancelled exactly, from
         * integer counts): the difference is ≲ ε·Σ|terms|/count ≈ ε·max|s_fine| ≈ 1e-15 for these
         * O(1) slopes (unit-variance phase over d = 0.5 m) — asserted to 1e-12 absolute */
        for (int q = 0; q < nb; q++) {
            ck_assert_rel(sb[q], mean[0][q] / cnt[q], 1e-12, 1.0);
            ck_assert_rel(sb[nb + q], mean[1][q] / cnt[q], 1e-12, 1.0);
        }
        /* a tilt is seen exactly */
        double *tilt = malloc((N + 1) * (N + 1) * sizeof *tilt);
        fill_phase(N, D_SUB, tilt, 2e-6, -7e-7, 0, 0, 0, 1e-6);
        memset(sb, 0, 2 * nb * sizeof *sb);
        wt_shack_hartmann_apply(big, 1.0, tilt, sb);
        for (int q = 0; q < nb; q++) {
            ck_assert_rel(sb[q], 2e-6, 1e-12, 0);
            ck_assert_rel(sb[nb + q], -7e-7, 1e-12, 0);
        }
        free(tilt), free(sb);
        wt_shack_hartmann_free(big);
    }
    free(phi), free(sf);
    wt_shack_hartmann_free(fine);
    wt_context_free(ctx);
}
END_TEST

/* The lit-area average model (SPEC §4, recon.sensor_model = "lit"): adjoint and assembly; a tilt is
 * measured exactly in every subaperture, the partly lit ones included (each lit cell's gradient is the
 * tilt, and the weights sum to one); on a bilinear phase of the coarse grid sampled q times finer, a
 * fully lit subaperture gives the Fried slope (the mean gradient of a bilinear cell is its Fried
 * difference, and the q² sub-cells of a lit square have equal weights). */
START_TEST(test_lit_model)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    for (int q = 1; q <= 3; q++)
        for (int m = 0; m <= 2; m++) {
            wt_shack_hartmann *s = NULL;
            ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, q, v, m, WT_SH_TILT_G, &s), WT_OK);
            ck_assert_int_eq(wt_shack_hartmann_nsub(s), m == 0 ? 5112 : m * m);
            ck_assert_int_eq(wt_shack_hartmann_ncorners(s), (N * q + 1) * (N * q + 1));
            check_adjoint_assembly(s, 400 + 10 * q + m);
            const int nq = N * q, nc = (nq + 1) * (nq + 1), ns = wt_shack_hartmann_nslopes(s), nsub = ns / 2;
            double *phi = malloc(nc * sizeof *phi), *sl = calloc(ns, sizeof *sl);
            fill_phase(nq, D_SUB / q, phi, 3e-6, -2e-6, 0, 0, 0, 1e-6);
            wt_shack_hartmann_apply(s, 1.0, phi, sl);
            for (int k = 0; k < nsub; k++) {
                ck_assert_double_eq_tol(sl[k], 3e-6, 1e-15);
                ck_assert_double_eq_tol(sl[nsub + k], -2e-6, 1e-15);
            }
            free(phi), free(sl);
            wt_shack_hartmann_free(s);
        }
    /* fully lit subapertures: lit(q) of the q-refined bilinear interpolant = Fried on the corners */
    wt_shack_hartmann *f = make(ctx, N, D_SUB, v, 0), *l = NULL;
    const int q = 2, nq = N * q;
    ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, q, v, 0, WT_SH_TILT_G, &l), WT_OK);
    double *pc = malloc((N + 1) * (N + 1) * sizeof *pc), *pf = malloc((nq + 1) * (nq + 1) * sizeof *pf);
    double *sf = calloc(2 * 5112, sizeof *sf), *sl = calloc(2 * 5112, sizeof *sl);
    tu_randn(pc, (N + 1) * (N + 1), 77);
    for (int j = 0; j <= nq; j++)
        for (int i = 0; i <= nq; i++) {
            int I = i / q < N ? i / q : N - 1, J = j / q < N ? j / q : N - 1;
            double u = (double)(i - I * q) / q, w = (double)(j - J * q) / q;
            const double *c = pc + I + (N + 1) * J;
            pf[i + (nq + 1) * j] = (1 - u) * (1 - w) * c[0] + u * (1 - w) * c[1] + (1 - u) * w * c[N + 1] + u * w * c[N + 2];
        }
    wt_shack_hartmann_apply(f, 1.0, pc, sf);
    wt_shack_hartmann_apply(l, 1.0, pf, sl);
    int full = 0;
    for (int k = 0; k < 5112; k++) {
        double x, y;
        wt_shack_hartmann_centre(f, k, &x, &y);
        double rmax = hypot(fabs(x) + 0.25, fabs(y) + 0.25), rmin = hypot(fmax(fabs(x) - 0.25, 0), fmax(fabs(y) - 0.25, 0));
        if (rmax > 21.0 || rmin < 0.28 * 21.0) continue; /* partly lit: the models differ there, by design */
        full++;
        ck_assert_double_eq_tol(sl[k], sf[k], 1e-12 * (fabs(sf[k]) + 1));
        ck_assert_double_eq_tol(sl[5112 + k], sf[5112 + k], 1e-12 * (fabs(sf[5112 + k]) + 1));
    }
    ck_assert_int_gt(full, 4000);
    free(pc), free(pf), free(sf), free(sl);
    wt_shack_hartmann_free(f);
    wt_shack_hartmann_free(l);
    wt_context_free(ctx);
}
END_TEST

/* The lit sensor with one sample per subaperture (the reconstructor's model) runs its own kernels over
 * runs of cells (shack_hartmann.c, quad_setup): they must give the CSR rows' results bit for bit (the
 * same additions in the same order, the transpose's per-corner order included), on the E-ELT pupil
 * (partly lit rim cells, central obstruction) and on a mask with random holes, for any α and any
 * starting y. */
/* slopes += α Γ phase (transpose 0) or phase += α Γᵀ slopes (transpose 1), by the CSR rows in order */
static void csr_reference(const wt_shack_hartmann *s, double alpha, double *phase, double *slopes, int transpose)
{
    const int32_t *rp, *col;
    const double *val;
    wt_shack_hartmann_csr(s, &rp, &col, &val);
    for (int r = 0; r < wt_shack_hartmann_nslopes(s); r++) {
        if (transpose) {
            const double t = alpha * slopes[r];
            for (int32_t q = rp[r]; q < rp[r + 1]; q++) phase[col[q]] += val[q] * t;
        } else {
            double acc = 0.0;
            for (int32_t q = rp[r]; q < rp[r + 1]; q++) acc += val[q] * phase[col[q]];
            slopes[r] += alpha * acc;
        }
    }
}

/* Z-tilt rows (ngs.wfs.tilt = "z"): the least-squares plane of the lit area. On a plane a + bx + cy both
 * tilts are (b, c) exactly (the normal equations reproduce any plane). On φ = x³ over a whole annulus of
 * radii R, r they differ, analytically: the G-tilt is the mean of 3x², 3(R² + r²)/4; the Z-tilt is
 * ∫x⁴/∫x² = (R⁶ − r⁶)/(2(R⁴ − r⁴)). The discrete sensors sample the lit area with cells of side δ (exact
 * lit fractions, corner weights by the trapezoid rule): the quadrature error is O(δ/R), so the test asks
 * |error| ≤ 2 δ/R of the value at 4 and 8 samples per subaperture, and that it shrinks with δ. */
START_TEST(test_ztilt_rows)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    const double R = 21.0, r = 0.28 * 21.0;
    const double gz = 3.0 * (R * R + r * r) / 4.0, zz = (pow(R, 6) - pow(r, 6)) / (2.0 * (pow(R, 4) - pow(r, 4)));
    double err_prev = INFINITY;
    for (int q = 1; q <= 4; q *= 2)
        for (int m = 1; m <= 2; m++) {
            wt_shack_hartmann *s = NULL;
            ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, q, v, m, WT_SH_TILT_Z, &s), WT_OK);
            check_adjoint_assembly(s, 500 + 10 * q + m);
            const int nq = N * q, nc = (nq + 1) * (nq + 1), ns = wt_shack_hartmann_nslopes(s), nsub = ns / 2;
            double *phi = malloc(nc * sizeof *phi), *sl = calloc(ns, sizeof *sl);
            fill_phase(nq, D_SUB / q, phi, 3e-6, -2e-6, 0, 0, 0, 1e-6);
            wt_shack_hartmann_apply(s, 1.0, phi, sl);
            for (int k = 0; k < nsub; k++) {
                ck_assert_double_eq_tol(sl[k], 3e-6, 1e-15);
                ck_assert_double_eq_tol(sl[nsub + k], -2e-6, 1e-15);
            }
            if (m == 1) {
                /* φ = x³ (units of R): whole pupil, one subaperture; G-tilt from the G rows on the same samples */
                const double dq = D_SUB / q;
                for (int j = 0; j <= nq; j++)
                    for (int i = 0; i <= nq; i++) phi[i + (nq + 1) * j] = pow(-0.5 * nq * dq + i * dq, 3);
                wt_shack_hartmann *g = NULL;
                ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, q, v, 1, WT_SH_TILT_G, &g), WT_OK);
                double sz[2] = {0, 0}, sg[2] = {0, 0};
                wt_shack_hartmann_apply(s, 1.0, phi, sz);
                wt_shack_hartmann_apply(g, 1.0, phi, sg);
                const double tol = 2.0 * dq / R, ez = fabs(sz[0] / zz - 1.0);
                ck_assert_msg(ez <= tol, "q = %d: Z-tilt of x^3 %g, analytic %g (rel. error %g > %g)", q, sz[0], zz, ez, tol);
                ck_assert_msg(fabs(sg[0] / gz - 1.0) <= tol, "q = %d: G-tilt of x^3 %g, analytic %g", q, sg[0], gz);
                ck_assert_double_le(fabs(sz[1]), 1e-9 * zz); /* no y part by symmetry */
                ck_assert_double_le(ez, err_prev);
                err_prev = ez;
                wt_shack_hartmann_free(g);
            }
            free(phi), free(sl);
            wt_shack_hartmann_free(s);
        }
    wt_shack_hartmann *s = NULL;
    ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, 1, v, 1, 2, &s), WT_ERR_INVALID);
    ck_assert_ptr_null(s);
    wt_context_free(ctx);
}
END_TEST

/* The E-ELT mask with ~16 % of its cells removed: short and single-cell runs */
static void holed_valid(uint8_t *v)
{
    double r[N * N];
    eelt_valid(v);
    tu_randn(r, N * N, 91);
    for (int k = 0; k < N * N; k++) v[k] = v[k] && r[k] > -1.0;
}

START_TEST(test_lit_runs_equal_csr)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    for (int mask = 0; mask < 2; mask++) {
        if (mask) holed_valid(v);
        else eelt_valid(v);
        wt_shack_hartmann *s = NULL;
        ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, 1, v, 0, WT_SH_TILT_G, &s), WT_OK);
        const int nc = wt_shack_hartmann_ncorners(s), ns = wt_shack_hartmann_nslopes(s);
        double *phi = malloc(nc * sizeof *phi), *p1 = malloc(nc * sizeof *p1), *p2 = malloc(nc * sizeof *p2);
        double *sl = malloc(ns * sizeof *sl), *s1 = malloc(ns * sizeof *s1), *s2 = malloc(ns * sizeof *s2);
        tu_randn(phi, nc, 92 + mask);
        tu_randn(sl, ns, 94 + mask);
        const double alphas[3] = {1.0, -0.37, 2.5e3};
        for (int a = 0; a < 3; a++) {
            tu_randn(s1, ns, 96 + a); /* y ← y + α Γ φ from a non-zero y */
            memcpy(s2, s1, ns * sizeof *s1);
            wt_shack_hartmann_apply(s, alphas[a], phi, s1);
            csr_reference(s, alphas[a], phi, s2, 0);
            ck_assert_mem_eq(s1, s2, ns * sizeof *s1);
            for (int z = 0; z < 2; z++) { /* from zero (as the reconstructor) and from a random phase */
                if (z) tu_randn(p1, nc, 98 + a);
                else memset(p1, 0, nc * sizeof *p1);
                memcpy(p2, p1, nc * sizeof *p1);
                wt_shack_hartmann_apply_t(s, alphas[a], sl, p1);
                csr_reference(s, alphas[a], p2, sl, 1);
                ck_assert_mem_eq(p1, p2, nc * sizeof *p1);
            }
        }
        free(phi), free(p1), free(p2), free(sl), free(s1), free(s2);
        wt_shack_hartmann_free(s);
    }
    wt_context_free(ctx);
}
END_TEST

/* The fp32 forms (wt_shack_hartmann_apply_f32, _apply_t_f32) against the double ones: the same operator to
 * float accuracy. The inputs are floats (x, the starting output y0 and α exactly representable in both), so
 * the difference is the float kernels' rounding alone, bounded per output o by c_o ε S_o, ε = 2^-24,
 * S_o = |y0_o| + |α| Σ_q |A_oq| |x_q| with A_oq the double operator's entries in o's row (Γ) or column (Γᵀ).
 * Counting the roundings each term goes through (each a relative ε) and ε |partial| ≤ ε S_o per
 * accumulation into the output:
 *  - run kernels (Fried; lit q = 1, scaled by its u_k rounded to float): apply at most 5 per term (u or
 *    α/(2d) to float, α u, a corner difference, the diagonals' sum or difference, the product) and one
 *    accumulation; apply_t 5 (u to float, s_x ± s_y, times u, the two cells' combination, times α) and
 *    two accumulations (a corner row is the top of one cell row's runs and the bottom of the next's):
 *    ≤ 7 ε S_o, asserted with c = 8;
 *  - CSR rows of L entries: coefficient to float, product, L − 1 additions, α, accumulation: (L + 3) ε S_o;
 *    a column of K entries: α s, coefficient, product, K accumulations: (K + 3) ε S_o; c = entries + 4.
 * The spare ε S_o covers the O(ε²) terms and the double results' own rounding (2^-53 per operation). */
static void f32_bounds(const wt_sparse *A, int transpose, int runs, double alpha, const double *x, const double *y0,
                       double *B, long nout)
{
    int *cnt = calloc(nout, sizeof *cnt);
    for (long o = 0; o < nout; o++) B[o] = 0.0;
    for (int64_t c = 0; c < A->ncol; c++)
        for (int64_t e = A->colptr[c]; e < A->colptr[c + 1]; e++) {
            const int64_t o = transpose ? c : A->rowind[e], i = transpose ? A->rowind[e] : c;
            B[o] += fabs(alpha * A->val[e] * x[i]);
            cnt[o]++;
        }
    for (long o = 0; o < nout; o++) B[o] = (runs ? 8 : cnt[o] + 4) * 0x1p-24 * (fabs(y0[o]) + B[o]);
    free(cnt);
}

static void randn_f32(float *x32, double *x64, long n, unsigned long seed)
{
    tu_randn(x64, n, seed);
    for (long k = 0; k < n; k++) x64[k] = x32[k] = (float)x64[k];
}

/* runs: the sensor applies through its run kernels (Fried, lit q = 1), else through its CSR rows */
static void check_f32(const wt_shack_hartmann *s, int runs, unsigned long seed)
{
    const long nc = wt_shack_hartmann_ncorners(s), ns = wt_shack_hartmann_nslopes(s);
    wt_sparse *A = NULL;
    ck_assert_int_eq(wt_shack_hartmann_assemble(s, &A), WT_OK);
    float *x32 = malloc(nc * sizeof *x32), *s32 = malloc(ns * sizeof *s32), *y32 = malloc(ns * sizeof *y32),
          *p32 = malloc(nc * sizeof *p32);
    double *x = malloc(nc * sizeof *x), *sl = malloc(ns * sizeof *sl), *y = malloc(ns * sizeof *y),
           *p = malloc(nc * sizeof *p), *y0 = malloc(ns * sizeof *y0), *p0 = malloc(nc * sizeof *p0),
           *By = malloc(ns * sizeof *By), *Bp = malloc(nc * sizeof *Bp);
    randn_f32(x32, x, nc, seed);
    randn_f32(s32, sl, ns, seed + 1);
    const float alphas[2] = {-0.7f, 3.25e2f};
    for (int a = 0; a < 2; a++) {
        const float alpha = alphas[a];
        /* 1. slopes: y0 + α Γ x from a non-zero y0 */
        randn_f32(y32, y0, ns, seed + 2 + a);
        memcpy(y, y0, ns * sizeof *y);
        wt_shack_hartmann_apply_f32(s, alpha, x32, y32);
        wt_shack_hartmann_apply(s, alpha, x, y);
        f32_bounds(A, 0, runs, alpha, x, y0, By, ns);
        for (long r = 0; r < ns; r++)
            ck_assert_msg(fabs(y32[r] - y[r]) <= By[r], "apply_f32 (alpha %g): slope %ld is %.9g, double %.17g (bound %.3g)",
                          alpha, r, y32[r], y[r], By[r]);
        /* 2. corners: p0 + α Γᵀ s from a non-zero p0 */
        randn_f32(p32, p0, nc, seed + 4 + a);
        memcpy(p, p0, nc * sizeof *p);
        wt_shack_hartmann_apply_t_f32(s, alpha, s32, p32);
        wt_shack_hartmann_apply_t(s, alpha, sl, p);
        f32_bounds(A, 1, runs, alpha, sl, p0, Bp, nc);
        for (long c = 0; c < nc; c++)
            ck_assert_msg(fabs(p32[c] - p[c]) <= Bp[c], "apply_t_f32 (alpha %g): corner %ld is %.9g, double %.17g (bound %.3g)",
                          alpha, c, p32[c], p[c], Bp[c]);
    }
    /* 3. ⟨Γ32 x, s⟩ = ⟨x, Γ32ᵀ s⟩: each side is within Σ_o |other vector_o| B_o (the bounds above with y0 = 0,
     * α = 1) of the exact ⟨Γx, s⟩; the double dot products add ≤ n 2^-53 Σ|terms| each, Σ|terms| =
     * Σ_rq |s_r| |Γ_rq| |x_q| */
    memset(y32, 0, ns * sizeof *y32);
    memset(p32, 0, nc * sizeof *p32);
    memset(y0, 0, ns * sizeof *y0);
    memset(p0, 0, nc * sizeof *p0);
    wt_shack_hartmann_apply_f32(s, 1.0f, x32, y32);
    wt_shack_hartmann_apply_t_f32(s, 1.0f, s32, p32);
    f32_bounds(A, 0, runs, 1.0, x, y0, By, ns);
    f32_bounds(A, 1, runs, 1.0, sl, p0, Bp, nc);
    double lhs = 0, rhs = 0, tol = 0, terms = 0;
    for (long r = 0; r < ns; r++) lhs += (double)y32[r] * sl[r], tol += fabs(sl[r]) * By[r];
    for (long c = 0; c < nc; c++) rhs += x[c] * (double)p32[c], tol += fabs(x[c]) * Bp[c];
    for (int64_t c = 0; c < A->ncol; c++)
        for (int64_t e = A->colptr[c]; e < A->colptr[c + 1]; e++) terms += fabs(sl[A->rowind[e]] * A->val[e] * x[c]);
    tol += 2.0 * (ns + nc) * 0x1p-53 * terms;
    ck_assert(terms > 0);
    ck_assert_msg(fabs(lhs - rhs) <= tol, "fp32 adjoint: <G x, s> = %.17g, <x, G^T s> = %.17g (|diff| / sum|terms| = %.3g, bound %.3g)",
                  lhs, rhs, fabs(lhs - rhs) / terms, tol / terms);
    /* and the bound is float-sized (16 ε for the run kernels, the CSR's row and column lengths' worth for
     * the averaged sensor), small enough to catch a wrong or missing term */
    ck_assert_double_le(tol, 1024 * 0x1p-24 * terms);
    wt_sparse_free(A);
    free(x32), free(s32), free(y32), free(p32);
    free(x), free(sl), free(y), free(p), free(y0), free(p0), free(By), free(Bp);
}

START_TEST(test_f32_fried)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    for (int mask = 0; mask < 2; mask++) {
        mask ? holed_valid(v) : eelt_valid(v);
        wt_shack_hartmann *s = make(ctx, N, D_SUB, v, 0);
        check_f32(s, 1, 600 + 10 * mask);
        wt_shack_hartmann_free(s);
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_f32_averaged)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    eelt_valid(v);
    wt_shack_hartmann *s = make(ctx, N, D_SUB, v, 2);
    check_f32(s, 0, 700);
    wt_shack_hartmann_free(s);
    wt_context_free(ctx);
}
END_TEST

/* q = 1, m = 0 (m = n): the reconstructor's lit model, through its quad_u run kernels (their u_k are 1/(2d)
 * to the rounding of w / (2 d w), partly lit rim cells included) */
START_TEST(test_f32_lit)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N];
    for (int mask = 0; mask < 2; mask++) {
        mask ? holed_valid(v) : eelt_valid(v);
        wt_shack_hartmann *s = NULL;
        ck_assert_int_eq(wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, 1, v, 0, WT_SH_TILT_G, &s), WT_OK);
        check_f32(s, 1, 800 + 10 * mask);
        wt_shack_hartmann_free(s);
    }
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_errors)
{
    wt_context *ctx = tu_context();
    uint8_t v[N * N], none[16] = {0};
    eelt_valid(v);
    wt_shack_hartmann *s = (wt_shack_hartmann *)&s;
    ck_assert_int_eq(wt_shack_hartmann_alloc_averaged(ctx, N, D_SUB, v, 5, &s), WT_ERR_INVALID);
    ck_assert_ptr_null(s);
    ck_assert(strstr(wt_error_message(ctx), "84"));
    ck_assert_int_eq(wt_shack_hartmann_alloc(ctx, 4, 1.0, none, &s), WT_ERR_INVALID);
    ck_assert_int_eq(wt_shack_hartmann_alloc(ctx, 0, 1.0, v, &s), WT_ERR_INVALID);
    ck_assert_int_eq(wt_shack_hartmann_alloc(ctx, N, -0.5, v, &s), WT_ERR_INVALID);
    wt_shack_hartmann_free(NULL);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_allocation)
{
    /* allocation failures in alloc and assemble: WT_ERR_NOMEM, nothing leaked; apply allocates nothing */
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    uint8_t v[N * N];
    eelt_valid(v);
    for (int m = 0; m <= 3; m++) { /* 3: the lit sensor of the reconstructor (q = 1, its run kernels) */
        int k, ok = 0;
        for (k = 0; k < 50 && !ok; k++) {
            wt_shack_hartmann *s = (wt_shack_hartmann *)&s;
            tu_alloc_budget(&fa, k);
            int st = m == 3 ? wt_shack_hartmann_alloc_lit(ctx, 42.0, 0.28, N, D_SUB, 1, v, 0, WT_SH_TILT_G, &s)
                     : m    ? wt_shack_hartmann_alloc_averaged(ctx, N, D_SUB, v, m, &s)
                            : wt_shack_hartmann_alloc(ctx, N, D_SUB, v, &s);
            if (st == WT_OK) {
                ok = 1;
                tu_alloc_budget(&fa, -1);
                double *phi = calloc((N + 1) * (N + 1), sizeof *phi), *sl = calloc(2 * 5112, sizeof *sl);
                long before = fa.nalloc;
                wt_shack_hartmann_apply(s, 1.0, phi, sl);
                wt_shack_hartmann_apply_t(s, 1.0, sl, phi);
                float *phi32 = calloc((N + 1) * (N + 1), sizeof *phi32), *sl32 = calloc(2 * 5112, sizeof *sl32);
                wt_shack_hartmann_apply_f32(s, 1.0f, phi32, sl32);
                wt_shack_hartmann_apply_t_f32(s, 1.0f, sl32, phi32);
                free(phi32), free(sl32);
                ck_assert_int_eq(fa.nalloc, before);
                TU_ASSEMBLE_UNDER_BUDGETS(&fa, A, wt_shack_hartmann_assemble(s, &A));
                wt_shack_hartmann_free(s);
                free(phi), free(sl);
            } else {
                ck_assert_int_eq(st, WT_ERR_NOMEM);
                ck_assert_ptr_null(s);
            }
            ck_assert_int_eq(fa.live, 0);
        }
        ck_assert_msg(ok && k > 3, "sensor %d: alloc never succeeded or too few allocations (%d)", m, k);
    }
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("shack_hartmann");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, test_counts_and_masks);
    tcase_add_test(tc, test_adjoint_and_assembly);
    tcase_add_test(tc, test_linear_and_quadratic_phase);
    tcase_add_test(tc, test_averaged_is_mean);
    tcase_add_test(tc, test_lit_model);
    tcase_add_test(tc, test_ztilt_rows);
    tcase_add_test(tc, test_lit_runs_equal_csr);
    tcase_add_test(tc, test_f32_fried);
    tcase_add_test(tc, test_f32_averaged);
    tcase_add_test(tc, test_f32_lit);
    tcase_add_test(tc, test_errors);
    tcase_add_test(tc, test_allocation);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
