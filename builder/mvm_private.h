/* builder/mvm_private.h: what the three files of the MVM builder share (SPEC §9; see mvm_build.h).
 *
 * Private to builder/mvm_build.c (the command maps E, R and RÂ), builder/mvm_assemble.c (Γ P, the
 * wavelet basis templates, the column-by-column construction of Ã) and builder/mvm_normal.c (N and
 * the factorised normal matrix M = N + B Q Bᵀ); included by nothing else. The normal object stays
 * opaque here too: the builder reaches the two things it needs from it through accessors.
 */
#ifndef WT_MVM_PRIVATE_H
#define WT_MVM_PRIVATE_H

#include "mvm_build.h"

#include <stddef.h>
#include <stdint.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* Index of the calling thread inside an OpenMP region (per-thread workspaces). */
static inline int wt_mvm_priv_thread(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

static inline void wt_mvm_priv_progress(const wt_mvm_options *opt, const char *phase, int64_t done, int64_t total)
{
    if (opt && opt->progress) opt->progress(opt->progress_user, phase, done, total);
}

/* Bytes of a CSC matrix with nnz entries and ncol columns (64-bit indices, double values). */
static inline double wt_mvm_priv_sparse_bytes(int64_t nnz, int64_t ncol)
{
    return 16.0 * (double)nnz + 8.0 * (double)(ncol + 1);
}

/* ---- mvm_assemble.c: the bottom of the builder (calls go one way: mvm_assemble ← mvm_normal ← mvm) -- */

/* Raise *peak to bytes, then refuse with WT_ERR_NOMEM (naming phase, bytes, detail and the budget)
 * when bytes exceeds opt->memory_budget > 0: called before each large allocation. */
int wt_mvm_priv_check_budget(wt_context *ctx, const wt_mvm_options *opt, double *peak, const char *phase,
                             double bytes, const char *detail);

/* The largest wavelet workspace (doubles) over the tomography's layers. */
size_t wt_mvm_priv_wavelet_work(const wt_tomography *t);

/* ---- mvm_normal.c ----------------------------------------------------------------------------------- */

/* Γ P (nslopes x nunknowns, CSC) kept by the normal object: the builder maps layers to slopes with it. */
const wt_sparse *wt_mvm_priv_normal_gp(const wt_mvm_normal *nm);
/* CHOLMOD's peak allocation so far [bytes] (it grows with the block solves). */
double wt_mvm_priv_normal_cholmod_peak(const wt_mvm_normal *nm);

/* ---- mvm_assemble.c: Γ P, the basis templates, the column construction ------------------------------ */

/* Γ P: nslopes x n (layer points in the order of the coefficients), rows in system slope order. */
int wt_mvm_priv_assemble_gp(wt_context *ctx, wt_tomography *t, wt_sparse **out);

/* The basis functions W⁻¹ e_λ of every layer, one template per level and orientation. */
typedef struct wt_mvm_priv_templates wt_mvm_priv_templates;
int wt_mvm_priv_templates_alloc(wt_context *ctx, const wt_tomography *t, wt_mvm_priv_templates **out);
void wt_mvm_priv_templates_free(wt_context *ctx, wt_mvm_priv_templates *tp);

/* Per-thread workspace of the column construction: acc, out, mark and list of nrow entries each. */
typedef struct {
    double *acc, *out;
    int64_t *mark, *list;
} wt_mvm_priv_col_work;

/* Computes column j: with rows == NULL only its non-zero count, else its sorted rows and values. */
typedef int64_t (*wt_mvm_priv_col_fn)(const void *c, int64_t j, wt_mvm_priv_col_work *w, int64_t *rows,
                                      double *vals);

/* Emit the cnt touched rows (tagged j in mark) in increasing order with their values src[row]; with
 * rows == NULL only return cnt. */
int64_t wt_mvm_priv_emit(wt_mvm_priv_col_work *w, int64_t j, int64_t cnt, int64_t *rows, double *vals,
                         const double *src);

/* One column workspace per thread, in one allocation. */
typedef struct {
    wt_context *ctx;
    int nth;
    int64_t nrow;
    wt_mvm_priv_col_work *w;
    void *store;
} wt_mvm_priv_col_pool;

int wt_mvm_priv_pool_alloc(wt_context *ctx, int nth, int64_t nrow, wt_mvm_priv_col_pool *p);
void wt_mvm_priv_pool_free(wt_mvm_priv_col_pool *p);

/* Pass 1: colptr[j + 1] = count of column j, then prefix sums (progress reported under phase, offset by
 * done0 out of total). */
void wt_mvm_priv_count_columns(wt_mvm_priv_col_pool *p, int64_t ncol, wt_mvm_priv_col_fn fn, const void *c,
                               int64_t *colptr, const wt_mvm_options *opt, const char *phase, int64_t done0,
                               int64_t total);
/* Pass 2: fill the columns of a (colptr already set). */
void wt_mvm_priv_fill_columns(wt_mvm_priv_col_pool *p, wt_sparse *a, wt_mvm_priv_col_fn fn, const void *c,
                              const wt_mvm_options *opt, const char *phase, int64_t done0, int64_t total);

/* The context of wt_mvm_priv_atilde_column: columns of Ã, or of Lᵀ Ã_LGS when weighted. */
typedef struct {
    const wt_sparse *gp;
    const wt_mvm_priv_templates *tp;
    int64_t nrows;      /* rows produced: every slope, or the LGS slopes (weighted) */
    int weighted;       /* 1: rows of Lᵀ Ã with C̃⁻¹ = L Lᵀ per subaperture */
    const double *w11, *w21, *w22; /* Lᵀ = [[w11, w21], [0, w22]], indexed by the x-row */
    const int64_t *partner;        /* x-row <-> y-row of the same subaperture */
    const uint8_t *is_x;
} wt_mvm_priv_acol_ctx;

/* A wt_mvm_priv_col_fn over a wt_mvm_priv_acol_ctx. */
int64_t wt_mvm_priv_atilde_column(const void *cv, int64_t j, wt_mvm_priv_col_work *w, int64_t *rows, double *vals);

#endif
