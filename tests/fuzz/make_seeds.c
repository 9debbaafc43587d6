/* tests/fuzz/make_seeds.c: the seed corpora of the HDF5 targets (`make fuzz` writes them under
 * build/fuzz/seeds/, nothing binary is committed): small MATRIX.h5 files for the demo configuration
 * through the library's own writer (wt_mvm_file_write), spoiled as the bad-input suite spoils them (G, H,
 * J), telemetry files of the demo system (2 frames; int32 slopes, a NaN, 0 frames, an extent of 10^9
 * frames: G, H, I), and recipes for fuzz_h5_recipe. `wavetomo sim --telemetry` adds a real one.
 * usage: make_seeds DEMO.cfg OUTDIR (OUTDIR/{mvm,telemetry,h5_recipe} must exist). */
#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/io/h5.h"
#include "core/io/mvm_file.h"
#include "core/model/system.h"
#include "fuzz.h"

static wt_context *ctx;

static void check(int st, const char *what)
{
    if (st < 0) fuzz_die(what, ctx);
}

static void matrix(const char *dir, const char *name, const wt_config *cfg, int kind)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/mvm/%s.h5", dir, name);
    float R[FUZZ_NACT * FUZZ_NSLOPES], RA[FUZZ_NACT * FUZZ_NACT];
    for (int i = 0; i < FUZZ_NACT * FUZZ_NSLOPES; i++) R[i] = 0.01f * (float)(i % 7);
    for (int i = 0; i < FUZZ_NACT * FUZZ_NACT; i++) RA[i] = i % (FUZZ_NACT + 1) ? 0.0f : 1.0f;
    if (kind == 1) R[7] = NAN;
    wt_mvm_file_record rec = {.variant = kind == 2 ? "cg9" : kind == 3 ? "pcg33" : "pcg3", .nunknowns = 42,
                              .nnz_factor = 1e3, .rank = 3, .build_time = 0.5, .peak_estimate = 1e6,
                              .ordering = "AMD", .cholmod_version = "5.0"};
    wt_h5_writer *w;
    check(wt_h5_create(ctx, path, &w), path);
    const wt_mvm_file_system fs = fuzz_file_system(cfg);
    const wt_mvm_file_data d = {.precision = WT_MVM_FILE_F32, .R = R, .RA = RA};
    check(wt_mvm_file_write(w, &fs, FUZZ_NACT, FUZZ_NSLOPES, &d, &rec), path);
    check(wt_h5_commit(w), path);
}

static void telemetry(const char *dir, const char *name, const wt_config *cfg, const wt_system *sys, int kind)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/telemetry/%s.h5", dir, name);
    int64_t ns = sys->nslopes, na = sys->nact;
    int ft = kind == 1 ? WT_H5_I32 : WT_H5_F32;
    wt_h5_writer *w;
    wt_h5_series *s, *so, *c;
    check(wt_h5_create(ctx, path, &w), path);
    check(wt_h5_write_string(w, "config", cfg->canonical, "configuration"), path);
    check(wt_h5_series_create(w, "slopes", ft, ns, "rad", "slopes", &s), path);
    check(wt_h5_series_create(w, "slopes_ol", ft, ns, "rad", "pseudo-open-loop slopes", &so), path);
    check(wt_h5_series_create(w, "commands", WT_H5_F32, na, "m", "commands", &c), path);
    float *buf = calloc((size_t)(ns > na ? ns : na), sizeof *buf);
    for (int t = 0; kind != 3 && t < 2; t++) {
        for (int64_t i = 0; i < ns; i++) buf[i] = kind == 1 ? 0.0f : 1e-7f * (float)((i + t) % 13);
        if (kind == 2 && t == 1) buf[9] = NAN;
        check(wt_h5_series_append(s, kind == 1 ? WT_H5_I32 : WT_H5_F32, buf), path);
        check(wt_h5_series_append(so, kind == 1 ? WT_H5_I32 : WT_H5_F32, buf), path);
        memset(buf, 0, (size_t)na * sizeof *buf);
        check(wt_h5_series_append(c, WT_H5_F32, buf), path);
    }
    free(buf);
    check(wt_h5_commit(w), path);
    if (kind == 4) { /* the header claims 10^9 frames */
        hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT), d = f < 0 ? -1 : H5Dopen2(f, "slopes", H5P_DEFAULT);
        hsize_t dims[2] = {1000000000ULL, (hsize_t)ns};
        if (d < 0 || H5Dset_extent(d, dims) < 0) fuzz_die("H5Dset_extent", NULL);
        H5Dclose(d), H5Fclose(f);
    }
}

static void recipe(const char *dir, const char *name, const unsigned char *b, size_t n)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/h5_recipe/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(b, 1, n, f) != n || fclose(f) != 0) fuzz_die(path, NULL);
}

int main(int argc, char **argv)
{
    if (argc != 3) return fprintf(stderr, "usage: make_seeds DEMO.cfg OUTDIR\n"), 2;
    if (!(ctx = wt_context_alloc())) return 1;
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    check(wt_config_read(ctx, argv[1], 0, NULL, &cfg), argv[1]);
    check(wt_system_alloc(ctx, cfg, &sys), "wt_system_alloc");
    const char *dir = argv[2];
    matrix(dir, "ok", cfg, 0);
    matrix(dir, "nan", cfg, 1);
    matrix(dir, "cg9", cfg, 2);
    matrix(dir, "variant", cfg, 3);
    telemetry(dir, "ok", cfg, sys, 0);
    telemetry(dir, "int32", cfg, sys, 1);
    telemetry(dir, "nan", cfg, sys, 2);
    telemetry(dir, "zero", cfg, sys, 3);
    telemetry(dir, "huge", cfg, sys, 4);
    /* recipes (see fuzz_h5_recipe.c): v2 format; complete = 1; creator, config_sha256, variant strings;
     * config and matrix_config texts; slopes, slopes_ol (2 x nslopes) and commands (2 x nact) float32
     * chunked with Fletcher32; R (6 x 10), RA (6 x 6) float32 */
    static const unsigned char good[] = {0,    0,    1,    4,    1,    2,    1,    3,    2,    0,    2,    1,
                                         3,    0,    26,   0xE2, 0x20, 100,  3,    0,    26,   0xE2, 0x20, 100,
                                         3,    0,    26,   0xE2, 0x40, 100,  3,    0,    26,   0x60, 0x80, 101,
                                         3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,
                                         3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,
                                         3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,
                                         3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,
                                         3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,    3,
                                         3,    0,    2,    0x60, 0x60, 100,  0};
    recipe(dir, "good", good, sizeof good);
    unsigned char v0[sizeof good];
    memcpy(v0, good, sizeof good);
    v0[0] = 1; /* the earliest format: no metadata checksums */
    recipe(dir, "v0", v0, sizeof v0);
    static const unsigned char links[] = {0, 0, 0, 0, 0, 7, 15, 31, 6, 3, 0xA1, 0xE2, 0x20, 251, 3, 0xF0, 4, 0xE1};
    recipe(dir, "links", links, sizeof links);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
    return 0;
}
