/* tests/test_atmosphere_project.c: the simulated atmosphere's line-of-sight projection (SPEC §3,
 * sim/atmosphere_project.c): the fast paths and the batched projection bit for bit against the point-by-point
 * and single projections, the geometry against an independent bilinear reference (with subharmonics, the
 * ground layer, the LGS cone), and the piston of a rendered screen. */
#include "atmosphere_fixture.h"

/* The fast row kernel (blocks without masked points skipped, wrap-free blocks branch-free, unit-step
 * blocks read contiguously, sparse blocks point by point; AVX clones where the CPU has them) gives the
 * same bits as the point-by-point reference on every path: NGS (one screen cell per target step) and
 * LGS (cone factor < 1: steps of fewer cells), a target spacing ≠ δ, rows across the screen's seam
 * (the 12 m target on a 16 m screen at several times), no mask, a disc, a sparse LGS-like mask and a
 * rim, with and without subharmonics, α ≠ 1 onto nonzero values, 1 and 2 threads. Any reordering of
 * a sum would show here as a last-bit difference. */
START_TEST(test_fast_equals_reference)
{
    wt_context *ctx = tu_context();
    const int nt = 97;
    const long np = (long)nt * nt;
    uint8_t *masks[4] = {NULL, malloc(np), malloc(np), malloc(np)};
    for (int j = 0; j < nt; j++)
        for (int i = 0; i < nt; i++) {
            double x = i - 48.0, y = j - 48.0, r = hypot(x, y);
            masks[1][i + nt * j] = r <= 47.0;
            masks[2][i + nt * j] = r <= 47.0 && (i % 4 == 0 || j % 4 == 0);
            masks[3][i + nt * j] = r <= 47.0 && r > 45.5;
        }
    double *init = malloc(np * sizeof *init), *a = malloc(np * sizeof *a), *b = malloc(np * sizeof *b);
    wt_rng rng;
    wt_rng_init(&rng, 5, 0);
    for (long k = 0; k < np; k++) init[k] = 1e-7 * wt_rng_normal(&rng);
    long cases = 0;
    for (int nosh = 0; nosh <= 1; nosh++) {
        atm_setup s = three_layers(17);
        s.nosh = nosh;
        wt_atmosphere *atm = make_atm(ctx, &s);
        for (int th = 1; th <= 2; th++) {
            wt_context_set_threads(ctx, th);
            for (int dxi = 0; dxi < 2; dxi++) {
                wt_grid tg = wt_grid_centred(nt, dxi ? 0.1 : 0.125);
                for (int mi = 0; mi < 4; mi++)
                    for (int src = 0; src < 2; src++)
                        for (int ti = 0; ti < 3; ti++) {
                            double t = 0.37 * ti + 0.011, H = src ? 90e3 : 0.0;
                            memcpy(a, init, np * sizeof *a);
                            memcpy(b, init, np * sizeof *b);
                            ck_assert_int_eq(wt_atmosphere_project(atm, t, H, 2e-4, -1e-4, &tg, masks[mi], 0.7, a),
                                             WT_OK);
                            ck_assert_int_eq(
                                wt_atmosphere_project_reference(atm, t, H, 2e-4, -1e-4, &tg, masks[mi], 0.7, b),
                                WT_OK);
                            ck_assert_msg(memcmp(a, b, np * sizeof *a) == 0,
                                          "fast != reference: sh %d, threads %d, dx %d, mask %d, H %g, t %g", !nosh,
                                          th, dxi, mi, H, t);
                            ck_assert(memcmp(a, init, np * sizeof *a) != 0);
                            cases++;
                        }
            }
        }
        wt_atmosphere_free(atm);
    }
    ck_assert_int_eq(cases, 2 * 2 * 2 * 4 * 2 * 3);
    for (int mi = 1; mi < 4; mi++) free(masks[mi]);
    free(init), free(a), free(b);
    wt_context_free(ctx);
}
END_TEST

/* The batched projection equals one wt_atmosphere_project per line of sight bit for bit: 12 lines of
 * sight (NGS and two LGS altitudes, different masks, one without), 1 and 2 threads; and with 12 source
 * altitudes (36 cone factors, over the batch's table) through its fallback. Outputs start nonzero; 6 of
 * the 12 are set (overwritten) instead of added to, which must equal zeroing them first. */
START_TEST(test_many_equals_single)
{
    wt_context *ctx = tu_context();
    atm_setup s = three_layers(23);
    wt_atmosphere *atm = make_atm(ctx, &s);
    const int nt = 81, nlos = 12;
    const long np = (long)nt * nt;
    wt_grid tg = wt_grid_centred(nt, 0.125);
    uint8_t *disc = malloc(np), *sparse = malloc(np);
    for (int j = 0; j < nt; j++)
        for (int i = 0; i < nt; i++) {
            double r = hypot(i - 40.0, j - 40.0);
            disc[i + nt * j] = r <= 39.0 && r >= 8.0;
            sparse[i + nt * j] = r <= 39.0 && (i % 4 == 0 || j % 4 == 0);
        }
    double *a = malloc(nlos * np * sizeof *a), *b = malloc(nlos * np * sizeof *b);
    wt_atmosphere_los los[12];
    for (int many_h = 0; many_h <= 1; many_h++)
        for (int th = 1; th <= 2; th++) {
            wt_context_set_threads(ctx, th);
            for (long k = 0; k < nlos * np; k++) a[k] = b[k] = 1e-8 * (double)(k % 7);
            for (int i = 0; i < nlos; i++) {
                double H = many_h ? 20e3 + 5e3 * i : (i % 3 == 0 ? 0.0 : i % 3 == 1 ? 90e3 : 80e3);
                los[i] = (wt_atmosphere_los){.source_altitude = H,
                                             .theta_x = 1e-4 * (i % 4 - 1.5),
                                             .theta_y = 1e-4 * (i / 4 - 1.0),
                                             .mask = i % 3 == 2 ? NULL : i % 2 ? sparse : disc,
                                             .out = a + i * np,
                                             .set = i % 5 < 2};
                if (los[i].set) /* set = the same bits as zeroing the masked points first */
                    for (long k = 0; k < np; k++)
                        if (!los[i].mask || los[i].mask[k]) b[i * np + k] = 0.0;
                ck_assert_int_eq(wt_atmosphere_project(atm, 0.29, H, los[i].theta_x, los[i].theta_y, &tg, los[i].mask,
                                                       0.9, b + i * np),
                                 WT_OK);
            }
            ck_assert_int_eq(wt_atmosphere_project_many(atm, 0.29, nlos, los, &tg, 0.9), WT_OK);
            ck_assert_msg(memcmp(a, b, nlos * np * sizeof *a) == 0, "many != single: threads %d, altitudes %d", th,
                          many_h);
        }
    /* alpha = 0: the outputs with set get their masked points zeroed, the others stay */
    for (long k = 0; k < nlos * np; k++) a[k] = b[k] = 1e-8 * (double)(k % 7);
    for (int i = 0; i < nlos; i++)
        if (los[i].set)
            for (long k = 0; k < np; k++)
                if (!los[i].mask || los[i].mask[k]) b[i * np + k] = 0.0;
    ck_assert_int_eq(wt_atmosphere_project_many(atm, 0.29, nlos, los, &tg, 0.0), WT_OK);
    ck_assert(memcmp(a, b, nlos * np * sizeof *a) == 0);
    /* a bad line of sight: an error, nothing written */
    los[3].source_altitude = 10e3; /* below the 12 km layer */
    for (long k = 0; k < nlos * np; k++) b[k] = a[k];
    ck_assert_int_eq(wt_atmosphere_project_many(atm, 0.29, nlos, los, &tg, 0.9), WT_ERR_INVALID);
    ck_assert(memcmp(a, b, nlos * np * sizeof *a) == 0);
    free(disc), free(sparse), free(a), free(b);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST
/* ---------------------------------------------------------------------------------------------- */
/* Geometry (SPEC §3) */

/* Independent periodic bilinear interpolation of a screen at (x, y) [m]. */
static double ref_sample(const double *scr, int n, double delta, wt_grid g, double x, double y)
{
    double u = fmod((x - g.x0) / delta, n), v = fmod((y - g.y0) / delta, n);
    if (u < 0) u += n;
    if (v < 0) v += n;
    int i = (int)floor(u), j = (int)floor(v);
    double fx = u - i, fy = v - j;
    i %= n, j %= n;
    int i1 = (i + 1) % n, j1 = (j + 1) % n;
    return (1 - fx) * (1 - fy) * scr[i + n * j] + fx * (1 - fy) * scr[i1 + n * j] + (1 - fx) * fy * scr[i + n * j1] +
           fx * fy * scr[i1 + n * j1];
}

/* Three layers (0, 4, 12 km), grid part only, LGS and NGS, t ≠ 0, target spacing ≠ δ, a mask, α ≠ 1 and
 * accumulation: every masked point equals out₀ + α Σ_ℓ screen_ℓ((1 − h/H) r + θh − v t) computed
 * independently; unmasked points keep out₀ exactly. Rounding only (different operation order): 1e-12
 * of the largest |Σ|, out₀ being of the same size. */
START_TEST(test_geometry_reference)
{
    wt_context *ctx = tu_context();
    atm_setup s = three_layers(41);
    s.nosh = 1;
    wt_atmosphere *atm = make_atm(ctx, &s);
    wt_grid g = wt_atmosphere_grid(atm);
    const int n = 128;
    wt_grid tg = {41, 33, 0.3, -6.1, -4.7};
    const long np = 41 * 33;
    uint8_t *mask = malloc(np);
    wt_rng rng;
    wt_rng_init(&rng, 3, 0);
    for (long i = 0; i < np; i++) mask[i] = wt_rng_uniform(&rng) < 0.7;
    const double Hs[2] = {90e3, 0.0}, alpha = -0.7, t = 0.41, thx = 2e-4, thy = -1.5e-4;
    double *out = malloc(np * sizeof *out), *ref = malloc(np * sizeof *ref), *base = malloc(np * sizeof *base);
    for (long i = 0; i < np; i++) base[i] = 1e-7 * sin(0.37 * i); /* prior contents at the OPD's scale */
    for (int k = 0; k < 2; k++) {
        double H = Hs[k];
        for (long i = 0; i < np; i++) out[i] = base[i];
        ck_assert_int_eq(wt_atmosphere_project(atm, t, H, thx, thy, &tg, mask, alpha, out), WT_OK);
        double scale = 0.0;
        for (int iy = 0; iy < tg.ny; iy++)
            for (int ix = 0; ix < tg.nx; ix++) {
                double x = tg.x0 + ix * tg.dx, y = tg.y0 + iy * tg.dx, sum = 0.0;
                for (int l = 0; l < 3; l++) {
                    double h = s.h[l], c = H > 0 ? 1 - h / H : 1, vx, vy;
                    wt_atmosphere_layer_wind(atm, l, &vx, &vy);
                    ck_assert_rel(vx, s.v[l] * cos(s.dir[l]), 1e-15, 1e-15);
                    sum += ref_sample(wt_atmosphere_layer_data(atm, l), n, 0.125, g, c * x + thx * h - vx * t,
                                      c * y + thy * h - vy * t);
                }
                ref[ix + tg.nx * iy] = base[ix + tg.nx * iy] + alpha * sum;
                scale = fmax(scale, fabs(sum));
            }
        for (long i = 0; i < np; i++) {
            if (mask[i]) ck_assert_msg(fabs(out[i] - ref[i]) <= 1e-12 * scale, "point %ld: %.17g vs %.17g", i, out[i], ref[i]);
            else ck_assert(out[i] == base[i]);
        }
    }
    free(mask), free(out), free(ref), free(base);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* The same with subharmonics, where every sample point stays inside the screen grid (no wrap): the
 * reference is the bilinear interpolation of the rendered screen (grid + subharmonics at the nodes).
 * Interpolating the subharmonic field instead of evaluating it costs at most its curvature,
 * (2π/3L)² δ²/8 ≈ 3e-5 of its amplitude for δ/L = 1/256: tolerance 1e-4 of the largest |φ|. */
START_TEST(test_geometry_reference_subharmonics)
{
    wt_context *ctx = tu_context();
    atm_setup s = three_layers(43);
    s.n = 256;
    wt_atmosphere *atm = make_atm(ctx, &s);
    wt_grid g = wt_atmosphere_grid(atm);
    const int n = 256;
    const long nn = (long)n * n;
    double *rend[3];
    for (int l = 0; l < 3; l++) {
        rend[l] = malloc(nn * sizeof(double));
        wt_atmosphere_layer_render(atm, l, rend[l]);
    }
    wt_grid tg = {41, 33, 0.3, -6.1, -4.7};
    const long np = 41 * 33;
    const double Hs[2] = {90e3, 0.0}, t = 0.2, thx = 2e-4, thy = -1.5e-4;
    double *out = malloc(np * sizeof *out);
    for (int k = 0; k < 2; k++) {
        double H = Hs[k], scale = 0.0, err = 0.0;
        memset(out, 0, np * sizeof *out);
        ck_assert_int_eq(wt_atmosphere_project(atm, t, H, thx, thy, &tg, NULL, 1.0, out), WT_OK);
        for (int iy = 0; iy < tg.ny; iy++)
            for (int ix = 0; ix < tg.nx; ix++) {
                double x = tg.x0 + ix * tg.dx, y = tg.y0 + iy * tg.dx, sum = 0.0;
                for (int l = 0; l < 3; l++) {
                    double h = s.h[l], c = H > 0 ? 1 - h / H : 1, vx, vy;
                    wt_atmosphere_layer_wind(atm, l, &vx, &vy);
                    double px = c * x + thx * h - vx * t, py = c * y + thy * h - vy * t;
                    ck_assert(px >= g.x0 && px < g.x0 + (n - 1) * 0.125 && py >= g.y0 && py < g.y0 + (n - 1) * 0.125);
                    sum += ref_sample(rend[l], n, 0.125, g, px, py);
                }
                scale = fmax(scale, fabs(sum));
                err = fmax(err, fabs(out[ix + tg.nx * iy] - sum));
            }
        ck_assert_msg(err <= 1e-4 * scale, "H = %g: max error %.3g of max |phi| %.3g", H, err, scale);
    }
    free(out);
    for (int l = 0; l < 3; l++) free(rend[l]);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* A layer at altitude 0 is the same in every direction and for every source altitude (c = 1, θ·0 = 0:
 * the sample points are bit-identical); a layer at 10 km is not. */
START_TEST(test_geometry_ground_layer)
{
    wt_context *ctx = tu_context();
    wt_grid tg = wt_grid_centred(64, 0.125);
    const long np = 64 * 64;
    double *a = calloc(np, sizeof *a), *b = calloc(np, sizeof *b);
    for (int k = 0; k < 2; k++) {
        atm_setup s = one_layer(128, 0.125, 25.0, k ? 10000.0 : 0.0, 8.0, 1.0, 51, 0);
        wt_atmosphere *atm = make_atm(ctx, &s);
        memset(a, 0, np * sizeof *a), memset(b, 0, np * sizeof *b);
        ck_assert_int_eq(wt_atmosphere_project(atm, 0.2, 0.0, 0.0, 0.0, &tg, NULL, 1.0, a), WT_OK);
        ck_assert_int_eq(wt_atmosphere_project(atm, 0.2, 90e3, 3e-4, 1e-4, &tg, NULL, 1.0, b), WT_OK);
        if (k == 0) ck_assert(memcmp(a, b, np * sizeof *a) == 0);
        else ck_assert(tu_rel_diff(a, b, np) > 0.1);
        wt_atmosphere_free(atm);
    }
    free(a), free(b);
    wt_context_free(ctx);
}
END_TEST

/* Cone factor (SPEC §3), with subharmonics: an LGS at H sees the layer at h on the target grid scaled
 * by c = 1 − h/H and shifted by θh — i.e. an NGS on axis looking through the grid {c r + θh}. Equal up
 * to rounding of the sample coordinates (1e-12). */
START_TEST(test_geometry_cone)
{
    wt_context *ctx = tu_context();
    atm_setup s = one_layer(256, 0.125, 25.0, 12700.0, 0.0, 0.0, 61, 0);
    wt_atmosphere *atm = make_atm(ctx, &s);
    const double H = 90e3, c = 1.0 - 12700.0 / H, thx = -2e-4, thy = 2.9e-4;
    wt_grid tg = wt_grid_centred(85, 0.5);
    wt_grid ts = {85, 85, c * 0.5, c * tg.x0 + thx * 12700.0, c * tg.y0 + thy * 12700.0};
    const long np = 85 * 85;
    double *a = calloc(np, sizeof *a), *b = calloc(np, sizeof *b), *d = calloc(np, sizeof *d);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, H, thx, thy, &tg, NULL, 1.0, a), WT_OK);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, 0.0, 0.0, &ts, NULL, 1.0, b), WT_OK);
    ck_assert(max_abs_diff(a, b, np) <= 1e-12 * rms(b, np));
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, thx, thy, &tg, NULL, 1.0, d), WT_OK);
    ck_assert(tu_rel_diff(a, d, np) > 0.05); /* the cone factor did something */
    free(a), free(b), free(d);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

/* The projection evaluates the same field as the rendered screen (grid + subharmonics) at grid nodes,
 * and the screen's piston is zero: the grid part and the whole screen have mean ≤ 1e-12 of their rms. */
START_TEST(test_render_piston)
{
    wt_context *ctx = tu_context();
    const int n = 128;
    atm_setup s = one_layer(n, 0.125, 25.0, 3000.0, 10.0, 0.5, 71, 0);
    wt_atmosphere *atm = make_atm(ctx, &s);
    wt_grid g = wt_atmosphere_grid(atm);
    const long nn = (long)n * n;
    double *p = calloc(nn, sizeof *p), *r = malloc(nn * sizeof *r);
    wt_atmosphere_layer_render(atm, 0, r);
    ck_assert_int_eq(wt_atmosphere_project(atm, 0.0, 0.0, 0.0, 0.0, &g, NULL, 1.0, p), WT_OK);
    ck_assert(max_abs_diff(p, r, nn) <= 1e-12 * rms(r, nn));
    const double *d = wt_atmosphere_layer_data(atm, 0);
    double md = 0.0, mr = 0.0;
    for (long i = 0; i < nn; i++) md += d[i], mr += r[i];
    ck_assert(fabs(md / nn) <= 1e-12 * rms(d, nn));
    ck_assert(fabs(mr / nn) <= 1e-12 * rms(r, nn));
    ck_assert(tu_rel_diff(r, d, nn) > 1e-3); /* the subharmonics are there (L = 16 m < L0) */
    free(p), free(r);
    wt_atmosphere_free(atm);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("atmosphere_project");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_geometry_reference);
    tcase_add_test(tc, test_geometry_reference_subharmonics);
    tcase_add_test(tc, test_geometry_ground_layer);
    tcase_add_test(tc, test_geometry_cone);
    tcase_add_test(tc, test_fast_equals_reference);
    tcase_add_test(tc, test_many_equals_single);
    tcase_add_test(tc, test_render_piston);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
