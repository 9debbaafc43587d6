/* core/model/precond_multilevel.h: the multilevel kind's layer blocks below the coarse squares
 * (precond_multilevel.c). Not part of any interface. */
#ifndef WT_PRECOND_MULTILEVEL_H
#define WT_PRECOND_MULTILEVEL_H

#include "precond_base.h"

/* The layer blocks below coarse squares of sides sc[l]; z = B_b⁻¹ r on the
 * blocks [b0, b1) */
int wt_precond__layer_blocks(wt_precond *p, const wt_tomography *t, const int *sc);
void wt_precond__layer_blocks_apply(const wt_precond *p, const double *r, double *z, int64_t b0, int64_t b1);

#endif
