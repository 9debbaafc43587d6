/* tests/test_mpi.c: `mpirun -n 2 wavetomo build|compare` (issue 11) equals the serial command bit for bit on
 * the demo system: the same R and RÂ, the same per-case Strehl, WFE and per-seed values. Two ranks of one
 * thread each against one process of one thread (the threads per case, not the ranks, fix the numbers).
 * Also the seed statistics of `compare --seeds N`: means, standard errors and paired differences equal a
 * direct computation from the per-seed values stored in results.h5, and the seeds are different
 * realisations. Uses $BIN/wavetomo and mpirun (OpenMPI, installed by the Makefile). */
#include <math.h>
#include <stdarg.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/io/h5.h"
#include "testutil.h"

static char dir[64], wt[512];

/* --allow-run-as-root: the build machine runs as root; --oversubscribe: 2 ranks on a 1-core host. Under
 * `make debug-test` the DWARF unwinder lets LeakSanitizer see OpenMPI's own leftovers (tests/lsan.supp). */
#define MPIRUN "LSAN_OPTIONS=\"$LSAN_OPTIONS:fast_unwind_on_malloc=0\" mpirun --oversubscribe --allow-run-as-root -n 2 "

/* Run "PREFIX $BIN/wavetomo ARGS" (prefix: "" or MPIRUN), output in dir/out.txt. */
static int run(const char *prefix, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int run(const char *prefix, const char *fmt, ...)
{
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(cmd, sizeof cmd, "%s%s ", prefix, wt);
    vsnprintf(cmd + n, sizeof cmd - (size_t)n, fmt, ap);
    va_end(ap);
    size_t l = strlen(cmd);
    snprintf(cmd + l, sizeof cmd - l, " > %s/out.txt 2>&1", dir);
    int st = system(cmd);
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
        char show[256];
        snprintf(show, sizeof show, "cat %s/out.txt >&2", dir);
        if (system(show) != 0) fprintf(stderr, "(no output)\n");
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_mpi_"); }
static void teardown(void) { tu_cli_teardown(dir); }

/* Dataset `name` of path as doubles (float32 converts exactly), with its element count; a float16 dataset
 * (fp16 storage) as its 16-bit patterns, each widened to a double. */
static double *read_all(const char *path, const char *name, size_t *count)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    ck_assert_msg(wt_h5_open(ctx, path, &r) == WT_OK, "%s", wt_error_message(ctx));
    int rank = 0;
    int64_t d[8];
    ck_assert_msg(wt_h5_dims(r, name, &rank, d) == WT_OK, "%s", wt_error_message(ctx));
    size_t n = 1;
    for (int k = 0; k < rank; k++) n *= (size_t)d[k];
    double *x = malloc(n * sizeof *x);
    ck_assert_ptr_nonnull(x);
    if (wt_h5_read(r, name, WT_H5_F64, rank, d, NULL, x, n) != WT_OK) {
        uint16_t *h = malloc(n * sizeof *h);
        ck_assert_ptr_nonnull(h);
        ck_assert_msg(wt_h5_read(r, name, WT_H5_F16, rank, d, NULL, h, n) == WT_OK, "%s", wt_error_message(ctx));
        for (size_t i = 0; i < n; i++) x[i] = h[i];
        free(h);
    }
    wt_h5_close(r);
    wt_context_free(ctx);
    *count = n;
    return x;
}

/* Bit-identical dataset in two files, and not all zero (a gather that lost rows would leave zeros). */
static void same_dataset(const char *a, const char *b, const char *name)
{
    size_t na, nb;
    double *x = read_all(a, name, &na), *y = read_all(b, name, &nb);
    ck_assert_uint_eq(na, nb);
    size_t diff = 0, zero = 0;
    for (size_t i = 0; i < na; i++) diff += memcmp(&x[i], &y[i], sizeof *x) != 0, zero += x[i] == 0.0;
    ck_assert_msg(diff == 0, "%s: %zu of %zu values differ between %s and %s", name, diff, na, a, b);
    ck_assert_msg(zero < na, "%s is all zero", name);
    free(x);
    free(y);
}

START_TEST(test_build_mpi_equals_serial)
{
    char s[128], m[128];
    /* demo: 759 actuators = blocks of 256, 256, 247; rank 0 solves blocks 0 and 2, rank 1 block 1 */
    /* and in fp16 storage: 16-bit rows with one scale each, gathered as they are */
    /* (cg9's MVM with the paper's diagonal prior: an MVM cannot hold its default "full" one) */
    const char *recon[] = {"pcg3", "cg9 --set recon.cg9.prior=\\\"paper\\\"", "pcg3 --set recon.mvm_precision=\\\"fp16\\\""};
    for (int k = 0; k < 3; k++) {
        snprintf(s, sizeof s, "%s/s-%d.h5", dir, k);
        snprintf(m, sizeof m, "%s/m-%d.h5", dir, k);
        ck_assert_int_eq(run("", "build --config data/presets/demo.cfg --recon %s --threads 1 --quiet --out %s", recon[k], s), 0);
        ck_assert_int_eq(run(MPIRUN, "build --config data/presets/demo.cfg --recon %s --threads 1 --out %s", recon[k], m), 0);
        same_dataset(s, m, "R");
        same_dataset(s, m, "RA");
        if (k == 2) same_dataset(s, m, "R_row_scale");
    }
}
END_TEST

/* The result datasets that must not depend on how the cases were dealt (timings do). */
static const char *const physics[] = {"strehl_le", "wfe_le", "strehl_le_on_axis", "strehl_le_field", "wfe_le_field",
                                      "reconstructor_memory", "strehl_psf", "psf_frames", "series/wfe_field",
                                      "psf/mvm_1/image", "psf/none_0/strehl_peak"};

START_TEST(test_compare_mpi_equals_serial)
{
    /* 3 methods x 2 sweep values x 2 seeds = 12 cases over 2 ranks, the MVM built once per sweep value */
    const char *opts = "compare --config data/presets/demo.cfg --recon mvm,pcg3,none --sweep lgs.wfs.photons=50,100 "
                       "--seeds 2 --frames 12 --threads 1 --out";
    ck_assert_int_eq(run("", "%s %s/s --quiet", opts, dir), 0);
    ck_assert_int_eq(run(MPIRUN, "%s %s/m", opts, dir), 0);
    char a[128], b[128];
    snprintf(a, sizeof a, "%s/s/results.h5", dir);
    snprintf(b, sizeof b, "%s/m/results.h5", dir);
    for (size_t k = 0; k < sizeof physics / sizeof *physics; k++) same_dataset(a, b, physics[k]);
    same_dataset(a, b, "seeds/strehl_le");
    same_dataset(a, b, "seeds/wfe_le_field");
    /* the text outputs too (rank 0 wrote them from the gathered results); only timings may differ */
    char cmd[512];
    snprintf(cmd, sizeof cmd, "cut -d, -f1-5,10- %s/s/summary.csv | cmp -s - <(cut -d, -f1-5,10- %s/m/summary.csv)", dir, dir);
    char bash[600];
    snprintf(bash, sizeof bash, "bash -c '%s'", cmd);
    ck_assert_int_eq(system(bash), 0);
}
END_TEST

/* Element i of dataset `name` of path. */
static double at(const char *path, const char *name, size_t i)
{
    size_t n;
    double *x = read_all(path, name, &n), v;
    ck_assert_msg(i < n, "%s[%zu] out of %zu", name, i, n);
    v = x[i];
    free(x);
    return v;
}

START_TEST(test_seed_statistics)
{
    /* 2 methods x 3 seeds (7, 8, 9), no sweep: results.h5 seeds/X is [method, seed] */
    const char *opts = "compare --config data/presets/demo.cfg --recon pcg3,mvm --frames 12 --threads 1 --quiet";
    ck_assert_int_eq(run("", "%s --seed 7 --seeds 3 --out %s/n", opts, dir), 0);
    char p[128], q[128], name[64];
    snprintf(p, sizeof p, "%s/n/results.h5", dir);
    const char *metric[] = {"strehl_le_on_axis", "strehl_le_field", "wfe_le_field"};
    const int ns = 3;
    for (int k = 0; k < 3; k++) {
        double x[2][3], mean[2], se[2];
        snprintf(name, sizeof name, "seeds/%s", metric[k]);
        for (int m = 0; m < 2; m++) {
            for (int s = 0; s < ns; s++) x[m][s] = at(p, name, (size_t)(m * ns + s));
            /* the seeds are different realisations: no two seeds give the same figure */
            ck_assert(x[m][0] != x[m][1] && x[m][1] != x[m][2] && x[m][0] != x[m][2]);
            double sum = 0.0, ss = 0.0;
            for (int s = 0; s < ns; s++) sum += x[m][s];
            mean[m] = sum / ns;
            for (int s = 0; s < ns; s++) ss += (x[m][s] - mean[m]) * (x[m][s] - mean[m]);
            se[m] = sqrt(ss / (ns - 1) / ns);
            ck_assert_rel(at(p, metric[k], (size_t)m), mean[m], 1e-12, 1e-15);
            snprintf(name, sizeof name, "stderr/%s", metric[k]);
            ck_assert_rel(at(p, name, (size_t)m), se[m], 1e-12, 1e-15);
            snprintf(name, sizeof name, "seeds/%s", metric[k]);
        }
        /* the paired difference pcg3 - mvm: mean and standard error of the per-seed differences */
        double d[3], dm = 0.0, dss = 0.0;
        for (int s = 0; s < ns; s++) d[s] = x[0][s] - x[1][s], dm += d[s] / ns;
        for (int s = 0; s < ns; s++) dss += (d[s] - dm) * (d[s] - dm);
        snprintf(name, sizeof name, "difference/%s", metric[k]);
        ck_assert_rel(at(p, name, 0), dm, 1e-12, 1e-15);
        snprintf(name, sizeof name, "difference/%s_se", metric[k]);
        ck_assert_rel(at(p, name, 0), sqrt(dss / (ns - 1) / ns), 1e-12, 1e-15);
        /* pairing: the paired SE is not the SE of a difference of independent means */
        ck_assert(fabs(sqrt(dss / (ns - 1) / ns) - sqrt(se[0] * se[0] + se[1] * se[1])) > 1e-9);
    }
    /* the per-seed datasets are [method, sweep value, seed(, direction)] */
    {
        wt_context *ctx = tu_context();
        wt_h5_reader *r = NULL;
        ck_assert_msg(wt_h5_open(ctx, p, &r) == WT_OK, "%s", wt_error_message(ctx));
        int rank = 0;
        int64_t d[8];
        ck_assert_int_eq(wt_h5_dims(r, "seeds/strehl_le", &rank, d), WT_OK);
        ck_assert_int_eq(rank, 4);
        ck_assert(d[0] == 2 && d[1] == 1 && d[2] == ns && d[3] >= 1);
        ck_assert_int_eq(wt_h5_dims(r, "seeds/strehl_le_field", &rank, d), WT_OK);
        ck_assert_int_eq(rank, 3);
        ck_assert(d[0] == 2 && d[1] == 1 && d[2] == ns);
        ck_assert_int_eq(wt_h5_dims(r, "seeds/done", &rank, d), WT_OK);
        ck_assert_int_eq(rank, 3);
        wt_h5_close(r);
        wt_context_free(ctx);
    }
    /* --resume of the finished comparison reads every seed's results back (nothing left to run) and
     * writes the same numbers */
    double before = at(p, "seeds/wfe_le_field", 4);
    ck_assert_int_eq(run("", "compare --config data/presets/demo.cfg --recon pcg3,mvm --frames 12 --threads 1 --seed 7 "
                             "--seeds 3 --out %s/n --resume", dir), 0);
    snprintf(q, sizeof q, "grep -q 'resuming: 6 of 6 cases done' %s/out.txt", dir);
    ck_assert_int_eq(system(q), 0);
    double after = at(p, "seeds/wfe_le_field", 4);
    ck_assert_msg(memcmp(&before, &after, sizeof before) == 0, "resume changed %.17g to %.17g", before, after);
    /* seed k is the run of sim.seed = 7 + k: a single run with --seed 8 is the second seed bit for bit */
    ck_assert_int_eq(run("", "%s --seed 8 --out %s/one", opts, dir), 0);
    snprintf(q, sizeof q, "%s/one/results.h5", dir);
    for (int m = 0; m < 2; m++) {
        double a = at(q, "strehl_le_field", (size_t)m), b = at(p, "seeds/strehl_le_field", (size_t)(m * ns + 1));
        ck_assert_msg(memcmp(&a, &b, sizeof a) == 0, "method %d: %.17g single vs %.17g in the seeds run", m, a, b);
    }
    /* --sweep sim.seed=7,8,9 is the same set of seeds */
    ck_assert_int_eq(run("", "%s --sweep sim.seed=7,8,9 --out %s/sw", opts, dir), 0);
    snprintf(q, sizeof q, "%s/sw/results.h5", dir);
    same_dataset(p, q, "seeds/strehl_le");
    same_dataset(p, q, "difference/wfe_le_field_se");
    /* the report says which differences are within the noise */
    snprintf(q, sizeof q, "grep -q 'differences are within the noise' %s/n/report.md", dir);
    ck_assert_int_eq(system(q), 0);
}
END_TEST

/* --dry-run under mpirun: one estimate (rank 0's), saying that the memory is per rank; nothing written. */
START_TEST(test_dry_run_once)
{
    ck_assert_int_eq(run(MPIRUN, "compare --config data/presets/demo.cfg --recon pcg3 --dry-run --out %s/d", dir), 0);
    char q[512];
    snprintf(q, sizeof q, "test $(grep -c 'dry-run (nothing allocated' %s/out.txt) -eq 1", dir);
    ck_assert_msg(system(q) == 0, "the estimate is not printed exactly once under 2 ranks");
    snprintf(q, sizeof q, "grep -q 'with 2 ranks: the memory is per rank' %s/out.txt", dir);
    ck_assert_int_eq(system(q), 0);
    snprintf(q, sizeof q, "test ! -e %s/d/results.h5", dir);
    ck_assert_int_eq(system(q), 0);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mpi");
    TCase *tc = tcase_create("mpirun");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_build_mpi_equals_serial);
    tcase_add_test(tc, test_compare_mpi_equals_serial);
    tcase_add_test(tc, test_seed_statistics);
    tcase_add_test(tc, test_dry_run_once);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
