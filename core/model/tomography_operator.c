/* core/model/tomography_operator.c: the normal operator, right-hand side and (P)CG solve of the wavelet MAP
 * tomography (paper eq. eqn_lse; SPEC §6):
 *
 *   M c = W Σ_m Pᵀ Γᵀ Ĉ_m⁻¹ Γ P W⁻¹ c + α D c,   b = W Σ_m Pᵀ Γᵀ Ĉ_m⁻¹ s_m,   M c = b by (P)CG,
 *
 * as stages (inverse DWT, forward, adjoint by sensor groups, adjoint by layers) over the object's fixed thread
 * layout, so that the result does not depend on the thread count; the fp32 operator's float stages are
 * tomography_operator_f32.c's, called from the same stage sequence. */
#include "tomography_private.h"

#include <stdint.h>
#include <string.h>

#include "../la/vec.h"
#include "../op/noise.h"
#include "../op/prior.h"
#include "../op/projection.h"
#include "../op/wavelet.h"

/* y += α W C_φ⁻¹ Wᵀ c on layer l (or α D c for a diagonal prior), on the given work arrays. */
static void prior_layer(const wt_tomography *t, int l, const double *c, double *y, double *phi, double *q,
                        double *wwork, double *pwork)
{
    const int64_t a = t->off[l], nl = t->off[l + 1] - a;
    if (!t->full_prior) {
        for (int64_t i = 0; i < nl; i++) y[i] += t->alpha_d[a + i] * c[i];
        return;
    }
    if (t->space) { /* (space needs the full prior: checked at set-up) */
        wt_prior_apply_full(t->prior[l], t->alpha, c, q, pwork);
        for (int64_t i = 0; i < nl; i++) y[i] += q[i];
        return;
    }
    wt_wavelet_inverse(t->wav[l], c, phi, wwork);
    wt_prior_apply_full(t->prior[l], t->alpha, phi, q, pwork);
    wt_wavelet_forward(t->wav[l], q, phi, wwork);
    for (int64_t i = 0; i < nl; i++) y[i] += phi[i];
}

void wt_tomography_prior_apply_layer(wt_tomography *t, int l, const double *c, double *y)
{
    wt_tomography_work *w = t->work;
    if (!t->full_prior) prior_layer(t, l, c, y, NULL, NULL, NULL, NULL); /* no workspace (pphi may be NULL) */
    else prior_layer(t, l, c, y, w->phi + t->off[l], w->pphi + t->off[l], w->wwork, w->pwork);
}

size_t wt_tomography_prior_layer_work(const wt_tomography *t)
{
    return 2 * wt_tomography__max_layer(t) + t->wsize + t->pwsize;
}

void wt_tomography_prior_apply_layer_ws(const wt_tomography *t, int l, const double *c, double *y, double *ws)
{
    const size_t nmax = wt_tomography__max_layer(t);
    prior_layer(t, l, c, y, ws, ws + nmax, ws + 2 * nmax, ws + 2 * nmax + t->wsize);
}

/* phi = W⁻¹ c layer by layer; with phi32 (the fp32 operator) the transform in float instead: c rounded to float,
 * phi32 = W⁻¹ c in float, and phi = phi32 in double for the full prior's FFTs. In space phi is c itself: only the
 * rounding to phi32 runs.
 * The fp32 operator runs the LGS's forward (P, Γ) and adjoint in float; the NGS's part (their explicit term, Gᵀ φ
 * from the float layers, Ĉ⁻¹, G w) and everything after the sum stay double. At low noise the NGS weigh ~10⁵ times
 * the LGS: a float rounding before their weights reaches the NGS term only through the NGS's dozen global modes
 * (the rows of Ĉ⁻¹ Γ P), which the preconditioner's Woodbury term holds exactly; one after them (a float Γᵀ, Pᵀ,
 * accumulator or DWT) spreads 1e-7 of that large term over every mode, and moved the low-noise field WFE by
 * +0.07 nm (docs/results.md §30; test_tomography_f32 test_single_precision_ngs_term). */
/* Thread id's part (of nt; inside a parallel region): its layers */
static void layers_dwt_team(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi, float *phi32,
                            int id, int nt)
{
    const double b0 = wt_tomography__prof_t0(w);
    for (int l = 0; l < t->L; l++) {
        if (wt_tomography__owner_of(t, l, nt) != id) continue;
        const int64_t a = t->off[l], b = t->off[l + 1];
        if (!phi32) {
            wt_wavelet_inverse(t->wav[l], c + a, phi + a, w->wwork + (size_t)id * t->wsize);
        } else if (t->space) {
            for (int64_t i = a; i < b; i++) phi32[i] = (float)c[i];
        } else /* (c rounded as it is read; phi, the double copy the full prior's FFTs read, row by row) */
            wt_wavelet_inverse_f32_of64(t->wav[l], c + a, phi32 + a, t->full_prior ? phi + a : NULL,
                                        w->wwork32 + (size_t)id * t->wsize);
    }
    wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_INVERSE_DWT, id, b0);
}

static void layers_dwt(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi, float *phi32)
{
    if (t->space) { /* the unknowns are the values */
        if (phi != c) memcpy(phi, c, (size_t)t->n * sizeof *phi);
        if (!phi32) return;
    }
    const double t0 = wt_tomography__prof_t0(w);
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        layers_dwt_team(t, w, c, phi, phi32, id, nt);
    }
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_INVERSE_DWT, t0);
}

static void inverse_dwt(const wt_tomography *t, wt_tomography_work *w, const double *c, double *phi)
{
    layers_dwt(t, w, c, phi, NULL);
}

/* slopes = Γ P φ for every sensor */
static void forward_slopes(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *slopes)
{
    const double t0 = wt_tomography__prof_t0(w);
    wt_sensor_stack_set(&t->stack, 1.0, phi, slopes, w->phase, t->nthreads);
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t0);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m. Each accumulator group takes its sensors in index order and the
 * groups are summed in order, so the result does not depend on the threads (core/la/vec.h). */
static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c);
static void adjoint_run(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                        double *c, int f32);

/* The right-hand side's adjoint: in float too with the fp32 operator (the measurements rounded to float: ~1e-7 of
 * b, where the noise is ~1e-1) */
static void adjoint_slopes(const wt_tomography *t, wt_tomography_work *w, const double *slopes, double *c)
{
    adjoint_run(t, w, slopes, NULL, c, t->fp32);
}

/* In space with at least two layers per thread the adjoint runs by layers (adjoint_space), else by sensor groups */
static int by_layers(const wt_tomography *t) { return t->space && t->L >= 2 * t->nthreads; }

/* The unknowns in space (fourier): the result is the sum itself, so the adjoint splits by layers instead of by
 * sensor groups: every sensor's weighted slopes and Γᵀ first (one task per sensor, into its own phase), then per
 * layer the prior's term (or 0) and the sensors' projections in index order (one task per layer). No group
 * accumulators to zero and add (2 x 1.2 MB each at E-ELT size); any thread gives the same bits. With fewer
 * layers than twice the threads the split would idle a thread: pcg3 keeps the groups. With cx and the full
 * prior, c holds the prior's term on entry (normal: forward_slopes_prior wrote it there) and the sensors' terms
 * are added to it. */
static void adjoint_space(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c)
{
    const wt_system *sys = t->sys;
    const double t0 = wt_tomography__prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        const int id = wt_thread_id();
        double b0 = wt_tomography__prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m < t->S; m++) {
            const wt_sensor *s = &sys->sensors[m];
            const wt_noise *nz = t->noise[m];
            const double *x = slopes + s->offset;
            double *ws = w->weighted + s->offset;
            wt_noise_set_weight_many(&nz, 1, &x, &ws);
            wt_tomography__common_add(t, w, m, ws);
            wt_sensor_stack_phase_t(&t->stack, m, 1.0, ws, w->phase + (size_t)m * t->ncg);
        }
        wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
        wt_tomography__prof_handover(w, &t1);
        b0 = wt_tomography__prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            const int64_t a = t->off[l], nl = t->off[l + 1] - a;
            if (!(cx && t->full_prior)) memset(c + a, 0, (size_t)nl * sizeof *c);
            /* (else c already holds the prior's term: forward_slopes_prior wrote it there) */
            for (int m = 0; m < t->S; m++) wt_projection_apply_t(t->proj[m * t->L + l], 1.0, w->phase + (size_t)m * t->ncg, c + a);
        }
        wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
    }
    /* (the master's clock after the sensors' barrier) */
    wt_tomography__prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1);
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}

/* c = W Σ_m Pᵀ Γᵀ Ĉ⁻¹ slopes_m (+ α D cx when cx is given; with the full prior + W w->pphi, the α C_φ⁻¹ φ of
 * cx's layers, which normal() leaves there). The group sum, the transform and the prior term of a layer run
 * in one task (the same per-element operations as three passes). */
/* One accumulator group's share of the adjoint: its accumulator cleared, the group's weights side by side
 * (wt_noise_set_weight_many), then its sensors' Γᵀ and Pᵀ in index order */
static void adjoint_group(const wt_tomography *t, wt_tomography_work *w, int g, const double *slopes)
{
    const wt_system *sys = t->sys;
    double *acc = w->acc + (size_t)g * t->n;
    memset(acc, 0, (size_t)t->n * sizeof *acc);
    const wt_noise *nz[2 * WT_MAX_GS];
    const double *x[2 * WT_MAX_GS];
    double *ws[2 * WT_MAX_GS];
    int k = 0;
    for (int m = 0; m < t->S; m++) {
        if (t->group[m] != g) continue;
        const wt_sensor *s = &sys->sensors[m];
        nz[k] = t->noise[m];
        x[k] = slopes + s->offset;
        ws[k] = w->weighted + s->offset;
        k++;
    }
    wt_noise_set_weight_many(nz, k, x, ws);
    for (int m = 0; m < t->S; m++)
        if (t->group[m] == g) wt_tomography__common_add(t, w, m, w->weighted + sys->sensors[m].offset);
    for (int m = 0; m < t->S; m++)
        if (t->group[m] == g)
            wt_sensor_stack_apply_t_sensor(&t->stack, m, 1.0, w->weighted + sys->sensors[m].offset, acc,
                                           w->phase + (size_t)m * t->ncg);
}

/* The adjoint's last stage: the groups' sum (in group order; from the float accumulators w->acc32 with f32, the
 * fp32 operator's), the prior's term and (f32) the NGS term in equal element shares, then each layer's W on its
 * owner */
static void adjoint_layers_team(const wt_tomography *t, wt_tomography_work *w, const double *cx, double *c, int f32,
                                int id, int nt)
{
    const int64_t n = t->n;
    double *sum = t->space ? c : w->phi; /* in space the sum is the result */
    const double b0 = wt_tomography__prof_t0(w);
    /* the sums element by element, in equal shares of all layers (by layers, the 128² layer's owner had twice the
     * other thread's part: half the stage's time went to one thread waiting), then each layer's W on its owner */
    const int64_t i0 = n * id / nt, i1 = n * (id + 1) / nt;
    if (f32) /* the groups' float sums (LGS), added in double */
        for (int64_t i = i0; i < i1; i++) {
            double v = w->acc32[i];
            for (int g = 1; g < WT_GROUPS; g++) v += w->acc32[(int64_t)g * n + i];
            sum[i] = v;
        }
    else
        for (int64_t i = i0; i < i1; i++) { /* wt_vec_sum_groups, groups in order */
            double v = w->acc[i];
            for (int g = 1; g < WT_GROUPS; g++) v += w->acc[(int64_t)g * n + i];
            sum[i] = v;
        }
    if (cx && t->full_prior)
        for (int64_t i = i0; i < i1; i++) sum[i] += w->pphi[i];
    if (f32 && t->any64) /* the fp32 operator's NGS, in double */
        wt_tomography__ngs_adjoint(t, w->weighted, i0, i1, sum + i0);
    if (!t->space) {
#pragma omp barrier
        for (int l = 0; l < t->L; l++) {
            if (wt_tomography__owner_of(t, l, nt) != id) continue;
            const int64_t a = t->off[l], b = t->off[l + 1];
            wt_wavelet_forward(t->wav[l], w->phi + a, c + a, w->wwork + (size_t)id * t->wsize);
            if (cx && !t->full_prior)
                for (int64_t i = a; i < b; i++) c[i] += t->alpha_d[i] * cx[i];
        }
    }
    wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
}

/* The adjoint by sensor groups then by layers (or by layers alone, by_layers), in double or, with f32, the fp32
 * operator's (slopes: then NULL for the forward's float slopes, or the double ones to round: the right-hand side) */
static void adjoint_run(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                        double *c, int f32)
{
    /* the LGS's common focus term needs two sums over all LGS slopes before any sensor's weight (the operator's
     * fp32 slopes are the float ones its forward wrote; the right-hand side's the double measurements) */
    if (t->fc_e) wt_tomography__common_coef(t, w, slopes, f32 && !slopes ? w->slopes32 : NULL);
    if (by_layers(t)) {
        if (f32) wt_tomography__adjoint_space_f32(t, w, slopes, cx, c);
        else adjoint_space(t, w, slopes, cx, c);
        return;
    }
    /* the groups and then the layers' stage in one parallel region (as dwt_forward_f32) */
    const double t0 = wt_tomography__prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
#pragma omp for schedule(static) nowait
        for (int g = 0; g < WT_GROUPS; g++) {
            const double b0 = wt_tomography__prof_t0(w);
            if (f32) wt_tomography__adjoint_group_f32(t, w, g, slopes);
            else adjoint_group(t, w, g, slopes);
            wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
        }
        wt_tomography__prof_handover(w, &t1);
        adjoint_layers_team(t, w, cx, c, f32, id, nt);
    }
    wt_tomography__prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1);
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}

static void adjoint_prior(const wt_tomography *t, wt_tomography_work *w, const double *slopes, const double *cx,
                          double *c)
{
    adjoint_run(t, w, slopes, cx, c, 0);
}

/* slopes = Γ P φ for every sensor and w->pphi = α C_φ⁻¹ φ on every layer (the full prior's term, which the
 * adjoint adds back): independent tasks, each writing its own output, so any thread may run any of them (the
 * same bits on any thread count). The layers' FFTs first, largest first (layer 0's 128² takes as long as
 * several sensors): with one dynamic loop the other thread takes the small layers and then the sensors, where
 * a loop over the layers alone (transform + FFT per layer) left it idle for half of the large layer's task. */
static void forward_slopes_prior(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *slopes,
                                 double *pphi)
{
    const double t0 = wt_tomography__prof_t0(w);
#pragma omp parallel num_threads(t->nthreads)
    {
        const double b0 = wt_tomography__prof_t0(w);
        int id, nt;
        wt_thread_team(&id, &nt);
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            if (wt_tomography__owner_of(t, l, nt) == id)
                wt_prior_apply_full(t->prior[l], t->alpha, phi + t->off[l], pphi + t->off[l],
                                    w->pwork + (size_t)id * t->pwsize);
        }
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m < t->S; m++)
            wt_sensor_stack_set_sensor(&t->stack, m, 1.0, phi, slopes, w->phase + (size_t)m * t->ncg);
        wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_FORWARD, id, b0);
    }
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t0);
}

/* The fp32 operator's first two stages in one parallel region (a region's start and end cost about two barriers,
 * and the fp32 stages are short): the layers' transforms (phi32; phi in double for the full prior's FFTs), then the forward.
 * In space phi is c and only its rounding runs. */
static void dwt_forward_f32(const wt_tomography *t, wt_tomography_work *w, const double *c, double *pphi)
{
    double *phi = t->space ? (double *)c : w->phi;
    const double t0 = wt_tomography__prof_t0(w);
    double t1 = t0;
#pragma omp parallel num_threads(t->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        layers_dwt_team(t, w, c, phi, w->phi32, id, nt);
        wt_tomography__prof_handover(w, &t1);
        wt_tomography__forward_f32_team(t, w, phi, pphi, id, nt);
    }
    wt_tomography__prof_wall_to(t, w, WT_TOMO_STAGE_INVERSE_DWT, t0, t1);
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_FORWARD, t1);
}

static void normal_f32(const wt_tomography *t, wt_tomography_work *w, const double *c, double *y)
{
    dwt_forward_f32(t, w, c, t->full_prior ? (by_layers(t) ? y : w->pphi) : NULL);
    adjoint_run(t, w, NULL, c, y, 1);
}

/* y = M c, overwritten: the operator of the PCG (wt_linop_fn), with no extra pass */
static void normal(const wt_tomography *t, wt_tomography_work *w, const double *c, double *y)
{
    if (t->fp32) {
        normal_f32(t, w, c, y);
        return;
    }
    const double *phi = c;
    if (!t->space) {
        inverse_dwt(t, w, c, w->phi);
        phi = w->phi;
    }
    /* adjoint_space adds the sensors' terms onto the prior's, so the prior's term goes straight to y (a copy of
     * y's size less per apply; the same values in the same order) */
    if (t->full_prior) forward_slopes_prior(t, w, phi, w->slopes, by_layers(t) ? y : w->pphi);
    else forward_slopes(t, w, phi, w->slopes);
    adjoint_prior(t, w, w->slopes, c, y);
}

/* The public forms accumulate (y ← y + α A x, as core/op does); w->b is their scratch (in the object's
 * own workspace it is also the solve's right-hand side, recomputed by every solve). */
void wt_tomography_apply_ws(const wt_tomography *t, wt_tomography_work *w, double alpha, const double *c, double *y)
{
    normal(t, w, c, w->b);
    for (int64_t i = 0; i < t->n; i++) y[i] += alpha * w->b[i];
}

void wt_tomography_apply(wt_tomography *t, double alpha, const double *c, double *y)
{
    wt_tomography_apply_ws(t, t->work, alpha, c, y);
}

void wt_tomography_rhs(wt_tomography *t, double alpha, const double *s, double *b)
{
    wt_tomography_work *w = t->work;
    adjoint_slopes(t, w, s, w->b);
    for (int64_t i = 0; i < t->n; i++) b[i] += alpha * w->b[i];
}

/* (neither is a stage of M or of the solve: the profile leaves them out) */
void wt_tomography_slopes(wt_tomography *t, double alpha, const double *c, double *s)
{
    wt_tomography_work *w = t->work;
    const int on = w->prof_on;
    w->prof_on = 0;
    inverse_dwt(t, w, c, w->phi);
    wt_sensor_stack_apply(&t->stack, alpha, w->phi, s, w->phase, t->nthreads);
    w->prof_on = on;
}

void wt_tomography_layers(wt_tomography *t, const double *c, double *phi)
{
    const int on = t->work->prof_on;
    t->work->prof_on = 0;
    inverse_dwt(t, t->work, c, phi);
    t->work->prof_on = on;
}

static void apply_cb(void *user, const double *x, double *y)
{
    const wt_tomography *t = user;
    normal(t, t->work, x, y);
}

/* The preconditioner's callback with the profile's clock around it (wt_tomography_profile_start) */
typedef struct timed_precond {
    const wt_tomography *t;
    wt_pcg_precond inner;
} timed_precond;

static void timed_precond_apply(void *user, const double *r, double *z)
{
    const timed_precond *tp = user;
    const double t0 = wt_tomography__prof_t0(tp->t->work);
    tp->inner.apply(tp->inner.user, r, z);
    wt_tomography__prof_wall(tp->t, tp->t->work, WT_TOMO_STAGE_PRECOND, t0);
}

static int solve(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int continuing, int max_iter,
                 double rtol, double *history, wt_pcg_result *res)
{
    const double t0 = wt_tomography__prof_t0(t->work);
    /* A NaN or Inf slope reaches the right-hand side (every slope has a weight and a non-empty Γᵀ, Pᵀ; NaN · 0 is
     * NaN): its n values are tested instead of the 2.5 times as many slopes (a pass over them per frame), and the slopes
     * searched only then; the solver's state is not touched (its next right-hand side is a buffer of its own) */
    double *b = wt_pcg_rhs(t->pcg);
    adjoint_slopes(t, t->work, s, b);
    if (wt_vec_first_nonfinite(b, t->n) >= 0) {
        const int64_t bad = wt_vec_first_nonfinite(s, t->sys->nslopes);
        if (bad >= 0)
            return WT_ERROR(t->ctx, WT_ERR_NUMERIC, "tomography: slope %lld is %g (NaN or Inf)", (long long)bad, s[bad]);
        return WT_ERROR(t->ctx, WT_ERR_NUMERIC, "tomography: the right-hand side of finite slopes is not finite (a "
                        "slope beyond the operator's range%s)", t->fp32 ? ", e.g. above float's 3.4e38" : "");
    }
    timed_precond tp = {t, P};
    if (t->work->prof_on && P.apply) P = (wt_pcg_precond){timed_precond_apply, &tp};
    if (t->fresh) continuing = 0, t->fresh = 0;
    const int st = wt_pcg_solve_rhs(t->pcg, apply_cb, t, NULL, P.apply, P.user, c, continuing,
                                    max_iter >= 0 ? max_iter : t->iterations, rtol >= 0 ? rtol : t->tol, history, res);
    wt_tomography__prof_wall(t, t->work, WT_TOMO_STAGE_SOLVE, t0);
    return st;
}

int wt_tomography_solve(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter, double rtol,
                        double *history, wt_pcg_result *res)
{
    return solve(t, P, s, c, 0, max_iter, rtol, history, res);
}

int wt_tomography_solve_continue(wt_tomography *t, wt_pcg_precond P, const double *s, double *c, int max_iter,
                                 double rtol, double *history, wt_pcg_result *res)
{
    return solve(t, P, s, c, 1, max_iter, rtol, history, res);
}
