/* core/optics/sodium.h: the mesospheric sodium density profile n(h) of an LGS (SPEC §4b "LGS source").
 *
 * A profile is a table of altitudes h_i [m] (strictly increasing) and relative densities n_i ≥ 0 (not all
 * zero), read as the piecewise-linear function through those points, zero outside [h_0, h_{n-1}].
 * Every moment below is exact for that function. The spot model (core/optics/spot.h) puts each
 * altitude h at β(h) = (r − l)(1/h − 1/H) on the detector (SPEC §4b; to first order the spot's centroid
 * sits at (r − l)(H − h̄)/H², h̄ = wt_sodium_centroid, and its length along (r − l) is |r − l|·FWHM/H²).
 *
 * Text format (wt_sodium_read): one "altitude_m density" pair per line, whitespace separated; blank
 * lines and everything after '#' are ignored. Refused, with the file and line: a missing or unreadable
 * file, no data, a non-numeric or non-finite field, a third field, a negative density, altitudes not
 * strictly increasing (unsorted or duplicate), all densities zero.
 */
#ifndef WT_SODIUM_H
#define WT_SODIUM_H

#include "core/base/base.h"

typedef struct wt_sodium {
    wt_context *ctx; /* the context that allocated it (frees through its allocator) */
    int n;           /* number of samples (≥ 2) */
    double *alt;     /* [n] altitudes above the telescope [m], strictly increasing */
    double *dens;    /* [n] relative density (any positive scale; the models normalise to unit mass) */
} wt_sodium;

/* Read a two-column text profile from `path`. [out] *out owns copies (free with wt_sodium_free).
 * Returns WT_ERR_IO (missing/unreadable), WT_ERR_INVALID (a defect, with file:line), WT_ERR_NOMEM. */
int wt_sodium_read(wt_context *ctx, const char *path, wt_sodium **out);

/* A profile from a table (copied); the same checks as the file, the message names `what`. */
int wt_sodium_from_table(wt_context *ctx, int n, const double *alt, const double *dens, const char *what,
                         wt_sodium **out);

/* A Gaussian layer of mean altitude H [m] and FWHM [m] (> 0), tabulated over H ± 2.5 FWHM at FWHM/50:
 * its measured centroid is H and its measured FWHM is `fwhm` to ~1e-4 (piecewise-linear sampling). */
int wt_sodium_gaussian(wt_context *ctx, double H, double fwhm, wt_sodium **out);

void wt_sodium_free(wt_sodium *na);

/* ∫ n(h) dh of the piecewise-linear profile [density × m]. */
double wt_sodium_mass(const wt_sodium *na);
/* Centroid altitude h̄ = ∫ h n dh / ∫ n dh [m]. */
double wt_sodium_centroid(const wt_sodium *na);
/* Measured FWHM [m]: distance between the outermost half-maximum crossings of the piecewise-linear
 * profile (for a multi-peak profile, the full extent above half the highest peak). */
double wt_sodium_fwhm(const wt_sodium *na);
/* WT_OK when the LGS focus altitude H lies within [h_0, h_{n-1}]; else WT_ERR_INVALID naming `what`
 * (e.g. the configuration key of the profile) and both ranges: the caller refuses such a sensor. */
int wt_sodium_check_covers(wt_context *ctx, const wt_sodium *na, double H, const char *what);

#endif
