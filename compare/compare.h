/* compare/compare.h: the cases of a comparison (SPEC §10): one closed-loop run (sim/loop.h) per
 * reconstructor and per value of a swept key, on identical turbulence and noise (the same seed), reduced
 * to the figures `wavetomo compare` reports: per-direction LE Strehl (Maréchal, SPEC §8) and residual WFE,
 * their on-axis value and field means, the time per frame by part, and the reconstructor's memory.
 *
 * A plan names the cases (methods x sweep values) and what makes their results comparable (the
 * configuration's canonical text hash, the seed, the frames); a stored plan that differs from the one
 * asked for is refused for resumption, naming what differs (compare --resume).
 */
#ifndef WT_COMPARE_H
#define WT_COMPARE_H

#include "../core/solve/mvm.h"
#include "../sim/loop.h"

#define WT_COMPARE_NPART 6     /* atmosphere, sensors, reconstruction, fitting, control, evaluation */
#define WT_COMPARE_MAXM 4
#define WT_COMPARE_MAXV 32

typedef struct wt_compare_result {
    double strehl[WT_MAX_EVAL], wfe[WT_MAX_EVAL]; /* LE Strehl and WFE [nm] per evaluation direction */
    double on_axis, field, wfe_field;             /* on-axis Strehl, field-mean Strehl, field-rms WFE [nm] */
    double parts[WT_COMPARE_NPART];               /* wall time per frame by part [ms] */
    double total, setup, memory;                  /* ms per frame, set-up [s] (incl. an MVM build), bytes */
    /* the long-exposure PSFs (sim/psf.h; all 0 when sim.psf_interval_frames = 0) */
    double psf_strehl[WT_MAX_EVAL];               /* PSF-peak Strehl per evaluation direction */
    double psf_on_axis, psf_field;                /* on-axis, field mean */
    double psf_frames, psf_pixels;                /* frames taken, image side n */
    double psf_pixel_lod, psf_pixel_mas;          /* pixel scale [λ/D], [mas] */
    double psf_fft;                               /* the padded FFT's size N */
    double psf_ms;                                /* wall time of the images per simulated frame [ms] */
    double frames;                                /* frames run (loop.frames of the case) */
    double lgs_gain_along, lgs_gain_across;       /* the diffractive LGS centroiders' in-loop gain (mean over the
                                                     LGS; core/model/sensing.h); 0 without diffractive LGS */
    int done;                                     /* 1: the case ran to its last frame */
} wt_compare_result;

/* Names of the parts of wt_compare_result.parts, in order. */
const char *wt_compare_part_name(int k);

/* Called after every frame with the running mean of the field short-exposure Strehl; return non-zero to
 * stop the case (it is then not done: WT_ERR_INTERRUPTED). */
typedef int (*wt_compare_frame_fn)(void *user, long frame, double mean_field_strehl);

/* What a case keeps beside its numbers, for the report's figures (NULL pointers: not kept). */
typedef struct wt_compare_series {
    double *wfe;  /* [loop.frames], caller's: the field-rms residual of each frame, sqrt(mean_j σ_j²) [nm] */
    float *psf;   /* set by wt_compare_run when sim.psf_interval_frames > 0: the LE PSFs [neval n n] (psf.h's layout),
                   * allocated in ctx (wt_free(ctx, ·) by the caller); NULL otherwise */
    struct wt_adapt *learned; /* set when the loop learned its atmosphere (or followed a night's truth): the record of
                               * its updates (sim/adapt.h, wt_adapt_free by the caller); NULL otherwise */
} wt_compare_series;

/* Run one case: the closed loop of reconstructor `kind` (mvm: the matrix `mvm`, built in build_s seconds)
 * on sys for its configuration's loop.frames and noise with random seed `seed` (turbulence and noise: the
 * loop's only random input), and reduce it into *res (res->done = 1); with sim.psf_interval_frames > 0 the long-exposure
 * PSFs too (sim/psf.h). ser: NULL, or what to keep of the frames. */
int wt_compare_run(wt_context *ctx, const wt_system *sys, int kind, const wt_mvm *mvm, double build_s, uint64_t seed,
                   wt_compare_frame_fn fn, void *user, wt_compare_result *res, wt_compare_series *ser);
/* The same with a learning MVM loop's rebuild callback (sim/adapt.h; NULL: none). */
int wt_compare_run_rebuild(wt_context *ctx, const wt_system *sys, int kind, const wt_mvm *mvm, double build_s,
                           uint64_t seed, wt_adapt_rebuild_fn rebuild, void *rebuild_user, wt_compare_frame_fn fn,
                           void *user, wt_compare_result *res, wt_compare_series *ser);

/* ---- statistics over seeds (`compare --seeds N`) -----------------------------------------------------------
 * Each seed is an independent realisation of the turbulence and noise; every method runs on the same seeds,
 * so methods are compared by the paired difference d_s = x_s(A) − x_s(B), whose scatter is much smaller than
 * that of either x_s (the realisation's luck is common to both). Standard error of a mean of n values:
 * s / √n with s the sample standard deviation (n − 1); 0 for n < 2. A difference is "within the noise" when
 * |mean| < 2 SE (about the 95 % two-sided level). */
#define WT_COMPARE_MAXS 64
enum { WT_METRIC_ON_AXIS, WT_METRIC_FIELD, WT_METRIC_WFE, WT_NMETRICS };
/* The figure of merit k of a result: on-axis LE Strehl, field-mean LE Strehl, field-rms WFE [nm]. */
double wt_compare_metric(const wt_compare_result *r, int k);
const char *wt_compare_metric_name(int k); /* "strehl_le_on_axis", "strehl_le_field", "wfe_le_field" */
/* Mean and standard error of x[0..n). */
void wt_compare_mean_se(const double *x, int n, double *mean, double *se);

typedef struct wt_compare_summary {
    wt_compare_result mean;    /* every field averaged over the seeds done; done = 1 when all ns are */
    double se[WT_NMETRICS];    /* standard error of the mean of each metric */
    int nseeds;                /* seeds done */
} wt_compare_summary;
/* Reduce the per-seed results r[0..ns) of one method and sweep value (only those done count). */
void wt_compare_summarise(const wt_compare_result *r, int ns, wt_compare_summary *out);
/* Paired difference of metric k, a − b, over the seeds done in both: mean, standard error, seeds used. */
void wt_compare_paired(const wt_compare_result *a, const wt_compare_result *b, int ns, int k, double *mean, double *se,
                       int *n);

typedef struct wt_compare_plan {
    char methods[256];       /* "mvm,pcg3,cg9" */
    char sweep_key[128];     /* "" without a sweep */
    char sweep_values[2048]; /* "20,50,100" ("" without a sweep) */
    char config_sha256[65];  /* SHA-256 of the canonical text of the first case's configuration */
    char seeds[1024];        /* "1,2,3" with several seeds ("" with one: `seed`) */
    uint64_t seed;
    int64_t frames;
} wt_compare_plan;

/* The plan of methods[nm] x values[nv] (nv = 0: no sweep) x seeds[ns] on cfg (the first case's
 * configuration; ns = 1: its seed). */
void wt_compare_plan_make(wt_compare_plan *p, int nm, char *const *methods, const char *key, int nv,
                          char *const *values, int ns, const uint64_t *seeds, const wt_config *cfg);
/* WT_OK when `stored` (read from `source`) describes the same cases and the same runs as `want`; else
 * WT_ERR_FORMAT with a message naming every field that differs and both values. */
int wt_compare_plan_check(wt_context *ctx, const char *source, const wt_compare_plan *stored,
                          const wt_compare_plan *want);

#endif
