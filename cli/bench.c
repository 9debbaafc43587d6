/* cli/bench.c: `wavetomo bench`: reconstructor kernel timings with flop/byte counts, against the
 * machine's own limits measured in the same run (a STREAM-like triad and an OpenBLAS DGEMM). The
 * timings are core/sim/bench.h's; this file parses, prints and times the MVM build. */
#include <cblas.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>

#include "cli.h"
#include "core/build/mvm_build.h"
#include "core/la/half.h"
#include "core/model/params.h"
#include "core/model/system.h"
#include "core/sim/bench.h"

static void help(void)
{
    printf("usage: wavetomo bench [CONFIG] [--reps N] [--loop-frames N] [--no-loop] [--no-build] [--threads N]\n"
           "                      [--sensing DCONFIG] [--sensing-only] [--sensing-frames N] [--set key=value]...\n"
           "\n"
           "Times, on CONFIG (default data/presets/eelt-mcao.cfg): one application of the normal operator M\n"
           "for pcg3 and cg9, one PCG iteration, and a whole pcg3 frame (right-hand side + the configured\n"
           "iterations), plus the cg9 fitting operator. Reports medians and the 10th, 90th and 99th percentiles of\n"
           "--reps runs (default 50), the flops and bytes per call, and the rates they imply, next to the\n"
           "machine's memory bandwidth (triad) and DGEMM rate measured in the same run. The byte counts are\n"
           "operand traffic; the working sets (~1 MB for pcg3) live in cache, so the implied GB/s can exceed\n"
           "the DRAM triad figure. Then the closed-loop simulation speed with pcg3 (--loop-frames, default\n"
           "20, after 3 warm-up frames; --no-loop skips it); the MVM apply (float32 GEMV of the real size, and\n"
           "the fp16 and bf16 GEMVs of recon.mvm_precision on the same matrix)\n"
           "against a STREAM copy of the same bytes; and the offline build of the pcg3 MVM with its peak\n"
           "memory (--no-build skips it; ~4 minutes at E-ELT size).\n"
           "\n"
           "Diffractive sensing (issue 19): the diffractive sensors of DCONFIG (--sensing; default CONFIG itself when\n"
           "it has any, e.g. data/presets/eelt-mcao-diffractive.cfg), LGS and NGS separately: per frame, images +\n"
           "detector noise + centroider of every sensor of the kind, median and [p10, p90] of --sensing-frames\n"
           "frames (default 7) on the --threads threads, with the parts, the sensors' set-up time and memory, and\n"
           "the flops and bytes per subaperture against the machine's DGEMM rate and triad bandwidth; next to the\n"
           "geometric sensors' time per frame of the closed loop above. --sensing-only times only the machine\n"
           "and the sensing (--set applies to DCONFIG too).\n");
}

static void report(const char *what, wt_bench_stats s, double flops, double bytes)
{
    printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]  %7.2f Mflop %7.1f MB  %6.2f GFlop/s %6.2f GB/s\n", what,
           s.med * 1e3, s.p10 * 1e3, s.p90 * 1e3, s.p99 * 1e3, flops / 1e6, bytes / 1e6, flops / s.med / 1e9,
           bytes / s.med / 1e9);
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
    if (b.has_fitting) {
        snprintf(label, sizeof label, "%s: fitting (%d CG iterations)", name, par.fit_iterations);
        printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]\n", label, b.fitting.med * 1e3, b.fitting.p10 * 1e3,
               b.fitting.p90 * 1e3, b.fitting.p99 * 1e3);
    }
    return WT_OK;
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

/* MVM apply at the system's size against the memory bound, measured side by side (core/sim/bench.h). */
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
        printf("  %s GEMV     %8.2f ms  [%.2f, %.2f]  reads %.2f GB: %.1f GB/s; %.2fx faster than sgemv; "
               "max |dy| / max |y| = %.1e\n",
               wt_prec_name(b.half_prec[k]), h.med * 1e3, h.p10 * 1e3, h.p90 * 1e3, bytes / 2e9,
               bytes / 2.0 / h.med / 1e9, g.med / h.med, b.half_error[k]);
    }
    printf("  STREAM copy    %8.2f ms  [%.2f, %.2f]  of the float32 bytes (read + write): %.1f GB/s\n", c.med * 1e3,
           c.p10 * 1e3, c.p90 * 1e3, 2.0 * bytes / c.med / 1e9);
    printf("  sgemv bandwidth / copy bandwidth = %.2f; a 500 Hz MVM would need %.0f GB/s (fp32), %.0f GB/s (16-bit)\n",
           (bytes / g.med) / (2.0 * bytes / c.med), bytes * 500.0 / 1e9, bytes * 250.0 / 1e9);
    return WT_OK;
}

/* The diffractive sensing of sys, LGS and NGS (core/sim/bench.h), beside the geometric sensors' time per
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
            printf("    target (issue 19): <= 1 s per frame for the 6 E-ELT LGS on 2 threads (stretch 0.5 s): median "
                   "%.2f s, %.2f s on idle cores\n",
                   b.frame.med, b.cpu / threads);
    }
    if (!any) printf("  (no diffractive sensor in %s)\n", sys->cfg->path);
    if (geometric >= 0)
        printf("  geometric sensors of the closed loop above (all sensors, slopes + noise): %.1f ms per frame\n",
               geometric * 1e3);
    return WT_OK;
}

typedef struct {
    const char *path, *sensing;
    long reps, loop_frames, sensing_frames;
    int skip_loop, skip_build, sensing_only;
} bench_args;

static int bench_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    bench_args *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--no-loop")) a->skip_loop = 1;
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
    } else if (o[0] == '-' || a->path) return 0;
    else a->path = o;
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

int wt_cmd_bench(int argc, char **argv)
{
    wt_cli cli;
    if (wt_cli_init(&cli, "wavetomo bench", help)) return 1;
    bench_args args = {NULL, NULL, 50, 20, 7, 0, 0, 0};
    int rc = wt_cli_parse(&cli, argc, argv, bench_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    const char *path = args.path;
    int reps = (int)args.reps, loop_frames = (int)args.loop_frames, skip_loop = args.skip_loop;
    if (!path && !cli.config_path) path = "data/presets/eelt-mcao.cfg";
    wt_config *cfg = NULL, *dcfg = NULL;
    wt_system *sys = NULL, *dsys = NULL;
    double geometric = -1.0;
    int st = wt_cli_read_config(&cli, path, &cfg);
    if (st < 0) goto out;
    st = wt_system_alloc(cli.ctx, cfg, &sys);
    if (st < 0) goto out;
    int threads = wt_context_threads(cli.ctx);
    printf("wavetomo bench: %s, %d OpenMP threads, %d OpenBLAS threads, %d repetitions\n", cfg->path, threads,
           openblas_get_num_threads(), reps);
    double bw = wt_bench_triad_bandwidth(cli.ctx, 5), gf = wt_bench_dgemm_rate();
    printf("machine: triad bandwidth %.1f GB/s, DGEMM %.1f GFlop/s (n = 2048, OpenBLAS)\n", bw / 1e9, gf / 1e9);
    if (args.sensing_only) goto sensing;
    printf("%-34s %9s     %s\n", "kernel", "median", "[p10, p90, p99] ms, work per call, implied rates");
    st = bench_variant(&cli, sys, WT_RECON_PCG3, reps);
    if (st < 0) goto out;
    st = bench_variant(&cli, sys, WT_RECON_CG9, reps < 20 ? reps : 20);
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
