/* tests/centroid_fixture.h: what the centroider suites share (test_centroid.c, test_centroid_noise.c): spots
 * made here (pixel-integrated, rotated, anisotropic Gaussians, integrated exactly (erf) across the conditional
 * axis and by Simpson's rule along the other, with analytic derivatives), noise draws by an exact Poisson
 * sampler by inversion written here (independent of the library's), and the centroider's parameters and set-up. */
#ifndef WT_TESTS_CENTROID_FIXTURE_H
#define WT_TESTS_CENTROID_FIXTURE_H

#include "testutil.h"

#include "core/optics/centroid.h"

#define ARCSEC (M_PI / (180.0 * 3600.0)) /* [rad] */
static const double PIX = 1.0 * ARCSEC; /* pixel scale p of every test [rad] */

/* ---------- spots ---------- */

typedef struct spot {
    double flux;   /* photo-electrons of the whole (untruncated) spot */
    double sl, ss; /* rms width along and across the elongation [rad] */
    double ang;    /* direction of the elongation from +x [rad] */
    double tx, ty; /* centre [rad] */
} spot;

/* Normal cdf and pdf of N(0, s²) */
static inline double ncdf(double z, double s) { return 0.5 * erfc(-z / (s * M_SQRT2)); }
static inline double npdf(double z, double s) { return exp(-0.5 * z * z / (s * s)) / (s * sqrt(2.0 * M_PI)); }

/* Image (and derivatives w.r.t. the centre, NULL: not wanted) of a spot on ns x ns pixels of scale PIX.
 * The spot density is the marginal N(0, Σxx) in u = x − tx times the conditional y − ty | u ~
 * N(k u, sc²), k = Σxy/Σxx, sc² = Σyy − Σxy²/Σxx: the pixel's y extent integrates exactly (Φ), the x
 * extent by Simpson's rule over 64 intervals (error ~ (p/64)⁴ f'''' , < 1e-8 for widths ≳ p/2). The limits in
 * u move with tx, so ∂I/∂tx is the integrand at the two x edges (Leibniz); ∂I/∂ty differentiates Φ. */
static inline void render(const spot *s, int ns, float *img, float *dx, float *dy)
{
    const double ca = cos(s->ang), sa = sin(s->ang);
    const double sxx = s->sl * s->sl * ca * ca + s->ss * s->ss * sa * sa;
    const double syy = s->sl * s->sl * sa * sa + s->ss * s->ss * ca * ca;
    const double sxy = (s->sl * s->sl - s->ss * s->ss) * ca * sa;
    const double sx = sqrt(sxx), k = sxy / sxx, sc = sqrt(syy - sxy * sxy / sxx);
    const double c0 = 0.5 * (ns - 1);
    enum { NQ = 64 };
    for (int iy = 0; iy < ns; iy++) {
        const double ylo = (iy - c0 - 0.5) * PIX - s->ty, yhi = ylo + PIX;
        for (int ix = 0; ix < ns; ix++) {
            const double ulo = (ix - c0 - 0.5) * PIX - s->tx, h = PIX / NQ;
            double in = 0.0, iny = 0.0, edge[2] = {0.0, 0.0};
            for (int q = 0; q <= NQ; q++) {
                const double u = ulo + q * h, w = (q == 0 || q == NQ) ? 1.0 : (q % 2 ? 4.0 : 2.0);
                const double fx = npdf(u, sx);
                const double f = fx * (ncdf(yhi - k * u, sc) - ncdf(ylo - k * u, sc));
                in += w * f;
                iny += w * fx * (npdf(ylo - k * u, sc) - npdf(yhi - k * u, sc));
                if (q == 0) edge[0] = f;
                if (q == NQ) edge[1] = f;
            }
            const int j = ix + ns * iy;
            img[j] = (float)(s->flux * in * h / 3.0);
            if (dx) dx[j] = (float)(-s->flux * (edge[1] - edge[0]));
            if (dy) dy[j] = (float)(s->flux * iny * h / 3.0);
        }
    }
}

/* A sensor of nsub spots: ref, dx, dy each nsub·ns² (malloc'd; free with free). */
static inline void render_sensor(const spot *s, int nsub, int ns, float **ref, float **dx, float **dy)
{
    const size_t npix = (size_t)ns * ns;
    *ref = malloc(npix * nsub * sizeof **ref);
    *dx = malloc(npix * nsub * sizeof **dx);
    *dy = malloc(npix * nsub * sizeof **dy);
    for (int i = 0; i < nsub; i++) render(&s[i], ns, *ref + npix * i, *dx + npix * i, *dy + npix * i);
}

/* ---------- noise draws ---------- */

/* Exact Poisson deviate by inversion of the cdf from 0 (O(mu) per draw: fine for the means here, < 200). */
static inline double tpoisson(wt_rng *r, double mu)
{
    if (mu <= 0.0) return 0.0;
    double u = wt_rng_uniform(r), p = exp(-mu), f = p;
    long k = 0;
    while (u > f && p > 0.0) {
        k++;
        p *= mu / k;
        f += p;
    }
    return (double)k;
}

/* d = Poisson(I + B) + N(0, σe²) − B; photons = 0 leaves the photon noise out (d = I + N(0, σe²)). */
static inline void draw(wt_rng *r, const float *img, size_t n, double b, double se, int photons, float *d)
{
    for (size_t j = 0; j < n; j++) {
        double v = photons ? tpoisson(r, img[j] + b) - b : img[j];
        if (se > 0.0) v += se * wt_rng_normal(r);
        d[j] = (float)v;
    }
}

static inline wt_centroid_params params(int method, double b, double se)
{
    wt_centroid_params p = {.method = method, .pixel = PIX, .background = b, .read_noise = se};
    return p;
}

static inline wt_centroid *make(wt_context *ctx, const wt_centroid_params *p, int nsub, int ns, const float *ref,
                         const float *dx, const float *dy)
{
    wt_centroid *c = NULL;
    int st = wt_centroid_alloc(ctx, p, nsub, ns, ref, dx, dy, &c);
    ck_assert_msg(st == WT_OK, "alloc: %s", wt_error_message(ctx));
    return c;
}
#endif
