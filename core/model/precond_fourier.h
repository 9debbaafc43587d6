/* core/model/precond_fourier.h: the fourier kind, B_F = W F⁻¹ diag(1/λ_max A(k)) F Wᵀ beside the coarse block
 * (precond_fourier.c). Not part of any interface. */
#ifndef WT_PRECOND_FOURIER_H
#define WT_PRECOND_FOURIER_H

#include "precond_base.h"

/* Set-up; z = B_F⁻¹ r (ngs: with the NGS term's Woodbury correction); the NGS
 * columns' sparse per-layer form */
int wt_precond__fourier(wt_precond *p, wt_tomography *t, int coarse_levels);
void wt_precond__fourier_apply(const wt_precond *p, const double *r, double *z, int ngs);
int wt_precond__fourier_ngs_columns(wt_precond *p, const wt_tomography *t, const double *R);
/* fourier with fd_rhat: Y = B⁻¹ R (n x nlr, 64-byte aligned), the bits of nlr applies of B⁻¹ to R's columns, the
 * nlr L layers side by side on the threads */
int wt_precond__fourier_lowrank_Y(const wt_precond *p, double *Y);

/* The layer-l coarse coefficients C = Qᵀ X (u: fd_sc fd_n of work) */
void wt_precond__coarse_coef(const wt_precond *p, const double *X, double *C, double *u);

#endif
