/* compare/budget.h: the error budget of the residual over the field (SPEC §11).
 *
 * Each term is measured by loop runs (sim/loop.h) on the same seed that remove one cause; σ² is the
 * field mean over the evaluation directions and the frames after the settle period (piston removed):
 *   fitting      σ²_fit: the DMs fitted to the true turbulence along the evaluation directions (no
 *                sensors; the cg9 fitting: its sampling, ε and the guard ring), evaluated like the loop
 *   tomography   σ²_OL,nf − σ²_fit: instantaneous open loop on noise-free slopes (tomography, aliasing,
 *                the reconstructor's model error); with diffractive sensors (or on request) the
 *                instantaneous pseudo-open loop, whose sensors see the previous frame's residual, so the
 *                term keeps the centroiders in their linear range (sim/loop.h WT_LOOP_OPEN_POLC)
 *   noise (OL)   σ²_OL − σ²_OL,nf: the same open loop with noise
 *   noise (CL)   σ²_CL − σ²_CL,nf: the closed loop with noise minus without
 *   servo        σ²_CL,nf,S − σ²_OL,nf: the closed loop (delay, integrator) whose pseudo-open-loop slopes add
 *                the truth sensors' own measurement of the applied DM shapes (exact POLC: its reconstructor
 *                sees the turbulence's slopes, as the open loop does) minus the instantaneous open loop
 *   polc         σ²_CL,nf − σ²_CL,nf,S: the POLC model error, the model's Â a in place of the truth sensors'
 *                slopes of the DM shapes (servo² + polc² = σ²_CL,nf − σ²_OL,nf). Diffractive sensors have
 *                no exact POLC run: their servo is σ²_CL,nf − σ²_OL,nf and polc is NaN
 *   with recon.predict (the reconstructed layers moved by their wind over the delay), the instantaneous runs
 *   without it (no delay to predict over: an open loop that predicted would add the shift as an error), and
 *   servo        as above, the closed loop with prediction: the lag that prediction leaves (the wind of the
 *                compressed layers that is not each atmospheric layer's, the integrator's response to a predicted
 *                input, the reconstruction's own error moved with the layers, and any evolution that is not
 *                frozen flow — none in this simulator's atmosphere); the first two analytic, band-limited:
 *                wt_budget_servo_band_predicted
 *   servo_no_predict  σ²_CL,nf,S,np − σ²_OL,nf: the same exact-POLC closed loop without prediction (the servo
 *                term of the budget without recon.predict, to the bit)
 *   servo_predicted   servo_no_predict² − servo²: the lag prediction removed (NaN both without recon.predict
 *                or an exact-POLC run)
 *   tip-tilt     the tip/tilt part of the closed loop's residual (least-squares plane per direction)
 *   rim/interior the residual variance in the outer annulus of width w (1 m) / inside it; they add to σ²_CL
 *   total        σ²_CL: the closed loop with noise (what `wavetomo sim` gives)
 * A term given as a quadrature difference is sign(Δ) √|Δ| (negative: the "removed" cause helped).
 * Closure: fitting² + tomography² + servo² + polc² + noise_OL² · Σh² against total² (the open-loop noise through
 * the integrator's noise gain; the closed-loop noise itself would make the sum telescope exactly).
 *
 * Analytic estimates [nm at any λ, computed at the evaluation wavelength λ, r0_λ = r0 (λ/500 nm)^(6/5)]:
 *   fitting  σ² = κ Σ_ℓ f_ℓ (p_k(ℓ)/r0_λ)^(5/3) rad², κ ∈ [0.23, 0.28] (bilinear DM), p_k(ℓ) the pitch of
 *            the DM nearest in altitude to layer ℓ (Cn²-weighted); the ground-DM-only value κ (p_0/r0_λ)^(5/3)
 *            is given too. Single-direction fitting: it does not hold the field's generalised fitting.
 *   noise    σ²_OL = σ² of the DM shape reconstructed from pure noise (no turbulence), over the field, mean
 *            over draws; closed loop σ²_OL times the integrator's noise gain Σ h² (g/(2−g) for d = 1;
 *            wt_budget_noise_gain, exact for the configured delay)
 *   servo    σ² = (f_G/f_3dB)^(5/3) rad², f_G = 0.427 v_eff / r0_λ, v_eff = (Σ_ℓ f_ℓ |v_ℓ|^(5/3))^(3/5),
 *            f_3dB the frequency where the rejection |E| = |1/(1 + g z^−d/(1 − z^−1))|, z = e^(2πi f/f_s),
 *            first reaches 1/√2 (the loop a_{t+d} = a_{t+d−1} + g (φ_t − a_t) of sim/loop.h); and the
 *            band-limited form (wt_budget_servo_band_limited): the same rejection applied to the spectrum
 *            of the frequencies the DMs correct.
 */
#ifndef WT_BUDGET_H
#define WT_BUDGET_H

#include "../core/model/system.h"
#include "../sim/loop.h"

struct wt_mvm;

enum {
    WT_BUDGET_FITTING,
    WT_BUDGET_TOMOGRAPHY,
    WT_BUDGET_NOISE_OL,
    WT_BUDGET_NOISE_CL,
    WT_BUDGET_SERVO,
    WT_BUDGET_SERVO_NO_PREDICT, /* recon.predict only (else NaN): the servo term of the same loop without prediction */
    WT_BUDGET_SERVO_PREDICTED,  /* recon.predict only: the lag prediction removed, √(servo_no_predict² − servo²) */
    WT_BUDGET_POLC,
    WT_BUDGET_TIPTILT,
    WT_BUDGET_RIM,
    WT_BUDGET_INTERIOR,
    WT_BUDGET_TOTAL,
    WT_BUDGET_NTERMS
};
/* Short names ("fitting", "tomography", …) and one-line descriptions of the terms. */
extern const char *const wt_budget_term_names[WT_BUDGET_NTERMS];
extern const char *const wt_budget_term_desc[WT_BUDGET_NTERMS];
/* 1 when term k is measured under cfg (servo_no_predict and servo_predicted: recon.predict only); the report, the
 * HDF5 and the plot leave the others out */
int wt_budget_term_used(const wt_config *cfg, int k);

/* The runs of one method (and the shared fitting run), field values of frames ≥ settle [m]. */
enum { WT_BUDGET_RUN_FIT, WT_BUDGET_RUN_OL_NF, WT_BUDGET_RUN_OL, WT_BUDGET_RUN_CL_NF, WT_BUDGET_RUN_CL,
       WT_BUDGET_RUN_NOISE, WT_BUDGET_RUN_CL_NF_POLC, WT_BUDGET_RUN_CL_NF_POLC_NO_PREDICT, WT_BUDGET_NRUNS };
extern const char *const wt_budget_run_names[WT_BUDGET_NRUNS];

typedef struct wt_budget_run {
    double wfe;      /* √(field-mean σ²) */
    double tiptilt;  /* √(field-mean tip/tilt σ²) */
    double rim;      /* √(field-mean Σ_rim e² / N): the rim's part of wfe² */
    double rim_area; /* fraction of the pupil's sample points in the rim */
    long frames;     /* frames averaged */
    double seconds;  /* wall time of the run */
} wt_budget_run;

typedef struct wt_budget_result {
    int recon;
    int open_loop;                      /* the instantaneous runs' form used (WT_LOOP_OPEN_FLAT / _POLC) */
    wt_budget_run run[WT_BUDGET_NRUNS];
    double term[WT_BUDGET_NTERMS];      /* measured [nm] */
    double analytic[WT_BUDGET_NTERMS];  /* analytic [nm], NaN where none */
    double analytic_hi[WT_BUDGET_NTERMS]; /* upper end of a range (fitting: κ = 0.28), else = analytic */
    double fitting_ground;              /* ground-DM-only analytic fitting, κ = 0.23 [nm] */
    double servo_band;                  /* band-limited servo estimate (wt_budget_servo_band_limited) [nm] */
    double servo_band_predicted;        /* with recon.predict (pcg3, cg9; else NaN): the same with the method's layers
                                           moved by their compressed winds (wt_budget_servo_band_predicted) [nm] */
    double servo_band_own_winds;        /* … and with each atmospheric layer moved by its own wind [nm] */
    double servo_tiptilt;               /* the servo term's tip-tilt part: the same runs' tip-tilt in quadrature [nm] */
    double servo_tiptilt_no_predict;    /* … of servo_no_predict (recon.predict only, else NaN) [nm] */
    double sum;                         /* the closure's quadrature sum [nm] */
    double closure;                     /* sum / total − 1 */
} wt_budget_result;

/* Progress of run `run` (0-based) of `nruns`: `done` of `total` frames, called after each frame; the call
 * with done = total comes when the run is complete, with its field WFE [nm] (NaN before). */
typedef void (*wt_budget_progress_fn)(void *user, int run, int nruns, const char *label, long done, long total,
                                      double wfe_nm);

typedef struct wt_budget_options {
    uint64_t seed;
    int fit_iterations;   /* CG iterations per frame of the fitting term (warm-started) */
    int noise_draws;      /* pure-noise frames of the analytic noise term */
    int warmup;           /* open-loop frames run before the settle period (for the warm starts) */
    double rim_width;     /* [m] */
    int open_loop;        /* the instantaneous runs: WT_LOOP_OPEN_FLAT (DMs flat in the sensors) or
                           * WT_LOOP_OPEN_POLC (the previous reconstruction in them: sim/loop.h); 0:
                           * automatic, POLC when a sensor is diffractive (a spot of the full open-loop
                           * turbulence leaves the centroider's linear range), else flat */
    wt_budget_progress_fn progress;
    void *user;
} wt_budget_options;

/* Defaults: fit_iterations 50, noise_draws 8, warmup 10, rim_width 1 m. */
void wt_budget_options_default(wt_budget_options *o, uint64_t seed);

/* The budget of nmethods reconstructors (recon[m]; mvm[m] the control matrix for WT_RECON_MVM, else
 * NULL) on sys (its config: frames, settle, noise, gain, delay). res[m] filled; the fitting run is
 * shared. sys->cfg->noise = 0: the noisy runs are the noise-free ones (noise terms 0). With recon.predict an
 * MVM needs two matrices: mvm[m] with the predictor (the closed loops that predict) and mvm_plain[m] without
 * it (the instantaneous runs and the closed loop without prediction); mvm_plain may be NULL otherwise. */
int wt_budget_compute(wt_context *ctx, const wt_system *sys, const wt_budget_options *opt, int nmethods,
                      const int *recon, const struct wt_mvm *const *mvm, const struct wt_mvm *const *mvm_plain,
                      wt_budget_result *res);
/* Runs the budget will make for nmethods methods (for progress). */
int wt_budget_nruns(const wt_system *sys, int nmethods);

/* Tolerance of the closure |sum / total − 1| stated in the report. */
#define WT_BUDGET_CLOSURE_TOL 0.05

/* report.md (through a temporary renamed onto path): the table of terms (measured and analytic, per
 * method), the runs, the closure against WT_BUDGET_CLOSURE_TOL, the analytic inputs; argv: the command. */
int wt_budget_write_report(wt_context *ctx, const char *path, const wt_config *cfg, int nmethods,
                           const char *const *methods, const wt_budget_result *res, int argc, char **argv);

/* The datasets of results.h5 (docs/formats.md "budget: results.h5"): per method "<method>/<term>" [nm] with the analytic
 * values as attributes, "<method>/runs/<run>", "<method>/closure"; the root attribute "methods". */
struct wt_h5_writer;
int wt_budget_write_h5(struct wt_h5_writer *w, int nmethods, const char *const *methods, const wt_budget_result *res);

/* Analytic pieces (units: nm at the evaluation wavelength, Hz). */
double wt_budget_fitting_analytic(const wt_config *cfg, double kappa, int ground_only);
double wt_budget_greenwood(const wt_config *cfg);
double wt_budget_f3db(double gain, double rate, int delay);
double wt_budget_servo_analytic(const wt_config *cfg);
/* The servo error of the spatial frequencies the DMs correct only: Σ_ℓ ∫_{|κx|,|κy| < 1/(2 p_k(ℓ))}
 * Φ_ℓ(κ) |E(κ·v_ℓ)|² d²κ, Φ_ℓ the von Kármán spectrum of layer ℓ (0.0229 f_ℓ r0_λ^(−5/3) (κ² + L0^−2)^(−11/6)
 * rad² per (cycles/m)²), E the rejection above: Greenwood's formula counts the lag of all frequencies,
 * most of which no DM corrects (they are in the fitting term). */
double wt_budget_servo_band_limited(const wt_config *cfg);
/* The same lag when the reconstruction is predicted over the lead τ (recon.predict_lead_frames, else the delay d):
 * layer ℓ, split onto the reconstruction layers j of var with the weights w_ℓj of the oracle's compression
 * (core/model/profile.h), is moved by P_ℓ(κ) = Σ_j w_ℓj exp(2πi κ·v̄_j τ), v̄_j the Cn²-weighted wind the layer j
 * holds, and its rejection becomes E = 1 − g P / (z^d − z^(d−1) + g), z = exp(2πi κ·v_ℓ / f_s) (P = 1: the rejection
 * above; P = z^d, the layer's own wind over the delay, leaves the integrator's averaging only). var NULL: each
 * atmospheric layer moved by its own wind. The difference in quadrature between the two is the part of the lag the
 * compressed layers cannot express, whatever shift they are given (issue 36 item 3; SPEC §12): on the E-ELT's 9
 * layers onto PCG-3's 3, over a pure delay of 4–6 ms, a shift by the Cn²-weighted mean wind leaves 0.490 of the lag
 * variance and the best linear predictor of each layer alone (the Cn²-weighted mean of its components' phasors)
 * 0.488 (docs/results.md §73). With recon.predict_integrator = "layers" (the integrator on the layers, each moved
 * by its wind U_j = exp(2πi κ·v̄_j / f_s) a frame) the rejection is E = 1 − Σ_j w_ℓj g P_j / (z^d − U_j z^(d−1) + g P_j),
 * P_j = exp(2πi κ·v̄_j τ): 0 for a layer moved by its own wind (U = z, τ = d / f_s), whatever g; what is left is the
 * integrator's lag on the motion relative to the reconstruction layer's. */
double wt_budget_servo_band_predicted(const wt_config *cfg, const wt_recon_variant_config *var);
/* Σ_k h_k²: the variance gain of white measurement noise through the loop's integrator with delay d
 * (impulse response h of a_{t+d} = a_{t+d−1} + g (n_t − a_t)); g/(2−g) for d = 1 (= wt_noise_loop_gain). */
double wt_budget_noise_gain(double gain, int delay);

#endif
