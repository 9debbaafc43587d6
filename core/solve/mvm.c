/* core/solve/mvm.c: the stored MVM control matrix: container, the one POLC apply, and its conversion
 * from and to the plain data of MATRIX.h5 (SPEC §9). */
#include "mvm.h"

#include <cblas.h>
#include <string.h>

#include "../io/mvm_file.h"
#include "../la/chol.h"

int wt_mvm_alloc(wt_context *ctx, int commands, int64_t nact, int64_t nslopes, wt_mvm **out)
{
    int st = WT_OK;
    wt_mvm *m = NULL;
    *out = NULL;
    WT_ALLOC(ctx, m, 1, "MVM");
    m->ctx = ctx;
    m->commands = commands;
    m->nact = nact;
    m->nslopes = nslopes;
    WT_ALLOC(ctx, m->R, (size_t)nact * (size_t)nslopes, "the control matrix R");
    WT_ALLOC(ctx, m->RA, (size_t)nact * (size_t)nact, "the POLC matrix RA");
    *out = m;
    return WT_OK;
fail:
    wt_mvm_free(m);
    return st;
}

void wt_mvm_free(wt_mvm *m)
{
    if (!m) return;
    wt_free(m->ctx, m->R);
    wt_free(m->ctx, m->RA);
    wt_free(m->ctx, m);
}

void wt_mvm_apply(const wt_mvm *m, const float *s, const float *a, float *y)
{
    const int na = (int)m->nact, ns = (int)m->nslopes;
    cblas_sgemv(CblasRowMajor, CblasNoTrans, na, ns, 1.0f, m->R, ns, s, 1, 0.0f, y, 1);
    if (a) cblas_sgemv(CblasRowMajor, CblasNoTrans, na, na, 1.0f, m->RA, na, a, 1, 1.0f, y, 1);
}

/* The identity of cfg's system as the file layer wants it: plain data. */
static wt_mvm_file_system file_system(const wt_config *cfg)
{
    return (wt_mvm_file_system){.sha256 = cfg->matrix_sha256, .text = cfg->matrix_text, .path = cfg->path,
                                .alpha = cfg->alpha, .tau = cfg->tau};
}

int wt_mvm_read(wt_context *ctx, const char *path, const wt_config *cfg, int64_t nact, int64_t nslopes, wt_mvm **out,
                char *variant_out)
{
    char variant[16];
    wt_mvm *m = NULL;
    *out = NULL;
    int st = wt_mvm_alloc(ctx, WT_MVM_LAYER_VALUES, nact, nslopes, &m);
    if (st < 0) return st;
    wt_mvm_file_system fs = file_system(cfg);
    if ((st = wt_mvm_file_read(ctx, path, &fs, nact, nslopes, m->R, m->RA, variant)) < 0) {
        wt_mvm_free(m);
        return st;
    }
    m->commands = !strcmp(variant, "cg9") ? WT_MVM_FITTING : WT_MVM_LAYER_VALUES;
    if (variant_out) memcpy(variant_out, variant, sizeof variant);
    *out = m;
    return WT_OK;
}

int wt_mvm_write(wt_h5_writer *w, const wt_mvm *m, const wt_config *cfg, const char *variant)
{
    const wt_mvm_stats *s = &m->stats;
    wt_mvm_file_record rec = {.variant = variant,
                              .nunknowns = s->nunknowns,
                              .nnz_factor = s->nnz_factor,
                              .rank = s->rank,
                              .build_time = s->t_total,
                              .peak_estimate = s->peak_estimate,
                              .ordering = s->ordering,
                              .cholmod_version = wt_chol_version()};
    wt_mvm_file_system fs = file_system(cfg);
    return wt_mvm_file_write(w, &fs, m->nact, m->nslopes, m->R, m->RA, &rec);
}
