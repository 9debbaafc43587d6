/* core/solve/mvm.h: the stored MVM control matrix at run time and its one POLC apply (SPEC §9, §7;
 * FFTW's execute to the planner of builder/mvm_build.h).
 *
 *   y = R s + (R Â) a        R: n_act x n_slopes, RÂ: n_act x n_act, float32, row = actuator,
 *
 * or both stored as 16-bit floats with a power-of-two scale per row and applied with float32
 * accumulation (recon.mvm_precision fp16/bf16, core/la/half.h: half the bytes per frame),
 *
 * the pseudo-open-loop reconstruction R s_ol with s_ol = s + Â a written so that Â is not needed at run
 * time (`wavetomo run`), or y = R s_ol when the caller already has the pseudo-open-loop slopes (the
 * closed loop of sim/loop, `sim --recon mvm`, `compare`). Slope order: the system's (LGS first,
 * then NGS; [s_x…, s_y…] per sensor); actuator order: DM by DM, active actuators in grid-index order.
 *
 * The container is plain data: the two matrices, what they are commands of, and the record of their
 * build (provenance, written into MATRIX.h5). It is made by the builder (wt_mvm_build) or read from a
 * file (wt_mvm_read); wt_mvm_apply is const, allocates nothing and can run from several threads.
 */
#ifndef WT_SOLVE_MVM_H
#define WT_SOLVE_MVM_H

#include "../base/base.h"
#include "../config/config.h"
#include "../io/h5.h"

/* What the commands are: pcg3's layer values at the actuators, or cg9's exact fitting of the layers. */
enum { WT_MVM_LAYER_VALUES = 0, WT_MVM_FITTING = 1 };

/* The record of a build (sizes, factor, times) — provenance, not needed to apply the matrix. */
typedef struct wt_mvm_stats {
    int64_t nunknowns, nslopes, nact;
    int64_t nnz_a;             /* non-zeros of the sparse LGS part of Ã */
    int64_t nnz_normal;        /* non-zeros of the upper triangle of N */
    int rank;                  /* r of the low-rank correction */
    double nnz_factor;         /* non-zeros of the Cholesky factor L */
    double factor_bytes;       /* bytes of the numeric factor */
    double factor_flops;       /* flops of the factorisation (CHOLMOD's count) */
    const char *ordering;      /* fill-reducing ordering CHOLMOD chose (static string) */
    double peak_estimate;      /* estimated peak memory of the build [bytes] */
    double cholmod_peak;       /* CHOLMOD's own peak allocation [bytes] */
    /* wall-clock seconds per phase */
    double t_assemble, t_normal, t_analyze, t_factorize, t_lowrank, t_fitting, t_solve, t_total;
} wt_mvm_stats;

typedef struct wt_mvm {
    wt_context *ctx;
    int commands;              /* WT_MVM_LAYER_VALUES or WT_MVM_FITTING */
    int64_t nact, nslopes;
    int precision;             /* WT_PREC_F32, or WT_PREC_F16 / WT_PREC_BF16 (core/la/half.h) */
    float *R;                  /* fp32: nact x nslopes, row-major: R[i * nslopes + j] (actuator i, slope j); else NULL */
    float *RA;                 /* fp32: nact x nact, row-major: (R Â)[i * nact + k]; else NULL */
    uint16_t *Rh, *RAh;        /* fp16/bf16: the same matrices as 16-bit floats of R_ij / c_i; else NULL */
    float *Rc, *RAc;           /* fp16/bf16: the row scales c_i (nact each); else NULL */
    int nthreads;              /* threads of the 16-bit apply (the fp32 one uses OpenBLAS's) */
    int predictive;            /* 1: R moves the layers by their wind over the loop's lead (recon.predict: the
                                * builder's predict_adjoint; a file read under a predicting configuration, whose
                                * identity holds the predictor); a run that must not predict refuses it */
    wt_mvm_stats stats;
} wt_mvm;

/* An nact x nslopes fp32 container with R and RÂ allocated (uninitialised), stats zero. [out] *out. */
int wt_mvm_alloc(wt_context *ctx, int commands, int64_t nact, int64_t nslopes, wt_mvm **out);
/* Store an fp32 container's matrices in `precision` instead (rounded to nearest even, the fp32 arrays
 * freed); WT_PREC_F32 or the current precision: nothing to do. A non-finite entry is refused. */
int wt_mvm_set_precision(wt_mvm *m, int precision);
void wt_mvm_free(wt_mvm *m);

/* y = R s + RÂ a, or y = R s when a is NULL (y: nact, overwritten; s: nslopes; a: nact). One float32
 * GEMV (two with a) through OpenBLAS, or core/la/half.h's 16-bit GEMV. Allocates nothing. */
void wt_mvm_apply(const wt_mvm *m, const float *s, const float *a, float *y);

/* MATRIX.h5 (core/io/mvm_file.h) <-> the container. read: for a system of nact actuators and nslopes
 * slopes described by cfg (the file's config hash must be cfg's; the container gets the file's precision,
 * whatever cfg's recon.mvm_precision says, and the context's thread count); variant_out: NULL or 16 bytes.
 * write: in m's precision.
 * write: into an open writer, variant "pcg3" or "cg9" (the caller adds provenance, layout, commits). */
int wt_mvm_read(wt_context *ctx, const char *path, const wt_config *cfg, int64_t nact, int64_t nslopes, wt_mvm **out,
                char *variant_out);
int wt_mvm_write(wt_h5_writer *w, const wt_mvm *m, const wt_config *cfg, const char *variant);

#endif
