/* core/model/estimate.h: the peak memory and the run time of a command, estimated from the configuration
 * alone, before anything large is allocated (sizes that fit every key's range but not the machine are refused
 * up front, naming the keys that drive them).
 *
 * Memory: the sum of the largest arrays each command holds at its peak, counted from the sizes the
 * configuration implies (SPEC §1: subapertures n, fine points n p + 1 per side, phase screens of side
 * 2 (D + 2 h_top θ_max) / δ as sim/loop.c sizes them, active actuators within D/2 + h tan θc plus the
 * guard rings, layer grids of the reconstruction variants) times the bytes the code stores per element,
 * plus the process's own base (libraries, ~15 MB). The sparse Cholesky factor of the MVM build is not known
 * before CHOLMOD's analysis: it is modelled as nnz(L) = 10.5 n^1.5 for n unknowns (fitted to the two E-ELT
 * builds of docs/results.md §4, 39.6 M and 402 M non-zeros, within 6 %), nnz(N) = nnz(L) / 2.5; the build
 * itself checks its exact figures again before each large allocation (builder/mvm_build.h).
 *
 * Time: counted work per frame divided by a calibrated rate. The atmosphere and the evaluation: one
 * bilinear read per fine point, layer and line of sight (sensors and evaluation directions); the
 * reconstructor: the flops of its iterations (the stencils of core/model/tomography_cost.c); the MVM: its
 * bytes streamed. The rates are the ones measured on this 2-core machine when quiet (docs/results.md §7b:
 * single thread, the GEMV of §2): the time is an order of magnitude, not a promise.
 *
 * Diffractive sensors (`*.wfs.model = "diffractive"`, built with the system by every command): the spot
 * kernel tables, k² Lp² floats per subaperture with its n_p² amplitudes (14 kB at the E-ELT LGS: 16 pixels
 * of 1.1″, k = 3, n_p 16, N 32; 431 MB for the 6 LGS, wt_spot_memory's figure), the images, references and
 * matched-filter rows beside them (~200 MB more; tests/test_sensing.c checks both), their set-up
 * (tables and 5 reference images per subaperture: ~1 s per E-ELT LGS) and, in `sim`, one image, its noise
 * and the centroider per subaperture and frame (~0.7 s per E-ELT frame on 2 idle cores; bench-spot rates).
 */
#ifndef WT_ESTIMATE_H
#define WT_ESTIMATE_H

#include <stdio.h>

#include "../config/config.h"

enum { WT_TASK_SIM = 0, WT_TASK_RUN, WT_TASK_BUILD, WT_TASK_INFO };

typedef struct wt_estimate_request {
    int task;        /* WT_TASK_* */
    int recon;       /* WT_RECON_* of core/model/reconstructor.h (sim, run; build: PCG3 or CG9) */
    int64_t frames;  /* frames to run (≤ 0: cfg->frames) */
    int iterations;  /* pcg3/cg9: (P)CG iterations per frame (≤ 0: recon.<variant>.iterations; a --iters override
                        counts here: an upper bound, the solver stops earlier at rounding level) */
} wt_estimate_request;

#define WT_ESTIMATE_TERMS 12

typedef struct wt_estimate {
    double bytes;    /* peak resident memory [bytes] */
    double seconds;  /* run time [s] */
    int nterms;
    struct {
        char what[64];   /* "phase screens" */
        char keys[192];  /* the keys that drive it */
        double bytes;
    } term[WT_ESTIMATE_TERMS];
} wt_estimate;

/* The estimate of one command on cfg. Allocates nothing. */
void wt_estimate_resources(const wt_config *cfg, const wt_estimate_request *req, wt_estimate *out);
/* Several commands one after the other (compare, budget): the peak is the largest, the times add up. */
void wt_estimate_add(wt_estimate *total, const wt_estimate *e);
/* "estimated peak memory 1.23 GB, run time 4.5 min" and the terms, largest first, one per line. */
void wt_estimate_print(FILE *f, const char *prefix, const wt_estimate *e);
/* MemAvailable of /proc/meminfo [bytes]; 0 when it cannot be read. */
double wt_memory_available(void);
/* WT_OK when e->bytes fits `limit` bytes (≤ 0: no limit); else WT_ERR_NOMEM with a message naming the
 * estimate, the limit and where it comes from (`source`), and the largest terms with their keys. */
int wt_estimate_check(wt_context *ctx, const char *what, const wt_estimate *e, double limit, const char *source);

#endif
