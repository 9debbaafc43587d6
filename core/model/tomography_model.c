/* core/model/tomography_model.c: what the reconstructor's atmosphere model sets in the tomography (SPEC §6, §12):
 *
 *   the prior's strength per layer   D_ℓ ∝ 1 / (f_ℓ r0^(−5/3))   (the von Kármán spectrum is linear in f r0^(−5/3) at
 *                                    fixed L0: a new model rescales every prior, it does not rebuild it),
 *   the layer-binning model error σ²_e,m = Σ_k f_k r0^(−5/3) u_m(h_k)   (u: a unit layer's, below),
 *   the sub-grid model error         σ²_g,m = Σ_k f_k r0^(−5/3) c_k² Σ_l b_kl a(Δ_l, d c_k)   (below),
 *   the sensors' noise weights       C̃_m = max(κσ², σ²_g,m) (…) + σ²_e,m I,
 *
 * at set-up (wt_tomography_alloc) and whenever the model changes (wt_tomography_set_profile: the loop that learns
 * its atmosphere, SPEC §12 "Updates"). The projections, wavelets and the NGS term do not depend on the model. */
#include "tomography_private.h"

#include <math.h>
#include <string.h>

#include "../base/rng.h"
#include "profile.h"
#include "sensing.h"

void wt_tomography__bin_profile(int L, const double *alt, int natm, const double *atm_alt, const double *atm_frac,
                                double *frac)
{
    /* compressed (SPEC §12, wt_profile_compress), then floored: a layer that receives less than
     * WT_PRIOR_FRACTION_FLOOR keeps that much, so that its prior still regularises it (a zero fraction is an
     * infinite prior weight, a layer the data could not move) */
    wt_profile_compress(natm, atm_alt, atm_frac, NULL, NULL, L, alt, frac, NULL, NULL);
    for (int l = 0; l < L; l++)
        if (frac[l] < WT_PRIOR_FRACTION_FLOOR) frac[l] = WT_PRIOR_FRACTION_FLOOR;
}

/* ---- Layer-binning model error of the LGS slopes (recon.model_error) ---------------------------------
 *
 * The prior puts the Cn² of a true layer at altitude h on the two nearest reconstruction layers
 * (wt_profile_bin_altitude): the model sees the layer's screen φ as (1 − w) φ at h_l plus w φ at h_{l+1}. Sensor m
 * then predicts Γ_m[(1 − w) P_m(h_l) + w P_m(h_{l+1})] φ where it measures Γ_m P_m(h) φ; the difference
 * (sub-metre structure seen through the shifts (h − h_l)θ_m and the LGS cone (h − h_l) r / H) cannot be
 * explained by any layer of the model, and at low noise the MAP explains it anyway with wrong
 * structure on the other layers. So it is treated as noise ("tomographic error as noise"): its variance
 * per slope, averaged over the sensor's slopes with their global tip-tilt removed (the weight removes
 * it; and their focus with recon.lgs_focus_removal: all of it in mode each, the 1/n_LGS share of its power that
 * the common direction f_c carries in mode common, as for focus errors independent between the LGS), is added to σ²:
 *   σ²_e,m = Σ_k E|(I − T) Γ_m [P_m(h_k) − (1 − w_k) P_m(h_l) − w_k P_m(h_{l+1})] φ_k|² / (2 nsub),
 * φ_k drawn from the layer's exact wavelet prior (Cn² fraction f_k) on the finest reconstruction
 * spacing, WT_MODEL_ERROR_DRAWS draws per layer with a fixed seed (the reconstructor stays a
 * deterministic function of the configuration). Zero when every true layer sits on a reconstruction
 * altitude (cg9's default layers). Only the LGS: the NGS are the only tip-tilt/low-order sensors and
 * average over 21–42 m, where the linear split is accurate (SPEC §6; docs/design.md).
 * The term is linear in each layer's f_k r0^(−5/3) (the screen scales with its square root): a model that
 * changes is served from unit layers (f = 1, r0 = 1 m) kept per altitude (wt_tomography_set_profile). */
enum { WT_MODEL_ERROR_DRAWS = 4 };

static void subgrid_error_add(const wt_tomography *t, wt_tomography *mt, double r0, int natm, const double *atm_alt,
                              const double *atm_frac, double *var_e);

void wt_tomography__model_error_grid(wt_tomography *t, const wt_recon_variant_config *var, int wavelet_levels)
{
    /* one sample grid for every true layer: the finest spacing, as wide as the widest layer */
    double dx = var->spacing[0], width = 0.0;
    for (int l = 0; l < t->L; l++) {
        if (var->spacing[l] < dx) dx = var->spacing[l];
        if (var->size[l] * var->spacing[l] > width) width = var->size[l] * var->spacing[l];
    }
    int n = 1 << wavelet_levels;
    while (n * dx < width - 1e-9) n *= 2;
    t->me_dx = dx;
    t->me_n = n;
}

/* var_e[m] += the model error of the natm layers (alt, frac) with r0, layer k drawn from stream stream0 + k */
static int model_error_add(wt_tomography *t, double r0, int natm, const double *atm_alt, const double *atm_frac,
                           uint64_t stream0, double *var_e)
{
    int st = WT_OK;
    wt_context *ctx = t->ctx;
    const wt_system *sys = t->sys;
    wt_wavelet *wav = NULL;
    wt_prior *prior = NULL;
    wt_projection *proj[3] = {NULL, NULL, NULL};
    double *c = NULL, *phi = NULL, *work = NULL, *ph = NULL, *sl = NULL, *fp = NULL;
    const double dx = t->me_dx;
    const int n = t->me_n;
    const wt_grid g = wt_grid_layer(n, dx);
    const int64_t np = wt_grid_size(&g);
    int nslopes_max = 0;
    for (int m = 0; m < t->S; m++)
        if (sys->sensors[m].nslopes > nslopes_max) nslopes_max = sys->sensors[m].nslopes;
    WT_TRY(wt_wavelet_alloc(ctx, n, t->wavelet_order, t->wavelet_levels, &wav));
    WT_ALLOC(ctx, c, np, "model-error coefficients");
    WT_ALLOC(ctx, phi, (size_t)WT_MODEL_ERROR_DRAWS * np, "model-error screens");
    WT_ALLOC(ctx, work, wt_wavelet_work_size(wav), "model-error wavelet workspace");
    WT_ALLOC(ctx, ph, t->ncg, "model-error phase");
    WT_ALLOC(ctx, sl, nslopes_max, "model-error slopes");
    if (t->lgs_focus) WT_ALLOC(ctx, fp, nslopes_max, "model-error focus pattern");
    for (int k = 0; k < natm; k++) {
        const double h = atm_alt[k], f = atm_frac[k];
        int l;
        double w;
        wt_profile_bin_altitude(t->L, t->alt, h, &l, &w);
        if (f <= 0.0 || (w == 0.0 && fabs(h - t->alt[l]) <= 1e-6 * fmax(1.0, h))) continue;
        WT_TRY(wt_prior_alloc(ctx, wav, dx, r0, f, t->L0, WT_PRIOR_EXACT, NULL, &prior));
        const double *d = wt_prior_diag(prior);
        wt_rng rng;
        wt_rng_init(&rng, 0x6d6f64656c657272ULL, stream0 + (uint64_t)k); /* fixed: "modelerr", one stream per layer */
        for (int r = 0; r < WT_MODEL_ERROR_DRAWS; r++) {
            for (int64_t i = 0; i < np; i++) c[i] = wt_rng_normal(&rng) / sqrt(d[i]);
            wt_wavelet_inverse(wav, c, phi + (size_t)r * np, work);
        }
        wt_prior_free(prior);
        prior = NULL;
        const double alt3[3] = {h, t->alt[l], w > 0.0 ? t->alt[l + 1] : t->alt[l]};
        const double wt3[3] = {1.0, -(1.0 - w), -w};
        for (int m = 0; m < t->S; m++) {
            const wt_sensor *s = &sys->sensors[m];
            if (s->kind != WT_SENSOR_LGS) continue;
            for (int q = 0; q < 3; q++)
                WT_TRY(wt_projection_alloc(ctx, 1, &g, &alt3[q], s->altitude, s->theta_x, s->theta_y, &sys->sense_grid,
                                           wt_shack_hartmann_corner_mask(s->sh), 0, &proj[q]));
            double sum = 0.0;
            if (fp) {
                st = wt_tomography__focus_pattern(ctx, s, fp);
                if (st < 0) goto fail;
                st = WT_OK; /* an LGS of the focus check's system has its pattern */
            }
            for (int r = 0; r < WT_MODEL_ERROR_DRAWS; r++) {
                memset(ph, 0, (size_t)t->ncg * sizeof *ph);
                for (int q = 0; q < 3; q++)
                    if (wt3[q] != 0.0) wt_projection_apply(proj[q], wt3[q], phi + (size_t)r * np, ph);
                memset(sl, 0, (size_t)s->nslopes * sizeof *sl);
                wt_shack_hartmann_apply(s->sh, 1.0, ph, sl);
                if (fp) { /* (I − T) with the focus: ‖(I − T_tt) v‖² − (fᵀv)², f ⟂ tip and tilt */
                    double a = 0.0;
                    for (int i = 0; i < s->nslopes; i++) a += fp[i] * sl[i];
                    sum -= t->lgs_focus == 2 ? a * a / sys->nlgs : a * a;
                }
                for (int axis = 0; axis < 2; axis++) { /* (I − T): the global tip and tilt removed */
                    double *v = sl + (size_t)axis * s->nsub, mean = 0.0;
                    for (int i = 0; i < s->nsub; i++) mean += v[i];
                    mean /= s->nsub;
                    for (int i = 0; i < s->nsub; i++) sum += (v[i] - mean) * (v[i] - mean);
                }
            }
            var_e[m] += sum / ((double)s->nslopes * WT_MODEL_ERROR_DRAWS);
            for (int q = 0; q < 3; q++) {
                wt_projection_free(proj[q]);
                proj[q] = NULL;
            }
        }
    }
fail:
    for (int q = 0; q < 3; q++) wt_projection_free(proj[q]);
    wt_prior_free(prior);
    wt_wavelet_free(wav);
    wt_free(ctx, c);
    wt_free(ctx, phi);
    wt_free(ctx, work);
    wt_free(ctx, ph);
    wt_free(ctx, sl);
    wt_free(ctx, fp);
    return st;
}

int wt_tomography__model_error(wt_tomography *t, double r0, int natm, const double *atm_alt, const double *atm_frac)
{
    for (int m = 0; m < t->S; m++) t->model_var[m] = t->subgrid_var[m] = 0.0;
    if (t->subgrid_error) subgrid_error_add(t, t, r0, natm, atm_alt, atm_frac, t->subgrid_var);
    return t->model_error ? model_error_add(t, r0, natm, atm_alt, atm_frac, 0, t->model_var) : WT_OK;
}

/* The unit layers' model error at each of the natm altitudes (kept: a learned model keeps its altitude grid, so
 * each altitude is drawn once per reconstructor), σ²_e,m = Σ_k f_k r0^(−5/3) u_m(h_k). Unit layer j of the cache
 * draws from stream 2^32 + j: the oracle's layers (streams 0, 1, …) are not reused. */
static int model_error_cached(wt_tomography *t, double r0, int natm, const double *atm_alt, const double *atm_frac,
                              double *var_e)
{
    for (int m = 0; m < t->S; m++) var_e[m] = 0.0;
    const double s53 = pow(r0, -5.0 / 3.0);
    for (int k = 0; k < natm; k++) {
        if (!(atm_frac[k] > 0.0)) continue;
        int j = 0;
        while (j < t->me_ncache && t->me_alt[j] != atm_alt[k]) j++;
        if (j == t->me_ncache) {
            if (j == WT_TOMO_MODEL_CACHE)
                return WT_ERROR(t->ctx, WT_ERR_INVALID, "tomography: more than %d distinct model altitudes over the "
                                "updates of one reconstructor", WT_TOMO_MODEL_CACHE);
            const double one = 1.0;
            double *u = t->me_unit + (size_t)j * (2 * WT_MAX_GS);
            for (int m = 0; m < 2 * WT_MAX_GS; m++) u[m] = 0.0;
            int st = model_error_add(t, 1.0, 1, &atm_alt[k], &one, (1ULL << 32) + (uint64_t)j, u);
            if (st < 0) return st;
            t->me_alt[j] = atm_alt[k];
            t->me_ncache++;
        }
        const double *u = t->me_unit + (size_t)j * (2 * WT_MAX_GS);
        for (int m = 0; m < t->S; m++) var_e[m] += atm_frac[k] * s53 * u[m];
    }
    return WT_OK;
}

/* ---- Sub-grid model error of the LGS slopes (recon.subgrid_error) ------------------------------------
 *
 * A reconstruction layer of spacing Δ holds no spatial frequency beyond its Nyquist 1/(2Δ) (in either axis),
 * while a subaperture averages the gradient of all of them: that part of every slope is explained by no
 * layer of the model, and with a confident noise weight (many photons) the MAP explains it anyway, with
 * wrong structure on the layers and in the modes only the prior holds (the field's tip-tilt: docs/results.md
 * "more light"). The weight then trusts a slope no more than the model can explain it: σ²_g floors the
 * measurement noise, max(κσ², σ²_g), rather than adding to it as the binning error does. The sum is the white-noise
 * model of it, but the part sits at the grid's finest scales, which a MAP with κσ² > σ²_g already leaves to its
 * prior, and adding it there weakens the large scales the slopes do measure (docs/results.md "more light": the sum
 * costs the demo at its 100 photons, the floor leaves it bit for bit). An LGS at H sees a layer at h through
 * subapertures of side d c, c = 1 − h/H, in the layer's coordinates, and its slope is c times the layer's
 * gradient averaged over them; per axis, for the von Kármán phase spectrum at 500 nm
 * W(f) = 0.023 r0^(−5/3) (|f|² + L0^(−2))^(−11/6) [rad² m²] and the slope as an angle (λ = 500 nm):
 *   a(Δ, d') = (λ/2π)² ∫_{max(|fx|,|fy|) > 1/(2Δ)} W(f) (2π fx)² sinc²(d' fx) sinc²(d' fy) d²f   (r0 = 1 m),
 *   σ²_g,m = Σ_k f_k r0^(−5/3) c_k² [(1 − w_k) a(Δ_l, d c_k) + w_k a(Δ_{l+1}, d c_k)],
 * the true layer k split onto its two nearest reconstruction layers l, l + 1 with the prior's weights w_k. The
 * global tip-tilt of these frequencies, which the weight removes, is negligible (sinc² at f ≥ 1/(2Δ) over a
 * whole pupil). The NGS average over metres, where the part is small against their σ², and are left alone. */
enum { WT_SUBGRID_IN = 48, WT_SUBGRID_OUT = 160 };

static double sinc(double x) { return fabs(x) < 1e-8 ? 1.0 : sin(M_PI * x) / (M_PI * x); }

/* a(Δ, dp) [rad² per unit f r0^(−5/3)]: midpoint rule on a tensor grid of one quadrant (the integrand is even in
 * fx and fy), uniform up to fc = 1/(2Δ), geometric from fc to 400/dp; the tail beyond decays as f^(−5/3) and
 * is below 1e-3 of the integral (a grid of twice the cells changes it by < 0.5 %) */
static double subgrid_unit(double delta, double dp, double L0)
{
    const double fc = 0.5 / delta, fhi = fmax(400.0 / dp, 8.0 * fc), lam = 500e-9;
    const int n = WT_SUBGRID_IN + WT_SUBGRID_OUT;
    double f[WT_SUBGRID_IN + WT_SUBGRID_OUT], w[WT_SUBGRID_IN + WT_SUBGRID_OUT];
    for (int i = 0; i < WT_SUBGRID_IN; i++) {
        w[i] = fc / WT_SUBGRID_IN;
        f[i] = (i + 0.5) * w[i];
    }
    const double q = pow(fhi / fc, 1.0 / WT_SUBGRID_OUT);
    for (int i = 0; i < WT_SUBGRID_OUT; i++) {
        const double a = fc * pow(q, i), b = a * q;
        f[WT_SUBGRID_IN + i] = 0.5 * (a + b);
        w[WT_SUBGRID_IN + i] = b - a;
    }
    const double k0 = 1.0 / (L0 * L0);
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
        const double sx = sinc(dp * f[i]), gx = 2.0 * M_PI * f[i] * sx;
        for (int j = (i < WT_SUBGRID_IN ? WT_SUBGRID_IN : 0); j < n; j++) {
            const double sy = sinc(dp * f[j]);
            sum += w[i] * w[j] * pow(f[i] * f[i] + f[j] * f[j] + k0, -11.0 / 6.0) * gx * gx * sy * sy;
        }
    }
    const double c = lam / (2.0 * M_PI);
    return 4.0 * 0.023 * c * c * sum;
}

/* a(Δ, d′) at t's L0, from t's memo when it has one (mt: the same t, writable; NULL: compute) */
static double subgrid_unit_memo(wt_tomography *mt, double delta, double dp, double L0)
{
    if (!mt) return subgrid_unit(delta, dp, L0);
    for (int i = 0; i < mt->subgrid_nmemo; i++) {
        const double *k = mt->subgrid_memo[i];
        if (k[0] == delta && k[1] == dp && k[2] == L0) return k[3];
    }
    const double a = subgrid_unit(delta, dp, L0);
    if (mt->subgrid_nmemo < WT_SUBGRID_MEMO) { /* (full: computed each time, as without the memo) */
        double *k = mt->subgrid_memo[mt->subgrid_nmemo++];
        k[0] = delta, k[1] = dp, k[2] = L0, k[3] = a;
    }
    return a;
}

static void subgrid_error_add(const wt_tomography *t, wt_tomography *mt, double r0, int natm, const double *atm_alt,
                              const double *atm_frac, double *var_e)
{
    const wt_system *sys = t->sys;
    const double s53 = pow(r0, -5.0 / 3.0);
    for (int m = 0; m < t->S; m++) {
        const wt_sensor *s = &sys->sensors[m];
        if (s->kind != WT_SENSOR_LGS || !(s->altitude > 0.0)) continue;
        const double d = sys->diameter / s->subapertures;
        double v = 0.0;
        for (int k = 0; k < natm; k++) {
            const double h = atm_alt[k], f = atm_frac[k], c = 1.0 - h / s->altitude;
            if (!(f > 0.0) || !(c > 0.0)) continue;
            int l;
            double w;
            wt_profile_bin_altitude(t->L, t->alt, h, &l, &w);
            double a = (1.0 - w) * subgrid_unit_memo(mt, t->grid[l].dx, d * c, t->L0);
            if (w > 0.0) a += w * subgrid_unit_memo(mt, t->grid[l + 1].dx, d * c, t->L0);
            v += f * s53 * c * c * a;
        }
        var_e[m] += v;
    }
}

double wt_tomography__subgrid_error(double delta, double dp, double L0) { return subgrid_unit(delta, dp, L0); }

void wt_tomography_subgrid_variances(const wt_tomography *t, double r0, int natm, const double *alt, const double *frac,
                                     double *var)
{
    for (int m = 0; m < t->S; m++) var[m] = 0.0;
    subgrid_error_add(t, NULL, r0, natm, alt, frac, var);
}

/* ---- the sensors' noise model ------------------------------------------------------------------------
 * C̃_i = max(κσ², σ²_g) I + κσ² (τ/θf²) β βᵀ + σ²_e I = σ²_t (I + (τ κσ²/σ²_t / θf²) β βᵀ),
 * σ²_t = max(κσ², σ²_g) + σ²_e: the model errors are isotropic, the elongation term keeps its size; κ (loop_noise_average, else 1)
 * scales the measurement noise only. With lit_noise as well, the per-subaperture factor c_i scales
 * σ²_t whole (the model error of a partly lit subaperture is taken as larger in the same
 * proportion: both options are off by default). */
/* *out (an LGS's weight) gets the focus removal too when it is on; *out is freed on failure */
static int sensor_focus(wt_tomography *t, const wt_sensor *s, wt_noise **out)
{
    if (t->lgs_focus != 1 || s->kind != WT_SENSOR_LGS) return WT_OK; /* (common: the tomography's own term) */
    int st = WT_OK;
    double *cx = NULL;
    WT_ALLOC(t->ctx, cx, 2 * (size_t)s->nsub, "subaperture centres");
    for (int k = 0; k < s->nsub; k++) wt_shack_hartmann_centre(s->sh, k, &cx[k], &cx[s->nsub + k]);
    st = wt_noise_set_focus(*out, cx, cx + s->nsub);
fail:
    wt_free(t->ctx, cx);
    if (st < 0) {
        wt_noise_free(*out);
        *out = NULL;
    }
    return st;
}

static int sensor_noise(wt_tomography *t, int m, wt_noise **out)
{
    wt_context *ctx = t->ctx;
    const wt_sensor *s = &t->sys->sensors[m];
    const double kappa = t->kappa;
    if (s->diffr) {
        /* a diffractive sensor: the centroider's calibrated 2x2 blocks Σ_i (sensing.h), κΣ_i + σ²_e I; τ
         * scales the part beyond the short axis, κ(Σ_i − λ_i I), which the isotropic model error leaves as
         * it is (the same rule as the paper's model above) */
        const int ns = s->nsub;
        double *cov = wt_malloc(ctx, 3 * (size_t)ns, sizeof *cov);
        if (!cov) return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for %s's noise blocks", s->name);
        for (int i = 0; i < ns; i++) {
            const double a = kappa * s->diffr->cov[i], b = kappa * s->diffr->cov[ns + i], d = kappa * s->diffr->cov[2 * ns + i];
            /* the sub-grid floor lifts the block's smaller eigenvalue to σ²_g (isotropic, as the error is) */
            const double lmin = 0.5 * (a + d) - sqrt(0.25 * (a - d) * (a - d) + b * b);
            const double e = t->model_var[m] + fmax(0.0, t->subgrid_var[m] - lmin);
            cov[i] = a + e;
            cov[ns + i] = b;
            cov[2 * ns + i] = d + e;
        }
        const int st = wt_noise_alloc_blocks(ctx, ns, cov, t->tau, s->kind == WT_SENSOR_LGS, out);
        wt_free(ctx, cov);
        return st < 0 ? st : sensor_focus(t, s, out);
    }
    const double s2n = kappa * s->sigma2, s2t = fmax(s2n, t->subgrid_var[m]) + t->model_var[m];
    const int st = wt_noise_alloc_scaled(ctx, s->nsub, s2t, s->noise_scale, s->spot_fwhm, s->beta,
                                         t->tau * (s2n / s2t), s->kind == WT_SENSOR_LGS, out);
    return st < 0 ? st : sensor_focus(t, s, out);
}

double wt_tomography_lgs_precision(const wt_tomography *t, int m)
{
    /* the smaller eigenvalue of each block sensor_noise builds: τ scales only the part beyond it */
    const wt_sensor *s = &t->sys->sensors[m];
    const double kappa = t->kappa, e = t->model_var[m], g = t->subgrid_var[m];
    double sum = 0.0;
    if (s->diffr) {
        const double *c = s->diffr->cov;
        const int ns = s->nsub;
        for (int i = 0; i < ns; i++) {
            const double a = kappa * c[i], b = kappa * c[ns + i], d = kappa * c[2 * ns + i];
            sum += 1.0 / (fmax(0.5 * (a + d) - sqrt(0.25 * (a - d) * (a - d) + b * b), g) + e);
        }
        return sum;
    }
    const double s2t = fmax(kappa * s->sigma2, g) + e;
    for (int i = 0; i < s->nsub; i++) sum += 1.0 / ((s->noise_scale ? s->noise_scale[i] : 1.0) * s2t);
    return sum;
}

int wt_tomography__noise(wt_tomography *t)
{
    for (int m = 0; m < t->S; m++) {
        wt_noise *nz = NULL;
        const int st = sensor_noise(t, m, &nz);
        if (st < 0) return st;
        wt_noise_free(t->noise[m]);
        t->noise[m] = nz;
    }
    wt_tomography__common_update(t);
    return WT_OK;
}

int wt_tomography_set_profile(wt_tomography *t, double r0, int natm, const double *alt, const double *frac)
{
    wt_context *ctx = t->ctx;
    if (!(r0 > 0.0) || !isfinite(r0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "tomography (%s): new model r0 = %g m, expected finite and > 0", t->variant, r0);
    if (natm < 1 || natm > WT_MAX_LAYERS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "tomography (%s): new model of %d layers, expected 1 … %d", t->variant, natm,
                        WT_MAX_LAYERS);
    double sum = 0.0;
    for (int k = 0; k < natm; k++) {
        if (!(frac[k] >= 0.0) || !isfinite(frac[k]) || !isfinite(alt[k]) || alt[k] < 0.0 || (k > 0 && !(alt[k] > alt[k - 1])))
            return WT_ERROR(ctx, WT_ERR_INVALID, "tomography (%s): new model layer %d (altitude %g m, fraction %g): "
                            "expected altitudes >= 0 increasing and fractions >= 0", t->variant, k, alt[k], frac[k]);
        sum += frac[k];
    }
    if (!(sum > 0.0)) return WT_ERROR(ctx, WT_ERR_INVALID, "tomography (%s): new model has no turbulence", t->variant);
    double f[WT_MAX_LAYERS], norm[WT_MAX_LAYERS], var_e[2 * WT_MAX_GS], var_g[2 * WT_MAX_GS];
    for (int k = 0; k < natm; k++) norm[k] = frac[k] / sum;
    wt_tomography__bin_profile(t->L, t->alt, natm, alt, norm, f);
    /* the model error first: it is the only step that can fail, and the object stays as it was if it does */
    for (int m = 0; m < t->S; m++) var_e[m] = var_g[m] = 0.0;
    if (t->model_error) {
        const int st = model_error_cached(t, r0, natm, alt, norm, var_e);
        if (st < 0) return st;
    }
    if (t->subgrid_error) subgrid_error_add(t, t, r0, natm, alt, norm, var_g);
    wt_noise *nz[2 * WT_MAX_GS] = {NULL};
    double keep[2 * WT_MAX_GS], keep_g[2 * WT_MAX_GS];
    memcpy(keep, t->model_var, sizeof keep);
    memcpy(keep_g, t->subgrid_var, sizeof keep_g);
    memcpy(t->model_var, var_e, sizeof var_e);
    memcpy(t->subgrid_var, var_g, sizeof var_g);
    for (int m = 0; m < t->S; m++) {
        const int st = sensor_noise(t, m, &nz[m]);
        if (st < 0) {
            for (int q = 0; q < m; q++) wt_noise_free(nz[q]);
            memcpy(t->model_var, keep, sizeof keep);
            memcpy(t->subgrid_var, keep_g, sizeof keep_g);
            return st;
        }
    }
    for (int m = 0; m < t->S; m++) {
        wt_noise_free(t->noise[m]);
        t->noise[m] = nz[m];
    }
    wt_tomography__common_update(t);
    const double s_old = pow(t->r0, -5.0 / 3.0), s_new = pow(r0, -5.0 / 3.0);
    for (int l = 0; l < t->L; l++) {
        wt_prior_rescale(t->prior[l], (f[l] * s_new) / (t->frac[l] * s_old));
        const double *d = wt_prior_diag(t->prior[l]);
        for (int64_t i = 0; i < wt_grid_size(&t->grid[l]); i++) t->alpha_d[t->off[l] + i] = t->alpha * d[i];
        t->frac[l] = f[l];
    }
    t->r0 = r0;
    t->fresh = 1; /* the next solve applies M: the previous residual belongs to the old operator */
    return WT_OK;
}

double wt_tomography_r0(const wt_tomography *t) { return t->r0; }
