/* tests/profile_fixture.h: what the profile suites share (test_profile.c, test_profile_error.c): the demo
 * preset read from the source tree (with overrides) and the matrix identity (matrix_sha256) of a configuration. */
#ifndef WT_TESTS_PROFILE_FIXTURE_H
#define WT_TESTS_PROFILE_FIXTURE_H

#include <string.h>
#include <unistd.h>

#include "core/config/config.h"
#include "testutil.h"

/* Presets live in data/presets of the source tree; tests run from its root (make test) or from tests/. */
static const char *root(void) { return access("data/presets/demo.cfg", R_OK) == 0 ? "" : "../"; }

static int read_demo(wt_context *ctx, int nov, const char *const *ov, wt_config **out)
{
    char path[256];
    snprintf(path, sizeof path, "%sdata/presets/demo.cfg", root());
    return wt_config_read(ctx, path, nov, ov, out);
}

static wt_config *demo_ok(wt_context *ctx, int nov, const char *const *ov)
{
    wt_config *c = NULL;
    const int st = read_demo(ctx, nov, ov, &c);
    ck_assert_msg(st == WT_OK, "status %d: %s", st, wt_error_message(ctx));
    return c;
}

/* The matrix identity (matrix_sha256) of the demo with the overrides ov. */
static void hash_of(wt_context *ctx, int nov, const char *const *ov, char out[65])
{
    wt_config *c = demo_ok(ctx, nov, ov);
    memcpy(out, c->matrix_sha256, 65);
    wt_config_free(ctx, c);
}

#endif
