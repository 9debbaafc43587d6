/* core/model/precond_base.h: the preconditioner object's layout and what every kind is built from
 * (precond_base.c): the bottom of the preconditioner's files. Each kind declares its entry points in a header of
 * its own, and a file includes the headers of what it calls, so the includes follow the calls, one way:
 *
 *   precond.c (the interface, the dispatch)      → every kind's header
 *   precond_update.c (a new atmosphere model)    → precond_lowrank.h
 *   precond_lowrank.c (the NGS term)             → precond_coarse.h, precond_fourier.h, precond_multilevel.h
 *   precond_coarse.c (the coarse block, B⁻¹)     → precond_fourier.h, precond_multilevel.h
 *   precond_fourier.c, precond_multilevel.c, precond_jacobi.c                   → precond_base.h only
 *
 * Not part of any interface. */
#ifndef WT_PRECOND_BASE_H
#define WT_PRECOND_BASE_H

#include "precond.h"

#include <complex.h> /* before fftw3.h: fftw_complex is then double complex */
#include <fftw3.h>
#include <stdint.h>

#define WT_FOURIER_MAX_SC 64 /* the fourier kind's coarse square, side per layer at most */
/* The coarse block's coefficients at most (coarse_ngs, multilevel, fourier): its dense factor is q² doubles (128 MB)
 * and its set-up q applies of M̃ plus q³/3 flops */
#define WT_PRECOND_COARSE_MAX 4096

struct wt_precond {
    wt_context *ctx;
    const wt_tomography *tomo; /* the fourier kind's wavelets and layer offsets */
    int kind;
    int64_t n;                /* unknowns */
    int nthreads;             /* the tomography's (small systems run serially) */
    double *jinv;             /* n: J⁻¹ (NULL for none) */
    /* NGS low-rank part (see lowrank_*): P = B + R C_n Rᵀ */
    int nlr;                  /* rank r: the NGS slopes (0: none) */
    double *lr_Y;             /* n x r: B⁻¹ R (coarse_ngs: freed once lr_Yb holds it) */
    double *lr_K;             /* r x r: Cholesky factor of Ĉ⁻¹_NGS + Rᵀ B⁻¹ R */
    double *lr_w;             /* r */
    double *lr_part;          /* r x WT_VEC_CHUNKS: the chunk sums of Yᵀ r */
    int64_t *lr_runs;         /* the row runs where Y is not all zero (wt_vec_runs) */
    int lr_nruns;
    /* coarse_ngs: Y by blocks of 8 rows, only the blocks with a non-zero (see lowrank_blocks) */
    int64_t lr_nblk;          /* kept blocks */
    int64_t *lr_blk;          /* lr_nblk: block b's first row is 8 lr_blk[b] */
    double *lr_Yb, *lr_Yb_raw; /* lr_nblk x r x 8 (block, column, row in the block), 64-byte aligned */
    float *lr_Yb32, *lr_Yb32_raw; /* single (wt_precond_params): the same in float, lr_Yb NULL */
    /* coarse block (coarse_ngs, see coarse_*): J replaced by B = J with the coarse coefficients' rows and
     * columns of the LGS + prior part of M, inverted exactly */
    int nc;                   /* coarse coefficients (0: none) */
    int64_t *c_idx;           /* nc: their indices in c */
    double *c_L;              /* nc x nc: Cholesky factor (lower, column-major) of that block, Lᵀ above */
    double *c_w;              /* nc */
    double *c_inv;            /* coarse_ngs: nc x nc, the block's inverse (L Lᵀ)⁻¹, symmetric, column-major */
    float *c_inv32;           /* single: the same in float, c_inv NULL */
    int64_t *c_free;          /* the runs [c_free[2j], c_free[2j+1]) of unknowns outside the coarse block */
    int c_nfree;
    /* layer blocks below the coarse square (multilevel, see compute_layer_blocks) */
    int64_t nb;               /* blocks (0: none) */
    int64_t *b_start;         /* nb + 1: block b's unknowns are b_idx[b_start[b] .. b_start[b + 1]) */
    int64_t *b_fac;           /* nb + 1: its factor starts at b_L[b_fac[b]] */
    int64_t *b_idx;           /* the unknowns of the blocks, block after block, layer order within one */
    double *b_L;              /* packed Cholesky factors, rows of L, each row's last entry 1 / L_aa */
    /* fourier (see fourier_*): the filter 1/(n² λ_max A(k)) on the half spectrum of every layer */
    int fd_n;                 /* layer side (0: not this kind) */
    int64_t fd_nk;            /* frequencies of the half spectrum, n (n/2 + 1) */
    double *fd_s;             /* fd_nk: the filter */
    double *fd_raw;           /* the allocation fd_buf lies in (fd_buf at its first 64-byte boundary) */
    double *fd_buf;           /* per thread: n² layer values, fd_nk complex values, WT_FOURIER_MAX_SC n of
                                 contraction work; 64-byte slices */
    size_t fd_slice;          /* doubles per thread in fd_buf */
    int fd_sc;                /* side of each layer's coarse square (coarse_basis; 0: no coarse block) */
    double *fd_B;             /* fd_sc x n: the 1-D basis of the coarse space, row i = φ_i */
    double *fd_cr, *fd_cphi;  /* nc: Qᵀ r and Qᵀ φ of the apply, layer after layer (sc² each, i + sc j) */
    /* fourier with the NGS term: Yᵀ r as Rᵀ u on the filtered layers (see fourier_ngs_dots) */
    int64_t *fd_rs_ptr;       /* L r + 1: the entries of column k on layer l are [ptr[l r + k], ptr[l r + k + 1]) */
    int32_t *fd_rs_idx;       /* their points in the layer */
    double *fd_rs_val;        /* the values of W⁻¹ R there */
    double *fd_rc;            /* nc x r: R's rows at the coarse coefficients */
    double *fd_dots;          /* L x r: the layers' R_sᵀ φ_l */
    fftw_plan fd_r2c, fd_c2r;
    int single;               /* coarse_ngs: its stored matrices in float (wt_precond_params.single) */
    /* the parts of an update (wt_precond_params.updatable; precond_update.c): M̃ = Σ_LGS (its part) + the prior's
     * part, each LGS's measured with its noise weights at set-up, the prior's with the layers' Cn² then */
    int parts;                /* 1: kept */
    int nlgs;
    double part_prec[2 * WT_MAX_GS]; /* per LGS: its short-axis precision then (wt_tomography_lgs_precision) */
    double part_cn2[WT_MAX_LAYERS];  /* per layer: its prior's Cn², f r0^(−5/3), then */
    double *pj;               /* nlgs x n: each LGS's part of J's diagonal (jacobi, jacobi_ngs, coarse_ngs) */
    double *pc;               /* (nlgs + 1) x nc²: each LGS's part of the coarse block, then the prior's */
    double complex *pa;       /* fourier: nlgs x nk x L(L+1)/2, each LGS's symbol (lower triangle, by columns) */
    double complex *pp;       /* fourier: nk x L, the prior's symbol per layer (no layer couples another there) */
    double *lr_R, *lr_cinv;   /* the NGS term's R (n x nlr) and Ĉ⁻¹_NGS (nlr x nlr) */
    double *part_sl;          /* 2 nslopes: the parts' probe slopes, all sensors' and one LGS's */
    double complex *fd_rhat;  /* fourier with the NGS term: nlr x L x nk, the spectra F Π_d R of R's columns per
                                 layer as the apply's forward FFT gives them (the update's Y = B⁻¹ R filters them:
                                 no forward FFT, the same bits) */
    double *pu_Y_raw;         /* fourier's update: room for Y = B⁻¹ R (n x nlr, 64-byte aligned), kept from set-up */
    size_t lr_Yb_bytes;       /* the allocation lr_Yb_raw or lr_Yb32_raw holds */
    void *pu_spare;           /* the Y blocks an update replaced, for the next one (an update writes 14 MB at E-ELT
                                 size: memory kept, not returned and faulted in again) */
    size_t pu_spare_bytes;
};

/* The kinds' names, by WT_PRECOND_* */
extern const char *const wt_precond__kind_names[WT_PRECOND_NKINDS];

/* In-place Cholesky of the q x q SPD matrix A (column-major; lower triangle used and overwritten); WT_ERR_NUMERIC
 * naming `what` when it is not positive definite */
int wt_precond__cholesky(wt_context *ctx, int q, double *A, const char *what);
/* The coarse block p->c_L (q x q, both triangles as computed) symmetrised, factored (wt_precond__cholesky, `what`
 * naming it) and Lᵀ copied into its upper triangle, so that the backward solve runs by contiguous columns too;
 * p->nc = q */
int wt_precond__coarse_factor(wt_precond *p, int q, const char *what);
/* Centre (in grid points) of the support of a periodic 1-D profile; the colouring's period and the per-thread buffer
 * sizes of the coloured probing (precond_jacobi.c, precond_multilevel.c) */
double wt_precond__support_centre(const double *mag, int n);
void wt_precond__probe_sizes(const wt_tomography *t, int *s, int64_t *maxn2, int64_t *maxsl, int64_t *wsize);
/* The parts, measured at set-up when wt_precond_params.updatable (precond_update.c updates from them): */
int wt_precond__parts_begin(wt_precond *p, const wt_tomography *t);
/* layer l's prior Cn² now, f r0^(−5/3) (its prior's precision scales as its inverse) */
double wt_precond__layer_cn2(const wt_tomography *t, int l);
/* into cols ((nlgs + 1) x n): the column of each LGS's part of M̃ for the probe e that is non-zero on layer l only,
 * Ãᵀ_m C̃_m⁻¹ Ã_m e (m < nlgs), then the prior's (layer l's) */
void wt_precond__part_columns(const wt_precond *p, wt_tomography *t, int l, const double *e, double *cols);

/* The NGS term's Y by blocks of 8 rows (precond_lowrank.c: the layout) */
typedef double yb_vec __attribute__((vector_size(64), aligned(8))); /* 8 rows (GCC/clang vectors: plain
                                                                     per-lane IEEE operations, any ISA) */
typedef float yb_vec32 __attribute__((vector_size(32), aligned(4))); /* 8 rows of the float copy (single) */

/* Column k of block b: 8 rows of Y, from the float copy (f32, converted: exact) or the double one (a macro: a
 * function returning the 64-byte vector by value would change the ABI off AVX-512) */
#define YB_COL(p, B, b, k, f32)                                                                                    \
    ((f32) ? __builtin_convertvector(((const yb_vec32 *)((p)->lr_Yb32 + (size_t)(b) * (B) * 8))[k], yb_vec)      \
           : ((const yb_vec *)((p)->lr_Yb + (size_t)(b) * (B) * 8))[k])

/* w ← (L Lᵀ)⁻¹ w in place, L (q x q) lower with Lᵀ above the diagonal; inlined into callers cloned for AVX2/AVX-512
 * like the transforms (WT_CPU_CLONES: both solves' column updates vectorise) */
static inline __attribute__((always_inline)) void wt_precond__chol_solves(const double *L, int q, double *w)
{
    for (int i = 0; i < q; i++) { /* forward: L y = w (column-oriented) */
        const double v = (w[i] /= L[i + (size_t)q * i]);
        const double *col = L + (size_t)q * i;
        for (int k = i + 1; k < q; k++) w[k] -= col[k] * v;
    }
    for (int i = q - 1; i >= 0; i--) { /* backward: Lᵀ x = y (column-oriented on Lᵀ, held above the diagonal) */
        const double v = (w[i] /= L[i + (size_t)q * i]);
        const double *col = L + (size_t)q * i;
        for (int k = 0; k < i; k++) w[k] -= col[k] * v;
    }
}

/* col = M̃ e for a probe e on layer l only: the LGS and prior part (sl: nslopes of work) */
void wt_precond__lgs_prior_column(wt_tomography *t, int l, const double *e, double *sl, double *col);
/* K v = w in place (the NGS term's factor); z −= Y w on Y's row blocks [b0, b1) */
void wt_precond__lowrank_solve(const wt_precond *p, double *w);
void wt_precond__yb_update(const wt_precond *p, const double *w, double *z, int64_t b0, int64_t b1);

#endif
