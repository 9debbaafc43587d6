/* core/optics/spot_private.h: the spot object's layout, shared by spot.c (set-up, tables, images, noise) and
 * spot_reference.c (the reference and its derivatives); not part of any interface. */
#ifndef WT_SPOT_PRIVATE_H
#define WT_SPOT_PRIVATE_H

#include "spot.h"

#include <fftw3.h>
#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define ALIGN 64
/* What the loop removes from a subaperture's phase in the reference's seeing: piston and tilt, the tilt
 * being the G-tilt (the spot's centroid shift, the slope the reconstructor models and the loop drives to
 * zero), so the reference is the mean spot re-centred on its centroid. With the Z-tilt (least-squares
 * plane) removed instead, the mean spot also holds the G − Z jitter and is wider than the loop's: the
 * matched filter's in-loop gain was 1.04–1.05 on the demo and the E-ELT presets, 0.97–0.99 with the G-tilt;
 * removing the x·y term of a DM at the subaperture's pitch as well moved it by < 1 % (docs/results.md §32). */
#define LOOP_GTILT 1
#define RAD2AS (180.0 * 3600.0 / M_PI)
/* output pixels per block of the direct sum in image_one: one row block is held in registers */
#define SUM_W 16
#define SUM_R 4 /* rows per block: 2·SUM_R independent accumulators hide the add latency */
typedef float v8f __attribute__((vector_size(32)));

typedef struct {
    void *block;           /* the allocation (workspace arrays are carved from it, aligned) */
    fftwf_complex *field;  /* N² */
    float *psf;            /* N², fft-shifted, scaled to photo-electrons */
    float *tmp;            /* M × N after the x rebinning */
    float *cells;          /* M² */
    double *opd;           /* n_p² (the tilted flat OPDs of wt_spot_reference) */
    float *img2;           /* Ns² (the second image of a central difference) */
    float *cv;             /* M² the non-zero cells' values, in the order (my, mx) */
    int *co;               /* M² their table offsets (phase·Lp² + e1x + Lp·e1y) */
} workspace;

struct wt_spot {
    wt_context *ctx;
    wt_spot_params par; /* sodium set to NULL after alloc */
    int nsub, np, N, Ns, k, M, Lp, R, nthreads;
    int lgs;             /* 1: built with a sodium profile (wt_spot_set_sodium may replace it) */
    int qmin, omin;      /* first lattice point of the cells; smallest pixel−cell offset kP − q */
    double theta_f;      /* PSF sample [rad] */
    double blur;         /* variance per axis the rebinning adds, θ_f²/12 + c²/6 [rad²] */
    double *flux;        /* [nsub] photons × lit */
    float *scale;        /* [nsub] flux / (N² Σ A²) */
    float *amp;          /* [nsub·n_p²] */
    double *xs;          /* [n_p] sample offsets from the subaperture centre [m] */
    int *rm;             /* [N·R] first cell of the overlap of PSF sample i, then consecutive cells */
    float *rw;           /* [N·R] overlap weights (fractions of the sample) */
    int *rn;             /* [N] cells PSF sample i overlaps */
    int *gs;             /* [M + 1] the same weights by cell: cell m gathers gi/gw[gs[m] .. gs[m+1]) */
    int *gi;             /* [N·R] PSF sample of each, ascending per cell */
    float *gw;           /* [N·R] its weight */
    float *K;            /* [nsub · k² · Lp²] phase tables of the source ⊛ pixel kernel */
    double *xc, *yc;     /* [nsub] subaperture centres [m] (the tables of a new sodium profile need them) */
    fftwf_plan rows, cols;
    fftwf_plan otf_fwd, otf_bwd; /* N × N complex, for the reference's seeing */
    workspace *ws;       /* [nthreads] */
    /* wt_spot_keep_reference: the rebinned cells of the reference's five images per subaperture (I0, −x, +x, −y,
     * +y: they do not depend on the sodium profile), [nsub · 5 · M²], and what they were made with */
    float *rcells;
    int rc_valid, rc_see;
    double rc_dtheta;
    wt_spot_seeing rc_seeing;
    double *dl;            /* the seeing's lag table of dl_key = {r0, L0, grid} (wt_spot_reference's last), or NULL */
    double dl_key[3];
};


/* One subaperture: OPD (float or double, one of them non-NULL) → image (spot.c). cells_in: the rebinned cells
 * to sum instead of an OPD (an image made before, cells_out); cells_out: where to copy this image's cells (M²
 * floats), or NULL. The same arithmetic either way: an image from kept cells has the bits of one made anew. */
void wt_spot__image_one(const wt_spot *s, int is, const float *opdf, const double *opdd, const float *otf, workspace *w,
                        float *img, const float *cells_in, float *cells_out);

#endif
