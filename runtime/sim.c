/* runtime/sim.c: `wavetomo sim`: the closed-loop end-to-end simulation of one reconstructor
 * (core/sim/loop), with its result file, optional telemetry and screen dumps. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "core/io/h5.h"
#include "core/solve/mvm.h"
#include "core/sim/atmosphere.h"
#include "core/sim/loop.h"
#include "core/model/estimate.h"

static void help(void)
{
    printf("usage: wavetomo sim --config FILE [--set key=value]... [--recon pcg3|cg9|none|mvm]\n"
           "                    [--matrix MATRIX.h5]\n"
           "                    [--frames N] [--seed S] [--iters N] [--no-noise] --out RUN.h5\n"
           "                    [--telemetry TEL.h5] [--dump-screens] [--threads N] [--quiet]\n"
           "\n"
           "Runs the closed-loop MCAO simulation of SPEC §2-§8: frozen-flow von Karman layers, truth\n"
           "Shack-Hartmann sensors with photon/read noise, spot elongation and LGS tip-tilt, the chosen\n"
           "reconstructor inside pseudo-open-loop control (delay and gain from the config), and the\n"
           "Strehl ratio in every evaluation direction.\n"
           "\n"
           "  --recon R        pcg3 (default: layers at the DMs, modified Jacobi PCG), cg9 (layers at the\n"
           "                   atmosphere altitudes, CG + fitting), none (DMs flat: the uncorrected baseline),\n"
           "                   mvm (the stored control matrix given by --matrix, from `wavetomo build`)\n"
           "  --matrix F       MATRIX.h5 for --recon mvm; refused unless built for this configuration\n"
           "  --frames N       frames to run (loop.frames); settle frames are kept below N\n"
           "  --seed S         random seed (sim.seed): the same seed gives identical results\n"
           "  --iters N        (P)CG iterations per frame (overrides recon.<variant>.iterations)\n"
           "  --no-noise       noise-free sensors (sim.noise = false)\n"
           "  --out RUN.h5     result file: per-direction LE Strehl and WFE, per-frame Strehl, timings,\n"
           "                   the configuration, seed and versions (see README, 'Result files')\n"
           "  --telemetry F    also write per frame the measured and pseudo-open-loop slopes and the\n"
           "                   applied commands (float32), for `wavetomo run`\n"
           "  --dump-screens   add the layer screens of frame 0 and the residual OPD maps of the last\n"
           "                   frame to RUN.h5\n"
           "  --dry-run        print the estimated peak memory and run time and the keys that drive them; stop\n"
           "  --max-memory S   refuse up front when the estimate exceeds S bytes (4G, 512M; default MemAvailable)\n"
           "A progress line (frames, frames/s, ETA, running field-average Strehl) goes to stderr on a terminal.\n");
}

typedef struct {
    wt_h5_series *slopes, *slopes_ol, *commands;
} telemetry;

static int write_results(wt_cli *cli, wt_h5_writer *w, const wt_config *cfg, const wt_system *sys, wt_loop *lp,
                         const char *recon, long frames, const double *se_field, const double *se_axis,
                         const float *rms_nm, int dump, int argc, char **argv)
{
    int st;
    const wt_strehl_le *le = wt_loop_le(lp);
    int nd = sys->neval;
    double sle[WT_MAX_EVAL], wfe[WT_MAX_EVAL], tx[WT_MAX_EVAL], ty[WT_MAX_EVAL], field = 0.0, fwfe = 0.0;
    for (int j = 0; j < nd; j++) {
        sle[j] = wt_strehl_le_strehl(le, j);
        wfe[j] = wt_strehl_le_wfe(le, j) * 1e9;
        tx[j] = sys->eval_x[j] / WT_ARCSEC;
        ty[j] = sys->eval_y[j] / WT_ARCSEC;
        field += sle[j] / nd;
        fwfe += wfe[j] * wfe[j] / nd;
    }
    int64_t dn[1] = {nd}, df[1] = {frames}, dr[2] = {frames, nd};
    if ((st = wt_cli_write_provenance(cli, w, cfg, argc, argv)) < 0) return st;
    if ((st = wt_h5_attr_write_string(w, "/", "recon", recon)) < 0) return st;
    if ((st = wt_h5_write_int64(w, "frames", frames, "", "frames simulated")) < 0) return st;
    if ((st = wt_h5_write_int64(w, "settle_frames", cfg->settle_frames, "",
                                "frames left out of the long-exposure averages")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "eval/wavelength", cfg->eval_wavelength * 1e9, "nm",
                                 "wavelength of the Strehl ratios (Marechal approximation)")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/theta_x", WT_H5_F64, WT_H5_F64, 1, dn, tx, "arcsec",
                          "evaluation direction x; index i + g*j of the g x g grid")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/theta_y", WT_H5_F64, WT_H5_F64, 1, dn, ty, "arcsec", "evaluation direction y")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/strehl_le", WT_H5_F64, WT_H5_F64, 1, dn, sle, "",
                          "long-exposure Strehl per evaluation direction (mean of the short-exposure Strehl after "
                          "the settle frames)")) < 0)
        return st;
    if ((st = wt_h5_write(w, "eval/wfe_le", WT_H5_F64, WT_H5_F64, 1, dn, wfe, "nm",
                          "residual wavefront error per direction: sqrt of the mean piston-removed variance after "
                          "the settle frames")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "strehl_le_on_axis", sle[sys->eval_centre], "",
                                 "long-exposure Strehl in the central (on-axis) direction")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "strehl_le_field", field, "",
                                 "long-exposure Strehl averaged over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write_double(w, "wfe_le_field", sqrt(fwfe), "nm",
                                 "residual wavefront error, rms over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/strehl_field", WT_H5_F64, WT_H5_F64, 1, df, se_field, "",
                          "short-exposure Strehl per frame, averaged over the evaluation directions")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/strehl_on_axis", WT_H5_F64, WT_H5_F64, 1, df, se_axis, "",
                          "short-exposure Strehl per frame in the central direction")) < 0)
        return st;
    if ((st = wt_h5_write(w, "frame/rms", WT_H5_F32, WT_H5_F32, 2, dr, rms_nm, "nm",
                          "piston-removed residual rms per frame and evaluation direction")) < 0)
        return st;
    wt_loop_times tm = wt_loop_get_times(lp);
    const char *names[] = {"atmosphere", "sensors", "reconstruction", "fitting", "control", "evaluation"};
    double vals[] = {tm.atmosphere, tm.sensors, tm.reconstruction, tm.fitting, tm.control, tm.evaluation};
    for (int k = 0; k < 6; k++) {
        char name[64];
        snprintf(name, sizeof name, "timing/%s", names[k]);
        if ((st = wt_h5_write_double(w, name, frames ? vals[k] / frames * 1e3 : 0.0, "ms",
                                     "mean wall time per frame of this part of the simulation")) < 0)
            return st;
    }
    if ((st = wt_cli_write_layout(w, sys)) < 0) return st;
    if (dump) {
        const wt_atmosphere *atm = wt_loop_atmosphere(lp);
        wt_grid g = wt_atmosphere_grid(atm);
        double *buf = malloc((size_t)wt_grid_size(&g) * sizeof *buf);
        if (!buf) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory dumping screens");
        for (int l = 0; l < wt_atmosphere_nlayers(atm); l++) {
            wt_atmosphere_layer_render(atm, l, buf);
            char name[64];
            snprintf(name, sizeof name, "screens/layer%d", l + 1);
            int64_t d[2] = {g.ny, g.nx};
            st = wt_h5_write(w, name, WT_H5_F32, WT_H5_F64, 2, d, buf, "m",
                             "OPD screen of this atmospheric layer at frame 0 on its periodic grid (row = y)");
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "altitude_m", wt_atmosphere_layer_altitude(atm, l));
            if (st >= 0) st = wt_h5_attr_write_double(w, name, "spacing_m", g.dx);
            if (st < 0) {
                free(buf);
                return st;
            }
        }
        free(buf);
        const wt_grid *f = wt_loop_fine_grid(lp);
        const uint8_t *mask = wt_loop_pupil_mask(lp);
        int64_t np = wt_grid_size(f);
        float *res = malloc((size_t)nd * np * sizeof *res);
        if (!res) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory dumping residuals");
        for (int j = 0; j < nd; j++) {
            const double *r = wt_loop_residual(lp, j);
            double mean = 0.0;
            int64_t c = 0;
            for (int64_t i = 0; i < np; i++)
                if (mask[i]) mean += r[i], c++;
            mean = c ? mean / c : 0.0;
            for (int64_t i = 0; i < np; i++) res[(size_t)j * np + i] = mask[i] ? (float)(r[i] - mean) : NAN;
        }
        int64_t d[3] = {nd, f->ny, f->nx};
        st = wt_h5_write(w, "residual", WT_H5_F32, WT_H5_F32, 3, d, res, "m",
                         "piston-removed residual OPD of the last frame per evaluation direction on the fine "
                         "pupil grid (row = y; NaN outside the pupil)");
        if (st >= 0) st = wt_h5_attr_write_double(w, "residual", "spacing_m", f->dx);
        free(res);
        if (st < 0) return st;
    }
    return WT_OK;
}

typedef struct {
    const char *recon, *out, *tel, *seed, *matrix;
    long frames, iters;
    int dump, nonoise;
} sim_args;

static int sim_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    sim_args *a = user;
    const char *o = argv[*i];
    const char **str = !strcmp(o, "--recon") ? &a->recon
                       : !strcmp(o, "--out")      ? &a->out
                       : !strcmp(o, "--telemetry") ? &a->tel
                       : !strcmp(o, "--seed")     ? &a->seed
                       : !strcmp(o, "--matrix")   ? &a->matrix
                                                  : NULL;
    if (!strcmp(o, "--no-noise")) a->nonoise = 1;
    else if (!strcmp(o, "--dump-screens")) a->dump = 1;
    else if (str) {
        if (!(*str = wt_cli_value(cli, argc, argv, i))) return -1;
    } else if (!strcmp(o, "--frames") || !strcmp(o, "--iters")) {
        const char *v = wt_cli_value(cli, argc, argv, i);
        if (!v || wt_cli_int(cli, o, v, o[2] == 'f' ? 1 : 0, 10000000, o[2] == 'f' ? &a->frames : &a->iters) < 0)
            return -1;
    } else
        return 0;
    return 1;
}

int wt_cmd_sim(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo sim", help)) return 1;
    sim_args args = {"pcg3", NULL, NULL, NULL, NULL, -1, -1, 0, 0};
    int rc = wt_cli_parse(&cli, argc, argv, sim_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    const char *recon = args.recon, *out = args.out, *tel = args.tel, *seed_opt = args.seed;
    int iters = (int)args.iters, dump = args.dump, nonoise = args.nonoise;
    long frames_opt = args.frames;
    int kind = wt_reconstructor_kind(recon);
    if (kind < 0) {
        rc = wt_cli_usage_error(&cli, "--recon expects pcg3, cg9, none or mvm, got '%s'", recon);
        goto done;
    }
    if ((kind == WT_RECON_MVM) != (args.matrix != NULL)) {
        rc = wt_cli_usage_error(&cli, kind == WT_RECON_MVM ? "--recon mvm needs --matrix MATRIX.h5"
                                                           : "--matrix is only for --recon mvm");
        goto done;
    }
    if (!out) {
        rc = wt_cli_usage_error(&cli, "--out RUN.h5 is required");
        goto done;
    }
    if (!cli.config_path) {
        rc = wt_cli_usage_error(&cli, "--config FILE is required");
        goto done;
    }
    if ((rc = wt_cli_run_overrides(&cli, frames_opt, seed_opt)) != 0) goto done;
    if (nonoise) cli.set[cli.nset++] = "sim.noise=false";

    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_loop *lp = NULL;
    wt_mvm *mvm = NULL;
    wt_h5_writer *w = NULL, *tw = NULL;
    telemetry T = {0};
    double *se_field = NULL, *se_axis = NULL;
    float *rms_nm = NULL, *fbuf = NULL;
    int st = wt_cli_read_config(&cli, NULL, &cfg);
    if (st < 0) goto fail;
    if ((rc = wt_cli_estimate(&cli, cfg, WT_TASK_SIM, kind)) >= 0) goto cleanup; /* --dry-run, or too big */
    rc = 0;
    /* find an unwritable output before the run, not after it */
    if ((st = wt_cli_check_output(&cli, out, 0, args.matrix, NULL)) < 0) goto fail;
    if ((st = wt_system_alloc(cli.ctx, cfg, &sys)) < 0) goto fail;
    long frames = cfg->frames;
    if (tel) {
        int64_t bytes = (int64_t)frames * (2 * sys->nslopes + sys->nact) * 4;
        if ((st = wt_cli_check_output(&cli, tel, bytes, args.matrix, NULL)) < 0) goto fail;
    }
    if (kind == WT_RECON_MVM && (st = wt_mvm_read(cli.ctx, args.matrix, cfg, sys->nact, sys->nslopes, &mvm, NULL)) < 0) goto fail;
    wt_loop_options o = {.recon = kind, .mvm = mvm, .iterations = iters, .seed = cfg->seed, .noise = cfg->noise};
    double t0 = wt_time_now();
    if ((st = wt_loop_alloc(cli.ctx, sys, &o, &lp)) < 0) goto fail;
    double setup = wt_time_now() - t0;
    se_field = calloc((size_t)frames, sizeof *se_field);
    se_axis = calloc((size_t)frames, sizeof *se_axis);
    rms_nm = calloc((size_t)frames * sys->neval, sizeof *rms_nm);
    fbuf = malloc((size_t)(sys->nslopes > sys->nact ? sys->nslopes : sys->nact) * sizeof *fbuf);
    if (!se_field || !se_axis || !rms_nm || !fbuf) {
        st = WT_ERROR(cli.ctx, WT_ERR_NOMEM, "out of memory for the per-frame results");
        goto fail;
    }
    if (tel) {
        if ((st = wt_h5_create(cli.ctx, tel, &tw)) < 0) goto fail;
        if ((st = wt_h5_series_create(tw, "slopes", WT_H5_F32, sys->nslopes, "rad",
                                      "measured slopes s_t per frame (OPD gradient), ordering in layout/", &T.slopes)) < 0)
            goto fail;
        if ((st = wt_h5_series_create(tw, "slopes_ol", WT_H5_F32, sys->nslopes, "rad",
                                      "pseudo-open-loop slopes s_t + A^ a_t per frame", &T.slopes_ol)) < 0)
            goto fail;
        if ((st = wt_h5_series_create(tw, "commands", WT_H5_F32, sys->nact, "m",
                                      "DM commands a_t applied during the frame (actuator OPD), ordering in "
                                      "layout/actuator_index",
                                      &T.commands)) < 0)
            goto fail;
    }
    if (!cli.quiet)
        fprintf(stderr, "wavetomo sim: %s, %s, %ld frames, seed %llu, %lld slopes, %lld actuators (set-up %.1f s)\n",
                cfg->path, recon, frames, (unsigned long long)cfg->seed, (long long)sys->nslopes,
                (long long)sys->nact, setup);
    wt_progress pr;
    wt_progress_start(&pr, "frames", "frames", frames);
    double run0 = wt_time_now(), sum_field = 0.0;
    for (long t = 0; t < frames; t++) {
        if ((st = wt_loop_step(lp)) < 0) goto fail;
        const double *rms = wt_loop_rms(lp);
        se_field[t] = wt_loop_field_strehl(lp);
        se_axis[t] = wt_strehl_marechal(rms[sys->eval_centre], cfg->eval_wavelength);
        for (int j = 0; j < sys->neval; j++) rms_nm[(size_t)t * sys->neval + j] = (float)(rms[j] * 1e9);
        sum_field += se_field[t];
        if (tel) {
            const double *src[3] = {wt_loop_slopes(lp), wt_loop_slopes_ol(lp), wt_loop_applied(lp)};
            wt_h5_series *dst[3] = {T.slopes, T.slopes_ol, T.commands};
            for (int k = 0; k < 3; k++) {
                int64_t n = k < 2 ? sys->nslopes : sys->nact;
                for (int64_t i = 0; i < n; i++) fbuf[i] = (float)src[k][i];
                if ((st = wt_h5_series_append(dst[k], WT_H5_F32, fbuf)) < 0) goto fail;
            }
        }
        char extra[64];
        snprintf(extra, sizeof extra, "field SE Strehl %.3f (mean %.3f)", se_field[t], sum_field / (t + 1));
        wt_progress_update(&pr, t + 1, extra);
    }
    wt_progress_end(&pr);
    double run = wt_time_now() - run0;

    if ((st = wt_h5_create(cli.ctx, out, &w)) < 0) goto fail;
    if ((st = write_results(&cli, w, cfg, sys, lp, recon, frames, se_field, se_axis, rms_nm, dump, argc, argv)) < 0)
        goto fail;
    if ((st = wt_h5_write_double(w, "timing/total", run / frames * 1e3, "ms", "mean wall time per frame")) < 0) goto fail;
    if ((st = wt_h5_write_double(w, "timing/setup", setup, "s", "set-up time (atmosphere, operators)")) < 0) goto fail;
    if (tw) {
        if ((st = wt_cli_write_provenance(&cli, tw, cfg, argc, argv)) < 0) goto fail;
        if ((st = wt_h5_attr_write_string(tw, "/", "recon", recon)) < 0) goto fail;
        if ((st = wt_cli_write_layout(tw, sys)) < 0) goto fail;
        st = wt_h5_commit(tw);
        tw = NULL;
        if (st < 0) goto fail;
    }
    st = wt_h5_commit(w);
    w = NULL;
    if (st < 0) goto fail;

    const wt_strehl_le *le = wt_loop_le(lp);
    double field = 0.0, fwfe = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        field += wt_strehl_le_strehl(le, j) / sys->neval;
        fwfe += pow(wt_strehl_le_wfe(le, j), 2) / sys->neval;
    }
    wt_loop_times tm = wt_loop_get_times(lp);
    printf("%s: %ld frames (%ld averaged) at %.0f nm\n", recon, frames, le->frames, cfg->eval_wavelength * 1e9);
    printf("  LE Strehl on-axis %.4f   field average %.4f\n", wt_strehl_le_strehl(le, sys->eval_centre), field);
    printf("  residual WFE on-axis %.1f nm   field rms %.1f nm\n", wt_strehl_le_wfe(le, sys->eval_centre) * 1e9,
           sqrt(fwfe) * 1e9);
    printf("  time per frame %.2f ms (%.2f frames/s): atmosphere %.2f, sensors %.2f, reconstruction %.2f, "
           "fitting %.2f, control %.2f, evaluation %.2f ms; set-up %.2f s\n",
           run / frames * 1e3, frames / run, tm.atmosphere / frames * 1e3, tm.sensors / frames * 1e3,
           tm.reconstruction / frames * 1e3, tm.fitting / frames * 1e3, tm.control / frames * 1e3,
           tm.evaluation / frames * 1e3, setup);
    printf("  results: %s%s%s\n", out, tel ? ", telemetry: " : "", tel ? tel : "");
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_h5_abort(w);
    wt_h5_abort(tw);
    free(se_field);
    free(se_axis);
    free(rms_nm);
    free(fbuf);
    wt_loop_free(lp);
    wt_mvm_free(mvm);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
done:
    wt_cli_done(&cli);
    return rc;
}
