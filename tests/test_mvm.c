/* tests/test_mvm.c: the offline MVM builder (builder/mvm_build.c, core/la/chol.c; SPEC §9): the assembled
 * Ã against the matrix-free slopes, the factorised M = N + B Q Bᵀ against the matrix-free normal
 * operator and PCG, R s against the converged matrix-free reconstructors (pcg3 and cg9), RÂ, the
 * orderings, the memory budget and the error paths. */
#include <cblas.h>

#include "core/la/chol.h"
#include "core/model/fitting.h"
#include "core/model/interaction.h"
#include "builder/mvm_build.h"
#include "core/model/system.h"
#include "core/model/params.h"
#include "core/model/precond.h"
#include "core/model/tomography.h"
#include "core/op/noise.h"
#include "core/op/shack_hartmann.h"
#include "testmodel.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

typedef struct {
    wt_context *ctx;
    wt_config *cfg;
    wt_system *sys;
    wt_tomography *t;
    wt_precond *p; /* the variant's preconditioner */
    int64_t n, ns, na;
} fixture;

/* The default prior is the full one (N dense); the fixture takes the paper's for both variants (the sparse
 * CHOLMOD path) unless a test's settings ask for the full one (setup_v), the same for the matrix and the
 * matrix-free operator it is checked against. */
static void setup(fixture *f, int cg9, int nset, const char *const *set)
{
    f->ctx = tu_context();
    const char *all[16] = {"recon.prior=\"paper\""};
    ck_assert_int_lt(nset, 16);
    for (int i = 0; i < nset; i++) all[i + 1] = set[i];
    ck_assert_msg(wt_config_read(f->ctx, DEMO, nset + 1, all, &f->cfg) == WT_OK, "%s", wt_error_message(f->ctx));
    ck_assert_msg(wt_system_alloc(f->ctx, f->cfg, &f->sys) == WT_OK, "%s", wt_error_message(f->ctx));
    wt_tomography_params tp;
    wt_tomography_params_from_config(f->cfg, &tp);
    const wt_recon_variant_config *v = cg9 ? &f->cfg->cg9 : &f->cfg->pcg3;
    tp.space = v->preconditioner == WT_PRECOND_FOURIER; /* (as core/model/params.c: fourier filters the layers' values) */
    ck_assert_msg(wt_tomography_alloc(f->ctx, f->sys, v, cg9 ? "cg9" : "pcg3", &tp, &f->t) == WT_OK, "%s",
                  wt_error_message(f->ctx));
    const wt_precond_params pp = wt_precond_params_from_variant(v);
    ck_assert_msg(wt_precond_alloc(f->ctx, f->t, &pp, &f->p) == WT_OK, "%s", wt_error_message(f->ctx));
    f->n = wt_tomography_nunknowns(f->t);
    f->ns = f->sys->nslopes;
    f->na = f->sys->nact;
}

static void teardown(fixture *f)
{
    wt_precond_free(f->p);
    wt_tomography_free(f->t);
    wt_system_free(f->sys);
    wt_config_free(f->ctx, f->cfg);
    wt_context_free(f->ctx);
}

static void build(fixture *f, int cg9, wt_mvm **mv)
{
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    opt.commands = cg9 ? WT_MVM_FITTING : WT_MVM_LAYER_VALUES;
    opt.fit_regularization = f->cfg->cg9.fit_regularization;
    opt.fit_sampling = f->cfg->cg9.fit_sampling;
    opt.block = 100; /* several blocks, the last one partial: the block loop's bookkeeping is exercised */
    ck_assert_msg(wt_mvm_build(f->ctx, f->t, &opt, mv) == WT_OK, "%s", wt_error_message(f->ctx));
}

/* y = R s with float32 R, accumulated in double */
static void apply_r(const wt_mvm *mv, const double *s, double *y)
{
    for (int64_t i = 0; i < mv->nact; i++) {
        double acc = 0.0;
        const float *row = mv->R + (size_t)i * mv->nslopes;
        for (int64_t j = 0; j < mv->nslopes; j++) acc += (double)row[j] * s[j];
        y[i] = acc;
    }
}

/* Slopes of real size [rad]: Ã of a random coefficient vector plus white noise. */
static void test_slopes(fixture *f, double *s, unsigned long seed)
{
    double *c = malloc(f->n * sizeof *c), *e = malloc(f->ns * sizeof *e);
    tu_randn(c, f->n, seed);
    for (int64_t i = 0; i < f->n; i++) c[i] *= 1e-7;
    tu_tomo_slopes(f->t, c, s);
    double rms = tu_norm(s, f->ns) / sqrt((double)f->ns);
    tu_randn(e, f->ns, seed + 1);
    for (int64_t i = 0; i < f->ns; i++) s[i] += 0.3 * rms * e[i];
    free(c);
    free(e);
}

/* Ã assembled column by column from the wavelet templates equals the matrix-free Γ P W⁻¹. Both are
 * sums of a few hundred double products per slope: 1e-12 relative is rounding, any wrong template
 * shift, layer offset, sensor row offset or weight is O(1). */
START_TEST(test_atilde_matches_slopes)
{
    for (int v = 0; v < 2; v++) {
        fixture f;
        setup(&f, v, 0, NULL);
        wt_sparse *A = NULL;
        ck_assert_msg(wt_mvm_assemble_atilde(f.ctx, f.t, &A) == WT_OK, "%s", wt_error_message(f.ctx));
        ck_assert_int_eq(A->nrow, f.ns);
        ck_assert_int_eq(A->ncol, f.n);
        double *c = malloc(f.n * sizeof *c), *y1 = calloc(f.ns, sizeof *y1), *y2 = malloc(f.ns * sizeof *y2);
        tu_randn(c, f.n, 21 + v);
        wt_sparse_apply(A, 1.0, c, y1);
        tu_tomo_slopes(f.t, c, y2);
        ck_assert_double_gt(tu_norm(y2, f.ns), 0.0);
        ck_assert_double_le(tu_rel_diff(y1, y2, f.ns), 1e-12);
        /* per sensor too, so that a small sensor (the NGS) cannot hide in the norm of the LGS */
        for (int m = 0; m < f.sys->nsensors; m++) {
            const wt_sensor *s = &f.sys->sensors[m];
            ck_assert_msg(tu_rel_diff(y1 + s->offset, y2 + s->offset, s->nslopes) <= 1e-12, "variant %d sensor %s", v,
                          s->name);
        }
        /* every column sorted (CHOLMOD and the builder rely on it) */
        for (int64_t j = 0; j < A->ncol; j++)
            for (int64_t k = A->colptr[j] + 1; k < A->colptr[j + 1]; k++) ck_assert(A->rowind[k] > A->rowind[k - 1]);
        free(c);
        free(y1);
        free(y2);
        wt_sparse_free(A);
        teardown(&f);
    }
}
END_TEST

/* The full prior (α W C_φ⁻¹ Wᵀ on every layer) makes N dense: the builder forms and factorises it by
 * LAPACK instead of CHOLMOD. The tests below run both paths: v = 0, 1 pcg3 / cg9 with the diagonal
 * prior, v = 2, 3 the same with the full one. */
static const char *const full_prior[2][1] = {{"recon.pcg3.prior=\"full\""}, {"recon.cg9.prior=\"full\""}};
static void setup_v(fixture *f, int v) { setup(f, v & 1, v >> 1, v >> 1 ? full_prior[v & 1] : NULL); }

static wt_mvm_normal *normal(fixture *f)
{
    wt_mvm_normal *nm = NULL;
    ck_assert_msg(wt_mvm_normal_alloc(f->ctx, f->t, NULL, 0.0, 1, &nm) == WT_OK, "%s", wt_error_message(f->ctx));
    return nm;
}

/* N + B Q Bᵀ is the matrix-free M (tip-tilt removal and NGS in the low-rank part): same sums in another
 * order, 1e-12 relative. The rank is 4 per LGS plus the NGS slopes. With the full prior the dense N's
 * layer blocks are the operator's own prior columns (FFT round trips: rounding 1e-15 of the prior). */
START_TEST(test_normal_apply_matches)
{
    for (int v = 0; v < 4; v++) {
        fixture f;
        setup_v(&f, v);
        ck_assert_int_eq(wt_tomography_full_prior(f.t), v >> 1);
        wt_mvm_normal *nm = normal(&f);
        int rank = 4 * f.sys->nlgs;
        for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
        ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
        ck_assert_int_eq(wt_mvm_normal_size(nm), f.n);
        double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2);
        for (int trial = 0; trial < 2; trial++) {
            tu_randn(x, f.n, 31 + trial);
            ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
            tu_tomo_apply(f.t, x, y2);
            ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
        }
        wt_mvm_stats st;
        wt_mvm_normal_stats(nm, &st);
        ck_assert_int_gt(st.nnz_normal, f.n);
        ck_assert_double_ge(st.nnz_factor, (double)st.nnz_normal); /* L holds at least N's upper pattern */
        if (v >> 1) {
            ck_assert_str_eq(st.ordering, "dense (LAPACK)");
            ck_assert_double_eq(st.nnz_factor, 0.5 * (double)f.n * (double)(f.n + 1));
        }
        free(x);
        free(y1);
        free(y2);
        wt_mvm_normal_free(nm);
        teardown(&f);
    }
}
END_TEST

/* M⁻¹ b by CHOLMOD (LAPACK with the full prior) + Woodbury equals PCG run to 1e-12. The direct solve's own residual through the
 * matrix-free M must be at rounding level (1e-10 allows κ ~ 1e5 times ε); the two solutions agree to
 * 1e-9 (PCG's residual 1e-12 times the condition number of M). Several right-hand sides at once check
 * the block path. */
START_TEST(test_normal_solve_matches_pcg)
{
    for (int v = 0; v < 4; v++) {
        fixture f;
        setup_v(&f, v);
        wt_mvm_normal *nm = normal(&f);
        const int k = 3;
        double *s = malloc(f.ns * sizeof *s), *b = malloc(k * f.n * sizeof *b), *x = malloc(k * f.n * sizeof *x),
               *xp = calloc(f.n, sizeof *xp), *r = malloc(f.n * sizeof *r);
        for (int j = 0; j < k; j++) {
            test_slopes(&f, s, 41 + 7 * j);
            tu_tomo_rhs(f.t, s, b + j * f.n);
        }
        ck_assert_int_eq(wt_mvm_normal_solve(nm, k, b, x), WT_OK);
        for (int j = 0; j < k; j++) {
            tu_tomo_apply(f.t, x + j * f.n, r);
            ck_assert_double_le(tu_rel_diff(r, b + j * f.n, f.n), 1e-10);
        }
        test_slopes(&f, s, 41 + 7 * (k - 1));
        wt_pcg_result res;
        int st = wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, xp, 20000, 1e-12, NULL, &res);
        ck_assert_msg(st == WT_OK, "PCG did not converge: %d its, %g", res.iterations, res.rel_resid);
        ck_assert_double_le(tu_rel_diff(x + (k - 1) * f.n, xp, f.n), 1e-9);
        free(s);
        free(b);
        free(x);
        free(xp);
        free(r);
        wt_mvm_normal_free(nm);
        teardown(&f);
    }
}
END_TEST

/* pcg3 commands computed independently of the builder: at each active actuator's position the layer at
 * the DM's altitude, plus the layers between this DM and its neighbours weighted by the hat function of
 * altitude (1 at this DM, 0 at the next), all read by bilinear interpolation (points at x0 + i δ). */
static void pcg3_commands(fixture *f, const double *c, double *a)
{
    double *phi = malloc(f->n * sizeof *phi);
    wt_tomography_layers(f->t, c, phi);
    const wt_dm *dm = f->sys->dm;
    int64_t q = 0;
    for (int k = 0; k < dm->ndms; k++) {
        double h = dm->altitude[k], below = -1.0, above = -1.0; /* the neighbouring DM altitudes (< 0: none) */
        for (int j = 0; j < dm->ndms; j++) {
            double hj = dm->altitude[j];
            if (hj < h && (below < 0.0 || hj > below)) below = hj;
            if (hj > h && (above < 0.0 || hj < above)) above = hj;
        }
        const wt_grid *dg = &dm->grid[k];
        for (int iy = 0; iy < dg->ny; iy++)
            for (int ix = 0; ix < dg->nx; ix++) {
                if (!dm->active[k][ix + dg->nx * iy]) continue;
                double x = dg->x0 + ix * dg->dx, y = dg->y0 + iy * dg->dx, v = 0.0;
                for (int l = 0; l < wt_tomography_nlayers(f->t); l++) {
                    double hl = wt_tomography_layer_altitude(f->t, l), w;
                    if (hl >= h) w = above < 0.0 ? 1.0 : fmax(0.0, 1.0 - (hl - h) / (above - h));
                    else w = below < 0.0 ? 1.0 : fmax(0.0, 1.0 - (h - hl) / (h - below));
                    if (w == 0.0) continue;
                    const wt_grid *lg = wt_tomography_layer_grid(f->t, l);
                    const double *layer = phi + wt_tomography_layer_offset(f->t, l);
                    double gx = (x - lg->x0) / lg->dx, gy = (y - lg->y0) / lg->dx;
                    int i0 = (int)floor(gx + 1e-9), j0 = (int)floor(gy + 1e-9);
                    double fx = fmax(0.0, gx - i0), fy = fmax(0.0, gy - j0);
                    double v00 = layer[i0 + lg->nx * j0];
                    double v10 = fx > 1e-9 ? layer[i0 + 1 + lg->nx * j0] : 0.0;
                    double v01 = fy > 1e-9 ? layer[i0 + lg->nx * (j0 + 1)] : 0.0;
                    double v11 = fx > 1e-9 && fy > 1e-9 ? layer[i0 + 1 + lg->nx * (j0 + 1)] : 0.0;
                    v += w * ((1 - fx) * (1 - fy) * v00 + fx * (1 - fy) * v10 + (1 - fx) * fy * v01 + fx * fy * v11);
                }
                a[q++] = v;
            }
    }
    ck_assert_int_eq(q, f->na);
    free(phi);
}

/* The issue test: R s equals the commands of the matrix-free reconstructor run to convergence
 * (PCG to 1e-12; cg9's fitting by CG to 1e-13). R is float32: relative rounding 6e-8 per entry, grown
 * by the cancellation in R s (‖|R| |s|‖ / ‖R s‖ ~ 10–100) to ≤ 1e-6; the converged iterations add
 * ~1e-9. The issue asks 1e-4; 1e-5 is tighter and still a factor 10 above that bound (2.4e-8 measured
 * on the demo). Any wrong row, column, weight or fitting ε is O(1e-3) or more. */
static void check_r_matches(int cg9, int nset, const char *const *set)
{
    fixture f;
    setup(&f, cg9, nset, set);
    wt_mvm *mv = NULL;
    build(&f, cg9, &mv);
    ck_assert_int_eq(mv->nact, f.na);
    ck_assert_int_eq(mv->nslopes, f.ns);
    double *s = malloc(f.ns * sizeof *s), *c = calloc(f.n, sizeof *c), *a = calloc(f.na, sizeof *a),
           *ar = malloc(f.na * sizeof *ar);
    for (int trial = 0; trial < 2; trial++) {
        test_slopes(&f, s, 51 + trial);
        memset(c, 0, f.n * sizeof *c);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c, 20000, 1e-12, NULL, &res), WT_OK);
        if (!cg9) {
            pcg3_commands(&f, c, a);
        } else {
            wt_fitting *fit = NULL;
            wt_grid grids[WT_MAX_LAYERS];
            double alts[WT_MAX_LAYERS];
            int L = wt_tomography_nlayers(f.t);
            for (int l = 0; l < L; l++) {
                grids[l] = *wt_tomography_layer_grid(f.t, l);
                alts[l] = wt_tomography_layer_altitude(f.t, l);
            }
            wt_fitting_params fp = {.regularization = f.cfg->cg9.fit_regularization, .sampling = f.cfg->cg9.fit_sampling};
            ck_assert_int_eq(wt_fitting_alloc(f.ctx, f.sys, L, grids, alts, &fp, &fit), WT_OK);
            double *phi = malloc(f.n * sizeof *phi);
            wt_tomography_layers(f.t, c, phi);
            memset(a, 0, f.na * sizeof *a);
            ck_assert_int_eq(wt_fitting_solve(fit, phi, a, 20000, 1e-13, NULL, &res), WT_OK);
            free(phi);
            wt_fitting_free(fit);
        }
        apply_r(mv, s, ar);
        ck_assert_double_gt(tu_norm(a, f.na), 0.0);
        ck_assert_double_le(tu_rel_diff(ar, a, f.na), 1e-5);
    }
    free(s);
    free(c);
    free(a);
    free(ar);
    wt_mvm_free(mv);
    teardown(&f);
}

START_TEST(test_r_matches_pcg3) { check_r_matches(0, 0, NULL); }
END_TEST

/* The same with layers between the DMs (1 m layers at 1 and 8 km, split onto the DMs around them and
 * interpolated at DM 1's 0.5 m actuators): the MVM stays the exact MAP of the PCG-3 system. */
static const char *const pcg3_split[] = {"recon.pcg3.layer_altitudes_m=[0.0, 1000.0, 4000.0, 8000.0, 12700.0]",
                                         "recon.pcg3.layer_spacing_m=[0.5, 1.0, 1.0, 1.0, 1.0]",
                                         "recon.pcg3.layer_size=[32, 16, 16, 32, 32]"};
START_TEST(test_r_matches_pcg3_split) { check_r_matches(0, 3, pcg3_split); }
END_TEST

START_TEST(test_r_matches_cg9) { check_r_matches(1, 0, NULL); }
END_TEST

/* The full prior: the dense path's R is the converged matrix-free MAP with the full prior, both variants. */
START_TEST(test_r_matches_full_prior)
{
    check_r_matches(0, 1, full_prior[0]);
    check_r_matches(1, 1, full_prior[1]);
}
END_TEST

/* RÂ = R · Â with the dense Â: the builder forms it from the double-precision rows before rounding,
 * so the difference to float R times Â is float rounding of R (6e-8) amplified by cancellation in the
 * sums; 1e-5 relative per row. */
START_TEST(test_ra_matches)
{
    fixture f;
    setup(&f, 0, 0, NULL);
    wt_mvm *mv = NULL;
    build(&f, 0, &mv);
    wt_interaction *ia = NULL;
    ck_assert_int_eq(wt_interaction_alloc(f.ctx, f.sys, &ia), WT_OK);
    double *ahat = calloc(f.ns * f.na, sizeof *ahat), *e = calloc(f.na, sizeof *e), *rf = malloc(f.ns * f.na * sizeof *rf),
           *ref = malloc(f.na * f.na * sizeof *ref), *got = malloc(f.na * sizeof *got);
    for (int64_t k = 0; k < f.na; k++) { /* dense Â column by column, matrix-free */
        e[k] = 1.0;
        wt_interaction_apply(ia, 1.0, e, ahat + k * f.ns);
        e[k] = 0.0;
    }
    for (int64_t i = 0; i < f.na * f.ns; i++) rf[i] = mv->R[i];
    /* ref = R Â: (na x ns row-major) · (ns x na column-major) */
    cblas_dgemm(CblasRowMajor, CblasNoTrans, CblasTrans, (int)f.na, (int)f.na, (int)f.ns, 1.0, rf, (int)f.ns, ahat,
                (int)f.ns, 0.0, ref, (int)f.na);
    for (int64_t i = 0; i < f.na; i++) {
        for (int64_t k = 0; k < f.na; k++) got[k] = mv->RA[i * f.na + k];
        ck_assert_msg(tu_rel_diff(got, ref + i * f.na, f.na) <= 1e-5, "row %lld: %g", (long long)i,
                      tu_rel_diff(got, ref + i * f.na, f.na));
    }
    free(ahat);
    free(e);
    free(rf);
    free(ref);
    free(got);
    wt_interaction_free(ia);
    wt_mvm_free(mv);
    teardown(&f);
}
END_TEST

/* Orderings: rows follow the actuators DM by DM in grid order, columns the slopes sensor by sensor.
 * A ground-DM actuator's command depends most on the ground-layer gradient next to it, so in an LGS
 * block of its row the subaperture of largest weight |R_x| + |R_y| is usually one of the four that
 * share the actuator's corner (0.35 m away; 84 % of the cases on the demo, the rest pulled elsewhere by
 * the global tip-tilt and the other layers); a transposed or shuffled layout makes that a 4/nsub
 * chance. Checked on the interior actuators of DM 1 (the rim is distorted by the pupil edge),
 * requiring 70 %. */
START_TEST(test_orderings)
{
    fixture f;
    setup(&f, 0, 0, NULL);
    wt_mvm *mv = NULL;
    build(&f, 0, &mv);
    ck_assert_int_eq(mv->nact, f.sys->nact);
    ck_assert_int_eq(mv->nslopes, f.sys->nslopes);
    const wt_grid *dg = &f.sys->dm->grid[0];
    const double rin = 0.5 * f.cfg->obstruction * f.cfg->diameter + 1.0, rout = 0.5 * f.cfg->diameter - 1.0;
    int good = 0, total = 0;
    int64_t q = 0;
    for (int iy = 0; iy < dg->ny; iy++)
        for (int ix = 0; ix < dg->nx; ix++) {
            if (!f.sys->dm->active[0][ix + dg->nx * iy]) continue;
            int64_t i = q++;
            double x = dg->x0 + ix * dg->dx, y = dg->y0 + iy * dg->dx, r = hypot(x, y);
            if (r < rin || r > rout) continue;
            for (int m = 0; m < f.sys->nlgs; m++) {
                const wt_sensor *s = &f.sys->sensors[m];
                const float *row = mv->R + i * f.ns + s->offset;
                int best = 0;
                double bw = -1.0;
                for (int k = 0; k < s->nsub; k++) {
                    double w = fabs(row[k]) + fabs(row[s->nsub + k]);
                    if (w > bw) bw = w, best = k;
                }
                double cx, cy;
                wt_shack_hartmann_centre(s->sh, best, &cx, &cy);
                good += hypot(cx - x, cy - y) <= 0.75 * f.sys->d;
                total++;
            }
        }
    ck_assert_int_gt(total, 20);
    ck_assert_msg(good >= 0.7 * total, "only %d of %d largest weights next to their actuator", good, total);
    wt_mvm_free(mv);
    teardown(&f);
}
END_TEST

/* The memory estimate refuses before allocating: a 1 MB budget stops at the first check, a budget one
 * byte below the build's own peak estimate stops at a later one; both name the bytes. */
START_TEST(test_budget_refuses)
{
    fixture f;
    setup(&f, 0, 0, NULL);
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    wt_mvm *mv = NULL;
    opt.memory_budget = 1e6;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_NOMEM);
    ck_assert_ptr_null(mv);
    const char *msg = wt_error_message(f.ctx);
    ck_assert_msg(strstr(msg, "bytes") && strstr(msg, "1000000"), "message: %s", msg);
    opt.memory_budget = 0.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_OK);
    double peak = mv->stats.peak_estimate;
    ck_assert_double_gt(peak, 4.0 * f.na * f.ns); /* R alone */
    ck_assert_double_gt(mv->stats.nnz_factor, 0.0);
    ck_assert_double_gt(mv->stats.t_total, 0.0);
    wt_mvm_free(mv);
    mv = NULL;
    opt.memory_budget = floor(peak) - 1.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_NOMEM);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "bytes"), "message: %s", wt_error_message(f.ctx));
    opt.memory_budget = peak + 1.0;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_OK);
    wt_mvm_free(mv);
    teardown(&f);
}
END_TEST

/* A stop request between solve blocks ends the build with WT_ERR_INTERRUPTED, nothing returned, the message
 * naming the rows done; polled once per block but the last, so a stop that never fires costs the same bits. */
static int stop_after(void *user)
{
    int *calls = user;
    return ++*calls >= 2;
}
START_TEST(test_stop_between_blocks)
{
    fixture f;
    setup(&f, 0, 0, NULL);
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    opt.block = 8; /* several blocks on the test system */
    ck_assert_int_gt(f.na, 3 * opt.block);
    int calls = 0;
    opt.stop = stop_after, opt.stop_user = &calls;
    wt_mvm *mv = NULL;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_INTERRUPTED);
    ck_assert_ptr_null(mv);
    ck_assert_int_eq(calls, 2);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "after 16 of"), "message: %s", wt_error_message(f.ctx));
    teardown(&f);
}
END_TEST

/* pcg3 needs a layer reaching every DM (a layer goes to the DMs around its altitude): layers at 0 and
 * 4 km only leave the 12.7 km DM 3 without any, refused naming the DM before any heavy work. */
START_TEST(test_pcg3_layer_mismatch_refused)
{
    const char *set[] = {"recon.pcg3.layer_altitudes_m=[0.0, 4000.0]", "recon.pcg3.layer_spacing_m=[0.5, 1.0]",
                         "recon.pcg3.layer_size=[32, 16]"};
    fixture f;
    setup(&f, 0, 3, set);
    wt_mvm_options opt;
    wt_mvm_options_default(&opt);
    wt_mvm *mv = NULL;
    ck_assert_int_eq(wt_mvm_build(f.ctx, f.t, &opt, &mv), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(f.ctx), "DM 3"), "message: %s", wt_error_message(f.ctx));
    teardown(&f);
}
END_TEST

/* CHOLMOD's failures come back as statuses naming the call: an indefinite matrix is WT_ERR_NUMERIC.
 * A small SPD one is solved to rounding. */
START_TEST(test_chol_errors_and_solve)
{
    wt_context *ctx = tu_context();
    wt_triplet *tr = NULL;
    wt_sparse *a = NULL;
    wt_chol *ch = NULL;
    /* [[1, 2], [2, 1]]: eigenvalues 3 and −1 */
    ck_assert_int_eq(wt_triplet_alloc(ctx, 2, 2, 3, &tr), WT_OK);
    wt_triplet_add(tr, 0, 0, 1.0);
    wt_triplet_add(tr, 0, 1, 2.0);
    wt_triplet_add(tr, 1, 1, 1.0);
    ck_assert_int_eq(wt_triplet_compress(tr, &a), WT_OK);
    wt_triplet_free(tr);
    ck_assert_int_eq(wt_chol_analyze(ctx, a, &ch), WT_OK);
    ck_assert_int_eq(wt_chol_factorize(ch, a), WT_ERR_NUMERIC);
    ck_assert_msg(strstr(wt_error_message(ctx), "cholmod_l_factorize"), "%s", wt_error_message(ctx));
    double b[2] = {1, 1}, x[2];
    ck_assert_int_eq(wt_chol_solve(ch, 1, b, 2, x, 2), WT_ERR_INVALID);
    wt_chol_free(ch);
    wt_sparse_free(a);
    /* [[4, 1], [1, 3]] x = [1, 2]: x = [1/11, 7/11] */
    ck_assert_int_eq(wt_triplet_alloc(ctx, 2, 2, 3, &tr), WT_OK);
    wt_triplet_add(tr, 0, 0, 4.0);
    wt_triplet_add(tr, 0, 1, 1.0);
    wt_triplet_add(tr, 1, 1, 3.0);
    ck_assert_int_eq(wt_triplet_compress(tr, &a), WT_OK);
    wt_triplet_free(tr);
    ck_assert_int_eq(wt_chol_analyze(ctx, a, &ch), WT_OK);
    ck_assert_int_eq(wt_chol_factorize(ch, a), WT_OK);
    b[1] = 2.0;
    ck_assert_int_eq(wt_chol_solve(ch, 1, b, 2, x, 2), WT_OK);
    ck_assert_rel(x[0], 1.0 / 11.0, 1e-14, 0.0);
    ck_assert_rel(x[1], 7.0 / 11.0, 1e-14, 0.0);
    wt_chol_info ci;
    wt_chol_info_get(ch, &ci);
    ck_assert_double_eq(ci.nnz_factor, 3.0);
    ck_assert_int_eq(ci.factorized, 1);
    wt_chol_free(ch);
    wt_sparse_free(a);
    wt_context_free(ctx);
}
END_TEST

/* ---- LGS focus removal (recon.lgs_focus_removal) ----------------------------------------------------- */
static const char *const focus_on[] = {"recon.lgs_focus_removal=true"};

/* The factorised normal equations' solve of the right-hand side of random slopes (s, b, x: scratch) equals PCG run
 * to convergence (xp) within 1e-9 */
static void solve_matches_pcg(fixture *f, wt_mvm_normal *nm, double *s, double *b, double *x, double *xp,
                              unsigned long seed)
{
    test_slopes(f, s, seed);
    tu_tomo_rhs(f->t, s, b);
    ck_assert_int_eq(wt_mvm_normal_solve(nm, 1, b, x), WT_OK);
    wt_pcg_result res;
    ck_assert_int_eq(wt_tomography_solve(f->t, wt_precond_pcg(f->p), s, xp, 20000, 1e-12, NULL, &res), WT_OK);
    ck_assert_double_le(tu_rel_diff(x, xp, f->n), 1e-9);
}

/* The factorised M with the focus in the low rank (6 per LGS) is the matrix-free M (1e-12, as above), and its
 * solve is PCG's converged one (1e-9, as above). */
START_TEST(test_focus_normal_matches)
{
    fixture f;
    setup(&f, 0, 1, focus_on);
    wt_mvm_normal *nm = normal(&f);
    int rank = 6 * f.sys->nlgs;
    for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
    ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
    double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2),
           *s = malloc(f.ns * sizeof *s), *xp = calloc(f.n, sizeof *xp);
    tu_randn(x, f.n, 71);
    ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
    tu_tomo_apply(f.t, x, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
    solve_matches_pcg(&f, nm, s, y1, x, xp, 72);
    free(x), free(y1), free(y2), free(s), free(xp);
    wt_mvm_normal_free(nm);
    teardown(&f);
}
END_TEST

/* R s = the converged pcg3 with the focus removal (the bound of check_r_matches) */
START_TEST(test_r_matches_pcg3_focus) { check_r_matches(0, 1, focus_on); }
END_TEST

/* ph = x² + y² on the sensing grid (a focus); returns the scale that makes its slopes on the first LGS 10 times the
 * rms of the slopes s */
static double focus_phase(const fixture *f, const double *s, double *ph)
{
    const wt_grid *g = &f->sys->sense_grid;
    const double rms = tu_norm(s, f->ns) / sqrt((double)f->ns);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            ph[ix + (int64_t)g->nx * iy] = x * x + y * y;
        }
    const wt_sensor *l1 = &f->sys->sensors[0];
    double *fs = calloc(l1->nslopes, sizeof *fs);
    wt_shack_hartmann_apply(l1->sh, 1.0, ph, fs);
    const double a = 10.0 * rms / (tu_norm(fs, l1->nslopes) / sqrt((double)l1->nslopes));
    free(fs);
    return a;
}

/* The LGS slopes of a pure focus phase φ = a r² (on the sensors' sample grid, through each LGS's own Γ: what a
 * sodium altitude change puts on every LGS) added to the slopes: with the focus removal the right-hand side
 * changes by rounding only (Ĉ⁻¹ Γ φ = 0: the Fried slopes of a quadratic are exactly ∝ the subaperture centres),
 * so the converged reconstruction by rounding times M's conditioning (1e-9); without it the reconstruction moves
 * by O(1) of its size (the focus is 10 times the slopes' rms). */
START_TEST(test_focus_slopes_ignored)
{
    for (int on = 0; on < 2; on++) {
        fixture f;
        setup(&f, 0, on, focus_on);
        const wt_grid *g = &f.sys->sense_grid;
        double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s),
               *s2 = malloc(f.ns * sizeof *s2), *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2),
               *c1 = calloc(f.n, sizeof *c1), *c2 = calloc(f.n, sizeof *c2);
        test_slopes(&f, s, 81);
        memcpy(s2, s, f.ns * sizeof *s);
        const double a = focus_phase(&f, s, ph);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, a, ph, s2 + l->offset);
        }
        tu_tomo_rhs(f.t, s, b1);
        tu_tomo_rhs(f.t, s2, b2);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c1, 20000, 1e-12, NULL, &res), WT_OK);
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s2, c2, 20000, 1e-12, NULL, &res), WT_OK);
        if (on) {
            /* the rhs sums ~ns terms of the 10× larger slopes: rounding ~ns ε × 10 of b */
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
            ck_assert_double_le(tu_rel_diff(c2, c1, f.n), 1e-9);
        } else {
            ck_assert_double_gt(tu_rel_diff(c2, c1, f.n), 0.1);
        }
        free(ph), free(s), free(s2), free(b1), free(b2), free(c1), free(c2);
        teardown(&f);
    }
}
END_TEST

/* Without an NGS that measures focus (three 1x1 tip-tilt sensors) the key is refused, naming it. */
START_TEST(test_focus_refused_without_ngs_focus)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_tomography *t = NULL;
    const char *set[] = {"recon.prior=\"paper\"", "recon.lgs_focus_removal=true", "ngs.subapertures=[1, 1, 1]"};
    ck_assert_msg(wt_config_read(ctx, DEMO, 3, set, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_tomography_params tp;
    wt_tomography_params_from_config(cfg, &tp);
    ck_assert_int_eq(wt_tomography_alloc(ctx, sys, &cfg->pcg3, "pcg3", &tp, &t), WT_ERR_CONFIG);
    ck_assert_ptr_null(t);
    ck_assert_msg(strstr(wt_error_message(ctx), "recon.lgs_focus_removal") != NULL, "%s", wt_error_message(ctx));
    ck_assert_msg(strstr(wt_error_message(ctx), "2x2") != NULL, "%s", wt_error_message(ctx));
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The layer-binning model error with the focus removal: the same draws' slopes, less their focus, so each LGS's
 * σ²_e is smaller by Σ (fᵀs)² / (2 nsub · draws) — positive for these random screens — and still > 0. */
START_TEST(test_focus_model_error)
{
    static const char *const me[] = {"recon.model_error=true", "recon.lgs_focus_removal=true",
                                     "recon.lgs_focus_mode=\"common\""};
    fixture off, on, co;
    setup(&off, 0, 1, me);
    setup(&on, 0, 2, me);
    setup(&co, 0, 3, me);
    for (int m = 0; m < off.sys->nlgs; m++) {
        const double a = wt_tomography_model_error(off.t, m), b = wt_tomography_model_error(on.t, m),
                     c = wt_tomography_model_error(co.t, m);
        ck_assert_double_gt(a, 0.0);
        ck_assert_double_gt(b, 0.0);
        ck_assert_msg(b < a, "LGS %d: %g with the focus removed, %g without", m, b, a);
        /* the common mode takes 1/n_LGS of each LGS's focus power: exactly between (rounding of the sums) */
        ck_assert_double_le(fabs(c - (a - (a - b) / off.sys->nlgs)), 1e-12 * a);
    }
    teardown(&off);
    teardown(&on);
    teardown(&co);
}
END_TEST


/* ---- The LGS's common focus only (recon.lgs_focus_mode = "common") -------------------------------------------- */
static const char *const common_on[] = {"recon.lgs_focus_removal=true", "recon.lgs_focus_mode=\"common\""};

/* y = Ĉ⁻¹ x over every sensor as the tomography weighs: the sensors' own weights plus the LGS's coupling term */
static void weigh_all(const fixture *f, const double *x, double *y)
{
    memset(y, 0, f->ns * sizeof *y);
    for (int m = 0; m < f->sys->nsensors; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        wt_noise_apply_weight(wt_tomography_noise(f->t, m), 1.0, x + s->offset, y + s->offset);
    }
    wt_tomography_weight_common(f->t, x, y);
}

/* x ← P x on the LGS slopes: each LGS's tip and tilt, then the common direction f_c = (e_1 … e_n)/√n, removed */
static void project_common(const fixture *f, double *x)
{
    const double *e = wt_tomography_common_focus(f->t);
    double a = 0.0;
    for (int m = 0; m < f->sys->nlgs; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        for (int h = 0; h < 2; h++) {
            double mean = 0.0;
            for (int i = 0; i < s->nsub; i++) mean += x[s->offset + h * s->nsub + i] / s->nsub;
            for (int i = 0; i < s->nsub; i++) x[s->offset + h * s->nsub + i] -= mean;
        }
        for (int i = 0; i < s->nslopes; i++) a += e[s->offset + i] * x[s->offset + i];
    }
    for (int m = 0; m < f->sys->nlgs; m++) {
        const wt_sensor *s = &f->sys->sensors[m];
        for (int i = 0; i < s->nslopes; i++) x[s->offset + i] -= a / f->sys->nlgs * e[s->offset + i];
    }
}

/* The weight is P C̃⁻¹ P with P the orthogonal projector that removes each LGS's tip-tilt and their common focus:
 * against that product formed explicitly (1e-12: the rank-2 form's sums in another order), symmetric (xᵀ W y = yᵀ W x),
 * zero on the common focus f_c and on each LGS's tip (1e-12 of W's size on a unit vector), and not on a differential
 * focus (e_1 − e_2: it keeps most of its weight, > 0.5 of what the tip-tilt-only weight gives it). The stacked
 * patterns are unit per LGS and ⟂ that LGS's tip and tilt. */
START_TEST(test_common_weight_projection)
{
    fixture f, g;
    setup(&f, 0, 2, common_on);
    setup(&g, 0, 0, NULL);
    const double *e = wt_tomography_common_focus(f.t);
    ck_assert_ptr_nonnull(e);
    ck_assert_ptr_null(wt_tomography_common_focus(g.t));
    for (int m = 0; m < f.sys->nsensors; m++) ck_assert_ptr_null(wt_noise_focus(wt_tomography_noise(f.t, m)));
    const int64_t ns = f.ns;
    double *x = malloc(ns * sizeof *x), *y = malloc(ns * sizeof *y), *w1 = malloc(ns * sizeof *w1),
           *w2 = calloc(ns, sizeof *w2), *px = malloc(ns * sizeof *px), *v = malloc(ns * sizeof *v);
    for (int m = 0; m < f.sys->nlgs; m++) {
        const wt_sensor *s = &f.sys->sensors[m];
        double nn = 0.0, sx = 0.0, sy = 0.0;
        for (int i = 0; i < s->nsub; i++) sx += e[s->offset + i], sy += e[s->offset + s->nsub + i];
        for (int i = 0; i < s->nslopes; i++) nn += e[s->offset + i] * e[s->offset + i];
        ck_assert_double_le(fabs(nn - 1.0), 1e-12);
        ck_assert_double_le(fabs(sx) + fabs(sy), 1e-12);
    }
    tu_randn(x, ns, 301);
    tu_randn(y, ns, 302);
    weigh_all(&f, x, w1);
    memcpy(px, x, ns * sizeof *x);
    project_common(&f, px);
    memset(v, 0, ns * sizeof *v);
    for (int m = 0; m < f.sys->nsensors; m++) {
        const wt_sensor *s = &f.sys->sensors[m];
        if (m < f.sys->nlgs) wt_noise_apply_inv(wt_tomography_noise(f.t, m), 1.0, px + s->offset, v + s->offset);
        else wt_noise_apply_weight(wt_tomography_noise(f.t, m), 1.0, x + s->offset, v + s->offset);
    }
    project_common(&f, v); /* (only the LGS's part: the NGS's weights have no projection) */
    ck_assert_double_le(tu_rel_diff(w1, v, ns), 1e-12);
    weigh_all(&f, y, w2);
    const double xy = tu_dot(x, w2, ns), yx = tu_dot(y, w1, ns);
    ck_assert_double_le(fabs(xy - yx), 1e-12 * tu_norm(x, ns) * tu_norm(w2, ns));
    /* f_c and a tip: annihilated */
    const double big = tu_norm(w1, ns) / tu_norm(x, ns);
    memset(x, 0, ns * sizeof *x);
    for (int m = 0; m < f.sys->nlgs; m++)
        for (int i = 0; i < f.sys->sensors[m].nslopes; i++) x[f.sys->sensors[m].offset + i] = e[f.sys->sensors[m].offset + i] / sqrt((double)f.sys->nlgs);
    weigh_all(&f, x, w1);
    ck_assert_double_le(tu_norm(w1, ns), 1e-12 * big);
    memset(x, 0, ns * sizeof *x);
    for (int i = 0; i < f.sys->sensors[1].nsub; i++) x[f.sys->sensors[1].offset + i] = 1.0;
    weigh_all(&f, x, w1);
    ck_assert_double_le(tu_norm(w1, ns), 1e-12 * big * sqrt((double)f.sys->sensors[1].nsub));
    /* e_1 − e_2: kept */
    memset(x, 0, ns * sizeof *x);
    for (int q = 0; q < 2; q++)
        for (int i = 0; i < f.sys->sensors[q].nslopes; i++)
            x[f.sys->sensors[q].offset + i] = (q ? -1.0 : 1.0) * e[f.sys->sensors[q].offset + i];
    weigh_all(&f, x, w1);
    weigh_all(&g, x, w2);
    ck_assert_double_gt(tu_dot(x, w1, ns), 0.5 * tu_dot(x, w2, ns));
    free(x), free(y), free(w1), free(w2), free(px), free(v);
    teardown(&f);
    teardown(&g);
}
END_TEST

/* The factorised M with the common focus in the low rank (4 per LGS + 2 in all) is the matrix-free M (1e-12), its
 * solve PCG's converged one (1e-9); R s = the converged pcg3 (1e-5): the bounds of the tests above. The fp32
 * operator with the mode is the double one to float accuracy (1e-5 relative on a random c). */
START_TEST(test_common_normal_matches)
{
    fixture f;
    setup(&f, 0, 2, common_on);
    wt_mvm_normal *nm = normal(&f);
    int rank = 4 * f.sys->nlgs + 2;
    for (int m = f.sys->nlgs; m < f.sys->nsensors; m++) rank += f.sys->sensors[m].nslopes;
    ck_assert_int_eq(wt_mvm_normal_rank(nm), rank);
    double *x = malloc(f.n * sizeof *x), *y1 = malloc(f.n * sizeof *y1), *y2 = malloc(f.n * sizeof *y2),
           *s = malloc(f.ns * sizeof *s), *xp = calloc(f.n, sizeof *xp);
    tu_randn(x, f.n, 311);
    ck_assert_int_eq(wt_mvm_normal_apply(nm, x, y1), WT_OK);
    tu_tomo_apply(f.t, x, y2);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-12);
    fixture g;
    const char *const f32[] = {common_on[0], common_on[1], "recon.pcg3.operator_precision=\"fp32\""};
    setup(&g, 0, 3, f32);
    tu_tomo_apply(g.t, x, y1);
    ck_assert_double_le(tu_rel_diff(y1, y2, f.n), 1e-5);
    teardown(&g);
    solve_matches_pcg(&f, nm, s, y1, x, xp, 312);
    free(x), free(y1), free(y2), free(s), free(xp);
    wt_mvm_normal_free(nm);
    teardown(&f);
}
END_TEST

START_TEST(test_r_matches_pcg3_common) { check_r_matches(0, 2, common_on); }
END_TEST

/* A focus a r² on every LGS, the same a (a sodium altitude change), 10× the slopes' rms: with the common mode the
 * right-hand side moves by rounding only (1e-11) and the converged reconstruction by 1e-9, in double and in fp32
 * (float rounding of 10× larger slopes: 1e-5 of b). A differential focus (+a, −a, +a, −a: the same size, zero common
 * part) moves the reconstruction by > 10 %: the LGS still see how focus differs between their lines of sight. */
START_TEST(test_common_slopes_ignored)
{
    for (int v = 0; v < 3; v++) { /* 0 double common, 1 fp32 common, 2 double common with the differential focus */
        fixture f;
        const char *const f32[] = {common_on[0], common_on[1], "recon.pcg3.operator_precision=\"fp32\""};
        setup(&f, 0, v == 1 ? 3 : 2, f32);
        const wt_grid *g = &f.sys->sense_grid;
        double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s),
               *s2 = malloc(f.ns * sizeof *s2), *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2),
               *c1 = calloc(f.n, sizeof *c1), *c2 = calloc(f.n, sizeof *c2);
        test_slopes(&f, s, 321);
        memcpy(s2, s, f.ns * sizeof *s);
        const double a = focus_phase(&f, s, ph);
        ck_assert_int_eq(f.sys->nlgs % 2, 0);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, v == 2 && (m & 1) ? -a : a, ph, s2 + l->offset);
        }
        tu_tomo_rhs(f.t, s, b1);
        tu_tomo_rhs(f.t, s2, b2);
        wt_pcg_result res;
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s, c1, 20000, v == 1 ? 1e-6 : 1e-12, NULL, &res), WT_OK);
        ck_assert_int_eq(wt_tomography_solve(f.t, wt_precond_pcg(f.p), s2, c2, 20000, v == 1 ? 1e-6 : 1e-12, NULL, &res), WT_OK);
        if (v == 0) {
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
            ck_assert_double_le(tu_rel_diff(c2, c1, f.n), 1e-9);
        } else if (v == 1) {
            ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-5);
        } else {
            ck_assert_double_gt(tu_rel_diff(c2, c1, f.n), 0.1);
        }
        free(ph), free(s), free(s2), free(b1), free(b2), free(c1), free(c2);
        teardown(&f);
    }
}
END_TEST


/* The same in space (cg9 with the fourier preconditioner: the adjoint by layers, adjoint_space): the right-hand side
 * ignores the same focus on every LGS (1e-11) and not a differential one (> 10 % of b) */
START_TEST(test_common_slopes_ignored_space)
{
    const char *const set[] = {common_on[0], common_on[1], "recon.cg9.preconditioner=\"fourier\"",
                               "recon.cg9.coarse_levels=0", "recon.cg9.layer_spacing_m=[1.0, 1.0, 1.0, 1.0, 1.0]",
                               "recon.cg9.prior=\"full\""};
    fixture f;
    setup(&f, 1, 6, set);
    const wt_grid *g = &f.sys->sense_grid;
    double *ph = malloc(wt_grid_size(g) * sizeof *ph), *s = malloc(f.ns * sizeof *s), *s2 = malloc(f.ns * sizeof *s2),
           *b1 = calloc(f.n, sizeof *b1), *b2 = calloc(f.n, sizeof *b2);
    test_slopes(&f, s, 331);
    const double rms = tu_norm(s, f.ns) / sqrt((double)f.ns);
    for (int iy = 0; iy < g->ny; iy++)
        for (int ix = 0; ix < g->nx; ix++) {
            const double x = g->x0 + ix * g->dx, y = g->y0 + iy * g->dx;
            ph[ix + (int64_t)g->nx * iy] = x * x + y * y;
        }
    const wt_sensor *l1 = &f.sys->sensors[0];
    double *fs = calloc(l1->nslopes, sizeof *fs);
    wt_shack_hartmann_apply(l1->sh, 1.0, ph, fs);
    const double a = 10.0 * rms / (tu_norm(fs, l1->nslopes) / sqrt((double)l1->nslopes));
    free(fs);
    tu_tomo_rhs(f.t, s, b1);
    for (int diff = 0; diff < 2; diff++) {
        memcpy(s2, s, f.ns * sizeof *s);
        for (int m = 0; m < f.sys->nlgs; m++) {
            const wt_sensor *l = &f.sys->sensors[m];
            wt_shack_hartmann_apply(l->sh, (diff && (m & 1) ? -a : a), ph, s2 + l->offset);
        }
        memset(b2, 0, f.n * sizeof *b2);
        tu_tomo_rhs(f.t, s2, b2);
        if (diff) ck_assert_double_gt(tu_rel_diff(b2, b1, f.n), 0.1);
        else ck_assert_double_le(tu_rel_diff(b2, b1, f.n), 1e-11);
    }
    free(ph), free(s), free(s2), free(b1), free(b2);
    teardown(&f);
}
END_TEST

/* recon.lgs_focus_mode without the removal is refused naming both keys; an unknown mode naming the choices */
START_TEST(test_common_mode_refused)
{
    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    const char *set[] = {"recon.lgs_focus_mode=\"common\""};
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 1, set, &cfg), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "recon.lgs_focus_mode") && strstr(wt_error_message(ctx), "recon.lgs_focus_removal"),
                  "%s", wt_error_message(ctx));
    const char *set2[] = {"recon.lgs_focus_removal=true", "recon.lgs_focus_mode=\"mean\""};
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 2, set2, &cfg), WT_ERR_CONFIG);
    ck_assert_msg(strstr(wt_error_message(ctx), "\"common\""), "%s", wt_error_message(ctx));
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mvm");
    TCase *tc = tcase_create("core");
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_chol_errors_and_solve);
    tcase_add_test(tc, test_atilde_matches_slopes);
    tcase_add_test(tc, test_normal_apply_matches);
    tcase_add_test(tc, test_normal_solve_matches_pcg);
    tcase_add_test(tc, test_r_matches_pcg3);
    tcase_add_test(tc, test_r_matches_pcg3_split);
    tcase_add_test(tc, test_r_matches_cg9);
    tcase_add_test(tc, test_r_matches_full_prior);
    tcase_add_test(tc, test_ra_matches);
    tcase_add_test(tc, test_orderings);
    tcase_add_test(tc, test_budget_refuses);
    tcase_add_test(tc, test_stop_between_blocks);
    tcase_add_test(tc, test_pcg3_layer_mismatch_refused);
    tcase_add_test(tc, test_focus_normal_matches);
    tcase_add_test(tc, test_r_matches_pcg3_focus);
    tcase_add_test(tc, test_focus_slopes_ignored);
    tcase_add_test(tc, test_focus_refused_without_ngs_focus);
    tcase_add_test(tc, test_focus_model_error);
    tcase_add_test(tc, test_common_weight_projection);
    tcase_add_test(tc, test_common_normal_matches);
    tcase_add_test(tc, test_r_matches_pcg3_common);
    tcase_add_test(tc, test_common_slopes_ignored);
    tcase_add_test(tc, test_common_slopes_ignored_space);
    tcase_add_test(tc, test_common_mode_refused);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
