/* tests/bench_ngs.c: `make bench-ngs`: cost and accuracy of the diffractive E-ELT NGS sensors (issue 19 item
 * 1/4: the 1x1 tip-tilt sensors see the whole partially corrected 42 m pupil, the 2x2 four 21 m quadrants)
 * against the pupil sampling n_p, the FFT size N, the pixels Ns (of 0.05") and the rebinning cells k.
 *
 * Per setting: the three NGS of eelt-mcao (two 1x1, one 2x2: 6 subapertures, H band, 0.05" pixels, tCoG
 * 3 sigma, 500 photons, 5 e- read noise) built as core/model/sensing.c builds them (amplitudes = lit
 * fraction of each sample's square), timed per frame (images + noise + tCoG; CPU time / threads and the
 * wall median); the set-up NEA (analytic, median over subapertures) and the tCoG gain (mean diagonal);
 * the noise-free slopes of `screens` partially corrected residual OPDs against the finest setting's (rms
 * over screens and axes, [mas]), and the largest |slope| the screens produce. The residual: a von
 * Karman screen (r0 0.129 m at 500 nm, L0 25 m) on a 1024² grid of 8.2 cm over 84 m, its power below the
 * DM cut-off 1/(2 x 0.5 m) scaled by `lowfrac` (the MCAO's partial correction at the NGS) plus a random
 * tip-tilt of `tt` mas rms per axis (the tip-tilt excursions the FFT field must hold); sampled bilinearly
 * at the pupil samples as the loop does.
 * Usage: bench_ngs [threads=2] [screens=20] [lowfrac=0.01] [tt_mas=20] [frames=9] [field] */
#include <fftw3.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/base/base.h"
#include "core/base/rng.h"
#include "core/op/pupil.h"
#include "core/optics/centroid.h"
#include "core/optics/spot.h"

#define AS (M_PI / 180.0 / 3600.0)
#define MAS (AS / 1000.0)
#define GN 1024
#define GL 84.0

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* one sensor kind: m x m subapertures over D */
typedef struct {
    int nsub;
    double xc[4], yc[4], side;
    wt_spot *s;
    wt_centroid *c;
    float *amp, *opd, *img;
} sensor;

static int sensor_alloc(wt_context *ctx, int m, int np, int N, int Ns, int k, sensor *o)
{
    const double D = 42.0, obs = 0.28, d = D / m;
    memset(o, 0, sizeof *o);
    o->side = d;
    for (int j = 0; j < m; j++)
        for (int i = 0; i < m; i++) o->xc[o->nsub] = -D / 2 + (i + 0.5) * d, o->yc[o->nsub++] = -D / 2 + (j + 0.5) * d;
    o->amp = malloc(sizeof(float) * o->nsub * np * np);
    o->opd = calloc((size_t)o->nsub * np * np, sizeof(float));
    o->img = malloc(sizeof(float) * o->nsub * Ns * Ns);
    double lit[4], dx = d / np;
    for (int s = 0; s < o->nsub; s++) {
        const double x0 = o->xc[s] - d / 2, y0 = o->yc[s] - d / 2;
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++)
                o->amp[(size_t)s * np * np + i + np * j] = (float)wt_pupil_fraction(D, obs, x0 + i * dx, y0 + j * dx, dx);
        lit[s] = 1.0; /* the star's photons per subaperture (sensing.h) */
    }
    wt_spot_params p = {0};
    p.wavelength = 1650e-9, p.subap_side = d, p.pupil_samples = np, p.fft_size = N, p.npix = Ns;
    p.pixel = 0.05 * AS, p.cells_per_pixel = k, p.photons = 500, p.read_noise = 5;
    if (wt_spot_alloc(ctx, &p, o->nsub, o->xc, o->yc, o->amp, lit, &o->s)) return 1;
    float *i0 = malloc(sizeof(float) * o->nsub * Ns * Ns * 3);
    wt_spot_reference(o->s, 0, NULL, i0, i0 + o->nsub * Ns * Ns, i0 + 2 * o->nsub * Ns * Ns);
    wt_centroid_params cp = {.method = WT_CENTROID_TCOG, .threshold_noise = 3.0, .apply_gain = 1, .pixel = p.pixel,
                             .read_noise = 5};
    int st = wt_centroid_alloc(ctx, &cp, o->nsub, Ns, i0, i0 + o->nsub * Ns * Ns, i0 + 2 * o->nsub * Ns * Ns, &o->c);
    free(i0);
    return st != 0;
}

static void sensor_free(sensor *o)
{
    wt_spot_free(o->s);
    wt_centroid_free(o->c);
    free(o->amp), free(o->opd), free(o->img);
}

/* bilinear sample of the screen at the pupil samples, plus the tilt (tx, ty) [rad] */
static void sample(sensor *o, int np, const double *scr, double tx, double ty)
{
    const double d = o->side, dx = d / np, h = GL / GN;
    for (int s = 0; s < o->nsub; s++)
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++) {
                const double x = o->xc[s] + (i + 0.5 - 0.5 * np) * dx, y = o->yc[s] + (j + 0.5 - 0.5 * np) * dx;
                const double u = (x + GL / 2) / h, v = (y + GL / 2) / h;
                const int a = (int)floor(u), b = (int)floor(v);
                const double fu = u - a, fv = v - b;
                const double *p = scr + a + (size_t)GN * b;
                o->opd[(size_t)s * np * np + i + np * j] =
                    (float)((1 - fv) * ((1 - fu) * p[0] + fu * p[1]) + fv * ((1 - fu) * p[GN] + fu * p[GN + 1]) +
                            tx * x + ty * y);
            }
}

int main(int argc, char **argv)
{
    const int nth = argc > 1 ? atoi(argv[1]) : 2, nscr = argc > 2 ? atoi(argv[2]) : 20;
    const double lowfrac = argc > 3 ? atof(argv[3]) : 0.01, tt = (argc > 4 ? atof(argv[4]) : 20.0) * MAS;
    const int frames = argc > 5 ? atoi(argv[5]) : 9;
    wt_context *ctx = wt_context_alloc();
    wt_context_set_threads(ctx, nth);

    /* the residual screens [m of OPD] */
    double *scr = malloc(sizeof(double) * GN * GN * nscr);
    {
        fftw_complex *f = fftw_malloc(sizeof(fftw_complex) * GN * GN);
        fftw_plan pl = fftw_plan_dft_2d(GN, GN, f, f, FFTW_BACKWARD, FFTW_ESTIMATE);
        const double r0 = 0.129, L0 = 25.0, df = 1.0 / GL, fc = 1.0 / (2 * 0.5), k500 = 500e-9 / (2 * M_PI);
        wt_rng r;
        wt_rng_init(&r, 2024, 0);
        double var = 0;
        for (int t = 0; t < nscr; t++) {
            for (int j = 0; j < GN; j++)
                for (int i = 0; i < GN; i++) {
                    const double fx = (i < GN / 2 ? i : i - GN) * df, fy = (j < GN / 2 ? j : j - GN) * df;
                    const double f2 = fx * fx + fy * fy;
                    double psd = 0.023 * pow(r0, -5.0 / 3) * pow(f2 + 1.0 / (L0 * L0), -11.0 / 6); /* rad² m² at 500 nm */
                    if (sqrt(f2) < fc) psd *= lowfrac;
                    if (i == 0 && j == 0) psd = 0;
                    const double a = sqrt(psd) * df * k500;
                    f[i + GN * j][0] = a * wt_rng_normal(&r), f[i + GN * j][1] = a * wt_rng_normal(&r);
                }
            fftw_execute(pl);
            for (size_t q = 0; q < (size_t)GN * GN; q++) scr[(size_t)t * GN * GN + q] = f[q][0];
            /* rms over the inner 42 m */
            double s = 0, s2 = 0;
            int n = 0;
            for (int j = GN / 4; j < 3 * GN / 4; j++)
                for (int i = GN / 4; i < 3 * GN / 4; i++) {
                    const double v = scr[(size_t)t * GN * GN + i + (size_t)GN * j];
                    s += v, s2 += v * v, n++;
                }
            var += (s2 / n - (s / n) * (s / n)) / nscr;
        }
        printf("bench-ngs: %d residual screens, %.0f nm rms over 42 m (Marechal Strehl at 1650 nm %.2f; low-order "
               "power x %.2f), tip-tilt %.0f mas rms per axis; %d threads; load: see uptime\n",
               nscr, sqrt(var) * 1e9, exp(-pow(2 * M_PI * sqrt(var) / 1650e-9, 2)), lowfrac, tt / MAS, nth);
        fftw_destroy_plan(pl);
        fftw_free(f);
    }
    wt_rng tr;
    wt_rng_init(&tr, 99, 0);
    double *tilt = malloc(sizeof(double) * 2 * nscr);
    for (int t = 0; t < 2 * nscr; t++) tilt[t] = tt * wt_rng_normal(&tr);

    static const int cfgs[][4] = {/* n_p, N, Ns, k; the first is the fine reference */
                                  {256, 512, 16, 15}, {128, 256, 16, 3}, {128, 256, 16, 5}, {128, 256, 16, 9},
                                  {128, 256, 16, 15}, {64, 128, 16, 9},  {32, 64, 16, 9},   {256, 512, 16, 9},
                                  {128, 256, 24, 9},  {64, 128, 16, 3},  {64, 128, 16, 5},  {96, 192, 16, 9}};
    /* "field": the FFT-field sweep alone, at k = 9 against n_p 256 */
    static const int fcfgs[][4] = {{256, 512, 16, 9}, {128, 256, 16, 9}, {64, 128, 16, 9}, {32, 64, 16, 9}};
    const int field_only = argc > 6 && !strcmp(argv[6], "field");
    const int ncfg = field_only ? 4 : (int)(sizeof cfgs / sizeof cfgs[0]);
    double *ref = malloc(sizeof(double) * 2 * 6 * nscr), *sl = malloc(sizeof(double) * 2 * 6 * nscr);
    printf("%4s %4s %3s %2s | %8s %8s %8s | %7s %7s | %6s %6s | %9s %9s | %7s\n", "n_p", "N", "Ns", "k", "cpu/thr",
           "wall", "set-up", "field", "1x1 NEA", "gain11", "gain22", "rms 1x1", "rms 2x2", "max|s|");
    printf("%4s %4s %3s %2s | %8s %8s %8s | %7s %7s | %6s %6s | %9s %9s | %7s\n", "", "", "", "", "ms", "ms", "s",
           "arcsec", "mas", "", "", "mas", "mas", "mas");
    for (int c = 0; c < ncfg; c++) {
        const int *cf = field_only ? fcfgs[c] : cfgs[c];
        const int np = cf[0], N = cf[1], Ns = cf[2], k = cf[3];
        sensor o[2]; /* 1x1 (used twice: two NGS), 2x2 */
        double t0 = wt_time_now();
        if (sensor_alloc(ctx, 1, np, N, Ns, k, &o[0]) || sensor_alloc(ctx, 2, np, N, Ns, k, &o[1])) {
            fprintf(stderr, "%s\n", wt_error_message(ctx));
            return 1;
        }
        const double setup = wt_time_now() - t0;
        /* accuracy: noise-free slopes of each screen */
        double ss[2] = {0, 0}, smax = 0;
        for (int t = 0; t < nscr; t++)
            for (int m = 0; m < 2; m++) {
                sample(&o[m], np, scr + (size_t)t * GN * GN, tilt[2 * t], tilt[2 * t + 1]);
                wt_spot_image(o[m].s, o[m].opd, o[m].img);
                double s[8];
                wt_centroid_apply(o[m].c, o[m].img, s);
                for (int q = 0; q < 2 * o[m].nsub; q++) {
                    double *dst = (c == 0 ? ref : sl) + (size_t)t * 12 + (m ? 2 : 0) + q;
                    *dst = s[q];
                    smax = fmax(smax, fabs(s[q]));
                    if (c > 0) {
                        const double e = s[q] - ref[(size_t)t * 12 + (m ? 2 : 0) + q];
                        ss[m] += e * e / (2.0 * o[m].nsub * nscr);
                    }
                }
            }
        /* cost: the three NGS (1x1 twice, 2x2 once) per frame */
        double *tw = malloc(sizeof(double) * frames);
        double c0 = cpu_now();
        for (int f = 0; f < frames; f++) {
            double a = wt_time_now();
            for (int m = 0; m < 3; m++) {
                sensor *x = &o[m == 2];
                double s[8];
                wt_spot_image(x->s, x->opd, x->img);
                wt_spot_noise(x->s, 1, (UINT64_C(1) << 32) + 64 * (uint64_t)f + m, x->img);
                wt_centroid_apply(x->c, x->img, s);
            }
            tw[f] = wt_time_now() - a;
        }
        const double cpu = (cpu_now() - c0) / frames;
        qsort(tw, frames, sizeof *tw, cmp);
        double cov[3], g[4], g2[4];
        wt_centroid_noise_cov(o[0].c, cov);
        wt_centroid_gain(o[0].c, 0, g);
        wt_centroid_gain(o[1].c, 0, g2);
        const double field = np * 1650e-9 / 42.0 / AS;
        printf("%4d %4d %3d %2d | %8.2f %8.2f %8.2f | %7.3f %7.3f | %6.3f %6.3f | ", np, N, Ns, k, cpu / nth * 1e3,
               tw[frames / 2] * 1e3, setup, field, sqrt(0.5 * (cov[0] + cov[2])) / MAS, 0.5 * (g[0] + g[3]),
               0.5 * (g2[0] + g2[3]));
        if (c == 0) printf("%9s %9s | %7.2f\n", "(ref)", "(ref)", smax / MAS);
        else printf("%9.3f %9.3f | %7.2f\n", sqrt(ss[0]) / MAS, sqrt(ss[1]) / MAS, smax / MAS);
        free(tw);
        sensor_free(&o[0]), sensor_free(&o[1]);
    }
    free(scr), free(ref), free(sl), free(tilt);
    wt_context_free(ctx);
    return 0;
}
