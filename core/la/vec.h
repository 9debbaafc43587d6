/* core/la/vec.h: vector kernels whose results do not depend on the thread count or scheduling.
 *
 * Floating-point sums depend on their order. OpenMP's reduction clause and per-thread accumulators
 * filled under dynamic scheduling combine partial sums in an order that changes from run to run, so
 * the same seed would not give the same numbers. These kernels fix the order instead: a dot product
 * is the ordered sum of WT_VEC_CHUNKS fixed chunk sums; scatter-adds go into WT_GROUPS fixed groups
 * (each item processed by one group, in index order) that are summed in group order.
 */
#ifndef WT_VEC_H
#define WT_VEC_H

#include <stdint.h>

#define WT_VEC_CHUNKS 64
/* Two groups balance the 6 LGS of the E-ELT (3 + 3) and the 25 fitting directions (13 + 12) over the
 * 2 cores this project targets; more groups would cost a zeroed n-vector each per application. */
#define WT_GROUPS 2

/* Σ x_i y_i, parallel for long vectors, bit-identical for any thread count. */
double wt_vec_dot(const double *x, const double *y, int64_t n);
/* wt_vec_dot in pieces for a caller's own parallel region: the chunk sums of chunks [c0, c1) into part
 * (WT_VEC_CHUNKS slots; 8 chunks side by side, as wt_vec_dot), and their ordered total; the chunks' rows:
 * chunk c is [c len, min((c + 1) len, n)), len = wt_vec_chunk_len(n). The same bits as wt_vec_dot whatever
 * the split of the chunks. */
int64_t wt_vec_chunk_len(int64_t n);
void wt_vec_dot_part(const double *x, const double *y, int64_t n, int c0, int c1, double *part);
double wt_vec_dot_finish(const double *part);

/* Dots of q ≤ WT_VEC_MAX_MANY columns X_k = X + k ld against one y, and the fused update
 * z ← z − Σ_k v_k X_k (each element taking the columns in order k = 0, 1, …): the same bits as q calls
 * of wt_vec_dot and q axpys in a row, in one pass each (the q sums side by side).
 * runs (optional, NULL = all rows): sorted disjoint row ranges [runs[2j], runs[2j+1]), j < nruns, outside
 * which every column is zero (wt_vec_runs finds them); those rows are skipped where that keeps the bits
 * (a sum that starts at +0 never becomes −0, so adding 0·y_i changes nothing for finite y). The plain forms
 * run on nthreads threads when n > 8192; the _part / _range forms are serial pieces for a caller's own
 * parallel region: dots over the chunks [c0, c1) of the WT_VEC_CHUNKS into part (q x WT_VEC_CHUNKS,
 * k major), summed by _finish; the update over the rows [i0, i1). */
#define WT_VEC_MAX_MANY 64
void wt_vec_dot_many(const double *X, int64_t ld, int q, const double *y, int64_t n, const int64_t *runs, int nruns,
                     double *out, int nthreads);
void wt_vec_dot_many_part(const double *X, int64_t ld, int q, const double *y, int64_t n, const int64_t *runs,
                          int nruns, int c0, int c1, double *part);
void wt_vec_dot_many_finish(int q, const double *part, double *out);
void wt_vec_sub_many(double *z, const double *X, int64_t ld, int q, const double *v, int64_t n, const int64_t *runs,
                     int nruns, int nthreads);
void wt_vec_sub_many_range(double *z, const double *X, int64_t ld, int q, const double *v, const int64_t *runs,
                           int nruns, int64_t i0, int64_t i1);
/* The runs of rows i < n where some column X_k[i] (k < q) is non-zero; runs needs room for n + 1 values
 * (at most ⌈n/2⌉ runs). Returns their number. */
int wt_vec_runs(const double *X, int64_t ld, int q, int64_t n, int64_t *runs);

/* Assign n items of the given costs to WT_GROUPS groups of about equal cost (greedy, largest first,
 * deterministic). group[i] ∈ [0, WT_GROUPS). */
void wt_vec_groups(int n, const double *cost, int *group);

/* The first i < n with x_i NaN or ±Inf, -1 when all are finite (one vectorised pass when they are). */
int64_t wt_vec_first_nonfinite(const double *x, int64_t n);

/* out[i] = Σ_g acc[g * n + i] in group order. */
void wt_vec_sum_groups(const double *acc, int64_t n, double *out);

#endif
