/* runtime/cmd_run.c: `wavetomo run`: apply a stored MVM (float32 GEMV, POLC form) or the matrix-free
 * wavelet reconstructor to every frame of a telemetry file, and time it (SPEC §7, §9), through the
 * public per-frame API (include/wavetomo/rtc.h) in its WT_RTC_RAW mode. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "runtime/cmd_run.h"
#include "cli/cli.h"
#include "core/io/h5.h"
#include "core/io/mvm_file.h"
#include "core/model/reconstructor.h"
#include "core/model/system.h"
#include "core/model/estimate.h"
#include "runtime/rtc_internal.h"

static void help(void)
{
    printf("usage: wavetomo run --matrix MATRIX.h5 --telemetry TEL.h5 --out CMDS.h5 [[--config] FILE]\n"
           "       wavetomo run --recon pcg3|cg9 --telemetry TEL.h5 --out CMDS.h5 [[--config] FILE] [--iters N]\n"
           "\n"
           "Replays the frames of a telemetry file written by `wavetomo sim --telemetry` through a\n"
           "reconstructor and writes, per frame, its output R s_ol (the commands before the POLC integrator):\n"
           "  --matrix F   the stored MVM in its POLC form, R s_ol = R s + (R A^) a, two float32 GEMVs\n"
           "               through OpenBLAS (threaded); refused unless built for the telemetry's system\n"
           "  --recon R    the matrix-free wavelet reconstructor (pcg3 or cg9) on the pseudo-open-loop slopes,\n"
           "               warm-started frame to frame; --iters overrides its iteration count\n"
           "  --config F   the system, or F alone (default: the configuration stored in the telemetry, with\n"
           "               the --set overrides); with --matrix it must match both the matrix and the telemetry\n"
           "  --dry-run        print the estimated peak memory and run time and the keys that drive them; stop\n"
           "  --max-memory S   refuse up front when the estimate exceeds S bytes (4G, 512M; default MemAvailable)\n"
           "Reports the time per frame (median and 99th percentile) of the reconstruction alone (not the file\n"
           "reads). A frame holding NaN or Inf stops the run naming the frame.\n");
}

typedef struct {
    const char *matrix, *recon, *tel, *out;
    long iters;
} run_args;

static int run_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    run_args *a = user;
    const char *o = argv[*i];
    const char **str = !strcmp(o, "--matrix") ? &a->matrix
                       : !strcmp(o, "--recon")     ? &a->recon
                       : !strcmp(o, "--telemetry") ? &a->tel
                       : !strcmp(o, "--out")       ? &a->out
                                                   : NULL;
    if (str) {
        if (!(*str = wt_cli_value(cli, argc, argv, i))) return -1;
    } else if (!strcmp(o, "--iters")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v || wt_cli_int(cli, o, v, 0, 100000, &a->iters) < 0) return -1;
    } else
        return 0;
    return 1;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int wt_cmd_run(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo run", help)) return 1;
    run_args args = {NULL, NULL, NULL, NULL, -1};
    int rc = wt_cli_parse(&cli, argc, argv, run_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    if ((args.matrix != NULL) == (args.recon != NULL) || !args.tel || !args.out) {
        rc = wt_cli_usage_error(&cli, "give --telemetry, --out and exactly one of --matrix or --recon");
        wt_cli_done(&cli);
        return rc;
    }
    int kind = args.recon ? wt_reconstructor_kind(args.recon) : WT_RECON_MVM;
    if (args.recon && kind != WT_RECON_PCG3 && kind != WT_RECON_CG9) {
        rc = wt_cli_usage_error(&cli, kind == WT_RECON_MVM ? "--recon mvm: give the stored matrix with --matrix MATRIX.h5 "
                                "instead (run takes --matrix for the MVM, or --recon pcg3|cg9), got '%s'"
                                : "--recon expects pcg3 or cg9 (or --matrix MATRIX.h5 for the MVM), got '%s'", args.recon);
        wt_cli_done(&cli);
        return rc;
    }
    wt_h5_reader *tr = NULL;
    wt_h5_writer *w = NULL;
    wt_h5_series *out_rec = NULL, *out_time = NULL;
    wt_config *cfg = NULL, *tcfg = NULL;
    wt_system *sys = NULL;
    wt_rtc *rtc = NULL;
    float *sf = NULL, *af = NULL, *rf = NULL;
    double *times = NULL;
    int st;
    if ((st = wt_cli_check_output(&cli, args.out, 0, args.tel, args.matrix)) < 0) goto fail;
    if ((st = wt_h5_open(cli.ctx, args.tel, &tr)) < 0) goto fail;
    /* the telemetry's own system, and the one asked for on the command line */
    if ((st = wt_cli_telemetry_config(&cli, tr, args.tel, &tcfg, &cfg)) < 0) goto fail;
    if (cfg) {
        if (strcmp(cfg->matrix_sha256, tcfg->matrix_sha256) != 0) {
            char diff[1024];
            wt_mvm_file_text_diff(tcfg->matrix_text, cfg->matrix_text, args.tel, cfg->path, diff, sizeof diff);
            st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s was recorded on another system than %s (%s)", args.tel,
                          cfg->path, diff[0] ? diff : "configuration hashes differ");
            goto fail;
        }
    }
    wt_config *use = cfg ? cfg : tcfg;
    {   /* the estimate counts the frames the file holds (fewer than loop.frames when `sim` was interrupted) */
        int rk = 0;
        int64_t d[3] = {0, 0, 0};
        const char *sn = kind == WT_RECON_MVM ? "slopes" : "slopes_ol";
        if (wt_h5_exists(tr, sn) && wt_h5_dims(tr, sn, &rk, d) >= 0 && rk == 2 && d[0] >= 1 && d[0] < use->frames)
            use->frames = (int)d[0];
    }
    if ((rc = wt_cli_estimate(&cli, use, WT_TASK_RUN, kind, (int)args.iters)) >= 0) goto cleanup;
    rc = 0;
    if ((st = wt_system_alloc(cli.ctx, use, &sys)) < 0) goto fail;
    int64_t dims[3], F;
    int64_t es[2] = {-1, sys->nslopes}, ea[2] = {-1, sys->nact};
    const char *sname = kind == WT_RECON_MVM ? "slopes" : "slopes_ol";
    if ((st = wt_h5_check_shape(tr, sname, 2, es, dims)) < 0) goto fail;
    F = dims[0];
    if (F < 1) st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s: dataset '%s' holds 0 frames: nothing to run", args.tel, sname);
    if (st < 0) goto fail;
    if (kind == WT_RECON_MVM) {
        if ((st = wt_h5_check_shape(tr, "commands", 2, ea, dims)) < 0) goto fail;
        if (dims[0] != F) {
            st = WT_ERROR(cli.ctx, WT_ERR_FORMAT, "%s: %lld frames of slopes but %lld of commands", args.tel,
                          (long long)F, (long long)dims[0]);
            goto fail;
        }
    }
    /* the matrix (refused unless built for this system) or the reconstructor; the frames carry s_ol (pcg3,
     * cg9) or s with the applied commands (the MVM's R s + (R Â) a), so no Â is built */
    if ((st = wt_rtc_open_system(cli.ctx, sys, kind, args.matrix, (int)args.iters, 1, &rtc)) < 0) goto fail;
    sf = malloc((size_t)sys->nslopes * sizeof *sf);
    af = malloc((size_t)sys->nact * sizeof *af);
    rf = malloc((size_t)sys->nact * sizeof *rf);
    times = malloc((size_t)(F > 0 ? F : 1) * sizeof *times);
    if (!sf || !af || !rf || !times) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory for the frame buffers");
        goto fail;
    }
    if ((st = wt_h5_create(cli.ctx, args.out, &w)) < 0) goto fail;
    if ((st = wt_h5_series_create(w, "reconstruction", WT_H5_F32, sys->nact, "m",
                                  "reconstructor output R s_ol per frame (commands before the POLC integrator)",
                                  &out_rec)) < 0)
        goto fail;
    if ((st = wt_h5_series_create(w, "time", WT_H5_F64, 0, "ms", "reconstruction time of each frame", &out_time)) < 0)
        goto fail;
    wt_progress pr;
    wt_progress_start(&pr, "frames", "frames", (long)F);
    if (cli.quiet) pr.enabled = 0;
    for (int64_t t = 0; t < F; t++) {
        /* the reader refuses NaN/Inf, naming the dataset, frame and column */
        if ((st = wt_h5_read_rows(tr, sname, WT_H5_F32, t, 1, sf)) < 0) goto fail;
        /* the MVM: R s_ol = R s + (R Â) a, the stored POLC form with the telemetry's applied commands (no Â
         * at run time); pcg3 / cg9: R s_ol of the telemetry's pseudo-open-loop slopes */
        if (kind == WT_RECON_MVM && (st = wt_h5_read_rows(tr, "commands", WT_H5_F32, t, 1, af)) < 0) goto fail;
        st = kind == WT_RECON_MVM
                 ? wt_rtc_frame_f32(rtc, sf, sys->nslopes, af, WT_RTC_RAW, rf, sys->nact)
                 : wt_rtc_frame_f32(rtc, sf, sys->nslopes, NULL, WT_RTC_RAW | WT_RTC_SLOPES_OL, rf, sys->nact);
        if (st < 0) goto fail;
        times[t] = wt_rtc_frame_time(rtc);
        double ms = times[t] * 1e3;
        if ((st = wt_h5_series_append(out_rec, WT_H5_F32, rf)) < 0) goto fail;
        if ((st = wt_h5_series_append(out_time, WT_H5_F64, &ms)) < 0) goto fail;
        wt_progress_update(&pr, (long)(t + 1), NULL);
    }
    wt_progress_end(&pr);
    if ((st = wt_cli_write_provenance(&cli, w, use, argc, argv)) < 0) goto fail;
    if ((st = wt_h5_attr_write_string(w, "/", "recon", args.matrix ? "mvm" : args.recon)) < 0) goto fail;
    if ((st = wt_cli_write_layout(w, sys)) < 0) goto fail;
    st = wt_h5_commit(w);
    w = NULL;
    if (st < 0) goto fail;
    if (F > 0) {
        qsort(times, (size_t)F, sizeof *times, cmp_double);
        double med = times[F / 2], p99 = times[(int64_t)floor(0.99 * (double)(F - 1))];
        printf("%s: %lld frames, time per frame median %.3f ms, 99th percentile %.3f ms\n",
               args.matrix ? "mvm" : args.recon, (long long)F, med * 1e3, p99 * 1e3);
        if (args.matrix)
            printf("  streams %.2f GB per frame (R and RA in float32): %.1f GB/s at the median\n",
                   4.0 * sys->nact * (double)(sys->nslopes + sys->nact) / 1e9,
                   4.0 * sys->nact * (double)(sys->nslopes + sys->nact) / med / 1e9);
    }
    printf("  commands: %s\n", args.out);
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_h5_abort(w);
    wt_h5_close(tr);
    free(sf), free(af), free(rf), free(times);
    wt_rtc_close(rtc);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_config_free(cli.ctx, tcfg);
    wt_cli_done(&cli);
    return rc;
}
