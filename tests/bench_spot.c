/* tests/bench_spot.c: `make bench-spot`: times the diffractive LGS images of the E-ELT (6 LGS × 5112
 * subapertures of 0.5 m at 589 nm, SPEC §1/§4b) per frame, noise included, against the 1 s target.
 * Usage: bench_spot [threads=2] [frames=7] [npix=16] [cells_per_pixel=3] */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <stdint.h>
#include <time.h>

#include "core/base/base.h"
#include "core/base/rng.h"
#include "core/op/pupil.h"
#include "core/optics/sodium.h"
#include "core/optics/spot.h"

#define AS (M_PI / 180.0 / 3600.0)

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

int main(int argc, char **argv)
{
    const int nth = argc > 1 ? atoi(argv[1]) : 2, frames = argc > 2 ? atoi(argv[2]) : 7;
    const int Ns = argc > 3 ? atoi(argv[3]) : 16, kc = argc > 4 ? atoi(argv[4]) : 3;
    const int n = 84, np = 16, NLGS = 6;
    const double D = 42.0, obs = 0.28, d = D / n;
    wt_context *ctx = wt_context_alloc();
    wt_context_set_threads(ctx, nth);
    uint8_t valid[84 * 84];
    int nv = wt_pupil_valid_subapertures(D, obs, n, 0.5, valid);
    double *xc = malloc(sizeof(double) * nv), *yc = malloc(sizeof(double) * nv), *lit = malloc(sizeof(double) * nv);
    float *amp = malloc(sizeof(float) * nv * np * np);
    int k = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            if (!valid[i + n * j]) continue;
            double x0 = -D / 2 + i * d, y0 = -D / 2 + j * d;
            xc[k] = x0 + d / 2, yc[k] = y0 + d / 2;
            lit[k] = wt_pupil_fraction(D, obs, x0, y0, d);
            /* each pupil sample's amplitude: the lit fraction of its square (the field integrated over it) */
            for (int b = 0; b < np; b++)
                for (int a = 0; a < np; a++)
                    amp[(size_t)k * np * np + a + np * b] =
                        (float)wt_pupil_fraction(D, obs, x0 + a * d / np, y0 + b * d / np, d / np);
            k++;
        }
    wt_sodium *na = NULL;
    if (wt_sodium_read(ctx, "data/sodium/default.txt", &na)) {
        fprintf(stderr, "%s\n", wt_error_message(ctx));
        return 1;
    }
    wt_spot_params p = {0};
    p.wavelength = 589e-9, p.subap_side = d, p.pupil_samples = np, p.fft_size = 2 * np;
    p.npix = Ns, p.pixel = 1.1 * AS, p.cells_per_pixel = kc, p.photons = 100, p.background = 0.5,
    p.read_noise = 3.0, p.uplink_fwhm = 1.0 * AS, p.sodium = na, p.lgs_altitude = 90e3;
    wt_spot *s[6];
    double t0 = wt_time_now();
    for (int m = 0; m < NLGS; m++) {
        double az = m * M_PI / 3;
        p.launch_x = 22.0 * cos(az), p.launch_y = 22.0 * sin(az);
        if (wt_spot_alloc(ctx, &p, nv, xc, yc, amp, lit, &s[m])) {
            fprintf(stderr, "%s\n", wt_error_message(ctx));
            return 1;
        }
    }
    double tsetup = wt_time_now() - t0;
    float *opd = malloc(sizeof(float) * nv * np * np), *img = malloc(sizeof(float) * nv * Ns * Ns);
    wt_rng r;
    wt_rng_init(&r, 1, 0);
    for (size_t i = 0; i < (size_t)nv * np * np; i++) opd[i] = (float)(100e-9 * wt_rng_normal(&r));
    double *ti = malloc(sizeof(double) * frames), *tn = malloc(sizeof(double) * frames), *tt = malloc(sizeof(double) * frames);
    double c0 = cpu_now(), w0 = wt_time_now();
    for (int f = 0; f < frames; f++) {
        double a = 0, b = 0;
        for (int m = 0; m < NLGS; m++) {
            double t1 = wt_time_now();
            wt_spot_image(s[m], opd, img);
            double t2 = wt_time_now();
            wt_spot_noise(s[m], 7, (UINT64_C(1) << 32) + 64 * (uint64_t)f + m, img);
            b += wt_time_now() - t2, a += t2 - t1;
        }
        ti[f] = a, tn[f] = b, tt[f] = a + b;
    }
    double cpu = (cpu_now() - c0) / frames, wall = (wt_time_now() - w0) / frames;
    qsort(ti, frames, sizeof(double), cmp), qsort(tn, frames, sizeof(double), cmp), qsort(tt, frames, sizeof(double), cmp);
    double fl, by;
    wt_spot_cost(s[0], &fl, &by);
    size_t mem = 0;
    for (int m = 0; m < NLGS; m++) mem += wt_spot_memory(s[m]);
    printf("bench-spot: %d LGS x %d subapertures, n_p %d, N %d, Ns %d, p 1.1\", k %d, %d threads, %d frames\n", NLGS, nv,
           np, 2 * np, Ns, kc, nth, frames);
    printf("  set-up            %.2f s\n", tsetup);
    printf("  per frame median  %.3f s (images %.3f s + noise %.3f s)  [target 1 s, stretch 0.5 s]\n", tt[frames / 2],
           ti[frames / 2], tn[frames / 2]);
    printf("  CPU time per frame %.3f s on %d threads (mean wall %.3f s): %.3f s of wall on %d idle cores\n", cpu, nth,
           wall, cpu / nth, nth);
    printf("  per subaperture   %.2f us (%.0f flops, %.0f bytes of table/input/output)\n",
           tt[frames / 2] / (NLGS * nv) * 1e6 * nth, fl, by);
    printf("  memory            %.0f MB (tables %.1f kB per subaperture)\n", mem / 1e6, by / 1e3);
    printf("  rebinning blur left after the uplink compensation: %.3g arcsec rms\n", sqrt(wt_spot_blur(s[0])) / AS);
    for (int m = 0; m < NLGS; m++) wt_spot_free(s[m]);
    wt_sodium_free(na);
    free(xc), free(yc), free(lit), free(amp), free(opd), free(img), free(ti), free(tn), free(tt);
    wt_context_free(ctx);
    return 0;
}
