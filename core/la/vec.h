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

/* out[k] = wt_vec_dot(X + k ld, y, n) for k < q, bit for bit, with the q sums side by side in one pass
 * over y (WT_VEC_MANY at a time); on nthreads threads when n > 8192. */
#define WT_VEC_MANY 16
void wt_vec_dot_many(const double *X, int64_t ld, int q, const double *y, int64_t n, double *out, int nthreads);

/* z ← z − Σ_k v_k X_k (X_k = X + k ld, k < q), each element taking the columns in order k = 0, 1, …: the
 * same bits as q axpys in a row, in one pass over z; on nthreads threads when n > 8192. */
void wt_vec_sub_many(double *z, const double *X, int64_t ld, int q, const double *v, int64_t n, int nthreads);

/* Assign n items of the given costs to WT_GROUPS groups of about equal cost (greedy, largest first,
 * deterministic). group[i] ∈ [0, WT_GROUPS). */
void wt_vec_groups(int n, const double *cost, int *group);

/* out[i] = Σ_g acc[g * n + i] in group order. */
void wt_vec_sum_groups(const double *acc, int64_t n, double *out);

#endif
