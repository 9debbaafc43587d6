/* compare/bench.h: kernel timings of the reconstructor (`wavetomo bench`, docs/results.md §2), with the
 * flop and byte counts they imply and the machine's own limits measured the same way.
 *
 * What is timed: one application of the tomography normal operator M = Σ Ãᵀ Ĉ⁻¹ Ã + αD (SPEC §6, paper
 * eq. eqn_lse), one (P)CG iteration, a whole frame (right-hand side + the configured iterations, warm
 * started), the cg9 fitting step (paper eq. fit_step_min), the closed loop (sim/loop.h), and the
 * MVM apply (core/solve/mvm.h, a float32 GEMV) next to a STREAM copy of the same bytes. The machine's
 * scale: a STREAM triad (memory bandwidth) and an OpenBLAS DGEMM (flop rate). Every timing is a
 * distribution over repetitions, summarised by its median and 10th/90th/99th percentiles.
 *
 * These functions allocate their own buffers (they are set-up-time tools, not per-frame code), read no
 * configuration (the caller passes parameter structs) and print nothing: the driver (compare/cmd_bench.c) does.
 */
#ifndef WT_BENCH_H
#define WT_BENCH_H

#include "../core/model/reconstructor.h"
#include "../sim/loop.h"

/* A timing distribution [s]. */
typedef struct wt_bench_stats {
    double med, p10, p90, p99;
} wt_bench_stats;

/* Sorts t[0..n) in place and returns its median and percentiles (n ≥ 1). */
wt_bench_stats wt_bench_summarise(double *t, int n);

/* STREAM triad a = b + s c over 3 x 256 MB (OpenMP, the context's threads): best of reps [bytes/s];
 * 0 when out of memory. */
double wt_bench_triad_bandwidth(wt_context *ctx, int reps);
/* OpenBLAS DGEMM of n = 2048: best of 3 [flop/s]; 0 when out of memory. */
double wt_bench_dgemm_rate(void);

/* The tomography kernels of one variant. */
typedef struct wt_bench_tomography {
    int64_t nunknowns;        /* wavelet coefficients */
    double setup;             /* operator set-up incl. the preconditioner [s] */
    double flops, bytes;      /* work of one apply of M (wt_tomography_cost) */
    double it_flops, it_bytes; /* work of one (P)CG iteration */
    wt_bench_stats apply;     /* one apply of M */
    wt_bench_stats iteration; /* one iteration: (9 iterations − 1) / 8 from the same start */
    wt_bench_stats frame;     /* rhs + par->iterations iterations, warm started */
    /* Where a frame goes: the same frames once more with the tomography's stages timed (wt_tomography_profile_*),
     * summed over prof_frames frames */
    int prof_frames;
    wt_tomography_stage stage[WT_TOMO_NSTAGES];
    int has_fitting;          /* cg9: the fitting was timed */
    wt_bench_stats fitting;   /* par->fit_iterations CG iterations of the fitting */
    /* recon.predict's shift (core/op/shift.h) of the variant's layers by the model's wind over the lead (the
     * configured one, else the loop's delay), whether or not CONFIG predicts; median of at least 200 */
    int shift_moving;         /* layers that move (0: no wind, not timed) */
    double shift_flops, shift_bytes; /* per call: the transforms and ramps; the layers read and written once */
    wt_bench_stats shift;
    /* recon.predict_integrator = "layers": one frame of the integrator on the layers (wt_shift_integrator_step: the
     * estimate to its spectra, the update, the new state back), median of at least 200 */
    double integrate_flops, integrate_bytes;
    wt_bench_stats integrate;
} wt_bench_tomography;

/* Times the variant described by par (name "pcg3" or "cg9" labels its operators) reps times on seeded
 * random coefficients and slopes. */
int wt_bench_tomography_run(wt_context *ctx, const wt_system *sys, const wt_reconstructor_params *par,
                            const char *name, int reps, wt_bench_tomography *out);

/* Paired timing: two reconstructors A and B of one kind (WT_RECON_PCG3 or CG9; two
 * configurations, of one system or of two) applied frame after frame, alternately — A B, B A, A B, … (the
 * order alternates so that neither side always runs on the caches and clock the other left) — to the
 * same slopes: a seeded sequence s_t = 0.9 s_{t−1} + 0.44 n_t, n_t white with 1 µrad rms (temporally
 * correlated like a loop's, so the warm start continues from a nearby frame; fixed-iteration solves do not
 * depend on the values). The host's speed changes between runs and within one (other jobs, frequency
 * scaling); the ratio of two frames measured side by side does not change with it, so the per-pair ratio
 * B / A is the figure to quote, with its spread. `warm` frames per side first (untimed), then `pairs`
 * pairs. Each side's slopes have its own system's length; when the two systems have the same slopes and
 * actuators the sides see the same values and the commands are compared. */
typedef struct wt_bench_pair {
    double setup[2];                    /* wt_reconstructor_alloc of each side [s] */
    double memory[2];                   /* wt_reconstructor_bytes of each side [bytes] */
    wt_bench_stats frame[2];            /* wt_reconstructor_apply [s] */
    wt_bench_stats tomography[2];       /* its tomography part (rhs + (P)CG + layers) [s] */
    wt_bench_stats fitting[2];          /* its fitting part (cg9; 0 for pcg3) [s] */
    wt_bench_stats ratio_frame, ratio_tomography, ratio_fitting; /* B / A per pair [-] (fitting: 0 for pcg3) */
    double command_diff;                /* ‖a_B − a_A‖ / ‖a_A‖ of the last frame; −1 when the systems differ */
    int has_fitting;                    /* cg9: fit below holds each side's fitting set-up */
    int fit_solver[2];                  /* WT_FIT_CG or WT_FIT_CHOLESKY */
    wt_fitting_stats fit[2];            /* the direct solver's set-up (zeros for CG) */
    wt_tomography_stage stage[2][WT_TOMO_NSTAGES]; /* each side's tomography stages, summed over the pairs */
} wt_bench_pair;

int wt_bench_pair_run(wt_context *ctx, const wt_system *const sys[2], const wt_reconstructor_params par[2], int kind,
                      int warm, int pairs, wt_bench_pair *out);

/* The closed loop: warm frames, then `frames` timed frames. */
typedef struct wt_bench_loop {
    double setup;            /* wt_loop_alloc_params [s] */
    wt_bench_stats frame;    /* per timed frame */
    wt_loop_times per_frame; /* mean time per timed frame of each part [s] */
} wt_bench_loop;

int wt_bench_loop_run(wt_context *ctx, const wt_system *sys, const wt_loop_options *opt, const wt_loop_params *par,
                      int warm, int frames, wt_bench_loop *out);

/* The MVM apply at nact x nslopes (R filled with a pattern: values do not change a GEMV's time), the same
 * apply from fp16 and bf16 copies of R, and a STREAM copy of R's bytes, alternated reps times. */
typedef struct wt_bench_mvm {
    double bytes;          /* bytes of R (float32) */
    wt_bench_stats sgemv;  /* the runtime's apply */
    wt_bench_stats half[2]; /* the same apply with R stored in half_prec[k] (recon.mvm_precision) */
    int half_prec[2];      /* WT_PREC_F16, WT_PREC_BF16 */
    double half_error[2];  /* max |y16 - y| / max |y| of the first repetition */
    wt_bench_stats copy;   /* read + write of R's bytes */
} wt_bench_mvm;

int wt_bench_mvm_apply(wt_context *ctx, int64_t nact, int64_t nslopes, int reps, wt_bench_mvm *out);

/* The diffractive sensing of one kind (WT_SENSOR_LGS or WT_SENSOR_NGS) of sys (core/model/sensing.h): per
 * frame, every diffractive sensor of that kind in turn, images (wt_spot_image) + detector noise
 * (wt_spot_noise, the loop's streams) + centroider (wt_centroid_apply), on a seeded OPD of 100 nm rms
 * white per pupil sample (the time does not depend on the values, except the Poisson sampler's, which a
 * faint image dominates either way); one warm frame, then reps timed frames on the context's threads. */
typedef struct wt_bench_sensing {
    int nsensors;              /* diffractive sensors of the kind (0: nothing timed) */
    int64_t nsub;              /* their subapertures in all */
    int np, N, ns, k;          /* pupil samples, FFT size, pixels, cells per pixel (first sensor) */
    double setup;              /* Σ of their set-up times (in wt_system_alloc) [s] */
    double memory;             /* Σ wt_sensing_memory [bytes] */
    double flops, bytes;       /* per subaperture per noise-free image, wt_spot_cost (first sensor) */
    wt_bench_stats frame;      /* per frame, all the sensors: images + noise + centroider */
    wt_bench_stats images, noise, centroid; /* the three parts, per frame */
    double cpu;                /* process CPU time per timed frame, all threads [s]: / threads = the wall
                                  time on idle cores (the wall medians grow with the machine's load) */
} wt_bench_sensing;

int wt_bench_sensing_run(wt_context *ctx, const wt_system *sys, int kind, int reps, wt_bench_sensing *out);

/* The sodium layer in time (sim/sodium_drive.h) for the diffractive LGS of sys: the truth's spot tables of a
 * new profile (wt_sensing_set_sodium, every LGS; the set-up profile moved up by 500 m), and the oracle's reference
 * rebuilt from them (wt_sensing_rebuild_reference: I0 and its derivatives, the centroider and its covariance): the
 * first rebuild, which makes the FFTs and keeps the profile-independent cells (wt_spot_keep_reference), then reps
 * rebuilds from the kept cells (what the loop pays every lgs.wfs.reference_update_s); the pixels' reference's per-frame
 * accumulation and rebuild (reps of each). The sensors are restored to
 * their set-up profile and reference after (wt_sensing_restore). */
typedef struct wt_bench_sodium {
    int nsensors;               /* diffractive LGS (0: nothing timed) */
    int64_t nsub;
    wt_bench_stats tables;      /* the truth's tables of every LGS [s] */
    double full;                /* the first reference rebuild of every LGS (FFTs; cells kept) [s] */
    wt_bench_stats reference;   /* a rebuild from the kept cells, every LGS [s] */
    double cpu_tables, cpu_reference; /* process CPU time per rebuild of each, all threads [s] */
    /* lgs.wfs.reference = pixels (sensing.h "wt_sensing_pixels_*"), every LGS: a frame's accumulation of the
     * re-centred images (the reference images with sub-pixel slopes), and a rebuild from the mean of 2 frames (mean,
     * derivatives, matched filter, covariance); the start (the set-up reference's derivatives for the anchor) once */
    wt_bench_stats accumulate, pixels;
    double pixels_start, cpu_accumulate, cpu_pixels;
    /* lgs.wfs.gain_update_s (sensing.h "wt_sensing_gain_*"), every LGS, on frames of the reference images: the
     * first estimate (the spot model's fit from the reference, 4 Gauss–Newton iterations) and reps more (from the
     * last estimate, 2 iterations: what the loop pays every gain_update_s, C_E's refresh not included) */
    double gain_first, cpu_gain;
    wt_bench_stats gain;
} wt_bench_sodium;

int wt_bench_sodium_run(wt_context *ctx, const wt_system *sys, int reps, wt_bench_sodium *out);

#endif
