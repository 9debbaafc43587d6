/* tests/test_subgrid.c: the sub-grid model error of the LGS slopes (recon.subgrid_error, core/model/tomography_model.c):
 * the unit integral a(Δ, d') against an independent quadrature, the demo's sum over the layers, its r0 scaling, the
 * weight's floor max(κσ², σ²_g) + σ²_e (the binning error still added, the elongation term unchanged, nothing changed
 * where κσ² is above the floor), and a model update that gives the set-up's value back. */
#include <string.h>
#include <math.h>
#include <stdlib.h>

#include "core/model/params.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/model/tomography_private.h"
#include "core/op/noise.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
} fixture;

static void setup(fixture *f, int cg9, int nset, const char *const *set)
{
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, DEMO, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    const wt_recon_variant_config *v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                  wt_error_message(f->ctx));
}

static void teardown(fixture *f)
{
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static double sinc(double x) { return fabs(x) < 1e-8 ? 1.0 : sin(M_PI * x) / (M_PI * x); }

/* a(Δ, d') by another rule: polar coordinates, log-spaced radius from fc to 2e4/d' (the tail beyond is
 * O((2e4)^(-5/3)) of the whole), the square |fx|, |fy| <= fc left out point by point; the two agree to the
 * smaller rule's accuracy (the tensor rule's < 0.5 %: 1 % asked) */
static double polar_reference(double delta, double dp, double L0)
{
    const double fc = 0.5 / delta, r1 = 2e4 / dp, lam = 500e-9;
    const int nr = 4000, nt = 720;
    const double du = log(r1 / fc) / nr, dt = 2.0 * M_PI / nt;
    double sum = 0.0;
    for (int i = 0; i < nr; i++) {
        const double r = fc * exp((i + 0.5) * du);
        const double w = pow(r * r + 1.0 / (L0 * L0), -11.0 / 6.0) * r * r * du; /* r dr = r² du */
        for (int j = 0; j < nt; j++) {
            const double fx = r * cos((j + 0.5) * dt), fy = r * sin((j + 0.5) * dt);
            if (fabs(fx) <= fc && fabs(fy) <= fc) continue;
            const double g = 2.0 * M_PI * fx * sinc(dp * fx) * sinc(dp * fy);
            sum += w * g * g * dt;
        }
    }
    return 0.023 * sum * (lam / (2.0 * M_PI)) * (lam / (2.0 * M_PI));
}

START_TEST(test_subgrid_unit)
{
    const double cases[][2] = {{0.5, 0.5}, {1.0, 0.5}, {1.0, 0.43}, {0.25, 0.5}};
    double prev = 0.0;
    for (int c = 0; c < 4; c++) {
        const double a = wt_tomography__subgrid_error(cases[c][0], cases[c][1], 25.0);
        ck_assert_rel(a, polar_reference(cases[c][0], cases[c][1], 25.0), 1e-2, 0.0);
        if (c == 1) ck_assert_double_gt(a, 2.0 * prev); /* a coarser grid misses more: 1 m against 0.5 m */
        prev = a;
    }
}
END_TEST

/* the demo's CG-9 (layers at the atmosphere's altitudes: no binning error): each LGS's variance is the sum of
 * the layers' f c² a(Δ, d c) r0^(−5/3), some 65 mas per axis (a few tens: more than nothing, less than the
 * ~190 mas slope rms of the whole atmosphere); the NGS get none; halving r0 multiplies it by 2^(5/3) */
START_TEST(test_subgrid_demo)
{
    const char *on[] = {"recon.subgrid_error=true"};
    const char *half[] = {"recon.subgrid_error=true", "atmosphere.r0_m=0.0645"};
    fixture f, h;
    setup(&f, 1, 1, on);
    setup(&h, 1, 2, half);
    const wt_config *c = f.cfg;
    int nlgs = 0;
    for (int m = 0; m < f.sys->nsensors; m++) {
        const wt_sensor *s = &f.sys->sensors[m];
        const double v = wt_tomography_subgrid_error(f.t, m);
        ck_assert_double_eq(wt_tomography_model_error(f.t, m), 0.0);
        if (s->kind != WT_SENSOR_LGS) {
            ck_assert_double_eq(v, 0.0);
            continue;
        }
        nlgs++;
        double e = 0.0;
        for (int k = 0; k < c->nlayers; k++) {
            const double h_k = c->layer_altitude[k], cc = 1.0 - h_k / s->altitude;
            e += c->layer_fraction[k] * cc * cc *
                 wt_tomography__subgrid_error(c->cg9.spacing[k], f.sys->diameter / s->subapertures * cc, c->L0);
        }
        e *= pow(c->r0, -5.0 / 3.0);
        ck_assert_rel(v, e, 1e-12, 0.0);
        const double mas = sqrt(v) / (M_PI / 180.0 / 3600.0) * 1e3;
        ck_assert_msg(mas > 40.0 && mas < 100.0, "sub-grid error %g mas", mas);
        ck_assert_rel(wt_tomography_subgrid_error(h.t, m), v * pow(2.0, 5.0 / 3.0), 1e-9, 0.0);
    }
    ck_assert_int_eq(nlgs, c->nlgs);
    teardown(&f);
    teardown(&h);
}
END_TEST

/* y = C̃ e_i for LGS m's subaperture i: the diagonal entry and the xy entry */
static void cov_entry(const wt_tomography *t, int m, int i, double *xx, double *xy)
{
    const int nsub = wt_tomography_noise(t, m) ? t->sys->sensors[m].nsub : 0;
    double *x = calloc((size_t)2 * nsub, sizeof *x), *y = calloc((size_t)2 * nsub, sizeof *y);
    x[i] = 1.0;
    wt_noise_apply_cov(wt_tomography_noise(t, m), 1.0, x, y);
    *xx = y[i];
    *xy = y[nsub + i];
    free(x), free(y);
}

/* PCG-3 at 10^4 photons (σ ~5 mas, under the ~65 mas floor): C̃_i = (σ²_g + σ²_e) I + σ² (τ/θf²) β βᵀ, the binning
 * error unchanged by the key; at the demo's 100 photons (σ ~146 mas, above it) the weight is the one without the
 * key, to the bit; a model update (r0 doubled, then back) gives the set-up's floor back (the binning error's
 * updates draw other screens, test_profile.c) */
START_TEST(test_subgrid_floor)
{
    const char *bright[] = {"lgs.wfs.photons=1e4", "recon.model_error=true", "recon.subgrid_error=true"};
    const char *bright0[] = {"lgs.wfs.photons=1e4", "recon.model_error=true", "recon.subgrid_error=false"};
    const char *dim[] = {"recon.model_error=true", "recon.subgrid_error=true"};
    const char *dim0[] = {"recon.model_error=true", "recon.subgrid_error=false"};
    fixture a, a0, b, b0;
    setup(&a, 0, 3, bright);
    setup(&a0, 0, 3, bright0);
    setup(&b, 0, 2, dim);
    setup(&b0, 0, 2, dim0);
    double v0[2 * WT_MAX_GS];
    for (int m = 0; m < a.sys->nsensors; m++) {
        const wt_sensor *s = &a.sys->sensors[m];
        const double g = wt_tomography_subgrid_error(a.t, m), e = wt_tomography_model_error(a.t, m);
        v0[m] = g;
        ck_assert_double_eq(e, wt_tomography_model_error(a0.t, m));
        if (s->kind != WT_SENSOR_LGS) continue;
        ck_assert_double_gt(g, 10.0 * s->sigma2);
        ck_assert_double_gt(e, 0.0);
        const int i = s->nsub / 3;
        ck_assert_ptr_nonnull(s->beta);
        const double k = a.cfg->tau / (s->spot_fwhm * s->spot_fwhm), bx = s->beta[i], by = s->beta[s->nsub + i];
        double xx, xy;
        cov_entry(a.t, m, i, &xx, &xy);
        ck_assert_rel(xx, g + e + s->sigma2 * k * bx * bx, 1e-12, 0.0);
        ck_assert_rel(xy, s->sigma2 * k * bx * by, 1e-12, 1e-30);
        /* 100 photons: above the floor, the weight of a reconstructor without the key */
        ck_assert_double_lt(wt_tomography_subgrid_error(b.t, m), b.sys->sensors[m].sigma2);
        double yy, yx, zz, zx;
        cov_entry(b.t, m, i, &yy, &yx);
        cov_entry(b0.t, m, i, &zz, &zx);
        ck_assert_double_eq(yy, zz);
        ck_assert_double_eq(yx, zx);
        ck_assert_double_eq(wt_tomography_lgs_precision(b.t, m), wt_tomography_lgs_precision(b0.t, m));
        ck_assert_rel(wt_tomography_lgs_precision(a.t, m), s->nsub / (g + e), 1e-12, 0.0);
    }
    const wt_config *c = a.cfg;
    ck_assert_int_eq(wt_tomography_set_profile(a.t, 2.0 * c->r0, c->nlayers, c->layer_altitude, c->layer_fraction), WT_OK);
    for (int m = 0; m < a.sys->nsensors; m++)
        ck_assert_rel(wt_tomography_subgrid_error(a.t, m), v0[m] * pow(2.0, -5.0 / 3.0), 1e-12, 0.0);
    ck_assert_int_eq(wt_tomography_set_profile(a.t, c->r0, c->nlayers, c->layer_altitude, c->layer_fraction), WT_OK);
    /* back to the first profile: the remembered unit integrals give the first bits; the computation without the
     * memo (wt_tomography_subgrid_variances, what `info` prints, whether the key is on or off) the same */
    double vc[2 * WT_MAX_GS], vo[2 * WT_MAX_GS];
    wt_tomography_subgrid_variances(a.t, c->r0, c->nlayers, c->layer_altitude, c->layer_fraction, vc);
    wt_tomography_subgrid_variances(a0.t, c->r0, c->nlayers, c->layer_altitude, c->layer_fraction, vo);
    for (int m = 0; m < a.sys->nsensors; m++) {
        ck_assert_double_eq(wt_tomography_subgrid_error(a.t, m), v0[m]);
        ck_assert_double_eq(vc[m], v0[m]);
        ck_assert_double_eq(vo[m], v0[m]);
        ck_assert_double_eq(wt_tomography_subgrid_error(a0.t, m), 0.0);
    }
    teardown(&a);
    teardown(&a0);
    teardown(&b);
    teardown(&b0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("subgrid");
    TCase *tc = tcase_create("subgrid");
    tcase_set_timeout(tc, 60);
    tcase_add_test(tc, test_subgrid_unit);
    tcase_add_test(tc, test_subgrid_demo);
    tcase_add_test(tc, test_subgrid_floor);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
