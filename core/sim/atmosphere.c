/* core/sim/atmosphere.c: frozen-flow von Kármán screens (FFT + subharmonics) and their line-of-sight OPD.
 *
 * SPEC §2 (spectrum, FFT screens with subharmonics, frozen flow, bilinear interpolation with periodic
 * wrap) and §3 (the cone factor 1 − h/H and the shift θh of paper eqs. P^NGS, P^LGS).
 *
 * FFT part. With c_k = a_k + i b_k, a_k, b_k ~ N(0, 1) independent, the real part of
 *   Σ_k c_k √Φ(κ_k) Δκ e^{2πi κ_k·x},   Δκ = 1/L,
 * has covariance Σ_k Φ(κ_k) Δκ² cos(2π κ_k·r): the Riemann sum of the von Kármán covariance over
 * the frequency grid. One complex FFT per layer (FFTW_BACKWARD: the + sign) gives it on the n x n grid;
 * the imaginary part (an independent screen) is discarded so that layer ℓ depends on stream ℓ only.
 *
 * Subharmonics. The 3 x 3 cells of size Δκ/3 tile the central cell that the grid leaves out (κ = 0),
 * their own central cell is tiled at the next level, and so on for 3 levels (Lane et al. 1992; as
 * in Schmidt, "Numerical simulation of optical wave propagation", listing 9.3). The field is
 *   Re Σ_p Σ_{(m,n) ≠ 0} c_{pmn} √Φ(κ_pmn) Δκ_p e^{2πi κ_pmn·x},  Δκ_p = Δκ/3^p,
 * minus its mean over the grid. Its 24 terms are evaluated exactly at every sample point rather than
 * baked into the grid: a grid with them added would not be periodic, and frozen flow across the
 * wrap would show a step of the size of the subharmonic field's difference over a distance L (for
 * L ~ L0, several radians at 500 nm). Evaluation is cheap because along a target row the sample
 * positions are an arithmetic progression: the y factors are fixed per row and the x factors
 * e^{2πi κ_p x} advance by one complex rotation per point.
 */
#include "atmosphere.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>

#include "../base/rng.h"

#define SHL WT_ATMOSPHERE_SUBHARMONIC_LEVELS
#define LAMBDA0 500e-9 /* wavelength of r0 [m] */
#define MAX_N 32768    /* 8 GiB per layer: beyond that the request is surely a units mistake */

typedef struct atm_layer {
    double altitude;        /* h [m] */
    double fraction;        /* normalised Cn² fraction */
    double vx, vy;          /* wind [m/s] */
    double *screen;         /* [n*n] periodic grid part [m] (inside atm->block) */
    double sh[SHL][3][3][2]; /* subharmonic amplitudes c √Φ Δκ_p [m]: [level][kx + 1][ky + 1][re, im] */
    double sh_offset;       /* minus the grid mean of the subharmonic field [m] */
} atm_layer;

struct wt_atmosphere {
    wt_context *ctx;
    int nlayers;
    int n;
    double delta;    /* [m] */
    double r0, L0;   /* [m] */
    int sh_levels;   /* 0 or SHL */
    wt_grid grid;    /* wt_grid_layer(n, delta) */
    atm_layer *layers;
    double *block;   /* nlayers * n * n screen values */
};

/* ---------------------------------------------------------------------------------------------- */
/* Subharmonic evaluation along a row of equally spaced points */

typedef struct sh_row {
    int levels;
    double g0;                   /* the kx = 0 terms plus the offset [m] */
    double gr[SHL], gi[SHL];     /* G_p: the kx = ±Δκ_p terms combined, Re[G_p e^{2πi Δκ_p x}] */
    double er[SHL], ei[SHL];     /* e^{2πi Δκ_p x} at the current point */
    double rr[SHL], ri[SHL];     /* e^{2πi Δκ_p dx}: the step to the next point */
} sh_row;

/* Prepare the subharmonic field of layer `ly` on the row y = py at x = px0 + k dpx.
 * With F = e^{2πi Δκ_p y}: B_p(m) = c_{m,−1} F̄ + c_{m,0} + c_{m,+1} F, and the field is
 * Re Σ_p [B_p(0) + B_p(+1) E + B_p(−1) Ē] = Σ_p Re B_p(0) + Re[(B_p(+1) + conj B_p(−1)) E], E = e^{2πi Δκ_p x}. */
static void sh_row_init(const atm_layer *ly, int levels, double dk, double py, double px0, double dpx,
                        sh_row *s)
{
    s->levels = levels;
    s->g0 = ly->sh_offset;
    double kp = dk;
    for (int p = 0; p < levels; p++) {
        kp /= 3.0;
        double fr = cos(2.0 * M_PI * kp * py), fi = sin(2.0 * M_PI * kp * py);
        double br[3], bi[3];
        for (int m = 0; m < 3; m++) {
            const double(*c)[2] = ly->sh[p][m]; /* c[ky + 1] */
            br[m] = c[1][0] + (c[0][0] + c[2][0]) * fr + (c[0][1] - c[2][1]) * fi;
            bi[m] = c[1][1] + (c[0][1] + c[2][1]) * fr + (c[2][0] - c[0][0]) * fi;
        }
        s->g0 += br[1];
        s->gr[p] = br[2] + br[0];
        s->gi[p] = bi[2] - bi[0];
        s->er[p] = cos(2.0 * M_PI * kp * px0);
        s->ei[p] = sin(2.0 * M_PI * kp * px0);
        s->rr[p] = cos(2.0 * M_PI * kp * dpx);
        s->ri[p] = sin(2.0 * M_PI * kp * dpx);
    }
}

/* The field at the current point, then step to the next one. The rotation recurrence drifts by
 * ~k·1e-16 relative after k points: negligible for rows of thousands of points. */
static inline double sh_row_next(sh_row *s)
{
    double v = s->g0;
    for (int p = 0; p < s->levels; p++) {
        double er = s->er[p], ei = s->ei[p];
        v += s->gr[p] * er - s->gi[p] * ei;
        s->er[p] = er * s->rr[p] - ei * s->ri[p];
        s->ei[p] = er * s->ri[p] + ei * s->rr[p];
    }
    return v;
}

/* ---------------------------------------------------------------------------------------------- */
/* Validation and sizes */

static int smooth_size(int n, int maxprime)
{
    static const int primes[] = {2, 3, 5, 7};
    for (int i = 0; i < 4 && primes[i] <= maxprime; i++)
        while (n % primes[i] == 0) n /= primes[i];
    return n == 1;
}

int wt_atmosphere_recommend_size(wt_context *ctx, double footprint, double delta, int *n)
{
    if (!n) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_atmosphere_recommend_size: n is NULL");
    *n = 0;
    if (!(footprint > 0.0) || !isfinite(footprint))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wt_atmosphere_recommend_size: footprint = %g m; expected a finite diameter > 0",
                        footprint);
    if (!(delta > 0.0) || !isfinite(delta))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wt_atmosphere_recommend_size: delta = %g m; expected a finite spacing > 0", delta);
    double need = ceil(2.0 * footprint / delta - 1e-9);
    if (need > MAX_N)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "wt_atmosphere_recommend_size: footprint %g m at delta %g m needs %.0f points "
                        "per side, more than the %d accepted",
                        footprint, delta, need, MAX_N);
    int m = need < 32 ? 32 : (int)need;
    if (m % 2) m++;
    while (!smooth_size(m, 5)) m += 2;
    *n = m;
    return WT_OK;
}

static int check_params(wt_context *ctx, const wt_atmosphere_params *p, double *fsum)
{
    const char *fn = "wt_atmosphere_alloc";
    if (!p) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: params is NULL", fn);
    if (p->nlayers < 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: nlayers = %d; expected at least 1", fn, p->nlayers);
    if (!p->altitudes || !p->fractions || !p->wind_speed || !p->wind_direction)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: NULL %s array", fn,
                        !p->altitudes ? "altitudes" : !p->fractions ? "fractions"
                        : !p->wind_speed ? "wind_speed" : "wind_direction");
    double s = 0.0;
    for (int l = 0; l < p->nlayers; l++) {
        if (!(p->altitudes[l] >= 0.0) || !isfinite(p->altitudes[l]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "%s: altitudes[%d] = %g m; expected a finite altitude >= 0",
                            fn, l, p->altitudes[l]);
        if (!(p->fractions[l] >= 0.0) || !isfinite(p->fractions[l]))
            return WT_ERROR(ctx, WT_ERR_INVALID,
                            "%s: fractions[%d] = %g; Cn2 fractions must be finite and >= 0", fn, l,
                            p->fractions[l]);
        if (!(p->wind_speed[l] >= 0.0) || !isfinite(p->wind_speed[l]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "%s: wind_speed[%d] = %g m/s; expected a finite speed >= 0",
                            fn, l, p->wind_speed[l]);
        if (!isfinite(p->wind_direction[l]))
            return WT_ERROR(ctx, WT_ERR_INVALID, "%s: wind_direction[%d] = %g rad is not finite", fn, l,
                            p->wind_direction[l]);
        s += p->fractions[l];
    }
    if (!(s > 0.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: the Cn2 fractions sum to %g; expected a positive sum", fn, s);
    if (!(p->r0 > 0.0) || !isfinite(p->r0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: r0 = %g m; expected a finite Fried parameter > 0", fn, p->r0);
    if (!(p->L0 > 0.0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: L0 = %g m; expected an outer scale > 0 (INFINITY allowed)",
                        fn, p->L0);
    if (!(p->delta > 0.0) || !isfinite(p->delta))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: delta = %g m; expected a finite screen spacing > 0", fn,
                        p->delta);
    if (p->n < 16 || p->n > MAX_N || p->n % 2 || !smooth_size(p->n, 7))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: screen size n = %d; expected an even n in [16, %d] with prime factors 2, 3, 5, 7 "
                        "only (see wt_atmosphere_recommend_size)",
                        fn, p->n, MAX_N);
    if (p->no_subharmonics != 0 && p->no_subharmonics != 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: no_subharmonics = %d; expected 0 or 1", fn, p->no_subharmonics);
    *fsum = s;
    return WT_OK;
}

/* ---------------------------------------------------------------------------------------------- */
/* Generation */

/* √Φ(κ) Δκ for a unit fraction, κ² = kappa2 [(cycles/m)²]. */
static double vk_amplitude(double kappa2, double r0, double L0, double dk)
{
    double c = (LAMBDA0 / (2.0 * M_PI)) * (LAMBDA0 / (2.0 * M_PI)) * 0.0229 * pow(r0, -5.0 / 3.0);
    double k0 = isinf(L0) ? 0.0 : 1.0 / (L0 * L0);
    return sqrt(c) * pow(kappa2 + k0, -11.0 / 12.0) * dk;
}

/* Mean over the screen grid of layer `ly`'s subharmonic field without offset. */
static double sh_grid_mean(const wt_atmosphere *atm, const atm_layer *ly)
{
    const int n = atm->n;
    double dk = 1.0 / (n * atm->delta), total = 0.0;
    for (int j = 0; j < n; j++) {
        sh_row s;
        sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, atm->delta, &s);
        s.g0 -= ly->sh_offset;
        double row = 0.0;
        for (int i = 0; i < n; i++) row += sh_row_next(&s);
        total += row;
    }
    return total / ((double)n * n);
}

/* Draw layer l from stream (seed, l): the n² grid amplitudes in index order, then the subharmonics. */
static void generate_layer(wt_atmosphere *atm, uint64_t seed, int l, const double *amp, fftw_complex *buf,
                           const fftw_plan plan)
{
    const int n = atm->n;
    const int64_t nn = (int64_t)n * n;
    atm_layer *ly = &atm->layers[l];
    double s = sqrt(ly->fraction);
    wt_rng rng;
    wt_rng_init(&rng, seed, (uint64_t)l);
    for (int64_t k = 0; k < nn; k++) {
        double a = wt_rng_normal(&rng), b = wt_rng_normal(&rng);
        buf[k][0] = a * amp[k] * s;
        buf[k][1] = b * amp[k] * s;
    }
    fftw_execute(plan);
    double mean = 0.0;
    for (int64_t k = 0; k < nn; k++) mean += buf[k][0];
    mean /= (double)nn; /* zero up to rounding: κ = 0 has no amplitude */
    for (int64_t k = 0; k < nn; k++) ly->screen[k] = buf[k][0] - mean;

    double dk = 1.0 / (n * atm->delta), kp = dk;
    for (int p = 0; p < SHL; p++) {
        kp /= 3.0;
        for (int ky = -1; ky <= 1; ky++)
            for (int kx = -1; kx <= 1; kx++) {
                double a = wt_rng_normal(&rng), b = wt_rng_normal(&rng);
                double w = (kx || ky) ? vk_amplitude(kp * kp * (kx * kx + ky * ky), atm->r0, atm->L0, kp) * s : 0.0;
                ly->sh[p][kx + 1][ky + 1][0] = a * w;
                ly->sh[p][kx + 1][ky + 1][1] = b * w;
            }
    }
    ly->sh_offset = 0.0;
    if (atm->sh_levels) ly->sh_offset = -sh_grid_mean(atm, ly);
}

void wt_atmosphere_free(wt_atmosphere *atm)
{
    if (!atm) return;
    wt_context *ctx = atm->ctx;
    wt_free(ctx, atm->block);
    wt_free(ctx, atm->layers);
    wt_free(ctx, atm);
}

int wt_atmosphere_alloc(wt_context *ctx, const wt_atmosphere_params *params, wt_atmosphere **out)
{
    int st = WT_OK;
    wt_atmosphere *atm = NULL;
    double *amp = NULL;
    fftw_complex *buf = NULL;
    fftw_plan plan = NULL;
    double fsum = 0.0;
    if (!out) return WT_ERROR(ctx, WT_ERR_INVALID, "wt_atmosphere_alloc: out is NULL");
    *out = NULL;
    if ((st = check_params(ctx, params, &fsum)) < 0) return st;

    const int n = params->n;
    const int64_t nn = (int64_t)n * n;
    WT_ALLOC(ctx, atm, 1, "the atmosphere");
    atm->ctx = ctx;
    atm->nlayers = params->nlayers;
    atm->n = n;
    atm->delta = params->delta;
    atm->r0 = params->r0;
    atm->L0 = params->L0;
    atm->sh_levels = params->no_subharmonics ? 0 : SHL;
    atm->grid = wt_grid_layer(n, params->delta);
    WT_ALLOC(ctx, atm->layers, params->nlayers, "the atmosphere's layer table");
    WT_ALLOC(ctx, atm->block, nn * params->nlayers, "the atmosphere's screens");
    for (int l = 0; l < params->nlayers; l++) {
        atm_layer *ly = &atm->layers[l];
        ly->altitude = params->altitudes[l];
        ly->fraction = params->fractions[l] / fsum;
        ly->vx = params->wind_speed[l] * cos(params->wind_direction[l]);
        ly->vy = params->wind_speed[l] * sin(params->wind_direction[l]);
        ly->screen = atm->block + nn * l;
    }

    /* Work space: the FFT buffer and the amplitude table √Φ(κ_k) Δκ shared by all layers. */
    WT_ALLOC(ctx, amp, nn, "the screen amplitude table");
    buf = wt_malloc(ctx, (size_t)nn, sizeof *buf);
    if (!buf) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory allocating the FFT buffer (%zu bytes)",
                      (size_t)nn * sizeof *buf);
        goto fail;
    }
    plan = fftw_plan_dft_2d(n, n, buf, buf, FFTW_BACKWARD, FFTW_ESTIMATE);
    if (!plan) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "wt_atmosphere_alloc: fftw_plan_dft_2d(%d, %d) returned NULL", n, n);
        goto fail;
    }
    const double dk = 1.0 / (n * params->delta);
    for (int j = 0; j < n; j++) {
        int ky = j <= n / 2 ? j : j - n; /* frequency index; ±n/2 is one mode */
        for (int i = 0; i < n; i++) {
            int kx = i <= n / 2 ? i : i - n;
            double k2 = dk * dk * ((double)kx * kx + (double)ky * ky);
            amp[i + (int64_t)n * j] = (kx || ky) ? vk_amplitude(k2, params->r0, params->L0, dk) : 0.0;
        }
    }
    for (int l = 0; l < params->nlayers; l++) generate_layer(atm, params->seed, l, amp, buf, plan);

    fftw_destroy_plan(plan);
    wt_free(ctx, buf);
    wt_free(ctx, amp);
    *out = atm;
    return WT_OK;

fail:
    if (plan) fftw_destroy_plan(plan);
    wt_free(ctx, buf);
    wt_free(ctx, amp);
    wt_atmosphere_free(atm);
    return st;
}

/* ---------------------------------------------------------------------------------------------- */
/* Accessors */

int wt_atmosphere_nlayers(const wt_atmosphere *atm) { return atm->nlayers; }
wt_grid wt_atmosphere_grid(const wt_atmosphere *atm) { return atm->grid; }
size_t wt_atmosphere_bytes(const wt_atmosphere *atm)
{
    return sizeof *atm + (size_t)atm->nlayers * (sizeof(atm_layer) + (size_t)atm->n * atm->n * sizeof(double));
}
double wt_atmosphere_layer_altitude(const wt_atmosphere *atm, int layer) { return atm->layers[layer].altitude; }
double wt_atmosphere_layer_fraction(const wt_atmosphere *atm, int layer) { return atm->layers[layer].fraction; }
void wt_atmosphere_layer_wind(const wt_atmosphere *atm, int layer, double *vx, double *vy)
{
    if (vx) *vx = atm->layers[layer].vx;
    if (vy) *vy = atm->layers[layer].vy;
}
const double *wt_atmosphere_layer_data(const wt_atmosphere *atm, int layer) { return atm->layers[layer].screen; }

void wt_atmosphere_layer_render(const wt_atmosphere *atm, int layer, double *out)
{
    const int n = atm->n;
    const atm_layer *ly = &atm->layers[layer];
    double dk = 1.0 / (n * atm->delta);
    for (int j = 0; j < n; j++) {
        const double *src = ly->screen + (int64_t)n * j;
        double *dst = out + (int64_t)n * j;
        if (!atm->sh_levels) {
            memcpy(dst, src, (size_t)n * sizeof *dst);
            continue;
        }
        sh_row s;
        sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, atm->delta, &s);
        for (int i = 0; i < n; i++) dst[i] = src[i] + sh_row_next(&s);
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Line-of-sight projection */

/* u mod n in [0, n). */
static inline double wrap(double u, int n)
{
    u -= n * floor(u / n);
    return u >= n ? u - n : u; /* u = −tiny rounds up to n */
}

/* Target row iy, every layer: out[row] += alpha · φ on the masked points. */
static void project_row(const wt_atmosphere *atm, double t, double H, double thx, double thy,
                        const wt_grid *tg, const uint8_t *mask, double alpha, double *out, int iy)
{
    const int nx = tg->nx, n = atm->n;
    const int64_t row = (int64_t)iy * nx;
    const uint8_t *mk = mask ? mask + row : NULL;
    int lo = 0, hi = nx - 1;
    if (mk) { /* sample only the span of masked points; the loop below still skips the holes */
        while (lo < nx && !mk[lo]) lo++;
        if (lo == nx) return;
        while (!mk[hi]) hi--;
    }
    double *o = out + row;
    const double inv = 1.0 / atm->delta, dk = 1.0 / (n * atm->delta);
    const double x = tg->x0 + lo * tg->dx, y = tg->y0 + iy * tg->dx;
    for (int l = 0; l < atm->nlayers; l++) {
        const atm_layer *ly = &atm->layers[l];
        const double h = ly->altitude;
        const double c = H > 0.0 ? 1.0 - h / H : 1.0; /* cone factor */
        const double px0 = c * x + thx * h - ly->vx * t, py = c * y + thy * h - ly->vy * t;
        const double b = c * tg->dx * inv; /* step in screen cells per target point */
        const double u0 = wrap((px0 - atm->grid.x0) * inv, n), v = wrap((py - atm->grid.y0) * inv, n);
        const int j = (int)v, j1 = j + 1 == n ? 0 : j + 1;
        const double fy = v - j;
        const double *r0 = ly->screen + (int64_t)n * j, *r1 = ly->screen + (int64_t)n * j1;
        int off = 0; /* multiple of n taken off the unwrapped index: u grows monotonically along the row */
        if (atm->sh_levels) {
            sh_row s;
            sh_row_init(ly, atm->sh_levels, dk, py, px0, c * tg->dx, &s);
            for (int ix = lo; ix <= hi; ix++) {
                double u = u0 + (ix - lo) * b;
                int iu = (int)u, i = iu - off;
                double fx = u - iu;
                while (i >= n) i -= n, off += n;
                int i1 = i + 1 == n ? 0 : i + 1;
                double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
                double val = a0 + fy * (a1 - a0) + sh_row_next(&s);
                if (!mk || mk[ix]) o[ix] += alpha * val;
            }
        } else {
            for (int ix = lo; ix <= hi; ix++) {
                double u = u0 + (ix - lo) * b;
                int iu = (int)u, i = iu - off;
                double fx = u - iu;
                while (i >= n) i -= n, off += n;
                int i1 = i + 1 == n ? 0 : i + 1;
                double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
                if (!mk || mk[ix]) o[ix] += alpha * (a0 + fy * (a1 - a0));
            }
        }
    }
}

int wt_atmosphere_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                          double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                          double *out)
{
    const char *fn = "wt_atmosphere_project";
    if (!atm) return WT_ERR_INVALID;
    wt_context *ctx = atm->ctx;
    if (!target || !out) return WT_ERROR(ctx, WT_ERR_INVALID, "%s: %s is NULL", fn, !target ? "target" : "out");
    if (target->nx < 1 || target->ny < 1 || !(target->dx > 0.0) || !isfinite(target->dx) ||
        !isfinite(target->x0) || !isfinite(target->y0))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: target grid %d x %d, dx = %g m, origin (%g, %g) m; expected >= 1 x 1 points, a "
                        "finite dx > 0 and a finite origin",
                        fn, target->nx, target->ny, target->dx, target->x0, target->y0);
    /* The unwrapped screen index along a row must fit an int. */
    if ((double)target->nx * target->dx / atm->delta > 1e9)
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: target rows span %g m, over 1e9 screen cells of %g m", fn,
                        target->nx * target->dx, atm->delta);
    if (!isfinite(t) || !isfinite(theta_x) || !isfinite(theta_y))
        return WT_ERROR(ctx, WT_ERR_INVALID, "%s: t = %g s, theta = (%g, %g) rad; expected finite values", fn,
                        t, theta_x, theta_y);
    if (!(source_altitude >= 0.0) || !isfinite(source_altitude))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "%s: source_altitude = %g m; expected 0 (infinity) or a finite altitude > 0", fn,
                        source_altitude);
    if (source_altitude > 0.0)
        for (int l = 0; l < atm->nlayers; l++)
            if (!(atm->layers[l].altitude < source_altitude))
                return WT_ERROR(ctx, WT_ERR_INVALID,
                                "%s: source_altitude = %g m is not above layer %d at %g m", fn, source_altitude,
                                l, atm->layers[l].altitude);
    if (alpha == 0.0) return WT_OK;
    const int ny = target->ny;
    const int nth = wt_context_threads(ctx);
    (void)nth;
#pragma omp parallel for schedule(static) num_threads(nth) if (nth > 1 && ny > 1)
    for (int iy = 0; iy < ny; iy++)
        project_row(atm, t, source_altitude, theta_x, theta_y, target, mask, alpha, out, iy);
    return WT_OK;
}
