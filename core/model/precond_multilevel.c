/* core/model/precond_multilevel.c: the multilevel kind's layer blocks below the coarse block (precond.h):
 *
 *   B_ml = the coarse block, and below it, per detail level, orientation and position, the exact L x L block of
 *          M̃ = Σ_LGS Ãᵀ C̃⁻¹ Ã + α D on the layers' coefficients there (a block Jacobi over a partition: SPD),
 *
 * their entries by J's coloured probing (precond_jacobi.c), each block Cholesky-factored. */
#include "precond_multilevel.h"

#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../op/noise.h"
#include "../op/projection.h"
#include "../op/shack_hartmann.h"
#include "../op/wavelet.h"

/* ---- layer blocks below the coarse block (multilevel) -------------------------------------------
 *
 * What is left after the coarse block is the coupling of the layers at the finer scales. Every LGS sees the
 * sum of the layers along its line of sight, shifted by θ_m h_l (≤ 5.2 m at 18 km for the E-ELT's 60"
 * asterism, ≤ 0.33 m below 1.2 km) and scaled by the cone 1 − h_l/H: a wavelet of layer l and the one at
 * the same place and scale on layer l' land on nearly the same subapertures of every LGS whenever the shift
 * is small against the wavelet's size — the 5 ground layers at every level, all layers at the coarser ones.
 * Jacobi sees each alone, so the iterations must separate them; the prior alone tells them apart.
 * multilevel groups the unknowns by their place in the Mallat layout: block b holds, for one detail
 * position (x, y) (one level, orientation and translate), the coefficient at (x, y) of every layer whose
 * grid has it outside the coarse square, and B_ml holds the exact q x q block of
 *   M̃ = Σ_LGS Ãᵀ C̃⁻¹ Ã + α D            (C̃: the LGS noise without the tip-tilt removal, as J's)
 * on those unknowns (q ≤ L), the coarse block on the coarse square, and nothing between blocks: a block
 * Jacobi over a partition of the unknowns, whose blocks are principal submatrices of the SPD M̃, so B_ml is
 * SPD. Its diagonal is J's. A layer of another size pairs by its Mallat position, which is the same
 * physical place and scale when the layers span the same period (pcg3's 128 x 0.5 m and 64 x 1 m). The
 * entries come by J's coloured probing (probe_block), one forward apply per layer and colour: the images
 * of one layer's probes are disjoint, each subaperture's 2x2 form S_lᵀ C̃⁻¹ S_l' belongs to entry (l, l')
 * of the block whose probe is nearest to it on both layers, and to no block when the two nearest
 * probes differ (that entry lies between blocks). Each block is Cholesky-factored; apply: per block a
 * gather, two triangular solves of order q (2 q² flops) and a scatter, 2 L flops per unknown. */

/* Mallat position (x, y) of an n x n layer with coarse square side sc: the detail block side m (a power of
 * two), or 0 inside the coarse square */
static int detail_side(int x, int y, int sc)
{
    int v = x > y ? x : y;
    if (v < sc) return 0;
    int m = 1;
    while (2 * m <= v) m *= 2;
    return m;
}

/* Accumulates into the blocks (acc: q x q each, column-major, at a_off[b]) the entries of every block of
 * Mallat detail side m, orientation orient and colour (a0, b0) (stride se): the layers in lay[0..nl-1]
 * (those with this block outside their coarse square), their probe fields' support centres cx/cy. Buffers:
 * coef (maxn2), work (wavelet), fields (nl x maxn2), ph (ncg), sl/z (nl x maxsl each), key (nl). */
static void probe_layer_blocks(const wt_tomography *t, int m, int orient, int se, int a0, int b0, int nl,
                               const int *lay, const double *cx, const double *cy, const int *slot,
                               const int64_t *gid, int nmax, const int64_t *a_off, const int *gq, double *acc,
                               double *coef, double *work, double *fields, int64_t maxn2, double *ph, double *sl,
                               double *z, int64_t maxsl, int *key)
{
    const wt_system *sys = wt_tomography_system(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;
    const int nprobe = m / se;
    for (int a = 0; a < nl; a++) {
        const int l = lay[a], n = wt_tomography_layer_grid(t, l)->nx;
        memset(coef, 0, (size_t)n * n * sizeof *coef);
        for (int j = b0; j < m; j += se)
            for (int i = a0; i < m; i += se) coef[bx + i + (int64_t)n * (by + j)] = 1.0;
        wt_wavelet_inverse(wt_tomography_wavelet(t, l), coef, fields + a * maxn2, work);
    }
    for (int mm = 0; mm < sys->nlgs; mm++) {
        const wt_sensor *s_ = &sys->sensors[mm];
        for (int a = 0; a < nl; a++) {
            const int l = lay[a];
            memset(ph, 0, (size_t)ncg * sizeof *ph);
            wt_projection_apply(wt_tomography_projection(t, mm, l), 1.0, fields + a * maxn2, ph);
            double *sa = sl + a * maxsl, *za = z + a * maxsl;
            memset(sa, 0, (size_t)s_->nslopes * sizeof *sa);
            wt_shack_hartmann_apply(s_->sh, 1.0, ph, sa);
            memset(za, 0, (size_t)s_->nslopes * sizeof *za);
            wt_noise_apply_inv(wt_tomography_noise(t, mm), 1.0, sa, za);
        }
        for (int k = 0; k < s_->nsub; k++) {
            double x = 0.0, y = 0.0;
            int any = 0;
            for (int a = 0; a < nl; a++) {
                const double *sa = sl + a * maxsl;
                key[a] = -1;
                if (sa[k] == 0.0 && sa[s_->nsub + k] == 0.0) continue;
                if (!any) wt_shack_hartmann_centre(s_->sh, k, &x, &y);
                any = 1;
                int pi = 0, pj = 0;
                if (nprobe > 1) { /* the nearest probe on layer l, as probe_block attributes it */
                    const int l = lay[a];
                    const wt_grid *g = wt_tomography_layer_grid(t, l);
                    const double alt = wt_tomography_layer_altitude(t, l);
                    const double cone = s_->altitude > 0 ? 1.0 - alt / s_->altitude : 1.0;
                    const int n = g->nx, step = n / m;
                    const double gx = (cone * x + s_->theta_x * alt - g->x0) / g->dx;
                    const double gy = (cone * y + s_->theta_y * alt - g->y0) / g->dx;
                    const double period = (double)step * se;
                    pi = (int)lround((gx - cx[a] - (double)step * a0) / period);
                    pj = (int)lround((gy - cy[a] - (double)step * b0) / period);
                    pi = ((pi % nprobe) + nprobe) % nprobe;
                    pj = ((pj % nprobe) + nprobe) % nprobe;
                }
                key[a] = pi + nprobe * pj;
            }
            if (!any) continue;
            for (int a = 0; a < nl; a++) {
                if (key[a] < 0) continue;
                const int pi = key[a] % nprobe, pj = key[a] / nprobe;
                const int64_t b = gid[bx + a0 + (int64_t)se * pi + (int64_t)nmax * (by + b0 + (int64_t)se * pj)];
                const int q = gq[b];
                double *A = acc + a_off[b];
                const double *sa = sl + a * maxsl;
                for (int c = a; c < nl; c++) {
                    if (key[c] != key[a]) continue;
                    const double *zc = z + c * maxsl;
                    A[slot[a] + (int64_t)q * slot[c]] += sa[k] * zc[k] + sa[s_->nsub + k] * zc[s_->nsub + k];
                }
            }
        }
    }
}

/* The blocks of B_ml below the coarse square (sc[l]: each layer's coarse square side) */
int wt_precond__layer_blocks(wt_precond *p, const wt_tomography *t, const int *sc)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
    const double *alpha_d = wt_tomography_alpha_prior(t);
    int64_t *gid = NULL, *a_off = NULL;
    int *gq = NULL;
    double *acc = NULL, *buf = NULL;
    int nmax = 0;
    for (int l = 0; l < L; l++)
        if (wt_tomography_layer_grid(t, l)->nx > nmax) nmax = wt_tomography_layer_grid(t, l)->nx;
    /* the partition: one block per Mallat detail position of the largest grid that some layer has outside
     * its coarse square */
    WT_ALLOC(ctx, gid, (size_t)nmax * nmax, "multilevel block map");
    int64_t nb = 0, nidx = 0, nfac = 0, nacc = 0;
    for (int64_t xy = 0; xy < (int64_t)nmax * nmax; xy++) {
        const int x = (int)(xy % nmax), y = (int)(xy / nmax);
        int q = 0;
        for (int l = 0; l < L; l++) {
            const int n = wt_tomography_layer_grid(t, l)->nx;
            if (x < n && y < n && detail_side(x, y, sc[l])) q++;
        }
        gid[xy] = q ? nb++ : -1;
        nidx += q;
        nfac += q * (q + 1) / 2;
        nacc += (int64_t)q * q;
    }
    p->nb = nb;
    WT_ALLOC(ctx, p->b_start, nb + 1, "multilevel block starts");
    WT_ALLOC(ctx, p->b_fac, nb + 1, "multilevel factor starts");
    WT_ALLOC(ctx, p->b_idx, nidx > 0 ? nidx : 1, "multilevel block indices");
    WT_ALLOC(ctx, p->b_L, nfac > 0 ? nfac : 1, "multilevel block factors");
    WT_ALLOC(ctx, gq, nb > 0 ? nb : 1, "multilevel block sizes");
    WT_ALLOC(ctx, a_off, nb + 1, "multilevel block offsets");
    WT_ALLOC(ctx, acc, nacc > 0 ? nacc : 1, "multilevel blocks");
    {
        int64_t b = 0, i = 0, f = 0, o = 0;
        for (int64_t xy = 0; xy < (int64_t)nmax * nmax; xy++) {
            if (gid[xy] < 0) continue;
            const int x = (int)(xy % nmax), y = (int)(xy / nmax);
            p->b_start[b] = i;
            p->b_fac[b] = f;
            a_off[b] = o;
            int q = 0;
            for (int l = 0; l < L; l++) {
                const int n = wt_tomography_layer_grid(t, l)->nx;
                if (x < n && y < n && detail_side(x, y, sc[l]))
                    p->b_idx[i + q++] = wt_tomography_layer_offset(t, l) + x + (int64_t)n * y;
            }
            gq[b] = q;
            i += q;
            f += q * (q + 1) / 2;
            o += (int64_t)q * q;
            b++;
        }
        p->b_start[nb] = i;
        p->b_fac[nb] = f;
        a_off[nb] = o;
    }

    /* the probing, block side by block side (the layers' levels pair by side) */
    int s;
    int64_t maxn2, maxsl, wsize;
    wt_precond__probe_sizes(t, &s, &maxn2, &maxsl, &wsize);
    int64_t phn = ncg > 2 * nmax ? ncg : 2 * nmax;
    const int nth = p->nthreads;
    const int64_t per = maxn2 + wsize + (int64_t)L * maxn2 + phn + 2 * (int64_t)L * maxsl + L;
    WT_ALLOC(ctx, buf, (size_t)nth * per, "multilevel probing workspace");
    for (int m = nmax / 2; m >= 1; m /= 2)
        for (int orient = 1; orient <= 3; orient++) {
            int lay[WT_MAX_LAYERS], slot[WT_MAX_LAYERS], nl = 0;
            double cx[WT_MAX_LAYERS], cy[WT_MAX_LAYERS];
            for (int l = 0; l < L; l++) {
                const int n = wt_tomography_layer_grid(t, l)->nx;
                if (2 * m > n || m < sc[l]) continue; /* not in this grid, or in its coarse square */
                slot[nl] = nl;
                lay[nl] = l;
                /* the support centre of the block's k = 0 basis function, as probe_block finds it */
                double *coef = buf, *field = buf + maxn2, *work = buf + 2 * maxn2, *mag = work + wsize;
                const int bx = (orient == 1 || orient == 3) ? m : 0, by = (orient == 2 || orient == 3) ? m : 0;
                memset(coef, 0, (size_t)n * n * sizeof *coef);
                coef[bx + (int64_t)n * by] = 1.0;
                wt_wavelet_inverse(wt_tomography_wavelet(t, l), coef, field, work);
                memset(mag, 0, 2 * (size_t)n * sizeof *mag);
                for (int iy = 0; iy < n; iy++)
                    for (int ix = 0; ix < n; ix++) {
                        double v = fabs(field[ix + (int64_t)n * iy]);
                        mag[ix] += v;
                        mag[n + iy] += v;
                    }
                cx[nl] = wt_precond__support_centre(mag, n);
                cy[nl] = wt_precond__support_centre(mag + n, n);
                nl++;
            }
            if (nl == 0) continue;
            /* a layer's slot in its blocks: the layers in a block are those of lay[] (the same set for every
             * position of this side and orientation), in increasing order */
            const int se = s < m ? s : m;
#pragma omp parallel for collapse(2) schedule(dynamic, 1) num_threads(nth)
            for (int b0 = 0; b0 < se; b0++)
                for (int a0 = 0; a0 < se; a0++) {
                    double *base = buf + (size_t)wt_thread_id() * per;
                    double *coef = base, *work = coef + maxn2, *fields = work + wsize, *ph = fields + L * maxn2;
                    double *sl = ph + phn, *z = sl + L * maxsl;
                    int key[WT_MAX_LAYERS];
                    probe_layer_blocks(t, m, orient, se, a0, b0, nl, lay, cx, cy, slot, gid, nmax, a_off, gq, acc,
                                       coef, work, fields, maxn2, ph, sl, z, maxsl, key);
                }
        }
    /* the prior on the diagonal, the lower triangle from the upper, and the factors */
    for (int64_t b = 0; b < nb; b++) {
        const int q = gq[b];
        double *A = acc + a_off[b];
        for (int a = 0; a < q; a++) {
            A[a + (int64_t)q * a] += alpha_d[p->b_idx[p->b_start[b] + a]];
            for (int c = a + 1; c < q; c++) A[c + (int64_t)q * a] = A[a + (int64_t)q * c];
        }
        WT_TRY(wt_precond__cholesky(ctx, q, A, "multilevel layer block"));
        /* packed by rows of L: row a holds L[a][0..a], the last entry stored as 1/L[a][a] */
        double *F = p->b_L + p->b_fac[b];
        for (int a = 0, f = 0; a < q; a++) {
            for (int c = 0; c < a; c++) F[f++] = A[a + (int64_t)q * c];
            F[f++] = 1.0 / A[a + (int64_t)q * a];
        }
    }
fail:
    wt_free(ctx, gid);
    wt_free(ctx, a_off);
    wt_free(ctx, gq);
    wt_free(ctx, acc);
    wt_free(ctx, buf);
    return st;
}

/* z[b's unknowns] = B_b⁻¹ r[b's unknowns] for the blocks [b0, b1) */
WT_CPU_CLONES void wt_precond__layer_blocks_apply(const wt_precond *p, const double *r, double *z, int64_t b0, int64_t b1)
{
    for (int64_t b = b0; b < b1; b++) {
        const int64_t *idx = p->b_idx + p->b_start[b];
        const int q = (int)(p->b_start[b + 1] - p->b_start[b]);
        const double *F = p->b_L + p->b_fac[b];
        double w[WT_MAX_LAYERS];
        for (int a = 0, f = 0; a < q; a++) { /* forward: L y = r */
            double v = r[idx[a]];
            for (int c = 0; c < a; c++) v -= F[f++] * w[c];
            w[a] = v * F[f++];
        }
        for (int a = q - 1; a >= 0; a--) { /* backward: Lᵀ x = y, row a of L is column a of Lᵀ */
            const double *row = F + (int64_t)a * (a + 1) / 2;
            const double v = (w[a] *= row[a]);
            for (int c = 0; c < a; c++) w[c] -= row[c] * v;
        }
        for (int a = 0; a < q; a++) z[idx[a]] = w[a];
    }
}

