/* sim/record.h: what `wavetomo sim` keeps of a closed-loop run (sim/loop.h) and writes to its
 * result file: per-frame short-exposure Strehl (field average and on-axis, Maréchal, SPEC §8), per-frame
 * residual rms per evaluation direction, optional telemetry (s_t, s_ol = s_t + Â a_t and a_t of paper
 * Algorithm POLC, float32 series), the long-exposure results, the per-part timings and the screen and
 * residual dumps. The datasets and their units are in docs/formats.md.
 *
 * Through core/io/h5.h only (plain data); the caller opens, documents (provenance, layout) and commits
 * the files. alloc allocates everything; wt_sim_record_frame allocates nothing.
 */
#ifndef WT_RECORD_H
#define WT_RECORD_H

#include "../core/io/h5.h"
#include "loop.h"

typedef struct wt_sim_record wt_sim_record;

/* Room for `frames` frames of sys; eval_wavelength [m] of the on-axis Strehl. tel: NULL, or an open
 * writer in which the three telemetry series are created (not owned). */
int wt_sim_record_alloc(wt_context *ctx, const wt_system *sys, long frames, double eval_wavelength,
                        wt_h5_writer *tel, wt_sim_record **out);
void wt_sim_record_free(wt_sim_record *r);

/* With the telemetry writer of alloc: every `every`-th frame (t mod every = 0) of wt_sim_record_frame also appends
 * to TEL.h5 maps/residual (ndir, ny, nx) float32 [m], the piston-removed residual OPD on the loop's fine grid (0
 * outside the pupil), maps/commands (nact) and maps/frame; maps/pupil (ny, nx) and the grid's spacing are written
 * here. Allocates one frame's maps. */
int wt_sim_record_maps(wt_sim_record *r, const wt_loop *lp, wt_h5_writer *tel, int every);

/* Keep the loop's last frame (and append it to the telemetry); step: the wall time of its wt_loop_step
 * [s], the last column of frame/time. Fails past `frames` frames. */
int wt_sim_record_frame(wt_sim_record *r, const wt_loop *lp, double step);
/* Field-average short-exposure Strehl of recorded frame t. */
double wt_sim_record_field_strehl(const wt_sim_record *r, long t);

/* The results of the recorded frames into w: frames, settle_frames, eval/ (directions, LE Strehl and WFE),
 * the field and on-axis summaries, frame/ (per-frame Strehl, rms and per-stage wall times) and timing/ (mean per part). */
int wt_sim_record_write(const wt_sim_record *r, wt_h5_writer *w, const wt_loop *lp, int settle_frames);

/* screens/layer<k> (frame 0 screens) and residual (last frame, piston removed, NaN outside the pupil). */
int wt_sim_write_dump(wt_context *ctx, wt_h5_writer *w, const wt_loop *lp, int neval);

#endif
