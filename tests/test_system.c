/* tests/test_system.c: the geometry of a configuration (SPEC §1, §3–§5; core/model/system.h) on the
 * paper's E-ELT system: its sizes as the paper and docs/SPEC.md §1 state them, the slope and actuator
 * orderings every other module relies on, the error of a DM that has no active actuator, and the
 * automatic layer grids (core/config/config_grid.c) against the operators that read the layers. */
#include "core/model/fitting.h"
#include "core/model/params.h"
#include "core/model/profile.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "core/op/projection.h"
#include "core/op/shack_hartmann.h"
#include "testutil.h"

static wt_system *eelt(wt_context *ctx, int nset, const char **set, wt_config **cfg)
{
    wt_system *sys;
    ck_assert_msg(wt_config_read(ctx, "data/presets/eelt-mcao.cfg", nset, set, cfg) == WT_OK, "%s",
                  wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, *cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    return sys;
}

/* 84 x 84 subapertures of 0.5 m: 5112 valid per LGS sensor, 6 LGS → 61344 LGS slopes, + a 2x2 NGS
 * (8 slopes) + two tip-tilt NGS (2 each) = 61356; slopes concatenated LGS first, [s_x…, s_y…] each. */
START_TEST(test_eelt_sizes_and_order)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys = eelt(ctx, 0, NULL, &cfg);
    ck_assert_int_eq(sys->nlgs, 6);
    ck_assert_int_eq(sys->nngs, 3);
    ck_assert_int_eq(sys->nvalid, 5112);
    ck_assert_int_eq(sys->nslopes, 61356);
    int64_t off = 0;
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        ck_assert_int_eq(s->kind, m < sys->nlgs ? WT_SENSOR_LGS : WT_SENSOR_NGS);
        ck_assert_int_eq(s->offset, off);
        ck_assert_int_eq(s->nslopes, 2 * s->nsub);
        if (s->kind == WT_SENSOR_LGS) ck_assert_int_eq(s->nsub, 5112);
        off += s->nslopes;
    }
    ck_assert_int_eq(off, sys->nslopes);
    /* the preset's one guard ring: 5857 + 1793 + 2377 active actuators, DM by DM */
    const int with_guard[3] = {5857, 1793, 2377};
    ck_assert_int_eq(sys->dm->ndms, 3);
    int64_t aoff = 0;
    for (int k = 0; k < 3; k++) {
        ck_assert_int_eq(sys->dm->nactive[k], with_guard[k]);
        ck_assert_int_eq(sys->dm->offset[k], aoff);
        aoff += sys->dm->nactive[k];
    }
    ck_assert_int_eq(sys->nact, 10027);
    ck_assert_int_eq(sys->nact, sys->dm->nact);
    /* the 5 x 5 evaluation grid, centre on axis */
    ck_assert_double_eq(sys->eval_x[sys->eval_centre], 0.0);
    ck_assert_double_eq(sys->eval_y[sys->eval_centre], 0.0);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);

    /* no guard ring: the paper's 5525 + 1609 + 2161 = 9295 actuators (SPEC §1) */
    const char *set[] = {"dm.guard_rings=0"};
    sys = eelt(ctx, 1, set, &cfg);
    const int paper[3] = {5525, 1609, 2161};
    for (int k = 0; k < 3; k++) ck_assert_int_eq(sys->dm->nactive[k], paper[k]);
    ck_assert_int_eq(sys->nact, 9295);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* A DM whose actuators all fall outside its metapupil: a configuration error naming file and DM. */
START_TEST(test_dm_without_actuators)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys = (wt_system *)&sys;
    const char *set[] = {"dm.guard_rings=0", "dm.actuators=[17, 2, 21]", "dm.pitch_m=[0.5, 100.0, 1.0]"};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 3, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_ERR_CONFIG);
    ck_assert_ptr_null(sys);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "demo.cfg"));
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "DM 2"));
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* ---------------------------------------------------------------- automatic layer grids */

static const char *const AUTO_GRIDS[] = {"recon.pcg3.layer_spacing_m=auto", "recon.pcg3.layer_size=auto",
                                         "recon.cg9.layer_spacing_m=auto", "recon.cg9.layer_size=auto"};

/* Does an n-point layer of spacing δ at altitude h hold everything the operators read on it? The
 * tomography's projection from every sensor's sample grid (its masks), the fitting's projection along
 * every evaluation direction (cg9's sampling, the wider one when it is > 1), and for pcg3 the active
 * actuators of the DMs the layer is read at (wt_reconstructor_command_map's test). The real operators'
 * checks, not config_grid.c's bounds. */
static int layer_holds(wt_context *ctx, const wt_system *sys, int pcg3, double h, int n, double delta)
{
    const wt_grid g = wt_grid_layer(n, delta);
    for (int m = 0; m < sys->nsensors; m++) {
        const wt_sensor *s = &sys->sensors[m];
        wt_projection *p = NULL;
        int st = wt_projection_alloc(ctx, 1, &g, &h, s->altitude, s->theta_x, s->theta_y, &sys->sense_grid,
                                     wt_shack_hartmann_corner_mask(s->sh), 0, &p);
        wt_projection_free(p);
        if (st < 0) return 0;
    }
    for (int q = 1; q <= 2; q++) {
        wt_grid sample;
        uint8_t *mask = NULL;
        ck_assert_int_eq(wt_fitting_sampling(ctx, sys, q, &sample, &mask), WT_OK);
        int ok = 1;
        for (int j = 0; j < sys->neval && ok; j++) {
            wt_projection *p = NULL;
            ok = wt_projection_alloc(ctx, 1, &g, &h, 0.0, sys->eval_x[j], sys->eval_y[j], &sample, mask, 0, &p) == WT_OK;
            wt_projection_free(p);
        }
        wt_free(ctx, mask);
        if (!ok) return 0;
    }
    if (pcg3) {
        const wt_dm *dm = sys->dm;
        double alt[WT_DM_MAX];
        int order[WT_DM_MAX], j;
        double w;
        for (int k = 0; k < dm->ndms; k++) order[k] = k;
        for (int a = 1; a < dm->ndms; a++) /* by altitude, as the command map */
            for (int b = a; b > 0 && dm->altitude[order[b]] < dm->altitude[order[b - 1]]; b--) {
                int o = order[b];
                order[b] = order[b - 1];
                order[b - 1] = o;
            }
        for (int k = 0; k < dm->ndms; k++) alt[k] = dm->altitude[order[k]];
        wt_profile_bin_altitude(dm->ndms, alt, h, &j, &w);
        for (int side = 0; side < 2; side++) {
            if ((side ? w : 1.0 - w) <= 0.0) continue;
            const int k = order[j + side];
            const wt_grid *dg = &dm->grid[k];
            for (int iy = 0; iy < dg->ny; iy++)
                for (int ix = 0; ix < dg->nx; ix++) {
                    if (!dm->active[k][ix + (int64_t)dg->nx * iy]) continue;
                    double u = (dg->x0 + ix * dg->dx - g.x0) / delta, v = (dg->y0 + iy * dg->dx - g.y0) / delta;
                    if (u < -1e-6 || v < -1e-6 || u > n - 1 + 1e-6 || v > n - 1 + 1e-6) return 0;
                }
        }
    }
    return 1;
}

/* Every automatic layer of both variants holds every footprint at its altitude (LGS, NGS, evaluation
 * directions; pcg3 also its DMs' actuators), and its size is the smallest power of two that does: n/2 does
 * not (or n is already the wavelet's minimum max(4, 2^J)). */
static void check_auto_layers(const char *preset, int nset, const char *const *set)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    ck_assert_msg(wt_config_read(ctx, preset, nset, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    const int minimum = (1 << cfg->wavelet_levels) > 4 ? 1 << cfg->wavelet_levels : 4;
    for (int pcg3 = 0; pcg3 < 2; pcg3++) {
        const wt_recon_variant_config *v = pcg3 ? &cfg->pcg3 : &cfg->cg9;
        ck_assert_int_eq(v->grid_auto, WT_GRID_AUTO);
        for (int l = 0; l < v->nlayers; l++) {
            const double h = v->altitudes[l];
            const int n = v->size[l];
            ck_assert_msg(layer_holds(ctx, sys, pcg3, h, n, v->spacing[l]), "%s %s layer %d (%g m, %d x %g m): %s",
                          preset, pcg3 ? "pcg3" : "cg9", l + 1, h, n, v->spacing[l], wt_error_message(ctx));
            ck_assert_msg(n == minimum || !layer_holds(ctx, sys, pcg3, h, n / 2, v->spacing[l]),
                          "%s %s layer %d (%g m): %d x %g m is not the smallest power of two (%d holds)", preset,
                          pcg3 ? "pcg3" : "cg9", l + 1, h, n, v->spacing[l], n / 2);
        }
    }
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}

START_TEST(test_auto_grid_covers_eelt) { check_auto_layers("data/presets/eelt-mcao.cfg", 4, AUTO_GRIDS); }
END_TEST

START_TEST(test_auto_grid_covers_42)
{
    /* and with the oversampling: 0.5 m layers on the 1 m system */
    check_auto_layers("data/presets/eelt-mcao-nea20-42.cfg", 4, AUTO_GRIDS);
    const char *set[] = {AUTO_GRIDS[0], AUTO_GRIDS[1], AUTO_GRIDS[2], AUTO_GRIDS[3], "recon.cg9.layer_oversampling=2",
                         "recon.pcg3.layer_oversampling=2"};
    check_auto_layers("data/presets/eelt-mcao-nea20-42.cfg", 6, set);
}
END_TEST

START_TEST(test_auto_grid_covers_demo)
{
    check_auto_layers("data/presets/demo.cfg", 4, AUTO_GRIDS);
    /* a wider field, a guard ring more and a layer between the DMs and one above them */
    const char *set[] = {AUTO_GRIDS[0], AUTO_GRIDS[1], AUTO_GRIDS[2], AUTO_GRIDS[3], "dm.guard_rings=2",
                         "ngs.radius_arcsec=150.0", "evaluation.grid=7",
                         "recon.pcg3.layer_altitudes_m=[0.0, 2500.0, 4000.0, 12700.0, 16000.0]",
                         "recon.cg9.layer_oversampling=1.5"};
    check_auto_layers("data/presets/demo.cfg", 9, set);
}
END_TEST

/* The demo with every layer grid automatic builds both reconstructors (their tomography, fitting and
 * command map check the grids again) and reconstructs a frame of slopes. */
START_TEST(test_auto_grid_runs)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    ck_assert_msg(wt_config_read(ctx, "data/presets/demo.cfg", 4, AUTO_GRIDS, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "%s", wt_error_message(ctx));
    double *s = calloc((size_t)sys->nslopes, sizeof *s), *a = calloc((size_t)sys->nact, sizeof *a);
    for (int64_t i = 0; i < sys->nslopes; i++) s[i] = 1e-7 * sin(0.37 * (double)i);
    const int kinds[2] = {WT_RECON_PCG3, WT_RECON_CG9};
    for (int k = 0; k < 2; k++) {
        wt_reconstructor_params par;
        wt_reconstructor *r = NULL;
        wt_reconstructor_params_from_config(cfg, kinds[k], 4, &par);
        ck_assert_msg(wt_reconstructor_alloc(ctx, sys, kinds[k], &par, &r) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_ge(wt_reconstructor_apply(r, s, a), 0);
        double norm = 0.0;
        for (int64_t i = 0; i < sys->nact; i++) norm += a[i] * a[i];
        ck_assert(isfinite(norm) && norm > 0.0);
        wt_reconstructor_free(r);
    }
    free(s);
    free(a);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("system");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_eelt_sizes_and_order);
    tcase_add_test(tc, test_dm_without_actuators);
    tcase_add_test(tc, test_auto_grid_covers_eelt);
    tcase_add_test(tc, test_auto_grid_covers_42);
    tcase_add_test(tc, test_auto_grid_covers_demo);
    tcase_add_test(tc, test_auto_grid_runs);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
