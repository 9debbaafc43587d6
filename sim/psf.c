/* sim/psf.c: long-exposure PSFs of the residual wavefront (SPEC §8b, psf.h): U = P exp(2πi φ/λ), zero-padded
 * N x N FFT in two 1-D passes (pupil rows, then the kept columns), |·|² / N_P² summed over the frames taken. */
#include "psf.h"

#include "../core/config/config.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define ALIGN 64
#define RAD2MAS (180.0 / M_PI * 3600.0 * 1e3)

typedef struct {
    void *block;
    fftwf_complex *rows; /* N_r x N: the pupil rows, then their x transforms */
    fftwf_complex *cols; /* n x N: the kept columns (zero below N_r), then their y transforms */
} workspace;

struct wt_psf {
    wt_context *ctx;
    wt_psf_params par;
    int ndir, N, n, nthreads;
    int x0, y0, nc, nr;  /* the pupil's bounding box on the grid: columns x0.., rows y0.. */
    int grid_nx;
    uint8_t *mask;       /* nr x nc: the pupil inside its box */
    double scale;        /* 1 / N_P² */
    double pixel;        /* θ_p [rad] */
    double *sum;         /* ndir x n x n */
    long frames;
    fftwf_plan prow, pcol;
    workspace *ws;       /* [nthreads] */
};

/* smallest m ≥ n with no prime factor above 7 (FFTW's fast sizes) */
static int good_size(int n)
{
    for (int m = n > 1 ? n : 1;; m++) {
        int r = m;
        for (int f = 2; f <= 7; f++)
            while (r % f == 0) r /= f;
        if (r == 1) return m;
    }
}

static void *carve(char **p, size_t bytes)
{
    uintptr_t a = ((uintptr_t)*p + ALIGN - 1) & ~(uintptr_t)(ALIGN - 1);
    *p = (char *)(a + bytes);
    return (void *)a;
}

void wt_psf_free(wt_psf *p)
{
    if (!p) return;
    wt_context *ctx = p->ctx;
    if (p->prow) fftwf_destroy_plan(p->prow);
    if (p->pcol) fftwf_destroy_plan(p->pcol);
    if (p->ws)
        for (int t = 0; t < p->nthreads; t++) wt_free(ctx, p->ws[t].block);
    wt_free(ctx, p->ws);
    wt_free(ctx, p->mask);
    wt_free(ctx, p->sum);
    wt_free(ctx, p);
}

void wt_psf_params_from_config(const wt_config *cfg, wt_psf_params *par)
{
    *par = (wt_psf_params){.wavelength = cfg->eval_wavelength, .diameter = cfg->diameter, .every = cfg->psf_interval,
                           .settle = cfg->settle_frames, .sampling = 2.0, .pixels = cfg->psf_pixels};
}

int wt_psf_alloc(wt_context *ctx, const wt_grid *grid, const uint8_t *mask, int ndir, const wt_psf_params *par,
                 wt_psf **out)
{
    int st = WT_OK;
    wt_psf *p = NULL;
    *out = NULL;
    if (ndir < 1 || !(par->wavelength > 0.0) || !(par->diameter > 0.0) || par->every < 1 || par->settle < 0 ||
        !(par->sampling >= 1.0 && par->sampling <= 64.0) || par->pixels < 0 || par->pixels % 2 || !(grid->dx > 0.0))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "psf: bad parameters (directions %d, wavelength %g m, diameter %g m, every %d, settle %d, "
                        "sampling %g, pixels %d, spacing %g m)",
                        ndir, par->wavelength, par->diameter, par->every, par->settle, par->sampling, par->pixels,
                        grid->dx);
    /* the pupil's bounding box and size */
    int x0 = grid->nx, x1 = -1, y0 = grid->ny, y1 = -1;
    int64_t np = 0;
    for (int iy = 0; iy < grid->ny; iy++)
        for (int ix = 0; ix < grid->nx; ix++)
            if (mask[ix + (int64_t)grid->nx * iy]) {
                np++;
                x0 = ix < x0 ? ix : x0, x1 = ix > x1 ? ix : x1;
                y0 = iy < y0 ? iy : y0, y1 = iy > y1 ? iy : y1;
            }
    if (np == 0) return WT_ERROR(ctx, WT_ERR_INVALID, "psf: the pupil mask is empty");
    WT_ALLOC(ctx, p, 1, "psf");
    p->ctx = ctx;
    p->par = *par;
    p->ndir = ndir;
    p->grid_nx = grid->nx;
    p->x0 = x0, p->y0 = y0, p->nc = x1 - x0 + 1, p->nr = y1 - y0 + 1;
    /* N dx ≥ q D (a pixel λ/(N dx) ≤ λ/(qD)), and the pupil's box fits */
    int need = (int)ceil(par->sampling * par->diameter / grid->dx - 1e-9);
    need = need > p->nc ? need : p->nc;
    need = need > p->nr ? need : p->nr;
    p->N = good_size(need);
    /* an image cannot hold more than the transform's N samples per side */
    p->n = par->pixels ? par->pixels : WT_PSF_DEFAULT_PIXELS;
    if (p->n > p->N) p->n = p->N - p->N % 2;
    p->scale = 1.0 / ((double)np * (double)np);
    p->pixel = par->wavelength / (p->N * grid->dx);
    WT_ALLOC(ctx, p->mask, (size_t)p->nr * p->nc, "psf pupil");
    for (int r = 0; r < p->nr; r++)
        memcpy(p->mask + (size_t)r * p->nc, mask + (x0 + (int64_t)grid->nx * (y0 + r)), (size_t)p->nc);
    WT_ALLOC(ctx, p->sum, (size_t)ndir * p->n * p->n, "psf sums");
#ifdef _OPENMP
    p->nthreads = wt_context_threads(ctx);
#else
    p->nthreads = 1;
#endif
    if (p->nthreads < 1) p->nthreads = 1;
    if (p->nthreads > ndir) p->nthreads = ndir;
    WT_ALLOC(ctx, p->ws, p->nthreads, "psf workspaces");
    const size_t brow = (size_t)p->nr * p->N * sizeof(fftwf_complex), bcol = (size_t)p->n * p->N * sizeof(fftwf_complex);
    for (int t = 0; t < p->nthreads; t++) {
        workspace *w = &p->ws[t];
        if (!(w->block = wt_malloc(ctx, brow + bcol + 2 * ALIGN, 1))) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "psf: out of memory for a thread workspace (%zu bytes)", brow + bcol);
            goto fail;
        }
        char *c = w->block;
        w->rows = carve(&c, brow);
        w->cols = carve(&c, bcol);
    }
    {
        /* plans on workspace 0; every workspace's arrays share its 64-byte alignment, so fftwf_execute_dft
         * may run them on any thread's arrays (FFTW's new-array rule); FFTW_ESTIMATE does not touch them */
        int nn[1] = {p->N};
        p->prow = fftwf_plan_many_dft(1, nn, p->nr, p->ws[0].rows, NULL, 1, p->N, p->ws[0].rows, NULL, 1, p->N,
                                      FFTW_FORWARD, FFTW_ESTIMATE);
        p->pcol = fftwf_plan_many_dft(1, nn, p->n, p->ws[0].cols, NULL, 1, p->N, p->ws[0].cols, NULL, 1, p->N,
                                      FFTW_FORWARD, FFTW_ESTIMATE);
        if (!p->prow || !p->pcol) {
            st = WT_ERROR(ctx, WT_ERR_LIBRARY, "psf: fftwf_plan_many_dft(%d) returned NULL", p->N);
            goto fail;
        }
    }
    *out = p;
    return WT_OK;
fail:
    wt_psf_free(p);
    return st;
}

/* The image of one residual map into sum (n x n), with workspace w. */
static void image_one(const wt_psf *p, const double *opd, workspace *w, double *sum)
{
    const int N = p->N, n = p->n, h = n / 2, nr = p->nr, nc = p->nc;
    const double k = 2.0 * M_PI / p->par.wavelength;
    fftwf_complex *A = w->rows, *B = w->cols;
    /* U on the pupil's box in the first nc columns of nr rows (its place in the padded array only multiplies
     * the transform by a phase ramp, which |·|² removes) */
    for (int r = 0; r < nr; r++) {
        const double *o = opd + p->x0 + (int64_t)p->grid_nx * (p->y0 + r);
        const uint8_t *m = p->mask + (size_t)r * nc;
        fftwf_complex *a = A + (size_t)r * N;
        for (int c = 0; c < nc; c++) {
            if (!m[c]) {
                a[c][0] = a[c][1] = 0.0f;
                continue;
            }
            /* phase reduced to [−π, π] in double before the float sin/cos: a large piston keeps its precision */
            double ph = k * o[c];
            ph -= 2.0 * M_PI * nearbyint(ph * (0.5 / M_PI));
            const float f = (float)ph;
            a[c][0] = cosf(f);
            a[c][1] = sinf(f);
        }
        memset(a + nc, 0, (size_t)(N - nc) * sizeof *a);
    }
    fftwf_execute_dft(p->prow, A, A);
    /* the n kept x frequencies kx = c − h (mod N), each a column of nr values padded to N, transformed in y;
     * gathered row by row (a row's kept values are two runs of h: a few cache lines) into B (L2-sized) */
    for (int r = 0; r < nr; r++) {
        const fftwf_complex *a = A + (size_t)r * N;
        for (int c = 0; c < n; c++) {
            const int kx = c < h ? N - h + c : c - h;
            B[(size_t)c * N + r][0] = a[kx][0], B[(size_t)c * N + r][1] = a[kx][1];
        }
    }
    for (int c = 0; c < n; c++) memset(B + (size_t)c * N + nr, 0, (size_t)(N - nr) * sizeof *B);
    fftwf_execute_dft(p->pcol, B, B);
    for (int c = 0; c < n; c++) {
        const fftwf_complex *b = B + (size_t)c * N;
        for (int q = 0; q < n; q++) {
            const float *z = b[(q - h + N) % N];
            sum[c + (size_t)n * q] += p->scale * ((double)z[0] * z[0] + (double)z[1] * z[1]);
        }
    }
}

void wt_psf_add(wt_psf *p, const double *const *opd)
{
    const size_t nn = (size_t)p->n * p->n;
    /* one direction per work item: its sum is written by one thread, so the bits do not depend on the threads */
#pragma omp parallel for schedule(dynamic, 1) num_threads(p->nthreads)
    for (int j = 0; j < p->ndir; j++) {
        int t = 0;
#ifdef _OPENMP
        t = omp_get_thread_num();
#endif
        image_one(p, opd[j], &p->ws[t], p->sum + nn * j);
    }
    p->frames++;
}

int wt_psf_frame(wt_psf *p, long t, const double *const *opd)
{
    if (t < p->par.settle || (t - p->par.settle) % p->par.every) return 0;
    wt_psf_add(p, opd);
    return 1;
}

int wt_psf_ndir(const wt_psf *p) { return p->ndir; }
long wt_psf_frames(const wt_psf *p) { return p->frames; }
int wt_psf_pixels(const wt_psf *p) { return p->n; }
int wt_psf_fft_size(const wt_psf *p) { return p->N; }
double wt_psf_pixel_scale(const wt_psf *p) { return p->pixel; }
double wt_psf_wavelength(const wt_psf *p) { return p->par.wavelength; }
double wt_psf_pixel_lod(const wt_psf *p) { return p->pixel * p->par.diameter / p->par.wavelength; }

void wt_psf_image(const wt_psf *p, int j, float *img)
{
    const size_t nn = (size_t)p->n * p->n;
    const double f = p->frames ? 1.0 / p->frames : 0.0;
    for (size_t i = 0; i < nn; i++) img[i] = (float)(p->sum[nn * j + i] * f);
}

double wt_psf_strehl(const wt_psf *p, int j)
{
    const size_t nn = (size_t)p->n * p->n;
    double m = 0.0;
    for (size_t i = 0; i < nn; i++) m = p->sum[nn * j + i] > m ? p->sum[nn * j + i] : m;
    return p->frames ? m / p->frames : 0.0;
}

int wt_psf_write_images(wt_h5_writer *w, const char *group, int nrun, int ndir, int n, const float *img,
                        const double *strehl, double wavelength, double pixel_lod, double pixel_rad, long frames,
                        int every, int fft_size)
{
    char name[256], sname[256];
    snprintf(name, sizeof name, "%s/image", group);
    snprintf(sname, sizeof sname, "%s/strehl_peak", group);
    const int lead = nrun > 0;
    int64_t d3[4] = {nrun, ndir, n, n}, d1[2] = {nrun, ndir};
    int st;
    if ((st = wt_h5_write(w, name, WT_H5_F32, WT_H5_F32, 3 + lead, d3 + !lead, img, "",
                          lead ? "long-exposure PSF per seed and evaluation direction (index as eval/theta_x), n x n "
                                 "pixels (row = y, pixel (ix, iy) at angle ((ix - n/2), (iy - n/2)) x pixel scale), "
                                 "normalised so the diffraction-limited PSF of the same pupil peaks at 1"
                               : "long-exposure PSF per evaluation direction (index as eval/theta_x), n x n pixels "
                                 "(row = y, pixel (ix, iy) at angle ((ix - n/2), (iy - n/2)) x pixel scale), "
                                 "normalised so the diffraction-limited PSF of the same pupil peaks at 1")) < 0 ||
        (st = wt_h5_attr_write_double(w, name, "wavelength_nm", wavelength * 1e9)) < 0 ||
        (st = wt_h5_attr_write_double(w, name, "pixel_lambda_over_d", pixel_lod)) < 0 ||
        (st = wt_h5_attr_write_double(w, name, "pixel_mas", pixel_rad * RAD2MAS)) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "frames", frames)) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "every", every)) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "fft_size", fft_size)) < 0 ||
        (st = wt_h5_attr_write_string(w, name, "normalisation", "diffraction-limited peak = 1")) < 0)
        return st;
    if ((st = wt_h5_write(w, sname, WT_H5_F64, WT_H5_F64, 1 + lead, d1 + !lead, strehl, "",
                          "PSF-peak Strehl per evaluation direction: the peak of the long-exposure PSF (compare "
                          "with the Marechal eval/strehl_le)")) < 0)
        return st;
    return WT_OK;
}

static void gather(const wt_psf *p, float *img, double *s);

int wt_psf_write(const wt_psf *p, wt_h5_writer *w, const char *group)
{
    int st = WT_OK;
    float *img = NULL;
    double *s = NULL;
    const size_t nn = (size_t)p->n * p->n;
    WT_ALLOC(p->ctx, img, nn * p->ndir, "psf images");
    WT_ALLOC(p->ctx, s, p->ndir, "psf Strehl");
    gather(p, img, s);
    st = wt_psf_write_images(w, group, 0, p->ndir, p->n, img, s, p->par.wavelength, wt_psf_pixel_lod(p), p->pixel,
                             p->frames, p->par.every, p->N);
fail:
    wt_free(p->ctx, img);
    wt_free(p->ctx, s);
    return st;
}

/* the mean images and peaks of p into img [ndir n n] and s [ndir] */
static void gather(const wt_psf *p, float *img, double *s)
{
    const size_t nn = (size_t)p->n * p->n;
    for (int j = 0; j < p->ndir; j++) {
        wt_psf_image(p, j, img + nn * j);
        s[j] = wt_psf_strehl(p, j);
    }
}

int wt_psf_write_bands(const wt_psf *const *p, int nw, wt_h5_writer *w, const char *group)
{
    wt_context *ctx = p[0]->ctx;
    const int ndir = p[0]->ndir, n = p[0]->n;
    for (int k = 1; k < nw; k++)
        if (p[k]->ndir != ndir || p[k]->n != n || p[k]->N != p[0]->N)
            return WT_ERROR(ctx, WT_ERR_INVALID, "psf: band %d has %d directions of %d pixels (N %d), band 0 %d of %d (N %d)",
                            k, p[k]->ndir, p[k]->n, p[k]->N, ndir, n, p[0]->N);
    int st = WT_OK;
    float *img = NULL;
    double *s = NULL, lnm[WT_MAX_PSF_WAVELENGTHS], mas[WT_MAX_PSF_WAVELENGTHS];
    if (nw < 1 || nw > WT_MAX_PSF_WAVELENGTHS)
        return WT_ERROR(ctx, WT_ERR_INVALID, "psf: %d wavelengths (1 to %d)", nw, WT_MAX_PSF_WAVELENGTHS);
    const size_t nn = (size_t)n * n;
    WT_ALLOC(ctx, img, nn * ndir * nw, "psf images");
    WT_ALLOC(ctx, s, (size_t)ndir * nw, "psf Strehl");
    for (int k = 0; k < nw; k++) {
        gather(p[k], img + nn * ndir * k, s + (size_t)ndir * k);
        lnm[k] = p[k]->par.wavelength * 1e9;
        mas[k] = p[k]->pixel * RAD2MAS;
    }
    char name[256];
    const int64_t d4[4] = {nw, ndir, n, n}, d2[2] = {nw, ndir}, d1[1] = {nw};
    snprintf(name, sizeof name, "%s/image", group);
    if ((st = wt_h5_write(w, name, WT_H5_F32, WT_H5_F32, 4, d4, img, "",
                          "long-exposure PSF per wavelength (index as wavelength_nm) and evaluation direction (index as "
                          "eval/theta_x), n x n pixels as psf/image, pixel scale pixel_mas of its wavelength, normalised "
                          "so the diffraction-limited PSF of the same pupil peaks at 1")) < 0 ||
        (st = wt_h5_attr_write_double(w, name, "pixel_lambda_over_d", wt_psf_pixel_lod(p[0]))) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "frames", p[0]->frames)) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "every", p[0]->par.every)) < 0 ||
        (st = wt_h5_attr_write_int64(w, name, "fft_size", p[0]->N)) < 0 ||
        (st = wt_h5_attr_write_string(w, name, "normalisation", "diffraction-limited peak = 1")) < 0)
        goto fail;
    snprintf(name, sizeof name, "%s/strehl_peak", group);
    if ((st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 2, d2, s, "",
                          "PSF-peak Strehl per wavelength and evaluation direction: the peak of image")) < 0)
        goto fail;
    snprintf(name, sizeof name, "%s/wavelength_nm", group);
    if ((st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 1, d1, lnm, "nm", "wavelength of each band (sim.psf_wavelengths_nm)")) < 0)
        goto fail;
    snprintf(name, sizeof name, "%s/pixel_mas", group);
    st = wt_h5_write(w, name, WT_H5_F64, WT_H5_F64, 1, d1, mas, "mas", "pixel scale of each band's images: lambda/(N dx)");
fail:
    wt_free(ctx, img);
    wt_free(ctx, s);
    return st;
}

int wt_psf_write_fits(const wt_psf *p, const char *path, const wt_fits_psf *meta)
{
    int st = WT_OK;
    float *img = NULL;
    double *s = NULL;
    WT_ALLOC(p->ctx, img, (size_t)p->n * p->n * p->ndir, "psf images");
    WT_ALLOC(p->ctx, s, p->ndir, "psf Strehl");
    gather(p, img, s);
    wt_fits_psf f = *meta;
    f.wavelength = p->par.wavelength, f.n = p->n, f.ndir = p->ndir, f.image = img, f.strehl = s;
    f.pixel = p->pixel, f.pixel_lod = wt_psf_pixel_lod(p), f.fft_size = p->N, f.frames = p->frames;
    f.every = p->par.every, f.diameter = p->par.diameter;
    st = wt_fits_write_psf(p->ctx, path, &f);
fail:
    wt_free(p->ctx, img);
    wt_free(p->ctx, s);
    return st;
}
