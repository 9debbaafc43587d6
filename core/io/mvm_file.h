/* core/io/mvm_file.h: the MVM control matrix file MATRIX.h5 (SPEC §9).
 *
 * Datasets: R (n_act x n_slopes, float32, row = actuator), RA = R Â (n_act x n_act, float32), and the
 * identity of the system they were built for: the root attribute "config_sha256" (SHA-256 of the
 * configuration keys that can change R, wt_config.matrix_sha256) and the dataset "matrix_config" (that
 * text), plus the variant, α, τ and the build statistics. A reader refuses a file built for another
 * system, of the wrong shape, truncated or incomplete — before any frame is processed.
 */
#ifndef WT_MVM_FILE_H
#define WT_MVM_FILE_H

#include "../model/mvm.h"
#include "h5.h"

/* Write R, RA, the identity and the statistics into an open writer (the caller adds provenance and
 * layout and commits). variant: "pcg3" or "cg9". */
int wt_mvm_file_write(wt_h5_writer *w, const wt_mvm *m, const wt_config *cfg, const char *variant);

/* Read MATRIX.h5 for the system `sys` (built from cfg). Refuses (WT_ERR_FORMAT, naming the file) a
 * matrix whose config_sha256 differs from cfg->matrix_sha256, or whose shapes differ from the system's
 * n_act x n_slopes. variant_out: NULL or 16 bytes for the stored variant. [out] *out (wt_mvm_free). */
int wt_mvm_file_read(wt_context *ctx, const char *path, const wt_config *cfg, const wt_system *sys, wt_mvm **out,
                     char *variant_out);

#endif
