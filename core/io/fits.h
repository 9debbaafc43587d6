/* core/io/fits.h: FITS export of long-exposure PSFs and their Strehl map (the astronomy ecosystem's image format,
 * through CFITSIO; docs/formats.md "FITS").
 *
 * The only module that includes fitsio.h. One file per wavelength λ, three HDUs:
 *   primary   float32 cube NAXIS1 = n (x), NAXIS2 = n (y), NAXIS3 = ndir (direction): the PSF of direction j is
 *             plane j, pixel (ix, iy) at the angle ((ix − n/2) θ_p, (iy − n/2) θ_p) (1-based FITS pixel
 *             CRPIX = n/2 + 1 is the optical axis of the plane), normalised so the diffraction-limited PSF of the
 *             same pupil peaks at 1 (its peak is the PSF-peak Strehl);
 *   STREHL    float64 g x g image of the PSF-peak Strehl on the square grid of directions (x fastest), with a
 *             linear world coordinate in arcsec (CRPIX = (g + 1)/2, CDELT = the grid's spacing);
 *   DIRECTIONS binary table, one row per direction: INDEX (the cube's plane, 0-based), THETA_X, THETA_Y
 *             [arcsec], STREHL (PSF peak), STREHL_M (Maréchal exp(−(2π σ/λ)²) of the long-exposure WFE σ),
 *             WFE [nm].
 * Keywords: WAVELENG [m], PIXSCALE [arcsec], PIXLOD [λ/D], SAMPLING [pixels per λ/D], FFTSIZE, NFRAMES,
 * EVERY, TELESCOP, TELDIAM, OBSTRUCT, RECON, SEED, CONFHASH (SHA-256 of the configuration text the run used),
 * CREATOR, DATE, and the linear world coordinates of the cube's axes 1, 2 in arcsec.
 *
 * Written atomically: everything goes to "PATH.tmp-<pid>" (created with fits_create_diskfile, so a name with
 * brackets is a plain name, not CFITSIO's extended syntax), closed, then rename()d onto PATH; on any failure
 * the temporary is removed and PATH is untouched. Plain data in, no model headers.
 */
#ifndef WT_FITS_H
#define WT_FITS_H

#include <stdint.h>

#include "../base/base.h"

typedef struct wt_fits_psf {
    double wavelength;        /* λ [m] */
    int n;                    /* image side (even) */
    int ndir;                 /* directions (planes of the cube) */
    const float *image;       /* [ndir][n][n], x fastest within a plane */
    const double *strehl;     /* PSF-peak Strehl per direction [ndir] */
    const double *wfe;        /* long-exposure rms residual per direction [m] [ndir] */
    const double *theta_x;    /* direction [rad] [ndir] */
    const double *theta_y;    /* direction [rad] [ndir] */
    int grid;                 /* the directions are the g x g grid index i + g j (ndir = g²) */
    double spacing;           /* its spacing [rad] */
    double pixel;             /* pixel scale θ_p [rad] */
    double pixel_lod;         /* θ_p in λ/D */
    int fft_size;             /* N of the zero-padded FFT */
    long frames;              /* frames in the long exposure */
    int every;                /* one frame in `every` taken */
    double diameter;          /* D [m] */
    double obstruction;       /* central obstruction, fraction of D */
    const char *telescope;    /* TELESCOP */
    const char *recon;        /* the reconstructor */
    uint64_t seed;            /* the run's seed */
    const char *config_sha256; /* 64 hex digits */
    const char *creator;      /* "wavetomo 0.1.0" */
} wt_fits_psf;

/* Write p to `path` (atomic, see above). WT_ERR_INVALID for inconsistent sizes, WT_ERR_IO naming the path and
 * CFITSIO's message for a failed write. Allocates only the table's columns. */
int wt_fits_write_psf(wt_context *ctx, const char *path, const wt_fits_psf *p);

/* "psf_2200nm.fits": the file name of wavelength λ [m] inside an export directory (%g of the nm). */
void wt_fits_psf_name(double wavelength, char *buf, size_t size);

#endif
