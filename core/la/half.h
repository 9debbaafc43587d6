/* core/la/half.h: float32 matrices stored as 16-bit floats (IEEE binary16 "fp16", or bfloat16 "bf16")
 * and their matrix-vector product with float32 accumulation (`recon.mvm_precision`; docs/guide.md "Storage
 * precision").
 *
 * The MVM apply y = R s reads every element of R once per frame and does 2 flops with it: it runs at the
 * memory bandwidth, so halving the bytes of R halves its time. Each row i is stored as
 *
 *   H_ij = round16(R_ij / c_i),   c_i = 2^k_i   (a power of two: the scaling adds no rounding),
 *
 * with k_i chosen so that max_j |R_ij| / c_i lies in [2^14, 2^15): fp16 (5-bit exponent, largest finite
 * 65504) neither overflows nor spends its 10-bit mantissa on subnormals for the large entries of a row;
 * bf16 has float32's exponent and needs no scaling, but the same rule costs nothing. Then
 *
 *   y_i = β y_i + c_i Σ_j H_ij x_j,
 *
 * and the error of the stored matrix alone is |R_ij − c_i H_ij| ≤ u |R_ij| for the entries H stores as
 * normal numbers (u = 2^-11 for fp16, 2^-8 for bf16: round to nearest even), and ≤ 2^-25 c_i for the fp16
 * entries below its smallest normal 2^-14 (subnormals are spaced 2^-24), so
 *
 *   |y_i − (R x)_i| ≤ u Σ_j |R_ij x_j| + 2^-25 c_i Σ_j |x_j| + (float32 accumulation error),
 *
 * the bound tests/test_half.c checks.
 */
#ifndef WT_LA_HALF_H
#define WT_LA_HALF_H

#include <stdint.h>

enum { WT_PREC_F32 = 0, WT_PREC_F16 = 1, WT_PREC_BF16 = 2 };

/* "fp32", "fp16", "bf16" (the names of the configuration key recon.mvm_precision). */
const char *wt_prec_name(int prec);

/* One value: round to nearest, ties to even; beyond the largest finite value: ±Inf; NaN stays NaN. */
uint16_t wt_half_from_float(int prec, float v);
/* Exact (every fp16 and bf16 value is a float32). */
float wt_half_to_float(int prec, uint16_t h);
/* 1 when h is ±Inf or NaN. */
int wt_half_is_nonfinite(int prec, uint16_t h);

/* H (rows x cols) and c (rows) from the float32 row-major A as described above; a zero row gets c = 1.
 * A must be finite. */
void wt_half_pack(int prec, int64_t rows, int64_t cols, const float *A, uint16_t *H, float *c, int nthreads);

/* y = beta y + diag(c) H x (y: rows; beta = 0 ignores the old y, NaN included). float32 accumulation
 * in 8 lanes per row. Rows are split over nthreads OpenMP threads. */
void wt_half_gemv(int prec, int64_t rows, int64_t cols, const uint16_t *H, const float *c, const float *x, float beta,
                  float *y, int nthreads);

#endif
