/* core/model/precond_lowrank.c: the NGS term of the preconditioners (jacobi_ngs and above; precond.h), by Woodbury:
 *
 *   P = B + R C_n Rᵀ,   P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ,   Y = B⁻¹ R,   K = Ĉ⁻¹_NGS + Rᵀ B⁻¹ R,
 *
 * its set-up (R, K's factor, Y laid out as the apply reads it) and the apply around the kind's B⁻¹
 * (precond_coarse.c, precond_multilevel.c, precond_fourier.c). */
#include "precond_lowrank.h"
#include "precond_coarse.h"
#include "precond_fourier.h"
#include "precond_multilevel.h"

#include <stdint.h>
#include <string.h>

#include "../la/vec.h"
#include "../op/noise.h"


/* ---- NGS low-rank correction --------------------------------------------------------------------
 *
 * The NGS term of M is Σ_NGS Ãᵀ C̃⁻¹ Ã = G Ĉ⁻¹_NGS Gᵀ with G = [Ãᵀ e_k] over the r NGS slopes (r = 12
 * for one 2x2 and two 1x1 sensors): rank r, but weighted by NGS noise variances that can be 10⁵ times
 * smaller than the LGS ones (SPEC §11: 0.05 mas against 20 mas). A diagonal cannot describe it — the
 * NGS modes are global tip-tilt-like shapes — and the few PCG iterations then spend themselves on them
 * (PCG-3 at low noise lost its correction entirely). So P = B + G Ĉ⁻¹ Gᵀ = B + R C_n Rᵀ, with
 * R = G Ĉ⁻¹ = [Ãᵀ Ĉ⁻¹ e_k] (r right-hand sides) and C_n = (Ĉ⁻¹_NGS)⁻¹, is inverted by Woodbury:
 *   P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ,   Y = B⁻¹ R,   K = Ĉ⁻¹_NGS + Rᵀ B⁻¹ R   (r x r, Cholesky once),
 * which costs 4 r n flops per iteration on top of B⁻¹. */

/* coarse_ngs's Woodbury term by blocks of 8 rows (lr_Yb: only the blocks where Y has a non-zero, each block's
 * r columns of 8 rows side by side). Yᵀ r: the kept blocks fall into WT_VEC_CHUNKS fixed chunks; in a chunk,
 * row e of every block (e < 8) adds into lane e of column k's sum, in block order, and the chunk's value is the
 * 8 lanes added pairwise in a fixed tree; the chunks are added in order (wt_vec_dot_many_finish). Which thread
 * runs a chunk changes nothing: the same bits for any thread count. B a compile-time constant (always inlined:
 * the B sums of 8 lanes stay in vector registers); a last block past n takes only its rows < n. The update
 * reads the same copy (one pass over ~1 MB each instead of a column-major Y and a row-major copy). */
/* (yb_vec, yb_vec32 and YB_COL: precond_base.h) */

static inline __attribute__((always_inline)) void yb_dots_chunk(const int B, const int f32, const wt_precond *p,
                                                                const double *r, int64_t b0, int64_t b1,
                                                                double *restrict part, int c)
{
    const int64_t n = p->n;
    yb_vec acc[WT_VEC_MAX_MANY];
    for (int k = 0; k < B; k++) acc[k] = (yb_vec){0.0};
    for (int64_t b = b0; b < b1; b++) {
        const int64_t i0 = 8 * p->lr_blk[b];
        yb_vec rr = {0.0};
        if (i0 + 8 <= n) rr = *(const yb_vec *)(r + i0);
        else
            for (int e = 0; e < n - i0; e++) rr[e] = r[i0 + e]; /* lanes past n: Y 0 (never set) times 0, their
                                                                   sums stay +0 */
        for (int k = 0; k < B; k++) acc[k] += YB_COL(p, B, b, k, f32) * rr;
    }
    for (int k = 0; k < B; k++)
        part[(int64_t)k * WT_VEC_CHUNKS + c] =
            ((acc[k][0] + acc[k][1]) + (acc[k][2] + acc[k][3])) + ((acc[k][4] + acc[k][5]) + (acc[k][6] + acc[k][7]));
}

WT_CPU_CLONES static void yb_dots(const wt_precond *p, const double *r, int c0, int c1)
{
    const int64_t nb = p->lr_nblk;
    for (int c = c0; c < c1; c++) {
        const int64_t b0 = nb * c / WT_VEC_CHUNKS, b1 = nb * (c + 1) / WT_VEC_CHUNKS;
        if (p->nlr == 12 && p->lr_Yb32) yb_dots_chunk(12, 1, p, r, b0, b1, p->lr_part, c); /* the E-ELT's 3 NGS */
        else if (p->nlr == 12) yb_dots_chunk(12, 0, p, r, b0, b1, p->lr_part, c);
        else if (p->lr_Yb32) yb_dots_chunk(p->nlr, 1, p, r, b0, b1, p->lr_part, c);
        else yb_dots_chunk(p->nlr, 0, p, r, b0, b1, p->lr_part, c);
    }
}

/* coarse_ngs: z = J⁻¹ r off the coarse block, its inverse on it, minus Y K⁻¹ Yᵀ r. Every part splits over
 * the threads by fixed pieces (rows, coarse rows, chunks of blocks), one barrier between the dots and the
 * update; each thread solves the small K system itself (no serial section). */
static void coarse_ngs_apply(const wt_precond *p, const double *r, double *z)
{
    const int64_t n = p->n;
#pragma omp parallel num_threads(p->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        const int64_t i0 = n * id / nt, i1 = n * (id + 1) / nt;
        for (int j = 0; j < p->c_nfree; j++) {
            const int64_t lo = p->c_free[2 * j] > i0 ? p->c_free[2 * j] : i0;
            const int64_t hi = p->c_free[2 * j + 1] < i1 ? p->c_free[2 * j + 1] : i1;
            for (int64_t i = lo; i < hi; i++) z[i] = p->jinv[i] * r[i];
        }
        wt_precond__coarse_inv_rows(p, r, z, (int)((int64_t)p->nc * id / nt), (int)((int64_t)p->nc * (id + 1) / nt));
        yb_dots(p, r, WT_VEC_CHUNKS * id / nt, WT_VEC_CHUNKS * (id + 1) / nt);
#pragma omp barrier
        double w[WT_VEC_MAX_MANY];
        wt_vec_dot_many_finish(p->nlr, p->lr_part, w);
        wt_precond__lowrank_solve(p, w);
        wt_precond__yb_update(p, w, z, p->lr_nblk * id / nt, p->lr_nblk * (id + 1) / nt);
    }
}

/* z = P⁻¹ r = B⁻¹ r − Y K⁻¹ Yᵀ r. B⁻¹ r (coarse_apply: mostly the coarse block's two triangular solves,
 * serial chains) and Yᵀ r (the r dots, which read r and not z) are independent: on two threads they run
 * side by side, then both threads share the update of z. Y is zero on ~60 % of the rows (the fine
 * wavelet coefficients away from the NGS footprints' rims): its runs of non-zero rows are skipped. */
void wt_precond__lowrank_apply(const wt_precond *p, const double *r, double *z)
{
    const int64_t n = p->n;
    const int q = p->nlr;
    if (q == 0) {
        wt_precond__base_apply(p, r, z);
        return;
    }
    if (p->fd_n > 0) {
        wt_precond__fourier_apply(p, r, z, 1);
        return;
    }
    if (p->lr_Yb || p->lr_Yb32) {
        coarse_ngs_apply(p, r, z);
        return;
    }
#pragma omp parallel num_threads(p->nthreads)
    {
        int id, nt;
        wt_thread_team(&id, &nt);
        if (p->nb > 0) {
            /* multilevel: the blocks in fixed chunks over the threads, the coarse solve on one of them (each
             * block's solve does not depend on the thread that runs it: the same bits on any thread count) */
#pragma omp single nowait
            wt_precond__coarse_solve(p, r, z);
#pragma omp for schedule(dynamic, 1) nowait
            for (int c = 0; c < 64; c++) wt_precond__layer_blocks_apply(p, r, z, p->nb * c / 64, p->nb * (c + 1) / 64);
        } else {
            /* no coarse block: J⁻¹ r split over the threads */
            for (int64_t i = n * id / nt; i < n * (id + 1) / nt; i++) z[i] = p->jinv[i] * r[i];
        }
        /* the dots' chunks split over the threads (the chunk sums land in fixed slots and are added in a fixed
         * order: the same bits as on one thread) */
        wt_vec_dot_many_part(p->lr_Y, n, q, r, n, p->lr_runs, p->lr_nruns, WT_VEC_CHUNKS * id / nt,
                             WT_VEC_CHUNKS * (id + 1) / nt, p->lr_part);
#pragma omp barrier
#pragma omp single
        {
            wt_vec_dot_many_finish(q, p->lr_part, p->lr_w);
            wt_precond__lowrank_solve(p, p->lr_w);
        } /* (its implicit barrier: w is ready for every thread, and every B⁻¹ r written) */
        wt_vec_sub_many_range(z, p->lr_Y, n, q, p->lr_w, p->lr_runs, p->lr_nruns, n * id / nt, n * (id + 1) / nt);
    }
}

/* Y = B⁻¹ R (B the kind's part before the NGS term, as it stands), K = Ĉ⁻¹_NGS + Rᵀ Y by Cholesky, and Y laid out
 * as the apply reads it: coarse_ngs and fourier by blocks of 8 rows, the blocks with a non-zero (in float when
 * single); the others column-major, with its zero runs. At set-up and at each update (p->nlr set). */
/* Rᵀ_j Y_k as wt_vec_dot(R_j, Y_k, n) sums it, from R_j's non-zeros on the layers (fourier's fd_rs): each of
 * WT_VEC_CHUNKS chunk sums is one chain in index order from 0, and a zero product leaves a chain's value as it is
 * (x + ±0 = x, +0 + −0 = +0), so the chains of the non-zeros alone are the same bits; then the ordered total. */
static double sparse_dot(const wt_precond *p, int j, const double *Yk)
{
    const wt_tomography *t = p->tomo;
    const int L = wt_tomography_nlayers(t), q = p->nlr;
    const int64_t len = wt_vec_chunk_len(p->n);
    double part[WT_VEC_CHUNKS] = {0.0};
    for (int l = 0; l < L; l++) {
        const int64_t o = wt_tomography_layer_offset(t, l);
        for (int64_t e = p->fd_rs_ptr[l * q + j]; e < p->fd_rs_ptr[l * q + j + 1]; e++) {
            const int64_t i = o + p->fd_rs_idx[e];
            part[i / len] += p->fd_rs_val[e] * Yk[i];
        }
    }
    return wt_vec_dot_finish(part);
}

int wt_precond__lowrank_factor(wt_precond *p, const double *R, const double *cinv)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const int64_t n = p->n;
    const int q = p->nlr, single = p->single;
    const int blocked = p->kind == WT_PRECOND_COARSE_NGS || p->fd_n > 0;
    double *Y = NULL;
    char *nz = NULL;
    WT_ALLOC(ctx, p->lr_K, (size_t)q * q, "NGS preconditioner K");
    if (!blocked) WT_ALLOC(ctx, p->lr_runs, n + 1, "NGS preconditioner runs");
    if (p->fd_rhat) { /* fourier's update: Y in the room kept for it (every entry written by the inverse FFTs) */
        Y = wt_align64(p->pu_Y_raw);
        WT_TRY(wt_precond__fourier_lowrank_Y(p, Y));
    } else {
        WT_ALLOC(ctx, p->lr_Y, (size_t)n * q, "NGS preconditioner Y");
        Y = p->lr_Y;
        for (int k = 0; k < q; k++) wt_precond__base_apply(p, R + (size_t)n * k, Y + (size_t)n * k);
    }
    if (!blocked) p->lr_nruns = wt_vec_runs(Y, n, q, n, p->lr_runs);
    for (int k = 0; k < q; k++)
        for (int j = 0; j <= k; j++) {
            const double d = p->fd_rs_ptr ? sparse_dot(p, j, Y + (size_t)k * n) : wt_vec_dot(R + (size_t)j * n, Y + (size_t)k * n, n);
            p->lr_K[j + (size_t)q * k] = p->lr_K[k + (size_t)q * j] = cinv[j + (size_t)q * k] + d;
        }
    /* in-place Cholesky, lower triangle (K is SPD: Ĉ⁻¹_NGS SPD, RᵀB⁻¹R semi-definite) */
    WT_TRY(wt_precond__cholesky(ctx, q, p->lr_K, "NGS preconditioner"));
    if (blocked) { /* Y by blocks of 8 rows, the blocks with a non-zero; each block's rows on one thread */
        const int64_t nb8 = (n + 7) / 8;
        WT_ALLOC(ctx, p->lr_blk, nb8, "NGS preconditioner blocks");
        WT_ALLOC(ctx, nz, nb8, "NGS preconditioner block flags");
#pragma omp parallel for schedule(static) num_threads(p->nthreads)
        for (int64_t b = 0; b < nb8; b++) {
            int z = 0;
            for (int64_t i = 8 * b; i < 8 * b + 8 && i < n && !z; i++)
                for (int k = 0; k < q && !z; k++) z = Y[(size_t)k * n + i] != 0.0;
            nz[b] = (char)z;
        }
        p->lr_nblk = 0;
        for (int64_t b = 0; b < nb8; b++)
            if (nz[b]) p->lr_blk[p->lr_nblk++] = b;
        /* (every entry written below: malloc, not calloc; 64-byte aligned: 16 floats or 8 doubles of slack; an
         * update takes the blocks the last one replaced when they are large enough) */
        const size_t bytes = ((size_t)p->lr_nblk * q * 8 + 16) * (single ? sizeof(float) : sizeof(double));
        void *mem = NULL;
        if (p->pu_spare && p->pu_spare_bytes >= bytes) {
            mem = p->pu_spare, p->lr_Yb_bytes = p->pu_spare_bytes;
            p->pu_spare = NULL, p->pu_spare_bytes = 0;
        } else if ((mem = wt_malloc(ctx, bytes, 1))) p->lr_Yb_bytes = bytes;
        if (!mem) {
            st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory allocating NGS preconditioner Y (blocks) (%zu bytes)", bytes);
            goto fail;
        }
        if (single) p->lr_Yb32_raw = mem;
        else p->lr_Yb_raw = mem;
        if (single) p->lr_Yb32 = p->lr_Yb32_raw + ((64 - (uintptr_t)p->lr_Yb32_raw % 64) % 64) / sizeof(float);
        else p->lr_Yb = wt_align64(p->lr_Yb_raw);
#pragma omp parallel for schedule(static) num_threads(p->nthreads)
        for (int64_t b = 0; b < p->lr_nblk; b++)
            for (int k = 0; k < q; k++)
                for (int a = 0; a < 8; a++) {
                    const size_t at = ((size_t)b * q + k) * 8 + a;
                    const int64_t i = 8 * p->lr_blk[b] + a;
                    const double v = i < n ? Y[(size_t)k * n + i] : 0.0; /* (rows past n: 0) */
                    if (single) p->lr_Yb32[at] = (float)v;
                    else p->lr_Yb[at] = v;
                }
        wt_free(ctx, p->lr_Y); /* the applies read the blocks only */
        p->lr_Y = NULL;
    }
fail:
    wt_free(ctx, nz);
    return st;
}

int wt_precond__lowrank(wt_precond *p, wt_tomography *t)
{
    int st = WT_OK;
    wt_context *ctx = p->ctx;
    const wt_system *sys = wt_tomography_system(t);
    const int64_t n = p->n, ns = sys->nslopes;
    double *e = NULL, *we = NULL, *cinv = NULL;
    int q = 0, first = -1;
    for (int m = 0; m < sys->nsensors; m++)
        if (sys->sensors[m].kind == WT_SENSOR_NGS) {
            if (first < 0) first = m;
            q += sys->sensors[m].nslopes;
        }
    if (q == 0 || q > 64) return WT_OK; /* no NGS (or an unusual many-slope NGS set: B alone) */
    const int64_t o0 = sys->sensors[first].offset; /* NGS slopes are the last, contiguous */
    double *R = NULL;
    WT_ALLOC(ctx, R, (size_t)n * q, "NGS preconditioner R");
    WT_ALLOC(ctx, p->lr_w, q, "NGS preconditioner work");
    WT_ALLOC(ctx, p->lr_part, (size_t)q * WT_VEC_CHUNKS, "NGS preconditioner work");
    WT_ALLOC(ctx, e, ns, "unit slope vector");
    WT_ALLOC(ctx, we, ns, "weighted unit slope vector");
    WT_ALLOC(ctx, cinv, (size_t)q * q, "NGS noise weight");
    for (int k = 0; k < q; k++) {
        e[o0 + k] = 1.0;
        wt_tomography_rhs(t, 1.0, e, R + (size_t)k * n); /* R was allocated zeroed: column k = Ãᵀ Ĉ⁻¹ e_k */
        /* column k of Ĉ⁻¹_NGS: the noise weight of each NGS sensor applied to e_k */
        memset(we, 0, (size_t)ns * sizeof *we);
        for (int m = first; m < sys->nsensors; m++) {
            const wt_sensor *s = &sys->sensors[m];
            wt_noise_apply_weight(wt_tomography_noise(t, m), 1.0, e + s->offset, we + s->offset);
        }
        for (int j = 0; j < q; j++) cinv[j + (size_t)q * k] = we[o0 + j];
        e[o0 + k] = 0.0;
    }
    p->nlr = q;
    WT_TRY(wt_precond__lowrank_factor(p, R, cinv));
    if (p->fd_n > 0) WT_TRY(wt_precond__fourier_ngs_columns(p, t, R));
    if (p->parts) { /* (the NGS's weights do not depend on the model: R and Ĉ⁻¹_NGS stay) */
        p->lr_R = R;
        p->lr_cinv = cinv;
        R = cinv = NULL;
    }
fail:
    wt_free(ctx, R);
    wt_free(ctx, e);
    wt_free(ctx, we);
    wt_free(ctx, cinv);
    return st;
}
