/* tests/test_tomography_model.c: the operator's noise and atmosphere model (core/model/tomography_model.c):
 * NEA and lit-area noise, the plate-scale modes, the model error and the loop's noise average. */
#include <lapacke.h>
#include <string.h>

#include "core/model/fitting.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/op/noise.h"
#include "core/op/projection.h"
#include "core/op/pupil.h"
#include "core/op/wavelet.h"
#include "testmodel.h"
#include "testutil.h"
#include "tomography_fixture.h"

/* The noise of a sensor given by an NEA with elongation on, and of partly lit subapertures
 * (lgs.wfs.lit_noise): σ² is NEA² (not widened by the elongation), each subaperture's variance factor
 * is 1/f with f its lit fraction of the annulus (f = 1: factor 1), the NGS sensors keep factor 1 (their
 * quadrants are alike), and the reconstructor's weight of a subaperture is the inverse of the truth's
 * covariance block at τ = 1 (here τ = 1 too, so model and truth agree block by block). */
START_TEST(test_nea_and_lit_noise)
{
    const char *set[] = {"lgs.wfs.nea_mas=30.0", "lgs.wfs.lit_noise=true", "ngs.wfs.lit_noise=true",
                         "recon.tau=1.0", "lgs.wfs.valid_fraction=0.3",
                         "recon.subgrid_error=false"}; /* the weight of the measurement noise alone */
    const double nea = 30e-3 * M_PI / (180.0 * 3600.0);
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 6, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_OK);
    int partial = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        ck_assert_ptr_nonnull(s->noise_scale);
        if (s->kind == WT_SENSOR_NGS) {
            for (int k = 0; k < s->nsub; k++) ck_assert_rel(s->noise_scale[k], 1.0, 1e-12, 0);
            continue;
        }
        ck_assert_rel(s->sigma2, nea * nea, 1e-14, 0);
        ck_assert_ptr_nonnull(s->beta);
        const double d = cfg->diameter / s->subapertures;
        for (int k = 0; k < s->nsub; k++) {
            double x, y, a, b, c;
            wt_shack_hartmann_centre(s->sh, k, &x, &y);
            double f = wt_pupil_fraction(cfg->diameter, cfg->obstruction, x - d / 2, y - d / 2, d);
            ck_assert_double_ge(f, 0.3 - 1e-12);
            ck_assert_rel(s->noise_scale[k], 1.0 / f, 1e-9, 0);
            partial += f < 0.999;
            /* model block × truth block = I: C̃_k = NEA²/f (I + ββᵀ/θf²) */
            double bx = s->beta[k], by = s->beta[s->nsub + k], g = 1.0 / (s->spot_fwhm * s->spot_fwhm);
            double v = nea * nea / f, ca = v * (1 + g * bx * bx), cb = v * g * bx * by, cc = v * (1 + g * by * by);
            wt_noise_inv_block(wt_tomography_noise(t, m), k, &a, &b, &c);
            ck_assert_rel(a * ca + b * cb, 1.0, 1e-10, 0);
            ck_assert_double_le(fabs(a * cb + b * cc), 1e-10);
            ck_assert_rel(b * cb + c * cc, 1.0, 1e-10, 0);
        }
    }
    ck_assert_int_gt(partial, 8); /* the rims of the 8 m demo pupil */
    wt_tomography_free(t);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* Fitting: layers at the DM altitudes on grids whose points include the actuators, filled with a DM
 * shape, are fitted exactly (up to ε and the unseen modes): compare the pupil-plane phase along every
 * evaluation direction. */
/* Tip-tilt and plate scale (issue 22): a quadratic φ = a|x|² on the highest pcg3 layer (altitude h) is, in
 * direction θ, a focus plus the field-dependent tilt 2 a h θ (a plate-scale mode). The LGS cannot see that
 * tilt (their global tip-tilt is removed by T) and see the focus almost alike from every altitude: without
 * NGS only the prior's split of the focus over the layers puts some of it at h. The NGS tip-tilt sensors
 * (NEA 0.05 mas) measure the tilt at three directions. From noise-free slopes of this layer, the tilt of
 * the reconstructed minus the true phase over the inner field (|θ| ≤ the LGS radius, where the layer is
 * seen; the field corners extrapolate beyond every guide star's footprint), relative to the largest true
 * tilt there, must drop to at most 0.4 of its no-NGS value for both NGS slope definitions (g and z are
 * equal on a quadratic): a broken NGS model, T projection or sign leaves it near the no-NGS value. Measured
 * (2026-11-25): 0.46 without NGS, 0.09 (G) and 0.16 (Z) with: the MAP does not give back a pure plate
 * scale exactly even from exact NGS tilts (its prior interpolates the field between the three NGS), a known
 * gap of the low-order path (docs/results.md §0e). The test runs with the paper's diagonal prior, where the
 * NGS path is what moves the figure. With the full prior (the default since session 11) the same converged
 * MAP gives 0.20 without NGS and 0.18 (G) / 0.16 (Z) with (6000 iterations to converge): it puts more of the
 * focus at h from the LGS alone, and the NGS move the inner field little (not yet understood: perhaps the
 * NGS tilts are explained by structure outside the LGS footprints), so there the figure cannot tell a working
 * NGS path from a broken one (docs/results.md §23). */
static double plate_scale_error(int tilt_z, int with_ngs)
{
    const char *set[] = {"lgs.wfs.nea_mas=5.0", "ngs.wfs.nea_mas=0.05", "lgs.sodium_fwhm_m=0.0", "recon.pcg3.prior=\"paper\"",
                         tilt_z ? "ngs.wfs.tilt=\"z\"" : "ngs.wfs.tilt=\"g\"", "ngs.azimuths_deg=[]", "ngs.subapertures=[]"};
    fixture f;
    setup(&f, DEMO, 0, with_ngs ? 5 : 7, set);
    const wt_system *sys = f.sys;
    const int L = wt_tomography_nlayers(f.t), top = L - 1;
    const int64_t n = wt_tomography_nunknowns(f.t), ns = sys->nslopes;
    int64_t np = 0;
    for (int l = 0; l < L; l++) np += wt_grid_size(wt_tomography_layer_grid(f.t, l));
    double *phi = calloc(np, sizeof *phi), *c = calloc(n, sizeof *c), *s = malloc(ns * sizeof *s);
    const double a = 2e-8, h = wt_tomography_layer_altitude(f.t, top); /* [m⁻¹]: 0.3 µm at the pupil edge */
    const wt_grid *g = wt_tomography_layer_grid(f.t, top);
    double *lay = phi + wt_tomography_layer_offset(f.t, top);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            lay[ix + (int64_t)g->nx * iy] = a * (x * x + y * y);
        }
    /* c_true = W φ on that layer (W⁻¹ W = I, so Ã c_true = Γ P φ exactly) */
    double *work = malloc(wt_wavelet_work_size(wt_tomography_wavelet(f.t, top)) * sizeof *work);
    wt_wavelet_forward(wt_tomography_wavelet(f.t, top), lay, c + wt_tomography_layer_offset(f.t, top), work);
    tu_tomo_slopes(f.t, c, s);
    memset(c, 0, n * sizeof *c);
    wt_pcg_result r;
    wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c, 2000, 1e-12, NULL, &r);
    double *rec = calloc(np, sizeof *rec);
    wt_tomography_layers(f.t, c, rec);
    for (int64_t i = 0; i < np; i++) rec[i] -= phi[i];
    wt_grid lg[WT_MAX_LAYERS];
    double alt[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++) lg[l] = *wt_tomography_layer_grid(f.t, l), alt[l] = wt_tomography_layer_altitude(f.t, l);
    const wt_grid *cg = &sys->corner_grid;
    const int64_t nc = wt_grid_size(cg);
    double worst = 0.0, tmax = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        if (hypot(sys->eval_x[j], sys->eval_y[j]) > f.cfg->lgs_radius * (1 + 1e-9)) continue;
        wt_projection *pr;
        ck_assert_int_eq(wt_projection_alloc(f.ctx, L, lg, alt, 0.0, sys->eval_x[j], sys->eval_y[j], cg, sys->corner_mask, 1, &pr),
                         WT_OK);
        double *e = calloc(nc, sizeof *e);
        wt_projection_apply(pr, 1.0, rec, e);
        /* least-squares plane of the error over the valid corners (centred normal equations) */
        double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, se = 0, sex = 0, sey = 0;
        for (int64_t k = 0; k < nc; k++) {
            if (!sys->corner_mask[k]) continue;
            const double x = cg->x0 + (k % cg->nx) * cg->dx, y = cg->y0 + (k / cg->nx) * cg->dx;
            sw += 1, sx += x, sy += y, sxx += x * x, sxy += x * y, syy += y * y, se += e[k], sex += e[k] * x, sey += e[k] * y;
        }
        const double mx = sx / sw, my = sy / sw, cxx = sxx - sw * mx * mx, cxy = sxy - sw * mx * my,
                     cyy = syy - sw * my * my, bx = sex - se * mx, by = sey - se * my, det = cxx * cyy - cxy * cxy;
        worst = fmax(worst, hypot((cyy * bx - cxy * by) / det, (cxx * by - cxy * bx) / det));
        tmax = fmax(tmax, 2.0 * a * h * hypot(sys->eval_x[j], sys->eval_y[j]));
        free(e);
        wt_projection_free(pr);
    }
    ck_assert_double_gt(tmax, 0.0);
    free(phi), free(c), free(s), free(rec), free(work);
    teardown(&f);
    return worst / tmax;
}

START_TEST(test_plate_scale_reconstructed)
{
    const double none = plate_scale_error(0, 0), eg = plate_scale_error(0, 1), ez = plate_scale_error(1, 1);
    printf("plate scale: inner-field tilt error / largest tilt: without NGS %.3f, NGS G-tilt %.3f, Z-tilt %.3f\n", none, eg, ez);
    ck_assert_double_ge(none, 0.3); /* the LGS see the focus, not its altitude: the prior splits it over the layers */
    ck_assert_double_le(eg, 0.4 * none);
    ck_assert_double_le(ez, 0.4 * none);
}
END_TEST

/* The layer-binning model error (recon.model_error, core/model/tomography.c): zero when every true layer
 * sits on a reconstruction altitude (cg9's layers are the atmosphere's), positive for the LGS of PCG-3
 * (the demo atmosphere has layers at 600, 2000, 6000 m between the DM altitudes), not given to the NGS;
 * its variance scales as r0^(-5/3) like the prior it is drawn from (the same fixed-seed draws); and it
 * enters the noise covariance as an isotropic term next to an unchanged elongation term:
 * C̃_i = (σ² + σ²_e) I + σ² (τ/θf²) β βᵀ. */
START_TEST(test_model_error)
{
    const char *on[] = {"recon.model_error=true"};
    const char *half_r0[] = {"recon.model_error=true", "atmosphere.r0_m=0.0645"};
    fixture f9, f3, fr;
    setup(&f9, DEMO, 1, 1, on);
    setup(&f3, DEMO, 0, 1, on);
    setup(&fr, DEMO, 0, 2, half_r0);
    const wt_system *sys = f3.sys;
    int nlgs = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        ck_assert_double_eq(wt_tomography_model_error(f9.t, m), 0.0);
        const double e2 = wt_tomography_model_error(f3.t, m);
        if (s->kind != WT_SENSOR_LGS) {
            ck_assert_double_eq(e2, 0.0);
            continue;
        }
        nlgs++;
        /* a few tens of mas: more than nothing, less than the slope rms of the whole atmosphere (~200 mas) */
        ck_assert_double_gt(sqrt(e2) / WT_ARCSEC * 1e3, 5.0);
        ck_assert_double_lt(sqrt(e2) / WT_ARCSEC * 1e3, 200.0);
        ck_assert_rel(wt_tomography_model_error(fr.t, m), e2 * pow(2.0, 5.0 / 3.0), 1e-9, 0.0);
        /* the covariance block of an elongated subaperture */
        const wt_noise *no = wt_tomography_noise(f3.t, m);
        const int nsub = s->nsub, i = nsub / 3;
        ck_assert_ptr_nonnull(s->beta);
        const double bx = s->beta[i], by = s->beta[nsub + i];
        const double g = f3.cfg->tau / (s->spot_fwhm * s->spot_fwhm);
        double *x = calloc((size_t)2 * nsub, sizeof *x), *y = calloc((size_t)2 * nsub, sizeof *y);
        x[i] = 1.0;
        wt_noise_apply_cov(no, 1.0, x, y);
        ck_assert_rel(y[i], s->sigma2 + e2 + s->sigma2 * g * bx * bx, 1e-12, 0.0);
        ck_assert_rel(y[nsub + i], s->sigma2 * g * bx * by, 1e-12, 1e-30);
        free(x), free(y);
    }
    ck_assert_int_eq(nlgs, f3.cfg->nlgs);
    teardown(&f9);
    teardown(&f3);
    teardown(&fr);
}
END_TEST

/* recon.pcg3.loop_noise_average: the measurement noise of every sensor (NGS too) scaled by the loop's noise
 * gain κ = Σh² (the demo: g 0.4, delay 2, κ = 7/18), elongation term included, and the model error added
 * unscaled: C̃_i = (κσ² + σ²_e) I + κσ² (τ/θf²) β βᵀ. */
START_TEST(test_loop_noise_average)
{
    const char *off[] = {"recon.model_error=true"};
    const char *on[] = {"recon.model_error=true", "recon.pcg3.loop_noise_average=true"};
    fixture a, b;
    setup(&a, DEMO, 0, 1, off);
    setup(&b, DEMO, 0, 2, on);
    const double k = wt_noise_loop_gain(b.cfg->gain, b.cfg->delay);
    ck_assert_rel(k, 7.0 / 18.0, 1e-12, 0.0); /* the demo's loop: g 0.4, delay 2 */
    for (int m = 0; m < b.sys->nsensors; m++) {
        const wt_sensor *s = &b.sys->sensors[m];
        const double e2 = wt_tomography_model_error(b.t, m);
        ck_assert_double_eq(e2, wt_tomography_model_error(a.t, m)); /* not averaged */
        const int nsub = s->nsub, i = nsub / 3;
        const double bx = s->beta ? s->beta[i] : 0.0, by = s->beta ? s->beta[nsub + i] : 0.0;
        const double g = b.cfg->tau / (s->spot_fwhm * s->spot_fwhm);
        double *x = calloc((size_t)2 * nsub, sizeof *x), *y = calloc((size_t)2 * nsub, sizeof *y);
        x[i] = 1.0;
        wt_noise_apply_cov(wt_tomography_noise(b.t, m), 1.0, x, y);
        ck_assert_rel(y[i], k * s->sigma2 + e2 + k * s->sigma2 * g * bx * bx, 1e-12, 0.0);
        ck_assert_rel(y[nsub + i], k * s->sigma2 * g * bx * by, 1e-12, 1e-30);
        free(x), free(y);
    }
    teardown(&a);
    teardown(&b);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("tomography_model");
    TCase *tc_core = tcase_create("core");
    tcase_set_timeout(tc_core, 900);
    tcase_add_test(tc_core, test_nea_and_lit_noise);
    tcase_add_test(tc_core, test_plate_scale_reconstructed);
    tcase_add_test(tc_core, test_model_error);
    tcase_add_test(tc_core, test_loop_noise_average);
    suite_add_tcase(s, tc_core);
    return s;
}

TU_MAIN
