/* tests/test_system.c: the geometry of a configuration (SPEC §1, §3–§5; core/model/system.h) on the
 * paper's E-ELT system: its sizes as the paper and docs/SPEC.md §1 state them, the slope and actuator
 * orderings every other module relies on, and the error of a DM that has no active actuator. */
#include "core/model/system.h"
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

Suite *make_suite(void)
{
    Suite *s = suite_create("system");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_eelt_sizes_and_order);
    tcase_add_test(tc, test_dm_without_actuators);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
