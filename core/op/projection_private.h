/* core/op/projection_private.h: the projection's tables, shared by its double (projection.c) and single-precision
 * (projection_f32.c) kernels; not for other modules (they see the opaque wt_projection of projection.h). */
#ifndef WT_PROJECTION_PRIVATE_H
#define WT_PROJECTION_PRIVATE_H

#include <stdint.h>

#include "projection.h"

struct wt_projection {
    wt_context *ctx;
    int nlayers;
    int tnx, tny;     /* target grid points along x, y */
    int64_t nin;      /* Σ layer points */
    int32_t *lnx;     /* [nlayers] points along x of each layer (row stride) */
    int32_t *cbase;   /* [nlayers * tnx] x index of the stencil's left column in the layer */
    double *cw0, *cw1; /* [nlayers * tnx] weights of the left and right columns */
    double *cw01;     /* [nlayers * tnx][2]: (cw0, cw1) side by side, for the two-lane kernels */
    int32_t *rbase;   /* [nlayers * tny] layer offset + (bottom row) * nx_ℓ: the stencil's row start */
    double *rw0, *rw1; /* [nlayers * tny] weights of the bottom and top rows */
    int narrow;       /* 1: the runs are 16 points long on average and along every run, every layer's columns
                         (the aligned layers' aside) are non-decreasing and span at most 6 cells over 8 points
                         (apply_layers_avx512's condition) */
    uint8_t *aligned; /* [nlayers] 1: the layer's stencil is the identity on every run (weights exactly (1, 0) in
                         x and y, columns advancing by one point per point: the ground layer under a sample grid
                         of its spacing and origin), so apply reads and apply_t writes it contiguously */
    int any_aligned;
    int32_t nrun;     /* runs of consecutive masked target points within a row */
    int cx0, cx1;     /* the columns [cx0, cx1) the runs cover, all rows together (apply_rows' x range) */
    int32_t *run_row, *run_lo, *run_hi; /* [nrun] row iy and columns [lo, hi) */
    /* The single-precision forms (projection_f32.c): the weights rounded to float, in one allocation */
    float *f32;       /* cw0, cw1 ([nlayers * tnx] each), then rw0, rw1 ([nlayers * tny] each) */
    float *cw0f, *cw1f, *rw0f, *rw1f;
    struct wt_proj_t32 *t32; /* [nlayers] the single-precision transpose's tables (projection_f32.c); NULL: none */
};

/* The single-precision transpose's tables of one layer (projection_f32.c): U, the target points' values summed
 * into layer rows (rows r_lo … r_lo + nrow − 1, columns cx0 … at stride ustride), then each layer column j =
 * c0 + 16 b + e (block b, lane e) as Σ_k wt[b][k][e] U[base[b] + idx[b][k][e]] over its K entries (the points
 * whose column stencil holds j, zero-weighted padding) */
typedef struct wt_proj_t32 {
    int ok;               /* 0: no tables for this layer (aligned, or beyond their limits): the other kernels */
    int64_t loff;         /* the layer's first value in the layers array */
    int32_t r_lo, nrow, ustride, c0, ncol, nblk, K;
    int32_t *urow;        /* [tny] U row of target row iy's bottom stencil row (−r_lo relative) */
    int32_t *base;        /* [nblk] first U column of block b's entries (relative to cx0) */
    int32_t *idx;         /* [nblk][K][16] entry's U column − base, 0 … 47 */
    uint16_t *hi;         /* [nblk][K] lanes whose idx ≥ 32 */
    float *wt;            /* [nblk][K][16] */
} wt_proj_t32;

/* Builds p->t32 (called by wt_projection_alloc for a covered projection; layers: its layer grids) */
int wt_projection_f32_setup(wt_projection *p, const wt_grid *layers);
void wt_projection_f32_free(wt_projection *p);

#endif
