/* tests/test_learn.c: identification from telemetry (SPEC §12; core/model/learn.h): the FFT cross-covariance maps
 * against the direct pair average, the non-negative least squares, the response maps against the covariance of
 * simulated von Kármán screens, and a single layer found at its altitude (the wind: test_learn_wind.c). */
#include <unistd.h>

#include "core/config/config.h"
#include "core/io/h5.h"
#include "core/model/learn.h"
#include "sim/atmosphere.h"
#include "core/op/grid.h"
#include "learn_fixture.h"
#include "testutil.h"

/* ---------------------------------------------------------------- the maps against the direct average */

/* The accumulated map equals Σ_t Σ_{a, a+δ valid} s̃_i(a) s̃_j(a + δ) / (K P(δ)) computed pair by pair (s̃: tip-tilt
 * removed). Both are sums of the same ~K nsub products; the FFT's rounding is ~ε log N relative to the largest
 * spectrum term, i.e. to Σ |s|² — tolerance 1e-11 of the maps' largest value. */
START_TEST(test_map_direct)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 9, 3, 30.0);
    const int n = G.n, ns = geom_nsub(&G), S = 2 * n - 1, K = 4;
    int sub[81];
    for (int k = 0, m = 0; k < n * n; k++)
        if (G.valid[k]) sub[m++] = k;
    wt_learn *L = NULL;
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 2, 2, &L), WT_OK);
    double *s = malloc(sizeof(double) * (size_t)K * G.nlgs * 2 * ns);
    tu_randn(s, (long)K * G.nlgs * 2 * ns, 11);
    /* a correlated component (common to the LGS, shifted) so that the maps are not just a spike at 0 */
    for (int t = 0; t < K; t++)
        for (int i = 1; i < G.nlgs; i++)
            for (int k = 0; k < 2 * ns; k++) s[((size_t)t * G.nlgs + i) * 2 * ns + k] += 0.7 * s[((size_t)t * G.nlgs) * 2 * ns + (k + 1) % (2 * ns)];
    for (int t = 0; t < K; t++) ck_assert_int_eq(wt_learn_add(L, s + (size_t)t * G.nlgs * 2 * ns), WT_OK);
    ck_assert_int_eq(wt_learn_frames(L), K);
    ck_assert_int_eq(wt_learn_map_side(L), S);
    double *map = malloc(sizeof(double) * S * S), *cnt = malloc(sizeof(double) * S * S);
    double *dir = calloc((size_t)S * S, sizeof(double)), *dcnt = calloc((size_t)S * S, sizeof(double));
    static const int ca[3] = {0, 1, 0}, cb[3] = {0, 1, 1};
    for (int p = 0; p < wt_learn_npairs(L); p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        ck_assert(i <= j);
        for (int c = 0; c < 3; c++) {
            ck_assert_int_eq(wt_learn_map(L, -1, p, c, map, cnt), WT_OK);
            memset(dir, 0, sizeof(double) * S * S), memset(dcnt, 0, sizeof(double) * S * S);
            for (int t = 0; t < K; t++) {
                const double *si = s + ((size_t)t * G.nlgs + i) * 2 * ns + (size_t)ca[c] * ns;
                const double *sj = s + ((size_t)t * G.nlgs + j) * 2 * ns + (size_t)cb[c] * ns;
                double mi = 0, mj = 0;
                for (int k = 0; k < ns; k++) mi += si[k] / ns, mj += sj[k] / ns;
                for (int a = 0; a < ns; a++)
                    for (int b = 0; b < ns; b++) {
                        int dx = sub[b] % n - sub[a] % n, dy = sub[b] / n - sub[a] / n;
                        int o = (dx + n - 1) + S * (dy + n - 1);
                        dir[o] += (si[a] - mi) * (sj[b] - mj);
                        if (t == 0) dcnt[o] += 1;
                    }
            }
            double mx = 0;
            for (int o = 0; o < S * S; o++) {
                if (dcnt[o] > 0) dir[o] /= K * dcnt[o];
                mx = fmax(mx, fabs(dir[o]));
            }
            for (int o = 0; o < S * S; o++) {
                ck_assert_msg(cnt[o] == dcnt[o], "pair count at %d: %g vs %g", o, cnt[o], dcnt[o]);
                ck_assert_msg(fabs(map[o] - dir[o]) <= 1e-11 * mx, "pair %d comp %d offset %d: %.17g vs %.17g", p, c, o,
                              map[o], dir[o]);
            }
        }
    }
    /* the batches add up to the whole */
    double *m0 = malloc(sizeof(double) * S * S), *m1 = malloc(sizeof(double) * S * S);
    ck_assert_int_eq(wt_learn_map(L, 0, 1, 0, m0, NULL), WT_OK);
    ck_assert_int_eq(wt_learn_map(L, 1, 1, 0, m1, NULL), WT_OK);
    ck_assert_int_eq(wt_learn_map(L, -1, 1, 0, map, NULL), WT_OK);
    for (int o = 0; o < S * S; o++) ck_assert(fabs(0.5 * (m0[o] + m1[o]) - map[o]) <= 1e-12 * (fabs(map[o]) + 1e-3));
    /* a NaN is refused, naming it, and not counted */
    s[3] = NAN;
    ck_assert_int_eq(wt_learn_add(L, s), WT_ERR_NUMERIC);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "LGS 1 slope 3"));
    ck_assert_int_eq(wt_learn_frames(L), K);
    ck_assert_int_eq(wt_learn_map(L, 5, 0, 0, map, NULL), WT_ERR_INVALID);
    free(s), free(map), free(cnt), free(dir), free(dcnt), free(m0), free(m1);
    wt_learn_free(L);
    wt_context_free(ctx);
}
END_TEST

/* The per-frame call allocates nothing (counted through the allocator hook); every allocation failure of _alloc is
 * WT_ERR_NOMEM with nothing left allocated. */
START_TEST(test_alloc)
{
    wt_context *ctx = tu_context();
    tu_alloc fa = TU_ALLOC_INIT;
    tu_alloc_install(ctx, &fa);
    geom G;
    geom_make(&G, 8, 3, 30.0);
    const int ns = geom_nsub(&G);
    wt_learn *L = NULL;
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 2, 3, &L), WT_OK);
    const long granted = fa.nalloc;
    double *s = malloc(sizeof(double) * (size_t)G.nlgs * 2 * ns);
    for (int t = 0; t < 8; t++) {
        tu_randn(s, (long)G.nlgs * 2 * ns, (unsigned long)(20 + t));
        ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    }
    ck_assert_int_eq(fa.nalloc, granted);
    wt_learn_free(L);
    ck_assert_int_eq(fa.live, 0);
    for (long k = 0; k < granted; k++) {
        tu_alloc_budget(&fa, k);
        L = NULL;
        ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 2, 3, &L), WT_ERR_NOMEM);
        ck_assert_ptr_null(L);
        ck_assert_int_eq(fa.live, 0);
    }
    tu_alloc_budget(&fa, -1);
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------- NNLS */

/* A consistent problem b = A x* with x* ≥ 0 (some zeros): the minimum is x* (to the conditioning of AᵀA times ε);
 * an inconsistent one: the KKT conditions, x ≥ 0, (q − G x)_k = 0 where x_k > 0 and ≤ 0 where x_k = 0. */
START_TEST(test_nnls)
{
    enum { M = 40, N = 10 };
    double A[M * N], xs[N], b[M], G[N * N], q[N], x[N], work[N * (2 * N + 3)];
    int iw[N];
    tu_randn(A, M * N, 3);
    for (int k = 0; k < N; k++) xs[k] = k % 3 == 0 ? 0.0 : 0.5 + k;
    for (int trial = 0; trial < 2; trial++) {
        for (int r = 0; r < M; r++) {
            b[r] = 0;
            for (int k = 0; k < N; k++) b[r] += A[r + M * k] * xs[k];
        }
        if (trial) {
            double e[M];
            tu_randn(e, M, 4);
            for (int r = 0; r < M; r++) b[r] += 3 * e[r];
        }
        for (int i = 0; i < N; i++) {
            q[i] = 0;
            for (int r = 0; r < M; r++) q[i] += A[r + M * i] * b[r];
            for (int k = 0; k < N; k++) {
                G[i + N * k] = 0;
                for (int r = 0; r < M; r++) G[i + N * k] += A[r + M * i] * A[r + M * k];
            }
        }
        ck_assert_int_ge(wt_learn_nnls(N, G, q, x, work, iw), 0);
        for (int k = 0; k < N; k++) {
            ck_assert(x[k] >= 0);
            if (!trial) ck_assert_msg(fabs(x[k] - xs[k]) <= 1e-9 * (1 + xs[k]), "x[%d] = %g vs %g", k, x[k], xs[k]);
            double g = q[k];
            for (int j = 0; j < N; j++) g -= G[k + N * j] * x[j];
            if (x[k] > 0) ck_assert_msg(fabs(g) <= 1e-9 * M * 10, "gradient %g at free x[%d]", g, k);
            else ck_assert_msg(g <= 1e-9 * M * 10, "gradient %g > 0 at held x[%d]", g, k);
        }
    }
}
END_TEST

/* ---------------------------------------------------------------- open-loop slopes of simulated screens */

/* K frames of the LGS slopes of a von Kármán atmosphere (sim/atmosphere.h), each slope the mean OPD gradient
 * over its subaperture, from q = 4 samples per side (trapezoid edge means), into s (K × nlgs × 2 nsub). Frames are
 * `step` metres of frozen flow apart (independent when step exceeds the footprint); each seed a new screen. */
/* frames of nl frozen-flow layers (each moving `step` = 10 m per frame, or speed[l] when speed is not NULL), per_seed
 * frames from each of `seeds` independent screens; the slopes of every LGS in the learn layout */
static void simulate_v(wt_context *ctx, const geom *G, int nl, const double *alt, const double *frac, const double *speed,
                       double r0, double L0, int seed0, int seeds, int per_seed, double *s)
{
    const int n = G->n, q = 4, np = n * q + 1, ns = geom_nsub(G);
    const double d = G->d, step = 10.0;
    wt_grid tg = {np, np, d / q, -n * d / 2, -n * d / 2};
    double *opd = malloc(sizeof(double) * np * np);
    double ws[8], wd[8];
    for (int l = 0; l < nl; l++) ws[l] = speed ? speed[l] : step, wd[l] = 0.0;
    int sub[32 * 32];
    for (int k = 0, m = 0; k < n * n; k++)
        if (G->valid[k]) sub[m++] = k;
    for (int sd = 0; sd < seeds; sd++) {
        wt_atmosphere_params ap = {nl, alt, frac, ws, wd, r0, L0, 512, 0.125, (uint64_t)(seed0 + sd), 0};
        wt_atmosphere *atm = NULL;
        ck_assert_int_eq(wt_atmosphere_alloc(ctx, &ap, &atm), WT_OK);
        for (int f = 0; f < per_seed; f++) {
            double *sf = s + ((size_t)sd * per_seed + f) * G->nlgs * 2 * ns;
            for (int i = 0; i < G->nlgs; i++) {
                memset(opd, 0, sizeof(double) * np * np);
                ck_assert_int_eq(wt_atmosphere_project(atm, f, 90e3, G->tx[i], G->ty[i], &tg, NULL, 1.0, opd), WT_OK);
                for (int k = 0; k < ns; k++) {
                    int ix = sub[k] % n, iy = sub[k] / n;
                    double gx = 0, gy = 0;
                    for (int u = 0; u <= q; u++) {
                        double w = (u == 0 || u == q ? 0.5 : 1.0) / q;
                        gx += w * (opd[(ix * q + q) + np * (iy * q + u)] - opd[(ix * q) + np * (iy * q + u)]);
                        gy += w * (opd[(ix * q + u) + np * (iy * q + q)] - opd[(ix * q + u) + np * (iy * q)]);
                    }
                    sf[(size_t)i * 2 * ns + k] = gx / d, sf[(size_t)i * 2 * ns + ns + k] = gy / d;
                }
            }
        }
        wt_atmosphere_free(atm);
    }
    free(opd);
}

static void simulate(wt_context *ctx, const geom *G, int nl, const double *alt, const double *frac, double r0,
                     double L0, int seeds, int per_seed, double *s)
{
    simulate_v(ctx, G, nl, alt, frac, NULL, r0, L0, 100, seeds, per_seed, s);
}

static int cmp_desc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x < y) - (x > y);
}

/* The response maps against the covariance of simulated screens at two altitudes: over the offsets (all pairs and
 * components, P(δ) ≥ WT_LEARN_MIN_PAIRS P(0)) that hold 90 % of Σ R², the rms of the difference is within 10 % of
 * the rms of R. Measured (4 sets of seeds): 0.053–0.094 with these 240 frames, 0.054–0.055 with 4× as many; so
 * ~6–7 % is Monte Carlo error (falling as 1/√frames) and ~4–5 % the model's against these screens (64 m period,
 * bilinear sampling at d/4, the 3-point edge quadrature). 10 % holds both at this size (seeds fixed: deterministic). */
START_TEST(test_response_screens)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 10, 3, 30.0);
    const int n = G.n, ns = geom_nsub(&G), S = 2 * n - 1, seeds = 12, per = 20, K = seeds * per;
    const double r0 = 0.15, L0 = 25.0, alts[2] = {0.0, 8000.0};
    double *s = malloc(sizeof(double) * (size_t)K * G.nlgs * 2 * ns);
    for (int ia = 0; ia < 2; ia++) {
        double one = 1.0;
        simulate(ctx, &G, 1, &alts[ia], &one, r0, L0, seeds, per, s);
        wt_learn *L = NULL;
        ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 1, 0, &L), WT_OK);
        for (int t = 0; t < K; t++) ck_assert_int_eq(wt_learn_add(L, s + (size_t)t * G.nlgs * 2 * ns), WT_OK);
        const int np = wt_learn_npairs(L), tot = np * 3 * S * S;
        double *R = malloc(sizeof(double) * 3 * S * S), *map = malloc(sizeof(double) * S * S);
        double *cnt = malloc(sizeof(double) * S * S), *rr = malloc(sizeof(double) * tot), *mm = malloc(sizeof(double) * tot);
        double *sq = malloc(sizeof(double) * tot);
        int m = 0;
        for (int p = 0; p < np; p++) {
            ck_assert_int_eq(wt_learn_response(L, p, 1, &alts[ia], L0, R), WT_OK);
            for (int c = 0; c < 3; c++) {
                ck_assert_int_eq(wt_learn_map(L, -1, p, c, map, cnt), WT_OK);
                for (int o = 0; o < S * S; o++)
                    if (cnt[o] >= WT_LEARN_MIN_PAIRS * cnt[(n - 1) * (S + 1)])
                        rr[m] = R[c * S * S + o] * pow(r0, -5.0 / 3.0), mm[m] = map[o], sq[m] = rr[m] * rr[m], m++;
            }
        }
        qsort(sq, (size_t)m, sizeof *sq, cmp_desc);
        double all = 0, acc = 0, thr = 0;
        for (int k = 0; k < m; k++) all += sq[k];
        for (int k = 0; k < m && acc < 0.9 * all; k++) acc += sq[k], thr = sq[k];
        double dd = 0, rs = 0;
        int used = 0;
        for (int k = 0; k < m; k++)
            if (rr[k] * rr[k] >= thr) dd += (mm[k] - rr[k]) * (mm[k] - rr[k]), rs += rr[k] * rr[k], used++;
        const double rel = sqrt(dd / rs);
        fprintf(stderr, "test_response_screens: h = %g m: rms difference %.3f of rms R over %d of %d offsets\n", alts[ia],
                rel, used, m);
        ck_assert_msg(rel <= 0.10, "h = %g m: response vs screens rms relative difference %.3f > 0.10", alts[ia], rel);
        free(R), free(map), free(cnt), free(rr), free(mm), free(sq);
        wt_learn_free(L);
    }
    free(s);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------- a single layer found at its altitude */

/* One layer at 6 km (demo geometry: 16 x 16 subapertures of 0.5 m, 4 LGS at 45″; altitude resolution d/θ ≈
 * 1.1–1.6 km): ≥ 90 % of the fitted Cn² within one grid step (1 km) of 6 km, and r0 within 10 % (4 sets of seeds:
 * 0.961–1.000 of the Cn² there, r0 −4 % to +2 % from the fit's total; from the small offsets −0.3 % on this set,
 * the batches' spread 0.6 %). */
START_TEST(test_single_layer)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 16, 4, 45.0);
    const int ns = geom_nsub(&G), seeds = 8, per = 30, K = seeds * per;
    const double r0 = 0.15, L0 = 25.0, h = 6000.0, one = 1.0;
    double *s = malloc(sizeof(double) * (size_t)K * G.nlgs * 2 * ns);
    simulate(ctx, &G, 1, &h, &one, r0, L0, seeds, per, s);
    wt_learn *L = NULL;
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 4, K / 4, &L), WT_OK);
    for (int t = 0; t < K; t++) ck_assert_int_eq(wt_learn_add(L, s + (size_t)t * G.nlgs * 2 * ns), WT_OK);
    double alt[WT_LEARN_MAX_ALT];
    const int na = wt_learn_default_grid(90e3, WT_LEARN_MAX_ALT, alt);
    ck_assert_int_eq(na, 22);
    wt_learn_estimate e;
    ck_assert_int_eq(wt_learn_fit(L, na, alt, L0, &e), WT_OK);
    double near = 0;
    for (int a = 0; a < na; a++) {
        if (fabs(alt[a] - h) <= 1000.0) near += e.fraction[a];
        fprintf(stderr, "  %5.1f km  %.3f ± %.3f\n", alt[a] / 1e3, e.fraction[a], e.fraction_sigma[a]);
    }
    fprintf(stderr, "test_single_layer: r0 %.4f ± %.4f m (truth %.3f), %.3f of the Cn² within 1 km of %g km, residual %.3f\n",
            e.r0, e.r0_sigma, r0, near, h / 1e3, e.residual);
    ck_assert_msg(near >= 0.9, "%.3f of the Cn² within 1 km of the layer", near);
    ck_assert_rel(e.r0, r0, 0.10, 0);
    /* the total is the small offsets' (learn_fit.c place_total): Σ c_h = r0^(−5/3) and Σ f_h = 1 to rounding, the
     * whole fit's own total beside it (well-sampled screens: both near the truth) */
    double sc = 0, sf = 0;
    for (int a = 0; a < na; a++) sc += e.cn2[a], sf += e.fraction[a];
    ck_assert_double_eq_tol(sc, pow(e.r0, -5.0 / 3.0), 1e-12 * sc);
    ck_assert_double_eq_tol(sf, 1.0, 1e-12);
    ck_assert_rel(e.r0_total, r0, 0.10, 0);
    ck_assert_int_eq(e.nbatch, 4);
    ck_assert(e.r0_sigma > 0 && e.r0_sigma < 0.05 * r0);
    free(s);
    wt_learn_free(L);
    wt_context_free(ctx);
}
END_TEST


/* The differential statistic (core/model/learn_fit.c): a ground layer is the same phase in every beam, so its own
 * sampling error cancels in C_ij − ½ (C_ii + C_jj) and is not taken for Cn² at altitude. A 6 km layer moving
 * 10 m a frame (240 frames: well sampled) beside a frozen ground layer 4× stronger (one screen: its maps are far
 * from their expected shape): the Cn² fitted at altitude (≥ 3 km) must not depend on which ground screen it is.
 * What is left is the ground × 6 km cross term, zero-mean, relative size ~ √(c_ground / c_6km) / √(independent
 * samples of the 6 km layer) ≈ 2 / √100 (2.4 km of screen through an 8 m pupil, correlated over ~L0 = 25 m) ≈ 20 %
 * on a map, less once fitted over many offsets. Bound 25 %. Measured: 10 % with the differences; the plain fit of
 * C_ij, which this replaces, moved it by 64 % (it took the ground's realisation for Cn² at altitude). */
START_TEST(test_ground_sampling)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 16, 4, 45.0);
    const int ns = geom_nsub(&G), K = 240, nsl = G.nlgs * 2 * ns;
    const double r0 = 0.15, L0 = 25.0, h0 = 0.0, h1 = 6000.0, f0 = 0.8, f1 = 0.2, v0 = 0.0, v1 = 10.0;
    /* each layer alone at r0 f^(−3/5) (its share of the Cn²); slopes are linear in the OPD */
    const double r00 = r0 * pow(f0, -0.6), r01 = r0 * pow(f1, -0.6), one = 1.0;
    double *sa = malloc(sizeof(double) * (size_t)K * nsl), *sg = malloc(sizeof(double) * (size_t)K * nsl);
    simulate_v(ctx, &G, 1, &h1, &one, &v1, r01, L0, 300, 1, K, sa);
    double alt[WT_LEARN_MAX_ALT], high[2];
    const int na = wt_learn_default_grid(90e3, WT_LEARN_MAX_ALT, alt);
    for (int k = 0; k < 2; k++) {
        simulate_v(ctx, &G, 1, &h0, &one, &v0, r00, L0, 400 + k, 1, K, sg);
        for (size_t i = 0; i < (size_t)K * nsl; i++) sg[i] += sa[i];
        wt_learn *L = NULL;
        ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 1, 0, &L), WT_OK);
        for (int t = 0; t < K; t++) ck_assert_int_eq(wt_learn_add(L, sg + (size_t)t * nsl), WT_OK);
        wt_learn_estimate e;
        ck_assert_int_eq(wt_learn_fit(L, na, alt, L0, &e), WT_OK);
        high[k] = 0;
        for (int a = 0; a < na; a++)
            if (alt[a] >= 3000.0) high[k] += e.cn2[a];
        fprintf(stderr, "test_ground_sampling: ground screen %d: Cn² at ≥ 3 km %.4g m^-5/3 (truth %.4g), r0 %.4f m\n", k,
                high[k], f1 * pow(r0, -5.0 / 3.0), e.r0);
        wt_learn_free(L);
    }
    ck_assert_msg(fabs(high[1] - high[0]) <= 0.25 * high[0], "the Cn² at altitude moved by %.1f %% with the ground's screen",
                  100 * fabs(high[1] - high[0]) / high[0]);
    free(sa), free(sg);
    wt_context_free(ctx);
}
END_TEST

/* The grid with a reconstructor's layers: every layer below H kept once, the default points closer than d / (2 θ_max)
 * to one of them dropped, ascending; too many points refused. 4 LGS on a 45" ring: θ_max = 90", s = 573 m. */
START_TEST(test_grid_layers)
{
    geom G;
    geom_make(&G, 16, 4, 45.0);
    const double layer[] = {4500.0, 47.0, 140.0, 9000.0, 95e3, 140.0}, want_s = 0.5 * 0.5 / (90.0 * ARCSEC);
    double alt[WT_LEARN_MAX_ALT], s = 0.0;
    const int na = wt_learn_grid_with_layers(&G.g, 6, layer, WT_LEARN_MAX_ALT, alt, &s);
    ck_assert_double_eq_tol(s, want_s, 1e-9 * want_s);
    /* 22 default points less 0, 0.5, 4, 5 and 9 km (9 km is a layer itself), plus the 4 layers below H */
    ck_assert_int_eq(na, 22 - 5 + 4);
    const double head[] = {47.0, 140.0, 1000.0, 2000.0, 3000.0, 4500.0, 6000.0, 7000.0, 8000.0, 9000.0, 10000.0};
    for (int k = 0; k < 11; k++) ck_assert_double_eq(alt[k], head[k]);
    for (int k = 1; k < na; k++) ck_assert(alt[k] > alt[k - 1]);
    ck_assert_int_eq(wt_learn_grid_with_layers(&G.g, 6, layer, 12, alt, NULL), WT_ERR_INVALID);
}
END_TEST

/* ---------------------------------------------------------------- reset, and one model for many fits */

/* After wt_learn_reset and the same frames again, every map (lag 0 and lagged) is bit-identical to a fresh object's
 * (the spectra are zeroed, not approximately cancelled); a model built once fits as wt_learn_fit does, bit for bit, and refuses an
 * accumulator of another geometry. */
START_TEST(test_reset_model)
{
    wt_context *ctx = tu_context();
    geom G, G2;
    geom_make(&G, 10, 3, 30.0);
    geom_make(&G2, 10, 3, 40.0);
    const int ns = geom_nsub(&G), S = 2 * 10 - 1, K = 12, fl = G.nlgs * 2 * ns;
    double *s = malloc(sizeof(double) * (size_t)K * fl), *junk = malloc(sizeof(double) * fl);
    const double h = 5000.0, one = 1.0;
    simulate(ctx, &G, 1, &h, &one, 0.15, 25.0, 2, K / 2, s); /* a profile the fit can find */
    tu_randn(junk, fl, 32);
    wt_learn *A = NULL, *B = NULL, *C = NULL;
    const int lags[2] = {1, 3};
    ck_assert_int_eq(wt_learn_alloc_lagged(ctx, &G.g, 3, 4, 2, lags, &A), WT_OK);
    ck_assert_int_eq(wt_learn_alloc_lagged(ctx, &G.g, 3, 4, 2, lags, &B), WT_OK);
    ck_assert_int_eq(wt_learn_alloc(ctx, &G2.g, 3, 4, &C), WT_OK);
    for (int t = 0; t < 7; t++) ck_assert_int_eq(wt_learn_add(A, junk), WT_OK);
    wt_learn_reset(A);
    ck_assert_int_eq(wt_learn_frames(A), 0);
    for (int t = 0; t < K; t++) {
        ck_assert_int_eq(wt_learn_add(A, s + (size_t)t * fl), WT_OK);
        ck_assert_int_eq(wt_learn_add(B, s + (size_t)t * fl), WT_OK);
        ck_assert_int_eq(wt_learn_add(C, s + (size_t)t * fl), WT_OK);
    }
    double *ma = malloc(sizeof(double) * S * S), *mb = malloc(sizeof(double) * S * S);
    for (int b = -1; b < 3; b++)
        for (int p = 0; p < wt_learn_npairs(A); p++)
            for (int c = 0; c < 3; c++) {
                ck_assert_int_eq(wt_learn_map(A, b, p, c, ma, NULL), WT_OK);
                ck_assert_int_eq(wt_learn_map(B, b, p, c, mb, NULL), WT_OK);
                ck_assert(!memcmp(ma, mb, sizeof(double) * S * S));
            }
    /* the lagged maps too: the ring's frames from before the reset are never paired with the new ones */
    for (int b = -1; b < 3; b++)
        for (int q = 0; q < 2; q++)
            for (int i = 0; i < G.nlgs; i++)
                for (int j = 0; j < G.nlgs; j++)
                    for (int c = 0; c < 2; c++) {
                        ck_assert_int_eq(wt_learn_lag_map(A, b, q, i, j, c, ma, NULL), WT_OK);
                        ck_assert_int_eq(wt_learn_lag_map(B, b, q, i, j, c, mb, NULL), WT_OK);
                        ck_assert(!memcmp(ma, mb, sizeof(double) * S * S));
                    }
    double alt[WT_LEARN_MAX_ALT];
    const int na = wt_learn_default_grid(90e3, WT_LEARN_MAX_ALT, alt);
    wt_learn_model *M = NULL;
    ck_assert_int_eq(wt_learn_model_alloc(A, na, alt, 25.0, &M), WT_OK);
    wt_learn_estimate e1, e2, e3;
    ck_assert_int_eq(wt_learn_fit_model(B, M, &e1), WT_OK);
    ck_assert_int_eq(wt_learn_fit(A, na, alt, 25.0, &e2), WT_OK);
    ck_assert(!memcmp(e1.cn2, e2.cn2, sizeof e1.cn2) && e1.r0 == e2.r0 && e1.residual == e2.residual);
    ck_assert(!memcmp(e1.batch_r0, e2.batch_r0, sizeof e1.batch_r0) && e1.rows == e2.rows && e1.nbatch == 3);
    ck_assert_int_eq(wt_learn_fit_model(C, M, &e3), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "another geometry"));
    alt[1] = -5;
    wt_learn_model *M2 = NULL;
    ck_assert_int_eq(wt_learn_model_alloc(A, na, alt, 25.0, &M2), WT_ERR_INVALID);
    ck_assert_ptr_null(M2);
    wt_learn_model_free(M);
    wt_learn_free(A), wt_learn_free(B), wt_learn_free(C);
    free(s), free(junk), free(ma), free(mb);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------- refusals */

START_TEST(test_refusals)
{
    wt_context *ctx = tu_context();
    geom G;
    geom_make(&G, 8, 2, 30.0);
    wt_learn *L = NULL;
    wt_learn_geometry bad = G.g;
    bad.H = 0;
    ck_assert_int_eq(wt_learn_alloc(ctx, &bad, 1, 0, &L), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "range H"));
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 0, 0, &L), WT_ERR_INVALID);
    ck_assert_int_eq(wt_learn_alloc(ctx, &G.g, 1, 0, &L), WT_OK);
    double alt[3] = {0, 1000, 2000};
    wt_learn_estimate e;
    ck_assert_int_eq(wt_learn_fit(L, 3, alt, 25.0, &e), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "at least 2"));
    double s[2 * 2 * 64] = {0};
    tu_randn(s, 2 * 2 * 40, 5);
    ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    ck_assert_int_eq(wt_learn_fit(L, 3, alt, 25.0, &e), WT_ERR_INVALID);
    alt[2] = 500;
    ck_assert_int_eq(wt_learn_add(L, s), WT_OK);
    ck_assert_int_eq(wt_learn_fit(L, 3, alt, 25.0, &e), WT_ERR_INVALID);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "not increasing"));
    alt[2] = 95e3;
    ck_assert_int_eq(wt_learn_fit(L, 3, alt, 25.0, &e), WT_ERR_INVALID);
    wt_learn_free(L);
    wt_context_free(ctx);
}
END_TEST


/* ---------------------------------------------------------------- the command */

static char wt[512], dir[64];

#define run(...) tu_run(wt, dir, __VA_ARGS__)
#define file_has(name, text) tu_file_has(dir, name, text)

/* A telemetry-like file: the demo's configuration (or none), F frames of slopes_ol (or none) */
static void write_tel(const char *path, int with_config, int with_ol, int F)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    wt_h5_writer *w;
    wt_h5_series *so;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    if (with_config) ck_assert_int_eq(wt_h5_write_string(w, "config", cfg->canonical, "configuration"), WT_OK);
    const int64_t nslopes = 1548; /* the demo system's slopes (wavetomo info) */
    ck_assert_int_eq(wt_h5_series_create(w, with_ol ? "slopes_ol" : "slopes", WT_H5_F32, nslopes, "rad", "slopes", &so),
                     WT_OK);
    float *buf = calloc((size_t)nslopes, sizeof *buf);
    for (int t = 0; t < F; t++) {
        for (int64_t i = 0; i < nslopes; i++) buf[i] = 1e-7f * (float)((i * 7 + t) % 13);
        ck_assert_int_eq(wt_h5_series_append(so, WT_H5_F32, buf), WT_OK);
    }
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    free(buf);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}

/* Refusals, each naming the file and what is missing, exit 1 and no output; then a short demo telemetry learnt */
START_TEST(test_command)
{
    tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_learn_");
    char p[256];
    ck_assert_int_eq(run("learn --help"), 0);
    ck_assert_int_eq(run("learn --telemetry %s/none.h5 --out %s/e.h5", dir, dir), 1);
    ck_assert(file_has("stderr.txt", "none.h5"));
    snprintf(p, sizeof p, "%s/noconf.h5", dir);
    write_tel(p, 0, 1, 30);
    ck_assert_int_eq(run("learn --telemetry %s --out %s/e.h5", p, dir), 1);
    ck_assert(file_has("stderr.txt", "no dataset 'config'"));
    snprintf(p, sizeof p, "%s/nool.h5", dir);
    write_tel(p, 1, 0, 30);
    ck_assert_int_eq(run("learn --telemetry %s --out %s/e.h5", p, dir), 1);
    ck_assert(file_has("stderr.txt", "pseudo-open-loop"));
    ck_assert(file_has("stderr.txt", "nool.h5"));
    snprintf(p, sizeof p, "%s/short.h5", dir);
    write_tel(p, 1, 1, 12);
    ck_assert_int_eq(run("learn --telemetry %s --out %s/e.h5", p, dir), 1);
    ck_assert(file_has("stderr.txt", "12 frames, fewer than an estimate"));
    ck_assert_int_eq(run("learn --telemetry %s --out %s/e.h5 --batches 2 --frames 13", p, dir), 1);
    ck_assert(file_has("stderr.txt", "fewer than --frames 13"));
    ck_assert_int_eq(run("learn --telemetry %s --out %s/e.h5 --config data/presets/demo.cfg --set lgs.radius_arcsec=40", p,
                         dir), 1);
    ck_assert(file_has("stderr.txt", "another system"));
    ck_assert(file_has("stderr.txt", "lgs.radius_arcsec"));
    snprintf(p, sizeof p, "%s/e.h5", dir);
    ck_assert_int_ne(access(p, F_OK), 0);
    /* a short closed loop's telemetry (60 frames: the numbers mean little, the chain and the file are the point) */
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --recon pcg3 --frames 60 --telemetry %s/tel.h5 --out %s/r.h5 "
                         "--quiet", dir, dir), 0);
    ck_assert_int_eq(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --wind", dir, dir), 1);
    ck_assert(file_has("stderr.txt", "too few for the wind's longest lag of 96 frames"));
    ck_assert_int_eq(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --lags 70", dir, dir), 1);
    ck_assert(file_has("stderr.txt", "too few for the wind's longest lag of 70 frames"));
    ck_assert_int_eq(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --lags 2,1", dir, dir), 2);
    /* --wind-png without its file, and into a directory that does not exist: refused, nothing written */
    ck_assert_int_eq(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --wind-png", dir, dir), 2);
    ck_assert_int_ne(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --lags 1,2 --wind-threshold 0.3 "
                         "--wind-png %s/no/such/dir/w.png", dir, dir, dir), 0);
    /* the wind of the strongest layer only (--wind-threshold 0.3: one layer, no search), two short lags: the chain
     * and the file; the accuracy is test_wind's */
    ck_assert_int_eq(run("learn --telemetry %s/tel.h5 --out %s/e.h5 --quiet --lags 1,2 --wind-threshold 0.3 "
                         "--wind-png %s/w.png", dir, dir, dir), 0);
    ck_assert(file_has("stdout.txt", "r0 (500 nm)"));
    ck_assert(file_has("stdout.txt", "wind plot:"));
    {
        char path[512], sig[8] = {0};
        snprintf(path, sizeof path, "%s/w.png", dir);
        FILE *f = fopen(path, "rb");
        ck_assert_ptr_nonnull(f);
        ck_assert_int_eq(fread(sig, 1, 8, f), 8);
        fclose(f);
        ck_assert(!memcmp(sig, "\x89PNG\r\n\x1a\n", 8));
    }
    ck_assert(file_has("stdout.txt", "compressed onto cg9's layers"));
    ck_assert(file_has("stdout.txt", "wind on pcg3's layers"));
    wt_context *ctx = tu_context();
    wt_h5_reader *r;
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    double r0;
    ck_assert_int_eq(wt_h5_read_double(r, "estimate/r0_m", &r0), WT_OK);
    ck_assert(r0 > 0.03 && r0 < 1.0);
    char *u = NULL;
    ck_assert_int_eq(wt_h5_attr_read_string(r, "estimate/pcg3/cn2_fraction", "description", &u), WT_OK);
    ck_assert_ptr_nonnull(strstr(u, "pcg3"));
    wt_free(ctx, u);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "estimate/wind/direction_rad", "description", &u), WT_OK);
    ck_assert_ptr_nonnull(strstr(u, "counter-clockwise from +x"));
    wt_free(ctx, u);
    ck_assert(wt_h5_exists(r, "truth/cg9/wind_speed_mps") && wt_h5_exists(r, "estimate/pcg3/wind_vx_sigma_mps"));
    wt_h5_close(r);
    wt_context_free(ctx);
    tu_cli_teardown(dir);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("learn");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_map_direct);
    tcase_add_test(tc, test_alloc);
    tcase_add_test(tc, test_nnls);
    tcase_add_test(tc, test_response_screens);
    tcase_add_test(tc, test_single_layer);
    tcase_add_test(tc, test_ground_sampling);
    tcase_add_test(tc, test_grid_layers);
    tcase_add_test(tc, test_reset_model);
    tcase_add_test(tc, test_refusals);
    tcase_add_test(tc, test_command);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
