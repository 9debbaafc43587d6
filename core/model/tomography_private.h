/* core/model/tomography_private.h: the tomography object's layout, shared by tomography.c (the object: set-up,
 * workspaces, profile), tomography_operator.c (the operator, right-hand side and solve), tomography_operator_f32.c
 * (the single-precision operator's float stages), tomography_ngs.c (its explicit NGS term), tomography_cost.c
 * (bytes, flops, non-zeros), tomography_model.c (what the atmosphere model sets: the prior's strengths, the
 * layer-binning model error, the sensors' noise weights), tomography_noise.c (the noise weights of sensors whose
 * reference changed) and tomography_focus.c (the LGS focus removal's own parts); not part of any interface. Calls between them go one way: the object calls the model's and
 * the NGS term's set-up; the operator calls its float stages, which call the NGS term. */
#ifndef WT_TOMOGRAPHY_PRIVATE_H
#define WT_TOMOGRAPHY_PRIVATE_H

#include "tomography.h"

#include "../op/noise.h"
#include "../op/prior.h"
#include "../op/projection.h"
#include "../op/wavelet.h"

/* distinct altitudes of the model profiles one tomography can take over its updates (a learned model's grid) */
#define WT_TOMO_MODEL_CACHE 128

/* the sub-grid unit integrals a tomography remembers (a learned grid: up to 64 altitudes, 2 layer spacings each) */
#define WT_SUBGRID_MEMO 256

struct wt_tomography {
    wt_context *ctx;
    const wt_system *sys;
    char variant[16];
    int L;
    wt_grid grid[WT_MAX_LAYERS];
    double alt[WT_MAX_LAYERS], frac[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS + 1];
    wt_wavelet *wav[WT_MAX_LAYERS];
    wt_prior *prior[WT_MAX_LAYERS];
    int64_t n;
    double *alpha_d;
    double alpha;             /* α (the full prior's weight; alpha_d holds α D otherwise) */
    int full_prior;           /* recon.prior = "full": α C_φ⁻¹ applied by FFT on the layers (core/op/prior.h) */
    int space;                /* the unknowns are the layers' values (no DWT pair around the operator) */
    int fp32;                 /* recon.<variant>.operator_precision = "fp32": normal() runs the LGS in float */
    uint8_t s32[2 * WT_MAX_GS]; /* fp32: sensor m's part in float (the LGS; the NGS's stays double: layers_dwt) */
    int any64;                /* fp32: some sensor's part is double (an NGS): the explicit term below */
    /* fp32 with NGS: their part of the operator through the explicit matrix G = [Pᵀ Γᵀ e_k] over the NGS slopes k
     * (layers' values x NGS slopes; CSR by layer point, made at set-up): forward Gᵀ φ, adjoint G (Ĉ⁻¹ s), in double
     * (tomography_ngs.c) */
    int64_t ngs_nrow;         /* layer points where G has a non-zero */
    int64_t *ngs_row;         /* [ngs_nrow] those points, ascending */
    int64_t *ngs_ptr;         /* [ngs_nrow + 1] row i's entries [ngs_ptr[i], ngs_ptr[i + 1]) */
    int32_t *ngs_col;         /* the entry's slope (its index in the slopes vector), ascending within a row */
    double *ngs_val;          /* the entry's value */
    wt_fft_wisdom *fft;       /* recon.fft_wisdom as read (NULL: FFTW_ESTIMATE plans) */
    int by_size[WT_MAX_LAYERS]; /* the layers, largest first (ties in index order): the FFT tasks' order */
    int owner[WT_MAX_LAYERS]; /* the thread that transforms layer l (inverse, forward, its FFTs), fixed */
    size_t pwsize;            /* its work per thread (doubles) */
    int iterations;
    double tol;
    int S;                    /* sensors */
    wt_projection **proj;     /* S x L: sensor m, layer l at [m * L + l] */
    wt_projection **projs;    /* S: sensor m, all L layers in one (the applies run the layers per point) */
    wt_sensor_stack stack;    /* Σ_m Γ_m P_m over projs (a view) */
    int64_t zero_offset;
    wt_noise **noise;         /* S: the reconstructor's model (τ as configured) */
    double model_var[2 * WT_MAX_GS];  /* S: layer-binning model error added to σ² [rad²] (model_error) */
    double subgrid_var[2 * WT_MAX_GS]; /* S: sub-grid model error, the floor of κσ² [rad²] (subgrid_error) */
    /* its unit integrals a(Δ, d′, L0) computed so far: every LGS at one range shares them, and a learned model's
     * updates keep their altitude grid, so after the first update none is computed again (~2 ms each) */
    int subgrid_nmemo;
    double subgrid_memo[WT_SUBGRID_MEMO][4]; /* Δ, d′, L0, a */
    int64_t ncg;              /* corner grid points */
    int nthreads;
    int group[2 * WT_MAX_GS];  /* sensor → accumulator group (fixed: results independent of threads) */
    size_t wsize;             /* wavelet workspace per thread (doubles) */
    wt_tomography_work *work; /* the object's own workspace: solve, set-up, the workspace-less applies */
    wt_pcg *pcg;
    /* the atmosphere model's part (core/model/tomography_model.c) */
    double r0, L0;            /* the model's r0 and outer scale [m] (the priors' strengths: f_ℓ r0^(−5/3)) */
    int wavelet_order, wavelet_levels;
    double kappa, tau;        /* the measurement noise's loop factor κ and the elongation weight τ of C̃ */
    int model_error;          /* recon.model_error */
    int subgrid_error;        /* recon.subgrid_error */
    int lgs_focus;            /* recon.lgs_focus_removal: 0 off, 1 each LGS's focus (in its noise object), 2 only
                                 the focus common to the LGS (recon.lgs_focus_mode = "common": the fc_* below) */
    int64_t fc_n;             /* common focus: the LGS's slopes, the first fc_n of the slope vector */
    double *fc_e, *fc_g;      /* [fc_n] e_j, g_j = Ĉ_tt,j⁻¹ e_j per LGS at its offset (tomography_focus.c); NULL: none */
    float *fc_e32, *fc_g32;   /* the same rounded to float (the fp32 operator) */
    double fc_gamma;          /* γ = Σ_j e_jᵀ g_j / n_LGS */
    double me_dx;             /* the model error's sample grid: spacing [m] and side */
    int me_n;
    int me_ncache;            /* unit layers' model error kept per altitude (wt_tomography_set_profile) */
    double me_alt[WT_TOMO_MODEL_CACHE];
    double me_unit[WT_TOMO_MODEL_CACHE * 2 * WT_MAX_GS];
    int fresh;                /* 1: the next solve applies M (the model changed since the last) */
};

/* What one application of the operators writes (GSL's workspaces): the operator itself stays const. */
struct wt_tomography_work {
    wt_context *ctx;
    double *phi;      /* n: spatial layers / adjoint sum */
    double *acc;      /* WT_GROUPS x n adjoint accumulators */
    double *phase;    /* S x ncg */
    double *slopes;   /* nslopes */
    double *weighted; /* nslopes */
    double *wwork;    /* nthreads x wsize wavelet workspace */
    double *b;        /* n: the applies' scratch, the solve's right-hand side */
    double *pphi;     /* full prior: n, α C_φ⁻¹ φ per layer */
    double *phi_raw, *pphi_raw; /* the allocations phi and pphi sit in at 64-byte boundaries: every layer starts at
                                   one (its n² is a multiple of 8 for n >= 4), so the full prior's FFTs read and write the
                                   layers in place (wt_prior_apply_full) */
    double *pwork;    /* full prior: nthreads x pwsize FFT workspace */
    /* fp32 (t->fp32): the float layers, group accumulators, phases, slopes and weighted slopes, and per thread one
       layer's float sum (the by-layers adjoint); one allocation, every array at a 64-byte boundary */
    float *f32_raw, *phi32, *acc32, *phase32, *slopes32, *weighted32, *lay32;
    float *wwork32;   /* fp32: nthreads x wsize float wavelet workspace */
    double *prof;     /* wt_tomography_profile_start: per stage, prof_stride doubles (calls, wall, then each thread's
                         busy time on a cache line of its own); NULL or prof_on 0: not timing */
    int prof_on;
    double fc_c1, fc_c2;  /* the common focus term's coefficients of the slopes being weighted (tomography_focus.c) */
};

/* core/model/tomography_model.c: the profile compressed onto the L layers at alt and floored; the model error's sample
 * grid from the variant; the model error σ²_e of the profile into t->model_var; the sensors' noise models from
 * t->model_var, κ and τ (replacing t->noise). */
void wt_tomography__bin_profile(int L, const double *alt, int natm, const double *atm_alt, const double *atm_frac,
                                double *frac);
/* core/model/tomography_focus.c. recon.lgs_focus_removal: a WT_ERR_CONFIG naming the key unless some NGS measures
 * focus (2x2) */
int wt_tomography__focus_check(const wt_tomography *t, const char *source);
/* f (2 nsub) = the unit focus slope pattern of sensor s (wt_noise_focus_pattern on its subaperture centres);
 * returns 1, or 0 when it has none (a 1x1 sensor), or an error status when out of memory */
int wt_tomography__focus_pattern(wt_context *ctx, const wt_sensor *s, double *f);
void wt_tomography__model_error_grid(wt_tomography *t, const wt_recon_variant_config *var, int wavelet_levels);
int wt_tomography__model_error(wt_tomography *t, double r0, int natm, const double *atm_alt, const double *atm_frac);
/* the sub-grid model error's a(Δ, d') of a unit layer [rad² per axis] (tomography_model.c), for the tests */
double wt_tomography__subgrid_error(double delta, double dp, double L0);
int wt_tomography__noise(wt_tomography *t);
/* core/model/tomography_focus.c, recon.lgs_focus_mode = "common" (each a no-op otherwise): the LGS's focus patterns
 * (alloc, at set-up), their weights g_j and γ after the noise models changed (update), the term's two coefficients
 * c1, c2 of the slopes x (or, x NULL, of the float x32) into w (coef, before the weights), and y_m += c1 e_m + c2 g_m
 * on sensor m's weighted slopes y (add; nothing for an NGS) */
int wt_tomography__common_alloc(wt_tomography *t);
void wt_tomography__common_free(wt_tomography *t);
void wt_tomography__common_update(wt_tomography *t);
void wt_tomography__common_coef(const wt_tomography *t, wt_tomography_work *w, const double *x, const float *x32);
void wt_tomography__common_add(const wt_tomography *t, const wt_tomography_work *w, int m, double *y);
void wt_tomography__common_add_f32(const wt_tomography *t, const wt_tomography_work *w, int m, float *y);

/* ---- the stages' profile clock (wt_tomography_profile_start), the layer owners and sizes: shared by the object
 * (tomography.c), the operator (tomography_operator.c), its single-precision stages (tomography_operator_f32.c)
 * and the cost model (tomography_cost.c) */

/* A stage's slots in w->prof: calls and wall, then nthreads busy times 8 doubles apart (no two threads write
 * one cache line) */
static inline int64_t wt_tomography__prof_stride(const wt_tomography *t) { return 8 * (1 + (int64_t)t->nthreads); }
static inline double wt_tomography__prof_t0(const wt_tomography_work *w) { return w->prof_on ? wt_time_now() : 0.0; }
/* one call of stage k that ran from t0 to t1 (t1 < 0: now) */
static inline void wt_tomography__prof_wall_to(const wt_tomography *t, wt_tomography_work *w, int k, double t0,
                                               double t1)
{
    if (!w->prof_on) return;
    double *s = w->prof + k * wt_tomography__prof_stride(t);
    s[0] += 1.0;
    s[1] += (t1 < 0.0 ? wt_time_now() : t1) - t0;
}
static inline void wt_tomography__prof_wall(const wt_tomography *t, wt_tomography_work *w, int k, double t0)
{
    wt_tomography__prof_wall_to(t, w, k, t0, -1.0);
}
static inline void wt_tomography__prof_busy(const wt_tomography *t, wt_tomography_work *w, int k, int id, double t0)
{
    if (w->prof_on && id < t->nthreads) w->prof[k * wt_tomography__prof_stride(t) + 8 * (1 + id)] += wt_time_now() - t0;
}

/* Inside a parallel region, from one stage to the next: every thread done with the first (a barrier), the master's
 * clock read into *t1 as the second's start, and with the profile on a second barrier, so that every thread's busy
 * time of the second stage lies within its wall from *t1 */
static inline void wt_tomography__prof_handover(const wt_tomography_work *w, double *t1)
{
#pragma omp barrier
#pragma omp master
    *t1 = wt_tomography__prof_t0(w);
    if (w->prof_on) {
#pragma omp barrier
    }
}

/* The thread that handles layer l in a team of nt: its fixed owner (the same thread every apply, so that a
 * layer's coefficients, values and FFT stay in one core's cache; any thread gives the same bits), folded onto a
 * smaller team (a nested or reduced one) */
static inline int wt_tomography__owner_of(const wt_tomography *t, int l, int nt) { return t->owner[l] % nt; }

/* the largest layer's points */
static inline size_t wt_tomography__max_layer(const wt_tomography *t)
{
    int64_t nmax = 0;
    for (int l = 0; l < t->L; l++)
        if (t->off[l + 1] - t->off[l] > nmax) nmax = t->off[l + 1] - t->off[l];
    return (size_t)nmax;
}

/* floats per thread in w->lay32 (a layer's float sum, by layers): the largest layer,
 * rounded to 64 bytes */
static inline size_t wt_tomography__lay32_size(const wt_tomography *t)
{
    return (wt_tomography__max_layer(t) + 15) / 16 * 16;
}

/* ---- core/model/tomography_ngs.c: the fp32 operator's NGS term, the explicit G = [Pᵀ Γᵀ e_k] (its comment says
 * why). Set-up: G from the double adjoint, into t->ngs_* (WT_ERR_NOMEM). Applies: */
int wt_tomography__ngs_explicit(wt_tomography *t);
/* sum[i − i0] += Σ_k G_ik wv_k for the layer points [i0, i1) (wv: the weighted slopes, indexed as the slopes) */
void wt_tomography__ngs_adjoint(const wt_tomography *t, const double *wv, int64_t i0, int64_t i1, double *sum);
/* The NGS's slopes Gᵀ φ (φ: the float layers) into slopes (at their indices; the others untouched) */
void wt_tomography__ngs_forward(const wt_tomography *t, const float *phi32, double *slopes);

/* ---- core/model/tomography_operator_f32.c: the fp32 operator's float stages, called by tomography_operator.c's
 * stage sequence (its parallel regions: the _team forms and adjoint_group_f32 run inside one) */
/* slopes32 = Γ P phi32 for every LGS, the NGS's slopes into w->slopes; with pphi also pphi = α C_φ⁻¹ φ */
void wt_tomography__forward_f32_team(const wt_tomography *t, wt_tomography_work *w, const double *phi, double *pphi,
                                     int id, int nt);
/* One accumulator group's share of the fp32 adjoint (s: the slopes to round first, or NULL: the forward's) */
void wt_tomography__adjoint_group_f32(const wt_tomography *t, wt_tomography_work *w, int g, const double *s);
/* The fp32 adjoint by layers (in space), a parallel region of its own */
void wt_tomography__adjoint_space_f32(const wt_tomography *t, wt_tomography_work *w, const double *s,
                                      const double *cx, double *c);

#endif

