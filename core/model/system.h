/* core/model/system.h: the MCAO system of a configuration, as geometry (SPEC §1, §3–§5, §8).
 *
 * Derived once from a wt_config: guide-star directions, the Shack–Hartmann operators and noise
 * parameters of every sensor, the valid-subaperture and Fried-corner masks, the DMs (core/op/dm.h:
 * actuator grids and active masks, |r| ≤ D/2 + h tan θc plus guard rings), and the evaluation directions.
 *
 * Sensor order: the nlgs LGS first, then the NGS; slopes are concatenated in that order, each sensor's
 * block laid out as in core/op/shack_hartmann.h ([s_x…, s_y…] over its valid subapertures).
 * All sensors share one fine Fried corner grid ((n+1)² points of spacing d = D/n, the LGS sampling);
 * an NGS sensor with m x m subapertures averages the fine Fried slopes inside each.
 * Actuator order: DM by DM, active actuators in grid-index order.
 */
#ifndef WT_SYSTEM_H
#define WT_SYSTEM_H

#include "../config/config.h"
#include "../op/dm.h"
#include "../op/grid.h"
#include "../op/shack_hartmann.h"

enum { WT_SENSOR_LGS = 0, WT_SENSOR_NGS = 1 };

typedef struct wt_sensor {
    int kind;                   /* WT_SENSOR_LGS or WT_SENSOR_NGS */
    int index;                  /* 0-based within its kind */
    double theta_x, theta_y;    /* direction [rad] */
    double altitude;            /* source altitude H [m]; 0 = infinity (NGS) */
    int subapertures;           /* subapertures per side (LGS: n; NGS: 1 or 2) */
    double launch_x, launch_y;  /* LGS launch position in the pupil [m] */
    double sigma2;              /* noise variance per axis [rad²] (photon + read noise, or NEA²) */
    double spot_fwhm;           /* θf [rad] */
    int tilt;                   /* WT_SH_TILT_G / _Z: what a slope is (ngs.wfs.tilt; LGS G), model and truth */
    wt_shack_hartmann *sh;      /* Γ_m (owned) */
    int nsub;                   /* valid subapertures */
    int nslopes;                /* 2 nsub */
    int64_t offset;             /* first slope of this sensor in the concatenated vector */
    double *noise_scale;        /* per-axis variance factor of each subaperture (lit_noise), nsub; NULL = all 1 */
    double *beta;               /* LGS elongation vectors [rad], 2*nsub ([βx…, βy…]); NULL for NGS or Δh = 0 */
    char name[16];              /* "LGS1", "NGS2", … for messages */
    struct wt_sensing *diffr;   /* the diffractive sensor (lgs/ngs.wfs.model = "diffractive", core/model/sensing.h;
                                   owned; NULL: geometric). Then sigma2 is its mean per-axis variance (for
                                   messages), noise_scale and beta are NULL, and the reconstructor's noise model
                                   is diffr->cov (the centroider's 2x2 blocks) with τ; the loop's truth uses it */
} wt_sensor;

typedef struct wt_system {
    wt_context *ctx;
    const wt_config *cfg;       /* not owned; must outlive the system (for the drivers and the config
                                   side, params.c / loop_config.c: the numerical objects take what they
                                   need in parameter structs) */
    const char *source;         /* the configuration file, for messages (cfg->path) */
    double diameter;            /* pupil diameter D [m] */
    double obstruction;         /* central obstruction, fraction of D */

    int n;                      /* fine subapertures per side */
    double d;                   /* fine subaperture side [m] */
    uint8_t *valid;             /* n*n valid-subaperture mask */
    int nvalid;
    wt_grid corner_grid;        /* (n+1)² Fried corner grid */
    uint8_t *corner_mask;       /* corners of valid subapertures */
    int64_t ncorners;           /* set corners */
    wt_grid sense_grid;         /* the sensor model's sample grid: (n q + 1)² of spacing d/q (q = 1: corner_grid) */
    int sense_q;                /* q */

    int nsensors, nlgs, nngs;
    wt_sensor sensors[2 * WT_MAX_GS];
    int64_t nslopes;            /* all sensors */

    wt_dm *dm;                  /* the DMs: grids, altitudes, active masks, offsets (owned) */
    int64_t nact;               /* active actuators, all DMs (= dm->nact) */

    int neval;                  /* evaluation directions, index i + g*j of the g x g grid */
    double eval_x[WT_MAX_EVAL], eval_y[WT_MAX_EVAL]; /* [rad] */
    int eval_centre;            /* index of the on-axis direction */
} wt_system;

int wt_system_alloc(wt_context *ctx, const wt_config *cfg, wt_system **out);
void wt_system_free(wt_system *sys);

#endif
