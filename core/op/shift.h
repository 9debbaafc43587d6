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
/* The loop's integrator on moving layers (recon.predict_integrator = "layers"), one frame:
 *   z_{t+d} = S_1 z_{t+d−1} + g S_d (φ_t − z_t),
 * S_d the layers moved over the loop's delay d (a shift `lead`), S_1 over a frame (`one`), φ_t the frame's estimate,
 * z_t the state whose commands are applied during frame t. Under frozen flow with the layers' own wind (φ_t = S_t φ_0),
 * once z_t = φ_t the state stays on the layers, z_{t+d} = φ_{t+d} whatever g, so the integrator's average adds no
 * lag; an error decays as (1 − g) per frame, moving with the layers.
 * The state is kept as the layers' spectra, Ẑ = DFT(z) on each periodic grid, where both shifts are diagonal (the
 * ramps of wt_shift_alloc: m_S(k) = m_x(k_x) m_y(k_y), their real parts at Nyquist):
 *   Ẑ_{t+d}(k) = m_1(k) Ẑ_{t+d−1}(k) + g m_d(k) (Φ̂_t(k) − Ẑ_t(k)),
 * so a frame costs one transform of φ_t and one back for z_{t+d} — one shift's work, where the two shifts in space
 * cost two. The same operators as wt_shift_apply_to's (equal to rounding); the state does not depend on the winds, so
 * new shifts (a new wind) apply from the next frame on. A layer's arithmetic does not depend on the thread count. */
typedef struct wt_shift_integrator wt_shift_integrator;
/* L layers on the square even grids g[l] from offset[l] (the shifts' layout), delay d ≥ 1 frames; the state zero.
 * Plans FFTW_ESTIMATE. Allocates (d + 2)·n(n/2 + 1) complex numbers and n²/2 more per layer. */
int wt_shift_integrator_alloc(wt_context *ctx, int L, const wt_grid *const *g, const int64_t *offset, int delay,
                              wt_shift_integrator **out);
void wt_shift_integrator_free(wt_shift_integrator *it);
/* The state back to zero, the frame count to 0. */
void wt_shift_integrator_reset(wt_shift_integrator *it);
/* One frame: zn ← z_{t+d} (the layers' range of zn, all n values of the layers' vector) from phi = φ_t, then t ← t + 1.
 * lead and one: shifts of the integrator's layers (WT_ERR_INVALID otherwise, nothing changed). Allocates nothing. */
int wt_shift_integrator_step(wt_shift_integrator *it, const wt_shift *lead, const wt_shift *one, double g,
                             const double *phi, double *zn);
/* Layers that move (a zero shift costs nothing); whether layer l does. */
int wt_shift_nmoving(const wt_shift *s);
int wt_shift_layer_moves(const wt_shift *s, int l);

#endif
