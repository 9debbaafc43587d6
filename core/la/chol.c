/* core/la/chol.c: CHOLMOD supernodal Cholesky behind the opaque wt_chol (SPEC §9: "factorise
 * Ãᵀ C̃⁻¹ Ã + αD with CHOLMOD"). The only file that includes cholmod.h. */
#include "chol.h"

#include <cholmod.h>
#include <string.h>

struct wt_chol {
    wt_context *ctx;
    cholmod_common cm;
    int started;
    cholmod_factor *L;
    cholmod_dense *X, *Y, *E; /* solve workspace kept between calls (cholmod_l_solve2) */
    int64_t n, nnz;
    int factorized;
};

#define WT_STR_(x) #x
#define WT_STR(x) WT_STR_(x)

const char *wt_chol_version(void)
{
    return "CHOLMOD " WT_STR(CHOLMOD_MAIN_VERSION) "." WT_STR(CHOLMOD_SUB_VERSION) "." WT_STR(CHOLMOD_SUBSUB_VERSION);
}

/* One status for every CHOLMOD failure, naming the call. */
static int cholmod_failure(wt_chol *c, const char *call)
{
    int s = c->cm.status;
    switch (s) {
    case CHOLMOD_OUT_OF_MEMORY:
        return WT_ERROR(c->ctx, WT_ERR_NOMEM, "%s: CHOLMOD ran out of memory (n = %lld, %lld non-zeros; CHOLMOD held %.3g GB at its peak)",
                        call, (long long)c->n, (long long)c->nnz, (double)c->cm.memory_usage / 1e9);
    case CHOLMOD_TOO_LARGE:
        return WT_ERROR(c->ctx, WT_ERR_LIBRARY, "%s: CHOLMOD reports integer overflow (problem too large: n = %lld, %lld non-zeros)",
                        call, (long long)c->n, (long long)c->nnz);
    case CHOLMOD_INVALID:
        return WT_ERROR(c->ctx, WT_ERR_LIBRARY, "%s: CHOLMOD reports an invalid input", call);
    case CHOLMOD_NOT_INSTALLED:
        return WT_ERROR(c->ctx, WT_ERR_LIBRARY, "%s: the requested CHOLMOD method is not installed", call);
    default:
        return WT_ERROR(c->ctx, WT_ERR_LIBRARY, "%s failed with CHOLMOD status %d", call, s);
    }
}

/* A cholmod_sparse view of the upper triangle of a wt_sparse: no copy (int64_t is SuiteSparse_long
 * on every LP64 platform the project builds on, checked below). */
static cholmod_sparse view_upper(const wt_sparse *a)
{
    cholmod_sparse s;
    memset(&s, 0, sizeof s);
    s.nrow = (size_t)a->nrow;
    s.ncol = (size_t)a->ncol;
    s.nzmax = (size_t)wt_sparse_nnz(a);
    s.p = a->colptr;
    s.i = a->rowind;
    s.x = a->val;
    s.stype = 1; /* symmetric, upper triangle used */
    s.itype = CHOLMOD_LONG;
    s.xtype = CHOLMOD_REAL;
    s.dtype = CHOLMOD_DOUBLE;
    s.sorted = 1;
    s.packed = 1;
    return s;
}

_Static_assert(sizeof(SuiteSparse_long) == sizeof(int64_t), "SuiteSparse_long must be 64-bit");

int wt_chol_analyze(wt_context *ctx, const wt_sparse *upper, wt_chol **out)
{
    int st = WT_OK;
    wt_chol *c = NULL;
    *out = NULL;
    if (!upper || upper->nrow != upper->ncol || upper->nrow < 1)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_chol_analyze: expected a non-empty square matrix, got %lld x %lld",
                        upper ? (long long)upper->nrow : 0LL, upper ? (long long)upper->ncol : 0LL);
    WT_ALLOC(ctx, c, 1, "Cholesky object");
    c->ctx = ctx;
    c->n = upper->nrow;
    c->nnz = wt_sparse_nnz(upper);
    if (!cholmod_l_start(&c->cm)) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "cholmod_l_start failed");
        goto fail;
    }
    c->started = 1;
    c->cm.print = 0;                        /* never print: failures come back as statuses */
    c->cm.supernodal = CHOLMOD_SUPERNODAL;  /* dense frontal kernels in the (threaded) BLAS */
    c->cm.final_asis = 1;                   /* keep the supernodal LLᵀ as it is for the solves */
    {
        cholmod_sparse a = view_upper(upper);
        c->L = cholmod_l_analyze(&a, &c->cm);
    }
    if (!c->L || c->cm.status < 0) {
        st = cholmod_failure(c, "cholmod_l_analyze");
        goto fail;
    }
    *out = c;
    return WT_OK;
fail:
    wt_chol_free(c);
    return st;
}

void wt_chol_free(wt_chol *c)
{
    if (!c) return;
    if (c->started) {
        if (c->L) cholmod_l_free_factor(&c->L, &c->cm);
        if (c->X) cholmod_l_free_dense(&c->X, &c->cm);
        if (c->Y) cholmod_l_free_dense(&c->Y, &c->cm);
        if (c->E) cholmod_l_free_dense(&c->E, &c->cm);
        cholmod_l_finish(&c->cm);
    }
    wt_free(c->ctx, c);
}

static const char *ordering_name(int o)
{
    switch (o) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_GIVEN: return "given";
    case CHOLMOD_AMD: return "AMD";
    case CHOLMOD_METIS: return "METIS";
    case CHOLMOD_NESDIS: return "NESDIS";
    case CHOLMOD_COLAMD: return "COLAMD";
    case CHOLMOD_POSTORDERED: return "postordered";
    default: return "unknown";
    }
}

void wt_chol_info_get(const wt_chol *c, wt_chol_info *info)
{
    memset(info, 0, sizeof *info);
    info->n = c->n;
    info->nnz_matrix = c->nnz;
    info->nnz_factor = c->cm.lnz;
    info->flops = c->cm.fl;
    info->peak_bytes = (double)c->cm.memory_usage;
    info->factorized = c->factorized;
    info->ordering = ordering_name(c->L ? (int)c->L->ordering : -1);
    const cholmod_factor *L = c->L;
    if (L && L->is_super) {
        info->supernodal = 1;
        info->factor_entries = (double)L->xsize;
        /* values, supernode row indices, and the per-supernode and per-column index arrays */
        info->factor_bytes = 8.0 * (double)L->xsize + 8.0 * (double)L->ssize + 8.0 * 4.0 * (double)(L->nsuper + 1) +
                             8.0 * 3.0 * (double)c->n;
        info->factorize_bytes = info->factor_bytes + 8.0 * (double)L->maxcsize;
    } else {
        info->factor_entries = c->cm.lnz;
        info->factor_bytes = 16.0 * c->cm.lnz + 8.0 * 6.0 * (double)c->n;
        info->factorize_bytes = info->factor_bytes;
    }
    /* the permuted copy of A and the integer workspace (measured on E-ELT cg9: factor 4.11 GB, A 2.99 GB,
     * CHOLMOD peak 7.77 GB) */
    info->factorize_bytes += 16.0 * (double)c->nnz + 8.0 * 8.0 * (double)c->n;
}

int wt_chol_factorize(wt_chol *c, const wt_sparse *upper)
{
    if (upper->nrow != c->n || upper->ncol != c->n)
        return WT_ERROR(c->ctx, WT_ERR_INVALID, "wt_chol_factorize: matrix is %lld x %lld, the analysis was for order %lld",
                        (long long)upper->nrow, (long long)upper->ncol, (long long)c->n);
    cholmod_sparse a = view_upper(upper);
    c->nnz = wt_sparse_nnz(upper);
    c->factorized = 0;
    int ok = cholmod_l_factorize(&a, c->L, &c->cm);
    if (!ok || c->cm.status < 0) return cholmod_failure(c, "cholmod_l_factorize");
    if (c->cm.status == CHOLMOD_NOT_POSDEF)
        return WT_ERROR(c->ctx, WT_ERR_NUMERIC,
                        "cholmod_l_factorize: the matrix is not positive definite (breakdown at column %lld of %lld "
                        "in the permuted order)",
                        (long long)c->L->minor, (long long)c->n);
    c->factorized = 1;
    return WT_OK;
}

int wt_chol_solve(wt_chol *c, int64_t nrhs, const double *b, int64_t ldb, double *x, int64_t ldx)
{
    if (!c->factorized) return WT_ERROR(c->ctx, WT_ERR_INVALID, "wt_chol_solve: called before a successful factorisation");
    if (nrhs < 0 || ldb < c->n || ldx < c->n)
        return WT_ERROR(c->ctx, WT_ERR_INVALID, "wt_chol_solve: nrhs = %lld, ldb = %lld, ldx = %lld (n = %lld)",
                        (long long)nrhs, (long long)ldb, (long long)ldx, (long long)c->n);
    if (nrhs == 0) return WT_OK;
    cholmod_dense B;
    memset(&B, 0, sizeof B);
    B.nrow = (size_t)c->n;
    B.ncol = (size_t)nrhs;
    B.nzmax = (size_t)(ldb * nrhs);
    B.d = (size_t)ldb;
    B.x = (void *)b; /* read only: CHOLMOD copies B into its workspace first */
    B.xtype = CHOLMOD_REAL;
    B.dtype = CHOLMOD_DOUBLE;
    int ok = cholmod_l_solve2(CHOLMOD_A, c->L, &B, NULL, &c->X, NULL, &c->Y, &c->E, &c->cm);
    if (!ok || c->cm.status < 0) return cholmod_failure(c, "cholmod_l_solve2");
    const double *xs = c->X->x;
    const int64_t d = (int64_t)c->X->d;
    for (int64_t j = 0; j < nrhs; j++) memcpy(x + j * ldx, xs + j * d, (size_t)c->n * sizeof *x);
    return WT_OK;
}

double wt_chol_solve_bytes(int64_t n, int64_t nrhs)
{
    /* X, Y (n x nrhs each, Y may be sized up to the supernode block) and E */
    return 8.0 * (double)n * (double)nrhs * 3.0;
}
