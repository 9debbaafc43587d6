/* cli/bench.c: `wavetomo bench`: reconstructor kernel timings with flop/byte counts, against the
 * machine's own limits measured in the same run (a STREAM-like triad and an OpenBLAS DGEMM). */
#include <cblas.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "cli.h"
#include "core/la/half.h"
#include "core/base/rng.h"
#include "core/model/fitting.h"
#include "core/model/system.h"
#include "core/model/params.h"
#include "core/model/tomography.h"
#include "core/build/mvm_build.h"
#include "core/sim/loop.h"
#include <sys/resource.h>

static void help(void)
{
    printf("usage: wavetomo bench [CONFIG] [--reps N] [--loop-frames N] [--no-loop] [--no-build] [--threads N]\n"
           "                      [--set key=value]...\n"
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
           "memory (--no-build skips it; ~4 minutes at E-ELT size).\n");
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

typedef struct {
    double med, p10, p90, p99;
} stats;

static stats summarise(double *t, int n)
{
    qsort(t, (size_t)n, sizeof *t, cmp_double);
    stats s = {t[n / 2], t[n / 10], t[(9 * n) / 10], t[(99 * n) / 100]};
    return s;
}

static void report(const char *what, stats s, double flops, double bytes)
{
    printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]  %7.2f Mflop %7.1f MB  %6.2f GFlop/s %6.2f GB/s\n", what,
           s.med * 1e3, s.p10 * 1e3, s.p90 * 1e3, s.p99 * 1e3, flops / 1e6, bytes / 1e6, flops / s.med / 1e9,
           bytes / s.med / 1e9);
}

/* STREAM triad a = b + s c over arrays far larger than the caches: 24 bytes per element. */
static double triad_bandwidth(int reps)
{
    const size_t n = 1 << 25; /* 3 x 256 MB */
    double *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *c = malloc(n * sizeof *c);
    if (!a || !b || !c) {
        free(a), free(b), free(c);
        return 0.0;
    }
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; i++) a[i] = 0.0, b[i] = 1.0, c[i] = 2.0;
    double best = 1e30;
    for (int r = 0; r < reps; r++) {
        double t0 = wt_time_now();
#pragma omp parallel for schedule(static)
        for (size_t i = 0; i < n; i++) a[i] = b[i] + 0.5 * c[i];
        double t = wt_time_now() - t0;
        if (t < best) best = t;
    }
    double bw = 24.0 * n / best;
    free(a), free(b), free(c);
    return bw;
}

static double dgemm_rate(void)
{
    const int n = 2048;
    double *a = malloc((size_t)n * n * sizeof *a), *b = malloc((size_t)n * n * sizeof *b),
           *c = calloc((size_t)n * n, sizeof *c);
    if (!a || !b || !c) {
        free(a), free(b), free(c);
        return 0.0;
    }
    for (size_t i = 0; i < (size_t)n * n; i++) a[i] = 1.0 / (1.0 + (double)(i % 97)), b[i] = 1.0 / (1.0 + (double)(i % 89));
    double best = 1e30;
    for (int r = 0; r < 3; r++) {
        double t0 = wt_time_now();
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, n, n, 1.0, a, n, b, n, 0.0, c, n);
        double t = wt_time_now() - t0;
        if (t < best) best = t;
    }
    free(a), free(b), free(c);
    return 2.0 * n * (double)n * n / best;
}

static int bench_variant(wt_cli *cli, const wt_system *sys, const wt_recon_variant_config *v, const char *name, int reps)
{
    wt_tomography *t = NULL;
    double t0 = wt_time_now();
    wt_tomography_params tp;
    wt_tomography_params_from_config(sys->cfg, &tp);
    int st = wt_tomography_alloc(cli->ctx, sys, v, name, &tp, &t);
    if (st < 0) return st;
    double setup = wt_time_now() - t0;
    int64_t n = wt_tomography_nunknowns(t);
    double *c = malloc((size_t)n * sizeof *c), *y = malloc((size_t)n * sizeof *y);
    double *s = malloc((size_t)sys->nslopes * sizeof *s), *times = malloc((size_t)reps * sizeof *times);
    if (!c || !y || !s || !times) {
        st = wt_error_set(cli->ctx, WT_ERR_NOMEM, __FILE__, __LINE__, "bench: out of memory");
        goto out;
    }
    wt_rng rng;
    wt_rng_init(&rng, 7, 0);
    for (int64_t i = 0; i < n; i++) c[i] = wt_rng_normal(&rng) * 1e-7;
    for (int64_t i = 0; i < sys->nslopes; i++) s[i] = wt_rng_normal(&rng) * 1e-6;
    double flops, bytes;
    wt_tomography_cost(t, &flops, &bytes);
    printf("\n%s: %lld unknowns in %d layers, %d sensors, %lld slopes (set-up %.2f s%s)\n", name, (long long)n,
           v->nlayers, sys->nsensors, (long long)sys->nslopes, setup, v->jacobi ? ", incl. the exact Jacobi diagonal" : "");

    wt_tomography_apply(t, 1.0, c, y); /* warm caches and pages */
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_tomography_apply(t, 1.0, c, y);
        times[r] = wt_time_now() - a;
    }
    char label[64];
    snprintf(label, sizeof label, "%s: apply M", name);
    report(label, summarise(times, reps), flops, bytes);

    double it_flops = flops + wt_pcg_flops_per_iteration(n, v->jacobi);
    double it_bytes = bytes + 8.0 * n * (v->jacobi ? 12.0 : 11.0);
    /* one iteration = (time of 9 iterations − time of 1) / 8, from the same starting point: the
     * right-hand side and the initial residual cancel out */
    for (int r = 0; r < reps; r++) {
        memset(c, 0, (size_t)n * sizeof *c);
        double a = wt_time_now();
        wt_tomography_solve(t, s, c, 1, 0.0, NULL, NULL);
        double one = wt_time_now() - a;
        memset(c, 0, (size_t)n * sizeof *c);
        a = wt_time_now();
        wt_tomography_solve(t, s, c, 9, 0.0, NULL, NULL);
        times[r] = ((wt_time_now() - a) - one) / 8.0;
    }
    snprintf(label, sizeof label, "%s: one %s iteration", name, v->jacobi ? "PCG" : "CG");
    report(label, summarise(times, reps), it_flops, it_bytes);

    /* a whole frame: right-hand side, the initial residual and the configured iterations, warm-started */
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_tomography_solve(t, s, c, v->iterations, 0.0, NULL, NULL);
        times[r] = wt_time_now() - a;
    }
    snprintf(label, sizeof label, "%s: frame (%d iterations)", name, v->iterations);
    stats fs = summarise(times, reps);
    /* rhs ≈ half an apply; initial residual = one apply */
    report(label, fs, flops * 1.5 + it_flops * v->iterations, bytes * 1.5 + it_bytes * v->iterations);
    if (!strcmp(name, "pcg3"))
        printf("  real-time goal: a %d-iteration pcg3 frame in 2 ms (500 Hz): measured %.2f ms = %.1fx the budget "
               "(p99 %.2f ms over %d frames)\n",
               v->iterations, fs.med * 1e3, fs.med / 2e-3, fs.p99 * 1e3, reps);

    if (v->fit_iterations > 0) {
        wt_fitting *f = NULL;
        wt_fitting_params fp = {.regularization = v->fit_regularization, .sampling = v->fit_sampling};
        st = wt_fitting_alloc_for(cli->ctx, t, &fp, &f);
        if (st < 0) goto out;
        double *a = calloc((size_t)sys->nact, sizeof *a), *phi = malloc((size_t)n * sizeof *phi);
        if (a && phi) {
            wt_tomography_layers(t, c, phi);
            for (int r = 0; r < reps; r++) {
                double a0 = wt_time_now();
                wt_fitting_solve(f, phi, a, v->fit_iterations, 0.0, NULL, NULL);
                times[r] = wt_time_now() - a0;
            }
            snprintf(label, sizeof label, "%s: fitting (%d CG iterations)", name, v->fit_iterations);
            stats s2 = summarise(times, reps);
            printf("%-34s %9.3f ms  [%7.3f, %7.3f, %7.3f]\n", label, s2.med * 1e3, s2.p10 * 1e3, s2.p90 * 1e3, s2.p99 * 1e3);
        }
        free(a);
        free(phi);
        wt_fitting_free(f);
    }
out:
    free(c);
    free(y);
    free(s);
    free(times);
    wt_tomography_free(t);
    return st;
}

/* Closed-loop speed (issue #3 goal: >= 5 frames/s at E-ELT size with pcg3): warm-up frames, then
 * timed frames, with the split by part. */
static int bench_loop(wt_cli *cli, const wt_system *sys, int frames)
{
    wt_loop *lp = NULL;
    wt_loop_options o = {.recon = WT_RECON_PCG3, .iterations = -1, .seed = sys->cfg->seed, .noise = 1};
    double t0 = wt_time_now();
    int st = wt_loop_alloc(cli->ctx, sys, &o, &lp);
    if (st < 0) return st;
    double setup = wt_time_now() - t0;
    const int warm = 3;
    for (int t = 0; t < warm && st >= 0; t++) st = wt_loop_step(lp);
    wt_loop_times a = wt_loop_get_times(lp);
    double *ft = malloc((size_t)frames * sizeof *ft);
    for (int t = 0; t < frames && st >= 0 && ft; t++) {
        double f0 = wt_time_now();
        st = wt_loop_step(lp);
        ft[t] = wt_time_now() - f0;
    }
    if (st >= 0 && ft) {
        wt_loop_times b = wt_loop_get_times(lp);
        stats s = summarise(ft, frames);
        printf("\nclosed loop, pcg3, %d frames after %d warm-up (set-up %.1f s): median %.1f ms/frame [%.1f, %.1f] = "
               "%.2f frames/s (goal >= 5)\n",
               frames, warm, setup, s.med * 1e3, s.p10 * 1e3, s.p90 * 1e3, 1.0 / s.med);
        printf("  mean per frame: atmosphere %.1f, sensors %.1f, reconstruction %.1f, control %.1f, evaluation %.1f ms\n",
               (b.atmosphere - a.atmosphere) / frames * 1e3, (b.sensors - a.sensors) / frames * 1e3,
               (b.reconstruction - a.reconstruction) / frames * 1e3, (b.control - a.control) / frames * 1e3,
               (b.evaluation - a.evaluation) / frames * 1e3);
    }
    free(ft);
    wt_loop_free(lp);
    return st;
}

typedef struct {
    const char *path;
    long reps, loop_frames;
    int skip_loop, skip_build;
} bench_args;

static int bench_option(wt_cli *cli, int argc, char **argv, int *i, void *user)
{
    bench_args *a = user;
    const char *o = argv[*i], *v;
    if (!strcmp(o, "--no-loop")) a->skip_loop = 1;
    else if (!strcmp(o, "--no-build")) a->skip_build = 1;
    else if (!strcmp(o, "--reps") || !strcmp(o, "--loop-frames")) {
        if (!(v = wt_cli_value(cli, argc, argv, i))) return -1;
        if (wt_cli_int(cli, o, v, 3, 100000, o[2] == 'r' ? &a->reps : &a->loop_frames) < 0) return -1;
    } else if (o[0] == '-' || a->path) return 0;
    else a->path = o;
    return 1;
}

/* MVM apply at the system's size against the memory bound, measured side by side: R (n_act x n_slopes
 * float32) must be streamed once per frame, so a STREAM copy of the same byte count (read + write of
 * R's size) sets the scale. Values do not change the time of a GEMV, so R is filled with a pattern. */
static int bench_mvm_apply(wt_cli *cli, const wt_system *sys, int reps)
{
    const int64_t na = sys->nact, ns = sys->nslopes;
    const size_t n = (size_t)na * (size_t)ns;
    float *R = malloc(n * sizeof *R), *C = malloc(n * sizeof *C), *x = malloc((size_t)ns * sizeof *x),
          *y = malloc((size_t)na * sizeof *y), *y16 = malloc((size_t)na * sizeof *y16);
    uint16_t *H[2] = {malloc(n * sizeof(uint16_t)), malloc(n * sizeof(uint16_t))};
    float *Hc[2] = {malloc((size_t)na * sizeof(float)), malloc((size_t)na * sizeof(float))};
    double *tg = malloc((size_t)reps * sizeof *tg), *tc = malloc((size_t)reps * sizeof *tc);
    double *th[2] = {malloc((size_t)reps * sizeof(double)), malloc((size_t)reps * sizeof(double))};
    const int prec[2] = {WT_PREC_F16, WT_PREC_BF16};
    int st = WT_OK;
    if (!R || !C || !x || !y || !y16 || !tg || !tc || !H[0] || !H[1] || !Hc[0] || !Hc[1] || !th[0] || !th[1]) {
        st = wt_error_set(cli->ctx, WT_ERR_NOMEM, __FILE__, __LINE__, "bench: out of memory for a %.2f GB matrix",
                          3.0 * n * 4.0 / 1e9);
        goto out;
    }
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; i++) R[i] = C[i] = (float)((i * 2654435761u) % 1000) * 1e-3f;
    for (int64_t i = 0; i < ns; i++) x[i] = (float)(i % 7) * 1e-6f;
    const int nth = wt_context_threads(cli->ctx);
    /* the runtime's own apply (core/solve/mvm.h) on containers that borrow R and its 16-bit copies */
    const wt_mvm view = {.ctx = cli->ctx, .commands = WT_MVM_LAYER_VALUES, .nact = na, .nslopes = ns, .R = R};
    wt_mvm v16[2];
    for (int k = 0; k < 2; k++) {
        wt_half_pack(prec[k], na, ns, R, H[k], Hc[k], nth);
        v16[k] = (wt_mvm){.ctx = cli->ctx, .commands = WT_MVM_LAYER_VALUES, .nact = na, .nslopes = ns,
                          .precision = prec[k], .Rh = H[k], .Rc = Hc[k], .nthreads = nth};
    }
    double err[2] = {0, 0}, ymax = 0;
    for (int r = 0; r < reps; r++) {
        double a = wt_time_now();
        wt_mvm_apply(&view, x, NULL, y);
        tg[r] = wt_time_now() - a;
        for (int k = 0; k < 2; k++) {
            a = wt_time_now();
            wt_mvm_apply(&v16[k], x, NULL, y16);
            th[k][r] = wt_time_now() - a;
            if (r == 0)
                for (int64_t i = 0; i < na; i++) {
                    err[k] = fmax(err[k], fabs((double)y16[i] - y[i]));
                    ymax = fmax(ymax, fabs((double)y[i]));
                }
        }
        a = wt_time_now();
#pragma omp parallel for schedule(static)
        for (size_t i = 0; i < n; i++) C[i] = R[i];
        tc[r] = wt_time_now() - a;
    }
    stats g = summarise(tg, reps), c = summarise(tc, reps);
    double bytes = 4.0 * (double)n;
    printf("\nMVM apply, R %lld x %lld float32 (%.2f GB), %d OpenBLAS / %d OpenMP threads, %d repetitions side by side:\n",
           (long long)na, (long long)ns, bytes / 1e9, openblas_get_num_threads(), nth, reps);
    printf("  sgemv          %8.2f ms  [%.2f, %.2f]  reads R once: %.1f GB/s\n", g.med * 1e3, g.p10 * 1e3, g.p90 * 1e3,
           bytes / g.med / 1e9);
    for (int k = 0; k < 2; k++) {
        stats h = summarise(th[k], reps);
        printf("  %s GEMV     %8.2f ms  [%.2f, %.2f]  reads %.2f GB: %.1f GB/s; %.2fx faster than sgemv; "
               "max |dy| / max |y| = %.1e\n",
               wt_prec_name(prec[k]), h.med * 1e3, h.p10 * 1e3, h.p90 * 1e3, bytes / 2e9, bytes / 2.0 / h.med / 1e9,
               g.med / h.med, ymax > 0 ? err[k] / ymax : 0.0);
    }
    printf("  STREAM copy    %8.2f ms  [%.2f, %.2f]  of the float32 bytes (read + write): %.1f GB/s\n", c.med * 1e3,
           c.p10 * 1e3, c.p90 * 1e3, 2.0 * bytes / c.med / 1e9);
    printf("  sgemv bandwidth / copy bandwidth = %.2f; a 500 Hz MVM would need %.0f GB/s (fp32), %.0f GB/s (16-bit)\n",
           (bytes / g.med) / (2.0 * bytes / c.med), bytes * 500.0 / 1e9, bytes * 250.0 / 1e9);
out:
    free(R), free(C), free(x), free(y), free(y16), free(tg), free(tc);
    for (int k = 0; k < 2; k++) free(H[k]), free(Hc[k]), free(th[k]);
    return st;
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
    bench_args args = {NULL, 50, 20, 0, 0};
    int rc = wt_cli_parse(&cli, argc, argv, bench_option, &args);
    if (rc >= 0) {
        wt_cli_done(&cli);
        return rc;
    }
    rc = 0;
    const char *path = args.path;
    int reps = (int)args.reps, loop_frames = (int)args.loop_frames, skip_loop = args.skip_loop;
    if (!path && !cli.config_path) path = "data/presets/eelt-mcao.cfg";
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    int st = wt_cli_read_config(&cli, path, &cfg);
    if (st < 0) goto out;
    st = wt_system_alloc(cli.ctx, cfg, &sys);
    if (st < 0) goto out;
    int threads = wt_context_threads(cli.ctx);
    printf("wavetomo bench: %s, %d OpenMP threads, %d OpenBLAS threads, %d repetitions\n", cfg->path, threads,
           openblas_get_num_threads(), reps);
    double bw = triad_bandwidth(5), gf = dgemm_rate();
    printf("machine: triad bandwidth %.1f GB/s, DGEMM %.1f GFlop/s (n = 2048, OpenBLAS)\n", bw / 1e9, gf / 1e9);
    printf("%-34s %9s     %s\n", "kernel", "median", "[p10, p90, p99] ms, work per call, implied rates");
    st = bench_variant(&cli, sys, &cfg->pcg3, "pcg3", reps);
    if (st < 0) goto out;
    st = bench_variant(&cli, sys, &cfg->cg9, "cg9", reps < 20 ? reps : 20);
    if (st < 0) goto out;
    /* the build first: its peak memory is read from the process's high-water mark, which the GEMV's
     * 2 x 2.3 GB buffers would otherwise set */
    if (!args.skip_build && (st = bench_mvm_build(&cli, sys)) < 0) goto out;
    if (!skip_loop && (st = bench_loop(&cli, sys, loop_frames)) < 0) goto out;
    st = bench_mvm_apply(&cli, sys, reps < 10 ? reps : 10);
out:
    if (st < 0) rc = wt_cli_fail(&cli, st);
    wt_system_free(sys);
    wt_config_free(cli.ctx, cfg);
    wt_cli_done(&cli);
    return rc;
}
