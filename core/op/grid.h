/* core/op/grid.h: a regular square-cell grid in metres, the common currency of the operators.
 *
 * Point (ix, iy) sits at (x0 + ix*dx, y0 + iy*dx); it is stored at index ix + nx*iy (x fastest).
 * Layer grids, DM actuator grids and the Fried corner grid of a sensor are all wt_grid.
 */
#ifndef WT_GRID_H
#define WT_GRID_H

#include <stdint.h>

typedef struct wt_grid {
    int nx, ny;     /* points along x and y */
    double dx;      /* spacing [m] */
    double x0, y0;  /* coordinates of point (0, 0) [m] */
} wt_grid;

static inline int64_t wt_grid_size(const wt_grid *g) { return (int64_t)g->nx * g->ny; }

/* A centred n x n grid of spacing dx: points at -(n-1)dx/2 ... +(n-1)dx/2. */
static inline wt_grid wt_grid_centred(int n, double dx)
{
    wt_grid g = {n, n, dx, -0.5 * (n - 1) * dx, -0.5 * (n - 1) * dx};
    return g;
}

/* The periodic wavelet-domain grid of a reconstruction layer: n x n points (n even) spanning
 * [-n dx/2, n dx/2). Point i sits at (i - n/2) dx, so x = 0 is a grid point and a centred actuator grid
 * of the same pitch with an odd number of actuators falls exactly on layer points. */
static inline wt_grid wt_grid_layer(int n, double dx)
{
    wt_grid g = {n, n, dx, -0.5 * n * dx, -0.5 * n * dx};
    return g;
}

#endif
