/* core/op/shift.h: the layers of a reconstruction moved by their wind over the loop's lead time (SPEC §12
 * "Prediction over the loop's delay").
 *
 * Under frozen flow a layer is φ_t(x) = φ_0(x − v t), so τ seconds later it is φ_t(x − v τ): the layer
 * shifted by s = v τ. On the periodic n × n layer grid of spacing δ (the reconstruction's own layers are
 * periodic: the prior's FFT), a shift by any fraction of a point is exact for the grid's band-limited
 * field: φ̂(k) ← φ̂(k) e^{−2πi k·s/(n δ)} (r2c / c2r; along an axis at its Nyquist frequency the factor is
 * its real part, cos(π s/δ)). A layer is left as it is when its shift is zero. */
#ifndef WT_SHIFT_H
#define WT_SHIFT_H

#include <stdint.h>

#include "../base/base.h"
#include "grid.h"

typedef struct wt_shift wt_shift;

/* L layers, layer l on the square grid g[l] (nx = ny even), stored from offset[l] in the layers' vector;
 * sx, sy [m] the shift of each (finite; |s| ≤ n δ / 4, else WT_ERR_CONFIG naming the layer: a lead that
 * moves a layer by a quarter of its grid wraps its content round). Plans FFTW_ESTIMATE (complex 1-D
 * transforms, shift.c: no wisdom needed). */
int wt_shift_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, const double *sx,
                   const double *sy, wt_shift **out);
void wt_shift_free(wt_shift *s);
/* phi ← every layer shifted, in place. Allocates nothing. */
void wt_shift_apply(wt_shift *s, double *phi);
/* out ← in with every layer shifted (the layers' ranges of out; a layer that does not move is copied). in and
 * out may be the same array, else they must not overlap. The same bits as wt_shift_apply. Allocates nothing. */
void wt_shift_apply_to(wt_shift *s, const double *in, double *out);
/* One frame of the loop's integrator on moving layers (recon.predict_integrator = "layers"), over n values:
 *   zn ← S_1 zp + g S_d (phi − zt),
 * S_d = lead (the layers moved over the loop's delay d), S_1 = one (over a frame), phi the frame's estimate, zt the
 * state whose commands are applied during it, zp the latest state (frame t + d − 1), zn the next (t + d). Under
 * frozen flow with the layers' own wind (phi_t = S_t phi_0), once zt = phi_t the state stays on the layers: zn =
 * phi_{t+d}, whatever g, so the integrator's average adds no lag; an error decays as (1 − g) per frame, moving with
 * the layers. e: n values of scratch; zn must not overlap the others. Allocates nothing. */
void wt_shift_integrate(wt_shift *lead, wt_shift *one, double g, const double *phi, const double *zt, const double *zp,
                        double *zn, double *e, int64_t n);
/* Layers that move (a zero shift costs nothing). */
int wt_shift_nmoving(const wt_shift *s);

#endif
