/* core/op/noise.c: the Shack–Hartmann noise covariance C_E of one sensor, its inverse and the LGS weight.
 *
 * Implements SPEC §4 and the paper's eq. elongation_matrix (C̃_i = σ²(I + (τ/θf²) β_i β_iᵀ), one 2x2
 * block per subaperture) and eq. widehatc (Ĉ⁻¹ = (I − T) C̃⁻¹ (I − T), T the orthogonal projection onto
 * the sensor's global tip and tilt). With the LGS focus removal T also projects onto the focus slope pattern f
 * (f ∝ (x_i − x̄, y_i − ȳ) over the valid subapertures, unit norm: orthogonal to tip and tilt because its halves
 * have zero mean), T = T_tt + f fᵀ, which is again an orthogonal projector. Everything block-wise is precomputed at alloc: the inverse blocks
 * (Sherman–Morrison), the covariance blocks and their Cholesky factors (for sampling), and the inverse blocks
 * rounded to float (for the fp32 weight).
 */
#include "noise.h"

#include <math.h>

struct wt_noise {
    wt_context *ctx;
    int nsub;
    int remove_tt;
    double sigma2;    /* per-axis variance [rad²] */
    double spot_fwhm; /* θf [rad] */
    double tau;       /* elongation weight of the model, in [0, 1] */
    /* Structure-of-arrays, nsub each, so the apply loops vectorise. */
    double *ia, *ib, *ic;    /* C̃_i⁻¹ = [[ia, ib], [ib, ic]] [1/rad²] */
    double *ca, *cb, *cc;    /* C̃_i   = [[ca, cb], [cb, cc]] [rad²] */
    double *l11, *l21, *l22; /* C̃_i = L Lᵀ, L = [[l11, 0], [l21, l22]] [rad] */
    float *fa, *fb, *fc;     /* ia, ib, ic rounded to float, for wt_noise_set_weight_many_f32 */
    double *store;           /* the one allocation the twelve arrays live in */
    double *focus;           /* NULL, or the unit focus pattern f (2 nsub) that T projects out as well */
};

double wt_noise_variance(double photons, double read_noise_e, double spot_fwhm, double pixel, int pixels,
                         double nea)
{
    if (nea > 0.0) return nea * nea;
    /* No photons and no NEA: there is no measurement, an infinite variance (rejected by alloc). */
    if (!(photons > 0.0)) return INFINITY;
    double ns2 = (double)pixels * (double)pixels;
    return spot_fwhm * spot_fwhm / (8.0 * log(2.0) * photons) +
           pixel * pixel * read_noise_e * read_noise_e * ns2 * ns2 / (12.0 * photons * photons);
}

double wt_noise_loop_gain(double gain, int delay)
{
    /* impulse response of the loop to a unit measurement at t = 0, summed until it has decayed: it
     * decays geometrically for the config's stable gains (g ≤ 1, d ≤ 2); a holds a_{t}..a_{t+d} */
    enum { N = 20000 };
    double a[3] = {0.0, 0.0, 0.0}, s = 0.0;
    for (int t = 0; t + delay < N; t++) {
        const double next = a[delay - 1] + gain * ((t == 0 ? 1.0 : 0.0) - a[0]);
        for (int k = 0; k < delay - 1; k++) a[k] = a[k + 1];
        a[delay - 1] = next;
        s += next * next;
    }
    return s;
}

void wt_noise_elongation(int nsub, const double *cx, const double *cy, double launch_x, double launch_y,
                         double sodium_fwhm, double lgs_altitude, double *beta)
{
    /* The sodium column of thickness Δh seen from a baseline b = r − l subtends b Δh / H² (small angles). */
    double s = sodium_fwhm / (lgs_altitude * lgs_altitude);
    for (int i = 0; i < nsub; i++) {
        beta[i] = (cx[i] - launch_x) * s;
        beta[nsub + i] = (cy[i] - launch_y) * s;
    }
}

void wt_noise_free(wt_noise *n)
{
    if (!n) return;
    wt_context *ctx = n->ctx;
    wt_free(ctx, n->store);
    wt_free(ctx, n->focus);
    wt_free(ctx, n);
}

double wt_noise_lit_factor(double photons, double read_noise_e, double spot_fwhm, double pixel, int pixels,
                           double nea, double lit)
{
    if (nea > 0.0) return 1.0 / lit; /* photon-noise limited: σ² ∝ 1/N */
    return wt_noise_variance(photons * lit, read_noise_e, spot_fwhm, pixel, pixels, nea) /
           wt_noise_variance(photons, read_noise_e, spot_fwhm, pixel, pixels, nea);
}

/* The one allocation the nine double block arrays of n (n->nsub each) and the three float ones after them live
 * in; the floats take ⌈3 nsub / 2⌉ doubles' room. */
static int alloc_store(wt_noise *n)
{
    wt_context *ctx = n->ctx;
    const int nsub = n->nsub;
    int st = WT_OK;
    WT_ALLOC(ctx, n->store, (size_t)9 * (size_t)nsub + ((size_t)3 * (size_t)nsub + 1) / 2, "noise blocks");
    double *p = n->store;
    n->ia = p, p += nsub;
    n->ib = p, p += nsub;
    n->ic = p, p += nsub;
    n->ca = p, p += nsub;
    n->cb = p, p += nsub;
    n->cc = p, p += nsub;
    n->l11 = p, p += nsub;
    n->l21 = p, p += nsub;
    n->l22 = p, p += nsub;
    float *f = (float *)p;
    n->fa = f, f += nsub;
    n->fb = f, f += nsub;
    n->fc = f;
fail:
    return st;
}

/* The float copies of the inverse blocks, once these are final: 1/σ² of any real sensor (σ ≫ 1e-19 rad) is far
 * inside float's range. */
static void round_blocks(wt_noise *n)
{
    for (int i = 0; i < n->nsub; i++) {
        n->fa[i] = (float)n->ia[i];
        n->fb[i] = (float)n->ib[i];
        n->fc[i] = (float)n->ic[i];
    }
}

int wt_noise_alloc(wt_context *ctx, int nsub, double sigma2, double spot_fwhm, const double *beta, double tau,
                   int remove_tt, wt_noise **out)
{
    return wt_noise_alloc_scaled(ctx, nsub, sigma2, NULL, spot_fwhm, beta, tau, remove_tt, out);
}

int wt_noise_alloc_scaled(wt_context *ctx, int nsub, double sigma2, const double *scale, double spot_fwhm,
                          const double *beta, double tau, int remove_tt, wt_noise **out)
{
    int st = WT_OK;
    wt_noise *n = NULL;
    *out = NULL;
    if (nsub < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "noise: nsub = %d, expected at least 1 subaperture", nsub);
    if (!(sigma2 > 0.0) || !isfinite(sigma2))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "noise: per-axis variance sigma2 = %g rad^2, expected finite and > 0 "
                        "(a noiseless sensor needs no noise model)",
                        sigma2);
    if (!(tau >= 0.0 && tau <= 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "noise: elongation weight tau = %g, expected in [0, 1]", tau);
    if (!(spot_fwhm > 0.0) || !isfinite(spot_fwhm))
        return WT_ERROR(ctx, WT_ERR_INVALID, "noise: spot FWHM = %g rad, expected finite and > 0", spot_fwhm);
    if (scale) {
        for (int i = 0; i < nsub; i++)
            if (!(scale[i] > 0.0) || !isfinite(scale[i]))
                return WT_ERROR(ctx, WT_ERR_INVALID, "noise: variance factor of subaperture %d is %g, expected finite and > 0",
                                i, scale[i]);
    }
    if (beta) {
        for (int i = 0; i < 2 * nsub; i++)
            if (!isfinite(beta[i]))
                return WT_ERROR(ctx, WT_ERR_INVALID, "noise: elongation vector entry %d is %g, expected finite", i,
                                beta[i]);
    }

    WT_ALLOC(ctx, n, 1, "noise model");
    n->ctx = ctx;
    n->nsub = nsub;
    n->remove_tt = remove_tt ? 1 : 0;
    n->sigma2 = sigma2;
    n->spot_fwhm = spot_fwhm;
    n->tau = tau;
    WT_TRY(alloc_store(n));

    double g = tau / (spot_fwhm * spot_fwhm);
    for (int i = 0; i < nsub; i++) {
        const double s2 = scale ? sigma2 * scale[i] : sigma2;
        double bx = beta ? beta[i] : 0.0, by = beta ? beta[nsub + i] : 0.0;
        double gxx = g * bx * bx, gxy = g * bx * by, gyy = g * by * by;
        double q = 1.0 + gxx + gyy; /* det(C̃_i) / σ⁴ = 1 + γ|β|² >= 1 */
        n->ca[i] = s2 * (1.0 + gxx);
        n->cb[i] = s2 * gxy;
        n->cc[i] = s2 * (1.0 + gyy);
        /* Sherman–Morrison: (I + γββᵀ)⁻¹ = I − γββᵀ / (1 + γ|β|²); no cancellation since q >= 1. */
        n->ia[i] = (1.0 - gxx / q) / s2;
        n->ib[i] = (-gxy / q) / s2;
        n->ic[i] = (1.0 - gyy / q) / s2;
        double l11 = sqrt(n->ca[i]);
        n->l11[i] = l11;
        n->l21[i] = n->cb[i] / l11;
        /* l22² = det / C11 exactly, avoiding the cancellation of C22 − l21² for long spots. */
        n->l22[i] = sqrt(s2 * q / (1.0 + gxx));
    }
    round_blocks(n);
    *out = n;
    return WT_OK;
fail:
    wt_noise_free(n);
    return st;
}

int wt_noise_alloc_blocks(wt_context *ctx, int nsub, const double *cov, double tau, int remove_tt, wt_noise **out)
{
    int st = WT_OK;
    wt_noise *n = NULL;
    *out = NULL;
    if (nsub < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "noise: nsub = %d, expected at least 1 subaperture", nsub);
    if (!(tau >= 0.0 && tau <= 1.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "noise: elongation weight tau = %g, expected in [0, 1]", tau);
    if (!cov) return WT_ERROR(ctx, WT_ERR_INVALID, "noise: the covariance blocks are NULL");
    for (int i = 0; i < nsub; i++) {
        const double a = cov[i], b = cov[nsub + i], c = cov[2 * nsub + i];
        if (!isfinite(a) || !isfinite(b) || !isfinite(c) || !(a > 0.0) || !(c > 0.0) || !(a * c - b * b > 0.0))
            return WT_ERROR(ctx, WT_ERR_INVALID,
                            "noise: covariance block of subaperture %d is [[%g, %g], [%g, %g]] rad^2, expected finite "
                            "and positive definite", i, a, b, b, c);
    }
    WT_ALLOC(ctx, n, 1, "noise model");
    n->ctx = ctx;
    n->nsub = nsub;
    n->remove_tt = remove_tt ? 1 : 0;
    n->tau = tau;
    WT_TRY(alloc_store(n));
    double smin = INFINITY;
    for (int i = 0; i < nsub; i++) {
        const double a0 = cov[i], b0 = cov[nsub + i], c0 = cov[2 * nsub + i];
        /* smaller eigenvalue without cancellation: det / larger one */
        const double h = 0.5 * (a0 + c0), r = hypot(0.5 * (a0 - c0), b0), lmax = h + r, lmin = (a0 * c0 - b0 * b0) / lmax;
        const double a = lmin + tau * (a0 - lmin), b = tau * b0, c = lmin + tau * (c0 - lmin);
        const double det = a * c - b * b;
        n->ca[i] = a, n->cb[i] = b, n->cc[i] = c;
        n->ia[i] = c / det, n->ib[i] = -b / det, n->ic[i] = a / det;
        n->l11[i] = sqrt(a);
        n->l21[i] = b / n->l11[i];
        n->l22[i] = sqrt(det / a);
        smin = fmin(smin, lmin);
    }
    n->sigma2 = smin;
    n->spot_fwhm = NAN; /* not a Gaussian-spot model */
    round_blocks(n);
    *out = n;
    return WT_OK;
fail:
    wt_noise_free(n);
    return st;
}

int wt_noise_nslopes(const wt_noise *n) { return 2 * n->nsub; }

double wt_noise_mean_variance(const wt_noise *n)
{
    double s = 0.0;
    for (int i = 0; i < n->nsub; i++) s += 0.5 * (n->ca[i] + n->cc[i]);
    return s / n->nsub;
}

/* y ← y + α B x for the m symmetric 2x2 blocks B_i = [[a_i, b_i], [b_i, c_i]] acting on (x_i, x_{m+i}) */
static void apply_blocks(int m, const double *a, const double *b, const double *c, double alpha, const double *x,
                         double *y)
{
    const double *xx = x, *xy = x + m;
    double *yx = y, *yy = y + m;
    for (int i = 0; i < m; i++) {
        double u = xx[i], v = xy[i];
        yx[i] += alpha * (a[i] * u + b[i] * v);
        yy[i] += alpha * (b[i] * u + c[i] * v);
    }
}

void wt_noise_apply_cov(const wt_noise *n, double alpha, const double *x, double *y)
{
    apply_blocks(n->nsub, n->ca, n->cb, n->cc, alpha, x, y);
}

void wt_noise_apply_inv(const wt_noise *n, double alpha, const double *x, double *y)
{
    apply_blocks(n->nsub, n->ia, n->ib, n->ic, alpha, x, y);
}

/* T x puts the mean of the x-slopes in every x entry and the mean of the y-slopes in every y entry:
 * the projection onto span{(1…1, 0…0), (0…0, 1…1)}, orthogonal because the two vectors are. */
static void means(int m, const double *x, double *mx, double *my)
{
    double sx = 0.0, sy = 0.0;
    for (int i = 0; i < m; i++) {
        sx += x[i];
        sy += x[m + i];
    }
    *mx = sx / m;
    *my = sy / m;
}

enum { MANY = 4 };

/* A batch: up to MANY consecutive sensors from j with the tip-tilt removal and the first one's size. */
static int batch_size(const wt_noise *const *ns, int k, int j)
{
    int b = 1;
    if (ns[j]->remove_tt && !ns[j]->focus)
        while (b < MANY && j + b < k && ns[j + b]->remove_tt && !ns[j + b]->focus && ns[j + b]->nsub == ns[j]->nsub)
            b++;
    return b;
}

/* The x and y means of B sensors' slopes (each sensor's two sums as its own chain, in slope order). */
static inline __attribute__((always_inline)) void batch_means(const int B, int m, const double *const *x, double *mx,
                                                              double *my)
{
    for (int q = 0; q < B; q++) mx[q] = my[q] = 0.0;
    for (int i = 0; i < m; i++)
        for (int q = 0; q < B; q++) {
            mx[q] += x[q][i];
            my[q] += x[q][m + i];
        }
    for (int q = 0; q < B; q++) {
        mx[q] /= m;
        my[q] /= m;
    }
}

/* y −= α T v for B sensors, from the sums svx, svy of v's halves. */
static inline __attribute__((always_inline)) void take_means(const int B, int m, double alpha, const double *svx,
                                                             const double *svy, double *const *y)
{
    for (int q = 0; q < B; q++) {
        const double dx = alpha * svx[q] / m, dy = alpha * svy[q] / m;
        double *restrict yy = y[q];
        for (int i = 0; i < m; i++) {
            yy[i] -= dx;
            yy[m + i] -= dy;
        }
    }
}

/* y += α (I − T) v with v = C̃⁻¹ (x − T x), in three O(n) passes and no scratch: T x and T v need only the
 * two means of each, so v is added to y while its means are summed, and α T v is then taken off y. For B
 * sensors of one size at once (wt_noise_apply_weight_many; 1 for wt_noise_apply_weight), each sensor's
 * sums in its own order; B is a compile-time constant at each call (always inlined), so the 4 B sums live
 * in registers. */
static inline __attribute__((always_inline)) void weight_batch(const int B, const wt_noise *const *ns, double alpha,
                                                               const double *const *x, double *const *y)
{
    const int m = ns[0]->nsub;
    double mx[MANY], my[MANY], svx[MANY], svy[MANY];
    for (int q = 0; q < B; q++) svx[q] = svy[q] = 0.0;
    batch_means(B, m, x, mx, my);
    for (int i = 0; i < m; i++)
        for (int q = 0; q < B; q++) {
            const wt_noise *n = ns[q];
            double u = x[q][i] - mx[q], v = x[q][m + i] - my[q];
            double vx = n->ia[i] * u + n->ib[i] * v;
            double vy = n->ib[i] * u + n->ic[i] * v;
            svx[q] += vx;
            svy[q] += vy;
            y[q][i] += alpha * vx;
            y[q][m + i] += alpha * vy;
        }
    take_means(B, m, alpha, svx, svy, y);
}

/* y += α (I − T) C̃⁻¹ (I − T) x with T = T_tt + f fᵀ: the means and fᵀx, v = C̃⁻¹ (x − T x) added to y while its
 * means and fᵀv are summed, then α T v taken off (one sensor at a time: the focus removal is an option) */
static void weight_focus(const wt_noise *n, double alpha, const double *x, double *y)
{
    const int m = n->nsub;
    const double *f = n->focus;
    double mx, my, a = 0.0, svx = 0.0, svy = 0.0, b = 0.0;
    means(m, x, &mx, &my);
    for (int i = 0; i < 2 * m; i++) a += f[i] * x[i];
    for (int i = 0; i < m; i++) {
        const double u = x[i] - mx - a * f[i], v = x[m + i] - my - a * f[m + i];
        const double vx = n->ia[i] * u + n->ib[i] * v, vy = n->ib[i] * u + n->ic[i] * v;
        svx += vx;
        svy += vy;
        b += f[i] * vx + f[m + i] * vy;
        y[i] += alpha * vx;
        y[m + i] += alpha * vy;
    }
    const double dx = alpha * svx / m, dy = alpha * svy / m, db = alpha * b;
    for (int i = 0; i < m; i++) {
        y[i] -= dx + db * f[i];
        y[m + i] -= dy + db * f[m + i];
    }
}

void wt_noise_apply_weight(const wt_noise *n, double alpha, const double *x, double *y)
{
    if (!n->remove_tt) {
        wt_noise_apply_inv(n, alpha, x, y);
        return;
    }
    if (n->focus) {
        weight_focus(n, alpha, x, y);
        return;
    }
    weight_batch(1, &n, alpha, &x, &y);
}

void wt_noise_apply_weight_many(const wt_noise *const *ns, int k, double alpha, const double *const *x,
                                double *const *y)
{
    int j = 0;
    while (j < k) {
        const int b = batch_size(ns, k, j);
        switch (b) {
        case 4: weight_batch(4, ns + j, alpha, x + j, y + j); break;
        case 3: weight_batch(3, ns + j, alpha, x + j, y + j); break;
        case 2: weight_batch(2, ns + j, alpha, x + j, y + j); break;
        default: wt_noise_apply_weight(ns[j], alpha, x[j], y[j]); break;
        }
        j += b;
    }
}

/* y = Ĉ⁻¹ x for B sensors of one size with the tip-tilt removal, y overwritten: the bits of weight_batch(B, ns,
 * 1.0, x, y) on y cleared to +0, in four passes of which two are contiguous vector arithmetic:
 *   means (B·2 chains, as weight_batch), v = C̃⁻¹ (x − T x) stored as y = 0 + v (what +0 += 1·v gives), the
 *   means of v summed from y (0 + v differs from v only for v = −0, and a chain that starts at +0 never holds −0,
 *   so adding +0 or −0 to it gives the same bits), and y −= mean. */
/* y = 0 + C̃⁻¹ (x − (ax, ay)) block by block: the halves as restrict parameters, so that the loop vectorises */
static inline __attribute__((always_inline)) void set_products(int m, const double *restrict xx,
                                                               const double *restrict xy, const double *restrict ia,
                                                               const double *restrict ib, const double *restrict ic,
                                                               double ax, double ay, double *restrict yx,
                                                               double *restrict yy)
{
    for (int i = 0; i < m; i++) {
        const double u = xx[i] - ax, v = xy[i] - ay;
        yx[i] = 0.0 + (ia[i] * u + ib[i] * v);
        yy[i] = 0.0 + (ib[i] * u + ic[i] * v);
    }
}

static inline __attribute__((always_inline)) void set_batch(const int B, const wt_noise *const *ns,
                                                            const double *const *x, double *const *y)
{
    const int m = ns[0]->nsub;
    double mx[MANY], my[MANY], svx[MANY], svy[MANY];
    for (int q = 0; q < B; q++) svx[q] = svy[q] = 0.0;
    batch_means(B, m, x, mx, my);
    for (int q = 0; q < B; q++) {
        set_products(m, x[q], x[q] + m, ns[q]->ia, ns[q]->ib, ns[q]->ic, mx[q], my[q], y[q], y[q] + m);
    }
    for (int i = 0; i < m; i++)
        for (int q = 0; q < B; q++) {
            svx[q] += y[q][i];
            svy[q] += y[q][m + i];
        }
    take_means(B, m, 1.0, svx, svy, y);
}

WT_CPU_CLONES void wt_noise_set_weight_many(const wt_noise *const *ns, int k, const double *const *x, double *const *y)
{
    int j = 0;
    while (j < k) {
        const int b = batch_size(ns, k, j);
        switch (b) {
        case 4: set_batch(4, ns + j, x + j, y + j); break;
        case 3: set_batch(3, ns + j, x + j, y + j); break;
        case 2: set_batch(2, ns + j, x + j, y + j); break;
        default:
            if (ns[j]->focus) {
                for (int i = 0; i < 2 * ns[j]->nsub; i++) y[j][i] = 0.0;
                weight_focus(ns[j], 1.0, x[j], y[j]);
            } else if (ns[j]->remove_tt) set_batch(1, ns + j, x + j, y + j);
            else {
                for (int i = 0; i < 2 * ns[j]->nsub; i++) y[j][i] = 0.0;
                wt_noise_apply_inv(ns[j], 1.0, x[j], y[j]);
            }
            break;
        }
        j += b;
    }
}

/* The float weight's sums: LANES independent double partial sums per sum, so that the adder's latency is hidden
 * (one chain waits ~4 cycles per subaperture) and a block of LANES subapertures is a few vector instructions.
 * 16 lanes are two AVX-512 or four AVX2 registers per sum, enough chains in flight for either; with 8, GCC 12
 * leaves the AVX-512 clone's products scalar, 32 gains nothing. */
enum { LANES = 16 };

static inline __attribute__((always_inline)) double lanes_total(const double *acc)
{
    double s = 0.0;
    for (int l = 0; l < LANES; l++) s += acc[l];
    return s;
}

/* Σ x[i] over i < m in double. One half at a time: with both halves' lanes in one loop GCC leaves the AVX-512
 * clone scalar. */
static inline __attribute__((always_inline)) double sum_f32(int m, const float *restrict x)
{
    double acc[LANES] = {0.0};
    int i = 0;
    for (; i + LANES <= m; i += LANES)
        for (int l = 0; l < LANES; l++) acc[l] += (double)x[i + l];
    for (int l = 0; i < m; i++, l++) acc[l] += (double)x[i];
    return lanes_total(acc);
}

/* y = C̃⁻¹ (x − (ax, ay)) in float, block by block, and the sums of its two halves in double as it is written
 * (the tip-tilt of v, one pass over x and y instead of two). */
static inline __attribute__((always_inline)) void products_f32(int m, const float *restrict xx,
                                                               const float *restrict xy, const float *restrict a,
                                                               const float *restrict b, const float *restrict c,
                                                               float ax, float ay, float *restrict yx,
                                                               float *restrict yy, double *sx, double *sy)
{
    double acx[LANES] = {0.0}, acy[LANES] = {0.0};
    int i = 0;
    for (; i + LANES <= m; i += LANES)
        for (int l = 0; l < LANES; l++) {
            const float u = xx[i + l] - ax, v = xy[i + l] - ay;
            const float vx = a[i + l] * u + b[i + l] * v, vy = b[i + l] * u + c[i + l] * v;
            yx[i + l] = vx;
            yy[i + l] = vy;
            acx[l] += (double)vx;
            acy[l] += (double)vy;
        }
    for (int l = 0; i < m; i++, l++) {
        const float u = xx[i] - ax, v = xy[i] - ay;
        const float vx = a[i] * u + b[i] * v, vy = b[i] * u + c[i] * v;
        yx[i] = vx;
        yy[i] = vy;
        acx[l] += (double)vx;
        acy[l] += (double)vy;
    }
    *sx = lanes_total(acx);
    *sy = lanes_total(acy);
}

/* y = C̃⁻¹ x in float (a sensor without the tip-tilt removal) */
static inline __attribute__((always_inline)) void inv_f32(int m, const float *restrict xx, const float *restrict xy,
                                                          const float *restrict a, const float *restrict b,
                                                          const float *restrict c, float *restrict yx,
                                                          float *restrict yy)
{
    for (int i = 0; i < m; i++) {
        const float u = xx[i], v = xy[i];
        yx[i] = a[i] * u + b[i] * v;
        yy[i] = b[i] * u + c[i] * v;
    }
}

/* y −= (dx, dy): T v taken off */
static inline __attribute__((always_inline)) void shift_f32(int m, float dx, float dy, float *restrict yx,
                                                            float *restrict yy)
{
    for (int i = 0; i < m; i++) {
        yx[i] -= dx;
        yy[i] -= dy;
    }
}

/* Ĉ⁻¹ x with the focus removal in float, the sums (means, fᵀx, fᵀv) in double */
static void focus_f32(const wt_noise *n, const float *xx, const float *xy, float *yx, float *yy)
{
    const int m = n->nsub;
    const double *fx = n->focus, *fy = n->focus + m;
    double sx = 0.0, sy = 0.0, a = 0.0;
    for (int i = 0; i < m; i++) {
        sx += (double)xx[i];
        sy += (double)xy[i];
        a += fx[i] * (double)xx[i] + fy[i] * (double)xy[i];
    }
    const float mx = (float)(sx / m), my = (float)(sy / m), af = (float)a;
    double vsx = 0.0, vsy = 0.0, b = 0.0;
    for (int i = 0; i < m; i++) {
        const float u = xx[i] - mx - af * (float)fx[i], v = xy[i] - my - af * (float)fy[i];
        const float vx = n->fa[i] * u + n->fb[i] * v, vy = n->fb[i] * u + n->fc[i] * v;
        yx[i] = vx;
        yy[i] = vy;
        vsx += (double)vx;
        vsy += (double)vy;
        b += fx[i] * (double)vx + fy[i] * (double)vy;
    }
    const float dx = (float)(vsx / m), dy = (float)(vsy / m), bf = (float)b;
    for (int i = 0; i < m; i++) {
        yx[i] -= dx + bf * (float)fx[i];
        yy[i] -= dy + bf * (float)fy[i];
    }
}

/* Ĉ⁻¹ x in the double set_batch's order (means of x, v = C̃⁻¹ (x − T x) with its sums, y = v − T v), in float with
 * the sums in double and the means rounded to float where they meet the slopes. One sensor at a time: the lanes
 * leave no adder latency for a batch to share, and three passes over x, the blocks and y run at about the L2's
 * bandwidth (on the E-ELT LGS a third of the double batch's time, AVX-512). */
WT_CPU_CLONES void wt_noise_set_weight_many_f32(const wt_noise *const *ns, int k, const float *const *x,
                                                float *const *y)
{
    for (int j = 0; j < k; j++) {
        const wt_noise *n = ns[j];
        const int m = n->nsub;
        const float *xx = x[j], *xy = x[j] + m;
        float *yx = y[j], *yy = y[j] + m;
        if (!n->remove_tt) {
            inv_f32(m, xx, xy, n->fa, n->fb, n->fc, yx, yy);
            continue;
        }
        if (n->focus) {
            focus_f32(n, xx, xy, yx, yy);
            continue;
        }
        const double mx = sum_f32(m, xx) / m, my = sum_f32(m, xy) / m;
        double sx, sy;
        products_f32(m, xx, xy, n->fa, n->fb, n->fc, (float)mx, (float)my, yx, yy, &sx, &sy);
        shift_f32(m, (float)(sx / m), (float)(sy / m), yx, yy);
    }
}

void wt_noise_remove_tt(const wt_noise *n, double *x)
{
    const int m = n->nsub;
    double mx, my, a = 0.0;
    means(m, x, &mx, &my);
    if (n->focus)
        for (int i = 0; i < 2 * m; i++) a += n->focus[i] * x[i];
    for (int i = 0; i < m; i++) {
        x[i] -= mx;
        x[m + i] -= my;
    }
    if (n->focus)
        for (int i = 0; i < 2 * m; i++) x[i] -= a * n->focus[i];
}

int wt_noise_focus_pattern(int nsub, const double *cx, const double *cy, double *f)
{
    double mx = 0.0, my = 0.0, span = 0.0;
    for (int i = 0; i < nsub; i++) {
        mx += cx[i];
        my += cy[i];
        span = fmax(span, fmax(fabs(cx[i]), fabs(cy[i])));
    }
    mx /= nsub;
    my /= nsub;
    double q = 0.0;
    for (int i = 0; i < nsub; i++) {
        f[i] = cx[i] - mx;
        f[nsub + i] = cy[i] - my;
        q += f[i] * f[i] + f[nsub + i] * f[nsub + i];
    }
    /* one subaperture (a tip-tilt sensor), or every centre at one point: no focus beyond the tip and tilt */
    if (!(q > 1e-24 * span * span * nsub) || !(span > 0.0)) return 0;
    const double r = 1.0 / sqrt(q);
    for (int i = 0; i < 2 * nsub; i++) f[i] *= r;
    return 1;
}

int wt_noise_set_focus(wt_noise *n, const double *cx, const double *cy)
{
    wt_context *ctx = n->ctx;
    int st = WT_OK;
    if (!n->remove_tt)
        return WT_ERROR(ctx, WT_ERR_INVALID, "noise: the focus removal needs the tip-tilt removal (an LGS weight)");
    double *f = NULL;
    WT_ALLOC(ctx, f, 2 * (size_t)n->nsub, "focus pattern");
    if (!wt_noise_focus_pattern(n->nsub, cx, cy, f)) {
        wt_free(ctx, f);
        return WT_ERROR(ctx, WT_ERR_INVALID, "noise: %d subaperture(s) with no focus pattern beyond tip and tilt",
                        n->nsub);
    }
    wt_free(ctx, n->focus);
    n->focus = f;
fail:
    return st;
}

const double *wt_noise_focus(const wt_noise *n) { return n->focus; }

void wt_noise_inv_block(const wt_noise *n, int i, double *a, double *b, double *c)
{
    *a = n->ia[i];
    *b = n->ib[i];
    *c = n->ic[i];
}

void wt_noise_sample(const wt_noise *n, wt_rng *rng, double *x)
{
    const int m = n->nsub;
    for (int i = 0; i < m; i++) {
        double z1 = wt_rng_normal(rng), z2 = wt_rng_normal(rng);
        x[i] += n->l11[i] * z1;
        x[m + i] += n->l21[i] * z1 + n->l22[i] * z2;
    }
}

int wt_noise_assemble_inv(const wt_noise *n, wt_sparse **out)
{
    int st = WT_OK;
    wt_triplet *t = NULL;
    const int m = n->nsub;
    *out = NULL;
    WT_TRY(wt_triplet_alloc(n->ctx, 2 * (int64_t)m, 2 * (int64_t)m, 4 * (int64_t)m, &t));
    for (int64_t i = 0; i < m; i++) {
        WT_TRY(wt_triplet_add(t, i, i, n->ia[i]));
        WT_TRY(wt_triplet_add(t, m + i, i, n->ib[i]));
        WT_TRY(wt_triplet_add(t, i, m + i, n->ib[i]));
        WT_TRY(wt_triplet_add(t, m + i, m + i, n->ic[i]));
    }
    WT_TRY(wt_triplet_compress(t, out));
fail:
    wt_triplet_free(t);
    return st;
}
