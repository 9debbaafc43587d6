/* compare/cmd_bench.c: `wavetomo bench`: reconstructor kernel timings with flop/byte counts, against the
 * machine's own limits measured in the same run (a STREAM-like triad and an OpenBLAS DGEMM). The
 * timings are compare/bench.h's; this file parses, prints and times the MVM build. */
#include <cblas.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#include <sys/resource.h>

#include "compare/cmd_compare.h"
#include "cli/cli.h"
#include "builder/mvm_build.h"
#include "core/la/half.h"
#include "core/model/learn.h"
#include "core/model/params.h"
#include "core/model/system.h"
#include "compare/bench.h"

static void help(void)
{
    printf("usage: wavetomo bench [[--config] CONFIG] [--reps N] [--loop-frames N] [--no-loop] [--no-build] [--threads N]\n"
           "                      [--sensing DCONFIG] [--sensing-only] [--sensing-frames N] [--set key=value]...\n"
           "       wavetomo bench [CONFIG] --pair-a key=value... --pair-b key=value... [--pair-recon pcg3|cg9]\n"
           "                      [--reps N] [--pair-warm N] [--threads N] [--set key=value]...\n"
           "\n"
           "Times, on CONFIG (default data/presets/eelt-mcao.cfg): one application of the normal operator M\n"
           "for pcg3 and cg9, one PCG iteration, and a whole pcg3 frame (right-hand side + the configured\n"
           "iterations), plus the cg9 fitting operator, and recon.predict's shift of the layers (core/op/shift.h) by the\n"
           "model's wind over the loop's delay with its share of the frame, and a frame of the integrator on the layers\n"
           "(recon.predict_integrator = \"layers\": its state kept as the layers' spectra, one shift's transforms).\n"
           "Reports medians and the 10th, 90th and 99th percentiles of --reps runs (default 50), the flops and bytes\n"
           "per call, and the rates they imply, next to the machine's memory bandwidth (triad) and DGEMM rate\n"
           "measured in the same run. The byte counts are operand traffic; the working sets (~10 MB for the E-ELT pcg3) live in cache, so the implied GB/s can\n"
           "exceed the DRAM triad figure. Each variant's frame is then run again with its stages timed (where a\n"
           "frame goes: inverse DWT, forward, adjoint by sensor and by layer, preconditioner, the rest), with the\n"
           "least and most busy thread's time inside each stage. Then a learned atmosphere model taken by pcg3 and\n"
           "cg9 at the next frame (priors, model error, noise weights, preconditioner; median of up to 7 updates\n"
           "between two 22-altitude profiles, and the first, which draws the model error's unit layers). Then the\n"
           "closed-loop simulation speed with pcg3\n"
           "(--loop-frames, default 20, after 3 warm-up frames; --no-loop skips it); the MVM apply (float32 GEMV of the real size, and\n"
           "the fp16 and bf16 GEMVs of recon.mvm_precision on the same matrix)\n"
           "against a STREAM copy of the same bytes; and the offline build of the pcg3 MVM with its peak\n"
           "memory (--no-build skips it; ~6 minutes at E-ELT size with the default full prior, whose normal matrix is dense).\n"
           "\n"
           "Diffractive sensing: the diffractive sensors of DCONFIG (--sensing; default CONFIG itself when\n"
           "it has any, e.g. data/presets/eelt-mcao-diffractive.cfg), LGS and NGS separately: per frame, images +\n"
           "detector noise + centroider of every sensor of the kind, median and [p10, p90] of --sensing-frames\n"
           "frames (default 7) on the --threads threads, with the parts, the sensors' set-up time and memory, and\n"
           "the flops and bytes per subaperture against the machine's DGEMM rate and triad bandwidth; next to the\n"
           "geometric sensors' time per frame of the closed loop above. Then the sodium layer in time (LGS): the\n"
           "truth's spot tables of a new profile and the oracle's reference rebuilt from them (lgs.wfs.reference). --sensing-only times only the machine\n"
           "and the sensing (--set applies to DCONFIG too).\n"
           "\n"
           "Paired mode, when --pair-a or --pair-b is given (and then only it): two configurations\n"
           "side by side in one process. A = CONFIG with the --set overrides and then the --pair-a ones (each\n"
           "key=value as for --set, repeatable), B the same with the --pair-b ones. Both reconstructors of\n"
           "--pair-recon (default cg9) are built, then apply frame after frame, alternately (A B, B A, A B, ...),\n"
           "to the same seeded slopes (temporally correlated like a loop's, warm-started): --pair-warm frames each\n"
           "first (default 3), then --reps pairs (default 50). Reported: each side's set-up time and memory, the\n"
           "median [p10, p90] and p99 of its frame time and of the frame's tomography and fitting parts, and the\n"
           "per-pair ratio B/A of each, median [p10, p90] and p99: the figure to quote, since the host's speed\n"
           "drifts between and within runs and a ratio of frames measured side by side does not; the machine's\n"
           "load average before and after; and |a_B - a_A| / |a_A| of the last frame's commands when both sides\n"
           "have one system; then where each side's tomography goes (its stages, as above, over the timed pairs).\n"
           "Example: --pair-a 'recon.cg9.fit_solver=\"cg\"' --pair-b 'recon.cg9.fit_solver=\"cholesky\"'.\n");
}

static void report(const char *what, wt_bench_stats s, double flops, double bytes)
{
    printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]  %7.2f Mflop %7.1f MB  %6.2f GFlop/s %6.2f GB/s\n", what,
           s.med * 1e3, s.p10 * 1e3, s.p90 * 1e3, s.p99 * 1e3, flops / 1e6, bytes / 1e6, flops / s.med / 1e9,
           bytes / s.med / 1e9);
}

/* Where a frame goes: per stage, its calls and wall time per frame, its share of the solve, and the least and
 * most busy thread's time inside it (their gap is one thread waiting for the other); the rest of the solve is
 * the PCG's vector work and the slopes' check */
static void report_profile(const char *what, const wt_tomography_stage *g, int frames)
{
    const double nf = frames, solve = g[WT_TOMO_STAGE_SOLVE].wall / nf;
    printf("  where %s goes (mean of %d frames, %.3f ms of solve, each stage timed; busy: the least / most busy\n"
           "  thread's time inside the stage):\n", what, frames, solve * 1e3);
    double rest = solve;
    for (int k = 0; k < WT_TOMO_NSTAGES; k++) {
        if (k == WT_TOMO_STAGE_SOLVE || g[k].calls == 0) continue;
        printf("    %-32s %4.1f calls %8.3f ms %5.1f %%", wt_tomography_stage_name(k), g[k].calls / nf,
               g[k].wall / nf * 1e3, 100.0 * g[k].wall / nf / solve);
        if (g[k].busy_min >= 0.0) printf("   busy %.3f / %.3f ms", g[k].busy_min / nf * 1e3, g[k].busy_max / nf * 1e3);
        printf("\n");
        rest -= g[k].wall / nf;
    }
    printf("    %-32s            %8.3f ms %5.1f %%\n", "the rest (PCG vectors, checks)", rest * 1e3, 100.0 * rest / solve);
}

static int bench_variant(wt_cli *cli, const wt_system *sys, int kind, int reps)
{
    const char *name = wt_reconstructor_name(kind);
    wt_reconstructor_params par;
    wt_reconstructor_params_from_config(sys->cfg, kind, -1, &par);
    const wt_recon_variant_config *v = par.variant;
    wt_bench_tomography b;
    int st = wt_bench_tomography_run(cli->ctx, sys, &par, name, reps, &b);
    if (st < 0) return st;
    printf("\n%s: %lld unknowns in %d layers, %d sensors, %lld slopes (set-up %.2f s%s)\n", name,
           (long long)b.nunknowns, v->nlayers, sys->nsensors, (long long)sys->nslopes, b.setup,
           v->preconditioner != WT_PRECOND_NONE ? ", incl. the preconditioner" : "");
    char label[64];
    snprintf(label, sizeof label, "%s: apply M", name);
    report(label, b.apply, b.flops, b.bytes);
    snprintf(label, sizeof label, "%s: one %s iteration", name, v->preconditioner != WT_PRECOND_NONE ? "PCG" : "CG");
    report(label, b.iteration, b.it_flops, b.it_bytes);
    snprintf(label, sizeof label, "%s: frame (%d iterations)", name, par.iterations);
    /* rhs ≈ half an apply; the initial residual continues the previous frame's (no apply of M,
     * wt_tomography_solve_continue), then one preconditioner apply and vector work: an iteration without
     * its apply */
    report(label, b.frame, b.flops * 0.5 + (b.it_flops - b.flops) + b.it_flops * par.iterations,
           b.bytes * 0.5 + (b.it_bytes - b.bytes) + b.it_bytes * par.iterations);
    if (kind == WT_RECON_PCG3)
        printf("  real-time goal: a %d-iteration pcg3 frame in 2 ms (500 Hz): measured %.2f ms = %.1fx the budget "
               "(p99 %.2f ms over %d frames)\n",
               par.iterations, b.frame.med * 1e3, b.frame.med / 2e-3, b.frame.p99 * 1e3, reps);
    if (b.shift_moving) {
        snprintf(label, sizeof label, "%s: shift (recon.predict, %d layers)", name, b.shift_moving);
        report(label, b.shift, b.shift_flops, b.shift_bytes);
        printf("  the prediction's shift is %.1f %% of the frame's median above (target <= 5 %%; median of 200 calls, "
               "the layers on the context's threads)\n", 100.0 * b.shift.med / b.frame.med);
        snprintf(label, sizeof label, "%s: integrator on the layers (recon.predict_integrator)", name);
        report(label, b.integrate, b.integrate_flops, b.integrate_bytes);
        printf("  a frame of the integrator on the layers (the estimate to its spectra, the update, the state back) is %.1f %% of "
               "the frame (in place of the shift's)\n", 100.0 * b.integrate.med / b.frame.med);
    }
    char what[64];
    snprintf(what, sizeof what, "a %s frame", name);
    report_profile(what, b.stage, b.prof_frames);
    if (b.has_fitting) {
        if (par.fitting.solver == WT_FIT_CHOLESKY)
            snprintf(label, sizeof label, "%s: fitting (Cholesky, %s)", name, par.fitting.factor_float32 ? "fp32" : "fp64");
        else snprintf(label, sizeof label, "%s: fitting (%d CG iterations)", name, par.fit_iterations);
        printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]\n", label, b.fitting.med * 1e3, b.fitting.p10 * 1e3,
               b.fitting.p90 * 1e3, b.fitting.p99 * 1e3);
    }
    return WT_OK;
}

/* A learned model taken at the next frame (SPEC §12 "Updates"; wt_reconstructor_set_model): two profiles on the
 * learning grid (22 altitudes, as an estimate gives them) in turn, r0 0.129 and 0.11 m; the first update draws
 * the unit layers' model error of every new altitude (once per reconstructor), the later ones rescale. The
 * preconditioner is updated from its parts (as a learning loop builds it, wt_precond_params.updatable); after
 * each update, side by side, the rebuild it replaces (wt_precond_alloc on the same tomography). */
static int bench_update(wt_cli *cli, const wt_system *sys, int kind, int reps)
{
    wt_reconstructor_params par;
    wt_reconstructor_params_from_config(sys->cfg, kind, -1, &par);
    par.precond.updatable = 1;
    wt_reconstructor *r = NULL;
    const double ts = wt_time_now();
    int st = wt_reconstructor_alloc(cli->ctx, sys, kind, &par, &r);
    if (st < 0) return st;
    const double setup = wt_time_now() - ts;
    wt_precond_params rebuild = par.precond;
    rebuild.updatable = 0;
    double alt[WT_LEARN_MAX_ALT], f[2][WT_LEARN_MAX_ALT];
    const int na = wt_learn_default_grid(sys->nlgs ? sys->sensors[0].altitude : 0.0, WT_LEARN_MAX_ALT, alt);
    for (int p = 0; p < 2; p++) {
        double sum = 0.0;
        for (int k = 0; k < na; k++) sum += f[p][k] = exp(-alt[k] / (p ? 2000.0 : 4000.0)) + (k == 0 ? 0.5 * p : 0.0);
        for (int k = 0; k < na; k++) f[p][k] /= sum;
    }
    double t0 = wt_time_now(), first = 0.0, m1 = 0.0, p1 = 0.0;
    double *tm = malloc((size_t)reps * sizeof *tm), *tp = malloc((size_t)reps * sizeof *tp),
           *tt = malloc((size_t)reps * sizeof *tt), *tr = malloc((size_t)reps * sizeof *tr);
    if (!tm || !tp || !tt || !tr) st = WT_ERROR(cli->ctx, WT_ERR_NOMEM, "out of memory for the update times");
    if (st >= 0 && (st = wt_reconstructor_set_model(r, 0.129, na, alt, f[0], NULL, NULL)) >= 0) {
        first = wt_time_now() - t0;
        wt_reconstructor_last_update_times(r, &m1, &p1);
    }
    for (int i = 0; i < reps && st >= 0; i++) {
        t0 = wt_time_now();
        st = wt_reconstructor_set_model(r, i % 2 ? 0.129 : 0.11, na, alt, f[(i + 1) % 2], NULL, NULL);
        tt[i] = wt_time_now() - t0;
        wt_reconstructor_last_update_times(r, &tm[i], &tp[i]);
        wt_precond *pre = NULL;
        t0 = wt_time_now();
        if (st >= 0) st = wt_precond_alloc(cli->ctx, wt_reconstructor_tomography(r), &rebuild, &pre);
        tr[i] = wt_time_now() - t0;
        wt_precond_free(pre);
    }
    if (st >= 0) {
        const wt_bench_stats a = wt_bench_summarise(tt, reps), b = wt_bench_summarise(tm, reps),
                             c = wt_bench_summarise(tp, reps), d = wt_bench_summarise(tr, reps);
        printf("%s: a learned model (%d altitudes) at the next frame: %.1f ms [%.1f, %.1f] (the model %.1f ms: priors, "
               "model error, noise; the preconditioner's update %.1f ms, against %.1f ms to rebuild it: x%.3f), median "
               "of %d; the first %.2f s (model %.2f s: the model error's unit layers drawn once); set-up with the "
               "update's parts %.2f s\n", wt_reconstructor_name(kind), na, a.med * 1e3, a.p10 * 1e3, a.p90 * 1e3,
               b.med * 1e3, c.med * 1e3, d.med * 1e3, c.med / d.med, reps, first, m1, setup);
    }
    free(tm), free(tp), free(tt), free(tr);
    wt_reconstructor_free(r);
    return st;
}

/* Closed-loop speed (issue #3 goal: >= 5 frames/s at E-ELT size with pcg3): warm-up frames, then
 * timed frames, with the split by part. */
static int bench_loop(wt_cli *cli, const wt_system *sys, int frames, double *sensors)
{
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = sys->cfg->seed, .noise = 1};
    wt_loop_params par;
    wt_loop_params_from_config(sys->cfg, &o, &par);
    const int warm = 3;
    wt_bench_loop b;
    int st = wt_bench_loop_run(cli->ctx, sys, &o, &par, warm, frames, &b);
    if (st < 0) return st;
    const wt_bench_stats s = b.frame;
    const wt_loop_times m = b.per_frame;
    *sensors = m.sensors;
    printf("\nclosed loop, pcg3, %d frames after %d warm-up (set-up %.1f s): median %.1f ms/frame [%.1f, %.1f] = "
           "%.2f frames/s (goal >= 5)\n",
           frames, warm, b.setup, s.med * 1e3, s.p10 * 1e3, s.p90 * 1e3, 1.0 / s.med);
    printf("  mean per frame: atmosphere %.1f, sensors %.1f, reconstruction %.1f, fitting %.1f, control %.1f, "
           "evaluation %.1f ms\n",
           m.atmosphere * 1e3, m.sensors * 1e3, m.reconstruction * 1e3, m.fitting * 1e3, m.control * 1e3,
           m.evaluation * 1e3);
    return WT_OK;
}

/* MVM apply at the system's size against the memory bound, measured side by side (compare/bench.h). */
static int bench_mvm_apply(wt_cli *cli, const wt_system *sys, int reps)
{
    wt_bench_mvm b;
    int st = wt_bench_mvm_apply(cli->ctx, sys->nact, sys->nslopes, reps, &b);
    if (st < 0) return st;
    const wt_bench_stats g = b.sgemv, c = b.copy;
    const double bytes = b.bytes;
    printf("\nMVM apply, R %lld x %lld float32 (%.2f GB), %d OpenBLAS / %d OpenMP threads, %d repetitions side by "
           "side:\n",
           (long long)sys->nact, (long long)sys->nslopes, bytes / 1e9, openblas_get_num_threads(),
           wt_context_threads(cli->ctx), reps);
    printf("  sgemv          %8.2f ms  [%.2f, %.2f]  reads R once: %.1f GB/s\n", g.med * 1e3, g.p10 * 1e3, g.p90 * 1e3,
           bytes / g.med / 1e9);
    for (int k = 0; k < 2; k++) {
        const wt_bench_stats h = b.half[k];
        printf("  %s GEMV     %8.2f ms  [%.2f, %.2f]  reads %.3g GB: %.3g GB/s; %.2f x sgemv's time (%s); "
               "max |dy| / max |y| = %.1e\n",
               wt_prec_name(b.half_prec[k]), h.med * 1e3, h.p10 * 1e3, h.p90 * 1e3, bytes / 2e9,
               bytes / 2.0 / h.med / 1e9, h.med / g.med, h.med < g.med ? "faster" : "slower", b.half_error[k]);
    }
    printf("  STREAM copy    %8.2f ms  [%.2f, %.2f]  of the float32 bytes (read + write): %.1f GB/s\n", c.med * 1e3,
           c.p10 * 1e3, c.p90 * 1e3, 2.0 * bytes / c.med / 1e9);
    printf("  sgemv bandwidth / copy bandwidth = %.2f; a 500 Hz MVM would need %.0f GB/s (fp32), %.0f GB/s (16-bit)\n",
           (bytes / g.med) / (2.0 * bytes / c.med), bytes * 500.0 / 1e9, bytes * 250.0 / 1e9);
    return WT_OK;
}

/* The diffractive sensing of sys, LGS and NGS (compare/bench.h), beside the geometric sensors' time per
 * frame of the closed loop (geometric < 0: not measured). */
static int bench_sensing(wt_cli *cli, const wt_system *sys, int frames, double geometric, double gf, double bw)
{
    const int threads = wt_context_threads(cli->ctx);
    printf("\ndiffractive sensing, %s: %d threads, median [p10, p90] of %d frames after 1 warm frame\n", sys->cfg->path,
           threads, frames);
    int any = 0;
    for (int kind = WT_SENSOR_LGS; kind <= WT_SENSOR_NGS; kind++) {
        wt_bench_sensing b;
        int st = wt_bench_sensing_run(cli->ctx, sys, kind, frames, &b);
        if (st < 0) return st;
        if (!b.nsensors) continue;
        any = 1;
        const char *name = kind == WT_SENSOR_LGS ? "LGS" : "NGS";
        const double per = b.frame.med * threads / (double)b.nsub; /* thread-seconds per subaperture */
        printf("  %s: %d sensors, %lld subapertures (n_p %d, N %d, %dx%d pixels, %d cells/pixel): %.1f ms per frame "
               "[%.1f, %.1f] = images %.1f + noise %.1f + centroider %.1f ms\n",
               name, b.nsensors, (long long)b.nsub, b.np, b.N, b.ns, b.ns, b.k, b.frame.med * 1e3, b.frame.p10 * 1e3,
               b.frame.p90 * 1e3, b.images.med * 1e3, b.noise.med * 1e3, b.centroid.med * 1e3);
        printf("    set-up %.2f s, memory %.0f MB; per subaperture %.2f thread-us per frame, image %.3g flop and %.3g "
               "bytes of table/input/output: %.2f GFlop/s (%.1f %% of DGEMM), %.2f GB/s (%.1f %% of triad)\n",
               b.setup, b.memory / 1e6, per * 1e6, b.flops, b.bytes, b.flops * b.nsub / b.images.med / 1e9,
               100.0 * b.flops * b.nsub / b.images.med / gf, b.bytes * b.nsub / b.images.med / 1e9,
               100.0 * b.bytes * b.nsub / b.images.med / bw);
        printf("    CPU time %.1f ms per frame on %d threads: %.1f ms of wall on %d idle cores (the median above "
               "grows with the machine's load)\n",
               b.cpu * 1e3, threads, b.cpu / threads * 1e3, threads);
        if (kind == WT_SENSOR_LGS)
            printf("    target: <= 1 s per frame for the 6 E-ELT LGS on 2 threads (stretch 0.5 s): median "
                   "%.2f s, %.2f s on idle cores\n",
                   b.frame.med, b.cpu / threads);
    }
    wt_bench_sodium na;
    const int st = wt_bench_sodium_run(cli->ctx, sys, 3, &na);
    if (st < 0) return st;
    if (na.nsensors)
        printf("  sodium layer in time, %d LGS (%lld subapertures), median [p10, p90] of 3: the truth's spot tables of a "
               "new profile %.3f s [%.3f, %.3f] (CPU %.3f s: %.3f s on %d idle cores); the oracle's reference rebuilt "
               "(I0, derivatives, matched filter, covariance) %.3f s [%.3f, %.3f] from the kept cells (CPU %.3f s: "
               "%.3f s on %d idle cores; the first, with its FFTs, %.2f s); target <= 2 s for the 6 E-ELT LGS on 2 "
               "threads\n",
               na.nsensors, (long long)na.nsub, na.tables.med, na.tables.p10, na.tables.p90, na.cpu_tables,
               na.cpu_tables / threads, threads, na.reference.med, na.reference.p10, na.reference.p90, na.cpu_reference,
               na.cpu_reference / threads, threads, na.full);
    if (na.nsensors)
        printf("  the reference from the loop's pixels (lgs.wfs.reference = pixels), %d LGS: a frame's re-centred images "
               "accumulated %.1f ms [%.1f, %.1f] (CPU %.1f ms: %.1f ms on %d idle cores; target <= 10 %% of a "
               "diffractive frame, above); a rebuild from their mean (I0, derivatives, matched filter, covariance) "
               "%.3f s [%.3f, %.3f] (CPU %.3f s: %.3f s on %d idle cores; target <= 2 s for the 6 E-ELT LGS on 2 "
               "threads); the start (the set-up derivatives of the anchor) %.2f s\n",
               na.nsensors, na.accumulate.med * 1e3, na.accumulate.p10 * 1e3, na.accumulate.p90 * 1e3,
               na.cpu_accumulate * 1e3, na.cpu_accumulate / threads * 1e3, threads, na.pixels.med, na.pixels.p10,
               na.pixels.p90, na.cpu_pixels, na.cpu_pixels / threads, threads, na.pixels_start);
    if (na.nsensors && na.gain_first > 0.0)
        printf("  the matched filter's gain from the loop's pixels (lgs.wfs.gain_update_s), %d LGS: an estimate (the spot "
               "model fitted to the mean image, its derivatives through the filter) %.3f s [%.3f, %.3f] from the last "
               "(CPU %.3f s: %.3f s on %d idle cores), the first, from the reference, %.2f s; C_E's refresh not "
               "included\n",
               na.nsensors, na.gain.med, na.gain.p10, na.gain.p90, na.cpu_gain, na.cpu_gain / threads, threads,
               na.gain_first);
    if (!any) printf("  (no diffractive sensor in %s)\n", sys->cfg->path);
    if (geometric >= 0)
        printf("  geometric sensors of the closed loop above (all sensors, slopes + noise): %.1f ms per frame\n",
               geometric * 1e3);
    return WT_OK;
}

typedef struct {
    const char *sensing;
    long reps, loop_frames, sensing_frames;
    int skip_loop, skip_build, sensing_only;
    int npair[2];                          /* --pair-a, --pair-b overrides */
    const char *pair[2][WT_CLI_MAX_SET];
    const char *pair_recon;                /* --pair-recon */
    long pair_warm;
} bench_args;

static int bench_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    bench_args *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--pair-a") || !strcmp(o, "--pair-b")) {
        const int k = o[7] == 'b';
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
        if (!strchr(v, '=')) {
            wt_cli_usage_error(cli, "%s expects key=value, got '%s'", o, v);
            return -1;
        }
        if (a->npair[k] == WT_CLI_MAX_SET) {
            wt_cli_usage_error(cli, "too many %s options (at most %d)", o, WT_CLI_MAX_SET);
            return -1;
        }
        a->pair[k][a->npair[k]++] = v;
    } else if (!strcmp(o, "--pair-recon")) {
        if (!(a->pair_recon = wt_cli_value(cli, argc, argv, i))) return -1;
        const int kind = wt_reconstructor_kind(a->pair_recon);
        if (kind != WT_RECON_PCG3 && kind != WT_RECON_CG9) {
            wt_cli_usage_error(cli, "--pair-recon expects pcg3 or cg9, got '%s'", a->pair_recon);
            return -1;
        }
    } else if (!strcmp(o, "--pair-warm")) {
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
        if (wt_cli_int(cli, o, v, 0, 100000, &a->pair_warm) < 0) return -1;
    } else if (!strcmp(o, "--no-loop")) a->skip_loop = 1;
    else if (!strcmp(o, "--sensing-only")) a->sensing_only = 1;
    else if (!strcmp(o, "--sensing")) {
        if (!(a->sensing = wt_cli_value(cli, argc, argv, i))) return -1;
    } else if (!strcmp(o, "--sensing-frames")) {
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
        if (wt_cli_int(cli, o, v, 3, 100000, &a->sensing_frames) < 0) return -1;
    }
    else if (!strcmp(o, "--no-build")) a->skip_build = 1;
    else if (!strcmp(o, "--reps") || !strcmp(o, "--loop-frames")) {
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
        if (wt_cli_int(cli, o, v, 3, 100000, o[2] == 'r' ? &a->reps : &a->loop_frames) < 0) return -1;
    } else return 0; /* CONFIG (positional or --config) is the common options' */
    return 1;
}

/* The offline build of the pcg3 control matrix, timed with its peak memory. */
static int bench_mvm_build(wt_cli *cli, const wt_system *sys)
{
    wt_mvm *m = NULL;
    double t0 = wt_time_now();
    int st = wt_mvm_build_variant(cli->ctx, sys, sys->cfg, "pcg3", NULL, &m);
    double el = wt_time_now() - t0;
    if (st >= 0) {
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        const wt_mvm_stats *s = &m->stats;
        printf("\nMVM build, pcg3: %.1f s (assemble %.1f, normal %.1f, analyse %.1f, factorise %.1f, solve %.1f); "
               "factor %.3g non-zeros; peak memory %.2f GB (process high-water mark, which the 0.8 GB triad test "
               "above also sets; estimate %.2f GB)\n",
               el, s->t_assemble, s->t_normal, s->t_analyze, s->t_factorize, s->t_solve, s->nnz_factor,
               ru.ru_maxrss / 1048576.0, s->peak_estimate / 1e9);
    }
    wt_mvm_free(m);
    return st;
}

/* The 1, 5 and 15 minute load averages (/proc/loadavg), or "?" where there is none. */
static void load_average(char *buf, size_t n)
{
    FILE *f = fopen("/proc/loadavg", "r");
    double l[3];
    if (f && fscanf(f, "%lf %lf %lf", &l[0], &l[1], &l[2]) == 3) snprintf(buf, n, "%.2f %.2f %.2f", l[0], l[1], l[2]);
    else snprintf(buf, n, "?");
    if (f) fclose(f);
}

/* The paired mode: configurations A and B (compare/bench.h wt_bench_pair_run), read from path with the
 * common --set overrides and then each side's own. */
static int bench_pair(wt_cli *cli, const char *path, const bench_args *args)
{
    const int kind = wt_reconstructor_kind(args->pair_recon ? args->pair_recon : "cg9");
    const char *sides = "AB";
    wt_config *cfg[2] = {NULL, NULL};
    wt_system *sys[2] = {NULL, NULL};
    const char **set = NULL;
    int st = WT_OK;
    const int pairs = (int)args->reps;
    char before[64], after[64];
    set = malloc((size_t)(cli->nset + WT_CLI_MAX_SET) * sizeof *set);
    if (!set) return WT_ERROR(cli->ctx, WT_ERR_NOMEM, "bench: out of memory");
    for (int k = 0; k < 2; k++) {
        int n = 0;
        for (int i = 0; i < cli->nset; i++) set[n++] = cli->set[i];
        for (int i = 0; i < args->npair[k]; i++) set[n++] = args->pair[k][i];
        if ((st = wt_config_read(cli->ctx, path, n, set, &cfg[k])) < 0) goto out;
        if ((st = wt_system_alloc(cli->ctx, cfg[k], &sys[k])) < 0) goto out;
    }
    wt_reconstructor_params par[2];
    for (int k = 0; k < 2; k++) wt_reconstructor_params_from_config(cfg[k], kind, -1, &par[k]);
    printf("wavetomo bench, paired: %s, %s, %d OpenMP threads, %d pairs after %ld warm frames per side, alternating "
           "A B / B A on the same slopes\n",
           cfg[0]->path, wt_reconstructor_name(kind), wt_context_threads(cli->ctx), pairs, args->pair_warm);
    for (int k = 0; k < 2; k++) {
        printf("  %c:", sides[k]);
        for (int i = 0; i < args->npair[k]; i++) printf(" %s", args->pair[k][i]);
        printf("%s\n", args->npair[k] ? "" : " (CONFIG as it is)");
    }
    const wt_system *const cs[2] = {sys[0], sys[1]};
    wt_bench_pair b;
    load_average(before, sizeof before);
    st = wt_bench_pair_run(cli->ctx, cs, par, kind, (int)args->pair_warm, pairs, &b);
    load_average(after, sizeof after);
    if (st < 0) goto out;
    printf("  machine load average (1, 5, 15 min): %s before, %s after\n", before, after);
    for (int k = 0; k < 2; k++)
        printf("  %c's FFT plans: %s%s%s\n", sides[k], cfg[k]->fft_wisdom[0] ? "from the wisdom " : "FFTW_ESTIMATE",
               cfg[k]->fft_wisdom, cfg[k]->fft_wisdom[0] ? " (recon.fft_wisdom)" : "");
    printf("  set-up: A %.2f s, B %.2f s; memory of the reconstructor: A %.1f MB, B %.1f MB\n", b.setup[0], b.setup[1],
           b.memory[0] / 1e6, b.memory[1] / 1e6);
    for (int k = 0; k < 2 && b.has_fitting; k++) {
        const wt_fitting_stats *fs = &b.fit[k];
        if (b.fit_solver[k] == WT_FIT_CHOLESKY)
            printf("  %c's fitting: Cholesky of N (%lld non-zeros) assembled in %.2f s, factored in %.2f s (%s): L has "
                   "%.3g non-zeros, %.1f MB held; the solves read %.1f MB per frame (split %.2g + %.2g | top %.2g)\n",
                   sides[k], (long long)fs->nnz_matrix, fs->t_assemble, fs->t_factorize, fs->ordering, fs->nnz_factor,
                   fs->factor_bytes / 1e6, 2.0 * fs->solve_bytes / 1e6, fs->split[0], fs->split[1], fs->split[2]);
        else printf("  %c's fitting: CG, %d iterations per frame\n", sides[k], par[k].fit_iterations);
    }
    printf("  %-11s %36s %36s %38s\n", "part", "A median [p10, p90] p99 ms", "B median [p10, p90] p99 ms",
           "B/A per pair median [p10, p90] p99");
    const char *names[3] = {"frame", "tomography", "fitting"};
    const wt_bench_stats *sa[3] = {&b.frame[0], &b.tomography[0], &b.fitting[0]};
    const wt_bench_stats *sb[3] = {&b.frame[1], &b.tomography[1], &b.fitting[1]};
    const wt_bench_stats *sr[3] = {&b.ratio_frame, &b.ratio_tomography, &b.ratio_fitting};
    for (int q = 0; q < (kind == WT_RECON_CG9 ? 3 : 2); q++) {
        char ca[64], cb[64], cr[64];
        snprintf(ca, sizeof ca, "%.3f [%.3f, %.3f] %.3f", sa[q]->med * 1e3, sa[q]->p10 * 1e3, sa[q]->p90 * 1e3,
                 sa[q]->p99 * 1e3);
        snprintf(cb, sizeof cb, "%.3f [%.3f, %.3f] %.3f", sb[q]->med * 1e3, sb[q]->p10 * 1e3, sb[q]->p90 * 1e3,
                 sb[q]->p99 * 1e3);
        snprintf(cr, sizeof cr, "%.4f [%.4f, %.4f] %.4f", sr[q]->med, sr[q]->p10, sr[q]->p90, sr[q]->p99);
        printf("  %-11s %36s %36s %38s\n", names[q], ca, cb, cr);
    }
    if (b.command_diff >= 0.0)
        printf("  commands of the last frame: |a_B - a_A| / |a_A| = %.3g (same slopes, warm-started each side)\n",
               b.command_diff);
    else printf("  (the two systems differ: no comparison of the commands)\n");
    for (int k = 0; k < 2; k++) {
        char what[32];
        snprintf(what, sizeof what, "%c's tomography", sides[k]);
        report_profile(what, b.stage[k], pairs);
    }
out:
    for (int k = 0; k < 2; k++) {
        wt_system_free(sys[k]);
        wt_config_free(cli->ctx, cfg[k]);
    }
    free(set);
    return st;
}

int wt_cmd_bench(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo bench", help)) return 1;
    bench_args args = {.reps = 50, .loop_frames = 20, .sensing_frames = 7, .pair_warm = 3};
    int rc = wt_cli_parse(&cli, argc, argv, bench_option, &args);
    if (rc < 0 && cli.dry_run) /* a common option that bench has no estimate for: refused, not ignored */
        rc = wt_cli_usage_error(&cli, "--dry-run: bench has no resource estimate; run it, or give --reps 1");
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    const char *path = cli.config_path ? cli.config_path : "data/presets/eelt-mcao.cfg";
    int reps = (int)args.reps, loop_frames = (int)args.loop_frames, skip_loop = args.skip_loop;
    wt_config *cfg = NULL, *dcfg = NULL;
    wt_system *sys = NULL, *dsys = NULL;
    double geometric = -1.0;
    int st;
    if (args.npair[0] || args.npair[1]) {
        st = bench_pair(&cli, path, &args);
        goto out;
    }
    st = wt_cli_read_config(&cli, path, &cfg);
    if (st < 0) goto out;
    st = wt_system_alloc(cli.ctx, cfg, &sys);
    if (st < 0) goto out;
    int threads = wt_context_threads(cli.ctx);
    printf("wavetomo bench: %s, %d OpenMP threads, %d OpenBLAS threads, %d repetitions\n", cfg->path, threads,
           openblas_get_num_threads(), reps);
    double bw = wt_bench_triad_bandwidth(cli.ctx, 5), gf = wt_bench_dgemm_rate();
    printf("machine: triad bandwidth %.1f GB/s, DGEMM %.1f GFlop/s (n = 2048, OpenBLAS)\n", bw / 1e9, gf / 1e9);
    printf("FFT plans: %s%s\n", cfg->fft_wisdom[0] ? "from the wisdom " : "FFTW_ESTIMATE (recon.fft_wisdom: measured ones)",
           cfg->fft_wisdom);
    if (args.sensing_only) goto sensing;
    printf("%-34s %9s     %s\n", "kernel", "median", "[p10, p90, p99] ms, work per call, implied rates");
    st = bench_variant(&cli, sys, WT_RECON_PCG3, reps);
    if (st < 0) goto out;
    st = bench_variant(&cli, sys, WT_RECON_CG9, reps < 20 ? reps : 20);
    if (st < 0) goto out;
    printf("\n");
    for (int kind = WT_RECON_PCG3; kind <= WT_RECON_CG9 && st >= 0; kind++) st = bench_update(&cli, sys, kind, reps < 7 ? reps : 7);
    if (st < 0) goto out;
    /* the build first: its peak memory is read from the process's high-water mark, which the GEMV's
     * 2 x 2.3 GB buffers would otherwise set */
    if (!args.skip_build && (st = bench_mvm_build(&cli, sys)) < 0) goto out;
    if (!skip_loop && (st = bench_loop(&cli, sys, loop_frames, &geometric)) < 0) goto out;
    if ((st = bench_mvm_apply(&cli, sys, reps < 10 ? reps : 10)) < 0) goto out;
sensing:
    if (args.sensing) {
        /* its own system: the diffractive sensors are built with it (their set-up is timed there) */
        if ((st = wt_cli_read_config(&cli, args.sensing, &dcfg)) < 0) goto out;
        if ((st = wt_system_alloc(cli.ctx, dcfg, &dsys)) < 0) goto out;
        st = bench_sensing(&cli, dsys, (int)args.sensing_frames, geometric, gf, bw);
    } else st = bench_sensing(&cli, sys, (int)args.sensing_frames, geometric, gf, bw);
out:
    if (st < 0) rc = wt_cli_fail(&cli, st);
    wt_system_free(dsys);
    wt_config_free(cli.ctx, dcfg);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_cli_done(&cli);
    return rc;
}
