/* core/solve/pcg.c: (P)CG, Hestenes–Stiefel form with the recursive residual (paper §6.1).
 *
 * Breakdown: in exact arithmetic pᵀAp > 0 and rᵀz > 0 until the residual is 0. In floating
 * point, with rtol = 0 and many iterations, the residual reaches rounding level and rᵀz underflows to 0
 * (then β = 0/0 = NaN poisons p) or pᵀAp rounds to ≤ 0. That is convergence, not a fault: the iteration
 * stops there with WT_WARN_BREAKDOWN, keeps the last iterate and reports the residual reached. Only a
 * pᵀAp ≤ 0 at the first iteration (A not positive definite) or a non-finite value is an error.
 * The recursive residual can also stall far below anything x can show without either going to 0: in the demo's
 * closed loop, frames whose ‖r‖/‖b‖ hovered at 1e-163 (rᵀz subnormal, each iteration slow) ran to any cap. The
 * true residual of an iterate is floored at ~ε (‖b‖ + ‖A‖ ‖x‖) ≥ ε ‖b‖, and a step of relative size ε² changes
 * no digit of x: so ‖r‖ ≤ ε² ‖b‖ (WT_PCG_ROUNDING) is rounding level reached too, with the same warning. */
#include "pcg.h"

#include <math.h>
#include <string.h>

#include "../la/vec.h"

#define WT_PCG_ROUNDING 0x1p-104 /* ε² of double: below it the recursive residual says nothing about x (above) */

#ifdef _OPENMP
#include <omp.h>
#endif

struct wt_pcg {
    wt_context *ctx;
    int64_t n;
    int nthreads; /* the context's thread count, for the vector updates */
    int r_valid;  /* r is b − A x of the last solve's b and x (up to its rounding drift) */
    double *r, *z, *p, *q;
    double *rhs;             /* 2 x n: the wt_pcg_solve_rhs right-hand sides, alternating */
    double *block;           /* the allocation r, z, p, q and rhs lie in, each at a 64-byte boundary */
    int64_t stride;          /* n rounded up to 8: from one vector of the block to the next */
    int cur;                 /* the half that holds the last wt_pcg_solve_rhs's */
    const double *cont_x;    /* that solve's unknowns while r belongs to them (else NULL) */
};

int wt_pcg_alloc(wt_context *ctx, int64_t n, wt_pcg **out)
{
    int st = WT_OK;
    wt_pcg *p = NULL;
    *out = NULL;
    if (n <= 0) return WT_ERROR(ctx, WT_ERR_INVALID, "pcg: size must be positive, got %lld", (long long)n);
    WT_ALLOC(ctx, p, 1, "pcg");
    p->ctx = ctx;
    p->n = n;
    p->nthreads = wt_context_threads(ctx);
    /* One block, every vector at a 64-byte boundary (8 doubles) whatever the allocator gives: the operators'
     * FFTs then run on the vectors' layers in place of copies (core/op/prior.c, core/model/precond.c: FFTW
     * executes a plan only on arrays of its planning alignment), and the vector passes start on cache lines. */
    const int64_t stride = p->stride = (n + 7) / 8 * 8;
    WT_ALLOC(ctx, p->block, 6 * stride + 8, "pcg vectors (r, z, p, q, 2 right-hand sides)");
    p->r = wt_align64(p->block);
    p->z = p->r + stride;
    p->p = p->z + stride;
    p->q = p->p + stride;
    p->rhs = p->q + stride; /* 2 x n, the second at rhs + stride (wt_pcg_solve_rhs) */
    *out = p;
    return WT_OK;
fail:
    wt_pcg_free(p);
    return st;
}

void wt_pcg_free(wt_pcg *p)
{
    if (!p) return;
    wt_free(p->ctx, p->block);
    wt_free(p->ctx, p);
}

double wt_pcg_flops_per_iteration(int64_t n, int preconditioned)
{
    /* 2 dots (pᵀq, rᵀz), 3 axpys (x, r, p) = 10n; the preconditioner adds n; ‖r‖ adds 2n */
    return (double)n * (12.0 + (preconditioned ? 1.0 : 0.0));
}

/* The vector work of an iteration runs on the solver's threads from PARALLEL_VECTORS_MIN unknowns on (PCG-3's E-ELT
 * 24576 included: serial dots and updates would otherwise be a visible part of an iteration), each dot as wt_vec_dot's fixed chunk sums split over the
 * threads (the same bits for any thread count), an update fused with the dot that follows it where both read
 * the same rows. */
enum {
    PARALLEL_VECTORS_MIN = 16384, /* unknowns from which an iteration's vector work is split over the threads */
    PARALLEL_UPDATE_MIN = 32768   /* the serial path's plain update takes the team above it: long enough a stream */
};
static int parallel_vectors(const wt_pcg *w) { return w->nthreads > 1 && w->n >= PARALLEL_VECTORS_MIN; }

/* This thread's chunks [c0, c1) of the WT_VEC_CHUNKS: whole groups of 8 (wt_vec_dot_part's side-by-side unit) */
static void my_chunks(int *c0, int *c1)
{
#ifdef _OPENMP
    const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
    const int nt = 1, id = 0;
#endif
    const int groups = WT_VEC_CHUNKS / 8;
    *c0 = 8 * (groups * id / nt);
    *c1 = 8 * (groups * (id + 1) / nt);
}

/* This thread's rows [*i0, *i1) of its chunks (my_chunks) */
static void my_rows(int64_t n, int64_t *i0, int64_t *i1)
{
    int c0, c1;
    my_chunks(&c0, &c1);
    const int64_t len = wt_vec_chunk_len(n);
    *i0 = c0 * len < n ? c0 * len : n;
    *i1 = c1 * len < n ? c1 * len : n;
}

static double dot(const wt_pcg *w, const double *a, const double *b)
{
    if (!parallel_vectors(w)) return wt_vec_dot(a, b, w->n);
    double part[WT_VEC_CHUNKS];
#pragma omp parallel num_threads(w->nthreads)
    {
        int c0, c1;
        my_chunks(&c0, &c1);
        wt_vec_dot_part(a, b, w->n, c0, c1, part);
    }
    return wt_vec_dot_finish(part);
}

/* mode 0: r −= a q (x's update waits for the pass over p: update_p); mode 1: r = (b − b_prev) + r (the continued
 * solve's initial residual; x, p, q unused), and with bb also bᵀb (the same chunk sums as dot(b, b), in the same
 * pass); then rᵀr. Each thread updates the rows of its own chunks, then sums them. */
static double update_r_norm2(const wt_pcg *w, int mode, double a, const double *q, double *r, const double *b,
                             const double *b_prev, double *bb)
{
    const int64_t n = w->n;
    if (!parallel_vectors(w)) {
        if (mode == 0)
#pragma omp parallel for schedule(static) if (n > PARALLEL_UPDATE_MIN) num_threads(w->nthreads)
            for (int64_t i = 0; i < n; i++) r[i] -= a * q[i];
        else
            for (int64_t i = 0; i < n; i++) r[i] = (b[i] - b_prev[i]) + r[i];
        if (bb) *bb = wt_vec_dot(b, b, n);
        return wt_vec_dot(r, r, n);
    }
    double part[WT_VEC_CHUNKS], bpart[WT_VEC_CHUNKS];
#pragma omp parallel num_threads(w->nthreads)
    {
        int c0, c1;
        int64_t i0, i1;
        my_chunks(&c0, &c1);
        my_rows(n, &i0, &i1);
        if (mode == 0)
            for (int64_t i = i0; i < i1; i++) r[i] -= a * q[i];
        else
            for (int64_t i = i0; i < i1; i++) r[i] = (b[i] - b_prev[i]) + r[i];
        if (bb) wt_vec_dot_part(b, b, n, c0, c1, bpart);
        wt_vec_dot_part(r, r, n, c0, c1, part);
    }
    if (bb) *bb = wt_vec_dot_finish(bpart);
    return wt_vec_dot_finish(part);
}

/* x += a p and then p = z + β p, in one pass over p (β = 0 and z = NULL: x += a p alone, at the solve's end).
 * x's update is the iteration's own (x + a p with the p of its step), only later: the same values. */
static void update_p(const wt_pcg *w, double a, double beta, const double *z, double *x, double *p)
{
    const int64_t n = w->n;
#pragma omp parallel for schedule(static) if (parallel_vectors(w)) num_threads(w->nthreads)
    for (int64_t i = 0; i < n; i++) {
        x[i] += a * p[i];
        if (z) p[i] = z[i] + beta * p[i];
    }
}

/* p = z, on the threads' chunks like the other updates (a copy: the same values) */
static void copy_vec(const wt_pcg *w, const double *z, double *p)
{
    const int64_t n = w->n;
#pragma omp parallel num_threads(w->nthreads) if (parallel_vectors(w))
    {
        int64_t i0, i1;
        my_rows(n, &i0, &i1);
        memcpy(p + i0, z + i0, (size_t)(i1 - i0) * sizeof *p);
    }
}

/* Inside a parallel region: xᵀy on the team (every thread its chunks' sums into part, a barrier, then every thread
 * adds them up in the same order: dot()'s bits), and this thread's chunks and rows for the update that follows */
static double team_dot(const wt_pcg *w, const double *x, const double *y, double *part, int *c0, int *c1, int64_t *i0,
                       int64_t *i1)
{
    my_chunks(c0, c1);
    my_rows(w->n, i0, i1);
    wt_vec_dot_part(x, y, w->n, *c0, *c1, part);
#pragma omp barrier
    return wt_vec_dot_finish(part);
}

/* An iteration's step after q = A p, on the threads (parallel_vectors): pᵀq, then, where it is finite and > 0,
 * a = rz / pᵀq, r −= a q and rᵀr, in one parallel region (the dot's chunk sums, a barrier, and every thread adds
 * them up in the same order: the bits of dot() and update_r_norm2()). *pq always; *a and *rr only then (else r is
 * untouched). */
static void step_r(const wt_pcg *w, const double *p, const double *q, double rz, double *r, double *pq, double *a,
                   double *rr)
{
    const int64_t n = w->n;
    double part[WT_VEC_CHUNKS], rpart[WT_VEC_CHUNKS];
    double pq_ = 0.0;
#pragma omp parallel num_threads(w->nthreads)
    {
        int c0, c1;
        int64_t i0, i1;
        const double v = team_dot(w, p, q, part, &c0, &c1, &i0, &i1);
        if (isfinite(v) && v > 0.0) {
            const double av = rz / v;
            for (int64_t i = i0; i < i1; i++) r[i] -= av * q[i];
            wt_vec_dot_part(r, r, n, c0, c1, rpart);
        }
#pragma omp master
        pq_ = v;
    }
    *pq = pq_;
    if (isfinite(pq_) && pq_ > 0.0) {
        *a = rz / pq_;
        *rr = wt_vec_dot_finish(rpart);
    }
}

/* The step after z = P⁻¹ r, on the threads: rᵀz, then x += a p and, where rᵀz is > 0, p = z + (rᵀz / rz) p (else
 * x's update alone), in one parallel region as step_r (the bits of dot() and update_p()) */
static double step_p(const wt_pcg *w, const double *r, const double *z, double rz, double a, double *x, double *p)
{
    double part[WT_VEC_CHUNKS];
    double rz_ = 0.0;
#pragma omp parallel num_threads(w->nthreads)
    {
        int c0, c1;
        int64_t i0, i1;
        const double v = team_dot(w, r, z, part, &c0, &c1, &i0, &i1);
        if (v > 0.0) {
            const double beta = v / rz;
            for (int64_t i = i0; i < i1; i++) {
                x[i] += a * p[i];
                p[i] = z[i] + beta * p[i];
            }
        } else
            for (int64_t i = i0; i < i1; i++) x[i] += a * p[i];
#pragma omp master
        rz_ = v;
    }
    return rz_;
}

static int solve(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                 const double *b, const double *b_prev, double *x, int max_iter, double rtol, double *history,
                 wt_pcg_result *res);

int wt_pcg_solve(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, const double *b, double *x,
                 int max_iter, double rtol, double *history, wt_pcg_result *res)
{
    return solve(w, A, user, inv_diag, NULL, NULL, b, NULL, x, max_iter, rtol, history, res);
}

int wt_pcg_solve_precond(wt_pcg *w, wt_linop_fn A, void *user, wt_precond_fn P, void *puser, const double *b,
                         double *x, int max_iter, double rtol, double *history, wt_pcg_result *res)
{
    return solve(w, A, user, NULL, P, puser, b, NULL, x, max_iter, rtol, history, res);
}

double *wt_pcg_rhs(wt_pcg *w) { return w->rhs + w->stride * (w->cur ^ 1); }

int wt_pcg_solve_rhs(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                     double *x, int continuing, int max_iter, double rtol, double *history, wt_pcg_result *res)
{
    if (inv_diag && P) return WT_ERROR(w->ctx, WT_ERR_INVALID, "pcg: give a Jacobi diagonal or a preconditioner, not both");
    const double *b = wt_pcg_rhs(w), *b_prev = continuing && x == w->cont_x ? w->rhs + w->stride * w->cur : NULL;
    w->cur ^= 1;
    int st = solve(w, A, user, inv_diag, P, puser, b, b_prev, x, max_iter, rtol, history, res);
    w->cont_x = st >= 0 ? x : NULL;
    return st;
}

/* Stop at a breakdown after `done` iterations: x holds the last iterate, res its residual. */
static int breakdown(wt_pcg *w, const char *what, double v, int done, const wt_pcg_result *res)
{
    return WT_ERROR(w->ctx, WT_WARN_BREAKDOWN,
                    "pcg: stopped after %d iterations: %s = %g, no longer > 0 (rounding level reached); relative "
                    "residual %.3g kept", done, what, v, res->rel_resid);
}

/* The solve, with r kept consistent with x (r_valid) on every non-error return, so that the next solve may
 * continue from it; any error leaves r_valid 0. */
static int solve_body(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                      const double *b, const double *b_prev, double *x, int max_iter, double rtol, double *history,
                      wt_pcg_result *res);

static int solve(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                 const double *b, const double *b_prev, double *x, int max_iter, double rtol, double *history,
                 wt_pcg_result *res)
{
    const int can_continue = b_prev != NULL && w->r_valid;
    w->r_valid = 0;
    w->cont_x = NULL; /* wt_pcg_solve_rhs sets it again after its own solves */
    int st = solve_body(w, A, user, inv_diag, P, puser, b, can_continue ? b_prev : NULL, x, max_iter, rtol, history, res);
    w->r_valid = st >= 0;
    return st;
}

static int solve_body(wt_pcg *w, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                      const double *b, const double *b_prev, double *x, int max_iter, double rtol, double *history,
                      wt_pcg_result *res)
{
    const int64_t n = w->n;
    double *r = w->r, *z = w->z, *p = w->p, *q = w->q;
    wt_pcg_result local = {0, 0.0};
    if (!res) res = &local;
    res->iterations = 0;
    res->rel_resid = 0.0;
    if (max_iter < 0 || !(rtol >= 0.0))
        return WT_ERROR(w->ctx, WT_ERR_INVALID, "pcg: iteration cap %d and tolerance %g must be >= 0", max_iter, rtol);

    /* continued: A x = b_prev − r_prev, so r = b − b_prev + r_prev in place, in the pass that sums bᵀb (r is
     * kept consistent with x below on every return, as the caller requires) */
    double bb, rr = 0.0;
    if (b_prev) rr = update_r_norm2(w, 1, 0.0, NULL, r, b, b_prev, &bb);
    else bb = dot(w, b, b);
    double bnorm = sqrt(bb);
    if (!isfinite(bnorm)) return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: right-hand side holds NaN or Inf");
    if (bnorm == 0.0) {
        for (int64_t i = 0; i < n; i++) x[i] = r[i] = 0.0;
        if (history) history[0] = 0.0;
        return WT_OK;
    }
    double rnorm;
    if (b_prev) {
        rnorm = sqrt(rr);
    } else {
        A(user, x, q);
        for (int64_t i = 0; i < n; i++) r[i] = b[i] - q[i];
        rnorm = sqrt(dot(w, r, r));
    }
    if (!isfinite(rnorm)) return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: initial guess gives a non-finite residual");
    if (history) history[0] = rnorm / bnorm;
    res->rel_resid = rnorm / bnorm;
    if (rtol > 0.0 && rnorm <= rtol * bnorm) return WT_OK;

    if (inv_diag)
        for (int64_t i = 0; i < n; i++) z[i] = inv_diag[i] * r[i];
    else if (P) P(puser, r, z);
    const double *zz = (inv_diag || P) ? z : r;
    copy_vec(w, zz, p);
    double rz = dot(w, r, zz);

    int k;
    const int fused = parallel_vectors(w);
    for (k = 0; k < max_iter; k++) {
        A(user, p, q);
        double pq, a = 0.0, rr2 = 0.0;
        if (fused) step_r(w, p, q, rz, r, &pq, &a, &rr2);
        else pq = dot(w, p, q);
        if (!isfinite(pq))
            return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: pᵀAp = %g at iteration %d (the operator returned NaN or Inf)",
                            pq, k + 1);
        if (!(pq > 0.0) && k > 0) return breakdown(w, "pᵀAp", pq, k, res);
        if (!(pq > 0.0))
            return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: pᵀAp = %g at iteration 1 (operator not positive definite)", pq);
        if (!fused) {
            a = rz / pq;
            rr2 = update_r_norm2(w, 0, a, q, r, NULL, NULL, NULL);
        }
        rnorm = sqrt(rr2);
        res->iterations = k + 1;
        res->rel_resid = rnorm / bnorm;
        if (history) history[k + 1] = rnorm / bnorm;
        /* from here x still waits for + a p: every return below gives it first */
        if (!isfinite(rnorm)) {
            update_p(w, a, 0.0, NULL, x, p);
            return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: residual became non-finite at iteration %d", k + 1);
        }
        if (rnorm <= WT_PCG_ROUNDING * bnorm && !(rtol > 0.0 && rnorm <= rtol * bnorm) && rnorm != 0.0) {
            update_p(w, a, 0.0, NULL, x, p);
            return WT_ERROR(w->ctx, WT_WARN_BREAKDOWN, "pcg: stopped after %d iterations: relative residual %.3g, "
                            "below ε² (rounding level reached)", k + 1, res->rel_resid);
        }
        if ((rtol > 0.0 && rnorm <= rtol * bnorm) || rnorm == 0.0 || k + 1 == max_iter) {
            update_p(w, a, 0.0, NULL, x, p); /* (rnorm = 0: exact solution, nothing left to do, rtol = 0 included) */
            if (k + 1 == max_iter && !(rtol > 0.0 && rnorm <= rtol * bnorm) && rnorm != 0.0) break;
            return WT_OK;
        }
        if (inv_diag)
            for (int64_t i = 0; i < n; i++) z[i] = inv_diag[i] * r[i];
        else if (P) P(puser, r, z);
        /* fused: rᵀz and the updates of x and p in one pass (x's alone where rᵀz is not > 0, as below) */
        double rz_new = fused ? step_p(w, r, zz, rz, a, x, p) : dot(w, r, zz);
        if (!(rz_new > 0.0)) { /* rounding level reached (or a preconditioner that is not SPD: first iteration) */
            if (!fused) update_p(w, a, 0.0, NULL, x, p);
            if (!isfinite(rz_new))
                return WT_ERROR(w->ctx, WT_ERR_NUMERIC, "pcg: rᵀz = %g at iteration %d (the preconditioner returned NaN "
                                "or Inf)", rz_new, k + 1);
            return breakdown(w, "rᵀz", rz_new, k + 1, res);
        }
        double beta = rz_new / rz;
        rz = rz_new;
        if (!fused) update_p(w, a, beta, zz, x, p);
    }
    return rtol > 0.0 ? WT_WARN_MAXITER : WT_OK;
}
