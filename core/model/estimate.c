/* core/model/estimate.c: resource estimates from the configuration (see estimate.h for the model and
 * its calibration). */
#include "estimate.h"

#include <math.h>
#include <stdarg.h>
#include <string.h>
#include <unistd.h>

#include "reconstructor.h"

#define BASE_BYTES 15e6       /* the process before any work: libraries, HDF5, OpenBLAS buffers (measured) */
#define SIM_BASE_BYTES 6e6    /* sim on top of that: FFTW plans, OpenMP pools, small arrays (measured) */
#define NS_POINT 4.0e-9       /* s per bilinear read (fine point x layer x line of sight), one thread */
#define FLOP_RATE 8.0e9       /* reconstructor flops per s, one thread (stencil-bound; §2: 30 Mflop in 3.2 ms) */
#define STREAM_RATE 28e9      /* bytes per s of a float32 GEMV (§2: sgemv of R at 28.1 GB/s, 2 threads) */
#define DENSE_RATE 55e9      /* flops per s of the dense path, 2 threads: 17 Tflop of dpotrf + dpotrs in 299 s (results §23) */
#define SOLVE_RATE 25e9       /* flops per s of CHOLMOD's supernodal solves (§4: 53 s for 10027 columns) */
#define NORMAL_NS 2.0e-6      /* s per non-zero of N formed (§4: 1.3–2.4 µs) */
/* Diffractive sensors (core/optics/spot.h; calibrated by `make bench-spot` on the E-ELT LGS, 2 threads): */
#define SPOT_TABLE_NS 30e-9   /* s of set-up per float of a subaperture's kernel table (2.99 s for 30672 × 3249) */
#define SPOT_FLOP_RATE 8e9    /* image flops (wt_spot_cost) per s, 2 threads (0.126 Mflop in ~15 µs of wall) */
#define SPOT_NOISE_NS 30e-9   /* s per pixel of Poisson + Gaussian noise, 2 threads */
#define SPOT_MC_NS 95e-9      /* s per pixel draw of the Monte-Carlo calibration, 2 threads (~190 thread-ns each, `make bench-spot`) */
/* the long-exposure PSFs (sim/psf.c), one thread, measured at the E-ELT size (336 pupil points across, N = 672,
 * 64 pixels: ~30 ms per frame taken for 25 directions when quiet, 60-80 ms at a load average of 10) */
#define PSF_POINT_NS 8e-9     /* s per pupil point: phase, reduction, sin/cos, store */
#define PSF_FFT_RATE 20e9     /* FFT flops (5 N log2 N per transform) per s, float32 */
#define PSF_TOUCH_NS 2e-9     /* s per complex sample zeroed or gathered (the padding, the kept columns) */

typedef struct {
    double nvalid, ncorners, nslopes, nlgs_slopes, nact, nfine, nlos, screen, neval, nsensors;
} sizes;

static double sq(double x) { return x * x; }

static void derive(const wt_config *c, sizes *s)
{
    const double n = c->lgs_wfs.subapertures, ring = M_PI / 4.0 * (1.0 - sq(c->obstruction));
    s->nvalid = ring * n * n;
    s->ncorners = ring * sq(n + 1);
    s->nlgs_slopes = 2.0 * c->nlgs * s->nvalid;
    s->nslopes = s->nlgs_slopes;
    for (int k = 0; k < c->nngs; k++) s->nslopes += 2.0 * sq(c->ngs_subapertures[k]);
    s->nact = 0.0;
    for (int k = 0; k < c->ndms; k++) {
        /* active within D/2 + h tan θc, plus the guard rings (core/op/dm.c), at most the whole grid */
        double r = 0.5 * c->diameter + c->dm_altitude[k] * tan(c->dm_field_radius) + c->dm_guard_rings * c->dm_pitch[k];
        s->nact += fmin(M_PI * sq(r / c->dm_pitch[k]), sq(c->dm_actuators[k]));
    }
    s->nfine = sq(n * c->points_per_subaperture + 1);
    s->neval = sq(c->eval_grid);
    s->nsensors = c->nlgs + c->nngs;
    s->nlos = s->nsensors + s->neval;
    /* the screen side of sim/loop.c: twice the widest footprint at the top layer */
    double eval = 0.5 * (c->eval_grid - 1) * c->eval_spacing * M_SQRT2;
    double th = fmax(fmax(c->nlgs ? c->lgs_radius : 0.0, c->nngs ? c->ngs_radius : 0.0), eval);
    double delta = c->diameter / (n * c->points_per_subaperture);
    s->screen = fmax(32.0, ceil(2.0 * (c->diameter + 2.0 * c->layer_altitude[c->nlayers - 1] * th + 2.0 * delta) / delta));
}

static void term(wt_estimate *e, double bytes, const char *what, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static void term(wt_estimate *e, double bytes, const char *what, const char *fmt, ...)
{
    e->bytes += bytes;
    if (e->nterms == WT_ESTIMATE_TERMS) return;
    snprintf(e->term[e->nterms].what, sizeof e->term[0].what, "%s", what);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->term[e->nterms].keys, sizeof e->term[0].keys, fmt, ap);
    va_end(ap);
    e->term[e->nterms++].bytes = bytes;
}

/* The diffractive sensors of one type (LGS or NGS): bytes of the spot tables and of the rest, set-up seconds,
 * and seconds per frame. Per subaperture, as core/optics/spot.c and core/model/sensing.c allocate: the kernel
 * table of k² Lp² floats (Lp = Ns + (M − 1)/k, M the rebinning lattice over the FFT field: spot.c's qmin..qmax)
 * and n_p² amplitudes (the spot); amplitudes, OPD, I0 and the image (the sensing, n_p² and Ns² floats); the
 * MF's 2 Ns² rows; ∂I0/∂θx,y (2 Ns² floats, freed after each sensor's set-up: one sensor's count). Set-up:
 * the tables, 5 images (I0 and the central differences), the Monte Carlo when asked. A frame: one image, its
 * noise, the centroider (2 Ns² multiply-adds at most). */
static void diffractive_sensors(const wt_config *c, int lgs, double *tables, double *rest, double *setup,
                                double *frame)
{
    const wt_sensor_config *w = lgs ? &c->lgs_wfs : &c->ngs_wfs;
    *tables = *rest = *setup = *frame = 0.0;
    if (w->model != WT_WFS_DIFFRACTIVE || (lgs ? c->nlgs : c->nngs) == 0) return;
    const double ring = M_PI / 4.0 * (1.0 - sq(c->obstruction));
    const int np = w->pupil_samples, N = w->fft_size, Ns = w->pixels, k = w->cells_per_pixel > 0 ? w->cells_per_pixel : 3;
    for (int g = 0; g < (lgs ? 1 : c->nngs); g++) {
        const int n = lgs ? w->subapertures : c->ngs_subapertures[g];
        const double nsub = (lgs ? c->nlgs : 1) * (n > 2 ? ring * n * n : (double)n * n);
        const double d = c->diameter / n, theta_f = w->wavelength / (N * d / np), cell = w->pixel / k;
        const double half = 0.5 * k * (Ns - 1), hf = 0.5 * theta_f / cell;
        const double qmin = floor((0 - N / 2) * theta_f / cell + half - hf);
        const double qmax = ceil((N - 1 - N / 2) * theta_f / cell + half + hf);
        const double M = qmax - qmin + 1, Lp = Ns + floor((M - 1) / k), tab = (double)k * k * Lp * Lp;
        *tables += nsub * (4.0 * tab + 4.0 * np * np + 12.0);
        /* lgs.wfs.reference = oracle: the reference's five images' rebinned cells kept (spot.h) */
        if (lgs && c->lgs_reference == 1) *tables += nsub * 5.0 * 4.0 * M * M;
        /* = pixels: the accumulator ((Ns + 8)² floats) and the anchor (2 Ns² floats) per subaperture */
        if (lgs && c->lgs_reference == 2) *tables += nsub * 4.0 * ((Ns + 8.0) * (Ns + 8.0) + 2.0 * Ns * Ns);
        *rest += nsub * (8.0 * np * np + 8.0 * Ns * Ns + (w->centroider == 2 ? 8.0 * Ns * Ns : 0.0) + 150.0) +
                 8.0 * Ns * Ns * nsub / (lgs ? c->nlgs : 1);
        const double flops = 20.0 * np * np + 5.0 * N * log2(N) * (np + N) + 7.0 * N * N + 4.0 * M * N +
                             2.0 * M * M * Ns * Ns; /* wt_spot_cost */
        *setup += nsub * (SPOT_TABLE_NS * tab + 5.0 * flops / SPOT_FLOP_RATE +
                          (w->noise_calibration == 1 ? SPOT_MC_NS * w->calibration_draws * Ns * Ns : 0.0));
        *frame += nsub * (flops / SPOT_FLOP_RATE + (c->noise ? SPOT_NOISE_NS * Ns * Ns : 0.0) +
                          4.0 * Ns * Ns / SPOT_FLOP_RATE);
    }
}

static double unknowns(const wt_recon_variant_config *v)
{
    double u = 0.0;
    for (int l = 0; l < v->nlayers; l++) u += sq(v->size[l]);
    return u;
}

/* The matrix-free reconstructor: its vectors and stencils (wt_tomography_bytes), and its flops per frame
 * (wt_tomography_cost: DWT 16 N per coefficient and level, 16 flops per corner point and layer and sensor
 * both ways, per iteration, plus the fitting's 25-direction projections for cg9). */
static void tomography(const wt_config *c, const sizes *s, int kind, int iterations, wt_estimate *e, double *flops)
{
    const wt_recon_variant_config *v = kind == WT_RECON_CG9 ? &c->cg9 : &c->pcg3;
    const char *name = kind == WT_RECON_CG9 ? "cg9" : "pcg3";
    double n = unknowns(v), L = v->nlayers;
    term(e, 88.0 * n + 16.0 * s->nslopes + 24.0 * s->ncorners * s->nsensors * L, "reconstructor vectors and stencils",
         "recon.%s.layer_size (%.3g unknowns), lgs.wfs.subapertures, lgs.count", name, n);
    /* (the fourier kind solves for the layers' values: no DWT pair, wt_tomography_space) */
    const double dwt = v->preconditioner == WT_PRECOND_FOURIER ? 0.0 : 2.0 * 16.0 * c->wavelet_order * n * 4.0 / 3.0;
    double per_iter = dwt + 32.0 * s->ncorners * L * s->nsensors + 22.0 * s->nslopes;
    *flops = per_iter * ((iterations > 0 ? iterations : v->iterations) + 1);
    if (kind == WT_RECON_CG9) {
        double samples = sq(c->lgs_wfs.subapertures * (v->fit_sampling > 0 ? v->fit_sampling : 1) + 1);
        term(e, 8.0 * s->neval * samples * (2.0 + c->ndms), "fitting maps and projections",
             "evaluation.grid, lgs.wfs.subapertures, recon.cg9.fit_sampling");
        if (v->fit_solver == 1) {
            /* the Cholesky fitting: L of ~3.5 nact^1.5 entries (E-ELT 3.5e6 for 10027 actuators, demo 8.6e4 for
             * 759), CHOLMOD's copy with ~30 % supernodal padding plus the solves' packed copy, and the assembly's
             * N and sparse products (~150 entries an actuator, 3 copies at the peak); a frame: the right-hand side
             * and 2 passes over L */
            const double lnz = 3.5 * s->nact * sqrt(s->nact);
            term(e, lnz * (1.3 * 8.0 + (v->fit_factor_precision ? 4.0 : 8.0)) + 3.0 * 16.0 * 150.0 * s->nact,
                 "fitting Cholesky factor", "dm.actuators, dm.pitch_m, recon.cg9.fit_solver");
            *flops += 2.0 * 8.0 * s->neval * samples * c->ndms + 4.0 * lnz;
        } else
            *flops += (v->fit_iterations + 1) * 2.0 * 8.0 * s->neval * samples * c->ndms;
    }
}

void wt_estimate_resources(const wt_config *c, const wt_estimate_request *req, wt_estimate *e)
{
    sizes s;
    derive(c, &s);
    memset(e, 0, sizeof *e);
    const double frames = req->frames > 0 ? (double)req->frames : c->frames;
    const double mvm_bytes = 4.0 * s.nact * (s.nslopes + s.nact);
    term(e, BASE_BYTES, "the process (libraries)", "-");
    /* the system: Shack-Hartmann operators and masks, ~100 B per subaperture and sensor */
    term(e, 100.0 * s.nvalid * s.nsensors + 64.0 * s.nact, "system geometry", "lgs.wfs.subapertures, lgs.count");
    /* diffractive sensors: built with the system, so by every command */
    double tab[2], rest[2], setup[2], frame[2];
    diffractive_sensors(c, 1, &tab[0], &rest[0], &setup[0], &frame[0]);
    diffractive_sensors(c, 0, &tab[1], &rest[1], &setup[1], &frame[1]);
    if (tab[0] + tab[1] > 0.0) {
        term(e, tab[0] + tab[1], "diffractive spot tables",
             "*.wfs.model = diffractive: lgs.count x lgs.wfs.subapertures, *.wfs.pixels, cells_per_pixel, pixel_arcsec, "
             "pupil_samples, fft_size");
        term(e, rest[0] + rest[1], "diffractive images and filters",
             "*.wfs.pixels, pupil_samples, centroider (mf: 2 Ns^2 per subaperture)");
    }
    const double sensing_setup = setup[0] + setup[1], sensing_frame = frame[0] + frame[1];
    double flops = 0.0;
    if (req->task == WT_TASK_SIM) {
        /* the screens (their FFT work space, 3 more screens, is freed before the maps below exist) */
        term(e, 8.0 * s.screen * s.screen * c->nlayers, "phase screens",
             "atmosphere.altitudes_m (%d layers), lgs.wfs.subapertures x sim.points_per_subaperture, telescope.diameter_m,"
             " the field (lgs/ngs.radius_arcsec, evaluation.*): %.0f points per side", c->nlayers, s.screen);
        term(e, 8.0 * s.nfine * s.nlos, "OPD maps",
             "lgs.wfs.subapertures x sim.points_per_subaperture (%.3g fine points), %.0f lines of sight (lgs.count, "
             "ngs.*, evaluation.grid)", s.nfine, s.nlos);
        /* Â: ~16 actuators per slope and DM (4 Fried corners x 4 bilinear weights), 12 B each */
        term(e, 192.0 * s.nslopes * c->ndms, "DM-to-slope interaction Â", "lgs.wfs.subapertures, lgs.count, dm.altitudes_m");
        term(e, SIM_BASE_BYTES, "FFTW and thread pools", "-");
        term(e, frames * (16.0 + 4.0 * s.neval), "per-frame results", "loop.frames (%.0f), evaluation.grid", frames);
        e->seconds = frames * NS_POINT * s.nfine * (s.nlos * c->nlayers + s.neval * c->ndms);
        if (c->psf_interval > 0) {
            /* pupil points across (nr rows), the padded N ≥ 2 nr, the kept n pixels; images taken */
            const double nr = c->lgs_wfs.subapertures * c->points_per_subaperture, N = 2.0 * nr;
            const double n = fmin((double)c->psf_pixels, N), taken = ceil((frames - c->settle_frames) / c->psf_interval);
            double bands = 1.0; /* the evaluation wavelength's and each other of sim.psf_wavelengths_nm */
            for (int k = 0; k < c->npsf_wavelengths; k++) bands += c->psf_wavelength[k] != c->eval_wavelength;
            term(e, bands * (12.0 * s.neval * n * n + 2.0 * 8.0 * (nr + n) * N), "long-exposure PSFs",
                 "sim.psf_pixels (%.0f), evaluation.grid, sim.points_per_subaperture, 2 threads' FFT rows%s", n,
                 bands > 1.0 ? ", sim.psf_wavelengths_nm (bands)" : "");
            e->seconds += bands * fmax(taken, 0.0) * s.neval *
                          (PSF_POINT_NS * M_PI / 4.0 * nr * nr + 5.0 * N * log2(N) * (nr + n) / PSF_FFT_RATE +
                           PSF_TOUCH_NS * (nr + n) * N);
        }
    }
    if (req->task == WT_TASK_SIM || req->task == WT_TASK_RUN) {
        if (req->recon == WT_RECON_MVM) {
            term(e, mvm_bytes, "control matrix R, RÂ (float32)", "lgs.wfs.subapertures, lgs.count, dm.actuators");
            e->seconds += frames * mvm_bytes / STREAM_RATE;
        } else if (req->recon == WT_RECON_PCG3 || req->recon == WT_RECON_CG9) {
            tomography(c, &s, req->recon, req->iterations, e, &flops);
            e->seconds += frames * flops / FLOP_RATE;
        }
    }
    if (req->task == WT_TASK_INFO) {
        wt_estimate a, b;
        memset(&a, 0, sizeof a), memset(&b, 0, sizeof b);
        tomography(c, &s, WT_RECON_PCG3, req->iterations, &a, &flops);
        tomography(c, &s, WT_RECON_CG9, req->iterations, &b, &flops);
        const wt_estimate *big = a.bytes > b.bytes ? &a : &b; /* one variant at a time */
        for (int k = 0; k < big->nterms; k++) term(e, big->term[k].bytes, big->term[k].what, "%s", big->term[k].keys);
        /* the symbolic count of Ã: ~60 J non-zeros per slope and layer, ~0.2 µs each */
        e->seconds = 2e-7 * 60.0 * c->wavelet_levels * s.nlgs_slopes * (c->pcg3.nlayers + c->cg9.nlayers);
    }
    if (req->task == WT_TASK_BUILD) {
        const wt_recon_variant_config *v = req->recon == WT_RECON_CG9 ? &c->cg9 : &c->pcg3;
        const char *name = req->recon == WT_RECON_CG9 ? "cg9" : "pcg3";
        double n = unknowns(v), nnz_l = 10.5 * pow(n, 1.5), nnz_n = nnz_l / 2.5;
        /* the full prior makes N dense: n² doubles, factorised and solved by LAPACK */
        const int dense = v->prior == WT_CFG_PRIOR_FULL;
        if (dense) nnz_l = 0.5 * n * n;
        /* two phases: assembling N (Lᵀ Ã_LGS and its transpose, ~60 J non-zeros per LGS slope and layer,
         * 12 B each, with N) and solving (R, RÂ, the factor, the blocks); the larger one is the peak */
        double nnz_a = 60.0 * c->wavelet_levels * s.nlgs_slopes * v->nlayers;
        double assemble = 24.0 * nnz_a + 12.0 * nnz_n;
        double factor = dense ? 8.0 * n * n + 12.0 * nnz_n : 12.0 * nnz_l + 2.0 * 12.0 * nnz_n;
        double blocks = 8.0 * n * (256.0 + 4.0 * c->nlgs + 8.0) + (req->recon == WT_RECON_CG9 ? 8.0 * s.nact * s.nact : 0.0);
        if (assemble > mvm_bytes + factor + blocks)
            term(e, assemble, "assembling Ã and N", "recon.%s.layer_size (%.3g unknowns), lgs.wfs.subapertures, lgs.count,"
                 " recon.wavelet_levels: ~%.3g non-zeros", name, n, nnz_a);
        else {
            term(e, mvm_bytes, "R and RÂ (float32)", "lgs.wfs.subapertures, lgs.count, dm.actuators (%.0f x %.0f)",
                 s.nact, s.nslopes);
            if (dense)
                term(e, factor, "dense N and its Cholesky factor", "recon.%s.layer_size (%.3g unknowns), recon.%s.prior "
                     "(\"full\": N dense; \"paper\" keeps it sparse)", name, n, name);
            else
                term(e, factor, "Cholesky factor and N", "recon.%s.layer_size (%.3g unknowns: factor ~%.3g non-zeros)",
                     name, n, nnz_l);
            term(e, blocks, "solve blocks, low rank, fitting", "recon.%s.layer_size, dm.actuators", name);
        }
        e->seconds = dense ? (n * n * n / 3.0 + 2.0 * n * n * s.nact) / DENSE_RATE + NORMAL_NS * nnz_n
                           : 4.0 * s.nact * nnz_l / SOLVE_RATE + NORMAL_NS * nnz_n;
        if (req->recon == WT_RECON_CG9) e->seconds += 8.0 * sq(s.nact) * s.nact / 3.0 / SOLVE_RATE; /* the fitting */
    }
    /* the diffractive sensors' set-up (every command), their images in every simulated frame */
    e->seconds += sensing_setup + (req->task == WT_TASK_SIM ? frames * sensing_frame : 0.0);
}

void wt_estimate_add(wt_estimate *total, const wt_estimate *e)
{
    double t = total->seconds + e->seconds;
    if (e->bytes > total->bytes) *total = *e;
    total->seconds = t;
}

static void human_time(char *buf, size_t n, double s)
{
    if (s < 120) snprintf(buf, n, "%.3g s", s);
    else if (s < 7200) snprintf(buf, n, "%.3g min", s / 60);
    else if (s < 2 * 86400) snprintf(buf, n, "%.3g h", s / 3600);
    else snprintf(buf, n, "%.3g days", s / 86400);
}

/* The 1-minute load average over the online cores, or a negative value when /proc/loadavg cannot be read. */
static double load_per_core(int *cores)
{
    FILE *f = fopen("/proc/loadavg", "r");
    double load = -1.0;
    if (!f) return -1.0;
    if (fscanf(f, "%lf", &load) != 1) load = -1.0;
    fclose(f);
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    *cores = n > 0 ? (int)n : 1;
    return load < 0.0 ? -1.0 : load / *cores;
}

/* Above this load per core the estimate, calibrated on an idle machine, is said to be a lower bound: the run gets
 * only a share of the cores (with a load of L per core, about 1/L of them; docs/results.md has a measured case). */
#define WT_ESTIMATE_BUSY_LOAD 0.5

void wt_estimate_print(FILE *f, const char *prefix, const wt_estimate *e)
{
    char t[32], busy[128] = "";
    human_time(t, sizeof t, e->seconds);
    int cores = 1;
    const double load = load_per_core(&cores);
    if (load > WT_ESTIMATE_BUSY_LOAD)
        snprintf(busy, sizeof busy, "; a lower bound here: load average %.1f on %d core%s", load * cores, cores,
                 cores == 1 ? "" : "s");
    fprintf(f, "%sestimated peak memory %.3g GB, run time %s (idle 2-core reference machine%s)\n", prefix, e->bytes / 1e9,
            t, busy);
    int used[WT_ESTIMATE_TERMS] = {0};
    for (int r = 0; r < e->nterms; r++) {
        int best = -1;
        for (int k = 0; k < e->nterms; k++)
            if (!used[k] && (best < 0 || e->term[k].bytes > e->term[best].bytes)) best = k;
        used[best] = 1;
        fprintf(f, "%s  %9.3g GB  %-36s %s\n", prefix, e->term[best].bytes / 1e9, e->term[best].what, e->term[best].keys);
    }
}

double wt_memory_available(void)
{
    FILE *f = fopen("/proc/meminfo", "r");
    char line[256];
    double kb = 0.0;
    if (!f) return 0.0;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "MemAvailable: %lf kB", &kb) == 1) break;
    fclose(f);
    return kb * 1024.0;
}

int wt_estimate_check(wt_context *ctx, const char *what, const wt_estimate *e, double limit, const char *source)
{
    if (!(limit > 0.0) || e->bytes <= limit) return WT_OK;
    /* the two largest terms that keys drive (not the process's base) */
    int a = -1, b = -1;
    for (int k = 0; k < e->nterms; k++) {
        if (!strcmp(e->term[k].keys, "-")) continue;
        if (a < 0 || e->term[k].bytes > e->term[a].bytes) b = a, a = k;
        else if (b < 0 || e->term[k].bytes > e->term[b].bytes) b = k;
    }
    char more[512] = "";
    if (b >= 0) snprintf(more, sizeof more, "; then %s %.3g GB (%s)", e->term[b].what, e->term[b].bytes / 1e9, e->term[b].keys);
    return WT_ERROR(ctx, WT_ERR_NOMEM,
                    "%s: estimated peak memory %.3g GB, more than the %.3g GB %s; the largest part: %s %.3g GB, driven by "
                    "%s%s (see --dry-run)",
                    what, e->bytes / 1e9, limit / 1e9, source, a >= 0 ? e->term[a].what : "?",
                    a >= 0 ? e->term[a].bytes / 1e9 : 0.0, a >= 0 ? e->term[a].keys : "?", more);
}
