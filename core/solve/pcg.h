/* core/solve/pcg.h: conjugate gradients and Jacobi-preconditioned CG for symmetric positive definite
 * operators given as callbacks (paper §6.1: CG for eqn_lse, PCG with the modified Jacobi J).
 *
 * The workspace is allocated once for a size n; wt_pcg_solve allocates nothing, so it can run every
 * frame. Warm start: x holds the initial guess on entry (the previous frame's solution).
 */
#ifndef WT_PCG_H
#define WT_PCG_H

#include "../base/base.h"

/* y = A x  (y must be fully overwritten). */
typedef void (*wt_linop_fn)(void *user, const double *x, double *y);

typedef struct wt_pcg wt_pcg;

int wt_pcg_alloc(wt_context *ctx, int64_t n, wt_pcg **out);
void wt_pcg_free(wt_pcg *p);

typedef struct wt_pcg_result {
    int iterations;   /* iterations done */
    double rel_resid; /* ‖b − A x‖ / ‖b‖ of the recursive residual at exit */
} wt_pcg_result;

/* Solve A x = b.
 *   inv_diag: NULL for plain CG, else the inverse of the Jacobi diagonal (preconditioner M⁻¹ = diag).
 *   max_iter: iteration cap (≥ 0); rtol: stop when ‖r‖/‖b‖ ≤ rtol (0: always run max_iter).
 *   history: NULL or max_iter + 1 doubles: ‖r_k‖/‖b‖ for k = 0 … iterations.
 * Returns WT_OK (also when the residual becomes exactly 0), WT_WARN_MAXITER when rtol > 0 was not
 * reached, WT_WARN_BREAKDOWN when after the first iteration pᵀAp or rᵀz stops being > 0 (the iteration
 * has converged to rounding level, e.g. rtol = 0 and thousands of iterations): x is the last iterate and
 * res->rel_resid its residual; WT_ERR_NUMERIC on a non-finite value or pᵀAp ≤ 0 at the first iteration
 * (A not positive definite). b = 0 gives x = 0. */
int wt_pcg_solve(wt_pcg *p, wt_linop_fn A, void *user, const double *inv_diag, const double *b, double *x,
                 int max_iter, double rtol, double *history, wt_pcg_result *res);

/* z = P⁻¹ r for a symmetric positive definite preconditioner P (z fully overwritten). */
typedef void (*wt_precond_fn)(void *user, const double *r, double *z);
/* A preconditioner handed through a caller that does not know its kind (the tomography's solve; the kinds are
 * core/model/precond.h's): apply NULL means none, plain CG. */
typedef struct wt_pcg_precond {
    wt_precond_fn apply;
    void *user;
} wt_pcg_precond;
/* The same with a general preconditioner P⁻¹ given as a callback. */
int wt_pcg_solve_precond(wt_pcg *p, wt_linop_fn A, void *user, wt_precond_fn P, void *puser, const double *b,
                         double *x, int max_iter, double rtol, double *history, wt_pcg_result *res);
/* Frame after frame (the reconstructor's warm start, paper §6.1), the workspace holds the right-hand side:
 * the caller writes it into wt_pcg_rhs(p) (n values; the buffer alternates between two halves, so the
 * previous solve's stays) and calls wt_pcg_solve_rhs. With `continuing` set and x the unchanged result of
 * the previous wt_pcg_solve_rhs on this workspace, that solve's recursive residual r_prev gives
 * A x = b_prev − r_prev, which replaces the initial apply of A: one apply per solve saved (of 5 in a
 * 4-iteration frame). The image differs from A x by the recursive residual's rounding drift, not by more;
 * the iterates are not bit-identical to a fresh solve's. Otherwise (continuing 0, the first solve, one
 * after an error or after a wt_pcg_solve*, other unknowns x) A x is applied: the same bits as wt_pcg_solve
 * (inv_diag) or wt_pcg_solve_precond (P); at most one of the two. */
double *wt_pcg_rhs(wt_pcg *p);
int wt_pcg_solve_rhs(wt_pcg *p, wt_linop_fn A, void *user, const double *inv_diag, wt_precond_fn P, void *puser,
                     double *x, int continuing, int max_iter, double rtol, double *history, wt_pcg_result *res);
/* Flops of one iteration outside the operator (vector updates, dots, preconditioner): for reports. */
double wt_pcg_flops_per_iteration(int64_t n, int preconditioned);

#endif
