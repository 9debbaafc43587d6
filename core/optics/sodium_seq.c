/* core/optics/sodium_seq.c: a sodium profile in time (sodium.h, "a profile in time"): a checked table of knots
 * read from a text file, interpolated linearly in night time. */
#include "sodium.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../base/numbers.h"

/* ends the message of a field that is not a number */
#define SEQ_EXPECTED                                                                                               \
    "(a sodium sequence: the word altitude_m and the altitudes [m], then a line per night time: time_s and a "    \
    "density per altitude)"

struct wt_sodium_seq {
    wt_context *ctx;
    char path[1024]; /* for messages */
    int n, K;        /* altitudes, knots */
    double *alt;     /* [n] */
    double *t;       /* [K] night times [s] */
    double *dens;    /* [K n] knot k's densities at dens + k n */
};

void wt_sodium_seq_free(wt_sodium_seq *q)
{
    if (!q) return;
    wt_context *ctx = q->ctx;
    wt_free(ctx, q->alt);
    wt_free(ctx, q->t);
    wt_free(ctx, q->dens);
    wt_free(ctx, q);
}

static int is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

/* append one knot (time + n densities) to q, growing its arrays */
static int add_knot(wt_sodium_seq *q, long *kcap, const double *v)
{
    if (q->K == *kcap) {
        const long nc = *kcap ? 2 * *kcap : 16;
        double *t2 = wt_malloc(q->ctx, (size_t)nc, sizeof *t2), *d2 = wt_malloc(q->ctx, (size_t)nc * q->n, sizeof *d2);
        if (!t2 || !d2) {
            wt_free(q->ctx, t2), wt_free(q->ctx, d2);
            return WT_ERROR(q->ctx, WT_ERR_NOMEM, "sodium sequence %s: out of memory", q->path);
        }
        if (q->K) {
            memcpy(t2, q->t, (size_t)q->K * sizeof *t2);
            memcpy(d2, q->dens, (size_t)q->K * q->n * sizeof *d2);
        }
        wt_free(q->ctx, q->t), wt_free(q->ctx, q->dens);
        q->t = t2, q->dens = d2, *kcap = nc;
    }
    q->t[q->K] = v[0];
    memcpy(q->dens + (size_t)q->K * q->n, v + 1, (size_t)q->n * sizeof *v);
    q->K++;
    return WT_OK;
}

int wt_sodium_seq_read(wt_context *ctx, const char *path, wt_sodium_seq **out)
{
    *out = NULL;
    FILE *f = fopen(path, "r");
    if (!f) return WT_ERROR(ctx, WT_ERR_IO, "sodium sequence %s: cannot open: %s", path, strerror(errno));
    int st = WT_OK, lineno = 0;
    char *buf = NULL;
    size_t bcap = 0;
    double *v = NULL;
    long vcap = 0, kcap = 0;
    wt_sodium_seq *q = NULL;
    WT_ALLOC(ctx, q, 1, "sodium sequence");
    q->ctx = ctx;
    snprintf(q->path, sizeof q->path, "%s", path);
    while (getline(&buf, &bcap, f) >= 0) {
        lineno++;
        char *hash = strchr(buf, '#');
        if (hash) *hash = '\0';
        char *p = buf;
        while (is_blank(*p)) p++;
        if (!*p) continue;
        if (!q->alt) { /* the altitude line */
            if (strncmp(p, "altitude_m", 10) || !is_blank(p[10])) {
                st = WT_ERROR(ctx, WT_ERR_INVALID,
                              "sodium sequence %s:%d: the first line must be the word altitude_m and the altitudes "
                              "[m] (then one line per night time: time_s and a density per altitude)",
                              path, lineno);
                goto fail;
            }
            const wt_numbers_where w = {path, lineno, 2, NULL, 0, SEQ_EXPECTED, WT_ERR_INVALID};
            const long n = wt_read_numbers(ctx, p + 10, &w, &v, &vcap);
            if (n < 0) {
                st = (int)n;
                goto fail;
            }
            if (n < 2 || n > 1000000) {
                st = WT_ERROR(ctx, WT_ERR_INVALID, "sodium sequence %s:%d: %ld altitude(s); need 2 to 10^6", path,
                              lineno, n);
                goto fail;
            }
            for (long i = 0; i < n; i++)
                if (!(v[i] > 0) || (i > 0 && !(v[i] > v[i - 1]))) {
                    st = WT_ERROR(ctx, WT_ERR_INVALID,
                                  "sodium sequence %s:%d: altitude %ld (%g m) %s: altitudes must be above the "
                                  "telescope and strictly increasing",
                                  path, lineno, i + 1, v[i], v[i] > 0 ? "is not above the previous one" : "is not > 0");
                    goto fail;
                }
            q->n = (int)n;
            WT_ALLOC(ctx, q->alt, n, "sodium sequence altitudes");
            memcpy(q->alt, v, (size_t)n * sizeof *v);
            continue;
        }
        const wt_numbers_where w = {path, lineno, 1, NULL, 0, SEQ_EXPECTED, WT_ERR_INVALID};
        const long n = wt_read_numbers(ctx, p, &w, &v, &vcap);
        if (n < 0) {
            st = (int)n;
            goto fail;
        }
        if (n != q->n + 1) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "sodium sequence %s:%d: %ld fields; expected %d (the night time and a density for each of "
                          "the %d altitudes of the altitude_m line)",
                          path, lineno, n, q->n + 1, q->n);
            goto fail;
        }
        if (q->K > 0 && !(v[0] > q->t[q->K - 1])) {
            st = WT_ERROR(ctx, WT_ERR_INVALID,
                          "sodium sequence %s:%d: night time %g s not above the previous line's %g s: times must be "
                          "strictly increasing",
                          path, lineno, v[0], q->t[q->K - 1]);
            goto fail;
        }
        int any = 0;
        for (int i = 0; i < q->n; i++) {
            if (v[1 + i] < 0) {
                st = WT_ERROR(ctx, WT_ERR_INVALID,
                              "sodium sequence %s:%d: negative density %g at altitude %g m (field %d)", path, lineno,
                              v[1 + i], q->alt[i], i + 2);
                goto fail;
            }
            any |= v[1 + i] > 0;
        }
        if (!any) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "sodium sequence %s:%d: every density is zero", path, lineno);
            goto fail;
        }
        WT_TRY(add_knot(q, &kcap, v));
    }
    if (ferror(f)) {
        st = WT_ERROR(ctx, WT_ERR_IO, "sodium sequence %s: read error", path);
        goto fail;
    }
    if (q->K == 0) {
        st = WT_ERROR(ctx, WT_ERR_INVALID,
                      "sodium sequence %s: no profile (expected a line 'altitude_m h1 h2 …', then lines 'time_s d1 "
                      "d2 …')",
                      path);
        goto fail;
    }
    *out = q;
    q = NULL;
fail:
    fclose(f);
    free(buf);
    wt_free(ctx, v);
    wt_sodium_seq_free(q);
    return st;
}

int wt_sodium_seq_knots(const wt_sodium_seq *q) { return q->K; }
int wt_sodium_seq_nalt(const wt_sodium_seq *q) { return q->n; }
double wt_sodium_seq_first(const wt_sodium_seq *q) { return q->t[0]; }
double wt_sodium_seq_last(const wt_sodium_seq *q) { return q->t[q->K - 1]; }

int wt_sodium_seq_check_covers(wt_context *ctx, const wt_sodium_seq *q, double t_first, double t_last, const char *what)
{
    if (!(t_first >= q->t[0] && t_last <= q->t[q->K - 1]))
        return WT_ERROR(ctx, WT_ERR_CONFIG,
                        "sodium sequence %s: its profiles span night times %g to %g s, the run's frames %g to %g s "
                        "(%s): the sequence must cover the run",
                        q->path, q->t[0], q->t[q->K - 1], t_first, t_last, what);
    return WT_OK;
}

int wt_sodium_seq_at(const wt_sodium_seq *q, double t, wt_sodium *na)
{
    if (!isfinite(t) || t < q->t[0] || t > q->t[q->K - 1])
        return WT_ERROR(q->ctx, WT_ERR_INVALID, "sodium sequence %s: night time %g s outside its span %g to %g s",
                        q->path, t, q->t[0], q->t[q->K - 1]);
    if (na->n != q->n) return WT_ERROR(q->ctx, WT_ERR_INVALID, "sodium sequence %s: a profile of %d altitudes, not %d",
                                       q->path, na->n, q->n);
    int lo = 0, hi = q->K - 1; /* the knot k with t_k ≤ t < t_{k+1} (the last knot at its own time) */
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (q->t[mid] <= t) lo = mid;
        else hi = mid - 1;
    }
    const double *a = q->dens + (size_t)lo * q->n;
    if (lo == q->K - 1 || t == q->t[lo]) {
        memcpy(na->dens, a, (size_t)q->n * sizeof *a);
        return WT_OK;
    }
    const double *b = a + q->n, w = (t - q->t[lo]) / (q->t[lo + 1] - q->t[lo]);
    /* (a convex combination of densities ≥ 0; the max keeps a rounding of a − a w from going below 0) */
    for (int i = 0; i < q->n; i++) na->dens[i] = fmax(0.0, a[i] + w * (b[i] - a[i]));
    return WT_OK;
}

int wt_sodium_seq_profile(wt_context *ctx, const wt_sodium_seq *q, double t, wt_sodium **out)
{
    *out = NULL;
    wt_sodium *na = NULL;
    int st = WT_OK;
    /* knot 0 as the template: altitudes, and densities that pass the profile's checks */
    WT_TRY(wt_sodium_from_table(ctx, q->n, q->alt, q->dens, q->path, &na));
    WT_TRY(wt_sodium_seq_at(q, t, na));
    *out = na;
    return WT_OK;
fail:
    wt_sodium_free(na);
    return st;
}
