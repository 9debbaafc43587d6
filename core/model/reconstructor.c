/* core/model/reconstructor.c: the pcg3 / cg9 / none reconstructors as one slopes → commands map. */
#include "reconstructor.h"
#include "profile.h"

#include "../la/sparse.h"
#include "../op/shift.h"
#include "../solve/mvm.h"

#include <math.h>
#include <string.h>

struct wt_reconstructor {
    wt_context *ctx;
    const wt_system *sys;
    int kind;
    int iterations;          /* tomography (P)CG iterations per frame */
    double tol;
    int fit_iterations;
    int warm;
    int cont;                /* c and a_fit are the last solves' results, untouched since: the next may continue */
    wt_tomography *tomo;
    wt_precond *pre;         /* the tomography's preconditioner */
    wt_fitting *fit;
    double *c;               /* wavelet coefficients (warm start) */
    double *phi;             /* spatial layers (the estimate, never shifted: wt_reconstructor_layers) */
    wt_shift *shift;         /* recon.predict: the layers moved by their wind over the delay (else NULL) */
    double *pred;            /* recon.predict: the shifted copy of phi that the commands are made from */
    int layer_wind;          /* 1: the layers' winds are lvx, lvy, set directly (wt_reconstructor_set_layer_wind) */
    double lvx[WT_MAX_LAYERS], lvy[WT_MAX_LAYERS]; /* [m/s] */
    double *a_fit;           /* fitting warm start */
    wt_sparse *cmap;         /* pcg3: Sᵀ, layer points x actuators (wt_reconstructor_command_map) */
    const wt_mvm *mvm;       /* mvm: the control matrix (not owned) */
    float *sf, *af;          /* mvm: float32 slopes and commands */
    double t_tomo, t_fit;
    wt_pcg_result last;
    wt_precond_params precond; /* to rebuild the preconditioner for a new model */
    double predict_lead;     /* [s] */
    /* recon.predict_integrator = "layers" (lgain > 0): the loop's integrator on the layers, z_{t+d} = S_1 z_{t+d-1} +
     * g S_d (phi_t - z_t), the commands fitted from z_{t+d} (reconstructor.h); the states are the layers' spectra */
    double lgain, frame_s;
    int ldelay;
    wt_shift_integrator *integ; /* its state (the layers' spectra, shift.h) */
    wt_shift *shift1;        /* the layers moved by their wind over one frame */
    int natm;                /* the current atmosphere model (SPEC §12): r0, profile, wind */
    double r0, atm_alt[WT_MAX_LAYERS], atm_frac[WT_MAX_LAYERS], atm_vx[WT_MAX_LAYERS], atm_vy[WT_MAX_LAYERS];
    double t_model, t_precond; /* the last wt_reconstructor_set_model's parts [s] */
};

int wt_predict_shift_alloc(wt_context *ctx, const wt_tomography *t, int natm, const double *alt, const double *frac,
                           const double *vx, const double *vy, double lead, wt_shift **out)
{
    const int L = wt_tomography_nlayers(t);
    double lalt[WT_MAX_LAYERS], lfrac[WT_MAX_LAYERS], sx[WT_MAX_LAYERS], sy[WT_MAX_LAYERS];
    const wt_grid *g[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++)
        lalt[l] = wt_tomography_layer_altitude(t, l), g[l] = wt_tomography_layer_grid(t, l),
        off[l] = wt_tomography_layer_offset(t, l);
    wt_profile_compress(natm, alt, frac, vx, vy, L, lalt, lfrac, sx, sy);
    for (int l = 0; l < L; l++) sx[l] *= lead, sy[l] *= lead;
    return wt_shift_alloc(ctx, L, g, off, sx, sy, out);
}

/* The shift of each layer by its wind (the model's compressed as its Cn², SPEC §12, or the layers' own) over `lead`
 * seconds */
static int make_shift_lead(wt_reconstructor *r, double lead, wt_shift **out)
{
    if (!r->layer_wind)
        return wt_predict_shift_alloc(r->ctx, r->tomo, r->natm, r->atm_alt, r->atm_frac, r->atm_vx, r->atm_vy, lead, out);
    const int L = wt_tomography_nlayers(r->tomo);
    double sx[WT_MAX_LAYERS], sy[WT_MAX_LAYERS];
    const wt_grid *g[WT_MAX_LAYERS];
    int64_t off[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++)
        g[l] = wt_tomography_layer_grid(r->tomo, l), off[l] = wt_tomography_layer_offset(r->tomo, l),
        sx[l] = r->lvx[l] * lead, sy[l] = r->lvy[l] * lead;
    return wt_shift_alloc(r->ctx, L, g, off, sx, sy, out);
}

/* The prediction's shifts for the current wind: over the lead, and over one frame for the layers' integrator. Both
 * or neither (on failure *sh and *sh1 are NULL). */
static int make_shifts(wt_reconstructor *r, wt_shift **sh, wt_shift **sh1)
{
    *sh = *sh1 = NULL;
    int st = make_shift_lead(r, r->predict_lead, sh);
    if (st >= 0 && r->lgain > 0.0) st = make_shift_lead(r, r->frame_s, sh1);
    if (st < 0) {
        wt_shift_free(*sh);
        *sh = NULL;
    }
    return st;
}

/* Layer l's value at (x, y) as bilinear weights on its grid points, times `weight`, into column col of
 * the triplet list (an actuator on a grid point gives one entry). WT_ERR_CONFIG when (x, y) is off the grid. */
static int add_bilinear(wt_context *ctx, wt_triplet *tr, const wt_tomography *t, int l, double x, double y, double weight,
                        int64_t col, int dm)
{
    const wt_grid *lg = wt_tomography_layer_grid(t, l);
    const int64_t off = wt_tomography_layer_offset(t, l);
    double g[2] = {(x - lg->x0) / lg->dx, (y - lg->y0) / lg->dx}, f[2];
    int64_t i[2];
    for (int d = 0; d < 2; d++) {
        double r = round(g[d]);
        if (fabs(g[d] - r) <= 1e-6) g[d] = r; /* on a grid line: no neighbour needed */
        i[d] = (int64_t)floor(g[d]);
        f[d] = g[d] - (double)i[d];
        int64_t nmax = d == 0 ? lg->nx : lg->ny;
        if (i[d] < 0 || i[d] + (f[d] > 0.0) >= nmax)
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "pcg3: an actuator of DM %d at (%.3f, %.3f) m falls off reconstruction layer %d's %d x %d grid "
                            "(spacing %g m); enlarge recon.pcg3.layer_size",
                            dm + 1, x, y, l + 1, lg->nx, lg->ny, lg->dx);
    }
    for (int b = 0; b < 4; b++) {
        int bx = b & 1, by = b >> 1;
        double wv = weight * (bx ? f[0] : 1.0 - f[0]) * (by ? f[1] : 1.0 - f[1]);
        if (wv == 0.0) continue;
        int st = wt_triplet_add(tr, off + i[0] + bx + (int64_t)lg->nx * (i[1] + by), col, wv);
        if (st < 0) return st;
    }
    return WT_OK;
}

int wt_reconstructor_command_map(wt_context *ctx, const wt_tomography *t, wt_sparse **out)
{
    int st = WT_OK;
    const wt_system *sys = wt_tomography_system(t);
    const wt_dm *dm = sys->dm;
    const int L = wt_tomography_nlayers(t), K = dm->ndms;
    wt_triplet *tr = NULL;
    double alt[WT_DM_MAX], reach[WT_DM_MAX] = {0};
    int order[WT_DM_MAX];
    int64_t first[WT_DM_MAX + 1];
    *out = NULL;
    /* the DMs by increasing altitude (the split needs them sorted) and each one's first command index */
    for (int k = 0; k < K; k++) order[k] = k;
    for (int i = 1; i < K; i++)
        for (int j = i; j > 0 && dm->altitude[order[j]] < dm->altitude[order[j - 1]]; j--) {
            int o = order[j];
            order[j] = order[j - 1];
            order[j - 1] = o;
        }
    for (int k = 0; k < K; k++) alt[k] = dm->altitude[order[k]];
    first[0] = 0;
    for (int k = 0; k < K; k++) first[k + 1] = first[k] + dm->nactive[k];
    WT_TRY(wt_triplet_alloc(ctx, wt_tomography_nunknowns(t), sys->nact, 4 * sys->nact, &tr));
    for (int l = 0; l < L; l++) {
        int j;
        double w;
        wt_profile_bin_altitude(K, alt, wt_tomography_layer_altitude(t, l), &j, &w);
        for (int side = 0; side < 2; side++) {
            double weight = side ? w : 1.0 - w;
            if (weight <= 0.0) continue;
            const int k = order[j + side];
            const wt_grid *dg = &dm->grid[k];
            int64_t q = first[k];
            reach[k] += weight;
            for (int iy = 0; iy < dg->ny; iy++)
                for (int ix = 0; ix < dg->nx; ix++) {
                    if (!dm->active[k][ix + (int64_t)dg->nx * iy]) continue;
                    WT_TRY(add_bilinear(ctx, tr, t, l, dg->x0 + ix * dg->dx, dg->y0 + iy * dg->dx, weight, q++, k));
                }
        }
    }
    for (int k = 0; k < K; k++)
        if (reach[k] <= 0.0) {
            st = WT_ERROR(ctx, WT_ERR_CONFIG,
                          "pcg3: DM %d (altitude %g m) receives no reconstruction layer (each layer goes to the DM at its "
                          "altitude, or is split linearly between the two DMs around it); put a layer of "
                          "recon.pcg3.layer_altitudes_m between DM %d and its neighbours",
                          k + 1, dm->altitude[k], k + 1);
            goto fail;
        }
    WT_TRY(wt_triplet_compress(tr, out));
fail:
    wt_triplet_free(tr);
    return st;
}

int wt_reconstructor_kind(const char *name)
{
    if (!strcmp(name, "pcg3")) return WT_RECON_PCG3;
    if (!strcmp(name, "cg9")) return WT_RECON_CG9;
    if (!strcmp(name, "none")) return WT_RECON_NONE;
    if (!strcmp(name, "mvm")) return WT_RECON_MVM;
    return -1;
}

const char *wt_reconstructor_name(int kind)
{
    switch (kind) {
    case WT_RECON_PCG3: return "pcg3";
    case WT_RECON_CG9: return "cg9";
    case WT_RECON_NONE: return "none";
    case WT_RECON_MVM: return "mvm";
    default: return "?";
    }
}

int wt_reconstructor_alloc(wt_context *ctx, const wt_system *sys, int kind, const wt_reconstructor_params *par,
                           wt_reconstructor **out)
{
    int st = WT_OK;
    wt_reconstructor *r = NULL;
    *out = NULL;
    if (kind != WT_RECON_NONE && kind != WT_RECON_PCG3 && kind != WT_RECON_CG9)
        return WT_ERROR(ctx, WT_ERR_INVALID, "unknown reconstructor kind %d", kind);
    if (kind != WT_RECON_NONE && (!par || !par->variant))
        return WT_ERROR(ctx, WT_ERR_INVALID, "reconstructor %s without its parameters", wt_reconstructor_name(kind));
    WT_ALLOC(ctx, r, 1, "reconstructor");
    r->ctx = ctx;
    r->sys = sys;
    r->kind = kind;
    r->warm = par ? par->warm_start : 0;
    if (kind == WT_RECON_NONE) {
        *out = r;
        return WT_OK;
    }
    r->iterations = par->iterations;
    r->tol = par->tolerance;
    r->fit_iterations = par->fit_iterations;
    WT_TRY(wt_tomography_alloc(ctx, sys, par->variant, wt_reconstructor_name(kind), &par->tomography, &r->tomo));
    WT_TRY(wt_precond_alloc(ctx, r->tomo, &par->precond, &r->pre));
    int64_t n = wt_tomography_nunknowns(r->tomo);
    WT_ALLOC(ctx, r->c, n, "coefficients");
    WT_ALLOC(ctx, r->phi, n, "layers");
    r->precond = par->precond;
    r->predict_lead = par->predict_lead;
    {
        const wt_tomography_params *tp = &par->tomography;
        r->natm = tp->natm;
        r->r0 = tp->r0;
        for (int k = 0; k < tp->natm; k++)
            r->atm_alt[k] = tp->atm_altitude[k], r->atm_frac[k] = tp->atm_fraction[k], r->atm_vx[k] = par->atm_vx[k],
            r->atm_vy[k] = par->atm_vy[k];
    }
    if (par->predict_lead > 0.0 && par->integrator_gain > 0.0) {
        if (!(par->integrator_gain <= 1.0 && par->integrator_delay >= 1 && par->frame_s > 0.0))
            WT_TRY(WT_ERROR(ctx, WT_ERR_INVALID, "reconstructor %s: the layers' integrator with gain %g, delay %d and frame time "
                    "%g s; expected a gain in (0, 1], a delay >= 1 frame and a positive frame time",
                    wt_reconstructor_name(kind), par->integrator_gain, par->integrator_delay, par->frame_s));
        r->lgain = par->integrator_gain, r->ldelay = par->integrator_delay, r->frame_s = par->frame_s;
        {
            const int L = wt_tomography_nlayers(r->tomo);
            const wt_grid *g[WT_MAX_LAYERS];
            int64_t off[WT_MAX_LAYERS];
            for (int l = 0; l < L; l++) g[l] = wt_tomography_layer_grid(r->tomo, l), off[l] = wt_tomography_layer_offset(r->tomo, l);
            WT_TRY(wt_shift_integrator_alloc(ctx, L, g, off, r->ldelay, &r->integ));
        }
    }
    if (par->predict_lead > 0.0) {
        WT_TRY(make_shifts(r, &r->shift, &r->shift1));
        WT_ALLOC(ctx, r->pred, n, "predicted layers");
    }
    if (kind == WT_RECON_PCG3) {
        /* the commands are the layer values at the actuators: the same map as the MVM builder's */
        WT_TRY(wt_reconstructor_command_map(ctx, r->tomo, &r->cmap));
    } else {
        WT_TRY(wt_fitting_alloc_for(ctx, r->tomo, &par->fitting, &r->fit));
        WT_ALLOC(ctx, r->a_fit, sys->nact, "fitting warm start");
    }
    *out = r;
    return WT_OK;
fail:
    wt_reconstructor_free(r);
    return st;
}

int wt_reconstructor_alloc_mvm(wt_context *ctx, const wt_system *sys, const wt_mvm *m, wt_reconstructor **out)
{
    int st = WT_OK;
    wt_reconstructor *r = NULL;
    *out = NULL;
    if (m->nact != sys->nact || m->nslopes != sys->nslopes)
        return WT_ERROR(ctx, WT_ERR_INVALID, "MVM of %lld x %lld for a system of %lld actuators and %lld slopes",
                        (long long)m->nact, (long long)m->nslopes, (long long)sys->nact, (long long)sys->nslopes);
    WT_ALLOC(ctx, r, 1, "reconstructor");
    r->ctx = ctx;
    r->sys = sys;
    r->kind = WT_RECON_MVM;
    r->mvm = m;
    WT_ALLOC(ctx, r->sf, sys->nslopes, "float32 slopes");
    WT_ALLOC(ctx, r->af, sys->nact, "float32 commands");
    *out = r;
    return WT_OK;
fail:
    wt_reconstructor_free(r);
    return st;
}

void wt_reconstructor_free(wt_reconstructor *r)
{
    if (!r) return;
    wt_free(r->ctx, r->sf);
    wt_free(r->ctx, r->af);
    wt_precond_free(r->pre);
    wt_tomography_free(r->tomo);
    wt_fitting_free(r->fit);
    wt_shift_free(r->shift);
    wt_shift_free(r->shift1);
    wt_shift_integrator_free(r->integ);
    wt_free(r->ctx, r->c);
    wt_free(r->ctx, r->phi);
    wt_free(r->ctx, r->pred);
    wt_free(r->ctx, r->a_fit);
    wt_sparse_free(r->cmap);
    wt_free(r->ctx, r);
}

void wt_reconstructor_reset(wt_reconstructor *r)
{
    if (r->c) memset(r->c, 0, (size_t)wt_tomography_nunknowns(r->tomo) * sizeof *r->c);
    r->cont = 0;
    if (r->a_fit) memset(r->a_fit, 0, (size_t)r->sys->nact * sizeof *r->a_fit);
}

int wt_reconstructor_apply(wt_reconstructor *r, const double *s_ol, double *a)
{
    const int64_t na = r->sys->nact;
    r->t_tomo = r->t_fit = 0.0;
    if (r->kind == WT_RECON_NONE) {
        memset(a, 0, (size_t)na * sizeof *a);
        return WT_OK;
    }
    if (r->kind == WT_RECON_MVM) {
        double t0 = wt_time_now();
        const int64_t ns = r->sys->nslopes;
        for (int64_t i = 0; i < ns; i++) {
            if (!isfinite(s_ol[i]))
                return WT_ERROR(r->ctx, WT_ERR_NUMERIC, "mvm: slope %lld is %g (NaN or Inf)", (long long)i, s_ol[i]);
            r->sf[i] = (float)s_ol[i];
        }
        wt_mvm_apply(r->mvm, r->sf, NULL, r->af);
        for (int64_t i = 0; i < na; i++) a[i] = r->af[i];
        r->t_tomo = wt_time_now() - t0;
        return WT_OK;
    }
    if (!r->warm) wt_reconstructor_reset(r);
    double t0 = wt_time_now();
    /* warm: the previous frame's solve is continued, its recursive residual standing in for the initial
     * apply of M (wt_tomography_solve_continue) */
    const int fit_cont = r->cont;
    const wt_pcg_precond P = wt_precond_pcg(r->pre);
    int st = r->cont ? wt_tomography_solve_continue(r->tomo, P, s_ol, r->c, r->iterations, r->tol, NULL, &r->last)
                     : wt_tomography_solve(r->tomo, P, s_ol, r->c, r->iterations, r->tol, NULL, &r->last);
    r->cont = r->warm && st >= 0;
    if (st < 0) return st;
    wt_tomography_layers(r->tomo, r->c, r->phi);
    const double *phi = r->phi;
    if (r->integ) { /* the integrator on the layers: z_{t+d} = S_1 z_{t+d-1} + g S_d (phi_t - z_t) */
        if ((st = wt_shift_integrator_step(r->integ, r->shift, r->shift1, r->lgain, r->phi, r->pred)) < 0) return st;
        phi = r->pred;
    } else if (r->shift) { /* (the estimate itself stays for wt_reconstructor_layers; the layers fill the vector) */
        wt_shift_apply_to(r->shift, r->phi, r->pred);
        phi = r->pred;
    }
    r->t_tomo = wt_time_now() - t0;
    if (r->kind == WT_RECON_PCG3) {
        memset(a, 0, (size_t)na * sizeof *a);
        wt_sparse_apply_t(r->cmap, 1.0, phi, a);
        return WT_OK;
    }
    t0 = wt_time_now();
    st = fit_cont ? wt_fitting_solve_continue(r->fit, phi, r->a_fit, r->fit_iterations, 0.0, NULL, NULL)
                  : wt_fitting_solve(r->fit, phi, r->a_fit, r->fit_iterations, 0.0, NULL, NULL);
    r->cont = r->cont && st >= 0;
    r->t_fit = wt_time_now() - t0;
    if (st < 0) return st;
    memcpy(a, r->a_fit, (size_t)na * sizeof *a);
    return WT_OK;
}

void wt_reconstructor_last_times(const wt_reconstructor *r, double *tomography, double *fitting)
{
    *tomography = r->t_tomo;
    *fitting = r->t_fit;
}

wt_pcg_result wt_reconstructor_last_pcg(const wt_reconstructor *r) { return r->last; }
double wt_reconstructor_bytes(const wt_reconstructor *r)
{
    if (r->kind == WT_RECON_MVM) /* R and RÂ: 4 bytes an element, 2 in fp16/bf16 plus the row scales */
        return (r->mvm->precision ? 2.0 : 4.0) * (double)r->mvm->nact * (double)(r->mvm->nslopes + r->mvm->nact) +
               (r->mvm->precision ? 8.0 * (double)r->mvm->nact : 0.0);
    if (r->kind == WT_RECON_NONE) return 0.0;
    const int64_t n = wt_tomography_nunknowns(r->tomo);
    double b = wt_tomography_bytes(r->tomo) + wt_precond_bytes(r->pre) + 16.0 * (double)n;
    if (r->fit) b += wt_fitting_bytes(r->fit) + 8.0 * (double)r->sys->nact;
    if (r->cmap) b += 16.0 * (double)wt_sparse_nnz(r->cmap) + 8.0 * (double)(r->cmap->ncol + 1);
    return b;
}

int wt_reconstructor_set_model(wt_reconstructor *r, double r0, int natm, const double *alt, const double *frac,
                               const double *vx, const double *vy)
{
    if (r->kind != WT_RECON_PCG3 && r->kind != WT_RECON_CG9)
        return WT_ERROR(r->ctx, WT_ERR_INVALID, "reconstructor %s: a new atmosphere model is for pcg3 and cg9 (an MVM "
                        "is rebuilt from it)", wt_reconstructor_name(r->kind));
    const double t0 = wt_time_now();
    int st = wt_tomography_set_profile(r->tomo, r0, natm, alt, frac);
    if (st < 0) return st;
    const double t1 = wt_time_now();
    wt_precond *pre = NULL;
    wt_shift *sh = NULL, *sh1 = NULL;
    const int keep_n = r->natm;
    const double keep_r0 = r->r0;
    double keep[4][WT_MAX_LAYERS];
    memcpy(keep[0], r->atm_alt, sizeof keep[0]);
    memcpy(keep[1], r->atm_frac, sizeof keep[1]);
    memcpy(keep[2], r->atm_vx, sizeof keep[2]);
    memcpy(keep[3], r->atm_vy, sizeof keep[3]);
    r->natm = natm;
    r->r0 = r0;
    for (int k = 0; k < natm; k++) {
        r->atm_alt[k] = alt[k], r->atm_frac[k] = frac[k];
        if (vx && vy) r->atm_vx[k] = vx[k], r->atm_vy[k] = vy[k];
        else if (natm != keep_n || alt[k] != keep[0][k]) r->atm_vx[k] = r->atm_vy[k] = 0.0; /* (checked below) */
    }
    if (!(vx && vy) && r->predict_lead > 0.0 && natm != keep_n)
        st = WT_ERROR(r->ctx, WT_ERR_INVALID, "reconstructor %s: a new model of %d layers (was %d) without its wind: "
                      "prediction needs the wind of every layer", wt_reconstructor_name(r->kind), natm, keep_n);
    /* the preconditioner: updated in place from its parts (wt_precond_update: no apply of M) when it kept them, else
     * rebuilt; the shift first, so that a failure of either leaves the old preconditioner untouched */
    if (st >= 0 && r->predict_lead > 0.0) st = make_shifts(r, &sh, &sh1);
    const int in_place = wt_precond_updatable(r->pre);
    if (st >= 0) st = in_place ? wt_precond_update(r->pre) : wt_precond_alloc(r->ctx, r->tomo, &r->precond, &pre);
    if (st < 0) { /* back to the old model, whole */
        wt_precond_free(pre);
        wt_shift_free(sh);
        wt_shift_free(sh1);
        r->natm = keep_n;
        r->r0 = keep_r0;
        memcpy(r->atm_alt, keep[0], sizeof keep[0]);
        memcpy(r->atm_frac, keep[1], sizeof keep[1]);
        memcpy(r->atm_vx, keep[2], sizeof keep[2]);
        memcpy(r->atm_vy, keep[3], sizeof keep[3]);
        const int st2 = wt_tomography_set_profile(r->tomo, keep_r0, keep_n, keep[0], keep[1]);
        (void)st2; /* (the old model's altitudes are in the model-error cache or need none: it cannot fail) */
        return st;
    }
    if (!in_place) {
        wt_precond_free(r->pre);
        r->pre = pre;
    }
    if (sh) {
        wt_shift_free(r->shift);
        wt_shift_free(r->shift1);
        r->shift = sh, r->shift1 = sh1;
    }
    /* the warm start stays (the layers change slowly with the model); the solve restarts from M c */
    r->t_model = t1 - t0;
    r->t_precond = wt_time_now() - t1;
    return WT_OK;
}

int wt_reconstructor_refresh_noise(wt_reconstructor *r)
{
    if (r->kind != WT_RECON_PCG3 && r->kind != WT_RECON_CG9) return WT_OK;
    int st = wt_tomography_refresh_noise(r->tomo);
    if (st < 0) return st;
    wt_precond *pre = NULL;
    if ((st = wt_precond_alloc(r->ctx, r->tomo, &r->precond, &pre)) < 0) return st;
    wt_precond_free(r->pre);
    r->pre = pre;
    return WT_OK;
}

void wt_reconstructor_last_update_times(const wt_reconstructor *r, double *model, double *precond)
{
    *model = r->t_model;
    *precond = r->t_precond;
}

wt_tomography *wt_reconstructor_tomography(wt_reconstructor *r) { return r->tomo; }
wt_precond *wt_reconstructor_precond(wt_reconstructor *r) { return r->pre; }
const wt_fitting *wt_reconstructor_fitting(const wt_reconstructor *r) { return r->fit; }

const double *wt_reconstructor_layers(const wt_reconstructor *r) { return r->phi; }

void wt_reconstructor_layer_wind(const wt_reconstructor *r, double *vx, double *vy)
{
    const int L = wt_tomography_nlayers(r->tomo);
    if (r->layer_wind) {
        memcpy(vx, r->lvx, (size_t)L * sizeof *vx);
        memcpy(vy, r->lvy, (size_t)L * sizeof *vy);
        return;
    }
    double alt[WT_MAX_LAYERS], frac[WT_MAX_LAYERS];
    for (int l = 0; l < L; l++) alt[l] = wt_tomography_layer_altitude(r->tomo, l);
    wt_profile_compress(r->natm, r->atm_alt, r->atm_frac, r->atm_vx, r->atm_vy, L, alt, frac, vx, vy);
}

int wt_reconstructor_set_layer_wind(wt_reconstructor *r, const double *vx, const double *vy)
{
    if (r->kind != WT_RECON_PCG3 && r->kind != WT_RECON_CG9)
        return WT_ERROR(r->ctx, WT_ERR_INVALID, "reconstructor %s: the layers' wind is for pcg3 and cg9 (the MVM does not "
                        "predict)", wt_reconstructor_name(r->kind));
    const int L = wt_tomography_nlayers(r->tomo), keep = r->layer_wind;
    double kx[WT_MAX_LAYERS], ky[WT_MAX_LAYERS];
    memcpy(kx, r->lvx, sizeof kx);
    memcpy(ky, r->lvy, sizeof ky);
    r->layer_wind = vx && vy;
    for (int l = 0; l < L && r->layer_wind; l++) r->lvx[l] = vx[l], r->lvy[l] = vy[l];
    if (!(r->predict_lead > 0.0)) return WT_OK;
    wt_shift *sh = NULL, *sh1 = NULL;
    const int st = make_shifts(r, &sh, &sh1);
    if (st < 0) { /* the old winds, whole */
        r->layer_wind = keep;
        memcpy(r->lvx, kx, sizeof kx);
        memcpy(r->lvy, ky, sizeof ky);
        return st;
    }
    wt_shift_free(r->shift);
    wt_shift_free(r->shift1);
    r->shift = sh, r->shift1 = sh1;
    return WT_OK;
}

void wt_reconstructor_reset_integrator(wt_reconstructor *r)
{
    if (r->integ) wt_shift_integrator_reset(r->integ);
}

int wt_reconstructor_integrates(const wt_reconstructor *r) { return r->integ != NULL; }
