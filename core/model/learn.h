/* core/model/learn.h: identification of the Cn² profile and r0 from the loop's own pseudo-open-loop LGS slopes
 * (SPEC §12, "Identification from the loop's own data": SLODAR generalised to many LGS).
 *
 * Data. Per frame, each LGS i's slopes with its own tip-tilt removed (s − mean over its valid subapertures, per
 * axis: LGS tip-tilt is not measured), laid on a zero-padded N × N grid (N = 2n ≥ 2n − 1: no wrap-around of the
 * correlation) and Fourier transformed. For every pair i ≤ j (autos included) and component c ∈ {xx, yy, xy}
 * (x slope of i with x of j, y with y, x of i with y of j) the cross-spectrum conj(Ŝ_i^a) Ŝ_j^b is summed over the
 * frames, so that a frame costs 2 n_lgs r2c FFTs plus n_pairs · 3 · N (N/2 + 1) complex products; the maps are
 * transformed back only when asked:
 *
 *   C_ij^c(δ) = Σ_t Σ_a M(a) M(a + δ) s_i^a(a, t) s_j^b(a + δ, t) / (K · P(δ)),   P(δ) = Σ_a M(a) M(a + δ),
 *
 * δ the offset in subapertures, M the valid mask (all LGS share it), K the frames.
 *
 * Model (core/model/learn_response.c). The same statistic for a unit layer (r0 = 1 m at 500 nm, outer scale L0)
 * at altitude h: R_ij^c(δ; h), computed from the von Kármán OPD structure function D (core/optics/seeing.h) over
 * the cone-beam footprints (scaled by 1 − h/H, shifted by θ h), with the same tip-tilt removal applied to the
 * model as to the data. D scales as r0^(−5/3), so the data are Σ_h c_h R(δ; h) with c_h = f_h r0^(−5/3) (f_h the Cn²
 * fractions) plus noise on the autos' δ = 0, which the fit leaves out.
 *
 * Fit (core/model/learn_fit.c). The statistic is differential: each cross pair's map less the mean of its two
 * autos, D_ij = C_ij − ½ (C_ii + C_jj) (a ground layer adds the same map to all three in every realisation, so the
 * differences carry no sampling error of it), with the autos themselves, δ = 0 (the noise) left out of every term.
 * c_h ≥ 0 on an altitude grid by non-negative least squares over the offsets where
 * P(δ) ≥ WT_LEARN_MIN_PAIRS · P(0), each weighted by P(δ) (the inverse variance of a mean over P(δ) products);
 * r0 = (Σ c_h)^(−3/5), f_h = c_h / Σ c_h. Frames are kept in B consecutive batches; the uncertainty of each output is
 * the spread of the B batch estimates / √B.
 *
 * Wind (core/model/learn_wind.c, SPEC §12 "Wind"; opt-in: wt_learn_alloc_lagged). The maps of frames k apart,
 *
 *   C_ij^c(δ; k) = Σ_t Σ_a M(a) M(a + δ) s_i^c(a, t − k) s_j^c(a + δ, t) / (K_k P(δ)),   c ∈ {x x, y y},
 *
 * for every ordered pair (i, j) (a lag breaks the symmetry) from a ring of the last k_max frames' spectra. Under
 * frozen flow (screen(x − v t), sim/atmosphere.h) a layer at h moving with v is, k frames later, the same
 * screen moved by v k Δt, so that it adds c_h R_ij^c(δ; h, s = v k Δt) to that map: the response of the
 * displacement δ d (1 − h/H) + (θ_j − θ_i) h − s. The fit: the lag-k map less the lag-0 map of the same frames
 * (the realisation's broad error cancels to first order in s), a layer l a local maximum of the profile fit's c_h
 * and the bins nearest to it sharing its wind, then each bin of a layer holding ≥ 2 % of the Cn² with its own wind
 * where that lowers the misfit (bins closer than the pairs' altitude resolution are parted by their motion); with
 * v_l and an amplitude a_l per layer (1 when the lagged maps hold the profile's Cn²),
 *   minimise Σ_{k,i,j,c,δ} w(δ) (C_k − C_0 − Σ_l a_l Σ_{h∈l} c_h (R(δ; h, v_l k Δt) − R(δ; h, 0)))²,
 * w = P(δ)/P(0) as for the profile, by Levenberg–Marquardt (derivatives in s analytic), the lags entered one by
 * one from the shortest (its shifts are under a subaperture, so v = 0 is a good start; each longer lag refines the
 * last one's v). Layers holding ≥ min_fraction of the Cn² are reported; those between 2 % and that are modelled,
 * not reported. A layer whose wind runs past 60 m/s is not in the lagged maps where its altitude says (Cn² the
 * profile put at the wrong altitude): it is dropped, the others refitted, and it is reported as not fitted.
 *
 * Threads: _add allocates nothing and is not thread-safe on one object; the response maps use the OpenMP team.
 */
#ifndef WT_LEARN_H
#define WT_LEARN_H

#include <stdint.h>

#include "../base/base.h"

/* Offsets whose pair count P(δ) is below this fraction of P(0) are left out of the fit: their mean is over few
 * products, and the few subapertures at the pupil's edge are the ones whose partial lighting the model ignores. */
#define WT_LEARN_MIN_PAIRS 0.25
#define WT_LEARN_MAX_ALT 64   /* altitudes of a grid */
#define WT_LEARN_MAX_BATCH 16 /* batches of frames for the uncertainty */
#define WT_LEARN_MAX_LAG 8    /* lags of the wind maps */
#define WT_LEARN_MAX_LAG_FRAMES 4096 /* the longest lag [frames] (the ring holds that many frames' spectra) */
enum { WT_LEARN_XX = 0, WT_LEARN_YY = 1, WT_LEARN_XY = 2, WT_LEARN_NCOMP = 3 };

/* The LGS geometry, plain data (copied by _alloc). Subaperture (ix, iy) is mask index ix + n iy, its centre at
 * ((ix − (n − 1)/2) d, (iy − (n − 1)/2) d); each LGS's slope block is [s_x of its valid subapertures in index
 * order, s_y …] (core/op/shack_hartmann.h), the blocks of the nlgs LGS one after the other. */
typedef struct wt_learn_geometry {
    int n;                       /* subapertures per side */
    double d;                    /* subaperture side [m] */
    const uint8_t *valid;        /* n*n valid mask, shared by every LGS */
    int nlgs;                    /* ≥ 1 */
    const double *theta_x;       /* [nlgs] directions [rad] */
    const double *theta_y;
    double H;                    /* LGS range [m] (> 0: the cone) */
} wt_learn_geometry;

typedef struct wt_learn wt_learn;

/* nbatch (1 … WT_LEARN_MAX_BATCH) batches of batch_frames frames each: frame t of _add goes to batch
 * min(t / batch_frames, nbatch − 1) (batch_frames ≤ 0: all to batch 0). Allocates the spectra (nbatch · npairs ·
 * 3 · N (N/2 + 1) complex) and plans the FFTs (FFTW_ESTIMATE; the planner is not thread-safe: call from one
 * thread). WT_ERR_INVALID naming a bad geometry. */
int wt_learn_alloc(wt_context *ctx, const wt_learn_geometry *g, int nbatch, int64_t batch_frames, wt_learn **out);
void wt_learn_free(wt_learn *L);
/* The same, also accumulating the lagged maps of the nlag (0 … WT_LEARN_MAX_LAG) increasing lags [frames] (1 …
 * WT_LEARN_MAX_LAG_FRAMES) for the wind: a ring of the last lags[nlag − 1] + 1 frames' spectra ((k_max + 1) · 2 nlgs
 * · N (N/2 + 1) complex) and nbatch · nlag · nlgs² · 2 spectra (at 84 × 84 subapertures, 6 LGS: 69 MB of ring for
 * k_max = 24 and 16 MB per lag and batch). A frame costs nlag · nlgs² · 2 · N (N/2 + 1) more complex products. */
int wt_learn_alloc_lagged(wt_context *ctx, const wt_learn_geometry *g, int nbatch, int64_t batch_frames, int nlag,
                          const int *lags, wt_learn **out);

/* Accumulate one frame: slopes = the nlgs LGS blocks (2 nsub each, as above) [rad]. Allocates nothing.
 * WT_ERR_NUMERIC naming the LGS and slope for NaN/Inf (the frame is then not counted). */
int wt_learn_add(wt_learn *L, const double *slopes);
int64_t wt_learn_frames(const wt_learn *L);    /* frames added */
/* Forget every frame added (the spectra, batch counts and, with lags, the ring of recent frames); the geometry and
 * plans stay, so that a loop can estimate from its last T seconds only. Allocates nothing. */
void wt_learn_reset(wt_learn *L);
/* A report of the long fits' progress (the wind's: minutes at E-ELT size): fn(user, phase, steps done, of total),
 * called from the fitting thread after each step; NULL: none (the default). */
typedef void (*wt_learn_progress_fn)(void *user, const char *phase, int64_t done, int64_t total);
void wt_learn_set_progress(wt_learn *L, wt_learn_progress_fn fn, void *user);
int wt_learn_npairs(const wt_learn *L);        /* nlgs (nlgs + 1) / 2; pair p = (i, j), i ≤ j, i-major order */
void wt_learn_pair(const wt_learn *L, int p, int *i, int *j);
int wt_learn_map_side(const wt_learn *L);      /* 2n − 1: maps are (2n − 1)² offsets, δ = (−(n−1) … n−1)² */

/* The averaged map C_p^c(δ) of batch b (−1: all frames) into map[(δx + n − 1) + (2n − 1)(δy + n − 1)] [rad²];
 * count (may be NULL) the pair counts P(δ). 0 where P(δ) = 0. WT_ERR_INVALID for no frames or a bad index. */
int wt_learn_map(const wt_learn *L, int batch, int p, int comp, double *map, double *count);

int wt_learn_nlags(const wt_learn *L);          /* 0 without lags */
int wt_learn_lag(const wt_learn *L, int q);      /* lag q [frames] (0 for a bad q) */
/* The lagged map C_ij^c(δ; lag q) of batch b (−1: all) laid out as wt_learn_map's, comp WT_LEARN_XX or _YY; pair
 * (t − k, t) counts in the batch of t. WT_ERR_INVALID for a bad index or no frame pairs k apart. */
int wt_learn_lag_map(const wt_learn *L, int batch, int q, int i, int j, int comp, double *map, double *count);

/* The response maps R_p^c(δ; h) of pair p for unit layers (r0 = 1 m) at the nalt altitudes alt [m] (each < H) with
 * outer scale L0 [m] (≤ 0: Kolmogorov), laid out as wt_learn_map's: resp[(a · 3 + c) · (2n−1)² + k] [rad²], the
 * same statistic as the data's (tip-tilt removed, averaged over the pairs of valid subapertures). A slope is the
 * mean OPD gradient over its subaperture: the difference of the OPD averaged along the two edges across the axis,
 * over d (WT_LEARN_EDGE_POINTS Gauss–Legendre points per edge); the covariance of two such differences is
 * −½ Σ ± D(…) over the four edge pairs. D is tabulated as D(ρ)/ρ^(5/3) (smooth) every d/WT_LEARN_TABLE_STEPS.
 * Allocates temporaries; uses the OpenMP team. */
#define WT_LEARN_EDGE_POINTS 3
#define WT_LEARN_TABLE_STEPS 16
int wt_learn_response(const wt_learn *L, int p, int nalt, const double *alt, double L0, double *resp);

/* A default altitude grid below H: 0, 0.5 km, then every 1 km to 20 km. Returns the count (≤ max). */
int wt_learn_default_grid(double H, int max, double *alt);
/* The default grid with the nlayer altitudes layer [m] (a reconstructor's, any order) added, ascending: every layer
 * altitude below g->H is kept (the compression onto those layers is then the identity for what the fit puts there),
 * and a default point is dropped when it is closer than the merge separation to one of them: half the finest
 * altitude resolution of the LGS pairs, d / (2 θ_max) with θ_max the widest pair's separation (two points closer than
 * that are the same bin for every pair; one of them only makes the fit's split between them noise). *sep (may be
 * NULL): that separation [m]. Returns the count (≤ max), or WT_ERR_INVALID when they do not fit in max. */
int wt_learn_grid_with_layers(const wt_learn_geometry *g, int nlayer, const double *layer, int max, double *alt,
                              double *sep);

/* The estimate (plain data). */
typedef struct wt_learn_estimate {
    int nalt;
    double altitude[WT_LEARN_MAX_ALT];   /* the grid [m] */
    double cn2[WT_LEARN_MAX_ALT];        /* c_h = f_h r0^(−5/3) [m^(−5/3)], all frames */
    double fraction[WT_LEARN_MAX_ALT];   /* f_h [-], sum 1 */
    double fraction_sigma[WT_LEARN_MAX_ALT]; /* spread of the batches' f_h / √B [-] (0 with one batch) */
    double r0, r0_sigma;                 /* [m] at 500 nm, and its uncertainty as above */
    double r0_total;                     /* [m] r0 of the whole fit's total Cn² (every offset; r0 is scaled on the
                                            autos within two subapertures: learn_fit.c small_scale) */
    double L0;                           /* the outer scale used [m] */
    int64_t frames;                      /* frames used */
    int nbatch;                          /* batches with frames */
    int64_t rows;                        /* (pair, component, offset) terms in the fit */
    double residual;                     /* weighted rms misfit / weighted rms of the statistic (autos and differences), all frames [-] */
    double batch_fraction[WT_LEARN_MAX_BATCH][WT_LEARN_MAX_ALT]; /* each batch's f_h (nbatch ≥ 2) [-] */
    double batch_r0[WT_LEARN_MAX_BATCH];                          /* each batch's r0 [m] */
    double sigma_factor;                 /* r0_sigma and fraction_sigma = the batches' spread / √B times this (1 from
                                            the fit; wt_learn_estimate_count_screens sets it) [-] */
    double screens;                      /* the turbulence renewals the frames saw, T/τ (0: not counted) [-] */
} wt_learn_estimate;

/* The batches' spread counts only the turbulence the batches saw apart: consecutive batches look at the same
 * screens until each layer has moved by about the aperture D (the maps average over the pupil; their slowest
 * part, the one that makes one realisation's r0 differ from the next, is the scales up to D). With the screens'
 * renewal time τ = D Σ_k f_k / max(v_k, WT_LEARN_VMIN) (Cn²-weighted: the slow layers set it) and batches of t_b
 * seconds, the standard error of the mean of batches with correlation time τ is the spread's / √B times
 * √max(1, τ / t_b) (batch means of a correlated sequence). Returns that factor; *screens (may be NULL) the renewals
 * the whole telemetry of T seconds saw, T / τ. n layers of fractions f and speeds v [m/s] (a model's: the wind is
 * not the estimate's). */
#define WT_LEARN_VMIN 1.0 /* [m/s]: a still layer still renews by boiling, on a time the model does not know */
double wt_learn_screen_factor(double D, double batch_s, double total_s, int n, const double *fraction,
                              const double *speed, double *screens);
/* r0_sigma and fraction_sigma of an estimate of frames of dt seconds in its batches scaled by that factor (the
 * uncertainty that counts the screens seen), sigma_factor and screens recorded. */
void wt_learn_estimate_count_screens(wt_learn_estimate *e, double D, double dt, int n, const double *fraction,
                                     const double *speed);

/* The response maps of the nalt increasing altitudes alt (< H) at outer scale L0, restricted to the offsets the fit
 * uses, and their normal matrix: computed once (the costly part of a fit, OpenMP team), so that a fit of new frames
 * is inverse FFTs of the accumulated spectra, the right-hand sides AᵀWb and an NNLS of nalt unknowns. Holds
 * nslot · 3 · nu · nalt doubles (nslot = 1 + nlgs (nlgs − 1)/2 distinct pairs, nu ≈ half of (2n − 1)² offsets: 118 MB
 * at 84 × 84 subapertures, 6 LGS, 22 altitudes). WT_ERR_INVALID for a bad grid. */
typedef struct wt_learn_model wt_learn_model;
int wt_learn_model_alloc(const wt_learn *L, int nalt, const double *alt, double L0, wt_learn_model **out);
void wt_learn_model_free(wt_learn_model *M);

/* Fit with a model built from L or from an object of the same geometry (WT_ERR_INVALID otherwise); the estimate as
 * wt_learn_fit's, bit for bit on one thread. Allocates temporaries (a few spectra per thread); OpenMP team. */
int wt_learn_fit_model(const wt_learn *L, const wt_learn_model *M, wt_learn_estimate *est);

/* Fit the profile on the nalt increasing altitudes alt (< H) with outer scale L0. Needs ≥ 2 frames in every
 * batch used (WT_ERR_INVALID otherwise, saying how many). WT_ERR_NUMERIC when the fit finds no turbulence
 * (every c_h = 0). Allocates temporaries. */
int wt_learn_fit(const wt_learn *L, int nalt, const double *alt, double L0, wt_learn_estimate *est);
/* (a convenience: wt_learn_model_alloc, wt_learn_fit_model, wt_learn_model_free) */

/* The wind per altitude of an estimate (plain data). Direction: of motion, counter-clockwise from +x [rad] in
 * [0, 2π) (sim/atmosphere.h's convention). */
#define WT_LEARN_WIND_MIN_FRACTION 0.05 /* SPEC §12 / the task: a wind for bins with ≥ 5 % of the Cn² */
typedef struct wt_learn_wind {
    int nalt;
    double altitude[WT_LEARN_MAX_ALT];   /* the estimate's grid [m] */
    double fraction[WT_LEARN_MAX_ALT];   /* its Cn² fractions [-] */
    int fitted[WT_LEARN_MAX_ALT];        /* 1 where a wind was estimated (its layer ≥ min_fraction) */
    double vx[WT_LEARN_MAX_ALT], vy[WT_LEARN_MAX_ALT];           /* [m/s], 0 where not fitted */
    double speed[WT_LEARN_MAX_ALT], direction[WT_LEARN_MAX_ALT]; /* [m/s], [rad] */
    double vx_sigma[WT_LEARN_MAX_ALT], vy_sigma[WT_LEARN_MAX_ALT]; /* spread of the batches / √B [m/s] */
    double speed_sigma[WT_LEARN_MAX_ALT], direction_sigma[WT_LEARN_MAX_ALT]; /* [m/s], [rad] */
    int nlag;
    int lag[WT_LEARN_MAX_LAG];           /* [frames] */
    double amplitude[WT_LEARN_MAX_ALT];  /* the layer's Cn² in the lagged maps / the profile fit's [-] (fitted bins) */
    double dt;                           /* frame time [s] */
    double residual;                     /* weighted rms misfit / weighted rms of the lagged maps, all frames [-] */
    int iterations;                      /* Levenberg–Marquardt iterations, all frames */
    int dropped;                         /* layers dropped: their wind ran past 60 m/s (then reported as not fitted) */
    int split;                           /* layers added by giving a peak's strong bins their own wind (0: none) */
    int nbatch;                          /* batches fitted for the spread (0: one batch, no spread) */
    double batch_vx[WT_LEARN_MAX_BATCH][WT_LEARN_MAX_ALT], batch_vy[WT_LEARN_MAX_BATCH][WT_LEARN_MAX_ALT]; /* [m/s] */
} wt_learn_wind;

/* The wind of the layers of est (wt_learn_fit of the same L) holding ≥ min_fraction of the Cn², from L's lagged maps
 * (wt_learn_alloc_lagged), dt the frame time [s]. WT_ERR_INVALID without lags, with too few frames for the longest
 * lag (saying how many), with no bin above min_fraction or a bad dt; WT_ERR_NUMERIC if the fit does not converge.
 * Allocates temporaries; OpenMP team. */
int wt_learn_wind_fit(const wt_learn *L, const wt_learn_estimate *est, double dt, double min_fraction, wt_learn_wind *w);

/* The estimate's profile and wind compressed onto nl reconstruction layers at the increasing altitudes ralt [m]
 * (core/model/profile.h: Cn² split linearly in altitude; a layer's wind = the Cn²-weighted mean of the vectors it
 * absorbs, over the fitted bins only: an unfitted bin's wind is unknown, not 0). rvx, rvy [m/s], rfrac [-]; also the
 * batches' spread of rvx, rvy (sigma_x, sigma_y may be NULL). Allocates nothing. */
void wt_learn_wind_compress(const wt_learn_wind *w, int nl, const double *ralt, double *rfrac, double *rvx, double *rvy,
                            double *sigma_x, double *sigma_y);

/* Non-negative least squares in normal-equation form: minimise ½ xᵀ G x − qᵀ x over x ≥ 0 (Lawson & Hanson 1974,
 * ch. 23, on the Gram matrix G = AᵀA, q = Aᵀb), G m × m column-major symmetric positive semi-definite. x [m] out.
 * work ≥ m (2 m + 3) doubles, iwork ≥ m ints. Returns the outer iterations, or WT_ERR_NUMERIC if a cap (3 m outer,
 * m + 1 inner) is hit. */
int wt_learn_nnls(int m, const double *G, const double *q, double *x, double *work, int *iwork);

#endif
