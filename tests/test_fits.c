/* tests/test_fits.c: the FITS export of PSFs (core/io/fits.h, `sim --fits`): a synthetic cube written and read
 * back with CFITSIO (shapes, keywords, pixels, the Strehl map and the directions' table, refusals that leave
 * nothing behind), and a demo run's files against its RUN.h5 (the same images, peaks and Strehl map, the
 * pixel scale λ/(N dx) of each band, the configuration's hash), with the bands of sim.psf_wavelengths_nm. */
#include <fitsio.h>
#include <sys/stat.h>

#include "core/base/sha256.h"
#include "core/io/fits.h"
#include "core/io/h5.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"
#define RAD2ARCSEC (180.0 / M_PI * 3600.0)

static char dir[64], wt[512];
static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_fits_"); }
static void teardown(void) { tu_cli_teardown(dir); }

static double key_double(fitsfile *f, const char *key)
{
    int fs = 0;
    double v = NAN;
    fits_read_key(f, TDOUBLE, key, &v, NULL, &fs);
    ck_assert_msg(fs == 0, "keyword %s: CFITSIO status %d", key, fs);
    return v;
}

static void key_string(fitsfile *f, const char *key, char *v)
{
    int fs = 0;
    fits_read_key(f, TSTRING, key, v, NULL, &fs);
    ck_assert_msg(fs == 0, "keyword %s: CFITSIO status %d", key, fs);
}

/* the primary cube's shape and pixels into img (n n nd floats, allocated) */
static float *read_cube(fitsfile *f, long *axes)
{
    int fs = 0, naxis = 0, bitpix = 0, any = 0;
    fits_get_img_param(f, 3, &bitpix, &naxis, axes, &fs);
    ck_assert_int_eq(fs, 0);
    ck_assert_int_eq(naxis, 3);
    ck_assert_int_eq(bitpix, FLOAT_IMG);
    const long np = axes[0] * axes[1] * axes[2];
    float *img = malloc((size_t)np * sizeof *img);
    fits_read_img(f, TFLOAT, 1, np, NULL, img, &any, &fs);
    ck_assert_int_eq(fs, 0);
    return img;
}

static void read_column(fitsfile *f, int col, long rows, double *v)
{
    int fs = 0, any = 0;
    fits_read_col(f, TDOUBLE, col, 1, 1, rows, NULL, v, &any, &fs);
    ck_assert_int_eq(fs, 0);
}

/* A 2 x 2 grid of 8 x 8 images with known values: every number written comes back exactly (float32 pixels,
 * float64 keywords and columns are stored in their own binary types; keywords print 15+ digits). */
START_TEST(test_roundtrip_synthetic)
{
    enum { n = 8, g = 2, nd = 4 };
    static float img[nd * n * n];
    double strehl[nd], wfe[nd], tx[nd], ty[nd];
    const double spacing = 30.0 / RAD2ARCSEC, lambda = 1.65e-6, pixel = lambda / (64 * 0.25);
    for (int i = 0; i < nd * n * n; i++) img[i] = (float)(0.001 * (i % 97));
    for (int j = 0; j < nd; j++) {
        img[j * n * n + n / 2 + n * (n / 2)] = (float)(0.2 + 0.1 * j); /* the peak */
        strehl[j] = 0.2 + 0.1 * j, wfe[j] = (150.0 + 10 * j) * 1e-9;
        tx[j] = ((j % g) - 0.5) * spacing, ty[j] = ((j / g) - 0.5) * spacing;
    }
    const char *hash = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
    wt_fits_psf p = {.wavelength = lambda, .n = n, .ndir = nd, .image = img, .strehl = strehl, .wfe = wfe,
                     .theta_x = tx, .theta_y = ty, .grid = g, .spacing = spacing, .pixel = pixel, .pixel_lod = 0.5,
                     .fft_size = 64, .frames = 7, .every = 3, .diameter = 8.0, .obstruction = 0.28,
                     .telescope = "simulated D = 8 m (test)", .recon = "pcg3", .seed = 42, .config_sha256 = hash,
                     .creator = "wavetomo test"};
    wt_context *ctx = tu_context();
    char path[128], name[64];
    wt_fits_psf_name(lambda, name, sizeof name);
    ck_assert_str_eq(name, "psf_1650nm.fits");
    snprintf(path, sizeof path, "%s/%s", dir, name);
    ck_assert_msg(wt_fits_write_psf(ctx, path, &p) == WT_OK, "%s", wt_error_message(ctx));
    /* written again: replaced through its temporary, no temporary left */
    ck_assert_msg(wt_fits_write_psf(ctx, path, &p) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(tu_run("ls", dir, "%s | grep -c tmp", dir), 1); /* grep -c: no match → exit 1 */

    fitsfile *f;
    int fs = 0, hdus = 0;
    fits_open_file(&f, path, READONLY, &fs);
    ck_assert_int_eq(fs, 0);
    fits_get_num_hdus(f, &hdus, &fs);
    ck_assert_int_eq(hdus, 3);
    long axes[3];
    float *back = read_cube(f, axes);
    ck_assert(axes[0] == n && axes[1] == n && axes[2] == nd);
    ck_assert(!memcmp(back, img, sizeof img));
    free(back);
    ck_assert_double_eq(key_double(f, "WAVELENG"), lambda);
    ck_assert_rel(key_double(f, "PIXSCALE"), pixel * RAD2ARCSEC, 1e-15, 0.0);
    ck_assert_double_eq(key_double(f, "PIXLOD"), 0.5);
    ck_assert_double_eq(key_double(f, "SAMPLING"), 2.0);
    ck_assert_double_eq(key_double(f, "CRPIX1"), n / 2 + 1);
    ck_assert_double_eq(key_double(f, "FFTSIZE"), 64);
    ck_assert_double_eq(key_double(f, "NFRAMES"), 7);
    ck_assert_double_eq(key_double(f, "SEED"), 42);
    char s[FLEN_VALUE];
    key_string(f, "CONFHASH", s);
    ck_assert_str_eq(s, hash);
    key_string(f, "TELESCOP", s);
    ck_assert_str_eq(s, "simulated D = 8 m (test)");
    key_string(f, "DATE", s);
    ck_assert_int_eq(strlen(s), 19); /* YYYY-MM-DDThh:mm:ss */

    /* the Strehl map: the grid's x fastest, centred world coordinates */
    fits_movnam_hdu(f, IMAGE_HDU, "STREHL", 0, &fs);
    ck_assert_int_eq(fs, 0);
    double map[nd];
    int any = 0;
    fits_read_img(f, TDOUBLE, 1, nd, NULL, map, &any, &fs);
    ck_assert_int_eq(fs, 0);
    for (int j = 0; j < nd; j++) ck_assert_double_eq(map[j], strehl[j]);
    ck_assert_double_eq(key_double(f, "CRPIX1"), 1.5);
    ck_assert_rel(key_double(f, "CDELT2"), 30.0, 1e-15, 0.0);

    /* the table: directions in arcsec, Strehl, Maréchal of the WFE, WFE in nm */
    fits_movnam_hdu(f, BINARY_TBL, "DIRECTIONS", 0, &fs);
    ck_assert_int_eq(fs, 0);
    long rows = 0;
    fits_get_num_rows(f, &rows, &fs);
    ck_assert_int_eq(rows, nd);
    /* every keyword once (a column's comment is modified, not a second TTYPE written) */
    int nkeys = 0, more = 0, ttype4 = 0;
    fits_get_hdrspace(f, &nkeys, &more, &fs);
    for (int i = 1; i <= nkeys; i++) {
        char card[FLEN_CARD];
        fits_read_record(f, i, card, &fs);
        ttype4 += !strncmp(card, "TTYPE4  =", 9);
    }
    ck_assert_int_eq(fs, 0);
    ck_assert_int_eq(ttype4, 1);
    char comment[FLEN_COMMENT];
    fits_read_key(f, TSTRING, "TTYPE4", s, comment, &fs);
    ck_assert_str_eq(s, "STREHL");
    ck_assert_ptr_nonnull(strstr(comment, "PSF-peak Strehl"));
    double c[6][nd];
    for (int k = 0; k < 6; k++) read_column(f, k + 1, nd, c[k]);
    for (int j = 0; j < nd; j++) {
        ck_assert_double_eq(c[0][j], j);
        ck_assert_rel(c[1][j], tx[j] * RAD2ARCSEC, 1e-15, 0.0);
        ck_assert_rel(c[2][j], ty[j] * RAD2ARCSEC, 1e-15, 0.0);
        ck_assert_double_eq(c[3][j], strehl[j]);
        ck_assert_rel(c[4][j], exp(-pow(2 * M_PI * wfe[j] / lambda, 2)), 1e-14, 0.0);
        ck_assert_rel(c[5][j], wfe[j] * 1e9, 1e-15, 0.0);
    }
    fits_close_file(f, &fs);

    /* refusals: sizes that disagree, a missing directory (nothing left behind) */
    p.grid = 3;
    ck_assert_int_eq(wt_fits_write_psf(ctx, path, &p), WT_ERR_INVALID);
    p.grid = g;
    snprintf(path, sizeof path, "%s/missing/x.fits", dir);
    ck_assert_int_eq(wt_fits_write_psf(ctx, path, &p), WT_ERR_IO);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "missing/x.fits"));
    wt_context_free(ctx);
}
END_TEST

/* plane sums and peaks of a float cube, in double */
static void plane_stats(const float *img, long nn, long nd, double *sum, double *peak)
{
    for (long j = 0; j < nd; j++) {
        sum[j] = 0.0, peak[j] = 0.0;
        for (long i = 0; i < nn; i++) {
            sum[j] += img[nn * j + i];
            peak[j] = img[nn * j + i] > peak[j] ? img[nn * j + i] : peak[j];
        }
    }
}

/* A demo run with two bands: each band's FITS cube is bit for bit the HDF5's psf/wavelengths/image plane (so the
 * sums and peaks agree to rounding of the sums' order), its STREHL map is psf/wavelengths/strehl_peak, its pixel
 * scale the band's pixel_mas; the band at evaluation.wavelength_nm equals psf/image; CONFHASH is the SHA-256 of
 * the stored configuration. Without the key: no psf/wavelengths, one file at the evaluation wavelength. */
START_TEST(test_sim_fits_against_h5)
{
    ck_assert_int_eq(tu_run(wt, dir,
                            "sim " DEMO " --frames 12 --set evaluation.settle_frames=4 --set sim.psf_interval_frames=2 "
                            "--set 'sim.psf_wavelengths_nm=[1650.0, 2200.0]' --threads 2 --quiet --out %s/run.h5 "
                            "--fits %s/fits",
                            dir, dir),
                     0);
    wt_context *ctx = tu_context();
    char path[256];
    snprintf(path, sizeof path, "%s/run.h5", dir);
    wt_h5_reader *r;
    ck_assert_msg(wt_h5_open(ctx, path, &r) == WT_OK, "%s", wt_error_message(ctx));
    int64_t dims[4];
    int rank;
    ck_assert_int_eq(wt_h5_dims(r, "psf/wavelengths/image", &rank, dims), WT_OK);
    ck_assert_int_eq(rank, 4);
    ck_assert_int_eq(dims[0], 2);
    const long nd = (long)dims[1], n = (long)dims[2], nn = n * n;
    float *h5img = malloc((size_t)(2 * nd * nn) * sizeof *h5img), *eval = malloc((size_t)(nd * nn) * sizeof *eval);
    double sp[2 * 225], lnm[2], mas[2];
    ck_assert_int_eq(wt_h5_read(r, "psf/wavelengths/image", WT_H5_F32, 4, dims, NULL, h5img, (size_t)(2 * nd * nn)), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "psf/image", WT_H5_F32, 3, dims + 1, NULL, eval, (size_t)(nd * nn)), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "psf/wavelengths/strehl_peak", WT_H5_F64, 2, dims, NULL, sp, 2 * 225), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "psf/wavelengths/wavelength_nm", WT_H5_F64, 1, dims, NULL, lnm, 2), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "psf/wavelengths/pixel_mas", WT_H5_F64, 1, dims, NULL, mas, 2), WT_OK);
    ck_assert(lnm[0] == 1650.0 && lnm[1] == 2200.0);
    ck_assert(!memcmp(h5img + nd * nn, eval, (size_t)(nd * nn) * sizeof *eval)); /* 2200 nm = evaluation's */
    ck_assert_rel(mas[0] / mas[1], 1650.0 / 2200.0, 1e-14, 0.0); /* the same N: θ_p ∝ λ */
    char *text = NULL, hash[65];
    ck_assert_int_eq(wt_h5_read_string(r, "config", &text), WT_OK);
    wt_sha256_hex(text, strlen(text), hash);
    wt_free(ctx, text);
    wt_h5_close(r);

    for (int k = 0; k < 2; k++) {
        char name[64];
        wt_fits_psf_name(lnm[k] * 1e-9, name, sizeof name);
        snprintf(path, sizeof path, "%s/fits/%s", dir, name);
        fitsfile *f;
        int fs = 0;
        fits_open_file(&f, path, READONLY, &fs);
        ck_assert_msg(fs == 0, "%s: CFITSIO status %d", path, fs);
        long axes[3];
        float *img = read_cube(f, axes);
        ck_assert(axes[0] == n && axes[1] == n && axes[2] == nd);
        double s1[225], p1[225], s2[225], p2[225];
        plane_stats(img, nn, nd, s1, p1);
        plane_stats(h5img + k * nd * nn, nn, nd, s2, p2);
        for (long j = 0; j < nd; j++) {
            ck_assert_rel(s1[j], s2[j], 1e-12, 0.0);
            ck_assert_double_eq(p1[j], p2[j]);
            ck_assert_rel(p1[j], sp[k * nd + j], 1e-6, 0.0); /* float32 image of the double peak */
        }
        free(img);
        ck_assert_double_eq(key_double(f, "WAVELENG"), lnm[k] * 1e-9);
        ck_assert_rel(key_double(f, "PIXSCALE"), mas[k] * 1e-3, 1e-14, 0.0);
        ck_assert_double_eq(key_double(f, "SAMPLING"), 2.0);
        char s[FLEN_VALUE];
        key_string(f, "CONFHASH", s);
        ck_assert_str_eq(s, hash);
        fits_movnam_hdu(f, IMAGE_HDU, "STREHL", 0, &fs);
        double map[225];
        int any = 0;
        fits_read_img(f, TDOUBLE, 1, nd, NULL, map, &any, &fs);
        ck_assert_int_eq(fs, 0);
        for (long j = 0; j < nd; j++) ck_assert_double_eq(map[j], sp[k * nd + j]);
        fits_close_file(f, &fs);
    }
    free(h5img);
    free(eval);

    /* the default: the evaluation wavelength's file only, no bands in RUN.h5 */
    ck_assert_int_eq(tu_run(wt, dir,
                            "sim " DEMO " --frames 6 --set evaluation.settle_frames=2 --threads 2 --quiet "
                            "--out %s/run0.h5 --fits %s/fits0",
                            dir, dir),
                     0);
    struct stat sb;
    snprintf(path, sizeof path, "%s/fits0/psf_2200nm.fits", dir);
    ck_assert_int_eq(stat(path, &sb), 0);
    snprintf(path, sizeof path, "%s/run0.h5", dir);
    ck_assert_int_eq(wt_h5_open(ctx, path, &r), WT_OK);
    ck_assert(!wt_h5_exists(r, "psf/wavelengths"));
    wt_h5_close(r);

    /* refusals: a file of that name that is not FITS (before the run: no RUN.h5), no PSFs to export, a wavelength
     * given twice (naming the key) */
    snprintf(path, sizeof path, "%s/fits0/psf_2200nm.fits", dir);
    FILE *fp = fopen(path, "w");
    ck_assert_ptr_nonnull(fp);
    fputs("not a FITS file\n", fp);
    fclose(fp);
    ck_assert_int_eq(tu_run(wt, dir, "sim " DEMO " --frames 6 --set evaluation.settle_frames=2 --quiet --out %s/run3.h5 "
                                     "--fits %s/fits0", dir, dir),
                     1);
    ck_assert(tu_file_has(dir, "stderr.txt", "psf_2200nm.fits' exists and is not a wavetomo output"));
    snprintf(path, sizeof path, "%s/run3.h5", dir);
    ck_assert_int_ne(stat(path, &sb), 0);

    ck_assert_int_eq(tu_run(wt, dir,
                            "sim " DEMO " --frames 6 --set evaluation.settle_frames=2 --set sim.psf_interval_frames=0 "
                            "--quiet --out %s/run1.h5 --fits %s/fits1", dir, dir),
                     1);
    ck_assert(tu_file_has(dir, "stderr.txt", "sim.psf_interval_frames = 0"));
    ck_assert_int_ne(tu_run(wt, dir,
                            "sim " DEMO " --frames 6 --set 'sim.psf_wavelengths_nm=[1650.0, 1650.0]' --quiet "
                            "--out %s/run2.h5", dir),
                     0);
    ck_assert(tu_file_has(dir, "stderr.txt", "sim.psf_wavelengths_nm"));
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("fits");
    TCase *tc = tcase_create("core");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_roundtrip_synthetic);
    tcase_add_test(tc, test_sim_fits_against_h5);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
