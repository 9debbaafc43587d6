/* core/optics/spot.c: diffractive Shack–Hartmann images (SPEC §4b): U = A·exp(2πi·OPD/λ) → Nyquist FFT →
 * |·|² → overlap rebinning onto cells of p/k → direct sum with the per-subaperture source⊛pixel table;
 * detector noise Poisson(I + B) + N(0, σe²) − B; the exact Poisson sampler. The design and its accuracy
 * are in spot.h. */
#include "spot_private.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif


static size_t ws_bytes(const wt_spot *s)
{
    size_t b = 0;
    b += ALIGN + (size_t)s->N * s->N * sizeof(fftwf_complex);
    b += ALIGN + (size_t)s->N * s->N * sizeof(float);
    b += ALIGN + (size_t)s->M * s->N * sizeof(float);
    b += ALIGN + (size_t)s->M * s->M * sizeof(float);
    b += ALIGN + (size_t)s->np * s->np * sizeof(double);
    b += ALIGN + (size_t)s->Ns * s->Ns * sizeof(float);
    b += ALIGN + (size_t)s->M * s->M * sizeof(float);
    b += ALIGN + (size_t)s->M * s->M * sizeof(int);
    return b + ALIGN;
}

static void *carve(char **p, size_t bytes)
{
    uintptr_t a = ((uintptr_t)*p + ALIGN - 1) & ~(uintptr_t)(ALIGN - 1);
    *p = (char *)(a + bytes);
    return (void *)a;
}

static int ws_init(wt_spot *s, workspace *w)
{
    w->block = wt_malloc(s->ctx, ws_bytes(s), 1);
    if (!w->block) return WT_ERROR(s->ctx, WT_ERR_NOMEM, "spot: out of memory for a thread workspace (%zu bytes)", ws_bytes(s));
    char *p = w->block;
    w->field = carve(&p, (size_t)s->N * s->N * sizeof(fftwf_complex));
    w->psf = carve(&p, (size_t)s->N * s->N * sizeof(float));
    w->tmp = carve(&p, (size_t)s->M * s->N * sizeof(float));
    w->cells = carve(&p, (size_t)s->M * s->M * sizeof(float));
    w->opd = carve(&p, (size_t)s->np * s->np * sizeof(double));
    w->img2 = carve(&p, (size_t)s->Ns * s->Ns * sizeof(float));
    w->cv = carve(&p, (size_t)s->M * s->M * sizeof(float));
    w->co = carve(&p, (size_t)s->M * s->M * sizeof(int));
    return WT_OK;
}

void wt_spot_free(wt_spot *s)
{
    if (!s) return;
    wt_context *ctx = s->ctx;
    if (s->rows) fftwf_destroy_plan(s->rows);
    if (s->cols) fftwf_destroy_plan(s->cols);
    if (s->otf_fwd) fftwf_destroy_plan(s->otf_fwd);
    if (s->otf_bwd) fftwf_destroy_plan(s->otf_bwd);
    if (s->ws)
        for (int t = 0; t < s->nthreads; t++) wt_free(ctx, s->ws[t].block);
    wt_free(ctx, s->ws);
    wt_free(ctx, s->flux);
    wt_free(ctx, s->scale);
    wt_free(ctx, s->amp);
    wt_free(ctx, s->xs);
    wt_free(ctx, s->rm);
    wt_free(ctx, s->rw);
    wt_free(ctx, s->rn);
    wt_free(ctx, s->gs);
    wt_free(ctx, s->gi);
    wt_free(ctx, s->gw);
    wt_free(ctx, s->K);
    wt_free(ctx, s->xc);
    wt_free(ctx, s->yc);
    wt_free(ctx, s->rcells);
    wt_free(ctx, s->dl);
    wt_free(ctx, s);
}

static int check_params(wt_context *ctx, const wt_spot_params *p, int nsub)
{
    if (nsub < 0 || nsub >= (1 << 20))
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: %d subapertures; accepted 0 to 2^20 - 1", nsub);
    if (!(p->wavelength > 0) || !isfinite(p->wavelength))
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: *.wfs.wavelength = %g m; must be > 0", p->wavelength);
    if (!(p->subap_side > 0) || !isfinite(p->subap_side))
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: subaperture side %g m; must be > 0", p->subap_side);
    if (p->pupil_samples < 2 || p->pupil_samples > 1024)
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: *.wfs.pupil_samples = %d; accepted 2 to 1024", p->pupil_samples);
    if (p->fft_size < 2 * p->pupil_samples) {
        const double d = p->subap_side, lam = p->wavelength;
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "spot: *.wfs.fft_size = %d with *.wfs.pupil_samples = %d samples the PSF at lambda/(N dx) "
                        "= %.4g arcsec, coarser than Nyquist lambda/(2d) = %.4g arcsec; the minimum "
                        "*.wfs.fft_size is %d (2 x *.wfs.pupil_samples)",
                        p->fft_size, p->pupil_samples, lam * p->pupil_samples / (p->fft_size * d) * RAD2AS,
                        lam / (2 * d) * RAD2AS, 2 * p->pupil_samples);
    }
    if (p->fft_size % 2 || p->fft_size > 4096)
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: *.wfs.fft_size = %d; must be even and at most 4096", p->fft_size);
    if (p->npix < 1 || p->npix > 1024)
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: *.wfs.npix = %d; accepted 1 to 1024", p->npix);
    if (!(p->pixel > 0) || !isfinite(p->pixel))
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: *.wfs.pixel_arcsec = %g arcsec; must be > 0", p->pixel * RAD2AS);
    if (p->cells_per_pixel < 0 || (p->cells_per_pixel > 0 && p->cells_per_pixel % 2 == 0) || p->cells_per_pixel > 31)
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: cells per pixel %d; must be odd, 1 to 31 (0: default 3)",
                        p->cells_per_pixel);
    if (!(p->photons >= 0) || !(p->background >= 0) || !(p->read_noise >= 0) || !isfinite(p->photons) ||
        !isfinite(p->background) || !isfinite(p->read_noise))
        return WT_ERROR(ctx, WT_ERR_INVALID,
                        "spot: *.wfs.photons = %g, background = %g, read noise = %g; each must be finite and >= 0",
                        p->photons, p->background, p->read_noise);
    if (!(p->uplink_fwhm >= 0) || !isfinite(p->uplink_fwhm))
        return WT_ERROR(ctx, WT_ERR_INVALID, "spot: uplink spot FWHM %g rad; must be >= 0", p->uplink_fwhm);
    if (p->sodium) {
        if (!(p->lgs_altitude > 0) || !isfinite(p->launch_x) || !isfinite(p->launch_y))
            return WT_ERROR(ctx, WT_ERR_INVALID, "spot: LGS altitude %g m must be > 0 and the launch position finite",
                            p->lgs_altitude);
        int st = wt_sodium_check_covers(ctx, p->sodium, p->lgs_altitude, "spot: lgs.sodium_profile");
        if (st < 0) return st;
    }
    return WT_OK;
}

/* ∫_{−∞}^{x} (1 − |t|)₊ dt */
static double tent_int(double x)
{
    if (x <= -1) return 0;
    if (x <= 0) return 0.5 * (x + 1) * (x + 1);
    if (x < 1) return 1 - 0.5 * (1 - x) * (1 - x);
    return 1;
}


/* The Gaussian's mass per cell as a function of the point's sub-cell offset f ∈ [0, 1]: row fi (f = fi/NF)
 * holds the masses of the cells −reach … reach + 1 around floor(position). Linear interpolation between
 * rows errs by ≤ (1/NF)²/8 · max|∂²mass/∂f²| ≈ 0.24/(8 NF² σ³) of the mass (σ in cells): 1e-6 at σ = 1,
 * NF = 256; it replaces ~30 erfc calls per line point by table reads. */
#define NF 256
typedef struct {
    double sg;   /* σ [cells]; 0: a point (no Gaussian) */
    int reach, nt;
    double *tab; /* [(NF + 1) · nt] */
} gauss_tab;

/* Standard normal CDF. */
static double Phi(double x) { return 0.5 * erfc(-x * M_SQRT1_2); }

static void gauss_tab_fill(gauss_tab *g)
{
    for (int fi = 0; fi <= NF; fi++) {
        const double f = (double)fi / NF;
        double lo = Phi((-g->reach - 0.5 - f) / g->sg);
        for (int j = 0; j < g->nt; j++) {
            double hi = Phi((j - g->reach + 0.5 - f) / g->sg);
            g->tab[fi * g->nt + j] = hi - lo;
            lo = hi;
        }
    }
}

/* The source kernel's mass per cell, S[ix + LS·iy] for cell centres at (o0 + ix, o0 + iy) cells from the
 * source point, for the subaperture at (xc, yc). The line is cut into points no further apart than half
 * the Gaussian's σ (then the comb's ripple after the Gaussian is below e^{-2π²·4} ≈ 1e-34) or a quarter
 * cell; each point deposits its Gaussian cell masses (separable, from the table). */
static void source_cells(const wt_spot *s, const wt_sodium *na, const double *stage, const gauss_tab *G, double xc,
                         double yc, int o0, int LS, double *S, double *gx, double *gy)
{
    const double c = s->par.pixel / s->k, sg = G->sg;
    const int reach = G->reach, nt = G->nt;
    memset(S, 0, (size_t)LS * LS * sizeof *S);
    double ux = 0, uy = 0, H = 1, mass = 1;
    int nseg = 1;
    if (na) {
        ux = xc - s->par.launch_x, uy = yc - s->par.launch_y, H = s->par.lgs_altitude;
        mass = wt_sodium_mass(na);
        nseg = na->n - 1;
    }
    const double step = fmax(fmin(0.5 * sg, 0.25), 1e-3); /* cells */
    const double ulen = hypot(ux, uy);
    for (int seg = 0; seg < nseg; seg++) {
        double h0 = 0, h1 = 0, f0 = 1, f1 = 1;
        int m = 1;
        if (na) {
            h0 = na->alt[seg], h1 = na->alt[seg + 1], f0 = na->dens[seg], f1 = na->dens[seg + 1];
            if (f0 == 0 && f1 == 0) continue;
            double span = ulen * (1.0 / h0 - 1.0 / h1) / c; /* angular length of the segment [cells] */
            m = (int)fmin(ceil(span / step), 1e6);
            if (m < 1) m = 1;
        }
        for (int j = 0; j < m; j++) {
            double bx = 0, by = 0, w = 1;
            if (na) {
                double t = (j + 0.5) / m, h = h0 + t * (h1 - h0);
                w = (f0 + t * (f1 - f0)) * (h1 - h0) / m / mass; /* midpoint rule: exact mass of a linear piece */
                bx = ux * (1.0 / h - 1.0 / H) / c, by = uy * (1.0 / h - 1.0 / H) / c;
                if (stage) bx += (2.0 * stage[2] * xc + stage[0]) / c, by += (2.0 * stage[2] * yc + stage[1]) / c;
            }
            if (w == 0) continue;
            /* local indices of the point in S */
            const double px = bx - o0, py = by - o0;
            if (reach == 0) {
                int ix = (int)floor(px + 0.5), iy = (int)floor(py + 0.5);
                if (ix >= 0 && ix < LS && iy >= 0 && iy < LS) S[ix + (size_t)LS * iy] += w;
                continue;
            }
            const int fx = (int)floor(px), fy = (int)floor(py);
            const int x0 = fx - reach, y0 = fy - reach;
            if (x0 + nt <= 0 || y0 + nt <= 0 || x0 >= LS || y0 >= LS) continue;
            const double ax = (px - fx) * NF, ay = (py - fy) * NF;
            const int ix = (int)fmin(ax, NF - 1), iy = (int)fmin(ay, NF - 1);
            const double tx = ax - ix, ty = ay - iy;
            const double *rx = G->tab + ix * nt, *ry = G->tab + iy * nt;
            for (int q = 0; q < nt; q++) gx[q] = (1 - tx) * rx[q] + tx * rx[q + nt];
            for (int q = 0; q < nt; q++) gy[q] = w * ((1 - ty) * ry[q] + ty * ry[q + nt]);
            const int qx0 = x0 < 0 ? -x0 : 0, qx1 = x0 + nt > LS ? LS - x0 : nt;
            const int qy0 = y0 < 0 ? -y0 : 0, qy1 = y0 + nt > LS ? LS - y0 : nt;
            for (int qy = qy0; qy < qy1; qy++) {
                double *row = S + (size_t)LS * (y0 + qy) + x0;
                const double wy = gy[qy];
                for (int qx = qx0; qx < qx1; qx++) row[qx] += wy * gx[qx];
            }
        }
    }
}

/* K_s in phase tables: Kd[(e0x + k e0y)·Lp² + mx + Lp·my] = K(k·mx + e0x + omin, k·my + e0y + omin), where
 * K(o) = Σ_{|a|,|b| ≤ (k−1)/2} S(o + (a, b)) is the source mass inside the pixel centred o cells away. */
static void kernel_table(const wt_spot *s, const double *S, int LS, double *B, float *Kd)
{
    const int k = s->k, Lp = s->Lp, LK = k * Lp;
    /* S covers offsets omin − h … omin + LK − 1 + h: S index = o − omin + h. Box sums, x then y. */
    for (int iy = 0; iy < LS; iy++)
        for (int ox = 0; ox < LK; ox++) {
            double a = 0;
            for (int t = 0; t < k; t++) a += S[ox + t + (size_t)LS * iy];
            B[ox + (size_t)LK * iy] = a;
        }
    for (int oy = 0; oy < LK; oy++)
        for (int ox = 0; ox < LK; ox++) {
            double a = 0;
            for (int t = 0; t < k; t++) a += B[ox + (size_t)LK * (oy + t)];
            int e0x = ox % k, mx = ox / k, e0y = oy % k, my = oy / k;
            Kd[(size_t)(e0x + k * e0y) * Lp * Lp + mx + (size_t)Lp * my] = (float)a;
        }
}

/* K for the source of profile na (NULL: a point, or the NGS's Gaussian), every subaperture; the subapertures are
 * independent, so the tables are the same for any thread count. */
static int build_tables(wt_spot *s, const wt_sodium *na, const double *stage)
{
    wt_context *ctx = s->ctx;
    int st = WT_OK;
    const int k = s->k, Lp = s->Lp, LK = k * Lp, LS = LK + k - 1, nth = s->nthreads;
    const double c = s->par.pixel / k;
    double *S = NULL, *B = NULL, *g = NULL;
    gauss_tab G = {0};
    /* σ in cells of the Gaussian the table applies: the source's, less the rebinning blur (spot.h) */
    const double su = s->par.uplink_fwhm / (2.0 * sqrt(2.0 * log(2.0)));
    G.sg = su * su > s->blur ? sqrt(su * su - s->blur) / c : 0.0;
    G.reach = G.sg > 0 ? (int)ceil(6.0 * G.sg) + 1 : 0; /* Φ(−6) ≈ 1e-9 of the mass left out */
    G.nt = 2 * G.reach + 2;
    WT_ALLOC(ctx, G.tab, (size_t)(NF + 1) * G.nt, "spot Gaussian table");
    if (G.sg > 0) gauss_tab_fill(&G);
    WT_ALLOC(ctx, S, (size_t)LS * LS * nth, "spot source cells");
    WT_ALLOC(ctx, B, (size_t)LK * LS * nth, "spot box sums");
    WT_ALLOC(ctx, g, 2 * (size_t)G.nt * nth, "spot Gaussian masses");
    {
        /* o = kP − q with q = qmin + m: omin = −qmax; S index o − omin + h, i.e. S's first cell at omin − h */
        const int o_min = s->omin, h = (k - 1) / 2;
#pragma omp parallel for schedule(dynamic, 16) num_threads(nth) if (nth > 1 && s->nsub > 1 && !omp_in_parallel())
        for (int is = 0; is < s->nsub; is++) {
            const int t = wt_thread_id();
            double *St = S + (size_t)LS * LS * t, *Bt = B + (size_t)LK * LS * t, *gt = g + 2 * (size_t)G.nt * t;
            source_cells(s, na, stage, &G, s->xc[is], s->yc[is], o_min - h, LS, St, gt, gt + G.nt);
            kernel_table(s, St, LS, Bt, s->K + (size_t)is * k * k * Lp * Lp);
        }
    }
fail:
    wt_free(ctx, S), wt_free(ctx, B), wt_free(ctx, g), wt_free(ctx, G.tab);
    return st;
}

int wt_spot_set_sodium_staged(wt_spot *s, const wt_sodium *na, const double stage[3])
{
    if (!s->lgs) return WT_ERROR(s->ctx, WT_ERR_INVALID, "spot: a sodium profile for a sensor built without one (an NGS)");
    if (!na) return WT_ERROR(s->ctx, WT_ERR_INVALID, "spot: NULL sodium profile");
    if (stage && !(isfinite(stage[0]) && isfinite(stage[1]) && isfinite(stage[2])))
        return WT_ERROR(s->ctx, WT_ERR_INVALID, "spot: focus stage (%g, %g, %g) not finite", stage[0], stage[1], stage[2]);
    const int st = wt_sodium_check_covers(s->ctx, na, s->par.lgs_altitude, "spot: the new sodium profile");
    if (st < 0) return st;
    const int on = stage && (stage[0] != 0.0 || stage[1] != 0.0 || stage[2] != 0.0);
    return build_tables(s, na, on ? stage : NULL);
}

int wt_spot_set_sodium(wt_spot *s, const wt_sodium *na) { return wt_spot_set_sodium_staged(s, na, NULL); }

int wt_spot_alloc(wt_context *ctx, const wt_spot_params *par, int nsub, const double *xc, const double *yc,
                  const float *amp, const double *lit, wt_spot **out)
{
    int st = WT_OK;
    *out = NULL;
    if (!par) return WT_ERROR(ctx, WT_ERR_INVALID, "spot: NULL parameters");
    st = check_params(ctx, par, nsub);
    if (st < 0) return st;
    if (nsub > 0 && (!xc || !yc)) return WT_ERROR(ctx, WT_ERR_INVALID, "spot: NULL subaperture centres");
    wt_spot *s = NULL;
    WT_ALLOC(ctx, s, 1, "spot");
    s->ctx = ctx;
    s->par = *par;
    s->par.sodium = NULL;
    s->lgs = par->sodium != NULL;
    s->nsub = nsub;
    s->np = par->pupil_samples;
    s->N = par->fft_size;
    s->Ns = par->npix;
    s->k = par->cells_per_pixel ? par->cells_per_pixel : 3;
    s->par.cells_per_pixel = s->k;
    s->nthreads = wt_context_threads(ctx);
    if (s->nthreads < 1) s->nthreads = 1;
    const int np = s->np, N = s->N, Ns = s->Ns, k = s->k;
    const double d = par->subap_side, dx = d / np, c = par->pixel / k;
    s->theta_f = par->wavelength / (N * dx);
    s->blur = s->theta_f * s->theta_f / 12 + c * c / 6;

    /* the cell lattice: u = θ/c + k(Ns−1)/2 puts pixel P's centre at u = kP and cell q's at u = q. PSF
     * sample i, a box [a, b] of width θ_f/c around u_i, goes to the lattice points by the overlap of the
     * box with the linear-interpolation tent (1 − |u − q|)₊: w_q = (T(b − q) − T(a − q))/(b − a), T the
     * tent's integral. The tent reproduces constants and linear functions, so each sample's mass and
     * first moment are kept exactly and the image moves smoothly and linearly with the tilt. */
    {
        const double half = 0.5 * k * (Ns - 1), hf = 0.5 * s->theta_f / c;
        const double u0 = (0 - N / 2) * s->theta_f / c + half, u1 = (N - 1 - N / 2) * s->theta_f / c + half;
        s->qmin = (int)floor(u0 - hf);
        const int qmax = (int)ceil(u1 + hf);
        s->M = qmax - s->qmin + 1;
        s->omin = -qmax;
        s->R = (int)ceil(2 * hf) + 3;
        s->Lp = Ns + (s->M - 1) / k;
        WT_ALLOC(ctx, s->rm, (size_t)N * s->R, "spot rebinning cells");
        WT_ALLOC(ctx, s->rw, (size_t)N * s->R, "spot rebinning weights");
        WT_ALLOC(ctx, s->rn, N, "spot rebinning counts");
        for (int i = 0; i < N; i++) {
            double ui = (i - N / 2) * s->theta_f / c + half, a = ui - hf, b = ui + hf;
            int n = 0;
            for (int q = (int)floor(a); q <= (int)ceil(b) && n < s->R; q++) {
                double wq = (tent_int(b - q) - tent_int(a - q)) / (b - a);
                if (wq <= 0) continue;
                s->rm[i * s->R + n] = q - s->qmin;
                s->rw[i * s->R + n] = (float)wq;
                n++;
            }
            s->rn[i] = n;
        }
        /* the same weights listed by cell (ascending sample), for the gathering x pass of image_one */
        WT_ALLOC(ctx, s->gs, s->M + 1, "spot rebinning lists");
        WT_ALLOC(ctx, s->gi, (size_t)N * s->R, "spot rebinning lists");
        WT_ALLOC(ctx, s->gw, (size_t)N * s->R, "spot rebinning lists");
        for (int i = 0; i < N; i++)
            for (int r = 0; r < s->rn[i]; r++) s->gs[s->rm[i * s->R + r] + 1]++;
        for (int m = 0; m < s->M; m++) s->gs[m + 1] += s->gs[m];
        for (int i = 0; i < N; i++)
            for (int r = 0; r < s->rn[i]; r++) {
                const int m = s->rm[i * s->R + r], at = s->gs[m]++;
                s->gi[at] = i, s->gw[at] = s->rw[i * s->R + r];
            }
        for (int m = s->M; m > 0; m--) s->gs[m] = s->gs[m - 1];
        s->gs[0] = 0;
    }

    WT_ALLOC(ctx, s->xs, np, "spot sample offsets");
    for (int i = 0; i < np; i++) s->xs[i] = (i + 0.5 - 0.5 * np) * dx;
    WT_ALLOC(ctx, s->amp, (size_t)nsub * np * np, "spot amplitudes");
    WT_ALLOC(ctx, s->flux, nsub, "spot fluxes");
    WT_ALLOC(ctx, s->scale, nsub, "spot scales");
    for (int is = 0; is < nsub; is++) {
        double a2 = 0;
        for (int j = 0; j < np * np; j++) {
            float a = amp ? amp[(size_t)is * np * np + j] : 1.0f;
            if (!(a >= 0.0f && a <= 1.0f)) {
                st = WT_ERROR(ctx, WT_ERR_INVALID, "spot: amplitude %g of subaperture %d sample %d outside [0, 1]", a,
                              is, j);
                goto fail;
            }
            s->amp[(size_t)is * np * np + j] = a;
            a2 += (double)a * a;
        }
        double f = lit ? lit[is] : a2 / (np * np);
        if (!(f >= 0 && f <= 1)) {
            st = WT_ERROR(ctx, WT_ERR_INVALID, "spot: lit fraction %g of subaperture %d outside [0, 1]", f, is);
            goto fail;
        }
        s->flux[is] = par->photons * f;
        /* Parseval: Σ|FFT U|² = N² Σ|U|² = N² Σ A², whatever the OPD */
        s->scale[is] = a2 > 0 ? (float)(s->flux[is] / ((double)N * N * a2)) : 0.0f;
    }

    /* the per-subaperture source ⊛ pixel tables */
    {
        const int Lp = s->Lp;
        /* padding: image_one reads blocks of SUM_R rows of SUM_W, past the last table's end (zeros, unused) */
        WT_ALLOC(ctx, s->K, (size_t)nsub * k * k * Lp * Lp + (size_t)SUM_R * Lp + SUM_W, "spot source/pixel tables");
        WT_ALLOC(ctx, s->xc, nsub, "spot subaperture centres");
        WT_ALLOC(ctx, s->yc, nsub, "spot subaperture centres");
        if (nsub) memcpy(s->xc, xc, (size_t)nsub * sizeof *xc), memcpy(s->yc, yc, (size_t)nsub * sizeof *yc);
        WT_TRY(build_tables(s, par->sodium, NULL));
    }

    WT_ALLOC(ctx, s->ws, s->nthreads, "spot workspaces");
    for (int t = 0; t < s->nthreads; t++) WT_TRY(ws_init(s, &s->ws[t]));
    {
        /* Plans on workspace 0; every workspace's field has the same (64-byte) alignment, so
         * fftwf_execute_dft may run them on any thread's arrays (FFTW's new-array rule). */
        fftwf_complex *f = s->ws[0].field;
        int n[1] = {N};
        s->rows = fftwf_plan_many_dft(1, n, np, f, NULL, 1, N, f, NULL, 1, N, FFTW_FORWARD, FFTW_ESTIMATE);
        s->cols = fftwf_plan_many_dft(1, n, N, f, NULL, N, 1, f, NULL, N, 1, FFTW_FORWARD, FFTW_ESTIMATE);
        s->otf_fwd = fftwf_plan_dft_2d(N, N, f, f, FFTW_FORWARD, FFTW_ESTIMATE);
        s->otf_bwd = fftwf_plan_dft_2d(N, N, f, f, FFTW_BACKWARD, FFTW_ESTIMATE);
        if (!s->rows || !s->cols || !s->otf_fwd || !s->otf_bwd) {
            st = WT_ERROR(ctx, WT_ERR_LIBRARY, "spot: fftwf_plan_many_dft(%d) returned NULL", N);
            goto fail;
        }
    }
    *out = s;
    return WT_OK;
fail:
    wt_spot_free(s);
    return st;
}

/* One subaperture: OPD (float or double, one of them non-NULL; or the workspace's double array) → image. */
WT_CPU_CLONES
void wt_spot__image_one(const wt_spot *s, int is, const float *opdf, const double *opdd, const float *otf, workspace *w,
                        float *img, const float *cells_in, float *cells_out)
{
    const int np = s->np, N = s->N, Ns = s->Ns, M = s->M, k = s->k, Lp = s->Lp, R = s->R;
    memset(img, 0, (size_t)Ns * Ns * sizeof *img);
    const float sc = s->scale[is];
    if (sc == 0.0f) return;
    const float *C = cells_in;
    if (!cells_in) {
        const float *A = s->amp + (size_t)is * np * np;
        fftwf_complex *F = w->field;
        const double kw = 2.0 * M_PI / s->par.wavelength;
        /* U on the first n_p × n_p corner of the N × N array (the position of the pupil in the padded array
         * only multiplies the FFT by a phase ramp, which |·|² removes) */
        memset(F, 0, (size_t)N * N * sizeof *F);
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++) {
                const float a = A[i + np * j];
                if (a == 0.0f) continue;
                /* phase reduced to [−π, π] in double, then float sin/cos (float32 is the field's precision) */
                double ph = kw * (opdf ? (double)opdf[i + np * j] : opdd[i + np * j]);
                ph -= 2.0 * M_PI * nearbyint(ph * (0.5 / M_PI));
                const float phf = (float)ph;
                F[i + N * j][0] = a * cosf(phf);
                F[i + N * j][1] = a * sinf(phf);
            }
        fftwf_execute_dft(s->rows, F, F);
        fftwf_execute_dft(s->cols, F, F);
        if (otf) {
            /* the mean seeing (seeing.h): |F|² is the DFT of the field's autocorrelation; its lag-u term is
             * multiplied by W(u) (real, even: the result stays real), then transformed back */
            for (size_t q = 0; q < (size_t)N * N; q++) F[q][0] = F[q][0] * F[q][0] + F[q][1] * F[q][1], F[q][1] = 0.0f;
            fftwf_execute_dft(s->otf_bwd, F, F);
            const float inv = 1.0f / ((float)N * N);
            for (size_t q = 0; q < (size_t)N * N; q++) F[q][0] *= otf[q] * inv, F[q][1] *= otf[q] * inv;
            fftwf_execute_dft(s->otf_fwd, F, F);
            /* the real part is the PSF; a magnitude with zero phase keeps the |·|² below */
            for (size_t q = 0; q < (size_t)N * N; q++) F[q][0] = sqrtf(fmaxf(F[q][0], 0.0f)), F[q][1] = 0.0f;
        }
        /* PSF sample (i, j) at angle ((i − N/2)θ_f, (j − N/2)θ_f): frequency (i + N/2) mod N */
        float *P = w->psf;
        for (int j = 0; j < N; j++) {
            const fftwf_complex *Fr = F + (size_t)N * ((j + N / 2) % N);
            float *Pr = P + (size_t)N * j;
            for (int i = 0; i < N / 2; i++) {
                const float *z = Fr[i + N / 2], *z2 = Fr[i];
                Pr[i] = sc * (z[0] * z[0] + z[1] * z[1]);
                Pr[i + N / 2] = sc * (z2[0] * z2[0] + z2[1] * z2[1]);
            }
        }
        /* overlap rebinning: x (rows of P → tmp[m + M j]), then y (tmp → cells[mx + M my]). The x pass
         * gathers per cell (its samples in ascending order: the sums and their order are those of scattering
         * each sample in turn, with no store-to-load chain between neighbouring samples). */
        float *T = w->tmp, *Cw = w->cells;
        memset(Cw, 0, (size_t)M * M * sizeof *Cw);
        for (int j = 0; j < N; j++) {
            const float *Pr = P + (size_t)N * j;
            float *Tr = T + (size_t)M * j;
            for (int m = 0; m < M; m++) {
                float a = 0.0f;
                for (int g = s->gs[m]; g < s->gs[m + 1]; g++) a += s->gw[g] * Pr[s->gi[g]];
                Tr[m] = a;
            }
        }
        for (int j = 0; j < N; j++)
            for (int r = 0; r < s->rn[j]; r++) {
                const float wv = s->rw[j * R + r];
                float *Cr = Cw + (size_t)M * s->rm[j * R + r];
                const float *Tr = T + (size_t)M * j;
                for (int m = 0; m < M; m++) Cr[m] += wv * Tr[m];
            }
        if (cells_out) memcpy(cells_out, Cw, (size_t)M * M * sizeof *Cw);
        C = Cw;
    }
    /* image(P) = Σ_q cells_q K(kP − q): cell m ↦ e = M−1−m = k·e1 + e0, table (phase e0) at P + e1. The
     * non-zero cells are listed with their table offsets, then each block of SUM_W pixels of a row sums
     * over the list in registers: per pixel the same additions in the same order (cells by (my, mx)) as
     * accumulating cell by cell into the image, without its loads and stores. */
    const float *K = s->K + (size_t)is * k * k * Lp * Lp;
    float *cv = w->cv;
    int *co = w->co, nc = 0;
    for (int my = 0; my < M; my++) {
        const int ey = M - 1 - my, e1y = ey / k, e0y = ey % k;
        for (int mx = 0; mx < M; mx++) {
            const float v = C[mx + (size_t)M * my];
            if (v == 0.0f) continue;
            const int ex = M - 1 - mx, e1x = ex / k, e0x = ex % k;
            cv[nc] = v;
            co[nc++] = (e0x + k * e0y) * Lp * Lp + e1x + Lp * e1y;
        }
    }
    for (int py = 0; py < Ns; py += SUM_R)
        for (int p0 = 0; p0 < Ns; p0 += SUM_W) {
            /* SUM_R rows × two 8-float vectors (GCC vector extension: the pixels are the vector lanes, not
             * the cells); rows past Ns read the table's padding and are not stored */
            v8f a[SUM_R][2];
            memset(a, 0, sizeof a);
            const float *Kp = K + (size_t)Lp * py + p0;
            for (int c = 0; c < nc; c++) {
                const float v = cv[c], *Kr = Kp + co[c];
                for (int r = 0; r < SUM_R; r++) {
                    v8f k0, k1;
                    memcpy(&k0, Kr + (size_t)Lp * r, sizeof k0);
                    memcpy(&k1, Kr + (size_t)Lp * r + 8, sizeof k1);
                    a[r][0] += v * k0;
                    a[r][1] += v * k1;
                }
            }
            const int nw = Ns - p0 < SUM_W ? Ns - p0 : SUM_W;
            for (int r = 0; r < SUM_R && py + r < Ns; r++) {
                float acc[SUM_W];
                memcpy(acc, a[r], sizeof acc);
                float *Ir = img + (size_t)Ns * (py + r) + p0;
                for (int q = 0; q < nw; q++) Ir[q] = acc[q];
            }
        }
}


static int images(const wt_spot *s, const float *opdf, const double *opdd, float *img)
{
    if (!img || (!opdf && !opdd)) return WT_ERROR(s->ctx, WT_ERR_INVALID, "wt_spot_image: NULL array");
    const int nth = s->nthreads;
    const size_t n2 = (size_t)s->np * s->np, ns2 = (size_t)s->Ns * s->Ns;
#pragma omp parallel for schedule(dynamic, 16) num_threads(nth) if (nth > 1 && s->nsub > 1 && !omp_in_parallel())
    for (int is = 0; is < s->nsub; is++)
        wt_spot__image_one(s, is, opdf ? opdf + is * n2 : NULL, opdd ? opdd + is * n2 : NULL, NULL, &s->ws[wt_thread_id()],
                           img + is * ns2, NULL, NULL);
    return WT_OK;
}

int wt_spot_image(const wt_spot *s, const float *opd, float *img) { return images(s, opd, NULL, img); }
int wt_spot_image_d(const wt_spot *s, const double *opd, float *img) { return images(s, NULL, opd, img); }

void wt_spot_truncation(const wt_spot *s, const float *img, double *trunc)
{
    const size_t ns2 = (size_t)s->Ns * s->Ns;
    for (int is = 0; is < s->nsub; is++) {
        double sum = 0;
        for (size_t p = 0; p < ns2; p++) sum += img[is * ns2 + p];
        trunc[is] = s->flux[is] > 0 ? 1.0 - sum / s->flux[is] : 0.0;
    }
}

double wt_spot_flux(const wt_spot *s, int isub) { return s->flux[isub]; }

double wt_spot_blur(const wt_spot *s)
{
    const double su = s->par.uplink_fwhm / (2.0 * sqrt(2.0 * log(2.0)));
    return s->blur > su * su ? s->blur - su * su : 0.0;
}
int wt_spot_nsub(const wt_spot *s) { return s->nsub; }
int wt_spot_npix(const wt_spot *s) { return s->Ns; }

size_t wt_spot_memory(const wt_spot *s)
{
    size_t b = sizeof *s;
    b += (size_t)s->nsub * (sizeof(double) + sizeof(float) + (size_t)s->np * s->np * sizeof(float));
    b += (size_t)s->nsub * s->k * s->k * s->Lp * s->Lp * sizeof(float);
    b += (size_t)s->nthreads * ws_bytes(s);
    if (s->rcells) b += (size_t)s->nsub * 5 * s->M * s->M * sizeof(float);
    return b;
}

void wt_spot_cost(const wt_spot *s, double *flops, double *bytes)
{
    const double N = s->N, np = s->np, M = s->M, Ns = s->Ns;
    /* field (sincos ~ 20 flops), 1-D FFT batches 5 n log2 n each, |·|², rebinning, the direct sum */
    double f = 20 * np * np + 5 * N * log2(N) * (np + N) + 3 * N * N + 2 * 2 * N * N + 2 * 2 * M * N + 2 * M * M * Ns * Ns;
    *flops = f;
    *bytes = (double)s->k * s->k * s->Lp * s->Lp * sizeof(float) + np * np * (sizeof(float) * 2) + Ns * Ns * sizeof(float);
}

/* ---- noise ---- */

double wt_poisson(wt_rng *rng, double mu)
{
    if (!(mu > 0)) return 0.0;
    if (mu < 10.0) {
        /* inversion by sequential search: k with F(k−1) < u ≤ F(k); p_k = p_{k−1}·mu/k */
        double u = wt_rng_uniform(rng);
        /* k = 0 when u ≤ e^{−mu}; e^{−mu} ≥ 1 − mu, so u below 1 − mu (less a margin for the rounding of
         * both sides) decides it without the exp: the same deviate, most pixels of a faint image */
        if (u <= (1.0 - mu) * (1.0 - 0x1p-48)) return 0.0;
        double p = exp(-mu), F = p;
        double k = 0;
        while (u > F && k < 1000) {
            k += 1;
            p *= mu / k;
            F += p;
        }
        return k;
    }
    /* PTRS (Hörmann 1993): transformed rejection with squeeze; constants from the paper */
    const double smu = sqrt(mu), lmu = log(mu);
    const double b = 0.931 + 2.53 * smu, a = -0.059 + 0.02483 * b;
    const double inv_alpha = 1.1239 + 1.1328 / (b - 3.4), vr = 0.9277 - 3.6224 / (b - 2);
    for (;;) {
        double U = wt_rng_uniform(rng) - 0.5, V = wt_rng_uniform(rng);
        double us = 0.5 - fabs(U);
        double k = floor((2 * a / us + b) * U + mu + 0.43);
        if (us >= 0.07 && V <= vr) return k;
        if (k < 0 || (us < 0.013 && V > us)) continue;
        int sgn;
        double lg = lgamma_r(k + 1, &sgn);
        if (log(V) + log(inv_alpha) - log(a / (us * us) + b) <= -mu + k * lmu - lg) return k;
    }
}

int wt_spot_noise(const wt_spot *s, uint64_t seed, uint64_t base_stream, float *img)
{
    if (base_stream >= (UINT64_C(1) << 43))
        return WT_ERROR(s->ctx, WT_ERR_INVALID, "wt_spot_noise: base stream %llu >= 2^43 (the stream rule of spot.h)",
                        (unsigned long long)base_stream);
    const int nth = s->nthreads;
    const size_t ns2 = (size_t)s->Ns * s->Ns;
    const double B = s->par.background, se = s->par.read_noise;
#pragma omp parallel for schedule(dynamic, 64) num_threads(nth) if (nth > 1 && s->nsub > 1 && !omp_in_parallel())
    for (int is = 0; is < s->nsub; is++) {
        wt_rng r;
        wt_rng_init(&r, seed, WT_SPOT_STREAM(base_stream, is));
        float *I = img + is * ns2;
        for (size_t p = 0; p < ns2; p++) {
            double v = wt_poisson(&r, (double)I[p] + B) - B;
            if (se > 0) v += se * wt_rng_normal(&r);
            I[p] = (float)v;
        }
    }
    return WT_OK;
}
