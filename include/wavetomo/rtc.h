/* wavetomo/rtc.h: the per-frame reconstructor API: slopes in, DM commands out, for a real-time computer
 * or another simulator's loop (docs/c-api.md).
 *
 * Part of the public, stable interface. Plan once, execute many (FFTW's shape):
 *   wt_rtc_open / wt_rtc_open_text / wt_rtc_open_mvm   set-up: reads the configuration (and the matrix),
 *                                                      builds the operators; may allocate, read files, fail
 *   wt_rtc_share                                       another loop on an instance's plan (its system, Â
 *                                                      and stored R, not copied): several loops, one R
 *   wt_rtc_frame / wt_rtc_frame_f32                    one frame: allocates nothing, does no I/O
 *   wt_rtc_reset, the queries, wt_rtc_close
 * An instance is one loop's state (the integrator, its delay queue, the warm start, the workspace) on a
 * plan that is read-only once built and freed with the last instance holding it.
 *
 * What a frame computes (pseudo-open-loop control, POLC, paper Algorithm POLC, SPEC §7), with s the
 * frame's slopes, a_t the commands applied while they were measured, R the reconstructor, Â the
 * DM-to-slope interaction, g the integrator gain (loop.gain; with loop.gain_levels the gain per spatial scale G
 * of the commands, the same law as `wavetomo sim`) and d the delay (loop.delay_frames):
 *
 *   s_ol    = s + Â a_t                     (flag WT_RTC_SLOPES_OL: s_ol = s, the slopes are already
 *                                            pseudo-open-loop)
 *   r       = R s_ol                        the reconstruction
 *   a_{t+d} = a_{t+d-1} + g (r − a_t)       the commands to send (the integrator); flag WT_RTC_RAW: r instead
 *
 * a_t is `applied` when the caller passes it (what the mirrors really did, e.g. after clipping), else
 * the commands this instance returned d frames earlier (zero for the first d frames). The integrator's
 * own state a_{t+d-1} is the last commands this instance returned. A WT_RTC_RAW frame leaves that state
 * alone.
 *
 * Reconstructors: "pcg3" (wavelet MAP, layers at the DM altitudes, modified-Jacobi PCG) and "cg9"
 * (9 layers, CG and the fitting step), matrix-free and warm-started frame to frame (recon.warm_start);
 * or a stored MVM (MATRIX.h5 of `wavetomo build`), whose R and R Â are applied as float32 GEMVs: with
 * the MVM, r = R s + (R Â) a_t (Â is not needed at run time), or r = R s with WT_RTC_SLOPES_OL.
 * Or "none": the system alone, for its sizes, orderings, configuration and Â (wt_rtc_interaction); its
 * reconstruction is r = 0 (`wavetomo sim --recon none`: the DMs stay flat).
 * These are the computations of `wavetomo run` (which uses this API) and of `wavetomo sim`'s loop (which
 * forms s_ol itself: with the MVM it applies R s_ol, the WT_RTC_SLOPES_OL form).
 *
 * Ordering (the same as every wavetomo file's "layout" group):
 *   slopes    sensor by sensor, the LGS first, then the NGS (wt_rtc_sensor: name, offset, count); within a
 *             sensor [s_x of every valid subaperture..., s_y of every valid subaperture...], subapertures in
 *             row-major order of the sensor's grid (x fastest), centres from wt_rtc_subapertures. Slopes
 *             are angles [rad].
 *   commands  DM by DM (wt_rtc_dm), active actuators in row-major grid order (x fastest), positions from
 *             wt_rtc_actuators; commands are mirror surface heights in the DM's conjugate plane [m].
 *
 * Threads: one instance may be used by one thread at a time (the warm start and the integrator are
 * state); different instances, shares of one plan included, may run frames concurrently from different
 * threads (a context each, for each its own error message). Set-up reads files through HDF5 and
 * libconfig, which are not thread-safe as Debian builds them, and a share counts its plan: open, share
 * and close instances from one thread at a time. The frame call uses the context's thread count in its
 * OpenMP regions (wt_context_set_threads), and the MVM's GEMV OpenBLAS's. The context's allocator is
 * called only by open, share and close.
 */
#ifndef WAVETOMO_RTC_H
#define WAVETOMO_RTC_H

#include <stdint.h>

#include "context.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct wt_rtc wt_rtc;

/* Flags of a frame (bitwise or). */
enum {
    WT_RTC_RAW = 1,       /* return r = R s_ol (the reconstruction), not the integrated commands */
    WT_RTC_SLOPES_OL = 2  /* the slopes given are already pseudo-open-loop: s_ol = s */
};

/* Open reconstructor `recon` ("pcg3", "cg9" or "none") for the system of a configuration file, with nset
 * "key=value" overrides applied after the file's own (the command line's --set; NULL when nset is 0).
 * Paths in the file (an @include, lgs.sodium_profile) are relative to the file. [out] *out, or NULL on
 * failure with the message in ctx (WT_ERR_IO: the file is missing; WT_ERR_CONFIG: a bad key or value,
 * named; WT_ERR_INVALID: an unknown recon). ctx must outlive the instance. */
int wt_rtc_open(wt_context *ctx, const char *recon, const char *config_file, int nset, const char *const *set,
                wt_rtc **out);
/* The same from the configuration's text (libconfig syntax, e.g. the "config" dataset of any wavetomo
 * output file); relative paths in it are relative to the working directory. */
int wt_rtc_open_text(wt_context *ctx, const char *recon, const char *config_text, int nset,
                     const char *const *set, wt_rtc **out);
/* A stored MVM (MATRIX.h5 of `wavetomo build`). The system is config_file's with the overrides, or
 * when config_file is NULL the configuration stored in the matrix file (with the overrides, e.g.
 * loop.gain). Refused (WT_ERR_FORMAT) when the matrix was built for another system: its configuration
 * hash (of the keys that can change R) differs. */
int wt_rtc_open_mvm(wt_context *ctx, const char *matrix_file, const char *config_file, int nset,
                    const char *const *set, wt_rtc **out);
/* A new loop on src's plan: the same system and configuration, Â and (for the MVM) R and R Â, which are
 * not copied: one R in memory for several loops. The new instance has its own integrator and delay queue
 * (zero, as after wt_rtc_reset), frame count, warm start and workspace; src is not modified and either
 * may be closed first (the plan lives while an instance holds it). pcg3 and cg9 have no stored R: the
 * share builds its own operators on the shared system (their preconditioner and fitting carry the warm
 * start and per-solve workspace), the set-up time and memory of an open without reading the configuration.
 * ctx receives the new instance's errors and allocations and sets its frames' threads; src's context,
 * which built the plan and frees it, must outlive every share. [out] *out, or NULL on failure. */
int wt_rtc_share(wt_context *ctx, const wt_rtc *src, wt_rtc **out);
/* Free the instance (NULL is accepted); the plan with the last instance holding it. */
void wt_rtc_close(wt_rtc *rtc);

/* One frame (see above). slopes: nslopes values; applied: NULL or nactuators values; commands:
 * nactuators values, overwritten. nslopes and nactuators must be the system's (WT_ERR_INVALID
 * otherwise, naming both). A slope or applied command that is NaN or Inf is refused (WT_ERR_NUMERIC,
 * naming the frame, the index, the sensor and the subaperture) before anything changes. Returns WT_OK,
 * a warning (> 0: an iterative solver stopped early; the commands are usable), or an error (< 0; the
 * message is in the context). Allocates nothing, does no I/O. */
int wt_rtc_frame(wt_rtc *rtc, const double *slopes, int64_t nslopes, const double *applied, unsigned flags,
                 double *commands, int64_t nactuators);
/* The same in float32 (the telemetry's type). With the MVM and `applied` (or WT_RTC_SLOPES_OL) in
 * WT_RTC_RAW mode the GEMVs read the caller's floats directly; otherwise the values are converted to
 * double, the frame runs as wt_rtc_frame, and the commands are rounded to float. */
int wt_rtc_frame_f32(wt_rtc *rtc, const float *slopes, int64_t nslopes, const float *applied, unsigned flags,
                     float *commands, int64_t nactuators);
/* Forget the history: the integrator's commands and their d-frame queue become zero, the warm start
 * starts from zero, the frame count from 0. Allocates nothing. */
void wt_rtc_reset(wt_rtc *rtc);

/* The DM-to-slope interaction Â (paper Algorithm POLC, SPEC §7): slopes = Â commands, the slopes [rad] the
 * sensors see of the DMs' commands [m] (the term a frame adds, s_ol = s + Â a_t, in the same operations);
 * and its transpose, commands = Âᵀ slopes. Buffers of the system's sizes (WT_ERR_INVALID otherwise, naming
 * both); a NaN or Inf input is refused (WT_ERR_NUMERIC, naming it). The output is overwritten. Allocates
 * nothing; uses the instance's workspace: one thread at a time per instance, as frames. Every public open
 * builds Â (for the MVM too, whose frames use R Â instead). */
int wt_rtc_interaction(wt_rtc *rtc, const double *commands, int64_t nactuators, double *slopes, int64_t nslopes);
int wt_rtc_interaction_t(wt_rtc *rtc, const double *slopes, int64_t nslopes, double *commands, int64_t nactuators);

/* The effective configuration as libconfig text: the file's (or the matrix's) with the overrides applied
 * and every key given, as the "config" dataset of wavetomo's output files. Owned by the instance (valid
 * until close). */
const char *wt_rtc_config(const wt_rtc *rtc);

/* Sizes and the loop's parameters. */
int64_t wt_rtc_nslopes(const wt_rtc *rtc);
int64_t wt_rtc_nactuators(const wt_rtc *rtc);
int wt_rtc_nsensors(const wt_rtc *rtc);
int wt_rtc_ndms(const wt_rtc *rtc);
/* "pcg3", "cg9", "none", "mvm-pcg3" or "mvm-cg9" (the MVM and the variant it was built from) */
const char *wt_rtc_recon(const wt_rtc *rtc);
int wt_rtc_delay(const wt_rtc *rtc);     /* d [frames] */
double wt_rtc_gain(const wt_rtc *rtc);   /* g [1] */
double wt_rtc_rate(const wt_rtc *rtc);   /* frame rate [Hz] */
/* Frames run since open or reset. */
int64_t wt_rtc_frames(const wt_rtc *rtc);
/* Wall time of the last frame call [s] (input checks, conversions and the reconstruction), 0 before the
 * first. */
double wt_rtc_frame_time(const wt_rtc *rtc);

enum { WT_RTC_LGS = 0, WT_RTC_NGS = 1 };

/* A wavefront sensor. */
typedef struct wt_rtc_sensor {
    char name[16];            /* "LGS1", …, "NGS1", … */
    int kind;                 /* WT_RTC_LGS or WT_RTC_NGS */
    int nsub;                 /* valid subapertures; the sensor has 2 nsub slopes */
    int64_t offset;           /* index of its first slope in a frame */
    double theta_x, theta_y;  /* direction on the sky [rad] */
    double altitude;          /* source altitude [m]; 0: at infinity (NGS) */
} wt_rtc_sensor;

/* A deformable mirror. */
typedef struct wt_rtc_dm {
    double altitude;          /* conjugation altitude [m] */
    double pitch;             /* actuator spacing [m] */
    int nactive;              /* active actuators (its commands) */
    int64_t offset;           /* index of its first command */
    int nx, ny;               /* its actuator grid */
    double x0, y0;            /* position of grid point (0, 0) [m] */
} wt_rtc_dm;

/* Sensor m (0 ≤ m < wt_rtc_nsensors) into *info; WT_ERR_INVALID for another m. */
int wt_rtc_sensor_info(const wt_rtc *rtc, int m, wt_rtc_sensor *info);
/* The centres (x, y) [m] in the pupil of sensor m's valid subapertures, in slope order: xy[2k], xy[2k+1]
 * (2 nsub values, caller's buffer). */
int wt_rtc_subapertures(const wt_rtc *rtc, int m, double *xy);
/* DM k (0 ≤ k < wt_rtc_ndms) into *info. */
int wt_rtc_dm_info(const wt_rtc *rtc, int k, wt_rtc_dm *info);
/* For every command i: the actuator's position xy[2i], xy[2i+1] [m] in its DM's conjugate plane, and
 * (when index is not NULL) index[3i..3i+2] = DM number (0-based), column ix, row iy on that DM's grid.
 * Caller's buffers of 2 and 3 nactuators values. */
int wt_rtc_actuators(const wt_rtc *rtc, double *xy, int32_t *index);

#ifdef __cplusplus
}
#endif

#endif
