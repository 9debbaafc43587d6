/* tests/test_shift.c: the layers moved by their wind (core/op/shift.h): a band-limited periodic field moved
 * by a sub-sample shift equals the field evaluated at the translated points (the method is exact for it, so
 * to rounding); two shifts compose; a zero shift leaves the layer's bits; out of place gives the in-place bits
 * and copies a layer that does not move; the bits do not depend on the thread count; a shift of a quarter of the
 * grid or a non-finite one is refused naming the layer. */
#include "testutil.h"

#include "core/op/shift.h"

/* f(x, y) = Σ_m a_m cos(2π (kx_m x + ky_m y)/L + p_m): frequencies below both grids' Nyquist (|k| < 8) */
#define NM 6
static const double KX[NM] = {1, 3, -5, 7, 0, 6}, KY[NM] = {0, 2, 4, -6, 7, -5}, A[NM] = {1, .5, .3, .2, .4, .1},
                    P[NM] = {.1, 2, -1, .7, 3, -2};
static double field(double x, double y, double L)
{
    double v = 0;
    for (int m = 0; m < NM; m++) v += A[m] * cos(2 * M_PI * (KX[m] * x + KY[m] * y) / L + P[m]);
    return v;
}

START_TEST(t_band_limited_exact)
{
    wt_context *ctx = tu_context();
    const int n1 = 32, n2 = 16;
    const double d1 = 0.5, d2 = 1.0;
    wt_grid g1 = {.nx = n1, .ny = n1, .dx = d1}, g2 = {.nx = n2, .ny = n2, .dx = d2};
    const wt_grid *g[3] = {&g1, &g2, &g1};
    const int64_t off[3] = {0, n1 * n1, n1 * n1 + n2 * n2};
    /* sub-sample and several-sample shifts; the third layer does not move */
    const double sx[3] = {0.37, -2.6, 0.0}, sy[3] = {-0.81, 1.3, 0.0};
    const int64_t N = off[2] + n1 * n1;
    double *phi = malloc(N * sizeof *phi), *orig = malloc(N * sizeof *orig);
    for (int l = 0; l < 3; l++) {
        const int n = g[l]->nx;
        const double dx = g[l]->dx, L = n * dx;
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) phi[off[l] + ix + (int64_t)n * iy] = field(ix * dx, iy * dx, L);
    }
    memcpy(orig, phi, N * sizeof *phi);
    wt_shift *s = NULL;
    ck_assert_int_eq(wt_shift_alloc(ctx, 3, g, off, sx, sy, &s), WT_OK);
    ck_assert_int_eq(wt_shift_nmoving(s), 2);
    wt_shift_apply(s, phi);
    /* φ_new(x) = φ(x − s): to rounding of two n² FFTs (n = 32: ~1e-14 of the field's scale) */
    for (int l = 0; l < 2; l++) {
        const int n = g[l]->nx;
        const double dx = g[l]->dx, L = n * dx;
        double err = 0;
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++)
                err = fmax(err, fabs(phi[off[l] + ix + (int64_t)n * iy] - field(ix * dx - sx[l], iy * dx - sy[l], L)));
        ck_assert_msg(err < 1e-12, "layer %d: max error %g", l + 1, err);
    }
    ck_assert_int_eq(memcmp(phi + off[2], orig + off[2], (size_t)n1 * n1 * sizeof *phi), 0);
    wt_shift_free(s);

    /* two shifts compose: (s then −s) returns the field */
    const double mx[1] = {-0.37}, my[1] = {0.81};
    const wt_grid *g0[1] = {&g1};
    const int64_t o0[1] = {0};
    ck_assert_int_eq(wt_shift_alloc(ctx, 1, g0, o0, mx, my, &s), WT_OK);
    wt_shift_apply(s, phi);
    ck_assert_double_lt(tu_rel_diff(phi, orig, n1 * n1), 1e-13);
    wt_shift_free(s);
    free(phi), free(orig);
    wt_context_free(ctx);
}
END_TEST

/* out of place (the reconstructor's phi → pred) against in place, on 1 and on 2 threads: the same bits; the
 * input untouched; the layer that does not move copied; layers of three sizes, the largest not first; the integrator's
 * spectral state (wt_shift_integrator) against the same law in space */
START_TEST(t_out_of_place_and_threads)
{
    wt_grid g1 = {.nx = 16, .ny = 16, .dx = 1.0}, g2 = {.nx = 64, .ny = 64, .dx = 0.5}, g3 = {.nx = 32, .ny = 32, .dx = 0.5};
    const wt_grid *g[4] = {&g1, &g2, &g3, &g2};
    const int64_t off[4] = {0, 256, 256 + 4096, 256 + 4096 + 1024};
    const int64_t N = off[3] + 4096;
    const double sx[4] = {0.3, -1.7, 0.0, 2.2}, sy[4] = {-0.45, 0.9, 0.0, -3.1};
    double *in = malloc(N * sizeof *in), *keep = malloc(N * sizeof *keep), *a = malloc(N * sizeof *a),
           *b = malloc(N * sizeof *b), *zi1 = malloc(N * sizeof *zi1);
    tu_randn(in, N, 11);
    memcpy(keep, in, N * sizeof *in);
    for (int threads = 1; threads <= 2; threads++) {
        wt_context *ctx = tu_context();
        wt_context_set_threads(ctx, threads);
        wt_shift *s = NULL;
        ck_assert_int_eq(wt_shift_alloc(ctx, 4, g, off, sx, sy, &s), WT_OK);
        ck_assert_int_eq(wt_shift_nmoving(s), 3);
        for (int64_t i = 0; i < N; i++) b[i] = NAN;
        wt_shift_apply_to(s, in, b);
        ck_assert_int_eq(memcmp(in, keep, N * sizeof *in), 0);
        ck_assert_int_eq(memcmp(b + off[2], in + off[2], 1024 * sizeof *b), 0);
        if (threads == 1) {
            memcpy(a, in, N * sizeof *a);
            wt_shift_apply(s, a);
        }
        ck_assert_msg(!memcmp(a, b, N * sizeof *a), "%d threads: out of place differs from in place on 1", threads);
        /* the integrator on the layers (its state the layers' spectra) against the same law in space, the two shifts
         * applied as wt_shift_apply_to does them, over 6 frames of random estimates with delay 2: equal to rounding
         * (the operators are the same; relative 1e-12 for ~20 transforms of 64 points); on 2 threads the bits of 1 */
        const double hx[4] = {0.1, -0.6, 0.0, 0.7}, hy[4] = {-0.2, 0.3, 0.0, -1.0}, gain = 0.3;
        wt_shift *h = NULL;
        wt_shift_integrator *it = NULL;
        ck_assert_int_eq(wt_shift_alloc(ctx, 4, g, off, hx, hy, &h), WT_OK);
        ck_assert_int_eq(wt_shift_integrator_alloc(ctx, 4, g, off, 2, &it), WT_OK);
        double *z[3], *zn = malloc(N * sizeof *zn), *e = malloc(N * sizeof *e), *ph = malloc(N * sizeof *ph);
        for (int k = 0; k < 3; k++) z[k] = calloc(N, sizeof *z[k]);
        for (int t = 0; t < 6; t++) {
            tu_randn(ph, N, 100 + t);
            for (int64_t i = 0; i < N; i++) e[i] = ph[i] - z[t % 3][i];
            wt_shift_apply(s, e);
            wt_shift_apply_to(h, z[(t + 1) % 3], z[(t + 2) % 3]);
            for (int64_t i = 0; i < N; i++) z[(t + 2) % 3][i] += gain * e[i];
            ck_assert_int_eq(wt_shift_integrator_step(it, s, h, gain, ph, zn), WT_OK);
            ck_assert_msg(tu_rel_diff(zn, z[(t + 2) % 3], N) < 1e-12, "%d threads, frame %d: the spectral state is %g from the "
                          "law in space", threads, t, tu_rel_diff(zn, z[(t + 2) % 3], N));
        }
        if (threads == 1) memcpy(zi1, zn, N * sizeof *zi1);
        else ck_assert_msg(!memcmp(zi1, zn, N * sizeof *zi1), "the integrator's bits depend on the thread count");
        /* shifts of other layers are refused */
        wt_shift *other = NULL;
        ck_assert_int_eq(wt_shift_alloc(ctx, 1, g, off, hx, hy, &other), WT_OK);
        ck_assert_int_eq(wt_shift_integrator_step(it, other, h, gain, ph, zn), WT_ERR_INVALID);
        wt_shift_free(other);
        for (int k = 0; k < 3; k++) free(z[k]);
        free(zn), free(e), free(ph);
        wt_shift_integrator_free(it);
        wt_shift_free(h);
        wt_shift_free(s);
        wt_context_free(ctx);
    }
    free(in), free(keep), free(a), free(b), free(zi1);
}
END_TEST

/* The integrator on moving layers (wt_shift_integrator) under frozen flow: a band-limited layer moving by v a frame
 * (φ_t = f(x − v t)), the law started from z = 0 with delay d = 2 and gain g = 0.4. Its error ε_t = z_t − φ_t obeys,
 * mode by mode (the shifts are unitary and commute), ε_t = u^t η_t with η_{t+2} = η_{t+1} − g η_t: roots of
 * x² − x + g, |x| = √g = 0.63, so after 70 frames the state is φ_{t+d} to ~0.63^70 ≈ 1e-14 (times the roots'
 * polynomial factor: tolerance 1e-10 of the field). The integrator on the commands (no S_1: z_{t+d} = z_{t+d−1} +
 * g (S_d φ_t − z_t)) keeps a lag instead: its error stays, here > 1 % of the field, which the test also checks so
 * that it can tell the two laws apart. */
START_TEST(t_integrate_frozen_flow)
{
    wt_context *ctx = tu_context();
    const int n = 32, d = 2, T = 70;
    const double dx = 0.5, L = n * dx, g = 0.4, vx = 0.23, vy = -0.11; /* [m per frame] */
    wt_grid g1 = {.nx = n, .ny = n, .dx = dx};
    const wt_grid *gg[1] = {&g1};
    const int64_t off[1] = {0}, N = (int64_t)n * n;
    const double lx = d * vx, ly = d * vy;
    wt_shift *lead = NULL, *one = NULL;
    ck_assert_int_eq(wt_shift_alloc(ctx, 1, gg, off, &lx, &ly, &lead), WT_OK);
    ck_assert_int_eq(wt_shift_alloc(ctx, 1, gg, off, &vx, &vy, &one), WT_OK);
    wt_shift_integrator *it = NULL;
    ck_assert_int_eq(wt_shift_integrator_alloc(ctx, 1, gg, off, d, &it), WT_OK);
    double *z = malloc(N * sizeof *z), *c[3], *phi = malloc(N * sizeof *phi), *e = malloc(N * sizeof *e);
    for (int k = 0; k < 3; k++) c[k] = calloc(N, sizeof *c[k]);
    double fmaxv = 0.0, err = 0.0, errc = 0.0;
    for (int t = 0; t < T; t++) {
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) phi[ix + n * iy] = field(ix * dx - vx * t, iy * dx - vy * t, L);
        ck_assert_int_eq(wt_shift_integrator_step(it, lead, one, g, phi, z), WT_OK);
        /* the commands' law, in the layers: z_{t+d} = z_{t+d−1} + g (S_d φ_t − z_t) */
        wt_shift_apply_to(lead, phi, e);
        for (int64_t k = 0; k < N; k++) c[(t + 2) % 3][k] = c[(t + 1) % 3][k] + g * (e[k] - c[t % 3][k]);
        if (t < T - 1) continue;
        err = errc = 0.0;
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) {
                const double f = field(ix * dx - vx * (t + d), iy * dx - vy * (t + d), L);
                fmaxv = fmax(fmaxv, fabs(f));
                err = fmax(err, fabs(z[ix + n * iy] - f));
                errc = fmax(errc, fabs(c[(t + 2) % 3][ix + n * iy] - f));
            }
    }
    ck_assert_msg(err < 1e-10 * fmaxv, "the layers' integrator is %g from the layer d frames later (field %g)", err, fmaxv);
    ck_assert_msg(errc > 1e-2 * fmaxv, "the commands' integrator kept up (%g): the test cannot tell the laws apart", errc);
    for (int k = 0; k < 3; k++) free(c[k]);
    free(z), free(phi), free(e);
    wt_shift_integrator_free(it);
    wt_shift_free(lead);
    wt_shift_free(one);
    wt_context_free(ctx);
}
END_TEST

START_TEST(t_refusals)
{
    wt_context *ctx = tu_context();
    wt_grid g1 = {.nx = 16, .ny = 16, .dx = 0.5}, godd = {.nx = 15, .ny = 15, .dx = 0.5};
    const wt_grid *g[2] = {&g1, &g1};
    const int64_t off[2] = {0, 256};
    wt_shift *s = NULL;
    const double big[2] = {0.0, 2.1}, zero[2] = {0.0, 0.0}, nan[2] = {NAN, 0.0};
    ck_assert_int_eq(wt_shift_alloc(ctx, 2, g, off, big, zero, &s), WT_ERR_CONFIG);
    ck_assert_ptr_null(s);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "layer 2"));
    ck_assert_int_eq(wt_shift_alloc(ctx, 2, g, off, nan, zero, &s), WT_ERR_CONFIG);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "layer 1"));
    const wt_grid *go[1] = {&godd};
    ck_assert_int_eq(wt_shift_alloc(ctx, 1, go, off, zero, zero, &s), WT_ERR_INVALID);
    /* the integrator: an odd grid, a delay below one frame */
    wt_shift_integrator *it = NULL;
    ck_assert_int_eq(wt_shift_integrator_alloc(ctx, 1, go, off, 2, &it), WT_ERR_INVALID);
    ck_assert_ptr_null(it);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "layer 1"));
    ck_assert_int_eq(wt_shift_integrator_alloc(ctx, 2, g, off, 0, &it), WT_ERR_INVALID);
    ck_assert_ptr_null(it);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "delay 0"));
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("shift");
    TCase *tc = tcase_create("core");
    tcase_add_test(tc, t_band_limited_exact);
    tcase_add_test(tc, t_out_of_place_and_threads);
    tcase_add_test(tc, t_integrate_frozen_flow);
    tcase_add_test(tc, t_refusals);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
