/* builder/mvm_assemble.c: the sparse Ã = Γ P W⁻¹ of the MVM builder (SPEC §9, §7; paper eq. eqn_lse):
 * the builder's options and memory budget, Γ P over all sensors and layers, the wavelet basis templates that give every column of W⁻¹, and the
 * parallel two-pass CSC construction that builder/mvm_normal.c reuses for G = Lᵀ Ã_LGS and N. */
#include "mvm_private.h"

#include <stdlib.h>
#include <string.h>

#include "../core/op/projection.h"

/* ---- options, memory budget, workspace sizes: the builder's bottom layer (mvm_build.c and mvm_normal.c
 * call these; this file calls neither of them) ------------------------------------------------------ */

void wt_mvm_options_default(wt_mvm_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->commands = WT_MVM_LAYER_VALUES;
    opt->block = 256;
}

int wt_mvm_priv_check_budget(wt_context *ctx, const wt_mvm_options *opt, double *peak, const char *phase,
                             double bytes, const char *detail)
{
    if (bytes > *peak) *peak = bytes;
    double budget = opt ? opt->memory_budget : 0.0;
    if (budget > 0.0 && bytes > budget)
        return WT_ERROR(ctx, WT_ERR_NOMEM,
                        "mvm: %s needs an estimated %.0f bytes (%.2f GB; %s) but only %.0f bytes (%.2f GB) are "
                        "available to the build",
                        phase, bytes, bytes / 1e9, detail, budget, budget / 1e9);
    return WT_OK;
}

size_t wt_mvm_priv_wavelet_work(const wt_tomography *t)
{
    size_t ws = 0;
    for (int l = 0; l < wt_tomography_nlayers(t); l++) {
        size_t s = wt_wavelet_work_size(wt_tomography_wavelet(t, l));
        if (s > ws) ws = s;
    }
    return ws;
}

/* ---- wavelet basis templates ------------------------------------------------------------------
 * All basis functions W⁻¹ e_λ of one layer, level and orientation are periodic shifts, by 2^level grid
 * points per coefficient step, of the block's first one (tests/test_wavelet.c, test_shift_property),
 * so one inverse DWT per block gives every column of W⁻¹. */

typedef struct {
    int npts, step;
    int32_t *tx, *ty; /* support of the block's (0, 0) basis function, grid indices */
    double *v;
} block_tmpl;

struct wt_mvm_priv_templates {
    int L;
    int n[WT_MAX_LAYERS], J[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS + 1];
    block_tmpl *blk[WT_MAX_LAYERS]; /* 3J + 1 per layer: (level-1)*3 + orient-1, approximation last */
};

void wt_mvm_priv_templates_free(wt_context *ctx, wt_mvm_priv_templates *tp)
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

int wt_mvm_priv_templates_alloc(wt_context *ctx, const wt_tomography *t, wt_mvm_priv_templates **out)
{
    int st = WT_OK;
    wt_mvm_priv_templates *tp = NULL;
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
    wt_mvm_priv_templates_free(ctx, tp);
    return st;
}

/* The template of coefficient j (global index) and the shift (sx, sy) that moves it there. */
static const block_tmpl *locate(const wt_mvm_priv_templates *tp, int64_t j, int *layer, int *sx, int *sy)
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

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

int64_t wt_mvm_priv_emit(wt_mvm_priv_col_work *w, int64_t j, int64_t cnt, int64_t *rows, double *vals,
                         const double *src)
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

/* Columns are tagged by their index in the marks: clear them before every pass. */
static void pool_reset(wt_mvm_priv_col_pool *p)
{
    for (int k = 0; k < p->nth; k++)
        for (int64_t r = 0; r < p->nrow; r++) p->w[k].mark[r] = -1;
}

void wt_mvm_priv_pool_free(wt_mvm_priv_col_pool *p)
{
    if (p->store) wt_free(p->ctx, p->store);
    wt_free(p->ctx, p->w);
    memset(p, 0, sizeof *p);
}

int wt_mvm_priv_pool_alloc(wt_context *ctx, int nth, int64_t nrow, wt_mvm_priv_col_pool *p)
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
    wt_mvm_priv_pool_free(p);
    return st;
}

enum { COL_CHUNK = 2048 };

void wt_mvm_priv_count_columns(wt_mvm_priv_col_pool *p, int64_t ncol, wt_mvm_priv_col_fn fn, const void *c,
                               int64_t *colptr, const wt_mvm_options *opt, const char *phase, int64_t done0,
                               int64_t total)
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

void wt_mvm_priv_fill_columns(wt_mvm_priv_col_pool *p, wt_sparse *a, wt_mvm_priv_col_fn fn, const void *c,
                              const wt_mvm_options *opt, const char *phase, int64_t done0, int64_t total)
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

int wt_mvm_priv_assemble_gp(wt_context *ctx, wt_tomography *t, wt_sparse **out)
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

int64_t wt_mvm_priv_atilde_column(const void *cv, int64_t j, wt_mvm_priv_col_work *w, int64_t *rows, double *vals)
{
    const wt_mvm_priv_acol_ctx *c = cv;
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
    if (!c->weighted) return wt_mvm_priv_emit(w, j, cnt, rows, vals, w->acc);
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
    return wt_mvm_priv_emit(w, j, cnt, rows, vals, w->out);
}

int wt_mvm_assemble_atilde(wt_context *ctx, wt_tomography *t, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *gp = NULL, *a = NULL;
    wt_mvm_priv_templates *tp = NULL;
    wt_mvm_priv_col_pool pool = {0};
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = wt_tomography_nunknowns(t);
    *out = NULL;
    WT_TRY(wt_mvm_priv_assemble_gp(ctx, t, &gp));
    WT_TRY(wt_mvm_priv_templates_alloc(ctx, t, &tp));
    WT_TRY(wt_mvm_priv_pool_alloc(ctx, wt_context_threads(ctx), sys->nslopes, &pool));
    wt_mvm_priv_acol_ctx c = {gp, tp, sys->nslopes, 0, NULL, NULL, NULL, NULL, NULL};
    int64_t *colptr = NULL;
    WT_ALLOC(ctx, colptr, n + 1, "column counts");
    wt_mvm_priv_count_columns(&pool, n, wt_mvm_priv_atilde_column, &c, colptr, NULL, NULL, 0, 0);
    st = wt_sparse_alloc(ctx, sys->nslopes, n, colptr[n], &a);
    if (st == WT_OK) memcpy(a->colptr, colptr, (size_t)(n + 1) * sizeof *colptr);
    wt_free(ctx, colptr);
    if (st < 0) goto fail;
    wt_mvm_priv_fill_columns(&pool, a, wt_mvm_priv_atilde_column, &c, NULL, NULL, 0, 0);
    *out = a;
    a = NULL;
fail:
    wt_mvm_priv_pool_free(&pool);
    wt_mvm_priv_templates_free(ctx, tp);
    wt_sparse_free(gp);
    wt_sparse_free(a);
    return st;
}
