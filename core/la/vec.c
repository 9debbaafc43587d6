/* core/la/vec.c: order-fixed reductions (see vec.h for why).
 *
 * A chunk's sum is one serial chain of additions, so one chunk at a time runs at the adder's latency
 * (3–4 cycles per element). The chunks are independent: the kernels below run 8 of them side by side
 * (8 chains in registers), each still summed in its own index order, which is the same arithmetic
 * (bit for bit) at about the load ports' rate instead. */
#include "vec.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum { SIDE = 8 }; /* chunks summed side by side */

/* part[c] = Σ_{i ∈ chunk c} x_i y_i for c in [c0, c1), chunk c = [c len, min(c len + len, n)) */
static void chunk_dots(const double *restrict x, const double *restrict y, int64_t n, int64_t len, int c0, int c1,
                       double *restrict part)
{
    int c = c0;
    for (; c + SIDE <= c1 && (int64_t)(c + SIDE) * len <= n; c += SIDE) {
        const double *xs = x + (int64_t)c * len, *ys = y + (int64_t)c * len;
        double s[SIDE] = {0.0};
        for (int64_t i = 0; i < len; i++)
            for (int k = 0; k < SIDE; k++) s[k] += xs[k * len + i] * ys[k * len + i];
        for (int k = 0; k < SIDE; k++) part[c + k] = s[k];
    }
    for (; c < c1; c++) {
        int64_t a = (int64_t)c * len, b = a + len < n ? a + len : n;
        double s = 0.0;
        for (int64_t i = a; i < b; i++) s += x[i] * y[i];
        part[c] = s;
    }
}

static double sum_parts(const double *part)
{
    double s = 0.0;
    for (int c = 0; c < WT_VEC_CHUNKS; c++) s += part[c];
    return s;
}

double wt_vec_dot(const double *x, const double *y, int64_t n)
{
    double part[WT_VEC_CHUNKS];
    const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS;
#pragma omp parallel if (n > 32768)
    {
#ifdef _OPENMP
        const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
        const int nt = 1, id = 0;
#endif
        /* contiguous whole groups of SIDE chunks per thread */
        const int groups = WT_VEC_CHUNKS / SIDE, g0 = groups * id / nt, g1 = groups * (id + 1) / nt;
        chunk_dots(x, y, n, len, g0 * SIDE, g1 * SIDE, part);
    }
    return sum_parts(part);
}

void wt_vec_dot_many(const double *X, int64_t ld, int q, const double *y, int64_t n, double *out, int nthreads)
{
    double part[WT_VEC_MANY][WT_VEC_CHUNKS];
    const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS;
    for (int k0 = 0; k0 < q; k0 += WT_VEC_MANY) {
        const int qk = q - k0 < WT_VEC_MANY ? q - k0 : WT_VEC_MANY;
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1) if (n > 8192)
        for (int c = 0; c < WT_VEC_CHUNKS; c++) {
            const int64_t a = (int64_t)c * len, b = a + len < n ? a + len : n;
            double s[WT_VEC_MANY] = {0.0};
            /* qk chains side by side over one chunk of y, each in index order */
            for (int64_t i = a; i < b; i++) {
                const double v = y[i];
                for (int k = 0; k < qk; k++) s[k] += X[(int64_t)(k0 + k) * ld + i] * v;
            }
            for (int k = 0; k < qk; k++) part[k][c] = s[k];
        }
        for (int k = 0; k < qk; k++) out[k0 + k] = sum_parts(part[k]);
    }
}

void wt_vec_sub_many(double *z, const double *X, int64_t ld, int q, const double *v, int64_t n, int nthreads)
{
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1) if (n > 8192)
    for (int c = 0; c < WT_VEC_CHUNKS; c++) {
        const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS, a = (int64_t)c * len, b = a + len < n ? a + len : n;
        int k = 0;
        /* four columns per pass, each element taking them in column order */
        for (; k + 4 <= q; k += 4) {
            const double *restrict x0 = X + (int64_t)k * ld, *restrict x1 = x0 + ld, *restrict x2 = x1 + ld,
                         *restrict x3 = x2 + ld;
            const double v0 = v[k], v1 = v[k + 1], v2 = v[k + 2], v3 = v[k + 3];
            for (int64_t i = a; i < b; i++) z[i] = (((z[i] - v0 * x0[i]) - v1 * x1[i]) - v2 * x2[i]) - v3 * x3[i];
        }
        for (; k < q; k++) {
            const double *restrict xk = X + (int64_t)k * ld, vk = v[k];
            for (int64_t i = a; i < b; i++) z[i] -= vk * xk[i];
        }
    }
}

void wt_vec_groups(int n, const double *cost, int *group)
{
    double load[WT_GROUPS] = {0};
    for (int i = 0; i < n; i++) group[i] = -1;
    for (int k = 0; k < n; k++) {
        /* the most expensive unassigned item (lowest index on ties) to the least loaded group */
        int best = -1;
        for (int i = 0; i < n; i++)
            if (group[i] < 0 && (best < 0 || cost[i] > cost[best])) best = i;
        int g = 0;
        for (int j = 1; j < WT_GROUPS; j++)
            if (load[j] < load[g]) g = j;
        group[best] = g;
        load[g] += cost[best];
    }
}

void wt_vec_sum_groups(const double *acc, int64_t n, double *out)
{
#pragma omp parallel for schedule(static) if (n > 16384)
    for (int64_t i = 0; i < n; i++) {
        double v = acc[i];
        for (int g = 1; g < WT_GROUPS; g++) v += acc[(int64_t)g * n + i];
        out[i] = v;
    }
}
