/* core/la/sparse.h: compressed-sparse-column matrices with 64-bit indices, and a triplet builder.
 *
 * wt_sparse is a plain-data struct (like cholmod_sparse) so that chol.c can hand it to CHOLMOD
 * without copying indices. Columns are sorted by row, duplicates summed. The `_assemble` functions of
 * the operators return these; tests check apply == assembled * x.
 */
#ifndef WT_SPARSE_H
#define WT_SPARSE_H

#include "../base/base.h"

typedef struct wt_sparse {
    int64_t nrow, ncol;
    int64_t *colptr; /* ncol + 1 */
    int64_t *rowind; /* nnz = colptr[ncol] */
    double *val;
    wt_context *ctx; /* allocator of the arrays */
} wt_sparse;

/* Growing list of (row, col, value) entries; duplicates are summed by wt_triplet_compress. */
typedef struct wt_triplet wt_triplet;

int wt_triplet_alloc(wt_context *ctx, int64_t nrow, int64_t ncol, int64_t capacity, wt_triplet **out);
void wt_triplet_free(wt_triplet *t);
/* Append an entry; grows the storage (may allocate). Zero values are kept out. */
int wt_triplet_add(wt_triplet *t, int64_t row, int64_t col, double v);
int64_t wt_triplet_nnz(const wt_triplet *t);
/* Build the CSC matrix (sorted, duplicates summed, exact zeros dropped). */
int wt_triplet_compress(const wt_triplet *t, wt_sparse **out);

int wt_sparse_alloc(wt_context *ctx, int64_t nrow, int64_t ncol, int64_t nnz, wt_sparse **out);
void wt_sparse_free(wt_sparse *a);
static inline int64_t wt_sparse_nnz(const wt_sparse *a) { return a->colptr[a->ncol]; }
/* y <- y + alpha * A x   (x: ncol, y: nrow) */
void wt_sparse_apply(const wt_sparse *a, double alpha, const double *x, double *y);
/* y <- y + alpha * A^T x (x: nrow, y: ncol) */
void wt_sparse_apply_t(const wt_sparse *a, double alpha, const double *x, double *y);
/* C = A^T (allocates). */
int wt_sparse_transpose(const wt_sparse *a, wt_sparse **out);
/* C = A * B (allocates). */
int wt_sparse_multiply(const wt_sparse *a, const wt_sparse *b, wt_sparse **out);
/* C = α A + β B, A and B of one size and canonical (rows sorted in each column, no duplicates); C canonical,
 * exact zeros dropped (allocates). */
int wt_sparse_add(const wt_sparse *a, double alpha, const wt_sparse *b, double beta, wt_sparse **out);

#endif
