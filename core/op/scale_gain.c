/* core/op/scale_gain.c: the scale-dependent integrator gain G = Σ_j g_j Π_j of the POLC loop (see
 * scale_gain.h).
 *
 * Bilinear basis: G = g_L I + Σ_{j<L} (g_j − g_{j+1}) P_j, P_j x = Σ_squares Q_s Q_sᵀ x_s, with Q_s an
 * orthonormal basis (≤ 4 columns) of {1, u, v, uv} on the active actuators of dyadic square s of side
 * 2^(L+1−j). Daubechies basis: G = M Wᵀ Λ W Mᵀ (embed, DWT, scale, inverse DWT, read back). */
#include "scale_gain.h"

#include <math.h>
#include <string.h>

#include "wavelet.h"

/* A column whose norm falls below this fraction of its own after Gram–Schmidt is in the span of the
 * previous ones: actuators sit on integer grid points (coordinates in units of the square, spacing 1/b),
 * so an exact dependence (one, two or collinear active actuators in a square) leaves rounding (~1e-16 √m),
 * while an independent column keeps a part of order 1/b² or more (b <= 2^16: > 2e-10): the threshold
 * separates the two. */
#define RANK_TOL 1e-11

/* One level j < L of the bilinear basis, over all DMs' squares. */
typedef struct level {
    int64_t nsq;      /* squares with at least one active actuator */
    int64_t *start;   /* nsq + 1: square s holds actuators idx[start[s] … start[s+1]) */
    int64_t *idx;     /* nact: command index of each actuator, square by square */
    double *q;        /* 4 nact: row i of Q_s (4 values, zero beyond its rank) at q + 4 i, i in start[s] …:
                       * one gather of x per actuator feeds all four dot products */
    int64_t dim;      /* Σ rank = dim V_j */
} level;

struct wt_scale_gain {
    wt_context *ctx;
    const wt_dm *dm;
    int basis;
    int levels;                           /* L */
    double gain[WT_SCALE_GAIN_MAX_BANDS];
    int n[WT_DM_MAX];                     /* per DM: the power-of-two side */
    level lev[WT_SCALE_GAIN_MAX_BANDS];   /* bilinear: V_0 … V_{L−1} */
    /* Daubechies */
    int scalar;                           /* all gains equal and not forced: G = g_0 I */
    wt_wavelet *w[WT_DM_MAX];             /* per DM: the DWT of its n x n grid */
    int64_t *pos[WT_DM_MAX];              /* per DM: the grid point of each active actuator */
    double *lam[WT_DM_MAX];               /* per DM: Λ, the gain of each coefficient (n²) */
    size_t nwork;                         /* max n² + the largest DWT workspace */
};

/* Orthonormal basis of {1, u, v, uv} on the m points (u[i], v[i]) by modified Gram–Schmidt, twice (the
 * second pass restores orthogonality to rounding); dependent columns are dropped. q holds 4 m doubles;
 * returns the rank. */
static int square_basis(int m, const double *u, const double *v, double *q)
{
    memset(q, 0, 4 * (size_t)m * sizeof *q);
    int r = 0;
    for (int c = 0; c < 4; c++) {
        double *f = q + (size_t)m * r, n0 = 0.0;
        for (int i = 0; i < m; i++) {
            f[i] = c == 0 ? 1.0 : c == 1 ? u[i] : c == 2 ? v[i] : u[i] * v[i];
            n0 += f[i] * f[i];
        }
        if (n0 == 0.0) continue;
        for (int pass = 0; pass < 2; pass++)
            for (int p = 0; p < r; p++) {
                const double *e = q + (size_t)m * p;
                double d = 0.0;
                for (int i = 0; i < m; i++) d += e[i] * f[i];
                for (int i = 0; i < m; i++) f[i] -= d * e[i];
            }
        double nf = 0.0;
        for (int i = 0; i < m; i++) nf += f[i] * f[i];
        if (!(nf > RANK_TOL * RANK_TOL * n0)) continue;
        nf = 1.0 / sqrt(nf);
        for (int i = 0; i < m; i++) f[i] *= nf;
        r++;
    }
    return r;
}

static void level_free(wt_context *ctx, level *lv)
{
    wt_free(ctx, lv->start);
    wt_free(ctx, lv->idx);
    wt_free(ctx, lv->q);
}

/* Level j of the bilinear basis: squares of side b = 2^(L+1−j) of every DM's embedded grid. cmd[k][p] is
 * the command index of DM k's grid point p (−1 when inactive); uv holds 6 b² doubles (coordinates, Q_s). */
static int level_alloc(wt_scale_gain *g, int j, int64_t *const *cmd, double *uv, level *lv)
{
    wt_context *ctx = g->ctx;
    const wt_dm *dm = g->dm;
    const int b = 1 << (g->levels + 1 - j);
    const int64_t nact = dm->nact > 0 ? dm->nact : 1;
    int st = WT_OK;
    int64_t nsq = 0;
    for (int k = 0; k < dm->ndms; k++) nsq += (int64_t)(g->n[k] / b) * (g->n[k] / b);
    WT_ALLOC(ctx, lv->start, nsq + 1, "scale-dependent gain: squares");
    WT_ALLOC(ctx, lv->idx, nact, "scale-dependent gain: actuators");
    WT_ALLOC(ctx, lv->q, 4 * nact, "scale-dependent gain: square bases");
    int64_t s = 0, a = 0;
    double *u = uv, *v = uv + (size_t)b * b, *qc = uv + 2 * (size_t)b * b; /* qc: Q_s by columns */
    for (int k = 0; k < dm->ndms; k++) {
        const wt_grid *gr = &dm->grid[k];
        const int n = g->n[k], ox = (n - gr->nx) / 2, oy = (n - gr->ny) / 2;
        for (int sy = 0; sy < n / b; sy++)
            for (int sx = 0; sx < n / b; sx++) {
                int m = 0;
                for (int iy = sy * b - oy; iy < (sy + 1) * b - oy; iy++) {
                    if (iy < 0 || iy >= gr->ny) continue;
                    for (int ix = sx * b - ox; ix < (sx + 1) * b - ox; ix++) {
                        const int64_t c = ix < 0 || ix >= gr->nx ? -1 : cmd[k][ix + (int64_t)gr->nx * iy];
                        if (c < 0) continue;
                        /* local coordinates in units of the square, centred: as well conditioned for any b */
                        u[m] = (ix + ox - sx * b - 0.5 * (b - 1)) / b;
                        v[m] = (iy + oy - sy * b - 0.5 * (b - 1)) / b;
                        lv->idx[a + m] = c;
                        m++;
                    }
                }
                if (m == 0) continue;
                lv->start[s] = a;
                lv->dim += square_basis(m, u, v, qc);
                for (int i = 0; i < m; i++)
                    for (int t = 0; t < 4; t++) lv->q[4 * (a + i) + t] = qc[i + (size_t)m * t];
                a += m;
                s++;
            }
    }
    lv->start[s] = a;
    lv->nsq = s;
fail:
    return st;
}

int wt_scale_gain_alloc(wt_context *ctx, const wt_dm *dm, const wt_scale_gain_params *p, wt_scale_gain **out)
{
    int st = WT_OK;
    wt_scale_gain *g = NULL;
    int64_t *cmd[WT_DM_MAX] = {0};
    double *uv = NULL;
    *out = NULL;
    if (!dm || !p) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_scale_gain_alloc: NULL DMs or parameters");
    if (p->basis != WT_SCALE_GAIN_BILINEAR && p->basis != WT_SCALE_GAIN_DAUBECHIES)
        return WT_ERROR(ctx, WT_ERR_INVALID, "scale-dependent gain: basis %d; expected bilinear (%d) or daubechies (%d)",
                        p->basis, WT_SCALE_GAIN_BILINEAR, WT_SCALE_GAIN_DAUBECHIES);
    if (p->nbands < 2 || p->nbands > WT_SCALE_GAIN_MAX_BANDS)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "scale-dependent gain: %d bands; expected 2 ... %d (the coarsest band and 1 ... %d finer ones)",
                        p->nbands, WT_SCALE_GAIN_MAX_BANDS, WT_SCALE_GAIN_MAX_BANDS - 1);
    for (int j = 0; j < p->nbands; j++)
        if (!(p->gain[j] > 0.0 && p->gain[j] <= 1.0))
            return WT_ERROR(ctx, WT_ERR_INVALID, "scale-dependent gain: band %d (%s) has gain %g; expected (0, 1]", j,
                            j == 0 ? "the coarsest" : j == p->nbands - 1 ? "the finest" : "an intermediate", p->gain[j]);
    WT_ALLOC(ctx, g, 1, "scale-dependent gain");
    g->ctx = ctx;
    g->dm = dm;
    g->basis = p->basis;
    g->levels = p->nbands - 1;
    memcpy(g->gain, p->gain, (size_t)p->nbands * sizeof *p->gain);
    const int L = g->levels;
    int nmax = 0;
    for (int k = 0; k < dm->ndms; k++) {
        const wt_grid *gr = &dm->grid[k];
        int n = 1, lmax = 0;
        while (n < gr->nx || n < gr->ny) n *= 2, lmax++;
        if (L + 1 > lmax) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "scale-dependent gain: %d bands (L = %d) need grids of at least 2^(L+1) = %d points per "
                          "side, but DM %d's %dx%d actuator grid embeds in %dx%d (at most %d bands)",
                          L + 1, L, 2 << L, k + 1, gr->nx, gr->ny, n, n, lmax);
            goto fail;
        }
        g->n[k] = n;
        if (n > nmax) nmax = n;
    }

    if (g->basis == WT_SCALE_GAIN_BILINEAR) {
        for (int k = 0; k < dm->ndms; k++) {
            WT_ALLOC(ctx, cmd[k], wt_grid_size(&dm->grid[k]), "scale-dependent gain: command indices");
            int64_t c = dm->offset[k];
            for (int64_t q = 0; q < wt_grid_size(&dm->grid[k]); q++) cmd[k][q] = dm->active[k][q] ? c++ : -1;
        }
        WT_ALLOC(ctx, uv, 6 * (size_t)nmax * nmax, "scale-dependent gain: square coordinates and bases");
        for (int j = 0; j < L; j++) WT_TRY(level_alloc(g, j, cmd, uv, &g->lev[j]));
        goto done;
    }

    /* Daubechies */
    g->scalar = !p->force_transform;
    for (int j = 1; j <= L; j++)
        if (p->gain[j] != p->gain[0]) g->scalar = 0;
    for (int k = 0; k < dm->ndms && !g->scalar; k++) {
        const wt_grid *gr = &dm->grid[k];
        const int n = g->n[k];
        WT_TRY(wt_wavelet_alloc(ctx, n, p->wavelet_order, L, &g->w[k]));
        const size_t nn = (size_t)n * n, need = nn + wt_wavelet_work_size(g->w[k]);
        if (need > g->nwork) g->nwork = need;
        /* centred, as the bilinear squares: the dyadic blocks fall symmetrically about the pupil centre */
        const int ox = (n - gr->nx) / 2, oy = (n - gr->ny) / 2;
        WT_ALLOC(ctx, g->pos[k], dm->nactive[k], "scale-dependent gain: active actuators' grid points");
        int64_t i = 0;
        for (int iy = 0; iy < gr->ny; iy++)
            for (int ix = 0; ix < gr->nx; ix++)
                if (dm->active[k][ix + (int64_t)gr->nx * iy]) g->pos[k][i++] = (ix + ox) + (int64_t)n * (iy + oy);
        /* Λ: wt_wavelet_classify's level 1 … L (finest first) and L + 1 (approximation) → band L + 1 − level */
        WT_ALLOC(ctx, g->lam[k], nn, "scale-dependent gain: gain per wavelet coefficient");
        for (int iy = 0; iy < n; iy++)
            for (int ix = 0; ix < n; ix++) {
                int lvl, orient;
                wt_wavelet_classify(g->w[k], ix, iy, &lvl, &orient);
                g->lam[k][ix + (size_t)n * iy] = p->gain[L + 1 - lvl];
            }
    }
done:
    for (int k = 0; k < WT_DM_MAX; k++) wt_free(ctx, cmd[k]);
    wt_free(ctx, uv);
    *out = g;
    return WT_OK;
fail:
    for (int k = 0; k < WT_DM_MAX; k++) wt_free(ctx, cmd[k]);
    wt_free(ctx, uv);
    wt_scale_gain_free(g);
    return st;
}

void wt_scale_gain_free(wt_scale_gain *g)
{
    if (!g) return;
    for (int j = 0; j < WT_SCALE_GAIN_MAX_BANDS; j++) level_free(g->ctx, &g->lev[j]);
    for (int k = 0; k < WT_DM_MAX; k++) {
        wt_wavelet_free(g->w[k]);
        wt_free(g->ctx, g->pos[k]);
        wt_free(g->ctx, g->lam[k]);
    }
    wt_free(g->ctx, g);
}

size_t wt_scale_gain_work_size(const wt_scale_gain *g) { return g->nwork; }
int wt_scale_gain_levels(const wt_scale_gain *g) { return g->levels; }
int wt_scale_gain_grid(const wt_scale_gain *g, int k) { return k < 0 || k >= g->dm->ndms ? 0 : g->n[k]; }
int64_t wt_scale_gain_dim(const wt_scale_gain *g, int j)
{
    if (j >= g->levels) return g->dm->nact;
    if (j < 0) return 0;
    if (g->basis == WT_SCALE_GAIN_BILINEAR) return g->lev[j].dim;
    /* Daubechies: the scaling coefficients of level L − j of every DM's padded grid */
    int64_t d = 0;
    for (int k = 0; k < g->dm->ndms; k++) d += (int64_t)(g->n[k] >> (g->levels - j)) * (g->n[k] >> (g->levels - j));
    return d;
}

/* y ← y + c P x for the bilinear V_j of lv: per square w = c Q_sᵀ x_s, then y_s += Q_s w */
static void project_add(const level *lv, double c, const double *x, double *y)
{
    for (int64_t s = 0; s < lv->nsq; s++) {
        const int64_t i0 = lv->start[s], i1 = lv->start[s + 1];
        const int64_t *idx = lv->idx;
        const double *q = lv->q;
        double w0 = 0.0, w1 = 0.0, w2 = 0.0, w3 = 0.0;
        for (int64_t i = i0; i < i1; i++) {
            const double xi = x[idx[i]], *qi = q + 4 * i;
            w0 += qi[0] * xi, w1 += qi[1] * xi, w2 += qi[2] * xi, w3 += qi[3] * xi;
        }
        w0 *= c, w1 *= c, w2 *= c, w3 *= c;
        for (int64_t i = i0; i < i1; i++) {
            const double *qi = q + 4 * i;
            y[idx[i]] += qi[0] * w0 + qi[1] * w1 + qi[2] * w2 + qi[3] * w3;
        }
    }
}

void wt_scale_gain_apply(const wt_scale_gain *g, double alpha, const double *x, double *y, double *work)
{
    const wt_dm *dm = g->dm;
    const int L = g->levels;
    if (g->basis == WT_SCALE_GAIN_BILINEAR || g->scalar) {
        /* G = g_L I + Σ_{j<L} (g_j − g_{j+1}) P_j (Daubechies scalar: all equal). The identity term is
         * (α g_L) x_i: α = 1 gives the single-gain loop's g (a_rec − a_t) bit for bit, and equal gains
         * leave every projection term out. */
        const double s = alpha * g->gain[L];
        for (int64_t i = 0; i < dm->nact; i++) y[i] += s * x[i];
        if (g->scalar) return;
        for (int j = 0; j < L; j++) {
            const double c = alpha * (g->gain[j] - g->gain[j + 1]);
            if (c != 0.0) project_add(&g->lev[j], c, x, y);
        }
        return;
    }
    for (int k = 0; k < dm->ndms; k++) {
        const int n = g->n[k];
        const size_t nn = (size_t)n * n;
        double *u = work, *ws = work + nn;
        const int64_t *pos = g->pos[k];
        const double *xk = x + dm->offset[k];
        double *yk = y + dm->offset[k];
        const double *lam = g->lam[k];
        memset(u, 0, nn * sizeof *u);
        for (int64_t i = 0; i < dm->nactive[k]; i++) u[pos[i]] = xk[i];      /* Mᵀ x */
        wt_wavelet_forward(g->w[k], u, u, ws);                                  /* W */
        for (size_t c = 0; c < nn; c++) u[c] *= lam[c];                         /* Λ */
        wt_wavelet_inverse(g->w[k], u, u, ws);                                  /* Wᵀ */
        for (int64_t i = 0; i < dm->nactive[k]; i++) yk[i] += alpha * u[pos[i]]; /* y + α M (…) */
    }
}
