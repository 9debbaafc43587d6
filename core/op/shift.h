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
/* Layers that move (a zero shift costs nothing). */
int wt_shift_nmoving(const wt_shift *s);

#endif
