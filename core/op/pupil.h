/* core/op/pupil.h: the annular telescope pupil and the masks derived from it (SPEC §1, §4).
 *
 * Pupil: outer diameter D, central obstruction ε·D, centred at the origin, in metres.
 * A Shack–Hartmann sensor with n x n subapertures of side d = D/n covers [-D/2, D/2]²; subaperture
 * (i, j) spans x ∈ [-D/2 + i d, -D/2 + (i+1) d] and likewise in y; index i + n*j.
 */
#ifndef WT_PUPIL_H
#define WT_PUPIL_H

#include <stdint.h>

#include "grid.h"

/* Fraction of the square [x0, x0+s] x [y0, y0+s] inside the annulus (outer radius D/2, inner ε D/2),
 * computed analytically (exact up to rounding, ~1e-15). */
double wt_pupil_fraction(double D, double obstruction, double x0, double y0, double s);

/* valid[i + n*j] = 1 when subaperture (i,j) of an n x n sensor over D is illuminated by at least
 * `threshold` of its area. Returns the number of valid subapertures, or WT_ERR_INVALID for n ≤ 0,
 * D ≤ 0 or an obstruction outside [0, 1). */
int wt_pupil_valid_subapertures(double D, double obstruction, int n, double threshold, uint8_t *valid);

/* corners[(n+1)*(n+1)]: 1 for every corner of a valid subaperture (the Fried phase points). */
void wt_pupil_corner_mask(int n, const uint8_t *valid, uint8_t *corners);

/* inside[g->nx * g->ny] = 1 for grid points inside the annulus. Returns the count. */
int64_t wt_pupil_mask_points(double D, double obstruction, const wt_grid *g, uint8_t *inside);

#endif
