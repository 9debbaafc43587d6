/* core/la/vec.c: order-fixed reductions (see vec.h for why). */
#include "vec.h"

double wt_vec_dot(const double *x, const double *y, int64_t n)
{
    double part[WT_VEC_CHUNKS];
    const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS;
#pragma omp parallel for schedule(static) if (n > 32768)
    for (int c = 0; c < WT_VEC_CHUNKS; c++) {
        int64_t a = c * len, b = a + len < n ? a + len : n;
        double s = 0.0;
        for (int64_t i = a; i < b; i++) s += x[i] * y[i];
        part[c] = s;
    }
    double s = 0.0;
    for (int c = 0; c < WT_VEC_CHUNKS; c++) s += part[c];
    return s;
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
