/* core/io/fits.c: the PSF cube, its Strehl map and its directions' table as one FITS file per wavelength
 * (fits.h), through CFITSIO, written to a temporary and renamed.
 *
 *   plane j of the cube = PSF_LE of direction j (x fastest), peak = PSF-peak Strehl S_j;
 *   STREHL[i + g k] = S_{i + g k};   STREHL_M_j = exp(−(2π σ_j / λ)²),  σ_j the long-exposure rms WFE.
 */
#include "fits.h"

#include <errno.h>
#include <fcntl.h>
#include <fitsio.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#define RAD2ARCSEC (180.0 / M_PI * 3600.0)

void wt_fits_psf_name(double wavelength, char *buf, size_t size)
{
    snprintf(buf, size, "psf_%.6gnm.fits", wavelength * 1e9);
}

/* CFITSIO's text for status st (and the top of its error stack) into the context's message */
static int fits_fail(wt_context *ctx, const char *path, const char *what, int st)
{
    char text[FLEN_STATUS] = "", detail[FLEN_ERRMSG] = "";
    fits_get_errstatus(st, text);
    if (!fits_read_errmsg(detail)) detail[0] = 0;
    fits_clear_errmsg();
    return WT_ERROR(ctx, WT_ERR_IO, "%s: FITS %s failed: %s (CFITSIO status %d)%s%s", path, what, text, st,
                    detail[0] ? ": " : "", detail);
}

/* the linear world coordinate of image axis `axis` (1-based) in arcsec: pixel crpix (1-based) at 0 */
static void axis_wcs(fitsfile *f, int axis, const char *type, double crpix, double cdelt, int *fs)
{
    char key[FLEN_KEYWORD];
    double zero = 0.0;
    snprintf(key, sizeof key, "CTYPE%d", axis);
    fits_write_key(f, TSTRING, key, (void *)type, "angular offset from the axis of the plane", fs);
    snprintf(key, sizeof key, "CUNIT%d", axis);
    fits_write_key(f, TSTRING, key, (void *)"arcsec", "unit of the axis", fs);
    snprintf(key, sizeof key, "CRPIX%d", axis);
    fits_write_key(f, TDOUBLE, key, &crpix, "reference pixel (1-based): offset 0", fs);
    snprintf(key, sizeof key, "CRVAL%d", axis);
    fits_write_key(f, TDOUBLE, key, &zero, "[arcsec] offset at the reference pixel", fs);
    snprintf(key, sizeof key, "CDELT%d", axis);
    fits_write_key(f, TDOUBLE, key, &cdelt, "[arcsec] per pixel", fs);
}

/* the keywords every HDU carries: what, where, which run */
static void common_keys(fitsfile *f, const wt_fits_psf *p, int *fs)
{
    double lambda = p->wavelength, d = p->diameter, obs = p->obstruction;
    long long seed = (long long)p->seed;
    fits_write_key(f, TDOUBLE, "WAVELENG", &lambda, "[m] wavelength of the images", fs);
    fits_write_key(f, TSTRING, "TELESCOP", (void *)p->telescope, "telescope (from the configuration)", fs);
    fits_write_key(f, TDOUBLE, "TELDIAM", &d, "[m] pupil diameter D", fs);
    fits_write_key(f, TDOUBLE, "OBSTRUCT", &obs, "central obstruction, fraction of D", fs);
    fits_write_key(f, TSTRING, "RECON", (void *)p->recon, "reconstructor of the closed loop", fs);
    fits_write_key(f, TLONGLONG, "SEED", &seed, "seed of turbulence and noise", fs);
    fits_write_key(f, TSTRING, "CONFHASH", (void *)p->config_sha256, "SHA-256 of the run's configuration text", fs);
    fits_write_key(f, TSTRING, "CREATOR", (void *)p->creator, "program that wrote this file", fs);
    fits_write_date(f, fs);
}

static int write_file(wt_context *ctx, fitsfile *f, const char *path, const wt_fits_psf *p)
{
    int fs = 0;
    const long n = p->n, nd = p->ndir, g = p->grid;
    /* primary: the PSF cube */
    long axes[3] = {n, n, nd};
    fits_create_img(f, FLOAT_IMG, 3, axes, &fs);
    if (fs) return fits_fail(ctx, path, "create the PSF cube", fs);
    fits_write_img(f, TFLOAT, 1, (LONGLONG)n * n * nd, (void *)p->image, &fs);
    {
        const double arcsec = p->pixel * RAD2ARCSEC, lod = p->pixel_lod, q = 1.0 / p->pixel_lod;
        const double c = (double)(n / 2 + 1);
        int fft = p->fft_size, every = p->every;
        long frames = p->frames;
        fits_write_key(f, TSTRING, "EXTNAME", (void *)"PSF", "long-exposure PSF per evaluation direction", &fs);
        fits_write_key(f, TSTRING, "BUNIT", (void *)"", "diffraction-limited peak = 1: peak = PSF-peak Strehl", &fs);
        common_keys(f, p, &fs);
        fits_write_key(f, TDOUBLE, "PIXSCALE", (void *)&arcsec, "[arcsec] pixel scale", &fs);
        fits_write_key(f, TDOUBLE, "PIXLOD", (void *)&lod, "[lambda/D] pixel scale", &fs);
        fits_write_key(f, TDOUBLE, "SAMPLING", (void *)&q, "pixels per lambda/D (2 = Nyquist)", &fs);
        fits_write_key(f, TINT, "FFTSIZE", &fft, "N of the zero-padded pupil FFT", &fs);
        fits_write_key(f, TLONG, "NFRAMES", &frames, "frames in the long exposure", &fs);
        fits_write_key(f, TINT, "EVERY", &every, "one frame in EVERY taken after the settle frames", &fs);
        axis_wcs(f, 1, "XOFFSET", c, arcsec, &fs);
        axis_wcs(f, 2, "YOFFSET", c, arcsec, &fs);
        fits_write_key(f, TSTRING, "CTYPE3", (void *)"DIRECTION", "plane = row INDEX of the DIRECTIONS table", &fs);
        fits_write_comment(f, "Pixel (ix, iy), 0-based, of a plane is at ((ix - n/2), (iy - n/2)) x PIXSCALE; "
                              "x right, y up (row = y).", &fs);
    }
    if (fs) return fits_fail(ctx, path, "write the PSF cube", fs);

    /* the Strehl map on the square grid of directions */
    long maxes[2] = {g, g};
    fits_create_img(f, DOUBLE_IMG, 2, maxes, &fs);
    fits_write_img(f, TDOUBLE, 1, (LONGLONG)g * g, (void *)p->strehl, &fs);
    fits_write_key(f, TSTRING, "EXTNAME", (void *)"STREHL", "PSF-peak Strehl on the grid of directions", &fs);
    common_keys(f, p, &fs);
    axis_wcs(f, 1, "XOFFSET", 0.5 * (double)(g + 1), p->spacing * RAD2ARCSEC, &fs);
    axis_wcs(f, 2, "YOFFSET", 0.5 * (double)(g + 1), p->spacing * RAD2ARCSEC, &fs);
    if (fs) return fits_fail(ctx, path, "write the Strehl map", fs);

    /* the directions' table */
    char *names[6] = {"INDEX", "THETA_X", "THETA_Y", "STREHL", "STREHL_M", "WFE"};
    char *forms[6] = {"1J", "1D", "1D", "1D", "1D", "1D"};
    char *units[6] = {"", "arcsec", "arcsec", "", "", "nm"};
    fits_create_tbl(f, BINARY_TBL, nd, 6, names, forms, units, "DIRECTIONS", &fs);
    if (fs) return fits_fail(ctx, path, "create the DIRECTIONS table", fs);
    int st = WT_OK;
    int *idx = NULL;
    double *col = NULL;
    WT_ALLOC(ctx, idx, (size_t)nd, "FITS table");
    WT_ALLOC(ctx, col, (size_t)nd, "FITS table");
    for (int j = 0; j < nd; j++) idx[j] = j;
    fits_write_col(f, TINT, 1, 1, 1, nd, idx, &fs);
    for (int c = 0; c < 5 && !fs; c++) {
        for (int j = 0; j < nd; j++)
            col[j] = c == 0   ? p->theta_x[j] * RAD2ARCSEC
                     : c == 1 ? p->theta_y[j] * RAD2ARCSEC
                     : c == 2 ? p->strehl[j]
                     : c == 3 ? exp(-pow(2.0 * M_PI * p->wfe[j] / p->wavelength, 2))
                              : p->wfe[j] * 1e9;
        fits_write_col(f, TDOUBLE, c + 2, 1, 1, nd, col, &fs);
    }
    /* the columns' meaning in the comments of their names (fits_create_tbl wrote generic ones) */
    fits_modify_comment(f, "TTYPE4", "PSF-peak Strehl: peak of the plane INDEX", &fs);
    fits_modify_comment(f, "TTYPE5", "Marechal exp(-(2 pi WFE/lambda)^2)", &fs);
    fits_modify_comment(f, "TTYPE6", "long-exposure rms residual, piston removed", &fs);
    common_keys(f, p, &fs);
    if (fs) st = fits_fail(ctx, path, "write the DIRECTIONS table", fs);
fail:
    wt_free(ctx, idx);
    wt_free(ctx, col);
    return st;
}

int wt_fits_write_psf(wt_context *ctx, const char *path, const wt_fits_psf *p)
{
    if (p->n < 2 || p->n % 2 || p->ndir < 1 || p->grid < 1 || (int64_t)p->grid * p->grid != p->ndir ||
        !(p->wavelength > 0.0) || !(p->pixel > 0.0) || !(p->pixel_lod > 0.0) || !p->image || !p->strehl || !p->wfe ||
        !p->theta_x || !p->theta_y || !p->telescope || !p->recon || !p->config_sha256 || !p->creator)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: FITS PSF export: bad description (n %d, %d directions on a %d x %d grid, wavelength %g m, "
                        "pixel %g rad)", path, p->n, p->ndir, p->grid, p->grid, p->wavelength, p->pixel);
    char temp[4200];
    if (snprintf(temp, sizeof temp, "%s.tmp-%ld", path, (long)getpid()) >= (int)sizeof temp)
        return WT_ERROR(ctx, WT_ERR_IO, "%s: FITS export: path too long", path);
    unlink(temp); /* a leftover of this pid: ffdkinit refuses an existing file */
    fitsfile *f = NULL;
    int fs = 0;
    fits_create_diskfile(&f, temp, &fs);
    if (fs) return fits_fail(ctx, path, "create (temporary '...tmp-<pid>')", fs);
    int status = write_file(ctx, f, path, p);
    fs = 0;
    fits_close_file(f, &fs);
    if (status >= 0 && fs) status = fits_fail(ctx, path, "close", fs);
    if (status >= 0) {
        /* on disk before it gets the final name: a crash leaves the old file or the new one, never half */
        int fd = open(temp, O_RDONLY), synced = fd >= 0 && fsync(fd) == 0;
        if (fd >= 0) close(fd);
        if (!synced)
            status = WT_ERROR(ctx, WT_ERR_IO, "%s: cannot fsync the temporary '%s': %s", path, temp, strerror(errno));
        else if (rename(temp, path) != 0)
            status = WT_ERROR(ctx, WT_ERR_IO, "%s: cannot rename the temporary '%s' onto it: %s", path, temp,
                              strerror(errno));
    }
    if (status < 0) unlink(temp);
    return status;
}
