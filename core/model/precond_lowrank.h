/* core/model/precond_lowrank.h: the NGS term of P = B + R C_n Rᵀ by Woodbury, P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ
 * (precond_lowrank.c). Not part of any interface. */
#ifndef WT_PRECOND_LOWRANK_H
#define WT_PRECOND_LOWRANK_H

#include "precond_base.h"

/* R, K and Y at set-up (nothing without NGS); z = P⁻¹ r */
int wt_precond__lowrank(wt_precond *p, wt_tomography *t);
void wt_precond__lowrank_apply(const wt_precond *p, const double *r, double *z);

/* Y = B⁻¹ R, K = Ĉ⁻¹_NGS + Rᵀ Y factored, Y laid out as the kind's apply reads it (R n x nlr, cinv nlr x nlr) */
int wt_precond__lowrank_factor(wt_precond *p, const double *R, const double *cinv);

#endif
