/* tests/tomography_fixture.h: the set-up the tomography suites share (test_tomography_*.c, test_precond_solve.c,
 * test_fitting.c): a configuration read with overrides, its system, and (cg9 >= 0) the variant's tomography operator
 * and preconditioner. Static inline: each suite uses what it needs. */
#ifndef WT_TESTS_TOMOGRAPHY_FIXTURE_H
#define WT_TESTS_TOMOGRAPHY_FIXTURE_H

#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
#define EELT "data/presets/eelt-mcao.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    wt_precond *p; /* the variant's preconditioner */
} fixture;

static inline void setup(fixture *f, const char *path, int cg9, int nset, const char *const *set)
{
    f->ctx = tu_context();
    ck_assert_msg(wt_config_read(f->ctx, path, nset, set, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    f->t = NULL;
    f->p = NULL;
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    if (cg9 >= 0) {
        const wt_recon_variant_config *v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
        ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                      wt_error_message(f->ctx));
        const wt_precond_params pp = wt_precond_params_from_variant(v);
        ck_assert_msg(wt_precond_alloc(f->ctx, f->t, &pp, &f->p) == WT_OK, "%s", wt_error_message(f->ctx));
    }
}

static inline void teardown(fixture *f)
{
    wt_precond_free(f->p);
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

#endif
