/* core/la/fft.h: how the reconstructor's hot 2-D real FFTs are planned — FFTW_ESTIMATE, or measured plans
 * carried by an FFTW wisdom file (FFTW manual §4.2 "Words of Wisdom"; docs/design.md "FFT plans").
 *
 * The full von Kármán prior (core/op/prior.c) and the fourier preconditioner (core/model/precond.c) each run
 * an n x n r2c + c2r pair per layer and iteration. FFTW_ESTIMATE picks the algorithm from a model, without
 * timing: the same plan, hence the same bits, on every machine. A measured plan (FFTW_MEASURE) is faster
 * at the E-ELT's n = 128, but timing depends on the machine and the moment, so two runs could pick
 * different algorithms and round differently. Wisdom separates the two: `wavetomo wisdom` measures once and
 * stores the chosen algorithms in a file; a run plans from that file alone (FFTW_WISDOM_ONLY), so the same
 * file gives the same plans and the same bits, and the file's SHA-256 (recon.fft_wisdom_sha256) travels in
 * every output's configuration.
 *
 * FFTW's wisdom is one global store per process (the planner is not thread-safe: plan at set-up, from one
 * thread). So that a wisdom file affects only the plans made here — not the simulator's ESTIMATE plans nor a
 * host program's own FFTW use — every planning call saves the store, replaces it by this object's wisdom,
 * plans, and puts the caller's store back.
 */
#ifndef WT_LA_FFT_H
#define WT_LA_FFT_H

#include "../base/base.h"

/* fftw3.h's plan type, declared here without the header: its fftw_complex is double[2] or C99 double complex
 * depending on whether <complex.h> came first, and includers of this header use both. */
struct fftw_plan_s;

typedef struct wt_fft_wisdom wt_fft_wisdom;

/* Read the wisdom file `path` (at most WT_FFT_WISDOM_MAX bytes) and check that FFTW accepts it. sha256: NULL
 * or "" (not checked), or the 64 hex digits the file must hash to. `key` names the configuration key the path
 * came from, for messages (e.g. "recon.fft_wisdom"). Errors: WT_ERR_IO (missing or unreadable file),
 * WT_ERR_FORMAT (not FFTW wisdom, or another SHA-256 than `sha256`). Allocates; wt_fft_wisdom_free. */
#define WT_FFT_WISDOM_MAX ((size_t)1 << 20)
int wt_fft_wisdom_read(wt_context *ctx, const char *path, const char *sha256, const char *key, wt_fft_wisdom **out);
/* An empty wisdom that learns (wt_fft_wisdom_learn), for `wavetomo wisdom`. */
int wt_fft_wisdom_learner(wt_context *ctx, wt_fft_wisdom **out);
void wt_fft_wisdom_free(wt_fft_wisdom *w);
/* Measure the n x n pair (FFTW_MEASURE on scratch arrays, which the measurement overwrites) and add the result to
 * learner w's text; the store of the process is left as it was. WT_ERR_INVALID for a wisdom read from a file. */
int wt_fft_wisdom_learn(wt_context *ctx, wt_fft_wisdom *w, int n);
/* Write the wisdom's text to `path` through a temporary file and rename (nothing half-written). */
int wt_fft_wisdom_write(wt_context *ctx, const wt_fft_wisdom *w, const char *path);
/* The wisdom's FFTW text (NUL-terminated; empty for a learner that has measured nothing) and its SHA-256 (hex),
 * the file's when read, the text's when learnt. */
const char *wt_fft_wisdom_text(const wt_fft_wisdom *w);
const char *wt_fft_wisdom_sha256(const wt_fft_wisdom *w);
/* FFTW's version and build ("fftw-3.3.10-sse2-avx"): wisdom holds only for the FFTW that made it. */
const char *wt_fft_version(void);

/* The n x n (row-major) pair: *r2c from re (n²) to c (n (n/2 + 1) complex values), *c2r back from c to re (destroying c, FFTW's
 * default), both out of place, executed later with fftw_execute_dft_r2c/_c2r on arrays of the same alignment.
 * w NULL: FFTW_ESTIMATE, arrays untouched. Otherwise FFTW_MEASURE | FFTW_WISDOM_ONLY from w's wisdom alone,
 * arrays untouched; a pair that w does not hold (another size, machine or FFTW version) is WT_ERR_CONFIG naming
 * w's file and n. `what` names the caller for messages. The caller destroys the plans (fftw_destroy_plan). */
int wt_fft_plan_pair(wt_context *ctx, wt_fft_wisdom *w, int n, double *re, void *c, const char *what,
                     struct fftw_plan_s **r2c, struct fftw_plan_s **c2r);

#endif
