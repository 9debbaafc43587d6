/* core/optics/sodium.c: the sodium density profile (SPEC §4b "LGS source"): a checked table read from a
 * text file or built as a Gaussian layer, and its exact piecewise-linear moments (mass, centroid, FWHM). */
#include "sodium.h"

#include "../base/numbers.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void wt_sodium_free(wt_sodium *na)
{
    if (!na) return;
    wt_context *ctx = na->ctx;
    wt_free(ctx, na->alt);
    wt_free(ctx, na->dens);
    wt_free(ctx, na);
}

/* The checks shared by the file and the table: `where(i)` names sample i in messages. */
static int check_table(wt_context *ctx, int n, const double *alt, const double *dens, const char *what,
                       const int *lines)
{
#define WHERE(i) what, (lines ? ":" : " sample "), (lines ? lines[i] : (i))
    if (n < 2) return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s: %d sample(s); need at least 2", what, n);
    int any = 0;
    for (int i = 0; i < n; i++) {
        if (!isfinite(alt[i]) || !isfinite(dens[i]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s%s%d: altitude or density not finite", WHERE(i));
        if (dens[i] < 0)
            return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s%s%d: negative density %g", WHERE(i), dens[i]);
        if (i > 0 && !(alt[i] > alt[i - 1]))
            return WT_ERROR(ctx, WT_ERR_INVALID,
                            "sodium profile %s%s%d: altitude %g m not above the previous one (%g m): altitudes "
                            "must be strictly increasing (unsorted or duplicate)",
                            WHERE(i), alt[i], alt[i - 1]);
        any |= dens[i] > 0;
    }
    if (!any) return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s: every density is zero", what);
    if (alt[0] <= 0)
        return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s: altitude %g m not above the telescope", what, alt[0]);
    return WT_OK;
#undef WHERE
}

static int make(wt_context *ctx, int n, const double *alt, const double *dens, wt_sodium **out)
{
    int st = WT_OK;
    wt_sodium *na = NULL;
    WT_ALLOC(ctx, na, 1, "sodium profile");
    na->ctx = ctx;
    na->n = n;
    WT_ALLOC(ctx, na->alt, n, "sodium profile altitudes");
    WT_ALLOC(ctx, na->dens, n, "sodium profile densities");
    memcpy(na->alt, alt, (size_t)n * sizeof *alt);
    memcpy(na->dens, dens, (size_t)n * sizeof *dens);
    *out = na;
    return WT_OK;
fail:
    wt_sodium_free(na);
    return st;
}

int wt_sodium_copy(const wt_sodium *na, wt_sodium **out) { return make(na->ctx, na->n, na->alt, na->dens, out); }

int wt_sodium_from_table(wt_context *ctx, int n, const double *alt, const double *dens, const char *what,
                         wt_sodium **out)
{
    *out = NULL;
    if (!alt || !dens) return WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s: NULL table", what);
    int st = check_table(ctx, n, alt, dens, what, NULL);
    if (st < 0) return st;
    return make(ctx, n, alt, dens, out);
}

#define PROFILE_EXPECTED "(a sodium profile: \"altitude_m density\" per line)"

int wt_sodium_read(wt_context *ctx, const char *path, wt_sodium **out)
{
    *out = NULL;
    FILE *f = fopen(path, "r");
    if (!f) return WT_ERROR(ctx, WT_ERR_IO, "sodium profile %s: cannot open: %s", path, strerror(errno));
    static const char *const names[] = {"altitude [m]", "density"};
    int st = WT_OK, n = 0, cap = 0, lineno = 0;
    double *alt = NULL, *dens = NULL, *v = NULL;
    int *lines = NULL;
    long vcap = 0;
    char *buf = NULL;
    size_t bcap = 0;
    while (getline(&buf, &bcap, f) >= 0) {
        lineno++;
        const wt_numbers_where w = {path, lineno, 1, names, 2, PROFILE_EXPECTED, WT_ERR_INVALID};
        const long nf = wt_read_numbers(ctx, buf, &w, &v, &vcap);
        if (nf < 0) {
            st = (int)nf;
            goto fail;
        }
        if (nf == 0) continue;
        if (nf != 2) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s:%d: %s; expected \"altitude_m density\"", path, lineno,
                          nf == 1 ? "one field" : "more than two fields");
            goto fail;
        }
        if (n == cap) {
            const int nc = cap ? 2 * cap : 64;
            double *a2 = wt_malloc(ctx, (size_t)nc, sizeof *a2), *d2 = wt_malloc(ctx, (size_t)nc, sizeof *d2);
            int *l2 = wt_malloc(ctx, (size_t)nc, sizeof *l2);
            if (!a2 || !d2 || !l2) {
                wt_free(ctx, a2), wt_free(ctx, d2), wt_free(ctx, l2);
                st = WT_ERROR(ctx, WT_ERR_NOMEM, "sodium profile %s: out of memory", path);
                goto fail;
            }
            if (n) {
                memcpy(a2, alt, (size_t)n * sizeof *alt);
                memcpy(d2, dens, (size_t)n * sizeof *dens);
                memcpy(l2, lines, (size_t)n * sizeof *lines);
            }
            wt_free(ctx, alt), wt_free(ctx, dens), wt_free(ctx, lines);
            alt = a2, dens = d2, lines = l2, cap = nc;
        }
        alt[n] = v[0], dens[n] = v[1], lines[n] = lineno;
        n++;
    }
    if (ferror(f)) {
        st = WT_ERROR(ctx, WT_ERR_IO, "sodium profile %s: read error", path);
        goto fail;
    }
    if (n == 0) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "sodium profile %s: no data lines (expected \"altitude_m density\")", path);
        goto fail;
    }
    WT_TRY(check_table(ctx, n, alt, dens, path, lines));
    WT_TRY(make(ctx, n, alt, dens, out));
fail:
    fclose(f);
    free(buf); /* getline's buffer comes from malloc */
    wt_free(ctx, v);
    wt_free(ctx, alt), wt_free(ctx, dens), wt_free(ctx, lines);
    return st;
}

int wt_sodium_gaussian(wt_context *ctx, double H, double fwhm, wt_sodium **out)
{
    *out = NULL;
    if (!(H > 0) || !(fwhm > 0) || !isfinite(H) || !isfinite(fwhm) || H - 2.5 * fwhm <= 0)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "sodium Gaussian profile: mean altitude %g m and FWHM %g m must be > 0 with H > 2.5 FWHM", H,
                        fwhm);
    enum { NG = 251 }; /* H ± 2.5 FWHM at FWHM/50 */
    double alt[NG], dens[NG];
    const double s = fwhm / (2.0 * sqrt(2.0 * log(2.0)));
    for (int i = 0; i < NG; i++) {
        double z = (i - (NG - 1) / 2) * fwhm / 50.0;
        alt[i] = H + z;
        dens[i] = exp(-0.5 * z * z / (s * s));
    }
    return make(ctx, NG, alt, dens, out);
}

double wt_sodium_mass(const wt_sodium *na)
{
    double m = 0;
    for (int i = 0; i + 1 < na->n; i++) m += 0.5 * (na->alt[i + 1] - na->alt[i]) * (na->dens[i] + na->dens[i + 1]);
    return m;
}

double wt_sodium_centroid(const wt_sodium *na)
{
    /* ∫_a^b h f dh for f linear from fa to fb: (b − a)/6 · (fa (2a + b) + fb (a + 2b)); exact. Moments are
     * taken about h_0 to keep the rounding relative to the layer's width, not its altitude. */
    double m = 0, m1 = 0, h0 = na->alt[0];
    for (int i = 0; i + 1 < na->n; i++) {
        double a = na->alt[i] - h0, b = na->alt[i + 1] - h0, fa = na->dens[i], fb = na->dens[i + 1];
        m += 0.5 * (b - a) * (fa + fb);
        m1 += (b - a) / 6.0 * (fa * (2 * a + b) + fb * (a + 2 * b));
    }
    return h0 + m1 / m;
}

double wt_sodium_fwhm(const wt_sodium *na)
{
    double peak = 0;
    for (int i = 0; i < na->n; i++) peak = fmax(peak, na->dens[i]);
    const double half = 0.5 * peak;
    /* first upward crossing from below, last downward crossing; linear interpolation on the segment (a
     * profile whose end sample is above half crosses at that end: zero outside the table) */
    double lo = na->alt[0], hi = na->alt[na->n - 1];
    for (int i = 0; i < na->n; i++)
        if (na->dens[i] >= half) {
            if (i > 0) {
                double t = (half - na->dens[i - 1]) / (na->dens[i] - na->dens[i - 1]);
                lo = na->alt[i - 1] + t * (na->alt[i] - na->alt[i - 1]);
            }
            break;
        }
    for (int i = na->n - 1; i >= 0; i--)
        if (na->dens[i] >= half) {
            if (i < na->n - 1) {
                double t = (na->dens[i] - half) / (na->dens[i] - na->dens[i + 1]);
                hi = na->alt[i] + t * (na->alt[i + 1] - na->alt[i]);
            }
            break;
        }
    return hi - lo;
}

int wt_sodium_check_covers(wt_context *ctx, const wt_sodium *na, double H, const char *what)
{
    if (!(H >= na->alt[0] && H <= na->alt[na->n - 1]))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: the sodium profile spans %.0f-%.0f m, which does not contain the LGS altitude %.0f m",
                        what, na->alt[0], na->alt[na->n - 1], H);
    return WT_OK;
}
