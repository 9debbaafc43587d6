/* core/model/mvm_normal.c: the sparse Ã = Γ P W⁻¹ and the factorised MAP normal matrix of the MVM
 * builder (SPEC §9, §7; paper eq. eqn_lse): N = Σ_LGS Ã_mᵀ C̃_m⁻¹ Ã_m + α D assembled column by column
 * and factorised by CHOLMOD, the LGS tip-tilt removal and the NGS as the low-rank B Q Bᵀ, and solves
 * with M = N + B Q Bᵀ by Sherman–Morrison–Woodbury (the derivation is in mvm.h). */
#include "mvm_private.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../la/chol.h"
#include "../op/noise.h"
#include "../op/projection.h"

/* ---- wavelet basis templates ------------------------------------------------------------------
 * All basis functions W⁻¹ e_λ of one layer, level and orientation are periodic shifts, by 2^level grid
 * points per coefficient step, of the block's first one (tests/test_wavelet.c, test_shift_property),
 * so one inverse DWT per block gives every column of W⁻¹. */

typedef struct {
    int npts, step;
    int32_t *tx, *ty; /* support of the block's (0, 0) basis function, grid indices */
    double *v;
} block_tmpl;

typedef struct {
    int L;
    int n[WT_MAX_LAYERS], J[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS + 1];
    block_tmpl *blk[WT_MAX_LAYERS]; /* 3J + 1 per layer: (level-1)*3 + orient-1, approximation last */
} templates;

static void templates_free(wt_context *ctx, templates *tp)
{
    if (!tp) return;
    for (int l = 0; l < tp->L; l++) {
        if (!tp->blk[l]) continue;
        for (int b = 0; b < 3 * tp->J[l] + 1; b++) {
            wt_free(ctx, tp->blk[l][b].tx);
            wt_free(ctx, tp->blk[l][b].ty);
            wt_free(ctx, tp->blk[l][b].v);
        }
        wt_free(ctx, tp->blk[l]);
    }
    wt_free(ctx, tp);
}

static void block_origin(int n, int level, int orient, int J, int *bx, int *by, int *step)
{
    int lev = level > J ? J : level, m = n >> lev;
    *bx = (orient == 1 || orient == 3) ? m : 0;
    *by = (orient == 2 || orient == 3) ? m : 0;
    *step = 1 << lev;
}

static int templates_alloc(wt_context *ctx, const wt_tomography *t, templates **out)
{
    int st = WT_OK;
    templates *tp = NULL;
    double *e = NULL, *psi = NULL, *work = NULL;
    *out = NULL;
    WT_ALLOC(ctx, tp, 1, "wavelet templates");
    tp->L = wt_tomography_nlayers(t);
    for (int l = 0; l < tp->L; l++) {
        const wt_wavelet *w = wt_tomography_wavelet(t, l);
        int n = wt_wavelet_n(w), J = wt_wavelet_levels(w);
        tp->n[l] = n;
        tp->J[l] = J;
        tp->off[l] = wt_tomography_layer_offset(t, l);
        tp->off[l + 1] = tp->off[l] + (int64_t)n * n;
        WT_ALLOC(ctx, tp->blk[l], 3 * J + 1, "wavelet templates");
        WT_ALLOC(ctx, e, (size_t)n * n, "template coefficients");
        WT_ALLOC(ctx, psi, (size_t)n * n, "template basis function");
        WT_ALLOC(ctx, work, wt_wavelet_work_size(w), "template workspace");
        for (int b = 0; b < 3 * J + 1; b++) {
            int level = b < 3 * J ? b / 3 + 1 : J + 1, orient = b < 3 * J ? b % 3 + 1 : 0, bx, by;
            block_tmpl *bt = &tp->blk[l][b];
            block_origin(n, level, orient, J, &bx, &by, &bt->step);
            memset(e, 0, (size_t)n * n * sizeof *e);
            e[bx + (int64_t)n * by] = 1.0;
            wt_wavelet_inverse(w, e, psi, work);
            int cnt = 0;
            for (int64_t p = 0; p < (int64_t)n * n; p++) cnt += psi[p] != 0.0;
            bt->npts = cnt;
            WT_ALLOC(ctx, bt->tx, cnt, "template support");
            WT_ALLOC(ctx, bt->ty, cnt, "template support");
            WT_ALLOC(ctx, bt->v, cnt, "template values");
            cnt = 0;
            for (int64_t p = 0; p < (int64_t)n * n; p++)
                if (psi[p] != 0.0) {
                    bt->tx[cnt] = (int32_t)(p % n);
                    bt->ty[cnt] = (int32_t)(p / n);
                    bt->v[cnt++] = psi[p];
                }
        }
        wt_free(ctx, e);
        wt_free(ctx, psi);
        wt_free(ctx, work);
        e = psi = work = NULL;
    }
    *out = tp;
    return WT_OK;
fail:
    wt_free(ctx, e);
    wt_free(ctx, psi);
    wt_free(ctx, work);
    templates_free(ctx, tp);
    return st;
}

/* The template of coefficient j (global index) and the shift (sx, sy) that moves it there. */
static const block_tmpl *locate(const templates *tp, int64_t j, int *layer, int *sx, int *sy)
{
    int l = 0;
    while (j >= tp->off[l + 1]) l++;
    int64_t lam = j - tp->off[l];
    int n = tp->n[l], J = tp->J[l], ix = (int)(lam % n), iy = (int)(lam / n);
    int m = n / 2, level = J + 1, orient = 0;
    for (int lv = 1; lv <= J; lv++, m /= 2)
        if (ix >= m || iy >= m) {
            level = lv;
            orient = (ix >= m) + 2 * (iy >= m);
            break;
        }
    int bx, by, step;
    block_origin(n, level, orient, J, &bx, &by, &step);
    *layer = l;
    *sx = (ix - bx) * step;
    *sy = (iy - by) * step;
    return &tp->blk[l][level <= J ? (level - 1) * 3 + orient - 1 : 3 * J];
}

/* ---- parallel two-pass CSC construction -------------------------------------------------------- */

typedef struct {
    double *acc, *out;
    int64_t *mark, *list;
} col_work;

/* Computes column j: with rows == NULL only its non-zero count, else its sorted rows and values. */
typedef int64_t (*col_fn)(const void *c, int64_t j, col_work *w, int64_t *rows, double *vals);

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* Emit the cnt touched rows (tagged j in mark) in increasing order with their values src[row]. */
static int64_t emit(col_work *w, int64_t j, int64_t cnt, int64_t *rows, double *vals, const double *src)
{
    if (!rows) return cnt;
    int64_t lo = INT64_MAX, hi = -1;
    for (int64_t k = 0; k < cnt; k++) {
        if (w->list[k] < lo) lo = w->list[k];
        if (w->list[k] > hi) hi = w->list[k];
    }
    if (cnt > 0 && 8 * cnt >= hi - lo + 1) { /* dense enough: scan the marks instead of sorting */
        int64_t q = 0;
        for (int64_t r = lo; r <= hi; r++)
            if (w->mark[r] == j) rows[q++] = r;
    } else {
        memcpy(rows, w->list, (size_t)cnt * sizeof *rows);
        qsort(rows, (size_t)cnt, sizeof *rows, cmp_i64);
    }
    for (int64_t k = 0; k < cnt; k++) vals[k] = src[rows[k]];
    return cnt;
}

typedef struct {
    wt_context *ctx;
    int nth;
    int64_t nrow;
    col_work *w;
    void *store;
} col_pool;

/* Columns are tagged by their index in the marks: clear them before every pass. */
static void pool_reset(col_pool *p)
{
    for (int k = 0; k < p->nth; k++)
        for (int64_t r = 0; r < p->nrow; r++) p->w[k].mark[r] = -1;
}

static void pool_free(col_pool *p)
{
    if (p->store) wt_free(p->ctx, p->store);
    wt_free(p->ctx, p->w);
    memset(p, 0, sizeof *p);
}

static int pool_alloc(wt_context *ctx, int nth, int64_t nrow, col_pool *p)
{
    int st = WT_OK;
    memset(p, 0, sizeof *p);
    p->ctx = ctx;
    p->nth = nth;
    WT_ALLOC(ctx, p->w, nth, "column workspaces");
    p->store = wt_malloc(ctx, (size_t)nth * 4, (size_t)nrow * 8);
    if (!p->store && nrow > 0) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory allocating column workspaces (%zu bytes)",
                      (size_t)nth * 32 * (size_t)nrow);
        goto fail;
    }
    p->nrow = nrow;
    for (int k = 0; k < nth; k++) {
        char *b = (char *)p->store + (size_t)k * 32 * (size_t)nrow;
        p->w[k].acc = (double *)b;
        p->w[k].out = (double *)(b + 8 * (size_t)nrow);
        p->w[k].mark = (int64_t *)(b + 16 * (size_t)nrow);
        p->w[k].list = (int64_t *)(b + 24 * (size_t)nrow);
    }
    return WT_OK;
fail:
    pool_free(p);
    return st;
}

enum { COL_CHUNK = 2048 };

/* Pass 1: colptr[j + 1] = count of column j, then prefix sums. */
static void count_columns(col_pool *p, int64_t ncol, col_fn fn, const void *c, int64_t *colptr,
                          const wt_mvm_options *opt, const char *phase, int64_t done0, int64_t total)
{
    pool_reset(p);
    colptr[0] = 0;
    for (int64_t j0 = 0; j0 < ncol; j0 += COL_CHUNK) {
        int64_t j1 = j0 + COL_CHUNK < ncol ? j0 + COL_CHUNK : ncol;
#pragma omp parallel for schedule(dynamic, 16) num_threads(p->nth)
        for (int64_t j = j0; j < j1; j++) colptr[j + 1] = fn(c, j, &p->w[wt_mvm_priv_thread()], NULL, NULL);
        wt_mvm_priv_progress(opt, phase, done0 + j1, total);
    }
    for (int64_t j = 0; j < ncol; j++) colptr[j + 1] += colptr[j];
}

/* Pass 2: fill the columns of a (colptr already set). */
static void fill_columns(col_pool *p, wt_sparse *a, col_fn fn, const void *c, const wt_mvm_options *opt,
                         const char *phase, int64_t done0, int64_t total)
{
    pool_reset(p);
    for (int64_t j0 = 0; j0 < a->ncol; j0 += COL_CHUNK) {
        int64_t j1 = j0 + COL_CHUNK < a->ncol ? j0 + COL_CHUNK : a->ncol;
#pragma omp parallel for schedule(dynamic, 16) num_threads(p->nth)
        for (int64_t j = j0; j < j1; j++)
            fn(c, j, &p->w[wt_mvm_priv_thread()], a->rowind + a->colptr[j], a->val + a->colptr[j]);
        wt_mvm_priv_progress(opt, phase, done0 + j1, total);
    }
}

/* ---- Γ P (all sensors, all layers) and Ã = Γ P W⁻¹ ---------------------------------------------- */

/* GP: nslopes x n (layer points in the order of the coefficients), rows in system slope order. */
static int assemble_gp(wt_context *ctx, wt_tomography *t, wt_sparse **out)
{
    int st = WT_OK;
    const wt_system *sys = wt_tomography_system(t);
    const int S = sys->nsensors, L = wt_tomography_nlayers(t);
    wt_sparse **part = NULL, *G = NULL, *P = NULL, *gp = NULL;
    *out = NULL;
    WT_ALLOC(ctx, part, (size_t)S * L, "Γ P blocks");
    for (int m = 0; m < S; m++) {
        WT_TRY(wt_shack_hartmann_assemble(sys->sensors[m].sh, &G));
        for (int l = 0; l < L; l++) {
            WT_TRY(wt_projection_assemble(wt_tomography_projection(t, m, l), &P));
            WT_TRY(wt_sparse_multiply(G, P, &part[m * L + l]));
            wt_sparse_free(P);
            P = NULL;
        }
        wt_sparse_free(G);
        G = NULL;
    }
    int64_t n = wt_tomography_nunknowns(t), nnz = 0;
    for (int i = 0; i < S * L; i++) nnz += wt_sparse_nnz(part[i]);
    WT_TRY(wt_sparse_alloc(ctx, sys->nslopes, n, nnz, &gp));
    int64_t q = 0;
    for (int l = 0; l < L; l++) {
        int64_t off = wt_tomography_layer_offset(t, l), nl = wt_grid_size(wt_tomography_layer_grid(t, l));
        for (int64_t p = 0; p < nl; p++) {
            for (int m = 0; m < S; m++) {
                const wt_sparse *a = part[m * L + l];
                for (int64_t k = a->colptr[p]; k < a->colptr[p + 1]; k++) {
                    gp->rowind[q] = sys->sensors[m].offset + a->rowind[k];
                    gp->val[q++] = a->val[k];
                }
            }
            gp->colptr[off + p + 1] = q;
        }
    }
    *out = gp;
    gp = NULL;
fail:
    if (part)
        for (int i = 0; i < S * L; i++) wt_sparse_free(part[i]);
    wt_free(ctx, part);
    wt_sparse_free(G);
    wt_sparse_free(P);
    wt_sparse_free(gp);
    return st;
}

typedef struct {
    const wt_sparse *gp;
    const templates *tp;
    int64_t nrows;      /* rows produced: every slope, or the LGS slopes (weighted) */
    int weighted;       /* 1: rows of Lᵀ Ã with C̃⁻¹ = L Lᵀ per subaperture */
    const double *w11, *w21, *w22; /* Lᵀ = [[w11, w21], [0, w22]], indexed by the x-row */
    const int64_t *partner;        /* x-row <-> y-row of the same subaperture */
    const uint8_t *is_x;
} acol_ctx;

static int64_t atilde_column(const void *cv, int64_t j, col_work *w, int64_t *rows, double *vals)
{
    const acol_ctx *c = cv;
    const wt_sparse *gp = c->gp;
    int l, sx, sy;
    const block_tmpl *b = locate(c->tp, j, &l, &sx, &sy);
    const int n = c->tp->n[l], mask = n - 1;
    const int64_t off = c->tp->off[l], nrows = c->nrows;
    int64_t cnt = 0;
    for (int q = 0; q < b->npts; q++) {
        int64_t p = off + ((b->tx[q] + sx) & mask) + (int64_t)n * ((b->ty[q] + sy) & mask);
        double v = b->v[q];
        for (int64_t k = gp->colptr[p]; k < gp->colptr[p + 1]; k++) {
            int64_t r = gp->rowind[k];
            if (r >= nrows) break; /* rows are sorted: the rest belong to sensors left out */
            if (w->mark[r] != j) {
                w->mark[r] = j;
                w->list[cnt++] = r;
                w->acc[r] = 0.0;
            }
            if (vals) w->acc[r] += v * gp->val[k];
        }
    }
    if (!c->weighted) return emit(w, j, cnt, rows, vals, w->acc);
    /* Lᵀ mixes the x and y slope of a subaperture: both rows of a touched pair are produced */
    int64_t c0 = cnt;
    for (int64_t k = 0; k < c0; k++) {
        int64_t pr = c->partner[w->list[k]];
        if (w->mark[pr] != j) {
            w->mark[pr] = j;
            w->list[cnt++] = pr;
            w->acc[pr] = 0.0;
        }
    }
    if (vals)
        for (int64_t k = 0; k < cnt; k++) {
            int64_t r = w->list[k];
            if (!c->is_x[r]) continue;
            double x = w->acc[r], y = w->acc[c->partner[r]];
            w->out[r] = c->w11[r] * x + c->w21[r] * y;
            w->out[c->partner[r]] = c->w22[r] * y;
        }
    return emit(w, j, cnt, rows, vals, w->out);
}

int wt_mvm_assemble_atilde(wt_context *ctx, wt_tomography *t, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *gp = NULL, *a = NULL;
    templates *tp = NULL;
    col_pool pool = {0};
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = wt_tomography_nunknowns(t);
    *out = NULL;
    WT_TRY(assemble_gp(ctx, t, &gp));
    WT_TRY(templates_alloc(ctx, t, &tp));
    WT_TRY(pool_alloc(ctx, wt_context_threads(ctx), sys->nslopes, &pool));
    acol_ctx c = {gp, tp, sys->nslopes, 0, NULL, NULL, NULL, NULL, NULL};
    int64_t *colptr = NULL;
    WT_ALLOC(ctx, colptr, n + 1, "column counts");
    count_columns(&pool, n, atilde_column, &c, colptr, NULL, NULL, 0, 0);
    st = wt_sparse_alloc(ctx, sys->nslopes, n, colptr[n], &a);
    if (st == WT_OK) memcpy(a->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    wt_free(ctx, colptr);
    if (st < 0) goto fail;
    fill_columns(&pool, a, atilde_column, &c, NULL, NULL, 0, 0);
    *out = a;
    a = NULL;
fail:
    pool_free(&pool);
    templates_free(ctx, tp);
    wt_sparse_free(gp);
    wt_sparse_free(a);
    return st;
}

/* ---- N = Gᵀ G + α D (upper triangle) ------------------------------------------------------------
 * The two rows of G of one subaperture (x and y, mixed by Lᵀ) have the same pattern (atilde_column
 * emits both of a touched pair), so Gᵀ is stored by pairs: one row list, two value arrays. The
 * product then walks each index list once for both rows, halving the index traffic of both passes. */

typedef struct {
    int64_t npairs;
    int64_t *colptr, *rowind; /* pair p: rowind[colptr[p] … colptr[p+1]), rows (unknowns) sorted */
    double *vx, *vy;
} pair_transpose;

static void pair_transpose_free(wt_context *ctx, pair_transpose *f)
{
    wt_free(ctx, f->colptr);
    wt_free(ctx, f->rowind);
    wt_free(ctx, f->vx);
    wt_free(ctx, f->vy);
    memset(f, 0, sizeof *f);
}

static double pair_transpose_bytes(int64_t nnz, int64_t npairs) { return 24.0 * (double)nnz / 2.0 + 8.0 * (npairs + 1); }

/* pair_of: pair index of each x-row (−1 for y-rows); partner: the other row of the pair. */
static int pair_transpose_alloc(wt_context *ctx, const wt_sparse *G, const int64_t *pair_of, const int64_t *partner,
                                int64_t npairs, pair_transpose *f)
{
    int st = WT_OK;
    int64_t *last = NULL;
    memset(f, 0, sizeof *f);
    f->npairs = npairs;
    WT_ALLOC(ctx, f->colptr, npairs + 1, "paired transpose");
    for (int64_t k = 0; k < wt_sparse_nnz(G); k++)
        if (pair_of[G->rowind[k]] >= 0) f->colptr[pair_of[G->rowind[k]] + 1]++;
    for (int64_t p = 0; p < npairs; p++) f->colptr[p + 1] += f->colptr[p];
    int64_t nnz = f->colptr[npairs];
    WT_ALLOC(ctx, f->rowind, nnz, "paired transpose");
    WT_ALLOC(ctx, f->vx, nnz, "paired transpose");
    WT_ALLOC(ctx, f->vy, nnz, "paired transpose");
    WT_ALLOC(ctx, last, npairs + 1, "paired transpose cursor");
    memcpy(last, f->colptr, (size_t)npairs * sizeof *last);
    for (int64_t j = 0; j < G->ncol; j++) {
        /* x-rows come first in a column only within a sensor, so take the x entries, then the y */
        for (int64_t k = G->colptr[j]; k < G->colptr[j + 1]; k++) {
            int64_t p = pair_of[G->rowind[k]];
            if (p < 0) continue;
            f->rowind[last[p]] = j;
            f->vx[last[p]++] = G->val[k];
        }
        for (int64_t k = G->colptr[j]; k < G->colptr[j + 1]; k++) {
            int64_t r = G->rowind[k];
            if (pair_of[r] >= 0) continue;
            int64_t p = pair_of[partner[r]];
            f->vy[last[p] - 1] = G->val[k]; /* the pair's entry of column j was the last one written */
        }
    }
    wt_free(ctx, last);
    return WT_OK;
fail:
    wt_free(ctx, last);
    pair_transpose_free(ctx, f);
    return st;
}

typedef struct {
    const wt_sparse *G;       /* nslopes_lgs x n */
    const pair_transpose *F;  /* Gᵀ by pairs */
    const int64_t *pair_of, *partner;
    const double *alpha_d;
} ncol_ctx;

static int64_t normal_column(const void *cv, int64_t j, col_work *w, int64_t *rows, double *vals)
{
    const ncol_ctx *c = cv;
    const wt_sparse *G = c->G;
    const pair_transpose *F = c->F;
    double *gval = w->out; /* G(:, j) scattered by row (sized ≥ the LGS rows) */
    int64_t cnt = 0;
    w->mark[j] = j; /* the diagonal always exists: α D > 0 */
    w->list[cnt++] = j;
    w->acc[j] = c->alpha_d[j];
    if (vals)
        for (int64_t kg = G->colptr[j]; kg < G->colptr[j + 1]; kg++) gval[G->rowind[kg]] = G->val[kg];
    for (int64_t kg = G->colptr[j]; kg < G->colptr[j + 1]; kg++) {
        int64_t p = c->pair_of[G->rowind[kg]];
        if (p < 0) continue;
        double gx = vals ? G->val[kg] : 0.0, gy = vals ? gval[c->partner[G->rowind[kg]]] : 0.0;
        for (int64_t q = F->colptr[p]; q < F->colptr[p + 1]; q++) {
            int64_t i = F->rowind[q];
            if (i > j) break; /* upper triangle only; the lists are sorted */
            if (w->mark[i] != j) {
                w->mark[i] = j;
                w->list[cnt++] = i;
                w->acc[i] = 0.0;
            }
            if (vals) w->acc[i] += gx * F->vx[q] + gy * F->vy[q];
        }
    }
    return emit(w, j, cnt, rows, vals, w->acc);
}

/* ---- the normal object -------------------------------------------------------------------------- */

struct wt_mvm_normal {
    wt_context *ctx;
    wt_tomography *t;
    const wt_system *sys;
    int64_t n, ns;
    int nth;
    wt_sparse *gp;      /* Γ P: nslopes x n (kept: the builder maps layers to slopes with it) */
    wt_sparse *N;       /* upper triangle of N (NULL unless keep_matrix) */
    wt_chol *chol;
    int r;              /* rank of the correction */
    double *B, *Z;      /* n x r each: B and N⁻¹ B */
    double *Q;          /* r x r */
    double *K;          /* r x r: LU of I + Q Bᵀ Z */
    lapack_int *ipiv;
    int maxblock;
    double *s1, *s2;    /* r x maxblock scratch */
    wt_mvm_stats stats;
};

int64_t wt_mvm_normal_size(const wt_mvm_normal *nm) { return nm->n; }
int wt_mvm_normal_rank(const wt_mvm_normal *nm) { return nm->r; }
void wt_mvm_normal_stats(const wt_mvm_normal *nm, wt_mvm_stats *stats) { *stats = nm->stats; }
const wt_sparse *wt_mvm_priv_normal_gp(const wt_mvm_normal *nm) { return nm->gp; }

double wt_mvm_priv_normal_cholmod_peak(const wt_mvm_normal *nm)
{
    wt_chol_info ci;
    wt_chol_info_get(nm->chol, &ci);
    return ci.peak_bytes;
}

void wt_mvm_normal_free(wt_mvm_normal *nm)
{
    if (!nm) return;
    wt_context *ctx = nm->ctx;
    wt_sparse_free(nm->gp);
    wt_sparse_free(nm->N);
    wt_chol_free(nm->chol);
    wt_free(ctx, nm->B);
    wt_free(ctx, nm->Z);
    wt_free(ctx, nm->Q);
    wt_free(ctx, nm->K);
    wt_free(ctx, nm->ipiv);
    wt_free(ctx, nm->s1);
    wt_free(ctx, nm->s2);
    wt_free(ctx, nm);
}

/* phi = (Γ P)ᵀ z, then c = W phi layer by layer: one column of Ãᵀ z. */
static void adjoint_column(const wt_mvm_normal *nm, const double *z, double *c, double *work)
{
    const wt_sparse *gp = nm->gp;
    for (int64_t p = 0; p < gp->ncol; p++) {
        double s = 0.0;
        for (int64_t k = gp->colptr[p]; k < gp->colptr[p + 1]; k++) s += gp->val[k] * z[gp->rowind[k]];
        c[p] = s;
    }
    for (int l = 0; l < wt_tomography_nlayers(nm->t); l++) {
        int64_t off = wt_tomography_layer_offset(nm->t, l);
        wt_wavelet_forward(wt_tomography_wavelet(nm->t, l), c + off, c + off, work);
    }
}

/* B = [Ãᵀ U_m, Ãᵀ V_m per LGS, Ã_ngsᵀ], Q block-diagonal (see mvm.h). */
static int build_lowrank(wt_mvm_normal *nm)
{
    int st = WT_OK;
    wt_context *ctx = nm->ctx;
    const wt_system *sys = nm->sys;
    const int64_t ns = nm->ns, n = nm->n;
    double *zs = NULL, *work = NULL;
    int r = 4 * sys->nlgs;
    for (int m = sys->nlgs; m < sys->nsensors; m++) r += sys->sensors[m].nslopes;
    nm->r = r;
    WT_ALLOC(ctx, nm->B, (size_t)n * r, "low-rank columns B");
    WT_ALLOC(ctx, nm->Z, (size_t)n * r, "low-rank solves N⁻¹ B");
    WT_ALLOC(ctx, nm->Q, (size_t)r * r, "low-rank core Q");
    WT_ALLOC(ctx, nm->K, (size_t)r * r, "Woodbury capacitance");
    WT_ALLOC(ctx, nm->ipiv, r, "Woodbury pivots");
    WT_ALLOC(ctx, zs, (size_t)ns * r, "low-rank slope vectors");
    double *Q = nm->Q;
    int c = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        const wt_noise *no = wt_tomography_noise(nm->t, m);
        const int ms = s->nsub;
        if (s->kind == WT_SENSOR_LGS) {
            /* columns c..c+3: U = [u_x, u_y] normalised tip and tilt, V = C̃⁻¹ U */
            double u = 1.0 / sqrt((double)ms);
            double *ux = zs + (size_t)c * ns + s->offset, *uy = ux + ns, *vx = uy + ns, *vy = vx + ns;
            for (int i = 0; i < ms; i++) {
                ux[i] = u;
                uy[ms + i] = u;
            }
            wt_noise_apply_inv(no, 1.0, ux, vx);
            wt_noise_apply_inv(no, 1.0, uy, vy);
            double g[2][2] = {{0, 0}, {0, 0}};
            for (int i = 0; i < 2 * ms; i++) {
                g[0][0] += ux[i] * vx[i];
                g[0][1] += ux[i] * vy[i];
                g[1][0] += uy[i] * vx[i];
                g[1][1] += uy[i] * vy[i];
            }
            /* Q_m = [[UᵀV, −I], [−I, 0]] (UᵀV symmetric as C̃⁻¹ is) */
            for (int a = 0; a < 2; a++) {
                for (int b = 0; b < 2; b++) Q[(c + a) + (size_t)r * (c + b)] = 0.5 * (g[a][b] + g[b][a]);
                Q[(c + a) + (size_t)r * (c + 2 + a)] = -1.0;
                Q[(c + 2 + a) + (size_t)r * (c + a)] = -1.0;
            }
            c += 4;
        } else {
            /* one column per NGS slope, Q_m = C̃_m⁻¹ (2x2 blocks) */
            for (int k = 0; k < 2 * ms; k++) zs[(size_t)(c + k) * ns + s->offset + k] = 1.0;
            for (int i = 0; i < ms; i++) {
                double a, b, cc;
                wt_noise_inv_block(no, i, &a, &b, &cc);
                Q[(c + i) + (size_t)r * (c + i)] = a;
                Q[(c + i) + (size_t)r * (c + ms + i)] = b;
                Q[(c + ms + i) + (size_t)r * (c + i)] = b;
                Q[(c + ms + i) + (size_t)r * (c + ms + i)] = cc;
            }
            c += 2 * ms;
        }
    }
    size_t ws = wt_mvm_priv_wavelet_work(nm->t);
    WT_ALLOC(ctx, work, (size_t)nm->nth * ws, "wavelet workspace");
#pragma omp parallel for schedule(dynamic, 1) num_threads(nm->nth)
    for (int k = 0; k < r; k++)
        adjoint_column(nm, zs + (size_t)k * ns, nm->B + (size_t)k * n, work + wt_mvm_priv_thread() * ws);

    /* Z = N⁻¹ B, K = I + Q (Bᵀ Z), LU */
    WT_TRY(wt_chol_solve(nm->chol, r, nm->B, n, nm->Z, n));
    double *btz = zs; /* reuse: r x r ≤ ns x r */
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, r, r, (int)n, 1.0, nm->B, (int)n, nm->Z, (int)n, 0.0, btz, r);
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, r, r, r, 1.0, Q, r, btz, r, 0.0, nm->K, r);
    for (int i = 0; i < r; i++) nm->K[i + (size_t)r * i] += 1.0;
    lapack_int info = LAPACKE_dgetrf(LAPACK_COL_MAJOR, r, r, nm->K, r, nm->ipiv);
    if (info != 0) {
        st = WT_ERROR(ctx, info < 0 ? WT_ERR_LIBRARY : WT_ERR_NUMERIC,
                      "LAPACKE_dgetrf of the %d x %d Woodbury capacitance I + Q Bᵀ N⁻¹ B returned %d (singular: "
                      "the MAP normal matrix is not invertible)",
                      r, r, (int)info);
        goto fail;
    }
fail:
    wt_free(ctx, zs);
    wt_free(ctx, work);
    return st;
}

int wt_mvm_normal_alloc(wt_context *ctx, wt_tomography *t, const wt_mvm_options *opt_in, double reserve,
                        int keep_matrix, wt_mvm_normal **out)
{
    int st = WT_OK;
    wt_mvm_options opt;
    if (opt_in) opt = *opt_in;
    else wt_mvm_options_default(&opt);
    if (opt.block <= 0) opt.block = 256;
    wt_mvm_normal *nm = NULL;
    templates *tp = NULL;
    col_pool pool = {0};
    wt_sparse *G = NULL, *N = NULL;
    pair_transpose F = {0};
    double *w3 = NULL;
    int64_t *partner = NULL, *pair_of = NULL, *colptr = NULL;
    uint8_t *is_x = NULL;
    char detail[512];
    double t0 = wt_time_now(), tt = t0;
    *out = NULL;

    WT_ALLOC(ctx, nm, 1, "MVM normal matrix");
    nm->ctx = ctx;
    nm->t = t;
    nm->sys = wt_tomography_system(t);
    nm->n = wt_tomography_nunknowns(t);
    nm->ns = nm->sys->nslopes;
    nm->nth = wt_context_threads(ctx);
    nm->maxblock = opt.block;
    const wt_system *sys = nm->sys;
    const int64_t n = nm->n;
    wt_mvm_stats *S = &nm->stats;
    S->nunknowns = n;
    S->nslopes = nm->ns;
    S->nact = sys->nact;
    int rank = 4 * sys->nlgs;
    for (int m = sys->nlgs; m < sys->nsensors; m++) rank += sys->sensors[m].nslopes;
    const double lowrank_bytes = 16.0 * (double)n * rank;

    /* Γ P, the basis templates, and the 2x2 Cholesky factors of the LGS weights */
    wt_mvm_priv_progress(&opt, "assemble", 0, 2 * n);
    WT_TRY(assemble_gp(ctx, t, &nm->gp));
    WT_TRY(templates_alloc(ctx, t, &tp));
    const int64_t nl = sys->nlgs > 0 ? sys->sensors[sys->nlgs - 1].offset + sys->sensors[sys->nlgs - 1].nslopes : 0;
    WT_ALLOC(ctx, w3, 3 * (size_t)(nl > 0 ? nl : 1), "LGS weight factors");
    WT_ALLOC(ctx, partner, nl > 0 ? nl : 1, "slope partners");
    WT_ALLOC(ctx, pair_of, nl > 0 ? nl : 1, "slope pairs");
    WT_ALLOC(ctx, is_x, nl > 0 ? nl : 1, "slope axes");
    int64_t npairs = 0;
    for (int m = 0; m < sys->nlgs; m++) {
        const wt_sensor *s = &sys->sensors[m];
        for (int i = 0; i < s->nsub; i++) {
            double a, b, c;
            wt_noise_inv_block(wt_tomography_noise(t, m), i, &a, &b, &c);
            int64_t x = s->offset + i, y = x + s->nsub;
            /* C̃_i⁻¹ = [[a, b], [b, c]] = L Lᵀ: l11 = √a, l21 = b/√a, l22 = √(det/a) */
            w3[x] = sqrt(a);
            w3[nl + x] = b / sqrt(a);
            w3[2 * nl + x] = sqrt((a * c - b * b) / a);
            partner[x] = y;
            partner[y] = x;
            pair_of[x] = npairs++;
            pair_of[y] = -1;
            is_x[x] = 1;
        }
    }
    const double gp_bytes = wt_mvm_priv_sparse_bytes(wt_sparse_nnz(nm->gp), n);

    /* G = Lᵀ Ã_LGS: count, check, fill */
    WT_TRY(pool_alloc(ctx, nm->nth, nl > n ? nl : n, &pool));
    acol_ctx ac = {nm->gp, tp, nl, 1, w3, w3 + nl, w3 + 2 * nl, partner, is_x};
    WT_ALLOC(ctx, colptr, n + 1, "column counts");
    count_columns(&pool, n, atilde_column, &ac, colptr, &opt, "assemble", 0, 2 * n);
    S->nnz_a = colptr[n];
    double g_bytes = wt_mvm_priv_sparse_bytes(S->nnz_a, n), f_bytes = pair_transpose_bytes(S->nnz_a, npairs);
    snprintf(detail, sizeof detail, "Γ P %.3g GB, Lᵀ Ã_LGS %.3g GB (%lld non-zeros) and its transpose %.3g GB",
             gp_bytes / 1e9, g_bytes / 1e9, (long long)S->nnz_a, f_bytes / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "assembling Ã", gp_bytes + g_bytes + f_bytes,
                                    detail));
    snprintf(detail, sizeof detail, "at least: the %.3g GB reserved for R, RÂ and the block workspace, Γ P, low rank",
             reserve / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "solving", reserve + gp_bytes + lowrank_bytes,
                                    detail));
    WT_TRY(wt_sparse_alloc(ctx, nl, n, S->nnz_a, &G));
    memcpy(G->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    fill_columns(&pool, G, atilde_column, &ac, &opt, "assemble", n, 2 * n);
    templates_free(ctx, tp);
    tp = NULL;
    WT_TRY(pair_transpose_alloc(ctx, G, pair_of, partner, npairs, &F));
    S->t_assemble = wt_time_now() - tt;
    tt = wt_time_now();

    /* N = Gᵀ G + α D, upper triangle */
    ncol_ctx nc = {G, &F, pair_of, partner, wt_tomography_alpha_prior(t)};
    wt_mvm_priv_progress(&opt, "normal", 0, 2 * n);
    count_columns(&pool, n, normal_column, &nc, colptr, &opt, "normal", 0, 2 * n);
    S->nnz_normal = colptr[n];
    double n_bytes = wt_mvm_priv_sparse_bytes(S->nnz_normal, n);
    snprintf(detail, sizeof detail, "Γ P %.3g GB, Lᵀ Ã_LGS and transpose %.3g GB, N %.3g GB (%lld non-zeros)",
             gp_bytes / 1e9, (g_bytes + f_bytes) / 1e9, n_bytes / 1e9, (long long)S->nnz_normal);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "forming N",
                                    gp_bytes + g_bytes + f_bytes + n_bytes, detail));
    /* the factor holds at least the pattern of N's upper triangle, and CHOLMOD copies N once */
    snprintf(detail, sizeof detail,
             "at least: N %.3g GB, CHOLMOD's permuted copy of it, a factor of ≥ %lld non-zeros %.3g GB, Γ P %.3g GB",
             n_bytes / 1e9, (long long)S->nnz_normal, 8.0 * S->nnz_normal / 1e9, gp_bytes / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N",
                                    gp_bytes + 2.0 * n_bytes + 8.0 * S->nnz_normal, detail));
    WT_TRY(wt_sparse_alloc(ctx, n, n, S->nnz_normal, &N));
    memcpy(N->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    fill_columns(&pool, N, normal_column, &nc, &opt, "normal", n, 2 * n);
    pool_free(&pool);
    wt_sparse_free(G);
    G = NULL;
    pair_transpose_free(ctx, &F);
    S->t_normal = wt_time_now() - tt;
    tt = wt_time_now();

    /* symbolic analysis: the factor's size is known before its memory is committed */
    wt_mvm_priv_progress(&opt, "analyze", 0, 1);
    WT_TRY(wt_chol_analyze(ctx, N, &nm->chol));
    wt_chol_info ci;
    wt_chol_info_get(nm->chol, &ci);
    S->nnz_factor = ci.nnz_factor;
    S->factor_bytes = ci.factor_bytes;
    S->factor_flops = ci.flops;
    S->ordering = ci.ordering;
    S->t_analyze = wt_time_now() - tt;
    wt_mvm_priv_progress(&opt, "analyze", 1, 1);
    snprintf(detail, sizeof detail,
             "N %.3g GB, CHOLMOD's factorisation %.3g GB (factor %.3g GB of %.4g non-zeros, %s ordering, plus its "
             "permuted copy of N and workspace), Γ P %.3g GB",
             n_bytes / 1e9, ci.factorize_bytes / 1e9, ci.factor_bytes / 1e9, ci.nnz_factor, ci.ordering, gp_bytes / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "factorising N",
                                    gp_bytes + n_bytes + ci.factorize_bytes, detail));
    double solve_ws = wt_chol_solve_bytes(n, opt.block > rank ? opt.block : rank) + 16.0 * rank * opt.block;
    double final_bytes = reserve + gp_bytes + ci.factor_bytes + lowrank_bytes + solve_ws + (keep_matrix ? n_bytes : 0.0);
    snprintf(detail, sizeof detail,
             "Cholesky factor %.3g GB, low rank %.3g GB, solve workspace %.3g GB, Γ P %.3g GB, reserved for the caller "
             "(R, RÂ, blocks) %.3g GB",
             ci.factor_bytes / 1e9, lowrank_bytes / 1e9, solve_ws / 1e9, gp_bytes / 1e9, reserve / 1e9);
    WT_TRY(wt_mvm_priv_check_budget(ctx, &opt, &S->peak_estimate, "solving", final_bytes, detail));

    tt = wt_time_now();
    wt_mvm_priv_progress(&opt, "factorize", 0, 1);
    WT_TRY(wt_chol_factorize(nm->chol, N));
    S->t_factorize = wt_time_now() - tt;
    wt_mvm_priv_progress(&opt, "factorize", 1, 1);
    if (keep_matrix) nm->N = N;
    else wt_sparse_free(N);
    N = NULL;

    tt = wt_time_now();
    WT_TRY(build_lowrank(nm));
    WT_ALLOC(ctx, nm->s1, (size_t)nm->r * nm->maxblock, "Woodbury scratch");
    WT_ALLOC(ctx, nm->s2, (size_t)nm->r * nm->maxblock, "Woodbury scratch");
    S->rank = nm->r;
    S->t_lowrank = wt_time_now() - tt;
    wt_chol_info_get(nm->chol, &ci);
    S->cholmod_peak = ci.peak_bytes;
    *out = nm;
    nm = NULL;
fail:
    pool_free(&pool);
    templates_free(ctx, tp);
    wt_sparse_free(G);
    pair_transpose_free(ctx, &F);
    wt_sparse_free(N);
    wt_free(ctx, w3);
    wt_free(ctx, partner);
    wt_free(ctx, pair_of);
    wt_free(ctx, is_x);
    wt_free(ctx, colptr);
    wt_mvm_normal_free(nm);
    return st;
}

int wt_mvm_normal_apply(const wt_mvm_normal *nm, const double *x, double *y)
{
    if (!nm->N)
        return WT_ERROR(nm->ctx, WT_ERR_INVALID, "wt_mvm_normal_apply: N was not kept (keep_matrix = 0 at alloc)");
    const wt_sparse *N = nm->N;
    memset(y, 0, (size_t)nm->n * sizeof *y);
    for (int64_t j = 0; j < nm->n; j++)
        for (int64_t k = N->colptr[j]; k < N->colptr[j + 1]; k++) {
            int64_t i = N->rowind[k];
            y[i] += N->val[k] * x[j];
            if (i != j) y[j] += N->val[k] * x[i];
        }
    const int r = nm->r, n = (int)nm->n;
    cblas_dgemv(CblasColMajor, CblasTrans, n, r, 1.0, nm->B, n, x, 1, 0.0, nm->s1, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, r, r, 1.0, nm->Q, r, nm->s1, 1, 0.0, nm->s2, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, n, r, 1.0, nm->B, n, nm->s2, 1, 1.0, y, 1);
    return WT_OK;
}

int wt_mvm_normal_solve(wt_mvm_normal *nm, int64_t nrhs, const double *b, double *x)
{
    int st;
    const int r = nm->r;
    const int64_t n = nm->n;
    for (int64_t j0 = 0; j0 < nrhs; j0 += nm->maxblock) {
        int nb = (int)(nrhs - j0 < nm->maxblock ? nrhs - j0 : nm->maxblock);
        double *xb = x + j0 * n;
        /* x = N⁻¹ b, then x −= Z K⁻¹ Q (Bᵀ x) */
        if ((st = wt_chol_solve(nm->chol, nb, b + j0 * n, n, xb, n)) < 0) return st;
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, r, nb, (int)n, 1.0, nm->B, (int)n, xb, (int)n, 0.0, nm->s1, r);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, r, nb, r, 1.0, nm->Q, r, nm->s1, r, 0.0, nm->s2, r);
        lapack_int info = LAPACKE_dgetrs(LAPACK_COL_MAJOR, 'N', r, nb, nm->K, r, nm->ipiv, nm->s2, r);
        if (info != 0) return WT_ERROR(nm->ctx, WT_ERR_LIBRARY, "LAPACKE_dgetrs (Woodbury correction) returned %d", (int)info);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)n, nb, r, -1.0, nm->Z, (int)n, nm->s2, r, 1.0, xb, (int)n);
    }
    return WT_OK;
}
