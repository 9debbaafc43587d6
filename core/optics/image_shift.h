/* core/optics/image_shift.h: sub-pixel shifts of small detector images by cubic B-spline interpolation, accumulated cheaply,
 * and the derivative images of the mean (the matched filter's reference rebuilt from the loop's own pixels;
 * docs/design.md "The reference from the loop's own pixels").
 *
 * An image I[m] (Ns x Ns pixels, zero outside the detector) is read as the cubic spline I(x) = Σ_k c[k] β3(x − k),
 * β3(x) = 2/3 − x² + |x|³/2 (|x| < 1), (2 − |x|)³/6 (1 ≤ |x| < 2), 0 beyond, whose coefficients interpolate the
 * pixels: I = B c, B = [1 4 1]/6, so c = P I with P = B⁻¹ the recursive filter of pole z = √3 − 2 (Unser, IEEE SP
 * Mag. 16(6), 22, 1999), separable in x and y. Shifted by u pixels (its content moved by +u):
 *   J = T_u P I,  (T_u c)[i] = Σ_k c[i − k] β3(k − u)  (four taps, k = ⌊u⌋ − 1 … ⌊u⌋ + 2).
 * T_u and P are convolutions and commute, so the mean of n shifted frames is P (Σ_f T_{u_f} I_f) / n: a frame costs
 * the four taps per axis (T_u I_f, on the detector grid widened by MARGIN pixels, where it is supported for |u| ≤ 2),
 * and P runs once per rebuild. The derivative image of the mean M along x (per pixel of shift) is that of its spline,
 * ∂M/∂u = −Σ_k c[k] β3'(x − k) at the pixels: −(c[i+1] − c[i−1])/2 along x, [1 4 1]/6 along y (c = P M with M zero
 * outside the detector: the image the detector holds) — the limit of the central differences by which the spot
 * model forms the set-up reference's derivatives (spot.h), here exact.
 *
 * Why the cubic spline: it reproduces polynomials to degree 3, so a shift u moves an image's centroid by exactly u
 * (the Lanczos-3 kernel, tried first, moves it by 0.84 u at small u and its derivative at zero shift is 0.83 of a
 * linear ramp's slope); it interpolates (the identity at u = 0: the noise-free test is exact to rounding); it does not
 * wrap a truncated spot round the field as a periodic Fourier shift would; and its taps commute with its prefilter,
 * so a frame costs four taps per axis. Its error is that of interpolating an undersampled image: an LGS spot of ~1.2″
 * on 1.1″ pixels (the demo and E-ELT presets) is not band-limited to the pixels' Nyquist frequency, so no
 * interpolation of its pixels gives the pixel-integrated spot's exact shift or derivative (the derivative of the
 * demo's set-up reference is 35–50 % off the spot model's: docs/results.md §49; a well-sampled spot, σ = 2 pixels,
 * within 1e-3 of the peak shifted and 1e-2 differentiated: tests/test_pixels.c). Cost per frame:
 * 2 · 4 · Ns (Ns + 2 MARGIN) multiply-adds at most (~3 k at Ns = 16).
 */
#ifndef WT_IMAGE_SHIFT_H
#define WT_IMAGE_SHIFT_H

/* Pixels by which the accumulator is wider than the detector on each side; shifts are clamped to ±MAXSHIFT pixels. */
#define WT_IMAGE_SHIFT_MARGIN 4
#define WT_SHIFT_MAXSHIFT 2.0

/* The side of an accumulator: ns + 2 MARGIN. */
int wt_image_shift_side(int ns);

/* acc[E²] (E = wt_image_shift_side(ns)) += T_u img[ns²] for the shift (ux, uy) [pixels], through tmp[ns E] (scratch; single
 * precision: the frame's pixels are). A non-finite shift is taken as 0, one beyond ±MAXSHIFT clamped to it. */
void wt_image_shift_accumulate(int ns, const float *img, double ux, double uy, float *acc, float *tmp);

/* The mean of the frames accumulated, scale = 1 / n: mean[ns²] = the detector's part of P acc · scale. tmp:
 * wt_image_shift_work(ns) doubles. */
void wt_image_shift_mean(int ns, const float *acc, double scale, float *mean, double *tmp);
/* The derivative images of the spline of img[ns²] (zero outside the detector) along x and y per pixel of shift (a
 * content moving by +u), either may be NULL. tmp: wt_image_shift_work(ns) doubles. */
void wt_image_shift_derivative(int ns, const float *img, float *dx, float *dy, double *tmp);
int wt_image_shift_work(int ns);

#endif
