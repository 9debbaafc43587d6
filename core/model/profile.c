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
    if (!wind) return;
    for (int l = 0; l < L; l++) { /* v_l = Σ c v / Σ c; nothing absorbed: no wind */
        rvx[l] = rfrac[l] > 0.0 ? rvx[l] / rfrac[l] : 0.0;
        rvy[l] = rfrac[l] > 0.0 ? rvy[l] / rfrac[l] : 0.0;
    }
}
