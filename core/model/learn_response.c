/* core/model/learn_response.c: the response maps R_ij(δ; h) of a unit von Kármán layer seen by two LGS through
 * their cone beams, with the data's tip-tilt removal and pair averaging (SPEC §12), optionally at a frozen-flow
 * shift s of the layer between the two sensors' frames (the lagged maps of the wind estimate).
 *
 * The covariance of slope ca of subaperture a (sensor i, time t) and slope cb of subaperture a + δ (sensor j, time
 * t + τ) for a layer at h moving with v (screen(x − v t)) depends only on their displacement at the layer,
 *
 *   Δ(δ) = δ d (1 − h/H) + (θ_j − θ_i) h − s,   s = v τ,
 *
 * as C(Δ) = −½ Σ_{edges, points} ± w w' D(|Δ + b − a|) / d² (each slope is the difference of its two edges' mean
 * OPD over d; a, b the edge points, Gauss–Legendre along the edge). The edge-point differences b − a are a few
 * fixed vectors; modulo the lattice step d (1 − h/H) (= 2e, the footprint's side) they take 5 (xx, yy) or 9 (xy)
 * values f, so D is evaluated once per (f, lattice point) and each C(δ) is a sum of tabulated values: 19 D's per
 * offset for the three components instead of 108. */
#include "learn_private.h"
#include "core/optics/seeing.h"

#include <fftw3.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* ∛x for x > 0: the exponent divided by 3 on the bit pattern (a guess within ~4 %), then two Halley steps
 * y ← y (y³ + 2x)/(2y³ + x), whose error cubes each time: within ~1e-14 of libm's cbrt and ~4× faster, and the D
 * evaluations (one ∛ and one √ each, ~10⁵ a response map at E-ELT size) are most of a response's time. */
static inline double cbrt_pos(double x)
{
    uint64_t i;
    memcpy(&i, &x, sizeof i);
    i = i / 3 + UINT64_C(0x2a9f7893782da1ce);
    double y;
    memcpy(&y, &i, sizeof y);
    double y3 = y * y * y;
    y = y * (y3 + 2 * x) / (2 * y3 + x);
    y3 = y * y * y;
    return y * (y3 + 2 * x) / (2 * y3 + x);
}

/* D(ρ)/ρ^(5/3) every `step` metres (smooth: Kolmogorov's constant at 0, falling where ρ reaches L0), linearly
 * interpolated; D itself is then exact at 0 and its ρ^(5/3) cusp is not interpolated */
static inline double dtable_eval(const wt_learn__rws *t, double rho)
{
    if (!(rho > 0)) return 0.0;
    double x = rho / t->step;
    int k = (int)x;
    if (k >= t->ntab - 1) k = t->ntab - 2;
    double w = x - k, c = cbrt_pos(rho);
    return ((1 - w) * t->tab[k] + w * t->tab[k + 1]) * rho * c * c;
}

/* D and dD/dρ of the same interpolant: D = f ρ^(5/3), D' = f' ρ^(5/3) + (5/3) f ρ^(2/3), f' the segment's slope */
static inline double dtable_eval_d(const wt_learn__rws *t, double rho, double *dd)
{
    if (!(rho > 0)) {
        *dd = 0;
        return 0.0;
    }
    double x = rho / t->step;
    int k = (int)x;
    if (k >= t->ntab - 1) k = t->ntab - 2;
    double w = x - k, c = cbrt_pos(rho), f = (1 - w) * t->tab[k] + w * t->tab[k + 1];
    double fp = (t->tab[k + 1] - t->tab[k]) / t->step, r23 = c * c;
    *dd = fp * rho * r23 + (5.0 / 3.0) * f * r23;
    return f * rho * r23;
}

double wt_learn__rmax(const wt_learn *L, double theta, double hmax, double smax)
{
    /* the farthest edge points of two subapertures: the pupil's diagonal, the beams' separation, the shift */
    return M_SQRT2 * (L->n + 1) * L->d + theta * hmax + smax + 2 * L->d;
}

void wt_learn__rws_free(const wt_learn *L, wt_learn__rws *w)
{
    if (!w) return;
    wt_free(L->ctx, w->tab), wt_free(L->ctx, w->buf), wt_free(L->ctx, w);
}

int wt_learn__rws_alloc(const wt_learn *L, double L0, double rmax, wt_learn__rws **out)
{
    const int n = L->n, N = L->N, NN = N * N, nf = L->nf, E = 2 * n + 1;
    int st = WT_OK;
    wt_learn__rws *w = NULL;
    *out = NULL;
    WT_ALLOC(L->ctx, w, 1, "a response work space");
    w->step = L->d / WT_LEARN_TABLE_STEPS;
    w->ntab = (int)ceil(rmax / w->step) + 2;
    WT_ALLOC(L->ctx, w->tab, w->ntab, "the structure-function table");
    /* C, its two derivatives, g, k2 (N²), the mask's, a work and a spare spectrum (nf complex each), 9 lattices of
     * D and of its two derivatives (E²), 8 for alignment of each of the arrays that FFTW reads or writes */
    WT_ALLOC(L->ctx, w->buf, (size_t)5 * (NN + 8) + (size_t)3 * (2 * nf + 8) + (size_t)27 * E * E,
             "the response work arrays");
    w->C = wt_align64(w->buf), w->Cx = wt_align64(w->C + NN), w->Cy = wt_align64(w->Cx + NN);
    w->g = wt_align64(w->Cy + NN), w->k2 = wt_align64(w->g + NN);
    w->Mh = wt_align64(w->k2 + NN), w->sp = wt_align64(w->Mh + 2 * nf), w->tmp = wt_align64(w->sp + 2 * nf);
    w->Df = w->tmp + 2 * nf;
    for (int k = 1; k < w->ntab; k++)
        w->tab[k] = wt_seeing_structure(k * w->step, 1.0, L0, 0.0) / pow(k * w->step, 5.0 / 3.0);
    w->tab[0] = w->tab[1]; /* the small-ρ limit: D/ρ^(5/3) is flat there (Kolmogorov's 6.88 (λ/2π)² r0^(−5/3)) */
    /* M̂, the mask's spectrum */
    memset(w->C, 0, (size_t)NN * sizeof *w->C);
    for (int s = 0; s < L->nsub; s++) w->C[L->sub[s] % n + N * (L->sub[s] / n)] = 1.0;
    fftw_execute_dft_r2c((fftw_plan)L->r2c, w->C, (fftw_complex *)w->Mh);
    *out = w;
    return WT_OK;
fail:
    wt_learn__rws_free(L, w);
    return st;
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

/* c2r of sp into out, scaled by 1/N² (the inverse DFT), through the object's plan on the work space's arrays */
static void inverse(const wt_learn *L, double *sp, double *out)
{
    fftw_execute_dft_c2r((fftw_plan)L->c2r, (fftw_complex *)sp, out);
    const double s = 1.0 / ((double)L->N * L->N);
    for (int k = 0; k < L->N * L->N; k++) out[k] *= s;
}

/* r = the data's statistic of the stationary covariance C (FFT layout): tip-tilt removal as the data's,
 * C(δ) − g(a)/nv − k(a+δ)/nv + c̄, averaged over the pairs (a, a + δ), with g(a) = Σ_u C(u) M(a + u),
 * k(b) = Σ_u C(u) M(b − u), c̄ = Σ_a M(a) g(a) / nv². Linear in C (so it maps ∂C/∂s to ∂r/∂s too). */
static void tt_remove(const wt_learn *L, wt_learn__rws *w, const double *C, double *r)
{
    const int n = L->n, N = L->N, NN = N * N, nf = L->nf, S = 2 * n - 1;
    const double nv = L->nsub, *P = L->pairs;
    double *g = w->g, *k2 = w->k2, *sp = w->sp, *tmp = w->tmp;
    memcpy(g, C, (size_t)NN * sizeof *C);
    fftw_execute_dft_r2c((fftw_plan)L->r2c, g, (fftw_complex *)sp);
    cmul(nf, sp, w->Mh, 1, tmp);
    inverse(L, tmp, g);
    cmul(nf, sp, w->Mh, 0, tmp);
    inverse(L, tmp, k2);
    double cbar = 0;
    for (int q = 0; q < NN; q++) {
        int in = (q % N) < n && (q / N) < n && L->valid[(q % N) + n * (q / N)];
        g[q] = in ? g[q] : 0.0, k2[q] = in ? k2[q] : 0.0;
        cbar += g[q];
    }
    cbar /= nv * nv;
    /* T2(δ) = Σ_a M g(a) M(a + δ), T3(δ) = Σ_a M(a) M k(a + δ), into g and k2 */
    fftw_execute_dft_r2c((fftw_plan)L->r2c, g, (fftw_complex *)sp);
    cmul(nf, sp, w->Mh, 1, tmp);
    inverse(L, tmp, g);
    fftw_execute_dft_r2c((fftw_plan)L->r2c, k2, (fftw_complex *)sp);
    cmul(nf, w->Mh, sp, 1, tmp);
    inverse(L, tmp, k2);
    for (int o = 0; o < S * S; o++) {
        int dx = o % S - (n - 1), dy = o / S - (n - 1), f = (dx + N) % N + N * ((dy + N) % N);
        r[o] = P[f] > 0 ? C[f] + cbar - (g[f] + k2[f]) / (nv * P[f]) : 0.0;
    }
}

void wt_learn__resp_eval_grad(const wt_learn *L, wt_learn__rws *w, double tx, double ty, double h, double sx,
                              double sy, int ca, int cb, double *r, double *rx, double *ry)
{
    static const double gx[WT_LEARN_EDGE_POINTS] = {-0.7745966692414834, 0.0, 0.7745966692414834};
    static const double gw[WT_LEARN_EDGE_POINTS] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0}; /* sum 1: edge means */
    const int n = L->n, N = L->N, NN = N * N, S = 2 * n - 1, E = 2 * n + 1, grad = rx != NULL;
    const double d = L->d, sc = 1.0 - h / L->H, e = 0.5 * d * sc, Ls = d * sc;
    const size_t E2 = (size_t)E * E;
    /* the terms: each (edge point pair) difference v = b − a = m Ls + f, m integer (|m| ≤ 1), f ∈ [0, Ls) */
    enum { NT = 4 * WT_LEARN_EDGE_POINTS * WT_LEARN_EDGE_POINTS };
    double fx[NT], fy[NT], wt[NT];
    int mx[NT], my[NT], fi[NT], nfr = 0, nt = 0;
    for (int it = 0; it < WT_LEARN_EDGE_POINTS; it++)
        for (int iu = 0; iu < WT_LEARN_EDGE_POINTS; iu++)
            for (int sa = -1; sa <= 1; sa += 2)
                for (int sb = -1; sb <= 1; sb += 2) {
                    /* edge points: x slope (±e, t e), y slope (t e, ±e); + for the far edge */
                    double ax = ca ? gx[it] * e : sa * e, ay = ca ? sa * e : gx[it] * e;
                    double bx = cb ? gx[iu] * e : sb * e, by = cb ? sb * e : gx[iu] * e;
                    double vx = bx - ax, vy = by - ay;
                    int kx = (int)floor(vx / Ls + 1e-9), ky = (int)floor(vy / Ls + 1e-9);
                    double ux = vx - kx * Ls, uy = vy - ky * Ls;
                    int f = 0;
                    while (f < nfr && !(fabs(fx[f] - ux) < 1e-9 * Ls && fabs(fy[f] - uy) < 1e-9 * Ls)) f++;
                    if (f == nfr) fx[nfr] = ux, fy[nfr] = uy, nfr++;
                    mx[nt] = kx, my[nt] = ky, fi[nt] = f, wt[nt] = gw[it] * gw[iu] * sa * sb, nt++;
                }
    /* D on the lattice Δ = k Ls + θh − s + f, k ∈ [−n, n]² (and ∂D/∂s = −D'(ρ) Δ/ρ) */
    const double ox = tx * h - sx, oy = ty * h - sy;
    double *Dx = w->Df + 9 * E2, *Dy = w->Df + 18 * E2;
    for (int f = 0; f < nfr; f++)
        for (int ky = 0; ky < E; ky++) {
            const size_t row = ((size_t)f * E + ky) * E;
            double *D = w->Df + row, y = (ky - n) * Ls + oy + fy[f];
            if (!grad)
                for (int kx = 0; kx < E; kx++) {
                    const double x = (kx - n) * Ls + ox + fx[f];
                    D[kx] = dtable_eval(w, sqrt(x * x + y * y)); /* no overflow here: hypot's care is not needed */
                }
            else
                for (int kx = 0; kx < E; kx++) {
                    double x = (kx - n) * Ls + ox + fx[f], rho = sqrt(x * x + y * y), dd;
                    D[kx] = dtable_eval_d(w, rho, &dd);
                    double q = rho > 0 ? -dd / rho : 0.0;
                    Dx[row + kx] = q * x, Dy[row + kx] = q * y;
                }
        }
    /* the stationary covariance C(δ) of subapertures δ apart, at FFT index (δ mod N) */
    double *C = w->C, *Cx = w->Cx, *Cy = w->Cy;
    memset(C, 0, (size_t)NN * sizeof *C);
    if (grad) memset(Cx, 0, (size_t)NN * sizeof *C), memset(Cy, 0, (size_t)NN * sizeof *C);
    for (int o = 0; o < S * S; o++) {
        int dx = o % S - (n - 1), dy = o / S - (n - 1), f = (dx + N) % N + N * ((dy + N) % N);
        double sum = 0, sumx = 0, sumy = 0;
        for (int q = 0; q < nt; q++) {
            const size_t at = ((size_t)fi[q] * E + dy + my[q] + n) * E + dx + mx[q] + n;
            sum += wt[q] * w->Df[at];
            if (grad) sumx += wt[q] * Dx[at], sumy += wt[q] * Dy[at];
        }
        C[f] = -0.5 * sum / (d * d);
        if (grad) Cx[f] = -0.5 * sumx / (d * d), Cy[f] = -0.5 * sumy / (d * d);
    }
    tt_remove(L, w, C, r);
    if (grad) tt_remove(L, w, Cx, rx), tt_remove(L, w, Cy, ry);
}

void wt_learn__resp_eval(const wt_learn *L, wt_learn__rws *w, double tx, double ty, double h, double sx, double sy,
                         int ca, int cb, double *r)
{
    wt_learn__resp_eval_grad(L, w, tx, ty, h, sx, sy, ca, cb, r, NULL, NULL);
}

int wt_learn_response(const wt_learn *L, int p, int nalt, const double *alt, double L0, double *resp)
{
    const int S = 2 * L->n - 1;
    const double H = L->H;
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
    int nth = 1;
#ifdef _OPENMP
    nth = omp_get_max_threads();
#endif
    if (nth > nalt * WT_LEARN_NCOMP) nth = nalt * WT_LEARN_NCOMP;
    wt_learn__rws *ws[WT_LEARN_MAX_THREADS] = {0};
    if (nth > WT_LEARN_MAX_THREADS) nth = WT_LEARN_MAX_THREADS;
    for (int k = 0; k < nth; k++)
        if ((st = wt_learn__rws_alloc(L, L0, wt_learn__rmax(L, hypot(tx, ty), hmax, 0.0), &ws[k])) < 0) goto fail;
    static const int ca[WT_LEARN_NCOMP] = {0, 1, 0}, cb[WT_LEARN_NCOMP] = {0, 1, 1};
    /* one (altitude, component) per task, each thread on its own work space (FFTW's execute is thread-safe) */
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
    for (int ac = 0; ac < nalt * WT_LEARN_NCOMP; ac++) {
        int tid = 0;
#ifdef _OPENMP
        tid = omp_get_thread_num();
#endif
        const int a = ac / WT_LEARN_NCOMP, c = ac % WT_LEARN_NCOMP;
        wt_learn__resp_eval(L, ws[tid], tx, ty, alt[a], 0.0, 0.0, ca[c], cb[c], resp + (size_t)ac * S * S);
    }
fail:
    for (int k = 0; k < nth; k++) wt_learn__rws_free(L, ws[k]);
    return st;
}
