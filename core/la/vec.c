/* core/la/vec.c: order-fixed reductions (see vec.h for why).
 *
 * A chunk's sum is one serial chain of additions, so one chunk at a time runs at the adder's latency
 * (3–4 cycles per element). The chunks are independent: the kernels below run 8 of them side by side
 * (8 chains in registers), each still summed in its own index order, which is the same arithmetic
 * (bit for bit) at about the load ports' rate instead. */
#include "vec.h"

#include <math.h>

#include "../base/base.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum { SIDE = 8 }; /* chunks summed side by side */
/* Lengths above which a call takes a thread team: below, the region's start and end cost more than the pass over
 * the vectors saves (a pass with more arrays pays sooner). The chunk sums make the bits independent of them. */
enum {
    DOT_PARALLEL_MIN = 32768,  /* wt_vec_dot: two arrays read */
    MANY_PARALLEL_MIN = 8192,  /* wt_vec_dot_many, wt_vec_sub_many: q + 1 arrays */
    GROUPS_PARALLEL_MIN = 16384 /* wt_vec_sum_groups: the groups' accumulators */
};

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
#pragma omp parallel if (n > DOT_PARALLEL_MIN)
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

int64_t wt_vec_chunk_len(int64_t n) { return (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS; }

void wt_vec_dot_part(const double *x, const double *y, int64_t n, int c0, int c1, double *part)
{
    chunk_dots(x, y, n, wt_vec_chunk_len(n), c0, c1, part);
}

double wt_vec_dot_finish(const double *part) { return sum_parts(part); }

/* s[k] += Σ_{i ∈ [a, b)} X_k[i] y[i] for k < B, B a compile-time constant (always inlined from the
 * switch below): the B sums are B chains in registers, each in index order. */
static inline __attribute__((always_inline)) void dots_block(const int B, const double *restrict X, int64_t ld,
                                                             const double *restrict y, int64_t a, int64_t b,
                                                             double *restrict s)
{
    double acc[16];
    for (int k = 0; k < B; k++) acc[k] = s[k];
    for (int64_t i = a; i < b; i++) {
        const double v = y[i];
        for (int k = 0; k < B; k++) acc[k] += X[(int64_t)k * ld + i] * v;
    }
    for (int k = 0; k < B; k++) s[k] = acc[k];
}

/* Runs [runs[2j], runs[2j+1]) are sorted and disjoint (NULL runs: the one run [0, n)); the kernels below
 * visit those that meet [a, b), clipped to it, starting at first_run: the first run ending after a. */
static int first_run(const int64_t *runs, int nruns, int64_t a)
{
    int lo = 0, hi = nruns;
    while (lo < hi) {
        const int mid = (lo + hi) / 2;
        if (runs[2 * mid + 1] <= a) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static void dots_range(const double *X, int64_t ld, int q, const double *y, int64_t a, int64_t b, double *s)
{
    int k = 0;
    for (; q - k >= 12; k += 12) dots_block(12, X + (int64_t)k * ld, ld, y, a, b, s + k);
    for (; q - k >= 8; k += 8) dots_block(8, X + (int64_t)k * ld, ld, y, a, b, s + k);
    for (; q - k >= 4; k += 4) dots_block(4, X + (int64_t)k * ld, ld, y, a, b, s + k);
    for (; k < q; k++) dots_block(1, X + (int64_t)k * ld, ld, y, a, b, s + k);
}

void wt_vec_dot_many_part(const double *X, int64_t ld, int q, const double *y, int64_t n, const int64_t *runs,
                          int nruns, int c0, int c1, double *part)
{
    const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS;
    for (int c = c0; c < c1; c++) {
        const int64_t a = (int64_t)c * len, b = a + len < n ? a + len : n;
        double s[WT_VEC_MAX_MANY];
        for (int k = 0; k < q; k++) s[k] = 0.0;
        if (!runs) {
            if (a < b) dots_range(X, ld, q, y, a, b, s);
        } else
            for (int j = first_run(runs, nruns, a); j < nruns && runs[2 * j] < b; j++) {
                const int64_t lo = runs[2 * j] > a ? runs[2 * j] : a, hi = runs[2 * j + 1] < b ? runs[2 * j + 1] : b;
                dots_range(X, ld, q, y, lo, hi, s);
            }
        for (int k = 0; k < q; k++) part[(int64_t)k * WT_VEC_CHUNKS + c] = s[k];
    }
}

void wt_vec_dot_many_finish(int q, const double *part, double *out)
{
    for (int k = 0; k < q; k++) out[k] = sum_parts(part + (int64_t)k * WT_VEC_CHUNKS);
}

void wt_vec_dot_many(const double *X, int64_t ld, int q, const double *y, int64_t n, const int64_t *runs, int nruns,
                     double *out, int nthreads)
{
    double part[WT_VEC_MAX_MANY * WT_VEC_CHUNKS];
#pragma omp parallel num_threads(nthreads > 0 ? nthreads : 1) if (n > MANY_PARALLEL_MIN)
    {
#ifdef _OPENMP
        const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
        const int nt = 1, id = 0;
#endif
        wt_vec_dot_many_part(X, ld, q, y, n, runs, nruns, WT_VEC_CHUNKS * id / nt, WT_VEC_CHUNKS * (id + 1) / nt, part);
    }
    wt_vec_dot_many_finish(q, part, out);
}

/* z[i] ← z[i] − Σ_k v_k X_k[i] over [a, b), columns in order, four per pass */
static void sub_range(double *restrict z, const double *restrict X, int64_t ld, int q, const double *v, int64_t a,
                      int64_t b)
{
    int k = 0;
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

void wt_vec_sub_many_range(double *z, const double *X, int64_t ld, int q, const double *v, const int64_t *runs,
                           int nruns, int64_t i0, int64_t i1)
{
    if (!runs) {
        if (i0 < i1) sub_range(z, X, ld, q, v, i0, i1);
        return;
    }
    int64_t at = i0; /* rows in [i0, at) are done */
    for (int j = first_run(runs, nruns, i0); at < i1; j++) {
        const int64_t lo = j < nruns && runs[2 * j] < i1 ? (runs[2 * j] > at ? runs[2 * j] : at) : i1;
        /* rows [at, lo) hold zeros in every column: z − v_k·(±0) = z, except −0 − (−0) = +0: a −0 takes
         * the full update (+0 − (±0) = +0; +0 is common here: rows no sensor sees keep r = z = +0) */
        for (int64_t i = at; i < lo; i++)
            if (z[i] == 0.0 && signbit(z[i])) sub_range(z, X, ld, q, v, i, i + 1);
        if (lo == i1) break;
        const int64_t hi = runs[2 * j + 1] < i1 ? runs[2 * j + 1] : i1;
        sub_range(z, X, ld, q, v, lo, hi);
        at = hi;
    }
}

void wt_vec_sub_many(double *z, const double *X, int64_t ld, int q, const double *v, int64_t n, const int64_t *runs,
                     int nruns, int nthreads)
{
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1) if (n > MANY_PARALLEL_MIN)
    for (int c = 0; c < WT_VEC_CHUNKS; c++) {
        const int64_t len = (n + WT_VEC_CHUNKS - 1) / WT_VEC_CHUNKS, a = (int64_t)c * len, b = a + len < n ? a + len : n;
        wt_vec_sub_many_range(z, X, ld, q, v, runs, nruns, a, b);
    }
}

int wt_vec_runs(const double *X, int64_t ld, int q, int64_t n, int64_t *runs)
{
    int nruns = 0, open = 0;
    for (int64_t i = 0; i < n; i++) {
        int nz = 0;
        for (int k = 0; k < q && !nz; k++) nz = X[(int64_t)k * ld + i] != 0.0;
        if (nz && !open) runs[2 * nruns] = i;
        if (!nz && open) runs[2 * nruns++ + 1] = i;
        open = nz;
    }
    if (open) runs[2 * nruns++ + 1] = n;
    return nruns;
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

/* Σ 0·x_i over 8 lanes: +0 or −0 while every x_i is finite, NaN once one is NaN or ±Inf (0·Inf = NaN), in any
 * order; a loop without the early exit of a per-element test, so it vectorises. Then the first bad index. */
WT_CPU_CLONES int64_t wt_vec_first_nonfinite(const double *x, int64_t n)
{
    double lane[8] = {0.0};
    int64_t i = 0;
    for (; i + 8 <= n; i += 8)
        for (int e = 0; e < 8; e++) lane[e] += 0.0 * x[i + e];
    for (; i < n; i++) lane[0] += 0.0 * x[i];
    double s = 0.0;
    for (int e = 0; e < 8; e++) s += lane[e];
    if (s == 0.0) return -1;
    for (i = 0; i < n; i++)
        if (!isfinite(x[i])) return i;
    return -1; /* not reached: a NaN sum has a non-finite term */
}

void wt_vec_sum_groups(const double *acc, int64_t n, double *out)
{
#pragma omp parallel for schedule(static) if (n > GROUPS_PARALLEL_MIN)
    for (int64_t i = 0; i < n; i++) {
        double v = acc[i];
        for (int g = 1; g < WT_GROUPS; g++) v += acc[(int64_t)g * n + i];
        out[i] = v;
    }
}
