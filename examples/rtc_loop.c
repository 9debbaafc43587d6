/* examples/rtc_loop.c: replay the slopes of `wavetomo sim --telemetry` through the per-frame API and check
 * the commands against `wavetomo run`'s, bit for bit (docs/c-api.md).
 *   rtc_loop TEL.h5 CMDS.h5 pcg3|cg9|MATRIX.h5
 *   cc rtc_loop.c $(pkg-config --cflags --libs wavetomo hdf5) -o rtc_loop */
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <wavetomo/wavetomo.h>

/* row t of an n-column float32 dataset (frame t of a time series) */
static int row(hid_t f, const char *name, hsize_t t, hsize_t n, float *out)
{
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT), fs = H5Dget_space(d), ms = H5Screate_simple(1, &n, NULL);
    hsize_t start[2] = {t, 0}, count[2] = {1, n};
    H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL);
    herr_t e = H5Dread(d, H5T_NATIVE_FLOAT, ms, fs, H5P_DEFAULT, out);
    H5Sclose(ms), H5Sclose(fs), H5Dclose(d);
    return e < 0 ? -1 : 0;
}

/* a string dataset: variable-length UTF-8 as wavetomo writes them, or fixed-length (files of earlier builds) */
static char *text(hid_t f, const char *name)
{
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT), ft = H5Dget_type(d), sp = H5Dget_space(d), mt = H5Tcopy(H5T_C_S1);
    int var = H5Tis_variable_str(ft) > 0;
    size_t n = var ? 0 : H5Tget_size(ft);
    char *s = NULL, *v = NULL;
    H5Tset_cset(mt, H5Tget_cset(ft));
    if (var && H5Tset_size(mt, H5T_VARIABLE) >= 0 && H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, &v) >= 0 && v) {
        n = strlen(v);
        s = calloc(n + 1, 1);
        memcpy(s, v, n);
        H5Dvlen_reclaim(mt, sp, H5P_DEFAULT, &v);
    } else if (!var) {
        s = calloc(n + 1, 1);
        if (H5Tset_size(mt, n + 1) < 0 || H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, s) < 0) s[0] = 0;
    }
    H5Tclose(mt), H5Sclose(sp), H5Tclose(ft), H5Dclose(d);
    return s ? s : calloc(1, 1);
}

int main(int argc, char **argv)
{
    if (argc != 4) return fprintf(stderr, "usage: rtc_loop TEL.h5 CMDS.h5 pcg3|cg9|MATRIX.h5\n"), 2;
    hid_t tel = H5Fopen(argv[1], H5F_ACC_RDONLY, H5P_DEFAULT), cmd = H5Fopen(argv[2], H5F_ACC_RDONLY, H5P_DEFAULT);
    if (tel < 0 || cmd < 0) return fprintf(stderr, "rtc_loop: cannot open %s or %s\n", argv[1], argv[2]), 1;
    wt_context *ctx = wt_context_alloc();
    wt_rtc *rtc;
    int mvm = strcmp(argv[3], "pcg3") && strcmp(argv[3], "cg9"), st;
    char *config = text(tel, "config"); /* the system the telemetry was recorded on */
    st = mvm ? wt_rtc_open_mvm(ctx, argv[3], NULL, 0, NULL, &rtc) : wt_rtc_open_text(ctx, argv[3], config, 0, NULL, &rtc);
    if (st < 0) return fprintf(stderr, "rtc_loop: %s\n", wt_error_message(ctx)), 1;
    const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
    float *s = malloc(ns * sizeof *s), *a = malloc(na * sizeof *a), *c = malloc(na * sizeof *c), *ref = malloc(na * sizeof *ref);
    hsize_t frames, dims[2];
    hid_t d = H5Dopen2(cmd, "reconstruction", H5P_DEFAULT), sp = H5Dget_space(d);
    H5Sget_simple_extent_dims(sp, dims, NULL), H5Sclose(sp), H5Dclose(d);
    frames = dims[0];
    double total = 0;
    long worst = 0; /* commands that differ */
    for (hsize_t t = 0; t < frames && st >= 0; t++) {
        /* the MVM: R s + (R A) a from the measured slopes and the applied commands; pcg3/cg9: R s_ol */
        if (row(tel, mvm ? "slopes" : "slopes_ol", t, ns, s) || (mvm && row(tel, "commands", t, na, a)) ||
            row(cmd, "reconstruction", t, na, ref))
            return fprintf(stderr, "rtc_loop: cannot read frame %llu\n", (unsigned long long)t), 1;
        st = wt_rtc_frame_f32(rtc, s, ns, mvm ? a : NULL, WT_RTC_RAW | (mvm ? 0 : WT_RTC_SLOPES_OL), c, na);
        for (int64_t i = 0; i < na; i++) worst += c[i] != ref[i];
        total += wt_rtc_frame_time(rtc);
    }
    if (st < 0) return fprintf(stderr, "rtc_loop: %s\n", wt_error_message(ctx)), 1;
    printf("rtc_loop: wavetomo %s, %s, %llu frames of %lld slopes -> %lld commands, %.3f ms per frame: %s\n",
           wt_version(), wt_rtc_recon(rtc), (unsigned long long)frames, (long long)ns, (long long)na,
           1e3 * total / (double)frames, worst ? "DIFFERENT from wavetomo run" : "identical to wavetomo run");
    wt_rtc_close(rtc), wt_context_free(ctx), free(config), free(s), free(a), free(c), free(ref);
    H5Fclose(tel), H5Fclose(cmd);
    return worst == 0 ? 0 : 1;
}
