/* core/io/mvm_file.h: the MVM control matrix file MATRIX.h5 (SPEC §9).
 *
 * Datasets: R (n_act x n_slopes, float32, row = actuator), RA = R Â (n_act x n_act, float32) — or, with
 * recon.mvm_precision fp16/bf16, both as 16-bit floats of R_ij / c_i with the power-of-two row scales c_i
 * in R_row_scale and RA_row_scale (n_act, float32; core/la/half.h) — and the
 * identity of the system they were built for: the root attribute "config_sha256" (SHA-256 of the
 * configuration keys that can change R, wt_config.matrix_sha256) and the dataset "matrix_config" (that
 * text), plus the variant, α, τ and the build statistics. A reader refuses a file built for another
 * system, of the wrong shape, truncated or incomplete — before any frame is processed.
 *
 * Plain data in and out (float arrays, sizes, a record of strings and numbers): the container and its
 * conversion are core/solve/mvm.h's (wt_mvm_read / wt_mvm_write).
 */
#ifndef WT_MVM_FILE_H
#define WT_MVM_FILE_H

#include "h5.h"

/* The identity of the system a matrix is built for, as plain data (the caller copies it from its
 * configuration: wt_config.matrix_sha256, .matrix_text, .path, .alpha, .tau). */
typedef struct wt_mvm_file_system {
    const char *sha256; /* SHA-256 (hex) of the configuration keys that can change R */
    const char *text;   /* that canonical text (written only) */
    const char *path;   /* the configuration file, named in messages */
    double alpha, tau;  /* prior weight α, elongation weight τ of the noise model (written only) */
} wt_mvm_file_system;

/* What is written beside the matrices: the variant and the record of the build. */
typedef struct wt_mvm_file_record {
    const char *variant;         /* "pcg3" or "cg9" */
    int64_t nunknowns;           /* wavelet coefficients of the MAP problem */
    double nnz_factor;           /* non-zeros of the Cholesky factor of N */
    int rank;                    /* rank of the Woodbury correction */
    double build_time;           /* wall time of the build [s] */
    double peak_estimate;        /* estimated peak memory of the build [bytes] */
    const char *ordering;        /* fill-reducing ordering (NULL: unknown) */
    const char *cholmod_version; /* the CHOLMOD that factorised */
} wt_mvm_file_record;

/* Storage precisions: the values of recon.mvm_precision (wt_config.mvm_precision), the same as
 * core/la/half.h's WT_PREC_* (core/solve/mvm.c checks it at compile time; the file layer does not
 * depend on la). */
enum { WT_MVM_FILE_F32 = 0, WT_MVM_FILE_F16 = 1, WT_MVM_FILE_BF16 = 2 };

/* The two matrices as stored: precision WT_MVM_FILE_F32 uses R (nact x nslopes) and RA (nact x nact),
 * float32 row-major; F16/BF16 use Rh and RAh (the same shapes, 16-bit patterns) and the row scales Rc,
 * RAc (nact each). */
typedef struct wt_mvm_file_data {
    int precision;
    float *R, *RA;
    uint16_t *Rh, *RAh;
    float *Rc, *RAc;
} wt_mvm_file_data;

/* Write the matrices of d in d->precision (root attribute "precision"), the identity sys and the
 * record into an open writer (the caller adds provenance and layout and commits). */
int wt_mvm_file_write(wt_h5_writer *w, const wt_mvm_file_system *sys, int64_t nact, int64_t nslopes,
                      const wt_mvm_file_data *d, const wt_mvm_file_record *rec);

/* The storage precision of MATRIX.h5 (its root attribute "precision": "fp32", "fp16" or "bf16"; a file
 * without it is fp32). Anything else is refused naming the file. */
int wt_mvm_file_precision(wt_context *ctx, const char *path, int *precision);

/* Read MATRIX.h5 for a system of nact actuators and nslopes slopes identified by sys into the caller's
 * buffers of d, allocated for d->precision (the file's, from wt_mvm_file_precision). Refuses
 * (WT_ERR_FORMAT, naming the file) a matrix whose config_sha256 differs from sys->sha256 (the
 * precision is not hashed: it is how R is stored, not which R), whose shapes or element types differ,
 * or whose values or row scales are not finite (scales: > 0). variant_out: 16 bytes for the stored
 * variant. Allocates only transiently. */
int wt_mvm_file_read(wt_context *ctx, const char *path, const wt_mvm_file_system *sys, int64_t nact,
                     int64_t nslopes, wt_mvm_file_data *d, char *variant_out);
/* The keys whose values differ between two canonical configuration texts a and b (wt_mvm_file_system.text,
 * the file's "matrix_config"), for a message: "recon.alpha = 1.0 in NAME_A, 0.5 in NAME_B", up to three
 * joined by "; ", then "; and K more keys"; a key one text lacks is "not set" there. buf gets "" when
 * they agree, or a text is NULL or longer than WT_MVM_FILE_DIFF_MAX_TEXT; truncated to n. Allocates nothing. */
#define WT_MVM_FILE_DIFF_MAX_TEXT 65536
void wt_mvm_file_text_diff(const char *a, const char *b, const char *name_a, const char *name_b, char *buf, size_t n);

/* The same from a file already open (its name is wt_h5_path(r); r stays open): tests/fuzz reads memory
 * images through it. */
int wt_mvm_file_read_open(wt_context *ctx, wt_h5_reader *r, const wt_mvm_file_system *sys, int64_t nact,
                          int64_t nslopes, wt_mvm_file_data *d, char *variant_out);

#endif
