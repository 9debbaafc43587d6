/* core/la/heig.c: λ_max of a small Hermitian matrix (heig.h has the method and its error bound).
 *
 *   scale:   A ← 2^−s A, max |Re a_ij|, |Im a_ij| in [1/2, 1)                 (exact; λ scales back exactly)
 *   reduce:  for i = 0 .. n − 3, (α, x) the column below a_ii: zlarfg's reflection H = I − τ v vᴴ with
 *            Hᴴ (α, x) = (β, 0), β = −sign(Re α) ‖(α, x)‖ real, v = (1, x / (α − β)), τ = (β − α) / β;
 *            then A₂₂ ← Hᴴ A₂₂ H = A₂₂ − v wᴴ − w vᴴ, p = τ A₂₂ v, w = p − ½ τ (pᴴ v) v   (zhetd2's steps);
 *            a column with x = 0 is left as it is: only |e_i|² enters below
 *   root:    T − x I = L D Lᵀ has the pivots q_0 = d_0 − x, q_i = d_i − x − e²_(i−1) / q_(i−1); the number of
 *            negative ones is #{λ(T) < x} (Sturm, Kahan; |q_i| < pivmin → −pivmin as dstebz), and
 *            G = det' / det = Σ q_i' / q_i = Σ_j 1 / (x − λ_j), H = −G' = Σ_j 1 / (x − λ_j)² by the pivots'
 *            derivatives q_i' = −1 + e²_(i−1) q_(i−1)' / q²_(i−1), q_i'' = e²_(i−1) (q_(i−1)'' / q²_(i−1) −
 *            2 q_(i−1)'² / q³_(i−1)). Laguerre's step x ← x − n / (G + √((n − 1)(n H − G²))) from x_0 =
 *            max_i (d_i + |e_(i−1)| + |e_i|) (Gershgorin, above every λ) descends monotonically and cubically to
 *            λ_max (a polynomial with real roots, started above them), each iterate an upper bound while every
 *            pivot stays negative; stopped when its step falls below 4 ε x (or a pivot turns ≥ 0: a lower
 *            bound), then the bracket [x − 8 ε |x|, x + 8 ε |x|] (its ends confirmed by counts) is bisected to
 *            2 ε |x|. Where a count does not confirm an end, the bisection starts from the bounds the iteration
 *            had (max d_i below).
 *
 * On full storage (both triangles: the products are axpys that vectorise) in real arithmetic on split real and
 * imaginary parts: C's complex product checks for NaN on every multiply. */
#include "heig.h"

#include <float.h>
#include <math.h>

#include "../base/base.h"

static inline __attribute__((always_inline)) int sturm_below(int n, const double *d, const double *e2, double pivmin, double x)
{
    int cnt = 0;
    double q = d[0] - x;
    if (fabs(q) < pivmin) q = -pivmin;
    cnt += q < 0.0;
    for (int i = 1; i < n; i++) {
        q = d[i] - x - e2[i - 1] / q;
        if (fabs(q) < pivmin) q = -pivmin;
        cnt += q < 0.0;
    }
    return cnt;
}

/* λ_max of T (d, e² of n ≥ 1) */
static inline __attribute__((always_inline)) double tridiag_max(int n, const double *d, const double *e2)
{
    double lo = d[0], hi = -INFINITY, e2max = 0.0;
    for (int i = 0; i < n; i++) {
        const double el = i > 0 ? sqrt(e2[i - 1]) : 0.0, er = i + 1 < n ? sqrt(e2[i]) : 0.0;
        lo = fmax(lo, d[i]);
        hi = fmax(hi, d[i] + el + er);
        if (i + 1 < n) e2max = fmax(e2max, e2[i]);
    }
    const double pivmin = DBL_MIN * fmax(1.0, e2max);
    double x = hi, est = hi;
    for (int it = 0; it < 100; it++) { /* Laguerre from above */
        double q = d[0] - x, dq = -1.0, ddq = 0.0, g = 0.0, h = 0.0;
        int neg = q < 0.0;
        for (int i = 1; i < n && neg; i++) {
            const double r = 1.0 / q, t = dq * r;
            g += t, h += t * t - ddq * r;
            const double er2 = e2[i - 1] * r * r;
            ddq = er2 * (ddq - 2.0 * dq * t);
            dq = -1.0 + er2 * dq;
            q = d[i] - x - e2[i - 1] * r;
            neg = q < 0.0;
        }
        est = x;
        if (!neg) { /* a pivot ≥ 0: fewer than n eigenvalues below x (rounding took the iteration to λ_max) */
            lo = fmax(lo, x);
            break;
        }
        hi = x;
        const double t = dq / q;
        g += t, h += t * t - ddq / q; /* G = Σ 1 / (x − λ_j) > 0, H = Σ 1 / (x − λ_j)² */
        const double disc = (n - 1) * (n * h - g * g);
        const double step = n / (g + sqrt(disc > 0.0 ? disc : 0.0));
        x -= step;
        if (x < lo) x = lo;
        est = x;
        if (!(step > 4.0 * DBL_EPSILON * fabs(x))) break;
    }
    /* a bracket of a few ulps about the estimate, where counts confirm its ends */
    const double w = 8.0 * DBL_EPSILON * fabs(est);
    if (est - w > lo && sturm_below(n, d, e2, pivmin, est - w) < n) lo = est - w;
    if (est + w < hi && sturm_below(n, d, e2, pivmin, est + w) == n) hi = est + w;
    for (int it = 0; it < 200 && hi - lo > 2.0 * DBL_EPSILON * fmax(fabs(lo), fabs(hi)); it++) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (sturm_below(n, d, e2, pivmin, mid) == n) hi = mid;
        else lo = mid;
    }
    return 0.5 * (lo + hi);
}

WT_CPU_CLONES double wt_heig_max(int n, double complex *a, int lda)
{
    enum { M = WT_HEIG_MAX };
    if (n < 1 || n > M || lda < n) return NAN;
    double ar[M * M], ai[M * M]; /* both triangles, column-major with leading dimension n */
    double amax = 0.0;
    for (int j = 0; j < n; j++)
        for (int i = j; i < n; i++) {
            const double complex v = a[i + (long)lda * j];
            if (!isfinite(creal(v)) || (i != j && !isfinite(cimag(v)))) return NAN;
            amax = fmax(amax, fmax(fabs(creal(v)), i == j ? 0.0 : fabs(cimag(v))));
        }
    if (amax == 0.0) return 0.0;
    int ex;
    (void)frexp(amax, &ex); /* amax = f 2^ex, f in [1/2, 1) */
    for (int j = 0; j < n; j++) {
        ar[j + n * j] = ldexp(creal(a[j + (long)lda * j]), -ex);
        ai[j + n * j] = 0.0;
        for (int i = j + 1; i < n; i++) {
            const double complex v = a[i + (long)lda * j];
            ar[i + n * j] = ar[j + n * i] = ldexp(creal(v), -ex);
            ai[i + n * j] = ldexp(cimag(v), -ex);
            ai[j + n * i] = -ai[i + n * j];
        }
    }
    double d[M], e2[M], vr[M], vi[M], pr[M], pi[M];
    for (int i = 0; i + 1 < n; i++) {
        const int m = n - i - 1, o = i + 1; /* the column below the diagonal: rows o .. n − 1 */
        const double *cr = ar + n * i, *ci = ai + n * i;
        const double alr = cr[o], ali = ci[o];
        double xn2 = 0.0;
        for (int r = o + 1; r < n; r++) xn2 += cr[r] * cr[r] + ci[r] * ci[r];
        d[i] = ar[i + n * i];
        if (xn2 == 0.0) {
            e2[i] = alr * alr + ali * ali;
            continue;
        }
        const double beta = -copysign(sqrt(alr * alr + ali * ali + xn2), alr);
        e2[i] = beta * beta;
        const double tr = (beta - alr) / beta, ti = -ali / beta;        /* τ */
        const double gr = alr - beta, gi = ali, g2 = gr * gr + gi * gi; /* 1 / (α − β) = conj(g) / |g|² */
        const double sr = gr / g2, si = -gi / g2;
        vr[0] = 1.0, vi[0] = 0.0;
        for (int r = 1; r < m; r++) {
            const double xr = cr[o + r], xi = ci[o + r];
            vr[r] = xr * sr - xi * si;
            vi[r] = xr * si + xi * sr;
        }
        /* u = A₂₂ v by columns, then p = τ u */
        for (int r = 0; r < m; r++) pr[r] = pi[r] = 0.0;
        for (int k = 0; k < m; k++) {
            const double *hr = ar + o + n * (o + k), *hi = ai + o + n * (o + k), br = vr[k], bi = vi[k];
            for (int r = 0; r < m; r++) {
                pr[r] += hr[r] * br - hi[r] * bi;
                pi[r] += hr[r] * bi + hi[r] * br;
            }
        }
        for (int r = 0; r < m; r++) {
            const double ur = pr[r], ui = pi[r];
            pr[r] = tr * ur - ti * ui;
            pi[r] = tr * ui + ti * ur;
        }
        /* w = p − ½ τ (pᴴ v) v */
        double dr = 0.0, di = 0.0;
        for (int r = 0; r < m; r++) dr += pr[r] * vr[r] + pi[r] * vi[r], di += pr[r] * vi[r] - pi[r] * vr[r];
        const double hr = -0.5 * (tr * dr - ti * di), hi = -0.5 * (tr * di + ti * dr);
        for (int r = 0; r < m; r++) {
            const double wr = pr[r] + hr * vr[r] - hi * vi[r], wi = pi[r] + hr * vi[r] + hi * vr[r];
            pr[r] = wr, pi[r] = wi;
        }
        /* A₂₂ −= v wᴴ + w vᴴ, column k: v conj(w_k) + w conj(v_k) */
        for (int k = 0; k < m; k++) {
            double *hcr = ar + o + n * (o + k), *hci = ai + o + n * (o + k);
            const double wkr = pr[k], wki = pi[k], vkr = vr[k], vki = vi[k];
            for (int r = 0; r < m; r++) {
                hcr[r] -= vr[r] * wkr + vi[r] * wki + pr[r] * vkr + pi[r] * vki;
                hci[r] -= vi[r] * wkr - vr[r] * wki + pi[r] * vkr - pr[r] * vki;
            }
        }
    }
    d[n - 1] = ar[(n - 1) * (n + 1)];
    return ldexp(tridiag_max(n, d, e2), ex);
}
