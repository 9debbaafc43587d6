/* core/model/precond_jacobi.c: the modified Jacobi diagonal of the preconditioners (paper's J; precond.h):
 *
 *   J = diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D,   exact, by coloured probing,
 *
 * below every kind but none and fourier (J⁻¹ off the coarse block, or alone). */
#include "precond_jacobi.h"

#include <math.h>
#include <string.h>

#include "../op/noise.h"
#include "../op/projection.h"
#include "../op/shack_hartmann.h"
#include "../op/wavelet.h"


/* ---- modified Jacobi diagonal ------------------------------------------------------------------ */

/* Accumulates Σ_LGS ‖Ã_m e_λ‖²_{C̃⁻¹} for all coefficients of (layer l, level, orientation) coloured
 * with stride s: coefficients on a sub-lattice of stride s ≥ 2N+2 (N the Daubechies order) have images
 * Ã_m e_λ with disjoint supports in slope space, so one application per colour gives every entry, each
 * subaperture's 2x2 quadratic form attributed to the nearest probe. Buffers: field (n²), coef (n²), work
 * (wavelet), ph (max(ncg, 2n)), sl/z (max slopes). */
static void probe_block(const wt_tomography *t, int l, int level, int orient, int s, double *diag, double *coef,
                        double *field, double *work, double *ph, double *sl, double *z, int a0, int b0, double *parts, int64_t nall)
{
    const wt_system *sys = wt_tomography_system(t);
    const wt_grid *g = wt_tomography_layer_grid(t, l);
    const wt_wavelet *wav = wt_tomography_wavelet(t, l);
    const double alt = wt_tomography_layer_altitude(t, l);
    const int64_t off = wt_tomography_layer_offset(t, l), ncg = wt_grid_size(&sys->sense_grid);
    const int n = g->nx, J = wt_wavelet_levels(wav);
    const int lev = level > J ? J : level;
    const int m = n >> lev, step = 1 << lev;
    const int se = s < m ? s : m;
    const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;

    /* where the k = 0 basis function of this block sits: centre of its support */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    coef[bx + (int64_t)n * by] = 1.0;
    wt_wavelet_inverse(wav, coef, field, work);
    double *colmag = ph, *rowmag = ph + n; /* the caller sizes ph for max(ncg, 2n) */
    memset(colmag, 0, 2 * (size_t)n * sizeof *colmag);
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            double v = fabs(field[ix + (int64_t)n * iy]);
            colmag[ix] += v;
            rowmag[iy] += v;
        }
    double cx0 = wt_precond__support_centre(colmag, n), cy0 = wt_precond__support_centre(rowmag, n);

    /* the colour's probes */
    memset(coef, 0, (size_t)n * n * sizeof *coef);
    for (int j = b0; j < m; j += se)
        for (int i = a0; i < m; i += se) coef[bx + i + (int64_t)n * (by + j)] = 1.0;
    wt_wavelet_inverse(wav, coef, field, work);

    const int nprobe = m / se;
    for (int mm = 0; mm < sys->nlgs; mm++) {
        const wt_sensor *s_ = &sys->sensors[mm];
        memset(ph, 0, (size_t)ncg * sizeof *ph);
        wt_projection_apply(wt_tomography_projection(t, mm, l), 1.0, field, ph);
        memset(sl, 0, (size_t)s_->nslopes * sizeof *sl);
        wt_shack_hartmann_apply(s_->sh, 1.0, ph, sl);
        memset(z, 0, (size_t)s_->nslopes * sizeof *z);
        wt_noise_apply_inv(wt_tomography_noise(t, mm), 1.0, sl, z);
        double cone = s_->altitude > 0 ? 1.0 - alt / s_->altitude : 1.0;
        for (int k = 0; k < s_->nsub; k++) {
            double q = sl[k] * z[k] + sl[s_->nsub + k] * z[s_->nsub + k];
            if (q == 0.0) continue;
            int pi = 0, pj = 0;
            if (nprobe > 1) {
                double x, y;
                wt_shack_hartmann_centre(s_->sh, k, &x, &y);
                double gx = (cone * x + s_->theta_x * alt - g->x0) / g->dx;
                double gy = (cone * y + s_->theta_y * alt - g->y0) / g->dx;
                double period = (double)step * se;
                pi = (int)lround((gx - cx0 - (double)step * a0) / period);
                pj = (int)lround((gy - cy0 - (double)step * b0) / period);
                pi = ((pi % nprobe) + nprobe) % nprobe;
                pj = ((pj % nprobe) + nprobe) % nprobe;
            }
            int64_t lam = bx + a0 + (int64_t)se * pi + (int64_t)n * (by + b0 + (int64_t)se * pj);
            diag[off + lam] += q;
            if (parts) parts[(size_t)mm * nall + off + lam] += q; /* (the parts: each LGS alone) */
        }
    }
}

/* J⁻¹ = 1 / (diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D), the diagonal by probe_block over every layer, level,
 * orientation and colour (a forward apply each). */
int wt_precond__jacobi(wt_precond *p, const wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const double *alpha_d = wt_tomography_alpha_prior(t);
    double *diag = NULL, *buf = NULL;
    int s;
    int64_t maxn2, maxsl, wsize;
    wt_precond__probe_sizes(t, &s, &maxn2, &maxsl, &wsize);
    int64_t phn = ncg;
    for (int l = 0; l < L; l++)
        if (2 * wt_tomography_layer_grid(t, l)->nx > phn) phn = 2 * wt_tomography_layer_grid(t, l)->nx;
    int64_t per = 2 * maxn2 + wsize + phn + 2 * maxsl;
    int nth = p->nthreads;
    WT_ALLOC(ctx, diag, p->n, "Jacobi diagonal");
    WT_ALLOC(ctx, buf, (size_t)nth * per, "Jacobi probing workspace");
    if (p->parts) WT_ALLOC(ctx, p->pj, (size_t)sys->nlgs * p->n, "Jacobi diagonal's parts");

    for (int l = 0; l < L; l++) {
        int J = wt_wavelet_levels(wt_tomography_wavelet(t, l)), n = wt_tomography_layer_grid(t, l)->nx;
        for (int level = 1; level <= J + 1; level++) {
            int o0 = level <= J ? 1 : 0, o1 = level <= J ? 3 : 0;
            for (int orient = o0; orient <= o1; orient++) {
                int lev = level > J ? J : level, m = n >> lev, se = s < m ? s : m;
#pragma omp parallel for collapse(2) schedule(dynamic, 1) num_threads(nth)
                for (int b0 = 0; b0 < se; b0++)
                    for (int a0 = 0; a0 < se; a0++) {
                        double *base = buf + (size_t)wt_thread_id() * per;
                        double *coef = base, *field = coef + maxn2, *work = field + maxn2;
                        double *ph = work + wsize, *sl = ph + phn, *z = sl + maxsl;
                        probe_block(t, l, level, orient, s, diag, coef, field, work, ph, sl, z, a0, b0, p->pj, p->n);
                    }
            }
        }
    }
    WT_ALLOC(ctx, p->jinv, p->n, "inverse Jacobi diagonal");
    for (int64_t i = 0; i < p->n; i++) p->jinv[i] = 1.0 / (diag[i] + alpha_d[i]);
fail:
    wt_free(ctx, diag);
    wt_free(ctx, buf);
    return st;
}
