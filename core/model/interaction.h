/* core/model/interaction.h: the DM-to-slope interaction Â (paper Algorithm POLC; SPEC §5, §7).
 *
 *   (Â a)_m = Γ_m H_m a,   H_m = the DMs seen along sensor m's line of sight (cone factor for an LGS),
 *
 * a the active-actuator commands (system order), H_m the bilinear influence of every DM at its
 * conjugate altitude sampled on the Fried corner grid (actuators beyond a DM's grid count as zero).
 * POLC uses it to rebuild open-loop slopes: s_ol = s + Â a.
 */
#ifndef WT_INTERACTION_H
#define WT_INTERACTION_H

#include "../la/sparse.h"
#include "system.h"

typedef struct wt_interaction wt_interaction;

int wt_interaction_alloc(wt_context *ctx, const wt_system *sys, wt_interaction **out);
void wt_interaction_free(wt_interaction *ia);
/* s <- s + alpha Â a  (a: nact, s: nslopes). Uses workspace in the object: not thread-safe per object. */
void wt_interaction_apply(wt_interaction *ia, double alpha, const double *a, double *s);
/* a <- a + alpha Âᵀ s */
void wt_interaction_apply_t(wt_interaction *ia, double alpha, const double *s, double *a);
/* The same with the caller's workspace, so that one operator serves several callers at once (one workspace
 * each; ia is not modified, the bits those of the forms above): grids of wt_interaction_grids_size doubles, phase
 * of wt_interaction_phase_size; nthreads: the OpenMP threads of the forward (the forms above use ia's context's). */
int64_t wt_interaction_grids_size(const wt_interaction *ia);
int64_t wt_interaction_phase_size(const wt_interaction *ia);
void wt_interaction_apply_ws(const wt_interaction *ia, double alpha, const double *a, double *s, double *grids,
                             double *phase, int nthreads);
void wt_interaction_apply_t_ws(const wt_interaction *ia, double alpha, const double *s, double *a, double *grids,
                               double *phase);
/* Â as a sparse matrix: nslopes x nact. */
int wt_interaction_assemble(wt_interaction *ia, wt_sparse **out);

#endif
