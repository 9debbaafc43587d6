/* core/optics/image_shift.c: cubic B-spline shifts accumulated and the mean image with its derivatives (image_shift.h):
 *   acc = Σ_f T_{u_f} I_f,  mean = P acc / n,  ∂mean/∂u_x = −D_x B_y P mean,  D = (c[i+1] − c[i−1]) / 2,
 *   B = [1 4 1]/6, P = B⁻¹ (causal and anti-causal recursions of pole z = √3 − 2, on lines padded with PAD zeros:
 *   the truncation is z^PAD ~ 1e-7 of the edge's coefficients). */
#include "image_shift.h"

#include <math.h>
#include <string.h>

#define PAD 12

int wt_image_shift_side(int ns) { return ns + 2 * WT_IMAGE_SHIFT_MARGIN; }

/* the four taps of a shift u: (T_u c)[i] = Σ_t c[i − k0 − t] w[t] */
static void taps(double u, int *k0, double w[4])
{
    /* k = f − 1 + t, x = k − u = t − 1 − a (u = f + a, 0 ≤ a < 1): β3 at 1 + a, a, 1 − a, 2 − a */
    const double f = floor(u), a = u - f, b = 1.0 - a;
    *k0 = (int)f - 1;
    w[0] = b * b * b / 6.0;
    w[1] = 2.0 / 3.0 - a * a + 0.5 * a * a * a;
    w[2] = 2.0 / 3.0 - b * b + 0.5 * b * b * b;
    w[3] = a * a * a / 6.0;
}

static double clampu(double u)
{
    if (!isfinite(u)) return 0.0;
    return u > WT_SHIFT_MAXSHIFT ? WT_SHIFT_MAXSHIFT : u < -WT_SHIFT_MAXSHIFT ? -WT_SHIFT_MAXSHIFT : u;
}

void wt_image_shift_accumulate(int ns, const float *img, double ux, double uy, float *acc, float *tmp)
{
    const int E = wt_image_shift_side(ns), M = WT_IMAGE_SHIFT_MARGIN;
    int kx, ky;
    double wx[4], wy[4];
    taps(clampu(ux), &kx, wx);
    taps(clampu(uy), &ky, wy);
    /* along x: tmp[j E + m + kx + t + M] += img[m, j] wx[t] (four contiguous axpys per row: vectorised) */
    memset(tmp, 0, (size_t)ns * E * sizeof *tmp);
    for (int j = 0; j < ns; j++) {
        const float *in = img + (size_t)j * ns;
        for (int t = 0; t < 4; t++) {
            float *restrict o = tmp + (size_t)j * E + kx + t + M;
            const float w = (float)wx[t];
            for (int m = 0; m < ns; m++) o[m] += in[m] * w;
        }
    }
    /* along y into acc: row j + ky + t + M */
    for (int j = 0; j < ns; j++) {
        const float *r = tmp + (size_t)j * E;
        for (int t = 0; t < 4; t++) {
            float *restrict o = acc + (size_t)(j + ky + t + M) * E;
            const float w = (float)wy[t];
            for (int i = 0; i < E; i++) o[i] += r[i] * w;
        }
    }
}

/* P along one line of n values at stride s, in place, padded with PAD zeros each side in line[n + 2 PAD] */
static void prefilter(double *x, int n, int s, double *line)
{
    const double z = sqrt(3.0) - 2.0;
    const int L = n + 2 * PAD;
    memset(line, 0, (size_t)L * sizeof *line);
    for (int i = 0; i < n; i++) line[PAD + i] = x[(size_t)i * s];
    for (int k = 1; k < L; k++) line[k] += z * line[k - 1];
    line[L - 1] *= z / (z * z - 1.0);
    for (int k = L - 2; k >= 0; k--) line[k] = z * (line[k + 1] - line[k]);
    for (int i = 0; i < n; i++) x[(size_t)i * s] = 6.0 * line[PAD + i];
}

int wt_image_shift_work(int ns)
{
    const int E = wt_image_shift_side(ns);
    return E * E + E + 2 * PAD; /* ≥ (ns + 2)² + ns + 2 + 2 PAD */
}

void wt_image_shift_mean(int ns, const float *acc, double scale, float *mean, double *tmp)
{
    const int E = wt_image_shift_side(ns), M = WT_IMAGE_SHIFT_MARGIN;
    double *a = tmp, *line = tmp + (size_t)E * E;
    /* the mean of the shifted frames: P acc (the accumulator's margin holds every frame's T_u I whole) */
    for (size_t q = 0; q < (size_t)E * E; q++) a[q] = acc[q] * scale;
    for (int j = 0; j < E; j++) prefilter(a + (size_t)j * E, E, 1, line);
    for (int i = 0; i < E; i++) prefilter(a + i, E, E, line);
    for (int j = 0; j < ns; j++)
        for (int i = 0; i < ns; i++) mean[i + (size_t)ns * j] = (float)a[(i + M) + (size_t)E * (j + M)];
}

void wt_image_shift_derivative(int ns, const float *mean, float *dx, float *dy, double *tmp)
{
    const int F = ns + 2;
    double *c = tmp, *line = tmp + (size_t)F * F;
    /* its spline coefficients, the detector's image with zeros outside: on ns + 2 (one pixel round) */
    memset(c, 0, (size_t)F * F * sizeof *c);
    for (int j = 0; j < ns; j++)
        for (int i = 0; i < ns; i++) c[(i + 1) + (size_t)F * (j + 1)] = mean[i + (size_t)ns * j];
    /* P on lines of F with the outer pixels 0: prefilter pads further */
    for (int j = 1; j <= ns; j++) prefilter(c + (size_t)j * F, F, 1, line);
    for (int i = 0; i < F; i++) prefilter(c + i, F, F, line);
    for (int j = 0; j < ns; j++)
        for (int i = 0; i < ns; i++) {
            const double *p = c + (i + 1) + (size_t)F * (j + 1);
            if (dx) {
                const double d0 = p[1 - F] - p[-1 - F], d1 = p[1] - p[-1], d2 = p[1 + F] - p[-1 + F];
                dx[i + (size_t)ns * j] = (float)(-0.5 * (d0 + 4.0 * d1 + d2) / 6.0);
            }
            if (dy) {
                const double d0 = p[F - 1] - p[-F - 1], d1 = p[F] - p[-F], d2 = p[F + 1] - p[-F + 1];
                dy[i + (size_t)ns * j] = (float)(-0.5 * (d0 + 4.0 * d1 + d2) / 6.0);
            }
        }
}
