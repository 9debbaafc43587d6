/* core/model/tomography_operator_f32.c: the float stages of the single-precision operator
 * (recon.<variant>.operator_precision = "fp32"; SPEC §6):
 *
 *   M c = Σ_LGS Pᵀ Γᵀ Ĉ⁻¹ Γ P φ (float)  +  G Ĉ⁻¹ Gᵀ φ (NGS, double)  +  α D c,   φ = W⁻¹ c,
 *
 * the LGS's forward and adjoint in float, the NGS's through their explicit term (tomography_ngs.c). The stage
 * sequence, the inverse transform and the layers' sum in double are tomography_operator.c's. */
#include "tomography_private.h"

#include <string.h>

#include "../op/noise.h"
#include "../op/projection.h"

/* The fp32 operator (t->fp32): the same stages as the double one (tomography_operator.c), the LGS's part in float:
 * w->phi32 → Γ P → w->slopes32 → Ĉ⁻¹ → Γᵀ → Pᵀ into float group accumulators (or per-layer float sums, by layers),
 * which the layers' stage adds up in double; the NGS's in double through their explicit term (tomography_ngs.c): Gᵀ φ
 * as one more task of the forward, Ĉ⁻¹ in the groups' stage, G w in the layers' stage's sum (tomography_operator.c's
 * layers_dwt says why). */

/* slopes32 = Γ P phi32 for every LGS, the NGS's slopes Gᵀ phi32 into w->slopes; with pphi (the full prior) also
 * pphi = α C_φ⁻¹ φ per layer, first (as forward_slopes_prior) */
void wt_tomography__forward_f32_team(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *pphi,
                                     int id, int nt)
{
    const double b0 = wt_tomography__prof_t0(w);
    for (int k = 0; pphi && k < t->L; k++) {
        const int l = t->by_size[k];
        if (wt_tomography__owner_of(t, l, nt) == id)
            wt_prior_apply_full(t->prior[l], t->alpha, phi + t->off[l], pphi + t->off[l],
                                w->pwork + (size_t)id * t->pwsize);
    }
#pragma omp for schedule(dynamic, 1) nowait
    for (int m = 0; m <= t->S; m++) /* the LGS, then (m = S) the NGS term's Gᵀ φ into the double slopes */
        if (m == t->S) {
            if (t->any64) wt_tomography__ngs_forward(t, w->phi32, w->slopes);
        } else if (t->s32[m])
            wt_sensor_stack_set_sensor_f32(&t->stack, m, 1.0f, w->phi32, w->slopes32, w->phase32 + (size_t)m * t->ncg);
    wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_FORWARD, id, b0);
}

/* The float weights of the k sensors ms (LGS) in one call (wt_noise_set_weight_many_f32) */
static void weigh_f32(const wt_tomography *t, wt_tomography_work *w, int k, const int *ms)
{
    /* zeroed: gcc -O1 (the sanitiser build) cannot see that the first k entries are all that is read */
    const wt_noise *nz[2 * WT_MAX_GS] = {0};
    const float *x[2 * WT_MAX_GS] = {0};
    float *ws[2 * WT_MAX_GS] = {0};
    for (int q = 0; q < k; q++) {
        const int64_t off = t->sys->sensors[ms[q]].offset;
        nz[q] = t->noise[ms[q]];
        x[q] = w->slopes32 + off;
        ws[q] = w->weighted32 + off;
    }
    wt_noise_set_weight_many_f32(nz, k, x, ws);
    for (int q = 0; q < k; q++) wt_tomography__common_add_f32(t, w, ms[q], ws[q]);
}

/* Sensor m's slopes s (double: the right-hand side's measurements) rounded into w->slopes32 */
static void round_slopes(const wt_tomography *t, wt_tomography_work *w, int m, const double *s)
{
    const int64_t a = t->sys->sensors[m].offset, b = a + t->sys->sensors[m].nslopes;
    for (int64_t i = a; i < b; i++) w->slopes32[i] = (float)s[i];
}

/* The double weights of the NGS of group g (g < 0: every NGS), of s or (NULL) of the forward's slopes
 * (wt_tomography__ngs_forward), into w->weighted (the NGS term's G applies them in the layers' stage) */
static void weigh_ngs(const wt_tomography *t, wt_tomography_work *w, int g, const double *s)
{
    const wt_noise *nz[2 * WT_MAX_GS];
    const double *x[2 * WT_MAX_GS];
    double *ws[2 * WT_MAX_GS];
    int k = 0;
    for (int m = 0; m < t->S; m++) {
        if ((g >= 0 && t->group[m] != g) || t->s32[m]) continue;
        nz[k] = t->noise[m];
        x[k] = (s ? s : w->slopes) + t->sys->sensors[m].offset;
        ws[k] = w->weighted + t->sys->sensors[m].offset;
        k++;
    }
    wt_noise_set_weight_many(nz, k, x, ws);
}

/* One group's share of the fp32 adjoint; s: the slopes to round first (the right-hand side), or NULL (the operator:
 * its forward left them in w->slopes32) */
void wt_tomography__adjoint_group_f32(const wt_tomography *t, wt_tomography_work *w, int g, const double *s)
{
    const wt_system *sys = t->sys;
    float *acc = w->acc32 + (size_t)g * t->n;
    memset(acc, 0, (size_t)t->n * sizeof *acc);
    int ms[2 * WT_MAX_GS], k = 0;
    for (int m = 0; m < t->S; m++)
        if (t->group[m] == g && t->s32[m]) ms[k++] = m;
    for (int q = 0; s && q < k; q++) round_slopes(t, w, ms[q], s);
    weigh_f32(t, w, k, ms);
    for (int q = 0; q < k; q++)
        wt_sensor_stack_apply_t_sensor_f32(&t->stack, ms[q], 1.0f, w->weighted32 + sys->sensors[ms[q]].offset, acc,
                                           w->phase32 + (size_t)ms[q] * t->ncg);
    if (t->any64) weigh_ngs(t, w, g, s);
}

/* adjoint_space in float: every sensor's weights and Γᵀ, then per layer the sensors' Pᵀ into a float sum that
 * is added (or, without the full prior's term there, copied) into c */
void wt_tomography__adjoint_space_f32(const wt_tomography *t, wt_tomography_work *w, const double *s,
                                      const double *cx, double *c)
{
    const double t0 = wt_tomography__prof_t0(w);
    double t1 = t0;
    const size_t nl32 = wt_tomography__lay32_size(t);
#pragma omp parallel num_threads(t->nthreads)
    {
        const int id = wt_thread_id();
        double b0 = wt_tomography__prof_t0(w);
#pragma omp for schedule(dynamic, 1) nowait
        for (int m = 0; m <= t->S; m++) { /* the LGS, then (m = S) every NGS's double weights */
            if (m == t->S) {
                if (t->any64) weigh_ngs(t, w, -1, s);
            } else if (t->s32[m]) {
                if (s) round_slopes(t, w, m, s);
                weigh_f32(t, w, 1, &m);
                wt_sensor_stack_phase_t_f32(&t->stack, m, 1.0f, w->weighted32 + t->sys->sensors[m].offset,
                                            w->phase32 + (size_t)m * t->ncg);
            }
        }
        wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, id, b0);
        wt_tomography__prof_handover(w, &t1);
        b0 = wt_tomography__prof_t0(w);
        float *sum = w->lay32 + (size_t)id * nl32;
#pragma omp for schedule(dynamic, 1) nowait
        for (int k = 0; k < t->L; k++) {
            const int l = t->by_size[k];
            const int64_t a = t->off[l], nl = t->off[l + 1] - a;
            memset(sum, 0, (size_t)nl * sizeof *sum);
            for (int m = 0; m < t->S; m++)
                if (t->s32[m]) wt_projection_apply_t_f32(t->proj[m * t->L + l], 1.0f, w->phase32 + (size_t)m * t->ncg, sum);
            if (cx && t->full_prior)
                for (int64_t i = 0; i < nl; i++) c[a + i] += sum[i];
            else
                for (int64_t i = 0; i < nl; i++) c[a + i] = sum[i];
            if (t->any64) wt_tomography__ngs_adjoint(t, w->weighted, a, a + nl, c + a); /* the NGS's term, in double */
        }
        wt_tomography__prof_busy(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, id, b0);
    }
    wt_tomography__prof_wall_to(t, w, WT_TOMO_STAGE_ADJOINT_SENSORS, t0, t1);
    wt_tomography__prof_wall(t, w, WT_TOMO_STAGE_ADJOINT_LAYERS, t1);
}
