/* core/model/mvm_private.h: what the two files of the MVM builder share (SPEC §9; see mvm.h).
 *
 * Private to core/model/mvm.c (the command maps E, R and RÂ) and core/model/mvm_normal.c (Ã, N and
 * the factorised normal matrix M = N + B Q Bᵀ); included by nothing else. The normal object stays
 * opaque here too: the builder reaches the two things it needs from it through accessors.
 */
#ifndef WT_MVM_PRIVATE_H
#define WT_MVM_PRIVATE_H

#include "mvm.h"

#include <stddef.h>
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

/* Raise *peak to bytes, then refuse with WT_ERR_NOMEM (naming phase, bytes, detail and the budget)
 * when bytes exceeds opt->memory_budget > 0: called before each large allocation. */
int wt_mvm_priv_check_budget(wt_context *ctx, const wt_mvm_options *opt, double *peak, const char *phase,
                             double bytes, const char *detail);

/* The largest wavelet workspace (doubles) over the tomography's layers. */
size_t wt_mvm_priv_wavelet_work(const wt_tomography *t);

/* Γ P (nslopes x nunknowns, CSC) kept by the normal object: the builder maps layers to slopes with it. */
const wt_sparse *wt_mvm_priv_normal_gp(const wt_mvm_normal *nm);
/* CHOLMOD's peak allocation so far [bytes] (it grows with the block solves). */
double wt_mvm_priv_normal_cholmod_peak(const wt_mvm_normal *nm);

#endif
