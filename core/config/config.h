/* core/config/config.h: the system description of SPEC §1 as typed values, read from a libconfig file.
 *
 * wt_config_read parses the file, applies `--set key=value` overrides, validates every key
 * (type, range, consistency) and fills a wt_config. Any failure stops with a message that names the
 * file, the line, the key, the value found and what is accepted. Units: each field says its own; the
 * file keys carry the unit in their name (…_m, …_arcsec, …_deg, …_nm, …_hz).
 * Angles are converted to radians and lengths to metres on reading.
 */
#ifndef WT_CONFIG_H
#define WT_CONFIG_H

#include "../base/base.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>

#define WT_MAX_LAYERS 64 /* atmosphere and reconstruction layers: the ESO 35-layer profile with room */
#define WT_MAX_GS 16
#define WT_MAX_DMS 8
#define WT_MAX_EVAL 225 /* 15 x 15 evaluation directions */
#define WT_MAX_GAIN_BANDS 16 /* loop.gain_levels: the scaling block and up to 15 wavelet levels */
#define WT_MAX_PSF_WAVELENGTHS 16 /* sim.psf_wavelengths_nm: J to N bands and more, each one PSF per direction */
#define WT_ARCSEC (M_PI / (180.0 * 3600.0)) /* radians per arcsecond */

typedef struct wt_sensor_config {
    int subapertures;        /* subapertures across the pupil (LGS: per side; NGS: per side, 1 or 2 typ.) */
    double valid_fraction;   /* a subaperture is valid when at least this fraction is illuminated */
    double photons;          /* detected photons per subaperture per frame */
    double read_noise_e;     /* read noise [e- rms per pixel] */
    double spot_fwhm;        /* non-elongated spot FWHM [rad] */
    double pixel;            /* pixel scale [rad] */
    int pixels;              /* pixels across a subaperture (Ns) */
    double nea;              /* noise-equivalent angle per axis [rad]; < 0: use the photon/read model */
    int lit_noise;           /* 1: a partly lit subaperture collects its lit fraction of the photons (more noise) */
    int tilt;                /* what a slope is (NGS only; LGS 0): 0 G-tilt, the average gradient over the lit
                                area (a centroid); 1 Z-tilt, the least-squares plane over it (WT_SH_TILT_*) */
    /* the sensor model (SPEC §4b): geometric (today's: lit-area gradient + Gaussian noise) or diffractive
     * (spot images on pixels, a centroider, its calibrated noise covariance); the rest is diffractive only */
    int model;               /* WT_WFS_GEOMETRIC or WT_WFS_DIFFRACTIVE */
    int centroider;          /* WT_CENTROID_COG / _TCOG / _MF (core/optics/centroid.h): 0 cog, 1 tcog, 2 mf */
    int apply_gain;          /* 1: slopes and covariance corrected by the calibrated 2x2 gain */
    double threshold_noise;  /* tCoG: T = threshold_noise sqrt(σe² + B) + threshold_peak max I0 */
    double threshold_peak;   /* tCoG: fraction of the reference peak [-] */
    int window_pixels;       /* CoG/tCoG window Nw [pixels]; 0: the whole detector */
    double background_e;     /* background per pixel per frame [e-] */
    int pupil_samples;       /* n_p: pupil samples across a subaperture */
    int fft_size;            /* N: FFT points (≥ 2 n_p) */
    int cells_per_pixel;     /* k: rebinning cells per pixel side (odd) */
    double wavelength;       /* sensing wavelength [m] */
    int noise_calibration;   /* 0 analytic, 1 Monte Carlo */
    int calibration_draws;   /* Monte Carlo draws */
    uint64_t calibration_seed; /* Monte Carlo seed */
} wt_sensor_config;

enum { WT_WFS_GEOMETRIC = 0, WT_WFS_DIFFRACTIVE = 1 };

/* The reconstructors' priors (recon.prior, recon.<variant>.prior: the index in "paper|exact|full") and each
 * variant's default when both keys are left out (docs/design.md "The prior"): the full covariance for both
 * (pcg3's MVM holds it as a dense normal matrix; docs/results.md §23 says what it costs and gains). */
enum { WT_CFG_PRIOR_PAPER = 0, WT_CFG_PRIOR_EXACT = 1, WT_CFG_PRIOR_FULL = 2 };
#define WT_PRIOR_DEFAULT_PCG3 WT_CFG_PRIOR_FULL
#define WT_PRIOR_DEFAULT_PCG3_TEXT "\"full\""
#define WT_PRIOR_DEFAULT_CG9 WT_CFG_PRIOR_FULL
#define WT_PRIOR_DEFAULT_CG9_TEXT "\"full\""

/* How a reconstruction variant's layer grids were chosen (wt_recon_variant_config.grid_auto). */
enum { WT_GRID_EXPLICIT = 0, WT_GRID_AUTO_SIZE = 1, WT_GRID_AUTO = 2 };

typedef struct wt_recon_variant_config {
    int nlayers;
    double altitudes[WT_MAX_LAYERS]; /* reconstruction layer altitudes [m] */
    double spacing[WT_MAX_LAYERS];   /* layer grid spacing [m] */
    int size[WT_MAX_LAYERS];         /* layer grid points per side, a power of two */
    int grid_auto;                   /* WT_GRID_EXPLICIT, WT_GRID_AUTO_SIZE (spacing given), WT_GRID_AUTO
                                        (both left out): how spacing and size were chosen (config_grid.c) */
    double oversampling;             /* layer_oversampling: the automatic spacing is grid_base / this [-] */
    double grid_base[WT_MAX_LAYERS]; /* WT_GRID_AUTO: the length the spacing divides: the LGS subaperture
                                        side d, or the pitch of DM grid_base_dm [m] */
    int grid_base_dm[WT_MAX_LAYERS]; /* WT_GRID_AUTO: -1 when grid_base is d, else the DM index (0-based) */
    int iterations;                  /* (P)CG iterations per frame */
    double tolerance;                /* relative residual to stop at; 0: always run `iterations` */
    int preconditioner;              /* index in "none|jacobi|jacobi_ngs|coarse_ngs|multilevel" (WT_PRECOND_* of
                                        core/model/precond.h): 0 plain CG, 1 modified Jacobi, 2 Jacobi + NGS
                                        low-rank term, 3 that with the coarse coefficients as one exact block,
                                        4 that with the layers' blocks per detail position below it */
    int coarse_levels;               /* coarse_ngs, multilevel: detail levels in the coarse block besides the
                                        scaling block */
    int loop_noise_average;          /* 1: the sensors' σ² times the integrator's noise gain Σh² */
    int prior;                       /* index in "paper|exact|full" (WT_CFG_PRIOR_*): resolved from recon.prior or
                                        the variant's default when left out */
    int fit_iterations;              /* fitting CG iterations (cg9 only; 0 for pcg3) */
    double fit_regularization;       /* fitting Tikhonov weight, relative to the mean diagonal of H^T H */
    int fit_sampling;                /* fitting sample points per subaperture side (1: Fried corners) */
    int fit_solver;                  /* index in "cg|cholesky" (WT_FIT_CG, WT_FIT_CHOLESKY of core/model/fitting.h) */
    int fit_factor_precision;        /* index in "fp64|fp32": the Cholesky factor's values in the solves (1: fp32) */
    int fit_kernels;                 /* index in "fast|reference": the fitting frame's kernels (1: reference, same bits) */
    int operator_precision;          /* index in "fp64|fp32": the sensors' part of the (P)CG operator (1: fp32) */
} wt_recon_variant_config;

/* The reconstructor's atmosphere (SPEC §12 "Truth and model are separate objects"; recon.atmosphere): where it
 * comes from. WT_MODEL_LEARNED starts from the given model and replaces it by the loop's own estimates
 * (sim/adapt.h). */
enum { WT_MODEL_ORACLE = 0, WT_MODEL_GIVEN = 1, WT_MODEL_LEARNED = 2 };

/* The reconstructor's atmosphere as a profile before it is compressed onto each variant's layers
 * (core/model/profile.h): the truth's for the oracle, the user's for a given model. */
typedef struct wt_model_atmosphere_config {
    int source;                           /* WT_MODEL_ORACLE, WT_MODEL_GIVEN, WT_MODEL_LEARNED (starts from given) */
    double r0;                            /* Fried parameter at 500 nm [m] */
    double L0;                            /* outer scale [m] */
    int nlayers;
    double altitude[WT_MAX_LAYERS];       /* [m], increasing (non-decreasing after error_high_shift: two layers
                                             may meet, the compression does not mind) */
    double fraction[WT_MAX_LAYERS];       /* Cn2 fractions, normalised to sum 1 */
    double wind_speed[WT_MAX_LAYERS];     /* [m/s] */
    double wind_direction[WT_MAX_LAYERS]; /* [rad], direction the layer moves towards */
    char profile[1024];                   /* given: the profile file as resolved, "" when the lists were given */
    double update_s;                      /* learned: night time between two estimates [s] */
    int learn_window;                     /* learned: 0 the frames since the previous estimate, 1 all since the start */
    double learn_memory;                  /* learned, interval: the estimates' memory [updates] (1: none) */
    int learn_grid;                       /* learned: 0 the default grid, 1 it with the variant's layer altitudes */
    int learn_wind;                       /* learned: 0 the start model's wind, 1 aligned on the layer estimates */
    double mvm_latency_s;                 /* learned, mvm: night time from an estimate to its matrix in the loop [s];
                                             < 0: the build's measured wall time */
    /* a controlled error of the model (recon.atmosphere.error_*, config_atmosphere.c), applied to the fields above
     * once the oracle's or the given profile is formed; the values of "no error" leave every bit as it was */
    double error_ground_fraction;         /* added to the ground layer's Cn2 fraction, the rest rescaled [-] */
    double error_ground_top;              /* the ground layer: the lowest layer and those at or below this [m] */
    double error_r0_scale;                /* r0 times this [-] */
    double error_high_shift;              /* altitude added to the layers at or above error_high_bottom [m] */
    double error_high_bottom;             /* [m] */
    double error_wind_speed_scale;        /* every layer's wind speed times this [-] */
    double error_wind_direction;          /* added to every layer's wind direction [rad] */
} wt_model_atmosphere_config;

/* A changing night of the truth (SPEC §12 "A changing night"; atmosphere.night.*, sim/night.h): the r0,
 * Cn² fractions and winds of the truth's layers over the night's time, from a file or a stochastic model. */
enum { WT_NIGHT_CFG_NONE = 0, WT_NIGHT_CFG_FILE = 1, WT_NIGHT_CFG_RANDOM = 2 };
typedef struct wt_night_config {
    int source;                      /* WT_NIGHT_CFG_NONE (the atmosphere fixed), _FILE or _RANDOM */
    char file[1024];                 /* the night file as resolved (relative paths against the configuration's
                                        directory); "" without one */
    double start;                    /* night time of frame 0 [s] */
    double compression;              /* night seconds per simulated second [1] */
    uint64_t seed;                   /* random: its own seed */
    double correlation_time;         /* random: τ of the Ornstein–Uhlenbeck walks [s] */
    double step;                     /* random: spacing of its knots [s] */
    double r0_rms, fraction_rms, wind_speed_rms; /* random: rms of ln r0, ln f, ln v [1] */
    double wind_direction_rms;       /* random: rms of the direction [rad] */
} wt_night_config;

typedef struct wt_config {
    char path[1024];                 /* file it was read from */
    char *canonical;                 /* the effective configuration as libconfig text (owned) */
    char *matrix_text;               /* the canonical text of the keys that can change an MVM matrix (owned) */
    char matrix_sha256[65];          /* SHA-256 of matrix_text: the identity of the system for MVM files */

    /* telescope */
    double diameter;                 /* pupil diameter D [m] */
    double obstruction;              /* central obstruction, fraction of D */

    /* atmosphere (simulation truth) */
    double r0;                       /* Fried parameter at 500 nm [m] */
    double L0;                       /* outer scale [m] */
    int nlayers;
    double layer_altitude[WT_MAX_LAYERS]; /* [m] */
    double layer_fraction[WT_MAX_LAYERS]; /* Cn2 fractions, normalised to sum 1 */
    double wind_speed[WT_MAX_LAYERS];     /* [m/s] */
    double wind_direction[WT_MAX_LAYERS]; /* [rad], direction the layer moves towards */
    char atm_profile[1024];          /* atmosphere.profile as resolved: the file the four lists above came from,
                                        "" when the configuration gave them */
    wt_night_config night;           /* the truth's changing night (atmosphere.night.*) */

    /* laser guide stars */
    int nlgs;
    double lgs_radius;               /* asterism radius [rad] */
    double lgs_azimuth0;             /* azimuth of the first LGS [rad]; the others follow every 2π/nlgs */
    double lgs_altitude;             /* sodium layer altitude H [m] */
    double sodium_fwhm;              /* sodium layer thickness Δh_Na [m]; 0 = no elongation */
    double launch_radius;            /* side-launch radius [m], at the azimuth of its LGS */
    double lgs_tt_jitter;            /* random LGS tip-tilt per axis per frame [rad rms] */
    int lgs_reference_seeing;        /* diffractive LGS reference: 0 none (flat wavefront), 1 tilt-removed sky seeing,
                                        2 the same rendered on the simulation grid (core/optics/seeing.h) */
    double uplink_fwhm;              /* diffractive LGS: FWHM of the uplink (laser) spot on the sodium layer [rad] */
    char sodium_profile[1024];       /* diffractive LGS: the profile file as resolved (relative paths against the
                                        configuration file's directory); "" = Gaussian of sodium_fwhm */
    char sodium_profile_sha256[65];  /* diffractive LGS with a profile: SHA-256 (hex) of the file's bytes, taken at
                                        reading (or as recorded in a stored text); "" when not used or unreadable */
    char sodium_sequence[1024];      /* diffractive LGS: the truth's profile in time (core/optics/sodium.h), resolved;
                                        "" = the set-up profile for the whole run */
    double sodium_sequence_update;   /* night time between two rebuilds of the truth's spot tables [s]; 0: every frame */
    int lgs_reference;               /* diffractive LGS reference in the loop: 0 static (set-up), 1 oracle, 2 pixels */
    double lgs_reference_update;     /* oracle, pixels: night time between two rebuilds [s] */
    double lgs_gain_update;          /* the matched filter's gain from the loop's pixels: night time between two
                                        estimates [s]; 0: none */
    int lgs_focus_stage;             /* diffractive LGS: the WFS focus stage and tip-tilt centring (sim/focus_stage.h) */
    double lgs_focus_stage_gain;     /* its integrators' gain */
    wt_sensor_config lgs_wfs;

    /* natural guide stars */
    int nngs;
    double ngs_radius;               /* asterism radius [rad] */
    double ngs_azimuth[WT_MAX_GS];   /* [rad] */
    int ngs_subapertures[WT_MAX_GS]; /* 2 = 2x2 sensor, 1 = tip-tilt sensor */
    wt_sensor_config ngs_wfs;        /* subapertures unused (see ngs_subapertures) */

    /* deformable mirrors */
    int ndms;
    double dm_altitude[WT_MAX_DMS];  /* [m] */
    double dm_pitch[WT_MAX_DMS];     /* [m] */
    int dm_actuators[WT_MAX_DMS];    /* actuators per side */
    double dm_field_radius;
    int dm_guard_rings;              /* rings of guard actuators outside the active radius (SPEC §5) */          /* θc: actuator active within D/2 + h tan(θc) of the centre [rad] */

    /* evaluation */
    int eval_grid;                   /* directions per side of the square grid */
    double eval_spacing;             /* [rad] */
    double eval_wavelength;          /* [m] */
    int settle_frames;               /* frames left out of the long-exposure averages */

    /* loop */
    double rate;                     /* frame rate [Hz] */
    int frames;
    int delay;                       /* frames between measurement and application (2 in the paper) */
    double gain;                     /* integrator gain g */
    int ngain_levels;                /* 0: the single gain; else L + 1 (core/op/scale_gain.h) */
    double gain_levels[WT_MAX_GAIN_BANDS]; /* gain per spatial band of the DM commands, coarsest first */
    int gain_basis;                  /* the bands: 0 bilinear multiwavelets, 1 Daubechies DWT */

    /* simulation */
    int points_per_subaperture;      /* simulation grid points per LGS subaperture side */
    uint64_t seed;
    int noise;                       /* 0: noise-free sensors (the truth adds no noise) */
    int psf_interval;                /* long-exposure PSFs: every N-th frame after the settle frames (0: none) */
    int psf_pixels;                  /* side of the stored PSF images (even) */
    int npsf_wavelengths;            /* 0: PSFs at eval_wavelength only; else the list below */
    double psf_wavelength[WT_MAX_PSF_WAVELENGTHS]; /* wavelengths of the PSF bands [m] */
    int telemetry_maps;              /* sim --telemetry: residual maps and commands every N-th frame (0: none) */

    /* reconstructor */
    int prior_aliasing;              /* 1: prior variances of grid samples (aliased spectrum) */
    int model_error;                 /* 1: LGS noise variance + the layer-binning model error */
    int subgrid_error;               /* 1: LGS noise variance floored at the slope variance beyond the layer grids' Nyquist */
    int lgs_focus_removal;           /* 1: the tomography removes LGS focus as it removes LGS tip-tilt */
    int lgs_focus_mode;              /* with lgs_focus_removal: 0 each LGS's own focus, 1 only their common focus */
    int lit_sensor_model;            /* reconstructor's sensor model: 0 Fried (paper), 1 lit-area average */
    int mvm_precision;               /* storage of the MVM control matrix: WT_PREC_* of core/la/half.h (0 fp32) */
    char fft_wisdom[1024];           /* FFTW wisdom file of the reconstructor's transforms as resolved (relative paths
                                        against the configuration's directory); "" = FFTW_ESTIMATE (core/la/fft.h) */
    char fft_wisdom_sha256[65];      /* SHA-256 (hex) of that file's bytes, taken at reading (or as recorded in a
                                        stored text); "" when not used or unreadable */
    int sensor_points;               /* lit model: sample points per subaperture side */
    double alpha;                    /* prior weight α */
    double tau;                      /* elongation weight τ of the reconstructor's noise model */
    int wavelet_order;               /* Daubechies order N (2N taps) */
    int wavelet_levels;              /* J */
    int exact_prior;                 /* recon.prior as given (WT_CFG_PRIOR_*), or -1 when left out; the variants'
                                        resolved values are in pcg3.prior and cg9.prior */
    int warm_start;
    int predict;                     /* recon.predict: the layers moved by their wind over the loop's delay */
    double predict_lead_frames;      /* recon.predict_lead_frames: the lead in frames; 0: the loop's delay */
    int predict_integrator;          /* recon.predict_integrator: 0 on the commands, 1 on the layers (moved every frame) */
    wt_model_atmosphere_config model; /* the reconstructors' atmosphere (recon.atmosphere), not the truth's above */
    wt_recon_variant_config pcg3;    /* layers at the DM altitudes, no fitting */
    wt_recon_variant_config cg9;     /* layers at the atmosphere altitudes, fitting over the evaluation directions */
} wt_config;

/* Read, override and validate. overrides: n strings "key=value" (key = dotted libconfig path).
 * On error returns WT_ERR_CONFIG (or WT_ERR_IO for an unreadable file) with the message in ctx. */
int wt_config_read(wt_context *ctx, const char *path, int noverrides, const char *const *overrides,
                   wt_config **out);
/* Parse from a string (tests; `name` stands for the file name in messages). */
int wt_config_parse(wt_context *ctx, const char *text, const char *name, int noverrides,
                    const char *const *overrides, wt_config **out);
void wt_config_free(wt_context *ctx, wt_config *cfg);

/* Key `path`'s unit in the file ("" for none) and its description, from the schema (static strings); WT_OK, or
 * WT_ERR_INVALID (and both NULL) when it is not a key. For labels (a sweep's axis) and messages. */
int wt_config_key_doc(const char *path, const char **unit, const char **description);

/* Print every key with its type, range and unit (the config reference), one per line. */
void wt_config_print_reference(FILE *f);

#endif
