/* tests/fuzz/fuzz_mvm.c: libFuzzer target of the MVM control-matrix reader (core/io/mvm_file.c, SPEC §9).
 *
 * Input: the bytes of a MATRIX.h5, opened as a memory image and read by wt_mvm_file_read_open for the
 * demo configuration (its config_sha256) with a FUZZ_NACT x FUZZ_NSLOPES matrix (the seeds are written
 * that size by tests/fuzz/make_seeds.c through the library's own writer). An accepted matrix must be
 * finite and of a variant the builder writes. */
#include "fuzz.h"
#include "fuzz_h5.h"

#include <math.h>

#include "core/io/mvm_file.h"

static wt_context *ctx;
static wt_config *demo;
static wt_mvm_file_system demo_fs;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    if (!(ctx = wt_context_alloc())) fuzz_die("wt_context_alloc", NULL);
    demo = fuzz_demo_config(ctx);
    demo_fs = fuzz_file_system(demo);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static float R[FUZZ_NACT * FUZZ_NSLOPES], RA[FUZZ_NACT * FUZZ_NACT];
    char variant[16];
    wt_h5_reader *r = NULL;
    long ids = fuzz_h5_open_ids();
    if (wt_h5_open_image(ctx, "fuzz-M.h5", data, size, &r) < 0) {
        fuzz_h5_check_ids(ids);
        return 0;
    }
    if (wt_mvm_file_read_open(ctx, r, &demo_fs, FUZZ_NACT, FUZZ_NSLOPES, &(wt_mvm_file_data){.precision = WT_MVM_FILE_F32, .R = R, .RA = RA}, variant) == WT_OK) {
        if (strcmp(variant, "pcg3") && strcmp(variant, "cg9")) abort();
        for (int i = 0; i < FUZZ_NACT * FUZZ_NSLOPES; i++)
            if (!isfinite(R[i])) abort();
        for (int i = 0; i < FUZZ_NACT * FUZZ_NACT; i++)
            if (!isfinite(RA[i])) abort();
    }
    wt_h5_close(r);
    fuzz_h5_check_ids(ids);
    return 0;
}
