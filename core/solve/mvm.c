/* core/solve/mvm.c: the stored MVM control matrix: container, the one POLC apply, and its conversion
 * from and to the plain data of MATRIX.h5 (SPEC §9). */
#include "mvm.h"

#include <cblas.h>
#include <math.h>
#include <string.h>

#include "../io/mvm_file.h"
#include "../la/chol.h"
#include "../la/half.h"

_Static_assert((int)WT_PREC_F32 == (int)WT_MVM_FILE_F32 && (int)WT_PREC_F16 == (int)WT_MVM_FILE_F16 &&
                   (int)WT_PREC_BF16 == (int)WT_MVM_FILE_BF16,
               "the file layer's precision codes are recon.mvm_precision's");

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
    m->precision = WT_PREC_F32;
    m->nthreads = wt_context_threads(ctx);
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
    wt_free(m->ctx, m->Rh);
    wt_free(m->ctx, m->RAh);
    wt_free(m->ctx, m->Rc);
    wt_free(m->ctx, m->RAc);
    wt_free(m->ctx, m);
}

/* The first non-finite entry of an n-element array, or -1. */
static int64_t first_nonfinite(const float *a, int64_t n)
{
    for (int64_t i = 0; i < n; i++)
        if (!isfinite(a[i])) return i;
    return -1;
}

int wt_mvm_set_precision(wt_mvm *m, int precision)
{
    int st = WT_OK;
    wt_context *ctx = m->ctx;
    if (precision == m->precision || precision == WT_PREC_F32) return WT_OK;
    if (m->precision != WT_PREC_F32)
        return WT_ERROR(ctx, WT_ERR_INVALID, "MVM: converting %s to %s: only an fp32 matrix is converted",
                        wt_prec_name(m->precision), wt_prec_name(precision));
    if (precision != WT_PREC_F16 && precision != WT_PREC_BF16)
        return WT_ERROR(ctx, WT_ERR_INVALID, "MVM: unknown precision %d", precision);
    const int64_t na = m->nact, ns = m->nslopes;
    int64_t bad;
    if ((bad = first_nonfinite(m->R, na * ns)) >= 0)
        return WT_ERROR(ctx, WT_ERR_NUMERIC, "MVM: R[%lld, %lld] is not finite; nothing to store as %s",
                        (long long)(bad / ns), (long long)(bad % ns), wt_prec_name(precision));
    if ((bad = first_nonfinite(m->RA, na * na)) >= 0)
        return WT_ERROR(ctx, WT_ERR_NUMERIC, "MVM: RA[%lld, %lld] is not finite; nothing to store as %s",
                        (long long)(bad / na), (long long)(bad % na), wt_prec_name(precision));
    WT_ALLOC(ctx, m->Rh, (size_t)(na * ns), "the 16-bit control matrix R");
    WT_ALLOC(ctx, m->RAh, (size_t)(na * na), "the 16-bit POLC matrix RA");
    WT_ALLOC(ctx, m->Rc, (size_t)na, "the row scales of R");
    WT_ALLOC(ctx, m->RAc, (size_t)na, "the row scales of RA");
    wt_half_pack(precision, na, ns, m->R, m->Rh, m->Rc, m->nthreads);
    wt_half_pack(precision, na, na, m->RA, m->RAh, m->RAc, m->nthreads);
    wt_free(ctx, m->R);
    wt_free(ctx, m->RA);
    m->R = m->RA = NULL;
    m->precision = precision;
    return WT_OK;
fail:
    wt_free(ctx, m->Rh);
    wt_free(ctx, m->RAh);
    wt_free(ctx, m->Rc);
    wt_free(ctx, m->RAc);
    m->Rh = m->RAh = NULL;
    m->Rc = m->RAc = NULL;
    return st;
}

void wt_mvm_apply(const wt_mvm *m, const float *s, const float *a, float *y)
{
    const int na = (int)m->nact, ns = (int)m->nslopes;
    if (m->precision != WT_PREC_F32) {
        wt_half_gemv(m->precision, na, ns, m->Rh, m->Rc, s, 0.0f, y, m->nthreads);
        if (a) wt_half_gemv(m->precision, na, na, m->RAh, m->RAc, a, 1.0f, y, m->nthreads);
        return;
    }
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
    int st = WT_OK;
    *out = NULL;
    int precision;
    WT_TRY(wt_mvm_file_precision(ctx, path, &precision));
    if (precision == WT_PREC_F32) {
        WT_TRY(wt_mvm_alloc(ctx, WT_MVM_LAYER_VALUES, nact, nslopes, &m));
    } else {
        WT_ALLOC(ctx, m, 1, "MVM");
        m->ctx = ctx;
        m->nact = nact;
        m->nslopes = nslopes;
        m->precision = precision;
        m->nthreads = wt_context_threads(ctx);
        WT_ALLOC(ctx, m->Rh, (size_t)(nact * nslopes), "the 16-bit control matrix R");
        WT_ALLOC(ctx, m->RAh, (size_t)(nact * nact), "the 16-bit POLC matrix RA");
        WT_ALLOC(ctx, m->Rc, (size_t)nact, "the row scales of R");
        WT_ALLOC(ctx, m->RAc, (size_t)nact, "the row scales of RA");
    }
    wt_mvm_file_data d = {m->precision, m->R, m->RA, m->Rh, m->RAh, m->Rc, m->RAc};
    wt_mvm_file_system fs = file_system(cfg);
    if ((st = wt_mvm_file_read(ctx, path, &fs, nact, nslopes, &d, variant)) < 0) goto fail;
    m->commands = !strcmp(variant, "cg9") ? WT_MVM_FITTING : WT_MVM_LAYER_VALUES;
    m->predictive = cfg->predict != 0;
    if (variant_out) memcpy(variant_out, variant, sizeof variant);
    *out = m;
    return WT_OK;
fail:
    wt_mvm_free(m);
    return st;
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
    wt_mvm_file_data d = {m->precision, m->R, m->RA, m->Rh, m->RAh, m->Rc, m->RAc};
    return wt_mvm_file_write(w, &fs, m->nact, m->nslopes, &d, &rec);
}
