/* tests/timing/centroid_time.c: per-frame time of wt_centroid_apply at E-ELT size (6 LGS × 5112 = 30672
 * subapertures of 16² pixels) for each centroider, 1 and 2 threads; also the set-up time. Not a test (no
 * timing in the suites); build and run by hand:
 *   make build/libwavetomo.a && gcc -std=c11 -D_DEFAULT_SOURCE -O3 -fopenmp -I. tests/timing/centroid_time.c \
 *       build/libwavetomo.a -lm -o build/centroid_time && build/centroid_time
 * Spots: sampled (not pixel-integrated) elongated Gaussians, enough for timing. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "core/base/base.h"
#include "core/optics/centroid.h"

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(void)
{
    const int nsub = 30672, ns = 16, nrep = 30;
    const size_t npix = (size_t)ns * ns, n = npix * nsub;
    const double p = 4.85e-6;
    float *ref = malloc(n * sizeof *ref), *dx = malloc(n * sizeof *dx), *dy = malloc(n * sizeof *dy);
    float *img = malloc(n * sizeof *img);
    double *sl = malloc(2 * (size_t)nsub * sizeof *sl);
    for (int i = 0; i < nsub; i++) {
        const double a = 0.37 * i, ca = cos(a), sa = sin(a), sl2 = pow((1 + (i % 7) * 0.4) * p, 2), ss2 = pow(0.8 * p, 2);
        /* inverse covariance of the spot */
        const double sxx = sl2 * ca * ca + ss2 * sa * sa, syy = sl2 * sa * sa + ss2 * ca * ca, sxy = (sl2 - ss2) * ca * sa;
        const double det = sxx * syy - sxy * sxy, ixx = syy / det, iyy = sxx / det, ixy = -sxy / det;
        for (int iy = 0; iy < ns; iy++)
            for (int ix = 0; ix < ns; ix++) {
                const double x = (ix - 7.5) * p, y = (iy - 7.5) * p;
                const double f = 500.0 * p * p / (2 * M_PI * sqrt(det)) * exp(-0.5 * (ixx * x * x + 2 * ixy * x * y + iyy * y * y));
                const size_t j = npix * i + ix + ns * iy;
                ref[j] = (float)f;
                dx[j] = (float)(f * (ixx * x + ixy * y)); /* ∂/∂θ of f(x − θ) at θ = 0 */
                dy[j] = (float)(f * (ixy * x + iyy * y));
                img[j] = (float)(f + 2.0 * ((i * 7919 + j * 104729) % 1000 / 1000.0 - 0.5));
            }
    }
    wt_context *ctx = wt_context_alloc();
    const char *name[] = {"CoG", "tCoG", "MF"};
    for (int m = WT_CENTROID_COG; m <= WT_CENTROID_MF; m++) {
        wt_centroid_params par = {.method = m, .pixel = p, .background = 1, .read_noise = 2, .threshold_noise = 3,
                                  .apply_gain = 1};
        wt_centroid *c = NULL;
        double t0 = wt_time_now();
        if (wt_centroid_alloc(ctx, &par, nsub, ns, ref, dx, dy, &c) != WT_OK) {
            fprintf(stderr, "%s\n", wt_error_message(ctx));
            return 1;
        }
        const double tset = wt_time_now() - t0;
        for (int th = 1; th <= 2; th++) {
            wt_context_set_threads(ctx, th);
            double t[64];
            wt_centroid_apply(c, img, sl); /* warm */
            for (int r = 0; r < nrep; r++) {
                t0 = wt_time_now();
                wt_centroid_apply(c, img, sl);
                t[r] = wt_time_now() - t0;
            }
            qsort(t, nrep, sizeof *t, cmp);
            printf("%-5s threads %d: per frame median %.2f ms, min %.2f ms (set-up %.2f s)\n", name[m], th,
                   1e3 * t[nrep / 2], 1e3 * t[0], tset);
        }
        if (m == WT_CENTROID_MF) { /* Monte-Carlo calibration: 1000 subapertures, K = 200 */
            static double cov[3 * 1000];
            wt_centroid *cm = NULL;
            wt_context_set_threads(ctx, 2);
            if (wt_centroid_alloc(ctx, &par, 1000, ns, ref, dx, dy, &cm) != WT_OK) return 1;
            t0 = wt_time_now();
            if (wt_centroid_noise_mc(cm, ref, 200, 1, cov, NULL) != WT_OK) return 1;
            const double tm = wt_time_now() - t0;
            printf("noise_mc: %.2f s for 1000 subapertures x 200 draws x %d pixels on 2 threads: %.1f ns per pixel draw\n",
                   tm, ns * ns, 1e9 * tm * 2 / (1000.0 * 200 * ns * ns));
            wt_centroid_free(cm);
        }
        wt_centroid_free(c);
    }
    wt_context_free(ctx);
    free(ref), free(dx), free(dy), free(img), free(sl);
    return 0;
}
