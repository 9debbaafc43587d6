/* core/la/fft.c: FFTW plans for the reconstructor's 2-D real transforms, from FFTW_ESTIMATE or from a wisdom
 * file (see fft.h; FFTW manual §4.2 and §4.3.2 "Planner Flags": FFTW_WISDOM_ONLY returns NULL instead of
 * planning anew, so a plan made with it is exactly the stored one). */
#include "fft.h"

#include <fftw3.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../base/sha256.h"

struct wt_fft_wisdom {
    wt_context *ctx;
    char *text;       /* FFTW's wisdom text, NUL-terminated (malloc: FFTW's export allocates with malloc) */
    char sha256[65];  /* of the file's bytes, or of the learnt text */
    char source[1100]; /* "'path' (key)" or "the wisdom being learnt", for messages */
    int learn;
};

/* FFTW's store is process-global: keep the caller's aside (*saved) while ours is in place. Returns 0 when
 * FFTW refused `text` (the caller's store is back then). */
static int store_swap_in(const char *text, char **saved)
{
    *saved = fftw_export_wisdom_to_string();
    fftw_forget_wisdom();
    if (text && *text && !fftw_import_wisdom_from_string(text)) {
        fftw_forget_wisdom();
        if (*saved) fftw_import_wisdom_from_string(*saved);
        free(*saved);
        *saved = NULL;
        return 0;
    }
    return 1;
}

static void store_restore(char *saved)
{
    fftw_forget_wisdom();
    if (saved && !fftw_import_wisdom_from_string(saved)) fftw_forget_wisdom(); /* its own text: never refused */
    free(saved);
}

static int wisdom_new(wt_context *ctx, wt_fft_wisdom **out)
{
    *out = wt_calloc(ctx, 1, sizeof **out);
    if (!*out) return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for an FFT wisdom");
    (*out)->ctx = ctx;
    return WT_OK;
}

int wt_fft_wisdom_read(wt_context *ctx, const char *path, const char *sha256, const char *key, wt_fft_wisdom **out)
{
    int st = WT_OK;
    *out = NULL;
    if (!path || !*path) return WT_ERROR(ctx, WT_ERR_INVALID, "FFT wisdom: no file name (%s)", key ? key : "path");
    FILE *f = fopen(path, "rb");
    if (!f)
        return WT_ERROR(ctx, WT_ERR_IO, "%s: cannot open the FFT wisdom file '%s': %s (make one on this machine with "
                        "`wavetomo wisdom CONFIG --out FILE`, or set the key to \"\" for FFTW_ESTIMATE plans)",
                        key ? key : "FFT wisdom", path, strerror(errno));
    wt_fft_wisdom *w = NULL;
    WT_TRY(wisdom_new(ctx, &w));
    snprintf(w->source, sizeof w->source, "'%s' (%s)", path, key ? key : "FFT wisdom");
    w->text = malloc(WT_FFT_WISDOM_MAX + 1);
    if (!w->text) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory reading the FFT wisdom %s", w->source);
        goto fail;
    }
    const size_t n = fread(w->text, 1, WT_FFT_WISDOM_MAX + 1, f);
    if (ferror(f)) {
        st = WT_ERROR(ctx, WT_ERR_IO, "cannot read the FFT wisdom %s: %s", w->source, strerror(errno));
        goto fail;
    }
    if (n > WT_FFT_WISDOM_MAX) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT, "the FFT wisdom %s is larger than %zu bytes: not a wisdom file",
                      w->source, WT_FFT_WISDOM_MAX);
        goto fail;
    }
    w->text[n] = '\0';
    wt_sha256_hex(w->text, n, w->sha256);
    if (sha256 && *sha256 && strcmp(sha256, w->sha256)) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT, "the FFT wisdom %s has SHA-256 %s, but the configuration records %s "
                      "(%s_sha256): the file changed since the configuration was written", w->source, w->sha256,
                      sha256, key ? key : "the wisdom key");
        goto fail;
    }
    if (strlen(w->text) != n || !*w->text) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT, "the FFT wisdom %s is %s: not FFTW wisdom", w->source,
                      n ? "binary" : "empty");
        goto fail;
    }
    char *saved;
    if (!store_swap_in(w->text, &saved)) {
        st = WT_ERROR(ctx, WT_ERR_FORMAT, "the FFT wisdom %s is not FFTW (double precision) wisdom: FFTW %s refused "
                      "it; make one on this machine with `wavetomo wisdom CONFIG --out FILE`", w->source,
                      fftw_version);
        goto fail;
    }
    store_restore(saved);
    fclose(f);
    *out = w;
    return WT_OK;
fail:
    fclose(f);
    wt_fft_wisdom_free(w);
    return st;
}

int wt_fft_wisdom_learner(wt_context *ctx, wt_fft_wisdom **out)
{
    int st = WT_OK;
    *out = NULL;
    wt_fft_wisdom *w = NULL;
    WT_TRY(wisdom_new(ctx, &w));
    w->learn = 1;
    snprintf(w->source, sizeof w->source, "the wisdom being learnt");
    w->text = calloc(1, 1);
    if (!w->text) {
        wt_fft_wisdom_free(w);
        return WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for an FFT wisdom");
    }
    wt_sha256_hex("", 0, w->sha256);
    *out = w;
fail:
    return st;
}

void wt_fft_wisdom_free(wt_fft_wisdom *w)
{
    if (!w) return;
    free(w->text);
    wt_free(w->ctx, w);
}

const char *wt_fft_wisdom_text(const wt_fft_wisdom *w) { return w->text; }
const char *wt_fft_wisdom_sha256(const wt_fft_wisdom *w) { return w->sha256; }
const char *wt_fft_version(void) { return fftw_version; }

int wt_fft_wisdom_write(wt_context *ctx, const wt_fft_wisdom *w, const char *path)
{
    char tmp[4200];
    if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
        return WT_ERROR(ctx, WT_ERR_INVALID, "FFT wisdom: the path '%s' is too long", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) return WT_ERROR(ctx, WT_ERR_IO, "cannot create '%s': %s", tmp, strerror(errno));
    const size_t n = strlen(w->text);
    const int ok = fwrite(w->text, 1, n, f) == n;
    if (fclose(f) != 0 || !ok || rename(tmp, path) != 0) {
        const int e = errno;
        remove(tmp);
        return WT_ERROR(ctx, WT_ERR_IO, "cannot write the FFT wisdom '%s': %s", path, strerror(e));
    }
    return WT_OK;
}

/* Measure the pair on scratch arrays (FFTW_MEASURE overwrites them) at 64-byte boundaries, as the arrays the
 * callers plan on (core/op/prior.c, core/model/precond.c): a stored algorithm may use SIMD loads that need the
 * alignment it was measured with, and FFTW_WISDOM_ONLY finds no plan for arrays that lack it. */
static int learn_pair(wt_context *ctx, wt_fft_wisdom *w, int n)
{
    const size_t nh = (size_t)n / 2 + 1;
    double *re = aligned_alloc(64, ((size_t)n * (size_t)n * sizeof *re + 63) / 64 * 64);
    fftw_complex *c = aligned_alloc(64, ((size_t)n * nh * sizeof *c + 63) / 64 * 64);
    fftw_plan a = NULL, b = NULL;
    int st = WT_OK;
    if (!re || !c) st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory measuring the %d x %d FFT pair", n, n);
    else {
        a = fftw_plan_dft_r2c_2d(n, n, re, c, FFTW_MEASURE);
        b = fftw_plan_dft_c2r_2d(n, n, c, re, FFTW_MEASURE);
        if (!a || !b) st = WT_ERROR(ctx, WT_ERR_LIBRARY, "FFTW could not measure the %d x %d r2c/c2r pair", n, n);
    }
    if (a) fftw_destroy_plan(a);
    if (b) fftw_destroy_plan(b);
    free(re);
    free(c);
    if (st < 0) return st;
    char *text = fftw_export_wisdom_to_string();
    if (!text) return WT_ERROR(ctx, WT_ERR_NOMEM, "FFTW could not export the wisdom of the %d x %d pair", n, n);
    free(w->text);
    w->text = text;
    wt_sha256_hex(text, strlen(text), w->sha256);
    return WT_OK;
}

int wt_fft_wisdom_learn(wt_context *ctx, wt_fft_wisdom *w, int n)
{
    if (!w->learn) return WT_ERROR(ctx, WT_ERR_INVALID, "FFT wisdom: %s is read-only (not a learner)", w->source);
    if (n < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "FFT wisdom: size %d, expected ≥ 1", n);
    char *saved;
    if (!store_swap_in(w->text, &saved)) return WT_ERROR(ctx, WT_ERR_FORMAT, "FFTW refused %s", w->source);
    const int st = learn_pair(ctx, w, n);
    store_restore(saved);
    return st;
}

int wt_fft_plan_pair(wt_context *ctx, wt_fft_wisdom *w, int n, double *re, void *cv, const char *what,
                     fftw_plan *r2c, fftw_plan *c2r)
{
    int st = WT_OK;
    fftw_complex *c = cv;
    *r2c = *c2r = NULL;
    if (n < 1) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: FFT size %d, expected ≥ 1", what, n);
    if (!w) {
        *r2c = fftw_plan_dft_r2c_2d(n, n, re, c, FFTW_ESTIMATE);
        *c2r = fftw_plan_dft_c2r_2d(n, n, c, re, FFTW_ESTIMATE);
    } else {
        char *saved;
        if (!store_swap_in(w->text, &saved)) return WT_ERROR(ctx, WT_ERR_FORMAT, "%s: FFTW refused %s", what, w->source);
        *r2c = fftw_plan_dft_r2c_2d(n, n, re, c, FFTW_MEASURE | FFTW_WISDOM_ONLY);
        *c2r = fftw_plan_dft_c2r_2d(n, n, c, re, FFTW_MEASURE | FFTW_WISDOM_ONLY);
        store_restore(saved);
        if (!*r2c || !*c2r) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG, "%s: the FFT wisdom %s holds no plan for the %d x %d real transforms "
                          "(made for another configuration, machine or FFTW than %s); make it again with `wavetomo "
                          "wisdom CONFIG --out FILE`, or leave the key empty (FFTW_ESTIMATE)",
                          what, w->source, n, n, fftw_version);
            goto fail;
        }
        return WT_OK;
    }
    if (!*r2c || !*c2r) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "%s: FFTW could not plan the %d x %d real transforms", what, n, n);
        goto fail;
    }
    return WT_OK;
fail:
    if (*r2c) fftw_destroy_plan(*r2c);
    if (*c2r) fftw_destroy_plan(*c2r);
    *r2c = *c2r = NULL;
    return st;
}
