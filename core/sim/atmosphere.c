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
 * positions are an arithmetic progression x0 + k dx: the y factors are fixed per row, and
 * e^{2πi κ_p x} = e^{2πi κ_p x_block} · e^{2πi κ_p dx i} with the second factor tabulated once per
 * layer and call for i < SH_CHUNK, so each block of points is a short vectorisable loop of 2
 * multiply-adds per level.
 *
 * Known limit: for L0 ≫ L (Kolmogorov-like screens) Lane's 3 levels still under-represent the
 * lowest frequencies (D(L/8) ~10–20 % short for L0 = ∞); with L ≥ L0 (the E-ELT case: L = 120 m,
 * L0 = 25 m) the structure function is within a few % (tests/test_atmosphere.c).
 */
#include "atmosphere.h"

#include "../op/prior.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#else
static inline int omp_in_parallel(void) { return 0; }
#endif

#include "../base/rng.h"

#define SHL WT_ATMOSPHERE_SUBHARMONIC_LEVELS
#define MAX_N 32768    /* 8 GiB per layer: beyond that the request is surely a units mistake */

typedef struct atm_layer {
    double altitude;        /* h [m] */
    double fraction;        /* normalised Cn² fraction */
    double vx, vy;          /* wind [m/s] */
    double *screen;         /* [n*n] periodic grid part [m] (inside atm->block) */
    double sh[SHL][3][3][2]; /* subharmonic amplitudes c √Φ Δκ_p [m]: [level][kx + 1][ky + 1][re, im] */
    double sh_offset;       /* minus the grid mean of the subharmonic field [m] */
    double scale, sx, sy;   /* wt_atmosphere_set_drift: screen factor [1], extra displacement [m] */
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

#define SH_CHUNK 32 /* points evaluated per block: the powers R^i make each block a vectorisable loop */

/* What all rows of one layer share for sample spacing dpx: the x rotations. */
typedef struct sh_step {
    _Alignas(64) double pr[SHL][SH_CHUNK]; /* e^{2πi Δκ_p dpx i}, i < SH_CHUNK (cache-line aligned rows) */
    _Alignas(64) double pi[SHL][SH_CHUNK];
    double rr[SHL], ri[SHL];               /* e^{2πi Δκ_p dpx SH_CHUNK}: block to block */
    int levels;
} sh_step;

/* One row: the field is g0 + Σ_p Re[G_p E_p(x)], E_p(x) = e^{2πi Δκ_p x}. */
typedef struct sh_row {
    double g0;               /* the kx = 0 terms plus the offset [m] */
    double gr[SHL], gi[SHL]; /* G_p [m] */
    double er[SHL], ei[SHL]; /* E_p at the first point of the next block */
} sh_row;

static void sh_step_init(int levels, double dk, double dpx, sh_step *q)
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
static void sh_row_y(const atm_layer *ly, int levels, double dk, double py, sh_row *s)
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

static void sh_row_x(int levels, double dk, double px0, sh_row *s)
{
    double kp = dk;
    for (int p = 0; p < levels; p++) {
        kp /= 3.0;
        s->er[p] = cos(2.0 * M_PI * kp * px0);
        s->ei[p] = sin(2.0 * M_PI * kp * px0);
    }
}

static void sh_row_init(const atm_layer *ly, int levels, double dk, double py, double px0, sh_row *s)
{
    sh_row_y(ly, levels, dk, py, s);
    sh_row_x(levels, dk, px0, s);
}

/* The block's coefficients A_p = G_p E_p (ar + i ai), then E_p stepped to the next block. The
 * block-to-block rotation drifts by ~1e-16 relative per block: negligible for rows of thousands of
 * points. */
static inline void sh_row_coef(const sh_step *q, sh_row *s, double *restrict ar, double *restrict ai)
{
    for (int p = 0; p < q->levels; p++) {
        double er = s->er[p], ei = s->ei[p];
        ar[p] = s->gr[p] * er - s->gi[p] * ei, ai[p] = s->gr[p] * ei + s->gi[p] * er; /* G E */
        s->er[p] = er * q->rr[p] - ei * q->ri[p];
        s->ei[p] = er * q->ri[p] + ei * q->rr[p];
    }
}

/* v[i] = the field at the next m ≤ SH_CHUNK points: g0 + Σ_p Re[A_p R_p^i], the levels added in
 * order; then step to the next block. */
static inline void sh_row_block(const sh_step *q, sh_row *s, int m, double *restrict v)
{
    double ar[SHL] = {0}, ai[SHL] = {0};
    sh_row_coef(q, s, ar, ai);
    for (int i = 0; i < m; i++) v[i] = s->g0;
    for (int p = 0; p < q->levels; p++) {
        const double *restrict pr = q->pr[p], *restrict pi = q->pi[p];
        for (int i = 0; i < m; i++) v[i] += ar[p] * pr[i] - ai[p] * pi[i];
    }
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
    sh_step_init(atm->sh_levels, dk, atm->delta, &q);
    for (int j = 0; j < n; j++) {
        sh_row s;
        sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, &s);
        s.g0 -= ly->sh_offset;
        double row = 0.0, v[SH_CHUNK];
        for (int i0 = 0; i0 < n; i0 += SH_CHUNK) {
            int m = n - i0 < SH_CHUNK ? n - i0 : SH_CHUNK;
            sh_row_block(&q, &s, m, v);
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
    if (atm->sh_levels) sh_step_init(atm->sh_levels, dk, atm->delta, &q);
    for (int j = 0; j < n; j++) {
        const double *src = ly->screen + (int64_t)n * j;
        double *dst = out + (int64_t)n * j;
        if (!atm->sh_levels) {
            memcpy(dst, src, (size_t)n * sizeof *dst);
            continue;
        }
        sh_row s;
        sh_row_init(ly, atm->sh_levels, dk, atm->grid.y0 + j * atm->delta, atm->grid.x0, &s);
        for (int i0 = 0; i0 < n; i0 += SH_CHUNK) {
            int m = n - i0 < SH_CHUNK ? n - i0 : SH_CHUNK;
            sh_row_block(&q, &s, m, dst + i0);
            for (int i = i0; i < i0 + m; i++) dst[i] += src[i];
        }
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Line-of-sight projection */

/* u mod n in [0, n). fmod is exact, where u − n floor(u / n) loses the result for |u| ≫ n and then
 * indexes outside the screen (issue 10: a wind of 1e22 m/s); a non-finite u maps to 0. */
static inline double wrap(double u, int n)
{
    u = fmod(u, n);
    if (u < 0.0) u += n;
    return u >= 0.0 && u < n ? u : 0.0; /* u = −tiny rounds up to n; NaN */
}

/* What every target row shares for one layer in one call. */
typedef struct layer_call {
    const atm_layer *ly;
    double c;      /* cone factor 1 − h/H */
    double ax, ay; /* θh − v t [m]: the sample point is c r + (ax, ay) */
    double b;      /* screen cells per target step */
    const sh_step *q; /* subharmonic rotations for the step c dx */
} layer_call;

/* Everything but q, which the caller points at sh_step_init(…, c dx) (shared by the layer calls with
 * the same cone factor in a batch). */
static void layer_call_init(const wt_atmosphere *atm, int l, double t, double H, double thx, double thy,
                            const wt_grid *tg, layer_call *lc)
{
    const atm_layer *ly = &atm->layers[l];
    lc->ly = ly;
    lc->c = H > 0.0 ? 1.0 - ly->altitude / H : 1.0;
    lc->ax = thx * ly->altitude - ly->vx * t - ly->sx;
    lc->ay = thy * ly->altitude - ly->vy * t - ly->sy;
    lc->b = lc->c * tg->dx / atm->delta;
    lc->q = NULL;
}

static void layer_call_step(const wt_atmosphere *atm, const wt_grid *tg, double c, sh_step *q)
{
    if (atm->sh_levels) sh_step_init(atm->sh_levels, 1.0 / (atm->n * atm->delta), c * tg->dx, q);
}

/* The masked points of one target row: the span [lo, hi] the kernels sample (the whole row without a
 * mask) and the masked points per block of SH_CHUNK from lo. It depends on the mask only, so a batch
 * computes it once per (mask, row) for all layers and lines of sight (span_memo). */
#define SPAN_BLOCKS 64
typedef struct row_span {
    int lo, hi;               /* lo > hi: no masked point */
    int nb;                   /* blocks counted in cnt (0: more than SPAN_BLOCKS; the kernel counts) */
    const uint8_t *mk;        /* the row's mask (NULL: all points) */
    uint8_t cnt[SPAN_BLOCKS]; /* masked points of block (k − lo) / SH_CHUNK */
} row_span;

static void row_span_init(const uint8_t *mask, int nx, int iy, row_span *sp)
{
    const uint8_t *mk = mask ? mask + (int64_t)iy * nx : NULL;
    int lo = 0, hi = nx - 1;
    sp->mk = mk, sp->nb = 0;
    if (mk) {
        while (lo < nx && !mk[lo]) lo++;
        while (hi >= lo && !mk[hi]) hi--;
        const int nb = hi < lo ? 0 : (hi - lo) / SH_CHUNK + 1;
        if (nb <= SPAN_BLOCKS) {
            sp->nb = nb;
            for (int bk = 0; bk < nb; bk++) {
                const int k0 = lo + bk * SH_CHUNK, m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
                int cnt = 0;
                for (int k = 0; k < m; k++) cnt += mk[k0 + k] != 0;
                sp->cnt[bk] = (uint8_t)cnt;
            }
        }
    }
    sp->lo = lo, sp->hi = hi;
}

/* What one (layer, target row) shares between the lines of sight of a batch: the y part of a row start
 * (the screen row position w and the subharmonic g0, G_p) depends on the layer and py only, the x part
 * (the position u0 and E_p) on px0 only. They are looked up by the bits of py and px0 (the same
 * arguments give the same fmod and libm results, so sharing is exact). The E-ELT's 25 evaluation
 * directions on a 5 x 5 grid have 5 distinct py and 5 distinct px0 per row and layer: 10 sets of 3
 * sincos and one fmod instead of 50. When full, the next ones are computed without sharing. */
#define ROW_MEMO 16
typedef struct row_memo {
    int ny, nx;
    uint64_t ykey[ROW_MEMO], xkey[ROW_MEMO];
    double w[ROW_MEMO], u0[ROW_MEMO];
    sh_row y[ROW_MEMO], x[ROW_MEMO]; /* y: g0, gr, gi; x: er, ei */
} row_memo;

static inline uint64_t dbits(double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

/* What both row kernels start from: the row's span, the unwrapped screen position u0 of point lo along
 * x, the screen rows r0, r1 (index j, j1 = j + 1 mod n) and weight fy along y, and the subharmonic row
 * state. */
typedef struct row_start {
    int lo, hi, j1;
    const uint8_t *mk; /* the row's mask (NULL: all points) */
    double *o;         /* the row's output */
    double u0, fy;
    const double *r0, *r1;
    sh_row s;
} row_start;

/* 0: the row has no masked point. mm: the memo of this (layer, row), or NULL. */
static inline int row_start_init(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg,
                                 const row_span *sp, double *out, int iy, row_memo *mm, row_start *r)
{
    if (sp->lo > sp->hi) return 0;
    const int n = atm->n, lo = sp->lo, levels = atm->sh_levels;
    const double inv = 1.0 / atm->delta, c = lc->c, dk = 1.0 / (n * atm->delta);
    const double px0 = c * (tg->x0 + lo * tg->dx) + lc->ax, py = c * (tg->y0 + iy * tg->dx) + lc->ay;
    double w, u0;
    sh_row *s = &r->s;
    *s = (sh_row){0};
    if (mm) {
        const uint64_t ky = dbits(py), kx = dbits(px0);
        int a = 0, b = 0;
        while (a < mm->ny && mm->ykey[a] != ky) a++;
        if (a < mm->ny) {
            w = mm->w[a];
            s->g0 = mm->y[a].g0;
            memcpy(s->gr, mm->y[a].gr, sizeof s->gr);
            memcpy(s->gi, mm->y[a].gi, sizeof s->gi);
        } else {
            w = wrap((py - atm->grid.y0) * inv, n);
            if (levels) sh_row_y(lc->ly, levels, dk, py, s);
            if (a < ROW_MEMO) mm->ykey[a] = ky, mm->w[a] = w, mm->y[a] = *s, mm->ny++;
        }
        while (b < mm->nx && mm->xkey[b] != kx) b++;
        if (b < mm->nx) {
            u0 = mm->u0[b];
            memcpy(s->er, mm->x[b].er, sizeof s->er);
            memcpy(s->ei, mm->x[b].ei, sizeof s->ei);
        } else {
            u0 = wrap((px0 - atm->grid.x0) * inv, n);
            if (levels) sh_row_x(levels, dk, px0, s);
            if (b < ROW_MEMO) mm->xkey[b] = kx, mm->u0[b] = u0, mm->x[b] = *s, mm->nx++;
        }
    } else {
        w = wrap((py - atm->grid.y0) * inv, n);
        u0 = wrap((px0 - atm->grid.x0) * inv, n);
        if (levels) sh_row_init(lc->ly, levels, dk, py, px0, s);
    }
    const int j = (int)w;
    r->lo = lo, r->hi = sp->hi, r->mk = sp->mk, r->o = out + (int64_t)iy * tg->nx;
    r->u0 = u0;
    r->j1 = j + 1 == n ? 0 : j + 1;
    r->fy = w - j;
    r->r0 = lc->ly->screen + (int64_t)n * j, r->r1 = lc->ly->screen + (int64_t)n * r->j1;
    return 1;
}

/* The reference (point by point, the definition of every bit): target row iy, one layer:
 * out[row] += alpha · screen on the masked points. */
static void project_row_reference(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg,
                                  const row_span *sp, double alpha, double *out, int iy, row_memo *mm, int set)
{
    (void)mm; /* the definition computes every row's set-up itself */
    const int n = atm->n;
    row_start r;
    if (!row_start_init(atm, lc, tg, sp, out, iy, NULL, &r)) return;
    const int lo = r.lo, hi = r.hi;
    const uint8_t *mk = r.mk;
    double *o = r.o;
    const double u0 = r.u0, fy = r.fy, b = lc->b, *r0 = r.r0, *r1 = r.r1;
    int off = 0; /* multiple of n taken off the unwrapped index: u grows monotonically along the row */
    sh_row s = r.s;
    for (int k0 = lo; k0 <= hi; k0 += SH_CHUNK) {
        const int m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
        double shv[SH_CHUNK];
        if (atm->sh_levels) sh_row_block(lc->q, &s, m, shv);
        else for (int k = 0; k < m; k++) shv[k] = 0.0;
        for (int k = 0; k < m; k++) {
            const int ix = k0 + k;
            const double u = u0 + (ix - lo) * b;
            const int iu = (int)u;
            const double fx = u - iu;
            int i = iu - off;
            while (i >= n) i -= n, off += n;
            const int i1 = i + 1 == n ? 0 : i + 1;
            const double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
            if (!mk || mk[ix]) o[ix] = (set ? 0.0 : o[ix]) + alpha * (a0 + fy * (a1 - a0) + shv[k]);
        }
    }
}

/* E_p advanced by one block without evaluating it (a block with no masked point): the same rotation
 * as the end of sh_row_block, so the blocks after it see the same E_p bit for bit. */
static inline void sh_row_skip(const sh_step *q, sh_row *s)
{
    for (int p = 0; p < q->levels; p++) {
        double er = s->er[p], ei = s->ei[p];
        s->er[p] = er * q->rr[p] - ei * q->ri[p];
        s->ei[p] = er * q->ri[p] + ei * q->rr[p];
    }
}

/* One block of a unit row (see project_row): levels SHL or 0, masked or not, one fx for the block or
 * one per point, adding to the output or setting it (set: 0 + the term, the bits of adding to a zeroed
 * output). Compile-time flags: each combination is its own branch-free loop. */
typedef struct unit_args {
    const double *p0, *p1;   /* the two screen rows from the block's first cell */
    const uint8_t *bm;       /* the block's mask (NULL: all points) */
    double *o;               /* the block's output */
    double u0, fy, alpha, g0, fx;
    double ar[SHL], ai[SHL]; /* the block's subharmonic coefficients */
    const double *pr[SHL], *pi[SHL];
    int d0, c0, m;
} unit_args;

static inline __attribute__((always_inline)) void unit_block(const unit_args *a, const int levels,
                                                             const int masked, const int fxc, const int set)
{
    const double *restrict p0 = a->p0, *restrict p1 = a->p1;
    const uint8_t *restrict bm = a->bm;
    double *restrict o = a->o;
    const double u0 = a->u0, fy = a->fy, alpha = a->alpha, g0 = a->g0, fxb = a->fx;
    const double ar0 = a->ar[0], ar1 = a->ar[1], ar2 = a->ar[2], ai0 = a->ai[0], ai1 = a->ai[1], ai2 = a->ai[2];
    const double *restrict pr0 = a->pr[0], *restrict pr1 = a->pr[1], *restrict pr2 = a->pr[2];
    const double *restrict pi0 = a->pi[0], *restrict pi1 = a->pi[1], *restrict pi2 = a->pi[2];
    const int d0 = a->d0, c0 = a->c0, m = a->m;
    for (int k = 0; k < m; k++) {
        const double fx = fxc ? fxb : (u0 + (double)(d0 + k)) - (double)(c0 + k);
        double sv = 0.0;
        if (levels) {
            sv = g0;
            sv += ar0 * pr0[k] - ai0 * pi0[k];
            sv += ar1 * pr1[k] - ai1 * pi1[k];
            sv += ar2 * pr2[k] - ai2 * pi2[k];
        }
        const double a0 = p0[k] + fx * (p0[k + 1] - p0[k]), a1 = p1[k] + fx * (p1[k + 1] - p1[k]);
        const double v = a0 + fy * (a1 - a0) + sv;
        const double o0 = set ? 0.0 : o[k];
        if (masked) o[k] = bm[k] ? o0 + alpha * v : o[k];
        else o[k] = o0 + alpha * v;
    }
}

/* The fast path of project_row_reference, with the same arithmetic on every computed point (so the
 * same bits; tests/test_atmosphere.c compares them) but organised per block of SH_CHUNK points:
 *  - a block with no masked point evaluates nothing (the NGS sensors read only the pupil rim, the LGS
 *    sensors ~7/16 of the points), it only steps the subharmonic rotation;
 *  - the sample index along the row is iu mod n (iu = ⌊u⌋ ≥ 0 grows along the row), so a block whose
 *    iu stay within one period and off its last cell needs no wrap test: a branch-free loop the
 *    compiler vectorises; blocks across the seam and sparse blocks take the point-by-point loop.
 * Sparse blocks evaluate only their masked points: in unit rows (below) those with fewer than a
 * quarter of their points masked, elsewhere those with at most half (the LGS rows between subaperture
 * corners, every 4th point).
 *
 * Unit rows. Where one target step is exactly one screen cell (b = 1: the lines of sight from
 * infinity, NGS and evaluation directions, 4/5 of all samples at E-ELT size), u_k = fl(u0 + k) and
 * ⌊u_k⌋ = ⌊u0⌋ + k for every k as long as the fraction of u0 is farther from 0 and 1 than the rounding
 * of u0 + k (≤ half an ulp of the row's largest u): then the cell index and the weight fx = u_k − ⌊u_k⌋
 * need no conversion back from u, the screen reads are contiguous, and the subharmonic sum, the
 * bilinear weights and the accumulation run in one loop without intermediate arrays; each value is
 * still formed by the same operations in the same order. Cloned for AVX2 and AVX-512 (WT_CPU_CLONES: wider
 * vectors, hardware gathers; the same bits on every CPU). */
WT_CPU_CLONES
static void project_row(const wt_atmosphere *atm, const layer_call *lc, const wt_grid *tg, const row_span *sp,
                        double alpha, double *out, int iy, row_memo *mm, int set)
{
    const int n = atm->n, levels = atm->sh_levels;
    row_start r;
    if (!row_start_init(atm, lc, tg, sp, out, iy, mm, &r)) return;
    const int lo = r.lo, hi = r.hi;
    const uint8_t *mk = r.mk;
    double *o = r.o;
    const double u0 = r.u0, fy = r.fy, b = lc->b, *r0 = r.r0, *r1 = r.r1;
    /* The sparse points (NGS rims, LGS rows between subaperture corners) read scattered screen cells
     * that miss every cache: their cells in the next screen row, which the next target row reads, are
     * prefetched (dense blocks measured no gain from it). */
    const double *r2 = lc->ly->screen + (int64_t)n * (r.j1 + 1 == n ? 0 : r.j1 + 1);
    sh_row s = r.s;
    int unit = 0, iu0 = 0;
    if (b == 1.0) {
        iu0 = (int)u0;
        const double f = u0 - iu0, eps = (u0 + (hi - lo) + 2.0) * 0x1p-52;
        unit = f > eps && f < 1.0 - eps;
    }
    for (int k0 = lo; k0 <= hi; k0 += SH_CHUNK) {
        const int m = hi - k0 + 1 < SH_CHUNK ? hi - k0 + 1 : SH_CHUNK;
        int cnt = m;
        if (mk) {
            const int bk = (k0 - lo) / SH_CHUNK;
            if (bk < sp->nb) cnt = sp->cnt[bk];
            else {
                cnt = 0;
                for (int k = 0; k < m; k++) cnt += mk[k0 + k] != 0;
            }
            if (cnt == 0) {
                if (levels) sh_row_skip(lc->q, &s);
                continue;
            }
        }
        const int d0 = k0 - lo; /* (ix − lo) of the block's first point */
        if (unit && 4 * cnt >= m) {
            const int c0 = iu0 + d0, i0 = c0 < n ? c0 : c0 % n; /* the block's first cell, wrapped */
            if (i0 + m <= n - 1) {
                unit_args ua = {.p0 = r0 + i0, .p1 = r1 + i0, .bm = mk && cnt < m ? mk + k0 : NULL, .o = o + k0,
                                .u0 = u0, .fy = fy, .alpha = alpha, .g0 = s.g0, .d0 = d0, .c0 = c0, .m = m};
                if (levels == SHL) {
                    sh_row_coef(lc->q, &s, ua.ar, ua.ai);
                    for (int p = 0; p < SHL; p++) ua.pr[p] = lc->q->pr[p], ua.pi[p] = lc->q->pi[p];
                }
                /* one fx for the block when its cells lie in one binade [2^e, 2^(e+1)): there
                 * fl(c + f) = c + (f rounded to the binade's ulp) for every integer c */
                const int fxc = c0 >= 1 && ((c0 ^ (c0 + m - 1)) <= c0);
                if (fxc) ua.fx = (u0 + (double)d0) - (double)c0;
                if (levels == SHL) {
                    /* each combination of the flags is its own loop (masked, one fx, set) */
                    switch ((ua.bm != NULL) << 2 | fxc << 1 | (set != 0)) {
                    case 0: unit_block(&ua, SHL, 0, 0, 0); break;
                    case 1: unit_block(&ua, SHL, 0, 0, 1); break;
                    case 2: unit_block(&ua, SHL, 0, 1, 0); break;
                    case 3: unit_block(&ua, SHL, 0, 1, 1); break;
                    case 4: unit_block(&ua, SHL, 1, 0, 0); break;
                    case 5: unit_block(&ua, SHL, 1, 0, 1); break;
                    case 6: unit_block(&ua, SHL, 1, 1, 0); break;
                    default: unit_block(&ua, SHL, 1, 1, 1); break;
                    }
                } else {
                    unit_block(&ua, 0, ua.bm != NULL, 0, set);
                }
                continue;
            }
        }
        const int iu_a = (int)(u0 + d0 * b), iu_b = (int)(u0 + (d0 + m - 1) * b);
        const int q0 = iu_a < n ? 0 : iu_a / n;
        if (2 * cnt > m && iu_b - q0 * n <= n - 2) {
            double shv[SH_CHUNK], val[SH_CHUNK];
            if (levels) sh_row_block(lc->q, &s, m, shv);
            else for (int k = 0; k < m; k++) shv[k] = 0.0;
            const int oc = q0 * n;
            double fxv[SH_CHUNK];
            int iv[SH_CHUNK], steps = 0;
            for (int k = 0; k < m; k++) {
                const double u = u0 + (d0 + k) * b;
                const int iu = (int)u;
                fxv[k] = u - iu;
                iv[k] = iu - oc;
            }
            for (int k = 0; k < m; k++) steps += iv[k] != iv[0] + k;
            if (steps == 0) { /* one screen cell per point */
                const double *restrict p0 = r0 + iv[0], *restrict p1 = r1 + iv[0];
                for (int k = 0; k < m; k++) {
                    const double a0 = p0[k] + fxv[k] * (p0[k + 1] - p0[k]), a1 = p1[k] + fxv[k] * (p1[k + 1] - p1[k]);
                    val[k] = a0 + fy * (a1 - a0) + shv[k];
                }
            } else {
                for (int k = 0; k < m; k++) {
                    const int i = iv[k];
                    const double a0 = r0[i] + fxv[k] * (r0[i + 1] - r0[i]), a1 = r1[i] + fxv[k] * (r1[i + 1] - r1[i]);
                    val[k] = a0 + fy * (a1 - a0) + shv[k];
                }
            }
            if (cnt == m)
                for (int k = 0; k < m; k++) o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * val[k];
            else
                for (int k = 0; k < m; k++)
                    if (mk[k0 + k]) o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * val[k];
            continue;
        }
        /* point by point (sparse blocks, the seam): the subharmonic sum of the masked points only, in
         * the order of sh_row_block */
        double ar[SHL] = {0}, ai[SHL] = {0};
        if (levels) sh_row_coef(lc->q, &s, ar, ai);
        for (int k = 0; k < m; k++) {
            if (mk && !mk[k0 + k]) continue;
            double sv = 0.0;
            if (levels) {
                sv = s.g0;
                for (int p = 0; p < levels; p++) sv += ar[p] * lc->q->pr[p][k] - ai[p] * lc->q->pi[p][k];
            }
            const double u = u0 + (d0 + k) * b;
            const int iu = (int)u;
            const double fx = u - iu;
            const int i = iu < n ? iu : iu % n, i1 = i + 1 == n ? 0 : i + 1;
            __builtin_prefetch(r2 + i);
            const double a0 = r0[i] + fx * (r0[i1] - r0[i]), a1 = r1[i] + fx * (r1[i1] - r1[i]);
            o[k0 + k] = (set ? 0.0 : o[k0 + k]) + alpha * (a0 + fy * (a1 - a0) + sv);
        }
    }
}

/* The checks of wt_atmosphere_project and wt_atmosphere_project_reference. */
static int check_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                         double theta_y, const wt_grid *target, double *out)
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
    return WT_OK;
}

/* The projection with row kernel `row`. Layers outer, rows inner: the per-layer set-up (subharmonic
 * rotations) is done once per thread. The static schedule gives each thread the same rows for every
 * layer, so `nowait` is safe and every point adds its layers in layer order whatever the thread count
 * (bit-identical results). */
typedef void (*row_kernel)(const wt_atmosphere *, const layer_call *, const wt_grid *, const row_span *, double,
                           double *, int, row_memo *, int);

static int project_with(row_kernel row, const wt_atmosphere *atm, double t, double source_altitude,
                        double theta_x, double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                        double *out)
{
    int st = check_project(atm, t, source_altitude, theta_x, theta_y, target, out);
    if (st < 0 || alpha == 0.0) return st;
    const int ny = target->ny, nl = atm->nlayers;
    const int nth = wt_context_threads(atm->ctx);
    (void)nth;
#pragma omp parallel num_threads(nth) if (nth > 1 && ny > 1 && !omp_in_parallel())
    for (int l = 0; l < nl; l++) {
        layer_call lc;
        sh_step q;
        layer_call_init(atm, l, t, source_altitude, theta_x, theta_y, target, &lc);
        layer_call_step(atm, target, lc.c, &q);
        lc.q = &q;
#pragma omp for schedule(static) nowait
        for (int iy = 0; iy < ny; iy++) {
            row_span sp;
            row_span_init(mask, target->nx, iy, &sp);
            row(atm, &lc, target, &sp, alpha * lc.ly->scale, out, iy, NULL, 0);
        }
    }
    return WT_OK;
}

int wt_atmosphere_project(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                          double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                          double *out)
{
    return project_with(project_row, atm, t, source_altitude, theta_x, theta_y, target, mask, alpha, out);
}

int wt_atmosphere_project_reference(const wt_atmosphere *atm, double t, double source_altitude, double theta_x,
                                    double theta_y, const wt_grid *target, const uint8_t *mask, double alpha,
                                    double *out)
{
    return project_with(project_row_reference, atm, t, source_altitude, theta_x, theta_y, target, mask, alpha,
                        out);
}

/* Batched: bands of BAND_ROWS target rows, and in each band every layer for every line of sight. The
 * lines of sight of one frame see nearly the same part of a layer (the E-ELT footprints differ by θh,
 * at most 15 m of 57 m at 18 km), so a band's screen rows are read from memory once for all of them
 * and then from cache, where one call per line of sight read each layer's footprint again (~0.7 MB
 * per line of sight and layer, 200 MB per E-ELT frame). Each point still adds its layers in layer
 * order, so the result is that of one wt_atmosphere_project per line of sight, bit for bit, for any
 * schedule. The set-up is per (line of sight, layer) with one subharmonic step per distinct cone
 * factor; beyond BATCH_PAIRS pairs or BATCH_STEPS factors it falls back to one call per line of sight. */
#define BAND_ROWS 8
#define BATCH_PAIRS 512
#define BATCH_STEPS 24
#define MANY_LAYERS 16

/* The spans of one target row by mask (the E-ELT's 34 lines of sight have 10 distinct masks). */
#define SPAN_MEMO 16
typedef struct span_memo {
    int n;
    const uint8_t *key[SPAN_MEMO];
    row_span v[SPAN_MEMO];
} span_memo;

static const row_span *span_lookup(span_memo *m, const uint8_t *mask, int nx, int iy, row_span *tmp)
{
    for (int k = 0; k < m->n; k++)
        if (m->key[k] == mask) return &m->v[k];
    row_span *sp = m->n < SPAN_MEMO ? &m->v[m->n] : tmp;
    row_span_init(mask, nx, iy, sp);
    if (m->n < SPAN_MEMO) m->key[m->n++] = mask;
    return sp;
}

/* The masked points of the outputs with `set` are zeroed (where the batch does not set them itself). */
static void zero_set_outputs(int nlos, const wt_atmosphere_los *los, const wt_grid *target)
{
    const int64_t np = wt_grid_size(target);
    for (int i = 0; i < nlos; i++)
        if (los[i].set)
            for (int64_t k = 0; k < np; k++)
                if (!los[i].mask || los[i].mask[k]) los[i].out[k] = 0.0;
}

int wt_atmosphere_project_many(const wt_atmosphere *atm, double t, int nlos, const wt_atmosphere_los *los,
                               const wt_grid *target, double alpha)
{
    if (!atm) return WT_ERR_INVALID;
    if (nlos < 0 || (nlos > 0 && !los))
        return WT_ERROR(atm->ctx, WT_ERR_INVALID, "wt_atmosphere_project_many: %d lines of sight at %p", nlos,
                        (const void *)los);
    for (int i = 0; i < nlos; i++) {
        int st = check_project(atm, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target, los[i].out);
        if (st < 0) return st;
    }
    if (nlos == 0) return WT_OK;
    const int nl = atm->nlayers, ny = target->ny;
    if (alpha == 0.0) {
        zero_set_outputs(nlos, los, target);
        return WT_OK;
    }
    layer_call lc[BATCH_PAIRS];
    sh_step q[BATCH_STEPS];
    double qc[BATCH_STEPS];
    int nq = 0, fit = (int64_t)nlos * nl <= BATCH_PAIRS && nl <= MANY_LAYERS;
    for (int i = 0; fit && i < nlos; i++)
        for (int l = 0; fit && l < nl; l++) {
            layer_call *c = &lc[i * nl + l];
            layer_call_init(atm, l, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target, c);
            int k = 0;
            while (k < nq && qc[k] != c->c) k++;
            if (k == nq) {
                if (nq == BATCH_STEPS) {
                    fit = 0;
                    break;
                }
                qc[nq] = c->c;
                layer_call_step(atm, target, c->c, &q[nq++]);
            }
            c->q = &q[k];
        }
    if (!fit) {
        zero_set_outputs(nlos, los, target);
        for (int i = 0; i < nlos; i++) {
            int st = wt_atmosphere_project(atm, t, los[i].source_altitude, los[i].theta_x, los[i].theta_y, target,
                                           los[i].mask, alpha, los[i].out);
            if (st < 0) return st;
        }
        return WT_OK;
    }
    const int nb = (ny + BAND_ROWS - 1) / BAND_ROWS, nth = wt_context_threads(atm->ctx);
    (void)nth;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) if (nth > 1 && nb > 1 && !omp_in_parallel())
    for (int bd = 0; bd < nb; bd++) {
        const int y0 = bd * BAND_ROWS, y1 = y0 + BAND_ROWS < ny ? y0 + BAND_ROWS : ny;
        span_memo spm;
        row_memo mm[MANY_LAYERS];
        for (int iy = y0; iy < y1; iy++) {
            spm.n = 0;
            for (int l = 0; l < nl; l++) mm[l].ny = mm[l].nx = 0;
            for (int i = 0; i < nlos; i++) {
                row_span tmp;
                const row_span *sp = span_lookup(&spm, los[i].mask, target->nx, iy, &tmp);
                for (int l = 0; l < nl; l++)
                    project_row(atm, &lc[i * nl + l], target, sp, alpha * lc[i * nl + l].ly->scale, los[i].out, iy, &mm[l],
                                l == 0 && los[i].set);
            }
        }
    }
    return WT_OK;
}
