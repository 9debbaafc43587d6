/* tests/regress/commands.c: the bit-identity guard of a refactor (issue 8 §0): SHA-256 of the exact
 * per-frame DM commands of short closed loops, so that a change meant to leave the numbers alone can be
 * shown to leave them alone.
 *
 *   regress_commands lib PRESET FRAMES SEED   runs, in process, the closed loop of every reconstructor
 *       (none, pcg3, cg9, and the MVM built for pcg3 and for cg9) on PRESET for FRAMES frames and prints
 *       one line per method: "lib-<method> <SHA-256 of the applied commands a_t of every frame, as
 *       float64, frame after frame>" — every bit of the doubles counts;
 *   regress_commands tel FILE...              prints "<file name> <SHA-256 of the dataset 'commands'>"
 *       of each telemetry file (`wavetomo sim --telemetry`, float32 as stored), or of 'reconstruction'
 *       of a `wavetomo run` output, which covers the drivers.
 *
 * tests/regress/commands.sh runs both and compares with tests/regress/commands.sha256 (`make
 * regress-commands`). Not a Check suite: a changed hash is a finding to explain, not a tolerance. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base/sha256.h"
#include "core/io/h5.h"
#include "builder/mvm_build.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "sim/loop.h"

static int fail(wt_context *ctx, const char *what)
{
    fprintf(stderr, "regress_commands: %s: %s\n", what, wt_error_message(ctx));
    return 1;
}

/* The MVM of a variant, as `wavetomo build` makes it (exact factorisation, no Jacobi diagonal). */
static int build_mvm(wt_context *ctx, const wt_config *cfg, const wt_system *sys, int cg9, wt_mvm **out)
{
    return wt_mvm_build_variant(ctx, sys, cfg, cg9 ? "cg9" : "pcg3", NULL, out);
}

static int run_lib(wt_context *ctx, const char *preset, const char *frames, const char *seed)
{
    char fset[64], sset[64];
    snprintf(fset, sizeof fset, "loop.frames=%s", frames);
    snprintf(sset, sizeof sset, "sim.seed=%s", seed);
    /* mvm-cg9 runs with cg9's prior set to the paper's (its default "full" makes the MVM's N dense, 174 GB
     * at E-ELT size: the sparse path is the one a cg9 MVM uses), on a system of its own */
    const char *set[4] = {fset, sset, "evaluation.settle_frames=0", "recon.cg9.prior=\"paper\""};
    wt_config *cfg = NULL, *cfg_p = NULL;
    wt_system *sys = NULL, *sys_p = NULL;
    if (wt_config_read(ctx, preset, 3, set, &cfg) < 0 || wt_config_read(ctx, preset, 4, set, &cfg_p) < 0)
        return fail(ctx, preset);
    if (wt_system_alloc(ctx, cfg, &sys) < 0 || wt_system_alloc(ctx, cfg_p, &sys_p) < 0) return fail(ctx, "system");
    const char *names[] = {"none", "pcg3", "cg9", "mvm-pcg3", "mvm-cg9"};
    const int kinds[] = {WT_RECON_NONE, WT_RECON_PCG3, WT_RECON_CG9, WT_RECON_MVM, WT_RECON_MVM};
    const size_t nact = (size_t)sys->nact;
    double *all = malloc((size_t)cfg->frames * nact * sizeof *all);
    if (!all) return fail(ctx, "out of memory");
    for (int k = 0; k < 5; k++) {
        wt_mvm *mvm = NULL;
        wt_loop *lp = NULL;
        wt_config *c = k == 4 ? cfg_p : cfg;
        wt_system *y = k == 4 ? sys_p : sys;
        if (kinds[k] == WT_RECON_MVM && build_mvm(ctx, c, y, k == 4, &mvm) < 0) return fail(ctx, names[k]);
        wt_loop_options o = {.recon = kinds[k], .mvm = mvm, .iterations = -1, .seed = c->seed, .noise = c->noise};
        if (wt_loop_alloc(ctx, y, &o, &lp) < 0) return fail(ctx, names[k]);
        for (long t = 0; t < cfg->frames; t++) {
            if (wt_loop_step(lp) < 0) return fail(ctx, names[k]);
            memcpy(all + (size_t)t * nact, wt_loop_applied(lp), nact * sizeof *all);
        }
        char hex[65];
        wt_sha256_hex(all, (size_t)cfg->frames * nact * sizeof *all, hex);
        printf("lib-%s %s\n", names[k], hex);
        wt_loop_free(lp);
        wt_mvm_free(mvm);
    }
    free(all);
    wt_system_free(sys);
    wt_system_free(sys_p);
    wt_config_free(ctx, cfg);
    wt_config_free(ctx, cfg_p);
    return 0;
}

static int run_tel(wt_context *ctx, const char *path)
{
    wt_h5_reader *r = NULL;
    int rank;
    int64_t dims[8];
    if (wt_h5_open(ctx, path, &r) < 0) return fail(ctx, path);
    const char *name = wt_h5_exists(r, "commands") ? "commands" : "reconstruction";
    if (wt_h5_dims(r, name, &rank, dims) < 0 || rank != 2) return fail(ctx, path);
    float *buf = malloc((size_t)(dims[0] * dims[1]) * sizeof *buf + 1);
    if (!buf || wt_h5_read_rows(r, name, WT_H5_F32, 0, dims[0], buf) < 0) return fail(ctx, path);
    char hex[65];
    wt_sha256_hex(buf, (size_t)(dims[0] * dims[1]) * sizeof *buf, hex);
    const char *base = strrchr(path, '/');
    printf("%s %s\n", base ? base + 1 : path, hex);
    free(buf);
    wt_h5_close(r);
    return 0;
}

int main(int argc, char **argv)
{
    wt_context *ctx = wt_context_alloc();
    int rc = 2;
    if (argc == 5 && !strcmp(argv[1], "lib")) rc = run_lib(ctx, argv[2], argv[3], argv[4]);
    else if (argc >= 3 && !strcmp(argv[1], "tel")) {
        rc = 0;
        for (int i = 2; i < argc && !rc; i++) rc = run_tel(ctx, argv[i]);
    } else
        fprintf(stderr, "usage: regress_commands lib PRESET FRAMES SEED | tel TELEMETRY.h5...\n");
    wt_context_free(ctx);
    return rc;
}
