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
/* A copy of na (same ctx). */
int wt_sodium_copy(const wt_sodium *na, wt_sodium **out);

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

/* ---- a profile in time (core/optics/sodium_seq.c; SPEC §12 "The sodium layer changes too") --------------
 *
 * A sequence is one altitude grid h_0 < … < h_{n-1} and K ≥ 1 knots (t_k, n_k(h_i)), t_k strictly increasing
 * night times [s], read as the profile at night time t ∈ [t_0, t_{K-1}]:
 *   n(h_i, t) = n_k(h_i) + w (n_{k+1}(h_i) − n_k(h_i)),  w = (t − t_k)/(t_{k+1} − t_k), t_k ≤ t < t_{k+1},
 * a knot's own numbers at a knot (bit for bit: a sequence of equal profiles is that profile), each knot a
 * profile of the rules above (densities ≥ 0, not all zero). Linear in time at each altitude: a layer that moves
 * is a sequence of knots close enough in time that the profile between them is the intended one (the shipped
 * data/sodium/ sequences put them every 10–30 s).
 *
 * Text format (wt_sodium_seq_read): '#' starts a comment, blank lines are skipped, fields are separated by
 * blanks. The first line is the word `altitude_m` and the n ≥ 2 altitudes above the telescope [m]; every
 * other line is one knot: the night time [s] and the n densities (any positive scale: each profile is
 * normalised to unit mass by the spot model). Refused with FILE:LINE: a first line that is not `altitude_m`
 * and two or more altitudes, altitudes not strictly increasing or not above 0, a field that is not a finite
 * number, a knot of another field count than 1 + n, a time not above the previous knot's, a negative density,
 * a knot whose densities are all zero; naming the file: no knot, or a missing or unreadable file. */
typedef struct wt_sodium_seq wt_sodium_seq;

int wt_sodium_seq_read(wt_context *ctx, const char *path, wt_sodium_seq **out);
void wt_sodium_seq_free(wt_sodium_seq *q);
/* Knots, altitudes, and the first and last night time [s]. */
int wt_sodium_seq_knots(const wt_sodium_seq *q);
int wt_sodium_seq_nalt(const wt_sodium_seq *q);
double wt_sodium_seq_first(const wt_sodium_seq *q);
double wt_sodium_seq_last(const wt_sodium_seq *q);
/* WT_OK when [t_first, t_last] lies within the knots' span; else WT_ERR_CONFIG naming the file, both spans and
 * `what` (the keys that set the run's night times). */
int wt_sodium_seq_check_covers(wt_context *ctx, const wt_sodium_seq *q, double t_first, double t_last,
                               const char *what);
/* The profile at night time t into *out (allocated, free with wt_sodium_free). WT_ERR_INVALID when t is not
 * finite or outside [t_0, t_{K-1}]. */
int wt_sodium_seq_profile(wt_context *ctx, const wt_sodium_seq *q, double t, wt_sodium **out);
/* The same into an existing profile of the sequence's altitudes (from wt_sodium_seq_profile): allocates nothing. */
int wt_sodium_seq_at(const wt_sodium_seq *q, double t, wt_sodium *na);

#endif
