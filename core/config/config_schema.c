/* core/config/config_schema.c: the configuration schema (SPEC §1): every key of the presets with its type,
 * range, unit, scale to internal units, description and destination in wt_config, in the order of the
 * canonical text (SPEC §9), and the reference `wavetomo info --keys` prints from it. config_read.c reads,
 * overrides and validates, config_check.c checks across keys and config_canonical.c canonicalises by walking
 * the same table, so a key cannot be documented one way and read another. */
#include "config_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CF(f) offsetof(wt_config, f)
#define NOCOUNT ((size_t)-1)
#define INF HUGE_VAL
#define ARCSEC WT_ARCSEC
#define DEG (M_PI / 180.0)
#define MAS (1e-3 * WT_ARCSEC)
/* Every float key has finite bounds that the code can run: a value of 1e308
 * gives Inf/NaN deep inside a computation, and an extreme one overflows an index. The bounds are wide
 * (well beyond any telescope or atmosphere) and derived sizes are checked after loading (config_derived.c). */
#define GT0(hi) F_LO_OPEN, 0.0, (hi) /* in (0, hi] */
#define GE0(hi) 0, 0.0, (hi)         /* in [0, hi] */
#define ANYANGLE 0, -360.0, 360.0
#define MAXALT 1e6     /* [m]: any altitude, well above a sodium layer at 90 km */
#define MAXFIELD 3600  /* [arcsec]: one degree, far beyond any AO field */

/* the wrappers expand GT0/GE0/ANYANGLE into their three arguments before the real macro sees them */
#define KF(...) KF_(__VA_ARGS__)
#define KI(...) KI_(__VA_ARGS__)
#define KFL(...) KFL_(__VA_ARGS__)
#define KIL(...) KIL_(__VA_ARGS__)
#define KF_(p, fl, lo, hi, u, sc, dst, d) {p, K_FLOAT, fl, lo, hi, u, sc, CF(dst), NOCOUNT, 0, 0, NULL, 0, d}
#define KI_(p, fl, lo, hi, dst, d) {p, K_INT, fl, lo, hi, "", 1, CF(dst), NOCOUNT, 0, 0, NULL, 0, d}
#define KB(p, dst, d) {p, K_BOOL, 0, 0, 1, "", 1, CF(dst), NOCOUNT, 0, 0, NULL, 0, d}
#define KE(p, ch, dst, d) {p, K_ENUM, 0, 0, 0, "", 1, CF(dst), NOCOUNT, 0, 0, ch, 0, d}
#define KFL_(p, fl, lo, hi, u, sc, dst, cnt, mn, mx, d) {p, K_FLOATS, fl, lo, hi, u, sc, CF(dst), CF(cnt), mn, mx, NULL, 0, d}
#define KIL_(p, fl, lo, hi, dst, cnt, mn, mx, d) {p, K_INTS, fl, lo, hi, "", 1, CF(dst), CF(cnt), mn, mx, NULL, 0, d}
/* keys with a default (F_DEFAULT: left out = the default written in the file, so in the canonical text and the
 * matrix hash as if given); def in the file's unit, an enum's the index of its choice; the text says it */
#define KFD(...) KFD_(__VA_ARGS__)
#define KID(...) KID_(__VA_ARGS__)
#define KFD_(p, fl, lo, hi, u, sc, dst, def, d) {p, K_FLOAT, F_DEFAULT | (fl), lo, hi, u, sc, CF(dst), NOCOUNT, 0, 0, NULL, def, d}
#define KID_(p, fl, lo, hi, dst, def, d) {p, K_INT, F_DEFAULT | (fl), lo, hi, "", 1, CF(dst), NOCOUNT, 0, 0, NULL, def, d}
#define KBD(p, dst, def, d) {p, K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(dst), NOCOUNT, 0, 0, NULL, def, d}
#define KED(p, ch, dst, def, d) {p, K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(dst), NOCOUNT, 0, 0, ch, def, d}

#define SENSOR(pre, w, rn, rns, fw, fws, px, pxs, cdef, cdefs, npdef, npdefs, nfdef, nfdefs, kdef, kdefs, wldef, wldefs)   \
    KF(pre ".photons", GT0(1e12), "photons", 1, w.photons, "detected photons per subaperture per frame"),        \
    KFD(pre ".read_noise_e", GE0(1e6), "e-", 1, w.read_noise_e, rn,                                          \
        "read noise per pixel (rms) (optional, default " rns ")"),                                           \
    KFD(pre ".spot_fwhm_arcsec", GT0(MAXFIELD), "arcsec", ARCSEC, w.spot_fwhm, fw,                           \
        "FWHM of the non-elongated spot (optional, default " fws ")"),                                       \
    KFD(pre ".pixel_arcsec", GT0(MAXFIELD), "arcsec", ARCSEC, w.pixel, px, "pixel scale (optional, default " pxs ")"), \
    KID(pre ".pixels", 0, 1, 1024, w.pixels, 4, "pixels across a subaperture (Ns) (optional, default 4)"),   \
    {pre ".nea_mas", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e7, "mas", MAS, CF(w.nea), NOCOUNT, 0, 0, NULL, -1.0, \
     "noise-equivalent angle per axis (rms) of the unelongated spot (the short axis of an elongated one); when "  \
     "given it replaces the photon/read-noise model"},                                                     \
    {pre ".lit_noise", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(w.lit_noise), NOCOUNT, 0, 0, NULL, 0,              \
     "a partly lit subaperture collects its lit fraction f of a full one's photons: the per-axis variance " \
     "is that of f N photons (NEA^2 / f with nea_mas), in the simulated noise and the reconstructor's "      \
     "weights (optional, default false)"},                                                                  \
    DIFFRACTIVE(pre, w, cdef, cdefs, npdef, npdefs, nfdef, nfdefs, kdef, kdefs, wldef, wldefs)

/* The diffractive sensor (SPEC §4b, docs/design.md "Diffractive sensing"): keys read only when
 * <pre>.model = "diffractive"; each has a default (F_DEFAULT), so today's files read as before. */
#define DFLT(p, t, fl, lo, hi, u, sc, dst, ch, d, txt) {p, t, F_DEFAULT | (fl), lo, hi, u, sc, CF(dst), NOCOUNT, 0, 0, ch, d, txt}
#define DIFFRACTIVE(pre, w, cdef, cdefs, npdef, npdefs, nfdef, nfdefs, kdef, kdefs, wldef, wldefs)                        \
    DFLT(pre ".model", K_ENUM, 0, 0, 0, "", 1, w.model, "geometric|diffractive", 0,                          \
         "sensor model: geometric = average gradient over the lit area plus a Gaussian draw of the "         \
         "reconstructor's noise model; diffractive = spot images (FFT of the lit pupil at wavelength_nm, LGS "  \
         "sodium line + uplink spot) on pixels with photon, read and background noise, measured by the "      \
         "centroider; the reconstructor's noise model is the centroider's covariance (docs/design.md) "       \
         "(optional, default geometric)"),                                                                   \
    DFLT(pre ".centroider", K_ENUM, 0, 0, 0, "", 1, w.centroider, "cog|tcog|mf", cdef,                       \
         "diffractive: cog = centre of gravity in the window, tcog = thresholded CoG, mf = matched filter "  \
         "from the noise-free reference image and its derivatives (optional, default " cdefs ")"),           \
    DFLT(pre ".apply_gain", K_BOOL, 0, 0, 1, "", 1, w.apply_gain, NULL, 1,                                   \
         "diffractive: correct each subaperture's slopes (and its noise covariance) by the inverse of the "  \
         "centroider's calibrated 2x2 gain (optional, default true)"),                                       \
    DFLT(pre ".tcog_threshold_noise", K_FLOAT, 0, 0.0, 100.0, "", 1, w.threshold_noise, NULL, 3.0,           \
         "tcog: threshold T = this x sqrt(read_noise_e^2 + background_e) + tcog_threshold_peak x the "       \
         "reference peak [e-] (optional, default 3)"),                                                       \
    DFLT(pre ".tcog_threshold_peak", K_FLOAT, F_HI_OPEN, 0.0, 1.0, "", 1, w.threshold_peak, NULL, 0.0,       \
         "tcog: the fraction of the noise-free reference peak in the threshold (optional, default 0)"),      \
    DFLT(pre ".window_pixels", K_INT, 0, 0, 1024, "", 1, w.window_pixels, NULL, 0,                           \
         "diffractive cog/tcog: window of this many pixels per side centred on the detector (pixels minus "  \
         "it even); 0 = the whole detector; mf uses every pixel (0 only) (optional, default 0)"),            \
    DFLT(pre ".background_e", K_FLOAT, 0, 0.0, 1e9, "e-", 1, w.background_e, NULL, 0.0,                      \
         "diffractive: background (sky, Rayleigh) per pixel per frame, Poisson, subtracted (optional, "      \
         "default 0)"),                                                                                      \
    DFLT(pre ".pupil_samples", K_INT, 0, 2, 1024, "", 1, w.pupil_samples, NULL, npdef,                       \
         "diffractive: pupil samples across a subaperture (the OPD is interpolated from the simulation grid "\
         "onto them); the FFT field is pupil_samples x wavelength / subaperture side (optional, default "    \
         npdefs ")"),                                                                                        \
    DFLT(pre ".fft_size", K_INT, 0, 4, 4096, "", 1, w.fft_size, NULL, nfdef,                                 \
         "diffractive: FFT points per side, even, >= 2 x pupil_samples (Nyquist sampling of wavelength / "   \
         "subaperture side) (optional, default " nfdefs ")"),                                                \
    DFLT(pre ".cells_per_pixel", K_INT, F_ODD, 1, 15, "", 1, w.cells_per_pixel, NULL, kdef,                  \
         "diffractive: rebinning cells per pixel side, odd (core/optics/spot.h): cells of pixel_arcsec / "   \
         "this blur a spot by (cell)^2/6 per axis where no source (the LGS uplink) absorbs it (optional, "    \
         "default " kdefs ")"),                                                                               \
    DFLT(pre ".wavelength_nm", K_FLOAT, 0, 100.0, 1e5, "nm", 1e-9, w.wavelength, NULL, wldef,                \
         "diffractive: sensing wavelength (optional, default " wldefs ")"),                                  \
    DFLT(pre ".noise_calibration", K_ENUM, 0, 0, 0, "", 1, w.noise_calibration, "analytic|montecarlo", 0,    \
         "diffractive: the reconstructor's 2x2 noise covariance per subaperture: analytic = first-order "    \
         "propagation of photon, read and background noise through the centroider; montecarlo = "            \
         "calibration_draws noisy reference frames with calibration_seed (optional, default analytic)"),     \
    DFLT(pre ".calibration_draws", K_INT, 0, 2, 10000000, "", 1, w.calibration_draws, NULL, 1000,            \
         "montecarlo: noisy frames per subaperture (optional, default 1000)"),                               \
    DFLT(pre ".calibration_seed", K_INT64, 0, 0.0, INF, "", 1, w.calibration_seed, NULL, 1,                  \
         "montecarlo: seed of the calibration draws (its own, not sim.seed) (optional, default 1)")

/* The automatic layer grids (config_grid.c, docs/design.md): the spacing rule of each variant, and what
 * pcg3's layers must also hold (the actuators they are read at). */
#define PCG3_SPACING "the pitch of the DM at the layer's altitude (the finer of the two DMs around it, the end DM " \
                     "outside their range)"
#define CG9_SPACING "min(LGS subaperture side d, the pitch of the DM at the layer's altitude or the finer of the two " \
                    "DMs around it, the end DM outside their range)"
#define PCG3_COVER " and the active actuators of the DMs the layer is read at"

#define PRIOR_CHOICES "paper|exact|full"
#define PRIOR_DESC "paper = the paper's scale-only diagonal D in the wavelet basis, exact = the exact diagonal "   \
                   "diag(W C W^T), full = the von Karman covariance C itself on the periodic layer grid, applied by " \
                   "FFT (not diagonal; an MVM built with it has a dense normal matrix, n² doubles: 4.8 GB for pcg3 at E-ELT size)"

#define VARIANT(pre, v, spacing_rule, cover, prior_default, alt_from, iters, iterss, prec, precs)                        \
    KFL(pre ".layer_altitudes_m", F_INCR | F_DEFAULT, 0.0, MAXALT, "m", 1, v.altitudes, v.nlayers, 1, WT_MAX_LAYERS, \
        "reconstruction layer altitudes, strictly increasing (optional, default " alt_from ")"),                 \
    {pre ".layer_spacing_m", K_FLOATS, F_LO_OPEN | F_AUTO, 0.0, 100.0, "m", 1, CF(v.spacing), CF(v.nlayers), 1,   \
     WT_MAX_LAYERS, NULL, 0, "grid spacing of each reconstruction layer; left out (or \"auto\"): per layer, "     \
     spacing_rule " / layer_oversampling (docs/design.md)"},                                          \
    {pre ".layer_size", K_INTS, F_POW2 | F_AUTO, 4, 8192, "", 1, CF(v.size), CF(v.nlayers), 1, WT_MAX_LAYERS, NULL, 0, \
     "grid points per side of each layer, >= 2^recon.wavelet_levels; left out (or \"auto\"): the smallest power of " \
     "two whose grid covers every LGS, NGS and evaluation footprint at the layer's altitude" cover   \
     "; with layer_spacing_m given, for that spacing (a size without layer_spacing_m is refused)"},                                                   \
    {pre ".layer_oversampling", K_FLOAT, F_OPT, 0.25, 16.0, "", 1, CF(v.oversampling), NOCOUNT, 0, 0, NULL, 1.0, \
     "the automatic layer_spacing_m is divided by this (default 1); refused beside a given layer_spacing_m"},                                                                                        \
    KID(pre ".iterations", 0, 1, 1000000, v.iterations, iters, "(P)CG iterations per frame (optional, default " iterss ")"), \
    KFD(pre ".tolerance", F_HI_OPEN, 0.0, 1.0, "", 1, v.tolerance, 0.0,                                      \
        "relative residual to stop at; 0 = always run all iterations (optional, default 0)"),                \
    KED(pre ".preconditioner", "none|jacobi|jacobi_ngs|coarse_ngs|multilevel|fourier", v.preconditioner, prec, \
       "jacobi = modified Jacobi PCG, jacobi_ngs = the same plus the exact rank-r NGS term (Woodbury), "   \
       "coarse_ngs = jacobi_ngs with the coarse wavelet coefficients of all layers inverted as one exact "  \
       "block, multilevel = coarse_ngs with, below the coarse block, the layers' coefficients at each "     \
       "detail level, orientation and position inverted as one exact block, fourier = each spatial "       \
       "frequency of the layers scaled by the inverse of the largest eigenvalue of the layers' symbol "    \
       "there, the coarsest scales solved exactly, plus the NGS term (every layer on one n x n grid, the full "  \
       "prior; the solve runs on the layers' values instead of their wavelet coefficients: the same "       \
       "iterates without the DWTs), none = plain CG (optional, default " precs ")"),                        \
    {pre ".coarse_levels", K_INT, F_DEFAULT, 0, 30, "", 1, CF(v.coarse_levels), NOCOUNT, 0, 0, NULL, 2,       \
     "coarse_ngs and multilevel: the coarse block holds the scaling coefficients and the coarse_levels "   \
     "coarsest detail levels of every layer; fourier: the same space, exactly (0 = the scaling "          \
     "functions: the E-ELT preset's comment) (optional, default 2)"},                                      \
    {pre ".loop_noise_average", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(v.loop_noise_average), NOCOUNT, 0, 0, NULL, 0, \
     "noise model of the loop's command: the sensors' noise variance times the integrator's noise gain "   \
     "(the sum of its squared impulse response for loop.gain and loop.delay_frames, 0.389 for 0.4 and 2); " \
     "the model error is not averaged (optional, default false)"},                                        \
    {pre ".prior", K_ENUM, F_AUTO, 0, 0, "", 1, CF(v.prior), NOCOUNT, 0, 0, PRIOR_CHOICES, 0,                    \
     "the variant's prior: " PRIOR_DESC "; left out (or \"auto\"): recon.prior when given, else "            \
     prior_default " (docs/design.md) (optional)"},                                                          \
    {pre ".operator_precision", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(v.operator_precision), NOCOUNT, 0, 0, "fp64|fp32", 0, \
     "the solver's normal operator and right-hand side: fp64, or fp32 = the layers' inverse DWT and the LGS's "    \
     "forward (P, Γ) and adjoint (Ĉ⁻¹, Γᵀ, Pᵀ) in single precision, 16 points per AVX-512 vector, and "            \
     "coarse_ngs's two stored matrices in float (applied in double); the NGS's part (10^5 times the LGS's weight "  \
     "at low noise: an explicit matrix over their few slopes), the prior, the forward DWT and the (P)CG stay "      \
     "double (docs/design.md \"Single-precision operator\") (optional, default fp64)"}

const wt_config_priv_key_spec wt_config_priv_keys[] = {
    KF("telescope.diameter_m", GT0(100.0), "m", 1, diameter, "pupil diameter D"),
    KF("telescope.obstruction", F_HI_OPEN, 0.0, 1.0, "", 1, obstruction, "central obstruction, fraction of D"),

    KF("atmosphere.r0_m", 0, 1e-3, 1e4, "m", 1, r0, "Fried parameter r0 at 500 nm"),
    KF("atmosphere.L0_m", 0, 1.0, 1e4, "m", 1, L0, "von Karman outer scale L0"),
    {"atmosphere.profile", K_STR, F_OPT, 0, 0, "", 1, CF(atm_profile), NOCOUNT, 0, 0, NULL, 0,
     "the truth's profile from a file (relative to the configuration file's directory like @include; shipped: "
     "data/atmosphere/eso35-median.txt): one layer a line, columns altitude [m], Cn2 fraction, wind speed [m/s] and "
     "an optional wind direction [deg]; '#' starts a comment. Altitudes strictly increasing, fractions >= 0 summing "
     "to 1 within 1e-3 (then normalised to 1), every line the same columns. The file fills altitudes_m, "
     "cn2_fractions, wind_speed_mps (and wind_direction_deg when it has the column), which are then left out; "
     "without the column, wind_direction_deg gives the directions. The canonical text holds the lists"},
    KFL("atmosphere.altitudes_m", F_INCR, 0.0, MAXALT, "m", 1, layer_altitude, nlayers, 1, WT_MAX_LAYERS,
        "altitude of each layer, strictly increasing"),
    KFL("atmosphere.cn2_fractions", 0, 0.0, 1.0, "", 1, layer_fraction, nlayers, 1, WT_MAX_LAYERS,
        "Cn2 fraction of each layer; the sum must be 1 within 1 % (then normalised to 1)"),
    KFL("atmosphere.wind_speed_mps", GE0(1000.0), "m/s", 1, wind_speed, nlayers, 1, WT_MAX_LAYERS, "wind speed of each layer"),
    KFL("atmosphere.wind_direction_deg", ANYANGLE, "deg", DEG, wind_direction, nlayers, 1, WT_MAX_LAYERS,
        "direction each layer moves towards, from +x towards +y"),
    /* a changing night of the truth (SPEC §12; sim/night.h): simulation only, never in the matrix identity */
    {"atmosphere.night.source", K_ENUM, F_OPT, 0, 0, "", 1, CF(night.source), NOCOUNT, 0, 0, "none|file|random", 0,
     "a changing night for the truth (the simulated atmosphere only; the reconstructors keep their own): none = the "
     "atmosphere above, fixed for the run; file = the states of atmosphere.night.file; random = the stochastic model "
     "of the atmosphere.night walk keys around the atmosphere above. The night's state at each frame's night time "
     "(start_s + frame time x compression x frame) scales each layer's screen by sqrt(f r0^(-5/3) / (f_0 r0_0^(-5/3))) "
     "against the configured f_0, r0_0 (L0 fixed; the layer count and altitudes are the configured ones) and moves "
     "it by its current wind over each frame time (docs/design.md \"A changing night\") (default none)"},
    {"atmosphere.night.file", K_STR, F_OPT, 0, 0, "", 1, CF(night.file), NOCOUNT, 0, 0, NULL, 0,
     "file: the night's states (relative to the configuration file's directory like @include; shipped: data/nights/),"
     " one a line: night time [s], r0 [m], then per layer of the truth its Cn2 fraction, wind speed [m/s] and wind "
     "direction [deg]; '#' starts a comment. Times strictly increasing, r0 > 0, fractions >= 0 summing to 1 within "
     "1e-3; interpolated linearly in time (fractions renormalised to 1, directions along the shorter arc); the states "
     "must cover the run's night times"},
    {"atmosphere.night.start_s", K_FLOAT, F_OPT, 0.0, 1e7, "s", 1, CF(night.start), NOCOUNT, 0, 0, NULL, 0.0,
     "the night time of the run's first frame (default 0)"},
    {"atmosphere.night.compression", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e7, "", 1, CF(night.compression), NOCOUNT, 0,
     0, NULL, 1.0,
     "time compression: night seconds per simulated second; each frame advances the night's clock by frame time x "
     "this while the turbulence moves by the frame time (SPEC §12: a short run stands for a long night) (default 1)"},
    {"atmosphere.night.seed", K_INT64, F_OPT, 0.0, INF, "", 1, CF(night.seed), NOCOUNT, 0, 0, NULL, 1,
     "random: the walks' own seed (not sim.seed: the same night under other turbulence) (default 1)"},
    {"atmosphere.night.correlation_time_s", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e7, "s", 1, CF(night.correlation_time),
     NOCOUNT, 0, 0, NULL, 1800.0,
     "random: correlation time tau of every walk, an Ornstein-Uhlenbeck process in log r0, log f, log v and the "
     "direction: correlation exp(-|dt| / tau) (default 1800, an assumption: profiles change over tens of minutes)"},
    {"atmosphere.night.step_s", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e6, "s", 1, CF(night.step), NOCOUNT, 0, 0, NULL, 10.0,
     "random: the walks are sampled exactly every step_s from night time 0 (where they start at the configured "
     "state) and interpolated linearly between (default 10)"},
    {"atmosphere.night.r0_log_rms", K_FLOAT, F_OPT, 0.0, 10.0, "", 1, CF(night.r0_rms), NOCOUNT, 0, 0, NULL, 0.2,
     "random: stationary rms of ln r0 (r0 = r0_m exp(this z), z a unit walk) (default 0.2, an assumption)"},
    {"atmosphere.night.fraction_log_rms", K_FLOAT, F_OPT, 0.0, 10.0, "", 1, CF(night.fraction_rms), NOCOUNT, 0, 0,
     NULL, 0.3,
     "random: stationary rms of ln f of each layer's Cn2 weight, each its own walk, renormalised to sum 1 (default "
     "0.3, an assumption)"},
    {"atmosphere.night.wind_speed_log_rms", K_FLOAT, F_OPT, 0.0, 10.0, "", 1, CF(night.wind_speed_rms), NOCOUNT, 0, 0,
     NULL, 0.2, "random: stationary rms of ln v of each layer's wind speed (default 0.2, an assumption)"},
    {"atmosphere.night.wind_direction_rms_deg", K_FLOAT, F_OPT, 0.0, 360.0, "deg", DEG, CF(night.wind_direction_rms),
     NOCOUNT, 0, 0, NULL, 10.0 * DEG,
     "random: stationary rms of each layer's wind direction about the configured one (default 10)"},

    KI("lgs.count", 0, 0, WT_MAX_GS, nlgs, "number of laser guide stars, evenly spaced in azimuth"),
    KF("lgs.radius_arcsec", GE0(MAXFIELD), "arcsec", ARCSEC, lgs_radius, "radius of the LGS asterism"),
    KF("lgs.azimuth0_deg", ANYANGLE, "deg", DEG, lgs_azimuth0, "azimuth of the first LGS; the others follow every 360/count deg"),
    KFD("lgs.altitude_m", GT0(MAXALT), "m", 1, lgs_altitude, 90000.0,
        "sodium layer altitude H; above every atmosphere, DM and reconstruction layer (optional, default 90000)"),
    KFD("lgs.sodium_fwhm_m", GE0(1e5), "m", 1, sodium_fwhm, 10000.0,
        "sodium layer FWHM thickness (spot elongation); 0 = no elongation; a diffractive LGS with "
        "lgs.sodium_profile uses the profile instead (optional, default 10000)"),
    KFD("lgs.launch_radius_m", GE0(1000.0), "m", 1, launch_radius, 0.0,
        "side-launch distance from the pupil centre, at the azimuth of its LGS (optional, default 0: launched from "
        "the centre, behind the secondary; a side launch elongates the spots more and must be given)"),
    KFD("lgs.tt_jitter_arcsec", GE0(100.0), "arcsec", ARCSEC, lgs_tt_jitter, 0.2,
        "random LGS tip-tilt per axis per frame (rms) (optional, default 0.2)"),
    KI("lgs.wfs.subapertures", 0, 1, 1024, lgs_wfs.subapertures, "Shack-Hartmann subapertures across the pupil"),
    KFD("lgs.wfs.valid_fraction", F_LO_OPEN, 0.0, 1.0, "", 1, lgs_wfs.valid_fraction, 0.5,
        "a subaperture is used when at least this fraction is illuminated (NGS sensors too) (optional, default 0.5)"),
    SENSOR("lgs.wfs", lgs_wfs, 3.0, "3", 1.1, "1.1", 1.0, "1", 2, "mf", 16, "16", 32, "32", 3, "3: 0.37 arcsec cells at 1.1 arcsec pixels, whose "
           "blur the 1 arcsec uplink spot absorbs", 589.0, "589 (sodium D2)"),
    {"lgs.uplink_fwhm_arcsec", K_FLOAT, F_DEFAULT, 0.0, 100.0, "arcsec", ARCSEC, CF(uplink_fwhm), NOCOUNT, 0, 0, NULL, 1.0,
     "diffractive LGS: FWHM of the Gaussian uplink (laser) spot on the sodium layer, convolved with the sodium "
     "line (optional, default 1)"},
    {"lgs.wfs.reference_seeing", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(lgs_reference_seeing), NOCOUNT, 0, 0,
     "none|tilt_removed|rendered", 1,
     "diffractive LGS: the seeing in the centroider's reference I0 and its derivatives (so in the matched "
     "filter and the reconstructor's noise covariance): tilt_removed = the mean short-exposure spot under the "
     "atmosphere's r0 and L0 at the sensing wavelength with each subaperture's tilt removed (the spot a "
     "sensor sees in the loop on the sky); rendered = the same seeing as the simulation renders it, on screens "
     "of the simulation grid's spacing (sim.points_per_subaperture) read by bilinear interpolation, which hold "
     "less of the finest turbulence: the spot the simulated sensor sees (core/optics/seeing.h); none = the "
     "diffraction-limited spot of a flat wavefront (a matched filter whose in-loop gain is below 1 and whose "
     "covariance is optimistic) (optional, default tilt_removed)"},
    {"lgs.sodium_profile", K_STR, F_OPT, 0, 0, "", 1, CF(sodium_profile), NOCOUNT, 0, 0, NULL, 0,
     "diffractive LGS: sodium density profile file, two columns \"altitude_m density\" (altitude above the "
     "telescope), relative to the configuration file's directory like @include (shipped: "
     "data/sodium/default.txt); left out: a Gaussian layer of lgs.sodium_fwhm_m at lgs.altitude_m. With a "
     "profile, lgs.sodium_fwhm_m is not used by the diffractive model (the geometric model ignores the file)"},
    {"lgs.sodium_profile_sha256", K_STR, F_AUTO | F_HEX, 0, 0, "", 1, CF(sodium_profile_sha256), NOCOUNT, 0, 0, NULL, 0,
     "diffractive LGS with lgs.sodium_profile: SHA-256 of the profile file's bytes, so that the matrix hash follows "
     "the file's contents (not its name); left out (or \"auto\"): computed when the configuration is read and "
     "written into the canonical text; given (a stored configuration): the file must still hash to it when the "
     "sensors are built"},
    /* the sodium layer in time (SPEC §12 "The sodium layer changes too"; core/optics/sodium.h): the truth's spots
     * and the loop's reference only, never in the matrix identity (the set-up reference is lgs.sodium_profile's) */
    {"lgs.sodium_sequence", K_STR, F_OPT, 0, 0, "", 1, CF(sodium_sequence), NOCOUNT, 0, 0, NULL, 0,
     "diffractive LGS: the truth's sodium profile in time, a file (relative to the configuration file's directory "
     "like @include; shipped: data/sodium/drift-1km-10min.txt, sporadic-2min.txt): a line 'altitude_m h1 h2 ...', "
     "then one line per night time 'time_s d1 d2 ...', interpolated linearly in time (format in "
     "core/optics/sodium.h). Each frame's night time is atmosphere.night.start_s + frame / loop.rate_hz x "
     "atmosphere.night.compression (the night's clock, with or without atmosphere.night.source), and the sequence "
     "must cover the run's. The spots follow it; the set-up reference (and the MVM's noise model) stays that of "
     "lgs.sodium_profile (or the Gaussian of lgs.sodium_fwhm_m), so start the sequence from that profile for a "
     "reference right at the start; lgs.wfs.reference = oracle follows the truth (optional, default none)"},
    {"lgs.sodium_sequence_update_s", K_FLOAT, F_OPT, 0.0, 1e7, "s", 1, CF(sodium_sequence_update), NOCOUNT, 0, 0,
     NULL, 0.0,
     "diffractive LGS with lgs.sodium_sequence: night time between two rebuilds of the truth's spot tables from the "
     "sequence (0: every frame; otherwise at least one frame's night time, 1 / loop.rate_hz x "
     "atmosphere.night.compression). A rebuild costs ~1.1 s of 2 idle cores for the 6 E-ELT LGS, ~3 times a "
     "diffractive frame's sensing (make bench): at that size give a cadence of several frames (optional, default 0)"},
    {"lgs.wfs.reference", K_ENUM, F_OPT, 0, 0, "", 1, CF(lgs_reference), NOCOUNT, 0, 0, "static|oracle|pixels", 0,
     "diffractive LGS: the centroider's reference I0 and its derivatives in the loop: static = built once at set-up "
     "from lgs.sodium_profile; oracle = rebuilt from the truth's current sodium profile (lgs.sodium_sequence) every "
     "lgs.wfs.reference_update_s of night time from the first frame on; pixels = rebuilt every "
     "lgs.wfs.reference_update_s from each subaperture's mean image over that period, every frame's image re-centred "
     "by its measured slopes (cubic B-spline), its derivatives those of the mean image (needs at least 2 frames per "
     "period; the set-up's reference until the first period is full); both with the matched filter, its covariance "
     "and the pcg3 / cg9 noise weights C_E (an MVM keeps the C_E it was built with) (optional, default static)"},
    {"lgs.wfs.reference_update_s", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e7, "s", 1, CF(lgs_reference_update), NOCOUNT,
     0, 0, NULL, 60.0,
     "lgs.wfs.reference = oracle or pixels: night time between two rebuilds of the reference (oracle: at least one "
     "frame's night time, pixels: at least two) (optional, default 60)"},
    {"lgs.wfs.gain_update_s", K_FLOAT, F_OPT, 0.0, 1e7, "s", 1, CF(lgs_gain_update), NOCOUNT, 0, 0, NULL, 0.0,
     "diffractive LGS with the matched filter (lgs.wfs.centroider = \"mf\"): night time between two measurements of "
     "the filter's gain on the loop's own pixels — the response to the derivative of the mean image of the period's "
     "frames, pooled in 8 classes by the distance from the launch, along and across the elongation — whose inverse "
     "then corrects the slopes and the noise model (pcg3 / cg9 C_E; an MVM keeps its own); at least two frames' night "
     "time; 0: none, the filter's gain is its reference's (optional, default 0)"},
    {"lgs.wfs.focus_stage", K_BOOL, F_OPT, 0, 1, "", 1, CF(lgs_focus_stage), NOCOUNT, 0, 0, NULL, 0,
     "diffractive LGS with lgs.sodium_sequence and recon.lgs_focus_removal = true: each LGS wavefront sensor has a "
     "focus stage that follows the focus common to the LGS's measured slopes, and each LGS's spots are centred on "
     "their mean tip-tilt (the launch telescope's steering mirror); both move the source as the sensor sees it, at "
     "each rebuild of the truth's spot tables (lgs.sodium_sequence_update_s), from the mean of the frames since the "
     "last (sim/focus_stage.h): a change of the sodium centroid's altitude then leaves the spots on the matched "
     "filter's reference instead of 1-2 pixels off it at 42 m (closed loop only) (optional, default false)"},
    {"lgs.wfs.focus_stage_gain", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1.0, "", 1, CF(lgs_focus_stage_gain), NOCOUNT, 0, 0,
     NULL, 0.5,
     "lgs.wfs.focus_stage = true: the gain of the focus stage's and the centring's integrators, per move (optional, "
     "default 0.5)"},

    KF("ngs.radius_arcsec", GE0(MAXFIELD), "arcsec", ARCSEC, ngs_radius, "radius of the NGS asterism"),
    KFL("ngs.azimuths_deg", ANYANGLE, "deg", DEG, ngs_azimuth, nngs, 0, WT_MAX_GS, "azimuth of each NGS"),
    KIL("ngs.subapertures", 0, 1, 2, ngs_subapertures, nngs, 0, WT_MAX_GS,
        "sensor of each NGS: 2 = 2x2 Shack-Hartmann, 1 = tip-tilt"),
    SENSOR("ngs.wfs", ngs_wfs, 5.0, "5", 0.1, "0.1: a partially corrected H-band spot", 0.05, "0.05", 0, "cog", 64,
           "64: the 1x1 sensor's whole pupil at D/64 (0.66 m on 42 m), an FFT field of 64 x 1650 nm / 42 m = 0.52 "
           "arcsec (1.04 arcsec for the 2x2), which holds a partially corrected H-band spot and +-0.2 arcsec of "
           "tip-tilt; the slopes of 64, 128 and 256 samples agree within 0.1 mas (docs/design.md, make bench-ngs)",
           128, "128 (Nyquist, 2 x pupil_samples)", 9,
           "9: the point-source spot (lambda/D = 8 mas on 42 m) is far smaller than a pixel, and cells of p/3 "
           "would widen it: at 0.05 arcsec pixels 3 cells/pixel give a tCoG gain 43 % low and an NEA 75 % high, "
           "9 cells/pixel within 2 %",
           1650.0, "1650 (H band)"),
    {"ngs.wfs.tilt", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(ngs_wfs.tilt), NOCOUNT, 0, 0, "g|z", 0,
     "what an NGS slope is, in the simulated sensors and the reconstructor's model alike: g = G-tilt, the "
     "average gradient over the lit area (what a centroiding sensor measures), z = Z-tilt, the least-squares "
     "plane over it (as other simulators' tip-tilt sensors; for like-for-like comparisons) (optional, default g)"},

    KFL("dm.altitudes_m", GE0(MAXALT), "m", 1, dm_altitude, ndms, 1, WT_MAX_DMS, "conjugation altitude of each DM"),
    KFL("dm.pitch_m", GT0(100.0), "m", 1, dm_pitch, ndms, 1, WT_MAX_DMS, "actuator pitch of each DM"),
    KIL("dm.actuators", 0, 2, 4096, dm_actuators, ndms, 1, WT_MAX_DMS, "actuators per side of each DM"),
    KF("dm.field_radius_arcsec", GE0(MAXFIELD), "arcsec", ARCSEC, dm_field_radius,
       "theta_c: an actuator is active within D/2 + h tan(theta_c) of the centre"),
    {"dm.guard_rings", K_INT, F_DEFAULT, 0, 4, "", 1, CF(dm_guard_rings), NOCOUNT, 0, 0, NULL, 1,
     "rings of guard actuators: also active when within this many pitches (square support) of that disk; "
     "the grid grows by this many actuators on each side; 0 = the paper's active set (optional, default 1)"},

    KID("evaluation.grid", F_ODD, 1, 15, eval_grid, 5,
        "evaluation directions per side of the square grid (optional, default 5)"),
    KFD("evaluation.spacing_arcsec", GE0(MAXFIELD), "arcsec", ARCSEC, eval_spacing, 30.0,
        "spacing of the evaluation directions (optional, default 30: a 2 arcmin square with the default grid)"),
    KFD("evaluation.wavelength_nm", 0, 10.0, 1e6, "nm", 1e-9, eval_wavelength, 2200.0,
        "wavelength of the Strehl ratios (optional, default 2200: K band)"),
    KID("evaluation.settle_frames", 0, 0, INF, settle_frames, 20,
        "frames left out of the long-exposure averages; < loop.frames (optional, default 20)"),

    KFD("loop.rate_hz", 0, 1.0, 1e6, "Hz", 1, rate, 500.0, "frame rate (optional, default 500)"),
    KID("loop.frames", 0, 1, INF, frames, 200, "frames to run (optional, default 200)"),
    KID("loop.delay_frames", 0, 1, 2, delay, 2, "frames between measurement and application (optional, default 2)"),
    KFD("loop.gain", F_LO_OPEN, 0.0, 1.0, "", 1, gain, 0.4, "integrator gain g (optional, default 0.4)"),
    {"loop.gain_levels", K_FLOATS, F_OPT | F_LO_OPEN, 0.0, 1.0, "", 1, CF(gain_levels), CF(ngain_levels), 2,
     WT_MAX_GAIN_BANDS, NULL, 0,
     "integrator gain per spatial scale of the DM commands, coarsest first: [g_0, ..., g_L]; band 0 = what is "
     "bilinear over squares of 2^(L+1) actuators (piston, tip, tilt, saddle), band j = what squares of 2^(L+1-j) "
     "add, band L = what is not bilinear over 4x4 squares (features of 2 pitches); each DM's grid embedded "
     "centred in the smallest power of two n, L + 1 <= log2 n for every DM; G = sum g_j Pi_j is symmetric with "
     "eigenvalues g_j (docs/design.md); replaces loop.gain in the integrator, which still sets the error budget "
     "and loop_noise_average; left out: loop.gain at every scale"},
    {"loop.gain_basis", K_ENUM, F_OPT, 0, 0, "", 1, CF(gain_basis), NOCOUNT, 0, 0, "bilinear|daubechies", 0,
     "bands of loop.gain_levels: bilinear = orthonormal bilinear multiwavelets of the active actuators (a tilt "
     "is all band 0); daubechies = the zero-padded periodic DWT of order recon.wavelet_order, band j = its "
     "detail level L+1-j (the edge of the active disk leaks a tilt into the detail bands) (default bilinear)"},

    KID("sim.points_per_subaperture", 0, 1, 16, points_per_subaperture, 4,
        "simulation grid points per LGS subaperture side (optional, default 4)"),
    {"sim.seed", K_INT64, F_DEFAULT, 0.0, INF, "", 1, CF(seed), NOCOUNT, 0, 0, NULL, 1,
     "seed of the turbulence and noise generators, up to 2^63 - 1 (read as 64 bits, no L suffix needed) "
     "(optional, default 1)"},
    KBD("sim.noise", noise, 1, "add sensor noise to the simulated measurements (optional, default true)"),
    {"sim.psf_interval_frames", K_INT, F_DEFAULT, 0, 1000000, "", 1, CF(psf_interval), NOCOUNT, 0, 0, NULL, 10,
     "long-exposure PSF per evaluation direction at evaluation.wavelength_nm (sim/psf.h): the image of every "
     "N-th frame after the settle frames is added (Nyquist-sampled FFT of the pupil field); 0 = no PSFs "
     "(optional, default 10)"},
    {"sim.psf_pixels", K_INT, F_DEFAULT | F_EVEN, 8, 4096, "", 1, CF(psf_pixels), NOCOUNT, 0, 0, NULL, 64,
     "side of the stored PSF images, even, around the centre, at most the padded FFT's N (Nyquist: 2 pixels per "
     "lambda/D, so 64 = +-16 lambda/D) (optional, default 64)"},
    {"sim.psf_wavelengths_nm", K_FLOATS, F_OPT, 10.0, 1e6, "nm", 1e-9, CF(psf_wavelength), CF(npsf_wavelengths), 1,
     WT_MAX_PSF_WAVELENGTHS, NULL, 0,
     "wavelengths of extra long-exposure PSFs per evaluation direction (psf/wavelengths/ of RUN.h5, one FITS file each "
     "with sim --fits): the residual OPD's phase 2 pi OPD / lambda at each; the padding N dx >= 2 D is the same at "
     "every lambda, so every image has Nyquist pixels of lambda/(2D), lambda / (N dx) in angle; left out: none (psf/ "
     "at evaluation.wavelength_nm is always made; --fits then writes that one)"},
    {"sim.telemetry_maps_interval_frames", K_INT, F_OPT, 0, 1000000, "", 1, CF(telemetry_maps), NOCOUNT, 0, 0, NULL, 0,
     "with sim --telemetry: every N-th frame (frames 0, N, 2N, ...) TEL.h5 also gets maps/residual, the "
     "piston-removed residual OPD on the pupil of every evaluation direction (float32, the fine grid), and "
     "maps/commands, the DM commands of those frames; 0 or left out: none"},

    KFD("recon.alpha", 0, 1e-12, 1e12, "", 1, alpha, 1.0, "prior weight alpha (optional, default 1)"),
    KFD("recon.tau", 0, 0.0, 1.0, "", 1, tau, 0.8,
        "elongation weight tau of the reconstructor's noise model (optional, default 0.8)"),
    KID("recon.wavelet_order", 0, 1, 10, wavelet_order, 3, "Daubechies order N (2N taps) (optional, default 3)"),
    KID("recon.wavelet_levels", 0, 1, 30, wavelet_levels, 3,
        "wavelet levels J (optional, default 3; the E-ELT preset's 128-point layers use 5)"),
    {"recon.prior", K_ENUM, F_AUTO, 0, 0, "", 1, CF(exact_prior), NOCOUNT, 0, 0, PRIOR_CHOICES, 0,
     "the prior of both variants (each variant's recon.<variant>.prior overrides it): " PRIOR_DESC
     "; left out (or \"auto\"): each variant's default (optional)"},
    {"recon.prior_aliasing", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(prior_aliasing), NOCOUNT, 0, 0, NULL, 0,
     "prior variances of grid samples: the power above the layer grid's Nyquist frequency folded back "
     "(optional, default false)"},
    {"recon.model_error", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(model_error), NOCOUNT, 0, 0, NULL, 0,
     "LGS noise variance plus the slope variance of the layer-binning model error (true layers between "
     "the reconstruction altitudes; zero for cg9's layers) (optional, default false)"},
    {"recon.subgrid_error", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(subgrid_error), NOCOUNT, 0, 0, NULL, 1,
     "the LGS measurement noise of the reconstructor's weight floored at the slope variance of the turbulence "
     "finer than the reconstruction layers' grids (beyond each grid's Nyquist frequency, through the "
     "subapertures and the LGS cone; analytic, von Karman, from the model's profile): max(kappa sigma^2, "
     "sigma_g^2), the binning error of model_error added as before. No layer of the model can explain that part "
     "of a slope, and a weight that trusts the slopes more than it (many photons) puts it on the layers anyway; "
     "nothing changes where the noise is above the floor; false: the weight of the measurement noise alone "
     "(optional, default true)"},
    {"recon.lgs_focus_removal", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(lgs_focus_removal), NOCOUNT, 0, 0, NULL, 0,
     "pcg3, cg9 and mvm: the LGS noise weights project out each LGS's global focus as they do its tip-tilt "
     "(Ĉ⁻¹ = (I − T) C̃⁻¹ (I − T), T onto tip, tilt and the focus slope pattern): a change of the sodium "
     "centroid's altitude, which every LGS reads as focus, no longer reaches the tomography, and the focus comes "
     "from the NGS; needs an NGS that measures focus (ngs.subapertures 2) (optional, default false)"},
    {"recon.lgs_focus_mode", K_ENUM, F_OPT, 0, 0, "", 1, CF(lgs_focus_mode), NOCOUNT, 0, 0, "each|common", 0,
     "with recon.lgs_focus_removal = true, which focus T projects out: each = every LGS's own focus (one direction "
     "per LGS); common = only the focus common to all LGS, f_c = (f_1, …, f_n)/√n, the one direction a change of "
     "the sodium centroid's altitude moves, so the differences of focus between the LGS (the altitude split of the "
     "turbulence's quadratic phase) stay in the tomography; tip-tilt per LGS either way (optional, default each)"},
    KBD("recon.warm_start", warm_start, 1, "start each frame from the previous frame's solution (optional, default true)"),
    {"recon.predict", K_BOOL, F_DEFAULT, 0, 1, "", 1, CF(predict), NOCOUNT, 0, 0, NULL, 0,
     "pcg3 and cg9: move each reconstructed layer by its wind (the reconstructor's atmosphere, recon.atmosphere, "
     "compressed onto the variant's layers) over the loop's delay, loop.delay_frames / loop.rate_hz, before the "
     "fitting (cg9) or the commands (pcg3): frozen flow predicted over the delay (SPEC §12); an MVM built with it holds "
     "the same shift inside R (its identity then holds the lead and the model's wind: `wavetomo build` again for "
     "another wind) (optional, default false)"},
    {"recon.predict_lead_frames", K_FLOAT, F_DEFAULT, 0.0, 100.0, "frames", 1, CF(predict_lead_frames), NOCOUNT, 0, 0,
     NULL, 0.0,
     "recon.predict: the time the layers are moved over, in frames; 0 (the default) = loop.delay_frames, the "
     "delay from the measurement to the commands' application. The integrator's memory adds a lag of about "
     "(1 - g) / g frames at gain g (the mean age of its average of the reconstructions), which a longer lead can "
     "predict too (SPEC §12)"},
    {"recon.predict_integrator", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(predict_integrator), NOCOUNT, 0, 0,
     "commands|layers", 0,
     "recon.predict (pcg3, cg9): where the loop's integrator runs. commands = on the DM commands, a_{t+d} = "
     "a_{t+d-1} + g (r_t - a_t), r_t made from the layers moved over the lead; its average of the last ~1/g "
     "reconstructions lags by ~(1 - g)/g frames more. layers = on the reconstructed layers, z_{t+d} = S_1 z_{t+d-1} "
     "+ g S_d (phi_t - z_t) with S_k each layer moved by its wind over k frames (S_d over the lead), the commands "
     "fitted from z_{t+d}: under frozen flow the state moves with the layers, so the average adds no lag "
     "(SPEC §12); without recon.predict both are the same law; not with loop.gain_levels (optional, default commands)"},
    {"recon.sensor_model", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(lit_sensor_model), NOCOUNT, 0, 0, "fried|lit", 1,
     "reconstructor's Shack-Hartmann model: fried = the paper's corner differences, lit = average gradient "
     "over the illuminated part of each subaperture, as the simulated sensors measure (optional, default lit)"},
    {"recon.sensor_points_per_subaperture", K_INT, F_AUTO, 1, 16, "", 1, CF(sensor_points), NOCOUNT, 0, 0, NULL, 1,
     "lit model: sample points per subaperture side at which the reconstructor's sensors read the layers; when "
     "left out (or \"auto\") the smallest q with d/q no coarser than the finest reconstruction layer of either "
     "variant (a sensor model sampled coarser than the layer cannot see part of it, and the MAP degrades as the "
     "layers get finer: docs/results.md §0e)"},
    {"recon.fft_wisdom", K_STR, F_OPT | F_EMPTY, 0, 0, "", 1, CF(fft_wisdom), NOCOUNT, 0, 0, NULL, 0,
     "FFTW wisdom file made on this machine by `wavetomo wisdom` (relative to the configuration file's directory): "
     "the full prior's and the fourier preconditioner's FFTs are planned from it (measured plans, ~1.6x faster at "
     "128 x 128; other rounding than FFTW_ESTIMATE, the same bits for the same file); left out or \"\": "
     "FFTW_ESTIMATE (the same plans on every machine). A file without this configuration's sizes is refused"},
    {"recon.fft_wisdom_sha256", K_STR, F_AUTO | F_HEX, 0, 0, "", 1, CF(fft_wisdom_sha256), NOCOUNT, 0, 0, NULL, 0,
     "with recon.fft_wisdom: SHA-256 of the wisdom file's bytes, so that every output records which plans ran; left "
     "out (or \"auto\"): computed when the configuration is read; given (a stored configuration): the file must "
     "still hash to it when the reconstructor is set up"},
    {"recon.mvm_precision", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(mvm_precision), NOCOUNT, 0, 0, "fp32|fp16|bf16", 0,
     "storage and apply of the MVM control matrix: fp32, or 16-bit floats (IEEE half / bfloat16, one power-of-two "
     "scale per row) with float32 accumulation, half the bytes per frame (optional, default fp32)"},
    {"recon.atmosphere.source", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(model.source), NOCOUNT, 0, 0, "oracle|given|learned",
     WT_MODEL_ORACLE,
     "the reconstructors' atmosphere (SPEC §12; the simulation's is atmosphere.*): oracle = the truth's profile, r0 "
     "and L0, compressed onto each variant's layer altitudes; given = the profile of the recon.atmosphere keys below "
     "(or its profile file), compressed the same way; learned = starts from the given profile (the same keys) and "
     "replaces it every update_s of night time by the loop's own estimate from its pseudo-open-loop LGS slopes "
     "(r0 and the Cn2 profile on 22 altitudes to 20 km, or with the variant's own, learn_grid; L0 and the wind stay the given ones): pcg3 and cg9 take it at "
     "the next frame, the MVM is rebuilt from it and swapped in after mvm_latency_s. Compression: each profile "
     "layer's Cn2 split linearly in altitude between the two nearest reconstruction altitudes (all of it to the end "
     "layer outside their range), the wind of a layer the Cn2-weighted mean of the wind vectors it absorbs "
     "(optional, default oracle)"},
    {"recon.atmosphere.update_s", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 1e6, "s", 1, CF(model.update_s), NOCOUNT, 0, 0, NULL, 60.0,
         "learned: night time between two estimates (each from at least 100 frames); the oracle in a changing night "
         "(atmosphere.night): between two updates of its model to the truth's state; a frame is 1/loop.rate_hz of "
         "night times atmosphere.night.compression (optional, default 60, refused with a given source)"},
    {"recon.atmosphere.learn_window", K_ENUM, F_OPT, 0, 0, "", 1, CF(model.learn_window), NOCOUNT, 0, 0, "interval|all",
     0, "learned: the frames of an estimate: interval = those since the previous estimate (a night that changes: the "
     "estimate follows it), all = every frame since the start (a static night: the estimate converges; its "
     "uncertainty needs frames in two quarters of the run) (optional, default interval, refused with another source)"},
    {"recon.atmosphere.learn_grid", K_ENUM, F_OPT, 0, 0, "", 1, CF(model.learn_grid), NOCOUNT, 0, 0, "default|layers",
     0, "learned: the altitudes the profile is fitted on: default = 0, 0.5 km and every 1 km to 20 km; layers = those "
     "and each variant's own layer altitudes, a default point closer to one of them than half the finest altitude "
     "resolution of the LGS pairs, d / (2 theta_max), dropped (what the fit puts at a variant's altitude then stays on "
     "that layer; but below the pairs' resolution the fit puts the Cn2 of several close layers on the lowest: on "
     "the E-ELT it cost CG-9 6-12 nm, docs/results.md section 46) (optional, default default, refused with another "
     "source)"},
    {"recon.atmosphere.learn_memory", K_FLOAT, F_OPT, 1.0, 1e6, "", 1, CF(model.learn_memory), NOCOUNT, 0, 0, NULL, 1.0,
     "learned, learn_window = interval: the memory of the estimates, in updates: the model's Cn2 per altitude (f r0^-5/3, "
     "what the maps measure linearly) is the exponential average of the estimates with weight 1/learn_memory on the "
     "newest (1: each estimate alone; 3: about the last three intervals, less scatter, more lag in a changing night) "
     "(optional, default 1, refused with another source)"},
    {"recon.atmosphere.learn_wind", K_ENUM, F_OPT, 0, 0, "", 1, CF(model.learn_wind), NOCOUNT, 0, 0, "start|aligned", 0,
     "learned: the wind that recon.predict moves each reconstruction layer by: start = the start model's (the given "
     "wind keys, compressed onto the layers), aligned = measured on the reconstructor's own layer estimates, the shift "
     "that best aligns each layer at t and t + k frames (SPEC §12; core/model/wind_align.h), taken at every update "
     "(a layer without a clear estimate keeps its wind); pcg3 and cg9 only (an MVM forms no layer estimates: its "
     "rebuilds take the start model's wind) (optional, default start, refused with another source)"},
    {"recon.atmosphere.mvm_latency_s", K_FLOAT, F_OPT, -1.0, 1e6, "s", 1, CF(model.mvm_latency_s), NOCOUNT, 0, 0, NULL, -1.0,
         "learned, mvm: night time from an estimate to its control matrix in the loop (the old one is applied "
         "meanwhile; one build at a time); -1: the build's measured wall time on this machine, e.g. a faster build "
         "cluster is a smaller value; also the oracle's MVM in a changing night (optional, default -1, refused with a "
         "given source)"},
    {"recon.atmosphere.r0_m", K_FLOAT, F_OPT, 1e-3, 1e4, "m", 1, CF(model.r0), NOCOUNT, 0, 0, NULL, 0,
     "given: the model's Fried parameter r0 at 500 nm (required with source = \"given\", refused otherwise)"},
    {"recon.atmosphere.L0_m", K_FLOAT, F_OPT, 1.0, 1e4, "m", 1, CF(model.L0), NOCOUNT, 0, 0, NULL, 0,
     "given: the model's von Karman outer scale L0 (required with source = \"given\", refused otherwise)"},
    {"recon.atmosphere.profile", K_STR, F_OPT, 0, 0, "", 1, CF(model.profile), NOCOUNT, 0, 0, NULL, 0,
     "given: the model's profile from a file in atmosphere.profile's format, instead of the four lists below "
     "(wind_direction_deg still given when the file has no direction column); the canonical text holds the lists"},
    {"recon.atmosphere.altitudes_m", K_FLOATS, F_OPT | F_INCR, 0.0, MAXALT, "m", 1, CF(model.altitude),
     CF(model.nlayers), 1, WT_MAX_LAYERS, NULL, 0,
     "given: the model's layer altitudes, strictly increasing; compressed onto each variant's layer_altitudes_m "
     "(the variant's own altitudes: its fractions exactly as given)"},
    {"recon.atmosphere.cn2_fractions", K_FLOATS, F_OPT, 0.0, 1.0, "", 1, CF(model.fraction), CF(model.nlayers), 1,
     WT_MAX_LAYERS, NULL, 0, "given: the model's Cn2 fraction of each layer; the sum must be 1 within 1 % (then "
     "normalised to 1)"},
    {"recon.atmosphere.wind_speed_mps", K_FLOATS, F_OPT, 0.0, 1000.0, "m/s", 1, CF(model.wind_speed),
     CF(model.nlayers), 1, WT_MAX_LAYERS, NULL, 0, "given: the model's wind speed of each layer"},
    {"recon.atmosphere.wind_direction_deg", K_FLOATS, F_OPT, -360.0, 360.0, "deg", DEG, CF(model.wind_direction),
     CF(model.nlayers), 1, WT_MAX_LAYERS, NULL, 0,
     "given: the direction each of the model's layers moves towards, from +x towards +y"},
    /* a controlled error of the model (sensitivity experiments; config_atmosphere.c): each left out = no error,
     * and a value of no error is left out of the canonical text, so the matrix identity is the error-free one */
    {"recon.atmosphere.error_ground_fraction", K_FLOAT, F_OPT, -1.0, 1.0, "", 1, CF(model.error_ground_fraction),
     NOCOUNT, 0, 0, NULL, 0.0,
     "a model error: added to the Cn2 fraction of the model's ground layer (its lowest layer and those at or below "
     "error_ground_top_m), each of those layers scaled alike, the other layers scaled so that the total stays 1; a "
     "ground fraction outside [0, 1] is refused. Applied, as every error_* key, to the oracle's or the given "
     "profile before it is compressed onto each variant's layers; the simulated truth never changes "
     "(default 0: no error)"},
    {"recon.atmosphere.error_ground_top_m", K_FLOAT, F_OPT, 0.0, MAXALT, "m", 1, CF(model.error_ground_top), NOCOUNT,
     0, 0, NULL, 0.0,
     "with error_ground_fraction: the model's layers at or below this altitude form its ground layer with the "
     "lowest one (a 35-layer profile spreads the ground layer over several); left out of the canonical text without "
     "error_ground_fraction (default 0: the lowest layer alone)"},
    {"recon.atmosphere.error_r0_scale", K_FLOAT, F_OPT | F_LO_OPEN, 0.0, 100.0, "", 1, CF(model.error_r0_scale),
     NOCOUNT, 0, 0, NULL, 1.0,
     "a model error: the model's r0 times this (the prior's weight, and the diffractive LGS reference's seeing); "
     "the result must stay within recon.atmosphere.r0_m's range (default 1: no error)"},
    {"recon.atmosphere.error_high_shift_m", K_FLOAT, F_OPT, -1e5, 1e5, "m", 1, CF(model.error_high_shift), NOCOUNT,
     0, 0, NULL, 0.0,
     "a model error: added to the altitude of every model layer at or above error_high_bottom_m (the layers are "
     "then ordered by altitude again; one that would go below 0 or reach the LGS altitude is refused, and so is a "
     "shift that moves no layer) (default 0: no error)"},
    {"recon.atmosphere.error_high_bottom_m", K_FLOAT, F_OPT, 0.0, MAXALT, "m", 1, CF(model.error_high_bottom),
     NOCOUNT, 0, 0, NULL, 5000.0,
     "with error_high_shift_m: the lowest altitude of the model layers it moves (the free atmosphere above the "
     "boundary layer and PCG-3's middle DM); left out of the canonical text without error_high_shift_m "
     "(default 5000)"},
    {"recon.atmosphere.error_wind_speed_scale", K_FLOAT, F_OPT, 0.0, 100.0, "", 1, CF(model.error_wind_speed_scale),
     NOCOUNT, 0, 0, NULL, 1.0,
     "a model error: every model layer's wind speed times this; only recon.predict reads the wind, so it is in an "
     "MVM's identity with recon.predict only (default 1: no error)"},
    {"recon.atmosphere.error_wind_direction_deg", K_FLOAT, F_OPT, -360.0, 360.0, "deg", DEG,
     CF(model.error_wind_direction), NOCOUNT, 0, 0, NULL, 0.0,
     "a model error: added to every model layer's wind direction (a rotation from +x towards +y); in an MVM's "
     "identity with recon.predict only, as error_wind_speed_scale (default 0: no error)"},
    VARIANT("recon.pcg3", pcg3, PCG3_SPACING, PCG3_COVER, WT_PRIOR_DEFAULT_PCG3_TEXT,
            "dm.altitudes_m: a layer at each DM", 4, "4", 2, "jacobi_ngs"),
    VARIANT("recon.cg9", cg9, CG9_SPACING, "", WT_PRIOR_DEFAULT_CG9_TEXT,
            "atmosphere.altitudes_m (after atmosphere.profile): a layer at each of the truth's", 20, "20", 2,
            "jacobi_ngs"),
    KID("recon.cg9.fit_iterations", 0, 1, 1000000, cg9.fit_iterations, 10,
        "fitting CG iterations per frame, with fit_solver = cg (optional, default 10)"),
    KFD("recon.cg9.fit_regularization", GE0(1e6), "", 1, cg9.fit_regularization, 1e-3,
        "fitting Tikhonov weight, relative to the mean diagonal of H^T H (optional, default 1e-3)"),
    {"recon.cg9.fit_points_per_subaperture", K_INT, F_AUTO, 1, 16, "", 1, CF(cg9.fit_sampling), NOCOUNT, 0, 0, NULL, 2,
     "fitting sample points per LGS subaperture side: 1 = the Fried corners of the valid subapertures, "
     "q > 1 = every point of the d/q grid inside the pupil; when left out (or \"auto\") the smallest q with d/q "
     "no coarser than half the finer of the finest cg9 layer spacing and the finest DM pitch (a fit sampled "
     "coarser leaves the DMs free between its points: docs/results.md §18)"},
    {"recon.cg9.fit_solver", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(cg9.fit_solver), NOCOUNT, 0, 0, "cg|cholesky", 1,
     "solver of the fitting's normal equations: cg = fit_iterations warm-started CG iterations per frame, "
     "cholesky = the normal matrix assembled and factored once (CHOLMOD) at set-up, a frame the right-hand side "
     "and two triangular solves, the exact fit (fit_iterations unused) (optional, default cholesky)"},
    {"recon.cg9.fit_factor_precision", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(cg9.fit_factor_precision), NOCOUNT, 0, 0,
     "fp64|fp32", 1,
     "cholesky: the factor's values as the per-frame solves read them: fp64, or fp32 (half the bytes; the "
     "arithmetic stays double; the commands move by ~1e-5 relative at E-ELT) (optional, default fp32)"},
    {"recon.cg9.fit_kernels", K_ENUM, F_DEFAULT, 0, 0, "", 1, CF(cg9.fit_kernels), NOCOUNT, 0, 0, "fast|reference", 0,
     "the fitting frame's kernels: fast, or reference = the plain ones (each direction through its own zeroed "
     "pupil buffer by the tomography's projection kernels, the Cholesky solves' scalar loops): the same bits, "
     "slower; the baseline of the paired bench (docs/results.md §20) (optional, default fast)"},
};
_Static_assert(sizeof wt_config_priv_keys / sizeof wt_config_priv_keys[0] == WT_CONFIG_PRIV_NKEYS,
               "WT_CONFIG_PRIV_NKEYS (config_private.h) must be the number of keys of the table");

/* ---------------------------------------------------------------- text shared with the other files */

const char *wt_config_priv_fmt_num(double v, char *buf, size_t n)
{
    for (int p = 15; p <= 17; p++) {
        snprintf(buf, n, "%.*g", p, v);
        if (strtod(buf, NULL) == v) break;
    }
    return buf;
}

void wt_config_priv_range(const wt_config_priv_key_spec *ks, char *buf, size_t n)
{
    char a[40], b[40];
    int lo = isfinite(ks->lo), hi = isfinite(ks->hi);
    wt_config_priv_fmt_num(ks->lo, a, sizeof a);
    wt_config_priv_fmt_num(ks->hi, b, sizeof b);
    if (ks->type == K_BOOL) snprintf(buf, n, "true|false");
    else if (ks->type == K_ENUM) snprintf(buf, n, "%s", ks->choices);
    else if (ks->type == K_STR) snprintf(buf, n, ks->flags & F_HEX ? "64 hex digits" : "a file path");
    else if (lo && hi)
        snprintf(buf, n, "in %c%s, %s%c", ks->flags & F_LO_OPEN ? '(' : '[', a, b, ks->flags & F_HI_OPEN ? ')' : ']');
    else if (lo) snprintf(buf, n, "%s %s", ks->flags & F_LO_OPEN ? ">" : ">=", a);
    else if (hi) snprintf(buf, n, "%s %s", ks->flags & F_HI_OPEN ? "<" : "<=", b);
    else snprintf(buf, n, "any");
}

/* ---------------------------------------------------------------- public */

void wt_config_print_reference(FILE *f)
{
    static const char *tname[] = {"int", "int", "float", "bool", "string", "float[]", "int[]", "path"};
    char rng[128], unit[32];
    for (int k = 0; k < WT_CONFIG_PRIV_NKEYS; k++) {
        const wt_config_priv_key_spec *ks = &wt_config_priv_keys[k];
        char core[96];
        wt_config_priv_range(ks, core, sizeof core);
        snprintf(rng, sizeof rng, "%s%s", ks->flags & F_POW2   ? "pow2, "
                                      : ks->flags & F_ODD  ? "odd, "
                                      : ks->flags & F_EVEN ? "even, "
                                                           : "",
                 core);
        if (wt_config_priv_is_list(ks->type)) {
            size_t l = strlen(rng);
            snprintf(rng + l, sizeof rng - l, "; %d..%d values", ks->minlen, ks->maxlen);
        }
        snprintf(unit, sizeof unit, *ks->unit ? "[%s]" : "-", ks->unit);
        fprintf(f, "%-36s %-8s %-38s %-10s %s%s\n", ks->path, ks->flags & F_HEX ? "string" : tname[ks->type], rng, unit, ks->desc,
                ks->flags & F_OPT    ? " (optional)"
                : ks->flags & F_AUTO ? " (optional: automatic when left out)"
                                     : "");
    }
}
