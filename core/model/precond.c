/* core/model/precond.c: the preconditioners of the tomography's PCG (see precond.h): the interface, and the
 * dispatch to the kinds' files:
 *
 *   J  = diag(Σ_LGS Ãᵀ C̃⁻¹ Ã) + α D                       exact, by coloured probing (paper's modified Jacobi)
 *   B  = J with the coarse coefficients' block of the LGS + prior part of M      (coarse_ngs)
 *   B_F⁻¹ = W F⁻¹ diag(1/λ_max A(k)) F Wᵀ beside the coarse block, A(k) the L x L symbol of that part per
 *         frequency                                                                          (fourier)
 *   P  = B + R C_n Rᵀ,  P⁻¹ = B⁻¹ − Y K⁻¹ Yᵀ,  Y = B⁻¹ R,  K = Ĉ⁻¹_NGS + Rᵀ B⁻¹ R   (Woodbury, the NGS term)
 *
 * Built only from the tomography's public operators (slopes Ã, the adjoint Ãᵀ Ĉ⁻¹, the projections, noise
 * models and wavelets it exposes), so the operator's file knows none of this. J: precond_jacobi.c; B:
 * precond_coarse.c, with precond_multilevel.c's layer blocks or precond_fourier.c's B_F; the NGS term:
 * precond_lowrank.c; what they are built from: precond_base.c; the updates: precond_update.c. */
#include "precond_coarse.h"
#include "precond_fourier.h"
#include "precond_jacobi.h"
#include "precond_lowrank.h"
#include "precond_multilevel.h"

#include <string.h>

#include "../la/vec.h"

#define kind_names wt_precond__kind_names

const char *wt_precond_kind_name(int kind) { return kind >= 0 && kind < WT_PRECOND_NKINDS ? kind_names[kind] : NULL; }

int wt_precond_kind(const char *name)
{
    for (int k = 0; k < WT_PRECOND_NKINDS; k++)
        if (name && !strcmp(name, kind_names[k])) return k;
    return -1;
}


/* ---- the interface ------------------------------------------------------------------------------ */

int wt_precond_alloc(wt_context *ctx, wt_tomography *t, const wt_precond_params *par, wt_precond **out)
{
    int st = WT_OK;
    wt_precond *p = NULL;
    *out = NULL;
    if (!wt_precond_kind_name(par->kind))
        return WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner kind %d: expected 0..%d (none, jacobi, jacobi_ngs, "
                        "coarse_ngs, multilevel, fourier)", par->kind, WT_PRECOND_NKINDS - 1);
    WT_ALLOC(ctx, p, 1, "preconditioner");
    p->ctx = ctx;
    p->kind = par->kind;
    p->n = wt_tomography_nunknowns(t);
    p->nthreads = wt_tomography_threads(t);
    p->tomo = t;
    p->single = par->single;
    if (par->updatable && p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_MULTILEVEL)
        WT_TRY(wt_precond__parts_begin(p, t));
    if (wt_tomography_space(t) && p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_FOURIER) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner %s: built on wavelet coefficients; this tomography's "
                      "unknowns are the layers' values (only none and fourier work there)", kind_names[p->kind]);
        goto fail;
    }
    if (p->kind != WT_PRECOND_NONE && p->kind != WT_PRECOND_FOURIER) WT_TRY(wt_precond__jacobi(p, t));
    if (par->coarse_levels < 0 && p->kind != WT_PRECOND_FOURIER && p->kind >= WT_PRECOND_COARSE_NGS) {
        st = WT_ERROR(ctx, WT_ERR_INVALID, "preconditioner %s: coarse_levels %d; expected >= 0", kind_names[p->kind],
                      par->coarse_levels);
        goto fail;
    }
    if (p->kind == WT_PRECOND_FOURIER) WT_TRY(wt_precond__fourier(p, t, par->coarse_levels));
    else if (p->kind >= WT_PRECOND_COARSE_NGS) WT_TRY(wt_precond__coarse(p, t, par->coarse_levels));
    if (p->kind == WT_PRECOND_COARSE_NGS) WT_TRY(wt_precond__coarse_invert(p, par->single));
    if (p->kind == WT_PRECOND_MULTILEVEL) {
        int sc[WT_MAX_LAYERS];
        for (int l = 0; l < wt_tomography_nlayers(t); l++) sc[l] = wt_precond__coarse_side(t, l, par->coarse_levels);
        WT_TRY(wt_precond__layer_blocks(p, t, sc));
    }
    if (p->kind >= WT_PRECOND_JACOBI_NGS) WT_TRY(wt_precond__lowrank(p, t));
    *out = p;
    return WT_OK;
fail:
    wt_precond_free(p);
    return st;
}

void wt_precond_free(wt_precond *p)
{
    if (!p) return;
    wt_context *ctx = p->ctx;
    wt_free(ctx, p->jinv);
    wt_free(ctx, p->lr_Y);
    wt_free(ctx, p->lr_K);
    wt_free(ctx, p->lr_w);
    wt_free(ctx, p->lr_part);
    wt_free(ctx, p->lr_runs);
    wt_free(ctx, p->c_idx);
    wt_free(ctx, p->c_free);
    wt_free(ctx, p->c_L);
    wt_free(ctx, p->c_w);
    wt_free(ctx, p->c_inv);
    wt_free(ctx, p->c_inv32);
    wt_free(ctx, p->lr_blk);
    wt_free(ctx, p->lr_Yb_raw);
    wt_free(ctx, p->lr_Yb32_raw);
    wt_free(ctx, p->b_start);
    wt_free(ctx, p->b_fac);
    wt_free(ctx, p->b_idx);
    wt_free(ctx, p->b_L);
    wt_free(ctx, p->fd_s);
    wt_free(ctx, p->fd_raw);
    wt_free(ctx, p->fd_B);
    wt_free(ctx, p->fd_cr);
    wt_free(ctx, p->fd_cphi);
    wt_free(ctx, p->fd_rs_ptr);
    wt_free(ctx, p->fd_rs_idx);
    wt_free(ctx, p->fd_rs_val);
    wt_free(ctx, p->fd_rc);
    wt_free(ctx, p->fd_dots);
    wt_free(ctx, p->pj);
    wt_free(ctx, p->pc);
    wt_free(ctx, p->pa);
    wt_free(ctx, p->pp);
    wt_free(ctx, p->lr_R);
    wt_free(ctx, p->lr_cinv);
    wt_free(ctx, p->part_sl);
    wt_free(ctx, p->fd_rhat);
    wt_free(ctx, p->pu_Y_raw);
    wt_free(ctx, p->pu_spare);
    if (p->fd_r2c) fftw_destroy_plan(p->fd_r2c);
    if (p->fd_c2r) fftw_destroy_plan(p->fd_c2r);
    wt_free(ctx, p);
}

void wt_precond_apply(const wt_precond *p, const double *r, double *z)
{
    if (p->kind == WT_PRECOND_NONE) memcpy(z, r, (size_t)p->n * sizeof *z);
    else if (p->kind == WT_PRECOND_JACOBI)
        for (int64_t i = 0; i < p->n; i++) z[i] = p->jinv[i] * r[i];
    else wt_precond__lowrank_apply(p, r, z); /* B⁻¹ alone when there is no NGS term (and no coarse block: J⁻¹) */
}

void wt_precond_apply_cb(void *user, const double *r, double *z) { wt_precond_apply(user, r, z); }

wt_pcg_precond wt_precond_pcg(const wt_precond *p)
{
    wt_pcg_precond none = {NULL, NULL};
    if (!p || p->kind == WT_PRECOND_NONE) return none;
    /* the callback's user is not const; apply changes only the scratch p points to */
    return (wt_pcg_precond){wt_precond_apply_cb, (void *)p};
}

int wt_precond_kind_of(const wt_precond *p) { return p->kind; }
const char *wt_precond_name(const wt_precond *p) { return kind_names[p->kind]; }
const double *wt_precond_jacobi_inverse(const wt_precond *p) { return p->jinv; }
int wt_precond_rank(const wt_precond *p) { return p->nlr; }
int wt_precond_coarse_size(const wt_precond *p) { return p->nc; }
int64_t wt_precond_nblocks(const wt_precond *p) { return p->nb; }

int wt_precond_block(const wt_precond *p, int64_t b, int64_t *idx, double *block)
{
    if (b < 0 || b >= p->nb) return -1;
    const int q = (int)(p->b_start[b + 1] - p->b_start[b]);
    const double *F = p->b_L + p->b_fac[b];
    if (idx)
        for (int a = 0; a < q; a++) idx[a] = p->b_idx[p->b_start[b] + a];
    if (block) /* (L Lᵀ)_ac = Σ_k≤min(a,c) L_ak L_ck, L_aa = 1 / the stored last entry of row a */
        for (int a = 0; a < q; a++)
            for (int c = 0; c < q; c++) {
                const double *ra = F + (int64_t)a * (a + 1) / 2, *rc = F + (int64_t)c * (c + 1) / 2;
                const int k1 = a < c ? a : c;
                double v = 0.0;
                for (int k = 0; k <= k1; k++)
                    v += (k == a ? 1.0 / ra[a] : ra[k]) * (k == c ? 1.0 / rc[c] : rc[k]);
                block[a + (int64_t)q * c] = v;
            }
    return q;
}

double wt_precond_bytes(const wt_precond *p)
{
    if (!p) return 0.0;
    const int L = wt_tomography_nlayers(p->tomo);
    const double parts = !p->parts ? 0.0
                                   : 8.0 * (double)p->nlgs * (p->pj ? (double)p->n : 0.0) +
                                         8.0 * (p->pc ? (double)(p->nlgs + 1) * p->nc * p->nc : 0.0) +
                                         16.0 * (p->pa ? (double)p->fd_nk * (p->nlgs * L * (L + 1) / 2 + L) : 0.0) +
                                         8.0 * (p->lr_R ? (double)p->nlr * (p->n + p->nlr) : 0.0) +
                                         16.0 * (p->fd_rhat ? (double)p->nlr * L * p->fd_nk : 0.0) +
                                         8.0 * (p->pu_Y_raw ? (double)p->nlr * p->n : 0.0) + (double)p->pu_spare_bytes;
    return parts + 8.0 * (double)p->n * ((p->jinv ? 1.0 : 0.0) + (p->lr_Y ? p->nlr : 0)) + (double)p->lr_nblk * ((p->lr_Yb32 ? 32.0 : 64.0) * p->nlr + 8.0) +
           8.0 * (double)p->nlr * (p->nlr + WT_VEC_CHUNKS + 1) + 16.0 * (double)p->c_nfree +
           16.0 * (double)p->lr_nruns + (double)p->nc * ((p->c_inv32 ? 4.0 : 8.0) * p->nc + 16.0) +
           (p->nb > 0 ? 8.0 * (double)(2 * (p->nb + 1) + p->b_start[p->nb] + p->b_fac[p->nb]) : 0.0) +
           (p->fd_n > 0 ? 8.0 * ((double)p->fd_nk + (double)p->nthreads * (double)p->fd_slice +
                                 (double)p->fd_sc * p->fd_n + 2.0 * p->nc)
                        : 0.0) +
           (p->fd_rs_ptr ? 12.0 * (double)p->fd_rs_ptr[wt_tomography_nlayers(p->tomo) * p->nlr] +
                               8.0 * (double)p->nlr * (p->nc + wt_tomography_nlayers(p->tomo))
                         : 0.0);
}
