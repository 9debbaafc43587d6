/* tests/pixels_fixture.h: the demo's first diffractive LGS sensor on its own (tests/test_pixels.c, test_mf_gain.c),
 * and the OPD of a tilt on its subapertures. */
#ifndef WT_TESTS_PIXELS_FIXTURE_H
#define WT_TESTS_PIXELS_FIXTURE_H

#include "core/model/sensing.h"
#include "core/model/system.h"
#include "testutil.h"

#define DDEMO "data/presets/demo-diffractive.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_sensing *ws; /* the first diffractive LGS */
} rig;

static void rig_open_with(rig *r, int nset, const char *const *set)
{
    r->ctx = tu_context();
    wt_context_set_threads(r->ctx, 2);
    ck_assert_msg(wt_config_read(r->ctx, DDEMO, nset, set, &r->cfg) == WT_OK, "%s", wt_error_message(r->ctx));
    ck_assert_msg(wt_system_alloc(r->ctx, r->cfg, &r->sys) == WT_OK, "%s", wt_error_message(r->ctx));
    r->ws = NULL;
    for (int m = 0; m < r->sys->nsensors && !r->ws; m++)
        if (r->sys->sensors[m].diffr && r->sys->sensors[m].kind == WT_SENSOR_LGS) r->ws = r->sys->sensors[m].diffr;
    ck_assert_ptr_nonnull(r->ws);
}

static inline void rig_close(rig *r)
{
    wt_system_free(r->sys);
    wt_config_free(r->ctx, r->cfg);
    wt_context_free(r->ctx);
}

/* ws->opd of a tilt (th[k] + ax, th[nsub + k] + ay) [rad] on every subaperture k */
static inline void set_tilt(wt_sensing *ws, const double *th, double ax, double ay)
{
    const int nsub = ws->nsub, np = ws->np;
    const double ds = ws->side / np;
    for (int k = 0; k < nsub; k++)
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++)
                ws->opd[(size_t)k * np * np + i + (size_t)np * j] =
                    (float)(ds * ((th[k] + ax) * (i - 0.5 * (np - 1)) + (th[nsub + k] + ay) * (j - 0.5 * (np - 1))));
}

#endif
