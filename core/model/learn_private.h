/* core/model/learn_private.h: the accumulator's layout, shared by learn.c (data), learn_response.c (model) and
 * learn_fit.c (fit); not part of any interface. */
#ifndef WT_LEARN_PRIVATE_H
#define WT_LEARN_PRIVATE_H

#include "learn.h"

struct fftw_plan_s;

struct wt_learn {
    wt_context *ctx;
    int n;                   /* subapertures per side */
    double d;                /* [m] */
    uint8_t *valid;          /* n*n */
    int nsub;                /* valid subapertures */
    int *sub;                /* [nsub] mask index of each valid subaperture, in slope order */
    int nlgs, npairs;
    double *theta_x, *theta_y; /* [nlgs] [rad] */
    double H;                /* [m] */
    int N;                   /* FFT side 2n */
    int nf;                  /* N (N/2 + 1) complex values of a spectrum */
    int nbatch;
    int64_t batch_frames;
    int64_t frames;
    int64_t *bframes;        /* [nbatch] frames per batch */
    double *spec;            /* [nbatch][npairs][3][nf][2] summed cross-spectra */
    double *pairs;           /* [N*N] P(δ) at FFT index (δx mod N) + N (δy mod N), rounded to integers */
    double *grid;            /* [N*N + 8] FFT input (aligned copy at grid_a) */
    double *grid_a;
    double *four;            /* [2 nlgs][nf][2] this frame's spectra of x and y slopes, LGS by LGS, + 8 doubles */
    double *four_a;
    struct fftw_plan_s *r2c, *c2r; /* grid_a -> four_a slot; c2r of a work spectrum (made with the work arrays) */
    double *cwork, *cwork_a; /* [nf][2] + 8: a spectrum for c2r */
    int nlag, kmax;          /* lags (0: none), the largest [frames] */
    int lag[WT_LEARN_MAX_LAG]; /* [frames], increasing */
    double *ring;            /* [kmax + 1][2 nlgs][nf][2] the last frames' spectra, frame t at slot t mod (kmax + 1) */
    double *lspec;           /* [nbatch][nlag][nlgs (i)][nlgs (j)][2 (x x, y y)][nf][2] lagged cross-spectra */
    int64_t *lframes;        /* [nbatch][nlag] frame pairs accumulated */
    wt_learn_progress_fn progress; /* NULL: none */
    void *progress_user;
};

/* The response maps of one (altitude grid, L0) restricted to the offsets the fit uses, and their Gram matrix
 * (learn_fit.c): what every fit of the same geometry shares. */
struct wt_learn_model {
    wt_context *ctx;
    int n, nsub, nlgs;       /* the geometry it was built for (the fit checks it) */
    double d, H;
    double theta_x[64], theta_y[64];
    uint8_t *valid;          /* [n*n] */
    int nalt;
    double alt[WT_LEARN_MAX_ALT]; /* [m] */
    double L0;               /* [m] */
    int nu;                  /* used offsets: P(δ) ≥ WT_LEARN_MIN_PAIRS P(0) */
    int *uoff;               /* [nu] their FFT index (δx mod N) + N (δy mod N) */
    double *uw;              /* [nu] weight P(δ)/P(0) */
    int u0;                  /* the index of δ = 0 in the list */
    int nslot;               /* distinct response maps: every auto pair shares slot 0 */
    int *slot;               /* [npairs] */
    double *R;               /* [nslot][3][nu][nalt] [rad²] for r0 = 1 m */
    double *G;               /* [nalt²] Σ w R_a R_b over the fit's terms (column-major) */
    int64_t rows;            /* the fit's terms */
};

/* Work space of the response maps (learn_response.c): the structure-function table of one L0 and the arrays of
 * one evaluation. One per thread: wt_learn__resp_eval only reads the object. */
#define WT_LEARN_MAX_THREADS 64
typedef struct wt_learn__rws {
    double step;             /* table step [m] */
    int ntab;
    double *tab;             /* [ntab] D(ρ)/ρ^(5/3) for r0 = 1 m [rad² m^(−5/3)] */
    double *buf;             /* all the arrays below */
    double *C, *Cx, *Cy, *g, *k2; /* [N*N] (64-byte aligned) */
    double *Mh, *sp, *tmp;   /* [nf][2] (aligned) */
    double *Df;              /* [3][9][(2n+1)²] D on the shifted lattices, then ∂D/∂s_x, ∂D/∂s_y */
} wt_learn__rws;

/* The largest separation [m] the table must cover: beams θ apart [rad] up to hmax [m], shifts up to smax [m]. */
double wt_learn__rmax(const wt_learn *L, double theta, double hmax, double smax);
int wt_learn__rws_alloc(const wt_learn *L, double L0, double rmax, wt_learn__rws **out);
void wt_learn__rws_free(const wt_learn *L, wt_learn__rws *w);
/* r[(2n−1)²] = the response map of slope ca of sensor i against slope cb of sensor j (0 x, 1 y), θ_j − θ_i =
 * (tx, ty) [rad], for a unit layer at h [m] shifted by s = (sx, sy) [m] between the two samples (the lagged maps:
 * s = v τ), laid out as wt_learn_map's. Allocates nothing; thread-safe on distinct work spaces. */
void wt_learn__resp_eval(const wt_learn *L, wt_learn__rws *w, double tx, double ty, double h, double sx, double sy,
                         int ca, int cb, double *r);
/* The same and (rx non-NULL) its derivatives ∂r/∂s_x, ∂r/∂s_y [rad²/m], exact for the tabulated D's interpolant */
void wt_learn__resp_eval_grad(const wt_learn *L, wt_learn__rws *w, double tx, double ty, double h, double sx,
                              double sy, int ca, int cb, double *r, double *rx, double *ry);

/* Solve A z = b for the k × k symmetric positive (semi-)definite A (column-major, leading dimension lda) by Cholesky
 * on a copy w (k²); a pivot that is not positive is lifted to 1e-12 of the largest diagonal (learn_fit.c). */
void wt_learn__spd_solve(int k, const double *A, int lda, const double *b, double *z, double *w);

/* The N × N real correlation (unnormalised, FFT order) of spectrum sp (nf complex) into out (N*N): copies sp
 * into the work spectrum, runs the c2r plan and scales by 1/N². Not thread-safe on one object. */
void wt_learn__inverse(const wt_learn *L, const double *sp, double *out);
/* r2c of an N*N real array (FFT order) into sp (nf complex), through the object's plan and work grid. */
void wt_learn__forward(const wt_learn *L, const double *in, double *sp);

#endif
