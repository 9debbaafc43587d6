/* core/sim/strehl.c: piston-removed rms, Maréchal Strehl, long-exposure averages (SPEC §8). */
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
