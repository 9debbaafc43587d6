/* core/model/learn_fit.c: the non-negative fit of the Cn² profile to the LGS cross-covariance maps, r0 from its
 * total, the batches' spread as the uncertainty (SPEC §12, "Identification from the loop's own data"). */
#include "learn_private.h"

#include <math.h>
#include <string.h>

/* Solve A z = b for the k × k symmetric positive definite A (column-major, leading dimension lda) by Cholesky in
 * place on a copy w (k²). A pivot that is not positive (a column that the others reproduce) is lifted to a
 * relative 1e-12 of the diagonal's largest: that column's z then comes out ~0, which the active set drops. */
static void spd_solve(int k, const double *A, int lda, const double *b, double *z, double *w)
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
            spd_solve(np, sub, m, rhs, zs, chol);
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

int wt_learn_fit(const wt_learn *L, int nalt, const double *alt, double L0, wt_learn_estimate *est)
{
    wt_context *ctx = L->ctx;
    const int n = L->n, S = 2 * n - 1, S2 = S * S, m = nalt;
    int st = WT_OK;
    memset(est, 0, sizeof *est);
    if (nalt < 1 || nalt > WT_LEARN_MAX_ALT)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %d altitudes, expected 1 to %d", nalt, WT_LEARN_MAX_ALT);
    for (int a = 1; a < nalt; a++)
        if (!(alt[a] > alt[a - 1]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: altitudes not increasing (%g m then %g m)", alt[a - 1], alt[a]);
    if (L->frames < 2)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %lld frame(s) accumulated; a covariance estimate needs at least 2",
                        (long long)L->frames);
    /* the batches that hold ≥ 2 frames give the spread; the fit of all frames is the estimate */
    int used[WT_LEARN_MAX_BATCH], nb = 0;
    for (int b = 0; b < L->nbatch; b++)
        if (L->bframes[b] >= 2) used[nb++] = b;
    if (nb < 2) nb = 0; /* one batch: no spread */
    const int nrhs = 1 + nb;
    int auto_done = 0;
    double *resp = NULL, *resp_auto = NULL, *map = NULL, *G = NULL, *q = NULL, *work = NULL, *x = NULL, *dn = NULL;
    int *iwork = NULL;
    WT_ALLOC(ctx, resp, (size_t)m * WT_LEARN_NCOMP * S2, "the response maps of a pair");
    WT_ALLOC(ctx, resp_auto, (size_t)m * WT_LEARN_NCOMP * S2, "the response maps of the auto pairs");
    WT_ALLOC(ctx, map, (size_t)nrhs * WT_LEARN_NCOMP * S2, "the maps of a pair");
    WT_ALLOC(ctx, G, (size_t)m * m, "the normal matrix");
    WT_ALLOC(ctx, q, (size_t)m * nrhs, "the normal right-hand sides");
    WT_ALLOC(ctx, x, (size_t)m * nrhs, "the fitted profiles");
    WT_ALLOC(ctx, dn, nrhs, "the data norms");
    WT_ALLOC(ctx, work, (size_t)m * (2 * m + 3), "the NNLS work space");
    WT_ALLOC(ctx, iwork, m, "the NNLS work space");
    const double P0 = L->pairs[0];
    for (int p = 0; p < L->npairs; p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        /* every auto pair sees the same thing (θ_j − θ_i = 0, one mask): its response maps are computed once */
        if (i != j || !auto_done) {
            if ((st = wt_learn_response(L, p, m, alt, L0, resp)) < 0) goto fail;
            if (i == j) {
                memcpy(resp_auto, resp, (size_t)m * WT_LEARN_NCOMP * S2 * sizeof *resp);
                auto_done = 1;
            }
        } else
            memcpy(resp, resp_auto, (size_t)m * WT_LEARN_NCOMP * S2 * sizeof *resp);
        for (int r = 0; r < nrhs; r++)
            for (int c = 0; c < WT_LEARN_NCOMP; c++)
                if ((st = wt_learn_map(L, r ? used[r - 1] : -1, p, c, map + ((size_t)r * WT_LEARN_NCOMP + c) * S2, NULL)) < 0)
                    goto fail;
        for (int c = 0; c < WT_LEARN_NCOMP; c++)
            for (int o = 0; o < S2; o++) {
                int dx = o % S - (n - 1), dy = o / S - (n - 1);
                double P = L->pairs[(dx + L->N) % L->N + L->N * ((dy + L->N) % L->N)];
                /* the autos' variances carry the noise (SPEC §12: noise at δ = 0 only): left out */
                if (P < WT_LEARN_MIN_PAIRS * P0 || (i == j && dx == 0 && dy == 0 && c != WT_LEARN_XY)) continue;
                const double w = P / P0;
                const double *R = resp + (size_t)c * S2 + o;
                for (int a = 0; a < m; a++)
                    for (int b = 0; b <= a; b++) G[a + (size_t)m * b] += w * R[(size_t)a * WT_LEARN_NCOMP * S2] *
                                                                          R[(size_t)b * WT_LEARN_NCOMP * S2];
                for (int r = 0; r < nrhs; r++) {
                    double v = map[((size_t)r * WT_LEARN_NCOMP + c) * S2 + o];
                    dn[r] += w * v * v;
                    for (int a = 0; a < m; a++) q[a + (size_t)m * r] += w * R[(size_t)a * WT_LEARN_NCOMP * S2] * v;
                }
                est->rows++;
            }
    }
    /* the scale: the slope variances are ~1e-12 rad²; the minimiser is unchanged by a common factor of G and q */
    double gmax = 0;
    for (int a = 0; a < m; a++) {
        for (int b = 0; b < a; b++) G[b + (size_t)m * a] = G[a + (size_t)m * b];
        gmax = fmax(gmax, G[a + (size_t)m * a]);
    }
    if (!(gmax > 0)) {
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the response maps are all zero (no offsets with enough pairs?)");
        goto fail;
    }
    for (int k = 0; k < m * m; k++) G[k] /= gmax;
    for (int k = 0; k < m * nrhs; k++) q[k] /= gmax;
    for (int r = 0; r < nrhs; r++)
        if (wt_learn_nnls(m, G, q + (size_t)m * r, x + (size_t)m * r, work, iwork) < 0) {
            st = WT_ERROR(ctx, WT_ERR_NUMERIC, "learn: the non-negative fit did not converge (%s)",
                          r ? "a batch" : "all frames");
            goto fail;
        }
    est->nalt = m, est->L0 = L0, est->frames = L->frames, est->nbatch = nb ? nb : 1;
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
    est->r0 = pow(tot, -3.0 / 5.0);
    if (nb >= 2) {
        /* the spread of the batch estimates, over √B: the standard error of their mean */
        double s0 = 0, s1 = 0;
        double fs[WT_LEARN_MAX_ALT] = {0}, fs2[WT_LEARN_MAX_ALT] = {0};
        for (int r = 1; r <= nb; r++) {
            double t = 0;
            for (int a = 0; a < m; a++) t += x[a + (size_t)m * r];
            double r0b = t > 0 ? pow(t, -3.0 / 5.0) : 0.0;
            s0 += r0b, s1 += r0b * r0b;
            est->batch_r0[r - 1] = r0b;
            for (int a = 0; a < m; a++) {
                double f = t > 0 ? x[a + (size_t)m * r] / t : 0.0;
                est->batch_fraction[r - 1][a] = f;
                fs[a] += f, fs2[a] += f * f;
            }
        }
        est->r0_sigma = sqrt(fmax(0.0, (s1 - s0 * s0 / nb) / (nb - 1)) / nb);
        for (int a = 0; a < m; a++) est->fraction_sigma[a] = sqrt(fmax(0.0, (fs2[a] - fs[a] * fs[a] / nb) / (nb - 1)) / nb);
    }
fail:
    wt_free(ctx, resp), wt_free(ctx, resp_auto), wt_free(ctx, map), wt_free(ctx, G), wt_free(ctx, q), wt_free(ctx, x), wt_free(ctx, dn);
    wt_free(ctx, work), wt_free(ctx, iwork);
    return st;
}
