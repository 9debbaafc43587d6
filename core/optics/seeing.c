/* core/optics/seeing.c: the von Kármán structure function and a subaperture's mean short-exposure,
 * tilt-removed seeing OTF factor (the equations are in seeing.h). */
#include "seeing.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LAMBDA0 500e-9 /* the wavelength r0 is given at [m] */

/* 1 − J0(x), without the cancellation of the difference at small x (series to x⁶: error < x⁸/147456) */
static double one_minus_j0(double x)
{
    if (x < 0.1) {
        const double q = 0.25 * x * x;
        return q * (1.0 - q * (0.25 - q / 36.0));
    }
    return 1.0 - j0(x);
}

/* sin(πx)/(πx) */
static double sinc(double x) { return fabs(x) < 1e-8 ? 1.0 : sin(M_PI * x) / (M_PI * x); }

double wt_seeing_structure(double rho, double r0, double L0, double grid)
{
    if (!(rho > 0.0)) return 0.0;
    const double a2 = (L0 > 0.0 && isfinite(L0)) ? 1.0 / (L0 * L0) : 0.0;
    const double c = (LAMBDA0 / (2.0 * M_PI)) * (LAMBDA0 / (2.0 * M_PI)) * 0.0229 * pow(r0, -5.0 / 3.0);
    /* Simpson in t = ln κ over [κ_lo, κ_hi] = [1e-3, 20]/ρ in two pieces: steps of 0.02 below κρ = 0.5
     * (J0 smooth there) and 0.002 above (at κ_hi a step of 2πκρ·0.002 = 0.25 rad, 25 points per period of
     * J0). Below κ_lo, 1 − J0(x) = x²/4 (to 1e-5 at x = 2π·1e-3) and the piece is in closed form: with
     * u = κ², ∫ κ³ (κ² + a²)^(−11/6) dκ = ½ [6 (u + a²)^(1/6) + (6/5) a² (u + a²)^(−5/6)] (Kolmogorov:
     * 3 κ^(2/3)/2·… = the same with a = 0), which for Kolmogorov is ~1 % of D and may not be dropped (its
     * integrand falls only as κ^(1/3) in ln κ). A rendering grid δ ends the spectrum at
     * the disc of the Nyquist square's area, κ_c = (2/√π)/(2δ), and weighs it by the bilinear
     * interpolation's power transfer sinc⁴(κδ) */
    const double kc = grid > 0.0 ? 1.0 / (sqrt(M_PI) * grid) : INFINITY;
    const double klo = fmin(1e-3 / rho, 0.5 * kc), khi = fmin(20.0 / rho, kc);
    const double tb[3] = {log(klo), log(fmin(0.5 / rho, khi)), log(khi)};
    const double U = klo * klo;
    double body = 0.5 * (6.0 * (pow(U + a2, 1.0 / 6.0) - pow(a2, 1.0 / 6.0)) +
                         1.2 * a2 * (a2 > 0.0 ? pow(U + a2, -5.0 / 6.0) - pow(a2, -5.0 / 6.0) : 0.0)) *
                  (M_PI * rho) * (M_PI * rho);
    for (int piece = 0; piece < 2; piece++) {
        const double t0 = tb[piece], t1 = tb[piece + 1];
        if (!(t1 > t0)) continue;
        const int n = 2 * (int)ceil((t1 - t0) / (piece ? 0.004 : 0.04)); /* even number of intervals */
        const double h = (t1 - t0) / n;
        double sum = 0.0;
        for (int i = 0; i <= n; i++) {
            const double k = exp(t0 + i * h);
            double f = pow(k * k + a2, -11.0 / 6.0) * k * k * one_minus_j0(2.0 * M_PI * k * rho);
            if (grid > 0.0) f *= pow(sinc(k * grid), 4);
            sum += (i == 0 || i == n ? 1.0 : (i % 2 ? 4.0 : 2.0)) * f;
        }
        body += sum * h / 3.0;
    }
    const double tail = grid > 0.0 ? 0.0 : 0.6 * pow(khi * khi + a2, -5.0 / 6.0);
    return 4.0 * M_PI * c * (body + tail);
}

int wt_seeing_lag_table(wt_context *ctx, int np, double dx, double wavelength, double r0, double L0, double grid,
                        double *Dl)
{
    if (np < 1 || !(dx > 0.0) || !(wavelength > 0.0) || !(r0 > 0.0) || !isfinite(dx) || !isfinite(wavelength) ||
        !isfinite(r0) || isnan(L0))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "seeing: %d samples of %g m at %g m with r0 = %g m, L0 = %g m; need samples >= 1 and "
                        "positive finite spacing, wavelength and r0",
                        np, dx, wavelength, r0, L0);
    const double k2 = (2.0 * M_PI / wavelength) * (2.0 * M_PI / wavelength);
    for (int uy = 0; uy < np; uy++)
        for (int ux = 0; ux <= uy; ux++) {
            const double v = k2 * wt_seeing_structure(dx * hypot(ux, uy), r0, L0, grid);
            Dl[ux + np * uy] = Dl[uy + np * ux] = v;
        }
    return WT_OK;
}

size_t wt_seeing_work_size(int np) { return 10 * (size_t)np * np; }

/* −D(a, b)/2 from the lag table: the covariance C up to the constant that the piston removal drops */
static inline double cov(const double *Dl, int np, int a, int b)
{
    const int ix = abs(a % np - b % np), iy = abs(a / np - b / np);
    return -0.5 * Dl[ix + np * iy];
}

/* basis function r of sample a: 1, x, y (sample units, centred) */
static inline double basis(int np, int a, int r)
{
    const double x = a % np - 0.5 * (np - 1), y = a / np - 0.5 * (np - 1);
    return r == 0 ? 1.0 : r == 1 ? x : y;
}

/* C̃_ab = C_ab − (Q M)_ab − (Q M)_ba + (Q S Qᵀ)_ab */
static inline double ctilde(int np, int m, const double *Dl, const double *Q, const double *M, const double *S, int a,
                            int b)
{
    double v = cov(Dl, np, a, b);
    for (int r = 0; r < m; r++) {
        v -= Q[m * a + r] * M[m * b + r] + Q[m * b + r] * M[m * a + r];
        double t = 0.0;
        for (int q = 0; q < m; q++) t += S[m * r + q] * Q[m * b + q];
        v += Q[m * a + r] * t;
    }
    return v;
}

/* Gauss–Jordan inverse of the m × m symmetric positive (semi)definite G (with its ridge) into Gi */
static void small_inverse(int m, double *G, double *Gi)
{
    for (int i = 0; i < m * m; i++) Gi[i] = (i % (m + 1)) == 0;
    for (int c = 0; c < m; c++) {
        int p = c;
        for (int r = c + 1; r < m; r++)
            if (fabs(G[r * m + c]) > fabs(G[p * m + c])) p = r;
        for (int q = 0; q < m; q++) {
            double t = G[c * m + q];
            G[c * m + q] = G[p * m + q], G[p * m + q] = t;
            t = Gi[c * m + q], Gi[c * m + q] = Gi[p * m + q], Gi[p * m + q] = t;
        }
        const double d = G[c * m + c];
        for (int q = 0; q < m; q++) G[c * m + q] /= d, Gi[c * m + q] /= d;
        for (int r = 0; r < m; r++) {
            if (r == c) continue;
            const double f = G[r * m + c];
            for (int q = 0; q < m; q++) G[r * m + q] -= f * G[c * m + q], Gi[r * m + q] -= f * Gi[c * m + q];
        }
    }
}

void wt_seeing_otf(int np, int gtilt, const double *Dl, const float *amp, int N, float *W, double *work)
{
    const int n = np * np, m = 3;
    memset(W, 0, (size_t)N * N * sizeof *W);
    /* work: V = Wt B (the A²-weighted basis), Q = B G⁻¹, M = Vᵀ C (m each per sample), diag C̃ */
    double *V = work, *Q = work + (size_t)m * n, *M = work + 2 * (size_t)m * n, *dg = work + 3 * (size_t)m * n;
    double G[3 * 3] = {0}, Gi[3 * 3];
    int lit = 0;
    for (int a = 0; a < n; a++) {
        const double w = (double)amp[a] * amp[a];
        for (int r = 0; r < m; r++) {
            V[m * a + r] = w * basis(np, a, r);
            for (int q = 0; q < m; q++) G[m * r + q] += w * basis(np, a, r) * basis(np, a, q);
        }
        lit += amp[a] > 0.0f;
    }
    if (!lit) return;
    if (gtilt) {
        /* the tilt rows become the G-tilt functionals, the mean of the A_a A_b-weighted differences of
         * neighbouring samples (what wt_sensing's in-loop gain calls the true slope); T = Q Vᵀ is then an
         * oblique projector (VᵀB = G is not symmetric), which the algebra below does not need */
        double wx = 0.0, wy = 0.0;
        for (int a = 0; a < n; a++) V[m * a + 1] = V[m * a + 2] = 0.0;
        for (int a = 0; a < n; a++) {
            const int i = a % np, j = a / np;
            if (i + 1 < np) {
                const double w = (double)amp[a] * amp[a + 1];
                V[m * (a + 1) + 1] += w, V[m * a + 1] -= w, wx += w;
            }
            if (j + 1 < np) {
                const double w = (double)amp[a] * amp[a + np];
                V[m * (a + np) + 2] += w, V[m * a + 2] -= w, wy += w;
            }
        }
        for (int a = 0; a < n; a++) {
            if (wx > 0) V[m * a + 1] /= wx;
            if (wy > 0) V[m * a + 2] /= wy;
        }
        for (int r = 0; r < m; r++)
            for (int q = 0; q < m; q++) {
                double g = 0.0;
                for (int a = 0; a < n; a++) g += V[m * a + r] * basis(np, a, q);
                G[m * r + q] = g;
            }
    }
    /* G + ε tr(G) I: a lit area of one row or column has no tilt across it (G singular); the small ridge
     * then removes what the area can carry and leaves the rest */
    double tr = 0.0;
    for (int r = 0; r < m; r++) tr += G[(m + 1) * r];
    for (int r = 0; r < m; r++) G[(m + 1) * r] += 1e-10 * tr;
    small_inverse(m, G, Gi);
    for (int a = 0; a < n; a++)
        for (int r = 0; r < m; r++) {
            double v = 0.0;
            for (int q = 0; q < m; q++) v += Gi[m * r + q] * basis(np, a, q);
            Q[m * a + r] = v;
        }
    /* M = Vᵀ C (only lit samples carry weight), S = M V (m × m) */
    for (int b = 0; b < n; b++) {
        double acc[3] = {0};
        for (int a = 0; a < n; a++) {
            if (amp[a] <= 0.0f) continue;
            const double c = cov(Dl, np, a, b);
            for (int r = 0; r < m; r++) acc[r] += V[m * a + r] * c;
        }
        for (int r = 0; r < m; r++) M[m * b + r] = acc[r];
    }
    double S[3 * 3] = {0};
    for (int a = 0; a < n; a++)
        for (int r = 0; r < m; r++)
            for (int q = 0; q < m; q++) S[m * r + q] += M[m * a + r] * V[m * a + q];
    /* C̃_ab = C_ab − (Q M)_ab − (Q M)_ba + (Q S Qᵀ)_ab, T = Q Vᵀ */
    for (int a = 0; a < n; a++) dg[a] = amp[a] > 0.0f ? ctilde(np, m, Dl, Q, M, S, a, a) : 0.0;
    for (int uy = -(np - 1); uy < np; uy++)
        for (int ux = -(np - 1); ux < np; ux++) {
            double num = 0.0, den = 0.0;
            for (int j = (uy < 0 ? -uy : 0); j < (uy > 0 ? np - uy : np); j++)
                for (int i = (ux < 0 ? -ux : 0); i < (ux > 0 ? np - ux : np); i++) {
                    const int a = i + np * j, b = a + ux + np * uy;
                    const double w = (double)amp[a] * amp[b];
                    if (w <= 0.0) continue;
                    const double d = dg[a] + dg[b] - 2.0 * ctilde(np, m, Dl, Q, M, S, a, b);
                    num += w * exp(-0.5 * (d > 0.0 ? d : 0.0));
                    den += w;
                }
            if (den > 0.0) W[((ux + N) % N) + (size_t)N * ((uy + N) % N)] = (float)(num / den);
        }
}
