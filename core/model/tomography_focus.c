/* core/model/tomography_focus.c: the LGS focus removal's parts that are the tomography's own (SPEC §4,
 * recon.lgs_focus_removal): the focus slope pattern of a sensor, the check that an NGS measures focus, and, with
 * recon.lgs_focus_mode = "common", the term of the LGS noise weight that couples the LGS (equations below). Each
 * LGS's own focus (mode each) is its noise object's (core/op/noise.c). */
#include "tomography_private.h"

#include <string.h>

/* ---- LGS focus removal (recon.lgs_focus_removal) -----------------------------------------------------
 * A change of the sodium centroid's altitude Δh moves every LGS spot by (r − l) Δh / H²: a tilt (the launch
 * offset l) plus a focus. T then projects each LGS's slopes onto span{tip, tilt, f} with f the focus slope
 * pattern (core/op/noise.h), and the tomography's focus comes from the NGS; one of them must measure it. */
int wt_tomography__focus_pattern(wt_context *ctx, const wt_sensor *s, double *f)
{
    int st = WT_OK;
    double *cx = NULL;
    WT_ALLOC(ctx, cx, 2 * (size_t)s->nsub, "subaperture centres");
    for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &cx[k], &cx[s->nsub + k]);
    st = wt_noise_focus_pattern(s->nsub, cx, cx + s->nsub, f);
fail:
    wt_free(ctx, cx);
    return st;
}

int wt_tomography__focus_check(const wt_tomography *t, const char *source)
{
    const wt_system *sys = t->sys;
    int st = WT_OK, ok = 0;
    double *f = NULL;
    for (int m = 0; m < sys->nsensors && !ok; m++) {
        const wt_sensor *s = &sys->sensors[m];
        if (s->kind != WT_SENSOR_NGS || s->nsub < 2) continue;
        WT_ALLOC(t->ctx, f, 2 * (size_t)s->nsub, "focus pattern");
        st = wt_tomography__focus_pattern(t->ctx, s, f);
        if (st < 0) goto fail;
        ok = st;
        st = WT_OK;
        wt_free(t->ctx, f);
        f = NULL;
    }
    if (!ok)
        st = WT_ERROR(t->ctx, WT_ERR_CONFIG,
                      "%s: recon.lgs_focus_removal = true removes the LGS focus (%s), and no NGS measures it (%d NGS, none "
                      "with 2x2 subapertures: ngs.subapertures needs a 2)", source ? source : "tomography",
                      t->lgs_focus == 2 ? "their common focus, recon.lgs_focus_mode = \"common\"" : "each LGS's focus",
                      sys->nngs);
fail:
    wt_free(t->ctx, f);
    return st;
}

/* ---- The LGS's common focus (recon.lgs_focus_mode = "common", t->lgs_focus == 2) -------------------------------
 *
 * A change Δh of the sodium centroid's altitude reads as the same focus on every LGS. With e_j the unit focus slope
 * pattern of LGS j (core/op/noise.h, ⟂ its tip and tilt) and n LGS, the one direction projected out beyond the
 * per-LGS tip-tilt is f_c = (e_1, …, e_n)/√n over the stacked LGS slopes (unit, ⟂ every T_tt,j). With
 * Q = I − T_tt (block-diagonal) and W_tt = Q C̃⁻¹ Q the per-LGS weights (the noise objects' own), P = Q − f_c f_cᵀ
 * gives
 *     Ĉ⁻¹ = P C̃⁻¹ P = W_tt − f_c wᵀ − w f_cᵀ + γ f_c f_cᵀ,   w = W_tt f_c,  γ = f_cᵀ W_tt f_c
 * (Q f_c = f_c). Per LGS, with g_j = W_tt,j e_j, P = Σ_j e_jᵀ x_j, G = Σ_j g_jᵀ x_j and γ = Σ_j e_jᵀ g_j / n:
 *     (Ĉ⁻¹ x)_j = W_tt,j x_j + c1 e_j + c2 g_j,   c1 = (γ P − G)/n,  c2 = −P/n,
 * a rank-2 term coupling the LGS through two sums of the input slopes: the sensors' weights stay per sensor and
 * batched, and the two sums are taken once before them. */

int wt_tomography__common_alloc(wt_tomography *t)
{
    const wt_system *sys = t->sys;
    wt_context *ctx = t->ctx;
    int st = WT_OK;
    if (t->lgs_focus != 2 || sys->nlgs == 0) return WT_OK;
    const wt_sensor *last = &sys->sensors[sys->nlgs - 1];
    t->fc_n = last->offset + last->nslopes; /* the LGS's slopes come first, contiguous */
    WT_ALLOC(ctx, t->fc_e, (size_t)t->fc_n, "common focus pattern");
    WT_ALLOC(ctx, t->fc_g, (size_t)t->fc_n, "common focus weight");
    WT_ALLOC(ctx, t->fc_e32, (size_t)t->fc_n, "common focus pattern (float)");
    WT_ALLOC(ctx, t->fc_g32, (size_t)t->fc_n, "common focus weight (float)");
    for (int m = 0; m < sys->nlgs; m++) {
        const wt_sensor *s = &sys->sensors[m];
        st = wt_tomography__focus_pattern(ctx, s, t->fc_e + s->offset);
        if (st < 0) return st;
        if (st == 0)
            return WT_ERROR(ctx, WT_ERR_CONFIG, "recon.lgs_focus_mode = \"common\": LGS %d has no focus pattern (%d "
                            "subaperture(s))", m, s->nsub);
        st = WT_OK;
        for (int i = 0; i < s->nslopes; i++) t->fc_e32[s->offset + i] = (float)t->fc_e[s->offset + i];
    }
fail:
    return st;
}

void wt_tomography__common_free(wt_tomography *t)
{
    wt_free(t->ctx, t->fc_e);
    wt_free(t->ctx, t->fc_g);
    wt_free(t->ctx, t->fc_e32);
    wt_free(t->ctx, t->fc_g32);
    t->fc_e = t->fc_g = NULL;
    t->fc_e32 = t->fc_g32 = NULL;
}

void wt_tomography__common_update(wt_tomography *t)
{
    const wt_system *sys = t->sys;
    if (!t->fc_e) return;
    double q = 0.0;
    for (int m = 0; m < sys->nlgs; m++) {
        const wt_sensor *s = &sys->sensors[m];
        double *g = t->fc_g + s->offset;
        const double *e = t->fc_e + s->offset;
        memset(g, 0, (size_t)s->nslopes * sizeof *g);
        wt_noise_apply_weight(t->noise[m], 1.0, e, g);
        for (int i = 0; i < s->nslopes; i++) {
            q += e[i] * g[i];
            t->fc_g32[s->offset + i] = (float)g[i];
        }
    }
    t->fc_gamma = q / sys->nlgs;
}

void wt_tomography__common_coef(const wt_tomography *t, wt_tomography_work *w, const double *x, const float *x32)
{
    if (!t->fc_e) return;
    double p = 0.0, g = 0.0;
    if (x)
        for (int64_t i = 0; i < t->fc_n; i++) {
            p += t->fc_e[i] * x[i];
            g += t->fc_g[i] * x[i];
        }
    else
        for (int64_t i = 0; i < t->fc_n; i++) {
            p += t->fc_e[i] * (double)x32[i];
            g += t->fc_g[i] * (double)x32[i];
        }
    const double n = t->sys->nlgs;
    w->fc_c1 = (t->fc_gamma * p - g) / n;
    w->fc_c2 = -p / n;
}

void wt_tomography__common_add(const wt_tomography *t, const wt_tomography_work *w, int m, double *y)
{
    if (!t->fc_e || m >= t->sys->nlgs) return;
    const wt_sensor *s = &t->sys->sensors[m];
    const double *e = t->fc_e + s->offset, *g = t->fc_g + s->offset, c1 = w->fc_c1, c2 = w->fc_c2;
    for (int i = 0; i < s->nslopes; i++) y[i] += c1 * e[i] + c2 * g[i];
}

void wt_tomography__common_add_f32(const wt_tomography *t, const wt_tomography_work *w, int m, float *y)
{
    if (!t->fc_e || m >= t->sys->nlgs) return;
    const wt_sensor *s = &t->sys->sensors[m];
    const float *e = t->fc_e32 + s->offset, *g = t->fc_g32 + s->offset;
    const float c1 = (float)w->fc_c1, c2 = (float)w->fc_c2;
    for (int i = 0; i < s->nslopes; i++) y[i] += c1 * e[i] + c2 * g[i];
}

void wt_tomography_weight_common(const wt_tomography *t, const double *x, double *y)
{
    if (!t->fc_e) return;
    wt_tomography_work w = {0};
    wt_tomography__common_coef(t, &w, x, NULL);
    for (int m = 0; m < t->sys->nlgs; m++)
        wt_tomography__common_add(t, &w, m, y + t->sys->sensors[m].offset);
}

const double *wt_tomography_common_focus(const wt_tomography *t) { return t->fc_e; }
