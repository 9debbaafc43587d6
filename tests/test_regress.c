/* tests/test_regress.c: the closed-loop Strehl regression table (tests/regress/strehl.tsv).
 *
 * Every row is a short closed loop on a demo-scale system (preset + overrides, reconstructor, frames,
 * settle, seed) with its reference field-average LE Strehl, on-axis LE Strehl and field WFE, and a
 * tolerance for each: one standard deviation of that metric over 8 seeds of the same case, measured by
 * tests/regress/update.sh (the realisation scatter, not what the code printed). The run here uses the
 * row's own seed, so an unchanged code reproduces the reference to its printed resolution; a change
 * larger than one realisation sigma, in either direction, fails, and the table is then updated in a
 * commit that says why. A malformed table fails too. */
#include "builder/mvm_build.h"
#include "core/model/system.h"
#include "core/model/tomography.h"
#include "sim/loop.h"
#include "testutil.h"

#define TABLE "tests/regress/strehl.tsv"
#define NCOL 16
enum { C_CASE, C_PRESET, C_OV, C_RECON, C_FRAMES, C_SETTLE, C_SEED, C_FSR, C_OSR, C_WFE, C_TFSR, C_TOSR, C_TWFE };

/* Split a tab-separated line in place; returns the number of fields. */
static int split(char *line, char **f, int max)
{
    int n = 0;
    line[strcspn(line, "\r\n")] = '\0';
    for (char *p = line; n < max;) {
        f[n++] = p;
        char *t = strchr(p, '\t');
        if (!t) break;
        *t = '\0';
        p = t + 1;
    }
    return n;
}

static double number(const char *s, const char *what, int row)
{
    char *end;
    double v = strtod(s, &end);
    ck_assert_msg(*s && !*end && isfinite(v), TABLE " row %d: %s '%s' is not a number", row, what, s);
    return v;
}

static int recon_kind(const char *s, int row)
{
    if (!strcmp(s, "none")) return WT_RECON_NONE;
    if (!strcmp(s, "pcg3")) return WT_RECON_PCG3;
    if (!strcmp(s, "cg9")) return WT_RECON_CG9;
    if (!strcmp(s, "mvm")) return WT_RECON_MVM;
    ck_abort_msg(TABLE " row %d: unknown reconstructor '%s'", row, s);
    return -1;
}

static void run_row(char **f, int row)
{
    wt_context *ctx = tu_context();
    const char *set[24];
    char buf[3][64], ovs[1024];
    int nset = 0;
    snprintf(buf[0], sizeof buf[0], "loop.frames=%d", (int)number(f[C_FRAMES], "frames", row));
    snprintf(buf[1], sizeof buf[1], "evaluation.settle_frames=%d", (int)number(f[C_SETTLE], "settle", row));
    set[nset++] = buf[0];
    set[nset++] = buf[1];
    snprintf(ovs, sizeof ovs, "%s", f[C_OV]);
    for (char *tok = strtok(ovs, ";"); tok && nset < 24; tok = strtok(NULL, ";")) set[nset++] = tok;
    const int kind = recon_kind(f[C_RECON], row);
    const double seed = number(f[C_SEED], "seed", row);
    wt_config *cfg = NULL;
    wt_system *sys = NULL;
    wt_mvm *mvm = NULL;
    wt_loop *lp = NULL;
    ck_assert_msg(wt_config_read(ctx, f[C_PRESET], nset, set, &cfg) == WT_OK, "row %d: %s", row, wt_error_message(ctx));
    ck_assert_msg(wt_system_alloc(ctx, cfg, &sys) == WT_OK, "row %d: %s", row, wt_error_message(ctx));
    if (kind == WT_RECON_MVM) {
        /* as `wavetomo build` and `compare` do: the exact MAP of the pcg3 system */
        ck_assert_msg(wt_mvm_build_variant(ctx, sys, cfg, "pcg3", NULL, &mvm) == WT_OK, "row %d: %s", row,
                      wt_error_message(ctx));
    }
    wt_loop_options o = {.recon = kind, .mvm = mvm, .iterations = -1, .seed = (uint64_t)seed, .noise = cfg->noise};
    ck_assert_msg(wt_loop_alloc(ctx, sys, &o, &lp) == WT_OK, "row %d: %s", row, wt_error_message(ctx));
    for (int t = 0; t < cfg->frames; t++) ck_assert_msg(wt_loop_step(lp) == WT_OK, "%s", wt_error_message(ctx));
    const wt_strehl_le *le = wt_loop_le(lp);
    double fsr = 0.0, var = 0.0;
    for (int j = 0; j < sys->neval; j++) {
        fsr += wt_strehl_le_strehl(le, j) / sys->neval;
        var += pow(wt_strehl_le_wfe(le, j), 2) / sys->neval;
    }
    const double osr = wt_strehl_le_strehl(le, sys->eval_centre), wfe = sqrt(var) * 1e9;
    const double rf = number(f[C_FSR], "field_sr", row), ro = number(f[C_OSR], "onaxis_sr", row);
    const double rw = number(f[C_WFE], "field_wfe_nm", row);
    const double tf = number(f[C_TFSR], "tol_field_sr", row), to = number(f[C_TOSR], "tol_onaxis_sr", row);
    const double tw = number(f[C_TWFE], "tol_wfe_nm", row);
    ck_assert_msg(tf > 0 && to > 0 && tw > 0, TABLE " row %d (%s): tolerances must be > 0", row, f[C_CASE]);
    fprintf(stderr, "regress %-12s field SR %.4f (ref %.4f ± %.4f)  on-axis %.4f (%.4f ± %.4f)  WFE %.1f nm (%.1f ± %.1f)\n",
            f[C_CASE], fsr, rf, tf, osr, ro, to, wfe, rw, tw);
    ck_assert_msg(fabs(fsr - rf) <= tf && fabs(osr - ro) <= to && fabs(wfe - rw) <= tw,
                  "%s (row %d): field SR %.4f vs reference %.4f ± %.4f, on-axis %.4f vs %.4f ± %.4f, field WFE %.1f nm "
                  "vs %.1f ± %.1f nm: the change exceeds the seed-to-seed scatter; if it is intended, rerun "
                  "tests/regress/update.sh and say why in the commit",
                  f[C_CASE], row, fsr, rf, tf, osr, ro, to, wfe, rw, tw);
    wt_loop_free(lp);
    wt_mvm_free(mvm);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}

START_TEST(test_regression_table)
{
    FILE *fp = fopen(TABLE, "r");
    ck_assert_msg(fp != NULL, "cannot open " TABLE " (run the tests from the repository root)");
    char line[4096], *f[NCOL + 1];
    ck_assert_msg(fgets(line, sizeof line, fp) != NULL, TABLE ": empty");
    ck_assert_msg(split(line, f, NCOL + 1) == NCOL && !strcmp(f[0], "case") && !strcmp(f[C_TWFE], "tol_wfe_nm"),
                  TABLE ": the header must have the %d columns written by tests/regress/update.sh", NCOL);
    int rows = 0, seen[4] = {0, 0, 0, 0};
    while (fgets(line, sizeof line, fp)) {
        rows++;
        ck_assert_msg(split(line, f, NCOL + 1) == NCOL, TABLE " row %d: expected %d tab-separated fields", rows, NCOL);
        seen[recon_kind(f[C_RECON], rows)] = 1;
        run_row(f, rows);
    }
    fclose(fp);
    /* the table covers every reconstructor */
    ck_assert_msg(rows >= 4 && seen[0] && seen[1] && seen[2] && seen[3], TABLE ": %d rows; every reconstructor needs one", rows);
}
END_TEST

/* The reader refuses what is not a number (the table is data the test trusts). */
START_TEST(test_number_parser)
{
    ck_assert_double_eq(number("0.25", "x", 0), 0.25);
    ck_assert_int_eq(split((char[]){"a\tb\tc\n"}, (char *[4]){0}, 4), 3);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("regress");
    TCase *tc = tcase_create("table");
    tcase_set_timeout(tc, 1200);
    tcase_add_test(tc, test_regression_table);
    tcase_add_test(tc, test_number_parser);
    suite_add_tcase(s, tc);
    return s;
}
TU_MAIN
