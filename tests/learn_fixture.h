/* tests/learn_fixture.h: what the identification suites share (test_learn.c, test_learn_wind.c): a small annular
 * Shack–Hartmann geometry with its LGS ring, in core/model/learn.h's layout. */
#ifndef WT_TESTS_LEARN_FIXTURE_H
#define WT_TESTS_LEARN_FIXTURE_H

#include <math.h>
#include <stdint.h>

#include "core/model/learn.h"

#define ARCSEC (M_PI / 180.0 / 3600.0)

/* n x n subapertures of d on an annulus (centre inside [obs, 1] x n/2 subapertures), nlgs LGS on a ring of
 * radius rad_as arcsec at 90 km */
typedef struct {
    int n, nlgs;
    double d;
    uint8_t valid[32 * 32];
    double tx[8], ty[8];
    wt_learn_geometry g;
} geom;

static inline void geom_make(geom *G, int n, int nlgs, double rad_as)
{
    G->n = n, G->nlgs = nlgs, G->d = 0.5;
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            double x = ix - (n - 1) / 2.0, y = iy - (n - 1) / 2.0, r = hypot(x, y) / (n / 2.0);
            G->valid[ix + n * iy] = r <= 1.0 && r >= 0.25;
        }
    for (int i = 0; i < nlgs; i++) {
        G->tx[i] = rad_as * ARCSEC * cos(2 * M_PI * i / nlgs);
        G->ty[i] = rad_as * ARCSEC * sin(2 * M_PI * i / nlgs);
    }
    G->g = (wt_learn_geometry){n, G->d, G->valid, nlgs, G->tx, G->ty, 90e3};
}

static inline int geom_nsub(const geom *G)
{
    int s = 0;
    for (int k = 0; k < G->n * G->n; k++) s += G->valid[k];
    return s;
}

#endif
