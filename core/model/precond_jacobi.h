/* core/model/precond_jacobi.h: J, the exact diagonal of the LGS and prior part of M (precond_jacobi.c). Not part
 * of any interface. */
#ifndef WT_PRECOND_JACOBI_H
#define WT_PRECOND_JACOBI_H

#include "precond_base.h"

/* J⁻¹ into p->jinv by coloured probing */
int wt_precond__jacobi(wt_precond *p, const wt_tomography *t);

#endif
