/* core/la/chol.h: sparse Cholesky factorisation of a symmetric positive definite matrix (CHOLMOD).
 *
 * The MVM builder (SPEC §9) factorises the sparse MAP normal matrix N = Σ Ãᵀ C̃⁻¹ Ã + α D with it and
 * solves for blocks of right-hand sides. This file pair is the only place that includes cholmod.h: the
 * rest of the library sees an opaque wt_chol and plain wt_sparse / column-major double arrays.
 *
 * CHOLMOD's long-index interface (cholmod_l_*) is used, so matrices of more than 2^31 non-zeros work;
 * wt_sparse's int64_t arrays are handed over without copying. Supernodal LLᵀ (its dense kernels run
 * in the BLAS, i.e. OpenBLAS's threads), fill-reducing ordering as CHOLMOD chooses it (AMD, and METIS
 * when AMD's fill is poor). CHOLMOD's memory comes from its own allocator (malloc), not the context's:
 * wt_chol_info reports what it holds. CHOLMOD prints nothing (print level 0); its failures become
 * WT_ERR_NOMEM, WT_ERR_NUMERIC (not positive definite) or WT_ERR_LIBRARY naming the call.
 */
#ifndef WT_CHOL_H
#define WT_CHOL_H

#include "sparse.h"

typedef struct wt_chol wt_chol;

typedef struct wt_chol_info {
    int64_t n;              /* order of the matrix */
    int64_t nnz_matrix;     /* entries of the upper triangle handed over */
    double nnz_factor;      /* non-zeros of L (CHOLMOD's count, without supernodal padding) */
    double factor_entries;  /* numerical entries L holds (with supernodal padding) */
    double factor_bytes;    /* bytes of the numeric factor (values and supernode row indices) */
    double factorize_bytes; /* CHOLMOD's peak during wt_chol_factorize: the factor, its permuted copy of
                               the matrix (supernodal numeric works on A(p,p)) and the largest update
                               matrix [bytes]; the caller's own copy of the matrix comes on top */
    double flops;           /* flops of the factorisation, as CHOLMOD's analysis counts them */
    double peak_bytes;      /* CHOLMOD's own peak memory so far [bytes] */
    int supernodal;         /* 1 supernodal, 0 simplicial */
    int factorized;         /* 1 after wt_chol_factorize */
    const char *ordering;   /* "AMD", "METIS", "NESDIS", "natural", … */
} wt_chol_info;

/* Symbolic analysis (ordering, elimination tree, supernodes) of the n x n SPD matrix whose UPPER
 * triangle is `upper` (CSC, rows sorted; entries below the diagonal are ignored). The sizes of the
 * factor are known after this call (wt_chol_info), before any numeric memory is committed.
 * `upper` is not copied and not kept. Allocates (CHOLMOD). */
int wt_chol_analyze(wt_context *ctx, const wt_sparse *upper, wt_chol **out);
void wt_chol_free(wt_chol *c);
void wt_chol_info_get(const wt_chol *c, wt_chol_info *info);

/* Numeric factorisation of the matrix (same pattern as at analysis; values may differ).
 * WT_ERR_NUMERIC when it is not positive definite (naming the column), WT_ERR_NOMEM, WT_ERR_LIBRARY. */
int wt_chol_factorize(wt_chol *c, const wt_sparse *upper);

/* X = A⁻¹ B for nrhs columns (column-major, leading dimensions ldb, ldx ≥ n; B and X may be the same
 * array). CHOLMOD allocates its solve workspace on the first call and reuses it while nrhs does not
 * grow; not thread-safe per object. */
int wt_chol_solve(wt_chol *c, int64_t nrhs, const double *b, int64_t ldb, double *x, int64_t ldx);

/* One right-hand side, frame after frame (the fitting's direct solve): x = A⁻¹ b by the two triangular solves
 * on the supernodal factor, without CHOLMOD's per-call copies, on up to two threads, optionally from a
 * float32 copy of L (half the bytes the solves stream; accumulation in double).
 *
 * wt_chol_prepare_one (after wt_chol_factorize; allocates) splits the supernodal elimination tree once: the
 * heaviest subtrees are dealt to two groups by their entries of L (greedy, largest first), their common
 * ancestors form the top part. Forward solve L y = P b: the two groups in parallel, each adding its updates
 * of top rows into its own buffer, then the top part; backward Lᵀ z = y: the top part, then the groups in
 * parallel (they write disjoint columns). The decomposition does not depend on the thread count, so neither
 * do the bits (they differ from wt_chol_solve's by rounding). float32: L rounded to float once, so the
 * solution carries a relative error up to ~κ(A) · 6e-8 (the exact factor of a matrix within ~1e-7 ‖A‖ of A).
 * wt_chol_solve_one allocates nothing; b and x may be the same array. WT_ERR_INVALID before a preparation. */
int wt_chol_prepare_one(wt_chol *c, int float32, int nthreads);
int wt_chol_solve_one(wt_chol *c, const double *b, double *x);
/* reference = 1: wt_chol_solve_one runs the plain reference kernels instead of the vectorised ones (the same
 * bits, slower: the oracle of the tests and the baseline of the paired bench); 0 (the default): the fast ones. */
void wt_chol_one_reference(wt_chol *c, int reference);
/* The split: entries of L in the two groups and in the top part (for reports and tests). */
void wt_chol_split(const wt_chol *c, double *group0, double *group1, double *top);
/* Bytes of the packed copy wt_chol_solve_one reads (each solve reads it once; 0 before a preparation). */
double wt_chol_one_bytes(const wt_chol *c);

/* Bytes CHOLMOD's solve needs for nrhs right-hand sides (its X, Y and E workspaces), for estimates. */
double wt_chol_solve_bytes(int64_t n, int64_t nrhs);

/* CHOLMOD's version string ("CHOLMOD 3.0.14"), for provenance records. */
const char *wt_chol_version(void);

#endif
