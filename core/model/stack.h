/* core/model/stack.h: the stack of the sensors' Γ_m P_m (SPEC §4, §6, §7; paper eq. eqn_lse):
 *
 *   y_m ← y_m + α Γ_m Σ_l P_{m,l} x_l          for every sensor m (y in system slope order),
 *   x_l ← x_l + α P_{m,l}ᵀ Γ_mᵀ y_m             one sensor's transpose,
 *
 * the loop over sensors that the tomography (x = the reconstruction layers) and the interaction
 * (x = the concatenated DM grids, one input) share. A view: it owns nothing; the workspace is the
 * caller's (one sample-grid phase per sensor), so two stacks over the same operators can run at once.
 */
#ifndef WT_STACK_H
#define WT_STACK_H

#include "../op/projection.h"
#include "system.h"

typedef struct wt_sensor_stack {
    const wt_system *sys;
    int nin;                          /* input grids seen by every sensor (layers; 1 for the DM grids) */
    wt_projection *const *proj;       /* nsensors x nin: P_{m,l} at [m * nin + l], onto sys->sense_grid */
    const int64_t *in_offset;         /* nin: first point of input grid l in x */
} wt_sensor_stack;

/* y ← y + α Γ P x for every sensor, sensors in parallel on nthreads (1: serial); phase: nsensors x
 * (points of sys->sense_grid), overwritten. Allocates nothing. */
void wt_sensor_stack_apply(const wt_sensor_stack *st, double alpha, const double *x, double *y, double *phase,
                           int nthreads);
/* y ← α Γ P x (y zeroed first, each sensor's slice by the thread that fills it: the bits of a memset
 * and wt_sensor_stack_apply, without the serial pass over all slopes). */
void wt_sensor_stack_set(const wt_sensor_stack *st, double alpha, const double *x, double *y, double *phase,
                         int nthreads);
/* wt_sensor_stack_set's work for sensor m alone (y_m ← α Γ_m P_m x), for a caller's own parallel loop; phase:
 * one sample-grid workspace, overwritten. */
void wt_sensor_stack_set_sensor(const wt_sensor_stack *st, int m, double alpha, const double *x, double *y,
                                double *phase);
/* The first half of wt_sensor_stack_apply_t_sensor, for a caller that projects by layers itself: phase ←
 * α Γ_mᵀ y_m (overwritten). */
void wt_sensor_stack_phase_t(const wt_sensor_stack *st, int m, double alpha, const double *y_m, double *phase);
/* x ← x + α Σ_l P_{m,l}ᵀ Γ_mᵀ y_m for sensor m alone (y_m: its slopes); phase: one sample-grid
 * workspace, overwritten. Sensors that write the same x must not run at once. */
void wt_sensor_stack_apply_t_sensor(const wt_sensor_stack *st, int m, double alpha, const double *y_m, double *x,
                                    double *phase);

/* Single precision (the tomography's recon.<variant>.operator_precision = "fp32"): wt_sensor_stack_set_sensor,
 * wt_sensor_stack_phase_t and wt_sensor_stack_apply_t_sensor on float layers, phases and slopes (the _f32 kernels
 * of projection.h and shack_hartmann.h; ~1e-6 relative to the double forms, not their bits). */
void wt_sensor_stack_set_sensor_f32(const wt_sensor_stack *st, int m, float alpha, const float *x, float *y,
                                    float *phase);
void wt_sensor_stack_phase_t_f32(const wt_sensor_stack *st, int m, float alpha, const float *y_m, float *phase);
void wt_sensor_stack_apply_t_sensor_f32(const wt_sensor_stack *st, int m, float alpha, const float *y_m, float *x,
                                        float *phase);

#endif
