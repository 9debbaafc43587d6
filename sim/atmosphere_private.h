/* sim/atmosphere_private.h: the atmosphere's layout and the evaluation of its subharmonic field along a row,
 * shared by atmosphere.c (the screens: drawing, the subharmonics, the accessors) and atmosphere_project.c (the
 * line-of-sight projection); not part of any interface. Calls go one way: the projection calls the screens' row
 * evaluation, never the reverse. */
#ifndef WT_ATMOSPHERE_PRIVATE_H
#define WT_ATMOSPHERE_PRIVATE_H

#include "atmosphere.h"

#include <stdint.h>

#define SHL WT_ATMOSPHERE_SUBHARMONIC_LEVELS

typedef struct atm_layer {
    double altitude;        /* h [m] */
    double fraction;        /* normalised Cn² fraction */
    double vx, vy;          /* wind [m/s] */
    double *screen;         /* [n*n] periodic grid part [m] (inside atm->block) */
    double sh[SHL][3][3][2]; /* subharmonic amplitudes c √Φ Δκ_p [m]: [level][kx + 1][ky + 1][re, im] */
    double sh_offset;       /* minus the grid mean of the subharmonic field [m] */
    double scale, sx, sy;   /* wt_atmosphere_set_drift: screen factor [1], extra displacement [m] */
} atm_layer;

struct wt_atmosphere {
    wt_context *ctx;
    int nlayers;
    int n;
    double delta;    /* [m] */
    double r0, L0;   /* [m] */
    int sh_levels;   /* 0 or SHL */
    wt_grid grid;    /* wt_grid_layer(n, delta) */
    atm_layer *layers;
    double *block;   /* nlayers * n * n screen values */
};

/* ---- the subharmonic field along a row of equally spaced points (atmosphere.c) */

#define SH_CHUNK 32 /* points evaluated per block: the powers R^i make each block a vectorisable loop */

/* What all rows of one layer share for sample spacing dpx: the x rotations. */
typedef struct sh_step {
    _Alignas(64) double pr[SHL][SH_CHUNK]; /* e^{2πi Δκ_p dpx i}, i < SH_CHUNK (cache-line aligned rows) */
    _Alignas(64) double pi[SHL][SH_CHUNK];
    double rr[SHL], ri[SHL];               /* e^{2πi Δκ_p dpx SH_CHUNK}: block to block */
    int levels;
} sh_step;

/* One row: the field is g0 + Σ_p Re[G_p E_p(x)], E_p(x) = e^{2πi Δκ_p x}. */
typedef struct sh_row {
    double g0;               /* the kx = 0 terms plus the offset [m] */
    double gr[SHL], gi[SHL]; /* G_p [m] */
    double er[SHL], ei[SHL]; /* E_p at the first point of the next block */
} sh_row;

/* The x rotations of the levels' frequencies Δκ_p = dk / 3^(p+1) for sample spacing dpx. */
void wt_atmosphere__sh_step_init(int levels, double dk, double dpx, sh_step *q);
/* The y part of row y = py of layer ly (g0, G_p) */
void wt_atmosphere__sh_row_y(const atm_layer *ly, int levels, double dk, double py, sh_row *s);
/* The x part of a row from x = px0 on (E_p) */
void wt_atmosphere__sh_row_x(int levels, double dk, double px0, sh_row *s);
/* Both: the row y = py from x = px0 on */
void wt_atmosphere__sh_row_init(const atm_layer *ly, int levels, double dk, double py, double px0, sh_row *s);

/* The block's coefficients A_p = G_p E_p (ar + i ai), then E_p stepped to the next block. The
 * block-to-block rotation drifts by ~1e-16 relative per block: negligible for rows of thousands of
 * points. */
static inline void wt_atmosphere__sh_row_coef(const sh_step *q, sh_row *s, double *restrict ar, double *restrict ai)
{
    for (int p = 0; p < q->levels; p++) {
        double er = s->er[p], ei = s->ei[p];
        ar[p] = s->gr[p] * er - s->gi[p] * ei, ai[p] = s->gr[p] * ei + s->gi[p] * er; /* G E */
        s->er[p] = er * q->rr[p] - ei * q->ri[p];
        s->ei[p] = er * q->ri[p] + ei * q->rr[p];
    }
}

/* v[i] = the field at the next m ≤ SH_CHUNK points: g0 + Σ_p Re[A_p R_p^i], the levels added in
 * order; then step to the next block. */
static inline void wt_atmosphere__sh_row_block(const sh_step *q, sh_row *s, int m, double *restrict v)
{
    double ar[SHL] = {0}, ai[SHL] = {0};
    wt_atmosphere__sh_row_coef(q, s, ar, ai);
    for (int i = 0; i < m; i++) v[i] = s->g0;
    for (int p = 0; p < q->levels; p++) {
        const double *restrict pr = q->pr[p], *restrict pi = q->pi[p];
        for (int i = 0; i < m; i++) v[i] += ar[p] * pr[i] - ai[p] * pi[i];
    }
}

#endif
