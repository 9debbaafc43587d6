/* core/optics/seeing.h: the mean short-exposure seeing a Shack–Hartmann subaperture adds to its spot
 * (SPEC §4b "The reference I0 … is the mean spot the sensor sees in the loop"; SPEC §2 for the spectrum).
 *
 * Phase statistics. The von Kármán OPD spectrum (r0 at λ0 = 500 nm, OPD in metres, κ in cycles/m)
 *     Φ(κ) = (λ0/2π)² · 0.0229 · r0^(−5/3) · (κ² + L0^(−2))^(−11/6)
 * has the OPD structure function
 *     D(ρ) = 4π ∫₀^∞ Φ(κ) (1 − J0(2πκρ)) κ dκ,
 * which tends to (λ0/2π)² · 6.88 (ρ/r0)^(5/3) for ρ ≪ L0 (tested). It is integrated numerically in log κ
 * (the oscillating part up to κρ = 50, sampled at ≥ 60 points per period of J0; above it 1 − J0 is taken
 * as 1 and the tail integrated in closed form, ∫_K^∞ κ (κ² + a²)^(−11/6) dκ = (3/5)(K² + a²)^(−5/6): the
 * neglected ∫ Φ κ J0 over the tail is below 1e-4 of D).
 * A simulated phase is rendered: screens of spacing δ (the simulation grid) hold the spectrum only inside
 * the Nyquist square |κx|, |κy| < 1/(2δ), and the pupil samples read them by bilinear interpolation, whose
 * power transfer is sinc⁴ per axis. With a rendering grid δ > 0 the integral takes Φ(κ) sinc⁴(κδ) over
 * the disc of the square's area, κ < 1/(√π δ) (a radial stand-in for the square band and the separable
 * sinc). That is the seeing the simulated spots carry: at the E-ELT preset's δ = d/4 the tilt-removed
 * phase of a subaperture has ~60 % of the sky's variance, and a reference with the sky's seeing gives the
 * matched filter an in-loop gain of ~1.15 on such spots (docs/results.md §32).
 *
 * Tilt removal. On the n_p × n_p samples x_a (spacing dx) of one subaperture with amplitudes A_a, the OPD
 * has the covariance C = −D(|x_a − x_b|)/2 up to a constant (the constant is piston, removed below). The
 * loop removes the subaperture's tilt (its DM, at about the subaperture's pitch, removes little more):
 * φ̃ = (I − T) φ with T = B (VᵀB)⁻¹ Vᵀ, B the basis {1, x, y} and Vᵀ the
 * functionals that measure them: the A²-weighted least-squares fit (Vᵀ = Bᵀ diag(A²): the Z-tilt), or,
 * with gtilt, the G-tilt (the mean of the A_a A_b-weighted differences of neighbouring samples, the
 * centroid shift), an oblique projector. Either way
 *     C̃ = (I − T) C (I − T)ᵀ,   D̃(a, b) = C̃_aa + C̃_bb − 2 C̃_ab.
 * Mean short-exposure OTF. For a Gaussian phase E[exp(ik(φ̃_a − φ̃_b))] = exp(−k² D̃(a, b)/2), k = 2π/λ.
 * The mean over the atmosphere of |FFT(A e^{ik(θ·x + φ̃)})|² is the FFT of the autocorrelation
 * Σ_a U(a + u) U*(a) exp(−k² D̃(a + u, a)/2); for a flat or tilted wavefront U(a + u)U*(a) = A A e^{ikθ·u}
 * whatever a, so the seeing multiplies the lag-u term of the autocorrelation by
 *     W(u) = Σ_a A(a + u) A(a) exp(−k² D̃(a + u, a)/2) / Σ_a A(a + u) A(a)     (W(0) = 1, W(−u) = W(u)),
 * exactly (no stationarity assumed: D̃ depends on a, not only on u). Lag u = (ux, uy) samples, |ux|, |uy| <
 * n_p; W is 0 where no pair of lit samples has that lag.
 */
#ifndef WT_SEEING_H
#define WT_SEEING_H

#include "core/base/base.h"

/* The von Kármán OPD structure function D(ρ) [m²] for r0 at 500 nm [m] and outer scale L0 [m] (L0 ≤ 0 or
 * infinite: Kolmogorov), rendered on a grid of spacing `grid` [m] (0: the sky's, unlimited). ρ ≥ 0 [m]. */
double wt_seeing_structure(double rho, double r0, double L0, double grid);

/* The phase structure function on the lags of an n_p × n_p sample grid of spacing dx [m]:
 * Dl[ux + n_p uy] = k² D(dx·|(ux, uy)|) [rad²] at the wavelength λ [m], 0 ≤ ux, uy < n_p. Dl holds n_p²
 * doubles. Refuses (WT_ERR_INVALID, naming the values) n_p < 1, dx, λ or r0 not > 0. One table serves every
 * subaperture of a sensor (a few ms: n_p²/2 quadratures). */
int wt_seeing_lag_table(wt_context *ctx, int np, double dx, double wavelength, double r0, double L0, double grid,
                        double *Dl); /* grid: as wt_seeing_structure */

/* W(u) of one subaperture (see above) from the lag table Dl, the phase less its piston and tilt, the tilt
 * fitted by least squares (gtilt = 0: Z-tilt) or measured as the G-tilt (gtilt = 1), on the N × N lag grid in FFT order: lag
 * (ux, uy) at [(ux mod N) + N (uy mod N)], N ≥ 2 n_p − 1 (so that no two lags share a cell; not checked
 * here: the caller's FFT size). amp [n_p²] (sample (i, j) at i + n_p j, the spacing of Dl). W: N² floats.
 * work: wt_seeing_work_size(n_p) doubles. A subaperture without a lit sample gets W = 0. Allocates
 * nothing, ~n_p⁴ exponentials. */
void wt_seeing_otf(int np, int gtilt, const double *Dl, const float *amp, int N, float *W, double *work);
size_t wt_seeing_work_size(int np);

#endif
