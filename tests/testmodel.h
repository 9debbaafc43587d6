/* tests/testmodel.h: the overwriting forms of model's accumulating operators (y ← y + α A x), for
 * the tests' algebra: y = A x. */
#ifndef WT_TESTMODEL_H
#define WT_TESTMODEL_H

#include <string.h>

#include "core/model/fitting.h"
#include "core/model/tomography.h"

/* y = M c */
static inline void tu_tomo_apply(wt_tomography *t, const double *c, double *y)
{
    memset(y, 0, (size_t)wt_tomography_nunknowns(t) * sizeof *y);
    wt_tomography_apply(t, 1.0, c, y);
}

/* s = Ã c */
static inline void tu_tomo_slopes(wt_tomography *t, const double *c, double *s)
{
    memset(s, 0, (size_t)wt_tomography_system(t)->nslopes * sizeof *s);
    wt_tomography_slopes(t, 1.0, c, s);
}

/* b = Σ Ãᵀ Ĉ⁻¹ s */
static inline void tu_tomo_rhs(wt_tomography *t, const double *s, double *b)
{
    memset(b, 0, (size_t)wt_tomography_nunknowns(t) * sizeof *b);
    wt_tomography_rhs(t, 1.0, s, b);
}

/* y = (Σ HᵀH + εI) a, for a system of nact actuators */
static inline void tu_fitting_apply(wt_fitting *f, int64_t nact, const double *a, double *y)
{
    memset(y, 0, (size_t)nact * sizeof *y);
    wt_fitting_apply(f, 1.0, a, y);
}

#endif
