/* core/model/learn_fit.c: the non-negative fit of the Cn² profile to the LGS cross-covariance maps, r0 from its
 * total, the batches' spread as the uncertainty (SPEC §12, "Identification from the loop's own data").
 *
 * The statistic is differential: every cross pair (i, j) enters as its map less the mean of the two autos,
 *
 *   D_ij^c(δ) = C_ij^c(δ) − ½ (C_ii^c(δ) + C_jj^c(δ)),   modelled by R_ij^c(δ; h) − R_auto^c(δ; h),
 *
 * and the autos as they are. A layer at the ground is the same phase in every beam, so it adds the same map to
 * C_ij and to C_ii, C_jj realisation by realisation, not only on average: the differences are free of the ground
 * layer's sampling error, which over a few seconds of frozen flow (a few pupils of screen) is most of the maps'
 * error, and which the plain fit of C_ij explained with Cn² at altitude (docs/results.md §47). The ground's share
 * then comes from the autos. The autos' δ = 0 (every component: the elongated spots' noise correlates x and y
 * within a subaperture) carries the measurement noise and is left out, from the autos and from the differences
 * that contain it.
 *
 * The fit minimises Σ_{p,c,δ∈U} w(δ) (d_p^c(δ) − Σ_h c_h r_p^c(δ; h))² over c ≥ 0 (d, r the statistic above and
 * its model), U the offsets with P(δ) ≥ WT_LEARN_MIN_PAIRS P(0), w = P(δ)/P(0): normal equations G c = q with
 * G_ab = Σ w r_a r_b (fixed by the geometry: the model object) and q_a = Σ w r_a d (the frames). */
#include "learn_private.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

static int team(void)
{
#ifdef _OPENMP
    int t = omp_get_max_threads();
    return t < WT_LEARN_MAX_THREADS ? t : WT_LEARN_MAX_THREADS;
#else
    return 1;
#endif
}


/* Solve A z = b for the k × k symmetric positive definite A (column-major, leading dimension lda) by Cholesky in
 * place on a copy w (k²). A pivot that is not positive (a column that the others reproduce) is lifted to a
 * relative 1e-12 of the diagonal's largest: that column's z then comes out ~0, which the active set drops. */
void wt_learn__spd_solve(int k, const double *A, int lda, const double *b, double *z, double *w)
{
    double dmax = 0;
    for (int c = 0; c < k; c++) dmax = fmax(dmax, A[c + (size_t)lda * c]);
    for (int c = 0; c < k; c++)
        for (int r = 0; r < k; r++) w[r + (size_t)k * c] = A[r + (size_t)lda * c];
    for (int c = 0; c < k; c++) {
        double s = w[c + (size_t)k * c];
        for (int q = 0; q < c; q++) s -= w[c + (size_t)k * q] * w[c + (size_t)k * q];
        s = s > 1e-12 * dmax ? sqrt(s) : sqrt(1e-12 * dmax + 1e-300);
        w[c + (size_t)k * c] = s;
        for (int r = c + 1; r < k; r++) {
            double v = w[r + (size_t)k * c];
            for (int q = 0; q < c; q++) v -= w[r + (size_t)k * q] * w[c + (size_t)k * q];
            w[r + (size_t)k * c] = v / s;
        }
    }
    for (int r = 0; r < k; r++) {
        double v = b[r];
        for (int q = 0; q < r; q++) v -= w[r + (size_t)k * q] * z[q];
        z[r] = v / w[r + (size_t)k * r];
    }
    for (int r = k - 1; r >= 0; r--) {
        double v = z[r];
        for (int q = r + 1; q < k; q++) v -= w[q + (size_t)k * r] * z[q];
        z[r] = v / w[r + (size_t)k * r];
    }
}

int wt_learn_nnls(int m, const double *G, const double *q, double *x, double *work, int *iwork)
{
    double *sub = work, *chol = sub + (size_t)m * m, *z = chol + (size_t)m * m, *zs = z + m, *rhs = zs + m;
    int *act = iwork; /* 1: in the passive set P (free), 0: held at 0 */
    double qmax = 0;
    for (int i = 0; i < m; i++) x[i] = 0, act[i] = 0, qmax = fmax(qmax, fabs(q[i]));
    const double tol = 1e-13 * (qmax > 0 ? qmax : 1.0);
    for (int it = 0; it < 3 * m; it++) {
        /* the negative gradient q − G x; its most positive component over the held set enters P */
        int jmax = -1;
        double wmax = tol;
        for (int i = 0; i < m; i++) {
            double v = q[i];
            for (int k = 0; k < m; k++) v -= G[i + (size_t)m * k] * x[k];
            if (!act[i] && v > wmax) wmax = v, jmax = i;
        }
        if (jmax < 0) return it;
        act[jmax] = 1;
        for (int inner = 0;; inner++) {
            if (inner > m) return WT_ERR_NUMERIC;
            /* the unconstrained minimiser over P: G_PP z_P = q_P (sub: the P columns, leading dimension m) */
            int np = 0;
            for (int i = 0; i < m; i++)
                if (act[i]) {
                    int r = 0;
                    for (int k = 0; k < m; k++)
                        if (act[k]) sub[r++ + (size_t)m * np] = G[k + (size_t)m * i];
                    rhs[np++] = q[i];
                }
            wt_learn__spd_solve(np, sub, m, rhs, zs, chol);
            for (int i = 0, r = 0; i < m; i++) z[i] = act[i] ? zs[r++] : 0.0;
            /* all of P positive: accept; otherwise step from x towards z to the first variable reaching 0 */
            double alpha = 1.0;
            int imin = -1;
            for (int i = 0; i < m; i++)
                if (act[i] && z[i] <= 0) {
                    double a = x[i] / (x[i] - z[i]);
                    if (imin < 0 || a < alpha) alpha = a, imin = i;
                }
            if (imin < 0) {
                memcpy(x, z, (size_t)m * sizeof *x);
                break;
            }
            for (int i = 0; i < m; i++) x[i] += alpha * (z[i] - x[i]);
            x[imin] = 0, act[imin] = 0;
            for (int i = 0; i < m; i++)
                if (act[i] && x[i] <= 0) x[i] = 0, act[i] = 0;
        }
    }
    return WT_ERR_NUMERIC;
}


void wt_learn_model_free(wt_learn_model *M)
{
    if (!M) return;
    wt_context *ctx = M->ctx;
    wt_free(ctx, M->valid), wt_free(ctx, M->uoff), wt_free(ctx, M->uw), wt_free(ctx, M->slot), wt_free(ctx, M->R), wt_free(ctx, M->G);
    wt_free(ctx, M);
}

/* the autos' offsets that r0 is scaled on (small_scale): the 24 within two subapertures, each map less its mean over
 * them. Measured on the demo (5 seeds) and the 9-layer E-ELT truth (2 seeds, 500 and 2000 frames), docs/results.md
 * §77: the rms error of r0 8.7 % / 3.8 % with the whole fit's total, 2.9 % / 0.6 % here; without the mean's removal
 * 5.6 % / 2.1 % at one subaperture and more at two or four (the large scales' realisation again); at one
 * subaperture, centred, 2.3 % / 1.7 % with a +1.6 % bias at E-ELT size (the simulation renders the phase at 4
 * points a subaperture: the smallest scales are its weakest) */
#define WT_LEARN_R0_RADIUS 2
#define WT_LEARN_R0_CENTRED 1
static int small_offset(const wt_learn *L, int f)
{
    int dx = f % L->N, dy = f / L->N;
    dx = dx >= L->n ? dx - L->N : dx, dy = dy >= L->n ? dy - L->N : dy;
    return abs(dx) <= WT_LEARN_R0_RADIUS && abs(dy) <= WT_LEARN_R0_RADIUS;
}

/* whether term (component c, used offset u) enters the fit: δ = 0 holds the autos' noise (SPEC §12: white, at
 * δ = 0 only; x and y correlated there by the elongation), and every term of the statistic holds an auto's δ = 0 */
static int term_used(const wt_learn_model *M, int c, int u)
{
    (void)c;
    return u != M->u0;
}

/* The scale of right-hand side r's profile shape f = x / Σ x (x its fit) that best fits the autos at the small
 * offsets U, 0 < max(|δx|, |δy|) ≤ WT_LEARN_R0_RADIUS, each map and its model less their (weighted) mean over U:
 *   s = Σ w d̃ r̃ / Σ w r̃²,   r = Σ_a f_a R_a (the auto's response), d the autos' maps, ̃ : less the mean over U
 * (qs: Σ_U w R_a d, then Σ_U w d, per map and right-hand side). This is the total Cn² (r0 = s^(−3/5)) that the
 * slopes' covariance over a few subapertures says. The whole fit's total also follows the large scales, which a few
 * seconds of a slow layer sample about once (docs/results.md §58: r0 off by the realisation, its sign with the
 * seed); slopes are mostly small scales (their spectrum κ² Φ falls as κ^(−5/3)), sampled many times a frame, and
 * what the large ones add is nearly constant over U: the mean's removal cancels it (and the tip-tilt removal's
 * −σ²/n of the noise). The shape comes from the whole fit; the small offsets hardly depend on it (every altitude's
 * slopes look alike at a subaperture's scale) nor on L0. */
static double small_scale(const wt_learn *L, const wt_learn_model *M, const double *qs, int nrhs, int ntask, int r,
                          const double *x)
{
    const int m = M->nalt, nu = M->nu;
    double tot = 0, num = 0, den = 0, sw[WT_LEARN_NCOMP] = {0}, swr[WT_LEARN_NCOMP] = {0};
    for (int a = 0; a < m; a++) tot += x[a];
    if (!(tot > 0)) return 0.0;
    for (int c = 0; c < WT_LEARN_NCOMP; c++) {
        const double *R = M->R + (size_t)c * nu * m; /* slot 0: every auto pair's */
        double srr = 0;
        for (int u = 0; u < nu; u++) {
            if (!term_used(M, c, u) || !small_offset(L, M->uoff[u])) continue;
            double ru = 0;
            for (int a = 0; a < m; a++) ru += R[(size_t)u * m + a] * x[a] / tot;
            srr += M->uw[u] * ru * ru, swr[c] += M->uw[u] * ru, sw[c] += M->uw[u];
        }
        den += L->nlgs * (WT_LEARN_R0_CENTRED && sw[c] > 0 ? srr - swr[c] * swr[c] / sw[c] : srr);
    }
    for (int t = 0; t < ntask; t++) {
        const double *qt = qs + ((size_t)t * nrhs + r) * (m + 1);
        const int c = t % WT_LEARN_NCOMP;
        for (int a = 0; a < m; a++) num += qt[a] * x[a] / tot;
        if (WT_LEARN_R0_CENTRED && sw[c] > 0) num -= qt[m] * swr[c] / sw[c];
    }
    return den > 0 ? num / den : 0.0;
}

/* The profile of right-hand side r (its fit x) with its total from the small offsets: c = x except at the lowest
 * altitude, which takes the difference s − Σ x (all of c scaled when that would make it negative), s = small_scale
 * of c's shape (twice: the shape moves with s, s hardly with the shape). Why the lowest: the pairs' differences
 * measure the Cn² at altitude free of the ground's sampling error (the file's header), the autos alone the rest;
 * where the whole fit's total and the small scales disagree, it is the slow low layers' large scales that the
 * frames sampled badly. Returns s (0: none). */
static double place_total(const wt_learn *L, const wt_learn_model *M, const double *qs, int nrhs, int ntask, int r,
                          const double *x, double *c)
{
    const int m = M->nalt;
    double s = 0;
    memcpy(c, x, (size_t)m * sizeof *c);
    for (int it = 0; it < 2; it++) {
        s = small_scale(L, M, qs, nrhs, ntask, r, c);
        if (!(s > 0)) return 0.0;
        double tot = 0;
        for (int a = 0; a < m; a++) tot += c[a];
        if (c[0] + (s - tot) >= 0) c[0] += s - tot;
        else
            for (int a = 0; a < m; a++) c[a] *= s / tot;
    }
    return s;
}

int wt_learn_model_alloc(const wt_learn *L, int nalt, const double *alt, double L0, wt_learn_model **out)
{
    wt_context *ctx = L->ctx;
    const int n = L->n, N = L->N, S = 2 * n - 1, S2 = S * S, m = nalt;
    int st = WT_OK, nth = team();
    wt_learn_model *M = NULL;
    wt_learn__rws *ws[WT_LEARN_MAX_THREADS] = {0};
    double *rb = NULL;
    *out = NULL;
    if (nalt < 1 || nalt > WT_LEARN_MAX_ALT)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %d altitudes, expected 1 to %d", nalt, WT_LEARN_MAX_ALT);
    for (int a = 0; a < nalt; a++) {
        if (a > 0 && !(alt[a] > alt[a - 1]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: altitudes not increasing (%g m then %g m)", alt[a - 1], alt[a]);
        if (!(alt[a] >= 0 && alt[a] < L->H))
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: altitude %g m outside [0, H = %g m)", alt[a], L->H);
    }
    WT_ALLOC(ctx, M, 1, "the learn model");
    M->ctx = ctx, M->n = n, M->nsub = L->nsub, M->nlgs = L->nlgs, M->d = L->d, M->H = L->H, M->nalt = m, M->L0 = L0;
    memcpy(M->theta_x, L->theta_x, (size_t)L->nlgs * sizeof(double));
    memcpy(M->theta_y, L->theta_y, (size_t)L->nlgs * sizeof(double));
    memcpy(M->alt, alt, (size_t)m * sizeof(double));
    WT_ALLOC(ctx, M->valid, n * n, "the model's valid mask");
    memcpy(M->valid, L->valid, (size_t)n * n);
    /* the used offsets, in the maps' order */
    const double P0 = L->pairs[0];
    WT_ALLOC(ctx, M->uoff, S2, "the used offsets");
    WT_ALLOC(ctx, M->uw, S2, "the offsets' weights");
    M->u0 = -1;
    for (int o = 0; o < S2; o++) {
        int dx = o % S - (n - 1), dy = o / S - (n - 1), f = (dx + N) % N + N * ((dy + N) % N);
        if (L->pairs[f] < WT_LEARN_MIN_PAIRS * P0) continue;
        if (dx == 0 && dy == 0) M->u0 = M->nu;
        M->uoff[M->nu] = f, M->uw[M->nu] = L->pairs[f] / P0, M->nu++;
    }
    const int nu = M->nu;
    /* slots: 0 for every auto pair (θ_j − θ_i = 0, one mask: one response), one per cross pair */
    WT_ALLOC(ctx, M->slot, L->npairs, "the pairs' slots");
    int pslot[64 * 65 / 2];
    M->nslot = 1;
    for (int p = 0; p < L->npairs; p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        M->slot[p] = i == j ? 0 : M->nslot++;
        if (i != j) pslot[M->slot[p]] = p;
        else pslot[0] = p;
    }
    WT_ALLOC(ctx, M->R, (size_t)M->nslot * WT_LEARN_NCOMP * nu * m, "the response maps");
    WT_ALLOC(ctx, M->G, (size_t)m * m, "the normal matrix");
    double thmax = 0, hmax = alt[m - 1];
    for (int i = 0; i < L->nlgs; i++)
        for (int j = 0; j < L->nlgs; j++)
            thmax = fmax(thmax, hypot(L->theta_x[j] - L->theta_x[i], L->theta_y[j] - L->theta_y[i]));
    const int ntask = M->nslot * m * WT_LEARN_NCOMP;
    if (nth > ntask) nth = ntask;
    for (int k = 0; k < nth; k++)
        if ((st = wt_learn__rws_alloc(L, L0, wt_learn__rmax(L, thmax, hmax, 0.0), &ws[k])) < 0) goto fail;
    WT_ALLOC(ctx, rb, (size_t)nth * S2, "the response work maps");
    /* one (slot, altitude, component) per task, each thread on its own work space */
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
    for (int t = 0; t < ntask; t++) {
        static const int ca[WT_LEARN_NCOMP] = {0, 1, 0}, cb[WT_LEARN_NCOMP] = {0, 1, 1};
        const int tid = wt_thread_id(), sl = t / (m * WT_LEARN_NCOMP), a = (t / WT_LEARN_NCOMP) % m, c = t % WT_LEARN_NCOMP;
        int i, j;
        wt_learn_pair(L, pslot[sl], &i, &j);
        double *r = rb + (size_t)tid * S2;
        wt_learn__resp_eval(L, ws[tid], L->theta_x[j] - L->theta_x[i], L->theta_y[j] - L->theta_y[i], M->alt[a], 0.0,
                            0.0, ca[c], cb[c], r);
        double *R = M->R + ((size_t)sl * WT_LEARN_NCOMP + c) * nu * m;
        for (int u = 0; u < nu; u++) {
            int f = M->uoff[u], dx = f % N, dy = f / N;
            dx = dx >= n ? dx - N : dx, dy = dy >= n ? dy - N : dy;
            R[(size_t)u * m + a] = r[(dx + n - 1) + S * (dy + n - 1)];
        }
    }
    /* the cross slots' model of the differential statistic: R_ij − R_auto (every LGS has the same mask, so the
     * autos share one response and ½ (R_ii + R_jj) = R_auto) */
    for (int sl = 1; sl < M->nslot; sl++)
        for (size_t k = 0; k < (size_t)WT_LEARN_NCOMP * nu * m; k++) M->R[(size_t)sl * WT_LEARN_NCOMP * nu * m + k] -= M->R[k];
    /* G = Σ_p Σ_c Σ_u w R Rᵀ, in pair order (every auto pair adds slot 0's terms) */
    for (int p = 0; p < L->npairs; p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        for (int c = 0; c < WT_LEARN_NCOMP; c++) {
            const double *R = M->R + ((size_t)M->slot[p] * WT_LEARN_NCOMP + c) * nu * m;
            for (int u = 0; u < nu; u++) {
                if (!term_used(M, c, u)) continue;
                const double w = M->uw[u], *Ru = R + (size_t)u * m;
                for (int b = 0; b < m; b++)
                    for (int a = b; a < m; a++) M->G[a + (size_t)m * b] += w * Ru[a] * Ru[b];
                M->rows++;
            }
        }
    }
    for (int a = 0; a < m; a++)
        for (int b = 0; b < a; b++) M->G[b + (size_t)m * a] = M->G[a + (size_t)m * b];
    *out = M;
    M = NULL;
fail:
    for (int k = 0; k < nth; k++) wt_learn__rws_free(L, ws[k]);
    wt_free(ctx, rb);
    wt_learn_model_free(M);
    return st;
}

int wt_learn_fit_model(const wt_learn *L, const wt_learn_model *M, wt_learn_estimate *est)
{
    wt_context *ctx = L->ctx;
    const int N = L->N, NN = N * N, nf = L->nf, m = M->nalt, nu = M->nu;
    int st = WT_OK;
    memset(est, 0, sizeof *est);
    int same = M->n == L->n && M->nsub == L->nsub && M->nlgs == L->nlgs && M->d == L->d && M->H == L->H;
    for (int i = 0; same && i < L->nlgs; i++) same = M->theta_x[i] == L->theta_x[i] && M->theta_y[i] == L->theta_y[i];
    same = same && !memcmp(M->valid, L->valid, (size_t)L->n * L->n);
    if (!same)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: the model was built for another geometry (%d x %d subapertures, "
                        "%d LGS) than the accumulator's (%d x %d, %d LGS)", M->n, M->n, M->nlgs, L->n, L->n, L->nlgs);
    if (L->frames < 2)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %lld frame(s) accumulated; a covariance estimate needs at least 2",
                        (long long)L->frames);
    /* the batches that hold ≥ 2 frames give the spread; the fit of all frames is the estimate */
    int used[WT_LEARN_MAX_BATCH], nb = 0;
    for (int b = 0; b < L->nbatch; b++)
        if (L->bframes[b] >= 2) used[nb++] = b;
    if (nb < 2) nb = 0; /* one batch: no spread */
    const int nrhs = 1 + nb, ntask = L->npairs * WT_LEARN_NCOMP;
    int autop[64]; /* the auto pair (i, i) of each LGS */
    for (int p = 0; p < L->npairs; p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        if (i == j) autop[i] = p;
    }
    int nth = team();
    if (nth > ntask) nth = ntask;
    double *G = NULL, *q = NULL, *qt = NULL, *work = NULL, *x = NULL, *dn = NULL, *buf = NULL, *qs = NULL;
    int *iwork = NULL;
    WT_ALLOC(ctx, G, (size_t)m * m, "the normal matrix");
    WT_ALLOC(ctx, q, (size_t)m * nrhs, "the normal right-hand sides");
    WT_ALLOC(ctx, qt, (size_t)ntask * (m + 1) * nrhs, "the right-hand sides of each map");
    WT_ALLOC(ctx, qs, (size_t)ntask * (m + 1) * nrhs, "the autos' small offsets' right-hand sides");
    WT_ALLOC(ctx, x, (size_t)m * nrhs, "the fitted profiles");
    WT_ALLOC(ctx, dn, nrhs, "the data norms");
    WT_ALLOC(ctx, work, (size_t)m * (2 * m + 3), "the NNLS work space");
    WT_ALLOC(ctx, iwork, m, "the NNLS work space");
    WT_ALLOC(ctx, buf, (size_t)nth * (2 * nf + NN + 16), "the inverse FFT work arrays");
    /* per (pair, component): the map of each right-hand side (the batches' spectra summed, c2r), then its terms
     * q_a += w R_a C(δ), C = corr / (K P), w = P/P0; into its own slot of qt, summed in task order below (the result
     * does not depend on the thread count) */
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
    for (int t = 0; t < ntask; t++) {
        const int tid = wt_thread_id(), p = t / WT_LEARN_NCOMP, c = t % WT_LEARN_NCOMP;
        double *sp = wt_align64(buf + (size_t)tid * (2 * nf + NN + 16)), *corr = wt_align64(sp + 2 * nf);
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        const double *R = M->R + ((size_t)M->slot[p] * WT_LEARN_NCOMP + c) * nu * m;
        for (int r = 0; r < nrhs; r++) {
            const int b0 = r ? used[r - 1] : 0, b1 = r ? used[r - 1] : L->nbatch - 1;
            const int64_t K = r ? L->bframes[b0] : L->frames;
            memset(sp, 0, (size_t)2 * nf * sizeof *sp);
            for (int b = b0; b <= b1; b++) {
                const double *s = L->spec + (((size_t)b * L->npairs + p) * WT_LEARN_NCOMP + c) * nf * 2;
                for (int k = 0; k < 2 * nf; k++) sp[k] += s[k];
                if (i == j) continue;
                /* the differential statistic: less the mean of the two autos (the maps are linear in the spectra) */
                const double *si = L->spec + (((size_t)b * L->npairs + autop[i]) * WT_LEARN_NCOMP + c) * nf * 2;
                const double *sj = L->spec + (((size_t)b * L->npairs + autop[j]) * WT_LEARN_NCOMP + c) * nf * 2;
                for (int k = 0; k < 2 * nf; k++) sp[k] -= 0.5 * (si[k] + sj[k]);
            }
            fftw_execute_dft_c2r((fftw_plan)L->c2r, (fftw_complex *)sp, corr);
            double *qr = qt + ((size_t)t * nrhs + r) * (m + 1); /* q_a then the data norm */
            double *qsr = qs + ((size_t)t * nrhs + r) * (m + 1); /* Σ w R_a d over the window, then Σ w d */
            const double sc = 1.0 / ((double)NN * (double)K * L->pairs[0]);
            for (int u = 0; u < nu; u++) {
                if (!term_used(M, c, u)) continue;
                /* w C = (P/P0) corr/(N² K P) */
                const double wv = corr[M->uoff[u]] * sc, v = wv / M->uw[u], *Ru = R + (size_t)u * m;
                qr[m] += wv * v;
                for (int a = 0; a < m; a++) qr[a] += Ru[a] * wv;
                if (i == j && small_offset(L, M->uoff[u])) {
                    for (int a = 0; a < m; a++) qsr[a] += Ru[a] * wv;
                    qsr[m] += wv;
                }
            }
        }
    }
    for (int t = 0; t < ntask; t++)
        for (int r = 0; r < nrhs; r++) {
            const double *qr = qt + ((size_t)t * nrhs + r) * (m + 1);
            for (int a = 0; a < m; a++) q[a + (size_t)m * r] += qr[a];
            dn[r] += qr[m];
        }
    est->rows = M->rows;
    /* the scale: the slope variances are ~1e-12 rad²; the minimiser is unchanged by a common factor of G and q */
    double gmax = 0;
    for (int a = 0; a < m; a++) gmax = fmax(gmax, M->G[a + (size_t)m * a]);
    if (!(gmax > 0)) {
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the response maps are all zero (no offsets with enough pairs?)");
        goto fail;
    }
    for (int k = 0; k < m * m; k++) G[k] = M->G[k] / gmax;
    for (int k = 0; k < m * nrhs; k++) q[k] /= gmax;
    for (int r = 0; r < nrhs; r++)
        if (wt_learn_nnls(m, G, q + (size_t)m * r, x + (size_t)m * r, work, iwork) < 0) {
            st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the non-negative fit did not converge (%s)",
                          r ? "a batch" : "all frames");
            goto fail;
        }
    const double *alt = M->alt;
    est->nalt = m, est->L0 = M->L0, est->frames = L->frames, est->nbatch = nb ? nb : 1, est->sigma_factor = 1.0;
    double tot = 0, mis = 0;
    for (int a = 0; a < m; a++) tot += x[a];
    if (!(tot > 0)) {
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the fit finds no turbulence (every Cn² = 0): are these open-loop slopes?");
        goto fail;
    }
    /* misfit² = xᵀGx − 2 qᵀx + Σ w m² (in G's scale) */
    for (int a = 0; a < m; a++) {
        double gx = 0;
        for (int b = 0; b < m; b++) gx += G[a + (size_t)m * b] * x[b];
        mis += x[a] * (gx - 2 * q[a]);
    }
    est->residual = dn[0] > 0 ? sqrt(fmax(0.0, mis * gmax + dn[0]) / dn[0]) : 0.0;
    for (int a = 0; a < m; a++) {
        est->altitude[a] = alt[a], est->cn2[a] = x[a], est->fraction[a] = x[a] / tot;
    }
    /* r0: the profile's shape from the whole fit, its scale from the autos' smallest offsets (small_scale) */
    est->r0_total = pow(tot, -3.0 / 5.0);
    double cb[WT_LEARN_MAX_ALT];
    const double sc0 = place_total(L, M, qs, nrhs, ntask, 0, x, est->cn2);
    if (!(sc0 > 0)) {
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the slopes' covariance within two subapertures is not positive "
                      "(%g of the fitted profile's): are these open-loop slopes?", sc0);
        goto fail;
    }
    est->r0 = pow(sc0, -3.0 / 5.0);
    for (int a = 0; a < m; a++) est->fraction[a] = est->cn2[a] / sc0;
    if (nb >= 2) {
        /* the spread of the batch estimates, over √B: the standard error of their mean */
        double s0 = 0, s1 = 0;
        double fs[WT_LEARN_MAX_ALT] = {0}, fs2[WT_LEARN_MAX_ALT] = {0};
        for (int r = 1; r <= nb; r++) {
            const double sr = place_total(L, M, qs, nrhs, ntask, r, x + (size_t)m * r, cb);
            double r0b = sr > 0 ? pow(sr, -3.0 / 5.0) : 0.0;
            s0 += r0b, s1 += r0b * r0b;
            est->batch_r0[r - 1] = r0b;
            for (int a = 0; a < m; a++) {
                double f = sr > 0 ? cb[a] / sr : 0.0;
                est->batch_fraction[r - 1][a] = f;
                fs[a] += f, fs2[a] += f * f;
            }
        }
        est->r0_sigma = sqrt(fmax(0.0, (s1 - s0 * s0 / nb) / (nb - 1)) / nb);
        for (int a = 0; a < m; a++) est->fraction_sigma[a] = sqrt(fmax(0.0, (fs2[a] - fs[a] * fs[a] / nb) / (nb - 1)) / nb);
    }
fail:
    wt_free(ctx, G), wt_free(ctx, q), wt_free(ctx, qt), wt_free(ctx, x), wt_free(ctx, dn), wt_free(ctx, buf);
    wt_free(ctx, work), wt_free(ctx, iwork), wt_free(ctx, qs);
    return st;
}

int wt_learn_fit(const wt_learn *L, int nalt, const double *alt, double L0, wt_learn_estimate *est)
{
    memset(est, 0, sizeof *est);
    /* the cheap refusals first: a model costs seconds */
    if (nalt < 1 || nalt > WT_LEARN_MAX_ALT)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: %d altitudes, expected 1 to %d", nalt, WT_LEARN_MAX_ALT);
    for (int a = 1; a < nalt; a++)
        if (!(alt[a] > alt[a - 1]))
            return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: altitudes not increasing (%g m then %g m)", alt[a - 1], alt[a]);
    if (L->frames < 2)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: %lld frame(s) accumulated; a covariance estimate needs at least 2",
                        (long long)L->frames);
    wt_learn_model *M = NULL;
    int st = wt_learn_model_alloc(L, nalt, alt, L0, &M);
    if (st < 0) return st;
    st = wt_learn_fit_model(L, M, est);
    wt_learn_model_free(M);
    return st;
}
