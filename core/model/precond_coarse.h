/* core/model/precond_coarse.h: the coarse block B_c of the LGS and prior part of M, and B⁻¹ of every kind
 * (precond_coarse.c). Not part of any interface. */
#ifndef WT_PRECOND_COARSE_H
#define WT_PRECOND_COARSE_H

#include "precond_base.h"

/* Layer l's coarse square's side; the block's Cholesky factor into p->c_L;
 * z = B_c⁻¹ r on the block by the factor's two solves, or by the inverse's rows [i0, i1) */
int wt_precond__coarse_side(const wt_tomography *t, int l, int coarse_levels);
int wt_precond__coarse(wt_precond *p, wt_tomography *t, int coarse_levels);
void wt_precond__coarse_solve(const wt_precond *p, const double *r, double *z);
void wt_precond__coarse_inv_rows(const wt_precond *p, const double *r, double *z, int i0, int i1);
/* coarse_ngs: c_L's factor replaced by the block's inverse c_inv (or c_inv32 when single) */
int wt_precond__coarse_invert(wt_precond *p, int single);
/* z = B⁻¹ r: the kind's part before the NGS term (J, the coarse block with the multilevel kind's layer blocks
 * or fourier's B_F) */
void wt_precond__base_apply(const wt_precond *p, const double *r, double *z);

#endif
