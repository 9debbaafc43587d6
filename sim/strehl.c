/* sim/strehl.c: piston-removed rms, Maréchal Strehl, long-exposure averages (SPEC §8). */
#include "strehl.h"

#include <math.h>

double wt_strehl_rms(const double *opd, const uint8_t *mask, int64_t n)
{
    /* two passes: the mean first, then the spread about it (no cancellation for large pistons) */
    double s = 0.0;
    int64_t c = 0;
    for (int64_t i = 0; i < n; i++)
        if (mask[i]) {
            s += opd[i];
            c++;
        }
    if (c == 0) return 0.0;
    double mean = s / (double)c, v = 0.0;
    for (int64_t i = 0; i < n; i++)
        if (mask[i]) {
            double d = opd[i] - mean;
            v += d * d;
        }
    return sqrt(v / (double)c);
}

/* WT_STREHL_CHAINS (4) sums in registers; a group of fewer maps repeats its first map in the free
 * chains and drops their results. */
void wt_strehl_rms_many(const double *const *opd, const uint8_t *mask, int64_t n, int count, double *rms)
{
    for (int j0 = 0; j0 < count; j0 += WT_STREHL_CHAINS) {
        const int m = count - j0 < WT_STREHL_CHAINS ? count - j0 : WT_STREHL_CHAINS;
        const double *restrict o0 = opd[j0], *restrict o1 = opd[j0 + (m > 1)], *restrict o2 = opd[j0 + 2 * (m > 2)],
                     *restrict o3 = opd[j0 + 3 * (m > 3)];
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
        int64_t c = 0;
        for (int64_t i = 0; i < n; i++)
            if (mask[i]) {
                s0 += o0[i], s1 += o1[i], s2 += o2[i], s3 += o3[i];
                c++;
            }
        double r[WT_STREHL_CHAINS] = {0.0, 0.0, 0.0, 0.0};
        if (c > 0) {
            const double m0 = s0 / (double)c, m1 = s1 / (double)c, m2 = s2 / (double)c, m3 = s3 / (double)c;
            double v0 = 0.0, v1 = 0.0, v2 = 0.0, v3 = 0.0;
            for (int64_t i = 0; i < n; i++)
                if (mask[i]) {
                    const double d0 = o0[i] - m0, d1 = o1[i] - m1, d2 = o2[i] - m2, d3 = o3[i] - m3;
                    v0 += d0 * d0, v1 += d1 * d1, v2 += d2 * d2, v3 += d3 * d3;
                }
            r[0] = sqrt(v0 / (double)c), r[1] = sqrt(v1 / (double)c), r[2] = sqrt(v2 / (double)c),
            r[3] = sqrt(v3 / (double)c);
        }
        for (int j = 0; j < m; j++) rms[j0 + j] = r[j];
    }
}

double wt_strehl_marechal(double rms, double wavelength)
{
    double p = 2.0 * M_PI * rms / wavelength;
    return exp(-p * p);
}

void wt_strehl_le_init(wt_strehl_le *le, int ndir)
{
    le->ndir = ndir;
    le->frames = 0;
    for (int j = 0; j < 225; j++) le->sum_strehl[j] = le->sum_var[j] = 0.0;
}

void wt_strehl_le_add(wt_strehl_le *le, const double *rms, double wavelength)
{
    for (int j = 0; j < le->ndir; j++) {
        le->sum_strehl[j] += wt_strehl_marechal(rms[j], wavelength);
        le->sum_var[j] += rms[j] * rms[j];
    }
    le->frames++;
}

double wt_strehl_le_strehl(const wt_strehl_le *le, int j) { return le->frames ? le->sum_strehl[j] / le->frames : 0.0; }
double wt_strehl_le_wfe(const wt_strehl_le *le, int j) { return le->frames ? sqrt(le->sum_var[j] / le->frames) : 0.0; }
