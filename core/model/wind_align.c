/* core/model/wind_align.c: the wind of each reconstructed layer from its aligned estimates (wind_align.h). */
#include "wind_align.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#else
static int omp_in_parallel(void) { return 0; }
#endif

/* a snapshot's layers run on the context's threads from this many points on: below it waking a team costs more
 * than the transforms (a few µs of work against a team that, on a loaded host, may wait a time slice) */
#define WT_WIND_ALIGN_PARALLEL_POINTS 65536

typedef struct {
    int n, nh;           /* n × n points; nh = n/2 + 1 columns of the r2c half spectrum */
    size_t nc, slot;     /* n · nh complex values; a ring slot's length (nc rounded up to 4: 64-byte aligned) */
    int64_t offset;
    double dx;           /* spacing δ [m] */
    fftw_plan r2c, c2r;
    fftw_complex *ring;  /* (lag_max + 1) slots: the last snapshots' spectra */
    double *S;           /* [batch][lag][nc] complex (re, im): Σ X_{t+τ} conj(X_t) */
    double *P;           /* [batch][nc]: Σ |X_t|² */
    double *T;           /* n²: the taper (1 inside 0.5 R, raised cosine to 0 at R; NULL: none, the periodic grid) */
} layer;

struct wt_wind_align {
    wt_context *ctx;
    int L, nthreads, R;  /* R: the longest lag [snapshots] */
    int parallel;        /* the layers of a snapshot on the context's threads (enough points to pay a team) */
    wt_wind_align_params par;
    layer *lay;
    double *work;        /* per thread: the largest n² (the layer copied to FFTW's alignment; the correlation) */
    fftw_complex *spec;  /* the largest nc: the weighted cross-spectrum for the inverse transform */
    double *sq, *pq;     /* estimate's scratch: nlag · nc complex sums, nc auto-spectrum */
    double *hw, *aw;     /* estimate's scratch: the filter's and the footprint's power per frequency (nc each) */
    double *tab;         /* estimate's scratch: the phase factors' 1-D tables (4 n) */
    size_t nwork, ncmax;
    long nsnap, last_t;
    long nq[WT_WIND_ALIGN_MAX_BATCH][WT_WIND_ALIGN_MAX_LAGS], np[WT_WIND_ALIGN_MAX_BATCH];
    double tacc;
};

void wt_wind_align_free(wt_wind_align *w)
{
    if (!w) return;
    for (int l = 0; l < w->L && w->lay; l++) {
        layer *y = &w->lay[l];
        if (y->r2c) fftw_destroy_plan(y->r2c);
        if (y->c2r) fftw_destroy_plan(y->c2r);
        fftw_free(y->ring);
        wt_free(w->ctx, y->S);
        wt_free(w->ctx, y->P);
        wt_free(w->ctx, y->T);
    }
    wt_free(w->ctx, w->lay);
    fftw_free(w->work);
    fftw_free(w->spec);
    wt_free(w->ctx, w->sq);
    wt_free(w->ctx, w->pq);
    wt_free(w->ctx, w->hw);
    wt_free(w->ctx, w->aw);
    wt_free(w->ctx, w->tab);
    wt_free(w->ctx, w);
}

int wt_wind_align_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, const double *radius,
                        wt_fft_wisdom *fft, const wt_wind_align_params *par, wt_wind_align **out)
{
    int st = WT_OK;
    wt_wind_align *w = NULL;
    *out = NULL;
    if (L < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: %d layers", L);
    if (par->stride < 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: a snapshot every %d frames; expected ≥ 1", par->stride);
    if (par->nlag < 1 || par->nlag > WT_WIND_ALIGN_MAX_LAGS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: %d lags; expected 1 to %d", par->nlag,
                        WT_WIND_ALIGN_MAX_LAGS);
    for (int q = 0; q < par->nlag; q++)
        if (par->lag[q] < 1 || (q > 0 && par->lag[q] <= par->lag[q - 1]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: lag %d is %d snapshots; the lags must be ≥ 1 and "
                            "increasing", q + 1, par->lag[q]);
    if (par->nbatch < 2 || par->nbatch > WT_WIND_ALIGN_MAX_BATCH)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: %d batches; the uncertainty needs 2 to %d", par->nbatch,
                        WT_WIND_ALIGN_MAX_BATCH);
    if (!(par->frame_dt > 0.0) || !isfinite(par->frame_dt))
        return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: a frame of %g s", par->frame_dt);
    int nmax = 0;
    for (int l = 0; l < L; l++) {
        const int n = g[l]->nx;
        if (g[l]->ny != n || n < 4 || n % 2 || !(g[l]->dx > 0.0))
            return WT_ERROR(ctx, WT_ERR_INVALID, "wind alignment: layer %d grid %d x %d of spacing %g m; need square, "
                            "even, at least 4", l + 1, g[l]->nx, g[l]->ny, g[l]->dx);
        if (n > nmax) nmax = n;
    }
    WT_ALLOC(ctx, w, 1, "wind alignment");
    w->ctx = ctx;
    w->L = L;
    w->par = *par;
    w->R = par->lag[par->nlag - 1];
    w->nthreads = wt_context_threads(ctx) > 1 ? wt_context_threads(ctx) : 1;
    int64_t points = 0;
    for (int l = 0; l < L; l++) points += (int64_t)g[l]->nx * g[l]->ny;
    w->parallel = w->nthreads > 1 && L > 1 && points >= WT_WIND_ALIGN_PARALLEL_POINTS;
    WT_ALLOC(ctx, w->lay, L, "wind alignment layers");
    w->nwork = ((size_t)nmax * nmax + 7) & ~(size_t)7; /* (slots of 64 bytes: FFTW's alignment on every thread) */
    w->ncmax = (size_t)nmax * (nmax / 2 + 1);
    w->work = fftw_alloc_real(w->nwork * (w->nthreads > 2 ? w->nthreads : 2)); /* (≥ 2: the estimate's pair) */
    w->spec = fftw_alloc_complex(w->ncmax);
    if (!w->work || !w->spec) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "wind alignment: out of memory for the %d x %d work arrays", nmax, nmax);
        goto fail;
    }
    WT_ALLOC(ctx, w->sq, 2 * w->ncmax * par->nlag, "wind alignment sums");
    WT_ALLOC(ctx, w->pq, w->ncmax, "wind alignment sums");
    WT_ALLOC(ctx, w->hw, w->ncmax, "wind alignment weights");
    WT_ALLOC(ctx, w->aw, w->ncmax, "wind alignment weights");
    WT_ALLOC(ctx, w->tab, 4 * (size_t)nmax, "wind alignment phase tables");
    for (int l = 0; l < L; l++) {
        layer *y = &w->lay[l];
        y->n = g[l]->nx, y->nh = y->n / 2 + 1;
        y->nc = (size_t)y->n * y->nh;
        y->slot = (y->nc + 3) & ~(size_t)3;
        y->offset = offset[l];
        y->dx = g[l]->dx;
        y->ring = fftw_alloc_complex(y->slot * (w->R + 1));
        if (!y->ring) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "wind alignment: out of memory for layer %d's ring of %d spectra", l + 1,
                          w->R + 1);
            goto fail;
        }
        WT_ALLOC(ctx, y->S, 2 * y->nc * par->nbatch * par->nlag, "wind alignment cross-spectra");
        WT_ALLOC(ctx, y->P, y->nc * par->nbatch, "wind alignment auto-spectra");
        if (radius && radius[l] > 0.0) { /* the taper, centred on the grid's x = y = 0 */
            WT_ALLOC(ctx, y->T, (size_t)y->n * y->n, "wind alignment taper");
            const double R = radius[l];
            for (int iy = 0; iy < y->n; iy++)
                for (int ix = 0; ix < y->n; ix++) {
                    const double r = hypot(g[l]->x0 + ix * y->dx, g[l]->y0 + iy * y->dx) / R;
                    const double c = cos(M_PI * (r - WT_WIND_ALIGN_TAPER_FLAT) / (1.0 - WT_WIND_ALIGN_TAPER_FLAT) / 2);
                    y->T[(size_t)iy * y->n + ix] = r <= WT_WIND_ALIGN_TAPER_FLAT ? 1.0 : r >= 1.0 ? 0.0 : c * c;
                }
        }
        /* planned on arrays of the alignment they run on (fftw_alloc'd bases, slots of a multiple of 64 bytes) */
        WT_TRY(wt_fft_plan_pair(ctx, fft, y->n, w->work, y->ring, "wind alignment", &y->r2c, &y->c2r));
    }
    *out = w;
    return WT_OK;
fail:
    wt_wind_align_free(w);
    return st;
}

void wt_wind_align_reset(wt_wind_align *w)
{
    for (int l = 0; l < w->L; l++) {
        layer *y = &w->lay[l];
        memset(y->S, 0, 2 * y->nc * w->par.nbatch * w->par.nlag * sizeof *y->S);
        memset(y->P, 0, y->nc * w->par.nbatch * sizeof *y->P);
    }
    memset(w->nq, 0, sizeof w->nq);
    memset(w->np, 0, sizeof w->np);
    w->nsnap = 0;
}

long wt_wind_align_snapshots(const wt_wind_align *w) { return w->nsnap; }
double wt_wind_align_seconds(const wt_wind_align *w) { return w->tacc; }

int wt_wind_align_add(wt_wind_align *w, long t, const double *phi)
{
    const int stride = w->par.stride;
    if (t < 0 || t % stride) return WT_OK;
    if (w->nsnap > 0 && t != w->last_t + stride)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "wind alignment: frame %ld after snapshot frame %ld; snapshots every %d "
                        "frames, without gaps", t, w->last_t, stride);
    const double t0 = wt_time_now();
    const long j = w->nsnap;
    const int R1 = w->R + 1, nlag = w->par.nlag;
    long b = j / (w->par.batch_snapshots > 0 ? w->par.batch_snapshots : 1);
    if (b >= w->par.nbatch) b = w->par.nbatch - 1;
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads) if (w->parallel && !omp_in_parallel())
    for (int l = 0; l < w->L; l++) {
        layer *y = &w->lay[l];
        double *wk = w->work + w->nwork * wt_thread_id();
        fftw_complex *x = y->ring + y->slot * (size_t)(j % R1);
        const size_t n2 = (size_t)y->n * y->n;
        memcpy(wk, phi + y->offset, n2 * sizeof *wk);
        if (y->T)
            for (size_t i = 0; i < n2; i++) wk[i] *= y->T[i];
        fftw_execute_dft_r2c(y->r2c, wk, x);
        double *P = y->P + y->nc * b;
        for (size_t k = 0; k < y->nc; k++) P[k] += x[k][0] * x[k][0] + x[k][1] * x[k][1];
        for (int q = 0; q < nlag; q++) {
            if (j < w->par.lag[q]) break;
            const fftw_complex *x0 = y->ring + y->slot * (size_t)((j - w->par.lag[q]) % R1);
            double *S = y->S + 2 * y->nc * ((size_t)b * nlag + q);
            for (size_t k = 0; k < y->nc; k++) { /* X_t conj(X_{t−τ}) */
                S[2 * k] += x[k][0] * x0[k][0] + x[k][1] * x0[k][1];
                S[2 * k + 1] += x[k][1] * x0[k][0] - x[k][0] * x0[k][1];
            }
        }
    }
    for (int q = 0; q < nlag; q++)
        if (j >= w->par.lag[q]) w->nq[b][q]++;
    w->np[b]++;
    w->nsnap++;
    w->last_t = t;
    w->tacc += wt_time_now() - t0;
    return WT_OK;
}

/* ---- the estimate ---- */

/* How often half-spectrum column ix stands for a frequency of the full plane (0 and n/2 once, the others twice) */
static inline double multiplicity(int ix, int n) { return ix == 0 || ix == n / 2 ? 1.0 : 2.0; }

/* The lag's numerator c(s) = Σ hw Re[S e^{2πi k·s/n}] (hw: the multiplicity, 0 where left out) or, S NULL, the
 * footprint's overlap A(s) = Σ aw cos(2π k·s/n): the value, gradient and Hessian (hxx, hxy, hyy) at s [points]. The
 * phase factor is separable: two 1-D tables. */
static double fsum(const layer *y, double *tab, const double *S, const double *wt, double sx, double sy, double *g,
                   double *h)
{
    const int n = y->n, nh = y->nh;
    double *cx = tab, *sxn = tab + n, *cy = tab + 2 * n, *syn = tab + 3 * n;
    const double a = 2.0 * M_PI / n;
    for (int i = 0; i < n; i++) {
        const int k = i <= n / 2 ? i : i - n;
        cx[i] = cos(a * k * sx), sxn[i] = sin(a * k * sx);
        cy[i] = cos(a * k * sy), syn[i] = sin(a * k * sy);
    }
    double F = 0.0, gx = 0.0, gy = 0.0, hxx = 0.0, hxy = 0.0, hyy = 0.0;
    for (int iy = 0; iy < n; iy++) {
        const double ky = a * (iy <= n / 2 ? iy : iy - n);
        for (int ix = 0; ix < nh; ix++) {
            const size_t k = (size_t)iy * nh + ix;
            if (wt[k] == 0.0) continue;
            const double er = cx[ix] * cy[iy] - sxn[ix] * syn[iy], ei = sxn[ix] * cy[iy] + cx[ix] * syn[iy];
            const double sr = S ? S[2 * k] : 1.0, si = S ? S[2 * k + 1] : 0.0;
            const double re = wt[k] * (sr * er - si * ei), im = wt[k] * (sr * ei + si * er), kx = a * ix;
            F += re;
            gx -= im * kx, gy -= im * ky;
            hxx -= re * kx * kx, hxy -= re * kx * ky, hyy -= re * ky * ky;
        }
    }
    if (g) g[0] = gx, g[1] = gy;
    if (h) h[0] = hxx, h[1] = hxy, h[2] = hyy;
    return F;
}

/* log R_q(s) = log c_q(s) − log A(s), its gradient and Hessian; −∞ where c_q ≤ 0 */
static double logr(const wt_wind_align *w, const layer *y, int q, double sx, double sy, double *g, double *h)
{
    double gc[2], hc[3], ga[2], ha[3];
    const double c = fsum(y, w->tab, w->sq + 2 * y->nc * q, w->hw, sx, sy, gc, hc);
    const double A = fsum(y, w->tab, NULL, w->aw, sx, sy, ga, ha);
    if (!(c > 0.0) || !(A > 0.0)) return -INFINITY;
    g[0] = gc[0] / c - ga[0] / A, g[1] = gc[1] / c - ga[1] / A;
    h[0] = hc[0] / c - gc[0] * gc[0] / (c * c) - ha[0] / A + ga[0] * ga[0] / (A * A);
    h[1] = hc[1] / c - gc[0] * gc[1] / (c * c) - ha[1] / A + ga[0] * ga[1] / (A * A);
    h[2] = hc[2] / c - gc[1] * gc[1] / (c * c) - ha[2] / A + ga[1] * ga[1] / (A * A);
    return log(c) - log(A);
}

/* G(u) = Σ_{q<nused} log R_q(u lag_q) and its derivatives in u */
static double objective(const wt_wind_align *w, const layer *y, int nused, const double *u, double *g, double *h)
{
    double G = 0.0;
    g[0] = g[1] = h[0] = h[1] = h[2] = 0.0;
    for (int q = 0; q < nused; q++) {
        const double L = w->par.lag[q];
        double gq[2], hq[3];
        G += logr(w, y, q, u[0] * L, u[1] * L, gq, hq);
        if (!isfinite(G)) return -INFINITY;
        g[0] += L * gq[0], g[1] += L * gq[1];
        h[0] += L * L * hq[0], h[1] += L * L * hq[1], h[2] += L * L * hq[2];
    }
    return G;
}

/* G maximised by Newton's method from u (points per snapshot): each step at most a quarter of a point at the
 * longest lag, halved until G does not fall; up the gradient where G is not concave */
static void newton(const wt_wind_align *w, const layer *y, int nused, double *u)
{
    const double cap = 0.25 / w->par.lag[nused - 1];
    double g[2], h[3], gn[2], hn[3];
    double G = objective(w, y, nused, u, g, h);
    if (!isfinite(G)) return;
    for (int it = 0; it < 50; it++) {
        double dx, dy;
        const double det = h[0] * h[2] - h[1] * h[1];
        if (h[0] < 0.0 && det > 0.0) {
            dx = -(h[2] * g[0] - h[1] * g[1]) / det;
            dy = -(h[0] * g[1] - h[1] * g[0]) / det;
        } else {
            const double gl = hypot(g[0], g[1]);
            if (gl == 0.0) break;
            dx = cap * g[0] / gl, dy = cap * g[1] / gl;
        }
        const double len = hypot(dx, dy);
        if (len > cap) dx *= cap / len, dy *= cap / len;
        double Gn = -INFINITY, v[2];
        for (int half = 0; half < 30; half++, dx *= 0.5, dy *= 0.5) {
            v[0] = u[0] + dx, v[1] = u[1] + dy;
            Gn = objective(w, y, nused, v, gn, hn);
            if (Gn >= G) break;
        }
        if (!(Gn >= G)) break;
        u[0] = v[0], u[1] = v[1];
        G = Gn;
        memcpy(g, gn, sizeof g);
        memcpy(h, hn, sizeof h);
        if (hypot(dx, dy) * w->par.lag[nused - 1] < 1e-9) break;
    }
}

/* The correlation coefficient of lag q at u: R_q(s) over the zero lag's R_0(0) = (Σ hw P / np) / A(0) */
static double rho(const wt_wind_align *w, const layer *y, int q, const double *u, double nq, double np)
{
    const double L = w->par.lag[q];
    const double c = fsum(y, w->tab, w->sq + 2 * y->nc * q, w->hw, u[0] * L, u[1] * L, NULL, NULL);
    const double A = fsum(y, w->tab, NULL, w->aw, u[0] * L, u[1] * L, NULL, NULL);
    const double A0 = fsum(y, w->tab, NULL, w->aw, 0.0, 0.0, NULL, NULL);
    double c0 = 0.0;
    for (size_t k = 0; k < y->nc; k++) c0 += w->hw[k] * w->pq[k];
    return c0 > 0.0 && A > 0.0 && nq > 0.0 ? (c / nq / A) / (c0 / np / A0) : 0.0;
}

/* The integer point (within a quarter of the grid, where the overlap is at least half its peak) where lag 0's
 * normalised correlation c/A peaks: two c2r */
static void integer_peak(wt_wind_align *w, const layer *y, double *s)
{
    const int n = y->n, nh = y->nh;
    double *num = w->work, *den = w->work + w->nwork;
    for (size_t k = 0; k < y->nc; k++) {
        const double m = multiplicity((int)(k % nh), n);
        w->spec[k][0] = w->hw[k] / m * w->sq[2 * k], w->spec[k][1] = w->hw[k] / m * w->sq[2 * k + 1];
    }
    fftw_execute_dft_c2r(y->c2r, w->spec, num);
    for (size_t k = 0; k < y->nc; k++) w->spec[k][0] = w->aw[k] / multiplicity((int)(k % nh), n), w->spec[k][1] = 0.0;
    fftw_execute_dft_c2r(y->c2r, w->spec, den);
    double best = -INFINITY;
    s[0] = s[1] = 0.0;
    for (int iy = 0; iy < n; iy++) {
        const int dy = iy <= n / 2 ? iy : iy - n;
        for (int ix = 0; ix < n; ix++) {
            const int dx = ix <= n / 2 ? ix : ix - n;
            const double a = den[(size_t)iy * n + ix];
            if (4 * abs(dy) >= n || 4 * abs(dx) >= n || !(a >= 0.5 * den[0])) continue;
            const double c = num[(size_t)iy * n + ix] / a;
            if (c > best) best = c, s[0] = dx, s[1] = dy;
        }
    }
}

/* The sums of layer y over batches b0 … b1 into w->sq (lag by lag), w->pq; their counts */
static void gather(wt_wind_align *w, const layer *y, int b0, int b1, double *nq, double *np)
{
    const int nlag = w->par.nlag;
    memset(w->sq, 0, 2 * y->nc * nlag * sizeof *w->sq);
    memset(w->pq, 0, y->nc * sizeof *w->pq);
    *np = 0.0;
    for (int q = 0; q < nlag; q++) nq[q] = 0.0;
    for (int b = b0; b <= b1; b++) {
        const double *P = y->P + y->nc * b;
        for (size_t k = 0; k < y->nc; k++) w->pq[k] += P[k];
        *np += (double)w->np[b];
        for (int q = 0; q < nlag; q++) {
            const double *S = y->S + 2 * y->nc * ((size_t)b * nlag + q);
            double *d = w->sq + 2 * y->nc * q;
            for (size_t k = 0; k < 2 * y->nc; k++) d[k] += S[k];
            nq[q] += (double)w->nq[b][q];
        }
    }
}

/* The weights of layer y: hw = 1 (0 at k = 0 and on the Nyquist row and column) and aw = |T̂|², T̂ the transform of the
 * taper (1 at k = 0 alone without one), each times the multiplicity */
static void footprint_weights(wt_wind_align *w, const layer *y)
{
    const int n = y->n, nh = y->nh;
    const size_t n2 = (size_t)n * n;
    if (y->T) {
        memcpy(w->work, y->T, n2 * sizeof *w->work);
        fftw_execute_dft_r2c(y->r2c, w->work, w->spec);
    }
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < nh; ix++) {
            const size_t k = (size_t)iy * nh + ix;
            const double m = multiplicity(ix, n);
            w->aw[k] = y->T ? m * (w->spec[k][0] * w->spec[k][0] + w->spec[k][1] * w->spec[k][1]) : k == 0;
            w->hw[k] = ix == n / 2 || iy == n / 2 || k == 0 ? 0.0 : m;
        }
}

int wt_wind_align_estimate(wt_wind_align *w, wt_wind_estimate *est)
{
    const int nlag = w->par.nlag, B = w->par.nbatch;
    if (w->nsnap < w->par.lag[0] + 1)
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "wind alignment: %ld snapshots (every %d frames) since the start; the "
                        "shortest lag needs at least %d", w->nsnap, w->par.stride, w->par.lag[0] + 1);
    const double scale_t = 1.0 / (w->par.stride * w->par.frame_dt); /* points per snapshot → points per second */
    for (int l = 0; l < w->L; l++) {
        const layer *y = &w->lay[l];
        wt_wind_estimate *e = &est[l];
        memset(e, 0, sizeof *e);
        footprint_weights(w, y);
        double nq[WT_WIND_ALIGN_MAX_LAGS], np;
        gather(w, y, 0, B - 1, nq, &np);
        int avail = 0;
        while (avail < nlag && nq[avail] > 0.0) avail++;
        double u[2];
        integer_peak(w, y, u);
        u[0] /= w->par.lag[0], u[1] /= w->par.lag[0];
        newton(w, y, 1, u);
        e->rho = rho(w, y, 0, u, nq[0], np);
        if (!(e->rho >= WT_WIND_ALIGN_RHO_MIN)) continue;
        int used = 1;
        for (int q = 1; q < avail; q++) { /* the longer lags while their peaks stay clear */
            double v[2] = {u[0], u[1]};
            newton(w, y, q + 1, v);
            if (!(rho(w, y, q, v, nq[q], np) >= WT_WIND_ALIGN_RHO_MIN)) break;
            u[0] = v[0], u[1] = v[1];
            used = q + 1;
        }
        e->valid = 1;
        e->nlag_used = used;
        e->vx = u[0] * y->dx * scale_t;
        e->vy = u[1] * y->dx * scale_t;
        /* the batches: each from its own sums, with the whole estimate's footprint and lags, from its estimate */
        double ub[WT_WIND_ALIGN_MAX_BATCH][2];
        int nb = 0;
        for (int b = 0; b < B; b++) {
            double nqb[WT_WIND_ALIGN_MAX_LAGS], npb;
            gather(w, y, b, b, nqb, &npb);
            int ok = npb > 0.0;
            for (int q = 0; q < used; q++) ok = ok && nqb[q] > 0.0;
            if (!ok) continue;
            ub[nb][0] = u[0], ub[nb][1] = u[1];
            newton(w, y, used, ub[nb]);
            nb++;
        }
        if (nb >= 2) {
            double mx = 0.0, my = 0.0, vxx = 0.0, vyy = 0.0;
            for (int b = 0; b < nb; b++) mx += ub[b][0] / nb, my += ub[b][1] / nb;
            for (int b = 0; b < nb; b++)
                vxx += (ub[b][0] - mx) * (ub[b][0] - mx), vyy += (ub[b][1] - my) * (ub[b][1] - my);
            e->sigma_x = sqrt(vxx / (nb - 1) / nb) * y->dx * scale_t;
            e->sigma_y = sqrt(vyy / (nb - 1) / nb) * y->dx * scale_t;
        }
    }
    return WT_OK;
}
