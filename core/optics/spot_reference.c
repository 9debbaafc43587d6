/* core/optics/spot_reference.c: the noise-free reference I0 and its derivatives (spot.h), with or without the mean
 * seeing, and the rebinned cells that a reference of another sodium profile can reuse (wt_spot_keep_reference). */
#include "seeing.h"
#include "spot_private.h"

int wt_spot_keep_reference(wt_spot *s)
{
    if (s->rcells) return WT_OK;
    const size_t n = (size_t)s->nsub * 5 * s->M * s->M;
    s->rcells = wt_malloc(s->ctx, n ? n : 1, sizeof *s->rcells);
    if (!s->rcells)
        return WT_ERROR(s->ctx, WT_ERR_NOMEM, "spot: out of memory for the reference's kept cells (%zu floats)", n);
    s->rc_valid = 0;
    return WT_OK;
}

int wt_spot_reference(wt_spot *s, double dtheta, const wt_spot_seeing *see, float *i0, float *didx, float *didy)
{
    if (!(dtheta > 0)) dtheta = s->par.wavelength / (20.0 * s->par.subap_side);
    /* kept cells of the same dtheta and seeing: the five images are their direct sums (the current tables) */
    const int reuse = s->rcells && s->rc_valid && s->rc_dtheta == dtheta && s->rc_see == (see != NULL) &&
                      (!see || (s->rc_seeing.r0 == see->r0 && s->rc_seeing.L0 == see->L0 &&
                                s->rc_seeing.grid == see->grid && !memcmp(s->rc_seeing.blur, see->blur, sizeof see->blur) &&
                                s->rc_seeing.scale == see->scale && !see->only));
    const int blur = see && (see->blur[0] != 0.0 || see->blur[1] != 0.0 || see->blur[2] != 0.0);
    /* keep them now: every image is made (a NULL output to a scratch image) */
    /* the kept cells are the plain reference's (the oracle's): a model with a blur or a strength, or a subset, is not */
    const int keep = s->rcells && !reuse && !(see && (see->only || see->scale > 0.0 || see->blur[0] != 0.0 ||
                                                      see->blur[1] != 0.0 || see->blur[2] != 0.0));
    const size_t M2 = (size_t)s->M * s->M;
    const int nth = s->nthreads, np = s->np, Ns = s->Ns, N = s->N;
    const size_t ns2 = (size_t)Ns * Ns, n2 = (size_t)np * np, N2 = (size_t)N * N;
    int st = WT_OK;
    double *Dl = NULL, *work = NULL;
    float *W = NULL, *W1 = NULL, *ones = NULL, *Gb = NULL;
    const size_t wk = wt_seeing_work_size(np);
    if (see && !reuse) {
        /* one lag table for the sensor, W of a fully lit subaperture shared, W of the others per thread */
        WT_ALLOC(s->ctx, Dl, n2, "seeing lag table");
        WT_ALLOC(s->ctx, work, wk * nth, "seeing workspace");
        WT_ALLOC(s->ctx, W, N2 * (nth + 1), "seeing OTFs");
        /* the lag table of the last (r0, L0, grid) kept: a fit of the seeing's strength scales it (D ∝ r0^(−5/3)) */
        if (!s->dl || s->dl_key[0] != see->r0 || s->dl_key[1] != see->L0 || s->dl_key[2] != see->grid) {
            if (!s->dl) WT_ALLOC(s->ctx, s->dl, n2, "seeing lag table");
            s->dl_key[0] = NAN;
            WT_TRY(wt_seeing_lag_table(s->ctx, np, s->par.subap_side / np, s->par.wavelength, see->r0, see->L0, see->grid,
                                       s->dl));
            s->dl_key[0] = see->r0, s->dl_key[1] = see->L0, s->dl_key[2] = see->grid;
        }
        const double scale = see->scale > 0.0 ? see->scale : 1.0;
        for (size_t q = 0; q < n2; q++) Dl[q] = scale * s->dl[q];
        W1 = W + N2 * nth;
        WT_ALLOC(s->ctx, ones, n2, "seeing amplitudes");
        for (size_t q = 0; q < n2; q++) ones[q] = 1.0f;
        wt_seeing_otf(np, LOOP_GTILT, Dl, ones, N, W1, work);
        if (blur) { /* the Gaussian's OTF exp(−2π² νᵀΣν), ν = lag·dx/λ, the lags in FFT order; W1 with it */
            WT_ALLOC(s->ctx, Gb, N2, "blur OTF");
            const double c = -2.0 * M_PI * M_PI * pow(s->par.subap_side / np / s->par.wavelength, 2);
            for (int v = 0; v < N; v++)
                for (int u = 0; u < N; u++) {
                    const double a = u <= N / 2 ? u : u - N, b = v <= N / 2 ? v : v - N;
                    Gb[u + (size_t)N * v] = (float)exp(c * (see->blur[0] * a * a + 2.0 * see->blur[1] * a * b + see->blur[2] * b * b));
                }
            for (size_t q = 0; q < N2; q++) W1[q] *= Gb[q];
        }
    }
#pragma omp parallel for schedule(dynamic, 16) num_threads(nth) if (nth > 1 && s->nsub > 1 && !omp_in_parallel())
    for (int is = 0; is < s->nsub; is++) {
        if (see && see->only && !see->only[is]) continue;
        const int t = wt_thread_id();
        workspace *w = &s->ws[t];
        const float *otf = NULL;
        float *rc = s->rcells ? s->rcells + (size_t)is * 5 * M2 : NULL;
        if (see && !reuse) {
            const float *A = s->amp + (size_t)is * n2;
            int full = 1;
            for (size_t q = 0; q < n2 && full; q++) full = A[q] == 1.0f;
            if (full) otf = W1;
            else {
                float *Wt = W + N2 * t;
                wt_seeing_otf(np, LOOP_GTILT, Dl, A, N, Wt, work + wk * t);
                if (blur)
                    for (size_t q = 0; q < N2; q++) Wt[q] *= Gb[q];
                otf = Wt;
            }
        }
        if (i0 || keep) {
            memset(w->opd, 0, n2 * sizeof *w->opd);
            wt_spot__image_one(s, is, NULL, w->opd, otf, w, i0 ? i0 + is * ns2 : w->img2, reuse ? rc : NULL,
                               keep ? rc : NULL);
        }
        for (int ax = 0; ax < 2; ax++) {
            float *D = ax ? didy : didx;
            if (!D && !keep) continue;
            /* (I(+δ) − I(−δ)) / 2δ, a tilt δ·x (or δ·y) on the OPD: the spot moves by +δ (spot.h) */
            for (int sgn = -1; sgn <= 1; sgn += 2) {
                for (int j = 0; j < np; j++)
                    for (int i = 0; i < np; i++) w->opd[i + np * j] = sgn * dtheta * (ax ? s->xs[j] : s->xs[i]);
                float *cell = rc ? rc + M2 * (size_t)(1 + 2 * ax + (sgn > 0)) : NULL;
                wt_spot__image_one(s, is, NULL, w->opd, otf, w, sgn < 0 || !D ? w->img2 : D + is * ns2,
                                   reuse ? cell : NULL, keep ? cell : NULL);
            }
            if (!D) continue;
            float *out = D + is * ns2;
            const float inv = (float)(0.5 / dtheta);
            for (size_t p = 0; p < ns2; p++) out[p] = (out[p] - w->img2[p]) * inv;
        }
    }
    if (keep) {
        s->rc_valid = 1, s->rc_dtheta = dtheta, s->rc_see = see != NULL;
        if (see) s->rc_seeing = *see;
    }
fail:
    wt_free(s->ctx, Dl);
    wt_free(s->ctx, work);
    wt_free(s->ctx, W);
    wt_free(s->ctx, ones);
    wt_free(s->ctx, Gb);
    return st;
}

