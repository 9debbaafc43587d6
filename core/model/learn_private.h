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
};

/* The N × N real correlation (unnormalised, FFT order) of spectrum sp (nf complex) into out (N*N): copies sp
 * into the work spectrum, runs the c2r plan and scales by 1/N². Not thread-safe on one object. */
void wt_learn__inverse(const wt_learn *L, const double *sp, double *out);
/* r2c of an N*N real array (FFT order) into sp (nf complex), through the object's plan and work grid. */
void wt_learn__forward(const wt_learn *L, const double *in, double *sp);

#endif
