/* core/op/prior.c: the diagonal wavelet prior D_ℓ of a reconstruction layer (SPEC §6, paper eq.
 * REG_WAV_penalty_discr), normalised against the exact von Kármán coefficient variances (SPEC §2).
 *
 * The layer is modelled as a periodic n x n grid of spacing δ (L = nδ) whose DFT modes a_k are
 * independent with E|a_k|² = Φ(κ_k)/L², κ_k = |k|/L, k the signed DFT frequencies; this is the Riemann
 * sum, on the grid's frequency lattice of cell 1/L², of the continuous spectrum. Then, for a real basis
 * function w = W⁻¹ e_λ with unnormalised DFT ŵ(k) = Σ_j w_j e^{−2πi k·j/n}:
 *     ⟨w, φ⟩ = Σ_k a_k conj(ŵ(k)),   Var ⟨w, φ⟩ = (W C_φ Wᵀ)_λλ = Σ_k Φ(κ_k)/L² |ŵ(k)|².
 * The periodic DWT maps every coefficient of a (level, orientation) to a translate of one basis function
 * and C_φ is circulant, so one FFT per (level, orientation) gives the whole diagonal: 3J + 1 FFTs.
 * The k = 0 (piston) mode carries Φ(0)/L²; it only enters the approximation coefficients (wavelets have
 * zero mean) and is kept: it is the lattice's share of the finite von Kármán power below 1/L.
 * Aliasing of power above the grid's Nyquist frequency is not modelled (the model's field is band-limited).
 *
 * Paper form: D_λλ = (1/c)(L0^(-11/3) + κ_λ^(11/3)) for the detail coefficients, κ_λ the centre of the
 * basis function's band (detail_kappa), c the geometric-mean fit of var·profile over the 3J detail
 * blocks; the approximation block takes its exact variance (see the diagonal loop). On the E-ELT grids
 * this puts D⁻¹ within 0.64-1.8x of the exact variance at every level and orientation.
 * Exact form: D_λλ = 1 / var(level, orientation).
 * Full form: the prior term φᵀ C_φ⁻¹ φ itself. With the unnormalised DFT F, C_φ = F⁻¹ Λ F, Λ_k = n² Φ(κ_k)/L²,
 * so C_φ⁻¹ φ = F*[(L²/(n⁴ Φ(κ_k))) F φ] (F* = FFTW's backward transform), and
 * (W C_φ⁻¹ Wᵀ)_λλ = Σ_k |ŵ(k)|² L²/(n⁴ Φ(κ_k)), one FFT per (level, orientation) as above.
 */
#include "prior.h"

#include <fftw3.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define LAMBDA0 500e-9 /* reference wavelength of r0 [m] */

struct wt_prior {
    wt_context *ctx;
    int n, levels, kind;
    double spacing;     /* δ [m] */
    double L0;          /* outer scale [m] */
    double scale;       /* c_ℓ of the paper form [m^(-5/3)]: D = profile [m^(-11/3)] / c [1/m²] */
    double *var;        /* exact variance [m²] at [level * 4 + orient], level 1 … J+1 */
    double *diag;       /* D_λλ [1/m²], n*n in the wavelet layout */
    double *inv;        /* full form: L²/(n⁴ Φ(κ_k)) on the r2c half spectrum, n x (n/2 + 1) */
    fftw_plan r2c, c2r; /* full form: planned unaligned, executed with the caller's work arrays */
};

double wt_von_karman_psd(double kappa, double r0, double fraction, double L0)
{
    const double k = LAMBDA0 / (2.0 * M_PI);
    return k * k * 0.0229 * fraction * pow(r0, -5.0 / 3.0) * pow(kappa * kappa + 1.0 / (L0 * L0), -11.0 / 6.0);
}

/* The frequency the paper form assigns to a detail coefficient [cycles/m]: the centre of its basis
 * function's band. A level-l high-pass axis passes |k| ∈ [1/(δ 2^(l+1)), 1/(δ 2^l)], geometric centre
 * 1/(√2 δ 2^l); the x- and y-details have one high-pass axis, the diagonal detail has two, so its band
 * sits √2 further out, at 1/(δ 2^l). (With 1/(δ 2^l) for every orientation, as core/op/prior.h first
 * proposed, the E-ELT grids miss the exact variances by up to 3.4x: the diagonal details carry ~3.7x
 * less power than the x/y details of the same level, which no orientation-blind D can straddle within
 * a factor 2.) */
static double detail_kappa(double spacing, int level, int orient)
{
    double edge = 1.0 / (spacing * ldexp(1.0, level));
    return orient == 3 ? edge : edge * M_SQRT1_2;
}

/* L0^(-11/3) + κ^(11/3): the paper's decay profile of D, the inverse shape of the variances. */
static double paper_profile(double L0, double kappa) { return pow(L0, -11.0 / 3.0) + pow(kappa, 11.0 / 3.0); }

void wt_prior_free(wt_prior *p)
{
    if (!p) return;
    wt_context *ctx = p->ctx;
    if (p->r2c) fftw_destroy_plan(p->r2c);
    if (p->c2r) fftw_destroy_plan(p->c2r);
    wt_free(ctx, p->var);
    wt_free(ctx, p->diag);
    wt_free(ctx, p->inv);
    wt_free(ctx, p);
}

/* Φ(κ_k) of the mode (kx, ky) of the periodic n x n grid of side L, aliased or not (core/op/prior.h) */
static double mode_psd(int kx, int ky, int n, double L, double r0, double fraction, double L0, int aliased)
{
    double psd = 0.0;
    const int A = aliased ? 4 : 0;
    for (int b = -A; b <= A; b++)
        for (int a = -A; a <= A; a++) {
            double fx = (double)kx + (double)a * n, fy = (double)ky + (double)b * n;
            psd += wt_von_karman_psd(sqrt(fx * fx + fy * fy) / L, r0, fraction, L0);
        }
    return psd;
}

/* var[level*4 + orient] for every (level, orientation) by one inverse DWT and one real FFT each: the
 * diagonal of W C_φ Wᵀ, or with `inverse` that of W C_φ⁻¹ Wᵀ. The r2c transform keeps kx = 0 … n/2; the
 * other half of the spectrum is the conjugate mirror, so the columns 0 < kx < n/2 count twice. */
static int exact_variances(wt_context *ctx, const wt_wavelet *w, double spacing, double r0, double fraction,
                           double L0, int aliased, int inverse, double *var)
{
    int st = WT_OK;
    const int n = wt_wavelet_n(w), J = wt_wavelet_levels(w), nh = n / 2 + 1;
    const double L = n * spacing;
    double *spec = NULL, *coef = NULL, *basis = NULL, *work = NULL;
    fftw_complex *hat = NULL;
    fftw_plan plan = NULL;
    WT_ALLOC(ctx, spec, (size_t)n * nh, "prior spectrum weights");
    WT_ALLOC(ctx, coef, (size_t)n * n, "prior coefficient vector");
    WT_ALLOC(ctx, basis, (size_t)n * n, "prior basis function");
    WT_ALLOC(ctx, work, wt_wavelet_work_size(w) ? wt_wavelet_work_size(w) : 1, "prior wavelet workspace");
    WT_ALLOC(ctx, hat, (size_t)n * nh, "prior basis spectrum");

    for (int iy = 0; iy < n; iy++) {
        int ky = iy <= n / 2 ? iy : iy - n;
        for (int kx = 0; kx < nh; kx++) {
            double mult = (kx == 0 || 2 * kx == n) ? 1.0 : 2.0;
            double psd = mode_psd(kx, ky, n, L, r0, fraction, L0, aliased);
            spec[(size_t)iy * nh + kx] = mult * (inverse ? L * L / ((double)n * n * n * n * psd) : psd / (L * L));
        }
    }
    /* The planner is FFTW's one global (non-thread-safe) state: plan with FFTW_ESTIMATE, which neither
     * measures nor overwrites the arrays, and only here at set-up. Row-major n0 = y, n1 = x matches
     * index ix + n*iy. */
    plan = fftw_plan_dft_r2c_2d(n, n, basis, hat, FFTW_ESTIMATE);
    if (!plan) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "prior: fftw_plan_dft_r2c_2d(%d, %d) returned NULL", n, n);
        goto fail;
    }
    for (int level = 1; level <= J + 1; level++) {
        int m = n >> (level <= J ? level : J); /* side of the level's blocks */
        for (int orient = (level <= J ? 1 : 0); orient <= (level <= J ? 3 : 0); orient++) {
            /* first coefficient of the block (Mallat layout, core/op/wavelet.h) */
            int ix = (orient == 1 || orient == 3) ? m : 0, iy = (orient == 2 || orient == 3) ? m : 0;
            memset(coef, 0, (size_t)n * n * sizeof *coef);
            coef[ix + (size_t)n * iy] = 1.0;
            wt_wavelet_inverse(w, coef, basis, work);
            fftw_execute(plan);
            double s = 0.0;
            for (size_t k = 0; k < (size_t)n * nh; k++) {
                double re = hat[k][0], im = hat[k][1];
                s += spec[k] * (re * re + im * im);
            }
            var[level * 4 + orient] = s;
        }
    }
fail:
    if (plan) fftw_destroy_plan(plan);
    wt_free(ctx, spec);
    wt_free(ctx, coef);
    wt_free(ctx, basis);
    wt_free(ctx, work);
    wt_free(ctx, hat);
    return st;
}

/* The full form's multipliers L²/(n⁴ Φ(κ_k)) and its two plans. The planner is FFTW's global state: plans
 * are made here, at set-up (core/la/fft.h: FFTW_ESTIMATE, or the wisdom's measured plans; either way no array
 * touched and the same algorithm every run: same bits); every thread executes them on its own 64-byte aligned
 * work arrays (wt_prior_apply_full). */
static int full_operator(wt_context *ctx, wt_prior *p, double r0, double fraction, int aliased, wt_fft_wisdom *fft)
{
    int st = WT_OK;
    const int n = p->n, nh = n / 2 + 1;
    const double L = n * p->spacing;
    double *a = NULL;
    fftw_complex *c = NULL;
    WT_ALLOC(ctx, p->inv, (size_t)n * nh, "prior inverse spectrum");
    for (int iy = 0; iy < n; iy++) {
        int ky = iy <= n / 2 ? iy : iy - n;
        for (int kx = 0; kx < nh; kx++)
            p->inv[(size_t)iy * nh + kx] = L * L / ((double)n * n * n * n * mode_psd(kx, ky, n, L, r0, fraction, p->L0, aliased));
    }
    /* planned on arrays at 64-byte boundaries, as the work arrays it runs on and as core/la/fft.c learns */
    a = aligned_alloc(64, ((size_t)n * n * sizeof *a + 63) / 64 * 64);
    c = aligned_alloc(64, ((size_t)n * nh * sizeof *c + 63) / 64 * 64);
    if (!a || !c) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "prior: out of memory for the %d x %d FFT plans' arrays", n, n);
        goto fail;
    }
    st = wt_fft_plan_pair(ctx, fft, n, a, c, "prior (full)", &p->r2c, &p->c2r);
fail:
    free(a);
    free(c);
    return st;
}

int wt_prior_alloc(wt_context *ctx, const wt_wavelet *w, double spacing, double r0, double fraction, double L0,
                   int kind, wt_fft_wisdom *fft, wt_prior **out)
{
    int st = WT_OK;
    wt_prior *p = NULL;
    *out = NULL;
    if (!w) return WT_ERROR(ctx, WT_ERR_INVALID, "prior: wavelet plan is NULL, expected the layer's plan");
    if (!(spacing > 0.0) || !isfinite(spacing))
        return WT_ERROR(ctx, WT_ERR_INVALID, "prior: layer spacing = %g m, expected finite and > 0", spacing);
    if (!(r0 > 0.0) || !isfinite(r0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "prior: r0 = %g m, expected finite and > 0", r0);
    if (!(fraction > 0.0) || !isfinite(fraction))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "prior: Cn2 fraction = %g, expected finite and > 0 (a layer without turbulence "
                        "has no prior)",
                        fraction);
    if (!(L0 > 0.0) || !isfinite(L0))
        return WT_ERROR(ctx, WT_ERR_INVALID, "prior: outer scale L0 = %g m, expected finite and > 0", L0);
    const int aliased = (kind & WT_PRIOR_ALIASED) != 0;
    kind &= ~WT_PRIOR_ALIASED;
    if (kind != WT_PRIOR_PAPER && kind != WT_PRIOR_EXACT && kind != WT_PRIOR_FULL)
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "prior: kind = %d, expected WT_PRIOR_PAPER (%d), WT_PRIOR_EXACT (%d) or WT_PRIOR_FULL (%d)",
                        kind, WT_PRIOR_PAPER, WT_PRIOR_EXACT, WT_PRIOR_FULL);

    const int n = wt_wavelet_n(w), J = wt_wavelet_levels(w);
    WT_ALLOC(ctx, p, 1, "prior");
    p->ctx = ctx;
    p->n = n;
    p->levels = J;
    p->kind = kind;
    p->spacing = spacing;
    p->L0 = L0;
    WT_ALLOC(ctx, p->var, (size_t)(J + 2) * 4, "prior variance table");
    for (int i = 0; i < (J + 2) * 4; i++) p->var[i] = NAN;
    WT_ALLOC(ctx, p->diag, (size_t)n * n, "prior diagonal");
    WT_TRY(exact_variances(ctx, w, spacing, r0, fraction, L0, aliased, 0, p->var));
    double *ivar = NULL; /* full form: diag(W C_φ⁻¹ Wᵀ) per (level, orientation) */
    if (kind == WT_PRIOR_FULL) {
        WT_ALLOC(ctx, ivar, (size_t)(J + 2) * 4, "prior inverse-covariance diagonal");
        st = exact_variances(ctx, w, spacing, r0, fraction, L0, aliased, 1, ivar);
        if (st == WT_OK) st = full_operator(ctx, p, r0, fraction, aliased, fft);
        if (st < 0) {
            wt_free(ctx, ivar);
            goto fail;
        }
    }

    /* c_ℓ: geometric-mean fit of var · profile over the 3J detail blocks, i.e. the least-squares fit of
     * log D⁻¹ to log var; the approximation block is left out because its variance is dominated by the
     * outer scale, which the paper's two-term profile only roughly describes. */
    double slog = 0.0;
    for (int level = 1; level <= J; level++)
        for (int orient = 1; orient <= 3; orient++)
            slog += log(p->var[level * 4 + orient] * paper_profile(L0, detail_kappa(spacing, level, orient)));
    p->scale = exp(slog / (3.0 * J));
    if (!isfinite(p->scale) || !(p->scale > 0.0)) {
        st = WT_ERROR(ctx, WT_ERR_NUMERIC, "prior: fitted scale c = %g is not finite and positive", p->scale);
        goto fail;
    }

    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            int level, orient;
            wt_wavelet_classify(w, ix, iy, &level, &orient);
            /* The approximation block's band reaches down to κ = 0, where the outer scale flattens the
             * spectrum, so no single κ in the paper profile stands for it at every J (1/(δ 2^(J+1)) is
             * within 1.15x on the E-ELT J = 5 grids but 3-50x off at J = 3): both forms take its exact
             * variance. It is (n/2^J)² coefficients, the layer's largest scales. */
            double d = kind == WT_PRIOR_FULL ? ivar[level * 4 + orient]
                       : (kind == WT_PRIOR_EXACT || orient == 0)
                           ? 1.0 / p->var[level * 4 + orient]
                           : paper_profile(L0, detail_kappa(spacing, level, orient)) / p->scale;
            p->diag[ix + (size_t)n * iy] = d;
        }
    wt_free(ctx, ivar);
    *out = p;
    return WT_OK;
fail:
    wt_prior_free(p);
    return st;
}

const double *wt_prior_diag(const wt_prior *p) { return p->diag; }
int wt_prior_kind(const wt_prior *p) { return p->kind; }

/* The caller's work holds, from its first 64-byte boundary, the transforms' input, spectrum and output:
 * FFTW runs its SIMD codelets only on arrays aligned as those it planned with (64 bytes: full_operator), and
 * wt_malloc promises 16 bytes. */
#define PRIOR_ALIGN_SLACK 8 /* doubles */
size_t wt_prior_work_size(const wt_prior *p)
{
    return p->kind == WT_PRIOR_FULL ? PRIOR_ALIGN_SLACK + 2 * (size_t)p->n * p->n + 2 * (size_t)p->n * (p->n / 2 + 1) : 0;
}

void wt_prior_apply_full(const wt_prior *p, double alpha, const double *phi, double *out, double *work)
{
    const size_t n2 = (size_t)p->n * p->n, nc = (size_t)p->n * (p->n / 2 + 1);
    double *in = wt_align64(work);
    fftw_complex *hat = (fftw_complex *)(in + n2);
    double *res = in + n2 + 2 * nc;
    /* FFTW runs a plan on other arrays only with the planning arrays' alignment (its SIMD codelets): the work
     * arrays are 64-byte aligned, and so are phi and out where the caller keeps its layers at 64-byte
     * boundaries (the tomography does): then the transforms read and write them directly, the same codelets on
     * the same values (an out-of-place r2c preserves its input: FFTW's default for every kind but c2r). */
    const int direct = ((uintptr_t)phi & 63) == 0 && ((uintptr_t)out & 63) == 0;
    if (direct) fftw_execute_dft_r2c(p->r2c, (double *)phi, hat);
    else {
        memcpy(in, phi, n2 * sizeof *in);
        fftw_execute_dft_r2c(p->r2c, in, hat);
    }
    for (size_t k = 0; k < nc; k++) {
        const double m = alpha * p->inv[k];
        hat[k][0] *= m;
        hat[k][1] *= m;
    }
    if (direct) fftw_execute_dft_c2r(p->c2r, hat, out);
    else {
        fftw_execute_dft_c2r(p->c2r, hat, res);
        memcpy(out, res, n2 * sizeof *out);
    }
}

double wt_prior_level_variance(const wt_prior *p, int level, int orient)
{
    int ok = (level >= 1 && level <= p->levels && orient >= 1 && orient <= 3) ||
             (level == p->levels + 1 && orient == 0);
    return ok ? p->var[level * 4 + orient] : NAN;
}

double wt_prior_scale(const wt_prior *p) { return p->scale; }

void wt_prior_rescale(wt_prior *p, double factor)
{
    if (!(factor > 0.0) || !isfinite(factor)) return;
    const int64_t n2 = (int64_t)p->n * p->n;
    for (int i = 0; i < (p->levels + 2) * 4; i++) p->var[i] *= factor; /* (NaN entries stay NaN) */
    for (int64_t i = 0; i < n2; i++) p->diag[i] /= factor;
    if (p->inv)
        for (int64_t i = 0; i < (int64_t)p->n * (p->n / 2 + 1); i++) p->inv[i] /= factor;
    p->scale *= factor;
}
