/* tests/fuzz/fuzz.h: what the libFuzzer targets of issue 10 share (`make fuzz`, docs/testing.md "Fuzzing").
 *
 * Each target feeds its bytes to one reader of the library and only asks that the reader returns (a
 * status, a message) without a crash, a leak, a hang, an UBSan report or an allocation beyond
 * libFuzzer's -malloc_limit_mb: what it accepts or refuses is the bad-input suite's business
 * (tests/test_badinput.c). The fixed inputs they need (the demo preset, the include sandbox) come from
 * WT_FUZZ_ROOT (the checkout, compiled in) and WT_FUZZ_SANDBOX (environment, set by the Makefile).
 */
#ifndef WT_FUZZ_H
#define WT_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/config/config.h"
#include "core/io/mvm_file.h"

#ifndef WT_FUZZ_ROOT
#define WT_FUZZ_ROOT "."
#endif
#define WT_FUZZ_DEMO WT_FUZZ_ROOT "/data/presets/demo.cfg"

/* The MVM target's system: the demo configuration (its hash) with a small matrix, so that an input is
 * kilobytes rather than the demo's 10 MB R (the reader takes the sizes from its caller). */
enum { FUZZ_NACT = 6, FUZZ_NSLOPES = 10 };

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

/* Abort set-up failures loudly: a target that silently tests nothing is worse than none. */
static inline void fuzz_die(const char *what, wt_context *ctx)
{
    fprintf(stderr, "fuzz set-up: %s%s%s\n", what, ctx ? ": " : "", ctx ? wt_error_message(ctx) : "");
    abort();
}

/* Work inside the include sandbox: a relative @include resolves there (wt_config_parse resolves against
 * the working directory). */
static inline void fuzz_enter_sandbox(void)
{
    const char *sb = getenv("WT_FUZZ_SANDBOX");
    if (!sb || chdir(sb) != 0) fuzz_die("WT_FUZZ_SANDBOX is not set to the sandbox directory (make fuzz sets it)", NULL);
}

/* 1 when the text may @include something outside the sandbox: a name starting with '/' or holding "..".
 * Conservative: any '"/' or ".." after an "@include" anywhere (the config reader's own scan is stricter
 * about where an @include may stand, and libconfig's is not ours to trust). */
static inline const char *fuzz_find(const char *p, const char *end, const char *w)
{
    for (size_t k = strlen(w); p + k <= end; p++)
        if (!memcmp(p, w, k)) return p;
    return NULL;
}

static inline int fuzz_escapes_sandbox(const char *s, size_t n)
{
    const char *p = s, *end = s + n;
    while ((p = fuzz_find(p, end, "@include")) != NULL) {
        p += 8;
        if (fuzz_find(p, end, "..") || fuzz_find(p, end, "\"/")) return 1;
    }
    return 0;
}

/* The demo configuration, read once. */
static inline wt_config *fuzz_demo_config(wt_context *ctx)
{
    wt_config *cfg = NULL;
    if (wt_config_read(ctx, WT_FUZZ_DEMO, 0, NULL, &cfg) < 0) fuzz_die("reading " WT_FUZZ_DEMO, ctx);
    return cfg;
}

/* The identity a matrix file is checked against, as the file layer takes it (plain data). */
static inline wt_mvm_file_system fuzz_file_system(const wt_config *c)
{
    return (wt_mvm_file_system){.sha256 = c->matrix_sha256, .text = c->matrix_text, .path = c->path,
                                .alpha = c->alpha, .tau = c->tau};
}

#endif
