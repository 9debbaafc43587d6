/* core/model/learn_wind.c: the wind of each identified layer from the time-lagged LGS cross-covariance maps (SPEC
 * §12, "Wind"; the model in core/model/learn.h).
 *
 * Under frozen flow the layer at h moves by s = v_h k Δt in k frames, so that the lag-k map of the ordered pair
 * (i, j) is
 *
 *   C_ij^c(δ; k) = Σ_l a_l Σ_{h ∈ l} c_h R_ij^c(δ; h, v_l k Δt) + ε,
 *
 * R the response of a unit layer at the displacement δ d (1 − h/H) + (θ_j − θ_i) h − s (learn_response.c), c_h the
 * profile fit's, a_l an amplitude per layer (1 when the lagged maps hold the profile fit's Cn²: it frees the wind
 * from that fit's errors, e.g. a layer it under-estimates). What is fitted is the lag-k map less the lag-0 map of
 * the same frames, D_k = C(δ; k) − C(δ; 0), against Σ_l a_l Σ_h c_h (R(δ; h, s_l) − R(δ; h, 0)): ε is mostly the
 * realisation of the large scales, broad in δ and, under frozen flow, the lag-0 error moved by s, so that the
 * difference cancels it to first order in s and keeps what v moves (load_maps). δ = 0 of the auto pairs is left
 * out (the lag-0 map holds the noise's variance there). The unknowns p = (a_1 … a_L, v_1x, v_1y, …) minimise
 *
 *   Φ(p) = Σ_{k,i,j,c,δ ∈ U} w(δ) (D_k − model)²,   w = P(δ)/P(0),
 *
 * by Levenberg–Marquardt on the normal equations (JᵀWJ + λ diag) Δp = JᵀW r; ∂R/∂s analytic (of the tabulated
 * D, through the same linear tip-tilt removal). The layers are fitted jointly: they overlap in every map (their
 * peaks sit (θ_j − θ_i) Δh apart, about a subaperture per km), so one at a time would let the strongest absorb its
 * neighbours. First a layer is a peak of c_h and the bins around it, sharing one v; then each bin of a peak with
 * ≥ WIND_SPLIT_MIN of the Cn² gets its own (split_peaks: layers closer than the altitude resolution are parted by
 * their relative motion), kept when it lowers Φ. With two layers or more, a layer starts from a coarse polar
 * search of v (the others held, its best amplitude in closed form), strongest first. The lags then enter one by
 * one from the shortest, each stage starting from the last's v: a stage's new shifts are within a subaperture or
 * so of their final value, where the model is close to linear in v. A layer whose v runs past WIND_PLAUSIBLE is
 * dropped and the others refitted. The uncertainty: each batch fitted from the all-frames solution; the spread of
 * its v over √B.
 */
#include "learn_private.h"
#include "core/model/profile.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#define WIND_ITERS 25        /* Levenberg–Marquardt iterations per stage (each stage converges in ~5) */
#define WIND_BATCH_ITERS 12  /* for a batch, from the all-frames solution */
#define WIND_STEP_CAP 0.5    /* largest change of a layer's shift per iteration at the longest lag [d] */
#define WIND_TOL 0.01        /* convergence: every |Δv| below this [m/s] (a tenth of the batches' spread) */
#define WIND_VMAX 100.0      /* |v| is held below this [m/s] (the table of D covers the shifts it makes) */
#define WIND_SEARCH_VMAX 40.0 /* the search's grid: speeds 0 … 40 m/s every 5 m/s, directions every 22.5° (LM refines) */
#define WIND_SEARCH_DV 5.0
#define WIND_SEARCH_NDIR 16
#define WIND_SEARCH_LAGS 2   /* the search fits the first 2 lags (shifts ≤ 2 subapertures at 40 m/s with the default
                                lags: one minimum per layer within the grid's reach, and half the cost of 3) */
#define WIND_PLAUSIBLE 60.0  /* a layer whose fit runs faster [m/s] is not in the lagged maps where its altitude
                                says (e.g. Cn² the profile put at the wrong altitude): it is dropped, the others refitted */
#define WIND_MAX_LAYERS 20   /* layers in the model (peaks of c_h, or their strong bins after a split) */
#define WIND_SPLIT_MIN 0.02  /* a bin of a peak with this much of the Cn² may get its own wind (split_peaks) */
#define WIND_MODEL_MIN 0.02  /* a peak with less of the Cn² is left out of the model: its wind would be noise, and
                                one above it is modelled (with its own wind) even when too weak to report, so that
                                its moving structure is not taken up by the layers reported */

typedef struct {
    const wt_learn *L;
    int nl;                      /* layers fitted (one v each) */
    int nb;                      /* bins of the grid in the model */
    double bh[WT_LEARN_MAX_ALT]; /* their altitudes [m] */
    double bc[WT_LEARN_MAX_ALT]; /* their c_h [m^(−5/3)] */
    int bl[WT_LEARN_MAX_ALT];    /* their layer */
    int ba[WT_LEARN_MAX_ALT];    /* their index in the estimate */
    int nu, *uoff;               /* used offsets (FFT index) */
    double *uw;                  /* their weights */
    double dt;                   /* [s] */
    int nth;
    wt_learn__rws *ws[WT_LEARN_MAX_THREADS];
    double *rb;                  /* [nth][nb][3][S²] response maps of a block and their ∂/∂s_x, ∂/∂s_y */
    double *data;                /* [nlag][nlgs][nlgs][2][nu] the maps being fitted: lag k's less lag 0's */
    double *zero;                /* [nlgs][nlgs][2][nu] the lag-0 maps of the same frames */
    double *r0m;                 /* [nslot][2][nb][nu] each bin's response at s = 0 (the lag-0 map's model) */
    int u0;                      /* the index of δ = 0 in the used offsets (left out of the auto pairs) */
    double *blk;                 /* [nblock][(3 nl)² + 3 nl + 2] each block's normal equations, cost, norm */
    double *oth;                 /* [nblock][nu] the model of the other layers (the search) */
    double lpf[WIND_MAX_LAYERS]; /* each layer's Cn² fraction (the search's order) */
    int off[WIND_MAX_LAYERS];    /* 1: dropped (its wind ran past WIND_PLAUSIBLE): out of the model */
    int srch[WIND_MAX_LAYERS];   /* 1: its start is searched (fit_layers) */
    double bf[WT_LEARN_MAX_ALT]; /* the bins' Cn² fractions */
} wfit;


/* The normal equations of the first nq lags at p = (a[nl], v[nl][2]): A (np × np), g = JᵀW r, *cost = Φ, *norm =
 * Σ w C². Blocks (lag, slot, component) in parallel, each into its own slot of blk, summed in block order (the
 * result does not depend on the thread count). Slot 0 is every auto pair (one response), then each ordered cross
 * pair. */
static void normal_eq(wfit *F, int nq, const double *p, double *A, double *g, double *cost, double *norm)
{
    const wt_learn *L = F->L;
    const int nl = F->nl, nlgs = L->nlgs, nslot = 1 + nlgs * (nlgs - 1), S = 2 * L->n - 1, S2 = S * S;
    const int np = 3 * nl, bs = np * np + np + 2, nblock = nq * nslot * 2, N = L->N;
#pragma omp parallel for schedule(dynamic, 1) num_threads(F->nth)
    for (int b = 0; b < nblock; b++) {
        const int q = b / (nslot * 2), sl = (b / 2) % nslot, c = b % 2, tid = wt_thread_id(), k = L->lag[q];
        double *out = F->blk + (size_t)b * bs, *rb = F->rb + (size_t)tid * F->nb * 3 * S2;
        memset(out, 0, (size_t)bs * sizeof *out);
        /* the pair(s) of this slot */
        int pi[64] = {0}, pj[64] = {0}, npair = 0;
        if (sl == 0)
            for (int i = 0; i < nlgs; i++) pi[npair] = i, pj[npair++] = i;
        else {
            int s = sl - 1, i = s / (nlgs - 1), j = s % (nlgs - 1);
            pi[0] = i, pj[0] = j >= i ? j + 1 : j, npair = 1;
        }
        const double tx = L->theta_x[pj[0]] - L->theta_x[pi[0]], ty = L->theta_y[pj[0]] - L->theta_y[pi[0]];
        for (int bi = 0; bi < F->nb; bi++) {
            const int l = F->bl[bi];
            if (F->off[l]) continue;
            const double sx = p[nl + 2 * l] * k * F->dt, sy = p[nl + 2 * l + 1] * k * F->dt;
            double *r = rb + (size_t)bi * 3 * S2;
            wt_learn__resp_eval_grad(L, F->ws[tid], tx, ty, F->bh[bi], sx, sy, c, c, r, r + S2, r + 2 * S2);
        }
        double J[3 * WIND_MAX_LAYERS];
        for (int u = 0; u < F->nu; u++) {
            int f = F->uoff[u], dx = f % N, dy = f / N;
            dx = dx >= L->n ? dx - N : dx, dy = dy >= L->n ? dy - N : dy;
            const int o = (dx + L->n - 1) + S * (dy + L->n - 1);
            if (sl == 0 && u == F->u0) continue; /* the lag-0 auto maps hold the noise's variance there */
            double model = 0;
            for (int x = 0; x < np; x++) J[x] = 0;
            for (int bi = 0; bi < F->nb; bi++) {
                const double *r = rb + (size_t)bi * 3 * S2 + o, cb = F->bc[bi];
                const int l = F->bl[bi];
                if (F->off[l]) continue;
                /* ∂/∂a_l = Σ_b c_b (R_b(s) − R_b(0)), ∂/∂v_l = a_l Σ_b c_b k Δt ∂R_b/∂s */
                J[l] += cb * (r[0] - F->r0m[(((size_t)sl * 2 + c) * F->nb + bi) * F->nu + u]);
                const double fac = p[l] * cb * k * F->dt;
                J[nl + 2 * l] += fac * r[S2], J[nl + 2 * l + 1] += fac * r[2 * S2];
            }
            for (int l = 0; l < nl; l++) model += p[l] * J[l];
            const double w = F->uw[u];
            for (int a = 0; a < npair; a++) {
                const double C = F->data[((((size_t)q * nlgs + pi[a]) * nlgs + pj[a]) * 2 + c) * F->nu + u];
                const double r = C - model;
                for (int x = 0; x < np; x++) {
                    out[np * np + x] += w * J[x] * r;
                    for (int y = 0; y <= x; y++) out[x + np * y] += w * J[x] * J[y];
                }
                out[np * np + np] += w * r * r, out[np * np + np + 1] += w * C * C;
            }
        }
    }
    memset(A, 0, (size_t)np * np * sizeof *A);
    memset(g, 0, (size_t)np * sizeof *g);
    *cost = *norm = 0;
    for (int b = 0; b < nblock; b++) {
        const double *in = F->blk + (size_t)b * bs;
        for (int x = 0; x < np; x++) {
            g[x] += in[np * np + x];
            for (int y = 0; y <= x; y++) {
                A[x + (size_t)np * y] += in[x + np * y];
                if (x != y) A[y + (size_t)np * x] += in[x + np * y];
            }
        }
        *cost += in[np * np + np], *norm += in[np * np + np + 1];
    }
}

/* Levenberg–Marquardt over the first nq lags from p (updated in place); returns the iterations */
static int lm(wfit *F, int nq, double *p, int maxit, double *cost_out, double *norm_out, double *work)
{
    const int nl = F->nl, np = 3 * nl;
    double *A = work, *g = A + np * np, *At = g + np, *gt = At + np * np, *M = gt + np, *dp = M + np * np,
           *pt = dp + np, *ch = pt + np;
    double cost, norm, ct, nt;
    normal_eq(F, nq, p, A, g, &cost, &norm);
    double lambda = 1e-3;
    const double kdt = F->L->lag[nq - 1] * F->dt;
    int it;
    for (it = 1; it <= maxit; it++) {
        /* a dropped layer's parameters have no equations: their diagonal gets the largest one's scale (not 1, which
         * would make every other pivot look singular to the Cholesky's relative test), so their step is 0 */
        double dA = 0;
        for (int x = 0; x < np; x++) dA = fmax(dA, A[x + (size_t)np * x]);
        for (int x = 0; x < np * np; x++) M[x] = A[x];
        for (int x = 0; x < np; x++)
            M[x + (size_t)np * x] += A[x + (size_t)np * x] > 0 ? lambda * A[x + (size_t)np * x] : (dA > 0 ? dA : 1.0);
        wt_learn__spd_solve(np, M, np, g, dp, ch);
        /* at most WIND_STEP_CAP subapertures of new shift per layer at the longest lag in use */
        double dvmax = 0;
        for (int l = 0; l < nl; l++) {
            double *d = dp + nl + 2 * l, m = hypot(d[0], d[1]) * kdt / (WIND_STEP_CAP * F->L->d);
            if (m > 1) d[0] /= m, d[1] /= m;
            dvmax = fmax(dvmax, fmax(fabs(d[0]), fabs(d[1])));
        }
        for (int x = 0; x < np; x++) pt[x] = p[x] + dp[x];
        for (int l = 0; l < nl; l++) {
            double *v = pt + nl + 2 * l, m = hypot(v[0], v[1]) / WIND_VMAX;
            if (m > 1) v[0] /= m, v[1] /= m;
            if (pt[l] < 0) pt[l] = 0; /* an amplitude is a Cn²: ≥ 0 */
        }
        normal_eq(F, nq, pt, At, gt, &ct, &nt);
        if (ct <= cost) {
            memcpy(p, pt, (size_t)np * sizeof *p);
            memcpy(A, At, (size_t)np * np * sizeof *A), memcpy(g, gt, (size_t)np * sizeof *g);
            cost = ct, lambda = fmax(lambda / 3, 1e-9);
            if (dvmax < WIND_TOL) break;
        } else {
            lambda *= 4;
            if (lambda > 1e8) break; /* no step lowers Φ: the minimum, to rounding */
        }
    }
    *cost_out = cost, *norm_out = norm;
    return it > maxit ? maxit : it;
}

/* The search of layer l's v: the others held, the cost of the first nq lags on a polar grid of v, each with its
 * best amplitude a ≥ 0 (closed form: the cost is quadratic in a); p[l] and v_l set to the best. LM's start: a
 * layer's lagged maps may have several local minima in v once layers overlap (a fast layer's moving peak can pass
 * for another's), which v = 0 does not choose between. */
static void search_layer(wfit *F, int nq, double *p, int l)
{
    const wt_learn *L = F->L;
    const int nl = F->nl, nlgs = L->nlgs, nslot = 1 + nlgs * (nlgs - 1), S = 2 * L->n - 1, S2 = S * S;
    const int nblock = nq * nslot * 2, N = L->N, ncand = 1 + (int)(WIND_SEARCH_VMAX / WIND_SEARCH_DV) * WIND_SEARCH_NDIR;
    /* the other layers' model per block */
#pragma omp parallel for schedule(dynamic, 1) num_threads(F->nth)
    for (int b = 0; b < nblock; b++) {
        const int q = b / (nslot * 2), sl = (b / 2) % nslot, c = b % 2, tid = wt_thread_id(), k = L->lag[q];
        int i = 0, j = 0;
        if (sl > 0) i = (sl - 1) / (nlgs - 1), j = (sl - 1) % (nlgs - 1), j = j >= i ? j + 1 : j;
        const double tx = L->theta_x[j] - L->theta_x[i], ty = L->theta_y[j] - L->theta_y[i];
        double *o = F->oth + (size_t)b * F->nu, *r = F->rb + (size_t)tid * F->nb * 3 * S2;
        memset(o, 0, (size_t)F->nu * sizeof *o);
        for (int bi = 0; bi < F->nb; bi++) {
            const int lb = F->bl[bi];
            if (lb == l || F->off[lb]) continue;
            wt_learn__resp_eval(L, F->ws[tid], tx, ty, F->bh[bi], p[nl + 2 * lb] * k * F->dt, p[nl + 2 * lb + 1] * k * F->dt,
                                c, c, r);
            for (int u = 0; u < F->nu; u++) {
                int f = F->uoff[u], dx = f % N, dy = f / N;
                dx = dx >= L->n ? dx - N : dx, dy = dy >= L->n ? dy - N : dy;
                o[u] += p[lb] * F->bc[bi] * (r[(dx + L->n - 1) + S * (dy + L->n - 1)] -
                                             F->r0m[(((size_t)sl * 2 + c) * F->nb + bi) * F->nu + u]);
            }
        }
    }
    double best = INFINITY, bvx = 0, bvy = 0, ba = p[l];
    for (int cnd = 0; cnd < ncand; cnd++) {
        const double sp = cnd ? WIND_SEARCH_DV * (1 + (cnd - 1) / WIND_SEARCH_NDIR) : 0.0;
        const double ang = cnd ? 2 * M_PI * ((cnd - 1) % WIND_SEARCH_NDIR) / WIND_SEARCH_NDIR : 0.0;
        const double vx = sp * cos(ang), vy = sp * sin(ang);
        /* per block: Σ w J r0, Σ w J², Σ w r0² with J the layer's unit-amplitude model, r0 = C − others */
#pragma omp parallel for schedule(dynamic, 1) num_threads(F->nth)
        for (int b = 0; b < nblock; b++) {
            const int q = b / (nslot * 2), sl = (b / 2) % nslot, c = b % 2, tid = wt_thread_id(), k = L->lag[q];
            int pi[64] = {0}, pj[64] = {0}, npair = 0;
            if (sl == 0)
                for (int i = 0; i < nlgs; i++) pi[npair] = i, pj[npair++] = i;
            else {
                int i = (sl - 1) / (nlgs - 1), j = (sl - 1) % (nlgs - 1);
                pi[0] = i, pj[0] = j >= i ? j + 1 : j, npair = 1;
            }
            const double tx = L->theta_x[pj[0]] - L->theta_x[pi[0]], ty = L->theta_y[pj[0]] - L->theta_y[pi[0]];
            double *r = F->rb + (size_t)tid * F->nb * 3 * S2, *J = r + S2, *out = F->blk + (size_t)b * 3;
            memset(J, 0, (size_t)S2 * sizeof *J);
            for (int bi = 0; bi < F->nb; bi++) {
                if (F->bl[bi] != l) continue;
                wt_learn__resp_eval(L, F->ws[tid], tx, ty, F->bh[bi], vx * k * F->dt, vy * k * F->dt, c, c, r);
                for (int o = 0; o < S2; o++) J[o] += F->bc[bi] * r[o];
            }
            out[0] = out[1] = out[2] = 0;
            const double *o = F->oth + (size_t)b * F->nu;
            for (int u = 0; u < F->nu; u++) {
                if (sl == 0 && u == F->u0) continue;
                int f = F->uoff[u], dx = f % N, dy = f / N;
                dx = dx >= L->n ? dx - N : dx, dy = dy >= L->n ? dy - N : dy;
                double Ju = J[(dx + L->n - 1) + S * (dy + L->n - 1)];
                const double w = F->uw[u];
                for (int bi = 0; bi < F->nb; bi++)
                    if (F->bl[bi] == l) Ju -= F->bc[bi] * F->r0m[(((size_t)sl * 2 + c) * F->nb + bi) * F->nu + u];
                for (int a = 0; a < npair; a++) {
                    const double r0 = F->data[((((size_t)q * nlgs + pi[a]) * nlgs + pj[a]) * 2 + c) * F->nu + u] - o[u];
                    out[0] += w * Ju * r0, out[1] += w * Ju * Ju, out[2] += w * r0 * r0;
                }
            }
        }
        double jr = 0, jj = 0, rr = 0;
        for (int b = 0; b < nblock; b++) jr += F->blk[3 * b], jj += F->blk[3 * b + 1], rr += F->blk[3 * b + 2];
        const double a = jj > 0 ? fmax(0.0, jr / jj) : 0.0, cost = rr - 2 * a * jr + a * a * jj;
        if (cost < best) best = cost, bvx = vx, bvy = vy, ba = a;
    }
    p[l] = ba, p[nl + 2 * l] = bvx, p[nl + 2 * l + 1] = bvy;
}

/* The layers' fit from p (a, v; updated in place): the searched layers' starts, strongest first (the others at
 * their last values), the lags one by one from the shortest (each stage from the last's a, v), then the implausible
 * layers out, one at a time from the fastest, the others refitted over all lags from their v. Returns the
 * iterations; *dropped counts the layers dropped. */
static int fit_layers(wfit *F, const char *phase, double *p, double *cost, double *norm, double *work, int *dropped)
{
    const wt_learn *L = F->L;
    const int nl = F->nl, nqs = L->nlag < WIND_SEARCH_LAGS ? L->nlag : WIND_SEARCH_LAGS;
    int order[WIND_MAX_LAYERS], it = 0, nsearch = 0, step = 0;
    for (int l = 0; nl > 1 && l < nl; l++) nsearch += F->srch[l] && !F->off[l];
    const int64_t total = nsearch + L->nlag;
    for (int l = 0; l < nl; l++) order[l] = l;
    for (int x = 1; x < nl; x++)
        for (int y = x; y > 0 && F->lpf[order[y]] > F->lpf[order[y - 1]]; y--) {
            int t = order[y];
            order[y] = order[y - 1], order[y - 1] = t;
        }
    /* one layer alone has one minimum within the first lag's reach of v = 0 (tests/test_learn.c): no search */
    for (int x = 0; nl > 1 && x < nl; x++)
        if (F->srch[order[x]] && !F->off[order[x]]) {
            search_layer(F, nqs, p, order[x]);
            if (L->progress) L->progress(L->progress_user, phase, ++step, total);
        }
    for (int q = 0; q < L->nlag; q++) {
        it += lm(F, q + 1, p, WIND_ITERS, cost, norm, work);
        if (L->progress) L->progress(L->progress_user, phase, ++step, total);
    }
    for (;;) {
        int worst = -1;
        double vmax = WIND_PLAUSIBLE;
        for (int l = 0; l < nl; l++)
            if (!F->off[l] && hypot(p[nl + 2 * l], p[nl + 2 * l + 1]) > vmax)
                vmax = hypot(p[nl + 2 * l], p[nl + 2 * l + 1]), worst = l;
        if (worst < 0) break;
        F->off[worst] = 1, p[worst] = 0, p[nl + 2 * worst] = p[nl + 2 * worst + 1] = 0;
        (*dropped)++;
        it += lm(F, L->nlag, p, WIND_ITERS, cost, norm, work);
    }
    return it;
}

/* The split model S of the per-peak fit (F, p): in each layer of F (not dropped) with two or more bins holding
 * ≥ WIND_SPLIT_MIN of the Cn² each, each such bin becomes a layer of its own and the weaker bins join the nearest
 * in altitude. Below the pairs' altitude resolution two layers' responses differ by less than the noise in every
 * unlagged map, but not in the lagged ones when they move differently: their shifts v k Δt part them (the E-ELT
 * truth's 562 m and 1125 m layers move at 9 m/s towards 120° and 160°, the ground's at 15 m/s towards 0°). Where the
 * bins do share one wind, S's minimum is the per-peak one (the same v for every bin). S's start ps: every layer
 * its parent's a and v, the split ones searched. Returns S's layers (F->nl: nothing to split). */
static int split_peaks(const wfit *F, const double *p, wfit *S, double *ps)
{
    const int nl = F->nl;
    int parent[WIND_MAX_LAYERS], ns = 0;
    *S = *F;
    for (int l = 0; l < nl; l++) {
        int strong[WT_LEARN_MAX_ALT], nst = 0;
        for (int b = 0; b < F->nb; b++)
            if (!F->off[l] && F->bl[b] == l && F->bf[b] >= WIND_SPLIT_MIN) strong[nst++] = b;
        if (ns + (nst < 2 ? 1 : nst) > WIND_MAX_LAYERS) return nl;
        if (nst < 2) {
            for (int b = 0; b < F->nb; b++)
                if (F->bl[b] == l) S->bl[b] = ns;
            S->lpf[ns] = F->lpf[l], S->off[ns] = F->off[l], S->srch[ns] = 0, parent[ns++] = l;
            continue;
        }
        const int first = ns;
        for (int k = 0; k < nst; k++) S->lpf[ns] = 0, S->off[ns] = 0, S->srch[ns] = 1, parent[ns++] = l;
        for (int b = 0; b < F->nb; b++) {
            if (F->bl[b] != l) continue;
            int kb = 0;
            for (int k = 1; k < nst; k++)
                if (fabs(F->bh[b] - F->bh[strong[k]]) < fabs(F->bh[b] - F->bh[strong[kb]])) kb = k;
            S->bl[b] = first + kb, S->lpf[first + kb] += F->bf[b];
        }
    }
    if (ns == nl) return nl;
    S->nl = ns;
    for (int m = 0; m < ns; m++) {
        const int l = parent[m];
        ps[m] = p[l], ps[ns + 2 * m] = p[nl + 2 * l], ps[ns + 2 * m + 1] = p[nl + 2 * l + 1];
    }
    return ns;
}

/* The lagged maps of batch b (−1: all) less the same frames' lag-0 maps, at the used offsets, into F->data. Why
 * the difference: the maps' error is mostly the realisation of the large scales (a layer crosses the pupil a few
 * times in a run), broad in δ and, under frozen flow, the same in the lag-k map moved by the shift s; C_k − C_0 keeps
 * the layers' s-dependent part, −s·∇R near the peaks, and cancels that error to first order in s (a fit of C_k alone
 * let a wrong v fit the broad error better than the right one fits the peak). */
static int load_maps(wfit *F, int batch, double *buf, int nth)
{
    const wt_learn *L = F->L;
    const int nlgs = L->nlgs, nf = L->nf, NN = L->N * L->N, ntask = L->nlag * nlgs * nlgs * 2, nz = nlgs * nlgs * 2;
    const int b0 = batch < 0 ? 0 : batch, b1 = batch < 0 ? L->nbatch - 1 : batch;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
    for (int t = 0; t < nz; t++) {
        /* (i, j, c) from the unordered pair's spectrum: C_ij(δ) = C_ji(−δ), the conjugate spectrum */
        const int i = t / (nlgs * 2), j = (t / 2) % nlgs, c = t % 2, tid = wt_thread_id(), lo = i < j ? i : j,
                  hi = i < j ? j : i, pr = lo * nlgs - lo * (lo - 1) / 2 + (hi - lo);
        const double sg = i > j ? -1.0 : 1.0;
        double *sp = wt_align64(buf + (size_t)tid * (2 * nf + NN + 16)), *corr = wt_align64(sp + 2 * nf);
        int64_t K = 0;
        memset(sp, 0, (size_t)2 * nf * sizeof *sp);
        for (int b = b0; b <= b1; b++) {
            const double *s = L->spec + (((size_t)b * L->npairs + pr) * WT_LEARN_NCOMP + c) * nf * 2;
            for (int k = 0; k < nf; k++) sp[2 * k] += s[2 * k], sp[2 * k + 1] += sg * s[2 * k + 1];
            K += L->bframes[b];
        }
        fftw_execute_dft_c2r((fftw_plan)L->c2r, (fftw_complex *)sp, corr);
        for (int u = 0; u < F->nu; u++)
            F->zero[(size_t)t * F->nu + u] = corr[F->uoff[u]] / ((double)NN * (double)K * L->pairs[F->uoff[u]]);
    }
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
    for (int t = 0; t < ntask; t++) {
        const int q = t / nz, tid = wt_thread_id();
        double *sp = wt_align64(buf + (size_t)tid * (2 * nf + NN + 16)), *corr = wt_align64(sp + 2 * nf);
        const double *z = F->zero + (size_t)(t % nz) * F->nu;
        int64_t K = 0;
        memset(sp, 0, (size_t)2 * nf * sizeof *sp);
        for (int b = b0; b <= b1; b++) {
            /* t enumerates (q, i, j, c) in lspec's order within a batch */
            const double *s = L->lspec + ((size_t)b * L->nlag * nlgs * nlgs * 2 + t) * nf * 2;
            for (int k = 0; k < 2 * nf; k++) sp[k] += s[k];
            K += L->lframes[(size_t)b * L->nlag + q];
        }
        fftw_execute_dft_c2r((fftw_plan)L->c2r, (fftw_complex *)sp, corr);
        for (int u = 0; u < F->nu; u++)
            F->data[(size_t)t * F->nu + u] = corr[F->uoff[u]] / ((double)NN * (double)K * L->pairs[F->uoff[u]]) - z[u];
    }
    return WT_OK;
}

/* Each bin's response at s = 0 for every slot and component, at the used offsets, into F->r0m */
static void zero_responses(wfit *F)
{
    const wt_learn *L = F->L;
    const int nlgs = L->nlgs, nslot = 1 + nlgs * (nlgs - 1), S = 2 * L->n - 1, S2 = S * S, N = L->N;
#pragma omp parallel for schedule(dynamic, 1) num_threads(F->nth)
    for (int t = 0; t < nslot * 2 * F->nb; t++) {
        const int sl = t / (2 * F->nb), c = (t / F->nb) % 2, bi = t % F->nb, tid = wt_thread_id();
        int i = 0, j = 0;
        if (sl > 0) i = (sl - 1) / (nlgs - 1), j = (sl - 1) % (nlgs - 1), j = j >= i ? j + 1 : j;
        double *r = F->rb + (size_t)tid * F->nb * 3 * S2, *out = F->r0m + (size_t)t * F->nu;
        wt_learn__resp_eval(L, F->ws[tid], L->theta_x[j] - L->theta_x[i], L->theta_y[j] - L->theta_y[i], F->bh[bi],
                            0.0, 0.0, c, c, r);
        for (int u = 0; u < F->nu; u++) {
            int f = F->uoff[u], dx = f % N, dy = f / N;
            dx = dx >= L->n ? dx - N : dx, dy = dy >= L->n ? dy - N : dy;
            out[u] = r[(dx + L->n - 1) + S * (dy + L->n - 1)];
        }
    }
}

static double wrap_pi(double a) { return a - 2 * M_PI * floor((a + M_PI) / (2 * M_PI)); }

int wt_learn_wind_fit(const wt_learn *L, const wt_learn_estimate *est, double dt, double min_fraction, wt_learn_wind *w)
{
    wt_context *ctx = L->ctx;
    const int n = L->n, N = L->N, S = 2 * n - 1, S2 = S * S, nlgs = L->nlgs;
    int st = WT_OK;
    memset(w, 0, sizeof *w);
    if (L->nlag < 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: no lagged maps for the wind (allocate with wt_learn_alloc_lagged)");
    if (!(dt > 0) || !isfinite(dt))
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: frame time %g s, expected > 0", dt);
    if (!(min_fraction >= 0 && min_fraction < 1))
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: wind threshold %g of the Cn², expected in [0, 1)", min_fraction);
    if (L->frames < L->kmax + 2)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: %lld frames accumulated, too few for the longest lag (%d frames): "
                        "the wind needs at least %d", (long long)L->frames, L->kmax, L->kmax + 2);
    if (est->nalt < 1 || est->nalt > WT_LEARN_MAX_ALT)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: an estimate of %d altitudes", est->nalt);
    wfit F = {0};
    F.L = L, F.dt = dt;
    w->nalt = est->nalt, w->dt = dt, w->nlag = L->nlag;
    memcpy(w->lag, L->lag, (size_t)L->nlag * sizeof *L->lag);
    /* the layers: each local maximum of the fitted c_h and the bins nearest to it (ties: the larger maximum's). The
     * grid's 1 km is finer than the pairs' resolution d/θ, so one layer spreads over 2–3 bins whose responses
     * differ by less than the noise: a wind per bin would be ill-conditioned, a wind per peak is not. A layer whose
     * bins hold ≥ min_fraction of the Cn² is fitted; the others are left out of the model. */
    const int na = est->nalt;
    int peak[WT_LEARN_MAX_ALT], npk = 0, owner[WT_LEARN_MAX_ALT];
    double pf[WT_LEARN_MAX_ALT] = {0};
    for (int a = 0; a < na; a++) {
        w->altitude[a] = est->altitude[a], w->fraction[a] = est->fraction[a];
        if (!(est->altitude[a] >= 0 && est->altitude[a] < L->H) || !isfinite(est->cn2[a]) || est->cn2[a] < 0)
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: estimate altitude %g m (Cn² %g) outside [0, H = %g m)",
                            est->altitude[a], est->cn2[a], L->H);
        const double c = est->cn2[a];
        if (c > 0 && (a == 0 || c >= est->cn2[a - 1]) && (a == na - 1 || c > est->cn2[a + 1])) peak[npk++] = a;
    }
    for (int a = 0; a < na; a++) {
        owner[a] = -1;
        if (!(est->cn2[a] > 0)) continue;
        for (int k = 0; k < npk; k++) {
            const double dk = fabs(est->altitude[a] - est->altitude[peak[k]]);
            const double db = owner[a] < 0 ? INFINITY : fabs(est->altitude[a] - est->altitude[peak[owner[a]]]);
            if (dk < db || (dk == db && est->cn2[peak[k]] > est->cn2[peak[owner[a]]])) owner[a] = k;
        }
        pf[owner[a]] += est->fraction[a];
    }
    int lay_of_peak[WT_LEARN_MAX_ALT];
    for (int k = 0; k < npk; k++) {
        lay_of_peak[k] = -1;
        if (pf[k] < fmin(min_fraction, WIND_MODEL_MIN)) continue;
        if (F.nl == WIND_MAX_LAYERS)
            return WT_ERROR(ctx, WT_ERR_INVALID, "learn: more than %d layers above %g of the Cn²", WIND_MAX_LAYERS,
                            min_fraction);
        F.lpf[F.nl] = pf[k], lay_of_peak[k] = F.nl++;
    }
    for (int a = 0; a < na; a++)
        if (owner[a] >= 0 && lay_of_peak[owner[a]] >= 0) {
            F.bh[F.nb] = est->altitude[a], F.bc[F.nb] = est->cn2[a], F.bl[F.nb] = lay_of_peak[owner[a]];
            F.bf[F.nb] = est->fraction[a], F.ba[F.nb++] = a, w->fitted[a] = pf[owner[a]] >= min_fraction;
        }
    int nfit = 0;
    for (int a = 0; a < na; a++) nfit += w->fitted[a];
    if (nfit == 0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "learn: no layer holds %g of the Cn²: no layer to find the wind of",
                        min_fraction);
    const int nslot = 1 + nlgs * (nlgs - 1), npmax = 3 * WIND_MAX_LAYERS;
    for (int l = 0; l < F.nl; l++) F.srch[l] = 1;
    F.nth = 1;
#ifdef _OPENMP
    F.nth = omp_get_max_threads();
#endif
    if (F.nth > WT_LEARN_MAX_THREADS) F.nth = WT_LEARN_MAX_THREADS;
    double *buf = NULL, *work = NULL, *p = NULL, *pb = NULL, *ps = NULL;
    /* the used offsets: the profile fit's (every offset counts here: noise is white, so a lag carries none) */
    WT_ALLOC(ctx, F.uoff, S2, "the used offsets");
    WT_ALLOC(ctx, F.uw, S2, "the offsets' weights");
    for (int o = 0; o < S2; o++) {
        int dx = o % S - (n - 1), dy = o / S - (n - 1), f = (dx + N) % N + N * ((dy + N) % N);
        if (L->pairs[f] < WT_LEARN_MIN_PAIRS * L->pairs[0]) continue;
        if (f == 0) F.u0 = F.nu;
        F.uoff[F.nu] = f, F.uw[F.nu++] = L->pairs[f] / L->pairs[0];
    }
    double thmax = 0, hmax = 0;
    for (int i = 0; i < nlgs; i++)
        for (int j = 0; j < nlgs; j++)
            thmax = fmax(thmax, hypot(L->theta_x[j] - L->theta_x[i], L->theta_y[j] - L->theta_y[i]));
    for (int b = 0; b < F.nb; b++) hmax = fmax(hmax, F.bh[b]);
    const double smax = WIND_VMAX * L->kmax * dt;
    for (int k = 0; k < F.nth; k++)
        if ((st = wt_learn__rws_alloc(L, est->L0, wt_learn__rmax(L, thmax, hmax, smax), &F.ws[k])) < 0) goto fail;
    WT_ALLOC(ctx, F.rb, (size_t)F.nth * F.nb * 3 * S2, "the wind's response maps");
    WT_ALLOC(ctx, F.data, (size_t)L->nlag * nlgs * nlgs * 2 * F.nu, "the lagged maps");
    WT_ALLOC(ctx, F.zero, (size_t)nlgs * nlgs * 2 * F.nu, "the lag-0 maps");
    WT_ALLOC(ctx, F.r0m, (size_t)nslot * 2 * F.nb * F.nu, "the responses at no shift");
    /* the blocks, the work space and the parameters for the most layers a split may make */
    WT_ALLOC(ctx, F.blk, (size_t)L->nlag * nslot * 2 * (npmax * npmax + npmax + 3), "the blocks' normal equations");
    WT_ALLOC(ctx, F.oth, (size_t)L->nlag * nslot * 2 * F.nu, "the other layers' model");
    WT_ALLOC(ctx, buf, (size_t)F.nth * (2 * L->nf + N * N + 16), "the inverse FFT work arrays");
    WT_ALLOC(ctx, work, (size_t)4 * npmax * npmax + 6 * npmax, "the Levenberg-Marquardt work space");
    WT_ALLOC(ctx, p, npmax, "the wind parameters");
    WT_ALLOC(ctx, pb, npmax, "a batch's wind parameters");
    WT_ALLOC(ctx, ps, npmax, "the split fit's parameters");
    /* all frames: one wind per peak, then each strong bin of a peak its own (split_peaks) */
    if ((st = load_maps(&F, -1, buf, F.nth)) < 0) goto fail;
    zero_responses(&F);
    double cost = 0, norm = 0;
    for (int l = 0; l < F.nl; l++) p[l] = 1.0;
    w->iterations += fit_layers(&F, "wind: one per peak", p, &cost, &norm, work, &w->dropped);
    wfit Sp;
    if (split_peaks(&F, p, &Sp, ps) > F.nl) {
        double cs = 0, ns = 0;
        int drs = 0;
        w->iterations += fit_layers(&Sp, "wind: bins split", ps, &cs, &ns, work, &drs);
        /* a superset of the per-peak model: kept when its minimum is the lower (a split whose search led to a local
         * minimum above the per-peak fit explains the maps no better) */
        if (cs < cost) {
            w->split = Sp.nl - F.nl, w->dropped += drs;
            F = Sp, cost = cs, norm = ns;
            double *t = p;
            p = ps, ps = t;
        }
    }
    const int nl = F.nl, np = 3 * nl;
    w->residual = norm > 0 ? sqrt(cost / norm) : 0.0;
    for (int b = 0; b < F.nb; b++) {
        const int a = F.ba[b], l = F.bl[b];
        if (F.off[l]) w->fitted[a] = 0;
        if (!w->fitted[a]) continue;
        w->vx[a] = p[nl + 2 * l], w->vy[a] = p[nl + 2 * l + 1], w->amplitude[a] = p[l];
        w->speed[a] = hypot(w->vx[a], w->vy[a]);
        w->direction[a] = fmod(atan2(w->vy[a], w->vx[a]) + 2 * M_PI, 2 * M_PI);
    }
    /* the batches: each from the all-frames solution, all lags */
    int used[WT_LEARN_MAX_BATCH], nb = 0;
    for (int b = 0; b < L->nbatch; b++) {
        int ok = 1;
        for (int q = 0; q < L->nlag; q++) ok = ok && L->lframes[(size_t)b * L->nlag + q] >= 2;
        if (ok) used[nb++] = b;
    }
    if (nb >= 2) {
        w->nbatch = nb;
        double s1[WT_LEARN_MAX_ALT][4] = {{0}}, s2[WT_LEARN_MAX_ALT][4] = {{0}};
        for (int r = 0; r < nb; r++) {
            if ((st = load_maps(&F, used[r], buf, F.nth)) < 0) goto fail;
            memcpy(pb, p, (size_t)np * sizeof *p);
            double cb, nbn;
            lm(&F, L->nlag, pb, WIND_BATCH_ITERS, &cb, &nbn, work);
            if (L->progress) L->progress(L->progress_user, "wind: batches", r + 1, nb);
            for (int b = 0; b < F.nb; b++) {
                const int a = F.ba[b], l = F.bl[b];
                if (!w->fitted[a]) continue;
                const double vx = pb[nl + 2 * l], vy = pb[nl + 2 * l + 1];
                w->batch_vx[r][a] = vx, w->batch_vy[r][a] = vy;
                const double x[4] = {vx, vy, hypot(vx, vy), wrap_pi(atan2(vy, vx) - w->direction[a])};
                for (int c = 0; c < 4; c++) s1[a][c] += x[c], s2[a][c] += x[c] * x[c];
            }
        }
        for (int a = 0; a < est->nalt; a++) {
            if (!w->fitted[a]) continue;
            double sg[4];
            for (int c = 0; c < 4; c++) sg[c] = sqrt(fmax(0.0, (s2[a][c] - s1[a][c] * s1[a][c] / nb) / (nb - 1)) / nb);
            w->vx_sigma[a] = sg[0], w->vy_sigma[a] = sg[1], w->speed_sigma[a] = sg[2], w->direction_sigma[a] = sg[3];
        }
    }
fail:
    for (int k = 0; k < F.nth; k++) wt_learn__rws_free(L, F.ws[k]);
    wt_free(ctx, F.oth), wt_free(ctx, F.uoff), wt_free(ctx, F.uw), wt_free(ctx, F.rb), wt_free(ctx, F.data), wt_free(ctx, F.blk);
    wt_free(ctx, F.zero), wt_free(ctx, F.r0m);
    wt_free(ctx, buf), wt_free(ctx, work), wt_free(ctx, p), wt_free(ctx, pb), wt_free(ctx, ps);
    return st;
}

void wt_learn_wind_compress(const wt_learn_wind *w, int nl, const double *ralt, double *rfrac, double *rvx, double *rvy,
                            double *sigma_x, double *sigma_y)
{
    double ff[WT_LEARN_MAX_ALT], junk[WT_LEARN_MAX_ALT > 64 ? WT_LEARN_MAX_ALT : 64];
    for (int a = 0; a < w->nalt; a++) ff[a] = w->fitted[a] ? w->fraction[a] : 0.0;
    wt_profile_compress(w->nalt, w->altitude, w->fraction, NULL, NULL, nl, ralt, rfrac, NULL, NULL);
    /* the wind over the fitted bins only: an unfitted bin's 0 is "unknown", not "still air" */
    wt_profile_compress(w->nalt, w->altitude, ff, w->vx, w->vy, nl, ralt, junk, rvx, rvy);
    if (!sigma_x && !sigma_y) return;
    double s1x[64] = {0}, s2x[64] = {0}, s1y[64] = {0}, s2y[64] = {0}, bx[64], by[64];
    for (int r = 0; r < w->nbatch; r++) {
        wt_profile_compress(w->nalt, w->altitude, ff, w->batch_vx[r], w->batch_vy[r], nl, ralt, junk, bx, by);
        for (int l = 0; l < nl && l < 64; l++) s1x[l] += bx[l], s2x[l] += bx[l] * bx[l], s1y[l] += by[l], s2y[l] += by[l] * by[l];
    }
    const int B = w->nbatch;
    for (int l = 0; l < nl && l < 64; l++) {
        double sx = B >= 2 ? sqrt(fmax(0.0, (s2x[l] - s1x[l] * s1x[l] / B) / (B - 1)) / B) : 0.0;
        double sy = B >= 2 ? sqrt(fmax(0.0, (s2y[l] - s1y[l] * s1y[l] / B) / (B - 1)) / B) : 0.0;
        if (sigma_x) sigma_x[l] = sx;
        if (sigma_y) sigma_y[l] = sy;
    }
}
