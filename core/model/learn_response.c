/* core/model/learn_response.c: the response maps R_ij(δ; h) of a unit von Kármán layer seen by two LGS through
 * their cone beams, with the data's tip-tilt removal and pair averaging (SPEC §12). */
#include "learn_private.h"
#include "core/optics/seeing.h"

#include <math.h>
#include <string.h>

/* D(ρ)/ρ^(5/3) every `step` metres (smooth: Kolmogorov's constant at 0, falling where ρ reaches L0), linearly
 * interpolated; D itself is then exact at 0 and its ρ^(5/3) cusp is not interpolated */
typedef struct {
    double step;
    int n;
    double *f;
} dtable;

static inline double dtable_eval(const dtable *t, double rho)
{
    if (!(rho > 0)) return 0.0;
    double x = rho / t->step;
    int k = (int)x;
    if (k >= t->n - 1) k = t->n - 2;
    double w = x - k, c = cbrt(rho);
    return ((1 - w) * t->f[k] + w * t->f[k + 1]) * rho * c * c;
}

/* cov(s_a^ca, s_b^cb) of two subapertures whose centres at the layer are Δ apart (b − a), both of footprint side
 * 2e at the layer, the slopes being OPD differences over the pupil's d (SPEC §12: footprints scale by 1 − h/H) */
static double slope_cov(const dtable *t, double dx, double dy, double e, double d, int ca, int cb)
{
    static const double gx[WT_LEARN_EDGE_POINTS] = {-0.7745966692414834, 0.0, 0.7745966692414834};
    static const double gw[WT_LEARN_EDGE_POINTS] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0}; /* sum 1: edge means */
    double sum = 0;
    for (int it = 0; it < WT_LEARN_EDGE_POINTS; it++)
        for (int iu = 0; iu < WT_LEARN_EDGE_POINTS; iu++) {
            /* edge points: x slope (±e, t e), y slope (t e, ±e); sign + for the far edge */
            double ax = ca ? gx[it] * e : e, ay = ca ? e : gx[it] * e;
            double bx = cb ? gx[iu] * e : e, by = cb ? e : gx[iu] * e;
            double a2x = ca ? ax : -ax, a2y = ca ? -ay : ay, b2x = cb ? bx : -bx, b2y = cb ? -by : by;
            double d11 = dtable_eval(t, hypot(dx + bx - ax, dy + by - ay));
            double d21 = dtable_eval(t, hypot(dx + b2x - ax, dy + b2y - ay));
            double d12 = dtable_eval(t, hypot(dx + bx - a2x, dy + by - a2y));
            double d22 = dtable_eval(t, hypot(dx + b2x - a2x, dy + b2y - a2y));
            sum += gw[it] * gw[iu] * (d11 - d21 - d12 + d22);
        }
    return -0.5 * sum / (d * d);
}

/* complex products of spectra: out = conj(a) b (conj_a) or a b */
static void cmul(int nf, const double *a, const double *b, int conj_a, double *out)
{
    const double sg = conj_a ? -1.0 : 1.0;
    for (int k = 0; k < nf; k++) {
        double ar = a[2 * k], ai = sg * a[2 * k + 1], br = b[2 * k], bi = b[2 * k + 1];
        out[2 * k] = ar * br - ai * bi, out[2 * k + 1] = ar * bi + ai * br;
    }
}

int wt_learn_response(const wt_learn *L, int p, int nalt, const double *alt, double L0, double *resp)
{
    const int n = L->n, N = L->N, nf = L->nf, S = 2 * n - 1, NN = N * N;
    const double d = L->d, H = L->H, nv = L->nsub;
    int st = WT_OK;
    if (p < 0 || p >= L->npairs || nalt < 1)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: response of pair %d (of %d) at %d altitudes", p, L->npairs, nalt);
    for (int a = 0; a < nalt; a++)
        if (!(alt[a] >= 0 && alt[a] < H))
            return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: altitude %g m outside [0, H = %g m)", alt[a], H);
    int i, j;
    wt_learn_pair(L, p, &i, &j);
    const double tx = L->theta_x[j] - L->theta_x[i], ty = L->theta_y[j] - L->theta_y[i];
    double hmax = 0;
    for (int a = 0; a < nalt; a++) hmax = fmax(hmax, alt[a]);
    dtable t = {d / WT_LEARN_TABLE_STEPS, 0, NULL};
    const double rmax = M_SQRT2 * (n + 1) * d + hypot(tx, ty) * hmax + 2 * d;
    t.n = (int)ceil(rmax / t.step) + 2;
    double *C = NULL, *Mh = NULL, *sp = NULL, *g = NULL, *k2 = NULL, *P = L->pairs;
    WT_ALLOC(L->ctx, t.f, t.n, "the structure-function table");
    WT_ALLOC(L->ctx, C, 3 * NN, "the response work arrays");
    WT_ALLOC(L->ctx, Mh, 4 * nf * 2, "the response work spectra");
    sp = Mh + 2 * nf, g = C + NN, k2 = C + 2 * NN;
#pragma omp parallel for schedule(dynamic, 16)
    for (int k = 1; k < t.n; k++) t.f[k] = wt_seeing_structure(k * t.step, 1.0, L0, 0.0) / pow(k * t.step, 5.0 / 3.0);
    t.f[0] = t.f[1]; /* the small-ρ limit: D/ρ^(5/3) is flat there (Kolmogorov's 6.88 (λ/2π)² r0^(−5/3)) */
    /* M̂, the mask's spectrum */
    memset(C, 0, (size_t)NN * sizeof *C);
    for (int s = 0; s < L->nsub; s++) C[L->sub[s] % n + N * (L->sub[s] / n)] = 1.0;
    wt_learn__forward(L, C, Mh);
    for (int a = 0; a < nalt; a++) {
        const double h = alt[a], sc = 1.0 - h / H, e = 0.5 * d * sc;
        static const int ca[WT_LEARN_NCOMP] = {0, 1, 0}, cb[WT_LEARN_NCOMP] = {0, 1, 1};
        for (int c = 0; c < WT_LEARN_NCOMP; c++) {
            /* the stationary covariance C(δ) of subapertures δ apart (layer offset δ d (1 − h/H) + (θ_j − θ_i) h) */
            memset(C, 0, (size_t)NN * sizeof *C);
#pragma omp parallel for schedule(static)
            for (int o = 0; o < S * S; o++) {
                int dx = o % S - (n - 1), dy = o / S - (n - 1);
                C[(dx + N) % N + N * ((dy + N) % N)] =
                    slope_cov(&t, dx * d * sc + tx * h, dy * d * sc + ty * h, e, d, ca[c], cb[c]);
            }
            /* tip-tilt removal as the data's: C(δ) − g(a)/nv − k(a+δ)/nv + c̄, averaged over the pairs (a, a + δ),
             * with g(a) = Σ_u C(u) M(a + u), k(b) = Σ_u C(u) M(b − u), c̄ = Σ_a M(a) g(a) / nv² */
            wt_learn__forward(L, C, sp);
            double *tmp = Mh + 4 * nf; /* spare spectrum */
            cmul(nf, sp, Mh, 1, tmp);
            wt_learn__inverse(L, tmp, g);
            cmul(nf, sp, Mh, 0, tmp);
            wt_learn__inverse(L, tmp, k2);
            double cbar = 0;
            for (int q = 0; q < NN; q++) {
                int in = (q % N) < n && (q / N) < n && L->valid[(q % N) + n * (q / N)];
                g[q] = in ? g[q] : 0.0, k2[q] = in ? k2[q] : 0.0;
                cbar += g[q];
            }
            cbar /= nv * nv;
            /* T2(δ) = Σ_a M g(a) M(a + δ), T3(δ) = Σ_a M(a) M k(a + δ), into g and k2 */
            wt_learn__forward(L, g, sp);
            cmul(nf, sp, Mh, 1, tmp);
            wt_learn__inverse(L, tmp, g);
            wt_learn__forward(L, k2, sp);
            cmul(nf, Mh, sp, 1, tmp);
            wt_learn__inverse(L, tmp, k2);
            double *r = resp + ((size_t)a * WT_LEARN_NCOMP + c) * S * S;
            for (int o = 0; o < S * S; o++) {
                int dx = o % S - (n - 1), dy = o / S - (n - 1), f = (dx + N) % N + N * ((dy + N) % N);
                r[o] = P[f] > 0 ? C[f] + cbar - (g[f] + k2[f]) / (nv * P[f]) : 0.0;
            }
        }
    }
fail:
    wt_free(L->ctx, t.f), wt_free(L->ctx, C), wt_free(L->ctx, Mh);
    return st;
}
