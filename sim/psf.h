/* sim/psf.h: long-exposure point-spread functions of the residual wavefront per evaluation direction
 * (SPEC §8b).
 *
 *   U = P · exp(2πi φ / λ)  on the fine pupil grid (P: the pupil mask, φ: the residual OPD [m]),
 *   zero-padded to N x N with N dx ≥ q D (q = 2: Nyquist, a pixel of λ/(N dx) ≤ λ/(2D)),
 *   PSF_t = |FFT(U)|² / N_P²   (N_P: the pupil's points),   PSF_LE = mean of PSF_t over the frames taken.
 *
 * The normalisation makes the diffraction-limited PSF (φ = 0) exactly 1 at its peak (|Σ P|² = N_P²), so the
 * peak of PSF_LE is the Strehl ratio measured on the image ("PSF-peak Strehl"), to be set beside the Maréchal
 * exp(−(2πσ/λ)²) of strehl.h: they agree for small residuals (extended Maréchal, σ ≲ 1 rad) and differ at low
 * Strehl, where the image peak also holds the halo's contribution and the frame-to-frame image motion.
 * Pixel (ix, iy) of an image is at the angle ((ix − n/2) θ_p, (iy − n/2) θ_p), θ_p = λ/(N dx), stored at
 * ix + n iy (x fastest, row = y); a residual tilt ∂φ/∂x = a [rad] moves the image by +a in x.
 *
 * Frames taken: t ≥ settle and (t − settle) mod every = 0.
 *
 * Cost: two passes of 1-D FFTs (float32) per direction and frame taken: the rows that hold the pupil
 * (N_r of them, length N), then only the n image columns (length N): (N_r + n) N log2 N butterflies instead of
 * the 2 N² log2 N of a full 2-D transform; FFTW plans made once (FFTW_ESTIMATE: the same plan and bits every
 * run), one workspace per thread, directions spread over the threads. float32 fields: relative rounding
 * ~1e-6 of the peak, far below the 4 digits the Strehl is quoted to. The sums over frames are double.
 */
#ifndef WT_PSF_H
#define WT_PSF_H

#include <stdint.h>

#include "../core/base/base.h"
#include "../core/io/fits.h"
#include "../core/io/h5.h"
#include "../core/op/grid.h"

typedef struct wt_psf wt_psf;

typedef struct wt_psf_params {
    double wavelength; /* λ of the images [m] (the Strehl's, evaluation.wavelength_nm) */
    double diameter;   /* telescope diameter D [m]: the pixel scale in λ/D and the padding */
    int every;         /* take every `every`-th frame after the settle window (≥ 1) */
    int settle;        /* frames before the first taken */
    double sampling;   /* q: pixels per λ/D at least (2 = Nyquist; ≥ 1) */
    int pixels;        /* image side n kept around the centre (even; more than N: N rounded down to even;
                        * 0: WT_PSF_DEFAULT_PIXELS) */
} wt_psf_params;

#define WT_PSF_DEFAULT_PIXELS 64

/* The parameters of the long-exposure PSFs of cfg (sim.psf_interval_frames, evaluation wavelength, settle frames,
 * Nyquist sampling); every = 0: none. */
struct wt_config;
void wt_psf_params_from_config(const struct wt_config *cfg, wt_psf_params *par);

/* Plan the images of ndir directions of residuals on `grid` inside `mask` (copied). Allocates and plans;
 * fails with a message on a bad parameter or a NULL FFTW plan. */
int wt_psf_alloc(wt_context *ctx, const wt_grid *grid, const uint8_t *mask, int ndir, const wt_psf_params *par,
                 wt_psf **out);
void wt_psf_free(wt_psf *p);

/* Add the images of the residual maps opd[j] (j < ndir, on the grid, read inside the mask) to the sums.
 * Allocates nothing. */
void wt_psf_add(wt_psf *p, const double *const *opd);
/* Frame t of a run: wt_psf_add when t is a frame taken (see above); returns 1 when it was, else 0. */
int wt_psf_frame(wt_psf *p, long t, const double *const *opd);

int wt_psf_ndir(const wt_psf *p);
long wt_psf_frames(const wt_psf *p);   /* frames taken so far */
int wt_psf_pixels(const wt_psf *p);    /* image side n */
int wt_psf_fft_size(const wt_psf *p);  /* N */
double wt_psf_pixel_scale(const wt_psf *p); /* θ_p [rad] */
double wt_psf_pixel_lod(const wt_psf *p);   /* θ_p in λ/D */
double wt_psf_wavelength(const wt_psf *p);  /* λ [m] */
/* The long-exposure image of direction j (n x n, mean of the frames taken; zeros before any). */
void wt_psf_image(const wt_psf *p, int j, float *img);
/* Its peak: the PSF-peak Strehl of direction j (0 before any frame). */
double wt_psf_strehl(const wt_psf *p, int j);

/* The images into w under `group`: group/image [ndir, n, n] float32 and group/strehl_peak [ndir], with the
 * attributes of docs/formats.md (units, pixel scale in λ/D and mas, wavelength, frames, every, N). */
int wt_psf_write(const wt_psf *p, wt_h5_writer *w, const char *group);
/* The same from plain arrays (the compare driver gathers images of runs done elsewhere): nrun = 0: img [ndir n n],
 * strehl [ndir]; nrun > 0: nrun runs (seeds) of them, img [nrun ndir n n], strehl [nrun ndir]. */
int wt_psf_write_images(wt_h5_writer *w, const char *group, int nrun, int ndir, int n, const float *img,
                        const double *strehl, double wavelength, double pixel_lod, double pixel_rad, long frames,
                        int every, int fft_size);

/* Several wavelengths' images (p[k], k < nw: the same directions, pupil, N and n; only λ differs, so the pixel is
 * the same in λ/D and λ_k/(N dx) in angle) into w under `group`: group/image [nw, ndir, n, n] float32,
 * group/strehl_peak [nw, ndir], group/wavelength_nm [nw], group/pixel_mas [nw]. */
int wt_psf_write_bands(const wt_psf *const *p, int nw, wt_h5_writer *w, const char *group);

/* The images of p as one FITS file at `path` (core/io/fits.h): meta gives the run's part (directions, their WFE,
 * the grid, telescope, reconstructor, seed, configuration hash, creator); the images, their Strehl, the wavelength,
 * pixel scales, N, frames and cadence come from p. Allocates the images for the call. */
int wt_psf_write_fits(const wt_psf *p, const char *path, const wt_fits_psf *meta);

#endif
