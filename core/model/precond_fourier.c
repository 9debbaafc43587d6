/* core/model/precond_fourier.c: the fourier kind (precond.h):
 *
 *   B_F⁻¹ = W F⁻¹ diag(1/λ_max A(k)) F Wᵀ on the complement of the coarse space, A(k) the L x L symbol of the LGS +
 *           prior part of M̃ per frequency (measured from one impulse per layer), and the exact block Qᵀ M̃ Q on the
 *           coarse space V_c (each layer's coarsest scaling functions);
 *   with the NGS term, Yᵀ r = Rᵀ u on the filtered layers (the NGS's adjoint columns held sparse per layer).
 */
#include "precond_fourier.h"

#include <lapacke.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "../la/fft.h"
#include "../la/vec.h"

/* ---- Fourier-domain filter (fourier) -------------------------------------------------------------
 *
 * In the closed loop the few iterations of a frame chase a moving MAP (docs/results.md §25): what lags is
 * the layers' common mode at each spatial frequency, which every LGS sees and whose weight falls by orders
 * of magnitude from the fine to the coarse scales. On layers of one periodic n x n grid the LGS + prior
 * part M̃ (as coarse_ngs's block) is, away from the pupil's rim, close to a block convolution: each LGS sees
 * layer l shifted by θ_m h_l (and scaled by the cone about the centre), every layer's prior is circulant.
 * Its symbol A(k), an L x L Hermitian matrix per frequency, is measured from the operator itself: an
 * impulse at the grid's centre on each layer in turn, M̃ applied, the responses on every layer Fourier
 * transformed (L applies at set-up), symmetrised, A ← (A + Aᴴ)/2. The preconditioner scales each frequency
 * by the inverse of A(k)'s largest eigenvalue, the common mode's, the same on every layer:
 *   B_F⁻¹ = F⁻¹ diag(1/λ_max(A(k))) F        (F the 2-D DFT of each layer)
 * SPD: F⁻¹ diag(s) F with s(k) = s(−k) > 0 is a real symmetric circulant. Inverting A(k) exactly (FDPCG,
 * Yang, Vogel & Ellerbroek 2006) was measured worse in the loop: at the low frequencies the L − 6 layer-split
 * directions hold the prior alone, ~10⁶ below the data, and the rim's leakage into them is amplified as
 * much; flooring A's eigenvalues at τ λ_max got better as τ rose, best at τ = 1, this filter (§25). The
 * filter misses the pupil and the LGS tip-tilt removal, which shape the largest scales, where the NGS fix
 * the layers' tip-tilt: the coarse space V_c (each layer's scaling functions of the DWT's coarsest level,
 * coarse_levels = 0, or of coarse_levels levels finer) takes M̃'s exact block there instead:
 *   B⁻¹ = Q (Qᵀ M̃ Q)⁻¹ Qᵀ + Π_d F⁻¹ diag(s) F Π_d,    Π_d = I − Q Qᵀ,
 * Q an orthonormal basis of V_c (SPD: an SPD block on V_c beside a compression of an SPD operator on its
 * complement). 6 iterations went from 13 nm above the converged MAP to 1.5 below with it (§25).
 *
 * The kind works on the layers' values (the tomography's unknowns in space, wt_tomography_space): the
 * same steps as on the wavelet coefficients, W orthogonal, without the DWT pair per layer of each apply
 * of M and of B⁻¹. V_c is V_J' ⊗ V_J' on every layer (J' = J − coarse_levels), spanned by the products
 * φ_i(x) φ_j(y) of the sc = n / 2^J' periodic 1-D scaling functions of level J', which the wavelet's own
 * inverse transform gives (coarse_basis): Qᵀ x and Q c are two 1-D contractions, 2 sc n² flops each
 * (sc = 4 at E-ELT size). The NGS term is added by Woodbury as for the other kinds. Apply, whole layers
 * per thread (the same bits on any thread count): Qᵀ r, the filter on r − Q Qᵀ r (a real FFT pair), Qᵀ of
 * the result; then the coarse block's solve (144² at E-ELT size) and per layer the coarse correction. */

static int fourier_grid(wt_context *ctx, const wt_tomography *t)
{
    const wt_grid *g0 = wt_tomography_layer_grid(t, 0);
    for (int l = 0; l < wt_tomography_nlayers(t); l++) {
        const wt_grid *g = wt_tomography_layer_grid(t, l);
        if (g->nx != g0->nx || g->ny != g0->ny || g->dx != g0->dx || g->nx != g->ny)
            return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: the fourier preconditioner needs every layer on one "
                            "n x n grid of one spacing (recon.<variant>.layer_size, layer_spacing_m); layer %d is "
                            "%d x %d at %g m, layer 0 %d x %d at %g m", l, g->nx, g->ny, g->dx, g0->nx, g0->ny, g0->dx);
        if (wt_wavelet_levels(wt_tomography_wavelet(t, l)) != wt_wavelet_levels(wt_tomography_wavelet(t, 0)) ||
            wt_wavelet_order(wt_tomography_wavelet(t, l)) != wt_wavelet_order(wt_tomography_wavelet(t, 0)))
            return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: the fourier preconditioner needs one wavelet on every "
                            "layer; layer %d differs from layer 0", l);
    }
    return WT_OK;
}

static double *fourier_phi(const wt_precond *p, int id) { return p->fd_buf + (size_t)id * p->fd_slice; }
static fftw_complex *fourier_hat(const wt_precond *p, int id)
{
    return (fftw_complex *)(p->fd_buf + (size_t)id * p->fd_slice + (size_t)p->fd_n * p->fd_n);
}

/* C = Qᵀ X on one layer (C[i + sc j] = Σ_y φ_j(y) Σ_x φ_i(x) X[x + n y]): U_j = Σ_y φ_j(y) X[·, y] by rows
 * (vectorised along x, no reassociation), then the sc² short dots. u: sc n of work. */
WT_CPU_CLONES void wt_precond__coarse_coef(const wt_precond *p, const double *X, double *C, double *u)
{
    const int n = p->fd_n, sc = p->fd_sc;
    const double *B = p->fd_B; /* sc x n: row i = φ_i */
    memset(u, 0, (size_t)sc * n * sizeof *u);
    for (int y = 0; y < n; y++)
        for (int j = 0; j < sc; j++) {
            const double b = B[(size_t)j * n + y];
            double *uj = u + (size_t)j * n;
            const double *xy = X + (size_t)n * y;
            for (int x = 0; x < n; x++) uj[x] += b * xy[x];
        }
    for (int j = 0; j < sc; j++)
        for (int i = 0; i < sc; i++) {
            double s = 0.0;
            for (int x = 0; x < n; x++) s += B[(size_t)i * n + x] * u[(size_t)j * n + x];
            C[i + sc * j] = s;
        }
}

/* X = S + Q C on one layer (X[x + n y] = S[x + n y] + Σ_i φ_i(x) g_i(y), g_i(y) = Σ_j C[i + sc j] φ_j(y)); S may be X
 * (X += Q C), the same operations in the same order either way */
WT_CPU_CLONES static void coarse_add_to(const wt_precond *p, const double *C, const double *S, double *X)
{
    const int n = p->fd_n, sc = p->fd_sc;
    const double *B = p->fd_B;
    double g[WT_FOURIER_MAX_SC];
    for (int y = 0; y < n; y++) {
        for (int i = 0; i < sc; i++) {
            double s = 0.0;
            for (int j = 0; j < sc; j++) s += C[i + sc * j] * B[(size_t)j * n + y];
            g[i] = s;
        }
        double *xy = X + (size_t)n * y;
        const double *sy = S + (size_t)n * y;
        for (int i = 0; i < sc; i++) {
            const double gi = g[i], *bi = B + (size_t)i * n, *src = i ? xy : sy;
            for (int x = 0; x < n; x++) xy[x] = src[x] + bi[x] * gi;
        }
    }
}

static void coarse_add(const wt_precond *p, const double *C, double *X) { coarse_add_to(p, C, X, X); }

/* The sc periodic 1-D scaling functions of level J' = J − coarse_levels on n points (fd_B, sc x n): the
 * wavelet's inverse transform of J' levels maps the unit coefficient (i, 0) of its approximation block to
 * φ_i(x) φ_0(y), whose sum over y is φ_i(x) (√2)^J' (each synthesis level multiplies a sum by Σh = √2).
 * Checked: orthonormal and the 2-D functions their products, to 1e-12 (else WT_ERR_NUMERIC). */
static int coarse_basis(wt_precond *p, const wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_wavelet *w0 = wt_tomography_wavelet(t, 0);
    const int n = p->fd_n, J = wt_wavelet_levels(w0), k = coarse_levels < J ? coarse_levels : J, Jc = J - k;
    const int sc = n >> Jc;
    wt_wavelet *wc = NULL;
    double *e = NULL, *f = NULL, *ww = NULL;
    if (sc > WT_FOURIER_MAX_SC)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: fourier with coarse_levels %d gives a coarse square of side %d "
                        "per layer; at most %d (lower coarse_levels)", coarse_levels, sc, WT_FOURIER_MAX_SC);
    p->fd_sc = sc;
    WT_ALLOC(ctx, p->fd_B, (size_t)sc * n, "fourier coarse basis");
    if (Jc == 0) { /* the whole layer: unit vectors */
        for (int i = 0; i < sc; i++) p->fd_B[(size_t)i * n + i] = 1.0;
        return WT_OK;
    }
    WT_TRY(wt_wavelet_alloc(ctx, n, wt_wavelet_order(w0), Jc, &wc));
    WT_ALLOC(ctx, e, (size_t)n * n, "fourier coarse probe");
    WT_ALLOC(ctx, f, (size_t)n * n, "fourier coarse function");
    WT_ALLOC(ctx, ww, wt_wavelet_work_size(wc), "fourier coarse work");
    const double norm = pow(sqrt(2.0), Jc);
    for (int i = 0; i < sc; i++) {
        e[i] = 1.0;
        wt_wavelet_inverse(wc, e, f, ww);
        e[i] = 0.0;
        for (int x = 0; x < n; x++) {
            double s = 0.0;
            for (int y = 0; y < n; y++) s += f[x + (size_t)n * y];
            p->fd_B[(size_t)i * n + x] = s / norm;
        }
    }
    double worst = 0.0;
    for (int i = 0; i < sc; i++)
        for (int j = 0; j < sc; j++) {
            double s = 0.0;
            for (int x = 0; x < n; x++) s += p->fd_B[(size_t)i * n + x] * p->fd_B[(size_t)j * n + x];
            worst = fmax(worst, fabs(s - (i == j)));
        }
    for (int i = 0; i < sc; i += sc > 1 ? sc - 1 : 1) { /* the first and the last 2-D function of each row */
        for (int j = 0; j < sc; j += sc > 1 ? sc - 1 : 1) {
            e[i + (size_t)n * j] = 1.0;
            wt_wavelet_inverse(wc, e, f, ww);
            e[i + (size_t)n * j] = 0.0;
            for (int y = 0; y < n; y++)
                for (int x = 0; x < n; x++)
                    worst = fmax(worst, fabs(f[x + (size_t)n * y] - p->fd_B[(size_t)i * n + x] * p->fd_B[(size_t)j * n + y]));
        }
    }
    if (!(worst <= 1e-12))
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "fourier preconditioner: the coarse space's 1-D basis (level %d of %d on %d "
                      "points) is off by %g (orthonormal products expected within 1e-12)", Jc, J, n, worst);
fail:
    wt_wavelet_free(wc);
    wt_free(ctx, e);
    wt_free(ctx, f);
    wt_free(ctx, ww);
    return st;
}

/* Qᵀ M̃ Q on V_c, Cholesky-factored in c_L (Lᵀ above the diagonal, as coarse_solve reads it): M̃ applied to
 * each product φ_i ⊗ φ_j on each layer (lgs_prior_column, nc applies at set-up), Qᵀ of the response */
static int fourier_coarse_block(wt_precond *p, wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t), n = p->fd_n, sc = p->fd_sc, sc2 = sc * sc, q = L * sc2;
    const int64_t m2 = (int64_t)n * n;
    double *e = NULL, *sl = NULL, *col = NULL, *u = NULL, *cols = NULL;
    if (q > WT_PRECOND_COARSE_MAX)
        return WT_ERROR(ctx, WT_ERR_CONFIG, "tomography: fourier's coarse block has %d coefficients; at most %d "
                        "(lower coarse_levels)", q, WT_PRECOND_COARSE_MAX);
    WT_ALLOC(ctx, p->c_L, (size_t)q * q, "coarse block");
    WT_ALLOC(ctx, p->c_w, q, "coarse work");
    WT_ALLOC(ctx, e, p->n, "coarse probe");
    WT_ALLOC(ctx, sl, sys->nslopes, "coarse probe slopes");
    WT_ALLOC(ctx, col, p->n, "coarse column");
    WT_ALLOC(ctx, u, (size_t)sc * n, "coarse contraction");
    if (p->parts) {
        WT_ALLOC(ctx, p->pc, (size_t)(p->nlgs + 1) * q * q, "coarse block's parts");
        WT_ALLOC(ctx, cols, (size_t)(p->nlgs + 1) * p->n, "coarse parts' columns");
    }
    for (int lj = 0; lj < L; lj++) {
        const int64_t o = wt_tomography_layer_offset(t, lj);
        for (int j = 0; j < sc2; j++) {
            const double *bx = p->fd_B + (size_t)(j % sc) * n, *by = p->fd_B + (size_t)(j / sc) * n;
            for (int y = 0; y < n; y++)
                for (int x = 0; x < n; x++) e[o + x + (int64_t)n * y] = bx[x] * by[y];
            wt_precond__lgs_prior_column(t, lj, e, sl, col);
            for (int l = 0; l < L; l++)
                wt_precond__coarse_coef(p, col + wt_tomography_layer_offset(t, l), p->c_L + (size_t)q * (lj * sc2 + j) + l * sc2, u);
            if (p->parts) {
                wt_precond__part_columns(p, t, lj, e, cols);
                for (int m = 0; m <= p->nlgs; m++)
                    for (int l = 0; l < L; l++)
                        wt_precond__coarse_coef(p, cols + (size_t)m * p->n + wt_tomography_layer_offset(t, l),
                                                p->pc + (size_t)m * q * q + (size_t)q * (lj * sc2 + j) + l * sc2, u);
            }
        }
        memset(e + o, 0, (size_t)m2 * sizeof *e);
    }
    WT_TRY(wt_precond__coarse_factor(p, q, "fourier coarse block"));
    WT_ALLOC(ctx, p->fd_cr, q, "fourier coarse coefficients");
    WT_ALLOC(ctx, p->fd_cphi, q, "fourier coarse coefficients of the filtered layers");
fail:
    wt_free(ctx, e);
    wt_free(ctx, sl);
    wt_free(ctx, col);
    wt_free(ctx, u);
    wt_free(ctx, cols);
    return st;
}

int wt_precond__fourier(wt_precond *p, wt_tomography *t, int coarse_levels)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    double *e = NULL, *sl = NULL, *col = NULL, *cols = NULL;
    double complex *A = NULL;
    if (!wt_tomography_space(t))
        return WT_ERROR(ctx, WT_ERR_INVALID, "fourier preconditioner: the tomography's unknowns must be the layers' "
                        "values (wt_tomography_params.space = 1), not wavelet coefficients");
    WT_TRY(fourier_grid(ctx, t));
    const int n = wt_tomography_layer_grid(t, 0)->nx, nh = n / 2 + 1;
    const int64_t n2 = (int64_t)n * n, nk = (int64_t)n * nh;
    p->fd_n = n;
    p->fd_nk = nk;
    /* n² and 2 nk are multiples of 8 doubles for n ≥ 8: every thread's slices keep the first one's alignment,
     * which the plans were made for; then sc n of contraction work */
    p->fd_slice = (size_t)(n2 + 2 * nk + (int64_t)WT_FOURIER_MAX_SC * n);
    /* at a 64-byte boundary: the plans are made on it, and the learnt wisdom on arrays as aligned (core/la/fft.c) */
    WT_ALLOC(ctx, p->fd_raw, (size_t)p->nthreads * p->fd_slice + 8, "fourier preconditioner work");
    p->fd_buf = wt_align64(p->fd_raw);
    WT_ALLOC(ctx, p->fd_s, nk, "fourier preconditioner filter");
    WT_ALLOC(ctx, A, (size_t)nk * L * L, "fourier preconditioner symbol");
    WT_ALLOC(ctx, e, p->n, "fourier probe");
    WT_ALLOC(ctx, sl, sys->nslopes, "fourier probe slopes");
    WT_ALLOC(ctx, col, p->n, "fourier probe column");
    const int T = L * (L + 1) / 2;
    if (p->parts) {
        WT_ALLOC(ctx, p->pa, (size_t)p->nlgs * nk * T, "fourier symbol's parts");
        WT_ALLOC(ctx, p->pp, (size_t)nk * L, "fourier prior symbol");
        WT_ALLOC(ctx, cols, (size_t)(p->nlgs + 1) * p->n, "fourier parts' columns");
    }
    double *phi = fourier_phi(p, 0);
    fftw_complex *hat = fourier_hat(p, 0);
    /* FFTW's planner is global and not thread-safe: planned here, at set-up, as the tomography's prior (core/la/
     * fft.h: FFTW_ESTIMATE or its wisdom's measured plans; no array touched, the same algorithm every run) */
    WT_TRY(wt_fft_plan_pair(ctx, wt_tomography_fft(t), n, phi, hat, "fourier preconditioner", &p->fd_r2c,
                            &p->fd_c2r));
    const int64_t centre = n / 2 + (int64_t)n * (n / 2);
    for (int lp = 0; lp < L; lp++) {
        const int64_t o = wt_tomography_layer_offset(t, lp);
        e[o + centre] = 1.0;
        wt_precond__lgs_prior_column(t, lp, e, sl, col); /* M̃'s column, as coarse_ngs's block */
        e[o + centre] = 0.0;
        for (int l = 0; l < L; l++) {
            memcpy(phi, col + wt_tomography_layer_offset(t, l), (size_t)n2 * sizeof *phi);
            fftw_execute_dft_r2c(p->fd_r2c, phi, hat);
            /* the response of the impulse at (n/2, n/2): symbol = spectrum · e^{2πi k·(n/2, n/2)/n} = (−1)^(kx+ky) */
            for (int ky = 0; ky < n; ky++)
                for (int kx = 0; kx < nh; kx++) {
                    const int64_t k = kx + (int64_t)nh * ky;
                    A[(size_t)k * L * L + l + (size_t)L * lp] = (((kx + ky) & 1) ? -1.0 : 1.0) * hat[k];
                }
        }
        if (!p->parts) continue;
        /* the parts: each LGS's column on every layer, symmetrised as A is below (entry (l, l') the mean of the
         * (l, l') and the conjugate (l', l) responses: the operator is not exactly shift-invariant) into the lower
         * triangle; the prior's on layer lp alone */
        e[o + centre] = 1.0;
        wt_precond__part_columns(p, t, lp, e, cols);
        e[o + centre] = 0.0;
        for (int m = 0; m <= p->nlgs; m++)
            for (int l = m < p->nlgs ? 0 : lp; l < (m < p->nlgs ? L : lp + 1); l++) {
                memcpy(phi, cols + (size_t)m * p->n + wt_tomography_layer_offset(t, l), (size_t)n2 * sizeof *phi);
                fftw_execute_dft_r2c(p->fd_r2c, phi, hat);
                const int i = l > lp ? l : lp, j = l > lp ? lp : l, tri = j * (2 * L - j + 1) / 2 + (i - j);
                for (int ky = 0; ky < n; ky++)
                    for (int kx = 0; kx < nh; kx++) {
                        const int64_t k = kx + (int64_t)nh * ky;
                        const double complex v = (((kx + ky) & 1) ? -1.0 : 1.0) * hat[k];
                        if (m == p->nlgs) p->pp[(size_t)k * L + lp] = v;
                        else if (l == lp) p->pa[((size_t)m * nk + k) * T + tri] = creal(v);
                        else p->pa[((size_t)m * nk + k) * T + tri] += 0.5 * (l > lp ? v : conj(v));
                    }
            }
    }
    for (int64_t k = 0; k < nk; k++) {
        double complex *a = A + (size_t)k * L * L; /* column-major, (l, l') at l + L l' */
        for (int j = 0; j < L; j++)
            for (int i = j; i < L; i++) a[i + L * j] = 0.5 * (a[i + L * j] + conj(a[j + L * i]));
        double ev[WT_MAX_LAYERS];
        const lapack_int info = LAPACKE_zheev(LAPACK_COL_MAJOR, 'N', 'L', L, (lapack_complex_double *)a, L, ev);
        if (info != 0 || !(ev[L - 1] > 0.0) || !isfinite(ev[L - 1])) {
            st = WT_ERROR(ctx, WT_ERR_NUMERIC, "fourier preconditioner: the largest eigenvalue of the %d x %d symbol "
                          "at frequency (%lld, %lld) is %g (LAPACK zheev info %d); expected positive", L, L,
                          (long long)(k % nh), (long long)(k / nh), info == 0 ? ev[L - 1] : NAN, (int)info);
            goto fail;
        }
        p->fd_s[k] = 1.0 / ((double)n2 * ev[L - 1]); /* the 1/n² of the unnormalised inverse FFT folded in */
    }
    if (coarse_levels >= 0) {
        WT_TRY(coarse_basis(p, t, coarse_levels));
        WT_TRY(fourier_coarse_block(p, t));
    }
fail:
    wt_free(ctx, A);
    wt_free(ctx, e);
    wt_free(ctx, sl);
    wt_free(ctx, col);
    wt_free(ctx, cols);
    return st;
}

/* With the NGS term, P⁻¹ r = u − Y K⁻¹ Yᵀ r with u = B⁻¹ r. Yᵀ r = Rᵀ u (B symmetric), and Rᵀ u needs no pass
 * over Y (n x r, 14 MB at E-ELT size): R's columns, the NGS slopes' adjoints, hold a few hundred values per
 * layer (the sensors' subaperture rims through the bilinear projection: ~70 000 for the E-ELT's 12 slopes),
 * and u_l = φ_l + Q (u_c − c_l) with φ_l the filtered layer and c_l = Qᵀ φ_l:
 *   Rᵀ u = Σ_l R_lᵀ φ_l + R_cᵀ (u_c − c),    R_c = Qᵀ R  (nc x r),
 * the sparse dots inside each layer's task, the coarse term after them. Only the update z −= Y w reads Y. */

static void fourier_ngs_dots(const wt_precond *p, int l, const double *phi)
{
    const int q = p->nlr;
    for (int k = 0; k < q; k++) {
        double d = 0.0;
        for (int64_t e = p->fd_rs_ptr[l * q + k]; e < p->fd_rs_ptr[l * q + k + 1]; e++)
            d += p->fd_rs_val[e] * phi[p->fd_rs_idx[e]];
        p->fd_dots[l * q + k] = d;
    }
}

/* z = B⁻¹ r (ngs = 0) or P⁻¹ r (ngs = 1): whole layers per thread, the coarse solve and the Woodbury weights
 * on one, the coarse corrections by layers and the update by rows (allocates nothing; every value is
 * computed in one fixed order whatever thread runs it: the same bits on any thread count) */
void wt_precond__fourier_apply(const wt_precond *p, const double *r, double *z, int ngs)
{
    const wt_tomography *t = p->tomo;
    const int L = wt_tomography_nlayers(t), q = ngs ? p->nlr : 0, sc2 = p->fd_sc * p->fd_sc;
    const int64_t nk = p->fd_nk, m2 = (int64_t)p->fd_n * p->fd_n;
#pragma omp parallel num_threads(p->nthreads)
    {
#pragma omp for schedule(dynamic, 1)
        for (int l = 0; l < L; l++) {
            const int id = wt_thread_id();
            double *phi = fourier_phi(p, id), *hat = (double *)fourier_hat(p, id);
            double *u = phi + p->fd_slice - (size_t)WT_FOURIER_MAX_SC * p->fd_n; /* the contractions' work */
            const int64_t o = wt_tomography_layer_offset(t, l);
            if (p->nc > 0) { /* the filter on Π_d r: Q's coefficients out, φ = r − Q c in one pass */
                double *c = p->fd_cr + (size_t)l * sc2, mc[WT_FOURIER_MAX_SC * WT_FOURIER_MAX_SC];
                wt_precond__coarse_coef(p, r + o, c, u);
                for (int i = 0; i < sc2; i++) mc[i] = -c[i];
                coarse_add_to(p, mc, r + o, phi);
            } else memcpy(phi, r + o, (size_t)m2 * sizeof *phi);
            fftw_execute_dft_r2c(p->fd_r2c, phi, (fftw_complex *)hat);
            for (int64_t k = 0; k < nk; k++) {
                hat[2 * k] *= p->fd_s[k];
                hat[2 * k + 1] *= p->fd_s[k];
            }
            /* FFTW runs the plan on z's layer when it has the planning arrays' alignment (64 bytes: the PCG's
             * vectors do); the same codelets either way, so the same bits */
            double *zl = ((uintptr_t)(z + o) & 63) == 0 ? z + o : phi;
            fftw_execute_dft_c2r(p->fd_c2r, (fftw_complex *)hat, zl);
            if (p->nc > 0) wt_precond__coarse_coef(p, zl, p->fd_cphi + (size_t)l * sc2, u);
            if (q > 0) fourier_ngs_dots(p, l, zl);
            if (zl != z + o) memcpy(z + o, phi, (size_t)m2 * sizeof *z);
        }
        if (p->nc > 0 || q > 0) {
#pragma omp single
            {
                if (p->nc > 0) { /* c_w = (Qᵀ M̃ Q)⁻¹ Qᵀ r − Qᵀ φ: the coarse correction of every layer */
                    double *w = p->c_w;
                    memcpy(w, p->fd_cr, (size_t)p->nc * sizeof *w);
                    wt_precond__chol_solves(p->c_L, p->nc, w);
                    for (int i = 0; i < p->nc; i++) w[i] -= p->fd_cphi[i];
                }
                if (q > 0) {
                    double *wv = p->lr_w;
                    for (int k = 0; k < q; k++) {
                        double d = 0.0;
                        for (int l = 0; l < L; l++) d += p->fd_dots[l * q + k];
                        for (int i = 0; i < p->nc; i++) d += p->fd_rc[i + (size_t)p->nc * k] * p->c_w[i];
                        wv[k] = d;
                    }
                    wt_precond__lowrank_solve(p, wv);
                }
            } /* (its barrier) */
            if (p->nc > 0) {
#pragma omp for schedule(dynamic, 1)
                for (int l = 0; l < L; l++) coarse_add(p, p->c_w + (size_t)l * sc2, z + wt_tomography_layer_offset(t, l));
            }
            if (q > 0) {
#ifdef _OPENMP
                const int nt = omp_get_num_threads(), id = omp_get_thread_num();
#else
                const int nt = 1, id = 0;
#endif
                wt_precond__yb_update(p, p->lr_w, z, p->lr_nblk * id / nt, p->lr_nblk * (id + 1) / nt);
            }
        }
    }
}

/* B⁻¹ r of the kind: the Fourier filter, or J⁻¹ / the layer blocks below the coarse block's exact solve */
/* fourier_apply's form of R (n x r, the layers' values): each column on each layer where it is not zero (the
 * adjoint leaves exact zeros off the NGS footprints' rims), and R_c = Qᵀ R (nc x r) */
int wt_precond__fourier_ngs_columns(wt_precond *p, const wt_tomography *t, const double *R)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const int L = wt_tomography_nlayers(t), q = p->nlr, sc2 = p->fd_sc * p->fd_sc;
    const int64_t m2 = (int64_t)p->fd_n * p->fd_n;
    double *c = NULL, *u = NULL;
    WT_ALLOC(ctx, p->fd_rs_ptr, (size_t)L * q + 1, "fourier NGS column pointers");
    WT_ALLOC(ctx, p->fd_dots, (size_t)L * q, "fourier NGS dots");
    WT_ALLOC(ctx, p->fd_rc, (size_t)p->nc * q + 1, "fourier NGS coarse rows");
    int64_t nnz = 0;
    for (int pass = 0; pass < 2; pass++) { /* count, then fill */
        nnz = 0;
        for (int l = 0; l < L; l++)
            for (int k = 0; k < q; k++) {
                const double *f = R + (size_t)p->n * k + wt_tomography_layer_offset(t, l);
                if (pass) p->fd_rs_ptr[l * q + k] = nnz;
                for (int64_t i = 0; i < m2; i++)
                    if (f[i] != 0.0) {
                        if (pass) {
                            p->fd_rs_idx[nnz] = (int32_t)i;
                            p->fd_rs_val[nnz] = f[i];
                        }
                        nnz++;
                    }
            }
        if (!pass) {
            WT_ALLOC(ctx, p->fd_rs_idx, nnz + 1, "fourier NGS column points");
            WT_ALLOC(ctx, p->fd_rs_val, nnz + 1, "fourier NGS column values");
        }
    }
    p->fd_rs_ptr[(size_t)L * q] = nnz;
    if (p->nc > 0) {
        WT_ALLOC(ctx, c, sc2, "fourier NGS coarse coefficients");
        WT_ALLOC(ctx, u, (size_t)p->fd_sc * p->fd_n, "fourier NGS contraction");
        for (int k = 0; k < q; k++)
            for (int l = 0; l < L; l++) {
                wt_precond__coarse_coef(p, R + (size_t)p->n * k + wt_tomography_layer_offset(t, l), c, u);
                for (int i = 0; i < sc2; i++) p->fd_rc[l * sc2 + i + (size_t)p->nc * k] = c[i];
            }
    }
    if (p->parts) { /* the update's spectra: the apply's first steps on R's columns, on thread 0's buffers (the
                       plans' alignment: the same codelets, the same bits as fourier_apply) */
        const int64_t nk = p->fd_nk;
        WT_ALLOC(ctx, p->fd_rhat, (size_t)q * L * nk, "fourier NGS spectra (update)");
        WT_ALLOC(ctx, p->pu_Y_raw, (size_t)p->n * q + 8, "fourier NGS Y (update)");
        double *phi = fourier_phi(p, 0), *uu = phi + p->fd_slice - (size_t)WT_FOURIER_MAX_SC * p->fd_n;
        fftw_complex *hat = fourier_hat(p, 0);
        for (int k = 0; k < q; k++)
            for (int l = 0; l < L; l++) {
                const double *r = R + (size_t)p->n * k + wt_tomography_layer_offset(t, l);
                if (p->nc > 0) {
                    double cc[WT_FOURIER_MAX_SC * WT_FOURIER_MAX_SC], mc[WT_FOURIER_MAX_SC * WT_FOURIER_MAX_SC];
                    wt_precond__coarse_coef(p, r, cc, uu);
                    for (int i = 0; i < sc2; i++) mc[i] = -cc[i];
                    coarse_add_to(p, mc, r, phi);
                } else memcpy(phi, r, (size_t)m2 * sizeof *phi);
                fftw_execute_dft_r2c(p->fd_r2c, phi, hat);
                memcpy(p->fd_rhat + ((size_t)k * L + l) * nk, hat, (size_t)nk * sizeof *hat);
            }
    }
fail:
    wt_free(ctx, c);
    wt_free(ctx, u);
    return st;
}

/* Y = B⁻¹ R from the kept spectra: per column k and layer l (the nlr L of them side by side) the filter on F Π_d R
 * and the inverse FFT, Qᵀ of the result; per column the coarse solve; per column and layer the coarse correction.
 * fourier_apply's operations on each value in its order (the forward FFT's output read back): the same bits as
 * nlr applies, with half their FFTs, and whole layers on every thread instead of L per apply. */
int wt_precond__fourier_lowrank_Y(const wt_precond *p, double *Y)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_tomography *t = p->tomo;
    const int L = wt_tomography_nlayers(t), q = p->nlr, sc2 = p->fd_sc * p->fd_sc, nc = p->nc;
    const int64_t nk = p->fd_nk, m2 = (int64_t)p->fd_n * p->fd_n, n = p->n;
    double *cw = NULL; /* nc x q: Qᵀ of the filtered layers, then the coarse corrections; nc x q of solves' work */
    if (nc > 0) WT_ALLOC(ctx, cw, (size_t)2 * nc * q, "fourier NGS coarse corrections (update)");
#pragma omp parallel num_threads(p->nthreads)
    {
#pragma omp for schedule(dynamic, 1)
        for (int task = 0; task < q * L; task++) {
            const int k = task / L, l = task % L, id = wt_thread_id();
            double *phi = fourier_phi(p, id), *hat = (double *)fourier_hat(p, id);
            double *u = phi + p->fd_slice - (size_t)WT_FOURIER_MAX_SC * p->fd_n;
            const double *src = (const double *)(p->fd_rhat + ((size_t)k * L + l) * nk);
            for (int64_t f = 0; f < nk; f++) {
                hat[2 * f] = src[2 * f] * p->fd_s[f];
                hat[2 * f + 1] = src[2 * f + 1] * p->fd_s[f];
            }
            double *z = Y + (size_t)n * k + wt_tomography_layer_offset(t, l);
            double *zl = ((uintptr_t)z & 63) == 0 ? z : phi;
            fftw_execute_dft_c2r(p->fd_c2r, (fftw_complex *)hat, zl);
            if (nc > 0) wt_precond__coarse_coef(p, zl, cw + (size_t)nc * k + (size_t)l * sc2, u);
            if (zl != z) memcpy(z, phi, (size_t)m2 * sizeof *z);
        }
        if (nc > 0) {
#pragma omp for schedule(dynamic, 1)
            for (int k = 0; k < q; k++) { /* (Qᵀ M̃ Q)⁻¹ Qᵀ R_k − Qᵀ φ */
                double *c = cw + (size_t)nc * k, *w = cw + (size_t)nc * (q + k);
                memcpy(w, p->fd_rc + (size_t)nc * k, (size_t)nc * sizeof *w);
                wt_precond__chol_solves(p->c_L, nc, w);
                for (int i = 0; i < nc; i++) c[i] = w[i] - c[i];
            }
#pragma omp for schedule(dynamic, 1)
            for (int task = 0; task < q * L; task++) {
                const int k = task / L, l = task % L;
                coarse_add(p, cw + (size_t)nc * k + (size_t)l * sc2, Y + (size_t)n * k + wt_tomography_layer_offset(t, l));
            }
        }
    }
fail:
    wt_free(ctx, cw);
    return st;
}
