/* sim/atmosphere.c: frozen-flow von Kármán screens (FFT + subharmonics): drawing them, the subharmonic
 * field along a row, the accessors. Their line-of-sight OPD (the cone factor 1 − h/H, the shift θh, bilinear
 * interpolation with periodic wrap: SPEC §3) is atmosphere_project.c's.
 *
 * SPEC §2 (spectrum, FFT screens with subharmonics, frozen flow).
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
 * positions are an arithmetic progression x0 + k dx: the y factors are fixed per row, and
 * e^{2πi κ_p x} = e^{2πi κ_p x_block} · e^{2πi κ_p dx i} with the second factor tabulated once per
 * layer and call for i < SH_CHUNK, so each block of points is a short vectorisable loop of 2
 * multiply-adds per level.
 *
 * Known limit: for L0 ≫ L (Kolmogorov-like screens) Lane's 3 levels still under-represent the
 * lowest frequencies (D(L/8) ~10–20 % short for L0 = ∞); with L ≥ L0 (the E-ELT case: L = 120 m,
 * L0 = 25 m) the structure function is within a few % (tests/test_atmosphere.c).
 */
#include "atmosphere_private.h"

#include "../core/op/prior.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>

#include "../core/base/rng.h"

#define MAX_N 32768    /* 8 GiB per layer: beyond that the request is surely a units mistake */

/* ---------------------------------------------------------------------------------------------- */
/* Subharmonic evaluation along a row of equally spaced points */

void wt_atmosphere__sh_step_init(int levels, double dk, double dpx, sh_step *q)
{
    q->levels = levels;
    double kp = dk;
    for (int p = 0; p < levels; p++) {
        kp /= 3.0;
        /* powers by recurrence (drift ≲ SH_CHUNK ulp), the block step directly */
        double cr = cos(2.0 * M_PI * kp * dpx), ci = sin(2.0 * M_PI * kp * dpx);
        q->pr[p][0] = 1.0, q->pi[p][0] = 0.0;
        for (int i = 1; i < SH_CHUNK; i++) {
            q->pr[p][i] = q->pr[p][i - 1] * cr - q->pi[p][i - 1] * ci;
            q->pi[p][i] = q->pr[p][i - 1] * ci + q->pi[p][i - 1] * cr;
        }
        q->rr[p] = cos(2.0 * M_PI * kp * dpx * SH_CHUNK);
        q->ri[p] = sin(2.0 * M_PI * kp * dpx * SH_CHUNK);
    }
}

/* The subharmonic field of layer `ly` on the row y = py, from x = px0 on.
 * With F = e^{2πi Δκ_p y}: B_p(m) = c_{m,−1} F̄ + c_{m,0} + c_{m,+1} F, and the field is
 * Re Σ_p [B_p(0) + B_p(+1) E + B_p(−1) Ē] = Σ_p Re B_p(0) + Re[(B_p(+1) + conj B_p(−1)) E].
 * Its two halves: the y part (g0, G_p) depends on the layer and py only, the x part (E_p at px0) on px0
 * only, so lines of sight that share py or px0 share them (row_memo). */
void wt_atmosphere__sh_row_y(const atm_layer *ly, int levels, double dk, double py, sh_row *s)
{
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
    }
}

void wt_atmosphere__sh_row_x(int levels, double dk, double px0, sh_row *s)
{
    double kp = dk;
    for (int p = 0; p < levels; p++) {
        kp /= 3.0;
        s->er[p] = cos(2.0 * M_PI * kp * px0);
        s->ei[p] = sin(2.0 * M_PI * kp * px0);
    }
}

void wt_atmosphere__sh_row_init(const atm_layer *ly, int levels, double dk, double py, double px0, sh_row *s)
{
    wt_atmosphere__sh_row_y(ly, levels, dk, py, s);
    wt_atmosphere__sh_row_x(levels, dk, px0, s);
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

/* √Φ(κ) Δκ for a unit fraction, κ² = kappa2 [(cycles/m)²]; Φ is the prior's von Kármán spectrum, so
 * the truth and the reconstructor's model share one formula (L0 = ∞ gives Kolmogorov). */
static double vk_amplitude(double kappa2, double r0, double L0, double dk)
{
    return sqrt(wt_von_karman_psd(sqrt(kappa2), r0, 1.0, L0)) * dk;
}

/* Mean over the screen grid of layer `ly`'s subharmonic field without offset. */
static double sh_grid_mean(const wt_atmosphere *atm, const atm_layer *ly)
{
    const int n = atm->n;
    double dk = 1.0 / (n * atm->delta), total = 0.0;
    sh_step q;
    wt_atmosphere__sh_step_init(atm->sh_levels, dk, atm->delta, &q);
    for (int j = 0; j < n; j++) {
        sh_row s;
        wt_atmosphere__sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, &s);
        s.g0 -= ly->sh_offset;
        double row = 0.0, v[SH_CHUNK];
        for (int i0 = 0; i0 < n; i0 += SH_CHUNK) {
            int m = n - i0 < SH_CHUNK ? n - i0 : SH_CHUNK;
            wt_atmosphere__sh_row_block(&q, &s, m, v);
            for (int i = 0; i < m; i++) row += v[i];
        }
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
        ly->scale = 1.0;
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
void wt_atmosphere_set_drift(wt_atmosphere *atm, const double *scale, const double *shift_x, const double *shift_y)
{
    for (int l = 0; l < atm->nlayers; l++) {
        atm_layer *ly = &atm->layers[l];
        ly->scale = scale ? scale[l] : 1.0, ly->sx = shift_x ? shift_x[l] : 0.0, ly->sy = shift_y ? shift_y[l] : 0.0;
    }
}
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
    const double dk = 1.0 / (n * atm->delta);
    sh_step q;
    if (atm->sh_levels) wt_atmosphere__sh_step_init(atm->sh_levels, dk, atm->delta, &q);
    for (int j = 0; j < n; j++) {
        const double *src = ly->screen + (int64_t)n * j;
        double *dst = out + (int64_t)n * j;
        if (!atm->sh_levels) {
            memcpy(dst, src, (size_t)n * sizeof *dst);
            continue;
        }
        sh_row s;
        wt_atmosphere__sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, &s);
        for (int i0 = 0; i0 < n; i0 += SH_CHUNK) {
            int m = n - i0 < SH_CHUNK ? n - i0 : SH_CHUNK;
            wt_atmosphere__sh_row_block(&q, &s, m, dst + i0);
            for (int i = i0; i < i0 + m; i++) dst[i] += src[i];
        }
    }
}
