/* core/la/chol.c: CHOLMOD supernodal Cholesky behind the opaque wt_chol (SPEC §9: "factorise
 * Ãᵀ C̃⁻¹ Ã + αD with CHOLMOD"). The only file that includes cholmod.h. */
#include "chol.h"

#include <cholmod.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* wt_chol_prepare_one's plan of the single right-hand-side solves */
typedef struct one_plan {
    int ready;
    int nthreads;           /* 1 or 2 */
    int float32;            /* the packed values are float (else double) */
    void *val;              /* L packed: supernode k's column j holds its rows j .. nsrow − 1 (the diagonal
                               block's lower triangle, then the rows below), columns one after another */
    int64_t *voff;          /* nsuper + 1: where supernode k's columns start in val */
    int64_t *order;         /* the supernodes of group 0, group 1, then the top part, each in elimination order */
    int64_t start[4];       /* order[start[g] .. start[g + 1]) is part g (0, 1: groups, 2: top) */
    double entries[3];      /* entries of L per part */
    double *y;              /* n: the permuted right-hand side / solution */
    double *buf[2];         /* n each: a group's updates of top rows (forward) */
    double *work[2];        /* max rows of a supernode, per group */
    int64_t *top_rows;      /* the rows of the top part's columns (the only ones buf touches) */
    int64_t ntop_rows;
    int *is_top;            /* n: 1 for those rows */
} one_plan;

struct wt_chol {
    wt_context *ctx;
    cholmod_common cm;
    int started;
    cholmod_factor *L;
    cholmod_dense *X, *Y, *E; /* solve workspace kept between calls (cholmod_l_solve2) */
    int64_t n, nnz;
    int factorized;
    one_plan one;
    int one_reference;        /* the single right-hand-side solves use the reference kernels */
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

static void one_plan_free(wt_context *ctx, one_plan *p)
{
    wt_free(ctx, p->val);
    wt_free(ctx, p->voff);
    wt_free(ctx, p->order);
    wt_free(ctx, p->y);
    for (int g = 0; g < 2; g++) {
        wt_free(ctx, p->buf[g]);
        wt_free(ctx, p->work[g]);
    }
    wt_free(ctx, p->top_rows);
    wt_free(ctx, p->is_top);
    memset(p, 0, sizeof *p);
}

void wt_chol_free(wt_chol *c)
{
    if (!c) return;
    one_plan_free(c->ctx, &c->one);
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
    /* the permuted copy of A and the integer workspace (CHOLMOD's peak is the factor, A and this copy together) */
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
    one_plan_free(c->ctx, &c->one); /* a plan of the old values: prepare again */
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

/* ---- single right-hand side, two threads (wt_chol_prepare_one, wt_chol_solve_one) ----------------------
 *
 * CHOLMOD's supernodal LLᵀ (final_asis): supernode k holds columns super[k] .. super[k+1) as one dense
 * column-major block of nsrow = pi[k+1] − pi[k] rows (row indices s[pi[k] ..], the first nscol = the
 * supernode's own columns) at x[px[k] ..]. Its parent in the supernodal elimination tree is the supernode
 * of its first row below the diagonal block; with CHOLMOD's postorder, a subtree is a contiguous range of
 * supernodes ending at its root. */

int wt_chol_prepare_one(wt_chol *c, int float32, int nthreads)
{
    int st = WT_OK;
    wt_context *ctx = c->ctx;
    one_plan *p = &c->one;
    const cholmod_factor *L = c->L;
    int64_t *parent = NULL, *col2sup = NULL, *first = NULL, *task = NULL, *mark = NULL;
    double *weight = NULL;
    one_plan_free(ctx, p);
    if (!c->factorized || !L->is_super || !L->is_ll)
        return WT_ERROR(ctx, WT_ERR_INVALID, "wt_chol_prepare_one: needs a supernodal LL' factorisation first");
    const int64_t n = c->n, ns = (int64_t)L->nsuper;
    const int64_t *super = L->super, *pi = L->pi, *px = L->px, *srow = L->s;
    WT_ALLOC(ctx, parent, ns, "solve plan");
    WT_ALLOC(ctx, col2sup, n, "solve plan");
    WT_ALLOC(ctx, first, ns, "solve plan");
    WT_ALLOC(ctx, weight, ns, "solve plan");
    WT_ALLOC(ctx, task, ns, "solve plan");
    WT_ALLOC(ctx, mark, ns, "solve plan");
    for (int64_t k = 0; k < ns; k++)
        for (int64_t j = super[k]; j < super[k + 1]; j++) col2sup[j] = k;
    /* parent, subtree weight (entries of L) and first supernode of each subtree (postorder: contiguous) */
    for (int64_t k = 0; k < ns; k++) {
        const int64_t nscol = super[k + 1] - super[k], nsrow = pi[k + 1] - pi[k];
        parent[k] = nsrow > nscol ? col2sup[srow[pi[k] + nscol]] : -1;
        if (parent[k] >= 0 && parent[k] <= k) {
            st = WT_ERROR(ctx, WT_ERR_LIBRARY, "wt_chol_prepare_one: the supernodes are not in postorder");
            goto fail;
        }
        first[k] = k;
    }
    for (int64_t k = 0; k < ns; k++) weight[k] += (double)(px[k + 1] - px[k]);
    for (int64_t k = 0; k < ns; k++)
        if (parent[k] >= 0) {
            weight[parent[k]] += weight[k];
            if (first[k] < first[parent[k]]) first[parent[k]] = first[k];
        }
    /* tasks: start with the roots; split the heaviest task into its root (→ top) and its children while it
     * weighs more than half of what the tasks hold (a task that heavy keeps one thread alone busy) */
    int64_t ntask = 0;
    for (int64_t k = 0; k < ns; k++)
        if (parent[k] < 0) task[ntask++] = k;
    for (int64_t split = 0; split < ns; split++) { /* each split moves one supernode to the top part */
        double tot = 0.0, big = -1.0;
        int64_t bi = -1;
        for (int64_t t = 0; t < ntask; t++) {
            tot += weight[task[t]];
            if (weight[task[t]] > big) big = weight[task[t]], bi = t;
        }
        if (bi < 0 || big <= 0.5 * tot) break;
        const int64_t r = task[bi];
        int64_t nchild = 0;
        for (int64_t k = first[r]; k < r; k++) nchild += parent[k] == r;
        if (nchild == 0) break; /* a single supernode: nothing to split */
        mark[r] = 1;            /* top part */
        task[bi] = task[--ntask];
        for (int64_t k = first[r]; k < r; k++)
            if (parent[k] == r) task[ntask++] = k;
    }
    /* deal the tasks to two groups, heaviest first to the lighter group (ties: lower index first, so the plan
     * is a function of the factor alone) */
    for (int64_t a = 1; a < ntask; a++) { /* insertion sort by weight descending, then index */
        const int64_t v = task[a];
        int64_t b = a - 1;
        while (b >= 0 && (weight[task[b]] < weight[v] || (weight[task[b]] == weight[v] && task[b] > v))) {
            task[b + 1] = task[b];
            b--;
        }
        task[b + 1] = v;
    }
    double gw[2] = {0.0, 0.0};
    for (int64_t t = 0; t < ntask; t++) {
        const int g = gw[1] < gw[0];
        gw[g] += weight[task[t]];
        for (int64_t k = first[task[t]]; k <= task[t]; k++) mark[k] = 2 + g;
    }
    WT_ALLOC(ctx, p->order, ns, "solve plan");
    int64_t at = 0;
    for (int part = 0; part < 3; part++) {
        p->start[part] = at;
        const int64_t want = part == 2 ? 1 : 2 + part;
        p->entries[part] = 0.0;
        for (int64_t k = 0; k < ns; k++)
            if (mark[k] == want) {
                p->order[at++] = k;
                p->entries[part] += (double)(px[k + 1] - px[k]);
            }
    }
    p->start[3] = at;
    if (at != ns) {
        st = WT_ERROR(ctx, WT_ERR_LIBRARY, "wt_chol_prepare_one: %lld of %lld supernodes placed", (long long)at, (long long)ns);
        goto fail;
    }
    /* the top part's columns: the rows the groups' buffers carry */
    p->ntop_rows = 0;
    for (int64_t q = p->start[2]; q < p->start[3]; q++) p->ntop_rows += super[p->order[q] + 1] - super[p->order[q]];
    WT_ALLOC(ctx, p->top_rows, p->ntop_rows + 1, "solve plan");
    WT_ALLOC(ctx, p->is_top, n, "solve plan");
    {
        int64_t m = 0;
        for (int64_t q = p->start[2]; q < p->start[3]; q++)
            for (int64_t j = super[p->order[q]]; j < super[p->order[q] + 1]; j++) {
                p->top_rows[m++] = j;
                p->is_top[j] = 1;
            }
    }
    int64_t maxrow = 1; /* a supernode's rows below its block and its columns (backward's partial dots) */
    for (int64_t k = 0; k < ns; k++)
        if (pi[k + 1] - pi[k] > maxrow) maxrow = pi[k + 1] - pi[k];
    WT_ALLOC(ctx, p->y, n, "solve vector");
    for (int g = 0; g < 2; g++) {
        WT_ALLOC(ctx, p->buf[g], n, "solve buffer");
        WT_ALLOC(ctx, p->work[g], maxrow, "solve workspace");
    }
    /* the packed copy: CHOLMOD keeps each diagonal block whole (its upper triangle unused), which the solves
     * would stream for nothing (the root supernode alone is a dense 988² block at E-ELT) */
    WT_ALLOC(ctx, p->voff, ns + 1, "packed factor offsets");
    for (int64_t k = 0; k < ns; k++) {
        const int64_t nscol = super[k + 1] - super[k], nsrow = pi[k + 1] - pi[k];
        p->voff[k + 1] = p->voff[k] + nscol * nsrow - nscol * (nscol - 1) / 2;
    }
    p->float32 = float32 != 0;
    p->val = wt_calloc(ctx, (size_t)p->voff[ns], float32 ? sizeof(float) : sizeof(double));
    if (!p->val) {
        st = WT_ERROR(ctx, WT_ERR_NOMEM, "out of memory for the packed factor (%lld values)", (long long)p->voff[ns]);
        goto fail;
    }
    {
        const double *x = L->x;
        for (int64_t k = 0; k < ns; k++) {
            const int64_t nscol = super[k + 1] - super[k], nsrow = pi[k + 1] - pi[k];
            int64_t o = p->voff[k];
            for (int64_t j = 0; j < nscol; j++)
                for (int64_t i = j; i < nsrow; i++, o++) {
                    const double v = x[px[k] + i + nsrow * j];
                    if (float32) ((float *)p->val)[o] = (float)v;
                    else ((double *)p->val)[o] = v;
                }
        }
    }
    p->nthreads = nthreads >= 2 ? 2 : 1;
    p->ready = 1;
fail:
    if (st < 0) one_plan_free(ctx, p);
    wt_free(ctx, parent);
    wt_free(ctx, col2sup);
    wt_free(ctx, first);
    wt_free(ctx, weight);
    wt_free(ctx, task);
    wt_free(ctx, mark);
    return st;
}

void wt_chol_one_reference(wt_chol *c, int reference) { c->one_reference = reference != 0; }

double wt_chol_one_bytes(const wt_chol *c)
{
    if (!c->one.ready) return 0.0;
    return (double)c->one.voff[c->L->nsuper] * (c->one.float32 ? 4.0 : 8.0);
}

void wt_chol_split(const wt_chol *c, double *group0, double *group1, double *top)
{
    *group0 = c->one.entries[0];
    *group1 = c->one.entries[1];
    *top = c->one.entries[2];
}

/* Supernode k packed (see one_plan.val), in double or float: column j starts at j (nscol + m) − j (j − 1) / 2
 * with m = nsrow − nscol rows below the diagonal block, and holds L(j, j), L(j + 1 .. nscol − 1, j), then
 * the m rows below. The kernels are written once over the value type and the variant (chol_kernels.inc,
 * included four times below) and cloned for AVX2/AVX-512 like the transforms. The dots keep 8 partial sums in fixed lanes
 * (lane i % 8), added in a fixed order at the end (ISO C: no FMA contraction), so every clone, variant and
 * thread count gives the same bits.
 *
 * Two variants of the same arithmetic: "ref", the plain loops (GCC left the float dots' lanes
 * scalar: one vcvtss2sd + vmulsd + vaddsd per entry), kept as the bit-for-bit oracle of tests/test_chol.c and
 * the baseline of the paired bench (recon.cg9.fit_kernels = "reference"); "fast", the lanes as one GCC vector
 * (8 doubles: one load, conversion, multiply and add per 8 entries in the AVX-512 clone), and the forward
 * block's next two y carried in registers (its divide no longer waits on reloading what a vector store of the
 * previous column wrote). */
#define ONE_COL(j, nscol, m) ((j) * ((nscol) + (m)) - (j) * ((j) - 1) / 2)
typedef double v8d __attribute__((vector_size(64)));
/* 8 lanes of partial sums: an array (ref) or one vector (fast); both are indexed acc[l] */
#define ACC8_ref(x) double x[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
#define ACC8_fast(x) v8d x = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
/* acc[l] += a[i + l] b[i + l], l < 8 */
#define DOT8_ref(LD, acc, a, b, i) for (int l = 0; l < 8; l++) acc[l] += (double)(a)[(i) + l] * (b)[(i) + l]
#define DOT8_fast(LD, acc, a, b, i)                                                                             \
    do {                                                                                                       \
        v8d x_, z_;                                                                                            \
        LD(&x_, (a) + (i));                                                                           \
        load8_d(&z_, (b) + (i));                                                                               \
        acc += x_ * z_;                                                                                        \
    } while (0)
/* the rows below, 4 columns a pass: acc_c[l] += c_c[i + l] w[i + l] */
#define DOT8x4_ref(LD, a0, a1, a2, a3, c0, c1, c2, c3, w, i)                                                    \
    for (int l = 0; l < 8; l++) {                                                                              \
        const double wi = w[(i) + l];                                                                          \
        a0[l] += (double)c0[(i) + l] * wi;                                                                     \
        a1[l] += (double)c1[(i) + l] * wi;                                                                     \
        a2[l] += (double)c2[(i) + l] * wi;                                                                     \
        a3[l] += (double)c3[(i) + l] * wi;                                                                     \
    }
#define DOT8x4_fast(LD, a0, a1, a2, a3, c0, c1, c2, c3, w, i)                                                   \
    do {                                                                                                       \
        v8d wi_, x0_, x1_, x2_, x3_;                                                                           \
        load8_d(&wi_, (w) + (i));                                                                              \
        LD(&x0_, (c0) + (i));                                                                         \
        LD(&x1_, (c1) + (i));                                                                         \
        LD(&x2_, (c2) + (i));                                                                         \
        LD(&x3_, (c3) + (i));                                                                         \
        a0 += x0_ * wi_;                                                                                       \
        a1 += x1_ * wi_;                                                                                       \
        a2 += x2_ * wi_;                                                                                       \
        a3 += x3_ * wi_;                                                                                       \
    } while (0)
/* forward's diagonal block: y[j] /= L(j, j), then y[j + i] −= L(j + i, j) y[j], column after column */
#define FWD_BLOCK_ref(T, v, yk, nscol, m)                                                                        \
    for (int64_t j = 0; j < nscol; j++) {                                                                      \
        const T *restrict col = v + ONE_COL(j, nscol, m);                                                      \
        const double yj = (yk[j] /= (double)col[0]);                                                           \
        const int64_t d = nscol - j;                                                                           \
        for (int64_t i = 1; i < d; i++) yk[j + i] -= (double)col[i] * yj;                                      \
    }
#define FWD_BLOCK_fast(T, v, yk, nscol, m)                                                                       \
    do {                                                                                                       \
        /* y[j] and y[j + 1] as the previous columns left them, in registers: column j's divide waits on one \
         * multiply-subtract, and the value it loads from memory (y[j + 2]) is needed a column later */        \
        double n1 = yk[0], n2 = nscol > 1 ? yk[1] : 0.0;                                                       \
        for (int64_t j = 0; j < nscol; j++) {                                                                  \
            const T *restrict col = v + ONE_COL(j, nscol, m);                                                  \
            const double yj = n1 / (double)col[0];                                                             \
            yk[j] = yj;                                                                                        \
            const int64_t d = nscol - j;                                                                       \
            if (d > 1) n1 = n2 - (double)col[1] * yj;                                                          \
            if (d > 2) n2 = yk[j + 2] - (double)col[2] * yj;                                                   \
            for (int64_t i = 3; i < d; i++) yk[j + i] -= (double)col[i] * yj;                                  \
        }                                                                                                      \
    } while (0)

/* 8 consecutive values (unaligned) as doubles: one vector load (+ conversion) in every clone; through a
 * pointer, since a 64-byte vector return would cross the default clone's ABI */
typedef double wt_v8_d __attribute__((vector_size(64)));
typedef float wt_v8_f __attribute__((vector_size(32)));
static inline __attribute__((always_inline)) void load8_d(v8d *out, const double *restrict a)
{
    wt_v8_d x;
    memcpy(&x, a, sizeof x);
    *out = __builtin_convertvector(x, v8d);
}
static inline __attribute__((always_inline)) void load8_f(v8d *out, const float *restrict a)
{
    wt_v8_f x;
    memcpy(&x, a, sizeof x);
    *out = __builtin_convertvector(x, v8d);
}

#define REAL double
#define LOAD8 load8_d
#define K(name) name##_ref_d
#define ACC8 ACC8_ref
#define DOT8 DOT8_ref
#define DOT8x4 DOT8x4_ref
#define FWD_BLOCK FWD_BLOCK_ref
#include "chol_kernels.inc"
#define REAL float
#define LOAD8 load8_f
#define K(name) name##_ref_f
#define ACC8 ACC8_ref
#define DOT8 DOT8_ref
#define DOT8x4 DOT8x4_ref
#define FWD_BLOCK FWD_BLOCK_ref
#include "chol_kernels.inc"
#define REAL double
#define LOAD8 load8_d
#define K(name) name##_fast_d
#define ACC8 ACC8_fast
#define DOT8 DOT8_fast
#define DOT8x4 DOT8x4_fast
#define FWD_BLOCK FWD_BLOCK_fast
#include "chol_kernels.inc"
#define REAL float
#define LOAD8 load8_f
#define K(name) name##_fast_f
#define ACC8 ACC8_fast
#define DOT8 DOT8_fast
#define DOT8x4 DOT8x4_fast
#define FWD_BLOCK FWD_BLOCK_fast
#include "chol_kernels.inc"

/* Part `part` of the plan, forward or backward; buf: the group's buffer of top rows (forward, groups only). */
static void one_part(const wt_chol *c, int part, int backward, double *w, double *buf, const int *top)
{
    const one_plan *p = &c->one;
    const cholmod_factor *L = c->L;
    const int64_t *super = L->super, *pi = L->pi, *srow = L->s;
    const int64_t a = p->start[part], b = p->start[part + 1];
    for (int64_t q = backward ? b - 1 : a; backward ? q >= a : q < b; q += backward ? -1 : 1) {
        const int64_t k = p->order[q], k1 = super[k], nscol = super[k + 1] - k1, nsrow = pi[k + 1] - pi[k];
        const int64_t *rows = srow + pi[k];
        const void *v = p->float32 ? (const void *)((const float *)p->val + p->voff[k])
                                   : (const void *)((const double *)p->val + p->voff[k]);
        const int kind = 2 * c->one_reference + p->float32;
        if (backward) {
            switch (kind) {
            case 0: backward_fast_d(v, rows, k1, nscol, nsrow, p->y, w); break;
            case 1: backward_fast_f(v, rows, k1, nscol, nsrow, p->y, w); break;
            case 2: backward_ref_d(v, rows, k1, nscol, nsrow, p->y, w); break;
            default: backward_ref_f(v, rows, k1, nscol, nsrow, p->y, w); break;
            }
        } else {
            switch (kind) {
            case 0: forward_fast_d(v, rows, k1, nscol, nsrow, p->y, w, buf, top); break;
            case 1: forward_fast_f(v, rows, k1, nscol, nsrow, p->y, w, buf, top); break;
            case 2: forward_ref_d(v, rows, k1, nscol, nsrow, p->y, w, buf, top); break;
            default: forward_ref_f(v, rows, k1, nscol, nsrow, p->y, w, buf, top); break;
            }
        }
    }
}

/* The two thread groups' parts of one sweep side by side (forward: each into its own update buffer of the top
 * rows; backward: each writes its own columns only), one group per thread when there are two. */
static void groups(const wt_chol *c, one_plan *p, int backward)
{
#pragma omp parallel num_threads(p->nthreads)
    {
#ifdef _OPENMP
        const int id = omp_get_thread_num(), nt = omp_get_num_threads();
#else
        const int id = 0, nt = 1;
#endif
        for (int g = id; g < 2; g += nt)
            one_part(c, g, backward, p->work[g], backward ? NULL : p->buf[g], backward ? NULL : p->is_top);
    }
}

int wt_chol_solve_one(wt_chol *c, const double *b, double *x)
{
    one_plan *p = &c->one;
    if (!p->ready) return WT_ERROR(c->ctx, WT_ERR_INVALID, "wt_chol_solve_one: called before wt_chol_prepare_one");
    const int64_t n = c->n, *perm = c->L->Perm;
    for (int64_t i = 0; i < n; i++) p->y[i] = b[perm[i]]; /* P b */
    for (int g = 0; g < 2; g++)
        for (int64_t m = 0; m < p->ntop_rows; m++) p->buf[g][p->top_rows[m]] = 0.0;
    /* forward: the two groups side by side, then their updates of the top rows (group 0's, then group 1's:
     * the same order on any number of threads), then the top part */
    groups(c, p, 0);
    for (int64_t m = 0; m < p->ntop_rows; m++) {
        const int64_t r = p->top_rows[m];
        p->y[r] -= p->buf[0][r];
        p->y[r] -= p->buf[1][r];
    }
    one_part(c, 2, 0, p->work[0], NULL, NULL);
    /* backward: the top part, then the groups side by side (each writes its own columns only) */
    one_part(c, 2, 1, p->work[0], NULL, NULL);
    groups(c, p, 1);
    for (int64_t i = 0; i < n; i++) x[perm[i]] = p->y[i]; /* Pᵀ z */
    return WT_OK;
}
