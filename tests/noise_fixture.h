/* tests/noise_fixture.h: what the noise-model suites share (test_noise.c, test_noise_model.c): the E-ELT LGS
 * spot and pixel, a ring of elongated subapertures and the noise model built on it. */
#ifndef WT_TESTS_NOISE_FIXTURE_H
#define WT_TESTS_NOISE_FIXTURE_H

#include "testutil.h"

#include "core/op/noise.h"

#define ARCSEC (M_PI / (180.0 * 3600.0)) /* [rad] */

/* E-ELT LGS defaults (SPEC §4, §1) */
static const double LGS_FWHM = 1.1 * ARCSEC;
static const double LGS_PIXEL = 1.0 * ARCSEC;

/* Elongation vectors of a ring of subapertures seen from a side launch, as on the E-ELT: |β| up to
 * 5e-5 rad, i.e. up to ~10 spot widths — the regime where the blocks are far from diagonal. */
static void make_beta(int nsub, double *beta, unsigned long seed)
{
    double *c = malloc(2 * (size_t)nsub * sizeof *c);
    wt_rng r;
    wt_rng_init(&r, seed, 1);
    for (int i = 0; i < nsub; i++) {
        c[i] = 42.0 * (wt_rng_uniform(&r) - 0.5);
        c[nsub + i] = 42.0 * (wt_rng_uniform(&r) - 0.5);
    }
    wt_noise_elongation(nsub, c, c + nsub, 22.0 * cos(1.0), 22.0 * sin(1.0), 10e3, 90e3, beta);
    free(c);
}

static double sigma2_lgs(void) { return wt_noise_variance(100.0, 3.0, LGS_FWHM, LGS_PIXEL, 4, 0.0); }

static wt_noise *make_noise(wt_context *ctx, int nsub, double tau, int remove_tt)
{
    double *beta = malloc(2 * (size_t)nsub * sizeof *beta);
    make_beta(nsub, beta, 7);
    wt_noise *n = NULL;
    ck_assert_int_eq(wt_noise_alloc(ctx, nsub, sigma2_lgs(), LGS_FWHM, beta, tau, remove_tt, &n), WT_OK);
    free(beta);
    return n;
}

#endif
