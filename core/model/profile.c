/* core/model/profile.c: a Cn² profile compressed onto reconstruction layers (SPEC §12; see profile.h). */
#include "profile.h"

void wt_profile_bin_altitude(int L, const double *alt, double h, int *l, double *w)
{
    *l = 0;
    *w = 0.0;
    if (h <= alt[0]) return;
    if (h >= alt[L - 1]) {
        *l = L - 1;
        return;
    }
    while (!(h >= alt[*l] && h < alt[*l + 1])) (*l)++;
    *w = (h - alt[*l]) / (alt[*l + 1] - alt[*l]);
}

/* v_l = Σ c v / Σ c from the sums Σ c v in rvx, rvy; a layer that absorbed nothing has no wind */
static void wind_mean(int L, const double *rfrac, double *rvx, double *rvy)
{
    for (int l = 0; l < L; l++) {
        rvx[l] = rfrac[l] > 0.0 ? rvx[l] / rfrac[l] : 0.0;
        rvy[l] = rfrac[l] > 0.0 ? rvy[l] / rfrac[l] : 0.0;
    }
}

void wt_profile_compress(int n, const double *alt, const double *frac, const double *vx, const double *vy, int L,
                         const double *ralt, double *rfrac, double *rvx, double *rvy)
{
    const int wind = vx && vy && rvx && rvy;
    for (int l = 0; l < L; l++) {
        rfrac[l] = 0.0;
        if (wind) rvx[l] = rvy[l] = 0.0;
    }
    for (int k = 0; k < n; k++) {
        int l;
        double w;
        wt_profile_bin_altitude(L, ralt, alt[k], &l, &w);
        /* c_{k,l} = (1 − w) f_k, c_{k,l+1} = w f_k: the order and form of these sums are the prior's since the
         * first binning of the profile (the same bits for today's configurations) */
        rfrac[l] += (1.0 - w) * frac[k];
        if (w > 0.0) rfrac[l + 1] += w * frac[k];
        if (!wind) continue;
        rvx[l] += (1.0 - w) * frac[k] * vx[k];
        rvy[l] += (1.0 - w) * frac[k] * vy[k];
        if (w > 0.0) {
            rvx[l + 1] += w * frac[k] * vx[k];
            rvy[l + 1] += w * frac[k] * vy[k];
        }
    }
    if (wind) wind_mean(L, rfrac, rvx, rvy);
}

/* φ_k(h): the hat of grid point k (1 at alt[k], 0 at its neighbours and beyond; no side past an end point) */
static double hat(int n, const double *alt, int k, double h)
{
    if (h < alt[k]) return k > 0 && h > alt[k - 1] ? (h - alt[k - 1]) / (alt[k] - alt[k - 1]) : 0.0;
    if (h > alt[k]) return k < n - 1 && h < alt[k + 1] ? (alt[k + 1] - h) / (alt[k + 1] - alt[k]) : 0.0;
    return 1.0;
}

/* acc[l] += s φ_k(h) b_l(h), b the linear split of wt_profile_bin_altitude */
static void hat_bin(int n, const double *alt, int k, int L, const double *ralt, double h, double s, double *acc)
{
    int l;
    double w;
    const double v = s * hat(n, alt, k, h);
    wt_profile_bin_altitude(L, ralt, h, &l, &w);
    acc[l] += (1.0 - w) * v;
    if (w > 0.0) acc[l + 1] += w * v;
}

void wt_profile_compress_hats(int n, const double *alt, const double *frac, const double *vx, const double *vy, int L,
                              const double *ralt, double *rfrac, double *rvx, double *rvy)
{
    if (n < 2) {
        wt_profile_compress(n, alt, frac, vx, vy, L, ralt, rfrac, rvx, rvy);
        return;
    }
    const int wind = vx && vy && rvx && rvy;
    for (int l = 0; l < L; l++) {
        rfrac[l] = 0.0;
        if (wind) rvx[l] = rvy[l] = 0.0;
    }
    for (int k = 0; k < n; k++) {
        if (!(frac[k] != 0.0)) continue;
        const double a = alt[k > 0 ? k - 1 : 0], c = alt[k < n - 1 ? k + 1 : n - 1];
        /* the knots of φ_k b_l on [a, c]: a, alt[k], c and the layers inside; between two of them the product of
         * two linear functions, a quadratic, which Simpson's rule integrates exactly */
        double x[WT_PROFILE_MAX_KNOTS];
        int m = 0;
        x[m++] = a;
        for (int l = 0; l < L && m < WT_PROFILE_MAX_KNOTS - 2; l++)
            if (ralt[l] > a && ralt[l] < alt[k]) x[m++] = ralt[l];
        if (alt[k] > a) x[m++] = alt[k];
        for (int l = 0; l < L && m < WT_PROFILE_MAX_KNOTS - 1; l++)
            if (ralt[l] > alt[k] && ralt[l] < c) x[m++] = ralt[l];
        if (c > alt[k]) x[m++] = c;
        double acc[WT_PROFILE_MAX_KNOTS] = {0};
        for (int i = 0; i + 1 < m; i++) {
            const double h = x[i + 1] - x[i], s = frac[k] / (0.5 * (c - a)) * h / 6.0;
            hat_bin(n, alt, k, L, ralt, x[i], s, acc);
            hat_bin(n, alt, k, L, ralt, 0.5 * (x[i] + x[i + 1]), 4.0 * s, acc);
            hat_bin(n, alt, k, L, ralt, x[i + 1], s, acc);
        }
        for (int l = 0; l < L; l++) {
            rfrac[l] += acc[l];
            if (wind) rvx[l] += acc[l] * vx[k], rvy[l] += acc[l] * vy[k];
        }
    }
    if (wind) wind_mean(L, rfrac, rvx, rvy);
}
