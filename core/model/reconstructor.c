/* core/model/reconstructor.c: the pcg3 / cg9 / none reconstructors as one slopes → commands map. */
#include "reconstructor.h"

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
    wt_tomography *tomo;
    wt_fitting *fit;
    double *c;               /* wavelet coefficients (warm start) */
    double *phi;             /* spatial layers */
    double *a_fit;           /* fitting warm start */
    int64_t *act_index;      /* pcg3: actuator → index into phi */
    const wt_mvm *mvm;       /* mvm: the control matrix (not owned) */
    float *sf, *af;          /* mvm: float32 slopes and commands */
    double t_tomo, t_fit;
    wt_pcg_result last;
};

int wt_reconstructor_actuator_points(wt_context *ctx, const wt_tomography *t, int64_t *points)
{
    const wt_system *sys = wt_tomography_system(t);
    const int L = wt_tomography_nlayers(t);
    int64_t q = 0;
    for (int k = 0; k < sys->dm->ndms; k++) {
        const wt_grid *dg = &sys->dm->grid[k];
        double h = sys->dm->altitude[k];
        int l = -1;
        for (int i = 0; i < L && l < 0; i++) {
            const wt_grid *lg = wt_tomography_layer_grid(t, i);
            double hl = wt_tomography_layer_altitude(t, i);
            if (fabs(hl - h) <= 1e-6 * fmax(1.0, h) && fabs(lg->dx - dg->dx) <= 1e-9 * dg->dx) l = i;
        }
        if (l < 0)
            return WT_ERROR(ctx, WT_ERR_CONFIG,
                            "pcg3: the commands are the layer values at the actuators, but DM %d (altitude %g m, "
                            "pitch %g m) has no reconstruction layer at its altitude with spacing equal to its pitch; "
                            "set recon.pcg3.layer_altitudes_m and layer_spacing_m to the DM altitudes and pitches",
                            k + 1, h, dg->dx);
        const wt_grid *lg = wt_tomography_layer_grid(t, l);
        int64_t off = wt_tomography_layer_offset(t, l);
        for (int iy = 0; iy < dg->ny; iy++)
            for (int ix = 0; ix < dg->nx; ix++) {
                if (!sys->dm->active[k][ix + (int64_t)dg->nx * iy]) continue;
                double gx = (dg->x0 + ix * dg->dx - lg->x0) / lg->dx, gy = (dg->y0 + iy * dg->dx - lg->y0) / lg->dx;
                double rx = round(gx), ry = round(gy);
                if (fabs(gx - rx) > 1e-6 || fabs(gy - ry) > 1e-6 || rx < 0 || ry < 0 || rx >= lg->nx || ry >= lg->ny)
                    return WT_ERROR(ctx, WT_ERR_CONFIG,
                                    "pcg3: actuator (%d, %d) of DM %d sits at layer %d grid position (%.4f, %.4f), not "
                                    "on a point of its %d x %d grid; an odd actuator count of the layer's pitch "
                                    "inside the layer grid is needed",
                                    ix, iy, k + 1, l + 1, gx, gy, lg->nx, lg->ny);
                points[q++] = off + (int64_t)rx + (int64_t)lg->nx * (int64_t)ry;
            }
    }
    return WT_OK;
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
    int64_t n = wt_tomography_nunknowns(r->tomo);
    WT_ALLOC(ctx, r->c, n, "coefficients");
    WT_ALLOC(ctx, r->phi, n, "layers");
    if (kind == WT_RECON_PCG3) {
        /* the commands are the layer values at the actuators: the same map as the MVM builder's */
        WT_ALLOC(ctx, r->act_index, sys->nact, "actuator map");
        WT_TRY(wt_reconstructor_actuator_points(ctx, r->tomo, r->act_index));
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
    wt_tomography_free(r->tomo);
    wt_fitting_free(r->fit);
    wt_free(r->ctx, r->c);
    wt_free(r->ctx, r->phi);
    wt_free(r->ctx, r->a_fit);
    wt_free(r->ctx, r->act_index);
    wt_free(r->ctx, r);
}

void wt_reconstructor_reset(wt_reconstructor *r)
{
    if (r->c) memset(r->c, 0, (size_t)wt_tomography_nunknowns(r->tomo) * sizeof *r->c);
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
    int st = wt_tomography_solve(r->tomo, s_ol, r->c, r->iterations, r->tol, NULL, &r->last);
    if (st < 0) return st;
    wt_tomography_layers(r->tomo, r->c, r->phi);
    r->t_tomo = wt_time_now() - t0;
    if (r->kind == WT_RECON_PCG3) {
        for (int64_t i = 0; i < na; i++) a[i] = r->phi[r->act_index[i]];
        return WT_OK;
    }
    t0 = wt_time_now();
    st = wt_fitting_solve(r->fit, r->phi, r->a_fit, r->fit_iterations, 0.0, NULL, NULL);
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
wt_tomography *wt_reconstructor_tomography(wt_reconstructor *r) { return r->tomo; }
