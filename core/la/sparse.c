/* core/la/sparse.c: CSC matrices, triplet assembly, products. */
#include "sparse.h"

#include <stdlib.h>
#include <string.h>

struct wt_triplet {
    wt_context *ctx;
    int64_t nrow, ncol, n, cap;
    int64_t *i, *j;
    double *v;
};

int wt_triplet_alloc(wt_context *ctx, int64_t nrow, int64_t ncol, int64_t capacity, wt_triplet **out)
{
    int st = WT_OK;
    wt_triplet *t = NULL;
    *out = NULL;
    if (nrow < 0 || ncol < 0) return WT_ERROR(ctx, WT_ERR_INVALID, "triplet: negative size %lld x %lld", (long long)nrow, (long long)ncol);
    if (capacity < 16) capacity = 16;
    WT_ALLOC(ctx, t, 1, "triplet");
    t->ctx = ctx;
    t->nrow = nrow;
    t->ncol = ncol;
    t->cap = capacity;
    WT_ALLOC(ctx, t->i, capacity, "triplet rows");
    WT_ALLOC(ctx, t->j, capacity, "triplet columns");
    WT_ALLOC(ctx, t->v, capacity, "triplet values");
    *out = t;
    return WT_OK;
fail:
    wt_triplet_free(t);
    return st;
}

void wt_triplet_free(wt_triplet *t)
{
    if (!t) return;
    wt_free(t->ctx, t->i);
    wt_free(t->ctx, t->j);
    wt_free(t->ctx, t->v);
    wt_free(t->ctx, t);
}

int64_t wt_triplet_nnz(const wt_triplet *t) { return t->n; }

static int grow(wt_triplet *t)
{
    int64_t cap = t->cap * 2;
    int64_t *ni = wt_malloc(t->ctx, (size_t)cap, sizeof *ni);
    int64_t *nj = wt_malloc(t->ctx, (size_t)cap, sizeof *nj);
    double *nv = wt_malloc(t->ctx, (size_t)cap, sizeof *nv);
    if (!ni || !nj || !nv) {
        wt_free(t->ctx, ni);
        wt_free(t->ctx, nj);
        wt_free(t->ctx, nv);
        return WT_ERROR(t->ctx, WT_ERR_NOMEM, "triplet: out of memory growing to %lld entries", (long long)cap);
    }
    memcpy(ni, t->i, (size_t)t->n * sizeof *ni);
    memcpy(nj, t->j, (size_t)t->n * sizeof *nj);
    memcpy(nv, t->v, (size_t)t->n * sizeof *nv);
    wt_free(t->ctx, t->i);
    wt_free(t->ctx, t->j);
    wt_free(t->ctx, t->v);
    t->i = ni;
    t->j = nj;
    t->v = nv;
    t->cap = cap;
    return WT_OK;
}

int wt_triplet_add(wt_triplet *t, int64_t row, int64_t col, double v)
{
    if (row < 0 || row >= t->nrow || col < 0 || col >= t->ncol)
        return WT_ERROR(t->ctx, WT_ERR_INVALID, "triplet: entry (%lld, %lld) outside %lld x %lld", (long long)row,
                        (long long)col, (long long)t->nrow, (long long)t->ncol);
    if (v == 0.0) return WT_OK;
    if (t->n == t->cap) {
        int st = grow(t);
        if (st) return st;
    }
    t->i[t->n] = row;
    t->j[t->n] = col;
    t->v[t->n] = v;
    t->n++;
    return WT_OK;
}

int wt_sparse_alloc(wt_context *ctx, int64_t nrow, int64_t ncol, int64_t nnz, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *a = NULL;
    *out = NULL;
    WT_ALLOC(ctx, a, 1, "sparse matrix");
    a->ctx = ctx;
    a->nrow = nrow;
    a->ncol = ncol;
    WT_ALLOC(ctx, a->colptr, ncol + 1, "sparse column pointers");
    WT_ALLOC(ctx, a->rowind, nnz, "sparse row indices");
    WT_ALLOC(ctx, a->val, nnz, "sparse values");
    *out = a;
    return WT_OK;
fail:
    wt_sparse_free(a);
    return st;
}

void wt_sparse_free(wt_sparse *a)
{
    if (!a) return;
    wt_free(a->ctx, a->colptr);
    wt_free(a->ctx, a->rowind);
    wt_free(a->ctx, a->val);
    wt_free(a->ctx, a);
}

/* Sort the entries of every column by row and sum duplicates, in place; drops exact zeros. */
static void canonicalise(wt_sparse *a, int64_t *work_row_pos)
{
    /* work_row_pos: nrow entries, -1 = row not yet seen in this column */
    int64_t nz = 0;
    for (int64_t r = 0; r < a->nrow; r++) work_row_pos[r] = -1;
    int64_t start = a->colptr[0];
    for (int64_t c = 0; c < a->ncol; c++) {
        int64_t end = a->colptr[c + 1];
        int64_t colstart = nz;
        for (int64_t k = start; k < end; k++) {
            int64_t r = a->rowind[k];
            if (work_row_pos[r] >= colstart) {
                a->val[work_row_pos[r]] += a->val[k];
            } else {
                work_row_pos[r] = nz;
                a->rowind[nz] = r;
                a->val[nz] = a->val[k];
                nz++;
            }
        }
        /* insertion sort of the (usually short, nearly sorted) column */
        for (int64_t k = colstart + 1; k < nz; k++) {
            int64_t r = a->rowind[k];
            double v = a->val[k];
            int64_t m = k - 1;
            while (m >= colstart && a->rowind[m] > r) {
                a->rowind[m + 1] = a->rowind[m];
                a->val[m + 1] = a->val[m];
                m--;
            }
            a->rowind[m + 1] = r;
            a->val[m + 1] = v;
        }
        /* drop exact zeros created by cancellation */
        int64_t w = colstart;
        for (int64_t k = colstart; k < nz; k++) {
            if (a->val[k] != 0.0) {
                a->rowind[w] = a->rowind[k];
                a->val[w] = a->val[k];
                w++;
            }
        }
        for (int64_t k = colstart; k < w; k++) work_row_pos[a->rowind[k]] = -1;
        for (int64_t k = w; k < nz; k++) work_row_pos[a->rowind[k]] = -1;
        nz = w;
        start = end;
        a->colptr[c + 1] = nz;
    }
    a->colptr[0] = 0;
}

int wt_triplet_compress(const wt_triplet *t, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *a = NULL;
    int64_t *work = NULL;
    *out = NULL;
    WT_TRY(wt_sparse_alloc(t->ctx, t->nrow, t->ncol, t->n, &a));
    WT_ALLOC(t->ctx, work, t->nrow > t->ncol ? t->nrow + 1 : t->ncol + 1, "triplet workspace");
    for (int64_t k = 0; k < t->n; k++) a->colptr[t->j[k] + 1]++;
    for (int64_t c = 0; c < t->ncol; c++) a->colptr[c + 1] += a->colptr[c];
    for (int64_t c = 0; c < t->ncol; c++) work[c] = a->colptr[c];
    for (int64_t k = 0; k < t->n; k++) {
        int64_t p = work[t->j[k]]++;
        a->rowind[p] = t->i[k];
        a->val[p] = t->v[k];
    }
    canonicalise(a, work);
    wt_free(t->ctx, work);
    *out = a;
    return WT_OK;
fail:
    wt_free(t->ctx, work);
    wt_sparse_free(a);
    return st;
}

void wt_sparse_apply(const wt_sparse *a, double alpha, const double *x, double *y)
{
    for (int64_t c = 0; c < a->ncol; c++) {
        double xc = alpha * x[c];
        if (xc == 0.0) continue;
        for (int64_t k = a->colptr[c]; k < a->colptr[c + 1]; k++) y[a->rowind[k]] += a->val[k] * xc;
    }
}

void wt_sparse_apply_t(const wt_sparse *a, double alpha, const double *x, double *y)
{
/* columns from which the transpose's independent dots take a thread team (fewer: the region costs more) */
enum { APPLY_T_PARALLEL_MIN = 4096 };
#pragma omp parallel for schedule(static) if (a->ncol > APPLY_T_PARALLEL_MIN)
    for (int64_t c = 0; c < a->ncol; c++) {
        double s = 0.0;
        for (int64_t k = a->colptr[c]; k < a->colptr[c + 1]; k++) s += a->val[k] * x[a->rowind[k]];
        y[c] += alpha * s;
    }
}

int wt_sparse_transpose(const wt_sparse *a, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *b = NULL;
    int64_t *next = NULL;
    int64_t nnz = wt_sparse_nnz(a);
    *out = NULL;
    WT_TRY(wt_sparse_alloc(a->ctx, a->ncol, a->nrow, nnz, &b));
    WT_ALLOC(a->ctx, next, a->nrow + 1, "transpose workspace");
    for (int64_t k = 0; k < nnz; k++) b->colptr[a->rowind[k] + 1]++;
    for (int64_t r = 0; r < a->nrow; r++) b->colptr[r + 1] += b->colptr[r];
    for (int64_t r = 0; r < a->nrow; r++) next[r] = b->colptr[r];
    for (int64_t c = 0; c < a->ncol; c++)
        for (int64_t k = a->colptr[c]; k < a->colptr[c + 1]; k++) {
            int64_t p = next[a->rowind[k]]++;
            b->rowind[p] = c;
            b->val[p] = a->val[k];
        }
    wt_free(a->ctx, next);
    *out = b;
    return WT_OK;
fail:
    wt_free(a->ctx, next);
    wt_sparse_free(b);
    return st;
}

int wt_sparse_multiply(const wt_sparse *a, const wt_sparse *b, wt_sparse **out)
{
    int st = WT_OK;
    wt_context *ctx = a->ctx;
    wt_sparse *c = NULL;
    int64_t *mark = NULL;
    double *acc = NULL;
    *out = NULL;
    if (a->ncol != b->nrow)
        return WT_ERROR(ctx, WT_ERR_INVALID, "sparse multiply: inner sizes differ (%lld vs %lld)", (long long)a->ncol,
                        (long long)b->nrow);
    /* first pass: count the non-zeros of every column of C */
    WT_ALLOC(ctx, mark, a->nrow, "multiply workspace");
    WT_ALLOC(ctx, acc, a->nrow, "multiply workspace");
    for (int64_t r = 0; r < a->nrow; r++) mark[r] = -1;
    int64_t nnz = 0;
    for (int64_t j = 0; j < b->ncol; j++)
        for (int64_t kb = b->colptr[j]; kb < b->colptr[j + 1]; kb++) {
            int64_t col = b->rowind[kb];
            for (int64_t ka = a->colptr[col]; ka < a->colptr[col + 1]; ka++)
                if (mark[a->rowind[ka]] != j) {
                    mark[a->rowind[ka]] = j;
                    nnz++;
                }
        }
    WT_TRY(wt_sparse_alloc(ctx, a->nrow, b->ncol, nnz, &c));
    for (int64_t r = 0; r < a->nrow; r++) mark[r] = -1;
    int64_t p = 0;
    for (int64_t j = 0; j < b->ncol; j++) {
        int64_t start = p;
        for (int64_t kb = b->colptr[j]; kb < b->colptr[j + 1]; kb++) {
            int64_t col = b->rowind[kb];
            double bv = b->val[kb];
            for (int64_t ka = a->colptr[col]; ka < a->colptr[col + 1]; ka++) {
                int64_t r = a->rowind[ka];
                if (mark[r] != j) {
                    mark[r] = j;
                    c->rowind[p++] = r;
                    acc[r] = a->val[ka] * bv;
                } else {
                    acc[r] += a->val[ka] * bv;
                }
            }
        }
        for (int64_t k = start; k < p; k++) c->val[k] = acc[c->rowind[k]];
        c->colptr[j + 1] = p;
    }
    /* sort rows within columns (canonical form) */
    int64_t *work = mark;
    canonicalise(c, work);
    wt_free(ctx, mark);
    wt_free(ctx, acc);
    *out = c;
    return WT_OK;
fail:
    wt_free(ctx, mark);
    wt_free(ctx, acc);
    wt_sparse_free(c);
    return st;
}

int wt_sparse_add(const wt_sparse *a, double alpha, const wt_sparse *b, double beta, wt_sparse **out)
{
    int st = WT_OK;
    wt_sparse *c = NULL;
    *out = NULL;
    if (a->nrow != b->nrow || a->ncol != b->ncol)
        return WT_ERROR(a->ctx, WT_ERR_INVALID, "sparse add: %lld x %lld and %lld x %lld", (long long)a->nrow,
                        (long long)a->ncol, (long long)b->nrow, (long long)b->ncol);
    WT_TRY(wt_sparse_alloc(a->ctx, a->nrow, a->ncol, wt_sparse_nnz(a) + wt_sparse_nnz(b), &c));
    int64_t p = 0;
    for (int64_t j = 0; j < a->ncol; j++) { /* merge of two sorted row lists */
        int64_t ka = a->colptr[j], kb = b->colptr[j];
        const int64_t ea = a->colptr[j + 1], eb = b->colptr[j + 1];
        while (ka < ea || kb < eb) {
            const int64_t ra = ka < ea ? a->rowind[ka] : INT64_MAX, rb = kb < eb ? b->rowind[kb] : INT64_MAX;
            double v;
            int64_t r;
            if (ra < rb) r = ra, v = alpha * a->val[ka++];
            else if (rb < ra) r = rb, v = beta * b->val[kb++];
            else r = ra, v = alpha * a->val[ka++] + beta * b->val[kb++];
            if (v == 0.0) continue;
            c->rowind[p] = r;
            c->val[p++] = v;
        }
        c->colptr[j + 1] = p;
    }
    *out = c;
    return WT_OK;
fail:
    wt_sparse_free(c);
    return st;
}
