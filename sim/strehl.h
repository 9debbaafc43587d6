/* sim/strehl.h: image quality of a residual wavefront (SPEC §8, paper §6.1).
 *
 *   σ² = mean over the pupil of (φ − mean φ)²  (piston removed),  S = exp(−(2π σ / λ)²)  (Maréchal)
 *
 * Long exposure: LE Strehl = mean of the short-exposure Strehl over the frames after the settle
 * period; the residual wavefront error (WFE) is √(mean σ²), reported in nm.
 */
#ifndef WT_STREHL_H
#define WT_STREHL_H

#include <stdint.h>

/* Piston-removed rms [m] of opd over the points with mask[i] ≠ 0 (n points in all). */
double wt_strehl_rms(const double *opd, const uint8_t *mask, int64_t n);
/* rms[j] = wt_strehl_rms(opd[j], mask, n) for j < count, bit for bit, in one pass over the mask: the
 * count sums are independent chains run side by side (WT_STREHL_CHAINS at a time), so their additions
 * overlap where one sum alone waits for each addition before the next (each sum keeps its order). */
#define WT_STREHL_CHAINS 4
void wt_strehl_rms_many(const double *const *opd, const uint8_t *mask, int64_t n, int count, double *rms);
/* Maréchal Strehl for an rms σ [m] at wavelength λ [m]. */
double wt_strehl_marechal(double rms, double wavelength);

/* Running long-exposure averages over several directions (a plain value type, no allocation). */
typedef struct wt_strehl_le {
    int ndir;
    long frames;           /* frames accumulated */
    double sum_strehl[225];
    double sum_var[225];   /* Σ σ² [m²] */
} wt_strehl_le;

void wt_strehl_le_init(wt_strehl_le *le, int ndir);
/* Add one frame: rms[ndir] [m] at wavelength λ. */
void wt_strehl_le_add(wt_strehl_le *le, const double *rms, double wavelength);
/* LE Strehl and WFE [m] of direction j (0 when no frame). */
double wt_strehl_le_strehl(const wt_strehl_le *le, int j);
double wt_strehl_le_wfe(const wt_strehl_le *le, int j);

#endif
