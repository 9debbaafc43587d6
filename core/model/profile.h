/* core/model/profile.h: a Cn² profile compressed onto reconstruction layers (SPEC §12, "Compressing a
 * profile onto reconstruction layers").
 *
 * The reconstructor's atmosphere lives on its own layer altitudes a_0 < … < a_{L−1}; a profile (the truth's for
 * recon.atmosphere.source = "oracle", the user's for "given") has layers at other altitudes h_k with Cn²
 * fractions f_k and wind vectors v_k. Each profile layer is split between the two nearest reconstruction
 * altitudes, linearly in altitude (wt_profile_bin_altitude):
 *
 *   h_k ∈ [a_l, a_{l+1}):  w = (h_k − a_l) / (a_{l+1} − a_l),   c_{k,l} = (1 − w) f_k,   c_{k,l+1} = w f_k
 *
 * so that Σ_l c_{k,l} = f_k (total Cn² kept) and Σ_l c_{k,l} a_l = f_k h_k (first moment kept). A profile layer
 * below a_0 or above a_{L−1} goes wholly to that end layer: the total is still kept but not the first moment,
 * which moves by f_k (a_end − h_k) — no split among the layers can put Cn² outside their range. The wind of a
 * reconstruction layer is the Cn²-weighted mean of the wind vectors it absorbs, v_l = Σ_k c_{k,l} v_k / Σ_k c_{k,l}
 * (vectors, not speeds, as SPEC §12 says: the mean displacement per unit time of the turbulence the layer stands
 * for); a layer that absorbs nothing has v_l = 0.
 */
#ifndef WT_PROFILE_H
#define WT_PROFILE_H

/* Where a profile layer at altitude h goes among the L increasing altitudes alt: fraction 1 − w to *l and w to
 * *l + 1 (the linear split between the two nearest; all of it to the end one outside their range, w = 0). The
 * compression below and pcg3's layers → DMs map (core/model/reconstructor.c) both use it. */
void wt_profile_bin_altitude(int L, const double *alt, double h, int *l, double *w);

/* n profile layers at increasing altitudes alt [m] with fractions frac (≥ 0; any sum: the compression is
 * linear) and optionally wind components vx, vy [m/s] (both NULL: no wind) → L reconstruction layers at the
 * increasing altitudes ralt [m]: rfrac[l] = Σ_k c_{k,l} (summed in k order, the prior's rounding), rvx, rvy (NULL
 * when vx, vy are) the Cn²-weighted wind. Allocates nothing. */
void wt_profile_compress(int n, const double *alt, const double *frac, const double *vx, const double *vy, int L,
                         const double *ralt, double *rfrac, double *rvx, double *rvy);

/* The same for a profile that samples a continuous one on a grid (an identification's estimate: each c_k stands for the
 * Cn² around its grid point, not for a layer at it): the continuous profile Σ_k f_k φ_k(h) / ∫φ_k, φ_k the hat of
 * grid point k (1 at alt[k], linear to 0 at its neighbours; the end points' hats have one side), compressed as
 * above, exactly (Simpson's rule between the knots of φ_k and of the split):
 *
 *   rfrac[l] = Σ_k f_k ∫ φ_k(h) b_l(h) dh / ∫ φ_k(h) dh,   b_l the linear split of wt_profile_bin_altitude.
 *
 * Totals and, inside [ralt_0, ralt_{L−1}], first moments are kept as the hats have them (the bottom half-hat's
 * centre is a third of the way up: 0 km with the next point at 0.5 km stands for Cn² around 167 m). Why: below the
 * LGS pairs' altitude resolution a fit puts a spread profile's Cn² on its end points (0 km, 1 km), and the point
 * compression sends all of 0 km's to the lowest layer (docs/results.md §47). n < 2: wt_profile_compress. L ≤
 * WT_PROFILE_MAX_KNOTS − 3 (more layers inside one hat than that are dropped from its knots: then not exact). */
#define WT_PROFILE_MAX_KNOTS 72
void wt_profile_compress_hats(int n, const double *alt, const double *frac, const double *vx, const double *vy, int L,
                              const double *ralt, double *rfrac, double *rvx, double *rvy);

#endif
