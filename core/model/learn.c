/* core/model/learn.c: the slope cross-covariance maps of LGS pairs, accumulated frame by frame by FFT of the
 * zero-padded, tip-tilt-removed slope maps (SPEC §12, "Identification from the loop's own data"). */
#include "learn_private.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>

void wt_learn__inverse(const wt_learn *L, const double *sp, double *out)
{
    const int N = L->N;
    memcpy(L->cwork_a, sp, (size_t)L->nf * 2 * sizeof(double));
    fftw_execute_dft_c2r((fftw_plan)L->c2r, (fftw_complex *)L->cwork_a, L->grid_a);
    const double s = 1.0 / ((double)N * N);
    for (int k = 0; k < N * N; k++) out[k] = L->grid_a[k] * s;
}

void wt_learn__forward(const wt_learn *L, const double *in, double *sp)
{
    const int N = L->N;
    memcpy(L->grid_a, in, (size_t)N * N * sizeof(double));
    fftw_execute_dft_r2c((fftw_plan)L->r2c, L->grid_a, (fftw_complex *)L->cwork_a);
    memcpy(sp, L->cwork_a, (size_t)L->nf * 2 * sizeof(double));
}

int wt_learn_default_grid(double H, int max, double *alt)
{
    /* 0 and 0.5 km resolve the ground layer from the one just above it (the autos and the widest pairs); above,
     * 1 km is about the resolution d/θ of the pairs of a 0.5 m subaperture and 1–2 arcmin separations */
    int k = 0;
    if (k < max && 0.0 < H) alt[k++] = 0.0;
    if (k < max && 500.0 < H) alt[k++] = 500.0;
    for (int km = 1; km <= 20 && k < max && 1e3 * km < H; km++) alt[k++] = 1e3 * km;
    return k;
}

double wt_learn_screen_factor(double D, double batch_s, double total_s, int n, const double *fraction,
                              const double *speed, double *screens)
{
    double tau = 0.0, ftot = 0.0;
    for (int k = 0; k < n; k++) {
        if (!(fraction[k] > 0.0)) continue;
        tau += fraction[k] / fmax(fabs(speed[k]), WT_LEARN_VMIN);
        ftot += fraction[k];
    }
    tau = ftot > 0.0 ? D * tau / ftot : 0.0;
    if (screens) *screens = tau > 0.0 ? total_s / tau : 0.0;
    return batch_s > 0.0 && tau > batch_s ? sqrt(tau / batch_s) : 1.0;
}

void wt_learn_estimate_count_screens(wt_learn_estimate *e, double D, double dt, int n, const double *fraction,
                                     const double *speed)
{
    const int B = e->nbatch > 0 ? e->nbatch : 1;
    const double T = (double)e->frames * dt;
    const double f = wt_learn_screen_factor(D, T / B, T, n, fraction, speed, &e->screens);
    e->sigma_factor = f;
    e->r0_sigma *= f;
    for (int a = 0; a < e->nalt; a++) e->fraction_sigma[a] *= f;
}

static double merge_separation(const wt_learn_geometry *g)
{
    double tmax = 0.0;
    for (int i = 0; i < g->nlgs; i++)
        for (int j = i + 1; j < g->nlgs; j++)
            tmax = fmax(tmax, hypot(g->theta_x[i] - g->theta_x[j], g->theta_y[i] - g->theta_y[j]));
    return tmax > 0.0 ? 0.5 * g->d / tmax : 0.0;
}

int wt_learn_grid_with_layers(const wt_learn_geometry *g, int nlayer, const double *layer, int max, double *alt,
                              double *sep)
{
    double def[WT_LEARN_MAX_ALT];
    const int nd = wt_learn_default_grid(g->H, WT_LEARN_MAX_ALT, def);
    const double s = merge_separation(g);
    if (sep) *sep = s;
    int k = 0;
    for (int i = 0; i < nlayer; i++) {
        int dup = !(layer[i] >= 0.0 && layer[i] < g->H);
        for (int j = 0; j < k && !dup; j++) dup = alt[j] == layer[i];
        if (dup) continue;
        if (k == max) return WT_ERR_INVALID;
        alt[k++] = layer[i];
    }
    const int nl = k;
    for (int i = 0; i < nd; i++) {
        int near = 0;
        for (int j = 0; j < nl && !near; j++) near = fabs(def[i] - alt[j]) < s;
        if (near) continue;
        if (k == max) return WT_ERR_INVALID;
        alt[k++] = def[i];
    }
    for (int i = 1; i < k; i++) /* ascending (insertion: a few dozen points) */
        for (int j = i; j > 0 && alt[j] < alt[j - 1]; j--) {
            const double t = alt[j];
            alt[j] = alt[j - 1], alt[j - 1] = t;
        }
    return k;
}

void wt_learn_free(wt_learn *L)
{
    if (!L) return;
    wt_context *ctx = L->ctx;
    if (L->r2c) fftw_destroy_plan((fftw_plan)L->r2c);
    if (L->c2r) fftw_destroy_plan((fftw_plan)L->c2r);
    wt_free(ctx, L->valid), wt_free(ctx, L->sub), wt_free(ctx, L->theta_x), wt_free(ctx, L->theta_y);
    wt_free(ctx, L->bframes), wt_free(ctx, L->spec), wt_free(ctx, L->pairs), wt_free(ctx, L->grid);
    wt_free(ctx, L->four), wt_free(ctx, L->cwork);
    wt_free(ctx, L->ring), wt_free(ctx, L->lspec), wt_free(ctx, L->lframes);
    wt_free(ctx, L);
}

int wt_learn_alloc(wt_context *ctx, const wt_learn_geometry *g, int nbatch, int64_t batch_frames, wt_learn **out)
{
    return wt_learn_alloc_lagged(ctx, g, nbatch, batch_frames, 0, NULL, out);
}

int wt_learn_alloc_lagged(wt_context *ctx, const wt_learn_geometry *g, int nbatch, int64_t batch_frames, int nlag,
                          const int *lags, wt_learn **out)
{
    int st = WT_OK;
    wt_learn *L = NULL;
    *out = NULL;
    if (!g || g->n < 2 || g->n > 4096 || !(g->d > 0) || !g->valid || g->nlgs < 1 || g->nlgs > 64 || !g->theta_x ||
        !g->theta_y || !(g->H > 0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: bad LGS geometry (n %d, d %g m, %d LGS, range H %g m): need n ≥ 2, "
                        "d > 0, 1–64 LGS with directions and a finite range H > 0", g ? g->n : 0, g ? g->d : 0.0,
                        g ? g->nlgs : 0, g ? g->H : 0.0);
    if (nbatch < 1 || nbatch > WT_LEARN_MAX_BATCH)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %d batches, expected 1 to %d", nbatch, WT_LEARN_MAX_BATCH);
    if (nlag < 0 || nlag > WT_LEARN_MAX_LAG || (nlag > 0 && !lags))
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %d lags, expected 0 to %d", nlag, WT_LEARN_MAX_LAG);
    for (int q = 0; q < nlag; q++)
        if (lags[q] < 1 || lags[q] > WT_LEARN_MAX_LAG_FRAMES || (q > 0 && lags[q] <= lags[q - 1]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: lag %d frames (lag %d of %d): lags must increase, from 1 to %d "
                            "frames", lags[q], q + 1, nlag, WT_LEARN_MAX_LAG_FRAMES);
    L = wt_calloc(ctx, 1, sizeof *L);
    if (!L) return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory allocating the learn accumulator");
    L->ctx = ctx;
    const int n = g->n, N = 2 * n;
    L->n = n, L->d = g->d, L->nlgs = g->nlgs, L->H = g->H, L->N = N, L->nf = N * (N / 2 + 1);
    L->npairs = g->nlgs * (g->nlgs + 1) / 2;
    L->nbatch = nbatch, L->batch_frames = batch_frames;
    WT_ALLOC(ctx, L->valid, n * n, "the learn valid mask");
    memcpy(L->valid, g->valid, (size_t)n * n);
    for (int k = 0; k < n * n; k++) L->nsub += L->valid[k] != 0;
    if (L->nsub < 2) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "learn: %d valid subapertures, need at least 2", L->nsub);
        goto fail;
    }
    WT_ALLOC(ctx, L->sub, L->nsub, "the learn subaperture list");
    for (int k = 0, m = 0; k < n * n; k++)
        if (L->valid[k]) L->sub[m++] = k;
    WT_ALLOC(ctx, L->theta_x, g->nlgs, "the LGS directions");
    WT_ALLOC(ctx, L->theta_y, g->nlgs, "the LGS directions");
    memcpy(L->theta_x, g->theta_x, (size_t)g->nlgs * sizeof(double));
    memcpy(L->theta_y, g->theta_y, (size_t)g->nlgs * sizeof(double));
    WT_ALLOC(ctx, L->bframes, nbatch, "the batch counts");
    WT_ALLOC(ctx, L->spec, (size_t)nbatch * L->npairs * WT_LEARN_NCOMP * L->nf * 2, "the cross-spectra");
    WT_ALLOC(ctx, L->pairs, N * N, "the pair counts");
    WT_ALLOC(ctx, L->grid, N * N + 8, "the FFT grid");
    WT_ALLOC(ctx, L->four, (size_t)2 * g->nlgs * L->nf * 2 + 8, "the frame spectra");
    WT_ALLOC(ctx, L->cwork, (size_t)L->nf * 2 + 8, "the FFT work spectrum");
    if (nlag > 0) {
        L->nlag = nlag, L->kmax = lags[nlag - 1];
        memcpy(L->lag, lags, (size_t)nlag * sizeof *lags);
        WT_ALLOC(ctx, L->ring, (size_t)(L->kmax + 1) * 2 * g->nlgs * L->nf * 2, "the ring of recent frames' spectra");
        WT_ALLOC(ctx, L->lspec, (size_t)nbatch * nlag * g->nlgs * g->nlgs * 2 * L->nf * 2, "the lagged cross-spectra");
        WT_ALLOC(ctx, L->lframes, (size_t)nbatch * nlag, "the lagged frame counts");
    }
    L->grid_a = wt_align64(L->grid), L->four_a = wt_align64(L->four), L->cwork_a = wt_align64(L->cwork);
    /* planned on the arrays they run on (or others of the same 64-byte alignment: every spectrum slot is, as
     * N (N/2 + 1) · 16 bytes is a multiple of 64 for even N) */
    L->r2c = (struct fftw_plan_s *)fftw_plan_dft_r2c_2d(N, N, L->grid_a, (fftw_complex *)L->cwork_a, FFTW_ESTIMATE);
    L->c2r = (struct fftw_plan_s *)fftw_plan_dft_c2r_2d(N, N, (fftw_complex *)L->cwork_a, L->grid_a, FFTW_ESTIMATE);
    if (!L->r2c || !L->c2r) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "fftw_plan_dft_r2c_2d/c2r_2d (%d x %d) failed for the learn maps", N, N);
        goto fail;
    }
    /* P(δ) = Σ_a M(a) M(a + δ): the autocorrelation of the mask, rounded (its values are integers) */
    {
        double *m = L->pairs;
        memset(m, 0, (size_t)N * N * sizeof *m);
        for (int s = 0; s < L->nsub; s++) m[L->sub[s] % n + N * (L->sub[s] / n)] = 1.0;
        wt_learn__forward(L, m, L->four_a);
        double *f = L->four_a;
        for (int k = 0; k < L->nf; k++) f[2 * k] = f[2 * k] * f[2 * k] + f[2 * k + 1] * f[2 * k + 1], f[2 * k + 1] = 0;
        wt_learn__inverse(L, f, m);
        for (int k = 0; k < N * N; k++) m[k] = nearbyint(m[k]);
    }
    *out = L;
    return WT_OK;
fail:
    wt_learn_free(L);
    return st;
}

int64_t wt_learn_frames(const wt_learn *L) { return L->frames; }

void wt_learn_set_progress(wt_learn *L, wt_learn_progress_fn fn, void *user)
{
    L->progress = fn, L->progress_user = user;
}

void wt_learn_reset(wt_learn *L)
{
    memset(L->spec, 0, (size_t)L->nbatch * L->npairs * WT_LEARN_NCOMP * L->nf * 2 * sizeof(double));
    memset(L->bframes, 0, (size_t)L->nbatch * sizeof *L->bframes);
    if (L->nlag > 0) {
        memset(L->lspec, 0, (size_t)L->nbatch * L->nlag * L->nlgs * L->nlgs * 2 * L->nf * 2 * sizeof(double));
        memset(L->lframes, 0, (size_t)L->nbatch * L->nlag * sizeof *L->lframes);
    }
    L->frames = 0; /* the ring's old frames are never read again: a lag pairs frames added since the reset */
}
int wt_learn_npairs(const wt_learn *L) { return L->npairs; }
int wt_learn_map_side(const wt_learn *L) { return 2 * L->n - 1; }

void wt_learn_pair(const wt_learn *L, int p, int *i, int *j)
{
    int a = 0;
    while (p >= L->nlgs - a) p -= L->nlgs - a, a++;
    *i = a, *j = a + p;
}

int wt_learn_add(wt_learn *L, const double *slopes)
{
    const int n = L->n, N = L->N, ns = L->nsub, nf = L->nf;
    for (int i = 0; i < L->nlgs; i++)
        for (int k = 0; k < 2 * ns; k++)
            if (!isfinite(slopes[(int64_t)i * 2 * ns + k]))
                return WT_ERROR(L->ctx, WT_ERR_NUMERIC, "learn: LGS %d slope %d is %g (frame %lld not used)", i + 1,
                                k, slopes[(int64_t)i * 2 * ns + k], (long long)L->frames);
    /* each LGS's x and y slopes, less their mean over the valid subapertures (its tip-tilt), on the padded grid */
    for (int i = 0; i < L->nlgs; i++)
        for (int c = 0; c < 2; c++) {
            const double *s = slopes + (int64_t)i * 2 * ns + (int64_t)c * ns;
            double mean = 0;
            for (int k = 0; k < ns; k++) mean += s[k];
            mean /= ns;
            memset(L->grid_a, 0, (size_t)N * N * sizeof(double));
            for (int k = 0; k < ns; k++) L->grid_a[L->sub[k] % n + N * (L->sub[k] / n)] = s[k] - mean;
            fftw_execute_dft_r2c((fftw_plan)L->r2c, L->grid_a, (fftw_complex *)(L->four_a + (size_t)(2 * i + c) * nf * 2));
        }
    int b = L->batch_frames > 0 ? (int)(L->frames / L->batch_frames) : 0;
    if (b >= L->nbatch) b = L->nbatch - 1;
    /* conj(Ŝ_i^a) Ŝ_j^b: the cross-correlation Σ_a s_i(a) s_j(a + δ) of the frame, in Fourier space */
    static const int ca[WT_LEARN_NCOMP] = {0, 1, 0}, cb[WT_LEARN_NCOMP] = {0, 1, 1};
    for (int p = 0; p < L->npairs; p++) {
        int i, j;
        wt_learn_pair(L, p, &i, &j);
        for (int c = 0; c < WT_LEARN_NCOMP; c++) {
            const double *x = L->four_a + (size_t)(2 * i + ca[c]) * nf * 2, *y = L->four_a + (size_t)(2 * j + cb[c]) * nf * 2;
            double *acc = L->spec + (((size_t)b * L->npairs + p) * WT_LEARN_NCOMP + c) * nf * 2;
            for (int k = 0; k < nf; k++) {
                acc[2 * k] += x[2 * k] * y[2 * k] + x[2 * k + 1] * y[2 * k + 1];
                acc[2 * k + 1] += x[2 * k] * y[2 * k + 1] - x[2 * k + 1] * y[2 * k];
            }
        }
    }
    /* the lagged products conj(Ŝ_i^c(t − k)) Ŝ_j^c(t), every ordered pair, c ∈ {x, y}: to the batch of t */
    if (L->nlag > 0) {
        const int R = L->kmax + 1, nl = L->nlgs;
        for (int q = 0; q < L->nlag; q++) {
            if (L->frames < L->lag[q]) continue;
            const double *old = L->ring + (size_t)((L->frames - L->lag[q]) % R) * 2 * nl * nf * 2;
            for (int i = 0; i < nl; i++)
                for (int j = 0; j < nl; j++)
                    for (int c = 0; c < 2; c++) {
                        const double *x = old + (size_t)(2 * i + c) * nf * 2, *y = L->four_a + (size_t)(2 * j + c) * nf * 2;
                        double *acc = L->lspec + ((((size_t)b * L->nlag + q) * nl + i) * nl * 2 + (size_t)j * 2 + c) * nf * 2;
                        for (int k = 0; k < nf; k++) {
                            acc[2 * k] += x[2 * k] * y[2 * k] + x[2 * k + 1] * y[2 * k + 1];
                            acc[2 * k + 1] += x[2 * k] * y[2 * k + 1] - x[2 * k + 1] * y[2 * k];
                        }
                    }
            L->lframes[(size_t)b * L->nlag + q]++;
        }
        memcpy(L->ring + (size_t)(L->frames % R) * 2 * nl * nf * 2, L->four_a, (size_t)2 * nl * nf * 2 * sizeof(double));
    }
    L->bframes[b]++;
    L->frames++;
    return WT_OK;
}

int wt_learn_map(const wt_learn *L, int batch, int p, int comp, double *map, double *count)
{
    const int n = L->n, N = L->N, nf = L->nf, S = 2 * n - 1;
    if (batch < -1 || batch >= L->nbatch || p < 0 || p >= L->npairs || comp < 0 || comp >= WT_LEARN_NCOMP)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: no map for batch %d, pair %d, component %d (%d batches, %d pairs)",
                        batch, p, comp, L->nbatch, L->npairs);
    int64_t K = batch < 0 ? L->frames : L->bframes[batch];
    if (K < 1) return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: no frames in %s", batch < 0 ? "the accumulator" : "the batch");
    double *sum = wt_calloc(L->ctx, (size_t)nf * 2 + (size_t)N * N, sizeof(double));
    if (!sum) return WT_ERROR(L->ctx, WT_ERR_NOMEM, "out of memory for a learn map");
    double *corr = sum + (size_t)nf * 2;
    for (int b = batch < 0 ? 0 : batch; b <= (batch < 0 ? L->nbatch - 1 : batch); b++) {
        const double *s = L->spec + (((size_t)b * L->npairs + p) * WT_LEARN_NCOMP + comp) * nf * 2;
        for (int k = 0; k < 2 * nf; k++) sum[k] += s[k];
    }
    wt_learn__inverse(L, sum, corr);
    for (int dy = -(n - 1); dy <= n - 1; dy++)
        for (int dx = -(n - 1); dx <= n - 1; dx++) {
            int f = (dx + N) % N + N * ((dy + N) % N), o = (dx + n - 1) + S * (dy + n - 1);
            double P = L->pairs[f];
            map[o] = P > 0 ? corr[f] / ((double)K * P) : 0.0;
            if (count) count[o] = P;
        }
    wt_free(L->ctx, sum);
    return WT_OK;
}

int wt_learn_nlags(const wt_learn *L) { return L->nlag; }
int wt_learn_lag(const wt_learn *L, int q) { return q >= 0 && q < L->nlag ? L->lag[q] : 0; }

int wt_learn_lag_map(const wt_learn *L, int batch, int q, int i, int j, int comp, double *map, double *count)
{
    const int n = L->n, N = L->N, nf = L->nf, S = 2 * n - 1, nl = L->nlgs;
    if (batch < -1 || batch >= L->nbatch || q < 0 || q >= L->nlag || i < 0 || i >= nl || j < 0 || j >= nl || comp < 0 ||
        comp > WT_LEARN_YY)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: no lagged map for batch %d, lag %d, LGS %d and %d, component %d "
                        "(%d batches, %d lags, %d LGS; x x and y y only)", batch, q, i, j, comp, L->nbatch, L->nlag, nl);
    int64_t K = 0;
    for (int b = batch < 0 ? 0 : batch; b <= (batch < 0 ? L->nbatch - 1 : batch); b++) K += L->lframes[(size_t)b * L->nlag + q];
    if (K < 1)
        return WT_ERROR(L->ctx, WT_ERR_INVALID, "learn: no frame pairs %d frames apart in %s (%lld frames added)", L->lag[q],
                        batch < 0 ? "the accumulator" : "the batch", (long long)L->frames);
    double *sum = wt_calloc(L->ctx, (size_t)nf * 2 + (size_t)N * N, sizeof(double));
    if (!sum) return WT_ERROR(L->ctx, WT_ERR_NOMEM, "out of memory for a learn map");
    double *corr = sum + (size_t)nf * 2;
    for (int b = batch < 0 ? 0 : batch; b <= (batch < 0 ? L->nbatch - 1 : batch); b++) {
        const double *s = L->lspec + ((((size_t)b * L->nlag + q) * nl + i) * nl * 2 + (size_t)j * 2 + comp) * nf * 2;
        for (int k = 0; k < 2 * nf; k++) sum[k] += s[k];
    }
    wt_learn__inverse(L, sum, corr);
    for (int dy = -(n - 1); dy <= n - 1; dy++)
        for (int dx = -(n - 1); dx <= n - 1; dx++) {
            int f = (dx + N) % N + N * ((dy + N) % N), o = (dx + n - 1) + S * (dy + n - 1);
            double P = L->pairs[f];
            map[o] = P > 0 ? corr[f] / ((double)K * P) : 0.0;
            if (count) count[o] = P;
        }
    wt_free(L->ctx, sum);
    return WT_OK;
}
