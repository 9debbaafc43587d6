/* tests/fuzz/fuzz_telemetry.c: libFuzzer target of the telemetry reading of `wavetomo run` (SPEC §9).
 *
 * Input: the bytes of a telemetry file (TEL.h5 of `wavetomo sim --telemetry`), opened as a memory image
 * (wt_h5_open_image: core driver, no disk I/O). The calls and their order are runtime/cmd_run.c's: the stored
 * configuration text parsed (in the include sandbox), its hash against the system's, the shapes of
 * slopes, slopes_ol and commands for the demo system, then every frame read row by row (at most 16) as
 * float32 and checked finite. The demo system (sizes) is built once. */
#include "fuzz.h"
#include "fuzz_h5.h"

#include <math.h>

#include "core/io/h5.h"
#include "core/model/system.h"

static wt_context *ctx;
static wt_config *demo;
static int64_t nslopes, nact;
static float *row;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    if (!(ctx = wt_context_alloc())) fuzz_die("wt_context_alloc", NULL);
    demo = fuzz_demo_config(ctx);
    wt_system *sys = NULL;
    if (wt_system_alloc(ctx, demo, &sys) < 0) fuzz_die("wt_system_alloc", ctx);
    nslopes = sys->nslopes, nact = sys->nact;
    wt_system_free(sys);
    if (!(row = malloc((size_t)(nslopes > nact ? nslopes : nact) * sizeof *row))) fuzz_die("malloc", NULL);
    fuzz_enter_sandbox();
    return 0;
}

/* One series: its shape for `cols` values per frame, then frames [0, min(F, 16)). [out] *frames. */
static int read_series(wt_h5_reader *r, const char *name, int64_t cols, int64_t *frames)
{
    int64_t expect[2] = {-1, cols}, dims[2];
    int st = wt_h5_check_shape(r, name, 2, expect, dims);
    if (st < 0) return st;
    if (dims[0] < 0 || dims[1] != cols) abort(); /* the shape check's promise */
    *frames = dims[0];
    for (int64_t t = 0; t < dims[0] && t < 16; t++) {
        if ((st = wt_h5_read_rows(r, name, WT_H5_F32, t, 1, row)) < 0) return st;
        for (int64_t i = 0; i < cols; i++)
            if (!isfinite(row[i])) abort(); /* H: the reader scans for NaN/Inf */
    }
    return WT_OK;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    wt_h5_reader *r = NULL;
    wt_config *tcfg = NULL;
    char *text = NULL;
    int64_t F = 0, Fo = 0, Fc = 0;
    long ids = fuzz_h5_open_ids();
    if (wt_h5_open_image(ctx, "fuzz-tel.h5", data, size, &r) < 0) goto done;
    if (wt_h5_read_string(r, "config", &text) < 0) goto done;
    if (fuzz_escapes_sandbox(text, strlen(text))) goto done;
    if (wt_config_parse(ctx, text, "fuzz-tel.h5:config", 0, NULL, &tcfg) < 0) goto done;
    /* run builds the stored system; here only the demo's is affordable per input */
    if (strcmp(tcfg->matrix_sha256, demo->matrix_sha256) != 0) goto done;
    if (read_series(r, "slopes", nslopes, &F) < 0) goto done;
    if (read_series(r, "slopes_ol", nslopes, &Fo) < 0) goto done;
    if (read_series(r, "commands", nact, &Fc) < 0) goto done;
done:
    wt_config_free(ctx, tcfg);
    wt_free(ctx, text);
    wt_h5_close(r);
    fuzz_h5_check_ids(ids);
    return 0;
}
