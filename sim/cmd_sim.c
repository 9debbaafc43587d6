/* sim/cmd_sim.c: `wavetomo sim`: the closed-loop end-to-end simulation of one reconstructor
 * (sim/loop), with its result file, optional telemetry and screen dumps (sim/record). */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sim/cmd_sim.h"
#include "cli/cli.h"
#include "builder/mvm_build.h"
#include "core/io/h5.h"
#include "core/solve/mvm.h"
#include "sim/loop.h"
#include "sim/focus_stage.h"
#include "core/model/estimate.h"
#include "core/model/params.h"
#include "sim/record.h"
#include "sim/psf.h"
#include "core/model/sensing.h"
#include "core/base/sha256.h"

static void help(void)
{
    printf("usage: wavetomo sim [--config] FILE [--set key=value]... [--recon pcg3|cg9|none|mvm]\n"
           "                    [--matrix MATRIX.h5]\n"
           "                    [--frames N] [--seed S] [--iters N] [--no-noise] --out RUN.h5\n"
           "                    [--telemetry TEL.h5] [--fits DIR] [--dump-screens] [--threads N] [--quiet]\n"
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
           "                   the long-exposure PSFs and their peak Strehl (sim.psf_interval_frames),\n"
           "                   the configuration, seed and versions (docs/formats.md)\n"
           "  --telemetry F    also write per frame the measured and pseudo-open-loop slopes and the\n"
           "                   applied commands (float32), for `wavetomo run`; with\n"
           "                   sim.telemetry_maps_interval_frames = N also every N-th frame's residual OPD maps\n"
           "  --fits DIR       also write the long-exposure PSFs as FITS, one file DIR/psf_<nm>nm.fits per\n"
           "                   wavelength of sim.psf_wavelengths_nm (or evaluation.wavelength_nm): the PSF cube\n"
           "                   (x, y, direction), the Strehl map and the directions' table (DIR is created)\n"
           "  --dump-screens   add the layer screens of frame 0 and the residual OPD maps of the last\n"
           "                   frame to RUN.h5\n"
           "  --dry-run        print the estimated peak memory and run time and the keys that drive them; stop\n"
           "  --max-memory S   refuse up front when the estimate exceeds S bytes (4G, 512M; default MemAvailable)\n"
           "A progress line (frames, frames/s, ETA, running field-average Strehl) goes to stderr on a terminal.\n"
           "Ctrl-C (SIGINT, SIGTERM, SIGHUP) during the loop finishes the frame in hand, writes RUN.h5 (and TEL.h5)\n"
           "with the frames done, marked by the root attributes 'interrupted' and 'frames_requested', then exits\n"
           "with 128 + the signal number; during the set-up, or a second signal, ends it at once (no file written).\n");
}

typedef struct {
    const char *recon, *out, *tel, *seed, *matrix, *fits;
    long frames, iters;
    int dump, nonoise;
} sim_args;

/* The diffractive LGS centroiders' in-loop gain (core/model/sensing.h) over the averaged frames: mean over
 * the LGS, printed, and per sensor in the result file. */
static int inloop_gain(wt_h5_writer *w, const wt_system *sys, int print)
{
    double g[2][WT_MAX_GS], e[2][WT_MAX_GS], mean[2] = {0, 0};
    int n = 0, st = WT_OK, fitted = 0;
    long frames = 0;
    for (int i = 0; i < sys->nsensors; i++) {
        const wt_sensor *s = &sys->sensors[i];
        if (!s->diffr || s->kind != WT_SENSOR_LGS || n >= WT_MAX_GS) continue;
        wt_sensing_gain_in_loop(s->diffr, &g[0][n], &g[1][n], &frames);
        e[0][n] = s->diffr->gain_est[0], e[1][n] = s->diffr->gain_est[1], fitted |= s->diffr->gain_fits > 0;
        mean[0] += g[0][n], mean[1] += g[1][n], n++;
    }
    if (!n || frames < 1) return WT_OK;
    if (w) {
        const int64_t dim = n;
        if ((st = wt_h5_write(w, "sensing/lgs_inloop_gain_along", WT_H5_F64, WT_H5_F64, 1, &dim, g[0], "",
                              "per LGS: least-squares slope of the measured slopes on the true ones (the average "
                              "gradient of the sampled OPD) along the elongation, over the averaged frames; 1 for a "
                              "centroider whose reference is the spot it sees")) < 0 ||
            (st = wt_h5_write(w, "sensing/lgs_inloop_gain_across", WT_H5_F64, WT_H5_F64, 1, &dim, g[1], "",
                              "per LGS: the same across the elongation")) < 0)
            return st;
        if (fitted &&
            ((st = wt_h5_write(w, "sensing/lgs_gain_estimate_along", WT_H5_F64, WT_H5_F64, 1, &dim, e[0], "",
                               "lgs.wfs.gain_update_s: per LGS, the last estimate of the matched filter's gain from the "
                               "loop's pixels (the spot model fitted to the period's mean image), along the "
                               "elongation, mean of the subapertures, before its correction; the slopes were divided "
                               "by it from then on")) < 0 ||
             (st = wt_h5_write(w, "sensing/lgs_gain_estimate_across", WT_H5_F64, WT_H5_F64, 1, &dim, e[1], "",
                               "per LGS: the same across the elongation")) < 0))
            return st;
    }
    if (print)
        printf("  LGS centroider in-loop gain (measured / true slope, %ld frames, mean of %d LGS): along the "
               "elongation %.3f, across %.3f\n", frames, n, mean[0] / n, mean[1] / n);
    return st;
}

/* The LGS focus stage (sim/focus_stage.h): the sodium altitude change it compensates and the centring, written
 * (w) or printed (w NULL) */
static int focus_stage(wt_h5_writer *w, const wt_focus_stage *fs)
{
    if (!fs) return WT_OK;
    const wt_focus_stage_stats s = wt_focus_stage_get_stats(fs);
    if (!w) {
        printf("  LGS focus stage: follows a sodium altitude change of %.0f m (last frame), %.0f m on average over %ld "
               "frames; tip-tilt centring %.3f arcsec rms\n", s.dh_now, s.dh_mean, s.frames_averaged,
               s.tilt_rms / WT_ARCSEC);
        return WT_OK;
    }
    int st = wt_h5_write_double(w, "sensing/lgs_focus_stage_dh_m", s.dh_mean, "m",
                                "lgs.wfs.focus_stage: the LGS focus stage's position as the sodium centroid's altitude "
                                "change it compensates, 2 H^2 c, averaged over the averaged frames");
    if (st >= 0)
        st = wt_h5_write_double(w, "sensing/lgs_focus_stage_tilt_rms", s.tilt_rms, "rad",
                                "lgs.wfs.focus_stage: rms over the LGS and the averaged frames of the tip-tilt "
                                "centring's offset");
    return st;
}

/* --fits DIR: PSFs to export, DIR made, and each file's name free (or a FITS file to replace) before the run */
static int check_fits(wt_cli *cli, const char *dir, const wt_config *cfg)
{
    if (cfg->psf_interval < 1)
        return WT_ERROR(cli->ctx, WT_ERR_CONFIG, "--fits %s: no PSFs to export with sim.psf_interval_frames = 0 (%s)", dir,
                        cfg->path);
    int st = wt_cli_ensure_dir(cli->ctx, dir);
    const int nw = cfg->npsf_wavelengths ? cfg->npsf_wavelengths : 1;
    for (int k = 0; k < nw && st >= 0; k++) {
        char name[64], path[4200];
        wt_fits_psf_name(cfg->npsf_wavelengths ? cfg->psf_wavelength[k] : cfg->eval_wavelength, name, sizeof name);
        snprintf(path, sizeof path, "%s/%s", dir, name);
        st = wt_cli_check_text_output(cli, path, "SIMPLE  =", NULL);
    }
    return st;
}

/* One FITS file of --fits: p's images with the run's directions, WFE and provenance. */
static int write_fits(const char *dir, const wt_psf *p, const wt_config *cfg, const wt_system *sys,
                      const wt_loop *lp, const char *recon)
{
    char name[64], path[4200], hash[65], telescope[80], creator[64];
    double wfe[WT_MAX_EVAL];
    const wt_strehl_le *le = wt_loop_le(lp);
    for (int j = 0; j < sys->neval; j++) wfe[j] = wt_strehl_le_wfe(le, j);
    wt_fits_psf_name(wt_psf_wavelength(p), name, sizeof name);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    wt_sha256_hex(cfg->canonical, strlen(cfg->canonical), hash);
    const char *base = strrchr(cfg->path, '/');
    snprintf(telescope, sizeof telescope, "simulated D = %.4g m (%.36s)", cfg->diameter, base ? base + 1 : cfg->path);
    snprintf(creator, sizeof creator, "wavetomo %s", WT_VERSION);
    const wt_fits_psf meta = {.wfe = wfe, .theta_x = sys->eval_x, .theta_y = sys->eval_y, .grid = cfg->eval_grid,
                              .spacing = cfg->eval_spacing, .obstruction = cfg->obstruction, .telescope = telescope,
                              .recon = recon, .seed = cfg->seed, .config_sha256 = hash, .creator = creator};
    return wt_psf_write_fits(p, path, &meta);
}

static const char *signal_name(int sig)
{
    return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : sig == SIGHUP ? "SIGHUP" : "a signal";
}

/* A run stopped by a signal: the root attributes saying so (the datasets hold the frames done). */
static int mark_stopped(wt_h5_writer *w, int sig, long done, long frames, long averaged)
{
    char why[256];
    snprintf(why, sizeof why, "stopped early by %s after %ld of %ld frames; long-exposure figures over the %ld frames "
             "after the settle window", signal_name(sig), done, frames, averaged);
    int st = wt_h5_attr_write_string(w, "/", "interrupted", why);
    if (st >= 0) st = wt_h5_attr_write_int64(w, "/", "frames_requested", frames);
    return st;
}

static int sim_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    sim_args *a = user;
    const char *o = argv[*i];
    const char **str = !strcmp(o, "--recon") ? &a->recon
                       : !strcmp(o, "--out")      ? &a->out
                       : !strcmp(o, "--telemetry") ? &a->tel
                       : !strcmp(o, "--seed")     ? &a->seed
                       : !strcmp(o, "--matrix")   ? &a->matrix
                       : !strcmp(o, "--fits")     ? &a->fits
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

/* A learning loop's updates: every estimate's r0 and ground-layer fraction, and what the learning cost. */
static void print_learned(const wt_adapt *a, long frames, double learning)
{
    if (!a) return;
    const int n = wt_adapt_nupdates(a);
    const wt_adapt_update *u = wt_adapt_updates(a);
    char wind[64] = "";
    if (wt_adapt_wind_seconds(a) > 0.0)
        snprintf(wind, sizeof wind, ", of which the layers' wind %.2f ms", wt_adapt_wind_seconds(a) / frames * 1e3);
    if (wt_adapt_follows_truth(a))
        printf("  the oracle follows the night: %d updates to the truth's state; %.2f ms per frame\n", n,
               learning / frames * 1e3);
    else
        printf("  learned atmosphere: %d estimates; learning %.2f ms per frame (accumulation %.2f ms%s); the grid's "
               "response maps %.2f s at set-up\n", n, learning / frames * 1e3, wt_adapt_accumulate_seconds(a) / frames * 1e3,
               wind, wt_adapt_model_setup_seconds(a));
    for (int k = 0; k < n; k++) {
        double low = 0.0; /* the Cn2 below 1 km */
        for (int j = 0; j < u[k].nalt; j++)
            if (u[k].altitude[j] < 1000.0) low += u[k].fraction[j];
        printf("    after frame %6ld (night %8.2f s): r0 %.4f +- %.4f m, below 1 km %.3f; fit %.2f s", u[k].frame,
               u[k].night, u[k].r0, u[k].r0_sigma, low, u[k].fit_s);
        if (u[k].build_s > 0.0) printf(", MVM build %.1f s", u[k].build_s);
        else if (u[k].applied_frame >= 0) printf(", new model %.3f s + preconditioner %.3f s", u[k].model_s, u[k].precond_s);
        if (u[k].applied_frame >= 0) printf(", in use from frame %ld\n", u[k].applied_frame);
        else printf(", never in use\n");
        if (u[k].nwind > 0) { /* learn_wind: each layer's wind, speed and direction (* kept: no clear estimate) */
            printf("      layers' wind [m/s, deg]:");
            for (int l = 0; l < u[k].nwind; l++)
                printf(" %.2f@%.0f%s%s", hypot(u[k].wind_vx[l], u[k].wind_vy[l]),
                       atan2(u[k].wind_vy[l], u[k].wind_vx[l]) * 180.0 / M_PI, u[k].wind_valid[l] ? "" : "*",
                       l + 1 < u[k].nwind ? "," : "\n");
        }
    }
}

int wt_cmd_sim(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo sim", help)) return 1;
    sim_args args = {"pcg3", NULL, NULL, NULL, NULL, NULL, -1, -1, 0, 0};
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
        rc = wt_cli_usage_error(&cli, "a configuration is required: FILE or --config FILE");
        goto done;
    }
    if ((rc = wt_cli_run_overrides(&cli, frames_opt, seed_opt)) != 0) goto done;
    if (nonoise) cli.set[cli.nset++] = "sim.noise=false";

    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_loop *lp = NULL;
    wt_mvm *mvm = NULL;
    wt_h5_writer *w = NULL, *tw = NULL;
    wt_sim_record *rec = NULL;
    wt_psf *psf = NULL, *band[WT_MAX_PSF_WAVELENGTHS] = {NULL};
    double tpsf = 0.0;
    int nband = 0;
    int st = wt_cli_read_config(&cli, NULL, &cfg);
    if (st < 0) goto fail;
    if ((rc = wt_cli_estimate(&cli, cfg, WT_TASK_SIM, kind, iters)) >= 0) goto cleanup; /* --dry-run, or too big */
    rc = 0;
    /* find an unwritable output before the run, not after it */
    if ((st = wt_cli_check_output(&cli, out, 0, args.matrix, NULL)) < 0) goto fail;
    if (args.fits && (st = check_fits(&cli, args.fits, cfg)) < 0) goto fail;
    if ((st = wt_system_alloc(cli.ctx, cfg, &sys)) < 0) goto fail;
    long frames = cfg->frames;
    if (tel) {
        int64_t bytes = (int64_t)frames * (2 * sys->nslopes + sys->nact) * 4;
        if (cfg->telemetry_maps > 0) { /* the maps on the loop's fine grid, (n p + 1)² points per direction */
            const int64_t side = (int64_t)sys->n * cfg->points_per_subaperture + 1;
            bytes += (frames + cfg->telemetry_maps - 1) / cfg->telemetry_maps * (sys->neval * side * side + sys->nact) * 4;
        }
        if ((st = wt_cli_check_output(&cli, tel, bytes, args.matrix, NULL)) < 0) goto fail;
    }
    /* (what the MVM cannot do under recon.predict, before the matrix is read: the loop refuses it too) */
    if ((st = wt_reconstructor_check_mvm_predict(cli.ctx, cfg, kind, 0)) < 0) goto fail;
    if (kind == WT_RECON_MVM && (st = wt_mvm_read(cli.ctx, args.matrix, cfg, sys->nact, sys->nslopes, &mvm, NULL)) < 0) goto fail;
    wt_loop_options o = {.recon = kind, .mvm = mvm, .iterations = iters, .seed = cfg->seed, .noise = cfg->noise};
    /* a learning MVM loop rebuilds its matrix (the variant it was built for) from each estimate */
    wt_mvm_rebuilder rb = {cli.ctx, sys, mvm && mvm->commands == WT_MVM_FITTING ? "cg9" : "pcg3", NULL};
    if (mvm) o.rebuild = wt_mvm_rebuild_model, o.rebuild_user = &rb; /* (used when it learns or follows a night) */
    double t0 = wt_time_now();
    if ((st = wt_loop_alloc(cli.ctx, sys, &o, &lp)) < 0) goto fail;
    wt_psf_params pp;
    wt_psf_params_from_config(cfg, &pp);
    if (pp.every > 0 &&
        (st = wt_psf_alloc(cli.ctx, wt_loop_fine_grid(lp), wt_loop_pupil_mask(lp), sys->neval, &pp, &psf)) < 0)
        goto fail;
    /* the bands of sim.psf_wavelengths_nm: the same images at each wavelength (psf.h); the evaluation wavelength's
     * band is psf itself (the same images, made once) */
    for (; pp.every > 0 && nband < cfg->npsf_wavelengths; nband++) {
        wt_psf_params pb = pp;
        pb.wavelength = cfg->psf_wavelength[nband];
        if (pb.wavelength == pp.wavelength) band[nband] = psf;
        else if ((st = wt_psf_alloc(cli.ctx, wt_loop_fine_grid(lp), wt_loop_pupil_mask(lp), sys->neval, &pb,
                                    &band[nband])) < 0)
            goto fail;
    }
    double setup = wt_time_now() - t0;
    if (tel && (st = wt_h5_create(cli.ctx, tel, &tw)) < 0) goto fail;
    if ((st = wt_sim_record_alloc(cli.ctx, sys, frames, cfg->eval_wavelength, tw, &rec)) < 0) goto fail;
    if (tw && cfg->telemetry_maps > 0 && (st = wt_sim_record_maps(rec, lp, tw, cfg->telemetry_maps)) < 0) goto fail;
    if (!tw && cfg->telemetry_maps > 0 && !cli.quiet)
        fprintf(stderr, "wavetomo sim: note: sim.telemetry_maps_interval_frames = %d records into --telemetry TEL.h5, "
                "which is not given: no maps\n", cfg->telemetry_maps);
    /* From here a first SIGINT/SIGTERM/SIGHUP only raises the deferral flag (core/io/h5_temp.c: a
     * sig_atomic_t, the one mutable global a handler needs); the loop finishes the frame in hand and the files
     * are written with the frames done (compare's mechanism). Before this point (set-up) a signal ends the
     * process and unlinks the temporaries: nothing is done yet. A second signal acts at once. */
    wt_interrupt_defer(1);
    if (!cli.quiet)
        fprintf(stderr, "wavetomo sim: %s, %s, %ld frames, seed %llu, %lld slopes, %lld actuators (set-up %.1f s)\n",
                cfg->path, recon, frames, (unsigned long long)cfg->seed, (long long)sys->nslopes,
                (long long)sys->nact, setup);
    wt_progress pr;
    wt_progress_start(&pr, "frames", "frames", frames);
    if (cli.quiet) pr.enabled = 0;
    double run0 = wt_time_now(), sum_field = 0.0;
    long done = frames; /* frames simulated: fewer when a signal stopped the loop */
    int sig = 0;
    for (long t = 0; t < frames; t++) {
        const double f0 = wt_time_now();
        if ((st = wt_loop_step(lp)) < 0 || (st = wt_sim_record_frame(rec, lp, wt_time_now() - f0)) < 0) goto fail;
        if (psf) { /* the long-exposure PSFs (sim.psf_interval_frames): timed apart from the loop's parts */
            const double p0 = wt_time_now();
            const double *maps[WT_MAX_EVAL];
            for (int j = 0; j < sys->neval; j++) maps[j] = wt_loop_residual(lp, j);
            wt_psf_frame(psf, t, maps);
            for (int k = 0; k < nband; k++)
                if (band[k] != psf) wt_psf_frame(band[k], t, maps);
            tpsf += wt_time_now() - p0;
        }
        double se = wt_sim_record_field_strehl(rec, t);
        sum_field += se;
        char extra[64];
        snprintf(extra, sizeof extra, "Strehl %.3f this frame, %.3f so far (field average)", se, sum_field / (t + 1));
        wt_progress_update(&pr, t + 1, extra);
        if ((sig = wt_interrupt_pending())) {
            done = t + 1;
            break;
        }
    }
    wt_progress_end(&pr);
    double run = wt_time_now() - run0;

    if ((st = wt_h5_create(cli.ctx, out, &w)) < 0) goto fail;
    if ((st = wt_cli_write_provenance(&cli, w, cfg, argc, argv)) < 0) goto fail;
    if ((st = wt_h5_attr_write_string(w, "/", "recon", recon)) < 0) goto fail;
    if (done < frames && (st = mark_stopped(w, sig, done, frames, wt_loop_le(lp)->frames)) < 0) goto fail;
    if ((st = wt_sim_record_write(rec, w, lp, cfg->settle_frames)) < 0) goto fail;
    if ((st = wt_cli_write_layout(w, sys)) < 0) goto fail;
    if ((st = inloop_gain(w, sys, 0)) < 0) goto fail;
    if ((st = focus_stage(w, wt_loop_focus_stage(lp))) < 0) goto fail;
    if (dump && (st = wt_sim_write_dump(cli.ctx, w, lp, sys->neval)) < 0) goto fail;
    if (psf && ((st = wt_psf_write(psf, w, "psf")) < 0 ||
                (st = wt_h5_write_double(w, "timing/psf", tpsf / done * 1e3, "ms",
                                         "mean wall time per frame of the long-exposure PSFs (sim.psf_interval_frames; included "
                                         "in timing/total, in no part of frame/time)")) < 0))
        goto fail;
    if (nband && (st = wt_psf_write_bands((const wt_psf *const *)band, nband, w, "psf/wavelengths")) < 0) goto fail;
    if ((st = wt_h5_write_double(w, "timing/total", run / done * 1e3, "ms", "mean wall time per frame")) < 0) goto fail;
    if ((st = wt_h5_write_double(w, "timing/setup", setup, "s", "set-up time (atmosphere, operators)")) < 0) goto fail;
    if (tw) {
        if ((st = wt_cli_write_provenance(&cli, tw, cfg, argc, argv)) < 0) goto fail;
        if ((st = wt_h5_attr_write_string(tw, "/", "recon", recon)) < 0) goto fail;
        if (done < frames && (st = mark_stopped(tw, sig, done, frames, wt_loop_le(lp)->frames)) < 0) goto fail;
        if ((st = wt_cli_write_layout(tw, sys)) < 0) goto fail;
        st = wt_h5_commit(tw);
        tw = NULL;
        if (st < 0) goto fail;
    }
    st = wt_h5_commit(w);
    w = NULL;
    if (st < 0) goto fail;
    if (args.fits) {
        if (nband)
            for (int k = 0; k < nband && st >= 0; k++) st = write_fits(args.fits, band[k], cfg, sys, lp, recon);
        else
            st = write_fits(args.fits, psf, cfg, sys, lp, recon);
        if (st < 0) goto fail;
    }

    const wt_strehl_le *le = wt_loop_le(lp);
    double field = 0.0, fwfe = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        field += wt_strehl_le_strehl(le, j) / sys->neval;
        fwfe += pow(wt_strehl_le_wfe(le, j), 2) / sys->neval;
    }
    wt_loop_times tm = wt_loop_get_times(lp);
    printf("%s: %ld frames (%ld averaged) at %.0f nm\n", recon, done, le->frames, cfg->eval_wavelength * 1e9);
    printf("  LE Strehl (Marechal) on-axis %.4f   field average %.4f\n", wt_strehl_le_strehl(le, sys->eval_centre), field);
    if (psf) {
        double pf = 0.0;
        for (int j = 0; j < sys->neval; j++) pf += wt_psf_strehl(psf, j) / sys->neval;
        printf("  PSF-peak Strehl on-axis %.4f   field average %.4f (long-exposure PSF of %ld frames, one in %d; "
               "LE Strehl above: Marechal)\n", wt_psf_strehl(psf, sys->eval_centre), pf, wt_psf_frames(psf), cfg->psf_interval);
    }
    printf("  residual WFE on-axis %.1f nm   field rms %.1f nm\n", wt_strehl_le_wfe(le, sys->eval_centre) * 1e9,
           sqrt(fwfe) * 1e9);
    printf("  time per frame %.2f ms (%.2f frames/s): atmosphere %.2f, sensors %.2f, reconstruction %.2f, "
           "fitting %.2f, control %.2f, evaluation %.2f ms; set-up %.2f s\n",
           run / done * 1e3, done / run, tm.atmosphere / done * 1e3, tm.sensors / done * 1e3,
           tm.reconstruction / done * 1e3, tm.fitting / done * 1e3, tm.control / done * 1e3,
           tm.evaluation / done * 1e3, setup);
    inloop_gain(NULL, sys, 1);
    focus_stage(NULL, wt_loop_focus_stage(lp));
    if (wt_loop_sodium(lp)) {
        const wt_sodium_drive_stats ds = wt_sodium_drive_get_stats(wt_loop_sodium(lp));
        printf("  sodium: truth's LGS spot tables rebuilt %ld times (%.3f s each); LGS reference %s, rebuilt %ld times "
               "(%.3f s each, of which C_E and preconditioner %.3f s)\n",
               ds.truth_rebuilds, ds.truth_rebuilds ? ds.truth_seconds / ds.truth_rebuilds : 0.0,
               cfg->lgs_reference == 2 ? "pixels" : cfg->lgs_reference == 1 ? "oracle" : "static", ds.reference_rebuilds,
               ds.reference_rebuilds ? ds.reference_seconds / ds.reference_rebuilds : 0.0,
               ds.reference_rebuilds ? ds.c_e_seconds / ds.reference_rebuilds : 0.0);
        if (cfg->lgs_reference == 2)
            printf("  pixels: re-centred images accumulated %.2f ms per frame (sensors above: %.2f ms per frame, "
                   "accumulation included)\n", ds.accumulate_seconds / done * 1e3, tm.sensors / done * 1e3);
        if (ds.gain_updates > 0)
            printf("  matched filter's gain from the pixels: measured %ld times (%.3f s each with C_E), the last %.3f "
                   "along / %.3f across the elongation (mean of the LGS), corrected from then on; images accumulated "
                   "%.2f ms per frame\n",
                   ds.gain_updates, ds.gain_seconds / ds.gain_updates, ds.gain_along, ds.gain_across,
                   ds.gain_accumulate_seconds / done * 1e3);
    }
    print_learned(wt_loop_adapt(lp), done, tm.learning);
    if (psf) printf("  PSF images %.2f ms per frame (in the time per frame above)\n", tpsf / done * 1e3);
    printf("  results: %s%s%s%s%s\n", out, tel ? ", telemetry: " : "", tel ? tel : "", args.fits ? ", FITS PSFs in " : "",
           args.fits ? args.fits : "");
    if (!sig) sig = wt_interrupt_pending(); /* a signal while the files were written: they are complete */
    if (sig) { /* after the files: the one line a script or a log needs, and the status that tells it apart */
        if (done < frames)
            fprintf(stderr, "wavetomo sim: stopped by %s after %ld of %ld frames: %s has them (attribute 'interrupted')\n",
                    signal_name(sig), done, frames, out);
        else
            fprintf(stderr, "wavetomo sim: %s after the last frame: %s is complete\n", signal_name(sig), out);
        rc = 128 + sig;
    }
    goto cleanup;
fail:
    rc = wt_cli_fail(&cli, st);
cleanup:
    wt_interrupt_defer(0);
    wt_sim_record_free(rec);
    wt_psf_free(psf);
    for (int k = 0; k < nband; k++)
        if (band[k] != psf) wt_psf_free(band[k]);
    wt_h5_abort(w);
    wt_h5_abort(tw);
    wt_loop_free(lp);
    wt_mvm_free(mvm);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
done:
    wt_cli_done(&cli);
    return rc;
}
